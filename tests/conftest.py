"""Shared set-up of the test suite.

The tests live in folders named for the capability they check, none of them a package:

* ``engine/``: the continuation engine (steps, events, crossings, Krein windows and
  collisions, failures), its linear algebra (bordered systems, CasADi buffers);
* ``floquet/``: multipliers, their pairs and Krein signatures, the step control's distances;
* ``chain/``: the N-dof chain of Legrand, Junca, Heng (2017) and its paper's statements;
* ``bar/``: the WFEM bar (lattice, operators, time stepping, stability, forced response,
  continuum limit);
* ``hybrid/``: hybrid systems (simulator, saltation, grazing, sections, the double pendulum,
  the bouncing ball, the impact oscillator, brute force);
* ``cases/``: YAML cases (preflight, vocabulary, restart, branch switching, two-parameter
  curves, diagrams);
* ``runs/``: runs on Dask; ``output/``: output folders, reports and figures;
* ``interface/``: the command line, the Python API, the documents' snippets, start-up, the
  ``Problem`` contract, the previous layout's import paths, the pycont-lite adapter.

pytest imports this file first and puts its folder, ``tests/``, on ``sys.path``: every test
imports the independent derivations as ``oracles.<module>`` and the plain helpers as
``helpers`` (whose asserts pytest rewrites, as a test's). Shared fixtures are here and in the
``conftest.py`` of a folder.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

pytest.register_assert_rewrite("helpers")


@pytest.fixture()
def write_case(tmp_path: Path) -> Callable[..., Path]:
    """``write_case(case, name="case.yaml")``: the case (a dict, dumped as YAML, or the text
    of a file) written to ``tmp_path / name``; its path."""

    def write(case: dict[str, Any] | str, name: str = "case.yaml") -> Path:
        path = tmp_path / name
        path.write_text(case if isinstance(case, str) else yaml.safe_dump(case))
        return path

    return write


@pytest.fixture()
def fresh_registry() -> Any:
    """The problem registry's scan of the entry points forgotten before and after the test
    (:func:`nsm_continuation.cases.registry.refresh`): for a test that replaces
    ``registry.entry_points`` or edits a plugin's metadata in place, which the scan's key
    (``sys.path`` and its folders' modification times) does not see."""
    from nsm_continuation.cases import registry

    registry.refresh()
    yield registry
    registry.refresh()
