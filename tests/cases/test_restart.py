"""Restart from any saved point of a run (``nsm_continuation/cases/restart.py``).

Oracles: the closed form (4.2) of the chain's branch (every restarted point is
``u(0) = (g / w_N) w(T)`` at its own ``T``; the chain is linear in the gap); the run's own
records (bit-equality of the saved unknowns with the points in memory and the CSV); a multiplier
at -1 where a hybrid orbit is restarted at its period doubling in another parameter.
"""

from __future__ import annotations

import csv
import hashlib
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import CASES
from oracles.scaled_chain import closed_form_y

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases.saved_runs import RESTART_FORMAT, RESTART_VERSION

#: the default chain case (Fig. 5.1, branch 1) cut to omega in [1.42, 1.49]: the linear grazing
#: start, the fold (pair through +1) at 1.4517 and four period doublings
CHAIN_OVERRIDES = {"continuation.min": 1.42, "continuation.max": 1.49, "output.plots": False,
                   "output.progress": False}


@pytest.fixture(scope="module")
def chain_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path]:
    res = nsm.run(CASES / "ndof_default.yaml", CHAIN_OVERRIDES)
    folder = tmp_path_factory.mktemp("runs") / "chain"
    res.save(folder, plots=False)
    return res, folder


def first_point(result: Any) -> Any:
    br = result.run_result.branches[0]
    return next(p for p in br.points if p.s == 0.0)


def test_record_is_versioned_and_exact(chain_run: tuple[Any, Path]) -> None:
    """report.json's restart block: format and version, the full parameters, and every
    event's unknowns and tangent bit-equal to the points in memory; an event that sits on a
    point (the branch ends) names its CSV row, whose y_<name> columns are the same bits."""
    res, folder = chain_run
    rep = json.loads((folder / "report.json").read_text())["restart"]
    assert (rep["format"], rep["version"]) == (RESTART_FORMAT, RESTART_VERSION)
    assert rep["problem"] == "ndof_impact" and rep["continued"] == "omega"
    assert rep["parameters"] == res.problem.params.model_dump(mode="json")
    [br] = rep["branches"]
    assert br["variables"] == res.problem.variables and br["parameter"] == "T"
    with open(folder / br["csv"], newline="") as fh:
        rows = list(csv.DictReader(fh))
    branch = res.run_result.branches[0]
    assert len(br["events"]) == len(branch.events) > 6
    for rec, ev in zip(br["events"], branch.events, strict=True):
        assert rec["kind"] == ev.kind
        assert np.array_equal(rec["y"], ev.point.y) and np.array_equal(rec["tangent"],
                                                                       ev.point.tangent)
        if rec["row"] is not None:
            y_csv = [float(rows[rec["row"]][f"y_{v}"]) for v in br["variables"]]
            assert np.array_equal(y_csv, ev.point.y)
    ends = [e["row"] for e in br["events"] if e["kind"] == "endpoint"]
    assert len(rows) - 1 in ends and set(ends) <= {0, len(rows) - 1}
    kinds = [e["kind"] for e in br["events"]]
    assert [e["index"] for e in br["events"] if e["kind"] == "period_doubling"] == \
        list(range(kinds.count("period_doubling")))


def test_restart_at_a_fold_is_one_newton_iteration_and_stays_on_the_closed_form(
        chain_run: tuple[Any, Path]) -> None:
    """From the fold of the saved run (a start at fixed parameter is singular there): the
    first point is the saved one after one Newton iteration, every point of the restarted
    branch is the closed form at its period, and the fold is located again where it was."""
    res, folder = chain_run
    [fold] = [e for e in res.events if e.kind == "fold"]
    again = nsm.run({"start": {"from": str(folder), "event": "fold"},
                     "continuation": {"max_points": 12}, "output": {"plots": False}})
    p0 = first_point(again)
    assert p0.newton_iterations == 1
    assert np.linalg.norm(p0.y - fold.point.y, np.inf) < 1e-11 * np.linalg.norm(fold.point.y)
    pr = again.problem
    for p in again.run_result.branches[0].points:
        ref = closed_form_y(pr, p.y[-1])
        assert np.linalg.norm(p.y - ref, np.inf) < 1e-9 * np.linalg.norm(ref, np.inf)
    folds = [e for e in again.events if e.kind == "fold"]
    assert len(folds) == 1
    assert abs(folds[0].record["omega"] - fold.record["omega"]) < 1e-9
    assert again.case.continuation.min == 1.42  # the window is inherited


