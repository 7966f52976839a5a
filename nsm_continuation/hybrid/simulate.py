"""Event-driven simulation of an impacting system with complete chattering (sec. 5).

Discrete states (Table 1, Fig. 5(b)); ``s5``, ``s6`` integrate the scaled extended state
``(x, h, u)`` of sec. 4.3 (``h = H/u``, ``u`` the latest outgoing velocity), so that the impacts
in the tail of a chattering sequence are located on ``h = 0``, an O(u) quantity, instead of on
``H(x)``, an O(u^2) quantity swamped by round-off:

====  =====================================  ===============================================
s1    free flight, ``v > 0``                 watch ``v`` falling through 0 (I -> s2)
s2    free flight, ``v < 0``                 watch ``H`` falling through 0 (impact: III, IV, V)
                                             and ``v`` rising through 0 (II -> s1)
s3    free flight after release, ``a > 0``   watch ``a`` falling through 0 (XII -> s1)
s4    sticking on ``F'`` (eq. 10)            watch ``a`` rising through 0 (release, XI -> s3)
s5    chattering flight, ``v > 0``           watch ``v`` falling (VI -> s6), ``a`` rising
                                             (VIII: chattering broken, -> s1)
s6    chattering flight, ``v < 0``           watch ``h`` falling (VII: impact, or IX: chatter
                                             map -> s4), ``v`` rising (X -> s1)
====  =====================================  ===============================================

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
(``tests/test_hybrid_failures.py``, ``tests/test_two_mass_chain.py``). What remains possible is
a dip of ``v`` itself (``v`` turning twice) shallower than the ``v`` interpolant's error within
one step of a trajectory that stays off the wall at both ends: a grazing contact of depth below
the integration error.

**Sensitivities.** Along the way the simulator carries ``J = dX/dX0`` and ``J_t = dt/dX0``
of the event-defined trajectory: each accepted step multiplies ``J`` by the exact Jacobian of the
Runge-Kutta step; each event time ``tau`` (``g(x(tau)) = 0``) contributes
``d tau = -(g_x J) / (g_x F)``; each event map ``E`` (impact ``R``, chatter map ``Q``, time jump
``q``) contributes ``J <- E_x J``, ``J_t <- J_t + e_x J``. This is the chain (40) of flows and
saltation matrices (43) written for event-parametrised time (see :mod:`.saltation` for the
equivalence); with a fixed end time the last correction is ``J <- J - F J_t``.

**Chatter map** (secs. 3.3, 3.4, 5.2): at each impact ``k`` of a chattering sequence (the
pre-impact state ``x_k``) the first-order map gives ``E_k = (Q(x_k), t_k + q(x_k))``. Order ``m``
combines ``m`` consecutive values by the extrapolation of eq. (35), repeated
(``L_j(k) = (L_{j-1}(k) - r^{j+1} L_{j-1}(k-1)) / (1 - r^{j+1})``), and its error is estimated
from one more impact, ``|L(k) - L(k-1)| r^{m+1} / (1 - r^{m+1})``. The map is applied when the
estimate is below ``chatter_tol`` and ``a < 0`` at the image (sec. 5.2); the image is projected
onto ``{H = 0, v = 0}`` (an ``O(v^2)`` move, below the map's own error) so that sticking starts
exactly on the sticking set.

**Work skipped, the same numbers** (issue 13, session 9; ``tests/test_speed_chatter_*.py``
check each against the computation it replaces). An event iteration that repeats an iterate
(Newton jittering on the round-off of ``g``, ~8 % of the events of a long chattering sequence
ran to the 30-iteration limit) ends where the 30 iterations would have (the iteration depends
on ``tau`` alone); the iterations evaluate the probe alone. A step of a chattering flight
(``s5``, ``s6``) is tried without its Jacobian, which is evaluated only if the step is taken
whole (nearly every such step ends at an event). An interpolant whose Bernstein control points
are all of one sign (beyond its rounding) has no crossing, and a step in which no component's
slope changes sign has no interior extremum: neither is searched. Each impact computes its own
extrapolation levels once (they do not depend on the window, :func:`_extrapolate`). The
Functions are called through buffers bound once (:mod:`nsm_continuation.core.casadi_buffers`).
Together: the 204-point continuation in ``e`` of ``benchmarks/bench_chatter.py`` 27.2 -> 13.4 s,
its CSV and report bit for bit the same.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nsm_continuation.hybrid.system import CompiledHybrid

S1, S2, S3, S4, S5, S6 = "s1", "s2", "s3", "s4", "s5", "s6"
EXTENDED = (S5, S6)
#: watched functions per state: (probe index, direction, name); probe = (H, v, a, jerk[, h, h'])
WATCH: dict[str, list[tuple[int, int, str]]] = {
    S1: [(1, -1, "v")],
    S2: [(0, -1, "H"), (1, +1, "v")],
    S3: [(2, -1, "a")],
    S4: [(2, +1, "a")],
    S5: [(1, -1, "v"), (2, +1, "a")],
    S6: [(4, -1, "h"), (1, +1, "v")],
}


#: below this error norm a step may be far shorter than the integration needs (the flow is
#: integrated exactly): the watched functions' interpolants are then checked (Simulator.
#: _hermite_trustworthy) before the step is taken
HERMITE_CHECK_BELOW = 1e-3

#: Newton iterations of an event time on the true flow (Simulator._refine)
REFINE_ITERATIONS = 30


class SimulationError(RuntimeError):
    """A simulation that cannot go on; ``reason`` is recorded by callers (never a hang)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass
