"""A saved run read back into memory: the inverse of :mod:`nsm_continuation.output.files`.

:func:`load_result` reads a run folder (``report.json``, its ``branch_<id>.csv`` files and the
marker; nothing is unpickled, nothing is computed) into a
:class:`~nsm_continuation.runs.result.RunResult` whose branches, events, tree and report are
those the run had in memory, so that everything done with a fresh run (its figures, its
report, a restart) can be done with it days later:

* every point is a CSV row read exactly (the CSV holds Python's shortest round-trip ``repr``
  of every float; integers stay integers, ``nan`` stays NaN, an empty cell is a quantity the
  point does not have): its derived quantities, admissibility tests, multipliers (in the
  CSV's order, by decreasing modulus), unknowns, arclength and Newton statistics;
* every event is its ``report.json`` record and its ``restart`` record (kind, detail, data,
  location bracket; unknowns, tangent and arclength exact): an event at a CSV row is that
  row's point, an event located between two rows a point of its own
  (:class:`RecordedPoint`: its admissibility as recorded, its test values not saved);
* the problem is rebuilt from the saved case without computing: as a restart from the run's
  own restart record would build it (:mod:`nsm_continuation.cases.restart`: the run's full
  parameters, continued parameter, period multiple of each branch, chart, two-parameter
  curve), or, for an algorithm that cannot restart (lattice, sweep), from the case input as
  ``nsm-continuation validate`` does.

What a run does not save is not restored: the tangent at a point that is not an event (zero),
the points' unit-circle tolerance (the case's) and event-function values (used while
continuing only); a point's discrete signature is its CSV's ``signature`` column, where the
problem has one. A folder that is not a run of this tool, a file changed since
the run (its SHA-256 differs from the marker's), or a run of a newer format is one
:class:`~nsm_continuation.core.errors.CaseError` line naming the folder and the problem.
"""

from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from nsm_continuation.cases.saved_runs import RunRecord, load_run, sha256
from nsm_continuation.cases.schema import Case
from nsm_continuation.core.errors import CaseError, short_text
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.core.settings import ContinuationSettings
from nsm_continuation.output.files import SIGNATURE_COLUMN, _f
from nsm_continuation.runs.result import RunResult

#: the columns of ``branch_<id>.csv`` between the head and the other derived quantities, and
#: between the test functions and the unknowns (:func:`~.files.branch_rows`)
STATE_COLUMNS = ["admissible", "stable", "max_abs_multiplier", "s"]
ACCURACY_COLUMNS = ["trivial_multiplier_error", "newton_iterations", "residual_inf"]

_INT = re.compile(r"^[+-]?\d+$")


@dataclass
class RecordedPoint(Point):
    """A point read back whose admissibility tests were not saved (an event located between
    two CSV rows): :attr:`admissible` is the recorded one."""

    recorded_admissible: bool = True

    @property
    def admissible(self) -> bool:
        return self.recorded_admissible


def _cell(text: str) -> Any:
    """A CSV cell as written (:func:`csv.writer` writes ``str(value)``): '' for a quantity
    the point does not have, an int, a bool, None, or a float (``repr`` round trip)."""
    if text == "":
        return ""
    if _INT.match(text):
        return int(text)
    if text in ("True", "False"):
        return text == "True"
    if text == "None":
        return None
    return float(text)


def _nan(value: Any) -> Any:
    """A JSON value of a derived quantity: None (NaN or infinite when written) as NaN."""
    return float("nan") if value is None else value


