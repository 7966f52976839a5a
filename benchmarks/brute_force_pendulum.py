"""Brute-force bifurcation diagrams of the double pendulum (Nordmark & Piiroinen 2009, sec. 6).

An independent cross-check of the continuation: the attractor is simulated section to section
(``q1 = pi/2`` mod ``2 pi``, no sensitivities, no Newton) with
:func:`nsm_continuation.problems.impacting.brute_force.sweep`, each parameter value starting from
the previous value's final state. Three scenarios:

* **Fig. 8(b)**: ``e`` from 0.85 to 0.92 (``d = 0.5``, ``T = -31.15``). The stable period-1 orbit
  with complete chattering loses its sticking at ``e*`` (sec. 6.1). Reported: the last ``e``
  whose recorded ``q2`` is a single point and the first where it is not, the last ``e`` whose
  returns all stick and the first where none does, ``e*`` from a linear fit of ``tau^2`` (the
  sticking time ``tau`` vanishes like ``sqrt(e* - e)``), and ``q2`` against a Newton solve of
  the shooting residual started from the simulated orbit; beyond ``e*`` the spread of the
  recorded ``q2`` against ``e - e*`` (log-log slope ``kappa``, paper: slightly above 1.2).
* **Fig. 9(b)-(c)**: ``d`` from 0.5000 to 0.5020 (``e = 0.19``, ``T = -40``), two sweeps
  from the period-2 orbit at ``d = 0.5009`` (up and down), plus a zoom on the period-doubling
  cascade. Reported: where the number of distinct ``q2`` values goes 2 -> 4, ``d_PD`` from a
  linear fit of the squared splitting of the period-4 orbit (``~ d - d_PD``), and, for
  comparison, the multiplier of the shooting Jacobian (2 returns) evaluated at the simulated
  period-2 orbits, interpolated to -1.
* **Fig. 10(b)**: ``T`` from -31.30 to -31.02 (``e = 0.9``, ``d = 0.5``): the return time
  (period), then the approach to the homoclinic orbit (sec. 6.3): the last torque ``T_h`` with a
  periodic orbit (bisection: beyond it the pendulum comes to rest on the wall) and the periods at
  ``T_h - delta``, ``delta = 1e-3 ... 1e-10``, with the fit ``period = c - ln(delta) / mu``.

Charts (``benchmarks/results/``, git-ignored): ``brute_force_fig8b.png``,
``brute_force_fig9bc.png`` (overview and zoom), ``brute_force_fig10b.png``; the numbers go to
``brute_force_summary.json`` and stdout.

``--quick``: coarse grids, short transients (< 1 min on 2 cores); the default is the full run
(~4.5-5.5 min on 2 shared cores; measured numbers in ``benchmarks/README.md``). The sweeps are
Dask tasks, the same tasks whatever runs them: Fig. 8(b), Fig. 9(b) up, Fig. 9(b)
down, Fig. 9(c) zoom and Fig. 10 (each a chain of values warm-started from the previous one,
so not split further); ``--workers N`` (default 2) runs them on a local cluster of N
single-threaded worker processes (:func:`nsm_continuation.runs.execution.start_client`, as
``nsm-continuation run --workers``), ``--scheduler tcp://HOST:8786`` on an existing cluster,
``--workers 1`` in this process. The results are merged by name, so the numbers do not depend
on where or in which order the tasks ran. ``--jobs N`` is a deprecated alias of ``--workers``.
``--only fig8b fig9 fig10``: a subset.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import time  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from nsm_continuation.problems.impacting.brute_force import (  # noqa: E402
    PendulumSweeper,
    SweepPoint,
    sweep,
    wrap,
)
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem  # noqa: E402

from nsm_continuation.hybrid.simulate import SimulationError  # noqa: E402
from nsm_continuation.runs.execution import Execution, dask_session  # noqa: E402

OUT = Path(__file__).resolve().parent / "results"
FIG8 = {"d": 0.5, "torque": -31.15}
FIG9 = {"e": 0.19, "torque": -40.0}
FIG10 = {"e": 0.9, "d": 0.5}
PAPER = {"e_star_fig8c": 0.896, "d_pd": 0.5010, "period_T_m31_09": 7.25,
         "T_fig11": -31.001666, "period_fig11": 76.26, "T_saddle": -31.00166609425}


def grid(a: float, b: float, step: float) -> np.ndarray:
    """``a, a + step, ...`` up to ``b`` (included when on the grid, never exceeded)."""
    n = int(np.floor((b - a) / step + 1e-9))
    return np.round(a + step * np.arange(n + 1), 10)


def merge(*parts: np.ndarray) -> np.ndarray:
    return np.unique(np.round(np.concatenate(parts), 10))


def summary_point(p: SweepPoint) -> dict[str, Any]:
    return {"value": p.value, "n_recorded": int(p.q2.size), "period": p.period(1e-7),
            "n_distinct_1e-6": p.n_distinct(1e-6),
            "q2_range": [float(p.q2.min()), float(p.q2.max())] if p.ok else None,
            "return_time_mean": float(p.return_times.mean()) if p.ok else None,
            "sticking_time_min": float(p.sticking_times.min()) if p.ok else None,
            "all_sticking": p.all_sticking, "failures": p.failures, "wall_s": p.wall}


# ---------------------------------------------------------------------------------- Fig. 8(b)
def run_fig8(quick: bool) -> dict[str, Any]:
    t0 = time.perf_counter()
    # segments: (values, transient, recorded); each continues from the previous one's end
    if quick:
        segs = [(merge(grid(0.85, 0.89, 0.02), grid(0.892, 0.896, 0.001),
                       grid(0.90, 0.92, 0.01)), 10, 10)]
    else:
        segs = [(merge(grid(0.85, 0.89, 0.0025), grid(0.89, 0.8944, 0.0005)), 20, 16),
                (grid(0.89441, 0.8945, 0.00001), 20, 12),      # bracket of e*
                (grid(0.895, 0.92, 0.001), 10, 30)]
    pts: list[SweepPoint] = []
    for values, tr, rec in segs:
        pts += sweep("e", values, FIG8, tr, rec, initial=pts[-1].state if pts else None,
                     converge_tol=1e-10, max_period=8, progress=not quick)
    res: dict[str, Any] = {"points": pts, "sweep_s": time.perf_counter() - t0}
    # a single point: spread of the recorded q2 below 1e-8 rad (n_distinct would merge a
    # densely filled small attractor into one cluster)
    single = [p.value for p in pts if p.ok and np.ptp(p.q2) < 1e-8]
    multi = [p.value for p in pts if p.ok and np.ptp(p.q2) >= 1e-8]
    stick = [p.value for p in pts if p.all_sticking]
    nostick = [p.value for p in pts if p.ok and not p.any_sticking]
    res["last_single_point"] = max(single) if single else None
    res["first_not_single"] = min((v for v in multi if not single or v > max(single)),
                                  default=None)
    res["last_all_sticking"] = max(stick) if stick else None
    res["first_no_sticking"] = min((v for v in nostick if not stick or v > max(stick)),
                                   default=None)
    # tau^2 ~ (e* - e): fit on the last sticking points below e*
    sp = [p for p in pts if p.all_sticking and p.value <= (res["last_all_sticking"] or 0)]
    sp = sp[-6:]
    if len(sp) >= 3:
        e = np.array([p.value for p in sp])
        tau2 = np.array([np.mean(p.sticking_times) ** 2 for p in sp])
        k, c0 = np.polyfit(e, tau2, 1)
        res["e_star_fit_tau2"] = float(-c0 / k)
        # size of the attractor beyond e*: ~ (e - e*)^kappa (paper: kappa slightly above 1.2)
        es = res["e_star_fit_tau2"]
        big = [(p.value - es, float(np.ptp(p.q2))) for p in pts
               if p.ok and es < p.value <= es + 2e-3 and np.ptp(p.q2) > 0]
        res["attractor_size"] = big
        if len(big) >= 3:
            de, size = np.array(big).T
            res["kappa_fit"] = float(np.polyfit(np.log(de), np.log(size), 1)[0])
    # Newton on the shooting residual from the simulated orbit (the continuation's equations)
    pb = DoublePendulumProblem({**FIG8, "e": 0.89})
    pb.set_parameter("e")
    checks = []
    for target in ([0.85, 0.89] if quick else [0.85, 0.87, 0.89, 0.8935, 0.8944]):
        p = min(pts, key=lambda q: abs(q.value - target))
        if not p.all_sticking or p.n_distinct(1e-6) != 1:
            continue
        y = np.append(p.state[1:4], p.value)
        y0 = y.copy()
        for _ in range(6):
            g, J = pb.shooting.residual_jacobian(y)
            dy = np.linalg.lstsq(J[:, :3], -g, rcond=None)[0]
            y[:3] += dy
            if np.max(np.abs(dy)) < 1e-13:
                break
        checks.append({"e": p.value, "q2_brute_force": float(wrap(y0[0])),
                       "q2_newton": float(wrap(y[0])),
                       "max_state_difference": float(np.max(np.abs(wrap(y0[:3] - y[:3])))),
                       "residual": float(np.max(np.abs(pb.shooting.residual_jacobian(y)[0])))})
    res["newton_checks"] = checks
    res["total_s"] = time.perf_counter() - t0
    return res


def plot_fig8(res: dict[str, Any], path: Path) -> None:
    pts: list[SweepPoint] = res["points"]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 7.5), sharex=True,
                                  gridspec_kw={"height_ratios": [2.2, 1]})
    for p in pts:
        if not p.ok:
            ax.axvline(p.value, color="0.8", lw=0.5)
            continue
        col = np.where(p.n_sticking > 0, "tab:blue", "k")
        ax.scatter(np.full(p.q2.size, p.value), p.q2, s=2, c=col, lw=0)
    ax.scatter([], [], s=8, c="tab:blue", label="return with sticking (complete chattering)")
    ax.scatter([], [], s=8, c="k", label="return without sticking")
    for key, ls, lab in (("e_star_fit_tau2", "--", "e* (fit of tau^2)"),):
        if res.get(key):
            ax.axvline(res[key], color="tab:red", ls=ls, lw=0.8, label=f"{lab} = {res[key]:.5f}")
            ax2.axvline(res[key], color="tab:red", ls=ls, lw=0.8)
    ax.axvline(PAPER["e_star_fig8c"], color="tab:green", ls=":", lw=0.8,
               label="e = 0.896 (paper Fig. 8(c): no sticking)")
    ax.set_ylabel("q2 at the section q1 = pi/2 [rad]")
    ax.set_title("Fig. 8(b), brute force: d = 0.5, T = -31.15, e increasing")
    ax.legend(fontsize=8, loc="lower left")
    for p in pts:
        if p.ok:
            ax2.scatter(np.full(p.q2.size, p.value), p.sticking_times, s=2, c="tab:blue", lw=0)
    ax2.set_xlabel("coefficient of restitution e")
    ax2.set_ylabel("sticking time per return [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


# ------------------------------------------------------------------------------- Fig. 9(b)-(c)
def _split(p: SweepPoint) -> float:
    """Splitting of a period-4 orbit: spread of the q2 values near the lower period-2 value."""
    lo = p.q2[p.q2 < np.median(p.q2)] if p.q2.size else p.q2
    return float(np.ptp(lo)) if lo.size else np.nan


def _fig9_start(tr0: int) -> np.ndarray:
    """The period-2 orbit at d = 0.5009 from the default initial state."""
    return sweep("d", [0.5009], FIG9, tr0, 4, converge_tol=1e-11)[0].state


def run_fig9_overview(quick: bool, side: str) -> dict[str, Any]:
    """Fig. 9(b): one of the two sweeps (``side``: ``up`` or ``down``) from the period-2
    orbit at d = 0.5009 (each task finds that orbit itself: the same state for both)."""
    t0 = time.perf_counter()
    d0 = 0.5009
    if quick:
        up, down, tr0, tr, rec = grid(d0, 0.5020, 2e-4), grid(0.5000, d0, 3e-4)[::-1], 60, 20, 12
    else:
        up, down, tr0, tr, rec = grid(d0, 0.5020, 2.5e-5), grid(0.5000, d0, 4e-5)[::-1], 150, 40, 24
    X0 = _fig9_start(tr0)
    pts = sweep("d", up if side == "up" else down, FIG9, tr, rec, initial=X0,
                converge_tol=1e-10, progress=not quick)
    return {side: pts, "total_s": time.perf_counter() - t0}


def classify_pd(p: SweepPoint) -> str:
    """``period-2``, ``-> period-2`` (4 distinct values, but the alternation
    ``|q2[k+2] - q2[k]|`` decays: a slow transient near the flip, multiplier near -1),
    ``period-4`` (4 distinct values, not decaying) or ``other``."""
    if not p.ok:
        return "failed"
    n = p.n_distinct(1e-6)
    if n == 2:
        return "period-2"
    a = np.abs(wrap(p.q2[2:] - p.q2[:-2]))
    q = max(len(a) // 4, 2)
    decaying = a[-q:].mean() < 0.9 * a[:q].mean()
    if n == 4 or (decaying and p.period(1e-4) in (2, 4)):
        return "-> period-2" if decaying else "period-4"
    return "other"


def run_fig9_zoom(quick: bool) -> dict[str, Any]:
    """Fig. 9(c): the first period doubling and the cascade, finely."""
    t0 = time.perf_counter()
    d0 = 0.5009
    if quick:
        zoom, tr0, tr, trz, recz = grid(0.50098, 0.50108, 2e-5), 60, 20, 50, 16
    else:
        zoom, tr0, tr, trz, recz = grid(0.50094, 0.50116, 4e-6), 150, 40, 100, 32
    X0 = _fig9_start(tr0)
    # continue the period-2 orbit to the zoom window
    below = sweep("d", grid(d0, zoom[0], 2e-5), FIG9, tr, 8, initial=X0, converge_tol=1e-11)
    pts_z = sweep("d", zoom, FIG9, trz, recz, initial=below[-1].state, converge_tol=1e-10,
                  progress=not quick)
    res: dict[str, Any] = {"zoom": pts_z}
    nd = [(p.value, p.n_distinct(1e-6)) for p in pts_z if p.ok]
    two = [v for v, n in nd if n == 2]
    res["last_two_distinct"] = max(two) if two else None
    four = [v for v, n in nd if n == 4 and (not two or v > max(two))]
    res["first_four_distinct"] = min(four) if four else None
    cls = [(p.value, classify_pd(p)) for p in pts_z]
    res["classes"] = cls
    p2 = [v for v, c in cls if c in ("period-2", "-> period-2")]
    res["last_period2"] = max(p2) if p2 else None
    p4 = [v for v, c in cls if c == "period-4" and (not p2 or v > max(p2))]
    res["first_period4"] = min(p4) if p4 else None
    # squared splitting of clean period-4 orbits: linear in d - d_PD
    clean = [p for p in pts_z if p.ok and p.period(1e-8) == 4 and _split(p) > 1e-4]
    if len(clean) >= 3:
        dd = np.array([p.value for p in clean])
        s2 = np.array([_split(p) ** 2 for p in clean])
        use = dd <= dd.min() + 4e-5
        k, c0 = np.polyfit(dd[use], s2[use], 1)
        res["d_pd_fit_split2"] = float(-c0 / k)
        res["split_fit_points"] = [float(dd[use].min()), float(dd[use].max()), int(use.sum())]
    # multipliers of the 2-return shooting Jacobian at the simulated period-2 orbits
    pb = DoublePendulumProblem({**FIG9, "d": d0})
    pb.set_parameter("d", returns=2)
    mult = []
    for p in pts_z:
        if p.ok and p.period(1e-6) == 2 and p.n_distinct(1e-6) == 2:
            y = np.append(p.state[1:4], p.value)
            fl = pb.floquet(y, None)
            if fl is not None:
                m = fl.multipliers
                mult.append((p.value, float(np.min(m.real[np.abs(m.imag) < 1e-9]))))
    res["multipliers"] = mult
    if len(mult) >= 2:
        dv, lam = np.array(mult).T
        o = np.argsort(dv)
        dv, lam = dv[o], lam[o]
        k, c0 = np.polyfit(dv[-4:], lam[-4:], 1)
        res["d_pd_multiplier"] = float((-1.0 - c0) / k)
    res["total_s"] = time.perf_counter() - t0
    return res


def plot_fig9(res: dict[str, Any], path: Path) -> None:
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(8, 9))
    for key, col, lab in (("up", "k", "d increasing from 0.5009"),
                          ("down", "tab:blue", "d decreasing from 0.5009")):
        first = True
        for p in res[key]:
            if p.ok:
                ax.scatter(np.full(p.q2.size, p.value), p.q2, s=1.5, c=col, lw=0,
                           label=lab if first else None)
                first = False
    z = res["zoom"]
    ax.axvspan(z[0].value, z[-1].value, color="tab:orange", alpha=0.15, label="zoom (c)")
    ax.set_xlabel("wall distance d")
    ax.set_ylabel("q2 at the section q1 = pi/2 [rad]")
    ax.set_title("Fig. 9(b), brute force: e = 0.19, T = -40")
    ax.legend(fontsize=8, markerscale=6)
    colours = {"period-2": "tab:blue", "-> period-2": "tab:cyan", "period-4": "k",
               "other": "0.45"}
    seen: set[str] = set()
    for p, (_, c) in zip(z, res["classes"], strict=True):
        if p.ok:
            sel = p.q2 < -1.6
            ax2.scatter(np.full(sel.sum(), p.value), p.q2[sel], s=3, c=colours[c], lw=0,
                        label=None if c in seen else c)
            seen.add(c)
    for key, col, lab in (("d_pd_fit_split2", "tab:red", "d_PD (split^2 fit)"),
                          ("d_pd_multiplier", "tab:green", "d_PD (shooting multiplier = -1)")):
        if res.get(key):
            ax2.axvline(res[key], color=col, ls="--", lw=0.8, label=f"{lab} = {res[key]:.6f}")
    ax2.axvline(PAPER["d_pd"], color="0.5", ls=":", lw=0.8, label="paper: d = 0.5010")
    ax2.set_xlabel("wall distance d")
    ax2.set_ylabel("q2 at the section (branch near -1.70) [rad]")
    ax2.set_title("Fig. 9(c), zoom: period-doubling cascade of the period-2 orbit")
    ax2.legend(fontsize=8, markerscale=3)
    ax2.ticklabel_format(axis="x", useOffset=False)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


# ---------------------------------------------------------------------------------- Fig. 10(b)
def run_fig10(quick: bool) -> dict[str, Any]:
    t0 = time.perf_counter()
    values = grid(-31.30, -31.02, 0.04 if quick else 0.01)
    pts = sweep("torque", values, FIG10, 10 if quick else 30, 8 if quick else 16,
                converge_tol=1e-10, max_time=300.0, progress=not quick)
    res: dict[str, Any] = {"points": pts}
    p09 = [p for p in pts if abs(p.value + 31.09) < 1e-9 and p.ok]
    if p09:
        res["period_T_m31_09"] = float(np.mean(p09[0].return_times))
    else:
        ts = [(p.value, np.mean(p.return_times)) for p in pts if p.ok and p.all_sticking]
        if ts:
            tv, per = np.array(ts).T
            res["period_T_m31_09"] = float(np.interp(-31.09, tv, per))
    # approach to the homoclinic orbit: continue the orbit towards T_h, then bisect
    sw = PendulumSweeper("torque", FIG10, -31.02)
    X = np.append(pts[-1].state, pts[-1].value)
    ladder = [-31.01, -31.005, -31.002, -31.0017, -31.00168, -31.00167]
    near = []
    for T in ladder:
        X[-1] = T
        for _ in range(4):
            X, r = sw.one_return(X, 3000.0)
        near.append((T, float(r.t)))
    good, lo, hi = X.copy(), -31.00167, -31.001666
    bis = 0
    while hi - lo > (1e-9 if quick else 2e-12):
        mid = 0.5 * (lo + hi)
        Y = good.copy()
        Y[-1] = mid
        try:
            for _ in range(3):
                Y, r = sw.one_return(Y, 3000.0)
            lo, good = mid, Y
        except SimulationError:
            hi = mid
        bis += 1
    res["T_h_bracket"] = [lo, hi]
    res["bisection_steps"] = bis
    Th = 0.5 * (lo + hi)
    deltas = [1e-3, 1e-5, 1e-7] if quick else [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    law = []
    for dl in deltas:
        Y = good.copy()
        Y[-1] = Th - dl
        for _ in range(4):
            Y, r = sw.one_return(Y, 3000.0)
        law.append((dl, float(r.t), float(r.sticking_time)))
    res["near_homoclinic"] = near
    res["log_law"] = law
    dl, per = np.array(law)[:, 0], np.array(law)[:, 1]
    k, c0 = np.polyfit(-np.log(dl), per, 1)
    res["mu_fit"] = float(1.0 / k)
    res["log_law_c"] = float(c0)
    try:
        Y = good.copy()
        Y[-1] = PAPER["T_saddle"]
        for _ in range(3):
            Y, r = sw.one_return(Y, 3000.0)
        res["at_T_saddle"] = f"periodic, period {r.t:.4f}"
    except SimulationError as exc:
        res["at_T_saddle"] = f"no periodic orbit: {exc.reason}"
    res["total_s"] = time.perf_counter() - t0
    return res


def plot_fig10(res: dict[str, Any], path: Path) -> None:
    pts: list[SweepPoint] = res["points"]
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.6))
    ax = axs[0]
    for p in pts:
        if p.ok:
            col = np.where(p.n_sticking > 0, "tab:blue", "k")
            ax.scatter(np.full(p.q2.size, p.value), p.q2, s=3, c=col, lw=0)
    ax.set_xlabel("torque T")
    ax.set_ylabel("q2 at the section q1 = pi/2 [rad]")
    ax.set_title("brute force: e = 0.9, d = 0.5 (blue: sticking)")
    ax = axs[1]
    for p in pts:
        if p.ok:
            ax.scatter(np.full(p.return_times.size, p.value), p.return_times, s=3,
                       c=np.where(p.n_sticking > 0, "tab:blue", "k"), lw=0)
    tn, pn = np.array(res["near_homoclinic"]).T
    ax.plot(tn, pn, "o", ms=3, color="tab:orange", label="towards T_h (continued orbit)")
    if "period_T_m31_09" in res:
        ax.plot([-31.09], [PAPER["period_T_m31_09"]], "r+", ms=10,
                label="paper: period 7.25 at T = -31.09")
    ax.set_xlabel("torque T")
    ax.set_ylabel("return time (period) [s]")
    ax.set_title("Fig. 10(b): period vs T")
    ax.legend(fontsize=8)
    ax = axs[2]
    dl, per, _ = np.array(res["log_law"]).T
    ax.semilogx(dl, per, "o", label="brute force")
    xs = np.geomspace(dl.min(), dl.max(), 50)
    ax.semilogx(xs, res["log_law_c"] - np.log(xs) * 1.0 / res["mu_fit"], "-", lw=0.8,
                label=f"c - ln(delta)/mu, mu = {res['mu_fit']:.4f}")
    ax.axhline(PAPER["period_fig11"], color="0.5", ls=":", label="paper: period 76.26")
    ax.set_xlabel(f"delta = T_h - T  (T_h = {np.mean(res['T_h_bracket']):.11f})")
    ax.set_ylabel("return time (period) [s]")
    ax.set_title("approach to the homoclinic orbit")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


# ---------------------------------------------------------------------------------- driver
#: the tasks: each a chain of sweeps (warm-started value to value), independent of the others
RUNNERS = {"fig8b": run_fig8, "fig9up": partial(run_fig9_overview, side="up"),
           "fig9down": partial(run_fig9_overview, side="down"),
           "fig9zoom": run_fig9_zoom, "fig10": run_fig10}
SCENARIOS = {"fig8b": ["fig8b"], "fig9": ["fig9up", "fig9down", "fig9zoom"], "fig10": ["fig10"]}
#: longest first, so that the workers balance
ORDER = ("fig9zoom", "fig8b", "fig10", "fig9up", "fig9down")


def run_task(name: str, quick: bool) -> dict[str, Any]:
    """One task, wherever it runs (BLAS limited to one thread)."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    return RUNNERS[name](quick)


