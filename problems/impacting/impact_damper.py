"""Impact damper (Masri & Caughey 1966): a forced primary mass with a free ball in a cavity.

The primary (mass 1, position ``x``) on a spring 1 with viscous damping ``2 zeta`` is forced by
``cos(omega t)``; a ball of mass ``mu`` (``mass_ratio``, position ``y``) moves freely inside a
cavity of the primary of clearance ``d`` (``clearance``): the relative position ``z = y - x``
satisfies ``|z| <= d/2``. Impacts conserve momentum ``x' + mu y'`` and reverse the relative
velocity with restitution ``e`` (``restitution``): ``z'+ = -e z'-``, which is Newton's law
``N^T qd+ = -e N^T qd-`` with the mass matrix ``diag(1, mu)`` (Nordmark & Piiroinen 2009, eqs.
54-59). State ``x = (x, y, xdot, ydot, phase)``, ``phase = omega t``.

The system is equivariant under ``(x, y, xdot, ydot, phase) -> (-x, -y, -xdot, -ydot,
phase + pi)``; the symmetric motion with one impact on each wall per forcing period, half a
period apart, is known in closed form (``tests/oracles/two_wall.py``, (T5)-(T13)); its impact
velocity vanishes where the primary's forced response has amplitude ``d/2`` (T9):
``omega = sqrt(1 + 2/d)`` undamped, ``sqrt(3)`` for ``d = 1`` whatever ``mu`` and ``e``.

``encoding`` says how the two walls are declared (:mod:`.two_walls`, with ``z = y - x`` and
``w = d/2``): two unilateral constraints ``d/2 - (y - x) >= 0`` and ``d/2 + (y - x) >= 0``
(``surfaces``, the default) or one smooth constraint ``d^2/4 - (y - x)^2 >= 0`` (``single``).
The Poincaré section is the stroboscopic one, ``phase = section_phase`` (mod ``2 pi``).
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


class ImpactDamperParameters(BaseModel):
    """``parameters:`` of ``problem: impact_damper``."""

    model_config = STRICT
    #: damping ratio ``zeta`` (``2 zeta qd`` in the equation of motion)
    zeta: float = Field(0.0, ge=0, allow_inf_nan=False)
    #: forcing frequency ``omega`` of ``cos(omega t)``
    omega: float = Field(2.0, gt=0, allow_inf_nan=False)
    #: the ball's mass over the primary's (``mu``)
    mass_ratio: float = Field(0.2, gt=0, allow_inf_nan=False)
    #: the cavity's clearance ``d``: ``|y - x| <= d/2``
    clearance: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: coefficient of restitution (``e``) of the relative velocity at both walls
    restitution: float = Field(0.6, ge=0, lt=1, allow_inf_nan=False)
    #: forcing phase of the stroboscopic section (``phase = section_phase`` mod ``2 pi``)
    section_phase: float = Field(0.0, ge=0, lt=2 * np.pi, allow_inf_nan=False)
    #: the hybrid simulator's numerics (defaults as the speed-accuracy chart recommends)
    integrator: IntegratorSpec = IntegratorSpec()
    #: two constraints (``surfaces``) or one whose zero set is both walls (``single``)
    encoding: Literal["surfaces", "single"] = "surfaces"


class ImpactDamperProblem(TwoWallForcedProblem):
    """Periodic motions of a forced primary mass with a free ball in a cavity."""

    name: ClassVar[str] = "impact_damper"
    Parameters: ClassVar[type[BaseModel]] = ImpactDamperParameters
    phase_index: ClassVar[int] = 4
    orbit_views: ClassVar[dict[str, tuple[str, ...]] | None] = {
        "time": ("x", "y"), "phase": ("x", "xdot"), "manifold": ("x", "y", "phase")}
    parameter_labels: ClassVar[dict[str, str]] = {
        "clearance": "clearance $d$", "mass_ratio": r"mass ratio $\mu$",
        "zeta": r"damping ratio $\zeta$"}

    def system(self) -> HybridSystem:
        q, qd, ph = ca.SX.sym("q", 2), ca.SX.sym("qd", 2), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k)
             for k in ("zeta", "omega", "mass_ratio", "clearance", "restitution")}
        M = ca.diag(ca.vertcat(1, p["mass_ratio"]))
        force = ca.vertcat(-q[0] - 2 * p["zeta"] * qd[0] + ca.cos(ph), 0)
        z, w, e = q[1] - q[0], p["clearance"] / 2, p["restitution"]
        return self.between_walls("impact_damper", q, qd, p, M, force, z, w, e, clock=ph,
                                  clock_rate=p["omega"],
                                  state_names=["x", "y", "xdot", "ydot", "phase"])

    def default_initial(self) -> np.ndarray:
        """The primary at rest, the ball in the middle of the cavity moving at unit speed
        (at rest there it would never touch a wall of a primary moving less than ``d/2``)."""
        return np.array([0.0, 0.0, 0.0, 1.0, self.section().value])
