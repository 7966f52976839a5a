"""YAML cases: schema, validation and ``--set`` overrides.

Every error is a :class:`CaseError` whose message is one line naming the offending key
(``continuation.step.min: ...``); the command line prints it and exits with status 2 before
anything is written.
"""

from __future__ import annotations

import copy
import math
import re
import stat
import unicodedata
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    model_validator,
)

from nsm_continuation.core.errors import CaseError, short_text

# strict: ``true`` is not a number and ``"3"`` is not an integer (an int is a valid float)
PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False, strict=True)]
Finite = Annotated[float, Field(allow_inf_nan=False, strict=True)]
PosInt = Annotated[int, Field(ge=1, strict=True)]
Bool = Annotated[bool, Field(strict=True)]
#: smallest step a case may ask for: below it a step does not move a point of size 1 (|y| eps)
STEP_FLOOR = 1e-14
#: largest number of points per direction (each point keeps y, tangent and multipliers)
MAX_POINTS = 1_000_000
#: a case file larger than this is refused unread (cases are a few hundred bytes)
MAX_CASE_BYTES = 1_000_000
#: a case that expands (YAML aliases included) to more values than this is refused
MAX_CASE_NODES = 200_000
#: a case name is a folder name, never a path
NAME_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9._+-]{0,99}$"


def _plain_name(name: str) -> str:
    """A case name names the output folder ``runs/<name>``: a plain folder name, not a path."""
    if not re.match(NAME_PATTERN, name) or name in {".", ".."}:
        raise ValueError(f"{name!r} is not a plain folder name (letters, digits, '_', '-', '.', "
                         "'+', at most 100 characters, no '/'); use --out or output.dir for a "
                         "path")
    return name


def _visible_name(name: str) -> str:
    """A problem name with an invisible, control or non-ASCII character (a zero-width space,
    a Cyrillic letter that looks like a Latin one) is refused with the name escaped, unless a
    problem is registered under exactly that name: the message of an unknown problem would
    show it as the registered name it looks like."""
    if not name or show_key(name) == name:  # empty: the registry says it is unknown
        return name
    from nsm_continuation.cases import registry

    if name in registry.available():
        return name
    odd = next((c for c in name if not (c.isascii() and c.isprintable()) or c == " "), "?")
    raise ValueError(f"unknown problem {show_key(name)}: it holds the character "
                     f"{ascii(odd)}, which registered problem names do not "
                     "(nsm-continuation list)")


#: the smallest ``continuation.newton_tol`` (a few units of double precision's resolution)
NEWTON_TOL_FLOOR = 1e-15


class StepSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    #: the first pseudo-arclength step (arclength in the scaled unknowns)
    initial: PosFloat = 1e-2
    #: the smallest step: a branch whose step falls below it ends, with the reason
    min: PosFloat = 1e-9
    #: the largest step (the step grows with easy Newton solves and shrinks at
    #: events, turning tangents and moving multipliers)
    max: PosFloat = 0.2

    @model_validator(mode="after")
    def _order(self) -> StepSpec:
        if self.min < STEP_FLOOR:
            raise ValueError(f"min: {self.min:g} is below {STEP_FLOOR:g}, where a step no "
                             "longer moves a point in floating point")
        if not self.min <= self.initial <= self.max:
            raise ValueError(f"need min <= initial <= max (got {self.min}, {self.initial}, "
                             f"{self.max})")
        return self


class ContinuationSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    #: the continued parameter; None (not given): the problem's
    #: (``Problem.case_parameter``, else ``Problem.parameter``), resolved by :func:`validate`
    #: once the problem is built
    parameter: str | None = None
    #: lower edge of the window of the continued parameter (a branch ends there with
    #: an ``endpoint``); default none
    min: Finite | None = None
    #: upper edge of the window of the continued parameter; default none
    max: Finite | None = None
    #: the pseudo-arclength step sizes
    step: StepSpec = StepSpec()
    #: points per direction of each branch, at most
    max_points: Annotated[int, Field(ge=2, le=MAX_POINTS, strict=True)] = 400
    #: a branch ends when the energy (the problem's ``energy_quantity``) exceeds it
    max_energy: PosFloat | None = None
    #: which way along ``continuation.parameter`` a branch is followed from its
    #: start (a problem whose internal parameter runs the other way turns it round:
    #: ``Problem.parameter_orientation``)
    direction: Literal["both", "increase", "decrease"] = "both"
    #: tolerance of the corrector's Newton iteration, on the step and the residual
    #: relative to the unknowns
    newton_tol: PosFloat = 1e-11
    #: the largest turn of the tangent in one step (radians)
    max_angle: PosFloat = 0.25
    #: bounds on derived quantities ``{name: [min, max]}`` (null for none), e.g.
    #: ``period: [null, 60]``; the branch stops where one is reached (an event of the kind the
    #: problem maps the quantity to, e.g. ``homoclinic_approach`` for the period)
    bounds: dict[str, tuple[Finite | None, Finite | None]] = {}
    #: the continuation algorithm (:mod:`nsm_continuation.algorithms.base`): one of the problem's
    #: ``algorithms`` (default: its first, ``palc`` for most, ``lattice`` for ``wfem_bar``)
    algorithm: Literal["palc", "lattice", "pycont", "sweep"] | None = None

    @model_validator(mode="after")
    def _bounds(self) -> ContinuationSpec:
        if self.newton_tol < NEWTON_TOL_FLOOR:
            raise ValueError(f"newton_tol: {self.newton_tol:g} is below {NEWTON_TOL_FLOOR:g}: "
                             "a Newton step and a residual relative to the unknowns are "
                             "resolved to ~1e-16 in double precision, so no iteration could "
                             "meet it")
        if self.min is not None and self.max is not None and self.min >= self.max:
            raise ValueError(f"need min < max (got min = {self.min}, max = {self.max})")
        for name, (lo, hi) in self.bounds.items():
            if lo is not None and hi is not None and lo >= hi:
                raise ValueError(f"bounds: {name}: need [min, max] with min < max (got "
                                 f"[{lo}, {hi}])")
        return self


#: event kinds at which ``analysis.branch_switching`` follows the branch born there
DIAGRAM_KINDS = ("period_doubling", "branch_point")
#: largest ``analysis.branch_switching.depth`` (generations of switched branches)
MAX_DIAGRAM_DEPTH = 8


def _unique(kinds: list[str]) -> list[str]:
    if len(set(kinds)) != len(kinds):
        raise ValueError(f"{kinds} names a kind twice")
    return kinds


class BranchSwitchingSpec(BaseModel):
    """``analysis.branch_switching``: a bifurcation diagram (:mod:`nsm_continuation.runs.diagrams`):
    every branch born at an event of ``kinds`` is followed, recursively, ``depth`` generations
    deep, into the same run."""

    model_config = ConfigDict(extra="forbid")
    #: generations of switched branches (children of children ...)
    depth: Annotated[int, Field(ge=1, le=MAX_DIAGRAM_DEPTH, strict=True)] = 1
    #: the event kinds at which the branch born there is followed
    kinds: Annotated[list[Literal["period_doubling", "branch_point"]], Field(min_length=1),
                     AfterValidator(_unique)] = list(DIAGRAM_KINDS)
    #: at most this many branches in the run (root branches included); the events beyond it
    #: are listed in the tree as not followed
    max_branches: Annotated[int, Field(ge=1, le=1000, strict=True)] = 64
    #: ``continuation.max_points`` of the switched branches (default: the case's)
    max_points: Annotated[int, Field(ge=2, le=MAX_POINTS, strict=True)] | None = None


class AnalysisSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    #: follow the branches born at detected points, recursively (a bifurcation diagram)
    branch_switching: BranchSwitchingSpec | None = None
    #: Floquet multipliers at every admissible point (and the events they locate)
    stability: Bool = True
    #: locate folds, branch points and multiplier crossings
    bifurcations: Bool = True
    #: end a branch where it loses admissibility (at the grazing), instead of
    #: following its phantom (non-physical) part
    stop_on_inadmissible: Bool = False
    #: also compute the multipliers of phantom (inadmissible) orbits
    stability_on_phantom: Bool = False
    #: a multiplier with ``|lambda| > 1 + unit_circle_tol`` counts as outside the unit
    #: circle (raised to ``1e3 eps |DF|`` where the matrix is large)
    unit_circle_tol: PosFloat = 1e-7
    #: location tolerance of events, in arclength
    event_tol: PosFloat = 1e-12
    #: bracket of the bisection on the count of multipliers outside the circle that
    #: detects a crossing (before it is located on the modulus)
    multiplier_event_tol: PosFloat = 1e-9
    #: the largest move of a multiplier near the unit circle in one step
    max_multiplier_step: PosFloat = 0.02


