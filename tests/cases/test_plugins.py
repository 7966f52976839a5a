"""Problems of other packages (plugins, registered under the entry-point group
``nsm_continuation.problems``): their faults are theirs, and named. A plugin that cannot be
imported, fails in ``__init__`` or ``preflight`` (an exception or ``SystemExit``), declares a
residual of the wrong shape or a ``Parameters`` model that is not strict is refused by
``validate`` and ``run`` with exit status 2, one line naming the problem, its ``module:Class``
and the fault, and nothing written; a name registered twice is said at ``list``, ``validate``
and ``run``.

Each plugin is a throwaway package in ``tmp_path`` with a ``*.dist-info`` declaring its entry
point, put on ``sys.path`` (a fresh interpreter gets it through ``PYTHONPATH``)."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
import time
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any, ClassVar

import casadi as ca
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from nsm_continuation import api, cli
from nsm_continuation.cases import registry, validation
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.problem import Problem

#: a minimal plugin: ``x = a mu`` in the unknowns ``(x, mu)``; the fields below are replaced
TEMPLATE = '''
from typing import ClassVar

import casadi as ca
from pydantic import BaseModel, ConfigDict

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.problem import Problem
{top}

class ToyParameters(BaseModel):
    model_config = {config}
    a: float = 1.0


class Toy(Problem):
    name: ClassVar[str] = "toy"
    Parameters: ClassVar[type[BaseModel]] = ToyParameters

    def __init__(self, params):
        super().__init__(params)
        self.variables = ["x", "mu"]
        self.parameter = "mu"
        {init}

    def residual(self, y):
        return {residual}

    def preflight(self, start, window, max_points):
        {preflight}
'''

#: a valid case of the toy plugin
CASE: dict[str, Any] = {"name": "toy", "problem": "toy", "parameters": {"a": 2.0},
                        "start": {}, "continuation": {"parameter": "mu", "min": 0.0, "max": 1.0},
                        "output": {"progress": False, "plots": False}}

_serial = itertools.count()


@pytest.fixture()
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Callable[..., str]:
    """``plugin(name="toy", **fields)``: a package in ``tmp_path`` whose module is
    :data:`TEMPLATE` with ``fields`` (``top``, ``config``, ``init``, ``residual``,
    ``preflight``) replaced, registered as ``name``; returns its ``module:Class``. Each
    package has its folder ``tmp_path/site-<package>``, put first on ``sys.path`` for this
    test."""

    def make(name: str = "toy", source: str | None = None, **fields: str) -> str:
        package = f"toy_plugin_{os.getpid()}_{next(_serial)}"
        root = tmp_path / f"site-{package}"
        values = {"top": "", "config": "STRICT", "init": "pass",
                  "residual": "y[0] - self.params.a * y[1]", "preflight": "return None",
                  **fields}
        (root / package).mkdir(parents=True)
        (root / package / "__init__.py").write_text("")
        (root / package / "toy.py").write_text(source if source is not None
                                               else TEMPLATE.format(**values))
        info = root / f"{package}-0.1.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {package}\nVersion: 0.1\n")
        (info / "entry_points.txt").write_text(
            f"[{registry.GROUP}]\n{name} = {package}.toy:Toy\n")
        monkeypatch.syspath_prepend(str(root))
        return f"{package}.toy:Toy"

    return make


def case_file(tmp_path: Path, **changes: Any) -> Path:
    """The toy case with ``changes`` at its top level, written to ``tmp_path/case.yaml``."""
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump({**CASE, **changes}))
    return path


def test_a_valid_plugin_is_valid(plugin: Callable[..., str], tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    target = plugin()
    assert registry.available()["toy"] == target
    assert cli.main(["validate", str(case_file(tmp_path))]) == 0
    assert "valid (toy, 2 unknowns)" in capsys.readouterr().out


@pytest.mark.parametrize(("fields", "what", "error"), [
    ({"top": "def broken(:\n    pass"}, "on import", "SyntaxError: "),
    ({"top": "raise RuntimeError('no licence server')"}, "on import",
     "RuntimeError: no licence server"),
    ({"top": "import a_module_nobody_has_0"}, "on import", "ModuleNotFoundError: "),
    ({"top": "raise SystemExit(4)"}, "on import", "SystemExit(4)"),
    ({"init": "raise KeyError('stiffness')"}, "in __init__", "KeyError: 'stiffness'"),
    ({"init": "raise SystemExit(3)"}, "in __init__", "SystemExit(3)"),
    ({"init": "import sys; sys.exit('bye')"}, "in __init__", "SystemExit('bye')"),
    ({"preflight": "raise TypeError('start must be a dict')"}, "in preflight",
     "TypeError: start must be a dict"),
    ({"preflight": "raise SystemExit(0)"}, "in preflight", "SystemExit(0)"),
])
def test_a_failing_plugin_is_named_as_the_fault(
        plugin: Callable[..., str], tmp_path: Path,
        refused_before_computing: Callable[[Path, str], None],
        fields: dict[str, str], what: str, error: str) -> None:
    """An import-time error (a SyntaxError too) or an exception or ``SystemExit`` in
    ``__init__`` or ``preflight``: exit 2 naming the problem, module:Class and exception, for
    ``validate`` and ``run``, nothing written; the Python API raises the same line."""
    target = plugin(**fields)
    path = case_file(tmp_path)
    line = f"problem: plugin 'toy' ({target}) failed {what}: {error}"
    refused_before_computing(path, line)
    for call in (lambda: api.load_case(path), lambda: api.run(path)):
        with pytest.raises(CaseError) as info:
            call()
        assert str(info.value).startswith(line) and "\n" not in str(info.value)
        assert str(info.value).endswith("(a fault of the plugin, not of nsm-continuation)")


def test_a_failing_plugin_is_named_by_the_api_problem(plugin: Callable[..., str]) -> None:
    target = plugin(init="raise LookupError('x')")
    with pytest.raises(CaseError, match=rf"^problem: plugin 'toy' \({target}\) failed in "
                                        r"__init__: LookupError: x \(a fault"):
        api.problem("toy", {"a": 1.0})


def test_a_bundled_problem_failing_is_still_a_bug(monkeypatch: pytest.MonkeyPatch) -> None:
    """The bundled problems' failures are this package's bugs: not blamed on a plugin."""
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    def broken(self: Any, params: Any) -> None:
        raise KeyError("bug")

    monkeypatch.setattr(NDofImpactProblem, "__init__", broken)
    raw = {**CASE, "problem": "ndof_impact",
           "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
           "start": {"mode": 1}, "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9}}
    with pytest.raises(KeyError):
        validation.validate(raw)


@pytest.mark.parametrize(("residual", "shape"), [
    ("ca.vertcat(y[0] - y[1], y[1])", "2 x 1"),     # n + 1 equations for n + 1 unknowns
    ("ca.SX(0, 1)", "0 x 1"),                       # none
    ("ca.horzcat(y[0], y[1])", "1 x 2"),            # a row
])
def test_a_residual_of_the_wrong_shape_is_refused(
        plugin: Callable[..., str], tmp_path: Path,
        refused_before_computing: Callable[[Path, str], None],
        residual: str, shape: str) -> None:
    """The residual of ``len(variables)`` unknowns has ``len(variables) - 1`` equations: else
    exit 2 naming the problem and the shapes (before, ``validate`` passed and ``run``
    crashed)."""
    target = plugin(residual=residual)
    refused_before_computing(case_file(tmp_path),
                             f"problem: plugin 'toy' ({target}): residual has shape {shape} "
                             "for 2 unknowns (x, mu)")


@pytest.mark.parametrize(("residual", "kind"), [
    ("[y[0] - y[1]]", "list"), ("1.0", "float"), ("ca.DM([1.0])", "DM"),
])
def test_a_residual_that_is_not_an_expression_is_refused(
        plugin: Callable[..., str], tmp_path: Path,
        refused_before_computing: Callable[[Path, str], None], residual: str, kind: str) -> None:
    target = plugin(residual=residual)
    refused_before_computing(case_file(tmp_path),
                             f"problem: plugin 'toy' ({target}): residual(y) must return a "
                             f"CasADi SX expression of the symbol y, got {kind}")


def _problem_class(unknowns: int, equations: int, symbolic: str) -> type[Problem]:
    """A problem of ``unknowns`` unknowns whose residual has ``equations`` rows."""

    class Params(BaseModel):
        model_config = STRICT

    class Counted(Problem):
        name: ClassVar[str] = "counted"
        Parameters: ClassVar[type[BaseModel]] = Params

        def __init__(self, params: BaseModel) -> None:
            super().__init__(params)
            self.symbolic = symbolic
            self.variables = [f"u{i}" for i in range(unknowns)]
            self.parameter = "u0"

        def residual(self, y: Any) -> Any:
            rows = [y[i % unknowns] for i in range(equations)]
            return ca.vertcat(*rows) if rows else (ca.SX if symbolic == "SX" else ca.MX)(0, 1)

    return Counted


@settings(max_examples=40, deadline=None)
@given(unknowns=st.integers(2, 6), equations=st.integers(0, 8),
       symbolic=st.sampled_from(["SX", "MX"]))
def test_any_equation_count_but_unknowns_minus_one_is_refused(
        unknowns: int, equations: int, symbolic: str) -> None:
    """Through the Python API's path (a class not registered): every count of equations but
    ``len(variables) - 1`` is refused naming the shapes; that one passes."""
    cls = _problem_class(unknowns, equations, symbolic)
    raw = {**CASE, "problem": "counted", "parameters": {},
           "continuation": {"parameter": "u0", "min": 0.0, "max": 1.0}}
    if equations == unknowns - 1:
        validation.validate(raw, problem_class=cls)
        return
    with pytest.raises(CaseError) as info:
        validation.validate(raw, problem_class=cls)
    assert str(info.value).startswith("problem: plugin 'counted' (")
    assert f"residual has shape {equations} x 1 for {unknowns} unknowns" in str(info.value)
    assert f"len(variables) - 1 = {unknowns - 1} equations" in str(info.value)


@pytest.mark.parametrize("init", [
    "self.variables = ['x']", "self.variables = 'x mu'", "self.parameter = 'omega'",
    "del self.parameter",
])
def test_unknowns_that_are_not_declared_are_refused(
        plugin: Callable[..., str], tmp_path: Path,
        refused_before_computing: Callable[[Path, str], None], init: str) -> None:
    target = plugin(init=init)
    refused_before_computing(case_file(tmp_path), f"problem: plugin 'toy' ({target}): ")


@pytest.mark.parametrize("config", ["ConfigDict()", "ConfigDict(extra='forbid')",
                                    "ConfigDict(strict=True)", "ConfigDict(extra='ignore')"])
@pytest.mark.parametrize("parameters", [{"aa": 2.0}, {"a": True}])
def test_a_plugin_whose_parameters_are_not_strict_is_refused(
        plugin: Callable[..., str], tmp_path: Path,
        refused_before_computing: Callable[[Path, str], None], config: str,
        parameters: dict[str, Any]) -> None:
    """A misspelt key (``aa``) or ``true`` for a number would pass a lax model unnoticed: the
    plugin is refused, naming its model and the fix, whatever the case says."""
    target = plugin(config=config)
    model = target.replace(":Toy", ":ToyParameters")
    refused_before_computing(case_file(tmp_path, parameters=parameters),
                             f"problem: 'toy' ({target}): its Parameters model {model} is "
                             "not strict")
    with pytest.raises(CaseError, match="model_config = nsm_continuation.core.preflight."
                                        r"STRICT$"):
        api.load_case(case_file(tmp_path, parameters=parameters))


def test_a_strict_plugin_refuses_a_typo_and_true_for_a_number(
        plugin: Callable[..., str], tmp_path: Path,
        refused_before_computing: Callable[[Path, str], None]) -> None:
    plugin()
    refused_before_computing(case_file(tmp_path, parameters={"aa": 2.0}), "parameters.aa: ")
    refused_before_computing(case_file(tmp_path, parameters={"a": True}), "parameters.a: ")


@pytest.mark.parametrize("name", sorted(registry.available()))
def test_every_bundled_problem_is_strict(name: str) -> None:
    cls = registry.get(name)
    assert cls.Parameters.model_config.get("extra") == "forbid"
    assert cls.Parameters.model_config.get("strict") is True


def test_a_duplicate_name_is_listed(plugin: Callable[..., str],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    target = plugin(name="ndof_impact")
    bundled = "nsm_continuation.problems.chain.ndof_impact:NDofImpactProblem"
    assert cli.main(["list"]) == 0
    lines = [line.split(None, 1)[1] for line in capsys.readouterr().out.splitlines()
             if line.split()[0] == "ndof_impact"]
    dist = target.split(".")[0]
    assert lines == [registry.describe(bundled),
                     f"{target} (duplicate from {dist}, ignored: {bundled} is used)"]
    assert registry.available()["ndof_impact"] == bundled
    with pytest.warns(registry.DuplicateProblemWarning,
                      match=f"problem 'ndof_impact' is registered 2 times: {bundled} "
                            rf"\(from nsm-continuation\) is used, {target} \(from {dist}\) "
                            "ignored"):
        assert registry.get("ndof_impact").__name__ == "NDofImpactProblem"


def test_between_two_plugins_the_first_on_the_path_is_used(plugin: Callable[..., str]) -> None:
    second = plugin()
    first = plugin()  # prepended to sys.path after the other
    assert [e.target for e in registry.registrations()["toy"]] == [first, second]
    with pytest.warns(registry.DuplicateProblemWarning, match=f"{first} .* is used, {second}"):
        assert registry.get("toy").__module__ == first.partition(":")[0]


def test_the_scan_of_the_entry_points_is_kept_until_the_path_changes(
        fresh_registry: Any, plugin: Callable[..., str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The entry points are read once while ``sys.path`` and its folders are unchanged; a
    folder put on the path, or a distribution installed in a folder already on it, is seen
    by the next lookup, and :func:`registry.refresh` forgets the scan."""
    scans = []
    real = registry.entry_points
    monkeypatch.setattr(registry, "entry_points",
                        lambda **kw: scans.append(kw) or real(**kw))
    assert "toy" not in registry.available()
    assert registry.available() == registry.available()
    assert registry.get("ndof_impact").__name__ == "NDofImpactProblem"
    assert len(scans) == 1
    target = plugin()  # its folder put first on sys.path
    assert registry.available()["toy"] == target
    assert len(scans) == 2
    # a second distribution installed beside the first (its folder's mtime changes; the
    # pause outlasts the file system's coarse clock tick)
    site = Path(sys.path[0])
    time.sleep(0.05)
    info = site / "other_toy-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: other_toy\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{registry.GROUP}]\ntoy2 = {target}\n")
    assert registry.available()["toy2"] == target
    assert len(scans) == 3
    registry.refresh()
    registry.available()
    assert len(scans) == 4


