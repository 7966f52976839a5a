"""Where the branches of a run are computed: in this process, or as tasks on Dask.

A run is a list of seeds (one per start of the case); each seed is one task that continues one
branch (:meth:`nsm_continuation.algorithms.base.Algorithm.run_branch`). The serial path runs them in
order and skips a seed that lies on a branch already computed
(:meth:`~nsm_continuation.algorithms.base.Algorithm.covered`). The Dask path (``dask.distributed``)
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

An algorithm may also split the search for its seeds into independent pieces
(:meth:`~nsm_continuation.algorithms.base.Algorithm.seed_pieces`: the lattice scan of the bar, by
chunks of periods). :func:`search_seeds_distributed` runs them as tasks before the seeds are
built, and the master adopts their results in piece order: the seeds are then built here by the
serial code, which finds the pieces' work done (the nodes they solved). A branch task returns,
with its branch, what the master needs to go on as if it had computed it
(:meth:`~nsm_continuation.algorithms.base.Algorithm.task_state`: for the lattice, the nodes it
visited, which decide the skipped seeds); the merge adopts it when it accepts the branch.

A run holds one :class:`DaskSession`: its client (and local cluster) starts when a phase first
has work to spread (the seed search's pieces, the branches, a generation of a bifurcation
diagram's switches, :func:`nsm_continuation.runs.diagrams.grow`) and serves the later phases.
A problem class the registry does not know (the Python API's) is sent to the workers by
reference, with the case.

``--workers N`` starts a local cluster of ``N`` single-threaded worker processes for the run;
``--scheduler tcp://HOST:8786`` uses an existing cluster (``dask scheduler``, ``dask worker``),
whose workers need this package (and any plugin problem) installed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from nsm_continuation.core.records import Branch
from nsm_continuation.runs.setup import rebuild_case

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


#: on a worker: the rebuilt (algorithm, seeds) of the last cases seen, so that the tasks of one
#: run rebuild the problem and its seeds once per worker, not once per task
_WORKER_CACHE: dict[str, tuple[Any, list[Any]]] = {}
_WORKER_CACHE_SIZE = 4


def _prepared(raw_case: dict[str, Any], explicit: list[Any] | None,
              problem_class: type | None = None,
              restart: tuple[Any, Any, Any] | None = None) -> tuple[Any, list[Any]]:
    import json
    import pickle

    key = json.dumps(raw_case, sort_keys=True, default=str) + "".join(
        "" if x is None else pickle.dumps(x).hex() for x in (explicit, problem_class, restart))
    hit = _WORKER_CACHE.get(key)
    if hit is None:
        case, _problem, window, algorithm = rebuild_case(raw_case, problem_class, restart)
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
                explicit: list[Any] | None, problem_class: type | None = None,
                restart: tuple[Any, Any, Any] | None = None, piece: int | None = None
                ) -> tuple[Any, float, dict[str, Any], Any]:
    """One task: the branch of seed ``index`` (of the case's starts, or of ``explicit`` start
    points), or its piece ``piece`` (:meth:`~nsm_continuation.algorithms.base.Algorithm.
    branch_pieces`), with its wall time, what it added to the algorithm's counters and the
    algorithm's :meth:`~nsm_continuation.algorithms.base.Algorithm.task_state`."""
    algorithm, seeds = _prepared(raw_case, explicit, problem_class, restart)
    before = _numeric(algorithm.counters())
    algorithm.begin_task()
    t0 = time.perf_counter()
    branch = (algorithm.run_branch(seeds[index], branch_id=branch_id) if piece is None
              else algorithm.run_piece(seeds[index], piece))
    dt = time.perf_counter() - t0
    state = algorithm.task_state()
    after = _numeric(algorithm.counters())
    return branch, dt, {k: v - before.get(k, 0) for k, v in after.items()}, state


#: on a worker: the rebuilt (case, window, algorithm) of the last cases whose seed search it
#: ran pieces of (the problem keeps what the earlier pieces solved; each piece records its own)
_PIECE_CACHE: dict[str, tuple[Any, Any, Any]] = {}


def seed_piece_task(raw_case: dict[str, Any], piece: Any) -> tuple[Any, float]:
    """One task of a seed search split in pieces: the algorithm's
    :meth:`~nsm_continuation.algorithms.base.Algorithm.seed_piece` result and its wall time."""
    import json

    key = json.dumps(raw_case, sort_keys=True, default=str)
    hit = _PIECE_CACHE.get(key)
    if hit is None:
        case, _problem, window, algorithm = rebuild_case(raw_case)
        if len(_PIECE_CACHE) >= _WORKER_CACHE_SIZE:
            _PIECE_CACHE.pop(next(iter(_PIECE_CACHE)))
        hit = _PIECE_CACHE[key] = (case, window, algorithm)
    case, window, algorithm = hit
    t0 = time.perf_counter()
    result = algorithm.seed_piece(case.start, window, piece)
    return result, time.perf_counter() - t0


