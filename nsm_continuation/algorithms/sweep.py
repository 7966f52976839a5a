"""The ``sweep`` algorithm: no continuation of a solution curve but the solution at each value
of a grid of the parameter, in order, each warm-started from the previous one (a frequency
sweep of a forced response, :class:`SweepProblem`; the recorded returns of a brute-force
bifurcation diagram). The grid is ``continuation.max_points`` values from
``continuation.min`` to ``max``, swept upwards, downwards or both
(``continuation.direction``)."""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.algorithms.base import Algorithm, Window, outside_bound
from nsm_continuation.core.capabilities import SweepSeed
from nsm_continuation.core.palc import HOOK_FAULTS, NUMERICAL_ERRORS, describe_error, describe_fault
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.core.settings import ContinuationSettings


class SweepProblem(Problem):
    """A problem solved at each value of a grid of its parameter (:class:`Sweep`): e.g. the
    steady state of a forced response at each forcing frequency, found by time stepping from
    the steady state at the previous frequency. No residual, no continuation. Implement
    :meth:`sweep_seeds` and :meth:`sweep_point`; a declared signature monitor raises an event
    where the points' ``signature`` changes between two consecutive grid values. (A problem
    with a residual is swept too when it lists ``"sweep"`` in ``algorithms`` and implements
    the two hooks of :class:`~nsm_continuation.core.problem.Problem`.)"""

    algorithms: ClassVar[tuple[str, ...]] = ("sweep",)

    def residual(self, y: Any) -> Any:  # pragma: no cover - never called by the sweep
        raise TypeError(f"problem {self.name!r} is a sweep problem: it has no residual")

    @abstractmethod
    def sweep_seeds(self, start: Any, window: Window) -> list[SweepSeed]:
        """The sweeps of the YAML ``start:`` block (``window``: the parameter's bounds)."""

    @abstractmethod
    def sweep_point(self, seed: SweepSeed, value: float, state: Any) -> tuple[Point, Any]:
        """The solution at the parameter ``value`` of the sweep ``seed``, from ``state`` (the
        seed's at the first value, then what the previous call returned): the point (its
        ``y[parameter_index]`` is ``value``) and the state the next value starts from. Raises
        :class:`~nsm_continuation.core.problem.EvaluationError` (or a numerical error) if the
        solution cannot be computed: the sweep then ends there with that reason."""


def sweep_point_record(y: np.ndarray, derived: dict[str, float], direction: int,
                       parameter_index: int, signature: str | None = None) -> Point:
    """A sweep's :class:`~nsm_continuation.core.records.Point`: no tests, no multipliers; the
    tangent is the unit vector of the parameter in the sweep's direction (read by the report
    to tell before from after); :class:`Sweep` sets ``s``, the distance swept so far."""
    tangent = np.zeros(len(y))
    tangent[parameter_index] = 1.0 if direction >= 0 else -1.0
    return Point(y=np.asarray(y, dtype=float), s=0.0, tangent=tangent, tests={}, multipliers=None,
                 trivial_error=0.0, n_unstable=0, derived=dict(derived),
                 bordered_det=float("nan"), signature=signature)


