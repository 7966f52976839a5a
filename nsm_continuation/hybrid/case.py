"""A hybrid system with a Poincaré section read from YAML: the base class of impacting families.

A concrete family (``problems/impacting/``) subclasses :class:`HybridCaseProblem`, sets
``name`` and ``Parameters`` (with an ``integrator`` field of type :class:`IntegratorSpec`) and
declares the system (:meth:`HybridCaseProblem.system`), the section (:class:`Section` on an
angle or a clock, or :class:`CrossingSection` crossed in a direction) and a default initial
state; the residual, Jacobian, multipliers, events
(:class:`~.problem.HybridShootingProblem`), the preflight (:mod:`.case_preflight`), the
continuation in the period (:mod:`.case_period`), the starts, brute-force sweeps
(:mod:`.brute_force`) and restarts are generic::

    from nsm_continuation.hybrid.case import (CrossingSection, HybridCaseProblem,
                                              IntegratorSpec, Section)
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, TypeAdapter

from nsm_continuation.core.preflight import as_list
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import START_WARNING
from nsm_continuation.core.vocabulary import as_parameters
from nsm_continuation.hybrid import brute_force
from nsm_continuation.hybrid.case_period import PeriodContinuation
from nsm_continuation.hybrid.case_preflight import CasePreflight
from nsm_continuation.hybrid.codim1 import DEFAULT_MARGIN, GrazingCurve
from nsm_continuation.hybrid.presentation import HybridCasePresentation
from nsm_continuation.hybrid.problem import HybridShootingProblem
from nsm_continuation.hybrid.return_map import (
    PERIOD,
    CrossingSection,
    HybridShooting,
    Section,
    ShootingFailure,
    wrap_periodic,
)
from nsm_continuation.hybrid.simulate import SimulationError, Simulator
from nsm_continuation.hybrid.specs import START_ADAPTER, IntegratorSpec
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem

#: a transient has settled on a periodic orbit when its last return to the section and the next
#: one (one more period) differ by at most this, relative to ``1 + |z|`` (in the infinity norm
#: of the section coordinates); beyond, the report warns that Newton started from a transient
#: that had not settled (:meth:`HybridCaseProblem.transient_unsettled`)
SETTLED = 1e-3

__all__ = ["CrossingSection", "HybridCaseProblem", "IntegratorSpec", "Section"]


class HybridCaseProblem(CasePreflight, PeriodContinuation, HybridShootingProblem):
    """A hybrid system with a Poincaré section, continued in any of its parameters.

    A concrete problem sets ``name``, ``Parameters`` (with an ``integrator`` field of type
    :class:`IntegratorSpec`) and implements :meth:`system` (the CasADi declaration),
    :meth:`section` and :meth:`default_initial`. Everything else (residual, Jacobian,
    multipliers, starts, events) is generic.
    """

    presentation_class = HybridCasePresentation

    start_adapter: ClassVar[TypeAdapter] = START_ADAPTER
    symbolic = "SX"
    #: continued (``palc``), or swept into a brute-force bifurcation diagram (``sweep``:
    #: :mod:`~nsm_continuation.hybrid.brute_force`, Figs. 8(b), 9(b)-(c) of the paper)
    algorithms: ClassVar[tuple[str, ...]] = ("palc", "sweep")
    #: recorded returns per value of a brute-force sweep when ``start.record`` is not given
    BRUTE_FORCE_RECORD: ClassVar[int] = 10

    def __init__(self, params: BaseModel | dict[str, Any]) -> None:
        params = as_parameters(self.Parameters, params)
        super().__init__(params)
        dumped = params.model_dump()
        self.integrator: IntegratorSpec = params.integrator  # type: ignore[attr-defined]
        self.values = {k: float(v) for k, v in dumped.items()
                       if k not in self.setting_fields}
        self.check_parameters(self.values)
        self.hybrid: HybridSystem = self.system()
        self.returns = 1
        self._compiled_for: str | None = None
        #: continuing in the period: the parameter that is an unknown (:meth:`_set_period`)
        self.free_parameter: str | None = None
        self.set_parameter(self.default_parameter)

    # -- to implement -----------------------------------------------------------------------
    default_parameter: ClassVar[str] = ""
    #: ``continuation.parameter: period``: the parameter that becomes an unknown when the start
    #: block names none (``start.free_parameter``); None: the start must name it
    period_partner: ClassVar[str | None] = None
    #: fields of ``Parameters`` that set up the computation (numerics, the section) rather
    #: than the system: not CasADi parameters, and not continued
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator",)
    #: parameters :meth:`curve_parameters` puts first (the preferred second parameter of a
    #: grazing curve's ``continue_from_here`` hint): the vocabulary's obstacle position
    #: (``gap``); a family whose obstacle is placed otherwise overrides it (the double
    #: pendulum: its wall distance ``d``)
    curve_preference: ClassVar[tuple[str, ...]] = ("gap",)

    @abstractmethod
    def system(self) -> HybridSystem:
        """The CasADi declaration of the impacting system."""

    @abstractmethod
    def section(self) -> Section:
        """The Poincaré section and the shift of its coordinate per period."""

    @abstractmethod
    def default_initial(self) -> np.ndarray:
        """A state to simulate from when ``start`` gives no guess."""

    def check_parameters(self, values: dict[str, float]) -> None:
        """Physical checks with messages naming the field (override; call super)."""
        e = values.get("restitution")
        if e is not None and not 0.0 <= e < 1.0:
            raise ValueError(f"parameters.restitution: {e} must lie in [0, 1) "
                             "(complete chattering needs r = e < 1, sec. 3)")

    def sweep_seeds(self, start: Any, window: tuple[float | None, float | None]
                    ) -> list[Any]:
        """The brute-force sweeps of the start block
        (:func:`~nsm_continuation.hybrid.brute_force.sweep_seeds`)."""
        items = as_list(START_ADAPTER.validate_python(start if start is not None else {}))
        return brute_force.sweep_seeds(self, [s.model_copy(update={
            "record": s.record or self.BRUTE_FORCE_RECORD}) for _, s in items])

    def sweep_point(self, seed: Any, value: float, state: Any) -> tuple[Any, Any]:
        """The recorded section returns at ``value``
        (:func:`~nsm_continuation.hybrid.brute_force.sweep_point`)."""
        return brute_force.sweep_point(self, seed, value, state)

    def monitor_names(self) -> list[str]:
        """The keys of :meth:`derived` at a simulated point."""
        extremes = [f"{m}_{name}" for name in self.hybrid.state_names for m in ("min", "max")]
        names = [self.parameter, "period", "sticking_time", "n_impacts_before_chatter",
                 "n_sticking_phases", "n_impacts", "min_impact_normal_velocity",
                 "min_impact_dH_dt", "grazing_margin",
                 *extremes, *(f"amplitude_{c}" for c in self.configuration_names)]
        if self.parameter == PERIOD:
            # the free parameter (any parameter may be named by the start block, which is read
            # after the bounds are checked; a bound on one that stays fixed never fires) and the
            # resolution of the period
            names += [k for k in self.values if k not in names] + ["period_uncertainty"]
        return names

    # -- generic ----------------------------------------------------------------------------
    def set_parameter(self, name: str, returns: int | None = None) -> None:
        if name == PERIOD and PERIOD not in self.values:
            self._set_period(self.free_parameter or self.period_partner, returns)
            return
        if name not in self.values:
            also = "" if self.forced else f", or {PERIOD}"
            raise ValueError(f"continuation.parameter: {name!r} is not a parameter of "
                             f"{self.name!r} (one of {sorted(self.values)}{also})")
        returns = self.returns if returns is None else returns
        if self._compiled_for == name and returns == self.returns:
            return
        self.parameter = name
        self.returns = returns
        try:
            c = self.hybrid.compile(self.values, free=[name], method=self.integrator.method)
        except HybridDeclarationError as exc:
            raise ValueError(f"parameters: {exc}") from None
        # a problem moved to another chart (rechart) keeps it when continued in another
        # parameter (a two-parameter curve's base problem, swapped round a turn)
        moved = self.chart() if self._compiled_for is not None else None
        # ``returns`` periods: the coordinate of a section on an angle or a clock moves that
        # many times as far; a crossing section is crossed that many times as often, in its
        # own direction
        sec = self.section().repeated(returns)
        self.shooting = HybridShooting(c, sec, self.integrator.options())
        self.declared_section = sec.value
        if moved is not None:
            self.shooting = self.in_chart(moved).shooting
        names = self.hybrid.state_names
        self.variables = [names[i] for i in self.shooting.free_idx] + [name]
        self._compiled_for = name

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        self.set_parameter(name)
        return lo, hi

    def derived(self, y: np.ndarray) -> dict[str, float]:
        """The hybrid derived quantities; continued in the period, also the free parameter
        (its value at the point) and ``period_uncertainty``
        (:meth:`HybridShooting.period_uncertainty`)."""
        out = super().derived(y)
        if self.parameter == PERIOD and self.free_parameter is not None:
            out[self.free_parameter] = float(np.asarray(y, dtype=float)[-2])
            try:
                out["period_uncertainty"] = self.shooting.period_uncertainty(
                    np.asarray(y, dtype=float))
            except ShootingFailure:
                out["period_uncertainty"] = np.nan
        return out

    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> Any:
        """Through a grazing as :meth:`HybridShootingProblem.continue_beyond`; not when
        continued in the period (the grazing normal form works on ``(z, p)``)."""
        if self.parameter == PERIOD:
            return None
        return super().continue_beyond(name, y, tangent, value, ds, tol)

    def tangent_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray,
                       value_before: float) -> np.ndarray | None:
        if self.parameter == PERIOD:
            return None
        return super().tangent_beyond(name, y, tangent, value_before)

    def transient(self, X: np.ndarray, returns: int) -> np.ndarray:
        """State on the section after ``returns`` section crossings from ``X`` (no
        sensitivities): the orbit a stable periodic orbit is found from."""
        c = self.shooting.c
        sim = Simulator(c, self.integrator.options(sensitivities=False))
        sec = self.section()
        Xc = X.copy()
        if abs(Xc[sec.index] - sec.value) > 1e-12:
            # first reach the section
            target = sec.value
            if sec.shift < 0 and Xc[sec.index] < target:
                target -= abs(sec.shift)
            if sec.shift > 0 and Xc[sec.index] > target:
                target += abs(sec.shift)
            res = sim.run(Xc, section=(sec.index, target, sec.direction))
            Xc = res.X.copy()
            Xc[sec.index] = sec.value
        for _ in range(returns):
            res = sim.run(Xc, section=(sec.index, sec.value + sec.shift, sec.direction))
            Xc = res.X.copy()
            Xc[sec.index] = sec.value
        return Xc

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        if self.parameter == PERIOD:
            return self._period_start_points(start)
        return self._parameter_start_points(start)

    def _parameter_start_points(self, start: Any) -> list[StartPoint]:
        """The starts of a continuation in the parameter :attr:`parameter`: each orbit from
        its guess on the section, or simulated from an initial state over a transient."""
        specs = START_ADAPTER.validate_python(start if start is not None else {})
        specs = specs if isinstance(specs, list) else [specs]
        out = []
        names = self.hybrid.state_names
        for s in specs:
            self.set_parameter(self.parameter, s.returns)
            c = self.shooting.c
            fi = self.shooting.free_idx
            p0 = self.values[self.parameter]
            if s.guess is not None:
                unknown = set(s.guess) - {names[i] for i in fi}
                missing = {names[i] for i in fi} - set(s.guess)
                if unknown or missing:
                    raise ValueError(f"start.guess: needs exactly {[names[i] for i in fi]} "
                                     f"(unknown {sorted(unknown)}, missing {sorted(missing)})")
                z = np.array([s.guess[names[i]] for i in fi])
                how = "guess"
            else:
                X = np.append(self.default_initial(), [p0])
                if s.initial is not None:
                    for k, v in s.initial.items():
                        if k not in names:
                            raise ValueError(f"start.initial: unknown state {k!r} (one of "
                                             f"{names})")
                        X[names.index(k)] = v
                try:
                    Xs = self.transient(X, s.transient * s.returns)
                except (SimulationError, HybridDeclarationError) as exc:
                    raise ValueError(f"start: transient simulation failed ({exc})") from None
                z = wrap_periodic(Xs[fi], fi, self.hybrid.periodic)
                how = f"simulation ({s.transient} periods)"
            y = np.append(z, [p0])
            d = {"both": 0, "increase": 1, "decrease": -1}[s.direction]
            label = s.label or (f"period-{s.returns} orbit" if s.returns > 1 else
                                "period-1 orbit")
            info: dict[str, Any] = {"start": how, "returns": s.returns, "n_state": c.n}
            found = None if s.guess is not None else self.transient_found(y, s.transient)
            if found is not None:  # said if the start fails
                info["found"] = found
            if s.guess is None and s.transient > 0:
                unsettled = self.transient_unsettled(Xs, s.transient, s.returns)
                if unsettled is not None:  # a warning of the report
                    info[START_WARNING] = unsettled
            out.append(StartPoint(y, label, d, info))
        return out

    def transient_unsettled(self, X: np.ndarray, periods: int, returns: int) -> str | None:
        """Whether the transient's end ``X`` (on the section) has settled on a
        period-``returns`` orbit: the distance between it and its next period-return
        ``P^returns(X)`` (the section coordinates, angles wrapped) at most ``SETTLED`` relative
        to ``1 + |z|``. If not, what the report says (the distance, the states); None if it
        has, or if the next return cannot be simulated (the start then says why)."""
        fi = self.shooting.free_idx
        periodic = self.hybrid.periodic
        try:
            Xn = self.transient(X, returns)
        except (SimulationError, HybridDeclarationError):
            return None
        z, zn = X[fi], Xn[fi]
        d = float(np.linalg.norm(wrap_periodic(zn - z, fi, periodic), np.inf))
        scale = 1.0 + float(np.linalg.norm(z, np.inf))
        if d <= SETTLED * scale:
            return None
        names = self.hybrid.state_names
        states = ", ".join(f"{names[k]} {a:.6g} -> {b:.6g}" for k, a, b in zip(
            fi, wrap_periodic(z, fi, periodic), wrap_periodic(zn, fi, periodic), strict=True))
        kind = "period-1" if returns == 1 else f"period-{returns}"
        return (f"the transient ({periods} periods from the initial state) has not settled on a "
                f"{kind} orbit: its last return to the section and the next one differ by "
                f"{d:.3g} ({d / scale:.2g} relative; {states}); Newton started from it")

    def transient_found(self, y: np.ndarray, periods: int) -> str | None:
        """What the transient from ``start.initial`` settled on, where it explains a start
        that fails: an orbit without impacts (it does not touch the impact surface; where the
        free motion is not isolated, e.g. a body that may rest anywhere between two walls,
        its Jacobian is singular). None for an orbit with impacts or sticking, and for a
        system without contact."""
        res = self.sim(y)
        if res is None or res.n_impacts or res.sticking_intervals or not self.hybrid.m:
            return None
        near = (f"; its closest approach leaves H = {res.grazing_margin:.3g}"
                if np.isfinite(res.grazing_margin) else "")
        return (f"the transient ({periods} periods from the initial state) settled on an orbit "
                f"without impacts: it does not touch the impact surface{near}. A free orbit "
                "that is not isolated (e.g. a body that may rest anywhere between two walls) "
                "has a singular Jacobian: start from a guess on an impacting orbit "
                "(start.guess) or from another initial state (start.initial)")

    # -- restart & branch switching (nsm_continuation.cases.restart) -------------------------------
    def period_multiple(self) -> int:
        """The returns to the section per period (``start.returns``)."""
        return int(self.returns)

    def iterated(self, multiple: int) -> HybridCaseProblem:
        """The same system, continued in the same parameter, with ``multiple`` returns to the
        section per period (the ``multiple``-times iterated return map)."""
        new = type(self)(self.params)
        new.set_parameter(self.parameter, multiple)
        return new.in_chart(self.chart())

    def with_parameters(self, values: dict[str, float]) -> HybridCaseProblem:
        """The same system with ``values`` changed, continued in the same parameter (or in the
        period with the same free parameter) with the same number of returns."""
        data = self.params.model_dump()
        for name, value in values.items():
            if name not in self.values:
                raise ValueError(f"{name!r} is not a parameter of {self.name!r} (one of "
                                 f"{sorted(self.values)})")
            data[name] = float(value)
        new = type(self)(self.Parameters.model_validate(data))
        if self.parameter == PERIOD and self.free_parameter is not None:
            new.free_parameter = self.free_parameter
            new._set_period(self.free_parameter, self.returns)
        else:
            new.set_parameter(self.parameter, self.returns)
        return new.in_chart(self.chart())

    def curve_parameters(self) -> list[str]:
        """Every parameter of the system (not the ``setting_fields``): a grazing curve
        (:class:`~nsm_continuation.hybrid.codim1.GrazingCurve`) may free or continue any of
        them; those of ``curve_preference`` first (in its order), then the others in the
        order of ``Parameters``."""
        first = [q for q in self.curve_preference if q in self.values]
        return first + [q for q in self.values if q not in first]

    def curve(self, kind: str, free: str, parameter: str, margin: float | None = None
              ) -> Problem | None:
        """The grazing curve through these orbits by its augmented system (eq. C1,
        :class:`~nsm_continuation.hybrid.codim1.GrazingCurve`): ``free`` solved for,
        ``parameter`` continued, the orbits missing the surface by ``margin`` (default
        :data:`~nsm_continuation.hybrid.codim1.DEFAULT_MARGIN`). None for another kind."""
        if kind != "grazing":
            return None
        return GrazingCurve(self, free, parameter,
                            DEFAULT_MARGIN if margin is None else float(margin))

    def restart_start(self, y: np.ndarray) -> dict[str, Any]:
        """``{guess: <section coordinates of y>, returns: k}`` (and ``free_parameter`` for a
        continuation in the period, whose unknowns end with that parameter and the period)."""
        in_period = self.parameter == PERIOD and self.free_parameter is not None
        n_state = len(self.variables) - (2 if in_period else 1)
        names = list(self.variables[:n_state])
        block: dict[str, Any] = {
            "guess": {n: float(v) for n, v in zip(names, y[:n_state], strict=True)},
            "returns": self.period_multiple()}
        if in_period:
            block["free_parameter"] = self.free_parameter
        return block
