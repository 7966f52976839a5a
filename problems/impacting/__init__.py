"""Hybrid impacting systems with complete chattering and sticking.

Nordmark, Piiroinen (2009), *Simulation and stability analysis of impacting systems with complete
chattering* (``../shared/papers/002_c96038ab39efa963.txt``), declared on
:mod:`nsm_continuation.hybrid`:

* problems: :mod:`.double_pendulum` (``double_pendulum``, sec. 6), :mod:`.impact_oscillator`
  (``impact_oscillator``, sec. 2.2.1), :mod:`.bouncing_ball` (``bouncing_ball``, secs. 3.5, 4.4)
  and :mod:`.two_mass_chain` (``two_mass_chain``, the worked example of
  ``docs/adding_an_impact_system.md``, not a system of the paper);
* two-wall systems (not of the paper), with closed-form symmetric orbits in
  ``tests/oracles/two_wall.py``: :mod:`.two_sided_oscillator` (``two_sided_oscillator``, a
  forced oscillator between two symmetric stops) and :mod:`.impact_damper` (``impact_damper``,
  a forced primary with a free ball in a cavity, Masri & Caughey 1966), whose walls and
  stroboscopic section are declared once in :mod:`.two_walls`;
* a smooth system (no contact, not registered): :mod:`.stuart_landau`, the Stuart-Landau
  oscillator, the worked example of a system without contact and of a crossing section;
* analyses of the double pendulum: :mod:`.brute_force` (brute-force bifurcation diagrams); the
  test oracles (an independent Euler-Lagrange derivation vs the printed eq. (53), the sticking
  saddle of sec. 6.3) live in ``tests/oracles/``.
"""
