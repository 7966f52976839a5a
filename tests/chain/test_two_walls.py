"""The 5-dof chain of Legrand, Junca, Heng (2017) with two contacts (``problem: ndof_two_walls``:
the last mass between the walls ``u5 = +-1``, ``e = 1``) against an independent closed form
(:mod:`oracles.chain_two_walls`: the symmetric orbit as the kernel of ``expm(A T/2) + S``, its
saltation monodromy, an event-driven simulation by the exact flow; numpy/scipy only).

On nonsmooth modes 1 and 2 (the symmetric one-impact-per-wall orbits near ``omega_1`` and
``omega_2``) the hybrid model's orbits agree with the closed form to 1e-9 (energy, state on the
section), the unfolding vanishes to rounding, the oracle's simulation from the reported section
state closes after the impacts in the reported order with the energy conserved, and the
multipliers agree with the saltation monodromy's (itself checked against finite differences of
the oracle's return map). Mode 1 ends where a third impact appears (``u5`` grazes a wall inside
a half period), where the hybrid model's grazing margin, equal to the oracle's, vanishes.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES, family_orbit, msd
from nsm_continuation.problems.chain.two_walls import TwoWallChainProblem
from oracles.chain_two_walls import TwoWallChain
from scipy.optimize import brentq, minimize_scalar

from nsm_continuation import cases

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: the agreement of the orbits (the hybrid model integrates at rtol 1e-12)
AGREE = 1e-9
#: orbits of mode 1 (stable and unstable ones) and mode 2, two of them (1.666, 5.75) beyond
#: the inflection of u5 at T/4 that makes the crossing of u5 = 0 tangent
OMEGAS = [1.45, 1.5, 1.6, 1.666, 4.3, 4.7, 5.75]


@pytest.fixture(scope="module")
def problem() -> TwoWallChainProblem:
    return TwoWallChainProblem(CHAIN)


@pytest.fixture(scope="module")
def oracle() -> TwoWallChain:
    return TwoWallChain(5, 0.2, 5.0, 1.0)


@pytest.fixture(scope="module")
def orbits(problem):
    return {w: family_orbit(problem, w) for w in OMEGAS}


def interior_margin(oracle: TwoWallChain, omega: float) -> float:
    """``g - max |u_c|`` over the interior extrema of the closed-form symmetric orbit's half
    period (the nearest approach to a wall between the two impacts; a grid, then a bounded
    1-D maximisation): negative where the orbit crosses a wall (a third impact)."""
    T = 2 * np.pi / omega
    X0 = oracle.symmetric_orbit(T)
    t = np.linspace(0.0, T / 2, 4001)
    a = np.abs(oracle.u_c(X0, t))
    inner = np.nonzero((a[1:-1] >= a[:-2]) & (a[1:-1] >= a[2:]))[0] + 1  # local maxima
    best = 0.0
    for k in inner:
        r = minimize_scalar(lambda s: -abs(oracle.u_c(X0, np.array([s]))[0]),
                            bounds=(t[k - 1], t[k + 1]), method="bounded",
                            options={"xatol": 1e-13})
        best = max(best, -float(r.fun))
    return float(oracle.g - best)


@pytest.mark.parametrize("omega", OMEGAS)
def test_orbits_match_the_closed_form(problem, oracle, orbits, omega) -> None:
    """Energy and state on the section ``u5 = 1/2`` (falling) equal the closed form's at the same
    frequency to 1e-9; the unfolding beta vanishes to rounding."""
    y, _, _ = orbits[omega]
    T = 2 * np.pi / omega
    X0 = oracle.symmetric_orbit(T)
    assert X0[oracle.N + oracle.c] < 0  # an admissible start: it leaves the upper wall
    d = problem.derived(y)
    assert abs(d["energy"] - oracle.energy(X0)) <= AGREE * oracle.energy(X0)
    Xs = oracle.section_state(X0, problem.params.section_value, T)
    X = problem.shooting.x0(y)[: 2 * oracle.N]
    assert np.max(np.abs(X - Xs)) <= AGREE * (1 + np.max(np.abs(Xs)))
    assert d["unfolding"] <= problem.unfolding_tolerance()
    assert abs(d["period"] - T) <= AGREE * T


@pytest.mark.parametrize("omega", OMEGAS)
def test_direct_simulation_closes_in_the_reported_order(problem, oracle, orbits, omega) -> None:
    """From the reported section state, the oracle's exact-flow simulation meets the walls in
    the order the hybrid model reports, conserves the energy, and is back on the section state
    after one period (1e-9)."""
    y, _, _ = orbits[omega]
    res = problem.shooting.simulate(y)
    reported = [res.surface_names[ev.surface] for ev in res.events if ev.kind == "impact"]
    assert problem.signature(y) == "I(lower) I(upper)"
    X = problem.shooting.x0(y)[: 2 * oracle.N]
    T = float(res.t)
    impacts, Xe, t_last = oracle.simulate(X, 2, T)
    assert [w for _, w, _ in impacts] == ["lower", "upper"]
    assert reported == ["lower", "upper"]
    E0 = oracle.energy(X)
    assert abs(oracle.energy(Xe) - E0) <= 1e-12 * E0
    back = oracle.flow(Xe, T - t_last)
    assert np.max(np.abs(back - X)) <= AGREE * (1 + np.max(np.abs(X)))
    # the impact velocities are the closed form's (a symmetric orbit: equal and opposite)
    assert abs(impacts[0][2] + impacts[1][2]) <= AGREE * abs(impacts[0][2])


@pytest.mark.parametrize("omega", OMEGAS)
def test_multipliers_match_the_saltation_monodromy(problem, oracle, orbits, omega) -> None:
    """The section map's multipliers without the family's +1 are the closed-form monodromy's
    without its two +1, and the stability agrees."""
    _, _, fl = orbits[omega]
    lam = oracle.multipliers(2 * np.pi / omega)
    err = msd(np.asarray(fl.multipliers), lam)
    assert err <= max(AGREE, 10 * fl.noise)
    outside = np.abs(lam) > 1 + 1e-6
    assert bool(np.any(outside)) == bool(np.any(np.abs(fl.multipliers) > 1 + 1e-6))


def test_saltation_monodromy_matches_finite_differences(oracle) -> None:
    """Cross-check of the oracle: the eigenvalues of the saltation monodromy are those of the
    central finite differences of its own event-driven return map (upper wall to upper wall),
    with the family's +1."""
    omega = 1.5
    T = 2 * np.pi / omega
    z = np.delete(oracle.symmetric_orbit(T), oracle.c)
    h = 1e-6
    J = np.empty((z.size, z.size))
    for i in range(z.size):
        e = np.zeros(z.size)
        e[i] = h
        J[:, i] = (oracle.return_map(z + e, 2, 1.5 * T)
                   - oracle.return_map(z - e, 2, 1.5 * T)) / (2 * h)
    fd = np.linalg.eigvals(J)
    assert msd(fd, np.append(oracle.multipliers(T), 1.0)) <= 1e-5


