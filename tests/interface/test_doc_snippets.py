"""The fenced blocks of README.md and docs/*.md are checked as written, none computing a branch
but the Python examples:

* every ```python block runs (with its own imports), in a fresh folder where `yaml_cases/` is the
  repository's; but a block marked ```python no-run (a run of tens of seconds, which the page says)
  compiles only;
* every ```yaml block parses (`yaml.safe_load`, and the case loader: duplicate keys refused).
  A block with a `problem:` key is a whole case and validates (`cases.validate`: schema,
  problem, preflight) as it stands; a block with a `start:` key but no `problem:` (the chain's
  `parameters:`/`start:` example) and a fragment (neither key, e.g. a lone `continuation:`) are
  merged key by key over the bundled default case (`yaml_cases/ndof_default.yaml`, the
  block's top-level keys replacing the default's) and the result validates. The placeholder
  `{...}` of the YAML reference is filled with the default case's value for that key. A restart
  (`start: {from: <run>}`) names a run the test does not compute: its `start:` block validates
  against the restart schema (`restart.parse_spec`) only. Commented-out alternatives
  (`# start: ...`) are not checked;
* every `nsm-continuation ...` command of a ```bash block (at the start of a line or after `&&`
  / `;`) is accepted by the CLI's argument parser (`cli._parser()`, nothing run), and the case
  file (or bundled case) it names validates; every `.py` / `.yaml` path a bash command names
  exists;
* every ```toml block parses (`tomllib`); its entry points are in the group the registry reads,
  and those of an importable module name a `Problem` subclass;
* no fenced block has another language, nor another word after its language (a new one would go
  unchecked). The docs site's directives are ``:::`` fences (MyST), not checked here; its generated
  reference pages (``docs/reference/``) are checked by ``test_doc_reference.py``.

Plus the README's promise about `BranchData`: `columns()` (and `to_frame()`, with pandas) are
the columns and values of `branch_<id>.csv`.
"""

from __future__ import annotations

import ast
import csv
import importlib
import importlib.util
import math
import re
import shlex
import tomllib
from importlib import resources
from typing import Any

import numpy as np
import pytest
import yaml
from helpers import CASES, ROOT

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: the languages of fenced blocks checked here ("" is plain text: the Architecture tree)
CHECKED = ("python", "yaml", "bash", "toml", "")
#: the word after ```python that marks a block compiled but not run
NO_RUN = "no-run"


def _fences() -> list[tuple[str, str, str]]:
    """(language, "file:line", text) of every fenced block; the language of a block with a word
    after it (```python no-run) is both (``python no-run``)."""
    out = []
    for doc in DOCS:
        text = doc.read_text()
        for m in re.finditer(r"^```([\w+-]*(?: [\w+-]+)*)[ \t]*\n(.*?)^```", text, re.S | re.M):
            line = text[:m.start()].count("\n") + 1
            out.append((m.group(1), f"{doc.name}:{line}", m.group(2)))
    return out


FENCES = _fences()


def _blocks(language: str) -> list[tuple[str, str]]:
    return [(name, text) for lang, name, text in FENCES if lang == language]


BLOCKS = _blocks("python")
NOT_RUN = _blocks(f"python {NO_RUN}")
YAML_BLOCKS = _blocks("yaml")
BASH_BLOCKS = _blocks("bash")
TOML_BLOCKS = _blocks("toml")


def _params(blocks: list[tuple[str, str]]) -> dict[str, Any]:
    return {"argvalues": [t for _, t in blocks], "ids": [n for n, _ in blocks]}


def test_the_docs_have_examples_of_every_kind():
    assert any(name.startswith("README.md") for name, _ in BLOCKS)
    assert YAML_BLOCKS and BASH_BLOCKS and TOML_BLOCKS


def test_every_fenced_block_is_checked():
    other = [(lang, name) for lang, name, _ in FENCES
             if lang not in (*CHECKED, f"python {NO_RUN}")]
    assert not other, f"fenced blocks in a language no test checks: {other}"


@pytest.mark.parametrize("code", **_params(NOT_RUN))
def test_snippet_not_run_compiles(code):
    """A block too long to run here is still Python, and names no module that is missing."""
    tree = compile(code, "<snippet>", "exec", flags=ast.PyCF_ONLY_AST, dont_inherit=True)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom | ast.Import):
            for name in ([node.module] if isinstance(node, ast.ImportFrom) else
                         [a.name for a in node.names]):
                assert importlib.util.find_spec(name.split(".")[0]) is not None, name


