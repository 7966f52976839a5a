"""Accuracy and cost of the WFEM lattice backbone vs N, against its continuum limit.

Yoong, Thorin, Legrand (2017), sec. 6.1: main backbone of mode 1 for g0 = 1e-3 (E = rho = L = 1).
The lattice orbits (eq. 12 with COND1-COND3, :mod:`problems.bar.wfem_lattice`) of this branch sit on
the line ``m = 2M - 4N`` (``M = m + p`` steps per period, ``T = M/N`` in units L/c); the continuum
branch (:mod:`problems.bar.continuum`) is ``t_f = 2T - 4`` with the exact energy
``E/E_ref = 8 / (pi^2 (T - 3)^2)`` and the asymptote ``omega/omega_1 = 4/3``. For
N = 50 ... 4000 this script scans every node of the line on the admissible side (3N < M < 4N) and
measures:

(a) ``max |E_lattice / E_continuum - 1|`` over the admissible lattice points: the lattice points
    are exact samples of the continuum curve, so this is round-off;
(b) the sampling error of the lattice curve: the maximum, over ``omega/omega_1 in [1.02, 1.30]``
    (a grid of 4001 frequencies), of the relative error of the linear interpolation (in
    ``(omega, E)``) between consecutive lattice points, and the largest frequency gap between
    consecutive lattice points there;
(c) the asymptote estimated from the lattice: (c1) ``E^(-1/2)`` extrapolated linearly in ``T``
    from the two admissible lattice points closest to it (exact on this branch, so round-off
    again), (c2) the distance from 4/3 of the highest-frequency admissible lattice point (the
    frequency resolution near the asymptote; for large N it saturates where COND3, strains
    > -1, fails: ``|sigma| = 2 E g0 / (L |mu|) <= E`` needs ``T - 3 >= g0/L``);
(d) the wall time of the scan: ``solve_node`` on every node (orbits at nodes with ``h = 1``,
    i.e. ``gcd(M, 2N) = 1``) and ``node_solutions`` on every node (also nodes with ``h > 1``
    where the continuum orbit is a sign combination of cycle vectors, enumerated for ``h <= 8``).

The reference row "continuum" is the continuation of the same branch by the pseudo-arclength
engine on the closed form (``BarContinuumProblem``, g0 = 1e-3, up to E/E_ref = 1e3): its wall
time and its maximum deviation from the formula.

Writes ``benchmarks/out/wfem_backbone_accuracy_vs_N.png`` (errors on the left axis, wall time on
the right axis, both vs N). OpenBLAS is pinned to one thread.

    python benchmarks/bench_wfem_accuracy.py [--sizes 50 100 200 500 1000 2000 4000]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from nsm_continuation.problems.bar.continuum import (  # noqa: E402
    BarContinuumProblem,
    main_signature,
)
from nsm_continuation.problems.bar.wfem_lattice import BarModel, solve_node  # noqa: E402

from nsm_continuation.core.palc import ContinuationEngine  # noqa: E402
from nsm_continuation.core.settings import ContinuationSettings  # noqa: E402

try:  # all candidates at nodes with h > 1 (newer wfem_lattice)
    from nsm_continuation.problems.bar.wfem_lattice import node_solutions  # noqa: E402
except ImportError:  # pragma: no cover
    node_solutions = None

OUT = Path(__file__).resolve().parent / "out"
G0 = 1e-3
WINDOW = (1.02, 1.30)
SIG = main_signature(1)


def energy_ratio_continuum(T: np.ndarray) -> np.ndarray:
    """E/E_ref of the continuum main backbone of mode 1 at period T (units L/c)."""
    return 32.0 / (np.pi**2 * SIG.mu(np.asarray(T, dtype=float)) ** 2)


def scan(N: int, all_nodes: bool) -> tuple[list[tuple[float, float]], float, int]:
    """Admissible lattice points (T, E/E_ref) on m = 2M - 4N, 3N < M < 4N; wall time; nodes."""
    md = BarModel(1.0, 1.0, 1.0, N, G0)
    pts: list[tuple[float, float]] = []
    t0 = time.perf_counter()
    nodes = 0
    for M in range(3 * N + 1, 4 * N):
        m = 2 * M - 4 * N
        nodes += 1
        if all_nodes:
            _, sols = node_solutions(md, (m, M - m))
        else:
            status, sol = solve_node(md, (m, M - m))
            sols = [sol] if status == "admissible" else []
        for s in sols[:1]:  # every candidate at a node of this line is the same orbit
            pts.append((s.period, s.energy / md.energy_ref))
    return pts, time.perf_counter() - t0, nodes


def measures(pts: list[tuple[float, float]]) -> dict[str, float]:
    T = np.array([p[0] for p in pts])
    E = np.array([p[1] for p in pts])
    out = {"points": len(T), "dev": float(np.max(np.abs(E / energy_ratio_continuum(T) - 1)))}
    r = 4.0 / T
    order = np.argsort(r)
    r, E, T = r[order], E[order], T[order]
    grid = np.linspace(*WINDOW, 4001)
    inside = (r >= WINDOW[0]) & (r <= WINDOW[1])
    if r[0] > WINDOW[0] or r[-1] < WINDOW[1]:
        out["interp"] = out["gap"] = float("nan")
    else:
        e_int = np.interp(grid, r, E)
        out["interp"] = float(np.max(np.abs(e_int / energy_ratio_continuum(4.0 / grid) - 1)))
        edges = np.concatenate([r[np.nonzero(inside)[0][0] - 1:np.nonzero(inside)[0][-1] + 2]])
        out["gap"] = float(np.max(np.diff(edges)))
    # (c1) extrapolation of E^(-1/2), linear in T, from the two points nearest the asymptote
    Ta, Tb = T[-2], T[-1]
    ya, yb = E[-2] ** -0.5, E[-1] ** -0.5
    T_star = Tb + (Ta - Tb) * yb / (yb - ya)
    out["asym_extrap"] = abs(4.0 / T_star - 4.0 / 3.0)
    out["asym_last"] = abs(r[-1] - 4.0 / 3.0)
    return out


def continuum_reference() -> dict[str, float]:
    pr = BarContinuumProblem({"gap": G0})
    st = ContinuationSettings(step_initial=0.005, step_max=0.02, max_points=800,
                              derived_bounds={"energy_ratio": (None, 1e3)},
                              stop_on_inadmissible=True, detect_bifurcations=False)
    t0 = time.perf_counter()
    (start,) = pr.start_points({"branch": "main", "mode": 1})
    br = ContinuationEngine(pr, st).run(start)
    wall = time.perf_counter() - t0
    pts = [p for p in br.points if p.admissible]  # the end point sits at t_c = -4e-13
    r = np.array([p.y[0] for p in pts])
    E = np.array([p.derived["energy_ratio"] for p in pts])
    return {"points": len(br.points), "wall": wall,
            "dev": float(np.max(np.abs(E / energy_ratio_continuum(4.0 / r) - 1))),
            "r_max": float(r.max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 100, 200, 500, 1000, 2000, 4000])
    ap.add_argument("--out", type=Path, default=OUT / "wfem_backbone_accuracy_vs_N.png")
    args = ap.parse_args()

    rows = []
    for N in args.sizes:
        pts1, wall1, nodes = scan(N, all_nodes=False)
        row = {"N": N, "nodes": nodes, "wall_h1": wall1, "pts_h1": len(pts1)}
        if node_solutions is not None:
            pts, wall, _ = scan(N, all_nodes=True)
            row["wall_all"] = wall
        else:
            pts, row["wall_all"] = pts1, float("nan")
        row.update(measures(pts))
        row["interp_h1"] = measures(pts1)["interp"]
        rows.append(row)
    ref = continuum_reference()

    print("Main backbone of mode 1, g0 = 1e-3: WFEM lattice points on m = 2M - 4N (3N < M < 4N) "
          "vs the continuum limit E/E_ref = 8/(pi^2 (T - 3)^2)")
    print(f"{'N':>6} {'nodes':>6} {'pts(h=1)':>8} {'pts(all)':>8} {'(a) max dev':>11} "
          f"{'(b) interp':>10} {'(b) h=1':>9} {'(b) gap':>9} {'(c1) extrap':>11} "
          f"{'(c2) last':>9} {'(d) h=1 [s]':>11} {'(d) all [s]':>11}")
    for r in rows:
        print(f"{r['N']:>6} {r['nodes']:>6} {r['pts_h1']:>8} {r['points']:>8} {r['dev']:>11.2e} "
              f"{r['interp']:>10.2e} {r['interp_h1']:>9.2e} {r['gap']:>9.2e} "
              f"{r['asym_extrap']:>11.2e} {r['asym_last']:>9.2e} {r['wall_h1']:>11.3f} "
              f"{r['wall_all']:>11.3f}")
    print(f"continuum (engine, closed form): {ref['points']} points up to omega/omega_1 = "
          f"{ref['r_max']:.6f} (E/E_ref = 1e3), max dev {ref['dev']:.1e}, wall {ref['wall']:.3f} s")
    print("(a) lattice vs continuum energy at lattice points; (b) linear interpolation between "
          f"consecutive lattice points, max rel. energy error on omega/omega_1 in {WINDOW}, "
          "'h=1' with solve_node points only, 'gap' = largest frequency gap (omega/omega_1); "
          "(c1) |omega* - 4/3| from E^-1/2 extrapolation, (c2) |omega_last - 4/3|; (d) scan time")

    Ns = np.array([r["N"] for r in rows], dtype=float)
    fig, ax = plt.subplots(figsize=(9, 7))
    floor = 1e-17
    ax.loglog(Ns, [r["interp"] for r in rows], "o-", color="tab:blue",
              label="(b) sampling error: lin. interp. between lattice points")
    ax.loglog(Ns, [r["interp_h1"] for r in rows], "o:", color="tab:blue", mfc="none",
              label="(b) same, h = 1 nodes only (solve_node)")
    ax.loglog(Ns, [r["asym_last"] for r in rows], "^-", color="tab:green",
              label="(c2) |last lattice omega - 4/3| / omega_1")
    ax.loglog(Ns, [max(r["asym_extrap"], floor) for r in rows], "v--", color="tab:olive",
              label="(c1) asymptote from E^-1/2 extrapolation")
    ax.loglog(Ns, [max(r["dev"], floor) for r in rows], "s--", color="tab:purple",
              label="(a) lattice vs continuum energy (round-off)")
    ax.loglog(Ns, 1.0 / Ns**2 * rows[0]["interp"] * Ns[0] ** 2, ":", color="0.5", lw=0.8,
              label="~N^-2")
    ax.set_xlabel("cells N")
    ax.set_ylabel("error (relative energy / frequency in omega_1)")
    ax.grid(alpha=0.3, which="both")
    ax2 = ax.twinx()
    ax2.loglog(Ns, [r["wall_h1"] for r in rows], "D-", color="tab:red",
               label="(d) scan time, solve_node")
    ax2.loglog(Ns, [r["wall_all"] for r in rows], "D--", color="tab:orange",
               label="(d) scan time, node_solutions")
    ax2.axhline(ref["wall"], color="tab:red", ls=":", lw=1,
                label=f"continuum engine ({ref['points']} pts)")
    ax2.set_ylabel("wall time [s]", color="tab:red")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.set_title("Mode-1 backbone (g0 = 1e-3): WFEM lattice vs continuum limit")
    fig.legend(h1 + h2, l1 + l2, fontsize=8, loc="lower center", ncol=2, framealpha=0.9)
    fig.tight_layout(rect=(0, 0.2, 1, 1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=130)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
