"""Fuzz suite of the command line.

Hypothesis mutates one small, fast case per problem (deleted keys, unknown keys, values of the
wrong type or out of range, path-like names, other problems, other problems' start blocks) and
generates ``parameters`` / ``start`` / ``continuation`` / ``analysis`` blocks from the pydantic
schemas; every case goes through ``validate`` and ``run`` in-process and must keep the contract
of the command line:

* exit status 0 (every start gave a branch), 3 (report written, some start failed) or 2 (bad
  input); never 1 (a bug) and never a Python traceback;
* on 2: exactly one line on stderr, ``error: <key>: ...``, and nothing written (no output
  folder, no hidden ``.<name>.tmp-*`` or lock left next to it);
* ``validate`` and ``run`` agree: validate 2 -> run 2 with the same message; validate 0 -> run 0
  or 3;
* every call returns within :data:`CALL_BOUND_S`.

A few fixed fault tests (file-level and output-location faults) and a few subprocess calls
(the real process: no traceback reaches the terminal) complete it. Everything is derandomized
(reproducible in CI) and shrinking is off, so a failing input costs at most two calls.
"""

from __future__ import annotations

import copy
import math
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from helpers import CASES
from hypothesis import HealthCheck, Phase, given, note, settings
from hypothesis import strategies as st

from nsm_continuation import cli
from nsm_continuation.cases import registry

TRACEBACK = "Traceback (most recent call last)"
#: wall-clock bound of one in-process call of the command line
CALL_BOUND_S = 20.0
#: a bad-input file (alias bomb, FIFO, /dev/zero, ...) must be refused within this
REFUSE_BOUND_S = 5.0
#: every base case runs in ~0.02-1 s on a 2-core machine; this is the assertion's margin
BASE_RUN_BOUND_S = 5.0

# --------------------------------------------------------------------------- base cases
#: continuation.max_points: 3, no plots, no progress bar: every run is a fraction of a second
TINY = {"continuation": {"max_points": 3}, "output": {"plots": False, "progress": False}}
#: problem -> (bundled case it is made from, overrides making it small)
BASE_SOURCES: dict[str, tuple[str, dict[str, Any]]] = {
    "ndof_impact": ("ndof_default.yaml", {}),
    "wfem_bar": ("wfem_fig5_6_backbones_gap_positive.yaml",
                 {"parameters": {"cells": 40}, "start": [{"branch": "main", "mode": 1}]}),
    "bar_continuum": ("bar_continuum_main.yaml", {}),
    "wfem_forced_bar": ("wfem_fig20_force_positive_gap.yaml",
                        {"parameters": {"cells": 20, "damping_ratio": 0.1}}),
    "bouncing_ball": ("ball_fig1_fig4_chatter.yaml", {}),
    "impact_oscillator": ("impact_oscillator_fig2_sticking.yaml", {"start": {"transient": 5}}),
    "two_mass_chain": ("chain_two_mass_wall.yaml", {"start": {"transient": 10}}),
    "double_pendulum": ("pendulum_sec6_1_complete_to_incomplete.yaml",
                        {"continuation": {"max_points": 2}}),
    "two_sided_oscillator": ("two_sided_oscillator.yaml", {}),
    "impact_damper": ("impact_damper.yaml", {}),
    "ndof_impact_hybrid": ("ndof_hybrid_branch1.yaml", {"continuation": {"max_points": 2}}),
    "ndof_two_walls": ("ndof_two_walls_modes.yaml",
                       {"start": [{"omega": 1.45}], "continuation": {"max_points": 2}}),
}
#: problems whose runs are cheap enough to fuzz ``run`` as well as ``validate`` with
#: schema-generated parameters (the hybrid ones simulate a transient of random systems)
SCHEMA_RUN = {"ndof_impact", "wfem_bar", "bar_continuum"}
#: hypothesis examples per problem for the mutation fuzz (validate + run)
MUTATION_EXAMPLES = {"ndof_impact": 60, "wfem_bar": 50, "bar_continuum": 50, "bouncing_ball": 30,
                     "impact_oscillator": 25, "two_mass_chain": 25, "double_pendulum": 20,
                     "wfem_forced_bar": 15, "two_sided_oscillator": 15, "impact_damper": 15,
                     "ndof_impact_hybrid": 15, "ndof_two_walls": 10}
SCHEMA_EXAMPLES = {"ndof_impact": 30, "wfem_bar": 30, "bar_continuum": 30}
SCHEMA_EXAMPLES_VALIDATE_ONLY = 15
#: parameters that set the size of a problem: kept from the base when a schema-generated
#: parameters block leaves them out
SIZE_KEYS = {"cells"}
#: mutated cases asking for more points than this are only validated (a long run is no bug)
RUN_MAX_POINTS = 10
#: derandomized (reproducible in CI), no shrinking (a failing input costs two calls, not a
#: search; the inputs are single mutations of a small case anyway)
FUZZ = settings(deadline=None, derandomize=True, database=None, print_blob=False,
                phases=[Phase.explicit, Phase.generate],
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large, HealthCheck.filter_too_much])


def _merge(a: dict, b: dict) -> dict:
    for k, v in b.items():
        if isinstance(v, dict) and isinstance(a.get(k), dict):
            _merge(a[k], v)
        else:
            a[k] = copy.deepcopy(v)
    return a


NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _numbers(obj: Any) -> Any:
    """PyYAML (YAML 1.1) reads ``1.0e3`` as a string; the bundled cases mean a number."""
    if isinstance(obj, dict):
        return {k: _numbers(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_numbers(v) for v in obj]
    if isinstance(obj, str) and NUMBER.match(obj):
        return float(obj)
    return obj


def base_case(problem: str) -> dict[str, Any]:
    """The small base case of ``problem`` (a fresh copy)."""
    source, overrides = BASE_SOURCES[problem]
    case = _numbers(yaml.safe_load((CASES / source).read_text()))
    _merge(case, TINY)
    _merge(case, overrides)
    case["output"].pop("dir", None)
    # the bundled bounds name problem monitors; keep the bases independent of them
    case["continuation"].pop("bounds", None)
    case["name"] = f"fuzz_{problem}"
    return case


PROBLEMS = sorted(BASE_SOURCES)

# --------------------------------------------------------------------------- calling the CLI


class _CallTimeout(BaseException):
    """Raised by SIGALRM inside the command line (not an ``Exception``: nothing swallows it)."""


_TIMER = {"fired": False}


def _alarm(signum: int, frame: object) -> None:
    # remembered: an extension module may turn the exception into another one (CasADi makes it
    # a SystemError); the timer repeats every second until the call has unwound
    _TIMER["fired"] = True
    raise _CallTimeout()


@dataclass
class Call:
    argv: list[str]
    rc: int | None  # None: did not return within the bound
    out: str
    err: str
    seconds: float

    def show(self) -> str:
        return (f"argv={self.argv}\nexit={self.rc} after {self.seconds:.2f} s\n"
                f"--- stderr ---\n{self.err}--- stdout ---\n{self.out[-2000:]}")


def _cli_warning_filters() -> None:
    """The filters of a plain ``python`` process (what a user's terminal shows)."""
    warnings.resetwarnings()
    warnings.simplefilter("default")
    for cat in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
        warnings.simplefilter("ignore", cat)


def run_cli(argv: list[str], capsys: Any, bound: float = CALL_BOUND_S,
            cwd: Path | None = None) -> Call:
    """``cli.main(argv)`` in-process, as the console script would run it: SystemExit is an exit
    status, an escaping exception is status 1 with its traceback on stderr, Python warnings are
    appended to stderr as the interpreter would print them, and a SIGALRM timer bounds the
    call."""
    argv = [str(a) for a in argv]
    capsys.readouterr()
    here = os.getcwd()
    extra = ""
    rc: int | None
    old = signal.signal(signal.SIGALRM, _alarm)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as rec:
            _cli_warning_filters()
            try:
                if cwd is not None:
                    os.chdir(cwd)
                _TIMER["fired"] = False
                signal.setitimer(signal.ITIMER_REAL, bound, 1.0)
                try:
                    rc = cli.main(argv)
                finally:
                    signal.setitimer(signal.ITIMER_REAL, 0)
            except SystemExit as exc:
                if exc.code is None or isinstance(exc.code, int):
                    rc = exc.code or 0
                else:
                    extra, rc = f"{exc.code}\n", 1
            except _CallTimeout:
                rc = None
            except Exception:
                extra, rc = traceback.format_exc(), 1
        shown = "".join(warnings.formatwarning(w.message, w.category, w.filename, w.lineno,
                                               w.line) for w in rec)
    except _CallTimeout:  # fired again while unwinding
        rc, shown = None, ""
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        os.chdir(here)
    if _TIMER["fired"]:
        rc = None
    seconds = time.perf_counter() - t0
    cap = capsys.readouterr()
    return Call(argv, rc, cap.out, cap.err + extra + shown, seconds)


def run_process(argv: list[str], cwd: Path, timeout: float = 60.0) -> Call:
    """The command line as a real process (``python -m nsm_continuation.cli``)."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "nsm_continuation.cli", *map(str, argv)],
                       capture_output=True, text=True, cwd=cwd, timeout=timeout,
                       stdin=subprocess.DEVNULL)
    return Call([str(a) for a in argv], r.returncode, r.stdout, r.stderr,
                time.perf_counter() - t0)


# --------------------------------------------------------------------------- assertions

#: ``error: <where>: <what>`` where <where> names a key (dotted, with [i]), the case file, an
#: option or the output location
ERROR_LINE = re.compile(r"^error: (?P<where>[^:\n]*\S[^:\n]*): \S")


def assert_sane(c: Call, allowed: tuple[int, ...]) -> None:
    assert c.rc is not None, f"no answer within {CALL_BOUND_S} s\n{c.show()}"
    assert TRACEBACK not in c.err and TRACEBACK not in c.out, c.show()
    assert c.rc in allowed, f"exit status {c.rc} not in {allowed}\n{c.show()}"


def assert_one_error_line(c: Call) -> str:
    """Exit 2's stderr: exactly one line, ``error: <key>: ...``; returns it."""
    lines = c.err.splitlines()
    assert len(lines) == 1, f"exit 2 needs exactly one line on stderr\n{c.show()}"
    assert ERROR_LINE.match(lines[0]), f"not 'error: <key>: ...'\n{c.show()}"
    return lines[0]


def tree(d: Path) -> list[str]:
    """Every entry under ``d`` (relative), hidden ones included."""
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


#: what an interrupted or failed write may leave: ``.<name>.tmp-*``, ``.<name>.lock``,
#: ``.<name>.old-*``
LEFTOVER = re.compile(r"(^|/)\.[^/]+\.(tmp-[^/]*|lock|old-[^/]*)$")


def leftovers(d: Path) -> list[str]:
    return [p for p in tree(d) if LEFTOVER.search(p)]


class _Dumper(yaml.SafeDumper):
    """Quotes every string that is not a plain word: PyYAML (YAML 1.1) writes ``1e-3`` bare,
    which a YAML 1.2 reader takes for a number; a string must stay a string."""


def _str(dumper: yaml.SafeDumper, s: str) -> yaml.ScalarNode:
    plain = re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", s) and s.lower() not in {
        "true", "false", "yes", "no", "on", "off", "null", "y", "n"}
    return dumper.represent_scalar("tag:yaml.org,2002:str", s, style=None if plain else "'")


_Dumper.add_representer(str, _str)


def dump(case: dict) -> str:
    return yaml.dump(case, Dumper=_Dumper, sort_keys=False, allow_unicode=True)


