"""The small-sum path of :meth:`TrigSum.critical_points` (what keeps the frequency-energy plot
of Fig. 3.2 under 3 s): a pointwise first pass and, after it, the Newton iteration and the
subdivision on Python floats.

Oracles, independent of the code under test:

* ``f'`` and ``f''`` re-implemented (``oracles/trig_sum.py``); the roots of ``f'`` by a dense
  sign-change grid (at least 200 samples per radian of the highest frequency) refined by
  :func:`scipy.optimize.brentq`; a double root built by construction (coefficients projected
  onto ``f'(t*) = f''(t*) = 0``); ``T / 2`` of a symmetric orbit known in closed form;
* the maximum of ``u_c`` of the chain's closed-form orbits by 200 001 samples polished by a
  parabola.

And the vectorised path (the large sums' path),
forced by setting the thresholds to 0: both give the same roots to the rounding of ``f'``
(within the Newton iteration's own acceptance band ``noise / |f''|``), the same number of them,
and the same maxima to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.chain import trig_sum
from nsm_continuation.problems.chain.trig_sum import TrigSum
from oracles.trig_sum import EPS, fprime, fsecond, fvalue, grid_roots

from nsm_continuation import api


@pytest.fixture
def vectorised(monkeypatch: pytest.MonkeyPatch):
    """Run :meth:`TrigSum.critical_points` on the vectorised (large-sum) path."""
    def use(flag: bool) -> None:
        monkeypatch.setattr(trig_sum, "SCALAR_MODES", -1 if flag else 16)
        monkeypatch.setattr(trig_sum, "POINTWISE_GRID", -1 if flag else 512)
    return use


def both_paths(vectorised, a, b, w, t0, t1) -> tuple[np.ndarray, np.ndarray]:
    vectorised(False)
    fast = TrigSum(a, b, w).critical_points(t0, t1)
    vectorised(True)
    slow = TrigSum(a, b, w).critical_points(t0, t1)
    vectorised(False)
    return fast, slow


def acceptance_band(a, b, w, t: np.ndarray) -> np.ndarray:
    """Where Newton may stop around a simple root ``t`` of ``f'``: ``|f'| <= noise0 + noise1
    |t|`` (the module's rounding bound of ``f'``) over ``|f''|``, plus a few ulps."""
    amp = np.abs(a) + np.abs(b)
    noise = 4 * EPS * (np.sum(w * amp) + np.sum(w**2 * amp) * np.abs(t))
    return noise / np.maximum(np.abs(fsecond(a, b, w, t)), 1e-300) + 16 * EPS * np.abs(t)


def random_sum(rng: np.random.Generator, n_max: int = 8):
    n = int(rng.integers(1, n_max + 1))
    w = rng.uniform(0.2, 10.0, n)
    a, b = rng.normal(size=n), rng.normal(size=n)
    t0 = float(rng.uniform(-2.0, 2.0))
    t1 = t0 + float(rng.uniform(0.3, 6.0))
    return a, b, w, t0, t1


@pytest.mark.parametrize("seed", range(24))
def test_small_path_finds_the_oracle_roots(seed: int) -> None:
    """Random sums of 1-8 sinusoids on short windows (the scalar path): every root of the
    grid oracle to 1e-10 and nothing else; each is a root of ``f'`` to rounding."""
    rng = np.random.default_rng(7000 + seed)
    a, b, w, t0, t1 = random_sum(rng)
    found = TrigSum(a, b, w).critical_points(t0, t1)
    expected = grid_roots(a, b, w, t0, t1, per_radian=200.0)
    assert found.size == expected.size, (found, expected)
    if found.size:
        assert np.max(np.abs(found - expected)) <= 1e-10
        scale = np.sum(w * (np.abs(a) + np.abs(b))) * (1 + np.max(w) * max(abs(t0), abs(t1)))
        assert np.all(np.abs(fprime(a, b, w, found)) <= 1e-13 * scale)
    assert np.all(np.diff(found) > 0) and np.all((found > t0) & (found < t1))


