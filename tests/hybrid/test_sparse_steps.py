"""Sparse sensitivity products of Runge-Kutta steps (:mod:`nsm_continuation.hybrid.sparse_steps`).

Oracles: the dense product of the same step Jacobian (the chained sensitivities of a whole
simulation must agree to rounding, the trajectory bit for bit), and the step Function's dense
Jacobian itself (no nonzero outside the structure read from the CasADi expression).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from nsm_continuation.hybrid.simulate import SimOptions, Simulator
from nsm_continuation.hybrid.sparse_steps import MIN_DIMENSION, SparseStep, sparse_steps
from nsm_continuation.hybrid.system import HybridSystem


def cubic_chain(N: int) -> HybridSystem:
    """``N`` unit masses joined by springs of force ``d + 0.5 d^3``, damping 0.05, the first
    forced by ``cos(phase)``, the last at a wall at 0 (not linear: Runge-Kutta)."""
    q, qd, ph = ca.SX.sym("q", N), ca.SX.sym("qd", N), ca.SX.sym("phase")
    p = {"omega": ca.SX.sym("omega")}

    def spring(d):
        return d + 0.5 * d ** 3

    f = []
    for i in range(N):
        left = spring(q[i] - (q[i - 1] if i > 0 else 0))
        right = spring(q[i + 1] - q[i]) if i < N - 1 else 0
        f.append(-left + right - 0.05 * qd[i] + (ca.cos(ph) if i == 0 else 0))
    return HybridSystem.mechanical(f"cubic{N}", q, qd, p, ca.SX.eye(N), ca.vertcat(*f),
                                   -q[N - 1], 0.8, clock=ph, clock_rate=p["omega"])


def test_structure_holds_every_nonzero_of_the_step_jacobian() -> None:
    """The step Jacobian of a 12-mass cubic chain is sparse (banded: each of the 12 stages
    couples neighbours), and its dense values vanish off the structure read from CasADi."""
    c = cubic_chain(12).compile({}, free=["omega"])
    m = c.N
    s = SparseStep(c.steps["free"][1], m, 4 * m + 4)
    assert s.density < 0.8
    Y = np.random.default_rng(3).normal(scale=0.3, size=m)
    Y[-1] = 0.9
    flat = c.calls().steps["free"][1].flat(Y, 0.2)
    J = flat[4 * m + 4:4 * m + 4 + m * m].reshape(m, m, order="F")
    off = np.ones(m * m, bool)
    off[s.positions] = False
    assert np.all(J.reshape(-1, order="F")[off] == 0.0)
    A = np.random.default_rng(4).normal(size=(m, m))
    assert np.allclose(s.chain(J, A), J @ A, rtol=0, atol=1e-13 * np.abs(J).max() * m)


def test_sparse_and_dense_products_give_the_same_simulation() -> None:
    """A return of the 6-mass cubic chain with sparse and with dense sensitivity products:
    with the step error test on the state alone the same trajectory (bit for bit), the same
    sensitivities to rounding; with the sensitivities in the test (the default), whose step
    sizes then see the products' rounding, the same return to the tolerance; the rule keeps
    the dense product for systems this small."""
    c = cubic_chain(6).compile({}, free=["omega"])
    X0 = np.zeros(c.N)
    X0[:6] = -0.1
    X0[-1] = 0.32
    for controlled in (False, True):
        out = []
        for sparse in (True, False):
            sim = Simulator(c, SimOptions(sparse_products=sparse,
                                          sensitivity_error=controlled))
            out.append(sim.run(X0, section=(12, 2 * np.pi, 1)))
        a, b = out
        if controlled:
            assert abs(a.t - b.t) < 1e-9 and np.allclose(a.X, b.X, rtol=0, atol=1e-9)
            assert np.allclose(a.J, b.J, rtol=0, atol=1e-8 * np.abs(b.J).max())
        else:
            assert a.t == b.t and np.array_equal(a.X, b.X)
            assert np.allclose(a.J, b.J, rtol=0, atol=1e-12 * np.abs(b.J).max())
        assert [e.kind for e in a.events] == [e.kind for e in b.events]
    assert c.N < MIN_DIMENSION
    assert sparse_steps(c.steps, {k: c.N for k in c.steps}, {k: 0 for k in c.steps},
                        None) == {}