def write_case(d: Path, case: dict | str, name: str = "case.yaml") -> Path:
    p = d / name
    p.write_text(case if isinstance(case, str) else dump(case))
    return p


def names(line: str, key: str) -> bool:
    """Whether an error line names ``key``: the dotted key (``start.[0]`` and ``start[0]`` are
    both taken as the first start), or a parent of it followed by its last name, as in
    ``error: start.guess: unknown state 'zz'``."""
    line = line.replace(".[", "[")
    if key in line:
        return True
    m = ERROR_LINE.match(line.strip())
    last = re.split(r"[.\[\]]", key.rstrip("]"))[-1]
    return bool(m and key.startswith(m["where"]) and last and last in line[m.end("where"):])


def _note(text: str) -> None:
    try:
        note(text)
    except Exception:  # not inside a hypothesis test
        pass


def check_contract(case: dict | str, capsys: Any, *, run: bool = True, out: bool = True,
                   quiet: bool = True, extra: tuple[str, ...] = (), expect: str | None = None,
                   output_errors_allowed: bool = False) -> tuple[Call, Call | None]:
    """Validate, then run, one case in a fresh sandbox and check the contract of the module
    docstring. ``expect``: the case must be refused with a message containing it.
    ``out=False`` runs without ``--out`` (the case's own output.dir or runs/<name>, in the
    sandbox's working directory ``box/a/work``)."""
    box = Path(tempfile.mkdtemp(prefix="fuzz-"))
    try:
        work = box / "a" / "work"
        work.mkdir(parents=True)
        path = write_case(work, case)
        text = path.read_text(errors="replace")
        _note(f"case.yaml:\n{text}")
        before = tree(box)
        v = run_cli(["validate", path, *extra], capsys, cwd=work)
        _note(f"validate: {v.rc} {v.err!r}")
        assert_sane(v, (0, 2))
        assert tree(box) == before, f"validate wrote something\n{v.show()}"
        if v.rc == 2:
            assert_one_error_line(v)
        if expect is not None:
            assert v.rc == 2, f"must be refused (naming {expect!r})\n{v.show()}"
            assert names(v.err, expect), f"the message must name {expect!r}\n{v.show()}"
        if not run:
            return v, None
        target = work / "out"
        argv = ["run", path, *extra, *(["--out", target] if out else []),
                *(["--quiet"] if quiet else [])]
        r = run_cli(argv, capsys, cwd=work)
        _note(f"run: {r.rc} {r.err!r}")
        assert_sane(r, (0, 2, 3))
        if r.rc == 2:
            line = assert_one_error_line(r)
            assert tree(box) == before, f"exit 2 but something was written\n{r.show()}"
            if v.rc == 2:
                assert r.err == v.err, f"validate and run disagree\n{v.show()}\n{r.show()}"
            else:
                where = ERROR_LINE.match(line)
                assert output_errors_allowed and where and \
                    where["where"].startswith("output"), \
                    f"validate said 0, run said 2\n{v.show()}\n{r.show()}"
        else:
            assert v.rc == 0, f"validate said 2, run said {r.rc}\n{v.show()}\n{r.show()}"
            if out:
                assert (target / "report.json").is_file(), f"no report.json\n{r.show()}"
            assert not leftovers(box), f"left behind: {leftovers(box)}\n{r.show()}"
        return v, r
    finally:
        shutil.rmtree(box, ignore_errors=True)


# --------------------------------------------------------------------------- mutations