@pytest.mark.parametrize("seed", range(60))
def test_small_path_equals_the_vectorised_path(vectorised, seed: int) -> None:
    """The scalar path and the vectorised one: the same roots (count, and each within the
    Newton iteration's acceptance band of the other), the same maximum to rounding. Windows
    from short (a few brackets: scalar Newton) to long (many: the vectorised fallback)."""
    rng = np.random.default_rng(8000 + seed)
    a, b, w, t0, t1 = random_sum(rng, n_max=16)
    if seed % 3 == 0:
        t1 = t0 + float(rng.uniform(6.0, 30.0))
    fast, slow = both_paths(vectorised, a, b, w, t0, t1)
    assert fast.size == slow.size, (fast, slow)
    if fast.size:
        assert np.all(np.abs(fast - slow) <= acceptance_band(a, b, w, slow)), fast - slow
        vf, vs = fvalue(a, b, w, fast), fvalue(a, b, w, slow)
        assert abs(vf.max() - vs.max()) <= 64 * EPS * np.sum(np.abs(a) + np.abs(b))


def test_small_path_exact_double_root_and_edge_cases(vectorised) -> None:
    """A double root of ``f'`` (``f' = f'' = 0`` at ``t*``: no sign change, found by the
    subdivision), a root at the window's ends (excluded: open interval), an empty window,
    a single mode, no root at all: both paths agree, the double root within sqrt(eps)."""
    rng = np.random.default_rng(5)
    w = np.array([1.0, 2.3, 4.1])
    ts = 1.3
    rows = np.array([np.concatenate([-w * np.sin(w * ts), w * np.cos(w * ts)]),
                     np.concatenate([-w**2 * np.cos(w * ts), -w**2 * np.sin(w * ts)])])
    c = np.concatenate([rng.normal(size=3), rng.normal(size=3)])
    q, _ = np.linalg.qr(rows.T)
    c = c - q @ (q.T @ c)
    a, b = c[:3], c[3:]
    fast, slow = both_paths(vectorised, a, b, w, 0.0, 4.0)
    for found in (fast, slow):
        near = found[np.abs(found - ts) < 1e-3]
        assert 1 <= near.size <= 64 and np.max(np.abs(near - ts)) < 1e-6
        others = found[np.abs(found - ts) >= 1e-3]
        exp = grid_roots(a, b, w, 0.0, 4.0, per_radian=200.0)
        exp = exp[np.abs(exp - ts) >= 1e-3]
        assert others.size == exp.size and np.max(np.abs(others - exp), initial=0) < 1e-10
    # sin t: roots of f' at pi/2 + k pi; the window (pi/2, 5 pi/2) excludes its ends
    one = (np.array([0.0]), np.array([1.0]), np.array([1.0]))
    fast, slow = both_paths(vectorised, *one, np.pi / 2, 5 * np.pi / 2)
    assert fast.size == slow.size == 1 and abs(fast[0] - 1.5 * np.pi) < 1e-14
    for t0, t1 in ((1.0, 1.0), (2.0, 1.0)):
        assert TrigSum(*one).critical_points(t0, t1).size == 0
    fast, slow = both_paths(vectorised, *one, 0.0, 1.0)
    assert fast.size == slow.size == 0
    assert TrigSum(*one).max_on(0.0, 1.0)[0] == -np.inf


@pytest.mark.parametrize("seed", range(6))
def test_small_path_symmetric_orbit_root_on_a_grid_edge(seed: int) -> None:
    """``f(t) = sum c_l cos(w_l (t - T/2))`` with ``T/2`` an edge of the first pass's grid:
    ``f'(T/2)`` is rounding noise; the root is reported at ``T/2`` (once) with the others."""
    rng = np.random.default_rng(300 + seed)
    n = int(rng.integers(2, 6))
    w = np.sort(rng.uniform(0.5, 6.0, n))
    T = float(rng.uniform(3.0, 9.0))
    cells = int(max(16, np.ceil(T * np.max(w) * 2.0)))
    if cells % 2:
        T *= (cells + 1) / cells
    c = rng.normal(size=n)
    a, b = c * np.cos(w * T / 2), c * np.sin(w * T / 2)
    found = TrigSum(a, b, w).critical_points(0.0, T)
    assert np.min(np.abs(found - T / 2)) <= 4 * EPS * T
    expected = grid_roots(a, b, w, 0.0, T, per_radian=200.0)
    assert found.size == expected.size and np.max(np.abs(found - expected)) <= 1e-9


