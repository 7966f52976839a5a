"""Dask's faults end in a bounded, named outcome (nsm_continuation/runs/execution.py and the
``execution:`` block of nsm_continuation/cases/schema.py): a malformed scheduler address is
refused alike by ``validate`` and ``run``; an address that never answers, or answers in
another protocol, is refused in one line within the timeout; a cluster that loses every
worker ends the branches still waiting with the reason; a local cluster larger than the
machine is refused before computing; SIGINT while the local cluster starts prints one line.

Oracles: real local sockets (a server that accepts and never answers, an HTTP server, one
that sends random bytes), a real LocalCluster whose workers are closed mid-run, the machine's
limits set by the test.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("distributed")

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation import cli  # noqa: E402
from nsm_continuation.cases import schema  # noqa: E402
from nsm_continuation.runs import execution  # noqa: E402

#: a frequency-energy plot of a 3-dof chain: 12 independent branches
CASE: dict[str, Any] = {
    "name": "fep3", "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"all": True, "max_subharmonic": 2},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 2.5, "max_points": 60},
    "output": {"plots": False, "progress": False},
}


def _cli(capsys: Any, *argv: str) -> tuple[int, list[str]]:
    """``nsm-continuation argv``: its exit status and the lines of its stderr."""
    code = cli.main(list(argv))
    return code, capsys.readouterr().err.strip().splitlines()


class _Server:
    """A TCP server on localhost in a thread: each connection is answered by ``reply(conn)``
    (which may say nothing and hold it open); the port in :attr:`address`."""

    def __init__(self, reply: Any) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.reply = reply
        self.held: list[socket.socket] = []
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:  # closed
                return
            self.held.append(conn)
            try:
                self.reply(conn)
            except OSError:
                pass

    def close(self) -> None:
        self.sock.close()
        for c in self.held:
            c.close()


@pytest.fixture()
def silent() -> Iterator[_Server]:
    """A port that accepts TCP connections and never says anything."""
    server = _Server(lambda conn: None)
    yield server
    server.close()


@pytest.fixture()
def http_address() -> Iterator[str]:
    """A server that speaks HTTP (another protocol): it answers the first bytes it receives,
    Dask's handshake, with an HTTP error, as an HTTP server answers a malformed request."""

    def reply(conn: socket.socket) -> None:
        conn.recv(1)
        conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n"
                     b"Connection: close\r\n\r\n")

    server = _Server(reply)
    yield server.address
    server.close()


# ------------------------------------------------------------------------- address syntax
BAD_ADDRESSES = ["tcp://127.0.0.1:99999", "tcp://127.0.0.1", "tcp://127.0.0.1:0",
                 "tcp://:8786", "tcp://host:port", "inproc://scheduler", "ucx://127.0.0.1:8786",
                 "tcp://127.0.0.1:8786/path", "tcp://127.0.0.1:8786?x=1", "localhost:8786"]


@pytest.mark.parametrize("address", BAD_ADDRESSES)
def test_a_malformed_address_is_refused_alike_by_validate_and_run(
        address: str, tmp_path: Path, capsys: Any) -> None:
    """A port out of range, no port, an ``inproc://`` address (one process's own), ``ucx://``
    without its package, anything after HOST:PORT: ``validate`` refuses it (before: valid)
    and ``run`` too, in one line naming ``execution.scheduler`` / ``--scheduler``, exit 2,
    nothing written (before: a traceback, exit 1)."""
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump({**CASE, "execution": {"scheduler": address}}))
    out = tmp_path / "out"
    code, err = _cli(capsys, "validate", str(path), "--out", str(out))
    assert code == 2 and len(err) == 1 and err[0].startswith("error: execution.scheduler: "), err
    code, err = _cli(capsys, "run", str(path), "--quiet", "--out", str(out))
    assert code == 2 and len(err) == 1 and err[0].startswith("error: execution.scheduler: "), err
    path.write_text(yaml.safe_dump(CASE))
    code, err = _cli(capsys, "run", str(path), "--quiet", "--out", str(out),
                     "--scheduler", address)
    assert code == 2 and len(err) == 1 and err[0].startswith("error: --scheduler: "), err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml"]


