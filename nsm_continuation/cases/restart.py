"""Restart a continuation from any saved point of a previous run.

The run's ``report.json`` holds a versioned restart record
(:mod:`nsm_continuation.runs.restart_record`), read back by
:mod:`nsm_continuation.cases.saved_runs`.

**A restart** is a case whose ``start:`` names a previous run (:class:`RestartSpec`)::

    start: {from: runs/chain_two_mass_wall, branch: 0, event: period_doubling}
    start: {from: runs/x, event: {kind: fold, index: 1}}      # the second fold of branch 0
    start: {from: runs/x, point: 120}                          # row 120 of branch_0.csv
    start: {from: runs/x, event: period_doubling, switch: true}   # the period-2 family

``problem:`` and ``parameters:`` are inherited from the run (a key of the case's
``parameters:`` overrides the run's), and so are ``continuation:`` (when the case continues
the same parameter, or names none) and ``analysis:``, key by key. ``continuation.parameter``
may be any parameter of the problem: the value the old continued parameter has at the point is
written into the parameters, and the new parameter's value becomes the unknown it plays
(for a hybrid orbit, the last component of ``y``). The restart point is a solution: the
corrector converges in one Newton iteration (tested).

Like AUTO's ``IRS`` (restart from a labelled solution of a previous run) and COCO's
``ode_ep2ep`` / ``ode_po2po`` constructors (restart from a saved solution, optionally in other
parameters). Everything here is checked by ``validate`` before computing: a missing folder, a
folder that is not a run of this tool (no output marker, or a ``report.json`` changed since),
a run without restart record, another problem, no such branch / event / point: one line naming
``start.from`` / ``start.branch`` / ``start.event`` / ``start.point``, exit status 2.

Branch switching at the event (``switch:``) is :mod:`nsm_continuation.algorithms.switching`.
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from nsm_continuation.cases.saved_runs import RunRecord, csv_row, load_run
from nsm_continuation.cases.schema import NAME_PATTERN, ContinuationSpec, _format
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.problem import Problem

#: event kinds at which ``start.switch`` follows another branch
SWITCH_KINDS = ("period_doubling", "branch_point")
#: at a restart from a branch point without switch, the start is moved by this (relative to
#: ``1 + |y|``) along the branch's tangent: at the point itself the tangent is not unique
BRANCH_POINT_NUDGE = 1e-6



# ---------------------------------------------------------------------- the start block
class EventSpec(BaseModel):
    """``start.event: {kind: period_doubling, index: 1}``: the event of that kind of the
    branch, counted from 0 in arclength order (as in ``report.json``)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    #: the event kind
    kind: Annotated[str, Field(min_length=1)]
    #: which event of that kind, from 0 in arclength order
    index: Annotated[int, Field(ge=0)] = 0


class RestartSpec(BaseModel):
    """``start:`` of a restart (module docstring)."""

    model_config = ConfigDict(extra="forbid", strict=True, populate_by_name=True)
    #: the saved run: its folder (a relative path is under the working directory)
    source: Annotated[str, Field(alias="from", min_length=1)]
    #: the branch's id (``branch_<id>.csv``); may be left out when the run has one branch
    branch: Annotated[int, Field(ge=0)] | None = None
    #: an event kind (the only event of that kind on the branch) or ``{kind, index}``
    event: Annotated[str, Field(min_length=1)] | EventSpec | None = None
    #: a row of ``branch_<id>.csv`` (from 0; negative counts from the end: -1 the last)
    point: int | None = None
    #: follow the other branch at the event: true, or the event's kind said again
    switch: bool | Literal["period_doubling", "branch_point"] = False
    #: the distance from the event of the first point of the switched branch (default: the
    #: first of a scan 1e-4 .. 3e-2 times 1 + |y| that gives a new solution)
    amplitude: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    #: along the continued parameter, as ``continuation.direction``; default: both ways
    #: (away from the period doubling for a switch there; onwards, out of the branch, from an
    #: ``endpoint``)
    direction: Literal["both", "increase", "decrease"] | None = None
    #: the new branch's label in the report (default: where it was born)
    label: str | None = None
    #: continue a curve of codimension-one points in two parameters from the point instead of
    #: its orbit (:mod:`nsm_continuation.hybrid.codim1`): ``grazing`` (eq. C1); any kind name
    #: here, checked once the problem is loaded (a multiplier kind or one the problem maps a
    #: test or event function to: :func:`nsm_continuation.algorithms.curves.curve_kinds`)
    curve: Annotated[str, Field(min_length=1)] | None = None
    #: how the curve is solved: ``augmented`` (the grazing curve's system C1, exact gradient;
    #: grazing only) or ``located`` (:mod:`nsm_continuation.algorithms.curves`, L1: each point an
    #: event located by a continuation of the base problem; the other kinds only). Implied by
    #: the kind; named for clarity or refused when it does not fit
    method: Literal["augmented", "located"] | None = None
    #: the curve's second parameter, solved for while ``continuation.parameter`` is continued
    #: (default: the parameter the run continued)
    free: Annotated[str, Field(min_length=1)] | None = None
    #: the distance the grazing orbits of the curve keep from the surface (times 1 + |y|)
    margin: Annotated[float, Field(gt=0, lt=1e-3, allow_inf_nan=False)] | None = None

    @property
    def event_kind(self) -> str | None:
        if self.event is None:
            return None
        return self.event if isinstance(self.event, str) else self.event.kind

    @property
    def event_index(self) -> int | None:
        return None if self.event is None or isinstance(self.event, str) else self.event.index


