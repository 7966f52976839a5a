"""Time-stepping WFEM simulation of the bar with unilateral contact (Algorithm 2, Appendix B).

Yoong, Thorin, Legrand (2017). The bar of section 2 (x in [0, L], contact end at x = L) is
advanced in the characteristic variables of :mod:`problems.bar.wfem_operators`::

    a_i = sigma_i + Z v_i  (moves left one cell per step),
    b_i = sigma_i - Z v_i  (moves right),       Z = rho c,  dt = dx / c  (A.18),

stored on the ring ``w = [b_1..b_N, a_N..a_1]``. One step is the signed rotation (A.18)-(A.21)
with the *floating boundary condition* of Appendix B decided every step at x = L: free
(B.4, ``a_N' = -b_N``) or contact (B.3, ``a_N' = +b_N``; with the moving wall of section 7,
``a_N' = b_N + 2 Z <w_t>``).

Additions to the paper's Algorithm 2 (all derived here):

* **Body force and viscous damping** (section 7: ``f(x, t)`` and "a velocity-dependent term with
  a small viscous damping coefficient in the left-hand side of Eq. (1)"):
  ``rho v_t - sigma_x = f - eta v``, ``sigma_t = E v_x``. Along the characteristics
  ``da/dt = +c (f - eta v)``, ``db/dt = -c (f - eta v)``.
* **Exact force integration** for a force uniform in x, ``f(t) = F0 + f0 sin(omega t)``: a
  content moving one cell gets ``-/+ c F(dt)`` with ``F(s) = int_tn^(tn+s) f``. The content of
  the end cell reflects at x = L at a time ``s`` uniformly distributed over the step, so its
  cell average becomes ``a_N' = s_L (b_N - c Fbar) + c (F(dt) - Fbar)`` with
  ``Fbar = (1/dt) int_0^dt F(s) ds`` (closed form for the sine), ``s_L = -1`` free, ``+1``
  contact; likewise ``b_1' = s_0 (a_1 + c Fbar) - c (F(dt) - Fbar)`` at x = 0 (``s_0 = +1``
  clamped, ``-1`` free). For piecewise-constant data this is the exact evolution of the cell
  averages as long as the boundary condition does not change inside the step.
* **Damping** by Strang splitting: half a step of the exact local solution of
  ``rho v_t = -eta v`` (``v *= exp(-eta dt / (2 rho))``, ``sigma`` unchanged, i.e. the exact 2x2
  exponential on ``(a_i, b_i)``), the exact transport above, half a damping step. Second order,
  and the energy decreases monotonically (transport conserves it, damping only removes kinetic
  energy).
* **A general force** ``f(x, t)`` (callable) is integrated by the midpoint rule along each
  characteristic (``c dt f(x_(i+1/2), t_n + dt/2)``, second order).
* ``source_scheme="euler"`` is the naive first-order alternative (``Q' = A Q + dt S(Q^n)``:
  the bare reflections, then ``+- c dt f(t_n)`` on every cell and ``w_t(t_n)`` at the wall),
  kept to show what the exact integration buys (benchmarks/bench_wfem_benchmark_table1.py).

**Interface quantities over a step** (the Riemann solution (A.12) at x = L with the ghost cells
(B.3)/(B.4)): the value of ``b`` arriving at x = L at ``t_n + s`` is ``b_N - c F(s)``, so free:
stress 0, velocity ``-(b_N - c Fbar)/Z`` on average; contact: velocity ``<w_t>``, stress
``b_N - c Fbar + Z <w_t>`` on average. The end displacement ``u_end`` is the exact time integral
of the interface velocity (B.2). With a clamped left end it also equals ``int sigma/E dx =
dx/(2E) sum_k w_k`` exactly (finite-volume conservation; tested).

**Switching rule** (Algorithm 2 with the sign conventions of
:mod:`problems.bar.wfem_operators`): the gap is ``g = g0 + w_wall(t) - u_end`` (section 7).
Contact is *a candidate* for step n if the bar was in contact, or if ``g_n <= 0``, or if the free
step would make the gap negative with the crossing in the first half of the step
(``g_n < -g_(n+1)^free``: the switch goes to the nearest grid time). A candidate is kept if the
wall stress of the contact step is compressive (``lambda = -S sigma >= 0``, B.5 with the
compressive sign: the paper's (3) and COND2 disagree on the sign of r); otherwise the end is
released (free step). Switching times that fall on the grid are thus found exactly; off-grid
switches cost O(dt) (at most half a step). This is
``switching="grid"``, the paper's algorithm: it conserves energy exactly without damping.

``switching="subcell"`` (an addition) places the switch inside the step: impact at the root
``theta`` of the linearly interpolated gap, release where the wall stress ``b + Z w_t`` turns
tensile; the end-cell content reflecting before and after ``t_n + theta dt`` gets the two
boundary conditions and the cell average of the result leaves the cell. This removes the
timing jitter of the grid rule (with a moving wall the switches fall anywhere in a step, and
at N = 100 the grid rule makes the period-averaged energy of a steady forced response
fluctuate by ~1 %, up to 3 %), at the price of a small numerical dissipation at each switch
(the intra-cell variance of the reflected cell is discarded; steady energies ~1-3 % low at
N = 100, first order in dx). Both keep ``u_end = int sigma/E`` exactly.

Everything is O(N) per step (a few vector operations on the ring).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from nsm_continuation.problems.bar.wfem_operators import (
    BarConstants,
    floating_bc_contact,
    to_ring,
)

ForceField = Callable[[np.ndarray, float], np.ndarray]


def _check_finite(name: str, value: float, positive: bool = False,
                  nonnegative: bool = False) -> float:
    try:
        val = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real number, got {value!r}") from exc
    if not math.isfinite(val):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and val <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    if nonnegative and val < 0.0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return val


# -- data ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BarParams(BarConstants):
    """Bar and mesh: Young's modulus, density, length, cells, cross-section, gap, left end.

    ``dt`` is fixed by the WFEM to ``dx / c`` (CFL number 1, (A.18)); passing ``dt`` only checks
    it.
    """

    E: float = 1.0
    rho: float = 1.0
    L: float = 1.0
    N: int = 100
    S: float = 1.0
    g0: float = 0.0
    left: Literal["clamped", "free"] = "clamped"
    dt: float | None = None

    def __post_init__(self) -> None:
        for name in ("E", "rho", "L", "S"):
            _check_finite(name, getattr(self, name), positive=True)
        _check_finite("g0", self.g0)
        if isinstance(self.N, bool) or not isinstance(self.N, (int, np.integer)):
            raise ValueError(f"N must be an integer, got {self.N!r}")
        if self.N < 2:
            raise ValueError(f"N must be >= 2, got {self.N!r}")
        if self.left not in ("clamped", "free"):
            raise ValueError(f"left must be 'clamped' or 'free', got {self.left!r}")
        if self.dt is not None:
            dt = _check_finite("dt", self.dt, positive=True)
            if abs(dt - self.dx / self.c) > 1e-12 * self.dx / self.c:
                raise ValueError(f"dt must equal dx/c = {self.dx / self.c!r} (WFEM, A.18), "
                                 f"got {dt!r}")

    @property
    def time_step(self) -> float:
        return self.dx / self.c

    @property
    def energy_ref(self) -> float:
        """Energy of the first linear mode's grazing orbit (14): ``pi^2 E S g0^2 / (16 L)``."""
        return math.pi**2 * self.E * self.S * self.g0**2 / (16.0 * self.L)

    @property
    def left_sign(self) -> int:
        return 1 if self.left == "clamped" else -1

    @property
    def x_centres(self) -> np.ndarray:
        return (np.arange(self.N) + 0.5) * self.dx


