"""Forced response of the damped bar with contact (Yoong, Thorin, Legrand 2017, section 7).

Runs the frequency sweeps of Figs. 20-22 with :func:`forced_response_sweep` (Algorithm 2
time stepping, continuation from one frequency to the next) and writes
``benchmarks/out/wfem_forced_response.png`` (one panel per configuration and gap, three damping
levels) and ``benchmarks/out/wfem_forced_response.npz`` (the sweeps, to re-plot with
``--replot`` without rerunning). Prints the wall time of every sweep.

Model choices (the paper gives no values):

* E = rho = L = S = 1 (section 6), bar clamped at x = 0, N = 100 cells (dt = 0.01);
  gaps g0 = +1e-3, 0, -1e-3 (the prestressed bar starts at rest compressed against the wall,
  ``sigma = E g0 / L``).
* moving wall (f0 = 0): ``w0 = 2e-3 = 2 |g0|`` (the paper requires ``w0 > g0``);
  distributed force (w0 = 0): uniform ``f0 = 4e-3``, whose quasi-static end excursion
  ``f0 L^2 / (2E) = 2e-3`` equals the wall amplitude: both close the gap at every frequency
  of the range for g0 >= 0 and open it for g0 < 0.
* damping: ``rho u_tt + eta u_t - E u_xx = f`` with ``eta = 2 rho omega_1 zeta`` for
  ``zeta = 0.01, 0.02, 0.05`` (modal damping ratio of the first free-fixed mode; the damping
  is mass-proportional, the same decay time ``2 rho / eta`` for every mode).
* 100 frequencies in ``[0.25, 4] omega_1``, increasing; per frequency at least 3 decay times of
  transient, then blocks of 8 forcing periods until the period-averaged energies repeat to
  2e-3 (period 1..4) or 12 decay times have been simulated; ``switching="subcell"``.

The same sweeps run from YAML, one case per panel, with the common runner (CSV, report,
figures): ``nsm-continuation run yaml_cases/wfem_fig2{0,1,2}_{wall,force}_*_gap.yaml``
(``problem: wfem_forced_bar``, ``sweep`` algorithm); this script puts the 18 sweeps on one
figure and measures their cost.

Backbones: ``--backbones FILE.npz`` with arrays ``<gap>__<name>__omega`` and
``<gap>__<name>__energy`` (gap in pos, zero, neg; normalised like the plot), or from Python
``make_figure(sweeps, backbones={"pos": [(omega_ratio, energy_ratio, label), ...]})``.

Usage::

    python benchmarks/bench_wfem_forced_response.py [--N 100] [--n-omega 100] [--jobs 1]
        [--switching subcell] [--backbones FILE.npz] [--replot [--sweeps FILE.npz]]
        [--out DIR]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from nsm_continuation.problems.bar.plots_forced import plot_forced_response  # noqa: E402
from nsm_continuation.problems.bar.wfem_simulation import (  # noqa: E402
    BarParams,
    ForcedPoint,
    ForcedSweep,
    forced_response_sweep,
)

GAPS = {"pos": 1e-3, "zero": 0.0, "neg": -1e-3}
CONFIGS = {"wall": {"w0": 2e-3, "f0": 0.0}, "force": {"w0": 0.0, "f0": 4e-3}}
ZETAS = (0.01, 0.02, 0.05)
OUT = Path(__file__).resolve().parent / "out"


def run_one(args: tuple[str, str, float, int, int, str]) -> ForcedSweep:
    """One sweep: (config, gap key, zeta, N, number of frequencies, switching)."""
    config, gap, zeta, N, n_omega, switching = args
    p = BarParams(E=1.0, rho=1.0, L=1.0, N=N, g0=GAPS[gap])
    omegas = np.linspace(0.25, 4.0, n_omega) * p.omega1
    eta = 2.0 * p.rho * p.omega1 * zeta
    return forced_response_sweep(p, omegas, eta, switching=switching, **CONFIGS[config])


def save_sweeps(path: Path, sweeps: dict[tuple[str, str, float], ForcedSweep]) -> None:
    data: dict[str, np.ndarray] = {}
    for (config, gap, zeta), sw in sweeps.items():
        key = f"{config}__{gap}__{zeta}"
        data[key + "__omega"] = sw.omegas
        data[key + "__energy"] = sw.energies
        data[key + "__steady"] = sw.steady
        data[key + "__multiple"] = np.array([pt.multiple for pt in sw.points])
        data[key + "__meta"] = np.array([sw.params.N, sw.params.g0, sw.eta, sw.w0, sw.f0,
                                         sw.wall_time, sw.total_steps])
    np.savez(path, **data)


def load_sweeps(path: Path) -> dict[tuple[str, str, float], ForcedSweep]:
    data = np.load(path)
    out: dict[tuple[str, str, float], ForcedSweep] = {}
    for name in data.files:
        if not name.endswith("__meta"):
            continue
        config, gap, zeta_s, _ = name.split("__")
        key = f"{config}__{gap}__{zeta_s}"
        N, g0, eta, w0, f0, wall, _steps = data[name]
        sw = ForcedSweep(BarParams(N=int(N), g0=float(g0)), float(eta), float(w0), float(f0))
        for om, en, st, k in zip(data[key + "__omega"], data[key + "__energy"],
                                 data[key + "__steady"], data[key + "__multiple"], strict=True):
            sw.points.append(ForcedPoint(float(om), float(en), np.zeros(0), bool(st), int(k),
                                         math.nan, math.nan, math.nan, 0, 0.0))
        sw.wall_time = float(wall)
        out[(config, gap, float(zeta_s))] = sw
    return out


def load_backbones(path: Path) -> dict[str, list[tuple[np.ndarray, np.ndarray, str]]]:
    data = np.load(path)
    out: dict[str, list[tuple[np.ndarray, np.ndarray, str]]] = {}
    for name in data.files:
        if name.endswith("__omega"):
            gap, label, _ = name.split("__")
            out.setdefault(gap, []).append(
                (data[name], data[f"{gap}__{label}__energy"], label))
    return out


def continuum_backbones() -> dict[str, list[tuple[np.ndarray, np.ndarray, str]]]:
    """Backbones to overlay: the exact continuum-limit branches (``bar_continuum`` cases) for
    g0 = +-1e-3 and the vertical g0 = 0 lines at the asymptotes (section 6.1, eq. 16)."""
    from nsm_continuation import cases
    from nsm_continuation.runs.runner import run_case

    root = Path(__file__).resolve().parents[1] / "yaml_cases"
    out: dict[str, list[tuple[np.ndarray, np.ndarray, str]]] = {}
    for gap, name in (("pos", "bar_continuum_subharmonics.yaml"),
                      ("neg", "bar_continuum_main_negative_gap.yaml")):
        case, problem = cases.load(root / name, ["output.progress=false"])
        for br in run_case(case, problem, progress=False).branches:
            pts = [p for p in br.points if p.admissible]
            out.setdefault(gap, []).append(
                (np.array([p.derived["omega_ratio"] for p in pts]),
                 np.array([p.derived["energy_ratio"] for p in pts]), br.label))
    for x, lab in ((4 / 3, "g0 = 0, mode 1"), (16 / 5, "g0 = 0, mode 2"),
                   (1.6, "g0 = 0, sub. n=1")):
        out.setdefault("zero", []).append((np.array([x, x]), np.array([1e-7, 1e-2]), lab))
    return out


def make_figure(sweeps: dict[tuple[str, str, float], ForcedSweep],
                backbones: dict[str, list] | None = None,
                path: Path | None = None) -> plt.Figure:
    """3 x 2 panels (gap rows, configuration columns), three damping levels per panel."""
    fig, axes = plt.subplots(3, 2, figsize=(12, 12), constrained_layout=True)
    titles = {"wall": "harmonically moving wall", "force": "harmonic distributed force"}
    for i, gap in enumerate(GAPS):
        for j, config in enumerate(CONFIGS):
            ax = axes[i, j]
            sws = [sweeps[(config, gap, z)] for z in ZETAS if (config, gap, z) in sweeps]
            labels = [rf"$\zeta_1$ = {z:g} ($\eta$ = {sweeps[(config, gap, z)].eta:.3g})"
                      for z in ZETAS if (config, gap, z) in sweeps]
            bbs = (backbones or {}).get(gap)
            plot_forced_response(ax, sws, backbones=bbs, labels=labels)
            ax.set_title(f"{titles[config]}, g0 = {GAPS[gap]:+g}")
            ax.legend(fontsize=7)
    fig.suptitle("WFEM forced response (filled: steady periodic/subharmonic; hollow: not "
                 "steady)")
    if path is not None:
        fig.savefig(path, dpi=120)
    return fig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--N", type=int, default=100)
    ap.add_argument("--n-omega", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--switching", default="subcell", choices=["grid", "subcell"])
    ap.add_argument("--backbones", type=Path, default=None)
    ap.add_argument("--replot", action="store_true", help="re-plot the saved sweeps only")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--sweeps", type=Path, default=None,
                    help="saved sweeps to re-plot (default OUT/wfem_forced_response.npz)")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    npz = args.out / "wfem_forced_response.npz"
    if args.replot:
        sweeps = load_sweeps(args.sweeps or npz)
    else:
        tasks = [(c, g, z, args.N, args.n_omega, args.switching)
                 for c in CONFIGS for g in GAPS for z in ZETAS]
        tic = time.perf_counter()
        if args.jobs > 1:
            from multiprocessing import Pool
            with Pool(args.jobs) as pool:
                results = pool.map(run_one, tasks)
        else:
            results = [run_one(t) for t in tasks]
        total = time.perf_counter() - tic
        sweeps = {(t[0], t[1], t[2]): r for t, r in zip(tasks, results, strict=True)}
        print(f"N = {args.N}, {args.n_omega} frequencies per sweep, switching = {args.switching}")
        print(f"{'config':6s} {'g0':>7s} {'zeta':>5s} {'eta':>7s} {'time [s]':>9s} "
              f"{'steps':>9s} {'us/step':>8s} {'steady':>7s} {'subharm.':>8s}")
        for (c, g, z), sw in sweeps.items():
            n_sub = sum(pt.multiple > 1 for pt in sw.points)
            print(f"{c:6s} {GAPS[g]:+7.0e} {z:5.2f} {sw.eta:7.4f} {sw.wall_time:9.1f} "
                  f"{sw.total_steps:9d} {1e6 * sw.wall_time / sw.total_steps:8.2f} "
                  f"{int(sw.steady.sum()):4d}/{len(sw.points):<3d}{n_sub:6d}")
        print(f"total wall time {total:.1f} s with {args.jobs} process(es)")
        save_sweeps(npz, sweeps)
    bbs = load_backbones(args.backbones) if args.backbones else continuum_backbones()
    make_figure(sweeps, bbs, args.out / "wfem_forced_response.png")
    print(f"wrote {args.out / 'wfem_forced_response.png'}")


if __name__ == "__main__":
    main()
