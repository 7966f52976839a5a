"""The discrete states of the simulation (Table 1, Fig. 5(b)) and the functions each one watches.

====  =====================================  ===============================================
s1    free flight, ``v > 0``                 watch ``v`` falling through 0 (I -> s2)
s2    free flight, ``v < 0``                 watch ``H`` falling through 0 (impact: III, IV, V)
                                             and ``v`` rising through 0 (II -> s1)
s3    free flight after release, ``a > 0``   watch ``a`` falling through 0 (XII -> s1)
s4    sticking on ``F'`` (eq. 10)            watch ``a`` rising through 0 (release, XI -> s3)
s5    chattering flight, ``v > 0``           watch ``v`` falling (VI -> s6), ``a`` rising
                                             (VIII: chattering broken, -> s1)
s6    chattering flight, ``v < 0``           watch ``h`` falling (VII: impact, or IX: chatter
                                             map -> s4), ``v`` rising (X -> s1)
====  =====================================  ===============================================

``s5``, ``s6`` integrate the scaled extended state ``(x, h, u)`` of sec. 4.3 (``EXTENDED``).
:func:`initial_state` is the state a simulation starts in.

**Several surfaces.** Each surface ``H_i`` has its own state. In free flight every surface is
in ``s1``, ``s2`` or ``s3`` and all are watched; at most one surface (the *active* one) sticks
or chatters (``s4``-``s6``), its field (``F'_i`` or the extended field of its chattering flight)
is integrated, and the others stay watched in ``s1``-``s3``. :func:`watches` lists the watched
functions of a combination, with their positions in the probe (:func:`.system.probe_layout`).
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.hybrid.sim_data import SimulationError
from nsm_continuation.hybrid.system import CompiledHybrid, probe_layout

S1, S2, S3, S4, S5, S6 = "s1", "s2", "s3", "s4", "s5", "s6"
EXTENDED = (S5, S6)
#: watched functions per state: (probe index, direction, name); probe = (H, v, a, jerk[, h, h'])
WATCH: dict[str, list[tuple[int, int, str]]] = {
    S1: [(1, -1, "v")],
    S2: [(0, -1, "H"), (1, +1, "v")],
    S3: [(2, -1, "a")],
    S4: [(2, +1, "a")],
    S5: [(1, -1, "v"), (2, +1, "a")],
    S6: [(4, -1, "h"), (1, +1, "v")],
}



def initial_state(c: CompiledHybrid, X: np.ndarray) -> str:
    """Discrete state of a point (free flight up/down, or sticking) for a one-surface system
    (the first surface's state for several: :func:`initial_states`)."""
    return initial_states(c, X)[0]


def initial_states(c: CompiledHybrid, X: np.ndarray) -> list[str]:
    """Discrete state of a point for each surface (free flight up/down, or sticking).

    Raises :class:`SimulationError` for a point on the inadmissible side of a surface, or in
    contact with two surfaces at once (a contact the simulator does not model)."""
    pr = c.calls().probe(X).ravel()
    scale = 1e-12 * (1.0 + np.linalg.norm(X))
    modes = []
    for i in range(c.m):
        H, v, a = pr[4 * i: 4 * i + 3]
        if H < -scale:
            where = "the impact surface" if c.m == 1 else c.surface_label(i)
            raise SimulationError(
                f"initial state on the inadmissible side of {where} (H = {H:.3g} < 0)")
        if abs(H) <= scale and abs(v) <= scale:
            modes.append(S4 if a < 0 else S3)
        elif v > 0 or (v == 0 and a > 0):
            modes.append(S1)
        else:
            modes.append(S2)
    stuck = [i for i, mo in enumerate(modes) if mo == S4]
    if len(stuck) > 1:
        raise SimulationError(
            "initial state in contact with " + " and ".join(c.surface_label(i) for i in stuck)
            + " at once: contact with two surfaces at once is not modelled")
    return modes


def watches(modes: list[str], active: int | None) -> list[tuple[int, int, str, int]]:
    """The watched functions of the surfaces' states ``modes`` (``active``: the surface that
    sticks or chatters, None in free flight): ``(probe index, direction, name, surface)``."""
    offsets = probe_layout(len(modes), active,
                           active is not None and modes[active] in EXTENDED)
    return [(offsets[i] + idx, direction, name, i)
            for i, mode in enumerate(modes) for idx, direction, name in WATCH[mode]]
