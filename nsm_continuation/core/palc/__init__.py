"""Pseudo-arclength continuation (Keller) with event detection; problem-agnostic.

* :mod:`~nsm_continuation.core.palc.engine`: :class:`ContinuationEngine`, the corrector, the
  tangent, the analysis of a point and the step loop;
* :mod:`~nsm_continuation.core.palc.step_control`: the step length and the checks of a step;
* :mod:`~nsm_continuation.core.palc.motion`: how far the Floquet multipliers move in a step;
* :mod:`~nsm_continuation.core.palc.locate`: the events of a step located on its arc;
* :mod:`~nsm_continuation.core.palc.folds`: when a sign change of the tangent is a fold;
* :mod:`~nsm_continuation.core.palc.crossings`: multiplier crossings and Krein collisions;
* :mod:`~nsm_continuation.core.palc.kinks`: kinks of the branch and moves to another chart;
* :mod:`~nsm_continuation.core.palc.asymptote`: branches that run to infinite amplitude;
* :mod:`~nsm_continuation.core.palc.ends`: branches that end at a boundary of their family;
* :mod:`~nsm_continuation.core.palc.loops`: branches that close on themselves (isolas);
* :mod:`~nsm_continuation.core.palc.errors`: how a step fails.
"""

from nsm_continuation.core.palc.asymptote import ASYMPTOTE_GROWTH, ASYMPTOTE_POINTS
from nsm_continuation.core.palc.crossings import CrossingLocator, crossing_events
from nsm_continuation.core.palc.engine import ContinuationEngine
from nsm_continuation.core.palc.errors import (
    HOOK_FAULTS,
    NUMERICAL_ERRORS,
    MonitorError,
    RetryStep,
    describe_error,
    describe_fault,
)
from nsm_continuation.core.palc.kinks import Kink, KinkCrosser, KinkCrossing
from nsm_continuation.core.palc.locate import EventLocator, EventSource, StepEvents
from nsm_continuation.core.palc.motion import (
    KREIN_CLOSING,
    KREIN_NEAR,
    OUTSIDE_TRAVEL,
    krein_closing,
    krein_motion,
    krein_motion_ratio,
    multiplier_motion,
)
from nsm_continuation.core.palc.step_control import (
    MOTION_LATTICE,
    MOTION_TARGET,
    STEP_RESOLUTION,
    TEST_STEP_FACTOR,
    Step,
    StepController,
    Trial,
)

__all__ = ["ASYMPTOTE_GROWTH", "ASYMPTOTE_POINTS", "HOOK_FAULTS", "KREIN_CLOSING", "KREIN_NEAR",
           "MOTION_LATTICE", "MOTION_TARGET", "NUMERICAL_ERRORS", "OUTSIDE_TRAVEL",
           "STEP_RESOLUTION", "TEST_STEP_FACTOR", "ContinuationEngine",
           "CrossingLocator", "EventLocator", "EventSource", "Kink", "KinkCrosser",
           "KinkCrossing", "MonitorError", "RetryStep", "Step", "StepController",
           "StepEvents", "Trial", "crossing_events", "describe_error", "describe_fault",
           "krein_closing", "krein_motion", "krein_motion_ratio", "multiplier_motion"]
