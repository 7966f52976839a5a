"""Bifurcation diagrams in one run (``nsm_continuation/runs/diagrams.py``) and
the report's links and "continue from here" lines.

Oracles: the logistic map's doublings computed here by a second method (Newton on the period-
``2^n`` orbit and its multiplier ``(f^{2^n})'(x) = -1`` in ``(x, r)``, by direct iteration, no
continuation), whose first one is ``r = 3`` and second ``1 + sqrt(6)`` in closed form; direct
iteration of every switched orbit (it returns after ``2^n`` iterations and not after
``2^(n-1)``); the transcritical normal form ``x (mu - x) = 0`` (the switched branch is
``x = mu``). The cheap stand-ins for the pendulum's cascade (``yaml_cases/
pendulum_sec6_2_cascade.yaml``, timed by ``benchmarks/bench_cascade.py``).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from helpers import CASES
from oracles.normal_forms import LogisticMap as Logistic
from oracles.normal_forms import LogisticParameters, MuParameters, Transcritical
from scipy.optimize import fsolve

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases import registry


def iterate(x: float, r: float, n: int) -> float:
    for _ in range(n):
        x = r * x * (1 - x)
    return x


def doubling_of_period(k: int, r_guess: float) -> float:
    """Second method: the ``r`` where the period-``k`` orbit's multiplier is -1, by Newton
    (``fsolve``) on ``f^k(x) = x``, ``(f^k)'(x) = -1``, from an orbit point found by iterating
    the map at ``r_guess`` (on the period-``k`` attractor)."""

    def eqs(z: np.ndarray) -> list[float]:
        x, r = z
        d, xx = 1.0, x
        for _ in range(k):
            d *= r * (1 - 2 * xx)
            xx = r * xx * (1 - xx)
        return [xx - x, d + 1]

    x0 = iterate(0.5, r_guess, 4000)
    z = fsolve(eqs, [x0, r_guess], xtol=1e-12)
    assert np.max(np.abs(eqs(z))) < 1e-12
    return float(z[1])


def logistic_diagram(depth: int = 3) -> Any:
    return nsm.continuation(Logistic(LogisticParameters()), {}, parameter="r", min=2.8,
                            max=3.57, step={"initial": 0.02, "min": 1e-9, "max": 0.05},
                            max_points=400, name="logistic_diagram",
                            analysis={"max_multiplier_step": 0.1,
                                      "branch_switching": {"depth": depth,
                                                           "kinds": ["period_doubling"]}})


@pytest.fixture(scope="module")
def diagram() -> Any:
    return logistic_diagram()


def test_cascade_in_one_run_matches_a_second_method(diagram: Any) -> None:
    """Depth 3 from the fixed point: branches 0 (period 1) .. 3 (period 8), each born at its
    parent's doubling; the four located doublings (the last on the period-8 branch, not
    followed) agree with Newton on the doubling conditions to 1e-9, the first two with their
    closed forms; the reported interval ratios are those of the second method; every point
    of every switched branch is an orbit of its period, not of half of it."""
    run = diagram.run_result
    assert [b.id for b in run.branches] == [0, 1, 2, 3]
    assert [run.branch_problems[b.id].k for b in run.branches] == [1, 2, 4, 8]
    assert [(n["depth"], n["parent"], n["event"], n["child"], n["status"]) for n in run.tree] \
        == [(g, g - 1, {"kind": "period_doubling", "index": 0}, g, "followed")
            for g in (1, 2, 3)]
    oracle = [doubling_of_period(k, r) for k, r in ((1, 2.9), (2, 3.4), (4, 3.53), (8, 3.562))]
    assert oracle[0] == pytest.approx(3.0, abs=1e-12)
    assert oracle[1] == pytest.approx(1 + np.sqrt(6), abs=1e-12)
    cascade = diagram.report()["diagram"]["period_doubling_cascade"]
    located = [p["parameter"] for p in cascade["points"]]
    assert [p["period_multiple"] for p in cascade["points"]] == [1, 2, 4, 8]
    assert np.max(np.abs(np.array(located) - oracle)) < 1e-9
    ratios = [(oracle[i + 1] - oracle[i]) / (oracle[i + 2] - oracle[i + 1]) for i in range(2)]
    assert np.allclose(cascade["ratios"], ratios, rtol=1e-6)
    assert 4.6 < ratios[1] < 4.7 < ratios[0] < 4.8  # 4.7514, 4.6562: towards 4.6692
    for b in diagram.branches[1:]:
        k = run.branch_problems[b.id].k
        for x, r in b.y:
            assert abs(iterate(x, r, k) - x) < 1e-11
            assert abs(iterate(x, r, k // 2) - x) > 1e-7


def test_ids_and_tree_are_deterministic(diagram: Any) -> None:
    """The same case twice: the same tree, the same branch ids, the same points (bitwise)."""
    again = logistic_diagram()
    assert again.run_result.tree == diagram.run_result.tree
    for a, b in zip(again.branches, diagram.branches, strict=True):
        assert (a.id, a.label) == (b.id, b.label)
        assert np.array_equal(a.y, b.y)


def test_depth_limits_the_generations() -> None:
    """depth 1: one switched branch; its own doubling is located but not followed."""
    run = logistic_diagram(depth=1).run_result
    assert len(run.branches) == 2 and len(run.tree) == 1
    assert [e.kind for e in run.branches[1].events].count("period_doubling") == 1


def test_report_says_why_the_tree_ends_early(tmp_path: Path) -> None:
    """``depth: 3`` with ``r <= 3.4``: the period-2 branch born at ``r = 3`` has no doubling
    below ``1 + sqrt(6) = 3.449``, so the tree ends at generation 1; report.md says so."""
    res = nsm.continuation(Logistic(LogisticParameters()), {}, parameter="r", min=2.8,
                           max=3.4, step={"initial": 0.02, "min": 1e-9, "max": 0.05},
                           max_points=400, analysis={"max_multiplier_step": 0.1,
                                                     "branch_switching": {"depth": 3}})
    assert [n["depth"] for n in res.run_result.tree] == [1]
    md = (res.save(tmp_path / "d", plots=False) / "report.md").read_text()
    assert ("The tree ends at generation 1: no period_doubling or branch_point event on "
            "branch 1") in md


def test_branch_point_is_not_switched_back() -> None:
    """Transcritical: the trivial branch's branch point gives ``x = mu`` (closed form at every
    point, through the origin); on it the same branch point is seen again and not followed
    (it is its birth point), so depth 3 still gives two branches."""
    res = nsm.continuation(Transcritical(MuParameters()), {}, parameter="mu", min=-0.5,
                           max=0.5, max_points=60, step={"initial": 0.05, "min": 1e-9,
                                                          "max": 0.05},
                           analysis={"branch_switching": {"depth": 3}})
    run = res.run_result
    assert len(run.branches) == 2
    x, mu = res.branches[1].y.T
    assert np.max(np.abs(x - mu)) < 1e-12 and mu.min() < -0.2 and mu.max() > 0.2
    statuses = [(n["parent"], n["status"]) for n in run.tree]
    assert statuses == [(0, "followed"),
                        (1, "not followed: the point this branch was born at")]


# ---------------------------------------------------------------------- report and paste
@pytest.fixture()
def logistic_registered(monkeypatch: pytest.MonkeyPatch) -> None:
    real = registry.get
    monkeypatch.setattr(registry, "get", lambda name: Logistic if name == Logistic.name
                        else real(name))


def _first_point(folder: Path) -> tuple[dict[str, str], list[str]]:
    rep = json.loads((folder / "report.json").read_text())
    variables = rep["restart"]["branches"][0]["variables"]
    with open(folder / "branch_0.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return next(r for r in rows if float(r["s"]) == 0.0), variables


def test_report_tree_links_figure_and_pasted_lines(diagram: Any, tmp_path: Path,
                                                   logistic_registered: None) -> None:
    """report.json / report.md of the diagram: the tree, the cascade, each child branch and
    each of its events linked to its parent, diagram.png in the chosen axes; a "continue
    from here" line pasted verbatim into a case file runs: the plain restart from the
    period-4 branch's end is that saved point after one Newton iteration, and the switch at
    the period-8 branch's doubling gives period-16 orbits (direct iteration)."""
    diagram.case.output.axes = ["r", "x"]
    folder = diagram.save(tmp_path / "diagram")
    rep = json.loads((folder / "report.json").read_text())
    md = (folder / "report.md").read_text()
    assert "diagram.png" in rep["figures"] and (folder / "diagram.png").stat().st_size > 10_000
    assert [b["parent"] for b in rep["branches"]] == [None] + [
        {"branch": g - 1, "event": {"kind": "period_doubling", "index": 0}, "depth": g}
        for g in (1, 2, 3)]
    for b in rep["branches"][1:]:
        assert all(e["parent"] == b["parent"] for e in b["events"])
    assert "| 3 | 2 | period_doubling #0 | 3.54409035955 | 3 | followed |" in md
    assert "| 3 (from branch 2, period_doubling #0) | period_doubling |" in md
    hints = {(h["branch"], h["kind"], h["index"]): h["yaml"] for h in rep["continue_from_here"]}
    assert hints[(3, "period_doubling", 0)] == (
        f"start: {{from: {folder}, branch: 3, event: {{kind: period_doubling, index: 0}}, "
        "switch: true}")
    for key, line in hints.items():
        assert f"`{line}`" in md, key
    tail = "continuation: {max_points: 4}\noutput: {plots: false, progress: false}\n"
    runs = {}
    for key in ((2, "endpoint", 0), (3, "period_doubling", 0)):
        case = tmp_path / f"{key[0]}_{key[1]}.yaml"
        case.write_text(hints[key] + "\n" + tail)
        out = tmp_path / f"out_{key[0]}_{key[1]}"
        assert cli.main(["run", str(case), "--out", str(out), "--quiet"]) == 0
        runs[key] = out
    row, variables = _first_point(runs[(2, "endpoint", 0)])
    assert row["newton_iterations"] == "1"
    [end] = [e for e in diagram.events if e.branch == 2 and e.kind == "endpoint"]
    y = np.array([float(row[f"y_{v}"]) for v in variables])
    assert np.linalg.norm(y - end.point.y, np.inf) < 1e-12
    rep16 = json.loads((runs[(3, "period_doubling", 0)] / "report.json").read_text())
    assert rep16["restart"]["branches"][0]["period_multiple"] == 16
    assert rep16["branches"][0]["parent"]["event"] == {"kind": "period_doubling", "index": 0}
    with open(runs[(3, "period_doubling", 0)] / "branch_0.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            x, rr = float(r["y_x"]), float(r["y_r"])
            assert abs(iterate(x, rr, 16) - x) < 1e-10 and abs(iterate(x, rr, 8) - x) > 1e-7


# ---------------------------------------------------------------------- bad input
BAD = [
    ("depth 0", "ndof_default.yaml", ["analysis.branch_switching={depth: 0}"],
     "analysis.branch_switching.depth: Input should be greater than or equal to 1"),
    ("depth 9", "ndof_default.yaml", ["analysis.branch_switching={depth: 9}"],
     "analysis.branch_switching.depth: Input should be less than or equal to 8"),
    ("kind", "ndof_default.yaml", ["analysis.branch_switching={kinds: [fold]}"],
     "analysis.branch_switching.kinds[0]: Input should be 'period_doubling' or"),
    ("kind twice", "ndof_default.yaml",
     ["analysis.branch_switching={kinds: [branch_point, branch_point]}"],
     "analysis.branch_switching.kinds: ['branch_point', 'branch_point'] names a kind twice"),
    ("no doubling", "ndof_default.yaml", ["analysis.branch_switching={depth: 2}"],
     "analysis.branch_switching.kinds: problem 'ndof_impact' cannot represent orbits of twice"),
    ("no detection", "ndof_default.yaml",
     ["analysis.branch_switching={kinds: [branch_point]}", "analysis.bifurcations=false"],
     "analysis.branch_switching: needs analysis.bifurcations: true"),
    ("lattice", "wfem_fig12_fep.yaml", ["analysis.branch_switching={kinds: [branch_point]}"],
     "analysis.branch_switching: problem 'wfem_bar' is continued by the lattice algorithm"),
    ("axes", "pendulum_sec6_2_period_doubling.yaml", ["output.axes=[d, nope]"],
     "output.axes[1]: 'nope' is not a quantity of problem 'double_pendulum' (one of: q2,"),
    ("one axis", "pendulum_sec6_2_period_doubling.yaml", ["output.axes=[d]"],
     "output.axes: List should have at least 2 items"),
]


@pytest.mark.parametrize(("label", "case", "overrides", "needle"), BAD, ids=[b[0] for b in BAD])
def test_bad_diagram_input_one_line_exit_2_nothing_written(tmp_path: Path, capsys: Any,
                                                           label: str, case: str,
                                                           overrides: list[str],
                                                           needle: str) -> None:
    out = tmp_path / "out"
    for command in ("validate", "run"):
        args = [command, str(CASES / case), "--out", str(out)]
        for o in overrides:
            args += ["--set", o]
        assert cli.main(args) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err, err
        assert err.startswith(f"error: {needle}"), err
    assert list(tmp_path.iterdir()) == []


def test_yaml_reference_keys_are_in_the_schema() -> None:
    """The cascade case validates as written (its keys are the documented ones)."""
    raw = yaml.safe_load((CASES / "pendulum_sec6_2_cascade.yaml").read_text())
    case = nsm.load_case(raw)
    spec = case.analysis.branch_switching
    assert (spec.depth, spec.kinds) == (3, ["period_doubling"])
    assert case.output.axes == ["d", "q2"]