@settings(max_examples=60, deadline=None)
@given(scheme=st.sampled_from(["tcp", "tls", "ws", "wss"]),
       host=st.sampled_from(["127.0.0.1", "localhost", "node-3.cluster", "[::1]"]),
       port=st.integers(min_value=-10, max_value=200_000))
def test_an_address_is_valid_exactly_when_its_port_is(scheme: str, host: str,
                                                      port: int) -> None:
    """Over protocols, hosts and ports: ``execution.scheduler`` is accepted exactly when the
    port is in 1..65535 (``tls://`` included: its settings are checked when connecting)."""
    address = f"{scheme}://{host}:{port}"
    if 1 <= port <= 65535:
        assert schema.ExecutionSpec(scheduler=address).scheduler == address
    else:
        with pytest.raises(ValueError, match="port"):
            schema.ExecutionSpec(scheduler=address)


# ------------------------------------------------------------------- bounded connection
def test_a_port_that_never_answers_is_refused_within_the_timeout(
        silent: _Server, tmp_path: Path, capsys: Any, monkeypatch: Any) -> None:
    """A port that accepts the connection and says nothing: refused once the connection
    timeout has passed, in one line naming the cause, exit 2, nothing written (before: the
    run waited forever, Dask's handshake has no timeout). The timeout is 10 s; 2 s here."""
    monkeypatch.setattr(execution, "CONNECT_TIMEOUT_S", 2.0)
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(CASE))
    out = tmp_path / "out"
    t0 = time.monotonic()
    code, err = _cli(capsys, "run", str(path), "--quiet", "--out", str(out),
                     "--scheduler", silent.address)
    assert time.monotonic() - t0 < 15.0
    assert code == 2 and len(err) == 1, err
    assert err[0] == (f"error: execution.scheduler (--scheduler): no Dask scheduler answers at "
                      f"{silent.address}: no answer within 2 s (the port accepts connections but "
                      "sends no Dask handshake)")
    assert not out.exists()


def test_an_http_server_is_not_a_dask_scheduler(http_address: str, tmp_path: Path,
                                                capsys: Any) -> None:
    """An HTTP server at the address: one line, exit 2, nothing written (before: Dask read
    the HTTP reply as a frame length and failed with ``MemoryError: Unable to allocate 2.82
    EiB``, exit 1)."""
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump({**CASE, "execution": {"scheduler": http_address}}))
    code, err = _cli(capsys, "run", str(path), "--quiet", "--out", str(tmp_path / "out"))
    assert code == 2 and len(err) == 1, err
    assert "not a Dask scheduler (it answered in another protocol)" in err[0]
    assert err[0].startswith("error: execution.scheduler (--scheduler): ")
    assert not (tmp_path / "out").exists()


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(payload=st.binary(min_size=1, max_size=80), hold=st.booleans())
def test_any_bytes_at_the_address_end_in_one_named_refusal(payload: bytes,
                                                          hold: bool) -> None:
    """A server that sends any bytes first (then closes, or holds the connection): a
    :class:`CaseError` naming the address and a cause, within the timeout (before:
    ``MemoryError``, ``struct.error`` or a wait without end)."""

    def reply(conn: socket.socket) -> None:
        conn.sendall(payload)
        if not hold:
            conn.close()

    server = _Server(reply)
    try:
        t0 = time.monotonic()
        with pytest.raises(nsm.CaseError) as exc:
            execution.check_scheduler(server.address, timeout=1.0)
        assert time.monotonic() - t0 < 8.0
    finally:
        server.close()
    text = str(exc.value)
    assert "\n" not in text and f"no Dask scheduler answers at {server.address}: " in text
    assert ("not a Dask scheduler" in text or "no answer within 1 s" in text), text


