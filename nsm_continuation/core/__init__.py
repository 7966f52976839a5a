"""The contract and the engines: the Problem in three parts (problem, presentation, capabilities)
with its monitors, the records a continuation produces, the pseudo-arclength (:mod:`.palc`) and
lattice engines, Floquet multipliers (:mod:`.floquet`), root finding and the bordered solves.
Nothing here reads YAML, writes files or draws."""
