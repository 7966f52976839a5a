"""Oracle tests of the hybrid layer: the saltation matrix (43), the bouncing ball (secs. 3.5,
4.2-4.4, eqs. 36-37, 47-50), the rank drop after sticking (sec. 4.4) and the monodromy against
finite differences of the simulated Poincaré map.

Paper: Nordmark & Piiroinen (2009). The printed closed form (48) has one wrong entry (row 4,
column 1: ``du/ds``); see :mod:`nsm_continuation.problems.impacting.bouncing_ball` for the
derivation, checked here three ways (chain of (47), explicit trajectory, simulator).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from helpers import CASES
from nsm_continuation.problems.impacting.bouncing_ball import (
    BouncingBallProblem,
    ball_chatter_jacobian,
    ball_extended_matrices,
    ball_pn_chain,
    ball_pn_closed_form,
    ball_system,
    closed_form,
    impact_times,
)
from oracles.bouncing_ball import ball_chatter_saltation

from nsm_continuation.hybrid.saltation import saltation_matrix
from nsm_continuation.hybrid.simulate import SimOptions, Simulator

G, E, S = 9.8, 0.8, 1.0                       # Fig. 4
V0 = -np.sqrt(2 * G * S)                      # first impact velocity v0'
T0 = np.sqrt(2 * S / G)                       # first impact time


def ref_impact_times(n: int) -> list[float]:
    return closed_form(G, E, S, n)["impact_times"]


# --------------------------------------------------------------------------- explicit ball
def explicit_extended(n: int, t: float) -> ca.Function:
    """``(s, w) -> (x1, x2, h, u)`` at the fixed time ``t`` in flight ``n`` (after ``n``
    impacts; ``n = 0``: before the first) of the explicit bouncing-ball trajectory."""
    s, w = ca.SX.sym("s"), ca.SX.sym("w")
    A = ca.sqrt(w**2 + 2 * G * s)              # |first impact velocity|
    if n == 0:
        x1 = s + w * t - G * t**2 / 2
        x2 = w - G * t
        u = A                                   # reconstructed "latest outgoing velocity"
    else:
        t0 = (w + A) / G
        tprev = t0 + 2 * A / G * sum(E**j for j in range(1, n))
        u = E**n * A
        tau = t - tprev
        x1 = u * tau - G * tau**2 / 2
        x2 = u - G * tau
    out = ca.vertcat(x1, x2, x1 / u, u)
    return ca.Function("ball", [ca.vertcat(s, w)], [out, ca.jacobian(out, ca.vertcat(s, w))])


def explicit_jacobian(n: int, t: float) -> np.ndarray:
    return np.asarray(explicit_extended(n, t)(np.array([S, 0.0]))[1], dtype=float)


@pytest.fixture(scope="module")
def ball():
    return ball_system().compile({"g": G, "e": E})


# --------------------------------------------------------------------------- saltation (43)
def test_saltation_matrix_builds_printed_D_k():
    """(47)'s D_k is (43) applied to the extended impact: E = R^ (h reset, u = v(R(x))),
    event function h, fields F^ before (u = -v_k') and after (u = -e v_k')."""
    _, D, _ = ball_extended_matrices(E, G, V0, 6)
    for k in range(6):
        vk_ = E**k * V0
        E_x = np.array([[1, 0, 0, 0], [0, -E, 0, 0], [0, 0, 0, 0], [0, -E, 0, 0]], float)
        B1 = np.array([vk_, -G, vk_ / (-vk_), 0.0])
        vp = -E * vk_
        B2 = np.array([vp, -G, vp / vp, 0.0])
        C = np.array([0, 0, 1.0, 0])
        Dk = saltation_matrix(E_x, np.zeros(4), B1, B2, C)
        np.testing.assert_allclose(Dk, D[k], rtol=1e-14, atol=1e-14)


def test_printed_P_k_and_P_0x_are_flow_jacobians():
    """(47)'s P_k is the Jacobian of the extended flow over 2 v_k / g; P_0x that of the state
    at the first impact w.r.t. the initial (s, w)."""
    P0x, _, P = ball_extended_matrices(E, G, V0, 5)
    np.testing.assert_allclose(explicit_jacobian(0, T0), P0x, rtol=1e-13, atol=1e-13)
    X = ca.SX.sym("X", 4)
    for k in range(1, 6):
        vk = E**k * abs(V0)
        tk = 2 * vk / G
        x1, x2, h, u = X[0], X[1], X[2], X[3]
        flow = ca.vertcat(x1 + x2 * tk - G * tk**2 / 2, x2 - G * tk,
                          h + (x2 * tk - G * tk**2 / 2) / u, u)
        Jf = ca.Function("Jf", [X], [ca.jacobian(flow, X)])
        np.testing.assert_allclose(np.asarray(Jf([0.0, vk, 0.0, vk])), P[k - 1],
                                   rtol=1e-13, atol=1e-13)


def test_event_parametrised_chain_is_the_saltation_product():
    """The simulator's update at an event (dtau = -(C J)/d, J <- J + B1 dtau,
    J_t <- J_t + dtau + e_x J, J <- E_x J) maps the time-fixed K = J - B1 J_t to
    K_new = J - B2 J_t = D K with D of (43) (module docstring of saltation.py)."""
    rng = np.random.default_rng(3)
    for n in (2, 4, 6):
        J, Jt = rng.normal(size=(n, n)), rng.normal(size=n)
        B1, B2, C, ex = (rng.normal(size=n) for _ in range(4))
        Ex = rng.normal(size=(n, n))
        dtau = -(C @ J) / (C @ B1)
        Jp = J + np.outer(B1, dtau)
        Jt_new = Jt + dtau + ex @ Jp
        K_new = Ex @ Jp - np.outer(B2, Jt_new)
        D = saltation_matrix(Ex, ex, B1, B2, C)
        np.testing.assert_allclose(K_new, D @ (J - np.outer(B1, Jt)), rtol=1e-10, atol=1e-10)


def test_saltation_rejects_grazing_event():
    with pytest.raises(ValueError, match="non-transversal"):
        saltation_matrix(np.eye(2), np.zeros(2), [1.0, 0.0], [1.0, 0.0], [0.0, 1.0])


# --------------------------------------------------------------------------- (47) -> (48)
@pytest.mark.parametrize("n", range(1, 13))
def test_chain_of_47_gives_corrected_48(n):
    """Chaining (47) n times equals the closed form (48) with the corrected (4,1) entry; the
    printed (4,1) entry -(g/v0') e^n (1 - e^n)/(1 - e) is wrong for n >= 2 (right: -(g/v0') e^n);
    every other printed entry is right."""
    chain = ball_pn_chain(E, G, V0, n)
    np.testing.assert_allclose(chain, ball_pn_closed_form(E, G, V0, n), rtol=1e-12, atol=1e-13)
    printed = ball_pn_closed_form(E, G, V0, n, as_printed=True)
    mask = np.ones_like(chain, dtype=bool)
    mask[3, 0] = False
    np.testing.assert_allclose(chain[mask], printed[mask], rtol=1e-12, atol=1e-13)
    assert chain[3, 0] == pytest.approx(-(G / V0) * E**n, rel=1e-12)
    if n >= 2:
        assert abs(printed[3, 0] - chain[3, 0]) > 1e-3 * abs(chain[3, 0])


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_48_from_the_explicit_trajectory(n):
    """p_n is the Jacobian of the extended state at the (reference) time of impact n: checked
    against the explicit trajectory (so the erratum is not an artefact of (47))."""
    t_n = ref_impact_times(n + 1)[n]
    np.testing.assert_allclose(explicit_jacobian(n, t_n), ball_pn_closed_form(E, G, V0, n),
                               rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("n", range(1, 13))
def test_simulator_jacobian_in_flight_n(ball, n):
    """The simulator's time-fixed J in flight n (after n impacts, chatter map held off) equals
    the derivative of the explicit trajectory and the flow after D_{n-1} p_{n-1} of (47)."""
    times = ref_impact_times(n + 1)
    opts = SimOptions(chatter_order=1, chatter_tol=1e-300)     # the map waits
    for frac in (0.37, 0.95):
        t_end = times[n - 1] + frac * (times[n] - times[n - 1])
        res = Simulator(ball, opts).run(np.array([S, 0.0]), t_end=t_end)
        assert res.n_impacts == n and not any(ev.kind == "chatter" for ev in res.events)
        J_exp = explicit_jacobian(n, t_end)[:2]
        np.testing.assert_allclose(res.J, J_exp, rtol=1e-8, atol=1e-8 * np.abs(J_exp).max())
        # the same from the paper's matrices: flow(tau) . D_{n-1} . p_{n-1}
        P0x, D, _ = ball_extended_matrices(E, G, V0, n)
        p_prev = ball_pn_chain(E, G, V0, n - 1) if n > 1 else P0x
        tau = t_end - times[n - 1]
        J_paper = np.array([[1.0, tau, 0, 0], [0, 1.0, 0, 0]]) @ D[n - 1] @ p_prev
        np.testing.assert_allclose(res.J, J_paper, rtol=1e-8, atol=1e-8 * np.abs(J_paper).max())
    # J_n = top rows of p_n (48): the Jacobian just before impact n
    res = Simulator(ball, opts).run(np.array([S, 0.0]), t_end=times[n] - 1e-10)
    assert res.n_impacts == n
    pn = ball_pn_closed_form(E, G, V0, n)[:2]
    np.testing.assert_allclose(res.J, pn, rtol=1e-8, atol=1e-8 * np.abs(pn).max())


# --------------------------------------------------------------------------- chatter, (50)
@pytest.mark.parametrize("order", [2, 3, 4])
def test_chatter_completion_time_exact(ball, order):
    """t* = sqrt(2s/g) + 2 e |v0'| / (g (1 - e)) (eq. 37) to 1e-12; after the map the state
    (0, 0) and its Jacobian w.r.t. the initial state vanish (eq. 50); the completion time's
    sensitivity is d t*/d(s, w) = ((1 + e)/(|v0'| (1 - e)), 1/g)."""
    cf = closed_form(G, E, S)
    res = Simulator(ball, SimOptions(chatter_order=order)).run(np.array([S, 0.0]), t_end=5.0)
    ch = [ev for ev in res.events if ev.kind == "chatter"]
    assert len(ch) == 1
    assert abs(ch[0].info["t_complete"] - cf["t_star"]) < 1e-12
    assert res.sticking_intervals[0][0] == pytest.approx(cf["t_star"], abs=1e-12)
    np.testing.assert_allclose(res.X, 0.0, atol=1e-15)
    np.testing.assert_allclose(res.J, 0.0, atol=1e-12)
    np.testing.assert_allclose(res.Jt, cf["dt_star"], rtol=1e-10)
    if order == 2:
        # the order-2 extrapolation (35) is exact for the ball: the first possible impact
        # (m + 1 = 3 first-order estimates) meets the tolerance at round-off
        assert ch[0].info["impacts"] == 2 and ch[0].info["error_estimate"] < 1e-13


@pytest.mark.parametrize("N", [2, 5, 15])
def test_eq_50_chatter_jacobian(N):
    """(50): D_N from (43) with the exact map (49) equals the printed D_N, and D_N p_N = 0."""
    D = ball_chatter_saltation(E, G, V0, N)
    np.testing.assert_allclose(D, ball_chatter_jacobian(E, N, V0), rtol=1e-14, atol=1e-14)
    pN = ball_pn_chain(E, G, V0, N)
    np.testing.assert_allclose(D @ pN, 0.0, atol=1e-12 * np.abs(pN).max())


def test_first_order_chatter_map_is_eq_36_37():
    """c.chatter's first-order map at random states is (36) (the v^2 term dropped) and adding
    the v^2 term of (37) gives X_5(x, v(x)) = (x1, 0, x3 + 2 e (-x2) / (g (1 - e)))."""
    c = ball_system(clock=True).compile({"g": G, "e": E})
    rng = np.random.default_rng(7)
    k = 2 * E / (G * (1 - E))
    for _ in range(20):
        x = rng.normal(size=3) * [0.5, 2.0, 3.0]
        Q1, q1, Q1x, q1x, r, rx = (np.asarray(z, dtype=float) for z in c.chatter(x))
        x1, x2, x3 = x
        np.testing.assert_allclose(Q1.ravel(), [x1 - k * x2**2, 0.0, x3 - k * x2],
                                   rtol=1e-13, atol=1e-13)
        X5 = Q1.ravel() + np.array([k * x2**2, 0.0, 0.0])
        np.testing.assert_allclose(X5, [x1, 0.0, x3 + k * (-x2)], rtol=1e-13, atol=1e-13)
        assert q1.item() == pytest.approx(-k * x2, rel=1e-13)
        np.testing.assert_allclose(Q1x, [[1, -2 * k * x2, 0], [0, 0, 0], [0, -k, 1]],
                                   rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(q1x.ravel(), [0, -k, 0], atol=1e-13)
        assert r.item() == pytest.approx(E) and np.allclose(rx, 0.0)


def test_bouncing_ball_problem_report():
    """The simulation case: 15 impacts resolved at the closed-form times (chatter_order 1,
    tolerance 0.02, Fig. 4's N = 15), completion time, (50) and the (48) erratum reported."""
    pb = BouncingBallProblem({"chatter_order": 1, "chatter_tol": 0.02})
    assert pb.start_points({}) == [] and pb.compiled is None
    with pytest.raises(NotImplementedError, match="simulation case"):
        pb.residual(None)
    out = pb.presentation.report_extras([])["bouncing_ball"]
    assert out["n_impacts_resolved"] == 15 == out["chatter_map"]["impacts_before_map"]
    assert out["impact_times_max_error"] < 1e-12
    assert abs(out["chatter_map"]["completion_time_error"]) < 1e-12
    np.testing.assert_allclose(out["chatter_map"]["jacobian_after_map"], 0.0, atol=1e-12)
    assert out["paper_eqs_47_50"]["chain_vs_closed_form_48_max_diff"] < 1e-10
    np.testing.assert_allclose(out["paper_eqs_47_50"]["D_N_times_p_N_eq_50"], 0.0, atol=1e-12)
    res = pb.simulate(record=True)
    np.testing.assert_allclose(impact_times(res), ref_impact_times(15), atol=1e-12)


# --------------------------------------------------------------------------- sec. 4.4, pendulum
Y61 = np.array([-1.14038278, -3.66533148, 0.23345446, 0.89])


@pytest.fixture(scope="module")
def pendulum():
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    pb = DoublePendulumProblem({"restitution": 0.89, "d": 0.5, "torque": -31.15})
    pb.set_parameter("restitution")
    return pb


@pytest.fixture(scope="module")
def pendulum_run(pendulum):
    """The 6.1 orbit simulated to its section, with the trajectory (impact times)."""
    c = pendulum.shooting.c
    opts = pendulum.integrator.options()
    opts.record = True
    sec = pendulum.shooting.section
    X0 = pendulum.shooting.x0(Y61)
    res = Simulator(c, opts).run(X0, section=(sec.index, sec.value + sec.shift, sec.direction))
    tr = res.trajectory
    imp = [tr[i][0] for i in range(1, len(tr))
           if tr[i][0] == tr[i - 1][0] and not np.array_equal(tr[i][1], tr[i - 1][1])
           and tr[i][0] < res.sticking_intervals[0][0]]
    t_map = next(ev.t for ev in res.events if ev.kind == "chatter")
    imp = [t for t in imp if t < t_map] + [t_map]
    return res, imp, X0


def _rows(c, X, J):
    gr = np.asarray(c.grads(X), dtype=float).reshape(3, -1)
    return gr[0, :4] @ J, gr[1, :4] @ J


def test_rank_drop_during_sticking(pendulum, pendulum_run):
    """Sec. 4.4: during sticking the time-fixed Jacobian of the full state has H_x P_x = 0 and
    v_x P_x = 0 (the state lies on the 2-dim sticking set {H = 0, v = 0} whatever the initial
    state): rank 2 on the 4-dim state."""
    res, _, X0 = pendulum_run
    c = pendulum.shooting.c
    t_mid = 0.5 * sum(res.sticking_intervals[0])
    r = Simulator(c, pendulum.integrator.options()).run(X0, t_end=t_mid)
    assert r.state == "s4"
    J = r.J[:4, :4]
    Hrow, vrow = _rows(c, r.X, J)
    nJ = np.linalg.norm(J)
    assert np.linalg.norm(Hrow) < 1e-12 * nJ and np.linalg.norm(vrow) < 1e-12 * nJ
    sv = np.linalg.svd(J, compute_uv=False)
    assert sv[1] > 1e-8 * sv[0] and sv[2] < 1e-13 * sv[0]


def test_section_map_multipliers_contain_zeros(pendulum, pendulum_run):
    """At the section (after sticking and release) the map factors through the release set,
    a curve in the sticking set (a = 0 there), and the event-defined end removes the time:
    the full 4x4 P_x has rank 1 and two of the three section multipliers are zero
    (round-off, ~1e-16), the third is the orbit's (-7.2e-4)."""
    mult = np.sort(np.abs(pendulum.floquet(Y61, None).multipliers))
    assert mult[0] < 1e-12 and mult[1] < 1e-12 and mult[2] > 1e-5
    res = pendulum.shooting.simulate(Y61)
    sv = np.linalg.svd(res.J[:4, :4], compute_uv=False)
    assert sv[1] < 1e-11 * sv[0]
    assert res.J[0, :4] == pytest.approx(np.zeros(4), abs=1e-14)   # q1 fixed on the section


def test_jacobian_before_the_chatter_map(pendulum, pendulum_run):
    """Postponing the map (t_end inside the chattering sequence, just before impact k): the
    H-row of the time-fixed Jacobian decays like r^k (H_x J_k -> 0) while the v-row converges
    to a nonzero limit; the map then sets the v-row to zero (previous test)."""
    res, imp, X0 = pendulum_run
    c = pendulum.shooting.c
    sim = Simulator(c, pendulum.integrator.options())
    r_ = 0.89
    ks = list(range(50, len(imp) - 1, 8)) + [len(imp) - 2]
    ratios, vnorms = [], []
    for k in ks:
        t_end = imp[k + 1] - 1e-3 * (imp[k + 1] - imp[k])
        rr = sim.run(X0, t_end=t_end)
        assert not any(ev.kind == "chatter" for ev in rr.events)
        Hrow, vrow = _rows(c, rr.X, rr.J[:4, :4])
        ratios.append(np.linalg.norm(Hrow) / r_**k)
        vnorms.append(np.linalg.norm(vrow))
    ratios, vnorms = np.array(ratios), np.array(vnorms)
    assert ratios.max() < 1.1 * ratios.min()                 # |H_x J_k| ~ C r^k
    assert vnorms.min() > 10.0 and vnorms.max() < 1.05 * vnorms.min()
    assert ratios[-1] * r_ ** ks[-1] < 1e-4 * vnorms[-1]      # H-row small, v-row not


# --------------------------------------------------------------------------- monodromy vs FD
def _fd_check(pb, y, step=1e-6, tol=1e-6):
    J = pb.jacobian(y)
    FD = np.zeros_like(J)
    for i in range(len(y)):
        dy = np.zeros(len(y))
        dy[i] = step
        FD[:, i] = (pb.evaluate(y + dy) - pb.evaluate(y - dy)) / (2 * step)
    assert np.all(np.isfinite(J))
    err = np.abs(FD - J).max()
    assert err < tol * max(1.0, np.abs(J).max()), (err, J, FD)
    return J


def test_monodromy_fd_pendulum(pendulum):
    assert np.abs(pendulum.evaluate(Y61)).max() < 1e-7
    _fd_check(pendulum, Y61)


@pytest.mark.parametrize("omega, sticking", [(0.45, True), (0.8, False)])
def test_monodromy_fd_impact_oscillator(omega, sticking):
    from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem

    pb = ImpactOscillatorProblem({"omega": omega})
    y = pb.start_points({"transient": 30})[0].y
    res = pb.shooting.simulate(y)
    assert bool(res.sticking_intervals) is sticking
    assert res.n_impacts >= 1
    _fd_check(pb, y, step=1e-6)
    _fd_check(pb, y, step=1e-7, tol=1e-6)


def test_ball_yaml_case_runs_with_zero_branches(tmp_path):
    """``nsm-continuation run yaml_cases/ball_fig1_fig4_chatter.yaml``: a simulation case with
    no branch; the results and the three figures are written."""
    import json

    from nsm_continuation import cli

    case = CASES / "ball_fig1_fig4_chatter.yaml"
    out = tmp_path / "ball"
    assert cli.main(["run", str(case), "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["branches"] == []
    bb = rep["problem_results"]["bouncing_ball"]
    assert bb["chatter_map"]["impacts_before_map"] == 15
    assert abs(bb["chatter_map"]["completion_time_error"]) < 1e-12
    for f in ("ball_fig1_position_velocity.png", "ball_fig3bc_H_h_tail.png",
              "ball_fig4_jacobian.png"):
        assert (out / f).stat().st_size > 1000
