"""BufferedFunction with its argument (and small result) memory bound once.

Oracle: CasADi's own call (``np.asarray`` of its ``DM`` results) on the same arguments. The
checks are about what binding the memory once could break: results of one call overwritten by
the next, arguments of another kind or shape than a 1-D float vector, a scalar broadcast into a
vector input, a large (unbound) result, calls from several threads.
"""

from __future__ import annotations

import threading

import casadi as ca
import numpy as np
import pytest

from nsm_continuation.core.casadi_buffers import SMALL_RESULTS, BufferedFunction


def _step_like() -> ca.Function:
    """(vector, scalar) -> one flat output, like the simulator's step Functions."""
    x = ca.SX.sym("x", 4)
    t = ca.SX.sym("t")
    return ca.Function("s", [x, t], [ca.vertcat(ca.sin(x) * t, ca.dot(x, x), x[0] * x[3] / t)])


def _plain(f: ca.Function, *args: object) -> np.ndarray:
    return np.asarray(f(*args), dtype=float).ravel(order="F")


def test_flat_equals_plain_call_and_results_are_fresh() -> None:
    f = _step_like()
    b = BufferedFunction(f)
    rng = np.random.default_rng(0)
    kept = []
    for _ in range(20):
        x, t = rng.normal(size=4), float(rng.uniform(0.1, 2.0))
        kept.append((x, t, b.flat(x, t)))
    for x, t, got in kept:  # earlier results are not overwritten by later calls
        assert np.array_equal(got, _plain(f, x, t))


def test_argument_kinds_give_the_plain_values() -> None:
    f = _step_like()
    b = BufferedFunction(f)
    x = np.array([0.3, -1.2, 2.0, 0.7])
    ref = _plain(f, x, 0.5)
    for xa in (x, x.reshape(4, 1), x.reshape(1, 4), list(x), x[::-1][::-1].copy(),
               np.asfortranarray(x.reshape(2, 2).T).T.reshape(4)):
        for ta in (0.5, np.float64(0.5), np.array(0.5), np.array([0.5]), [0.5]):
            assert np.array_equal(b.flat(xa, ta), ref)
            assert np.array_equal(b(xa, ta).ravel(order="F"), ref)
    # an integer vector is converted as CasADi converts it
    xi = np.array([1, -2, 3, 0])
    assert np.array_equal(b.flat(xi, 2.0), _plain(f, xi.astype(float), 2.0))
    # a strided view (not contiguous)
    big = np.arange(8.0)
    assert np.array_equal(b.flat(big[::2], 0.25), _plain(f, big[::2].copy(), 0.25))


def test_a_scalar_is_not_broadcast_into_a_vector_input() -> None:
    b = BufferedFunction(_step_like())
    with pytest.raises(ValueError, match="argument 0 has 1 elements, expects 4"):
        b.flat(1.0, 0.5)
    with pytest.raises(ValueError, match="argument 1 has 2 elements, expects 1"):
        b.flat(np.zeros(4), np.zeros(2))
    with pytest.raises(TypeError, match="expects 2 arguments, got 1"):
        b.flat(np.zeros(4))


def test_several_outputs_and_a_large_unbound_result() -> None:
    n = int(np.sqrt(SMALL_RESULTS)) + 2  # an n x n result is above the bound size
    x = ca.SX.sym("x", n)
    f = ca.Function("g", [x], [ca.mtimes(x, x.T), ca.sum1(x), 2 * x])
    b = BufferedFunction(f)
    assert not b._bound
    rng = np.random.default_rng(1)
    first_x = rng.normal(size=n)
    first = b(first_x)
    second = b(rng.normal(size=n))
    for got, ref in zip(first, f(first_x), strict=True):
        assert np.array_equal(got, np.asarray(ref, dtype=float))
    assert not np.array_equal(first[0], second[0])
    with pytest.raises(TypeError, match="one output"):
        b.flat(first_x)
    h = ca.Function("h", [x], [ca.sum1(x), 2 * x])
    small = BufferedFunction(h)
    assert small._bound
    kept = small(first_x)
    small(rng.normal(size=n))  # a later call leaves the earlier results alone
    for got, ref in zip(kept, h(first_x), strict=True):
        assert np.array_equal(got, np.asarray(ref, dtype=float))


def test_calls_from_threads_are_serialised() -> None:
    f = _step_like()
    b = BufferedFunction(f)
    rng = np.random.default_rng(2)
    xs = [rng.normal(size=4) for _ in range(200)]
    refs = [_plain(f, x, 0.7) for x in xs]
    bad: list[int] = []

    def work(offset: int) -> None:
        for i in range(offset, len(xs), 4):
            if not np.array_equal(b.flat(xs[i], 0.7), refs[i]):
                bad.append(i)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not bad
