"""Validation of a case: the schema, the problem built from its parameters, the problem's own
preflight of its start block, a restart's saved point: everything that can be checked without
computing. Every failure is a :class:`~nsm_continuation.core.errors.CaseError` whose one line
names the key; ``nsm-continuation validate`` is :func:`validate`, and ``run`` starts with it.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from nsm_continuation.cases import registry
from nsm_continuation.cases import restart as rs
from nsm_continuation.cases.schema import (
    ORBIT_POINT_WORDS,
    ORBIT_VIEWS,
    Case,
    _check_size,
    _format,
    _keyed,
    _reject_nan,
    apply_overrides,
    load_raw,
)
from nsm_continuation.core.errors import CaseError, short_text
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.vocabulary import canonical_keys


def validate(raw: dict[str, Any], *, restart_record: Any = None,
             problem_class: type[Problem] | None = None) -> tuple[Case, Problem]:
    """Validate a raw case, build its problem and run its preflight (:meth:`Problem.preflight`):
    everything that can be checked without computing. Raises :class:`CaseError` (one line
    naming the key). ``nsm-continuation validate`` is exactly this, and ``run`` starts with it,
    so the two agree on every input.

    A restart (``start: {from: <run folder>, ...}``, :mod:`nsm_continuation.cases.restart`) reads
    the run's restart record here (``restart_record``: a run in memory instead), inherits its
    problem, parameters, ``continuation`` and ``analysis``, and is checked like any start.
    ``problem_class``: the problem's class when it is not registered (the Python API)."""
    if not isinstance(raw, dict):
        raise CaseError("case: must be a mapping of keys")
    _check_size(raw, "case")
    _reject_nan(raw, "")
    resolved = None
    if isinstance(raw.get("start"), list) and any(rs.is_restart(s) for s in raw["start"]):
        raise CaseError("start: a restart (start.from) is one start mapping, not a list item")
    if rs.is_restart(raw.get("start")):
        resolved = rs.resolve(raw["start"], raw, restart_record)
        raw = resolved[3]
    try:
        case = Case.model_validate(raw)
    except ValidationError as err:
        raise CaseError(_format(err, raw)) from None
    if case.problem is None:
        raise CaseError("problem: required key is missing")
    if case.parameters is None:
        raise CaseError("parameters: required key is missing")
    try:
        cls = problem_class if problem_class is not None else registry.get(case.problem)
    except registry.UnknownProblemError as exc:
        raise CaseError(f"problem: {exc}") from None
    if not isinstance(case.parameters, dict):
        raise CaseError("parameters: must be a mapping of keys")
    if isinstance(case.start, list) and not case.start:
        raise CaseError("start: an empty list starts no branch")
    try:  # deprecated keys renamed first, so that an error names the key as it now reads
        raw_params = canonical_keys(cls.Parameters, case.parameters)
    except ValueError as exc:  # an old key together with its new one
        raise CaseError(str(exc)) from None
    user_params = raw_params
    if resolved is not None:  # the run's parameters, the case's on top
        raw_params = rs.merged_parameters(resolved[1], resolved[2], user_params)
        case.parameters = raw_params
    with plugin_hook(cls, case.problem, "in its Parameters validators"):
        try:
            params = cls.Parameters.model_validate(raw_params)
        except ValidationError as err:
            raise CaseError(_format(err, raw_params, "parameters")) from None
    with plugin_hook(cls, case.problem, "in __init__"):
        try:
            problem = cls(params)
        except (ValueError, ArithmeticError) as exc:
            raise CaseError(_keyed("parameters", str(exc))) from None
        check_unknowns(problem, case.problem)
    if case.continuation.parameter is None:  # not given: the problem's own parameter
        case.continuation.parameter = problem.case_parameter or problem.parameter
    adapter = cls.start_adapter
    if adapter is not None and resolved is None:
        try:
            adapter.validate_python(case.start)
        except ValidationError as err:
            raise CaseError(_format(err, case.start, "start")) from None
    c = case.continuation
    if c.algorithm is not None:
        from nsm_continuation.algorithms.registry import unsupported

        why = unsupported(c.algorithm, problem)
        if why is not None:
            raise CaseError(f"continuation.algorithm: {why}")
    # a two-parameter curve continues its own parameter (checked with the curve, in
    # _validate_restart), which the base problem may not be able to continue
    curve = resolved is not None and rs.curve_of(resolved[0], resolved[1]) is not None
    with plugin_hook(cls, case.problem, "in parameter_bounds or monitor_names"):
        try:
            window = ((c.min, c.max) if curve
                      else problem.parameter_bounds(c.parameter, c.min, c.max))
        except ValueError as exc:
            raise CaseError(_keyed("continuation.parameter", str(exc))) from None
        monitors = problem.monitor_names()
    for name in c.bounds:
        if name not in monitors:
            known = ", ".join(monitors) if monitors else "none declared"
            raise CaseError(f"continuation.bounds.{name}: not a quantity of problem "
                            f"{case.problem!r} (one of: {known})")
    if c.max_energy is not None and problem.energy_quantity is None:
        raise CaseError(f"continuation.max_energy: problem {case.problem!r} has no energy; "
                        "bound one of its quantities with continuation.bounds instead")
    if resolved is not None:
        problem = _validate_restart(case, problem, resolved, user_params, window)
        _check_diagram(case, problem)
        return case, problem
    _check_diagram(case, problem)
    preflight(problem, case, case.start, window)
    return case, problem


