"""Pseudo-arclength continuation (Keller) with event detection; problem-agnostic.

The curve ``G(y) = 0``, ``G: R^(n+1) -> R^n``, is followed by

* a tangent predictor ``y_p = y_k + h t_k`` with ``t_k`` the unit null vector of ``G_y(y_k)``
  (oriented continuously: ``t_{k+1} . t_k > 0``, which passes folds);
* a Newton corrector on the bordered system ``[G(y); t_k . (y - y_k) - h] = 0`` with the exact
  CasADi Jacobian;
* step control: a step is rejected (and retried with ``h / 2``) when Newton fails (or the
  problem raises :class:`~nsm_continuation.protocol.EvaluationError`) or the tangent turns by more
  than ``max_angle``; accepted steps grow or shrink ``h`` from the number of Newton iterations
  and the turning angle. A step never carries the parameter past an edge of the window (it is
  shortened to end on the edge, corrected there), nor an admissibility test function far past a
  zero (``TEST_STEP_FACTOR``);
* termination with a recorded reason, never an exception: parameter bound, bound on a derived
  quantity, maximum number of points, step below minimum (with the problem's own message when it
  raised), step below the floating-point resolution, singular Jacobian, loss of admissibility
  (when asked), an asymptote (amplitude growing without bound, ``p*`` extrapolated), and
  ``internal error: Type: message`` for a bug, keeping the points computed so far.

At each accepted point the problem's hooks give admissibility test functions and Floquet
multipliers; sign changes of the test functions listed in :func:`_test_values` are located with
:mod:`nsm_continuation.events`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .events import bisect_predicate, illinois, interior_extremum, pole_estimate
from .floquet import classify_crossing, count_outside
from .protocol import EvaluationError, FloquetData, Problem, StartPoint
from .records import Branch, Event, Point
from .settings import ContinuationSettings

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


class _RetryStep(Exception):
    """Raised while analysing a step whose result cannot be trusted (an event that cannot be
    located on the arc, a bound not reached): the step is retried with half its length."""


class ContinuationEngine:
    """Continue the solution branches of a :class:`~nsm_continuation.protocol.Problem`."""

    def __init__(self, problem: Problem, settings: ContinuationSettings,
                 progress: Callable[[int], None] | None = None) -> None:
        self.problem = problem
        self.settings = settings
        self.progress = progress
        self.ip = problem.parameter_index
        self.n_evaluations = 0
        self.motion_limited_steps = 0
        self.unlocated_events = 0
        #: set while the events of a step longer than a few step_min are analysed: an event
        #: that cannot be located on the step's arc then retries the step shorter
        self._retry_allowed = False
        #: running minimum of each monitored quantity along the current half-branch
        self._monitor_min: dict[str, float] = {}

    # ------------------------------------------------------------------ linear algebra
    def _bordered(self, y: np.ndarray, t: np.ndarray) -> np.ndarray:
        return np.vstack([self.problem.jacobian(y), t[None, :]])

    def correct(self, y_guess: np.ndarray, t_ref: np.ndarray, y_ref: np.ndarray,
                sigma: float) -> tuple[np.ndarray | None, int, str]:
        """Newton on ``[G(y); t_ref . (y - y_ref) - sigma] = 0``; returns (y, iterations, why)."""
        st = self.settings
        y = np.array(y_guess, dtype=float)
        r0 = None
        nr = float("nan")
        for it in range(1, st.newton_max_iter + 1):
            try:
                g, J = self.problem.evaluate_with_jacobian(y)
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
            A = np.vstack([J, t_ref[None, :]])
            try:
                dy = np.linalg.solve(A, -rhs)
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
        J = self.problem.jacobian(y)
        if t_prev is None:
            _, sv, vt = np.linalg.svd(J)
            if sv.size and sv[-1] < 1e-13 * max(sv[0], 1.0):
                raise np.linalg.LinAlgError("Jacobian rank deficient at start")
            t = vt[-1]
        else:
            A = np.vstack([J, t_prev[None, :]])
            rhs = np.zeros(len(y))
            rhs[-1] = 1.0
            t = np.linalg.solve(A, rhs)
        t = t / np.linalg.norm(t)
        if t_prev is not None and t @ t_prev < 0:
            t = -t
        return t

    def analyse(self, y: np.ndarray, t: np.ndarray, s: float, iterations: int = 0,
                tests: bool = True, floquet: bool = True,
                known: FloquetData | None = None) -> Point:
        """Evaluate the problem's hooks at a corrected point.

        ``tests``/``floquet`` switch off the admissibility tests or the multipliers while an event
        of the other kind is being located (the located point is then analysed in full).
        Multipliers are computed only on admissible points unless
        ``settings.stability_on_phantom``: stability of a phantom orbit has no physical meaning.
        """
        pr = self.problem
        test_values = pr.admissibility(y) if tests else {}
        fl = None
        if floquet and (self.settings.stability_on_phantom or not tests
                        or all(v >= 0 for v in test_values.values())):
            fl = known if known is not None else self._floquet(y, t)
        mult = None if fl is None else np.asarray(fl.multipliers)
        circle_tol = self.settings.unit_circle_tol
        if fl is not None:
            # eigenvalues are known to ~ eps * |B| only: never classify below that
            circle_tol = max(circle_tol, 1e3 * np.finfo(float).eps * fl.matrix_norm)
        n_out = 0 if mult is None else count_outside(mult, circle_tol)
        A = self._bordered(y, t)
        sign, logdet = np.linalg.slogdet(A)
        det = float(sign * np.exp(min(logdet, 700.0))) if sign != 0 else 0.0
        return Point(
            y=y, s=s, tangent=t, tests=test_values, multipliers=mult,
            trivial_error=0.0 if fl is None else fl.trivial_error, n_unstable=n_out,
            derived=pr.derived(y), bordered_det=det, newton_iterations=iterations,
            residual_norm=float(np.linalg.norm(pr.evaluate(y), np.inf)),
            circle_tol=circle_tol,
            signature=pr.signature(y) if pr.signature_kind is not None else None,
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
        try:
            p0, why = self.correct_start(start)
        except Exception as exc:  # a bug in a hook must not take the whole run down
            p0, why = None, f"internal error at start point: {type(exc).__name__}: {exc}"
        if p0 is None:
            return Branch(branch_id, start.label, [], [], {"start": why}, dict(start.info))
        directions = [1] if (start.direction != 0 or self.settings.direction != 0) else [1, -1]
        if self.settings.direction != 0 and start.direction == 0:
            if np.sign(p0.tangent[self.ip]) != np.sign(self.settings.direction):
                p0.tangent = -p0.tangent
        halves = []
        termination: dict[str, str] = {}
        for d in directions:
            t0 = p0.tangent * d
            # det[G_y; t^T] is odd in t: flip it with the tangent
            first = Point(**{**p0.__dict__, "tangent": t0, "bordered_det": p0.bordered_det * d})
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
        return Branch(branch_id, start.label, points, events, termination, dict(start.info))

    def _continue_one_direction(self, p0: Point) -> tuple[list[Point], list[Event], str]:
        """One half-branch from ``p0``: ``(points, events, termination reason)``. Never raises:
        an unexpected exception (a bug in a hook or here) ends the half-branch with the reason
        ``internal error: Type: message``, keeping the points computed so far."""
        pts = [p0]
        events: list[Event] = []
        try:
            reason = self._walk(pts, events)
        except Exception as exc:  # noqa: BLE001 - recorded, never raised
            reason = f"internal error: {type(exc).__name__}: {exc}"
        return pts, events, reason

    def _walk(self, pts: list[Point], events: list[Event]) -> str:
        """Steps from ``pts[-1]``, appending accepted points and located events in place;
        returns the termination reason."""
        st = self.settings
        ip = self.ip
        p0 = pts[0]
        h = st.step_initial
        # a start outside the parameter window ends at once
        par = p0.y[ip]
        if (st.param_min is not None and par < st.param_min) or (
                st.param_max is not None and par > st.param_max):
            return "start outside parameter bounds"
        motion_halvings = 0
        why = ""
        self._monitor_min = {}
        while len(pts) < st.max_points:
            a = pts[-1]
            res = STEP_RESOLUTION * (1.0 + float(np.linalg.norm(a.y, np.inf)))
            if h < res:
                return (f"step_below_resolution (a step of {h:.3g} does not move a point of "
                        f"size {res / STEP_RESOLUTION - 1:.3g} in floating point"
                        + (f"; last failure: {why})" if why else ")"))
            # the step never carries the parameter past an edge of the window: the step that
            # would is shortened to end on the edge, corrected at the edge's parameter value
            h_step, edge = h, None
            cap = self._window_cap(a)
            if cap is not None:
                dist, value = cap
                if abs(value - a.y[ip]) <= STEP_RESOLUTION * (1.0 + abs(value)):
                    return self._stop_on_edge(a, events)
                if dist <= h_step:
                    h_step, edge = dist, value
            # nor carries an admissibility test function far past a zero (see _test_cap)
            tcap = max(self._test_cap(pts), st.step_min, 4 * res)
            if tcap < h_step:
                h_step, edge = tcap, None
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
            if y_new is None:
                h = 0.5 * h_step
                if h < st.step_min:
                    return f"step_below_minimum ({why})"
                continue
            cos_angle = float(np.clip(t_new @ a.tangent, -1.0, 1.0))
            angle = float(np.arccos(cos_angle))
            if angle > st.max_angle and h_step > 2 * st.step_min:
                h = 0.5 * h_step
                continue
            pre = None
            if a.multipliers is not None and h_step > 4 * st.step_min \
                    and motion_halvings < st.max_multiplier_halvings:
                # multipliers near the unit circle must not move too far in one step: a
                # collision and a narrow instability window (out and back in) could hide inside
                # it. Checked before the (costlier) admissibility tests of the new point.
                pre = self._floquet(y_new, t_new)
                if pre is not None and multiplier_motion(
                        a.multipliers, np.asarray(pre.multipliers)) > st.max_multiplier_step:
                    h = 0.5 * h_step
                    motion_halvings += 1
                    if motion_halvings == st.max_multiplier_halvings:
                        self.motion_limited_steps += 1
                    continue
            s_new = a.s + (h_step if edge is None else float(a.tangent @ (y_new - a.y)))
            if not s_new > a.s:  # the corrector at the edge went backwards: not this branch
                h, why = 0.5 * h_step, "corrector at the window edge went backwards"
                continue
            # an event that cannot be located on the arc of a long step: retry it shorter
            self._retry_allowed = h_step > 4 * st.step_min
            try:
                b = self.analyse(y_new, t_new, s_new, it, known=pre)
                new_events, stop = self._events_between(a, b, pts)
            except _RetryStep as exc:
                h, why = 0.5 * h_step, str(exc)
                continue
            except NUMERICAL_ERRORS as exc:
                h, why = 0.5 * h_step, describe_error(exc)
                if h < st.step_min:
                    return f"step_below_minimum ({why})"
                continue
            finally:
                self._retry_allowed = False
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
            # step adaptation: few iterations and small turning -> grow
            if it <= 3 and angle < 0.4 * st.max_angle:
                h = min(h * 1.6, st.step_max)
            elif it >= 6 or angle > 0.8 * st.max_angle:
                h = max(h * 0.6, st.step_min)
        return "max_points"

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
        """Longest step that moves no admissibility test function towards zero by more than
        ``TEST_STEP_FACTOR`` times its value, predicted from the secant of the last step. A huge
        step could otherwise jump over a zero pair (out of admissibility and back) or land on
        another solution beyond a grazing point, with no sign change to see."""
        if len(pts) < 2:
            return np.inf
        a, prev = pts[-1], pts[-2]
        ds = a.s - prev.s
        cap = np.inf
        if not ds > 0:
            return cap
        for name, fa in a.tests.items():
            fp = prev.tests.get(name)
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
        point there. ``p*`` is extrapolated by :func:`~nsm_continuation.events.pole_estimate`.

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
                           floquet: bool = False) -> tuple[Point, float]:
        h = b.s - a.s
        hi = h if hi is None else hi
        flo = fun(a) if flo is None else flo
        fhi = fun(b) if fhi is None else fhi

        def f(sig: float) -> tuple[float, Point | None]:
            p = self._point_at(a, b, sig, tests=True, floquet=floquet)
            return (float("nan"), None) if p is None else (fun(p), p)

        sig, p, width = illinois(f, lo, flo, hi, fhi, self.settings.event_tol)
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
        st = self.settings
        found: list[Event] = []
        stops: list[tuple[Point, str]] = []
        ip = self.ip

        # 1. parameter bounds and bounds on derived quantities -> endpoint, stop
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
                    p, w = self._locate_continuous(a, b, fun, flo=fa, fhi=fb)
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

        # 2. admissibility test functions -> grazing (nonsmooth) events
        for name in b.tests:
            if name not in a.tests:
                continue
            fa, fb = a.tests[name], b.tests[name]
            if not (np.isfinite(fa) and np.isfinite(fb)):
                continue
            brackets: list[tuple[float, float, float, float]] = []
            if np.sign(fa) != np.sign(fb):
                brackets.append((0.0, fa, b.s - a.s, fb))
            elif len(history) >= 2 and name in history[-2].tests:
                prev = history[-2]
                sv = interior_extremum(np.array([prev.s, a.s, b.s]),
                                       np.array([prev.tests[name], fa, fb]))
                if sv is not None:
                    pm = self._point_at(a, b, sv - a.s)
                    fm = np.nan if pm is None else pm.tests.get(name, np.nan)
                    if np.isfinite(fm) and np.sign(fm) != np.sign(fa):
                        brackets += [(0.0, fa, sv - a.s, fm), (sv - a.s, fm, b.s - a.s, fb)]
                    elif pm is not None and name not in pm.tests:
                        # the test is not even defined inside the dip (the sticking time of
                        # an orbit that loses sticking and regains it within the step)
                        found.append(self._locate_test_presence(a, b, name, 0.0,
                                                                sv - a.s, False))
                        found.append(self._locate_test_presence(a, b, name, sv - a.s,
                                                                b.s - a.s, True))
            for lo, flo, hi, fhi in brackets:
                def fun(p: Point, n: str = name) -> float:
                    return p.tests.get(n, np.nan)
                p, w = self._locate_continuous(a, b, fun, lo, flo, hi, fhi)
                if not self._on_arc(a, b, p):
                    if self._retry_allowed:
                        raise _RetryStep(f"test function '{name}' changes sign but its zero "
                                         "is not on the step's arc")
                    self.unlocated_events += 1
                    continue
                leaving = flo >= 0 > fhi
                kind = self.problem.test_kinds.get(name, "grazing")
                ev = Event(kind, p, f"test function '{name}' "
                           + ("becomes negative: admissibility lost" if leaving
                              else "becomes positive: admissibility regained"),
                           data={"test": name, "admissible_before": bool(flo >= 0),
                                 "admissible_after": bool(fhi >= 0)}, bracket=w)
                found.append(ev)
                if leaving and st.stop_on_inadmissible:
                    stops.append((p, f"grazing: admissibility lost ('{name}')"))

        # 2b. a test function defined at one end of the step only: the quantity it measures
        # ceases to exist or appears (the sticking time of an orbit that loses its sticking
        # phase: the transition to incomplete chattering). The change is an event of the test's
        # kind, located by bisection on the test's presence.
        for name in [n for n in a.tests if n not in b.tests] + \
                [n for n in b.tests if n not in a.tests]:
            found.append(self._locate_test_presence(a, b, name, 0.0, b.s - a.s,
                                                    name in a.tests))

        if st.detect_bifurcations:
            # 3. fold: the parameter component of the tangent changes sign
            if np.sign(a.tangent[ip]) != np.sign(b.tangent[ip]):
                p, w = self._locate_continuous(a, b, lambda q: q.tangent[ip])
                found.append(Event("fold", p, "limit point: the parameter reaches an extremum "
                                   "along the branch", data={"test": "tangent"}, bracket=w))
            # 4. branch point: determinant of the bordered Jacobian changes sign
            elif np.sign(a.bordered_det) != np.sign(b.bordered_det) and a.bordered_det != 0:
                p, w = self._locate_continuous(a, b, lambda q: q.bordered_det)
                if self._on_arc(a, b, p):
                    found.append(Event("branch_point", p, "simple branch point: det[G_y; t^T] "
                                       "changes sign", data={"test": "bordered_determinant"},
                                       bracket=w))
                else:
                    self.unlocated_events += 1
            # 5. multipliers crossing the unit circle
            if a.multipliers is not None and b.multipliers is not None \
                    and a.n_unstable != b.n_unstable:
                found.extend(self._locate_multiplier_crossings(a, b))

        # 6. the problem's discrete signature (event sequence of a hybrid orbit) changes
        if a.signature is not None and b.signature is not None and a.signature != b.signature:
            found.extend(self._locate_signature_change(a, b))

        found = _merge_coincident_grazing(found, self.settings.event_tol)
        if stops:
            stop = min(stops, key=lambda sp: sp[0].s)
            return found, stop
        return found, None

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
        kind = self.problem.test_kinds.get(name, "grazing")
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
        """Locate where the number of multipliers outside the unit circle changes."""
        tol = self.settings.unit_circle_tol

        def f(sig: float) -> tuple[int | None, Point | None]:
            p = self._point_at(a, b, sig, tests=False)
            return (None, None) if p is None else (p.n_unstable, p)

        events: list[Event] = []
        lo, vlo, plo = 0.0, a.n_unstable, a
        h = b.s - a.s
        for _ in range(4):  # at most a few crossings in one step
            if vlo == b.n_unstable:
                break
            sig, p, width, vl, vr = bisect_predicate(f, lo, vlo, h, b.n_unstable,
                                                     self.settings.multiplier_event_tol)
            right = b if p is None else p  # has multipliers (analysed without tests)
            p = b if p is None else self.full(p)
            left = self._point_at(a, b, max(sig - width, 0.0), tests=False) or plo
            if left.multipliers is None:
                left = plo
            kind, leaving = classify_crossing(left.multipliers, right.multipliers,
                                              max(tol, right.circle_tol, left.circle_tol))
            if p.multipliers is None:  # the crossing point itself is a phantom: keep them
                p.multipliers, p.n_unstable = right.multipliers, right.n_unstable
            stable_before, stable_after = vl == 0, vr == 0
            data = {"n_outside_before": int(vl), "n_outside_after": int(vr),
                    "stable_before": stable_before, "stable_after": stable_after,
                    "leaving_multipliers": [[float(z.real), float(z.imag)] for z in leaving]}
            detail = {
                "fold": "a multiplier pair crosses the unit circle at +1",
                "period_doubling": "a multiplier crosses the unit circle at -1 (flip)",
                "neimark_sacker": "a complex pair crosses the unit circle away from +-1 "
                                  "(Krein collision in a conservative system)",
                "stability_change": "multipliers cross the unit circle",
            }[kind]
            events.append(Event(kind, p, detail, data=dict(data), bracket=width))
            if stable_before != stable_after:
                events.append(Event("stability_change", p,
                                    "stable -> unstable" if stable_before else
                                    "unstable -> stable", data=dict(data), bracket=width))
            lo, vlo, plo = p.s - a.s, vr, p
        return events


def _merge_coincident_grazing(events: list[Event], tol: float) -> list[Event]:
    """Several admissibility tests vanishing at the same point are one grazing event (for the
    impact oscillator: zero outgoing velocity and a critical point entering at t = 0+ together
    make a linear grazing orbit). The merged event lists every test in ``data['tests']``."""
    graz = sorted((e for e in events if e.kind == "grazing"), key=lambda e: e.point.s)
    others = [e for e in events if e.kind != "grazing"]
    merged: list[Event] = []
    for ev in graz:
        ev.data.setdefault("tests", [ev.data.get("test")])
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


def multiplier_motion(a: np.ndarray, b: np.ndarray, lo: float = 0.5, hi: float = 2.0) -> float:
    """Hausdorff distance between the multipliers of two points, restricted to the annulus
    ``lo < |lambda| < hi`` around the unit circle.

    Instability windows of conservative systems open and close where two multipliers collide on
    the unit circle; if a step moves multipliers by more than the width of such a window, the
    window (out and back in) hides inside the step with the same count at both ends. Bounding
    this motion per step keeps the count test honest.
    """
    a = a[(np.abs(a) > lo) & (np.abs(a) < hi)]
    b = b[(np.abs(b) > lo) & (np.abs(b) < hi)]
    if a.size == 0 or b.size == 0:
        return 0.0
    d = np.abs(a[:, None] - b[None, :])
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))
