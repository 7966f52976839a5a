"""The declared Problem protocol: the core reads only declared members,
a problem with only the required members runs end to end with honest defaults, event kinds are
registered by the problem family, algorithms are chosen by ``continuation.algorithm``."""

from __future__ import annotations

import ast
import csv
import json
from pathlib import Path
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import PACKAGE
from pydantic import BaseModel, ConfigDict

from nsm_continuation.cases.schema import Case
from nsm_continuation.cases.validation import validate
from nsm_continuation.core import records
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.monitors import Monitors, admissibility
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint
from nsm_continuation.figures import branches as plots
from nsm_continuation.figures import kit, multipliers
from nsm_continuation.figures.make import make_all
from nsm_continuation.output.files import write_outputs
from nsm_continuation.runs.result import RunResult
from nsm_continuation.runs.runner import run_case


# ---------------------------------------------------------------------- (a) no probing
def _names_a_problem(node: ast.expr) -> bool:
    """``problem``, ``pr``, ``self.problem``, ``res.problem``, ``cls`` / ``self`` inside a
    Problem subclass is handled by the caller."""
    if isinstance(node, ast.Name):
        return "problem" in node.id.lower() or node.id == "pr"
    if isinstance(node, ast.Attribute):
        return "problem" in node.attr.lower() or node.attr == "pr"
    return False


