"""Command line and YAML cases: the output contract, and one clear error (exit 2, nothing
written) for every kind of bad input."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import CASES

from nsm_continuation import cli
from nsm_continuation.output import files as results

BASE = {
    "name": "t",
    "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9,
                     "step": {"initial": 0.01, "min": 1e-9, "max": 0.1}, "max_points": 60},
    "analysis": {"stop_on_inadmissible": True},
    "output": {"progress": False},
}


def _with(path: list[str], value) -> dict:
    import copy

    case = copy.deepcopy(BASE)
    node = case
    for k in path[:-1]:
        node = node[k]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return case


_DELETE = object()


def test_default_case_runs_and_writes_the_contract(tmp_path, capsys):
    out = tmp_path / "run"
    assert cli.main(["run", "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    for key in ("case", "problem", "parameters", "timings", "branches"):
        assert key in rep
    assert rep["problem"] == "ndof_impact"
    br = rep["branches"][0]
    for key in ("id", "n_points", "termination", "events"):
        assert key in br
    kinds = {e["kind"] for e in br["events"]}
    assert kinds <= set(["fold", "branch_point", "period_doubling", "neimark_sacker",
                         "stability_change", "grazing", "endpoint"])
    assert "grazing" in kinds and "stability_change" in kinds and "endpoint" in kinds
    for e in br["events"]:
        for key in ("kind", "T", "omega", "energy", "multipliers"):
            assert key in e
        if e["kind"] == "stability_change":
            assert isinstance(e["stable_before"], bool) and isinstance(e["stable_after"], bool)
    with open(out / f"branch_{br['id']}.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == br["n_points"]
    for col in ("T", "omega", "energy", "admissible", "stable", "max_abs_multiplier"):
        assert col in rows[0]
    assert (out / "report.md").read_text().startswith("# Bifurcation report")
    for fig in ("fep.png", "multipliers_vs_omega.png", "multipliers_complex_plane.png",
                "w_N.png"):
        assert (out / fig).stat().st_size > 10_000


def test_console_script_list_and_validate(write_case):
    exe = [sys.executable, "-m", "nsm_continuation.cli"]
    r = subprocess.run(exe + ["list"], capture_output=True, text=True, check=True)
    assert "ndof_impact" in r.stdout
    case = write_case(BASE)
    r = subprocess.run(exe + ["validate", str(case)], capture_output=True, text=True)
    assert r.returncode == 0 and "valid" in r.stdout


def test_set_override_applies(tmp_path, write_case):
    case = write_case(BASE)
    out = tmp_path / "o"
    assert cli.main(["run", str(case), "--out", str(out), "--quiet",
                     "--set", "continuation.max_points=7", "--set", "output.plots=false"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["branches"][0]["n_points"] <= 7
    assert not (out / "fep.png").exists()


BAD = [
    ("unknown top-level key", _with(["colour"], "red"), "colour"),
    ("unknown nested key", _with(["continuation", "stepp"], 1), "continuation.stepp"),
    ("wrong type", _with(["continuation", "max_points"], "many"), "continuation.max_points"),
    ("unknown problem", _with(["problem"], "pendulum"), "problem"),
    ("NaN", _with(["parameters", "gap"], float("nan")), "parameters.gap"),
    ("non-symmetric M", _with(["parameters"], {"M": [[1, 0.5], [0, 1]], "K": [[2, -1], [-1, 2]],
                                               "gap": 1}), "not symmetric"),
    ("non-positive-definite K", _with(["parameters"], {"M": [[1, 0], [0, 1]],
                                                       "K": [[1, 2], [2, 1]], "gap": 1}),
     "not positive definite"),
    ("restitution", _with(["parameters", "restitution"], 0.8), "parameters.restitution"),
    ("impacting dof", _with(["parameters", "impacting_dof"], 4), "impacting_dof"),
    ("missing key", _with(["parameters", "gap"], _DELETE), "parameters.gap"),
    ("mode out of range", _with(["start"], {"mode": 9}), "start"),
    ("bad start key", _with(["start"], {"mod": 1}), "start"),
    ("min >= max", _with(["continuation", "min"], 2.0), "continuation"),
    ("bad step order", _with(["continuation", "step"], {"initial": 1.0, "min": 1e-9,
                                                        "max": 0.1}), "continuation.step"),
    ("bad parameter", _with(["continuation", "parameter"], "energy"), "continuation.parameter"),
]


@pytest.mark.parametrize("label, case, needle", BAD, ids=[b[0] for b in BAD])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, write_case, capsys, label, case,
                                                   needle):
    path = write_case(case)
    out = tmp_path / "out"
    assert cli.main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err, err
    assert needle in err, err
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["case.yaml"]


def test_missing_file_and_invalid_yaml(tmp_path, write_case, capsys):
    assert cli.main(["run", str(tmp_path / "nope.yaml"), "--quiet"]) == 2
    assert "does not exist" in capsys.readouterr().err
    bad = write_case("problem: [unclosed\n")
    assert cli.main(["validate", str(bad)]) == 2
    assert "not valid YAML" in capsys.readouterr().err
    assert cli.main(["validate", str(write_case(BASE, "c2.yaml")), "--set", "noequals"]) == 2


def test_failed_run_leaves_no_half_written_folder(tmp_path, write_case, monkeypatch, capsys):
    from nsm_continuation.figures import make as plots

    def boom(*a, **k):
        raise RuntimeError("plotting failed")

    monkeypatch.setattr(plots, "make_all", boom)
    case = write_case(BASE)
    out = tmp_path / "out"
    # an exception that should not happen is a bug: exit 1, one line, traceback in a file
    assert cli.main(["run", str(case), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "plotting failed" in err and "bug" in err
    crash = Path(err.rsplit("traceback in ", 1)[1])
    assert "RuntimeError: plotting failed" in crash.read_text()
    crash.unlink()
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case.yaml"]


def test_every_bundled_case_validates():
    from nsm_continuation import cases

    files = sorted(CASES.glob("*.yaml"))
    assert len(files) >= 6
    for f in files:
        case, problem = cases.load(f)
        prefix = {"ndof": "ndof_impact", "wfem": "wfem_bar", "bar": "bar_continuum",
                  "impact": "impact_oscillator", "pendulum": "double_pendulum",
                  "ball": "bouncing_ball", "chain": "two_mass_chain"}
        if f.stem in ("two_sided_oscillator", "impact_damper"):
            expected = f.stem  # the two-wall systems, named for their problem
        else:
            expected = prefix[f.name.split("_")[0]]
        if f.name.startswith(("wfem_fig20", "wfem_fig21", "wfem_fig22")):
            expected = "wfem_forced_bar"  # the bar's forced response (Figs. 20-22)
        if f.name.startswith("ndof_hybrid"):
            expected = "ndof_impact_hybrid"  # the chain through the hybrid layer
        if f.name.startswith("ndof_two_walls"):
            expected = "ndof_two_walls"  # the chain with its last mass between two walls
        assert case.problem == expected
        if case.problem == "ndof_impact":
            assert problem.N == 5


def test_multiplier_rows_sorted_and_json_safe():
    import numpy as np

    rows = results.multipliers_list(np.array([0.1 + 0j, 2.0 + 1j, -1.5 + 0j]))
    assert [round(abs(complex(*r)), 6) for r in rows] == [round(abs(2 + 1j), 6), 1.5, 0.1]
    assert results.multipliers_list(None) == []