class Sweep(Algorithm):
    """The solution at each value of a parameter grid, in order (module docstring).

    The grid is ``numpy.linspace(continuation.min, continuation.max, continuation.max_points)``
    of the problem's parameter, reversed for a decreasing sweep (a seed with an ``origin``
    sweeps the grid values on its side of it, from it: :meth:`grid`); each value starts from
    the state the previous one ended in (:meth:`Problem.sweep_point`), which gives one point
    or a list of points (a brute-force diagram's recorded returns: the branch's
    ``info['draw']`` is then ``markers``, and the figures draw its points as dots, not a
    line). Each value is one tick of progress. A sweep ends at the end of the grid, at the
    first value with a point outside a bound on a derived quantity (``continuation.
    max_energy``, ``continuation.bounds``; that value is not kept) or where a value cannot be
    solved (the reason is the branch's termination). Events: ``endpoint`` at both ends, the
    problem's signature monitor at the first point of a new signature.
    """

    name: ClassVar[str] = "sweep"
    takes_start_points: ClassVar[bool] = False
    setup_key: ClassVar[str] = "seeds_s"

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        if "sweep" not in problem.algorithms or not problem.can_sweep():
            raise ValueError(f"the sweep algorithm needs a problem that can be swept ('sweep' "
                             f"in its algorithms, sweep_seeds() and sweep_point()); "
                             f"{problem.name!r} is not one")
        super().__init__(problem, settings)
        self.sweep_problem = problem
        self.n_evaluations = 0

    def grid(self, direction: int, origin: float | None = None) -> np.ndarray:
        """The parameter values of a sweep in ``direction`` (+1 increasing, -1 decreasing);
        with an ``origin`` (:attr:`SweepSeed.origin`), the values on its side of it, preceded
        by ``origin`` itself unless it is one of them (to 1e-9 of the grid step)."""
        lo, hi = self.settings.param_min, self.settings.param_max
        if lo is None or hi is None or not lo < hi:
            raise ValueError("continuation.min: a sweep needs a window min < max of the "
                             "parameter (continuation.min and continuation.max)")
        values = np.linspace(lo, hi, self.settings.max_points)
        values = values if direction > 0 else values[::-1]
        if origin is None:
            return values
        tol = 1e-9 * (hi - lo) / max(self.settings.max_points - 1, 1)
        side = values[(values - origin) * direction > tol]
        return np.concatenate([[origin], side])

    def starts(self, case_start: Any, window: Window) -> list[Any]:
        self.grid(1)  # a window is required: refused here as a failed start
        seeds = []
        both = [1, -1] if self.settings.direction == 0 else [self.settings.direction]
        for seed in self.sweep_problem.sweep_seeds(case_start, window):
            for d in ([seed.direction] if seed.direction else both):
                label = seed.label if seed.direction or len(both) == 1 else \
                    f"{seed.label}, {'increasing' if d > 0 else 'decreasing'}"
                seeds.append(replace(seed, label=label, direction=d, info=dict(seed.info)))
        return seeds

    def seeds_from_points(self, points: list[StartPoint]) -> list[Any]:
        raise ValueError("a sweep problem starts from its start: block only")

    def covered(self, seed: Any, branches: list[Branch]) -> bool:
        return False

    def run_branch(self, seed: SweepSeed, branch_id: int) -> Branch:
        """The sweep ``seed`` over the grid; never raises (a failure ends it with a reason)."""
        seed = replace(seed, info=dict(seed.info))  # what the problem notes is this run's
        points: list[Point] = []
        events: list[Event] = []
        listed: list[bool] = []
        key = "increase" if seed.direction > 0 else "decrease"
        try:
            reason = self._sweep(seed, points, events, listed)
        except NUMERICAL_ERRORS as exc:
            reason = describe_error(exc)
        except HOOK_FAULTS as exc:  # noqa: BLE001 - recorded, never raised
            reason = describe_fault(exc, self.problem.name)
        if points:
            events.insert(0, Event("endpoint", points[0], "sweep start: first grid value",
                                   data={"reason": "first grid value"}))
            events.append(Event("endpoint", points[-1], f"sweep end: {reason}",
                                data={"reason": reason}))
        info = {**seed.info, "algorithm": "sweep", "direction": seed.direction}
        if any(listed):
            info["draw"] = "markers"
        return Branch(branch_id, seed.label, points, events, {key: reason}, info)

    def _sweep(self, seed: SweepSeed, points: list[Point], events: list[Event],
               listed: list[bool]) -> str:
        """Fill ``points`` and ``events`` along the grid (``listed``: whether each value gave
        a list of points); returns the termination reason."""
        pr = self.sweep_problem
        grid = self.grid(seed.direction, seed.origin)
        state = seed.state
        kind = pr.monitors.signature_kind
        for value in grid:
            solved, state = pr.sweep_point(seed, float(value), state)
            self.n_evaluations += 1
            listed.append(isinstance(solved, list))
            new = solved if isinstance(solved, list) else [solved]
            for point in new:
                point.s = abs(float(value) - float(grid[0]))
                bound = outside_bound(point, self.settings)
                if bound is not None:
                    return f"bound: {bound} at {pr.parameter} = {value:.6g} (value not kept)"
            for point in new:
                if kind is not None and points and point.signature != points[-1].signature:
                    before, after = points[-1].signature, point.signature
                    events.append(Event(kind, point, f"{before} -> {after}",
                                        data={"signature_before": before,
                                              "signature_after": after}))
                points.append(point)
            self._tick(1)
        return f"end of the grid ({len(grid)} values of {pr.parameter})"

    def counters(self) -> dict[str, Any]:
        return {"sweep_points_solved": self.n_evaluations}


__all__ = ["Sweep", "SweepProblem", "sweep_point_record"]
