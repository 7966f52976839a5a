"""The routines a run of the chain uses instead of SciPy's (importing ``scipy.linalg`` and
``scipy.optimize`` costs 0.3 s of the default case), checked against the
SciPy originals: Brent's bounded minimisation step for step, the generalised symmetric
eigenproblem of the modal analysis (2.9), and the roots of ``w_N`` (Illinois instead of
``brentq``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sla
from nsm_continuation.problems.chain.ndof_impact import (
    NDofImpactProblem,
    chain_case_matrices,
    generalized_eigh,
)
from scipy.optimize import brentq, minimize_scalar

from nsm_continuation.core.scalar_search import bounded_minimum

FUNCTIONS = {
    "quartic": (lambda x: (x - 0.3) ** 4 - 0.1 * x, -1.0, 2.0, 1e-9, 500),
    "kink": (lambda x: abs(x - math.pi / 7), 0.0, 1.0, 1e-12, 500),
    "cosine": (lambda x: math.cos(3 * x), 0.0, 2.0, 1e-7, 500),
    "minimum at the lower end": (lambda x: x * x, 0.5, 3.0, 1e-10, 500),
    "minimum at the upper end": (lambda x: -x, -2.0, 5.0, 1e-10, 500),
    "constant": (lambda x: 1.0, 0.0, 1.0, 1e-8, 500),
    "failures as inf": (lambda x: math.inf if 0.2 < x < 0.4 else (x - 0.6) ** 2,
                        0.0, 1.0, 1e-10, 500),
    "cut by maxiter": (lambda x: (x - 0.123456789) ** 2, 0.0, 1.0, 1e-14, 7),
    "empty interval": (lambda x: x, 1.5, 1.5, 1e-8, 500),
}


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # SciPy's
@pytest.mark.parametrize("name", list(FUNCTIONS))
def test_bounded_minimum_is_scipys_bounded_brent_step_for_step(name):
    """The same minimiser, value and number of evaluations as
    ``minimize_scalar(method="bounded")``, to the last bit, and the same abscissae visited."""
    f, lo, hi, xatol, maxiter = FUNCTIONS[name]
    ours_x: list[float] = []
    theirs_x: list[float] = []
    x, fx, n = bounded_minimum(lambda t: (ours_x.append(t), f(t))[1], lo, hi, xatol, maxiter)
    ref = minimize_scalar(lambda t: (theirs_x.append(float(t)), f(t))[1], bounds=(lo, hi),
                          method="bounded", options={"xatol": xatol, "maxiter": maxiter})
    assert (x, fx, n) == (float(ref.x), float(ref.fun), int(ref.nfev))
    assert ours_x == theirs_x


def test_bounded_minimum_finds_the_minimum_to_its_tolerance():
    """Against the closed form: the minimum of ``|x - c| (1 + x)`` (a kink: no flat bottom
    whose values round to equal) is found within twice Brent's tolerance ``xatol / 3 +
    sqrt(eps) |c|`` of ``c``; bad bounds are refused."""
    for c in (0.1, 0.5, 0.987654321):
        x, fx, _ = bounded_minimum(lambda t, c=c: abs(t - c) * (1 + t), 0.0, 1.0, xatol=1e-10)
        assert abs(x - c) <= 2 * (1e-10 / 3 + 1.5e-8 * c) and fx == abs(x - c) * (1 + x)
    for lo, hi in ((1.0, 0.0), (0.0, math.inf), (math.nan, 1.0)):
        with pytest.raises(ValueError, match="bounds"):
            bounded_minimum(lambda t: t, lo, hi)


def _spd(n: int, rng: np.random.Generator) -> np.ndarray:
    A = rng.standard_normal((n, n))
    return A @ A.T + n * np.eye(n)


@pytest.mark.parametrize("n", [2, 5, 30])
def test_generalized_eigh_solves_the_modal_problem_as_scipy(n):
    """``K P = M P diag(w2)``, ``P^T M P = I``, ascending ``w2``: the eigenvalues of
    ``scipy.linalg.eigh(K, M)`` to 1e-13 and the same mode shapes up to sign, for a full
    mass matrix and the chain's diagonal one (bit for bit for the paper's 5-dof chain: its
    bundled results do not move)."""
    rng = np.random.default_rng(n)
    M, K = _spd(n, rng), _spd(n, rng)
    w2, P = generalized_eigh(K, M)
    ref_w2, ref_P = sla.eigh(K, M)
    assert np.all(np.diff(w2) > 0)
    np.testing.assert_allclose(w2, ref_w2, rtol=0, atol=1e-14 * ref_w2[-1])
    signs = np.sign(np.sum(P * ref_P, axis=0))
    np.testing.assert_allclose(P * signs, ref_P, atol=1e-10 * np.abs(ref_P).max())
    np.testing.assert_allclose(P.T @ M @ P, np.eye(n), atol=1e-13)
    np.testing.assert_allclose(K @ P, M @ P * w2, atol=1e-12 * np.abs(K).max())
    Mc, Kc = chain_case_matrices(max(n, 5))
    w2c, Pc = generalized_eigh(Kc, Mc)
    ref_w2c, ref_Pc = sla.eigh(Kc, Mc)
    # both backward stable: eigenvalues agree to rounding of the largest one
    np.testing.assert_allclose(w2c, ref_w2c, rtol=0, atol=1e-14 * ref_w2c[-1])
    np.testing.assert_allclose(Pc, ref_Pc, atol=1e-12 * np.abs(ref_Pc).max())
    if n == 5:
        assert np.array_equal(w2c, ref_w2c) and np.array_equal(Pc, ref_Pc)


def test_generalized_eigh_refuses_a_mass_matrix_that_is_not_positive_definite():
    with pytest.raises(np.linalg.LinAlgError):
        generalized_eigh(np.eye(3), np.diag([1.0, -1.0, 1.0]))


def test_roots_of_w_N_are_brentqs():
    """The roots of ``w_N`` (Illinois between grid points) against ``brentq`` on the same
    brackets, for the paper's 5-dof chain on [0.3, 5]: the same count, the same roots to
    2e-15 relative, and ``w_N`` vanishes there to rounding."""
    pr = NDofImpactProblem({"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0})
    roots = pr.zeros_of_w_N(0.3, 5.0)
    ref = []
    poles = [p[0] for p in pr.poles(1e-12, 5.0 * (1 + 1e-12), 1000)]
    edges = sorted({0.3, 5.0, *[p for p in poles if 0.3 < p < 5.0]})
    for lo, hi in zip(edges[:-1], edges[1:], strict=False):
        grid = np.linspace(lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo), 400)
        vals = pr.w_N(grid)
        for i in np.nonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))[0]:
            r = brentq(lambda t: float(pr.w_N(t)), grid[i], grid[i + 1], xtol=1e-15,
                       rtol=4 * np.finfo(float).eps)
            if abs(pr.w_N(r)) < 1e-6 * (1 + abs(vals[i]) + abs(vals[i + 1])):
                ref.append(r)
    assert len(roots) == len(ref) > 10
    np.testing.assert_allclose(roots, ref, rtol=2e-15)
