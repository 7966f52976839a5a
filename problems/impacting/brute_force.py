"""Brute-force bifurcation diagrams of the double pendulum (Nordmark & Piiroinen 2009, sec. 6).

An independent cross-check of the continuation: for each parameter value the attractor is
simulated return by return on the Poincaré section ``q1 = pi/2`` (mod ``2 pi``), without
sensitivities, and ``q2`` (wrapped to ``(-pi, pi]``) is recorded at every return after a
transient. The sweep continues the attractor: each value starts from the previous value's final
state. A :class:`~nsm_continuation.hybrid.simulate.SimulationError` is recorded (its reason)
and the value is restarted from the problem's default initial state.

No Newton iteration, no monodromy matrix, no event order: only the event-driven simulator, so
agreement with the shooting orbits (Figs. 8(b), 9(b)-(c), 10(b)) checks the continuation.

Usage::

    from nsm_continuation.problems.impacting.brute_force import brute_force
    out = brute_force("e", np.linspace(0.85, 0.92, 71), {"d": 0.5, "torque": -31.15})
    for e, q2 in out: ...
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

from nsm_continuation.hybrid.simulate import SimOptions, SimulationError, Simulator

TWO_PI = 2.0 * np.pi


def wrap(q: Any) -> Any:
    """Angle(s) wrapped to ``(-pi, pi]``."""
    return np.pi - np.mod(np.pi - np.asarray(q, dtype=float), TWO_PI)


@dataclass
class SweepPoint:
    """The recorded attractor at one parameter value.

    Per recorded return (same length as ``q2``): ``return_times`` (time between consecutive
    section crossings), ``sticking_times`` (total time sticking during that return),
    ``n_sticking`` (sticking intervals), ``n_impacts`` (impacts resolved individually, those
    replaced by the chatter map excluded), ``signatures`` (event sequence, see
    :attr:`SimResult.signature`)."""

    value: float
    q2: np.ndarray
    state: np.ndarray | None = None
    return_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sticking_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_sticking: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    n_impacts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    signatures: list[str] = field(default_factory=list)
    #: reasons of the SimulationErrors met at this value (each one triggered a restart)
    failures: list[str] = field(default_factory=list)
    #: started from the default initial state (after a failure here or at the previous value),
    #: not from the previous value's attractor
    restarted: bool = False
    wall: float = 0.0

    @property
    def ok(self) -> bool:
        return self.q2.size > 0

    @property
    def all_sticking(self) -> bool:
        """Every recorded return has at least one sticking interval."""
        return self.ok and bool(np.all(self.n_sticking > 0))

    @property
    def any_sticking(self) -> bool:
        return self.ok and bool(np.any(self.n_sticking > 0))

    def period(self, tol: float = 1e-6, max_period: int | None = None) -> int | None:
        """Smallest ``p`` with ``|q2[k + p] - q2[k]| <= tol`` (circular distance) for all
        recorded ``k``; None if none up to ``max_period`` (default: half the record)."""
        return sequence_period(self.q2, tol, max_period)

    def n_distinct(self, tol: float = 1e-6) -> int:
        return n_distinct(self.q2, tol)


def _circ(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(wrap(np.asarray(a) - np.asarray(b)))


def sequence_period(q2: np.ndarray, tol: float = 1e-6, max_period: int | None = None
                    ) -> int | None:
    """Smallest period of the recorded sequence (None: not periodic within the record)."""
    q2 = np.asarray(q2, dtype=float)
    n = q2.size
    if n == 0:
        return None
    top = n // 2 if max_period is None else min(max_period, n - 1)
    for p in range(1, max(top, 1) + 1):
        if p >= n:
            break
        if np.all(_circ(q2[p:], q2[:-p]) <= tol):
            return p
    return None


def n_distinct(q2: np.ndarray, tol: float = 1e-6) -> int:
    """Number of clusters of ``q2`` values (gaps larger than ``tol`` split clusters)."""
    q2 = np.sort(np.asarray(q2, dtype=float))
    if q2.size == 0:
        return 0
    k = 1 + int(np.sum(np.diff(q2) > tol))
    if k > 1 and _circ(q2[0], q2[-1]) <= tol:   # a cluster straddling +-pi
        k -= 1
    return k


class PendulumSweeper:
    """Section-to-section simulation of the double pendulum with one parameter lifted into the
    state (compiled once for the whole sweep)."""

    def __init__(self, param_name: str, fixed: dict[str, float], value: float,
                 options: SimOptions | None = None) -> None:
        self.param = param_name
        self.pb = DoublePendulumProblem({**fixed, param_name: value})
        self.pb.set_parameter(param_name)
        self.c = self.pb.shooting.c
        opts = options if options is not None else SimOptions()
        self.sim = Simulator(self.c, replace(opts, sensitivities=False, record=False))
        sec = self.pb.section()
        self.index, self.value, self.shift = sec.index, sec.value, sec.shift
        self.direction = 1 if self.shift > 0 else -1

    def default_state(self, value: float) -> np.ndarray:
        self.pb.values[self.param] = value
        return np.append(self.pb.default_initial(), [value])

    def one_return(self, X: np.ndarray, max_time: float | None = None) -> tuple[np.ndarray, Any]:
        """From ``X`` on the section (``q1 = pi/2``) to the next crossing; q1 is reset to the
        section value and q2 wrapped, so the state stays bounded. No crossing within
        ``max_time`` (the pendulum came to rest) is a :class:`SimulationError`."""
        res = self.sim.run(X, section=(self.index, self.value + self.shift, self.direction),
                           max_time=max_time)
        if res.ended_by != "section":
            raise SimulationError(f"no return to the section within t = {res.t:.6g} (the "
                                  f"pendulum came to rest: q1 = {res.X[0]:.6g}, "
                                  f"q1dot = {res.X[2]:.3g})")
        Xn = res.X.copy()
        Xn[self.index] = self.value
        Xn[1] = wrap(Xn[1])
        return Xn, res


def _repeats(history: list[np.ndarray], tol: float, max_period: int) -> int | None:
    """Smallest ``p <= max_period`` with the last state equal to the one ``p`` returns
    earlier (angles compared modulo 2 pi), or None."""
    x = history[-1]
    for p in range(1, min(max_period, len(history) - 1) + 1):
        d = history[-1 - p] - x
        d[:2] = wrap(d[:2])
        if np.max(np.abs(d)) <= tol * (1.0 + np.max(np.abs(x))):
            return p
    return None


def sweep(param_name: str, values: Any, fixed: dict[str, float], transient_returns: int = 30,
          recorded_returns: int = 30, options: SimOptions | None = None,
          initial: np.ndarray | None = None, converge_tol: float | None = None,
          max_period: int = 8, max_time: float | None = 1000.0,
          progress: bool = False) -> list[SweepPoint]:
    """Brute-force sweep with the per-return details (see :class:`SweepPoint`).

    ``initial``: state ``(q1, q2, q1dot, q2dot)`` on the section to start the first value from
    (default: the problem's :meth:`default_initial`). ``converge_tol``: if given, the transient
    ends early once the state on the section repeats (period ``p <= max_period``) to this
    relative tolerance, and then only ``max(4 p, 8)`` returns (at most ``recorded_returns``)
    are recorded; otherwise exactly ``transient_returns`` and ``recorded_returns`` are
    simulated. ``max_time``: a return that takes longer is a failure (the pendulum at rest)."""
    values = [float(v) for v in np.atleast_1d(values)]
    sw = PendulumSweeper(param_name, fixed, values[0], options)
    X: np.ndarray | None = None
    if initial is not None:
        X = np.append(np.asarray(initial, dtype=float)[:4], [values[0]])
    out: list[SweepPoint] = []
    for i, val in enumerate(values):
        t0 = time.perf_counter()
        pt = SweepPoint(val, np.zeros(0))
        attempts = [X, None] if X is not None else [None]
        for start in attempts:
            if start is None:
                start = sw.default_state(val)
                pt.restarted = i > 0 or bool(pt.failures)
            Xc = start.copy()
            Xc[-1] = val
            rec: list[tuple[float, float, float, int, int, str]] = []
            n_rec = recorded_returns
            try:
                hist = [Xc[:4].copy()]
                for _ in range(transient_returns):
                    Xc, _res = sw.one_return(Xc, max_time)
                    if converge_tol is not None:
                        hist.append(Xc[:4].copy())
                        p = _repeats(hist, converge_tol, max_period)
                        if p is not None:
                            n_rec = min(recorded_returns, max(4 * p, 8))
                            break
                for _ in range(n_rec):
                    Xc, res = sw.one_return(Xc, max_time)
                    rec.append((Xc[1], res.t, res.sticking_time, len(res.sticking_intervals),
                                res.n_impacts, res.signature))
            except SimulationError as exc:
                pt.failures.append(exc.reason)
                X = None
                continue
            pt.q2 = np.array([r[0] for r in rec])
            pt.return_times = np.array([r[1] for r in rec])
            pt.sticking_times = np.array([r[2] for r in rec])
            pt.n_sticking = np.array([r[3] for r in rec], dtype=int)
            pt.n_impacts = np.array([r[4] for r in rec], dtype=int)
            pt.signatures = [r[5] for r in rec]
            pt.state = Xc[:4].copy()
            X = Xc
            break
        pt.wall = time.perf_counter() - t0
        if progress:
            per = pt.period()
            print(f"  {param_name} = {val:.7g}: {pt.q2.size} returns, period "
                  f"{per if per is not None else '-'}, sticking "
                  f"{'all' if pt.all_sticking else ('some' if pt.any_sticking else 'none')}, "
                  f"T_return {np.mean(pt.return_times) if pt.ok else np.nan:.4f}, "
                  f"{pt.wall:.2f} s" + (f", FAILED: {pt.failures}" if pt.failures else ""),
                  flush=True)
        out.append(pt)
    return out


def brute_force(param_name: str, values: Any, fixed: dict[str, float],
                transient_returns: int = 30, recorded_returns: int = 30,
                options: SimOptions | None = None, **kwargs: Any
                ) -> list[tuple[float, np.ndarray]]:
    """``[(value, q2 at the section q1 = pi/2 mod 2 pi, wrapped to (-pi, pi]), ...]``: the
    recorded returns after ``transient_returns`` returns, each value started from the previous
    one's final state (an empty array where the simulation failed twice). ``kwargs``: the
    further options of :func:`sweep`."""
    return [(p.value, p.q2) for p in sweep(param_name, values, fixed, transient_returns,
                                           recorded_returns, options, **kwargs)]