@pytest.mark.parametrize("code", **_params(BLOCKS))
def test_snippet_runs(code, tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    (tmp_path / "yaml_cases").symlink_to(CASES)
    monkeypatch.chdir(tmp_path)
    # dont_inherit: the snippet does not get this module's ``from __future__ import annotations``
    # (string annotations of a snippet's pydantic model would not resolve: no module holds them)
    exec(compile(code, "<snippet>", "exec", dont_inherit=True), {"__name__": "__snippet__"})


# ------------------------------------------------------------------------------------ YAML
def _default_case() -> dict[str, Any]:
    from nsm_continuation import cases

    path = resources.files("nsm_continuation.yaml_cases").joinpath("ndof_default.yaml")
    return cases.load_raw(str(path))


def _fill_placeholders(block: dict[str, Any], default: dict[str, Any]) -> dict[str, Any]:
    """The reference's ``key: {...}`` (YAML: ``{'...': None}``) -> the default case's value."""
    return {k: default[k] if v == {"...": None} else v for k, v in block.items()}


@pytest.mark.parametrize("text", **_params(YAML_BLOCKS))
def test_yaml_block_parses_and_validates(text, monkeypatch, tmp_path):
    from nsm_continuation import cases
    from nsm_continuation.cases import restart as rs

    data = yaml.safe_load(text)
    assert isinstance(data, dict) and data, "a YAML block of the docs is a mapping of keys"
    data = cases.parse_yaml(text, "block")  # the case loader: duplicate keys refused
    (tmp_path / "yaml_cases").symlink_to(CASES)
    monkeypatch.chdir(tmp_path)  # nothing is written, but a relative path resolves here
    if rs.is_restart(data.get("start")):
        rs.parse_spec(data["start"])
        return
    default = _default_case()
    data = _fill_placeholders(data, default)
    case = data if "problem" in data else {**default, **data}
    cases.validate(case)


# ------------------------------------------------------------------------------------ bash
def _commands(text: str) -> list[list[str]]:
    """The shell commands of a block: lines split at ``&&``, ``||``, ``;`` and ``|``, comments
    dropped."""
    out = []
    for line in text.splitlines():
        lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
        lexer.whitespace_split = True
        command: list[str] = []
        for token in lexer:
            if token in ("&&", "||", ";", "|", "&"):
                out.append(command)
                command = []
            else:
                command.append(token)
        out.append(command)
    return [c for c in out if c]


def test_bash_blocks_have_cli_commands():
    assert any(c[0] == "nsm-continuation" for _, t in BASH_BLOCKS for c in _commands(t))


@pytest.mark.parametrize("text", **_params(BASH_BLOCKS))
def test_bash_commands_parse(text, capsys):
    from nsm_continuation import cases, cli

    for argv in _commands(text):
        for token in argv[1:]:
            if token.endswith((".py", ".yaml")):
                assert (ROOT / token).is_file(), f"{' '.join(argv)}: {token} does not exist"
        if argv[0] != "nsm-continuation":
            continue
        try:
            args = cli._parser().parse_args(argv[1:])
        except SystemExit as exc:  # the parser's error: one line on stderr, status 2
            pytest.fail(f"{' '.join(argv)}: refused by the CLI's parser (status {exc.code}): "
                        f"{capsys.readouterr().err.strip()}")
        if getattr(args, "case", None):  # a file of the repository, or a bundled case's name
            path = ROOT / args.case
            cases.load(path if path.exists() else args.case, args.overrides)


# ------------------------------------------------------------------------------------ TOML
@pytest.mark.parametrize("text", **_params(TOML_BLOCKS))
def test_toml_block_parses(text):
    from nsm_continuation.cases import registry
    from nsm_continuation.core.problem import Problem

    data = tomllib.loads(text)
    points = data.get("project", {}).get("entry-points", {})
    assert points, "a TOML block of the docs declares entry points"
    assert set(points) == {registry.GROUP}, f"entry points outside {registry.GROUP}: {points}"
    for name, target in points[registry.GROUP].items():
        module, _, attr = target.partition(":")
        assert re.match(r"^[\w.]+$", module) and attr.isidentifier(), f"{name} = {target!r}"
        if importlib.util.find_spec(module.split(".")[0]) is None:
            continue  # a placeholder package (my_package)
        cls = getattr(importlib.import_module(module), attr)
        assert issubclass(cls, Problem) and cls.name == name


# ------------------------------------------------------------------------- BranchData / CSV
@pytest.fixture(scope="module")
def saved_branch(tmp_path_factory):
    """A short chain branch (with multipliers, some undefined), in memory and as saved."""
    import nsm_continuation as nsm

    chain = nsm.problem("ndof_impact", {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0},
                                        "gap": 1.0})
    result = nsm.continuation(chain, {"mode": 1}, parameter="omega", min=0.3, max=0.9,
                              max_points=12)
    folder = result.save(tmp_path_factory.mktemp("run") / "chain", plots=False)
    with open(folder / "branch_0.csv", newline="") as fh:
        rows = [row for row in csv.reader(fh) if row and not row[0].startswith("#")]
    return result.branches[0], rows[0], rows[1:]


def _csv_value(text: str) -> float:
    return math.nan if text == "" else float(text)


def test_branch_columns_are_the_csv(saved_branch):
    branch, header, rows = saved_branch
    assert len(rows) == len(branch) > 2
    columns = branch.columns()
    assert list(columns) == header == branch.column_names
    for j, name in enumerate(header):
        np.testing.assert_array_equal(columns[name], [_csv_value(r[j]) for r in rows],
                                      err_msg=name)


def test_branch_to_frame_is_the_csv(saved_branch):
    pd = pytest.importorskip("pandas")
    branch, header, rows = saved_branch
    frame = branch.to_frame()
    assert isinstance(frame, pd.DataFrame)
    assert list(frame.columns) == header
    assert len(frame) == len(rows)
    for name in header:
        np.testing.assert_array_equal(frame[name].to_numpy(dtype=float), branch[name],
                                      err_msg=name)