@dataclass(frozen=True)
class Loading:
    """External actions (section 7): ``f(x, t) = F0 + f0 sin(omega t) [+ force_field(x, t)]``,
    wall ``w(t) = w0 sin(omega t)``, viscous damping ``eta`` (``rho v_t - sigma_x = f - eta v``).
    """

    F0: float = 0.0
    f0: float = 0.0
    omega: float = 0.0
    w0: float = 0.0
    eta: float = 0.0
    force_field: ForceField | None = None
    source_scheme: Literal["exact", "euler"] = "exact"

    def __post_init__(self) -> None:
        for name in ("F0", "f0", "w0"):
            _check_finite(name, getattr(self, name))
        _check_finite("omega", self.omega, nonnegative=True)
        _check_finite("eta", self.eta, nonnegative=True)
        if self.source_scheme not in ("exact", "euler"):
            raise ValueError(f"source_scheme must be 'exact' or 'euler', got "
                             f"{self.source_scheme!r}")
        if self.force_field is not None and not callable(self.force_field):
            raise ValueError("force_field must be a callable f(x, t)")

    def wall(self, t: np.ndarray | float) -> np.ndarray:
        return self.w0 * np.sin(self.omega * np.asarray(t, dtype=float))

    def force(self, t: np.ndarray | float) -> np.ndarray:
        """Uniform part ``F0 + f0 sin(omega t)`` of the body force."""
        return self.F0 + self.f0 * np.sin(self.omega * np.asarray(t, dtype=float))


