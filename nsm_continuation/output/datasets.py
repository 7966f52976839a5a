"""A run as data for analysis: branch columns with booleans as booleans, the events as a table
(a pandas DataFrame), the whole run as an xarray Dataset and its netCDF file.

* :func:`branch_columns`: the columns of ``branch_<id>.csv`` (:func:`~.files.branch_rows`) as
  numpy arrays, ``admissible`` and ``stable`` as booleans (:func:`flags`: masked where not
  defined; the CSV files keep their 1/0/blank), the ``signature`` as text, the rest floats
  (NaN: not defined). In a DataFrame a flag with missing values is pandas' nullable
  ``boolean``; in the Dataset (xarray and netCDF have no boolean with missing values) it is
  1.0 / 0.0 / NaN.
* :func:`events_frame`: one row per located event (branch ends, kind ``endpoint``,
  included), in branch then arclength order, as :attr:`nsm_continuation.api.Result.events`.
  A DataFrame rather than a numpy structured array: the events of a run are heterogeneous
  (text kinds and details, derived quantities that only some kinds have, a stability that is
  missing where no multipliers were computed), which a DataFrame holds with NaN and pandas'
  nullable booleans and lets a researcher filter by kind, group by branch and plot.
* :func:`to_xarray`: every point of every branch along one dimension ``point`` (coordinates
  ``branch`` and ``row``, the CSV row), the unknowns ``y(point, unknown)``, the Floquet
  multipliers ``multipliers(point, multiplier)`` as complex numbers (by decreasing modulus, as
  in the CSV; NaN where a point has fewer; no such variable when no point has any: a
  brute-force sweep, a run without stability), the events along ``event`` (variables
  ``event_*``); the continued parameter (``<name>`` and ``event_<name>``) is a coordinate;
  attributes name the problem, the case, the continued parameter and the fixed parameters
  (``fixed_parameters``, JSON), and each quantity's ``long_name`` is its axis label
  (:meth:`Presentation.label <nsm_continuation.core.presentation.Presentation.label>`:
  words, symbol and units where the problem declares them).
* :func:`to_netcdf` / :func:`open_netcdf`: the Dataset in a netCDF file and back, equal.
  With ``h5netcdf`` (netCDF-4, the ``xarray`` extra) complex numbers are stored as they are;
  SciPy's netCDF-3 writer (always installed with SciPy) cannot hold complex numbers, so
  there each complex variable is written as two real ones, ``<name>_real`` and
  ``<name>_imag``, which :func:`open_netcdf` joins again; nor an empty dimension (a run
  without events or points), whose variables :func:`open_netcdf` restores from an
  attribute.

pandas, xarray and h5netcdf are optional (``pip install "nsm-continuation[xarray]"``): without
them each function here raises one :class:`ImportError` line naming what to install.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.output.files import SIGNATURE_COLUMN, branch_rows
from nsm_continuation.output.summary import parameter_name
from nsm_continuation.runs.result import RunResult

#: the extra that installs pandas, xarray and a netCDF-4 engine
EXTRA = "pip install 'nsm-continuation[xarray]'"

#: the columns of ``branch_<id>.csv`` that are booleans (written 1/0, blank: not defined)
FLAG_COLUMNS = ("admissible", "stable")

#: the netCDF engines :func:`to_netcdf` may use, the preferred first
ENGINES = ("h5netcdf", "scipy")

#: the names of the Dataset's own coordinates and variables along ``point`` (a derived
#: quantity of one of these names is ``<name>_value``)
RESERVED = frozenset({"branch", "row", "unknown", "multiplier", "y", "multipliers"})

#: the attribute naming the complex variable a real one is part of (netCDF-3 files)
COMPLEX_PART = "complex_part_of"

#: the Dataset's attribute describing the variables along an empty dimension (netCDF-3 files)
EMPTY = "variables_along_empty_dimensions"


def need(module: str, what: str) -> Any:
    """The module ``module`` imported, else one :class:`ImportError` line saying that ``what``
    needs it and how to install it (:data:`EXTRA`)."""
    from importlib import import_module

    try:
        return import_module(module)
    except ImportError:
        raise ImportError(f"{what} needs {module}: {EXTRA} (or pip install {module})"
                          ) from None


def flags(values: Sequence[bool | None]) -> np.ndarray:
    """A boolean column: a numpy ``bool`` array, masked where a value is not defined (a point
    without multipliers has no stability: ``np.ma.MaskedArray``, its masked entries False, so
    that ``omega[stable]`` selects the points known to be stable), a plain array when every
    value is defined."""
    data = np.array([bool(v) for v in values], dtype=bool)
    missing = np.array([v is None for v in values], dtype=bool)
    return np.ma.MaskedArray(data, mask=missing) if missing.any() else data


def as_float(col: np.ndarray) -> np.ndarray:
    """A column with its masked entries NaN (a masked flag column as 1.0 / 0.0 / NaN, as the
    CSV holds it; xarray and netCDF have no boolean with missing values), else unchanged."""
    if isinstance(col, np.ma.MaskedArray):
        return col.astype(float).filled(np.nan)
    return col


def branch_columns(branch: Branch, problem: Problem) -> tuple[list[str], dict[str, np.ndarray]]:
    """The column names of ``branch_<id>.csv`` and each column as a numpy array (module
    docstring)."""
    cols, rows = branch_rows(branch, problem.variables, problem.presentation.csv_head)
    out: dict[str, np.ndarray] = {}
    for j, c in enumerate(cols):
        if c == SIGNATURE_COLUMN:  # text: the family of each point
            out[c] = np.array([str(r[j]) for r in rows], dtype=object)
        elif c == "admissible":
            out[c] = flags([p.admissible for p in branch.points])
        elif c == "stable":
            out[c] = flags([p.stable for p in branch.points])
        else:
            out[c] = np.array([np.nan if r[j] == "" or r[j] is None else r[j] for r in rows],
                              dtype=float)
    return cols, out


def frame(columns: dict[str, np.ndarray], what: str = "BranchData.to_frame") -> Any:
    """A pandas DataFrame of ``columns``, a flag column with missing values (:func:`flags`) as
    pandas' nullable ``boolean``; ``what`` names the caller in the :class:`ImportError`."""
    pd = need("pandas", what)
    df = pd.DataFrame({k: as_float(v) for k, v in columns.items()})
    for c, v in columns.items():
        if isinstance(v, np.ma.MaskedArray):
            df[c] = pd.array([None if m else bool(x) for x, m in zip(v.data, v.mask,
                                                                      strict=True)],
                             dtype="boolean")
    return df


