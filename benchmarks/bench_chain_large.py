"""Large chains with stability: the 200-dof mode-1 branch, one point at N = 1000, and the
paper's 5-dof branch 1 (targets: "200-dof chain ... < 30 s", "N = 1000: < 0.1 s per
continuation point with multipliers", "branch 1 with all 27 events < 0.15 s").

* ``N = 200``: the chain of eq. (2.17) with ``m = 1/N``, ``k = N`` (paper's scaling), gap 1,
  ``start: {mode: 1}``, omega in [0.5, 3], stability and bifurcations on, through
  ``nsm_continuation.continuation`` (the runner, as a YAML case); wall time, points, events by
  kind, Floquet calls answered by the dense fallback, termination; with ``--oracle M`` the
  located crossings are checked against the number of multipliers outside the circle on ``M``
  closed-form orbits of the same period range (no continuation): every grid interval where
  that number changes should contain a located crossing.
* ``N = 1000``: the same chain, one converged point of branch 1; the parts of one
  continuation point timed separately (best of repeats): residual + Jacobian, one bordered
  Newton step (dense LU of size N + 2), the tangent, the multipliers from the structure
  (:meth:`NDofImpactProblem.floquet`, O(N^2), warm start from a point 1e-9 T away, and cold)
  and their Krein definiteness, against the dense eigenvalues
  (:meth:`NDofImpactProblem.floquet_dense`, O(N^3)), and the exact admissibility test; then
  whole runs of ``RUN_POINTS`` points from it (the engine's step control included) without
  multipliers, with them, and with their crossings located, per point, with the multiplier
  sets computed per point.
* ``N = 5`` (the paper's chain, ``m = 0.2``, ``k = 5``): branch 1 from ``0.99 T_1`` down to
  ``0.90 T_1`` with detection on (the window of ``bench_engine_vs_pycont.py``), wall time and
  events, with the Krein-aware step control and with the generic motion check.

With ``--baseline FILE`` (another version of ``nsm_continuation/core/floquet.py``, e.g. the
committed one: ``git show HEAD:nsm_continuation/core/floquet.py > /tmp/floquet_head.py``) the
``N = 1000`` point is timed twice in the same run, first with the chain's multipliers from
that file's solvers (``low_rank_update_eigen``, ``krein_definiteness``, ``refine_roots``),
then with the current ones, so that a change is measured under the same load (``--repeat
R``: R such rounds, alternating, the best of each number kept); the ``N = 200`` branch is
run with both too, and the periods of its located crossings compared.

BLAS pinned to one thread (see benchmarks/README.md). Machine: 2 cores (shared), see
``/work/.library/env``; the numbers change with the load: rerun to refresh.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import collections  # noqa: E402
import contextlib  # noqa: E402
import importlib.util  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from nsm_continuation.problems.chain import stability as chain_stability  # noqa: E402
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem  # noqa: E402

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation.core.palc import ContinuationEngine  # noqa: E402
from nsm_continuation.core.problem import StartPoint  # noqa: E402
from nsm_continuation.core.settings import ContinuationSettings  # noqa: E402


def best(fun: Callable[[], Any], repeat: int = 3) -> float:
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fun()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def paper_scaled_chain(n: int) -> NDofImpactProblem:
    return NDofImpactProblem({"chain": {"dofs": n, "mass": 1.0 / n, "stiffness": float(n)},
                              "gap": 1.0})


def branch_200(n: int, max_points: int) -> tuple[dict[str, Any], list[float], Any]:
    pb = paper_scaled_chain(n)
    t0 = time.perf_counter()
    res = nsm.continuation(pb, {"mode": 1}, parameter="omega", min=0.5, max=3.0,
                           max_points=max_points,
                           analysis={"stability": True, "bifurcations": True})
    wall = time.perf_counter() - t0
    br = res.branches[0]
    kinds = collections.Counter(ev.kind for ev in res.events)
    # the period of each located crossing (T is the problem's own parameter, the last unknown)
    crossings = sorted(float(ev.point.y[-1]) for ev in res.events
                       if ev.kind in ("neimark_sacker", "period_doubling", "fold"))
    T = 2 * np.pi / np.asarray(br["omega"])
    return ({"wall [s]": round(wall, 2), "points": len(br["omega"]),
             "T range": (float(T.min()), float(T.max())),
             "events": dict(kinds), "termination": br.termination,
             "Floquet calls answered densely": pb.floquet_fallbacks},
            crossings, (float(T.min()), float(T.max())))


def oracle_coverage(n: int, t_range: tuple[float, float], samples: int,
                    crossings: list[float]) -> dict[str, Any]:
    """Independent check of the crossings: the number of multipliers outside the circle
    (``> 1 + 1e-7``) on a uniform grid of ``samples`` periods of the branch (closed-form orbits
    (4.2), dense eigenvalues for N <= 40 else the structured ones, no continuation, no step
    control), and how many grid intervals where that count changes contain a located
    crossing. An interval with a change and no located crossing is a window the engine
    missed (at the grid's resolution)."""
    pb = paper_scaled_chain(n)
    Ts = np.linspace(t_range[0], t_range[1], samples)
    counts = []
    for T in Ts:
        u0, du0 = pb.closed_form(T)
        y = pb.y_from_state(u0, du0, T)
        if not all(v >= 0 for v in pb.admissibility(y).values()):
            counts.append(-1)
            continue
        t = np.linalg.svd(pb.jacobian(y))[2][-1]
        fl = pb.floquet(y, t)
        if fl is None:  # at (numerical) grazing: no multipliers
            counts.append(-1)
            continue
        tol = max(1e-7, 1e3 * np.finfo(float).eps * fl.matrix_norm)
        counts.append(int(np.sum(np.abs(fl.multipliers) > 1 + tol)))
    c = np.array(counts)
    x = np.asarray(crossings)
    changed = missed = 0
    for i in range(samples - 1):
        if c[i] < 0 or c[i + 1] < 0 or c[i] == c[i + 1]:
            continue
        changed += 1
        if not np.any((x >= Ts[i]) & (x <= Ts[i + 1])):
            missed += 1
    return {"grid step": float(Ts[1] - Ts[0]), "intervals with a count change": changed,
            "of them without a located crossing": missed}


def branch1_point(n: int) -> tuple[NDofImpactProblem, ContinuationEngine, np.ndarray,
                                    np.ndarray, np.ndarray]:
    """The chain, an engine, a converged point ``y`` of branch 1 at ``T = (1 - 1e-5) T_1``
    with its tangent ``t``, and the closed-form point ``y2`` 1e-9 T away (a warm start)."""
    pb = paper_scaled_chain(n)
    eng = ContinuationEngine(pb, ContinuationSettings(stability_on_phantom=True))
    T = pb.T_lin[0] * (1 - 1e-5)
    u0, du0 = pb.closed_form(T)
    p0, why = eng.correct_start(StartPoint(pb.y_from_state(u0, du0, T), "b1", -1))
    if p0 is None:
        raise RuntimeError(why)
    y, t = p0.y, p0.tangent
    T2 = T * (1 - 1e-9)
    u2, du2 = pb.closed_form(T2)
    y2 = pb.y_from_state(u2, du2, T2)
    return pb, eng, y, t, y2


def point_1000(n: int) -> dict[str, float]:
    pb, eng, y, t, y2 = branch1_point(n)
    out: dict[str, float] = {}
    out["G + J"] = best(lambda: (pb.evaluate(y), pb.jacobian(y)))
    out["Newton step"] = best(lambda: eng.correct(y, t, y, 0.0))
    out["tangent"] = best(lambda: eng.tangent(y, t))

    def warm() -> None:
        pb.floquet(y, t)       # leaves its multipliers as the next start
        t0 = time.perf_counter()
        pb.floquet(y2, t)
        warm_times.append(time.perf_counter() - t0)

    warm_times: list[float] = []
    for _ in range(3):
        warm()
    out["Floquet structured (warm)"] = min(warm_times)

    def cold() -> None:
        pb.multiplier_memory.clear()
        pb.floquet(y, t)

    out["Floquet structured (cold)"] = best(cold)
    krein = pb.floquet(y, t).krein_source  # what the step control asks for once per set
    out["Krein definiteness of a set"] = best(krein)
    out["Floquet dense"] = best(lambda: pb.floquet_dense(y, t), repeat=1)
    out["admissibility"] = best(lambda: pb.admissibility(y), repeat=2)
    fs, fd = pb.floquet(y, t), pb.floquet_dense(y, t)
    from scipy.optimize import linear_sum_assignment

    cost = np.abs(fs.multipliers[:, None] - fd.multipliers[None, :])
    r, c = linear_sum_assignment(cost)
    out["max |structured - dense|"] = float(cost[r, c].max())
    # whole continuation points: the engine's run (multipliers, step control, admissibility,
    # located events) from the converged point, per returned point
    for stability, detect, key in ((False, False, "without multipliers"),
                                    (True, False, "with multipliers, crossings not located"),
                                    (True, True, "with multipliers and located crossings")):
        st = ContinuationSettings(stability_on_phantom=True, stability=stability,
                                  detect_bifurcations=detect, max_points=RUN_POINTS,
                                  step_initial=1e-3, direction=-1)
        run = ContinuationEngine(pb, st)
        sets = [0]
        floquet = pb.floquet

        def counted(*args: Any, floquet: Callable[..., Any] = floquet,
                    sets: list[int] = sets) -> Any:
            sets[0] += 1
            return floquet(*args)

        pb.floquet = counted  # type: ignore[method-assign]
        t0 = time.perf_counter()
        br = run.run(StartPoint(y, "b1", -1))
        out[f"per point, {key}"] = (time.perf_counter() - t0) / len(br.points)
        del pb.floquet  # the method again
        if stability:
            out[f"  multiplier sets per point ({'' if detect else 'not '}located)"] = \
                sets[0] / len(br.points)
        if detect:
            out["  crossings located in the run"] = float(
                sum(e.kind != "endpoint" for e in br.events))
    return out


#: points of the timed runs of :func:`point_1000`
RUN_POINTS = 20


@contextlib.contextmanager
def multiplier_solvers(path: str | None) -> Iterator[None]:
    """Within the block the chain's multipliers come from the solvers of the ``floquet.py``
    at ``path`` (loaded as a module of the package, so that its relative imports resolve);
    None: the current ones. A keyword the other version does not know (``off_circle`` of
    :func:`~nsm_continuation.core.floquet.krein_definiteness`) is dropped."""
    if path is None:
        yield
        return
    spec = importlib.util.spec_from_file_location("nsm_continuation._floquet_baseline", path)
    if spec is None or spec.loader is None:
        raise FileNotFoundError(path)
    base = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = base  # its dataclasses look their module up there
    spec.loader.exec_module(base)

    def krein(*args: Any, off_circle: float | None = None) -> np.ndarray:
        return base.krein_definiteness(*args)

    names = {"low_rank_update_eigen": base.low_rank_update_eigen,
             "krein_definiteness": krein, "refine_roots": base.refine_roots}
    saved = {k: getattr(chain_stability, k) for k in names}
    try:
        for k, v in names.items():
            setattr(chain_stability, k, v)
        yield
    finally:
        for k, v in saved.items():
            setattr(chain_stability, k, v)
        del sys.modules[spec.name]


def branch1_paper(krein: bool) -> dict[str, Any]:
    pb = NDofImpactProblem({"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0})
    T1 = pb.T_lin[0]
    st = ContinuationSettings(step_initial=1e-2, step_max=0.2, step_min=1e-6,
                              param_min=0.90 * T1, param_max=0.99 * T1, direction=-1,
                              newton_tol=1e-8, krein_step_control=krein)
    u0, du0 = pb.closed_form(0.99 * T1)
    start = StartPoint(pb.y_from_state(u0, du0, 0.99 * T1), "branch 1", -1)
    times, n_ev, kinds, npts = [], 0, None, 0
    for _ in range(3):
        pb.multiplier_memory.clear()
        eng = ContinuationEngine(pb, st)
        t0 = time.perf_counter()
        br = eng.run(start)
        times.append(time.perf_counter() - t0)
        ev = [e for e in br.events if e.kind != "endpoint"]
        n_ev, npts = len(ev), len(br.points)
        kinds = dict(collections.Counter(e.kind for e in ev))
    return {"wall": min(times), "points": npts, "events": n_ev, "kinds": kinds}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-branch", type=int, default=200)
    ap.add_argument("--n-point", type=int, default=1000)
    ap.add_argument("--max-points", type=int, default=3000)
    ap.add_argument("--skip", nargs="*", default=[], choices=["branch", "point", "paper"])
    ap.add_argument("--oracle", type=int, default=0,
                    help="check the branch's crossings against this many sampled orbits")
    ap.add_argument("--baseline", default=None, metavar="FILE",
                    help="a floquet.py to time the N = 1000 point against, in the same run")
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs of the N = 1000 point (alternating with --baseline); best kept")
    args = ap.parse_args(argv)
    print(f"BLAS threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}, "
          f"cores: {os.cpu_count()}, load: {os.getloadavg()}")
    if "paper" not in args.skip:
        print("\n5-dof paper chain, branch 1, [0.90, 0.99] T_1, detection on")
        print(f"{'step control':<22}{'wall [s]':>10}{'points':>8}{'events':>8}  kinds")
        for krein in (True, False):
            r = branch1_paper(krein)
            print(f"{'Krein-aware' if krein else 'generic motion':<22}{r['wall']:>10.3f}"
                  f"{r['points']:>8}{r['events']:>8}  {r['kinds']}")
    if "point" not in args.skip:
        print(f"\nN = {args.n_point}: one continuation point, parts (best of repeats) [s]")
        variants = ((("baseline", args.baseline),) if args.baseline else ()) \
            + (("current", None),)
        runs: dict[str, dict[str, float]] = {}
        for _ in range(args.repeat):  # alternated, so that a change of load hits both
            for label, path in variants:
                with multiplier_solvers(path):
                    r = point_1000(args.n_point)
                runs[label] = {k: min(v, runs.get(label, r)[k]) for k, v in r.items()}
        print(f"  {'':<30}" + "".join(f"{label:>12}" for label in runs))
        for k in runs["current"]:
            print(f"  {k:<30}" + "".join(f"{r[k]:>12.4g}" for r in runs.values()))
    if "branch" not in args.skip:
        print(f"\nN = {args.n_branch}: mode-1 branch, omega in [0.5, 3], stability + "
              f"bifurcations, max_points {args.max_points}")
        if args.baseline:  # the same branch from the other solvers: the same events?
            with multiplier_solvers(args.baseline):
                rb, base_crossings, _ = branch_200(args.n_branch, args.max_points)
            print(f"  baseline: {rb}")
        r, crossings, t_range = branch_200(args.n_branch, args.max_points)
        for k, v in r.items():
            print(f"  {k}: {v}")
        if args.baseline:
            same = len(crossings) == len(base_crossings)
            print("  crossings' periods, largest difference to the baseline's: " + (
                f"{np.max(np.abs(np.subtract(crossings, base_crossings)), initial=0.0):.3g}"
                if same else f"counts differ ({len(crossings)} vs {len(base_crossings)})"))
        if args.oracle:
            print(f"  oracle ({args.oracle} closed-form orbits on the branch's T range):")
            for k, v in oracle_coverage(args.n_branch, t_range, args.oracle, crossings).items():
                print(f"    {k}: {v}")


if __name__ == "__main__":
    main()
