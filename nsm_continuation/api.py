"""The Python API: everything the command line does, from a notebook or a script.

.. code-block:: python

    import nsm_continuation as nsm

    case = nsm.load_case("ndof_default")                        # a bundled case, a path, a dict
    result = nsm.run(case)
    branch = result.branches[0]
    branch["omega"], branch["energy"]                           # numpy arrays, one per column
    [(e.kind, e.parameter) for e in result.events]
    result.save("runs/my_study")                                # the CLI's files, same policy
    again = nsm.load("runs/my_study")                           # read back, days later
    fold = result.restart(event="fold", max_points=50)         # from a point of the result
    nsm.run({"start": {"from": "runs/my_study", "point": 12}})  # or of a saved run
    flip = nsm.run("chain_two_mass_wall")
    period2 = flip.restart(event="period_doubling", switch=True)  # the period-2 family

    problem = nsm.problem("ndof_impact", {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0},
                                          "gap": 1.0})
    result = nsm.continuation(problem, {"mode": 1}, parameter="omega", min=0.3, max=0.9)

A case is validated exactly as on the command line
(:func:`nsm_continuation.cases.validation.validate`):
bad input raises :class:`~nsm_continuation.core.errors.CaseError` whose message names the key,
before
anything is computed.
"""

from __future__ import annotations

import copy
import functools
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from pydantic import ValidationError

from nsm_continuation.cases import registry, schema, validation
from nsm_continuation.cases.schema import Case
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import Branch, OrbitTrace, Point
from nsm_continuation.output.datasets import branch_columns, frame
from nsm_continuation.output.files import (
    build_report,
    event_record,
    termination_text,
    write_outputs,
)
from nsm_continuation.output.folders import OutputError
from nsm_continuation.output.loading import load_result
from nsm_continuation.runs.result import RunResult
from nsm_continuation.runs.runner import run_case

CaseSource = str | Path | Mapping[str, Any] | Case
F = TypeVar("F", bound=Callable[..., Any])

#: the command line's advice in the messages of the layers below, and its words in this API
_CLI_ADVICE = (
    ("pass --overwrite", "pass overwrite=True"),
    (", or --set output.if_exists=new for a numbered folder", ""),
    ("--set output.if_exists=new", "output.if_exists: new"),
    ("choose another --out", "choose another directory"),
    ("use --out or output.dir for a path", "use output.dir or Result.save(directory) for a "
     "path"),
    ("(--scheduler)", "(scheduler=)"),
    ("(--workers)", "(workers=)"),
)


def _api_words(func: F) -> F:
    """``func`` with the command line's advice in its one-line errors (``--set``,
    ``--overwrite``, ``--out``) said as this API's arguments; the error keeps its type."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (CaseError, OutputError) as exc:
            msg = str(exc)
            for cli_words, api_words in _CLI_ADVICE:
                msg = msg.replace(cli_words, api_words)
            if msg == str(exc):
                raise
            raise type(exc)(msg) from None

    return wrapper  # type: ignore[return-value]


def _kind(value: Any) -> str:
    """The type and value of a wrong argument, for a one-line message."""
    from nsm_continuation.core.errors import short_text

    return f"{type(value).__name__} {short_text(repr(value), 60)}"


def _mapping(value: Any, name: str) -> dict[str, Any]:
    """``value`` (a mapping, or None for none) as a dict; else a :class:`CaseError` naming the
    argument ``name``."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise CaseError(f"{name}: expected a mapping of keys (a dict such as {{'key': value}}), "
                        f"got {_kind(value)}")
    return dict(value)


def _flag(value: Any, name: str) -> bool:
    """``value`` if it is a bool; else a :class:`CaseError` naming the argument ``name``."""
    if not isinstance(value, bool | np.bool_):
        raise CaseError(f"{name}: expected True or False, got {_kind(value)}")
    return bool(value)


@_api_words
def load_case(source: CaseSource, overrides: Sequence[str] | Mapping[str, Any] = ()) -> Case:
    """A validated case from a YAML file, a mapping or a :class:`Case`.

    ``overrides`` are ``"dotted.key=value"`` strings (as ``--set``) or a mapping
    ``{"continuation.max": 2.0}``. The problem is built and its preflight run, so an invalid
    case raises :class:`CaseError` here, as ``nsm-continuation validate`` would.
    """
    case, _ = _validated(source, overrides)
    return case


