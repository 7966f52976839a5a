"""The bar's lattice scan (Fig. 12) as Dask tasks: speed-up, per-task costs, and an
estimate of the scan at N = 1000 cells on a 64-core cluster.

Prints
1. ``yaml_cases/wfem_fig12_fep.yaml`` (``--cells``, default the case's N = 200) serially and with
   ``workers=2`` (a local cluster started for the run, as ``--workers 2``), the speed-up, and a
   check that the outputs are identical (report without its timings, every branch's CSV);
2. the cost of each piece of the split scan (a range of periods, one task) and the parts of
   the distributed run that stay serial: starting the cluster, adopting the pieces' results
   (the nodes they solved) on the master, building the seeds from them, and continuing the
   branches (on the master: most of a scan's seeds lie on an earlier branch and are skipped);
3. the estimate at ``--target-cells`` (default 1000) on ``--cores`` (default 64): the scan's work
   from the measured cost of a few of its pieces at that N (run here, one core, a sample spread
   over the window) times the number of pieces, the serial part scaled from item 2 by the
   number of nodes (adopting) and of branch points (continuing), then Amdahl's law and the
   bound of the longest piece.

Run: ``python benchmarks/bench_distributed_lattice.py [--cells 200] [--workers 2]
[--target-cells 1000] [--cores 64] [--samples 6]`` (~2.5 min at the defaults on 2 cores).
Needs ``pip install ".[dask]"``. The scan is split only if the problem implements the seed
pieces of :class:`nsm_continuation.core.lattice.LatticeProblem`; otherwise the run is serial in
both cases and item 3 is skipped.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation.output.files import branch_rows, build_report  # noqa: E402
from nsm_continuation.runs.execution import PIECES_PER_WORKER  # noqa: E402
from nsm_continuation.runs.setup import rebuild_case  # noqa: E402

CASE = ROOT / "yaml_cases" / "wfem_fig12_fep.yaml"
#: adopting a piece's nodes on the master overlaps with the later pieces on the workers;
#: counted as serial here (an upper bound)
ADOPT = "adopt the pieces' nodes (master, overlapped)"


def outputs(res: Any) -> tuple[str, list[str]]:
    """report.json without its timings and the recorded execution block (where it ran, not
    what it computed), and each branch's CSV, as written."""
    rr = res.run_result
    rep = build_report(rr, "run")
    rep.pop("timings", None)
    rep["case"]["input"].pop("execution", None)
    csvs = []
    for br in rr.branches:
        cols, rows = branch_rows(br, rr.problem.variables, rr.problem.presentation.csv_head)
        fh = io.StringIO()
        w = csv.writer(fh)
        w.writerow(cols)
        w.writerows(rows)
        csvs.append(fh.getvalue())
    return json.dumps(rep, default=str), csvs


def timed(case: Any, **kw: Any) -> tuple[float, Any]:
    t0 = time.perf_counter()
    res = nsm.run(case, **kw)
    return time.perf_counter() - t0, res


def stats(xs: list[float]) -> str:
    a = np.asarray(xs, dtype=float)
    return (f"n = {a.size}, min {a.min():.2f} s, median {np.median(a):.2f} s, "
            f"max {a.max():.2f} s, sum {a.sum():.1f} s (max / mean {a.max() / a.mean():.2f})")