#: the views of ``output.orbits`` (:mod:`nsm_continuation.figures.orbits`): signals against t / T, a
#: phase portrait, a 3-D projection of orbits along the first branch
ORBIT_VIEWS = ("time", "phase", "manifold")
#: the words of ``output.orbits.points`` besides event kinds and numbers
ORBIT_POINT_WORDS = ("first", "last", "events")
#: most points ``output.orbits.points`` may select (one line per point in a figure)
MAX_ORBIT_POINTS = 12
#: most periods drawn per orbit (``output.orbits.periods``, ``Result.orbit``)
MAX_ORBIT_PERIODS = 50
OrbitView = Literal["time", "phase", "manifold"]
Name = Annotated[str, Field(min_length=1, max_length=100, strict=True)]


class OrbitsSpec(BaseModel):
    """``output.orbits``: figures of the periodic orbits at chosen points
    (:mod:`nsm_continuation.figures.orbits`, from :meth:`Presentation.orbit
    <nsm_continuation.core.presentation.Presentation.orbit>`). ``points``: ``first`` / ``last`` (of
    each
    branch), ``events`` (every located event but the branch ends), an event kind (every event
    of that kind) or a number (the point nearest that value of ``continuation.parameter``);
    ``views``: ``time`` (``orbits_time.png``), ``phase`` (``orbits_phase.png``), ``manifold``
    (``manifold.png``: orbits spread along the first branch); ``periods``: periods drawn per
    orbit; ``log``: signals of the time view drawn as ``|value|`` on a log scale;
    ``branches``: the branch ids drawn (default all); ``figures``: a caption per view (e.g.
    the paper figure it reproduces), put in its title."""

    model_config = ConfigDict(extra="forbid")
    #: the points whose orbits are drawn: ``first``, ``last`` (of each branch),
    #: ``events`` (every located event but the branch ends), an event kind, or a number (the
    #: point nearest that value of ``continuation.parameter``)
    points: Annotated[list[Name | Finite], Field(min_length=1, max_length=MAX_ORBIT_POINTS)
                      ] = ["first", "last"]
    #: the figures: ``time`` (``orbits_time.png``, signals against t / T), ``phase``
    #: (``orbits_phase.png``), ``manifold`` (``manifold.png``, orbits spread along the first
    #: branch in 3-D)
    views: Annotated[list[OrbitView], Field(min_length=1), AfterValidator(_unique)] = [
        "time", "phase"]
    #: periods drawn per orbit
    periods: Annotated[int, Field(ge=1, le=MAX_ORBIT_PERIODS, strict=True)] = 1
    #: signals of the time view drawn as ``|value|`` on a log scale
    log: list[Name] = []
    #: the branches (ids, as in ``branch_<id>.csv``) the points and the manifold are taken
    #: from; default every branch (the manifold: the first with points)
    branches: Annotated[list[Annotated[int, Field(ge=0, strict=True)]], Field(min_length=1),
                        AfterValidator(_unique)] | None = None
    #: a caption per view, put in its title (e.g. ``{time: "Fig. 5.2"}``)
    figures: dict[OrbitView, Annotated[str, Field(max_length=200, strict=True)]] = {}


class OutputSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    #: the output folder (default ``runs/<name>``; ``--out`` overrides it)
    dir: Annotated[str, Field(min_length=1, strict=True)] | None = None
    #: draw the figures (the CSVs and reports are always written)
    plots: Bool = True
    #: a progress bar on stderr (the command line draws it on a terminal only)
    progress: Bool = True
    #: an existing output folder holding a previous run: refuse (error), replace the files that
    #: run wrote (overwrite, as ``--overwrite``), or write to a numbered sibling (new)
    if_exists: Literal["error", "overwrite", "new"] = "error"
    #: the quantities (unknowns or derived quantities) on the axes of ``diagram.png``, e.g.
    #: ``[d, q2]`` (default: the problem's diagram axes)
    axes: Annotated[list[Annotated[str, Field(min_length=1, strict=True)]],
                    Field(min_length=2, max_length=2)] | None = None
    #: figures of the periodic orbits at chosen points (default None: none)
    orbits: OrbitsSpec | None = None


