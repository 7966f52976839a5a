"""The exact flow of systems linear between events (:mod:`nsm_continuation.hybrid.linear_flow`).

Oracles: the Runge-Kutta step of the same compiled system (a short DOP853 step is exact to
rounding: its local error is ``O(dt^9)``), finite differences of the exact step, the closed-form
free flight of the forced oscillator (:mod:`tests.oracles.linear_flight`, written independently),
and the Runge-Kutta path through whole simulations and continuations of the bundled
piecewise-linear problems (impact oscillator, two-mass chain), which must agree with the exact
path to the Runge-Kutta tolerance. Refusals are checked to name their cause.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem
from nsm_continuation.problems.impacting.two_mass_chain import TwoMassChainProblem
from oracles.linear_flight import free_flight

import nsm_continuation as nsm
from nsm_continuation.hybrid.case import IntegratorSpec
from nsm_continuation.hybrid.simulate import SimOptions, SimulationError, Simulator
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem


def oscillator(force_of=None, zeta: float = 0.1) -> HybridSystem:
    """``q'' = force(q, qd, phase)`` (default ``-q - 2 zeta qd + cos(phase)``), ``q >= gap``,
    ``phase' = omega``."""
    q, qd, ph = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase")
    p = {k: ca.SX.sym(k) for k in ("omega", "gap", "zeta")}
    force = (-q - 2 * p["zeta"] * qd + ca.cos(ph)) if force_of is None else force_of(q, qd, ph,
                                                                                    p)
    return HybridSystem.mechanical("osc", q, qd, p, ca.SX(1.0), force, q - p["gap"], 0.8,
                                   clock=ph, clock_rate=p["omega"])


def chain3() -> HybridSystem:
    """Three unit masses and springs, damping 0.05, the first forced by ``cos(phase) +
    0.3 sin(2 phase) + 0.1`` (two harmonics and a constant), the last at a wall."""
    q, qd, ph = ca.SX.sym("q", 3), ca.SX.sym("qd", 3), ca.SX.sym("phase")
    p = {"omega": ca.SX.sym("omega")}
    f = ca.vertcat(-2 * q[0] + q[1] + ca.cos(ph) + 0.3 * ca.sin(2 * ph) + 0.1,
                   q[0] - 2 * q[1] + q[2], q[1] - q[2]) - 0.05 * qd
    return HybridSystem.mechanical("chain3", q, qd, p, ca.SX.eye(3), f, 0.5 - q[2], 0.8,
                                   clock=ph, clock_rate=p["omega"])


CASES = {
    "oscillator": (lambda: oscillator(), {"gap": -1.0, "zeta": 0.1}),
    "two harmonics": (chain3, {}),
}


def random_state(N: int, seed: int = 1) -> np.ndarray:
    Y = np.random.default_rng(seed).normal(size=N)
    Y[-1] = 0.83                                # the freed omega
    return Y