class SimOptions:
    """Tolerances and guards of one simulation."""

    rtol: float = 1e-10
    atol: float = 1e-12
    h_init: float = 1e-3
    h_max: float = np.inf
    #: tolerance on the chatter map's estimated error (scaled by 1 + |x|, sec. 3.4)
    chatter_tol: float = 1e-10
    #: 1: eqs. (30)-(31); 2: the improved estimate of eq. (35); 3: one more extrapolation level
    chatter_order: int = 3
    #: "map": the chatter map; "cut": the naive baseline that stops the sequence after
    #: ``cut_after`` impacts by a perfectly plastic impact (no map)
    chatter: str = "map"
    cut_after: int = 20
    #: a chattering sequence longer than this without meeting the tolerance is a failure
    max_chatter_impacts: int = 2000
    max_events: int = 200_000
    #: wall-clock guard (seconds) on every simulation
    wall_time: float = 30.0
    #: simulated-time guard: a return to a section that takes longer fails (e.g. an orbit
    #: trapped at a stable equilibrium on the sticking surface)
    max_time: float | None = None
    sensitivities: bool = True
    record: bool = False
    #: validate r and W at every impact (sec. 2.3-2.4)
    validate: bool = True


@dataclass
class SimEvent:
    kind: str
    t: float
    x: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class SimResult:
    X: np.ndarray
    t: float
    J: np.ndarray | None
    Jt: np.ndarray | None
    events: list[SimEvent]
    state: str
    sticking_intervals: list[tuple[float, float]]
    chatter_counts: list[int]
    n_impacts: int
    min_impact_velocity: float
    grazing_margin: float
    chatter_errors: list[float]
    trajectory: list[tuple[float, np.ndarray]] | None
    n_steps: int
    ended_by: str
    #: ``(n, 2)``: minimum and maximum of each state component over the simulated trajectory
    #: (step ends, events and the interior extrema of each step's cubic Hermite interpolant)
    extremes: np.ndarray | None = None
    #: signed grazing margin of every near approach (its ``H_min > 0``) and of every impact
    #: with ``a > 0`` (``-v^2 / (2a) < 0``: where the free flight continued through the wall
    #: would turn), in time order; each crosses zero where that approach becomes an impact
    grazing_margins: list[float] = field(default_factory=list)

    def grazing_function(self, separation: float = 4.0) -> float:
        """The signed grazing margin closest to zero, a continuous function of the orbit that
        vanishes at a grazing (smooth in the parameter: ``-v^2/(2a)`` is linear in the depth
        where ``v`` has the square-root singularity). NaN if there is none, or if a margin of
        the opposite sign lies within ``separation`` times its distance to zero (the closest
        one could then switch sides without any grazing: no event is raised on it)."""
        m = np.asarray(self.grazing_margins, dtype=float)
        m = m[np.isfinite(m)]
        if not m.size:
            return float("nan")
        k = int(np.argmin(np.abs(m)))
        g = float(m[k])
        rivals = m[np.sign(m) != np.sign(g)]
        if rivals.size and np.min(np.abs(rivals)) < separation * abs(g):
            return float("nan")
        return g

    @property
    def sticking_time(self) -> float:
        return float(sum(b - a for a, b in self.sticking_intervals))

    @property
    def n_impacts_before_chatter(self) -> int:
        return int(sum(self.chatter_counts))

    @property
    def signature(self) -> str:
        """The sequence of events over the simulated time, in a structural notation that does
        not depend on tolerances: ``I`` an impact (each impact of a chattering sequence that
        breaks off counts), ``C`` a chattering sequence completed by the chatter map (an
        accumulation of impacts ending in sticking: how many impacts were resolved before the
        map is a numerical choice, ``chatter_counts``), ``S`` a release from sticking.

        Impacts just before a completed sequence are part of it (``IIC`` is ``C``).
        E.g. ``I``: one impact per period; ``II``: two; ``CS``: complete chattering, sticking
        and release (Fig. 2); ``-``: no event (a free orbit)."""
        out: list[str] = []
        for ev in self.events:
            if ev.kind == "impact":
                out.append("I")
            elif ev.kind in ("chatter", "chatter_broken"):
                # the sequence began with the impact recorded last
                if out and out[-1] == "I":
                    out.pop()
                out.append("C" if ev.kind == "chatter" else "I" * int(ev.info["impacts"]))
            elif ev.kind == "release":
                out.append("S")
        # impacts resolved one by one just before an accumulation belong to it: whether the
        # first of them already starts the geometric sequence (a < 0 at it) or bounces once
        # more (a > 0) is no structural change of the orbit (it happens smoothly, at a = 0)
        return re.sub(r"I+C", "C", "".join(out)) or "-"


def initial_state(c: CompiledHybrid, X: np.ndarray) -> str:
    """Discrete state of a point (free flight up/down, or sticking)."""
    H, v, a, _ = c.calls().probe(X).ravel()
    scale = 1e-12 * (1.0 + np.linalg.norm(X))
    if H < -scale:
        raise SimulationError(
            f"initial state on the inadmissible side of the impact surface (H = {H:.3g} < 0)")
    if abs(H) <= scale and abs(v) <= scale:
        return S4 if a < 0 else S3
    if v > 0 or (v == 0 and a > 0):
        return S1
    return S2


