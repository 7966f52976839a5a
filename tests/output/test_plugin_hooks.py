"""A problem's presentation hook (a plugin's code, run after the computation) that raises or
returns what the report cannot hold never loses the computed results: the branch CSVs and
report.json are written without that hook's part, a warning names the problem, the class and
the hook, and the run is not reported as a bug of this tool."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from nsm_continuation.problems.chain.presentation import ChainPresentation

from nsm_continuation import cli

CASE = {
    "name": "hooks",
    "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 15},
    "output": {"plots": False, "progress": False},
}


class _Opaque:
    """An object JSON cannot write."""


def _raise(*a, **k):
    raise RuntimeError("plugin bug")


#: hook -> (replacement on the presentation class, the report key that loses its part)
GARBAGE = {
    "summary": (lambda self: {"modes": {1, "two"}}, "problem_summary"),
    "summary_object": (lambda self: {"thing": _Opaque()}, "problem_summary"),
    "summary_not_dict": (lambda self: [1, 2], "problem_summary"),
    "report_extras": (lambda self, branches: _raise(), "problem_results"),
    "warnings": (lambda self: _raise(), None),
    "csv_head": (property(lambda self: ["no_such_quantity"]), None),
    "event_columns": (property(lambda self: 42), "event_columns"),
}


@pytest.mark.parametrize("bad", sorted(GARBAGE))
def test_a_failing_presentation_hook_is_named_and_the_results_written(tmp_path, capsys,
                                                                      monkeypatch, bad):
    replacement, key = GARBAGE[bad]
    hook = bad.split("_object")[0].split("_not_dict")[0]
    monkeypatch.setattr(ChainPresentation, hook, replacement, raising=False)
    case = tmp_path / "case.yaml"
    case.write_text(yaml.safe_dump(CASE))
    out = tmp_path / "out"
    status = cli.main(["run", str(case), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert status == 0, err
    lines = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    # one line per failing hook (the default event_columns repeat csv_head's names)
    assert lines and all("'ndof_impact'" in ln and "ChainPresentation." in ln for ln in lines)
    assert any(f"ChainPresentation.{hook} failed" in ln for ln in lines), err
    assert "this is a bug" not in err
    assert {p.name for p in out.iterdir()} >= {"branch_0.csv", "report.json", "report.md"}
    rep = json.loads((out / "report.json").read_text())
    assert rep["branches"][0]["n_points"] > 0
    assert any(f"ChainPresentation.{hook}" in w for w in rep["warnings"])
    if key is not None:
        assert rep[key] in ({}, [])
    header = (out / "branch_0.csv").read_text().splitlines()[0].split(",")
    assert "omega" in header and "no_such_quantity" not in header
    assert len(Path(out / "branch_0.csv").read_text().splitlines()) == rep["branches"][0][
        "n_points"] + 1
