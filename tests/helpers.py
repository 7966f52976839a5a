"""Plain helpers shared by the tests, imported as ``helpers`` (``tests/`` is on ``sys.path``:
see ``tests/conftest.py``): where the repository's files are, a fresh interpreter, the
distance of two multisets of multipliers, the orbit of a conservative family at a frequency,
and the empty parameter model of toy problems.

Fixtures are in ``tests/conftest.py`` and in the ``conftest.py`` of each folder."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel
from scipy.optimize import linear_sum_assignment

#: the repository's root (the tests read its bundled cases, documents and sources)
ROOT = Path(__file__).resolve().parents[1]
#: the bundled YAML cases
CASES = ROOT / "yaml_cases"
#: the package's sources
PACKAGE = ROOT / "nsm_continuation"


def run_fresh(code: str, cwd: Path) -> str:
    """Run ``code`` in a fresh interpreter (no thread but the main one: this test process may
    hold Dask's, which turn the fork off, and has long imported everything); its stdout. The
    interpreter must exit with status 0."""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=cwd, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def msd(x: np.ndarray, y: np.ndarray) -> float:
    """Largest distance of an optimal pairing of two multisets of complex numbers."""
    cost = np.abs(np.asarray(x)[:, None] - np.asarray(y)[None, :])
    r, c = linear_sum_assignment(cost)
    return float(cost[r, c].max())


def family_orbit(pb: Any, omega: float) -> tuple[np.ndarray, np.ndarray, Any]:
    """The orbit of a conservative family (a ``ConservativeFamilyProblem``) at ``omega``:
    Newton in ``(z, beta)`` from the problem's start at that frequency, its tangent along the
    family and its Floquet data."""
    (sp,) = pb.start_points({"omega": omega})
    y = np.asarray(sp.y, dtype=float).copy()
    for _ in range(6):
        g, A = pb.evaluate_with_jacobian(y)
        dy = np.linalg.solve(A[:, :-1], -g)
        y[:-1] += dy
        if np.max(np.abs(dy)) < 1e-13:
            break
    _, A = pb.evaluate_with_jacobian(y)
    tangent = np.linalg.svd(A)[2][-1]
    return y, tangent, pb.floquet(y, tangent)


class NoParameters(BaseModel):
    """The parameters of a toy problem that has none."""

