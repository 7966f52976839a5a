"""Where the hybrid methods fail, and that every failure ends with a recorded reason (a
``SimulationError`` / ``ValueError`` with a checked message, a branch termination reason),
never a hang: near grazing, incomplete chattering, restitution near 0 and near 1, tiny impact
velocities, the wall-clock guard, Newton near a homoclinic orbit, bad declarations.

Nordmark & Piiroinen (2009): grazing (sec. 6.1), incomplete chattering (secs. 5.2, 6.1),
``0 <= r <= 1`` (eq. 9, sec. 3; ``r = 1`` elastic, no chatter map), transversality of W
(sec. 2.4), homoclinic orbit (sec. 6.3).
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.impacting.bouncing_ball import (
    BouncingBallProblem,
    ball_system,
    closed_form,
)
from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem
from scipy.integrate import solve_ivp

from nsm_continuation.hybrid.simulate import SimOptions, SimulationError, Simulator
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem

G = 9.8


def ball(e: float):
    return ball_system().compile({"g": G, "e": e})


# --------------------------------------------------------------------------- near grazing
ZETA, OMEGA = 0.1, 0.8
Q_MIN, PHASE_MIN = -0.5, 0.0           # local minimum of q: qdot = 0, a = -q + cos = 1.5 > 0
A_MIN = -Q_MIN + np.cos(PHASE_MIN)


@pytest.fixture(scope="module")
def grazing_start():
    """A state one time unit before the free flow's local minimum ``q = -0.5`` (the impact
    oscillator's flow does not depend on the gap, so the gap sets the depth of the dip)."""

    def f(t, x):
        return [x[1], -x[0] - 2 * ZETA * x[1] + np.cos(x[2]), OMEGA]

    sol = solve_ivp(f, (0.0, -1.0), [Q_MIN, 0.0, PHASE_MIN], method="DOP853", rtol=1e-13,
                    atol=1e-15)
    return sol.y[:, -1]


def oscillator(sigma: float):
    pb = ImpactOscillatorProblem({"omega": OMEGA, "zeta": ZETA})
    return pb.hybrid.compile({"zeta": ZETA, "omega": OMEGA, "gap": sigma, "restitution": 0.6})