def _problem_of(res: RunResult, branch: Branch) -> Problem:
    return res.branch_problems.get(branch.id, res.problem)


def _scalar(value: Any) -> bool:
    return isinstance(value, str | bool | int | float | np.bool_ | np.integer | np.floating)


def _multipliers(points: Sequence[Point], n: int) -> np.ndarray:
    """``(len(points), n)`` complex: each point's multipliers by decreasing modulus (the CSV's
    order), NaN where it has fewer or none."""
    out = np.full((len(points), n), complex(np.nan, np.nan), dtype=complex)
    for i, p in enumerate(points):
        if p.multipliers is not None and p.multipliers.size:
            m = np.asarray(p.multipliers, dtype=complex)
            out[i, :m.size] = m[np.argsort(-np.abs(m), kind="stable")]
    return out


def _events(res: RunResult) -> list[tuple[Branch, Event, int | None]]:
    """Every event with its branch and the CSV row of its point (None: located between
    rows)."""
    out = []
    for b in res.branches:
        rows = {id(p): k for k, p in enumerate(b.points)}
        out += [(b, ev, rows.get(id(ev.point))) for ev in b.events]
    return out


def event_columns(res: RunResult) -> dict[str, list[Any]]:
    """The columns of :func:`events_frame` as lists: ``branch``, ``kind``, the continued
    parameter (named as the case names it), ``stable`` (None: no multipliers),
    ``admissible``, ``detail``, ``s``, ``row`` (the CSV row of the event's point, None when
    it was located between rows), ``location_bracket`` (the accuracy of its location in
    arclength), ``max_abs_multiplier``, ``multipliers`` (complex, by decreasing modulus), then
    every derived quantity and every scalar datum of the events (None where an event has
    not that one)."""
    name = parameter_name(res)
    events = _events(res)
    cols: dict[str, list[Any]] = {k: [] for k in (
        "branch", "kind", name, "stable", "admissible", "detail", "s", "row",
        "location_bracket", "max_abs_multiplier", "multipliers")}
    extra: list[str] = []
    for _, ev, _ in events:
        for k, v in [*ev.point.derived.items(), *ev.data.items()]:
            if k not in cols and k not in extra and _scalar(v):
                extra.append(k)
    for b, ev, row in events:
        p = ev.point
        variables = list(_problem_of(res, b).variables)
        m = _multipliers([p], p.multipliers.size if p.multipliers is not None else 0)[0]
        for k, v in (("branch", b.id), ("kind", ev.kind), (name, p.value(name, variables)),
                     ("stable", p.stable), ("admissible", bool(p.admissible)),
                     ("detail", ev.detail), ("s", float(p.s)), ("row", row),
                     ("location_bracket", float(ev.bracket)),
                     ("max_abs_multiplier", p.max_abs_multiplier), ("multipliers", m)):
            cols[k].append(v)
        for k in extra:
            v = ev.data.get(k, p.derived.get(k))
            cols.setdefault(k, []).append(v if _scalar(v) else None)
    return cols


