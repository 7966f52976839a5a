"""Periodically forced 1-dof impact oscillator between two symmetric stops.

``qdd + 2 zeta qd + q = cos(omega t)``, ``-d <= q <= d`` (``d``: ``clearance``), Newton's law
``qd+ = -e qd-`` at both stops (``e``: ``restitution``). State ``x = (q, qd, phase)`` with
``phase = omega t`` (Nordmark & Piiroinen 2009, eq. 4). The system is equivariant under
``(q, qd, phase) -> (-q, -qd, phase + pi)``; its symmetric period-1 orbit with one impact on each
stop per forcing period, half a period apart, is known in closed form
(``tests/oracles/two_wall.py``: phase (T6), impact velocity (T7), folds (T8), the end where the
impact velocity vanishes (T9), multipliers from the half map (T12)). Being a 2-dimensional map
with determinant ``e^4 exp(-2 zeta T) < 1``, the symmetric orbit loses stability only at folds and
symmetry-breaking pitchforks (no period doubling, no Neimark-Sacker).

``encoding`` says how the two stops are declared (:mod:`.two_walls`, with ``z = q`` and
``w = d``): two unilateral constraints ``d - q >= 0`` and ``d + q >= 0`` (``surfaces``, the
default) or one smooth constraint ``d^2 - q^2 >= 0`` (``single``). The Poincaré section is the
stroboscopic one, ``phase = section_phase`` (mod ``2 pi``).
"""

from __future__ import annotations

from typing import ClassVar, Literal

import casadi as ca
import numpy as np
from nsm_continuation.problems.impacting.two_walls import TwoWallForcedProblem
from pydantic import BaseModel, Field

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.hybrid.case import IntegratorSpec
from nsm_continuation.hybrid.system import HybridSystem


class TwoSidedOscillatorParameters(BaseModel):
    """``parameters:`` of ``problem: two_sided_oscillator``."""

    model_config = STRICT
    #: damping ratio ``zeta`` (``2 zeta qd`` in the equation of motion)
    zeta: float = Field(0.05, ge=0, allow_inf_nan=False)
    #: forcing frequency ``omega`` of ``cos(omega t)``
    omega: float = Field(2.0, gt=0, allow_inf_nan=False)
    #: the stops are at ``q = +clearance`` and ``q = -clearance``
    clearance: float = Field(0.5, gt=0, allow_inf_nan=False)
    #: coefficient of restitution (``e``) at both stops
    restitution: float = Field(0.6, ge=0, lt=1, allow_inf_nan=False)
    #: forcing phase of the stroboscopic section (``phase = section_phase`` mod ``2 pi``)
    section_phase: float = Field(0.0, ge=0, lt=2 * np.pi, allow_inf_nan=False)
    #: the hybrid simulator's numerics (defaults as the speed-accuracy chart recommends)
    integrator: IntegratorSpec = IntegratorSpec()
    #: two constraints (``surfaces``) or one whose zero set is both stops (``single``)
    encoding: Literal["surfaces", "single"] = "surfaces"


class TwoSidedOscillatorProblem(TwoWallForcedProblem):
    """Periodic orbits of the forced oscillator between two symmetric stops."""

    name: ClassVar[str] = "two_sided_oscillator"
    Parameters: ClassVar[type[BaseModel]] = TwoSidedOscillatorParameters
    phase_index: ClassVar[int] = 2
    orbit_views: ClassVar[dict[str, tuple[str, ...]] | None] = {
        "time": ("q",), "phase": ("q", "qdot"), "manifold": ("q", "qdot", "phase")}
    parameter_labels: ClassVar[dict[str, str]] = {
        "clearance": "clearance $d$ (stops at $q = \\pm d$)", "zeta": r"damping ratio $\zeta$"}

    def system(self) -> HybridSystem:
        q, qd, ph = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("zeta", "omega", "clearance", "restitution")}
        force = -q - 2 * p["zeta"] * qd + ca.cos(ph)
        d, e = p["clearance"], p["restitution"]
        return self.between_walls("two_sided_oscillator", q, qd, p, ca.SX(1.0), force, q, d, e,
                                  clock=ph, clock_rate=p["omega"],
                                  state_names=["q", "qdot", "phase"])

    def default_initial(self) -> np.ndarray:
        """At rest in the middle of the gap."""
        return np.array([0.0, 0.0, self.section().value])
