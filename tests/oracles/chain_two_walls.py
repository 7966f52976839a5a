r"""The chain of Legrand, Junca, Heng (2017) with its last mass between two walls ``|u_c| <= g``
(``e = 1``): the symmetric orbits in closed form, their monodromy with saltation matrices, and
an independent event-driven simulation by the exact flow (numpy/scipy only: nothing of the
package is imported).

Between impacts ``X' = A X``, ``X = (u, u')``, ``A = [[0, I], [-M^-1 K, 0]]``, exactly
``X(t) = expm(A t) X(0)``; at ``u_c = +-g`` Newton's law with ``e = 1``: ``X+ = R X-`` with
``R = diag(I, I - 2 e_c e_c^T)``.

**Symmetric orbit.** ``u(t + T/2) = -u(t)``, an impact on the upper wall at ``t = 0`` and on the
lower one at ``t = T/2``: with ``X0`` the post-impact state and ``S = diag(I, I - 2 e_c e_c^T)``,
the half-period flight ends in the reflected pre-impact state, ``expm(A T/2) X0 = -S X0``: ``X0``
spans the kernel of ``expm(A T/2) + S`` (found by an SVD, scaled to ``u_c(0) = g``). No modal
decomposition and no assumption on which dofs move at impact.

**Monodromy.** From ``X0``: flight ``E = expm(A T/2)``, impact on the lower wall, flight,
impact on the upper wall; each impact's saltation matrix for ``h(X) = 0`` (``h = g - u_c`` or
``u_c + g``, ``n = grad h``): ``S_i = R + (F+ - R F-) n^T / (n^T F-)`` (``F-- = A X-``,
``F+ = A R X-``). ``Phi_T = S_up E S_low E``: its eigenvalues are the ``+1`` of the flow, the
``+1`` of the family and ``2N - 2`` others.

**Direct simulation** (:func:`simulate`): the exact flow sampled on a grid, the first crossing of
either wall bracketed and refined by ``brentq``, reflected; the impacts (time, wall, velocity)
and the final state. :func:`return_map` is the map from the upper wall (post-impact,
``u_c = g``) back to it after ``k`` impacts, whose finite-difference Jacobian cross-checks the
saltation monodromy.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq


def chain_matrices(N: int, m: float, k: float) -> tuple[np.ndarray, np.ndarray]:
    """``M`` and ``K`` of the chain wall - k - m - k - ... - k - m (free end), eq. (2.17)."""
    K = 2 * k * np.eye(N) - k * (np.eye(N, k=1) + np.eye(N, k=-1))
    K[-1, -1] = k
    return m * np.eye(N), K


class TwoWallChain:
    """The chain (``N`` masses ``m``, springs ``k``) with dof ``c`` (0-based) in ``|u_c| <= g``."""

    def __init__(self, N: int, m: float, k: float, g: float, c: int | None = None) -> None:
        self.N, self.g = N, g
        self.c = N - 1 if c is None else c
        self.M, self.K = chain_matrices(N, m, k)
        Z = np.zeros((N, N))
        self.A = np.block([[Z, np.eye(N)], [-np.linalg.solve(self.M, self.K), Z]])
        self.R = np.eye(2 * N)
        self.R[N + self.c, N + self.c] = -1.0
        self.omega = np.sqrt(np.linalg.eigvals(np.linalg.solve(self.M, self.K)).real)
        self.omega.sort()
        self._w, self._V = np.linalg.eig(self.A)
        self._Vinv = np.linalg.inv(self._V)

    def energy(self, X: np.ndarray) -> float:
        u, du = X[: self.N], X[self.N:]
        return float(0.5 * (du @ self.M @ du + u @ self.K @ u))

    def symmetric_orbit(self, T: float) -> np.ndarray:
        """The post-impact state on the upper wall of the symmetric orbit of period ``T``."""
        E = expm(self.A * T / 2)
        _, s, Vt = np.linalg.svd(E + self.R)
        X = Vt[-1]
        return X * self.g / X[self.c]

    def _saltation(self, X: np.ndarray, sign: float) -> np.ndarray:
        n = np.zeros(2 * self.N)
        n[self.c] = -sign  # upper (sign +1): h = g - u_c; lower (sign -1): h = u_c + g
        Fm, Fp = self.A @ X, self.A @ (self.R @ X)
        return self.R + np.outer(Fp - self.R @ Fm, n) / (n @ Fm)

    def monodromy(self, T: float) -> np.ndarray:
        """``Phi_T`` of the symmetric orbit from its post-impact state on the upper wall."""
        X0 = self.symmetric_orbit(T)
        E = expm(self.A * T / 2)
        Xl = E @ X0
        Xu = E @ (self.R @ Xl)
        return self._saltation(Xu, +1.0) @ E @ self._saltation(Xl, -1.0) @ E

    def multipliers(self, T: float) -> np.ndarray:
        """The ``2N - 2`` multipliers of the symmetric orbit: ``Phi_T``'s without the two
        nearest ``+1``."""
        lam = np.linalg.eigvals(self.monodromy(T))
        drop = np.argsort(np.abs(lam - 1.0))[:2]
        return np.delete(lam, drop)

    def u_c(self, X0: np.ndarray, t: np.ndarray) -> np.ndarray:
        """``u_c`` of the free flight from ``X0`` at the times ``t``."""
        a = (self._Vinv * np.asarray(X0, dtype=float)).sum(axis=1)
        return (np.exp(np.multiply.outer(t, self._w)) * (self._V[self.c] * a)).sum(axis=1).real

    def flow(self, X0: np.ndarray, t: float) -> np.ndarray:
        """The free flight's state at ``t`` from ``X0`` (by the eigenvectors of ``A``; the
        element-wise sums keep this small algebra off the threaded BLAS)."""
        a = (self._Vinv * np.asarray(X0, dtype=float)).sum(axis=1)
        return (self._V * (np.exp(self._w * t) * a)).sum(axis=1).real

    def section_state(self, X0: np.ndarray, value: float, t_max: float) -> np.ndarray:
        """The state where the free flight from ``X0`` first falls through ``u_c = value``."""
        ts = np.linspace(0.0, t_max, int(t_max * 500) + 2)[1:]
        k = int(np.nonzero(self.u_c(X0, ts) < value)[0][0])
        t = brentq(lambda s: self.u_c(X0, np.array([s]))[0] - value, ts[k - 1], ts[k],
                   xtol=1e-15, rtol=4 * np.finfo(float).eps)
        X = self.flow(X0, t)
        X[self.c] = value
        return X

    def simulate(self, X0: np.ndarray, n_impacts: int, t_max: float,
                 samples_per_unit: int = 500) -> tuple[list[tuple[float, str, float]],
                                                        np.ndarray, float]:
        """``n_impacts`` impacts from ``X0`` (none before ``t_max``: an error): each ``(time,
        wall, pre-impact velocity of u_c)``, the post-impact state after the last, its time."""
        X, t0, out = np.asarray(X0, dtype=float).copy(), 0.0, []
        for _ in range(n_impacts):
            ts = np.linspace(0.0, t_max, int(t_max * samples_per_unit) + 2)[1:]
            u = self.u_c(X, ts)
            up = np.nonzero(u > self.g)[0]
            lo = np.nonzero(u < -self.g)[0]
            k = min(up[0] if up.size else ts.size, lo[0] if lo.size else ts.size)
            if k >= ts.size:
                raise RuntimeError("no impact before t_max")
            sign = 1.0 if u[k] > self.g else -1.0
            a = ts[k - 1] if k > 0 else 1e-12
            Xs = X.copy()
            t = brentq(lambda s, Xs=Xs, sign=sign: sign * self.u_c(Xs, np.array([s]))[0] - self.g,
                       a, ts[k],
                       xtol=1e-15, rtol=4 * np.finfo(float).eps)
            Xm = self.flow(X, t)
            out.append((t0 + t, "upper" if sign > 0 else "lower", float(Xm[self.N + self.c])))
            X = self.R @ Xm
            X[self.c] = sign * self.g
            t0 += t
        return out, X, t0

    def return_map(self, z: np.ndarray, n_impacts: int, t_max: float) -> np.ndarray:
        """The map from the upper wall back to it after ``n_impacts`` impacts, in the
        coordinates ``z`` = the post-impact state without ``u_c`` (fixed at ``g``)."""
        X = np.insert(np.asarray(z, dtype=float), self.c, self.g)
        _, Xe, _ = self.simulate(X, n_impacts, t_max)
        return np.delete(Xe, self.c)
