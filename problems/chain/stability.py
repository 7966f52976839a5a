"""Stability of the chain's orbits: the linearised first return map, its Floquet multipliers
and their Krein signatures (Legrand, Junca, Heng 2017, sec. 3.2, sec. 6, Appendix A).

:class:`ChainStability` (a mixin of
:class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`): ``Gamma(T)`` (A.1), the
Jacobian ``DF`` of the first return map (A.7)-(A.8) densely and as a rotation plus a rank-two
saltation term (3.5), the non-trivial multipliers (the trivial ``1`` deflated with the branch
tangent, eq. 6.5) from that structure or densely, and the Krein definiteness of each multiplier
(the impact conserves energy, Prop. 6.1). :class:`MultiplierMemory` keeps the multipliers of the
last calls as starts of the next.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from nsm_continuation.core.floquet import (
    KreinFloquetData,
    deflate_known_eigenvector,
    krein_definiteness,
    low_rank_update_eigen,
    refine_roots,
    restrict_to_section,
)
from nsm_continuation.core.problem import FloquetData


class MultiplierMemory:
    """Multipliers of the last :meth:`ChainStability.floquet` calls with their point ``y``: the
    start of the next call is extrapolated from the sets computed at the nearest points
    (:meth:`nearest_guess`; event location bisects inside a step: the points computed so far
    around it are the best start), and their lineage (sets of one lineage were started from
    each other: multiplier k of one is multiplier k of the other)."""

    #: how many multiplier sets :meth:`ChainStability.floquet` remembers as starts
    MULTIPLIER_MEMORY: ClassVar[int] = 8
    #: :meth:`nearest_guess`: a multiplier that moved more than this between the two
    #: nearest remembered points is not extrapolated (a jump, or not the same multiplier)
    EXTRAPOLATE_MAX_MOVE: ClassVar[float] = 0.05
    #: :meth:`nearest_guess`: no extrapolation farther than this many secant lengths
    EXTRAPOLATE_MAX_SECANTS: ClassVar[float] = 2.0

    def __init__(self) -> None:
        #: ``(y, multipliers, lineage)`` of the last calls, oldest first
        self.entries: list[tuple[np.ndarray, np.ndarray, int]] = []
        #: the last lineage number given out
        self.lineages = 0

    def clear(self) -> None:
        """Forget the remembered sets (the next call starts cold)."""
        self.entries.clear()

    def nearest_guess(self, y: np.ndarray) -> tuple[np.ndarray, int] | None:
        """The start of the Aberth iteration at the point ``y`` and its lineage: the
        multipliers ``m1`` remembered at the nearest point ``y1``, extrapolated linearly along
        the secant to the second nearest ``y2`` (multipliers ``m2``): ``m1 + s (m1 - m2)``
        with ``s = (y - y1).(y1 - y2) / |y1 - y2|^2`` (the projection of ``y`` on the line
        through ``y1`` and ``y2``; ``-1 < s < 0`` interpolates, as when an event is located
        inside a step). Only sets of one lineage pair by index (multiplier ``k`` of one set
        descends from multiplier ``k`` of the set it was started from); one that moved by
        more than ``EXTRAPOLATE_MAX_MOVE`` between ``y2`` and ``y1`` (a jump) is not
        extrapolated, nor is anything beyond ``EXTRAPOLATE_MAX_SECANTS``. The start only
        changes the number of sweeps, not the roots the iteration converges to."""
        if not self.entries:
            return None
        y = np.asarray(y, dtype=float)
        mem = sorted(self.entries, key=lambda e: float(np.linalg.norm(e[0] - y)))
        y1, m1, lin = mem[0]
        other = [e for e in mem[1:]
                 if e[2] == lin and e[1].shape == m1.shape and not np.array_equal(e[0], y1)]
        if not other:
            return m1, lin
        y2, m2, _ = other[0]
        dy = y1 - y2
        nn = float(dy @ dy)
        if nn == 0.0:
            return m1, lin
        step = float((y - y1) @ dy) / nn
        if not abs(step) <= self.EXTRAPOLATE_MAX_SECANTS:
            return m1, lin
        delta = m1 - m2
        return np.where(np.abs(delta) <= self.EXTRAPOLATE_MAX_MOVE, m1 + step * delta, m1), lin

    def remember(self, y: np.ndarray, mult: np.ndarray,
                 lineage: int | None) -> None:
        """Remember ``mult`` at ``y``; ``lineage`` None: a new lineage (a cold start)."""
        if lineage is None:
            self.lineages += 1
            lineage = self.lineages
        self.entries.append((np.array(y, dtype=float), mult, lineage))
        del self.entries[:-self.MULTIPLIER_MEMORY]


class ChainStability:
    """The linearised first return map of the chain, its multipliers and their Krein
    definiteness."""

    N: int
    c: int
    g: float
    formulation: str
    omega: np.ndarray
    P: np.ndarray
    Pinv: np.ndarray
    M: np.ndarray
    multiplier_memory: MultiplierMemory
    #: :meth:`floquet` calls answered by the dense method (structured iteration failed)
    floquet_fallbacks: int

    #: up to this many dofs the multipliers are the dense eigenvalues (:meth:`floquet_dense`:
    #: below ~40 dofs LAPACK beats the O(N^2) iteration's per-sweep overhead), above it they
    #: come from the structure (:meth:`floquet`); the Krein definiteness always does
    DENSE_MULTIPLIERS_UP_TO: ClassVar[int] = 40
    #: :meth:`floquet` of a conservative chain: multipliers farther than this from the unit
    #: circle (their accuracy is ~1e-10) are off it, with Krein definiteness 0 exactly
    #: (:func:`~nsm_continuation.core.floquet.krein_definiteness`, ``off_circle``)
    KREIN_OFF_CIRCLE: ClassVar[float] = 1e-6

    def gamma(self, T: float) -> tuple[np.ndarray, np.ndarray]:
        """``Gamma(T)`` of (A.1) (flight then impact, physical coordinates) and ``dGamma/dT``."""
        P, Pi, w, c = self.P, self.Pinv, self.omega, self.c
        cw, sw = np.cos(w * T), np.sin(w * T)
        S = np.ones(self.N)
        S[c] = -1.0

        def blocks(cc: np.ndarray, ss: np.ndarray) -> np.ndarray:
            return np.block([[(P * cc) @ Pi, (P * (ss / w)) @ Pi],
                             [S[:, None] * ((P * (-w * ss)) @ Pi), S[:, None] * ((P * cc) @ Pi)]])

        G = blocks(cw, sw)
        # d/dT cos = -w sin, d/dT sin = w cos
        dG = np.block([[(P * (-w * sw)) @ Pi, (P * cw) @ Pi],
                       [S[:, None] * ((P * (-w**2 * cw)) @ Pi),
                        S[:, None] * ((P * (-w * sw)) @ Pi)]])
        return G, dG

    def return_map_jacobian(self, y: np.ndarray) -> np.ndarray:
        """``DF`` of (A.8) in physical coordinates (2N x 2N): ``Gamma + (Gamma' x) grad T`` with
        ``grad T = -e_c^T Gamma / (e_c^T Gamma' x)`` (A.7). Row ``c`` vanishes (F(H) in H)."""
        u0, du0, T = self.state(y)
        x = np.concatenate([u0, du0])
        G, dG = self.gamma(T)
        dGx = dG @ x
        denom = dGx[self.c]  # = u_c'-(T) = -u_c'(0+)
        gradT = -G[self.c, :] / denom
        return G + np.outer(dGx, gradT)

    def return_map_structure(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """The linearised first return map (3.5)/(A.8) as a rotation plus a rank-two term.

        Energy coordinates ``z = (xi, eta)``, ``xi = Omega P^-1 u``, ``eta = P^-1 u'`` (the
        energy is ``|z|^2 / 2``, the symplectic form ``omega = sum_j d xi_j ^ d eta_j / w_j``).
        In them the flight over ``T`` is the orthogonal block rotation ``D`` (block ``j``:
        ``[[cos w_j T, sin w_j T], [-sin w_j T, cos w_j T]]``, eigenvalues ``exp(+-i w_j T)``,
        eigenvectors ``(1, +-i)/sqrt 2``), the impact ``u_c' -> -u_c'`` is
        ``J = I - 2 e_b a_eta^T`` (``b = P^-1 e_c``, ``a = P^T e_c``: a Householder reflector
        when ``M_ck = 0``), and the period gradient (A.7) ``grad T = -h^T D / (h^T f)``
        (``h``: the row of ``u_c``, ``f``: the vector field at the pre-impact state ``D z0``) so
        that (A.8) reads ``DF = J (I - f h^T / h^T f) D``: the *saltation* form,

        ``DF = (I + U V^T) D``,  ``U = [-2 e_b, -J f / (h^T f)]``,  ``V = [a_eta, h]``.

        In the eigenbasis ``Q`` of ``D`` this is ``diag(mu) + X Y^T`` with ``mu_(j,+-) =
        exp(+-i w_j T)``, ``X = Q^H U``, ``Y = diag(mu) Q^T V`` (n x 2): the input of
        :func:`~nsm_continuation.core.floquet.low_rank_update_eigen`. The symplectic form's
        Hermitian
        form ``-i omega(conj v, v)`` is diagonal there, with weights ``+-1/w_j``
        (``krein_weights``). Also returned: ``D``'s angles, ``U``, ``V`` (for
        :meth:`return_map_apply`) and ``z0``.
        """
        th, _, _, U, V, xi0, eta0 = self._saltation(y)
        w = self.omega
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

    def _saltation(self, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(theta, cos theta, sin theta, U, V, xi0, eta0)`` of :meth:`return_map_structure`:
        the flight's angles ``theta_j = w_j T``, the saltation factors ``U = [-2 e_b,
        -J f / (h^T f)]``, ``V = [a_eta, h]`` (``DF = (I + U V^T) D``) and the post-impact state
        ``z0 = (xi0, eta0)`` in energy coordinates; shared with :meth:`_krein_dense` (which
        needs neither ``X``, ``Y`` nor a second evaluation of the sines and cosines)."""
        u0, du0, T = self.state(y)
        w, Pi = self.omega, self.Pinv
        a = self.P[self.c, :]
        b = Pi[:, self.c]
        xi0, eta0 = w * (Pi @ u0), Pi @ du0
        th = w * T
        c, s = np.cos(th), np.sin(th)
        xim, etam = c * xi0 + s * eta0, -s * xi0 + c * eta0  # pre-impact state D z0
        fxi, feta = w * etam, -w * xim                         # vector field there
        hf = float(a @ etam)                                   # h^T f = u_c'-(T) = -v
        Jfeta = feta - 2.0 * b * float(a @ feta)
        n = w.size
        # U = [[0, fxi], [-2 b, J feta]] / [1, -hf], V = [[0, a / w], [a, 0]] (columns)
        U = np.empty((2 * n, 2))
        U[:n, 0] = 0.0
        U[n:, 0] = -2.0 * b
        U[:n, 1] = fxi / -hf
        U[n:, 1] = Jfeta / -hf
        V = np.zeros((2 * n, 2))
        V[n:, 0] = a
        V[:n, 1] = a / w
        return th, c, s, U, V, xi0, eta0

    @staticmethod
    def return_map_apply(st: dict[str, np.ndarray], z: np.ndarray) -> np.ndarray:
        """``DF z = (I + U V^T) D z`` in energy coordinates, O(N) (``st`` from
        :meth:`return_map_structure`)."""
        n = st["angles"].size
        c, s = np.cos(st["angles"]), np.sin(st["angles"])
        Dz = np.concatenate([c * z[:n] + s * z[n:], -s * z[:n] + c * z[n:]])
        return Dz + st["U"] @ (st["V"].T @ Dz)

    def energy_coordinates(self, du: np.ndarray, ddu: np.ndarray) -> np.ndarray:
        """``z = (Omega P^-1 u, P^-1 u')`` of a physical state (or perturbation)."""
        return np.concatenate([self.omega * (self.Pinv @ du), self.Pinv @ ddu])

    @property
    def conservative(self) -> bool:
        """Whether the return map is symplectic (Krein signatures apply: :mod:`palc` step
        control): the impact conserves energy iff ``M_ck = 0`` for ``k != c`` (Prop. 6.1)
        (:attr:`nsm_continuation.core.problem.Problem.conservative`)."""
        return self.g != 0.0 and not np.any(np.delete(self.M[self.c, :], self.c) != 0.0)

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """Non-trivial multipliers of the linearised first return map (3.5), from its structure
        (:meth:`return_map_structure`, O(N^2)): the roots of
        ``det(DF_W - lam) = prod_m (mu_m - lam) det(I_3 + Y^T (diag(mu) - lam)^-1 X)``, with
        ``DF_W = DF - t l^T / (l^T t)`` Wielandt's deflation of the trivial ``1`` to ``0``
        (:meth:`_deflated_update`: right eigenvector the branch tangent ``t``, eq. 6.5, left
        one ``grad E``), less the double root ``0`` (that one and the section normal's,
        sec. 6.1), divided out of the characteristic polynomial exactly
        (:func:`~nsm_continuation.core.floquet.low_rank_update_eigen`). Up to
        ``DENSE_MULTIPLIERS_UP_TO`` dofs the dense eigenvalues (:meth:`floquet_dense`) are
        used instead. With them the Krein definiteness of each multiplier, computed when
        first asked (:class:`~nsm_continuation.core.floquet.KreinFloquetData`; its sign is the Krein
        signature on the unit circle). ``trivial_error`` is ``|DF t - t| / |t|`` plus
        ``|h^T DF|`` (the section row, eq. A.10), both O(N). The iteration starts from the
        multipliers computed at the nearest points among the last calls, extrapolated
        (:meth:`MultiplierMemory.nearest_guess`); it falls back to :meth:`floquet_dense`
        when it does not converge (counted in ``floquet_fallbacks``)."""
        r = self._family_direction(y, tangent)
        if r is None:
            return None
        if self.N <= self.DENSE_MULTIPLIERS_UP_TO:
            # small chains: the dense eigenvalues are cheaper than the iteration's overhead;
            # the Krein definiteness is computed at them from the structure (no iteration),
            # when asked for
            dense = self.floquet_dense(y, tangent)
            if dense is None:
                return None
            mult = np.asarray(dense.multipliers, dtype=complex)

            def source() -> np.ndarray:
                return self._krein_dense(y, mult)

            return KreinFloquetData(mult, trivial_error=dense.trivial_error,
                                    matrix_norm=dense.matrix_norm, krein_source=source)
        st = self.return_map_structure(y)
        X, Y, removed = self._deflated_update(st, r)
        start = self.multiplier_memory.nearest_guess(y)
        out = None if start is None else low_rank_update_eigen(
            st["mu"], X, Y, removed=removed, guess=start[0])
        lineage = None if start is None else start[1]
        if out is None:
            out, lineage = low_rank_update_eigen(st["mu"], X, Y, removed=removed), None
        if out is None:
            self.floquet_fallbacks += 1
            return self.floquet_dense(y, tangent)
        mult, _, _ = out
        self.multiplier_memory.remember(y, mult, lineage)
        res = np.linalg.norm(self.return_map_apply(st, r) - r) / np.linalg.norm(r)
        U, V = st["U"], st["V"]
        # |h^T DF| / |h|: h^T U = (0, -1) and V[:, 1] = h make the section row vanish
        h = V[:, 1]
        sec = float(np.linalg.norm(h @ U + np.array([0.0, 1.0]))) * float(np.linalg.norm(V))
        # Frobenius norm of DF = (I + U V^T) D (D orthogonal), in O(N)
        n2 = U.shape[0] + 2.0 * np.trace(V.T @ U) + float(np.sum((U.T @ U) * (V.T @ V)))
        mult = np.asarray(mult, dtype=complex)
        # symplectic (Prop. 6.1): off the circle kappa = 0 exactly, not computed
        off = self.KREIN_OFF_CIRCLE if self.conservative else None
        return KreinFloquetData(
            mult, trivial_error=float(res + sec), matrix_norm=float(np.sqrt(max(n2, 0.0))),
            krein_source=lambda: krein_definiteness(st["mu"], X, Y, mult, st["krein_weights"],
                                                    off_circle=off))

    def _family_direction(self, y: np.ndarray, tangent: np.ndarray) -> np.ndarray | None:
        """The branch tangent in energy coordinates (the trivial multiplier's eigenvector,
        eq. 6.5), or None where no multipliers are reported: at (numerically) exact grazing
        the return map is not differentiable (sec. 6, [21]: ``DF ~ 1/v``)."""
        u0, du0, _ = self.state(y)
        if self.g == 0.0 or abs(du0[self.c]) <= 1e-9 * abs(self.g) * self.omega[0]:
            return None
        du, ddu, _ = self.state(tangent)
        r = self.energy_coordinates(du, ddu)
        return None if np.linalg.norm(r) == 0.0 else r

    def multipliers_near(self, y: np.ndarray, tangent: np.ndarray, guesses: np.ndarray
                         ) -> np.ndarray | None:
        """The multipliers nearest to ``guesses`` (distinct) from the secular equation of
        :meth:`floquet` (:func:`~nsm_continuation.core.floquet.refine_roots`: O(N) per multiplier
        and sweep); up to ``DENSE_MULTIPLIERS_UP_TO`` dofs, where LAPACK is cheaper, the dense
        eigenvalues (:meth:`floquet_dense`) nearest to them."""
        if self.N <= self.DENSE_MULTIPLIERS_UP_TO:
            dense = self.floquet_dense(y, tangent)
            if dense is None:
                return None
            m = np.asarray(dense.multipliers, dtype=complex)
            picked: list[int] = []
            for g in np.asarray(guesses, dtype=complex):
                d = np.abs(m - g)
                d[picked] = np.inf
                picked.append(int(np.argmin(d)))
            return m[picked] if len(picked) <= m.size else None
        r = self._family_direction(y, tangent)
        if r is None:
            return None
        st = self.return_map_structure(y)
        X, Y, removed = self._deflated_update(st, r)
        return refine_roots(st["mu"], X, Y, np.asarray(guesses, dtype=complex),
                            removed=removed)

    def _krein_dense(self, y: np.ndarray, mult: np.ndarray) -> np.ndarray:
        """Krein definiteness of the multipliers ``mult`` from the dense eigenvectors of
        ``DF = (I + U V^T) D`` in energy coordinates (small chains: one LAPACK call beats the
        per-root work of :func:`~nsm_continuation.core.floquet.krein_definiteness`):
        ``kappa = g(v) / |v|^2``, ``g(v) = -i omega(conj v, v) = 2 sum_j Im(conj xi_j eta_j)
        / w_j``, ``|v|^2 = sum_j (|xi_j|^2 + |eta_j|^2) / w_j``; each multiplier takes the
        eigenvector of the nearest eigenvalue. ``D``, ``U``, ``V`` from :meth:`_saltation`
        (not the whole :meth:`return_map_structure`); ``D`` filled in place (the matrix
        ``np.block([[diag c, diag s], [-diag s, diag c]])``, negative zeros included)."""
        _, c, s, U, V, _, _ = self._saltation(y)
        n = self.N
        D = np.zeros((2 * n, 2 * n))
        D[n:, :n] = -0.0
        i = np.arange(n)
        D[i, i] = c
        D[i, i + n] = s
        D[i + n, i] = -s
        D[i + n, i + n] = c
        A = D + U @ (V.T @ D)
        lam, V = np.linalg.eig(A)
        V = V[:, np.argmin(np.abs(lam[None, :] - np.asarray(mult)[:, None]), axis=1)]
        xi, eta = V[:n], V[n:]
        iw = 1.0 / self.omega[:, None]
        g = 2.0 * ((np.conj(xi) * eta).imag * iw).sum(axis=0)
        nrm = ((np.abs(xi) ** 2 + np.abs(eta) ** 2) * iw).sum(axis=0)
        return g / nrm

    @staticmethod
    def _deflated_update(st: dict[str, np.ndarray], r: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, tuple[float, ...]]:
        """``(X, Y, removed)`` of the map whose non-trivial spectrum is sought.

        The trivial multiplier 1 has the right eigenvector ``r = dz0/ds`` (the branch tangent,
        eq. 6.5) and the left eigenvector ``l = grad E = z0`` (energy conservation, proof of
        Corollary 3.1). Wielandt's deflation ``DF - r l^T / (l^T r)`` moves it to 0 and keeps
        every other eigenvalue (``l`` is orthogonal to their right eigenvectors): one more
        column of the update, and the removed roots are ``0, 0`` (section normal and the
        deflated 1), far from the unit circle where the multipliers that matter lie. (Dividing
        the 1 out of the characteristic polynomial instead leaves a cluster of three roots at
        +1 at a fold, resolved only to ~eps^(1/3).) Where ``l^T r = dE/ds`` vanishes (an
        energy extremum along the branch: 1 is then defective) the 1 is divided out."""
        z0 = st["z0"]
        lr = float(z0 @ r)
        if abs(lr) <= 1e-8 * np.linalg.norm(z0) * np.linalg.norm(r):
            return st["X"], st["Y"], (0.0, 1.0)
        n = z0.size // 2
        r2 = np.sqrt(0.5)
        qr = np.concatenate([(r[:n] - 1j * r[n:]) * r2, (r[:n] + 1j * r[n:]) * r2]) / -lr
        ql = np.concatenate([(z0[:n] + 1j * z0[n:]) * r2, (z0[:n] - 1j * z0[n:]) * r2])
        return (np.concatenate([st["X"], qr[:, None]], axis=1),
                np.concatenate([st["Y"], ql[:, None]], axis=1), (0.0, 0.0))

    def floquet_dense(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """The dense method (the oracle of :meth:`floquet`, O(N^3)): eigenvalues of ``DF`` (A.8)
        in physical coordinates restricted to the section (its row ``c`` vanishes, removing
        the extraneous 0) with the family direction deflated by a Householder reflector
        (removing the 1, eq. 6.5)."""
        u0, du0, _ = self.state(y)
        # at (numerically) exact grazing the return map is not differentiable (sec. 6, [21]):
        # DF ~ 1/v, so no multipliers are reported there
        if self.g == 0.0 or abs(du0[self.c]) <= 1e-9 * abs(self.g) * self.omega[0]:
            return None
        DF = self.return_map_jacobian(y)
        red = restrict_to_section(DF, self.c)
        du, ddu, _ = self.state(tangent)
        v = np.delete(np.concatenate([du, ddu]), self.c)
        if np.linalg.norm(v) == 0.0:
            return None
        B, lam, res = deflate_known_eigenvector(red, v)
        mult = np.linalg.eigvals(B) if B.size else np.empty(0, dtype=complex)
        norm = float(np.linalg.norm(B)) if B.size else 1.0  # Frobenius: cheap, >= 2-norm
        return FloquetData(np.asarray(mult, dtype=complex), trivial_error=abs(lam - 1.0) + res,
                           matrix_norm=norm)

