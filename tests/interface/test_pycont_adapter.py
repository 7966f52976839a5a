"""pycont-lite, driven through nsm_continuation.adapters.pycont, follows our branches.

The oracle is independent of both continuation codes: the closed form (4.2) of Legrand et al.
(2017) at each point's own period, ``NDofImpactProblem.closed_form(T)``.
"""

from __future__ import annotations

import sys
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from oracles.scaled_chain import closed_form_y
from pydantic import BaseModel

from nsm_continuation.adapters.pycont import (
    PYCONT_MISSING,
    as_pycont_system,
    correct_at_fixed_parameter,
    run_pycont,
)
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.settings import ContinuationSettings

PAPER_CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: branch 1 window: from 0.99 T_1 down to 0.93 T_1 (smooth, no pole or zero of w_N inside)
T_START, T_STOP = 0.99, 0.93
TOL = 1e-10  # pycont's corrector tolerance (max norm of the extended residual)


@pytest.fixture(scope="module")
def paper_problem() -> NDofImpactProblem:
    return NDofImpactProblem(PAPER_CHAIN)


def distance_to_closed_form(problem: NDofImpactProblem, ys: np.ndarray) -> np.ndarray:
    """Relative max-norm distance of each point to the closed form at its own T."""
    out = []
    for y in ys:
        yc = closed_form_y(problem, y[problem.parameter_index])
        out.append(np.max(np.abs(y - yc)) / np.max(np.abs(yc)))
    return np.array(out)


class CircleProblem(Problem):
    """x^2 + p^2 = 1, z = x, with the parameter p in the *middle* of y = (x, p, z)."""

    name: ClassVar[str] = "circle_test"

    class Parameters(BaseModel):
        pass

    def __init__(self) -> None:
        super().__init__(self.Parameters())
        self.variables = ["x", "p", "z"]
        self.parameter = "p"

    def residual(self, y: Any) -> Any:
        return ca.vertcat(y[0] ** 2 + y[1] ** 2 - 1.0, y[2] - y[0])


# ---------------------------------------------------------------------- no pycont needed
def test_split_join_roundtrip_parameter_in_the_middle() -> None:
    problem = CircleProblem()
    G, split, join = as_pycont_system(problem)
    y = np.array([0.6, 0.8, -2.0])
    u, p = split(y)
    np.testing.assert_array_equal(u, [0.6, -2.0])
    assert p == 0.8
    np.testing.assert_array_equal(join(u, p), y)
    np.testing.assert_allclose(G(u, p), problem.evaluate(y), rtol=0, atol=0)
    assert G.n_calls == 1


def test_residual_is_the_problem_residual(paper_problem: NDofImpactProblem) -> None:
    G, split, _ = as_pycont_system(paper_problem)
    rng = np.random.default_rng(0)
    for _ in range(5):
        y = rng.normal(size=paper_problem.dim)
        y[-1] = abs(y[-1]) + 1.0
        u, p = split(y)
        assert u.shape == (paper_problem.dim - 1,)
        np.testing.assert_array_equal(G(u, p), paper_problem.evaluate(y))


def test_complex_arguments_are_rejected() -> None:
    G, _, _ = as_pycont_system(CircleProblem())
    with pytest.raises(TypeError, match="complex"):
        G(np.array([1.0 + 1e-3j, 0.0]), 0.0)
    # a complex array with zero imaginary part is just real
    np.testing.assert_allclose(G(np.array([1.0 + 0j, 1.0]), 0.0), [0.0, 0.0])


def test_missing_pycont_gives_install_hint(monkeypatch: pytest.MonkeyPatch,
                                           paper_problem: NDofImpactProblem) -> None:
    monkeypatch.setitem(sys.modules, "pycont", None)  # makes `import pycont` raise ImportError
    y0 = closed_form_y(paper_problem, T_START * paper_problem.T_lin[0])
    with pytest.raises(ImportError) as info:
        run_pycont(paper_problem, y0, n_steps=2)
    assert "pip install nsm-continuation[pycont]" in str(info.value)
    assert str(info.value) == PYCONT_MISSING


def test_correct_at_fixed_parameter_keeps_the_parameter(
        paper_problem: NDofImpactProblem) -> None:
    T = 0.95 * paper_problem.T_lin[0]
    y_exact = closed_form_y(paper_problem, T)
    guess = y_exact * (1 + 1e-3 * np.arange(paper_problem.dim) / paper_problem.dim)
    guess[-1] = T
    y = correct_at_fixed_parameter(paper_problem, guess)
    assert y[-1] == T
    np.testing.assert_allclose(y, y_exact, rtol=1e-12, atol=1e-12)


# ---------------------------------------------------------------------- with pycont
@pytest.fixture(scope="module")
def pycont_branch(paper_problem: NDofImpactProblem) -> np.ndarray:
    pytest.importorskip("pycont")
    T1 = paper_problem.T_lin[0]
    y0 = closed_form_y(paper_problem, T_START * T1)
    return run_pycont(paper_problem, y0, ds_min=1e-6, ds_max=0.1, ds_0=1e-2, n_steps=40,
                      direction=-1, tolerance=TOL, param_min=T_STOP * T1,
                      bifurcation_detection=False)