def test_restart_from_an_endpoint_goes_onwards(chain_run: tuple[Any, Path]) -> None:
    """From the branch's end at the window's edge (omega = 1.49, the period T falling), with
    the window widened: every point of the restarted branch lies beyond the end (T below it)
    and on the closed form, nothing is walked again; ``direction: both`` walks back too."""
    res, folder = chain_run
    [end] = [e for e in res.events if e.kind == "endpoint"
             and e.point is res.run_result.branches[0].points[-1]]
    T_end = end.point.y[-1]
    onwards = nsm.run({"start": {"from": str(folder), "event": "endpoint"},
                       "continuation": {"max": 1.52, "max_points": 8}, "output": {"plots": False}})
    pts = onwards.run_result.branches[0].points
    assert len(pts) >= 6
    assert all(p.y[-1] <= T_end * (1 + 1e-12) for p in pts)
    assert min(p.y[-1] for p in pts) < T_end * (1 - 1e-3)
    pr = onwards.problem
    for p in pts:
        ref = closed_form_y(pr, p.y[-1])
        assert np.linalg.norm(p.y - ref, np.inf) < 1e-9 * np.linalg.norm(ref, np.inf)
    both = nsm.run({"start": {"from": str(folder), "event": "endpoint", "direction": "both"},
                    "continuation": {"max": 1.52, "max_points": 8}, "output": {"plots": False}})
    T = [p.y[-1] for p in both.run_result.branches[0].points]
    assert max(T) > T_end * (1 + 1e-3) and min(T) < T_end * (1 - 1e-3)


def test_restart_from_csv_rows_and_the_api(chain_run: tuple[Any, Path]) -> None:
    """``point: 40`` and ``point: -1`` start from the saved rows (bit-equal to the points in
    memory, one Newton iteration); ``Result.restart`` with an event of the result gives the
    first point the folder gives."""
    res, folder = chain_run
    pts = res.run_result.branches[0].points
    for row in (40, -1):
        again = nsm.run({"start": {"from": str(folder), "point": row},
                         "continuation": {"max_points": 2}, "output": {"plots": False}})
        p0 = first_point(again)
        assert p0.newton_iterations == 1
        assert np.linalg.norm(p0.y - pts[row].y, np.inf) < 1e-11 * np.linalg.norm(pts[row].y)
        assert again.run_result.branches[0].info["restart_point"] == row
    pd = [e for e in res.events if e.kind == "period_doubling"][2]
    by_api = res.restart(event=pd, max_points=2)
    by_folder = nsm.run({"start": {"from": str(folder),
                                   "event": {"kind": "period_doubling", "index": 2}},
                         "continuation": {"max_points": 2}, "output": {"plots": False}})
    assert np.array_equal(first_point(by_api).y, first_point(by_folder).y)
    assert first_point(by_api).newton_iterations == 1


def test_parameters_are_inherited_and_overridden(chain_run: tuple[Any, Path]) -> None:
    """The chain is linear in the gap: restarted with ``parameters: {gap: 2}`` at the same
    period, the orbit is twice the saved one (its unknowns are in units of the gap: the same
    numbers, a converged point at once); continued in T instead of omega, the window is the
    case's (not inherited in other units)."""
    res, folder = chain_run
    pd = [e for e in res.events if e.kind == "period_doubling"][0]
    T = pd.point.y[-1]
    again = nsm.run({"start": {"from": str(folder), "event": {"kind": "period_doubling"}},
                     "parameters": {"gap": 2.0},
                     "continuation": {"parameter": "T", "min": T - 0.01, "max": T + 0.01,
                                      "max_points": 3},
                     "output": {"plots": False}})
    p0 = first_point(again)
    assert p0.y[-1] == pytest.approx(T, abs=1e-12)
    for new, old in zip(again.run_result.problem.state(p0.y)[:2],
                        res.run_result.problem.state(pd.point.y)[:2], strict=True):
        assert np.linalg.norm(new - 2 * old, np.inf) < 1e-9
    assert p0.derived["energy"] == pytest.approx(4 * pd.point.derived["energy"], rel=1e-9)
    assert again.case.parameters["gap"] == 2.0
    assert again.case.parameters["chain"] == {"dofs": 5, "mass": 0.2, "stiffness": 5.0}
    ts = [p.y[-1] for p in again.run_result.branches[0].points]
    assert min(ts) >= T - 0.01 - 1e-12 and max(ts) <= T + 0.01 + 1e-12
    assert p0.newton_iterations == 1  # the scaled orbit solves the residual at once


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _fake_old_run(src: Path, dst: Path) -> Path:
    """``src`` copied, its report.json without the restart block, the marker updated: a run
    written before restart records (or by a future format)."""
    shutil.copytree(src, dst)
    rep = json.loads((dst / "report.json").read_text())
    del rep["restart"]
    (dst / "report.json").write_text(json.dumps(rep))
    marker = dst / ".nsm-continuation-run.json"
    data = json.loads(marker.read_text())
    data["files"]["report.json"] = _sha(dst / "report.json")
    marker.write_text(json.dumps(data))
    return dst


