"""The transitions of Table 1: impacts (eq. 5), the chatter map, sticking, release, turns.

Mixed into :class:`~nsm_continuation.hybrid.simulate.Simulator`, which locates the event and
calls :meth:`Transitions._transition` with the state just before it; each transition returns
the new discrete state (:mod:`.modes`), the state after the event and its sensitivities
(``J <- E_x J``, ``J_t <- J_t + e_x J`` for an event map ``E``: the impact ``R``, the chatter map
``Q``, the time jump ``q``).

**Chatter map** (secs. 3.3, 3.4, 5.2): at each impact ``k`` of a chattering sequence (the
pre-impact state ``x_k``) the first-order map gives ``E_k = (Q(x_k), t_k + q(x_k))``. Order ``m``
combines ``m`` consecutive values by the extrapolation of eq. (35), repeated
(``L_j(k) = (L_{j-1}(k) - r^{j+1} L_{j-1}(k-1)) / (1 - r^{j+1})``, :func:`extrapolate`), and its
error is estimated from one more impact, ``|L(k) - L(k-1)| r^{m+1} / (1 - r^{m+1})``. The map is
applied when the estimate is below ``chatter_tol`` and ``a < 0`` at the image (sec. 5.2); the
image is projected onto ``{H = 0, v = 0}`` (an ``O(v^2)`` move, below the map's own error) so
that sticking starts exactly on the sticking set.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsm_continuation.hybrid.modes import EXTENDED, S1, S2, S3, S4, S5, S6
from nsm_continuation.hybrid.sim_data import SimEvent, SimOptions, SimulationError
from nsm_continuation.hybrid.system import ELASTIC_TOL, CompiledHybrid

#: an elastic impact (``r = 1``) with ``a < 0`` whose rebound flight ``2 |v| / |a|`` is shorter
#: than this times ``1 + t`` starts a chattering sequence that never ends: refused
ELASTIC_MIN_FLIGHT = 1e-10


class Transitions:
    """The transitions of Table 1 (see the module docstring), for the simulator of ``c``."""

    c: CompiledHybrid
    o: SimOptions
    #: the compiled Functions, called through their buffers (``CompiledHybrid.calls``)
    calls: Any
    #: chatter error estimates of the current sequence (stall detection)
    _errs: list[float]

    def _transition(self, mode: str, name: str, Y: np.ndarray, J: np.ndarray | None,
                    Jt: np.ndarray | None, t: float, pr: np.ndarray, seq: list[Any],
                    events: list[SimEvent], chatter_errors: list[float], surface: int = 0
                    ) -> tuple[Any, ...]:
        """The transition of Table 1 fired by ``name`` of ``surface`` in its state ``mode``
        (``pr``: the probe from that surface's block on): a flight transition
        (:meth:`_flight_transition`) or an impact (:meth:`_impact_transition`).
        Returns ``(new mode, Y, J, Jt, t, info)``."""
        if name in ("H", "h"):
            return self._impact_transition(mode, Y, J, Jt, t, seq, events, chatter_errors,
                                           surface)
        return self._flight_transition(mode, name, Y, J, Jt, t, pr, seq, events, surface)

    def _flight_transition(self, mode: str, name: str, Y: np.ndarray, J: np.ndarray | None,
                           Jt: np.ndarray | None, t: float, pr: np.ndarray, seq: list[Any],
                           events: list[SimEvent], surface: int = 0) -> tuple[Any, ...]:
        """Transitions I, II, VI, VIII, X, XI, XII of Table 1 (turns of ``v``, sign changes of
        ``a``): no jump of the state; the extended state is dropped where chattering ends."""
        c = self.c
        N = c.N
        info: dict[str, Any] = {}
        if mode == S1 and name == "v":                                  # I
            return S2, Y, J, Jt, t, info
        if mode == S2 and name == "v":                                  # II: local minimum of H
            info["near_approach"] = float(pr[0])
            # J at the turn: the grazing normal form (:mod:`.grazing`) needs the
            # gradient of H_min = H(x(t_turn)) (dH/dt = v = 0 there) and the tail sensitivity
            events.append(SimEvent("near_approach", t, Y[: c.n].copy(),
                                   {"H": float(pr[0]), "J": None if J is None else J[:N].copy()},
                                   surface=surface))
            return S1, Y, J, Jt, t, info
        if mode == S3 and name == "a":                                  # XII
            return S1, Y, J, Jt, t, info
        if mode == S4 and name == "a":                                  # XI: release
            events.append(SimEvent("release", t, Y[: c.n].copy(), surface=surface))
            return S3, Y, J, Jt, t, info
        if mode == S5 and name == "v":                                  # VI
            return S6, Y, J, Jt, t, info
        if mode == S5 and name == "a":                                  # VIII: chattering broken
            count = len(seq)
            seq.clear()
            events.append(SimEvent("chatter_broken", t, Y[: c.n].copy(), {"impacts": count},
                                   surface=surface))
            return S1, Y[:N].copy(), None if J is None else J[:N].copy(), Jt, t, info
        if mode == S6 and name == "v":                                  # X: turned before impact
            count = len(seq)
            seq.clear()
            info["near_approach"] = float(pr[0])
            # a near approach too (H_min = H at the turn): J for the grazing normal form
            events.append(SimEvent("chatter_broken", t, Y[: c.n].copy(),
                                   {"impacts": count, "H": float(pr[0]),
                                    "J": None if J is None else J[:N].copy()}, surface=surface))
            return S1, Y[:N].copy(), None if J is None else J[:N].copy(), Jt, t, info
        raise SimulationError(f"no transition for {name!r} in state {mode}")  # pragma: no cover

    def _impact_transition(self, mode: str, Y: np.ndarray, J: np.ndarray | None,
                           Jt: np.ndarray | None, t: float, seq: list[Any],
                           events: list[SimEvent], chatter_errors: list[float],
                           surface: int = 0) -> tuple[Any, ...]:
        """Transitions III, IV, V, VII, IX of Table 1 on ``surface``: an impact (eq. 5), the
        chatter map once its error estimate meets the tolerance (:meth:`_chatter_step`), or
        sticking."""
        c, o = self.c, self.o
        sc = self.calls.surfaces[surface]
        N = c.N
        info: dict[str, Any] = {}
        # ---------------------------------------------------------------- impacts
        X = Y[:N].copy()
        JX = None if J is None else J[:N].copy()
        q = c.q(X, surface)
        if o.validate:
            c.validate_at(X, f"at the impact at t = {t:.6g}", q, surface)
        info["impact_velocity"] = abs(q["v"])
        a = q["a"]
        if a > 0:
            # a decelerating approach: the free flight continued through the wall would turn
            # at H = -v^2 / (2a); with the near approaches' H_min > 0 this is the signed
            # grazing margin, continuous through a grazing bifurcation
            info["near_approach"] = -q["v"] ** 2 / (2.0 * a)
        if mode == S2:
            seq.clear()
        # an elastic impact (r = 1): the rebound leaves with the incoming speed, so impacts
        # where the field pushes into the surface (a < 0) do not accumulate: a plain impact,
        # no chatter map (it needs r < 1). Near rest on the surface the rebounds come back
        # within the time resolution and never end: a chattering sequence at r = 1, refused
        elastic = q["r"] >= 1.0 - ELASTIC_TOL
        if elastic and a < 0 and 2.0 * abs(q["v"]) <= ELASTIC_MIN_FLIGHT * (1.0 + abs(t)) * -a:
            raise SimulationError(
                f"chattering at r = 1 (t = {t:.6g}): an elastic impact on "
                f"{c.surface_label(surface)} at |v| = {abs(q['v']):.3g} where the field pushes "
                f"into it (a = {a:.3g} < 0) rebounds for less than {ELASTIC_MIN_FLIGHT:g} (1 + t):"
                " a chattering sequence with r = 1 does not converge (the chatter map needs "
                "r < 1, sec. 3)")
        if a < 0 and o.chatter in ("map", "cut") and not elastic:
            # a chattering sequence: impacts accumulate where a < 0 (sec. 2.5)
            done = self._chatter_step(X, JX, Jt, t, seq, events, chatter_errors, surface)
            if done is not None:
                Xs, Js, Jts, ts, count = done
                info["chatter_count"] = count
                return S4, Xs, Js, Jts, ts, info
        R, Rx, _v, _r = sc.impact(X)
        Xp = R.ravel()
        Jp = None if JX is None else Rx @ JX
        v_plus, v_grad = sc.vgrad(Xp)
        vplus = v_plus.item()
        if mode == S2:
            events.append(SimEvent("impact", t, X[: c.n].copy(),
                                   {"v": q["v"], "a": a,
                                    "J": None if JX is None else JX.copy()}, surface=surface))
        if mode in EXTENDED and not a < 0:
            # an impact of a chattering sequence after which the flight leaves the wall:
            # the sequence breaks off (this impact is not in ``seq``, which holds a < 0 only)
            events.append(SimEvent("chatter_broken", t, X[: c.n].copy(),
                                   {"impacts": len(seq) + 1, "v": q["v"], "a": a,
                                    "J": None if JX is None else JX.copy()}, surface=surface))
            seq.clear()
        if vplus <= 1e-14 * (1.0 + abs(q["v"])):                          # r = 0 (IV, V)
            seq.clear()
            # stick or release on the acceleration at the post-impact state (on {H = 0,
            # v = 0}): a force that depends on the velocity (damping) changes sign across the
            # impact, and the pre-impact a would release into the wall or stick off it
            if self.calls.probe.flat(Xp)[4 * surface + 2] < 0:
                Xs, Js = self._project(Xp, Jp, surface)
                events.append(SimEvent("plastic_stick", t, Xs[: c.n].copy(), surface=surface))
                return S4, Xs, Js, Jt, t, info
            return S3, Xp, Jp, Jt, t, info
        if a < 0 and not elastic:                                         # III, VII
            v_row = v_grad.ravel()
            Ye = np.concatenate([Xp, [0.0, vplus]])
            Je = None
            if Jp is not None:
                Je = np.vstack([Jp, np.zeros((1, N)), (v_row @ Jp)[None, :]])
            return S5, Ye, Je, Jt, t, info
        seq.clear()
        return S1, Xp, Jp, Jt, t, info

    def _project(self, X: np.ndarray, J: np.ndarray | None, surface: int = 0
                 ) -> tuple[np.ndarray, Any]:
        P, Px = self.calls.surfaces[surface].project(X)
        return P.ravel(), (None if J is None else Px @ J)

    def _chatter_step(self, X: np.ndarray, JX: np.ndarray | None, Jt: np.ndarray | None,
                      t: float, seq: list[Any], events: list[SimEvent],
                      chatter_errors: list[float], surface: int = 0) -> tuple[Any, ...] | None:
        """Record the first-order chatter estimate at this impact; apply the map when its
        estimated error meets the tolerance (returns the sticking state), else None."""
        c, o = self.c, self.o
        N = c.N
        sens = JX is not None
        Q1, q1, Q1x, q1x, r, rx = self.calls.surfaces[surface].chatter(X)
        val = np.concatenate([Q1.ravel(), [t + q1.item()]])
        jac = None
        rj = None
        if sens:
            jac = np.vstack([Q1x @ JX, (Jt + q1x.ravel() @ JX)[None, :]])
            rj = rx.ravel() @ JX
        # the last slot memoises this impact's extrapolated values (extrapolate)
        seq.append([val, jac, r.item(), rj, {}])
        count = len(seq)
        if o.chatter == "cut":
            if count < o.cut_after:
                return None
            # naive baseline: a perfectly plastic K-th impact, no map, no time jump
            Xs, Js = self._project(X, JX, surface)
            seq.clear()
            events.append(SimEvent("chatter", t, Xs[: c.n].copy(), {"impacts": count,
                                                                   "cut": True},
                                   surface=surface))
            return Xs, Js, Jt, t, count
        m = o.chatter_order
        if count < m + 1:
            if count > o.max_chatter_impacts:
                raise SimulationError("chatter map never met its tolerance")
            return None
        value, vjac, prev, _ = extrapolate(seq[-(m + 1):], m)
        rr = seq[-2][2]
        w = rr ** (m + 1)
        # max norms (what np.linalg.norm(., inf) computes for a vector)
        scale = 1.0 + float(np.abs(value[:N]).max())
        err = float(np.abs(value - prev).max()) * w / (1.0 - w) / scale
        if count == m + 1:
            self._errs = []
        self._errs.append(err)
        floor_hit = False
        if o.chatter_tol < err <= 1e4 * o.chatter_tol and len(self._errs) >= 4 \
                and err >= min(self._errs[-4:-1]):
            # close to the tolerance the estimate stopped decreasing (it should shrink by
            # r^(m+1) per impact): a round-off floor (near the loss of sticking, a -> 0).
            # Continuing would resolve impacts until round-off breaks the sequence and report
            # a wrong orbit; the map is applied and the floor recorded in the event.
            floor_hit = True
        if err > o.chatter_tol and not floor_hit:
            if count > o.max_chatter_impacts:
                raise SimulationError(
                    f"chattering sequence of {count} impacts without meeting the chatter map's "
                    f"tolerance (r = {rr:.6g}; convergence slows as r -> 1)")
            return None
        Xs = value[:N]
        a_star = c.q(Xs, surface)["a"]
        if not a_star < 0:
            # sec. 5.2: no sticking after the map; keep impacting (incomplete chattering)
            if count > o.max_chatter_impacts:
                raise SimulationError("chattering ends at a >= 0: incomplete chattering with "
                                      f"more than {o.max_chatter_impacts} impacts")
            return None
        Jx = None if vjac is None else vjac[:N]
        Xs, Js = self._project(Xs, Jx, surface)
        Jts = None if vjac is None else vjac[N].copy()
        ts = float(value[N])
        chatter_errors.append(err)
        seq.clear()
        # the impact at x_k is replaced by the map: count - 1 impacts were resolved
        events.append(SimEvent("chatter", t, Xs[: c.n].copy(),
                               {"impacts": count - 1, "error_estimate": err,
                                "t_complete": ts, "error_floor": floor_hit},
                               surface=surface))
        return Xs, Js, Jts, ts, count - 1

def extrapolate(entries: list[Any], m: int) -> tuple[np.ndarray, Any, np.ndarray, Any]:
    """Richardson tableau of eq. (35) over ``m + 1`` consecutive first-order chatter estimates.

    Returns the order-``m`` value at the last impact and at the one before (for the error
    estimate), with the Jacobian of the former (the weights' dependence on ``r(x)`` included).

    Entry ``k`` is ``(value, Jacobian, r, dr/dX0[, memo])``. Level ``j`` at entry ``k``,
    ``L_j(k) = (L_{j-1}(k) - w L_{j-1}(k-1)) / (1 - w)`` with ``w = r_{k-1}^(j+1)``, depends on
    entries ``k - j ... k`` only, not on the window: an entry's ``memo`` dict keeps its levels,
    so each impact of a sequence computes its own levels once (the same operations, the same
    values as the whole tableau)."""

    def level(i: int, j: int) -> tuple[np.ndarray, Any]:
        e = entries[i]
        if j == 0:
            return e[0], e[1]
        memo = e[4] if len(e) > 4 else None
        if memo is not None and j in memo:
            return memo[j]
        v1, j1 = level(i, j - 1)
        v0, j0 = level(i - 1, j - 1)
        r, rj = entries[i - 1][2], entries[i - 1][3]
        w = r ** (j + 1)
        v = (v1 - w * v0) / (1.0 - w)
        jj = None
        if j1 is not None:
            dw = (j + 1) * r ** j * rj
            jj = (j1 - w * j0) / (1.0 - w) + np.outer((v1 - v0) / (1.0 - w) ** 2, dw)
        if memo is not None:
            memo[j] = (v, jj)
        return v, jj

    n = len(entries)
    value, vjac = level(n - 1, m - 1)
    prev, _ = level(n - 2, m - 1)
    return value, vjac, prev, None
