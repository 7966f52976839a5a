"""The chain of Legrand, Junca, Heng (2017) declared through the hybrid layer: the second model
of the same nonsmooth modes (``problem: ndof_impact_hybrid``).

``M u'' + K u = 0`` between impacts (the matrices of the chain, :class:`.parameters.ChainSpec`,
the same as ``ndof_impact``'s), the wall ``H = g - u_c >= 0`` at the impacting dof ``c`` with
Newton's law ``u_c'+ = -e u_c'-`` (``e = 1``: eq. 2.5), simulated event by event
(:class:`~nsm_continuation.hybrid.simulate.Simulator`: Runge-Kutta between impacts, located
impacts, saltation-chained sensitivities) and continued as a conservative family
(:class:`~nsm_continuation.hybrid.conservative_family.ConservativeFamilyProblem`: the unfolding
``M u'' + K u = beta M u'`` that vanishes on every orbit, shooting on the section ``u_c = 0``
crossed falling, the energy ``E = (u'^T M u' + u^T K u) / 2``).

**Which model runs.** ``ndof_impact`` (the closed form (4.1)-(4.2), its multipliers from
(A.8)) is the default: exact to round-off, 1.4 ms per point (0.25 s here), but only for one
impact per period. This model assumes nothing about the impact sequence (several impacts per
period, a damping or a restitution below 1 to check that the unfolding catches them); a case
chooses it explicitly, and the report names it (``problem_summary.model``). The two agree on
the one-impact modes (``tests/chain/test_two_models.py``).

Starts: ``{omega: w}`` or ``{T: T}``: the closed-form orbit (4.2) at that period (a guess: the
hybrid model corrects it in its own equations at that frequency), or ``{guess: {...}}`` on the
section. The section is crossed once per period on branch 1; a start counts the crossings of
its orbit (``returns``). ``{resonance: {order: k, rotation: m, omega: w}}``: the family of
period-``k`` orbits born where the one-impact family near ``w`` has the multiplier
``exp(2 pi i m / k)`` (located on the closed form, :mod:`.resonance`; switched onto in this
model, :mod:`nsm_continuation.algorithms.resonance_switching`; docs/internal_resonances.md).
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

import casadi as ca
import numpy as np
from nsm_continuation.problems.chain.modal import ModalModel
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from nsm_continuation.problems.chain.parameters import ChainSpec
from nsm_continuation.problems.chain.resonance import nearest_resonance
from pydantic import BaseModel, Field, model_validator

from nsm_continuation.algorithms.resonance_switching import resonance_starts
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.preflight import STRICT, one_or_many
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.core.settings import ContinuationSettings
from nsm_continuation.hybrid.conservative_family import ConservativeFamilyProblem, GuessStart
from nsm_continuation.hybrid.return_map import CrossingSection
from nsm_continuation.hybrid.specs import IntegratorSpec
from nsm_continuation.hybrid.system import HybridSystem

Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
#: the highest order of a resonance start (its family's orbits are simulated over k periods)
MAX_ORDER = 12
#: the residual floor of a resonance start's family (``Problem.residual_floor``), times the
#: integrator's ``rtol``: the residual of the simulated map at its noise (measured ``1e-14 ...
#: 7e-14`` at ``rtol = 1e-12`` on the period-4 orbits of branch 1)
RESIDUAL_FLOOR = 0.1


class HybridChainParameters(BaseModel):
    """``parameters:`` of ``problem: ndof_impact_hybrid``: the chain, the gap (the wall at
    ``u_c = gap > 0``), the impacting dof (default the last), the restitution (1: the nonsmooth
    modes; below 1 the unfolding does not vanish and the branch ends, named), a viscous damping
    ``damping * K`` (0: conservative) and the integrator (default ``rtol`` 1e-12)."""

    model_config = STRICT
    #: the chain's masses and springs (as for ``problem: ndof_impact``)
    chain: ChainSpec
    #: the wall's position: the impacting dof's displacement ``u_c <= gap``
    gap: Positive
    #: the dof that hits the wall (1-based; null: the last)
    impacting_dof: Annotated[int, Field(ge=1)] | None = None
    #: coefficient of restitution (1: elastic, the nonsmooth modes; below 1 the unfolding
    #: parameter does not vanish and the branch ends, named)
    restitution: float = Field(1.0, gt=0, le=1, allow_inf_nan=False)
    #: viscous damping ``damping * K`` (0: conservative)
    damping: float = Field(0.0, ge=0, allow_inf_nan=False)
    #: the section ``u_c = section_value`` (crossed falling: moving away from the wall)
    section_value: float = Field(0.0, allow_inf_nan=False)
    #: the impacts per period of the orbits continued (1: the paper's one-impact modes; a
    #: branch ends where its impact sequence changes, e.g. at the nonlinear grazing orbit B);
    #: null: any
    impacts: Annotated[int, Field(ge=1)] | None = 1
    #: the simulation's tolerances and integrator (default ``rtol`` 1e-12)
    integrator: IntegratorSpec = IntegratorSpec(rtol=1e-12, atol=1e-14)

    @model_validator(mode="after")
    def _checks(self) -> HybridChainParameters:
        if self.impacting_dof is not None and not 1 <= self.impacting_dof <= self.chain.dofs:
            raise ValueError(f"impacting_dof = {self.impacting_dof} is out of range "
                             f"1..{self.chain.dofs}")
        if not self.section_value < self.gap:
            raise ValueError(f"section_value = {self.section_value} must lie below the wall "
                             f"(gap = {self.gap})")
        return self


class ClosedFormStart(BaseModel):
    """``start: {omega: w}`` or ``{T: T}``: the closed-form one-impact orbit (4.2) at that
    period, as the guess."""

    model_config = STRICT
    #: the orbit's angular frequency (give this or ``T``)
    omega: Positive | None = None
    #: the orbit's period (give this or ``omega``)
    T: Positive | None = None
    #: the directions to continue in from the start
    direction: Literal["both", "increase", "decrease"] = "both"
    #: a label for the start's branch
    label: str | None = None

    @model_validator(mode="after")
    def _one(self) -> ClosedFormStart:
        if (self.omega is None) == (self.T is None):
            raise ValueError("give exactly one of omega, T")
        return self

    @property
    def period(self) -> float:
        return self.T if self.T is not None else 2.0 * np.pi / float(self.omega)  # type: ignore[arg-type]


class ResonanceSpec(BaseModel):
    """The resonance of a ``start: {resonance: {...}}``."""

    model_config = STRICT
    #: ``k``: the order of the resonance (the multiplier ``exp(2 pi i m / k)``, ``k >= 3``;
    #: ``k = 2`` is a period doubling: ``analysis.branch_switching``)
    order: int = Field(ge=3, le=MAX_ORDER)
    #: ``m``: the multiplier's rotation number numerator (``1 <= m < k / 2``, ``gcd(m, k) = 1``)
    rotation: int = Field(1, ge=1)
    #: the frequency of the one-impact family near which the resonance lies (the nearest zero
    #: of the closed-form condition within 1 %)
    omega: Positive

    @model_validator(mode="after")
    def _coprime(self) -> ResonanceSpec:
        if not (2 * self.rotation < self.order and np.gcd(self.rotation, self.order) == 1):
            raise ValueError(f"rotation = {self.rotation}: need 2 m < k = {self.order} and "
                             "gcd(m, k) = 1")
        return self


class ResonanceStart(BaseModel):
    """``start: {resonance: {order: k, rotation: m, omega: w}}``: the family of period-``k``
    orbits (``k`` impacts per period) born at the ``m/k`` resonance of the one-impact family
    near ``w``, continued away from it (both sides where it crosses the resonance)."""

    model_config = STRICT
    #: the resonance: its order, rotation and approximate frequency
    resonance: ResonanceSpec
    #: a label for the family's branches
    label: str | None = None


class ChainFamilyProblem(ConservativeFamilyProblem):
    """A conservative family of the chain of Legrand et al. (2017) through the hybrid layer:
    the chain's matrices and modal data from its closed-form problem (``chain_problem``), the
    case's parameters validated by the subclass's ``Parameters``."""

    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "chain", "impacting_dof",
                                                 "section_value", "impacts")

    def __init__(self, params: BaseModel | dict[str, Any]) -> None:
        p = params if isinstance(params, BaseModel) else self.Parameters.model_validate(
            dict(params))
        self.chain_problem = NDofImpactProblem(
            {"chain": p.chain.model_dump(), "gap": p.gap,  # type: ignore[attr-defined]
             "impacting_dof": p.impacting_dof})  # type: ignore[attr-defined]
        super().__init__(p)

    @property
    def modal(self) -> ModalModel:
        """The chain's matrices and modal data (shared with its closed form)."""
        return self.chain_problem.modal

    def chain_mechanics(self) -> tuple[ca.DM, ca.DM, ca.SX, ca.SX, list[str], ca.SX]:
        """``(M, K, u, du, names, E)``: the chain's mass and stiffness matrices, its
        displacements and velocities (symbols), their state names ``u1 .. uN, du1 .. duN`` and
        its energy ``E = (du^T M du + u^T K u) / 2`` (between impacts, ``M u'' + K u = 0``)."""
        cp = self.chain_problem
        M, K = ca.DM(cp.M), ca.DM(cp.K)
        q, qd = ca.SX.sym("u", cp.N), ca.SX.sym("du", cp.N)
        names = [f"u{i + 1}" for i in range(cp.N)] + [f"du{i + 1}" for i in range(cp.N)]
        energy = 0.5 * (ca.dot(qd, ca.mtimes(M, qd)) + ca.dot(q, ca.mtimes(K, q)))
        return M, K, q, qd, names, energy

    def impacts_per_period(self) -> int | None:
        """The case's ``impacts`` (None: any number per period)."""
        return self.params.impacts  # type: ignore[attr-defined,no-any-return]

    def section(self) -> CrossingSection:
        """The impacting dof's crossing of ``section_value``, falling, once per period."""
        return CrossingSection(self.chain_problem.c, float(self.params.section_value),  # type: ignore[attr-defined]
                               0.0, crossing=-1, returns=1)


