"""A saved run read back: its marker, its restart record and its CSV rows.

Every run folder holds a marker (:data:`MARKER`: the tool, its version and the SHA-256 of every
file the run wrote, :mod:`nsm_continuation.output.folders`) and a ``report.json`` whose
``restart`` block (format :data:`RESTART_FORMAT`, version :data:`RESTART_VERSION`,
:func:`nsm_continuation.runs.restart_record.restart_block`) names the problem, its full
parameters and, per branch, the unknowns and every located event with its ``y`` and tangent.
:func:`load_run` reads a folder back as a :class:`RunRecord` (``start.from`` of a restart):
a missing folder, a folder that is not a run of this tool, a ``report.json`` or CSV changed
since the run, or a record of another version is a :class:`CaseError` naming ``start.from`` or
``start.point``. The record is input like a case: it is checked against a strict schema
(:class:`RestartRecord`: types, lengths, finite numbers, unique branch ids and event ordinals)
when it is read, and a record that fails is one line naming ``start.from`` and the field's path
in the record (``start.from: runs/x/report.json: restart.branches[0].events[2].y: ...``).
"""

from __future__ import annotations

import csv
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, ValidationError

from nsm_continuation.cases.schema import _format
from nsm_continuation.core.errors import CaseError, short_text

#: marker file of a run directory: JSON with the tool, its version, the time and the files written
MARKER = ".nsm-continuation-run.json"


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def read_marker(directory: Path) -> dict | None:
    """The marker of a run directory, or None if ``directory`` is not a run of this tool."""
    try:
        data = json.loads((directory / MARKER).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("tool") != "nsm-continuation" \
            or not isinstance(data.get("files"), dict):
        return None
    return data


#: ``restart.format`` of ``report.json``
RESTART_FORMAT = "nsm-continuation-restart"


#: ``restart.version`` this module writes and reads
RESTART_VERSION = 1


# ---------------------------------------------------------------------- the record's schema
_Finite = Annotated[float, Field(allow_inf_nan=False)]
_Text = Annotated[str, Field(min_length=1, max_length=1000)]
_Count = Annotated[int, Field(ge=0)]


class _Strict(BaseModel):
    """A part of the record: exact JSON types (``"1"`` is no number, ``true`` no int), no
    unknown keys."""

    model_config = ConfigDict(extra="forbid", strict=True)


class EventRecord(_Strict):
    """An event of a branch: its kind, its ordinal among the events of that kind, the CSV row
    of its point (None: located between two points), the parameter unknown, the arclength,
    and the unknowns ``y`` and unit tangent (as many as the branch's ``variables``)."""

    kind: _Text
    index: _Count
    row: _Count | None
    parameter: _Finite
    s: _Finite
    y: list[_Finite]
    tangent: list[_Finite]
    chart: dict[_Text, _Finite] = {}


class ChartMove(_Strict):
    """From CSV row ``from_row`` on, the branch's unknowns are in ``chart``."""

    from_row: _Count
    chart: dict[_Text, _Finite]


class BranchRecord(_Strict):
    """A branch of the run: its id, CSV file, number of points, unknowns and events."""

    id: _Count
    label: Annotated[str, Field(max_length=10_000)]
    csv: Annotated[str, Field(pattern=r"^[A-Za-z0-9_][A-Za-z0-9_.+-]{0,200}\.csv$")]
    n_points: _Count
    variables: Annotated[list[_Text], Field(min_length=1)]
    parameter: _Text
    period_multiple: Annotated[int, Field(ge=1)]
    events: list[EventRecord]
    charts: list[ChartMove] = []


class BaseSettings(_Strict):
    """The settings of the base run a located curve keeps."""

    newton_tol: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    step_initial: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    #: a bound ``[low, high]``: a JSON list read as the pair (the only place the record
    #: holds a tuple; its numbers stay strict)
    derived_bounds: dict[_Text, Annotated[tuple[_Finite | None, _Finite | None],
                                          Strict(False)]] = {}


class CurveRecord(_Strict):
    """A run that is a two-parameter curve: what builds it again."""

    kind: _Text
    free: _Text
    method: Literal["augmented", "located"]
    margin: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    base_settings: BaseSettings | None = None


class RestartRecord(_Strict):
    """The ``restart`` block of ``report.json`` (written by
    :func:`nsm_continuation.runs.restart_record.restart_block`)."""

    format: Literal["nsm-continuation-restart"]
    version: Literal[1]
    tool_version: Annotated[str, Field(max_length=100)] | None = None
    problem: _Text
    parameters: dict[str, Any]
    continued: _Text | None
    branches: list[BranchRecord]
    curve: CurveRecord | None = None


def _consistency(rec: RestartRecord) -> str | None:
    """What the types cannot say: unique branch ids, the branch's parameter among its
    unknowns, ``y`` and tangents of the branch's size, events of each kind counted 0, 1, ...
    in order, rows within the branch; the path and the problem, or None."""
    ids: set[int] = set()
    for b, br in enumerate(rec.branches):
        at = f"restart.branches[{b}]"
        if br.id in ids:
            return f"{at}.id: branch {br.id} is listed twice"
        ids.add(br.id)
        if len(set(br.variables)) != len(br.variables):
            return f"{at}.variables: {br.variables} names an unknown twice"
        if br.parameter not in br.variables:
            return (f"{at}.parameter: {br.parameter!r} is not one of the branch's unknowns "
                    f"{br.variables}")
        counts: dict[str, int] = {}
        for e, ev in enumerate(br.events):
            where = f"{at}.events[{e}]"
            for key in ("y", "tangent"):
                if len(getattr(ev, key)) != len(br.variables):
                    return (f"{where}.{key}: {len(getattr(ev, key))} numbers, the branch has "
                            f"{len(br.variables)} unknowns ({', '.join(br.variables)})")
            if ev.index != counts.get(ev.kind, 0):
                return (f"{where}.index: {ev.index}, but it is {ev.kind} event number "
                        f"{counts.get(ev.kind, 0)} of the branch (a duplicated or missing "
                        "event)")
            counts[ev.kind] = ev.index + 1
            if ev.row is not None and ev.row >= br.n_points:
                return f"{where}.row: {ev.row}, the branch has {br.n_points} points"
        for c, move in enumerate(br.charts):
            if move.from_row >= max(br.n_points, 1):
                return (f"{at}.charts[{c}].from_row: {move.from_row}, the branch has "
                        f"{br.n_points} points")
    return None


def check_record(block: dict[str, Any], label: str) -> None:
    """:class:`CaseError` ``start.from: <label>: restart.<path>: ...`` (one line) unless
    ``block`` is a well-formed restart record."""
    try:
        rec = RestartRecord.model_validate(block)
    except ValidationError as err:
        raise CaseError(f"start.from: {label}: {_format(err, block, 'restart')}") from None
    problem = _consistency(rec)
    if problem is not None:
        raise CaseError(f"start.from: {label}: {problem}")


# ---------------------------------------------------------------------- reading a run
@dataclass
class RunRecord:
    """A previous run: its restart block and its case input; ``folder`` is None for a run in
    memory (:meth:`nsm_continuation.api.Result.restart`), whose CSV rows are ``rows``."""

    label: str
    restart: dict[str, Any]
    case_input: dict[str, Any]
    folder: Path | None = None
    marker: dict[str, Any] = field(default_factory=dict)
    rows: dict[int, np.ndarray] = field(default_factory=dict)


def _run_first(folder: Path) -> str:
    """``; run it first: nsm-continuation run NAME`` when ``folder`` is where the bundled case
    NAME writes (``runs/NAME``, the parent run of a bundled restart case), else ''."""
    from nsm_continuation.cases import bundled

    if folder.parent.name != "runs" or bundled.find(folder.name) is None:
        return ""
    return f"; run it first: nsm-continuation run {folder.name}"


def load_run(source: str) -> RunRecord:
    """The run in the folder ``source`` (``start.from``); :class:`CaseError` naming
    ``start.from`` when it is not a readable run of this tool with a restart record."""

    shown = short_text(source)
    folder = Path(source).expanduser()
    try:
        if not folder.exists():
            where = "" if folder.is_absolute() else f" (looked for in {Path.cwd()})"
            raise CaseError(f"start.from: {shown} does not exist{where}{_run_first(folder)}")
        if not folder.is_dir():
            raise CaseError(f"start.from: {shown} is not a folder (the output folder of a "
                            "run)")
        marker = read_marker(folder)
        if marker is None or "report.json" not in marker["files"]:
            raise CaseError(f"start.from: {shown} is not a run of nsm-continuation (no "
                            f"{MARKER} listing its report.json)")
        path = folder / "report.json"
        if not path.is_file():
            raise CaseError(f"start.from: {shown}/report.json is missing")
        if sha256(path) != marker["files"]["report.json"]:
            raise CaseError(f"start.from: {shown}/report.json was changed after the run (its "
                            "SHA-256 differs from the run's marker); restart from an "
                            "unchanged run")
        report = json.loads(path.read_text(encoding="utf-8"))
    except CaseError:
        raise
    except OSError as exc:
        raise CaseError(f"start.from: cannot read {shown} ({exc.strerror or exc})") from None
    except (ValueError, RecursionError):
        raise CaseError(f"start.from: {shown}/report.json is not valid JSON") from None
    block = report.get("restart") if isinstance(report, dict) else None
    if not isinstance(block, dict) or block.get("format") != RESTART_FORMAT:
        raise CaseError(f"start.from: {shown}/report.json has no restart record (written "
                        "before restart records existed); run its case again")
    if block.get("version") != RESTART_VERSION:
        raise CaseError(f"start.from: {shown} holds a restart record of version "
                        f"{block.get('version')!r}; this version reads {RESTART_VERSION}")
    case = report.get("case")
    case_input = case.get("input") if isinstance(case, dict) else None
    if not isinstance(case_input, dict):
        raise CaseError(f"start.from: {shown}/report.json has no case input")
    check_record(block, f"{shown}/report.json")
    return RunRecord(shown, block, case_input, folder, marker)


def csv_row(record: RunRecord, br: dict[str, Any], row: int) -> np.ndarray:
    """Row ``row`` of the branch's CSV: its ``y_<name>`` columns (exact: written in repr)."""
    if record.folder is None:
        return np.array(record.rows[int(br["id"])][row], dtype=float)

    name = str(br["csv"])
    path = record.folder / name
    digest = record.marker.get("files", {}).get(name)
    try:
        if digest is None or not path.is_file() or sha256(path) != digest:
            raise CaseError(f"start.point: {record.label}/{name} is missing or was changed "
                            "after the run")
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.reader(fh)
            head = next(reader)
            cols = [head.index(f"y_{v}") if f"y_{v}" in head else -1 for v in br["variables"]]
            if min(cols) < 0:
                raise CaseError(f"start.point: {record.label}/{name} lacks the columns "
                                f"y_<unknown> of {', '.join(br['variables'])}")
            for k, values in enumerate(reader):
                if k == row:
                    return np.array([float(values[c]) for c in cols], dtype=float)
    except CaseError:
        raise
    except OSError as exc:
        raise CaseError(f"start.point: cannot read {record.label}/{name} "
                        f"({exc.strerror or exc})") from None
    except (ValueError, IndexError, StopIteration):
        raise CaseError(f"start.point: row {row} of {record.label}/{name} is not a row of "
                        "numbers") from None
    raise CaseError(f"start.point: {record.label}/{name} has fewer than {row + 1} rows")
