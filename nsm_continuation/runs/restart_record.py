"""The restart record of a run: the versioned ``restart`` block of ``report.json``.

The block (format :data:`~nsm_continuation.cases.saved_runs.RESTART_FORMAT`) holds the
problem's name and its *full* validated parameters, the continued parameter (as the case named
it), and per branch the names of the unknowns, the unknown that is the parameter, the period
multiple (returns to the section per period of a hybrid orbit) and every event with its kind,
its ordinal among the events of that kind, the CSV row of its point (or None: events are
located between the points) and its unknowns ``y`` and unit tangent, exactly (JSON floats are
written in repr precision, as the CSV's ``y_<name>`` columns are). A restart reads it back
(:mod:`nsm_continuation.cases.saved_runs`, :mod:`nsm_continuation.cases.restart`).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from nsm_continuation import __version__
from nsm_continuation.algorithms.curves import CodimOneCurve
from nsm_continuation.cases.saved_runs import RESTART_FORMAT, RESTART_VERSION, RunRecord
from nsm_continuation.runs.result import RunResult


def _floats(v: Any) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=float).ravel()]


def restart_block(res: RunResult) -> dict[str, Any]:
    """The ``restart`` block of ``report.json`` (the module docstring); a run read back from
    its folder keeps the one it was saved with."""
    if res.saved_report is not None and isinstance(res.saved_report.get("restart"), dict):
        return json.loads(json.dumps(res.saved_report["restart"]))
    pr = res.problem
    parameters = pr.parameters_block()
    if parameters is None:  # parameters that are not a pydantic model: the case's block
        parameters = dict(res.case.parameters)
    # a two-parameter curve is a run of its base problem, with what rebuilds the curve
    curve_block = pr.restart_curve() if isinstance(pr, CodimOneCurve) else None
    problem_name = curve_block.pop("base_problem") if curve_block else pr.name
    branches = []
    for br in res.branches:
        rows = {id(p): k for k, p in enumerate(br.points)}
        counts: dict[str, int] = {}
        events = []
        for ev in br.events:
            n = counts.get(ev.kind, 0)
            counts[ev.kind] = n + 1
            p = ev.point
            events.append({"kind": ev.kind, "index": n, "row": rows.get(id(p)),
                           "parameter": float(p.y[pr.parameter_index]), "s": float(p.s),
                           "y": _floats(p.y), "tangent": _floats(p.tangent)}
                          | ({"chart": dict(p.chart)} if p.chart else {}))
        # the rows from which the unknowns are in another chart (Problem.rechart)
        charts = [{"from_row": k, "chart": dict(p.chart or {})}
                  for k, p in enumerate(br.points)
                  if (p.chart or None) != (br.points[k - 1].chart or None if k else None)]
        multiple = br.info.get("period_multiple", br.info.get("returns"))
        bpr = res.branch_problems.get(br.id, pr)
        branches.append({
            "id": br.id, "label": br.label, "csv": f"branch_{br.id}.csv",
            "n_points": br.n_points, "variables": list(pr.variables),
            "parameter": pr.parameter,
            "period_multiple": (int(multiple) if multiple is not None
                                else int(bpr.period_multiple())),
            "events": events} | ({"charts": charts} if charts else {}))
    block = {"format": RESTART_FORMAT, "version": RESTART_VERSION, "tool_version": __version__,
             "problem": problem_name, "parameters": parameters,
             "continued": res.case.continuation.parameter, "branches": branches}
    if curve_block:
        block["curve"] = curve_block
    return block


def record_from_result(res: RunResult, label: str) -> RunRecord:
    """The restart record of a run in memory (its CSV rows are the branches' points)."""
    block = restart_block(res)
    rows = {}
    for br in res.branches:
        if br.points:
            rows[br.id] = np.array([p.y for p in br.points], dtype=float)
    return RunRecord(label, json.loads(json.dumps(block)),
                     res.case.model_dump(mode="json"), None, {}, rows)
