"""Symbolic declaration of an impacting system and every quantity CasADi derives from it.

A system (Nordmark & Piiroinen 2009, sec. 2) is a vector field ``F(x)`` on ``R^n``, an impact
surface ``H(x) = 0`` with admissible side ``H >= 0``, and an impact law ``R(x) = x + W(x) v(x)``
(eq. 5). The user writes ``F``, ``H`` and ``W`` (or, for a mechanical system, ``M(q)``, the
generalized force, ``H(q)`` and a restitution ``e``: eqs. (54)-(59)) as CasADi expressions; the
rest is derived here, never by hand:

=====================  ==========================================================================
``v = L_F H``          velocity relative to the surface, eq. (2)
``a = L_F^2 H``        acceleration, eq. (3); ``jerk = L_F^3 H`` (release detection, Hermite data)
``r``                  low-velocity restitution ``-(1 + L_W L_F H)``, eq. (8)
``lambda, F'``         sticking multiplier and field ``F' = F - lambda W``, eqs. (10)-(12)
``Q, q``               first-order chatter map and chatter time, eqs. (30)-(31)
``R_x, Q_x, ...``      exact Jacobians for the saltation-chained monodromy (eqs. 40, 43)
``step``               one explicit Runge-Kutta step of ``F``, ``F'`` or the scaled extended
                       field (sec. 4.3, eq. 44), its error estimate and its exact Jacobian
=====================  ==========================================================================

**Several surfaces.** ``H`` may be a column of ``m`` constraints ``H_i(x) >= 0`` (a two-sided stop,
a ball in a cavity, several masses at walls), each with its own jump ``W_i`` (column ``i`` of
``W``; for a mechanical system its own restitution ``e_i``) and an optional name: every derived
quantity above exists per surface (:class:`SurfaceFunctions`), and the simulator tracks impacts,
chattering, sticking and release per surface. Each ``H_i`` must be smooth: an expression built
with a nonsmooth operation (``fabs``, ``sign``, ``fmin``/``fmax``, ``if_else``, comparisons,
``floor``...) is refused (its Lie derivatives, the saltation matrices and the event location
need continuous derivatives); declare the pieces as separate surfaces instead.

**No surface.** ``H`` may also be empty (:meth:`HybridSystem.smooth`, ``m = 0``): a smooth
flow, simulated between its Poincaré section's crossings with the same exact sensitivities, no
event to watch (the check of a smooth system's closed forms, e.g. a Hopf family).

Continuation parameters are *lifted into the state* (``free=`` in :meth:`HybridSystem.compile`):
they become extra components with zero rate, so the Jacobian of the simulated map with respect to
them comes out of the same chain of step and saltation Jacobians as the state part (the
parameter column of the shooting Jacobian is exact, like the rest).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from nsm_continuation.core.casadi_buffers import BufferedFunction
from nsm_continuation.hybrid import linear_flow, tableaus


class HybridDeclarationError(ValueError):
    """A declaration that cannot describe an impacting system (named field, clear message)."""


#: a restitution ``r >= 1 - ELASTIC_TOL`` is an elastic impact (``r = 1`` up to the round-off of
#: its derivation, eq. 8): no chatter map (:meth:`CompiledHybrid.validate_at`)
ELASTIC_TOL = 1e-12


def _dop853() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    return (tableaus.DOP853_A, tableaus.DOP853_B, tableaus.DOP853_C, tableaus.DOP853_E5,
            tableaus.DOP853_E3, 8)


def _dopri5() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, None, int]:
    return tableaus.DOPRI5_A, tableaus.DOPRI5_B, tableaus.DOPRI5_C, tableaus.DOPRI5_E, None, 5


#: explicit embedded Runge-Kutta tableaus (:mod:`nsm_continuation.hybrid.tableaus`)
TABLEAUS = {"dop853": _dop853, "dopri5": _dopri5}

#: the choices of free flight besides a tableau: ``exact`` (the closed-form flow of a system
#: linear between events, :mod:`.linear_flow`; refused with the reason otherwise) and ``auto``
#: (the exact flow where it applies and pays, :data:`AUTO_MIN_DYNAMIC`, else DOP853). Sticking
#: and chattering fields keep DOP853.
FLOWS = ("auto", "exact")

#: ``auto`` runs the exact flow from this many dynamic state components on (three degrees of
#: freedom of a mechanical system). Measured per continuation point, CPU time, on the forced
#: chain of ``benchmarks/bench_exact_flow.py`` (both paths in one run): 2 masses (4 dynamic
#: components) 1.0x, 3 masses 1.4x, 5 masses 1.9x, 10 masses 2.3x faster by the exact flow.
#: Below, a simulation's cost is its per-event and per-step bookkeeping, the same on both
#: paths, and the Runge-Kutta path (the default, hence the bundled numbers) runs.
AUTO_MIN_DYNAMIC = 6


def rk_step(f: ca.Function, X: ca.SX, dt: ca.SX, method: str) -> tuple[ca.SX, ca.SX, ca.SX]:
    """Symbolic embedded RK step: ``(X_new, err_main, err_aux)`` (FSAL stage included).

    For DOP853 the two error vectors are SciPy's ``err5`` and ``err3`` (the norm combines them as
    in ``scipy.integrate.DOP853``); for DOPRI5 ``err_aux`` is zero.
    """
    A, B, _C, E, E3, _order = TABLEAUS[method]()
    s = len(B)
    K = [f(X)]
    for i in range(1, s):
        inc = sum((float(A[i, j]) * K[j] for j in range(i) if A[i, j] != 0.0), ca.SX.zeros(X.shape))
        K.append(f(X + dt * inc))
    Xn = X + dt * sum((float(B[i]) * K[i] for i in range(s) if B[i] != 0.0),
                      ca.SX.zeros(X.shape))
    K.append(f(Xn))
    err = dt * sum((float(E[i]) * K[i] for i in range(s + 1) if E[i] != 0.0),
                   ca.SX.zeros(X.shape))
    if E3 is not None:
        err3 = dt * sum((float(E3[i]) * K[i] for i in range(s + 1) if E3[i] != 0.0),
                        ca.SX.zeros(X.shape))
    else:
        err3 = ca.SX.zeros(X.shape)
    return Xn, err, err3


def _lie(expr: ca.SX, X: ca.SX, field_: ca.SX) -> ca.SX:
    """Lie derivative ``L_field expr = expr_X field`` (exact, by CasADi's forward mode)."""
    return ca.jtimes(expr, X, field_)


@dataclass
class HybridSystem:
    """Symbolic declaration: state ``x``, parameters, ``F``, ``H`` and ``W`` (eq. 5).

    ``params`` maps parameter names to scalar CasADi symbols used in the expressions.
    ``periodic`` maps state indices of angle-like coordinates to their period (``2 pi``), used by
    Poincaré sections and plots; ``clock`` names a phase coordinate of a forced system
    (``x_3 = omega t`` in eq. (4)).
    """

    name: str
    x: ca.SX
    params: dict[str, ca.SX]
    F: ca.SX
    H: ca.SX
    W: ca.SX
    state_names: list[str]
    periodic: dict[int, float] = field(default_factory=dict)
    #: indices of the position coordinates moved when the chatter map's end point is projected
    #: onto the sticking set (default: every state component ``H`` depends on)
    position: list[int] | None = None
    #: number of configuration coordinates (positions) at the head of the state of a mechanical
    #: system (its response quantities are their extremes); None: every state component
    n_config: int | None = None
    #: the parameter that is the rate of the clock of a forced system (``x_3' = omega``), so
    #: that its orbits are presented as frequency responses; None for autonomous systems
    forcing_frequency: str | None = None
    #: the index of the clock (the forcing's phase) in the state of a forced system: a
    #: section on it may be moved along the orbit (``HybridShootingProblem.rechart``)
    clock_index: int | None = None
    #: one name per surface (``H_i``, column ``i`` of ``W``); default ``H`` for one surface,
    #: ``H1 .. Hm`` for several
    surface_names: list[str] | None = None

    def __post_init__(self) -> None:
        n = self.x.numel()
        if self.F.numel() != n:
            raise HybridDeclarationError(
                f"system {self.name!r}: F has {self.F.numel()} components, state has {n}")
        if isinstance(self.H, (list, tuple)):
            self.H = ca.vertcat(*[ca.SX(h) for h in self.H])
        if isinstance(self.W, (list, tuple)) and not self.W:
            self.W = ca.SX(n, 0)
        if self.H.numel() == 0:
            # no contact (:meth:`smooth`): a smooth flow, its sections and multipliers
            self.H = ca.SX(0, 1)
        if self.H.size2() != 1:
            raise HybridDeclarationError(
                f"system {self.name!r}: H must be a scalar or a column (one constraint per "
                f"surface), not {self.H.size1()}x{self.H.size2()}")
        m = self.H.numel()
        if self.W.numel() != n * m or (m > 1 and self.W.size2() != m):
            raise HybridDeclarationError(
                f"system {self.name!r}: W must have one column of {n} components per surface "
                f"({m}), not {self.W.size1()}x{self.W.size2()}")
        if self.W.size2() != m:
            self.W = ca.reshape(self.W, n, m)
        if self.surface_names is None:
            self.surface_names = ["H"] if m == 1 else [f"H{i + 1}" for i in range(m)]
        self.surface_names = [str(k) for k in self.surface_names]
        if len(self.surface_names) != m or len(set(self.surface_names)) != m:
            raise HybridDeclarationError(
                f"system {self.name!r}: surfaces needs {m} distinct names, got "
                f"{self.surface_names}")
        for i in range(m):
            what = "H" if m == 1 else f"H of surface {self.surface_names[i]!r}"
            if not ca.depends_on(self.H[i], self.x):
                raise HybridDeclarationError(
                    f"system {self.name!r}: {what} does not depend on the state (no impact "
                    "surface)")
            ops = _nonsmooth_operations(self.H[i], self.x, list(self.params.values()))
            if ops:
                raise HybridDeclarationError(
                    f"system {self.name!r}: {what} uses {', '.join(ops)}, which is not smooth: "
                    "the event location and the saltation matrices need a smooth constraint; "
                    "declare each smooth piece as its own surface (a list of H)")
        if len(self.state_names) != n:
            raise HybridDeclarationError(
                f"system {self.name!r}: {len(self.state_names)} state names for {n} states")
        if self.position is None:
            self.position = [i for i in range(n) if ca.depends_on(self.H, self.x[i])]

    @property
    def n(self) -> int:
        return int(self.x.numel())

    @property
    def m(self) -> int:
        """Number of impact surfaces (constraints ``H_i >= 0``)."""
        return int(self.H.numel())

    # ------------------------------------------------------------------ constructors
    @classmethod
    def smooth(cls, name: str, x: ca.SX, params: dict[str, ca.SX], F: ca.SX,
               state_names: Sequence[str], *, periodic: dict[int, float] | None = None,
               clock_index: int | None = None, forcing_frequency: str | None = None
               ) -> HybridSystem:
        """A smooth system ``x' = F(x)`` without contact (no surface: ``H`` and ``W`` empty,
        ``m = 0``). Its orbits are continued like an impacting system's (a section, the
        monodromy by the variational equations, the multipliers), with no impact, sticking or
        grazing to locate: the check of a smooth problem's closed forms (a Hopf family), or a
        system whose contacts are added later."""
        return cls(name, x, params, F, ca.SX(0, 1), ca.SX(x.numel(), 0), list(state_names),
                   dict(periodic or {}), clock_index=clock_index,
                   forcing_frequency=forcing_frequency)

    @classmethod
    def mechanical(cls, name: str, q: ca.SX, qd: ca.SX, params: dict[str, ca.SX], M: ca.SX,
                   force: ca.SX, H: ca.SX | Sequence[ca.SX], e: Any, *,
                   surfaces: Sequence[str] | None = None,
                   clock: ca.SX | None = None, clock_rate: ca.SX | None = None,
                   state_names: Sequence[str] | None = None,
                   periodic: dict[int, float] | None = None) -> HybridSystem:
        """A mechanical system ``M(q) qdd = force(q, qd[, clock])`` with unilateral constraints
        ``H_i(q) >= 0`` and Newton's law ``N_i^T qd+ = -e_i N_i^T qd-`` at each (eqs. 54-59).

        ``H`` is one constraint or a list of them (one per surface, named by ``surfaces``), and
        ``e`` one restitution or a list with one per surface. The state is
        ``x = (q, qd[, clock])``; ``N_i = (H_i)_q^T`` and
        ``W_i = (0, -(1 + e_i) M^{-1} N_i / (N_i^T M^{-1} N_i)[, 0])`` (eq. 58), so ``r_i = e_i``
        (eq. 8) and ``L_{W_i} H_i = 0`` identically (``W_i`` is tangent to its surface, as
        sec. 2.4 requires); the impulse ``M^{-1} N_i`` conserves the momentum of every
        direction orthogonal to ``N_i`` (e.g. the total momentum of two colliding masses).
        """
        Hs = list(H) if isinstance(H, (list, tuple)) else [H]
        es = list(e) if isinstance(e, (list, tuple)) else [e] * len(Hs)
        if len(es) != len(Hs):
            raise HybridDeclarationError(
                f"system {name!r}: {len(es)} restitutions for {len(Hs)} surfaces")
        for h in Hs:
            if isinstance(h, ca.SX) and h.numel() != 1:
                raise HybridDeclarationError(
                    f"system {name!r}: H must be a scalar or a list of scalars (one per "
                    f"surface), not {h.size1()}x{h.size2()}")
            if ca.depends_on(ca.SX(h), qd):
                raise HybridDeclarationError(
                    f"system {name!r}: H must depend on positions only for a mechanical system")
        nq = q.numel()
        Minv_force = ca.solve(M, force)
        Wqs = []
        for h, ei in zip(Hs, es, strict=True):
            N = ca.jacobian(h, q).T
            MiN = ca.solve(M, N)
            Wqs.append(-(1 + ei) * MiN / ca.dot(N, MiN))
        Wq = ca.horzcat(*Wqs)
        m = len(Hs)
        parts_x, parts_F, parts_W = [q, qd], [qd, Minv_force], [ca.SX.zeros(nq, m), Wq]
        if clock is not None:
            parts_x.append(clock)
            parts_F.append(clock_rate if clock_rate is not None else ca.SX.ones(clock.numel()))
            parts_W.append(ca.SX.zeros(clock.numel(), m))
        x = ca.vertcat(*parts_x)
        names = list(state_names) if state_names is not None else [
            *(f"q{i + 1}" for i in range(nq)), *(f"q{i + 1}dot" for i in range(nq)),
            *(["phase"] if clock is not None else [])]
        forcing = None if clock_rate is None else next(
            (k for k, sym in params.items() if ca.is_equal(ca.SX(clock_rate), sym)), None)
        Hcol = Hs[0] if m == 1 else ca.vertcat(*[ca.SX(h) for h in Hs])
        sys = cls(name, x, params, ca.vertcat(*parts_F), Hcol, ca.vertcat(*parts_W), names,
                  dict(periodic or {}), n_config=nq, forcing_frequency=forcing,
                  clock_index=2 * nq if clock is not None else None,
                  surface_names=list(surfaces) if surfaces is not None else None)
        sys._mass = ca.Function("M", [q, *params.values()], [M])  # type: ignore[attr-defined]
        #: the inputs ``M`` depends on: a constant mass matrix is checked once per parameter set
        sys._mass_uses_q = bool(ca.depends_on(ca.SX(M), q))  # type: ignore[attr-defined]
        sys._nq = nq  # type: ignore[attr-defined]
        return sys

    # ------------------------------------------------------------------ compilation
    def compile(self, values: dict[str, float], free: Sequence[str] = (),
                method: str = "dop853") -> CompiledHybrid:
        """Substitute numeric ``values`` for every parameter except ``free`` (lifted into the
        state) and build the CasADi Functions: the derived quantities of the module docstring
        (eqs. 2-12, 24, 30-31), the projection onto the sticking set and the Runge-Kutta steps
        (:func:`_step_functions`). Raises :class:`HybridDeclarationError` naming the parameter
        on a missing, unknown or non-finite value.

        ``method``: a Runge-Kutta tableau (``dop853``, ``dopri5``) for every field, or one of
        :data:`FLOWS`: the free flight by its exact flow (:mod:`.linear_flow`; ``exact``
        refuses a system that is not linear between events with the reason, ``auto`` falls
        back to DOP853 and keeps the reason in :attr:`CompiledHybrid.flow_note`), the sticking
        and chattering fields by DOP853. With the exact flow the Runge-Kutta step Functions
        of the free flight are not built (:attr:`CompiledHybrid.steps` has no ``free``)."""
        self._check_values(values, free, method)
        tableau = method if method in TABLEAUS else "dop853"
        fixed = [k for k in self.params if k not in free]
        sym_fixed = [self.params[k] for k in fixed]
        num_fixed = [float(values[k]) for k in fixed]
        free_syms = [self.params[k] for k in free]

        def sub(expr: ca.SX) -> ca.SX:
            return ca.substitute([expr], sym_fixed, num_fixed)[0] if sym_fixed else expr

        X = ca.vertcat(self.x, *free_syms) if free_syms else self.x
        nfree = len(free_syms)
        m = self.m
        F = ca.vertcat(sub(self.F), ca.SX.zeros(nfree))
        Wall = ca.vertcat(sub(self.W), ca.SX.zeros(nfree, m))
        Hall = sub(self.H)
        parts = []
        for i in range(m):
            H, W = Hall[i], Wall[:, i]
            v = _lie(H, X, F)
            a = _lie(v, X, F)
            jerk = _lie(a, X, F)
            LWH = _lie(H, X, W)
            LWv = _lie(v, X, W)
            r = -(1 + LWv)
            lam = a / LWv                                        # eq. (12): -a / (1 + r)
            Fs = F - lam * W                                      # eq. (10)
            R = X + W * v                                         # eq. (5)
            K = 2 * F * r / a + W                                 # eq. (24)
            Q1 = X + K * v / (1 - r)                              # eq. (30), first order
            q1 = 2 * r * v / (a * (1 - r))                        # eq. (31), first order
            P = self._sticking_projection(X, H, v, W, r, i)
            parts.append((H, v, a, jerk, LWH, r, lam, Fs, R, Q1, q1, P, W))
        blocks = [ca.vertcat(H, v, a, jerk) for H, v, a, jerk, *_ in parts]
        probe = blocks[0] if m == 1 else ca.vertcat(*blocks)
        modal = None
        note = ""
        if method in FLOWS:
            found = linear_flow.modal_flow(
                ca.Function("F", [X], [F]), ca.Function("probe", [X], [probe]), self.n,
                self.clock_index, [*self.state_names, *free])
            if isinstance(found, str):
                if method == "exact":
                    raise HybridDeclarationError(f"integrator 'exact': {self.name}: {found}")
                note = f"the exact flow does not apply: {found}"
            elif method == "auto" and found.field.dyn.size < AUTO_MIN_DYNAMIC:
                note = (f"the exact flow applies but does not pay below {AUTO_MIN_DYNAMIC} "
                        f"dynamic state components (here {found.field.dyn.size})")
            else:
                modal = found
        fF, steps, probe_field, ext = _step_functions(
            X, F, [(pt[7], pt[1]) for pt in parts], blocks, [pt[0] for pt in parts], tableau,
            free_flight=modal is None)
        surfaces = []
        for i, (H, v, a, _jerk, LWH, r, lam, _Fs, R, Q1, q1, P, W) in enumerate(parts):
            fFs, fFe, probe_e, Xe = ext[i]
            grads = ca.vertcat(ca.jacobian(H, X), ca.jacobian(v, X), ca.jacobian(a, X))
            surfaces.append(SurfaceFunctions(
                name=self.surface_names[i], index=i,  # type: ignore[index]
                stick_key=_key("stick", i), ext_key=_key("ext", i),
                fs=fFs, fe=fFe,
                probe_e=ca.Function("probe_e", [Xe], [probe_e]),
                grads=ca.Function("grads", [X], [grads]),
                quantities=ca.Function("quantities", [X], [ca.vertcat(H, v, a, r, lam, LWH)]),
                impact=ca.Function("impact", [X], [R, ca.jacobian(R, X), v, r]),
                vgrad=ca.Function("vgrad", [X], [v, ca.jacobian(v, X)]),
                jump=ca.Function("jump", [X], [W]),
                chatter=ca.Function("chatter", [X], [Q1, q1, ca.jacobian(Q1, X),
                                                     ca.jacobian(q1, X), r, ca.jacobian(r, X)]),
                project=ca.Function("project", [X], [P, ca.jacobian(P, X)])))
        return CompiledHybrid(
            system=self, n=self.n, N=int(X.numel()), free=list(free), method=tableau,
            order=TABLEAUS[tableau]()[5], f=fF,
            probe=ca.Function("probe", [X], [probe]),
            surfaces=surfaces, steps=steps, probe_field=probe_field,
            values={k: float(v) for k, v in values.items()},
            flow="exact" if modal is not None else tableau, flow_note=note, modal=modal,
        )

    def _check_values(self, values: dict[str, float], free: Sequence[str], method: str) -> None:
        """Every parameter is freed or has a finite value; no unknown name; a known method."""
        names = list(self.params)
        for k in free:
            if k not in self.params:
                raise HybridDeclarationError(f"{self.name}: cannot free unknown parameter {k!r}"
                                             f" (parameters: {names})")
        for k in names:
            if k not in free and k not in values:
                raise HybridDeclarationError(f"{self.name}: missing value for parameter {k!r}")
        for k, val in values.items():
            if k not in self.params:
                raise HybridDeclarationError(f"{self.name}: unknown parameter {k!r}")
            if not np.isfinite(float(val)):
                raise HybridDeclarationError(f"{self.name}: parameter {k!r} is not finite")
        if method not in TABLEAUS and method not in FLOWS:
            raise HybridDeclarationError(
                f"integrator {method!r}: choose one of {[*FLOWS, *TABLEAUS]}")

    def _sticking_projection(self, X: ca.SX, H: ca.SX, v: ca.SX, W: ca.SX, r: ca.SX,
                             surface: int = 0) -> ca.SX:
        """Projection of a chatter end point onto the sticking set ``{H = 0, v = 0}``: Newton
        steps along ``grad H`` (positions) and along ``W`` (velocities). It moves the point by
        ``O(v^2)``, the order of the first-order map's own error, and makes ``v`` exactly
        invariant under ``F'``."""
        pos = ca.SX.zeros(X.shape)
        for i in self.position or []:
            if self.m == 1 or ca.depends_on(self.H[surface], self.x[i]):
                pos[i] = 1
        Hx = ca.jacobian(H, X).T * pos
        Hfun = ca.Function("Hf", [X], [H, Hx, v, W, r])
        P = X
        for _ in range(2):
            h_, hx_, v_, w_, r_ = Hfun(P)
            P = P - hx_ * h_ / ca.dot(hx_, hx_)
            h_, hx_, v_, w_, r_ = Hfun(P)
            P = P + w_ * v_ / (1 + r_)
        return P


def _key(kind: str, surface: int) -> str:
    """Name of the field and probe layout ``kind`` (``stick``, ``ext``) on ``surface``: the
    first surface's are ``stick`` and ``ext``, the others' ``stick2``, ``ext2``, ..."""
    return kind if surface == 0 else f"{kind}{surface + 1}"


def probe_layout(m: int, active: int | None, extended: bool) -> list[int]:
    """Offset of each surface's block ``(H, v, a, jerk)`` in the probe of a layout: in free
    flight (``active`` None) the blocks in order; sticking or chattering on surface ``active``
    its block first (then ``h, h'`` in a chattering flight), the others after it in order."""
    if active is None:
        return [4 * i for i in range(m)]
    offsets, pos = [0] * m, 6 if extended else 4
    for i in range(m):
        if i != active:
            offsets[i], pos = pos, pos + 4
    return offsets


def _step_functions(X: ca.SX, F: ca.SX, sticking: list[tuple[ca.SX, ca.SX]],
                    blocks: list[ca.SX], Hs: list[ca.SX], method: str,
                    free_flight: bool = True) -> tuple[Any, ...]:
    """The fields ``F``, ``F'_i`` of each surface ``i`` (``sticking[i] = (F'_i, v_i)``) and the
    scaled extended field of sec. 4.3, eq. (44) (``(X, h, u)``, ``h' = v_i/u``, ``u' = 0``), with
    one Runge-Kutta step of each and its exact Jacobian (and its error estimates' Jacobians),
    each with its probe (the blocks
    ``(H, v, a, jerk)`` of every surface in the order of :func:`probe_layout`):
    ``(fF, steps, probe_field, ext)``; ``probe_field[key]`` gives the probe and the field of
    ``key`` at a state in one call; ``ext[i] = (fFs_i, fFe_i, probe_e_i, Xe)``. While sticking
    on surface ``i`` the other surfaces' blocks are Lie derivatives along ``F'_i`` (the field
    integrated), so that each watched function's next entry is its time derivative. Without
    ``free_flight`` the steps of ``F`` are not built (the exact flow replaces them)."""
    hs, us = ca.SX.sym("h"), ca.SX.sym("u")
    Xe = ca.vertcat(X, hs, us)
    m = len(blocks)
    probe = blocks[0] if m == 1 else ca.vertcat(*blocks)
    fF = ca.Function("F", [X], [F])
    layouts: list[tuple[str, ca.Function, ca.SX, ca.SX]] = [("free", fF, X, probe)]
    ext = []
    for i, (Fs, v) in enumerate(sticking):
        others = [blocks[j] for j in range(m) if j != i]
        Fe = ca.vertcat(F, v / us, 0)
        probe_e = ca.vertcat(blocks[i], hs, v / us, *others)
        fFs = ca.Function("Fs", [X], [Fs])
        fFe = ca.Function("Fe", [Xe], [Fe])
        along = []
        for j in range(m):
            if j != i:
                h = Hs[j]
                vj = _lie(h, X, Fs)
                aj = _lie(vj, X, Fs)
                along.append(ca.vertcat(h, vj, aj, _lie(aj, X, Fs)))
        probe_s = blocks[i] if m == 1 else ca.vertcat(blocks[i], *along)
        layouts += [(_key("stick", i), fFs, X, probe_s), (_key("ext", i), fFe, Xe, probe_e)]
        ext.append((fFs, fFe, probe_e, Xe))
    dt = ca.SX.sym("dt")
    steps = {}
    probe_field = {}
    for key, f, Y, pr in layouts:
        probe_field[key] = ca.Function(f"probe_field_{key}", [Y], [ca.vertcat(pr, f(Y))])
        if key == "free" and not free_flight:
            continue
        Yn, err, err3 = rk_step(f, Y, dt, method)
        fields = f(Yn)
        prn = ca.substitute([pr], [Y], [Yn])[0]
        # the step's Jacobian and its error estimates' (the error of the variational
        # equations integrated by the step, ``d err / dY @ J``: :mod:`.step_error`)
        JE = ca.jacobian(ca.vertcat(Yn, err, err3) if method == "dop853"
                         else ca.vertcat(Yn, err), Y)
        # one flat output per call (a single DM -> numpy conversion): Yn, err, err3, probe,
        # field, vec(J), vec(d (err[, err3]) / dY) (column-major); split by
        # Simulator._step. The third Function is the
        # probe alone (the event iterations of Simulator._refine need nothing else; 15 % fewer
        # instructions than the whole step). Common-subexpression elimination (``cse``) would
        # save another 5-13 %, but it costs 0.3 s per build, as much as it saves in the
        # 204-point continuation of benchmarks/bench_chatter.py
        steps[key] = (
            ca.Function(f"step_{key}", [Y, dt], [ca.vertcat(Yn, err, err3, prn, fields)]),
            ca.Function(f"stepJ_{key}", [Y, dt],
                        [ca.vertcat(Yn, err, err3, prn, fields,
                                    ca.vec(JE[:Y.numel(), :]), ca.vec(JE[Y.numel():, :]))]),
            ca.Function(f"stepP_{key}", [Y, dt], [prn]),
        )
    return fF, steps, probe_field, ext


def _nonsmooth_operations(expr: ca.SX, x: ca.SX, params: list[ca.SX]) -> list[str]:
    """Names of the nonsmooth CasADi operations ``expr`` is built with (empty if none)."""
    names = {"FABS": "fabs", "SIGN": "sign", "FLOOR": "floor", "CEIL": "ceil", "FMIN": "fmin",
             "FMAX": "fmax", "IF_ELSE_ZERO": "if_else", "LT": "a comparison",
             "LE": "a comparison", "EQ": "a comparison", "NE": "a comparison",
             "NOT": "a logical operation", "AND": "a logical operation",
             "OR": "a logical operation", "FMOD": "fmod", "COPYSIGN": "copysign",
             "REMAINDER": "remainder"}
    ops = {getattr(ca, f"OP_{k}"): v for k, v in names.items() if hasattr(ca, f"OP_{k}")}
    f = ca.Function("H", [x, *params], [expr])
    found = {ops[f.instruction_id(k)] for k in range(f.n_instructions())
             if f.instruction_id(k) in ops}
    return sorted(found)


@dataclass(frozen=True)
class SurfaceFunctions:
    """The compiled Functions of one impact surface ``H_i`` (its jump ``W_i``): the derived
    quantities of the module docstring (eqs. 2-12, 24, 30-31) for that surface, the fields
    ``F'_i`` (sticking on it, eq. 10) and the extended field of a chattering flight on it
    (eq. 44), and the keys of its steps in :attr:`CompiledHybrid.steps`."""

    name: str
    index: int
    stick_key: str
    ext_key: str
    fs: ca.Function
    fe: ca.Function
    probe_e: ca.Function
    #: rows: the gradients of ``H_i``, ``v_i``, ``a_i``
    grads: ca.Function
    #: ``H, v, a, r, lambda, L_W H`` of this surface
    quantities: ca.Function
    impact: ca.Function
    vgrad: ca.Function
    #: ``W_i(x)`` of the impact law ``R = x + W_i v_i`` (eq. 5)
    jump: ca.Function
    chatter: ca.Function
    project: ca.Function


@dataclass(frozen=True)
class SurfaceCalls:
    """The Functions of one :class:`SurfaceFunctions` the simulator evaluates, buffered."""

    fs: BufferedFunction
    fe: BufferedFunction
    probe_e: BufferedFunction
    grads: BufferedFunction
    quantities: BufferedFunction
    impact: BufferedFunction
    vgrad: BufferedFunction
    chatter: BufferedFunction
    project: BufferedFunction


#: the Functions of a surface the simulator calls through buffers (:class:`SurfaceCalls`)
_BUFFERED = ("fs", "fe", "probe_e", "grads", "quantities", "impact", "vgrad", "chatter",
             "project")


@dataclass(frozen=True)
class HybridCalls:
    """The simulator's Functions of a :class:`CompiledHybrid` as
    :class:`~nsm_continuation.core.casadi_buffers.BufferedFunction` (numpy in, numpy out)."""

    f: BufferedFunction
    probe: BufferedFunction
    surfaces: tuple[SurfaceCalls, ...]
    #: per field (free, stick, ext, ...): the step, the step with its Jacobian, the probe after it
    steps: dict[str, tuple[BufferedFunction, BufferedFunction, BufferedFunction]]
    #: per field: the probe and the field at a state, in one vector
    probe_field: dict[str, BufferedFunction]


@dataclass
class CompiledHybrid:
    """Compiled CasADi Functions of a :class:`HybridSystem` at fixed parameter values.

    ``X`` = state followed by the ``free`` parameters (dimension ``N = n + len(free)``);
    ``probe`` = the blocks ``(H_i, v_i, a_i, jerk_i)`` of every surface; ``surfaces[i]`` the
    Functions of surface ``i`` (:class:`SurfaceFunctions`); ``fs``, ``grads``, ``impact``, ...
    are the first surface's (the only one of a one-surface system).
    """

    system: HybridSystem
    n: int
    N: int
    free: list[str]
    method: str
    order: int
    f: ca.Function
    probe: ca.Function
    surfaces: list[SurfaceFunctions]
    steps: dict[str, tuple[ca.Function, ca.Function, ca.Function]]
    #: per field (free, stick, ext, ...): ``vertcat(probe, field)`` at a state
    probe_field: dict[str, ca.Function] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)
    #: the free flight that runs: ``exact`` (:mod:`.linear_flow`) or the Runge-Kutta tableau
    flow: str = ""
    #: why ``method: auto`` runs Runge-Kutta (the exact flow does not apply, or does not pay)
    flow_note: str = ""
    #: the closed-form flow of the free flight (:class:`.linear_flow.ModalFlow`), if it runs
    modal: linear_flow.ModalFlow | None = None
    _calls: HybridCalls | None = field(default=None, init=False, repr=False, compare=False)
    #: parameter sets at which a mass matrix independent of ``q`` passed :meth:`mass_check`
    _mass_checked: set[tuple[float, ...]] = field(default_factory=set, init=False, repr=False,
                                                  compare=False)

    # the first surface's Functions (the only surface of a one-surface system)
    @property
    def fs(self) -> ca.Function:
        return self.surfaces[0].fs

    @property
    def fe(self) -> ca.Function:
        return self.surfaces[0].fe

    @property
    def probe_e(self) -> ca.Function:
        return self.surfaces[0].probe_e

    @property
    def grads(self) -> ca.Function:
        return self.surfaces[0].grads

    @property
    def impact(self) -> ca.Function:
        return self.surfaces[0].impact

    @property
    def jump(self) -> ca.Function:
        return self.surfaces[0].jump

    @property
    def chatter(self) -> ca.Function:
        return self.surfaces[0].chatter

    @property
    def m(self) -> int:
        """Number of impact surfaces."""
        return len(self.surfaces)

    def calls(self) -> HybridCalls:
        """The Functions the simulator evaluates, called through their buffers (built once):
        the same values as calling them, without the ``DM`` conversions."""
        if self._calls is None:
            self._calls = HybridCalls(
                f=BufferedFunction(self.f), probe=BufferedFunction(self.probe),
                surfaces=tuple(SurfaceCalls(**{
                    k: BufferedFunction(getattr(sf, k)) for k in _BUFFERED})
                    for sf in self.surfaces),
                steps={k: tuple(BufferedFunction(f) for f in fs)  # type: ignore[misc]
                       for k, fs in self.steps.items()},
                probe_field={k: BufferedFunction(f) for k, f in self.probe_field.items()})
            if self.modal is not None:
                self._calls.steps["free"] = linear_flow.exact_steps(  # type: ignore[assignment]
                    self.modal, self._calls.probe_field["free"], self._calls.probe, self.n)
        return self._calls

    def flow_description(self) -> str:
        """The free flight that runs, in words (reports): the exact flow, or the tableau and,
        for ``method: auto`` that chose it, why (the exact flow does not apply, or does not
        pay: :data:`AUTO_MIN_DYNAMIC`)."""
        if self.modal is not None:
            return (f"exact (closed-form modal flow between events; sticking and chattering: "
                    f"{self.method})")
        if self.flow_note:
            return f"{self.method} ({self.flow_note})"
        return self.method

    def surface_values(self, X: np.ndarray) -> np.ndarray:
        """``H_i(X)`` of every surface."""
        return np.asarray(self.calls().probe.flat(X), dtype=float)[0::4][: self.m]

    def q(self, X: np.ndarray, surface: int = 0) -> dict[str, float]:
        """``H, v, a, r, lambda, L_W H`` of ``surface`` at ``X`` as floats."""
        vals = self.calls().surfaces[surface].quantities.flat(X)
        return dict(zip(("H", "v", "a", "r", "lam", "LWH"), vals.tolist(), strict=True))

    def surface_label(self, surface: int) -> str:
        """``the impact surface`` for a one-surface system, ``surface NAME`` otherwise."""
        return "the impact surface" if self.m == 1 else \
            f"surface {self.surfaces[surface].name!r}"

    def validate_at(self, X: np.ndarray, where: str,
                    qv: dict[str, float] | None = None, surface: int = 0) -> None:
        """Check the impact law at a point of ``surface`` (eqs. 6, 9 and sec. 2.4):
        ``0 <= r <= 1`` and ``W`` tangent to the surface (``qv``: :meth:`q` at ``X`` if already
        evaluated). ``r = 1`` (to :data:`ELASTIC_TOL`) is an elastic impact: it needs no
        chatter map (its impacts do not accumulate), and the simulator refuses a chattering
        sequence at it. Raises :class:`HybridDeclarationError`."""
        qv = self.q(X, surface) if qv is None else qv
        at = "" if self.m == 1 else f" on {self.surface_label(surface)}"
        if not np.isfinite(list(qv.values())).all():
            raise HybridDeclarationError(f"{self.system.name}: non-finite H, v, a, r or lambda "
                                         f"{where}{at}: {qv}")
        if not (-1e-12 <= qv["r"] <= 1.0 + ELASTIC_TOL):
            raise HybridDeclarationError(
                f"{self.system.name}: restitution r = {qv['r']:.6g} {where}{at}; the impact "
                "law needs 0 <= r <= 1 (eq. 9, sec. 3: r < 1 for the chatter map, r = 1 "
                "elastic)")
        # W tangent to {H = 0} where v = 0 (sec. 2.4): L_W H must vanish on the surface
        scale = 1.0 + float(np.linalg.norm(self.calls().f.flat(X)))
        if abs(qv["LWH"]) > 1e-9 * scale:
            raise HybridDeclarationError(
                f"{self.system.name}: W is not tangent to {self.surface_label(surface)} "
                f"(L_W H = {qv['LWH']:.3g} {where}); the impact law must keep H = 0 (sec. 2.4)")

    def mass_check(self, X: np.ndarray) -> None:
        """For mechanical systems: ``M(q)`` symmetric positive definite at ``X``."""
        sys = self.system
        values = self.values
        if not hasattr(sys, "_mass"):
            return
        pars = []
        for k in sys.params:
            if k in values:
                pars.append(values[k])
            else:
                pars.append(float(X[self.n + self.free.index(k)]))
        key = None
        if not getattr(sys, "_mass_uses_q", True):
            # M does not depend on q: the check at these parameters holds at every state
            key = tuple(pars)
            if key in self._mass_checked:
                return
        Mq = np.asarray(sys._mass(X[: sys._nq], *pars), dtype=float)
        if not np.allclose(Mq, Mq.T, rtol=1e-12, atol=1e-12):
            raise HybridDeclarationError(f"{sys.name}: mass matrix M(q) is not symmetric")
        try:
            np.linalg.cholesky(Mq)
        except np.linalg.LinAlgError:
            raise HybridDeclarationError(
                f"{sys.name}: mass matrix M(q) is not positive definite at q = "
                f"{X[: sys._nq].tolist()}") from None
        if key is not None:
            self._mass_checked.add(key)
