"""Named ends: where a branch that cannot go on ends at a located event instead of a failed
step.

A half-branch that fails (the step falls below ``step_min`` or below the floating-point
resolution) next to a boundary of its family ends *at* that boundary, named:

* **a located kink it cannot cross** (:meth:`EndLocator.expect`): the problem located the zero of
  an event function ahead of the last point (e.g. a grazing of a hybrid orbit,
  :meth:`~nsm_continuation.core.problem.Problem.continue_beyond`) but no branch beyond it can be
  followed; the zero is appended as the branch's last point, with its event;
* **a vanishing quantity** (:func:`~nsm_continuation.core.monitors.vanishing`): a positive
  derived quantity falls towards zero along the last points (e.g. the impact velocity of a
  family of impacting orbits, which ends where it vanishes: beyond, the impact would have to
  leave the surface). The branch cannot be followed to the zero itself (there the residual's
  Jacobian blows up, and its noise with it), so the zero is *extrapolated*: the arclength and
  every unknown as polynomials in the quantity ``q`` over the last resolved points (residual
  at most ``RESOLVED x newton_tol``), evaluated at ``q = 0`` (:func:`extrapolate_to_zero`).
  The location's uncertainty (the event's bracket, and the digits the reason prints) is the
  largest change of that value with one degree less or without the point nearest the zero.
  The end point is that extrapolation, with its derived quantities extrapolated too (the
  vanishing one is 0 there); its residual (``residual_at_end``) says how far the
  extrapolated unknowns are from a periodic orbit.
  The zero must be simple (``q ~ (s* - s)^k`` with ``k`` near 1, :data:`ORDER`): the quantity
  would change sign beyond it, the family ends. The zero of an impact velocity is a grazing,
  where the *branch* may go on along another family (the free orbit beyond a single grazing,
  eq. G2): the kink crosser is asked first, and where it crosses the branch goes on; where it
  locates the zero but finds nothing beyond, the branch ends at that located zero. It is
  looked for after an accepted point that is not resolved (:meth:`EndLocator.unresolved_end`:
  the branch would creep on in noisy steps), after a failed step that would have reached it,
  and at the end of a failing half-branch.

Otherwise the failure's own reason stands.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsm_continuation.core.monitors import Source
from nsm_continuation.core.palc.errors import NUMERICAL_ERRORS
from nsm_continuation.core.palc.kinks import KinkCrossing
from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.records import Event, Point

#: points whose residual is at most this many times ``newton_tol`` (relative to ``1 + |y|``)
#: are resolved: only they are extrapolated (near the zero the residual's noise grows)
RESOLVED = 10.0
#: the extrapolation fits (least squares: averaging their noise) the resolved points of the
#: last monotone fall of the quantity whose values lie within SPAN times the smallest, or the
#: MIN_POINTS smallest within SPAN_MAX times it where fewer do. Measured on the impact
#: damper's end at omega = sqrt(3) (``tests/hybrid/test_named_ends.py``): SPAN 10 with degree 3
#: is 8e-10 off, degree 2 4e-8 (the bracket); SPAN 30 degree 3 6e-9, 12 points 2e-8
SPAN = 10.0
SPAN_MAX = 100.0
MIN_POINTS = 6
#: degree of the polynomials in ``q`` (the bracket compares with one degree less)
DEGREE = 3
#: the quantity must have fallen at least this many times over the points fitted, and the zero
#: must lie no farther beyond the last point than the span of those points (an extrapolation,
#: not a prediction)
FALL = 3.0
#: after an unresolved point the branch ends at the extrapolated zero only when it is located
#: this well (relative to ``1 + |p|``); else it goes on, closer, until it fails
ACCURATE = 1e-7
#: the kink crosser is asked to locate the zero from points of the last fall where the
#: quantity was these many times its last value, then from where the fall began, until one
#: locates it (the margin-fixed solves of a grazing do not start from orbits next to it:
#: measured on the impact oscillator, from 1000 times the last impact velocity they do, from
#: 100 times they do not; each attempt that fails does so at its first solve)
START_SPANS = (30.0, 1000.0)
#: the quantity must fall like ``(s* - s)^k`` with ``k`` in this range: a simple zero, where
#: the quantity would change sign beyond it (the family ends), not a turn of the branch
#: (``k = 1/2``: the quantity's square is smooth in the arclength)
ORDER = (0.7, 1.5)


def supported(value: float, uncertainty: float) -> str:
    """``value`` with the significant digits its ``uncertainty`` supports (at least 3, at
    most 15)."""
    if not (np.isfinite(value) and np.isfinite(uncertainty)) or value == 0 or uncertainty <= 0:
        return f"{value:.12g}"
    digits = int(np.ceil(np.log10(abs(value) / uncertainty)))
    return f"{value:.{min(max(digits, 3), 15)}g}"


def extrapolate_to_zero(q: np.ndarray, values: np.ndarray, degree: int) -> np.ndarray:
    """The columns of ``values`` (one row per point) as polynomials of ``degree`` in ``q``
    (least squares), evaluated at ``q = 0``."""
    q = np.asarray(q, dtype=float)
    scale = float(np.max(np.abs(q)))
    V = np.vander(q / scale, degree + 1)
    coef, *_ = np.linalg.lstsq(V, np.asarray(values, dtype=float), rcond=None)
    return np.asarray(coef[-1], dtype=float)


def zero_order(s: np.ndarray, q: np.ndarray) -> float:
    """The order ``k`` of the zero that ``q`` approaches along the arclength ``s``,
    ``q ~ c (s* - s)^k``: the ``k`` in [0.25, 4] whose ``q^(1/k)`` is most nearly linear in
    ``s`` (as :func:`~nsm_continuation.core.roots.pole_estimate` chooses its exponent)."""
    ks = np.geomspace(0.25, 4.0, 97)
    best, order = np.inf, float("nan")
    for k in ks:
        z = q ** (1.0 / k)
        c = np.polyfit(s - s[-1], z, 1)
        err = float(np.max(np.abs(np.polyval(c, s - s[-1]) - z)) / max(np.ptp(z), 1e-300))
        if err < best:
            best, order = err, float(k)
    return order


class EndLocator(EnginePart):
    """Ends a failing half-branch at a located boundary of its family (module docstring)."""

    def __init__(self, engine: Any) -> None:
        super().__init__(engine)
        #: a kink located ahead that the branch cannot be continued across, with the value of
        #: its event function at the point it was located from
        self._pending: tuple[KinkCrossing, str, float] | None = None

    def begin(self) -> None:
        """A new half-branch: nothing located ahead."""
        self._pending = None

    def expect(self, crossing: KinkCrossing, start: Point) -> None:
        """A kink located ahead of ``start`` (an ``end`` crossing): the branch ends there if it
        fails before passing it."""
        name = crossing.events[0].data.get("function")
        if name is not None:
            self._pending = (crossing, str(name), float(start.event_values.get(name, np.nan)))

    def expecting(self, last: Point) -> bool:
        """Whether a kink located earlier still lies ahead of ``last``, or at it: its event
        function keeps its sign there (or is exactly zero: the steps towards the zero landed on
        it) and is no farther from zero than where the kink was located (else the branch has
        passed or turned away, and it is forgotten)."""
        if self._pending is None:
            return False
        _, name, f0 = self._pending
        f = last.event_values.get(name, np.nan)
        if np.isfinite(f) and np.isfinite(f0) and (np.sign(f) == np.sign(f0) or f == 0.0) \
                and abs(f) <= abs(f0) * (1.0 + 1e-9):
            return True
        self._pending = None
        return False

    def named(self, pts: list[Point], events: list[Event], reason: str) -> str:
        """The reason a failing half-branch ends: at a kink located ahead that it cannot
        cross, or at the extrapolated zero of a vanishing quantity (appended to ``pts`` and
        ``events``, the reason naming it), else ``reason`` itself."""
        if self.expecting(pts[-1]):
            return self._end_at_kink(pts, events, f"last step: {reason}")
        return self.vanishing_end(pts, events, f"the step towards it: {reason}") or reason

    def _end_at_kink(self, pts: list[Point], events: list[Event], why: str) -> str:
        """End at the kink located ahead (:meth:`expect`): its zero appended with its event."""
        crossing, _, _ = self._pending  # type: ignore[misc]
        self._pending = None
        zero = crossing.points[-1]
        last = pts[-1]
        zero.s = last.s + float(np.linalg.norm(zero.y - last.y))
        pts.append(zero)
        events.extend(crossing.events)
        return f"{crossing.end} ({why})"

    def vanishing_end(self, pts: list[Point], events: list[Event], why: str,
                      reach: float = np.inf, cross: bool = False, accurate: bool = False
                      ) -> str | None:
        """The end of the half-branch at the zero of a vanishing quantity ahead, within
        ``reach`` of its last point, and the reason naming it (``why``: what stopped the
        branch short of it); None if there is none. Where a kink was located ahead
        (:meth:`expect`, or, with ``cross``, by the kink crosser asked now: the zero of an
        impact velocity is a grazing, and the branch may go on beyond it along another
        family), the kink decides: the branch goes on across it (its points and events
        appended, None returned) or ends at its located zero; otherwise at the extrapolated
        zero (appended to ``pts`` and ``events``). ``accurate``: only a zero located to
        ``ACCURATE`` (relative to ``1 + |p|``): the branch may still come closer to it."""
        for m in self.problem.monitors.of(Source.VANISHING):
            found = self._vanishing(pts, m.name, m.kind, reach)
            if found is None:
                continue
            point, event = found
            p_end = float(event.data["parameter_end"])
            if accurate and event.data["parameter_uncertainty"] > ACCURATE * (1 + abs(p_end)):
                continue
            if cross and not self.expecting(pts[-1]):
                # the kink is located from earlier points of the fall: the last ones may lie
                # too close to it for its solves to start from
                h = max(2.0 * (point.s - pts[-1].s), self.engine.step_control.h)
                for start in self._fall_starts(pts, m.name):
                    crossing = self.engine.kinks.ahead(pts, h, start)
                    if crossing is not None and crossing.end is None:
                        crossing.record(pts, events)
                        return None
                    if crossing is not None:
                        self.expect(crossing, pts[-1])
                        break
            if self.expecting(pts[-1]):
                return self._end_at_kink(pts, events, why)
            pts.append(point)
            events.append(event)
            where = supported(event.data["parameter_end"], event.data["parameter_uncertainty"])
            return f"{m.kind} at {self.problem.parameter} = {where} (extrapolated; {why})"
        return None

    def resolved(self, p: Point) -> bool:
        """Whether the residual at ``p`` is at most ``RESOLVED`` times ``newton_tol`` (relative
        to ``1 + |y|``)."""
        scale = 1.0 + float(np.linalg.norm(p.y, np.inf))
        return p.residual_norm <= RESOLVED * self.settings.newton_tol * scale

    def unresolved_end(self, pts: list[Point], events: list[Event]) -> str | None:
        """After an accepted point that is not resolved (its residual's noise exceeds
        ``RESOLVED x newton_tol``) next to the zero of a vanishing quantity: the branch goes
        on across a kink there, or ends at it (:meth:`vanishing_end`, asking the kink crosser
        first); None to go on. Near such a zero the residual's noise grows like the return
        map's Jacobian: the branch would creep towards it in ever shorter noisy steps and end
        on a failed one."""
        if not self.problem.monitors.of(Source.VANISHING) or self.resolved(pts[-1]):
            return None
        why = (f"the orbits approaching it are no longer resolved: residual "
               f"{pts[-1].residual_norm:.2g}")
        return self.vanishing_end(pts, events, why, cross=True, accurate=True)

    def _fall_starts(self, pts: list[Point], name: str) -> list[Point]:
        """Points of the last monotone fall of ``name`` along the half-branch (resolved) to
        locate its zero from, nearest first: the last where it was at least ``START_SPANS``
        times its last value, and where the fall began."""
        last = float(pts[-1].derived.get(name, np.nan))
        fall: list[Point] = []
        for p in reversed(pts):
            q = float(p.derived.get(name, np.nan))
            if not (np.isfinite(q) and q > 0):
                break
            if not self.resolved(p):
                continue
            if fall and q < float(fall[-1].derived[name]):
                break
            fall.append(p)
        starts: list[Point] = []
        for span in START_SPANS:
            near = next((p for p in fall if float(p.derived[name]) >= span * last), None)
            if near is not None and all(near is not p for p in starts):
                starts.append(near)
        if fall and all(fall[-1] is not p for p in starts):
            starts.append(fall[-1])
        return starts

    def _resolved(self, pts: list[Point], name: str) -> list[Point]:
        """The resolved points (oldest first) of the last monotone fall of ``name`` towards
        zero along the half-branch whose values lie within ``SPAN`` times the smallest, or the
        ``MIN_POINTS`` smallest within ``SPAN_MAX`` times it where fewer do."""
        out: list[Point] = []
        for p in reversed(pts):
            q = float(p.derived.get(name, np.nan))
            if not (np.isfinite(q) and q > 0):
                if out:
                    break
                continue
            if not self.resolved(p):
                continue
            if out and not q > float(out[-1].derived[name]):
                break
            if out and q > SPAN_MAX * float(out[0].derived[name]):
                break
            out.append(p)
        if out:
            q_min = float(out[0].derived[name])
            near = [p for p in out if float(p.derived[name]) <= SPAN * q_min]
            out = near if len(near) >= MIN_POINTS else out[:MIN_POINTS]
        return out[::-1]

    def _vanishing(self, pts: list[Point], name: str, kind: str, reach: float
                   ) -> tuple[Point, Event] | None:
        """The extrapolated zero of the vanishing quantity ``name`` ahead of the last points,
        as the branch's end point and its event, or None (too few resolved points, the
        quantity not falling enough, not to a simple zero, or a zero farther ahead than the
        span of the points fitted or than ``reach`` from the last point of the branch)."""
        fit = self._resolved(pts, name)
        if len(fit) < MIN_POINTS:
            return None
        q = np.array([float(p.derived[name]) for p in fit])
        s = np.array([p.s for p in fit])
        if not q[0] >= FALL * q[-1] or not np.all(np.diff(s) > 0):
            return None
        cols = np.column_stack([s, np.array([p.y for p in fit])])
        deg = min(DEGREE, len(fit) - 3)
        at = extrapolate_to_zero(q, cols, deg)
        # the uncertainty: against one degree less, and without the point nearest the zero
        others = (extrapolate_to_zero(q, cols, deg - 1),
                  extrapolate_to_zero(q[:-1], cols[:-1], min(deg, len(fit) - 4)))
        s_end, y_end = float(at[0]), at[1:]
        if not (np.all(np.isfinite(at)) and 0.0 < s_end - s[-1] <= s[-1] - s[0]
                and 0.0 < s_end - pts[-1].s <= reach):
            return None
        order = zero_order(s, q)
        if not ORDER[0] <= order <= ORDER[1]:
            return None  # no simple zero (e.g. q ~ sqrt(s* - s): the branch turns there)
        # the tangent at the zero: d(y)/dq of the fitted polynomials, oriented along the branch
        scale = float(np.max(q))
        coef, *_ = np.linalg.lstsq(np.vander(q / scale, deg + 1), cols, rcond=None)
        d = coef[-2][1:]
        t = d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else fit[-1].tangent
        t = t if float(t @ fit[-1].tangent) >= 0 else -t
        try:
            end = self.engine.analyse(y_end, t, s_end, floquet=False)
        except NUMERICAL_ERRORS:
            return None
        # the end point is the branch's extrapolation, not a solution the corrector resolved
        # (its residual says how far the extrapolated unknowns are from one): its derived
        # quantities are extrapolated with the unknowns, the vanishing one to zero
        keys = [k for k, v in fit[0].derived.items() if isinstance(v, float)
                and all(np.isfinite(float(p.derived.get(k, np.nan))) for p in fit)]
        if keys:
            values = extrapolate_to_zero(
                q, np.array([[float(p.derived[k]) for k in keys] for p in fit]), deg)
            end.derived.update({k: float(v) for k, v in zip(keys, values, strict=True)})
        end.derived[name] = 0.0
        par = self.problem.parameter
        p_end = float(y_end[self.ip])
        uncertainty = max(abs(p_end - float(o[1 + self.ip])) for o in others)
        bracket = max(abs(s_end - float(o[0])) for o in others)
        detail = (f"{name} falls to zero at {par} = {supported(p_end, uncertainty)} "
                  f"(extrapolated from {len(fit)} resolved points, {name} {q[0]:.3g} .. "
                  f"{q[-1]:.3g}, ~ (s* - s)^{order:.2g}; {par} uncertain by {uncertainty:.2g})")
        data = {"monitor": name, "parameter_end": p_end, "parameter_uncertainty": uncertainty,
                "points_fitted": len(fit), "monitor_range": [float(q[-1]), float(q[0])],
                "zero_order": order, "signature_before": fit[-1].signature,
                "located_on": "extrapolation", "residual_at_end": float(end.residual_norm)}
        return end, Event(kind, end, detail, data=data, bracket=bracket)
