"""Multipliers of real maps by conjugate pairs (what keeps a point of the N = 1000 chain with
its multipliers under 0.1 s): :func:`nsm_continuation.core.floquet.low_rank_update_eigen`
iterates one member of each conjugate pair and the real roots, and returns an exactly
conjugate-closed spectrum; :func:`nsm_continuation.core.floquet.krein_definiteness` computes
one member of each pair.

Oracles, independent of the code under test: ``numpy.linalg.eigvals`` of the real matrix
``(I + U V^T) D`` (LAPACK returns its real eigenvalues with a zero imaginary part and its
complex ones in exact conjugate pairs), the Krein form of the dense eigenvectors
(``numpy.linalg.eig``), and the chain's dense multipliers
(:meth:`NDofImpactProblem.floquet_dense`).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import msd
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from oracles.scaled_chain import closed_form_point
from scipy.optimize import linear_sum_assignment

from nsm_continuation.core.floquet import krein_definiteness, low_rank_update_eigen, lowrank


def exactly_closed(lam: np.ndarray) -> bool:
    """Whether ``lam`` equals its conjugate as a multiset, bit for bit."""
    return bool(np.array_equal(np.sort_complex(lam), np.sort_complex(np.conj(lam))))


def real_map(theta: np.ndarray, U: np.ndarray, V: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``A = (I + U V^T) D`` (``D``: rotations by ``theta``, 2n x 2n, real) and its form
    ``diag(mu) + X Y^T`` in the eigenbasis ``(1, -+i)/sqrt 2`` of ``D`` (the chain's
    :meth:`NDofImpactProblem.return_map_structure`): ``(A, mu, X, Y)``."""
    n = theta.size
    c, s = np.cos(theta), np.sin(theta)
    D = np.block([[np.diag(c), np.diag(s)], [-np.diag(s), np.diag(c)]])
    r2 = np.sqrt(0.5)
    ep, em = np.exp(1j * theta), np.exp(-1j * theta)
    X = np.concatenate([(U[:n] - 1j * U[n:]) * r2, (U[:n] + 1j * U[n:]) * r2])
    Y = np.concatenate([(V[:n] + 1j * V[n:]) * (r2 * ep)[:, None],
                        (V[:n] - 1j * V[n:]) * (r2 * em)[:, None]])
    return (np.eye(2 * n) + U @ V.T) @ D, np.concatenate([ep, em]), X, Y


