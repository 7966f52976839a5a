"""The 5-dof chain's return map structure and dense Krein definiteness
(:meth:`NDofImpactProblem.return_map_structure` built on :meth:`_saltation`,
:meth:`NDofImpactProblem._krein_dense` without ``np.block`` nor a second structure) equal
their direct formulas.

Oracles, independent of the code under test:

* the return map ``DF`` (A.8) in physical coordinates (:meth:`return_map_jacobian`, from
  ``Gamma(T)``), taken to energy coordinates ``z = S x``, ``S = diag(Omega P^-1, P^-1)``:
  ``(I + U V^T) D = S DF S^-1``, the spectrum of ``diag(mu) + X Y^T`` is that of ``S DF S^-1``,
  and ``z0 = S x0``;
* the Krein definiteness ``kappa = 2 sum Im(conj xi eta) / w / sum (|xi|^2 + |eta|^2) / w`` of
  the eigenvectors of ``S DF S^-1`` (numpy), for well separated multipliers;
* reference implementations of the direct formulas, kept here (:func:`_structure_reference`,
  :func:`_krein_dense_reference`): the package's give the same bits.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

CHAIN = {"dofs": 5, "mass": 0.2, "stiffness": 5.0}


def _problem(formulation: str = "half_angle") -> NDofImpactProblem:
    return NDofImpactProblem({"chain": CHAIN, "gap": 1.0, "formulation": formulation})


def _points(p: NDofImpactProblem, count: int = 40) -> list[np.ndarray]:
    out = []
    for T in np.linspace(0.6, 4.7, count):
        u0, du0 = p.closed_form(float(T))
        if np.all(np.isfinite(u0)) and np.max(np.abs(u0)) < 1e3 and abs(du0[p.c]) > 1e-6:
            out.append(p.y_from_state(u0, du0, float(T)))
    return out


def _structure_reference(p: NDofImpactProblem, y: np.ndarray) -> dict[str, np.ndarray]:
    """:meth:`return_map_structure` by its direct formulas (the reference)."""
    u0, du0, T = p.state(y)
    w, Pi = p.omega, p.Pinv
    a = p.P[p.c, :]
    b = Pi[:, p.c]
    xi0, eta0 = w * (Pi @ u0), Pi @ du0
    th = w * T
    c, s = np.cos(th), np.sin(th)
    xim, etam = c * xi0 + s * eta0, -s * xi0 + c * eta0
    fxi, feta = w * etam, -w * xim
    hf = float(a @ etam)
    Jfeta = feta - 2.0 * b * float(a @ feta)
    zero = np.zeros_like(w)
    U = np.stack([np.concatenate([zero, -2.0 * b]),
                  np.concatenate([fxi, Jfeta]) / -hf], axis=1)
    V = np.stack([np.concatenate([zero, a]), np.concatenate([a / w, zero])], axis=1)
    r2 = np.sqrt(0.5)
    ep, em = np.exp(1j * th), np.exp(-1j * th)
    n = w.size
    Uxi, Ueta = U[:n], U[n:]
    Vxi, Veta = V[:n], V[n:]
    X = np.concatenate([(Uxi - 1j * Ueta) * r2, (Uxi + 1j * Ueta) * r2])
    Y = np.concatenate([(Vxi + 1j * Veta) * (r2 * ep)[:, None],
                        (Vxi - 1j * Veta) * (r2 * em)[:, None]])
    return {"mu": np.concatenate([ep, em]), "X": X, "Y": Y,
            "krein_weights": np.concatenate([1.0 / w, -1.0 / w]), "angles": th,
            "U": U, "V": V, "z0": np.concatenate([xi0, eta0])}


def _krein_dense_reference(p: NDofImpactProblem, y: np.ndarray, mult: np.ndarray
                           ) -> np.ndarray:
    """:meth:`_krein_dense` by its direct formulas (the reference)."""
    st = _structure_reference(p, y)
    n = p.N
    c, s = np.cos(st["angles"]), np.sin(st["angles"])
    D = np.block([[np.diag(c), np.diag(s)], [-np.diag(s), np.diag(c)]])
    A = D + st["U"] @ (st["V"].T @ D)
    lam, V = np.linalg.eig(A)
    V = V[:, np.argmin(np.abs(lam[None, :] - np.asarray(mult)[:, None]), axis=1)]
    xi, eta = V[:n], V[n:]
    iw = 1.0 / p.omega[:, None]
    g = 2.0 * np.sum(np.imag(np.conj(xi) * eta) * iw, axis=0)
    nrm = np.sum((np.abs(xi) ** 2 + np.abs(eta) ** 2) * iw, axis=0)
    return g / nrm


def _energy_map(p: NDofImpactProblem, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(S DF S^-1, S)`` from the physical return map (A.8)."""
    n = p.N
    S = np.zeros((2 * n, 2 * n))
    S[:n, :n] = p.omega[:, None] * p.Pinv
    S[n:, n:] = p.Pinv
    return S @ p.return_map_jacobian(y) @ np.linalg.inv(S), S


