"""An independent event-driven simulator of a gear pair with backlash (numpy/scipy only:
nothing of the package is imported).

One relative coordinate ``x`` between two surfaces ``x = +b`` and ``x = -b``:

    x'' + 2 zeta x' + x = fm + cos(omega t),      |x| <= b,      x'+ = -e x'-  at a wall.

With ``q = x - fm`` the flight is the closed form of :mod:`oracles.linear_flight` (unit
forcing), between walls at ``q = b - fm`` (upper) and ``q = -b - fm`` (lower). Impacts are
found on a grid of ``1/steps`` of a period and refined by :func:`brentq`; an interior extremum
of ``x`` is checked too, so that no impact hides between grid points, and an extremum that
stays off the walls is a near approach. The grazing margins of an orbit are the gaps of its
near approaches (``b - x`` at a maximum, ``x + b`` at a minimum) and ``-v^2 / (2 a)`` of its
impacts that decelerate (``a`` the acceleration away from the wall at the impact): the free
flight continued through the wall would turn at that depth.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from oracles.linear_flight import free_flight


class Gear(NamedTuple):
    zeta: float
    fm: float
    b: float
    e: float


class Flight(NamedTuple):
    """The state after ``periods`` forcing periods, the impacts ``(wall, velocity before)``
    and the grazing margins on the way (near approaches and decelerating impacts)."""

    x: float
    v: float
    impacts: list[tuple[str, float]]
    margins: list[float]

    @property
    def margin(self) -> float:
        """The grazing margin closest to zero."""
        return min(self.margins, key=abs)


def _first_contact(g: Gear, omega: float, t0: float, q0: float, v0: float, t_end: float,
                   steps: int) -> tuple[float, str] | None:
    """Time and wall of the first impact after ``t0`` and before ``t_end``, or None."""
    n = max(2, int(np.ceil((t_end - t0) * omega / (2 * np.pi) * steps)) + 1)
    grid = np.linspace(t0, t_end, n)
    q, v = free_flight(grid, t0, q0, v0, g.zeta, omega)
    walls = (("upper", 1.0, g.b - g.fm), ("lower", -1.0, -g.b - g.fm))

    def gap(t: float, sgn: float, w: float) -> float:
        return sgn * (w - float(free_flight(np.array(t), t0, q0, v0, g.zeta, omega)[0]))

    for k in range(n - 1):
        a, c = grid[k], grid[k + 1]
        hits = []
        for wall, sgn, w in walls:
            if sgn * (w - q[k + 1]) < 0 <= sgn * (w - q[k]):
                hits.append((brentq(gap, a, c, args=(sgn, w), xtol=1e-15, rtol=1e-15), wall))
            elif v[k] * v[k + 1] < 0:
                te = brentq(lambda t: float(free_flight(np.array(t), t0, q0, v0, g.zeta,
                                                        omega)[1]), a, c, xtol=1e-15, rtol=1e-15)
                if gap(te, sgn, w) < 0 < gap(a, sgn, w):
                    hits.append((brentq(gap, a, te, args=(sgn, w), xtol=1e-15, rtol=1e-15),
                                 wall))
        if hits:
            return min(hits)
    return None


def _near_approaches(g: Gear, omega: float, t0: float, q0: float, v0: float, t1: float,
                     steps: int) -> list[float]:
    """Gaps to the approached wall at the turns of ``x`` in the flight from ``t0`` to ``t1``."""
    n = max(2, int(np.ceil((t1 - t0) * omega / (2 * np.pi) * steps)) + 1)
    grid = np.linspace(t0, t1, n)
    v = free_flight(grid, t0, q0, v0, g.zeta, omega)[1]
    out = []
    for k in range(n - 1):
        if v[k] * v[k + 1] < 0:
            te = brentq(lambda t: float(free_flight(np.array(t), t0, q0, v0, g.zeta, omega)[1]),
                        grid[k], grid[k + 1], xtol=1e-15, rtol=1e-15)
            x = float(free_flight(np.array(te), t0, q0, v0, g.zeta, omega)[0]) + g.fm
            out.append(g.b - x if v[k] > 0 else x + g.b)
    return out


def simulate(g: Gear, omega: float, x0: float, v0: float, periods: int, steps: int = 400
             ) -> Flight:
    """The flight from ``(x0, v0)`` at forcing phase 0 over ``periods`` forcing periods."""
    t, t_end = 0.0, periods * 2 * np.pi / omega
    q, v = x0 - g.fm, v0
    impacts: list[tuple[str, float]] = []
    margins: list[float] = []
    while True:
        hit = _first_contact(g, omega, t, q, v, t_end, steps)
        t1 = t_end if hit is None else hit[0]
        margins += _near_approaches(g, omega, t, q, v, t1, steps)
        qe, ve = free_flight(np.array(t1), t, q, v, g.zeta, omega)
        if hit is None:
            return Flight(float(qe) + g.fm, float(ve), impacts, margins)
        impacts.append((hit[1], float(ve)))
        # q'' = cos(omega t) - q - 2 zeta q' (unit forcing), away from the wall
        acc = np.cos(omega * t1) - float(qe) - 2 * g.zeta * float(ve)
        a = -acc if hit[1] == "upper" else acc
        if a > 0:
            margins.append(-float(ve) ** 2 / (2 * a))
        if len(impacts) > 100:
            raise RuntimeError("chattering: not handled by this oracle")
        t, q, v = t1, (g.b if hit[1] == "upper" else -g.b) - g.fm, -g.e * float(ve)
