"""The period-doubling cascade of the double pendulum (Nordmark & Piiroinen 2009, sec. 6.2) as
one bifurcation diagram, timed and cross-checked.

Runs ``yaml_cases/pendulum_sec6_2_cascade.yaml`` (``analysis.branch_switching``: the period-2
orbit continued in ``d``, every period doubling switched at, ``--depth`` generations: 2 gives
periods 4 and 8 and locates the 8 -> 16 doubling on the period-8 branch, 3 also follows the
period-16 family) and prints:

* the time of each branch and of the whole run (target: the cascade to period 8 in < 5 min
  on this machine);
* the located doublings, the intervals between them and their ratios, against Feigenbaum's
  ``delta = 4.6692``;
* the non-trivial multipliers at each doubling (one at -1, the others zero to round-off: the
  return map of orbits that stick has rank one, README "Bifurcation diagrams");
* the brute-force values of ``benchmarks/brute_force_pendulum.py`` (``benchmarks/README.md``:
  2 -> 4 at ``d_PD = 0.5010011`` from the splitting fit, 0.5010007 from the multiplier
  extrapolation, first period-4 attractor at 0.501000; 4 -> 8 near 0.50107-0.50108);
* unless ``--no-brute``: a second, independent check by direct simulation (no Newton, no
  continuation: :func:`nsm_continuation.problems.impacting.brute_force.sweep`): the attractor
  at the midpoint of each interval between located doublings must have the period of the
  branch that is stable there (4, 8, 16).

Usage::

    python benchmarks/bench_cascade.py                 # depth 2 (to period 8), brute check
    python benchmarks/bench_cascade.py --depth 3       # and the period-16 family
    python benchmarks/bench_cascade.py --out runs/cascade --no-brute
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import nsm_continuation as nsm

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "yaml_cases" / "pendulum_sec6_2_cascade.yaml"
FIG9 = {"restitution": 0.19, "torque": -40.0}
BRUTE = {"2->4 (splitting fit)": 0.5010011, "2->4 (multiplier extrapolation)": 0.5010007,
         "2->4 (first period-4 attractor)": 0.501000, "4->8 (attractor count)": "0.50107-0.50108"}


def brute_periods(points: list[float]) -> list[tuple[float, int | None, int]]:
    """``(d, period of the simulated attractor, returns simulated)`` at the midpoints of the
    intervals between successive located doublings, each swept up from the period-2 orbit at
    d = 0.5009 (found by simulation from the default state)."""
    from nsm_continuation.problems.impacting.brute_force import sweep

    start = sweep("d", [0.5009], FIG9, 150, 4, converge_tol=1e-11)[0].state
    mids = [(a + b) / 2 for a, b in zip(points, points[1:], strict=False)]
    out = []
    state = start
    # approach each midpoint in small steps so the attractor is followed, not jumped over
    d = 0.5009
    for m in mids:
        path = np.linspace(d, m, 6)[1:]
        pts = sweep("d", path, FIG9, 200, 64, initial=state, converge_tol=1e-10,
                    max_period=32)
        state, d = pts[-1].state, m
        p = pts[-1]
        out.append((m, p.period(1e-7, max_period=32), int(p.q2.size)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depth", type=int, default=2, help="generations of switched branches")
    ap.add_argument("--out", type=Path, default=None, help="also save the run here")
    ap.add_argument("--no-brute", action="store_true", help="skip the simulation check")
    a = ap.parse_args()
    t0 = time.perf_counter()
    res = nsm.run(CASE, {"analysis.branch_switching.depth": a.depth, "output.progress": False})
    wall = time.perf_counter() - t0
    run = res.run_result
    print(f"case {CASE.relative_to(ROOT)}, depth {a.depth}: {len(run.branches)} branches, "
          f"{run.timings['n_points']} points, {wall:.1f} s wall "
          f"(diagram part {run.timings.get('diagram_s', 0.0):.1f} s)")
    for br, t in zip(run.branches, run.timings["per_branch_s"], strict=False):
        k = br.info.get("period_multiple", br.info.get("returns"))
        print(f"  branch {br.id}: period {k}, {br.n_points} points, {t:.1f} s; "
              f"{'; '.join(f'{x}: {y}' for x, y in br.termination.items())}")
    for node in run.tree:
        print(f"  tree: generation {node['depth']}, branch {node['parent']} "
              f"{node['event']['kind']} #{node['event']['index']} at d = "
              f"{node['parameter']:.10f} -> {node['child']} ({node['status'][:100]})")
    rep = res.report()
    cascade = rep.get("diagram", {}).get("period_doubling_cascade")
    if not cascade:
        print("no cascade (fewer than two doublings located)")
        return
    print("located doublings (d):")
    for q in cascade["points"]:
        br = run.branches[q["branch"]]
        [ev] = [e for e in br.events if e.kind == "period_doubling"
                and abs(e.point.y[-1] - q["parameter"]) < 1e-12]
        mult = np.sort_complex(ev.point.multipliers)
        print(f"  {q['period_multiple']:>2} -> {q['to']:<2}  d = {q['parameter']:.10f}   "
              f"multipliers {', '.join(f'{z.real:+.3e}' for z in mult)}")
    print("intervals:", ", ".join(f"{g:.6e}" for g in cascade["intervals"]))
    print("ratios:   ", ", ".join(f"{r:.4f}" for r in cascade["ratios"]),
          f"(Feigenbaum delta = {cascade['feigenbaum_delta']:.4f})")
    print("brute force (benchmarks/README.md):", json.dumps(BRUTE))
    if not a.no_brute:
        tb = time.perf_counter()
        points = [q["parameter"] for q in cascade["points"]]
        for m, per, n in brute_periods(points):
            print(f"  simulated attractor at d = {m:.8f}: period {per} ({n} recorded returns "
                  "of the section q1 = pi/2; 2 returns per period-2 orbit)")
        print(f"  brute-force check: {time.perf_counter() - tb:.1f} s")
    if a.out is not None:
        print("saved:", res.save(a.out, overwrite=True))


if __name__ == "__main__":
    main()
