"""The Stuart-Landau oscillator: a smooth system (no contact) declared through the hybrid layer.

``x' = mu x - y - x (x^2 + y^2)``, ``y' = x + mu y - y (x^2 + y^2)`` (the normal form of a
supercritical Hopf bifurcation, in Cartesian form). For ``mu > 0`` its periodic orbit is the
circle of radius ``sqrt(mu)``, of period ``2 pi`` (polar form ``r' = r (mu - r^2)``,
``theta' = 1``), with the nontrivial Floquet multiplier ``exp(-4 pi mu)`` (``d r'/d r = -2 mu``
on it, over ``2 pi``); it is born at ``mu = 0`` from the equilibrium at the origin.

The first check of a continuation tool on a smooth system, and the worked example of a system
without contact in ``docs/adding_an_impact_system.md``: :meth:`HybridSystem.smooth
<nsm_continuation.hybrid.system.HybridSystem.smooth>` (no surface) and a
:class:`~nsm_continuation.hybrid.return_map.CrossingSection` (the section ``x = 0`` crossed with
``x`` rising, ``crossing = +1``, where ``y = -sqrt(mu)``; ``crossing = -1`` takes the other
crossing, ``y = +sqrt(mu)``). Not registered as a plugin (it is continued from Python; register
it in your own package for YAML cases).
"""

from __future__ import annotations

from typing import ClassVar, Literal

import casadi as ca
import numpy as np
from pydantic import BaseModel, Field

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.hybrid.case import CrossingSection, HybridCaseProblem, IntegratorSpec
from nsm_continuation.hybrid.system import HybridSystem


class StuartLandauParameters(BaseModel):
    """``parameters:`` of the Stuart-Landau oscillator."""

    model_config = STRICT
    #: the distance past the Hopf point (periodic orbits for ``mu > 0``)
    mu: float = Field(0.1, allow_inf_nan=False)
    #: the direction the section ``x = 0`` is crossed in (+1: ``x`` rising, at ``y < 0``)
    crossing: Literal[-1, 1] = 1
    integrator: IntegratorSpec = IntegratorSpec()


class StuartLandauProblem(HybridCaseProblem):
    """The Stuart-Landau oscillator in Cartesian form (see the module docstring)."""

    name: ClassVar[str] = "stuart_landau"
    Parameters: ClassVar[type[BaseModel]] = StuartLandauParameters
    default_parameter: ClassVar[str] = "mu"
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "crossing")

    def system(self) -> HybridSystem:
        x, y, mu = ca.SX.sym("x"), ca.SX.sym("y"), ca.SX.sym("mu")
        r2 = x ** 2 + y ** 2
        F = ca.vertcat(mu * x - y - x * r2, x + mu * y - y * r2)
        return HybridSystem.smooth("stuart_landau", ca.vertcat(x, y), {"mu": mu}, F,
                                   ["x", "y"])

    def section(self) -> CrossingSection:            # x = 0, crossed in `crossing`
        return CrossingSection(0, 0.0, 0.0, crossing=self.params.crossing)  # type: ignore[attr-defined]

    def default_initial(self) -> np.ndarray:         # off the origin, on the section
        return np.array([0.0, -0.5 * self.params.crossing])  # type: ignore[attr-defined]
