"""Brute-force bifurcation diagrams of a hybrid system (Nordmark & Piiroinen 2009, sec. 6:
Figs. 8(b), 9(b)-(c) and 10(b) are brute-force diagrams of the double pendulum).

At each value of a grid of one parameter the attractor is simulated return by return on the
problem's Poincaré section (:meth:`~nsm_continuation.hybrid.case.HybridCaseProblem.section`)
with the event-driven simulator and **no sensitivities**: ``transient`` returns are discarded,
then ``record`` returns are recorded. Each value starts from the previous value's final state
(the attractor is followed); the first from the sweep's start state. A
:class:`~nsm_continuation.hybrid.simulate.SimulationError` at a value (e.g. no return to the
section: the system came to rest) is recorded with its reason and the value is restarted from
the problem's default initial state (:meth:`HybridCaseProblem.default_initial`); if that fails
too the value records nothing and the next one starts from the default state again.

No Newton iteration, no monodromy matrix, no prescribed event order: agreement with the shooting
orbits of the continuation is an independent check of it.

The recorded state of a return is the full state on the section (its section coordinate reset
to the section's value) with the angles that turn (``HybridSystem.periodic``) wrapped to
``(-per/2, per/2]``, i.e. ``(-pi, pi]``. As a continuation point
(:func:`recorded_points`, the ``sweep`` algorithm of a
:class:`~nsm_continuation.hybrid.case.HybridCaseProblem`) its unknowns are the section
coordinates and the parameter, the layout of the shooting unknowns, and its derived quantities
those of the simulated return (``period``: the time of that return to the section).

Usage (the pendulum's benchmark, ``benchmarks/brute_force_pendulum.py``, goes through
:mod:`nsm_continuation.problems.impacting.brute_force`)::

    stepper = ReturnMap(problem, "restitution")
    points = sweep(stepper, np.linspace(0.85, 0.92, 71), transient=30, record=30)
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any
from weakref import WeakKeyDictionary

import numpy as np

from nsm_continuation.algorithms.sweep import sweep_point_record
from nsm_continuation.core.capabilities import SweepSeed
from nsm_continuation.core.progress import progress_bar
from nsm_continuation.core.records import Point
from nsm_continuation.hybrid.simulate import SimOptions, SimResult, SimulationError, Simulator

if TYPE_CHECKING:  # pragma: no cover
    from nsm_continuation.hybrid.case import HybridCaseProblem

TWO_PI = 2.0 * np.pi

#: the lines of a sweep with ``progress`` (one a value, level INFO)
logger = logging.getLogger(__name__)


def wrap(q: Any, period: float = TWO_PI) -> Any:
    """Angle(s) ``q`` wrapped to ``(-period/2, period/2]`` (``(-pi, pi]`` by default)."""
    half = 0.5 * period
    return half - np.mod(half - np.asarray(q, dtype=float), period)


@dataclass
class SweepPoint:
    """The recorded attractor at one parameter value.

    ``section``: the diagram coordinate (``ReturnMap.coordinate``) at every recorded return;
    ``states``: the full recorded states (``(record, n)``); ``state``: the final state (where
    the next value starts). Per recorded return: ``return_times`` (time between consecutive
    section crossings), ``sticking_times`` (total time sticking during that return),
    ``n_sticking`` (sticking intervals), ``n_impacts`` (impacts resolved individually, those
    replaced by the chatter map excluded), ``signatures`` (event sequence,
    :attr:`SimResult.signature`) and ``quantities`` (the problem's derived quantities of the
    return, :meth:`HybridShootingProblem.result_quantities`)."""

    value: float
    section: np.ndarray
    state: np.ndarray | None = None
    states: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    return_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sticking_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_sticking: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    n_impacts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    signatures: list[str] = field(default_factory=list)
    quantities: list[dict[str, float]] = field(default_factory=list)
    #: reasons of the SimulationErrors met at this value (each one triggered a restart)
    failures: list[str] = field(default_factory=list)
    #: started from the default initial state (after a failure here or at the previous value),
    #: not from the previous value's attractor
    restarted: bool = False
    wall: float = 0.0

    @property
    def ok(self) -> bool:
        return self.section.size > 0

    @property
    def all_sticking(self) -> bool:
        """Every recorded return has at least one sticking interval."""
        return self.ok and bool(np.all(self.n_sticking > 0))

    @property
    def any_sticking(self) -> bool:
        return self.ok and bool(np.any(self.n_sticking > 0))

    def period(self, tol: float = 1e-6, max_period: int | None = None) -> int | None:
        """Smallest ``p`` with ``|section[k + p] - section[k]| <= tol`` (circular distance)
        for all recorded ``k``; None if none up to ``max_period`` (default: half the record)."""
        return sequence_period(self.section, tol, max_period)

    def n_distinct(self, tol: float = 1e-6) -> int:
        return n_distinct(self.section, tol)


def _circ(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(wrap(np.asarray(a) - np.asarray(b)))


def sequence_period(q: np.ndarray, tol: float = 1e-6, max_period: int | None = None
                    ) -> int | None:
    """Smallest period of the recorded sequence (None: not periodic within the record)."""
    q = np.asarray(q, dtype=float)
    n = q.size
    if n == 0:
        return None
    top = n // 2 if max_period is None else min(max_period, n - 1)
    for p in range(1, max(top, 1) + 1):
        if p >= n:
            break
        if np.all(_circ(q[p:], q[:-p]) <= tol):
            return p
    return None


def n_distinct(q: np.ndarray, tol: float = 1e-6) -> int:
    """Number of clusters of ``q`` values (gaps larger than ``tol`` split clusters)."""
    q = np.sort(np.asarray(q, dtype=float))
    if q.size == 0:
        return 0
    k = 1 + int(np.sum(np.diff(q) > tol))
    if k > 1 and _circ(q[0], q[-1]) <= tol:   # a cluster straddling +-pi
        k -= 1
    return k


class ReturnMap:
    """Section-to-section simulation of a hybrid problem with one parameter lifted into the
    state (the problem's compiled system for that parameter, compiled once for the sweep),
    without sensitivities. ``coordinate``: the state component of the diagram (default the
    first section coordinate)."""

    def __init__(self, problem: HybridCaseProblem, parameter: str,
                 options: SimOptions | None = None, coordinate: int | None = None) -> None:
        self.problem = problem
        problem.set_parameter(parameter)
        #: the parameter's name as the problem knows it, and as given (progress lines)
        self.param, self.label = problem.parameter, parameter
        self.c = problem.shooting.c
        opts = options if options is not None else problem.integrator.options(
            sensitivities=False)
        self.sim = Simulator(self.c, replace(opts, sensitivities=False, record=False))
        sec = problem.section()
        self.index, self.value, self.shift = sec.index, sec.value, sec.shift
        self.direction = sec.direction
        self.n = self.c.n
        self.free_idx = [i for i in range(self.n) if i != self.index]
        self.periodic = {k: p for k, p in problem.hybrid.periodic.items()
                         if k != self.index and p}
        self.coordinate = self.free_idx[0] if coordinate is None else coordinate

    def default_state(self, value: float) -> np.ndarray:
        """The problem's default initial state at ``value`` (it may depend on the parameter,
        e.g. the pendulum's torque), the parameter appended."""
        values = self.problem.values
        old = values[self.param]
        values[self.param] = value
        try:
            X0 = np.asarray(self.problem.default_initial(), dtype=float)
        finally:
            values[self.param] = old
        return np.append(X0, [value])

    def to_section(self, X: np.ndarray) -> np.ndarray:
        """``X`` itself if it lies on the section, else the state at its first crossing
        (:meth:`HybridCaseProblem.transient` with no return)."""
        if abs(X[self.index] - self.value) <= 1e-12:
            return X
        return self.problem.transient(X, 0)

    def one_return(self, X: np.ndarray, max_time: float | None = None
                   ) -> tuple[np.ndarray, SimResult]:
        """From ``X`` on the section to the next crossing; the section coordinate is reset to
        the section's value and the periodic ones wrapped, so the state stays bounded. No
        crossing within ``max_time`` (e.g. a pendulum come to rest) is a
        :class:`SimulationError`."""
        res = self.sim.run(X, section=(self.index, self.value + self.shift, self.direction),
                           max_time=max_time)
        if res.ended_by != "section":
            q = self.problem.hybrid.state_names
            rest = ", ".join(f"{q[k]} = {res.X[k]:.6g}" for k in range(self.n))
            raise SimulationError(f"no return to the section within t = {res.t:.6g} (the "
                                  f"system came to rest? {rest})")
        Xn = res.X.copy()
        Xn[self.index] = self.value
        for k, per in self.periodic.items():
            Xn[k] = wrap(Xn[k], per)
        return Xn, res


def _repeats(history: list[np.ndarray], tol: float, max_period: int,
             periodic: dict[int, float]) -> int | None:
    """Smallest ``p <= max_period`` with the last state equal to the one ``p`` returns
    earlier (periodic components compared modulo their period), or None."""
    x = history[-1]
    for p in range(1, min(max_period, len(history) - 1) + 1):
        d = history[-1 - p] - x
        for k, per in periodic.items():
            d[k] = wrap(d[k], per)
        if np.max(np.abs(d)) <= tol * (1.0 + np.max(np.abs(x))):
            return p
    return None


def attractor(stepper: ReturnMap, value: float, X: np.ndarray | None, transient: int,
              record: int, converge_tol: float | None = None, max_period: int = 8,
              max_time: float | None = 1000.0, first: bool = True
              ) -> tuple[SweepPoint, np.ndarray | None]:
    """The attractor at ``value`` from the state ``X`` (parameter appended; None: the default
    initial state): ``transient`` returns, then ``record`` recorded ones. A
    :class:`SimulationError` restarts the value once from the default initial state (the
    reason is kept in ``failures``). ``converge_tol``: the transient ends early once the
    state on the section repeats (period ``p <= max_period``) to this relative tolerance, and
    only ``max(4 p, 8)`` returns (at most ``record``) are recorded. ``first``: the first value
    of a sweep (starting from the default state there is no restart). Returns the point and the
    state the next value starts from (None after two failures)."""
    t0 = time.perf_counter()
    pt = SweepPoint(value, np.zeros(0))
    attempts = [X, None] if X is not None else [None]
    for start in attempts:
        if start is None:
            start = stepper.to_section(stepper.default_state(value))
            pt.restarted = not first or bool(pt.failures)
        Xc = start.copy()
        Xc[-1] = value
        rec: list[tuple[np.ndarray, SimResult]] = []
        n_rec = record
        try:
            hist = [Xc[:stepper.n].copy()]
            for _ in range(transient):
                Xc, _res = stepper.one_return(Xc, max_time)
                if converge_tol is not None:
                    hist.append(Xc[:stepper.n].copy())
                    p = _repeats(hist, converge_tol, max_period, stepper.periodic)
                    if p is not None:
                        n_rec = min(record, max(4 * p, 8))
                        break
            for _ in range(n_rec):
                Xc, res = stepper.one_return(Xc, max_time)
                rec.append((Xc[:stepper.n].copy(), res))
        except SimulationError as exc:
            pt.failures.append(exc.reason)
            X = None
            continue
        pt.states = np.array([s for s, _ in rec]).reshape(len(rec), stepper.n)
        pt.section = pt.states[:, stepper.coordinate].copy()
        pt.return_times = np.array([r.t for _, r in rec])
        pt.sticking_times = np.array([r.sticking_time for _, r in rec])
        pt.n_sticking = np.array([r.n_sticking_phases for _, r in rec], dtype=int)
        pt.n_impacts = np.array([r.n_impacts for _, r in rec], dtype=int)
        pt.signatures = [r.signature for _, r in rec]
        pt.quantities = [stepper.problem.result_quantities(r, value) for _, r in rec]
        pt.state = Xc[:stepper.n].copy()
        X = Xc
        break
    pt.wall = time.perf_counter() - t0
    return pt, X


def _summary(label: str, value: float, pt: SweepPoint) -> str:
    """One line on the attractor at ``value``: returns, period, sticking, return time, wall
    time, failures."""
    per = pt.period()
    sticking = "all" if pt.all_sticking else ("some" if pt.any_sticking else "none")
    return (f"{label} = {value:.7g}: {pt.section.size} returns, period "
            f"{per if per is not None else '-'}, sticking {sticking}, T_return "
            f"{np.mean(pt.return_times) if pt.ok else np.nan:.4f}, {pt.wall:.2f} s"
            + (f", FAILED: {pt.failures}" if pt.failures else ""))


def sweep(stepper: ReturnMap, values: Any, transient: int = 30, record: int = 30,
          initial: np.ndarray | None = None, converge_tol: float | None = None,
          max_period: int = 8, max_time: float | None = 1000.0,
          progress: bool = False) -> list[SweepPoint]:
    """The brute-force diagram over ``values``, in order, each value from the previous one's
    final state (:func:`attractor`). ``initial``: the state on the section (without the
    parameter) the first value starts from (default: the problem's default initial state).
    ``progress``: a progress bar (:func:`~nsm_continuation.core.progress.progress_bar`, one
    tick a value) and one line a value on the logger ``nsm_continuation.hybrid.brute_force``
    (level INFO: shown with ``logging.basicConfig(level=logging.INFO)``)."""
    values = [float(v) for v in np.atleast_1d(values)]
    X: np.ndarray | None = None
    if initial is not None:
        X = np.append(np.asarray(initial, dtype=float)[:stepper.n], [values[0]])
    out: list[SweepPoint] = []
    bar = progress_bar(f"brute force {stepper.label}", len(values), "value") \
        if progress else None
    for i, val in enumerate(values):
        pt, X = attractor(stepper, val, X, transient, record, converge_tol, max_period,
                          max_time, first=i == 0)
        if bar is not None:
            logger.info("%s", _summary(stepper.label, val, pt))
            bar.update(1)
        out.append(pt)
    if bar is not None:
        bar.close()
    return out


# ------------------------------------------------------------------ the sweep algorithm
def sweep_seeds(problem: HybridCaseProblem, specs: list[Any]) -> list[SweepSeed]:
    """One sweep per start of the ``start:`` block (:class:`HybridStartSpec`), from the value
    ``parameters.<name>`` of the swept parameter (``SweepSeed.origin``) in the start's
    ``direction``: its state on the section from ``guess``, else the full state ``initial``
    brought to the section, else None (the default initial state at the first value)."""
    name = problem.parameter
    p0 = problem.values[name]
    stepper = ReturnMap(problem, name)
    names = problem.hybrid.state_names
    coords = [names[i] for i in stepper.free_idx]
    seeds = []
    for s in specs:
        X: np.ndarray | None = None  # the default initial state, at the first value
        how = "default initial state"
        if s.guess is not None:
            X = problem.shooting.x0(np.append([s.guess[n] for n in coords], [p0]))
            how = "guess"
        elif s.initial:
            X = stepper.default_state(p0)
            for k, v in s.initial.items():
                X[names.index(k)] = v
            X = stepper.to_section(X)
            how = "initial"
        d = {"both": 0, "increase": 1, "decrease": -1}[s.direction]
        seeds.append(SweepSeed(s.label or f"brute force from {name} = {p0:g}", X, d,
                               {"start": how, "transient": s.transient, "record": s.record,
                                "coordinate": names[stepper.coordinate]}, origin=p0))
    return seeds


def recorded_points(problem: HybridCaseProblem, pt: SweepPoint, direction: int
                    ) -> list[Point]:
    """The recorded returns of ``pt`` as sweep points: ``y`` the section coordinates and the
    parameter (the shooting unknowns' layout), derived the return's quantities
    (:meth:`HybridShootingProblem.result_quantities`; ``period`` is the time of that return)
    with ``return_index`` (1, 2, ... within the value), ``restarted`` (1: the value started
    from the default initial state) and ``failures`` (simulation failures met at the value);
    no signature (no events inside a brute-force diagram)."""
    fi = [i for i in range(pt.states.shape[1]) if i != problem.shooting.section.index]
    ip = problem.parameter_index
    out = []
    for k, (x, q) in enumerate(zip(pt.states, pt.quantities, strict=True)):
        derived = {**q, "return_index": float(k + 1), "restarted": float(pt.restarted),
                   "failures": float(len(pt.failures))}
        out.append(sweep_point_record(np.append(x[fi], [pt.value]), derived, direction, ip))
    return out


def sweep_point(problem: HybridCaseProblem, seed: SweepSeed, value: float, state: Any
                ) -> tuple[list[Point], Any]:
    """One value of the sweep ``seed`` (:func:`attractor` with the start's ``transient`` and
    ``record``) from ``state`` = ``(X, first)``; the failures are noted in
    ``seed.info['failures']``. A value whose restart fails too gives no point."""
    stepper = _stepper(problem, seed)
    X, first = state if isinstance(state, tuple) else (state, True)
    pt, Xn = attractor(stepper, value, None if X is None else np.asarray(X, dtype=float),
                       int(seed.info["transient"]), int(seed.info["record"]),
                       max_time=problem.integrator.max_return_time, first=first)
    if pt.failures:
        seed.info.setdefault("failures", []).append(
            f"{problem.parameter} = {value:.10g}: " + "; ".join(pt.failures)
            + ("" if pt.ok else " (nothing recorded)"))
    return recorded_points(problem, pt, seed.direction), (Xn, False)


#: the :class:`ReturnMap` of each problem being swept (built once per problem and parameter)
_STEPPERS: WeakKeyDictionary[Any, ReturnMap] = WeakKeyDictionary()


def _stepper(problem: HybridCaseProblem, seed: SweepSeed) -> ReturnMap:
    """The problem's :class:`ReturnMap` for its swept parameter, built once."""
    cached = _STEPPERS.get(problem)
    if cached is None or cached.param != problem.parameter:
        cached = _STEPPERS[problem] = ReturnMap(problem, problem.parameter)
    return cached


__all__ = ["ReturnMap", "SweepPoint", "attractor", "n_distinct", "recorded_points",
           "sequence_period", "sweep", "sweep_point", "sweep_seeds", "wrap"]
