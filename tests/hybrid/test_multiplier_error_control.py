"""The multipliers are as accurate as the state: the step error test covers the sensitivities.

Oracle: the Stuart-Landau oscillator in polar form, ``r' = r (mu - r^2)``, ``theta' = 1``,
declared as a hybrid case (a wall at ``r = 10`` it never reaches; the Poincare section on the
angle). Its periodic orbit ``r = sqrt(mu)`` has period ``2 pi`` and the multiplier
``exp(-4 pi mu)`` in closed form (the linearisation ``dr' = -2 mu dr``). On the orbit the state
has no local error (``r`` constant, ``theta`` linear), so an error test on the state alone lets
the steps grow to a fraction of the period while the sensitivity ``dr/dr0 = exp(-2 mu t)`` is
integrated with them: its error, not the state's, then sets the multiplier's.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem
from pydantic import BaseModel

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.system import HybridSystem


class _Params(BaseModel):
    model_config = STRICT
    mu: float = 0.5
    wall: float = 10.0
    integrator: IntegratorSpec = IntegratorSpec()


class StuartLandauPolar(HybridCaseProblem):
    """The Stuart-Landau oscillator in polar form (a wall it never reaches)."""

    name: ClassVar[str] = "stuart_landau_polar"
    Parameters: ClassVar[type[BaseModel]] = _Params
    default_parameter: ClassVar[str] = "mu"

    def system(self) -> HybridSystem:
        x, mu, wall = ca.SX.sym("x", 2), ca.SX.sym("mu"), ca.SX.sym("wall")
        F = ca.vertcat(x[0] * (mu - x[0] ** 2), ca.SX(1.0))
        return HybridSystem("stuart_landau_polar", x, {"mu": mu, "wall": wall}, F,
                            wall - x[0], ca.vertcat(ca.SX(-1.0), ca.SX(0.0)),
                            ["r", "theta"], periodic={1: 2 * np.pi})

    def section(self) -> Section:
        return Section(1, 0.0, 2 * np.pi)

    def default_initial(self) -> np.ndarray:
        return np.array([np.sqrt(self.values["mu"]), 0.0])


def _multipliers(mu: float, integrator: dict[str, Any]) -> tuple[np.ndarray, Any]:
    """The multipliers of the orbit ``r = sqrt(mu)`` (the section's return map, the freed
    ``mu`` column dropped) and the simulation of one return."""
    pb = StuartLandauPolar({"mu": mu, "integrator": integrator})
    pb.set_parameter("mu")
    y = np.array([np.sqrt(mu), mu])
    P = pb.shooting.poincare_jacobian(y)
    return np.linalg.eigvals(P), pb.sim(y)


@pytest.mark.parametrize("method", ["dop853", "dopri5"])
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_multiplier_to_the_tolerance(method: str, rtol: float) -> None:
    """``exp(-4 pi mu)`` to a few ``rtol`` (relative) or ``atol`` (absolute) for mu up to 1,
    where the multiplier is 3.5e-6, with either tableau; the period ``2 pi`` likewise."""
    atol = rtol * 1e-2
    for mu in (0.1, 0.5, 1.0):
        m, res = _multipliers(mu, {"method": method, "rtol": rtol, "atol": atol})
        exact = np.exp(-4 * np.pi * mu)
        got = m[np.argmin(np.abs(m - exact))]
        assert abs(got - exact) <= 20 * (rtol * exact + atol), (mu, got, exact)
        assert abs(res.t - 2 * np.pi) <= 20 * rtol * 2 * np.pi


def test_state_only_error_test_misses_the_multiplier() -> None:
    """The case discriminates: with the error test on the state alone (``sensitivity_error:
    false``) the same orbit takes a handful of steps and its multiplier is wrong by far more
    than the tolerance, while the state (the return time) is right."""
    mu, rtol = 0.5, 1e-10
    exact = np.exp(-4 * np.pi * mu)
    loose, res_loose = _multipliers(mu, {"rtol": rtol, "atol": rtol * 1e-2,
                                         "sensitivity_error": False})
    tight, res_tight = _multipliers(mu, {"rtol": rtol, "atol": rtol * 1e-2})
    assert abs(res_loose.t - 2 * np.pi) <= 20 * rtol * 2 * np.pi
    assert np.min(np.abs(loose - exact)) > 1e3 * rtol * exact
    assert np.min(np.abs(tight - exact)) <= 20 * rtol * exact
    assert res_tight.n_steps > res_loose.n_steps


def test_exact_flow_unaffected() -> None:
    """The exact flow (``integrator.method: exact``) has no integration error and carries its
    sensitivities in closed form: on an orbit of free flights and impacts the option changes
    none of its numbers (residual, Jacobian, steps), bit for bit."""
    params = {"zeta": 0.0, "omega": 1.5, "gap": -0.5, "restitution": 0.8,
              "section_phase": np.pi}
    out = []
    for flag in (True, False):
        pb = ImpactOscillatorProblem({**params, "integrator": {"method": "exact",
                                                               "sensitivity_error": flag}})
        assert pb.shooting.c.flow == "exact"
        y = pb.start_points({"transient": 40})[0].y
        r, J = pb.shooting.residual_jacobian(y)
        out.append((y, r, J, pb.shooting.simulate(y).n_steps))
    (ya, ra, Ja, na), (yb, rb, Jb, nb) = out
    assert np.array_equal(ya, yb) and np.array_equal(ra, rb) and np.array_equal(Ja, Jb)
    assert na == nb
