"""Pseudo-arclength continuation (Keller) with event detection; problem-agnostic.

The curve ``G(y) = 0``, ``G: R^(n+1) -> R^n``, is followed by

* a tangent predictor ``y_p = y_k + h t_k`` with ``t_k`` the unit null vector of ``G_y(y_k)``
  (oriented continuously: ``t_{k+1} . t_k > 0``, which passes folds);
* a Newton corrector on the bordered system ``[G(y); t_k . (y - y_k) - h] = 0`` with the exact
  CasADi Jacobian;
* step control (:mod:`~nsm_continuation.core.palc.step_control`): a step is rejected (and
  retried with ``h / 2``) when Newton fails (or the problem raises
  :class:`~nsm_continuation.core.problem.EvaluationError`) or the tangent turns by more than
  ``max_angle``; accepted steps grow or shrink ``h`` from the number of Newton iterations and
  the turning angle, and their growth is capped by the ratio of the multipliers' motion to the
  limits below (:func:`~nsm_continuation.core.palc.step_control._motion_capped_step`). A step
  never carries the parameter past an edge of the window (it is shortened to end on the edge,
  corrected there), nor an admissibility test function or an event function far past a zero
  (``TEST_STEP_FACTOR``), and the multipliers near the unit circle move at most
  ``max_multiplier_step`` per step (:func:`~nsm_continuation.core.palc.motion.
  multiplier_motion`); in a conservative family (``problem.conservative``, multipliers with
  Krein signatures) only those near a collision with a partner of the other signature do
  (:func:`~nsm_continuation.core.palc.motion.krein_motion`), and a step may not close the
  nearest such collision by more than half nor swap the multipliers outside the circle
  (:func:`~nsm_continuation.core.palc.motion.krein_closing`);
* termination with a recorded reason, never an exception: parameter bound, bound on a derived
  quantity, maximum number of points, step below minimum (with the problem's own message when it
  raised), step below the floating-point resolution, singular Jacobian, loss of admissibility
  (when asked), an asymptote (amplitude growing without bound, ``p*`` extrapolated), and
  ``internal error: Type: message`` for a bug, keeping the points computed so far. A branch
  that fails next to a boundary of its family ends at it, named
  (:mod:`~nsm_continuation.core.palc.ends`): a kink located ahead that cannot be crossed, or the
  extrapolated zero of a vanishing quantity (e.g. an impact velocity). A branch that returns
  to its start (a closed loop, e.g. an isola) ends there after one round, its events once
  each, and is not walked again the other way (:mod:`~nsm_continuation.core.palc.loops`).

At each accepted point the problem's hooks give admissibility test functions, event functions
(:meth:`~nsm_continuation.core.problem.Problem.event_functions`: located, never ending the branch),
Floquet multipliers and a signature; their changes between two points are located on the curve
with :mod:`nsm_continuation.core.roots`
(:meth:`~nsm_continuation.core.palc.locate.EventLocator.events_between`). A multiplier crossing is
detected by the number of multipliers outside ``|lambda| = 1 + tol`` and located on
``|lambda_c| = 1`` (:meth:`~nsm_continuation.core.palc.crossings.CrossingLocator.locate`).

The engine holds the curve (corrector, tangent, analysis of a point, points on the arc of a
step) and the step loop (:meth:`ContinuationEngine._walk`); its parts hold the rest: the step
control (:class:`~.step_control.StepController`), the event location
(:class:`~.locate.EventLocator`), the multiplier crossings (:class:`~.crossings.
CrossingLocator`), kinks and charts (:class:`~.kinks.KinkCrosser`), asymptotes
(:class:`~.asymptote.AsymptoteMonitor`), named ends (:class:`~.ends.EndLocator`) and closed
loops (:class:`~.loops.LoopCloser`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from nsm_continuation.core.floquet import count_outside
from nsm_continuation.core.palc.asymptote import AsymptoteMonitor
from nsm_continuation.core.palc.crossings import CrossingLocator
from nsm_continuation.core.palc.ends import EndLocator
from nsm_continuation.core.palc.errors import (
    HOOK_FAULTS,
    NUMERICAL_ERRORS,
    MonitorError,
    RetryStep,
    check_finite,
    describe_error,
    describe_fault,
)
from nsm_continuation.core.palc.kinks import KinkCrosser, KinkCrossing
from nsm_continuation.core.palc.locate import EventLocator
from nsm_continuation.core.palc.loops import LoopCloser
from nsm_continuation.core.palc.step_control import StepController
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint
from nsm_continuation.core.records import CLOSED_LOOP, START_OUTSIDE, Branch, Event, Point
from nsm_continuation.core.settings import ContinuationSettings

#: corrector iterates with their residual at the problem's ``residual_floor`` that make a
#: converged point (the smallest of them) (:meth:`ContinuationEngine.correct`)
FLOOR_ITERATES = 3


class ContinuationEngine:
    """Continue the solution branches of a :class:`~nsm_continuation.core.problem.Problem`."""

    def __init__(self, problem: Problem, settings: ContinuationSettings,
                 progress: Callable[[int], None] | None = None) -> None:
        self.problem = problem
        self.settings = settings
        self.progress = progress
        self.ip = problem.parameter_index
        # the run's statistics (read by the algorithm's report)
        self.n_evaluations = 0
        #: steps taken although the multipliers moved too far (the halvings ran out)
        self.motion_limited_steps = 0
        #: events whose zero could not be located on the step's arc (not recorded)
        self.unlocated_events = 0
        #: steps in which two multipliers of opposite Krein signature passed each other on
        #: the circle (checked on their discriminant: no window,
        #: :meth:`~.crossings.CrossingLocator.krein_windows`)
        self.krein_passings = 0
        #: sign changes of an event function that are not zeros (poles, jumps: no event)
        self.sign_changes_without_zero = 0
        #: every move to another chart in the run (:meth:`~.kinks.KinkCrosser.rechart`), for
        #: the report
        self.rechart_notes: list[str] = []
        # the parts of the engine (each keeps a reference to it)
        self.step_control = StepController(self)
        self.locator = EventLocator(self)
        self.crossings = CrossingLocator(self)
        self.kinks = KinkCrosser(self)
        self.asymptote = AsymptoteMonitor(self)
        self.ends = EndLocator(self)
        self.loops = LoopCloser(self)

    # ------------------------------------------------------------------ linear algebra
    # every solve is with the bordered matrix [G_y(y); r^T], factorised by the problem
    # (Problem.bordered_factor: dense by default, structured where the problem has structure)
    def correct(self, y_guess: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray,
                sigma: float) -> tuple[np.ndarray | None, int, str]:
        """Newton on ``[G(y); t_ref . (y - y_ref) - sigma] = 0``; returns (y, iterations, why).

        Converged where a step is below ``newton_tol`` (and the residual there small), or,
        for a problem that declares a ``residual_floor`` (:attr:`Problem.residual_floor`),
        once :data:`FLOOR_ITERATES` iterates have had their residual at that floor: the one
        with the smallest is then a solution to the residual's noise, and the steps, that noise
        over a nearly singular Jacobian, say only how well its position along the nearly null
        direction is determined."""
        st = self.settings
        y = np.array(y_guess, dtype=float)
        r0 = None
        nr = float("nan")
        floor = self.problem.residual_floor
        at_floor: list[tuple[float, np.ndarray]] = []  # iterates at the problem's floor
        for it in range(1, st.newton_max_iter + 1):
            try:
                g, factor = self.problem.residual_and_factor(y, t_ref)
            except NUMERICAL_ERRORS as exc:  # the problem names the cause: carry it
                return None, it, describe_error(exc)
            self.n_evaluations += 1
            rhs = np.append(g, t_ref @ (y - y_ref) - sigma)
            nr = np.linalg.norm(rhs, np.inf)
            if not np.isfinite(nr):
                return None, it, "non-finite residual"
            if r0 is None:
                r0 = nr
            elif nr > 1e4 * max(r0, 1e-300):
                return None, it, "Newton diverged"
            if floor is not None and nr <= floor * (1.0 + np.linalg.norm(y, np.inf)):
                at_floor.append((float(nr), y))
                if len(at_floor) >= FLOOR_ITERATES:
                    return min(at_floor, key=lambda a: a[0])[1], it, ""
            try:
                dy = factor.solve(-rhs)
            except np.linalg.LinAlgError:
                return None, it, "singular Jacobian"
            if not np.all(np.isfinite(dy)):
                return None, it, "non-finite Newton step"
            y = y + dy
            scale = 1.0 + np.linalg.norm(y, np.inf)
            if np.linalg.norm(dy, np.inf) <= st.newton_tol * scale:
                try:
                    g = self.problem.evaluate(y)
                except NUMERICAL_ERRORS as exc:
                    return None, it, describe_error(exc)
                if np.linalg.norm(g, np.inf) <= 1e3 * st.newton_tol * scale:
                    return y, it, ""
        return None, st.newton_max_iter, (f"Newton did not converge (residual {nr:.3g} after "
                                          f"{st.newton_max_iter} iterations)")

    def tangent(self, y: np.ndarray, t_prev: np.ndarray | None) -> np.ndarray:
        """Unit null vector of ``G_y(y)``, oriented along ``t_prev`` (or by SVD at a start)."""
        if t_prev is None:
            _, sv, vt = np.linalg.svd(self.problem.jacobian(y))
            if sv.size and sv[-1] < 1e-13 * max(sv[0], 1.0):
                raise np.linalg.LinAlgError("Jacobian rank deficient at start")
            t = vt[-1]
        else:
            rhs = np.zeros(len(y))
            rhs[-1] = 1.0
            t = self.problem.bordered_factor(y, t_prev).solve(rhs)
        t = t / np.linalg.norm(t)
        if t_prev is not None and t @ t_prev < 0:
            t = -t
        return t

    def analyse(self, y: np.ndarray, t: np.ndarray, s: float, iterations: int = 0,
                tests: bool = True, floquet: bool = True,
                known: FloquetData | None = None) -> Point:
        """Evaluate the problem's hooks at a corrected point.

        ``tests``/``floquet`` switch off the admissibility tests (and the event functions) or the
        multipliers while an event of the other kind is being located (the located point is then
        analysed in full).
        Multipliers are computed only on admissible points unless
        ``settings.stability_on_phantom``: stability of a phantom orbit has no physical meaning.
        """
        pr = self.problem
        test_values = pr.admissibility(y) if tests else {}
        check_finite("admissibility test (Problem.admissibility)", test_values, self._at(y))
        event_values = pr.event_functions(y) if tests else {}
        fl = None
        if floquet and (self.settings.stability_on_phantom or not tests
                        or all(v >= 0 for v in test_values.values())):
            fl = known if known is not None else self.floquet(y, t)
        mult = None if fl is None else np.asarray(fl.multipliers)
        circle_tol = self.settings.unit_circle_tol
        if fl is not None:
            # eigenvalues are known to ~ eps * |B| only: never classify below that
            circle_tol = max(circle_tol, 1e3 * np.finfo(float).eps * fl.matrix_norm,
                             fl.noise)
        n_out = 0 if mult is None else count_outside(mult, circle_tol)
        sign, logdet = pr.bordered_factor(y, t).slogdet()
        det = float(sign * np.exp(min(logdet, 700.0))) if sign != 0 else 0.0
        return Point(
            y=y, s=s, tangent=t, tests=test_values, multipliers=mult,
            trivial_error=0.0 if fl is None else fl.trivial_error, n_unstable=n_out,
            derived=pr.derived(y), bordered_det=det, newton_iterations=iterations,
            residual_norm=float(np.linalg.norm(pr.evaluate(y), np.inf)),
            circle_tol=circle_tol,
            signature=pr.signature(y) if pr.monitors.signature_kind is not None else None,
            event_values=event_values, chart=pr.chart(),
        )

    def floquet(self, y: np.ndarray, t: np.ndarray) -> FloquetData | None:
        """The problem's multipliers, or None where they cannot be computed (e.g. exactly at
        grazing, where the return map is not differentiable): recorded as unknown. Never
        called on the problem when ``settings.stability`` is false."""
        if not self.settings.stability:
            return None
        try:
            fl = self.problem.floquet(y, t)
        except (*NUMERICAL_ERRORS, ValueError):
            return None
        if fl is None:
            return None
        if not isinstance(fl, FloquetData):
            raise MonitorError(f"Problem.floquet at {self._at(y)} returned "
                               f"{type(fl).__name__}, not FloquetData or None")
        mult = np.asarray(fl.multipliers)
        if not np.all(np.isfinite(mult)):
            raise MonitorError(f"Floquet multipliers (Problem.floquet) at {self._at(y)} are "
                               f"not finite: {mult.tolist()}")
        return fl

    def _at(self, y: np.ndarray) -> str:
        """Where a point is, for a message: ``problem 'name', p = value``."""
        pr = self.problem
        return f"{pr.parameter} = {float(y[self.ip]):.10g} (problem {pr.name!r})"

    def full(self, p: Point) -> Point:
        """``p`` analysed with every hook (after a partial analysis during event location)."""
        return self.analyse(p.y, p.tangent, p.s, p.newton_iterations)

    # ------------------------------------------------------------------ start
    def correct_start(self, start: StartPoint) -> tuple[Point | None, str]:
        """Newton at fixed parameter from the start guess; returns the first point."""
        y0 = np.asarray(start.y, dtype=float)
        if not np.all(np.isfinite(y0)):
            return None, "start guess is not finite"
        e = np.zeros(len(y0))
        e[self.ip] = 1.0
        y, it, why = self.correct(y0, e, y0, 0.0)
        if y is None:
            return None, f"start point did not converge ({why})"
        try:
            t = self.tangent(y, None)
        except np.linalg.LinAlgError:
            return None, "singular Jacobian at start point"
        except NUMERICAL_ERRORS as exc:
            return None, f"no tangent at start point ({describe_error(exc)})"
        if start.direction != 0 and np.sign(t[self.ip]) != np.sign(start.direction):
            t = -t
        try:
            return self.analyse(y, t, 0.0, it), ""
        except NUMERICAL_ERRORS as exc:
            return None, f"start point cannot be analysed ({describe_error(exc)})"

    # ------------------------------------------------------------------ branches
    def run(self, start: StartPoint, branch_id: int = 0) -> Branch:
        """Continue the branch through ``start``; never raises: every failure, numerical or
        not, ends the branch (or the half-branch) with a recorded reason."""
        moved_before = len(self.rechart_notes)
        try:
            p0, why = self.correct_start(start)
        except HOOK_FAULTS as exc:  # a bug in a hook must not take the whole run down
            p0, why = None, f"at the start point: {describe_fault(exc, self.problem.name)}"
        if p0 is None:
            if start.info.get("found"):  # what the start's own search found, e.g. a transient
                why = f"{why}; {start.info['found']}"
            return Branch(branch_id, start.label, [], [], {"start": why}, dict(start.info))
        directions = [1] if (start.direction != 0 or self.settings.direction != 0) else [1, -1]
        if self.settings.direction != 0 and start.direction == 0:
            if np.sign(p0.tangent[self.ip]) != np.sign(self.settings.direction):
                # reversed with its bordered determinant: a tangent flipped alone made the
                # first step see a sign change of det[G_y; t^T], a branch point at the start
                p0 = _with_tangent(p0, -p0.tangent)
        halves = []
        termination: dict[str, str] = {}
        for d in directions:
            first = _with_tangent(p0, p0.tangent * d)
            if any(r.startswith(CLOSED_LOOP) for r in termination.values()):
                break  # the loop is closed: walked once, not again the other way
            self.loops.begin(first, [h[1][-1] for h in halves])
            pts, evs, reason = self._continue_one_direction(first)
            if not any(ev.kind == "endpoint" and ev.point is pts[-1] for ev in evs):
                evs.append(Event("endpoint", pts[-1], f"branch end: {reason}",
                                 data={"reason": reason}))
            halves.append((d, pts, evs))
            termination["forward" if d == 1 else "backward"] = reason
        # merge: backward (reversed, negative arclength) + forward
        points: list[Point] = []
        events: list[Event] = []
        for d, pts, evs in halves:
            if d == -1:
                # negate the arclength of every point once (an event may sit on a branch point)
                flipped = {id(p): p for p in pts} | {id(ev.point): ev.point for ev in evs}
                for p in flipped.values():
                    p.s = -p.s
                points = list(reversed(pts[1:])) + points
            else:
                points = points + pts
            events.extend(evs)
        events.sort(key=lambda ev: ev.point.s)
        info = dict(start.info)
        if len(self.rechart_notes) > moved_before:
            info["chart_moves"] = self.rechart_notes[moved_before:]
        return Branch(branch_id, start.label, points, events, termination, info)

    def _continue_one_direction(self, p0: Point) -> tuple[list[Point], list[Event], str]:
        """One half-branch from ``p0``: ``(points, events, termination reason)``. Never raises:
        an unexpected exception (a bug in a hook or here) ends the half-branch with the reason
        ``internal error: Type: message``, keeping the points computed so far."""
        pts = [p0]
        events: list[Event] = []
        base = self.problem
        try:
            reason = self._walk(pts, events)
        except HOOK_FAULTS as exc:  # noqa: BLE001 - recorded, never raised
            reason = describe_fault(exc, self.problem.name)
        finally:  # the other half starts from p0, in p0's chart
            self.problem = base
        return pts, events, reason

    def _walk(self, pts: list[Point], events: list[Event]) -> str:
        """Steps from ``pts[-1]``, appending accepted points and located events in place;
        returns the termination reason. One step: its length (:meth:`StepController.plan`),
        predictor and corrector (:meth:`_predict_correct`), the checks of the turning angle
        and of the multipliers' motion (:meth:`StepController.admit`), the analysis of the
        new point and the events of the step (:meth:`EventLocator.step`), a kink crossed in
        the step or met by a step that failed (:class:`KinkCrosser`), then the next step's
        length (:meth:`StepController.accept`)."""
        control = self.step_control
        if not control.inside_window(pts[0]):  # a start outside the window ends at once
            st = self.settings
            return (f"{START_OUTSIDE} (the start's parameter {pts[0].y[control.ip]:.10g} is "
                    f"outside the window [{st.param_min}, {st.param_max}])")
        control.begin()
        self.asymptote.begin()
        self.ends.begin()
        kink_tried = -1
        while len(pts) < self.settings.max_points:
            self.kinks.rechart(pts)
            a = pts[-1]
            step = control.plan(pts)
            if isinstance(step, str):  # the step no longer moves the point
                return self.ends.named(pts, events, step)
            if step is None:  # on the window edge
                return self.locator.stop_on_edge(a, events)
            if control.approaching_kink(step) and kink_tried != len(pts) \
                    and not self.ends.expecting(a):
                # an event function's zero approached geometrically: a kink may lie there
                kink_tried = len(pts)
                crossing = self.kinks.ahead(pts, step.h)
                if crossing is not None and crossing.end is None:
                    if (closed := self._cross(crossing, pts, events)) is not None:
                        return closed
                    continue
                if crossing is not None:  # located, nothing beyond: ends there if it fails
                    self.ends.expect(crossing, a)
            y, t, it, control.why = self._predict_correct(a, step.h, step.edge)
            if y is None:
                # the step may have failed on a kink of the branch ahead (e.g. a grazing
                # approached from the side where the residual's Jacobian blows up): looked
                # for once from each point, and not again while one located ahead that
                # cannot be crossed still lies there (the branch ends at it if it fails)
                crossing = None if kink_tried == len(pts) or self.ends.expecting(a) \
                    else self.kinks.ahead(pts, step.h)
                kink_tried = len(pts)
                if crossing is not None and crossing.end is None:
                    if (closed := self._cross(crossing, pts, events)) is not None:
                        return closed
                    continue
                if crossing is not None:
                    self.ends.expect(crossing, a)
                # a step that failed reaching past the zero of a vanishing quantity (the
                # family ends there): the branch ends at it
                if (end := self.ends.vanishing_end(pts, events, f"the step towards it: "
                                                   f"{control.why}", step.h)) is not None:
                    return end
                if (stop := control.fail(step, control.why)) is not None:
                    return self.ends.named(pts, events, stop)
                continue
            trial = control.admit(a, step, y, t, it)
            if trial is None:
                continue
            try:
                b, found = self.locator.step(a, pts, trial)
            except RetryStep as exc:
                control.refuse(step, str(exc))
                continue
            except NUMERICAL_ERRORS as exc:
                if (stop := control.fail(step, describe_error(exc))) is not None:
                    return self.ends.named(pts, events, stop)
                continue
            crossing = self.kinks.in_step(a, found, step.h)
            if crossing is not None:
                if crossing.end is not None:  # located, and no branch beyond it
                    crossing.record(pts, events)
                    return crossing.end
                if (closed := self._cross(crossing, pts, events)) is not None:
                    return closed
                continue
            if found.stop is not None:
                events.extend(found.until_stop())
                pts.append(found.stop[0])
                return found.stop[1]
            events.extend(self.kinks.family_events(a, b, found.entries))
            pts.append(b)
            if self.progress is not None:
                self.progress(1)
            if (closed := self.loops.closes(pts, events, len(pts) - 1)) is not None:
                return closed
            asym = self.asymptote.check(pts)
            if asym is not None:
                events.append(asym)
                return f"asymptote ({asym.detail})"
            if (end := self.ends.unresolved_end(pts, events)) is not None:
                return end
            control.accept(trial)
        return "max_points"

    def _cross(self, crossing: KinkCrossing, pts: list[Point], events: list[Event]
               ) -> str | None:
        """A kink crossed (its points and events appended); the reason the half-branch ends if
        the points beyond it close a loop (:meth:`~.loops.LoopCloser.closes`), else None."""
        n_before = len(pts)
        crossing.record(pts, events)
        return self.loops.closes(pts, events, n_before)

    # ------------------------------------------------------------------ predictor, corrector
    def _predict_correct(self, a: Point, h_step: float, edge: float | None
                         ) -> tuple[np.ndarray | None, np.ndarray, int, str]:
        """Tangent predictor and Newton corrector of one step (at the edge's parameter when
        the step ends on the window edge); ``(y, tangent, iterations, why)``, ``y`` None when
        the step failed (``why``)."""
        y_pred = a.y + h_step * a.tangent
        if edge is None:
            y_new, it, why = self.correct(y_pred, a.tangent, a.y, h_step)
        else:
            y_new, it, why = self._correct_on_edge(y_pred, edge, h_step)
        t_new = a.tangent
        if y_new is not None:
            try:
                t_new = self.tangent(y_new, a.tangent)
            except np.linalg.LinAlgError:
                y_new, why = None, "singular Jacobian"
            except NUMERICAL_ERRORS as exc:
                y_new, why = None, describe_error(exc)
        return y_new, t_new, it, why

    def _correct_on_edge(self, y_pred: np.ndarray, value: float, h: float
                         ) -> tuple[np.ndarray | None, int, str]:
        """Newton at the fixed parameter ``value`` (a window edge) from the predictor ``y_pred``
        of a step of length ``h``; a solution farther than ``h`` from it is another branch's."""
        e = np.zeros(len(y_pred))
        e[self.ip] = 1.0
        ref = y_pred.copy()
        ref[self.ip] = value
        y, it, why = self.correct(y_pred, e, ref, 0.0)
        if y is None:
            return None, it, why
        if np.linalg.norm(y - y_pred) > h:
            return None, it, "corrector at the window edge left the branch"
        y[self.ip] = value  # exact to round-off already: the end point lies on the edge
        return y, it, ""

    # ------------------------------------------------------------------ points on a step's arc
    def _corrected_point(self, a: Point, guess: np.ndarray, t_ref: np.ndarray,
                         y_ref: np.ndarray, sigma: float, max_dist: float = np.inf,
                         **flags: bool) -> Point | None:
        """Newton on ``[G; t_ref . (y - y_ref) - sigma]`` from ``guess``, then analysed (the
        arclength is measured from ``a`` along its tangent). A solution farther than
        ``max_dist`` from the guess belongs to another branch and is rejected."""
        y, it, _ = self.correct(guess, t_ref, y_ref, sigma)
        if y is None or np.linalg.norm(y - guess) > max_dist:
            return None
        try:
            t = self.tangent(y, a.tangent)
            return self.analyse(y, t, a.s + float(a.tangent @ (y - a.y)), it, **flags)
        except NUMERICAL_ERRORS:  # the problem cannot evaluate there: no point
            return None

    def point_at(self, a: Point, b: Point, sigma: float, tests: bool = True,
                  floquet: bool = True) -> Point | None:
        """Corrected branch point at arclength ``sigma`` from ``a`` (between ``a`` and ``b``)."""
        h = b.s - a.s
        lam = sigma / h if h != 0 else 0.0
        guess = (1 - lam) * a.y + lam * b.y
        # the arc between two accepted points stays within ~h sin(max_angle) of the chord
        return self._corrected_point(a, guess, a.tangent, a.y, sigma,
                                     max_dist=0.5 * abs(h) + 1e-12, tests=tests,
                                     floquet=floquet)

    def point_at_parameter(self, a: Point, b: Point, lam: float, value: float) -> Point | None:
        """Corrected point with the parameter fixed at ``value`` (a bound), by Newton at fixed
        parameter from the chord (a parameter bound needs no root finding on the curve)."""
        e = np.zeros(len(a.y))
        e[self.ip] = 1.0
        guess = (1 - lam) * a.y + lam * b.y
        ref = guess.copy()
        ref[self.ip] = value
        return self._corrected_point(a, guess, e, ref, 0.0,
                                     max_dist=0.5 * abs(b.s - a.s) + 1e-12)

    def on_chord(self, a: Point, b: Point, sig: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The branch point at arclength ``sig`` from ``a`` (Newton from the chord ``a -> b``)
        and its tangent, without analysis (the pair trackers' trial points); None if the
        corrector fails or lands off the arc."""
        h = b.s - a.s
        lam = sig / h if h != 0 else 0.0
        guess = (1 - lam) * a.y + lam * b.y
        y, _, _ = self.correct(guess, a.tangent, a.y, sig)
        if y is None or np.linalg.norm(y - guess) > 0.5 * abs(h) + 1e-12:
            return None
        try:
            return y, self.tangent(y, a.tangent)
        except NUMERICAL_ERRORS:
            return None


def _with_tangent(p: Point, t: np.ndarray) -> Point:
    """A copy of ``p`` with the tangent ``t`` (``+-p.tangent``) and its bordered determinant
    ``det[G_y; t^T]``, which is linear in ``t`` (expansion along the last row): it changes
    sign with the tangent. The branch-point test compares determinants of consecutive points
    whose tangents are oriented continuously (``t_{k+1} . t_k > 0``); a reversed tangent with
    the determinant of the other orientation is a spurious sign change."""
    sign = 1.0 if float(t @ p.tangent) >= 0 else -1.0
    return replace(p, tangent=np.asarray(t, dtype=float), bordered_det=p.bordered_det * sign)