def is_restart(start: Any) -> bool:
    """Whether a ``start:`` block is a restart (a mapping with ``from``)."""
    return isinstance(start, dict) and "from" in start


def parse_spec(start: Any) -> RestartSpec:
    """The validated restart block; one-line :class:`CaseError` naming the key."""

    try:
        spec = RestartSpec.model_validate(start)
    except ValidationError as err:
        raise CaseError(_format(err, start, "start")) from None
    if spec.event is not None and spec.point is not None:
        raise CaseError("start.point: give start.event or start.point, not both")
    if spec.event is None and spec.point is None:
        raise CaseError("start.event: a restart needs start.event (an event of the branch) "
                        "or start.point (a row of its CSV)")
    if spec.switch is not False:
        if spec.event is None:
            raise CaseError("start.switch: a branch is switched at an event (start.event: "
                            "period_doubling or branch_point), not at start.point")
        kind = spec.event_kind
        if kind not in SWITCH_KINDS:
            raise CaseError(f"start.switch: switching is defined at {' and '.join(SWITCH_KINDS)}"
                            f" events, not at {kind!r}")
        if isinstance(spec.switch, str) and spec.switch != kind:
            raise CaseError(f"start.switch: {spec.switch!r} does not match the event's kind "
                            f"{kind!r}")
    elif spec.amplitude is not None:
        raise CaseError("start.amplitude: only used with start.switch")
    if spec.curve is None:
        for key in ("free", "margin", "method"):
            if getattr(spec, key) is not None:
                raise CaseError(f"start.{key}: only used with start.curve (a two-parameter "
                                "curve: curve: grazing)")
    elif spec.method == "augmented" and spec.curve != "grazing":
        raise CaseError(f"start.method: the augmented system is built for grazing curves; a "
                        f"{spec.curve} curve is continued by the located method (drop "
                        "start.method)")
    elif spec.margin is not None and (spec.curve != "grazing" or spec.method == "located"):
        raise CaseError("start.margin: only used with the augmented grazing curve (curve: "
                        "grazing, method: augmented)")
    elif spec.switch is not False:
        raise CaseError("start.curve: a curve continues the event itself in two parameters; "
                        "it is not a branch switch (drop start.switch)")
    return spec


# ---------------------------------------------------------------------- problem-side hooks
def period_multiple(problem: Problem) -> int:
    """:meth:`Problem.period_multiple`."""
    return int(problem.period_multiple())


def iterated(problem: Problem, multiple: int) -> Problem | None:
    """:meth:`Problem.iterated` (this instance when it already has ``multiple``)."""
    if multiple == period_multiple(problem):
        return problem
    return problem.iterated(multiple)


def restart_start(problem: Problem, y: np.ndarray) -> Any:
    """:meth:`Problem.restart_start`."""
    return problem.restart_start(y)


