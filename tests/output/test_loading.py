"""A saved run read back (``nsm.load``, ``Result.load``,
:mod:`nsm_continuation.output.loading`): the branches, events, tree and report of the run in
memory, exactly (floats compared with ``==``: the files hold every float's round-trip
``repr``), figures and restarts that work as from the run itself, and one line for a folder
that is not a run, a file changed since the run or a run of a newer format.

The oracle is the run in memory: the same case is computed, saved with the command line's
writer (:meth:`Result.save`) and read back."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import NoParameters
from pydantic import BaseModel

import nsm_continuation as nsm
from nsm_continuation.cases.saved_runs import MARKER, sha256
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.problem import Problem
from nsm_continuation.output.files import _f

#: the chain near omega_1 (Fig. 5.1, branch 1): folds, period doublings, stability changes,
#: events located between the points; the impact oscillator's period-1 orbit with its two
#: period doublings (a branch whose section moves: charts) grown into a diagram whose
#: switched branches are period-2 orbits (problems of their own)
CASES = {
    "chain": ("ndof_default", {"continuation.max_points": 80, "output.plots": False}),
    "diagram": ("impact_oscillator_period_doubling", {
        "output.plots": False, "continuation.max_points": 40,
        "analysis.branch_switching": {"kinds": ["period_doubling"], "depth": 1,
                                      "max_points": 12}}),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def saved(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
          ) -> tuple[nsm.Result, nsm.Result, Path]:
    """``(the run in memory, the run read back, its folder)``."""
    name, over = CASES[request.param]
    fresh = nsm.run(name, over)
    folder = fresh.save(tmp_path_factory.mktemp(request.param) / "run", plots=False)
    return fresh, nsm.load(folder), folder


def _json(value: Any) -> Any:
    """``value`` as ``report.json`` holds it."""
    return json.loads(json.dumps(value, default=_f))


def test_every_column_of_every_branch_is_the_same(saved) -> None:
    fresh, loaded, _ = saved
    assert [b.id for b in loaded.branches] == [b.id for b in fresh.branches]
    for a, b in zip(fresh.branches, loaded.branches, strict=True):
        assert b.label == a.label and b.termination == a.termination
        assert b.column_names == a.column_names
        for column in a.column_names:
            np.testing.assert_array_equal(b[column], a[column], err_msg=column, strict=True)
        assert np.array_equal(b.y, a.y) and np.array_equal(b.parameter, a.parameter)
        for pa, pb in zip(a.raw.points, b.raw.points, strict=True):
            assert pa.s == pb.s and pa.admissible == pb.admissible and pa.stable == pb.stable
            assert pa.tests == pb.tests and pa.newton_iterations == pb.newton_iterations
            if pa.multipliers is not None:  # the CSV's order: by decreasing modulus
                order = np.argsort(-np.abs(pa.multipliers), kind="stable")
                assert np.array_equal(pb.multipliers, pa.multipliers[order])
            assert (pa.chart or None) == (pb.chart or None)


def test_every_event_is_the_same(saved) -> None:
    fresh, loaded, _ = saved
    assert len(loaded.events) == len(fresh.events) > 2
    for a, b in zip(fresh.events, loaded.events, strict=True):
        assert (b.kind, b.branch, b.parameter, b.detail) == (a.kind, a.branch, a.parameter,
                                                             a.detail)
        assert _json(b.record) == _json(a.record)
        assert np.array_equal(b.point.y, a.point.y)
        assert np.array_equal(b.point.tangent, a.point.tangent)
        assert b.point.admissible == a.point.admissible and b.point.stable == a.point.stable
    located = [e for e in loaded.events if e.kind != "endpoint"]
    assert located and any(e.point not in loaded.branches[e.branch].raw.points
                           for e in located)  # some located between two points


def test_tree_report_and_files_are_those_of_the_run(saved, tmp_path: Path) -> None:
    fresh, loaded, folder = saved
    assert loaded.tree == _json(fresh.tree)
    assert loaded.report() == json.loads((folder / "report.json").read_text())
    assert loaded.warnings == fresh.warnings and loaded.source == folder
    # written again from what was read: the same bytes
    again = loaded.save(tmp_path / "again", plots=False)
    for csv_file in folder.glob("branch_*.csv"):
        assert (again / csv_file.name).read_bytes() == csv_file.read_bytes()
    rebuilt = json.loads((again / "report.json").read_text())
    original = json.loads((folder / "report.json").read_text())
    for key in original.keys() - {"continue_from_here"}:
        assert rebuilt[key] == original[key], key
    if fresh.run_result.branch_problems:  # a switched branch has the problem it had
        for i, pr in fresh.run_result.branch_problems.items():
            got = loaded.run_result.branch_problems.get(i, loaded.problem)
            assert (type(got), got.period_multiple()) == (type(pr), pr.period_multiple())


def test_figures_and_orbits_of_a_loaded_run(saved) -> None:
    """The branch diagram draws the same lines; an orbit is the same trace."""
    fresh, loaded, _ = saved
    fa, fb = fresh.plot(), loaded.plot()
    la, lb = fa.axes[0].get_lines(), fb.axes[0].get_lines()
    assert len(la) == len(lb) > 0
    for x, y in zip(la, lb, strict=True):
        assert np.array_equal(x.get_xydata(), y.get_xydata(), equal_nan=True)
    br = fresh.branches[-1].id
    ta, tb = fresh.orbit(branch=br, point=-1), loaded.orbit(branch=br, point=-1)
    assert ta.period == tb.period and ta.signals.keys() == tb.signals.keys()
    for k in ta.signals:
        np.testing.assert_array_equal(tb.signals[k], ta.signals[k])


def test_a_loaded_run_restarts_as_the_run_itself(saved) -> None:
    """``restart`` from the first located event of the loaded run: the same branch as from the
    run in memory (the restart record is the saved one)."""
    fresh, loaded, _ = saved
    k = next(i for i, e in enumerate(fresh.events) if e.kind != "endpoint")
    a = fresh.restart(event=fresh.events[k], max_points=6, analysis={"stability": False})
    b = loaded.restart(event=loaded.events[k], max_points=6, analysis={"stability": False})
    assert len(a.branches[0]) > 1
    assert np.array_equal(a.branches[0].y, b.branches[0].y)


def _corrupt(folder: Path, name: str, text: str, tmp_path: Path, *, remark: bool) -> Path:
    """A copy of the run ``folder`` with ``name`` replaced by ``text`` (its SHA-256 written
    into the copy's marker if ``remark``: a file the tool wrote so)."""
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    (copy / name).write_text(text)
    if remark:
        marker = json.loads((copy / MARKER).read_text())
        marker["files"][name] = sha256(copy / name)
        (copy / MARKER).write_text(json.dumps(marker))
    return copy


def test_what_is_not_a_run_is_one_line(saved, tmp_path: Path) -> None:
    _, _, folder = saved
    (tmp_path / "empty").mkdir()
    cases = [
        (tmp_path / "nowhere", "does not exist"),
        (tmp_path / "empty", "is not a run of nsm-continuation"),
        (_corrupt(folder, "branch_0.csv", "omega\n1\n", tmp_path, remark=False),
         "branch_0.csv was changed after the run"),
    ]
    for source, expected in cases:
        with pytest.raises(CaseError) as err:
            nsm.load(source)
        msg = str(err.value)
        assert msg.startswith("load: ") and expected in msg and "\n" not in msg, msg


def test_a_run_of_a_newer_format_is_one_line(saved, tmp_path: Path) -> None:
    _, _, folder = saved
    rep = json.loads((folder / "report.json").read_text())
    rep["restart"]["version"] = 2
    newer = _corrupt(folder, "report.json", json.dumps(rep), tmp_path, remark=True)
    with pytest.raises(CaseError, match=r"^load: .* holds a restart record of version 2; "
                                        r"this version reads 1$"):
        nsm.load(newer)


class _Circle(Problem):
    """``x^2 + p^2 = 1``, a problem no registry knows."""

    name: ClassVar[str] = "unregistered_circle"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, params: BaseModel | None = None) -> None:
        super().__init__(params or NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"

    def residual(self, y: Any) -> Any:
        return ca.vertcat(y[0] ** 2 + y[1] ** 2 - 1.0)


def test_a_run_of_an_unregistered_problem_is_one_line(tmp_path: Path) -> None:
    res = nsm.continuation(_Circle(), [0.6, 0.8], min=-0.9, max=0.9, max_points=5)
    folder = res.save(tmp_path / "circle", plots=False)
    with pytest.raises(CaseError, match=r"^load: .*: the run's problem cannot be rebuilt "
                                        r"\(problem 'unregistered_circle' is not registered"):
        nsm.load(folder)

