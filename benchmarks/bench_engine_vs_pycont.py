"""Our continuation engine against pycont-lite on branch 1 of the paper's 5-dof chain.

System: ``NDofImpactProblem({"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0})``
(Legrand et al. 2017, sec. 3-6). Branch 1 starts at the linear grazing orbit ``T = T_1`` and
exists for ``T < T_1`` down to the zero of ``w_N`` at ``T ~ 0.890 T_1`` (infinite energy). Every
method starts from the closed form (4.2) at ``T = 0.99 T_1`` and continues towards decreasing
``T`` down to the bound ``T = 0.90 T_1`` (same window, same first step ``1e-2``, same maximum
step ``0.2``, same minimum step ``1e-6``).

Methods (each one a marker series in the chart):

* ``engine``: :class:`~nsm_continuation.core.palc.ContinuationEngine`, exact CasADi Jacobian,
  ``detect_bifurcations`` off, for several ``newton_tol``. Every point still runs the problem's
  hooks (admissibility test functions, Floquet multipliers);
* ``engine + detection``: the same with ``detect_bifurcations`` on (multiplier crossings and
  branch points are located by bisection/Illinois on the curve: many extra corrected points);
* ``engine, hooks off``: the engine on the same problem with ``admissibility`` and ``floquet``
  returning nothing: the bare predictor-corrector, the work pycont-lite does;
* ``engine, coarse steps`` / ``engine + det., coarse``: hooks on, but without the step control
  by multiplier motion (``max_multiplier_step = inf``). On this conservative system the stable
  multipliers sit on the unit circle and turn with ``T``; limiting their motion to 0.02 per step
  (the default) costs ~30x more points on this window, and is what makes the detection find every
  crossing (compare the event counts);
* ``pycont``: pycont-lite (matrix-free Newton-Krylov, finite-difference Jacobian-vector
  products) through :mod:`nsm_continuation.adapters.pycont`, bifurcation detection and stability
  analysis off, several ``tolerance``;
* ``pycont + bif + stab``: the same with ``bifurcation_detection`` and ``analyze_stability`` on.

Accuracy of a run = maximum over all the points it returns of

(a) the relative fixed-point residual of the *full* first-return map (all ``2N`` rows, including
    the redundant velocity row the residual drops): ``|Gamma(T) x - x|_inf / |x|_inf`` with
    ``x = (u(0), u'(0+))`` and ``Gamma`` of eq. (A.1), ``problem.gamma(T)``;
(b) the relative distance to the closed form at the same period:
    ``|x - x_cf(T)|_inf / |x_cf(T)|_inf``.

Wall time: best of ``--repeat`` runs (CasADi functions built before timing, once). The script
prints a table, the speed ratio at equal or better accuracy, and writes
``benchmarks/results/engine_vs_pycont.png`` (error vs wall time, log-log).

Run: ``python benchmarks/bench_engine_vs_pycont.py [--repeat 5]`` (under a minute).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # see bench_scaling.py: 2 threads thrash here

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem  # noqa: E402

from nsm_continuation.adapters.pycont import as_pycont_system, run_pycont  # noqa: E402
from nsm_continuation.core.palc import ContinuationEngine  # noqa: E402
from nsm_continuation.core.problem import FloquetData, StartPoint  # noqa: E402
from nsm_continuation.core.settings import ContinuationSettings  # noqa: E402

PAPER_CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
T_START, T_STOP = 0.99, 0.90  # in units of T_1
STEP_INITIAL, STEP_MAX, STEP_MIN = 1e-2, 0.2, 1e-6
ENGINE_TOLS = (1e-6, 1e-8, 1e-10, 1e-12)
PYCONT_TOLS = (1e-6, 1e-8, 1e-10, 1e-12)
OUT = Path(__file__).resolve().parent / "results" / "engine_vs_pycont.png"


class BareProblem(NDofImpactProblem):
    """The same residual without the per-point hooks (admissibility, Floquet multipliers)."""

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {}

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        return None


@dataclass
class Row:
    method: str
    tol: float
    times: list[float]
    n_points: int
    n_residuals: int
    fixed_point: float
    closed_form: float
    T_range: tuple[float, float]
    events: list[str] = field(default_factory=list)

    @property
    def time(self) -> float:
        return min(self.times)

    @property
    def error(self) -> float:
        return max(self.fixed_point, self.closed_form)


def accuracy(problem: NDofImpactProblem, ys: np.ndarray) -> tuple[float, float]:
    """(a) max relative full return-map residual, (b) max relative distance to the closed form."""
    fp, cf = 0.0, 0.0
    for y in ys:
        u0, du0, T = problem.state(y)
        x = np.concatenate([u0, du0])
        G, _ = problem.gamma(T)
        fp = max(fp, float(np.max(np.abs(G @ x - x)) / np.max(np.abs(x))))
        uc, duc = problem.closed_form(T)
        xc = np.concatenate([uc, duc])
        cf = max(cf, float(np.max(np.abs(x - xc)) / np.max(np.abs(xc))))
    return fp, cf


def start_y(problem: NDofImpactProblem) -> np.ndarray:
    T = T_START * problem.T_lin[0]
    u0, du0 = problem.closed_form(T)
    return problem.y_from_state(u0, du0, T)


def run_engine(problem: NDofImpactProblem, tol: float, detect: bool, coarse: bool = False
               ) -> tuple[np.ndarray, int, list[str]]:
    T1 = problem.T_lin[0]
    settings = ContinuationSettings(step_initial=STEP_INITIAL, step_max=STEP_MAX,
                                    step_min=STEP_MIN, newton_tol=tol, param_min=T_STOP * T1,
                                    max_points=10_000, direction=-1, detect_bifurcations=detect)
    if coarse and hasattr(settings, "max_multiplier_step"):
        settings.max_multiplier_step = float("inf")  # no step control by multiplier motion
    engine = ContinuationEngine(problem, settings)
    branch = engine.run(StartPoint(start_y(problem), "branch 1", -1))
    if not branch.points:
        raise RuntimeError(f"engine failed: {branch.termination}")
    ys = np.array([p.y for p in branch.points])
    return ys, engine.n_evaluations, [ev.kind for ev in branch.events]


def run_pycont_once(problem: NDofImpactProblem, tol: float, extras: bool
                    ) -> tuple[np.ndarray, int, list[str]]:
    T1 = problem.T_lin[0]
    out = run_pycont(problem, start_y(problem), ds_min=STEP_MIN, ds_max=STEP_MAX,
                     ds_0=STEP_INITIAL, n_steps=10_000, direction=-1, tolerance=tol,
                     param_min=T_STOP * T1, bifurcation_detection=extras,
                     analyze_stability=extras, full_output=True)
    return out.y, out.n_evaluations, [ev.kind for ev in out.result.events]


def measure(name: str, tol: float, fun: Callable[[], tuple[np.ndarray, int, list[str]]],
            problem: NDofImpactProblem, repeat: int) -> Row:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        ys, n_res, events = fun()
        times.append(time.perf_counter() - t0)
    fp, cf = accuracy(problem, ys)
    T1 = problem.T_lin[0]
    return Row(name, tol, times, len(ys), n_res, fp, cf,
               (float(ys[:, -1].min() / T1), float(ys[:, -1].max() / T1)), events)


def speed_ratios(rows: list[Row], engine_methods: tuple[str, ...], pycont_method: str
                 ) -> list[tuple[Row, Row | None, float]]:
    """For each pycont run: the fastest engine run (of ``engine_methods``) with an error (max of
    (a) and (b)) at most the pycont run's error, and the ratio t_pycont / t_engine."""
    out = []
    for pr in (r for r in rows if r.method == pycont_method):
        ok = [r for r in rows if r.method in engine_methods and r.error <= pr.error]
        best = min(ok, key=lambda r: r.time) if ok else None
        out.append((pr, best, pr.time / best.time if best else float("nan")))
    return out


