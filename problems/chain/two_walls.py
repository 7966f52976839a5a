"""The chain of Legrand, Junca, Heng (2017) with two contacts: its impacting dof between two
walls (``problem: ndof_two_walls``).

``M u'' + K u = 0`` between impacts (the chain of eq. 2.17, :class:`.parameters.ChainSpec`), the
impacting dof ``c`` confined to ``-g_l <= u_c <= g`` by two rigid walls, two unilateral
constraints ``H_upper = g - u_c >= 0`` and ``H_lower = u_c + g_l >= 0`` each with Newton's law
and ``e = 1`` (eq. 2.5e at both walls), declared through the hybrid layer
(:meth:`~nsm_continuation.hybrid.system.HybridSystem.mechanical` with two surfaces) and continued
as a conservative family (:class:`~nsm_continuation.hybrid.conservative_family.
ConservativeFamilyProblem`: the unfolding ``M u'' + K u = beta M u'`` that vanishes on every
orbit, shooting on the section ``u_c = section_value`` crossed falling (default ``gap / 2``),
the energy ``E = (u'^T M u' + u^T K u) / 2``). Paper 000 names this configuration beyond its
reach: one impact per period on one wall is its assumption throughout.

**The section.** A section between the walls turns tangent to the flow where a turn of ``u_c``
inside the period reaches its value (on mode 2 the interior maximum grown from the inflection
at ``T/4`` reaches ``u_c = gap / 2`` at omega = 5.8870): the return map jumps there, though the
family goes on. Where a turn comes within ``SECTION_MARGIN`` of the section's value the section
moves to the impacts on the upper wall (:meth:`impact_section`,
:mod:`~nsm_continuation.hybrid.conservative_charts`), transversal to the flow as long as the
orbit hits that wall with a nonzero velocity: the family is followed to its own end (on mode 2
the grazing of both walls at omega = 5.92312286, where the interior extrema reach them).

**Why this configuration.** A mass moving in a clearance (a loose support, a rattling gear, a
tube in its baffle) is the two-contact setting met first in practice, and it keeps paper 000's
impacting dof and modes, so its nonsmooth modes can be set against the one-wall ones at the same
frequencies. With symmetric walls (``g_l = g``) the system is equivariant under ``(u, u') ->
-(u, u')``, and the symmetric orbits (``u(t + T/2) = -u(t)``, one impact on each wall per period,
half a period apart) have a closed form like (4.2):

    ``w2(T) = sum_j a_j tan(w_j T / 4) / w_j``,   ``u'(0+) = v e_c``,   ``v = -g / w2(T)``,
    ``u(0) = -v P diag(tan(w_j T / 4) / w_j) P^-1 e_c``                                  (W1)

(``a_j = P_cj (P^-1)_jc`` as in (2.11); the post-impact state on the upper wall, ``u_c(0) = g``).
Derivation: with ``q = P^-1 u``, ``p = P^-1 u'`` and ``theta_j = w_j T / 2``, the half-period
flight must end in the reflected state, ``q(T/2) = -q(0)`` and ``p(T/2-) = -R p(0+)``; for
``u'(0+) = v e_c`` (the only moving dof at impact, by time reversal as in Prop. 4.1) ``R u' =
-u'`` and both conditions reduce to ``q_j = -tan(theta_j / 2) p_j / w_j``. (W1) is admissible
where ``v < 0`` (the mass leaves the upper wall) and ``|u_c| < g`` inside each half period; its
poles ``w2 -> inf`` are the odd subharmonics ``T = (2k + 1) T_j`` (the linear grazing orbits,
``v -> 0``), its zeros ``w2 = 0`` energy asymptotes (``v -> inf``). Only odd multiples of ``T_j``
appear: the linear orbit of period ``2k T_j`` is not antisymmetric over half a period.

(W1) is this model's start (a guess, corrected by the shooting in its own equations at the same
frequency), never its answer; the tests check the continued families against an independent
closed form (the nullspace of ``e^{A T/2} + diag(I, R)``, ``tests/oracles/chain_two_walls.py``)
and its saltation monodromy.

Starts: ``{omega: w}`` or ``{T: T}`` (the symmetric orbit (W1) at that period: symmetric walls
only), or ``{guess: {...}}`` on the section (any walls, any orbit).
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar

import casadi as ca
import numpy as np
from nsm_continuation.problems.chain.hybrid_model import ChainFamilyProblem, ClosedFormStart
from nsm_continuation.problems.chain.parameters import ChainSpec
from pydantic import BaseModel, Field, model_validator

from nsm_continuation.core import monitors as monitor
from nsm_continuation.core.monitors import Monitors, Source
from nsm_continuation.core.preflight import STRICT, one_or_many
from nsm_continuation.hybrid.conservative_family import GuessStart
from nsm_continuation.hybrid.return_map import CrossingSection
from nsm_continuation.hybrid.specs import IntegratorSpec
from nsm_continuation.hybrid.system import HybridSystem

Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
#: the names of the two walls (``u_c = gap``, ``u_c = -lower_gap``)
WALLS = ["upper", "lower"]


class TwoWallChainParameters(BaseModel):
    """``parameters:`` of ``problem: ndof_two_walls``: the chain, the upper wall ``u_c = gap``,
    the lower wall ``u_c = -lower_gap`` (null: ``gap``, the symmetric clearance), the impacting
    dof (default the last), the section, the impacts per period and the integrator."""

    model_config = STRICT
    #: the chain's masses and springs (as for ``problem: ndof_impact``)
    chain: ChainSpec
    #: the upper wall: ``u_c <= gap``
    gap: Positive
    #: the lower wall: ``u_c >= -lower_gap`` (null: ``gap``, symmetric walls)
    lower_gap: Positive | None = None
    #: the dof between the walls (1-based; null: the last)
    impacting_dof: Annotated[int, Field(ge=1)] | None = None
    #: the section ``u_c = section_value`` (crossed falling), between the walls (null: halfway
    #: to the upper wall, ``gap / 2``; on a symmetric orbit ``u_c = 0`` is crossed at ``T / 4``,
    #: and that crossing turns tangent where ``u_c`` has an inflection there), or on the upper
    #: wall (``gap``: the impacts on it, transversal as long as they have a velocity); a
    #: section between the walls moves to the upper wall's impacts where a turn of ``u_c``
    #: comes near it (a branch continues through the section's tangency)
    section_value: float | None = Field(None, allow_inf_nan=False)
    #: the impacts per period of the orbits continued (2: one on each wall; a branch ends
    #: where its impact sequence changes); null: any
    impacts: Annotated[int, Field(ge=1)] | None = 2
    #: the simulation's tolerances and integrator (default ``rtol`` 1e-12)
    integrator: IntegratorSpec = IntegratorSpec(rtol=1e-12, atol=1e-14)

    @model_validator(mode="after")
    def _checks(self) -> TwoWallChainParameters:
        if self.impacting_dof is not None and not 1 <= self.impacting_dof <= self.chain.dofs:
            raise ValueError(f"impacting_dof = {self.impacting_dof} is out of range "
                             f"1..{self.chain.dofs}")
        if self.lower_gap is None:
            self.lower_gap = self.gap
        if self.section_value is None:
            self.section_value = 0.5 * self.gap
        if not -self.lower_gap < self.section_value <= self.gap:
            raise ValueError(f"section_value = {self.section_value} must lie between the walls "
                             f"or on the upper one (-lower_gap = {-self.lower_gap}, gap = "
                             f"{self.gap})")
        return self


class TwoWallChainProblem(ChainFamilyProblem):
    """The chain's nonsmooth modes with its impacting dof between two walls (see the module
    docstring)."""

    name: ClassVar[str] = "ndof_two_walls"
    Parameters: ClassVar[type[BaseModel]] = TwoWallChainParameters
    case_parameter: ClassVar[str | None] = "omega"
    start_adapter = one_or_many(ClosedFormStart | GuessStart)
    #: the symmetric families end where a near approach grazes a wall: its margin is a
    #: vanishing quantity (the end extrapolated to its zero, named ``grazing``). The energy is
    #: not watched for an asymptote: the families end at such a grazing before (W1)'s energy
    #: asymptote (a zero of ``w2(T)``, where ``v -> inf``): as ``v`` grows the flight between
    #: the impacts (``u_c`` from ``g`` to ``-g``) has interior extrema of size ``~ |v|``, which
    #: reach a wall first (mode 1 at omega = 1.66836 before 1.68, mode 2 at 5.92312 before
    #: 5.99); extrapolated from the steep rise of the energy, the asymptote would end mode 2
    #: at omega ~ 5.90, short of its grazing
    monitors: ClassVar[Monitors] = Monitors(
        (*(m for m in ChainFamilyProblem.monitors.declared if m.source is not Source.ASYMPTOTE),
         monitor.vanishing("grazing_margin", "grazing")),
        ChainFamilyProblem.monitors.default_kind)
    model: ClassVar[str] = (
        "hybrid (problem ndof_two_walls): event-driven simulation of the chain between impacts "
        "on two walls with the unfolding beta; no closed form covers every orbit of two "
        "contacts (the symmetric one-impact-per-wall orbit (W1) is only the start)")

    def conservative_system(self) -> tuple[HybridSystem, ca.SX | None]:
        M, K, q, qd, names, energy = self.chain_mechanics()
        p = {k: ca.SX.sym(k) for k in ("gap", "lower_gap")}
        c = self.chain_problem.c
        system = HybridSystem.mechanical(
            "chain_two_walls", q, qd, p, M, -ca.mtimes(K, q),
            [p["gap"] - q[c], q[c] + p["lower_gap"]], [1.0, 1.0], surfaces=WALLS,
            state_names=names)
        return system, energy

    def section(self) -> CrossingSection:
        """``u_c = section_value`` crossed falling; on the upper wall (``section_value =
        gap``) the impacts on it (the post-impact states)."""
        value = float(self.params.section_value)  # type: ignore[attr-defined]
        if value == float(self.params.gap):  # type: ignore[attr-defined]
            return self.impact_section()
        return super().section()

    def impact_section(self) -> CrossingSection:
        """The impacts on the upper wall: where a turn of ``u_c`` reaches a section between
        the walls, the section moves there (:meth:`rechart`)."""
        return CrossingSection(self.chain_problem.c, float(self.params.gap), 0.0,  # type: ignore[attr-defined]
                               crossing=-1, returns=1, surface=WALLS.index("upper"))

    def symmetric_orbit(self, T: float) -> tuple[np.ndarray, np.ndarray]:
        """The symmetric orbit (W1) of period ``T``: its state just after the impact on the
        upper wall, ``(u(0), u'(0+))``."""
        md, c = self.modal, self.chain_problem.c
        tan = np.tan(md.omega * T / 4.0) / md.omega
        v = -float(self.params.gap) / float(np.sum(md.a * tan))  # type: ignore[attr-defined]
        du = np.zeros(self.chain_problem.N)
        du[c] = v
        return -v * (md.P @ (tan * md.Pinv[:, c])), du

    def orbit_start(self, spec: Any) -> tuple[np.ndarray, float, str, dict[str, Any]]:
        """The symmetric orbit (W1) at the start's period (symmetric walls only)."""
        prm = self.params
        if prm.lower_gap != prm.gap:  # type: ignore[attr-defined]
            raise ValueError("start: the closed-form start (W1) is the symmetric orbit of "
                             "symmetric walls (lower_gap = gap); give a guess on the section")
        T = spec.period
        u0, du0 = self.symmetric_orbit(T)
        if not du0[self.chain_problem.c] < 0:
            raise ValueError(f"start: the symmetric orbit of period {T:.6g} is not admissible "
                             "(it does not leave the upper wall: beyond a zero of w2(T))")
        label = spec.label or f"omega = {2 * np.pi / T:.6g}"
        return np.concatenate([u0, du0]), T, label, {"start": "symmetric closed form (W1)",
                                                     "T0": T}