class StepLog(Simulator):
    """Records every step attempted from the phase it starts at (dip inside one step?)."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.log: list[tuple[str, float, float, float, float]] = []

    def _step(self, key, Y, dt, jac):
        out = super()._step(key, Y, dt, jac)
        self.log.append((key, float(Y[2]), float(dt), float(Y[0]), float(out[0][0])))
        return out


def test_grazing_miss_by_1e9_no_impact(grazing_start):
    """min q is 1e-9 above the wall: no impact, a near approach with H = 1e-9."""
    c = oscillator(Q_MIN - 1e-9)
    for opts in (SimOptions(), SimOptions(h_init=1.0)):
        res = Simulator(c, opts).run(grazing_start, t_end=1.5)
        assert res.n_impacts == 0 and not any(ev.kind == "impact" for ev in res.events)
        near = [ev for ev in res.events if ev.kind == "near_approach"]
        assert len(near) == 1 and near[0].info["H"] == pytest.approx(1e-9, abs=2e-12)
        assert res.grazing_margin == pytest.approx(1e-9, abs=2e-12)


@pytest.mark.parametrize("depth", [1e-9, 1e-7, 1e-5])
def test_grazing_dip_inside_one_step_is_found(grazing_start, depth):
    """min q is ``depth`` below the wall: an impact with velocity sqrt(2 a depth) is recorded,
    although the whole dip (width ~2 sqrt(2 depth / a)) lies inside one attempted step whose
    two ends are off the wall (the cubic Hermite interpolant's O(dt^4) error, ~1e-5 here, hides
    the dip from the H test; the v turn with H < 0 recovers it)."""
    c = oscillator(Q_MIN + depth)
    half = np.sqrt(2 * depth / A_MIN) * OMEGA        # half width of the dip in phase
    for opts in (SimOptions(), SimOptions(h_init=1.0)):
        sim = StepLog(c, opts)
        res = sim.run(grazing_start, t_end=1.5)
        imp = [ev for ev in res.events if ev.kind == "impact"]
        assert len(imp) == 1
        assert abs(imp[0].info["v"]) == pytest.approx(np.sqrt(2 * A_MIN * depth), rel=1e-3)
        assert res.n_impacts == 1
        assert res.grazing_margin == pytest.approx(-depth, rel=1e-3, abs=3e-12)
        spanning = [s for s in sim.log if s[0] == "free" and s[1] < PHASE_MIN - half
                    and s[1] + OMEGA * s[2] > PHASE_MIN + half
                    and s[3] > Q_MIN + depth and s[4] > Q_MIN + depth]
        assert spanning, "the dip was not inside one step: the test does not test the guard"


# --------------------------------------------------------------------------- incomplete chattering
def test_transition_to_incomplete_chattering():
    """Impact oscillator (zeta = 0.1, e = 0.6): at omega = 0.45 the period-1 orbit chatters
    completely and sticks; at omega = 0.62 the chattering breaks off (events chatter_broken,
    no sticking, no chatter map)."""
    pb = ImpactOscillatorProblem({"omega": 0.45})
    res = pb.shooting.simulate(pb.start_points({"transient": 30})[0].y)
    kinds = [ev.kind for ev in res.events]
    assert "chatter" in kinds and "release" in kinds and res.sticking_time > 0.1
    pb = ImpactOscillatorProblem({"omega": 0.62})
    res = pb.shooting.simulate(pb.start_points({"transient": 30})[0].y)
    kinds = [ev.kind for ev in res.events]
    assert "chatter_broken" in kinds and "chatter" not in kinds
    # incomplete chattering: every impact of the broken-off sequence is one ``I``
    assert res.sticking_intervals == [] and res.signature == "I" * res.n_impacts
    assert res.n_impacts >= 2


# --------------------------------------------------------------------------- restitution extremes
def test_plastic_impact_sticks_immediately():
    res = Simulator(ball(0.0)).run(np.array([1.0, 0.0]), t_end=2.0)
    assert [ev.kind for ev in res.events] == ["impact", "plastic_stick"]
    t0 = closed_form(G, 0.0, 1.0)["t0"]
    assert res.events[1].t == pytest.approx(t0, abs=1e-12)
    assert res.sticking_intervals[0][0] == pytest.approx(t0, abs=1e-12)
    np.testing.assert_allclose(res.X, 0.0, atol=1e-15)
    np.testing.assert_allclose(res.J, 0.0, atol=1e-15)


def test_tiny_restitution_completes():
    e = 1e-6
    # written at the former simulator default, order 2 (at order 3 the fourth impact
    # velocity, ~1e-18 |v0'|, is below round-off and the sequence ends by plastic_stick)
    res = Simulator(ball(e), SimOptions(chatter_order=2)).run(np.array([1.0, 0.0]),
                                                               t_end=2.0)
    ch = [ev for ev in res.events if ev.kind == "chatter"]
    assert len(ch) == 1 and res.state == "s4"
    assert ch[0].info["t_complete"] == pytest.approx(closed_form(G, e, 1.0)["t_star"],
                                                     abs=1e-12)


def test_restitution_near_one():
    """e = 0.99: the sequence lasts ~90 time units. The order-2 map (exact for the ball)
    converges; the first-order map needs ~1400 impacts and, capped at 30, ends with the
    recorded reason."""
    e = 0.99
    t_star = closed_form(G, e, 1.0)["t_star"]
    res = Simulator(ball(e), SimOptions(chatter_order=2)).run(np.array([1.0, 0.0]),
                                                               t_end=t_star + 1)
    ch = [ev for ev in res.events if ev.kind == "chatter"]
    assert len(ch) == 1 and ch[0].info["t_complete"] == pytest.approx(t_star, abs=1e-9)
    with pytest.raises(SimulationError, match="without meeting the chatter map's tolerance"):
        Simulator(ball(e), SimOptions(chatter_order=1, max_chatter_impacts=30)).run(
            np.array([1.0, 0.0]), t_end=t_star + 1)


def test_restitution_one_or_more_rejected():
    for e in (1.0, 1.5):
        with pytest.raises(ValueError, match=r"(?s)\brestitution\b.*less than 1"):
            BouncingBallProblem({"restitution": e})
        with pytest.raises(ValueError, match=r"(?s)\brestitution\b.*less than 1"):
            ImpactOscillatorProblem({"restitution": e})
    # a system compiled with r > 1 anyway is stopped at its first impact (eq. 9)
    with pytest.raises(HybridDeclarationError, match="restitution r = 1.5"):
        Simulator(ball(1.5)).run(np.array([1.0, 0.0]), t_end=1.0)


def test_elastic_ball_bounces_to_its_height_and_refuses_chattering_at_rest():
    """r = 1 is an elastic impact: released from rest at s = 1 the ball hits the floor at
    sqrt(2 s / g) and every 2 sqrt(2 s / g) after, with the speed sqrt(2 g s) each time (no
    accumulation, no chatter map); arriving on the floor at a round-off speed (a = -g < 0)
    the elastic 'sequence' of bounces would never end: refused, named."""
    res = Simulator(ball(1.0), SimOptions(rtol=1e-12, atol=1e-14)).run(
        np.array([1.0, 0.0]), t_end=10.0)
    t_fall = np.sqrt(2.0 / G)
    impacts = [ev for ev in res.events if ev.kind == "impact"]
    assert len(impacts) == int((10.0 + t_fall) / (2 * t_fall))
    for k, ev in enumerate(impacts):
        assert ev.t == pytest.approx((2 * k + 1) * t_fall, abs=1e-10)
        assert abs(ev.info["v"]) == pytest.approx(np.sqrt(2 * G), rel=1e-10)
    assert not any(ev.kind in ("chatter", "chatter_broken") for ev in res.events)
    with pytest.raises(SimulationError, match="chattering at r = 1"):
        Simulator(ball(1.0)).run(np.array([0.0, -1e-11]), t_end=1.0)


# --------------------------------------------------------------------------- tiny velocities
def test_start_on_surface_with_round_off_velocity_sticks():
    """x = (0, -1e-12): on the sticking set to round-off; the ball stays there."""
    res = Simulator(ball(0.8)).run(np.array([0.0, -1e-12]), t_end=1.0)
    assert res.state == "s4"
    np.testing.assert_allclose(res.X, 0.0, atol=1e-11)


def test_tiny_impact_velocity_from_tiny_height():
    """Released from 1e-10: impact velocity 4.4e-5, chattering completes at the closed-form
    time (a sequence 1e5 times faster than the s = 1 one)."""
    s = 1e-10
    # chatter_order 2: the order these numbers are computed at
    res = Simulator(ball(0.8), SimOptions(chatter_order=2)).run(np.array([s, 0.0]), t_end=1.0)
    ch = [ev for ev in res.events if ev.kind == "chatter"]
    assert len(ch) == 1 and res.state == "s4"
    assert ch[0].info["t_complete"] == pytest.approx(closed_form(G, 0.8, s)["t_star"],
                                                     rel=1e-9)


def test_start_on_surface_moving_in_impacts():
    # chatter_order 2: the former simulator default, at which this case was checked
    res = Simulator(ball(0.8), SimOptions(chatter_order=2)).run(np.array([0.0, -1e-9]),
                                                                 t_end=1.0)
    assert res.X[0] >= -1e-12
    assert res.state == "s4" and res.n_impacts >= 1


# --------------------------------------------------------------------------- guards
def test_wall_clock_guard():
    pb = ImpactOscillatorProblem({"omega": 0.8})
    t0 = time.perf_counter()
    with pytest.raises(SimulationError, match="wall-clock"):
        Simulator(pb.shooting.c, SimOptions(wall_time=1e-3)).run(
            np.array([1.0, 0.0, 0.0, 0.8]), t_end=1e5)
    assert time.perf_counter() - t0 < 5.0


def test_newton_near_homoclinic_orbit_ends_with_a_reason():
    """Sec. 6.3 (e = 0.9, d = 0.5): continuing the period-1 orbit in the torque from -31.09
    towards -31.0017, the period grows without bound; predictor steps beyond the homoclinic
    parameter land where the orbit is trapped at a stable sticking equilibrium (the simulation
    fails with a reason and Newton retreats). The branch must end with a homoclinic_approach
    event (the period bound) or a termination reason, never an exception."""
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    from nsm_continuation.core.palc import ContinuationEngine
    from nsm_continuation.core.settings import ContinuationSettings

    pb = DoublePendulumProblem({"restitution": 0.9, "d": 0.5, "torque": -31.09,
                                "integrator": {"wall_time": 2.0}})
    pb.set_parameter("torque")
    # from the 6.1 orbit's section state (the default initial state sticks for ever here)
    start = pb.start_points({"transient": 10,
                             "initial": {"q2": -1.14, "q1dot": -3.67, "q2dot": 0.23}})[0]
    assert pb.derived(start.y)["period"] == pytest.approx(7.26, abs=0.02)   # paper: ~7.25
    settings = ContinuationSettings(param_min=-31.1, param_max=-31.0, max_points=40,
                                    step_initial=0.01, step_max=0.02, newton_tol=1e-9,
                                    direction=1, derived_bounds={"period": (None, 40.0)})
    t0 = time.perf_counter()
    br = ContinuationEngine(pb, settings).run(start)
    assert time.perf_counter() - t0 < 45.0
    kinds = [ev.kind for ev in br.events]
    assert "homoclinic_approach" in kinds or br.termination
    assert all(isinstance(v, str) and v for v in br.termination.values())
    if "homoclinic_approach" in kinds:
        ev = br.events[kinds.index("homoclinic_approach")]
        # the homoclinic torque of sec. 6.3 is -31.00166609425
        assert ev.point.y[-1] == pytest.approx(-31.0017, abs=2e-4)


#: the period-1 orbit of sec. 6.3 at torque -31.09 on the section q1 = pi/2
HOMOCLINIC_GUESS = {"q2": -1.1351634, "q1dot": -3.65803681, "q2dot": 0.2554524}


def test_homoclinic_torque_from_the_period_continuation():
    """The homoclinic torque of sec. 6.3 (the paper's saddle at -31.00166609425), guarded by
    the well-conditioned formulation: the period prescribed (7.26 -> 50), the torque solved
    for (``continuation.parameter: period``), the law ``p - p* = a exp(-mu T) + ...`` fitted
    (:func:`~nsm_continuation.hybrid.homoclinic.homoclinic_fit`) and extrapolated to p*.
    At the default tolerances (rtol = chatter_tol = 1e-10) the last periodic torque found by
    bisection on direct simulations is -31.0016660945425 (benchmarks/README.md); converged
    (rtol <= 1e-12, chatter_tol <= 1e-12) p* = -31.0016660941 (tests/hybrid/test_homoclinic.py,
    the bundled case): all within 1e-9 of the paper's torque."""
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    from nsm_continuation.core.palc import ContinuationEngine
    from nsm_continuation.core.settings import ContinuationSettings
    from nsm_continuation.hybrid.homoclinic import homoclinic_fit

    pb = DoublePendulumProblem({"restitution": 0.9, "d": 0.5, "torque": -31.09})
    pb.parameter_bounds("period", 7.0, 50.0)
    (start,) = pb.start_points({"guess": HOMOCLINIC_GUESS, "free_parameter": "torque",
                                "direction": "increase"})
    settings = ContinuationSettings(param_min=7.0, param_max=50.0, max_points=40,
                                    step_initial=0.5, step_max=3.0, newton_tol=1e-9,
                                    direction=1, event_tol=1e-9)
    t0 = time.perf_counter()
    br = ContinuationEngine(pb, settings).run(start)
    assert time.perf_counter() - t0 < 45.0
    assert br.termination == {"forward": "bound: period = max"}
    assert sorted(ev.kind for ev in br.events) == ["endpoint", "homoclinic_approach"]
    p = np.array([q.y[3] for q in br.points])
    T = np.array([q.derived["period"] for q in br.points])
    assert np.all(np.diff(p) > 0) and T[-1] == pytest.approx(50.0, abs=1e-6)
    fit = homoclinic_fit(p, T)
    assert fit is not None
    assert fit["p_star"] == pytest.approx(-31.00166609425, abs=1e-9)       # the paper
    assert fit["p_star"] == pytest.approx(-31.0016660945425, abs=1e-9)     # bisection
    assert fit["mu_unstable"] == pytest.approx(0.28879, rel=1e-3)


# --------------------------------------------------------------------------- declarations
def test_mass_matrix_not_positive_definite():
    q, qd, g = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("g")
    sysm = HybridSystem.mechanical("bad", q, qd, {"g": g}, ca.SX(-1.0), -g, q, 0.5)
    c = sysm.compile({"g": G})
    with pytest.raises(HybridDeclarationError, match="not positive definite"):
        c.mass_check(np.array([1.0, 0.0]))
    with pytest.raises(HybridDeclarationError, match="not positive definite"):
        Simulator(c).run(np.array([1.0, 0.0]), t_end=1.0)


def test_constant_mass_matrix_is_checked_at_every_parameter_set():
    """A mass matrix independent of ``q`` is checked once per parameter set, not once for
    all: a freed mass that turns negative is still refused (and a positive one passes at
    every state)."""
    q, qd, m = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("m")
    sysm = HybridSystem.mechanical("mass", q, qd, {"m": m}, m, -q, q + 1.0, 0.5)
    c = sysm.compile({}, free=["m"])
    c.mass_check(np.array([0.3, 0.0, 1.0]))
    c.mass_check(np.array([-0.7, 2.0, 1.0]))
    with pytest.raises(HybridDeclarationError, match="not positive definite"):
        c.mass_check(np.array([0.3, 0.0, -1.0]))


def test_W_not_tangent_rejected_at_first_impact():
    """A custom impact law that moves the position (L_W H = 0.1 != 0, sec. 2.4)."""
    x = ca.SX.sym("x", 2)
    e = 0.5
    sysw = HybridSystem("bad_W", x, {}, ca.vertcat(x[1], -G), x[0],
                        ca.vertcat(0.1, -(1 + e)), ["x1", "x2"])
    c = sysw.compile({})
    with pytest.raises(HybridDeclarationError, match="not tangent"):
        Simulator(c).run(np.array([1.0, 0.0]), t_end=1.0)
    with pytest.raises(HybridDeclarationError, match="not tangent"):
        c.validate_at(np.array([0.0, -1.0]), "here")


def test_H_independent_of_state_rejected():
    x = ca.SX.sym("x", 2)
    p = ca.SX.sym("p")
    with pytest.raises(HybridDeclarationError, match="does not depend on the state"):
        HybridSystem("no_surface", x, {"p": p}, ca.vertcat(x[1], -G), p + 1.0,
                     ca.vertcat(0, -2.0), ["x1", "x2"])


def test_chatter_estimate_round_off_floor_near_loss_of_sticking():
    """Near e* the chatter map's error estimate stalls above a tight chatter_tol (round-off,
    a -> 0). The map must still be applied (floor recorded), never skipped until round-off
    breaks the sequence into a wrong, unflagged orbit. Oracle: every order gives the same
    sticking time and a converged orbit."""
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    y = np.array([-1.1403809635651985, -3.665330511373152, 0.23345989973542672, 0.894463])
    taus = []
    for order in (2, 4):
        pb = DoublePendulumProblem({"restitution": 0.894463, "integrator": {
            "rtol": 1e-12, "atol": 1e-14, "chatter_tol": 1e-12, "chatter_order": order,
            "wall_time": 20.0}})
        res = pb.shooting.simulate(y)
        assert res.sticking_time > 1e-3
        assert np.abs(pb.evaluate(y)).max() < 1e-8
        taus.append(res.sticking_time)
    assert abs(taus[0] - taus[1]) < 1e-8


def test_turning_lower_bar_periodic_modulo_two_pi():
    """Sec. 6.2: over two revolutions of the upper bar the lower bar turns too, so q2 returns
    modulo 2 pi. The shooting residual wraps it: at the period-2 orbit (d = 0.5009, found by
    simulation and Newton in this session) the residual vanishes although q2 itself has moved
    by a multiple of 2 pi."""
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    pb = DoublePendulumProblem({"restitution": 0.19, "torque": -40.0, "d": 0.5009})
    pb.set_parameter("d", returns=2)
    y = np.array([-1.70463256, -5.01976446, -3.28324432, 0.5009])
    res = pb.shooting.simulate(y)
    turned = (res.X[1] - y[0]) / (2 * np.pi)
    assert abs(turned) > 0.5 and abs(turned - round(turned)) < 1e-6
    assert np.abs(pb.evaluate(y)).max() < 1e-6


def test_start_at_rest_where_the_force_balances_still_sees_the_impact() -> None:
    """The forced oscillator from its default start (q, q') = (gap + 1, 0) at phase 0, where
    v = a = jerk = 0 (the force -q + cos(0) balances): the flight falls onto the stop, and the
    first impact is where an independent ``solve_ivp`` meets ``q = gap`` (not missed: the
    flight is not taken for one moving away, and q does not pass through the stop)."""
    import dataclasses

    import nsm_continuation as nsm

    omega, zeta = 2.5, 0.1
    pb = nsm.problem("impact_oscillator", {"zeta": zeta, "omega": omega, "gap": 0.0,
                                           "restitution": 0.6})
    pb.set_parameter("omega")
    sim = Simulator(pb.shooting.c, dataclasses.replace(pb.shooting.sim.o, sensitivities=False))
    res = sim.run(np.array([1.0, 0.0, 0.0, omega]), section=(2, 2 * np.pi, 1))
    first = next(e for e in res.events if e.kind == "impact")

    def stop(t: float, x: np.ndarray) -> float:
        return x[0]

    stop.terminal, stop.direction = True, -1.0  # type: ignore[attr-defined]
    sol = solve_ivp(lambda t, x: [x[1], -x[0] - 2 * zeta * x[1] + np.cos(omega * t)],
                    (0.0, 10.0), [1.0, 0.0], method="DOP853", rtol=1e-12, atol=1e-13,
                    events=stop)
    assert first.t == pytest.approx(float(sol.t_events[0][0]), abs=1e-8)
    assert res.extremes is None or res.extremes[0, 0] >= -1e-9


@pytest.mark.parametrize("depth", [1e-7, 1e-5])
def test_grazing_dip_found_when_a_parallel_surface_turns_first(grazing_start, depth):
    """The same dip with a second, parallel stop far above (``q <= 10``, declared first): at
    the dip both surfaces' ``v`` turn at one instant and the far stop's turn is the crossing
    found first; the impact inside the dip is still located (not recorded as a near approach
    of the lower stop with ``H < 0``), with velocity ``sqrt(2 a depth)``."""
    q, qd, ph = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase")
    p = {"omega": ca.SX.sym("omega")}
    force = -q - 2 * ZETA * qd + ca.cos(ph)
    sys = HybridSystem.mechanical("two_stops", q, qd, p, ca.SX(1.0), force,
                                  [10.0 - q, q - (Q_MIN + depth)], 0.6,
                                  surfaces=["far", "near"], clock=ph, clock_rate=p["omega"])
    c = sys.compile({"omega": OMEGA})
    for opts in (SimOptions(), SimOptions(h_init=1.0)):
        res = Simulator(c, opts).run(grazing_start, t_end=1.5)
        imp = [ev for ev in res.events if ev.kind == "impact"]
        assert len(imp) == 1 and imp[0].surface == 1
        assert abs(imp[0].info["v"]) == pytest.approx(np.sqrt(2 * A_MIN * depth), rel=1e-3)
        assert all(ev.info["H"] >= 0 for ev in res.events if ev.kind == "near_approach")
