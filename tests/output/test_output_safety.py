"""The output policy (nsm_continuation.output.folders): a run never deletes or overwrites a file it
did
not write, refuses an unusable location before computing, and leaves nothing partial behind
when it fails or is interrupted."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from helpers import CASES

from nsm_continuation import cli
from nsm_continuation.cases.saved_runs import MARKER
from nsm_continuation.output.folders import lock_text
from nsm_continuation.runs import runner as run_module

# the default chain, cut short: a run takes well under a second
CASE = {
    "name": "safety",
    "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 15},
    "output": {"plots": False, "progress": False},
}


def _case(tmp_path: Path, **changes: object) -> Path:
    data = json.loads(json.dumps(CASE))
    data.update(changes)
    p = tmp_path / "case.yaml"
    p.write_text(yaml.safe_dump(data))
    return p


def _snapshot(d: Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _forbid_compute(monkeypatch) -> None:
    def boom(*a, **k):
        raise AssertionError("the computation started")

    monkeypatch.setattr(run_module, "run_case", boom)


@pytest.fixture
def no_compute(monkeypatch):
    """Fail the test if the computation starts (refusals must come before it)."""
    _forbid_compute(monkeypatch)


def _run(argv: list[str], capsys) -> tuple[int, str]:
    code = cli.main(["run", *argv, "--quiet"])
    return code, capsys.readouterr().err


def test_existing_folder_with_user_files_is_refused_untouched(tmp_path, capsys, no_compute):
    user = tmp_path / "thesis"
    (user / "chapter").mkdir(parents=True)
    (user / "notes.txt").write_text("years of work")
    (user / "chapter" / "fig.png").write_bytes(b"\x89PNG")
    case = _case(tmp_path)
    before = _snapshot(tmp_path)
    code, err = _run([str(case), "--out", str(user)], capsys)
    assert code == 2
    assert err.startswith("error: output:") and len(err.strip().splitlines()) == 1
    assert "did not write" in err
    # nothing changed, nothing added (no temp folder, no lock) ...
    assert _snapshot(tmp_path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "thesis"]
    # ... even when the user asks to overwrite: these are not files of a previous run
    code, err = _run([str(case), "--out", str(user), "--overwrite"], capsys)
    assert code == 2 and _snapshot(tmp_path) == before


def test_out_naming_an_existing_file_is_refused(tmp_path, capsys, no_compute):
    f = tmp_path / "results.dat"
    f.write_text("data")
    code, err = _run([str(_case(tmp_path)), "--out", str(f)], capsys)
    assert code == 2 and "not a directory" in err
    assert f.read_text() == "data"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "results.dat"]


@pytest.mark.parametrize("name", ["/abs/path", ".", "..", "", "../../x", "a/b", "x" * 300,
                                  ".hidden/../y"])
def test_name_is_a_folder_name_never_a_path(tmp_path, capsys, monkeypatch, name, no_compute):
    monkeypatch.chdir(tmp_path)
    code, err = _run([str(_case(tmp_path, name=name))], capsys)
    assert code == 2
    assert err.startswith("error: name:") and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml"]


def test_rerun_needs_overwrite_which_replaces_only_our_files(tmp_path, capsys):
    case = _case(tmp_path)
    out = tmp_path / "out"
    assert _run([str(case), "--out", str(out)], capsys)[0] == 0
    marker = json.loads((out / MARKER).read_text())
    assert marker["tool"] == "nsm-continuation"
    assert set(marker["files"]) == {"branch_0.csv", "report.json", "report.md"}  # + SHA-256
    first = _snapshot(out)
    # a second run refuses to replace the first one silently
    code, err = _run([str(case), "--out", str(out)], capsys)
    assert code == 2 and "--overwrite" in err
    assert _snapshot(out) == first
    # the user adds a file of their own into the run folder; --overwrite keeps it
    (out / "my_analysis.py").write_text("print(1)")
    old_csv = (out / "branch_0.csv").read_text()
    case2 = _case(tmp_path, continuation={**CASE["continuation"], "max_points": 8})
    assert _run([str(case2), "--out", str(out), "--overwrite"], capsys)[0] == 0
    assert (out / "my_analysis.py").read_text() == "print(1)"
    assert (out / "branch_0.csv").read_text() != old_csv  # the new result
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "out"]


def test_overwrite_never_replaces_a_user_file_with_an_output_name(tmp_path, capsys):
    out = tmp_path / "out"
    no_plots = _case(tmp_path)
    assert _run([str(no_plots), "--out", str(out)], capsys)[0] == 0
    # fep.png was not written by the first run (plots off): this one is the user's
    (out / "fep.png").write_bytes(b"mine")
    before = _snapshot(out)
    plots = _case(tmp_path, output={"plots": True, "progress": False})
    code, err = _run([str(plots), "--out", str(out), "--overwrite"], capsys)
    assert code == 2 and "fep.png" in err
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "out"]


def test_if_exists_new_writes_a_numbered_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = _case(tmp_path, output={"plots": False, "progress": False, "if_exists": "new"})
    for _ in range(3):
        assert _run([str(case)], capsys)[0] == 0
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [
        "safety", "safety-2", "safety-3"]


def test_ordinary_permissions(tmp_path, capsys):
    old = os.umask(0o022)
    try:
        out = tmp_path / "out"
        assert _run([str(_case(tmp_path)), "--out", str(out)], capsys)[0] == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o755
    for f in out.iterdir():
        assert stat.S_IMODE(f.stat().st_mode) == 0o644, f.name


@pytest.mark.parametrize("where", ["parent_is_file", "proc", "long_name", "disk_full"])
def test_unusable_location_refused_before_computing(tmp_path, capsys, monkeypatch, where,
                                                    no_compute):
    case = _case(tmp_path)
    if where == "parent_is_file":
        (tmp_path / "afile").write_text("x")
        out = tmp_path / "afile" / "out"
    elif where == "proc":
        out = Path("/proc/nsm_out")
    elif where == "long_name":
        out = tmp_path / ("x" * 300)
    else:
        import shutil
        from collections import namedtuple

        usage = namedtuple("usage", "total used free")
        monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(10**9, 10**9, 1000))
        out = tmp_path / "out"
    before = _snapshot(tmp_path)
    code, err = _run([str(case), "--out", str(out)], capsys)
    assert code == 2, err
    assert err.startswith("error: output:") and len(err.strip().splitlines()) == 1
    assert _snapshot(tmp_path) == before
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


def test_concurrent_run_is_refused_and_stale_lock_taken_over(tmp_path, capsys, no_compute):
    out = tmp_path / "out"
    lock = tmp_path / ".out.lock"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        lock.write_text(lock_text(sleeper.pid))
        code, err = _run([str(_case(tmp_path)), "--out", str(out)], capsys)
        assert code == 2 and f"pid {sleeper.pid}" in err
        assert lock.read_text() == lock_text(sleeper.pid) and not out.exists()
    finally:
        sleeper.kill()
        sleeper.wait()
    # the process holding the lock is gone: the lock is stale and taken over (the computation
    # then starts, which the no_compute fixture turns into a bug report, exit 1)
    code, err = _run([str(_case(tmp_path)), "--out", str(out)], capsys)
    assert code == 1 and "the computation started" in err
    assert not lock.exists() and not out.exists()
    for f in Path(err.rsplit("traceback in ", 1)[1].strip()).parent.glob(
            "nsm-continuation-crash-*.txt"):
        f.unlink()


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signal_mid_run_leaves_previous_result_intact(tmp_path, sig, code):
    out = tmp_path / "out"
    quick = _case(tmp_path)
    assert cli.main(["run", str(quick), "--out", str(out), "--quiet"]) == 0
    before = _snapshot(out)
    # a long run (the full frequency-energy plot), interrupted while it computes
    slow = CASES / "ndof_fig3_2_fep.yaml"
    proc = subprocess.Popen(
        [sys.executable, "-m", "nsm_continuation.cli", "run", str(slow), "--out", str(out),
         "--overwrite", "--quiet", "--set", "output.progress=false"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # a shell's background job inherits SIGINT ignored: restore what a terminal gives
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.time()
    while not any(p.name.startswith(".out.tmp-") for p in tmp_path.iterdir()):
        assert proc.poll() is None, proc.communicate()
        assert time.time() - t0 < 60
        time.sleep(0.05)
    time.sleep(0.5)  # inside the computation
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "out"]


def _two_runs(tmp_path: Path, capsys) -> tuple[Path, Path]:
    case = _case(tmp_path)
    out = tmp_path / "out"
    assert _run([str(case), "--out", str(out)], capsys)[0] == 0
    return case, out


@pytest.mark.parametrize("tamper", ["edited", "replaced_by_dir", "listed_in_marker", "symlink"])
def test_overwrite_never_removes_what_the_user_changed_or_added(tmp_path, capsys, tamper,
                                                                 monkeypatch):
    case, out = _two_runs(tmp_path, capsys)
    _forbid_compute(monkeypatch)  # the refusal must come before computing
    if tamper == "edited":  # the user annotated the report of the previous run
        (out / "report.md").write_text("my notes")
    elif tamper == "replaced_by_dir":  # a folder of theirs where a run's file was
        (out / "report.md").unlink()
        (out / "report.md").mkdir()
        (out / "report.md" / "data.txt").write_text("precious")
    elif tamper == "listed_in_marker":  # a marker edited to list the user's files
        (out / "notes.txt").write_text("precious")
        marker = json.loads((out / MARKER).read_text())
        marker["files"]["notes.txt"] = "0" * 64
        (out / MARKER).write_text(json.dumps(marker))
    else:
        (out / "branch_0.csv").unlink()
        (out / "branch_0.csv").symlink_to(tmp_path / "case.yaml")
    before = _snapshot(tmp_path)
    code, err = _run([str(case), "--out", str(out), "--overwrite"], capsys)
    assert code == 2 and err.startswith("error: output:"), err
    assert _snapshot(tmp_path) == before  # refused before computing, nothing touched


def test_signal_during_the_final_move_is_held_until_it_is_complete(tmp_path, capsys,
                                                                   monkeypatch):
    import nsm_continuation.output.folders as output

    case, out = _two_runs(tmp_path, capsys)
    real = os.replace
    calls = []

    def replace_and_interrupt(a, b):
        calls.append(b)
        if len(calls) == 2:  # in the middle of swapping the files
            os.kill(os.getpid(), signal.SIGINT)
        return real(a, b)

    monkeypatch.setattr(output.os, "replace", replace_and_interrupt)
    code, err = _run([str(case), "--out", str(out), "--overwrite"], capsys)
    assert len(calls) > 2
    assert code == 130 and "complete" in err
    # the new result is whole: every file the marker lists is there, byte for byte
    assert output.previous_run_files(out).keys() == {"branch_0.csv", "report.json", "report.md"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "out"]


def test_validate_checks_where_the_run_would_write(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = _case(tmp_path)
    (tmp_path / "runs").write_text("a file where the runs folder would be")
    assert cli.main(["validate", str(case)]) == 2
    assert capsys.readouterr().err.startswith("error: output:")
    assert cli.main(["validate", str(case), "--out", str(tmp_path / "elsewhere")]) == 0
    assert not (tmp_path / "elsewhere").exists()


@pytest.mark.parametrize("where", ["here", "child"])
def test_folders_created_for_a_run_are_removed_when_it_fails(tmp_path, capsys, monkeypatch,
                                                              where):
    """Interrupted while the figures are drawn, by this process (``here``) or by the child
    forked before the computation (``child``: the interrupt arrives while this process waits
    for it): exit 130, and the folders the run created are gone."""
    from nsm_continuation.figures import make as plots
    from nsm_continuation.figures import process as figure_process

    def boom(*a, **k):
        raise KeyboardInterrupt

    if where == "here":
        monkeypatch.setattr(figure_process, "FORKS", False)
        monkeypatch.setattr(plots, "make_all", boom)
    else:
        monkeypatch.setattr(figure_process, "can_fork", lambda: True)
        monkeypatch.setattr(figure_process.FigureProcess, "figures", boom)
    case = _case(tmp_path, output={"plots": True, "progress": False})
    code, _ = _run([str(case), "--out", str(tmp_path / "a" / "b" / "out")], capsys)
    assert code == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml"]


def test_if_exists_new_skips_a_number_another_run_is_writing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = _case(tmp_path, output={"plots": False, "progress": False, "if_exists": "new"})
    (tmp_path / "runs").mkdir()
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "runs" / ".safety.lock").write_text(lock_text(sleeper.pid))
        assert _run([str(case)], capsys)[0] == 0
    finally:
        sleeper.kill()
        sleeper.wait()
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == [".safety.lock", "safety-2"]


@pytest.mark.parametrize("lock_kind", ["user_file", "pid_text", "folder", "symlink", "other_tool",
                                       "empty"])
def test_a_lock_we_cannot_prove_we_wrote_is_refused_never_deleted(tmp_path, capsys, lock_kind,
                                                                  no_compute):
    """Something named ``.<name>.lock`` next to the output folder that is not a regular file of
    this user holding this tool's lock JSON is never taken for a stale lock: refused, kept."""
    lock = tmp_path / ".out.lock"
    if lock_kind == "user_file":
        lock.write_text("my lock notes, do not delete")
    elif lock_kind == "pid_text":  # looks like a PID of a process that is gone
        lock.write_text("999999999")
    elif lock_kind == "folder":
        lock.mkdir()
        (lock / "keep.txt").write_text("precious")
    elif lock_kind == "symlink":
        lock.symlink_to(tmp_path / "case.yaml")
    elif lock_kind == "other_tool":
        lock.write_text(json.dumps({"tool": "other", "kind": "lock", "pid": 999999999,
                                    "uid": os.getuid()}))
    else:
        lock.write_text("")
    case = _case(tmp_path)
    before = _snapshot(tmp_path)
    code, err = _run([str(case), "--out", str(tmp_path / "out")], capsys)
    assert code == 2, err
    assert err.startswith("error: output:") and len(err.strip().splitlines()) == 1
    assert str(lock) in err
    assert _snapshot(tmp_path) == before
    assert lock.exists() or lock.is_symlink()