@dataclass
class Selection:
    """The restart point: its branch record, its unknowns ``y`` in the run's variables, its
    event (None for a CSV row) and what to show in labels."""

    branch: dict[str, Any]
    y: np.ndarray
    event: dict[str, Any] | None
    what: str

    @property
    def variables(self) -> list[str]:
        return list(self.branch["variables"])

    @property
    def parameter(self) -> str:
        return str(self.branch["parameter"])

    @property
    def tangent(self) -> np.ndarray | None:
        if self.event is None or self.event.get("tangent") is None:
            return None
        return np.asarray(self.event["tangent"], dtype=float)

    #: the chart of ``y`` (``Point.chart``; None: the problem's own), set by :func:`select`
    chart: dict[str, float] | None = None


def _kinds(events: list[dict[str, Any]]) -> str:
    counts: dict[str, int] = {}
    for e in events:
        counts[e["kind"]] = counts.get(e["kind"], 0) + 1
    return ", ".join(f"{k} x{n}" for k, n in counts.items()) or "none"


def select(record: RunRecord, spec: RestartSpec) -> Selection:
    """The branch and point ``spec`` names in ``record``; :class:`CaseError` naming
    ``start.branch`` / ``start.event`` / ``start.point`` when there is none."""
    branches = record.restart.get("branches") or []
    ids = [b.get("id") for b in branches]
    if spec.branch is None:
        if len(branches) != 1:
            raise CaseError(f"start.branch: {record.label} has {len(branches)} branches "
                            f"(ids {', '.join(map(str, ids))}); choose one")
        br = branches[0]
    else:
        match = [b for b in branches if b.get("id") == spec.branch]
        if not match:
            raise CaseError(f"start.branch: {record.label} has no branch {spec.branch} (ids "
                            f"{', '.join(map(str, ids)) or 'none'})")
        br = match[0]
    where = f"branch {br['id']} of {record.label}"
    n = int(br.get("n_points", 0))
    if n == 0:
        raise CaseError(f"start.branch: {where} has no points (its start failed)")
    if spec.event is not None:
        kind = spec.event_kind
        evs = [e for e in br.get("events", []) if e.get("kind") == kind]
        if not evs:
            raise CaseError(f"start.event: {where} has no {kind} event (its events: "
                            f"{_kinds(br.get('events', []))})")
        index = spec.event_index
        if index is None:
            if len(evs) > 1:
                values = ", ".join(f"{e['parameter']:.8g}" for e in evs[:6])
                raise CaseError(f"start.event: {where} has {len(evs)} {kind} events (at "
                                f"{br['parameter']} = {values}{', ...' if len(evs) > 6 else ''});"
                                f" choose one with event: {{kind: {kind}, index: "
                                f"0..{len(evs) - 1}}}")
            index = 0
        if index >= len(evs):
            raise CaseError(f"start.event.index: {where} has {len(evs)} {kind} event"
                            f"{'s' if len(evs) != 1 else ''} (index 0..{len(evs) - 1}), "
                            f"not {index}")
        ev = evs[index]
        y = np.asarray(ev["y"], dtype=float)
        what = f"{kind} #{index} of branch {br['id']}"
        sel = Selection(br, y, ev, what, ev.get("chart") or None)
    else:
        assert spec.point is not None
        row = spec.point if spec.point >= 0 else n + spec.point
        if not 0 <= row < n:
            raise CaseError(f"start.point: {where} has {n} points (rows 0..{n - 1}), not "
                            f"{spec.point}")
        y = csv_row(record, br, row)
        moves = [c for c in br.get("charts", []) if int(c["from_row"]) <= row]
        sel = Selection(br, y, None, f"point {row} of branch {br['id']}",
                        (moves[-1]["chart"] or None) if moves else None)
    if y.size != len(br["variables"]) or not np.all(np.isfinite(y)):
        raise CaseError(f"start.from: the unknowns of {sel.what} in {record.label} are not "
                        f"{len(br['variables'])} finite numbers")
    return sel


