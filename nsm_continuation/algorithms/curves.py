"""Two-parameter curves of codimension-one points, as sequences of located events.

A codimension-one point of a family of orbits (a period doubling, a fold, a Neimark-Sacker
point, a zero of a test or event function the problem maps to an event kind, ...) is a zero
of a scalar condition ``c`` on the orbit ``y = (z, p)`` of the base problem ``G(y; q) = 0``.
With a second parameter ``q`` free the points form a curve in the ``(q, p)`` plane,

    G(z, p; q) = 0,        c(z, p; q) = 0.                                           (L1)

:mod:`nsm_continuation.hybrid.codim1` solves (C1), the grazing case, as one augmented system
with the exact gradient of the margin. The gradient of a multiplier condition (``det(M + I)``
for a period doubling) needs the second derivatives of the return map, i.e. second-order
sensitivities through every impact, chattering sequence and sticking phase: not available for
hybrid orbits. This module solves (L1) *by reduction* instead, with what the engine already
does exactly:

* the next point is predicted by the secant of the last two curve points, at arclength ``h``
  in the ``(q, p)`` plane (the first step: ``step.initial / 10`` in ``q``, ``p`` kept);
* the parameter that changes most along the secant is fixed at its predicted value, and the
  base problem there (:meth:`~nsm_continuation.core.problem.Problem.with_parameters`) is
  continued in the other one from the prediction (Newton with the exact Jacobian of ``G``,
  corrected along the base branch's tangent, well posed at a fold), over a window around the
  prediction, by the pseudo-arclength engine (:mod:`nsm_continuation.core.palc`), which detects and
  locates the event of the curve's kind on its true condition to ``analysis.event_tol``
  (``|lambda| - 1`` for multiplier crossings, the test function for admissibility events);
  of the events of the curve's kind (and, for a test or event function, the same function)
  the one nearest the prediction is the next point;
* none in the window, or one farther from the prediction than a quarter of the step (another
  zero of the condition: the secant's error is ``O(h^2)``): the window is widened (x4, once),
  then ``h`` is halved;
* a secant much longer than the step (a long step, then halvings, e.g. where a step overshot
  the tip of a U) errs by its own turn, ``kappa h_s / 2`` (``kappa`` the curvature, ``h_s``
  its length), so its prediction errs in proportion to ``h`` and halving does not help: a point
  located within a few steps of the last one is then taken as the new secant's end, and the
  step is predicted again along it (:meth:`CurveTracer._stale`).

Fixing the parameter that moves most is what lets the curve go round its turns (the U-shaped
period-doubling curve of the impact oscillator in ``(omega, gap)``:
``tests/cases/test_event_curves.py``);
a problem that can be continued only in ``p`` (``Problem.parameter_bounds`` refuses ``q``)
steps in ``q`` only and ends at a turn. Every point is a located event of the base problem,
with its tolerance, and nothing is differentiated numerically. ``h`` grows by 1.5 after a
point and is halved after a failure, within ``continuation.step``; the curve ends at the bounds
of ``q``, after ``max_points``, or where no event can be located for a step ``>= step.min``
(the reason names what the base continuations found: a codimension-two point where the event
ceases to exist, the end of the orbit family, ...). The cost is that of a few base points and
one event location per curve point (AUTO's and MatCont's augmented systems need second
derivatives of the return map instead, which hybrid orbits do not offer). Not for the
grazing of a hybrid orbit: there the family has a nonsmooth fold (the impacting orbit turns
back), which a continuation of the base problem does not locate reliably; the augmented system
(C1) does. A family that goes on smoothly through its grazing (the chain's nonlinear grazing
orbits, an admissibility test at zero) is followed here.

The curve problem's unknowns are ``(z, p, q)`` (the base's and the continued parameter), as
for (C1); :meth:`LocatedCurve.condition` evaluates ``c`` at a curve point (the distance of the
nearest multiplier to -1 for a period doubling, ...), which every point of the report carries
(column ``condition``) and the tests check against closed forms.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from nsm_continuation.core.monitors import Source
from nsm_continuation.core.palc import (
    HOOK_FAULTS,
    NUMERICAL_ERRORS,
    ContinuationEngine,
    describe_fault,
)
from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.core.settings import ContinuationSettings

#: the multiplier kinds a located curve can follow for any problem, with the condition ``c``
#: of (L1)
MULTIPLIER_KINDS: dict[str, str] = {
    "period_doubling": "a multiplier at -1",
    "fold": "a limit point of the family (a multiplier at +1)",
    "neimark_sacker": "a complex pair of multipliers on the unit circle",
}
def monitor_kinds(problem: Problem) -> set[str]:
    """The event kinds ``problem`` maps its test and event functions to (its declared test and
    function monitors, and the default kind of unlisted ones when the problem has test or
    event functions at all)."""
    cls = type(problem)
    declared = (*cls.monitors.of(Source.TEST), *cls.monitors.of(Source.FUNCTION))
    kinds = {m.kind for m in declared}
    if (cls.admissibility is not Problem.admissibility
            or cls.event_functions is not Problem.event_functions):
        kinds.add(cls.monitors.default_kind)
    return kinds


def curve_kinds(problem: Problem) -> set[str]:
    """The kinds of codimension-one point a located curve of ``problem`` can follow: the
    multiplier kinds (:data:`MULTIPLIER_KINDS`) and every kind the problem maps one of its
    test or event functions to (:func:`monitor_kinds`)."""
    return set(MULTIPLIER_KINDS) | monitor_kinds(problem)


def curve_kind_refusal(problem: Problem, kind: str) -> str | None:
    """None if a located curve of ``problem`` can follow ``kind`` points (:func:`curve_kinds`),
    else the one-line refusal naming ``start.curve`` and the kinds this problem offers (its
    monitors' kinds, then the multiplier kinds)."""
    offered = curve_kinds(problem)
    if kind in offered:
        return None
    names = [repr(k) for k in (*sorted(offered - set(MULTIPLIER_KINDS)), *MULTIPLIER_KINDS)]
    listing = ", ".join(names[:-1]) + f" or {names[-1]}" if len(names) > 1 else names[0]
    return (f"start.curve: Input should be {listing} (the kinds of codimension-one point a "
            f"curve of problem {problem.name!r} can follow), not {kind!r}")


def condition_meaning(kind: str) -> str:
    """The condition ``c`` of (L1) for a curve of ``kind`` points, in words."""
    if kind in MULTIPLIER_KINDS:
        return MULTIPLIER_KINDS[kind]
    return (f"a test or event function the problem maps to {kind} at zero "
            "(Problem.monitors)")


#: growth of the step in ``q`` after a located point, and of the window of ``p`` after a miss
STEP_GROWTH = 1.5
WINDOW_GROWTH = 4.0
WINDOW_WIDENINGS = 1
#: largest distance of a located point from the secant prediction, relative to the step
CONTINUITY = 0.25
#: a secant is re-taken from the last point where the step falls below this fraction of its
#: length (:meth:`CurveTracer._stale`)
STALE = 0.25
#: the first step is step.initial divided by this
FIRST_STEP_FRACTION = 10.0
#: points of each base continuation (both ways from the prediction)
INNER_MAX_POINTS = 60


class CodimOneCurve(Problem):
    """A curve of codimension-one points in two parameters: unknowns ``(z, p, q)``, ``q``
    (``parameter``) continued, ``p`` (``free``) solved for."""

    #: the kind of codimension-one point the curve follows (``start.curve``)
    curve_kind: str
    free: str
    base: Problem

    def restart_curve(self) -> dict[str, Any]:
        """What a restart record keeps to build this curve again."""
        return {"kind": self.curve_kind, "free": self.free, "base_problem": self.base.name}


#: the settings of the base run that its continuations inside a located curve keep
BASE_SETTINGS = ("newton_tol", "derived_bounds", "step_initial")


def flat_parameters(values: dict[str, Any]) -> dict[str, Any]:
    """A nested mapping of parameters flattened to its leaves, each under its own key
    (``{"chain": {"stiffness": 4}}`` -> ``{"stiffness": 4}``)."""
    out: dict[str, Any] = {}
    for k, v in values.items():
        out.update(flat_parameters(v) if isinstance(v, dict) else {k: v})
    return out


class LocatedCurvePresentation(Presentation):
    """A located two-parameter curve: the continued parameter against the free one, each point
    with its condition."""

    two_parameter: ClassVar[bool] = True

    @property
    def diagram_title(self) -> str:  # type: ignore[override]
        """``<Kind> curve in two parameters``."""
        return f"{self.problem.curve_kind.replace('_', ' ').capitalize()} curve in two parameters"

    @property
    def fep_axes(self) -> tuple[str, str]:
        return (self.problem.parameter, self.problem.free)

    @property
    def fep_labels(self) -> tuple[str, str]:
        """The two parameters as the base family labels them."""
        pr = self.problem
        base = pr.base.presentation
        return (base.label(pr.parameter),
                f"{base.label(pr.free)} at the {pr.curve_kind.replace('_', ' ')}")

    def start_point(self, branch: Any) -> Any:
        """The point of the curve at the base run's value of the continued parameter (the
        codimension-one point it was started from; the curve's arclength starts at one of its
        ends)."""
        value = getattr(self.problem, "start_value", None)
        if value is None or not branch.points:
            return super().start_point(branch)
        i = self.problem.variables.index(self.problem.parameter)
        return min(branch.points, key=lambda p: abs(p.y[i] - value))

    def branch_name(self, branch: Any) -> str:
        return f"{self.problem.curve_kind.replace('_', ' ')} curve (computed)"

    def closed_forms(self, x_range: tuple[float, float], branches: list[Any]
                     ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """The base family's closed form of this curve, if it has one."""
        pr = self.problem
        return pr.base.presentation.curve_closed_forms(pr.curve_kind, pr.parameter, pr.free,
                                                       x_range)

    @property
    def csv_head(self) -> list[str]:
        return [self.problem.parameter, self.problem.free, "condition"]

    def summary(self) -> dict[str, Any]:
        pr = self.problem
        return {"curve": f"{pr.curve_kind} points of {pr.base.name} (eq. L1 of "
                         "nsm_continuation.algorithms.curves: each point a located event)",
                "continued": pr.parameter, "free": pr.free,
                "condition": condition_meaning(pr.curve_kind),
                "unknowns": list(pr.variables)}


class LocatedCurve(CodimOneCurve):
    """The points of kind ``kind`` of ``base`` (continued in ``free``) as ``parameter`` varies
    (L1), each located by a continuation of ``base`` at that value of ``parameter``."""

    name: ClassVar[str] = "event_curve"
    Parameters: ClassVar[type[BaseModel]] = BaseModel
    algorithms: ClassVar[tuple[str, ...]] = ("located_events",)
    presentation_class = LocatedCurvePresentation

    def __init__(self, base: Problem, kind: str, free: str, parameter: str,
                 base_settings: dict[str, Any] | None = None) -> None:
        super().__init__(base.params)
        refusal = curve_kind_refusal(base, kind)
        if refusal is not None:
            raise ValueError(refusal)
        if free == parameter:
            raise ValueError(f"continuation.parameter: the {kind} curve needs two parameters "
                             f"(free {free!r} and continued {parameter!r} are the same)")
        probe = base.with_parameters({})
        if probe is None:
            raise ValueError(f"start.curve: problem {base.name!r} cannot be rebuilt at another "
                             "value of a parameter (Problem.with_parameters), so no "
                             "two-parameter curve can be continued")
        # the base problem continued in ``free`` (the instance handed over may have been set
        # to the case's continued parameter, ``q``)
        probe.parameter_bounds(free, None, None)
        self.base = probe
        #: the value of ``parameter`` the curve was started at (that of the base run)
        self.start_value: float | None = flat_parameters(base.params.model_dump()).get(parameter)
        self.curve_kind = kind
        self.free = free
        self.parameter = parameter
        self.variables = list(probe.variables) + [parameter]
        #: what the continuations of the base problem keep of the base run's settings
        #: (:data:`BASE_SETTINGS`: its Newton tolerance, its bounds, such as the floor of a
        #: derived quantity that defines the problem's event, and its initial step, the scale of
        #: the first window); the case's own settings are those of the curve
        self.base_settings = dict(base_settings or {})
        self._at: tuple[float, Problem] | None = None
        self._swapped: tuple[float, Problem] | None = None
        self._can_swap: bool | None = None

    # ------------------------------------------------------------------ the base problem
    def adopt_chart(self, chart: dict[str, float] | None) -> None:
        """Continue the curve with the base problem's unknowns in ``chart`` (a
        ``Point.chart`` of a located event: the base continuation moved there)."""
        self.base = self.base.in_chart(chart)
        self._at = self._swapped = None

    def base_at(self, q: float) -> Problem:
        """The base problem with ``parameter = q`` (the last one kept)."""
        if self._at is None or self._at[0] != q:
            new = self.base.with_parameters({self.parameter: float(q)})
            assert new is not None  # checked in __init__
            self._at = (float(q), new)
        return self._at[1]

    @property
    def can_swap(self) -> bool:
        """Whether the base problem can also be continued in ``parameter`` at fixed ``free``
        (then the curve goes round its turns in ``parameter``)."""
        if self._can_swap is None:
            try:
                self.swapped_at(float(self.base.params.model_dump().get(self.free, 0.0)))
                self._can_swap = True
            except (ValueError, TypeError, ArithmeticError):
                self._can_swap = False
        return self._can_swap

    def swapped_at(self, p: float) -> Problem:
        """The base problem with ``free = p``, continued in ``parameter`` (the last one
        kept); ValueError where the problem cannot continue ``parameter``."""
        if self._swapped is None or self._swapped[0] != p:
            new = self.base.with_parameters({self.free: float(p)})
            assert new is not None  # checked in __init__
            new.parameter_bounds(self.parameter, None, None)
            self._swapped = (float(p), new)
        return self._swapped[1]

    def residual(self, y: Any) -> Any:  # pragma: no cover - numeric problem
        raise NotImplementedError("a located curve has no residual: its points are events")

    @property
    def compiled(self) -> Any:
        return None

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        """``G(z, p; q)`` at a curve point (the first block of (L1))."""
        return self.base_at(float(y[-1])).evaluate(np.asarray(y[:-1], dtype=float))

    def period_multiple(self) -> int:
        return self.base.period_multiple()

    def condition(self, point: Point) -> float:
        """The condition ``c`` of (L1) at a located point of the base problem (unknowns
        ``(z, p)``): ``min |lambda + 1|`` (period doubling), ``min |lambda - 1|`` over the
        non-trivial multipliers (fold; the tangent's parameter component if there are none),
        ``min ||lambda| - 1|`` over complex pairs (Neimark-Sacker), ``min |value|`` of the
        test and event functions the base problem maps to the curve's kind
        (:meth:`Problem.monitor_kind`).
        NaN where it is not defined."""
        m = point.multipliers
        kind = self.curve_kind
        if kind in ("period_doubling", "fold", "neimark_sacker"):
            if m is None or len(m) == 0:
                if kind == "fold":
                    return float(abs(point.tangent[-1]))
                return float("nan")
            m = np.asarray(m)
            if kind == "period_doubling":
                return float(np.min(np.abs(m + 1.0)))
            if kind == "fold":
                return float(np.min(np.abs(m - 1.0)))
            pairs = m[np.abs(m.imag) > 1e-9 * np.maximum(1.0, np.abs(m))]
            return float(np.min(np.abs(np.abs(pairs) - 1.0))) if len(pairs) else float("nan")
        # the test and event functions the base problem maps to the curve's kind
        values = [abs(v) for source, monitors in (("test", point.tests),
                                                  ("function", point.event_values))
                  for name, v in monitors.items()
                  if self.base.monitors.kind(source, name) == kind and np.isfinite(v)]
        return float(min(values)) if values else float("nan")

    def monitor_names(self) -> list[str]:
        return [self.free, self.parameter, "condition"]

    def restart_curve(self) -> dict[str, Any]:
        bounds = {k: list(v) for k, v in self.base_settings.get("derived_bounds", {}).items()}
        return {**super().restart_curve(), "method": "located",
                "base_settings": {**self.base_settings, "derived_bounds": bounds}}



# ---------------------------------------------------------------------- the algorithm
@dataclasses.dataclass
class _Located:
    """A curve point: unknowns ``(z, p, q)`` and the located event's point of the base
    problem it was found on (continued in ``p`` at fixed ``q``, or the other way round:
    ``along``)."""

    y: np.ndarray
    point: Point
    along: str


def _which(ev: Event) -> str | None:
    """The test or event function an event is the zero of (None: a multiplier crossing)."""
    for key in ("test", "function", "bound"):
        if key in ev.data:
            return f"{key}:{ev.data[key]}"
    return None


class CurveTracer:
    """Continuation of (L1) by arclength in the ``(q, p)`` plane (module docstring): each step
    fixes the parameter that changes most along the curve's secant and locates the event in
    the other one, so the curve goes round its turns in either parameter."""

    def __init__(self, curve: LocatedCurve, settings: ContinuationSettings,
                 progress: Any = None) -> None:
        self.curve = curve
        self.settings = settings
        self.progress = progress
        self.n_base_points = 0
        self.n_base_runs = 0
        #: the test or event function whose zero the curve follows (set by the first point:
        #: a family may have several, e.g. the chain's clearance and outgoing velocity)
        self.which: str | None = None

    # ------------------------------------------------------------------ one point
    def _inner_settings(self, centre: float, width: float, direction: int,
                        rate: float = 1.0) -> ContinuationSettings:
        """The case's settings for a continuation of the base problem over ``centre +-
        width`` (the case's bounds are on
        ``q``, the curve's parameter, and do not apply). ``rate``: ``|dp/ds|`` along the
        base branch (steps are in arclength: a quarter window of ``p`` is ``width / 4 /
        rate``)."""
        base = self.curve.base_settings
        bounds = {k: (v[0], v[1]) for k, v in base.get("derived_bounds", {}).items()}
        return dataclasses.replace(
            self.settings, param_min=centre - width, param_max=centre + width,
            direction=direction, max_points=INNER_MAX_POINTS,
            step_initial=width / 4.0 / rate, step_max=width / 2.0 / rate,
            step_min=min(self.settings.step_min, width * 1e-6),
            newton_tol=base.get("newton_tol", self.settings.newton_tol),
            # the count of multipliers outside the circle only brackets a crossing; its
            # location is that of |lambda| - 1 (secant, to event_tol) inside the bracket
            multiplier_event_tol=max(self.settings.multiplier_event_tol, width * 1e-3),
            # the window may start on the far side of the event (a phantom, inadmissible
            # orbit beyond a grazing): the continuation must go on through it
            stop_on_inadmissible=False, derived_bounds=bounds)

    def locate(self, along: str, y_pred: np.ndarray, tangent: np.ndarray | None, width: float
               ) -> tuple[_Located | None, str]:
        """The event of the curve's kind nearest the prediction ``y_pred`` (unknowns ``(z, p,
        q)``): ``along = "p"`` fixes ``q`` and continues the base problem in ``p`` over
        ``p +- width`` (``"q"`` the other way round); None and what was found if there is
        none. The continuation runs across the window from its low end, and from its high end
        backwards."""
        from nsm_continuation.algorithms.base import StartTangentEngine, TangentStart

        curve = self.curve
        p, q = float(y_pred[-2]), float(y_pred[-1])
        if along == "p":
            base, yb, centre, fixed = curve.base_at(q), np.asarray(y_pred[:-1]), p, (
                curve.parameter, q)
        else:
            base, centre, fixed = curve.swapped_at(p), q, (curve.free, p)
            yb = np.append(y_pred[:-2], q)
        ip = base.parameter_index
        rate = 1.0
        if tangent is not None and len(tangent) == len(yb):
            rate = float(np.clip(abs(tangent[ip]) / np.linalg.norm(tangent), 1e-4, 1.0))
        found: list[Event] = []
        ends: list[str] = []
        # across the window from its low end, and from its high end backwards unless the
        # first run crossed the whole window (a family that turns or ends inside the window
        # is seen from both sides)
        for sign in (1, -1):
            y0 = yb.copy()
            y0[ip] = centre - sign * width
            engine: ContinuationEngine = StartTangentEngine(
                base, self._inner_settings(centre, width, sign, rate))
            # Newton at fixed parameter first; along the base branch's tangent (well posed
            # at a fold) where that fails
            for t in (None, tangent) if tangent is not None else (None,):
                br: Branch = engine.run(TangentStart(y0, "curve", sign, {}, tangent=t))
                self.n_base_runs += 1
                self.n_base_points += br.n_points
                if "start" not in br.termination:
                    break
            found += [e for e in br.events if e.kind == curve.curve_kind
                      and (self.which is None or _which(e) == self.which)]
            reason = br.termination.get("start") or "; ".join(
                sorted(set(br.termination.values())))
            kinds = sorted({e.kind for e in br.events} - {"endpoint"})
            ends.append(reason + (f" (events: {', '.join(kinds)})" if kinds else ""))
            if sign > 0 and reason == f"bound: {base.parameter} = max":
                break  # across the whole window, up: nothing left to see from the other end
        if not found:
            name = curve.free if along == "p" else curve.parameter
            return None, (f"no {curve.curve_kind} within {name} = {centre:.10g} +- "
                          f"{width:.3g} at {fixed[0]} = {fixed[1]:.10g}; the base "
                          f"continuations ended: {' / '.join(ends)}")
        # the event nearest the prediction (parameters; the orbit where it is in the same
        # chart), of the same test function
        best = min(found, key=lambda e: float(np.linalg.norm(
            (e.point.y - yb) if e.point.chart == base.chart() else (e.point.y - yb)[-1:])))
        if best.point.chart != base.chart():
            # the base continuation moved its unknowns to another chart (Problem.rechart: a
            # section moved off an impact): the curve goes on in that chart
            self.curve.adopt_chart(best.point.chart)
        if self.which is None:
            self.which = _which(best)
        yl = np.asarray(best.point.y, dtype=float)
        y = (np.append(yl, q) if along == "p"
             else np.concatenate([yl[:-1], [p], yl[-1:]]))
        return _Located(y, best.point, along), ""

    # ------------------------------------------------------------------ one direction
    @staticmethod
    def _secant(a: _Located, b: _Located) -> np.ndarray:
        """The secant from ``a`` to ``b``, of unit length in the ``(p, q)`` plane (of the
        parameters only where the two are in different charts)."""
        d = b.y - a.y
        if a.point.chart != b.point.chart:
            d[:-2] = 0.0  # unknowns in two charts: the secant of the parameters only
        return d / float(np.linalg.norm(d[-2:]))

    def _step(self, pts: list[_Located], sign: int, h: float,
              secant: np.ndarray | None = None) -> tuple[np.ndarray, str, bool]:
        """The prediction of the next point at arclength ``h`` in the ``(p, q)`` plane (along
        ``secant``, default that of the last two points), the parameter to locate in, and
        whether the step ends on a bound of ``q``."""
        st = self.settings
        last = pts[-1]
        if secant is not None:
            d = secant
        elif len(pts) < 2:  # no secant yet: a step in q
            d = np.zeros_like(last.y)
            d[-1] = sign
        else:
            d = self._secant(pts[-2], last)
        y = last.y + h * d
        along = "p" if abs(d[-1]) >= abs(d[-2]) or not self.curve.can_swap else "q"
        edge = False
        for bound, beyond in ((st.param_max, lambda v, b: v >= b),
                              (st.param_min, lambda v, b: v <= b)):
            if bound is not None and beyond(y[-1], bound) and d[-1] != 0:
                y = last.y + (bound - last.y[-1]) / d[-1] * d
                y[-1] = bound
                along, edge = "p", True
        return y, along, edge

    def _rechart(self, got: _Located) -> _Located:
        """``got``, or ``got`` in the base problem's new chart where the base problem asks
        for one there (:meth:`Problem.rechart`, e.g. an impact about to reach a forced
        system's section): the curve goes on in that chart (the next secant is of the
        parameters only, the next base continuation starts without a tangent)."""
        q = float(got.y[-1])
        yb = np.asarray(got.y[:-1], dtype=float)
        direction = np.zeros(len(yb))
        direction[-1] = 1.0
        try:
            moved = self.curve.base_at(q).rechart(yb, direction)
        except NUMERICAL_ERRORS:
            moved = None
        if moved is None:
            return got
        chart = moved.problem.chart()
        self.curve.adopt_chart(chart)
        y = np.append(np.asarray(moved.y, dtype=float), q)
        return _Located(y, dataclasses.replace(got.point, y=np.asarray(moved.y, dtype=float),
                                               chart=chart), "")

    @staticmethod
    def _continues(last: _Located, y_pred: np.ndarray, got: _Located) -> bool:
        """Whether ``got`` continues the curve: within ``CONTINUITY`` of the step from the
        secant's prediction in the ``(p, q)`` plane (the secant's error is ``O(h^2)``; a point
        farther off is another zero of the condition, e.g. another tangency of the chain's
        orbit, which the step then halves away from)."""
        step = float(np.linalg.norm(y_pred[-2:] - last.y[-2:]))
        return float(np.linalg.norm(got.y[-2:] - y_pred[-2:])) <= CONTINUITY * step

    @staticmethod
    def _stale(pts: list[_Located], h: float, got: _Located) -> bool:
        """Whether the secant of the last two points, not ``got``, is what is off: the step
        ``h`` is less than ``STALE`` of the secant's own length and ``got`` lies within
        ``h / CONTINUITY`` of the last point. The secant's direction then errs by
        ``kappa h_s / 2`` (``kappa`` the curvature, ``h_s`` its length), so its prediction
        at ``h`` errs by ``kappa h_s h / 2``: linear in ``h``, which halving ``h`` does not
        reduce relative to the step (round the tip of a U-shaped curve, where ``kappa``
        grows); another zero of the condition lies a finite distance away and is not
        within a few steps of the last point once ``h`` is small."""
        if len(pts) < 2:
            return False
        last = pts[-1]
        base = float(np.linalg.norm(last.y[-2:] - pts[-2].y[-2:]))
        near = float(np.linalg.norm(got.y[-2:] - last.y[-2:]))
        return h < STALE * base and near <= h / CONTINUITY

    def _half(self, first: _Located, sign: int, width0: float) -> tuple[list[_Located], str]:
        st = self.settings
        pts = [first]
        # the first step has no secant to predict p: a tenth of step.initial, so that the
        # window (the base run's scale of p) holds the next point; steps grow from there
        h = st.step_initial / FIRST_STEP_FRACTION
        #: the secant of the last point and a point located from it at a step well below
        #: the last two points' distance (:meth:`_stale`), the prediction's direction until
        #: the next point is accepted
        fresh: np.ndarray | None = None
        while len(pts) < st.max_points:
            y_pred, along, edge = self._step(pts, sign, h, fresh)
            last = pts[-1]
            if edge and abs(y_pred[-1] - last.y[-1]) <= 1e-14 * (1.0 + abs(last.y[-1])):
                return pts, f"bound reached: {self.curve.parameter}"
            k = -2 if along == "p" else -1
            width = width0 if len(pts) < 2 else max(
                2.0 * abs(float(y_pred[k] - last.y[k])), width0 * 1e-3)
            tangent = last.point.tangent if last.along == along else None
            got, why = None, ""
            for _ in range(WINDOW_WIDENINGS + 1):
                got, why = self.locate(along, y_pred, tangent, width)
                if got is not None:
                    break
                width *= WINDOW_GROWTH
            if got is not None and len(pts) >= 2 and not self._continues(last, y_pred, got):
                if fresh is None and self._stale(pts, h, got):
                    # predict again along the secant to the point found, at the same step
                    fresh = self._secant(last, got)
                    continue
                got, why = None, (f"the {self.curve.curve_kind} located at "
                                  f"{self.curve.parameter} = {got.y[-1]:.10g} is off the "
                                  "secant prediction (another zero of its condition)")
            if got is None:
                h /= 2.0
                if h < st.step_min:
                    return pts, f"no {self.curve.curve_kind} point located: {why}"
                continue
            lo, hi = self.settings.param_min, self.settings.param_max
            bound = (lo if lo is not None and got.y[-1] < lo
                     else hi if hi is not None and got.y[-1] > hi else None)
            if bound is not None:  # past the bound of q: the point on it instead
                frac = (bound - last.y[-1]) / (got.y[-1] - last.y[-1])
                y_edge = last.y + frac * (got.y - last.y)
                y_edge[-1] = bound
                got, why = self.locate("p", y_edge, None, max(
                    2.0 * abs(float(got.y[-2] - last.y[-2])), width0 * 1e-3))
                if got is not None:
                    pts.append(got)
                return pts, f"bound reached: {self.curve.parameter}" + (
                    "" if got is not None else f" (the point on it not located: {why})")
            pts.append(self._rechart(got))
            fresh = None
            if self.progress is not None:
                self.progress(1)
            if edge:
                return pts, f"bound reached: {self.curve.parameter}"
            h = min(h * STEP_GROWTH, st.step_max)
        return pts, "max_points reached"

    def run(self, seed: Any, branch_id: int = 0) -> Branch:
        """The curve through ``seed`` (a start point with unknowns ``(z, p, q)``, at or near a
        point of the curve's kind): the event is located again at that ``q``, then the curve
        is followed both ways (or one, ``seed.direction``: along ``q``). Never raises."""
        first, why, width0 = self.first_point(seed)
        if first is None:
            return self.branch(seed, branch_id, why, {})
        return self.branch(seed, branch_id, "", {sign: self.half(first, sign, width0)
                                                 for sign in self.signs(seed)})

    @staticmethod
    def signs(seed: Any) -> list[int]:
        """The ways the curve is followed from its first point: along ``q`` increasing
        (``+1``), decreasing (``-1``), or both, in this order."""
        return [int(np.sign(seed.direction))] if seed.direction != 0 else [1, -1]

    def first_point(self, seed: Any) -> tuple[_Located | None, str, float]:
        """``(the event located again at the seed's q, why not, the first window's width)``:
        the window is twice the base run's initial step (its scale of ``p``)."""
        y0 = np.asarray(seed.y, dtype=float)
        width0 = 2.0 * float(self.curve.base_settings.get(
            "step_initial", 1e-3 * (1.0 + abs(float(y0[-2])))))
        try:
            first, why = self.locate("p", y0, getattr(seed, "tangent", None), width0)
        except HOOK_FAULTS as exc:  # noqa: BLE001 - recorded on the branch
            first, why = None, describe_fault(exc)
        return first, why, width0

    def half(self, first: _Located, sign: int, width0: float) -> tuple[list[_Located], str]:
        """The curve from ``first`` one way (:meth:`_half`), an internal error recorded as
        its end."""
        try:
            return self._half(first, sign, width0)
        except HOOK_FAULTS as exc:  # noqa: BLE001 - recorded on the branch
            return [first], describe_fault(exc)

    def branch(self, seed: Any, branch_id: int, failed: str,
               halves: dict[int, tuple[list[_Located], str]],
               counts: tuple[int, int] | None = None) -> Branch:
        """The curve's branch from its halves (``sign: (points, reason)``, as from
        :meth:`half`), or the failed start ``failed``; ``counts``: the base runs and points it
        took (default: this tracer's counters)."""
        runs, points_ = counts if counts is not None else (self.n_base_runs,
                                                            self.n_base_points)
        if failed:
            return Branch(branch_id, seed.label, [], [], {"start": failed}, dict(seed.info))
        termination = {"forward" if sign > 0 else "backward": reason
                       for sign, (_, reason) in halves.items()}
        if len(halves) == 1:  # one way: in the order continued
            ((ordered, _),) = halves.values()
        else:
            ordered = list(reversed(halves[-1][0]))[:-1] + halves[1][0]
        points = self._points(ordered)
        events = [Event("endpoint", points[k], f"curve end: {termination[side]}",
                        data={"reason": termination[side]})
                  for k, side in ((0, "backward"), (-1, "forward")) if side in termination]
        return Branch(branch_id, seed.label, points, events, termination,
                      {**dict(seed.info), "base_runs": runs, "base_points": points_})

    def _defining_tests(self, point: Point) -> tuple[str, ...]:
        """The admissibility test whose zero a curve point is (of the curve's kind, the least
        in modulus: the one :meth:`LocatedCurve.condition` reads); none for a curve of
        multiplier events."""
        own = {name: abs(v) for name, v in point.tests.items()
               if self.curve.base.monitors.kind("test", name) == self.curve.curve_kind
               and np.isfinite(v)}
        return (min(own, key=own.__getitem__),) if own else ()

    def _points(self, located: list[_Located]) -> list[Point]:
        """The curve's points: unknowns ``(z, p, q)``, arclength in ``(z, p, q)``, the secant
        tangent, the located point's multipliers and tests, and the condition (L1)."""
        out: list[Point] = []
        s = 0.0
        for k, loc in enumerate(located):
            if k:
                s += float(np.linalg.norm(loc.y - located[k - 1].y))
            nb = located[min(k + 1, len(located) - 1)].y - located[max(k - 1, 0)].y
            n = float(np.linalg.norm(nb))
            t = nb / n if n > 0 else np.eye(len(loc.y))[-1]
            free = loc.point.derived.get(self.curve.free, float(loc.y[-2]))
            derived = {**loc.point.derived, self.curve.free: float(free),
                       self.curve.parameter: float(loc.y[-1]),
                       "condition": self.curve.condition(loc.point)}
            boundary = self._defining_tests(loc.point)
            out.append(dataclasses.replace(loc.point, y=loc.y, s=s, tangent=t,
                                           derived=derived, on_boundary=boundary))
        return out


__all__ = ["MULTIPLIER_KINDS", "CodimOneCurve", "CurveTracer",
           "LocatedCurve", "condition_meaning", "curve_kind_refusal", "curve_kinds",
           "flat_parameters", "monitor_kinds"]
