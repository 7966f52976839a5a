"""Steady forced responses of the damped bar by time stepping (section 7, Figs. 20-22).

Yoong, Thorin, Legrand (2017), section 7: at each forcing frequency the bar is advanced by the
WFEM time stepping (Algorithm 2, :func:`problems.bar.wfem_stepping.simulate`) through a transient,
then by blocks of forcing periods until the energy averaged over each period repeats with period
k T (:func:`steady_multiple`: k = 1 periodic, k > 1 subharmonic, 0 not steady within the time
budget). :func:`forced_response_point` finds one steady state (warm-started from the previous
frequency's, the forcing phase kept continuous); :func:`forced_response_sweep` runs a sweep of
frequencies.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from nsm_continuation.problems.bar.wfem_stepping import (
    BarParams,
    BarState,
    Loading,
    SimulationResult,
    _check_finite,
    rest_state,
    simulate,
)


def period_averages(t: np.ndarray, y: np.ndarray, period: float, n_periods: int) -> np.ndarray:
    """Averages of the piecewise-linear interpolant of ``y(t)`` over the last ``n_periods``
    windows of length ``period`` ending at ``t[-1]`` (exact for the interpolant)."""
    dt = t[1] - t[0]
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * dt)])

    def integral_to(tt: float) -> float:
        k = int(min(max(math.floor((tt - t[0]) / dt), 0), len(t) - 2))
        tau = tt - t[k]
        return float(cum[k] + y[k] * tau + (y[k + 1] - y[k]) * tau * tau / (2.0 * dt))

    ends = t[-1] - period * np.arange(n_periods, -1, -1)
    if ends[0] < t[0] - 1e-12 * period:
        raise ValueError("record too short for the requested number of periods")
    vals = np.array([integral_to(float(te)) for te in ends])
    return np.diff(vals) / period


@dataclass
class ForcedPoint:
    """Steady-state result at one forcing frequency."""

    omega: float
    energy_mean: float          # total energy averaged over one (sub)harmonic steady period
    period_averages: np.ndarray  # energy averaged over each of the last forcing periods
    steady: bool                # period averages repeat with multiplicity `multiple`
    multiple: int               # 1 periodic, k: period k T (subharmonic), 0: not steady
    contact_fraction: float     # fraction of steps in contact over the averaging window
    u_max: float
    u_min: float
    n_steps: int
    wall_time: float


@dataclass
class ForcedSweep:
    """A frequency sweep (increasing or as given) with continuation of the state."""

    params: BarParams
    eta: float
    w0: float
    f0: float
    points: list[ForcedPoint] = field(default_factory=list)
    wall_time: float = 0.0

    @property
    def omegas(self) -> np.ndarray:
        return np.array([p.omega for p in self.points])

    @property
    def energies(self) -> np.ndarray:
        return np.array([p.energy_mean for p in self.points])

    @property
    def steady(self) -> np.ndarray:
        return np.array([p.steady for p in self.points])

    @property
    def total_steps(self) -> int:
        return sum(p.n_steps for p in self.points)


def steady_multiple(averages: np.ndarray, tol: float, max_multiple: int = 4) -> int:
    """Smallest k <= max_multiple with ``|A_j - A_(j-k)| <= tol * mean|A|`` over the record
    (k-periodic period averages: a T- or k T-periodic steady state), else 0."""
    A = np.asarray(averages, dtype=float)
    scale = max(float(np.mean(np.abs(A))), np.finfo(float).tiny)
    for k in range(1, max_multiple + 1):
        if len(A) < 2 * k:
            break
        if np.max(np.abs(A[k:] - A[:-k])) <= tol * scale:
            return k
    return 0


@dataclass(frozen=True)
class SteadyStateRule:
    """How :func:`forced_response_point` finds the steady state at one frequency: transient of
    ``n_periods_transient`` forcing periods and at least ``min_transient_time``, then blocks of
    ``n_periods_average`` periods until the period averages are k-periodic to ``tol``
    (:func:`steady_multiple`) or ``max_time`` has been simulated; ``switching`` as in
    :func:`simulate`. Build it with :func:`steady_state_rule` (validation and defaults)."""

    n_periods_transient: int
    n_periods_average: int
    min_transient_time: float
    max_time: float
    tol: float
    switching: Literal["grid", "subcell"]


def steady_state_rule(params: BarParams, eta: float, n_periods_transient: int = 10,
                      n_periods_average: int = 8, min_transient_time: float | None = None,
                      max_time: float | None = None, tol: float = 2e-3,
                      switching: Literal["grid", "subcell"] = "subcell") -> SteadyStateRule:
    """The validated :class:`SteadyStateRule`; defaults scale with the amplitude decay time
    ``2 rho / eta`` of the damped bar: a transient of 3 decay times, at most 12 decay times per
    frequency (``max_time`` is required without damping)."""
    eta = _check_finite("eta", eta, nonnegative=True)
    for name, val in (("n_periods_transient", n_periods_transient),
                      ("n_periods_average", n_periods_average)):
        if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {val!r}")
    if n_periods_average < 2:
        raise ValueError("n_periods_average must be >= 2")
    _check_finite("tol", tol, positive=True)
    decay = 2.0 * params.rho / eta if eta > 0.0 else math.inf
    if min_transient_time is None:
        min_transient_time = 3.0 * decay if eta > 0.0 else 0.0
    if max_time is None:
        if eta == 0.0:
            raise ValueError("max_time is required without damping (eta = 0)")
        max_time = 12.0 * decay
    min_transient_time = _check_finite("min_transient_time", min_transient_time,
                                       nonnegative=True)
    max_time = _check_finite("max_time", max_time, positive=True)
    if switching not in ("grid", "subcell"):
        raise ValueError(f"switching must be 'grid' or 'subcell', got {switching!r}")
    return SteadyStateRule(int(n_periods_transient), int(n_periods_average),
                           float(min_transient_time), float(max_time), float(tol), switching)


def _check_omegas(omegas: Sequence[float] | np.ndarray) -> np.ndarray:
    """The forcing frequencies as a 1-D array, refused unless positive and finite."""
    om_arr = np.asarray(omegas, dtype=float)
    if om_arr.ndim != 1 or om_arr.size == 0 or not np.all(np.isfinite(om_arr)) \
            or np.any(om_arr <= 0.0):
        raise ValueError("omegas must be a non-empty 1-D array of positive finite frequencies")
    return om_arr


def _average_until_steady(params: BarParams, load: Loading, state: BarState, period: float,
                          rule: SteadyStateRule, steps: int
                          ) -> tuple[SimulationResult, np.ndarray, int, int]:
    """Blocks of ``n_periods_average`` forcing periods until the energy averaged over each
    period of a block (:func:`period_averages`) is k-periodic (:func:`steady_multiple`) or
    ``max_time`` has been simulated (``steps`` already done at this frequency). Returns the last
    block, its period averages, k (0: not steady) and the total number of steps."""
    dt = params.time_step
    n_blk = int(math.ceil(rule.n_periods_average * period / dt)) + 1
    while True:
        res = simulate(params, load, n_blk, state, switching=rule.switching)
        state = res.final
        steps += n_blk
        avgs = period_averages(res.t, res.energy, period, rule.n_periods_average)
        k = steady_multiple(avgs, rule.tol)
        if k or steps * dt >= rule.max_time:
            return res, avgs, k, steps


def _steady_mean(averages: np.ndarray, k: int) -> float:
    """Mean energy over a whole number of steady (sub)harmonic periods k T of the block (all
    of the block when not steady)."""
    if k:
        n_use = k * (len(averages) // k)
        return float(np.mean(averages[-n_use:]))
    return float(np.mean(averages))


def forced_response_point(params: BarParams, base: Loading, omega: float, state: BarState,
                          phase: float, rule: SteadyStateRule
                          ) -> tuple[ForcedPoint, BarState, float]:
    """The steady state at the forcing frequency ``omega`` (section 7) from ``state``, whose
    time origin is shifted so that the forcing phase ``omega t`` equals ``phase`` at its start
    (wall position and force continuous when ``state`` ends the previous frequency): a
    transient (:class:`SteadyStateRule`), then :func:`_average_until_steady`. ``base`` holds the
    amplitudes and the damping (its ``omega`` is replaced). Returns the point, the final state
    and the forcing phase there (to warm-start the next frequency)."""
    t1 = time.perf_counter()
    st = replace(state, t=phase / omega)
    load = replace(base, omega=float(omega))
    T = 2.0 * math.pi / omega
    dt = params.time_step
    n_tr = int(math.ceil(max(rule.n_periods_transient * T, rule.min_transient_time) / dt))
    steps = 0
    if n_tr:
        st = simulate(params, load, n_tr, st, switching=rule.switching).final
        steps += n_tr
    res, avgs, k, steps = _average_until_steady(params, load, st, T, rule, steps)
    st = res.final
    pt = ForcedPoint(float(omega), _steady_mean(avgs, k), avgs, bool(k), int(k),
                     float(np.mean(res.contact)), float(np.max(res.u_end)),
                     float(np.min(res.u_end)), steps, time.perf_counter() - t1)
    return pt, st, math.fmod(omega * st.t, 2.0 * math.pi)


def forced_response_sweep(
    params: BarParams,
    omegas: Sequence[float] | np.ndarray,
    eta: float,
    w0: float = 0.0,
    f0: float = 0.0,
    n_periods_transient: int = 10,
    n_periods_average: int = 8,
    min_transient_time: float | None = None,
    max_time: float | None = None,
    tol: float = 2e-3,
    continuation: bool = True,
    switching: Literal["grid", "subcell"] = "subcell",
    state: BarState | None = None,
    progress: Callable[[ForcedPoint], None] | None = None,
) -> ForcedSweep:
    """Steady-state forced response (section 7, Figs. 20-22) over ``omegas`` (rad/time unit).

    For each frequency (:func:`forced_response_point`): a transient of ``n_periods_transient``
    forcing periods, at least ``min_transient_time`` (default: 3 amplitude decay times
    ``3 * 2 rho / eta``), is discarded; then blocks of ``n_periods_average`` periods are run
    and the energy (elastic + kinetic) is averaged over each period of the block
    (:func:`period_averages`). The response is *steady* when these averages are k-periodic
    (k <= 4; k > 1 is a subharmonic response) to ``tol`` (:func:`steady_multiple`); blocks are
    added until it is, or until ``max_time`` (default 12 decay times) has been simulated at this
    frequency. A point that never settles is reported with ``steady=False`` (quasi-periodic or
    chaotic, as in the paper where no NSM branch exists) and the mean over its last block.

    With ``continuation`` the final state of one frequency starts the next one, with the time
    origin shifted so that the forcing phase ``omega t`` is continuous (wall position and force
    continuous). ``switching``: see :func:`simulate` (``"subcell"`` by default: with the wall
    moving, contact switches fall anywhere in a step and the grid rule of Algorithm 2 makes the
    period-averaged energy jitter by a few percent at N = 100, which hides the steady states).
    """
    om_arr = _check_omegas(omegas)
    rule = steady_state_rule(params, eta, n_periods_transient, n_periods_average,
                             min_transient_time, max_time, tol, switching)
    base = Loading(f0=f0, w0=w0, eta=float(eta))
    sweep = ForcedSweep(params, float(eta), float(w0), float(f0))
    st = rest_state(params) if state is None else state.copy()
    tic = time.perf_counter()
    phase = 0.0
    for om in om_arr:
        if not continuation:
            st = rest_state(params) if state is None else state.copy()
            phase = 0.0
        pt, st, phase = forced_response_point(params, base, float(om), st, phase, rule)
        sweep.points.append(pt)
        if progress is not None:
            progress(pt)
    sweep.wall_time = time.perf_counter() - tic
    return sweep



__all__ = [
    "ForcedPoint",
    "ForcedSweep",
    "SteadyStateRule",
    "forced_response_point",
    "forced_response_sweep",
    "period_averages",
    "steady_multiple",
    "steady_state_rule",
]
