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

``--workers N`` starts a local cluster of ``N`` single-threaded worker processes for the run
(at most what the machine runs: :func:`nsm_continuation.cases.schema._local_workers`);
``--scheduler tcp://HOST:8786`` uses an existing cluster (``dask scheduler``, ``dask worker``),
whose workers need this package (and any plugin problem) installed.

Every address and every state of a cluster ends in a bounded, named outcome: the address's
syntax is checked with the case (:func:`nsm_continuation.cases.schema._scheduler_address`); a
scheduler that refuses the connection, does not answer within :data:`CONNECT_TIMEOUT_S`, or
answers in another protocol (an HTTP server: Dask would read its reply as a frame of 2.8 EiB)
is refused in one line (:func:`check_scheduler`); a cluster left without any worker for
``execution.no_workers_timeout`` seconds ends the tasks still waiting, whose branches record
why and which workers were lost (:meth:`DaskSession.watch`); the branches computed are kept.
"""

from __future__ import annotations

import asyncio
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.records import Branch
from nsm_continuation.runs.setup import rebuild_case

#: retries of a task whose worker died (Dask reschedules it on another worker)
TASK_RETRIES = 2
#: seconds an existing scheduler has to accept the connection and answer Dask's handshake
CONNECT_TIMEOUT_S = 10.0
#: a recorded reason that is not a task's own failure (the merge records it as it is)
NOT_COMPUTED = "not computed: "


@dataclass
class Execution:
    """How to compute the branches: ``workers`` local processes or an existing ``scheduler``
    (neither: serial, in this process)."""

    workers: int | None = None
    scheduler: str | None = None
    #: seconds without any worker after which the waiting tasks end (``execution:``)
    no_workers_timeout: float = 30.0

    @property
    def distributed(self) -> bool:
        return bool(self.workers) or bool(self.scheduler)


#: on a worker: the rebuilt (algorithm, seeds) of the last cases seen, so that the tasks of one
#: run rebuild the problem and its seeds once per worker, not once per task
_WORKER_CACHE: dict[str, tuple[Any, list[Any]]] = {}
_WORKER_CACHE_SIZE = 4


def _task_case(raw_case: dict[str, Any]) -> dict[str, Any]:
    """The case a task rebuilds: without its ``execution:`` block, which concerns the master
    (and whose ``workers`` is checked against the machine's available memory, which the
    workers themselves now hold)."""
    return {k: v for k, v in raw_case.items() if k != "execution"}


def _prepared(raw_case: dict[str, Any], explicit: list[Any] | None,
              problem_class: type | None = None,
              restart: tuple[Any, Any, Any] | None = None) -> tuple[Any, list[Any]]:
    import json
    import pickle

    key = json.dumps(raw_case, sort_keys=True, default=str) + "".join(
        "" if x is None else pickle.dumps(x).hex() for x in (explicit, problem_class, restart))
    hit = _WORKER_CACHE.get(key)
    if hit is None:
        case, _problem, window, algorithm = rebuild_case(_task_case(raw_case), problem_class,
                                                         restart)
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
        case, _problem, window, algorithm = rebuild_case(_task_case(raw_case))
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

    A cluster of one's own (``scheduler``) is set up by whoever starts it (docs/dask.md). Without
    Dask installed, one :class:`CaseError` line saying how to install it."""
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError:
        what = _SCHEDULER if execution.scheduler else "execution.workers (--workers)"
        raise CaseError(f"{what}: computing the branches as Dask tasks needs Dask, which is "
                        "not installed here: pip install 'nsm-continuation[dask]'") from None

    if execution.scheduler:
        security = check_scheduler(execution.scheduler)
        try:
            client = Client(execution.scheduler, timeout=CONNECT_TIMEOUT_S, security=security)
            _quiet_reconnects()
            return client, None
        except (OSError, TimeoutError) as exc:  # it went away since it answered the check
            raise CaseError(f"{_SCHEDULER}: no Dask scheduler answers at "
                            f"{execution.scheduler}: {one_line(str(exc))}") from None
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
    from distributed.deploy.spec import SpecCluster

    before = set(SpecCluster._instances)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": {**pre_spawn, **one},
                          "distributed.worker.profile.enabled": False,
                          "distributed.admin.tick.interval": "1s"}):
        try:
            cluster = LocalCluster(n_workers=int(execution.workers or 1),
                                   threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=40, env=one)
        except (KeyboardInterrupt, SystemExit) as exc:  # SIGINT / SIGTERM while it starts
            _abandon(set(SpecCluster._instances) - before)
            raise exc from None
        except RuntimeError as exc:  # e.g. "Nanny failed to start."
            raise RuntimeError(
                f"the local Dask cluster of {execution.workers} workers did not start ({exc}); "
                "a Python script that starts one must run under "
                "`if __name__ == \"__main__\":` (each worker process imports the script "
                "again)") from None
    return Client(cluster), cluster


