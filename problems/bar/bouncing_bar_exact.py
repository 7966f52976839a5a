"""Exact solution of the bouncing elastic bar of Table 1 by back-tracing characteristics.

Yoong, Thorin, Legrand (2017), section 3, Table 1: E = 900, rho = 1, L = 10, g0 = 5, F0 = 10
(c = 30). The paper leaves the boundary and initial conditions implicit; they are reconstructed
as the bouncing bar of Doyen, Ern and Piperno: a bar *free at x = 0*, initially at rest and
stress-free, its end x = L at distance ``g0`` from a rigid obstacle, falling under the uniform
body force ``F0`` (per unit volume, pointing towards the obstacle). A clamped left end is also
supported (the bar then never reaches the obstacle for Table 1: static deflection
``F0 L^2 / (2E) = 0.56 << g0``).

This module is an oracle for :mod:`problems.bar.wfem_stepping` and shares no code with it: it
works in *continuous* time, with no grid. Along the characteristics of ``rho v_t - sigma_x = F0``,
``sigma_t = E v_x`` (A.1 with a body force),

    a = sigma + Z v  moves left at speed c,  da/dt = +c F0,
    b = sigma - Z v  moves right at speed c, db/dt = -c F0,      Z = rho c.

Let ``B(t)`` be the value of ``b`` arriving at x = L, ``A(t)`` the value of ``a`` leaving x = L,
``s0 = -1`` (free, sigma(0) = 0) or ``+1`` (clamped, v(0) = 0) the reflection sign at x = 0,
``tau = 2L/c`` the round trip. Back-tracing one lap gives the exact recursion

    B(t) = s0 A(t - tau) + F0 L (s0 - 1)        (t >= L/c),     B(t) = -c F0 t  (t < L/c),
    A(t) = -B(t) (free end, sigma(L) = 0),  A(t) = +B(t) (contact with the fixed wall, v(L) = 0),

and ``A(s) = c F0 s`` on ``[-L/c, 0)`` encodes the initial rest state. With a constant force
every function involved is piecewise linear in t, so the switching times are found exactly:
impact is the first root of the piecewise-quadratic gap ``g0 - u(L, t)``, with
``u_t(L, t) = -B(t)/Z`` in free flight; release is the first time the wall stress
``sigma(L, t) = B(t)`` becomes tensile (the compressive contact force is ``lambda = -S B``).
The solution is built lap by lap (the lap k only needs lap k - 1), so it is exact up to
round-off for any final time.

Fields at (x, t): ``a = A(t - (L - x)/c) + F0 (L - x)``, ``b = Bl(t - x/c) - F0 x`` with
``Bl(s) = s0 (A(s - L/c) + F0 L)`` the ``b`` leaving x = 0 (``Bl(s) = -c F0 s`` for s < 0). They
are piecewise linear in x with known breakpoints, so the energy
``S int (a^2 + b^2)/(4E) dx`` and ``int x sigma dx`` are integrated exactly (3-point Gauss on
every piece). The potential energy of the body force is ``-F0 S int u dx`` with
``int_0^L u dx = L u(L, t) - (1/E) int_0^L x sigma(x, t) dx`` (integration by parts of
``u(x) = u(L) - int_x^L sigma/E``), so ``bar energy + potential`` must stay at its initial value
0: an independent consistency check of the back-traced fields.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(3)


@dataclass
class _PiecewiseLinear:
    """``f(t) = v[k] + s[k] (t - tb[k])`` on ``[tb[k], tb[k+1])``; jumps allowed at breakpoints."""

    tb: np.ndarray
    v: np.ndarray
    s: np.ndarray

    def __call__(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.tb, t, side="right") - 1, 0, len(self.v) - 1)
        return self.v[k] + self.s[k] * (t - self.tb[k])

    def left_limit(self, t: np.ndarray | float) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        k = np.clip(np.searchsorted(self.tb, t, side="left") - 1, 0, len(self.v) - 1)
        return self.v[k] + self.s[k] * (t - self.tb[k])


@dataclass
class BouncingBarExact:
    """Exact motion of the bar under a uniform constant body force against a fixed obstacle.

    Attributes after construction: ``impacts`` and ``releases`` (switching times), the lap-wise
    piecewise-linear ``A`` (characteristic leaving x = L) and ``B`` (arriving at x = L) on
    ``[-L/c, t_end]``, the contact indicator, the end displacement and the contact impulse at
    every breakpoint (exact piecewise integrals).
    """

    E: float = 900.0
    rho: float = 1.0
    L: float = 10.0
    g0: float = 5.0
    F0: float = 10.0
    t_end: float = 20.0
    S: float = 1.0
    left: Literal["free", "clamped"] = "free"
    impacts: list[float] = field(init=False, default_factory=list)
    releases: list[float] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        for name in ("E", "rho", "L", "S", "t_end"):
            val = float(getattr(self, name))
            if not np.isfinite(val) or val <= 0.0:
                raise ValueError(f"{name} must be a positive finite number, got {val!r}")
        for name in ("g0", "F0"):
            if not np.isfinite(float(getattr(self, name))):
                raise ValueError(f"{name} must be finite, got {getattr(self, name)!r}")
        if self.g0 <= 0.0:
            raise ValueError("g0 must be > 0 (the bar starts at rest away from the obstacle)")
        if self.left not in ("free", "clamped"):
            raise ValueError(f"left must be 'free' or 'clamped', got {self.left!r}")
        self.c = float(np.sqrt(self.E / self.rho))
        self.Z = self.rho * self.c
        self.tau = 2.0 * self.L / self.c
        self.s0 = -1.0 if self.left == "free" else 1.0
        self._build()

    # -- construction ----------------------------------------------------------------------------
    def _build(self) -> None:
        c, F0, L, Z, tau, s0 = self.c, self.F0, self.L, self.Z, self.tau, self.s0
        tol_t = 1e-13 * max(self.t_end, tau)
        # Segments (t_start, t_end, value at t_start, slope) of A, starting with the rest state.
        A_segs: list[tuple[float, float, float, float]] = [(-L / c, 0.0, -F0 * L, c * F0)]
        B_segs: list[tuple[float, float, float, float]] = []
        contact = False
        u = 0.0
        # Pieces of the end motion (start time, u, impulse, contact flag, B and its slope there).
        rec_t: list[float] = []
        rec_u: list[float] = []
        rec_I: list[float] = []
        rec_c: list[bool] = []
        rec_b: list[float] = []
        rec_s: list[float] = []
        impulse = 0.0
        scale_B = max(abs(c * F0) * max(self.t_end, tau), abs(F0 * L), 1.0)
        tol_B = 1e-12 * scale_B
        tol_g = 1e-12 * max(self.g0, 1.0)
        n_laps = int(np.ceil(self.t_end / tau)) + 1
        for k in range(n_laps):
            t_lo, t_hi = k * tau, (k + 1) * tau
            # B on the lap from A on the previous lap (or the rest state for t < L/c).
            lap: list[tuple[float, float, float, float]] = []
            if k == 0:
                lap.append((0.0, L / c, 0.0, -c * F0))
                src = [sg for sg in A_segs if sg[1] > -L / c + tol_t]
                for (ta, tb_, va, sa) in src:
                    lap.append((ta + tau, tb_ + tau, s0 * va + F0 * L * (s0 - 1.0), s0 * sa))
                lap = [sg for sg in lap if sg[0] >= -tol_t]
            else:
                for (ta, tb_, va, sa) in A_segs:
                    if tb_ <= t_lo - tau + tol_t or ta >= t_hi - tau - tol_t:
                        continue
                    lap.append((ta + tau, tb_ + tau, s0 * va + F0 * L * (s0 - 1.0), s0 * sa))
            # March through the lap, splitting segments at switching times.
            for (ta, tb_, va, sa) in lap:
                t = ta
                while t < tb_ - tol_t:
                    b0 = va + sa * (t - ta)  # B at t (right limit)
                    if contact:
                        if b0 > tol_B:
                            t_sw = t  # tensile wall stress: release now
                        elif sa > 0.0 and b0 + sa * (tb_ - t) > tol_B:
                            t_sw = t - b0 / sa
                        else:
                            t_sw = tb_
                    else:
                        t_sw = self._impact_time(t, tb_, u, b0, sa, tol_g)
                    t_sw = min(max(t_sw, t), tb_)
                    # Piece [t, t_sw) with the current boundary condition.
                    if t_sw > t + tol_t:
                        dt_ = t_sw - t
                        sgn = 1.0 if contact else -1.0
                        B_segs.append((t, t_sw, b0, sa))
                        A_segs.append((t, t_sw, sgn * b0, sgn * sa))
                        rec_t.append(t)
                        rec_u.append(u)
                        rec_I.append(impulse)
                        rec_c.append(contact)
                        rec_b.append(b0)
                        rec_s.append(sa)
                        if contact:
                            impulse += -self.S * (b0 * dt_ + 0.5 * sa * dt_ * dt_)
                        else:
                            u += -(b0 * dt_ + 0.5 * sa * dt_ * dt_) / Z
                    if t_sw < tb_ - tol_t:
                        b_sw = va + sa * (t_sw - ta)
                        if contact:
                            contact = False
                            self.releases.append(t_sw)
                        elif b_sw <= tol_B:  # approaching (v_end = -B/Z >= 0): close the gap
                            contact = True
                            u = self.g0  # remove the O(eps) residual of the root
                            self.impacts.append(t_sw)
                    t = t_sw
            if t_hi > self.t_end + tau:
                break
        self.A = self._to_pl(A_segs)
        self.B = self._to_pl(B_segs)
        self._rec_t = np.array(rec_t)
        self._rec_u = np.array(rec_u)
        self._rec_I = np.array(rec_I)
        self._rec_c = np.array(rec_c, dtype=bool)
        self._rec_b = np.array(rec_b)
        self._rec_s = np.array(rec_s)

    @staticmethod
    def _to_pl(segs: list[tuple[float, float, float, float]]) -> _PiecewiseLinear:
        segs = sorted(segs)
        tb = np.array([s[0] for s in segs] + [segs[-1][1]])
        return _PiecewiseLinear(tb, np.array([s[2] for s in segs]), np.array([s[3] for s in segs]))

    def _impact_time(self, t: float, t_hi: float, u: float, b0: float, sa: float,
                     tol_g: float) -> float:
        """First time in [t, t_hi) at which the gap ``g0 - u`` closes during free flight.

        ``gap(x) = G0 + (b0 x + sa x^2 / 2)/Z`` for ``x = t' - t``; returns ``t_hi`` if none.
        """
        G0 = self.g0 - u
        if G0 <= tol_g and b0 < 0.0:
            return t  # touching and approaching
        X = t_hi - t
        qa, qb, qc = 0.5 * sa / self.Z, b0 / self.Z, G0
        roots: list[float] = []
        if abs(qa) * X * X <= 1e-15 * (abs(qb) * X + abs(qc)):
            if qb != 0.0:
                roots.append(-qc / qb)
        else:
            disc = qb * qb - 4.0 * qa * qc
            if disc >= 0.0:
                sq = np.sqrt(disc)
                q = -0.5 * (qb + np.copysign(sq, qb)) if qb != 0.0 else 0.5 * sq
                if q != 0.0:
                    roots += [q / qa, qc / q]
                else:
                    roots.append(0.0)
        # Gap must decrease through the root: gap'(x) = qb + 2 qa x <= 0.
        cands = [x for x in roots if 1e-14 * X < x < X and qb + 2.0 * qa * x <= 0.0]
        return t + min(cands) if cands else t_hi

    # -- end quantities --------------------------------------------------------------------------
    def _piece(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Piece index, elapsed time in the piece and ``B`` there (pieces of the end motion)."""
        t = np.asarray(t, dtype=float)
        if np.any(t < 0.0) or np.any(t > self.t_end + self.tau):
            raise ValueError(f"t must lie in [0, {self.t_end + self.tau}]")
        k = np.clip(np.searchsorted(self._rec_t, t, side="right") - 1, 0, len(self._rec_t) - 1)
        dt_ = t - self._rec_t[k]
        return k, dt_, self._rec_b[k] + self._rec_s[k] * dt_

    def contact_at(self, t: np.ndarray | float) -> np.ndarray:
        """Contact indicator (right limit at switching times)."""
        return self._rec_c[self._piece(t)[0]]

    def u_end(self, t: np.ndarray | float) -> np.ndarray:
        """Displacement ``u(L, t)`` (exact piecewise quadratic)."""
        k, dt_, _ = self._piece(t)
        intB = self._rec_b[k] * dt_ + 0.5 * self._rec_s[k] * dt_ * dt_
        return np.where(self._rec_c[k], self._rec_u[k], self._rec_u[k] - intB / self.Z)

    def impulse(self, t: np.ndarray | float) -> np.ndarray:
        """``int_0^t lambda dt``, ``lambda = -S sigma(L) >= 0`` the compressive contact force."""
        k, dt_, _ = self._piece(t)
        intB = self._rec_b[k] * dt_ + 0.5 * self._rec_s[k] * dt_ * dt_
        return np.where(self._rec_c[k], self._rec_I[k] - self.S * intB, self._rec_I[k])

    def v_end(self, t: np.ndarray | float) -> np.ndarray:
        """End velocity ``-B/Z`` in free flight, 0 in contact (right limit at switches)."""
        k, _, B = self._piece(t)
        return np.where(self._rec_c[k], 0.0, -B / self.Z)

    def contact_force(self, t: np.ndarray | float) -> np.ndarray:
        """Compressive contact force ``lambda = -S sigma(L, t) = -S B(t)`` in contact, else 0."""
        k, _, B = self._piece(t)
        return np.where(self._rec_c[k], -self.S * B, 0.0)

    def step_averages(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Averages of the end velocity and contact force over ``[t_n, t_n+1]`` (exact).

        Integrated piece by piece inside each step (no difference of large antiderivatives).
        """
        t = np.asarray(t, dtype=float)
        k0, dt0, B0 = self._piece(t[:-1])
        k1 = self._piece(t[1:])[0]
        h = np.diff(t)
        s = self._rec_s[k0]
        intB = B0 * h + 0.5 * s * h * h  # valid where the step lies in one piece
        v_avg = np.where(self._rec_c[k0], 0.0, -intB / self.Z) / h
        f_avg = np.where(self._rec_c[k0], -self.S * intB, 0.0) / h
        for n in np.flatnonzero(k1 != k0):
            v_sum = f_sum = 0.0
            ta = t[n]
            for k in range(int(k0[n]), int(k1[n]) + 1):
                tb_ = min(t[n + 1], self._rec_t[k + 1]) if k + 1 < len(self._rec_t) else t[n + 1]
                x0, x1 = ta - self._rec_t[k], tb_ - self._rec_t[k]
                ib = self._rec_b[k] * (x1 - x0) + 0.5 * self._rec_s[k] * (x1 * x1 - x0 * x0)
                if self._rec_c[k]:
                    f_sum -= self.S * ib
                else:
                    v_sum -= ib / self.Z
                ta = tb_
            v_avg[n] = v_sum / h[n]
            f_avg[n] = f_sum / h[n]
        return v_avg, f_avg

    # -- fields and energies ---------------------------------------------------------------------
    def _b_left(self, s: np.ndarray) -> np.ndarray:
        """``b`` leaving x = 0 at time s (``-c F0 s`` before the initial data is exhausted)."""
        s = np.asarray(s, dtype=float)
        return np.where(s < 0.0, -self.c * self.F0 * s,
                        self.s0 * (self.A(s - self.L / self.c) + self.F0 * self.L))

    def fields(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(sigma(x, t), v(x, t))`` (right limits in time at the characteristics' breakpoints)."""
        x = np.asarray(x, dtype=float)
        a = self.A(t - (self.L - x) / self.c) + self.F0 * (self.L - x)
        b = self._b_left(t - x / self.c) - self.F0 * x
        return 0.5 * (a + b), 0.5 * (a - b) / self.Z

    def _x_breaks(self, t: float) -> np.ndarray:
        L, c = self.L, self.c
        tb = self.A.tb
        xa = L - c * (t - tb)
        xb = c * (t - (tb + L / c))
        xs = np.concatenate([[0.0, L], xa, xb, [c * t]])
        xs = xs[(xs >= 0.0) & (xs <= L)]
        return np.unique(xs)

    def _integrate(self, t: float) -> tuple[float, float, float]:
        """Exact ``int (a^2 + b^2)/(4E) dx``, ``int x sigma dx`` and ``int sigma dx`` at time t."""
        xs = self._x_breaks(t)
        lo, hi = xs[:-1], xs[1:]
        keep = hi - lo > 1e-12 * self.L
        lo, hi = lo[keep], hi[keep]
        half = 0.5 * (hi - lo)
        mid = 0.5 * (hi + lo)
        xq = (mid[:, None] + half[:, None] * _GAUSS_X[None, :]).ravel()
        wq = (half[:, None] * _GAUSS_W[None, :]).ravel()
        sig, v = self.fields(xq, t)
        energy = self.S * np.sum(wq * (sig**2 / (2 * self.E) + 0.5 * self.rho * v**2))
        return float(energy), float(np.sum(wq * xq * sig)), float(np.sum(wq * sig))

    def energy(self, t: float) -> float:
        """Elastic + kinetic energy of the bar (exact)."""
        return self._integrate(t)[0]

    def potential(self, t: float) -> float:
        """Potential energy of the body force, ``-F0 S int u dx`` (0 at t = 0)."""
        _, xsig, _ = self._integrate(t)
        int_u = self.L * float(self.u_end(t)) - xsig / self.E
        return -self.F0 * self.S * int_u

    def period(self) -> float:
        """Time between the first and the third impact (two bounces per period, see module doc)."""
        if len(self.impacts) < 3:
            raise ValueError("t_end too short: fewer than three impacts")
        return self.impacts[2] - self.impacts[0]
