"""Would the seeds' branches of a lattice scan pay as speculative Dask tasks?

The bar's Fig. 12 scan seeds one branch per physical orbit, continued in seed order; a seed
lying on an earlier branch is skipped, so the branches are not independent. Continued ``W``
uncovered seeds at a time and merged with the serial rule (``merge_in_seed_order``), the
outputs would be the serial run's, but a seed covered by a branch of its own window is
computed for nothing. This script continues the seeds serially, keeps each accepted branch's
visited lattice keys, and replays windows of ``W`` = 2, 3, 4 on that record: rounds, branches
computed, wasted share; with the serial time per branch.

Run: ``python benchmarks/bench_seed_speculation.py [--cells 300 500]`` (2 cores; the scan
itself takes ~4 s at N = 300 and ~25 s at N = 500). One run on that machine: N = 300, 152
branches of 688 seeds, W = 2 wastes 18 %; N = 500, 296 of 1418, W = 2 wastes 12 %; ~11 ms per
branch at N = 500, ~30 ms at N = 1000.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import nsm_continuation as nsm
from nsm_continuation.runs.setup import rebuild_case

CASE = Path(__file__).resolve().parents[1] / "yaml_cases" / "wfem_fig12_fep.yaml"


def speculation(cells: int, windows: tuple[int, ...] = (2, 3, 4)) -> None:
    case = nsm.load_case(CASE, {"output.plots": False, "output.progress": False,
                                "parameters.cells": cells})
    c, problem, window, algorithm = rebuild_case(case.model_dump(mode="json"))
    seeds = algorithm.starts(c.start, window)
    keys_of: dict[int, set] = {}
    branches = []
    t0 = time.perf_counter()
    for i, seed in enumerate(seeds):
        if algorithm.covered(seed, branches):
            continue
        branches.append(algorithm.run_branch(seed, len(branches)))
        keys_of[i] = set(algorithm.engine.last_keys)
    dt = time.perf_counter() - t0
    print(f"N = {cells}: {len(seeds)} seeds, {len(branches)} branches, {dt:.2f} s serially "
          f"({1e3 * dt / max(len(branches), 1):.1f} ms per branch)")
    key = [problem.lattice_key(s.solution) for s in seeds]
    for W in windows:
        visited: set = set()
        i = rounds = computed = 0
        while i < len(seeds):
            batch = []
            while i < len(seeds) and len(batch) < W:
                if key[i] not in visited:
                    batch.append(i)
                i += 1
            if not batch:
                break
            rounds += 1
            computed += len(batch)
            for j in batch:  # merged in seed order with the serial rule
                if key[j] not in visited:
                    visited |= keys_of[j]
        waste = computed - len(branches)
        print(f"   W = {W}: {rounds} rounds, {computed} branches computed, {waste} for "
              f"nothing ({waste / max(computed, 1):.0%})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, nargs="+", default=[300, 500])
    for cells in ap.parse_args().cells:
        speculation(cells)


if __name__ == "__main__":
    main()