class _ConnectionLossFilter:
    """Drops the client's tracebacks of a lost scheduler connection (its reconnection
    attempts): the run says it in one line (:meth:`DaskSession.watch`)."""

    def filter(self, record: Any) -> bool:
        if str(record.msg).startswith("Failed to reconnect to scheduler"):
            return False
        exc = record.exc_info[1] if record.exc_info else None
        while exc is not None:
            if isinstance(exc, (OSError, asyncio.CancelledError)) or \
                    type(exc).__name__ == "CommClosedError":
                return False
            exc = exc.__cause__ or exc.__context__
        return True


def _quiet_reconnects() -> None:
    """Install :class:`_ConnectionLossFilter` on Dask's client logger (once)."""
    import logging

    log = logging.getLogger("distributed.client")
    if not any(isinstance(f, _ConnectionLossFilter) for f in log.filters):
        log.addFilter(_ConnectionLossFilter())


def _abandon(clusters: set[Any]) -> None:
    """End quietly the local ``clusters`` whose start was interrupted (SIGINT or SIGTERM,
    which end the run): Dask's own exit hook would close them and print three tracebacks
    (the half-started workers' status, "Nanny failed to start", an asyncio task never
    retrieved) after the run's one line. Their worker processes are daemonic: they end with
    this process. Dask's and asyncio's loggers are silenced for the shutdown."""
    import logging

    for name in ("distributed", "asyncio", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    from distributed.deploy.spec import SpecCluster

    for cluster in clusters:
        SpecCluster._instances.discard(cluster)
        cluster.shutdown_on_close = False


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
        #: why the tasks still waiting were ended (:meth:`watch`), else None
        self.lost: str | None = None
        self._client: Any = None
        self._cluster: Any = None
        self._seen: set[str] = set()  # every worker seen in the cluster
        self._alone_since: float | None = None  # since when there has been no worker
        self._checked = 0.0

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

    def watch(self) -> str | None:
        """Why the tasks still waiting will not be computed, else None: the cluster has had no
        worker for ``execution.no_workers_timeout`` seconds (every worker died, or none
        joined the scheduler); Dask would keep them waiting for a worker forever. Asks the
        scheduler at most once a second; once it holds, it holds for the rest of the run."""
        now = time.monotonic()
        if self.lost is not None or self._client is None:
            return self.lost
        status = str(getattr(self._client, "status", "running"))
        if status not in ("running", "newly-created"):
            # the scheduler went away: Dask's client tries to reconnect, then cancels every
            # future ("scheduler-connection-lost"); the run ends with this reason at once
            where = self.execution.scheduler or "the local cluster"
            self.lost = one_line(f"{NOT_COMPUTED}the connection to the Dask scheduler of "
                                 f"{where} was lost during the run (client {status})")
            return self.lost
        if now - self._checked < 1.0:
            return None
        self._checked = now
        try:
            workers = set(self._client.scheduler_info().get("workers", {}))
        except Exception:  # noqa: BLE001 - no answer this time: decide at the next one
            return None
        if workers:
            self._seen |= workers
            self._alone_since = None
            return None
        if self._alone_since is None:
            self._alone_since = now
        timeout = self.execution.no_workers_timeout
        if now - self._alone_since < timeout:
            return None
        where = self.execution.scheduler or "the local cluster"
        self.lost = one_line(
            f"{NOT_COMPUTED}no Dask worker in {where} for {timeout:g} s "
            f"(execution.no_workers_timeout); "
            + (f"workers lost: {', '.join(sorted(self._seen))}" if self._seen
               else "no worker joined it"))
        return self.lost

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None


#: how messages name the scheduler's address (the YAML key and the flag)
_SCHEDULER = "execution.scheduler (--scheduler)"
#: what an address that answered, but not as Dask does, is
_OTHER_PROTOCOL = "not a Dask scheduler (it answered in another protocol)"


def check_scheduler(address: str, timeout: float | None = None) -> Any:
    """The Dask security settings to reach the scheduler at ``address`` if it is one, else
    :class:`CaseError` naming why, within ``timeout`` seconds: connection refused (at once),
    no answer within ``timeout`` s (a port that accepts and says nothing: Dask's own connect
    waits for the handshake forever), not a Dask scheduler (it answered in another protocol:
    Dask reads an HTTP reply as the length of a frame, 2.8 EiB, and fails with MemoryError or
    struct.error), a Dask worker, or a ``tls://`` address without Dask's TLS settings.
    ``timeout``: default :data:`CONNECT_TIMEOUT_S`."""
    from distributed.security import Security

    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    security = Security()
    if address.startswith("tls://") and \
            security.get_connection_args("client").get("ssl_context") is None:
        raise CaseError(f"{_SCHEDULER}: {address} is a tls:// address and Dask's TLS settings "
                        "are not configured (distributed.comm.tls.ca-file, "
                        "distributed.comm.tls.client.cert and .key, e.g. "
                        "DASK_DISTRIBUTED__COMM__TLS__CA_FILE=...)")
    deadline = time.monotonic() + timeout
    why = _tcp_refusal(address, timeout) or _handshake(address, security,
                                                      deadline - time.monotonic(), timeout)
    if why is not None:
        raise CaseError(f"{_SCHEDULER}: no Dask scheduler answers at {address}: {why}")
    warn_if_unauthenticated(address)
    return security


class UnauthenticatedClusterWarning(UserWarning):
    """The scheduler is reached without TLS on another machine: whoever can reach it runs
    code in this process's tasks, and sees them."""


def warn_if_unauthenticated(address: str) -> None:
    """One warning line when ``address`` is a plain (``tcp://``, ``ws://``) scheduler that is not
    on this machine (a loopback address or ``localhost``): the cluster runs this process's
    tasks, pickled Python, without authentication (docs/runs.md, "Who may do what")."""
    import ipaddress
    from urllib.parse import urlsplit

    parts = urlsplit(address)
    if parts.scheme not in ("tcp", "ws") or parts.hostname is None:
        return
    host = parts.hostname
    try:
        local = ipaddress.ip_address(host).is_loopback
    except ValueError:  # a name
        local = host == "localhost" or host.endswith(".localhost")
    if not local:
        warnings.warn_explicit(
            f"{_SCHEDULER}: {address} is not this machine and {parts.scheme}:// is not "
            "authenticated: the cluster runs this process's tasks (pickled Python) and anyone "
            "who can reach it can too; use tls:// with Dask's security settings on a network "
            "you do not control", UnauthenticatedClusterWarning, "nsm-continuation", 0)


def _tcp_refusal(address: str, timeout: float) -> str | None:
    """Why a TCP connection to the host and port of ``address`` fails (refused: nothing
    listens there, which Dask's connect would retry for the whole timeout; an unknown host;
    no answer within ``timeout`` s), else None."""
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(address)
    if parts.hostname is None or parts.port is None:
        return None  # not a HOST:PORT address (the schema checks the syntax)
    try:
        with socket.create_connection((parts.hostname, parts.port), timeout=timeout):
            return None
    except ConnectionRefusedError:
        return "connection refused: nothing listens on that port"
    except TimeoutError:
        return f"no answer within {timeout:g} s"
    except OSError as exc:
        return f"cannot connect: {one_line(str(exc))}"


def _handshake(address: str, security: Any, left: float, timeout: float) -> str | None:
    """Dask's handshake with ``address`` and its ``identity``, bounded by ``left`` seconds
    (in a thread of its own: the caller may be inside an event loop, e.g. Jupyter's): why
    it is not a Dask scheduler, else None."""
    import asyncio
    import threading

    from distributed.comm import connect

    async def identity() -> Any:
        comm = await connect(address, timeout=left,
                             **security.get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    outcome: list[Any] = []

    def probe() -> None:
        try:
            outcome.append(asyncio.run(asyncio.wait_for(identity(), max(left, 0.1))))
        except BaseException as exc:  # noqa: BLE001 - every way of failing is named below
            outcome.append(exc)

    thread = threading.Thread(target=probe, name="nsm-scheduler-check", daemon=True)
    thread.start()
    thread.join(max(left, 0.1) + 5.0)  # the wait_for above ends it; 5 s to unwind
    reply = outcome[0] if outcome else TimeoutError()
    if isinstance(reply, TimeoutError):
        return (f"no answer within {timeout:g} s (the port accepts connections but sends no "
                "Dask handshake)")
    if isinstance(reply, OSError):  # closed, reset, or timed out inside Dask's connect
        text = one_line(str(reply))
        return (f"no answer within {timeout:g} s" if "Timed out" in text
                else f"{_OTHER_PROTOCOL}: {text}" if text else _OTHER_PROTOCOL)
    if isinstance(reply, BaseException) or not isinstance(reply, dict):
        return _OTHER_PROTOCOL  # MemoryError, struct.error, a decoding error, ...
    if reply.get("type") == "Worker":
        return "a Dask worker, not the scheduler: give the scheduler's address"
    if reply.get("type") != "Scheduler":
        return _OTHER_PROTOCOL
    return None


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
             done_callback: Callable[[Any], None] | None = None,
             session: DaskSession | None = None) -> None:
    """Wait for every future, calling ``poll`` (the signals) every 0.25 s and
    ``done_callback`` on each future as it finishes. With the ``session``, when its cluster
    has had no worker for too long (:meth:`DaskSession.watch`), the futures still pending are
    cancelled with that reason (their ``result()`` raises it) and the wait ends."""
    from dask.distributed import wait

    pending = set(futures)
    while pending:
        why = None if session is None else session.watch()
        if why is not None:
            for f in pending:
                f.cancel(reason=why)
            return
        try:
            done, pending = wait(list(pending), timeout=0.25, return_when="FIRST_COMPLETED")
        except TimeoutError:  # nothing finished yet: only the signals are polled
            done = set()
        except Exception:  # futures cancelled by a lost scheduler: end with that reason
            why = None if session is None else session.watch()
            if why is None:
                raise
            for f in pending:
                f.cancel(reason=why)
            return
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
            if futures[len(per_piece)].cancelled():  # the cluster was lost (session.watch)
                raise ValueError(f"start: {session.watch() or NOT_COMPUTED + 'cancelled'}")
            result, dt = futures[len(per_piece)].result()  # a piece's error raises here
            t2 = time.perf_counter()
            algorithm.adopt_seed_piece(result)
            t_adopt += time.perf_counter() - t2
            per_piece.append(dt)

    wait_all(futures, poll, adopt_in_order, session)
    if session.lost is not None:  # the search is incomplete: no seeds (a failed start)
        raise ValueError(f"start: {session.lost}")
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
    wait_all([f for fs in futures for f in fs], poll, advance, session)
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
            why = (session.lost if session.lost is not None and any(f.cancelled() for f in fs)
                   else one_line(f"{type(exc).__name__}: {exc}"))
            results.append((None, 0.0, {}, why, None))
    return merge_in_seed_order(algorithm, seeds, results)


def merge_in_seed_order(algorithm: Any, seeds: list[Any],
                        results: list[tuple[Any, ...]]
                        ) -> tuple[list[Branch], list[str], list[float], dict[str, Any]]:
    """The serial loop's rule applied to results computed independently: in seed order, a
    seed that lies on an already accepted branch is skipped; the accepted branches are
    numbered ``0, 1, ...``; a failed task becomes a branch without points whose termination
    names the failure (a reason starting with :data:`NOT_COMPUTED`, as it is). ``results``:
    ``(branch, seconds, counters, error)``, optionally with the
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
            reason = (error if str(error).startswith(NOT_COMPUTED)
                      else f"task failed on a worker: {error}")
            branch = Branch(len(branches), algorithm.label(seed), [], [], {"task": reason})
        elif adopt is not None and rest:
            adopt(branch, rest[0])
        branch.id = len(branches)
        branches.append(branch)
        per_branch.append(dt)
        for k, v in cnt.items():
            if isinstance(v, int | float) and not isinstance(v, bool):
                counters[k] = counters.get(k, 0) + v
    return branches, skipped, per_branch, counters