def test_scalar_evaluation_equals_d12() -> None:
    """``_scalar_d12`` (Python floats) is :meth:`TrigSum.d12` to rounding."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        n = int(rng.integers(1, 17))
        f = TrigSum(rng.normal(size=n), rng.normal(size=n), rng.uniform(0.1, 12.0, n))
        terms = f._scalar_terms()
        t = rng.uniform(-20.0, 20.0, 7)
        d1, d2 = f.d12(t)
        s = np.array([TrigSum._scalar_d12(terms, float(x)) for x in t])
        amp = np.abs(f.a) + np.abs(f.b)
        bound1 = 4 * EPS * (np.sum(f.w * amp) + np.sum(f.w**2 * amp) * np.abs(t))
        bound2 = 4 * EPS * (np.sum(f.w**2 * amp) + np.sum(f.w**3 * amp) * np.abs(t))
        assert np.all(np.abs(s[:, 0] - d1) <= bound1)
        assert np.all(np.abs(s[:, 1] - d2) <= bound2)


def test_large_sums_keep_the_vectorised_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """More than ``SCALAR_MODES`` modes (the N = 200..1000 chains): the scalar path is never
    entered, and the first pass is the matrix product of :meth:`TrigSum.d12_grid`."""
    def fail(*args, **kwargs):
        raise AssertionError("scalar path used for a large sum")

    monkeypatch.setattr(TrigSum, "_critical_points_scalar", fail)
    grids: list[int] = []
    d12_grid = TrigSum.d12_grid

    def counted(self, t0, h, n, block=64):
        grids.append(n)
        return d12_grid(self, t0, h, n, block)

    monkeypatch.setattr(TrigSum, "d12_grid", counted)
    rng = np.random.default_rng(3)
    n = trig_sum.SCALAR_MODES + 1
    a, b, w = rng.normal(size=n), rng.normal(size=n), np.sort(rng.uniform(0.5, 8.0, n))
    found = TrigSum(a, b, w).critical_points(0.0, 4.0)
    assert grids
    expected = grid_roots(a, b, w, 0.0, 4.0, per_radian=200.0)
    assert found.size == expected.size and np.max(np.abs(found - expected)) <= 1e-10


def _chain_points():
    """Closed-form orbits of the Fig. 3.2 chain (5 dofs) over the whole window, with their
    problem: ``u_c`` on ``(0, T)`` is the admissibility test's sum of sinusoids."""
    p = api.problem("ndof_impact", {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0},
                                    "gap": 1.0})
    out = []
    for T in np.linspace(0.58, 4.8, 97):
        u0, du0 = p.closed_form(float(T))
        if np.all(np.isfinite(u0)) and np.isfinite(du0).all() and np.max(np.abs(u0)) < 1e3:
            out.append(p.y_from_state(u0, du0, float(T)))
    return p, out


def test_chain_admissibility_matches_brute_force_and_the_vectorised_path(vectorised) -> None:
    """The 5-dof chain's admissibility along its closed-form orbits: the clearance (exact
    maximum of ``u_c`` over ``(0, T)``) equals the sampled and polished maximum to 1e-8, and
    the vectorised path's to rounding (1e-14 of the amplitude)."""
    p, ys = _chain_points()
    assert len(ys) > 60
    n_checked = 0
    for y in ys:
        vectorised(False)
        fast = p.admissibility(y)
        vectorised(True)
        slow = p.admissibility(y)
        vectorised(False)
        assert fast.keys() == slow.keys()
        if not fast:
            continue
        f = p.displacement_sum(y)
        T = float(y[-1])
        amp = float(np.sum(np.hypot(f.a, f.b)))
        assert fast["outgoing_velocity"] == slow["outgoing_velocity"]
        assert abs(fast["clearance"] - slow["clearance"]) <= 1e-14 * max(amp, 1.0)
        t = np.linspace(0.0, T, 200_001)
        v = fvalue(f.a, f.b, f.w, t)
        inner = np.nonzero((v[1:-1] >= v[:-2]) & (v[1:-1] >= v[2:]))[0] + 1
        if inner.size:
            i = inner[np.argmax(v[inner])]
            fm, f0, fp = v[i - 1], v[i], v[i + 1]
            den = fm - 2 * f0 + fp
            peak = f0 - 0.125 * (fm - fp) ** 2 / den if den < 0 else f0
            assert abs((p.g - peak) / abs(p.g) - fast["clearance"]) <= 1e-8 * max(amp, 1.0)
            n_checked += 1
    assert n_checked > 60