def preflight(problem: Problem, case: Case, start: Any,
              window: tuple[float | None, float | None]) -> None:
    """The problem's checks of ``start`` before computing: :meth:`Problem.sweep_preflight`
    for a run of the sweep algorithm, else :meth:`Problem.preflight`; a failure is a
    :class:`CaseError` naming the key."""
    c = case.continuation
    algorithm = c.algorithm or problem.algorithms[0]
    check = problem.sweep_preflight if algorithm == "sweep" else problem.preflight
    name = case.problem or problem.name
    if algorithm in RESIDUAL_ALGORITHMS:
        with plugin_hook(type(problem), name, "in residual"):
            check_residual(problem, name)
    with plugin_hook(type(problem), name, f"in {check.__name__}"):
        try:
            check(start, window, c.max_points)
        except (ValueError, ArithmeticError) as exc:
            raise CaseError(_keyed("start", str(exc))) from None


#: the algorithms that evaluate the problem's residual ``G`` (the others, ``lattice`` and
#: ``sweep``, solve through their own hooks)
RESIDUAL_ALGORITHMS = ("palc", "pycont")


@contextmanager
def plugin_hook(cls: type, name: str, what: str) -> Iterator[None]:
    """Calls into the code of problem class ``cls`` (registered as ``name``): an exception
    other than a :class:`CaseError`, or a ``SystemExit``, raised there by a plugin (a problem
    of another package) is the plugin's fault: a
    :class:`~nsm_continuation.cases.registry.PluginError` naming the problem, its
    ``module:Class``, ``what`` it was doing and the exception (exit status 2, nothing
    computed). In a bundled problem it is a bug of this package and goes on up."""
    try:
        yield
    except CaseError:
        raise
    except (Exception, SystemExit) as exc:
        if registry.is_bundled(cls):
            raise
        raise registry.plugin_fault(name, cls, what, exc) from None


def check_unknowns(problem: Problem, name: str) -> None:
    """A plugin's ``__init__`` set ``variables`` (the ``n + 1 >= 2`` unknowns' names) and
    ``parameter`` (one of them), which everything after reads: else a :class:`CaseError`
    naming the problem (bundled problems are tested)."""
    if registry.is_bundled(type(problem)):
        return
    where = f"problem: plugin {name!r} ({registry.target_of(type(problem))})"
    try:
        variables, parameter = problem.variables, problem.parameter
    except AttributeError as exc:
        raise CaseError(f"{where}: __init__ must set variables (the names of the n + 1 "
                        f"unknowns) and parameter (one of them): {exc}") from None
    if not (isinstance(variables, (list, tuple)) and len(variables) >= 2
            and all(isinstance(v, str) for v in variables)):
        raise CaseError(f"{where}: variables must be the names of the n + 1 >= 2 unknowns "
                        f"(set by __init__), got {short_text(repr(variables))}")
    if parameter not in variables:
        raise CaseError(f"{where}: parameter {short_text(repr(parameter))} is not one of its "
                        f"variables ({', '.join(variables)})")


