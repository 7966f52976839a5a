"""Event location on the arc of a step: bounds, admissibility tests, event functions, folds,
branch points, multiplier crossings (:mod:`~nsm_continuation.core.palc.crossings`) and changes of
the problem's signature.

At each accepted point the problem's hooks give admissibility test functions, event functions
(:meth:`~nsm_continuation.core.problem.Problem.event_functions`: located, never ending the branch),
Floquet multipliers and a signature; their changes between two points are located on the curve
with :mod:`nsm_continuation.core.roots` (:meth:`EventLocator.events_between`): a zero of a
continuous function by Illinois with Dekker's closing step (:meth:`EventLocator.
_locate_continuous`), a change of a discrete quantity by bisection. Each event is returned with
the test that found it (:class:`EventSource`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

import numpy as np

from nsm_continuation.core.monitors import Source
from nsm_continuation.core.palc.branch_points import plus_one_events, stencil_zero
from nsm_continuation.core.palc.errors import RetryStep
from nsm_continuation.core.palc.folds import Accuracy, accuracy, is_fold, known_ends
from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.palc.step_control import Trial
from nsm_continuation.core.records import Event, Point
from nsm_continuation.core.roots import bisect_predicate, illinois, interior_extremum

if TYPE_CHECKING:
    from nsm_continuation.core.palc.engine import ContinuationEngine


class EventSource(Enum):
    """The test of a step that found an event (:meth:`EventLocator.events_between`)."""

    #: a parameter bound or a bound on a derived quantity
    BOUND = "bound"
    #: a zero of an admissibility test function, or a test that ceases to be (becomes) defined
    TEST = "test"
    #: a zero of an event function: the branch may have a kink there
    #: (:mod:`~nsm_continuation.core.palc.kinks`)
    FUNCTION = "function"
    #: a fold, a simple branch point or a multiplier crossing
    BIFURCATION = "bifurcation"
    #: a change of the problem's discrete signature
    SIGNATURE = "signature"


@dataclass
class StepEvents:
    """The events of one step in the order recorded, each with its source, and the earliest
    stop among them (the point where the branch ends and the reason), if any."""

    entries: list[tuple[EventSource, Event]]
    stop: tuple[Point, str] | None = None

    @property
    def events(self) -> list[Event]:
        """Every event of the step."""
        return [ev for _, ev in self.entries]

    def of(self, source: EventSource) -> list[Event]:
        """The events found by ``source``."""
        return [ev for src, ev in self.entries if src is source]

    def until_stop(self) -> list[Event]:
        """The events up to the stop (every event if there is none)."""
        if self.stop is None:
            return self.events
        return [ev for ev in self.events if ev.point.s <= self.stop[0].s]


class EventLocator(EnginePart):
    """Locates the events of each step on its arc.

    ``retry_allowed`` is set while the events of a step longer than a few ``step_min`` are
    located: an event that cannot be located on the step's arc then retries the step shorter
    (:class:`~nsm_continuation.core.palc.errors.RetryStep`, :meth:`unresolved`).
    ``last_was_pole``: whether the last sign change located by :meth:`_locate_continuous`
    was through a pole, not a zero."""

    def __init__(self, engine: ContinuationEngine) -> None:
        super().__init__(engine)
        self.retry_allowed = False
        self.last_was_pole = False
        #: the accuracies of the last few points asked (:meth:`_accuracy`)
        self._accuracies: list[tuple[Point, Accuracy]] = []

    def step(self, a: Point, pts: list[Point], trial: Trial) -> tuple[Point, StepEvents]:
        """The new point of the step ``a -> b`` analysed (with the multipliers of the trial)
        and the events of the step. An event that cannot be located on the arc of a long step
        raises :class:`~nsm_continuation.core.palc.errors.RetryStep` (the step is retried
        shorter)."""
        self.retry_allowed = trial.step.h > 4 * self.settings.step_min
        try:
            b = self.engine.analyse(trial.y, trial.tangent, trial.s, trial.iterations,
                                    known=trial.floquet)
            found = self.events_between(a, b, pts)
        finally:
            self.retry_allowed = False
        return b, found

    def unresolved(self, why: str) -> list[Event]:
        """A step whose events cannot be told apart: retried shorter if it may be, else kept
        and counted (``unlocated_events``)."""
        if self.retry_allowed:
            raise RetryStep(why)
        self.engine.unlocated_events += 1
        return []

    def stop_on_edge(self, a: Point, events: list[Event]) -> str:
        """``a`` lies on the window edge its tangent points out of: it is the end point."""
        hi = self.settings.param_max is not None and a.tangent[self.ip] > 0
        label = f"{self.problem.parameter} = {'max' if hi else 'min'}"
        events.append(Event(self.bound_kind(label), a, f"bound reached: {label}",
                            data={"bound": label}))
        return f"bound: {label}"

    def bound_kind(self, label: str) -> str:
        """Event kind of a bound (``endpoint`` unless the problem maps the quantity)."""
        return self.problem.monitors.bound_kind(label)

    def _locate_continuous(self, a: Point, b: Point, fun: Callable[[Point], float],
                           lo: float = 0.0, flo: float | None = None,
                           hi: float | None = None, fhi: float | None = None,
                           floquet: bool = False, tests: bool = True,
                           failures: list[float] | None = None) -> tuple[Point, float]:
        """A zero of ``fun`` on the arc from ``a`` to ``b`` (Illinois with Dekker's closing
        step, to ``event_tol`` in arclength, between arclengths ``lo`` and ``hi`` from ``a``:
        5-10 trial points where the plain iteration's halvings took 20-30), as ``(point,
        bracket width)``; the point is analysed in full. The trial points are analysed with
        the multipliers only if ``floquet`` and with the admissibility tests and event
        functions only if ``tests``: a function of the parameter, of a derived quantity, of
        the tangent or of the bordered determinant reads neither (each trial point's tests
        cost the chain's certified critical points of ``u_N``). ``failures`` collects the
        arclengths of the trial points where the corrector failed (or ``fun`` is NaN)."""
        h = b.s - a.s
        hi = h if hi is None else hi
        flo = fun(a) if flo is None else flo
        fhi = fun(b) if fhi is None else fhi

        seen = [abs(flo), abs(fhi)]

        def f(sig: float) -> tuple[float, Point | None]:
            p = self.engine.point_at(a, b, sig, tests=tests, floquet=floquet)
            value = float("nan") if p is None else fun(p)
            if np.isfinite(value):
                seen.append(abs(value))
            elif failures is not None:
                failures.append(sig)
            return value, p

        sig, p, width = illinois(f, lo, flo, hi, fhi, self.settings.event_tol, close=True)
        #: whether the sign change just located was through a pole, not a zero: the last
        #: values met, next to the sign change, exceed both ends in modulus (they shrink like
        #: the bracket at a zero, they grow like its inverse at a pole)
        self.last_was_pole = len(seen) > 2 and min(seen[-2:]) > max(seen[:2])
        if p is None:
            p = b if abs(sig - h) < abs(sig) else a
        return self.engine.full(p), width

    def _locate_branch_point(self, a: Point, b: Point) -> Event | None:
        """The simple branch point of the step ``a -> b`` where ``det[G_y; t^T]`` changes sign
        (Illinois, :meth:`_locate_continuous`). Where the corrector failed at trial points
        near it (the bordered Jacobian is singular there), the location is checked against
        the zero interpolated from resolved points around it (:func:`~nsm_continuation.core.
        palc.branch_points.stencil_zero`, at least 8 widths of the failed zone away): where
        that zero is accurate to ``multiplier_event_tol`` (the accuracy a crossing's location
        must reach, :meth:`~.crossings.CrossingLocator._locate_on_modulus`) and either more
        accurate than the iteration's bracket (which covers the failed trial points,
        :func:`~nsm_continuation.core.roots.illinois`) or away from it by more than both
        accuracies (the corrector's noise misled the iteration), the interpolated zero is the
        event (``data['interpolated']``;
        ``data['iteration_offset']``: how far the iteration's location was). None through a
        pole (the Jacobian blows up, e.g. like ``1/|v|`` as an impact's velocity vanishes at a
        grazing: no second branch crosses) or off the step's arc (counted in
        ``sign_changes_without_zero`` / ``unlocated_events``)."""
        def det(q: Point) -> float:
            return q.bordered_det

        failed: list[float] = []
        p, w = self._locate_continuous(a, b, det, tests=False, failures=failed)
        if self.last_was_pole:
            self.engine.sign_changes_without_zero += 1
            return None
        data: dict[str, object] = {"test": "bordered_determinant"}
        sig = p.s - a.s
        z = None if not failed else stencil_zero(
            sig, b.s - a.s, lambda x: self.engine.point_at(a, b, x, tests=False, floquet=False),
            det, float(np.sign(a.bordered_det)), min_half_width=8.0 * (max(failed) - min(failed)))
        if z is not None and z.accuracy <= self.settings.multiplier_event_tol \
                and (z.accuracy < w or abs(z.sigma - sig) > max(w, z.accuracy)):
            p = self.engine.analyse(z.y, z.tangent, a.s + z.sigma)
            w = max(z.accuracy, self.settings.event_tol)
            data.update(interpolated=True, iteration_offset=float(abs(z.sigma - sig)))
        if not self._on_arc(a, b, p):
            self.engine.unlocated_events += 1
            return None
        return Event("branch_point", p, "simple branch point: det[G_y; t^T] changes sign",
                     data=data, bracket=w)

    def _on_arc(self, a: Point, b: Point, p: Point) -> bool:
        """Whether a located point can lie on the arc between ``a`` and ``b``: where the
        parameter is monotone over the step (no fold), it must lie between theirs. A point
        outside was reached by a corrector that jumped to another solution: the event is not
        recorded (counted in ``unlocated_events``) rather than placed on the wrong curve."""
        ip = self.ip
        if np.sign(a.tangent[ip]) != np.sign(b.tangent[ip]):
            return True
        lo, hi = sorted((a.y[ip], b.y[ip]))
        tol = 1e-9 * (1.0 + abs(hi))
        return lo - tol <= p.y[ip] <= hi + tol

    def events_between(self, a: Point, b: Point, history: list[Point]) -> StepEvents:
        """Every event of the step ``a -> b`` (``history[-2]`` is the point before ``a``), each
        with the test that found it (:class:`EventSource`), and the earliest stop, if any:
        bounds (:meth:`_bound_events`), admissibility tests (:meth:`_admissibility_events`),
        event functions (:meth:`_event_function_events`), bifurcations
        (:meth:`_bifurcation_events`) and the signature (:meth:`_signature_events`)."""
        bounds, stops = self._bound_events(a, b)
        tests, test_stops = self._admissibility_events(a, b, history)
        stops += test_stops
        entries = [(EventSource.BOUND, ev) for ev in bounds]
        entries += [(EventSource.TEST, ev) for ev in tests]
        entries += [(EventSource.FUNCTION, ev)
                    for ev in self._event_function_events(a, b, history)]
        if self.settings.detect_bifurcations:
            entries += [(EventSource.BIFURCATION, ev)
                        for ev in self._bifurcation_events(a, b, tests)]
        entries += [(EventSource.SIGNATURE, ev) for ev in self._signature_events(a, b)]
        source = {id(ev): src for src, ev in entries}
        merged = _merge_coincident_grazing([ev for _, ev in entries], self.settings.event_tol)
        stop = min(stops, key=lambda sp: sp[0].s) if stops else None
        return StepEvents([(source[id(ev)], ev) for ev in merged], stop)

    def _bound_events(self, a: Point, b: Point
                      ) -> tuple[list[Event], list[tuple[Point, str]]]:
        """Parameter bounds and bounds on derived quantities crossed by the step: an
        ``endpoint`` (or the kind of the quantity's bound monitor) and a stop at each."""
        st = self.settings
        ip = self.ip
        found: list[Event] = []
        stops: list[tuple[Point, str]] = []
        bound_tests: list[tuple[str, Callable[[Point], float]]] = []
        if st.param_max is not None:
            bound_tests.append((f"{self.problem.parameter} = max",
                                lambda p: st.param_max - p.y[ip]))
        if st.param_min is not None:
            bound_tests.append((f"{self.problem.parameter} = min",
                                lambda p: p.y[ip] - st.param_min))
        # a quantity missing from a point's derived values (e.g. at a point the problem could
        # not simulate) has no value there: NaN, which no bound test fires on
        for name, (lo, hi) in st.derived_bounds.items():
            if hi is not None:
                bound_tests.append((f"{name} = max",
                                    lambda p, n=name, v=hi: v - p.derived.get(n, np.nan)))
            if lo is not None:
                bound_tests.append((f"{name} = min",
                                    lambda p, n=name, v=lo: p.derived.get(n, np.nan) - v))
        for label, fun in bound_tests:
            fa, fb = fun(a), fun(b)
            # (b exactly on the bound: a step ending on the window edge, see _walk)
            if (fa >= 0 and fb < 0) or (fa > 0 and fb == 0):
                p, w = (b, 0.0) if fb == 0 else (None, 0.0)
                on_parameter = label.startswith(f"{self.problem.parameter} =")
                value = st.param_max if label.endswith("max") else st.param_min
                if p is None and on_parameter:
                    p = self.engine.point_at_parameter(a, b, fa / (fa - fb), value)
                if p is None:
                    p, w = self._locate_continuous(a, b, fun, flo=fa, fhi=fb, tests=False)
                if on_parameter and abs(p.y[ip] - value) > 1e-9 * (1.0 + abs(value)):
                    # not located on the bound: never record a point outside the window
                    if self.retry_allowed:
                        raise RetryStep(f"bound {label} not located on the step's arc")
                    p, w = a, abs(b.s - a.s)
                ev = Event(self.bound_kind(label), p, f"bound reached: {label}", bracket=w,
                           data={"bound": label})
                found.append(ev)
                stops.append((p, f"bound: {label}"))
            elif fa < 0 and fb < fa:
                # started outside the bound and moving further out: stop here
                found.append(Event("endpoint", b, f"outside bound and leaving: {label}"))
                stops.append((b, f"bound: {label} (start outside, moving away)"))
        return found, stops

    def _sign_change_brackets(self, a: Point, b: Point, history: list[Point],
                              value: Callable[[Point], float]
                              ) -> tuple[list[tuple[float, float, float, float]],
                                         tuple[float, Point | None] | None]:
        """Brackets ``(lo, f(lo), hi, f(hi))`` (arclength from ``a``) of the zeros of a
        continuous function ``value`` (NaN where undefined; finite at ``a`` and ``b``) on the
        step: one for a sign change, two for a double zero hidden inside the step (the vertex
        of the parabola through the last three values, :func:`interior_extremum`, where the
        function has the other sign). When that vertex was evaluated without finding the other
        sign, ``(vertex, point there)`` is returned as well."""
        fa, fb = value(a), value(b)
        if np.sign(fa) != np.sign(fb):
            return [(0.0, fa, b.s - a.s, fb)], None
        if len(history) < 2:
            return [], None
        prev = history[-2]
        fp = value(prev)
        if not np.isfinite(fp):
            return [], None
        sv = interior_extremum(np.array([prev.s, a.s, b.s]), np.array([fp, fa, fb]))
        if sv is None:
            return [], None
        pm = self.engine.point_at(a, b, sv - a.s)
        fm = np.nan if pm is None else value(pm)
        if np.isfinite(fm) and np.sign(fm) != np.sign(fa):
            return [(0.0, fa, sv - a.s, fm), (sv - a.s, fm, b.s - a.s, fb)], None
        return [], (sv, pm)

    def _admissibility_events(self, a: Point, b: Point, history: list[Point]
                              ) -> tuple[list[Event], list[tuple[Point, str]]]:
        """Zeros of the admissibility test functions (``grazing`` or the test's kind; a stop
        where admissibility is lost if ``stop_on_inadmissible``) and tests that cease to be,
        or become, defined."""
        st = self.settings
        found: list[Event] = []
        stops: list[tuple[Point, str]] = []
        for name in b.tests:
            if name not in a.tests:
                continue
            fa, fb = a.tests[name], b.tests[name]
            if not (np.isfinite(fa) and np.isfinite(fb)):
                continue

            def fun(p: Point, n: str = name) -> float:
                return p.tests.get(n, np.nan)

            brackets, dip = self._sign_change_brackets(a, b, history, fun)
            if dip is not None and dip[1] is not None and name not in dip[1].tests:
                # the test is not even defined inside the dip (the sticking time of an orbit
                # that loses sticking and regains it within the step)
                sv = dip[0]
                found.append(self._locate_test_presence(a, b, name, 0.0, sv - a.s, False))
                found.append(self._locate_test_presence(a, b, name, sv - a.s, b.s - a.s,
                                                        True))
            for lo, flo, hi, fhi in brackets:
                located = self._zero_on_arc(a, b, fun, (lo, flo, hi, fhi),
                                            f"test function '{name}'")
                if located is None:
                    continue
                p, w = located
                leaving = flo >= 0 > fhi
                kind = self.problem.monitors.kind(Source.TEST, name)
                ev = Event(kind, p, f"test function '{name}' "
                           + _admissibility_change(name, leaving, a.tests if leaving
                                                   else b.tests),
                           data={"test": name, "admissible_before": bool(flo >= 0),
                                 "admissible_after": bool(fhi >= 0)}, bracket=w)
                found.append(ev)
                if leaving and st.stop_on_inadmissible:
                    stops.append((p, f"grazing: admissibility lost ('{name}')"))

        # a test function defined at one end of the step only: the quantity it measures ceases
        # to exist or appears (the sticking time of an orbit that loses its sticking phase:
        # the transition to incomplete chattering). The change is an event of the test's kind,
        # located by bisection on the test's presence.
        for name in [n for n in a.tests if n not in b.tests] + \
                [n for n in b.tests if n not in a.tests]:
            found.append(self._locate_test_presence(a, b, name, 0.0, b.s - a.s,
                                                    name in a.tests))
        return found, stops

    def _zero_on_arc(self, a: Point, b: Point, fun: Callable[[Point], float],
                     bracket: tuple[float, float, float, float], what: str
                     ) -> tuple[Point, float] | None:
        """The zero of ``fun`` in ``bracket`` located on the curve (:meth:`_locate_continuous`)
        with its bracket width, or None (counted in ``unlocated_events``) when it is not on
        the step's arc; :class:`RetryStep` instead where a shorter step may be tried."""
        lo, flo, hi, fhi = bracket
        p, w = self._locate_continuous(a, b, fun, lo, flo, hi, fhi)
        if self._on_arc(a, b, p):
            return p, w
        if self.retry_allowed:
            raise RetryStep(f"{what} changes sign but its zero is not on the step's arc")
        self.engine.unlocated_events += 1
        return None

    def _event_function_events(self, a: Point, b: Point, history: list[Point]) -> list[Event]:
        """Zeros of the problem's event functions (:meth:`Problem.event_functions`) on the
        step, each located on the curve to ``event_tol`` (Illinois) and recorded with the kind
        the problem's monitors give it (default ``grazing``); they never stop the branch. A
        function missing or not finite at either end raises nothing, nor does one that is
        exactly zero at ``a`` (that zero was recorded by the step that reached it)."""
        found: list[Event] = []
        for name, fb in b.event_values.items():
            fa = a.event_values.get(name, np.nan)
            if not (np.isfinite(fa) and np.isfinite(fb)) or fa == 0.0:
                continue

            def fun(p: Point, n: str = name) -> float:
                return p.event_values.get(n, np.nan)

            brackets, _ = self._sign_change_brackets(a, b, history, fun)
            for lo, flo, hi, fhi in brackets:
                located = self._zero_on_arc(a, b, fun, (lo, flo, hi, fhi),
                                            f"event function '{name}'")
                if located is None:
                    continue
                p, w = located
                if not abs(fun(p)) < min(abs(flo), abs(fhi)):
                    # the sign changed through a pole or a jump (e.g. a margin -v^2/(2a) as
                    # the acceleration at an impact passes zero), not a zero: no event
                    self.engine.sign_changes_without_zero += 1
                    continue
                found.append(Event(self.problem.monitors.kind(Source.FUNCTION, name), p,
                                   f"event function '{name}' vanishes ({flo:+.3g} -> "
                                   f"{fhi:+.3g})",
                                   data={"function": name, "value_before": float(flo),
                                         "value_after": float(fhi)}, bracket=w))
        return found

    def _bifurcation_events(self, a: Point, b: Point,
                            kinks: list[Event] | None = None) -> list[Event]:
        """Folds (the parameter component of the tangent changes sign, :meth:`_locate_fold`),
        simple branch points
        (``det[G_y; t^T]`` changes sign, tangents oriented continuously,
        :meth:`_locate_branch_point`) and multipliers crossing the unit circle, a crossing
        at +1 named fold or branch point by the tangent test
        (:func:`~nsm_continuation.core.palc.branch_points.plus_one_events`). ``kinks``: the
        step's admissibility events, beyond which an end may have no multipliers
        (:meth:`~nsm_continuation.core.palc.crossings.CrossingLocator.ends`)."""
        ip = self.ip
        found: list[Event] = []
        fold = self._locate_fold(a, b) if np.sign(a.tangent[ip]) != np.sign(b.tangent[ip]) \
            else None
        if fold is not None:
            found.append(fold)
        elif np.sign(a.bordered_det) != np.sign(b.bordered_det) and a.bordered_det != 0:
            bp = self._locate_branch_point(a, b)
            if bp is not None:
                found.append(bp)
        found.extend(self.engine.crossings.events(a, b, kinks or []))
        return plus_one_events(found, self.problem.conservative)

    def _locate_fold(self, a: Point, b: Point) -> Event | None:
        """The fold of the step ``a -> b``, whose tangents' parameter components differ in sign:
        the zero of that component located on the arc (Illinois,
        :meth:`_locate_continuous`), kept if the sign change is a fold
        (:func:`~nsm_continuation.core.palc.folds.is_fold`: the component known beyond its
        accuracy and the parameter's extremum not contradicted). Along a vertical family the
        component is noise and no fold is recorded."""
        ip = self.ip
        ends = (self._accuracy(a), self._accuracy(b))
        tangents = (float(a.tangent[ip]), float(b.tangent[ip]))
        if known_ends(tangents, ends) == 0:
            return None
        p, w = self._locate_continuous(a, b, lambda q: q.tangent[ip], tests=False)
        if not is_fold(tangents, ends,
                       (float(a.y[ip]), float(p.y[ip]), float(b.y[ip])), self._accuracy(p)):
            return None
        return Event("fold", p, "limit point: the parameter reaches an extremum along the "
                     "branch", data={"test": "tangent"}, bracket=w)

    def _accuracy(self, q: Point) -> Accuracy:
        """The accuracy of ``q``'s tangent and parameter
        (:func:`~nsm_continuation.core.palc.folds.accuracy`), kept for the last few points
        asked: the end of one step is the start of the next."""
        for p, acc in self._accuracies:
            if p is q:
                return acc
        acc = accuracy(self.problem, q.y, q.tangent, self.settings.newton_tol)
        self._accuracies = [*self._accuracies[-2:], (q, acc)]
        return acc

    def _signature_events(self, a: Point, b: Point) -> list[Event]:
        """A change of the problem's discrete signature (event sequence of a hybrid orbit)."""
        if a.signature is not None and b.signature is not None and a.signature != b.signature:
            return self._locate_signature_change(a, b)
        return []

    def _locate_test_presence(self, a: Point, b: Point, name: str, lo: float, hi: float,
                              was: bool) -> Event:
        """Bisection on whether the test ``name`` is defined, on the arc from ``a`` to ``b``
        between arclengths ``lo`` and ``hi`` from ``a`` (defined at ``lo`` iff ``was``, and in
        the other state at ``hi``); the event sits at the first point found in the new state."""
        def f(sig: float) -> tuple[bool | None, Point | None]:
            p = self.engine.point_at(a, b, sig, tests=True, floquet=False)
            return (None, None) if p is None else (name in p.tests, p)

        sig, p, width, vl, vr = bisect_predicate(f, lo, was, hi, not was,
                                                 self.settings.signature_event_tol)
        if p is None:  # the bracket never moved off ``hi``: the event is there
            p = b if hi >= b.s - a.s else (self.engine.point_at(a, b, hi) or b)
        else:
            p = self.engine.full(p)
        kind = self.problem.monitors.kind(Source.TEST, name)
        return Event(kind, p, f"test function '{name}' "
                     + ("ceases to be defined" if was else "becomes defined"),
                     data={"test": name, "defined_before": bool(vl),
                           "defined_after": bool(vr)}, bracket=width)

    def _locate_signature_change(self, a: Point, b: Point) -> list[Event]:
        """Bisection on the signature between two points; one event at the first change.

        A problem may declare a change not worth locating (``locate_signature(before, after)``
        False: e.g. only the number of impacts a simulator resolves before a chatter map, a
        tolerance-dependent count): the event is then recorded at ``b`` with the step as bracket.
        The event's kind is the problem's signature monitor's.
        """
        kind = self.problem.monitors.signature_kind
        assert kind is not None  # signatures are only evaluated when a kind is declared
        if not self.problem.locate_signature(a.signature, b.signature):
            return [Event(kind, b, f"event sequence {a.signature} -> {b.signature} (not "
                          "located: within the step)",
                          data={"signature_before": a.signature,
                                "signature_after": b.signature}, bracket=b.s - a.s)]

        def f(sig: float) -> tuple[str | None, Point | None]:
            p = self.engine.point_at(a, b, sig, tests=False, floquet=False)
            return (None, None) if p is None else (p.signature, p)

        sig, p, width, vl, vr = bisect_predicate(f, 0.0, a.signature, b.s - a.s, b.signature,
                                                 self.settings.signature_event_tol)
        p = b if p is None else self.engine.full(p)
        return [Event(kind, p, f"event sequence {vl} -> {vr}",
                      data={"signature_before": vl, "signature_after": vr}, bracket=width)]


def _admissibility_change(name: str, leaving: bool, others: dict[str, float]) -> str:
    """What a test's sign change does to the orbit, for the event's detail: admissibility
    lost (regained) only if every other test is non-negative on the side the orbit comes from
    (goes to), ``others`` (the tests at that end of the step); otherwise the test changes sign
    on an orbit another test already makes inadmissible (a linear grazing crossed where the
    clearance stays negative on both sides, say), and the detail names those tests."""
    blocking = sorted(k for k, v in others.items() if k != name and v < 0)
    if not blocking:
        return ("becomes negative: admissibility lost" if leaving
                else "becomes positive: admissibility regained")
    return (f"becomes negative (the orbit was already inadmissible: {blocking})" if leaving
            else f"becomes positive (the orbit stays inadmissible: {blocking})")


def _merge_coincident_grazing(events: list[Event], tol: float) -> list[Event]:
    """Several admissibility tests (or event functions) vanishing at the same point are one
    grazing event (for the impact oscillator: zero outgoing velocity and a critical point
    entering at t = 0+ together make a linear grazing orbit). The merged event lists every test
    and event function in ``data['tests']``."""
    graz = sorted((e for e in events if e.kind == "grazing"), key=lambda e: e.point.s)
    others = [e for e in events if e.kind != "grazing"]
    merged: list[Event] = []
    for ev in graz:
        name = ev.data.get("test", ev.data.get("function"))
        ev.data.setdefault("tests", [] if name is None else [name])
        # 1e-7 in arclength: a test that jumps at a switching point (a critical point entering
        # the period at t = 0+) is located only to the round-off of the value it jumps to
        if merged and abs(ev.point.s - merged[-1].point.s) <= max(
                1e-7 * (1 + abs(ev.point.s)), 2 * ev.bracket, 2 * merged[-1].bracket):
            last = merged[-1]
            last.data["tests"] = sorted(set(last.data["tests"]) | set(ev.data["tests"]))
            last.detail = f"test functions {last.data['tests']} vanish together"
            continue
        merged.append(ev)
    return others + merged
