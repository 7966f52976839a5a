"""The bar's lattice scan (Fig. 12 of Yoong, Thorin, Legrand 2017) with and without its
structure (target: Fig. 12 at N = 1000 in < 10 min on this machine).

The scan solves every one-contact-phase node ``(m, M - m)`` with ``1 <= h <= 8`` of every
period ``M`` in the window. Three uses of the structure, each switched off in the "plain" run:

* the kernel dimensions of a period in closed form, ``h = g - rho`` or ``rho``
  (:func:`problems.bar.wfem_operators.kernel_dimensions_at_period`; plain: the O(M N) sweep of
  every slot's sign);
* the batch COND2 screen (:func:`problems.bar.wfem_lattice.scan_screen`; plain: every node
  solved);
* the per-cycle sign test of ``h > q`` nodes
  (:func:`problems.bar.wfem_lattice.contact_sign_conflict`; plain: all ``2^(h-1)`` sign
  combinations formed).

Both runs must give the same orbits, counters and filter reasons (checked here at every N run
both ways). The plain scan at N = 1000 is estimated at ~38 min (2289 s): it is run only
with ``--plain-1000``.

    python benchmarks/bench_wfem_scan.py [--cells 200 1000] [--plain-1000]

BLAS pinned to one thread (benchmarks/README.md).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
from collections.abc import Iterator  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from math import gcd  # noqa: E402
from typing import Any  # noqa: E402

import nsm_continuation.problems.bar.wfem_lattice as wfem_lattice  # noqa: E402
import nsm_continuation.problems.bar.wfem_nodes as wfem_nodes  # noqa: E402
import numpy as np  # noqa: E402
from nsm_continuation.problems.bar.wfem_bar import WfemBarProblem  # noqa: E402
from nsm_continuation.problems.bar.wfem_operators import kernel_dimensions_by_sweep  # noqa: E402

WINDOW = (1.0, 4.0)  # [omega_1, Omega_2] of Fig. 12


@contextmanager
def plain() -> Iterator[None]:
    """The scan without its structure: kernel dimensions by sweep, no screen, no sign test."""
    saved = (wfem_nodes.kernel_dimensions_at_period, wfem_nodes.scan_screen,
             wfem_lattice.contact_sign_conflict)
    wfem_nodes.kernel_dimensions_at_period = kernel_dimensions_by_sweep
    wfem_nodes.scan_screen = lambda N, M, ms: np.ones(np.asarray(ms).size, dtype=bool)
    wfem_lattice.contact_sign_conflict = lambda Js: False
    try:
        yield
    finally:
        (wfem_nodes.kernel_dimensions_at_period, wfem_nodes.scan_screen,
         wfem_lattice.contact_sign_conflict) = saved


def scan(N: int) -> tuple[float, WfemBarProblem, list[Any]]:
    pb = WfemBarProblem({"E": 1.0, "rho": 1.0, "L": 1.0, "cells": N, "gap": 1e-3})
    t0 = time.perf_counter()
    found = pb.scan_window(WINDOW)
    return time.perf_counter() - t0, pb, found


def same(a: tuple[float, WfemBarProblem, list[Any]],
         b: tuple[float, WfemBarProblem, list[Any]]) -> bool:
    _, pa, fa = a
    _, pb, fb = b
    return (len(fa) == len(fb)
            and all(x.counts == y.counts and np.array_equal(x.w0, y.w0)
                    for x, y in zip(fa, fb, strict=True))
            and pa.node_evaluations == pb.node_evaluations
            and pa.filter_counts == pb.filter_counts and list(pa._cache) == list(pb._cache))


def node_census(N: int) -> tuple[int, int]:
    """Scanned nodes (1 <= h <= 8) and all nodes of the window's periods."""
    lo, hi = int(np.ceil(4 * N / WINDOW[1])), int(np.floor(4 * N / WINDOW[0]))
    scanned = total = 0
    for M in range(max(lo, 2), hi + 1):
        s = M % (2 * N)
        g = gcd(s, 2 * N) if s else 2 * N
        q, rho = np.divmod(np.arange(1, M), g)
        h = np.where(q % 2 == 0, g - rho, rho)
        scanned += int(np.sum((h >= 1) & (h <= 8)))
        total += M - 1
    return scanned, total


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cells", type=int, nargs="+", default=[200, 1000])
    ap.add_argument("--plain-1000", action="store_true",
                    help="also run the plain scan at N >= 1000 (~38 min estimated at N = 1000)")
    args = ap.parse_args(argv)
    print("| N | scanned nodes | physical orbits | structured scan | plain scan | ratio | "
          "same result |")
    print("|---:|---:|---:|---:|---:|---:|---|")
    for N in args.cells:
        scanned, _ = node_census(N)
        fast = scan(N)
        if N < 1000 or args.plain_1000:
            with plain():
                slow = scan(N)
            plain_s, ratio, ok = (f"{slow[0]:.1f} s", f"{slow[0] / fast[0]:.1f}x",
                                  "yes" if same(fast, slow) else "NO")
        else:
            plain_s, ratio, ok = "(not run)", "-", "-"
        print(f"| {N} | {scanned} | {len(fast[2])} | {fast[0]:.1f} s | {plain_s} | {ratio} | "
              f"{ok} |", flush=True)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
    print(f"\npeak RSS {rss:.2f} GB (the node cache: every scanned node is kept)")


if __name__ == "__main__":
    main()
