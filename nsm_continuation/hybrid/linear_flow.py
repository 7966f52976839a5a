"""Exact free flight of a system that is linear between events (piecewise-linear impact systems).

Most impacting systems studied are linear between impacts (impact oscillators, chains, gear
pairs with backlash, reduced finite-element models with a contact): ``M q'' + C q' + K q = f(t)``
with constant matrices and a periodic forcing. Their flow between events is known in closed form,
so the free-flight steps of the simulator need no Runge-Kutta integration: this module detects
the structure from the compiled CasADi declaration and builds steps with the same interface as
the Runge-Kutta step Functions of :func:`.system._step_functions` (``.flat(Y, dt)``, the same flat
layout), which :class:`~.simulate.Simulator` calls as it calls those. It also asks them how long
their next step may be (no integration error to control: as long as the watched functions are
certified clear of zero, :mod:`.modal_sums`) and the extremes of the state over a step.

Why the choice is not automatic by default: the exact path changes a run's numbers at the
Runge-Kutta tolerance (about 1e-10), so the bundled cases keep ``dop853`` and a case asks for
``method: exact`` (or ``auto``: exact where it applies) in ``parameters.integrator``. Sticking
and chattering flights keep their Runge-Kutta steps: in a chattering flight the scaled
height ``h = H / u`` of sec. 4.3 must keep its relative precision as ``u -> 0``, which the modal
sum (velocities as sums of O(1) modal terms) would lose.

**Detection** (:func:`detect`). With ``X`` the compiled state (the system state, then the freed
parameters) and ``F = f(X)``, write ``x`` for the dynamic components (every state component but
the clock ``phi``). The exact flow applies when

* ``F_x`` restricted to ``x`` is affine in ``x`` with a constant matrix ``A`` (its Jacobian
  depends on nothing: no nonlinear force, no parametric excitation, no freed parameter in ``A``);
* what remains, ``b(phi) = F_x(0, phi)``, is a finite sum of harmonics of the clock,
  ``b(phi) = b_0 + sum_k Re(c_k e^{i k phi})``, ``k = 1 .. MAX_HARMONIC`` (found by a discrete
  Fourier transform of ``SAMPLES`` samples and checked at further irrational phases to rounding:
  a forcing at a frequency that is not a harmonic of the clock is refused);
* the clock's rate is a constant or the freed forcing frequency itself; no other freed parameter
  enters ``F`` (parameters of the constraints, such as a gap, may be freed);
* ``A = V diag(lambda) V^{-1}`` is diagonalisable with well-conditioned eigenvectors
  (``cond(V) <= MAX_CONDITION``: the rounding of the modal flow is about ``cond(V)`` units in the
  last place; a defective or nearly defective ``A`` is refused), and invertible (a zero
  eigenvalue, e.g. a free rigid-body motion, makes the particular solution secular).

Otherwise the reason is returned and the Runge-Kutta path is the one that runs.

**Exact step.** With ``omega`` the clock's rate, the particular (periodic) solution is

    x_p(phi) = x_0 + Re(sum_k Z_k e^{i k phi}),  x_0 = -A^{-1} b_0,
    Z_k = V (i k omega - Lambda)^{-1} V^{-1} c_k,

(``x_p' = A x_p + b``: ``i k omega Z_k = A Z_k + c_k``), and the step of length ``dt`` from
``(x, phi)`` is

    x(dt) = x_p(phi + omega dt) + Phi(dt) (x - x_p(phi)),  Phi(dt) = Re(V e^{Lambda dt} V^{-1}),

with the Jacobian in closed form: ``dx(dt)/dx = Phi(dt)``,
``dx(dt)/dphi = x_p'(phi + omega dt) - Phi(dt) x_p'(phi)`` (``x_p' = dx_p/dphi``) and, when
``omega`` is freed, ``dx(dt)/domega = d_omega x_p(phi + omega dt) + dt x_p'(phi + omega dt) -
Phi(dt) d_omega x_p(phi)`` with ``d_omega Z_k = -i k V (i k omega - Lambda)^{-2} V^{-1} c_k``.
The error estimates are zero; the probe and the field at the step end come from the compiled
CasADi ``probe`` and ``f``. A forcing frequency that (nearly) resonates with an eigenvalue,
``|i k omega - lambda| <= RESONANCE_GAP (|lambda| + k omega)``, is refused at compile time for a
fixed rate, and ends the simulation with a :class:`~.sim_data.SimulationError` naming it for a
freed one (the particular solution would lose ``1 / gap`` of its digits).

Conjugate eigenpairs are used once: with ``S`` the real eigenvalues and one of each complex pair,
weight ``w_j = 1`` or ``2``, ``Phi(dt) = Re(sum_{j in S} w_j e^{lambda_j dt} v_j u_j^T)``
(``u_j^T`` the rows of ``V^{-1}``), one real matrix product of size ``n``.

**Composition.** The flow of the extended autonomous system ``(x, phi, omega)`` is exact, so its
steps compose, ``phi_a o phi_b = phi_{a+b}``: the Jacobian over several steps without an event
is one evaluation over their total time. The step objects say so (``exact``) and the simulator
defers the sensitivity products of such steps to the next event
(:meth:`~.simulate.Simulator._deferred`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from nsm_continuation.core.casadi_buffers import BufferedFunction
from nsm_continuation.hybrid import modal_sums
from nsm_continuation.hybrid.sim_data import SimulationError

#: the largest condition number of the eigenvector matrix ``V`` accepted (the modal flow's
#: rounding is about ``cond(V)`` units in the last place: 1e6 keeps it below the default
#: integration tolerance 1e-10)
MAX_CONDITION = 1e6
#: the highest harmonic of the clock a forcing may contain
MAX_HARMONIC = 16
#: samples of the forcing over one period of the clock (the discrete Fourier transform)
SAMPLES = 64
#: a forcing frequency ``k omega`` closer than this (relative) to an eigenvalue is a resonance
RESONANCE_GAP = 1e-7
#: relative size below which a harmonic of the forcing is rounding
HARMONIC_FLOOR = 1e-13
#: bound on the error of the cubic Hermite interpolants of the state over one exact step,
#: relative to the size of the state (:meth:`ModalFlow.max_step`)
HERMITE_TOL = 2e-6


@dataclass(frozen=True)
class LinearField:
    """The vector field on the dynamic components: ``A x + b_0 + sum_k Re(c_k e^{i k phi})``.

    ``dyn``: indices of the dynamic components in ``X``; ``clock``: index of the clock (None
    for an autonomous system); its rate is ``rate`` or, when ``rate_index`` is set, the freed
    parameter ``X[rate_index]``; ``orders[i]`` is the harmonic ``k`` of ``coef[i] = c_k``."""

    N: int
    dyn: np.ndarray
    clock: int | None
    rate: float
    rate_index: int | None
    A: np.ndarray
    b0: np.ndarray
    orders: np.ndarray
    coef: np.ndarray
    #: the gradient of the probe with respect to the dynamic components when it is constant
    #: (constraints affine in the state), else None
    P: np.ndarray | None = None


def detect(f: ca.Function, probe: ca.Function, n: int, clock: int | None, names: list[str]
           ) -> LinearField | str:
    """The linear structure of the compiled field ``f`` (module docstring), or why there is
    none; with the gradient of the compiled ``probe`` when it is constant. ``n``: the
    system's dimension (then the freed parameters); ``names``: one per component of ``X``
    (state names, then the freed parameters')."""
    N = int(f.size1_in(0))
    X = ca.SX.sym("X", N)
    F = f(X)
    dyn = [i for i in range(n) if i != clock]
    freed = list(range(n, N))
    Fd = F[dyn]
    for j in freed:
        if ca.depends_on(Fd, X[j]):
            return (f"the freed parameter {names[j]!r} enters the vector field (only the clock's "
                    "rate may be freed)")
    J = ca.jacobian(Fd, X[dyn])
    for i in dyn:
        if ca.depends_on(J, X[i]):
            return f"the vector field is not linear in the state (it is nonlinear in {names[i]!r})"
    if clock is not None and ca.depends_on(J, X[clock]):
        return "the linear part depends on the clock (a parametric excitation)"
    A = np.asarray(ca.Function("A", [X], [J])(np.zeros(N)), dtype=float)
    rate, rate_index = 0.0, None
    if clock is not None:
        found = _clock_rate(F[clock], X, dyn + [clock], freed, names)
        if isinstance(found, str):
            return found
        rate, rate_index = found
    bfun = ca.Function("b", [X], [Fd])

    def b(phase: float) -> np.ndarray:
        Y = np.zeros(N)
        if clock is not None:
            Y[clock] = phase
        return np.asarray(bfun(Y), dtype=float).ravel()

    Jp = ca.jacobian(probe(X), X[dyn])
    P = None if ca.depends_on(Jp, X) else np.asarray(
        ca.Function("P", [X], [Jp])(np.zeros(N)), dtype=float)
    if clock is None:
        return LinearField(N, np.array(dyn), None, 0.0, None, A, b(0.0), np.zeros(0, int),
                           np.zeros((0, len(dyn)), complex), P)
    found = _harmonics(b, len(dyn))
    if isinstance(found, str):
        return found
    b0, orders, coef = found
    return LinearField(N, np.array(dyn), clock, rate, rate_index, A, b0, orders, coef, P)


def _clock_rate(rate_expr: ca.SX, X: ca.SX, state: list[int], freed: list[int],
                names: list[str]) -> tuple[float, int | None] | str:
    """The clock's rate: a constant ``(value, None)`` or a freed parameter ``(0, index)``."""
    if ca.depends_on(rate_expr, X[state]):
        return "the clock's rate depends on the state"
    g = ca.Function("rate", [X], [rate_expr, ca.jacobian(rate_expr, X)])
    val0, grad = (np.asarray(v, dtype=float).ravel() for v in g(np.zeros(X.numel())))
    uses = [j for j in freed if ca.depends_on(rate_expr, X[j])]
    if not uses:
        return float(val0[0]), None
    j = uses[0]
    probe = np.zeros(X.numel())
    probe[j] = 1.7320508075688772
    val1 = float(np.asarray(g(probe)[0]).ravel()[0])
    if len(uses) > 1 or val0[0] != 0.0 or grad[j] != 1.0 or val1 != probe[j]:
        return (f"the clock's rate is not a constant or a freed parameter itself "
                f"({', '.join(names[i] for i in uses)} enter it otherwise)")
    return 0.0, j


def _harmonics(b: Any, nd: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | str:
    """``b(phi) = b_0 + sum_k Re(c_k e^{i k phi})`` from ``SAMPLES`` samples (discrete Fourier
    transform), checked at irrational phases; or why ``b`` is no such sum."""
    phases = 2 * np.pi * np.arange(SAMPLES) / SAMPLES
    samples = np.array([b(p) for p in phases])
    if not np.all(np.isfinite(samples)):
        return "the forcing is not finite"
    hat = np.fft.rfft(samples, axis=0) / SAMPLES
    scale = 1.0 + float(np.max(np.abs(samples)))
    b0 = hat[0].real
    coef = 2.0 * hat[1:]
    keep = [k for k in range(1, coef.shape[0] + 1)
            if np.max(np.abs(coef[k - 1])) > HARMONIC_FLOOR * scale]
    orders = np.array([k for k in keep if k <= MAX_HARMONIC], dtype=int)
    cs = coef[orders - 1] if orders.size else np.zeros((0, nd), complex)

    def model(p: float) -> np.ndarray:
        return b0 + (cs * np.exp(1j * orders * p)[:, None]).real.sum(axis=0)

    for p in (0.7390851332151607, 2.718281828459045, 5.123105625617661, 41.30689110477372):
        err = float(np.max(np.abs(b(p) - model(p))))
        if err > 1e-11 * scale:
            return (f"the forcing is not a sum of harmonics of the clock up to order "
                    f"{MAX_HARMONIC} (off by {err:.1e} at phase {p:.4g})")
    return b0, orders, cs


class ModalFlow:
    """The closed-form flow of a :class:`LinearField` in modal coordinates (module
    docstring); :meth:`build` returns it, or why the modal flow is refused.

    Conjugate pairs enter once (``S``: the real eigenvalues and those with a positive
    imaginary part, weight ``w_j`` 1 or 2). The particular solution is kept as real arrays,
    ``x_p(phi) = x_0 + sum_k (cos(k phi) Re Z_k - sin(k phi) Im Z_k)``, rebuilt when ``omega``
    changes (once per simulation when it is freed). ``probe_modes``: the gradient ``P`` of the
    probe (constant: constraints affine in the state) times the modes, ``P V_S``, or None."""

    def __init__(self, fld: LinearField, lam: np.ndarray, V: np.ndarray, U: np.ndarray,
                 x0: np.ndarray) -> None:
        self.field = fld
        self.lam, self.V, self.U, self.x0 = lam, V, U, x0
        real = np.abs(lam.imag) == 0.0
        sel = np.flatnonzero(real | (lam.imag > 0))
        self.lam_s = lam[sel]
        self._w = np.where(real[sel], 1.0, 2.0)
        self._VS = V[:, sel]
        self._US = U[sel]
        cplx = ~real[sel]
        self._cplx = cplx
        #: the rows of ``Re(U_S)`` and those of ``Im(U_S)`` of the complex modes: ``Phi`` is
        #: ``[Re(P), -Im(P)_cplx] @ Ustack`` with ``P = V_S diag(w e^{lambda dt})``
        self._Ustack = np.vstack([self._US.real, self._US.imag[cplx]])
        growth = float(np.max(lam.real, initial=0.0))
        #: an unstable mode grows at most e-fold over a step: steps at most ``1 / Re lambda``
        self.h_growth = 1.0 / growth if growth > 0 else np.inf
        #: ``|lambda_j|^4`` of the modes, e-fold grown when one is unstable (bounds of the
        #: fourth derivatives, :mod:`.modal_sums`)
        self.lam4_grown = np.abs(self.lam_s) ** 4 * (np.e if growth > 0 else 1.0)
        self.lam2_grown = np.abs(self.lam_s) ** 2 * (np.e if growth > 0 else 1.0)
        self._absVS4 = np.abs(self._VS) * self.lam4_grown
        self._size0 = float(np.max(np.abs(x0), initial=0.0))
        self._k = fld.orders.astype(float)
        self._omega: float | None = None
        nd = fld.dyn.size
        #: ``[Re Z_k; -Im Z_k]`` and the same of ``d Z_k / d omega`` (rows), at ``_omega``
        self._Zs = self._dZs = np.zeros((0, nd))
        self._forced4 = np.zeros(nd)
        self._size = self._size0
        #: the dynamic components are the first ones (a mechanical system: ``q, qdot``, then
        #: the clock): the state-transition block is a slice of the Jacobian
        self._dyn_first = bool(np.array_equal(fld.dyn, np.arange(fld.dyn.size)))
        #: position of each component of ``X`` among the dynamic ones
        self.pos = np.full(fld.N, -1)
        self.pos[fld.dyn] = np.arange(nd)
        #: the last :meth:`modal` (the simulator asks it several times of one state)
        self._modal_key: bytes | None = None
        self._modal_last: tuple[float, float, np.ndarray] = (0.0, 0.0, np.zeros(0))
        #: :meth:`hermite_cell` of the last :meth:`modal` (its modal coordinates)
        self._cell_of: np.ndarray | None = None
        self._cell = 0.0
        self.probe_modes: np.ndarray | None = (
            None if fld.P is None else fld.P @ self._VS)

    @classmethod
    def build(cls, fld: LinearField) -> ModalFlow | str:
        A = fld.A
        if not np.all(np.isfinite(A)):
            return "the linear part of the vector field is not finite"
        lam, V = np.linalg.eig(A)
        cond = float(np.linalg.cond(V))
        if not np.isfinite(cond) or cond > MAX_CONDITION:
            return (f"the linear part is defective or nearly so (condition number of its "
                    f"eigenvectors {cond:.1e} > {MAX_CONDITION:.0e}): its modal flow would not be "
                    "accurate")
        size = max(1.0, float(np.max(np.abs(lam))))
        if float(np.min(np.abs(lam))) <= 1e-12 * size:
            return ("the linear part is singular (a zero eigenvalue: a free rigid-body motion or "
                    "a constant drift): no periodic particular solution")
        U = np.linalg.inv(V)
        x0 = np.linalg.solve(A, -fld.b0)
        flow = cls(fld, lam, V, U, x0)
        if fld.rate_index is None and fld.orders.size:
            reason = flow._resonance(fld.rate)
            if reason:
                return reason
        return flow

    # ------------------------------------------------------------------ particular solution
    def _resonance(self, omega: float) -> str:
        """Why ``omega`` resonates with an eigenvalue (empty if it does not)."""
        for k in self.field.orders:
            d = np.abs(1j * k * omega - self.lam)
            j = int(np.argmin(d))
            if d[j] <= RESONANCE_GAP * (abs(self.lam[j]) + k * abs(omega)):
                return (f"the forcing's harmonic {k} at frequency {k * omega:.10g} resonates "
                        f"with the eigenvalue {self.lam[j]:.6g} of the linear part: no periodic "
                        "particular solution")
        return ""

    def _particular(self, omega: float) -> None:
        """``Z_k = V (i k omega - Lambda)^{-1} V^{-1} c_k`` and
        ``d Z_k / d omega = -i k V (i k omega - Lambda)^{-2} V^{-1} c_k`` at ``omega`` (kept
        until ``omega`` changes), with the bound of ``|x_p^(4)|`` and the size of ``x_p``
        (:meth:`hermite_cell`)."""
        if self._omega == omega or not self._k.size:
            return
        reason = self._resonance(omega)
        if reason:
            raise SimulationError(f"exact flow: {reason}")
        k = self._k[:, None]
        den = 1j * k * omega - self.lam[None, :]
        zeta = (self.field.coef @ self.U.T) / den            # rows: modal coordinates of Z_k
        Z = zeta @ self.V.T
        dZ = (-1j * k * zeta / den) @ self.V.T
        self._Zs = np.vstack([Z.real, -Z.imag])
        self._dZs = np.vstack([dZ.real, -dZ.imag])
        amp = np.abs(Z)
        self._forced4 = (self._k * abs(omega)) ** 4 @ amp
        self._size = self._size0 + float(np.max(amp.sum(axis=0)))
        self._omega = omega

    def _trig(self, phases: Any) -> np.ndarray:
        """``(cos(k phase), sin(k phase))`` of the harmonics (rows per phase for an array):
        ``x_p = x_0 + trig @ _Zs``."""
        kp = np.multiply.outer(phases, self._k)
        return np.concatenate([np.cos(kp), np.sin(kp)], axis=-1)

    def xp(self, phase: Any) -> np.ndarray:
        """``x_p`` at ``phase`` (rows for an array of phases), at the current ``omega``."""
        if not self._k.size:
            return self.x0 if np.ndim(phase) == 0 else np.tile(self.x0, (len(phase), 1))
        return self.x0 + self._trig(phase) @ self._Zs

    def _xp_rate(self, phases: Any) -> np.ndarray:
        """``d x_p / d phase`` at ``phases`` (rows for an array)."""
        cs = self._trig(phases)
        K = self._k.size
        turned = np.concatenate([-self._k * cs[..., K:], self._k * cs[..., :K]], axis=-1)
        return turned @ self._Zs

    def _xp_omega(self, phase: float) -> np.ndarray:
        """``d x_p / d omega`` at ``phase``."""
        return self._trig(phase) @ self._dZs

    def modal(self, Y: np.ndarray) -> tuple[float, float, np.ndarray]:
        """``(omega, phase, w xi)`` at ``Y``: the clock's rate and phase and the weighted modal
        coordinates of ``x - x_p(phase)`` (the particular solution brought to ``omega``)."""
        key = Y.tobytes()
        if key == self._modal_key:
            return self._modal_last
        fld = self.field
        omega = fld.rate if fld.rate_index is None else float(Y[fld.rate_index])
        phase = float(Y[fld.clock]) if fld.clock is not None else 0.0
        self._particular(omega)
        out = omega, phase, self._w * (self._US @ (Y[fld.dyn] - self.xp(phase)))
        self._modal_key, self._modal_last = key, out
        return out

    def state_sum(self, k: int) -> tuple[np.ndarray, tuple[float, np.ndarray, np.ndarray]]:
        """Component ``k`` of ``X`` (dynamic) as a sum along the flow: its row of the modes
        ``V_S`` and its particular part ``(x_0, orders, Z_k)`` (``x_p = x_0 + sum Re(Z_k
        e^{i k phi})``, at the current ``omega``)."""
        p = int(self.pos[k])
        K = self._k.size
        Z = self._Zs[:K, p] - 1j * self._Zs[K:, p]
        return self._VS[p], (float(self.x0[p]), self.field.orders, Z)

    # ------------------------------------------------------------------ along the flow
    def hermite_cell(self, Y: np.ndarray) -> float:
        """The longest time over which the cubic Hermite interpolant of every state
        component from ``Y`` (values and slopes at both ends, what the simulator locates
        events and extremes with) is within ``HERMITE_TOL`` of the state's size: its error is
        at most ``h^4 / 384 max |x^(4)|``, and ``|x^(4)|`` is at most
        ``sum_j w_j |v_j| |lambda_j|^4 |xi_j| + sum_k (k omega)^4 |Z_k|`` (:mod:`.modal_sums`).
        Cells of this width make the interpolants at least as accurate as those of the
        Runge-Kutta path at its default tolerance (there the midpoint defect is about 1e-5
        of the state; here below 1e-5)."""
        _omega, _phase, xi = self.modal(Y)
        if self._cell_of is xi:
            return self._cell
        x = Y[self.field.dyn]
        m4 = float(np.max(self.fourth_bounds(Y), initial=0.0))
        size = float(np.max(np.abs(x), initial=0.0)) + self._size
        cell = self.h_growth if m4 == 0.0 else min(
            self.h_growth, (384.0 * HERMITE_TOL * size / m4) ** 0.25)
        self._cell_of, self._cell = xi, cell
        return cell

    def fourth_bounds(self, Y: np.ndarray) -> np.ndarray:
        """Bounds of ``|x^(4)|`` of each dynamic component along the flow from ``Y`` (over a
        step no longer than ``h_growth``): ``sum_j w_j |v_j| |lambda_j|^4 |xi_j| + sum_k
        (k omega)^4 |Z_k|`` (a mode with ``Re lambda > 0`` counted e-fold grown)."""
        return self._absVS4 @ np.abs(self.modal(Y)[2]) + self._forced4

    def grid(self, Y: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The dynamic components and their rates at the equally spaced times ``t`` (from 0)
        from ``Y`` (rows), by one matrix product."""
        omega, phase, xi = self.modal(Y)
        E = modal_sums.powers(np.exp(t[1] * self.lam_s), t.size) if t.size > 1 else np.exp(
            np.outer(t, self.lam_s))
        B = self._VS * xi
        vals = (E @ B.T).real + self.xp(phase + omega * t)
        rates = ((E * self.lam_s) @ B.T).real
        if self._k.size:
            rates += omega * self._xp_rate(phase + omega * t)
        return vals, rates

    def components(self, Y: np.ndarray, times: np.ndarray, idx: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Component ``idx[m]`` (dynamic) of the state, and its rate, at time ``times[m]``
        from ``Y``, ``O(len(times) n)`` in all."""
        omega, phase, xi = self.modal(Y)
        rows = self.pos[idx]
        E = np.exp(np.outer(times, self.lam_s)) * self._VS[rows]
        values = (E @ xi).real + self.x0[rows]
        rates = (E @ (self.lam_s * xi)).real
        if self._k.size:
            cs = self._trig(phase + omega * times)
            K = self._k.size
            Zr, Zi = self._Zs[:K][:, rows].T, self._Zs[K:][:, rows].T   # Re Z_k, -Im Z_k
            c, s = cs[:, :K], cs[:, K:]
            values += (c * Zr + s * Zi).sum(axis=1)
            rates += omega * (self._k * (c * Zi - s * Zr)).sum(axis=1)
        return values, rates

    # ------------------------------------------------------------------ the step
    def _apply(self, e: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``Phi(dt) v`` for one vector or the columns of a matrix (``e = w e^{lambda dt}``)."""
        xi = self._US @ v
        return (self._VS @ (e[:, None] * xi if xi.ndim == 2 else e * xi)).real

    def phi(self, dt: float) -> np.ndarray:
        """``Phi(dt) = Re(V e^{Lambda dt} V^{-1})`` (one real product of size ``n``)."""
        P = self._VS * (self._w * np.exp(self.lam_s * dt))
        return np.hstack([P.real, -P.imag[:, self._cplx]]) @ self._Ustack

    def step(self, Y: np.ndarray, dt: float, jac: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """The state after ``dt`` from ``Y`` and (``jac``) the Jacobian ``dY(dt)/dY``."""
        fld = self.field
        dyn, ck = fld.dyn, fld.clock
        omega, phase, xi = self.modal(Y)
        phase1 = phase + omega * dt
        e = np.exp(self.lam_s * dt)
        Yn = Y.copy()
        Yn[dyn] = self.xp(phase1) + (self._VS @ (e * xi)).real
        if ck is not None:
            Yn[ck] = phase1
        if not jac:
            return Yn, None
        J = np.eye(fld.N)
        nd = dyn.size
        if self._dyn_first:
            J[:nd, :nd] = self.phi(dt)
        else:
            J[np.ix_(dyn, dyn)] = self.phi(dt)
        if ck is not None and self._k.size:
            we = self._w * e
            dxp0, dxp1 = self._xp_rate(phase), self._xp_rate(phase1)
            dom0, dom1 = self._xp_omega(phase), self._xp_omega(phase1)
            cols = self._apply(we, np.column_stack([dxp0, dom0]))
            J[dyn, ck] = dxp1 - cols[:, 0]
            if fld.rate_index is not None:
                J[dyn, fld.rate_index] = dom1 + dt * dxp1 - cols[:, 1]
        if ck is not None and fld.rate_index is not None:
            J[ck, fld.rate_index] = dt
        return Yn, J


class ExactStep:
    """One of the three step Functions of a field layout (:func:`.system._step_functions`)
    computed by a :class:`ModalFlow`: ``kind`` ``state`` (``Yn, err, err3, probe, field``),
    ``jacobian`` (the same and ``vec(J)``, column-major) or ``probe`` (the probe after the
    step), each as one flat array from ``flat(Y, dt)``; the errors are zero. The simulator
    also asks it the length of its next step (:meth:`max_step`) and the extremes of the state
    over a step (:meth:`extremes`), and defers the Jacobians of its steps to the events
    (``exact``: :meth:`.simulate.Simulator._deferred`)."""

    #: the steps compose exactly, bound their own length and give the extremes
    exact = True

    def __init__(self, flow: ModalFlow, kind: str, probe_field: BufferedFunction,
                 probe: BufferedFunction, n: int) -> None:
        self.flow, self.kind, self.n = flow, kind, n
        self._probe_field, self._probe = probe_field, probe
        self._q_key: tuple[float, ...] | None = None
        self._q: Any = None
        #: the probe at the columns of a matrix of ``Q_SAMPLES + 2`` states (one CasADi call,
        #: :func:`.modal_sums.clock_sum`), built on first use
        self._probe_many: BufferedFunction | None = None

    def flat(self, Y: Any, dt: Any) -> np.ndarray:
        Y = np.asarray(Y, dtype=float).ravel()
        Yn, J = self.flow.step(Y, float(dt), self.kind == "jacobian")
        if self.kind == "probe":
            return self._probe.flat(Yn)
        zeros = np.zeros(Yn.size)
        parts = [Yn, zeros, zeros, self._probe_field.flat(Yn)]
        if J is not None:
            parts.append(J.ravel(order="F"))
        return np.concatenate(parts)

    def jacobian(self, Y: np.ndarray, dt: float) -> np.ndarray:
        """``dY(dt)/dY`` of the step of length ``dt`` from ``Y`` alone (the deferred
        sensitivity product of :meth:`.simulate.Simulator._deferred`)."""
        return self.flow.step(np.asarray(Y, dtype=float).ravel(), float(dt), True)[1]

    def max_step(self, Y: np.ndarray, watched: list[int],
                 section: tuple[int, float, int] | None = None,
                 fired: tuple[int, ...] = ()) -> tuple[float, float | None, bool]:
        """The next step from ``Y``: one Hermite cell (:meth:`ModalFlow.hermite_cell`), or,
        when the probe is affine in the state, as many cells as the ``watched`` probe entries
        (and the coordinate of a ``section`` on a dynamic component) are certified clear of
        zero (:func:`.modal_sums.certified_length`; ``fired``: the positions in ``watched`` of
        those that fired at ``Y``). Also the step after it when this certificate already fixes
        it (else None): the one cell it could not clear, which the simulator's Hermite search
        then examines with the cell's accuracy, as it would after a new certificate from the
        step's end (whose first cell that is); and whether the step is certified (no watched
        function has a zero in it: the simulator need not search it)."""
        flow = self.flow
        cell = flow.hermite_cell(Y)
        if flow.probe_modes is None or not watched or not np.isfinite(cell):
            return cell, None, False
        sec = None
        if section is not None and section[0] != flow.field.clock:
            if flow.pos[section[0]] < 0:
                return cell, None, False
            sec = (section[0], section[1])
        q = self._clock_sum(Y)
        if q is None:
            return cell, None, False
        length, first = modal_sums.certified_length(flow, Y, watched, cell, q, sec, fired)
        if length >= flow.h_growth:
            return flow.h_growth, None, first > 0
        return length, (cell if 0 < first < modal_sums.MAX_CELLS else None), first > 0

    def _clock_sum(self, Y: np.ndarray) -> Any:
        """:func:`.modal_sums.clock_sum` at the freed parameters of ``Y`` (kept until they
        change)."""
        key = tuple(Y[self.n:].tolist())
        if key != self._q_key:
            if self._probe_many is None:
                self._probe_many = BufferedFunction(
                    self._probe.function.map(modal_sums.Q_SAMPLES + 2))
            self._q = modal_sums.clock_sum(self.flow, Y, self._probe_many)
            self._q_key = key
        return self._q

    def watched(self, Y: np.ndarray, dt: float, row: int) -> tuple[float, float] | None:
        """Probe entry ``row`` and its time derivative after the step of length ``dt`` from
        ``Y``, as the exponential-trigonometric sum of :mod:`.modal_sums` (no state, no CasADi
        call: the event iterations of :meth:`.simulate.Simulator._refine`); None when the
        probe is not affine in the state or its clock dependence no such sum."""
        flow = self.flow
        if flow.probe_modes is None:
            return None
        q = self._clock_sum(Y)
        if q is None:
            return None
        omega, phase, xi = flow.modal(Y)
        beta = flow.probe_modes[row] * xi
        e = np.exp(flow.lam_s * dt)
        be = beta * e
        g = float(q[0][row]) + float(be.sum().real)
        dg = float((be @ flow.lam_s).real)
        orders = q[1]
        if orders.size:
            gam = q[2][:, row] * np.exp(1j * orders * (phase + omega * dt))
            g += float(gam.sum().real)
            dg += float((gam @ (1j * omega * orders)).real)
        return g, dg

    def extremes(self, Y0: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The extremes of the system's state components over the step of length ``dt`` from
        ``Y0`` (:func:`.modal_sums.grid_extremes`, on Hermite cells)."""
        Y0 = np.asarray(Y0, dtype=float).ravel()
        return modal_sums.grid_extremes(self.flow, Y0, dt, self.flow.hermite_cell(Y0), self.n)


def exact_steps(flow: ModalFlow, probe_field: BufferedFunction, probe: BufferedFunction,
                n: int) -> tuple[ExactStep, ExactStep, ExactStep]:
    """The step, the step with its Jacobian and the probe after the step (the layout of
    :func:`.system._step_functions`) by the exact flow (``n``: the system's dimension)."""
    return tuple(ExactStep(flow, k, probe_field, probe, n)  # type: ignore[return-value]
                 for k in ("state", "jacobian", "probe"))


def modal_flow(f: ca.Function, probe: ca.Function, n: int, clock: int | None,
               names: list[str]) -> ModalFlow | str:
    """The exact flow of the compiled field ``f`` (:func:`detect`, :meth:`ModalFlow.build`),
    or why there is none; ``probe``: the compiled probe (its gradient, when constant, lets
    steps run as long as the watched functions are certified clear of zero)."""
    fld = detect(f, probe, n, clock, names)
    return fld if isinstance(fld, str) else ModalFlow.build(fld)
