"""The same nonsmooth modes, two models: the closed form of Legrand, Junca, Heng (2017)
(``ndof_impact``: eqs. 4.1-4.2, the multipliers of A.8) and the chain declared through the
hybrid layer (``ndof_impact_hybrid``: Runge-Kutta between located impacts, shooting on a section
with the unfolding of Munoz-Almaraz et al. 2003). Neither is used to compute the other: the
closed-form orbit is only the hybrid model's initial guess, which it corrects in its own
equations at the same frequency.

On branch 1 of the 5-dof chain (``yaml_cases/ndof_default.yaml``, from the linear grazing orbit
A at ``omega_1`` to the nonlinear grazing orbit B) the two agree to 1e-9 on the energy, the
state on the section and the multipliers at the same frequency, on the Krein signatures, on the
location of every stability change (each collision of multipliers of the closed-form branch,
located in the hybrid model on the colliding pair's discriminant), and on point B (located on
the hybrid model's grazing margin); the unfolding vanishes to rounding.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES, family_orbit, msd
from nsm_continuation.problems.chain.hybrid_model import NDofImpactHybridProblem
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

import nsm_continuation as nsm
from nsm_continuation import cases
from nsm_continuation.core.floquet import discriminant, krein_of
from nsm_continuation.core.problem import EvaluationError
from nsm_continuation.runs.runner import run_case

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: the agreement the two models reach (the hybrid model integrates at rtol 1e-12)
AGREE = 1e-9


@pytest.fixture(scope="module")
def closed_form():
    case, problem = cases.load(CASES / "ndof_default.yaml")
    return problem, run_case(case, problem, progress=False).branches[0]


@pytest.fixture(scope="module")
def hybrid():
    return NDofImpactHybridProblem(CHAIN)


def closed_form_orbit(cp, omega: float):
    """The closed-form orbit at ``omega``: its unknowns and its Floquet data."""
    T = 2 * np.pi / omega
    u0, du0 = cp.closed_form(T)
    y = cp.y_from_state(u0, du0, T)
    tangent = np.linalg.svd(cp.jacobian(y))[2][-1]
    return y, cp.floquet(y, tangent)


def closed_form_section_state(cp, y: np.ndarray, value: float) -> np.ndarray:
    """The closed-form orbit's state where ``u_c`` first falls through ``value`` (the hybrid
    model's section): the modal flight (2.9)-(2.10) from the post-impact state, its crossing
    bracketed on a grid and refined by bisection."""
    u0, du0, T = cp.state(y)
    w, P = cp.omega, cp.P
    q, p = cp.Pinv @ u0, cp.Pinv @ du0

    def state(t: float) -> np.ndarray:
        return np.concatenate([P @ (np.cos(w * t) * q + np.sin(w * t) * p / w),
                               P @ (-w * np.sin(w * t) * q + np.cos(w * t) * p)])

    ts = np.linspace(0.0, T, 4001)
    uc = np.array([state(t)[cp.c] - value for t in ts])
    k = int(np.flatnonzero((uc[:-1] > 0) & (uc[1:] <= 0))[0])
    lo, hi = ts[k], ts[k + 1]
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if state(mid)[cp.c] > value else (lo, mid)
    return state(0.5 * (lo + hi))


@pytest.mark.parametrize("omega", [1.43, 1.47, 1.52, 1.58])
def test_same_orbit_energy_section_state_multipliers_and_krein(hybrid, closed_form, omega):
    cp, _ = closed_form
    y, _, fl = family_orbit(hybrid, omega)
    d = hybrid.derived(y)
    yc, flc = closed_form_orbit(cp, omega)
    assert d["omega"] == pytest.approx(omega, rel=1e-14)
    assert abs(d["energy"] - cp.energy(yc)) <= AGREE * cp.energy(yc)
    x = hybrid.shooting.x0(y)[: hybrid.shooting.c.n]
    xc = closed_form_section_state(cp, yc, hybrid.shooting.section.value)
    assert np.max(np.abs(x - xc)) <= AGREE * np.max(np.abs(xc))
    assert d["n_impacts"] == 1 and hybrid.returns == 1
    # the unfolding vanishes to rounding, the family's +1 is removed to 1e-11
    assert abs(d["beta"]) * d["period"] < 1e-12
    assert fl.trivial_error < 1e-10
    assert fl.multipliers.size == flc.multipliers.size == 8
    assert msd(fl.multipliers, flc.multipliers) <= AGREE
    kh, kc = krein_of(fl), krein_of(flc)
    compared = 0
    for m, k in zip(fl.multipliers, kh, strict=True):
        j = int(np.argmin(np.abs(flc.multipliers - m)))
        if abs(abs(m) - 1.0) < 1e-6 and abs(kc[j]) > 1e-3:  # on the circle, definite
            assert np.sign(k) == np.sign(kc[j])
            compared += 1
    assert compared >= 2  # at least one pair on the circle (all eight at the stable points)


@pytest.mark.parametrize(("omega", "returns"), [(2.2, 3), (2.28, 1), (4.3, 1)])
def test_subharmonic_orbits_agree(hybrid, closed_form, omega, returns):
    """Branch 3 (mode 3, T ~ 3 T_3: near its pole the orbit crosses the section three times a
    period, the returns are chained) and branch 4 (mode 4, T ~ 2 T_4): energy, section state
    and multipliers at the same frequency."""
    cp, _ = closed_form
    y, _, fl = family_orbit(hybrid, omega)
    yc, flc = closed_form_orbit(cp, omega)
    assert hybrid.returns == returns
    assert abs(hybrid.derived(y)["energy"] - cp.energy(yc)) <= AGREE * cp.energy(yc)
    x = hybrid.shooting.x0(y)[: hybrid.shooting.c.n]
    xc = closed_form_section_state(cp, yc, hybrid.shooting.section.value)
    assert np.max(np.abs(x - xc)) <= AGREE * np.max(np.abs(xc))
    assert msd(fl.multipliers, flc.multipliers) <= AGREE


def collision_in_hybrid(pb: NDofImpactHybridProblem, omega: float, critical: complex,
                        h: float = 1e-7) -> tuple[float, float, float]:
    """Where the hybrid model's pair of multipliers nearest ``critical`` collides near
    ``omega``: the zero of the pair's discriminant (positive on the circle, negative off it,
    analytic through the collision), interpolated between ``omega -+ h``; with the
    discriminant's values there."""
    f = []
    for w in (omega - h, omega + h):
        _, _, fl = family_orbit(pb, w)
        m = fl.multipliers
        pair = m[np.argsort(np.abs(m - critical))[:2]]
        f.append(discriminant(*pair))
    return omega - h - f[0] * 2 * h / (f[1] - f[0]), f[0], f[1]


