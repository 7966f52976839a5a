"""Event-driven simulation of an impacting system with complete chattering (sec. 5).

The discrete states of Table 1 (Fig. 5(b), :mod:`.modes`); ``s5``, ``s6`` integrate the scaled
extended state ``(x, h, u)`` of sec. 4.3 (``h = H/u``, ``u`` the latest outgoing velocity), so that
the impacts in the tail of a chattering sequence are located on ``h = 0``, an O(u) quantity,
instead of on ``H(x)``, an O(u^2) quantity swamped by round-off. This module walks through them:
the Runge-Kutta steps under error control, the watched crossings on each step
(:mod:`.hermite`), the event times on the true flow, the sensitivities; the transitions fired at
the events (impacts, the chatter map, sticking, release) are :mod:`.transitions`, what the
simulation is given and returns :mod:`.sim_data`.

**No missed double crossing.** Inside a state the impact function is monotone (``H`` decreases
in s2 because ``v < 0`` there; the state changes when ``v`` changes sign), so ``H`` is crossed
at most once per state. Sign changes of the watched functions are looked for on each accepted
step with the cubic Hermite interpolant built from the function and its exact time derivative at
both ends (``H' = v``, ``v' = a``, ``a' = jerk``, ``h' = v/u``: all CasADi Lie derivatives), so
two roots inside one step (``v`` dipping below zero and back: a near-grazing local minimum of
``H``) are both found, not only an odd number of them; the root is then refined on the true flow
by a safeguarded Newton iteration; a dip of the interpolant that the true flow does not make is
rejected by evaluating the true function at the interpolant's extremum. The interpolant's error
is ``O(dt^4)`` but not tied to the tolerance, so a shallow dip of ``H`` below the wall can be
missed by the ``H`` interpolant; it is recovered when ``v`` turns: a turn found with ``H < 0``
(``h < 0`` in s6) means an impact was passed, and since ``H`` is monotone before the turn the
impact is located in the bracket between the step start and the turn
(``tests/hybrid/test_hybrid_failures.py``, ``tests/hybrid/test_two_mass_chain.py``). What remains
possible is
a dip of ``v`` itself (``v`` turning twice) shallower than the ``v`` interpolant's error within
one step of a trajectory that stays off the wall at both ends: a grazing contact of depth below
the integration error.

**Sensitivities.** Along the way the simulator carries ``J = dX/dX0`` and ``J_t = dt/dX0``
of the event-defined trajectory: each accepted step multiplies ``J`` by the exact Jacobian of the
Runge-Kutta step; each event time ``tau`` (``g(x(tau)) = 0``) contributes
``d tau = -(g_x J) / (g_x F)``; each event map ``E`` (impact ``R``, chatter map ``Q``, time jump
``q``) contributes ``J <- E_x J``, ``J_t <- J_t + e_x J``. This is the chain (40) of flows and
saltation matrices (43) written for event-parametrised time (see :mod:`.saltation` for the
equivalence); with a fixed end time the last correction is ``J <- J - F J_t``. The step error
test covers ``J`` as well as the state (CVODES' ``errconS``, :mod:`.step_error`):
the error estimate of the variational equations integrated by a step is the derivative of the
step's own estimate, ``d err/dY @ J``; without it an orbit on which the state has no local
error (a constant amplitude) is crossed in a few long steps that integrate the transverse
contraction, and so the multipliers, far less accurately than the state
(``tests/hybrid/test_multiplier_error_control.py``).

**Exact flows** (:mod:`.linear_flow`, ``integrator: {method: exact | auto}``). A field whose
steps are an exact flow (the free flight of a system linear between events) has no integration
error to control: it gives the length of its next step itself (as long as the watched functions,
and a section on a dynamic coordinate, are certified clear of zero, else one cell over which the
cubic Hermite interpolants are accurate, :func:`.modal_sums.certified_length`), so its steps are
not checked at the midpoint; it gives the extremes of the state over a step
(:func:`.modal_sums.grid_extremes`); its event iterations run on the watched function's modal
sum (:meth:`.linear_flow.ExactStep.watched`); and since its steps compose exactly, the
sensitivity product ``J <- J_step J`` of its steps is deferred to the next event, where the
Jacobian of the flow over their total time is one evaluation (:meth:`Simulator._deferred`),
and runs on through a maximum of ``H`` (transition I: no jump, the same field; the next event's
time alone fixes the end). Runge-Kutta fields run as before, to the bit.

**Extremes when asked for.** The values of the state at the turns inside a step (steps on the
true flow, the exact flow's grid) are what the extremes of a result cost; they are left to
:attr:`.sim_data.SimResult.extremes`, computed on first use (the reported orbit), not in the
Newton iterations whose simulations nobody reports. The same values.

**Work skipped, the same numbers** (``tests/hybrid/test_simulator_shortcuts_equal_plain_code.py,
tests/hybrid/test_rk_step_functions_equal_stagewise_step.py,
tests/engine/test_bound_casadi_buffers_equal_plain_call.py`` check each against the
computation it replaces). An event iteration that repeats an iterate (Newton jittering on the
round-off of ``g``, ~8 % of the events of a long chattering sequence ran to the 30-iteration
limit) ends where the 30 iterations would have (the iteration depends on ``tau`` alone); the
iterations evaluate the probe alone. A step of a chattering flight (``s5``, ``s6``) is tried
without its Jacobian, which is evaluated only if the step is taken whole (nearly every such
step ends at an event). An interpolant whose Bernstein control points are all of one sign
(beyond its rounding) has no crossing, and a step in which no component's slope changes sign
has no interior extremum: neither is searched. Each impact computes its own extrapolation
levels once (they do not depend on the window, :func:`.transitions.extrapolate`). The Functions
are called through buffers bound once (:mod:`nsm_continuation.core.casadi_buffers`).
"""

