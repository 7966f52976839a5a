"""Run outputs (a stable contract): ``report.json``, ``branch_<id>.csv``, ``report.md``, and
the figures a drawing function given by the caller writes (:mod:`nsm_continuation.figures`).

Where and how they are written (never over a user's files, atomically) is
:mod:`nsm_continuation.output.folders`.
"""

from __future__ import annotations

import csv
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.output import report as report_md
from nsm_continuation.output.folders import IfExists, OutputTarget
from nsm_continuation.runs.diagrams import parent_link, summary
from nsm_continuation.runs.restart_record import restart_block
from nsm_continuation.runs.result import RunResult

#: draws every figure of a run into a folder and returns their file names
#: (:func:`nsm_continuation.figures.make.make_all`)
Draw = Callable[[RunResult, Path], list[str]]


class Drawer(Protocol):
    """Draws a run's figures elsewhere while this process writes the rest
    (:class:`nsm_continuation.figures.process.FigureProcess`)."""

    def send(self, res: RunResult, directory: Path) -> bool:
        """Start drawing ``res`` into ``directory``: False when it cannot (the caller draws)."""

    def figures(self) -> list[str]:
        """The file names drawn after :meth:`send`."""


def _f(x: Any) -> Any:
    """JSON-safe float (NaN/inf -> None)."""
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, (set, frozenset)):
        return sorted(x)
    return x


def multipliers_list(m: np.ndarray | None) -> list[list[float]]:
    if m is None:
        return []
    order = np.argsort(-np.abs(m), kind="stable")
    return [[float(m[i].real), float(m[i].imag)] for i in order]


def event_record(ev: Event) -> dict[str, Any]:
    p = ev.point
    rec: dict[str, Any] = {"kind": ev.kind, "detail": ev.detail}
    rec.update({k: _f(v) for k, v in p.derived.items()})
    rec["s"] = _f(p.s)
    rec["multipliers"] = multipliers_list(p.multipliers)
    rec["admissible"] = p.admissible
    rec["stable"] = p.stable
    rec["location_bracket"] = _f(ev.bracket)
    for k, v in ev.data.items():
        rec[k] = v if not isinstance(v, (float, np.floating)) else _f(v)
    rec["y"] = [float(v) for v in p.y]
    return rec


def termination_text(br: Branch) -> str:
    return "; ".join(f"{k}: {v}" for k, v in br.termination.items())


def branch_rows(br: Branch, variables: list[str], head: list[str] | None = None
                ) -> tuple[list[str], list[list[Any]]]:
    """Columns and rows of ``branch_<id>.csv``: ``head`` (the problem's ``csv_head``, derived
    quantities or unknowns), admissibility and stability, the other derived quantities, the
    test functions, accuracy, the unknowns and the multipliers."""
    pts: list[Point] = br.points
    derived_keys: list[str] = []
    test_keys: list[str] = []
    for p in pts:
        for k in p.derived:
            if k not in derived_keys:
                derived_keys.append(k)
        for k in p.tests:
            if k not in test_keys:
                test_keys.append(k)
    n_mult = max((0 if p.multipliers is None else p.multipliers.size) for p in pts) if pts else 0
    head = list(head) if head is not None else []
    extra = [k for k in derived_keys if k not in head]
    cols = (head + ["admissible", "stable", "max_abs_multiplier", "s"] + extra
            + [f"test_{k}" for k in test_keys]
            + ["trivial_multiplier_error", "newton_iterations", "residual_inf"]
            + [f"y_{v}" for v in variables]
            + [f"mu{i + 1}_{part}" for i in range(n_mult) for part in ("re", "im")])
    rows = []
    for p in pts:
        mult = multipliers_list(p.multipliers)
        mult_flat = [c for z in mult for c in z] + [""] * (2 * n_mult - 2 * len(mult))
        stable = "" if p.stable is None else int(p.stable)
        mam = p.max_abs_multiplier
        rows.append([p.value(k, variables, "") for k in head] + [int(p.admissible), stable,
                    "" if not np.isfinite(mam) else mam, p.s]
                    + [p.derived.get(k, "") for k in extra]
                    + [p.tests.get(k, "") for k in test_keys]
                    + [p.trivial_error if p.multipliers is not None else "",
                       p.newton_iterations, p.residual_norm]
                    + list(map(float, p.y)) + mult_flat)
    return cols, rows


