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

Where pytest-xdist is installed (the ``test`` extra installs it), a plain ``pytest`` runs the
suite on one worker process per core this process may use, each test file on one worker
(``--dist loadfile``: a module's fixtures are computed once), BLAS limited to one thread per
worker; ``-n N`` / ``--dist MODE`` choose otherwise, ``-p no:xdist`` (or ``-n 0``) runs it in
this process. Without pytest-xdist the suite runs in this process, as before.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

pytest.register_assert_rewrite("helpers")

#: the thread counts of the BLAS libraries numpy and scipy may load, pinned for the workers
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _cores() -> int:
    """The cores this process may run on (its affinity mask: taskset, a cgroup's cpuset)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # no affinity on this platform
        return os.cpu_count() or 1


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> None:
    """With pytest-xdist installed and no ``-n`` given: one worker per core, each test file
    on one worker. Before xdist's own hook (which turns ``numprocesses`` into worker
    processes); not in a worker (its options say ``dist = "no"``), not under ``--pdb`` or
    ``--collect-only``, not on one core. Workers inherit one BLAS thread each (N workers on
    N cores, not N x the BLAS threads; an explicit setting in the environment wins)."""
    if not config.pluginmanager.hasplugin("xdist") or hasattr(config, "workerinput"):
        return
    option = config.option
    if (option.numprocesses is None and not option.tx and not option.collectonly
            and not option.usepdb and _cores() > 1):
        option.numprocesses = _cores()
        if option.dist == "no":
            option.dist = "loadfile"
    if option.numprocesses:
        for name in BLAS_THREADS:
            os.environ.setdefault(name, "1")


def pytest_report_header(config: pytest.Config) -> str:
    """The header says how the suite runs: on workers (how many, which distribution) or here."""
    n = getattr(config.option, "numprocesses", None)
    if n:
        return f"workers: {n} (pytest-xdist, --dist {config.option.dist})"
    if importlib.util.find_spec("xdist") is None:
        return ("workers: none, every test runs in this process (pytest-xdist is not "
                "installed; `pip install -e \".[test]\"` installs it: one worker per core)")
    return "workers: none, every test runs in this process"


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
