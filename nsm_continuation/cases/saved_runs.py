"""A saved run read back: its marker, its restart record and its CSV rows.

Every run folder holds a marker (:data:`MARKER`: the tool, its version and the SHA-256 of every
file the run wrote, :mod:`nsm_continuation.output.folders`) and a ``report.json`` whose
``restart`` block (format :data:`RESTART_FORMAT`, version :data:`RESTART_VERSION`,
:func:`nsm_continuation.runs.restart_record.restart_block`) names the problem, its full
parameters and, per branch, the unknowns and every located event with its ``y`` and tangent.
:func:`load_run` reads a folder back as a :class:`RunRecord` (``start.from`` of a restart):
a missing folder, a folder that is not a run of this tool, a ``report.json`` or CSV changed
since the run, or a record of another version is a :class:`CaseError` naming ``start.from`` or
``start.point``.
"""

from __future__ import annotations

import csv
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

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


def load_run(source: str) -> RunRecord:
    """The run in the folder ``source`` (``start.from``); :class:`CaseError` naming
    ``start.from`` when it is not a readable run of this tool with a restart record."""

    shown = short_text(source)
    folder = Path(source).expanduser()
    try:
        if not folder.exists():
            where = "" if folder.is_absolute() else f" (looked for in {Path.cwd()})"
            raise CaseError(f"start.from: {shown} does not exist{where}")
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
