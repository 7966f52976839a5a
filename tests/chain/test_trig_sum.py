"""TrigSum: certified critical points and maximum of a finite sum of sinusoids.

Oracles (independent of :mod:`problems.chain.trig_sum`):

* ``f'`` is re-implemented (``oracles/trig_sum.py``) and its roots are found by a dense
  sign-change grid (at least 100 samples per radian of the highest frequency) refined by
  :func:`scipy.optimize.brentq`;
* (near-)double roots are built by construction (coefficients projected onto the subspace with
  ``f'(t*) = f''(t*) = 0``, or ``f'(t1) = f'(t2) = 0`` for two close points), so their location is
  known in closed form;
* the maximum is compared with a 200 001-point brute-force sampling (local maxima of the samples,
  polished by the vertex of the parabola through the three samples around the best one).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from nsm_continuation.problems.chain.trig_sum import TrigSum
from oracles.trig_sum import EPS, fprime, fvalue, grid_roots
from scipy.optimize import brentq


def assert_roots_match(found: np.ndarray, expected: np.ndarray, tol: float) -> None:
    assert found.size == expected.size, (found.size, expected.size)
    if found.size:
        err = np.max(np.abs(found - expected))
        assert err <= tol, err


def random_sum(seed: int):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 7))
    w = rng.uniform(0.2, 8.0, n)
    a, b = rng.normal(size=n), rng.normal(size=n)
    t0 = float(rng.uniform(-2.0, 2.0))
    t1 = t0 + float(rng.uniform(1.0, 12.0))
    return a, b, w, t0, t1


@pytest.mark.parametrize("seed", range(8))
def test_critical_points_random_sums(seed: int) -> None:
    a, b, w, t0, t1 = random_sum(seed)
    found = TrigSum(a, b, w).critical_points(t0, t1)
    expected = grid_roots(a, b, w, t0, t1)
    assert expected.size > 0 or np.max(w) * (t1 - t0) < np.pi  # the test is not vacuous
    assert_roots_match(found, expected, 1e-9)
    # and they are roots of f' (independent evaluation), to round-off
    scale = np.sum(w * (np.abs(a) + np.abs(b)))
    assert np.all(np.abs(fprime(a, b, w, found)) <= 1e-12 * scale)


@pytest.mark.parametrize("ripple", [2e-2, 1e-4])
def test_critical_points_widely_separated_frequencies(ripple: float) -> None:
    """Frequencies spread over four decades (0.013 .. 230): a slow drift plus a fast ripple whose
    slope either dominates ``f'`` (hundreds of roots) or does not (a few roots)."""
    w = np.array([0.013, 1.7, 230.0])
    a = np.array([5.0, 1.0, ripple])
    b = np.array([-3.0, 0.4, 0.5 * ripple])
    t0, t1 = 0.3, 6.3
    found = TrigSum(a, b, w).critical_points(t0, t1)
    expected = grid_roots(a, b, w, t0, t1)
    if ripple > 1e-3:
        assert expected.size > 300
    assert_roots_match(found, expected, 1e-9)


def _project(a, b, w, rows):
    """Coefficients closest to ``(a, b)`` satisfying the linear conditions ``rows @ c = 0``
    (orthogonal projection computed with a QR factorisation, stable for nearly parallel rows)."""
    c = np.concatenate([a, b])
    q, _ = np.linalg.qr(np.asarray(rows).T)
    c = c - q @ (q.T @ c)
    n = len(w)
    return c[:n], c[n:]


def _d1_row(w, t):
    return np.concatenate([-w * np.sin(w * t), w * np.cos(w * t)])


def _d2_row(w, t):
    return np.concatenate([-w**2 * np.cos(w * t), -w**2 * np.sin(w * t)])


@pytest.mark.parametrize("gap", [2e-6, 5e-7])
def test_critical_points_close_pair_of_roots(gap: float) -> None:
    """Two simple roots of ``f'`` ``gap`` apart (a near-tangential double root): both are found to
    1e-9 with every other root, and nothing else appears but candidates the certificate cannot
    rule out: points where ``|f'| <= L * min_width`` (``L`` = the bound on ``|f''|``; the module's
    stated resolution), never a flood of them."""
    rng = np.random.default_rng(11)
    w = np.array([1.0, 2.3, 4.1])
    ta, tb = 1.3, 1.3 + gap
    a, b = _project(rng.normal(size=3), rng.normal(size=3), w, [_d1_row(w, ta), _d1_row(w, tb)])
    # the construction really gives two simple roots: f' changes sign at ta and at tb
    probe = fprime(a, b, w, np.array([ta - gap / 2, 0.5 * (ta + tb), tb + gap / 2]))
    assert probe[0] * probe[1] < 0 and probe[1] * probe[2] < 0
    t0, t1 = 0.0, 8.0
    f = TrigSum(a, b, w)
    start = time.perf_counter()
    found = f.critical_points(t0, t1)
    elapsed = time.perf_counter() - start
    # the pair, located by brentq on the two brackets checked above (the construction's round-off
    # moves the roots off ta, tb by ~ |f'| eps / |f''| ~ 1e-10)
    pair = [brentq(lambda t: float(fprime(a, b, w, t)), lo, hi, xtol=1e-16, rtol=4 * EPS)
            for lo, hi in ((ta - gap / 2, 0.5 * (ta + tb)), (0.5 * (ta + tb), tb + gap / 2))]
    assert np.allclose(pair, [ta, tb], rtol=0, atol=1e-8)
    expected = np.sort(np.concatenate([grid_roots(a, b, w, t0, t1, skip=(ta - 1e-3, tb + 1e-3)),
                                       pair]))
    nearest = np.abs(found[None, :] - expected[:, None]).min(axis=1)
    assert np.max(nearest) <= 1e-9, nearest
    matched = np.abs(found[:, None] - expected[None, :]).min(axis=1) <= 1e-9
    extra = found[~matched]
    min_width = 1e-13 * (t1 - t0)
    assert np.all(np.abs(fprime(a, b, w, extra)) <= f.d2_bound * min_width), extra
    assert np.all((extra > ta - 1e-6) & (extra < tb + 1e-6))
    assert extra.size <= 64
    assert elapsed < 2.0


