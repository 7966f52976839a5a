"""One speed-vs-accuracy chart per system: error against wall time, log-log.

    python benchmarks/charts.py [--quick] [--out-dir DIR] [--docs-dir DIR | --no-docs]
                                [--only chain double_pendulum wfem_bar]

Each chart is written to ``--out-dir`` (default ``benchmarks/results/``, git-ignored) and, for
the README, to ``--docs-dir`` (default ``docs/figures/``) as ``speed_accuracy_<system>.png``;
the tables are printed and written to ``<out-dir>/speed_accuracy.md``. BLAS is pinned to one
thread. Times are the best of repeats (the machine may be shared); errors are against
independent references, named on each chart:

* ``chain``: (a) branch 1 of the paper's 5-dof chain, ``T`` from 0.99 to 0.90 ``T_1`` (the
  window of ``bench_engine_vs_pycont.py``, whose runs are reused): our engine with detection
  off and on, the engine with the structured (secular) multipliers forced at N = 5 (the default
  there is dense eigenvalues), pycont-lite with and without its bifurcation/stability options.
  Error: the maximum over the branch of the relative distance to the closed form (4.2) and of
  the full return-map residual. (b) the multipliers of one point of branch 1 of the
  paper-scaled chain (``m = 1/N``, ``k = N``, as ``bench_chain_large.py``) for several N:
  structured (warm start, as in a continuation, and cold) against dense eigenvalues; error:
  largest distance to the eigenvalues of the return-map Jacobian (A.8) refined by a
  first-order correction with residuals in extended (80-bit) precision.
* ``double_pendulum``: the sec. 6.1 chattering orbit (``bench_chatter.py``, whose functions are
  reused): orbit + multipliers from a 1e-4 guess with the chatter map (DOP853, several orders,
  ``rtol = chatter_tol``) against the naive cut after K impacts; errors in the period, the
  sticking time and the multiplier against the reference orbit computed at 1e-13.
* ``wfem_bar``: the main backbone of mode 1 (g0 = 1e-3) of the bar: the lattice scan
  (``bench_wfem_accuracy.py``) against time simulation (Algorithm 2, the floating boundary
  condition with the nearest-grid closure rule, started from the continuum orbit at each target
  frequency, 10 periods; the period is read from the impact instants). Error: the relative
  deviation of the energy of the backbone points from the continuum closed form
  ``E/E_ref = 8 / (pi^2 (T - 3)^2)`` at their frequency, at 8 target frequencies in
  ``omega/omega_1 in [1.03, 1.29]`` (lattice: interpolated linearly in omega between the
  nearest lattice orbits below and above each target; also shown: the lattice points
  themselves). Wall time: the whole scan (every node of the branch's lattice line), or only
  the nodes around the targets, against the 8 simulations (the simulation is given the exact
  continuum orbit as its initial state: favourable to it).

Run time here (2 shared cores): ~3 min, ``--quick`` ~40 s. Numbers: benchmarks/README.md.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import io  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import scipy  # noqa: E402
import scipy.linalg as sla  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import NullFormatter  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_chain_large as chain_large  # noqa: E402
import bench_chatter as chatter  # noqa: E402
import bench_engine_vs_pycont as evp  # noqa: E402
import bench_wfem_accuracy as wfem_acc  # noqa: E402
from nsm_continuation.problems.bar.wfem_lattice import BarModel  # noqa: E402
from nsm_continuation.problems.bar.wfem_operators import ring_energy  # noqa: E402
from nsm_continuation.problems.bar.wfem_stability import (  # noqa: E402
    CONTACT,
    continuum_state,
    floating_bc_simulation,
)
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem  # noqa: E402
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem  # noqa: E402

from nsm_continuation.adapters.pycont import run_pycont  # noqa: E402

HERE = Path(__file__).resolve().parent
FLOOR = 1e-17  # an exact zero would vanish from a log axis
DPI = 100

Table = list[dict[str, Any]]


class StructuredChain(NDofImpactProblem):
    """The chain with the structured (secular) multipliers at every size (default above 40)."""

    DENSE_MULTIPLIERS_UP_TO = 0


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        pass
    return (f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python "
            f"{platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
            f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")


def markdown(rows: Table, cols: list[tuple[str, str, str]]) -> list[str]:
    """``cols``: (key, header, format spec; '' for str) -> markdown table lines."""
    out = ["| " + " | ".join(h for _, h, _ in cols) + " |",
           "|" + "|".join("---" if not f else "---:" for _, _, f in cols) + "|"]
    for r in rows:
        cells = []
        for k, _, f in cols:
            v = r.get(k)
            cells.append("-" if v is None else (format(v, f) if f else str(v)))
        out.append("| " + " | ".join(cells) + " |")
    return out


def finish(fig: Any, name: str, dirs: list[Path]) -> list[Path]:
    """Write the chart as ``speed_accuracy_<name>.png`` into each folder, as a palette PNG
    (a few tens of kB: the README's copies live in git)."""
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, dpi=DPI)
    plt.close(fig)
    buf.seek(0)
    img = Image.open(buf).convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE)
    paths = []
    for d in dirs:
        d.mkdir(parents=True, exist_ok=True)
        p = d / f"speed_accuracy_{name}.png"
        img.save(p, optimize=True)
        paths.append(p)
    return paths


