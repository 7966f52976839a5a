"""Physics of the N-dof impact oscillator (Legrand, Junca, Heng 2017) against independent oracles.

Every oracle here is computed without the problem's own modal machinery: the modal matrix comes
from ``numpy.linalg.eigh`` of ``L^-1 K L^-T`` (``M = L L^T``), trajectories from
``scipy.integrate.solve_ivp`` (DOP853) or ``scipy.linalg.expm`` of the first-order system,
derivatives from central finite differences, and the rest from closed forms of the paper (eq.
numbers refer to it). The paper's example is the chain (2.17) with ``N = 5`` (``m = 0.2``,
``k = 5``), impacting dof ``c = N``, gap ``g = 1``.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem, simulate_first_return
from scipy.integrate import solve_ivp
from scipy.linalg import expm
from scipy.optimize import fsolve, linear_sum_assignment, minimize_scalar

from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.records import Branch
from nsm_continuation.core.settings import ContinuationSettings

PAPER_CHAIN = {"dofs": 5, "mass": 0.2, "stiffness": 5.0}
FORMULATIONS = ("half_angle", "shooting")
HYP = settings(max_examples=25, deadline=None)


# ---------------------------------------------------------------------------------------------
# independent oracle
# ---------------------------------------------------------------------------------------------
class Modal:
    """Modal data and closed-form orbits of ``M u'' + K u = 0`` with a wall on dof ``c``,
    written from the paper's formulas without using :class:`NDofImpactProblem`."""

    def __init__(self, M: np.ndarray, K: np.ndarray, c: int, g: float) -> None:
        self.M, self.K, self.c, self.g = np.asarray(M, float), np.asarray(K, float), c, g
        L = np.linalg.cholesky(self.M)
        Li = np.linalg.inv(L)
        w2, Z = np.linalg.eigh(Li @ self.K @ Li.T)
        self.w = np.sqrt(w2)
        self.P = Li.T @ Z  # P^T M P = I, P^T K P = diag(w^2)   (2.9)
        self.Pinv = self.P.T @ self.M
        self.a = self.P[c, :] * self.Pinv[:, c]  # (2.11)
        self.T_lin = 2 * np.pi / self.w
        self.N = len(self.w)

    def phi(self, T: float) -> np.ndarray:  # (3.1)/(4.1a)
        return np.sin(self.w * T) / (self.w * (1 - np.cos(self.w * T)))

    def w_vec(self, T: float) -> np.ndarray:  # (4.1b)
        return self.P @ (self.phi(T) * self.Pinv[:, self.c])

    def w_N(self, T: float) -> float:
        return float(np.sum(self.a * self.phi(T)))

    def x0(self, T: float, g: float | None = None) -> np.ndarray:
        """Initial data (4.2)/(7.1): ``(u(0), u'(0+)) = (g / w_N(T)) (w(T), e_c)``."""
        g = self.g if g is None else g
        e = np.zeros(self.N)
        e[self.c] = 1.0
        return g / self.w_N(T) * np.concatenate([self.w_vec(T), e])

    def uc(self, t: float | np.ndarray, T: float) -> np.ndarray:
        """``u_c(t; T)`` on ``(0, T)``, eq. (7.3)."""
        t = np.asarray(t, dtype=float)[..., None]
        b = self.Pinv[:, self.c]
        coef = self.P[self.c] * b
        return self.g / self.w_N(T) * np.sum(
            coef * (np.cos(self.w * t) * self.phi(T) + np.sin(self.w * t) / self.w), axis=-1)

    def duc(self, t: float | np.ndarray, T: float) -> np.ndarray:
        t = np.asarray(t, dtype=float)[..., None]
        coef = self.P[self.c] * self.Pinv[:, self.c]
        return self.g / self.w_N(T) * np.sum(
            coef * (-self.w * np.sin(self.w * t) * self.phi(T) + np.cos(self.w * t)), axis=-1)

    def gamma(self, T: float) -> np.ndarray:
        """Flight then impact (A.1), from the matrix exponential of the first-order system."""
        N = self.N
        A = np.block([[np.zeros((N, N)), np.eye(N)],
                      [-np.linalg.solve(self.M, self.K), np.zeros((N, N))]])
        J = np.eye(2 * N)
        J[N + self.c, N + self.c] = -1.0
        return J @ expm(A * T), J @ A @ expm(A * T)

    def poles(self, T_hi: float) -> np.ndarray:
        return np.sort([k * Tj for Tj in self.T_lin for k in range(1, int(T_hi / Tj) + 2)])

    def pole_distance(self, T: float) -> float:
        """Relative distance of ``T`` to the nearest pole ``k T_j`` of ``w_N``."""
        return float(np.min(np.abs(self.poles(2 * T) - T)) / T)


