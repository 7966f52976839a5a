"""Closed-form orbits of the chain and the spectrum of ``w_N`` (Legrand, Junca, Heng 2017).

:class:`ChainClosedForm` (a mixin of
:class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`): the vector ``w(T)``
(4.1b) and its impacting entry ``w_N(T)`` (3.1), the one-impact orbit at a given period (4.2)/(7.1)
and its displacement ``u_c(t)`` as a sum of sinusoids (5.4); the poles ``k T_j`` of ``w_N``, its
roots (the ``g = 0`` spectrum of Prop. 7.2, :meth:`ChainClosedForm.static_grazing_spectrum`), the
linear grazing energies and the internal resonances of Assumption 3.1.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from nsm_continuation.problems.chain.trig_sum import TrigSum

from nsm_continuation.core.roots import illinois


class ChainClosedForm:
    """The closed form (4.1)-(4.2), (5.4), (7.1) and the poles and roots of ``w_N`` (3.1)."""

    N: int
    c: int
    g: float
    omega: np.ndarray
    P: np.ndarray
    Pinv: np.ndarray
    T_lin: np.ndarray
    a: np.ndarray
    #: (the branches, their static grazing spectrum): see :meth:`static_grazing_spectrum`
    _spectrum_cache: tuple[list[Any], list[dict[str, Any]]] | None

    def w_vector(self, T: float | np.ndarray) -> np.ndarray:
        """``w(T) = P Phi(T) P^-1 e_c`` (4.1b); ``Phi = Omega^-1 cot(T Omega / 2)``."""
        phi = 1.0 / (self.omega * np.tan(self.omega * np.asarray(T)[..., None] / 2))
        return (phi * self.Pinv[:, self.c]) @ self.P.T

    def w_N(self, T: float | np.ndarray) -> np.ndarray:
        """``w_N(T) = sum_j a_j / (w_j tan(w_j T / 2))`` (3.1), for the impacting dof."""
        T = np.asarray(T, dtype=float)
        return np.sum(self.a / (self.omega * np.tan(np.multiply.outer(T, self.omega) / 2)),
                      axis=-1)

    def closed_form(self, T: float, g: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Initial data (4.2)/(7.1): ``u(0) = (g / w_N) w(T)``, ``u'(0+) = (g / w_N) e_c``."""
        g = self.g if g is None else g
        w = self.w_vector(T)
        v = g / w[self.c]
        du = np.zeros(self.N)
        du[self.c] = v
        return v * w, du

    def displacement_sum(self, y: np.ndarray) -> TrigSum:
        """``u_c(t)`` on ``0 < t < T`` as a sum of sinusoids (5.4)."""
        u0, du0, _ = self.state(y)
        q = self.Pinv @ u0
        p = self.Pinv @ du0
        Pc = self.P[self.c, :]
        return TrigSum(Pc * q, Pc * p / self.omega, self.omega.copy())

    def count_poles(self, T_lo: float, T_hi: float, kmax: int) -> int:
        """Number of poles ``k T_j`` (``k <= kmax``) in ``[T_lo, T_hi]``, in O(N)."""
        T = self.T_lin
        k_lo = np.maximum(np.ceil(T_lo / T), 1)
        k_hi = np.minimum(np.floor(T_hi / T), kmax)
        return int(np.sum(np.maximum(k_hi - k_lo + 1, 0)))

    def poles(self, T_lo: float, T_hi: float, kmax: int) -> list[tuple[float, int, int]]:
        """Poles ``k T_j`` of ``w_N`` in ``[T_lo, T_hi]``: (T, mode j 0-based, k). Only the
        ``k`` near ``[T_lo, T_hi] / T_j`` are visited (O(number of poles), whatever ``kmax``)."""
        out = []
        for j, Tj in enumerate(self.T_lin):
            k_first = int(max(1.0, min(np.floor(T_lo / Tj), kmax + 1.0)))
            k_last = int(min(float(kmax), np.ceil(T_hi / Tj)))
            for k in range(k_first, k_last + 1):
                if T_lo <= k * Tj <= T_hi:
                    out.append((k * Tj, j, k))
        return sorted(out)

    def zeros_of_w_N(self, T_lo: float, T_hi: float, kmax: int = 1000) -> np.ndarray:
        """Roots of ``w_N`` in ``(T_lo, T_hi)``: each sign change of ``w_N`` on a grid of 400
        points between consecutive poles, closed by the Illinois iteration to ``1e-15 + 4 eps T``
        (a pole between two grid points is not a root: ``|w_N|`` must be small there)."""
        poles = [p[0] for p in self.poles(1e-12, T_hi * (1 + 1e-12), kmax)]
        edges = sorted({T_lo, T_hi, *[p for p in poles if T_lo < p < T_hi]})
        roots = []
        for lo, hi in zip(edges[:-1], edges[1:], strict=False):
            eps = 1e-9 * (hi - lo)
            grid = np.linspace(lo + eps, hi - eps, 400)
            vals = self.w_N(grid)
            for i in np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]:
                r = illinois(lambda t: (float(self.w_N(t)), None), grid[i], float(vals[i]),
                             grid[i + 1], float(vals[i + 1]),
                             tol=1e-15 + 4 * np.finfo(float).eps * grid[i + 1], close=True)[0]
                if abs(self.w_N(r)) < 1e-6 * (1 + abs(vals[i]) + abs(vals[i + 1])):
                    roots.append(r)
        return np.array(roots)

    def polish_root(self, T0: float) -> float:
        """Root of ``w_N`` near ``T0`` by Newton on the closed form (``w_N' < 0`` between poles
        when every ``a_j > 0``; falls back to ``T0`` if Newton leaves the neighbourhood)."""
        T = T0
        for _ in range(50):
            h = 1e-7 * T
            d = (self.w_N(T + h) - self.w_N(T - h)) / (2 * h)
            step = float(self.w_N(T) / d)
            T -= step
            if abs(step) < 1e-15 * T:
                break
        return float(T) if abs(T - T0) < 1e-3 * T0 else float(T0)

    def grazing_energy(self, j: int) -> float:
        """Energy of the linear grazing orbit of mode ``j`` (0-based): top of its flat part."""
        return 0.5 * (self.g / self.P[self.c, j]) ** 2 * self.omega[j] ** 2

    def internal_resonances(self, kmax: int = 10, rtol: float = 1e-9) -> list[str]:
        """Pairs ``k T_j = l T_i`` (i != j, k, l <= kmax): Assumption 3.1 violated there."""
        out = []
        for j in range(self.N):
            for i in range(j + 1, self.N):
                r = self.omega[i] / self.omega[j]
                for lden in range(1, kmax + 1):
                    knum = round(r * lden)
                    if 1 <= knum <= kmax and abs(r * lden - knum) < rtol * r * lden:
                        out.append(f"internal resonance: {knum} T_{i + 1} = {lden} T_{j + 1} "
                                   f"(omega_{i + 1}/omega_{j + 1} = {knum}/{lden}); "
                                   "Assumption 3.1 is violated and branches through these "
                                   "poles are not covered by Theorem 3.1")
                        break
        return out

    def static_grazing_spectrum(self, branches: list[Any]) -> list[dict[str, Any]]:
        """For g = 0 (Prop. 7.2): each branch point of ``branches`` polished to a root of
        ``w_N``, with its admissibility. Cached for the last list of branches (the report and
        the figure both use it; the branches are compared by identity)."""
        if self.g != 0.0:
            return []
        hit = self._spectrum_cache
        if hit is not None and len(hit[0]) == len(branches) and all(
                a is b for a, b in zip(hit[0], branches, strict=True)):
            return [dict(s) for s in hit[1]]
        spec = []
        for br in branches:
            for ev in br.events:
                if ev.kind == "branch_point":
                    T_bp = float(ev.point.y[-1])
                    T = self.polish_root(T_bp)
                    spec.append({"T": T, "omega": 2 * np.pi / T, "T_branch_point": T_bp,
                                 "w_N(T_branch_point)": float(self.w_N(T_bp)),
                                 "admissible": self.static_grazing_admissible(T)})
        self._spectrum_cache = (list(branches), spec)
        return [dict(s) for s in spec]

