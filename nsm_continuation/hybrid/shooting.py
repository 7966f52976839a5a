"""Periodic orbits of an impacting system on a Poincaré section, as a continuation Problem.

Unknowns ``y = (z, p)``: ``z`` the state on the section ``x_k = c`` without its fixed component
``x_k``, ``p`` the continuation parameter. The residual is ``G(z, p) = P(x0) - x0 - shift``
restricted to the components other than ``k``, where ``P`` is the return map simulated by
:class:`~nsm_continuation.hybrid.simulate.Simulator` (impacts, chatter map, sticking, release:
the event order is *not* prescribed, sec. 1) and ``shift`` is ``delta`` on the section component
(``-2 pi`` for one revolution of the pendulum's upper bar, ``2 pi m`` for ``m`` forcing periods
of a forced system whose phase is the clock ``x_3 = omega t``). Its Jacobian ``[P_z - I, P_p]``
is the saltation-chained monodromy of the simulation, with the parameter lifted into the state:
no finite differences.

The Floquet multipliers are the eigenvalues of ``P_z`` (the trivial multiplier of an autonomous
orbit is removed by the section); the free accuracy check is the time-fixed monodromy
``Phi_T = P_x - F J_t`` mapping the flow direction to itself (``trivial_error``).
After sticking, ``P_x`` loses rank (``H_x P_x = 0``, ``v_x P_x = 0``, sec. 4.4): such orbits have
zero multipliers, which are exact, not round-off.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from ..preflight import one_or_many
from ..protocol import EvaluationError, FloquetData, Problem
from .grazing import locate_grazing, step_beyond, tangent_beyond
from .presentation import HybridPresentation
from .simulate import SimOptions, SimResult, SimulationError, Simulator
from .system import CompiledHybrid


@dataclass
class Section:
    """Poincaré section ``x[index] = value``; one period moves ``x[index]`` by ``shift``."""

    index: int
    value: float
    shift: float

    @property
    def direction(self) -> int:
        return 1 if self.shift > 0 else -1


class ShootingFailure(Exception):
    pass


def wrap_periodic(values: np.ndarray, indices: list[int], periodic: dict[int, float]
                  ) -> np.ndarray:
    """``values[j]`` (state component ``indices[j]``) wrapped to ``[-per/2, per/2)`` for the
    periodic components (angles that may turn); others unchanged."""
    out = np.array(values, dtype=float)
    for j, k in enumerate(indices):
        per = periodic.get(k)
        if per:
            out[j] = (out[j] + 0.5 * per) % per - 0.5 * per
    return out


class HybridShooting:
    """Return map, residual and Jacobian of a compiled hybrid system on a section (cached)."""

    def __init__(self, c: CompiledHybrid, section: Section, opts: SimOptions,
                 cache_size: int = 16) -> None:
        self.c = c
        self.section = section
        self.sim = Simulator(c, opts)
        self.free_idx = [i for i in range(c.n) if i != section.index]
        self._cache: OrderedDict[bytes, SimResult | str] = OrderedDict()
        self.cache_size = cache_size
        self.n_simulations = 0

    def x0(self, y: np.ndarray) -> np.ndarray:
        """Full initial state (with the freed parameters) from the unknowns ``y``."""
        c = self.c
        X = np.empty(c.N)
        X[self.free_idx] = y[: c.n - 1]
        X[self.section.index] = self.section.value
        X[c.n:] = y[c.n - 1:]
        return X

    def simulate(self, y: np.ndarray) -> SimResult:
        key = np.asarray(y, dtype=float).tobytes()
        hit = self._cache.get(key)
        if hit is None:
            s = self.section
            try:
                hit = self.sim.run(self.x0(y), section=(s.index, s.value + s.shift,
                                                          s.direction))
            except SimulationError as exc:
                hit = exc.reason
            except HybridDeclarationError as exc:  # e.g. r >= 1 at an impact (e past 1)
                hit = str(exc)
            self.n_simulations += 1
            self._cache[key] = hit
            if len(self._cache) > self.cache_size:
                self._cache.popitem(last=False)
        if isinstance(hit, str):
            raise ShootingFailure(hit)
        return hit

    def residual_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c = self.c
        res = self.simulate(y)
        fi = self.free_idx
        g = res.X[fi] - self.x0(y)[fi]
        # angles that may turn (the pendulum's lower bar): periodicity modulo their period
        g = wrap_periodic(g, fi, self.c.system.periodic)
        cols = fi + list(range(c.n, c.N))
        Jm = res.J[np.ix_(fi, cols)].copy()
        Jm[:, : len(fi)] -= np.eye(len(fi))
        return g, Jm

    def poincare_jacobian(self, y: np.ndarray) -> np.ndarray:
        res = self.simulate(y)
        fi = self.free_idx
        return res.J[np.ix_(fi, fi)]

    def trivial_error(self, y: np.ndarray) -> float:
        """``|Phi_T F(x0) - F(x_T)| / |F|`` with ``Phi_T = P_x - F(x_T) J_t``."""
        c = self.c
        res = self.simulate(y)
        X0 = self.x0(y)
        n = c.n
        F0 = np.asarray(c.f(X0), dtype=float).ravel()[:n]
        FT = np.asarray(c.f(res.X), dtype=float).ravel()[:n]
        Phi = res.J[:n, :n] - np.outer(FT, res.Jt[:n])
        return float(np.linalg.norm(Phi @ F0 - FT) / max(np.linalg.norm(F0), 1e-300))


class HybridShootingProblem(HybridPresentation, Problem):
    """Base class of shooting problems on a hybrid system (the concrete problem builds
    ``self.shooting`` in ``__init__`` and sets ``variables`` / ``parameter``).

    Hooks: ``derived`` (period, sticking time, impacts before the chatter map, ...), the
    admissibility tests (the sticking time ``tau`` for orbits with sticking: its zero is the
    transition to incomplete chattering, reported as ``sticking_lost``), and the event signature
    (a change is ``impact_sequence_change``).
    """

    shooting: HybridShooting
    event_kinds: ClassVar[dict[str, str]] = {
        "sticking_lost": "the sticking time tends to zero: complete chattering turns into "
                         "incomplete chattering (the branch of orbits with sticking ends; "
                         "located where the sticking time reaches its floor, extrapolated to "
                         "zero)",
        "impact_sequence_change": "the sequence of events over one period changes (an impact "
                                  "is gained or lost, or the number of impacts resolved before "
                                  "the chatter map changes)",
        "homoclinic_approach": "the period grows without bound: the orbit approaches a "
                               "homoclinic orbit of a saddle (limit parameter from a fit "
                               "T ~ -ln|p - p*|/mu)",
    }
    #: the sticking time (an admissibility test of orbits with sticking) vanishes where
    #: complete chattering is lost
    test_kinds: ClassVar[dict[str, str]] = {"sticking_time": "sticking_lost"}
    #: the signed grazing margin closest to zero (``SimResult.grazing_function``): a near
    #: approach that becomes an impact, or an impact that vanishes
    event_function_kinds: ClassVar[dict[str, str]] = {"grazing_margin": "grazing"}
    signature_kind: ClassVar[str | None] = "impact_sequence_change"
    #: a bound on the period ends the branch near a homoclinic orbit, one on the sticking time
    #: where sticking is lost
    bound_kinds: ClassVar[dict[str, str]] = {"period": "homoclinic_approach",
                                             "sticking_time": "sticking_lost"}
    def residual(self, y: Any) -> Any:  # pragma: no cover - numeric problem
        raise NotImplementedError("hybrid shooting problems evaluate numerically")

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[0]

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[1]

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian from one (cached) simulation. A simulation that fails raises
        :class:`~nsm_continuation.protocol.EvaluationError` with the simulator's reason (e.g.
        ``simulation: time limit: ...``): the engine retries the step smaller and, if the branch
        has to end, records that reason, not a NaN residual."""
        try:
            return self.shooting.residual_jacobian(np.asarray(y, dtype=float))
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None

    @property
    def compiled(self) -> Any:  # the engine touches ``problem.compiled`` once: nothing to build
        return None

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        try:
            P = self.shooting.poincare_jacobian(y)
            triv = self.shooting.trivial_error(y)
        except ShootingFailure:
            return None
        mult = np.linalg.eigvals(P)
        return FloquetData(multipliers=mult, trivial_error=triv,
                           matrix_norm=float(np.linalg.norm(P, 2)))

    def sim(self, y: np.ndarray) -> SimResult | None:
        try:
            return self.shooting.simulate(np.asarray(y, dtype=float))
        except ShootingFailure:
            return None

    def derived(self, y: np.ndarray) -> dict[str, float]:
        res = self.sim(y)
        p = float(y[self.parameter_index])
        if res is None:
            return {self.parameter: p, "period": np.nan, "sticking_time": np.nan,
                    "n_impacts_before_chatter": np.nan}
        out = {
            self.parameter: p,
            "period": float(res.t),
            "sticking_time": res.sticking_time,
            "n_impacts_before_chatter": float(res.n_impacts_before_chatter),
            "n_sticking_phases": float(len(res.sticking_intervals)),
            "n_impacts": float(res.n_impacts),
            "min_impact_velocity": (float(res.min_impact_velocity)
                                    if np.isfinite(res.min_impact_velocity) else np.nan),
            # signed grazing margin: min H of the near approaches (> 0) or -v^2/(2a) of a
            # decelerating impact (< 0); crosses zero at a grazing bifurcation
            "grazing_margin": (float(res.grazing_margin) if np.isfinite(res.grazing_margin)
                               else np.nan),
        }
        if res.extremes is not None:
            names = self.shooting.c.system.state_names
            for k, name in enumerate(names):
                out[f"min_{name}"] = float(res.extremes[k, 0])
                out[f"max_{name}"] = float(res.extremes[k, 1])
            out.update(self.response_quantities(out))
        return out

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        """``grazing_margin``: the signed margin (near approach ``H_min > 0``, decelerating
        impact ``-v^2/(2a) < 0``) closest to zero; its zero is a grazing, located on this
        smooth function (the square-root singularity is in ``v``, not in ``v^2``)."""
        res = self.sim(y)
        if res is None:
            return {}
        g = res.grazing_function()
        return {} if not np.isfinite(g) else {"grazing_margin": g}

    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> tuple[np.ndarray, np.ndarray] | None:
        """At a grazing (zero of ``grazing_margin``): the grazing orbit, located on the margin
        by margin-fixed solves from ``y`` (:func:`.grazing.locate_grazing`), and the first
        orbit beyond it from the discontinuity-map normal form (:func:`.grazing.step_beyond`,
        eqs. G1-G2): the impacting orbit born at the grazing, or the free one that follows an
        impact that vanished."""
        if name != "grazing_margin":
            return None
        y = np.asarray(y, dtype=float)
        tangent = np.asarray(tangent, dtype=float)
        yg = locate_grazing(self.shooting, y, tol)
        if yg is None:
            return None
        y1 = step_beyond(self.shooting, yg, tangent, from_impacting=value < 0, ds=ds, tol=tol)
        return None if y1 is None else (yg, y1)

    def tangent_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray,
                       value_before: float) -> np.ndarray | None:
        """The tangent of the branch beyond the grazing point ``y`` (eq. G2), on the side the
        branch did not come from (``value_before`` < 0: it arrived impacting)."""
        if name != "grazing_margin":
            return None
        return tangent_beyond(self.shooting, np.asarray(y, dtype=float),
                              np.asarray(tangent, dtype=float), from_impacting=value_before < 0)

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        res = self.sim(y)
        if res is None:
            return {}
        tests: dict[str, float] = {}
        if res.sticking_intervals:
            tests["sticking_time"] = res.sticking_time
        return tests

    def locate_signature(self, before: str | None, after: str | None) -> bool:
        """Locate (by bisection) only structural changes: an impact gained or lost, a sticking
        phase gained or lost. A change of the number of impacts resolved before the chatter
        map alone depends on the chatter tolerance and is recorded within its step."""
        import re

        def strip(sig: str | None) -> str:
            return re.sub(r"\d+", "", sig or "")

        return strip(before) != strip(after)

    def signature(self, y: np.ndarray) -> str | None:
        res = self.sim(y)
        return None if res is None else res.signature


