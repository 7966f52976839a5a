"""Where the branches of a run are computed: in this process, or as tasks on Dask.

A run is a list of seeds (one per start of the case); each seed is one task that continues one
branch (:meth:`nsm_continuation.algorithms.Algorithm.run_branch`). The serial path runs them in
order and skips a seed that lies on a branch already computed
(:meth:`~nsm_continuation.algorithms.Algorithm.covered`). The Dask path (``dask.distributed``)
runs every seed as a task on the workers and then merges the results **in seed order with the
same rule**: a branch whose seed lies on an earlier accepted branch is dropped, the others are
numbered in order. So the branches, their ids and order and every event are those of the serial
run, to the last digit (each task computes exactly what the serial loop would: the branches are
independent, and a task rebuilds the problem, the settings and the seeds from the case itself).

A task carries only the case (its validated input as plain data) and the seed's index (or the
seed itself when it cannot be rebuilt from the case: explicit start points, restarts): the
problem and its CasADi functions are built on the worker from the case, never pickled. A worker
lost during a task makes Dask run the task elsewhere (``retries``); a task that raises ends its
branch with the recorded reason ``task failed on a worker: ...``, never the run. SIGINT or
SIGTERM (the CLI's ``poll``) cancels the pending tasks and leaves no output.

``--workers N`` starts a local cluster of ``N`` single-threaded worker processes for the run;
``--scheduler tcp://HOST:8786`` uses an existing cluster (``dask scheduler``, ``dask worker``),
whose workers need this package (and any plugin problem) installed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .records import Branch

#: retries of a task whose worker died (Dask reschedules it on another worker)
TASK_RETRIES = 2


@dataclass
class Execution:
    """How to compute the branches: ``workers`` local processes or an existing ``scheduler``
    (neither: serial, in this process)."""

    workers: int | None = None
    scheduler: str | None = None

    @property
    def distributed(self) -> bool:
        return bool(self.workers) or bool(self.scheduler)


def _rebuild(raw_case: dict[str, Any]) -> tuple[Any, Any, Any, Any]:
    """On a worker: the case, problem, settings and algorithm, from the case's input alone."""
    from . import registry
    from .algorithms import make_algorithm
    from .cases import Case
    from .runner import settings_from_case

    case = Case.model_validate(raw_case)
    problem = registry.get(case.problem)(case.parameters)
    settings, window = settings_from_case(case, problem)
    algorithm = make_algorithm(case.continuation.algorithm or problem.algorithms[0], problem,
                               settings)
    problem.energy_cap = case.continuation.max_energy
    return case, problem, window, algorithm


#: on a worker: the rebuilt (algorithm, seeds) of the last cases seen, so that the tasks of one
#: run rebuild the problem and its seeds once per worker, not once per task
_WORKER_CACHE: dict[str, tuple[Any, list[Any]]] = {}
_WORKER_CACHE_SIZE = 4


def _prepared(raw_case: dict[str, Any], explicit: list[Any] | None) -> tuple[Any, list[Any]]:
    import json
    import pickle

    key = json.dumps(raw_case, sort_keys=True, default=str) + (
        "" if explicit is None else pickle.dumps(explicit).hex())
    hit = _WORKER_CACHE.get(key)
    if hit is None:
        case, _problem, window, algorithm = _rebuild(raw_case)
        seeds = (algorithm.starts(case.start, window) if explicit is None
                 else algorithm.seeds_from_points(explicit))
        algorithm.prepare()
        if len(_WORKER_CACHE) >= _WORKER_CACHE_SIZE:
            _WORKER_CACHE.pop(next(iter(_WORKER_CACHE)))
        hit = _WORKER_CACHE[key] = (algorithm, seeds)
    return hit


def _numeric(counters: dict[str, Any]) -> dict[str, float]:
    return {k: v for k, v in counters.items()
            if isinstance(v, int | float) and not isinstance(v, bool)}


