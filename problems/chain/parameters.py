"""The YAML schema of ``problem: ndof_impact`` and the sizing of a run.

Legrand, Junca, Heng (2017): the chain of eq. (2.17) (:class:`ChainSpec`) or general SPD
matrices ``M``, ``K`` (eq. 2.5), the gap ``g``, the impacting dof ``c`` and the restitution
``e = 1`` (:class:`NDofParameters`); the start blocks (:class:`ModeStart`: a linear grazing orbit
(2.14) or its subharmonic, :class:`PeriodStart`: the closed form (4.2) at a period,
:class:`AllStart`: every branch of a window) and :data:`START_ADAPTER`. :class:`ChainSizing`
estimates the memory and time of a run before anything of size ``N^2`` is built.
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import (
    BaseModel,
    Discriminator,
    Field,
    Tag,
    field_validator,
    model_validator,
)

from nsm_continuation.core.preflight import (
    STRICT,
    check_budget,
    check_gap,
    exactly,
    one_or_many,
)
from nsm_continuation.core.vocabulary import CanonicalNames

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class ChainSpec(CanonicalNames):
    """The spring-mass chain of eq. (2.17): wall - k_1 - m_1 - k_2 - ... - k_N - m_N (free end);
    ``dofs`` is the paper's ``N`` (the old key ``n`` is deprecated)."""

    model_config = STRICT
    deprecated_names = {"n": "dofs"}
    key_path = "parameters.chain"
    #: the number of masses (the paper's ``N``)
    dofs: Annotated[int, Field(ge=1)]
    #: the masses ``m_i``: one value for all, or one per mass
    mass: Positive | list[Positive]
    #: the spring stiffnesses ``k_i``: one value for all, or one per spring
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
    #: the spring-mass chain of eq. (2.17) (or give ``M`` and ``K``)
    chain: ChainSpec | None = None
    #: an explicit mass matrix (symmetric positive definite; with ``K``, instead of ``chain``)
    M: list[list[Finite]] | None = None
    #: an explicit stiffness matrix (symmetric positive definite; with ``M``)
    K: list[list[Finite]] | None = None
    #: the gap ``g``: the wall at ``u_c = gap``; > 0 open, 0 static grazing, < 0
    #: pre-stressed
    gap: Finite
    #: the impacting dof ``c`` (1-based; default the last, ``N``)
    impacting_dof: Annotated[int, Field(ge=1)] | None = None
    #: the restitution ``e``: must be 1 (the families exist only for a purely elastic
    #: impact)
    restitution: Finite = 1.0
    #: the residual: ``half_angle`` (``N + 1`` equations in ``u(0), v, T``, full rank
    #: through the linear grazing orbits) or ``shooting`` (``(Gamma(T) - I) x = 0`` less the
    #: redundant row)
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
    #: the mode ``j``: start at its linear grazing orbit, at the period ``k T_j``
    mode: Annotated[int, Field(ge=1)]
    #: ``k``: start at the pole ``k T_j`` (1: the mode itself)
    subharmonic: Annotated[int, Field(ge=1)] = 1
    #: 'admissible' continues towards a_j (T - k T_j) < 0 only; 'both' also through the pole
    side: Literal["admissible", "both"] = "admissible"


class PeriodStart(BaseModel):
    """Start from the closed form (4.2) at a given period."""

    model_config = STRICT
    #: the period at which the closed form (4.2) gives the start
    T: Positive
    #: which way along ``continuation.parameter`` the branch is followed: 1, -1 or
    #: 0 (both)
    direction: Annotated[Literal[-1, 0, 1], exactly(-1, 0, 1)] = 0


class AllStart(BaseModel):
    """Every branch in the continuation window: one start per pole ``k T_j`` (k <= max), plus
    seeds in the pole-free gaps; a pole already crossed by a computed branch is skipped."""

    model_config = STRICT
    #: ``true``: every branch of the window
    all: Annotated[Literal[True], exactly(True)]
    #: the highest ``k`` of the poles ``k T_j`` started from
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


def chain_case_matrices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The paper's example (2.17): ``m = 1/N``, ``k = N``."""
    return ChainSpec(dofs=n, mass=1.0 / n, stiffness=float(n)).matrices()


class ChainSizing:
    """Sizes of a run of the chain, checked before the dense matrices are built (a mixin of
    :class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`)."""

    N: int
    params: NDofParameters

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
