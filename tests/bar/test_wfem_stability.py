"""Orbital stability of the WFEM bar's nonsmooth modes (problems/bar/wfem_stability.py).

Oracles: the lattice orbits of problems/bar/wfem_lattice.py (exact periodic orbits of the scheme),
the exact conservation laws of a signed permutation, and brute-force distance computations.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.bar.continuum import main_signature
from nsm_continuation.problems.bar.wfem_lattice import (
    BarModel,
    LatticeSolution,
    node_solutions,
    solve_node,
)
from nsm_continuation.problems.bar.wfem_operators import ring_energy
from nsm_continuation.problems.bar.wfem_stability import (
    classify_growth,
    continuum_state,
    family_distance,
    floating_bc_simulation,
    main_backbone_counts,
    orbit_states,
    orbital_distance,
    perturb,
    perturbation_growth,
    perturbation_step,
)


def mode1(N: int = 50, M: int = 177, g0: float = 1e-3) -> LatticeSolution:
    status, sol = solve_node(BarModel(1.0, 1.0, 1.0, N, g0), main_backbone_counts(N, M))
    assert status == "admissible" and sol is not None
    return sol


def mode2(N: int = 100, M: int = 111) -> LatticeSolution:
    sols = node_solutions(BarModel(1.0, 1.0, 1.0, N, -1e-3), main_backbone_counts(N, M, 2))[1]
    assert sols
    return sols[0]


@pytest.mark.parametrize("sol", [mode1(), mode1(50, 127, -1e-3), mode2()],
                         ids=["mode1+", "mode1-", "mode2-"])
def test_unperturbed_orbit_stays_on_itself_for_50_periods(sol: LatticeSolution) -> None:
    P = 50
    run = floating_bc_simulation(sol.model, sol.w0, P * sol.M,
                                 sample_steps=np.arange(P + 1) * sol.M)
    assert run.pattern() == tuple(sol.pattern) * P
    scale = np.abs(sol.w0).max()
    assert np.abs(run.states - sol.w0).max() <= 1e-12 * scale
    assert orbital_distance(run.states, orbit_states(sol), "l1").max() <= 1e-12
    # u_end is the displacement of the state, never reset: back to g0 after every period
    assert np.allclose(run.u_end[::sol.M], sol.model.g0, rtol=0, atol=1e-12 * abs(sol.model.g0))


@pytest.mark.parametrize("sol", [mode1(), mode2()], ids=["mode1", "mode2"])
def test_perturbation_below_switching_resolution_is_transported_without_change(
        sol: LatticeSolution) -> None:
    """Nearest-step switching (closure_tol = 0.5): a perturbation with ``|eta|_1 < A/2`` moves the
    end displacement by less than half a step, so no switching instant moves and the scheme is
    exactly linear: the difference is transported by the orbit's signed permutations, its L1 and
    energy norms are constant to round-off, even on the (resolved-)unstable mode 2."""
    md, N, P = sol.model, sol.model.N, 50
    A = np.abs(sol.w0).max()
    rng = np.random.default_rng(1)
    eta = rng.uniform(-1, 1, 2 * N) * 0.2 * A / (2 * N)
    samples = np.arange(P + 1) * sol.M
    ref = floating_bc_simulation(md, sol.w0, P * sol.M, sample_steps=samples, closure_tol=0.5)
    per = floating_bc_simulation(md, sol.w0 + eta, P * sol.M, sample_steps=samples,
                                 closure_tol=0.5)
    assert np.array_equal(per.signs, ref.signs)
    diff = per.states - ref.states
    assert np.allclose(np.abs(diff).sum(axis=1), np.abs(eta).sum(), rtol=1e-9)
    assert np.allclose(np.linalg.norm(diff, axis=1), np.linalg.norm(eta), rtol=1e-9)
    # the orbital distance neither grows nor decays
    d = orbital_distance(per.states, orbit_states(sol), "l1")
    assert np.ptp(d) <= 1e-9 * d[0]


@pytest.mark.parametrize("kind,eps", [("delay", 0.1), ("shift", 0.1), ("smooth", 0.3),
                                      ("scale", 0.2)])
def test_energy_and_value_multiset_are_conserved_with_any_perturbation(kind: str,
                                                                       eps: float) -> None:
    """Every floating-BC step is a signed permutation: the energy and the multiset of |w_k| are
    invariant, so the energy-norm orbital distance is bounded by 1 + |w0|/|W| (no exponential
    growth in the energy norm is possible)."""
    sol = mode2()
    r = perturbation_growth(sol, eps, 30, kind, keep_run=True, family=False)
    run = r.run
    assert run is not None
    e = run.energy()
    assert np.abs(e / e[0] - 1).max() <= 1e-13
    vals = np.sort(np.abs(run.states), axis=1)
    assert np.abs(vals - vals[0]).max() <= 1e-15 * vals.max()
    W = np.linalg.norm(sol.w0)
    assert r.distance["energy"].max() <= 1 + np.linalg.norm(run.states[0]) / W
    # a large random (non-smooth) perturbation as well: 20 periods, energy to round-off
    md = sol.model
    w = sol.w0 + np.random.default_rng(2).normal(size=sol.w0.size) * 0.5 * np.abs(sol.w0).max()
    run2 = floating_bc_simulation(md, w, 20 * sol.M, sample_steps=np.arange(21) * sol.M)
    e2 = np.array([ring_energy(s, md.dx, md.E) for s in run2.states])
    assert np.abs(e2 / e2[0] - 1).max() <= 1e-13


def test_mode1_point_is_bounded_by_the_stated_criterion() -> None:
    """GROWTH_CRITERION: running maximum of the L1 orbital distance after a 4-period transient
    grows by at most a factor 3 (floor: two slots of grid resolution) over 150 periods ->
    'bounded'. Measured: resolved switching-time perturbations (release delayed by 1-2 steps, a
    jump moved by 2 slots) stay within twice their initial distance and never decay."""
    sol = mode1(100, 351)  # omega/omega_1 = 1.14, E/E_ref = 3.2
    for kind, slots in [("delay", 1), ("delay", 2), ("shift", 2)]:
        r = perturbation_growth(sol, 0.0, 150, kind, slots=slots, family=False)
        d = r.distance["l1"]
        assert r.classification["l1"]["label"] == "bounded", (kind, slots)
        assert r.classification["energy"]["label"] == "bounded", (kind, slots)
        assert d[1:].max() <= 2 * d[0] + 1e-12
        assert d[1:].min() >= 0.5 * d[0] - 1e-12  # neutral: never returns to the orbit


def test_mode2_point_grows_linearly_and_identically_under_refinement() -> None:
    """The same physical perturbation (release delayed by L/(100 c)) on the same mode-2 orbit at
    N = 100 and N = 200 gives the same relative distances to round-off (the continuum limit is
    reached), and they grow linearly to ~15x the initial perturbation."""
    a = perturbation_growth(mode2(100, 111), 0.0, 150, "delay", slots=1, family=False)
    b = perturbation_growth(mode2(200, 222), 0.0, 150, "delay", slots=2, family=False)
    assert np.abs(a.distance["l1"] - b.distance["l1"]).max() <= 1e-12
    c = a.classification["l1"]
    assert c["label"] == "linear growth" and c["amplification"] > 10
    # rate proportional to the size: twice the delay, about half the time to reach 0.05
    d2 = perturbation_growth(mode2(100, 111), 0.0, 150, "delay", slots=2, family=False)
    k1 = int(np.argmax(a.distance["l1"] >= 0.05))
    k2 = int(np.argmax(d2.distance["l1"] >= 0.05))
    assert 0.3 < k2 / k1 < 0.7


def test_classify_growth_on_synthetic_histories() -> None:
    k = np.arange(101.0)
    assert classify_growth(0.01 * (1 + 0.5 * np.sin(k)))["label"] == "bounded"
    assert classify_growth(0.01 * (1 + 0.3 * k))["label"] == "linear growth"
    assert classify_growth(1e-4 * np.exp(0.08 * k))["label"] == "exponential growth"
    q = 0.01 * np.ones(101)
    q[5:] = 0.0
    assert classify_growth(q)["label"] == "returns to orbit"


def test_orbital_distance_pruning_is_exact_and_phase_invariant() -> None:
    sol = mode1()
    orbit = orbit_states(sol)
    rng = np.random.default_rng(3)
    states = orbit[rng.integers(0, sol.M, 6)] + rng.normal(size=(6, orbit.shape[1])) * 1e-4
    d, ph = orbital_distance(states, orbit, "l1", return_phase=True)
    brute = np.array([np.abs(orbit - s).sum(axis=1).min() for s in states])
    assert np.allclose(d, brute / np.abs(orbit).sum(axis=1).mean(), rtol=1e-12)
    # an orbit state at any phase is at distance 0
    assert orbital_distance(orbit[::17], orbit, "energy").max() == 0.0


def test_family_member_states_match_the_lattice_orbit() -> None:
    """Cell averages of the continuum member at integer T N and t N equal the lattice orbit."""
    sol = mode1(40, 141)
    md = sol.model
    orbit = orbit_states(sol)
    A = np.abs(sol.w0).max()
    T = sol.M / md.N
    for n in range(0, sol.M, 7):
        w = continuum_state(md, main_signature(1), T, n / md.N, A)
        assert np.abs(w - orbit[n]).max() <= 1e-12 * A
    # the same-energy member is the orbit itself: zero distance to the family
    assert family_distance(orbit[::5], md, main_signature(1)).max() <= 1e-9


def test_perturbations_are_admissible_and_resolved() -> None:
    sol = mode1()
    md = sol.model
    orbit = orbit_states(sol)
    n0 = perturbation_step(sol)
    assert sol.counts[0] <= n0 < sol.M  # middle of the contact phase
    for kind in ("shift", "smooth", "scale"):
        w, info = perturb(md, orbit[n0], kind, 0.04)
        u = md.dx / (2 * md.E) * w.sum()
        assert u <= md.g0 * (1 + 1e-12)  # opens the gap, never a penetration
        assert info["size_l1"] > 0
    w, info = perturb(md, orbit[n0], "shift", 0.04)
    assert abs(info["slots"]) == 2 and np.isclose(ring_energy(w, md.dx, md.E), sol.energy)


# -- one Algorithm 2: the O(1) ring stepper is simulate() specialised ---------------------------
@pytest.mark.parametrize("sol,kind,eps", [(mode1(), "smooth", 0.05), (mode1(), "shift", 0.04),
                                          (mode1(50, 127, -1e-3), "scale", 0.03),
                                          (mode2(), "smooth", 0.05)],
                         ids=["mode1+ smooth", "mode1+ shift", "mode1- scale", "mode2- smooth"])
def test_floating_bc_simulation_equals_general_simulate(sol: LatticeSolution, kind: str,
                                                        eps: float) -> None:
    """Second method: the general time stepper (problems/bar/wfem_simulation.simulate: rotated
    array, source terms, grid switching) and the O(1) moving-origin ring stepper
    (floating_bc_simulation with closure="nearest" and zero tolerances), run separately on the
    same perturbed orbit (undamped, unforced, fixed wall) over 150 periods, make the same
    switching decision at every step (hundreds of switches, resolved perturbations that move
    them) and carry the same states and end displacement to round-off. simulate() is called one
    period at a time, so its contact flag is also carried across calls."""
    from nsm_continuation.problems.bar.wfem_operators import CONTACT, FREE
    from nsm_continuation.problems.bar.wfem_simulation import BarParams, BarState, Loading, simulate

    md, P = sol.model, 150
    orbit = orbit_states(sol)
    w, _ = perturb(md, orbit[perturbation_step(sol, "contact", orbit)], kind, eps)
    ring = floating_bc_simulation(md, w, P * sol.M, sample_steps=np.arange(P + 1) * sol.M,
                                  closure="nearest", closure_tol=0.0, release_tol=0.0)
    bar = BarParams(E=md.E, rho=md.rho, L=md.L, N=md.N, g0=md.g0)
    st = BarState(w.copy(), float(ring.u_end[0]), 0.0, False)
    signs, states, u_end = [], [st.w], [st.u_end]
    for _ in range(P):
        res = simulate(bar, Loading(), sol.M, st, switching="grid")
        st = res.final
        signs.append(np.where(res.contact, CONTACT, FREE))
        states.append(st.w)
        u_end.append(st.u_end)
    assert len(ring.switches) >= 2 * P - 1  # the rule is exercised: 2 switches per period
    assert np.array_equal(np.concatenate(signs), ring.signs)
    A = np.abs(w).max()
    assert np.abs(np.array(states) - ring.states).max() <= 1e-12 * A
    assert np.abs(np.array(u_end) - ring.u_end[::sol.M]).max() <= 1e-12 * abs(md.g0)


def test_tolerance_and_nearest_closure_differ_only_in_rounding() -> None:
    """On the unperturbed +-A orbit the nearest-grid closure rule (simulate's) and the
    default tolerance rule give the same pattern: the closure happens where u_end returns to
    g0 exactly, where both rules agree; closure must be one of the two."""
    sol = mode1()
    P = 20
    a = floating_bc_simulation(sol.model, sol.w0, P * sol.M)
    b = floating_bc_simulation(sol.model, sol.w0, P * sol.M, closure="nearest",
                               closure_tol=0.0, release_tol=0.0)
    assert a.pattern() == b.pattern() == tuple(sol.pattern) * P
    with pytest.raises(ValueError, match="closure"):
        floating_bc_simulation(sol.model, sol.w0, 3, closure="first")  # type: ignore[arg-type]