def events_frame(res: RunResult) -> Any:
    """The events as a pandas DataFrame, one row per event (:func:`event_columns`):
    ``stable`` a nullable boolean, ``row`` a nullable integer, numbers float (NaN: not
    defined), ``multipliers`` a complex array per row."""
    pd = need("pandas", "Result.events_frame")
    cols = event_columns(res)
    name = parameter_name(res)
    df = pd.DataFrame({k: pd.Series(v, dtype=object) for k, v in cols.items()})
    df["branch"] = df["branch"].astype(int)
    df["stable"] = pd.array(cols["stable"], dtype="boolean")
    df["admissible"] = df["admissible"].astype(bool)
    df["row"] = pd.array(cols["row"], dtype="Int64")
    for k in cols:
        if k in ("branch", "stable", "admissible", "row", "multipliers"):
            continue
        if k in ("kind", "detail") or any(isinstance(v, str) for v in cols[k]):
            df[k] = df[k].astype(str if k in ("kind", "detail") else object)
        elif all(v is None or isinstance(v, bool | np.bool_) for v in cols[k]) and k != name:
            df[k] = pd.array(cols[k], dtype="boolean")
        else:
            df[k] = pd.to_numeric(df[k].map(lambda v: np.nan if v is None else v),
                                  errors="coerce").astype(float)
    return df


def _attrs(res: RunResult, name: str) -> dict[str, str]:
    """The attributes of quantity ``name``: its axis label as ``long_name``."""
    return {"long_name": res.problem.presentation.label(name)}


