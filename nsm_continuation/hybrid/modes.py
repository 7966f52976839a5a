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
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.hybrid.sim_data import SimulationError
from nsm_continuation.hybrid.system import CompiledHybrid

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
    """Discrete state of a point (free flight up/down, or sticking)."""
    H, v, a, _ = c.calls().probe(X).ravel()
    scale = 1e-12 * (1.0 + np.linalg.norm(X))
    if H < -scale:
        raise SimulationError(
            f"initial state on the inadmissible side of the impact surface (H = {H:.3g} < 0)")
    if abs(H) <= scale and abs(v) <= scale:
        return S4 if a < 0 else S3
    if v > 0 or (v == 0 and a > 0):
        return S1
    return S2
