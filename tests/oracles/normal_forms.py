"""Closed-form normal forms of branch points, as test problems (shared by the switching and
diagram tests): the transcritical ``x (mu - x) = 0`` and the pitchfork ``x (mu - x^2) = 0``."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from nsm_continuation.preflight import STRICT
from nsm_continuation.protocol import Problem, StartPoint


class MuParameters(BaseModel):
    model_config = STRICT
    mu0: float = -0.5


class Transcritical(Problem):
    """``G(x, mu) = x (mu - x)``: the trivial branch and ``x = mu`` cross at the origin."""

    name: ClassVar[str] = "test_transcritical"
    Parameters: ClassVar[type[BaseModel]] = MuParameters

    def __init__(self, params: BaseModel) -> None:
        super().__init__(params)
        self.variables = ["x", "mu"]
        self.parameter = "mu"

    def residual(self, y: Any) -> Any:
        return y[0] * (y[1] - y[0])

    def start_points(self, start: Any, window: Any = (None, None)) -> list[StartPoint]:
        return [StartPoint(np.array([0.0, self.params.mu0]), "trivial", 1)]


class Pitchfork(Transcritical):
    """``G(x, mu) = x (mu - x^2)``: the branch ``mu = x^2`` leaves the trivial one at 0."""

    name: ClassVar[str] = "test_pitchfork"

    def residual(self, y: Any) -> Any:
        return y[0] * (y[1] - y[0] ** 2)
