"""The small-spectrum paths of the Krein step control's distances (what keeps the
frequency-energy plot of Fig. 3.2 under 3 s): :func:`collision_distances` and
:func:`definite_sign` on Python lists up to ``_SMALL_SPECTRUM`` multipliers, and
:func:`nearest_distances`' one-shot dense formula.

Oracles, independent of the code under test:

* the definitions computed densely here: the on-circle test and the definite signature; the
  chord ``2 sin(|phi_i - phi_j| / 2)`` (angles wrapped with ``numpy.mod``) to every multiplier
  of the other signature; ``|m_i - m_j|`` over all pairs; the partner ``|m - 1/conj(m)|``;
* the large-spectrum path (the one large spectra take, forced by setting
  ``_SMALL_SPECTRUM`` to 0): *exactly* equal, the small path computing the same numbers by the
  same numpy formulas (only the bookkeeping moved to Python lists).

Inputs: random sets with the edge cases of a symplectic spectrum: multipliers exactly at +1
and -1 with both signatures, empty sets, one signature only, off-circle pairs ``lambda,
1/conj(lambda)`` and 0, indefinite signatures, duplicated and clustered values, sizes around
the threshold.
"""

from __future__ import annotations

import numpy as np
import pytest

from nsm_continuation.core.floquet import (
    KREIN_DEFINITE,
    collision_distances,
    definite_sign,
    nearest_distances,
)
from nsm_continuation.core.floquet import krein as krein_geometry


# ---------------------------------------------------------------- oracles
def sign_oracle(m: np.ndarray, krein: np.ndarray, tol: float) -> np.ndarray:
    out = np.zeros(len(m))
    for i, (z, k) in enumerate(zip(m, krein, strict=True)):
        if abs(abs(complex(z)) - 1.0) <= tol and abs(k) >= KREIN_DEFINITE:
            out[i] = 1.0 if k > 0 else -1.0
    return out


def collision_oracle(m: np.ndarray, krein: np.ndarray | None, tol: float) -> np.ndarray:
    m = np.asarray(m, dtype=complex)
    if krein is None:
        return np.zeros(m.size)
    s = sign_oracle(m, np.asarray(krein, dtype=float), tol)
    on = np.abs(np.abs(m) - 1.0) <= tol
    out = np.full(m.size, np.inf)
    phi = np.angle(m)
    dist = np.abs(m[:, None] - m[None, :])
    for i in range(m.size):
        cands = [out[i]]
        if s[i] != 0:
            for j in range(m.size):
                if s[j] == -s[i]:
                    d = np.mod(phi[i] - phi[j] + np.pi, 2 * np.pi) - np.pi
                    cands.append(2.0 * np.sin(0.5 * abs(d)))
        for j in range(m.size):
            if j != i and (s[j] == 0 or s[i] == 0):
                cands.append(dist[i, j])
        if not on[i]:
            with np.errstate(divide="ignore", invalid="ignore"):
                cands.append(abs(m[i] - 1.0 / np.conj(m[i])))
        out[i] = min(cands)
        if on[i] and s[i] == 0:
            out[i] = 0.0
    return out


