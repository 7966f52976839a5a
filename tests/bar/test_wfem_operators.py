"""WFEM operators (Yoong et al. 2017, App. A-B): structure, energy, orientation, kernels."""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.bar.wfem_operators import (
    CONTACT,
    FREE,
    A_g,
    dense_operator,
    end_series,
    from_ring,
    pattern_from_counts,
    phase_operator,
    ring_energy,
    ring_step,
    simulate_ring,
    to_ring,
)
from oracles.wfem_bar import ring_basis

Z = 1.7  # rho c (rho = 1.7, c = 1)


def energy_matrix(N: int, dx: float, E: float, rho: float) -> np.ndarray:
    """Quadratic form of the energy on Q = [sigma; v]: dx (sigma^2 / 2E + rho v^2 / 2)."""
    return np.diag(np.r_[np.full(N, dx / (2 * E)), np.full(N, dx * rho / 2)])


@pytest.mark.parametrize("N", [5, 6])
@pytest.mark.parametrize("end", ["free", "contact"])
def test_dense_matrices_are_the_signed_rotation_and_conserve_energy(N: int, end: str) -> None:
    A = dense_operator(N, Z, end)
    T = ring_basis(N, Z)
    s = FREE if end == "free" else CONTACT
    P = phase_operator(N, ((1, s),)).dense()
    assert np.abs(T @ A @ np.linalg.inv(T) - P).max() < 1e-14
    rho, c = Z, 1.0
    W = energy_matrix(N, 0.1, rho * c**2, rho)
    assert np.abs(A.T @ W @ A - W).max() < 1e-14


def test_fixed_end_is_x0_and_printed_matrix_is_the_mirror_image() -> None:
    """Which end is fixed: the flux of sum(sigma) through x = 0 vanishes (A.19), so under A_c
    (both ends fixed) sum(sigma) is conserved; under A_f it changes by the free-end flux only.
    The printed (A.26)-(A.27) matrix is the same bar mirrored (free at 0, fixed at L)."""
    N = 7
    rng = np.random.default_rng(0)
    Q = rng.normal(size=2 * N)
    sig, v = Q[:N], Q[N:]
    Ac = dense_operator(N, Z, "contact")
    assert np.isclose((Ac @ Q)[:N].sum(), sig.sum(), atol=1e-13)
    Af = dense_operator(N, Z, "free")
    v_end = v[-1] - sig[-1] / Z  # Riemann solution (A.12) with the free ghost (A.19)
    # d/dt int sigma = E (v(L) - v(0)), dt E / dx = Z (c = 1 here: E = Z c^2 = Z, dt = dx)
    assert np.isclose((Af @ Q)[:N].sum() - sig.sum(), Z * v_end, atol=1e-13)
    printed = dense_operator(N, Z, "free", corners="printed")
    J = np.eye(N)[::-1]
    mirror = np.block([[J, 0 * J], [0 * J, -J]])  # x -> L - x: sigma even, v odd
    assert np.abs(mirror @ Af @ mirror - printed).max() < 1e-14
    assert np.abs(printed - Af).max() > 0.1


def test_printed_A21_sign_breaks_energy_conservation() -> None:
    """(A.21) prints sigma_N' = (sigma_(N-1) - sigma_N + rho c (v_N + v_(N-1)))/2; (A.18) with the
    ghost (A.19) gives ``- v_(N-1)``. The printed row does not conserve energy."""
    N = 6
    A = dense_operator(N, Z, "free")
    assert np.isclose(A[N - 1, 2 * N - 2], -Z / 2)  # derived coefficient of v_(N-1)
    B = A.copy()
    B[N - 1, 2 * N - 2] = +Z / 2
    W = energy_matrix(N, 0.1, Z, Z)
    assert np.abs(A.T @ W @ A - W).max() < 1e-14
    assert np.abs(B.T @ W @ B - W).max() > 1e-3


def test_A_g_pattern() -> None:
    A = A_g(4, 1, 2, 3, 4) * 2
    assert A[0, 0] == 1 and A[3, 3] == 4 and A[0, 1] == 2 and A[1, 0] == 3 and A[1, 1] == 0


@pytest.mark.parametrize("N", [4, 5])
def test_kernel_dimension_matches_dense_svd_for_all_nodes(N: int) -> None:
    Af, Ac = dense_operator(N, Z, "free"), dense_operator(N, Z, "contact")
    powf = [np.linalg.matrix_power(Af, m) for m in range(4 * N + 1)]
    powc = [np.linalg.matrix_power(Ac, p) for p in range(4 * N + 1)]
    T = ring_basis(N, Z)
    empty = 0
    for m in range(1, 4 * N + 1):
        for p in range(1, 4 * N + 1):
            S = powc[p] @ powf[m] - np.eye(2 * N)
            sv = np.linalg.svd(S, compute_uv=False)
            h_dense = int(np.sum(sv < 1e-9 * max(1.0, sv[0])))
            op = phase_operator(N, pattern_from_counts(m, p))
            assert op.kernel_dimension() == h_dense, (m, p)
            K = op.kernel()
            empty += K.shape[1] == 0
            if K.shape[1]:
                Qk = np.linalg.solve(T, K)  # kernel vectors in (sigma, v)
                assert np.abs(S @ Qk).max() < 1e-12
                assert np.allclose(K.T @ K, np.eye(K.shape[1]))
    assert empty > 0  # patterns with an empty kernel exist


def test_two_phase_pattern_and_end_series_match_step_by_step() -> None:
    N = 6
    rng = np.random.default_rng(1)
    w0 = rng.normal(size=2 * N)
    pattern = pattern_from_counts(5, 3, 9, 3)
    states = simulate_ring(w0, pattern)
    assert np.allclose(phase_operator(N, pattern).apply(w0), states[-1])
    J = end_series(w0, pattern)
    assert np.allclose(J, states[:-1, N - 1])
    # free left end (falling-bar benchmark): sign -1 at slot 2N-1 -> 0
    w = ring_step(w0, FREE, left_sign=-1)
    assert w[0] == -w0[-1]
    assert np.allclose(phase_operator(N, ((1, FREE),), left_sign=-1).apply(w0), w)


def test_ring_conversion_and_energy() -> None:
    rng = np.random.default_rng(2)
    sig, v = rng.normal(size=5), rng.normal(size=5)
    w = to_ring(sig, v, Z)
    s2, v2 = from_ring(w, Z)
    assert np.allclose(s2, sig) and np.allclose(v2, v)
    E, dx = Z, 0.2  # c = 1
    direct = dx * np.sum(sig**2 / (2 * E) + Z * v**2 / 2)
    assert np.isclose(ring_energy(w, dx, E), direct)


def test_negative_phase_rejected() -> None:
    with pytest.raises(ValueError):
        phase_operator(4, ((-1, FREE),))
