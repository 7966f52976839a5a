"""Sparse sensitivity products of the Runge-Kutta steps of large systems.

The simulator chains the sensitivities of every accepted Runge-Kutta step, ``J <- J_step J``
(the chain (40) of flows and saltation matrices, :mod:`.simulate`), ``J`` dense of size ``n``
(the state and the freed parameters). A dense product costs ``n^3`` operations per step: for a
chain of ``N`` masses (``n = 2 N + 2``) it is the part of a simulation that grows fastest with
``N`` (``benchmarks/bench_nonlinear_chain.py``). But the Jacobian of one step of a system with
local coupling is sparse: each stage of the explicit Runge-Kutta step couples a mass to its
neighbours only, so ``J_step`` of a chain is banded, its bandwidth about the number of stages
(twelve for DOP853), plus the columns of the clock and the freed parameters. Its structural
nonzeros are known from the compiled CasADi expression (the sparsity of the step Function's
output, which is the exact Jacobian ``ca.jacobian(Y_new, Y)``), so the product is formed as a
sparse times dense product, ``nnz(J_step) n`` operations.

The values are those of the dense product up to the order of the sums (rounding): the rule
keeps the dense product below :data:`MIN_DIMENSION` state components (every bundled case), and
for systems whose step Jacobian is more than :data:`MAX_DENSITY` full (nothing to gain).
``SimOptions.sparse_products`` forces either.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.sparse as sp

#: the sparse product is used from this many components of the (extended) state on: measured
#: against numpy's dense product (OpenBLAS, one thread) for banded step Jacobians with 24
#: nonzeros per column (the cubic chain's DOP853 step), the sparse one is 4x slower at 82
#: components, even at about 200 and 1.6-1.7x faster at 300-400 (a compressed-column times
#: dense product has a fixed cost of tens of microseconds and no blocking)
MIN_DIMENSION = 250
#: and when the step Jacobian has at most this fraction of nonzeros
MAX_DENSITY = 0.5


class SparseStep:
    """The structure of the Jacobian block of one step Function's flat output
    (``vec(J_step)``, column-major, after ``offset`` other entries): :meth:`chain` forms
    ``J_step J`` from the flat output's dense ``J_step`` by a sparse product."""

    def __init__(self, f: ca.Function, m: int, offset: int) -> None:
        sparsity = f.sparsity_out(0)
        rows = np.asarray(sparsity.row(), dtype=np.int64)
        # r + m c, column-major order (the error estimates' Jacobians that follow it excluded)
        pos = rows[(rows >= offset) & (rows < offset + m * m)] - offset
        self.m = m
        #: positions of the nonzeros in ``vec(J_step)``, in compressed-column order
        self.positions = pos
        self.indices = (pos % m).astype(np.int32)
        cols = pos // m
        self.indptr = np.searchsorted(cols, np.arange(m + 1)).astype(np.int32)
        self.density = pos.size / float(m * m)

    def chain(self, Jstep: np.ndarray, J: np.ndarray) -> np.ndarray:
        """``J_step J`` with ``J_step`` (``m x m``, dense, zero off the structure) as a
        compressed-column matrix of its structural nonzeros."""
        data = Jstep.reshape(-1, order="F")[self.positions]
        A = sp.csc_matrix((data, self.indices, self.indptr), shape=(self.m, self.m))
        return np.asarray(A @ J)


def sparse_steps(steps: dict[str, tuple[ca.Function, ...]], sizes: dict[str, int],
                 offsets: dict[str, int], choice: bool | None) -> dict[str, SparseStep]:
    """The fields whose step sensitivities are chained by sparse products: all (``choice``
    True), none (False), or by the rule of the module docstring (None). ``steps[key][1]``:
    the step Function with its Jacobian; ``sizes[key]``: its state's dimension; ``offsets``:
    where ``vec(J_step)`` starts in its flat output."""
    out = {}
    if choice is False:
        return out
    for key, fs in steps.items():
        m = sizes[key]
        if choice is None and m < MIN_DIMENSION:
            continue
        s = SparseStep(fs[1], m, offsets[key])
        if choice is None and s.density > MAX_DENSITY:
            continue
        out[key] = s
    return out
