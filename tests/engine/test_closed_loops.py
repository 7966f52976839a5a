"""Closed branches (:mod:`nsm_continuation.core.palc.loops`): a branch that returns to its start
ends there, walked once in one direction only, its events once each; one that only passes
near its start goes on.

Oracles: the circle ``x^2 + p^2 = 1`` (circumference ``2 pi``, folds at ``p = +-1``) and the
helix ``(cos kz, z, sin kz)``, which returns above its start at the distance ``2 pi / k`` in
``z`` after each turn and never to the start itself.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import NoParameters
from pydantic import BaseModel

from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import CLOSED_LOOP
from nsm_continuation.core.settings import ContinuationSettings


class Circle(Problem):
    """x^2 + p^2 = 1: a closed branch with folds (limit points in p) at (0, +-1)."""

    name: ClassVar[str] = "loop_circle"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"

    def residual(self, y: Any) -> Any:
        return y[0] ** 2 + y[1] ** 2 - 1


class Helix(Problem):
    """x = cos(k z), p = sin(k z): over the (x, p) circle, but ``2 pi / k`` higher in z after
    each turn (its folds in p repeat on every turn)."""

    name: ClassVar[str] = "loop_helix"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, pitch: float) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "z", "p"]
        self.parameter = "p"
        self.k = 2 * np.pi / pitch

    def residual(self, y: Any) -> Any:
        return ca.vertcat(y[0] - ca.cos(self.k * y[1]), y[2] - ca.sin(self.k * y[1]))


def _run(problem: Problem, y0: list[float], direction: int = 0, **kw: Any):
    settings = ContinuationSettings(**{"step_initial": 0.05, "step_max": 0.1,
                                       "max_points": 400, **kw})
    return ContinuationEngine(problem, settings).run(
        StartPoint(np.array(y0, float), "t", direction))


def _turned(points: list) -> float:
    """The angle the points of a circle branch turn through, in order."""
    angle = np.unwrap([np.arctan2(p.y[1], p.y[0]) for p in points])
    return float(angle[-1] - angle[0])


@pytest.mark.parametrize("direction", [0, 1, -1])
def test_circle_closes_after_one_round_with_each_fold_once(direction):
    br = _run(Circle(), [1.0, 0.0], direction)
    assert list(br.termination) == ["forward"], br.termination  # no second walk the other way
    reason = br.termination["forward"]
    assert reason.startswith(f"{CLOSED_LOOP}: the branch returned to its start after "), reason
    # once round: the angle turns through 2 pi, the last point is the start
    assert abs(abs(_turned(br.points)) - 2 * np.pi) < 1e-9
    assert np.linalg.norm(br.points[-1].y - br.points[0].y) < 1e-9
    assert abs(abs(br.points[-1].s - br.points[0].s) - 2 * np.pi) < 0.01 * 2 * np.pi
    assert all(abs(p.y[0] ** 2 + p.y[1] ** 2 - 1) < 1e-10 for p in br.points)
    folds = sorted(e.point.y[1] for e in br.events if e.kind == "fold")
    assert len(folds) == 2 and abs(folds[0] + 1) < 1e-12 and abs(folds[1] - 1) < 1e-12, folds
    ends = [e for e in br.events if e.kind == "endpoint"]
    assert len(ends) == 1 and ends[0].point is br.points[-1]
    assert len(br.points) < 200


def test_backward_half_meets_the_forward_end_instead_of_walking_the_loop_again():
    """The forward half stops short of a round (``max_points``): the backward half walks the
    rest of the loop the other way and ends where the forward half ended, so the two together
    cover the circle once."""
    br = _run(Circle(), [1.0, 0.0], 0, max_points=40)
    assert br.termination["forward"] == "max_points"
    assert br.termination["backward"].startswith(
        f"{CLOSED_LOOP}: the branch met the end of its other half"), br.termination
    assert abs(abs(_turned(br.points)) - 2 * np.pi) < 1e-9
    assert np.linalg.norm(br.points[-1].y - br.points[0].y) < 1e-9
    folds = sorted(e.point.y[1] for e in br.events if e.kind == "fold")
    assert len(folds) == 2 and abs(folds[0] + 1) < 1e-12 and abs(folds[1] - 1) < 1e-12, folds


@pytest.mark.parametrize("pitch", [0.05, 1e-5])
def test_a_branch_passing_near_its_start_goes_on(pitch):
    """The helix passes above its start ``pitch`` away in z after each turn (within a step,
    and within 1e-5): not closed, it goes round again, its folds repeated, until max_points."""
    max_points = 300
    br = _run(Helix(pitch), [1.0, 0.0, 0.0], 1, max_points=max_points)
    assert br.termination == {"forward": "max_points"}
    z = np.array([p.y[1] for p in br.points])
    assert z[-1] - z[0] > 1.5 * pitch  # more than one turn, and each turn is pitch higher
    folds = [e for e in br.events if e.kind == "fold"]
    assert len(folds) > 2
