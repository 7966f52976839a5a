"""Multipliers of the N-dof chain from the structure of its return map.

``DF`` (eq. 3.5 / A.8) in energy coordinates is a block rotation plus a rank-two term
(:meth:`NDofImpactProblem.return_map_structure`); its non-trivial multipliers are the roots of
a secular equation (:func:`nsm_continuation.core.floquet.low_rank_update_eigen`) and their Krein
definiteness comes from the secular null vectors (:func:`krein_definiteness`).

Oracles (independent of the structure):

* the dense eigenvalues of ``DF`` in physical coordinates, restricted and deflated
  (:meth:`NDofImpactProblem.floquet_dense`, built from ``Gamma`` of eq. A.1 by matrix products);
* the Krein form ``g(v) = -i v^H Omega v`` of the dense eigenvectors of ``DF`` carried to energy
  coordinates, ``Omega`` the canonical symplectic form ``du ^ d(M u')`` written there;
* ``DF`` preserves that form on the section's energy level (symplectic), which the Krein
  argument needs; both dense.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import msd
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from oracles.scaled_chain import closed_form_point, scaled_chain

from nsm_continuation.core.floquet import KREIN_DEFINITE, krein_of


def chain(n: int, structured: bool = True) -> NDofImpactProblem:
    """The paper's scaling (2.17): ``m = 1/N``, ``k = N`` (N = 5: the paper's chain)."""
    pb = scaled_chain(n)
    if structured:
        pb.DENSE_MULTIPLIERS_UP_TO = 0  # the O(N^2) iteration at every size
    return pb


def dense_energy_map(pb: NDofImpactProblem, y: np.ndarray) -> np.ndarray:
    """``DF`` (A.8, dense, physical) carried to energy coordinates ``z = T_z x``."""
    w, P, Pi = pb.omega, pb.P, pb.Pinv
    Tz = np.block([[w[:, None] * Pi, np.zeros_like(Pi)], [np.zeros_like(Pi), Pi]])
    Tzi = np.block([[P / w[None, :], np.zeros_like(P)], [np.zeros_like(P), P]])
    return Tz @ pb.return_map_jacobian(y) @ Tzi


def omega_z(pb: NDofImpactProblem) -> np.ndarray:
    """The canonical form ``sum_j dq_j ^ dp_j`` in energy coordinates (``q_j = xi_j / w_j``)."""
    Wi = np.diag(1.0 / pb.omega)
    Z = np.zeros_like(Wi)
    return np.block([[Z, Wi], [-Wi, Z]])


# a point of branch 1 next to the linear grazing orbit, one in the middle, one near its end
FRACS = [0.9999, 0.999, 0.99]


@pytest.mark.parametrize("n", [5, 50, 200])
@pytest.mark.parametrize("frac", FRACS)
def test_structured_multipliers_equal_dense_eigenvalues(n: int, frac: float) -> None:
    """All ``2N - 2`` non-trivial multipliers agree with the dense eigenvalues to 1e-9 (measured:
    <= 1.2e-10, the largest next to the linear grazing orbit where ``|DF| ~ 1/v``); the
    removed 0 and 1 are not among them; ``DF t = t`` holds to 1e-10."""
    pb = chain(n)
    y, t = closed_form_point(pb, frac * pb.T_lin[0])
    fs, fd = pb.floquet(y, t), pb.floquet_dense(y, t)
    assert fs.multipliers.shape == (2 * n - 2,)
    assert msd(fs.multipliers, fd.multipliers) <= 1e-9
    assert fs.trivial_error <= 1e-10
    assert pb.floquet_fallbacks == 0


@pytest.mark.parametrize("dT", [1e-4, 1e-6, -1e-6, -1e-4])
def test_near_the_fold_at_plus_one(dT: float) -> None:
    """5-dof chain, branch 1, the pair through +1 at T = 4.3283005085 (a fold of the
    multipliers next to the trivial 1, removed by Wielandt's deflation): within 1e-4 in T the
    pair is 3e-3 ... 3e-2 from 1; structured and dense agree to 1e-8, and the pair's moduli to
    1e-8 (measured <= 2e-10)."""
    pb = chain(5)
    y, t = closed_form_point(pb, 4.328300508516754 + dT)
    fs, fd = pb.floquet(y, t), pb.floquet_dense(y, t)
    assert msd(fs.multipliers, fd.multipliers) <= 1e-8
    near = lambda m: np.sort(np.abs(m[np.argsort(np.abs(m - 1.0))[:2]]))  # noqa: E731
    assert np.allclose(near(fs.multipliers), near(fd.multipliers), atol=1e-8)


@pytest.mark.parametrize("dT", [-1e-5, 1e-5])
@pytest.mark.parametrize("edge", [4.176402496, 4.178795002])
def test_near_the_krein_collisions_of_the_narrow_window(edge: float, dT: float) -> None:
    """The two Krein collisions bounding the 8.6e-4-wide Neimark-Sacker window of Fig. 6.1
    (omega 1.503588 / 1.504449): 1e-5 in T on either side, structured and dense agree to 1e-8;
    on the stable side the colliding pair is on the circle with definite, opposite
    signatures, on the unstable side it is off the circle with zero definiteness."""
    pb = chain(5)
    y, t = closed_form_point(pb, edge + dT)
    fs, fd = pb.floquet(y, t), pb.floquet_dense(y, t)
    assert msd(fs.multipliers, fd.multipliers) <= 1e-8
    m, k = fs.multipliers, krein_of(fs)
    off = np.abs(np.abs(m) - 1.0) > 1e-7
    assert np.all(np.abs(k[off]) < 1e-6)
    assert np.all(np.abs(k[~off]) >= KREIN_DEFINITE)


@pytest.mark.parametrize("n", [5, 50])
@pytest.mark.parametrize("frac", FRACS)
def test_krein_definiteness_against_dense_eigenvectors(n: int, frac: float) -> None:
    """``kappa = g(v)/|v|^2`` from the secular null vectors equals the Krein form of the dense
    eigenvectors of ``DF`` (energy coordinates), to 1e-7 for multipliers 1e-4 apart from the
    others (an eigenvector is only defined to its distance to the nearest eigenvalue); it is
    in ``[-1, 1]``, flips sign under conjugation, and vanishes off the circle."""
    pb = chain(n)
    y, t = closed_form_point(pb, frac * pb.T_lin[0])
    fs = pb.floquet(y, t)
    DFz = dense_energy_map(pb, y)
    lam, V = np.linalg.eig(DFz)
    Om = omega_z(pb)
    wt = np.concatenate([1.0 / pb.omega, 1.0 / pb.omega])
    g = np.real(-1j * np.einsum("im,ij,jm->m", V.conj(), Om, V))
    kd = g / np.einsum("im,i->m", np.abs(V) ** 2, wt)
    m, k = fs.multipliers, krein_of(fs)
    assert np.all(np.abs(k) <= 1.0 + 1e-12)
    sep = np.array([np.min(np.abs(np.delete(m, i) - m[i])) for i in range(m.size)])
    checked = 0
    for i in np.nonzero(sep > 1e-4)[0]:
        j = int(np.argmin(np.abs(lam - m[i])))
        assert abs(k[i] - kd[j]) <= 1e-7, (m[i], k[i], kd[j])
        jc = int(np.argmin(np.abs(m - np.conj(m[i]))))
        if abs(m[i].imag) > 1e-6:
            assert abs(k[i] + k[jc]) <= 1e-7
        if abs(abs(m[i]) - 1.0) > 1e-6:
            assert abs(k[i]) <= 1e-6
        checked += 1
    assert checked >= m.size // 2


@pytest.mark.parametrize("n", [5, 30])
def test_return_map_is_symplectic_on_the_energy_level_of_the_section(n: int) -> None:
    """``omega(DF a, DF b) = omega(a, b)`` for ``a, b`` in the section (``u_c`` fixed) and the
    energy level (``grad E . a = 0``): the symplectic form the Krein signatures refer to; and
    in energy coordinates ``grad E = z0`` (the left eigenvector of the trivial 1)."""
    pb = chain(n)
    y, _ = closed_form_point(pb, 0.995 * pb.T_lin[0])
    DFz = dense_energy_map(pb, y)
    st = pb.return_map_structure(y)
    z0 = st["z0"]
    h = st["V"][:, 1]
    assert np.linalg.norm(z0 @ DFz - z0) <= 1e-10 * np.linalg.norm(z0) * np.linalg.norm(DFz)
    rng = np.random.default_rng(3)
    C = np.stack([h, z0], axis=1)
    A = rng.normal(size=(2 * n, 4))
    A -= C @ np.linalg.lstsq(C, A, rcond=None)[0]  # project onto ker h^T and ker z0^T
    Om = omega_z(pb)
    lhs = (DFz @ A).T @ Om @ (DFz @ A)
    rhs = A.T @ Om @ A
    assert np.abs(lhs - rhs).max() <= 1e-9 * np.linalg.norm(DFz) ** 2


def test_structure_reproduces_the_dense_return_map() -> None:
    """``(I + U V^T) D`` (:meth:`return_map_apply`) equals the dense (A.8) in energy
    coordinates, column by column (the saltation form of the derivation)."""
    pb = chain(7)
    y, _ = closed_form_point(pb, 0.97 * pb.T_lin[0])
    st = pb.return_map_structure(y)
    DFz = dense_energy_map(pb, y)
    cols = np.stack([pb.return_map_apply(st, e) for e in np.eye(14)], axis=1)
    assert np.abs(cols - DFz).max() <= 1e-11 * np.abs(DFz).max()


@pytest.mark.parametrize("frac", FRACS)
def test_small_chain_krein_from_dense_eigenvectors_equals_secular(frac: float) -> None:
    """Up to ``DENSE_MULTIPLIERS_UP_TO`` dofs the Krein definiteness comes from the dense
    eigenvectors of ``(I + U V^T) D``; it equals the secular null-vector formula (the large-N
    path) to 1e-7 for multipliers 1e-4 apart from the others."""
    dense, sec = chain(5, structured=False), chain(5)
    y, t = closed_form_point(dense, frac * dense.T_lin[0])
    fd, fs = dense.floquet(y, t), sec.floquet(y, t)
    kd, ks = krein_of(fd), krein_of(fs)
    md, ms = fd.multipliers, fs.multipliers
    for i in range(md.size):
        if np.min(np.abs(np.delete(md, i) - md[i])) > 1e-4:
            j = int(np.argmin(np.abs(ms - md[i])))
            assert abs(kd[i] - ks[j]) <= 1e-7
