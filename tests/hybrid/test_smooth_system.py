"""A smooth system through the hybrid layer: the Stuart-Landau oscillator in Cartesian form.

``problems/impacting/stuart_landau.py``: no contact (``HybridSystem.smooth``), the section
``x = 0`` crossed in a declared direction (``CrossingSection``), continued in ``mu``. The oracle is
the closed form: the orbit is the circle of radius ``sqrt(mu)``, of period ``2 pi``, with the
nontrivial multiplier ``exp(-4 pi mu)``; crossed rising (``x' = -y > 0``) the section state is
``y = -sqrt(mu)``, crossed falling ``y = +sqrt(mu)``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.impacting.stuart_landau import StuartLandauProblem

import nsm_continuation as nsm
from nsm_continuation.hybrid.return_map import CrossingSection, ShootingFailure
from nsm_continuation.hybrid.simulate import SimOptions, Simulator
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem

RTOL = 1e-10


def closed_form_errors(b: nsm.Branch, crossing: int) -> tuple[np.ndarray, ...]:
    """Per point: the relative error of the radius (the section state ``y = -crossing
    sqrt(mu)``), the error of the period and of the multiplier ``exp(-4 pi mu)``."""
    mu, y, T = (np.asarray(b[k], dtype=float) for k in ("mu", "y_y", "period"))
    lam = np.asarray(b["mu1_re"], dtype=float) + 1j * np.asarray(b["mu1_im"], dtype=float)
    return (np.abs(y + crossing * np.sqrt(mu)) / np.sqrt(mu), np.abs(T - 2 * np.pi),
            np.abs(lam - np.exp(-4 * np.pi * mu)))


def test_a_system_without_contact_is_declared_and_simulated() -> None:
    x, mu = ca.SX.sym("x", 2), ca.SX.sym("mu")
    F = ca.vertcat(mu * x[0] - x[1], x[0] + mu * x[1])          # a linear focus
    for system in (HybridSystem.smooth("focus", x, {"mu": mu}, F, ["x", "y"]),
                   HybridSystem("focus", x, {"mu": mu}, F, [], [], ["x", "y"])):
        assert system.m == 0 and system.surface_names == []
        sim = Simulator(system.compile({"mu": -0.1}), SimOptions(rtol=RTOL, atol=1e-14))
        res = sim.run(np.array([0.0, -1.0]), section=(0, 0.0, +1))
        # one turn of the spiral: x(t) = e^(mu t) (sin t, -cos t), back at x = 0 at t = 2 pi
        assert res.t == pytest.approx(2 * np.pi, rel=1e-9)
        assert res.X[1] == pytest.approx(-np.exp(-0.2 * np.pi), rel=1e-9)
        assert res.n_impacts == 0 and not res.events[:-1] and res.state == "s1"
    with pytest.raises(HybridDeclarationError, match="W must have one column"):
        HybridSystem("focus", x, {"mu": mu}, F, [], ca.SX.ones(2), ["x", "y"])


def test_a_mechanical_system_without_contact_against_scipy() -> None:
    """A forced Duffing oscillator declared by ``HybridSystem.mechanical`` with no constraint:
    one forcing period, the state and the monodromy against SciPy's DOP853 on the same field
    and its variational equations."""
    from scipy.integrate import solve_ivp

    q, qd, phase, w = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase"), ca.SX.sym("w")
    force = -q - 0.1 * qd - q ** 3 + ca.cos(phase)
    system = HybridSystem.mechanical("duffing", q, qd, {"w": w}, ca.SX(1), force, [], [],
                                     clock=phase, clock_rate=w)
    assert system.m == 0
    omega = 1.2
    sim = Simulator(system.compile({"w": omega}), SimOptions(rtol=1e-12, atol=1e-14))
    res = sim.run(np.array([0.3, 0.0, 0.0]), section=(2, 2 * np.pi, 1))

    def rhs(t: float, z: np.ndarray) -> np.ndarray:
        x, v, P = z[0], z[1], z[2:].reshape(2, 2)
        A = np.array([[0.0, 1.0], [-1.0 - 3 * x ** 2, -0.1]])
        return np.concatenate([[v, -x - 0.1 * v - x ** 3 + np.cos(omega * t)], (A @ P).ravel()])

    T = 2 * np.pi / omega
    ref = solve_ivp(rhs, (0.0, T), [0.3, 0.0, 1.0, 0.0, 0.0, 1.0], method="DOP853",
                    rtol=1e-12, atol=1e-14).y[:, -1]
    assert res.t == pytest.approx(T, rel=1e-12)
    assert res.X[:2] == pytest.approx(ref[:2], abs=1e-9)
    # the section is on the clock: the map's Jacobian in (q, qd) is the time-T monodromy
    assert res.J[:2, :2] == pytest.approx(ref[2:].reshape(2, 2), abs=1e-8)


def test_the_crossing_direction_survives_the_continuation_setup() -> None:
    for crossing in (-1, 1):
        pb = StuartLandauProblem({"mu": 0.25, "crossing": crossing})
        sec = pb.shooting.section
        assert isinstance(sec, CrossingSection)
        assert (sec.direction, sec.crossings) == (crossing, 1)
        twice = pb.iterated(2).shooting.section
        assert (twice.direction, twice.crossings) == (crossing, 2)


@pytest.mark.parametrize("crossing", [1, -1])
def test_stuart_landau_family_against_the_closed_form(crossing: int) -> None:
    pb = StuartLandauProblem({"mu": 0.05, "crossing": crossing,
                              "integrator": {"rtol": RTOL, "atol": 1e-2 * RTOL}})
    res = nsm.continuation(pb, {"transient": 30}, parameter="mu", min=0.05, max=1.0,
                           max_points=200)
    b = res.branches[0]
    assert b.termination == {"forward": "bound: mu = max", "backward": "bound: mu = min"}
    mu = np.asarray(b["mu"], dtype=float)
    assert mu.min() == pytest.approx(0.05) and mu.max() == pytest.approx(1.0)
    radius, period, multiplier = closed_form_errors(b, crossing)
    # the integration error (rtol) amplified by the fixed point's condition 1 / (1 - lambda),
    # at most 2.1 here (mu >= 0.05)
    assert radius.max() < 100 * RTOL
    assert period.max() < 100 * RTOL * 2 * np.pi
    assert multiplier.max() < 100 * RTOL
    assert not res.events_frame().kind.isin(["period_doubling", "fold", "branch_point"]).any()


def test_the_iterated_map_has_twice_the_period_and_the_squared_multiplier() -> None:
    mu = 0.2
    pb = StuartLandauProblem({"mu": mu, "integrator": {"rtol": RTOL, "atol": 1e-2 * RTOL}})
    y = np.array([-np.sqrt(mu), mu])
    for periods in (1, 2, 3):
        sh = pb.iterated(periods).shooting
        g, _ = sh.residual_jacobian(y)
        assert np.abs(g).max() < 1e2 * RTOL
        assert sh.simulate(y).t == pytest.approx(2 * np.pi * periods, rel=1e2 * RTOL)
        lam = np.linalg.eigvals(sh.poincare_jacobian(y))
        assert lam == pytest.approx([np.exp(-4 * np.pi * mu * periods)], abs=1e2 * RTOL)


def test_a_state_crossing_the_wrong_way_is_refused_with_the_reason() -> None:
    pb = StuartLandauProblem({"mu": 0.2})                # crossed rising: y < 0
    with pytest.raises(ShootingFailure, match="against the section's crossing direction"):
        pb.shooting.simulate(np.array([np.sqrt(0.2), 0.2]))


def test_the_family_ends_at_the_hopf_point() -> None:
    """Towards ``mu = 0`` the multiplier tends to 1 and the fixed point of the return map is
    set only to the integration error over ``1 - lambda ~ 4 pi mu``; the orbit shrinks onto the
    equilibrium, which lies on the section, and the branch ends there, named (it does not go
    on along the equilibrium into ``mu < 0``, where there is no periodic orbit)."""
    pb = StuartLandauProblem({"mu": 0.1, "integrator": {"rtol": RTOL, "atol": 1e-2 * RTOL}})
    res = nsm.continuation(pb, {"guess": {"y": -np.sqrt(0.1)}}, parameter="mu", min=-0.1,
                           max=0.1, max_points=200)
    b = res.branches[0]
    end = b.termination["backward"]
    assert "crossing direction" in end or "shrunk onto an equilibrium" in end
    mu = np.asarray(b["mu"], dtype=float)
    assert 0.0 < mu.min() < 1e-6
    radius, _, multiplier = closed_form_errors(b, 1)
    lam = np.exp(-4 * np.pi * mu)
    assert np.all(radius <= 10 * RTOL / (1 - lam))
    assert multiplier.max() < 100 * RTOL
    assert lam[np.argmin(mu)] > 1 - 1e-4
