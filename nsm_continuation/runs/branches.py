"""The branches of one run: build the settings, continue every start of a validated case with
the case's algorithm (:mod:`nsm_continuation.algorithms`), in this process or as Dask tasks,
and collect them into a :class:`~nsm_continuation.runs.result.RunResult`. A bifurcation
diagram grows on top of this (:mod:`nsm_continuation.runs.diagrams`, through ``grow``)."""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import nullcontext
from typing import Any

from nsm_continuation.algorithms.registry import make_algorithm, unsupported
from nsm_continuation.cases.restart import start_points
from nsm_continuation.cases.schema import Case
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.palc import HOOK_FAULTS, describe_fault
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.progress import progress_bar
from nsm_continuation.core.records import Branch
from nsm_continuation.core.settings import ContinuationSettings
from nsm_continuation.runs.execution import (
    DaskSession,
    Execution,
    lazy_session,
    run_distributed,
    search_seeds_distributed,
)
from nsm_continuation.runs.result import RunResult
from nsm_continuation.runs.setup import registered_class, settings_from_case

#: grows a run into a bifurcation diagram: ``grow(result, poll, session)``
Grow = Callable[[RunResult, Callable[[], None] | None, DaskSession | None], None]


class _Progress:
    """Per-point callback of the engines: advances the progress bar (if ``progress``,
    :func:`progress_bar`) and calls ``poll`` (e.g. the CLI's check for a pending
    SIGINT/SIGTERM: a signal whose exception was swallowed inside a CasADi call is honoured at
    the next point)."""

    def __init__(self, case: Case, total: int, progress: bool,
                 poll: Callable[[], None] | None) -> None:
        self.bar = progress_bar(case.name, total) if progress else None
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
                  window: tuple[float | None, float | None], exc: Exception | str,
                  t0: float) -> RunResult:
    """The start block passed the preflight but its starts could not be built (e.g. the
    transient simulation that finds a hybrid orbit failed): one failed branch records why."""
    msg = str(exc).removeprefix("start: ")
    failed = Branch(0, "start", [], [], {"start": f"no start point: {msg}"})
    return RunResult(case, problem, [failed], settings, window,
                     {"total_s": time.perf_counter() - t0, "n_points": 0, "per_branch_s": []})


def run_branches(case: Case, problem: Problem, progress: bool = True,
                 starts: list[StartPoint] | None = None,
                 poll: Callable[[], None] | None = None,
                 execution: Execution | None = None, grow: Grow | None = None) -> RunResult:
    """Continue every start of ``case`` (or the given ``starts``: explicit start points of a
    curve problem, e.g. from the Python API) with the case's algorithm
    (``continuation.algorithm``, default the problem's first,
    :mod:`nsm_continuation.algorithms.base`)
    and collect the branches: in this process, or as Dask tasks (``execution``, else the
    case's ``execution:`` block; :mod:`nsm_continuation.runs.execution`), with the same result.
    ``poll`` is called after every point (it may raise to stop the run); ``grow``, when
    given, grows the run into a bifurcation diagram inside the same Dask session."""
    settings, window = settings_from_case(case, problem)
    name = case.continuation.algorithm or problem.algorithms[0]
    why = unsupported(name, problem)
    if why is not None:
        raise CaseError(f"continuation.algorithm: {why}")
    algorithm = make_algorithm(name, problem, settings)
    if starts is not None and not algorithm.takes_start_points:
        raise CaseError(f"start: the {name} algorithm starts from the start: block only (a "
                        "lattice problem has no start guess)")
    execution = execution or Execution(case.execution.workers, case.execution.scheduler,
                                       case.execution.no_workers_timeout)
    # one Dask client for the whole run, started when a phase has work to spread
    with lazy_session(execution) if execution.distributed else nullcontext() as session:
        result = _run(case, problem, algorithm, settings, window, progress, starts, poll,
                      session, grow)
    return result


