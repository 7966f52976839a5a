"""The records a continuation produces: :class:`Point` (one solution and everything computed
there), :class:`Event` (a located change along a branch) and :class:`Branch`. Every algorithm
(:mod:`nsm_continuation.core.palc`, :mod:`nsm_continuation.core.lattice`) returns them, and the
outputs
(:mod:`nsm_continuation.output.files`, :mod:`nsm_continuation.figures.branches`) read only them.
:class:`OrbitTrace` is the periodic orbit at one point, sampled in time
(:meth:`nsm_continuation.core.presentation.Presentation.orbit`), drawn by
:mod:`nsm_continuation.figures.orbits`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: the event kinds of the core, raised by any algorithm for any problem: kind -> one-line
#: meaning (written in ``report.md``). A problem family adds its own kinds with their meanings
#: (``Problem.event_kinds``, registered by :func:`register_event_kinds` when the class is
#: defined).
CORE_EVENT_KINDS: dict[str, str] = {
    "fold": "a limit point: the continuation parameter reaches an extremum along the branch "
            "(the tangent test), where a multiplier passes +1; in a conservative family a "
            "multiplier pair colliding at +1, where the family turns in energy",
    "branch_point": "two solution curves cross: det of the bordered Jacobian changes sign, and "
                    "a real multiplier passes +1 where the parameter does not turn (a "
                    "symmetry-breaking pitchfork or a transcritical point)",
    "period_doubling": "a multiplier passes through -1: a family of period-2T orbits bifurcates",
    "neimark_sacker": "a complex pair leaves the unit circle away from +-1 (for a conservative "
                      "system, after a Krein collision): quasi-periodic motion nearby",
    "unresolved_crossing": "the number of multipliers counted outside the unit circle "
                           "changes, but the multiplier responsible is not resolved beyond "
                           "the multipliers' noise on both sides of the circle: no bifurcation "
                           "is claimed (the bracket is where the count changes)",
    "stability_change": "the number of multipliers outside the unit circle becomes zero or "
                        "non-zero",
    "grazing": "an admissibility test or event function reaches zero: the orbit touches the "
               "obstacle tangentially (nonlinear grazing) or leaves it with zero velocity "
               "(linear grazing). Where the test is an admissibility test the orbit beyond it "
               "is a phantom; where it is an event function an impact is born or vanishes and "
               "the branch goes on with the changed event sequence",
    "endpoint": "end of the computed branch (bound reached or numerical termination)",
    "asymptote": "a monitored quantity (the energy, the size of the unknowns) grows without "
                 "bound as the parameter approaches a limit (estimated from the last points)",
}

#: how the engines locate each core kind (kind -> one line; the event glossary of the docs).
#: "Located on the curve" is a zero found between two points of the branch by Illinois regula
#: falsi with Dekker's closing step, to ``analysis.event_tol`` in arclength
#: (:mod:`nsm_continuation.core.palc.locate`)
CORE_EVENT_LOCATION: dict[str, str] = {
    "fold": "a sign change of the tangent's parameter component, located on the curve (a +1 "
            "crossing of the same step is that fold); in a conservative family a pair "
            "colliding at +1, located as neimark_sacker "
            "(:mod:`nsm_continuation.core.palc.branch_points`)",
    "branch_point": "a sign change of the bordered determinant ``det[G_y; t^T]`` (tangents "
                    "oriented continuously), located on the curve, or from the cubic through "
                    "its values at resolved points on both sides where the corrector cannot "
                    "converge near it; merged with the +1 crossing of the same step",
    "period_doubling": "the count of multipliers outside ``1 + analysis.unit_circle_tol`` "
                       "changes over a step: bisection on the count (to "
                       "``analysis.multiplier_event_tol``), then the zero of ``|lambda| - 1`` "
                       "of the crossing multiplier, located on the curve "
                       "(:mod:`nsm_continuation.core.palc.crossings`)",
    "neimark_sacker": "as period_doubling; in a conservative family a Krein collision is "
                      "located on the colliding pair's discriminant ``(nu_1 - nu_2)^2``, and a "
                      "window opened and closed inside one step is found from the Krein signs "
                      "at its ends (:mod:`nsm_continuation.core.floquet.krein`)",
    "unresolved_crossing": "not located: recorded at the bracket where the count of "
                           "multipliers outside the circle changes, the multiplier responsible "
                           "staying within the multipliers' noise on one side",
    "stability_change": "with the crossing that makes the number of unstable multipliers zero "
                        "or non-zero (at a grazing, where the multipliers jump, at the "
                        "grazing)",
    "grazing": "the zero of the admissibility test or event function that raises it, located "
               "on the curve (a parabola through the last three values finds a double zero "
               "inside one step); a kink there is crossed by the problem "
               "(``Problem.continue_beyond``). The lattice engine: where the number of grazing "
               "instants changes between two consecutive points",
    "endpoint": "where the branch ends: an edge of the ``continuation`` window or a "
                "``continuation.bounds`` entry, located on the bound; ``max_points``; a "
                "closed loop (the branch returned to its start, walked once); or a "
                "numerical termination, at the last point, with its reason",
    "asymptote": "not located: a monitored quantity fits ``|p - p*|^(-k)`` over the last "
                 "points and has grown a hundredfold; ``p*`` is extrapolated "
                 "(:mod:`nsm_continuation.core.palc.asymptote`) and the branch ends",
}

#: kinds declared by the problem families defined so far (kind -> declaring class)
_FAMILY_KINDS: dict[str, str] = {}


def register_event_kinds(kinds: dict[str, str], owner: str) -> None:
    """Register the event kinds a problem family declares (``Problem.event_kinds``), so that
    :class:`Event` accepts them. A family may not redefine a core kind."""
    for kind in kinds:
        if kind in CORE_EVENT_KINDS:
            raise TypeError(f"{owner}: event kind {kind!r} is a core kind; declare a new name")
        _FAMILY_KINDS.setdefault(kind, owner)


#: the termination reason of a direction whose start lies outside the parameter window
START_OUTSIDE = "start outside parameter bounds"
#: the termination reason of a half-branch that closed a loop (it returned to its start, or met
#: the end of its other half: :mod:`nsm_continuation.core.palc.loops`) begins with these words
CLOSED_LOOP = "closed loop"
#: the key of :attr:`Branch.info` (and of a start's ``info``) that holds a warning about how
#: the start was found (e.g. a transient that has not settled on a periodic orbit): the
#: report lists it among its warnings, with the start orbit's stability
START_WARNING = "start_warning"

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
        if self.kind not in CORE_EVENT_KINDS and self.kind not in _FAMILY_KINDS:
            raise ValueError(f"unknown event kind {self.kind!r} (neither a core kind nor "
                             "declared in a problem's event_kinds)")


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
    #: values of the problem's event functions (``Problem.event_functions``): a zero between
    #: two points is located and raises an event, but never ends the branch
    event_values: dict[str, float] = field(default_factory=dict)
    #: the chart of ``y`` when the problem moved to another one on the way
    #: (``Problem.rechart``; ``Problem.in_chart`` gives its problem); None: the problem's own
    chart: dict[str, float] | None = None
    #: the admissibility tests this point lies on the zero of by construction (a point of a
    #: two-parameter grazing curve is a located zero of its clearance test): their sign there
    #: is rounding, and :attr:`admissible` disregards them
    on_boundary: tuple[str, ...] = ()

    @property
    def admissible(self) -> bool:
        """Whether every admissibility test is non-negative (Problem.tests: the orbit is
        physical), those the point lies on the zero of by construction (:attr:`on_boundary`)
        excepted."""
        return all(v >= 0.0 for k, v in self.tests.items() if k not in self.on_boundary)

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

    def value(self, name: str, variables: Sequence[str], missing: Any = float("nan")) -> Any:
        """The quantity ``name`` here: a derived quantity, else the unknown of that name
        (``variables``: the problem's), else ``missing``. What the figures, the CSV columns and
        the orbit selection read."""
        if name in self.derived:
            return self.derived[name]
        if name in variables:
            return float(self.y[variables.index(name)])
        return missing


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

    @property
    def failed_start(self) -> bool:
        """Whether the start failed: no point (its correction failed), or a start outside the
        parameter window that no direction could leave (:data:`START_OUTSIDE`)."""
        return not self.points or (bool(self.termination) and all(
            str(v).startswith(START_OUTSIDE) for v in self.termination.values()))


@dataclass(frozen=True)
class OrbitTrace:
    """The periodic orbit at one point of a branch, sampled densely in time
    (:meth:`nsm_continuation.core.presentation.Presentation.orbit`; drawn by
    :mod:`nsm_continuation.figures.orbits`).

    ``t`` runs from 0 (the state the problem's unknowns describe: the post-impact state of the
    chain, the Poincare section of a hybrid orbit) over ``periods`` periods of length
    ``period``; an instant may appear twice (the states before and after an impact).
    ``signals`` are named time series sampled at ``t`` (e.g. ``u5``, ``du5``, ``X``, ``dY``),
    ``labels`` their axis labels (units, LaTeX), ``marks`` instants ``(t, kind)`` such as
    impacts, ``intervals`` spans ``(t0, t1, kind)`` such as sticking phases, and ``views`` the
    family's default views: ``"time": (signal, ...)`` (each against ``t / period``),
    ``"phase": (x, y)`` and optionally ``"manifold": (a, b, c)`` (a 3-D projection drawn for
    many orbits along a branch)."""

    t: np.ndarray
    period: float
    signals: dict[str, np.ndarray]
    labels: dict[str, str] = field(default_factory=dict)
    marks: list[tuple[float, str]] = field(default_factory=list)
    intervals: list[tuple[float, float, str]] = field(default_factory=list)
    views: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def label(self, name: str) -> str:
        """The axis label of signal ``name`` (its name if none is declared)."""
        return self.labels.get(name, name)

    def at(self, name: str, t: float) -> float:
        """Signal ``name`` at time ``t`` (linear interpolation between samples; at a repeated
        instant, the later sample: the state after an impact)."""
        k = int(np.searchsorted(self.t, t, side="right")) - 1
        k = min(max(k, 0), self.t.size - 1)
        if k + 1 < self.t.size and self.t[k + 1] > self.t[k] and t > self.t[k]:
            w = (t - self.t[k]) / (self.t[k + 1] - self.t[k])
            return float((1.0 - w) * self.signals[name][k] + w * self.signals[name][k + 1])
        return float(self.signals[name][k])