def test_mode_1_ends_where_a_third_impact_appears(problem, oracle) -> None:
    """Mode 1's nearest interior approach to a wall (the hybrid model's grazing margin, the
    event function that locates a grazing) is the closed form's to 1e-8, up to 1e-4 before
    ``omega_B``: the zero of the closed form's margin, beyond which the orbit of (W1) crosses a
    wall (a third impact)."""
    wB = brentq(lambda w: interior_margin(oracle, w), 1.664, 1.672, xtol=1e-12)
    assert interior_margin(oracle, wB + 1e-3) < 0  # beyond omega_B (W1) crosses a wall
    for w in (1.664, wB - 1e-4):
        y, _, _ = family_orbit(problem, w)
        d = problem.derived(y)
        assert d["n_impacts"] == 2
        assert abs(d["grazing_margin"] - interior_margin(oracle, w)) <= 1e-8


def test_pitchfork_is_where_the_one_wall_mode_grazes_the_other_wall(problem, oracle) -> None:
    """Paper 000's one-wall mode (its closed form (4.2), ``ndof_impact``) is an orbit of the
    clearance as long as ``u5 >= -1``; at the frequency ``omega_G`` where it grazes the lower
    wall, the symmetric family of the hybrid two-wall model has its first pitchfork: a
    multiplier pair crosses +1 there (2 multipliers outside just below, 1 just above; the
    closed form's monodromy agrees)."""
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    one_wall = NDofImpactProblem(CHAIN)

    def lowest(w: float) -> float:
        T = 2 * np.pi / w
        X = np.concatenate(one_wall.closed_form(T))
        t = np.linspace(0.0, T, 4001)
        k = int(np.argmin(oracle.u_c(X, t)))
        r = minimize_scalar(lambda s: oracle.u_c(X, np.array([s]))[0], method="bounded",
                            bounds=(t[k - 1], t[k + 1]), options={"xatol": 1e-13})
        return float(r.fun) + oracle.g

    wG = brentq(lowest, 1.43, 1.45, xtol=1e-14)
    for w, n in ((wG - 1e-6, 2), (wG + 1e-6, 1)):
        _, _, fl = family_orbit(problem, w)
        assert int(np.sum(np.abs(fl.multipliers) > 1 + 1e-6)) == n
        assert int(np.sum(np.abs(oracle.multipliers(2 * np.pi / w)) > 1 + 1e-6)) == n