#: pieces of a seed search per worker: enough for the dynamic scheduling to even out pieces
#: of unequal cost, few enough that each stays much longer than a task's overhead (~ms)
PIECES_PER_WORKER = 8


def start_client(execution: Execution) -> tuple[Any, Any]:
    """A ``dask.distributed`` client for ``execution`` and the local cluster it started
    (``None`` for an existing ``scheduler``): ``workers`` single-threaded worker processes,
    BLAS limited to one thread, set up for tasks that hold the GIL (see below). Close both
    when done (``client.close()``, ``cluster.close()``). Also used by the benchmarks' own
    tasks (``benchmarks/brute_force_pendulum.py``).

    Three of Dask's defaults cost a task that computes in Python most of the time (the bar's
    lattice scan, N = 200, on 2 workers: the pieces' CPU time 1.3x the serial scan's with
    them, 1.05x without):

    * ``MALLOC_TRIM_THRESHOLD_=65536`` in the worker's environment
      (``distributed.nanny.pre-spawn-environ``) also turns off glibc's adaptive mmap
      threshold: every temporary array above 128 kB is then mapped and unmapped, page by page
      (7x the page faults). Not set here (it must be set before the process starts: ``env`` is
      applied after);
    * the statistical profiler samples the task's stack every 10 ms
      (``distributed.worker.profile``): off;
    * the event loop ticks every 20 ms (``distributed.admin.tick.interval``), each tick taking
      the GIL from the task: every second.

    A cluster of one's own (``scheduler``) is set up by whoever starts it (README)."""
    import dask
    from dask.distributed import Client, LocalCluster

    if execution.scheduler:
        from nsm_continuation.core.errors import CaseError

        refused = _refused(execution.scheduler)
        try:
            if refused is not None:  # nothing listens there: no need to wait 10 s
                raise ConnectionRefusedError(refused)
            return Client(execution.scheduler, timeout="10s"), None
        except (OSError, TimeoutError) as exc:  # nothing listening, or not a scheduler
            raise CaseError(f"execution.scheduler (--scheduler): no Dask scheduler answers at "
                            f"{execution.scheduler} ({one_line(str(exc))})") from None
    import multiprocessing

    if getattr(multiprocessing.current_process(), "_inheriting", False):
        # a worker process of the cluster this script is starting, still importing the
        # script (no `if __name__ == "__main__":` guard; multiprocessing's own test for it):
        # end it quietly, the script's own process says why its cluster did not start
        raise SystemExit(1)
    # one thread per worker, BLAS included: N workers on N cores, not N x (BLAS threads)
    one = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    pre_spawn = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ",
                                                  {}).items()
                 if k != "MALLOC_TRIM_THRESHOLD_"}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": {**pre_spawn, **one},
                          "distributed.worker.profile.enabled": False,
                          "distributed.admin.tick.interval": "1s"}):
        try:
            cluster = LocalCluster(n_workers=int(execution.workers or 1),
                                   threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=40, env=one)
        except RuntimeError as exc:  # e.g. "Nanny failed to start."
            raise RuntimeError(
                f"the local Dask cluster of {execution.workers} workers did not start ({exc}); "
                "a Python script that starts one must run under "
                "`if __name__ == \"__main__\":` (each worker process imports the script "
                "again)") from None
    return Client(cluster), cluster


class DaskSession:
    """The Dask client of one run, started on first use (:func:`start_client`): the phases of
    a run that have parallel work (the seed search's pieces, the branches, each generation
    of a bifurcation diagram) share one cluster, and a run without any starts none.
    ``futures`` collects what was submitted, for :meth:`cancel`."""

    def __init__(self, execution: Execution) -> None:
        self.execution = execution
        self.futures: list[Any] = []
        #: seconds spent connecting, or starting the local cluster (0 until used)
        self.start_s = 0.0
        self._client: Any = None
        self._cluster: Any = None

    @property
    def client(self) -> Any:
        if self._client is None:
            t0 = time.perf_counter()
            self._client, self._cluster = start_client(self.execution)
            self.start_s = time.perf_counter() - t0
        return self._client

    @property
    def started(self) -> bool:
        return self._client is not None

    def n_workers(self) -> int:
        return _n_workers(self.client, self.execution)

    def submit(self, fn: Callable[..., Any], *args: Any, key: str) -> Any:
        """``client.submit(fn, *args)`` as a task that is retried if its worker dies, keyed
        ``key`` (made unique) and remembered in :attr:`futures`."""
        future = self.client.submit(fn, *args, pure=False, retries=TASK_RETRIES,
                                    key=f"{key}-{time.time_ns()}")
        self.futures.append(future)
        return future

    def cancel(self) -> None:
        for f in self.futures:
            f.cancel()

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None


