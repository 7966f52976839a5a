"""Floquet helpers: removal of the trivial multipliers and classification of crossings.

Oracles: spectra of matrices built with a known eigen-decomposition ``A = V D V^-1`` (real
eigenvalues and real 2x2 rotation-scaling blocks for complex pairs), the determinant expansion
along a zero row, and synthetic multiplier sets with the structure of a conservative system
(reciprocal and conjugate pairs).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from nsm_continuation.core.floquet import (
    CROSSING_COMPLEX,
    CROSSING_MINUS_ONE,
    CROSSING_PLUS_ONE,
    classify_crossing,
    count_outside,
    deflate_known_eigenvector,
    householder_basis,
    restrict_to_section,
)


def multiset_distance(x: np.ndarray, y: np.ndarray) -> float:
    """Largest distance of an optimal one-to-one pairing of two multisets of complex numbers."""
    x, y = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    assert x.shape == y.shape
    if x.size == 0:
        return 0.0
    cost = np.abs(x[:, None] - y[None, :])
    r, c = linear_sum_assignment(cost)
    return float(cost[r, c].max())


def matrix_with_spectrum(rng: np.random.Generator, n: int
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Real ``A = V D V^-1`` with real and complex-pair eigenvalues; returns ``(A, V, eigs)``;
    column 0 of ``V`` is a real eigenvector for the real eigenvalue ``eigs[0]``."""
    D = np.zeros((n, n))
    eigs = []
    i = 0
    while i < n:
        if n - i >= 2 and rng.random() < 0.5 and i > 0:
            r, th = rng.uniform(0.3, 2.0), rng.uniform(0.2, 3.0)
            D[i:i + 2, i:i + 2] = r * np.array([[np.cos(th), -np.sin(th)],
                                                [np.sin(th), np.cos(th)]])
            eigs += [r * np.exp(1j * th), r * np.exp(-1j * th)]
            i += 2
        else:
            lam = rng.uniform(-2.0, 2.0)
            D[i, i] = lam
            eigs.append(lam)
            i += 1
    # well-conditioned V: orthogonal times a mild diagonal scaling
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    V = Q @ np.diag(rng.uniform(0.5, 2.0, n))
    return V @ D @ np.linalg.inv(V), V, np.array(eigs, dtype=complex)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 9), seed=st.integers(0, 2**31 - 1), flip=st.booleans())
def test_deflation_removes_exactly_the_known_eigenvalue(n: int, seed: int, flip: bool) -> None:
    rng = np.random.default_rng(seed)
    A, V, eigs = matrix_with_spectrum(rng, n)
    v = V[:, 0] * (-1.0 if flip else 1.0)  # either sign of the first component (Householder)
    B, lam, res = deflate_known_eigenvector(A, v)
    assert B.shape == (n - 1, n - 1)
    assert abs(lam - eigs[0].real) < 1e-10 * max(1.0, abs(eigs[0]))
    assert res < 1e-10 * np.linalg.norm(A, 2)
    # spec(A) = {lam} U spec(B), compared with the eigenvalues used to build A
    assert multiset_distance(np.linalg.eigvals(B), eigs[1:]) < 1e-8
    # the basis is orthogonal, symmetric, and its first column is +-v/|v|
    H = householder_basis(v)
    assert np.allclose(H @ H.T, np.eye(n), atol=1e-14)
    assert np.allclose(H, H.T, atol=0)
    u = v / np.linalg.norm(v)
    assert abs(abs(H[:, 0] @ u) - 1.0) < 1e-14


def test_deflation_reports_a_wrong_eigenvector() -> None:
    """An approximate eigenvector is flagged by the residual: ``|A u - lam u|`` ~ perturbation."""
    rng = np.random.default_rng(3)
    A, V, _ = matrix_with_spectrum(rng, 6)
    v = V[:, 0] + 1e-4 * rng.normal(size=6)
    _, _, res = deflate_known_eigenvector(A, v)
    assert 1e-7 < res < 1e-2
    with pytest.raises(ValueError):
        deflate_known_eigenvector(A, np.zeros(6))