def run_tasks(order: list[str], quick: bool, workers: int,
              scheduler: str | None) -> dict[str, dict[str, Any]]:
    """The tasks ``order`` in this process (``workers`` 1, no ``scheduler``) or as Dask tasks
    on a local cluster of ``workers`` processes or on ``scheduler``; results by name."""
    if not scheduler and (workers <= 1 or len(order) <= 1):
        return {name: run_task(name, quick) for name in order}
    with dask_session(Execution(workers=None if scheduler else workers,
                                scheduler=scheduler)) as (client, futures):
        futures += [client.submit(run_task, name, quick, pure=False, retries=2,
                                  key=f"brute-force-{name}-{time.time_ns()}") for name in order]
        return {name: f.result() for name, f in zip(order, futures, strict=True)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarse grids (< 1 min)")
    ap.add_argument("--workers", type=int, default=2,
                    help="worker processes of a local Dask cluster (1: in this process)")
    ap.add_argument("--jobs", type=int, dest="workers", help="deprecated alias of --workers")
    ap.add_argument("--scheduler", default=None, help="address of a running Dask scheduler")
    ap.add_argument("--only", nargs="*", choices=sorted(SCENARIOS), default=None)
    ap.add_argument("--out", type=Path, default=OUT, help="output directory")
    a = ap.parse_args()
    # the per-value lines of a full run (logged by nsm_continuation.hybrid.brute_force)
    logging.basicConfig(level=logging.INFO, format="  %(message)s")
    if a.workers < 1:
        ap.error("--workers: at least 1")
    a.out.mkdir(parents=True, exist_ok=True)
    names = a.only or ["fig8b", "fig9", "fig10"]
    tasks = [t for n in names for t in SCENARIOS[n]]
    order = [t for t in ORDER if t in tasks]
    t0 = time.perf_counter()
    results = run_tasks(order, a.quick, a.workers, a.scheduler)
    task_s = {name: results[name]["total_s"] for name in order}
    if "fig9zoom" in results:
        zres = results.pop("fig9zoom")
        up = results.pop("fig9up", {"up": [], "total_s": 0.0})
        down = results.pop("fig9down", {"down": [], "total_s": 0.0})
        overview_s = up["total_s"] + down["total_s"]
        results["fig9"] = {**zres, "up": up["up"], "down": down["down"],
                           "total_s": zres["total_s"] + overview_s,
                           "zoom_s": zres["total_s"], "overview_s": overview_s}
    wall = time.perf_counter() - t0
    summary: dict[str, Any] = {"mode": "quick" if a.quick else "full", "wall_s": wall,
                               "task_s": task_s, "paper": PAPER}
    if "fig8b" in results:
        r = results["fig8b"]
        plot_fig8(r, a.out / "brute_force_fig8b.png")
        summary["fig8b"] = {k: v for k, v in r.items() if k != "points"}
        summary["fig8b"]["n_values"] = len(r["points"])
        summary["fig8b"]["failures"] = [(p.value, p.failures) for p in r["points"] if p.failures]
        summary["fig8b"]["near_e_star"] = [summary_point(p) for p in r["points"]
                                           if 0.8935 <= p.value <= 0.8965]
    if "fig9" in results:
        r = results["fig9"]
        plot_fig9(r, a.out / "brute_force_fig9bc.png")
        summary["fig9"] = {k: v for k, v in r.items() if k not in ("up", "down", "zoom", "classes")}
        summary["fig9"]["n_values"] = sum(len(r[k]) for k in ("up", "down", "zoom"))
        summary["fig9"]["zoom"] = [{**summary_point(p), "class": c}
                                   for p, (_, c) in zip(r["zoom"], r["classes"], strict=True)]
        summary["fig9"]["failures"] = [(p.value, p.failures) for k in ("up", "down", "zoom")
                                       for p in r[k] if p.failures]
    if "fig10" in results:
        r = results["fig10"]
        plot_fig10(r, a.out / "brute_force_fig10b.png")
        summary["fig10"] = {k: v for k, v in r.items() if k != "points"}
        summary["fig10"]["sweep"] = [(p.value, float(np.mean(p.return_times)) if p.ok else None,
                                      p.period(1e-7), p.all_sticking) for p in r["points"]]
    (a.out / "brute_force_summary.json").write_text(json.dumps(summary, indent=1, default=str))
    skip = ("zoom", "near_e_star", "sweep", "paper")
    for k, v in summary.items():
        if isinstance(v, dict):
            print(f"{k}:")
            for kk, vv in v.items():
                if kk not in skip:
                    print(f"  {kk}: {json.dumps(vv, default=str)}")
        else:
            print(f"{k}: {v}")
    print(f"written: {a.out}/brute_force_{{fig8b,fig9bc,fig10b}}.png, brute_force_summary.json")
    where = (f"scheduler {a.scheduler}" if a.scheduler else
             f"{a.workers} worker process{'es' if a.workers > 1 else ''}" if a.workers > 1
             else "serial")
    print(f"total wall time {wall:.1f} s ({'quick' if a.quick else 'full'}, {where}; sum of the "
          f"tasks {sum(task_s.values()):.1f} s)")


if __name__ == "__main__":
    main()
