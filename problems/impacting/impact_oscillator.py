"""Periodically forced 1-dof linear impact oscillator (Nordmark & Piiroinen 2009, sec. 2.2.1).

``qdd + 2 zeta qd + q = cos(omega t)``, ``q >= sigma``, ``qd+ = -e qd-`` at ``q = sigma``; the
parameters are ``gap`` (``sigma`` in Nordmark & Piiroinen sec. 2.2.1: the position of the stop,
so the rest position ``q = 0`` is clear of it for ``gap < 0``) and ``restitution`` (``e``); the
old keys ``sigma`` and ``e`` are deprecated. State
``x = (q, qd, phase)`` with ``phase = omega t`` (eq. 4); ``H = q - sigma``; ``W = (0, -(1 + e), 0)``
(sec. 2.5.1), so ``r = e``. Fig. 2 (zeta = 0.1, omega = 1, sigma = 0, e = 0.6): orbits enter
sticking through complete chattering (or, exceptionally, without impact through Sigma_3^-) and
leave it at ``Sigma_3^+ = (0, 0, 3 pi / 2)`` where ``a = -q - 2 zeta qd + cos(phase)`` rises
through 0.

The Poincaré section is the stroboscopic one, ``phase = section_phase`` (default 0), mod
``2 pi m`` for a period-``m`` orbit (``start.returns``).
"""

from __future__ import annotations

from typing import ClassVar

import casadi as ca
import numpy as np
from nsm_continuation.problems.impacting.impact_oscillator_closed_form import (
    ImpactOscillatorPresentation,
)
from pydantic import BaseModel, Field

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.vocabulary import CanonicalNames, CanonicalParameter
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.system import HybridSystem


class ImpactOscillatorParameters(CanonicalNames):
    """``parameters:`` of ``problem: impact_oscillator`` (defaults: Fig. 2)."""

    model_config = STRICT
    deprecated_names = {"sigma": "gap", "e": "restitution"}
    #: damping ratio ``zeta`` (``2 zeta qd`` in the equation of motion)
    zeta: float = Field(0.1, ge=0, allow_inf_nan=False)
    #: forcing frequency ``omega`` of ``cos(omega t)``
    omega: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: the stop's position, ``q >= gap`` (``sigma`` in Nordmark & Piiroinen sec. 2.2.1)
    gap: float = Field(0.0, allow_inf_nan=False)
    #: coefficient of restitution (``e``)
    restitution: float = Field(0.6, ge=0, lt=1, allow_inf_nan=False)
    #: forcing phase of the stroboscopic section (``phase = section_phase`` mod ``2 pi``): move
    #: it away from a phase where the orbit grazes (for omega > 1 the free orbit's minimum is at
    #: phase 0, where a section would sit on the grazing point)
    section_phase: float = Field(0.0, ge=0, lt=2 * np.pi, allow_inf_nan=False)
    #: the hybrid simulator's numerics (defaults as the speed-accuracy chart recommends)
    integrator: IntegratorSpec = IntegratorSpec()


class ImpactOscillatorProblem(CanonicalParameter, HybridCaseProblem):
    """Forced 1-dof impact oscillator, chattering and sticking (Nordmark, Piiroinen 2009).
    Its periodic orbits (sec. 2.2)."""

    name: ClassVar[str] = "impact_oscillator"
    presentation_class = ImpactOscillatorPresentation
    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    Parameters: ClassVar[type[BaseModel]] = ImpactOscillatorParameters
    default_parameter: ClassVar[str] = "omega"
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "section_phase")
    #: orbit figures in the state ``x = (q, qdot, phase)`` of Fig. 2 (``x_3 = omega t``, eq. 4)
    orbit_views: ClassVar[dict[str, tuple[str, ...]] | None] = {
        "time": ("q",), "phase": ("q", "qdot"), "manifold": ("q", "qdot", "phase")}
    orbit_labels: ClassVar[dict[str, str]] = {
        "q": r"$x_1 = q$", "qdot": r"$x_2 = \dot q$", "phase": r"$x_3 = \omega t$"}
    parameter_labels: ClassVar[dict[str, str]] = {
        "omega": r"forcing frequency $\omega$", "gap": r"stop position $\sigma$ (gap)",
        "restitution": "restitution $e$", "zeta": r"damping ratio $\zeta$"}

    def system(self) -> HybridSystem:
        q, qd, ph = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("zeta", "omega", "gap", "restitution")}
        force = -q - 2 * p["zeta"] * qd + ca.cos(ph)
        return HybridSystem.mechanical("impact_oscillator", q, qd, p, ca.SX(1.0), force,
                                       q - p["gap"], p["restitution"], clock=ph,
                                       clock_rate=p["omega"],
                                       state_names=["q", "qdot", "phase"])

    def section(self) -> Section:
        return Section(2, self.params.section_phase, 2 * np.pi)  # type: ignore[attr-defined]

    def default_initial(self) -> np.ndarray:
        return np.array([self.values["gap"] + 1.0, 0.0, self.section().value])