#: the protocols of a Dask scheduler's address
SCHEDULER_PROTOCOLS = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def _scheduler_address(value: str) -> str:
    """``value`` if it is a Dask scheduler address this tool can reach: a protocol Dask speaks
    between processes, then ``HOST:PORT`` with a port in 1..65535 and nothing after it (Dask
    itself fails on the others only when it connects, with a traceback); else ValueError."""
    from importlib.util import find_spec
    from urllib.parse import urlsplit

    scheme, sep, rest = value.partition("://")
    if not sep or scheme not in SCHEDULER_PROTOCOLS:
        raise ValueError(f"an address such as tcp://HOST:8786 ({', '.join(SCHEDULER_PROTOCOLS)}"
                         f"), got {value!r}")
    if scheme == "inproc":
        raise ValueError(f"{value!r}: an inproc:// scheduler lives inside one process; give "
                         "the address of a running `dask scheduler` (tcp://HOST:8786)")
    if scheme == "ucx" and find_spec("distributed_ucxx") is None:
        raise ValueError(f"{value!r}: ucx:// needs the distributed-ucxx package, which is not "
                         "installed (or use the scheduler's tcp:// address)")
    try:
        parts = urlsplit(f"//{rest}")
        port = parts.port
    except ValueError:  # a port that is not a number in 0..65535
        port = -1
    if not parts.hostname or parts.username is not None or parts.path or parts.query \
            or parts.fragment or "?" in rest or "#" in rest or any(c.isspace() for c in rest):
        raise ValueError(f"an address such as {scheme}://HOST:8786 (HOST:PORT and nothing "
                         f"else), got {value!r}")
    if port is None:
        raise ValueError(f"{value!r} has no port: write it out, HOST:PORT (a scheduler listens "
                         "on 8786 by default)")
    if not 1 <= port <= 65535:
        raise ValueError(f"{value!r}: the port must be a number in 1..65535 (the scheduler's "
                         "port, 8786 by default)")
    return value


