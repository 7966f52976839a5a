"""Paths that are not UTF-8 (bytes a POSIX file name may hold, which Python gives as lone
surrogates, ``os.fsdecode``) work alike for the case file and for ``--out``
(``nsm_continuation/cli.py``, ``nsm_continuation/output/folders.py``).

Oracle: the files on disk at the byte path, and the exit status of ``validate`` and ``run``."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from nsm_continuation import cli

CASE = """\
name: bytes_path
problem: ndof_impact
parameters:
  chain: {dofs: 2, mass: 1.0, stiffness: 1.0}
  gap: 1.0
start: {mode: 1}
continuation: {parameter: omega, min: 0.3, max: 0.9, max_points: 4}
output: {plots: false, progress: false}
"""


def test_a_non_utf8_out_path_works_as_a_non_utf8_case_path(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = os.fsdecode(os.fsencode(tmp_path) + b"/case\xff")
    os.mkdir(folder)
    case = os.path.join(folder, "c.yaml")
    Path(case).write_text(CASE)
    out = os.fsdecode(os.fsencode(tmp_path) + b"/out\xfe")
    assert cli.main(["validate", case, "--out", out]) == 0, capsys.readouterr().err
    assert not os.path.exists(out)
    assert cli.main(["run", case, "--out", out, "--quiet"]) == 0, capsys.readouterr().err
    written = sorted(os.listdir(os.fsencode(tmp_path) + b"/out\xfe"))
    assert {b"report.json", b"branch_0.csv", b".nsm-continuation-run.json"} <= set(written)
    # a second run is refused by the output policy, in one line, not by the path's bytes
    assert cli.main(["run", case, "--out", out, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "holds a previous run" in err, err