def _refused(address: str) -> str | None:
    """Why a TCP connection to the scheduler ``address`` (``tcp://HOST:PORT``) is refused at
    once (nothing listens on that port), else None (it may answer, or take time to)."""
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(address)
    if parts.scheme != "tcp" or parts.hostname is None or parts.port is None:
        return None
    try:
        with socket.create_connection((parts.hostname, parts.port), timeout=2.0):
            return None
    except ConnectionRefusedError as exc:
        return f"connection refused: {exc}"
    except OSError:
        return None  # unreachable or slow: the client's own timeout decides


def one_line(text: str) -> str:
    """``text`` on one line (a task's error for a report's table cell or a message)."""
    return " ".join(text.split())


@contextmanager
def lazy_session(execution: Execution) -> Iterator[DaskSession]:
    """A :class:`DaskSession` for a block: if the block raises (SIGINT included) the
    submitted tasks are cancelled; the client, and the local cluster it started, are closed
    in any case."""
    session = DaskSession(execution)
    try:
        yield session
    except BaseException:
        session.cancel()
        raise
    finally:
        session.close()


@contextmanager
def dask_session(execution: Execution) -> Iterator[tuple[Any, list[Any]]]:
    """:func:`lazy_session` started at once, as ``(client, futures)``: the futures appended to
    the list are cancelled if the block raises."""
    with lazy_session(execution) as session:
        yield session.client, session.futures


def wait_all(futures: list[Any], poll: Callable[[], None] | None,
              done_callback: Callable[[Any], None] | None = None) -> None:
    """Wait for every future, calling ``poll`` (the signals) every 0.25 s and
    ``done_callback`` on each future as it finishes."""
    from dask.distributed import wait

    pending = set(futures)
    while pending:
        try:
            done, pending = wait(list(pending), timeout=0.25, return_when="FIRST_COMPLETED")
        except TimeoutError:  # nothing finished yet: only the signals are polled
            done = set()
        if done_callback is not None:
            for f in done:
                done_callback(f)
        if poll is not None:
            poll()


def _n_workers(client: Any, execution: Execution) -> int:
    if execution.workers:
        return int(execution.workers)
    try:
        return max(1, len(client.scheduler_info().get("workers", {})))
    except Exception:  # noqa: BLE001 - only the number of pieces depends on it
        return 1


def search_seeds_distributed(session: DaskSession, raw_case: dict[str, Any], algorithm: Any,
                             case_start: Any, window: Any,
                             poll: Callable[[], None] | None = None) -> dict[str, Any]:
    """The pieces of the algorithm's seed search (:meth:`~nsm_continuation.algorithms.base.
    Algorithm.seed_pieces`) as Dask tasks, adopted in piece order by ``algorithm``, which then
    builds its seeds (:meth:`~nsm_continuation.algorithms.base.Algorithm.starts`) without redoing
    them. Nothing (no cluster started) when the search is not split. A piece that raises
    raises here (as the serial search would: a ``ValueError`` is a failed start).

    Returns timings for ``report.json``: ``seed_pieces`` (how many), ``seed_pieces_s`` (each
    on its worker), ``seed_cluster_start_s`` (connecting, or starting the local cluster),
    ``seed_pieces_wall_s`` (from the first submission to the last result adopted),
    ``seed_adopt_s`` (adopting the results here, in order, while the later pieces compute)
    and ``seed_search_distributed_s`` (all of it)."""
    if not algorithm.seed_pieces(case_start, window, 1):
        return {}
    t0 = time.perf_counter()
    count = PIECES_PER_WORKER * session.n_workers()
    t_start = session.start_s
    pieces = algorithm.seed_pieces(case_start, window, count)
    t1 = time.perf_counter()
    futures = [session.submit(seed_piece_task, raw_case, piece, key=f"nsm-seed-piece-{i}")
               for i, piece in enumerate(pieces)]
    per_piece: list[float] = []
    t_adopt = 0.0

    def adopt_in_order(_: Any = None) -> None:
        # in piece order (the serial search's), each as soon as it and those before it are
        # done: adopting overlaps with the pieces still computing
        nonlocal t_adopt
        while len(per_piece) < len(futures) and futures[len(per_piece)].done():
            result, dt = futures[len(per_piece)].result()  # a piece's error raises here
            t2 = time.perf_counter()
            algorithm.adopt_seed_piece(result)
            t_adopt += time.perf_counter() - t2
            per_piece.append(dt)

    wait_all(futures, poll, adopt_in_order)
    adopt_in_order()
    t_wall = time.perf_counter() - t1
    return {"seed_pieces": len(per_piece), "seed_pieces_s": per_piece,
            "seed_cluster_start_s": t_start, "seed_pieces_wall_s": t_wall,
            "seed_adopt_s": t_adopt, "seed_search_distributed_s": time.perf_counter() - t0}


