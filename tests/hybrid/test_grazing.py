"""Grazing of hybrid periodic orbits: simulator robustness, the normal-form tangents
(nsm_continuation/hybrid/grazing.py, eqs. G1-G2), the structural event sequence, the orbit's
extremes, and continuation up to, at and through a grazing.

Oracle: the forced impact oscillator ``q'' + 2 zeta q' + q = cos(omega t)``, ``q >= gap`` with
Newton restitution ``e``, whose non-impacting periodic orbit is ``A cos(omega t - phi)`` with
``A = 1 / sqrt((1 - omega^2)^2 + (2 zeta omega)^2)``: it grazes where ``A = |gap|``. For
``zeta = 0`` the impacting period-1 orbit with one impact per period has a closed form too
(:func:`undamped_impacting_orbit`, Shaw & Holmes 1983): free flight ``q = A cos(omega t + phi)
+ b cos t + c sin t`` between impacts at ``q = gap``, with exit velocity ``e v`` and entry
velocity ``-v``. Both are independent of the simulator.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES
from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem
from scipy.optimize import fsolve

from nsm_continuation.hybrid.grazing import (
    locate_grazing,
    margin_gradient,
    normal_form,
    solve_margin,
    step_beyond,
)

GAP, E = -0.5, 0.8
OMEGA_G = np.sqrt(3.0)  # zeta = 0: 1 / (omega^2 - 1) = 1/2


def problem(zeta: float = 0.0, omega: float = 1.8, gap: float = GAP) -> ImpactOscillatorProblem:
    """The oscillator with its stroboscopic section at phase pi (the orbit's maximum for
    omega > 1), away from the grazing point at phase 0."""
    pb = ImpactOscillatorProblem({"zeta": zeta, "omega": omega, "gap": gap, "restitution": E,
                                  "section_phase": np.pi})
    pb.set_parameter("omega")
    return pb


def amplitude(omega: float, zeta: float = 0.0) -> float:
    return 1.0 / np.sqrt((1 - omega ** 2) ** 2 + (2 * zeta * omega) ** 2)


def free_orbit_point(omega: float, zeta: float = 0.0) -> np.ndarray:
    """Unknowns ``(q, qdot, omega)`` of the non-impacting orbit on the phase-pi section."""
    A, ph = amplitude(omega, zeta), np.arctan2(2 * zeta * omega, 1 - omega ** 2)
    return np.array([A * np.cos(np.pi - ph), -omega * A * np.sin(np.pi - ph), omega])


def undamped_impacting_orbit(omega: float) -> tuple[float, float]:
    """``(v, phase of the impact)`` of the low-velocity one-impact orbit of the undamped
    oscillator (closed-form flight, two equations solved to 1e-14)."""
    A, T = 1 / (1 - omega ** 2), 2 * np.pi / omega

    def eqs(z: np.ndarray) -> list[float]:
        phi, v = z
        b = GAP - A * np.cos(phi)
        c = E * v + A * omega * np.sin(phi)
        return [b * (np.cos(T) - 1) + c * np.sin(T),
                -A * omega * np.sin(phi) - b * np.sin(T) + c * np.cos(T) + v]

    v0 = 3.9 * (omega - OMEGA_G)
    z = fsolve(eqs, [2 * np.pi - 1e-3, v0], xtol=1e-13)
    assert np.max(np.abs(eqs(z))) < 1e-13
    return float(z[1]), float(np.mod(z[0], 2 * np.pi))



def undamped_impacting_point(omega: float) -> np.ndarray:
    """Unknowns ``(q, qdot, omega)`` on the phase-pi section of the closed-form one-impact
    orbit (:func:`undamped_impacting_orbit`): its flight from the impact, at forcing phase
    ``phi``, to forcing phase pi."""
    v, phi = undamped_impacting_orbit(omega)
    A = 1 / (1 - omega ** 2)
    b, c = GAP - A * np.cos(phi), E * v + A * omega * np.sin(phi)
    t = np.mod(np.pi - phi, 2 * np.pi) / omega
    return np.array([-A + b * np.cos(t) + c * np.sin(t), -b * np.sin(t) + c * np.cos(t), omega])

# --------------------------------------------------------------------------- the simulator
@pytest.mark.parametrize("dw", [1e-3, 1e-6, 1e-9, 1e-12])
def test_simulates_arbitrarily_close_to_grazing(dw: float) -> None:
    """A low-velocity impact (omega just below grazing: the free orbit would dip below the
    wall by ~dw/2), a tangential touch and a near miss all simulate, and the margin of the
    approach is the closed form's: ``-v^2/(2a)`` ~ ``gap + A`` to first order."""
    pb = problem()
    for w in (OMEGA_G - dw, OMEGA_G + dw):
        res = pb.shooting.simulate(free_orbit_point(w))
        depth = GAP + amplitude(w)   # > 0: the free orbit passes below the wall
        g = res.grazing_function()
        if abs(depth) > 1e-10:   # beyond the integration error (rtol 1e-10, atol 1e-12)
            assert res.n_impacts == (1 if depth > 0 else 0)
        # the margin is the free orbit's, H_min = -depth, to first order in the depth and to
        # the integration error of H over one flight (~1e-11 observed)
        assert g == pytest.approx(-depth, rel=1e-3, abs=5e-11)


