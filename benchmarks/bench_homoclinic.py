"""The homoclinic approach of sec. 6.3: period reached, p*, mu, time.

1. The bundled case ``yaml_cases/pendulum_sec6_3_homoclinic.yaml``: the period-1 orbit of the
   double pendulum (e = 0.9, d = 0.5) continued in its PERIOD, the torque solved for, until the
   period is no longer resolved (``period_uncertainty`` 0.5). Prints the period reached, the
   homoclinic torque p* and mu of the fit ``p - p* = a1 exp(-mu T) + (a2 + a3 T)
   exp(-2 mu T)`` against the saddle's unstable eigenvalue (0.28879), the leading law alone,
   the events, and the wall time.
2. How far double precision carries the period: ``T_max = c + ln(1 / dp) / mu`` for the
   torque resolved to ``eps |p|`` and to the resolution the branch shows (its deviation from
   the law beyond period 60).
3. With ``--compare-torque``: the other set-up, the torque continued at the default
   tolerances with the period bound 80: the period reached, the spurious multiplier
   crossings reported (none: the multipliers within their noise are not classified) and the
   fit. ~1-2 min more.

Run: ``python benchmarks/bench_homoclinic.py [--compare-torque]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation.hybrid.return_map import period_reach  # noqa: E402

CASE = ROOT / "yaml_cases" / "pendulum_sec6_3_homoclinic.yaml"
MU_SADDLE = 0.28879317  # tests/oracles/pendulum_equilibria.py


def period_case() -> None:
    t0 = time.perf_counter()
    res = nsm.run(CASE, {"output.plots": False})
    wall = time.perf_counter() - t0
    (br,) = res.branches
    rep = res.report()["problem_results"]
    fit = rep["branches"][0]["homoclinic_fit"]
    T, p = br["period"], br["torque"]
    print("1. continuation in the period (yaml_cases/pendulum_sec6_3_homoclinic.yaml)")
    print(f"   wall time {wall:.1f} s, {len(br)} points, termination: {br.termination}")
    print(f"   period {T[0]:.4f} -> {T[-1]:.4f} (paper's Fig. 11 orbit: 76.26), torque "
          f"{p[0]:.12f} -> {p[-1]:.14f}")
    print(f"   period_uncertainty at the end {br['period_uncertainty'][-1]:.3g}")
    print(f"   events: {[e.kind for e in res.events]}")
    print(f"   fit on {fit['n_points']} points, periods {fit['period_range'][0]:.2f} .. "
          f"{fit['period_range'][1]:.2f}: {fit['model']}")
    print(f"   p* = {fit['p_star']:.13f} (paper's saddle torque -31.00166609425)")
    print(f"   mu = {fit['mu_unstable']:.7f} +- {fit['mu_unstable_stderr']:.1e} "
          f"(saddle {MU_SADDLE}: {100 * (fit['mu_unstable'] / MU_SADDLE - 1):+.4f} %), "
          f"weighted rms {fit['rms_residual']:.2f}")
    print(f"   leading law alone: mu = {fit['mu_leading_only']:.6f} "
          f"({100 * (fit['mu_leading_only'] / MU_SADDLE - 1):+.3f} %); c = {fit['c']:.3f}")
    eq = rep["sticking_equilibria"][0]
    print(f"   saddle at the last torque: eigenvalues {eq['eigenvalues']}")
    c, mu, p_star = fit["c"], fit["mu_unstable"], fit["p_star"]
    mid, end = (T > 40) & (T < 55), T > 60
    a = np.median((p[mid] - p_star) * np.exp(mu * T[mid]))
    dev = float(np.max(np.abs(p[end] - p_star - a * np.exp(-mu * T[end]))))
    eps = np.finfo(float).eps
    print("2. how far double precision carries the period (no digit left: dT = 1/mu)")
    print(f"   torque resolved to eps|p| = {eps * abs(p_star):.2g}: T_max = "
          f"{period_reach(c, mu, p_star):.1f}")
    print(f"   torque resolved to {dev:.2g} (deviation from the law beyond period 60, the "
          f"simulated map's round-off): T_max = {period_reach(c, mu, p_star, dev):.1f}")
    print(f"   period 150 needs |p - p*| = {np.exp(-mu * (150 - c)):.2g}")


def torque_case() -> None:
    t0 = time.perf_counter()
    res = nsm.run(CASE, {"output.plots": False, "parameters.integrator": {},
                         "start.free_parameter": None,
                         "continuation": {"parameter": "torque", "min": -31.3, "max": -30.9,
                                          "step": {"initial": 0.002, "min": 1e-12,
                                                   "max": 0.01},
                                          "max_points": 200, "newton_tol": 1e-9,
                                          "bounds": {"period": [None, 80.0]}}})
    wall = time.perf_counter() - t0
    (br,) = res.branches
    kinds = [e.kind for e in res.events]
    fit = res.report()["problem_results"]["branches"][0].get("homoclinic_fit")
    print("3. the other set-up: continued in the torque, default tolerances, period <= 80")
    print(f"   wall time {wall:.1f} s, {len(br)} points, period reached "
          f"{np.nanmax(br['period']):.2f}, termination: {br.termination}")
    print(f"   events: {kinds} (period doublings: {kinds.count('period_doubling')})")
    if fit is not None:
        print(f"   fit: p* = {fit['p_star']:.12f}, mu = {fit['mu_unstable']:.5f} "
              f"({100 * (fit['mu_unstable'] / MU_SADDLE - 1):+.2f} %)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--compare-torque", action="store_true",
                    help="also run the continuation in the torque (~1-2 min)")
    args = ap.parse_args()
    period_case()
    if args.compare_torque:
        torque_case()


if __name__ == "__main__":
    main()
