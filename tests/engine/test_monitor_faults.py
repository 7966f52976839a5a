"""A problem's monitors during a run: values the engine cannot use, and ``sys.exit`` in a hook.

* An admissibility test that is not finite (NaN, infinity, a string) decides nothing: the
  half-branch ends at that point with a reason naming the test and ``Problem.admissibility``
  (before, a NaN test silently made every later point inadmissible, their multipliers were
  dropped and no event was raised);
* Floquet multipliers that are not finite, or ``Problem.floquet`` returning something else than
  ``FloquetData``: the half-branch ends naming ``Problem.floquet`` (before, dropped without a
  word, the stability of the rest of the branch unknown);
* ``SystemExit`` raised in a hook (``sys.exit`` in a plugin) ends the half-branch, or the start,
  with a reason naming the problem, and never the process (before, the process exited with the
  plugin's code and no message).

Oracle: the circle ``x^2 + p^2 = 1`` continued from ``(1, 0)``; each hook misbehaves only where
``p > 0.5``, so the branch must run normally up to there (its points on the circle) and end at
the first point beyond.
"""

from __future__ import annotations

import sys
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from pydantic import BaseModel

import nsm_continuation as nsm
from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint


class Params(BaseModel):
    model_config = STRICT
    fault: str = ""


class Circle(Problem):
    name: ClassVar[str] = "faulty_circle"
    Parameters: ClassVar[type[BaseModel]] = Params

    def __init__(self, params: Any) -> None:
        super().__init__(Params.model_validate(params))
        self.variables, self.parameter = ["x", "p"], "p"
        self.fault = self.params.fault

    def residual(self, y: Any) -> Any:
        return ca.vertcat(y[0] ** 2 + y[1] ** 2 - 1.0)

    def start_points(self, start: Any, window: Any = (None, None)) -> list[StartPoint]:
        if self.fault == "exit_start":
            sys.exit(7)
        return [StartPoint(np.array([1.0, 0.0]), "circle", 1)]

    def _bad(self, y: np.ndarray, fault: str) -> bool:
        return self.fault == fault and y[1] > 0.5

    def admissibility(self, y: np.ndarray) -> dict[str, Any]:
        for fault, value in (("nan_test", np.nan), ("inf_test", -np.inf), ("str_test", "high")):
            if self._bad(y, fault):
                return {"margin": value}
        if self._bad(y, "exit_test"):
            sys.exit(3)
        return {"margin": 1.0 - float(y[1])}

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> Any:
        if self._bad(y, "nan_mu"):
            return FloquetData(np.array([np.nan, 0.5]))
        if self._bad(y, "inf_mu"):
            return FloquetData(np.array([0.1 + 0.0j, complex(np.inf, 1.0)]))
        if self._bad(y, "list_mu"):
            return [0.5, 0.2]
        if self._bad(y, "exit_mu"):
            raise SystemExit(0)
        return FloquetData(np.array([0.5, 0.2]))

    def derived(self, y: np.ndarray) -> dict[str, float]:
        if self._bad(y, "exit_derived"):
            sys.exit("bye")
        return {"p": float(y[1])}


def continued(fault: str) -> Any:
    return nsm.continuation(Circle({"fault": fault}), {}, parameter="p", min=-0.9, max=0.9,
                            max_points=100, step={"initial": 0.02, "max": 0.05})


@pytest.mark.parametrize(("fault", "words"), [
    ("nan_test", ["admissibility test (Problem.admissibility) 'margin' is nan"]),
    ("inf_test", ["admissibility test (Problem.admissibility) 'margin' is -inf"]),
    ("str_test", ["admissibility test (Problem.admissibility) 'margin' is 'high'"]),
    ("nan_mu", ["Floquet multipliers (Problem.floquet)", "are not finite: [nan, 0.5]"]),
    ("inf_mu", ["Floquet multipliers (Problem.floquet)", "are not finite"]),
    ("list_mu", ["Problem.floquet at p = ", "returned list, not FloquetData or None"]),
    ("exit_test", ["problem 'faulty_circle' raised SystemExit(3) in a hook"]),
    ("exit_mu", ["problem 'faulty_circle' raised SystemExit(0) in a hook"]),
    ("exit_derived", ["problem 'faulty_circle' raised SystemExit('bye') in a hook"]),
])
def test_a_monitor_fault_ends_the_branch_naming_it(fault: str, words: list[str]) -> None:
    res = continued(fault)
    (branch,) = res.branches
    reason = branch.termination["forward"]
    for w in words:
        assert w in reason, reason
    assert "\n" not in reason
    p = branch["p"]
    # the branch ran up to the fault, on the circle, and no further
    assert 0.45 < p.max() <= 0.5
    np.testing.assert_allclose(branch.y[:, 0] ** 2 + branch.y[:, 1] ** 2, 1.0, rtol=1e-9)
    if "exit" in fault or "test" in fault:
        return
    assert all(m is not None and np.all(np.isfinite(m)) for m in branch.multipliers)


def test_sys_exit_in_start_points_is_a_failed_start_not_an_exit() -> None:
    res = continued("exit_start")
    (branch,) = res.branches
    assert len(branch.parameter) == 0
    assert "problem 'faulty_circle' raised SystemExit(7) in a hook" in branch.termination["start"]


def test_a_well_behaved_circle_runs_through() -> None:
    """The same problem without a fault: the branch reaches the window's edge."""
    res = continued("")
    assert res.branches[0].termination["forward"] == "bound: p = max"