@dataclass
class _Layout:
    """Where each part of a ``branch_<id>.csv`` row is (:func:`~.files.branch_rows`)."""

    head: list[str]
    extra: list[str]
    tests: list[str]
    y: slice
    n_mult: int

    @classmethod
    def of(cls, cols: list[str], variables: list[str], where: str) -> _Layout:
        try:
            a = cols.index("admissible")
            t = cols.index("trivial_multiplier_error", a)
        except ValueError:
            raise CaseError(f"{where}: not a branch table of this tool (no admissible / "
                            "trivial_multiplier_error columns)") from None
        y0 = t + len(ACCURACY_COLUMNS)
        ys = [f"y_{v}" for v in variables]
        mult = cols[y0 + len(ys):]
        if cols[a:a + 4] != STATE_COLUMNS or cols[t:y0] != ACCURACY_COLUMNS \
                or cols[y0:y0 + len(ys)] != ys or len(mult) % 2 \
                or mult != [f"mu{i // 2 + 1}_{('re', 'im')[i % 2]}" for i in range(len(mult))]:
            raise CaseError(f"{where}: its columns are not those of a branch of unknowns "
                            f"{', '.join(variables)}")
        middle = cols[a + 4:t]
        if middle[:1] == [SIGNATURE_COLUMN]:  # the family of each point (text)
            middle = middle[1:]
        k = len(middle)
        while k > 0 and middle[k - 1].startswith("test_"):
            k -= 1
        return cls(cols[:a], middle[:k], [c.removeprefix("test_") for c in middle[k:]],
                   slice(y0, y0 + len(ys)), len(mult) // 2)


def _point(row: list[Any], lay: _Layout, derived_order: list[str], cols: list[str],
           tol: float) -> Point:
    """The point of one CSV row (its cells already :func:`_cell`)."""
    cell = dict(zip(cols, row, strict=True))
    y = np.array(row[lay.y], dtype=float)
    derived = {k: cell[k] for k in derived_order if cell.get(k, "") != ""}
    tests = {k: cell[f"test_{k}"] for k in lay.tests if cell[f"test_{k}"] != ""}
    start = lay.y.stop
    pairs = [(row[start + 2 * i], row[start + 2 * i + 1]) for i in range(lay.n_mult)]
    mult = None
    if cell["stable"] != "":
        mult = np.array([complex(re_, im) for re_, im in pairs if re_ != ""], dtype=complex)
    n_out = 0 if mult is None or cell["stable"] else max(1, int(np.sum(np.abs(mult) > 1 + tol)))
    trivial = cell["trivial_multiplier_error"]
    return Point(y=y, s=float(cell["s"]), tangent=np.zeros_like(y), tests=tests,
                 multipliers=mult, trivial_error=0.0 if trivial == "" else trivial,
                 n_unstable=n_out, derived=derived, bordered_det=float("nan"),
                 newton_iterations=cell["newton_iterations"],
                 residual_norm=cell["residual_inf"], circle_tol=tol,
                 signature=cell.get(SIGNATURE_COLUMN) or None)


def _derived_order(events: list[dict[str, Any]], lay: _Layout, variables: list[str],
                   known: list[str]) -> list[str]:
    """The derived quantities of a branch's points, in the order the points hold them: those
    of its event records first (``kind, detail, <derived...>, s``: the exact keys and order
    of a point's ``derived``), then the CSV's. A head column that is an unknown is a derived
    quantity only if an event record or the problem (``known``: ``monitor_names``) has it."""
    order: list[str] = []
    for rec in events:
        keys = list(rec)
        if "detail" in keys and "s" in keys:
            order += [k for k in keys[keys.index("detail") + 1:keys.index("s")]
                      if k not in order]
    shadow = set(order) | set(known)
    for k in [*lay.head, *lay.extra]:
        if k not in order and (k not in variables or k in shadow):
            order.append(k)
    return order


def _event(rec: dict[str, Any], saved: dict[str, Any], points: list[Point], tol: float
           ) -> Event:
    """An event from its ``report.json`` record ``rec`` and its restart record ``saved``."""
    keys = list(rec)
    data_keys = keys[keys.index("location_bracket") + 1:keys.index("y")] \
        if "location_bracket" in keys and "y" in keys else []
    data = {k: rec[k] for k in data_keys}
    row = saved.get("row")
    if row is not None:
        point = points[int(row)]
        # a datum named as a derived quantity was written in its place (event_record)
        for k in keys[keys.index("detail") + 1:keys.index("s")]:
            if json.dumps(_f(point.derived.get(k, ""))) != json.dumps(rec[k]):
                data[k] = rec[k]
    else:
        y = np.array(saved["y"], dtype=float)
        stable = rec.get("stable")
        mult = None if stable is None else np.array(
            [complex(a, b) for a, b in rec.get("multipliers", [])], dtype=complex)
        n_out = 0 if mult is None or stable else max(1, int(np.sum(np.abs(mult) > 1 + tol)))
        derived = {k: _nan(rec[k]) for k in keys[keys.index("detail") + 1:keys.index("s")]}
        point = RecordedPoint(
            y=y, s=float(saved["s"]), tangent=np.array(saved["tangent"], dtype=float),
            tests={}, multipliers=mult, trivial_error=float("nan"), n_unstable=n_out,
            derived=derived, bordered_det=float("nan"), circle_tol=tol,
            chart=dict(saved["chart"]) if saved.get("chart") else None,
            recorded_admissible=bool(rec.get("admissible", True)))
    if row is not None:  # the row's point is the event's: its tangent was saved with it
        point.tangent = np.array(saved["tangent"], dtype=float)
    bracket = rec.get("location_bracket")
    return Event(rec["kind"], point, rec.get("detail", ""), data,
                 float("nan") if bracket is None else float(bracket))


def read_rows(folder: Path, name: str, marker: dict[str, Any], label: str
              ) -> tuple[list[str], list[list[Any]]]:
    """The columns and rows (cells read by :func:`_cell`) of the run's CSV ``name``, checked
    against the marker's SHA-256."""
    path = folder / name
    digest = marker.get("files", {}).get(name)
    where = f"load: {label}/{name}"
    try:
        if digest is None or not path.is_file():
            raise CaseError(f"{where} is missing")
        if sha256(path) != digest:
            raise CaseError(f"{where} was changed after the run (its SHA-256 differs from "
                            "the run's marker)")
        with open(path, newline="", encoding="utf-8") as fh:
            table = list(csv.reader(fh))
        # the signature column (the family of each point) is text
        text = table[0].index(SIGNATURE_COLUMN) if SIGNATURE_COLUMN in table[0] else -1
        return table[0], [[c if j == text else _cell(c) for j, c in enumerate(r)]
                          for r in table[1:]]
    except CaseError:
        raise
    except OSError as exc:
        raise CaseError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    except (ValueError, IndexError):
        raise CaseError(f"{where}: not a table of numbers") from None


def _branch(rep_b: dict[str, Any], rec_b: dict[str, Any], record: RunRecord,
            table: tuple[list[str], list[list[Any]]], problem: Problem, tol: float) -> Branch:
    """One branch: its points from its CSV ``table``, its events from the two records."""
    variables = list(rec_b["variables"])
    cols, rows = table
    where = f"load: {record.label}/{rec_b['csv']}"
    if len(rows) != int(rec_b["n_points"]):
        raise CaseError(f"{where}: {len(rows)} rows, the report says {rec_b['n_points']}")
    lay = _Layout.of(cols, variables, where)
    order = _derived_order(rep_b["events"], lay, variables, problem.monitor_names())
    points = [_point(r, lay, order, cols, tol) for r in rows]
    for move in rec_b.get("charts", []):
        for p in points[int(move["from_row"]):]:
            p.chart = dict(move["chart"]) or None
    if len(rep_b["events"]) != len(rec_b["events"]):
        raise CaseError(f"load: {record.label}/report.json: branch {rep_b['id']} lists "
                        f"{len(rep_b['events'])} events and {len(rec_b['events'])} restart "
                        "records")
    events = [_event(rec, saved, points, tol)
              for rec, saved in zip(rep_b["events"], rec_b["events"], strict=True)]
    return Branch(int(rep_b["id"]), rep_b["label"], points, events,
                  dict(rep_b.get("termination_by_direction") or {}), dict(rep_b["info"]))


def _settings(rep: dict[str, Any], case: Case, problem: Problem
              ) -> tuple[ContinuationSettings, tuple[float | None, float | None]]:
    """The run's settings and window: those the case gives (as the run built them), with the
    values ``report.json`` lists on top where the case cannot give them (a restart's
    inherited blocks)."""
    from nsm_continuation.runs.setup import settings_from_case

    try:
        settings, window = settings_from_case(case, problem)
    except (ValueError, ArithmeticError):
        settings, window = ContinuationSettings(), (None, None)
    saved = rep.get("continuation", {})
    names = {f.name for f in fields(ContinuationSettings)}
    for key, value in (saved.get("settings") or {}).items():
        if key in names and not isinstance(getattr(settings, key), dict):
            setattr(settings, key, value)
    if isinstance(saved.get("window"), list) and len(saved["window"]) == 2:
        window = (saved["window"][0], saved["window"][1])
    return settings, window


def _problems(record: RunRecord, case: Case) -> tuple[Problem, dict[int, Problem]]:
    """The run's problem and the problems of branches computed with another one (a switched
    branch of a diagram: its period multiple), built as a restart from the run's own record
    would build them; for an algorithm that cannot restart, or where that restart is refused,
    the case's problem (:func:`_case_problem`)."""
    from nsm_continuation.algorithms.registry import ALGORITHMS
    from nsm_continuation.cases import registry
    from nsm_continuation.cases.validation import validate

    name = str(record.restart["problem"])
    try:
        cls = registry.get(name)
    except registry.UnknownProblemError:
        raise CaseError(f"problem {name!r} is not registered here (nsm-continuation list): a "
                        "run of a problem class the registry does not know cannot be read "
                        "back") from None
    algorithm = ALGORITHMS.get(case.continuation.algorithm or cls.algorithms[0])
    if algorithm is not None and not algorithm.takes_start_points:
        return _case_problem(record, cls), {}
    by_multiple: dict[int, Problem] = {}
    per_branch: dict[int, Problem] = {}
    for b in record.restart["branches"]:
        if not b["n_points"]:
            continue
        key = int(b.get("period_multiple", 1))
        if key not in by_multiple:
            start = {"from": record.label, "branch": int(b["id"]),
                     "point": int(b["n_points"]) // 2}
            try:
                by_multiple[key] = validate({"start": start,
                                             "output": {"plots": False, "progress": False}},
                                            restart_record=record)[1]
            except CaseError:  # e.g. a start check the saved point does not pass
                by_multiple[key] = _case_problem(record, cls)
        per_branch[int(b["id"])] = by_multiple[key]
    if not per_branch:  # no branch with points
        return _case_problem(record, cls), {}
    main = next(iter(per_branch.values()))
    if getattr(main, "start_value", None) is not None:
        # a two-parameter curve rebuilt at one of its points: it started where the run's
        # parameters are (LocatedCurve.start_value)
        from nsm_continuation.algorithms.curves import flat_parameters

        main.start_value = flat_parameters(record.restart["parameters"]).get(main.parameter)
    return main, {i: p for i, p in per_branch.items() if p is not main}


def _case_problem(record: RunRecord, cls: type[Problem]) -> Problem:
    """The problem of the saved case as ``nsm-continuation validate`` builds it, else (a
    restart case, whose run it started from may be gone) of the run's full parameters."""
    from nsm_continuation.cases.validation import validate

    raw = json.loads(json.dumps(record.case_input))
    start = raw.get("start")
    if not (isinstance(start, dict) and "from" in start):
        raw["output"] = {**raw.get("output", {}), "plots": False, "progress": False}
        try:
            return validate(raw)[1]
        except CaseError:
            pass
    try:
        return cls(cls.Parameters.model_validate(record.restart["parameters"]))
    except (ValueError, ArithmeticError) as exc:
        raise CaseError(f"its parameters do not build problem {cls.name!r} "
                        f"({short_text(str(exc), 200)})") from None


def load_result(source: str | Path) -> tuple[RunResult, dict[str, Any]]:
    """The run in the folder ``source`` and its ``report.json`` (module docstring); a
    :class:`CaseError` ``load: ...`` naming the folder and the problem when it cannot be."""
    if not isinstance(source, str | Path) or not str(source):
        raise CaseError(f"load: expected the folder of a run (str or pathlib.Path), got "
                        f"{type(source).__name__}")
    try:
        record = load_run(str(source))
    except CaseError as exc:
        raise CaseError(str(exc).replace("start.from: ", "load: ", 1)
                        .replace("; run its case again", "; run its case again to read it "
                                 "back")) from None
    assert record.folder is not None
    rep = json.loads((record.folder / "report.json").read_text(encoding="utf-8"))
    rec_branches = {int(b["id"]): b for b in record.restart["branches"]}
    tables = {i: read_rows(record.folder, b["csv"], record.marker, record.label)
              for i, b in rec_branches.items()}  # every file checked before anything is built
    try:
        case = Case.model_validate(record.case_input)
        problem, branch_problems = _problems(record, case)
    except CaseError as exc:
        raise CaseError(f"load: {record.label}: the run's problem cannot be rebuilt "
                        f"({short_text(str(exc), 300)})") from None
    tol = float(case.analysis.unit_circle_tol)
    branches = []
    for rep_b in rep.get("branches", []):
        rec_b = rec_branches.get(int(rep_b["id"]))
        if rec_b is None:
            raise CaseError(f"load: {record.label}/report.json: branch {rep_b['id']} has no "
                            "restart record")
        branches.append(_branch(rep_b, rec_b, record, tables[int(rep_b["id"])],
                                branch_problems.get(int(rep_b["id"]), problem), tol))
    settings, window = _settings(rep, case, problem)
    diagram = rep.get("diagram") or {}
    res = RunResult(case, problem, branches, settings, window,
                    timings=dict(rep.get("timings") or {}),
                    skipped=list(rep.get("skipped_starts") or []),
                    tree=list(diagram.get("tree") or []),
                    branch_problems={i: p for i, p in branch_problems.items()
                                     if any(b.id == i for b in branches)},
                    saved_report=rep)
    return res, rep


__all__ = ["RecordedPoint", "load_result", "read_rows"]