class NDofImpactHybridProblem(ChainFamilyProblem):
    """The chain's nonsmooth modes by the hybrid layer (see the module docstring)."""

    name: ClassVar[str] = "ndof_impact_hybrid"
    Parameters: ClassVar[type[BaseModel]] = HybridChainParameters
    case_parameter: ClassVar[str | None] = "omega"
    start_adapter = one_or_many(ClosedFormStart | GuessStart | ResonanceStart)
    model: ClassVar[str] = (
        "hybrid (problem ndof_impact_hybrid): event-driven simulation of the chain between "
        "impacts with the unfolding beta, chosen by the case; the closed form (problem "
        "ndof_impact) is the default model of one-impact orbits")

    def conservative_system(self) -> tuple[HybridSystem, ca.SX | None]:
        M, K, q, qd, names, energy = self.chain_mechanics()
        p = {k: ca.SX.sym(k) for k in ("gap", "restitution", "damping")}
        force = -ca.mtimes(K, q) - p["damping"] * ca.mtimes(K, qd)
        system = HybridSystem.mechanical("chain", q, qd, p, M, force,
                                         p["gap"] - q[self.chain_problem.c],
                                         p["restitution"], state_names=names)
        return system, energy

    def orbit_start(self, spec: Any) -> tuple[np.ndarray, float, str, dict[str, Any]]:
        """The closed-form orbit (4.2) at the start's period: its post-impact state."""
        T = spec.period
        u0, du0 = self.chain_problem.closed_form(T)
        label = spec.label or f"omega = {2 * np.pi / T:.6g}"
        return np.concatenate([u0, du0]), T, label, {"start": "closed form (4.2)", "T0": T}

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        """The starts; a :class:`ResonanceStart` (the only start of its case) makes this problem
        the ``k``-times iterated one and gives the first points of the period-``k`` family."""
        specs = self._starts(start)
        res = [s for _, s in specs if isinstance(s, ResonanceStart)]
        if not res:
            return super().start_points(start, window)
        if len(specs) > 1:
            raise ValueError("start: a resonance start is the only start of its case")
        return self._resonance_starts(res[0])

    def _resonance_starts(self, s: ResonanceStart) -> list[StartPoint]:
        """Locate the resonance on the closed form (R1), correct the one-impact orbit there in
        this model, switch onto the period-``k`` family (in the ``k``-iterated problem)."""
        k, m = s.resonance.order, s.resonance.rotation
        try:
            w_star = nearest_resonance(self.chain_problem, k, m, s.resonance.omega)
        except ValueError as exc:
            raise ValueError(f"start.resonance.omega: {exc}") from None
        base = type(self)(self.params)
        base.set_parameter(self.parameter, 1)
        (sp,) = base.start_points({"omega": w_star})
        settings = ContinuationSettings()
        e = np.zeros(len(sp.y))
        e[base.parameter_index] = 1.0
        yb, _, why = ContinuationEngine(base, settings).correct(sp.y, e, sp.y, 0.0)
        if yb is None:
            raise ValueError(f"start.resonance: the one-impact orbit at omega = {w_star:.12g} "
                             f"did not converge ({why})")
        self.multiple = k
        self.set_parameter(self.parameter, base.returns * k)
        # the period-k orbits are nearly degenerate along their circle (weak resonances):
        # converged where the residual is at the simulated map's noise
        self.residual_floor = RESIDUAL_FLOOR * float(self.integrator.rtol)
        label = s.label or f"{m}/{k} resonance at omega = {w_star:.8g}"
        info = {"start": f"{m}/{k} resonance of the one-impact family",
                "resonance_omega_closed_form": w_star, "resonance_order": k,
                "resonance_rotation": m}
        starts, _ = resonance_starts(base, self, yb, settings, label, info)
        return list(starts)