# ---------------------------------------------------------------------- the new case
def _deep_merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``base`` with the keys of ``over`` (mappings merged key by key)."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def inherit_raw(raw: dict[str, Any], record: RunRecord, sel: Selection,
                spec: RestartSpec) -> dict[str, Any]:
    """The raw case with what a restart inherits from the run (module docstring):
    ``problem`` (checked), ``continuation`` (same or no parameter named) and ``analysis``, key
    by key under the case's own; a default ``name``. The parameters are merged later
    (:func:`merged_parameters`, they need the problem's vocabulary)."""
    out = copy.deepcopy(raw)
    problem = record.restart.get("problem")
    if raw.get("problem") is None:
        out["problem"] = problem
    elif raw["problem"] != problem:
        raise CaseError(f"start.from: {record.label} is a run of problem {problem!r}, not of "
                        f"{raw['problem']!r} (problem:)")
    if out.get("parameters") is None:
        out["parameters"] = {}
    old = record.case_input
    cont = raw.get("continuation", {})
    if isinstance(cont, dict) and isinstance(old.get("continuation"), dict):
        same = cont.get("parameter") in (None, old["continuation"].get("parameter"))
        if same:
            out["continuation"] = _deep_merge(old["continuation"], cont)
    if isinstance(raw.get("analysis", {}), dict) and isinstance(old.get("analysis"), dict):
        out["analysis"] = _deep_merge(old["analysis"], raw.get("analysis", {}))
    if "name" not in raw:

        base = str(old.get("name", "run"))
        suffix = "_switch" if spec.switch is not False else "_restart"
        name = base[: 100 - len(suffix)] + suffix
        out["name"] = name if re.match(NAME_PATTERN, name) else "restart"
    return out


def merged_parameters(record: RunRecord, sel: Selection, user: dict[str, Any]
                      ) -> dict[str, Any]:
    """The run's full parameters, the old continued parameter set to its value at the point
    (when it is a parameter), then the case's own ``parameters:`` (already in canonical names)
    on top, key by key."""
    params = copy.deepcopy(record.restart.get("parameters") or {})
    # the continued parameter, and any other unknown that is a parameter (the free one of a
    # two-parameter curve, the partner of a continuation in the period)
    for k, name in enumerate(sel.variables):
        if name in params and not isinstance(params[name], dict | list | bool):
            params[name] = float(sel.y[k])
    return _deep_merge(params, user)


def _parameter_value(params: dict[str, Any], name: str) -> float | None:
    """The number ``name`` in ``parameters:``, at the top or one level down (the chain's
    ``chain: {stiffness: ...}``); None if there is none."""
    for where in (params, *(v for v in params.values() if isinstance(v, dict))):
        v = where.get(name)
        if isinstance(v, int | float) and not isinstance(v, bool):
            return float(v)
    return None


def map_unknowns(problem: Problem, sel: Selection, user: dict[str, Any],
                 params: dict[str, Any]) -> np.ndarray:
    """The restart point in the unknowns of ``problem`` (which may continue another
    parameter): each unknown from the run's point by name, except the continued parameter
    when the case's ``parameters:`` set it; a parameter that is no unknown of the run (the
    new continued one) from the parameters."""
    y = np.empty(problem.dim)
    old = sel.variables
    for k, name in enumerate(problem.variables):
        if name == problem.parameter and name in user and not isinstance(user[name], dict):
            y[k] = float(user[name])
        elif name in old:
            y[k] = sel.y[old.index(name)]
        elif _parameter_value(params, name) is not None:
            y[k] = float(_parameter_value(params, name))  # type: ignore[arg-type]
        else:
            raise CaseError(f"start.from: the unknown {name!r} of problem {problem.name!r} is "
                            f"neither an unknown of the run ({', '.join(old)}) nor a "
                            "parameter")
    return y


