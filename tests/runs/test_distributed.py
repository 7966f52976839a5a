"""Branches as Dask tasks (nsm_continuation/runs/execution.py): the same result as a serial run, to
the last digit, on a local cluster of worker processes and on a cluster started as separate
``dask scheduler`` / ``dask worker`` processes; a worker killed mid-run; a failed task.

Oracle: the serial run of the same case (branches, ids, order, every point and every event).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from helpers import CASES

pytest.importorskip("distributed")

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation import cli  # noqa: E402
from nsm_continuation.core.records import Branch  # noqa: E402
from nsm_continuation.runs.execution import merge_in_seed_order  # noqa: E402

#: a frequency-energy plot of a 3-dof chain: 12 independent branches
CASE: dict[str, Any] = {
    "name": "fep3", "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"all": True, "max_subharmonic": 2},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 2.5, "max_points": 60},
    "analysis": {"stability": True},
    "output": {"plots": False, "progress": False},
}


def _wait_for(condition: Any, timeout: float = 120.0) -> None:
    """Poll ``condition`` every 50 ms until it holds (a state, not a guessed sleep: CI
    machines differ in speed)."""
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "condition not reached in time"
        time.sleep(0.05)


def same_branches(a: list[Branch], b: list[Branch]) -> None:
    assert [(x.id, x.label, x.n_points) for x in a] == [(x.id, x.label, x.n_points) for x in b]
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(np.array([p.y for p in x.points]), np.array([p.y for p in y.points]))
        assert [(e.kind, e.detail) for e in x.events] == [(e.kind, e.detail) for e in y.events]
        assert all(np.array_equal(e.point.y, f.point.y) for e, f in zip(x.events, y.events,
                                                                          strict=True))
        assert x.termination == y.termination


@pytest.fixture(scope="module")
def serial() -> Any:
    return nsm.run(CASE)


def test_local_cluster_gives_the_serial_result(serial: Any, monkeypatch: Any) -> None:
    from distributed import Future

    fetches: dict[str, int] = {}
    result = Future.result

    def counted(self: Any, *args: Any, **kwargs: Any) -> Any:
        fetches[self.key] = fetches.get(self.key, 0) + 1
        return result(self, *args, **kwargs)

    monkeypatch.setattr(Future, "result", counted)
    res = nsm.run(CASE, workers=2)
    # each branch crosses from its worker to this process once (progress and merge share it)
    assert len(fetches) == res.run_result.timings["dask_branch_tasks"]
    assert set(fetches.values()) == {1}
    assert len(serial.run_result.branches) >= 10
    same_branches(serial.run_result.branches, res.run_result.branches)
    assert res.run_result.timings["dask_branch_tasks"] >= 10
    # the run records where it was computed
    assert res.run_result.case.execution.workers == 2
    assert serial.run_result.case.execution.workers is None


def test_a_single_branch_starts_no_local_cluster(monkeypatch: Any) -> None:
    """``workers=2`` on a case of one branch (the default case): computed in this process,
    the serial result, no cluster started (nothing to spread; ~1 s saved)."""
    from nsm_continuation.runs import execution

    def no_cluster(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("a local cluster was started for a single branch")

    monkeypatch.setattr(execution, "start_client", no_cluster)
    over = {"output.plots": False, "output.progress": False}
    res = nsm.run(nsm.load_case(cli._default_case_path(), over), workers=2)
    ser = nsm.run(nsm.load_case(cli._default_case_path(), over))
    assert len(res.run_result.branches) == 1
    assert res.run_result.timings["dask_branch_tasks"] == 0
    same_branches(ser.run_result.branches, res.run_result.branches)


def two_transcriticals(**execution: Any) -> Any:
    from oracles.normal_forms import MuParameters, TwoTranscriticals

    return nsm.continuation(TwoTranscriticals(MuParameters()), {}, parameter="mu", min=-0.5,
                            max=1.5, max_points=80, step={"initial": 0.05, "min": 1e-9,
                                                          "max": 0.05},
                            analysis={"branch_switching": {"depth": 2}}, **execution)


def test_diagram_generation_as_tasks_gives_the_serial_tree(monkeypatch: Any) -> None:
    """A bifurcation diagram (``x (mu - x) (1 - mu - x) = 0``, a problem class the registry
    does not know, sent to the workers by reference): its first generation's two switches run
    as Dask tasks on the one cluster of the run; the tree, ids and every point are the
    serial run's, and the switched branches are the closed forms ``x = mu``, ``x = 1 - mu``
    (the second generation's branch point at (1/2, 1/2), switched from branch 1, gives
    branch 2 again: not followed)."""
    from nsm_continuation.runs import execution

    ser = two_transcriticals()
    started: list[Any] = []
    real = execution.start_client
    monkeypatch.setattr(execution, "start_client",
                        lambda ex: started.append(ex) or real(ex))
    res = two_transcriticals(workers=2)
    assert len(started) == 1  # one cluster for the whole run
    run = res.run_result
    assert run.timings["dask_switch_tasks"] == 2  # generation 1; generation 2 has one switch
    assert run.tree == ser.run_result.tree
    same_branches(ser.run_result.branches, run.branches)
    assert len(run.branches) == 3
    x, mu = res.branches[1].y.T
    assert np.max(np.abs(x - mu)) < 1e-12
    x, mu = res.branches[2].y.T
    assert np.max(np.abs(x - (1 - mu))) < 1e-12
    assert [(n["depth"], n["parent"], n["child"]) for n in run.tree] == [
        (1, 0, 1), (1, 0, 2), (2, 1, None), (2, 1, None), (2, 2, None), (2, 2, None)]
    assert [n["status"] for n in run.tree[2:]] == [
        "not followed: the branch born there is branch 2",
        "not followed: the point this branch was born at",
        "not followed: a point already switched",
        "not followed: the point this branch was born at"]


def test_diagram_switches_cut_by_max_branches_as_in_the_serial_walk() -> None:
    """``max_branches: 2`` (the root and one child): the serial walk follows the first
    branch point only; the tasks computed ahead for the second are dropped, the tree and
    branches are the serial run's."""
    from oracles.normal_forms import MuParameters, TwoTranscriticals

    def run(**ex: Any) -> Any:
        return nsm.continuation(
            TwoTranscriticals(MuParameters()), {}, parameter="mu", min=-0.5, max=1.5,
            max_points=80, step={"initial": 0.05, "min": 1e-9, "max": 0.05},
            analysis={"branch_switching": {"depth": 2, "max_branches": 2}}, **ex).run_result

    ser, par = run(), run(workers=2)
    assert par.tree == ser.tree and len(par.branches) == 2
    assert par.tree[1]["status"].startswith("not followed: analysis.branch_switching."
                                            "max_branches = 2")
    same_branches(ser.branches, par.branches)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_cluster_arguments_refused_in_one_line(tmp_path: Path, capsys: Any) -> None:
    """``--workers`` with ``--scheduler``, a malformed address and an address where no
    scheduler answers: one line naming the argument, exit 2, nothing written (the last at
    once: nothing listens on the port, the connection is refused; the client's 10 s timeout
    is for an address that does not answer at all), before any branch is computed."""
    address = f"tcp://127.0.0.1:{_free_port()}"
    for extra, expect in ((["--workers", "2", "--scheduler", address], "not allowed with"),
                          (["--scheduler", "localhost:8786"],
                           "--scheduler: an address such as tcp://HOST:8786"),
                          (["--scheduler", address], "no Dask scheduler answers at")):
        out = tmp_path / "out"
        t0 = time.perf_counter()
        with pytest.raises(SystemExit) as exc:
            sys.exit(cli.main(["run", "--quiet", "--out", str(out), *extra]))
        assert exc.value.code == 2, extra
        assert time.perf_counter() - t0 < 8.0, extra
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and expect in err[0], err
        assert not out.exists()
    with pytest.raises(nsm.CaseError, match="exclude each other"):
        nsm.run(CASE, workers=2, scheduler=address)


