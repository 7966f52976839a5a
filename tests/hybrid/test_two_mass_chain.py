"""The worked example ``problems/impacting/two_mass_chain.py`` (docs/adding_an_impact_system.md).

A system that is not in the paper, declared in a few lines: checks that the declaration errors
name the field, that the derived impact map is Newton's law (energy), and that the exact shooting
Jacobian and the multipliers agree with finite differences at a periodic orbit.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.impacting.two_mass_chain import TwoMassChainProblem
from pydantic import ValidationError

from nsm_continuation.cases import registry

BASE = {"m1": 1.0, "m2": 1.0, "k1": 1.0, "k2": 1.0, "c": 0.05, "F0": 0.5, "gap": 0.5,
        "restitution": 0.8}


def test_registered() -> None:
    assert registry.get("two_mass_chain") is TwoMassChainProblem


@pytest.mark.parametrize(("field", "value"), [("restitution", 1.2), ("restitution", -0.1),
                                               ("m1", -1.0), ("m2", 0.0), ("stiffness", 1.0)])
def test_declaration_errors_name_the_field(field: str, value: float) -> None:
    with pytest.raises(ValidationError) as err:
        TwoMassChainProblem({**BASE, field: value})
    assert err.value.errors()[0]["loc"] == (field,)
    assert isinstance(err.value, ValueError)


def test_inadmissible_initial_state_is_reported() -> None:
    pb = TwoMassChainProblem({**BASE, "gap": -0.1})
    with pytest.raises(ValueError, match="inadmissible side"):
        pb.start_points({"transient": 1})


def energy(X: np.ndarray, p: dict[str, float]) -> float:
    q1, q2, v1, v2 = X[:4]
    return 0.5 * (p["m1"] * v1**2 + p["m2"] * v2**2 + p["k1"] * q1**2 + p["k2"] * (q2 - q1)**2)


def test_impact_map_conserves_energy_for_e_near_one() -> None:
    p = {**BASE, "c": 0.0, "F0": 0.0, "restitution": 0.999999, "m2": 2.0}
    pb = TwoMassChainProblem(p)
    c = pb.shooting.c
    # on the wall q2 = gap, moving into it; X = state + the freed parameter (omega)
    X = np.array([0.3, p["gap"], -0.7, 1.3, 0.4, 1.0])
    R, _Rx, v, r = (np.asarray(z, dtype=float).ravel() for z in c.impact(X))
    assert v[0] == pytest.approx(-1.3) and r[0] == pytest.approx(p["restitution"])
    assert np.array_equal(R[[0, 1, 2, 4, 5]], X[[0, 1, 2, 4, 5]])   # only q2dot jumps
    assert R[3] == pytest.approx(-p["restitution"] * X[3], rel=1e-14)
    E0, E1 = energy(X, p), energy(R, p)
    assert abs(E1 - E0) / E0 < 2e-6
    # the loss is exactly (1 - e^2) times m2's kinetic energy
    assert E0 - E1 == pytest.approx((1 - p["restitution"] ** 2) * 0.5 * p["m2"] * X[3] ** 2,
                                    rel=1e-6)


def periodic_orbit(omega: float) -> tuple[TwoMassChainProblem, np.ndarray]:
    pb = TwoMassChainProblem({**BASE, "omega": omega})
    y = pb.start_points({"transient": 30})[0].y.copy()
    for _ in range(8):
        g, J = pb.evaluate_with_jacobian(y)
        if np.abs(g).max() < 1e-12:
            break
        y[:-1] += np.linalg.solve(J[:, :-1], -g)
    assert np.abs(pb.evaluate(y)).max() < 1e-11
    return pb, y


# 0.62: the impact has a > 0; 0.67: a < 0 at the impact, so the flight after it is integrated in
# the scaled extended system of sec. 4.3 (both have the event sequence "I")
@pytest.fixture(scope="module", params=[0.62, 0.67])
def orbit(request: pytest.FixtureRequest) -> tuple[TwoMassChainProblem, np.ndarray]:
    return periodic_orbit(request.param)


def fd_jacobian(f, y: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = []
    for j in range(y.size):
        d = np.zeros_like(y)
        d[j] = h
        cols.append((f(y + d) - f(y - d)) / (2 * h))
    return np.column_stack(cols)


def test_orbit_impacts(orbit: tuple[TwoMassChainProblem, np.ndarray]) -> None:
    pb, y = orbit
    res = pb.shooting.simulate(y)
    assert res.n_impacts == 1 and res.min_impact_velocity > 0.5
    assert res.t == pytest.approx(2 * np.pi / y[-1], rel=1e-12)


def test_shooting_jacobian_matches_finite_differences(
        orbit: tuple[TwoMassChainProblem, np.ndarray]) -> None:
    pb, y = orbit
    J = pb.jacobian(y)
    Jfd = fd_jacobian(pb.evaluate, y)
    assert np.abs(J - Jfd).max() < 1e-6      # |J| ~ 5; observed ~ 4e-9


def test_multipliers_match_finite_difference_poincare_map(
        orbit: tuple[TwoMassChainProblem, np.ndarray]) -> None:
    pb, y = orbit
    n = y.size - 1

    def poincare(z: np.ndarray) -> np.ndarray:
        return pb.evaluate(np.append(z, y[-1])) + z

    P = fd_jacobian(poincare, y[:-1])
    mu = pb.floquet(y, None).multipliers
    mu_fd = np.linalg.eigvals(P)
    assert mu.size == n
    dist = np.abs(mu[:, None] - mu_fd[None, :])
    assert dist.min(axis=1).max() < 1e-6 and dist.min(axis=0).max() < 1e-6  # ~1e-10
    assert np.abs(mu).max() < 1.0            # both orbits are stable (before the flip)
