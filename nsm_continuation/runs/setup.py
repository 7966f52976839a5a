"""What a run is built from a validated case: the engine's settings and parameter window
(:func:`settings_from_case`), and on a Dask worker the whole case, problem and algorithm again
from the case's input (:func:`rebuild_case`)."""

from __future__ import annotations

from typing import Any

from nsm_continuation.algorithms.registry import make_algorithm
from nsm_continuation.cases import registry
from nsm_continuation.cases.restart import configure
from nsm_continuation.cases.schema import Case
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.settings import ContinuationSettings


def settings_from_case(case: Case, problem: Problem) -> tuple[ContinuationSettings,
                                                              tuple[float | None, float | None]]:
    """The engine's settings from the case's ``continuation:`` and ``analysis:`` blocks, and the
    window of the problem's internal parameter (``continuation.min/max``)."""
    c, a = case.continuation, case.analysis
    lo, hi = problem.parameter_bounds(c.parameter, c.min, c.max)
    derived_bounds = ({problem.energy_quantity: (None, c.max_energy)}
                      if c.max_energy is not None and problem.energy_quantity else {})
    derived_bounds.update({k: (v[0], v[1]) for k, v in c.bounds.items()})
    settings = ContinuationSettings(
        step_initial=c.step.initial, step_min=c.step.min, step_max=c.step.max,
        max_points=c.max_points, newton_tol=c.newton_tol, max_angle=c.max_angle,
        param_min=lo, param_max=hi,
        derived_bounds=derived_bounds, energy_cap=c.max_energy,
        unit_circle_tol=a.unit_circle_tol, event_tol=a.event_tol,
        multiplier_event_tol=a.multiplier_event_tol, max_multiplier_step=a.max_multiplier_step,
        stop_on_inadmissible=a.stop_on_inadmissible, detect_bifurcations=a.bifurcations,
        stability_on_phantom=a.stability_on_phantom, stability=a.stability,
        # meant along continuation.parameter: along the internal parameter it may be reversed
        direction=({"both": 0, "increase": 1, "decrease": -1}[c.direction]
                   * problem.parameter_orientation(c.parameter)),
    )
    return settings, (lo, hi)


def registered_class(name: str | None) -> type[Problem] | None:
    """The class the registry builds for the problem ``name``, or None."""
    if name is None:
        return None
    try:
        return registry.get(name)
    except registry.UnknownProblemError:
        return None


def rebuild_case(raw_case: dict[str, Any], problem_class: type | None = None,
                 restart: tuple[Any, Any, Any] | None = None) -> tuple[Any, Any, Any, Any]:
    """On a worker: the case, problem, settings and algorithm, from the case's input alone
    (and the problem's class, sent by reference, when it is not registered: the Python API's
    own problems; it must be importable on the worker). ``restart``: the case's restart
    ``(spec, record, selection)`` (:class:`~nsm_continuation.cases.restart.Restart`), whose
    problem is not the registered one: the period-``2k`` problem of a switch at a period
    doubling, the run's period multiple (:func:`~nsm_continuation.cases.restart.configure`)."""
    case = Case.model_validate(raw_case)
    cls = problem_class or registry.get(case.problem)
    problem = cls(cls.Parameters.model_validate(case.parameters))
    if restart is not None:
        spec, record, selection = restart
        problem, _ = configure(problem, selection, spec, record, case.continuation.parameter)
    settings, window = settings_from_case(case, problem)
    algorithm = make_algorithm(case.continuation.algorithm or problem.algorithms[0], problem,
                               settings)
    return case, problem, window, algorithm
