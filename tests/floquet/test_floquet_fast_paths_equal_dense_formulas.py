"""The fast paths of the multipliers and of the Krein step control give the values of the
direct formulas (the fast paths keep a point of the N = 1000 chain under 0.1 s).

Oracles, independent of the code under test:

* the dense ``O(n m)`` formulas the fast paths replace, kept here as private references:
  :func:`_krein_motion_reference` (the full distance matrix of
  :func:`nsm_continuation.core.palc.krein_motion`), :func:`_collision_distances_reference` and
  :func:`_krein_definiteness_reference` (the two-pass formula of
  :func:`nsm_continuation.core.floquet.krein_definiteness`);
* the dense eigenvalues of ``diag(mu) + X Y^T`` (``numpy.linalg.eigvals``) and of the chain's
  return map (:meth:`NDofImpactProblem.floquet_dense`);
* the nearest pole by the minimum over all poles.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import msd
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from oracles.scaled_chain import closed_form_point, scaled_chain

from nsm_continuation.core.floquet import (
    collision_distances,
    definite_sign,
    krein_definiteness,
    krein_of,
    low_rank_update_eigen,
    nearest_distances,
)
from nsm_continuation.core.floquet.secular import _Poles
from nsm_continuation.core.palc import krein_motion, krein_motion_ratio


# ---------------------------------------------------------------- references (dense)
def _collision_distances_reference(mult: np.ndarray, krein: np.ndarray | None,
                                   circle_tol: float) -> np.ndarray:
    m = np.asarray(mult, dtype=complex)
    if krein is None or m.size == 0:
        return np.zeros(m.size)
    sign = definite_sign(m, krein, circle_tol)
    out = np.full(m.size, np.inf)
    for sgn in (1.0, -1.0):  # every pair of opposite signature: the smallest angle between
        mine, other = np.nonzero(sign == sgn)[0], np.nonzero(sign == -sgn)[0]
        if mine.size and other.size:
            diff = np.angle(m[mine])[:, None] - np.angle(m[other])[None, :]
            out[mine] = 2.0 * np.sin(0.5 * np.abs(np.angle(np.exp(1j * diff))).min(axis=1))
    loose = np.nonzero(sign == 0)[0]
    if loose.size:
        d = np.abs(m[:, None] - m[None, loose])
        d[loose, np.arange(loose.size)] = np.inf
        out = np.minimum(out, d.min(axis=1))
        out[loose] = np.minimum(out[loose], np.abs(m[loose, None] - m[None, :]).min(
            axis=1, initial=np.inf, where=~np.eye(m.size, dtype=bool)[loose]))
    on_circle = np.abs(np.abs(m) - 1.0) <= circle_tol
    for i in range(m.size):  # off the circle: its partner 1/conj(lambda) too; on it and
        if not on_circle[i]:  # of no definite signature: 0
            out[i] = min(out[i], abs(m[i] - 1.0 / np.conj(m[i])))
        elif sign[i] == 0:
            out[i] = 0.0
    return out


def _reference_displacements(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                             krein_b: np.ndarray, circle_tol: float, lo: float = 0.5,
                             hi: float = 2.0) -> list[tuple[np.ndarray, np.ndarray]]:
    distances = (_collision_distances_reference(a, krein_a, circle_tol),
                 _collision_distances_reference(b, krein_b, circle_tol))
    out = []
    sa, sb = definite_sign(a, krein_a, circle_tol), definite_sign(b, krein_b, circle_tol)
    full = np.abs(a[:, None] - b[None, :])
    for d_all, sx, sz, x, cx in ((full, sa, sb, a, distances[0]),
                                 (full.T, sb, sa, b, distances[1])):
        watch = (np.abs(x) > lo) & (np.abs(x) < hi)
        if not watch.any():
            continue
        d = d_all[watch]
        other = (sx[watch][:, None] * sz[None, :]) < 0
        disp = np.where(other, np.inf, d).min(axis=1)
        out.append((np.where(np.isfinite(disp), disp, d.min(axis=1)), cx[watch]))
    return out


def _krein_motion_reference(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                            krein_b: np.ndarray, circle_tol: float, fraction: float) -> float:
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    motion = 0.0
    for disp, cx in _reference_displacements(a, krein_a, b, krein_b, circle_tol):
        counts = disp >= fraction * cx
        if counts.any():
            motion = max(motion, float(disp[counts].max()))
    return motion


def _krein_motion_ratio_reference(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                                  krein_b: np.ndarray, circle_tol: float, fraction: float,
                                  step: float) -> float:
    """Each watched multiplier's displacement over the larger of ``step`` and ``fraction``
    of its collision distance, the largest of them."""
    ratios = [disp[i] / max(step, fraction * cx[i])
              for disp, cx in _reference_displacements(np.asarray(a), krein_a, np.asarray(b),
                                                       krein_b, circle_tol)
              for i in range(disp.size)]
    return max(ratios, default=0.0)


def _krein_definiteness_reference(mu: np.ndarray, X: np.ndarray, Y: np.ndarray,
                                  lam: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Direct formula: ``v = -(diag(mu) - lam)^-1 X w`` scaled by ``mu_* - lam``, ``w`` the
    largest column of ``adj(M)``, ``M = (mu_* - lam) S(lam)``, all sums formed densely."""
    from nsm_continuation.core.floquet.secular import _adj

    k = X.shape[1]
    D = mu[None, :] - lam[:, None]
    d2 = np.abs(D) ** 2
    star = np.argmin(d2, axis=1)
    rows = np.arange(lam.size)
    G = 1.0 / np.where(d2 > 0, D, 1.0)
    G[rows, star] = 0.0
    S = np.einsum("km,mi,mj->kij", G, Y, X) + np.eye(k)
    d_star = mu[star] - lam
    M = d_star[:, None, None] * S + Y[star][:, :, None] * X[star][:, None, :]
    A = _adj(M)
    col = np.argmax(np.linalg.norm(A, axis=1), axis=1)
    w = A[rows, :, col]
    p = np.abs(w @ X.T) ** 2
    scale = np.abs(d_star)[:, None] ** 2 / np.where(d2 > 0, d2, 1.0)
    scale[rows, star] = 1.0
    p *= scale
    num, den = p @ s, p @ np.abs(s)
    return np.where(den > 0, num / den, np.sign(s[star]))