def spectrum(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``2 n`` multipliers closed under conjugation (``kappa(conj) = -kappa``), with the
    edge cases mixed in."""
    ang = rng.uniform(0.0, np.pi, n)
    r = 1.0 + rng.choice([0.0, 0.0, 1e-12, 1e-9, 1e-3, 0.3], n) * rng.standard_normal(n)
    m = r * np.exp(1j * ang)
    k = rng.choice([-1.0, 1.0, 0.4, -0.7, 1e-8, -3e-7, KREIN_DEFINITE, -KREIN_DEFINITE,
                    0.999 * KREIN_DEFINITE, 1.5 * KREIN_DEFINITE], n)
    special = rng.random(n)
    m[special < 0.08] = 1.0
    m[(special >= 0.08) & (special < 0.16)] = -1.0
    if n > 2 and rng.random() < 0.5:  # a duplicated and a clustered value
        m[1] = m[0]
        m[2] = m[0] * (1 + 1e-15)
    return np.concatenate([m, np.conj(m)]), np.concatenate([k, -k])


def edge_cases() -> list[tuple[np.ndarray, np.ndarray | None, float]]:
    e = np.exp(1j * np.array([0.3, 1.1, 2.0]))
    return [
        (np.array([], dtype=complex), np.array([]), 1e-7),
        (np.array([1.0 + 0j]), np.array([0.5]), 1e-7),
        (np.array([1.0 + 0j, 1.0 + 0j]), np.array([0.5, -0.5]), 1e-7),      # collision at +1
        (np.array([-1.0 + 0j, -1.0 + 0j]), np.array([0.5, -0.5]), 1e-7),    # ... at -1
        (np.array([-1.0 + 0j, 1.0 + 0j]), np.array([1.0, 1.0]), 1e-7),      # one signature
        (np.concatenate([e, np.conj(e)]), np.ones(6), 1e-7),                # one signature
        (np.concatenate([e, np.conj(e)]), np.array([1, 1, 1, -1, -1, -1.0]), 1e-7),
        (np.concatenate([e, np.conj(e)]), np.full(6, 1e-9), 1e-7),          # all indefinite
        (np.array([1.3, 1 / 1.3, -2.0, -0.5]) + 0j, np.zeros(4), 1e-7),      # all off, real
        (np.array([0.0, 1.0, -1.0]) + 0j, np.array([0.0, 1.0, -1.0]), 1e-7),  # a zero one
        (np.array([1.2j, 1 / 1.2j, 1.0]), np.array([0.0, 0.0, 1.0]), 1e-7),
        (e, None, 1e-7),
        (np.full(5, np.exp(0.4j)), np.array([1.0, -1.0, 1.0, 1e-9, -1.0]), 1e-7),  # cluster
    ]


@pytest.fixture
def large_path(monkeypatch: pytest.MonkeyPatch):
    def use(flag: bool) -> None:
        monkeypatch.setattr(krein_geometry, "_SMALL_SPECTRUM", -1 if flag else 24)
    return use


def both(large_path, fn, *args):
    large_path(False)
    small = fn(*args)
    large_path(True)
    large = fn(*args)
    large_path(False)
    return small, large


# ---------------------------------------------------------------- collision distances
@pytest.mark.parametrize("case", range(len(edge_cases())))
def test_collision_distances_edge_cases(large_path, case: int) -> None:
    m, k, tol = edge_cases()[case]
    small, large = both(large_path, collision_distances, m, k, tol)
    np.testing.assert_array_equal(small, large)
    np.testing.assert_allclose(small, collision_oracle(m, k, tol), rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("seed", range(80))
def test_collision_distances_small_spectra(large_path, seed: int) -> None:
    """Random spectra of 2 to 30 multipliers (both sides of the threshold): the small path is
    the large one exactly, and both are the dense definition to rounding."""
    rng = np.random.default_rng(4000 + seed)
    m, k = spectrum(rng, int(rng.integers(1, 16)))
    if seed % 7 == 3:  # an odd number of multipliers
        m, k = m[:-1], k[:-1]
    tol = float(rng.choice([1e-10, 1e-7, 1e-3]))
    small, large = both(large_path, collision_distances, m, k, tol)
    np.testing.assert_array_equal(small, large)
    np.testing.assert_allclose(small, collision_oracle(m, k, tol), rtol=1e-13, atol=1e-15)


@pytest.mark.filterwarnings("ignore:invalid value encountered")
def test_collision_distances_non_finite_and_list_inputs(large_path) -> None:
    """A non-finite multiplier (the small path hands over to the large one) and inputs given
    as lists: the large path's values."""
    m = np.array([np.inf + 0j, np.exp(0.3j), np.exp(-0.3j), 1.5])
    k = np.array([0.0, 1.0, -1.0, 0.0])
    small, large = both(large_path, collision_distances, m, k, 1e-7)
    np.testing.assert_array_equal(small, large)
    small, large = both(large_path, collision_distances, list(m[1:]), list(k[1:]), 1e-7)
    np.testing.assert_array_equal(small, large)


# ---------------------------------------------------------------- definite sign
@pytest.mark.parametrize("seed", range(30))
def test_definite_sign_small_and_large(large_path, seed: int) -> None:
    rng = np.random.default_rng(5000 + seed)
    m, k = spectrum(rng, int(rng.integers(1, 16)))
    tol = float(rng.choice([1e-10, 1e-7, 1e-3]))
    small, large = both(large_path, definite_sign, m, k, tol)
    np.testing.assert_array_equal(small, large)
    np.testing.assert_array_equal(small, sign_oracle(m, k, tol))
    assert small.dtype == large.dtype and small.shape == large.shape
    # krein broadcast from a scalar: the large path's rule
    small, large = both(large_path, definite_sign, m, 0.5, tol)
    np.testing.assert_array_equal(small, large)
    e = both(large_path, definite_sign, np.array([], dtype=complex), np.array([]), tol)
    assert e[0].shape == e[1].shape == (0,)


# ---------------------------------------------------------------- nearest distances
@pytest.mark.parametrize("seed", range(30))
def test_nearest_distances_small_inputs(seed: int) -> None:
    """Small sets (the one-shot dense formula) with and without excluded indices, duplicates,
    and empty sets: exactly the dense minimum."""
    rng = np.random.default_rng(6000 + seed)
    n, p = int(rng.integers(0, 12)), int(rng.integers(0, 12))
    pts = np.exp(1j * rng.uniform(-np.pi, np.pi, p)) * (1 + 1e-3 * rng.standard_normal(p))
    x = np.exp(1j * rng.uniform(-np.pi, np.pi, n))
    q = min(n, p)
    x[:q // 2] = pts[:q // 2]  # duplicates of points
    excl = np.where(rng.random(n) < 0.5, rng.integers(0, max(p, 1), n), -1) if p else None
    if p == 0:
        assert np.all(np.isinf(nearest_distances(x, pts))) and nearest_distances(
            x, pts).shape == (n,)
        return
    d = np.abs(x[:, None] - pts[None, :])
    assert np.array_equal(nearest_distances(x, pts), d.min(axis=1, initial=np.inf))
    for i in range(n):
        if excl[i] >= 0:
            d[i, excl[i]] = np.inf
    assert np.array_equal(nearest_distances(x, pts, exclude=excl),
                          d.min(axis=1, initial=np.inf))
    # as lists, and with a NaN (propagated, as by the dense formula)
    assert np.array_equal(nearest_distances(list(x), list(pts)),
                          np.abs(x[:, None] - pts[None, :]).min(axis=1, initial=np.inf))
    if n:
        xn = x.copy()
        xn[0] = np.nan
        assert np.isnan(nearest_distances(xn, pts)[0])