@dataclass
class BarState:
    """Ring vector ``w`` (2N), end displacement, time, contact flag of the last step."""

    w: np.ndarray
    u_end: float = 0.0
    t: float = 0.0
    contact: bool = False

    def copy(self) -> BarState:
        return BarState(self.w.copy(), self.u_end, self.t, self.contact)


@dataclass
class SimulationResult:
    """Per-step outputs of :func:`simulate`.

    ``t``, ``u_end``, ``energy`` (elastic + kinetic) are sampled at ``t_n`` (M + 1 values);
    ``v_end`` and ``contact_force`` (compressive, ``>= 0``) are averages over ``[t_n, t_n+1]``
    and ``contact`` the boundary condition of that step (with ``switching="subcell"``: the one
    at its end) (M values). ``ring`` holds the M + 1 ring vectors if requested.
    """

    params: BarParams
    loading: Loading
    t: np.ndarray
    u_end: np.ndarray
    v_end: np.ndarray
    contact_force: np.ndarray
    energy: np.ndarray
    contact: np.ndarray
    final: BarState
    ring: np.ndarray | None = None
    wall_time: float = 0.0

    def fields(self) -> tuple[np.ndarray, np.ndarray]:
        """``(sigma, v)`` cell averages, arrays (M + 1, N); needs ``store_fields=True``."""
        if self.ring is None:
            raise ValueError("fields were not stored: call simulate(..., store_fields=True)")
        N = self.params.N
        b = self.ring[:, :N]
        a = self.ring[:, N:][:, ::-1]
        return 0.5 * (a + b), 0.5 * (a - b) / self.params.Z

    def displacement_field(self) -> np.ndarray:
        """``u`` at the cell interfaces ``x_0..x_N`` (M + 1, N + 1): ``u(x) = u_end - int_x^L
        sigma/E`` (exact for the cell averages)."""
        sigma, _ = self.fields()
        p = self.params
        tail = np.cumsum(sigma[:, ::-1], axis=1)[:, ::-1] * p.dx / p.E  # int_x(i-1/2)^L
        u = np.empty((sigma.shape[0], p.N + 1))
        u[:, :p.N] = self.u_end[:, None] - tail
        u[:, p.N] = self.u_end
        return u


# -- initial states ------------------------------------------------------------------------------
def state_from_fields(params: BarParams, sigma: np.ndarray, v: np.ndarray, u_end: float,
                      t: float = 0.0, contact: bool = False) -> BarState:
    """State from cell averages (validated)."""
    sigma = np.asarray(sigma, dtype=float)
    v = np.asarray(v, dtype=float)
    if sigma.shape != (params.N,) or v.shape != (params.N,):
        raise ValueError(f"sigma and v must have shape ({params.N},)")
    if not (np.all(np.isfinite(sigma)) and np.all(np.isfinite(v))):
        raise ValueError("sigma and v must be finite")
    _check_finite("u_end", u_end)
    _check_finite("t", t)
    return BarState(to_ring(sigma, v, params.Z), float(u_end), float(t), bool(contact))


