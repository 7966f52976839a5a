"""A finite sum of sinusoids ``f(t) = sum_j a_j cos(w_j t) + b_j sin(w_j t)`` written without
:mod:`problems.chain.trig_sum`: its value and first two derivatives, and the roots of ``f'`` by
a dense sign-change grid refined by :func:`scipy.optimize.brentq`. Shared by the tests of
``TrigSum`` (its critical points and maximum, on both of its paths)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

EPS = np.finfo(float).eps


def fprime(a: np.ndarray, b: np.ndarray, w: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """``f'(t)`` written independently of TrigSum."""
    t = np.asarray(t, dtype=float)
    wt = np.multiply.outer(t, w)
    return np.sum(w * (b * np.cos(wt) - a * np.sin(wt)), axis=-1)


def fsecond(a: np.ndarray, b: np.ndarray, w: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """``f''(t)``."""
    t = np.asarray(t, dtype=float)
    wt = np.multiply.outer(t, w)
    return -np.sum(w**2 * (a * np.cos(wt) + b * np.sin(wt)), axis=-1)


def fvalue(a: np.ndarray, b: np.ndarray, w: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """``f(t)``."""
    t = np.asarray(t, dtype=float)
    wt = np.multiply.outer(t, w)
    return np.sum(a * np.cos(wt) + b * np.sin(wt), axis=-1)


def grid_roots(a, b, w, t0, t1, per_radian=100.0, skip=None):
    """Roots of ``f'`` in ``(t0, t1)`` by a dense sign-change grid (at least ``per_radian``
    samples per radian of the highest frequency) + brentq.

    ``skip = (lo, hi)``: a sub-interval left out of the grid (handled by construction).
    """
    n = int(np.ceil((t1 - t0) * np.max(w) * per_radian)) + 2000
    grid = np.linspace(t0, t1, n)
    vals = fprime(a, b, w, grid)
    roots = [float(grid[i]) for i in range(1, n - 1) if vals[i] == 0.0]
    for i in np.nonzero(vals[:-1] * vals[1:] < 0)[0]:
        lo, hi = grid[i], grid[i + 1]
        if skip is not None and hi > skip[0] and lo < skip[1]:
            continue
        roots.append(brentq(lambda t: float(fprime(a, b, w, t)), lo, hi, xtol=1e-15,
                            rtol=4 * EPS))
    return np.sort(np.array(roots))