def test_a_tls_address_without_tls_settings_is_refused_in_one_line(tmp_path: Path,
                                                                  capsys: Any) -> None:
    """``tls://`` is valid syntax, but reaching it needs Dask's TLS settings: without them,
    one line saying so (before: a ``TypeError`` traceback from Dask's TLS connector)."""
    import dask

    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(CASE))
    with dask.config.set({"distributed.comm.tls.ca-file": None,
                          "distributed.comm.tls.client.cert": None,
                          "distributed.comm.tls.client.key": None}):
        code, err = _cli(capsys, "run", str(path), "--quiet", "--out", str(tmp_path / "out"),
                         "--scheduler", "tls://127.0.0.1:8786")
    assert code == 2 and len(err) == 1, err
    assert "tls:// address and Dask's TLS settings are not configured" in err[0]
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------------- lost workers
def _wait_for_a_finished_task(client: Any, run: threading.Thread) -> None:
    """Until the scheduler holds one finished task (or the run has ended)."""

    def finished() -> int:
        return int(client.run_on_scheduler(lambda dask_scheduler: sum(
            ts.state == "memory" for ts in dask_scheduler.tasks.values())))

    end = time.monotonic() + 120
    while finished() < 1 and run.is_alive():
        assert time.monotonic() < end, "no task finished"
        time.sleep(0.05)


def test_a_cluster_that_loses_every_worker_ends_the_waiting_branches(tmp_path: Path) -> None:
    """An existing cluster (a LocalCluster here) whose only worker is closed mid-run: after
    ``execution.no_workers_timeout`` (1 s here) the branches not computed end with a reason
    naming the lost worker, those computed before are kept, and the run returns (before: it
    waited forever, without a word). A worker's address is refused as a scheduler's."""
    from dask.distributed import Client, LocalCluster

    case = {**CASE, "continuation": {**CASE["continuation"], "max_points": 150},
            "execution": {"no_workers_timeout": 1}}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0", silence_logs=40) as cluster, \
            Client(cluster) as client:
        worker = next(iter(client.scheduler_info()["workers"]))
        with pytest.raises(nsm.CaseError, match="a Dask worker, not the scheduler"):
            execution.check_scheduler(worker)
        result: list[Any] = []
        run = threading.Thread(target=lambda: result.append(
            nsm.run(case, scheduler=cluster.scheduler_address)), daemon=True)
        run.start()

        _wait_for_a_finished_task(client, run)
        assert run.is_alive(), "the run ended before its worker could be closed"
        cluster.scale(0)
        run.join(60)
        assert not run.is_alive(), "the run still waits for a worker"
    branches = result[0].run_result.branches
    done = [b for b in branches if b.points]
    lost = [b for b in branches if not b.points]
    assert done and lost, [b.termination for b in branches]
    for b in lost:
        assert b.termination == {"task": (
            f"not computed: no Dask worker in {cluster.scheduler_address} for 1 s "
            f"(execution.no_workers_timeout); workers lost: {worker}")}


def test_a_scheduler_lost_mid_run_ends_the_waiting_branches_at_once(tmp_path: Path) -> None:
    """An existing cluster whose scheduler goes away mid-run (closed here): the branches not
    computed end with one reason naming the lost connection, those computed before are kept,
    and the run returns well before Dask's own reconnection attempts would have cancelled
    everything (before: an ``internal error: FuturesCancelledError`` with Dask's tracebacks)."""
    from dask.distributed import Client, LocalCluster

    case = {**CASE, "continuation": {**CASE["continuation"], "max_points": 150}}
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=40)
    address = cluster.scheduler_address
    result: list[Any] = []
    run = threading.Thread(target=lambda: result.append(nsm.run(case, scheduler=address)),
                           daemon=True)
    with Client(cluster) as client:
        run.start()

        _wait_for_a_finished_task(client, run)
        assert run.is_alive(), "the run ended before its scheduler could be closed"
    t0 = time.monotonic()
    cluster.close()
    run.join(60)
    assert not run.is_alive(), "the run still waits for its scheduler"
    assert time.monotonic() - t0 < 30
    branches = result[0].run_result.branches
    done = [b for b in branches if b.points]
    lost = [b for b in branches if not b.points]
    assert done and lost, [b.termination for b in branches]
    for b in lost:
        (why,) = b.termination.values()
        assert why.startswith(f"not computed: the connection to the Dask scheduler of {address} "
                              "was lost during the run"), why


def test_no_workers_timeout_is_a_positive_number_of_seconds(tmp_path: Path,
                                                            capsys: Any) -> None:
    """``execution.no_workers_timeout``: refused in one line when not a positive number."""
    path = tmp_path / "case.yaml"
    for bad in (0, -1, "30s", float("inf")):
        path.write_text(yaml.safe_dump({**CASE, "execution": {"no_workers_timeout": bad}}))
        code, err = _cli(capsys, "validate", str(path))
        assert code == 2 and len(err) == 1, err
        assert err[0].startswith("error: execution.no_workers_timeout"), err


