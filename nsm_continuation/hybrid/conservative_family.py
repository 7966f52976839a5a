"""A conservative impacting system whose families of periodic orbits are continued at fixed
physical parameters: the base class of such problems (:class:`ConservativeFamilyProblem`).

A concrete family sets ``name`` and ``Parameters`` (a strict pydantic model with an
``integrator: IntegratorSpec`` field; every other field a parameter of the declaration) and
implements :meth:`~ConservativeFamilyProblem.conservative_system` (the mechanical declaration,
elastic impacts, and its energy), :meth:`~ConservativeFamilyProblem.section` (a
:class:`~.return_map.CrossingSection`) and :meth:`~ConservativeFamilyProblem.start_points`.
The unfolding (eq. U1 of :mod:`.conservative`), the shooting system (U2) in the period, the
frequency or the energy, the check that the unfolding vanishes, the multipliers without the
family's ``+1`` and their Krein signatures, the grazing margin (an event: a near approach that
becomes an impact) and the signature of the impact sequence are generic.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import replace
from typing import Any, ClassVar, Literal

import casadi as ca
import numpy as np
from pydantic import BaseModel, Field, TypeAdapter

from nsm_continuation.core import monitors as monitor
from nsm_continuation.core.floquet import KreinFloquetData, deflate_known_eigenvector
from nsm_continuation.core.floquet.norms import spectral_norm
from nsm_continuation.core.monitors import Monitors
from nsm_continuation.core.preflight import STRICT, as_list, one_or_many, start_key
from nsm_continuation.core.problem import EvaluationError, FloquetData, Problem, StartPoint
from nsm_continuation.core.vocabulary import as_parameters
from nsm_continuation.hybrid.conservative import (
    UNFOLDING,
    UNFOLDING_TOL,
    ConservativeShooting,
    krein_definiteness,
    momentum_jacobian,
    unfold,
)
from nsm_continuation.hybrid.conservative_charts import SectionCharts
from nsm_continuation.hybrid.conservative_presentation import ConservativePresentation
from nsm_continuation.hybrid.problem import HybridShootingProblem
from nsm_continuation.hybrid.return_map import (
    AMBIGUOUS_NOISE,
    CrossingSection,
    ShootingFailure,
    section_return,
)
from nsm_continuation.hybrid.simulate import SimulationError, Simulator
from nsm_continuation.hybrid.specs import IntegratorSpec
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem


class GuessStart(BaseModel):
    """``start: {guess: {...}}``: the section coordinates of a periodic orbit (``beta = 0``);
    ``returns``: crossings of the section per period (default the section's)."""

    model_config = STRICT
    #: the section coordinates of a periodic orbit, by state name
    guess: dict[str, float]
    #: crossings of the section per period (null: the section's)
    returns: int | None = Field(None, ge=1)
    #: the directions to continue in from the start
    direction: Literal["both", "increase", "decrease"] = "both"
    #: a label for the start's branch
    label: str | None = None


#: the largest number of section crossings a start may count in one period
MAX_RETURNS = 64
#: a start orbit whose crossings of the section take a time this far (relative) from its
#: period is not near a periodic orbit of the system (e.g. an orbit of another model that
#: crosses the wall here)
START_CLOSURE = 0.05


class ConservativeFamilyProblem(SectionCharts, HybridShootingProblem):
    """Families of periodic orbits of a conservative impacting system (see the module
    docstring). Unknowns ``(z, beta, s)``: the section coordinates, the unfolding and the
    continued quantity ``s`` (``period``, ``omega`` or ``energy``; :attr:`parameter`)."""

    #: the quantity a case continues when it names none
    case_parameter: ClassVar[str | None] = "period"
    energy_quantity: ClassVar[str | None] = "energy"
    algorithms: ClassVar[tuple[str, ...]] = ("palc",)
    #: fields of ``Parameters`` that set up the computation, not parameters of the system
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator",)
    #: the model, for the report (``summary``): what runs and why a case chooses it
    model: ClassVar[str] = ("hybrid simulation: event-driven shooting on a Poincare section "
                            "with the unfolding beta (Munoz-Almaraz et al. 2003)")
    presentation_class = ConservativePresentation
    #: the starts: a guess on the section (:class:`GuessStart`); a family adds its own kinds
    #: (:meth:`orbit_start`) in its ``start_adapter``
    start_adapter: ClassVar[TypeAdapter | None] = one_or_many(GuessStart)
    monitors: ClassVar[Monitors] = Problem.monitors.with_(
        # a near approach that becomes an impact (or an impact that vanishes): an event,
        # located; no impact law changes there, the branch goes on if it can
        monitor.event_function("grazing_margin", "grazing"),
        monitor.signature("impact_sequence_change"))
    #: multipliers farther than this from the unit circle have Krein definiteness 0 exactly
    #: (off the circle ``omega(conj v, v) = |lambda|^2 omega(conj v, v)``)
    KREIN_OFF_CIRCLE: ClassVar[float] = 1e-6

    def __init__(self, params: BaseModel | dict[str, Any]) -> None:
        params = as_parameters(self.Parameters, params)
        super().__init__(params)
        dumped = params.model_dump()
        self.integrator: IntegratorSpec = params.integrator  # type: ignore[attr-defined]
        self.values = {k: float(v) for k, v in dumped.items() if k not in self.setting_fields}
        system, energy = self.conservative_system()
        try:
            self.hybrid: HybridSystem = unfold(system)
            self.compiled_system = self.hybrid.compile(
                self.values, free=[UNFOLDING], method=self.integrator.method)
        except HybridDeclarationError as exc:
            raise ValueError(f"parameters: {exc}") from None
        fixed = [k for k in self.hybrid.params if k != UNFOLDING]
        X = ca.vertcat(self.hybrid.x, self.hybrid.params[UNFOLDING])
        sub = [self.hybrid.params[k] for k in fixed], [self.values[k] for k in fixed]
        self.energy_function: ca.Function | None = None
        if energy is not None:
            E = ca.substitute([energy], *sub)[0]
            self.energy_function = ca.Function("E", [X], [E, ca.jacobian(E, X)])
        dqp = ca.substitute([momentum_jacobian(self.hybrid)(
            self.hybrid.x, *self.hybrid.params.values())], *sub)[0]
        self._dqp = ca.Function("dqp", [X], [dqp])
        self.shooting: ConservativeShooting  # type: ignore[assignment]
        #: the orbits are this many periods of the family's (a period-doubled family: 2)
        self.multiple = 1
        self.set_parameter(self.case_parameter or "period")

    # -- to implement -----------------------------------------------------------------------
    @abstractmethod
    def conservative_system(self) -> tuple[HybridSystem, ca.SX | None]:
        """The mechanical declaration (elastic impacts, a conservative force, no clock) and its
        energy as an expression of the same symbols (None: not declared; the family is then
        continued in the period or the frequency, without Krein signatures)."""

    @abstractmethod
    def section(self) -> CrossingSection:
        """The Poincaré section, its crossing direction and the returns per period."""

    # -- the continued quantity ------------------------------------------------------------
    @property
    def quantities(self) -> list[str]:
        """The quantities this family can be continued in."""
        return ConservativeShooting.quantities(self.energy_function is not None)

    def set_parameter(self, name: str, returns: int | None = None) -> None:
        """Continue in ``name`` (one of :attr:`quantities`) with ``returns`` crossings of the
        section per period (default the section's)."""
        if name not in self.quantities:
            raise ValueError(f"continuation.parameter: {name!r} is not a quantity of "
                             f"{self.name!r} (one of {self.quantities}): its physical "
                             "parameters are fixed along a conservative family")
        sec = self.current_section()
        if returns is not None:
            sec = replace(sec, returns=int(returns))
        self.shooting = ConservativeShooting(self.compiled_system, sec,
                                             self.integrator.options(), name,
                                             self.energy_function, multiple=self.multiple)
        names = self.hybrid.state_names
        self.parameter = name
        self.variables = [names[i] for i in self.shooting.free_idx] + [UNFOLDING, name]

    @property
    def returns(self) -> int:
        return int(self.shooting.section.returns)

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """Bounds on the continued quantity (a period or a frequency is positive)."""
        if name != self.parameter:
            self.set_parameter(name, self.returns)
        for key, v in (("min", lo), ("max", hi)):
            if name != "energy" and v is not None and not v > 0:
                raise ValueError(f"continuation.{key}: {name} = {v:g} is not positive")
        return lo, hi

    @property
    def swept_parameter(self) -> str:
        return self.parameter

    @property
    def conservative(self) -> bool:
        """Krein signatures apply where the energy (hence the symplectic structure of a
        conservative force) is declared."""
        return self.energy_function is not None

    def monitor_names(self) -> list[str]:
        extremes = [f"{m}_{name}" for name in self.hybrid.state_names for m in ("min", "max")]
        return [*dict.fromkeys([self.parameter, "period", "omega", UNFOLDING, "unfolding",
                                *(["energy"] if self.energy_function is not None else []),
                                "n_impacts", "min_impact_normal_velocity", "grazing_margin",
                                *extremes])]

    # -- the numerics ----------------------------------------------------------------------
    def impacts_per_period(self) -> int | None:
        """The impacts per period of the orbits continued (None: any). Where an orbit has
        another number the branch cannot go on in this family: its impact sequence changes
        there (a near approach grazes the surface and becomes an impact, or an impact grazes
        and vanishes), and the branch ends with that reason."""
        return None

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residual and Jacobian of (U2); :class:`EvaluationError` with the simulator's
        reason, or where the orbit's impacts per period are not the family's
        (:meth:`impacts_per_period`)."""
        y = np.asarray(y, dtype=float)
        try:
            out = self.shooting.residual_jacobian(y)
            res = self.shooting.simulate(y)
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None
        n = res.n_impacts
        k = self.impacts_per_period()
        k = None if k is None else k * self.multiple
        if k is not None and n != k:
            tangent = self.tangency_reason(y, res, n, k)
            if tangent is not None:
                raise EvaluationError(tangent)
            raise EvaluationError(
                f"impact sequence: {n} impacts per period where the family has {k}: a near "
                "approach grazes the surface and becomes an impact (or an impact grazes and "
                f"vanishes), the end of the family of {k}-impact orbits")
        return out

    def unfolding_tolerance(self) -> float:
        """The largest ``|beta| T`` that is zero to the simulated map's accuracy."""
        return UNFOLDING_TOL * (float(self.integrator.rtol) + 10.0 * np.finfo(float).eps)

    def derived(self, y: np.ndarray) -> dict[str, float]:
        """The hybrid derived quantities (:meth:`HybridShootingProblem.derived`) and the
        family's: ``period``, ``omega``, ``energy``, ``beta`` and ``unfolding = |beta| T``
        (and ``section_<coordinate>``, the value of the section the unknowns are on, where the
        section may move: :meth:`impact_section`).
        Raises :class:`EvaluationError` (the branch ends with that reason) where the unfolding
        does not vanish (:meth:`unfolding_tolerance`): the system is not conservative."""
        y = np.asarray(y, dtype=float)
        out = super().derived(y)
        beta = float(y[-2])
        T = float(out.get("period", np.nan))
        out[UNFOLDING] = beta
        out["unfolding"] = abs(beta) * T
        if self.impact_section() is not None:  # where the section state was taken (rechart)
            sec = self.shooting.section
            out[f"section_{self.hybrid.state_names[sec.index]}"] = float(sec.value)
        out["omega"] = 2.0 * np.pi / T if T > 0 else np.nan
        if self.energy_function is not None:
            out["energy"] = self.shooting.energy_gradient(y)[0]
        if np.isfinite(T) and not abs(beta) * T <= self.unfolding_tolerance():
            raise EvaluationError(
                f"unfolding: beta = {beta:.3g} does not vanish (|beta| T = {abs(beta) * T:.3g}"
                f" > {self.unfolding_tolerance():.3g}): the orbit is periodic only because "
                "beta balances a loss or gain of energy, so the system is not conservative "
                "(damping, a restitution below 1 or a non-conservative force)")
        return out

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """The section map's multipliers without the family's ``+1``: ``P_z`` deflated by the
        family direction ``r`` (the ``z`` part of the branch tangent;
        :func:`~nsm_continuation.core.floquet.deflate_known_eigenvector`), ``trivial_error =
        |lambda - 1| + |P_z r - lambda r| / |r|`` (the removal's accuracy) plus the flow's
        check (:meth:`ConservativeShooting.trivial_error`); known to ``noise`` =
        :meth:`ConservativeShooting.monodromy_noise`. With a declared energy, the Krein
        definiteness of each multiplier (:func:`~.conservative.krein_definiteness` of the
        eigenvector of ``P_z`` nearest to it, lifted to the full state)."""
        sh = self.shooting
        m = len(sh.free_idx)
        r = np.asarray(tangent, dtype=float)[:m]
        try:
            P = sh.poincare_jacobian(y)
            noise = sh.monodromy_noise(y)
            flow = sh.trivial_error(y)
        except ShootingFailure:
            return None
        if not np.linalg.norm(r) > 0:
            return None
        B, lam, res = deflate_known_eigenvector(P, r)
        mult = np.linalg.eigvals(B) if B.size else np.empty(0, dtype=complex)
        if noise >= AMBIGUOUS_NOISE and np.any(np.abs(np.abs(mult) - 1.0) <= noise):
            return None
        removal = abs(lam - 1.0) + res
        common = {"trivial_error": float(removal + flow),
                  "matrix_norm": spectral_norm(P), "noise": float(noise)}
        if not self.conservative:
            return FloquetData(np.asarray(mult, dtype=complex), **common)
        X0 = sh.x0(y)

        def source() -> np.ndarray:
            lam_all, V = np.linalg.eig(P)
            pick = np.argmin(np.abs(lam_all[None, :] - np.asarray(mult)[:, None]), axis=1)
            dqp = np.asarray(self._dqp(X0), dtype=float)[:, : sh.c.n]
            kappa = krein_definiteness(sh.lift(V[:, pick]), dqp)
            off = np.abs(np.abs(mult) - 1.0) > self.KREIN_OFF_CIRCLE
            return np.where(off, 0.0, kappa)

        return KreinFloquetData(np.asarray(mult, dtype=complex), krein_source=source,
                                **common)

    # -- what this family does not do ------------------------------------------------------
    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> Any:
        """No passage through a grazing (its normal form, :mod:`.grazing`, works on a
        continuation in a parameter, not along a family)."""
        return None

    def tangent_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray,
                       value_before: float) -> np.ndarray | None:
        return None

    def restart_start(self, y: np.ndarray) -> dict[str, Any]:
        """``{guess: <section coordinates>, returns: k}`` (:class:`GuessStart`)."""
        y = np.asarray(y, dtype=float)
        m = len(self.shooting.free_idx)
        return {"guess": {n: float(v) for n, v in zip(self.variables[:m], y[:m], strict=True)},
                "returns": self.returns}

    def period_multiple(self) -> int:
        """The periods of the family's orbits each orbit makes (2 on a period-doubled
        family)."""
        return self.multiple

    def iterated(self, multiple: int) -> ConservativeFamilyProblem:
        """The same family's orbits of ``multiple`` periods (the period-``2k`` family born at
        a period doubling): ``multiple / period_multiple`` times the crossings of the section
        and the impacts per period; its continued period or frequency is the base period's
        (the doubling's point is a point of both problems)."""
        new = type(self)(self.params)
        new.multiple = int(multiple)
        new.set_parameter(self.parameter, self.returns * int(multiple) // self.multiple)
        if self.moved_section is not None:  # the same chart (a moved section)
            new = new._with_section(replace(self.moved_section, returns=new.returns))
        return new

    # -- starts ------------------------------------------------------------------------------
    def orbit_start(self, spec: Any) -> tuple[np.ndarray, float, str, dict[str, Any]]:
        """A family's own start ``spec`` (not a :class:`GuessStart`): a state on (or near) a
        periodic orbit (the ``n`` state components), its period, a label and what to record.
        Default: none (only guesses)."""
        raise ValueError("start: give a guess of the section coordinates ({guess: {...}})")

    def _starts(self, start: Any) -> list[tuple[int | None, Any]]:
        assert self.start_adapter is not None
        return as_list(self.start_adapter.validate_python(start if start is not None else {}))

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """The start block: a guess names exactly the section coordinates."""
        for i, s in self._starts(start):
            if isinstance(s, GuessStart):
                self._check_guess(i, s)

    def _check_guess(self, i: int | None, s: GuessStart) -> None:
        names = [self.hybrid.state_names[k] for k in self.shooting.free_idx]
        unknown, missing = set(s.guess) - set(names), set(names) - set(s.guess)
        if unknown or missing:
            raise ValueError(f"{start_key(i, 'guess')}: needs exactly {names} "
                             f"(unknown {sorted(unknown)}, missing {sorted(missing)})")

    def _to_section(self, X: np.ndarray, period: float | None) -> tuple[np.ndarray, int]:
        """The first crossing of the section from the state ``X`` (``beta = 0``, no
        sensitivities) and the crossings in one ``period`` from there (None: the section's
        returns)."""
        sh = self.shooting
        sec = sh.section
        sim = Simulator(sh.c, replace(sh.sim.o, sensitivities=False))
        Xs = np.append(np.asarray(X, dtype=float)[: sh.c.n], 0.0)
        Xs = section_return(sim, Xs, sec).X.copy()
        Xs[sec.index] = sec.value
        if period is None:
            return Xs, sec.returns
        X, t, k = Xs.copy(), 0.0, 0
        while k < MAX_RETURNS:
            res = section_return(sim, X, sec)
            X = res.X.copy()
            X[sec.index] = sec.value
            t, k = t + float(res.t), k + 1
            if t >= period - 0.5 * float(res.t):  # the number of crossings nearest the period
                break
        if abs(t - period) > START_CLOSURE * period:
            raise ValueError(f"start: the start orbit does not close: {k} crossings of the "
                             f"section take {t:.6g}, its period is {period:.6g}")
        return Xs, k

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        """The starts: each orbit on the section with ``beta = 0`` and its continued quantity
        (the given frequency or period of a family's start exactly; otherwise that of the
        simulated orbit); the engine corrects it at that value (Newton in ``(z, beta)``)."""
        out, returns = [], set()
        sh = self.shooting
        for i, s in self._starts(start):
            T: float | None = None
            if isinstance(s, GuessStart):
                self._check_guess(i, s)
                X = sh.x0(np.append([s.guess[n] for n in self.variables[: len(sh.free_idx)]],
                                    0.0))
                k, label, info = s.returns or self.section().returns, s.label, {"start": "guess"}
            else:
                Xo, T, label, info = self.orbit_start(s)
                try:
                    X, k = self._to_section(Xo, T)
                except (SimulationError, HybridDeclarationError) as exc:
                    raise ValueError(f"{start_key(i)}: the start orbit does not reach the "
                                     f"section ({exc})") from None
            returns.add(k)
            if len(returns) > 1:
                raise ValueError(f"{start_key(i)}: the starts cross the section {sorted(returns)}"
                                 " times per period: one case per number of crossings")
            self.set_parameter(self.parameter, k)
            sh = self.shooting
            z = X[sh.free_idx]
            y = np.concatenate([z, [0.0, 0.0]])
            try:
                t = float(sh.simulate(y).t)
            except ShootingFailure as exc:
                raise ValueError(f"{start_key(i)}: the start does not return to the section "
                                 f"({exc})") from None
            if T is not None and self.parameter != "energy" and self.multiple == 1:
                y[-1] = T if self.parameter == "period" else 2.0 * np.pi / T  # as given
            else:
                y[-1] = sh.quantity_value(y)
            T = t if T is None else T
            d = {"both": 0, "increase": 1, "decrease": -1}[getattr(s, "direction", "both")]
            out.append(StartPoint(y, label or f"orbit of period {T:.6g}", d,
                                  {**info, "returns": k}))
        return out