def tangency_omega(oracle: TwoWallChain, value: float) -> float:
    """Where on mode 2 the interior maximum of ``u5`` grown from the inflection at ``T/4``
    reaches ``value`` (the closed form; ``u5`` on a grid of the half period, then a bounded
    maximisation after ``T/4``): where the section ``u5 = value`` turns tangent to the flow."""

    def top(w: float) -> float:
        T = 2 * np.pi / w
        X0 = oracle.symmetric_orbit(T)
        r = minimize_scalar(lambda s: -oracle.u_c(X0, np.array([s]))[0],
                            bounds=(T / 4, 0.45 * T), method="bounded",
                            options={"xatol": 1e-13})
        return -float(r.fun) - value

    return float(brentq(top, 5.75, 5.92, xtol=1e-13))


@pytest.fixture(scope="module")
def on_wall() -> TwoWallChainProblem:
    return TwoWallChainProblem({**CHAIN, "section_value": CHAIN["gap"]})


@pytest.mark.parametrize("omega", [4.7, 5.9, 5.92])
def test_impact_section_orbits_match_the_closed_form(on_wall, oracle, omega) -> None:
    """On the section at the impacts on the upper wall (``section_value = gap``) the state is
    the closed form's post-impact state (W1) itself, to 1e-9, with its energy and the
    multipliers of its saltation monodromy; at 5.9 and 5.92 beyond the frequency where the
    section ``u5 = 1/2`` turns tangent to the flow (the interior maximum of ``u5`` reaches
    1/2), up to the family's grazing."""
    assert tangency_omega(oracle, 0.5) < 5.9
    y, _, fl = family_orbit(on_wall, omega)
    T = 2 * np.pi / omega
    X0 = oracle.symmetric_orbit(T)
    X = on_wall.shooting.x0(y)[: 2 * oracle.N]
    assert np.max(np.abs(X - X0)) <= AGREE * (1 + np.max(np.abs(X0)))
    d = on_wall.derived(y)
    assert abs(d["energy"] - oracle.energy(X0)) <= AGREE * oracle.energy(X0)
    assert d["n_impacts"] == 2 and d["section_u5"] == CHAIN["gap"]
    lam = oracle.multipliers(T)
    assert msd(np.asarray(fl.multipliers), lam) <= max(AGREE, 10 * fl.noise) * max(
        1.0, float(np.abs(lam).max()))