def check_residual(problem: Problem, name: str) -> None:
    """A plugin's symbolic residual (:meth:`Problem.residual`, compiled by the engine) is a
    CasADi expression of the problem's symbol type with ``len(variables) - 1`` rows and one
    column: else a :class:`CaseError` naming the problem and the shapes, before the run
    would fail on its first evaluation. Built once more than the run does, so only for
    plugins (the bundled problems' shapes are tested, and the largest take seconds to build);
    a problem that evaluates numerically (:meth:`Problem.evaluate` or ``compiled``
    overridden) would need its start computed, and is not checked here."""
    cls = type(problem)
    numeric = (cls.compiled is not Problem.compiled or cls.evaluate is not Problem.evaluate
               or cls.jacobian is not Problem.jacobian
               or cls.evaluate_with_jacobian is not Problem.evaluate_with_jacobian)
    if registry.is_bundled(cls) or numeric:
        return
    import casadi as ca

    where = f"problem: plugin {name!r} ({registry.target_of(cls)})"
    if problem.symbolic not in ("SX", "MX"):
        raise CaseError(f"{where}: symbolic must be 'SX' or 'MX', got "
                        f"{short_text(repr(problem.symbolic))}")
    sym = ca.SX if problem.symbolic == "SX" else ca.MX
    g = problem.residual(sym.sym("y", problem.dim))
    if not isinstance(g, sym):
        raise CaseError(f"{where}: residual(y) must return a CasADi {problem.symbolic} "
                        f"expression of the symbol y, got {type(g).__name__}")
    expected = (problem.dim - 1, 1)
    if tuple(g.shape) != expected:
        raise CaseError(f"{where}: residual has shape {g.shape[0]} x {g.shape[1]} for "
                        f"{problem.dim} unknowns ({', '.join(problem.variables)}); continuation "
                        f"needs a column of len(variables) - 1 = {expected[0]} equations")


def diagram_quantities(problem: Problem) -> list[str]:
    """The names ``output.axes`` may give: the problem's unknowns, its declared derived
    quantities (``monitor_names``) and the columns of its diagram and CSV head."""
    show = problem.presentation
    names = [*problem.variables, *problem.monitor_names(), *show.fep_axes, *show.csv_head]
    return list(dict.fromkeys(names))


def _check_diagram(case: Case, problem: Problem) -> None:
    """``output.axes`` names quantities of the problem; ``analysis.branch_switching`` needs
    an algorithm that starts from points, and a problem that can represent what it asks for
    (orbits of twice the period at a period doubling: ``Problem.iterated``)."""
    axes = case.output.axes
    if axes is not None:
        known = diagram_quantities(problem)
        for i, name in enumerate(axes):
            if name not in known:
                raise CaseError(f"output.axes[{i}]: {name!r} is not a quantity of problem "
                                f"{case.problem!r} (one of: {', '.join(known)})")
    if case.output.orbits is not None:
        check_orbits(case.output.orbits.points, problem, "output.orbits",
                     case.output.orbits.views)
    spec = case.analysis.branch_switching
    if spec is None:
        return
    from nsm_continuation.algorithms.curves import CodimOneCurve

    if isinstance(problem, CodimOneCurve):
        raise CaseError("analysis.branch_switching: a two-parameter curve (start.curve) has no "
                        "branches born on it to follow; switch on the orbits' runs instead")
    from nsm_continuation.algorithms.registry import ALGORITHMS

    name = case.continuation.algorithm or problem.algorithms[0]
    algorithm = ALGORITHMS.get(name)
    if algorithm is not None and not algorithm.takes_start_points:
        raise CaseError(f"analysis.branch_switching: problem {case.problem!r} is continued by "
                        f"the {name} algorithm, which cannot start a branch at a detected "
                        "point")
    if "period_doubling" in spec.kinds and type(problem).iterated is Problem.iterated:
        raise CaseError(f"analysis.branch_switching.kinds: problem {case.problem!r} cannot "
                        "represent orbits of twice the period (Problem.iterated), so no branch "
                        "is born at its period doublings; list branch_point only")
    if not case.analysis.bifurcations:
        raise CaseError("analysis.branch_switching: needs analysis.bifurcations: true (the "
                        "branches start at the detected points)")


