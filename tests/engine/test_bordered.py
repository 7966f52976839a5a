"""The engine's linear algebra: CasADi results read through function buffers, and the
chain's bordered systems solved from their structure (:mod:`nsm_continuation.core.bordered`).

Oracles: CasADi's own evaluation (``Function.__call__``, a ``DM`` converted by numpy) for the
buffers; dense LAPACK (``numpy.linalg.solve`` / ``slogdet`` of the assembled bordered matrix
with the exact CasADi Jacobian) for the structured factor, including exactly at a pole of a
mode (``sin(w_j T / 2) = 0``), where the diagonal part is singular and the matrix is not; the
dense path of the engine for a whole continuation run.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from oracles.scaled_chain import closed_form_y, scaled_chain

from nsm_continuation.core.bordered import DenseBorderedFactor, DiagonalBorderedFactor
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.core.settings import ContinuationSettings


@pytest.mark.parametrize("n", [5, 60])  # SX and MX
def test_buffers_return_what_casadi_returns(n: int) -> None:
    pb = scaled_chain(n)
    noise = 1e-3 * np.random.default_rng(1).standard_normal(n + 2)
    y = closed_form_y(pb, pb.T_lin[0] * 0.995) + noise
    cp = pb.compiled
    g_ref = np.asarray(cp.G(y), dtype=float).ravel()
    J_ref = np.asarray(cp.J(y), dtype=float)
    g, J = pb.evaluate_with_jacobian(y)
    assert np.array_equal(pb.evaluate(y), g_ref) and np.array_equal(g, g_ref)
    assert np.array_equal(pb.jacobian(y), J_ref) and np.array_equal(J, J_ref)
    assert J.shape == (n + 1, n + 2)
    # a fresh array per call: the caller may keep or change it
    J[0, 0] += 1.0
    assert np.array_equal(pb.jacobian(y), J_ref)
    with pytest.raises(ValueError, match="unknowns"):
        pb.evaluate(y[:-1])


def _cases(pb: NDofImpactProblem) -> list[tuple[str, float]]:
    pole = 2 * np.pi * 3 / pb.omega[4]  # sin(w_5 T / 2) = 0: a pole of mode 5, k = 3
    return [("generic", pb.T_lin[0] * 0.999), ("at a pole", pole),
            ("next to a pole", pole * (1 + 1e-9))]


@pytest.mark.parametrize("n", [50, 200])
def test_structured_factor_equals_dense_lapack(n: int) -> None:
    pb = scaled_chain(n)
    rng = np.random.default_rng(n)
    for what, T in _cases(pb):
        y = closed_form_y(pb, T)
        row = rng.standard_normal(n + 2)
        F = pb.bordered_factor(y, row)
        assert isinstance(F, DiagonalBorderedFactor), what
        D = DenseBorderedFactor(pb.jacobian(y), row)
        b = rng.standard_normal(n + 2)
        x, xd = F.solve(b), D.solve(b)
        # backward stable as LAPACK (the residual relative to |A| |x|), and the same solution
        # to the conditioning of A (forward error ~ cond(A) eps for both)
        scale = np.linalg.norm(D.A, np.inf) * np.linalg.norm(x, np.inf)
        assert np.linalg.norm(D.A @ x - b, np.inf) <= 1e-14 * scale, what
        cond = np.linalg.cond(D.A)
        assert np.linalg.norm(x - xd, np.inf) <= 10 * cond * 2.2e-16 * np.linalg.norm(
            xd, np.inf), what
        (s, ld), (sd, ldd) = F.slogdet(), D.slogdet()
        assert s == sd and abs(ld - ldd) <= 1e-10 * abs(ldd), what
        if what == "at a pole":
            assert F.bad.size >= 1  # the vanishing diagonal entry is kept in the dense system


def test_structured_factor_refuses_a_singular_matrix() -> None:
    pb = scaled_chain(60)
    y = closed_form_y(pb, pb.T_lin[0] * 0.999)
    with pytest.raises(np.linalg.LinAlgError):
        pb.bordered_factor(y, np.zeros(62)).solve(np.ones(62))


def test_small_chains_and_the_shooting_formulation_stay_dense() -> None:
    y5 = closed_form_y(scaled_chain(5), scaled_chain(5).T_lin[0] * 0.999)
    assert isinstance(scaled_chain(5).bordered_factor(y5, np.ones(7)), DenseBorderedFactor)
    pb = NDofImpactProblem({"chain": {"dofs": 60, "mass": 1 / 60, "stiffness": 60.0},
                            "gap": 1.0, "formulation": "shooting"})
    y = np.ones(pb.dim)
    assert isinstance(pb.bordered_factor(y, np.ones(pb.dim)), DenseBorderedFactor)


def test_a_run_with_structured_solves_is_the_dense_run() -> None:
    """Mode 1 of a 60-dof chain with stability and events, structured and dense: the same
    points (to the corrector's tolerance) and the same events."""
    runs = []
    for dense in (False, True):
        pb = scaled_chain(60)
        if dense:
            pb.DENSE_SOLVES_UP_TO = 10**6
        st = ContinuationSettings(max_points=60, step_initial=1e-3, direction=-1,
                                  stability_on_phantom=True, newton_tol=1e-10)
        T = pb.T_lin[0] * (1 - 1e-4)
        br = ContinuationEngine(pb, st).run(StartPoint(closed_form_y(pb, T), "b1", -1))
        runs.append(br)
    a, b = runs
    assert len(a.points) == len(b.points) == 60
    ya = np.array([p.y for p in a.points])
    yb = np.array([p.y for p in b.points])
    assert np.abs(ya - yb).max() <= 1e-8
    ka = [(e.kind, round(float(e.point.y[-1]), 7)) for e in a.events]
    kb = [(e.kind, round(float(e.point.y[-1]), 7)) for e in b.events]
    assert ka == kb and len([e for e in a.events if e.kind != "endpoint"]) >= 1
