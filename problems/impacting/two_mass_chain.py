"""Two-mass chain hitting a wall: the worked example of ``docs/adding_an_impact_system.md``.

Mass ``m1`` (position ``q1``) hangs on a spring ``k1`` from a fixed base and is forced by
``F0 cos(omega t)``; mass ``m2`` (``q2``) is coupled to it by a spring ``k2``; both have viscous
damping ``c`` to the ground. ``m2`` hits a rigid wall at ``q2 = gap`` (admissible side
``H = gap - q2 >= 0``) with Newton's law ``q2dot+ = -e q2dot-`` (``e``: ``restitution``; the
old key ``e`` is deprecated). State
``x = (q1, q2, q1dot, q2dot, phase)`` with the clock ``phase = omega t`` (eq. 4); the Poincaré
section is the stroboscopic one, ``phase = 0 (mod 2 pi)``. Not a system of the paper: everything
but the equations of motion (``v, a, r, lambda, F'``, chatter map, Jacobians) is derived by
:mod:`nsm_continuation.hybrid`.
"""

from __future__ import annotations

from typing import ClassVar

import casadi as ca
import numpy as np
from pydantic import BaseModel, Field

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.vocabulary import CanonicalNames, CanonicalParameter
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.system import HybridSystem


class TwoMassChainParameters(CanonicalNames):
    """``parameters:`` of ``problem: two_mass_chain``."""

    model_config = STRICT
    deprecated_names = {"e": "restitution"}
    #: mass ``m1`` (on the spring ``k1`` to the fixed base, forced)
    m1: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: mass ``m2`` (the one that hits the wall)
    m2: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: stiffness ``k1`` of the spring from the base to ``m1``
    k1: float = Field(1.0, ge=0, allow_inf_nan=False)
    #: stiffness ``k2`` of the spring from ``m1`` to ``m2``
    k2: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: viscous damping ``c`` of both masses
    c: float = Field(0.05, ge=0, allow_inf_nan=False)
    #: amplitude ``F0`` of the force ``F0 cos(omega t)`` on ``m1``
    F0: float = Field(0.5, allow_inf_nan=False)
    #: forcing frequency ``omega``
    omega: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: the wall's position: ``q2 <= gap`` (``H = gap - q2 >= 0``)
    gap: float = Field(0.5, allow_inf_nan=False)
    #: coefficient of restitution ``e``: ``q2dot+ = -e q2dot-``
    restitution: float = Field(0.8, ge=0, lt=1, allow_inf_nan=False)
    #: the hybrid simulator's numerics (defaults as the speed-accuracy chart recommends)
    integrator: IntegratorSpec = IntegratorSpec()


class TwoMassChainProblem(CanonicalParameter, HybridCaseProblem):
    """Periodic orbits of a forced two-mass chain whose second mass hits a wall."""

    name: ClassVar[str] = "two_mass_chain"
    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    Parameters: ClassVar[type[BaseModel]] = TwoMassChainParameters
    default_parameter: ClassVar[str] = "omega"
    parameter_labels: ClassVar[dict[str, str]] = {
        "gap": "wall position (gap)", "c": "damping $c$", "F0": "forcing amplitude $F_0$"}

    def system(self) -> HybridSystem:
        q, qd, ph = ca.SX.sym("q", 2), ca.SX.sym("qd", 2), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k)
             for k in ("m1", "m2", "k1", "k2", "c", "F0", "omega", "gap", "restitution")}
        M = ca.diag(ca.vertcat(p["m1"], p["m2"]))
        spring = p["k2"] * (q[1] - q[0])
        force = ca.vertcat(-p["k1"] * q[0] + spring + p["F0"] * ca.cos(ph),
                           -spring) - p["c"] * qd
        return HybridSystem.mechanical("two_mass_chain", q, qd, p, M, force, p["gap"] - q[1],
                                       p["restitution"], clock=ph, clock_rate=p["omega"],
                                       state_names=["q1", "q2", "q1dot", "q2dot", "phase"])

    def section(self) -> Section:
        return Section(4, 0.0, 2 * np.pi)

    def default_initial(self) -> np.ndarray:
        return np.zeros(5)