def random_real_map(rng: np.random.Generator, n: int, k: int = 3, scale: float = 0.3
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return real_map(rng.uniform(0.0, np.pi, n), scale * rng.standard_normal((2 * n, k)),
                    scale * rng.standard_normal((2 * n, k)))


# ---------------------------------------------------------------- the spectrum
@pytest.mark.parametrize("n", [5, 40, 150])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_real_map_spectrum_by_pairs_equals_dense_and_is_exactly_closed(n: int, seed: int
                                                                        ) -> None:
    """Random real maps (rank 3, with real eigenvalues among them): every eigenvalue agrees
    with LAPACK's to 1e-9 relative, the same number are exactly real, the rest come in
    exact conjugate pairs, and the paired iteration did it (no fallback); with a conjugate
    pair of eigenvalues removed, the others."""
    rng = np.random.default_rng(seed)
    A, mu, X, Y = random_real_map(rng, n)
    dense = np.linalg.eigvals(A)
    out = low_rank_update_eigen(mu, X, Y)
    assert out is not None and out[2].get("pairs") == 1.0
    lam = out[0]
    assert exactly_closed(lam)
    assert np.sum(lam.imag == 0) == np.sum(dense.imag == 0)
    cost = np.abs(lam[:, None] - dense[None, :]) / (1.0 + np.abs(dense[None, :]))
    r, c = linear_sum_assignment(cost)
    assert cost[r, c].max() <= 1e-9
    i = int(np.argmax(dense.imag))  # a conjugate pair (exact in LAPACK's output)
    drop = (dense[i], np.conj(dense[i]))
    out2 = low_rank_update_eigen(mu, X, Y, removed=drop)
    assert out2 is not None and out2[2].get("pairs") == 1.0 and exactly_closed(out2[0])
    rest = np.delete(dense, [i, int(np.argmin(np.abs(dense - np.conj(dense[i]))))])
    assert msd(out2[0], rest) <= 1e-8


def test_pairs_split_into_real_roots_at_minus_one_and_plus_one_and_merge_back() -> None:
    """Two rotation blocks near ``-1`` and ``+1`` (angles ``pi - 0.01`` and ``0.01``) pushed
    by ``eps`` (block ``[[(1 + eps) c, (1 + eps) s], [-s, c]]``: real eigenvalues for
    ``eps > ~0.02``): along ``eps = 0 -> 0.05 -> 0`` each set is started from the previous
    one, so that two conjugate pairs split on the real axis (period doubling at -1, a fold
    at +1) and merge back. Each set equals LAPACK's (1e-12), with its four real eigenvalues
    exactly real (two next to -1, two next to +1), in few sweeps."""
    rng = np.random.default_rng(5)
    n = 40
    theta = rng.uniform(0.3, np.pi - 0.3, n)
    theta[0], theta[1] = np.pi - 0.01, 0.01
    U0, V0 = 0.01 * rng.standard_normal((2 * n, 1)), 0.01 * rng.standard_normal((2 * n, 1))
    e = np.eye(2 * n)[:, :2]
    prev = None
    for eps in (0.0, 0.015, 0.03, 0.05, 0.03, 0.015, 0.0):
        A, mu, X, Y = real_map(theta, np.hstack([U0, eps * e]), np.hstack([V0, e]))
        dense = np.linalg.eigvals(A)
        out = low_rank_update_eigen(mu, X, Y, guess=prev)
        assert out is not None and out[2].get("pairs") == 1.0
        lam = out[0]
        assert exactly_closed(lam)
        assert msd(lam, dense) <= 1e-12
        real = np.sort(lam[lam.imag == 0].real)
        assert real.size == np.sum(dense.imag == 0) == (4 if eps >= 0.03 else 0)
        assert np.allclose(real, np.sort(dense[dense.imag == 0].real), rtol=0, atol=1e-12)
        assert np.all(np.abs(np.abs(real) - 1.0) < 0.05)  # two next to -1, two next to +1
        assert np.sum(real < 0) == np.sum(real > 0)
        assert out[2]["sweeps"] <= 6
        prev = lam


def test_a_start_that_is_not_conjugate_closed_keeps_its_slots() -> None:
    """A start off the spectrum by up to 1e-4 in random directions (not conjugate-closed,
    the real eigenvalues off the axis): the result is exactly closed, equals LAPACK's, and
    each eigenvalue stays in the slot of the start it came from (the nearest one)."""
    rng = np.random.default_rng(3)
    A, mu, X, Y = random_real_map(rng, 60)
    dense = np.linalg.eigvals(A)
    assert np.any(dense.imag == 0)
    guess = dense + 1e-4 * rng.uniform(0, 1, dense.size) * np.exp(
        2j * np.pi * rng.random(dense.size))
    out = low_rank_update_eigen(mu, X, Y, guess=guess)
    assert out is not None and out[2].get("pairs") == 1.0
    lam = out[0]
    assert exactly_closed(lam)
    assert np.max(np.abs(lam - dense)) <= 1e-10


def test_without_pairs_the_general_iteration_is_made_exactly_closed(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Should the paired iteration fail, the general one answers, its result symmetrised
    (pairs of nearest conjugates averaged, the rest on the real axis): still exactly closed
    and equal to LAPACK's."""
    rng = np.random.default_rng(8)
    A, mu, X, Y = random_real_map(rng, 50)
    monkeypatch.setattr(lowrank, "_aberth_pairs", lambda *args: None)
    out = low_rank_update_eigen(mu, X, Y)
    assert out is not None and "pairs" not in out[2]
    dense = np.linalg.eigvals(A)
    assert exactly_closed(out[0]) and np.sum(out[0].imag == 0) == np.sum(dense.imag == 0)
    assert msd(out[0], dense) <= 1e-10


def test_a_complex_map_is_not_taken_for_a_real_one() -> None:
    """``diag(mu) + X Y^T`` with ``X`` off the conjugate structure by one entry: no pairs
    (its spectrum is not closed), the general iteration, LAPACK's eigenvalues."""
    rng = np.random.default_rng(4)
    _, mu, X, Y = random_real_map(rng, 30)
    X = X.copy()
    X[3, 1] += 1e-3j
    out = low_rank_update_eigen(mu, X, Y)
    assert out is not None and "pairs" not in out[2]
    assert msd(out[0], np.linalg.eigvals(np.diag(mu) + X @ Y.T)) <= 1e-10


# ---------------------------------------------------------------- Krein collisions of the chain
def _chain_structure(pb: NDofImpactProblem, frac: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple]:
    y, t = closed_form_point(pb, frac * pb.T_lin[0])
    st = pb.return_map_structure(y)
    X, Y, removed = pb._deflated_update(st, pb._family_direction(y, t))
    return y, t, st["mu"], X, Y, removed


@pytest.mark.parametrize("fracs", [(0.998995, 0.998990), (0.998900, 0.998895),
                                   (0.998825, 0.998820)])
def test_a_krein_collision_between_two_starts_costs_few_sweeps(fracs: tuple[float, float]
                                                               ) -> None:
    """N = 60 chain, branch 1 next to the grazing orbit: between the two periods two
    multipliers of opposite signature collide on the circle and leave it (the number off it
    changes). Started from the multipliers of the first period, the two on the circle stand
    across the line of the two roots off it, where separate Aberth steps are trapped (18-22
    sweeps measured); moved together (one quadratic factor) they converge in a few. The
    multipliers equal the dense ones (1e-9)."""
    pb = NDofImpactProblem({"chain": {"dofs": 60, "mass": 1.0 / 60, "stiffness": 60.0},
                            "gap": 1.0})
    _, _, mu, X, Y, removed = _chain_structure(pb, fracs[0])
    start = low_rank_update_eigen(mu, X, Y, removed=removed)
    assert start is not None
    y, t, mu, X, Y, removed = _chain_structure(pb, fracs[1])
    out = low_rank_update_eigen(mu, X, Y, removed=removed, guess=start[0])
    assert out is not None and out[2].get("pairs") == 1.0
    off = lambda m: int(np.sum(np.abs(np.abs(m) - 1.0) > 1e-8))  # noqa: E731
    assert off(out[0]) != off(start[0])
    assert out[2]["sweeps"] <= 6
    assert exactly_closed(out[0])
    assert msd(out[0], pb.floquet_dense(y, t).multipliers) <= 1e-9


# ---------------------------------------------------------------- Krein definiteness
def test_krein_definiteness_of_conjugates_is_exactly_opposite_and_equals_dense() -> None:
    """A real map with the form ``s = (1/w, -1/w)`` (odd under conjugation, as the
    symplectic form's): ``kappa(conj lam) = -kappa(lam)`` bit for bit, and each ``kappa``
    equals ``sum s |v|^2 / sum |s| |v|^2`` of LAPACK's eigenvector (1e-9, eigenvalues 1e-3
    apart from the others); real eigenvalues have ``kappa = 0`` (to 1e-12). With
    ``off_circle`` those farther from the circle are exactly 0, the others unchanged."""
    rng = np.random.default_rng(9)
    n = 40
    _, mu, X, Y = random_real_map(rng, n, scale=0.2)
    w = rng.uniform(0.5, 2.0, n)
    s = np.concatenate([1.0 / w, -1.0 / w])
    out = low_rank_update_eigen(mu, X, Y)
    assert out is not None
    lam = out[0]
    kd = krein_definiteness(mu, X, Y, lam, s)
    up = np.nonzero(lam.imag > 0)[0]
    lo = np.array([int(np.nonzero(lam == np.conj(z))[0][0]) for z in lam[up]])
    assert np.array_equal(kd[lo], -kd[up])
    assert np.all(np.abs(kd[lam.imag == 0]) <= 1e-12)
    ev, V = np.linalg.eig(np.diag(mu) + X @ Y.T)
    ref = (np.abs(V) ** 2 * s[:, None]).sum(0) / (np.abs(V) ** 2 * np.abs(s)[:, None]).sum(0)
    sep = np.array([np.min(np.abs(np.delete(lam, i) - lam[i])) for i in range(lam.size)])
    checked = 0
    for i in np.nonzero(sep > 1e-3)[0]:
        j = int(np.argmin(np.abs(ev - lam[i])))
        assert abs(kd[i] - ref[j]) <= 1e-9
        checked += 1
    assert checked >= lam.size // 2
    tol = float(np.median(np.abs(np.abs(lam) - 1.0)))  # (not symplectic: none on the circle)
    on = np.abs(np.abs(lam) - 1.0) <= tol
    ko = krein_definiteness(mu, X, Y, lam, s, off_circle=tol)
    assert np.all(ko[~on] == 0.0) and np.any(~on) and np.any(on)
    assert np.array_equal(ko[on], kd[on])