def split(flat: np.ndarray, N: int, npr: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State, probe + field, Jacobian of a step Function's flat output (the Runge-Kutta
    step's Jacobians of its error estimates follow; not compared)."""
    i = 4 * N + npr
    return flat[:N], flat[3 * N: i], flat[i:i + N * N].reshape(N, N, order="F")


@pytest.mark.parametrize("case", sorted(CASES))
def test_exact_step_equals_a_short_runge_kutta_step(case: str) -> None:
    """A DOP853 step of 0.02 is exact to rounding: the exact step's state, probe, field and
    Jacobian (the freed omega's column included) agree with it at 1e-13."""
    build, values = CASES[case]
    system = build()
    exact = system.compile(values, free=["omega"], method="exact")
    rk = system.compile(values, free=["omega"], method="dop853")
    assert exact.flow == "exact" and rk.flow == "dop853"
    N, npr = exact.N, 4
    Y = random_state(N)
    for dt in (0.02, 0.013):
        a = split(exact.calls().steps["free"][1].flat(Y, dt), N, npr)
        b = split(rk.calls().steps["free"][1].flat(Y, dt), N, npr)
        for x, y in zip(a, b, strict=True):
            assert np.max(np.abs(x - y)) <= 1e-13 * max(1.0, np.max(np.abs(y)))
        assert np.max(np.abs(a[2][:, -1])) > 1e-3      # the omega column is not trivially 0


def test_long_exact_step_equals_composed_runge_kutta_steps() -> None:
    """Over 1.7 time units, the exact step and its Jacobian equal the composition of 85 short
    Runge-Kutta steps (the chain rule of their Jacobians) to 1e-12."""
    system = chain3()
    exact = system.compile({}, free=["omega"], method="exact")
    rk = system.compile({}, free=["omega"], method="dop853")
    N = exact.N
    Y = random_state(N, 3)
    Yn, _pf, J = split(exact.calls().steps["free"][1].flat(Y, 1.7), N, 4)
    Z, JZ = Y.copy(), np.eye(N)
    for _ in range(85):
        z, _pf, Jz = split(rk.calls().steps["free"][1].flat(Z, 0.02), N, 4)
        Z, JZ = z, Jz @ JZ
    assert np.max(np.abs(Yn - Z)) <= 1e-12 * np.max(np.abs(Z))
    assert np.max(np.abs(J - JZ)) <= 1e-12 * np.max(np.abs(JZ))


def test_exact_step_matches_the_closed_form_oscillator() -> None:
    """The forced oscillator's flight written out independently (tests.oracles.linear_flight)
    over a long step (12 time units, a phase not at 0)."""
    zeta, omega = 0.1, 0.77
    c = oscillator().compile({"gap": -5.0, "zeta": zeta}, free=["omega"], method="exact")
    q0, v0, t0 = 0.3, -0.4, 1.1
    Y = np.array([q0, v0, omega * t0, omega])
    Yn = c.calls().steps["free"][0].flat(Y, 12.0)[:4]
    q, v = free_flight(np.array([t0 + 12.0]), t0, q0, v0, zeta, omega)
    assert abs(Yn[0] - q[0]) <= 1e-13 and abs(Yn[1] - v[0]) <= 1e-13


def test_exact_jacobian_matches_finite_differences() -> None:
    """Every column of the exact step's Jacobian (state, phase, omega) against central
    differences of the exact step."""
    system = chain3()
    c = system.compile({}, free=["omega"], method="exact")
    N = c.N
    step = c.calls().steps["free"]
    Y = random_state(N, 5)
    dt = 2.3
    J = split(step[1].flat(Y, dt), N, 4)[2]
    h = 1e-6
    for j in range(N):
        e = np.zeros(N)
        e[j] = h
        fd = (step[0].flat(Y + e, dt)[:N] - step[0].flat(Y - e, dt)[:N]) / (2 * h)
        assert np.max(np.abs(fd - J[:, j])) <= 1e-8 * (1 + np.max(np.abs(fd)))


@pytest.mark.parametrize(("force_of", "free", "words"), [
    (lambda q, qd, ph, p: -q - 0.2 * q ** 3 + ca.cos(ph), ["omega"],
     "not linear in the state (it is nonlinear in 'q1')"),
    (lambda q, qd, ph, p: -q - 0.2 * qd + ca.cos(ph) + ca.cos(np.sqrt(2) * ph), ["omega"],
     "not a sum of harmonics of the clock"),
    (lambda q, qd, ph, p: -q - 2 * p["zeta"] * qd + ca.cos(ph), ["omega", "zeta"],
     "the freed parameter 'zeta' enters the vector field"),
    (lambda q, qd, ph, p: -q + ca.cos(ph), [], "resonates with the eigenvalue"),
    (lambda q, qd, ph, p: -0.1 * qd + ca.cos(ph), ["omega"], "singular"),
    (lambda q, qd, ph, p: ca.cos(ph) + 0 * q, ["omega"], "defective"),
    (lambda q, qd, ph, p: -(1 + 0.3 * ca.cos(ph)) * q - 0.1 * qd, ["omega"],
     "parametric excitation"),
])
def test_refusals_name_their_cause(force_of, free: list[str], words: str) -> None:
    """``exact`` refuses a system that is not linear between events with the reason; ``auto``
    falls back to DOP853 and keeps the reason (reported)."""
    system = oscillator(force_of)
    values = {k: v for k, v in {"omega": 1.0, "gap": -1.0, "zeta": 0.1}.items() if k not in free}
    with pytest.raises(HybridDeclarationError, match="integrator 'exact'") as err:
        system.compile(values, free=free, method="exact")
    assert words in str(err.value)
    auto = system.compile(values, free=free, method="auto")
    assert auto.flow == "dop853" and words in auto.flow_note
    assert words in auto.flow_description()


def test_resonance_of_a_freed_frequency_ends_the_simulation_with_its_reason() -> None:
    """Undamped oscillator continued in omega: at omega = 1 the particular solution does not
    exist; the simulation ends with a SimulationError naming the resonance (not a NaN)."""
    c = oscillator().compile({"gap": -5.0, "zeta": 0.0}, free=["omega"], method="exact")
    with pytest.raises(SimulationError, match="resonates with the eigenvalue"):
        Simulator(c).run(np.array([0.1, 0.0, 0.0, 1.0]), t_end=1.0)


@pytest.mark.parametrize("depth", [1e-7, -1e-7])
def test_a_shallow_grazing_contact_is_seen(depth: float) -> None:
    """Undamped oscillator on its free periodic orbit ``q = cos(omega t) / (1 - omega^2)``
    with the stop ``1e-7`` inside (an impact) or outside (a near approach) its minimum: the
    exact path's long steps still see the contact (certified clear of zero elsewhere)."""
    omega = 1.5
    amp = 1.0 / abs(1.0 - omega ** 2)           # q = -amp cos(omega t): minimum -amp at t = 0
    gap = -amp + depth
    c = oscillator().compile({"gap": gap, "zeta": 0.0}, free=["omega"], method="exact")
    # start half a period before the minimum, at the maximum, moving down
    X0 = np.array([amp, 0.0, np.pi, omega])
    res = Simulator(c, SimOptions(sensitivities=False)).run(X0, t_end=1.5 * np.pi / omega)
    kinds = [e.kind for e in res.events]
    assert kinds[:1] == (["impact"] if depth > 0 else ["near_approach"])
    if depth < 0:
        assert res.events[0].info["H"] == pytest.approx(-depth, rel=1e-6)
    assert res.n_steps < 12


def orbit_pair(problem, params: dict, transient: int) -> tuple:
    """The same periodic orbit's return map evaluated by both paths."""
    rk = problem({**params, "integrator": {"method": "dop853"}})
    ex = problem({**params, "integrator": {"method": "exact"}})
    y = rk.start_points({"transient": transient})[0].y
    return rk, ex, y


@pytest.mark.parametrize(("problem", "params"), [
    (ImpactOscillatorProblem, {}),                                     # chattering, sticking
    (ImpactOscillatorProblem, {"zeta": 0.0, "omega": 1.5, "gap": -0.5, "restitution": 0.8,
                               "section_phase": np.pi}),
    (TwoMassChainProblem, {"omega": 0.6}),
])
def test_return_map_of_both_paths_agree(problem, params: dict) -> None:
    """Residual, exact Jacobian, events and extremes of one return to the section, on orbits
    with impacts, chattering and sticking (whose fields keep their Runge-Kutta steps)."""
    rk, ex, y = orbit_pair(problem, params, 40)
    assert ex.shooting.c.flow == "exact"
    ra, Ja = rk.shooting.residual_jacobian(y)
    rb, Jb = ex.shooting.residual_jacobian(y)
    assert np.max(np.abs(ra - rb)) <= 1e-9
    assert np.max(np.abs(Ja - Jb)) <= 1e-7 * np.max(np.abs(Ja))
    sa, sb = rk.shooting.simulate(y), ex.shooting.simulate(y)
    ea, eb = sa.events, sb.events
    assert [e.kind for e in ea] == [e.kind for e in eb]
    assert np.allclose([e.t for e in ea], [e.t for e in eb], rtol=0, atol=1e-9)
    # the extremes over the return (the exact flow's found when first asked for)
    assert np.max(np.abs(sa.extremes - sb.extremes)) <= 1e-8


@pytest.mark.parametrize(("problem", "params", "window"), [
    (ImpactOscillatorProblem, {"zeta": 0.0, "omega": 1.5, "gap": -0.5, "restitution": 0.8,
                               "section_phase": np.pi}, (1.5, 1.8)),
    (TwoMassChainProblem, {"omega": 0.6}, (0.6, 0.7)),
])
def test_continuations_of_both_paths_agree(problem, params: dict, window: tuple) -> None:
    """A short continuation in omega by both paths: the same points to 1e-9 and the same
    events (here a fold; the two-mass chain's period doubling at 0.69276)."""
    rk, ex, y = orbit_pair(problem, params, 60)
    out = []
    for pb in (rk, ex):
        res = nsm.continuation(pb, y, parameter="omega", min=window[0], max=window[1],
                               max_points=14, step={"initial": 0.02, "max": 0.04},
                               newton_tol=1e-10)
        br = res.branches[0]
        out.append((np.column_stack([br[f"y_{v}"] for v in pb.variables]),
                    [(e.kind, e.parameter) for e in res.events]))
    (ya, ea), (yb, eb) = out
    assert ya.shape == yb.shape and ya.shape[0] >= 10
    assert np.max(np.abs(ya - yb)) <= 1e-9
    assert [k for k, _ in ea] == [k for k, _ in eb]
    assert np.allclose([p for _, p in ea], [p for _, p in eb], rtol=0, atol=1e-9)


def test_integrator_spec_and_report_name_the_flow() -> None:
    """``method`` accepts auto and exact (default dop853, the bundled cases' numbers); the
    case summary names the flow that ran, and for ``auto`` on Runge-Kutta why: the two-mass
    chain (4 dynamic components) is below the size where the exact flow pays."""
    assert IntegratorSpec().method == "dop853"
    with pytest.raises(ValueError, match="method"):
        IntegratorSpec(method="rk4")
    for method, starts in (("exact", "exact"), ("auto", "dop853 (the exact flow applies but "
                                                       "does not pay below 6")):
        pb = TwoMassChainProblem({"integrator": {"method": method}})
        summary = pb.presentation_class(pb).summary()
        assert summary["flow"].startswith(starts)
    assert "flow" not in TwoMassChainProblem({}).presentation_class(
        TwoMassChainProblem({})).summary()


def test_auto_runs_the_exact_flow_where_it_applies_and_pays() -> None:
    """``auto``: the exact flow for the three-mass chain (6 dynamic components, the size from
    which it pays, ``AUTO_MIN_DYNAMIC``); Runge-Kutta, with the reason, for the one-mass
    oscillator (2) and for a system that is not linear between events."""
    assert chain3().compile({}, free=["omega"], method="auto").flow == "exact"
    small = oscillator().compile({"gap": -1.0, "zeta": 0.1}, free=["omega"], method="auto")
    assert small.flow == "dop853" and "does not pay below 6" in small.flow_note
    cubic = oscillator(lambda q, qd, ph, p: -q - q ** 3 + ca.cos(ph)).compile(
        {"gap": -1.0, "zeta": 0.1}, free=["omega"], method="auto")
    assert cubic.flow == "dop853" and "not linear in the state" in cubic.flow_description()


def test_autonomous_system_with_a_section_on_a_dynamic_coordinate() -> None:
    """A damped mass on a spring under gravity bouncing on the floor (no clock: the particular
    solution is the static deflection), returning to the section ``q = 0.5`` crossed upwards:
    the exact path's long steps certify the section coordinate too; its section state,
    Jacobian and events equal the Runge-Kutta path's."""
    q, qd = ca.SX.sym("q"), ca.SX.sym("qd")
    p = {"floor": ca.SX.sym("floor")}
    system = HybridSystem.mechanical("mass_spring_floor", q, qd, p, ca.SX(1.0),
                                     -1.3 * (q - 1.0) - 0.05 * qd - 2.0, q - p["floor"], 0.7)
    X0 = np.array([0.5, 3.0, 0.0])
    out = []
    for method in ("exact", "dop853"):
        c = system.compile({}, free=["floor"], method=method)
        assert c.flow == method
        res = Simulator(c).run(X0, section=(0, 0.5, 1), t_min_section=1e-3)
        out.append(res)
    a, b = out
    assert [e.kind for e in a.events] == [e.kind for e in b.events]
    assert "impact" in [e.kind for e in a.events]
    assert abs(a.t - b.t) <= 1e-9
    assert np.max(np.abs(a.X - b.X)) <= 1e-9
    assert np.max(np.abs(a.J - b.J)) <= 1e-7 * np.max(np.abs(b.J))
    assert a.n_steps < b.n_steps