def test_our_stale_lock_is_taken_over(tmp_path, capsys):
    """A lock this tool wrote, whose process is gone, does not block the next run."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / ".out.lock").write_text(lock_text(dead.pid))
    code, err = _run([str(_case(tmp_path)), "--out", str(tmp_path / "out")], capsys)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "out"]


@pytest.mark.parametrize("inside", ["run_folder", "run_subfolder", "tmp_folder", "tmp_name"])
def test_output_inside_another_run_is_refused(tmp_path, capsys, inside, monkeypatch):
    """An output folder inside a run folder or inside another run's temporary folder would be
    removed by that run's overwrite or clean-up: refused before computing, nothing written."""
    case, out = _two_runs(tmp_path, capsys)
    _forbid_compute(monkeypatch)
    if inside == "run_folder":
        target = out / "nested"
    elif inside == "run_subfolder":
        target = out / "a" / "b"
    elif inside == "tmp_folder":
        tmp = tmp_path / ".other.tmp-abc123"
        tmp.mkdir()
        target = tmp / "nested"
    else:
        target = tmp_path / ".other.tmp-xyz"
    before = _snapshot(tmp_path)
    names = sorted(p.name for p in tmp_path.iterdir())
    code, err = _run([str(case), "--out", str(target)], capsys)
    assert code == 2, err
    assert err.startswith("error: output:") and len(err.strip().splitlines()) == 1
    assert str(target) in err
    assert _snapshot(tmp_path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == names
    assert not target.exists()