def _raw(source: CaseSource) -> dict[str, Any]:
    if isinstance(source, Case):
        return source.model_dump(mode="python")
    if isinstance(source, Mapping):
        return copy.deepcopy(dict(source))  # overrides never change the caller's mapping
    if isinstance(source, str | Path):
        return schema.load_raw(source)
    raise CaseError(f"case: expected a YAML path, a mapping or a Case, got "
                    f"{type(source).__name__}")


def _validated(source: CaseSource, overrides: Sequence[str] | Mapping[str, Any] = ()
               ) -> tuple[Case, Problem]:
    if isinstance(overrides, Mapping):
        raw = _raw(source)
        for key, value in overrides.items():
            if not isinstance(key, str) or not all(key.split(".")):
                raise CaseError(f"overrides: the key {key!r} is not a dotted key such as "
                                "'continuation.max'")
            schema.set_dotted(raw, key, value, "overrides:")
    elif isinstance(overrides, str | bytes) or not isinstance(overrides, Sequence):
        raise CaseError(f"overrides: expected a list of 'dotted.key=value' strings or a "
                        f"mapping {{'dotted.key': value}}, got {_kind(overrides)}")
    else:
        raw = schema.apply_overrides(_raw(source), list(overrides), "overrides:")
    return validation.validate(raw)


@_api_words
def run(source: CaseSource, overrides: Sequence[str] | Mapping[str, Any] = (),
        progress: bool = False, *, workers: int | None = None,
        scheduler: str | None = None) -> Result:
    """Run a case (file, mapping or :class:`Case`) and return its :class:`Result`. Nothing is
    written: call :meth:`Result.save`. ``workers`` (a local Dask cluster of that many
    processes) or ``scheduler`` (an existing cluster's address) compute the branches as Dask
    tasks, with the same result (:mod:`nsm_continuation.runs.execution`); they replace the case's
    ``execution:`` block (default: serial), and exclude each other."""
    progress = _flag(progress, "progress")
    case, problem = _validated(source, overrides)
    case = schema.with_execution(case, workers, scheduler)
    return Result(run_case(case, problem, progress=progress))._logged()


@_api_words
def load(folder: str | Path) -> Result:
    """The run saved in ``folder`` (by the command line or :meth:`Result.save`) read back as
    a :class:`Result`: its branches, events, tree and report as the run had them, and its
    figures, orbits and restarts as from the run itself
    (:mod:`nsm_continuation.output.loading`: the files are read, nothing is unpickled or
    computed). A folder that is not a run of this tool, a file changed since the run, or a run
    of a newer format is a :class:`CaseError` whose one line names the folder and the
    problem."""
    res, _ = load_result(folder)
    return Result(res, source=Path(os.fsdecode(folder)))


@_api_words
def problem(name: str, parameters: Mapping[str, Any] | None = None) -> Problem:
    """The registered problem ``name`` (``nsm-continuation list``) built from ``parameters``
    (the YAML ``parameters:`` block, validated by the problem's schema)."""
    if not isinstance(name, str):
        raise CaseError(f"problem: expected a problem name (nsm-continuation list), got "
                        f"{_kind(name)}")
    params_raw = _mapping(parameters, "parameters")
    try:
        schema._visible_name(name)
        cls = registry.get(name)
    except CaseError:  # already one line naming its key (a plugin's fault)
        raise
    except (registry.UnknownProblemError, ValueError) as exc:
        raise CaseError(f"problem: {exc}") from None
    try:
        params = cls.Parameters.model_validate(params_raw)
    except ValidationError as err:
        raise CaseError(schema._format(err, params_raw, "parameters")) from None
    with validation.plugin_hook(cls, name, "in __init__"):  # a plugin's fault: named
        try:
            return cls(params)
        except (ValueError, ArithmeticError) as exc:
            raise CaseError(schema._keyed("parameters", str(exc))) from None


