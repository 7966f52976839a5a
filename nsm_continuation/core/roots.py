"""Events along a branch: records, and root location of test functions between two points.

A test function is evaluated at points of the branch. When it changes sign between two accepted
points ``a`` and ``b``, the zero is located on the *solution curve* (not on the chord): every
trial point is the corrected solution at pseudo-arclength ``sigma`` from ``a``, and ``sigma`` is
found by the Illinois variant of regula falsi (superlinear, bracketing, robust to a test function
that jumps) or, for integer-valued tests such as the number of multipliers outside the unit circle,
by bisection. Both stop when the bracket is shorter than ``tol`` in arclength, so an event is
located to ``tol`` in every component of ``y`` (``|dy| <= d sigma`` on a unit-tangent
parametrisation, up to curvature).

A double crossing inside one step (a test function that dips below zero and comes back, as at a
grazing tangency) shows no sign change at the step ends. :func:`interior_extremum` fits a parabola
through the last three values; if its vertex lies inside the step with the opposite sign the
engine evaluates the curve there and locates both crossings.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from nsm_continuation.core.scalar_search import bounded_minimum


def illinois(f: Callable[[float], tuple[float, Any]], a: float, fa: float, b: float, fb: float,
             tol: float, max_iter: int = 80, close: bool = False) -> tuple[float, Any, float]:
    """Locate a sign change of ``f`` in ``[a, b]`` (``fa * fb <= 0``) by the Illinois method.

    ``f(sigma)`` returns ``(value, payload)``; the payload of the best final iterate is returned
    with its abscissa and the final bracket width.

    A trial point where ``f`` fails (returns ``nan``: the corrector did not converge there) says
    nothing about the side of the zero, so the bracket keeps both of its evaluated ends and the
    next trial is the midpoint of the widest gap between the ends and the failed points inside
    the bracket (:func:`_widest_gap`). The bracket only ever shrinks to a point where ``f`` has
    a sign, and the width returned always covers the failed points: where they surround the zero,
    the width says how far from it the iteration could get, never less.

    A secant iterate within ``1e-3`` of the bracket's width from one of its ends is replaced by
    the midpoint (the ends then approach the zero by halves). With ``close``, it is instead
    moved ``tol / 2`` past the secant's estimate, away from that end (Dekker's step): a
    secant estimate that accurate usually has the zero between it and the end, so the bracket
    closes to about ``tol`` in one or two evaluations instead of ~20 halvings.
    """
    side = 0
    best = (a, None) if abs(fa) < abs(fb) else (b, None)
    failed: list[float] = []
    for _ in range(max_iter):
        if abs(b - a) <= tol:
            break
        inside = [x for x in failed if min(a, b) < x < max(a, b)]
        if inside:
            c, gap = _widest_gap(a, b, inside)
            if gap <= tol:
                break
        else:
            c = _secant_point(a, fa, b, fb, tol, close)
        fc, payload_c = f(c)
        if not np.isfinite(fc):
            failed.append(c)
            continue
        best = (c, payload_c)
        if fc == 0.0:
            return c, payload_c, 0.0
        if np.sign(fc) == np.sign(fb):
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
    return best[0], best[1], abs(b - a)


def _widest_gap(a: float, b: float, failed: list[float]) -> tuple[float, float]:
    """The midpoint and the length of the widest gap between consecutive points of ``a``, ``b``
    and the failed trial points ``failed`` (all strictly inside ``[a, b]``)."""
    pts = np.sort(np.array([a, b, *failed], dtype=float))
    gaps = np.diff(pts)
    i = int(np.argmax(gaps))
    return 0.5 * (pts[i] + pts[i + 1]), float(gaps[i])


def _secant_point(a: float, fa: float, b: float, fb: float, tol: float, close: bool) -> float:
    """The Illinois trial point of the bracket ``[a, b]``: the secant's zero, replaced by the
    midpoint within ``1e-3`` of the bracket's width from one of its ends (or, with ``close``,
    moved ``tol / 2`` past the estimate away from that end)."""
    if np.isfinite(fa) and np.isfinite(fb) and fb != fa:
        c = b - fb * (b - a) / (fb - fa)
    else:
        c = 0.5 * (a + b)
    # keep c strictly inside; fall back to bisection near the ends
    lo, hi = min(a, b), max(a, b)
    margin = 1e-3 * (hi - lo)
    if not (lo + margin < c < hi - margin):
        if close and lo <= c <= hi:
            c = min(max(c + 0.5 * tol, lo), hi) if c - lo < hi - c else \
                min(max(c - 0.5 * tol, lo), hi)
            if not (lo < c < hi):
                c = 0.5 * (a + b)
        else:
            c = 0.5 * (a + b)
    return c


def bisect_predicate(f: Callable[[float], tuple[Any, Any]], a: float, va: Any, b: float, vb: Any,
                     tol: float, max_iter: int = 80) -> tuple[float, Any, float, Any, Any]:
    """Bisection on a piecewise-constant function (``va != vb``) to bracket width ``tol``.

    Returns ``(sigma, payload, width, value_left, value_right)``: ``sigma`` is the right end of
    the final bracket (first point with the new value), its payload, the bracket width and the
    values on both sides.
    """
    payload_b = None
    for _ in range(max_iter):
        if abs(b - a) <= tol:
            break
        c = 0.5 * (a + b)
        vc, pc = f(c)
        if vc is None:
            break
        if vc == va:
            a, va = c, vc
        else:
            b, vb, payload_b = c, vc, pc
    return b, payload_b, abs(b - a), va, vb


def interior_extremum(s: np.ndarray, f: np.ndarray) -> float | None:
    """Vertex of the parabola through three ``(s, f)`` pairs if it lies in ``(s[1], s[2])`` and
    the parabola changes sign there (a double crossing hidden inside the last step)."""
    s0, s1, s2 = s
    f0, f1, f2 = f
    if not (np.isfinite(f).all() and s0 < s1 < s2):
        return None
    d01 = (f1 - f0) / (s1 - s0)
    d12 = (f2 - f1) / (s2 - s1)
    c2 = (d12 - d01) / (s2 - s0)
    if c2 == 0.0:
        return None
    c1 = d01 - c2 * (s0 + s1)
    sv = -c1 / (2.0 * c2)
    if not (s1 < sv < s2):
        return None
    fv = f1 + d01 * (sv - s1) + c2 * (sv - s0) * (sv - s1)
    if np.sign(fv) != np.sign(f1) and np.sign(fv) != np.sign(f2):
        return float(sv)
    return None


def pole_estimate(p: np.ndarray, q: np.ndarray, k_range: tuple[float, float] = (0.25, 4.0),
                  rtol: float = 0.02) -> dict[str, float] | None:
    """Where a positive quantity growing like ``q ~ C |p - p*|^(-k)`` becomes infinite, from its
    values at consecutive points of a branch (``p`` the parameter); None unless the values fit
    such a pole ahead of the last point.

    For such growth ``1 / (d ln q / dp) = (p* - p) / k`` is linear in ``p`` with slope
    ``-1 / k``: its secants over consecutive points must decrease in magnitude (an exponential
    or a power of ``p`` does not), and ``q^(-1/k)`` is linear in ``p``, vanishing at ``p*``: the
    lattice engine's extrapolation of ``E^(-1/2)`` to zero, with the exponent ``k`` chosen in
    ``k_range`` (strictly inside) to make ``q^(-1/k)`` most nearly linear instead of assumed.
    Accepted only if
    ``q`` increases while ``p`` moves monotonically towards ``p*`` and the linear fit has
    relative residual (to the range of ``q^(-1/k)``) below ``rtol``.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if len(p) < 4 or len(p) != len(q) or not (np.all(np.isfinite(p)) and np.all(q > 0)
                                              and np.all(np.isfinite(q))):
        return None
    dp, dl = np.diff(p), np.diff(np.log(q))
    direction = np.sign(dp[-1])
    if direction == 0 or not (np.all(np.sign(dp) == direction) and np.all(dl > 0)):
        return None
    # secant slope of 1 / (d ln q / dp) against p: -1/k < 0 for a pole
    g = dp / dl
    mid = 0.5 * (p[1:] + p[:-1])
    if not np.polyfit(mid - mid[-1], g, 1)[0] < 0:
        return None
    x = p - p[-1]
    ln_q = np.log(q / q[-1])

    def fit(k: float) -> tuple[float, float]:
        """Relative residual of the linear fit of (q / q[-1])^(-1/k), and its root - p[-1]."""
        z = np.exp(-ln_q / k)
        c1, c0 = np.polyfit(x, z, 1)
        err = float(np.max(np.abs(c0 + c1 * x - z)) / max(np.ptp(z), 1e-300))
        return err, (-c0 / c1 if c1 != 0 else np.nan)

    ks = np.geomspace(k_range[0], k_range[1], 161)
    i = int(np.argmin([fit(k)[0] for k in ks]))
    k = float(ks[i])
    if 0 < i < len(ks) - 1:  # refine between the grid neighbours (golden section)
        k = bounded_minimum(lambda v: fit(v)[0], ks[i - 1], ks[i + 1], xatol=1e-10 * k)[0]
    err, dist = fit(k)  # dist = p* - p[-1]
    at_edge = k <= k_range[0] * (1 + 1e-9) or k >= k_range[1] * (1 - 1e-9)
    if at_edge or not (err <= rtol and np.isfinite(dist) and np.sign(dist) == direction):
        return None
    return {"parameter_asymptote": float(p[-1] + dist), "exponent": k,
            "fit_residual": err}
