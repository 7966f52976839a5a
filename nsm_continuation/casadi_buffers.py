"""CasADi Functions called through their buffers: numpy in, numpy out, no ``DM`` in between.

Calling a CasADi ``Function`` from Python with numpy arguments converts every argument to a
``DM`` and every result back (``np.asarray(DM)`` goes through a Python list of the elements):
a function of 8 inputs with a vector and an 8 x 8 output took 32 us per call that way, 6 us
through ``Function.buffer()``, which reads its arguments from, and writes its results into,
memory the caller owns. The hybrid simulator calls such functions at every Runge-Kutta step,
event probe and impact: the conversions were 34-45 % of the wall time of three hybrid runs
(``benchmarks/README.md``, "Scans below O(N^3), buffered CasADi calls").
"""

from __future__ import annotations

from threading import Lock
from typing import Any

import casadi as ca
import numpy as np


def densified(f: ca.Function) -> ca.Function:
    """``f`` with dense outputs (a buffer writes only the structural nonzeros), the same
    values: built on symbols of ``f``'s own kind, so an ``SXFunction`` stays one."""
    if all(f.sparsity_out(i).is_dense() for i in range(f.n_out())):
        return f
    sym = ca.SX.sym if f.is_a("SXFunction") else ca.MX.sym
    ins = [sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
    outs = f.call(ins)
    return ca.Function(f.name(), ins, [ca.densify(o) for o in outs],
                       f.name_in(), f.name_out())


class BufferedFunction:
    """``f(*args)`` as ``np.asarray`` of CasADi's result would give it: one array of shape
    ``(rows, cols)`` per output (a tuple when ``f`` has several), the same values to the last
    bit, fresh arrays on every call (callers keep them). Arguments: arrays or floats, with
    as many elements as ``f``'s dense inputs. Calls are serialised by a lock: a buffer is not
    re-entrant."""

    def __init__(self, f: ca.Function) -> None:
        for i in range(f.n_in()):
            if not f.sparsity_in(i).is_dense():
                raise ValueError(f"{f.name()}: input {f.name_in(i)} is not dense")
        self.function = densified(f)
        self._buffer, self._trigger = self.function.buffer()
        self._n_in = [f.numel_in(i) for i in range(f.n_in())]
        self._shapes = [(f.size2_out(i), f.size1_out(i)) for i in range(f.n_out())]
        self._lock = Lock()

    def __call__(self, *args: Any) -> Any:
        if len(args) != len(self._n_in):
            raise TypeError(f"{self.function.name()}: expects {len(self._n_in)} arguments, "
                            f"got {len(args)}")
        ins = [np.ascontiguousarray(a, dtype=float).reshape(-1) for a in args]
        for a, n, i in zip(ins, self._n_in, range(len(ins)), strict=True):
            if a.size != n:
                raise ValueError(f"{self.function.name()}: argument {i} has {a.size} "
                                 f"elements, expects {n}")
        # column-major results: the rows of a (cols, rows) C array are the columns
        outs = [np.empty(shape) for shape in self._shapes]
        with self._lock:
            for i, a in enumerate(ins):
                self._buffer.set_arg(i, memoryview(a))
            for i, o in enumerate(outs):
                self._buffer.set_res(i, memoryview(o))
            self._trigger()
        res = [o.T for o in outs]
        return res[0] if len(res) == 1 else tuple(res)