def chart(rows: list[Row], path: Path) -> None:
    styles = {
        "engine": ("o", "C0"), "engine + detection": ("s", "C1"),
        "engine, hooks off": ("D", "C2"), "engine, coarse steps": ("P", "C5"),
        "engine + det., coarse": ("X", "C6"), "pycont": ("^", "C3"),
        "pycont + bif + stab": ("v", "C4"),
    }
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharex=True)
    floor = 1e-17  # an exact zero would vanish from a log axis
    for ax, attr, title in ((axes[0], "fixed_point", "(a) full return-map residual"),
                            (axes[1], "closed_form", "(b) distance to the closed form (4.2)")):
        for method, (marker, color) in styles.items():
            sel = [r for r in rows if r.method == method]
            if not sel:
                continue
            x = [r.time for r in sel]
            y = [max(getattr(r, attr), floor) for r in sel]
            ax.loglog(x, y, marker=marker, color=color, linestyle=":", label=method)
            for r, xi, yi in zip(sel, x, y, strict=True):
                ax.annotate(f"{r.tol:.0e}", (xi, yi), textcoords="offset points",
                            xytext=(4, 3), fontsize=7, color=color)
        ax.set_xlabel("wall time per run [s] (best of repeats)")
        ax.set_ylabel("max relative error over the branch")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axes[1].legend(loc="best", fontsize=8)
    fig.suptitle("Branch 1 of the 5-dof chain, T from 0.99 T1 to 0.90 T1 "
                 "(labels: newton_tol / pycont tolerance)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def main(argv: list[str] | None = None) -> list[Row]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per configuration")
    ap.add_argument("--out", type=Path, default=OUT, help="chart file")
    args = ap.parse_args(argv)

    problem = NDofImpactProblem(PAPER_CHAIN)
    bare = BareProblem(PAPER_CHAIN)
    _ = (problem.compiled, bare.compiled)  # build the CasADi functions before timing
    import_time = time.perf_counter()
    as_pycont_system(problem)
    run_pycont(problem, start_y(problem), n_steps=1, tolerance=1e-6)  # warm pycont imports
    import_time = time.perf_counter() - import_time

    rows: list[Row] = []
    for tol in ENGINE_TOLS:
        rows.append(measure("engine", tol, lambda t=tol: run_engine(problem, t, False),
                            problem, args.repeat))
        rows.append(measure("engine + detection", tol,
                            lambda t=tol: run_engine(problem, t, True), problem, args.repeat))
        rows.append(measure("engine, hooks off", tol, lambda t=tol: run_engine(bare, t, False),
                            problem, args.repeat))
        if hasattr(ContinuationSettings(), "max_multiplier_step"):
            rows.append(measure("engine, coarse steps", tol,
                                lambda t=tol: run_engine(problem, t, False, True), problem,
                                args.repeat))
            rows.append(measure("engine + det., coarse", tol,
                                lambda t=tol: run_engine(problem, t, True, True), problem,
                                args.repeat))
    for tol in PYCONT_TOLS:
        rows.append(measure("pycont", tol, lambda t=tol: run_pycont_once(problem, t, False),
                            problem, args.repeat))
        rows.append(measure("pycont + bif + stab", tol,
                            lambda t=tol: run_pycont_once(problem, t, True), problem,
                            args.repeat))

    print(f"branch 1, T in [{T_STOP} T1, {T_START} T1], T1 = {problem.T_lin[0]:.6f}; "
          f"best of {args.repeat} runs (pycont warm-up incl. imports: {import_time:.2f} s)\n")
    head = (f"{'method':<22}{'tol':>8}{'time [ms]':>11}{'median':>9}{'points':>8}"
            f"{'G evals':>9}{'(a) fixed pt':>14}{'(b) closed f':>14}  T range / T1   events")
    print(head)
    print("-" * len(head))
    for r in rows:
        ev = {k: r.events.count(k) for k in dict.fromkeys(r.events)}
        evs = ", ".join(f"{k} x{v}" if v > 1 else k for k, v in ev.items())
        print(f"{r.method:<22}{r.tol:>8.0e}{1e3 * r.time:>11.1f}"
              f"{1e3 * statistics.median(r.times):>9.1f}{r.n_points:>8d}{r.n_residuals:>9d}"
              f"{r.fixed_point:>14.2e}{r.closed_form:>14.2e}  "
              f"[{r.T_range[0]:.4f}, {r.T_range[1]:.4f}]  {evs}")

    print("\nspeed ratio t_pycont / t_engine at equal or better accuracy "
          "(error = max of (a), (b); fastest engine run with error <= pycont's):")
    pairs = [
        ("pycont", ("engine",), "engine (hooks on, detection off) vs pycont (bif/stab off)"),
        ("pycont", ("engine, hooks off",), "engine hooks off vs pycont (bif/stab off)"),
        ("pycont", ("engine, coarse steps",),
         "engine coarse steps (hooks on, detection off) vs pycont (bif/stab off)"),
        ("pycont + bif + stab", ("engine + detection",),
         "engine + detection vs pycont + bif + stab"),
    ]
    summary = []
    for pmethod, emethods, label in pairs:
        print(f"  {label}:")
        ratios = speed_ratios(rows, emethods, pmethod)
        for pr, er, ratio in ratios:
            if er is None:
                print(f"    pycont tol {pr.tol:.0e} (error {pr.error:.1e}, {1e3 * pr.time:.1f} ms)"
                      ": no engine run that accurate")
                continue
            print(f"    pycont tol {pr.tol:.0e} (error {pr.error:.1e}, {1e3 * pr.time:.1f} ms) "
                  f"vs engine tol {er.tol:.0e} (error {er.error:.1e}, {1e3 * er.time:.1f} ms): "
                  f"{ratio:.2f}x")
        finite = [r for _, _, r in ratios if np.isfinite(r)]
        if finite:
            summary.append((label, min(finite), max(finite)))
    print("\nsummary (target: engine >= 10x faster at equal or better accuracy):")
    for label, lo, hi in summary:
        verdict = "met" if lo >= 10 else ("not met" if hi < 10 else "met for some tolerances")
        print(f"  {label}: {lo:.2f}x .. {hi:.2f}x -> target {verdict}")
    chart(rows, args.out)
    print(f"\nchart: {args.out}")
    return rows


if __name__ == "__main__":
    main()

