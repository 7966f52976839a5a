"""Figures of a run: the drawing kit (:mod:`.kit`), the branch diagram, the multipliers, the
tree of a diagram, the orbits, all drawn by :func:`.make.make_all` (in a forked child where it
can, :mod:`.process`)."""
