"""Pseudo-arclength continuation (Keller) with event detection; problem-agnostic.

The curve ``G(y) = 0``, ``G: R^(n+1) -> R^n``, is followed by

* a tangent predictor ``y_p = y_k + h t_k`` with ``t_k`` the unit null vector of ``G_y(y_k)``
  (oriented continuously: ``t_{k+1} . t_k > 0``, which passes folds);
* a Newton corrector on the bordered system ``[G(y); t_k . (y - y_k) - h] = 0`` with the exact
  CasADi Jacobian;
* step control: a step is rejected (and retried with ``h / 2``) when Newton fails (or the
  problem raises :class:`~nsm_continuation.core.problem.EvaluationError`) or the tangent turns by
  more
  than ``max_angle``; accepted steps grow or shrink ``h`` from the number of Newton iterations
  and the turning angle, and their growth is capped by the ratio of the multipliers' motion to
  the limits below (:func:`_motion_capped_step`). A step never carries the
  parameter past an edge of the window (it is shortened to end on the edge, corrected there),
  nor an admissibility test function or an event function far past a zero
  (``TEST_STEP_FACTOR``), and the multipliers near the unit circle move at most
  ``max_multiplier_step`` per step (:func:`multiplier_motion`); in a
  conservative family (``problem.conservative``, multipliers with Krein signatures) only those
  near a collision with a partner of the other signature do (:func:`krein_motion`), and a step
  may not close the nearest such collision by more than half nor swap the multipliers outside
  the circle (:func:`krein_closing`);
* termination with a recorded reason, never an exception: parameter bound, bound on a derived
  quantity, maximum number of points, step below minimum (with the problem's own message when it
  raised), step below the floating-point resolution, singular Jacobian, loss of admissibility
  (when asked), an asymptote (amplitude growing without bound, ``p*`` extrapolated), and
  ``internal error: Type: message`` for a bug, keeping the points computed so far.

At each accepted point the problem's hooks give admissibility test functions, event functions
(:meth:`~nsm_continuation.core.problem.Problem.event_functions`: located, never ending the branch),
Floquet multipliers and a signature; their changes between two points are located on the curve
with :mod:`nsm_continuation.core.roots` (:meth:`ContinuationEngine._events_between`). A multiplier
crossing is detected by the number of multipliers outside ``|lambda| = 1 + tol`` and located on
``|lambda_c| = 1`` (:meth:`ContinuationEngine._locate_multiplier_crossings`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from nsm_continuation.core.floquet import (
    classify_crossing,
    collision_distances,
    count_outside,
    definite_sign,
    krein_of,
    nearest_distances,
)
from nsm_continuation.core.floquet.krein import SEVERAL, discriminant, swap_paths
from nsm_continuation.core.problem import EvaluationError, FloquetData, Problem, StartPoint
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.core.roots import bisect_predicate, illinois, interior_extremum, pole_estimate
from nsm_continuation.core.scalar_search import bounded_minimum
from nsm_continuation.core.settings import ContinuationSettings

#: errors of numerical origin (a problem that cannot evaluate at a point, linear algebra,
#: floating point): a step that meets one is retried smaller, like a failed Newton step, and the
#: error's message is the termination reason if the branch has to end. Any other exception is a
#: bug: it ends the half-branch (``internal error: ...``) and keeps the points computed so far.
NUMERICAL_ERRORS = (EvaluationError, np.linalg.LinAlgError, FloatingPointError, OverflowError,
                    ZeroDivisionError)

#: a step shorter than this times ``1 + |y|_inf`` does not move the point in floating point
STEP_RESOLUTION = 1e-14

#: a step may move an admissibility test function towards zero by at most this many times its
#: value (predicted linearly from the secant of the last step): a zero is crossed and located,
#: never jumped over with the test changing sign twice inside one step. Must exceed 1 (a cap
#: at a fraction of the value would approach the zero geometrically and never reach it).
TEST_STEP_FACTOR = 2.0

#: asymptote detection (ContinuationEngine._asymptote): over the last ASYMPTOTE_POINTS points
#: a monitored quantity fits ``|p - p*|^(-k)``, and it has grown ASYMPTOTE_GROWTH times along
#: the half-branch
ASYMPTOTE_POINTS = 6
ASYMPTOTE_GROWTH = 100.0


def describe_error(exc: BaseException) -> str:
    """The message of a problem's :class:`EvaluationError` (the real cause), or ``Type: msg``."""
    if isinstance(exc, EvaluationError) and str(exc):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


#: a tangent's parameter component below this at both ends of a step is noise: its sign
#: change is no fold. Along a branch on which the parameter is constant (the g = 0 chain's
#: modes, Prop. 7.2, a vertical line in the FEP) the component is ~1e-17 and flips at random,
#: and up to ~1e-12 next to the branch point it is born at (an ill-conditioned bordered
#: solve); a genuine fold moves the parameter by less than this times the step between two
#: points whose tangents are both this close to it
TANGENT_NOISE = 1e-9


class _RetryStep(Exception):
    """Raised while analysing a step whose result cannot be trusted (an event that cannot be
    located on the arc, a bound not reached): the step is retried with half its length."""