@pytest.mark.parametrize("k", [0, 2, 5])
def test_restrict_to_section_when_a_row_vanishes(k: int) -> None:
    """Expanding ``det(A - z I)`` along a zero row ``k``: ``spec(A) = {0} U spec(A minus row and
    column k)``; with that row non-zero the identity fails (the test has teeth)."""
    rng = np.random.default_rng(k)
    A = rng.normal(size=(6, 6))
    A[k, :] = 0.0
    R = restrict_to_section(A, k)
    assert R.shape == (5, 5)
    keep = [i for i in range(6) if i != k]
    assert np.array_equal(R, A[np.ix_(keep, keep)])
    expected = np.concatenate([[0.0], np.linalg.eigvals(R)])
    assert multiset_distance(np.linalg.eigvals(A), expected) < 1e-10
    A[k, :] = rng.normal(size=6)
    assert multiset_distance(np.linalg.eigvals(A),
                             np.concatenate([[0.0], np.linalg.eigvals(restrict_to_section(A, k))])
                             ) > 1e-3


def _pair(r: float, th: float) -> list[complex]:
    return [r * np.exp(1j * th), r * np.exp(-1j * th)]


STABLE_REST = _pair(1.0, 2.0) + _pair(1.0, 0.7)
TOL = 1e-7


@pytest.mark.parametrize(
    ("before", "after", "kind", "leaving"),
    [
        # a pair collides at +1 on the circle and splits along the real axis: (r, 1/r)
        (_pair(1.0, 0.02) + STABLE_REST, [1.05, 1 / 1.05] + STABLE_REST, CROSSING_PLUS_ONE,
         [1.05]),
        # the same at -1
        (_pair(1.0, np.pi - 0.02) + STABLE_REST, [-1.05, -1 / 1.05] + STABLE_REST,
         CROSSING_MINUS_ONE, [-1.05]),
        # Krein collision away from +-1: a complex quadruple (r e^{+-i th}, r^-1 e^{+-i th})
        (_pair(1.0, 1.2) + _pair(1.0, 1.25) + STABLE_REST,
         _pair(1.03, 1.22) + _pair(1 / 1.03, 1.22) + STABLE_REST, CROSSING_COMPLEX,
         _pair(1.03, 1.22)),
    ],
    ids=["plus_one_pair", "minus_one_pair", "complex_quadruple"],
)
def test_classify_crossing(before, after, kind, leaving) -> None:
    before, after = np.array(before, dtype=complex), np.array(after, dtype=complex)
    # the synthetic sets have the structure of a conservative map: closed under z -> 1/z, conj
    for s in (before, after):
        assert multiset_distance(s, 1 / s) < 1e-12
        assert multiset_distance(s, np.conj(s)) < 1e-12
    assert count_outside(before, TOL) == 0 and count_outside(after, TOL) == len(leaving)
    got, out = classify_crossing(before, after, TOL)
    assert got == kind
    assert multiset_distance(out, np.array(leaving, dtype=complex)) < 1e-12
    # the way back (unstable -> stable) is the same bifurcation, read on the unstable side
    got_back, out_back = classify_crossing(after, before, TOL)
    assert got_back == kind
    assert multiset_distance(out_back, np.array(leaving, dtype=complex)) < 1e-12


def test_classify_crossing_without_leaving_multiplier() -> None:
    s = np.array(STABLE_REST, dtype=complex)
    kind, out = classify_crossing(s, s * (1 - 1e-3), TOL)
    assert kind == "stability_change" and out.size == 0


# ---------------------------------------------------------------------------------------------
# Structured spectra: diagonal plus low rank, Krein definiteness
# ---------------------------------------------------------------------------------------------
from nsm_continuation.core.floquet import (  # noqa: E402
    KREIN_DEFINITE,
    collision_distances,
    krein_definiteness,
    low_rank_update_eigen,
)