def _bits(x: np.ndarray) -> bytes:
    return np.ascontiguousarray(x).tobytes()


@pytest.mark.parametrize("formulation", ["half_angle", "shooting"])
def test_structure_is_the_physical_return_map(formulation: str) -> None:
    p = _problem(formulation)
    pts = _points(p)
    assert len(pts) > 25
    for y in pts:
        st = p.return_map_structure(y)
        ref = _structure_reference(p, y)
        assert st.keys() == ref.keys()
        for k in st:
            assert st[k].dtype == ref[k].dtype and st[k].shape == ref[k].shape
            assert _bits(st[k]) == _bits(ref[k]), k
        E, S = _energy_map(p, y)
        c, s = np.cos(st["angles"]), np.sin(st["angles"])
        D = np.block([[np.diag(c), np.diag(s)], [-np.diag(s), np.diag(c)]])
        DF = (np.eye(D.shape[0]) + st["U"] @ st["V"].T) @ D
        assert np.max(np.abs(DF - E)) <= 1e-9 * np.max(np.abs(E))
        u0, du0, _ = p.state(y)
        assert np.allclose(st["z0"], S @ np.concatenate([u0, du0]), rtol=1e-13, atol=1e-13)
        lam = np.sort_complex(np.linalg.eigvals(np.diag(st["mu"]) + st["X"] @ st["Y"].T))
        ref_lam = np.sort_complex(np.linalg.eigvals(E))
        d = np.abs(lam[:, None] - ref_lam[None, :]).min(axis=1)
        assert np.max(d) <= 1e-6 * max(1.0, np.max(np.abs(ref_lam)))


def test_krein_dense_equals_the_eigenvectors_of_the_physical_map() -> None:
    """``_krein_dense`` at the multipliers of :meth:`floquet_dense`: the same bits as the
    reference implementation, and the definiteness of the eigenvectors of ``S DF S^-1`` for
    every multiplier separated from the others (elsewhere the eigenvector is not defined);
    in ``[-1, 1]``, opposite for conjugates, and 0 off the circle (to 1e-6)."""
    p = _problem()
    checked = 0
    for y in _points(p):
        t = np.linalg.svd(p.jacobian(y))[2][-1]
        fl = p.floquet_dense(y, t)
        if fl is None:
            continue
        mult = np.asarray(fl.multipliers, dtype=complex)
        kappa = p._krein_dense(y, mult)
        assert _bits(kappa) == _bits(_krein_dense_reference(p, y, mult))
        assert np.all(np.abs(kappa) <= 1.0 + 1e-12)
        E, _ = _energy_map(p, y)
        lam, vec = np.linalg.eig(E)
        iw = 1.0 / p.omega
        n = p.N
        for m, k in zip(mult, kappa, strict=True):
            gaps = np.sort(np.abs(lam - m))
            if gaps[1] < 1e-3 or gaps[0] > 1e-8:
                continue
            v = vec[:, np.argmin(np.abs(lam - m))]
            xi, eta = v[:n], v[n:]
            ref = 2.0 * np.sum(np.imag(np.conj(xi) * eta) * iw) / np.sum(
                (np.abs(xi) ** 2 + np.abs(eta) ** 2) * iw)
            assert abs(k - ref) <= 1e-6, (m, k, ref)
            if abs(abs(m) - 1.0) > 1e-4:
                assert abs(k) <= 1e-6
            checked += 1
        conj = [np.argmin(np.abs(mult - np.conj(z))) for z in mult]
        sep = np.array([np.sort(np.abs(mult - z))[1] > 1e-3 for z in mult])
        assert np.allclose(kappa[sep], -kappa[conj][sep], atol=1e-6)
    assert checked > 100