def chain_matrices(masses, stiffnesses) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (2.17): wall - k_1 - m_1 - k_2 - m_2 ... - k_N - m_N (free end)."""
    m, k = np.asarray(masses, float), np.asarray(stiffnesses, float)
    n = len(m)
    K = np.diag(k.copy())
    K[:-1, :-1] += np.diag(k[1:])
    for i in range(1, n):
        K[i - 1, i] = K[i, i - 1] = -k[i]
    return np.diag(m), K


def random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


@cache
def paper(formulation: str = "half_angle", gap: float = 1.0) -> NDofImpactProblem:
    return NDofImpactProblem({"chain": PAPER_CHAIN, "gap": gap, "formulation": formulation})


@cache
def paper_oracle(gap: float = 1.0) -> Modal:
    M, K = chain_matrices([0.2] * 5, [5.0] * 5)
    return Modal(M, K, 4, gap)


@cache
def random_system(seed: int, formulation: str = "half_angle") -> tuple[NDofImpactProblem, Modal]:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 6))
    M, K = random_spd(rng, n), random_spd(rng, n)
    g = float(rng.uniform(0.3, 2.0))
    p = NDofImpactProblem({"M": M.tolist(), "K": K.tolist(), "gap": g,
                           "formulation": formulation})
    return p, Modal(p.M, p.K, n - 1, g)


def point(p: NDofImpactProblem, T: float) -> np.ndarray:
    u0, du0 = p.closed_form(T)
    return p.y_from_state(u0, du0, T)


def multiset_distance(x: np.ndarray, y: np.ndarray, relative: bool = True) -> float:
    x, y = np.asarray(x, dtype=complex), np.asarray(y, dtype=complex)
    assert x.shape == y.shape, (x.shape, y.shape)
    if x.size == 0:
        return 0.0
    cost = np.abs(x[:, None] - y[None, :])
    if relative:
        cost = cost / np.maximum(1.0, np.abs(y))[None, :]
    r, c = linear_sum_assignment(cost)
    return float(cost[r, c].max())


def null_tangent(p: NDofImpactProblem, y: np.ndarray) -> np.ndarray:
    return np.linalg.svd(p.jacobian(y))[2][-1]


# ---------------------------------------------------------------------------------------------
# a. interaction coefficients
# ---------------------------------------------------------------------------------------------
@HYP
@given(data=st.data(), n=st.integers(1, 8))
def test_interaction_coefficients_of_chains(data, n: int) -> None:
    """(2.12) ``sum_j a_j = 1``; (2.16) for a diagonal mass matrix ``a_j = m_c P_cj^2 >= 0``, and
    ``> 0`` at the free end ``c = N`` (last components of the eigenvectors of a Jacobi matrix
    never vanish); also the chain matrices (2.17) and the frequencies."""
    pos = st.floats(0.1, 10.0)
    masses = data.draw(st.lists(pos, min_size=n, max_size=n), label="masses")
    stiff = data.draw(st.lists(pos, min_size=n, max_size=n), label="stiffnesses")
    c = data.draw(st.integers(1, n), label="impacting dof")
    p = NDofImpactProblem({"chain": {"dofs": n, "mass": masses, "stiffness": stiff}, "gap": 1.0,
                           "impacting_dof": c})
    M, K = chain_matrices(masses, stiff)
    assert np.allclose(p.M, M, rtol=0, atol=0) and np.allclose(p.K, K, rtol=1e-15, atol=0)
    o = Modal(M, K, c - 1, 1.0)
    assert np.allclose(p.omega, o.w, rtol=1e-10)
    assert abs(np.sum(p.a) - 1.0) < 1e-12
    expected = masses[c - 1] * o.P[c - 1, :] ** 2
    assert np.allclose(p.a, expected, rtol=1e-8, atol=1e-12)
    assert np.all(p.a >= -1e-15)
    if c == n:
        assert np.all(p.a > 0)
        assert np.all(expected > 0)


@HYP
@given(n=st.integers(1, 6), seed=st.integers(0, 2**31 - 1))
def test_interaction_coefficients_general_spd(n: int, seed: int) -> None:
    """(2.11)-(2.12) for full SPD ``M, K``: ``a_j = P_cj (P^-1)_jc`` sums to 1 (signs free)."""
    rng = np.random.default_rng(seed)
    M, K = random_spd(rng, n), random_spd(rng, n)
    p = NDofImpactProblem({"M": M.tolist(), "K": K.tolist(), "gap": 1.0})
    o = Modal(p.M, p.K, n - 1, 1.0)
    assert abs(np.sum(p.a) - 1.0) < 1e-12
    assert np.allclose(p.a, o.a, atol=1e-10)


# ---------------------------------------------------------------------------------------------
# b. closed form (4.2): residual, full fixed point, symmetry, independent simulation
# ---------------------------------------------------------------------------------------------
def _check_closed_form(p: NDofImpactProblem, o: Modal, T: float) -> None:
    u0, du0 = p.closed_form(T)
    x = np.concatenate([u0, du0])
    scale = np.max(np.abs(x))
    assert np.max(np.abs(x - o.x0(T))) <= 1e-9 * scale  # same data as the oracle's (4.2)
    assert abs(u0[p.c] - p.g) <= 1e-12 * scale  # on the section
    y = p.y_from_state(u0, du0, T)
    assert np.max(np.abs(p.evaluate(y))) <= 1e-10 * max(1.0, np.max(np.abs(y)))
    G, _ = p.gamma(T)
    assert np.linalg.norm(G @ x - x) <= 1e-10 * np.linalg.norm(x)  # (R(T) - I) Q = 0 in full


@HYP
@given(T=st.floats(0.2, 12.0), formulation=st.sampled_from(FORMULATIONS))
def test_closed_form_paper_chain(T: float, formulation: str) -> None:
    o = paper_oracle()
    assume(o.pole_distance(T) > 1e-3 and abs(o.w_N(T)) > 1e-6)
    _check_closed_form(paper(formulation), o, T)


@HYP
@given(seed=st.integers(0, 7), frac=st.floats(0.2, 3.0), formulation=st.sampled_from(FORMULATIONS))
def test_closed_form_random_spd(seed: int, frac: float, formulation: str) -> None:
    p, o = random_system(seed, formulation)
    T = frac * o.T_lin[0]
    assume(o.pole_distance(T) > 1e-3 and abs(o.w_N(T)) > 1e-6)
    _check_closed_form(p, o, T)


@pytest.mark.parametrize("T", [0.5, 1.45, 3.95, 4.2, 7.7])
def test_gamma_is_flight_then_impact(T: float) -> None:
    """``Gamma(T)`` (A.1) and ``dGamma/dT`` equal ``J exp(A T)`` and ``J A exp(A T)``."""
    G, dG = paper().gamma(T)
    G_ref, dG_ref = paper_oracle().gamma(T)
    assert np.max(np.abs(G - G_ref)) <= 1e-11 * np.max(np.abs(G_ref))
    assert np.max(np.abs(dG - dG_ref)) <= 1e-11 * np.max(np.abs(dG_ref))


def _integrate(M, K, x0, T, rtol=1e-12):
    N = len(M)
    MK = np.linalg.solve(M, K)

    def rhs(_t, z):
        return np.concatenate([z[N:], -MK @ z[:N]])

    return solve_ivp(rhs, (0.0, T), x0, method="DOP853", rtol=rtol,
                     atol=1e-13 * np.max(np.abs(x0)), dense_output=True)


@pytest.mark.parametrize(("system", "T"), [("paper", 0.5), ("paper", 1.45), ("paper", 3.95),
                                           ("paper", 4.2), ("paper", 7.7), ("random", 1.7)])
def test_symmetry_and_periodicity_by_simulation(system: str, T: float) -> None:
    """Prop. 4.1.3: ``u(T/2 + t) = u(T/2 - t)`` and ``u'(T/2) = 0``; Def. 2.1: the free flight
    from the closed-form data returns to ``u(0)`` at ``t = T`` with ``u_c(T) = g`` and
    ``u'(T-) = S u'(0+)``. Holds for every solution of the extended formulation (admissible or
    phantom); the flight is integrated by DOP853, independently of the modal closed form."""
    if system == "paper":
        p = paper()
    else:
        p, o = random_system(3)
        T = T * o.T_lin[0]
        assert o.pole_distance(T) > 1e-2
    u0, du0 = p.closed_form(T)
    x0 = np.concatenate([u0, du0])
    N, c = p.N, p.c
    sol = _integrate(p.M, p.K, x0, T)
    scale = np.max(np.abs(x0))
    t = np.linspace(0.0, T / 2, 13)
    plus, minus = sol.sol(T / 2 + t), sol.sol(T / 2 - t)
    assert np.max(np.abs(plus[:N] - minus[:N])) <= 1e-8 * scale
    assert np.max(np.abs(sol.sol(T / 2)[N:])) <= 1e-8 * scale * np.max(p.omega)
    xT = sol.y[:, -1]
    assert np.max(np.abs(xT[:N] - u0)) <= 1e-8 * scale
    assert abs(xT[c] - p.g) <= 1e-8 * scale
    S = np.ones(N)
    S[c] = -1.0
    assert np.max(np.abs(xT[N:] - S * du0)) <= 1e-8 * scale * np.max(p.omega)


# ---------------------------------------------------------------------------------------------
# c. rank of the residual Jacobian and of the full linear system
# ---------------------------------------------------------------------------------------------
def _branch_samples(o: Modal, lo: float, hi: float, n: int = 25) -> list[float]:
    return [float(T) for T in np.linspace(lo, hi, n) if o.pole_distance(T) > 1e-2]


@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_jacobian_full_row_rank_along_branches(formulation: str) -> None:
    """Away from the poles ``k T_j`` the residual Jacobian has full row rank on branch 1
    (``T`` in (3.94, 0.99 T_1)) and branch 2 (``T`` in (1.40, 0.99 T_2))."""
    p, o = paper(formulation), paper_oracle()
    samples = (_branch_samples(o, 3.94, 0.99 * o.T_lin[0])
               + _branch_samples(o, 1.40, 0.99 * o.T_lin[1]))
    assert len(samples) > 30
    for T in samples:
        J = p.jacobian(point(p, T))
        assert J.shape == (p.dim - 1, p.dim)
        s = np.linalg.svd(J, compute_uv=False)
        assert s[-1] > 1e-6 * s[0], (T, s[-1] / s[0])


@pytest.mark.parametrize("T", [1.4, 3.0, 4.2, 7.7])
def test_full_fixed_point_system_rank_and_redundant_rows(T: float) -> None:
    """``[Gamma(T) - I; e_c^T]`` (2N+1 rows, 2N unknowns) has rank 2N: one row is redundant.

    What is true (left null vector ``l`` of ``Gamma - I``, Lemma 4.1 / (4.6)): ``l`` is supported
    on the N position rows and the c-th velocity row only. Hence removing the c-th velocity row
    (``u_c'(T-) = -u_c'(0+)``) or any position row keeps rank 2N, while removing one of the other
    velocity rows (the conditions ``u_k'(0) = 0``, k != c) or the section row ``u_c(0)`` drops the
    rank to 2N - 1. The c-th velocity row is the one the shooting formulation leaves out.
    """
    p = paper("shooting")
    N, c = p.N, p.c
    G, _ = p.gamma(T)
    A = G - np.eye(2 * N)
    ec = np.zeros(2 * N)
    ec[c] = 1.0
    F = np.vstack([A, ec])
    tol = 1e-10 * np.linalg.norm(F, 2)

    def rank(X):
        return int(np.linalg.matrix_rank(X, tol=tol))

    assert rank(A) == 2 * N - 1
    assert rank(F) == 2 * N
    U, s, _ = np.linalg.svd(A)
    l_vec = U[:, -1] / np.max(np.abs(U[:, -1]))
    vel_other = [N + k for k in range(N) if k != c]
    assert np.max(np.abs(l_vec[vel_other])) < 1e-10
    assert abs(l_vec[N + c]) > 1e-3 and np.min(np.abs(l_vec[:N])) > 1e-3
    for i in range(2 * N + 1):
        expected = 2 * N if (i < N or i == N + c) else 2 * N - 1
        assert rank(np.delete(F, i, axis=0)) == expected, i


@pytest.mark.parametrize(("j", "k"), [(0, 1), (1, 1), (2, 3), (3, 2)])
def test_rank_at_poles(j: int, k: int) -> None:
    """At a pole ``T = k T_j`` (the linear grazing orbit (2.14)) both formulations are solved,
    the half-angle Jacobian keeps full rank, the shooting Jacobian does not.

    Why the shooting rank drops: at ``T = k T_j`` every phase of linear mode ``j``,
    ``u(0) = A cos(phi) P_j``, ``u'(0) = -A w_j sin(phi) P_j`` with ``A cos(phi) P_cj = g``, is
    ``T``-periodic, so it satisfies all the retained rows (``u(T) = u(0)``, ``u_k'(T) = u_k'(0)``
    for ``k != c``, ``u_c(0) = g``) while violating only the dropped c-th velocity row. The
    solution set at fixed ``T`` is then a curve crossing the branch: a branch point. The
    half-angle form divides the factor ``2 sin(w_j T/2)`` out and has no such curve.
    """
    ph, ps = paper("half_angle"), paper("shooting")
    for p in (ph, ps):
        y = p.grazing_start(j, k)
        assert y[-1] == pytest.approx(k * paper_oracle().T_lin[j], rel=1e-14)
        assert np.max(np.abs(p.evaluate(y))) < 1e-13
    s = np.linalg.svd(ph.jacobian(ph.grazing_start(j, k)), compute_uv=False)
    assert s[-1] > 1e-3 * s[0]
    s = np.linalg.svd(ps.jacobian(ps.grazing_start(j, k)), compute_uv=False)
    assert s[-1] < 1e-12 * s[0]
    # the family of spurious shooting solutions at fixed T (see docstring)
    o = paper_oracle()
    Pj, wj = o.P[:, j], o.w[j]
    for phi in (0.3, -1.1):
        amp = ps.g / (np.cos(phi) * Pj[ps.c])
        y = ps.y_from_state(amp * np.cos(phi) * Pj, -amp * wj * np.sin(phi) * Pj,
                            k * o.T_lin[j])
        assert np.max(np.abs(ps.evaluate(y))) < 1e-12 * np.max(np.abs(y))
        # ... which are not periodic orbits of the impact problem: the dropped row fails
        G, _ = ps.gamma(k * o.T_lin[j])
        x = y[:-1]
        assert abs((G @ x - x)[ps.N + ps.c]) > 1e-2


# ---------------------------------------------------------------------------------------------
# d. CasADi Jacobian vs finite differences
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize("seed", range(4))
def test_casadi_jacobian_matches_finite_differences(formulation: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    p = paper(formulation)
    o = paper_oracle()
    T = float(rng.uniform(1.0, 8.0))
    while o.pole_distance(T) < 1e-2:
        T = float(rng.uniform(1.0, 8.0))
    y = point(p, T) + 0.1 * rng.normal(size=p.dim)  # on and off the solution set
    J = p.jacobian(y)
    J_fd = np.zeros_like(J)
    for i in range(p.dim):
        h = 1e-6 * (1.0 + abs(y[i]))
        e = np.zeros(p.dim)
        e[i] = h
        J_fd[:, i] = (p.evaluate(y + e) - p.evaluate(y - e)) / (2 * h)
    assert np.max(np.abs(J - J_fd)) <= 1e-7 * np.max(np.abs(J))


# ---------------------------------------------------------------------------------------------
# e. DF (3.5)/(A.8) vs finite differences of the simulated first return map
# ---------------------------------------------------------------------------------------------
# Branch 1 near T_1 and branch 2 near T_2 (admissible side, a_j (T - T_j) < 0). Points closer to
# the pole than ~0.995 T_1 are left out: there u_c'(T) -> 0 and the excursion of the unimpacted
# flow above the wall after t = T lasts 2|u_c'(T)|/|u_c''| ~ 0.01, shorter than a DOP853 step,
# so simulate_first_return can miss the impact event (it raises at T = 0.999 T_1).
DF_POINTS = [(0, 0.90), (0, 0.95), (0, 0.99), (0, 0.995), (1, 0.95), (1, 0.97), (1, 0.98)]


@pytest.mark.parametrize(("mode", "frac"), DF_POINTS)
def test_return_map_jacobian_matches_simulation(mode: int, frac: float) -> None:
    p = paper()
    N, c = p.N, p.c
    T = frac * p.T_lin[mode]
    u0, du0 = p.closed_form(T)
    x = np.concatenate([u0, du0])
    # the simulated first return of the closed-form orbit is itself (fixed point, return time T)
    u1, du1, T1 = simulate_first_return(p, u0, du0, 1.5 * T)
    assert abs(T1 - T) <= 1e-10 * T
    assert np.max(np.abs(np.concatenate([u1, du1]) - x)) <= 1e-10 * np.max(np.abs(x))
    # central differences along the section coordinates (delta u_c = 0)
    h = 1e-6 * np.max(np.abs(x))
    keep = [i for i in range(2 * N) if i != c]
    FD = np.zeros((2 * N, 2 * N))
    for i in keep:
        e = np.zeros(2 * N)
        e[i] = h
        fp = np.concatenate(simulate_first_return(p, u0 + e[:N], du0 + e[N:], 1.5 * T)[:2])
        fm = np.concatenate(simulate_first_return(p, u0 - e[:N], du0 - e[N:], 1.5 * T)[:2])
        FD[:, i] = (fp - fm) / (2 * h)
    DF = p.return_map_jacobian(point(p, T))
    assert np.max(np.abs(DF[c])) <= 1e-12 * np.max(np.abs(DF))  # F(H) in H
    R, R_fd = DF[np.ix_(keep, keep)], FD[np.ix_(keep, keep)]
    assert np.max(np.abs(R - R_fd)) <= 1e-6 * np.max(np.abs(R))
    ev, ev_fd = np.linalg.eigvals(R), np.linalg.eigvals(R_fd)
    assert multiset_distance(ev, ev_fd) <= 1e-6
    assert np.min(np.abs(ev_fd - 1.0)) <= 1e-6  # the family direction, seen by simulation


# ---------------------------------------------------------------------------------------------
# f. Floquet multipliers
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("formulation", FORMULATIONS)
@pytest.mark.parametrize(("mode", "frac"), [(0, 0.974), (0, 0.93), (0, 0.895), (1, 0.95),
                                            (1, 0.98)])
def test_floquet_multipliers_conservative_structure(formulation: str, mode: int,
                                                    frac: float) -> None:
    """For the conservative chain (M diagonal, Prop. 6.1) the first return map restricted to an
    energy level is symplectic: the remaining 2N - 2 multipliers are closed under
    ``lambda -> 1/lambda`` and ``lambda -> conj(lambda)`` (product 1). The removed ones are the
    0 (section normal) and the 1 (family direction, eq. 6.5) of the full DF. Also checked:
    ``DF dx/dT = dx/dT`` with ``dx/dT`` by differences of the oracle's closed form, and
    ``grad E^T DF = grad E^T`` (energy conservation, proof of Corollary 3.1)."""
    p, o = paper(formulation), paper_oracle()
    T = frac * o.T_lin[mode]
    y = point(p, T)
    fl = p.floquet(y, null_tangent(p, y))
    assert fl is not None
    mult = fl.multipliers
    assert mult.shape == (2 * p.N - 2,)
    assert fl.trivial_error < 1e-8
    assert multiset_distance(mult, 1.0 / mult) < 1e-7
    assert multiset_distance(mult, np.conj(mult)) < 1e-7
    assert abs(np.prod(mult) - 1.0) < 1e-7
    DF = p.return_map_jacobian(y)
    assert multiset_distance(np.linalg.eigvals(DF), np.concatenate([[0.0, 1.0], mult])) < 1e-7
    h = 1e-6 * T
    dx = (o.x0(T + h) - o.x0(T - h)) / (2 * h)
    assert np.linalg.norm(DF @ dx - dx) <= 1e-6 * np.linalg.norm(dx)
    u0, du0, _ = p.state(y)
    gradE = np.concatenate([p.K @ u0, p.M @ du0])
    assert np.linalg.norm(gradE @ DF - gradE) <= 1e-10 * np.linalg.norm(gradE) * np.linalg.norm(DF)


# ---------------------------------------------------------------------------------------------
# g. N = 1: everything in closed form
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("m", "k", "g"), [(1.0, 1.0, 1.0), (1.7, 3.1, 0.6), (0.2, 50.0, 2.5)])
@pytest.mark.parametrize("frac", [0.3, 0.51, 0.6, 0.8, 0.99, 1.2, 1.7, 1.9, 2.6, 2.8, 3.55])
def test_single_mass_closed_form(m: float, k: float, g: float, frac: float) -> None:
    """One mass ``m``, spring ``k``, gap ``g > 0``, ``w = sqrt(k/m)``, ``theta = w T / 2``.

    Derivation: ``P = 1/sqrt(m)``, ``a = 1``, ``w_N = cot(theta)/w`` (3.1), so (4.2) gives the
    outgoing velocity ``v = g / w_N = g w tan(theta)``, and on ``(0, T)``
    ``u(t) = g cos(w (t - T/2)) / cos(theta)`` (the symmetric solution with ``u(0) = u(T) = g``).
    Energy (code convention ``E = (m v^2 + k u^2) / 2``, the paper's Prop. 6.1 omits the 1/2):
    ``E = (m g^2 w^2 tan^2 + k g^2) / 2 = m w^2 g^2 / (2 cos^2 theta)``.
    Admissibility: ``v < 0`` iff ``tan(theta) < 0``; the interior critical points of ``u`` are
    ``w (t - T/2) = n pi`` with ``|n pi| < theta``, with values ``g (-1)^n / cos(theta)``, so
    ``clearance = 1 - max_n (-1)^n / cos(theta)``. Both are positive exactly for
    ``T in (T1/2, T1)``; for ``T in ((k - 1/2) T1, k T1)``, ``k >= 2``, ``v < 0`` but the mass
    crosses the wall at ``w (t - T/2) = pi`` (``u = g / |cos(theta)| > g``).
    """
    p = NDofImpactProblem({"chain": {"dofs": 1, "mass": m, "stiffness": k}, "gap": g})
    w = np.sqrt(k / m)
    T1 = 2 * np.pi / w
    T = frac * T1
    th = w * T / 2
    y = point(p, T)
    d = p.derived(y)
    assert d["v_out"] == pytest.approx(g * w * np.tan(th), rel=1e-12)
    assert d["w_N"] == pytest.approx(1 / (w * np.tan(th)), rel=1e-12)
    assert p.energy(y) == pytest.approx(0.5 * m * w**2 * g**2 / np.cos(th) ** 2, rel=1e-12)
    assert d["energy"] == pytest.approx(p.energy(y), rel=1e-15)
    tests = p.admissibility(y)
    assert tests["outgoing_velocity"] == pytest.approx(-np.tan(th), rel=1e-12)
    n = np.arange(-int(th / np.pi) - 1, int(th / np.pi) + 2)
    n = n[np.abs(n * np.pi) < th]
    clearance = 1 - np.max((-1.0) ** n / np.cos(th))
    assert tests["clearance"] == pytest.approx(clearance, rel=1e-10, abs=1e-12)
    admissible = all(v > 0 for v in tests.values())
    assert admissible == (0.5 < frac < 1.0)
    if frac > 1 and (frac % 1.0) > 0.5:  # ((k - 1/2) T1, k T1), k >= 2
        assert tests["outgoing_velocity"] > 0 and tests["clearance"] < 0


@pytest.mark.parametrize("formulation", ["half_angle", "shooting"])
@pytest.mark.parametrize("j", range(5))
def test_clearance_past_a_linear_grazing_is_quadratic_not_noise(j: int, formulation: str) -> None:
    """Past the linear grazing orbit of mode ``j`` (``T = T_j (1 + d)``, the outgoing velocity
    ``v = u_c'(0+)`` through zero into the wall) a maximum of ``u_c`` enters at ``t* = -v /
    u_c''(0)``, ``v^2 / (2 |u_c''(0)|)`` above the wall: the clearance is ``v^2 / (2 u_c''(0)
    |g|) < 0`` (Taylor at ``t = 0``, ``u_c''(0)`` in closed form), down to ``d = 1e-10``
    (a clearance of ~1e-20). The difference ``g - u_c(t*)`` keeps only its rounding there
    (~1e-16, either sign: a spurious zero of the clearance next to the grazing)."""
    p = paper(formulation)
    Tj = 2 * np.pi / p.omega[j]
    for d in (1e-4, 1e-6, 1e-8, 1e-10):
        y = point(p, Tj * (1 + d))
        u0, du0, T = p.state(y)
        v = du0[p.c]
        f = p.displacement_sum(y)
        taylor = v**2 / (2 * float(f.d2(np.array([0.0]))[0]) * abs(p.g))
        tests = p.admissibility(y)
        assert tests["outgoing_velocity"] < 0 and taylor < 0
        assert tests["clearance"] == pytest.approx(taylor, rel=1e-3 + 10 * abs(v), abs=0.0)


# ---------------------------------------------------------------------------------------------
# h. continuation of branch 1 up to its nonlinear grazing orbit
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def branch1() -> Branch:
    p = paper()
    # max_points well above what the branch needs (~150-550 points depending on step control)
    st_ = ContinuationSettings(stop_on_inadmissible=True, param_min=2 * np.pi / 1.7,
                               max_points=3000)
    return ContinuationEngine(p, st_).run(p.start_points({"mode": 1})[0])


def test_branch1_points_are_closed_form_solutions(branch1: Branch) -> None:
    p = paper()
    assert branch1.n_points > 20
    T = np.array([q.y[-1] for q in branch1.points])
    assert T[0] == pytest.approx(p.T_lin[0], rel=1e-12)
    assert np.all(np.diff(T) < 0)  # towards the admissible side a_1 (T - T_1) < 0
    for q in branch1.points:
        assert np.max(np.abs(p.evaluate(q.y))) < 1e-10
        assert np.max(np.abs(q.y - point(p, q.y[-1]))) <= 1e-9 * max(1.0, np.max(np.abs(q.y)))


def test_branch1_ends_at_nonlinear_grazing(branch1: Branch) -> None:
    """Independent location of the grazing orbit: solve ``u_c(t*; T) = g``, ``u_c'(t*; T) = 0``
    for ``(t*, T)`` with the oracle's closed form (7.3), from the engine's ``T`` and the largest
    interior maximum of ``u_c`` on a grid; then check that maximum is the global one and that
    ``max u_c = g`` at the located orbit (tangency)."""
    o = paper_oracle()
    reason = branch1.termination["forward"]
    assert reason.startswith("grazing")
    last = branch1.points[-1]
    grazing = [ev for ev in branch1.events if ev.kind == "grazing"]
    assert grazing and np.array_equal(grazing[-1].point.y, last.y)
    T_eng = float(last.y[-1])
    tt = np.linspace(0.0, T_eng, 40001)[1:-1]
    uu = o.uc(tt, T_eng)
    i = int(np.argmax(uu))
    t_star, T_star = fsolve(lambda z: [o.uc(z[0], z[1]) - o.g, o.duc(z[0], z[1])],
                            [tt[i], T_eng], xtol=1e-14)
    assert abs(o.uc(t_star, T_star) - o.g) < 1e-12 and abs(o.duc(t_star, T_star)) < 1e-12
    assert abs(T_star - T_eng) <= 1e-10 * T_eng
    # a genuine interior maximum, not the impact instant, and its mirror image (symmetry)
    assert 0.05 * T_star < t_star < 0.95 * T_star
    assert abs(o.uc(T_star - t_star, T_star) - o.g) < 1e-9
    # tangency at the engine's orbit: the maximum of u_c over (0, T) is g
    res = minimize_scalar(lambda t: -o.uc(t, T_eng), bounds=(tt[i] - 1e-3, tt[i] + 1e-3),
                          method="bounded", options={"xatol": 1e-12})
    assert abs(-res.fun - o.g) <= 1e-9
    assert np.max(uu) <= o.g + 1e-9
    # just before the end the orbit was admissible with clearance (no earlier contact)
    prev = branch1.points[-2]
    assert np.max(o.uc(tt / T_eng * prev.y[-1], prev.y[-1])) < o.g
    assert abs(last.tests["clearance"]) < 1e-9


# ---------------------------------------------------------------------------------------------
# i. g = 0: the spectrum is the set of zeros of w_N (Prop. 7.2, Lemma 7.1)
# ---------------------------------------------------------------------------------------------
def test_zeros_of_w_N_one_per_gap_between_poles() -> None:
    """All ``a_j > 0`` (2.16) so ``w_N' = -sum_j a_j / (2 sin^2(w_j T/2)) < 0``: between two
    consecutive poles ``w_N`` decreases from +inf to -inf and has exactly one root."""
    p = NDofImpactProblem({"chain": PAPER_CHAIN, "gap": 0.0})
    o = Modal(p.M, p.K, p.c, 0.0)
    T_lo, T_hi = 0.3, 10.0
    roots = p.zeros_of_w_N(T_lo, T_hi)
    poles = o.poles(T_hi)
    poles = np.unique(np.round(poles[(poles > T_lo) & (poles < T_hi)], 12))
    assert np.min(np.diff(poles)) > 1e-3  # no (near) internal resonance in this window
    for r in roots:  # a sign change of the oracle's w_N within 1e-9 (relative) of each root
        d = 1e-9 * r
        assert o.w_N(r - d) > 0 > o.w_N(r + d)
    for lo, hi in zip(poles[:-1], poles[1:], strict=True):
        assert np.sum((roots > lo) & (roots < hi)) == 1
    # end intervals: a root iff the sign at the window end says so
    assert np.sum(roots < poles[0]) == int(o.w_N(T_lo) > 0)
    assert np.sum(roots > poles[-1]) == int(o.w_N(T_hi) < 0)


# ---------------------------------------------------------------------------------------------
# j. g < 0 (Prop. 7.1)
# ---------------------------------------------------------------------------------------------
def _sampled_admissible(o: Modal, T: float, g: float) -> bool:
    """Definition 2.2 by sampling: ``u_c'(0+) < 0`` and ``u_c <= g`` on 20 000 points."""
    x = o.x0(T, g)
    t = np.linspace(0.0, T, 20001)[1:-1]
    uc = g / o.g * o.uc(t, T)  # u(.; T, g) is linear in g (7.2)
    return bool(x[o.N + o.c] < 0 and np.max(uc) <= g)


def test_prestress_sign_flip_never_both_admissible() -> None:
    """Prop. 7.1.1: ``u(.; T, -g) = -u(.; T, +g)``; if it is admissible for ``+g`` it is not for
    ``-g`` (and conversely). The code's admissibility is also compared with a sampled check."""
    pp, pm, o = paper(gap=1.0), paper(gap=-1.0), paper_oracle()
    Ts = [T for T in np.linspace(0.3, 10.0, 300)
          if o.pole_distance(T) > 1e-4 and abs(o.w_N(T)) > 1e-4]
    n_plus = n_minus = 0
    for T in Ts:
        yp, ym = point(pp, T), point(pm, T)
        assert np.allclose(ym[:-1], -yp[:-1], rtol=1e-14, atol=0)
        tp, tm = pp.admissibility(yp), pm.admissibility(ym)
        adm_p = min(tp.values()) > 0
        adm_m = min(tm.values()) > 0
        assert not (adm_p and adm_m), T
        n_plus += adm_p
        n_minus += adm_m
        for g, tests, adm in ((1.0, tp, adm_p), (-1.0, tm, adm_m)):
            if min(abs(v) for v in tests.values()) > 1e-3:
                assert adm == _sampled_admissible(o, T, g), (T, g)
    assert n_plus > 10 and n_minus > 10  # both sides have admissible orbits: not vacuous


@pytest.mark.parametrize("rel", [-1e-3, -1e-5, 1e-5, 1e-3])
def test_prestress_inadmissible_near_poles(rel: float) -> None:
    """Prop. 7.1.2: for ``g < 0`` and ``T`` close to a pole ``k T_j`` the orbit is close to the
    linear grazing orbit ``g cos(w_j t)`` on dof c, whose maximum ``|g| > g``: inadmissible."""
    p = paper(gap=-1.0)
    for j in range(p.N):
        for k in (1, 2, 3):
            T = k * p.T_lin[j] * (1 + rel)
            tests = p.admissibility(point(p, T))
            assert min(tests.values()) < 0, (j, k, tests)


# ---------------------------------------------------------------------------------------------
# k. starts at (or very near) singular points
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", [{"T": float(paper().T_lin[0] * (1 - 1e-12)), "direction": -1},
                                  {"mode": 1}], ids=["T_1(1-1e-12)", "mode_1"])
def test_start_arbitrarily_close_to_linear_grazing(spec) -> None:
    p = paper()
    br = ContinuationEngine(p, ContinuationSettings(max_points=12)).run(
        p.start_points(spec)[0])
    assert "start" not in br.termination, br.termination
    assert br.n_points >= 12
    first = br.points[0]
    assert first.y[-1] == pytest.approx(p.T_lin[0], rel=1e-11)
    assert np.max(np.abs(p.evaluate(first.y))) < 1e-12
    T = np.array([q.y[-1] for q in br.points])
    assert np.all(np.diff(T) < 0)  # continued towards the admissible side
    for q in br.points[1:]:
        assert np.max(np.abs(q.y - point(p, q.y[-1]))) <= 1e-9 * max(1.0, np.max(np.abs(q.y)))


@pytest.mark.parametrize("rel", [0.0, 1e-10, 1e-6])
def test_start_near_a_zero_of_w_N(rel: float) -> None:
    """Near a zero of ``w_N`` the energy diverges (``|u| ~ g/|w_N|``): the start either converges
    to a genuine solution or the branch records why it did not; it never raises."""
    p = paper()
    r = float(p.zeros_of_w_N(3.8, 4.0)[0])
    br = ContinuationEngine(p, ContinuationSettings(max_points=8)).run(
        p.start_points({"T": r * (1 + rel)})[0])
    assert isinstance(br, Branch)
    if br.n_points == 0:
        assert br.termination.get("start"), br.termination
    else:
        for q in br.points:
            assert np.all(np.isfinite(q.y))
            assert np.max(np.abs(p.evaluate(q.y))) <= 1e-9 * np.max(np.abs(q.y))
        assert all(isinstance(v, str) and v for v in br.termination.values())


# ---------------------------------------------------------------------------------------------
# l. internal resonance
# ---------------------------------------------------------------------------------------------
def test_internal_resonance_is_reported_and_does_not_raise() -> None:
    """``M = I``, ``K = Q diag(1, 9) Q^T``: ``w_2 = 3 w_1`` so ``3 T_2 = T_1`` (Assumption 3.1
    violated). The instance warns, and a start at the coincident pole returns a Branch."""
    th = 0.4
    Q = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    K = Q @ np.diag([1.0, 9.0]) @ Q.T
    p = NDofImpactProblem({"M": np.eye(2).tolist(), "K": K.tolist(), "gap": 1.0})
    assert p.omega == pytest.approx([1.0, 3.0], rel=1e-12)
    assert np.all(np.abs(p.a) > 1e-3)
    warnings = p.presentation.warnings()
    assert any("internal resonance" in w for w in warnings)
    assert any("3 T_2 = 1 T_1" in w for w in warnings)
    start = p.start_points({"mode": 2, "subharmonic": 3})[0]
    assert start.y[-1] == pytest.approx(2 * np.pi, rel=1e-12)
    br = ContinuationEngine(p, ContinuationSettings(max_points=15)).run(start)
    assert isinstance(br, Branch)
    assert br.termination and all(isinstance(v, str) and v for v in br.termination.values())
    for q in br.points:
        assert np.max(np.abs(p.evaluate(q.y))) < 1e-9
    # a non-resonant chain raises no such warning
    assert not any("internal resonance" in w for w in paper().presentation.warnings())


def test_alpha_is_static_compliance_and_high_frequency_limit():
    """alpha = sum_j a_j / w_j^2 (Prop. 5.2) equals (K^-1 M)_cc, since K^-1 M = P Omega^-2 P^-1;
    and w_N(T) ~ 2 alpha / T as T -> 0 (eq. 5.12). For the paper's chain alpha = m sum 1/k_i =
    (1/5) * 5 * (1/5) = 0.2 > 0: admissible frequencies are bounded."""
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 8):
        chain = {"dofs": n, "mass": rng.uniform(0.5, 2, n).tolist(),
                 "stiffness": rng.uniform(0.5, 2, n).tolist()}
        pr = NDofImpactProblem({"chain": chain, "gap": 1.0})
        alpha = float(np.sum(pr.a / pr.omega**2))
        oracle = np.linalg.solve(pr.K, pr.M)[pr.c, pr.c]
        assert abs(alpha - oracle) < 1e-12 * oracle
        T = 1e-4 * pr.T_lin[-1]
        assert abs(float(pr.w_N(T)) * T / (2 * alpha) - 1) < 1e-6
    paper = NDofImpactProblem({"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0})
    assert abs(float(np.sum(paper.a / paper.omega**2)) - 0.2) < 1e-14


@pytest.mark.parametrize("direction, sign", [("increase", 1), ("decrease", -1)])
def test_direction_is_along_the_continued_parameter(direction: str, sign: int) -> None:
    """``continuation.direction`` is meant along ``continuation.parameter``: continued in
    ``omega`` (the period ``T = 2 pi / omega`` inside), ``increase`` makes omega grow."""
    import nsm_continuation as nsm

    case = {"name": "dir", "problem": "ndof_impact",
            "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
            "start": {"T": 5.0},
            "continuation": {"parameter": "omega", "min": 0.5, "max": 3.0, "max_points": 6,
                             "direction": direction},
            "analysis": {"stability": False, "bifurcations": False}}
    res = nsm.run(case)
    omega = res.branches[0]["omega"]
    assert np.all(sign * np.diff(omega) > 0)


# ---------------------------------------------------------------------------------------------
# h. Structured multipliers and the declared conservative capability
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("formulation", FORMULATIONS)
def test_structured_floquet_equals_dense_for_both_formulations(formulation: str) -> None:
    """The O(N^2) multipliers (forced for the 5-dof chain) equal the dense ones to 1e-9 in both
    formulations (the tangent's velocity part is read from either), and the chain declares
    itself conservative (its impact conserves energy: M diagonal)."""
    p = paper(formulation)
    p.DENSE_MULTIPLIERS_UP_TO = 0
    y = point(p, 0.95 * p.T_lin[0])
    t = null_tangent(p, y)
    fs, fd = p.floquet(y, t), p.floquet_dense(y, t)
    assert multiset_distance(fs.multipliers, fd.multipliers) <= 1e-9
    assert p.conservative


def test_a_coupled_mass_matrix_is_not_conservative() -> None:
    """``M_ck != 0``: the impact law does not conserve energy (Prop. 6.1), the map is not
    symplectic, and the engine must keep the generic motion check (``conservative`` False)."""
    M = [[2.0, 0.3], [0.3, 1.0]]
    K = [[3.0, -1.0], [-1.0, 1.0]]
    p = NDofImpactProblem({"M": M, "K": K, "gap": 1.0})
    assert not p.conservative