# ---------------------------------------------------------------------- YAML-facing base class
from abc import abstractmethod  # noqa: E402
from typing import Literal  # noqa: E402

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter  # noqa: E402

from ..protocol import StartPoint  # noqa: E402
from .system import HybridDeclarationError, HybridSystem  # noqa: E402


class IntegratorSpec(BaseModel):
    """``parameters.integrator``: numerics of the hybrid simulator (defaults are the ones the
    speed-accuracy chart in ``benchmarks/bench_chatter.py`` recommends)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    method: Literal["dop853", "dopri5"] = "dop853"
    #: at least 1e-14: below, the step error test asks for less than the round-off of a step
    rtol: float = Field(1e-10, ge=1e-14, lt=1e-2)
    atol: float = Field(1e-12, gt=0, lt=1e-2)
    chatter_tol: float = Field(1e-10, gt=0, lt=1e-2)
    chatter_order: int = Field(3, ge=1, le=4)
    max_chatter_impacts: int = Field(2000, ge=2)
    wall_time: float = Field(30.0, gt=0)
    #: a return to the Poincare section taking longer than this (simulated time) fails
    max_return_time: float = Field(1000.0, gt=0)

    def options(self, sensitivities: bool = True) -> SimOptions:
        return SimOptions(rtol=self.rtol, atol=self.atol, chatter_tol=self.chatter_tol,
                          max_time=self.max_return_time,
                          chatter_order=self.chatter_order,
                          max_chatter_impacts=self.max_chatter_impacts,
                          wall_time=self.wall_time, sensitivities=sensitivities)


class HybridStartSpec(BaseModel):
    """``start:`` of a hybrid shooting case. ``guess`` gives the section coordinates of a
    periodic orbit; without it the orbit is found by simulation from ``initial`` (a full state,
    default: the problem's) over ``transient`` returns to the section (a stable orbit)."""

    #: strict: ``true`` is not a number, ``"3"`` or ``2.0`` not an integer
    model_config = ConfigDict(extra="forbid", strict=True)
    guess: dict[str, float] | None = None
    initial: dict[str, float] | None = None
    transient: int = Field(40, ge=0)
    #: returns to the section per period (2 for a period-2 orbit)
    returns: int = Field(1, ge=1)
    direction: Literal["both", "increase", "decrease"] = "both"
    label: str | None = None


#: one start mapping or a list of them
START_ADAPTER = one_or_many(HybridStartSpec)


class HybridCaseProblem(HybridShootingProblem):
    """A hybrid system with a Poincaré section, continued in any of its parameters.

    A concrete problem sets ``name``, ``Parameters`` (with an ``integrator`` field of type
    :class:`IntegratorSpec`) and implements :meth:`system` (the CasADi declaration),
    :meth:`section` and :meth:`default_initial`. Everything else (residual, Jacobian,
    multipliers, starts, events) is generic.
    """

    start_adapter: ClassVar[TypeAdapter] = START_ADAPTER
    symbolic = "SX"

    def __init__(self, params: BaseModel | dict[str, Any]) -> None:
        if isinstance(params, dict):
            params = self.Parameters.model_validate(params)
        super().__init__(params)
        dumped = params.model_dump()
        self.integrator: IntegratorSpec = params.integrator  # type: ignore[attr-defined]
        self.values = {k: float(v) for k, v in dumped.items()
                       if k not in self.setting_fields}
        self.check_parameters(self.values)
        self.hybrid: HybridSystem = self.system()
        self.returns = 1
        self._compiled_for: str | None = None
        self.set_parameter(self.default_parameter)

    # -- to implement -----------------------------------------------------------------------
    default_parameter: ClassVar[str] = ""
    #: fields of ``Parameters`` that set up the computation (numerics, the section) rather
    #: than the system: not CasADi parameters, and not continued
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator",)

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

    # -- preflight (issue 9) ------------------------------------------------------------------
    #: rough upper costs (s, 2-core machine) of one return to the section without
    #: sensitivities (the transient that finds a start) and of one continuation point per
    #: return of the period (shooting with sensitivities, multipliers, events; the pendulum
    #: takes ~0.2 s per point)
    TRANSIENT_SECONDS_PER_RETURN: ClassVar[float] = 0.05
    SECONDS_PER_POINT: ClassVar[float] = 1.0
    #: cost of the explicit Runge-Kutta integration of a stiff field: about
    #: ``STEPS_PER_STIFFNESS * rho * T`` steps per return (``rho`` the spectral radius of
    #: ``dF/dx``, ``T`` the return time) at ``SECONDS_PER_STEP`` each, and a continuation point
    #: costs about ``RETURNS_PER_POINT`` returns with sensitivities. Measured on the two-mass
    #: chain, k2 = 1e4 and 1e6 (2.2 steps per unit of rho T, 0.75-1.5e-4 s per step).
    #: largest magnitude of a start state's component (|x| beyond it: a Newton step relative to
    #: 1 + |y| no longer resolves the orbit; 1e300 was "converged" with a residual of 44)
    MAX_STATE: ClassVar[float] = 1e12
    STEPS_PER_STIFFNESS: ClassVar[float] = 2.2
    SECONDS_PER_STEP: ClassVar[float] = 1e-4
    RETURNS_PER_POINT: ClassVar[float] = 15.0

    def parameter_domain(self, name: str) -> tuple[float | None, bool, float | None, bool]:
        """``(lo, lo_open, hi, hi_open)``: the bounds the ``Parameters`` model declares for
        ``name`` (None: unbounded on that side; open: the bound itself is excluded)."""
        import annotated_types as at

        lo = hi = None
        lo_open = hi_open = False
        field = type(self.params).model_fields.get(name)
        for m in (field.metadata if field is not None else []):
            if isinstance(m, at.Gt):
                lo, lo_open = float(m.gt), True
            elif isinstance(m, at.Ge):
                lo, lo_open = float(m.ge), False
            elif isinstance(m, at.Lt):
                hi, hi_open = float(m.lt), True
            elif isinstance(m, at.Le):
                hi, hi_open = float(m.le), False
        return lo, lo_open, hi, hi_open

    def _check_window(self, lo: float | None, hi: float | None) -> None:
        """The continuation window of the continued parameter lies inside its domain (the
        ``Parameters`` bounds and :meth:`check_parameters`), and is closed on every side where
        the domain is bounded: a branch leaving the domain (e.g. ``e >= 1``, where the impact
        law has no chatter map) would fail inside the simulator."""
        name = self.parameter
        d_lo, lo_open, d_hi, hi_open = self.parameter_domain(name)
        rng = (f"{'(' if lo_open else '['}{d_lo if d_lo is not None else -np.inf:g}, "
               f"{d_hi if d_hi is not None else np.inf:g}{')' if hi_open else ']'}")
        for side, bound, d, is_open, below in (("max", hi, d_hi, hi_open, True),
                                               ("min", lo, d_lo, lo_open, False)):
            if d is None:
                continue
            if bound is None:
                raise ValueError(
                    f"continuation.{side}: continuing in {name} needs continuation.{side} "
                    f"(parameters.{name} must lie in {rng}; a branch leaving that domain "
                    "cannot be simulated)")
            outside = (bound >= d if is_open else bound > d) if below else \
                (bound <= d if is_open else bound < d)
            if outside:
                raise ValueError(f"continuation.{side}: {name} = {bound:g} is outside the "
                                 f"domain of parameters.{name}, {rng}")
        for side, bound in (("min", lo), ("max", hi)):
            if bound is None:
                continue
            try:
                self.check_parameters({**self.values, name: float(bound)})
            except ValueError as exc:
                raise ValueError(f"continuation.{side}: {name} = {bound:g} leaves the domain "
                                 f"of the parameters ({exc})") from None

    def _check_state(self, key: str, X: np.ndarray) -> None:
        """A start state (with the parameter appended) is finite, on the admissible side of the
        impact surface (``H >= 0``) and, for a mechanical system, has ``M(q)`` positive
        definite."""
        c = self.shooting.c
        if not np.all(np.isfinite(X)):
            raise ValueError(f"{key}: the state is not finite")
        big = float(np.max(np.abs(X[: c.n])))
        if big > self.MAX_STATE:
            raise ValueError(f"{key}: a state component of {big:.3g} is beyond "
                             f"{self.MAX_STATE:g}: the corrector's relative tolerance would "
                             "accept any orbit there; rescale the model")
        H = float(np.asarray(c.probe(X), dtype=float).ravel()[0])
        if H < -1e-12 * (1.0 + float(np.linalg.norm(X))):
            raise ValueError(f"{key}: the state is on the inadmissible side of the impact "
                             f"surface (H = {H:.3g} < 0)")
        try:
            c.mass_check(X)
        except HybridDeclarationError as exc:
            raise ValueError(f"{key}: {exc}") from None

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Everything checkable without simulating (``window``: bounds on the continued
        parameter, already chosen by :meth:`parameter_bounds`):

        * the window lies in the parameter's domain and is closed where the domain is bounded
          (:meth:`_check_window`); the start value ``parameters.<name>`` lies in the window;
        * ``start.guess`` names exactly the section coordinates (and comes without ``initial``
          or ``transient``, which it makes unused); ``start.initial`` names only states;
        * the start state (the guess on the section, or the initial state) is finite,
          admissible (``H >= 0``) and has ``M(q)`` positive definite;
        * time: ``transient x returns`` returns plus ``2 max_points x returns`` points
          (``TRANSIENT_SECONDS_PER_RETURN``, ``SECONDS_PER_POINT``) within the limit.
        """
        from ..preflight import as_list, check_budget

        lo, hi = window
        name = self.parameter
        self._check_window(lo, hi)
        p0 = self.values[name]
        if (lo is not None and p0 < lo) or (hi is not None and p0 > hi):
            raise ValueError(
                f"parameters.{name}: the start value {p0:g} lies outside the continuation "
                f"window [{lo if lo is not None else -np.inf:g}, "
                f"{hi if hi is not None else np.inf:g}] (continuation.min/max): a branch "
                "starting there computes nothing")
        items = as_list(START_ADAPTER.validate_python(start if start is not None else {}))
        names = self.hybrid.state_names
        fi = self.shooting.free_idx
        coords = [names[j] for j in fi]
        sec = self.shooting.section
        seconds = 0.0
        for i, s in items:
            def key(field: str, i: int | None = i) -> str:
                return "start" + ("" if i is None else f"[{i}]") + f".{field}"

            if s.guess is not None:
                unknown = sorted(set(s.guess) - set(coords))
                missing = [n for n in coords if n not in s.guess]
                if unknown or missing:
                    what = (f"unknown state {unknown[0]!r}" if unknown
                            else f"missing {', '.join(missing)}")
                    raise ValueError(
                        f"{key('guess')}: {what}; a guess gives exactly the section coordinates "
                        f"{', '.join(coords)} ({names[sec.index]} = {sec.value:g} is fixed by "
                        "the section)")
                for unused in ("initial", "transient"):
                    if unused in s.model_fields_set:
                        raise ValueError(f"{key(unused)}: not used with start.guess (the guess "
                                         "is corrected directly, nothing is simulated "
                                         "before): remove one of them")
                y = np.append([s.guess[n] for n in coords], [p0])
                self._check_state(key("guess"), self.shooting.x0(y))
            else:
                X = np.append(np.asarray(self.default_initial(), dtype=float), [p0])
                for k, v in (s.initial or {}).items():
                    if k not in names:
                        raise ValueError(f"{key('initial')}: unknown state {k!r} (the states "
                                         f"are {', '.join(names)})")
                    X[names.index(k)] = v
                self._check_state(key("initial") if s.initial else "start", X)
                per_return = max(self.TRANSIENT_SECONDS_PER_RETURN, self._return_seconds(X))
                seconds += s.transient * s.returns * per_return
            per_point = self.RETURNS_PER_POINT * self._return_seconds(
                self.shooting.x0(y) if s.guess is not None else X)
            seconds += 2 * max_points * s.returns * max(self.SECONDS_PER_POINT, per_point)
        check_budget("start" if len(items) == 1 else "start[0]",
                     f"{len(items)} start{'s' if len(items) != 1 else ''} with their transient "
                     f"and continuation.max_points = {max_points}", seconds=seconds)

    def _return_seconds(self, X: np.ndarray) -> float:
        """Estimated cost of one return to the section from the full state ``X`` for an explicit
        integrator: ``STEPS_PER_STIFFNESS * rho * T`` steps, with ``rho`` the spectral radius of
        the exact ``dF/dx`` at ``X`` and ``T = |shift| / |F_index(X)|`` the return time of a
        section coordinate moving at its present rate (a clock: exact); 1 when it is at rest."""
        c = self.shooting.c
        Xs = ca.SX.sym("X", c.N)
        field = ca.Function("Fj", [Xs], [c.f(Xs), ca.jacobian(c.f(Xs), Xs)])
        try:
            F, J = (np.asarray(v, dtype=float) for v in field(X))
            rho = float(np.max(np.abs(np.linalg.eigvals(J[: c.n, : c.n]))))
        except (RuntimeError, np.linalg.LinAlgError):
            return 0.0
        sec = self.shooting.section
        rate = abs(float(F.reshape(-1)[sec.index]))
        T = abs(sec.shift) / rate if rate > 1e-12 else 1.0
        if not np.isfinite(rho * T):
            return float("inf")
        return self.SECONDS_PER_STEP * self.STEPS_PER_STIFFNESS * rho * T

    def monitor_names(self) -> list[str]:
        """The keys of :meth:`derived` at a simulated point."""
        extremes = [f"{m}_{name}" for name in self.hybrid.state_names for m in ("min", "max")]
        return [self.parameter, "period", "sticking_time", "n_impacts_before_chatter",
                "n_sticking_phases", "n_impacts", "min_impact_velocity", "grazing_margin",
                *extremes, *(f"amplitude_{c}" for c in self.configuration_names)]

    # -- generic ----------------------------------------------------------------------------
    def set_parameter(self, name: str, returns: int | None = None) -> None:
        if name not in self.values:
            raise ValueError(f"continuation.parameter: {name!r} is not a parameter of "
                             f"{self.name!r} (one of {sorted(self.values)})")
        returns = self.returns if returns is None else returns
        if self._compiled_for == name and returns == self.returns:
            return
        self.parameter = name
        self.returns = returns
        try:
            c = self.hybrid.compile(self.values, free=[name], method=self.integrator.method)
        except HybridDeclarationError as exc:
            raise ValueError(f"parameters: {exc}") from None
        sec = self.section()
        sec = Section(sec.index, sec.value, sec.shift * returns)
        self.shooting = HybridShooting(c, sec, self.integrator.options())
        names = self.hybrid.state_names
        self.variables = [names[i] for i in self.shooting.free_idx] + [name]
        self._compiled_for = name

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        self.set_parameter(name)
        return lo, hi

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
            out.append(StartPoint(y, label, d, {"start": how, "returns": s.returns,
                                                "n_state": c.n}))
        return out

    def summary(self) -> dict[str, Any]:
        sec = self.shooting.section
        return {"parameters": dict(self.values), "integrator": self.integrator.model_dump(),
                "section": {"coordinate": self.hybrid.state_names[sec.index],
                            "value": sec.value, "shift_per_period": sec.shift},
                "unknowns": list(self.variables)}
