"""A family with two impacts per period, born at a period doubling of branch 1 of the 5-dof
chain in the hybrid model (``analysis.branch_switching``; :meth:`ConservativeFamilyProblem.\
iterated`): every orbit of it checked by an independent direct simulation (SciPy's DOP853 on
``M u'' + K u = 0`` with the wall ``u_5 = g`` located as an event and ``u_5' -> -u_5'`` there,
no part of the hybrid layer): periodic to 1e-9 over the reported period, the energy conserved to
1e-12 at each impact, two impacts per period as reported, and no period-1 orbit.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.chain.hybrid_model import NDofImpactHybridProblem
from oracles.chain_direct import direct_period

import nsm_continuation as nsm

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}


@pytest.fixture(scope="module")
def diagram():
    pb = NDofImpactHybridProblem(CHAIN)
    res = nsm.continuation(pb, {"omega": 1.4667, "direction": "increase"}, parameter="omega",
                           min=1.4667, max=1.4669, step={"initial": 1e-4, "max": 1e-3},
                           max_points=6, analysis={"branch_switching": {
                               "depth": 1, "kinds": ["period_doubling"], "max_points": 4}})
    return pb, res.run_result


def test_period_two_family_born_at_the_doubling(diagram):
    pb, run = diagram
    parent, child = run.branches
    (pd,) = [ev for ev in parent.events if ev.kind == "period_doubling"]
    problem = run.branch_problems[child.id]
    assert problem.period_multiple() == 2 and problem.returns == 2
    assert len(child.points) == 4
    M, K = pb.modal.M, pb.modal.K
    c, g = pb.chain_problem.c, pb.chain_problem.g
    for p in child.points:
        x0 = problem.shooting.x0(p.y)[: 2 * M.shape[0]]
        T = p.derived["period"]
        # the base frequency of a period-2 orbit: twice its own
        assert p.y[-1] == pytest.approx(4 * np.pi / T, rel=1e-12)
        xT, impacts, energies = direct_period(M, K, c, g, x0, T)
        assert np.max(np.abs(xT - x0)) <= 1e-9 * np.max(np.abs(x0))
        assert len(impacts) == 2 == p.derived["n_impacts"]
        assert np.ptp(energies) <= 1e-12 * energies[0]
        assert energies[0] == pytest.approx(p.derived["energy"], rel=1e-12)
        # not the period-1 orbit: half the period does not close
        xh, _, _ = direct_period(M, K, c, g, x0, T / 2)
        assert np.max(np.abs(xh - x0)) > 1e-6
    # the family leaves the doubling point (along the eigenvector of -1: flat in omega)
    assert np.linalg.norm(child.points[-1].y - pd.point.y) > 1e-3
