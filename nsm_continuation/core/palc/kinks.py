"""Kinks and charts: where the problem's own local parametrisation takes over from the
arclength corrector.

* a kink of the branch at a zero of an event function (e.g. a grazing of a hybrid orbit, where
  the Jacobian of the residual jumps): the problem returns the points across it
  (:meth:`~nsm_continuation.core.problem.Problem.continue_beyond`), found in a step
  (:meth:`KinkCrosser.in_step`) or ahead of a step that failed (:meth:`KinkCrosser.ahead`);
  where the problem locates the zero but cannot go beyond it, the crossing is an ``end``
  (:class:`~nsm_continuation.core.palc.ends.EndLocator` ends the branch there if it cannot step
  past the zero either); a change of the problem's signature across a crossed kink is a
  change of family, an event of the ``family`` monitor's kind;
* a move to another chart where the problem asks for one
  (:meth:`~nsm_continuation.core.problem.Problem.rechart`, :meth:`KinkCrosser.rechart`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from nsm_continuation.core.monitors import Source
from nsm_continuation.core.palc.crossings import crossing_events
from nsm_continuation.core.palc.errors import NUMERICAL_ERRORS
from nsm_continuation.core.palc.locate import EventSource, StepEvents
from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.problem import EvaluationError
from nsm_continuation.core.records import Event, Point


@dataclass(frozen=True)
class Kink:
    """A zero of the event function ``function`` where the branch may have a kink:
    ``value`` is the function's value at the point the approach starts from (``start``, or
    the last point of the branch when None)."""

    function: str
    value: float
    start: Point | None = None


@dataclass
class KinkCrossing:
    """The branch across a kink: the points to append (the approach, the zero and the first
    point beyond) and the events to record with them. ``end``: the kink is located but the
    branch cannot be continued beyond it (the points end at the zero; the reason the branch
    ends there)."""

    points: list[Point]
    events: list[Event]
    end: str | None = None

    def record(self, pts: list[Point], events: list[Event]) -> None:
        """Append the crossing to a half-branch's points and events."""
        pts.extend(self.points)
        events.extend(self.events)