from __future__ import annotations

import functools
import math
import time
from typing import Any

import numpy as np

from nsm_continuation.hybrid.hermite import hermite_first_root, hermite_one_sign, quadratic_roots
from nsm_continuation.hybrid.modes import (
    EXTENDED,
    S1,
    S2,
    S3,
    S4,
    S5,
    S6,
    WATCH,
    initial_state,
    initial_states,
    watches,
)
from nsm_continuation.hybrid.sim_data import SimEvent, SimOptions, SimResult, SimulationError
from nsm_continuation.hybrid.sparse_steps import SparseStep, sparse_steps
from nsm_continuation.hybrid.step_error import sensitivity_error_norm, state_error_norm
from nsm_continuation.hybrid.surfaces import SurfaceContacts
from nsm_continuation.hybrid.system import CompiledHybrid, probe_layout
from nsm_continuation.hybrid.transitions import Transitions
from nsm_continuation.hybrid.walk import _Walk

__all__ = ["EXTENDED", "S1", "S2", "S3", "S4", "S5", "S6", "WATCH", "HERMITE_CHECK_BELOW",
           "REFINE_ITERATIONS", "SimEvent", "SimOptions", "SimResult", "SimulationError",
           "Simulator", "initial_state"]


#: below this error norm a step may be far shorter than the integration needs (the flow is
#: integrated exactly): the watched functions' interpolants are then checked (Simulator.
#: _hermite_trustworthy) before the step is taken
HERMITE_CHECK_BELOW = 1e-3

#: Newton iterations of an event time on the true flow (Simulator._refine)
REFINE_ITERATIONS = 30


