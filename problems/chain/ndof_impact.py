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

Unknowns ``y = (u_1(0) .. u_N(0), v, T)``, equations ``sin(w_j T/2) q_j - cos(w_j T/2) p_j/w_j = 0``
(``j = 1..N``) and ``u_c(0) - g = 0``: ``N + 1`` equations in ``N + 2`` unknowns.

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
  multipliers and events; energy times ``g^2``; tested). Gaps with ``0 < |g| < 1e-100`` or
  ``|g| > 1e100`` are refused (:func:`nsm_continuation.core.preflight.check_gap`): there the
  energies leave the range double precision resolves (with ``g = 1e-300`` the first branch
  ended after 14 points at a spurious branch point instead of its nonlinear grazing orbit);
  solve at a gap in range and scale the results.

Sizes: nothing of size ``N^2`` is built at construction (``validate`` constructs the problem);
the memory (dense ``N x N`` and ``2N x 2N`` matrices) and time (multipliers at every point) of
a run are estimated and refused above ``NSM_CONTINUATION_MAX_MEMORY_GB`` /
``NSM_CONTINUATION_MAX_HOURS`` (:meth:`NDofImpactProblem.preflight`).
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import casadi as ca
import numpy as np
from nsm_continuation.problems.chain.trig_sum import TrigSum
from pydantic import (
    BaseModel,
    Discriminator,
    Field,
    Tag,
    TypeAdapter,
    field_validator,
    model_validator,
)

from nsm_continuation.core.bordered import BorderedFactor, DiagonalBorderedFactor
from nsm_continuation.core.floquet import (
    KreinFloquetData,
    deflate_known_eigenvector,
    krein_definiteness,
    low_rank_update_eigen,
    refine_roots,
    restrict_to_section,
)
from nsm_continuation.core.preflight import (
    STRICT,
    as_list,
    check_budget,
    check_gap,
    exactly,
    one_or_many,
    start_key,
)
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint
from nsm_continuation.core.records import OrbitTrace
from nsm_continuation.core.roots import illinois
from nsm_continuation.core.vocabulary import CanonicalNames, as_parameters

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class ChainSpec(CanonicalNames):
    """The spring-mass chain of eq. (2.17): wall - k_1 - m_1 - k_2 - ... - k_N - m_N (free end);
    ``dofs`` is the paper's ``N`` (the old key ``n`` is deprecated)."""

    model_config = STRICT
    deprecated_names = {"n": "dofs"}
    key_path = "parameters.chain"
    dofs: Annotated[int, Field(ge=1)]
    mass: Positive | list[Positive]
    stiffness: Positive | list[Positive]

    @model_validator(mode="after")
    def _lengths(self) -> ChainSpec:
        for name in ("mass", "stiffness"):
            v = getattr(self, name)
            if isinstance(v, list) and len(v) != self.dofs:
                raise ValueError(f"{name} has {len(v)} entries, expected dofs = {self.dofs}")
        return self

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.dofs
        m = np.broadcast_to(np.asarray(self.mass, dtype=float), (n,)).copy()
        k = np.broadcast_to(np.asarray(self.stiffness, dtype=float), (n,)).copy()
        K = np.zeros((n, n))
        for i in range(n):
            K[i, i] += k[i]
            if i > 0:
                K[i - 1, i - 1] += k[i]
                K[i - 1, i] -= k[i]
                K[i, i - 1] -= k[i]
        return np.diag(m), K


class NDofParameters(CanonicalNames):
    """YAML ``parameters`` of ``problem: ndof_impact``: ``gap`` is the paper's ``g`` (wall at
    ``u_c = gap``), ``restitution`` its ``e`` (must be 1)."""

    model_config = STRICT
    chain: ChainSpec | None = None
    M: list[list[Finite]] | None = None
    K: list[list[Finite]] | None = None
    gap: Finite
    impacting_dof: Annotated[int, Field(ge=1)] | None = None
    restitution: Finite = 1.0
    formulation: Literal["half_angle", "shooting"] = "half_angle"

    @field_validator("gap")
    @classmethod
    def _gap_range(cls, v: float) -> float:
        return check_gap(v)

    @field_validator("restitution")
    @classmethod
    def _elastic(cls, v: float) -> float:
        if v != 1.0:
            raise ValueError(f"must be 1 for ndof_impact (got {v}): its families of periodic "
                             "orbits exist only for a purely elastic impact law")
        return v

    @model_validator(mode="after")
    def _matrices(self) -> NDofParameters:
        if self.chain is None and (self.M is None or self.K is None):
            raise ValueError("give either 'chain: {dofs, mass, stiffness}' or both 'M' and 'K'")
        if self.chain is not None and (self.M is not None or self.K is not None):
            raise ValueError("give either 'chain' or 'M'/'K', not both")
        if self.chain is None:
            for name in ("M", "K"):
                A = np.asarray(getattr(self, name), dtype=float)
                if A.ndim != 2 or A.shape[0] != A.shape[1] or A.size == 0:
                    raise ValueError(f"{name} must be a non-empty square matrix")
                if not np.allclose(A, A.T, rtol=1e-12, atol=1e-14 * np.abs(A).max()):
                    raise ValueError(f"{name} is not symmetric")
                try:
                    np.linalg.cholesky(A)
                except np.linalg.LinAlgError:
                    raise ValueError(f"{name} is not positive definite") from None
            if len(self.M) != len(self.K):
                raise ValueError(f"M is {len(self.M)}x{len(self.M)} but K is "
                                 f"{len(self.K)}x{len(self.K)}")
        n = self.chain.dofs if self.chain is not None else len(self.M)
        if self.impacting_dof is not None and not 1 <= self.impacting_dof <= n:
            raise ValueError(f"impacting_dof = {self.impacting_dof} is out of range 1..{n}")
        return self

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        if self.chain is not None:
            return self.chain.matrices()
        return np.asarray(self.M, dtype=float), np.asarray(self.K, dtype=float)


class ModeStart(BaseModel):
    """Start at the linear grazing orbit of mode ``mode`` (or its subharmonic ``k T_j``)."""

    model_config = STRICT
    mode: Annotated[int, Field(ge=1)]
    subharmonic: Annotated[int, Field(ge=1)] = 1
    #: 'admissible' continues towards a_j (T - k T_j) < 0 only; 'both' also through the pole
    side: Literal["admissible", "both"] = "admissible"


class PeriodStart(BaseModel):
    """Start from the closed form (4.2) at a given period."""

    model_config = STRICT
    T: Positive
    direction: Annotated[Literal[-1, 0, 1], exactly(-1, 0, 1)] = 0


class AllStart(BaseModel):
    """Every branch in the continuation window: one start per pole ``k T_j`` (k <= max), plus
    seeds in the pole-free gaps; a pole already crossed by a computed branch is skipped."""

    model_config = STRICT
    all: Annotated[Literal[True], exactly(True)]
    max_subharmonic: Annotated[int, Field(ge=1)] = 10


def _start_kind(v: Any) -> str:
    """Which start model a mapping is, by its keys (``all`` / ``T`` / else a mode start), so an
    error names the key of that model, not of every model of the union."""
    if isinstance(v, dict):
        return "All" if "all" in v else "Period" if "T" in v else "Mode"
    return {AllStart: "All", PeriodStart: "Period"}.get(type(v), "Mode")


#: capitalised tags are left out of error locations (cases._format)
StartSpec = Annotated[Annotated[ModeStart, Tag("Mode")] | Annotated[PeriodStart, Tag("Period")]
                      | Annotated[AllStart, Tag("All")], Discriminator(_start_kind)]
START_ADAPTER = one_or_many(StartSpec)