def test_without_dask_workers_are_one_line(tmp_path: Path, capsys: Any,
                                           monkeypatch: Any) -> None:
    """Dask not installed (``import dask`` fails): ``--workers`` / ``workers=`` on a case of
    several branches is one line naming the argument and the extra to install, exit 2,
    nothing written."""
    monkeypatch.setitem(sys.modules, "dask", None)
    two = {**CASE, "start": [{"mode": 1}, {"mode": 2}],
           "continuation": {**CASE["continuation"], "max_points": 5}}
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(two))
    out = tmp_path / "out"
    assert cli.main(["run", str(path), "--quiet", "--out", str(out), "--workers", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--workers" in err[0] and "nsm-continuation[dask]" in err[0], err
    assert not out.exists()
    with pytest.raises(nsm.CaseError, match=r"^execution.workers \(workers=\): .*needs Dask"):
        nsm.run(two, workers=2)


def test_a_script_problem_class_is_refused_for_an_existing_cluster() -> None:
    """A problem class defined in the user's script (``__main__``) cannot be imported by the
    workers of an existing cluster: refused in one line before any branch is computed
    (before: each branch failed on the workers with a ``PicklingError``)."""
    from oracles.normal_forms import MuParameters, Transcritical

    mine = type("Mine", (Transcritical,), {"__module__": "__main__", "name": "mine"})
    with pytest.raises(nsm.CaseError, match=r"execution.scheduler: the problem class Mine is "
                                            r"defined in the script \(__main__\)"):
        nsm.continuation(mine(MuParameters()), {}, parameter="mu", min=-0.5, max=0.5,
                         max_points=10, scheduler=f"tcp://127.0.0.1:{_free_port()}")


def test_a_script_without_the_main_guard_gets_one_message(tmp_path: Path) -> None:
    """A script that starts a local cluster at its top level (no ``if __name__ ==
    "__main__":``): each worker process imports the script again; those end quietly and the
    script fails once with the message naming the guard (before: the message three times
    among 15 Dask tracebacks, 550 lines)."""
    script = tmp_path / "no_guard.py"
    script.write_text("import nsm_continuation as nsm\n"
                      f"nsm.run({CASE!r}, workers=2)\n")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300)
    assert proc.returncode == 1
    assert proc.stderr.count("a Python script that starts one must run under "
                             "`if __name__ == \"__main__\":`") == 1, proc.stderr
    assert proc.stderr.count("Traceback") == 1 and len(proc.stderr.splitlines()) < 60


def test_merge_applies_the_serial_rule_and_records_a_failed_task() -> None:
    """In seed order, a seed on an accepted branch is skipped and the ids are renumbered; a
    task that raised is a branch without points whose termination names the failure."""

    class Alg:
        def covered(self, seed: int, branches: list[Branch]) -> bool:
            return seed == 1  # as if seed 1 lay on branch 0

        def label(self, seed: int) -> str:
            return f"seed {seed}"

    def br(i: int) -> Branch:
        return Branch(i, f"seed {i}", [], [], {"forward": "max_points"})

    results = [(br(0), 1.0, {"n": 2}, None), (br(1), 1.0, {"n": 3}, None),
               (None, 0.0, {}, "RuntimeError: boom"), (br(3), 2.0, {"n": 5}, None)]
    branches, skipped, per, counters = merge_in_seed_order(Alg(), [0, 1, 2, 3], results)
    assert [b.id for b in branches] == [0, 1, 2] and skipped == ["seed 1"]
    assert branches[1].termination == {"task": "task failed on a worker: RuntimeError: boom"}
    assert branches[2].label == "seed 3" and counters == {"n": 7} and per == [1.0, 0.0, 2.0]


def test_cli_workers_flag_validated(tmp_path: Path, capsys: Any) -> None:
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(CASE))
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", str(path), "--workers", "0", "--out", str(tmp_path / "o")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--workers" in err
    assert not (tmp_path / "o").exists()
    bad = {**CASE, "execution": {"scheduler": "localhost:8786"}}
    path.write_text(yaml.safe_dump(bad))
    assert cli.main(["validate", str(path)]) == 2
    assert capsys.readouterr().err.startswith("error: execution.scheduler")


