"""The families with two impacts per period born at the period doublings of branch 1 of the
5-dof chain (hybrid model, conservative, ``e = 1``; the whole run is
``yaml_cases/ndof_hybrid_multi_impact.yaml``, checked orbit by orbit in
``benchmarks/bench_multi_impact.py``): a short piece of three of them, from a parent run in a
narrow window around its doubling (the doubling at ``omega = 1.46683`` is
``tests/chain/test_hybrid_period_doubling.py``; the one at ``1.48239`` is checked by the
benchmark only, to keep the test short). Every orbit is checked by the direct
simulation of :mod:`oracles.chain_direct` (SciPy, no part of the package): periodic to 1e-9
over the reported period and not over half of it, the energy conserved to 1e-12 at each impact
and equal to the reported one, the impacts as many as reported and at the reported times (their
order), and the unfolding ``beta`` zero to rounding (``|beta| T < 1e-12``). At the doublings
``omega = 1.53859`` and ``1.48843`` no amplitude of the switch resolves the family's parameter
offset (the families are flat): their start must be taken where its own correction converges,
away from the doubling, where the bordered Jacobian amplifies the residual's noise past the
corrector's tolerance (:func:`~nsm_continuation.algorithms.switching.start_converges`)."""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.chain.hybrid_model import NDofImpactHybridProblem
from oracles.chain_direct import direct_period

import nsm_continuation as nsm
from nsm_continuation.output.files import build_report
from nsm_continuation.output.report import markdown

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: a window around doublings of branch 1 (located in the bundled case's run at 1.5385872,
#: 1.4884263, 1.4736701: the three families that are vertical in the frequency-energy plot,
#: two of them the switches that once failed), as the inputs of the parent runs; the doubling
#: at 1.4823912 (a family like the one at 1.4668329) is checked in benchmarks/ only
WINDOWS = [(1.53857, 1.53861), (1.48841, 1.48845), (1.47365, 1.47369)]


@pytest.fixture(scope="module", params=WINDOWS, ids=lambda w: f"omega_{w[0]}")
def family(request):
    lo, hi = request.param
    pb = NDofImpactHybridProblem(CHAIN)
    res = nsm.continuation(pb, {"omega": lo, "direction": "increase"}, parameter="omega",
                           min=lo - 1e-5, max=hi, step={"initial": 2e-4, "max": 1e-3}, max_points=6,
                           analysis={"branch_switching": {
                               "depth": 1, "kinds": ["period_doubling"], "max_points": 3}})
    return pb, res.run_result


def test_the_report_marks_the_orbits_with_several_impacts(family):
    _, run = family
    rep = build_report(run)
    parent, child = rep["branches"]
    # the counts the direct simulation checks below (one impact per period on branch 1)
    assert parent["impacts_per_period"] == [1] and child["impacts_per_period"] == [2]
    text = markdown(rep)
    assert f"| {child['id']} | 2 | 2 | **several impacts per period** |" in text
    assert f"| {parent['id']} | 1 | 1 | one impact per period |" in text


def test_each_orbit_is_a_two_impact_orbit_of_the_chain(family):
    pb, run = family
    parent, child = run.branches
    assert [ev.kind for ev in parent.events].count("period_doubling") == 1
    problem = run.branch_problems[child.id]
    assert problem.period_multiple() == 2
    assert len(child.points) == 3, child.termination
    M, K = pb.modal.M, pb.modal.K
    c, g = pb.chain_problem.c, pb.chain_problem.g
    for p in child.points:
        x0 = problem.shooting.x0(p.y)[: 2 * M.shape[0]]
        T = p.derived["period"]
        assert abs(p.derived["beta"]) * T < 1e-12
        xT, impacts, energies = direct_period(M, K, c, g, x0, T)
        assert np.max(np.abs(xT - x0)) <= 1e-9 * np.max(np.abs(x0))
        reported = [ev.t for ev in problem.shooting.simulate(p.y).events if ev.kind == "impact"]
        assert len(impacts) == 2 == p.derived["n_impacts"] == len(reported)
        assert np.allclose(impacts, reported, rtol=0.0, atol=1e-9 * T)
        assert np.ptp(energies) <= 1e-12 * energies[0]
        assert energies[0] == pytest.approx(p.derived["energy"], rel=1e-12)
        xh, _, _ = direct_period(M, K, c, g, x0, T / 2)
        assert np.max(np.abs(xh - x0)) > 1e-6
