"""Crossings and extrema of cubic Hermite interpolants over one integration step.

A watched function ``g`` of the simulation (``H``, ``v``, ``a``, ``h``, the section coordinate) is
known at both ends of an accepted step together with its exact time derivative (CasADi Lie
derivatives): :func:`hermite_first_root` finds the first crossing of its cubic Hermite
interpolant in a given direction (both roots of a dip inside the step count),
:func:`hermite_one_sign` rules out any crossing from the Bernstein control points, and
:func:`quadratic_roots` gives the interior extrema of a state component's interpolant.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def hermite_one_sign(g0: float, m0: float, g1: float, m1: float) -> bool:
    """Whether the cubic Hermite interpolant with values ``g0``, ``g1`` and slopes ``m0``,
    ``m1`` (per unit of ``s``) keeps one strict sign on ``[0, 1]``, with room for the rounding
    of its evaluation: then :func:`hermite_first_root` finds no crossing.

    Its Bernstein control points ``g0, g0 + m0/3, g1 - m1/3, g1`` enclose it on ``[0, 1]``;
    all beyond ``1e-13`` of the data's size (the evaluation's rounding is below ``1e-14`` of
    it; ``1e-300`` covers the absolute rounding of subnormal values), no value at any knot can
    reach zero or the other side. NaN or infinite data: False."""
    b1, b2 = g0 + m0 / 3.0, g1 - m1 / 3.0
    margin = 1e-13 * (abs(g0) + abs(g1) + abs(m0) + abs(m1)) + 1e-300
    return min(g0, g1, b1, b2) > margin or max(g0, g1, b1, b2) < -margin


def hermite_first_root(g0: float, d0: float, g1: float, d1: float, dt: float,
                        direction: int, floor: float = 0.0,
                        verify: Any = None) -> float | None:
    """First ``s`` in ``(0, 1]`` where the cubic Hermite interpolant of ``g`` crosses zero in
    ``direction`` (``-1`` falling, ``+1`` rising); both roots of a dip inside the step count.

    ``floor`` is a hysteresis for functions known only to round-off near zero (``v`` hovering
    at 1e-14 on a degenerate tangency): a crossing counts only from a value beyond it. A crossing
    inside the step with both step ends on the same side (a dip) is confirmed on the true flow by
    ``verify(s, direction)`` at the interpolant's extremum before it counts."""
    # Python floats: the same IEEE operations as on numpy scalars, several times faster
    g0, g1, dt = float(g0), float(g1), float(dt)
    m0, m1 = float(d0) * dt, float(d1) * dt
    if hermite_one_sign(g0, m0, g1, m1):
        return None
    # p(s) = c0 + c1 s + c2 s^2 + c3 s^3
    c0, c1 = g0, m0
    c2 = -3 * g0 - 2 * m0 + 3 * g1 - m1
    c3 = 2 * g0 + m0 - 2 * g1 + m1
    knots = [0.0]
    if c3 != 0.0:
        disc = c2 * c2 - 3 * c3 * c1
        if disc >= 0:
            sq = math.sqrt(disc)
            knots += sorted(s for s in ((-c2 - sq) / (3 * c3), (-c2 + sq) / (3 * c3))
                            if 0.0 < s < 1.0)
    elif c2 != 0.0:
        s = -c1 / (2 * c2)
        if 0.0 < s < 1.0:
            knots.append(s)
    knots.append(1.0)
    vals = [c0 + s * (c1 + s * (c2 + s * c3)) for s in knots]
    vals[0] = g0 if g0 != 0.0 else (0.0 if m0 == 0 else float(np.sign(m0)) * 1e-300)
    falling = direction < 0
    for k in range(len(knots) - 1):
        sa, va, sb, vb = knots[k], vals[k], knots[k + 1], vals[k + 1]
        if falling and va > floor and vb <= -floor * (sb < 1.0) \
                or direction > 0 and va < -floor and vb >= floor * (sb < 1.0):
            if sb < 1.0 and verify is not None and not verify(sb, direction):
                # a dip of the interpolant that the true flow does not make
                continue
            # bisection on the interpolant (p inlined: the same operations)
            lo, hi = sa, sb
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if (c0 + mid * (c1 + mid * (c2 + mid * c3)) > 0) == falling:
                    lo = mid
                else:
                    hi = mid
            return hi
    return None


def quadratic_roots(p0: float, p1: float, p2: float) -> np.ndarray:
    """``np.roots([p0, p1, p2])`` for ``p0 != 0`` and ``p2 != 0`` (no zero to strip): the
    eigenvalues of the same companion matrix by the same LAPACK call, without ``np.roots``'s
    general bookkeeping (the same values to the last bit)."""
    p = np.array([p0, p1, p2], dtype=float)
    A = np.zeros((2, 2))
    A[1, 0] = 1.0
    A[0, :] = -p[1:] / p[0]
    return np.linalg.eigvals(A)

