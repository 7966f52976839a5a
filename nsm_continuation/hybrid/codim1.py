"""Two-parameter continuation of the grazing of a hybrid periodic orbit.

A grazing is a codimension-one condition on a periodic orbit: its closest approach to the
surface is zero, ``H_min = 0``. With two parameters ``(p, q)`` free, the grazing orbits form a
curve, the solution set of the augmented system

    G(z; p, q) = 0,      m(z; p, q) = margin,                                        (C1)

``G`` the shooting residual (:mod:`.shooting`) and ``m`` the signed grazing margin closest to
zero (``H_min`` of a near approach, :func:`.grazing.margin_gradient`), with its exact gradient
from the saltation-chained sensitivities of the same simulation. The curve sits exactly on the
kink of the return map; ``margin`` (default ``1e-9``, relative to ``1 + |y|``) keeps it on the
free side, where ``G`` is smooth: the continued orbits miss the surface by ``margin``, whose
closed form is that of the grazing orbit with the gap moved by ``margin`` (the margin is
documented and tested, not hidden: ``tests/test_grazing.py`` compares with the closed form
*including* it).

The unknowns are ``y = (z, p, q)``; ``q`` is the continuation parameter and ``p`` is solved
for. Like TC-HAT's and COCO's grazing curves (``coco`` ``'hspo'`` demos), but on the automatic
event sequence of the simulator rather than a prescribed segment sequence.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from ..protocol import EvaluationError, Problem
from .grazing import margin_gradient
from .shooting import HybridCaseProblem, HybridShooting, ShootingFailure


class GrazingCurve(Problem):
    """Grazing orbits of ``base`` with ``free`` solved for and ``parameter`` continued (C1)."""

    name: ClassVar[str] = "grazing_curve"
    #: the base problem's parameters are the curve's (its model is the base's)
    Parameters: ClassVar[type[BaseModel]] = BaseModel
    diagram_title: ClassVar[str] = "Grazing curve"

    def __init__(self, base: HybridCaseProblem, free: str, parameter: str,
                 margin: float = 1e-9) -> None:
        super().__init__(base.params)
        if free == parameter:
            raise ValueError(f"continuation.parameter: the grazing curve needs two parameters "
                             f"(free {free!r} and continued {parameter!r} are the same)")
        for key, name in (("free", free), ("parameter", parameter)):
            if name not in base.values:
                raise ValueError(f"{key}: {name!r} is not a parameter of {base.name!r} "
                                 f"(one of {sorted(base.values)})")
        self.base = base
        c = base.hybrid.compile(base.values, free=[free, parameter],
                                method=base.integrator.method)
        sec = base.section()
        self.shooting = HybridShooting(c, sec, base.integrator.options())
        names = base.hybrid.state_names
        self.variables = [names[i] for i in self.shooting.free_idx] + [free, parameter]
        self.parameter = parameter
        self.free = free
        self.margin = float(margin)

    def residual(self, y: Any) -> Any:  # pragma: no cover - numeric problem
        raise NotImplementedError("the grazing curve evaluates numerically")

    @property
    def compiled(self) -> Any:
        return None

    def target(self, y: np.ndarray) -> float:
        """The margin the continued orbits keep from the surface at ``y`` (C1)."""
        return self.margin * (1.0 + float(np.linalg.norm(y)))

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``[G; m - margin]`` and its exact Jacobian (C1)."""
        y = np.asarray(y, dtype=float)
        try:
            g, Gy = self.shooting.residual_jacobian(y)
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None
        mg = margin_gradient(self.shooting, y)
        if mg is None:
            raise EvaluationError("no near approach to the surface: the orbit is not near a "
                                  "grazing")
        m, dm = mg
        target = self.target(y)
        # d target / dy is margin * y / |y|: included so that the Jacobian is exact
        ny = float(np.linalg.norm(y))
        dt = self.margin * y / ny if ny > 0 else np.zeros_like(y)
        return np.append(g, m - target), np.vstack([Gy, dm - dt])

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[0]

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[1]

    def derived(self, y: np.ndarray) -> dict[str, float]:
        out = {self.free: float(y[-2]), self.parameter: float(y[-1])}
        try:
            res = self.shooting.simulate(np.asarray(y, dtype=float))
        except ShootingFailure:
            return out
        out["period"] = float(res.t)
        out["grazing_margin"] = res.grazing_function()
        return out

    def monitor_names(self) -> list[str]:
        return [self.free, self.parameter, "period", "grazing_margin"]

    @property
    def fep_axes(self) -> tuple[str, str]:
        return (self.parameter, self.free)

    @property
    def fep_labels(self) -> tuple[str, str]:
        return (self.parameter, f"{self.free} at the grazing")

    @property
    def csv_head(self) -> list[str]:
        return [self.parameter, self.free, "period", "grazing_margin"]


def grazing_curve_start(curve: GrazingCurve, y_grazing: np.ndarray) -> np.ndarray:
    """The curve's unknowns from a grazing orbit of the base problem (unknowns ``(z, p)`` with
    ``p`` = ``curve.free``): the continued parameter's value is the base problem's."""
    y = np.asarray(y_grazing, dtype=float)
    return np.append(y, curve.base.values[curve.parameter])