def _paths(obj: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path of a nested dict / list (dict keys and list indices)."""
    out: list[tuple] = []
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) \
        if isinstance(obj, list) else ()
    for k, v in items:
        out.append((*prefix, k))
        out.extend(_paths(v, (*prefix, k)))
    return out


def _get(obj: Any, path: tuple) -> Any:
    for k in path:
        obj = obj[k]
    return obj


def dotted(path: tuple) -> str:
    """The key as the error message names it: ``a.b[0].c``."""
    s = ""
    for k in path:
        s += f"[{k}]" if isinstance(k, int) and not isinstance(k, bool) else \
            (f".{k}" if s else str(k))
    return s


def _kind(x: Any) -> str:
    if isinstance(x, bool):
        return "bool"
    if isinstance(x, int | float):
        return "number"
    if isinstance(x, str):
        return "str"
    if isinstance(x, list):
        return "list"
    if isinstance(x, dict):
        return "dict"
    return "null"


#: replacing a scalar of the first kind by one of these kinds is never valid (a number may be a
#: list: chain masses and stiffnesses are scalars or lists)
WRONG_KINDS = {"number": {"bool", "str", "dict"}, "bool": {"number", "str", "list", "dict"},
               "str": {"number", "bool", "list", "dict"}, "dict": {"number", "bool", "str"},
               "list": {"number", "bool", "str"}}
ODD_VALUES = ["", "x", "1.0", "true", ".nan", "../x", "/abs", True, False, None, [], [1, 2],
              ["a"], {}, {"a": 1}, 0, -1, 0.0, -0.0, 10**12, -(10**12), 2**64, 1e308, -1e308,
              1e-300, -1e-300, float("nan"), float("inf"), float("-inf")]
VALUES = st.one_of(
    st.sampled_from(ODD_VALUES),
    st.integers(-3, 60),
    st.floats(),
    st.text(max_size=6),
    st.lists(st.integers(-2, 5), max_size=3),
    st.dictionaries(st.sampled_from(["a", "mode", "n", "T"]), st.integers(0, 3), max_size=2),
)
UNKNOWN_KEYS = st.one_of(
    st.sampled_from(["zz_fuzz", "Name", "max-points", "zz.dot", "zz fuzz", "zz_ünï"]),
    st.from_regex(r"zz_[a-z0-9_]{0,6}", fullmatch=True),
    st.integers(-2, 2),
    st.booleans(),
    st.none(),
)
#: names that are paths, not folder names (and one too long for any file system)
PATH_NAMES = ["../x", "/abs", ".", "..", "", "a/b", "runs/../../x", "./x", "x/", "a\x00b",
              "x" * 300]
BAD_PROBLEMS = ["", "pendulum", "NDOF_IMPACT", "ndof_impact ", "../ndof_impact", "os:system"]


def mutations(problem: str) -> st.SearchStrategy:
    """(kind, path, value) on the base case of ``problem``."""
    base = base_case(problem)
    paths = _paths(base)
    dict_paths = [(), *[p for p in paths if isinstance(_get(base, p), dict)]]
    other_starts = [base_case(q)["start"] for q in PROBLEMS if q != problem]
    others = [q for q in registry.available() if q != problem]
    return st.one_of(
        st.tuples(st.just("delete"), st.sampled_from(paths), st.none()),
        st.tuples(st.just("unknown"), st.sampled_from(dict_paths), st.tuples(UNKNOWN_KEYS,
                                                                             VALUES)),
        st.tuples(st.just("replace"), st.sampled_from(paths), VALUES),
        st.tuples(st.just("name"), st.just(("name",)), st.sampled_from(PATH_NAMES)),
        st.tuples(st.just("problem"), st.just(("problem",)),
                  st.sampled_from(BAD_PROBLEMS + others)),
        st.tuples(st.just("start"), st.just(("start",)), st.sampled_from(other_starts)),
    )


def apply(base: dict, mutation: tuple) -> dict:
    kind, path, value = mutation
    case = copy.deepcopy(base)
    if kind == "delete":
        del _get(case, path[:-1])[path[-1]]
    elif kind == "unknown":
        key, val = value
        _get(case, path)[key] = copy.deepcopy(val)
    else:
        _get(case, path[:-1])[path[-1]] = copy.deepcopy(value)
    return case


def expected_refusal(base: dict, mutation: tuple) -> str | None:
    """The key an error must name if this mutation can never give a valid case (None when it
    may be valid). ``""``: must be refused, any key."""
    kind, path, value = mutation
    if kind == "unknown":
        key = value[0]
        return dotted((*path, key)) if isinstance(key, str) and key else ""
    if kind == "name":
        return "name"
    if kind == "problem" and value not in registry.available():
        return "problem"
    if kind == "delete" and path in {("problem",), ("parameters",), ("start",)}:
        return path[0]
    if kind == "replace":
        if isinstance(value, float) and not math.isfinite(value):
            return dotted(path)
        old = _get(base, path)
        if _kind(value) in WRONG_KINDS.get(_kind(old), set()):
            return dotted(path)
    return None


@pytest.mark.parametrize("problem", PROBLEMS)
def test_fuzz_mutations(problem: str, capsys: Any) -> None:
    """One mutation of the base case: the contract holds, and a mutation that can never be
    valid (unknown key, wrong type, NaN/inf, path as name, unknown problem, missing required
    key) is refused with a message naming the key."""
    base = base_case(problem)

    @settings(FUZZ, max_examples=MUTATION_EXAMPLES[problem])
    @given(mutation=mutations(problem), quiet=st.booleans())
    def inner(mutation: tuple, quiet: bool) -> None:
        case = apply(base, mutation)
        # a path as name: without --out the name is the output folder, so run without --out
        # (in the sandbox) unless it is absolute
        name = case.get("name")
        no_out = mutation[0] == "name" and isinstance(name, str) and not name.startswith("/")
        cont = case.get("continuation", {})
        points = cont.get("max_points", 400) if isinstance(cont, dict) else 3
        run = not (isinstance(points, int) and points > RUN_MAX_POINTS)
        check_contract(case, capsys, run=run, out=not no_out, quiet=quiet,
                       expect=expected_refusal(base, mutation))

    inner()


# --------------------------------------------------------------------------- schema cases


def from_schema(schema: dict, defs: dict) -> st.SearchStrategy:
    """Values valid for a (pydantic) JSON schema, with small sizes: integers at most 8 above
    their minimum, unbounded numbers in [-10, 10], arrays of at most 3 items."""
    if "$ref" in schema:
        return from_schema(defs[schema["$ref"].split("/")[-1]], defs)
    if "const" in schema:
        return st.just(schema["const"])
    if "enum" in schema:
        return st.sampled_from(schema["enum"])
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return st.one_of([from_schema(s, defs) for s in schema[key]])
    t = schema.get("type")
    if t == "null":
        return st.none()
    if t == "boolean":
        return st.booleans()
    if t == "integer":
        lo = schema.get("minimum", schema.get("exclusiveMinimum", -4) + 1)
        hi = schema.get("maximum", schema.get("exclusiveMaximum", 10**9) - 1)
        return st.integers(lo, max(lo, min(hi, lo + 8)))
    if t == "number":
        lo = schema.get("minimum", schema.get("exclusiveMinimum"))
        hi = schema.get("maximum", schema.get("exclusiveMaximum"))
        if lo is None and hi is None:
            lo, hi = -10.0, 10.0
        elif hi is None:
            hi = lo + 10.0
        elif lo is None:
            lo = hi - 10.0
        return st.floats(lo, hi, exclude_min="exclusiveMinimum" in schema,
                         exclude_max="exclusiveMaximum" in schema)
    if t == "string":
        return st.text(min_size=schema.get("minLength", 0), max_size=6)
    if t == "array":
        if "prefixItems" in schema:
            return st.tuples(*[from_schema(s, defs) for s in schema["prefixItems"]]).map(list)
        lo = schema.get("minItems", 0)
        hi = min(schema.get("maxItems", lo + 3), lo + 3)
        return st.lists(from_schema(schema.get("items", {}), defs), min_size=lo, max_size=hi)
    if t == "object" or "properties" in schema:
        props = schema.get("properties", {})
        required = set(schema.get("required", []))
        fixed = st.fixed_dictionaries(
            {k: from_schema(v, defs) for k, v in props.items() if k in required},
            optional={k: from_schema(v, defs) for k, v in props.items() if k not in required})
        extra = schema.get("additionalProperties")
        if isinstance(extra, dict) and not props:
            return st.dictionaries(st.text(min_size=1, max_size=4), from_schema(extra, defs),
                                   max_size=2)
        return fixed
    return st.sampled_from([None, 1, 0.5, "x", [1], {"a": 1}])  # "any"


def _schema_of(model_or_adapter: Any) -> st.SearchStrategy:
    schema = (model_or_adapter.json_schema() if hasattr(model_or_adapter, "json_schema")
              else model_or_adapter.model_json_schema())
    return from_schema(schema, schema.get("$defs", {}))


def schema_cases(problem: str) -> st.SearchStrategy:
    """The base case with parameters, start, and some continuation / analysis keys drawn from
    the schemas (parameter and window kept from the base, so many cases are valid)."""
    cls = registry.get(problem)
    base = base_case(problem)
    params = _schema_of(cls.Parameters)
    adapter = getattr(cls, "start_adapter", None)
    start = _schema_of(adapter) if adapter is not None else st.just(base["start"])
    from nsm_continuation import cases

    defs = cases.Case.model_json_schema()["$defs"]
    cont = from_schema(defs["ContinuationSpec"], defs)
    analysis = from_schema(defs["AnalysisSpec"], defs)

    def build(p: dict, s: Any, c: dict, a: dict, keep: tuple[bool, bool, bool, bool]) -> dict:
        case = copy.deepcopy(base)
        if keep[0]:
            # a size left to its default (cells: 200) makes a lattice scan take ~30 s: no bug
            for key in SIZE_KEYS & set(base["parameters"]):
                p.setdefault(key, base["parameters"][key])
            case["parameters"] = p
        if keep[1]:
            case["start"] = s
        if keep[2]:
            c = {k: v for k, v in c.items() if k not in ("parameter", "min", "max", "bounds")}
            c.setdefault("max_points", 3)
            case["continuation"].update(c)
        if keep[3]:
            case["analysis"] = a
        return case

    return st.builds(build, params, start, cont, analysis,
                     st.tuples(st.booleans(), st.booleans(), st.booleans(), st.booleans()))


@pytest.mark.parametrize("problem", PROBLEMS)
def test_fuzz_schema_cases(problem: str, capsys: Any) -> None:
    """Cases generated from the schemas: the contract holds (run too for the cheap
    problems)."""
    run = problem in SCHEMA_RUN

    @settings(FUZZ, max_examples=SCHEMA_EXAMPLES.get(problem, SCHEMA_EXAMPLES_VALIDATE_ONLY))
    @given(case=schema_cases(problem))
    def inner(case: dict) -> None:
        check_contract(case, capsys, run=run)

    inner()


# --------------------------------------------------------------------------- --set overrides

SET_KEYS = st.one_of(
    st.sampled_from([dotted(p) for p in _paths(base_case("ndof_impact"))
                     if not any(isinstance(k, int) for k in p)]),
    st.sampled_from(["", ".", "a..b", "parameters.", ".name", "zz_fuzz", "parameters.zz",
                     "name.x", "continuation.step.min.x", "start.0", "output.dir"]),
    st.from_regex(r"[a-z_.]{1,12}", fullmatch=True),
)
SET_VALUES = st.one_of(
    st.sampled_from(["", "1", "-1", "0", "true", "null", ".nan", ".inf", "[1, 2]", "{a: 1}",
                     "{", "[", "'", "&a [*a]", "!!python/object:os.system x", "1e308",
                     "1000000000000", "../x", "a: b: c", "- x"]),
    st.text(max_size=8),
)


def test_fuzz_set_overrides(capsys: Any) -> None:
    """``--set KEY=VALUE`` with odd keys and values: the contract holds for validate and
    run."""
    base = base_case("ndof_impact")

    @settings(FUZZ, max_examples=60)
    @given(key=SET_KEYS, value=SET_VALUES, sep=st.sampled_from(["=", "==", " = "]))
    def inner(key: str, value: str, sep: str) -> None:
        if "\x00" in key + value:
            value = value.replace("\x00", "")
            key = key.replace("\x00", "")
        check_contract(base, capsys, extra=("--set", f"{key}{sep}{value}"))

    inner()


#: valid-typed extreme values found by an exhaustive sweep (every leaf x ODD_VALUES) of the bases
#: that the sampled fuzz above does not reach: each must end in the contract, in bounded time
EXTREME = [
    ("bouncing_ball", ("parameters", "g"), 1e308),
    ("two_mass_chain", ("parameters", "k2"), 10**12),
]


@pytest.mark.parametrize("problem, path, value", EXTREME,
                         ids=[f"{p}:{dotted(k)}={v!r}" for p, k, v in EXTREME])
def test_extreme_values(problem: str, path: tuple, value: Any, capsys: Any) -> None:
    check_contract(apply(base_case(problem), ("replace", path, value)), capsys)


# --------------------------------------------------------------------------- base cases run


def test_every_registered_problem_has_a_fuzz_base() -> None:
    # the problems this distribution registers (a user's plugin in the same environment is
    # not ours to fuzz)
    ours = {k for k, v in registry.available().items()
            if v.startswith("nsm_continuation.problems.")}
    assert ours <= set(BASE_SOURCES), f"add a base case for {ours - set(BASE_SOURCES)}"


@pytest.mark.parametrize("problem", PROBLEMS)
def test_base_case_is_valid_and_fast(problem: str, tmp_path: Path, capsys: Any) -> None:
    """The fuzz bases themselves: valid, exit 0, a report, within a few seconds (~0.02-1 s)."""
    path = write_case(tmp_path, base_case(problem))
    v = run_cli(["validate", path], capsys)
    assert_sane(v, (0,))
    r = run_cli(["run", path, "--out", tmp_path / "out", "--quiet"], capsys)
    assert_sane(r, (0,))
    assert (tmp_path / "out" / "report.json").is_file()
    assert r.seconds < BASE_RUN_BOUND_S, r.show()


#: the bases whose figures take ~1-2 s (the ball's take ~6 s)
PLOT_PROBLEMS = [p for p in PROBLEMS if p != "bouncing_ball"]


@pytest.mark.parametrize("problem", PLOT_PROBLEMS)
def test_base_case_with_plots(problem: str, capsys: Any) -> None:
    """The figures are part of a run: with ``output.plots: true`` the contract holds too."""
    case = base_case(problem)
    case["output"]["plots"] = True
    check_contract(case, capsys)


# --------------------------------------------------------------------------- fixed faults

GOOD = base_case("ndof_impact")


def _refused(c: Call) -> str:
    assert_sane(c, (2,))
    return assert_one_error_line(c)


def _both_refused(path: Path, tmp_path: Path, capsys: Any,
                  bound: float = CALL_BOUND_S) -> str:
    """validate and run (with --out) both exit 2, one identical line, nothing written."""
    before = tree(tmp_path)
    v = run_cli(["validate", path], capsys, bound=bound)
    line = _refused(v)
    r = run_cli(["run", path, "--out", tmp_path / "out"], capsys, bound=bound)
    assert _refused(r) == line, r.show()
    assert tree(tmp_path) == before
    assert v.seconds < bound and r.seconds < bound
    return line


def test_non_utf8_case_file(tmp_path: Path, capsys: Any) -> None:
    path = tmp_path / "case.yaml"
    path.write_bytes(b"name: caf\xe9\nproblem: ndof_impact\n\xff\xfe\n")
    line = _both_refused(path, tmp_path, capsys)
    assert line.startswith("error: case file"), line


def test_directory_as_case(tmp_path: Path, capsys: Any) -> None:
    d = tmp_path / "dir.yaml"
    d.mkdir()
    _both_refused(d, tmp_path, capsys)


def test_dev_null_as_case(tmp_path: Path, capsys: Any) -> None:
    line = _refused(run_cli(["validate", "/dev/null"], capsys))
    assert any(w in line for w in ("empty", "mapping", "regular file")), line
    r = run_cli(["run", "/dev/null", "--out", tmp_path / "out"], capsys)
    assert _refused(r) == line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text", ["", "   \n\n", "# only a comment\n", "~\n", "[1, 2]\n",
                                  "42\n", "just a string\n", "--- \n...\n",
                                  "a: 1\n---\nb: 2\n", "? [a, b]\n: 1\n", "1: 2\n"],
                         ids=["empty", "blank", "comment", "null", "list", "int", "str",
                              "empty-doc", "two-docs", "complex-key", "int-key"])
def test_not_a_mapping_of_names(text: str, tmp_path: Path, capsys: Any) -> None:
    _both_refused(write_case(tmp_path, text), tmp_path, capsys)


def _alias_bomb() -> str:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        prev, cur = chr(96 + i), chr(97 + i)
        lines.append(f"{cur}: &{cur} [" + ",".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def test_yaml_alias_bomb_refused_fast(tmp_path: Path, capsys: Any) -> None:
    """Billion laughs (< 1 kB, 9^9 values once expanded): exit 2 within 5 s, as the whole
    document and as a value inside a valid case."""
    bomb = _alias_bomb()
    assert len(bomb) < 1000
    _both_refused(write_case(tmp_path, bomb), tmp_path, capsys, bound=REFUSE_BOUND_S)
    inside = dump(GOOD) + bomb.replace("a: &a", "zz: &a", 1)
    _both_refused(write_case(tmp_path, inside, "inside.yaml"), tmp_path, capsys,
                  bound=REFUSE_BOUND_S)


def test_yaml_alias_bomb_in_set_refused_fast(tmp_path: Path, capsys: Any) -> None:
    path = write_case(tmp_path, GOOD)
    value = "[" + ",".join(["&a [1,1,1,1,1,1,1,1,1]"] + ["*a"] * 8) + "]"
    c = run_cli(["validate", path, "--set", f"description={value}"], capsys,
                bound=REFUSE_BOUND_S)
    assert_sane(c, (2,))
    assert_one_error_line(c)


def test_deeply_nested_yaml(tmp_path: Path, capsys: Any) -> None:
    deep = "name: x\nproblem: ndof_impact\nparameters: " + "[" * 50_000 + "]" * 50_000 + "\n"
    _both_refused(write_case(tmp_path, deep), tmp_path, capsys, bound=REFUSE_BOUND_S)


@pytest.mark.parametrize("where", ["top", "nested", "start"])
def test_duplicate_keys(where: str, tmp_path: Path, capsys: Any) -> None:
    text = dump(GOOD)
    if where == "top":
        text += "name: again\n"
        key = "name"
    elif where == "nested":
        text = text.replace("  gap: 1.0\n", "  gap: 1.0\n  gap: 2.0\n")
        key = "gap"
    else:
        text = text.replace("start:\n", "start:\n  mode: 2\n")
        key = "mode"
    assert text.count(f"{key}:") >= 2
    line = _both_refused(write_case(tmp_path, text), tmp_path, capsys)
    assert key in line, line


WRONG_TYPES = [
    ("ndof_impact", ("parameters", "chain", "dofs"), True),
    ("ndof_impact", ("parameters", "chain", "dofs"), "3"),
    ("ndof_impact", ("parameters", "gap"), True),
    ("ndof_impact", ("parameters", "chain", "mass"), "0.2"),
    ("ndof_impact", ("start", "mode"), True),
    ("ndof_impact", ("continuation", "max_points"), True),
    ("ndof_impact", ("continuation", "max"), "2"),
    ("ndof_impact", ("analysis", "stability"), "yes please"),
    ("wfem_bar", ("parameters", "cells"), True),
    ("wfem_bar", ("parameters", "gap"), "1e-3"),
    ("wfem_bar", ("parameters", "gap"), "0.001"),
    ("wfem_bar", ("start", 0, "mode"), False),
    ("bar_continuum", ("parameters", "E"), True),
    ("bouncing_ball", ("parameters", "chatter_order"), True),
    ("impact_oscillator", ("parameters", "omega"), "0.4"),
    ("impact_oscillator", ("start", "transient"), True),
    ("two_mass_chain", ("parameters", "restitution"), True),
    ("double_pendulum", ("start", "guess", "q2"), True),
    ("double_pendulum", ("parameters", "torque"), "-31.15"),
]


@pytest.mark.parametrize("problem, path, value", WRONG_TYPES,
                         ids=[f"{p}:{dotted(k)}={v!r}" for p, k, v in WRONG_TYPES])
def test_wrong_type_is_refused_naming_the_key(problem: str, path: tuple, value: Any,
                                              tmp_path: Path, capsys: Any) -> None:
    """``n: true`` for a number (and the like): exit 2 naming the key, never coerced."""
    case = apply(base_case(problem), ("replace", path, value))
    line = _both_refused(write_case(tmp_path, case), tmp_path, capsys)
    assert names(line, dotted(path)), line


@pytest.mark.parametrize("problem", PROBLEMS)
def test_unknown_key_in_start_is_refused(problem: str, tmp_path: Path, capsys: Any) -> None:
    """An unknown key is refused everywhere, also in a problem's start block."""
    case = base_case(problem)
    start = case["start"][0] if isinstance(case["start"], list) else case["start"]
    start["zz_fuzz"] = 1
    line = _both_refused(write_case(tmp_path, case), tmp_path, capsys)
    assert "zz_fuzz" in line, line


def test_300_character_name(tmp_path: Path, capsys: Any) -> None:
    """Without --out the name is the output folder (at most 255 bytes): refused, one line,
    nothing written; validate agrees."""
    case = dict(GOOD, name="n" * 300)
    path = write_case(tmp_path, case)
    line = _refused(run_cli(["validate", path], capsys))
    assert line.startswith("error: name"), line
    before = tree(tmp_path)
    r = run_cli(["run", path], capsys, cwd=tmp_path)
    assert _refused(r) == line
    assert tree(tmp_path) == before


@pytest.mark.parametrize("name", PATH_NAMES, ids=[repr(n)[:20] for n in PATH_NAMES])
def test_path_as_name_is_refused(name: str, tmp_path: Path, capsys: Any) -> None:
    case = dict(GOOD, name=name)
    work = tmp_path / "a" / "work"
    work.mkdir(parents=True)
    path = write_case(work, case)
    line = _refused(run_cli(["validate", path], capsys))
    assert line.startswith("error: name"), line
    if not name.startswith("/"):
        before = tree(tmp_path)
        assert _refused(run_cli(["run", path], capsys, cwd=work)) == line
        assert tree(tmp_path) == before


# --------------------------------------------------------------------------- output location


def _run_refused_untouched(argv_out: str | Path, tmp_path: Path, capsys: Any,
                           case: dict | None = None) -> str:
    path = write_case(tmp_path, case or GOOD)
    v = run_cli(["validate", path], capsys)
    assert_sane(v, (0,))
    before = tree(tmp_path)
    r = run_cli(["run", path, "--out", argv_out], capsys)
    line = _refused(r)
    assert tree(tmp_path) == before, r.show()
    return line


def test_out_is_an_existing_file(tmp_path: Path, capsys: Any) -> None:
    f = tmp_path / "result.txt"
    f.write_text("precious\n")
    mtime = f.stat().st_mtime_ns
    _run_refused_untouched(f, tmp_path, capsys)
    assert f.read_text() == "precious\n" and f.stat().st_mtime_ns == mtime


def test_out_below_an_existing_file(tmp_path: Path, capsys: Any) -> None:
    f = tmp_path / "result.txt"
    f.write_text("precious\n")
    _run_refused_untouched(f / "sub" / "out", tmp_path, capsys)
    assert f.read_text() == "precious\n"


def test_out_is_a_directory_with_other_files(tmp_path: Path, capsys: Any) -> None:
    d = tmp_path / "mine"
    d.mkdir()
    (d / "thesis.tex").write_text("precious\n")
    _run_refused_untouched(d, tmp_path, capsys)
    assert (d / "thesis.tex").read_text() == "precious\n"


@pytest.mark.parametrize("out", ["/proc/nsm-fuzz-out", "/proc/self/nsm-fuzz-out/run",
                                 "/dev/null", "/dev/null/out", "/sys/nsm-fuzz-out"])
def test_out_in_an_unwritable_system_location(out: str, tmp_path: Path, capsys: Any) -> None:
    """Works as root too (/proc and /sys refuse even root)."""
    line = _run_refused_untouched(out, tmp_path, capsys)
    assert "output" in line or "--out" in line, line
    assert not Path(out).exists() or out == "/dev/null"


def _freeze(d: Path) -> bool:
    """Make ``d`` unwritable: chmod 0555, or for root (who ignores modes) the immutable
    attribute; False if neither works here."""
    if os.geteuid() != 0:
        d.chmod(0o555)
        return True
    if shutil.which("chattr") is None:
        return False
    r = subprocess.run(["chattr", "+i", str(d)], capture_output=True)
    if r.returncode != 0:
        return False
    try:
        (d / "probe").touch()
    except OSError:
        return True
    (d / "probe").unlink()
    _unfreeze(d)
    return False


def _unfreeze(d: Path) -> None:
    for p in [d, *(d.rglob("*") if d.is_dir() else [])]:
        if os.geteuid() == 0 and shutil.which("chattr") and p.is_dir():
            subprocess.run(["chattr", "-i", str(p)], capture_output=True)
        if p.is_dir() and not p.is_symlink():
            p.chmod(p.stat().st_mode | stat.S_IWUSR)


def test_out_inside_a_read_only_directory(tmp_path: Path, capsys: Any) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    (ro / "keep.txt").write_text("keep\n")
    if not _freeze(ro):
        pytest.skip("cannot make a directory unwritable here (root without chattr +i)")
    try:
        for out in (ro / "out", ro / "deeper" / "out"):
            line = _run_refused_untouched(out, tmp_path, capsys)
            assert "output" in line, line
        assert sorted(p.name for p in ro.iterdir()) == ["keep.txt"]
    finally:
        _unfreeze(ro)


@pytest.mark.parametrize("value", ["", ".", "..", "case.yaml", "case.yaml/x", "/proc/nsm-fuzz",
                                   "/dev/null", "a\x00b", "x" * 300, "~", "sub/dir"],
                         ids=["empty", "dot", "dotdot", "file", "below-file", "proc", "devnull",
                              "nul", "long", "tilde", "sub"])
def test_output_dir_in_the_case(value: str, capsys: Any) -> None:
    """output.dir (run without --out, in a sandbox): exit 0 with the report where asked, or 2
    naming the output with nothing written; never 1."""
    case = copy.deepcopy(GOOD)
    case["output"]["dir"] = value
    check_contract(case, capsys, out=False, output_errors_allowed=True)


@pytest.mark.parametrize("which", ["case-component", "case-path", "out-component", "out-path"])
def test_overlong_paths(which: str, tmp_path: Path, capsys: Any) -> None:
    """A path the OS refuses (ENAMETOOLONG) is bad input, not a crash."""
    path = write_case(tmp_path, GOOD)
    long_component = "x" * 300
    long_path = "a/" * 3000 + "b"
    before = tree(tmp_path)
    if which.startswith("case"):
        case = tmp_path / (long_component + ".yaml" if which == "case-component" else long_path)
        c = run_cli(["validate", case], capsys)
        assert _refused(c).startswith("error: case file"), c.show()
        c = run_cli(["run", case, "--out", tmp_path / "out"], capsys)
    else:
        out = tmp_path / (long_component if which == "out-component" else long_path)
        c = run_cli(["run", path, "--out", out], capsys)
    _refused(c)
    assert tree(tmp_path) == before


# --------------------------------------------------------------------------- special files


def test_fifo_as_case_is_refused_fast(tmp_path: Path, capsys: Any) -> None:
    """A named pipe nobody writes to: refused, not waited on forever."""
    fifo = tmp_path / "case.yaml"
    os.mkfifo(fifo)
    c = run_cli(["validate", fifo], capsys, bound=REFUSE_BOUND_S)
    _refused(c)


@pytest.mark.parametrize("dev", ["/dev/zero", "/dev/urandom"])
def test_endless_device_as_case_is_refused_fast(dev: str, capsys: Any) -> None:
    _refused(run_cli(["validate", dev], capsys, bound=REFUSE_BOUND_S))


def test_huge_case_file_bounded(tmp_path: Path, capsys: Any) -> None:
    text = dump(GOOD) + ("# padding " * 100 + "\n") * 3000
    c = run_cli(["validate", write_case(tmp_path, text)], capsys, bound=REFUSE_BOUND_S)
    assert_sane(c, (0, 2))
    if c.rc == 2:
        assert_one_error_line(c)


# --------------------------------------------------------------------------- command line

BAD_ARGV = [["run", "--bogus"], ["frobnicate"], [], ["validate"], ["run", "a.yaml", "b.yaml"],
            ["run", "--set"], ["list", "extra"], ["run", "--out"]]


@pytest.mark.parametrize("argv", BAD_ARGV, ids=[" ".join(a) or "none" for a in BAD_ARGV])
def test_bad_command_line_is_one_error_line(argv: list[str], capsys: Any) -> None:
    """A bad command line is bad input too: exit 2, one ``error: ...`` line."""
    _refused(run_cli(argv, capsys))


# --------------------------------------------------------------------------- real processes


def test_process_bad_file_no_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "case.yaml"
    bad.write_bytes(b"name: \xff\xfe\n")
    c = run_process(["validate", bad], tmp_path)
    assert_sane(c, (2,))
    assert_one_error_line(c)


def test_process_alias_bomb_refused_fast(tmp_path: Path) -> None:
    path = write_case(tmp_path, _alias_bomb())
    try:
        c = run_process(["run", path, "--out", tmp_path / "out"], tmp_path,
                        timeout=REFUSE_BOUND_S + 5)
    except subprocess.TimeoutExpired:
        pytest.fail(f"alias bomb not refused within {REFUSE_BOUND_S + 5} s (process)")
    assert_sane(c, (2,))
    assert_one_error_line(c)
    assert not (tmp_path / "out").exists()


def test_process_huge_chain_no_traceback(tmp_path: Path) -> None:
    """A 10^12-dof chain: refused as bad input (not a MemoryError)."""
    path = write_case(tmp_path, apply(GOOD, ("replace", ("parameters", "chain", "dofs"), 10**12)))
    c = run_process(["validate", path], tmp_path)
    assert_sane(c, (2,))
    assert "parameters.chain.dofs" in assert_one_error_line(c)


def test_process_good_run_and_unwritable_out(tmp_path: Path) -> None:
    path = write_case(tmp_path, GOOD)
    c = run_process(["run", path, "--out", tmp_path / "out"], tmp_path)
    assert_sane(c, (0,))
    assert (tmp_path / "out" / "report.json").is_file()
    c = run_process(["run", path, "--out", "/proc/nsm-fuzz-out"], tmp_path)
    assert_sane(c, (2,))
    assert_one_error_line(c)
