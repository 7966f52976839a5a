"""Run outputs (a stable contract): ``report.json``, ``branch_<id>.csv``, ``report.md``, and
the figures a drawing function given by the caller writes (:mod:`nsm_continuation.figures`).

Where and how they are written (never over a user's files, atomically) is
:mod:`nsm_continuation.output.folders`.
"""

from __future__ import annotations

import csv
import errno
import json
import re
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from nsm_continuation.core.errors import short_text
from nsm_continuation.core.records import START_WARNING, Branch, Event, Point
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


def location_uncertainty(br: Branch, ev: Event, names: list[str],
                         variables: list[str]) -> dict[str, float]:
    """How far each quantity of ``names`` (a derived quantity or an unknown) may lie from its
    value at the event: the event's bracket (the accuracy of its location in arclength) times
    the quantity's rate along the branch, the largest secant slope over the intervals of the
    branch's points around the event (0 for an event located exactly, as a bound)."""
    w = float(ev.bracket)
    pts = br.points
    if not np.isfinite(w) or len(pts) < 2:
        return {}
    s = np.array([p.s for p in pts], dtype=float)
    i = int(np.searchsorted(s, float(ev.point.s)))
    spans = [(j, j + 1) for j in range(max(i - 2, 0), min(i + 1, len(pts) - 1))]
    out = {}
    for name in names:
        slope = 0.0
        for j, k in spans:
            dv = pts[k].value(name, variables) - pts[j].value(name, variables)
            if s[k] > s[j] and np.isfinite(dv):
                slope = max(slope, abs(dv) / (s[k] - s[j]))
        out[name] = slope * w
    return out


def termination_text(br: Branch) -> str:
    return "; ".join(f"{k}: {v}" for k, v in br.termination.items())


#: the text column of ``branch_<id>.csv`` naming the family of each point (its signature)
SIGNATURE_COLUMN = "signature"


def branch_rows(br: Branch, variables: list[str], head: list[str] | None = None
                ) -> tuple[list[str], list[list[Any]]]:
    """Columns and rows of ``branch_<id>.csv``: ``head`` (the problem's ``csv_head``, derived
    quantities or unknowns), admissibility and stability, the arclength, the signature (the
    family of each point; problems with a signature only), the other derived quantities, the
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
    # the family each point belongs to: the problem's signature (a hybrid orbit's sequence of
    # events), text
    family = [SIGNATURE_COLUMN] if any(p.signature is not None for p in pts) else []
    cols = (head + ["admissible", "stable", "max_abs_multiplier", "s"] + family + extra
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
                    + ([p.signature or ""] if family else [])
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


class _NotJSON(TypeError):
    """A value ``report.json`` cannot hold."""


def _json_value(x: Any) -> Any:
    """``default`` of :func:`json.dumps` checking a hook's value: what :func:`_f` converts, and
    nothing else (an arbitrary object raises instead of being written as garbage)."""
    y = _f(x)
    if y is x:
        raise _NotJSON(f"{type(x).__name__} is not JSON")
    return y


def is_plugin(problem: Any) -> bool:
    """Whether ``problem``'s class (and so its presentation's figure hooks) is another
    package's or a script's, not one of this package's: a failure of its figures is then its
    own, reported, not a bug of this tool."""
    return not type(problem).__module__.startswith("nsm_continuation.")


def hook_name(problem: Any, hook: str) -> str:
    """The hook of ``problem``'s presentation named for a message: problem name, class, hook."""
    cls = type(problem.presentation)
    return f"problem {problem.name!r}: {cls.__module__}.{cls.__qualname__}.{hook}"


def call_hook(problem: Any, hook: str, call: Callable[[], Any], check: Callable[[Any], Any],
              fallback: Any, failures: list[str]) -> Any:
    """The value of a presentation hook, ``call()`` then ``check(value)`` (which returns the
    value to use or raises); on any exception, ``fallback`` and one line in ``failures`` naming
    the problem, the class and the hook. A plugin's presentation runs after the computation:
    its failure must not lose what was computed, nor pass for a bug of this tool."""
    try:
        return check(call())
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - any failure of a hook is reported
        failures.append(f"{hook_name(problem, hook)} failed ({type(exc).__name__}: "
                        f"{short_text(str(exc))}); its part of the outputs is left out")
        return fallback