def sample_pieces(cells: int, count: int, samples: int) -> tuple[list[float], int, float]:
    """The wall time of ``samples`` pieces (spread over the window) of the Fig. 12 scan at ``cells``
    split into ``count`` pieces, run here one after the other; the number of pieces, and the
    number of nodes of the whole scan (those of the samples times pieces / samples)."""
    raw = nsm.load_case(CASE, {"parameters.cells": cells}).model_dump(mode="json")
    case, problem, window, algorithm = rebuild_case(raw)
    pieces = algorithm.seed_pieces(case.start, window, count)
    # the middle of each of ``samples`` equal stretches (the ends of the window are atypical:
    # the last period has a handful of nodes)
    picks = sorted({int((k + 0.5) * len(pieces) / samples) for k in range(samples)})
    times = []
    for i in picks:
        t0 = time.perf_counter()
        algorithm.seed_piece(case.start, window, pieces[i])
        times.append(time.perf_counter() - t0)
    nodes = problem.presentation.report_extras([]).get("lattice_nodes_evaluated", 0)
    return times, len(pieces), nodes * len(pieces) / len(picks)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=None, help="N of the measured scan (case: 200)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--target-cells", type=int, default=1000)
    ap.add_argument("--cores", type=int, default=64)
    ap.add_argument("--samples", type=int, default=6, help="pieces run at --target-cells")
    a = ap.parse_args()
    over: dict[str, Any] = {"output.plots": False, "output.progress": False}
    if a.cells:
        over["parameters.cells"] = a.cells
    case = nsm.load_case(CASE, over)
    t_ser, r_ser = timed(case)
    t_dist, r_dist = timed(case, workers=a.workers)
    same = outputs(r_ser) == outputs(r_dist)
    ts, td = r_ser.run_result.timings, r_dist.run_result.timings
    nb, ns = len(r_ser.run_result.branches), len(r_ser.run_result.skipped)
    N = r_ser.run_result.problem.model.N
    extras = r_ser.run_result.problem.presentation.report_extras(r_ser.run_result.branches)
    n_nodes = int(extras.get("lattice_nodes_evaluated", 0))
    print(f"1. Fig. 12 scan ({CASE.relative_to(ROOT)}, N = {N}, plots off)")
    print(f"   {nb} branches ({ns} seeds skipped), {ts['n_points']} points, {n_nodes} lattice "
          "nodes solved")
    print(f"   serial                         {t_ser:7.2f} s  (scan {ts['seeds_s']:.2f} s, "
          f"branches {sum(ts['per_branch_s']):.2f} s)")
    print(f"   workers={a.workers} (cluster started)   {t_dist:7.2f} s  speed-up "
          f"{t_ser / t_dist:4.2f}x  identical outputs: {same}")
    if "seed_pieces_s" not in td:
        print("   the scan was not split: the problem does not implement the seed pieces of "
              "LatticeProblem (nsm_continuation/core/lattice.py); no estimate")
        return
    per = td["seed_pieces_s"]
    close = (td["seed_search_distributed_s"] - td["seed_cluster_start_s"]
             - td["seed_pieces_wall_s"])
    serial_parts = {
        "cluster start": td["seed_cluster_start_s"],
        ADOPT: td["seed_adopt_s"],
        "seeds from the adopted nodes (master)": td["seeds_s"] - td["seed_search_distributed_s"],
        "branches (master)": sum(td["per_branch_s"]),
        "cluster close": close,
        "case, preflight (master)": t_dist - td["seeds_s"] - sum(td["per_branch_s"]),
    }
    print("2. per-task costs and serial parts of the distributed run")
    print(f"   pieces of the scan (one task each, {PIECES_PER_WORKER} per worker): {stats(per)}")
    print(f"   pieces' wall time on {a.workers} workers {td['seed_pieces_wall_s']:.2f} s: "
          f"{sum(per) / td['seed_pieces_wall_s']:.2f} pieces busy on average; their sum is "
          f"{sum(per) / ts['seeds_s']:.2f}x the serial scan")
    for k, v in serial_parts.items():
        print(f"   {k:45s} {v:6.2f} s")
    s_here = sum(serial_parts.values()) - serial_parts["cluster start"] - close
    frac = s_here / t_ser
    print(f"   serial fraction (without starting and closing the cluster) {frac:.3f}: Amdahl bound "
          f"{1 / frac:.0f}x; here {a.workers} workers -> "
          f"{1 / (frac + (1 - frac) / a.workers):.2f}x")

    # 3. the estimate at target N on target cores
    Nt, P = a.target_cells, a.cores
    count = PIECES_PER_WORKER * P
    t0 = time.perf_counter()
    sample, n_pieces, nodes_t = sample_pieces(Nt, count, a.samples)
    t_sample = time.perf_counter() - t0
    work = float(np.mean(sample)) * n_pieces
    scale_nodes = nodes_t / max(n_nodes, 1)
    points_ratio = Nt / N  # branch points ~ periods in the window ~ N
    node_cost_ratio = (work / max(nodes_t, 1)) / (ts["seeds_s"] / max(n_nodes, 1))
    serial_t = ((serial_parts[ADOPT]
                 + serial_parts["seeds from the adopted nodes (master)"]) * scale_nodes
                + serial_parts["branches (master)"] * points_ratio * node_cost_ratio
                + serial_parts["case, preflight (master)"])
    longest = float(np.max(sample))
    t_p = serial_t + max(work / P, longest)  # a task's own overhead: milliseconds
    print(f"3. estimate: the Fig. 12 scan at N = {Nt} on {P} cores ({count} pieces)")
    print(f"   measured here ({t_sample:.0f} s): {len(sample)} of its {n_pieces} pieces cost "
          f"{', '.join(f'{x:.2f}' for x in sample)} s on one core; ~{nodes_t:.2e} nodes "
          f"({scale_nodes:.0f}x N = {N}), {node_cost_ratio:.2f}x the cost per node")
    print(f"   scan work {work:7.0f} s = {work / 3600:.2f} core-hours (serial run: about "
          f"{(work + serial_t) / 60:.0f} min)")
    print(f"   serial part {serial_t:5.0f} s (adopting and seeding x{scale_nodes:.0f}, "
          f"branches x{points_ratio * node_cost_ratio:.1f}; the pieces ran in this process's "
          "main thread: a worker adds ~5 %)")
    print(f"   on {P} cores: {serial_t:.0f} + max({work:.0f} / {P}, longest piece "
          f"{longest:.1f}) = {t_p:.0f} s, plus the cluster start (~2 s locally, seconds to "
          f"minutes for a batch cluster); speed-up {(work + serial_t) / t_p:.0f}x "
          f"(Amdahl with serial fraction {serial_t / (work + serial_t):.3f})")
    # the master keeps a scanned period's nodes without orbits as one int32 each (the sorted m
    # of WfemBarProblem._scanned_empty); the workers keep their pieces' nodes (~300 B each)
    mp = r_dist.run_result.problem
    implied = sum(int(v.size) for v in mp._scanned_empty.values())
    listed = len(mp._cache)
    print(f"   memory here (N = {N}): the master lists {listed} nodes one by one and "
          f"{implied} implied by their periods (4 B each); each worker holds the nodes of its "
          f"pieces: ~{n_nodes * 300 / a.workers / 1e9:.2f} GB at ~300 B per node")
    print(f"   memory at N = {Nt} on {P} cores: ~{nodes_t * 300 / P / 1e9:.2f} GB per worker, "
          f"~{nodes_t * 4 / 1e9:.2f} GB of implied nodes on the master")


if __name__ == "__main__":
    main()
