"""Multiplier crossings of the unit circle and Krein collisions, located on the arc of a step.

* :meth:`CrossingLocator.locate`: the number of multipliers outside ``|lambda| = 1 + tol``
  changes over the step; the change is bisected and located on the true condition
  ``|lambda_c| = 1`` of the crossing multiplier (:meth:`CrossingLocator._locate_on_modulus`),
  or, for a Krein collision of a conservative family, on the colliding pair's discriminant
  (:meth:`CrossingLocator._locate_collision`, :func:`~nsm_continuation.core.floquet.krein.
  discriminant`);
* :meth:`CrossingLocator.krein_windows`: an instability window opened and closed inside one
  step (the same count at both ends), found from the Krein signs of the ends
  (:func:`~nsm_continuation.core.floquet.krein.swap_paths`).

Each crossing is recorded with :func:`crossing_events` (its kind from
:func:`~nsm_continuation.core.floquet.classify_outside`, and a ``stability_change`` where
stability changes); a change of the count that no multiplier resolved on both sides of the
circle explains is an ``unresolved_crossing`` (:func:`unresolved_event`). Whether a +1 crossing
is a fold or a branch point is decided with the step's other tests
(:func:`~nsm_continuation.core.palc.branch_points.plus_one_events`).
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.floquet import classify_crossing, classify_outside
from nsm_continuation.core.floquet.krein import SEVERAL, discriminant, swap_paths
from nsm_continuation.core.palc.errors import NUMERICAL_ERRORS
from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.records import Event, Point
from nsm_continuation.core.roots import bisect_predicate, illinois
from nsm_continuation.core.scalar_search import bounded_minimum

#: the tracked values of a crossing multiplier by arclength, and the arclength where it is
#: inside the circle beyond noise (:meth:`CrossingLocator._track_inward`)
_Track = tuple[dict[float, complex], float] | str
#: :meth:`CrossingLocator._track_inward` found no point where the multiplier is inside beyond
#: noise
UNRESOLVED = "unresolved"


class CrossingLocator(EnginePart):
    """Locates where multipliers cross the unit circle in a step (and Krein collisions)."""

    def events(self, a: Point, b: Point, kinks: list[Event]) -> list[Event]:
        """The multiplier crossings of the step ``a -> b``, compared on the ends
        :meth:`ends` (``kinks``: the step's admissibility events): located where the number
        outside the circle differs (:meth:`locate`), else windows hidden inside the step
        (:meth:`krein_windows`)."""
        ma, mb = self.ends(a, b, kinks)
        if ma.multipliers is None or mb.multipliers is None:
            return []
        if ma.n_unstable != mb.n_unstable:
            return self.locate(ma, mb)
        return self.krein_windows(ma, mb)

    def ends(self, a: Point, b: Point, kinks: list[Event]) -> tuple[Point, Point]:
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
        q = self.engine.point_at(a, b, sig, tests=False)
        if q is None or q.multipliers is None:
            return a, b
        return (a, q) if b.multipliers is None else (q, b)

    def locate(self, a: Point, b: Point) -> list[Event]:
        """Locate where multipliers cross the unit circle between ``a`` and ``b``.

        Detector: the number of multipliers outside ``|lambda| = 1 + tol`` (``tol`` the
        point's ``circle_tol``: ``unit_circle_tol`` raised to the noise of the eigenvalues),
        bisected to ``multiplier_event_tol`` in arclength. It finds each change of the count,
        classifies it from the point of the count's bracket with more multipliers outside, on
        that point's own threshold (``classify_outside`` of
        :mod:`~nsm_continuation.core.floquet`) and names the crossing multiplier ``lambda_c``
        (the outside one closest to the circle there).

        Evidence on both sides: ``lambda_c`` is outside beyond its noise at the outside end of
        the bracket (by the count); it is tracked by continuity through the points analysed on
        the other side (:meth:`_track_inward`) to one where it lies inside beyond the noise
        there (``|lambda_c| - 1 < -circle_tol``). In a dissipative family a count change
        without that evidence is no crossing: the multiplier stays within the noise band of
        the circle on that side, and the count changed because the noise threshold passed it
        (e.g. ``(rtol + 10 eps) |Phi_T|`` of a hybrid orbit, growing with the multipliers near
        a zero-velocity impact). It is reported as an ``unresolved_crossing`` at the count's
        bracket (:func:`unresolved_event`), not as a bifurcation; a conservative family, whose
        stable multipliers lie on the circle within noise, keeps the count's location.

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
        h = b.s - a.s
        #: every point analysed with multipliers on the arc, by arclength from ``a``
        seen: dict[float, Point] = {0.0: a, h: b}

        def f(sig: float) -> tuple[int | None, Point | None]:
            p = self.engine.point_at(a, b, sig, tests=False)
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
            left = self.engine.point_at(a, b, sig_left, tests=False) or plo
            if left.multipliers is None:
                left, sig_left = plo, lo
            else:
                seen[sig_left] = left
            outside = right if vr > vl else left
            kind, leaving = classify_outside(np.asarray(outside.multipliers),
                                             outside.circle_tol)
            located = None
            track: _Track | None = None
            if leaving.size:
                # the newly outside multiplier at the outside end of the count's bracket
                lam_out = leaving[np.argmin(np.abs(leaving))]
                out_sig, inward = (sig, -1.0) if vr > vl else (sig_left, 1.0)
                track = self._track_inward(seen, out_sig, lam_out, inward)
                if track is UNRESOLVED and not self.problem.conservative:
                    events.append(unresolved_event(self.engine.full(right), width, int(vl),
                                                   int(vr), _nearest(right.multipliers,
                                                                     lam_out)))
                    lo, vlo, plo = right.s - a.s, vr, right
                    continue
                if isinstance(track, tuple):
                    located = self._locate_on_modulus(a, b, *track, out_sig)
            if located is not None:
                p, width, lam_c = located
                located_on = "multiplier_modulus"
            else:
                p = self.engine.full(right)
                if p.multipliers is None:  # the crossing point itself is a phantom: keep them
                    p.multipliers, p.n_unstable = right.multipliers, right.n_unstable
                lam_c = (None if not leaving.size else
                         _nearest(right.multipliers, leaving[np.argmin(np.abs(leaving))]))
                located_on = "count"
            events += crossing_events(kind, p, width, int(vl), int(vr), leaving, lam_c,
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
        pairs = self._colliding_pair(a, b, tol)
        if pairs is None:
            return None
        h = b.s - a.s
        #: the pair at each arclength computed (the step's ends first)
        ends = {0.0: pairs[0], h: pairs[1]}

        def disc(pair: np.ndarray) -> float:
            return discriminant(pair[0], pair[1])

        def f(sig: float) -> tuple[float, tuple[np.ndarray, np.ndarray] | None]:
            on_arc = self.engine.on_chord(a, b, sig)
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
        return self._confirm_collision(a, b, sig, width, payload[1], tol, d0, dh)

    def _colliding_pair(self, a: Point, b: Point, tol: float
                        ) -> tuple[np.ndarray, np.ndarray] | None:
        """The pair of multipliers that collides in the step ``a -> b``, at ``a`` and at
        ``b`` (:meth:`_locate_collision`): the one multiplier that left the circle (outside at
        one end, in the upper half plane, with its nearest multiplier at the other end inside)
        with its partner ``1 / conj`` there, and the two multipliers nearest to its direction
        ``rho`` on the circle at the other end; None when there is no such isolated pair."""
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
        return (pair_in, pair_out) if p_in is a else (pair_out, pair_in)

    def _confirm_collision(self, a: Point, b: Point, sig: float, width: float,
                           pair: np.ndarray, tol: float, d0: float, dh: float
                           ) -> list[Event] | None:
        """The crossing events of a collision located at arclength ``sig`` from ``a`` (the
        pair there: ``pair``; the discriminant at the step's ends: ``d0``, ``dh``), or None
        when the count does not confirm it: the event point, analysed in full, has the count
        of one end, and a point just past it on the other side that of the other end (no
        other crossing in the step)."""
        st = self.settings
        h = b.s - a.s
        q = self.engine.point_at(a, b, sig)
        if q is None:
            return None
        if q.multipliers is None:  # a phantom: keep the multipliers computed without tests
            p = self.engine.point_at(a, b, sig, tests=False)
            if p is None or p.multipliers is None:
                return None
            q.multipliers, q.n_unstable, q.circle_tol = p.multipliers, p.n_unstable, p.circle_tol
        vl, vr = int(a.n_unstable), int(b.n_unstable)
        delta = max(width, st.multiplier_event_tol)
        # off the circle |log|lambda|| = sqrt(-d) / 2: the pair counts as outside once
        # -d > 4 tol^2, i.e. about 4 tol^2 / |d'| past the collision (d' from the step's ends)
        past = max(delta, 16.0 * tol**2 * abs(h) / max(abs(dh - d0), 1e-300))
        if q.n_unstable == vl:
            right = b if sig + past >= h else self.engine.point_at(a, b, sig + past, tests=False)
            left = q
        elif q.n_unstable == vr:
            left = a if sig - past <= 0.0 else self.engine.point_at(a, b, sig - past, tests=False)
            right = q
        else:
            return None
        if (left is None or right is None or left.n_unstable != vl
                or right.n_unstable != vr):
            return None
        kind, leaving = classify_crossing(left.multipliers, right.multipliers, tol)
        lam_c = _nearest(q.multipliers, complex(pair[np.argmax(np.abs(pair))]))
        return crossing_events(kind, q, width, vl, vr, leaving, lam_c, "krein_discriminant")

    def krein_windows(self, a: Point, b: Point) -> list[Event]:
        """An instability window opened and closed inside the step ``a -> b`` (the same
        number of multipliers outside the circle at both ends) of a conservative family:
        its two crossings, located on the colliding pair's discriminant.

        The Krein words of the ends (:mod:`nsm_continuation.core.floquet.krein`) differ when two
        multipliers of opposite signature met inside the step; one transposition (or one flip
        at ``+-1``) names the pair and how it moved (:func:`~nsm_continuation.core.floquet.krein.
        swap_paths`). Its discriminant ``d(sigma)`` (:func:`~nsm_continuation.core.floquet.krein.
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
        unresolved = self.engine.locator.unresolved
        krein_at = self.engine.step_control.krein_at
        ka, kb = krein_at(a), krein_at(b)
        if ka is None or kb is None:
            return []
        tol = max(st.unit_circle_tol, a.circle_tol, b.circle_tol)
        paths = swap_paths(np.asarray(a.multipliers), ka, np.asarray(b.multipliers), kb, tol)
        if paths is None:
            return []
        if paths == SEVERAL:
            return unresolved("several Krein collisions in one step")
        assert not isinstance(paths, str)
        (z1a, z1b), (z2a, z2b) = paths
        h = b.s - a.s

        def f(sig: float) -> tuple[float, tuple[np.ndarray, np.ndarray] | None]:
            on_arc = self.engine.on_chord(a, b, sig)
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
            self.engine.krein_passings += 1
            return []
        vl = int(a.n_unstable)
        middle = self.engine.point_at(a, b, sig_m, tests=False)
        if middle is None or middle.multipliers is None or middle.n_unstable <= vl:
            return unresolved("a hidden Krein window the count does not confirm")
        events: list[Event] = []
        kind, leaving = classify_crossing(np.asarray(a.multipliers), middle.multipliers, tol)
        vm = int(middle.n_unstable)
        for lo, flo, hi, fhi, before, after in ((0.0, d0, sig_m, d_m, vl, vm),
                                                (sig_m, d_m, h, dh, vm, vl)):
            sig, payload, width = illinois(f, lo, flo, hi, fhi, st.event_tol, close=True)
            q = self.engine.point_at(a, b, sig)
            if payload is None or q is None:
                return unresolved("a hidden Krein window not located on its discriminant")
            if q.multipliers is None:  # a phantom: the multipliers computed without tests
                p = self.engine.point_at(a, b, sig, tests=False)
                if p is None or p.multipliers is None:
                    return unresolved("a hidden Krein window without multipliers")
                q.multipliers, q.n_unstable, q.circle_tol = (p.multipliers, p.n_unstable,
                                                             p.circle_tol)
            lam_c = _nearest(q.multipliers, complex(payload[1][0]))
            for ev in crossing_events(kind, q, width, before, after, leaving, lam_c,
                                      "krein_discriminant"):
                ev.data["hidden_in_step"] = True
                events.append(ev)
        return events

    def _multipliers_near(self, y: np.ndarray, t: np.ndarray, guesses: np.ndarray
                          ) -> np.ndarray | None:
        """The multipliers nearest to ``guesses`` (distinct): the problem's
        :meth:`~nsm_continuation.core.problem.Problem.multipliers_near`, else from all of them."""
        pair = self.problem.multipliers_near(y, t, guesses)
        if pair is None:
            fl = self.engine.floquet(y, t)
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

    @staticmethod
    def _track_inward(seen: dict[float, Point], out_sig: float, lam_out: complex,
                      inward: float) -> _Track | None:
        """``lambda_c`` (``lam_out`` at ``out_sig``, outside the circle) tracked by continuity
        (nearest neighbour, point by point) through the points already analysed on the side
        ``inward`` (``-1``: smaller arclength) to the nearest one where it lies inside the
        circle beyond the noise of its eigenvalues (``|lambda_c| - 1 < -circle_tol``): ``(the
        tracked values by arclength, that arclength)``; :data:`UNRESOLVED` where it never does
        (no evidence that it crossed), None where the tracking is ambiguous (two multipliers
        about equally close to the tracked one)."""
        track: dict[float, complex] = {out_sig: complex(lam_out)}
        lam = complex(lam_out)
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
                return track, k
        return UNRESOLVED

    def _locate_on_modulus(self, a: Point, b: Point, track: dict[float, complex],
                           sig_in: float, out_sig: float) -> tuple[Point, float, complex] | None:
        """Zero of ``phi(sigma) = |lambda_c(sigma)| - 1`` on the arc from ``a`` to ``b``:
        ``(event point, bracket width, lambda_c there)``, or None where ``phi`` gives no
        trustworthy location (then the count's location stands).

        ``track``: ``lambda_c`` at the points analysed between ``out_sig`` (outside: ``phi >
        tol``) and ``sig_in`` (inside beyond noise: ``phi < -circle_tol``,
        :meth:`_track_inward`). On that bracket the Illinois iteration
        (:func:`~nsm_continuation.core.roots.illinois`) locates ``phi = 0`` to ``event_tol``
        in arclength; at each trial point ``lambda_c`` is the multiplier nearest to the linear
        interpolation of the tracked values on both sides. The result is kept only if the
        iteration converged to within ``multiplier_event_tol`` and ``|phi|`` there is below
        ``circle_tol`` or the change of a continuous ``phi`` over the final bracket (not a
        jump of the tracked multiplier).
        """
        st = self.settings

        def phi(sig: float) -> tuple[float, tuple[Point, complex] | None]:
            p = self.engine.point_at(a, b, sig, tests=False)
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
        q = self.engine.full(p)
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


def unresolved_event(p: Point, width: float, n_before: int, n_after: int,
                     lam: complex) -> Event:
    """An ``unresolved_crossing`` at ``p`` (the count's bracket ``width``): the number of
    multipliers counted outside the circle changes ``n_before -> n_after`` while the
    multiplier ``lam`` (the one counted on one side only, nearest to ``p``'s) is not resolved
    beyond the noise of the multipliers on the other side (:meth:`CrossingLocator.locate`)."""
    dist = abs(lam) - 1.0
    data = {"n_outside_before": n_before, "n_outside_after": n_after,
            "stable_before": n_before == 0, "stable_after": n_after == 0,
            "located_on": "count", "critical_multiplier": [float(lam.real), float(lam.imag)],
            "modulus_minus_one": float(dist), "noise": float(p.circle_tol)}
    detail = (f"the count of multipliers outside the unit circle changes ({n_before} -> "
              f"{n_after}) while |lambda| - 1 = {dist:.2g} stays within the multipliers' "
              f"noise ({p.circle_tol:.2g}) on one side: no crossing resolved")
    return Event("unresolved_crossing", p, detail, data=data, bracket=width)


def crossing_events(kind: str, p: Point, width: float, n_before: int, n_after: int,
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

def _nearest(multipliers: np.ndarray, ref: complex) -> complex:
    """The multiplier nearest to ``ref``."""
    m = np.asarray(multipliers)
    return complex(m[int(np.argmin(np.abs(m - ref)))])