@dataclass
class Restart:
    """A validated restart (attached to the :class:`~nsm_continuation.cases.schema.Case` by
    ``validate``, used by :func:`nsm_continuation.runs.runner.run_case`): the point ``y`` in the
    unknowns of the problem to continue, and for a switch the problem it was found on
    (``base``: the period-``k`` problem at a period doubling)."""

    spec: RestartSpec
    record: RunRecord
    selection: Selection
    y: np.ndarray
    base: Problem
    switch: str | None = None
    #: +1 / -1 / 0 along the internal parameter (``StartPoint.direction``); None: the
    #: switch's own default
    direction: int | None = None
    #: the case's ``parameters:`` change some of the run's: the point is only a guess there,
    #: corrected at fixed parameter (not along the saved tangent)
    overridden: bool = False
    #: a two-parameter curve from the point (``start.curve``): its kind and free parameter
    curve: str | None = None
    free: str | None = None

    @property
    def same_unknowns(self) -> bool:
        return list(self.base.variables) == self.selection.variables

    def label(self) -> str:
        if self.spec.label:
            return self.spec.label
        sel = self.selection
        if self.curve is not None:
            return (f"{self.curve} curve in ({self.free}, {self.base.parameter}) from the "
                    f"{sel.what} of {self.record.label}")
        if self.switch == "period_doubling":
            k = 2 * period_multiple(self.base)
            return f"period-{k} orbit from the {sel.what} of {self.record.label}"
        if self.switch == "branch_point":
            return f"other branch at the {sel.what} of {self.record.label}"
        return f"restart from the {sel.what} of {self.record.label}"

    def info(self) -> dict[str, Any]:
        spec = self.spec
        ev = self.selection.event
        out: dict[str, Any] = {"restart_from": self.record.label,
                               "restart_branch": int(self.selection.branch["id"]),
                               "period_multiple": period_multiple(self.base)}
        if ev is not None:
            out.update({"restart_event": ev["kind"], "restart_event_index": int(ev["index"])})
        else:
            out["restart_point"] = int(spec.point) if spec.point is not None else None
        if self.switch is not None:
            out["switch"] = self.switch
        if self.curve is not None:
            out.update({"curve": self.curve, "free": self.free})
        return out


@dataclass
class CurveSpec:
    """The curve a restart continues (:func:`curve_of`)."""

    kind: str
    free: str
    #: ``augmented`` (C1, grazing) or ``located`` (L1); None: the kind's (:func:`configure`)
    method: str | None
    margin: float | None


def curve_of(spec: RestartSpec, record: RunRecord) -> CurveSpec | None:
    """The curve a restart continues: the case's ``start.curve`` / ``free`` / ``method`` /
    ``margin``, else the run's own when the run is a curve (a restart from a curve continues
    it), else None."""
    saved = record.restart.get("curve") or {}
    kind = spec.curve or saved.get("kind")
    if kind is None:
        return None
    free = spec.free or saved.get("free") or record.restart.get("continued")
    margin = spec.margin if spec.margin is not None else saved.get("margin")
    method = spec.method or saved.get("method")
    return CurveSpec(str(kind), str(free), method, margin)


def located_curve(problem: Problem, sel: Selection, record: RunRecord, parameter: str,
                  curve: CurveSpec) -> Problem:
    """The curve of ``curve.kind`` points of ``problem`` through the selected event, by the
    located method (:class:`~nsm_continuation.algorithms.curves.LocatedCurve`, eq. L1); one-line
    :class:`CaseError` naming the key where it cannot be built."""
    from nsm_continuation.algorithms.curves import LocatedCurve

    if not record.restart.get("curve"):
        kind = sel.event["kind"] if sel.event is not None else None
        if kind != curve.kind:
            what = (f"{'an' if kind[0] in 'aeiou' else 'a'} {kind} event" if kind is not None
                    else "a CSV row (start.point)")
            raise CaseError(f"start.curve: a {curve.kind} curve starts from a {curve.kind} "
                            f"event of the run (start.event: {curve.kind}), not from {what}")
    continued = record.restart.get("continued")
    if not record.restart.get("curve") and curve.free != continued:
        raise CaseError(f"start.free: the located {curve.kind} curve solves for the "
                        f"parameter the run continued ({continued}), not {curve.free!r}")
    saved = (record.restart.get("curve") or {}).get("base_settings")
    try:
        if saved is None:  # a run of the base problem: its own settings

            c = ContinuationSpec.model_validate(record.case_input.get("continuation") or {})
            saved = {"newton_tol": c.newton_tol, "step_initial": c.step.initial,
                     "derived_bounds": {k: list(v) for k, v in c.bounds.items()}}
        return LocatedCurve(problem, curve.kind, curve.free, parameter, saved)
    except ValueError as exc:
        msg = str(exc)
        raise CaseError(msg if msg.startswith(("start.", "continuation."))
                        else f"start.curve: {msg}") from None


