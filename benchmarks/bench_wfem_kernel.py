"""Kernel of ``S_T = A_c^p A_f^m - I`` (Yoong, Thorin, Legrand 2017, eq. 12): structured vs dense.

For every lattice node (m, p) the paper's solution procedure (sec. 5.2) needs ``h = dim ker S_T``
and a kernel basis. Two ways:

* ``structured``: :func:`problems.bar.wfem_operators.phase_operator` writes ``A_c^p A_f^m`` as a
  signed rotation of the ring of 2N characteristic slots (dt = dx/c); its kernel is read from the
  cycles of the rotation (one basis vector per cycle with sign product +1): ``h`` in O(N)
  (``kernel_dimension``, the column compared with the dense method); the orthonormal basis
  (``kernel()``) is timed separately: it is stored as a dense 2N x h array, O(N h), which
  dominates for nodes with large h (e.g. h = N/2 at ``M = 3.5 N`` with ``gcd(M, 2N) = N/2``);
* ``dense``: the 2N x 2N matrices of Appendix A.7
  (:func:`problems.bar.wfem_operators.dense_operator`, corner entries as derived from
  (A.18)-(A.19)), ``numpy.linalg.matrix_power`` for ``A_c^p`` and ``A_f^m`` (O(N^3 log M)), then
  ``h = 2N - matrix_rank(S_T)`` (an SVD, O(N^3)).

Nodes: for each N, three nodes with ``M = m + p`` near ``3.5 N``: two on the main backbone of mode 1
(``m = 2M - 4N``, one with ``h = 1``, one with ``gcd(M, 2N) > 1`` and ``h > 1``) and one off it
(``m = M/2``). ``h`` of both methods is compared wherever both run.

The dense method is run for N in increasing order while the predicted cumulative dense time stays
within ``--dense-budget`` seconds (default 60; prediction: the last measured time per node scaled
by N^3); above, its time per node is extrapolated by N^3 from the largest measured N and marked as
such in the table and on the chart.

Writes ``benchmarks/out/wfem_kernel_structured_vs_dense.png`` (log-log time per node vs N).
OpenBLAS is pinned to one thread (see benchmarks/README.md).

    python benchmarks/bench_wfem_kernel.py [--sizes 100 200 500 1000 2000 5000] [--dense-budget 60]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from math import gcd  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from nsm_continuation.problems.bar.wfem_operators import (  # noqa: E402
    dense_operator,
    pattern_from_counts,
    phase_operator,
)

OUT = Path(__file__).resolve().parent / "out"


def nodes_for(N: int) -> list[tuple[int, int]]:
    """Three (m, p) nodes near M = 3.5 N (module docstring)."""
    M0 = int(3.5 * N)
    M1 = next(M for M in range(M0, 4 * N) if gcd(M, 2 * N) == 1)  # h = 1 on the backbone
    M2 = next(M for M in range(M0, 4 * N) if gcd(M, 2 * N) > 2)   # split cycles: h > 1
    M3 = M0 + 1
    return [(2 * M1 - 4 * N, M1 - (2 * M1 - 4 * N)), (2 * M2 - 4 * N, M2 - (2 * M2 - 4 * N)),
            (M3 // 2, M3 - M3 // 2)]


def structured(N: int, node: tuple[int, int]) -> int:
    """``h`` from the cycles of the signed rotation (O(N))."""
    return phase_operator(N, pattern_from_counts(*node)).kernel_dimension()


def structured_basis(N: int, node: tuple[int, int]) -> np.ndarray:
    """An orthonormal kernel basis (2N x h, dense storage: O(N h))."""
    return phase_operator(N, pattern_from_counts(*node)).kernel()


def dense(N: int, node: tuple[int, int], Af: np.ndarray, Ac: np.ndarray) -> int:
    m, p = node
    S = np.linalg.matrix_power(Ac, p) @ np.linalg.matrix_power(Af, m) - np.eye(2 * N)
    return 2 * N - int(np.linalg.matrix_rank(S))


def best_time(fun, min_time: float = 0.2, rounds: int = 3) -> tuple[float, object]:
    """Best over ``rounds`` of the mean time per call, each round lasting ~``min_time`` s."""
    t0 = time.perf_counter()
    out = fun()
    first = time.perf_counter() - t0
    reps = max(1, int(min_time / max(first, 1e-9)))
    best = first
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(reps):
            fun()
        best = min(best, (time.perf_counter() - t0) / reps)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 200, 500, 1000, 2000, 5000])
    ap.add_argument("--dense-budget", type=float, default=60.0,
                    help="cumulative seconds of dense computation allowed (then extrapolate)")
    ap.add_argument("--out", type=Path, default=OUT / "wfem_kernel_structured_vs_dense.png")
    args = ap.parse_args()

    rows = []
    dense_total = 0.0
    last_dense: tuple[int, float] | None = None
    for N in sorted(args.sizes):
        nodes = nodes_for(N)
        t_s, h_s, t_b = [], [], []
        for node in nodes:
            t, h = best_time(lambda node=node, N=N: structured(N, node))
            tb, K = best_time(lambda node=node, N=N: structured_basis(N, node))
            t_s.append(t)
            t_b.append(tb)
            h_s.append(h)
            # the kernel vectors are fixed points of the operator
            op = phase_operator(N, pattern_from_counts(*node))
            assert K.shape[1] == h
            assert all(np.allclose(op.apply(K[:, j]), K[:, j]) for j in range(h))
        predicted = (last_dense[1] * (N / last_dense[0]) ** 3 * len(nodes)
                     if last_dense else 0.0)
        if dense_total + predicted <= args.dense_budget:
            Z = 1.0
            t0 = time.perf_counter()
            Af, Ac = dense_operator(N, Z, "free"), dense_operator(N, Z, "contact")
            t_build = time.perf_counter() - t0
            t_d, h_d = [], []
            for node in nodes:
                t0 = time.perf_counter()
                h_d.append(dense(N, node, Af, Ac))
                t_d.append(time.perf_counter() - t0 + t_build / len(nodes))
            dense_total += sum(t_d)
            last_dense = (N, float(np.mean(t_d)))
            agree = h_d == h_s
            assert agree, f"N = {N}: structured h = {h_s}, dense h = {h_d}"
            rows.append(dict(N=N, nodes=nodes, h=h_s, t_struct=float(np.mean(t_s)),
                             t_basis=float(np.mean(t_b)), t_dense=float(np.mean(t_d)),
                             measured=True, agree=agree))
        else:
            t_ext = last_dense[1] * (N / last_dense[0]) ** 3 if last_dense else float("nan")
            rows.append(dict(N=N, nodes=nodes, h=h_s, t_struct=float(np.mean(t_s)),
                             t_basis=float(np.mean(t_b)), t_dense=t_ext, measured=False,
                             agree=None))

    print("Kernel of A_c^p A_f^m - I per lattice node (mean over the nodes), "
          "OPENBLAS_NUM_THREADS=" + os.environ.get("OPENBLAS_NUM_THREADS", "?"))
    print(f"{'N':>6} {'nodes (m, p)':>40} {'h':>14} {'struct. h [s]':>14} "
          f"{'struct. basis [s]':>17} {'dense h [s]':>12} {'dense/struct':>12}  h agrees")
    for r in rows:
        tag = "" if r["measured"] else " (extrap. N^3)"
        nodes = ", ".join(f"({m},{p})" for m, p in r["nodes"])
        print(f"{r['N']:>6} {nodes:>40} {str(r['h']):>14} {r['t_struct']:>14.3e} "
              f"{r['t_basis']:>17.3e} {r['t_dense']:>12.3e} "
              f"{r['t_dense'] / r['t_struct']:>12.3g}  "
              f"{'yes' if r['agree'] else ('-' if r['agree'] is None else 'NO')}{tag}")
    print(f"dense computation total: {dense_total:.1f} s (budget {args.dense_budget:.0f} s)")

    Ns = np.array([r["N"] for r in rows], dtype=float)
    ts = np.array([r["t_struct"] for r in rows])
    td = np.array([r["t_dense"] for r in rows])
    meas = np.array([r["measured"] for r in rows])
    fig, ax = plt.subplots(figsize=(7.5, 5))
    tb = np.array([r["t_basis"] for r in rows])
    ax.loglog(Ns, ts, "o-", color="tab:blue", label="structured h (signed rotation, cycles)")
    ax.loglog(Ns, tb, "o:", color="tab:blue", mfc="none",
              label="structured h + kernel basis (dense 2N x h array)")
    ax.loglog(Ns[meas], td[meas], "s-", color="tab:red",
              label="dense h (matrix powers + SVD rank)")
    if (~meas).any():
        k = np.nonzero(meas)[0][-1]
        xs = np.concatenate([[Ns[k]], Ns[~meas]])
        ys = np.concatenate([[td[k]], td[~meas]])
        ax.loglog(xs, ys, "s--", color="tab:red", mfc="none", label="dense, extrapolated ~N^3")
    ref = Ns / Ns[0]
    ax.loglog(Ns, ts[0] * ref, ":", color="0.5", lw=0.8, label="~N")
    ax.loglog(Ns, td[0] * ref**3, "-.", color="0.5", lw=0.8, label="~N^3")
    ax.set_xlabel("cells N (state size 2N)")
    ax.set_ylabel("time per (m, p) node [s]")
    ax.set_title("ker(A_c^p A_f^m - I): structured O(N) vs dense")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=130)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
