"""WFEM time stepping with floating boundary conditions (Algorithm 2) and its oracles.

Oracles independent of :mod:`problems.bar.wfem_simulation`:

* conservation laws of the continuous problem (energy without damping and forcing, to
  round-off; monotone decay with damping);
* ``u_end = int sigma / E dx`` for a clamped left end (finite-volume conservation, derived in
  the module docstring) against the time-integrated end velocity;
* the bouncing bar of Table 1 solved exactly in continuous time by back-tracing characteristics
  (:mod:`problems.bar.bouncing_bar_exact`, no grid, no shared code), and its physical facts derived
  by hand: impact at ``t1 = sqrt(2 rho g0 / F0) = 1`` with speed 10, contact phases of ``2L/c``,
  rigid rebound at speed 10, period ``2 (2L/c) + 2 (2V / (F0/rho)) = 16/3``, energy plus the
  body-force potential constant;
* the damped forced linear bar (no contact): steady state from its modal series
  (``q_k'' + (eta/rho) q_k' + omega_k^2 q_k = 2 f0 / (rho L beta_k) sin(omega t)``,
  ``oracles/wfem_bar.py``), also checked against the closed form of the module.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from nsm_continuation.problems.bar.bouncing_bar_exact import BouncingBarExact
from nsm_continuation.problems.bar.wfem_operators import floating_bc_contact
from nsm_continuation.problems.bar.wfem_simulation import (
    BarParams,
    BarState,
    Loading,
    forced_response_point,
    forced_response_sweep,
    linear_forced_end_amplitude,
    linear_forced_energy,
    linear_forced_fields,
    linear_wall_response,
    period_averages,
    rest_state,
    ring_displacement,
    simulate,
    state_from_fields,
    steady_multiple,
    steady_state_rule,
)
from oracles.wfem_bar import falling_bar_exact, modal_steady_state

TABLE1 = {"E": 900.0, "rho": 1.0, "L": 10.0, "g0": 5.0, "F0": 10.0}


@pytest.fixture(scope="module")
def exact_bar() -> BouncingBarExact:
    return BouncingBarExact(t_end=18.0, **TABLE1)


def random_state(p: BarParams, seed: int = 0, amp: float = 1e-2) -> BarState:
    rng = np.random.default_rng(seed)
    sigma = amp * rng.normal(size=p.N)
    v = amp * rng.normal(size=p.N)
    u_end = float(np.sum(sigma) * p.dx / p.E) if p.left == "clamped" else 0.0
    return state_from_fields(p, sigma, v, u_end)


def n_switches(contact: np.ndarray) -> int:
    return int(np.sum(np.diff(contact.astype(int)) != 0))


# -- conservation ----------------------------------------------------------------------------------
def test_energy_conserved_with_contact_switching() -> None:
    p = BarParams(N=60, g0=2e-4)
    st = random_state(p)
    res = simulate(p, Loading(), 6000, st)
    assert n_switches(res.contact) > 20
    assert res.contact.any() and (~res.contact).any()
    assert np.max(np.abs(res.energy - res.energy[0])) <= 1e-13 * res.energy[0]
    # the contact force is compressive and vanishes when free
    assert np.all(res.contact_force[res.contact] >= 0.0)
    assert np.all(res.contact_force[~res.contact] == 0.0)


@pytest.mark.parametrize("switching", ["grid", "subcell"])
def test_end_displacement_equals_integral_of_strain(switching: str) -> None:
    p = BarParams(N=40, g0=1e-3)
    st = random_state(p, seed=1)
    loads = [Loading(),
             Loading(f0=0.05, omega=3.0, w0=0.02, eta=0.2),
             Loading(F0=0.01, f0=0.05, omega=2.0,
                     force_field=lambda x, t: 0.1 * x * np.cos(t))]
    for load in loads:
        res = simulate(p, load, 2500, st, store_fields=True, switching=switching)
        assert n_switches(res.contact) > 5
        u_int = np.array([ring_displacement(p, w) for w in res.ring])
        assert np.max(np.abs(u_int - res.u_end)) <= 1e-13 * np.max(np.abs(res.u_end))
        # the displacement field reconstruction ends on u_end and starts at the clamp
        u_field = res.displacement_field()
        assert np.allclose(u_field[:, -1], res.u_end)
        assert np.max(np.abs(u_field[:, 0])) <= 1e-13 * np.max(np.abs(res.u_end))


@pytest.mark.parametrize("switching", ["grid", "subcell"])
def test_damping_decreases_energy_monotonically(switching: str) -> None:
    p = BarParams(N=50, g0=2e-4)
    res = simulate(p, Loading(eta=0.3), 5000, random_state(p, seed=2), switching=switching)
    assert n_switches(res.contact) > 10
    assert np.all(np.diff(res.energy) <= 1e-15 * res.energy[0])
    assert res.energy[-1] < 0.5 * res.energy[0]
    if switching == "grid":
        # decay rate bounded by the kinetic-energy rate eta/rho (the subcell switch also
        # dissipates: averaging the end cell discards its intra-cell variance)
        assert res.energy[-1] >= res.energy[0] * math.exp(-0.3 * res.t[-1]) * 0.999


# -- Table 1: exact solution -----------------------------------------------------------------------
def test_bouncing_bar_exact_physical_facts(exact_bar: BouncingBarExact) -> None:
    ex = exact_bar
    c = math.sqrt(TABLE1["E"] / TABLE1["rho"])
    tau = 2 * TABLE1["L"] / c
    alpha = TABLE1["F0"] / TABLE1["rho"]
    t1 = math.sqrt(2 * TABLE1["g0"] / alpha)
    V = alpha * t1
    assert t1 == pytest.approx(1.0) and V == pytest.approx(10.0)
    assert ex.impacts[0] == pytest.approx(t1, abs=1e-12)
    # every contact phase lasts 2L/c, every flight 2V/alpha (centre of mass back at g0)
    n = min(len(ex.impacts), len(ex.releases))
    np.testing.assert_allclose(np.array(ex.releases[:n]) - np.array(ex.impacts[:n]), tau,
                               atol=1e-12)
    np.testing.assert_allclose(np.array(ex.impacts[1:n]) - np.array(ex.releases[:n - 1]),
                               2 * V / alpha, atol=1e-12)
    assert ex.period() == pytest.approx(2 * tau + 4 * V / alpha, abs=1e-12)
    # impact speed and free-fall before impact
    assert float(ex.v_end(0.5)) == pytest.approx(5.0)
    assert float(ex.u_end(0.5)) == pytest.approx(1.25)
    # contact force: Z V at impact, grows like c F0 t (no reflection back yet)
    Z = TABLE1["rho"] * c
    assert float(ex.contact_force(1.0)) == pytest.approx(Z * V)
    assert float(ex.contact_force(1.3)) == pytest.approx(c * TABLE1["F0"] * 1.3)
    # rebound: after the first contact the bar moves away rigidly at speed V with the
    # stress sigma = -2 F0 x; after the second, at speed V stress-free (time-reversed impact)
    x = np.linspace(0.05, 9.95, 25)
    sig, v = ex.fields(x, ex.releases[0] + 1e-9)
    np.testing.assert_allclose(v, -V, atol=1e-6)
    np.testing.assert_allclose(sig, -2 * TABLE1["F0"] * x, atol=1e-5)
    sig, v = ex.fields(x, ex.releases[1] + 1e-9)
    np.testing.assert_allclose(v, -V, atol=1e-6)
    np.testing.assert_allclose(sig, 0.0, atol=1e-5)
    # periodic: same fields one period later
    T = ex.period()
    for t in (0.3, 2.0, 4.1):
        s0, v0 = ex.fields(x, t + 1.0)
        s1, v1 = ex.fields(x, t + 1.0 + T)
        np.testing.assert_allclose(s1, s0, atol=1e-9)
        np.testing.assert_allclose(v1, v0, atol=1e-9)
    # energy + potential of the body force stays 0 (its value at rest)
    for t in np.linspace(0.0, 17.0, 23):
        e = ex.energy(float(t))
        assert abs(e + ex.potential(float(t))) <= 1e-12 * 1000.0
    # the convenience wrapper
    u, vv, lam, en = falling_bar_exact(np.array([0.5, 1.3]))
    np.testing.assert_allclose(u, [1.25, 5.0])
    np.testing.assert_allclose(lam, [0.0, 390.0])
    np.testing.assert_allclose(en[0], 0.5 * TABLE1["rho"] * TABLE1["L"] * 25.0)


def _table1_errors(ex: BouncingBarExact, N: int, g0: float = 5.0,
                   scheme: str = "exact", switching: str = "grid") -> tuple[float, float, float]:
    p = BarParams(E=900.0, rho=1.0, L=10.0, N=N, g0=g0, left="free")
    M = int(round(17.0 / p.time_step))
    res = simulate(p, Loading(F0=10.0, source_scheme=scheme), M,  # type: ignore[arg-type]
                   switching=switching)  # type: ignore[arg-type]
    u_ex = ex.u_end(res.t)
    v_ex, f_ex = ex.step_averages(res.t)
    return (float(np.max(np.abs(res.u_end - u_ex)) / np.max(np.abs(u_ex))),
            float(np.max(np.abs(res.v_end - v_ex)) / np.max(np.abs(v_ex))),
            float(np.max(np.abs(res.contact_force - f_ex)) / np.max(np.abs(f_ex))))


def test_table1_wfem_error_at_round_off(exact_bar: BouncingBarExact) -> None:
    # Measured: 1.7e-14, 2.1e-12, 1.6e-12 at N = 100 over 3 periods (switching times on the
    # grid, exact source integration): far below the paper's 1e-6 % = 1e-8.
    eu, ev, ef = _table1_errors(exact_bar, 100)
    assert eu < 1e-12 and ev < 1e-10 and ef < 1e-10
    eu, ev, ef = _table1_errors(exact_bar, 100, switching="subcell")
    assert eu < 1e-10 and ev < 1e-8 and ef < 1e-8


def test_table1_naive_source_is_first_order(exact_bar: BouncingBarExact) -> None:
    e10 = _table1_errors(exact_bar, 10, scheme="euler")[0]
    e100 = _table1_errors(exact_bar, 100, scheme="euler")[0]
    assert 1e-3 < e100 < 0.05 and e10 > 2.0 * e100


def test_table1_off_grid_switching_is_first_order() -> None:
    ex = BouncingBarExact(t_end=18.0, **{**TABLE1, "g0": 5.1})
    e30 = _table1_errors(ex, 30, g0=5.1)[0]
    e300 = _table1_errors(ex, 300, g0=5.1)[0]
    assert e300 < 0.01 and e30 / e300 > 4.0


def test_field_force_midpoint_equals_uniform_for_constant_force() -> None:
    p = BarParams(E=900.0, rho=1.0, L=10.0, N=30, g0=5.0, left="free")
    r1 = simulate(p, Loading(F0=10.0), 600)
    r2 = simulate(p, Loading(force_field=lambda x, t: np.full_like(x, 10.0)), 600)
    np.testing.assert_allclose(r2.u_end, r1.u_end, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r2.contact_force, r1.contact_force, rtol=0, atol=1e-9)


# -- forced linear bar -----------------------------------------------------------------------------
def test_linear_forced_response_matches_closed_form() -> None:
    p = BarParams(N=100, g0=1e3)  # the gap never closes
    f0, eta = 1.0, 0.3
    omega = 1.3 * p.omega1
    U_L, e_mean = modal_steady_state(p, f0, omega, eta)
    assert linear_forced_end_amplitude(p, f0, omega, eta) == pytest.approx(U_L, rel=1e-6)
    # from rest: transient e^(-eta t / (2 rho)) decays below 1e-6 by t = 100
    T = 2 * math.pi / omega
    M = int(round((100.0 + 2 * T) / p.time_step))
    res = simulate(p, Loading(f0=f0, omega=omega, eta=eta), M)
    assert not res.contact.any()
    tail = res.t > res.t[-1] - 2 * T
    u_ex = np.imag(U_L * np.exp(1j * omega * res.t[tail]))
    err = np.max(np.abs(res.u_end[tail] - u_ex)) / abs(U_L)
    # measured 5.8e-6 at N = 100, second order (2.3e-5, 5.8e-6, 1.5e-6 at N = 50, 100, 200)
    assert err < 2e-5
    avg = period_averages(res.t, res.energy, T, 2)
    np.testing.assert_allclose(avg, e_mean, rtol=1e-4)  # measured 2.0e-5
    # starting on the exact steady orbit: no transient
    sig, v, uL = linear_forced_fields(p, f0, omega, eta)
    st = state_from_fields(p, sig, v, uL)
    res2 = simulate(p, Loading(f0=f0, omega=omega, eta=eta), int(round(2 * T / p.time_step)),
                    st)
    u_ex2 = np.imag(U_L * np.exp(1j * omega * res2.t))
    assert np.max(np.abs(res2.u_end - u_ex2)) / abs(U_L) < 2e-5


def test_forced_sweep_linear_and_contact() -> None:
    p = BarParams(N=50, g0=1e3)
    eta = 2 * p.omega1 * 0.1
    om = np.array([0.7, 1.4]) * p.omega1
    sw = forced_response_sweep(p, om, eta, f0=1.0, n_periods_average=4)
    assert sw.steady.all() and all(pt.multiple == 1 for pt in sw.points)
    for pt in sw.points:
        assert pt.energy_mean == pytest.approx(modal_steady_state(p, 1.0, pt.omega, eta)[1],
                                               rel=5e-3)
        assert pt.contact_fraction == 0.0
    # with contact (moving wall, small gap): runs, contact happens, energies finite
    p2 = BarParams(N=50, g0=1e-3)
    sw2 = forced_response_sweep(p2, np.array([0.8, 1.2]) * p2.omega1, 2 * p2.omega1 * 0.05,
                                w0=2e-3, n_periods_average=4)
    assert all(pt.contact_fraction > 0 for pt in sw2.points)
    assert np.all(np.isfinite(sw2.energies)) and np.all(sw2.energies > 0)
    assert np.all([pt.u_max <= p2.g0 + 2e-3 + 1e-6 for pt in sw2.points])


@pytest.mark.parametrize("omega_ratio, eta", [(0.3, 0.0), (0.7, 0.05), (1.3, 0.3), (2.9, 0.1),
                                             (4.6, 0.02)])
def test_linear_forced_energy_closed_form_equals_modal_series(omega_ratio: float,
                                                              eta: float) -> None:
    """The closed form of the period-averaged energy (integrals of |cos|^2, |sin|^2 with a
    complex wavenumber) against the modal series (4000 modes), undamped included."""
    p = BarParams(N=10, g0=1.0, L=1.7, E=2.0, rho=0.5)
    om = omega_ratio * p.omega1
    assert linear_forced_energy(p, 0.7, om, eta) == pytest.approx(
        modal_steady_state(p, 0.7, om, eta)[1], rel=1e-9)


def test_permanent_contact_wall_response_matches_time_stepping() -> None:
    """g0 < 0 and a small wall amplitude: the bar never leaves the moving wall, and the closed
    form (fixed-fixed bar with a moving end plus the prestress) equals the steady state of the
    time stepping (second method) to 1e-3 (measured 2.5e-4); the contact margin of the closed
    form is positive there, and negative for a wall amplitude that does release the bar."""
    p = BarParams(N=100, g0=-1e-3)
    eta = 2 * p.omega1 * 0.05
    rule = steady_state_rule(p, eta, n_periods_average=4)
    for ratio in (0.5, 1.3, 2.6):
        om = ratio * p.omega1
        energy, margin = linear_wall_response(p, 1e-4, om, eta)
        assert margin > 0
        pt, _, _ = forced_response_point(p, Loading(w0=1e-4, eta=eta), om, rest_state(p), 0.0,
                                         rule)
        assert pt.contact_fraction == 1.0 and pt.steady
        assert pt.energy_mean == pytest.approx(energy, rel=1e-3)
    om = 1.3 * p.omega1
    assert linear_wall_response(p, 2e-3, om, eta)[1] < 0
    pt, _, _ = forced_response_point(p, Loading(w0=2e-3, eta=eta), om, rest_state(p), 0.0, rule)
    assert pt.contact_fraction < 1.0


def test_floating_bc_contact_is_algorithm_2() -> None:
    """The one switching decision (App. B) on cases decided by hand: (in_contact, gap,
    gap after a free step, wall stress, nearest)."""
    f = floating_bc_contact
    assert f(True, 0.5, 0.2, -1.0, True)  # in contact, compressive: stays
    assert not f(True, 0.0, 0.0, 1e-12, True)  # tensile: released (B.5)
    assert not f(False, 1.0, 0.5, -1.0, True)  # open gap that stays open: free
    assert f(False, 0.0, 0.5, -1.0, False)  # g <= 0 (B.2) and compressive: contact
    assert not f(False, -1e-3, 0.5, 1.0, False)  # g < 0 but tensile: free
    # nearest grid time: a crossing in the first half of the free step closes now, one in the
    # second half at the next step; without `nearest` only g <= gap_tol closes
    assert f(False, 0.3, -0.7, -1.0, True) and not f(False, 0.7, -0.3, -1.0, True)
    assert not f(False, 0.3, -0.7, -1.0, False)
    assert f(False, 0.3, -0.7, -1.0, False, gap_tol=0.5)
    assert f(False, 0.1, 1.0, 0.5, False, gap_tol=0.2, stress_tol=0.5)
    assert not f(False, 0.1, 1.0, 0.6, False, gap_tol=0.2, stress_tol=0.5)


def test_period_averages_and_steady_multiple() -> None:
    t = np.linspace(0.0, 10.0, 10001)
    y = 2.0 + np.sin(2 * np.pi * t / 1.3) ** 2
    np.testing.assert_allclose(period_averages(t, y, 1.3, 5), 2.5, rtol=1e-6)
    assert steady_multiple(np.array([1.0, 1.0, 1.0, 1.0]), 1e-3) == 1
    assert steady_multiple(np.array([1.0, 2.0, 1.0, 2.0, 1.0, 2.0]), 1e-3) == 2
    rng = np.random.default_rng(0)
    assert steady_multiple(1.0 + 0.1 * rng.random(8), 1e-3) == 0


def test_prestressed_rest_state_is_static() -> None:
    p = BarParams(N=20, g0=-1e-3)
    st = rest_state(p)
    assert st.contact and st.u_end == p.g0
    res = simulate(p, Loading(), 200, st)
    assert res.contact.all()
    np.testing.assert_allclose(res.u_end, p.g0)
    np.testing.assert_allclose(res.contact_force, -p.E * p.g0 / p.L * p.S)


# -- input validation and cost -----------------------------------------------------------------
@pytest.mark.parametrize("kwargs, field", [
    ({"N": 0}, "N"), ({"N": 2.5}, "N"), ({"E": -1.0}, "E"), ({"rho": 0.0}, "rho"),
    ({"L": float("nan")}, "L"), ({"S": float("inf")}, "S"), ({"g0": float("nan")}, "g0"),
    ({"dt": -1.0}, "dt"), ({"dt": 0.02}, "dt"), ({"left": "pinned"}, "left"),
])
def test_bar_params_validation(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        BarParams(**kwargs)


@pytest.mark.parametrize("kwargs, field", [
    ({"eta": -0.1}, "eta"), ({"omega": float("nan")}, "omega"), ({"f0": float("inf")}, "f0"),
    ({"w0": float("nan")}, "w0"), ({"F0": "x"}, "F0"), ({"source_scheme": "rk4"}, "source"),
])
def test_loading_validation(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        Loading(**kwargs)


def test_simulate_validation() -> None:
    p = BarParams(N=10)
    assert BarParams(N=10, dt=0.1).time_step == pytest.approx(0.1)
    with pytest.raises(ValueError, match="n_steps"):
        simulate(p, Loading(), -1)
    with pytest.raises(ValueError, match="state.w"):
        simulate(p, Loading(), 5, BarState(np.zeros(7)))
    with pytest.raises(ValueError, match="state.w"):
        simulate(p, Loading(), 5, BarState(np.full(20, np.nan)))
    with pytest.raises(ValueError, match="u_end"):
        simulate(p, Loading(), 5, BarState(np.zeros(20), u_end=float("nan")))
    with pytest.raises(ValueError, match="switching"):
        simulate(p, Loading(), 5, switching="exact")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="omegas"):
        forced_response_sweep(p, [1.0, -2.0], 0.1)
    with pytest.raises(ValueError, match="max_time"):
        forced_response_sweep(p, [1.0], 0.0)
    with pytest.raises(ValueError, match="switching"):
        steady_state_rule(p, 0.1, switching="exact")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="n_periods_average"):
        steady_state_rule(p, 0.1, n_periods_average=1)
    with pytest.raises(ValueError, match="g0"):
        BouncingBarExact(g0=-1.0)
    with pytest.raises(ValueError, match="fields were not stored"):
        simulate(p, Loading(), 3).fields()


def test_wall_clock_per_step() -> None:
    # Measured ~4 us/step at N = 100 with wall, force and damping (7 us inside the sweeps).
    p = BarParams(N=100, g0=1e-3)
    load = Loading(f0=4e-3, w0=2e-3, omega=2.0, eta=0.1)
    simulate(p, load, 100)
    tic = time.perf_counter()
    res = simulate(p, load, 20000)
    elapsed = time.perf_counter() - tic
    assert res.contact.any()
    assert elapsed < 1.0, f"{elapsed / 20000 * 1e6:.1f} us/step"