def grazing_curve(problem: Problem, sel: Selection, spec: RestartSpec, record: RunRecord,
                  parameter: str, free: str, margin: float | None) -> Problem:
    """The grazing curve of ``problem`` by its own augmented system (:meth:`Problem.curve`,
    e.g. a hybrid problem with the run's period multiple) through the selected point,
    ``free`` solved for and ``parameter`` continued; one-line :class:`CaseError` naming
    ``start.curve`` / ``start.free`` / ``continuation.parameter`` where it cannot be built."""
    names = problem.curve_parameters()
    if not names:
        raise CaseError(f"start.curve: problem {problem.name!r} is not a hybrid system; "
                        "grazing curves are continued for the orbits of hybrid problems "
                        "(impact_oscillator, two_mass_chain, double_pendulum, ...)")
    if not record.restart.get("curve"):
        kind = sel.event["kind"] if sel.event is not None else None
        if kind != "grazing":
            what = (f"{'an' if kind[0] in 'aeiou' else 'a'} {kind} event" if kind is not None
                    else "a CSV row (start.point)")
            raise CaseError(f"start.curve: a grazing curve starts from a grazing event of "
                            f"the run (start.event: grazing), not from {what}")
    known = sorted(names)
    if free not in names:
        raise CaseError(f"start.free: {free!r} is not a parameter of {problem.name!r} (one "
                        f"of {known})")
    if parameter == free:
        raise CaseError(f"start.free: the grazing curve needs two parameters, and {free!r} "
                        "is the one continued (continuation.parameter); continue another "
                        f"one (one of {[k for k in known if k != free]})")
    if parameter not in names:
        raise CaseError(f"continuation.parameter: {parameter!r} is not a parameter of "
                        f"{problem.name!r} (one of {known})")
    try:
        curve = problem.curve("grazing", free, parameter, margin)
    except ValueError as exc:
        raise CaseError(f"start.curve: {exc}") from None
    if curve is None:
        raise CaseError(f"start.curve: problem {problem.name!r} has no augmented system for "
                        "grazing curves (Problem.curve); drop start.method")
    return curve


def configure(problem: Problem, sel: Selection, spec: RestartSpec, record: RunRecord,
              parameter: str | None = None) -> tuple[Problem, Problem]:
    """``(problem to continue, base problem)``: the base has the run's period multiple; at a
    period-doubling switch the problem to continue has twice it (:func:`iterated`); for a
    two-parameter curve (``start.curve``, or a run that is a curve) both are the curve, in
    ``parameter`` (``continuation.parameter``) and its free parameter."""
    k = int(sel.branch.get("period_multiple", 1) or 1)
    base = iterated(problem, k)
    if base is None:
        raise CaseError(f"start.from: {sel.what} of {record.label} is an orbit of {k} base "
                        f"periods, which problem {problem.name!r} cannot represent")
    # the point's unknowns are those of its chart (the run may have moved its section)
    base = base.in_chart(sel.chart)
    cs = curve_of(spec, record)
    if cs is not None:
        from nsm_continuation.algorithms.curves import curve_kind_refusal

        refusal = curve_kind_refusal(base, cs.kind)
        if refusal is not None:
            raise CaseError(refusal)
        # a problem with grazing-curve parameters continues its grazing curves by C1
        hybrid = bool(base.curve_parameters())
        if cs.kind == "grazing" and hybrid and cs.method == "located":
            raise CaseError("start.method: the grazing curve of a hybrid orbit is continued "
                            "by its augmented system (C1): at a grazing the family of orbits "
                            "has a nonsmooth fold that a continuation of the base problem "
                            "does not locate reliably (drop start.method)")
        if cs.method is None:
            cs.method = "augmented" if cs.kind == "grazing" and hybrid else "located"
        if cs.method == "located":
            curve = located_curve(base, sel, record, parameter or base.parameter, cs)
        else:
            curve = grazing_curve(base, sel, spec, record, parameter or base.parameter,
                                  cs.free, cs.margin)
        return curve, curve
    if spec.switch is False or spec.event_kind != "period_doubling":
        return base, base
    doubled = iterated(base, 2 * k)
    if doubled is None:
        raise CaseError(f"start.switch: problem {problem.name!r} cannot represent orbits of "
                        f"twice the period (Problem.iterated), so the period-{2 * k} family "
                        "cannot be continued")
    return doubled, base