def test_a_replaced_entry_point_scan_is_seen_after_refresh(
        fresh_registry: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """A test (or a tool) replacing ``entry_points`` sees its own registrations once the
    scan is forgotten (the ``fresh_registry`` fixture)."""
    fake = metadata.EntryPoint("fake", "fake_module:Fake", registry.GROUP)
    monkeypatch.setattr(registry, "entry_points", lambda **kw: [fake])
    assert registry.available() == {"fake": "fake_module:Fake"}
    with pytest.raises(registry.PluginError, match="plugin 'fake' .*fake_module:Fake"):
        registry.get("fake")


def test_a_duplicate_name_is_said_by_validate_and_run(plugin: Callable[..., str],
                                                     tmp_path: Path) -> None:
    """In a fresh interpreter (the warning on stderr as a user sees it): one line naming both
    targets, from ``validate`` (a valid case) and ``run`` (here refused later, on a parameter:
    the warning comes first, from finding the problem)."""
    target = plugin(name="ndof_impact")
    case = {"problem": "ndof_impact",
            "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
            "start": {"mode": 1},
            "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9}}
    path = tmp_path / "dup.yaml"
    path.write_text(yaml.safe_dump(case))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(map(str, tmp_path.glob("site-*")))}
    for command, extra, status in (("validate", [], 0),
                                   ("run", ["--set", "parameters.chain.dofs=0"], 2)):
        proc = subprocess.run([sys.executable, "-m", "nsm_continuation.cli", command, str(path),
                               "--out", str(tmp_path / "out"), *extra],
                              capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
        assert proc.returncode == status, proc.stderr
        warning = [line for line in proc.stderr.splitlines() if "DuplicateProblemWarning" in line]
        assert len(warning) == 1, proc.stderr
        assert "nsm_continuation.problems.chain.ndof_impact:NDofImpactProblem" in warning[0]
        assert f"{target} (from" in warning[0] and "ignored" in warning[0]
    assert not (tmp_path / "out").exists()


def test_a_plugin_missing_its_class_or_not_a_problem(plugin: Callable[..., str], tmp_path: Path,
                                                     refused_before_computing: Callable[
                                                         [Path, str], None]) -> None:
    target = plugin(source="Toy = 3\n")
    refused_before_computing(case_file(tmp_path),
                             f"problem: plugin 'toy' ({target}) failed to provide a Problem "
                             "subclass")


#: the toy plugin with a start and hooks that fail during the run, as ``FAULT`` says
RUNNING = TEMPLATE.format(
    top="import sys\nimport numpy as np\nfrom nsm_continuation.core.problem import StartPoint\n"
        "from nsm_continuation.core.presentation import Presentation\n"
        "FAULT = {fault!r}\n\n\n"
        "class ToyPresentation(Presentation):\n"
        "    def plot_decorations(self, ax, x_range, branches):\n"
        "        if FAULT == 'figure':\n"
        "            raise RuntimeError('no colour map')\n"
        "        if FAULT == 'figure_exit':\n"
        "            sys.exit(6)\n",
    config="STRICT", init="self.presentation_class = ToyPresentation",
    residual="y[0] - self.params.a * y[1]", preflight="return None",
) + '''
    def start_points(self, start, window=(None, None)):
        if FAULT == "start_exit":
            sys.exit(7)
        if FAULT == "start_outside":  # an orbit at mu = 2, outside the window [0, 1]
            return [StartPoint(np.array([2.0 * self.params.a, 2.0]), "toy")]
        return [StartPoint(np.array([0.0, 0.0]), "toy")]
'''


@pytest.mark.parametrize(("fault", "status", "line"), [
    ("start_exit", 3, "problem 'toy' raised SystemExit(7) in a hook (sys.exit)"),
    ("start_outside", 3, "start outside parameter bounds (the start's parameter 2 is outside "
                         "the window [0.0, 1.0])"),
    ("figure", 0, "problem 'toy' ({module}): the figures failed in its code (RuntimeError: "
                  "no colour map); they are left out"),
    ("figure_exit", 0, "problem 'toy' ({module}): the figures failed in its code "
                       "(SystemExit: 6); they are left out"),
])
def test_a_plugin_failing_during_the_run_is_named_and_the_results_written(
        plugin: Callable[..., str], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        fault: str, status: int, line: str) -> None:
    """After the preflight, a plugin's ``start_points`` calling ``sys.exit`` or giving a start
    outside the parameter window (a branch of one point that no direction can leave) is a
    failed start (exit 3, its reason named, the report written), and its figure hooks failing (an
    exception or ``sys.exit``) leave the figures out with a warning naming it, the data and
    the report written: not the plugin's exit code without a word, nor "this is a bug" with
    everything computed lost."""
    target = plugin(source=RUNNING.replace("{fault!r}", repr(fault)))
    line = line.format(module=target.partition(":")[0])
    path = case_file(tmp_path, output={"progress": False, "plots": True})
    out = tmp_path / "out"
    assert cli.main(["run", str(path), "--out", str(out)]) == status
    err = capsys.readouterr().err
    assert line in err, err
    assert (out / "branch_0.csv").is_file() and (out / "report.md").is_file()
    assert line in (out / "report.md").read_text() or status == 3


@pytest.mark.parametrize(("fault", "line"), [
    ("start_exit", "toy: 1 of 1 starts failed: branch 0 (start): start: no start point: "
                   "problem 'toy' raised SystemExit(7) in a hook (sys.exit)"),
    ("figure", "toy: problem 'toy' ({module}): the figures failed in its code (RuntimeError: "
               "no colour map); they are left out"),
])
def test_what_the_command_line_says_an_api_user_is_told(
        plugin: Callable[..., str], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        caplog: pytest.LogCaptureFixture, fault: str, line: str) -> None:
    """The failed start (the command line's exit 3 and its line) is logged when ``nsm.run``
    returns; the figures a plugin failed to draw are logged by ``Result.save`` (the command
    line's warning), each once, to the ``nsm_continuation`` logger; nothing on stdout."""
    import logging

    target = plugin(source=RUNNING.replace("{fault!r}", repr(fault)))
    line = line.format(module=target.partition(":")[0])
    path = case_file(tmp_path, output={"progress": False, "plots": True})
    with caplog.at_level(logging.WARNING, logger="nsm_continuation"):
        res = api.run(str(path))
        res.save(tmp_path / "out")
    logged = [r.getMessage() for r in caplog.records if r.name == "nsm_continuation"]
    assert sum(m.startswith(line) for m in logged) == 1, logged
    assert capsys.readouterr().out == ""
    assert (tmp_path / "out" / "branch_0.csv").is_file()
