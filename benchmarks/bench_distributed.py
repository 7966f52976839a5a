"""Branches as Dask tasks: speed-up and overhead, one run, same machine.

Prints the wall time of
1. ``yaml_cases/ndof_fig3_2_fep.yaml`` (Fig. 3.2, one branch per pole) serially, on a local
   cluster of 2 worker processes started for the run (``--workers 2``), and on a cluster
   already running (``--scheduler``), with a check that the branches and events are identical;
2. the bundled default case (one branch): the overhead of the distributed path, with a
   cluster started for the run and with one already running;
3. per-task costs, from which it estimates a 100-dof FEP on 64 cores.

Run: ``python benchmarks/bench_distributed.py`` (2 cores, Python 3.11; the machine in
``/work/.library/env``). The lattice scan of the bar (Fig. 12), split into pieces of its seed
search: ``benchmarks/bench_distributed_lattice.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nsm_continuation as nsm  # noqa: E402


def timed(case: object, **kw: object) -> tuple[float, object]:
    t0 = time.perf_counter()
    res = nsm.run(case, **kw)
    return time.perf_counter() - t0, res


def same(a: object, b: object) -> bool:
    ba, bb = a.run_result.branches, b.run_result.branches
    if [(x.label, x.n_points) for x in ba] != [(x.label, x.n_points) for x in bb]:
        return False
    return all(np.array_equal(np.array([p.y for p in x.points]), np.array([p.y for p in y.points]))
               and [e.kind for e in x.events] == [e.kind for e in y.events]
               for x, y in zip(ba, bb, strict=True))


def main() -> None:
    from nsm_continuation.runs.execution import Execution, start_client

    fep = ROOT / "yaml_cases" / "ndof_fig3_2_fep.yaml"
    default = ROOT / "yaml_cases" / "ndof_default.yaml"
    over = {"output.plots": False}
    t_ser, r_ser = timed(nsm.load_case(fep, over))
    t_loc, r_loc = timed(nsm.load_case(fep, over), workers=2)
    # a running cluster set up as the README recommends (the local cluster of --workers:
    # one thread, no MALLOC_TRIM_THRESHOLD_, no profiler, 1 s tick)
    client, cluster = start_client(Execution(workers=2))
    try:
        client.wait_for_workers(2)
        addr = cluster.scheduler_address
        timed(nsm.load_case(default, over), scheduler=addr)  # warm the workers' imports
        t_run, r_run = timed(nsm.load_case(fep, over), scheduler=addr)
        t_run2, _ = timed(nsm.load_case(fep, over), scheduler=addr)  # the case's problem cached
        t_def_ser, _ = timed(nsm.load_case(default, over))
        t_def_run, _ = timed(nsm.load_case(default, over), scheduler=addr)
    finally:
        client.close()
        cluster.close()
    t_def_loc, _ = timed(nsm.load_case(default, over), workers=2)
    per = r_ser.run_result.timings["per_branch_s"]
    nb = len(r_ser.run_result.branches)
    print("1. Fig. 3.2 FEP (yaml_cases/ndof_fig3_2_fep.yaml, plots off)")
    print(f"   {nb} branches, {sum(b.n_points for b in r_ser.run_result.branches)} points")
    print(f"   serial                       {t_ser:6.2f} s")
    print(f"   --workers 2 (cluster started) {t_loc:6.2f} s  speed-up {t_ser / t_loc:4.2f}x  "
          f"identical: {same(r_ser, r_loc)}")
    print(f"   --scheduler (cluster running) {t_run:6.2f} s  speed-up {t_ser / t_run:4.2f}x  "
          f"identical: {same(r_ser, r_run)}")
    print(f"   the same case again            {t_run2:6.2f} s  speed-up {t_ser / t_run2:4.2f}x  "
          "(the workers keep the case's problem)")
    print(f"   longest branch {max(per):.2f} s of {sum(per):.2f} s: the bound on the speed-up "
          f"is {sum(per) / max(per):.1f}x with enough workers")
    print("2. default case (one branch)")
    print(f"   serial {t_def_ser:.2f} s; --scheduler {t_def_run:.2f} s (overhead "
          f"{t_def_run - t_def_ser:+.2f} s); --workers 2 {t_def_loc:.2f} s (overhead "
          f"{t_def_loc - t_def_ser:+.2f} s: a single branch starts no local cluster)")
    mean = float(np.mean(per))
    print("3. estimate: a 100-dof FEP on 64 cores")
    print(f"   measured here: {mean:.3f} s per 5-dof branch on average; a 100-dof point costs "
          "about (100/5)^2.4 = 1.3e3 times a 5-dof point (benchmarks/bench_scaling.py slope)")
    n_branches = 100 * 10  # 100 modes x subharmonics up to 10
    t_branch = mean * (100 / 5) ** 2.4
    print(f"   {n_branches} branches x {t_branch:.0f} s = {n_branches * t_branch / 3600:.0f} "
          f"core-hours; on 64 cores {n_branches * t_branch / 64 / 3600:.1f} h if the longest "
          "branch is shorter than that")


if __name__ == "__main__":
    main()