def check_start(problem: Problem, y: np.ndarray, window: tuple[float | None, float | None],
                max_points: int) -> None:
    """The checks of an ordinary start at ``y``: the problem's preflight on its own start
    block (:func:`restart_start`), else the continued parameter's value in the window."""
    block = restart_start(problem, y)
    if block is not None:
        try:
            problem.preflight(block, window, max_points)
        except (ValueError, ArithmeticError) as exc:
            # the problem names the key of its own start block (``start.T: ...``): the user
            # wrote start.from, and the restart point is what fails the check
            msg = str(exc)
            if msg.startswith("start."):
                msg = msg.split(": ", 1)[-1]
            raise CaseError(f"start.from: the restart point fails the start checks: "
                            f"{msg}") from None
        return
    p = float(y[problem.parameter_index])
    lo, hi = window
    if (lo is not None and p < lo) or (hi is not None and p > hi):
        show = (f"[{lo if lo is not None else -np.inf:.10g}, "
                f"{hi if hi is not None else np.inf:.10g}]")
        raise CaseError(f"start.from: the restart point has {problem.parameter} = {p:.10g}, "
                        f"outside the continuation window {show} of {problem.parameter} "
                        "(continuation.min/max)")


def resolve(raw_start: Any, raw: dict[str, Any], record: RunRecord | None
            ) -> tuple[RestartSpec, RunRecord, Selection, dict[str, Any]]:
    """Parse ``start:``, read the run (unless ``record`` is given), select the point and
    return the raw case with what it inherits (:func:`inherit_raw`)."""
    spec = parse_spec(raw_start)
    rec = record if record is not None else load_run(spec.source)
    sel = select(rec, spec)
    return spec, rec, sel, inherit_raw(raw, rec, sel, spec)


def direction_of(spec: RestartSpec, problem: Problem, parameter: str) -> int | None:
    """``start.direction`` along the internal parameter (None: not given)."""
    if spec.direction is None:
        return None
    d = {"both": 0, "increase": 1, "decrease": -1}[spec.direction]
    return d * problem.parameter_orientation(parameter)


def start_points(r: Restart, problem: Problem, settings: Any) -> tuple[list[Any], dict[str, Any]]:
    """The start of a restart (``(starts, counters)``): the saved point itself, with its
    tangent when the unknowns and parameters are the run's (corrected on the
    pseudo-arclength condition: one Newton iteration; else at fixed parameter, as any
    guess), or the first point of the switched branch
    (:func:`nsm_continuation.algorithms.switching.switch_start`)."""
    from nsm_continuation.algorithms.base import TangentStart

    if r.switch is not None:
        from nsm_continuation.algorithms.switching import Switch, switch_start

        switch = Switch(r.y, r.switch, r.base, r.selection.tangent, r.spec.amplitude,
                        r.direction, r.label(), r.info())
        return switch_start(switch, problem, settings)
    y = np.array(r.y, dtype=float)
    t = r.selection.tangent if r.same_unknowns and not r.overridden else None
    from nsm_continuation.algorithms.curves import LocatedCurve

    if isinstance(problem, LocatedCurve):
        # the base branch's tangent, where the event is located again (none from a curve)
        t = None if r.record.restart.get("curve") else r.selection.tangent
    ev = r.selection.event
    if t is not None and ev is not None and ev["kind"] == "branch_point":
        # the tangent is not unique at a branch point: start just beside it on this branch
        y = y + BRANCH_POINT_NUDGE * (1.0 + float(np.linalg.norm(y, np.inf))) * t
    if t is not None and ev is not None and ev["kind"] == "endpoint" and r.direction is None:
        # from a branch's end, onwards: the saved tangent of an end points the way its half of
        # the branch was going (out of the branch), so the branch is extended, not walked again
        # back over the saved points; ``start.direction`` asks for both ways or one explicitly
        return [TangentStart(y, r.label(), 1, r.info(), tangent=t, forward_only=True)], {}
    direction = r.direction if r.direction is not None else 0
    return [TangentStart(y, r.label(), direction, r.info(), tangent=t)], {}


__all__ = ["EventSpec", "Restart", "RestartSpec", "Selection", "configure", "is_restart",
           "iterated", "period_multiple", "restart_start", "select"]
