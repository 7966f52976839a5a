"""The modal model of the chain (Legrand, Junca, Heng 2017, eqs. 2.9-2.11).

:func:`generalized_eigh` solves ``K P = M P Omega^2`` with ``P^T M P = I`` (2.9);
:class:`ModalModel` holds the matrices, the linear frequencies ``omega_j``, the periods
``T_j = 2 pi / omega_j`` and the interaction coefficients ``a_j = P_cj (P^-1)_jc`` (2.11), all
computed on first use (nothing of size ``N^2`` is built before the sizes are checked).
"""

from __future__ import annotations

from functools import cached_property
from typing import ClassVar

import numpy as np
from nsm_continuation.problems.chain.parameters import NDofParameters


def generalized_eigh(K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The modal analysis (2.9): ``K P = M P diag(w2)`` with ``P^T M P = I``, ``w2`` ascending,
    for symmetric ``K`` and symmetric positive definite ``M``. The reduction LAPACK's
    ``sygvd`` makes (what ``scipy.linalg.eigh(K, M)`` calls): ``M = L L^T``,
    ``C = L^-1 K L^-T``, ``C Q = Q diag(w2)``, ``P = L^-T Q``, in numpy alone: a run of the
    chain then never imports SciPy (0.16 s of its start-up, ``benchmarks/bench_startup.py``).
    Raises ``numpy.linalg.LinAlgError`` if ``M`` is not positive definite."""
    L = np.linalg.cholesky(M)
    A = np.linalg.solve(L, K)
    C = np.linalg.solve(L, A.T)  # L^-1 K L^-T (K symmetric)
    w2, Q = np.linalg.eigh(0.5 * (C + C.T))
    return w2, np.linalg.solve(L.T, Q)


class ModalModel:
    """The matrices and modal data of a chain (``params``) impacting at dof ``c`` (0-based),
    each computed on first use."""

    #: largest relative error of omega_1^2 accepted from the modal analysis, ~ eps (w_N/w_1)^2
    MODAL_RESOLUTION: ClassVar[float] = 1e-6

    def __init__(self, params: NDofParameters, c: int) -> None:
        self.params = params
        self.c = c

    @cached_property
    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """``(M, K)``, built on first use."""
        with np.errstate(over="ignore", invalid="ignore"):  # checked in decomposition
            return self.params.matrices()

    @property
    def M(self) -> np.ndarray:
        """Mass matrix (built on first use)."""
        return self.matrices[0]

    @property
    def K(self) -> np.ndarray:
        """Stiffness matrix (built on first use)."""
        return self.matrices[1]

    @property
    def matrix_key(self) -> str:
        return "parameters.chain" if self.params.chain is not None else "parameters.K"

    @cached_property
    def decomposition(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Modal data (2.9) ``P^T M P = I, P^T K P = Omega^2``: ``(omega, P, P^-1)``, computed
        on first use (O(N^3)); raises ``ValueError`` naming the parameters if it fails."""
        M, K = self.M, self.K
        if not (np.isfinite(M).all() and np.isfinite(K).all()):
            raise ValueError(f"{self.matrix_key}: the mass or stiffness matrix overflows "
                             "(an entry beyond 1.8e308)")
        try:
            w2, P = generalized_eigh(K, M)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise ValueError(f"{self.matrix_key}: the modal analysis K P = M P Omega^2 "
                             f"failed ({str(exc).splitlines()[0]})") from None
        if not np.all(np.isfinite(w2)) or np.any(w2 <= 0):
            raise ValueError(f"{self.matrix_key}: K must be positive definite (rigid-body "
                             "modes are excluded)")
        return np.sqrt(w2), P, P.T @ M

    @property
    def omega(self) -> np.ndarray:
        """Linear frequencies ``omega_j`` (ascending)."""
        return self.decomposition[0]

    @property
    def P(self) -> np.ndarray:
        """Mass-normalised mode shapes (columns)."""
        return self.decomposition[1]

    @property
    def Pinv(self) -> np.ndarray:
        return self.decomposition[2]

    @property
    def T_lin(self) -> np.ndarray:
        """Linear periods ``T_j = 2 pi / omega_j``."""
        return 2 * np.pi / self.omega

    @cached_property
    def a(self) -> np.ndarray:
        """Interaction coefficients (2.11) ``a_j = P_cj (P^-1)_jc``."""
        return self.P[self.c, :] * self.Pinv[:, self.c]

    @cached_property
    def Pinv_slogdet(self) -> tuple[float, float]:
        """``(sign, log |det P^-1|)``."""
        sign, logdet = np.linalg.slogdet(self.Pinv)
        return float(sign), float(logdet)

    def check_resolution(self) -> None:
        """The modal analysis succeeds and resolves omega_1 (relative error ~ eps (w_N/w_1)^2)."""
        omega = self.omega  # raises ValueError naming the parameters
        ratio = float(omega[-1] / omega[0])
        err = np.finfo(float).eps * ratio**2
        if err > self.MODAL_RESOLUTION:
            raise ValueError(
                f"{self.matrix_key}: the linear frequencies span omega_N / omega_1 = "
                f"{ratio:.3g}, so double precision resolves omega_1^2 only to ~{err:.1g} "
                f"(relative; at most {self.MODAL_RESOLUTION:g} accepted): make the masses and "
                "stiffnesses less disparate")
        for name, v in (("omega_N", omega[-1]), ("omega_1", omega[0])):
            if not 1e-100 <= v <= 1e100:
                raise ValueError(f"{self.matrix_key}: the linear frequency {name} = {v:.3g} "
                                 "is outside [1e-100, 1e100]: rescale masses and stiffnesses")