class ContinuationEngine:
    """Continue the solution branches of a :class:`~nsm_continuation.core.problem.Problem`."""

    def __init__(self, problem: Problem, settings: ContinuationSettings,
                 progress: Callable[[int], None] | None = None) -> None:
        self.problem = problem
        self.settings = settings
        self.progress = progress
        self.ip = problem.parameter_index
        self.n_evaluations = 0
        self.motion_limited_steps = 0
        self.unlocated_events = 0
        #: steps in which two multipliers of opposite Krein signature passed each other on
        #: the circle (checked on their discriminant: no window, :meth:`_krein_windows`)
        self.krein_passings = 0
        #: the Floquet data of the last few points, by their unknowns (:meth:`_krein_at`)
        self._floquet_memo: dict[bytes, FloquetData] = {}
        #: set while the events of a step longer than a few step_min are analysed: an event
        #: that cannot be located on the step's arc then retries the step shorter
        self._retry_allowed = False
        #: running minimum of each monitored quantity along the current half-branch
        self._monitor_min: dict[str, float] = {}
        #: every move to another chart in the run (:meth:`_rechart`), for the report
        self.rechart_notes: list[str] = []
        #: sign changes of an event function that are not zeros (poles, jumps: no event)
        self.sign_changes_without_zero = 0
        self.last_was_pole = False

    # ------------------------------------------------------------------ linear algebra
    # every solve is with the bordered matrix [G_y(y); r^T], factorised by the problem
    # (Problem.bordered_factor: dense by default, structured where the problem has structure)
    def correct(self, y_guess: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray,
                sigma: float) -> tuple[np.ndarray | None, int, str]:
        """Newton on ``[G(y); t_ref . (y - y_ref) - sigma] = 0``; returns (y, iterations, why)."""
        st = self.settings
        y = np.array(y_guess, dtype=float)
        r0 = None
        nr = float("nan")
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
        event_values = pr.event_functions(y) if tests else {}
        fl = None
        if floquet and (self.settings.stability_on_phantom or not tests
                        or all(v >= 0 for v in test_values.values())):
            fl = known if known is not None else self._floquet(y, t)
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
            signature=pr.signature(y) if pr.signature_kind is not None else None,
            event_values=event_values, chart=pr.chart(),
        )

    def _floquet(self, y: np.ndarray, t: np.ndarray) -> FloquetData | None:
        """The problem's multipliers, or None where they cannot be computed (e.g. exactly at
        grazing, where the return map is not differentiable): recorded as unknown. Never
        called on the problem when ``settings.stability`` is false."""
        if not self.settings.stability:
            return None
        try:
            fl = self.problem.floquet(y, t)
        except (*NUMERICAL_ERRORS, ValueError):
            return None
        if fl is None or not np.all(np.isfinite(fl.multipliers)):
            return None
        return fl

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
        except Exception as exc:  # a bug in a hook must not take the whole run down
            p0, why = None, f"internal error at start point: {type(exc).__name__}: {exc}"
        if p0 is None:
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
        except Exception as exc:  # noqa: BLE001 - recorded, never raised
            reason = f"internal error: {type(exc).__name__}: {exc}"
        finally:  # the other half starts from p0, in p0's chart
            self.problem = base
        return pts, events, reason

    def _rechart(self, pts: list[Point]) -> None:
        """Move to the problem's new chart where it asks for one (:meth:`Problem.rechart`):
        the last point is replaced by the same orbit analysed in the new unknowns, at the same
        arclength, and the rest of the half-branch is continued with the new problem."""
        a = pts[-1]
        try:
            moved = self.problem.rechart(a.y, a.tangent)
        except (*NUMERICAL_ERRORS, EvaluationError):
            return  # no better chart: go on in this one
        if moved is None:
            return
        previous = self.problem
        self.problem = moved.problem
        try:
            pts[-1] = self.analyse(np.asarray(moved.y, dtype=float),
                                   np.asarray(moved.tangent, dtype=float), a.s,
                                   a.newton_iterations)
        except NUMERICAL_ERRORS:
            self.problem = previous
            return
        self.rechart_notes.append(f"{moved.note} (at {self.problem.parameter} = "
                                  f"{a.y[self.ip]:.10g})")

    def _walk(self, pts: list[Point], events: list[Event]) -> str:
        """Steps from ``pts[-1]``, appending accepted points and located events in place;
        returns the termination reason. One step: its length (:meth:`_step_length`), predictor
        and corrector (:meth:`_predict_correct`), the turning-angle and multiplier-motion
        checks (:meth:`_multiplier_motion`), the analysis of the new point and the
        events of the step (:meth:`_analyse_step`), then the step adaptation
        (:func:`_adapted_step`)."""
        st = self.settings
        h = st.step_initial
        par = pts[0].y[self.ip]
        if (st.param_min is not None and par < st.param_min) or (
                st.param_max is not None and par > st.param_max):
            return "start outside parameter bounds"  # a start outside the window ends at once
        motion_halvings = 0
        kink_tried = -1
        why = ""
        self._monitor_min = {}
        while len(pts) < st.max_points:
            self._rechart(pts)
            a = pts[-1]
            res = STEP_RESOLUTION * (1.0 + float(np.linalg.norm(a.y, np.inf)))
            if h < res:
                return (f"step_below_resolution (a step of {h:.3g} does not move a point of "
                        f"size {res / STEP_RESOLUTION - 1:.3g} in floating point"
                        + (f"; last failure: {why})" if why else ")"))
            length = self._step_length(pts, h, res)
            if length is None:  # a lies on the window edge its tangent points out of
                return self._stop_on_edge(a, events)
            h_step, edge = length
            y_new, t_new, it, why = self._predict_correct(a, h_step, edge)
            if y_new is None and kink_tried != len(pts):
                # the step may have failed on a kink of the branch ahead (e.g. a grazing
                # approached from the side where the residual's Jacobian blows up)
                kink_tried = len(pts)
                ahead = self._kink_ahead(pts, h_step)
                crossed = None if ahead is None else self._cross_kink(a, *ahead, h_step)
                if crossed is not None:
                    pts.extend(crossed[0])
                    events.extend(crossed[1])
                    continue
            if y_new is None:
                h = 0.5 * h_step
                if h < st.step_min:
                    return f"step_below_minimum ({why})"
                continue
            angle = float(np.arccos(float(np.clip(t_new @ a.tangent, -1.0, 1.0))))
            if angle > st.max_angle and h_step > 2 * st.step_min:
                h = 0.5 * h_step
                continue
            pre, ratio = self._multiplier_motion(a, y_new, t_new, h_step, motion_halvings)
            if ratio > 1.0:
                h = 0.5 * h_step
                motion_halvings += 1
                if motion_halvings == st.max_multiplier_halvings:
                    self.motion_limited_steps += 1
                continue
            s_new = a.s + (h_step if edge is None else float(a.tangent @ (y_new - a.y)))
            if not s_new > a.s:  # the corrector at the edge went backwards: not this branch
                h, why = 0.5 * h_step, "corrector at the window edge went backwards"
                continue
            try:
                b, new_events, stop = self._analyse_step(a, pts, y_new, t_new, s_new, it, pre,
                                                         h_step)
            except _RetryStep as exc:
                h, why = 0.5 * h_step, str(exc)
                continue
            except NUMERICAL_ERRORS as exc:
                h, why = 0.5 * h_step, describe_error(exc)
                if h < st.step_min:
                    return f"step_below_minimum ({why})"
                continue
            crossed = self._kink_in_step(a, new_events, stop, h_step)
            if crossed is not None:
                new_pts, kink_events = crossed
                s_zero = kink_events[0].point.s
                # the step's end lies beyond the kink, where the Jacobian jumps: a sign change
                # of det[G_y; t^T] or of the tangent's parameter component located at the kink
                # itself is that jump, no branch point or fold
                at_kink = 1e-6 * h_step
                events.extend(ev for ev in new_events if ev.point.s < s_zero - 1e-12
                              and ev.kind != self.problem.signature_kind
                              and "function" not in ev.data
                              and not (ev.kind in ("branch_point", "fold")
                                       and s_zero - ev.point.s <= at_kink))
                events.extend(kink_events)
                pts.extend(new_pts)
                continue
            if stop is not None:
                stop_point, stop_reason = stop
                events.extend(ev for ev in new_events if ev.point.s <= stop_point.s)
                pts.append(stop_point)
                return stop_reason
            events.extend(new_events)
            pts.append(b)
            motion_halvings = 0
            if self.progress is not None:
                self.progress(1)
            asym = self._asymptote(pts)
            if asym is not None:
                events.append(asym)
                return f"asymptote ({asym.detail})"
            h = _adapted_step(h, it, angle, st)
            if ratio > 0.0:
                h = min(h, _motion_capped_step(h_step, ratio))
        return "max_points"

    # ------------------------------------------------------------------ kinks
    def _kink_in_step(self, a: Point, new_events: list[Event], stop: tuple[Point, str] | None,
                      h_step: float) -> tuple[list[Point], list[Event]] | None:
        """A zero of an event function located in the step ``a -> b`` at which the problem
        says the branch has a kink (:meth:`Problem.continue_beyond`): the branch goes on from
        the problem's point beyond it instead of from ``b`` (which the arclength corrector may
        have reached across the kink on another branch, or on the right one inaccurately)."""
        zeros = [ev for ev in new_events if "function" in ev.data and "value_before" in ev.data]
        if not zeros:
            return None
        ev = min(zeros, key=lambda e: e.point.s)
        if stop is not None and stop[0].s <= ev.point.s:
            return None
        return self._cross_kink(a, ev.data["function"], float(ev.data["value_before"]), h_step,
                                start=ev.point)

    def _kink_ahead(self, pts: list[Point], h_step: float) -> tuple[str, float] | None:
        """An event function approaching zero at the last point ``a`` so that the step that
        just failed may have met its zero: ``|f(a)| <= 2 h |f'(a)|`` (``f'`` from the last two
        points; on the side where the function is quadratic in the arclength, as a grazing
        margin ``-v^2/(2a)`` is, the linear extrapolation reaches zero at half the distance)."""
        if len(pts) < 2:
            return None
        a, prev = pts[-1], pts[-2]
        ds = a.s - prev.s
        for name, fa in a.event_values.items():
            fp = prev.event_values.get(name, np.nan)
            if not (np.isfinite(fa) and np.isfinite(fp)) or ds <= 0 or fa == 0.0:
                continue
            slope = (fa - fp) / ds
            if np.sign(fa) == np.sign(fp) and abs(fa) < abs(fp) \
                    and abs(fa) <= 2.0 * h_step * abs(slope):
                return name, float(fa)
        return None

    def _cross_kink(self, a: Point, name: str, value: float, h_step: float,
                    start: Point | None = None) -> tuple[list[Point], list[Event]] | None:
        """The points the problem returns across a kink at a zero of event function ``name``
        (:meth:`Problem.continue_beyond`, from ``start`` or ``a``): the approach, the zero and
        the first point beyond, analysed in order, with the event at the zero (and a
        ``stability_change`` there when the number of multipliers outside the circle differs
        on the two sides: they jump at a kink, there is no crossing to locate). The zero itself
        gets no multipliers: the map is not differentiable there. None when the problem does
        not resolve the kink."""
        src = start if start is not None else a
        try:
            out = self.problem.continue_beyond(name, src.y, src.tangent, value, h_step,
                                               self.settings.newton_tol)
            if out is None:
                return None
            path: list[Point] = []
            prev = a
            for z in out.approach:
                z = np.asarray(z, dtype=float)
                if np.linalg.norm(z - prev.y) <= 1e-12 * (1.0 + np.linalg.norm(z)):
                    continue
                t = self.tangent(z, prev.tangent)
                prev = self.analyse(z, t, prev.s + float(np.linalg.norm(z - prev.y)))
                path.append(prev)
            yg, y1 = (np.asarray(z, dtype=float) for z in (out.zero, out.beyond))
            pg = self.analyse(yg, prev.tangent, prev.s + float(np.linalg.norm(yg - prev.y)),
                              floquet=False)
            d = y1 - yg
            if not self._kink_is_real(name, value, pg, prev, d):
                return None
            p1 = self.analyse(y1, self.tangent(y1, d / np.linalg.norm(d)),
                              pg.s + float(np.linalg.norm(d)))
        except (*NUMERICAL_ERRORS, EvaluationError):
            return None
        ip = self.ip
        if np.sign(prev.tangent[ip]) != np.sign(p1.tangent[ip]):
            # the parameter turns at the kink (a nonsmooth fold): like a fold, the point has
            # no direction in the parameter (its tangent is the bisector, flat in p)
            t0 = prev.tangent + p1.tangent
            t0[ip] = 0.0
            if np.linalg.norm(t0) > 0:
                pg = replace(pg, tangent=t0 / np.linalg.norm(t0))
        data: dict[str, Any] = {
            "function": name, "value_before": value,
            "value_after": float(p1.event_values.get(name, np.nan)), "kink": True,
            "signature_before": a.signature, "signature_after": p1.signature}
        kind = self.problem.monitor_kind("function", name)
        found = [Event(kind, pg, f"event function '{name}' vanishes; the branch has a kink "
                       "here and goes on beyond it (the problem's local parametrisation)",
                       data=data, bracket=0.0)]
        if prev.multipliers is not None and p1.multipliers is not None \
                and prev.n_unstable != p1.n_unstable:
            found += _crossing_events("stability_change", pg, 0.0, prev.n_unstable,
                                      p1.n_unstable, np.array([]), None, "kink")
        if self.progress is not None:
            self.progress(len(path) + 2)
        return [*path, pg, p1], found

    def _kink_is_real(self, name: str, value: float, zero: Point, prev: Point,
                      beyond: np.ndarray) -> bool:
        """The problem's kink point is a zero of the event function (to ``1e-6`` of the value
        it started from, or where the function is not defined: a grazing orbit whose margin
        is exactly where the event sequence changes) and the point beyond it leaves the zero
        away from the side the branch came from (its step does not turn back onto the
        approach, which would retrace the branch)."""
        fz = zero.event_values.get(name, np.nan)
        if np.isfinite(fz) and abs(fz) > 1e-6 * max(abs(value), 1e-300):
            return False
        back = zero.y - prev.y
        nb, nd = float(np.linalg.norm(back)), float(np.linalg.norm(beyond))
        if nb == 0.0 or nd == 0.0:
            return True
        return bool(beyond @ back / (nb * nd) > -0.99)

    def _step_length(self, pts: list[Point], h: float, res: float
                     ) -> tuple[float, float | None] | None:
        """``(h_step, edge)``: the step from ``pts[-1]`` shortened so that it never carries
        the parameter past an edge of the window (it then ends on the edge, whose parameter
        value is ``edge``) nor a test or event function far past a zero (:meth:`_test_cap`);
        None when the point already lies on the edge its tangent points out of."""
        st = self.settings
        a = pts[-1]
        h_step, edge = h, None
        cap = self._window_cap(a)
        if cap is not None:
            dist, value = cap
            if abs(value - a.y[self.ip]) <= STEP_RESOLUTION * (1.0 + abs(value)):
                return None
            if dist <= h_step:
                h_step, edge = dist, value
        tcap = max(self._test_cap(pts), st.step_min, 4 * res)
        if tcap < h_step:
            h_step, edge = tcap, None
        return h_step, edge

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

    def _multiplier_motion(self, a: Point, y_new: np.ndarray, t_new: np.ndarray,
                           h_step: float, halvings: int) -> tuple[FloquetData | None, float]:
        """``(multipliers at the trial point, motion ratio)``: the step is refused when the
        ratio exceeds 1. Multipliers near the unit circle must not move too far in one step
        (:func:`multiplier_motion`, :func:`krein_motion_ratio`): a collision and a narrow
        instability window (out and back in) could hide inside it; in a conservative family
        a step must not close the nearest collision too fast either (:func:`krein_closing`);
        the larger ratio counts. The ratio is 0 when the check does not apply. Checked
        before the (costlier) admissibility tests of the new point, whose analysis reuses
        the multipliers."""
        st = self.settings
        if a.multipliers is None or not h_step > 4 * st.step_min \
                or halvings >= st.max_multiplier_halvings:
            return None, 0.0
        pre = self._floquet(y_new, t_new)
        if pre is None:
            return None, 0.0
        b_mult = np.asarray(pre.multipliers)
        # Krein-aware check (conservative families): only multipliers that may collide with a
        # partner of the other signature within the step are bounded
        krein_a = self._krein_at(a)
        krein_b = krein_of(pre) if krein_a is not None else None
        self._remember_floquet(y_new, pre)
        if krein_a is not None and krein_b is not None:
            tol = max(st.unit_circle_tol, a.circle_tol,
                      1e3 * np.finfo(float).eps * pre.matrix_norm)
            dist = (collision_distances(a.multipliers, krein_a, tol),
                    collision_distances(b_mult, krein_b, tol))
            closing = krein_closing(a.multipliers, krein_a, b_mult, krein_b, tol,
                                    st.max_multiplier_step, dist)
            return pre, max(closing, krein_motion_ratio(
                a.multipliers, krein_a, b_mult, krein_b, tol, st.krein_fraction,
                st.max_multiplier_step, distances=dist))
        return pre, multiplier_motion(a.multipliers, b_mult) / st.max_multiplier_step

    def _remember_floquet(self, y: np.ndarray, fl: FloquetData | None) -> None:
        """Keep the multipliers (and their Krein data) of the last few trial points: the
        step checks and :meth:`_krein_windows` read those of both ends of a step."""
        if fl is None:
            return
        memo = self._floquet_memo
        if len(memo) >= 4:
            memo.pop(next(iter(memo)))
        memo[np.asarray(y, dtype=float).tobytes()] = fl

    def _krein_at(self, a: Point) -> np.ndarray | None:
        """Krein definiteness of the multipliers of ``a`` (:class:`~nsm_continuation.core.floquet.
        KreinFloquetData`), or None (generic motion check). Only for a problem that declares
        itself conservative (:attr:`Problem.conservative`: its map is symplectic) and when
        ``settings.krein_step_control``. Remembered from the trial point that became ``a``;
        otherwise (a start, a located or kink point) the multipliers are computed again."""
        st = self.settings
        if not (st.krein_step_control and self.problem.conservative):
            return None
        key = np.asarray(a.y, dtype=float).tobytes()
        # the step from ``a`` may be halved more times than the memo holds trial points: the
        # Krein data of the last ``a`` are kept aside (the same values, not computed again)
        base = getattr(self, "_krein_base", None)
        if base is not None and base[0] == key and base[1].shape == np.shape(a.multipliers):
            return base[1]
        fl = self._floquet_memo.get(key)
        if fl is None:
            fl = self._floquet(a.y, a.tangent)
            self._remember_floquet(a.y, fl)
        krein = krein_of(fl)
        if krein is None or np.asarray(fl.multipliers).shape != np.asarray(a.multipliers).shape:
            return None
        self._krein_base = (key, krein)
        return krein

    def _analyse_step(self, a: Point, pts: list[Point], y_new: np.ndarray, t_new: np.ndarray,
                      s_new: float, it: int, pre: FloquetData | None, h_step: float
                      ) -> tuple[Point, list[Event], tuple[Point, str] | None]:
        """The new point analysed and the events of the step ``a -> b``: ``(b, events,
        stop)``. An event that cannot be located on the arc of a long step raises
        :class:`_RetryStep` (the step is retried shorter)."""
        self._retry_allowed = h_step > 4 * self.settings.step_min
        try:
            b = self.analyse(y_new, t_new, s_new, it, known=pre)
            new_events, stop = self._events_between(a, b, pts)
        finally:
            self._retry_allowed = False
        return b, new_events, stop

    def _window_cap(self, a: Point) -> tuple[float, float] | None:
        """``(arclength along a's tangent to the window edge ahead, that edge's parameter)``,
        or None when no edge lies ahead."""
        st = self.settings
        tp = float(a.tangent[self.ip])
        if tp > 0 and st.param_max is not None:
            value = st.param_max
        elif tp < 0 and st.param_min is not None:
            value = st.param_min
        else:
            return None
        return max((value - float(a.y[self.ip])) / tp, 0.0), value

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

    def _stop_on_edge(self, a: Point, events: list[Event]) -> str:
        """``a`` lies on the window edge its tangent points out of: it is the end point."""
        hi = self.settings.param_max is not None and a.tangent[self.ip] > 0
        label = f"{self.problem.parameter} = {'max' if hi else 'min'}"
        events.append(Event(self._bound_kind(label), a, f"bound reached: {label}",
                            data={"bound": label}))
        return f"bound: {label}"

    def _bound_kind(self, label: str) -> str:
        """Event kind of a bound (``endpoint`` unless the problem maps the quantity)."""
        kind = "endpoint"
        for name_, kind_ in self.problem.bound_kinds.items():
            if label.startswith(f"{name_} ="):
                kind = kind_
        return kind

    def _test_cap(self, pts: list[Point]) -> float:
        """Longest step that moves no admissibility test function and no event function
        towards zero by more than ``TEST_STEP_FACTOR`` times its value, predicted from the
        secant of the last step. A huge step could otherwise jump over a zero pair (out of
        admissibility and back; an event function's two zeros) or land on another solution
        beyond a grazing point, with no sign change to see."""
        if len(pts) < 2:
            return np.inf
        a, prev = pts[-1], pts[-2]
        ds = a.s - prev.s
        cap = np.inf
        if not ds > 0:
            return cap
        for now, before in ((a.tests, prev.tests), (a.event_values, prev.event_values)):
            for name, fa in now.items():
                fp = before.get(name)
                if fp is None or fa == 0 or not (np.isfinite(fa) and np.isfinite(fp)):
                    continue
                slope = (fa - fp) / ds
                if slope * fa < 0:
                    cap = min(cap, TEST_STEP_FACTOR * abs(fa / slope))
        return cap

    def _asymptote(self, pts: list[Point]) -> Event | None:
        """An ``asymptote`` event at the last point when a monitored quantity grows like
        ``|p - p*|^(-k)``: the branch runs to infinite amplitude as the parameter approaches
        ``p*`` (e.g. a zero of ``w_N`` of the impacting chain) and would spend every remaining
        point there. ``p*`` is extrapolated by :func:`~nsm_continuation.core.roots.pole_estimate`.

        Monitored: ``|y|`` (the unknowns without the parameter) and the derived quantities
        named by the problem's ``asymptote_monitors`` (default ``("energy",)``). The estimate
        must hold on the last ``ASYMPTOTE_POINTS`` points and on those ending three points
        earlier (same ``p*`` within a tenth of the remaining distance), and the quantity must
        have grown ``ASYMPTOTE_GROWTH`` times along the half-branch. A safety net: a user bound
        on a derived quantity (``max_energy``) ends such a branch itself, and the detection is
        then off, so a bounded run ends exactly where it is asked to.
        """
        n, lag = ASYMPTOTE_POINTS, 3
        if len(pts) < n + lag or any(hi is not None
                                     for _, hi in self.settings.derived_bounds.values()):
            return None
        keep = np.arange(len(pts[-1].y)) != self.ip
        monitors: dict[str, Callable[[Point], float]] = {
            "|y|": lambda p: float(np.linalg.norm(p.y[keep]))}
        for name in self.problem.asymptote_monitors:
            if name in pts[-1].derived:
                monitors[name] = lambda p, n_=name: float(p.derived.get(n_, np.nan))
        par = np.array([p.y[self.ip] for p in pts[-(n + lag):]])
        for label, fun in monitors.items():
            q_last = fun(pts[-1])
            # cheap test first: a large growth along the half-branch (running minimum, reset
            # by _walk for each half-branch)
            if label not in self._monitor_min:
                self._monitor_min[label] = min(fun(p) for p in pts)
            q_min = self._monitor_min[label] = min(self._monitor_min[label], q_last)
            if not q_last >= ASYMPTOTE_GROWTH * max(q_min, np.finfo(float).tiny):
                continue
            q = np.array([fun(p) for p in pts[-(n + lag):]])
            est = pole_estimate(par[lag:], q[lag:])
            before = pole_estimate(par[:n], q[:n])
            if est is None or before is None:
                continue
            p_star, k = est["parameter_asymptote"], est["exponent"]
            if abs(p_star - before["parameter_asymptote"]) > 0.1 * abs(p_star - par[-1]):
                continue
            name = self.problem.parameter
            return Event("asymptote", pts[-1],
                         f"{label} grows like |{name} - {name}*|^(-{k:.3g}) without bound: "
                         f"{name}* = {p_star:.10g}",
                         data={**est, "monitor": label})
        return None

    # ------------------------------------------------------------------ events
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

    def _point_at(self, a: Point, b: Point, sigma: float, tests: bool = True,
                  floquet: bool = True) -> Point | None:
        """Corrected branch point at arclength ``sigma`` from ``a`` (between ``a`` and ``b``)."""
        h = b.s - a.s
        lam = sigma / h if h != 0 else 0.0
        guess = (1 - lam) * a.y + lam * b.y
        # the arc between two accepted points stays within ~h sin(max_angle) of the chord
        return self._corrected_point(a, guess, a.tangent, a.y, sigma,
                                     max_dist=0.5 * abs(h) + 1e-12, tests=tests,
                                     floquet=floquet)

    def _point_at_parameter(self, a: Point, b: Point, lam: float, value: float) -> Point | None:
        """Corrected point with the parameter fixed at ``value`` (a bound), by Newton at fixed
        parameter from the chord (a parameter bound needs no root finding on the curve)."""
        e = np.zeros(len(a.y))
        e[self.ip] = 1.0
        guess = (1 - lam) * a.y + lam * b.y
        ref = guess.copy()
        ref[self.ip] = value
        return self._corrected_point(a, guess, e, ref, 0.0,
                                     max_dist=0.5 * abs(b.s - a.s) + 1e-12)

    def _locate_continuous(self, a: Point, b: Point, fun: Callable[[Point], float],
                           lo: float = 0.0, flo: float | None = None,
                           hi: float | None = None, fhi: float | None = None,
                           floquet: bool = False, tests: bool = True) -> tuple[Point, float]:
        """A zero of ``fun`` on the arc from ``a`` to ``b`` (Illinois with Dekker's closing
        step, to ``event_tol`` in arclength, between arclengths ``lo`` and ``hi`` from ``a``:
        5-10 trial points where the plain iteration's halvings took 20-30), as ``(point,
        bracket width)``; the point is analysed in full. The trial points are analysed with
        the multipliers only if ``floquet`` and with the admissibility tests and event
        functions only if ``tests``: a function of the parameter, of a derived quantity, of
        the tangent or of the bordered determinant reads neither (each trial point's tests
        cost the chain's certified critical points of ``u_N``)."""
        h = b.s - a.s
        hi = h if hi is None else hi
        flo = fun(a) if flo is None else flo
        fhi = fun(b) if fhi is None else fhi

        seen = [abs(flo), abs(fhi)]

        def f(sig: float) -> tuple[float, Point | None]:
            p = self._point_at(a, b, sig, tests=tests, floquet=floquet)
            value = float("nan") if p is None else fun(p)
            if np.isfinite(value):
                seen.append(abs(value))
            return value, p

        sig, p, width = illinois(f, lo, flo, hi, fhi, self.settings.event_tol, close=True)
        #: whether the sign change just located was through a pole, not a zero: the last
        #: values met, next to the sign change, exceed both ends in modulus (they shrink like
        #: the bracket at a zero, they grow like its inverse at a pole)
        self.last_was_pole = len(seen) > 2 and min(seen[-2:]) > max(seen[:2])
        if p is None:
            p = b if abs(sig - h) < abs(sig) else a
        return self.full(p), width

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

    def _events_between(self, a: Point, b: Point, history: list[Point]
                        ) -> tuple[list[Event], tuple[Point, str] | None]:
        """Every event of the step ``a -> b`` (``history[-2]`` is the point before ``a``) and
        the earliest stop, if any: bounds (:meth:`_bound_events`), admissibility tests
        (:meth:`_admissibility_events`), event functions (:meth:`_event_function_events`),
        bifurcations (:meth:`_bifurcation_events`) and the signature
        (:meth:`_signature_events`)."""
        found, stops = self._bound_events(a, b)
        tests, test_stops = self._admissibility_events(a, b, history)
        found += tests
        stops += test_stops
        found += self._event_function_events(a, b, history)
        if self.settings.detect_bifurcations:
            found += self._bifurcation_events(a, b, tests)
        found += self._signature_events(a, b)
        found = _merge_coincident_grazing(found, self.settings.event_tol)
        if stops:
            stop = min(stops, key=lambda sp: sp[0].s)
            return found, stop
        return found, None

    def _bound_events(self, a: Point, b: Point
                      ) -> tuple[list[Event], list[tuple[Point, str]]]:
        """Parameter bounds and bounds on derived quantities crossed by the step: an
        ``endpoint`` (or the quantity's ``bound_kinds`` kind) and a stop at each."""
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
                    p = self._point_at_parameter(a, b, fa / (fa - fb), value)
                if p is None:
                    p, w = self._locate_continuous(a, b, fun, flo=fa, fhi=fb, tests=False)
                if on_parameter and abs(p.y[ip] - value) > 1e-9 * (1.0 + abs(value)):
                    # not located on the bound: never record a point outside the window
                    if self._retry_allowed:
                        raise _RetryStep(f"bound {label} not located on the step's arc")
                    p, w = a, abs(b.s - a.s)
                ev = Event(self._bound_kind(label), p, f"bound reached: {label}", bracket=w,
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
        pm = self._point_at(a, b, sv - a.s)
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
                p, w = self._locate_continuous(a, b, fun, lo, flo, hi, fhi)
                if not self._on_arc(a, b, p):
                    if self._retry_allowed:
                        raise _RetryStep(f"test function '{name}' changes sign but its zero "
                                         "is not on the step's arc")
                    self.unlocated_events += 1
                    continue
                leaving = flo >= 0 > fhi
                kind = self.problem.monitor_kind("test", name)
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

    def _event_function_events(self, a: Point, b: Point, history: list[Point]) -> list[Event]:
        """Zeros of the problem's event functions (:meth:`Problem.event_functions`) on the
        step, each located on the curve to ``event_tol`` (Illinois) and recorded with the kind
        ``event_function_kinds[name]`` (default ``grazing``); they never stop the branch. A
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
                p, w = self._locate_continuous(a, b, fun, lo, flo, hi, fhi)
                if not self._on_arc(a, b, p):
                    if self._retry_allowed:
                        raise _RetryStep(f"event function '{name}' changes sign but its zero "
                                         "is not on the step's arc")
                    self.unlocated_events += 1
                    continue
                if not abs(fun(p)) < min(abs(flo), abs(fhi)):
                    # the sign changed through a pole or a jump (e.g. a margin -v^2/(2a) as
                    # the acceleration at an impact passes zero), not a zero: no event
                    self.sign_changes_without_zero += 1
                    continue
                found.append(Event(self.problem.monitor_kind("function", name), p,
                                   f"event function '{name}' vanishes ({flo:+.3g} -> "
                                   f"{fhi:+.3g})",
                                   data={"function": name, "value_before": float(flo),
                                         "value_after": float(fhi)}, bracket=w))
        return found

    def _bifurcation_events(self, a: Point, b: Point,
                            kinks: list[Event] | None = None) -> list[Event]:
        """Folds (the parameter component of the tangent changes sign), simple branch points
        (``det[G_y; t^T]`` changes sign, tangents oriented continuously) and multipliers
        crossing the unit circle. ``kinks``: the step's admissibility events, beyond which
        an end may have no multipliers (:meth:`_multiplier_ends`)."""
        ip = self.ip
        found: list[Event] = []
        if np.sign(a.tangent[ip]) != np.sign(b.tangent[ip]) \
                and max(abs(a.tangent[ip]), abs(b.tangent[ip])) > TANGENT_NOISE:
            p, w = self._locate_continuous(a, b, lambda q: q.tangent[ip], tests=False)
            found.append(Event("fold", p, "limit point: the parameter reaches an extremum "
                               "along the branch", data={"test": "tangent"}, bracket=w))
        elif np.sign(a.bordered_det) != np.sign(b.bordered_det) and a.bordered_det != 0:
            p, w = self._locate_continuous(a, b, lambda q: q.bordered_det, tests=False)
            if self.last_was_pole:
                # through a pole, not a zero: the Jacobian blows up (e.g. like 1/|v| as an
                # impact's velocity vanishes at a grazing), no second branch crosses here
                self.sign_changes_without_zero += 1
            elif self._on_arc(a, b, p):
                found.append(Event("branch_point", p, "simple branch point: det[G_y; t^T] "
                                   "changes sign", data={"test": "bordered_determinant"},
                                   bracket=w))
            else:
                self.unlocated_events += 1
        ma, mb = self._multiplier_ends(a, b, kinks or [])
        if ma.multipliers is not None and mb.multipliers is not None:
            if ma.n_unstable != mb.n_unstable:
                found.extend(self._locate_multiplier_crossings(ma, mb))
            else:
                found.extend(self._krein_windows(ma, mb))
        return _merge_fold_crossings(found)

    def _multiplier_ends(self, a: Point, b: Point, kinks: list[Event]) -> tuple[Point, Point]:
        """The ends of the part of the step ``a -> b`` whose multipliers are compared: the
        step itself, unless one end has none (an orbit past a grazing, whose return map the
        problem does not linearise) and an admissibility event lies in the step. Then the
        missing end is replaced by the point on the step's arc at the near side of the
        event's bracket (the earliest event when ``b`` has none, the latest when ``a`` has
        none): a multiplier that crossed the circle between ``a`` and the grazing is located
        there, instead of being lost with the end that cannot show it."""
        if (a.multipliers is None) == (b.multipliers is None) or not kinks:
            return a, b
        h = b.s - a.s
        if b.multipliers is None:
            ev = min(kinks, key=lambda e: e.point.s)
            sig = min(max(ev.point.s - a.s - ev.bracket, 0.0), h)
        else:
            ev = max(kinks, key=lambda e: e.point.s)
            sig = min(max(ev.point.s - a.s + ev.bracket, 0.0), h)
        if sig in (0.0, h):
            return a, b
        q = self._point_at(a, b, sig, tests=False)
        if q is None or q.multipliers is None:
            return a, b
        return (a, q) if b.multipliers is None else (q, b)

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
            p = self._point_at(a, b, sig, tests=True, floquet=False)
            return (None, None) if p is None else (name in p.tests, p)

        sig, p, width, vl, vr = bisect_predicate(f, lo, was, hi, not was,
                                                 self.settings.signature_event_tol)
        if p is None:  # the bracket never moved off ``hi``: the event is there
            p = b if hi >= b.s - a.s else (self._point_at(a, b, hi) or b)
        else:
            p = self.full(p)
        kind = self.problem.monitor_kind("test", name)
        return Event(kind, p, f"test function '{name}' "
                     + ("ceases to be defined" if was else "becomes defined"),
                     data={"test": name, "defined_before": bool(vl),
                           "defined_after": bool(vr)}, bracket=width)

    def _locate_signature_change(self, a: Point, b: Point) -> list[Event]:
        """Bisection on the signature between two points; one event at the first change.

        A problem may declare a change not worth locating (``locate_signature(before, after)``
        False: e.g. only the number of impacts a simulator resolves before a chatter map, a
        tolerance-dependent count): the event is then recorded at ``b`` with the step as bracket.
        The event's kind is the problem's ``signature_kind``.
        """
        kind = self.problem.signature_kind
        assert kind is not None  # signatures are only evaluated when a kind is declared
        if not self.problem.locate_signature(a.signature, b.signature):
            return [Event(kind, b, f"event sequence {a.signature} -> {b.signature} (not "
                          "located: within the step)",
                          data={"signature_before": a.signature,
                                "signature_after": b.signature}, bracket=b.s - a.s)]

        def f(sig: float) -> tuple[str | None, Point | None]:
            p = self._point_at(a, b, sig, tests=False, floquet=False)
            return (None, None) if p is None else (p.signature, p)

        sig, p, width, vl, vr = bisect_predicate(f, 0.0, a.signature, b.s - a.s, b.signature,
                                                 self.settings.signature_event_tol)
        p = b if p is None else self.full(p)
        return [Event(kind, p, f"event sequence {vl} -> {vr}",
                      data={"signature_before": vl, "signature_after": vr}, bracket=width)]

    def _locate_multiplier_crossings(self, a: Point, b: Point) -> list[Event]:
        """Locate where multipliers cross the unit circle between ``a`` and ``b``.

        Detector: the number of multipliers outside ``|lambda| = 1 + tol`` (``tol`` the
        point's ``circle_tol``), bisected to ``multiplier_event_tol`` in arclength. It finds
        each change of the count, classifies it (``classify_crossing`` of
        :mod:`~nsm_continuation.core.floquet`) and names the crossing multiplier ``lambda_c`` (the
        newly outside one closest to the circle).

        Location: on the true condition ``phi(sigma) = |lambda_c(sigma)| - 1 = 0``
        (:meth:`_locate_on_modulus`): ``phi = -lambda_c - 1`` for a real multiplier through
        -1, ``lambda_c - 1`` through +1, the modulus of the pair for a complex pair. The count
        alone locates ``phi = tol``, off the crossing by ``tol / |phi'|``. Where ``phi`` has
        no usable sign change (a conservative collision: ``phi = 0`` on the whole stable side;
        with ``phi ~ c sqrt(sigma - sigma*)`` the count's threshold lies ``(tol / c)^2`` from
        the collision, and the location is accurate to ``multiplier_event_tol``) the count's
        location is kept. A Krein collision of a conservative family whose problem computes
        pairs of multipliers is located first on the pair's discriminant
        (:meth:`_locate_collision`). ``data['located_on']`` says which
        (``'krein_discriminant'``, ``'multiplier_modulus'`` or ``'count'``);
        ``data['modulus_minus_one']`` is ``|lambda_c| - 1`` at the event point,
        ``data['critical_multiplier']`` is ``lambda_c`` there.
        """
        collision = self._locate_collision(a, b)
        if collision is not None:
            return collision
        tol = self.settings.unit_circle_tol
        h = b.s - a.s
        #: every point analysed with multipliers on the arc, by arclength from ``a``
        seen: dict[float, Point] = {0.0: a, h: b}

        def f(sig: float) -> tuple[int | None, Point | None]:
            p = self._point_at(a, b, sig, tests=False)
            if p is None:
                return None, None
            if p.multipliers is not None:
                seen[sig] = p
            return p.n_unstable, p

        events: list[Event] = []
        lo, vlo, plo = 0.0, a.n_unstable, a
        for _ in range(4):  # at most a few crossings in one step
            if vlo == b.n_unstable:
                break
            sig, p, width, vl, vr = bisect_predicate(f, lo, vlo, h, b.n_unstable,
                                                     self.settings.multiplier_event_tol)
            right = b if p is None else p  # has multipliers (analysed without tests)
            sig_left = max(sig - width, 0.0)
            left = self._point_at(a, b, sig_left, tests=False) or plo
            if left.multipliers is None:
                left, sig_left = plo, lo
            else:
                seen[sig_left] = left
            kind, leaving = classify_crossing(left.multipliers, right.multipliers,
                                              max(tol, right.circle_tol, left.circle_tol))
            located = None
            if leaving.size:
                # the newly outside multiplier at the outside end of the count's bracket
                lam_out = leaving[np.argmin(np.abs(leaving))]
                out_sig, inward = (sig, -1.0) if vr > vl else (sig_left, 1.0)
                located = self._locate_on_modulus(a, b, seen, out_sig, lam_out, inward)
            if located is not None:
                p, width, lam_c = located
                located_on = "multiplier_modulus"
            else:
                p = self.full(right)
                if p.multipliers is None:  # the crossing point itself is a phantom: keep them
                    p.multipliers, p.n_unstable = right.multipliers, right.n_unstable
                lam_c = (None if not leaving.size else
                         _nearest(right.multipliers, leaving[np.argmin(np.abs(leaving))]))
                located_on = "count"
            events += _crossing_events(kind, p, width, int(vl), int(vr), leaving, lam_c,
                                       located_on)
            lo, vlo, plo = right.s - a.s, vr, right
        return events

    def _locate_collision(self, a: Point, b: Point) -> list[Event] | None:
        """A Krein collision of a conservative family located on a smooth test function of
        the colliding pair alone, or None (then the count is bisected).

        In a symplectic map a window of instability opens where two multipliers of opposite
        Krein signature collide on the unit circle (at +-1 or at a complex ``rho``) and leave
        it as ``r rho, rho / r``. With ``nu_j = -i log(lambda_j / rho)`` the pair's
        *discriminant* ``d = (nu_1 - nu_2)^2`` is real and analytic through the collision:
        ``(theta_1 - theta_2)^2 > 0`` on the circle, ``-4 (log r)^2 < 0`` off it, a simple zero
        at the collision (where each multiplier alone has a square-root singularity, so
        ``|lambda| - 1`` has no usable sign change: the count's threshold lies
        ``(tol / c)^2`` from the collision). The Illinois iteration locates ``d = 0`` to
        ``event_tol`` in arclength; at each trial point only the pair is computed
        (:meth:`~nsm_continuation.core.problem.Problem.multipliers_near`, started from the pair
        at the nearest arclength computed so far): O(N) per multiplier where the whole spectrum
        is O(N^2). Used when the problem computes pairs (else None) and the count changes by
        the pair alone (one multiplier for a collision at +-1, two for a complex quadruple);
        the located point is analysed in full and must have the count of one of the step's
        ends, a point past it on the other side that of the other end (``multiplier_event_tol``
        past it, or as far as the pair needs to move ``unit_circle_tol`` off the circle);
        otherwise the count is bisected as before (``data['located_on'] =
        'krein_discriminant'`` when kept)."""
        pr, st = self.problem, self.settings
        if (not pr.conservative or a.multipliers is None or b.multipliers is None
                or abs(int(a.n_unstable) - int(b.n_unstable)) not in (1, 2)):
            return None
        tol = max(st.unit_circle_tol, a.circle_tol, b.circle_tol)
        opening = b.n_unstable > a.n_unstable
        p_in, p_out = (a, b) if opening else (b, a)
        m_in, m_out = np.asarray(p_in.multipliers), np.asarray(p_out.multipliers)
        # the multiplier that left: outside at one end (upper half plane), its nearest
        # multiplier at the other end inside; exactly one, else the count is bisected
        outside = m_out[(np.abs(m_out) > 1.0 + tol) & (m_out.imag >= -1e-12)]
        if not outside.size or m_in.size < 3:
            return None
        nearest_in = m_in[np.argmin(np.abs(outside[:, None] - m_in[None, :]), axis=1)]
        new = outside[np.abs(nearest_in) <= 1.0 + tol]
        if new.size != 1:
            return None
        lam_out = complex(new[0])
        rho = lam_out / abs(lam_out)
        pair_out = self._pair_near(np.asarray(p_out.multipliers), lam_out, 1.0 / np.conj(lam_out))
        pair_in = self._pair_near(np.asarray(p_in.multipliers), rho, rho)
        if pair_out is None or pair_in is None:
            return None
        h = b.s - a.s
        #: the pair at each arclength computed (the step's ends first)
        ends = {0.0: pair_in if p_in is a else pair_out, h: pair_out if p_in is a else pair_in}

        def disc(pair: np.ndarray) -> float:
            return discriminant(pair[0], pair[1])

        def f(sig: float) -> tuple[float, tuple[np.ndarray, np.ndarray] | None]:
            on_arc = self._on_chord(a, b, sig)
            if on_arc is None:
                return float("nan"), None
            y, t = on_arc
            # start from the pair at the nearest arclength computed so far
            near = min(ends, key=lambda k: abs(k - sig))
            try:
                pair = pr.multipliers_near(y, t, ends[near])
            except NUMERICAL_ERRORS:
                return float("nan"), None
            if pair is None or pair.size != 2 or not np.all(np.isfinite(pair)):
                return float("nan"), None
            ends[sig] = pair
            return disc(pair), (y, pair)

        d0, dh = disc(ends[0.0]), disc(ends[h])
        if not (np.isfinite(d0) and np.isfinite(dh)) or d0 * dh > 0:
            return None
        sig, payload, width = illinois(f, 0.0, d0, h, dh, st.event_tol, close=True)
        if payload is None or width > st.multiplier_event_tol:
            return None
        # the event point, analysed in full, has the count of one end; a point just past it
        # on the other side must have the other end's (no other crossing in the step)
        q = self._point_at(a, b, sig)
        if q is None:
            return None
        if q.multipliers is None:  # a phantom: keep the multipliers computed without tests
            p = self._point_at(a, b, sig, tests=False)
            if p is None or p.multipliers is None:
                return None
            q.multipliers, q.n_unstable, q.circle_tol = p.multipliers, p.n_unstable, p.circle_tol
        vl, vr = int(a.n_unstable), int(b.n_unstable)
        delta = max(width, st.multiplier_event_tol)
        # off the circle |log|lambda|| = sqrt(-d) / 2: the pair counts as outside once
        # -d > 4 tol^2, i.e. about 4 tol^2 / |d'| past the collision (d' from the step's ends)
        past = max(delta, 16.0 * tol**2 * abs(h) / max(abs(dh - d0), 1e-300))
        if q.n_unstable == vl:
            right = b if sig + past >= h else self._point_at(a, b, sig + past, tests=False)
            left = q
        elif q.n_unstable == vr:
            left = a if sig - past <= 0.0 else self._point_at(a, b, sig - past, tests=False)
            right = q
        else:
            return None
        if (left is None or right is None or left.n_unstable != vl
                or right.n_unstable != vr):
            return None
        kind, leaving = classify_crossing(left.multipliers, right.multipliers, tol)
        lam_c = _nearest(q.multipliers, complex(payload[1][np.argmax(np.abs(payload[1]))]))
        return _crossing_events(kind, q, width, vl, vr, leaving, lam_c, "krein_discriminant")

    def _krein_windows(self, a: Point, b: Point) -> list[Event]:
        """An instability window opened and closed inside the step ``a -> b`` (the same
        number of multipliers outside the circle at both ends) of a conservative family:
        its two crossings, located on the colliding pair's discriminant.

        The Krein words of the ends (:mod:`nsm_continuation.core.krein`) differ when two
        multipliers of opposite signature met inside the step; one transposition (or one flip
        at ``+-1``) names the pair and how it moved (:func:`~nsm_continuation.core.krein.
        swap_paths`). Its discriminant ``d(sigma)`` (:func:`~nsm_continuation.core.krein.
        discriminant`; the pair at each trial point is the one nearest to the linear
        interpolation of its ends' positions) is positive at both ends; its minimum over the
        step (Brent's bounded search to ``event_tol``) is negative exactly when the pair left
        the circle in between. Then both zeros are located (Illinois, as in
        :meth:`_locate_collision`) and the point of the minimum, analysed in full, must have
        more multipliers outside than the ends (the count, a second method); the window's
        opening and closing crossings are returned (``data['located_on'] =
        'krein_discriminant'``, ``data['hidden_in_step'] = True``). A minimum that is not
        negative beyond ``-4 tol^2`` (the pair within ``tol`` of the circle) is a passing of
        the two multipliers: no event (``krein_passings``). Several collisions in the step,
        or a window the count does not confirm, retry the step shorter (when it may be
        retried; else the step is kept and ``unlocated_events`` counts it)."""
        pr, st = self.problem, self.settings
        if not (pr.conservative and st.krein_step_control):
            return []
        ka, kb = self._krein_at(a), self._krein_at(b)
        if ka is None or kb is None:
            return []
        tol = max(st.unit_circle_tol, a.circle_tol, b.circle_tol)
        paths = swap_paths(np.asarray(a.multipliers), ka, np.asarray(b.multipliers), kb, tol)
        if paths is None:
            return []
        if paths == SEVERAL:
            return self._unresolved("several Krein collisions in one step")
        assert not isinstance(paths, str)
        (z1a, z1b), (z2a, z2b) = paths
        h = b.s - a.s

        def f(sig: float) -> tuple[float, tuple[np.ndarray, np.ndarray] | None]:
            on_arc = self._on_chord(a, b, sig)
            if on_arc is None:
                return float("nan"), None
            y, t = on_arc
            lam = sig / h if h != 0 else 0.0
            g = np.array([z1a + lam * (z1b - z1a), z2a + lam * (z2b - z2a)])
            try:
                pair = self._multipliers_near(y, t, g)
            except NUMERICAL_ERRORS:
                return float("nan"), None
            if pair is None:
                return float("nan"), None
            return discriminant(pair[0], pair[1]), (y, pair)

        d0, dh = discriminant(z1a, z2a), discriminant(z1b, z2b)
        sig_m, d_m, _ = bounded_minimum(lambda sig: np.nan_to_num(f(sig)[0], nan=np.inf),
                                        0.0, h, xatol=st.event_tol, maxiter=60)
        if not d_m < -4.0 * tol**2:
            self.krein_passings += 1
            return []
        vl = int(a.n_unstable)
        middle = self._point_at(a, b, sig_m, tests=False)
        if middle is None or middle.multipliers is None or middle.n_unstable <= vl:
            return self._unresolved("a hidden Krein window the count does not confirm")
        events: list[Event] = []
        kind, leaving = classify_crossing(np.asarray(a.multipliers), middle.multipliers, tol)
        vm = int(middle.n_unstable)
        for lo, flo, hi, fhi, before, after in ((0.0, d0, sig_m, d_m, vl, vm),
                                                (sig_m, d_m, h, dh, vm, vl)):
            sig, payload, width = illinois(f, lo, flo, hi, fhi, st.event_tol, close=True)
            q = self._point_at(a, b, sig)
            if payload is None or q is None:
                return self._unresolved("a hidden Krein window not located on its "
                                        "discriminant")
            if q.multipliers is None:  # a phantom: the multipliers computed without tests
                p = self._point_at(a, b, sig, tests=False)
                if p is None or p.multipliers is None:
                    return self._unresolved("a hidden Krein window without multipliers")
                q.multipliers, q.n_unstable, q.circle_tol = (p.multipliers, p.n_unstable,
                                                             p.circle_tol)
            lam_c = _nearest(q.multipliers, complex(payload[1][0]))
            for ev in _crossing_events(kind, q, width, before, after, leaving, lam_c,
                                       "krein_discriminant"):
                ev.data["hidden_in_step"] = True
                events.append(ev)
        return events

    def _on_chord(self, a: Point, b: Point, sig: float) -> tuple[np.ndarray, np.ndarray] | None:
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

    def _multipliers_near(self, y: np.ndarray, t: np.ndarray, guesses: np.ndarray
                          ) -> np.ndarray | None:
        """The multipliers nearest to ``guesses`` (distinct): the problem's
        :meth:`~nsm_continuation.core.problem.Problem.multipliers_near`, else from all of them."""
        pair = self.problem.multipliers_near(y, t, guesses)
        if pair is None:
            fl = self._floquet(y, t)
            if fl is None:
                return None
            m = np.asarray(fl.multipliers, dtype=complex)
            picked: list[int] = []
            for g in guesses:
                d = np.abs(m - g)
                d[picked] = np.inf
                picked.append(int(np.argmin(d)))
            pair = m[picked]
        pair = np.asarray(pair, dtype=complex)
        return pair if pair.size == guesses.size and np.all(np.isfinite(pair)) else None

    def _unresolved(self, why: str) -> list[Event]:
        """A step whose events cannot be told apart: retried shorter if it may be, else kept
        and counted (``unlocated_events``)."""
        if self._retry_allowed:
            raise _RetryStep(why)
        self.unlocated_events += 1
        return []

    @staticmethod
    def _pair_near(m: np.ndarray, z1: complex, z2: complex) -> np.ndarray | None:
        """The two multipliers nearest to ``z1`` and ``z2`` (distinct), or None if a third one
        is about as near (the pair is then not isolated)."""
        if m.size < 3:
            return None
        i = int(np.argmin(np.abs(m - z1)))
        d2 = np.abs(m - z2)
        d2[i] = np.inf
        j = int(np.argmin(d2))
        pair = m[[i, j]]
        centre = 0.5 * (pair[0] + pair[1])
        radius = max(abs(pair[0] - centre), 1e-300)
        others = np.delete(m, [i, j])
        if np.min(np.abs(others - centre)) <= 2.0 * radius:
            return None
        return pair

    def _locate_on_modulus(self, a: Point, b: Point, seen: dict[float, Point],
                           out_sig: float, lam_out: complex, inward: float
                           ) -> tuple[Point, float, complex] | None:
        """Zero of ``phi(sigma) = |lambda_c(sigma)| - 1`` on the arc from ``a`` to ``b``:
        ``(event point, bracket width, lambda_c there)``, or None where ``phi`` gives no
        trustworthy location (then the count's location stands).

        ``lambda_c`` is ``lam_out`` at ``out_sig`` (outside: ``phi > tol``) and is tracked by
        continuity (nearest neighbour, step by step) through the points already analysed on
        the side ``inward`` (``-1``: smaller arclength) to the nearest one where it lies
        inside the circle beyond the noise of the eigenvalues (``phi < -circle_tol``). On that
        bracket the Illinois iteration (:func:`~nsm_continuation.core.roots.illinois`) locates
        ``phi = 0`` to ``event_tol`` in arclength; at each trial point ``lambda_c`` is the
        multiplier nearest to the linear interpolation of the tracked values on both sides.
        The result is kept only if the iteration converged to within
        ``multiplier_event_tol`` and ``|phi|`` there is below ``circle_tol`` or the change of
        a continuous ``phi`` over the final bracket (not a jump of the tracked multiplier).
        """
        st = self.settings
        track: dict[float, complex] = {out_sig: complex(lam_out)}
        lam = complex(lam_out)
        sig_in = None
        for k in sorted((k for k in seen if (k - out_sig) * inward > 0),
                        key=lambda k: abs(k - out_sig)):
            m = np.asarray(seen[k].multipliers)
            d = np.abs(m - lam)
            order = np.argsort(d)
            if m.size > 1 and d[order[1]] <= 2.0 * d[order[0]]:
                return None  # ambiguous: two multipliers equally close to the tracked one
            lam = complex(m[order[0]])
            track[k] = lam
            if abs(lam) - 1.0 < -seen[k].circle_tol:
                sig_in = k
                break
        if sig_in is None:
            return None  # phi never clearly negative: no sign change to locate

        def phi(sig: float) -> tuple[float, tuple[Point, complex] | None]:
            p = self._point_at(a, b, sig, tests=False)
            if p is None or p.multipliers is None or p.multipliers.size == 0:
                return float("nan"), None
            ks = sorted(track)
            i = int(np.searchsorted(ks, sig))
            k0, k1 = ks[max(i - 1, 0)], ks[min(i, len(ks) - 1)]
            w = 0.0 if k1 == k0 else (sig - k0) / (k1 - k0)
            ref = (1.0 - w) * track[k0] + w * track[k1]
            lam_c = _nearest(p.multipliers, ref)
            track[sig] = lam_c
            return abs(lam_c) - 1.0, (p, lam_c)

        f_in = abs(track[sig_in]) - 1.0
        f_out = abs(track[out_sig]) - 1.0
        sig, payload, width = illinois(phi, sig_in, f_in, out_sig, f_out, st.event_tol)
        if payload is None or width > st.multiplier_event_tol:
            return None
        p, lam_c = payload
        # a tracked multiplier that jumped (another one picked up) leaves |phi| of the size of
        # the jump at the final iterate; a continuous phi is there within its slope times the
        # bracket (the secant slope over the initial bracket, with a wide margin)
        slope = abs(f_out - f_in) / abs(out_sig - sig_in)
        if abs(abs(lam_c) - 1.0) > max(p.circle_tol, 100.0 * slope * max(width, st.event_tol)):
            return None
        q = self.full(p)
        if q.multipliers is None:  # a phantom: keep the multipliers computed without tests
            q.multipliers, q.n_unstable, q.circle_tol = p.multipliers, p.n_unstable, p.circle_tol
        return q, width, lam_c


#: the ``detail`` of a multiplier crossing, by kind
_CROSSING_DETAIL = {
    "fold": "a multiplier pair crosses the unit circle at +1",
    "period_doubling": "a multiplier crosses the unit circle at -1 (flip)",
    "neimark_sacker": "a complex pair crosses the unit circle away from +-1 (in a "
                      "conservative system: a Krein collision)",
    "stability_change": "multipliers cross the unit circle",
}


def _crossing_events(kind: str, p: Point, width: float, n_before: int, n_after: int,
                     leaving: np.ndarray, lam_c: complex | None, located_on: str
                     ) -> list[Event]:
    """The event of a multiplier crossing located at ``p`` (``n_before -> n_after``
    multipliers outside the circle), and a ``stability_change`` there if stability changes."""
    stable_before, stable_after = n_before == 0, n_after == 0
    data = {"n_outside_before": n_before, "n_outside_after": n_after,
            "stable_before": stable_before, "stable_after": stable_after,
            "leaving_multipliers": [[float(z.real), float(z.imag)] for z in leaving],
            "located_on": located_on,
            "critical_multiplier": (None if lam_c is None
                                    else [float(lam_c.real), float(lam_c.imag)]),
            "modulus_minus_one": float("nan") if lam_c is None else float(abs(lam_c) - 1.0)}
    change = "stable -> unstable" if stable_before else "unstable -> stable"
    if kind == "stability_change":  # one event, not the crossing and its companion
        detail = change if stable_before != stable_after else _CROSSING_DETAIL[kind]
        return [Event(kind, p, detail, data=dict(data), bracket=width)]
    events = [Event(kind, p, _CROSSING_DETAIL[kind], data=dict(data), bracket=width)]
    if stable_before != stable_after:
        events.append(Event("stability_change", p, change, data=dict(data), bracket=width))
    return events


def _with_tangent(p: Point, t: np.ndarray) -> Point:
    """A copy of ``p`` with the tangent ``t`` (``+-p.tangent``) and its bordered determinant
    ``det[G_y; t^T]``, which is linear in ``t`` (expansion along the last row): it changes
    sign with the tangent. The branch-point test compares determinants of consecutive points
    whose tangents are oriented continuously (``t_{k+1} . t_k > 0``); a reversed tangent with
    the determinant of the other orientation is a spurious sign change."""
    sign = 1.0 if float(t @ p.tangent) >= 0 else -1.0
    return replace(p, tangent=np.asarray(t, dtype=float), bordered_det=p.bordered_det * sign)


#: :func:`_motion_capped_step`: the motion ratio a step is aimed at, and the lattice of its
#: factors (powers of ``2^(1 / MOTION_LATTICE)``)
MOTION_TARGET = 0.9
MOTION_LATTICE = 4


def _motion_capped_step(h_step: float, ratio: float) -> float:
    """The longest step after an accepted one whose multiplier motion ratio
    (:meth:`ContinuationEngine._multiplier_motion`) was ``ratio``: displacements grow
    linearly with a short step, so ``h_step * MOTION_TARGET / ratio`` is aimed just inside
    the limit; it caps the growth of :func:`_adapted_step`, and spares the attempts that the
    check would refuse. A refused step is still halved: the closing rule approaches a
    collision geometrically (:func:`krein_closing`), and larger cuts, tried, skipped a
    Neimark-Sacker window 1.5e-7 wide on the 200-dof branch
    (``benchmarks/bench_chain_large.py``).

    The factor is rounded down to a power of ``2^(1/4)``: like the fixed factors of
    :func:`_adapted_step`, it then does not follow the rounding errors of the multipliers,
    so two runs whose multipliers differ by rounding (another BLAS, a structured and a dense
    solve) take the same steps, unless a ratio lies on a boundary of the lattice."""
    factor = MOTION_TARGET / ratio
    return h_step * 2.0 ** (np.floor(MOTION_LATTICE * np.log2(factor)) / MOTION_LATTICE)


def _adapted_step(h: float, iterations: int, angle: float, st: ContinuationSettings) -> float:
    """Next step length after an accepted step: few Newton iterations and a small turning
    angle grow it (x 1.6, up to ``step_max``), many iterations or a large angle shrink it
    (x 0.6, down to ``step_min``)."""
    if iterations <= 3 and angle < 0.4 * st.max_angle:
        return min(h * 1.6, st.step_max)
    if iterations >= 6 or angle > 0.8 * st.max_angle:
        return max(h * 0.6, st.step_min)
    return h


def _merge_fold_crossings(events: list[Event]) -> list[Event]:
    """A limit point of the branch (the tangent's parameter component changes sign) is where a
    multiplier passes +1: the crossing located there on the multipliers is the same event,
    reported once (the fold, with the crossing's data: multipliers outside before and after)."""
    folds = [e for e in events if e.kind == "fold" and e.data.get("test") == "tangent"]
    if not folds:
        return events
    out: list[Event] = []
    for ev in events:
        twin = next((f for f in folds if ev is not f and ev.kind == "fold" and abs(
            ev.point.s - f.point.s) <= max(1e-8 * (1.0 + abs(f.point.s)),
                                           2 * ev.bracket, 2 * f.bracket)), None)
        if twin is not None:
            twin.data.update({k: v for k, v in ev.data.items() if k != "test"})
            continue
        out.append(ev)
    return out


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


def _nearest(multipliers: np.ndarray, ref: complex) -> complex:
    """The multiplier nearest to ``ref``."""
    m = np.asarray(multipliers)
    return complex(m[int(np.argmin(np.abs(m - ref)))])


def _krein_displacements(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                         krein_b: np.ndarray, circle_tol: float, lo: float, hi: float,
                         distances: tuple[np.ndarray, np.ndarray] | None
                         ) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(displacement, collision distance)]`` of the multipliers of ``a`` and of ``b`` in
    the annulus ``lo < |lambda| < hi`` (one pair of arrays per end), as
    :func:`krein_motion` defines them."""
    if distances is None:
        distances = (collision_distances(a, krein_a, circle_tol),
                     collision_distances(b, krein_b, circle_tol))
    out = []
    sa, sb = definite_sign(a, krein_a, circle_tol), definite_sign(b, krein_b, circle_tol)
    for sx, sz, x, z, cx in ((sa, sb, a, b, distances[0]), (sb, sa, b, a, distances[1])):
        watch = (np.abs(x) > lo) & (np.abs(x) < hi)
        if not watch.any():
            continue
        xw, sw = x[watch], sx[watch]
        # nearest multiplier of the other point among those of signature +1, -1 and of no
        # definite signature (off the circle or indefinite), each set searched on its own
        # (k-d tree, O(n log n)): a definite multiplier's displacement is the distance to
        # the nearest one that is not definite of the opposite sign, or to the nearest of
        # all when there is no such one; any other multiplier's, to the nearest of all
        d_pos, d_neg, d_none = (nearest_distances(xw, z[sel])
                                for sel in (sz > 0, sz < 0, sz == 0))
        nearest = np.minimum(np.minimum(d_pos, d_neg), d_none)
        disp = np.where(sw > 0, np.minimum(d_pos, d_none),
                        np.where(sw < 0, np.minimum(d_neg, d_none), nearest))
        out.append((np.where(np.isfinite(disp), disp, nearest), cx[watch]))
    return out


def krein_motion(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray, krein_b: np.ndarray,
                 circle_tol: float, fraction: float, lo: float = 0.5, hi: float = 2.0,
                 distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The motion that matters in a conservative family: the largest displacement, between
    two points, of a multiplier in the annulus ``lo < |lambda| < hi`` that is *near a
    collision that can open or close an instability window*, 0 if there is none.

    Krein's theorem (MacKay 1986, "Stability of equilibria of Hamiltonian systems"): a
    multiplier on the unit circle with a definite Krein signature stays on it under small
    symplectic perturbations; the circle can only be left where two multipliers of *opposite*
    signature collide (a conjugate pair at ``+-1``: ``conj`` flips the signature), and
    re-entered where the pair ``lambda, 1/conj(lambda)`` meets again on it. So a window can
    hide inside a step only if some multiplier moves by at least ``fraction`` of its
    *collision distance* (:func:`~nsm_continuation.core.floquet.collision_distances`: to the
    nearest multiplier of the other signature on the circle, or to any multiplier off it;
    0 for a multiplier of indefinite signature). Multipliers of one signature may pass
    through each other at any speed. The displacement of a multiplier on the circle with a
    definite signature is measured to the nearest multiplier *of the same signature* at the
    other point (two of opposite signature that swapped places moved, whatever their
    positions); any other multiplier to the whole other set (as :func:`multiplier_motion`).

    With ``fraction = 0`` this is :func:`multiplier_motion` (every multiplier in the annulus
    counts), the generic check of damped and hybrid problems. ``distances``: the collision
    distances of ``a`` and ``b`` if already computed.
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    motion = 0.0
    for disp, cx in _krein_displacements(a, krein_a, b, krein_b, circle_tol, lo, hi,
                                         distances):
        counts = disp >= fraction * cx
        if counts.any():
            motion = max(motion, float(disp[counts].max()))
    return motion


def krein_motion_ratio(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                       krein_b: np.ndarray, circle_tol: float, fraction: float, step: float,
                       lo: float = 0.5, hi: float = 2.0,
                       distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The Krein-aware motion check as one number: ``max_i d_i / max(step, fraction c_i)``
    over the multipliers in the annulus (displacement ``d_i`` and collision distance ``c_i``
    as in :func:`krein_motion`), 0 if there is none. It exceeds 1 exactly when
    :func:`krein_motion` exceeds ``step`` (up to the tie ``d_i = fraction c_i``): some
    multiplier moved by more than ``step`` *and* by at least ``fraction`` of its collision
    distance. Displacements grow linearly with a short step, so the ratio also predicts the
    step that would bring it to a target (:func:`_motion_capped_step`)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    ratio = 0.0
    for disp, cx in _krein_displacements(a, krein_a, b, krein_b, circle_tol, lo, hi,
                                         distances):
        ratio = max(ratio, float((disp / np.maximum(step, fraction * cx)).max()))
    return ratio


#: :func:`krein_closing`: a step may shrink the smallest collision distance at most by this
#: factor, once it is below ``KREIN_NEAR``
KREIN_CLOSING = 0.5
KREIN_NEAR = 0.1
#: :func:`krein_closing`: a multiplier outside the circle is the same one at both ends of a
#: step if it moved by at most ``match`` or by this fraction of its distance to the circle
OUTSIDE_TRAVEL = 0.5


def _outside_travel(x: np.ndarray, y: np.ndarray, match: float) -> np.ndarray:
    """How far a multiplier outside the unit circle may move between ``x`` and its match
    ``y`` at the other end of a step and still be the same one, never on the circle in
    between: ``max(match, OUTSIDE_TRAVEL (min(|x|, |y|) - 1))``. Every point ``z`` of the
    segment from ``x`` to ``y`` has ``|z| >= |x| - |x - y|``, so a motion below
    ``|x| - 1`` (and below ``|y| - 1``) cannot have reached the circle: no window closed and
    opened again on the way, as the count at the two ends cannot show. Far from the circle
    this lets a multiplier move by half its distance to it, instead of ``match``; near it
    (within ``2 match``) the rule is ``match`` as before."""
    return np.maximum(match, OUTSIDE_TRAVEL * (np.minimum(np.abs(x), np.abs(y)) - 1.0))


def krein_closing(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray, krein_b: np.ndarray,
                  circle_tol: float, match: float = 0.02,
                  distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """How fast a step from ``a`` to ``b`` (multipliers with their Krein definiteness)
    closes the nearest collision, as a ratio that exceeds 1 when the step is refused: the
    smallest collision distance
    (:func:`~nsm_continuation.core.floquet.collision_distances`, over the annulus
    ``0.5 < |lambda| < 2``) falls below ``KREIN_NEAR`` and below ``KREIN_CLOSING`` times its
    value at ``a``, with the same number of multipliers outside the circle at both ends.

    This catches the window that the endpoints of a step cannot show: two multipliers of
    opposite signature that approach, collide, leave the circle and come back *on the same
    side* within one step (the collision distance dips to 0 and recovers; each multiplier
    ends close to where it started, so no displacement is large). Halving the step until the
    distance shrinks at most by half per step approaches a collision geometrically: either
    the multipliers leave the circle at the end of a step (the count changes, the crossing is
    located) or the distance turns and grows again (a near miss, no window). In a step whose
    count changes, the multipliers of that crossing (and their partners) are left out of the
    test: it is located by the count.

    Also refused: a step whose multipliers *outside* the circle (and inside ``|lambda| < 2``)
    are not the same ones at both ends (one outside at one end has none outside within its
    allowance at the other end: ``match``, or half its distance to the circle,
    :func:`_outside_travel`) beyond a single crossing: with the same count at both ends a
    window closed and another opened within the step, two crossings the count cannot see;
    more than two such multipliers, more crossings than one (a conjugate pair, or a real
    multiplier, leaves or enters at a crossing) in the step.

    The ratio (linear in a short step, so it also predicts the next step): for a refusal of
    the second kind, the largest distance from a multiplier outside (inside ``|lambda| <
    2``) to the nearest one outside at the other end over its allowance (2 when one end has
    none outside: the step is halved); otherwise the larger of that ratio when every such
    multiplier is matched within its allowance, and, once the smallest distance ``c_b`` at
    ``b`` is below ``KREIN_NEAR``, of the fraction of the smallest distance ``c_a`` at
    ``a`` that the step closed over the fraction allowed, ``(1 - c_b / c_a) / (1 -
    KREIN_CLOSING)`` (``> 1`` exactly when ``c_b < KREIN_CLOSING c_a``)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    n_a, n_b = count_outside(a, circle_tol), count_outside(b, circle_tol)
    if abs(n_a - n_b) > 2:
        return 2.0  # more than one crossing (a complex pair, or a real multiplier) at once
    same_count = n_a == n_b
    out_a, out_b = a[np.abs(a) > 1.0 + circle_tol], b[np.abs(b) > 1.0 + circle_tol]
    # multipliers outside the circle (and near it: only those can have come from it or gone
    # back to it) at one end with none outside within ``match`` at the other end
    near_a, near_b = np.abs(out_a) < 2.0, np.abs(out_b) < 2.0
    moved = 0.0  # the largest motion of a multiplier outside over the motion it may have
    if out_a.size and out_b.size:
        d = np.abs(out_a[:, None] - out_b[None, :])
        ia, ib = d.argmin(axis=1), d.argmin(axis=0)
        da, db = d[np.arange(out_a.size), ia], d[ib, np.arange(out_b.size)]
        ra, rb = da / _outside_travel(out_a, out_b[ia], match), \
            db / _outside_travel(out_b, out_a[ib], match)
        crossed = np.concatenate([out_a[(ra > 1.0) & near_a], out_b[(rb > 1.0) & near_b]])
        moved = max(float(ra[near_a].max(initial=0.0)), float(rb[near_b].max(initial=0.0)))
    else:
        crossed = np.concatenate([out_a[near_a], out_b[near_b]])
    if (same_count and crossed.size) or crossed.size > 2:
        # a window closed and another opened (same count), or more than one crossing (a
        # complex pair or a real multiplier) in the step: the count cannot show them all
        return moved if moved > 1.0 else 2.0
    matched = moved if not crossed.size and moved <= 1.0 else 0.0
    ca, cb = distances if distances is not None else (
        collision_distances(a, krein_a, circle_tol), collision_distances(b, krein_b, circle_tol))
    wa = (np.abs(a) > 0.5) & (np.abs(a) < 2.0)
    wb = (np.abs(b) > 0.5) & (np.abs(b) < 2.0)
    if crossed.size:
        # the crossing of the step itself (located by the count) is not a hidden window: its
        # multipliers, their partners 1/conj and conjugates are left out
        near = np.concatenate([crossed, 1.0 / np.conj(crossed)])
        near = np.concatenate([near, np.conj(near)])
        wa &= np.abs(a[:, None] - near[None, :]).min(axis=1) > match
        wb &= np.abs(b[:, None] - near[None, :]).min(axis=1) > match
    if not (wa.any() and wb.any()):
        return matched
    min_a, min_b = float(ca[wa].min()), float(cb[wb].min())
    if not (min_b < KREIN_NEAR and min_a > 0.0):
        return matched
    return max(matched, max(1.0 - min_b / min_a, 0.0) / (1.0 - KREIN_CLOSING))


def multiplier_motion(a: np.ndarray, b: np.ndarray, lo: float = 0.5, hi: float = 2.0) -> float:
    """How far the multipliers near the unit circle move between two points: the largest
    distance from a multiplier of either point lying in the annulus ``lo < |lambda| < hi`` to
    the nearest multiplier of the other point, over the *whole* other set,

    ``max( max_{alpha in A, lo<|alpha|<hi} min_{beta in B} |alpha - beta|,
    max_{beta in B, lo<|beta|<hi} min_{alpha in A} |alpha - beta| )``.

    Instability windows of conservative systems open and close where two multipliers collide on
    the unit circle; if a step moves multipliers by more than the width of such a window, the
    window (out and back in) hides inside the step with the same count at both ends. Bounding
    this motion per step keeps the count test honest. Only the multipliers in the annulus are
    watched, but each is matched against the full other set, so a multiplier entering or
    leaving the annulus (``|lambda|`` through 0.5 or 2) moves by its true displacement, not by
    the distance to another multiplier (the Hausdorff distance of the two restricted sets
    jumped there and collapsed the step for tens of points).
    """
    a = np.asarray(a)
    b = np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    d = np.abs(a[:, None] - b[None, :])
    in_a = (np.abs(a) > lo) & (np.abs(a) < hi)
    in_b = (np.abs(b) > lo) & (np.abs(b) < hi)
    motion = 0.0
    if in_a.any():
        motion = max(motion, float(d[in_a].min(axis=1).max()))
    if in_b.any():
        motion = max(motion, float(d[:, in_b].min(axis=0).max()))
    return motion
