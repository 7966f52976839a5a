"""N-dof linear oscillator with one dof impacting a rigid wall, e = 1 (Legrand, Junca, Heng 2017).

Model (eq. 2.5): ``M u'' + K u = lambda e_c`` with the impacting dof ``c`` (the paper: ``c = N``),
``u_c <= g`` and the impact law ``u_c'+ = -u_c'-``. Periodic orbits with one impact per period are
the fixed points of the first return map ``F(Q) = R(T(Q)) Q`` (Definition 2.5); with the period
``T`` given, ``(R(T) - I) Q = 0`` is linear in ``Q`` (eq. 2.28) and ``u_c(0) = g`` fixes the scale.

Residual used for continuation (``formulation: half_angle``, the default). The block elimination
(4.4)-(4.6) of ``(R(T) - I) Q = 0`` shows:

* the velocity block reduces to ``(S + I) u'(0) = 0``: every velocity but ``v = u_c'(0)`` vanishes,
  and row ``c`` of that block is ``0 = 0``. This is **the redundant equation**: the ``c``-th
  velocity condition ``u_c'-(T) = -u_c'(0)`` is a linear combination of the position conditions
  for every ``T`` that is not a pole (``R(T) - I`` has rank ``2N - 1``, Lemma 4.1);
* the position block, in modal coordinates ``q = P^-1 u(0)`` and with
  ``p = P^-1 e_c v``, reads ``2 sin(w_j T/2) [sin(w_j T/2) q_j - cos(w_j T/2) p_j / w_j] = 0``.
  The factor ``2 sin(w_j T/2)`` vanishes at the poles ``T = k T_j`` of ``w_N``; dividing it out
  gives an analytic residual whose Jacobian keeps full rank *through* the linear grazing orbits,
  so a branch is continued across a pole from its phantom to its admissible part (Theorem 3.1).

Unknowns ``y = (u_1(0) .. u_N(0), v, T)`` (displacements and velocity in units of ``|g|``, below),
equations ``sin(w_j T/2) q_j - cos(w_j T/2) p_j/w_j = 0`` (``j = 1..N``) and
``u_c(0) - sign(g) = 0``: ``N + 1`` equations in ``N + 2`` unknowns.

``formulation: shooting`` keeps the physical ``2N + 1`` unknowns ``(u(0), u'(0), T)`` and the rows
of ``(Gamma(T) - I) x`` (``Gamma`` = eq. A.1) without the redundant one, plus ``u_c(0) = g``. Its
Jacobian loses rank at the poles (the linear mode with any phase solves the reduced rows there),
which the engine reports as a branch point: kept as a general template and as a test of that.

Conventions (differences from the paper, documented and tested):

* energy ``E = (u'^T M u' + u^T K u) / 2`` (the paper's Prop. 6.1 omits the 1/2);
* for ``g = 0`` (sec. 7.2) the outgoing velocity of an admissible orbit is ``v < 0`` (the mass
  leaves the wall towards ``u_c < 0``); Prop. 7.2 prints ``v >= 0``, which would put the mass on
  the wrong side of the wall at ``t = 0+`` since ``u_c(t) = v t + O(t^2)``;
* the impact is energy-conserving only if ``M_ck = 0`` for ``k != c`` (Prop. 6.1); other SPD mass
  matrices are accepted with a warning;
* the gap only sets the scale: the residual is linear in ``(u(0), v)`` and in ``g``, so for
  ``g != 0`` every orbit is ``|g|`` times the orbit for ``g = sign(g)`` (same periods,
  multipliers and events; energy times ``g^2``; tested). The unknowns ``u(0), v`` are in units
  of ``|g|`` (:attr:`NDofImpactProblem.length`; :meth:`~NDofImpactProblem.state` and
  :meth:`~NDofImpactProblem.y_from_state` convert), so the residual, its Jacobian and every
  step of the continuation are the gap-1 problem's whatever the gap (the arclength measured in
  physical units made a gap of 1000 cover 1.6 % of its branch, tested over 1e-100 .. 1e100 in
  ``tests/chain/test_gap_scale_invariance.py``). Gaps with ``0 < |g| < 1e-100`` or
  ``|g| > 1e100`` are refused (:func:`nsm_continuation.core.preflight.check_gap`): there the
  energies leave the range double precision resolves (with ``g = 1e-300`` the first branch
  ended after 14 points at a spurious branch point instead of its nonlinear grazing orbit);
  solve at a gap in range and scale the results.

Sizes: nothing of size ``N^2`` is built at construction (``validate`` constructs the problem);
the memory (dense ``N x N`` and ``2N x 2N`` matrices) and time (multipliers at every point) of
a run are estimated and refused above ``NSM_CONTINUATION_MAX_MEMORY_GB`` /
``NSM_CONTINUATION_MAX_HOURS`` (:meth:`NDofImpactProblem.preflight`).

The problem is composed from one module per idea: :mod:`.parameters` (the YAML schema and
the sizing), :mod:`.modal` (the modal model 2.9-2.11), :mod:`.closed_form` (the closed-form
orbits (4.1)-(4.2), (5.4), (7.1) and the spectrum of ``w_N``), :mod:`.admissibility`
(Definition 2.2), :mod:`.stability` (the return map (A.8), its Floquet multipliers and
their Krein signatures), :mod:`.starts` (starts, bounds, preflight), :mod:`.presentation`
(figures and report) and :mod:`.simulate` (an independent simulation, the oracle); this
module holds the unknowns, the residual and its bordered solves.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
from nsm_continuation.problems.chain.admissibility import ChainAdmissibility
from nsm_continuation.problems.chain.closed_form import ChainClosedForm
from nsm_continuation.problems.chain.modal import ModalModel, generalized_eigh
from nsm_continuation.problems.chain.parameters import (
    START_ADAPTER,
    AllStart,
    ChainSizing,
    ChainSpec,
    ModeStart,
    NDofParameters,
    PeriodStart,
    StartSpec,
    chain_case_matrices,
)
from nsm_continuation.problems.chain.presentation import ChainPresentation
from nsm_continuation.problems.chain.simulate import simulate_first_return
from nsm_continuation.problems.chain.stability import ChainStability, MultiplierMemory
from nsm_continuation.problems.chain.starts import ChainStarts
from pydantic import BaseModel, TypeAdapter

from nsm_continuation.core.bordered import BorderedFactor, DiagonalBorderedFactor
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.vocabulary import as_parameters


class NDofImpactProblem(ChainStability, ChainAdmissibility, ChainClosedForm, ChainStarts,
                        ChainSizing, Problem):
    """N-dof chain, one mass impacting a rigid wall with e = 1 (Legrand, Junca, Heng 2017).
    T-parametrised fixed points of the first return map R(T)."""

    presentation_class = ChainPresentation
    #: the figures depend on the results and the parameters only
    figures_from_inputs: ClassVar[bool] = True

    name: ClassVar[str] = "ndof_impact"
    #: a case continues the frequency unless it says otherwise (its unknown is T)
    case_parameter: ClassVar[str | None] = "omega"
    Parameters: ClassVar[type[BaseModel]] = NDofParameters
    start_adapter: ClassVar[TypeAdapter] = START_ADAPTER
    energy_quantity = "energy"
    #: the residual is smooth with an exact Jacobian: pycont-lite can follow it as well
    algorithms: ClassVar[tuple[str, ...]] = ("palc", "pycont")

    def __init__(self, params: NDofParameters | dict[str, Any]) -> None:
        params = as_parameters(NDofParameters, params)
        super().__init__(params)
        # nothing of size N^2 (let alone the O(N^3) modal analysis) is built here: ``validate``
        # constructs the problem, and the sizes are checked first (``check_size``, preflight)
        self.N = params.chain.dofs if params.chain is not None else len(params.M or [])
        self.c = (params.impacting_dof or self.N) - 1
        self.g = float(params.gap)
        #: the unit of the unknowns ``u(0)``, ``v``: ``|g|`` (1 for ``g = 0``). The model is
        #: linear in the gap, so in these units the residual is the gap-1 problem's and the
        #: continuation at any gap is the one at ``sign(g)``, step for step (see the module
        #: docstring); :meth:`state` and :meth:`y_from_state` convert
        self.length = abs(self.g) if self.g != 0.0 else 1.0
        self.formulation = params.formulation
        self.check_size()
        N = self.N
        if self.formulation == "half_angle":
            self.variables = [f"u{i + 1}" for i in range(N)] + ["v", "T"]
        else:
            self.variables = ([f"u{i + 1}" for i in range(N)]
                              + [f"du{i + 1}" for i in range(N)] + ["T"])
        self.parameter = "T"
        #: +1 continued in T, -1 in omega (set by :meth:`parameter_bounds`): a start's
        #: ``direction`` is meant along the continued parameter
        self._orientation = 1
        self.symbolic = "SX" if N <= 30 else "MX"
        #: the matrices and modal data (2.9)-(2.11), each computed on first use
        self.modal = ModalModel(params, self.c)
        #: (the branches, their static grazing spectrum): see :meth:`static_grazing_spectrum`
        self._spectrum_cache: tuple[list[Any], list[dict[str, Any]]] | None = None
        #: multipliers of the last :meth:`floquet` calls with their point ``y``, the starts of
        #: the next (:class:`~nsm_continuation.problems.chain.stability.MultiplierMemory`)
        self.multiplier_memory = MultiplierMemory()
        #: :meth:`floquet` calls answered by the dense method (structured iteration failed)
        self.floquet_fallbacks = 0

    #: above this many dofs the engine's bordered systems are solved from the structure
    #: (:meth:`bordered_factor`, O(N^2)); up to it, dense (LAPACK is cheaper there, and the
    #: paper's chains keep the dense path they were validated with)
    DENSE_SOLVES_UP_TO: ClassVar[int] = 40

    def monitor_names(self) -> list[str]:
        return ["T", "omega", "energy", "v_out", "w_N"]

    # ------------------------------------------------------------------ modal data
    @property
    def M(self) -> np.ndarray:
        """Mass matrix (built on first use)."""
        return self.modal.M

    @property
    def K(self) -> np.ndarray:
        """Stiffness matrix (built on first use)."""
        return self.modal.K

    @property
    def omega(self) -> np.ndarray:
        """Linear frequencies ``omega_j`` (ascending)."""
        return self.modal.omega

    @property
    def P(self) -> np.ndarray:
        """Mass-normalised mode shapes (columns)."""
        return self.modal.P

    @property
    def Pinv(self) -> np.ndarray:
        return self.modal.Pinv

    @property
    def T_lin(self) -> np.ndarray:
        """Linear periods ``T_j = 2 pi / omega_j``."""
        return self.modal.T_lin

    @property
    def a(self) -> np.ndarray:
        """Interaction coefficients (2.11) ``a_j = P_cj (P^-1)_jc``."""
        return self.modal.a

    # ------------------------------------------------------------------ residual
    def residual(self, y: Any) -> Any:
        N, c = self.N, self.c
        T = y[-1]
        u0 = y[:N]
        mtimes = ca.mtimes
        P, Pinv, w = (ca.DM(self.P), ca.DM(self.Pinv), ca.DM(self.omega))
        if self.formulation == "half_angle":
            v = y[N]
            q = mtimes(Pinv, u0)
            p = ca.DM(self.Pinv[:, c]) * v
            half = w * T / 2
            modal = ca.sin(half) * q - ca.cos(half) * p / w
            return ca.vertcat(modal, u0[c] - self.g / self.length)
        du0 = y[N:2 * N]
        q = mtimes(Pinv, u0)
        p = mtimes(Pinv, du0)
        cwt, swt = ca.cos(w * T), ca.sin(w * T)
        uT = mtimes(P, cwt * q + swt * p / w)
        vT = mtimes(P, -w * swt * q + cwt * p)
        s = np.ones(N)
        s[c] = -1.0
        vel = vT - ca.DM(s) * du0
        keep = [i for i in range(N) if i != c]
        return ca.vertcat(uT - u0, vel[keep], u0[c] - self.g / self.length)

    # ------------------------------------------------------------------ linear algebra
    def _structured_solves(self) -> bool:
        return self.formulation == "half_angle" and self.N > self.DENSE_SOLVES_UP_TO

    def bordered_factor(self, y: np.ndarray, row: np.ndarray,
                        jacobian: np.ndarray | None = None) -> BorderedFactor:
        """The bordered matrix ``[G_y; r^T]`` of the ``half_angle`` residual from its structure.

        With ``q = P^-1 u(0)``, ``p = P^-1 e_c v`` and ``h = w T / 2`` the residual's modal rows
        are ``sin(h) q - cos(h) p / w`` and its last row ``u_c(0) - g``. In the modal unknowns
        ``z = P^-1 du`` the Jacobian is a diagonal, ``diag(sin h)``, bordered by two columns
        (``d/dv = -cos(h) P^-1 e_c / w``, ``d/dT = (w/2) cos(h) q + sin(h) p / 2``) and two
        rows (``e_c^T P`` and the border ``r_u^T P``):
        :class:`~nsm_continuation.core.bordered.DiagonalBorderedFactor`, O(N^2) per solve. The zeros
        of ``sin(w_j T / 2)`` at the poles ``T = 2 pi l / w_j`` stay in its small dense system,
        so the factor is exact through them (where the Jacobian keeps full rank). Up to
        ``DENSE_SOLVES_UP_TO`` dofs, and for the ``shooting`` formulation, the dense default."""
        if not self._structured_solves():
            return super().bordered_factor(y, row, jacobian)
        N, c = self.N, self.c
        y = np.asarray(y, dtype=float)
        u0, v, T = y[:N], float(y[N]), float(y[N + 1])
        w, P, Pi = self.omega, self.P, self.Pinv
        q, pc = Pi @ u0, Pi[:, c]
        half = w * T / 2
        sh, ch = np.sin(half), np.cos(half)
        C = np.column_stack([-ch * pc / w, 0.5 * w * ch * q + 0.5 * sh * pc * v])
        R = np.vstack([P[c, :], row[:N] @ P])
        E = np.array([[0.0, 0.0], [row[N], row[N + 1]]])
        return DiagonalBorderedFactor(sh, C, R, E, Pi, P, self.modal.Pinv_slogdet)

    def residual_and_factor(self, y: np.ndarray, row: np.ndarray
                            ) -> tuple[np.ndarray, BorderedFactor]:
        if not self._structured_solves():
            return super().residual_and_factor(y, row)
        return self.evaluate(y), self.bordered_factor(y, row)

    # ------------------------------------------------------------------ state helpers
    def state(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Physical initial state ``(u(0), u'(0+))`` on the section and the period (the
        unknowns are in units of :attr:`length`)."""
        N, L = self.N, self.length
        y = np.asarray(y, dtype=float)
        if self.formulation == "half_angle":
            du = np.zeros(N)
            du[self.c] = y[N] * L
            return y[:N] * L, du, float(y[-1])
        return y[:N] * L, y[N:2 * N] * L, float(y[-1])

    def y_from_state(self, u0: np.ndarray, du0: np.ndarray, T: float) -> np.ndarray:
        """The unknowns of the physical state ``(u(0), u'(0+))`` and the period ``T``."""
        L = self.length
        if self.formulation == "half_angle":
            return np.concatenate([u0 / L, [du0[self.c] / L], [T]])
        return np.concatenate([u0 / L, du0 / L, [T]])

    def energy(self, y: np.ndarray) -> float:
        u0, du0, _ = self.state(y)
        return 0.5 * float(du0 @ self.M @ du0 + u0 @ self.K @ u0)

    def derived(self, y: np.ndarray) -> dict[str, float]:
        u0, du0, T = self.state(y)
        return {"T": T, "omega": 2 * np.pi / T, "energy": self.energy(y),
                "v_out": float(du0[self.c]), "w_N": float(self.w_N(T))}

    #: parameters :meth:`with_parameters` can change (a chain's uniform mass or stiffness)
    CHANGEABLE: ClassVar[tuple[str, ...]] = ("gap", "mass", "stiffness")

    def with_parameters(self, values: dict[str, float]) -> NDofImpactProblem:
        """The chain with ``gap``, or its uniform ``mass`` or ``stiffness`` (``chain.mass``,
        ``chain.stiffness``: one value for every spring) changed, continued in the same
        parameter (``T`` or ``omega``)."""
        data = self.params.model_dump()
        for name, value in values.items():
            if name not in self.CHANGEABLE:
                raise ValueError(f"{name!r} is not a parameter of {self.name!r} that a "
                                 f"two-parameter curve can vary (one of {self.CHANGEABLE})")
            if name == "gap":
                data["gap"] = float(value)
                continue
            chain = data.get("chain")
            if chain is None or isinstance(chain[name], list):
                raise ValueError(f"chain.{name}: a two-parameter curve varies a chain's "
                                 f"{name} given as one value for every dof (not a list or "
                                 "matrices)")
            chain[name] = float(value)
        new = type(self)(NDofParameters.model_validate(data))
        new._orientation = self._orientation
        return new


__all__ = ["NDofImpactProblem", "NDofParameters", "simulate_first_return", "chain_case_matrices",
           "ChainSpec", "ModeStart", "PeriodStart", "AllStart", "StartSpec", "START_ADAPTER",
           "generalized_eigh"]