def test_section_at_an_event_is_not_missed() -> None:
    """The turn of q (v = 0) falls on the phase-pi section within round-off: the section must
    still end the return (not missed: the simulation does not run to its time limit)."""
    pb = problem()
    res = pb.shooting.simulate(np.array([0.5 + 6e-9, 1.5e-9, OMEGA_G]))
    assert res.ended_by == "section" and res.t == pytest.approx(2 * np.pi / OMEGA_G, rel=1e-8)


def test_extremes_are_the_closed_form_amplitude() -> None:
    """Far from the wall the orbit is ``A cos(omega t - phi)``: its extremes (derived
    ``min_q``, ``max_q``, ``min_qdot``, ``max_qdot``) are ``-+A`` and ``-+omega A``."""
    for zeta in (0.0, 0.1):
        pb = problem(zeta, gap=-5.0)
        w = 1.8
        y = free_orbit_point(w, zeta)
        d = pb.derived(y)
        A = amplitude(w, zeta)
        assert d["min_q"] == pytest.approx(-A, abs=1e-10)
        assert d["max_q"] == pytest.approx(A, abs=1e-10)
        assert d["min_qdot"] == pytest.approx(-w * A, abs=1e-10)
        assert d["max_qdot"] == pytest.approx(w * A, abs=1e-10)


# --------------------------------------------------------------------------- normal form
def test_normal_form_tangents_match_the_closed_forms() -> None:
    """At the grazing point the tangent into the impacting side (eq. G2) is the closed-form
    orbit's, ``d|v|/domega`` included (a nonsmooth fold: omega turns back, the impacting orbit
    coexists with the free one); the tangent into the free side is the free orbit's,
    ``dq/domega = -2 omega / (omega^2 - 1)^2``."""
    pb = problem()
    yg = free_orbit_point(OMEGA_G)
    t_free = free_orbit_point(OMEGA_G - 1e-6) - free_orbit_point(OMEGA_G + 1e-6)
    t_in = t_free / np.linalg.norm(t_free)      # arriving from the free side (omega falls)
    nf = normal_form(pb.shooting, yg, t_in)
    assert nf is not None
    t_imp = pb.tangent_beyond("grazing_margin", yg, t_in, value_before=1e-3)
    assert np.allclose(t_imp, nf.impacting)
    assert t_imp[2] > 0                         # omega turns back: a nonsmooth fold
    # closed form d|v|/domega at omega_g (one-sided differences of the closed form, O(h^2))
    h = 1e-4
    v1, v2 = undamped_impacting_orbit(OMEGA_G + h)[0], undamped_impacting_orbit(OMEGA_G + 2 * h)[0]
    assert nf.kappa / t_imp[2] == pytest.approx((4 * v1 - v2) / (2 * h), rel=1e-5)
    # into the free side, arriving from the impacting one
    t_back = pb.tangent_beyond("grazing_margin", yg, -t_imp, value_before=-1e-6)
    slope = -2 * OMEGA_G / (OMEGA_G ** 2 - 1) ** 2
    assert t_back[0] / t_back[2] == pytest.approx(slope, rel=1e-8)
    assert t_back[2] > 0 and abs(t_back[1]) < 1e-9


