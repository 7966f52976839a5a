"""Numerical settings of one continuation run, shared by every algorithm (the YAML
``continuation:`` and ``analysis:`` blocks map here: see
:func:`nsm_continuation.runs.setup.settings_from_case`)."""

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
    #: the case's ``continuation.max_energy`` (None: unbounded): in ``derived_bounds`` for the
    #: problem's ``energy_quantity``, and handed to a lattice problem's seed search
    #: (:meth:`~nsm_continuation.core.lattice.LatticeProblem.lattice_seeds`)
    energy_cap: float | None = None
    #: a multiplier counts as outside the unit circle where ``|lambda| > 1 + unit_circle_tol``
    #: (the detector of crossings; their location does not depend on it)
    unit_circle_tol: float = 1e-7
    #: location tolerance (arclength) of zeros of continuous test functions: admissibility
    #: tests, event functions, folds, branch points, ``|lambda_c| - 1`` of multiplier crossings
    event_tol: float = 1e-12
    stop_on_inadmissible: bool = False
    detect_bifurcations: bool = True
    #: compute Floquet multipliers (``Problem.floquet``); False (YAML ``analysis.stability:
    #: false``): the problem's ``floquet`` is never called and points carry no multipliers
    stability: bool = True
    stability_on_phantom: bool = False
    #: bracket (arclength) of the bisection on the number of multipliers outside
    #: ``|lambda| = 1 + unit_circle_tol`` that detects a crossing; the crossing is then located
    #: on ``|lambda_c| = 1`` to ``event_tol`` (the count's location, this accurate, is kept
    #: where ``|lambda_c| - 1`` has no usable sign change: a conservative collision)
    multiplier_event_tol: float = 1e-9
    #: largest move of a multiplier near the unit circle in one step (see multiplier_motion);
    #: in a conservative family a multiplier outside the circle may also move by half its
    #: distance to it (:func:`palc.motion.krein_closing`, :func:`palc.motion._outside_travel`)
    max_multiplier_step: float = 0.02
    #: Krein-aware step control for conservative problems (``problem.conservative`` and
    #: multipliers with their Krein definiteness): only a multiplier that moves by at least
    #: ``krein_fraction`` of its distance to a collision partner (of the other Krein signature,
    #: or off the circle) is held to ``max_multiplier_step`` (:func:`palc.motion.krein_motion`);
    #: False: every multiplier near the circle is (:func:`palc.motion.multiplier_motion`)
    krein_step_control: bool = True
    krein_fraction: float = 0.25
    #: at most this many halvings of one step for multiplier motion (then the step is taken and
    #: counted in ``ContinuationEngine.motion_limited_steps``): multipliers that move fast for
    #: any step (near grazing, DF ~ 1/v; dense spectra at large N) must not stall the branch
    max_multiplier_halvings: int = 10
    #: 0: both directions from the start, +1 / -1: only towards increasing / decreasing parameter
    direction: int = 0
    #: location tolerance (arclength) of a change of the problem's event signature
    signature_event_tol: float = 1e-6
