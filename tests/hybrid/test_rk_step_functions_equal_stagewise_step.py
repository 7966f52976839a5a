"""The Runge-Kutta step Functions of the hybrid simulator equal the step they compile.

Three oracles, each independent of how the step Functions are compiled:

* a step evaluated stage by stage in numpy from the field alone (the tableau of
  :mod:`nsm_continuation.hybrid.tableaus`, ``F`` called once per stage): the compiled step, its
  error estimates, the probe and the field at its end equal it to rounding, and its Jacobian
  equals central differences of it;
* the same step written with :func:`nsm_continuation.hybrid.system.rk_step` into a CasADi
  Function of its own (the probe by calling the probe Function, not by substitution): the
  compiled outputs equal it bit for bit;
* the three Functions of one field (the step, the step with its Jacobian, the probe alone) and
  the fused probe-and-field Function agree with each other bit for bit (the simulator mixes
  them: a step tried without its Jacobian is taken with the Jacobian's Function, an event is
  located with the probe alone).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.impacting.bouncing_ball import ball_system
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

from nsm_continuation.hybrid import tableaus
from nsm_continuation.hybrid.system import rk_step

KEYS = ("free", "stick", "ext")


def _pendulum(method: str):
    pb = DoublePendulumProblem({"restitution": 0.89, "integrator": {"method": method}})
    pb.set_parameter("restitution")
    return pb.shooting.c


@pytest.fixture(scope="module", params=["dop853", "dopri5"])
def compiled(request):
    return _pendulum(request.param)


@pytest.fixture(scope="module")
def ball_clock():
    return ball_system(clock=True).compile({"g": 9.81, "e": 0.5}, method="dop853")


def _field_and_probe(c, key: str):
    """The field Function of ``key`` and the probe Function its steps report."""
    f = {"free": c.f, "stick": c.fs, "ext": c.fe}[key]
    probe = c.probe_e if key == "ext" else c.probe
    return f, probe


def _numpy_step(c, key: str, Y: np.ndarray, dt: float) -> np.ndarray:
    """The embedded RK step, stage by stage in numpy: ``(Yn, err, err3, probe, field)``."""
    f, probe = _field_and_probe(c, key)

    def F(x: np.ndarray) -> np.ndarray:
        return np.asarray(f(x), dtype=float).ravel()

    if c.method == "dop853":
        A, B, E, E3 = tableaus.DOP853_A, tableaus.DOP853_B, tableaus.DOP853_E5, tableaus.DOP853_E3
    else:
        A, B, E, E3 = tableaus.DOPRI5_A, tableaus.DOPRI5_B, tableaus.DOPRI5_E, None
    K = [F(Y)]
    for i in range(1, len(B)):
        K.append(F(Y + dt * sum(A[i, j] * K[j] for j in range(i))))
    Yn = Y + dt * sum(B[i] * K[i] for i in range(len(B)))
    K.append(F(Yn))
    err = dt * sum(E[i] * K[i] for i in range(len(E)))
    err3 = np.zeros_like(Y) if E3 is None else dt * sum(E3[i] * K[i] for i in range(len(E3)))
    pr = np.asarray(probe(Yn), dtype=float).ravel()
    return np.concatenate([Yn, err, err3, pr, F(Yn)])


def _states(c, key: str, rng: np.random.Generator, k: int) -> list[np.ndarray]:
    """Random states near the 6.1 orbit's scale (the extended state has ``u > 0``)."""
    out = []
    for _ in range(k):
        X = np.concatenate([rng.normal(size=c.n), 0.85 + 0.05 * rng.random(c.N - c.n)])
        if key == "ext":
            X = np.concatenate([X, [abs(rng.normal()) * 1e-3, 0.05 + rng.random()]])
        out.append(X)
    return out


@pytest.mark.parametrize("key", KEYS)
def test_step_equals_the_stage_by_stage_numpy_step(compiled, key: str) -> None:
    c = compiled
    calls = c.calls()
    rng = np.random.default_rng(1)
    for Y in _states(c, key, rng, 6):
        for dt in (1e-4, 3e-3, 2e-2):
            ref = _numpy_step(c, key, Y, dt)
            got = calls.steps[key][0].flat(Y, dt)
            assert got.shape == ref.shape
            scale = 1.0 + np.abs(ref)
            assert np.max(np.abs(got - ref) / scale) < 1e-13
            # the error estimates are O(dt^k) differences: compare them to their own size
            m = Y.size
            e_ref, e_got = ref[m:3 * m], got[m:3 * m]
            assert np.max(np.abs(e_got - e_ref)) <= 1e-12 * (np.max(np.abs(e_ref)) + 1e-300) \
                + 1e-15 * dt