@pytest.mark.parametrize("k", [1, 2, 3])
@pytest.mark.parametrize("n", [4, 30, 120])
@pytest.mark.parametrize("seed", [0, 1])
def test_low_rank_update_eigenvalues_against_dense(k: int, n: int, seed: int) -> None:
    """``diag(mu) + X Y^T`` with ``mu`` on the unit circle (a rotation) and random ``X, Y``
    (n x k): every eigenvalue from the secular equation agrees with ``numpy.linalg.eigvals``
    of the dense matrix to 1e-9 (relative to ``1 + |lambda|``); removing known eigenvalues
    (two of the dense ones, passed as ``removed``) leaves exactly the others."""
    rng = np.random.default_rng(seed)
    mu = np.exp(1j * rng.uniform(-np.pi, np.pi, n))
    X = (rng.normal(size=(n, k)) + 1j * rng.normal(size=(n, k))) / np.sqrt(n)
    Y = (rng.normal(size=(n, k)) + 1j * rng.normal(size=(n, k))) / np.sqrt(n)
    dense = np.linalg.eigvals(np.diag(mu) + X @ Y.T)
    out = low_rank_update_eigen(mu, X, Y)
    assert out is not None
    lam = out[0]
    cost = np.abs(lam[:, None] - dense[None, :]) / (1.0 + np.abs(dense[None, :]))
    r, c = linear_sum_assignment(cost)
    assert cost[r, c].max() <= 1e-9
    drop = dense[:2]
    out2 = low_rank_update_eigen(mu, X, Y, removed=tuple(drop))
    assert out2 is not None and out2[0].size == n - 2
    rest = dense[2:]
    cost = np.abs(out2[0][:, None] - rest[None, :]) / (1.0 + np.abs(rest[None, :]))
    r, c = linear_sum_assignment(cost)
    assert cost[r, c].max() <= 1e-8


def test_krein_definiteness_of_a_symplectic_rotation_pair() -> None:
    """The unperturbed rotation (``X = Y = 0``) in the eigenbasis: ``kappa = sign(s_m)`` of its
    own weight; with the Hermitian form ``g = sum s_m |v_m|^2`` of a coupled 2 x 2 Hermitian-
    pencil model, ``kappa`` is ``g(v)/sum|s||v|^2`` of the dense eigenvectors."""
    mu = np.exp(1j * np.array([0.4, -0.4, 1.1, -1.1]))
    s = np.array([1.0, -1.0, 0.5, -0.5])
    X = np.zeros((4, 1), complex)
    lam = mu * (1 + 1e-13)
    assert np.allclose(krein_definiteness(mu, X, X, lam, s), np.sign(s))
    rng = np.random.default_rng(5)
    X = 0.05 * (rng.normal(size=(4, 2)) + 1j * rng.normal(size=(4, 2)))
    Y = 0.05 * (rng.normal(size=(4, 2)) + 1j * rng.normal(size=(4, 2)))
    lam, V = np.linalg.eig(np.diag(mu) + X @ Y.T)
    want = (np.abs(V) ** 2 * s[:, None]).sum(0) / (np.abs(V) ** 2 * np.abs(s)[:, None]).sum(0)
    assert np.allclose(krein_definiteness(mu, X, Y, lam, s), want, atol=1e-9)


def test_collision_distances() -> None:
    """Definite multipliers on the circle: distance to the nearest one of the other signature
    (their own conjugate included: near +-1 the distance is small); off the circle: to the
    partner ``1/conj(lambda)``; indefinite on the circle: 0; no Krein data: all 0."""
    th = np.array([0.5, -0.5, 0.6, -0.6, 3.1, -3.1])
    m = np.exp(1j * th)
    k = np.array([1.0, -1.0, 1.0, -1.0, -1.0, 1.0])
    d = collision_distances(m, k, 1e-7)
    assert d[0] == pytest.approx(2 * np.sin(0.5), rel=1e-12)      # to exp(-0.5 i)
    assert d[4] == pytest.approx(2 * np.sin(0.0416), rel=1e-3)     # -1: to its conjugate
    m2 = np.concatenate([m, [1.1 * np.exp(1j), np.exp(1j) / 1.1, np.exp(2.0j)]])
    k2 = np.concatenate([k, [0.0, 0.0, 0.1 * KREIN_DEFINITE]])
    d2 = collision_distances(m2, k2, 1e-7)
    assert d2[6] == pytest.approx(1.1 - 1 / 1.1, rel=1e-12)
    assert d2[8] == 0.0
    assert np.all(collision_distances(m, None, 1e-7) == 0.0)