@pytest.mark.parametrize("ds", [1e-1, 1e-2, 1e-3])
def test_step_beyond_lands_on_the_closed_form_orbits(ds: float) -> None:
    """The margin-fixing corrector (``grazing.step_beyond``) lands on the closed-form
    impacting orbit (its impact velocity to 1e-7 relative, at |v| from 4e-4 to 4e-2) and, the
    other way, on the free orbit (to 1e-10), where an arclength corrector oscillates across
    the kink."""
    sh = problem().shooting
    yg = free_orbit_point(OMEGA_G)
    t_free = free_orbit_point(OMEGA_G - 1e-6) - free_orbit_point(OMEGA_G + 1e-6)
    t_in = t_free / np.linalg.norm(t_free)
    z = step_beyond(sh, yg, t_in, False, ds)
    assert z is not None and z[2] > OMEGA_G
    res = sh.simulate(z)
    v, _ = undamped_impacting_orbit(z[2])
    assert res.n_impacts == 1 and res.min_impact_velocity == pytest.approx(v, rel=1e-7)
    assert np.linalg.norm(z - yg) == pytest.approx(ds, rel=0.05)
    z2 = step_beyond(sh, yg, -t_in, True, ds)
    assert z2 is not None and z2[2] > OMEGA_G
    assert sh.simulate(z2).n_impacts == 0
    assert z2[0] == pytest.approx(free_orbit_point(z2[2])[0], abs=1e-10)



@pytest.mark.parametrize("dw", [1e-3, 1e-4])
def test_margin_fixed_solve_converges_from_a_slow_impact(dw: float) -> None:
    """From the closed-form impacting orbit at ``omega_g + dw`` (impact velocity 3.9e-3,
    3.9e-4) the margin-fixed Newton (``grazing.solve_margin``) reaches the orbit with a
    quarter of its margin (``|v|`` halved) in at most 8 steps, and that orbit is the closed
    form's: its impact velocity to 1e-6, its margin the target to 1e-6. The first, full step
    linearises ``|v| = sqrt(-2 a m)`` and leaves a residual of the order of ``|v|`` against a
    margin error of the order of ``v^2``: a merit adding the two rejected it (damping to 1/64
    and less; no convergence in 30 steps), the natural monotonicity test accepts it."""
    sh = problem().shooting
    y = undamped_impacting_point(OMEGA_G + dw)
    m = margin_gradient(sh, y)
    assert m is not None and m[0] < 0
    z = solve_margin(sh, y, m[0] / 4, 1e-11, max_iter=8)
    assert z is not None
    res = sh.simulate(z)
    assert res.n_impacts == 1
    v, _ = undamped_impacting_orbit(float(z[2]))
    assert res.min_impact_velocity == pytest.approx(v, rel=1e-6)
    assert res.min_impact_velocity == pytest.approx(0.5 * sh.simulate(y).min_impact_velocity,
                                                    rel=1e-2)
    assert res.grazing_function() == pytest.approx(m[0] / 4, rel=1e-6)

# --------------------------------------------------------------------------- sequences
def test_sequence_notation_is_structural() -> None:
    """A single impact after which the flight is integrated in the scaled system (a < 0 at
    the impact) is ``I``, as one with a > 0: no false sequence change (not ``IB1``)."""
    from nsm_continuation.problems.impacting.two_mass_chain import TwoMassChainProblem
    base = {"m1": 1.0, "m2": 1.0, "k1": 1.0, "k2": 1.0, "c": 0.05, "F0": 0.5, "gap": 0.5,
            "restitution": 0.8}
    for omega in (0.62, 0.67):
        pb = TwoMassChainProblem({**base, "omega": omega})
        y = pb.start_points({"transient": 30})[0].y
        res = pb.shooting.simulate(y)
        assert res.n_impacts == 1 and res.signature == "I"


# --------------------------------------------------------------------------- location
@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_grazing_located_on_the_closed_form_from_both_sides(zeta: float) -> None:
    """``grazing.locate_grazing`` from a free orbit and from an impacting one lands on the
    closed-form grazing frequency, ``1/sqrt((1 - w^2)^2 + (2 zeta w)^2) = |gap|``, to 1e-10
    (measured 8e-12: the integration error of ``H`` over one period)."""
    from scipy.optimize import brentq

    sh = problem(zeta).shooting
    wg = brentq(lambda w: amplitude(w, zeta) + GAP, 1.2, 3.0, xtol=1e-15)
    yg = locate_grazing(sh, free_orbit_point(wg + 0.02, zeta), 1e-11)
    assert yg is not None and yg[2] == pytest.approx(wg, abs=1e-10)
    t_free = free_orbit_point(wg - 1e-6, zeta) - free_orbit_point(wg + 1e-6, zeta)
    z = step_beyond(sh, yg, t_free / np.linalg.norm(t_free), False, 0.05)
    assert z is not None and sh.simulate(z).n_impacts == 1
    yg2 = locate_grazing(sh, z, 1e-11)
    assert yg2 is not None and yg2[2] == pytest.approx(wg, abs=1e-10)


