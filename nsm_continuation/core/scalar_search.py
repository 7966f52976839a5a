"""Brent's bounded minimisation of a function of one variable, without SciPy.

:func:`bounded_minimum` is the algorithm of ``scipy.optimize.minimize_scalar(method="bounded")``
(``fminbound``: golden section safeguarded by successive parabolic interpolation, Brent 1973,
*Algorithms for Minimization without Derivatives*, ch. 5), step for step, so its iterates and
result are those of SciPy's to the last bit (``tests/chain/test_scipy_replacements_equal_scipy.py``
compares them).
It is here because importing ``scipy.optimize`` costs 0.16 s, a tenth of the default case's
wall time (``benchmarks/bench_startup.py``), for one call per hidden Krein window.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

_SQRT_EPS = math.sqrt(2.2e-16)
_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))


def bounded_minimum(f: Callable[[float], float], lo: float, hi: float, xatol: float = 1e-5,
                    maxiter: int = 500) -> tuple[float, float, int]:
    """A local minimum of ``f`` on ``[lo, hi]`` to the absolute tolerance ``xatol`` (plus
    ``sqrt(eps) |x|``): ``(x, f(x), evaluations)``, at most ``maxiter`` evaluations.

    Brent's method: each step is the minimum of the parabola through the three best points
    when it falls inside the bracket and moves less than half the step before last, else a
    golden-section step into the larger part; no step is shorter than the tolerance. A ``nan``
    of ``f`` compares as not smaller, as in SciPy (callers map failures to ``inf``)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise ValueError(f"bounded_minimum: bounds [{lo}, {hi}] must be finite and ordered")
    a, b = lo, hi
    v = w = x = a + _GOLDEN * (b - a)  # v, w: the previous two best points
    e = d = 0.0  # the step before last, the last step
    fx = f(x)
    fv = fw = fx
    fu = np.inf
    n = 1
    xm = 0.5 * (a + b)
    tol1 = _SQRT_EPS * abs(x) + xatol / 3.0
    tol2 = 2.0 * tol1
    while abs(x - xm) > tol2 - 0.5 * (b - a):
        golden = True
        if abs(e) > tol1:  # try the parabola through (v, w, x)
            golden = False
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            r, e = e, d
            if abs(p) < abs(0.5 * q * r) and q * (a - x) < p < q * (b - x):
                d = (p + 0.0) / q
                u = x + d
                if (u - a) < tol2 or (b - u) < tol2:  # not closer than tol2 to an end
                    d = tol1 * (np.sign(xm - x) + ((xm - x) == 0))
            else:
                golden = True
        if golden:
            e = (a - x) if x >= xm else (b - x)
            d = _GOLDEN * e
        u = x + (np.sign(d) + (d == 0)) * max(abs(d), tol1)
        fu = f(u)
        n += 1
        if fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v, fv = w, fw
            w, fw = x, fx
            x, fx = u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv = w, fw
                w, fw = u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
        xm = 0.5 * (a + b)
        tol1 = _SQRT_EPS * abs(x) + xatol / 3.0
        tol2 = 2.0 * tol1
        if n >= maxiter:
            break
    return float(x), float(fx), n
