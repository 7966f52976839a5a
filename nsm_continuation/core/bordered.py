"""The bordered matrix of pseudo-arclength continuation and its factorisations.

Every linear solve of the engine (:mod:`nsm_continuation.core.palc`) is with a bordered matrix
``A = [G_y(y); r^T]`` (``(n + 1) x (n + 1)``): the Newton corrector (``r`` the reference
tangent), the tangent (``r`` the previous tangent, right-hand side ``e_(n+1)``), and the
branch-point test function ``det A`` (``r`` the tangent at ``y``: it changes sign where the
branch crosses another, Keller's bordering; Govaerts, *Numerical methods for bifurcations of
dynamical equilibria*, SIAM 2000, ch. 3). A problem supplies the factorisation through
:meth:`nsm_continuation.core.problem.Problem.bordered_factor`: by default the dense one here (LAPACK
``gesv`` and ``getrf``, what the engine always used); a problem with structure supplies its own
(the chain's, :class:`DiagonalBorderedFactor`: ``O(N^2)`` instead of ``O(N^3)``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class BorderedFactor(ABC):
    """A factorisation of ``A = [G_y(y); r^T]``: solves and the (signed, log) determinant."""

    @abstractmethod
    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b``; raises ``numpy.linalg.LinAlgError`` if ``A`` is singular."""

    @abstractmethod
    def slogdet(self) -> tuple[float, float]:
        """``(sign, log|det A|)`` as :func:`numpy.linalg.slogdet`."""


class DenseBorderedFactor(BorderedFactor):
    """The dense matrix, solved by LAPACK each time (the default, exact for every problem)."""

    def __init__(self, jacobian: np.ndarray, row: np.ndarray) -> None:
        self.A = np.vstack([jacobian, row[None, :]])

    def solve(self, b: np.ndarray) -> np.ndarray:
        return np.linalg.solve(self.A, b)

    def slogdet(self) -> tuple[float, float]:
        sign, logdet = np.linalg.slogdet(self.A)
        return float(sign), float(logdet)


class DiagonalBorderedFactor(BorderedFactor):
    """``A = A~ blockdiag(W, I_k)`` with ``A~`` a diagonal bordered by ``k`` rows and columns:

    ``A~ = [[diag(d), C], [R, E]]``  (``d``: length ``m``; ``C``: ``m x k``; ``R``: ``k x m``;
    ``E``: ``k x k``), and ``W`` an ``m x m`` change of variables ``z = W x`` of the first
    ``m`` unknowns (the chain's modal coordinates ``q = P^-1 u``: ``W = P^-1``, ``W^-1 = P``).

    Elimination of the diagonal entries with ``|d_j| >= threshold * max|d|`` leaves a dense
    system for the other (few) entries and the border, of size ``k + #small``: the Schur
    complement. Entries of ``d`` that vanish (the chain's ``sin(w_j T / 2)`` at a pole
    ``T = 2 pi l / w_j``) stay in that small system, so ``A`` is solved wherever it is regular,
    however singular ``diag(d)`` is. One step of iterative refinement with the exact product
    (``apply``) restores the accuracy the eliminated pivots (at least ``threshold``) may cost.
    ``O(m^2)`` per solve (two products with ``W`` or ``W^-1``) against ``O(m^3)`` dense.

    ``log|det A| = sum log|d_j| (eliminated) + log|det S| + log|det W|``, with the sign
    likewise (a symmetric permutation leaves the determinant unchanged).
    """

    #: diagonal entries below this fraction of the largest stay in the dense Schur system
    THRESHOLD = 1e-3

    def __init__(self, d: np.ndarray, C: np.ndarray, R: np.ndarray, E: np.ndarray,
                 W: np.ndarray, Winv: np.ndarray, W_slogdet: tuple[float, float]) -> None:
        self.d, self.C, self.R, self.E = d, C, R, E
        self.W, self.Winv, self.W_slogdet = W, Winv, W_slogdet
        m, k = C.shape
        scale = float(np.max(np.abs(d))) if m else 0.0
        small = np.abs(d) < self.THRESHOLD * scale
        self.good = np.flatnonzero(~small)
        self.bad = np.flatnonzero(small)
        g, b = self.good, self.bad
        dg = d[g]
        # Schur complement on (bad modal entries, border): rows/columns ordered (bad, border)
        nb = b.size
        S = np.zeros((nb + k, nb + k))
        S[:nb, :nb] = np.diag(d[b])
        S[:nb, nb:] = C[b]
        S[nb:, :nb] = R[:, b]
        S[nb:, nb:] = E - (R[:, g] / dg) @ C[g]
        self.S = S
        self._dg = dg

    def _solve_structured(self, rhs: np.ndarray) -> np.ndarray:
        """``A~^-1 rhs`` by elimination of the large diagonal entries."""
        m = self.d.size
        g, b = self.good, self.bad
        top, tail = rhs[:m], rhs[m:]
        red = np.concatenate([top[b], tail - self.R[:, g] @ (top[g] / self._dg)])
        try:
            w = np.linalg.solve(self.S, red)
        except np.linalg.LinAlgError:
            raise np.linalg.LinAlgError("Singular matrix") from None
        nb = b.size
        border = w[nb:]
        z = np.empty(m)
        z[b] = w[:nb]
        z[g] = (top[g] - self.C[g] @ border) / self._dg
        return np.concatenate([z, border])

    def apply(self, x: np.ndarray) -> np.ndarray:
        """``A x`` (exact: two products with ``W``)."""
        m = self.d.size
        z = self.W @ x[:m]
        tail = x[m:]
        return np.concatenate([self.d * z + self.C @ tail, self.R @ z + self.E @ tail])

    def _solve_once(self, b: np.ndarray) -> np.ndarray:
        m = self.d.size
        zt = self._solve_structured(b)
        # A = A~ blockdiag(W, I): x = (W^-1 z, tail)
        return np.concatenate([self.Winv @ zt[:m], zt[m:]])

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        x = self._solve_once(b)
        return x + self._solve_once(b - self.apply(x))

    def slogdet(self) -> tuple[float, float]:
        sign_s, log_s = np.linalg.slogdet(self.S)
        dg = self._dg
        sign = float(sign_s) * float(np.prod(np.sign(dg))) * self.W_slogdet[0]
        return sign, float(log_s + np.sum(np.log(np.abs(dg))) + self.W_slogdet[1])