def generalized_eigh(K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The modal analysis (2.9): ``K P = M P diag(w2)`` with ``P^T M P = I``, ``w2`` ascending,
    for symmetric ``K`` and symmetric positive definite ``M``. The reduction LAPACK's
    ``sygvd`` makes (what ``scipy.linalg.eigh(K, M)`` calls): ``M = L L^T``,
    ``C = L^-1 K L^-T``, ``C Q = Q diag(w2)``, ``P = L^-T Q``, in numpy alone: a run of the
    chain then never imports SciPy (0.16 s of its start-up, ``benchmarks/bench_startup.py``).
    Raises ``numpy.linalg.LinAlgError`` if ``M`` is not positive definite."""
    L = np.linalg.cholesky(M)
    A = np.linalg.solve(L, K)
    C = np.linalg.solve(L, A.T)  # L^-1 K L^-T (K symmetric)
    w2, Q = np.linalg.eigh(0.5 * (C + C.T))
    return w2, np.linalg.solve(L.T, Q)


class NDofImpactProblem(Problem):
    """T-parametrised fixed points of the first return map R(T) (Legrand et al. 2017)."""

    name: ClassVar[str] = "ndof_impact"
    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    #: a case continues the frequency unless it says otherwise (its unknown is T)
    case_parameter: ClassVar[str | None] = "omega"
    Parameters: ClassVar[type[BaseModel]] = NDofParameters
    start_adapter: ClassVar[TypeAdapter] = START_ADAPTER
    energy_quantity = "energy"
    #: the residual is smooth with an exact Jacobian: pycont-lite can follow it as well
    algorithms: ClassVar[tuple[str, ...]] = ("palc", "pycont")
    # presentation: the frequency-energy plot of Fig. 3.2
    fep_axes = ("omega", "energy")
    fep_labels = (r"frequency $\omega = 2\pi/T$ [rad/s]",
                  r"energy $E = \frac{1}{2}(\dot u^T M \dot u + u^T K u)$")
    diagram_title: ClassVar[str] = "Frequency-energy plot"
    diagram_yscale: ClassVar[str] = "log"
    csv_head = ["T", "omega", "energy"]
    event_columns = ["omega", "T", "energy"]
    #: largest subharmonic order k of the references omega_j / k (Fig. 3.2) and of the poles
    #: k T_j drawn in Fig. 3.1
    SUBHARMONIC_KMAX: ClassVar[int] = 10

    def __init__(self, params: NDofParameters | dict[str, Any]) -> None:
        params = as_parameters(NDofParameters, params)
        super().__init__(params)
        # nothing of size N^2 (let alone the O(N^3) modal analysis) is built here: ``validate``
        # constructs the problem, and the sizes are checked first (``check_size``, preflight)
        self.N = params.chain.dofs if params.chain is not None else len(params.M or [])
        self.c = (params.impacting_dof or self.N) - 1
        self.g = float(params.gap)
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
        #: (the branches, their static grazing spectrum): see :meth:`static_grazing_spectrum`
        self._spectrum_cache: tuple[list[Any], list[dict[str, Any]]] | None = None
        #: multipliers of the last :meth:`floquet` calls with their point ``y``: the start of
        #: the next call is extrapolated from the sets computed at the nearest points
        #: (:meth:`_nearest_guess`; event location bisects inside a step: the points computed
        #: so far around it are the best start), and their lineage (sets of one lineage were
        #: started from each other: multiplier k of one is multiplier k of the other)
        self._multiplier_memory: list[tuple[np.ndarray, np.ndarray, int]] = []
        self._lineages = 0
        #: :meth:`floquet` calls answered by the dense method (structured iteration failed)
        self.floquet_fallbacks = 0

    # ------------------------------------------------------------------ sizes and preflight
    #: memory of a run in doubles per N^2: M, K, P, P^-1 and the eigensolver's copies; the
    #: dense 2N x 2N flight/impact matrices of the multipliers (Gamma, Gamma', DF, the
    #: restricted and deflated maps, the eigenvalue workspace); the Jacobians of the corrector
    #: and the admissibility test's sinusoid sums (measured: 0.65 GB at N = 1000)
    MEMORY_DOUBLES_PER_N2: ClassVar[float] = 100.0
    #: run time per point (s) ~ A N^2 + B N^3: the exact admissibility (critical points of u_c,
    #: O(N) sinusoids on O(N) sub-intervals) and ~30 eigenvalue problems of size 2N per point
    #: (multiplier crossings located by bisection), measured on a 2-core machine (1 s per point
    #: at N = 100, 4 s at N = 200, ~45 s at N = 1000)
    SECONDS_PER_POINT_N2: ClassVar[float] = 1e-4
    SECONDS_PER_POINT_N3: ClassVar[float] = 4e-8
    #: up to this many dofs the multipliers are the dense eigenvalues (:meth:`floquet_dense`:
    #: below ~40 dofs LAPACK beats the O(N^2) iteration's per-sweep overhead), above it they
    #: come from the structure (:meth:`floquet`); the Krein definiteness always does
    DENSE_MULTIPLIERS_UP_TO: ClassVar[int] = 40
    #: above this many dofs the engine's bordered systems are solved from the structure
    #: (:meth:`bordered_factor`, O(N^2)); up to it, dense (LAPACK is cheaper there, and the
    #: paper's chains keep the dense path they were validated with)
    DENSE_SOLVES_UP_TO: ClassVar[int] = 40
    #: largest relative error of omega_1^2 accepted from the modal analysis, ~ eps (w_N/w_1)^2
    MODAL_RESOLUTION: ClassVar[float] = 1e-6

    def memory_estimate(self) -> float:
        """Bytes a run of this chain needs (dense N x N and 2N x 2N matrices)."""
        return 8.0 * self.MEMORY_DOUBLES_PER_N2 * float(self.N) ** 2

    def seconds_per_point(self) -> float:
        N = float(self.N)
        return self.SECONDS_PER_POINT_N2 * N**2 + self.SECONDS_PER_POINT_N3 * N**3

    @property
    def _size_key(self) -> str:
        return "parameters.chain.dofs" if self.params.chain is not None else "parameters.M"

    def check_size(self) -> None:
        """Refuse a chain whose dense matrices exceed the memory limit (before building them)."""
        check_budget(self._size_key, f"{self.N} dofs", memory_bytes=self.memory_estimate())

    def _check_time(self, n_branches: int, max_points: int, what: str = "",
                    setup: float = 0.0) -> None:
        seconds = 2.0 * n_branches * max_points * self.seconds_per_point() + setup
        check_budget(self._size_key,
                     f"{self.N} dofs with continuation.max_points = {max_points} (2 directions"
                     f" x {n_branches} branch{'es' if n_branches != 1 else ''}{what}, "
                     "multipliers at every point)", seconds=seconds)

    def _check_modal(self) -> None:
        """The modal analysis succeeds and resolves omega_1 (relative error ~ eps (w_N/w_1)^2)."""
        omega = self.omega  # raises ValueError naming the parameters
        ratio = float(omega[-1] / omega[0])
        err = np.finfo(float).eps * ratio**2
        if err > self.MODAL_RESOLUTION:
            raise ValueError(
                f"{self._matrix_key}: the linear frequencies span omega_N / omega_1 = "
                f"{ratio:.3g}, so double precision resolves omega_1^2 only to ~{err:.1g} "
                f"(relative; at most {self.MODAL_RESOLUTION:g} accepted): make the masses and "
                "stiffnesses less disparate")
        for name, v in (("omega_N", omega[-1]), ("omega_1", omega[0])):
            if not 1e-100 <= v <= 1e100:
                raise ValueError(f"{self._matrix_key}: the linear frequency {name} = {v:.3g} "
                                 "is outside [1e-100, 1e100]: rescale masses and stiffnesses")

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Everything checkable before computing (``window``: bounds on ``T``):

        * sizes: the dense matrices within ``NSM_CONTINUATION_MAX_MEMORY_GB``
          (:meth:`memory_estimate`, ``MEMORY_DOUBLES_PER_N2 N^2`` doubles) and the run time
          ``2 x branches x max_points x`` :meth:`seconds_per_point` within
          ``NSM_CONTINUATION_MAX_HOURS``; only then the modal analysis (O(N^3)) is done, here,
          once (it is reused by the run);
        * the modal analysis succeeds (finite matrices, ``K`` positive definite) and resolves
          ``omega_1`` (:data:`MODAL_RESOLUTION`); frequencies in ``[1e-100, 1e100]``;
        * ``start.mode <= N``, ``gap != 0`` for a mode start, the start period ``k T_j`` (mode,
          subharmonic) or ``T`` inside the window (a start outside it computes nothing);
          ``all: true`` needs both window ends, and its number of branches (the poles
          ``k T_j`` in the window, ``k <= max_subharmonic``) enters the time estimate.

        The gap range (``0`` or ``1e-100 <= |g| <= 1e100``) is checked with the parameters
        (:func:`nsm_continuation.core.preflight.check_gap`).
        """
        lo, hi = window
        for T in (lo, hi):
            if T is not None and not (np.isfinite(T) and T > 0):
                raise ValueError(f"continuation: continuation.min/max give the period bound "
                                 f"T = {T:g}, not a positive finite number")
        items = as_list(START_ADAPTER.validate_python(start))
        self.check_size()
        for i, s in items:
            if isinstance(s, ModeStart):
                key = start_key(i, "mode")
                if s.mode > self.N:
                    raise ValueError(f"{key}: {s.mode} is beyond the {self.N} modes of the "
                                     f"chain (1..{self.N})")
                if self.g == 0.0:
                    raise ValueError(f"{key}: a start at a linear grazing orbit needs "
                                     "parameters.gap != 0 (for gap = 0 use start: {all: true})")
            elif isinstance(s, AllStart) and (lo is None or hi is None):
                raise ValueError(f"{start_key(i, 'all')}: needs continuation.min and "
                                 "continuation.max (the window whose branches are computed)")
            elif isinstance(s, PeriodStart):
                self._check_in_window(start_key(i, "T"), "the start period T", s.T, window)
        n_explicit = sum(1 for _, s in items if not isinstance(s, AllStart))
        self._check_time(max(n_explicit, 1), max_points)
        self._check_modal()
        n_all, setup = 0, 0.0
        for i, s in items:
            if isinstance(s, ModeStart):
                j, k = s.mode - 1, s.subharmonic
                self._check_in_window(start_key(i, "subharmonic" if k > 1 else "mode"),
                                      f"the pole k T_j = {k} T_{s.mode}", k * self.T_lin[j],
                                      window)
            elif isinstance(s, AllStart):
                assert lo is not None and hi is not None
                n_all += self.count_poles(lo, hi, s.max_subharmonic) + 1
                # the roots of w_N between the poles (k <= 10 max_subharmonic) seed the gaps:
                # a 400-point grid of w_N (O(N) each) and a root polish per interval
                n_int = self.count_poles(1e-12, hi, 10 * s.max_subharmonic) + 1
                setup += n_int * (4e-6 * self.N + 5e-4)
        if n_all:
            self._check_time(n_explicit + n_all, max_points,
                             ", one per pole k T_j in the window", setup)

    @staticmethod
    def _check_in_window(key: str, what: str, T: float,
                         window: tuple[float | None, float | None]) -> None:
        lo, hi = window
        if (lo is not None and T < lo) or (hi is not None and T > hi):
            show = (f"T in [{lo if lo is not None else -np.inf:.6g}, "
                    f"{hi if hi is not None else np.inf:.6g}]")
            raise ValueError(f"{key}: {what} = {T:.6g} (omega = {2 * np.pi / T:.6g}) lies "
                             f"outside the continuation window ({show}, from "
                             "continuation.min/max): a branch starting there computes nothing")

    def count_poles(self, T_lo: float, T_hi: float, kmax: int) -> int:
        """Number of poles ``k T_j`` (``k <= kmax``) in ``[T_lo, T_hi]``, in O(N)."""
        T = self.T_lin
        k_lo = np.maximum(np.ceil(T_lo / T), 1)
        k_hi = np.minimum(np.floor(T_hi / T), kmax)
        return int(np.sum(np.maximum(k_hi - k_lo + 1, 0)))

    def monitor_names(self) -> list[str]:
        return ["T", "omega", "energy", "v_out", "w_N"]

    # ------------------------------------------------------------------ lazy data
    @cached_property
    def _matrices(self) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(over="ignore", invalid="ignore"):  # checked in _modal
            return self.params.matrices()

    @property
    def M(self) -> np.ndarray:
        """Mass matrix (built on first use)."""
        return self._matrices[0]

    @property
    def K(self) -> np.ndarray:
        """Stiffness matrix (built on first use)."""
        return self._matrices[1]

    @property
    def _matrix_key(self) -> str:
        return "parameters.chain" if self.params.chain is not None else "parameters.K"

    @cached_property
    def _modal(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Modal data (2.9) ``P^T M P = I, P^T K P = Omega^2``: ``(omega, P, P^-1)``, computed
        on first use (O(N^3)); raises ``ValueError`` naming the parameters if it fails."""
        M, K = self.M, self.K
        if not (np.isfinite(M).all() and np.isfinite(K).all()):
            raise ValueError(f"{self._matrix_key}: the mass or stiffness matrix overflows "
                             "(an entry beyond 1.8e308)")
        try:
            w2, P = generalized_eigh(K, M)
        except (np.linalg.LinAlgError, ValueError) as exc:
            raise ValueError(f"{self._matrix_key}: the modal analysis K P = M P Omega^2 "
                             f"failed ({str(exc).splitlines()[0]})") from None
        if not np.all(np.isfinite(w2)) or np.any(w2 <= 0):
            raise ValueError(f"{self._matrix_key}: K must be positive definite (rigid-body "
                             "modes are excluded)")
        return np.sqrt(w2), P, P.T @ M

    @property
    def omega(self) -> np.ndarray:
        """Linear frequencies ``omega_j`` (ascending)."""
        return self._modal[0]

    @property
    def P(self) -> np.ndarray:
        """Mass-normalised mode shapes (columns)."""
        return self._modal[1]

    @property
    def Pinv(self) -> np.ndarray:
        return self._modal[2]

    @property
    def T_lin(self) -> np.ndarray:
        """Linear periods ``T_j = 2 pi / omega_j``."""
        return 2 * np.pi / self.omega

    @cached_property
    def a(self) -> np.ndarray:
        """Interaction coefficients (2.11) ``a_j = P_cj (P^-1)_jc``."""
        return self.P[self.c, :] * self.Pinv[:, self.c]

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
            return ca.vertcat(modal, u0[c] - self.g)
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
        return ca.vertcat(uT - u0, vel[keep], u0[c] - self.g)

    # ------------------------------------------------------------------ linear algebra
    def _structured_solves(self) -> bool:
        return self.formulation == "half_angle" and self.N > self.DENSE_SOLVES_UP_TO

    @cached_property
    def _Pinv_slogdet(self) -> tuple[float, float]:
        sign, logdet = np.linalg.slogdet(self.Pinv)
        return float(sign), float(logdet)

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
        return DiagonalBorderedFactor(sh, C, R, E, Pi, P, self._Pinv_slogdet)

    def residual_and_factor(self, y: np.ndarray, row: np.ndarray
                            ) -> tuple[np.ndarray, BorderedFactor]:
        if not self._structured_solves():
            return super().residual_and_factor(y, row)
        return self.evaluate(y), self.bordered_factor(y, row)

    # ------------------------------------------------------------------ state helpers
    def state(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Physical initial state ``(u(0), u'(0+))`` on the section and the period."""
        N = self.N
        y = np.asarray(y, dtype=float)
        if self.formulation == "half_angle":
            du = np.zeros(N)
            du[self.c] = y[N]
            return y[:N].copy(), du, float(y[-1])
        return y[:N].copy(), y[N:2 * N].copy(), float(y[-1])

    def y_from_state(self, u0: np.ndarray, du0: np.ndarray, T: float) -> np.ndarray:
        if self.formulation == "half_angle":
            return np.concatenate([u0, [du0[self.c]], [T]])
        return np.concatenate([u0, du0, [T]])

    def w_vector(self, T: float | np.ndarray) -> np.ndarray:
        """``w(T) = P Phi(T) P^-1 e_c`` (4.1b); ``Phi = Omega^-1 cot(T Omega / 2)``."""
        phi = 1.0 / (self.omega * np.tan(self.omega * np.asarray(T)[..., None] / 2))
        return (phi * self.Pinv[:, self.c]) @ self.P.T

    def w_N(self, T: float | np.ndarray) -> np.ndarray:
        """``w_N(T) = sum_j a_j / (w_j tan(w_j T / 2))`` (3.1), for the impacting dof."""
        T = np.asarray(T, dtype=float)
        return np.sum(self.a / (self.omega * np.tan(np.multiply.outer(T, self.omega) / 2)),
                      axis=-1)

    def closed_form(self, T: float, g: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Initial data (4.2)/(7.1): ``u(0) = (g / w_N) w(T)``, ``u'(0+) = (g / w_N) e_c``."""
        g = self.g if g is None else g
        w = self.w_vector(T)
        v = g / w[self.c]
        du = np.zeros(self.N)
        du[self.c] = v
        return v * w, du

    def gamma(self, T: float) -> tuple[np.ndarray, np.ndarray]:
        """``Gamma(T)`` of (A.1) (flight then impact, physical coordinates) and ``dGamma/dT``."""
        P, Pi, w, c = self.P, self.Pinv, self.omega, self.c
        cw, sw = np.cos(w * T), np.sin(w * T)
        S = np.ones(self.N)
        S[c] = -1.0

        def blocks(cc: np.ndarray, ss: np.ndarray) -> np.ndarray:
            return np.block([[(P * cc) @ Pi, (P * (ss / w)) @ Pi],
                             [S[:, None] * ((P * (-w * ss)) @ Pi), S[:, None] * ((P * cc) @ Pi)]])

        G = blocks(cw, sw)
        # d/dT cos = -w sin, d/dT sin = w cos
        dG = np.block([[(P * (-w * sw)) @ Pi, (P * cw) @ Pi],
                       [S[:, None] * ((P * (-w**2 * cw)) @ Pi),
                        S[:, None] * ((P * (-w * sw)) @ Pi)]])
        return G, dG

    def displacement_sum(self, y: np.ndarray) -> TrigSum:
        """``u_c(t)`` on ``0 < t < T`` as a sum of sinusoids (5.4)."""
        u0, du0, _ = self.state(y)
        q = self.Pinv @ u0
        p = self.Pinv @ du0
        Pc = self.P[self.c, :]
        return TrigSum(Pc * q, Pc * p / self.omega, self.omega.copy())

    #: samples per period of :meth:`orbit`: at least this many, and at least
    #: ``ORBIT_SAMPLES_PER_OSCILLATION`` per period of the fastest mode
    ORBIT_SAMPLES: ClassVar[int] = 600
    ORBIT_SAMPLES_PER_OSCILLATION: ClassVar[int] = 40

    def orbit(self, y: np.ndarray, periods: int = 1) -> OrbitTrace:
        """The orbit at ``y`` in closed form: from the post-impact state ``(u(0), u'(0+))``
        the free flight of the linear chain (eqs. 2.9-2.10, (5.4) for ``u_c``),
        ``u(t) = P (cos(Omega t) q + Omega^-1 sin(Omega t) p)`` with ``q = P^-1 u(0)``,
        ``p = P^-1 u'(0+)``, on ``[0, T]`` (the last sample is the state ``u'(T-)`` before
        the impact), repeated ``periods`` times (the impact law ``u_c'+ = -u_c'-`` maps the
        state at ``T-`` to the one at ``0``: a fixed point of the return map). Signals
        ``u1..uN``, ``du1..duN``; views: ``u_c`` against ``t / T`` (Figs. 5.2, 5.7), the phase
        portrait ``(u_c, u_c')`` (Fig. 5.10) and the manifold ``(u_{c-1}, u_c, u_c')``
        (Figs. 5.4-5.9, 7.2, 7.4); an impact mark at every ``t = k T``."""
        u0, du0, T = self.state(y)
        w = self.omega
        q, p = self.Pinv @ u0, self.Pinv @ du0
        n = max(self.ORBIT_SAMPLES,
                int(np.ceil(self.ORBIT_SAMPLES_PER_OSCILLATION * w.max() * T / (2 * np.pi))))
        s = np.linspace(0.0, T, n)
        wt = np.multiply.outer(s, w)
        cw, sw = np.cos(wt), np.sin(wt)
        U = (cw * q + sw * (p / w)) @ self.P.T
        dU = (-sw * (w * q) + cw * p) @ self.P.T
        k = int(periods)
        t = np.concatenate([s + j * T for j in range(k)])
        signals: dict[str, np.ndarray] = {}
        labels: dict[str, str] = {}
        for i in range(self.N):
            signals[f"u{i + 1}"] = np.tile(U[:, i], k)
            signals[f"du{i + 1}"] = np.tile(dU[:, i], k)
            labels[f"u{i + 1}"] = rf"displacement $u_{{{i + 1}}}$"
            labels[f"du{i + 1}"] = rf"velocity $\dot u_{{{i + 1}}}$"
        return OrbitTrace(t=t, period=T, signals=signals, labels=labels,
                          marks=[(j * T, "impact") for j in range(k + 1)],
                          views=self.orbit_signal_views())

    def orbit_signal_views(self) -> dict[str, tuple[str, ...]]:
        """The views of :meth:`orbit` with their signals: ``u_c`` against ``t / T``, the phase
        portrait ``(u_c, u_c')`` and, for ``N > 1``, the manifold ``(u_{c-1}, u_c, u_c')``
        (the neighbour ``u_2`` for ``c = 1``)."""
        c = f"{self.c + 1}"
        views: dict[str, tuple[str, ...]] = {"time": (f"u{c}",), "phase": (f"u{c}", f"du{c}")}
        if self.N > 1:
            other = self.c if self.c > 0 else 2  # the neighbour of the impacting dof (1-based)
            views["manifold"] = (f"u{other}", f"u{c}", f"du{c}")
        return views

    def orbit_view_names(self) -> tuple[str, ...]:
        """The views of :meth:`orbit_signal_views` (no manifold for one degree of freedom)."""
        return tuple(self.orbit_signal_views())

    # ------------------------------------------------------------------ hooks
    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        """Definition 2.2 decided from the closed form (no sampling):

        * ``outgoing_velocity = -u_c'(0+) / (|g| w_1)`` > 0: the mass leaves the wall (H+);
        * ``clearance = (g - max u_c(t_k)) / |g|`` over the critical points ``t_k`` of ``u_c`` in
          ``(0, T)``, located exactly (:class:`~problems.chain.trig_sum.TrigSum`); it vanishes at a
          nonlinear grazing orbit (an extra tangential contact, Fig. 5.2). Computed as
          ``-max (u_c(t_k) - u_c(t_ref)) / |g|``, the rise from the nearer impact ``t_ref = 0``
          or ``T`` (:meth:`~problems.chain.trig_sum.TrigSum.rise`; ``u_c(0) = u_c(T) = g`` on
          the branch, the residual's last row and the periodicity, so the value is the same to
          the residual, ~1e-16). The difference ``g - u_c(t_k)`` would keep only its rounding
          for a critical point next to an impact: past a linear grazing orbit (the outgoing
          velocity through zero) a maximum enters at ``t = 0+`` above the wall by
          ``O(v^2)``, and the clearance's sign there would be noise, its zero located up to
          ~1e-9 in ``T`` away from the grazing as a second event.

        For ``g = 0`` (sec. 7.2) the gap gives no scale: the orbit's own amplitude
        ``A = max(|u(0)|_inf, |u_c'(0+)| / w_1)`` does (:meth:`_static_grazing_scale`), so both
        tests are homogeneous of degree 0 in ``(u(0), v)``: constant along each half ``v < 0``,
        ``v > 0`` of a vertical family (7.5)-(7.6), admissible on the half ``v < 0`` of an
        admissible root only (Prop. 7.2, sign corrected: module docstring). The static
        equilibrium ``u = 0`` (``A = 0``, the trivial branch) has no test: it is admissible
        (proof of Prop. 7.2).
        """
        u0, du0, T = self.state(y)
        scale = abs(self.g) if self.g != 0.0 else self._static_grazing_scale(u0, du0)
        if scale == 0.0:
            return {}
        f = self.displacement_sum(y)
        tc = f.critical_points(0.0, T)
        clearance = 1.0
        if tc.size:
            rise = f.rise(tc, np.where(tc < 0.5 * T, 0.0, T))
            clearance = -float(rise.max()) / scale
        return {"outgoing_velocity": -du0[self.c] / (scale * self.omega[0]),
                "clearance": float(clearance)}

    def _static_grazing_scale(self, u0: np.ndarray, du0: np.ndarray) -> float:
        """Amplitude ``A = max(|u(0)|_inf, |u_c'(0+)| / w_1)`` of a ``g = 0`` orbit, the scale
        of its admissibility tests (0 at the static equilibrium)."""
        return float(max(np.max(np.abs(u0)), abs(du0[self.c]) / self.omega[0]))

    def return_map_jacobian(self, y: np.ndarray) -> np.ndarray:
        """``DF`` of (A.8) in physical coordinates (2N x 2N): ``Gamma + (Gamma' x) grad T`` with
        ``grad T = -e_c^T Gamma / (e_c^T Gamma' x)`` (A.7). Row ``c`` vanishes (F(H) in H)."""
        u0, du0, T = self.state(y)
        x = np.concatenate([u0, du0])
        G, dG = self.gamma(T)
        dGx = dG @ x
        denom = dGx[self.c]  # = u_c'-(T) = -u_c'(0+)
        gradT = -G[self.c, :] / denom
        return G + np.outer(dGx, gradT)

    def return_map_structure(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """The linearised first return map (3.5)/(A.8) as a rotation plus a rank-two term.

        Energy coordinates ``z = (xi, eta)``, ``xi = Omega P^-1 u``, ``eta = P^-1 u'`` (the
        energy is ``|z|^2 / 2``, the symplectic form ``omega = sum_j d xi_j ^ d eta_j / w_j``).
        In them the flight over ``T`` is the orthogonal block rotation ``D`` (block ``j``:
        ``[[cos w_j T, sin w_j T], [-sin w_j T, cos w_j T]]``, eigenvalues ``exp(+-i w_j T)``,
        eigenvectors ``(1, +-i)/sqrt 2``), the impact ``u_c' -> -u_c'`` is
        ``J = I - 2 e_b a_eta^T`` (``b = P^-1 e_c``, ``a = P^T e_c``: a Householder reflector
        when ``M_ck = 0``), and the period gradient (A.7) ``grad T = -h^T D / (h^T f)``
        (``h``: the row of ``u_c``, ``f``: the vector field at the pre-impact state ``D z0``) so
        that (A.8) reads ``DF = J (I - f h^T / h^T f) D``: the *saltation* form,

        ``DF = (I + U V^T) D``,  ``U = [-2 e_b, -J f / (h^T f)]``,  ``V = [a_eta, h]``.

        In the eigenbasis ``Q`` of ``D`` this is ``diag(mu) + X Y^T`` with ``mu_(j,+-) =
        exp(+-i w_j T)``, ``X = Q^H U``, ``Y = diag(mu) Q^T V`` (n x 2): the input of
        :func:`~nsm_continuation.core.floquet.low_rank_update_eigen`. The symplectic form's
        Hermitian
        form ``-i omega(conj v, v)`` is diagonal there, with weights ``+-1/w_j``
        (``krein_weights``). Also returned: ``D``'s angles, ``U``, ``V`` (for
        :meth:`return_map_apply`) and ``z0``.
        """
        th, _, _, U, V, xi0, eta0 = self._saltation(y)
        w = self.omega
        r2 = np.sqrt(0.5)
        ep, em = np.exp(1j * th), np.exp(-1j * th)
        n = w.size
        Uxi, Ueta = U[:n], U[n:]
        Vxi, Veta = V[:n], V[n:]
        X = np.concatenate([(Uxi - 1j * Ueta) * r2, (Uxi + 1j * Ueta) * r2])
        Y = np.concatenate([(Vxi + 1j * Veta) * (r2 * ep)[:, None],
                            (Vxi - 1j * Veta) * (r2 * em)[:, None]])
        return {"mu": np.concatenate([ep, em]), "X": X, "Y": Y,
                "krein_weights": np.concatenate([1.0 / w, -1.0 / w]), "angles": th,
                "U": U, "V": V, "z0": np.concatenate([xi0, eta0])}

    def _saltation(self, y: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(theta, cos theta, sin theta, U, V, xi0, eta0)`` of :meth:`return_map_structure`:
        the flight's angles ``theta_j = w_j T``, the saltation factors ``U = [-2 e_b,
        -J f / (h^T f)]``, ``V = [a_eta, h]`` (``DF = (I + U V^T) D``) and the post-impact state
        ``z0 = (xi0, eta0)`` in energy coordinates; shared with :meth:`_krein_dense` (which
        needs neither ``X``, ``Y`` nor a second evaluation of the sines and cosines)."""
        u0, du0, T = self.state(y)
        w, Pi = self.omega, self.Pinv
        a = self.P[self.c, :]
        b = Pi[:, self.c]
        xi0, eta0 = w * (Pi @ u0), Pi @ du0
        th = w * T
        c, s = np.cos(th), np.sin(th)
        xim, etam = c * xi0 + s * eta0, -s * xi0 + c * eta0  # pre-impact state D z0
        fxi, feta = w * etam, -w * xim                         # vector field there
        hf = float(a @ etam)                                   # h^T f = u_c'-(T) = -v
        Jfeta = feta - 2.0 * b * float(a @ feta)
        n = w.size
        # U = [[0, fxi], [-2 b, J feta]] / [1, -hf], V = [[0, a / w], [a, 0]] (columns)
        U = np.empty((2 * n, 2))
        U[:n, 0] = 0.0
        U[n:, 0] = -2.0 * b
        U[:n, 1] = fxi / -hf
        U[n:, 1] = Jfeta / -hf
        V = np.zeros((2 * n, 2))
        V[n:, 0] = a
        V[:n, 1] = a / w
        return th, c, s, U, V, xi0, eta0

    @staticmethod
    def return_map_apply(st: dict[str, np.ndarray], z: np.ndarray) -> np.ndarray:
        """``DF z = (I + U V^T) D z`` in energy coordinates, O(N) (``st`` from
        :meth:`return_map_structure`)."""
        n = st["angles"].size
        c, s = np.cos(st["angles"]), np.sin(st["angles"])
        Dz = np.concatenate([c * z[:n] + s * z[n:], -s * z[:n] + c * z[n:]])
        return Dz + st["U"] @ (st["V"].T @ Dz)

    def energy_coordinates(self, du: np.ndarray, ddu: np.ndarray) -> np.ndarray:
        """``z = (Omega P^-1 u, P^-1 u')`` of a physical state (or perturbation)."""
        return np.concatenate([self.omega * (self.Pinv @ du), self.Pinv @ ddu])

    @property
    def conservative(self) -> bool:
        """Whether the return map is symplectic (Krein signatures apply: :mod:`palc` step
        control): the impact conserves energy iff ``M_ck = 0`` for ``k != c`` (Prop. 6.1)
        (:attr:`nsm_continuation.core.problem.Problem.conservative`)."""
        return self.g != 0.0 and not np.any(np.delete(self.M[self.c, :], self.c) != 0.0)

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """Non-trivial multipliers of the linearised first return map (3.5), from its structure
        (:meth:`return_map_structure`, O(N^2)): the roots of
        ``det(DF_W - lam) = prod_m (mu_m - lam) det(I_3 + Y^T (diag(mu) - lam)^-1 X)``, with
        ``DF_W = DF - t l^T / (l^T t)`` Wielandt's deflation of the trivial ``1`` to ``0``
        (:meth:`_deflated_update`: right eigenvector the branch tangent ``t``, eq. 6.5, left
        one ``grad E``), less the double root ``0`` (that one and the section normal's,
        sec. 6.1), divided out of the characteristic polynomial exactly
        (:func:`~nsm_continuation.core.floquet.low_rank_update_eigen`). Up to
        ``DENSE_MULTIPLIERS_UP_TO`` dofs the dense eigenvalues (:meth:`floquet_dense`) are
        used instead. With them the Krein definiteness of each multiplier, computed when
        first asked (:class:`~nsm_continuation.core.floquet.KreinFloquetData`; its sign is the Krein
        signature on the unit circle). ``trivial_error`` is ``|DF t - t| / |t|`` plus
        ``|h^T DF|`` (the section row, eq. A.10), both O(N). The iteration starts from the
        multipliers computed at the nearest points among the last calls, extrapolated
        (:meth:`_nearest_guess`); it falls back to :meth:`floquet_dense` when it does not
        converge (counted in ``floquet_fallbacks``)."""
        r = self._family_direction(y, tangent)
        if r is None:
            return None
        if self.N <= self.DENSE_MULTIPLIERS_UP_TO:
            # small chains: the dense eigenvalues are cheaper than the iteration's overhead;
            # the Krein definiteness is computed at them from the structure (no iteration),
            # when asked for
            dense = self.floquet_dense(y, tangent)
            if dense is None:
                return None
            mult = np.asarray(dense.multipliers, dtype=complex)

            def source() -> np.ndarray:
                return self._krein_dense(y, mult)

            return KreinFloquetData(mult, trivial_error=dense.trivial_error,
                                    matrix_norm=dense.matrix_norm, krein_source=source)
        st = self.return_map_structure(y)
        X, Y, removed = self._deflated_update(st, r)
        start = self._nearest_guess(y)
        out = None if start is None else low_rank_update_eigen(
            st["mu"], X, Y, removed=removed, guess=start[0])
        lineage = None if start is None else start[1]
        if out is None:
            out, lineage = low_rank_update_eigen(st["mu"], X, Y, removed=removed), None
        if out is None:
            self.floquet_fallbacks += 1
            return self.floquet_dense(y, tangent)
        mult, _, _ = out
        self._remember_multipliers(y, mult, lineage)
        res = np.linalg.norm(self.return_map_apply(st, r) - r) / np.linalg.norm(r)
        U, V = st["U"], st["V"]
        # |h^T DF| / |h|: h^T U = (0, -1) and V[:, 1] = h make the section row vanish
        h = V[:, 1]
        sec = float(np.linalg.norm(h @ U + np.array([0.0, 1.0]))) * float(np.linalg.norm(V))
        # Frobenius norm of DF = (I + U V^T) D (D orthogonal), in O(N)
        n2 = U.shape[0] + 2.0 * np.trace(V.T @ U) + float(np.sum((U.T @ U) * (V.T @ V)))
        mult = np.asarray(mult, dtype=complex)
        # symplectic (Prop. 6.1): off the circle kappa = 0 exactly, not computed
        off = self.KREIN_OFF_CIRCLE if self.conservative else None
        return KreinFloquetData(
            mult, trivial_error=float(res + sec), matrix_norm=float(np.sqrt(max(n2, 0.0))),
            krein_source=lambda: krein_definiteness(st["mu"], X, Y, mult, st["krein_weights"],
                                                    off_circle=off))

    def _family_direction(self, y: np.ndarray, tangent: np.ndarray) -> np.ndarray | None:
        """The branch tangent in energy coordinates (the trivial multiplier's eigenvector,
        eq. 6.5), or None where no multipliers are reported: at (numerically) exact grazing
        the return map is not differentiable (sec. 6, [21]: ``DF ~ 1/v``)."""
        u0, du0, _ = self.state(y)
        if self.g == 0.0 or abs(du0[self.c]) <= 1e-9 * abs(self.g) * self.omega[0]:
            return None
        du, ddu, _ = self.state(tangent)
        r = self.energy_coordinates(du, ddu)
        return None if np.linalg.norm(r) == 0.0 else r

    def multipliers_near(self, y: np.ndarray, tangent: np.ndarray, guesses: np.ndarray
                         ) -> np.ndarray | None:
        """The multipliers nearest to ``guesses`` (distinct) from the secular equation of
        :meth:`floquet` (:func:`~nsm_continuation.core.floquet.refine_roots`: O(N) per multiplier
        and sweep); up to ``DENSE_MULTIPLIERS_UP_TO`` dofs, where LAPACK is cheaper, the dense
        eigenvalues (:meth:`floquet_dense`) nearest to them."""
        if self.N <= self.DENSE_MULTIPLIERS_UP_TO:
            dense = self.floquet_dense(y, tangent)
            if dense is None:
                return None
            m = np.asarray(dense.multipliers, dtype=complex)
            picked: list[int] = []
            for g in np.asarray(guesses, dtype=complex):
                d = np.abs(m - g)
                d[picked] = np.inf
                picked.append(int(np.argmin(d)))
            return m[picked] if len(picked) <= m.size else None
        r = self._family_direction(y, tangent)
        if r is None:
            return None
        st = self.return_map_structure(y)
        X, Y, removed = self._deflated_update(st, r)
        return refine_roots(st["mu"], X, Y, np.asarray(guesses, dtype=complex),
                            removed=removed)

    def _krein_dense(self, y: np.ndarray, mult: np.ndarray) -> np.ndarray:
        """Krein definiteness of the multipliers ``mult`` from the dense eigenvectors of
        ``DF = (I + U V^T) D`` in energy coordinates (small chains: one LAPACK call beats the
        per-root work of :func:`~nsm_continuation.core.floquet.krein_definiteness`):
        ``kappa = g(v) / |v|^2``, ``g(v) = -i omega(conj v, v) = 2 sum_j Im(conj xi_j eta_j)
        / w_j``, ``|v|^2 = sum_j (|xi_j|^2 + |eta_j|^2) / w_j``; each multiplier takes the
        eigenvector of the nearest eigenvalue. ``D``, ``U``, ``V`` from :meth:`_saltation`
        (not the whole :meth:`return_map_structure`); ``D`` filled in place (the matrix
        ``np.block([[diag c, diag s], [-diag s, diag c]])``, negative zeros included)."""
        _, c, s, U, V, _, _ = self._saltation(y)
        n = self.N
        D = np.zeros((2 * n, 2 * n))
        D[n:, :n] = -0.0
        i = np.arange(n)
        D[i, i] = c
        D[i, i + n] = s
        D[i + n, i] = -s
        D[i + n, i + n] = c
        A = D + U @ (V.T @ D)
        lam, V = np.linalg.eig(A)
        V = V[:, np.argmin(np.abs(lam[None, :] - np.asarray(mult)[:, None]), axis=1)]
        xi, eta = V[:n], V[n:]
        iw = 1.0 / self.omega[:, None]
        g = 2.0 * ((np.conj(xi) * eta).imag * iw).sum(axis=0)
        nrm = ((np.abs(xi) ** 2 + np.abs(eta) ** 2) * iw).sum(axis=0)
        return g / nrm

    #: :meth:`floquet` of a conservative chain: multipliers farther than this from the unit
    #: circle (their accuracy is ~1e-10) are off it, with Krein definiteness 0 exactly
    #: (:func:`~nsm_continuation.core.floquet.krein_definiteness`, ``off_circle``)
    KREIN_OFF_CIRCLE: ClassVar[float] = 1e-6
    #: how many multiplier sets :meth:`floquet` remembers as starts
    MULTIPLIER_MEMORY: ClassVar[int] = 8
    #: :meth:`_nearest_guess`: a multiplier that moved more than this between the two
    #: nearest remembered points is not extrapolated (a jump, or not the same multiplier)
    EXTRAPOLATE_MAX_MOVE: ClassVar[float] = 0.05
    #: :meth:`_nearest_guess`: no extrapolation farther than this many secant lengths
    EXTRAPOLATE_MAX_SECANTS: ClassVar[float] = 2.0

    def _nearest_guess(self, y: np.ndarray) -> tuple[np.ndarray, int] | None:
        """The start of the Aberth iteration at the point ``y`` and its lineage: the
        multipliers ``m1`` remembered at the nearest point ``y1``, extrapolated linearly along
        the secant to the second nearest ``y2`` (multipliers ``m2``): ``m1 + s (m1 - m2)``
        with ``s = (y - y1).(y1 - y2) / |y1 - y2|^2`` (the projection of ``y`` on the line
        through ``y1`` and ``y2``; ``-1 < s < 0`` interpolates, as when an event is located
        inside a step). Only sets of one lineage pair by index (multiplier ``k`` of one set
        descends from multiplier ``k`` of the set it was started from); one that moved by
        more than ``EXTRAPOLATE_MAX_MOVE`` between ``y2`` and ``y1`` (a jump) is not
        extrapolated, nor is anything beyond ``EXTRAPOLATE_MAX_SECANTS``. The start only
        changes the number of sweeps, not the roots the iteration converges to."""
        if not self._multiplier_memory:
            return None
        y = np.asarray(y, dtype=float)
        mem = sorted(self._multiplier_memory, key=lambda e: float(np.linalg.norm(e[0] - y)))
        y1, m1, lin = mem[0]
        other = [e for e in mem[1:]
                 if e[2] == lin and e[1].shape == m1.shape and not np.array_equal(e[0], y1)]
        if not other:
            return m1, lin
        y2, m2, _ = other[0]
        dy = y1 - y2
        nn = float(dy @ dy)
        if nn == 0.0:
            return m1, lin
        step = float((y - y1) @ dy) / nn
        if not abs(step) <= self.EXTRAPOLATE_MAX_SECANTS:
            return m1, lin
        delta = m1 - m2
        return np.where(np.abs(delta) <= self.EXTRAPOLATE_MAX_MOVE, m1 + step * delta, m1), lin

    def _remember_multipliers(self, y: np.ndarray, mult: np.ndarray,
                              lineage: int | None) -> None:
        """Remember ``mult`` at ``y``; ``lineage`` None: a new lineage (a cold start)."""
        if lineage is None:
            self._lineages += 1
            lineage = self._lineages
        self._multiplier_memory.append((np.array(y, dtype=float), mult, lineage))
        del self._multiplier_memory[:-self.MULTIPLIER_MEMORY]

    @staticmethod
    def _deflated_update(st: dict[str, np.ndarray], r: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, tuple[float, ...]]:
        """``(X, Y, removed)`` of the map whose non-trivial spectrum is sought.

        The trivial multiplier 1 has the right eigenvector ``r = dz0/ds`` (the branch tangent,
        eq. 6.5) and the left eigenvector ``l = grad E = z0`` (energy conservation, proof of
        Corollary 3.1). Wielandt's deflation ``DF - r l^T / (l^T r)`` moves it to 0 and keeps
        every other eigenvalue (``l`` is orthogonal to their right eigenvectors): one more
        column of the update, and the removed roots are ``0, 0`` (section normal and the
        deflated 1), far from the unit circle where the multipliers that matter lie. (Dividing
        the 1 out of the characteristic polynomial instead leaves a cluster of three roots at
        +1 at a fold, resolved only to ~eps^(1/3).) Where ``l^T r = dE/ds`` vanishes (an
        energy extremum along the branch: 1 is then defective) the 1 is divided out."""
        z0 = st["z0"]
        lr = float(z0 @ r)
        if abs(lr) <= 1e-8 * np.linalg.norm(z0) * np.linalg.norm(r):
            return st["X"], st["Y"], (0.0, 1.0)
        n = z0.size // 2
        r2 = np.sqrt(0.5)
        qr = np.concatenate([(r[:n] - 1j * r[n:]) * r2, (r[:n] + 1j * r[n:]) * r2]) / -lr
        ql = np.concatenate([(z0[:n] + 1j * z0[n:]) * r2, (z0[:n] - 1j * z0[n:]) * r2])
        return (np.concatenate([st["X"], qr[:, None]], axis=1),
                np.concatenate([st["Y"], ql[:, None]], axis=1), (0.0, 0.0))

    def floquet_dense(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """The dense method (the oracle of :meth:`floquet`, O(N^3)): eigenvalues of ``DF`` (A.8)
        in physical coordinates restricted to the section (its row ``c`` vanishes, removing
        the extraneous 0) with the family direction deflated by a Householder reflector
        (removing the 1, eq. 6.5)."""
        u0, du0, _ = self.state(y)
        # at (numerically) exact grazing the return map is not differentiable (sec. 6, [21]):
        # DF ~ 1/v, so no multipliers are reported there
        if self.g == 0.0 or abs(du0[self.c]) <= 1e-9 * abs(self.g) * self.omega[0]:
            return None
        DF = self.return_map_jacobian(y)
        red = restrict_to_section(DF, self.c)
        du, ddu, _ = self.state(tangent)
        if self.formulation == "half_angle":
            ddu = np.zeros(self.N)
            ddu[self.c] = tangent[self.N]
        v = np.delete(np.concatenate([du, ddu]), self.c)
        if np.linalg.norm(v) == 0.0:
            return None
        B, lam, res = deflate_known_eigenvector(red, v)
        mult = np.linalg.eigvals(B) if B.size else np.empty(0, dtype=complex)
        norm = float(np.linalg.norm(B)) if B.size else 1.0  # Frobenius: cheap, >= 2-norm
        return FloquetData(np.asarray(mult, dtype=complex), trivial_error=abs(lam - 1.0) + res,
                           matrix_norm=norm)

    def energy(self, y: np.ndarray) -> float:
        u0, du0, _ = self.state(y)
        return 0.5 * float(du0 @ self.M @ du0 + u0 @ self.K @ u0)

    def derived(self, y: np.ndarray) -> dict[str, float]:
        u0, du0, T = self.state(y)
        return {"T": T, "omega": 2 * np.pi / T, "energy": self.energy(y),
                "v_out": float(du0[self.c]), "w_N": float(self.w_N(T))}

    # ------------------------------------------------------------------ starts and bounds
    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """User bounds on ``omega`` or ``T`` -> bounds on ``T`` (both are positive: a bound
        at or below zero has no meaning and is refused)."""
        for key, v in (("min", lo), ("max", hi)):
            if v is not None and v <= 0:
                raise ValueError(f"continuation.{key}: {name} = {v:g} is not positive (a "
                                 f"{'frequency' if name == 'omega' else 'period'} bound)")
        self._orientation = self.parameter_orientation(name)
        if name == "T":
            return lo, hi
        if name == "omega":
            return (None if hi is None else 2 * np.pi / hi,
                    None if lo is None else 2 * np.pi / lo)
        raise ValueError(f"continuation.parameter: {name!r} is not one of 'omega', 'T'")

    def parameter_orientation(self, name: str) -> int:
        """``T = 2 pi / omega`` falls as ``omega`` grows."""
        return -1 if name == "omega" else 1

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

    def restart_start(self, y: np.ndarray) -> dict[str, Any]:
        """A restart is checked as a start at its period ``{T: ...}`` (window, sizes)."""
        return {"T": float(y[-1])}

    def grazing_start(self, j: int, k: int) -> np.ndarray:
        """The linear grazing orbit (2.14) of mode ``j`` (0-based) at ``T = k T_j``: a point of
        the branch (Theorem 3.1: the Lipschitz extension of the nonlinear family)."""
        Pj = self.P[:, j]
        u0 = self.g / Pj[self.c] * Pj
        return self.y_from_state(u0, np.zeros(self.N), k * self.T_lin[j])

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        """Starts from the YAML ``start`` block; ``window`` = (T_min, T_max) for ``all``."""
        specs = START_ADAPTER.validate_python(start)
        specs = specs if isinstance(specs, list) else [specs]
        out: list[StartPoint] = []
        for s in specs:
            if isinstance(s, ModeStart):
                j, k = s.mode - 1, s.subharmonic
                if j >= self.N:
                    raise ValueError(f"start.mode: {s.mode} is beyond the {self.N} modes of "
                                     f"the chain (1..{self.N})")
                if self.g == 0.0:
                    raise ValueError("start.mode: a start at a linear grazing orbit needs "
                                     "parameters.gap != 0 (for gap = 0 use start: {all: true})")
                direction = 0 if s.side == "both" else -int(np.sign(self.a[j]))
                out.append(StartPoint(self.grazing_start(j, k), f"mode {s.mode}, k = {k}",
                                      direction, {"mode": s.mode, "subharmonic": k,
                                                  "pole_T": k * self.T_lin[j]}))
            elif isinstance(s, PeriodStart):
                u0, du0 = self.closed_form(s.T) if self.g != 0 else (np.zeros(self.N),
                                                                   np.zeros(self.N))
                out.append(StartPoint(self.y_from_state(u0, du0, s.T), f"T = {s.T:g}",
                                      s.direction * self._orientation,
                                      {"T0": s.T}))
            else:
                out.extend(self._all_starts(window, s.max_subharmonic))
        return out

    def _all_starts(self, window: tuple[float | None, float | None], kmax: int
                    ) -> list[StartPoint]:
        """Every branch in the window: for g != 0 one start per pole ``k T_j`` (the branch
        crosses the pole from its phantom to its admissible side) plus seeds in pole-free gaps;
        for g = 0 the trivial branch, whose branch points are the roots of ``w_N``."""
        lo, hi = window
        if lo is None or hi is None:
            raise ValueError("start: {all: true} needs continuation.min and continuation.max")
        if self.g == 0.0:
            y0 = self.y_from_state(np.zeros(self.N), np.zeros(self.N), lo)
            return [StartPoint(y0, "trivial branch (g = 0)", +1, {"trivial": True})]
        starts = [StartPoint(self.grazing_start(j, k), f"pole {k} T_{j + 1}", 0,
                             {"mode": j + 1, "subharmonic": k, "pole_T": T,
                              "skip_if_covered": True})
                  for T, j, k in self.poles(lo, hi, kmax)]
        # seeds between singularities that contain no pole (e.g. high frequencies T < T_N)
        pole_set = [p[0] for p in self.poles(lo, hi, kmax)]
        sing = sorted({lo, hi, *pole_set, *self.zeros_of_w_N(lo, hi, 10 * kmax).tolist()})
        for a, b in zip(sing[:-1], sing[1:], strict=False):
            if any(a - 1e-12 <= p <= b + 1e-12 for p in pole_set):
                continue
            Tm = 0.5 * (a + b)
            u0, du0 = self.closed_form(Tm)
            starts.append(StartPoint(self.y_from_state(u0, du0, Tm), f"T = {Tm:.6g}", 0,
                                     {"T0": Tm, "skip_if_covered": True}))
        return starts

    def poles(self, T_lo: float, T_hi: float, kmax: int) -> list[tuple[float, int, int]]:
        """Poles ``k T_j`` of ``w_N`` in ``[T_lo, T_hi]``: (T, mode j 0-based, k). Only the
        ``k`` near ``[T_lo, T_hi] / T_j`` are visited (O(number of poles), whatever ``kmax``)."""
        out = []
        for j, Tj in enumerate(self.T_lin):
            k_first = int(max(1.0, min(np.floor(T_lo / Tj), kmax + 1.0)))
            k_last = int(min(float(kmax), np.ceil(T_hi / Tj)))
            for k in range(k_first, k_last + 1):
                if T_lo <= k * Tj <= T_hi:
                    out.append((k * Tj, j, k))
        return sorted(out)

    def zeros_of_w_N(self, T_lo: float, T_hi: float, kmax: int = 1000) -> np.ndarray:
        """Roots of ``w_N`` in ``(T_lo, T_hi)``: each sign change of ``w_N`` on a grid of 400
        points between consecutive poles, closed by the Illinois iteration to ``1e-15 + 4 eps T``
        (a pole between two grid points is not a root: ``|w_N|`` must be small there)."""
        poles = [p[0] for p in self.poles(1e-12, T_hi * (1 + 1e-12), kmax)]
        edges = sorted({T_lo, T_hi, *[p for p in poles if T_lo < p < T_hi]})
        roots = []
        for lo, hi in zip(edges[:-1], edges[1:], strict=False):
            eps = 1e-9 * (hi - lo)
            grid = np.linspace(lo + eps, hi - eps, 400)
            vals = self.w_N(grid)
            for i in np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]:
                r = illinois(lambda t: (float(self.w_N(t)), None), grid[i], float(vals[i]),
                             grid[i + 1], float(vals[i + 1]),
                             tol=1e-15 + 4 * np.finfo(float).eps * grid[i + 1], close=True)[0]
                if abs(self.w_N(r)) < 1e-6 * (1 + abs(vals[i]) + abs(vals[i + 1])):
                    roots.append(r)
        return np.array(roots)

    def polish_root(self, T0: float) -> float:
        """Root of ``w_N`` near ``T0`` by Newton on the closed form (``w_N' < 0`` between poles
        when every ``a_j > 0``; falls back to ``T0`` if Newton leaves the neighbourhood)."""
        T = T0
        for _ in range(50):
            h = 1e-7 * T
            d = (self.w_N(T + h) - self.w_N(T - h)) / (2 * h)
            step = float(self.w_N(T) / d)
            T -= step
            if abs(step) < 1e-15 * T:
                break
        return float(T) if abs(T - T0) < 1e-3 * T0 else float(T0)

    def static_grazing_admissible(self, T: float) -> bool:
        """For ``g = 0``: the orbit ``x = v (w(T), e_c)`` with ``v < 0`` (Prop. 7.2, sign
        corrected) is admissible iff ``u_c <= 0`` on ``(0, T)``; its shape is ``v``-independent."""
        u0, du0 = self.closed_form(T, g=1.0)  # direction only: scale by v = -1
        scale = -1.0 / du0[self.c]
        y = self.y_from_state(u0 * scale, du0 * scale, T)
        umax, _ = self.displacement_sum(y).max_on(0.0, T)
        return bool(umax <= 1e-12 * np.max(np.abs(u0 * scale)))

    def grazing_energy(self, j: int) -> float:
        """Energy of the linear grazing orbit of mode ``j`` (0-based): top of its flat part."""
        return 0.5 * (self.g / self.P[self.c, j]) ** 2 * self.omega[j] ** 2

    def internal_resonances(self, kmax: int = 10, rtol: float = 1e-9) -> list[str]:
        """Pairs ``k T_j = l T_i`` (i != j, k, l <= kmax): Assumption 3.1 violated there."""
        out = []
        for j in range(self.N):
            for i in range(j + 1, self.N):
                r = self.omega[i] / self.omega[j]
                for lden in range(1, kmax + 1):
                    knum = round(r * lden)
                    if 1 <= knum <= kmax and abs(r * lden - knum) < rtol * r * lden:
                        out.append(f"internal resonance: {knum} T_{i + 1} = {lden} T_{j + 1} "
                                   f"(omega_{i + 1}/omega_{j + 1} = {knum}/{lden}); "
                                   "Assumption 3.1 is violated and branches through these "
                                   "poles are not covered by Theorem 3.1")
                        break
        return out

    def warnings(self) -> list[str]:
        w = self.internal_resonances()
        off = np.delete(self.M[self.c, :], self.c)
        if np.any(off != 0.0):
            w.append("M couples the impacting dof to the others (M_ck != 0): the impact law "
                     "u_c'+ = -u_c'- does not conserve energy (Prop. 6.1)")
        if np.any(np.abs(self.a) < 1e-12):
            w.append("an interaction coefficient a_j vanishes (Assumption 2.1 violated)")
        return w

    def summary(self) -> dict[str, Any]:
        return {"N": self.N, "impacting_dof": self.c + 1, "gap": self.g,
                "omega_linear": self.omega.tolist(), "T_linear": self.T_lin.tolist(),
                "interaction_coefficients": self.a.tolist(),
                "alpha": float(np.sum(self.a / self.omega**2)),
                "formulation": self.formulation}


    # ------------------------------------------------------------------ report and figure hooks
    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """Fig. 3.2 references: linear frequencies (thick) and subharmonics w_j / k (thin); for
        g > 0 the flat (linear, contact-free) part of each mode up to its linear grazing energy
        (for g < 0 there is none, Prop. 7.1); for g = 0 the
        discrete spectrum (roots of w_N, Prop. 7.2) found on ``branches``."""
        import matplotlib.pyplot as plt

        lo, hi = x_range
        lo, hi = lo - 0.02 * (hi - lo), hi + 0.02 * (hi - lo)
        colors = plt.get_cmap("tab10")
        kmax = self.SUBHARMONIC_KMAX
        for j, w in enumerate(self.omega):
            for k in range(1, kmax + 1):
                if lo <= w / k <= hi:
                    ax.axvline(w / k, color=colors(j % 10), lw=1.6 if k == 1 else 0.5,
                               alpha=0.8 if k == 1 else 0.5, zorder=1)
            # g < 0: no contact-free (linear) orbit exists, u_c = 0 is beyond the wall
            # (sec. 7.1: the spectrum is not connected to the linear one)
            if lo <= w <= hi and self.g > 0.0:
                ax.plot([w, w], [1e-300, self.grazing_energy(j)], color=colors(j % 10), lw=3.2,
                        solid_capstyle="butt", zorder=4)
        if self.g == 0.0:
            for T in [s["T"] for s in self.static_grazing_spectrum(branches)]:
                w = 2 * np.pi / T
                if lo <= w <= hi:
                    ax.axvline(w, color="tab:green", lw=1.8, ls="--", zorder=2)


    def legend_handles(self) -> list[Any]:
        from matplotlib.lines import Line2D

        h = [Line2D([], [], color="tab:blue", lw=1.6, label=r"linear $\omega_j$ (colour = mode)"),
             Line2D([], [], color="tab:blue", lw=0.5, label=r"subharmonics $\omega_j/k$")]
        if self.g > 0.0:
            h.append(Line2D([], [], color="tab:blue", lw=3.2, label="linear (flat) part of a mode"))
        elif self.g == 0.0:
            h.append(Line2D([], [], color="tab:green", lw=1.8, ls="--",
                            label=r"roots of $w_N$ (g = 0 spectrum)"))
        return h


    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        out: dict[str, Any] = {
            "linear_grazing_energies": [float(self.grazing_energy(j)) if self.g != 0 else 0.0
                                        for j in range(self.N)]}
        graz = []
        for br in branches:
            for ev in br.events:
                if ev.kind == "grazing" and ev.data.get("tests") == ["clearance"]:
                    graz.append({"branch": br.id, "T": ev.point.derived["T"],
                                 "omega": ev.point.derived["omega"],
                                 "energy": ev.point.derived["energy"],
                                 "admissible_before": ev.data.get("admissible_before")})
        if graz:
            out["nonlinear_grazing_orbits"] = graz
        if self.g == 0.0:
            out["static_grazing_spectrum"] = self.static_grazing_spectrum(branches)
        return out

    def static_grazing_spectrum(self, branches: list[Any]) -> list[dict[str, Any]]:
        """For g = 0 (Prop. 7.2): each branch point of ``branches`` polished to a root of
        ``w_N``, with its admissibility. Cached for the last list of branches (the report and
        the figure both use it; the branches are compared by identity)."""
        if self.g != 0.0:
            return []
        hit = self._spectrum_cache
        if hit is not None and len(hit[0]) == len(branches) and all(
                a is b for a, b in zip(hit[0], branches, strict=True)):
            return [dict(s) for s in hit[1]]
        spec = []
        for br in branches:
            for ev in br.events:
                if ev.kind == "branch_point":
                    T_bp = float(ev.point.y[-1])
                    T = self.polish_root(T_bp)
                    spec.append({"T": T, "omega": 2 * np.pi / T, "T_branch_point": T_bp,
                                 "w_N(T_branch_point)": float(self.w_N(T_bp)),
                                 "admissible": self.static_grazing_admissible(T)})
        self._spectrum_cache = (list(branches), spec)
        return [dict(s) for s in spec]


    def extra_plots(self, out_dir: Any, branches: list[Any],
                          window: tuple[float | None, float | None]) -> list[str]:
        """Fig. 3.1: w_N(T) with its poles k T_j and zeros."""
        import matplotlib.pyplot as plt

        lo, hi = window
        lo = lo if lo is not None else 0.05 * self.T_lin[-1]
        hi = hi if hi is not None else 1.2 * self.T_lin[0]
        T = np.linspace(lo, hi, 20000)
        wn = self.w_N(T)
        kmax = self.SUBHARMONIC_KMAX
        # created at the file's dpi: tight_layout and savefig lay the text out once
        fig, ax = plt.subplots(figsize=(9, 4.5), dpi=130)
        poles = self.poles(lo, hi, kmax)
        wn_plot = np.where(np.abs(wn) > 50 * np.median(np.abs(wn)), np.nan, wn)
        ax.plot(T, wn_plot, color="k", lw=1.0)
        cmap = plt.get_cmap("tab10")
        for Tp, j, k in poles:
            ax.axvline(Tp, color=cmap(j % 10), lw=1.4 if k == 1 else 0.6, alpha=0.8)
        zeros = self.zeros_of_w_N(lo, hi)
        ax.plot(zeros, np.zeros_like(zeros), "o", color="tab:green", ms=4, label=r"zeros of $w_N$")
        ax.axhline(0, color="0.5", lw=0.6)
        ax.set_xlabel("period T [s]")
        ax.set_ylabel(r"$w_N(T) = \sum_j a_j \cot(\omega_j T/2)/\omega_j$")
        ax.set_title(r"Fig. 3.1: $w_N$; poles at $kT_j$ (coloured by mode, thick: k = 1)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.25)
        fig.tight_layout()
        fig.savefig(Path(out_dir) / "w_N.png", dpi=130)
        plt.close(fig)
        return ["w_N.png"]


def simulate_first_return(problem: NDofImpactProblem, u0: np.ndarray, du0: np.ndarray,
                          t_max: float, rtol: float = 1e-13, atol: float = 1e-15
                          ) -> tuple[np.ndarray, np.ndarray, float]:
    """Event-driven simulation of the chain (scipy DOP853 on ``M u'' + K u = 0``) from a state on
    the section to the next impact ``u_c = g`` (crossing upwards), then the impact law.

    Independent of the modal closed form: used as the oracle for ``DF`` (finite differences of
    this map) and for the closed-form orbits.
    """
    from scipy.integrate import solve_ivp

    N, c, g = problem.N, problem.c, problem.g
    Minv_K = np.linalg.solve(problem.M, problem.K)

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        return np.concatenate([z[N:], -Minv_K @ z[:N]])

    def hit(_t: float, z: np.ndarray) -> float:
        return z[c] - g

    hit.terminal = True  # type: ignore[attr-defined]
    hit.direction = 1.0  # type: ignore[attr-defined]
    z0 = np.concatenate([u0, du0])
    # the event function is only checked at step ends: a short excursion above the wall (a
    # near-grazing return) could hide inside one step, so steps are capped well below the
    # shortest linear period
    max_step = float(problem.T_lin.min()) / 200.0
    sol = solve_ivp(rhs, (0.0, t_max), z0, method="DOP853", rtol=rtol, atol=atol,
                    events=hit, dense_output=False, max_step=max_step)
    if not sol.t_events[0].size:
        raise RuntimeError("no impact before t_max")
    T = float(sol.t_events[0][0])
    z = sol.y_events[0][0].copy()
    z[c] = g
    u, du = z[:N], z[N:]
    du = du.copy()
    du[c] = -du[c]
    return u, du, T


def chain_case_matrices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The paper's example (2.17): ``m = 1/N``, ``k = N``."""
    return ChainSpec(dofs=n, mass=1.0 / n, stiffness=float(n)).matrices()


__all__ = ["NDofImpactProblem", "NDofParameters", "simulate_first_return", "chain_case_matrices"]