def test_critical_points_exact_double_root() -> None:
    """``f'(t*) = f''(t*) = 0``, ``f'''(t*) != 0``: ``f'`` touches 0 without changing sign (a
    horizontal inflection of ``f``). The brackets miss it by construction; the certified
    subdivision must report it (to round-off: ``|t - t*| <~ sqrt(eps)``), without a flood of
    candidates there (the first-order certificate alone leaves ~1e6 cells of width ``min_width``
    around a double root), and still find every simple root elsewhere.

    Duplicates inside the round-off band are tolerated (they do not change ``max_on``); the
    docstring's "the remaining candidate is taken at the point of smallest |f'|" would give one.
    """
    rng = np.random.default_rng(5)
    w = np.array([1.0, 2.3, 4.1])
    ts = 1.3
    a, b = _project(rng.normal(size=3), rng.normal(size=3), w, [_d1_row(w, ts), _d2_row(w, ts)])
    f3 = -np.sum(w**3 * (b * np.sin(w * ts) + a * np.cos(w * ts)))
    assert abs(f3) > 1.0  # a genuine double (not triple) root
    t0, t1 = 0.0, 8.0
    start = time.perf_counter()
    found = TrigSum(a, b, w).critical_points(t0, t1)
    elapsed = time.perf_counter() - start
    near = found[np.abs(found - ts) < 1e-3]
    assert 1 <= near.size <= 64, near.size
    assert np.max(np.abs(near - ts)) < 1e-6
    others = found[np.abs(found - ts) >= 1e-3]
    assert_roots_match(others, grid_roots(a, b, w, t0, t1, skip=(ts - 1e-3, ts + 1e-3)), 1e-9)
    assert elapsed < 2.0


def brute_force_interior_max(a, b, w, t0, t1, n=200_001):
    """Largest interior local maximum of ``n`` samples, polished by a parabola through the three
    samples around it (error O(h^3) instead of O(h^2))."""
    t = np.linspace(t0, t1, n)
    v = fvalue(a, b, w, t)
    interior = np.nonzero((v[1:-1] >= v[:-2]) & (v[1:-1] >= v[2:]))[0] + 1
    if interior.size == 0:
        return -np.inf, np.nan, np.nan, t[1] - t[0]
    i = interior[np.argmax(v[interior])]
    h = t[1] - t[0]
    fm, f0, fp = v[i - 1], v[i], v[i + 1]
    denom = fm - 2 * f0 + fp
    delta = 0.5 * (fm - fp) / denom if denom < 0 else 0.0
    polished = f0 - 0.25 * (fm - fp) * delta
    return float(v[i]), float(polished), float(t[i] + delta * h), h


@pytest.mark.parametrize("seed", range(8))
def test_max_on_agrees_with_brute_force(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(1, 6))
    w = rng.uniform(0.3, 6.0, n)
    a, b = rng.normal(size=n), rng.normal(size=n)
    t0 = float(rng.uniform(-1.0, 1.0))
    t1 = t0 + float(rng.uniform(2.0, 6.0))
    fmax, targ = TrigSum(a, b, w).max_on(t0, t1)
    raw, polished, t_brute, h = brute_force_interior_max(a, b, w, t0, t1)
    if not np.isfinite(raw):
        assert fmax == -np.inf
        return
    scale = np.sum(np.hypot(a, b))
    # exact critical-point maximum: never below a sampled local maximum ...
    assert fmax >= raw - 1e-13 * scale
    # ... and equal to the polished brute-force maximum to ~1e-9 relative
    assert abs(fmax - polished) <= 1e-9 * scale
    # the argmax is a root of f' with that value
    assert abs(fvalue(a, b, w, targ) - fmax) <= 1e-14 * scale
    assert abs(fprime(a, b, w, targ)) <= 1e-12 * np.sum(w * np.hypot(a, b))