# --------------------------------------------------------------------------- separate processes
def _dask() -> str:
    exe = shutil.which("dask")
    if exe is None:
        pytest.skip("the dask command is not installed")
    return exe


@pytest.fixture()
def cluster(tmp_path: Path):
    """``dask scheduler`` and two ``dask worker`` processes on localhost."""
    dask = _dask()
    sched_file = tmp_path / "scheduler.json"
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    procs = [subprocess.Popen([dask, "scheduler", "--scheduler-file", str(sched_file),
                               "--port", "0", "--no-dashboard", "--host", "127.0.0.1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)]
    for _ in range(60):
        if sched_file.exists() and sched_file.stat().st_size:
            break
        time.sleep(0.25)
    address = json.loads(sched_file.read_text())["address"]
    for _ in range(2):
        procs.append(subprocess.Popen([dask, "worker", address, "--nthreads", "1",
                                       "--no-dashboard", "--no-nanny"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      env=env))
    from dask.distributed import Client

    with Client(address, timeout="20s") as client:
        client.wait_for_workers(2, timeout=60)
    yield address, procs
    for p in procs:
        p.kill()
        p.wait()


@pytest.fixture(scope="module")
def pd_base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The impact oscillator's run through its period doubling
    (``yaml_cases/impact_oscillator_period_doubling.yaml``), saved once for the restarts
    below, which only read it."""
    base = nsm.run(str(CASES / "impact_oscillator_period_doubling.yaml"),
                   {"output.plots": False, "output.progress": False})
    return base.save(tmp_path_factory.mktemp("pd") / "base", plots=False)


def _cli_run(case: dict[str, Any], out: Path, *extra: str) -> dict[str, Any]:
    path = out.parent / f"{out.name}.yaml"
    path.write_text(yaml.safe_dump(case))
    proc = subprocess.run([sys.executable, "-m", "nsm_continuation.cli", "run", str(path),
                           "--out", str(out), "--quiet", *extra],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads((out / "report.json").read_text())


def _comparable(report: dict[str, Any]) -> Any:
    return [{k: v for k, v in b.items()} for b in report["branches"]]


def test_scheduler_and_worker_processes_give_the_serial_outputs(cluster: Any,
                                                               tmp_path: Path) -> None:
    """``--scheduler`` on a cluster of separate processes: report.json's branches and
    every CSV are byte-identical to the serial run's."""
    address, _ = cluster
    ser = _cli_run(CASE, tmp_path / "serial")
    dist = _cli_run(CASE, tmp_path / "dask", "--scheduler", address)
    assert _comparable(ser) == _comparable(dist)
    for b in ser["branches"]:
        name = b["csv"]
        assert (tmp_path / "serial" / name).read_bytes() == (tmp_path / "dask" / name).read_bytes()


def test_a_switch_restart_on_the_scheduler_is_the_serial_branch(cluster: Any, pd_base: Path,
                                                               tmp_path: Path) -> None:
    """A restart's single branch is sent to an existing cluster (``--scheduler``): the
    worker must continue the restart's own problem (the period-2 problem of a switch at a
    period doubling, not the registered period-1 one, whose branch would start from omega =
    1.0949697 instead of 1.0949765). The CSV is byte-identical to the serial run's."""
    address, _ = cluster
    case = {"name": "switch", "start": {"from": str(pd_base),
                                        "event": {"kind": "period_doubling", "index": 0},
                                        "switch": True},
            "continuation": {"max_points": 10}, "output": {"plots": False, "progress": False}}
    ser = _cli_run(case, tmp_path / "serial")
    dist = _cli_run(case, tmp_path / "dask", "--scheduler", address)
    assert dist["timings"]["dask_branch_tasks"] == 1
    assert _comparable(ser) == _comparable(dist)
    assert (tmp_path / "serial" / "branch_0.csv").read_bytes() == \
        (tmp_path / "dask" / "branch_0.csv").read_bytes()


def test_a_two_parameter_curve_is_two_tasks_with_the_serial_result(pd_base: Path) -> None:
    """A period-doubling curve (``start.curve``) is followed both ways from its first point:
    with ``workers=2`` the two halves are two tasks (the restart's curve problem rebuilt on
    each worker), joined into the serial branch: every point, event, termination, the
    branch's counts of base runs and the run's counters."""
    case = nsm.load_case({
        "name": "pd_curve", "start": {"from": str(pd_base), "curve": "period_doubling",
                                      "event": {"kind": "period_doubling", "index": 0}},
        "continuation": {"parameter": "gap", "min": -0.7, "max": -0.3, "max_points": 4,
                         "step": {"initial": 0.01, "min": 1e-7, "max": 0.05}},
        "output": {"plots": False, "progress": False}})
    ser, par = nsm.run(case).run_result, nsm.run(case, workers=2).run_result
    assert par.timings["dask_branch_tasks"] == 2
    same_branches(ser.branches, par.branches)
    assert ser.branches[0].info == par.branches[0].info
    assert set(ser.branches[0].termination) == {"forward", "backward"}
    for key in ("base_continuations", "base_points", "n_points"):
        assert ser.timings[key] == par.timings[key], key


def test_a_worker_killed_mid_run_changes_nothing(cluster: Any, tmp_path: Path) -> None:
    """One of the two workers is killed while the run's tasks are running: Dask runs its
    tasks again on the other, and the outputs are the serial run's."""
    address, procs = cluster
    case = {**CASE, "continuation": {**CASE["continuation"], "max_points": 150}}
    ser = _cli_run(case, tmp_path / "serial")
    path = tmp_path / "dask.yaml"
    path.write_text(yaml.safe_dump(case))
    run = subprocess.Popen([sys.executable, "-m", "nsm_continuation.cli", "run", str(path),
                            "--out", str(tmp_path / "dask"), "--quiet", "--scheduler", address],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    from dask.distributed import Client

    with Client(address, timeout="20s") as client:  # kill while both workers hold tasks
        _wait_for(lambda: sum(bool(t) for t in client.processing().values()) >= 2
                  or run.poll() is not None)
    assert run.poll() is None, "the run ended before the worker could be killed"
    procs[1].send_signal(signal.SIGKILL)
    out, err = run.communicate(timeout=600)
    assert run.returncode == 0, err
    dist = json.loads((tmp_path / "dask" / "report.json").read_text())
    assert _comparable(ser) == _comparable(dist)


def test_sigint_cancels_the_tasks_and_writes_nothing(tmp_path: Path) -> None:
    """SIGINT during a distributed run: exit 130, the tasks cancelled, no output folder."""
    # a run of ~20 s serially here (30 branches: 8 dofs, subharmonics to 6, 3000 points per
    # branch), long after the workers are busy
    case = {**CASE, "parameters": {**CASE["parameters"], "chain": {"dofs": 8, "mass": 1.0,
                                                                   "stiffness": 1.0}},
            "start": {"all": True, "max_subharmonic": 6},
            "continuation": {**CASE["continuation"], "max_points": 3000}}
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    run = subprocess.Popen([sys.executable, "-m", "nsm_continuation.cli", "run", str(path),
                            "--out", str(tmp_path / "out"), "--quiet", "--workers", "2"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    import psutil

    # signal once the local cluster's workers have computed for a while: their CPU time
    # (load-independent) past starting and importing (~1-2 s each), far from the ~21 s of
    # the whole run
    parent = psutil.Process(run.pid)

    def workers_cpu() -> float:
        total = 0.0
        for p in parent.children(recursive=True):
            try:
                t = p.cpu_times()
                total += t.user + t.system
            except psutil.Error:
                pass
        return total

    _wait_for(lambda: run.poll() is not None or workers_cpu() >= 7.0)
    assert run.poll() is None, "the run ended before the signal"
    run.send_signal(signal.SIGINT)
    _, err = run.communicate(timeout=120)
    assert run.returncode == 130, err
    assert not (tmp_path / "out").exists()
    assert not any(p.name.startswith(".out") for p in tmp_path.iterdir())
