"""The simulator's Runge-Kutta tableaus satisfy their order conditions (an oracle independent of
where the numbers came from): row sums equal the nodes, and the weights integrate t^(k-1)
exactly, ``b . c^(k-1) = 1/k``, up to the method's order (the bushy-tree conditions); the
embedded error weights sum to zero (both solutions are consistent)."""

from __future__ import annotations

import numpy as np
import pytest

from nsm_continuation.hybrid import tableaus as t


@pytest.mark.parametrize("A, b, c, order", [
    (t.DOP853_A, t.DOP853_B, t.DOP853_C, 8),
    (t.DOPRI5_A, t.DOPRI5_B, t.DOPRI5_C, 5),
])
def test_order_conditions(A, b, c, order):
    s = len(b)
    A = np.hstack([A, np.zeros((s, s - A.shape[1]))])  # SciPy stores DOPRI5's A as s x (s-1)
    assert np.allclose(np.triu(A), 0.0)  # explicit
    assert np.allclose(A.sum(axis=1), c, atol=1e-15)
    for k in range(1, order + 1):
        assert b @ c ** (k - 1) == pytest.approx(1.0 / k, abs=1e-14), k
    # and the order is no higher: the next quadrature condition fails
    assert abs(b @ c**order - 1.0 / (order + 1)) > 1e-8
    # a second family of conditions: b . (A c^(k-1)) = 1/(k (k+1))
    for k in range(1, order):
        assert b @ (A @ c ** (k - 1)) == pytest.approx(1.0 / (k * (k + 1)), abs=1e-14), k


def test_error_weights_are_consistent():
    for E in (t.DOP853_E5, t.DOP853_E3, t.DOPRI5_E):
        assert abs(E.sum()) < 1e-14
        assert np.abs(E).max() > 1e-6
