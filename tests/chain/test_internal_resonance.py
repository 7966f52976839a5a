"""Internal resonances of branch 1 of the 5-dof chain (docs/internal_resonances.md).

* One one-impact orbit per period: ``Gamma(T) - I`` (flight then impact, eq. A.1) has a
  one-dimensional kernel all along branch 1, so no one-impact family branches off it; its
  ``+1`` multiplier pair sits where the energy is extremal (a fold of the energy, located here
  by minimising the closed-form energy, independently of the multipliers).
* The 1/3 resonances (a multiplier ``exp(2 pi i / 3)``) located on the closed form (R1) are
  resonances of the hybrid model too: its simulated monodromy has that multiplier there.
* The period-3 family switched onto at the resonance near ``omega = 1.4912``, and the two
  period-4 families at the weak 1/4 resonance near ``omega = 1.5356``: every orbit
  checked by an independent direct simulation (the chain's exact modal flow between impacts,
  the impacts located by a root-finder on the gap; no part of the package): periodic to 1e-9
  over the reported period, the energy conserved to 1e-12, ``k`` impacts per period about one
  base period apart, and no period-1 orbit; ``beta`` vanishes.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.chain.hybrid_model import NDofImpactHybridProblem
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from nsm_continuation.problems.chain.resonance import resonance_frequencies
from scipy.linalg import eigh
from scipy.optimize import brentq, minimize_scalar

import nsm_continuation as nsm
from nsm_continuation.algorithms.switching import null_vector
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.settings import ContinuationSettings

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: branch 1: from just above the linear grazing orbit A to just below the grazing orbit B
BRANCH1 = (1.4233, 1.5955)


def exact_period(M: np.ndarray, K: np.ndarray, c: int, g: float, x0: np.ndarray, T: float,
                 h: float = 2e-3) -> tuple[np.ndarray, list[float], list[float]]:
    """The chain from ``x0`` over ``T`` by its exact modal flow, the impacts (``u_c = g``
    reached from below) located by Brent's method on a bracket of a grid of step ``h``, and
    ``u_c' -> -u_c'`` there: the end state, the impact times, the energy at the start and
    after each impact."""
    w2, P = eigh(K, M)
    w, Pi, n = np.sqrt(w2), P.T @ M, M.shape[0]

    def flow(x: np.ndarray, s: float | np.ndarray) -> np.ndarray:
        q, p = Pi @ x[:n], Pi @ x[n:]
        s = np.atleast_1d(s)[None, :]
        cs, sn = np.cos(w[:, None] * s), np.sin(w[:, None] * s)
        qs = q[:, None] * cs + (p / w)[:, None] * sn
        ps = -(q * w)[:, None] * sn + p[:, None] * cs
        return np.vstack([P @ qs, P @ ps])

    def energy(x: np.ndarray) -> float:
        return 0.5 * float(x[n:] @ M @ x[n:] + x[:n] @ K @ x[:n])

    x, t, impacts, energies = np.asarray(x0, dtype=float), 0.0, [], [energy(x0)]
    while True:
        ss = np.append(np.arange(h, T - t, h), T - t)
        gap = flow(x, ss)[c] - g
        hit = np.nonzero(gap > 0)[0]
        if hit.size == 0:
            return flow(x, T - t)[:, 0], impacts, energies
        i = int(hit[0])
        lo = ss[i - 1] if i > 0 else 0.0
        s = brentq(lambda r, z=x: float(flow(z, r)[c, 0]) - g, lo, ss[i], xtol=1e-15)
        x = flow(x, s)[:, 0]
        x[c], x[n + c] = g, -x[n + c]
        t += s
        impacts.append(t)
        energies.append(energy(x))


@pytest.fixture(scope="module")
def closed_form():
    return NDofImpactProblem(CHAIN)


def test_one_one_impact_orbit_per_period(closed_form):
    cf = closed_form
    for w in np.linspace(*BRANCH1, 60):
        G, _ = cf.gamma(2 * np.pi / w)
        s = np.linalg.svd(G - np.eye(2 * cf.N), compute_uv=False)
        assert s[-1] < 1e-12 * s[0]  # the orbit (4.2)
        assert s[-2] > 1e-4 * s[0]  # and no other one of this period


def test_plus_one_pair_at_the_energy_minimum(closed_form):
    cf = closed_form

    def energy(w: float) -> float:
        T = 2 * np.pi / w
        return cf.energy(cf.y_from_state(*cf.closed_form(T), T))

    w_min = minimize_scalar(energy, bounds=(1.44, 1.46), method="bounded",
                            options={"xatol": 1e-12}).x

    def pair_at_one(w: float) -> float:
        # prod_i (2 - rho_i) = det(z I - DF) / (z^N (z - 1)) at z = 1, from the
        # characteristic polynomial less its roots 0 and 1
        T = 2 * np.pi / w
        DF = cf.return_map_jacobian(cf.y_from_state(*cf.closed_form(T), T))
        q, _ = np.polydiv(np.poly(DF), [1.0, -1.0, 0.0])
        return float(np.polyval(q, 1.0).real)

    w_pair = brentq(pair_at_one, 1.44, 1.46, xtol=1e-14)
    # the energy's minimum is flat: located to ~ sqrt(eps)
    assert w_pair == pytest.approx(w_min, abs=1e-6)


def test_resonances_of_the_closed_form_are_resonances_of_the_hybrid_model(closed_form):
    roots = resonance_frequencies(closed_form, 3, 1, *BRANCH1)
    assert len(roots) == 5
    # the same roots from the eigenvalues of DF: a multiplier at angle 2 pi / 3
    for w in roots:
        T = 2 * np.pi / w
        ev = np.linalg.eigvals(closed_form.return_map_jacobian(
            closed_form.y_from_state(*closed_form.closed_form(T), T)))
        assert np.min(np.abs(ev - np.exp(2j * np.pi / 3))) < 1e-6
    # the hybrid model's orbit at the closed-form resonance, corrected at that frequency
    pb = NDofImpactHybridProblem(CHAIN)
    pb.set_parameter("omega", 1)
    w = roots[2]
    (sp,) = pb.start_points({"omega": w})
    e = np.zeros(len(sp.y))
    e[pb.parameter_index] = 1.0
    y, _, why = ContinuationEngine(pb, ContinuationSettings()).correct(sp.y, e, sp.y, 0.0)
    assert y is not None, why
    mult = np.asarray(pb.floquet(y, null_vector(pb.jacobian(y))).multipliers)
    assert np.min(np.abs(mult - np.exp(2j * np.pi / 3))) < 1e-8


@pytest.fixture(scope="module")
def period_three():
    pb = NDofImpactHybridProblem(CHAIN)
    res = nsm.continuation(pb, {"resonance": {"order": 3, "rotation": 1, "omega": 1.4912}},
                           parameter="omega", min=1.3, max=1.7,
                           step={"initial": 1e-3, "max": 5e-3}, max_points=4,
                           analysis={"stability": False})
    return pb, res.run_result


def check_by_direct_simulation(pb: NDofImpactHybridProblem, branch, k: int) -> None:
    """Every orbit of ``branch`` (period ``k T`` of the base frequency): periodic over the
    reported period by :func:`exact_period`, the energy conserved, ``k`` impacts about one
    base period apart, not ``k`` copies of one period, ``beta`` vanishing."""
    M, K = pb.modal.M, pb.modal.K
    c, g, n = pb.chain_problem.c, pb.chain_problem.g, M.shape[0]
    for p in branch.points:
        T = p.derived["period"]
        assert T == pytest.approx(k * 2 * np.pi / p.y[-1], rel=1e-12)
        x0 = pb.shooting.x0(p.y)[: 2 * n]
        xT, impacts, energies = exact_period(M, K, c, g, x0, T)
        assert np.max(np.abs(xT - x0)) <= 1e-9 * np.max(np.abs(x0))
        assert np.ptp(energies) <= 1e-12 * energies[0]
        assert len(impacts) == k == p.derived["n_impacts"]
        # one impact near each impact of the period-1 parent: a base period apart
        assert np.diff(impacts) == pytest.approx([T / k] * (k - 1), rel=0.05)
        # not k copies of one period
        x1, _, _ = exact_period(M, K, c, g, x0, T / k)
        assert np.max(np.abs(x1 - x0)) > 1e-6 * np.max(np.abs(x0))
        assert abs(p.derived["beta"]) < 1e-10


def test_period_three_family_by_direct_simulation(period_three, closed_form):
    pb, run = period_three
    assert pb.period_multiple() == 3
    w_star = resonance_frequencies(closed_form, 3, 1, 1.49, 1.492)[0]
    sides = sorted(np.sign(br.points[-1].y[-1] - w_star) for br in run.branches)
    assert sides == [-1.0, 1.0]  # the family crosses the resonance: both sides
    for br in run.branches:
        assert len(br.points) == 4
        check_by_direct_simulation(pb, br, 3)


def test_period_four_families_at_a_weak_resonance_by_direct_simulation():
    # the 1/4 resonance at omega* = 1.5356441: the scan of the plane finds no period-4 orbit
    # there (the orbits are nearly degenerate along their circle); the zeros of the reduced
    # equation's bifurcation function give the two period-4 families
    pb = NDofImpactHybridProblem(CHAIN)
    res = nsm.continuation(pb, {"resonance": {"order": 4, "rotation": 1, "omega": 1.5356}},
                           parameter="omega", min=1.3, max=1.7,
                           step={"initial": 1e-3, "max": 5e-3}, max_points=2,
                           analysis={"stability": False})
    run = res.run_result
    assert pb.period_multiple() == 4
    assert len(run.branches) == 2
    orbits = []
    for br in run.branches:
        assert br.info["switch_method"].startswith("zeros of the bifurcation function")
        assert len(br.points) == 2
        check_by_direct_simulation(pb, br, 4)
        orbits.append(pb.shooting.x0(br.points[0].y))
    # two different orbits (not the same orbit from two of its four section points)
    assert np.linalg.norm(orbits[0] - orbits[1]) > 1e-3


def test_resonance_start_bad_input():
    pb = NDofImpactHybridProblem(CHAIN)
    with pytest.raises(ValueError, match="rotation"):
        pb.start_points({"resonance": {"order": 4, "rotation": 2, "omega": 1.5}})
    with pytest.raises(ValueError, match="start.resonance.omega: no 1/3 resonance"):
        pb.start_points({"resonance": {"order": 3, "rotation": 1, "omega": 1.47}})