def run_distributed(session: DaskSession, raw_case: dict[str, Any], algorithm: Any,
                    seeds: list[Any], explicit: list[Any] | None,
                    progress: Callable[[int], None] | None,
                    poll: Callable[[], None] | None,
                    problem_class: type | None = None,
                    restart: tuple[Any, Any, Any] | None = None
                    ) -> tuple[list[Branch], list[str], list[float], dict[str, Any]]:
    """Every seed as a Dask task, merged in seed order (see the module docstring): the
    accepted branches, the skipped seeds' labels, the per-branch times and the summed
    counters. ``problem_class``: sent when the problem is not registered (the Python API);
    ``restart``: the case's restart, whose problem the workers build
    (:func:`rebuild_case`)."""
    # each finished task's result, fetched once as it finishes (a branch of thousands of
    # points costs the master its transfer and unpickling; the merge below reuses it)
    fetched: dict[str, Any] = {}

    def advance(f: Any) -> None:
        if f.status != "finished":
            return
        try:
            fetched[f.key] = out = f.result()
        except Exception:  # noqa: BLE001 - fetched again by the merge, which records why
            return
        if progress is not None and isinstance(out[0], Branch):
            progress(out[0].n_points)

    pieces = [algorithm.branch_pieces(seed) for seed in seeds]
    futures = [[session.submit(branch_task, raw_case, i, i, explicit, problem_class, restart,
                               None if n == 1 else k, key=f"nsm-branch-{i}-{k}")
                for k in range(n)] for i, n in enumerate(pieces)]
    wait_all([f for fs in futures for f in fs], poll, advance)
    results: list[tuple[Branch | None, float, dict[str, Any], str | None, Any]] = []
    for i, fs in enumerate(futures):
        try:
            outs = [fetched[f.key] if f.key in fetched else f.result() for f in fs]
            if len(outs) == 1:
                branch, dt, counters, state = outs[0]
            else:  # the branch's pieces, joined as the serial run computes it
                branch = algorithm.join_pieces(seeds[i], [o[0] for o in outs], i)
                dt, state = sum(o[1] for o in outs), None
                counters = {k: sum(o[2].get(k, 0) for o in outs) for k in outs[0][2]}
                if progress is not None:
                    progress(branch.n_points)
            results.append((branch, dt, counters, None, state))
        except Exception as exc:  # noqa: BLE001 - recorded on the branch, never raised
            results.append((None, 0.0, {}, one_line(f"{type(exc).__name__}: {exc}"), None))
    return merge_in_seed_order(algorithm, seeds, results)


def merge_in_seed_order(algorithm: Any, seeds: list[Any],
                        results: list[tuple[Any, ...]]
                        ) -> tuple[list[Branch], list[str], list[float], dict[str, Any]]:
    """The serial loop's rule applied to results computed independently: in seed order, a
    seed that lies on an already accepted branch is skipped; the accepted branches are
    numbered ``0, 1, ...``; a failed task becomes a branch without points whose termination
    names the failure. ``results``: ``(branch, seconds, counters, error)``, optionally with the
    task's state, which the algorithm adopts when its branch is accepted
    (:meth:`~nsm_continuation.algorithms.base.Algorithm.adopt_branch`), before the next seed."""
    branches: list[Branch] = []
    skipped: list[str] = []
    per_branch: list[float] = []
    counters: dict[str, Any] = {}
    adopt = getattr(algorithm, "adopt_branch", None)
    for seed, (branch, dt, cnt, error, *rest) in zip(seeds, results, strict=True):
        if algorithm.covered(seed, branches):
            skipped.append(algorithm.label(seed))
            continue
        if branch is None:
            branch = Branch(len(branches), algorithm.label(seed), [], [],
                            {"task": f"task failed on a worker: {error}"})
        elif adopt is not None and rest:
            adopt(branch, rest[0])
        branch.id = len(branches)
        branches.append(branch)
        per_branch.append(dt)
        for k, v in cnt.items():
            if isinstance(v, int | float) and not isinstance(v, bool):
                counters[k] = counters.get(k, 0) + v
    return branches, skipped, per_branch, counters
