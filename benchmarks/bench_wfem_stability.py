"""Orbital stability of the WFEM bar's main backbones under floating-BC time stepping.

Yoong, Thorin, Legrand (2017) leave the stability of the bar's nonsmooth modes open. Method and
reasoning: :mod:`problems.bar.wfem_stability`. E = rho = L = 1, |g0| = 1e-3; branches (main
backbones, lattice nodes ``m = 2k M - 4N``):

* mode 1, g0 = +1e-3 (hardening from omega_1), mode 1, g0 = -1e-3 (softening from 2 omega_1),
* mode 2, g0 = -1e-3 (softening from 4 omega_1), and, as an extra, mode 2, g0 = +1e-3.

For each branch, a few points (target omega/omega_1, the nearest lattice node at N = 200 and the
node with twice the period steps at N = 400, i.e. the same orbit on the refined mesh) and three
perturbations, all admissible and resolved by the grid:

* ``delay``: the release delayed by ``j`` steps (j = 1 at N = 200, 2 at N = 400: the same
  physical delay L/(200 c)): a switching-time error, which leaves a thin pulse (width j, height
  2A) in the outgoing wave; energy-preserving;
* ``shift``: a profile jump moved by ``0.01 N`` slots in the contact phase (energy-preserving);
* ``smooth``: a random smooth perturbation of relative sup size 0.05 (changes the energy).

Each is stepped ``--periods`` periods (default 200). Table: ``d0`` and ``max d`` (relative L1
orbital distance), ``a`` (amplification of the running maximum, :data:`GROWTH_CRITERION`), the
fitted linear slope per period (relative) and exponential rate, the classification in L1 and in
the energy norm (on d^2), and for ``smooth`` the final distance to the same-energy family
member. Then (b) the size scaling of the growth at one point per branch
(N = 800, delays of 1, 2, 4, 8 steps, 400 periods: the time to reach d = 0.1 is ~ 1/d0 for
linear growth, ~ log(1/d0) for exponential growth), (c) long runs (1000 periods) and the
nearest-step switching rule (closure_tol = 0.5) at one point per branch.

Writes ``benchmarks/out/wfem_stability.png`` (L1 orbital distance vs periods, log y).

    python benchmarks/bench_wfem_stability.py [--periods 200] [--sizes 200 400] [--quick]
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
from nsm_continuation.problems.bar.wfem_lattice import (  # noqa: E402
    BarModel,
    LatticeSolution,
    node_solutions,
)
from nsm_continuation.problems.bar.wfem_stability import (  # noqa: E402
    GROWTH_CRITERION,
    GrowthResult,
    main_backbone_counts,
    perturbation_growth,
)

OUT = Path(__file__).resolve().parent / "out"
BRANCHES = [  # label, g0, mode, omega/omega_1 targets
    ("mode 1, g0>0", 1e-3, 1, (1.05, 1.14, 1.23, 1.31)),
    ("mode 1, g0<0", -1e-3, 1, (1.45, 1.60, 1.80, 1.95)),
    ("mode 2, g0<0", -1e-3, 2, (3.35, 3.50, 3.70, 3.90)),
    ("mode 2, g0>0", 1e-3, 2, (3.05, 3.15)),
]


def node_near(N: int, g0: float, mode: int, ratio: float, M_hint: int | None = None
              ) -> LatticeSolution | None:
    """An admissible main-backbone node at omega/omega_1 close to ``ratio`` (or at M_hint)."""
    md = BarModel(1.0, 1.0, 1.0, N, g0)
    M0 = M_hint if M_hint is not None else int(round(4 * N / ratio))
    for dM in range(0, 12):
        for M in (M0 + dM, M0 - dM) if dM else (M0,):
            m, p = main_backbone_counts(N, M, mode)
            if m < 1 or p < 1:
                continue
            sols = node_solutions(md, (m, p))[1]
            if sols:
                return sols[0]
    return None


def runs_for(sol: LatticeSolution, periods: int) -> list[GrowthResult]:
    N = sol.model.N
    return [
        perturbation_growth(sol, 0.0, periods, "delay", slots=N // 200, family=False),
        perturbation_growth(sol, 0.01, periods, "shift", family=False),
        perturbation_growth(sol, 0.05, periods, "smooth", family=True),
    ]


def fmt_row(label: str, sol: LatticeSolution, r: GrowthResult) -> str:
    md = sol.model
    c, ce = r.classification["l1"], r.classification["energy"]
    d = r.distance["l1"]
    size = f"j={r.info['slots']}" if r.kind in ("delay", "shift") else f"eps={r.eps:g}"
    fam = f"{r.family['l1'][-1]:.4f}" if r.family else "   -  "
    sat = "*" if c["saturated"] else " "
    return (f"{label:13s} {md.N:4d} {sol.M:5d} {sol.omega / md.omega1:6.3f} "
            f"{sol.energy / md.energy_ref:9.2f} {r.kind:6s} {size:9s} {d[0]:.4f} {d.max():.4f} "
            f"{c['amplification']:6.1f} {c['slope_rel']:8.4f} {c['log_slope']:7.4f} "
            f"{c['label'] + sat:19s} {ce['label']:18s} {fam}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--periods", type=int, default=200)
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 400])
    ap.add_argument("--quick", action="store_true", help="two points per branch, no (b), (c)")
    ap.add_argument("--out", type=Path, default=OUT / "wfem_stability.png")
    args = ap.parse_args()
    t_start = time.perf_counter()
    print("criterion:", GROWTH_CRITERION, "\n")
    head = (f"{'branch':13s} {'N':>4s} {'M':>5s} {'w/w1':>6s} {'E/E_ref':>9s} {'kind':6s} "
            f"{'size':9s} {'d0(L1)':6s} {'max d':6s} {'a':>6s} {'slope/T':>8s} {'lambda':>7s} "
            f"{'class (L1)':19s} {'class (energy)':18s} fam d_end")
    print("(a) L1 orbital distance over", args.periods, "periods ('*': saturated before the end)")
    print(head)
    print("-" * len(head))
    curves: dict[str, list[tuple[str, np.ndarray]]] = {"delay": [], "smooth": []}
    verdicts: dict[str, list[str]] = {}
    for label, g0, mode, targets in BRANCHES:
        if args.quick:
            targets = targets[1:3]
        for ratio in targets:
            base = node_near(args.sizes[0], g0, mode, ratio)
            if base is None:
                print(f"{label:13s} omega/omega_1 = {ratio}: no node found")
                continue
            for N in args.sizes:
                f = N // args.sizes[0]
                sol = base if f == 1 else node_near(N, g0, mode, ratio, M_hint=f * base.M)
                if sol is None:
                    continue
                for r in runs_for(sol, args.periods):
                    print(fmt_row(label, sol, r))
                    verdicts.setdefault(label, []).append(r.classification["l1"]["label"])
                    if ratio == targets[len(targets) // 2] and r.kind in curves:
                        curves[r.kind].append((f"{label}, w/w1={sol.omega / sol.model.omega1:.2f}"
                                               f", N={N}", r.distance["l1"]))
        print()
    print("verdicts (L1) per branch:")
    for label, v in verdicts.items():
        counts = {k: v.count(k) for k in sorted(set(v))}
        print(f"  {label:13s} {counts}")

    if not args.quick:
        N = args.sizes[-1]
        Nb = 2 * N
        print(f"\n(b) size scaling at N = {Nb}: release delayed by j steps, 400 periods; k = first "
              "period with d >= 0.1. Linear growth: k d0 constant; exponential growth: k - k(2j)"
              " constant (= ln 2 / rate)")
        print(f"{'branch':13s} {'w/w1':>6s} {'j':>3s} {'d0':>7s} {'max d':>7s} {'k':>5s} "
              f"{'k d0':>7s} {'k-k(2j)':>7s} {'class':16s}")
        for label, g0, mode, targets in BRANCHES:
            sol = node_near(Nb, g0, mode, targets[len(targets) // 2])
            if sol is None:
                continue
            ks: list[int] = []
            rows = []
            for j in (1, 2, 4, 8):
                r = perturbation_growth(sol, 0.0, 400, "delay", slots=j, family=False,
                                        norms=("l1",))
                d = r.distance["l1"]
                hit = np.nonzero(d >= 0.1)[0]
                ks.append(int(hit[0]) if hit.size else -1)
                rows.append((j, d[0], d.max(), r.classification["l1"]["label"]))
            for i, (j, d0, dmax, lab) in enumerate(rows):
                k = ks[i]
                kd = f"{k * d0:7.3f}" if k >= 0 else "      -"
                dk = f"{k - ks[i + 1]:7d}" if i + 1 < len(ks) and k >= 0 and ks[i + 1] >= 0 \
                    else "      -"
                print(f"{label:13s} {sol.omega / sol.model.omega1:6.3f} {j:3d} {d0:7.4f} "
                      f"{dmax:7.4f} {k:5d} {kd} {dk} {lab:16s}")
        print(f"\n(c) 1000 periods (release delayed by 2 steps, N = {N}) and nearest-step "
              "switching (closure_tol = 0.5, 200 periods)")
        print(f"{'branch':13s} {'w/w1':>6s} {'rule':>10s} {'P':>5s} {'d0':>7s} {'max d':>7s} "
              f"{'a':>6s} {'class':16s} {'time':>6s}")
        for label, g0, mode, targets in BRANCHES:
            sol = node_near(N, g0, mode, targets[len(targets) // 2])
            if sol is None:
                continue
            for rule, P in ((1e-9, 1000), (0.5, 200)):
                t0 = time.perf_counter()
                r = perturbation_growth(sol, 0.0, P, "delay", slots=2, family=False,
                                        norms=("l1",), closure_tol=rule)
                c = r.classification["l1"]
                print(f"{label:13s} {sol.omega / sol.model.omega1:6.3f} {rule:10g} {P:5d} "
                      f"{r.distance['l1'][0]:7.4f} {c['max']:7.4f} {c['amplification']:6.1f} "
                      f"{c['label']:16s} {time.perf_counter() - t0:5.1f}s")

    fig, axes = plt.subplots(1, 2, figsize=(13, 5), sharey=True)
    for ax, kind, title in ((axes[0], "delay", "release delayed by L/(200c) (1 step at N=200)"),
                            (axes[1], "smooth", "random smooth perturbation, eps = 0.05")):
        for i, (name, d) in enumerate(curves[kind]):
            ls = "-" if name.endswith(f"N={args.sizes[0]}") else "--"
            ax.semilogy(np.arange(len(d)), np.maximum(d, 1e-5), ls, color=f"C{i // 2}",
                        label=name, lw=1.2)
        ax.set_xlabel("periods")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("relative L1 orbital distance  min_k |w - W_k|_1 / |W|_1")
    axes[0].legend(fontsize=7)
    fig.suptitle("WFEM bar, floating BC: orbital distance of perturbed main-backbone orbits "
                 f"(solid N={args.sizes[0]}, dashed N={args.sizes[-1]})", fontsize=11)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=130)
    print(f"\nwrote {args.out}  ({time.perf_counter() - t_start:.1f} s)")


if __name__ == "__main__":
    main()
