"""Internal resonances of branch 1 of the 5-dof chain (docs/internal_resonances.md): every
``m/k`` resonance (a multiplier ``exp(2 pi i m / k)``) of the one-impact family, located on the
closed form (R1) of :mod:`nsm_continuation.problems.chain.resonance`, checked against the
hybrid model's simulated multipliers there, switched onto (the period-``k`` family,
:mod:`nsm_continuation.algorithms.resonance_switching`) and followed for ``--points`` points
each way; per resonance: its frequency, the hybrid multiplier's distance to
``exp(2 pi i m / k)``, the switch's outcome, the family's extent, impacts per period, end reason
and wall time, and every orbit checked by a direct simulation (``tests/oracles/chain_direct.py``).

    python benchmarks/bench_internal_resonance.py [--orders 3 4 5] [--points 40]
                                                  [--only OMEGA ...]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from nsm_continuation.problems.chain.hybrid_model import NDofImpactHybridProblem  # noqa: E402
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem  # noqa: E402
from nsm_continuation.problems.chain.resonance import resonance_frequencies  # noqa: E402
from oracles.chain_direct import direct_period  # noqa: E402

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation.algorithms.switching import null_vector  # noqa: E402
from nsm_continuation.core.palc import ContinuationEngine  # noqa: E402
from nsm_continuation.core.settings import ContinuationSettings  # noqa: E402

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
BRANCH1 = (1.4233, 1.5955)


def hybrid_distance(w: float, k: int, m: int) -> float:
    """Distance of the hybrid model's nearest multiplier to ``exp(2 pi i m / k)`` at the
    one-impact orbit of frequency ``w`` (corrected in that model)."""
    pb = NDofImpactHybridProblem(CHAIN)
    pb.set_parameter("omega", 1)
    (sp,) = pb.start_points({"omega": w})
    e = np.zeros(len(sp.y))
    e[pb.parameter_index] = 1.0
    y, _, why = ContinuationEngine(pb, ContinuationSettings()).correct(sp.y, e, sp.y, 0.0)
    if y is None:
        return float("nan")
    fl = pb.floquet(y, null_vector(pb.jacobian(y)))
    return float(np.min(np.abs(np.asarray(fl.multipliers) - np.exp(2j * np.pi * m / k))))


def verify(pb: NDofImpactHybridProblem, branch, k: int) -> dict:
    """Every orbit of ``branch`` by the direct simulation of ``tests/oracles/chain_direct.py``
    (SciPy's DOP853 between located impacts, no part of the package): the worst relative
    periodicity defect over the reported period, energy spread over the impacts, ``|beta| T``,
    the orbits whose direct impact count is not ``k``, and the smallest relative distance of
    the state after one base period (``> 0``: no period-1 orbit)."""
    M, K = pb.modal.M, pb.modal.K
    c, g, n = pb.chain_problem.c, pb.chain_problem.g, M.shape[0]
    out = {"periodic": 0.0, "energy": 0.0, "beta_T": 0.0, "not_k_impacts": 0,
           "off_parent": np.inf}
    for p in branch.points:
        T = float(p.derived["period"])
        x0 = pb.shooting.x0(p.y)[: 2 * n]
        scale = float(np.max(np.abs(x0)))
        xT, impacts, energies = direct_period(M, K, c, g, x0, T)
        x1, _, _ = direct_period(M, K, c, g, x0, T / k)
        out["periodic"] = max(out["periodic"], float(np.max(np.abs(xT - x0))) / scale)
        out["energy"] = max(out["energy"], float(np.ptp(energies)) / energies[0])
        out["beta_T"] = max(out["beta_T"], abs(float(p.derived["beta"])) * T)
        out["not_k_impacts"] += int(not len(impacts) == k == int(p.derived["n_impacts"]))
        out["off_parent"] = min(out["off_parent"], float(np.max(np.abs(x1 - x0))) / scale)
    return out


def follow(w: float, k: int, m: int, points: int) -> dict:
    """The period-``k`` family born at the resonance ``w``: a run with a resonance start."""
    t0 = time.perf_counter()
    pb = NDofImpactHybridProblem(CHAIN)
    try:
        res = nsm.continuation(pb, {"resonance": {"order": k, "rotation": m, "omega": w}},
                               parameter="omega", min=1.0, max=2.0,
                               step={"initial": 1e-3, "max": 0.02}, max_points=points,
                               analysis={"stability": True})
    except ValueError as exc:
        return {"outcome": str(exc), "time": time.perf_counter() - t0}
    run = res.run_result
    ok = any(br.points for br in run.branches)
    out = {"outcome": "switched" if ok else "not switched", "time": time.perf_counter() - t0,
           "branches": []}
    for br in run.branches:
        pts = br.points
        ws = [float(p.y[-1]) for p in pts]
        es = [float(p.derived.get("energy", np.nan)) for p in pts]
        imp = sorted({int(p.derived.get("n_impacts", -1)) for p in pts})
        beta = max((abs(float(p.derived.get("beta", 0.0))) for p in pts), default=np.nan)
        out["branches"].append({
            "label": br.label, "points": len(pts),
            "omega": (min(ws), max(ws)) if ws else None,
            "energy": (min(es), max(es)) if es else None, "impacts": imp,
            "max_beta": beta, "end": br.termination,
            "events": [(ev.kind, round(float(ev.point.y[-1]), 8)) for ev in br.events],
            "direct": verify(pb, br, k) if pts else None})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", type=int, nargs="+", default=[3, 4, 5])
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--only", type=float, nargs="*", default=None,
                    help="only the resonances within 1e-3 of these frequencies")
    a = ap.parse_args()
    cf = NDofImpactProblem(CHAIN)
    print(f"load average {os.getloadavg()[0]:.2f}")
    for k in a.orders:
        for m in range(1, (k + 1) // 2):
            if np.gcd(m, k) != 1:
                continue
            t0 = time.perf_counter()
            roots = resonance_frequencies(cf, k, m, *BRANCH1)
            print(f"\n{m}/{k}: {len(roots)} resonances on branch 1 (closed form, "
                  f"{time.perf_counter() - t0:.2f} s): {[f'{w:.10f}' for w in roots]}")
            for w in roots:
                if a.only and not any(abs(w - o) < 1e-3 for o in a.only):
                    continue
                d = hybrid_distance(w, k, m)
                r = follow(w, k, m, a.points)
                print(f"  omega* = {w:.12f}: hybrid multiplier off exp(2 pi i {m}/{k}) by "
                      f"{d:.2e}; {r['outcome']} ({r['time']:.1f} s)")
                for b in r.get("branches", []):
                    print(f"    {b['label']}: {b['points']} points, omega {b['omega']}, "
                          f"energy {b['energy']}, impacts {b['impacts']}, max |beta| "
                          f"{b['max_beta']:.1e}, events {b['events']}, end {b['end']}")
                    if b["direct"]:
                        print("      direct simulation: " + ", ".join(
                            f"{key} {v:.2g}" for key, v in b["direct"].items()))
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
