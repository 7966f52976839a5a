"""CasADi Functions called through their buffers: numpy in, numpy out, no ``DM`` in between.

Calling a CasADi ``Function`` from Python with numpy arguments converts every argument to a
``DM`` and every result back (``np.asarray(DM)`` goes through a Python list of the elements):
a function of 8 inputs with a vector and an 8 x 8 output took 32 us per call that way, 6 us
through ``Function.buffer()``, which reads its arguments from, and writes its results into,
memory the caller owns. The hybrid simulator calls such functions at every Runge-Kutta step,
event probe and impact: the conversions were 34-45 % of the wall time of three hybrid runs
(``benchmarks/README.md``, "Scans below O(N^3), buffered CasADi calls").

The buffer is bound once to arrays owned by the :class:`BufferedFunction` (its arguments, and
its results when they are small): a call copies the arguments in, evaluates, and copies the
results out, instead of re-binding every argument and result (``set_arg``/``set_res`` cost
about 1.5 us each, more than the copies). Large results (a chain's dense Jacobian) are still
written straight into fresh arrays: copying them would cost more than the binding.
"""

from __future__ import annotations

from threading import Lock
from typing import Any

import casadi as ca
import numpy as np

#: results with at most this many elements in all are written into arrays bound once and
#: copied out; larger ones are written into fresh arrays bound at every call
SMALL_RESULTS = 4096


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
    re-entrant.

    :meth:`flat` is the fast path of a function with one output: that output as a fresh 1-D
    array (column-major order), the same values."""

    def __init__(self, f: ca.Function) -> None:
        for i in range(f.n_in()):
            if not f.sparsity_in(i).is_dense():
                raise ValueError(f"{f.name()}: input {f.name_in(i)} is not dense")
        self.function = densified(f)
        self._buffer, self._trigger = self.function.buffer()
        self._n_in = [f.numel_in(i) for i in range(f.n_in())]
        self._shapes = [(f.size2_out(i), f.size1_out(i)) for i in range(f.n_out())]
        self._lock = Lock()
        # the arguments' memory, bound once: a call copies the arguments into it
        self._args = [np.zeros(n) for n in self._n_in]
        for i, a in enumerate(self._args):
            self._buffer.set_arg(i, memoryview(a))
        # column-major results: the rows of a (cols, rows) C array are the columns
        self._bound = sum(r * c for r, c in self._shapes) <= SMALL_RESULTS
        self._outs = [np.empty(shape) for shape in self._shapes]
        if self._bound:
            for i, o in enumerate(self._outs):
                self._buffer.set_res(i, memoryview(o))
        #: the single bound output as a 1-D view (:meth:`flat`), None otherwise
        self._flat = self._outs[0].reshape(-1) if self._bound and len(self._outs) == 1 else None
        #: inputs (vector, scalar): the signature of a Runge-Kutta step, with a fast path
        self._vs = len(self._n_in) == 2 and self._n_in[1] == 1

    def _load(self, args: tuple[Any, ...]) -> None:
        """Copy the arguments into the bound argument arrays (caller holds the lock)."""
        if len(args) != len(self._n_in):
            raise TypeError(f"{self.function.name()}: expects {len(self._n_in)} arguments, "
                            f"got {len(args)}")
        i = 0
        for dst, a in zip(self._args, args, strict=True):
            # fast paths: a vector of the right length, a float for a scalar input
            if type(a) is np.ndarray and a.ndim == 1 and a.shape[0] == dst.shape[0]:
                dst[:] = a
            elif isinstance(a, float) and dst.shape[0] == 1:
                dst[0] = a
            else:
                v = np.asarray(a, dtype=float).reshape(-1)
                if v.size != dst.size:
                    raise ValueError(f"{self.function.name()}: argument {i} has {v.size} "
                                     f"elements, expects {dst.size}")
                dst[:] = v
            i += 1

    def __call__(self, *args: Any) -> Any:
        with self._lock:
            self._load(args)
            if self._bound:
                self._trigger()
                res = [o.copy().T for o in self._outs]
            else:
                outs = [np.empty(shape) for shape in self._shapes]
                for i, o in enumerate(outs):
                    self._buffer.set_res(i, memoryview(o))
                self._trigger()
                res = [o.T for o in outs]
        return res[0] if len(res) == 1 else tuple(res)

    def flat(self, *args: Any) -> np.ndarray:
        """The single output of ``f`` as a fresh 1-D array (column-major), the same values as
        ``self(*args).ravel(order="F")``."""
        out = self._flat
        if out is None:
            if len(self._shapes) != 1:
                raise TypeError(f"{self.function.name()}: flat() needs a function with one "
                                "output")
            return self(*args).ravel(order="F")
        with self._lock:
            if self._vs and len(args) == 2:
                y, t = args
                a0 = self._args[0]
                if type(y) is np.ndarray and y.ndim == 1 and y.shape[0] == a0.shape[0] \
                        and isinstance(t, float):
                    a0[:] = y
                    self._args[1][0] = t
                else:
                    self._load(args)
            else:
                self._load(args)
            self._trigger()
            return out.copy()