def _run(case: Case, problem: Problem, algorithm: Any, settings: ContinuationSettings,
         window: tuple[float | None, float | None], progress: bool,
         starts: list[StartPoint] | None, poll: Callable[[], None] | None,
         session: DaskSession | None, grow: Grow | None) -> RunResult:
    """:func:`run_branches` once its algorithm is made: ``session`` is None for a serial run."""
    t0 = time.perf_counter()
    start_counters: dict[str, Any] = {}
    registered = registered_class(case.problem)
    # what a worker builds the problem from: the registered class of case.problem (for a
    # restart, configured as the restart says), else the problem's own class (the Python
    # API's); a restart of a problem the registry does not know is computed here
    problem_class = None if registered is type(problem) or (
        registered is not None and case.restart is not None) else type(problem)
    rebuildable = problem_class is None or case.restart is None
    try:
        if starts is None and case.restart is not None:
            # a restart (start: {from: <run>}): the saved point, or the switched branch's
            # first point (nsm_continuation.cases.restart, nsm_continuation.algorithms.switching)
            starts, start_counters = start_points(case.restart, problem, settings)
        if starts is None and session is not None:
            # the pieces of a split seed search (the lattice scan) as Dask tasks, adopted
            # here in order: starts() below then finds their work done
            start_counters.update(search_seeds_distributed(
                session, case.model_dump(mode="json"), algorithm, case.start, window, poll))
        seeds = (algorithm.starts(case.start, window) if starts is None
                 else algorithm.seeds_from_points(starts))
    except ValueError as exc:
        return _failed_start(case, problem, settings, window, exc, t0)
    except HOOK_FAULTS as exc:  # the problem's start_points failed: its fault, named
        return _failed_start(case, problem, settings, window, describe_fault(exc, problem.name),
                             t0)
    algorithm.prepare()
    t_setup = time.perf_counter() - t0
    bar = _Progress(case, len(seeds) * settings.max_points, progress, poll)
    algorithm.progress = bar
    # a local cluster only where there is work to spread: a single task (one branch in one
    # piece) runs here (the same result, without the ~1 s of starting workers); an existing
    # cluster (scheduler) is always used, the user chose where the work runs
    tasks = sum(algorithm.branch_pieces(seed) for seed in seeds)
    spread = session is not None and algorithm.distributable and rebuildable and (
        tasks > 1 or (session.execution.scheduler is not None and tasks == 1))
    start_counters["dask_branch_tasks"] = tasks if spread else 0
    if spread and session is not None and session.execution.scheduler is not None \
            and problem_class is not None and problem_class.__module__ == "__main__":
        raise CaseError(f"execution.scheduler: the problem class {problem_class.__name__} is "
                        "defined in the script (__main__), which the workers of an existing "
                        "cluster cannot import: define it in a module installed on them")
    if spread:
        assert session is not None
        explicit = starts if (starts is not None or case.restart is not None) else None
        r = case.restart
        restart = None if r is None else (r.spec, r.record, r.selection)
        branches, skipped, per_branch, counters = run_distributed(
            session, case.model_dump(mode="json"), algorithm, seeds, explicit, bar, poll,
            problem_class, restart)
    else:
        branches, skipped, per_branch = [], [], []
        for seed in seeds:
            if algorithm.covered(seed, branches):
                skipped.append(algorithm.label(seed))
                continue
            tb = time.perf_counter()
            branches.append(algorithm.run_branch(seed, branch_id=len(branches)))
            per_branch.append(time.perf_counter() - tb)
        counters = algorithm.counters()
    bar.close()
    timings = {"total_s": time.perf_counter() - t0, algorithm.setup_key: t_setup,
               "per_branch_s": per_branch,
               "n_points": int(sum(b.n_points for b in branches)), **counters,
               **start_counters}
    result = RunResult(case, problem, branches, settings, window, timings, skipped)
    if grow is not None:
        # a bifurcation diagram: the branches born at the detected points, recursively,
        # each generation's switches as Dask tasks when the run has a session
        grow(result, poll, session)
        timings["total_s"] = time.perf_counter() - t0
    if session is not None and session.started:
        timings["dask_start_s"] = session.start_s
    return result


