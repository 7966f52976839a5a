"""Numerical settings of one continuation run, shared by every algorithm (the YAML
``continuation:`` and ``analysis:`` blocks map here: see
:func:`nsm_continuation.runner.settings_from_case`)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ContinuationSettings:
    """Numerical settings of one continuation run (the YAML ``continuation`` block maps here)."""

    step_initial: float = 1e-2
    step_min: float = 1e-9
    step_max: float = 0.2
    max_points: int = 400
    newton_tol: float = 1e-11
    newton_max_iter: int = 10
    max_angle: float = 0.25
    param_min: float | None = None
    param_max: float | None = None
    #: bounds on derived quantities, e.g. {"energy": (None, 1e3)}
    derived_bounds: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    unit_circle_tol: float = 1e-7
    event_tol: float = 1e-12
    stop_on_inadmissible: bool = False
    detect_bifurcations: bool = True
    #: compute Floquet multipliers (``Problem.floquet``); False (YAML ``analysis.stability:
    #: false``): the problem's ``floquet`` is never called and points carry no multipliers
    stability: bool = True
    stability_on_phantom: bool = False
    #: location tolerance (arclength) for multiplier crossings, found by bisection
    multiplier_event_tol: float = 1e-9
    #: largest move of a multiplier near the unit circle in one step (see multiplier_motion)
    max_multiplier_step: float = 0.02
    #: at most this many halvings of one step for multiplier motion (then the step is taken and
    #: counted in ``ContinuationEngine.motion_limited_steps``): multipliers that move fast for
    #: any step (near grazing, DF ~ 1/v; dense spectra at large N) must not stall the branch
    max_multiplier_halvings: int = 10
    #: 0: both directions from the start, +1 / -1: only towards increasing / decreasing parameter
    direction: int = 0
    #: location tolerance (arclength) of a change of the problem's event signature
    signature_event_tol: float = 1e-6
