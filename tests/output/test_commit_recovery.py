"""Replacing a previous run (``--overwrite``) survives a kill at any step of the final move:
afterwards, once :func:`~nsm_continuation.output.folders.recover` ran (the next run into the
same parent folder, or ``nsm-continuation recover``), the folder holds the complete previous run
or the complete new one, the user's own files, and nothing hidden is left next to it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from nsm_continuation import cli
from nsm_continuation.cases.saved_runs import MARKER, sha256
from nsm_continuation.output import folders
from nsm_continuation.output.folders import OutputTarget, previous_run_files

OLD = {"branch_0.csv": "old csv", "report.json": "{}", "report.md": "old report",
       "fep.png": "old figure"}
NEW = {"branch_0.csv": "new csv", "branch_1.csv": "new second", "report.json": '{"n": 1}',
       "report.md": "new report"}

#: a process that replaces the run in ``out`` by NEW and dies (os._exit: no clean-up, as a
#: SIGKILL) at its ``kill_at``-th rename
KILLED_COMMIT = textwrap.dedent("""
    import os, sys
    from pathlib import Path
    from nsm_continuation.output import folders
    out, kill_at, new = Path(sys.argv[1]), int(sys.argv[2]), eval(sys.argv[3])
    target = folders.OutputTarget(out, "overwrite")
    target.prepare()
    for name, text in new.items():
        (target.tmp / name).write_text(text)
    real, calls = os.replace, []
    def replace(a, b):
        calls.append(b)
        if len(calls) == kill_at:
            os._exit(9)
        return real(a, b)
    folders.os.replace = replace
    target.commit()
""")


def _write_run(out: Path, files: dict[str, str]) -> dict[str, str]:
    """A complete run folder ``out`` holding ``files``; its files' SHA-256."""
    target = OutputTarget(out, "overwrite")
    target.prepare()
    assert target.tmp is not None
    for name, text in files.items():
        (target.tmp / name).write_text(text)
    target.commit()
    return {n: sha256(out / n) for n in files}


def _state(out: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in out.iterdir()}


@pytest.mark.parametrize("how", ["next_run", "recover_command"])
def test_a_kill_at_any_step_of_an_overwrite_leaves_one_complete_run(tmp_path, how, capsys):
    out = tmp_path / "out"
    steps = 0
    for kill_at in range(1, 30):
        if out.exists():
            for p in out.iterdir():
                p.unlink()
            out.rmdir()
        old_digests = _write_run(out, OLD)
        (out / "mine.txt").write_text("the user's notes")
        proc = subprocess.run([sys.executable, "-c", KILLED_COMMIT, str(out), str(kill_at),
                               repr(NEW)], capture_output=True, text=True, timeout=120)
        if proc.returncode == 0:  # the commit has fewer renames than that: all steps tried
            break
        assert proc.returncode == 9, proc.stderr
        steps += 1
        # nothing of either run is lost meanwhile: the killed run's temporary folder holds
        # whatever is not in the folder
        if how == "next_run":
            other = OutputTarget(tmp_path / "elsewhere")
            other.prepare()
            other.abort()
            assert other.recovered, kill_at
        else:
            assert cli.main(["recover", str(out)]) == 0
            assert capsys.readouterr().out.strip()
        files = previous_run_files(out)
        expected = [{**old_digests}, {n: sha256(out / n) for n in NEW if (out / n).exists()}]
        assert files in expected, (kill_at, sorted(files))
        state = _state(out)
        assert state.pop("mine.txt") == "the user's notes"
        state.pop(MARKER)
        assert state in (OLD, NEW), (kill_at, state)
        assert set(json.loads((out / MARKER).read_text())["files"]) == set(state)
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out"], kill_at
    assert steps >= 2 + len(OLD) + len(NEW)  # journal, old marker and files, new files, marker


def test_an_error_during_the_move_puts_the_previous_run_back(tmp_path, monkeypatch):
    """An exception at any rename of the move (a disk error, an interrupt): the previous run is
    back, byte for byte, and the temporary folder gone."""
    out = tmp_path / "out"
    _write_run(out, OLD)
    before = _state(out)
    real = os.replace
    for fail_at in range(1, 2 + len(OLD) + len(NEW) + 1):
        calls: list[Path] = []

        def replace(a, b, fail_at=fail_at, calls=calls):
            calls.append(b)
            if len(calls) == fail_at:
                raise RuntimeError("cut")
            return real(a, b)

        target = OutputTarget(out, "overwrite")
        target.prepare()
        assert target.tmp is not None
        for name, text in NEW.items():
            (target.tmp / name).write_text(text)
        monkeypatch.setattr(folders.os, "replace", replace)
        with pytest.raises(RuntimeError):
            try:
                target.commit()
            except BaseException:
                target.abort()
                raise
        monkeypatch.setattr(folders.os, "replace", real)
        assert _state(out) == before, fail_at
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out"], fail_at


def test_a_killed_runs_temporary_folder_is_removed_by_the_next_run(tmp_path, capsys):
    """The temporary folder and the lock of a run killed while it computed (its process gone)
    are recognised as ours by their markers and removed by the next run into that parent; a
    hidden folder named like one but not ours stays."""
    code = ("import os; from pathlib import Path; from nsm_continuation.output import folders;"
            f"t = folders.OutputTarget(Path({str(tmp_path / 'out')!r})); t.prepare();"
            "(t.tmp / 'branch_0.csv').write_text('half'); os._exit(9)")
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 9
    assert {p.name for p in tmp_path.iterdir()} >= {".out.lock"}
    stranger = tmp_path / ".x.tmp-user"
    stranger.mkdir()
    (stranger / "keep.txt").write_text("precious")
    target = OutputTarget(tmp_path / "out")
    target.prepare()
    assert len(target.recovered) == 2, target.recovered
    target.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == [".x.tmp-user"]
    assert (stranger / "keep.txt").read_text() == "precious"
