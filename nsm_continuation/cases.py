"""YAML cases: schema, validation and ``--set`` overrides.

Every error is a :class:`CaseError` whose message is one line naming the offending key
(``continuation.step.min: ...``); the command line prints it and exits with status 2 before
anything is written.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from . import registry
from .problem import Problem

PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
PosInt = Annotated[int, Field(ge=1)]


class CaseError(ValueError):
    """Bad input: the message names the key and what is wrong."""


class StepSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    initial: PosFloat = 1e-2
    min: PosFloat = 1e-9
    max: PosFloat = 0.2

    @model_validator(mode="after")
    def _order(self) -> StepSpec:
        if not self.min <= self.initial <= self.max:
            raise ValueError(f"need min <= initial <= max (got {self.min}, {self.initial}, "
                             f"{self.max})")
        return self


class ContinuationSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    parameter: str = "omega"
    min: Finite | None = None
    max: Finite | None = None
    step: StepSpec = StepSpec()
    max_points: PosInt = 400
    max_energy: PosFloat | None = None
    direction: Literal["both", "increase", "decrease"] = "both"
    newton_tol: PosFloat = 1e-11
    max_angle: PosFloat = 0.25
    #: bounds on derived quantities ``{name: [min, max]}`` (null for none), e.g.
    #: ``period: [null, 60]``; the branch stops where one is reached (an event of the kind the
    #: problem maps the quantity to, e.g. ``homoclinic_approach`` for the period)
    bounds: dict[str, tuple[Finite | None, Finite | None]] = {}

    @model_validator(mode="after")
    def _bounds(self) -> ContinuationSpec:
        if self.min is not None and self.max is not None and self.min >= self.max:
            raise ValueError(f"need min < max (got min = {self.min}, max = {self.max})")
        return self


class AnalysisSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    stability: bool = True
    bifurcations: bool = True
    stop_on_inadmissible: bool = False
    stability_on_phantom: bool = False
    unit_circle_tol: PosFloat = 1e-7
    event_tol: PosFloat = 1e-12
    multiplier_event_tol: PosFloat = 1e-9
    max_multiplier_step: PosFloat = 0.02


class OutputSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    dir: str | None = None
    plots: bool = True
    progress: bool = True


class Case(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str = "case"
    description: str = ""
    problem: str
    parameters: dict[str, Any]
    start: Any
    continuation: ContinuationSpec = ContinuationSpec()
    analysis: AnalysisSpec = AnalysisSpec()
    output: OutputSpec = OutputSpec()


def _format(err: ValidationError, prefix: str = "") -> str:
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"] if not str(p).startswith("function-after"))
    # drop pydantic's union-member tags (e.g. 'ModeStart') from the location
    parts = [p for p in loc.split(".")
             if p and not (p[0].isupper() and any(ch.islower() for ch in p))]
    where = ".".join(([prefix] if prefix else []) + parts)
    msg = e["msg"].removeprefix("Value error, ")
    extra = " (unknown key)" if e["type"] == "extra_forbidden" else ""
    return f"{where or prefix or 'case'}: {msg}{extra}"


def _reject_nan(obj: Any, where: str) -> None:
    if isinstance(obj, float) and not math.isfinite(obj):
        raise CaseError(f"{where}: {obj} is not a finite number")
    if isinstance(obj, dict):
        for k, v in obj.items():
            _reject_nan(v, f"{where}.{k}" if where else str(k))
    if isinstance(obj, list):
        for i, v in enumerate(obj):
            _reject_nan(v, f"{where}[{i}]")


def apply_overrides(raw: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Apply ``dotted.key=value`` overrides (values parsed as YAML)."""
    out = copy.deepcopy(raw)
    for item in overrides:
        if "=" not in item:
            raise CaseError(f"--set {item!r}: expected dotted.key=value")
        key, value = item.split("=", 1)
        parts = key.strip().split(".")
        if not all(parts):
            raise CaseError(f"--set {item!r}: empty key")
        node = out
        for p in parts[:-1]:
            if not isinstance(node.get(p, {}), dict):
                raise CaseError(f"--set {key}: {p} is not a mapping")
            node = node.setdefault(p, {})
        try:
            node[parts[-1]] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise CaseError(f"--set {key}: value is not valid YAML ({exc})") from None
    return out


def load_raw(path: str | Path) -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise CaseError(f"case file: {path} does not exist")
    try:
        raw = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        at = f" (line {line + 1})" if line is not None else ""
        raise CaseError(f"case file: {path} is not valid YAML{at}") from None
    if not isinstance(raw, dict):
        raise CaseError(f"case file: {path} must contain a mapping of keys")
    return raw


def validate(raw: dict[str, Any]) -> tuple[Case, Problem]:
    """Validate a raw case and build its problem; raises :class:`CaseError`."""
    _reject_nan(raw, "")
    try:
        case = Case.model_validate(raw)
    except ValidationError as err:
        raise CaseError(_format(err)) from None
    try:
        cls = registry.get(case.problem)
    except registry.UnknownProblemError as exc:
        raise CaseError(f"problem: {exc}") from None
    try:
        params = cls.Parameters.model_validate(case.parameters)
    except ValidationError as err:
        raise CaseError(_format(err, "parameters")) from None
    try:
        problem = cls(params)
    except ValueError as exc:
        raise CaseError(f"parameters: {exc}") from None
    adapter = getattr(cls, "start_adapter", None)
    if adapter is not None:
        try:
            adapter.validate_python(case.start)
        except ValidationError as err:
            raise CaseError(_format(err, "start")) from None
    try:
        problem.parameter_bounds(case.continuation.parameter, case.continuation.min,
                                 case.continuation.max)
    except ValueError as exc:
        raise CaseError(str(exc)) from None
    return case, problem


def load(path: str | Path, overrides: list[str] | None = None) -> tuple[Case, Problem]:
    raw = apply_overrides(load_raw(path), overrides or [])
    return validate(raw)
