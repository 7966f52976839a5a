"""Closed-form test problems shared by the switching and diagram tests: the normal forms of
branch points (transcritical ``x (mu - x) = 0``, pitchfork ``x (mu - x^2) = 0``) and the
logistic map's period-k points (a period-doubling cascade with known values)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint


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


class TwoTranscriticals(Transcritical):
    """``G(x, mu) = x (mu - x) (1 - mu - x)``: the trivial branch meets ``x = mu`` at
    ``mu = 0`` and ``x = 1 - mu`` at ``mu = 1``, and those two cross at ``(1/2, 1/2)``: a
    diagram with two switches in its first generation and a point reached from both in its
    second."""

    name: ClassVar[str] = "test_two_transcriticals"

    def residual(self, y: Any) -> Any:
        return y[0] * (y[1] - y[0]) * (1 - y[1] - y[0])


class LogisticParameters(BaseModel):
    model_config = STRICT
    r: float = 2.8


class LogisticMap(Problem):
    """Period-``k`` points of the logistic map ``f(x) = r x (1 - x)``: ``f^k(x) - x = 0``. It
    declares the switching hooks itself (:meth:`Problem.period_multiple`,
    :meth:`Problem.iterated`) and its multiplier ``(f^k)'(x)``. Closed forms: the fixed point
    ``1 - 1/r`` doubles at ``r = 3`` into ``x = (r + 1 +- sqrt((r - 3)(r + 1))) / (2 r)``, which
    doubles at ``r = 1 + sqrt(6)``."""

    name: ClassVar[str] = "test_logistic"
    Parameters: ClassVar[type[BaseModel]] = LogisticParameters

    def __init__(self, params: BaseModel, k: int = 1) -> None:
        super().__init__(params)
        self.k = k
        self.variables = ["x", "r"]
        self.parameter = "r"

    def _fk(self, x: Any, r: Any) -> Any:
        for _ in range(self.k):
            x = r * x * (1 - x)
        return x

    def residual(self, y: Any) -> Any:
        return self._fk(y[0], y[1]) - y[0]

    def period_multiple(self) -> int:
        return self.k

    def iterated(self, multiple: int) -> Problem | None:
        return LogisticMap(self.params, multiple)

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> Any:
        x, r, d = float(y[0]), float(y[1]), 1.0
        for _ in range(self.k):
            d *= r * (1 - 2 * x)
            x = r * x * (1 - x)
        return FloquetData(np.array([d]))

    def start_points(self, start: Any, window: Any = (None, None)) -> list[StartPoint]:
        r = self.params.r
        return [StartPoint(np.array([1 - 1 / r, r]), "fixed point", 1)]
