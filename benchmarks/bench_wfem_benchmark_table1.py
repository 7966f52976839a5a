"""Table 1 benchmark (Yoong, Thorin, Legrand 2017, section 3): WFEM error vs N.

The bouncing bar: E = 900, rho = 1, L = 10, g0 = 5, F0 = 10 (c = 30), reconstructed as a bar free
at x = 0, at rest and stress-free at distance g0 from the obstacle at t = 0, falling under the
uniform body force F0 (module docstring of :mod:`problems.bar.bouncing_bar_exact`). Exact solution:
impacts at t = 1, 11/3, 19/3, ... (every 8/3 s: contact 2L/c = 2/3 s, flight 2V/(F0/rho) = 2 s),
period 16/3 s (two bounces of two kinds). The WFEM (:func:`simulate`, Algorithm 2) runs
``[0, 17]`` s, i.e. 3 periods after the first impact, for N = 10 ... 1000.

Errors are ``max_n |num - exact| / max_n |exact|`` over the run:

* ``u``: end displacement at ``t_n``;
* ``v``, ``lambda``: end velocity and compressive contact force *averaged over each step*
  (what the WFEM interface value (A.12) is) against the exact step averages;
* ``v pt``, ``lambda pt``: the same WFEM values against the exact *point* values at ``t_n``
  (first order: both vary linearly in time with slope c F0 within a step);
* ``euler``: naive explicit first-order source (``Q' = A Q + dt S(Q^n)``);
* ``off-grid``: g0 = 5.1, for which no switching time falls on the grid (``max`` errors of
  discontinuous signals are then O(1) at the switching steps; the L1-in-time relative error of
  ``lambda`` is given instead);
* ``energy``: ring energy of the cell averages vs the exact bar energy, sampled at 400 times
  (O(dx^2): the energy of cell averages misses the intra-cell variance of the linear fields).

Writes ``benchmarks/out/wfem_table1_error_vs_N.png`` (errors and wall time vs N on one figure).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from nsm_continuation.problems.bar.bouncing_bar_exact import BouncingBarExact  # noqa: E402
from nsm_continuation.problems.bar.wfem_simulation import BarParams, Loading, simulate  # noqa: E402

TABLE1 = {"E": 900.0, "rho": 1.0, "L": 10.0, "g0": 5.0, "F0": 10.0}
T_END = 17.0
OUT = Path(__file__).resolve().parent / "out"


def rel_max(num: np.ndarray, ex: np.ndarray) -> float:
    return float(np.max(np.abs(num - ex)) / np.max(np.abs(ex)))


def rel_l1(num: np.ndarray, ex: np.ndarray) -> float:
    return float(np.sum(np.abs(num - ex)) / np.sum(np.abs(ex)))


def errors(N: int, exact: BouncingBarExact, g0: float, scheme: str = "exact",
           energy_samples: int = 0) -> dict[str, float]:
    p = BarParams(E=TABLE1["E"], rho=TABLE1["rho"], L=TABLE1["L"], N=N, g0=g0, left="free")
    M = int(round(T_END / p.time_step))
    best = np.inf
    for _ in range(3 if N <= 200 else 1):
        res = simulate(p, Loading(F0=TABLE1["F0"], source_scheme=scheme), M)  # type: ignore[arg-type]
        best = min(best, res.wall_time)
    u_ex = exact.u_end(res.t)
    v_avg, f_avg = exact.step_averages(res.t)
    out = {
        "steps": float(M),
        "time": best,
        "u": rel_max(res.u_end, u_ex),
        "v": rel_max(res.v_end, v_avg),
        "f": rel_max(res.contact_force, f_avg),
        "v_l1": rel_l1(res.v_end, v_avg),
        "f_l1": rel_l1(res.contact_force, f_avg),
        # right limits at t_n (switching times fall on the grid up to round-off)
        "v_pt": rel_max(res.v_end, exact.v_end(res.t[:-1] + 1e-9 * p.time_step)),
        "f_pt": rel_max(res.contact_force,
                        exact.contact_force(res.t[:-1] + 1e-9 * p.time_step)),
    }
    if energy_samples:
        idx = np.linspace(0, M, energy_samples).astype(int)
        e_ex = np.array([exact.energy(float(res.t[k])) for k in idx])
        out["energy"] = rel_max(res.energy[idx], e_ex)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 50, 100, 200, 500, 1000])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    tic = time.perf_counter()
    ex = BouncingBarExact(t_end=T_END + 1.0, **TABLE1)
    ex_off = BouncingBarExact(t_end=T_END + 1.0, **{**TABLE1, "g0": 5.1})
    t_exact = time.perf_counter() - tic
    print(f"exact solution: impacts {np.round(ex.impacts[:7], 6).tolist()}")
    print(f"                releases {np.round(ex.releases[:7], 6).tolist()}")
    print(f"                period {ex.period():.12f} (16/3 = {16 / 3:.12f}); built in "
          f"{t_exact:.3f} s")
    rows = []
    for N in args.sizes:
        e = errors(N, ex, TABLE1["g0"], energy_samples=400)
        eu = errors(N, ex, TABLE1["g0"], scheme="euler")
        eo = errors(N, ex_off, 5.1)
        rows.append((N, e, eu, eo))
    hdr = (f"{'N':>5s} {'steps':>6s} {'time[s]':>8s} {'us/step':>7s} | {'u':>8s} {'v':>8s} "
           f"{'lambda':>8s} | {'v pt':>8s} {'lam pt':>8s} {'energy':>8s} | {'euler u':>8s} "
           f"{'eul lamL1':>9s} | {'off u':>8s} {'off lamL1':>9s}")
    print("\nmax relative errors over 3 periods (exact-source WFEM unless stated)")
    print(hdr)
    for N, e, eu, eo in rows:
        print(f"{N:5d} {int(e['steps']):6d} {e['time']:8.4f} {1e6 * e['time'] / e['steps']:7.2f} | "
              f"{e['u']:8.1e} {e['v']:8.1e} {e['f']:8.1e} | {e['v_pt']:8.1e} {e['f_pt']:8.1e} "
              f"{e['energy']:8.1e} | {eu['u']:8.1e} {eu['f_l1']:9.1e} | {eo['u']:8.1e} "
              f"{eo['f_l1']:9.1e}")

    Ns = np.array([r[0] for r in rows], dtype=float)
    fig, ax = plt.subplots(figsize=(8, 7), constrained_layout=True)
    floor = 1e-17
    series = [
        ("u (exact source)", [r[1]["u"] for r in rows], "o-", "tab:blue"),
        ("v step avg (exact source)", [r[1]["v"] for r in rows], "s-", "tab:cyan"),
        (r"$\lambda$ step avg (exact source)", [r[1]["f"] for r in rows], "^-", "tab:purple"),
        (r"$\lambda$ vs point values", [r[1]["f_pt"] for r in rows], "^--", "tab:olive"),
        ("energy (cell averages)", [r[1]["energy"] for r in rows], "d--", "tab:brown"),
        ("u, naive Euler source", [r[2]["u"] for r in rows], "o:", "tab:red"),
        ("u, off-grid switching (g0 = 5.1)", [r[3]["u"] for r in rows], "o-.", "tab:orange"),
    ]
    for lab, ys, sty, col in series:
        ax.loglog(Ns, np.maximum(ys, floor), sty, color=col, label=lab)
    ax.axhline(1e-8, color="gray", lw=0.8, ls=":")
    ax.text(Ns[-1], 1.5e-8, "paper: 1e-6 % at N = 100", fontsize=8, color="gray", ha="right")
    ax.set_xlabel("N (cells)")
    ax.set_ylabel("max relative error over 3 periods")
    ax2 = ax.twinx()
    ax2.loglog(Ns, [r[1]["time"] for r in rows], "k*-", label="wall time (exact source)")
    ax2.set_ylabel("wall time of the run [s]")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    fig.legend(h1 + h2, l1 + l2, fontsize=8, loc="outside lower center", ncol=2)
    ax.set_title("Table 1 bouncing bar: WFEM error and cost vs N (t in [0, 17] s)")
    path = args.out / "wfem_table1_error_vs_N.png"
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