BAD = [
    ("missing folder", {"from": "{tmp}/nowhere", "event": "fold"}, {},
     "start.from: {tmp}/nowhere does not exist"),
    ("not a run", {"from": "{tmp}/plain", "event": "fold"}, {},
     "start.from: {tmp}/plain is not a run of nsm-continuation"),
    ("changed", {"from": "{tmp}/changed", "event": "fold"}, {},
     "start.from: {tmp}/changed/report.json was changed after the run"),
    ("old run", {"from": "{tmp}/old", "event": "fold"}, {},
     "start.from: {tmp}/old/report.json has no restart record"),
    ("other problem", {"from": "{run}", "event": "fold"}, {"problem": "two_mass_chain"},
     "start.from: {run} is a run of problem 'ndof_impact', not of 'two_mass_chain'"),
    ("no branch", {"from": "{run}", "branch": 3, "event": "fold"}, {},
     "start.branch: {run} has no branch 3"),
    ("no such event", {"from": "{run}", "event": "grazing"}, {},
     "start.event: branch 0 of {run} has no grazing event"),
    ("ambiguous", {"from": "{run}", "event": "period_doubling"}, {},
     "start.event: branch 0 of {run} has 4 period_doubling events"),
    ("index", {"from": "{run}", "event": {"kind": "fold", "index": 1}}, {},
     "start.event.index: branch 0 of {run} has 1 fold event (index 0..0), not 1"),
    ("row", {"from": "{run}", "point": 100000}, {}, "start.point: branch 0 of {run} has"),
    ("both", {"from": "{run}", "point": 1, "event": "fold"}, {}, "start.point: give"),
    ("neither", {"from": "{run}"}, {}, "start.event: a restart needs"),
    ("switch at a fold", {"from": "{run}", "event": "fold", "switch": True}, {},
     "start.switch: switching is defined at"),
    ("switch kind", {"from": "{run}", "event": "fold", "switch": "period_doubling"}, {},
     "start.switch: switching is defined at"),
    ("period doubling of the chain",
     {"from": "{run}", "event": {"kind": "period_doubling"}, "switch": True}, {},
     "start.switch: problem 'ndof_impact' cannot represent orbits of twice the period"),
    ("unknown key", {"from": "{run}", "event": "fold", "evnt": 1}, {},
     "start.evnt: unknown key"),
    ("outside the window", {"from": "{run}", "event": "fold"},
     {"continuation": {"max": 1.44}},
     "start.from: the restart point fails the start checks: the start period T ="),
    ("list", [{"from": "{run}", "event": "fold"}], {}, "start: a restart (start.from) is one"),
]


@pytest.mark.parametrize(("label", "start", "extra", "needle"), BAD, ids=[b[0] for b in BAD])
def test_bad_restart_one_line_exit_2_nothing_written(chain_run: tuple[Any, Path],
                                                     tmp_path: Path, write_case: Any,
                                                     refused_before_computing: Any, label: str,
                                                     start: Any, extra: dict[str, Any],
                                                     needle: str) -> None:
    _, folder = chain_run
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "report.json").write_text("{}")
    shutil.copytree(folder, tmp_path / "changed")
    with open(tmp_path / "changed" / "report.json", "a") as fh:
        fh.write(" ")
    _fake_old_run(folder, tmp_path / "old")

    def fill(v: Any) -> Any:
        if isinstance(v, str):
            return v.replace("{tmp}", str(tmp_path)).replace("{run}", str(folder))
        if isinstance(v, dict):
            return {k: fill(x) for k, x in v.items()}
        if isinstance(v, list):
            return [fill(x) for x in v]
        return v

    case = {"name": "again", "start": fill(start), "output": {"progress": False}, **extra}
    refused_before_computing(write_case(case), fill(needle))