#: local Dask workers per usable core, at most: a worker computes on one core; a few per core
#: still keep the cores busy, more only share them (and each holds its own memory)
WORKERS_PER_CORE = 4
#: available memory each local Dask worker needs, at least (GB): a worker process with NumPy,
#: CasADi and its problem holds 0.2-0.4 GB before its branch's points
WORKER_MEMORY_GB = 0.5


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def available_memory_gb() -> float | None:
    """The memory available to new processes now (GB; Linux ``MemAvailable``, else psutil's
    ``available``), or None when it cannot be measured (then only the cores limit workers)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1024**2
    except (OSError, ValueError, IndexError):
        pass
    try:
        import psutil
    except ImportError:
        return None
    return float(psutil.virtual_memory().available) / 1024**3


def _local_workers(n: int) -> int:
    """``n`` if this machine can run that many local worker processes (:data:`WORKERS_PER_CORE`
    per usable core, :data:`WORKER_MEMORY_GB` of available memory each); else ValueError naming
    both limits: a local cluster of 1000 workers would start spawning before failing."""
    cores, gb = usable_cores(), available_memory_gb()
    by_cores = WORKERS_PER_CORE * cores
    by_memory = by_cores if gb is None else max(1, int(gb / WORKER_MEMORY_GB))
    if n > min(by_cores, by_memory):
        memory = ("available memory unknown" if gb is None else
                  f"{WORKER_MEMORY_GB} GB of the {gb:.1f} GB of available memory each: "
                  f"at most {by_memory}")
        raise ValueError(f"{n} local workers are more than this machine runs: at most "
                         f"{min(by_cores, by_memory)} ({WORKERS_PER_CORE} per usable core, "
                         f"{cores} cores: at most {by_cores}; {memory})")
    return n


class ExecutionSpec(BaseModel):
    """``execution:``: where the branches are computed (:mod:`nsm_continuation.runs.execution`):
    serially in this process (default), on a local cluster of ``workers`` processes, or on
    the Dask cluster at ``scheduler`` (``tcp://HOST:8786``). ``workers`` is bounded by this
    machine (:func:`_local_workers`); ``no_workers_timeout``: seconds without any worker (all
    lost, or none joined an existing cluster) after which the tasks still waiting end their
    branches with that reason instead of waiting forever."""

    model_config = ConfigDict(extra="forbid")
    #: compute the branches on a local Dask cluster of this many worker processes
    #: (at most 4 per usable core and one per 0.5 GB of available memory)
    workers: Annotated[int, Field(ge=1, le=1024, strict=True),
                       AfterValidator(_local_workers)] | None = None
    #: compute the branches on the existing Dask cluster at this address
    #: (``tcp://HOST:8786``); excludes ``workers``
    scheduler: Annotated[str, Field(min_length=1, max_length=1000, strict=True),
                         AfterValidator(_scheduler_address)] | None = None
    #: seconds without any worker after which the tasks still waiting end their
    #: branches with that reason
    no_workers_timeout: Annotated[float, Field(gt=0, le=86_400, allow_inf_nan=False,
                                               strict=True)] = 30.0

    @model_validator(mode="after")
    def _one_cluster(self) -> ExecutionSpec:
        if self.workers is not None and self.scheduler is not None:
            raise ValueError("workers and scheduler exclude each other: a local cluster of "
                             "that many workers, or the existing cluster at that address")
        return self


def with_execution(case: Case, workers: int | None, scheduler: str | None,
                   names: tuple[str, str] = ("workers", "scheduler")) -> Case:
    """``case`` with ``workers`` / ``scheduler`` (command-line flags or API arguments, named
    ``names`` in messages) as its ``execution:`` block, which they replace (so that
    ``report.json`` records where the run was computed); unchanged if both are None.
    :class:`CaseError` naming the argument when they are invalid or given together."""
    if workers is None and scheduler is None:
        return case
    if workers is not None and scheduler is not None:
        raise CaseError(f"{names[0]} and {names[1]} exclude each other: a local cluster of "
                        "that many workers, or the existing cluster at that address")
    try:
        spec = ExecutionSpec(workers=workers, scheduler=scheduler,
                             no_workers_timeout=case.execution.no_workers_timeout)
    except ValidationError as exc:
        err = exc.errors()[0]
        name = names[0] if err["loc"] and err["loc"][0] == "workers" else names[1]
        raise CaseError(f"{name}: {str(err['msg']).removeprefix('Value error, ')}") from None
    return case.model_copy(update={"execution": spec})


class Case(BaseModel):
    model_config = ConfigDict(extra="forbid")
    #: the output folder's name (``runs/<name>``: a plain name, no path) and the
    #: report's title
    name: Annotated[str, Field(strict=True), AfterValidator(_plain_name)] = "case"
    #: free text, copied into the report
    description: Annotated[str, Field(max_length=10_000, strict=True)] = ""
    #: required, except in a restart (``start: {from: <run>}``), which inherits it
    problem: Annotated[str, Field(strict=True), AfterValidator(_visible_name)] | None = None
    #: required, except in a restart, which inherits the run's (these override them)
    parameters: dict[str, Any] | None = None
    #: where branches start: a mapping or a list of mappings of the problem's start
    #: forms (its page of the reference), or a restart from a saved run (``{from: <run>,
    #: ...}``)
    start: Any
    #: the continuation: its parameter, window, steps and algorithm
    continuation: ContinuationSpec = ContinuationSpec()
    #: what is computed at each point and which events are located
    analysis: AnalysisSpec = AnalysisSpec()
    #: where and what the run writes
    output: OutputSpec = OutputSpec()
    #: where the branches are computed (default: serially, in this process)
    execution: ExecutionSpec = ExecutionSpec()
    #: the resolved restart (:class:`nsm_continuation.cases.restart.Restart`) of a ``start: {from:
    #: ...}`` case, set by :func:`validate`
    _restart: Any = PrivateAttr(default=None)

    @property
    def restart(self) -> Any:
        """The resolved restart of a ``start: {from: <run>}`` case (None otherwise)."""
        return self._restart


def _keyed(prefix: str, msg: str) -> str:
    """``prefix: msg`` unless ``msg`` already starts with the prefix (``parameters.e: ...``)."""
    if re.match(rf"^({re.escape(prefix)}|{'|'.join(Case.model_fields)})[.:\[]", msg):
        return msg
    return f"{prefix}: {msg}"


def _script(char: str) -> str:
    """The script of a letter (``LATIN``, ``CYRILLIC``, ``GREEK``, ...) from its Unicode name."""
    return unicodedata.name(char, "?").split(" ")[0]


def show_key(key: Any) -> str:
    """A key as a one-line message shows it: as written when it reads as what it is, else
    quoted with every non-ASCII character escaped (``'ga\\u200bp'``) so that the user sees why
    the key is not the one they meant: a key with an invisible or control character (a
    zero-width space, a bell), with letters of two scripts (a Cyrillic letter that looks like
    a Latin one), with leading or trailing spaces, or empty. A key that is no string (``5``)
    is shown as its Python literal."""
    if not isinstance(key, str):
        return repr(key)
    scripts = {_script(c) for c in key if c.isalpha()}
    odd = not key or key.strip() != key or not key.isprintable() or len(scripts) > 1
    return ascii(key) if odd else key


def _first_error(err: ValidationError) -> dict[str, Any]:
    """The error to report: an unknown key that holds an invisible or look-alike character
    first (``ga\\u200bp`` is the cause of the missing ``gap``), else pydantic's first."""
    errors = err.errors()
    for e in errors:
        if e["type"] == "extra_forbidden" and e["loc"] and isinstance(e["loc"][-1], str) \
                and show_key(e["loc"][-1]) != e["loc"][-1]:
            return dict(e)
    first = errors[0]
    if first["type"].endswith("_type") and len(first["loc"]) > 1:
        # a union (``float | list[float]``) whose first member does not even take the value's
        # type: the member that took it and failed deeper (``stiffness[1]: greater than 0``)
        # says what is wrong, not "should be a valid number"
        n = len(first["loc"]) - 1
        for e in errors[1:]:
            if len(e["loc"]) > n + 1 and e["loc"][:n] == first["loc"][:n]:
                return dict(e)
    return dict(first)


def _format(err: ValidationError, raw: Any, prefix: str = "") -> str:
    """One line from the first pydantic error: the dotted key as the user wrote it (pydantic's
    union tags such as ``constrained-float`` or ``ModeStart`` are dropped by walking ``raw``;
    keys that are not plain names are shown escaped, :func:`show_key`)."""
    e = _first_error(err)
    parts: list[str] = []
    node = raw
    loc = list(e["loc"])
    bad_key: tuple[Any] | None = None  # a mapping key that is not a string
    for i, part in enumerate(loc):
        if part == "[key]" and i > 0 and isinstance(loc[i - 1], int | float | bool | None):
            bad_key = (loc[i - 1],)
            break
        if isinstance(node, dict) and part in node:
            if i + 1 < len(loc) and loc[i + 1] == "[key]" and not isinstance(part, str):
                bad_key = (part,)
                break
            parts.append(show_key(part))
            node = node[part]
        elif isinstance(node, list | tuple) and isinstance(part, int) and part < len(node):
            parts[-1:] = [f"{parts[-1]}[{part}]" if parts else f"[{part}]"]
            node = node[part]
        elif e["type"] == "missing" and i == len(loc) - 1:
            parts.append(show_key(part))
    where = ".".join(([prefix] if prefix else []) + parts)
    msg = e["msg"].removeprefix("Value error, ")
    if bad_key is not None:
        msg = (f"the key {bad_key[0]!r} is not a name (keys are strings; quote it, "
               f"'{bad_key[0]}', if it is meant as one)")
    elif e["type"] == "extra_forbidden":
        msg = "unknown key"
    elif e["type"] == "missing":
        msg = "required key is missing"
    elif e["type"] in ("model_type", "dict_type") and not isinstance(node, dict):
        # pydantic names its model class ("or instance of ContinuationSpec"): the user wrote YAML
        msg = (f"expected a mapping of keys (key: value), got "
               f"{short_text(ascii(node) if isinstance(node, str) else repr(node))}")
    elif e["type"] in ("float_type", "int_type", "bool_type", "string_type") \
            and not isinstance(node, dict | list):
        msg = f"{msg} (got {short_text(ascii(node) if isinstance(node, str) else repr(node))})"
    msg = msg.splitlines()[0] if msg else "invalid value"
    sub = re.match(r"^([a-z_][a-z0-9_]*): ", msg)
    if where and sub:  # a model validator naming one of its own fields
        return f"{where}.{msg}"
    return _keyed(where, msg) if where else f"case: {msg}"


def _reject_nan(obj: Any, where: str) -> None:
    if isinstance(obj, float) and not math.isfinite(obj):
        raise CaseError(f"{where}: {obj} is not a finite number")
    if isinstance(obj, dict):
        for k, v in obj.items():
            _reject_nan(v, f"{where}.{show_key(k)}" if where else show_key(k))
    if isinstance(obj, list):
        for i, v in enumerate(obj):
            _reject_nan(v, f"{where}[{i}]")


class _CaseLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate keys (YAML says they are an error; PyYAML
    keeps the last one silently), lets a key written in a mapping override the same key
    merged into it (``<<: *base``, the merge rule), and marks the numbers YAML 1.1 reads
    differently from YAML 1.2 (:class:`_Yaml11Number`)."""


#: the tag of a merge key ``<<``
MERGE_TAG = "tag:yaml.org,2002:merge"


def _mapping_without_duplicates(loader: _CaseLoader, node: yaml.MappingNode,
                                deep: bool = False) -> dict[Any, Any]:
    """A mapping whose keys, as written in it, are unique; the mappings merged in by ``<<``
    then fill in the keys it does not write (a written key overrides a merged one)."""
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = (MERGE_TAG if key_node.tag == MERGE_TAG
               else loader.construct_object(key_node, deep=deep))
        try:
            duplicate = key in seen
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, f"unhashable key {key!r}", key_node.start_mark) from None
        if duplicate:
            shown = "<<" if key == MERGE_TAG else show_key(key)
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {shown}", key_node.start_mark)
        seen.add(key)
    # the merged pairs go first, so the mapping's own value of a key is the one kept
    loader.flatten_mapping(node)
    return loader.construct_mapping(node, deep=deep)


_CaseLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                            _mapping_without_duplicates)
# YAML 1.2 floats: PyYAML (YAML 1.1) reads ``1e-9`` and ``1.0e3`` as strings
_CaseLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |[-+]?\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


class _Yaml11Number(str):
    """A plain scalar that would be read as another number than the one written: one YAML 1.1
    reads as a number and YAML 1.2 does not (or as another one), ``010`` (octal 8 in 1.1, 10
    in 1.2) or ``1:00`` (base 60: 60 in 1.1, a string in 1.2); or a float beyond double
    precision, ``1e-400`` (0) or ``1e400`` (infinity). Kept as its text; :func:`parse_yaml`
    refuses it, naming its key and quoting it."""

    #: ``octal``, ``base-60``, ``underflow`` or ``overflow``
    form: str
    #: the value it would be read as
    value: float | int


#: an octal integer of YAML 1.1 (a leading zero); ``0`` alone is zero in both versions
OCTAL = re.compile(r"^[-+]?0[0-7_]+$")


#: the mantissa of a float literal with a nonzero digit (``1e-400``, not ``0.0e5``)
NONZERO_FLOAT = re.compile(r"^[-+]?[0-9_]*\.?[0-9_]*[1-9]")
#: ``.inf``, ``-.inf``, ``.nan`` (written as such: refused later as not finite)
SPECIAL_FLOAT = re.compile(r"^[-+]?\.(?:inf|Inf|INF|nan|NaN|NAN)$")


def _number(loader: _CaseLoader, node: yaml.ScalarNode, build: Any) -> Any:
    text = loader.construct_scalar(node)
    if not isinstance(text, str):
        return build(loader, node)
    form = "base-60" if ":" in text else "octal" if OCTAL.match(text) else None
    value = build(loader, node)
    if form is None and isinstance(value, float) and not SPECIAL_FLOAT.match(text):
        if value == 0.0 and NONZERO_FLOAT.match(re.split("[eE]", text)[0]):
            form = "underflow"
        elif math.isinf(value):
            form = "overflow"
    if form is None:
        return value
    out = _Yaml11Number(text)
    out.form, out.value = form, value
    return out


_CaseLoader.add_constructor(
    "tag:yaml.org,2002:int",
    lambda loader, node: _number(loader, node, yaml.constructor.SafeConstructor.construct_yaml_int))
_CaseLoader.add_constructor(
    "tag:yaml.org,2002:float",
    lambda loader, node: _number(loader, node,
                                 yaml.constructor.SafeConstructor.construct_yaml_float))


def _first_yaml11(obj: Any, path: str = "") -> tuple[str, _Yaml11Number, bool] | None:
    """The first :class:`_Yaml11Number` in ``obj``: the dotted path of its key, the number, and
    whether it is itself a key (of the mapping at that path); None if there is none."""
    if isinstance(obj, _Yaml11Number):
        return path, obj, False
    if isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(k, _Yaml11Number):
                return path, k, True
            found = _first_yaml11(v, f"{path}.{show_key(k)}" if path else show_key(k))
            if found is not None:
                return found
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            found = _first_yaml11(v, f"{path}[{i}]")
            if found is not None:
                return found
    return None


def _refuse_yaml11(obj: Any, where: str) -> None:
    """:class:`CaseError` naming the key of the first :class:`_Yaml11Number` in ``obj`` (or
    ``where`` for a document that is one): the value as written, what YAML 1.1 reads and how
    to write what is meant."""
    found = _first_yaml11(obj)
    if found is None:
        return
    key, num, is_key = found
    text = str(num)
    if num.form in ("underflow", "overflow"):
        limit = "smallest" if num.form == "underflow" else "largest"
        why = (f"is beyond the {limit} number double precision holds (it would be read as "
               f"{num.value}); rescale the problem")
        raise CaseError(f"{key or where}: {text!r} {why}")
    if num.form == "octal":
        sign = "-" if text.startswith("-") else ""
        decimal = sign + (text.replace("_", "").lstrip("+-").lstrip("0") or "0")
        write = decimal if str(num.value) == decimal else f"{decimal} (or {num.value})"
        why = (f"is an octal number in YAML 1.1 (read as {num.value}) and {decimal} in YAML "
               f"1.2; write {write} without the leading zero")
    else:
        why = (f"is a base-60 number in YAML 1.1 (read as {num.value}) and a string in YAML "
               f"1.2; write {num.value} for that number")
    shown = f"the key {text!r}" if is_key else repr(text)
    raise CaseError(f"{key or where}: {shown} {why}, or quote it for a string")


def _check_size(obj: Any, where: str) -> None:
    """Refuse a document that expands to more than :data:`MAX_CASE_NODES` values (a YAML
    alias bomb is a few hundred bytes and billions of values once expanded)."""
    stack, count = [obj], 0
    while stack:
        node = stack.pop()
        count += 1
        if count > MAX_CASE_NODES:
            raise CaseError(f"{where}: expands to more than {MAX_CASE_NODES} values (YAML "
                            "aliases?); a case is a few dozen keys")
        if isinstance(node, dict):
            stack.extend(node.keys())
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)


def parse_yaml(text: str, where: str) -> Any:
    """YAML text -> Python objects, with duplicate keys and oversized documents refused."""
    try:
        data = yaml.load(text, Loader=_CaseLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None)
        why = f": {problem}" if problem else ""
        raise CaseError(f"{where}: not valid YAML{at}{why}") from None
    except RecursionError:
        raise CaseError(f"{where}: nested too deeply") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise CaseError(f"{where}: {str(exc).splitlines()[0]}") from None
    _check_size(data, where)
    _refuse_yaml11(data, where)
    return data


def apply_overrides(raw: dict[str, Any], overrides: list[str],
                    source: str = "--set") -> dict[str, Any]:
    """Apply ``dotted.key=value`` overrides (values parsed as YAML); errors name ``source``
    (``--set`` on the command line, ``overrides:`` in the Python API)."""
    out = copy.deepcopy(raw)
    for item in overrides:
        if not isinstance(item, str):
            raise CaseError(f"{source} {short_text(repr(item))}: expected a 'dotted.key=value' "
                            "string")
        if "=" not in item:
            raise CaseError(f"{source} {short_text(repr(item))}: expected dotted.key=value")
        key, value = item.split("=", 1)
        if not all(key.strip().split(".")):
            raise CaseError(f"{source} {short_text(repr(item))}: empty key")
        set_dotted(out, key.strip(), parse_yaml(value, f"{source} {key}"), source)
    return out


def set_dotted(raw: dict[str, Any], key: str, value: Any, source: str) -> None:
    """``raw[a][b][c] = value`` for the dotted ``key`` ``a.b.c`` (mappings created on the
    way); a part that is no mapping, or a list index (``start[0]``), is refused naming
    ``source``."""
    parts = key.split(".")
    at = next((i for i, p in enumerate(parts) if re.search(r"\[-?\d*\]$", p)), None)
    if at is not None:
        whole = short_text(".".join([*parts[:at], parts[at].split("[")[0]]))
        example = f"--set '{whole}=[...]'" if source == "--set" else f"{{'{whole}': [...]}}"
        raise CaseError(f"{source} {short_text(key)}: {short_text(parts[at])} indexes a list, "
                        f"which a dotted key cannot; set the whole list instead, e.g. {example}")
    node = raw
    for p in parts[:-1]:
        if not isinstance(node.get(p, {}), dict):
            raise CaseError(f"{source} {key}: {p} is not a mapping")
        node = node.setdefault(p, {})
    node[parts[-1]] = value


def load_raw(path: str | Path) -> dict[str, Any]:
    """The case file as a mapping; every problem with the file is one :class:`CaseError`.
    ``path`` may name a bundled case (:func:`nsm_continuation.cases.bundled.resolve`: an
    existing path wins)."""
    from nsm_continuation.cases.bundled import resolve

    shown = short_text(str(path))
    try:
        p = resolve(path)  # an existing path, else a bundled case of that name
        if p.is_dir():
            raise CaseError(f"case file: {shown} is a directory, not a YAML file")
        mode = p.stat().st_mode
        if stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode):  # reading would block
            raise CaseError(f"case file: {shown} is a pipe or socket, not a YAML file")
        with open(p, "rb") as fh:
            data = fh.read(MAX_CASE_BYTES + 1)
    except (OSError, ValueError) as exc:
        if isinstance(exc, CaseError):
            raise
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise CaseError(f"case file: cannot read {shown} ({why})") from None
    if len(data) > MAX_CASE_BYTES:
        raise CaseError(f"case file: {shown} is larger than {MAX_CASE_BYTES // 1000} kB; a case "
                        "is a short YAML file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError(f"case file: {shown} is not UTF-8 text (byte {exc.start})") from None
    if not text.strip():
        raise CaseError(f"case file: {shown} is empty")
    raw = parse_yaml(text, f"case file {shown}")
    if not isinstance(raw, dict):
        raise CaseError(f"case file: {shown} must contain a mapping of keys")
    bad = [k for k in raw if not isinstance(k, str)]
    if bad:
        raise CaseError(f"case file: key {bad[0]!r} is not a name")
    return raw