@pytest.mark.parametrize("key", KEYS)
def test_step_jacobian_equals_central_differences(compiled, key: str) -> None:
    c = compiled
    calls = c.calls()
    rng = np.random.default_rng(2)
    Y = _states(c, key, rng, 1)[0]
    dt = 5e-3
    m = Y.size
    npr = 6 if key == "ext" else 4
    # vec(J), then the Jacobians of the error estimates (err, and err3 for DOP853); the errors
    # are checked over a long step, where they are well above the differences' round-off
    h = 1e-6
    for dt_, rows in ((dt, 1), (0.2, 3)):
        flat = calls.steps[key][1].flat(Y, dt_)[4 * m + npr:]
        dE = flat[m * m:].reshape(-1, m, order="F")
        blocks = [flat[:m * m].reshape(m, m, order="F"), *(dE[k:k + m]
                                                           for k in range(0, dE.shape[0], m))]
        assert len(blocks) == (3 if c.method == "dop853" else 2)
        for j in range(m):
            d = np.zeros(m)
            d[j] = h
            diff = (_numpy_step(c, key, Y + d, dt_) - _numpy_step(c, key, Y - d, dt_)) / (2 * h)
            for b, block in enumerate(blocks[:rows]):
                col = diff[b * m:(b + 1) * m]
                scale = 1.0 if b == 0 else np.max(np.abs(block))
                assert scale > 0 and np.allclose(block[:, j], col, rtol=1e-6, atol=1e-6 * scale)


def _plain_step(c, key: str) -> ca.Function:
    """The step of ``key`` as a CasADi Function of its own, built from rk_step."""
    f, probe = _field_and_probe(c, key)
    Y = ca.SX.sym("Y", f.numel_in(0))
    dt = ca.SX.sym("dt")
    Yn, err, err3 = rk_step(f, Y, dt, c.method)
    return ca.Function("plain", [Y, dt], [ca.vertcat(Yn, err, err3, probe(Yn), f(Yn))])


@pytest.mark.parametrize("key", KEYS)
def test_compiled_step_is_bitwise_the_plain_step(compiled, key: str) -> None:
    c = compiled
    plain = _plain_step(c, key)
    calls = c.calls()
    rng = np.random.default_rng(3)
    for Y in _states(c, key, rng, 20):
        dt = float(10 ** rng.uniform(-7, -1))
        ref = np.asarray(plain(Y, dt), dtype=float).ravel()
        assert np.array_equal(calls.steps[key][0].flat(Y, dt), ref)


def _check_functions_agree(c, key: str, rng: np.random.Generator) -> None:
    calls = c.calls()
    step, stepJ, stepP = calls.steps[key]
    m = c.N + (2 if key == "ext" else 0)
    npr = 6 if key == "ext" else 4
    for Y in _states(c, key, rng, 30):
        dt = float(10 ** rng.uniform(-8, 0))
        a = step.flat(Y, dt)
        b = stepJ.flat(Y, dt)
        p = stepP.flat(Y, dt)
        # the step with its Jacobian starts with the step; the probe alone is its probe part
        assert np.array_equal(a, b[: a.size], equal_nan=True)
        assert np.array_equal(p, a[3 * m: 3 * m + npr], equal_nan=True)
        # probe and field at a state, fused, equal the separate Functions
        f, probe = _field_and_probe(c, key)
        both = calls.probe_field[key].flat(Y)
        assert np.array_equal(both[:npr], np.asarray(probe(Y), dtype=float).ravel())
        assert np.array_equal(both[npr:], np.asarray(f(Y), dtype=float).ravel())


@pytest.mark.parametrize("key", KEYS)
def test_step_functions_of_one_field_agree_bitwise(compiled, key: str) -> None:
    _check_functions_agree(compiled, key, np.random.default_rng(4))


@pytest.mark.parametrize("key", KEYS)
def test_step_functions_agree_for_a_clocked_system(ball_clock, key: str) -> None:
    """A second system: the bouncing ball with a clock coordinate (three states)."""
    _check_functions_agree(ball_clock, key, np.random.default_rng(5))
