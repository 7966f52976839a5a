"""The wheel holds every subpackage: ``pyproject.toml`` lists its packages explicitly (with
``problems/`` mapped to ``nsm_continuation.problems``), so a folder of modules that is not
listed would be missing after ``pip install .`` while an editable install still finds it."""

from __future__ import annotations

import tomllib

from helpers import ROOT


def test_every_package_folder_is_listed_in_pyproject() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = set()
    for top, prefix in (("nsm_continuation", "nsm_continuation"),
                        ("problems", "nsm_continuation.problems")):
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / top).parts
            found.add(".".join((prefix, *rel)))
    assert found == listed