def _hermite_one_sign(g0: float, m0: float, g1: float, m1: float) -> bool:
    """Whether the cubic Hermite interpolant with values ``g0``, ``g1`` and slopes ``m0``,
    ``m1`` (per unit of ``s``) keeps one strict sign on ``[0, 1]``, with room for the rounding
    of its evaluation: then :func:`_hermite_first_root` finds no crossing.

    Its Bernstein control points ``g0, g0 + m0/3, g1 - m1/3, g1`` enclose it on ``[0, 1]``;
    all beyond ``1e-13`` of the data's size (the evaluation's rounding is below ``1e-14`` of
    it; ``1e-300`` covers the absolute rounding of subnormal values), no value at any knot can
    reach zero or the other side. NaN or infinite data: False."""
    b1, b2 = g0 + m0 / 3.0, g1 - m1 / 3.0
    margin = 1e-13 * (abs(g0) + abs(g1) + abs(m0) + abs(m1)) + 1e-300
    return min(g0, g1, b1, b2) > margin or max(g0, g1, b1, b2) < -margin


def _hermite_first_root(g0: float, d0: float, g1: float, d1: float, dt: float,
                        direction: int, floor: float = 0.0,
                        verify: Any = None) -> float | None:
    """First ``s`` in ``(0, 1]`` where the cubic Hermite interpolant of ``g`` crosses zero in
    ``direction`` (``-1`` falling, ``+1`` rising); both roots of a dip inside the step count.

    ``floor`` is a hysteresis for functions known only to round-off near zero (``v`` hovering
    at 1e-14 on a degenerate tangency): a crossing counts only from a value beyond it. A crossing
    inside the step with both step ends on the same side (a dip) is confirmed on the true flow by
    ``verify(s, direction)`` at the interpolant's extremum before it counts."""
    # Python floats: the same IEEE operations as on numpy scalars, several times faster
    g0, g1, dt = float(g0), float(g1), float(dt)
    m0, m1 = float(d0) * dt, float(d1) * dt
    if _hermite_one_sign(g0, m0, g1, m1):
        return None
    # p(s) = c0 + c1 s + c2 s^2 + c3 s^3
    c0, c1 = g0, m0
    c2 = -3 * g0 - 2 * m0 + 3 * g1 - m1
    c3 = 2 * g0 + m0 - 2 * g1 + m1
    knots = [0.0]
    if c3 != 0.0:
        disc = c2 * c2 - 3 * c3 * c1
        if disc >= 0:
            sq = math.sqrt(disc)
            knots += sorted(s for s in ((-c2 - sq) / (3 * c3), (-c2 + sq) / (3 * c3))
                            if 0.0 < s < 1.0)
    elif c2 != 0.0:
        s = -c1 / (2 * c2)
        if 0.0 < s < 1.0:
            knots.append(s)
    knots.append(1.0)
    vals = [c0 + s * (c1 + s * (c2 + s * c3)) for s in knots]
    vals[0] = g0 if g0 != 0.0 else (0.0 if m0 == 0 else float(np.sign(m0)) * 1e-300)
    falling = direction < 0
    for k in range(len(knots) - 1):
        sa, va, sb, vb = knots[k], vals[k], knots[k + 1], vals[k + 1]
        if falling and va > floor and vb <= -floor * (sb < 1.0) \
                or direction > 0 and va < -floor and vb >= floor * (sb < 1.0):
            if sb < 1.0 and verify is not None and not verify(sb, direction):
                # a dip of the interpolant that the true flow does not make
                continue
            # bisection on the interpolant (p inlined: the same operations)
            lo, hi = sa, sb
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if (c0 + mid * (c1 + mid * (c2 + mid * c3)) > 0) == falling:
                    lo = mid
                else:
                    hi = mid
            return hi
    return None


def _quadratic_roots(p0: float, p1: float, p2: float) -> np.ndarray:
    """``np.roots([p0, p1, p2])`` for ``p0 != 0`` and ``p2 != 0`` (no zero to strip): the
    eigenvalues of the same companion matrix by the same LAPACK call, without ``np.roots``'s
    general bookkeeping (the same values to the last bit)."""
    p = np.array([p0, p1, p2], dtype=float)
    A = np.zeros((2, 2))
    A[1, 0] = 1.0
    A[0, :] = -p[1:] / p[0]
    return np.linalg.eigvals(A)


@dataclass
class _Walk:
    """Mutable state of one simulation (:meth:`Simulator.run`): the discrete state ``mode``,
    the (extended) state ``Y`` with its sensitivities ``J = dY/dX0`` and ``Jt = dt/dX0``, the
    time, the next step size, the probe and field at ``Y``, and what the result reports."""

    mode: str
    Y: np.ndarray
    J: np.ndarray | None
    Jt: np.ndarray | None
    h: float
    pr: np.ndarray
    F: np.ndarray
    #: running extremes of the state components (Simulator._extend_extremes)
    lo: np.ndarray
    hi: np.ndarray
    traj: list[tuple[float, np.ndarray]] | None
    stick_start: float | None
    t: float = 0.0
    #: the watched function that fired last (exactly zero at the step start)
    just: str | None = None
    n_steps: int = 0
    n_imp: int = 0
    vmin: float = np.inf
    graze: float = np.inf
    events: list[SimEvent] = field(default_factory=list)
    stick_iv: list[tuple[float, float]] = field(default_factory=list)
    chatter_counts: list[int] = field(default_factory=list)
    chatter_errors: list[float] = field(default_factory=list)
    #: first-order chatter estimates of the current chattering sequence
    seq: list[Any] = field(default_factory=list)
    #: signed grazing margins of the near approaches and decelerating impacts, in time order
    margins: list[float] = field(default_factory=list)

    def record(self) -> None:
        if self.traj is not None:
            self.traj.append((self.t, self.Y[: self.lo.size].copy()))