def _double_root_sum(rng: np.random.Generator, ts: float, n: int = 4):
    """Coefficients with ``f'(ts) = f''(ts) = 0`` (projected onto that subspace)."""
    w = np.sort(rng.uniform(0.5, 6.0, n))
    rows = np.array([np.concatenate([-w * np.sin(w * ts), w * np.cos(w * ts)]),
                     np.concatenate([-w**2 * np.cos(w * ts), -w**2 * np.sin(w * ts)])])
    c = rng.normal(size=2 * n)
    q, _ = np.linalg.qr(rows.T)
    c = c - q @ (q.T @ c)
    return c[:n], c[n:], w


@pytest.mark.parametrize("seed", range(12))
def test_small_path_double_roots_anywhere_in_a_cell(vectorised, seed: int) -> None:
    """A double root of ``f'`` at a random place of the first pass's grid: ``f'`` has no sign
    change there, so only the certificates can leave its cell open; the subdivision reports
    it (within sqrt(eps)), as the vectorised path does, and every simple root as the oracle."""
    rng = np.random.default_rng(900 + seed)
    for _ in range(100):  # a clean double root: the third derivative away from 0, else redrawn
        ts = float(rng.uniform(0.5, 3.5))
        a, b, w = _double_root_sum(rng, ts)
        f3 = -np.sum(w**3 * (b * np.sin(w * ts) + a * np.cos(w * ts)))
        if abs(f3) >= 0.1:
            break
    assert abs(f3) >= 0.1
    fast, slow = both_paths(vectorised, a, b, w, 0.0, 4.0)
    for found in (fast, slow):
        near = found[np.abs(found - ts) < 1e-3]
        assert 1 <= near.size <= 64, (near, found)
        assert np.max(np.abs(near - ts)) < 1e-6
        exp = grid_roots(a, b, w, 0.0, 4.0, per_radian=200.0)
        exp = exp[np.abs(exp - ts) >= 1e-3]
        others = found[np.abs(found - ts) >= 1e-3]
        assert others.size == exp.size and np.max(np.abs(others - exp), initial=0) < 1e-10


@pytest.mark.parametrize("lo, hi", [(-0.5, 3.1), (-3.0, 0.4), (-1.4, 3.0), (0.5, 3.3)])
def test_scalar_newton_stays_in_its_bracket(lo: float, hi: float) -> None:
    """Wide brackets of ``f' = sin t`` (``f = -cos t``) around its root 0 (or pi) where the
    Newton step from the midpoint leaves the bracket: the safeguard keeps the iteration in
    it; the root is the one inside, as the vectorised iteration's."""
    f = TrigSum(np.array([-1.0]), np.array([0.0]), np.array([1.0]))
    flo, fhi = np.sin(lo), np.sin(hi)
    root = 0.0 if lo < 0.0 < hi else np.pi
    t = TrigSum._scalar_newton(f._scalar_terms(), f._noise(), lo, hi, float(flo), float(fhi))
    assert lo <= t <= hi and abs(t - root) <= 4 * EPS * max(1.0, root)
    v = f._bracketed_roots(np.array([lo]), np.array([hi]), np.array([flo]), np.array([fhi]))
    assert abs(t - v[0]) <= 4 * EPS * max(1.0, root)


def test_scalar_newton_with_a_vanishing_derivative_bisects() -> None:
    """``f'' = 0`` at an iterate (numpy's ``f / 0``: an infinite step): the safeguard bisects.
    Mode data that make ``f'' = 0`` everywhere with ``f' = cos t`` (not a trigonometric sum,
    only the iteration's arithmetic): the root ``pi/2`` of ``[1, 2]`` by bisection."""
    terms = [(1.0, 1.0, 0.0, 0.0, 0.0)]
    assert TrigSum._scalar_d12(terms, 1.3)[1] == 0.0
    t = TrigSum._scalar_newton(terms, (0.0, 0.0), 1.0, 2.0, float(np.cos(1.0)),
                               float(np.cos(2.0)))
    assert 1.0 <= t <= 2.0 and abs(t - np.pi / 2) <= 16 * EPS
