"""Cost of one continuation point vs the number of dofs N, for random spring-mass chains.

Systems: ``NDofImpactProblem`` chains (eq. 2.17) with ``N = 5, 20, 100, 500``, masses and
stiffnesses drawn uniformly in ``[0.5, 2]`` (seeded), gap 1, last dof impacting. Every component
is timed at a converged, admissible point of branch 1 (closed form (4.2) at
``T = T_1 - (T_1 - T_p) / 4``, ``T_p`` the largest pole ``k T_j`` below ``T_1``, corrected by the
engine):

* ``build``: ``NDofImpactProblem(...)`` (generalised eigenproblem ``K P = M P Omega^2``) and
  ``problem.compiled`` (CasADi Functions of ``G`` and its exact Jacobian; SX for N <= 30, MX
  above), each on a fresh instance;
* ``G + J``: ``problem.evaluate(y)`` + ``problem.jacobian(y)``;
* ``Newton step``: ``ContinuationEngine.correct`` from a converged point (one bordered iteration:
  G, J, dense solve of size N + 2, and the convergence check);
* ``tangent``: ``ContinuationEngine.tangent`` (one bordered solve);
* ``Floquet``: ``problem.floquet``: for ``N > 40`` the multipliers from the structure of the
  return map (rotation plus rank two, secular equation, O(N^2), started from the multipliers
  of the previous call) with their Krein definiteness; up to 40 dofs the dense eigenvalues;
* ``Floquet dense``: ``problem.floquet_dense`` (return-map Jacobian (A.8), restriction,
  Householder deflation, ``eigvals`` of a ``(2N - 2)`` square matrix): the O(N^3) oracle;
* ``admissibility``: ``problem.admissibility`` (exact maximum of ``u_N(t)`` over ``(0, T)`` by
  certified subdivision, :class:`~nsm_continuation.problems.chain.trig_sum.TrigSum`);
* ``per point``: wall time of ``ContinuationEngine.run`` (bifurcation detection off, no bounds,
  multipliers also on phantom points) divided by the number of points it returns: Newton
  corrections + tangent + every hook.

Time: best of several repeats. Peak memory: ``tracemalloc`` peak above the baseline during one
call (Python and numpy allocations; CasADi's C++ heap and BLAS workspaces are not traced).
Writes ``benchmarks/results/scaling.png`` (time per point vs N, log-log, with components) and
times the full Fig. 3.2 frequency-energy plot case (``yaml_cases/ndof_fig3_2_fep.yaml`` through
``nsm_continuation.runs.runner.run_case``) unless ``--skip-fep``.

BLAS threads: OpenBLAS is pinned to one thread (``OPENBLAS_NUM_THREADS=1`` unless already set).
On this 2-core machine, shared with other jobs, two OpenBLAS threads made ``eigh``/``eigvals`` of
the N = 500 matrices up to 100x slower and erratic (0.03 s vs 0.07-4 s for the same ``eigh``):
spinning threads contend for the cores. Matrices of size <= 1000 gain nothing from threads here.

What limits large N and how cost grows with N: measured numbers are in benchmarks/README.md
(they change with the code; rerun this script to update them).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem  # noqa: E402

from nsm_continuation.core.palc import ContinuationEngine  # noqa: E402
from nsm_continuation.core.problem import StartPoint  # noqa: E402
from nsm_continuation.core.settings import ContinuationSettings  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).resolve().parent / "results" / "scaling.png"
FEP_CASE = ROOT / "yaml_cases" / "ndof_fig3_2_fep.yaml"
COMPONENTS = ("G + J", "Newton step", "tangent", "Floquet", "Floquet dense", "admissibility",
              "per point")


def random_chain(n: int, seed: int = 1) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    return {"chain": {"dofs": n, "mass": rng.uniform(0.5, 2.0, n).tolist(),
                      "stiffness": rng.uniform(0.5, 2.0, n).tolist()}, "gap": 1.0}


def branch1_period(problem: NDofImpactProblem, frac: float = 0.25) -> float:
    """A period on branch 1 itself: ``T_1 - frac (T_1 - T_p)`` with ``T_p`` the largest pole
    ``k T_j < T_1`` (for large N the subharmonic poles crowd below ``T_1``; beyond the first one
    lies another branch, often phantom, whose points would skip the Floquet hook)."""
    T1 = problem.T_lin[0]
    k = np.floor(T1 / problem.T_lin[1:] * (1 - 1e-12))
    below = (k * problem.T_lin[1:])[k >= 1]
    Tp = float(below.max()) if below.size else 0.5 * T1
    return T1 - frac * (T1 - Tp)


def best_time(fun: Callable[[], Any], min_total: float = 0.3, max_repeat: int = 50,
              min_repeat: int = 2) -> float:
    """Best wall time of repeated calls (at least ``min_repeat``, until ``min_total`` s)."""
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < max_repeat and (len(times) < min_repeat
                                       or time.perf_counter() - start < min_total):
        t0 = time.perf_counter()
        fun()
        times.append(time.perf_counter() - t0)
    return min(times)


def peak_memory(fun: Callable[[], Any]) -> float:
    """tracemalloc peak (bytes) above the current traced size during one call."""
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        fun()
        return float(tracemalloc.get_traced_memory()[1] - base)
    finally:
        tracemalloc.stop()


@dataclass
class SizeResult:
    n: int
    time: dict[str, float] = field(default_factory=dict)
    memory: dict[str, float] = field(default_factory=dict)
    n_points: int = 0
    symbolic: str = ""
    #: hook evaluations (ContinuationEngine.analyse calls) and residual evaluations in one run:
    #: more analyses than points = steps rejected after their hooks ran, or event location
    analyses: int = 0
    evaluations: int = 0


def measure_size(n: int, points: int) -> SizeResult:
    params = random_chain(n)
    res = SizeResult(n)

    def build() -> NDofImpactProblem:
        return NDofImpactProblem(params)

    def build_compiled() -> None:
        _ = build().compiled

    t_init = best_time(build, min_total=0.2, max_repeat=5)
    t_both = best_time(build_compiled, min_total=0.2, max_repeat=5)
    res.time["build: problem"] = t_init
    res.time["build: CasADi"] = max(t_both - t_init, 0.0)
    res.memory["build: problem + CasADi"] = peak_memory(build_compiled)

    problem = build()
    _ = problem.compiled
    res.symbolic = problem.symbolic
    settings = ContinuationSettings(detect_bifurcations=False, max_points=points, direction=-1)
    if hasattr(settings, "stability_on_phantom"):
        # multipliers at every point (the engine skips them on phantom points otherwise; the
        # poles crowd below T_1 for large N, so a few steps may leave the admissible part)
        settings.stability_on_phantom = True
    engine = ContinuationEngine(problem, settings)
    T = branch1_period(problem)
    u0, du0 = problem.closed_form(T)
    start = StartPoint(problem.y_from_state(u0, du0, T), "branch 1", -1)
    p0, why = engine.correct_start(start)
    if p0 is None:
        raise RuntimeError(f"N = {n}: start did not converge ({why})")
    y, t = p0.y, p0.tangent

    parts: dict[str, Callable[[], Any]] = {
        "G + J": lambda: (problem.evaluate(y), problem.jacobian(y)),
        "Newton step": lambda: engine.correct(y, t, y, 0.0),
        "tangent": lambda: engine.tangent(y, t),
        "Floquet": lambda: problem.floquet(y, t),
        "Floquet dense": lambda: problem.floquet_dense(y, t),
        "admissibility": lambda: problem.admissibility(y),
    }
    for name, fun in parts.items():
        res.time[name] = best_time(fun)
        res.memory[name] = peak_memory(fun)

    start_conv = StartPoint(y.copy(), "branch 1", -1)
    n_pts = 0

    def run() -> None:
        nonlocal n_pts
        eng = ContinuationEngine(problem, settings)
        analyse = eng.analyse

        def counted(*a: Any, **k: Any) -> Any:
            res.analyses += 1
            return analyse(*a, **k)

        eng.analyse = counted  # type: ignore[method-assign]
        res.analyses = 0
        branch = eng.run(start_conv)
        n_pts = len(branch.points)
        res.evaluations = eng.n_evaluations

    t_run = best_time(run, min_total=0.5, max_repeat=5, min_repeat=1 if n >= 500 else 2)
    res.n_points = n_pts
    res.time["per point"] = t_run / max(n_pts, 1)
    res.memory["per point"] = peak_memory(run)
    return res


def exponent(ns: list[int], ts: list[float]) -> float:
    x, y = np.log(np.asarray(ns, float)), np.log(np.asarray(ts, float))
    return float(np.polyfit(x, y, 1)[0])


def chart(results: list[SizeResult], path: Path) -> None:
    ns = [r.n for r in results]
    fig, ax = plt.subplots(figsize=(8, 5.5))
    styles = {"per point": ("k", "o", "-", 2.5), "Floquet": ("C3", "s", "--", 1.5),
              "Floquet dense": ("C3", "x", ":", 1.0),
              "admissibility": ("C2", "D", "--", 1.5), "G + J": ("C0", "^", ":", 1.2),
              "Newton step": ("C1", "v", ":", 1.2), "tangent": ("C4", "<", ":", 1.2),
              "build: CasADi": ("C7", "x", "-.", 1.0), "build: problem": ("C5", "+", "-.", 1.0)}
    for name, (color, marker, ls, lw) in styles.items():
        ts = [r.time[name] for r in results]
        slope = exponent(ns[1:], ts[1:]) if len(ns) > 2 else float("nan")
        label = f"{name} (once per problem)" if name.startswith("build") else name
        ax.loglog(ns, ts, color=color, marker=marker, linestyle=ls, linewidth=lw,
                  label=f"{label} ~N^{slope:.1f}" if np.isfinite(slope) else label)
    ax.set_xlabel("number of degrees of freedom N")
    ax.set_ylabel("wall time [s] (best of repeats, 1 BLAS thread)")
    ax.set_title("Cost per continuation point and its components, random chains\n"
                 "(slopes: log-log fit over N = 20..500)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def time_fep() -> str:
    """Full Fig. 3.2 FEP run through the case runner, if the runner exists."""
    try:
        from nsm_continuation import cases
        from nsm_continuation.runs.runner import run_case
    except ImportError as exc:
        return f"FEP: skipped (no case runner: {exc})"
    if not FEP_CASE.exists():
        return f"FEP: skipped ({FEP_CASE} not found)"
    t0 = time.perf_counter()
    case, problem = cases.load(FEP_CASE)
    result = run_case(case, problem, progress=False)
    wall = time.perf_counter() - t0
    tm = result.timings
    return (f"FEP ({FEP_CASE.name}): {wall:.1f} s wall, {len(result.branches)} branches, "
            f"{tm.get('n_points', '?')} points, {tm.get('residual_evaluations', '?')} residual "
            f"evaluations, {1e3 * wall / max(int(tm.get('n_points', 1)), 1):.2f} ms per point")


def main(argv: list[str] | None = None) -> list[SizeResult]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 20, 100, 500])
    ap.add_argument("--points", type=int, default=6,
                    help="points per timed continuation run (start included)")
    ap.add_argument("--skip-fep", action="store_true", help="do not time the Fig. 3.2 case")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)

    print(f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    results = []
    for n in args.sizes:
        t0 = time.perf_counter()
        results.append(measure_size(n, args.points))
        print(f"  N = {n}: measured in {time.perf_counter() - t0:.1f} s", flush=True)

    cols = ["build: problem", "build: CasADi", *COMPONENTS]
    print("\ntime [ms] (best of repeats)")
    print(f"{'N':>5} {'sym':>4}" + "".join(f"{c:>15}" for c in cols)
          + f"{'pts':>5}{'analyses':>9}{'G evals':>8}")
    for r in results:
        print(f"{r.n:>5} {r.symbolic:>4}" + "".join(f"{1e3 * r.time[c]:>15.3f}" for c in cols)
              + f"{r.n_points:>5}{r.analyses:>9}{r.evaluations:>8}")
    if len(results) > 2:
        ns = [r.n for r in results[1:]]
        print(f"{'slope':>10}" + "".join(
            f"{exponent(ns, [r.time[c] for r in results[1:]]):>15.2f}" for c in cols)
            + f"   (log-log fit, N = {ns[0]}..{ns[-1]})")
    mcols = ["build: problem + CasADi", *COMPONENTS]
    print("\npeak traced memory [MB] (tracemalloc, one call)")
    print(f"{'N':>5}     " + "".join(f"{c:>25}" if i == 0 else f"{c:>15}"
                                     for i, c in enumerate(mcols)))
    for r in results:
        print(f"{r.n:>5}     " + "".join(
            f"{r.memory[c] / 2**20:>25.3f}" if i == 0 else f"{r.memory[c] / 2**20:>15.3f}"
            for i, c in enumerate(mcols)))
    print("\nshare of the time per point [%] (component at the start point x analyses per point"
          " for Floquet/admissibility)")
    for r in results:
        per = r.analyses / max(r.n_points, 1)
        share = {c: 100 * r.time[c] / r.time["per point"] for c in COMPONENTS[:-1]
                 if c != "Floquet dense"}
        hooks = 100 * per * (r.time["Floquet"] + r.time["admissibility"]) / r.time["per point"]
        print(f"  N = {r.n:>4}: " + "   ".join(f"{c} {v:5.1f}" for c, v in share.items())
              + f"   | {per:.2f} analyses/point -> hooks ~{hooks:5.1f}")
    chart(results, args.out)
    print(f"\nchart: {args.out}")
    if not args.skip_fep:
        print(time_fep())
    return results


if __name__ == "__main__":
    main()