# --------------------------------------------------------------------------- the engine
def _run(start: dict, omega: float, direction: str, max_points: int) -> object:
    import nsm_continuation as nsm

    case = {"name": "graze", "problem": "impact_oscillator",
            "parameters": {"zeta": 0.0, "omega": omega, "gap": GAP, "restitution": E,
                           "section_phase": float(np.pi)},
            "start": {**start, "direction": direction},
            "continuation": {"parameter": "omega", "min": 1.2, "max": 1.85,
                             "step": {"initial": 0.01, "min": 1e-9, "max": 0.05},
                             "max_points": max_points, "newton_tol": 1e-10},
            "analysis": {"stability": True, "bifurcations": True}}
    return nsm.run(case)


def test_continuation_through_grazing_both_ways() -> None:
    """The engine carries the branch through the grazing with no collapse of the step, each
    way: from the free orbit (omega falling to sqrt(3)) onto the low-velocity impacting orbit
    (omega rising again: a nonsmooth fold), and back from that impacting orbit onto the free
    one. Second method: every impacting point's impact velocity is the closed-form orbit's,
    every free point's amplitude ``1/(omega^2 - 1)``; one grazing event, at sqrt(3) to 1e-10,
    with the sequence ``- -> I`` (``I -> -`` the other way)."""
    A0 = amplitude(1.8)
    res = _run({"guess": {"q": A0, "qdot": 0.0}}, 1.8, "decrease", 40)
    br = res.run_result.branches[0]
    graz = [ev for ev in br.events if ev.kind == "grazing"]
    assert len(graz) == 1 and graz[0].point.y[2] == pytest.approx(OMEGA_G, abs=1e-10)
    assert (graz[0].data["signature_before"], graz[0].data["signature_after"]) == ("-", "I")
    after = [p for p in br.points if p.s > graz[0].point.s + 1e-9]
    assert len(after) >= 10 and all(p.y[2] > OMEGA_G for p in after)
    for p in after[1:]:
        v, _ = undamped_impacting_orbit(p.y[2])
        assert p.derived["n_impacts"] == 1
        # H = q - gap: dH/dt and the normal velocity N^T qdot / |N| are both qdot
        assert p.derived["min_impact_normal_velocity"] == pytest.approx(v, rel=1e-6)
        assert p.derived["min_impact_dH_dt"] == pytest.approx(v, rel=1e-6)
    for p in br.points:
        if p.s < graz[0].point.s - 1e-9:
            assert p.derived["max_q"] == pytest.approx(amplitude(p.y[2]), abs=1e-9)
    # back: from the last impacting orbit towards the grazing, then onto the free orbit
    last = after[-1]
    res2 = _run({"guess": {"q": float(last.y[0]), "qdot": float(last.y[1])}},
                float(last.y[2]), "decrease", 40)
    br2 = res2.run_result.branches[0]
    graz2 = [ev for ev in br2.events if ev.kind == "grazing"]
    assert len(graz2) == 1 and graz2[0].point.y[2] == pytest.approx(OMEGA_G, abs=1e-10)
    assert (graz2[0].data["signature_before"], graz2[0].data["signature_after"]) == ("I", "-")
    free = [p for p in br2.points if p.s > graz2[0].point.s + 1e-9]
    assert len(free) >= 5
    for p in free[1:]:
        assert p.derived["n_impacts"] == 0
        assert p.derived["max_q"] == pytest.approx(amplitude(p.y[2]), abs=1e-9)


# --------------------------------------------------------------------------- two parameters
@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_grazing_curve_is_the_closed_form(zeta: float) -> None:
    """The grazing curve in (omega, gap) (``hybrid.codim1.GrazingCurve``, eq. C1, continued in
    the gap) is the closed form ``1/sqrt((1 - w^2)^2 + (2 zeta w)^2) = -gap - margin`` (the
    continued orbits miss the stop by the documented margin) at every point, to 1e-10."""
    from oracles.hybrid_codim1 import grazing_curve_start
    from scipy.optimize import brentq

    import nsm_continuation as nsm
    from nsm_continuation.core.problem import StartPoint
    from nsm_continuation.hybrid.codim1 import GrazingCurve

    curve = GrazingCurve(problem(zeta), "omega", "gap")
    wg = brentq(lambda w: amplitude(w, zeta) + GAP, 1.2, 3.0, xtol=1e-15)
    y0 = grazing_curve_start(curve, free_orbit_point(wg, zeta))
    res = nsm.continuation(curve, StartPoint(y0, "grazing curve", 0), min=-0.9, max=-0.2,
                           step={"initial": 0.01, "min": 1e-9, "max": 0.05}, max_points=16,
                           newton_tol=1e-10,
                           analysis={"stability": False, "bifurcations": False})
    br = res.run_result.branches[0]
    gaps = [p.y[-1] for p in br.points]
    assert len(br.points) >= 20 and max(gaps) - min(gaps) > 0.01
    for p in br.points:
        omega, gap = p.y[-2], p.y[-1]
        assert amplitude(omega, zeta) == pytest.approx(-gap - curve.target(p.y), abs=1e-10)
        assert curve.shooting.simulate(p.y).n_impacts == 0


