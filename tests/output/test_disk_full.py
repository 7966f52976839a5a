"""A full disk (or an exhausted quota) while a run's results are written is not a bug: one line
naming the folder and the bytes the results need, exit status 4, nothing partial in the output
location, and the computed results kept in a named folder of the system's temporary directory."""

from __future__ import annotations

import builtins
import errno
import json
import tempfile
from pathlib import Path

import pytest
import yaml

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases.saved_runs import MARKER, read_marker
from nsm_continuation.output import files
from nsm_continuation.output.files import NoSpaceError

CASE = {
    "name": "full",
    "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 15},
    "output": {"plots": False, "progress": False},
}


def _full_disk_at(monkeypatch, code: int, folder_prefix: str) -> None:
    """The writer of the outputs (``open`` and ``Path.write_text`` of the files module) raises
    ``OSError(code)`` for any output file (not the tool's own markers) in a folder whose name
    starts with ``folder_prefix``."""
    real_open, real_write = builtins.open, Path.write_text

    def full(path: object) -> None:
        p = Path(str(path))
        if p.parent.name.startswith(folder_prefix) and not p.name.startswith(".nsm-"):
            raise OSError(code, "No space left on device", str(path))

    def fake_open(path, *a, **k):
        full(path)
        return real_open(path, *a, **k)

    def fake_write(self, *a, **k):
        full(self)
        return real_write(self, *a, **k)

    monkeypatch.setattr(files, "open", fake_open, raising=False)
    monkeypatch.setattr(Path, "write_text", fake_write)


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT])
def test_disk_full_keeps_the_results_elsewhere_exit_4(tmp_path, capsys, monkeypatch, code):
    systmp = tmp_path / "systmp"
    systmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(systmp))
    _full_disk_at(monkeypatch, code, ".out.tmp-")
    case = tmp_path / "case.yaml"
    case.write_text(yaml.safe_dump(CASE))
    out = tmp_path / "out"
    status = cli.main(["run", str(case), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert status == 4, err
    line = err.strip()
    assert len(line.splitlines()) == 1 and line.startswith("error: output:"), err
    assert "bug" not in line and str(out) in line
    kept = [p for p in systmp.iterdir()]
    assert len(kept) == 1 and str(kept[0]) in line
    assert "bytes" in line
    # the kept folder is a complete run (marker, CSV, report) that a case can start from
    marker = read_marker(kept[0])
    assert marker is not None and {"branch_0.csv", "report.json"} <= set(marker["files"])
    assert json.loads((kept[0] / "report.json").read_text())["case"]["name"] == "full"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml", "systmp"]


def test_disk_full_everywhere_says_the_results_are_lost(tmp_path, capsys, monkeypatch):
    systmp = tmp_path / "systmp"
    systmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(systmp))
    _full_disk_at(monkeypatch, errno.ENOSPC, ".")
    case = tmp_path / "case.yaml"
    case.write_text(yaml.safe_dump(CASE))
    status = cli.main(["run", str(case), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert status == 4 and len(err.splitlines()) == 1 and "either" in err, err
    assert list(systmp.iterdir()) == []


def test_result_save_on_a_full_disk_raises_naming_the_kept_folder(tmp_path, monkeypatch):
    result = nsm.run(CASE)
    systmp = tmp_path / "systmp"
    systmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(systmp))
    _full_disk_at(monkeypatch, errno.ENOSPC, ".out.tmp-")
    with pytest.raises(NoSpaceError) as info:
        result.save(tmp_path / "out", plots=False)
    assert info.value.kept is not None and str(info.value.kept) in str(info.value)
    assert (info.value.kept / MARKER).is_file()
    assert not (tmp_path / "out").exists()