class KinkCrosser(EnginePart):
    """Crosses kinks of the branch and moves to the problem's new charts."""

    def rechart(self, pts: list[Point]) -> None:
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
        engine = self.engine
        previous = engine.problem
        engine.problem = moved.problem
        try:
            pts[-1] = engine.analyse(np.asarray(moved.y, dtype=float),
                                     np.asarray(moved.tangent, dtype=float), a.s,
                                     a.newton_iterations)
        except NUMERICAL_ERRORS:
            engine.problem = previous
            return
        engine.rechart_notes.append(f"{moved.note} (at {self.problem.parameter} = "
                                    f"{a.y[self.ip]:.10g})")

    def in_step(self, a: Point, found: StepEvents, h_step: float) -> KinkCrossing | None:
        """A zero of an event function located in the step ``a -> b`` (the earliest, before
        any stop) at which the problem says the branch has a kink
        (:meth:`Problem.continue_beyond`): the branch goes on from the problem's point beyond
        it instead of from ``b`` (which the arclength corrector may have reached across the
        kink on another branch, or on the right one inaccurately), or, where the problem finds
        no branch beyond it (an ``end`` crossing), ends at the zero. The crossing's events are
        the step's before the kink, then the kink's."""
        zeros = found.of(EventSource.FUNCTION)
        if not zeros:
            return None
        ev = min(zeros, key=lambda e: e.point.s)
        if found.stop is not None and found.stop[0].s <= ev.point.s:
            return None
        kink = Kink(ev.data["function"], float(ev.data["value_before"]), ev.point)
        crossing = self.cross(a, kink, h_step)
        if crossing is None:
            return None
        s_zero = crossing.events[0].point.s
        # the step's end lies beyond the kink, where the Jacobian jumps: a sign change of
        # det[G_y; t^T] or of the tangent's parameter component located at the kink itself is
        # that jump, no branch point or fold; the step's zeros of event functions and changes
        # of signature are left out: the kink's event records the function and the signatures
        # on both sides
        at_kink = 1e-6 * h_step
        before = [e for src, e in found.entries if e.point.s < s_zero - 1e-12
                  and src not in (EventSource.SIGNATURE, EventSource.FUNCTION)
                  and not (e.kind in ("branch_point", "fold")
                           and s_zero - e.point.s <= at_kink)]
        return KinkCrossing(crossing.points, before + crossing.events, crossing.end)

    def family_events(self, a: Point, b: Point, found: list[tuple[EventSource, Event]]
                      ) -> list[Event]:
        """The events of a step ``a -> b`` that crossed a zero of an event function without
        the problem's parametrisation (the arclength corrector went across it): where the
        signature changes over the step, the branch went on along another family at the zero,
        and its change of signature is the ``family`` monitor's event at the zero (located on
        the smooth function, where the signature's bisection across the kink is not
        reliable). Other steps' events unchanged."""
        family = self.problem.monitors.family_kind
        zeros = [ev for src, ev in found if src is EventSource.FUNCTION]
        if family is None or not zeros or a.signature == b.signature \
                or a.signature is None or b.signature is None:
            return [ev for _, ev in found]
        out: list[Event] = []
        for src, ev in found:
            if src is not EventSource.SIGNATURE:
                out.append(ev)
                continue
            zero = min(zeros, key=lambda z: abs(z.point.s - ev.point.s))
            before = ev.data.get("signature_before")
            after = ev.data.get("signature_after")
            out.append(Event(family, zero.point, f"event sequence {before} -> {after}: the "
                             f"branch goes on along another family across the {zero.kind}",
                             data={"signature_before": before, "signature_after": after,
                                   "at": zero.kind}, bracket=zero.bracket))
        return out

    def ahead(self, pts: list[Point], h_step: float, start: Point | None = None
              ) -> KinkCrossing | None:
        """After a step from ``pts[-1]`` that failed: the crossing of a kink the step may have
        met (:meth:`_approaching`), or None (an ``end`` crossing: the kink is located, the
        branch cannot be continued beyond it). ``start``: an earlier point of the branch to
        locate the kink from (where the last ones are too close to it to be resolved)."""
        kink = self._approaching(pts, h_step)
        if kink is not None and start is not None and kink.function in start.event_values:
            kink = Kink(kink.function, float(start.event_values[kink.function]), start)
        return None if kink is None else self.cross(pts[-1], kink, h_step)

    def _approaching(self, pts: list[Point], h_step: float) -> Kink | None:
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
                return Kink(name, float(fa))
        return None

    def cross(self, a: Point, kink: Kink, h_step: float) -> KinkCrossing | None:
        """The points the problem returns across a kink at a zero of event function
        ``kink.function`` (:meth:`Problem.continue_beyond`, from ``kink.start`` or ``a``; the
        function's value there ``kink.value``): the approach, the zero and
        the first point beyond, analysed in order, with the event at the zero (and a
        ``stability_change`` there when the number of multipliers outside the circle differs
        on the two sides: they jump at a kink, there is no crossing to locate). The zero itself
        gets no multipliers: the map is not differentiable there. None when the problem does
        not resolve the kink."""
        name, value = kink.function, kink.value
        src = kink.start if kink.start is not None else a
        try:
            out = self.problem.continue_beyond(name, src.y, src.tangent, value, h_step,
                                               self.settings.newton_tol)
            if out is None:
                return None
            path: list[Point] = []
            prev = a
            # the approach from ``a`` on (from an earlier start it may pass points behind it),
            # without points that are the zero itself to round-off
            reach = float(np.linalg.norm(a.y - np.asarray(out.zero, dtype=float)))
            for z in out.approach:
                z = np.asarray(z, dtype=float)
                tiny = 1e-12 * (1.0 + np.linalg.norm(z))
                if np.linalg.norm(z - prev.y) <= tiny \
                        or not tiny < np.linalg.norm(z - out.zero) < reach:
                    continue
                t = self.engine.tangent(z, prev.tangent)
                prev = self.engine.analyse(z, t, prev.s + float(np.linalg.norm(z - prev.y)))
                path.append(prev)
            yg = np.asarray(out.zero, dtype=float)
            pg = self.engine.analyse(yg, prev.tangent,
                                     prev.s + float(np.linalg.norm(yg - prev.y)), floquet=False)
            if out.beyond is None:
                return self._end_at(name, value, a, path, pg, out.why)
            y1 = np.asarray(out.beyond, dtype=float)
            d = y1 - yg
            if not self._is_real(name, value, pg, prev, d):
                return None
            p1 = self.engine.analyse(y1, self.engine.tangent(y1, d / np.linalg.norm(d)),
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
        kind = self.problem.monitors.kind(Source.FUNCTION, name)
        found = [Event(kind, pg, f"event function '{name}' vanishes; the branch has a kink "
                       "here and goes on beyond it (the problem's local parametrisation)",
                       data=data, bracket=0.0)]
        family = self.problem.monitors.family_kind
        if family is not None and a.signature != p1.signature \
                and a.signature is not None and p1.signature is not None:
            found.append(Event(family, pg, f"event sequence {a.signature} -> {p1.signature}: "
                               f"the branch goes on along another family across the {kind}",
                               data={"signature_before": a.signature,
                                     "signature_after": p1.signature, "at": kind},
                               bracket=0.0))
        if prev.multipliers is not None and p1.multipliers is not None \
                and prev.n_unstable != p1.n_unstable:
            found += crossing_events("stability_change", pg, 0.0, prev.n_unstable,
                                     p1.n_unstable, np.array([]), None, "kink")
        if self.engine.progress is not None:
            self.engine.progress(len(path) + 2)
        return KinkCrossing([*path, pg, p1], found)

    def _end_at(self, name: str, value: float, a: Point, path: list[Point], zero: Point,
                why: str) -> KinkCrossing | None:
        """The crossing that ends at the zero ``zero`` of event function ``name`` (the problem
        locates it but cannot continue the branch beyond it, for the reason ``why``): the
        approach and the zero, with the zero's event; None if ``zero`` is no zero."""
        fz = zero.event_values.get(name, np.nan)
        if np.isfinite(fz) and abs(fz) > 1e-6 * max(abs(value), 1e-300):
            return None
        kind = self.problem.monitors.kind(Source.FUNCTION, name)
        p = float(zero.y[self.ip])
        data: dict[str, Any] = {"function": name, "value_before": value, "kink": True,
                                "crossed": False, "signature_before": a.signature,
                                "reason": why}
        ev = Event(kind, zero, f"event function '{name}' vanishes; the branch is not continued "
                   f"beyond it: {why}", data=data, bracket=0.0)
        end = (f"{kind} at {self.problem.parameter} = {p:.12g}, located; the branch is not "
               f"continued beyond it: {why}")
        return KinkCrossing([*path, zero], [ev], end=end)

    def _is_real(self, name: str, value: float, zero: Point, prev: Point,
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
