"""The records a continuation produces: :class:`Point` (one solution and everything computed
there), :class:`Event` (a located change along a branch) and :class:`Branch`. Every algorithm
(:mod:`nsm_continuation.palc`, :mod:`nsm_continuation.lattice`) returns them, and the outputs
(:mod:`nsm_continuation.results`, :mod:`nsm_continuation.plots`) read only them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

EVENT_KINDS = (
    "fold",
    "branch_point",
    "period_doubling",
    "neimark_sacker",
    "stability_change",
    "grazing",
    "endpoint",
    # lattice problems (nsm_continuation.lattice): energy without bound, change of phase pattern
    "asymptote",
    "pattern_change",
    # hybrid (impacting) systems with chattering (nsm_continuation.hybrid)
    "sticking_lost",
    "impact_sequence_change",
    "homoclinic_approach",
)


@dataclass
class Event:
    """A located event. ``point`` is the branch point (a ``continuation.Point``) where it sits."""

    kind: str
    point: Any
    detail: str = ""
    data: dict[str, Any] = field(default_factory=dict)
    #: width of the final bracket in arclength (the location accuracy actually achieved)
    bracket: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in EVENT_KINDS:
            raise ValueError(f"unknown event kind {self.kind!r}")


@dataclass
class Point:
    """One solution on a branch, with everything computed there."""

    y: np.ndarray
    s: float
    tangent: np.ndarray
    tests: dict[str, float]
    multipliers: np.ndarray | None
    trivial_error: float
    n_unstable: int
    derived: dict[str, float]
    bordered_det: float
    newton_iterations: int = 0
    residual_norm: float = 0.0
    #: unit-circle tolerance actually used at this point (see ContinuationEngine.analyse)
    circle_tol: float = 0.0
    #: the problem's discrete signature (e.g. the event sequence of a hybrid orbit), if any
    signature: str | None = None

    @property
    def admissible(self) -> bool:
        return all(v >= 0.0 for v in self.tests.values())

    @property
    def stable(self) -> bool | None:
        if self.multipliers is None:
            return None
        return self.n_unstable == 0

    @property
    def max_abs_multiplier(self) -> float:
        if self.multipliers is None or self.multipliers.size == 0:
            return float("nan") if self.multipliers is None else 1.0
        return float(np.max(np.abs(self.multipliers)))


@dataclass
class Branch:
    """A continued branch: points ordered by arclength, located events, termination reasons."""

    id: int
    label: str
    points: list[Point]
    events: list[Event]
    termination: dict[str, str]
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def n_points(self) -> int:
        return len(self.points)
