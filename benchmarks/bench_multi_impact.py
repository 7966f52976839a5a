"""The multi-impact families of the 5-dof chain, every orbit checked: the acceptance run.

Runs ``yaml_cases/ndof_hybrid_multi_impact.yaml`` (branch 1 of the chain in the hybrid model
between omega = 1.445 and 1.545 and the period-2 families born at its five period doublings),
or reads a saved run of it (``--run DIR``), and checks every orbit of every branch against the
direct simulation of ``tests/oracles/chain_direct.py`` (SciPy's DOP853 between impacts, the
wall located as an event, no part of the package):

* periodic over the reported period (``|x(T) - x(0)|_inf / |x(0)|_inf``, required <= 1e-9);
* the energy conserved at each impact (its spread over the period, relative, <= 1e-12) and
  equal to the reported one (<= 1e-12);
* the impacts as many as reported (``n_impacts``) and at the reported times (the hybrid
  simulation's impact events, to 1e-9 T): their count and order;
* the unfolding zero to rounding (``|beta| T < 1e-12``).

Prints one row per branch (orbits, impacts per period, the worst value of each check, the
branch's share of the run time) and exits 1 when a check fails. Run:
``python benchmarks/bench_multi_impact.py [--run DIR] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from oracles.chain_direct import direct_period  # noqa: E402

import nsm_continuation as nsm  # noqa: E402

CASE = ROOT / "yaml_cases" / "ndof_hybrid_multi_impact.yaml"


def check_branch(branch, problem, M: np.ndarray, K: np.ndarray, c: int, g: float
                 ) -> dict[str, float]:
    """The worst value of each check over the branch's orbits."""
    worst = {"periodic": 0.0, "energy_spread": 0.0, "energy_vs_reported": 0.0,
             "impact_times": 0.0, "beta_T": 0.0, "count_mismatches": 0}
    counts = set()
    for p in branch.points:
        x0 = problem.shooting.x0(p.y)[: 2 * M.shape[0]]
        T = float(p.derived["period"])
        xT, impacts, energies = direct_period(M, K, c, g, x0, T)
        reported = [ev.t for ev in problem.shooting.simulate(p.y).events if ev.kind == "impact"]
        n = int(p.derived["n_impacts"])
        counts.add(n)
        worst["periodic"] = max(worst["periodic"],
                                float(np.max(np.abs(xT - x0)) / np.max(np.abs(x0))))
        worst["energy_spread"] = max(worst["energy_spread"], float(np.ptp(energies))
                                     / energies[0])
        worst["energy_vs_reported"] = max(worst["energy_vs_reported"], abs(
            energies[0] / float(p.derived["energy"]) - 1.0))
        worst["beta_T"] = max(worst["beta_T"], abs(float(p.derived["beta"])) * T)
        if not (len(impacts) == n == len(reported)):
            worst["count_mismatches"] += 1
        else:
            worst["impact_times"] = max(worst["impact_times"], float(np.max(np.abs(
                np.subtract(impacts, reported)), initial=0.0)) / T)
    worst["impacts_per_period"] = sorted(counts)  # type: ignore[assignment]
    return worst


def passes(w: dict[str, float]) -> bool:
    """The requirements of the module docstring."""
    return (w["periodic"] <= 1e-9 and w["energy_spread"] <= 1e-12
            and w["energy_vs_reported"] <= 1e-12 and w["impact_times"] <= 1e-9
            and w["beta_T"] < 1e-12 and w["count_mismatches"] == 0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", help="a saved run of the case (default: run it)")
    ap.add_argument("--out", help="where to save the run (default: a temporary folder)")
    args = ap.parse_args()
    if args.run:
        res = nsm.load(args.run)
        run_s = float(res.run_result.timings.get("total_s", float("nan")))
    else:
        out = Path(args.out or tempfile.mkdtemp()) / "ndof_hybrid_multi_impact"
        t0 = time.perf_counter()
        res = nsm.run(CASE)
        run_s = time.perf_counter() - t0
        res.save(out, overwrite=True)
        print(f"run saved to {out}")
    run = res.run_result
    pb = run.problem
    M, K = pb.modal.M, pb.modal.K
    c, g = pb.chain_problem.c, pb.chain_problem.g
    per_branch = run.timings.get("per_branch_s") or []
    print(f"run: {run_s:.1f} s wall, {run.timings.get('n_points')} points\n")
    print("| branch | born at omega | orbits | impacts per period | periodic | energy spread "
          "| energy vs reported | impact times / T | max beta T | run time (s) | check |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    ok = True
    for br in run.branches:
        problem = run.branch_problems.get(br.id, pb)
        t0 = time.perf_counter()
        w = check_branch(br, problem, M, K, c, g)
        good = passes(w)
        ok &= good
        born = br.points[0].y[problem.parameter_index] if br.info.get("switch") else None
        share = per_branch[br.id] if br.id < len(per_branch) else float("nan")
        print(f"| {br.id} | {'-' if born is None else f'{born:.8f}'} | {len(br.points)} | "
              f"{w['impacts_per_period']} | {w['periodic']:.1e} | {w['energy_spread']:.1e} | "
              f"{w['energy_vs_reported']:.1e} | {w['impact_times']:.1e} | {w['beta_T']:.1e} | "
              f"{share:.1f} | {'ok' if good else 'FAIL'} ({time.perf_counter() - t0:.0f} s) |")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
