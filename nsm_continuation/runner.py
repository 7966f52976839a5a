"""Run a validated case: build settings, continue every start, collect the results."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .cases import Case, CaseError
from .palc import ContinuationEngine
from .protocol import Problem, StartPoint
from .records import Branch
from .settings import ContinuationSettings


@dataclass
class RunResult:
    case: Case
    problem: Problem
    branches: list[Branch]
    settings: ContinuationSettings
    window: tuple[float | None, float | None]
    timings: dict[str, Any] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)


def settings_from_case(case: Case, problem: Problem) -> tuple[ContinuationSettings,
                                                              tuple[float | None, float | None]]:
    c, a = case.continuation, case.analysis
    lo, hi = problem.parameter_bounds(c.parameter, c.min, c.max)
    derived_bounds = ({problem.energy_quantity: (None, c.max_energy)}
                      if c.max_energy is not None and problem.energy_quantity else {})
    derived_bounds.update({k: (v[0], v[1]) for k, v in c.bounds.items()})
    settings = ContinuationSettings(
        step_initial=c.step.initial, step_min=c.step.min, step_max=c.step.max,
        max_points=c.max_points, newton_tol=c.newton_tol, max_angle=c.max_angle,
        param_min=lo, param_max=hi,
        derived_bounds=derived_bounds,
        unit_circle_tol=a.unit_circle_tol, event_tol=a.event_tol,
        multiplier_event_tol=a.multiplier_event_tol, max_multiplier_step=a.max_multiplier_step,
        stop_on_inadmissible=a.stop_on_inadmissible, detect_bifurcations=a.bifurcations,
        stability_on_phantom=a.stability_on_phantom,
        direction={"both": 0, "increase": 1, "decrease": -1}[c.direction],
    )
    return settings, (lo, hi)


def _covered(start: StartPoint, branches: list[Branch], ip: int) -> bool:
    """Whether a start lies on an already computed branch (within 1e-6 relative)."""
    y0 = np.asarray(start.y)
    p0 = y0[ip]
    for br in branches:
        ys = np.array([p.y for p in br.points]) if br.points else np.empty((0, len(y0)))
        for k in range(len(ys) - 1):
            a, b = ys[k, ip], ys[k + 1, ip]
            if min(a, b) <= p0 <= max(a, b) and a != b:
                lam = (p0 - a) / (b - a)
                yi = (1 - lam) * ys[k] + lam * ys[k + 1]
                if np.linalg.norm(yi - y0) <= 1e-6 * (1 + np.linalg.norm(y0)) + \
                        1e-3 * np.linalg.norm(ys[k + 1] - ys[k]):
                    return True
    return False


class _Progress:
    """Per-point callback of the engines: advances the tqdm bar (if any) and calls ``poll``
    (e.g. the CLI's check for a pending SIGINT/SIGTERM: a signal whose exception was swallowed
    inside a CasADi call is honoured at the next point)."""

    def __init__(self, case: Case, total: int, progress: bool,
                 poll: Callable[[], None] | None) -> None:
        self.bar = None
        if progress:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="pt", leave=False, desc=case.name, disable=None)
        self.poll = poll

    def __call__(self, n: int) -> None:
        if self.bar is not None:
            self.bar.update(n)
        if self.poll is not None:
            self.poll()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _failed_start(case: Case, problem: Problem, settings: ContinuationSettings,
                  window: tuple[float | None, float | None], exc: Exception,
                  t0: float) -> RunResult:
    """The start block passed the preflight but its starts could not be built (e.g. the
    transient simulation that finds a hybrid orbit failed): one failed branch records why."""
    msg = str(exc).removeprefix("start: ")
    failed = Branch(0, "start", [], [], {"start": f"no start point: {msg}"})
    return RunResult(case, problem, [failed], settings, window,
                     {"total_s": time.perf_counter() - t0, "n_points": 0, "per_branch_s": []})


def run_case(case: Case, problem: Problem, progress: bool = True,
             starts: list[StartPoint] | None = None,
             poll: Callable[[], None] | None = None) -> RunResult:
    """Continue every start of ``case`` (or the given ``starts``: explicit start points of a
    curve problem, e.g. from the Python API) and collect the branches. ``poll`` is called after
    every point (it may raise to stop the run)."""
    settings, window = settings_from_case(case, problem)
    if getattr(problem, "lattice", False):
        if starts is not None:
            raise CaseError("start: a lattice problem starts from its start: block only")
        return run_lattice_case(case, problem, settings, window, progress, poll)
    if case.analysis.stability is False:
        problem.floquet = lambda y, t: None  # type: ignore[method-assign]
    t0 = time.perf_counter()
    if starts is None:
        try:
            starts = problem.start_points(case.start, window)
        except ValueError as exc:
            return _failed_start(case, problem, settings, window, exc, t0)
    _ = problem.compiled  # build CasADi functions once
    t_build = time.perf_counter() - t0
    bar = _Progress(case, len(starts) * settings.max_points, progress, poll)
    engine = ContinuationEngine(problem, settings, progress=bar)
    branches: list[Branch] = []
    skipped: list[str] = []
    per_branch = []
    for start in starts:
        if start.info.get("skip_if_covered") and _covered(start, branches, problem.parameter_index):
            skipped.append(start.label)
            continue
        tb = time.perf_counter()
        br = engine.run(start, branch_id=len(branches))
        per_branch.append(time.perf_counter() - tb)
        branches.append(br)
    bar.close()
    total = time.perf_counter() - t0
    timings = {"total_s": total, "build_casadi_s": t_build, "per_branch_s": per_branch,
               "n_points": int(sum(b.n_points for b in branches)),
               "residual_evaluations": engine.n_evaluations,
               "steps_taken_despite_multiplier_motion": engine.motion_limited_steps,
               "events_not_located_on_their_arc": engine.unlocated_events}
    return RunResult(case, problem, branches, settings, window, timings, skipped)


def run_lattice_case(case: Case, problem: Problem, settings: ContinuationSettings,
                     window: tuple[float | None, float | None], progress: bool,
                     poll: Callable[[], None] | None = None) -> RunResult:
    """Same contract as :func:`run_case` for a :class:`~nsm_continuation.lattice.LatticeProblem`."""
    from .lattice import LatticeContinuation, LatticeProblem

    assert isinstance(problem, LatticeProblem)
    t0 = time.perf_counter()
    if hasattr(problem, "energy_cap"):
        problem.energy_cap = case.continuation.max_energy
    try:
        seeds = problem.lattice_seeds(case.start, window)
    except ValueError as exc:
        return _failed_start(case, problem, settings, window, exc, t0)
    t_seed = time.perf_counter() - t0
    bar = _Progress(case, len(seeds) * settings.max_points, progress, poll)
    engine = LatticeContinuation(problem, settings, progress=bar)
    branches: list[Branch] = []
    skipped: list[str] = []
    per_branch = []
    for seed in seeds:
        if problem.lattice_key(seed.solution) in engine.visited:
            skipped.append(seed.label)
            continue
        tb = time.perf_counter()
        branches.append(engine.run(seed, branch_id=len(branches)))
        per_branch.append(time.perf_counter() - tb)
    bar.close()
    timings = {"total_s": time.perf_counter() - t0, "seeds_s": t_seed,
               "per_branch_s": per_branch, "n_points": int(sum(b.n_points for b in branches)),
               "lattice_steps": engine.n_evaluations}
    return RunResult(case, problem, branches, settings, window, timings, skipped)