def test_yaml_restart_writes_a_restartable_run(chain_run: tuple[Any, Path], tmp_path: Path,
                                               write_case: Any) -> None:
    """A restart case written by the CLI is itself a run with a restart record: its problem
    and parameters are the inherited ones, and restarting from its own fold gives the same
    point again (one Newton iteration)."""
    _, folder = chain_run
    case = write_case({"start": {"from": str(folder), "event": "fold"},
                       "continuation": {"max_points": 6},
                       "output": {"plots": False, "progress": False}})
    out = tmp_path / "second"
    assert cli.main(["run", str(case), "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["problem"] == "ndof_impact" and rep["case"]["name"] == "ndof_default_restart"
    assert rep["parameters"]["chain"] == {"dofs": 5, "mass": 0.2, "stiffness": 5.0}
    info = rep["branches"][0]["info"]
    assert info["restart_from"] == str(folder) and info["restart_event"] == "fold"
    third = nsm.run({"start": {"from": str(out), "event": "fold"},
                     "continuation": {"max_points": 2}, "output": {"plots": False}})
    first, second = (json.loads((f / "report.json").read_text())["restart"]["branches"][0]
                     for f in (folder, out))
    [fold1], [fold2] = ([e for e in b["events"] if e["kind"] == "fold"]
                        for b in (first, second))
    p0 = first_point(third)
    assert p0.newton_iterations == 1
    assert np.linalg.norm(p0.y - fold2["y"], np.inf) < 1e-11
    assert np.linalg.norm(p0.y - fold1["y"], np.inf) < 1e-8  # the fold located again


# ----------------------------------------------------------------------- a hybrid orbit
def test_hybrid_restart_in_another_parameter(flip_run: tuple[Any, Path]) -> None:
    """Restarted at the flip in the wall position ``gap``: omega takes its value at the flip
    (in ``parameters``), the unknowns are the section state and gap, the first point is the
    saved orbit after one Newton iteration, and it still has its multiplier at -1."""
    res, folder = flip_run
    [pd] = [e for e in res.events if e.kind == "period_doubling"]
    assert pd.parameter == pytest.approx(0.6927610, abs=1e-7)
    again = nsm.run({"start": {"from": str(folder), "event": "period_doubling"},
                     "continuation": {"parameter": "gap", "min": 0.49, "max": 0.51,
                                      "max_points": 2},
                     "output": {"plots": False}})
    pr = again.problem
    assert pr.variables == ["q1", "q2", "q1dot", "q2dot", "gap"]
    assert again.case.parameters["omega"] == pd.point.y[-1]
    p0 = first_point(again)
    assert p0.newton_iterations == 1
    assert p0.y[-1] == 0.5
    assert np.linalg.norm(p0.y[:-1] - pd.point.y[:-1], np.inf) < 1e-9
    assert np.min(np.abs(p0.multipliers + 1.0)) < 1e-8


def test_start_curve_takes_any_kind_name_checked_with_the_problem() -> None:
    """``start.curve`` is any kind name in the schema (the kinds a problem's curves can follow
    come from the problem, :func:`nsm_continuation.algorithms.curves.curve_kinds`, checked once it
    is loaded); an empty name is refused naming the key."""
    from nsm_continuation.cases.restart import parse_spec

    spec = parse_spec({"from": "runs/x", "event": "some_family_kind", "curve": "some_family_kind"})
    assert spec.curve == "some_family_kind"
    with pytest.raises(Exception, match=r"start\.curve"):
        parse_spec({"from": "runs/x", "event": "fold", "curve": ""})


def test_a_bundled_restart_without_its_parent_run_says_which_to_run_first(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
        ) -> None:
    """A bundled restart case run in an empty folder (its parent run, ``runs/<case>``, is
    not there): one line naming the bundled case that writes it; a folder that no bundled
    case writes gets no such advice."""
    from nsm_continuation.cases import bundled

    monkeypatch.chdir(tmp_path)
    restart = [name for name, path in bundled.cases().items()
               if "from: runs/impact_oscillator_grazing," in path.read_text()]
    assert restart, "a bundled restart case starts from runs/impact_oscillator_grazing"
    assert cli.main(["run", restart[0], "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: start.from: runs/impact_oscillator_grazing does not exist (looked "
                   f"for in {tmp_path}); run it first: nsm-continuation run "
                   "impact_oscillator_grazing"]
    with pytest.raises(nsm.CaseError) as exc:
        nsm.load("runs/no_such_case")
    assert "run it first" not in str(exc.value)