def branch_task(raw_case: dict[str, Any], index: int, branch_id: int,
                explicit: list[Any] | None) -> tuple[Branch, float, dict[str, Any]]:
    """One task: the branch of seed ``index`` (of the case's starts, or of ``explicit`` start
    points), with its wall time and what it added to the algorithm's counters."""
    algorithm, seeds = _prepared(raw_case, explicit)
    before = _numeric(algorithm.counters())
    t0 = time.perf_counter()
    branch = algorithm.run_branch(seeds[index], branch_id=branch_id)
    dt = time.perf_counter() - t0
    after = _numeric(algorithm.counters())
    return branch, dt, {k: v - before.get(k, 0) for k, v in after.items()}


def _client(execution: Execution) -> Any:
    from dask.distributed import Client, LocalCluster

    if execution.scheduler:
        return Client(execution.scheduler, timeout="10s"), None
    # one thread per worker, BLAS included: N workers on N cores, not N x (BLAS threads)
    one = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    cluster = LocalCluster(n_workers=int(execution.workers or 1), threads_per_worker=1,
                           processes=True, dashboard_address=None, silence_logs=40, env=one)
    return Client(cluster), cluster


def run_distributed(execution: Execution, raw_case: dict[str, Any], algorithm: Any,
                    seeds: list[Any], explicit: list[Any] | None,
                    progress: Callable[[int], None] | None,
                    poll: Callable[[], None] | None
                    ) -> tuple[list[Branch], list[str], list[float], dict[str, Any]]:
    """Every seed as a Dask task, merged in seed order (see the module docstring): the
    accepted branches, the skipped seeds' labels, the per-branch times and the summed
    counters."""
    from dask.distributed import wait

    client, cluster = _client(execution)
    futures = []
    try:
        futures = [client.submit(branch_task, raw_case, i, i, explicit, pure=False,
                                 retries=TASK_RETRIES, key=f"nsm-branch-{i}-{time.time_ns()}")
                   for i in range(len(seeds))]
        pending = set(futures)
        while pending:
            try:
                done, pending = wait(list(pending), timeout=0.25,
                                     return_when="FIRST_COMPLETED")
            except TimeoutError:  # nothing finished yet: only the signals are polled
                done = set()
            for f in done:
                if progress is not None and f.status == "finished":
                    progress(f.result()[0].n_points)
            if poll is not None:
                poll()
        results: list[tuple[Branch | None, float, dict[str, Any], str | None]] = []
        for f in futures:
            try:
                branch, dt, counters = f.result()
                results.append((branch, dt, counters, None))
            except Exception as exc:  # noqa: BLE001 - recorded on the branch, never raised
                results.append((None, 0.0, {}, f"{type(exc).__name__}: {exc}"))
    except BaseException:
        for f in futures:
            f.cancel()
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return merge_in_seed_order(algorithm, seeds, results)


def merge_in_seed_order(algorithm: Any, seeds: list[Any],
                        results: list[tuple[Branch | None, float, dict[str, Any], str | None]]
                        ) -> tuple[list[Branch], list[str], list[float], dict[str, Any]]:
    """The serial loop's rule applied to results computed independently: in seed order, a
    seed that lies on an already accepted branch is skipped; the accepted branches are
    numbered ``0, 1, ...``; a failed task becomes a branch without points whose termination
    names the failure."""
    branches: list[Branch] = []
    skipped: list[str] = []
    per_branch: list[float] = []
    counters: dict[str, Any] = {}
    for seed, (branch, dt, cnt, error) in zip(seeds, results, strict=True):
        if algorithm.covered(seed, branches):
            skipped.append(algorithm.label(seed))
            continue
        if branch is None:
            branch = Branch(len(branches), algorithm.label(seed), [], [],
                            {"task": f"task failed on a worker: {error}"})
        branch.id = len(branches)
        branches.append(branch)
        per_branch.append(dt)
        for k, v in cnt.items():
            if isinstance(v, int | float) and not isinstance(v, bool):
                counters[k] = counters.get(k, 0) + v
    return branches, skipped, per_branch, counters