def _multipliers(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A symplectic-looking set: most on the circle (radius within rounding or ``1e-9``),
    some off it, some with indefinite Krein definiteness, with conjugates."""
    ang = rng.uniform(0.0, np.pi, n)
    r = 1.0 + rng.choice([0.0, 1e-12, 1e-9, 1e-3, 0.3], n) * rng.standard_normal(n)
    m = r * np.exp(1j * ang)
    k = rng.choice([-1.0, 1.0, 0.4, -0.7, 1e-8], n)
    return np.concatenate([m, np.conj(m)]), np.concatenate([k, -k])


# ---------------------------------------------------------------- nearest distances
@pytest.mark.parametrize("seed", range(6))
def test_nearest_distances_equal_the_dense_minimum(seed: int) -> None:
    """The k-d tree search gives exactly ``min_j |x_i - p_j|`` (with one excluded index per
    point), also with duplicated points, for small (dense path) and large sets."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 700)), int(rng.integers(1, 700))
    p = np.exp(1j * rng.uniform(-np.pi, np.pi, m)) * (1 + 1e-3 * rng.standard_normal(m))
    q = min(n // 3, m)  # the first q points are points of p, excluded from their own search
    x = np.concatenate([p[:q], np.exp(1j * rng.uniform(-np.pi, np.pi, n - q))])
    excl = np.where(np.arange(x.size) < q, np.arange(x.size), -1)
    d = np.abs(x[:, None] - p[None, :])
    ref = d.min(axis=1)
    assert np.array_equal(nearest_distances(x, p), ref)
    r = np.nonzero(excl >= 0)[0]
    d[r, excl[r]] = np.inf
    assert np.array_equal(nearest_distances(x, p, exclude=excl), d.min(axis=1))
    assert np.all(np.isinf(nearest_distances(x, p[:0])))


# ---------------------------------------------------------------- Krein step control
@pytest.mark.parametrize("seed", range(40))
def test_krein_motion_and_collision_distances_equal_the_dense_reference(seed: int) -> None:
    """Random multiplier sets (with unequal sizes, indefinite and off-circle members):
    :func:`krein_motion` and :func:`collision_distances` return the values of the dense
    distance-matrix formulas (to rounding)."""
    rng = np.random.default_rng(1000 + seed)
    n = int(rng.integers(1, 1200))
    a, ka = _multipliers(rng, n)
    b = a + rng.choice([1e-5, 1e-3, 3e-2]) * (rng.standard_normal(a.size)
                                            + 1j * rng.standard_normal(a.size))
    kb = ka * rng.choice([1.0, 1.0, 1.0, -1.0], a.size)
    if seed % 3 == 0:
        b, kb = b[:-2], kb[:-2]
    tol = float(rng.choice([1e-10, 1e-7, 1e-3]))
    frac = float(rng.choice([0.0, 0.25, 1.0]))
    # equal to rounding: the reference takes every pair's angle, the code the neighbours'
    np.testing.assert_allclose(collision_distances(a, ka, tol),
                               _collision_distances_reference(a, ka, tol), rtol=1e-13, atol=0)
    assert krein_motion(a, ka, b, kb, tol, frac) == pytest.approx(
        _krein_motion_reference(a, ka, b, kb, tol, frac), rel=1e-13, abs=0)
    # the step control's ratio: the same displacements over max(step, fraction c), and it
    # exceeds 1 exactly when the motion exceeds the step
    step = float(rng.choice([1e-4, 0.02, 0.1]))
    ratio = krein_motion_ratio(a, ka, b, kb, tol, frac, step)
    assert ratio == pytest.approx(
        _krein_motion_ratio_reference(a, ka, b, kb, tol, frac, step), rel=1e-13, abs=0)
    assert (ratio > 1.0) == (krein_motion(a, ka, b, kb, tol, frac) > step)


# ---------------------------------------------------------------- secular equation
def _update(rng: np.random.Generator, n: int, on_circle: bool
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if on_circle:
        mu = np.exp(1j * rng.uniform(-np.pi, np.pi, n))
    else:
        mu = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    X = 0.3 * (rng.standard_normal((n, 3)) + 1j * rng.standard_normal((n, 3)))
    Y = 0.3 * (rng.standard_normal((n, 3)) + 1j * rng.standard_normal((n, 3)))
    return mu, X, Y


@pytest.mark.parametrize("on_circle", [True, False])
def test_nearest_pole_is_the_minimum_over_all_poles(on_circle: bool) -> None:
    """On the circle the nearest pole is found by angle; it is the argmin of the distance
    (points near the circle, far from it, and at the wrap ``+-pi``)."""
    rng = np.random.default_rng(7)
    mu, _, _ = _update(rng, 500, on_circle)
    lam = np.concatenate([
        np.exp(1j * rng.uniform(-np.pi, np.pi, 300)) * (1 + 1e-4 * rng.standard_normal(300)),
        3.0 * rng.standard_normal(100) + 3j * rng.standard_normal(100),
        -1.0 + 1e-9j * rng.standard_normal(20)])
    poles = _Poles(mu)
    assert poles.on_circle == on_circle
    ref = np.argmin(np.abs(mu[None, :] - lam[:, None]), axis=1)
    got = poles.nearest(lam)
    if on_circle:
        assert np.array_equal(got, ref)
    else:
        assert got is None


@pytest.mark.parametrize("on_circle", [True, False])
def test_secular_roots_and_krein_equal_dense(on_circle: bool) -> None:
    """All eigenvalues of ``diag(mu) + X Y^T`` (n = 300, rank 3) equal the dense ones; the
    Krein definiteness equals the direct (dense) formula at the same roots."""
    rng = np.random.default_rng(11)
    mu, X, Y = _update(rng, 300, on_circle)
    out = low_rank_update_eigen(mu, X, Y)
    assert out is not None
    lam = out[0]
    dense = np.linalg.eigvals(np.diag(mu) + X @ Y.T)
    assert msd(lam, dense) <= 1e-9
    s = rng.choice([-1.0, 1.0], mu.size) / rng.uniform(0.5, 2.0, mu.size)
    kd = krein_definiteness(mu, X, Y, lam, s)
    assert np.allclose(kd, _krein_definiteness_reference(mu, X, Y, lam, s),
                       rtol=0, atol=1e-10)


# ---------------------------------------------------------------- the chain
def _chain_point(n: int, T: float) -> tuple[NDofImpactProblem, np.ndarray, np.ndarray]:
    pb = scaled_chain(n)
    pb.DENSE_MULTIPLIERS_UP_TO = 0
    y, t = closed_form_point(pb, T)
    return pb, y, t


def test_chain_warm_starts_and_repeated_points_give_the_dense_multipliers() -> None:
    """Along a few points of branch 1 (N = 60), the multipliers from the extrapolated warm
    start equal the dense eigenvalues (1e-9) and those of a cold start (1e-11), the last
    point interpolated between remembered ones (event location inside a step)."""
    n = 60
    pb, _, _ = _chain_point(n, 1.0)
    T1 = pb.T_lin[0]
    pts = []
    for frac in (0.999, 0.9985, 0.998, 0.9975, 0.99825):
        _, y, t = _chain_point(n, frac * T1)
        pts.append((y, t))
        fs = pb.floquet(y, t)
        cold = NDofImpactProblem(pb.params)
        cold.DENSE_MULTIPLIERS_UP_TO = 0
        fc = cold.floquet(y, t)
        fd = pb.floquet_dense(y, t)
        assert msd(fs.multipliers, fd.multipliers) <= 1e-9
        assert msd(fs.multipliers, fc.multipliers) <= 1e-11
        assert np.allclose(np.sort(krein_of(fs)), np.sort(krein_of(fc)), atol=1e-8)
    start = pb.multiplier_memory.nearest_guess(pts[-1][0])
    assert start is not None and start[0].shape == (2 * n - 2,)
    assert pb.floquet_fallbacks == 0