def test_fig2_oscillator_continues_below_0_3465_without_event() -> None:
    """The bundled sticking oscillator (Fig. 2 case) continued down from 0.4 to 0.33 reaches
    the window's bound with no event in between: no false ``impact_sequence_change`` and no
    Newton failure near omega = 0.3465 (the acceleration at the first impact changes sign near
    0.338, which is no change of the orbit), and the orbit's structure, simulated again at both
    ends, is the same: complete chattering and one sticking phase per period."""

    import nsm_continuation as nsm

    case = CASES / \
        "impact_oscillator_fig2_sticking.yaml"
    res = nsm.run(nsm.load_case(case, {"output.plots": False, "output.progress": False,
                                       "start.direction": "decrease",
                                       "continuation.min": 0.33}))
    (br,) = res.run_result.branches
    assert br.termination == {"forward": "bound: omega = min"}
    assert [e.kind for e in br.events] == ["endpoint"]
    omega = res.branches[0]["omega"]
    assert omega.max() >= 0.4 - 1e-12 and omega.min() == pytest.approx(0.33, abs=1e-12)
    shooting = res.run_result.problem.shooting
    ends = [shooting.simulate(p.y) for p in (br.points[0], br.points[-1])]
    assert [r.signature for r in ends] == ["CS", "CS"]  # complete chattering, then sticking
    assert all(len(r.sticking_intervals) == 1 and r.sticking_time > 0 for r in ends)


def test_two_mass_chain_grazing_at_0_772_against_fixed_frequency_solves() -> None:
    """The bundled two-mass chain's branch reaches the grazing at omega = 0.772 (a second,
    low-velocity impact is born: sequence ``I -> II``, no Newton failure) and goes on past it
    to the window's bound. Second method:
    one-impact orbits at fixed frequencies just below it (Newton in the section unknowns at
    fixed omega, from the located point): the line through their grazing margins vanishes
    within 1e-9 of the located omega."""

    import nsm_continuation as nsm

    case = CASES / "chain_two_mass_wall.yaml"
    res = nsm.run(nsm.load_case(case, {"output.plots": False, "output.progress": False,
                                       "continuation.max": 0.7725}))
    (br,) = res.run_result.branches
    (ev,) = [e for e in br.events if e.kind == "grazing"]
    assert (ev.data["signature_before"], ev.data["signature_after"]) == ("I", "II")
    assert br.termination["forward"] == "bound: omega = max"
    # the point's unknowns are those of its chart (the section may have moved off an impact)
    pb = res.run_result.problem.in_chart(ev.point.chart)
    ip = pb.parameter_index
    w_g = float(ev.point.y[ip])
    assert w_g == pytest.approx(0.7720148, abs=1e-6)

    def margin(w: float) -> float:
        """The grazing margin of the one-impact orbit at the fixed frequency ``w``."""
        y = np.array(ev.point.y, dtype=float)
        y[ip] = w
        free = [k for k in range(y.size) if k != ip]
        for _ in range(30):
            g, J = pb.evaluate_with_jacobian(y)
            dy = np.linalg.solve(J[:, free], -np.asarray(g))
            y[free] += dy
            if np.max(np.abs(dy)) < 1e-14 * (1 + np.max(np.abs(y))):
                break
        sim = pb.shooting.simulate(y)
        assert sim.signature == "I"
        return float(sim.grazing_function())

    # the one-impact side, below the grazing: the margin (the rebound's distance to the
    # wall) is smooth and positive there; its line's zero is the grazing
    ws = w_g - np.array([4e-9, 3e-9, 2e-9, 1e-9])
    ms = np.array([margin(w) for w in ws])
    assert np.all(ms > 0)
    slope, icpt = np.polyfit(ws - w_g, ms, 1)
    root = w_g - icpt / slope
    assert abs(root - w_g) < 1e-9