class Simulator(Transitions, SurfaceContacts):
    """Event-driven simulator for one compiled system (see the module docstring)."""

    def __init__(self, c: CompiledHybrid, opts: SimOptions | None = None) -> None:
        self.c = c
        #: the compiled Functions, called through their buffers
        self.calls = c.calls()
        self.o = opts or SimOptions()
        #: chatter error estimates of the current sequence (stall detection)
        self._errs: list[float] = []
        #: the fields integrated by an exact flow (:mod:`.linear_flow`): steps of their own
        #: length, extremes of their own, sensitivity products deferred to the next event
        self._exact = {k: fs[0] for k, fs in self.calls.steps.items()
                       if getattr(fs[0], "exact", False)}
        #: the Runge-Kutta fields whose step sensitivities are chained by sparse products
        #: (:mod:`.sparse_steps`), for the choice ``o.sparse_products`` they were found for
        self._sparse: dict[str, SparseStep] = {}
        self._sparse_choice: Any = "unset"

    # ------------------------------------------------------------------ helpers
    def _key(self, modes: list[str], active: int | None) -> str:
        """The field (and probe layout) integrated: ``free``, or the sticking field or the
        extended chattering field of the active surface (:func:`.system._key`)."""
        if active is None:
            return "free"
        sf = self.c.surfaces[active]
        return sf.ext_key if modes[active] in EXTENDED else sf.stick_key

    def _npr(self, key: str) -> int:
        """Length of the probe of layout ``key``."""
        return 4 * self.c.m + (2 if key.startswith("ext") else 0)

    def _step(self, key: str, Y: np.ndarray, dt: float, jac: bool) -> tuple[Any, ...]:
        """One Runge-Kutta step of length ``dt`` from ``Y`` of the field ``key``: ``(Y_new,
        err, err3, probe, field[, J, dE])`` at the step end (views into one fresh array);
        ``dE`` stacks the Jacobians ``d err / dY`` (and ``d err3 / dY``) of the error
        estimates, shape ``(k m, m)`` (None for an exact flow, which has no error)."""
        flat = self.calls.steps[key][1 if jac else 0].flat(Y, dt)
        m = Y.size
        npr = self._npr(key)
        i1, i2, i3, i4, i5 = m, 2 * m, 3 * m, 3 * m + npr, 4 * m + npr
        parts = (flat[:i1], flat[i1:i2], flat[i2:i3], flat[i3:i4], flat[i4:i5])
        if jac:
            i6 = i5 + m * m
            dE = flat[i6:].reshape(-1, m, order="F") if flat.size > i6 else None
            return (*parts, flat[i5:i6].reshape(m, m, order="F"), dE)
        return parts

    def _step_probe(self, key: str, Y: np.ndarray, dt: float) -> np.ndarray:
        """The probe (``H, v, a, jerk[, h, h']`` and the other surfaces' blocks) after one step
        of length ``dt`` from ``Y``: ``self._step(key, Y, dt, False)[3]``, without splitting
        the other outputs."""
        return self.calls.steps[key][2].flat(Y, dt)

    def _probe_field(self, key: str, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The probe and the field of layout ``key`` at ``Y``."""
        both = self.calls.probe_field[key].flat(Y)
        npr = self._npr(key)
        return both[:npr], both[npr:]

    # ------------------------------------------------------------------ main loop
    def run(self, X0: np.ndarray, t_end: float | None = None,
            section: tuple[int, float, int] | None = None, t_min_section: float = 0.0,
            max_time: float | None = None, stop_impact: int | None = None) -> SimResult:
        """Simulate from ``X0`` (state followed by freed parameters) until ``t_end`` or until
        component ``section[0]`` crosses ``section[1]`` in direction ``section[2]`` (after time
        ``t_min_section``), or (``stop_impact``) just after the first impact on that surface
        from which the flight leaves it (an impact section: the post-impact state, its
        sensitivities through the impact's saltation, ``ended_by`` "impact"). Raises
        :class:`SimulationError` with a reason on failure.

        Each pass of the loop tries one Runge-Kutta step (:meth:`_attempt`), looks for the first
        watched crossing inside it (:meth:`_first_crossing`), and either accepts the whole step
        (:meth:`_accept`) or advances to the crossing and applies the transition
        (:meth:`_fire`)."""
        w = self._begin(X0)
        t_stop = t_end if t_end is not None else max_time
        clock0 = time.perf_counter()
        while True:
            self._guard(w, clock0)
            dt = min(w.h, self.o.h_max)
            w.certified = False
            if w.key in self._exact:
                # no integration error to control: the flow says how far it may go
                if w.next_exact is not None:
                    dt, w.next_exact = w.next_exact, None
                else:
                    dt, w.next_exact, w.certified = self._exact[w.key].max_step(
                        w.Y, [wa[0] for wa in w.watch], section,
                        tuple(i for i, wa in enumerate(w.watch) if (wa[2], wa[3]) in w.just))
                if dt > self.o.h_max:
                    dt, w.next_exact = self.o.h_max, None
            last = False
            if t_stop is not None and w.t + dt >= t_stop:
                dt, last = t_stop - w.t, True
            if dt <= 0.0:
                break
            outs = self._attempt(w, dt)
            if outs is None:
                continue
            hit = self._first_crossing(w, dt, outs, section, t_min_section)
            if hit is None:
                self._accept(w, dt, outs, last)
                if last:
                    break
                continue
            impacts = w.n_imp
            if self._fire(w, dt, hit, section):
                return self._result(w, "section")
            if stop_impact is not None and w.n_imp > impacts and w.modes[stop_impact] == S1 \
                    and w.events and w.events[-1].kind == "impact" \
                    and w.events[-1].surface == stop_impact:
                return self._result(w, "impact")
        if w.defer is not None:
            w.J = self._deferred(w, 0.0) @ w.J
        if w.J is not None and t_end is not None:
            # fixed end time: t_end - t_k(X0) is the last flow time
            w.J = w.J - np.outer(w.F, w.Jt)
        return self._result(w, "time" if t_end is not None else "max_time")

    def _begin(self, X0: np.ndarray) -> _Walk:
        """The walk state at ``t = 0`` (an impact at ``t = 0`` applied if ``X0`` lies on the
        surface moving inwards)."""
        c, o = self.c, self.o
        X0 = np.asarray(X0, dtype=float).ravel()
        if X0.size != c.N:
            raise ValueError(f"initial state has {X0.size} components, expected {c.N}")
        if not np.all(np.isfinite(X0)):
            raise SimulationError("initial state is not finite")
        modes = initial_states(c, X0)
        c.mass_check(X0)
        sens = o.sensitivities
        active = next((i for i, mo in enumerate(modes) if mo == S4), None)
        w = _Walk(modes=modes, active=active, Y=X0.copy(), J=np.eye(c.N) if sens else None,
                  Jt=np.zeros(c.N) if sens else None, h=o.h_init,
                  pr=np.empty(0), F=np.empty(0),
                  lo=X0[: c.n].copy(), hi=X0[: c.n].copy(),
                  traj=[] if o.record else None,
                  stick_start=0.0 if active is not None else None)
        self._relayout(w)
        w.record()
        tiny = 1e-12 * (1.0 + np.linalg.norm(X0))
        for i in range(c.m):
            off = w.offsets[i]
            if modes[i] in (S1, S2) and abs(w.pr[off + 1]) <= tiny:
                # a start at a turning point of H (v = 0 to round-off, e.g. a maximum on a
                # stroboscopic section): v is "just fired", so its sign cannot hide the turn
                # (the floor of the v watch would not see v falling from +1e-14); a decides,
                # the jerk where a vanishes too (a start at rest where the force balances,
                # e.g. the forced oscillator's (gap + 1, 0) at phase 0), and otherwise the
                # approach: its watches (the impact, the turn of v) see a flight moving away
                # too, not conversely
                a, jerk = float(w.pr[off + 2]), float(w.pr[off + 3])
                modes[i] = S1 if (a > tiny or (abs(a) <= tiny and jerk > tiny)) else S2
                w.just.add(("v", i))
        self._relayout(w, probe=False)
        for i in range(c.m):
            if w.modes[i] == S2 and abs(w.pr[w.offsets[i]]) <= tiny:
                # a start on the surface moving inwards: the impact happens at t = 0
                self._apply_transition(w, "H", w.pr, i)
        return w

    def _relayout(self, w: _Walk, probe: bool = True) -> None:
        """After a change of the surfaces' states: the field integrated, the watched
        functions, the probe offsets and (``probe``) the probe and field at ``w.Y``."""
        w.key = self._key(w.modes, w.active)
        w.watch = watches(w.modes, w.active)
        w.next_exact = None
        w.offsets = probe_layout(self.c.m, w.active, w.key != "free" and w.mode in EXTENDED)
        if probe:
            w.pr, w.F = self._probe_field(w.key, w.Y)

    def _guard(self, w: _Walk, clock0: float) -> None:
        """The wall-clock, simulated-time and event-count guards (never a hang)."""
        o = self.o
        w.n_steps += 1
        if w.n_steps % 256 == 0 and time.perf_counter() - clock0 > o.wall_time:
            raise SimulationError(f"wall-clock guard: {o.wall_time:g} s exceeded at t = "
                                  f"{w.t:.6g} after {len(w.events)} events")
        if o.max_time is not None and w.t > o.max_time:
            raise SimulationError(f"time limit: no end condition (section or end time) "
                                  f"reached by t = {o.max_time:g} (state {w.mode})")
        if len(w.events) > o.max_events:
            raise SimulationError(f"more than {o.max_events} events (t = {w.t:.6g})")

    def _attempt(self, w: _Walk, dt: float) -> tuple[Any, ...] | None:
        """One Runge-Kutta step of length ``dt`` under error control: its outputs
        ``(Y_new, err, err3, probe, field, J or None, dE or None, J_step w.J or None, error
        norm)``, or None (rejected; ``w.h`` shrunk).

        In a chattering flight (``s5``, ``s6``) nearly every step ends at an event (the turn of
        ``v``, the next impact), whose sensitivities come from the step to the event
        (:meth:`_refine`): the step's Jacobian (four times the cost of the step) is then left
        to :meth:`_accept`, which evaluates it only for a step taken whole (the same
        ``Y_new``: both are the same CasADi expressions,
        ``tests/hybrid/test_rk_step_functions_equal_stagewise_step.py``).
        """
        exact = w.key in self._exact
        jac = w.J is not None and w.mode not in EXTENDED and not exact
        outs = self._step(w.key, w.Y, dt, jac)
        if not jac:
            outs = (*outs, None, None)
        Yn = outs[0].ravel()
        o = self.o
        en = 0.0 if exact else state_error_norm(w.Y, Yn, outs[1], outs[2], o.rtol, o.atol,
                                                self.c.method == "dop853")
        Jn = None
        if jac and o.sensitivity_error and outs[6] is not None and math.isfinite(en):
            Jn = self._chain(w.key, outs[5], w.J)
            en = max(en, sensitivity_error_norm(w.J, Jn, outs[6], o.rtol, o.atol))
        if not math.isfinite(en) or not np.isfinite(Yn).all():
            w.h = dt * 0.2
            if w.h < 1e-15 * (1 + abs(w.t)):
                raise SimulationError(f"non-finite state at t = {w.t:.6g}")
            return None
        if en > 1.0:
            w.h = dt * max(0.2, 0.9 * en ** (-1.0 / (self.c.order + 1)))
            if w.h < 1e-14 * (1 + abs(w.t)):
                raise SimulationError(f"step size underflow at t = {w.t:.6g}")
            return None
        if en < HERMITE_CHECK_BELOW and not exact and not self._hermite_trustworthy(w, dt, outs):
            w.h = dt * 0.25
            return None
        return (*outs, Jn, en)

    def _hermite_trustworthy(self, w: _Walk, dt: float, outs: tuple[Any, ...]) -> bool:
        """Whether the cubic Hermite interpolants of the watched functions over a step whose
        error estimate is tiny still describe them: checked against the true flow at the
        midpoint. The error estimate controls the state, not the functions of it that are
        watched: where the flow is integrated exactly (sticking on a wall while only the
        forcing clock moves, ``a = cos(phase)``) it is zero, the step grows fivefold per step,
        and a step spanning a whole oscillation of ``a`` would hide the release (the
        stroboscopic oscillator at omega ~ 0.357 then stuck to the wall for ever)."""
        mid = self._step_probe(w.key, w.Y, 0.5 * dt)
        prn = outs[3].ravel()
        for idx, _direction, _name, _surface in w.watch:
            g0, d0, g1, d1 = w.pr[idx], w.pr[idx + 1] * dt, prn[idx], prn[idx + 1] * dt
            p_mid = 0.5 * (g0 + g1) + 0.125 * (d0 - d1)
            scale = abs(g0) + abs(g1) + 0.25 * (abs(d0) + abs(d1))
            if abs(mid[idx] - p_mid) > 0.05 * scale + 1e-14:
                return False
        return True

    def _first_crossing(self, w: _Walk, dt: float, outs: tuple[Any, ...],
                        section: tuple[int, float, int] | None, t_min_section: float
                        ) -> tuple[float, str, int, int, int] | None:
        """First watched crossing in the step (cubic Hermite, both roots of a dip):
        ``(s, name, index, direction, surface)`` with ``s`` the fraction of the step, or
        None."""
        key, Y = w.key, w.Y
        # Python floats: the same arithmetic as on the arrays' elements, faster
        pr, prn = w.pr.tolist(), outs[3].tolist()
        best: tuple[float, str, int, int, int] | None = None
        fdt = float(dt)
        # (a step of an exact flow certified clear of the watched functions' zeros has none)
        for idx, direction, name, surface in ([] if w.certified else w.watch):
            # the function that just fired is exactly zero at the step start (its round-off
            # sign must not fire it again): its derivative decides
            g0 = 0.0 if (name, surface) in w.just else pr[idx]
            if hermite_one_sign(g0, pr[idx + 1] * fdt, prn[idx], prn[idx + 1] * fdt):
                continue  # no crossing (what hermite_first_root would find first)
            floor = 0.0 if name in ("H", "h") else 1e-13 * (
                1.0 + abs(pr[idx]) + abs(prn[idx]) + dt * (abs(pr[idx + 1]) + abs(prn[idx + 1])))

            def verify(sx: float, d: int, idx: int = idx) -> bool:
                gv = self._step_probe(key, Y, sx * dt)[idx]
                return gv < 0 if d < 0 else gv > 0

            s = hermite_first_root(g0, pr[idx + 1], prn[idx], prn[idx + 1], dt, direction,
                                    floor, verify)
            if s is not None and (best is None or s < best[0]):
                best = (s, name, idx, direction, surface)
        if section is not None and w.t + dt > t_min_section:
            k, val, sd = section
            s = hermite_first_root(Y[k] - val, w.F[k], outs[0][k] - val, outs[4][k], dt, sd)
            if s is not None and (best is None or s < best[0]):
                best = (s, "section", k, sd, -1)
        return best

    def _accept(self, w: _Walk, dt: float, outs: tuple[Any, ...], last: bool) -> None:
        """Take the whole step (no crossing inside it) and choose the next step size."""
        Yn, prn, Fn, en = outs[0].ravel(), outs[3].ravel(), outs[4].ravel(), outs[-1]
        w.just = set()
        if w.J is not None and w.key in self._exact:
            _key, Y0, T = w.defer if w.defer is not None else (w.key, w.Y, 0.0)
            w.defer = (w.key, Y0, T + dt)
        elif w.J is not None:
            if outs[7] is not None:
                # chained already for the sensitivities' error test (_attempt)
                w.J = outs[7]
            else:
                Jstep = outs[5] if outs[5] is not None else self._step(w.key, w.Y, dt, True)[5]
                w.J = self._chain(w.key, Jstep, w.J)
        self._extend_extremes(w, w.Y, w.F, Yn, Fn, dt)
        w.Y, w.pr, w.F = Yn, prn, Fn
        w.t += dt
        w.record()
        if not last:
            w.h = dt * (5.0 if en == 0 else
                        min(5.0, max(0.2, 0.9 * en ** (-1.0 / (self.c.order + 1)))))

    def _extend_extremes(self, w: _Walk, Y0: np.ndarray, F0: np.ndarray, Y1: np.ndarray,
                         F1: np.ndarray, dt: float) -> None:
        """Extremes of each state component over the flow step from ``Y0`` to ``Y1`` (field
        ``w.key``): the ends, and where a component's slope changes sign inside the step, its
        value on the true flow at the extremum of the cubic Hermite interpolant (ends and
        slopes ``F``). The location error ``ds`` of the interpolant costs ``O(ds^2)`` in the
        value: the extremes are exact to about the integration tolerance."""
        exact = self._exact.get(w.key)
        if exact is not None:
            # the exact flow's own, on a grid as fine as these interpolants need, found when
            # the result's extremes are first asked for (SimResult.extremes); a step that goes
            # on from the end of the last one (no jump between: the flow composes) extends it
            runs = w.deferred_extremes
            if runs and w.extremes_end is Y0 and runs[-1][0] == exact.extremes:
                runs[-1] = (exact.extremes, runs[-1][1], runs[-1][2] + dt)
            else:
                runs.append((exact.extremes, Y0, dt))
            w.extremes_end = Y1
            return
        n = self.c.n
        a, b = Y0[:n], Y1[:n]
        np.minimum(w.lo, np.minimum(a, b), out=w.lo)
        np.maximum(w.hi, np.maximum(a, b), out=w.hi)
        # the slopes' signs in Python floats first (the same products as on the arrays): most
        # steps have no component turning inside them
        fdt = float(dt)
        turning = [i for i, (f0, f1) in enumerate(zip(F0[:n].tolist(), F1[:n].tolist(),
                                                     strict=True))
                   if (f0 * fdt) * (f1 * fdt) < 0]
        if not turning:
            return
        # the values at the turns need steps on the true flow: found when the result's
        # extremes are first asked for (SimResult.extremes), not in every Newton iteration
        w.deferred_extremes.append(
            (functools.partial(self._turn_extremes, w.key, F0, Y1, F1, turning), Y0, dt))

    def _turn_extremes(self, key: str, F0: np.ndarray, Y1: np.ndarray, F1: np.ndarray,
                       turning: list[int], Y0: np.ndarray, dt: float
                       ) -> tuple[np.ndarray, np.ndarray]:
        """The extremes of the components ``turning`` inside the Runge-Kutta step of the field
        ``key`` from ``Y0`` to ``Y1`` (:meth:`_extend_extremes`): ``(lo, hi)`` over the system's
        components, infinite for the others."""
        n = self.c.n
        lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
        a, b = Y0[:n], Y1[:n]
        m0, m1 = F0[:n] * dt, F1[:n] * dt
        for i in turning:
            # p(s) = a + m0 s + c2 s^2 + c3 s^3 on [0, 1]; p'(s) = 0 between the ends
            c2 = -3 * a[i] - 2 * m0[i] + 3 * b[i] - m1[i]
            c3 = 2 * a[i] + m0[i] - 2 * b[i] + m1[i]
            roots = quadratic_roots(3 * c3, 2 * c2, m0[i]) if c3 != 0 else np.array(
                [-m0[i] / (2 * c2)] if c2 != 0 else [])
            for r in roots:
                if abs(r.imag) < 1e-14 and 0.0 < r.real < 1.0:
                    sr = r.real
                    out = self._step(key, Y0, sr * dt, False)
                    curv = 2 * c2 + 6 * c3 * sr
                    if curv != 0.0:
                        # one Newton step on the true slope: the value is then exact to
                        # O(ds^4) instead of O(ds^2)
                        s1 = sr - float(out[4][i]) * dt / curv
                        if 0.0 < s1 < 1.0:
                            out = self._step(key, Y0, s1 * dt, False)
                    v = float(out[0][i])
                    lo[i] = min(lo[i], v)
                    hi[i] = max(hi[i], v)
        return lo, hi

    def _fire(self, w: _Walk, dt: float, hit: tuple[float, str, int, int, int],
              section: tuple[int, float, int] | None) -> bool:
        """Advance to the crossing ``hit`` located on the true flow, chain its saltation into
        the sensitivities and apply its transition; True when it is the section (the end)."""
        key, Y, pr = w.key, w.Y, w.pr
        s, name, idx, _direction, surface = hit
        tau, Ye, pre, Fe, Jstep = self._refine(key, Y, dt, s * dt, name, idx, section)
        # the turn of v (or the section) came after an impact function went negative: an
        # impact inside a dip the interpolant of H (or h) did not resolve (or placed after the
        # section). H (h) is monotone before the turn, so [0, tau] brackets exactly one impact.
        # (any approaching surface: the turn that fired may be a parallel surface's, e.g. the
        # other wall of a cavity, whose v turns with this one's)
        candidates = ([j for j, mo in enumerate(w.modes) if mo in (S2, S6)]
                      if name in ("v", "section") else [])
        for j in candidates:
            hi_, hn = (w.offsets[j], "H") if w.modes[j] == S2 else (4, "h")
            if pre[hi_] < 0 <= pr[hi_]:
                name, idx, surface = hn, hi_, j
                tau, Ye, pre, Fe, Jstep = self._refine(
                    key, Y, tau, tau * pr[hi_] / (pr[hi_] - pre[hi_]), name, idx, section)
                break
        if section is not None and name != "section":
            # the refined crossing may lie past the section (an event within round-off of
            # it, e.g. a turning point of q on a stroboscopic section): the section comes first
            k, val, sd = section
            a0, a1 = sd * (Y[k] - val), sd * (Ye[k] - val)
            if a0 < 0 <= a1:
                name, idx, surface = "section", k, -1
                tau, Ye, pre, Fe, Jstep = self._refine(key, Y, tau, tau * a0 / (a0 - a1),
                                                       name, idx, section)
        if w.J is not None and key in self._exact and name == "v" and self.c.m == 1 \
                and w.modes[surface] == S1:
            # transition I (a maximum of H): no jump, the same field on: the flow composes
            # through it and the next event's time alone fixes the end (its event-time
            # correction would cancel there), so the deferred product runs on
            _key, Y0, T = w.defer if w.defer is not None else (key, Y, 0.0)
            w.defer = (key, Y0, T + tau)
        elif w.J is not None:
            if key in self._exact:
                Jstep = self._deferred(w, tau)
            Je = Jstep @ w.J if key in self._exact else self._chain(key, Jstep, w.J)
            gx = self._gx(name, idx, Ye, surface)
            dtau = -(gx @ Je) / (gx @ Fe)
            w.J = Je + np.outer(Fe, dtau)
            w.Jt = w.Jt + dtau
        self._extend_extremes(w, Y, w.F, Ye, Fe, tau)
        w.Y, w.t = Ye, w.t + tau
        w.record()
        if name == "section":
            w.events.append(SimEvent("section", w.t, w.Y[: self.c.n].copy()))
            return True
        self._apply_transition(w, name, pre, surface)
        return False

    def _apply_transition(self, w: _Walk, name: str, pre: np.ndarray, surface: int,
                          coincident: bool = True) -> None:
        """Apply the transition of ``name`` on ``surface`` in its current state
        (:meth:`_transition`) and keep the walk's bookkeeping (impacts, sticking intervals,
        the surfaces' states, next step size). An impact on another surface than the one that
        sticks or chatters, or on another part of the same surface than the chattering
        sequence's (:meth:`_same_contact`), first ends that sequence (:meth:`_break_chatter`)."""
        pre_s = pre[w.offsets[surface]:]
        if name == "H" and w.active is not None and surface != w.active:
            self._break_chatter(w, surface)
        elif name == "h" and not self._same_contact(w):
            self._break_chatter(w, surface)
            name = "H"
        if name == "H":
            self._check_single_contact(w, surface)
        mode = w.modes[surface]
        newmode, w.Y, w.J, w.Jt, w.t, info = self._transition(
            mode, name, w.Y, w.J, w.Jt, w.t, pre_s, w.seq, w.events, w.chatter_errors, surface)
        if info.get("impact_velocity") is not None:
            w.n_imp += 1
            w.vmin = min(w.vmin, info["impact_velocity"])
        if info.get("near_approach") is not None:
            w.graze = min(w.graze, info["near_approach"])
            w.margins.append(info["near_approach"])
            w.margin_surfaces.append(surface)
        if info.get("chatter_count") is not None:
            w.chatter_counts.append(info["chatter_count"])
        if mode == S4 and newmode != S4 and w.stick_start is not None:
            w.stick_iv.append((w.stick_start, w.t))
            w.stick_start = None
        if newmode == S4 and mode != S4:
            w.stick_start = w.t
        if newmode == S5 and mode == S2:
            w.seq_normal = self._contact_normal(w.Y, surface)
        w.record()
        w.modes[surface] = newmode
        if newmode in (S4, S5, S6):
            w.active = surface
        elif w.active == surface:
            w.active = None
        w.just = {(name, surface)}
        self._relayout(w)
        if name in ("H", "h") and self.c.m > 1:
            self._reclassify_others(w, surface)
        if name == "v" and coincident and self.c.m > 1:
            self._coincident_turns(w, surface)
        if newmode in EXTENDED and name in ("H", "h"):
            # next flight lasts about 2u/|a| (constant acceleration)
            u, a = w.Y[self.c.N + 1], w.pr[2]
            w.h = min(max(2.0 * u / max(abs(a), 1e-300), 1e-300), max(w.h, 1e-300)) * 1.05

    def _result(self, w: _Walk, ended_by: str) -> SimResult:
        N = self.c.N
        if w.mode == S4 and w.stick_start is not None:
            # a sticking phase open at the end (the section or the end time) counts up to it
            w.stick_iv.append((w.stick_start, w.t))
            w.stick_start = None
        return SimResult(
            X=w.Y[:N].copy(), t=w.t, J=None if w.J is None else w.J[:N].copy(),
            Jt=None if w.Jt is None else w.Jt.copy(), events=w.events, state=w.mode,
            sticking_intervals=w.stick_iv, chatter_counts=w.chatter_counts, n_impacts=w.n_imp,
            min_impact_velocity=float(w.vmin), grazing_margin=float(w.graze),
            chatter_errors=w.chatter_errors, trajectory=w.traj, n_steps=w.n_steps,
            ended_by=ended_by, bounds=np.column_stack([w.lo, w.hi]),
            deferred_extremes=w.deferred_extremes,
            grazing_margins=list(w.margins), grazing_surfaces=list(w.margin_surfaces),
            surface_names=None if self.c.m == 1 else [sf.name for sf in self.c.surfaces])

    def _chain(self, key: str, Jstep: np.ndarray, J: np.ndarray) -> np.ndarray:
        """``J_step J``: the sensitivities chained through one step of the field ``key``, by a
        sparse product for the fields of :mod:`.sparse_steps`, else dense."""
        if self._sparse_choice != self.o.sparse_products:
            self._sparse_choice = self.o.sparse_products
            c = self.c
            keys = [k for k in c.steps if k not in self._exact]
            self._sparse = sparse_steps(
                {k: c.steps[k] for k in keys},
                {k: c.N + (2 if k.startswith("ext") else 0) for k in keys},
                {k: 4 * (c.N + (2 if k.startswith("ext") else 0)) + self._npr(k)
                 for k in keys}, self.o.sparse_products)
        sparse = self._sparse.get(key)
        return Jstep @ J if sparse is None else sparse.chain(Jstep, J)

    def _deferred(self, w: _Walk, tau: float) -> np.ndarray:
        """The Jacobian of an exact flow from the start of the steps deferred since the last
        event (or from ``w.Y``) over their time and ``tau`` more: one evaluation instead of a
        product per step (the flow composes, ``Phi(a) Phi(b) = Phi(a + b)``,
        :mod:`.linear_flow`). Clears the deferral."""
        key, Y0, T = w.defer if w.defer is not None else (w.key, w.Y, 0.0)
        w.defer = None
        return self._exact[key].jacobian(Y0, T + tau)

    def _gx(self, name: str, idx: int, Y: np.ndarray, surface: int) -> np.ndarray:
        """Gradient of the event function ``name`` of ``surface`` with respect to the
        (extended) state."""
        N = self.c.N
        g = np.zeros(Y.size)
        if name == "section":
            g[idx] = 1.0
        elif name == "h":
            g[N] = 1.0
        else:
            row = {"H": 0, "v": 1, "a": 2}[name]
            g[:N] = self.calls.surfaces[surface].grads(Y[:N])[row]
        return g

    def _event_function(self, key: str, Y: np.ndarray, tau0: float, name: str, idx: int,
                        section: tuple[int, float, int] | None) -> Any:
        """``tau -> (g, g')``: the event function ``name`` (probe entry ``idx``, or the
        section's coordinate minus its value) and its time derivative after a step of length
        ``tau`` from ``Y`` of the field ``key``. Along an exact flow a probe entry is its
        modal sum (:meth:`.linear_flow.ExactStep.watched`: the same closed form, without the
        state and the probe's CasADi call) where there is one."""
        exact = self._exact.get(key)
        first = exact.watched(Y, tau0, idx) if exact is not None and name != "section" else None
        if first is not None:
            # (the first iterate is tau0: its value is the one just computed)
            return lambda tau: first if tau == tau0 else exact.watched(Y, tau, idx)
        if name == "section":
            # the state and the field after the step
            state = self.calls.steps[key][0].flat
            idg = 3 * Y.size + self._npr(key) + idx
            off = section[1] if section is not None else 0.0

            def at_section(tau: float) -> tuple[float, float]:
                flat = state(Y, tau)
                return flat[idx] - off, flat[idg]
            return at_section
        # the probe after the step: the watched function and its time derivative
        probe = self.calls.steps[key][2].flat

        def watched(tau: float) -> tuple[float, float]:
            flat = probe(Y, tau)
            return flat[idx], flat[idx + 1]
        return watched

    def _refine(self, key: str, Y: np.ndarray, dt: float, tau0: float, name: str, idx: int,
                section: tuple[int, float, int] | None) -> tuple[Any, ...]:
        """Event time on the true flow: safeguarded Newton from the Hermite root ``tau0``.

        ``g(tau)`` is the watched function after one RK step of length ``tau`` from ``Y`` (field
        ``key``, under error control, since ``tau <= dt``); ``g'(tau)`` its exact time
        derivative there. The Jacobian of an exact flow's step is left to the caller
        (:meth:`_deferred`)."""
        sens = self.o.sensitivities and key not in self._exact
        sample = self._event_function(key, Y, tau0, name, idx, section)
        lo, hi = 0.0, dt
        tau = tau0
        # the iteration is a function of tau alone: once an iterate repeats (Newton jittering
        # on the round-off of g), the iterate the loop would end on is known from the cycle
        seen: dict[float, int] = {}
        taus: list[float] = []
        for k in range(REFINE_ITERATIONS):
            i = seen.get(tau)
            if i is not None:
                tau = taus[i + (REFINE_ITERATIONS - i) % (k - i)]
                break
            seen[tau] = k
            taus.append(tau)
            g, dg = sample(tau)
            if g == 0.0:
                break
            step_ = -g / dg if dg != 0.0 else 0.0
            new = tau + step_
            # keep inside the step; bisect towards the Hermite root otherwise
            if not (0.0 < new <= dt) or not math.isfinite(new):
                new = 0.5 * (tau + (lo if step_ < 0 else hi))
            if abs(new - tau) <= 4e-16 * max(1.0, tau) + 1e-300:
                tau = new
                break
            tau = new
        out = self._step(key, Y, tau, sens)
        Ye, pre, Fe = out[0].ravel(), out[3].ravel(), out[4].ravel()
        return tau, Ye, pre, Fe, (out[5] if sens else None)
