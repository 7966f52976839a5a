"""Periodically forced 1-dof linear impact oscillator (Nordmark & Piiroinen 2009, sec. 2.2.1).

``qdd + 2 zeta qd + q = cos(omega t)``, ``q >= sigma``, ``qd+ = -e qd-`` at ``q = sigma``. State
``x = (q, qd, phase)`` with ``phase = omega t`` (eq. 4); ``H = q - sigma``; ``W = (0, -(1 + e), 0)``
(sec. 2.5.1), so ``r = e``. Fig. 2 (zeta = 0.1, omega = 1, sigma = 0, e = 0.6): orbits enter
sticking through complete chattering (or, exceptionally, without impact through Sigma_3^-) and
leave it at ``Sigma_3^+ = (0, 0, 3 pi / 2)`` where ``a = -q - 2 zeta qd + cos(phase)`` rises
through 0.

The Poincaré section is the stroboscopic one, ``phase = 0`` (mod ``2 pi m`` for a period-``m``
orbit: ``start.returns``).
"""

from __future__ import annotations

from typing import ClassVar

import casadi as ca
import numpy as np
from pydantic import BaseModel, Field

from nsm_continuation.hybrid.shooting import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.system import HybridSystem
from nsm_continuation.preflight import STRICT


class ImpactOscillatorParameters(BaseModel):
    """``parameters:`` of ``problem: impact_oscillator`` (defaults: Fig. 2)."""

    model_config = STRICT
    zeta: float = Field(0.1, ge=0, allow_inf_nan=False)
    omega: float = Field(1.0, gt=0, allow_inf_nan=False)
    sigma: float = Field(0.0, allow_inf_nan=False)
    e: float = Field(0.6, ge=0, lt=1, allow_inf_nan=False)
    integrator: IntegratorSpec = IntegratorSpec()


class ImpactOscillatorProblem(HybridCaseProblem):
    """Periodic orbits (with chattering and sticking) of the forced impact oscillator."""

    name: ClassVar[str] = "impact_oscillator"
    Parameters: ClassVar[type[BaseModel]] = ImpactOscillatorParameters
    default_parameter: ClassVar[str] = "omega"

    def system(self) -> HybridSystem:
        q, qd, ph = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("zeta", "omega", "sigma", "e")}
        force = -q - 2 * p["zeta"] * qd + ca.cos(ph)
        return HybridSystem.mechanical("impact_oscillator", q, qd, p, ca.SX(1.0), force,
                                       q - p["sigma"], p["e"], clock=ph, clock_rate=p["omega"],
                                       state_names=["q", "qdot", "phase"])

    def section(self) -> Section:
        return Section(2, 0.0, 2 * np.pi)

    def default_initial(self) -> np.ndarray:
        return np.array([self.values["sigma"] + 1.0, 0.0, 0.0])