def check_orbits(points: list[str | float], problem: Problem, key: str,
                 views: Sequence[str] = ()) -> None:
    """Orbit figures (``output.orbits``, ``Result.plot_orbits``) need a problem that draws its
    orbits (:meth:`Presentation.orbit` overridden), each named point is ``first``, ``last``,
    ``events`` or an event kind of the problem, and each of ``views`` is one the problem
    draws (:func:`check_orbit_view`): else a :class:`CaseError` naming ``key``."""
    if not problem.presentation.draws_orbits:
        raise CaseError(f"{key}: problem {problem.name!r} does not draw its orbits "
                        "(Presentation.orbit is not implemented)")
    kinds = [k for k in problem.all_event_kinds() if k != "endpoint"]
    for i, entry in enumerate(points):
        if isinstance(entry, str) and entry not in ORBIT_POINT_WORDS and entry not in kinds:
            raise CaseError(f"{key}.points[{i}]: {entry!r} is not first, last, events, a "
                            f"number or an event kind of problem {problem.name!r} (one of: "
                            f"{', '.join(kinds)})")
    for i, view in enumerate(views):
        check_orbit_view(view, problem, f"{key}.views[{i}]")


def check_orbit_view(view: str, problem: Problem, key: str) -> None:
    """``view`` is one of :data:`ORBIT_VIEWS` that ``problem``'s orbits have
    (:meth:`Presentation.orbit_view_names`): else a :class:`CaseError` naming ``key`` and the views
    it draws."""
    drawn = problem.presentation.orbit_view_names()
    if view not in ORBIT_VIEWS:
        raise CaseError(f"{key}: {view!r} is not one of {', '.join(ORBIT_VIEWS)}")
    if view not in drawn:
        raise CaseError(f"{key}: problem {problem.name!r} does not draw the {view!r} view of "
                        f"its orbits (it draws: {', '.join(drawn) or 'none'})")


def _validate_restart(case: Case, problem: Problem, resolved: tuple[Any, ...],
                      user_params: dict[str, Any],
                      window: tuple[float | None, float | None]) -> Problem:
    """The rest of :func:`validate` for a restart: the problem with the run's period multiple
    (twice it for a switch at a period doubling), the point in its unknowns, the checks of an
    ordinary start there; the :class:`~nsm_continuation.cases.restart.Restart` is attached to
    ``case``. Returns the problem to continue."""
    from nsm_continuation.algorithms.curves import CodimOneCurve
    from nsm_continuation.algorithms.registry import ALGORITHMS
    spec, record, sel, _ = resolved
    c = case.continuation
    algorithm = ALGORITHMS.get(c.algorithm or problem.algorithms[0])
    if algorithm is not None and not algorithm.takes_start_points:
        raise CaseError(f"start.from: problem {problem.name!r} is continued by the "
                        f"{algorithm.name} algorithm, which cannot start from a saved point")
    try:
        target, base = rs.configure(problem, sel, spec, record, c.parameter)
        base.parameter_bounds(c.parameter, c.min, c.max)
        window = target.parameter_bounds(c.parameter, c.min, c.max)
    except (ValueError, ArithmeticError) as exc:
        raise CaseError(_keyed("start", str(exc))) from None
    assert case.parameters is not None
    y = rs.map_unknowns(base, sel, user_params, case.parameters)
    if spec.switch is not False and spec.event_kind == "branch_point" \
            and base.parameter != sel.parameter:
        raise CaseError(f"start.switch: a branch point is switched in the parameter it was "
                        f"found in ({sel.parameter}), not in {base.parameter}")
    try:
        rs.check_start(target, y, window, c.max_points)
    except (ValueError, ArithmeticError) as exc:
        raise CaseError(_keyed("start", str(exc))) from None
    case._restart = rs.Restart(
        spec, record, sel, y, base,
        switch=spec.event_kind if spec.switch is not False else None,
        direction=rs.direction_of(spec, target, c.parameter),
        overridden=any(record.restart.get("parameters", {}).get(k) != v
                       for k, v in user_params.items()),
        curve=target.curve_kind if isinstance(target, CodimOneCurve) else None,
        free=target.free if isinstance(target, CodimOneCurve) else None)
    return target


def load(path: str | Path, overrides: list[str] | None = None) -> tuple[Case, Problem]:
    """Read, override and validate a case file (see :func:`validate`)."""
    raw = apply_overrides(load_raw(path), overrides or [])
    return validate(raw)