def rest_state(params: BarParams) -> BarState:
    """Static equilibrium without load: unstressed if ``g0 >= 0``; for ``g0 < 0`` (clamped bar)
    uniformly compressed against the wall, ``sigma = E g0 / L``, ``u_end = g0``, in contact."""
    N = params.N
    if params.g0 >= 0.0 or params.left == "free":
        return BarState(np.zeros(2 * N), 0.0, 0.0, False)
    sigma = np.full(N, params.E * params.g0 / params.L)
    return state_from_fields(params, sigma, np.zeros(N), params.g0, 0.0, True)


def ring_displacement(params: BarParams, w: np.ndarray) -> float:
    """``u_end = int_0^L sigma/E dx = dx/(2E) sum_k w_k`` (clamped left end only)."""
    return float(params.dx / (2.0 * params.E) * np.sum(w))


# -- source integrals ----------------------------------------------------------------------------
def _sinc_and_g(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``sin(h)/h`` and ``(cos h - sin(h)/h)/h`` without cancellation."""
    h = np.asarray(h, dtype=float)
    small = np.abs(h) < 1e-3
    hs = np.where(small, 1.0, h)
    sinc = np.where(small, 1.0 - h * h / 6.0 + h**4 / 120.0, np.sin(hs) / hs)
    g = np.where(small, -h / 3.0 + h**3 / 30.0, (np.cos(hs) - np.sin(hs) / hs) / hs)
    return sinc, g


def step_source_terms(params: BarParams, loading: Loading, t0: float, n0: int,
                      M: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-step ``c F(dt)``, ``c Fbar``, ``<w_t>`` and ``w(t_n+1) - w(t_n)`` for steps
    ``n0..n0+M-1`` with ``t_n = t0 + n dt`` (module docstring; closed forms for the sine).

    ``euler`` scheme: ``c dt f(t_n)``, 0, ``w_t(t_n)`` and the same exact wall increment.
    """
    dt, c = params.time_step, params.c
    n = np.arange(n0, n0 + M, dtype=float)
    tn = t0 + n * dt
    om, f0, F0, w0 = loading.omega, loading.f0, loading.F0, loading.w0
    m = om * (tn + 0.5 * dt)
    h = 0.5 * om * dt
    sinc, g = _sinc_and_g(np.array(h))
    sin_h = math.sin(h)
    dw = 2.0 * w0 * np.cos(m) * sin_h  # w(t_n+1) - w(t_n)
    if loading.source_scheme == "euler":
        cFdt = c * dt * (F0 + f0 * np.sin(om * tn))
        cFbar = np.zeros(M)
        wdot = w0 * om * np.cos(om * tn)
        return cFdt, cFbar, wdot, dw
    # int_0^dt f0 sin = f0 dt sin(m) sinc(h);  Fbar = f0 dt/2 (sin m sinc h + cos m g(h))
    cFdt = c * dt * (F0 + f0 * np.sin(m) * sinc)
    cFbar = c * 0.5 * dt * (F0 + f0 * (np.sin(m) * sinc + np.cos(m) * g))
    return cFdt, cFbar, dw / dt, dw


# -- the time loop -------------------------------------------------------------------------------
@dataclass(frozen=True)
class _StepConstants:
    """What every step of one :func:`simulate` call reads (module docstring for the symbols)."""

    N: int
    dt: float
    c: float
    Z: float
    S: float
    g0: float
    s0: float  # left-end reflection sign: +1 clamped, -1 free
    t0: float
    subcell: bool
    wall: bool  # the wall moves
    w0: float
    omega: float
    field_force: ForceField | None
    x_if: np.ndarray  # interfaces x_(i+1/2), i = 0..N


@dataclass(frozen=True)
class _StepSource:
    """Source terms of one step: ``c F(dt)`` of the uniform force (``uniform``, added along
    every characteristic), ``c F(dt)`` and ``c Fbar`` of the content reflecting at x = L
    (``d_L``, ``bar_L``) and at x = 0 (``d_0``, ``bar_0``), field force included; ``phi`` the
    field force's ``c dt f(x_(i+1/2), t_n + dt/2)`` (None without one)."""

    uniform: float
    d_L: float
    bar_L: float
    d_0: float
    bar_0: float
    phi: np.ndarray | None


@dataclass(frozen=True)
class _EndStep:
    """The contact end over one step (floating boundary condition, App. B)."""

    a_new: float  # characteristic a_N leaving x = L at t_(n+1)
    v_end: float  # mean end velocity over the step
    u: float  # end displacement at t_(n+1) (exact time integral of the interface velocity)
    force: float  # mean contact force over the step (compressive >= 0)
    contact: bool  # boundary condition at the end of the step


def _check_state(params: BarParams, state: BarState | None) -> tuple[np.ndarray, float, float,
                                                                      bool]:
    """``(w, u_end, t, contact)`` of the initial state (default :func:`rest_state`), validated;
    ``w`` is a copy."""
    st = rest_state(params) if state is None else state
    w = np.array(st.w, dtype=float)
    if w.shape != (2 * params.N,):
        raise ValueError(f"state.w must have shape ({2 * params.N},), got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("state.w must be finite")
    return (w, _check_finite("state.u_end", st.u_end), _check_finite("state.t", st.t),
            bool(st.contact))


def _chunk_terms(params: BarParams, loading: Loading, k: _StepConstants, n: int,
                 mc: int) -> tuple[list[float], ...]:
    """Per-step source terms of steps ``n..n+mc-1`` as lists (fast scalar access):
    ``c F(dt)``, ``c Fbar``, ``<w_t>``, ``w(t_n+1) - w(t_n)`` (:func:`step_source_terms`) and
    the wall position and velocity at ``t_n..t_n+mc``."""
    terms = [a.tolist() for a in step_source_terms(params, loading, k.t0, n, mc)]
    t_blk = k.t0 + (n + np.arange(mc + 1)) * k.dt
    wall_n = loading.wall(t_blk).tolist() if k.wall else [0.0] * (mc + 1)
    wdp = (k.w0 * k.omega * np.cos(k.omega * t_blk)).tolist() if k.wall else [0.0] * (mc + 1)
    return (*terms, wall_n, wdp)


def _step_source(k: _StepConstants, cFdt: float, cFbar: float, i: int) -> _StepSource:
    """The source terms of step ``i`` (module docstring: exact for the uniform force, midpoint
    along each characteristic for a field force)."""
    fb = fb0 = cFbar
    fd = fd0 = cFdt
    phi = None
    if k.field_force is not None:
        phi = k.c * k.dt * np.asarray(k.field_force(k.x_if, k.t0 + (i + 0.5) * k.dt),
                                      dtype=float)
        fd += phi[k.N]
        fb += 0.5 * phi[k.N]
        fd0 += phi[0]
        fb0 += 0.5 * phi[0]
    return _StepSource(cFdt, fd, fb, fd0, fb0, phi)


def _damp_half_step(aview: np.ndarray, bview: np.ndarray, q_half: float) -> None:
    """Half a step of the exact damping ``rho v_t = -eta v`` on ``(a_i, b_i)`` (Strang
    splitting, module docstring): ``v`` decays, ``sigma = (a + b)/2`` is unchanged."""
    d = aview - bview
    d *= q_half
    bview += d
    aview -= d


def _subcell_theta(k: _StepConstants, contact: bool, J: float, src: _StepSource, g_n: float,
                   g_next: float, wdp_a: float, wdp_b: float) -> float:
    """Fraction ``theta`` of the step where the boundary condition would switch
    (``switching="subcell"``), -1 if none: in contact, where the wall stress ``b + Z w_t``
    (linear over the step) turns tensile; free, at the root of the linearly interpolated gap."""
    if contact:
        sg0 = J + k.Z * wdp_a  # wall stress at t_n+ and at t_n+1-
        sg1 = J - src.d_L + k.Z * wdp_b
        return sg0 / (sg0 - sg1) if sg0 <= 0.0 < sg1 else -1.0
    return g_n / (g_n - g_next) if g_n > 0.0 and g_next < 0.0 else -1.0


def _subcell_switch(k: _StepConstants, contact: bool, be: float, src: _StepSource, u: float,
                    i: int, theta: float, wall_a: float, wall_b: float) -> _EndStep | None:
    """The switch at ``t_n + theta dt`` inside step ``i``: the end-cell content reflecting
    before and after it gets the two boundary conditions and its average leaves the cell
    (module docstring). A release always happens; an impact only if the wall stress after it
    is compressive (else None: the step stays free)."""
    dt, Z = k.dt, k.Z
    t_th = k.t0 + (i + theta) * dt
    w_th = k.w0 * math.sin(k.omega * t_th) if k.wall else 0.0
    fd, fb = src.d_L, src.bar_L
    if contact:  # release
        wd1 = (w_th - wall_a) / (theta * dt)
        sig1 = be + Z * wd1
        a_new = theta * (be + 2.0 * Z * wd1) - (1.0 - theta) * be + (fd - fb)
        u_new = u + (w_th - wall_a) - (1.0 - theta) * dt * be / Z
        return _EndStep(a_new, (u_new - u) / dt, u_new, -k.S * theta * sig1, False)
    wd2 = (wall_b - w_th) / ((1.0 - theta) * dt)
    sig2 = be + Z * wd2
    if sig2 > 0.0:
        return None
    a_new = -theta * be + (1.0 - theta) * (be + 2.0 * Z * wd2) + (fd - fb)
    u_new = u - theta * dt * be / Z + (wall_b - w_th)
    return _EndStep(a_new, (u_new - u) / dt, u_new, -k.S * (1.0 - theta) * sig2, True)


def _whole_step(k: _StepConstants, contact: bool, be: float, sig_c: float, src: _StepSource,
                u: float, wd: float, dw: float) -> _EndStep:
    """One boundary condition over the whole step: contact (B.3, moving wall: ``a_N' = b_N + 2
    Z <w_t>``) or free (B.4, ``a_N' = -b_N``), with the exact force terms."""
    if contact:
        return _EndStep(be + 2.0 * k.Z * wd + (src.d_L - src.bar_L), wd, u + dw, -k.S * sig_c,
                        True)
    v_end = -be / k.Z
    return _EndStep(-be + (src.d_L - src.bar_L), v_end, u + k.dt * v_end, 0.0, False)


def _end_step(k: _StepConstants, J: float, src: _StepSource, contact: bool, u: float, i: int,
              wall_a: float, wall_b: float, wdp_a: float, wdp_b: float, wd: float,
              dw: float) -> _EndStep:
    """One step of the floating boundary condition at x = L (Algorithm 2): ``J`` the
    characteristic ``b_N`` arriving, ``contact`` the condition of the previous step, ``u`` the
    end displacement at ``t_n``; ``wall_a, wall_b`` and ``wdp_a, wdp_b`` the wall position and
    velocity at ``t_n`` and ``t_(n+1)``, ``wd`` its mean velocity over the step, ``dw`` its
    increment. The decision is :func:`~problems.bar.wfem_operators.floating_bc_contact` with the
    gap (B.2) and the wall stress ``b + Z <w_t>`` (B.5); ``switching="grid"`` closes at the
    nearest grid time, ``"subcell"`` first tries a switch inside the step."""
    be = J - src.bar_L  # mean b arriving at x = L over the step
    g_n = k.g0 + wall_a - u
    g_next = k.g0 + wall_b - (u - k.dt * be / k.Z)  # gap at t_(n+1) after a free step
    if k.subcell:
        theta = _subcell_theta(k, contact, J, src, g_n, g_next, wdp_a, wdp_b)
        if theta > 0.0:
            switched = _subcell_switch(k, contact, be, src, u, i, theta, wall_a, wall_b)
            if switched is not None:
                return switched
    sig_c = be + k.Z * wd
    contact = floating_bc_contact(contact, g_n, g_next, sig_c, nearest=not k.subcell)
    return _whole_step(k, contact, be, sig_c, src, u, wd, dw)


def _transport(w: np.ndarray, bview: np.ndarray, wa: np.ndarray, N: int, src: _StepSource,
               a_new: float, b_new: float) -> None:
    """(A.18): rotate the ring one slot, add the sources along the characteristics, set the
    two reflected values."""
    w[1:] = w[:-1]
    if src.uniform != 0.0:
        bview -= src.uniform
        wa += src.uniform
    if src.phi is not None:
        w[1:N] -= src.phi[1:N]
        wa[1:] += src.phi[N - 1:0:-1]
    w[N] = a_new
    w[0] = b_new


def simulate(params: BarParams, loading: Loading, n_steps: int, state: BarState | None = None,
             store_fields: bool = False, switching: Literal["grid", "subcell"] = "grid",
             chunk: int = 65536) -> SimulationResult:
    """Algorithm 2 with floating boundary conditions, force, moving wall and damping.

    ``n_steps`` WFEM steps of ``dt = dx/c`` (A.18) from ``state`` (default: :func:`rest_state`),
    the contact end switched by the gap (B.2) and the sign of the wall stress (B.5) as in the
    module docstring (``switching`` "grid": Algorithm 2; "subcell": sub-step switching). O(N)
    per step; ``store_fields`` keeps every ring vector (O(N M) memory, for space-time plots).
    Each step: half a damping step, the source terms (:func:`_step_source`), the floating
    boundary condition (:func:`_end_step`), the reflection at x = 0, the transport
    (:func:`_transport`), half a damping step.
    """
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
        raise ValueError(f"n_steps must be a non-negative integer, got {n_steps!r}")
    w, u, t0, contact = _check_state(params, state)
    if switching not in ("grid", "subcell"):
        raise ValueError(f"switching must be 'grid' or 'subcell', got {switching!r}")
    N = params.N
    M = int(n_steps)
    k = _StepConstants(N, params.time_step, params.c, params.Z, params.S, params.g0,
                       float(params.left_sign), t0, switching == "subcell",
                       loading.w0 != 0.0 and loading.omega != 0.0, loading.w0, loading.omega,
                       loading.force_field, np.arange(N + 1) * params.dx)
    en_fac = params.S * params.dx / (4.0 * params.E)
    gamma = loading.eta / params.rho
    damp = gamma > 0.0
    q_half = 0.5 * (1.0 - math.exp(-0.5 * gamma * k.dt))  # b += q (a - b), a -= q (a - b)

    t_out = t0 + np.arange(M + 1) * k.dt
    u_out = np.empty(M + 1)
    e_out = np.empty(M + 1)
    v_out = np.empty(M)
    f_out = np.empty(M)
    c_out = np.zeros(M, dtype=bool)
    ring = np.empty((M + 1, 2 * N)) if store_fields else None
    u_out[0] = u
    e_out[0] = en_fac * float(np.dot(w, w))
    if ring is not None:
        ring[0] = w

    bview = w[:N]
    aview = w[N:][::-1]  # a_1..a_N, aligned with b_1..b_N
    wa = w[N:]
    tic = time.perf_counter()
    n = 0
    while n < M:
        mc = min(chunk, M - n)
        cFdt, cFbar, wdot, dw, wall_n, wdp = _chunk_terms(params, loading, k, n, mc)
        for j in range(mc):
            i = n + j
            if damp:
                _damp_half_step(aview, bview, q_half)
            src = _step_source(k, cFdt[j], cFbar[j], i)
            a1 = w[2 * N - 1]
            end = _end_step(k, w[N - 1], src, contact, u, i, wall_n[j], wall_n[j + 1],
                            wdp[j], wdp[j + 1], wdot[j], dw[j])
            contact, u = end.contact, end.u
            b_new = k.s0 * (a1 + src.bar_0) - (src.d_0 - src.bar_0)  # reflection at x = 0
            _transport(w, bview, wa, N, src, end.a_new, b_new)
            if damp:
                _damp_half_step(aview, bview, q_half)
            v_out[i] = end.v_end
            f_out[i] = end.force
            c_out[i] = contact
            u_out[i + 1] = u
            e_out[i + 1] = en_fac * float(np.dot(w, w))
            if ring is not None:
                ring[i + 1] = w
        n += mc
    wall_time = time.perf_counter() - tic
    final = BarState(w.copy(), u, t0 + M * k.dt, contact)
    return SimulationResult(params, loading, t_out, u_out, v_out, f_out, e_out, c_out, final,
                            ring, wall_time)


__all__ = [
    "BarParams",
    "BarState",
    "Loading",
    "SimulationResult",
    "rest_state",
    "ring_displacement",
    "simulate",
    "state_from_fields",
    "step_source_terms",
]