def _point_variables(res: RunResult, unknowns: list[str], n_mult: int
                     ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The data variables and coordinates along ``point`` (module docstring)."""
    tables = [(b, *branch_columns(b, _problem_of(res, b))) for b in res.branches]
    names: list[str] = []
    for b, cols, _ in tables:
        variables = list(_problem_of(res, b).variables)
        skip = {f"y_{v}" for v in variables}
        names += [c for c in cols if c not in names and c not in skip
                  and not (c.startswith("mu") and c[-3:] in ("_re", "_im"))]
    data: dict[str, list[np.ndarray]] = {c: [] for c in names}
    ys, branch, row = [], [], []
    for b, _, columns in tables:
        n = len(b.points)
        for c in names:
            kind = object if c == SIGNATURE_COLUMN else None
            data[c].append(as_float(columns[c]) if c in columns else
                           np.full(n, "" if kind is object else np.nan, dtype=kind))
        variables = list(_problem_of(res, b).variables)
        y = np.full((n, len(unknowns)), np.nan)
        for j, v in enumerate(variables):
            y[:, unknowns.index(v)] = [p.y[j] for p in b.points]
        ys.append(y)
        branch += [b.id] * n
        row += list(range(n))
    variables_out: dict[str, Any] = {}
    for c, parts in data.items():
        col = np.concatenate(parts) if parts else np.array([])
        if c in FLAG_COLUMNS and col.dtype != bool and not np.isnan(col.astype(float)).any():
            col = col.astype(bool)  # every value defined: booleans
        # a derived quantity named as a coordinate or a variable of the Dataset's own
        variables_out[f"{c}_value" if c in RESERVED else c] = ("point", col, _attrs(res, c))
    all_points = [p for b in res.branches for p in b.points]
    variables_out["y"] = (("point", "unknown"), np.concatenate(ys) if ys else
                          np.zeros((0, len(unknowns))), {"long_name": "the unknowns"})
    variables_out["multipliers"] = (
        ("point", "multiplier"), _multipliers(all_points, n_mult),
        {"long_name": "Floquet multipliers, by decreasing modulus (NaN: none)"})
    coords = {"branch": ("point", np.array(branch, dtype=int)),
              "row": ("point", np.array(row, dtype=int))}
    return variables_out, coords


def _event_variables(res: RunResult, unknowns: list[str], n_mult: int) -> dict[str, Any]:
    """The data variables along ``event``: :func:`event_columns` prefixed ``event_`` (row -1:
    between rows; stable as for a branch, :func:`flags`), the unknowns ``event_y`` and the
    multipliers ``event_multipliers``; data that are not numbers or text are left out."""
    cols = event_columns(res)
    events = _events(res)
    out: dict[str, Any] = {}
    for k, values in cols.items():
        if k == "multipliers":
            continue
        if k in ("stable", "admissible"):
            col = as_float(flags(values))
        elif k in ("row", "branch"):
            col = np.array([-1 if v is None else v for v in values], dtype=int)
        elif k in ("kind", "detail") or any(isinstance(v, str) for v in values):
            col = np.array(["" if v is None else str(v) for v in values], dtype=object)
        else:
            col = np.array([np.nan if v is None else float(v) for v in values], dtype=float)
        out[f"event_{k}"] = ("event", col, _attrs(res, k))
    y = np.full((len(events), len(unknowns)), np.nan)
    for i, (b, ev, _) in enumerate(events):
        for j, v in enumerate(_problem_of(res, b).variables):
            y[i, unknowns.index(v)] = ev.point.y[j]
    out["event_y"] = (("event", "unknown"), y, {"long_name": "the unknowns at the event"})
    out["event_multipliers"] = (
        ("event", "multiplier"), _multipliers([ev.point for _, ev, _ in events], n_mult),
        {"long_name": "Floquet multipliers at the event, by decreasing modulus (NaN: none)"})
    return out


def to_xarray(res: RunResult, source: str | None = None) -> Any:
    """The run as an xarray Dataset (module docstring); ``source``: the folder it was read
    from, an attribute."""
    from nsm_continuation import __version__

    xr = need("xarray", "Result.to_xarray")
    unknowns = list(res.problem.variables)
    for b in res.branches:
        unknowns += [v for v in _problem_of(res, b).variables if v not in unknowns]
    points = [p for b in res.branches for p in b.points]
    points += [ev.point for b in res.branches for ev in b.events]
    n_mult = max((p.multipliers.size for p in points if p.multipliers is not None), default=0)
    variables, coords = _point_variables(res, unknowns, n_mult)
    variables.update(_event_variables(res, unknowns, n_mult))
    coords["unknown"] = ("unknown", np.array(unknowns, dtype=object))
    if n_mult:
        coords["multiplier"] = ("multiplier", np.arange(1, n_mult + 1))
    else:  # no multipliers anywhere (a brute-force sweep, a run without stability)
        del variables["multipliers"], variables["event_multipliers"]
    name = parameter_name(res)
    # the problem's parameters but the continued one (it varies along ``point``)
    fixed = {k: v for k, v in res.problem.params.model_dump(mode="json").items()
             if k not in (name, res.problem.parameter)}
    attrs = {"title": f"nsm_continuation run of case {res.case.name}",
             "problem": res.problem.name, "case": res.case.name,
             "continued_parameter": name, "continued_parameter_long_name":
             res.problem.presentation.label(name),
             "parameter_unknown": res.problem.parameter,
             "fixed_parameters": json.dumps(fixed),
             "nsm_continuation_version": __version__}
    if source is not None:
        attrs["source"] = source
    ds = xr.Dataset(variables, coords=coords, attrs=attrs)
    # the continued parameter as a coordinate (``ds.multipliers.plot.scatter(x="omega")``)
    return ds.set_coords([k for k in (name, f"event_{name}") if k in ds.data_vars])


def _engine(engine: str | None) -> str:
    """``engine``, else the first of :data:`ENGINES` installed."""
    if engine is not None:
        if engine not in ENGINES:
            raise ValueError(f"engine: {engine!r} is not one of {', '.join(ENGINES)}")
        return engine
    try:
        import h5netcdf  # noqa: F401
        import h5py  # noqa: F401
    except ImportError:
        return "scipy"
    return "h5netcdf"


def _netcdf3(ds: Any) -> Any:
    """``ds`` as netCDF-3 can hold it: each complex variable as its parts ``<name>_real`` and
    ``<name>_imag`` (attribute :data:`COMPLEX_PART`), the variables along an empty dimension
    (no point, no event: SciPy cannot read a fixed dimension of size 0 back) left out and
    described in the attribute :data:`EMPTY` (JSON) for :func:`open_netcdf`."""
    empty = {d for d, n in ds.sizes.items() if n == 0}
    gone = {k: {"dims": list(v.dims), "shape": list(v.shape), "dtype": v.dtype.str,
                "attrs": dict(v.attrs), "coord": k in ds.coords}
            for k, v in ds.variables.items() if set(v.dims) & empty}
    out = ds.drop_vars(list(gone))
    if gone:
        out.attrs[EMPTY] = json.dumps(gone)
    for k in [k for k, v in out.data_vars.items() if np.iscomplexobj(v.values)]:
        v = out[k]
        out = out.drop_vars(k)
        for part in ("real", "imag"):
            out[f"{k}_{part}"] = (v.dims, getattr(v.values, part), {**v.attrs, COMPLEX_PART: k})
    return out


def _in_this_process() -> Any:
    """A context in which xarray reads and writes the in-memory Dataset without asking Dask for
    a scheduler: Dask's ``synchronous`` one where Dask is installed (xarray picks its file lock
    by the session's Dask scheduler, and a session whose distributed scheduler went away, e.g.
    a run on a cluster whose scheduler was lost, would otherwise fail the write with "no Client
    active"); nothing to do without Dask."""
    import contextlib
    import importlib.util

    if importlib.util.find_spec("dask") is None:
        return contextlib.nullcontext()
    import dask

    return dask.config.set(scheduler="synchronous")


def to_netcdf(ds: Any, path: str | Path, engine: str | None = None) -> Path:
    """Write the Dataset ``ds`` (:func:`to_xarray`) to the netCDF file ``path`` with
    ``engine`` (default: ``h5netcdf`` where it is installed, else ``scipy``); returns the path.
    netCDF-3 (``scipy``) holds no complex numbers and no empty dimension: :func:`_netcdf3`
    (module docstring)."""
    need("xarray", "Result.to_netcdf")
    engine = _engine(engine)
    if engine == "h5netcdf":
        need("h5netcdf", "a netCDF-4 file")
        need("h5py", "a netCDF-4 file")
    path = Path(path)
    with _in_this_process():
        (_netcdf3(ds) if engine == "scipy" else ds).to_netcdf(path, engine=engine)
    return path


def open_netcdf(path: str | Path) -> Any:
    """The Dataset written by :func:`to_netcdf` at ``path``, read into memory, as it was
    written: complex variables whole again, variables along an empty dimension back
    (netCDF-3, :func:`_netcdf3`)."""
    xr = need("xarray", "open_netcdf")
    with _in_this_process(), xr.open_dataset(path) as opened:
        ds = opened.load()
    parts = {k: v.attrs[COMPLEX_PART] for k, v in ds.data_vars.items() if COMPLEX_PART in v.attrs}
    for name in sorted(set(parts.values())):
        re_, im = ds[f"{name}_real"], ds[f"{name}_imag"]
        attrs = {k: v for k, v in re_.attrs.items() if k != COMPLEX_PART}
        ds = ds.drop_vars([f"{name}_real", f"{name}_imag"])
        whole = np.empty(re_.shape, dtype=complex)
        whole.real, whole.imag = re_.values, im.values
        ds[name] = (re_.dims, whole, attrs)
    gone = json.loads(ds.attrs.pop(EMPTY, "{}"))
    for k, spec in gone.items():
        ds[k] = (spec["dims"], np.empty(spec["shape"], dtype=np.dtype(spec["dtype"])),
                 spec["attrs"])
    return ds.set_coords([k for k, spec in gone.items() if spec["coord"]])


__all__ = ["as_float", "branch_columns", "event_columns", "events_frame", "flags", "frame",
           "open_netcdf", "to_netcdf", "to_xarray"]