def test_section_moves_to_the_wall_before_it_turns_tangent(problem, oracle) -> None:
    """Within ``SECTION_MARGIN`` of the tangency the section ``u5 = 1/2`` moves to the
    impacts on the upper wall (:meth:`rechart`): the moved point is the closed form's
    post-impact state, a solution in the new chart (residual at rounding), and the moved
    tangent is the family's tangent there (the Jacobian's kernel). Far from it (mode 1, and
    mode 2 before the inflection at ``T/4``) the section stays."""
    for w in (1.6, 5.5):
        y, t, _ = family_orbit(problem, w)
        assert problem.rechart(y, t) is None
    w = 0.5 * (tangency_omega(oracle, 0.4) + tangency_omega(oracle, 0.5))
    y, t, _ = family_orbit(problem, w)
    assert problem.section_margin(y) < problem.SECTION_MARGIN
    moved = problem.rechart(y, t)
    assert moved is not None
    new = moved.problem
    assert new.chart() == {"u5": 1.0, "section_returns": 1.0} and problem.chart() is None
    X0 = oracle.symmetric_orbit(2 * np.pi / w)
    X = new.shooting.x0(moved.y)[: 2 * oracle.N]
    assert np.max(np.abs(X - X0)) <= AGREE * (1 + np.max(np.abs(X0)))
    g, A = new.evaluate_with_jacobian(moved.y)
    assert np.max(np.abs(g)) <= AGREE * (1 + np.max(np.abs(X0)))
    kernel = np.linalg.svd(A)[2][-1]
    assert abs(abs(kernel @ moved.tangent) - 1.0) <= 1e-8
    # the same orbit in both charts; a restart reads the moved chart back
    assert abs(new.derived(moved.y)["energy"] - problem.derived(y)["energy"]) <= 1e-12 * (
        oracle.energy(X0))
    assert problem.in_chart(new.chart()).chart() == new.chart()
    assert new.in_chart(None).chart() is None


def test_end_of_a_section_between_the_walls_is_named(problem, oracle) -> None:
    """Just past the tangency the return to the section ``u5 = 1/2`` comes back before the
    orbit's impacts: the evaluation says so, naming the section tangency and the frequency
    (not a change of the impact sequence)."""
    from nsm_continuation.core.problem import EvaluationError

    w = tangency_omega(oracle, 0.5) + 1e-4
    T = 2 * np.pi / w
    X0 = oracle.symmetric_orbit(T)
    Xs = oracle.section_state(X0, 0.5, T)
    y = np.append(np.delete(Xs, oracle.c), [0.0, w])
    with pytest.raises(EvaluationError, match=r"section tangent to the flow at omega = 5\.88"):
        problem.evaluate_with_jacobian(y)


def test_mode_2_ends_at_the_grazing_of_both_walls(oracle) -> None:
    """On the section at the impacts mode 2 is continued to its own end: the branch ends named
    (``grazing``, the near approaches' margin extrapolated to zero) at the closed form's
    ``omega`` where the interior extrema of ``u5`` reach the walls (the zero of its interior
    margin), to 1e-8 (measured: 2e-11)."""
    import nsm_continuation as nsm

    wG = brentq(lambda w: interior_margin(oracle, w), 5.92, 5.9235, xtol=1e-13)
    res = nsm.run(CASES / "ndof_two_walls_modes.yaml", {
        "output.plots": False, "parameters.section_value": CHAIN["gap"],
        "start": [{"omega": 5.922, "direction": "increase"}], "analysis.stability": False})
    (branch,) = res.branches
    assert branch.termination["forward"].startswith("grazing at omega = 5.923122")
    (end,) = [ev for ev in res.events if ev.kind == "grazing"]
    assert abs(end.parameter - wG) <= 1e-8


def test_bundled_case_and_bad_input() -> None:
    """The bundled case loads; bad parameters and starts are one line naming the field."""
    case, pb = cases.load(CASES / "ndof_two_walls_modes.yaml")
    assert pb.name == "ndof_two_walls" and pb.parameter == "omega"
    with pytest.raises(ValueError, match="section_value"):
        TwoWallChainProblem({**CHAIN, "section_value": 1.5})
    asym = TwoWallChainProblem({**CHAIN, "lower_gap": 0.5})
    with pytest.raises(ValueError, match="symmetric walls"):
        asym.start_points({"omega": 1.5})
    sym = TwoWallChainProblem(CHAIN)
    # beyond the zero of w2(T) (an energy asymptote near omega = 1.68) the symmetric orbit
    # does not leave the upper wall
    with pytest.raises(ValueError, match="not admissible"):
        sym.start_points({"omega": 1.681})
