"""Windows hidden inside one step: what the Krein words find, and what
loosening the step control costs in missed events.

For each case, the events located with the default step control are the reference; the same
case is run again with

* ``max_multiplier_step: 0.1`` and ``1`` (the closing rule kept, as in the defaults),
* ``max_multiplier_step: 1`` with the closing rule also removed
  (``palc.step_control.krein_closing`` replaced by one that never refuses: not a setting, a
  test of the safety net alone),
* the defaults without the cap from the motion ratio on the growth of an accepted step
  (``palc.step_control._motion_capped_step`` replaced: the step grows by the constant factor
  alone),

and each run prints its points, step attempts (predictor-corrector calls), compute time, how
many of the reference's crossings it finds (same kind on the same branch within 1e-9 in the
problem's parameter) and how many of its
events were found inside a step (``hidden_in_step``). Cases: the bundled default case (the
paper's 5-dof chain, branch 1) and Fig. 3.2 (``yaml_cases/ndof_fig3_2_fep.yaml``); with
``--n200`` also the 200-dof mode-1 branch of ``bench_chain_large.py`` (about 30 s per run).

Run: ``python benchmarks/bench_krein_windows.py [--n200]`` (2 cores, Python 3.11; the machine
in ``/work/.library/env``). BLAS pinned to one thread.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import collections  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation.core import palc  # noqa: E402
from nsm_continuation.core.palc import step_control  # noqa: E402

CROSSINGS = ("fold", "period_doubling", "neimark_sacker")
#: (label, analysis overrides, closing rule kept, steps sized by the motion ratio)
VARIANTS = (("defaults (max_multiplier_step 0.02)", {}, True, True),
            ("defaults, growth not capped", {}, True, False),
            ("max_multiplier_step 0.1", {"max_multiplier_step": 0.1}, True, True),
            ("max_multiplier_step 1", {"max_multiplier_step": 1.0}, True, True),
            ("max_multiplier_step 1, no closing rule", {"max_multiplier_step": 1.0}, False,
             True))


def _uncapped(h: float, ratio: float) -> float:
    """No cap from the motion ratio on the growth of an accepted step."""
    return float("inf")


def yaml_case(path: Path) -> Callable[[dict[str, Any]], Any]:
    def run(analysis: dict[str, Any]) -> Any:
        over = {"output.plots": False, "output.progress": False,
                **{f"analysis.{k}": v for k, v in analysis.items()}}
        return nsm.run(nsm.load_case(path, over)).run_result
    return run


def chain_200(analysis: dict[str, Any]) -> Any:
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    pb = NDofImpactProblem({"chain": {"dofs": 200, "mass": 1 / 200, "stiffness": 200.0},
                            "gap": 1.0})
    return nsm.continuation(pb, {"mode": 1}, parameter="omega", min=0.5, max=3.0,
                            max_points=3000, analysis={"stability": True,
                                                       "bifurcations": True,
                                                       **analysis}).run_result


def crossings(run: Any) -> list[tuple[int, str, float]]:
    ip = run.problem.parameter_index
    return [(b.id, e.kind, float(e.point.y[ip])) for b in run.branches for e in b.events
            if e.kind in CROSSINGS]


def measure(name: str, case: Callable[[dict[str, Any]], Any], warm: bool = True) -> None:
    """One table; ``warm``: run the defaults once untimed first (imports, first calls)."""
    print(f"\n{name}")
    if warm:
        case({})
    print(f"  {'step control':42s} {'points':>7s} {'attempts':>9s} {'time [s]':>9s} "
          f"{'crossings':>10s} {'found':>6s} {'hidden':>7s}")
    ref: list[tuple[int, str, float]] | None = None
    engine = palc.ContinuationEngine
    predict_correct = engine._predict_correct
    attempts = [0]

    def counted(self: Any, *args: Any) -> Any:
        attempts[0] += 1
        return predict_correct(self, *args)

    for label, analysis, closing, sized in VARIANTS:
        saved, scaled = step_control.krein_closing, step_control._motion_capped_step
        if not closing:
            step_control.krein_closing = lambda *a, **k: False
        if not sized:
            step_control._motion_capped_step = _uncapped
        engine._predict_correct = counted  # type: ignore[method-assign]
        attempts[0] = 0
        try:
            t0 = time.perf_counter()
            run = case(analysis)
            dt = time.perf_counter() - t0
        finally:
            step_control.krein_closing, step_control._motion_capped_step = saved, scaled
            engine._predict_correct = predict_correct  # type: ignore[method-assign]
        got = crossings(run)
        if ref is None:
            ref = got
        by_key = collections.defaultdict(list)
        for b, k, p in got:
            by_key[(b, k)].append(p)
        found = sum(any(abs(p - q) <= 1e-9 for q in by_key[(b, k)]) for b, k, p in ref)
        hidden = sum(bool(e.data.get("hidden_in_step")) for b in run.branches
                     for e in b.events if e.kind in CROSSINGS)
        print(f"  {label:42s} {run.timings['n_points']:7d} {attempts[0]:9d} {dt:9.2f} "
              f"{len(got):10d} {found:>3d}/{len(ref):<3d} {hidden:6d}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n200", action="store_true", help="also the 200-dof branch (~2 min)")
    a = ap.parse_args()
    measure("default case (5-dof chain, branch 1)",
            yaml_case(ROOT / "yaml_cases" / "ndof_default.yaml"))
    measure("Fig. 3.2 (23 branches)", yaml_case(ROOT / "yaml_cases" / "ndof_fig3_2_fep.yaml"))
    if a.n200:
        measure("200-dof chain, mode 1", chain_200, warm=False)


if __name__ == "__main__":
    main()