@_api_words
def continuation(problem: Problem, start: Any, *, name: str = "python",
                 analysis: Mapping[str, Any] | None = None, workers: int | None = None,
                 scheduler: str | None = None, **settings: Any) -> Result:
    """Continue ``problem`` from ``start`` with our pseudo-arclength engine.

    ``start`` is the YAML ``start:`` block of the problem (e.g. ``{"mode": 1}``), a
    :class:`~nsm_continuation.core.problem.StartPoint`, or a guess ``y`` (array of the problem's
    unknowns, corrected by Newton at fixed parameter). ``settings`` are the keys of the YAML
    ``continuation:`` block (``parameter``, ``min``, ``max``, ``step={...}``, ``max_points``,
    ...) and ``analysis`` those of ``analysis:``. ``workers`` / ``scheduler``: as for
    :func:`run` (the branches of several starts, the switches of a bifurcation diagram as
    Dask tasks; ``problem``'s class must be importable by the workers).
    """
    if not isinstance(problem, Problem):
        raise CaseError(f"problem: expected a Problem (nsm.problem(name, parameters)), got "
                        f"{_kind(problem)}")
    if not isinstance(start, Mapping | StartPoint | np.ndarray | list | tuple):
        raise CaseError(f"start: expected the problem's start: block (a mapping such as "
                        f"{{'mode': 1}}), a StartPoint or a guess of its {problem.dim} "
                        f"unknowns, got {_kind(start)}")
    block = dict(start) if isinstance(start, Mapping) else {}
    adapter = type(problem).start_adapter
    if adapter is not None and isinstance(start, Mapping):
        try:
            adapter.validate_python(block)
        except ValidationError as err:
            raise CaseError(schema._format(err, block, "start")) from None
    raw = {"name": name, "problem": problem.name,
           "parameters": problem.params.model_dump(mode="python"), "start": block,
           "continuation": {"parameter": problem.parameter, **settings},
           "analysis": _mapping(analysis, "analysis"),
           "output": {"plots": False, "progress": False}}
    try:
        case = Case.model_validate(raw)
    except ValidationError as err:
        raise CaseError(schema._format(err, raw)) from None
    case = schema.with_execution(case, workers, scheduler)
    try:
        window = problem.parameter_bounds(case.continuation.parameter, case.continuation.min,
                                          case.continuation.max)
    except ValueError as exc:
        raise CaseError(schema._keyed("continuation.parameter", str(exc))) from None
    if isinstance(start, Mapping):
        validation.preflight(problem, case, block, window)
        return Result(run_case(case, problem, progress=False))._logged()
    if not isinstance(start, StartPoint):
        try:
            y = np.asarray(start, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise CaseError(f"start: a guess needs {problem.dim} numbers "
                            f"({problem.variables}), got {_kind(start)}") from None
        if not np.all(np.isfinite(y)):
            raise CaseError(f"start: a guess needs {problem.dim} finite numbers, got "
                            f"{_kind(start)}")
        if y.size != problem.dim:
            raise CaseError(f"start: a guess needs {problem.dim} values ({problem.variables}), "
                            f"got {y.size}")
        start = StartPoint(y, "from guess")
    return Result(run_case(case, problem, progress=False, starts=[start]))._logged()


def _orbit_periods(periods: Any, key: str) -> int:
    """``periods`` as a whole number from 1 to
    :data:`~nsm_continuation.cases.schema.MAX_ORBIT_PERIODS`, else a
    :class:`CaseError` (a ``ValueError``) naming ``key``."""
    if isinstance(periods, bool) or not isinstance(periods, int | np.integer) \
            or not 1 <= periods <= schema.MAX_ORBIT_PERIODS:
        raise CaseError(f"{key}: {periods!r} is not a whole number of periods from 1 to "
                        f"{schema.MAX_ORBIT_PERIODS}")
    return int(periods)


def _names_or_numbers(values: Any, key: str, *, numbers: bool,
                      example: str = "['first', 'last']") -> list[Any]:
    """``values`` as a list of names (and finite numbers if ``numbers``; an empty list is
    left to the figure's own check): else a :class:`CaseError` (a
    ``ValueError``) naming ``key``; a single string is not a list of names
    (``points="first"`` would be five letters)."""
    if isinstance(values, str | bytes | Mapping) or not isinstance(values, Sequence | np.ndarray):
        raise CaseError(f"{key}: expected a list (e.g. {example}), got {_kind(values)}")
    out = list(values)
    for i, v in enumerate(out):
        number = isinstance(v, int | float | np.integer | np.floating) \
            and not isinstance(v, bool | np.bool_)
        if isinstance(v, str) and v:
            continue
        if numbers and number and math.isfinite(float(v)):
            out[i] = float(v)
            continue
        what = "a name or a finite number" if numbers else "a name"
        raise CaseError(f"{key}[{i}]: expected {what}, got {_kind(v)}")
    return out


@dataclass(frozen=True)
class EventRecord:
    """One located event: its kind, branch, the value of the problem's parameter unknown
    (``problem.parameter``: the chain's period ``T`` even when a case continues it in
    ``omega = 2 pi / T``; the continued quantity is in ``record``), and the full record
    written to ``report.json`` (multipliers, derived quantities, data)."""

    kind: str
    branch: int
    parameter: float
    detail: str
    record: dict[str, Any]
    point: Point


class BranchData:
    """One branch as columns (the CSV columns, as numpy arrays: ``branch["omega"]``) and as
    records (:attr:`raw`, the :class:`~nsm_continuation.core.records.Branch`). ``admissible``
    and ``stable`` are numpy booleans (:func:`~nsm_continuation.output.datasets.flags`:
    ``stable`` is a masked array where some points have no multipliers, its masked entries
    False, so ``branch["omega"][branch["stable"]]`` are the points known to be stable), the
    ``signature`` text, the rest floats (NaN: not defined at that point)."""

    def __init__(self, branch: Branch, problem: Problem) -> None:
        self.raw = branch
        self.id = branch.id
        self.label = branch.label
        self.termination = dict(branch.termination)
        self.column_names, self._columns = branch_columns(branch, problem)
        self.parameter = np.array([p.y[problem.parameter_index] for p in branch.points])
        self.y = np.array([p.y for p in branch.points]).reshape(len(branch.points),
                                                               problem.dim)
        self.multipliers = [p.multipliers for p in branch.points]

    def __len__(self) -> int:
        return len(self.raw.points)

    def __getitem__(self, column: str) -> np.ndarray:
        try:
            return self._columns[column]
        except KeyError:
            raise KeyError(f"{column!r} is not a column of branch {self.id} (one of "
                           f"{self.column_names})") from None

    def columns(self) -> dict[str, np.ndarray]:
        """Every column as a numpy array (NaN where a value is not defined; the ``signature``
        column, the family of each point, as text)."""
        return dict(self._columns)

    def to_frame(self) -> Any:
        """The branch as a pandas DataFrame, one row per point (needs pandas: ``pip install
        "nsm-continuation[xarray]"``): the columns of :meth:`columns`, ``stable`` a nullable
        boolean where some points have no multipliers."""
        return frame(self._columns)

    def __repr__(self) -> str:
        return (f"BranchData(id={self.id}, label={self.label!r}, points={len(self)}, "
                f"termination={termination_text(self.raw)!r})")


class Result:
    """The result of a run: branches, events, the report, and the CLI's outputs on demand.
    Computed (:func:`run`, :func:`continuation`, :meth:`restart`) or read back from a saved
    run (:func:`load`, :meth:`Result.load`; :attr:`source` is its folder). Displayed as a
    summary of its branches and special points (text, and HTML or Markdown in a notebook)."""

    def __init__(self, run_result: RunResult, source: Path | None = None) -> None:
        self.run_result = run_result
        self.problem = run_result.problem
        self.case = run_result.case
        self.branches = [BranchData(b, self.problem) for b in run_result.branches]
        #: the folder this result was read from (:func:`load`); None for a computed one
        self.source = source
        self._warnings: list[str] | None = None

    @classmethod
    def load(cls, folder: str | Path) -> Result:
        """:func:`load`: the run saved in ``folder``."""
        return load(folder)

    @property
    def warnings(self) -> list[str]:
        """The run's warnings, as ``report.json`` lists them: the problem's (e.g. a model
        outside the paper's assumptions), what ``output.orbits`` cannot draw, multipliers
        that are not reliable, parts of the outputs a plugin's hook could not give. Logged
        to the ``nsm_continuation`` logger when the run ends."""
        if self._warnings is None:
            self._warnings = list(self.report().get("warnings", []))
        return list(self._warnings)

    def _logged(self) -> Result:
        """This result, its :attr:`warnings` and its :attr:`failed_starts` (the command
        line's ``n of m starts failed``) logged, each once, as warnings."""
        from nsm_continuation import logger

        for w in self.warnings:
            logger.warning("%s: %s", self.case.name, w)
        failed = self.failed_starts
        if failed:
            logger.warning("%s: %d of %d starts failed: %s", self.case.name, len(failed),
                           len(self.branches), "; ".join(
                               f"branch {b.id} ({b.label}): {termination_text(b.raw)}"
                               for b in failed))
        return self

    @property
    def events(self) -> list[EventRecord]:
        """Every located event of every branch, in branch then arclength order (branch ends,
        kind ``endpoint``, included)."""
        ip = self.problem.parameter_index
        return [EventRecord(ev.kind, b.id, float(ev.point.y[ip]), ev.detail, event_record(ev),
                            ev.point)
                for b in self.run_result.branches for ev in b.events]

    def events_frame(self) -> Any:
        """:attr:`events` as a pandas DataFrame, one row per event: ``branch``, ``kind``, the
        continued parameter (named as the case names it: ``omega`` for the chain), ``stable``
        (nullable boolean: missing without multipliers), ``admissible``, ``detail``, ``s``,
        ``row`` (the event's row in ``branch_<id>.csv``; missing when it was located between
        rows), ``location_bracket``, ``max_abs_multiplier``, ``multipliers`` (complex, by
        decreasing modulus), then the events' derived quantities and data
        (:func:`~nsm_continuation.output.datasets.events_frame`). Needs pandas (``pip install
        "nsm-continuation[xarray]"``; without it, an ``ImportError`` saying so)."""
        from nsm_continuation.output.datasets import events_frame

        return events_frame(self.run_result)

    def to_xarray(self) -> Any:
        """The run as an xarray Dataset: every point of every branch along ``point``
        (coordinates ``branch`` and ``row``), each CSV column a variable (``admissible`` and
        ``stable`` booleans), the unknowns ``y(point, unknown)``, the Floquet multipliers
        ``multipliers(point, multiplier)`` as complex numbers, the events along ``event``
        (variables ``event_*``); the continued parameter a coordinate (``ds.omega``); the
        problem, the case and the continued parameter as attributes, each quantity's axis
        label as its ``long_name`` (:func:`~nsm_continuation.output.datasets.to_xarray`).
        Select a branch with ``ds.where(ds.branch == 1, drop=True)``. Needs xarray (``pip
        install "nsm-continuation[xarray]"``)."""
        from nsm_continuation.output.datasets import to_xarray

        return to_xarray(self.run_result, self._source_text())

    def to_netcdf(self, path: str | Path, engine: str | None = None) -> Path:
        """:meth:`to_xarray` written to the netCDF file ``path`` (``engine``: ``"h5netcdf"``,
        netCDF-4, the default where installed, or ``"scipy"``, netCDF-3, whose complex
        multipliers are written as real and imaginary parts); read it back with
        :func:`nsm_continuation.open_netcdf` (:func:`~nsm_continuation.output.datasets.to_netcdf`).
        Returns the path."""
        from nsm_continuation.output.datasets import need, to_netcdf

        need("xarray", "Result.to_netcdf")
        if not isinstance(path, str | os.PathLike) or not os.fspath(path):
            raise CaseError(f"path: expected a file path (str or pathlib.Path), got "
                            f"{_kind(path)}")
        return to_netcdf(self.to_xarray(), Path(os.fsdecode(path)), engine)

    @property
    def tree(self) -> list[dict[str, Any]]:
        """The tree of a bifurcation diagram (``analysis.branch_switching``,
        :mod:`nsm_continuation.runs.diagrams`): per event considered, its generation, parent
        branch, event ``{kind, index}``, parameter, child branch (None if not followed) and
        status; empty for a run without branch switching."""
        return [dict(n) for n in self.run_result.tree]

    @property
    def failed_starts(self) -> list[BranchData]:
        """Branches whose start failed (no point, or a start outside the parameter window;
        the termination says why: :attr:`Branch.failed_start
        <nsm_continuation.core.records.Branch.failed_start>`)."""
        return [b for b in self.branches if b.raw.failed_start]

    def report(self) -> dict[str, Any]:
        """The content of ``report.json`` (of a result read back: the file itself)."""
        if self.run_result.saved_report is not None:
            return copy.deepcopy(self.run_result.saved_report)
        return build_report(self.run_result)

    @_api_words
    def save(self, directory: str | Path, *, overwrite: bool = False,
             plots: bool = True) -> Path:
        """Write the CLI's outputs into ``directory`` under the output policy (docs/runs.md,
        "Runs: output folders, exit status, limits"): a new folder, or a previous run replaced
        only with ``overwrite=True``. Returns the directory written. What the command line
        would say on writing (a plugin's figures that failed and were left out, what killed
        runs had left next to the folder) is logged to the ``nsm_continuation`` logger as
        warnings."""
        from nsm_continuation.figures.make import make_all

        if not isinstance(directory, str | os.PathLike) or not os.fspath(directory):
            raise CaseError(f"directory: expected a folder path (str or pathlib.Path), got "
                            f"{_kind(directory)}")
        from nsm_continuation import logger

        overwrite = _flag(overwrite, "overwrite")
        plots = _flag(plots, "plots")
        notes: list[str] = []
        path = write_outputs(self.run_result, Path(os.fsdecode(directory)),
                             make_all if plots else None,
                             if_exists="overwrite" if overwrite else "error", notes=notes)
        known = set(self.warnings)  # logged when the run ended
        for line in notes:
            if line not in known:
                logger.warning("%s: %s", self.case.name, line)
        return path

    @_api_words
    def restart(self, *, branch: int | None = None, event: Any = None, point: int | None = None,
                switch: bool | str = False, amplitude: float | None = None,
                direction: str | None = None, parameters: Mapping[str, Any] | None = None,
                name: str | None = None, analysis: Mapping[str, Any] | None = None,
                curve: str | None = None, free: str | None = None,
                margin: float | None = None, method: str | None = None,
                **settings: Any) -> Result:
        """Continue again from a point of this result (:mod:`nsm_continuation.cases.restart`), as a
        case with ``start: {from: <this run>, ...}`` would from its saved folder.

        ``event``: a kind (the only event of that kind on the branch), ``{"kind": ...,
        "index": n}``, or one of :attr:`events` (its branch and place are taken from it);
        ``point``: a row of the branch (its CSV row); ``switch=True`` follows the branch that
        bifurcates there (:mod:`nsm_continuation.algorithms.switching`: the period-2 family at a
        period
        doubling, the other branch at a branch point); ``curve=<kind>`` continues the event in
        two parameters, ``free`` (the parameter this run continued) solved for and
        ``parameter=...`` continued: ``"grazing"`` by the augmented system
        (:mod:`nsm_continuation.hybrid.codim1`), ``"period_doubling"``, ``"fold"``,
        ``"neimark_sacker"`` and any kind the problem maps a monitor to (e.g. a hybrid
        orbit's ``"sticking_lost"``; ``"grazing"`` with ``method="located"``) as located
        events (:func:`nsm_continuation.algorithms.curves.curve_kinds`).
        ``parameters`` override this run's,
        ``settings`` are keys of the ``continuation:`` block (``parameter`` may be any
        parameter of the problem; the rest of the block is inherited when it is the same),
        ``analysis`` keys of ``analysis:``. Nothing is written (:meth:`save`)."""
        from nsm_continuation.runs.restart_record import record_from_result

        if isinstance(event, EventRecord):
            same = [e for e in self.events if e.branch == event.branch and e.kind == event.kind]
            index = next((k for k, e in enumerate(same) if e.point is event.point), None)
            if index is None:
                raise CaseError("start.event: this event is not an event of this result")
            branch, event = event.branch, {"kind": event.kind, "index": index}
        start: dict[str, Any] = {"from": f"<result {self.case.name}>"}
        for key, value in (("branch", branch), ("event", event), ("point", point),
                           ("amplitude", amplitude), ("direction", direction),
                           ("curve", curve), ("free", free), ("margin", margin),
                           ("method", method)):
            if value is not None:
                start[key] = dict(value) if isinstance(value, Mapping) else value
        if switch is not False:
            start["switch"] = switch
        raw: dict[str, Any] = {"start": start,
                               "parameters": _mapping(parameters, "parameters"),
                               "continuation": dict(settings),
                               "analysis": _mapping(analysis, "analysis"),
                               "output": {"plots": False, "progress": False}}
        if name is not None:
            raw["name"] = name
        record = record_from_result(self.run_result, start["from"])
        case, problem = validation.validate(raw, restart_record=record,
                                       problem_class=type(self.problem))
        return Result(run_case(case, problem, progress=False))._logged()

    @_api_words
    def orbit(self, branch: int = 0, point: int = -1, periods: int = 1) -> OrbitTrace:
        """The periodic orbit at row ``point`` of branch ``branch`` (its id, as in
        ``branch_<id>.csv``; a negative row counts from the end) over ``periods`` periods
        (1 to :data:`~nsm_continuation.cases.schema.MAX_ORBIT_PERIODS`; :meth:`Presentation.orbit
        <nsm_continuation.core.presentation.Presentation.orbit>`): time ``t``, named ``signals``,
        their
        ``labels``, impact ``marks``, sticking ``intervals`` and the family's ``views``.
        ``ValueError`` naming the argument for a branch, row or number of periods the run
        does not have, or if the problem does not draw its orbits."""
        from nsm_continuation.figures.orbit_selection import problem_of

        n = _orbit_periods(periods, "periods")
        br = self._branch(branch)
        rows = len(br.points)
        if isinstance(point, bool) or not isinstance(point, int | np.integer) \
                or not -rows <= point < rows:
            raise ValueError(f"point: {point!r} is not a row of branch {br.id} ({rows} points: "
                             f"rows 0 to {rows - 1}, or -{rows} to -1 from the end)")
        p = br.points[int(point)]
        trace = problem_of(self.run_result, br, p).presentation.orbit(p.y, n)
        if trace is None:
            raise ValueError(f"problem {self.problem.name!r} does not draw its orbits "
                             "(Presentation.orbit is not implemented)")
        return trace

    def _branch(self, branch: int) -> Branch:
        """The branch of id ``branch`` with points, else a ``ValueError`` naming the ids."""
        by_id = {br.id: br for br in self.run_result.branches}
        br = by_id.get(branch) if isinstance(branch, int | np.integer) \
            and not isinstance(branch, bool) else None
        if br is None:
            raise ValueError(f"branch: {branch!r} is not a branch of this run (ids: "
                             f"{', '.join(map(str, by_id))})")
        if not br.points:
            raise ValueError(f"branch: branch {br.id} has no points "
                             f"({termination_text(br)})")
        return br

    @_api_words
    def plot_orbits(self, points: Sequence[str | float] = ("first", "last"),
                    view: str = "time", ax: Any = None, periods: int = 1,
                    log: Sequence[str] = ()) -> Any:
        """An orbit figure as the case key ``output.orbits`` draws it
        (:mod:`nsm_continuation.figures.orbits`): the ``view`` (``time``, ``phase`` or ``manifold``,
        as the problem draws them: :meth:`Presentation.orbit_view_names
        <nsm_continuation.core.presentation.Presentation.orbit_view_names>`) of the orbits at
        ``points``
        (``first``, ``last``, ``events``, an event kind or a value of the continued
        parameter), on ``ax`` (a new figure if None; the time view then draws its first signal
        only). Returns the matplotlib Figure; :class:`CaseError` (a ``ValueError``) naming the
        argument for a view the problem does not draw, a point that selects nothing, a
        ``log`` signal the time view does not draw or a number of periods out of range."""
        from nsm_continuation.figures import orbits

        points = _names_or_numbers(points, "plot_orbits.points", numbers=True)
        log = _names_or_numbers(log, "plot_orbits.log", numbers=False,
                                example="['u1']")
        if ax is not None and not hasattr(ax, "get_figure"):
            raise CaseError(f"plot_orbits.ax: expected a matplotlib Axes or None, got "
                            f"{_kind(ax)}")
        validation.check_orbit_view(view, self.problem, "plot_orbits.view")
        n = _orbit_periods(periods, "plot_orbits.periods")
        validation.check_orbits(points, self.problem, "plot_orbits")
        return orbits.plot(self.run_result, points, view, ax, n, log)

    def plot(self, ax: Any = None) -> Any:
        """The branch diagram (the run's ``fep.png``) drawn on ``ax`` (a new figure if None);
        returns the matplotlib Figure. A new figure is made without ``pyplot``
        (:func:`nsm_continuation.figures.kit.figure`): the backend and ``pyplot``'s figures
        are left as they were; Jupyter shows it as a cell's value, ``fig.savefig`` writes it."""
        from nsm_continuation.figures import branches as plots

        return plots.diagram(self.run_result, ax)

    def __repr__(self) -> str:
        """The summary: branches (points, parameter range, ends) and special points."""
        from nsm_continuation.output.summary import text

        return text(self.run_result, self._source_text())

    def _repr_html_(self) -> str:
        from nsm_continuation.output.summary import as_html

        return as_html(self.run_result, self._source_text())

    def _repr_markdown_(self) -> str:
        from nsm_continuation.output.summary import as_markdown

        return as_markdown(self.run_result, self._source_text())

    def _source_text(self) -> str | None:
        return None if self.source is None else str(self.source)