def test_every_stability_change_of_branch_1_at_the_same_frequency(hybrid, closed_form):
    """The twelve stability changes of branch 1 (fold, period doublings and Krein collisions)
    located in the hybrid model within 1e-9 of the closed form's, each with the closed form's
    direction (on the circle, ``discriminant > 0``, on the stable side)."""
    _, branch = closed_form
    changes = [ev for ev in branch.events if ev.kind == "stability_change"]
    assert len(changes) == 12
    for ev in changes:
        omega = ev.point.derived["omega"]
        critical = complex(*ev.data["critical_multiplier"])
        found, f_lo, f_hi = collision_in_hybrid(hybrid, omega, critical)
        assert abs(found - omega) <= AGREE, (omega, found)
        # omega increases along the branch: the stable side is before the change if it was
        # stable before
        stable_below = ev.data["stable_before"]
        assert (f_lo > 0) == stable_below and (f_hi > 0) != stable_below, (omega, f_lo, f_hi)


def test_point_b_the_nonlinear_grazing_orbit(hybrid, closed_form):
    """Point B ends branch 1 in the closed form (admissibility lost, a tangency with the
    wall); in the hybrid model it is the zero of the grazing margin (the two symmetric near
    approaches of the orbit touch the wall), found from below by inverse quadratic
    interpolation of the frequency in the margin (beyond B the one-impact orbit does not exist:
    an iterate there fails and is pulled back halfway)."""
    _, branch = closed_form
    (graze,) = [ev for ev in branch.events if ev.kind == "grazing"]
    omega_b = graze.point.derived["omega"]

    def margin(w: float) -> float | None:
        try:
            return hybrid.derived(family_orbit(hybrid, w)[0])["grazing_margin"]
        except (ValueError, EvaluationError):  # beyond B: no one-impact orbit
            return None

    w = [omega_b - 1e-4, omega_b - 5e-5, omega_b - 2.5e-5]
    g = [margin(x) for x in w]
    assert all(v is not None and v > 0 for v in g)
    for _ in range(12):
        nxt = float(np.polyval(np.polyfit(g[-3:], w[-3:], 2), 0.0))
        val = margin(nxt)
        while val is None:
            nxt = 0.5 * (nxt + w[-1])
            val = margin(nxt)
        w.append(nxt)
        g.append(val)
        if abs(w[-1] - w[-2]) < 1e-12:
            break
    assert abs(g[-1]) < 1e-9 and abs(w[-1] - omega_b) <= AGREE, (w[-1], g[-1], omega_b)


def test_stability_changes_of_a_subharmonic_branch(hybrid):
    """Branch 3 (mode 3, k = 3) of the closed form, continued from its pole to omega = 2.31:
    its two stability changes (a Krein collision and the collision that closes the window)
    at the same frequencies in the hybrid model."""
    cp = NDofImpactProblem(CHAIN)
    res = nsm.continuation(cp, {"mode": 3, "subharmonic": 3}, parameter="omega", min=2.18,
                           max=2.31, step={"initial": 0.005, "min": 1e-9, "max": 0.05},
                           max_points=400, analysis={"stability": True})
    changes = [ev for ev in res.run_result.branches[0].events if ev.kind == "stability_change"]
    assert len(changes) == 2
    for ev in changes:
        omega = ev.point.derived["omega"]
        found, _, _ = collision_in_hybrid(hybrid, omega, complex(*ev.data["critical_multiplier"]))
        assert abs(found - omega) <= AGREE, (omega, found)



def test_the_report_names_the_model_that_ran(hybrid, closed_form):
    """``report.md`` lists ``problem_summary`` under "System": each problem names its model
    and why it runs (the closed form by default, the hybrid one when a case asks for it)."""
    cp, _ = closed_form
    assert cp.presentation.summary()["model"].startswith("closed form")
    assert "default" in cp.presentation.summary()["model"]
    model = hybrid.presentation.summary()["model"]
    assert model.startswith("hybrid") and "chosen by the case" in model
