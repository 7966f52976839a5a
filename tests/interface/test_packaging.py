"""What is packaged: the wheel holds every subpackage (``pyproject.toml`` lists its packages
explicitly, with ``problems/`` mapped to ``nsm_continuation.problems``, so a folder of modules
that is not listed would be missing after ``pip install .`` while an editable install still
finds it) and every bundled case as package data, run by name from any folder; the sdist
holds what its tests read; one version, one licence; the command line's help, ``list`` and
``cases``. Building and installing a wheel is ``benchmarks/check_wheel.sh`` (minutes, not CI)."""

from __future__ import annotations

import csv
import fnmatch
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import ROOT

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases import bundled, registry
from nsm_continuation.core.errors import CaseError


def test_every_package_folder_is_listed_in_pyproject() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = set()
    for top, prefix in (("nsm_continuation", "nsm_continuation"),
                        ("problems", "nsm_continuation.problems"),
                        ("yaml_cases", "nsm_continuation.yaml_cases")):
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / top).parts
            found.add(".".join((prefix, *rel)))
    assert found == listed


# ---------------------------------------------------------------------- what the wheel ships
def _package_data() -> dict[str, list[str]]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]


def _tracked(folder: str) -> list[Path]:
    """The files of ``folder`` the repository holds (git), else those on disk."""
    try:
        out = subprocess.run(["git", "ls-files", folder], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        return [p for p in (ROOT / folder).rglob("*") if p.is_file()]
    return [ROOT / f for f in out]


def test_every_bundled_case_is_package_data_of_the_wheel() -> None:
    """``yaml_cases/`` is the package ``nsm_continuation.yaml_cases`` and its globs take every
    case of the repository, the restart cases included: what ``pip install .`` installs."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"]["nsm_continuation.yaml_cases"] == "yaml_cases"
    assert (ROOT / "yaml_cases" / "__init__.py").is_file()
    globs = _package_data()["nsm_continuation.yaml_cases"]
    cases = [p for p in _tracked("yaml_cases") if p.suffix == ".yaml"]
    assert len(cases) >= 40 and any(p.parent.name == "restart" for p in cases)
    for path in cases:
        rel = path.relative_to(ROOT / "yaml_cases").as_posix()
        assert any(fnmatch.fnmatchcase(rel, g) and rel.count("/") == g.count("/")
                   for g in globs), f"{rel} is not package data"
    assert "py.typed" in _package_data()["nsm_continuation"]
    assert (ROOT / "nsm_continuation" / "py.typed").is_file()


def test_the_sdist_takes_what_its_tests_read() -> None:
    """MANIFEST.in: the tests with their oracles, the cases, the documents the snippet test
    reads, the licence and the changelog (an sdist whose tests can run)."""
    rules = [line.split() for line in (ROOT / "MANIFEST.in").read_text().splitlines()
             if line.strip() and not line.startswith("#")]
    recursive = {r[1]: r[2:] for r in rules if r[0] == "recursive-include"}
    included = {name for r in rules if r[0] == "include" for name in r[1:]}
    assert "*.py" in recursive["tests"]  # tests/oracles/*.py among them
    assert (ROOT / "tests" / "oracles" / "__init__.py").is_file()
    assert "*.yaml" in recursive["yaml_cases"]
    assert {"*.md", "*.png", "*.py"} <= set(recursive["docs"])  # the reference generator too
    assert {"LICENSE", "CHANGELOG.md", "CITATION.cff", "README.md"} <= included
    for name in included:
        assert (ROOT / name).is_file(), name


def test_one_version_one_licence() -> None:
    """The version is written once (``nsm_continuation.__version__``, read by setuptools) and
    CITATION.cff cites it; the licence is the SPDX expression the project declares, whose
    text is the LICENSE file."""
    import nsm_continuation

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {
        "attr": "nsm_continuation.__version__"}
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert str(cff["version"]) == nsm_continuation.__version__
    assert project["project"]["license"] == cff["license"] == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")
    assert project["project"]["license-files"] == ["LICENSE"]
    assert not any(c.startswith("License ::") for c in project["project"]["classifiers"])
    # the three papers are cited, by the DOIs and the HAL identifier their texts give
    refs = {r.get("doi") or r.get("url") for r in cff["references"]}
    assert refs == {"10.1016/j.cnsns.2016.08.022", "https://hal.science/hal-01471341",
                    "10.1007/s11071-008-9463-y"}


# ---------------------------------------------------------------------- cases by name
def test_a_bundled_case_is_found_by_its_name() -> None:
    found = bundled.cases()
    on_disk = {p.relative_to(ROOT / "yaml_cases").with_suffix("").as_posix(): p
               for p in (ROOT / "yaml_cases").rglob("*.yaml")}
    assert set(found) == set(on_disk)
    for name, path in found.items():
        assert path.read_bytes() == on_disk[name].read_bytes()
        stem = name.rsplit("/", 1)[-1]
        for spelling in (name, f"{name}.yaml", f"yaml_cases/{name}.yaml", stem):
            assert bundled.find(spelling) == path, spelling


def test_an_existing_path_wins_and_an_unknown_name_lists_close_ones(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    own = tmp_path / "ndof_default"
    own.write_text("name: mine\n")
    assert bundled.resolve("ndof_default") == Path("ndof_default")  # the user's file
    assert bundled.resolve("ndof_fig3_2_fep") == bundled.cases()["ndof_fig3_2_fep"]
    with pytest.raises(CaseError) as err:
        bundled.resolve("ndof_fig3_2_fap")
    msg = str(err.value)
    assert msg.startswith("case file: ndof_fig3_2_fap does not exist, and no bundled case")
    assert "ndof_fig3_2_fep" in msg and "\n" not in msg
    with pytest.raises(CaseError, match="nsm-continuation cases lists the bundled cases"):
        bundled.resolve("zzzzzz")


def test_a_case_is_run_by_name_from_an_empty_folder(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """``nsm-continuation run NAME`` and ``nsm.run(NAME)`` in a folder without
    ``yaml_cases/``: the bundled case, the same problem and start as its file says."""
    monkeypatch.chdir(tmp_path)
    over = ["--set", "continuation.max_points=12", "--set", "output.plots=false"]
    assert cli.main(["run", "ndof_default", *over, "--quiet"]) == 0
    rep = json.loads((tmp_path / "runs" / "ndof_default" / "report.json").read_text())
    case = yaml.safe_load((ROOT / "yaml_cases" / "ndof_default.yaml").read_text())
    assert rep["case"]["input"]["parameters"] == case["parameters"]
    assert rep["case"]["input"]["start"] == case["start"]
    # the README's spelling of the same case, from the API: the same points
    res = nsm.run("yaml_cases/ndof_default.yaml", {"continuation.max_points": 12,
                                                   "output.plots": False})
    with open(tmp_path / "runs" / "ndof_default" / "branch_0.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    saved = np.array([[float(r[f"y_{v}"]) for v in res.problem.variables] for r in rows])
    np.testing.assert_array_equal(res.branches[0].y, saved)


# ---------------------------------------------------------------------- the command line
def test_python_m_and_help_with_examples() -> None:
    out = subprocess.run([sys.executable, "-m", "nsm_continuation", "--help"],
                         capture_output=True, text=True, check=True).stdout
    assert "examples:" in out and "nsm-continuation run ndof_fig3_2_fep" in out
    version = subprocess.run([sys.executable, "-m", "nsm_continuation", "--version"],
                             capture_output=True, text=True, check=True).stdout
    import nsm_continuation

    assert version.split() == ["nsm-continuation", nsm_continuation.__version__]


def test_list_says_what_each_problem_is(capsys: pytest.CaptureFixture[str]) -> None:
    """One line per problem: its name and the first sentence of its class docstring (read
    here from the imported class: the command line reads the source without importing)."""
    import inspect
    import re

    assert cli.main(["list"]) == 0
    lines = dict(line.split(None, 1) for line in capsys.readouterr().out.splitlines())
    for name in registry.available():
        doc = " ".join(inspect.getdoc(registry.get(name)).split("\n\n")[0].split())
        first = re.split(r"(?<!\bal)\.\s+(?=[A-Z])", doc, maxsplit=1)[0].rstrip(".")
        assert lines[name] == (first if len(first) <= 90 else first[:86].rstrip() + " ...")
        assert ":" not in lines[name].split()[0]  # not a module:Class path
        assert len(lines[name]) <= 90


def test_cases_lists_and_copies_the_bundled_cases(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["cases"]) == 0
    out = capsys.readouterr().out
    names = [line.split()[0] for line in out.splitlines()[:-2]]
    assert names == list(bundled.cases())
    assert "Fig. 3.2" in next(line for line in out.splitlines()
                              if line.startswith("ndof_fig3_2_fep "))
    dest = tmp_path / "mine"
    assert cli.main(["cases", "--copy", str(dest)]) == 0
    for name, path in bundled.cases().items():
        assert (dest / f"{name}.yaml").read_bytes() == path.read_bytes()
    assert cli.main(["cases", "--copy", str(dest)]) == 2  # never over a file
    assert "exists" in capsys.readouterr().err


def test_tests_import_oracles_and_helpers_from_their_folder() -> None:
    """The console ``pytest`` (CI's) puts ``tests/`` on ``sys.path``, not the repository: a test
    importing ``tests.oracles...`` is not collected there (``conftest.py``)."""
    root = Path(__file__).resolve().parents[1]
    bad = [str(p.relative_to(root)) for p in root.rglob("*.py")
           if any(line.startswith(("from tests.", "import tests."))
                  for line in p.read_text().splitlines())]
    assert bad == []