def series_plot(ax: Any, rows: Table, key: str, styles: dict[str, tuple[str, str]],
                tag: Callable[[dict[str, Any]], str]) -> None:
    """One marker series per method: x = row['time'], y = row[key], labels from ``tag``."""
    for method, (marker, color) in styles.items():
        sel = [r for r in rows if r["method"] == method]
        if not sel:
            continue
        x = [r["time"] for r in sel]
        y = [max(r[key], FLOOR) for r in sel]
        ax.loglog(x, y, marker=marker, color=color, ls=":", label=method)
        for r, xi, yi in zip(sel, x, y, strict=True):
            ax.annotate(tag(r), (xi, yi), textcoords="offset points", xytext=(4, 3),
                        fontsize=6, color=color)
    ax.xaxis.set_minor_formatter(NullFormatter())  # minor tick labels overlap on short ranges
    ax.grid(True, which="both", alpha=0.3)


# ------------------------------------------------------------------------------------ chain
@contextmanager
def window(t_start: float, t_stop: float) -> Iterator[None]:
    """The branch window of ``bench_engine_vs_pycont`` (its module constants), restored after."""
    old = evp.T_START, evp.T_STOP
    evp.T_START, evp.T_STOP = t_start, t_stop
    try:
        yield
    finally:
        evp.T_START, evp.T_STOP = old


def chain_branch(quick: bool) -> Table:
    """(a) the 5-dof branch 1: engine / engine + detection / structured multipliers / pycont."""
    repeat = 2 if quick else 5
    tols = (1e-6, 1e-8, 1e-12) if quick else evp.ENGINE_TOLS
    pb = NDofImpactProblem(evp.PAPER_CHAIN)
    st = StructuredChain(evp.PAPER_CHAIN)
    bare = evp.BareProblem(evp.PAPER_CHAIN)
    _ = (pb.compiled, st.compiled, bare.compiled)
    run_pycont(pb, evp.start_y(pb), n_steps=1, tolerance=1e-6)  # warm pycont's imports
    rows: list[evp.Row] = []
    for tol in tols:
        rows.append(evp.measure("engine", tol, lambda t=tol: evp.run_engine(pb, t, False), pb,
                                repeat))
        rows.append(evp.measure("engine + detection", tol,
                                lambda t=tol: evp.run_engine(pb, t, True), pb, repeat))
        rows.append(evp.measure("engine + detection, structured multipliers", tol,
                                lambda t=tol: evp.run_engine(st, t, True), pb, repeat))
        rows.append(evp.measure("engine, hooks off (no multipliers, no admissibility)", tol,
                                lambda t=tol: evp.run_engine(bare, t, False), pb, repeat))
        rows.append(evp.measure("pycont-lite", tol,
                                lambda t=tol: evp.run_pycont_once(pb, t, False), pb, repeat))
        rows.append(evp.measure("pycont-lite + bif + stab", tol,
                                lambda t=tol: evp.run_pycont_once(pb, t, True), pb, repeat))
    out = []
    for r in rows:
        events = [e for e in r.events if e not in ("endpoint", "SP", "PARAM_MIN")]
        out.append({"method": r.method, "setting": f"tol {r.tol:.0e}", "tol": r.tol,
                     "time": r.time, "error": r.error, "fixed_point": r.fixed_point,
                     "closed_form": r.closed_form, "points": r.n_points,
                     "evals": r.n_residuals, "events": len(events)})
    if st.floquet_fallbacks:
        print(f"  note: {st.floquet_fallbacks} structured multiplier calls fell back to dense")
    return out