@pytest.fixture(scope="module")
def engine_branch(paper_problem: NDofImpactProblem) -> np.ndarray:
    T1 = paper_problem.T_lin[0]
    y0 = closed_form_y(paper_problem, T_START * T1)
    settings = ContinuationSettings(direction=-1, param_min=T_STOP * T1, max_points=5000,
                                    detect_bifurcations=False)
    branch = ContinuationEngine(paper_problem, settings).run(StartPoint(y0, "branch 1", -1))
    assert branch.points, branch.termination
    return np.array([p.y for p in branch.points])


def test_pycont_points_satisfy_our_residual(paper_problem: NDofImpactProblem,
                                            pycont_branch: np.ndarray) -> None:
    assert len(pycont_branch) >= 10
    res = np.array([np.max(np.abs(paper_problem.evaluate(y))) for y in pycont_branch])
    # newton_krylov stops at |[G; arclength eq]|_inf <= TOL; pycont's fallback acceptance
    # (2-norm <= 10 max(TOL, rdiff)) would show up here as a larger residual
    assert res.max() <= 10 * TOL, res


def test_pycont_points_agree_with_closed_form(paper_problem: NDofImpactProblem,
                                              pycont_branch: np.ndarray) -> None:
    err = distance_to_closed_form(paper_problem, pycont_branch)
    # residual ~TOL, Jacobian of the branch well conditioned in this window
    assert err.max() <= 100 * TOL, err


def test_pycont_goes_towards_decreasing_period(paper_problem: NDofImpactProblem,
                                               pycont_branch: np.ndarray) -> None:
    T1 = paper_problem.T_lin[0]
    T = pycont_branch[:, -1]
    assert T[0] == pytest.approx(T_START * T1, rel=1e-14)
    assert np.all(np.diff(T) < 0)
    assert T[-1] == pytest.approx(T_STOP * T1, rel=1e-9)


def test_same_branch_as_engine(paper_problem: NDofImpactProblem, pycont_branch: np.ndarray,
                               engine_branch: np.ndarray) -> None:
    T1 = paper_problem.T_lin[0]
    Tp, Te = pycont_branch[:, -1], engine_branch[:, -1]
    lo, hi = max(Tp.min(), Te.min()), min(Tp.max(), Te.max())
    assert hi - lo >= 0.9 * (T_START - T_STOP) * T1  # overlapping T ranges
    # the engine's points are on the closed form too ...
    assert distance_to_closed_form(paper_problem, engine_branch).max() <= 1e-10
    # ... and the two codes agree where they overlap: interpolate the engine branch (dense in T,
    # smooth) at pycont's periods, component by component, with a cubic through 4 neighbours
    order = np.argsort(Te)
    Te_s, Ye_s = Te[order], engine_branch[order]
    for y in pycont_branch:
        T = y[-1]
        if not lo <= T <= hi:
            continue
        k = int(np.clip(np.searchsorted(Te_s, T) - 2, 0, len(Te_s) - 4))
        coef = np.polyfit(Te_s[k:k + 4] - T, Ye_s[k:k + 4, :-1], 3)
        np.testing.assert_allclose(coef[-1], y[:-1], rtol=0, atol=1e-6)


def test_parameter_in_the_middle_and_fold() -> None:
    """A circle x^2 + p^2 = 1 continued from p = 0 in increasing p turns at the fold p = 1:
    pycont restarts a segment there; run_pycont chains it onto the branch."""
    pytest.importorskip("pycont")
    problem = CircleProblem()
    y0 = np.array([1.0, 0.0, 1.0])
    ys = run_pycont(problem, y0, ds_min=1e-6, ds_max=0.05, ds_0=1e-2, n_steps=60,
                    direction=1, tolerance=1e-12, bifurcation_detection=False)
    assert ys.shape[1] == 3
    res = np.abs(ys[:, 0] ** 2 + ys[:, 1] ** 2 - 1.0) + np.abs(ys[:, 2] - ys[:, 0])
    # pycont-lite 0.6 places its fold point on the chord between the two bracketing points
    # (x_left + alpha (x_right - x_left)) without correcting it: O(ds^2) off the curve there
    off = np.flatnonzero(res > 1e-9)
    assert len(off) <= 1 and res[off].max(initial=0.0) <= 0.05**2 * 4, res[off]
    assert ys[:, 1].max() == pytest.approx(1.0, abs=1e-2)  # reached the fold ...
    assert ys[-1, 0] < -0.1  # ... and went round it to x < 0
    angle = np.unwrap(np.arctan2(ys[:, 1], ys[:, 0]))
    assert np.all(np.diff(angle) > 0)  # one ordered path, counter-clockwise all the way round