# ---------------------------------------------------------------------- worker limits
@settings(max_examples=80, deadline=None)
@given(cores=st.integers(1, 64), gb=st.one_of(st.none(), st.floats(0.1, 512.0)),
       n=st.integers(1, 1024))
def test_local_workers_are_bounded_by_the_cores_and_the_memory(
        cores: int, gb: float | None, n: int) -> None:
    """``execution.workers`` (and ``--workers``, ``workers=``) is refused above 4 per usable
    core and above one per 0.5 GB of available memory, the message naming both; accepted
    at or below (available memory unknown: the cores alone)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(schema, "usable_cores", lambda: cores)
        mp.setattr(schema, "available_memory_gb", lambda: gb)
        limit = min(4 * cores, 4 * cores if gb is None else max(1, int(gb / 0.5)))
        if n <= limit:
            assert schema.ExecutionSpec(workers=n).workers == n
        else:
            with pytest.raises(ValueError) as exc:
                schema.ExecutionSpec(workers=n)
            text = str(exc.value)
            assert f"at most {limit} (4 per usable core, {cores} cores: at most " \
                   f"{4 * cores};" in text
            assert gb is None or f"0.5 GB of the {gb:.1f} GB of available memory each" in text


def test_a_thousand_workers_are_refused_before_computing(tmp_path: Path, capsys: Any,
                                                         monkeypatch: Any) -> None:
    """``--workers 1000`` on a 2-core machine with 23 GB available: refused in one line
    naming ``--workers`` and both limits, exit 2, nothing written, no cluster started
    (before: accepted, and 1000 worker processes started spawning); ``validate`` refuses
    ``execution.workers: 1000`` alike."""
    monkeypatch.setattr(schema, "usable_cores", lambda: 2)
    monkeypatch.setattr(schema, "available_memory_gb", lambda: 23.0)
    started: list[Any] = []
    monkeypatch.setattr(execution, "start_client", lambda *a: started.append(a))
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(CASE))
    code, err = _cli(capsys, "run", str(path), "--quiet", "--out", str(tmp_path / "out"),
                     "--workers", "1000")
    assert code == 2 and err == [
        "error: --workers: 1000 local workers are more than this machine runs: at most 8 "
        "(4 per usable core, 2 cores: at most 8; 0.5 GB of the 23.0 GB of available memory "
        "each: at most 46)"]
    assert not started and not (tmp_path / "out").exists()
    path.write_text(yaml.safe_dump({**CASE, "execution": {"workers": 1000}}))
    code, err = _cli(capsys, "validate", str(path))
    assert code == 2 and len(err) == 1 and err[0].startswith("error: execution.workers: 1000")


# ------------------------------------------------------------------- SIGINT at start-up
@pytest.mark.parametrize("processes", [2, 3])
def test_sigint_while_the_local_cluster_starts_prints_one_line(processes: int,
                                                               tmp_path: Path) -> None:
    """SIGINT while the local cluster starts (once it has started ``processes`` processes:
    the worker processes being spawned): exit 130, the one line "interrupted: ...", no
    traceback (before: 30-70 lines of Dask tracebacks after it), no worker process left
    behind, nothing written."""
    import signal

    import psutil

    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(CASE))
    run = subprocess.Popen([sys.executable, "-m", "nsm_continuation.cli", "run", str(path),
                            "--out", str(tmp_path / "out"), "--quiet", "--workers", "2"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    parent = psutil.Process(run.pid)
    end = time.monotonic() + 120
    while len(parent.children(recursive=True)) < processes:  # the cluster starts them
        assert run.poll() is None and time.monotonic() < end, "no cluster started"
        time.sleep(0.01)
    children = parent.children(recursive=True)
    run.send_signal(signal.SIGINT)
    _, err = run.communicate(timeout=120)
    assert run.returncode == 130, err
    assert err.strip().splitlines() == [
        "interrupted: nothing written (any previous result is intact)"], err
    psutil.wait_procs(children, timeout=10)
    assert not [c for c in children if c.is_running() and c.status() != psutil.STATUS_ZOMBIE]
    assert not (tmp_path / "out").exists()