def run_folder(directory: Path | str) -> str:
    """The folder a run's files end up in, as a case's ``start.from`` names it: ``directory``
    itself, or the final folder of a hidden ``.<name>.tmp-*`` sibling being written
    (:class:`~nsm_continuation.output.folders.OutputTarget`); relative to the working directory when
    it lies below it."""
    d = Path(directory)
    m = re.match(r"^\.(.+)\.tmp-[^/]*$", d.name)
    if m:
        d = d.parent / m.group(1)
    try:
        return str(d.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(d.resolve())


def build_report(res: RunResult, folder: str | None = None) -> dict[str, Any]:
    """The content of ``report.json``; ``folder``: where the run is (or will be) saved, for
    the ``start:`` lines of ``continue_from_here`` (default: ``runs/<case name>``)."""
    pr = res.problem
    columns = list(pr.presentation.event_columns)
    branches = []
    for br in res.branches:
        bpr = res.branch_problems.get(br.id, pr)
        link = parent_link(br)
        events = []
        for ev in br.events:
            rec = event_record(ev)
            for c in columns:  # a column that is an unknown, not a derived quantity
                if c not in rec and c in bpr.variables:
                    rec[c] = _f(ev.point.y[bpr.variables.index(c)])
            if link is not None:
                rec["parent"] = link  # the event's branch was born there
            events.append(rec)
        branches.append({
            "id": br.id, "label": br.label, "n_points": br.n_points,
            "parent": link, "depth": int(br.info.get("depth", 0)),
            "termination": termination_text(br), "termination_by_direction": br.termination,
            "csv": f"branch_{br.id}.csv",
            "parameter_range": ([float(min(p.y[bpr.parameter_index] for p in br.points)),
                                 float(max(p.y[bpr.parameter_index] for p in br.points))]
                                if br.points else None),
            "admissible_points": int(sum(p.admissible for p in br.points)),
            # BifurcationKit's habit: the trivial multiplier is a free accuracy check
            "max_trivial_multiplier_error": _f(max((p.trivial_error for p in br.points
                                                     if p.multipliers is not None),
                                                    default=float("nan"))),
            "info": {k: _f(v) for k, v in br.info.items()},
            "events": events,
        })
    s = res.settings
    warnings = list(pr.presentation.warnings())
    if res.case.output.orbits is not None:
        from nsm_continuation.figures.orbit_selection import spec_warnings

        warnings += spec_warnings(res)
    for b in branches:
        err = b["max_trivial_multiplier_error"]
        if err is not None and err > 1e-6:
            warnings.append(f"branch {b['id']}: the trivial multiplier drifts from 1 by {err:.1e}:"
                            " multipliers near the unit circle are not reliable there")
    rep = {
        "case": {"name": res.case.name, "description": res.case.description,
                 "input": res.case.model_dump(mode="json")},
        "problem": pr.name,
        "problem_summary": pr.presentation.summary(),
        "parameters": res.case.parameters,
        "warnings": warnings,
        "continuation": {"parameter": pr.parameter, "window": [_f(w) for w in res.window],
                         "settings": {k: _f(v) for k, v in s.__dict__.items()
                                      if not isinstance(v, dict)}},
        "timings": {k: ([_f(x) for x in v] if isinstance(v, list) else _f(v))
                    for k, v in res.timings.items()},
        "skipped_starts": res.skipped,
        "event_columns": columns,
        "event_kinds": pr.all_event_kinds(),
        "branches": branches,
        "problem_results": pr.presentation.report_extras(res.branches),
        # versioned, machine-readable: what a later case needs to start from any event or
        # CSV row of this run (start: {from: <this folder>, ...}; nsm_continuation.cases.restart)
        "restart": restart_block(res),
    }
    diagram = summary(res)
    if diagram is not None:
        rep["diagram"] = diagram
    from nsm_continuation.output.report import annotate_parameter_directions, continue_hints

    # the changes read along the case's continued parameter (omega for the chain, whose
    # internal T falls as omega grows)
    name = res.case.continuation.parameter or pr.parameter
    rep["continuation"]["case_parameter"] = name
    annotate_parameter_directions(rep, res.branches, pr.parameter_index,
                                  pr.parameter_orientation(name))
    from nsm_continuation.algorithms.registry import ALGORITHMS

    # a run whose algorithm cannot start from a saved point (a sweep: its recorded returns
    # are not orbits to continue) gets no "continue from here" lines
    algorithm = ALGORITHMS.get(res.case.continuation.algorithm or pr.algorithms[0])
    rep["continue_from_here"] = continue_hints(
        rep["restart"], folder if folder is not None else f"runs/{res.case.name}",
        **hint_context(res)) if algorithm is None or algorithm.takes_start_points else []
    return rep


def hint_context(res: RunResult) -> dict[str, Any]:
    """What the ``continue_from_here`` lines need to know of the problem: whether it can
    switch at a period doubling (``Problem.iterated``), and the parameters a grazing curve
    could free or continue, in order of preference (``Problem.curve_parameters``; none for a
    curve: its events restart the curve)."""
    from nsm_continuation.core.problem import Problem

    pr = res.problem
    return {"doubling": type(pr).iterated is not Problem.iterated,
            "curve_parameters": list(pr.curve_parameters())}


def write_files(res: RunResult, directory: Path, draw: Draw | None = None,
                drawer: Drawer | None = None) -> None:
    """Write every output of a run (CSV per branch, report.json, report.md, figures) into
    ``directory``, which exists and is the run's own (see :mod:`nsm_continuation.output.folders`).
    The figures (none when ``draw`` is None) are drawn by ``drawer`` where it can (a process
    started before the computation, :class:`~nsm_continuation.figures.process.FigureProcess`,
    drawing while this process writes the CSVs and the report), else here by ``draw``."""
    directory = Path(directory)
    drawing = draw is not None and drawer is not None and drawer.send(res, directory)
    rep = build_report(res, run_folder(directory))
    for br in res.branches:
        cols, rows = branch_rows(br, res.problem.variables,
                                  res.problem.presentation.csv_head)
        with open(directory / f"branch_{br.id}.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            w.writerows(rows)
    figures: list[str] = []
    if drawing:
        assert drawer is not None
        figures = drawer.figures()
    elif draw is not None:
        figures = draw(res, directory)
    rep["figures"] = figures
    (directory / "report.json").write_text(json.dumps(rep, indent=1, default=_f))
    (directory / "report.md").write_text(report_md.markdown(rep))


def write_outputs(res: RunResult, out_dir: Path | str, draw: Draw | None = None,
                  if_exists: IfExists = "error") -> Path:
    """Write every output of a run into ``out_dir`` under the output policy of
    :mod:`nsm_continuation.output.folders` (never deletes what this tool did not write), the
    figures with ``draw`` (none when None); returns the directory written (a numbered sibling
    with ``if_exists="new"``)."""
    target = OutputTarget(Path(out_dir), if_exists)
    target.prepare()
    try:
        assert target.tmp is not None
        write_files(res, target.tmp, draw)
        return target.commit()
    except BaseException:
        target.abort()
        raise