def refined_eigenvalues(A: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``A`` with one first-order correction ``y^H (A x - lam x) / (y^H x)``, the
    residual in extended (80-bit) precision: the reference of the multiplier errors."""
    lam, yl, xr = sla.eig(A, left=True, right=True)
    x = xr.astype(np.clongdouble)
    y = yl.astype(np.clongdouble)
    r = A.astype(np.clongdouble) @ x - x * lam.astype(np.clongdouble)[None, :]
    corr = np.sum(np.conj(y) * r, axis=0) / np.sum(np.conj(y) * x, axis=0)
    return (lam.astype(np.clongdouble) + corr).astype(complex)


def multiplier_error(mult: np.ndarray, ref: np.ndarray) -> float:
    """Largest distance of the multipliers to their assigned reference eigenvalues."""
    cost = np.abs(np.asarray(mult)[:, None] - ref[None, :])
    r, c = linear_sum_assignment(cost)
    return float(cost[r, c].max())


def chain_multipliers(quick: bool) -> Table:
    """(b) multipliers at one converged point of branch 1, structured vs dense, vs N."""
    sizes = (50, 100, 200) if quick else (50, 100, 200, 400)
    repeat = 3
    rows = []
    for n in sizes:
        # y2: a neighbour on the branch, the warm start of the structured multipliers
        pb, _, y, t, y2 = chain_large.branch1_point(n)
        ref = refined_eigenvalues(pb.return_map_jacobian(y))

        def warm(pb: NDofImpactProblem = pb, y: np.ndarray = y, t: np.ndarray = t,
                 y2: np.ndarray = y2) -> Any:
            pb.multiplier_memory.clear()
            pb.floquet(y2, t)
            t0 = time.perf_counter()
            fl = pb.floquet(y, t)
            return time.perf_counter() - t0, fl

        def cold(pb: NDofImpactProblem = pb, y: np.ndarray = y, t: np.ndarray = t) -> Any:
            pb.multiplier_memory.clear()
            return pb.floquet(y, t)

        ws = [warm() for _ in range(repeat)]
        tw, fw = min(w[0] for w in ws), ws[-1][1]
        tc, fc = chatter.best_time(cold, repeat)
        td, fd = chatter.best_time(lambda pb=pb, y=y, t=t: pb.floquet_dense(y, t), repeat)
        for method, tm, fl in (("structured, warm start", tw, fw), ("structured, cold", tc, fc),
                               ("dense eigenvalues", td, fd)):
            rows.append({"method": method, "N": n, "setting": f"N = {n}", "time": tm,
                         "error": multiplier_error(fl.multipliers, ref),
                         "count": len(fl.multipliers)})
        print(f"  N = {n}: structured warm {1e3 * tw:.1f} ms, cold {1e3 * tc:.1f} ms, dense "
              f"{1e3 * td:.1f} ms", flush=True)
    return rows


def chart_chain(branch: Table, mult: Table, dirs: list[Path]) -> list[Path]:
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.4))
    panels = [
        (branch, {"engine": ("o", "C0"), "engine + detection": ("s", "C1"),
                  "engine + detection, structured multipliers": ("X", "C2"),
                  "engine, hooks off (no multipliers, no admissibility)": ("D", "C7"),
                  "pycont-lite": ("^", "C3"), "pycont-lite + bif + stab": ("v", "C4")},
         lambda r: f"{r['tol']:.0e}", "wall time of the branch [s] (best of repeats)",
         "max over the branch of the relative error\n"
         "vs the closed form (4.2) and of the return-map residual",
         "(a) 5-dof chain, branch 1, T in [0.90, 0.99] T1\n"
         "(labels: newton_tol / pycont tolerance)"),
        (mult, {"structured, warm start": ("o", "C2"), "structured, cold": ("D", "C8"),
                "dense eigenvalues": ("s", "C1")},
         lambda r: f"N={r['N']}", "wall time of one multiplier computation [s] (best of 3)",
         "max |multiplier - reference|\n"
         "(reference: eigenvalues of DF (A.8), refined in 80-bit)",
         "(b) N-dof chain (m = 1/N, k = N), one point of branch 1\n"
         "Floquet multipliers: structured vs dense")]
    for ax, (rows, styles, tag, xlabel, ylabel, title) in zip(axes, panels, strict=True):
        series_plot(ax, rows, "error", styles, tag)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)
    fig.tight_layout()
    return finish(fig, "chain", dirs)


# --------------------------------------------------------------------------- double pendulum
def pendulum(quick: bool) -> tuple[Table, dict[str, float]]:
    repeat = 2 if quick else 3
    orders = (3,) if quick else (2, 3, 4)
    cut_rtols = (1e-10,) if quick else chatter.CUT_RTOLS
    cuts = (10, 20, 40, 80, 160)
    pbs = {m: DoublePendulumProblem({**chatter.PARAMS, "e": chatter.E0,
                                     "integrator": {"method": m}}) for m in chatter.METHODS}
    ref_opts = chatter.SimOptions(rtol=chatter.REF_TOL, atol=chatter.REF_TOL,
                                  chatter_tol=chatter.REF_TOL, chatter_order=4, wall_time=300.0)
    refs = {}
    for m, pb in pbs.items():
        chatter.set_options(pb, ref_opts)
        refs[m] = chatter.solve(pb, chatter.KNOWN, tol=chatter.REF_TOL)
    ref, alt = refs["dop853"], refs["dopri5"]
    spread = {"err_T": abs(alt.period - ref.period), "err_tau": abs(alt.sticking - ref.sticking),
              "err_mu": abs(alt.mu - ref.mu) / abs(ref.mu)}
    configs = [(f"chatter map, order {k}", f"rtol {rt:.0e}", chatter.opts_for(rt, k))
               for k in orders for rt in chatter.RTOLS]
    configs += [(f"impact cut, rtol {rt:.0e}", f"K = {K}",
                 chatter.SimOptions(rtol=rt, atol=rt / 100, chatter="cut", cut_after=K,
                                    wall_time=120.0))
                for rt in cut_rtols for K in cuts]
    pb = pbs["dop853"]
    rows: Table = []
    for rnd in range(repeat):  # every setting once per round: load changes spread over all
        for i, (method, setting, opts) in enumerate(configs):
            m = chatter.measure(pb, opts, ref, 1)
            if rnd == 0:
                m.pop("orbit", None)
                rows.append({"method": method, "setting": setting, **m})
            elif "failure" not in m and "failure" not in rows[i]:
                rows[i]["t_solve"] = min(rows[i]["t_solve"], m["t_solve"])
    for r in rows:
        r["time"] = r.get("t_solve", np.nan)
        r["error"] = r.get("err_T")  # the tables' `error` column: the period error
    return rows, {"T": ref.period, "tau": ref.sticking, "mu": ref.mu.real, **spread}


def chart_pendulum(rows: Table, ref: dict[str, float], dirs: list[Path]) -> list[Path]:
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.6))
    ok = [r for r in rows if "failure" not in r]
    methods = list(dict.fromkeys(r["method"] for r in ok))
    styles = {m: (("o" if "map" in m else "s"), f"C{i}") for i, m in enumerate(methods)}
    for ax, key, what in ((axes[0], "err_T", "period error |T - T_ref| [s]"),
                          (axes[1], "err_tau", "sticking-time error |tau - tau_ref| [s]"),
                          (axes[2], "err_mu", "multiplier error |mu - mu_ref| / |mu_ref|")):
        series_plot(ax, ok, key, styles, lambda r: r["setting"].split()[-1])
        ax.axhline(max(ref[key], FLOOR), color="grey", lw=0.8, ls="--",
                   label="reference's own error\n(DOP853 vs DOPRI5 at 1e-13)")
        ax.set_xlabel("wall time: orbit + multipliers from a 1e-4 guess [s]")
        ax.set_ylabel(what)
    axes[0].legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)
    fig.suptitle("Double pendulum, sec. 6.1 chattering orbit (e = 0.89): chatter map "
                 "(labels: rtol = chatter_tol) vs impact cut after K impacts (labels: K);\n"
                 f"reference: the orbit at rtol = atol = chatter_tol = 1e-13 (T = "
                 f"{ref['T']:.9f} s, tau = {ref['tau']:.9f} s)", fontsize=9)
    fig.tight_layout()
    return finish(fig, "double_pendulum", dirs)


# ----------------------------------------------------------------------------------- bar
TARGETS = np.linspace(1.03, 1.29, 8)  # omega / omega_1
SIM_PERIODS = 10


def simulated_point(md: BarModel, r: float) -> tuple[float, float]:
    """(T, E/E_ref) of the backbone point at omega/omega_1 = r seen by time simulation:
    Algorithm 2 from the continuum orbit's state (cell averages), SIM_PERIODS periods; the
    period is the mean interval between impacts, the energy the (conserved) state energy."""
    T = 4.0 / r  # units L/c: omega_1 = pi c / (2 L)
    A = 2 * md.E * md.g0 / (md.L * float(wfem_acc.SIG.mu(T)))
    w0 = continuum_state(md, wfem_acc.SIG, T, 0.0, A)
    run = floating_bc_simulation(md, w0, int(np.ceil(SIM_PERIODS * T * md.N)) + 2,
                                 closure="nearest")
    s = run.signs
    onsets = np.nonzero((s[1:] == CONTACT) & (s[:-1] != CONTACT))[0] + 1
    period = (onsets[-1] - onsets[0]) / (len(onsets) - 1) * md.dt
    return period, ring_energy(w0, md.dx, md.E) / md.energy_ref


def lattice_at_targets(md: BarModel) -> tuple[np.ndarray, int]:
    """The lattice's answer at the targets alone: for each target, the nearest nodes of the
    branch's line ``m = 2M - 4N`` below and above its period with an orbit, interpolated
    linearly in omega. Returns E/E_ref at the targets and the number of nodes solved."""
    N = md.N
    cache: dict[int, tuple[float, float] | None] = {}

    def node(M: int) -> tuple[float, float] | None:
        if M not in cache:
            m = 2 * M - 4 * N
            sols = wfem_acc.node_solutions(md, (m, M - m))[1]
            cache[M] = (sols[0].period, sols[0].energy / md.energy_ref) if sols else None
        return cache[M]

    out = []
    for r in TARGETS:
        M0 = 4.0 / r * N
        lo = next(p for M in range(int(np.ceil(M0)), 4 * N) if (p := node(M)) is not None)
        hi = next(p for M in range(int(np.floor(M0)), 3 * N, -1) if (p := node(M)) is not None)
        r_lo, r_hi = 4.0 / lo[0], 4.0 / hi[0]
        out.append(lo[1] if r_hi == r_lo else
                   lo[1] + (hi[1] - lo[1]) * (r - r_lo) / (r_hi - r_lo))
    return np.array(out), len(cache)


def bar(quick: bool) -> Table:
    sizes = (50, 100, 200, 500, 1000) if quick else (50, 100, 200, 500, 1000, 2000, 4000)
    repeat = 2 if quick else 3
    rows: Table = []
    for N in sizes:
        md = BarModel(1.0, 1.0, 1.0, N, wfem_acc.G0)
        wall, (pts, _, nodes) = chatter.best_time(lambda N=N: wfem_acc.scan(N, all_nodes=True),
                                                  repeat)
        T = np.array([p[0] for p in pts])
        E = np.array([p[1] for p in pts])
        order = np.argsort(4.0 / T)
        e_int = np.interp(TARGETS, (4.0 / T)[order], E[order])
        err = float(np.max(np.abs(e_int / wfem_acc.energy_ratio_continuum(4.0 / TARGETS) - 1)))
        m = wfem_acc.measures(pts)
        rows.append({"method": "lattice, interpolated at the targets", "N": N, "time": wall,
                     "error": err, "setting": f"N = {N}", "points": len(pts), "nodes": nodes,
                     "window": m["interp"]})
        rows.append({"method": "lattice points (exact samples)", "N": N, "time": wall,
                     "error": m["dev"], "setting": f"N = {N}", "points": len(pts),
                     "nodes": nodes})
        tt, (e_t, n_nodes) = chatter.best_time(lambda md=md: lattice_at_targets(md), repeat)
        rows.append({"method": "lattice, only the nodes around the targets", "N": N, "time": tt,
                     "error": float(np.max(np.abs(
                         e_t / wfem_acc.energy_ratio_continuum(4.0 / TARGETS) - 1))),
                     "setting": f"N = {N}", "points": len(TARGETS), "nodes": n_nodes})
        ts, sim = chatter.best_time(lambda md=md: [simulated_point(md, r) for r in TARGETS], repeat)
        Ts = np.array([p[0] for p in sim])
        Es = np.array([p[1] for p in sim])
        rows.append({"method": "time simulation (Algorithm 2)", "N": N, "time": ts,
                     "error": float(np.max(np.abs(Es / wfem_acc.energy_ratio_continuum(Ts) - 1))),
                     "setting": f"N = {N}", "points": len(TARGETS),
                     "period_err": float(np.max(np.abs(Ts - 4.0 / TARGETS)))})
        print(f"  N = {N}: lattice scan {wall:.3f} s, at the targets {tt:.4f} s, simulation "
              f"{ts:.3f} s", flush=True)
    return rows


def chart_bar(rows: Table, dirs: list[Path]) -> list[Path]:
    fig, ax = plt.subplots(figsize=(7.5, 5))
    styles = {"lattice, interpolated at the targets": ("o", "C0"),
              "lattice, only the nodes around the targets": ("P", "C2"),
              "lattice points (exact samples)": ("D", "C9"),
              "time simulation (Algorithm 2)": ("s", "C3")}
    series_plot(ax, rows, "error", styles, lambda r: f"N={r['N']}")
    ax.set_xlabel("wall time [s] (lattice: whole scan of the branch, or the nodes around the "
                  f"targets; simulation: {len(TARGETS)} orbits x {SIM_PERIODS} periods)",
                  fontsize=8)
    ax.set_ylabel("max relative energy error of the backbone points\n"
                  "vs the continuum E/E_ref = 8 / (pi^2 (T - 3)^2)")
    ax.set_title("Elastic bar (WFEM), main backbone of mode 1, g0 = 1e-3:\n"
                 f"{len(TARGETS)} targets omega/omega_1 in [{TARGETS[0]:.2f}, {TARGETS[-1]:.2f}]"
                 " (labels: cells N)", fontsize=9)
    ax.legend(fontsize=7, loc="center right")
    fig.tight_layout()
    return finish(fig, "wfem_bar", dirs)


# ----------------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer settings and repeats")
    ap.add_argument("--out-dir", type=Path, default=HERE / "results")
    ap.add_argument("--docs-dir", type=Path, default=HERE.parent / "docs" / "figures",
                    help="the README's copy of each chart")
    ap.add_argument("--no-docs", action="store_true", help="do not write the README's copies")
    ap.add_argument("--only", nargs="*", choices=["chain", "double_pendulum", "wfem_bar"],
                    default=["chain", "double_pendulum", "wfem_bar"])
    args = ap.parse_args(argv)
    dirs = [args.out_dir] + ([] if args.no_docs else [args.docs_dir])
    t_start = time.perf_counter()
    load0 = os.getloadavg()
    lines = [f"Machine: {machine()}.", f"Load average at start: {load0[0]:.2f}. "
             f"Mode: {'--quick' if args.quick else 'full'}.", ""]

    def say(s: str = "") -> None:
        print(s, flush=True)
        lines.append(s)

    for s in lines:
        print(s)
    common = [("method", "method", ""), ("setting", "setting", ""),
              ("time", "wall time [s]", ".4f"), ("error", "error", ".2e")]
    def section(name: str, t0: float, blocks: list[tuple[str, Table, list[Any]]],
                paths: list[Path], notes: list[str]) -> None:
        say(f"### {name} ({time.perf_counter() - t0:.0f} s)")
        say()
        for text, rows, cols in blocks:
            say(text)
            say()
            for s in markdown(rows, common + cols):
                say(s)
            say()
        for s in notes:
            say(s)
        say("chart: " + ", ".join(str(p) for p in paths))
        say()

    if "chain" in args.only:
        t0 = time.perf_counter()
        print("chain: (a) 5-dof branch 1 ...", flush=True)
        branch = chain_branch(args.quick)
        print("chain: (b) multipliers, structured vs dense ...", flush=True)
        mult = chain_multipliers(args.quick)
        section("chain", t0, [
            ("(a) 5-dof chain, branch 1, T in [0.90, 0.99] T_1. Error: max over the branch of "
             "the relative distance to the closed form (4.2) and of the full return-map "
             "residual (a: `fixed point`, b: `closed form`).", branch,
             [("fixed_point", "fixed point", ".1e"), ("closed_form", "closed form", ".1e"),
              ("points", "points", "d"), ("evals", "G evals", "d"),
              ("events", "events located", "d")]),
            ("(b) Multipliers at one point of branch 1 (T = (1 - 1e-5) T_1) of the chain with "
             "m = 1/N, k = N. Error: max distance to the eigenvalues of DF (A.8) refined in "
             "80-bit precision.", mult, [("count", "multipliers", "d")])],
            chart_chain(branch, mult, dirs), [])
    if "double_pendulum" in args.only:
        t0 = time.perf_counter()
        print("double pendulum: reference and sweep ...", flush=True)
        rows, ref = pendulum(args.quick)
        section("double_pendulum", t0, [
            (f"Reference (rtol = atol = chatter_tol = 1e-13): T = {ref['T']:.10f} s, tau = "
             f"{ref['tau']:.10f} s, mu = {ref['mu']:.6e}; its own error (DOP853 vs DOPRI5): "
             f"{ref['err_T']:.1e} s, {ref['err_tau']:.1e} s, {ref['err_mu']:.1e}. Time: orbit "
             "+ multipliers from a 1e-4 guess (best of rounds); `error`: the period error "
             "|T - T_ref| [s].", rows,
             [("err_tau", "err tau [s]", ".1e"), ("err_mu", "rel. err mu", ".1e"),
              ("impacts", "impacts resolved", "d")])],
            chart_pendulum(rows, ref, dirs),
            [f"* {r['method']} {r['setting']} failed: {r['failure']}"
             for r in rows if "failure" in r])
    if "wfem_bar" in args.only:
        t0 = time.perf_counter()
        print("wfem bar: lattice scan vs time simulation ...", flush=True)
        rows = bar(args.quick)
        section("wfem_bar", t0, [
            ("Main backbone of mode 1, g0 = 1e-3. Error: max relative deviation of the energy "
             "from the continuum E/E_ref = 8/(pi^2 (T - 3)^2) at the points' own period, at "
             f"{len(TARGETS)} targets omega/omega_1 in [{TARGETS[0]:.2f}, {TARGETS[-1]:.2f}]. "
             "`window`: the lattice's linear interpolation, max over omega/omega_1 in "
             "[1.02, 1.30] (4001 frequencies); `max |dT|`: the simulated period against the "
             "target's (units L/c).", rows,
             [("points", "points", "d"), ("nodes", "nodes solved", "d"),
              ("window", "window", ".1e"), ("period_err", "max |dT|", ".1e")])],
            chart_bar(rows, dirs), [])
    load1 = os.getloadavg()
    say(f"Total run time {time.perf_counter() - t_start:.0f} s; load average {load0[0]:.2f} at "
        f"start, {load1[0]:.2f} at end (1-minute).")
    args.out_dir.mkdir(parents=True, exist_ok=True)
    md = args.out_dir / "speed_accuracy.md"
    md.write_text("\n".join(lines) + "\n")
    print(f"wrote {md}")


if __name__ == "__main__":
    main()