def _json_dict(value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise TypeError(f"returned {type(value).__name__}, not a dict")
    return json.loads(json.dumps(value, default=_json_value, allow_nan=True))


def _str_list(value: Any) -> list[str]:
    if isinstance(value, (str, bytes)) or not all(isinstance(v, str) for v in value):
        raise TypeError(f"returned {short_text(repr(value))}, not a list of names")
    return list(value)


def _named_columns(res: RunResult) -> Callable[[Any], list[str]]:
    """Check of ``csv_head`` and ``event_columns``: a list of names, each a derived quantity
    or an unknown of the run (when it has points)."""
    variables = set(res.problem.variables)
    derived = {k for br in res.branches for pt in br.points for k in pt.derived}
    for bpr in res.branch_problems.values():
        variables.update(bpr.variables)

    def check(value: Any) -> list[str]:
        names = _str_list(value)
        unknown = [n for n in names if n not in variables and n not in derived]
        if unknown and derived | variables and any(br.points for br in res.branches):
            raise ValueError(f"{unknown[0]!r} is neither a derived quantity nor an unknown")
        return names

    return check


def presentation_warnings(problem: Any, failures: list[str]) -> list[str]:
    """``problem.presentation.warnings()``, guarded (:func:`call_hook`)."""
    pres = problem.presentation
    return call_hook(problem, "warnings", lambda: pres.warnings(), _str_list, [], failures)


def _problem_parts(res: RunResult, branches: list[dict[str, Any]], failures: list[str]
                   ) -> tuple[dict[str, Any], dict[str, Any], list[str]]:
    """The problem's summary and results (its presentation hooks, guarded) and the run's
    warnings: the hooks' failures, the problem's warnings, what ``output.orbits`` cannot
    draw, and the branches whose trivial multiplier drifts."""
    pr = res.problem
    pres = pr.presentation
    warnings = presentation_warnings(pr, failures)
    summary_part = call_hook(pr, "summary", lambda: pres.summary(), _json_dict, {}, failures)
    extras = call_hook(pr, "report_extras", lambda: pres.report_extras(res.branches),
                       _json_dict, {}, failures)
    warnings = [*failures, *warnings]
    if res.case.output.orbits is not None:
        from nsm_continuation.figures.orbit_selection import spec_warnings

        warnings += spec_warnings(res)
    warnings += start_warnings(res.branches)
    for b in branches:
        err = b["max_trivial_multiplier_error"]
        if err is not None and err > 1e-6:
            warnings.append(f"branch {b['id']}: the trivial multiplier drifts from 1 by {err:.1e}:"
                            " multipliers near the unit circle are not reliable there")
    return summary_part, extras, warnings


def start_warnings(branches: list[Branch]) -> list[str]:
    """The warnings about how the branches' starts were found (:data:`START_WARNING` of their
    info, e.g. a transient that has not settled), each with the stability of the orbit the
    start's Newton converged to (the branch's point at arclength 0)."""
    out = []
    for br in branches:
        note = br.info.get(START_WARNING)
        if not note:
            continue
        if br.points:
            p = min(br.points, key=lambda q: abs(q.s))
            if p.multipliers is None:
                note += "; the stability of the orbit it converged to is not known"
            elif p.n_unstable:
                n = p.n_unstable
                note += (f"; it converged to an orbit that is unstable ({n} multiplier"
                         f"{'s' if n > 1 else ''} outside the unit circle, the largest "
                         f"|lambda| = {p.max_abs_multiplier:.4g}): not the attractor the "
                         "simulation approaches")
            else:
                note += (f"; it converged to a stable orbit (the largest |lambda| = "
                         f"{p.max_abs_multiplier:.4g})")
        out.append(f"branch {br.id} ({br.label}): {note}")
    return out


def unchecked_note(res: RunResult) -> str | None:
    """What the run's algorithm does not check (:attr:`Algorithm.unchecked
    <nsm_continuation.algorithms.base.Algorithm.unchecked>`), or None."""
    from nsm_continuation.algorithms.registry import ALGORITHMS

    algorithm = ALGORITHMS.get(res.case.continuation.algorithm or res.problem.algorithms[0])
    return None if algorithm is None else algorithm.unchecked


def impacts_per_period(points: list[Point]) -> list[int]:
    """The distinct numbers of impacts per period (the derived ``n_impacts``: over the
    orbit's whole period, ``2k`` base periods for a family born at a period doubling) of the
    points that report it, increasing; empty where none does."""
    counts = {p.derived.get("n_impacts") for p in points}
    return sorted(int(c) for c in counts if c is not None and np.isfinite(c))


def orbit_kinds(points: list[Point], ip: int) -> dict[str, Any]:
    """What kinds of orbits a branch holds, for its ``report.json`` entry: ``families``, the
    signature runs it went through, and ``impacts_per_period`` (:func:`impacts_per_period`),
    each where there is one."""
    out: dict[str, Any] = {}
    runs = report_md.family_runs(points, ip)
    if runs:
        out["families"] = runs
    impacts = impacts_per_period(points)
    if impacts:
        out["impacts_per_period"] = impacts
    return out


def build_report(res: RunResult, folder: str | None = None,
                 failures: list[str] | None = None) -> dict[str, Any]:
    """The content of ``report.json``; ``folder``: where the run is (or will be) saved, for
    the ``start:`` lines of ``continue_from_here`` (default: ``runs/<case name>``). A
    presentation hook of the problem that fails or returns what the report cannot hold is left
    out, with one line naming it appended to ``failures`` and to the report's warnings."""
    failures = [] if failures is None else failures
    pr = res.problem
    pres = pr.presentation
    columns = call_hook(pr, "event_columns", lambda: pres.event_columns, _named_columns(res),
                        [], failures)
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
            # what the location's accuracy leaves of each printed value (report.md's digits)
            rec["location_uncertainty"] = {k: _f(v) for k, v in location_uncertainty(
                br, ev, list(dict.fromkeys([*columns, bpr.parameter])), bpr.variables).items()}
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
        branches[-1].update(orbit_kinds(br.points, bpr.parameter_index))
    s = res.settings
    saved = res.saved_report
    if saved is not None:  # read back: what the problem said at the end of the run
        warnings = list(saved.get("warnings", []))
        summary_part = saved.get("problem_summary", {})
        extras = saved.get("problem_results", {})
    else:
        summary_part, extras, warnings = _problem_parts(res, branches, failures)
        note = unchecked_note(res)
        if note is not None:
            warnings.append(note)
    rep = {
        "case": {"name": res.case.name, "description": res.case.description,
                 "input": res.case.model_dump(mode="json")},
        "problem": pr.name,
        "problem_summary": summary_part,
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
        "problem_results": extras,
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
                drawer: Drawer | None = None) -> list[str]:
    """Write every output of a run (CSV per branch, report.json, report.md, figures) into
    ``directory``, which exists and is the run's own (see :mod:`nsm_continuation.output.folders`).
    The figures (none when ``draw`` is None) are drawn by ``drawer`` where it can (a process
    started before the computation, :class:`~nsm_continuation.figures.process.FigureProcess`,
    drawing while this process writes the CSVs and the report), else here by ``draw``.
    Returns the failures of the problem's presentation hooks (:func:`call_hook`: one line each,
    also among the report's warnings), whose parts were left out."""
    directory = Path(directory)
    drawing = draw is not None and drawer is not None and drawer.send(res, directory)
    failures: list[str] = []
    pres = res.problem.presentation
    head = call_hook(res.problem, "csv_head", lambda: pres.csv_head, _named_columns(res), None,
                     failures)
    rep = build_report(res, run_folder(directory), failures)
    for br in res.branches:
        cols, rows = branch_rows(br, res.problem.variables, head)
        with open(directory / f"branch_{br.id}.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            w.writerows(rows)
    figures: list[str] = []
    try:
        if drawing:
            assert drawer is not None
            figures = drawer.figures()
        elif draw is not None:
            figures = draw(res, directory)
    except (Exception, SystemExit) as exc:
        if not is_plugin(res.problem) or is_no_space(exc):
            raise
        line = (f"problem {res.problem.name!r} ({type(res.problem).__module__}): the figures "
                f"failed in its code ({type(exc).__name__}: {short_text(str(exc))}); they are "
                "left out, the data and the report are written")
        failures.append(line)
        rep["warnings"] = [*rep.get("warnings", []), line]
    rep["figures"] = figures
    (directory / "report.json").write_text(json.dumps(rep, indent=1, default=_f))
    (directory / "report.md").write_text(report_md.markdown(rep))
    return failures


#: ``errno`` values of a full disk or an exhausted quota
NO_SPACE = (errno.ENOSPC, errno.EDQUOT)


def is_no_space(exc: BaseException) -> bool:
    """``exc`` says the disk is full or the quota exhausted."""
    return isinstance(exc, OSError) and exc.errno in NO_SPACE


class NoSpaceError(Exception):
    """The output location ran out of space while a run's results were written (exit status
    4, not a bug): the message names the folder, the space the results need where known, and
    :attr:`kept`, the folder in the system's temporary directory holding them (None if they
    could not be kept there either)."""

    def __init__(self, message: str, kept: Path | None) -> None:
        super().__init__(message)
        #: where the computed results were written instead (None: nowhere)
        self.kept = kept


def keep_elsewhere(res: RunResult, folder: Path, exc: OSError) -> NoSpaceError:
    """After ``exc`` (no space) while writing ``res`` into ``folder`` (its temporary folder
    already removed): write the results, without figures, into a new folder of the system's
    temporary directory (:func:`tempfile.gettempdir`) under the output policy, and return the
    error to raise, naming both folders and the size of the results."""
    why = "no space left" if exc.errno == errno.ENOSPC else "disk quota exceeded"
    stamp = time.strftime("%Y%m%d-%H%M%S")
    fallback = Path(tempfile.gettempdir()) / f"nsm-continuation-{res.case.name}-{stamp}"
    try:
        kept = _write_outputs(res, fallback, None, "new", keep=False)
    except Exception as again:  # noqa: BLE001 - the fallback is best effort; the line says so
        reason = again.strerror if isinstance(again, OSError) and again.strerror else again
        return NoSpaceError(f"output: {why} writing {folder}; the results could not be kept in "
                            f"{tempfile.gettempdir()} either ({short_text(str(reason))})", None)
    size = sum(f.stat().st_size for f in kept.iterdir() if f.is_file())
    return NoSpaceError(f"output: {why} writing {folder} (the results need {size} bytes, "
                        f"figures not included); they were kept in {kept}", kept)


def write_outputs(res: RunResult, out_dir: Path | str, draw: Draw | None = None,
                  if_exists: IfExists = "error", notes: list[str] | None = None) -> Path:
    """Write every output of a run into ``out_dir`` under the output policy of
    :mod:`nsm_continuation.output.folders` (never deletes what this tool did not write), the
    figures with ``draw`` (none when None); returns the directory written (a numbered sibling
    with ``if_exists="new"``). A full disk raises :class:`NoSpaceError`, the results kept in the
    system's temporary directory when it has room (:func:`keep_elsewhere`). ``notes``, when
    given, gets what the command line would print: what killed runs had left next to the
    folder (:attr:`OutputTarget.recovered`) and the failures of the problem's hooks
    (:func:`write_files`)."""
    return _write_outputs(res, out_dir, draw, if_exists, keep=True, notes=notes)


def _write_outputs(res: RunResult, out_dir: Path | str, draw: Draw | None,
                   if_exists: IfExists, keep: bool, notes: list[str] | None = None) -> Path:
    """:func:`write_outputs`; ``keep``: on a full disk, keep the results elsewhere."""
    target = OutputTarget(Path(out_dir), if_exists)
    target.prepare()
    try:
        assert target.tmp is not None
        failures = write_files(res, target.tmp, draw)
        path = target.commit()
        if notes is not None:
            notes += [*target.recovered, *failures]
        return path
    except BaseException as exc:
        where = target.path
        target.abort()
        if keep and isinstance(exc, OSError) and is_no_space(exc):
            raise keep_elsewhere(res, where, exc) from None
        raise
