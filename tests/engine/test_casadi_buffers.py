"""BufferedFunction (nsm_continuation/core/casadi_buffers.py) against CasADi's own call: the same
values, shapes and output count, bit for bit, also for sparse and matrix outputs, and fresh
arrays on every call. Oracle: ``np.asarray`` of the ``DM`` results of a plain call."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nsm_continuation.core.casadi_buffers import BufferedFunction


def _function() -> ca.Function:
    x = ca.SX.sym("x", 3)
    t = ca.SX.sym("t")
    J = ca.jacobian(ca.vertcat(x[0] * x[1], ca.sin(x[2]), t * x[0]), x)  # structural zeros
    A = ca.horzcat(ca.vertcat(x[0], t), ca.vertcat(x[1], x[2] ** 2),
                   ca.vertcat(0, t * x[1]))  # 2 x 3, not square: catches a missing transpose
    return ca.Function("f", [x, t], [ca.exp(x) * t, J, A, x[1] * t])


def test_values_and_shapes_equal_the_plain_call() -> None:
    f = _function()
    assert not f.sparsity_out(1).is_dense()  # the densified path is exercised
    b = BufferedFunction(f)
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, t = rng.normal(size=3), float(rng.normal())
        plain = [np.asarray(z, dtype=float) for z in f(x, t)]
        buffered = b(x, t)
        assert len(buffered) == len(plain) == 4
        for p, q in zip(plain, buffered, strict=True):
            assert p.shape == q.shape
            assert np.array_equal(p, q)


def test_single_output_and_fresh_arrays() -> None:
    x = ca.SX.sym("x", 2)
    b = BufferedFunction(ca.Function("g", [x], [2 * x]))
    first = b(np.array([1.0, 2.0]))
    second = b(np.array([3.0, 4.0]))
    assert isinstance(first, np.ndarray) and first.shape == (2, 1)
    assert np.array_equal(first.ravel(), [2.0, 4.0])  # not overwritten by the second call
    assert np.array_equal(second.ravel(), [6.0, 8.0])


def test_wrong_arguments_are_refused() -> None:
    b = BufferedFunction(_function())
    with pytest.raises(TypeError, match="expects 2 arguments, got 1"):
        b(np.zeros(3))
    with pytest.raises(ValueError, match="argument 0 has 2 elements, expects 3"):
        b(np.zeros(2), 1.0)
