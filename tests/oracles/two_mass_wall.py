"""Event-driven simulation of the two-mass chain with a wall by SciPy, independent of the package's
simulator (``problems/impacting/two_mass_chain.py``).

Free flight ``m1 q1'' = -k1 q1 + k2 (q2 - q1) + F0 cos(omega t) - c q1'``,
``m2 q2'' = -k2 (q2 - q1) - c q2'`` (``solve_ivp``, DOP853, the wall ``q2 = gap`` a terminal
event located by SciPy's root finder); an impact is Newton's law ``q2'+ = -e q2'-``. After a
plastic impact (``q2'+ = 0``) the second mass sticks to the wall while the wall must push it
back, i.e. while the force on it with ``q2 = gap``, ``q2' = 0`` points into the wall,
``k2 (q1 - gap) > 0`` (the damping force vanishes at rest); it is released where that force
changes sign (a second terminal event). In sticking only ``q1`` moves, with ``q2 = gap``.
Nothing here comes from the package: not the impact detection, not the sticking rule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

RTOL, ATOL = 1e-12, 1e-13
#: time integrated without the wall's event after the mass leaves it at rest (the event
#: function starts at zero and stays within round-off of it at first: SciPy would fire it
#: again at once)
LEAVE = 1e-6


@dataclass
class Flight:
    """The state at the end time, the largest ``q2`` over the flight and what happened."""

    x: np.ndarray
    max_q2: float
    impacts: int
    sticking_time: float
    #: sticking phases, one cut by the start and the end counted once
    sticking_phases: int


def simulate(x0: np.ndarray, t0: float, t1: float, p: dict[str, float],
             max_impacts: int = 200) -> Flight:
    """From ``x0 = (q1, q2, q1', q2')`` at ``t0`` to ``t1``."""
    m1, m2, k1, k2, c = p["m1"], p["m2"], p["k1"], p["k2"], p["c"]
    F0, w, gap, e = p["F0"], p["omega"], p["gap"], p["restitution"]

    def free(t: float, x: np.ndarray) -> list[float]:
        q1, q2, v1, v2 = x
        return [v1, v2, (-k1 * q1 + k2 * (q2 - q1) + F0 * np.cos(w * t) - c * v1) / m1,
                (-k2 * (q2 - q1) - c * v2) / m2]

    def stuck(t: float, x: np.ndarray) -> list[float]:
        q1, v1 = x
        return [v1, (-k1 * q1 + k2 * (gap - q1) + F0 * np.cos(w * t) - c * v1) / m1]

    def wall(t: float, x: np.ndarray) -> float:
        return x[1] - gap
    wall.terminal, wall.direction = True, 1.0  # type: ignore[attr-defined]

    def release(t: float, x: np.ndarray) -> float:
        return x[0] - gap               # k2 (q1 - gap): the wall's push on m2, over k2
    release.terminal, release.direction = True, -1.0  # type: ignore[attr-defined]

    x, t = np.asarray(x0, dtype=float).copy(), t0
    sticking = abs(x[1] - gap) < 1e-12 and abs(x[3]) < 1e-12 and x[0] > gap
    max_q2, impacts, stick_time = float(x[1]), 0, 0.0
    began_stuck, entered, ended_stuck = sticking, 0, False
    while t < t1:
        if sticking:
            sol = solve_ivp(stuck, (t, t1), x[[0, 2]], method="DOP853", rtol=RTOL, atol=ATOL,
                            events=release)
            stick_time += sol.t[-1] - t
            t = sol.t[-1]
            x = np.array([sol.y[0, -1], gap, sol.y[1, -1], 0.0])
            sticking, ended_stuck = False, sol.status != 1
            if t < t1:                 # released: q2 leaves the wall at rest with q2'' = 0,
                x[0] = min(x[0], gap)  # i.e. the wall's event is zero for a while (cubic)
                t, x = _leave(free, t, min(t + LEAVE, t1), x)
                max_q2 = max(max_q2, float(x[1]))
            continue
        sol = solve_ivp(free, (t, t1), x, method="DOP853", rtol=RTOL, atol=ATOL, events=wall,
                        dense_output=True)
        ts = np.linspace(t, sol.t[-1], 200)
        max_q2 = max(max_q2, float(sol.sol(ts)[1].max()), float(sol.y[1, -1]))
        t, x = sol.t[-1], sol.y[:, -1].copy()
        if sol.status == 1:              # the wall: Newton's law
            impacts += 1
            if impacts > max_impacts:
                raise RuntimeError(f"more than {max_impacts} impacts (chattering)")
            x[1], x[3] = gap, -e * x[3]
            sticking = e == 0.0 and x[0] > gap
            entered += sticking
            if e == 0.0 and not sticking:
                t, x = _leave(free, t, min(t + LEAVE, t1), x)
                max_q2 = max(max_q2, float(x[1]))
    return Flight(x, max_q2, impacts, stick_time,
                  entered + int(began_stuck and not ended_stuck))


def _leave(free: Any, t: float, t1: float, x: np.ndarray) -> tuple[float, np.ndarray]:
    """The first ``LEAVE`` of a flight leaving the wall at rest, without the wall's event."""
    sol = solve_ivp(free, (t, t1), x, method="DOP853", rtol=RTOL, atol=ATOL)
    return float(sol.t[-1]), sol.y[:, -1].copy()
