"""The declared hooks the restart record and the ``continue_from_here`` hints read (one
declared contract): ``Problem.parameters_block`` and ``Problem.curve_parameters``.

The results, restart and report modules read only these declared members (no
``isinstance(problem, HybridCaseProblem)``, no undeclared ``values``, no probing of
``params.model_dump`` through ``except AttributeError``, no pendulum's ``d`` written in), so a
problem of any family that declares them gets the same hints."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import PACKAGE
from pydantic import BaseModel, ConfigDict

from nsm_continuation.cases.schema import Case
from nsm_continuation.core import problem as protocol
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.output.files import hint_context, write_outputs
from nsm_continuation.output.report import continue_hints
from nsm_continuation.runs.runner import run_case


class ToyParameters(BaseModel):
    model_config = ConfigDict(extra="forbid")
    a: float = 0.0
    b: float = 2.0
    c: float = 3.0


class Toy(Problem):
    """``x^2 + a^2 = 1`` with an event function ``x - 1/2`` (a grazing that does not end the
    branch): only the required members."""

    name: ClassVar[str] = "toy_contract"
    Parameters: ClassVar[type[BaseModel]] = ToyParameters

    def __init__(self, params: Any = None) -> None:
        super().__init__(ToyParameters() if params is None else params)
        self.variables = ["x", "a"]
        self.parameter = "a"

    def residual(self, y: Any) -> Any:
        return ca.vertcat(y[0] ** 2 + y[1] ** 2 - 1.0)

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        return {"x_half": float(y[0] - 0.5)}


class ToyWithCurves(Toy):
    """The toy declaring grazing-curve parameters: ``c`` preferred to ``b``."""

    def curve_parameters(self) -> list[str]:
        return ["c", "a", "b"]


# ---------------------------------------------------------------------- (a) the defaults
def test_base_defaults_are_the_documented_ones() -> None:
    """No grazing-curve parameters, and the parameters block is the ``params`` model dumped
    in JSON mode (None when ``params`` is not a pydantic model); both documented in the
    module docstring's list of the contract."""
    pr = Toy(ToyParameters(a=0.5))
    assert pr.curve_parameters() == []
    assert pr.parameters_block() == {"a": 0.5, "b": 2.0, "c": 3.0}
    assert Toy({"a": 1.0}).parameters_block() is None
    doc = protocol.__doc__ or ""
    for name in ("parameters_block", "curve_parameters"):
        assert f":meth:`{name}`" in doc
        assert "Default" in (getattr(Problem, name).__doc__ or "")
    assert "default none" in doc and "default the ``params`` model, dumped" in doc


def test_core_reads_no_undeclared_hybrid_member() -> None:
    """results / restart / report name neither the hybrid class nor its ``values``, and do not
    probe for attributes through AttributeError."""
    for mod in ("output/files.py", "cases/restart.py", "output/report.py"):
        text = (PACKAGE / mod).read_text()
        assert "HybridCaseProblem" not in text, mod
        assert "except AttributeError" not in text, mod
        assert "problem.values" not in text and "pr.values" not in text, mod
    assert "CURVE_PREFERENCE" not in (PACKAGE / "output" / "report.py").read_text()


# ---------------------------------------------------------------------- (b) the hints
def toy_case() -> Case:
    return Case.model_validate({
        "name": "toy", "problem": "toy_contract", "parameters": {}, "start": {},
        "continuation": {"parameter": "a", "min": -0.95, "max": 0.95, "max_points": 300},
        "output": {"plots": False, "progress": False}})


def toy_report(problem: Problem, tmp_path: Path) -> dict[str, Any]:
    start = StartPoint(np.array([1.0, 0.0]), "right half")
    res = run_case(toy_case(), problem, progress=False, starts=[start])
    out = write_outputs(res, tmp_path / "out")
    return json.loads((out / "report.json").read_text())


def test_a_non_hybrid_problem_declaring_curve_parameters_gets_the_grazing_curve_hint(
        tmp_path: Path) -> None:
    """The toy continued in ``a`` grazes twice (x = 1/2); declaring ``curve_parameters`` its
    grazing hints are the grazing curve freeing ``a`` and continuing the first other declared
    parameter (``c``), in the same form as a hybrid problem's
    (tests/cases/test_grazing_curves_from_yaml.py); without the declaration, the orbit
    restarted."""
    rep = toy_report(ToyWithCurves(), tmp_path / "with")
    folder = tmp_path / "with" / "out"
    grazing = [h for h in rep["continue_from_here"] if h["kind"] == "grazing"]
    assert len(grazing) == 2
    for h in grazing:
        assert h["yaml"] == (f"start: {{from: {folder}, event: {{kind: grazing, index: "
                             f"{h['index']}}}, curve: grazing, free: a}}\n"
                             "continuation: {parameter: c}")
        assert h["what"].startswith("the grazing curve in (a, c) through this orbit")
    plain = toy_report(Toy(), tmp_path / "without")
    grazing = [h for h in plain["continue_from_here"] if h["kind"] == "grazing"]
    assert len(grazing) == 2
    assert all("curve" not in h["yaml"] for h in grazing)
    assert all(h["what"].startswith("this orbit, restarted") for h in grazing)
    # the restart record's parameters: the declared block
    assert rep["restart"]["parameters"] == {"a": 0.0, "b": 2.0, "c": 3.0}


def test_hint_context_reads_the_declared_hook() -> None:
    res = SimpleNamespace(problem=ToyWithCurves())
    assert hint_context(res) == {"doubling": False,  # type: ignore[arg-type]
                                 "curve_parameters": ["c", "a", "b"]}


def _old_second(values: list[str], continued: str) -> str | None:
    """The second parameter of a hybrid problem's ``values`` by the rule written out: ``gap``
    or ``d`` if not continued, else the first other value."""
    others = [q for q in values if q != continued]
    return next((q for q in ("gap", "d") if q in others), others[0] if others else None)


def _hint_second(curve_parameters: list[str], continued: str) -> str | None:
    restart = {"continued": continued, "branches": [
        {"id": 0, "events": [{"kind": "grazing", "index": 0, "parameter": 0.0}]}]}
    [h] = continue_hints(restart, "runs/x", curve_parameters=curve_parameters)
    if "\ncontinuation: {parameter: " not in h["yaml"]:
        return None
    return h["yaml"].split("\ncontinuation: {parameter: ")[1].rstrip("}")


@pytest.mark.parametrize("module, cls, first", [
    ("impact_oscillator", "ImpactOscillatorProblem", "gap"),
    ("two_mass_chain", "TwoMassChainProblem", "gap"),
    ("double_pendulum", "DoublePendulumProblem", "d"),
])
def test_hybrid_problems_keep_their_grazing_curve_hints(module: str, cls: str,
                                                        first: str) -> None:
    """A hybrid problem's ``curve_parameters`` are its parameters, the obstacle position first:
    for every continued parameter the hint's second parameter is the one the report chose
    from the undeclared ``values`` before (``gap``, then ``d``, then the first other)."""
    import importlib

    problem_cls = getattr(importlib.import_module(
        f"nsm_continuation.problems.impacting.{module}"), cls)
    pr = problem_cls({})
    names = pr.curve_parameters()
    assert names[0] == first
    assert sorted(names) == sorted(pr.values)
    for continued in names:
        assert _hint_second(names, continued) == _old_second(list(pr.values), continued)