class Simulator:
    """Event-driven simulator for one compiled system (see the module docstring)."""

    def __init__(self, c: CompiledHybrid, opts: SimOptions | None = None) -> None:
        self.c = c
        #: the compiled Functions, called through their buffers
        self.calls = c.calls()
        self.o = opts or SimOptions()
        #: chatter error estimates of the current sequence (stall detection)
        self._errs: list[float] = []

    # ------------------------------------------------------------------ helpers
    def _step(self, mode: str, Y: np.ndarray, dt: float, jac: bool) -> tuple[Any, ...]:
        """One Runge-Kutta step of length ``dt`` from ``Y`` in state ``mode``: ``(Y_new, err,
        err3, probe, field[, J])`` at the step end (views into one fresh array)."""
        key = "ext" if mode in EXTENDED else ("stick" if mode == S4 else "free")
        flat = self.calls.steps[key][1 if jac else 0].flat(Y, dt)
        m = Y.size
        npr = 6 if key == "ext" else 4
        i1, i2, i3, i4, i5 = m, 2 * m, 3 * m, 3 * m + npr, 4 * m + npr
        parts = (flat[:i1], flat[i1:i2], flat[i2:i3], flat[i3:i4], flat[i4:i5])
        if jac:
            return (*parts, flat[i5:].reshape(m, m, order="F"))
        return parts

    def _step_probe(self, mode: str, Y: np.ndarray, dt: float) -> np.ndarray:
        """The probe (``H, v, a, jerk[, h, h']``) after one step of length ``dt`` from ``Y``:
        ``self._step(mode, Y, dt, False)[3]``, without splitting the other outputs."""
        key = "ext" if mode in EXTENDED else ("stick" if mode == S4 else "free")
        return self.calls.steps[key][2].flat(Y, dt)

    def _field(self, mode: str, Y: np.ndarray) -> np.ndarray:
        if mode in EXTENDED:
            return self.calls.fe.flat(Y)
        if mode == S4:
            return self.calls.fs.flat(Y)
        return self.calls.f.flat(Y)

    def _probe(self, mode: str, Y: np.ndarray) -> np.ndarray:
        if mode in EXTENDED:
            return self.calls.probe_e.flat(Y)
        return self.calls.probe.flat(Y)

    def _err_norm(self, Y: np.ndarray, Yn: np.ndarray, err: np.ndarray, err3: np.ndarray,
                  dt: float) -> float:
        o = self.o
        scale = o.atol + o.rtol * np.maximum(np.abs(Y), np.abs(Yn))
        e5 = err.ravel() / scale
        if self.c.method == "dop853":
            e3 = err3.ravel() / scale
            n5, n3 = float(e5 @ e5), float(e3 @ e3)
            if n5 == 0.0 and n3 == 0.0:
                return 0.0
            return n5 / np.sqrt((n5 + 0.01 * n3) * len(scale))
        return float(np.sqrt(e5 @ e5 / len(scale)))

    # ------------------------------------------------------------------ main loop
    def run(self, X0: np.ndarray, t_end: float | None = None,
            section: tuple[int, float, int] | None = None, t_min_section: float = 0.0,
            max_time: float | None = None) -> SimResult:
        """Simulate from ``X0`` (state followed by freed parameters) until ``t_end`` or until
        component ``section[0]`` crosses ``section[1]`` in direction ``section[2]`` (after time
        ``t_min_section``). Raises :class:`SimulationError` with a reason on failure.

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
            if self._fire(w, dt, hit, section):
                return self._result(w, "section")
        if w.mode == S4 and w.stick_start is not None:
            w.stick_iv.append((w.stick_start, w.t))
        if w.J is not None and t_end is not None:
            # fixed end time: t_end - t_k(X0) is the last flow time
            w.J = w.J - np.outer(self._field(w.mode, w.Y), w.Jt)
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
        mode = initial_state(c, X0)
        c.mass_check(X0)
        sens = o.sensitivities
        w = _Walk(mode=mode, Y=X0.copy(), J=np.eye(c.N) if sens else None,
                  Jt=np.zeros(c.N) if sens else None, h=o.h_init,
                  pr=self._probe(mode, X0), F=self._field(mode, X0),
                  lo=X0[: c.n].copy(), hi=X0[: c.n].copy(),
                  traj=[] if o.record else None,
                  stick_start=0.0 if mode == S4 else None)
        w.record()
        if mode in (S1, S2) and abs(w.pr[1]) <= 1e-12 * (1.0 + np.linalg.norm(X0)):
            # a start at a turning point of H (v = 0 to round-off, e.g. a maximum on a
            # stroboscopic section): v is "just fired", so its sign cannot hide the turn
            # (the floor of the v watch would not see v falling from +1e-14); a decides, the
            # jerk where a vanishes too (a start at rest where the force balances, e.g. the
            # forced oscillator's (gap + 1, 0) at phase 0), and otherwise the approach: its
            # watches (the impact, the turn of v) see a flight moving away too, not conversely
            tiny = 1e-12 * (1.0 + np.linalg.norm(X0))
            a, jerk = float(w.pr[2]), float(w.pr[3])
            w.mode = mode = S1 if (a > tiny or (abs(a) <= tiny and jerk > tiny)) else S2
            w.just = "v"
        if mode == S2 and abs(w.pr[0]) <= 1e-12 * (1.0 + np.linalg.norm(X0)):
            # a start on the surface moving inwards: the impact happens at t = 0
            self._apply_transition(w, "H", w.pr)
        return w

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
        ``(Y_new, err, err3, probe, field, J or None, error norm)``, or None (rejected; ``w.h``
        shrunk).

        In a chattering flight (``s5``, ``s6``) nearly every step ends at an event (the turn of
        ``v``, the next impact), whose sensitivities come from the step to the event
        (:meth:`_refine`): the step's Jacobian (four times the cost of the step) is then left
        to :meth:`_accept`, which evaluates it only for a step taken whole (the same
        ``Y_new``: both are the same CasADi expressions, ``tests/test_speed_chatter_step.py``).
        """
        jac = w.J is not None and w.mode not in EXTENDED
        outs = self._step(w.mode, w.Y, dt, jac)
        if not jac:
            outs = (*outs, None)
        Yn = outs[0].ravel()
        en = self._err_norm(w.Y, Yn, outs[1], outs[2], dt)
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
        if en < HERMITE_CHECK_BELOW and not self._hermite_trustworthy(w, dt, outs):
            w.h = dt * 0.25
            return None
        return (*outs, en)

    def _hermite_trustworthy(self, w: _Walk, dt: float, outs: tuple[Any, ...]) -> bool:
        """Whether the cubic Hermite interpolants of the watched functions over a step whose
        error estimate is tiny still describe them: checked against the true flow at the
        midpoint. The error estimate controls the state, not the functions of it that are
        watched: where the flow is integrated exactly (sticking on a wall while only the
        forcing clock moves, ``a = cos(phase)``) it is zero, the step grows fivefold per step,
        and a step spanning a whole oscillation of ``a`` would hide the release (the
        stroboscopic oscillator at omega ~ 0.357 then stuck to the wall for ever)."""
        mid = self._step_probe(w.mode, w.Y, 0.5 * dt)
        prn = outs[3].ravel()
        for idx, _direction, _name in WATCH[w.mode]:
            g0, d0, g1, d1 = w.pr[idx], w.pr[idx + 1] * dt, prn[idx], prn[idx + 1] * dt
            p_mid = 0.5 * (g0 + g1) + 0.125 * (d0 - d1)
            scale = abs(g0) + abs(g1) + 0.25 * (abs(d0) + abs(d1))
            if abs(mid[idx] - p_mid) > 0.05 * scale + 1e-14:
                return False
        return True

    def _first_crossing(self, w: _Walk, dt: float, outs: tuple[Any, ...],
                        section: tuple[int, float, int] | None, t_min_section: float
                        ) -> tuple[float, str, int, int] | None:
        """First watched crossing in the step (cubic Hermite, both roots of a dip):
        ``(s, name, index, direction)`` with ``s`` the fraction of the step, or None."""
        mode, Y = w.mode, w.Y
        # Python floats: the same arithmetic as on the arrays' elements, faster
        pr, prn = w.pr.tolist(), outs[3].tolist()
        best: tuple[float, str, int, int] | None = None
        fdt = float(dt)
        for idx, direction, name in WATCH[mode]:
            # the function that just fired is exactly zero at the step start (its round-off
            # sign must not fire it again): its derivative decides
            g0 = 0.0 if name == w.just else pr[idx]
            if _hermite_one_sign(g0, pr[idx + 1] * fdt, prn[idx], prn[idx + 1] * fdt):
                continue  # no crossing (what _hermite_first_root would find first)
            floor = 0.0 if name in ("H", "h") else 1e-13 * (
                1.0 + abs(pr[idx]) + abs(prn[idx]) + dt * (abs(pr[idx + 1]) + abs(prn[idx + 1])))

            def verify(sx: float, d: int, idx: int = idx) -> bool:
                gv = self._step_probe(mode, Y, sx * dt)[idx]
                return gv < 0 if d < 0 else gv > 0

            s = _hermite_first_root(g0, pr[idx + 1], prn[idx], prn[idx + 1], dt, direction,
                                    floor, verify)
            if s is not None and (best is None or s < best[0]):
                best = (s, name, idx, direction)
        if section is not None and w.t + dt > t_min_section:
            k, val, sd = section
            s = _hermite_first_root(Y[k] - val, w.F[k], outs[0][k] - val, outs[4][k], dt, sd)
            if s is not None and (best is None or s < best[0]):
                best = (s, "section", k, sd)
        return best

    def _accept(self, w: _Walk, dt: float, outs: tuple[Any, ...], last: bool) -> None:
        """Take the whole step (no crossing inside it) and choose the next step size."""
        Yn, prn, Fn, en = outs[0].ravel(), outs[3].ravel(), outs[4].ravel(), outs[-1]
        w.just = None
        if w.J is not None:
            Jstep = outs[5] if outs[5] is not None else self._step(w.mode, w.Y, dt, True)[5]
            w.J = Jstep @ w.J
        self._extend_extremes(w, w.Y, w.F, Yn, Fn, dt)
        w.Y, w.pr, w.F = Yn, prn, Fn
        w.t += dt
        w.record()
        if not last:
            w.h = dt * (5.0 if en == 0 else
                        min(5.0, max(0.2, 0.9 * en ** (-1.0 / (self.c.order + 1)))))

    def _extend_extremes(self, w: _Walk, Y0: np.ndarray, F0: np.ndarray, Y1: np.ndarray,
                         F1: np.ndarray, dt: float) -> None:
        """Extremes of each state component over the flow step from ``Y0`` to ``Y1`` (mode
        ``w.mode``): the ends, and where a component's slope changes sign inside the step, its
        value on the true flow at the extremum of the cubic Hermite interpolant (ends and
        slopes ``F``). The location error ``ds`` of the interpolant costs ``O(ds^2)`` in the
        value: the extremes are exact to about the integration tolerance."""
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
        m0, m1 = F0[:n] * dt, F1[:n] * dt
        for i in turning:
            # p(s) = a + m0 s + c2 s^2 + c3 s^3 on [0, 1]; p'(s) = 0 between the ends
            c2 = -3 * a[i] - 2 * m0[i] + 3 * b[i] - m1[i]
            c3 = 2 * a[i] + m0[i] - 2 * b[i] + m1[i]
            roots = _quadratic_roots(3 * c3, 2 * c2, m0[i]) if c3 != 0 else np.array(
                [-m0[i] / (2 * c2)] if c2 != 0 else [])
            for r in roots:
                if abs(r.imag) < 1e-14 and 0.0 < r.real < 1.0:
                    sr = r.real
                    out = self._step(w.mode, Y0, sr * dt, False)
                    curv = 2 * c2 + 6 * c3 * sr
                    if curv != 0.0:
                        # one Newton step on the true slope: the value is then exact to
                        # O(ds^4) instead of O(ds^2)
                        s1 = sr - float(out[4][i]) * dt / curv
                        if 0.0 < s1 < 1.0:
                            out = self._step(w.mode, Y0, s1 * dt, False)
                    v = float(out[0][i])
                    w.lo[i] = min(w.lo[i], v)
                    w.hi[i] = max(w.hi[i], v)

    def _fire(self, w: _Walk, dt: float, hit: tuple[float, str, int, int],
              section: tuple[int, float, int] | None) -> bool:
        """Advance to the crossing ``hit`` located on the true flow, chain its saltation into
        the sensitivities and apply its transition; True when it is the section (the end)."""
        mode, Y, pr = w.mode, w.Y, w.pr
        s, name, idx, _direction = hit
        tau, Ye, pre, Fe, Jstep = self._refine(mode, Y, dt, s * dt, name, idx, section)
        if name == "v" and mode in (S2, S6):
            # the turn of v came after the impact function went negative: an impact inside a
            # dip the interpolant of H (or h) did not resolve. H (h) is monotone before the
            # turn, so [0, tau] brackets exactly one impact.
            hi_, hn = (0, "H") if mode == S2 else (4, "h")
            if pre[hi_] < 0 <= pr[hi_]:
                name, idx = hn, hi_
                tau, Ye, pre, Fe, Jstep = self._refine(
                    mode, Y, tau, tau * pr[hi_] / (pr[hi_] - pre[hi_]), name, idx, section)
        if section is not None and name != "section":
            # the refined crossing may lie past the section (an event within round-off of
            # it, e.g. a turning point of q on a stroboscopic section): the section comes first
            k, val, sd = section
            a0, a1 = sd * (Y[k] - val), sd * (Ye[k] - val)
            if a0 < 0 <= a1:
                name, idx = "section", k
                tau, Ye, pre, Fe, Jstep = self._refine(mode, Y, tau, tau * a0 / (a0 - a1),
                                                       name, idx, section)
        if w.J is not None:
            Je = Jstep @ w.J
            gx = self._gx(mode, name, idx, Ye)
            dtau = -(gx @ Je) / (gx @ Fe)
            w.J = Je + np.outer(Fe, dtau)
            w.Jt = w.Jt + dtau
        self._extend_extremes(w, Y, w.F, Ye, Fe, tau)
        w.Y, w.t = Ye, w.t + tau
        w.record()
        if name == "section":
            w.events.append(SimEvent("section", w.t, w.Y[: self.c.n].copy()))
            return True
        self._apply_transition(w, name, pre)
        return False

    def _apply_transition(self, w: _Walk, name: str, pre: np.ndarray) -> None:
        """Apply the transition of ``name`` in the current state (:meth:`_transition`) and
        keep the walk's bookkeeping (impacts, sticking intervals, next step size)."""
        mode = w.mode
        newmode, w.Y, w.J, w.Jt, w.t, info = self._transition(
            mode, name, w.Y, w.J, w.Jt, w.t, pre, w.seq, w.events, w.chatter_errors)
        if info.get("impact_velocity") is not None:
            w.n_imp += 1
            w.vmin = min(w.vmin, info["impact_velocity"])
        if info.get("near_approach") is not None:
            w.graze = min(w.graze, info["near_approach"])
            w.margins.append(info["near_approach"])
        if info.get("chatter_count") is not None:
            w.chatter_counts.append(info["chatter_count"])
        if mode == S4 and newmode != S4 and w.stick_start is not None:
            w.stick_iv.append((w.stick_start, w.t))
            w.stick_start = None
        if newmode == S4 and mode != S4:
            w.stick_start = w.t
        w.record()
        w.mode = newmode
        w.just = name
        key = "ext" if newmode in EXTENDED else ("stick" if newmode == S4 else "free")
        both = self.calls.probe_field[key].flat(w.Y)
        npr = 6 if key == "ext" else 4
        w.pr, w.F = both[:npr], both[npr:]
        if newmode in EXTENDED and name in ("H", "h"):
            # next flight lasts about 2u/|a| (constant acceleration)
            u, a = w.Y[self.c.N + 1], w.pr[2]
            w.h = min(max(2.0 * u / max(abs(a), 1e-300), 1e-300), max(w.h, 1e-300)) * 1.05

    def _result(self, w: _Walk, ended_by: str) -> SimResult:
        N = self.c.N
        return SimResult(
            X=w.Y[:N].copy(), t=w.t, J=None if w.J is None else w.J[:N].copy(),
            Jt=None if w.Jt is None else w.Jt.copy(), events=w.events, state=w.mode,
            sticking_intervals=w.stick_iv, chatter_counts=w.chatter_counts, n_impacts=w.n_imp,
            min_impact_velocity=float(w.vmin), grazing_margin=float(w.graze),
            chatter_errors=w.chatter_errors, trajectory=w.traj, n_steps=w.n_steps,
            ended_by=ended_by, extremes=np.column_stack([w.lo, w.hi]),
            grazing_margins=list(w.margins))

    def _gx(self, mode: str, name: str, idx: int, Y: np.ndarray) -> np.ndarray:
        """Gradient of the event function ``name`` with respect to the (extended) state."""
        N = self.c.N
        g = np.zeros(Y.size)
        if name == "section":
            g[idx] = 1.0
        elif name == "h":
            g[N] = 1.0
        else:
            row = {"H": 0, "v": 1, "a": 2}[name]
            g[:N] = self.calls.grads(Y[:N])[row]
        return g

    def _refine(self, mode: str, Y: np.ndarray, dt: float, tau0: float, name: str, idx: int,
                section: tuple[int, float, int] | None) -> tuple[Any, ...]:
        """Event time on the true flow: safeguarded Newton from the Hermite root ``tau0``.

        ``g(tau)`` is the watched function after one RK step of length ``tau`` from ``Y`` (under
        error control, since ``tau <= dt``); ``g'(tau)`` its exact time derivative there."""
        sens = self.o.sensitivities
        key = "ext" if mode in EXTENDED else ("stick" if mode == S4 else "free")
        m = Y.size
        off = 0.0
        if name == "section":
            # the state and the field after the step
            step = self.calls.steps[key][0].flat
            ig, idg = idx, 3 * m + (6 if key == "ext" else 4) + idx
            off = section[1]
        else:
            # the probe after the step: the watched function and its time derivative
            step = self.calls.steps[key][2].flat
            ig, idg = idx, idx + 1
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
            flat = step(Y, tau)
            g, dg = (flat[ig] - off if name == "section" else flat[ig]), flat[idg]
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
        out = self._step(mode, Y, tau, sens)
        Ye, pre, Fe = out[0].ravel(), out[3].ravel(), out[4].ravel()
        return tau, Ye, pre, Fe, (out[5] if sens else None)

    # ------------------------------------------------------------------ transitions
    def _transition(self, mode: str, name: str, Y: np.ndarray, J: np.ndarray | None,
                    Jt: np.ndarray | None, t: float, pr: np.ndarray, seq: list[Any],
                    events: list[SimEvent], chatter_errors: list[float]) -> tuple[Any, ...]:
        """The transition of Table 1 fired by ``name`` in state ``mode``: a flight transition
        (:meth:`_flight_transition`) or an impact (:meth:`_impact_transition`).
        Returns ``(new mode, Y, J, Jt, t, info)``."""
        if name in ("H", "h"):
            return self._impact_transition(mode, Y, J, Jt, t, seq, events, chatter_errors)
        return self._flight_transition(mode, name, Y, J, Jt, t, pr, seq, events)

    def _flight_transition(self, mode: str, name: str, Y: np.ndarray, J: np.ndarray | None,
                           Jt: np.ndarray | None, t: float, pr: np.ndarray, seq: list[Any],
                           events: list[SimEvent]) -> tuple[Any, ...]:
        """Transitions I, II, VI, VIII, X, XI, XII of Table 1 (turns of ``v``, sign changes of
        ``a``): no jump of the state; the extended state is dropped where chattering ends."""
        c = self.c
        N = c.N
        info: dict[str, Any] = {}
        if mode == S1 and name == "v":                                  # I
            return S2, Y, J, Jt, t, info
        if mode == S2 and name == "v":                                  # II: local minimum of H
            info["near_approach"] = float(pr[0])
            # J at the turn: the grazing normal form (shooting.grazing_tangent) needs the
            # gradient of H_min = H(x(t_turn)) (dH/dt = v = 0 there) and the tail sensitivity
            events.append(SimEvent("near_approach", t, Y[: c.n].copy(),
                                   {"H": float(pr[0]), "J": None if J is None else J.copy()}))
            return S1, Y, J, Jt, t, info
        if mode == S3 and name == "a":                                  # XII
            return S1, Y, J, Jt, t, info
        if mode == S4 and name == "a":                                  # XI: release
            events.append(SimEvent("release", t, Y[: c.n].copy()))
            return S3, Y, J, Jt, t, info
        if mode == S5 and name == "v":                                  # VI
            return S6, Y, J, Jt, t, info
        if mode == S5 and name == "a":                                  # VIII: chattering broken
            count = len(seq)
            seq.clear()
            events.append(SimEvent("chatter_broken", t, Y[: c.n].copy(), {"impacts": count}))
            return S1, Y[:N].copy(), None if J is None else J[:N].copy(), Jt, t, info
        if mode == S6 and name == "v":                                  # X: turned before impact
            count = len(seq)
            seq.clear()
            info["near_approach"] = float(pr[0])
            # a near approach too (H_min = H at the turn): J for the grazing normal form
            events.append(SimEvent("chatter_broken", t, Y[: c.n].copy(),
                                   {"impacts": count, "H": float(pr[0]),
                                    "J": None if J is None else J[:N].copy()}))
            return S1, Y[:N].copy(), None if J is None else J[:N].copy(), Jt, t, info
        raise SimulationError(f"no transition for {name!r} in state {mode}")  # pragma: no cover

    def _impact_transition(self, mode: str, Y: np.ndarray, J: np.ndarray | None,
                           Jt: np.ndarray | None, t: float, seq: list[Any],
                           events: list[SimEvent], chatter_errors: list[float]
                           ) -> tuple[Any, ...]:
        """Transitions III, IV, V, VII, IX of Table 1: an impact (eq. 5), the chatter map once
        its error estimate meets the tolerance (:meth:`_chatter_step`), or sticking."""
        c, o = self.c, self.o
        N = c.N
        info: dict[str, Any] = {}
        # ---------------------------------------------------------------- impacts
        X = Y[:N].copy()
        JX = None if J is None else J[:N].copy()
        q = c.q(X)
        if o.validate:
            c.validate_at(X, f"at the impact at t = {t:.6g}", q)
        info["impact_velocity"] = abs(q["v"])
        a = q["a"]
        if a > 0:
            # a decelerating approach: the free flight continued through the wall would turn
            # at H = -v^2 / (2a); with the near approaches' H_min > 0 this is the signed
            # grazing margin, continuous through a grazing bifurcation
            info["near_approach"] = -q["v"] ** 2 / (2.0 * a)
        if mode == S2:
            seq.clear()
        if a < 0 and o.chatter in ("map", "cut"):
            # a chattering sequence: impacts accumulate where a < 0 (sec. 2.5)
            done = self._chatter_step(X, JX, Jt, t, seq, events, chatter_errors)
            if done is not None:
                Xs, Js, Jts, ts, count = done
                info["chatter_count"] = count
                return S4, Xs, Js, Jts, ts, info
        R, Rx, _v, _r = self.calls.impact(X)
        Xp = R.ravel()
        Jp = None if JX is None else Rx @ JX
        v_plus, v_grad = self.calls.vgrad(Xp)
        vplus = v_plus.item()
        if mode == S2:
            events.append(SimEvent("impact", t, X[: c.n].copy(),
                                   {"v": q["v"], "a": a,
                                    "J": None if JX is None else JX.copy()}))
        if mode in EXTENDED and not a < 0:
            # an impact of a chattering sequence after which the flight leaves the wall:
            # the sequence breaks off (this impact is not in ``seq``, which holds a < 0 only)
            events.append(SimEvent("chatter_broken", t, X[: c.n].copy(),
                                   {"impacts": len(seq) + 1, "v": q["v"], "a": a,
                                    "J": None if JX is None else JX.copy()}))
            seq.clear()
        if vplus <= 1e-14 * (1.0 + abs(q["v"])):                          # r = 0 (IV, V)
            seq.clear()
            if a < 0:
                Xs, Js = self._project(Xp, Jp)
                events.append(SimEvent("plastic_stick", t, Xs[: c.n].copy()))
                return S4, Xs, Js, Jt, t, info
            return S3, Xp, Jp, Jt, t, info
        if a < 0:                                                         # III, VII
            v_row = v_grad.ravel()
            Ye = np.concatenate([Xp, [0.0, vplus]])
            Je = None
            if Jp is not None:
                Je = np.vstack([Jp, np.zeros((1, N)), (v_row @ Jp)[None, :]])
            return S5, Ye, Je, Jt, t, info
        seq.clear()
        return S1, Xp, Jp, Jt, t, info

    def _project(self, X: np.ndarray, J: np.ndarray | None) -> tuple[np.ndarray, Any]:
        P, Px = self.calls.project(X)
        return P.ravel(), (None if J is None else Px @ J)

    def _chatter_step(self, X: np.ndarray, JX: np.ndarray | None, Jt: np.ndarray | None,
                      t: float, seq: list[Any], events: list[SimEvent],
                      chatter_errors: list[float]) -> tuple[Any, ...] | None:
        """Record the first-order chatter estimate at this impact; apply the map when its
        estimated error meets the tolerance (returns the sticking state), else None."""
        c, o = self.c, self.o
        N = c.N
        sens = JX is not None
        Q1, q1, Q1x, q1x, r, rx = self.calls.chatter(X)
        val = np.concatenate([Q1.ravel(), [t + q1.item()]])
        jac = None
        rj = None
        if sens:
            jac = np.vstack([Q1x @ JX, (Jt + q1x.ravel() @ JX)[None, :]])
            rj = rx.ravel() @ JX
        # the last slot memoises this impact's extrapolated values (_extrapolate)
        seq.append([val, jac, r.item(), rj, {}])
        count = len(seq)
        if o.chatter == "cut":
            if count < o.cut_after:
                return None
            # naive baseline: a perfectly plastic K-th impact, no map, no time jump
            Xs, Js = self._project(X, JX)
            seq.clear()
            events.append(SimEvent("chatter", t, Xs[: c.n].copy(), {"impacts": count,
                                                                   "cut": True}))
            return Xs, Js, Jt, t, count
        m = o.chatter_order
        if count < m + 1:
            if count > o.max_chatter_impacts:
                raise SimulationError("chatter map never met its tolerance")
            return None
        value, vjac, prev, _ = _extrapolate(seq[-(m + 1):], m)
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
        a_star = c.q(Xs)["a"]
        if not a_star < 0:
            # sec. 5.2: no sticking after the map; keep impacting (incomplete chattering)
            if count > o.max_chatter_impacts:
                raise SimulationError("chattering ends at a >= 0: incomplete chattering with "
                                      f"more than {o.max_chatter_impacts} impacts")
            return None
        Jx = None if vjac is None else vjac[:N]
        Xs, Js = self._project(Xs, Jx)
        Jts = None if vjac is None else vjac[N].copy()
        ts = float(value[N])
        chatter_errors.append(err)
        seq.clear()
        # the impact at x_k is replaced by the map: count - 1 impacts were resolved
        events.append(SimEvent("chatter", t, Xs[: c.n].copy(),
                               {"impacts": count - 1, "error_estimate": err,
                                "t_complete": ts, "error_floor": floor_hit}))
        return Xs, Js, Jts, ts, count - 1


def _extrapolate(entries: list[Any], m: int) -> tuple[np.ndarray, Any, np.ndarray, Any]:
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