def test_max_on_without_interior_critical_point() -> None:
    """``sin t`` on (0, 1) is increasing: no interior critical point, so ``max_on`` (a maximum
    over critical points only) is ``-inf``; on (0, 4) the only one is ``t = pi/2``."""
    f = TrigSum(np.array([0.0]), np.array([1.0]), np.array([1.0]))
    assert f.critical_points(0.0, 1.0).size == 0
    assert f.critical_points(1.0, 1.0).size == 0
    m, t = f.max_on(0.0, 1.0)
    assert m == -np.inf and np.isnan(t)
    m, t = f.max_on(0.0, 4.0)
    assert abs(t - np.pi / 2) < 1e-14 and abs(m - 1.0) < 1e-15


@pytest.mark.parametrize("seed", range(4))
def test_root_on_a_grid_edge_costs_no_bisection(seed: int) -> None:
    """A symmetric orbit ``f(t) = sum a_l cos(w_l (t - T/2))`` on ``(0, T)`` has a critical point
    at ``T / 2``, an edge of the first pass's grid when its cell count is even. ``f'`` vanishes
    there to rounding, so its sign (hence which cell brackets the root) is noise, and Newton
    from inside that cell overshoots the end every time: a safeguard bisecting towards it would
    gain one bit per evaluation (14-19 evaluations). The root is at ``T / 2`` exactly (closed
    form) and costs no iteration; every other root is located too (grid oracle)."""
    rng = np.random.default_rng(300 + seed)
    n = int(rng.integers(2, 6))
    w = np.sort(rng.uniform(0.5, 6.0, n))
    T = float(rng.uniform(3.0, 9.0))
    c = rng.normal(size=n)
    a, b = c * np.cos(w * T / 2), c * np.sin(w * T / 2)  # c cos(w (t - T/2))
    f = TrigSum(a, b, w)
    cells = int(max(16, np.ceil(T * np.max(w) * 2.0)))
    if cells % 2:  # an even grid: T/2 is an edge (the cell count grows with T)
        T *= (cells + 1) / cells
        a, b = c * np.cos(w * T / 2), c * np.sin(w * T / 2)
        f = TrigSum(a, b, w)
    calls: list[int] = []
    d12 = f.d12

    def counted(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        calls.append(np.size(t))
        return d12(t)

    f.d12 = counted  # type: ignore[method-assign]
    found = f.critical_points(0.0, T)
    assert np.min(np.abs(found - T / 2)) <= 4 * EPS * T
    assert_roots_match(found, grid_roots(a, b, w, 0.0, T), 1e-9)
    assert len(calls) <= 8, calls  # the end point (1) plus a few Newton steps, no bisection


def fthird(a: np.ndarray, b: np.ndarray, w: np.ndarray, t: float) -> float:
    """``f'''(t) = sum w^3 (a sin(w t) - b cos(w t))``, written independently of TrigSum."""
    return float(np.sum(w**3 * (a * np.sin(w * t) - b * np.cos(w * t))))


def fsecond(a: np.ndarray, b: np.ndarray, w: np.ndarray, t: float) -> float:
    return float(-np.sum(w**2 * (a * np.cos(w * t) + b * np.sin(w * t))))


@pytest.mark.parametrize("seed", range(6))
def test_rise_keeps_its_relative_accuracy_next_to_the_reference(seed: int) -> None:
    """``f(t) - f(r)`` (:meth:`TrigSum.rise`) against the Taylor polynomial of degree 3 at
    ``r`` (``f'``, ``f''``, ``f'''`` in closed form) for ``|t - r|`` down to 1e-12: relative
    error at the rounding level, where the difference of two values of ``f`` loses
    ``eps |f| / |f(t) - f(r)|`` (1e-4 relative at ``h = 1e-12``); and the plain difference
    where it is accurate (``h`` of order 1)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 30))
    a, b = rng.normal(size=n), rng.normal(size=n)
    w = np.sort(rng.uniform(0.3, 8.0, size=n))
    f = TrigSum(a, b, w)
    r = float(rng.uniform(0.0, 10.0))
    d1, d2, d3 = float(fprime(a, b, w, r)), fsecond(a, b, w, r), fthird(a, b, w, r)
    bound4 = float(np.sum(w**4 * np.hypot(a, b)))  # |f''''| <= this
    for h in (1e-3, 1e-5, 1e-7, 1e-9, 1e-12):
        for t in (r + h, r - h):
            s = t - r  # exact (Sterbenz): the step the rounded ``t`` really is
            taylor = d1 * s + d2 * s**2 / 2 + d3 * s**3 / 6
            rise = float(f.rise(np.array([t]), r)[0])
            assert abs(rise - taylor) <= bound4 * h**4 / 24 + 1e-13 * abs(taylor) + 1e-30
    t = rng.uniform(0.0, 10.0, size=20)
    direct = fvalue(a, b, w, t) - fvalue(a, b, w, r)
    np.testing.assert_allclose(f.rise(t, r), direct, rtol=0,
                               atol=1e-13 * float(np.sum(np.hypot(a, b))))