def _probes(tree: ast.AST) -> list[tuple[int, str, str]]:
    """``(line, function, attribute)`` of every getattr/hasattr on a problem: on a name for a
    problem, or on ``self`` / ``cls`` inside a class whose bases name a Problem."""
    found: list[tuple[int, str, str]] = []

    def visit(node: ast.AST, in_problem_class: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inside = in_problem_class
            if isinstance(child, ast.ClassDef):
                inside = any("Problem" in ast.unparse(b) for b in child.bases)
            if (isinstance(child, ast.Call) and isinstance(child.func, ast.Name)
                    and child.func.id in ("getattr", "hasattr") and child.args):
                target = child.args[0]
                on_self = (inside and isinstance(target, ast.Name)
                           and target.id in ("self", "cls"))
                if _names_a_problem(target) or on_self:
                    attr = (child.args[1].value if len(child.args) > 1
                            and isinstance(child.args[1], ast.Constant) else "?")
                    found.append((child.lineno, child.func.id, str(attr)))
            visit(child, inside)

    visit(tree, False)
    return found


def test_no_core_module_probes_a_problem() -> None:
    files = sorted(PACKAGE.rglob("*.py"))
    assert len(files) > 15
    offenders = []
    for path in files:
        for line, fn, attr in _probes(ast.parse(path.read_text(), str(path))):
            offenders.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {fn}(..., {attr!r})")
    assert offenders == [], "undeclared members probed:\n" + "\n".join(offenders)


def test_the_probe_finder_finds_probes() -> None:
    """The checker itself: it flags probes of undeclared members (``getattr``/``hasattr`` on
    a problem)."""
    src = ("def f(pr, self):\n"
           "    a = getattr(pr, 'bound_kinds', {})\n"
           "    b = hasattr(self.problem, 'signature')\n"
           "    c = getattr(res.problem, 'fep_labels', None)\n"
           "    d = getattr(args, 'case', None)\n"
           "class P(HybridShootingProblem):\n"
           "    def g(self):\n"
           "        return getattr(self, 'watch_sticking', True)\n")
    assert [a for _, _, a in _probes(ast.parse(src))] == [
        "bound_kinds", "signature", "fep_labels", "watch_sticking"]


# ---------------------------------------------------------------------- a toy problem
class CircleParameters(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Circle(Problem):
    """``x^2 + p^2 = 1``: only the required members (name, Parameters, variables, parameter,
    residual)."""

    name: ClassVar[str] = "toy_circle"
    Parameters: ClassVar[type[BaseModel]] = CircleParameters

    def __init__(self, params: BaseModel | None = None) -> None:
        super().__init__(params or CircleParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"

    def residual(self, y: Any) -> Any:
        return ca.vertcat(y[0] ** 2 + y[1] ** 2 - 1.0)


class CircleWithKind(Circle):
    """The circle with a test function and an event kind of its own."""

    event_kinds: ClassVar[dict[str, str]] = {
        "toy_crossing": "x passes 1/2 (a kind the toy problem declares)"}
    monitors: ClassVar[Monitors] = Problem.monitors.with_(
        admissibility("x_above_half", "toy_crossing"))

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {"x_above_half": float(y[0] - 0.5)}


class CircleWithMultipliers(Circle):
    """The circle with a (made-up) multiplier that counts the calls of ``floquet``."""

    def __init__(self) -> None:
        super().__init__()
        self.floquet_calls = 0

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        self.floquet_calls += 1
        return FloquetData(np.array([0.5 * y[0] + 0j]))


def toy_case(**sections: Any) -> Case:
    raw: dict[str, Any] = {
        "name": "toy", "problem": "toy_circle", "parameters": {}, "start": {},
        "continuation": {"parameter": "p", "min": -0.95, "max": 0.95, "max_points": 300},
        "output": {"plots": True, "progress": False}}
    for key, value in sections.items():
        raw[key] = {**raw.get(key, {}), **value}
    return Case.model_validate(raw)


def run_toy(problem: Problem, **sections: Any) -> RunResult:
    start = StartPoint(np.array([1.0, 0.0]), "right half")
    return run_case(toy_case(**sections), problem, progress=False, starts=[start])


def test_required_members_only_run_with_honest_defaults(tmp_path: Path) -> None:
    pr = Circle()
    res = run_toy(pr)
    (br,) = res.branches
    ys = np.array([p.y for p in br.points])
    assert len(ys) > 10
    np.testing.assert_allclose(ys[:, 0] ** 2 + ys[:, 1] ** 2, 1.0, rtol=0, atol=1e-10)
    # both window edges reached, on the circle's right half
    assert ys[:, 1].min() == pytest.approx(-0.95, abs=1e-12)
    assert ys[:, 1].max() == pytest.approx(0.95, abs=1e-12)
    assert np.all(ys[:, 0] > 0)
    assert all(p.multipliers is None for p in br.points)
    # declared defaults: the parameter against the other unknown, labelled by the symbols
    # their names spell, linear scale
    assert pr.presentation.fep_axes == ("p", "x")
    assert pr.presentation.fep_labels == ("$p$", "$x$")
    assert pr.presentation.csv_head == ["p", "x"] and pr.presentation.event_columns == ["p", "x"]
    assert pr.algorithms == ("palc",) and pr.monitors.signature_kind is None

    out = write_outputs(res, tmp_path / "out", make_all)
    with open(out / "branch_0.csv") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][:3] == ["p", "x", "admissible"]
    np.testing.assert_allclose([float(r[0]) for r in rows[1:]], ys[:, 1], rtol=0, atol=0)
    rep = json.loads((out / "report.json").read_text())
    assert rep["event_columns"] == ["p", "x"]
    ends = [e for e in rep["branches"][0]["events"] if e["kind"] == "endpoint"]
    assert sorted(round(e["p"], 12) for e in ends) == [-0.95, 0.95]
    md = (out / "report.md").read_text()
    assert "| branch | kind | p | x |" in md
    assert rep["figures"] == ["fep.png"]  # no multipliers: no multiplier figures

    fig = plots.diagram(res)
    ax = fig.axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("$p$", "$x$")
    assert ax.get_title() == "Branch diagram"
    assert ax.get_yscale() == "linear"
    drawn = np.concatenate([ln.get_xdata() for ln in ax.get_lines() if len(ln.get_xdata()) > 1])
    assert drawn.min() == pytest.approx(-0.95) and drawn.max() == pytest.approx(0.95)


def test_paper_problems_keep_their_presentation() -> None:
    from nsm_continuation.problems.bar.continuum import BarContinuumProblem
    from nsm_continuation.problems.bar.wfem_bar import WfemBarProblem
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    for cls in (NDofImpactProblem, WfemBarProblem, BarContinuumProblem):
        assert cls.presentation_class.diagram_title == "Frequency-energy plot"
        assert cls.presentation_class.diagram_yscale == "log"
    chain = NDofImpactProblem({"chain": {"dofs": 2, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0})
    assert chain.presentation.fep_axes == ("omega", "energy")
    assert chain.presentation.fep_labels[0].startswith("frequency")
    assert chain.presentation.csv_head == ["T", "omega", "energy"]
    assert WfemBarProblem.algorithms == ("lattice",)
    assert WfemBarProblem.character_kinds == {"grazing_instants": "grazing"}


def test_hybrid_problems_label_by_their_parameter_and_period() -> None:
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    pr = DoublePendulumProblem({})
    pr.parameter_bounds("d", 0.4, 0.6)
    assert pr.presentation.fep_axes == ("d", "period")
    assert pr.presentation.fep_labels == ("wall position $d$",
                                          "period (return time to the section)")
    assert pr.presentation.csv_head[:2] == ["d", "period"]
    assert pr.presentation.diagram_title == "Bifurcation diagram"
    assert "sticking_lost" in pr.all_event_kinds()


# ---------------------------------------------------------------------- (c) event kinds
def test_problem_declared_event_kind_is_reported_with_its_meaning(tmp_path: Path) -> None:
    res = run_toy(CircleWithKind())
    (br,) = res.branches
    hits = [ev for ev in br.events if ev.kind == "toy_crossing"]
    assert len(hits) == 2  # x = 1/2 on both sides, p = +-sqrt(3)/2
    for ev in hits:
        assert abs(ev.point.y[1]) == pytest.approx(np.sqrt(0.75), abs=1e-9)
    out = write_outputs(res, tmp_path / "out")
    md = (out / "report.md").read_text()
    assert "- **toy_crossing**: x passes 1/2 (a kind the toy problem declares)" in md
    assert "| toy_crossing |" in md
    rep = json.loads((out / "report.json").read_text())
    assert rep["event_kinds"]["toy_crossing"].startswith("x passes 1/2")
    assert rep["event_kinds"]["grazing"] == records.CORE_EVENT_KINDS["grazing"]


def test_family_kinds_are_not_core_kinds() -> None:
    core = set(records.CORE_EVENT_KINDS)
    assert core == {"fold", "branch_point", "period_doubling", "neimark_sacker",
                    "unresolved_crossing", "stability_change", "grazing", "endpoint",
                    "asymptote"}
    from nsm_continuation.core.lattice import LatticeProblem
    from nsm_continuation.hybrid.problem import HybridShootingProblem

    assert set(HybridShootingProblem.event_kinds) == {
        "sticking_lost", "impact_sequence_change", "homoclinic_approach", "family_change",
        "impact_velocity_vanishes"}
    assert set(LatticeProblem.event_kinds) == {"pattern_change"}


def test_undeclared_event_kinds_are_refused() -> None:
    with pytest.raises(ValueError, match="unknown event kind 'never_declared'"):
        records.Event("never_declared", None)
    with pytest.raises(TypeError, match="'made_up' is neither a core kind"):
        class _Bad(Circle):  # noqa: F841 - the definition itself is refused
            monitors: ClassVar[Monitors] = Problem.monitors.with_(
                admissibility("x", "made_up"))
    with pytest.raises(TypeError, match="core kind"):
        class _Shadow(Circle):  # noqa: F841
            event_kinds: ClassVar[dict[str, str]] = {"fold": "my own fold"}
    with pytest.raises(TypeError, match="no signature monitor"):
        class _NoKind(Circle):  # noqa: F841
            def signature(self, y: np.ndarray) -> str | None:
                return "A"


def test_monitors_declared_with_the_earlier_maps_are_the_same_monitors() -> None:
    """A plugin written with the class-level maps of the previous release (``test_kinds``,
    ``event_function_kinds``, ``bound_kinds``, ``signature_kind``) gets the same declared
    monitors, with a DeprecationWarning naming the maps; a map it defines replaces the
    inherited one, as a class attribute did."""
    with pytest.warns(DeprecationWarning, match="test_kinds, event_function_kinds"):
        class _Legacy(Circle):
            test_kinds: ClassVar[dict[str, str]] = {"x": "stability_change"}
            event_function_kinds: ClassVar[dict[str, str]] = {"g": "branch_point"}
            bound_kinds: ClassVar[dict[str, str]] = {"x": "fold"}
            signature_kind: ClassVar[str | None] = "stability_change"

            def signature(self, y: np.ndarray) -> str | None:
                return "A"

    m = _Legacy.monitors
    assert m.kind("test", "x") == "stability_change" and m.kind("test", "other") == "grazing"
    assert m.kind("function", "g") == "branch_point"
    assert m.bound_kind("x = max") == "fold" and m.bound_kind("p = max") == "endpoint"
    assert m.signature_kind == "stability_change" and m.asymptote_names == ("energy",)
    with pytest.warns(DeprecationWarning, match="test_kinds"):
        class _Cleared(_Legacy):
            test_kinds: ClassVar[dict[str, str]] = {}
    assert _Cleared.monitors.kind("test", "x") == "grazing"
    assert _Cleared.monitors.kind("function", "g") == "branch_point"


# ---------------------------------------------------------------------- (d) algorithms
SMALL_CHAIN = {
    "name": "alg", "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 40},
    "output": {"plots": False, "progress": False},
}


def test_unsupported_algorithm_is_refused_naming_the_key() -> None:
    raw = json.loads(json.dumps(SMALL_CHAIN))
    raw["continuation"]["algorithm"] = "lattice"
    with pytest.raises(CaseError, match=r"^continuation\.algorithm: .*'lattice'") as info:
        validate(raw)
    assert "\n" not in str(info.value) and "palc" in str(info.value)
    raw["continuation"]["algorithm"] = "simplex"
    with pytest.raises(CaseError, match=r"^continuation\.algorithm"):
        validate(raw)
    bar = {"name": "b", "problem": "wfem_bar", "parameters": {"cells": 20, "gap": 1e-3},
           "start": {"branch": "main", "mode": 1},
           "continuation": {"parameter": "omega_ratio", "min": 1.0, "max": 1.4,
                            "algorithm": "palc"}}
    with pytest.raises(CaseError, match=r"^continuation\.algorithm: .*'palc'"):
        validate(bar)


def test_default_algorithm_is_the_problems_first() -> None:
    case, problem = validate(json.loads(json.dumps(SMALL_CHAIN)))
    assert case.continuation.algorithm is None
    res = run_case(case, problem, progress=False)
    assert "residual_evaluations" in res.timings and "build_casadi_s" in res.timings
    raw = json.loads(json.dumps(SMALL_CHAIN))
    raw["continuation"]["algorithm"] = "palc"
    again = run_case(*validate(raw), progress=False)
    assert [p.y.tolist() for p in again.branches[0].points] == \
        [p.y.tolist() for p in res.branches[0].points]


def test_pycont_algorithm_follows_the_same_branch() -> None:
    """``continuation.algorithm: pycont``: pycont-lite's points, analysed by the problem's
    hooks, on the branch the engine follows, cut at the energy bound or at its first phantom
    orbit (the grazing the engine locates is then between its last two points)."""
    pytest.importorskip("pycont")
    raw = json.loads(json.dumps(SMALL_CHAIN))
    raw["continuation"].update(algorithm="pycont", max_points=200, max_energy=5.0,
                               step={"initial": 0.01, "min": 1e-6, "max": 0.1})
    case, problem = validate(raw)
    res = run_case(case, problem, progress=False)
    (br,) = res.branches
    assert br.n_points > 5, br.termination
    for p in br.points:
        assert np.linalg.norm(problem.evaluate(p.y), np.inf) < 1e-8
        assert p.derived["energy"] <= 5.0
        # analysed by the problem's hooks: multipliers on the admissible points (not at the
        # start, the linear grazing orbit, where the return map is not differentiable)
        assert (p.multipliers is not None) == (p.admissible and p.s != 0.0)
    assert br.info["algorithm"].startswith("pycont-lite")
    assert res.timings["pycont_residual_evaluations"] > 0
    # the engine, from the same start, locates the grazing where pycont's branch was cut
    raw["continuation"]["algorithm"] = "palc"
    raw["analysis"] = {"stability": False}
    (ref,) = run_case(*validate(raw), progress=False).branches
    np.testing.assert_allclose(br.points[0].y, ref.points[0].y, rtol=1e-12, atol=1e-12)
    assert br.termination["forward"].startswith("admissibility: ")
    ip = problem.parameter_index
    grazing = [ev.point.y[ip] for ev in ref.events if ev.kind == "grazing"]
    last, cut = br.points[-2].y[ip], br.points[-1].y[ip]
    assert any(min(last, cut) < t < max(last, cut) for t in grazing)


def test_pycont_cuts_a_branch_at_its_first_inadmissible_point_and_says_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The bundled default case (the chain's mode 1 up to the nonlinear grazing orbit B) with
    ``algorithm: pycont``: pycont-lite would follow the phantom orbits past B; the branch ends
    at the first inadmissible point, and the engine's located grazing (a second method) lies
    between it and the point before. The report's warnings, ``report.md`` and the command
    line's last line say what pycont-lite does not check."""
    pytest.importorskip("pycont")
    import nsm_continuation as nsm
    from nsm_continuation import cli
    from nsm_continuation.algorithms.pycont_lite import PycontLite

    out = tmp_path / "pycont"
    assert cli.main(["run", "ndof_default", "--out", str(out), "--set",
                     "continuation.algorithm=pycont", "--set", "output.plots=false"]) == 0
    stdout = capsys.readouterr().out.strip().splitlines()
    assert stdout[-1] == f"warning: {PycontLite.unchecked}"
    assert "pycont-lite locates no events" in (out / "report.md").read_text()
    rep = json.loads((out / "report.json").read_text())
    assert PycontLite.unchecked in rep["warnings"]
    (branch,) = rep["branches"]
    assert branch["termination_by_direction"]["forward"].startswith("admissibility: ")
    with open(out / "branch_0.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["admissible"] for r in rows[-2:]] == ["1", "0"]
    assert all(r["admissible"] == "1" for r in rows[:-1])
    engine = nsm.run("ndof_default", {"output.plots": False})
    (grazing,) = [e for e in engine.events if e.kind == "grazing"]
    before, after = float(rows[-2]["y_T"]), float(rows[-1]["y_T"])
    assert min(before, after) < grazing.parameter < max(before, after)


# ---------------------------------------------------------------------- (e) stability switch
def test_stability_false_never_calls_floquet(monkeypatch: pytest.MonkeyPatch) -> None:
    pr = CircleWithMultipliers()
    res = run_toy(pr, analysis={"stability": False})
    assert pr.floquet_calls == 0
    assert "floquet" not in vars(pr)  # not monkeypatched on the instance
    assert res.settings.stability is False
    assert all(p.multipliers is None for br in res.branches for p in br.points)

    on = CircleWithMultipliers()
    res_on = run_toy(on)
    assert on.floquet_calls > 0
    assert all(p.multipliers is not None for br in res_on.branches for p in br.points)
    # the same branch either way
    assert [p.y.tolist() for p in res.branches[0].points] == \
        [p.y.tolist() for p in res_on.branches[0].points]
    # the multiplier plots are labelled by the continued quantity, not "frequency"
    figures: list[Any] = []
    monkeypatch.setattr(kit.Figure, "savefig", lambda fig, *a, **k: figures.append(fig))
    assert multipliers.multipliers_along(res_on, Path("unused.png"))
    assert multipliers.multipliers_plane(res_on, Path("unused.png"))
    assert figures[0].axes[2].get_xlabel() == "$p$"
    assert figures[1].axes[-1].get_ylabel() == "$p$"  # the colour bar
