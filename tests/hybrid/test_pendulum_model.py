"""Double pendulum of Nordmark & Piiroinen (2009), sec. 6: Euler-Lagrange model vs printed
eq. (53)/(59), and the sticking saddle of sec. 6.3 (eqs. (60)-(61)) with its eigenvalues.

Measured (DOP853, rtol = atol = 1e-12, 10 time units, D = T = 0; paper masses/lengths), relative
energy drift ``max_t |E(t) - E(0)| / |E(0)|``:

* x0 = (0.7, -1.1, 0.4, 1.3): derived 7.8e-12, printed 4.4e-1;
* x0 = (2.0, 0.5, -1.0, 0.8): derived 9.8e-11 (printed 6.4e4, not run: slow);
* m1 = m2 = 2 (only the sign error of the printed L left), x0 as first: derived 1.1e-11,
  printed 2.6e-1.

Saddle (T = -31.00166609425, d = 0.5): q1*, q2*, lambda* agree with the paper to ~1e-14 (all
printed digits); the eigenvalues do NOT: we get mu = 0.288793, -3.247521 by two independent
methods (reduced 1-dof Lagrangian; 4-dim sticking field F' of eqs. (10)-(12), (58)-(59)) and by
direct simulation of F'; the paper prints 0.3366, -3.2953. The sums agree (-2.95873 vs -2.9587,
i.e. -D/m), the products do not (-0.93786 vs -1.10920).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from oracles.pendulum_equilibria import (
    PAPER_SADDLE,
    reduced_eigenvalues,
    sticking_equilibrium,
)
from oracles.pendulum_lagrange import (
    PAPER_PARAMS,
    contact_normal,
    energy,
    energy_function,
    lagrange_terms,
    printed_terms,
    rhs_functions,
    wall_distance,
)
from scipy.integrate import solve_ivp

D_WALL = 0.5
GUESS = (4.9, 0.5, 10.0)
# Our eigenvalues (reduced model == 4-dim F' to ~1e-15); regression values, not the paper's.
MU_OURS = (-3.247520831, 0.288793171)


def _drift(rhs, E, x0, t_end=10.0):
    sol = solve_ivp(rhs, (0.0, t_end), x0, method="DOP853", rtol=1e-12, atol=1e-12,
                    t_eval=np.linspace(0.0, t_end, 201))
    E0 = E(x0)
    return max(abs(E(x) - E0) for x in sol.y.T) / abs(E0)


@pytest.fixture(scope="module")
def saddle():
    return sticking_equilibrium(PAPER_PARAMS, D_WALL, GUESS)


# --- energy -------------------------------------------------------------------------------------

def test_energy_conserved_by_derived_model_not_by_printed():
    par = dict(PAPER_PARAMS, torque=0.0, D=0.0)
    derived, printed = rhs_functions(par)
    E = energy_function(par)
    x0a = np.array([0.7, -1.1, 0.4, 1.3])
    x0b = np.array([2.0, 0.5, -1.0, 0.8])
    assert _drift(derived, E, x0a) < 1e-9  # measured 7.8e-12
    assert _drift(derived, E, x0b) < 1e-9  # measured 9.8e-11
    assert _drift(printed, E, x0a) > 1e-3  # measured 4.4e-1


def test_printed_sign_error_alone_breaks_energy():
    # m1 = m2: the printed first Coriolis component is then right; the sign of the second is not.
    par = dict(PAPER_PARAMS, torque=0.0, D=0.0, m1=2.0, m2=2.0)
    derived, printed = rhs_functions(par)
    E = energy_function(par)
    x0 = np.array([0.7, -1.1, 0.4, 1.3])
    assert _drift(derived, E, x0) < 1e-9  # measured 1.1e-11
    assert _drift(printed, E, x0) > 1e-3  # measured 2.6e-1


def _power_functions():
    """``(q, qd, T, D) -> (dE/dt - (T qd1 - D qd1^2))`` for the derived and printed models, with
    torque and damping as SX parameters."""
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    T, D = ca.SX.sym("T"), ca.SX.sym("D")
    par = dict(PAPER_PARAMS, torque=T, D=D)
    E = energy(q, qd, par)
    out = []
    for terms in (lagrange_terms, printed_terms):
        M, f = terms(q, qd, par)
        qdd = ca.solve(M, f)
        dEdt = ca.dot(ca.gradient(E, q), qd) + ca.dot(ca.gradient(E, qd), qdd)
        out.append(ca.Function("p", [q, qd, T, D], [dEdt - (T * qd[0] - D * qd[0] ** 2), dEdt]))
    return out


@pytest.mark.parametrize("torque, damping", [(0.0, 10.0), (-31.0, 10.0), (7.5, 0.3)])
def test_power_balance(torque, damping):
    """dE/dt = T q1' - D q1'^2 along the derived field (so dE/dt = -D q1'^2 <= 0 for T = 0)."""
    derived, printed = _power_functions()
    rng = np.random.default_rng(1)
    worst_printed = 0.0
    for _ in range(20):
        q, qd = rng.uniform(-np.pi, np.pi, 2), rng.normal(0.0, 2.0, 2)
        err, dEdt = (float(v) for v in derived(q, qd, torque, damping))
        assert abs(err) < 1e-12 * (1.0 + abs(dEdt))
        if torque == 0.0:
            assert dEdt <= 1e-12
        worst_printed = max(worst_printed, abs(float(printed(q, qd, torque, damping)[0])))
    assert worst_printed > 1.0


# --- M and the Coriolis vector --------------------------------------------------------------------

def test_mass_matrix_and_printed_errors():
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    p = ca.SX.sym("p", 7)
    par = dict(zip(("g", "m1", "m2", "L1", "L2", "torque", "D"), ca.vertsplit(p), strict=True))
    M, f = lagrange_terms(q, qd, par)
    Mp, fp = printed_terms(q, qd, par)
    g, m1, m2, L1, L2, T, D = ca.vertsplit(p)
    s12 = ca.sin(q[0] - q[1])
    L_correct = m2 * L1 * L2 * s12 * ca.vertcat(qd[1] ** 2, -qd[0] ** 2)
    L_printed = L1 * L2 * s12 * ca.vertcat(m1 * qd[1] ** 2, m2 * qd[0] ** 2)
    V = ca.vertcat((m1 + m2) * g * L1 * ca.sin(q[0]) - T, m2 * g * L2 * ca.sin(q[1]))
    f_correct = -L_correct - V + ca.vertcat(-D * qd[0], 0)
    fp_expected = f - (L_printed - L_correct)
    fun = ca.Function("chk", [q, qd, p], [M, M - Mp, f - f_correct, fp - fp_expected])
    rng = np.random.default_rng(2)
    for _ in range(20):
        pv = np.concatenate([rng.uniform(0.5, 10.0, 5), rng.normal(0.0, 10.0, 2)])
        qv, qdv = rng.uniform(-4.0, 4.0, 2), rng.normal(0.0, 2.0, 2)
        Mv, dM, df, dfp = (np.asarray(v) for v in fun(qv, qdv, pv))
        assert np.allclose(Mv, Mv.T, rtol=0, atol=1e-12)
        assert np.all(np.linalg.eigvalsh(Mv) > 0)
        assert np.max(np.abs(dM)) < 1e-12 * np.max(np.abs(Mv))
        assert np.max(np.abs(df)) < 1e-10   # derived f == -L_correct - V + K qd
        assert np.max(np.abs(dfp)) < 1e-10  # printed f differs from derived by the L terms only


# --- the saddle of sec. 6.3 ----------------------------------------------------------------------

def test_saddle_reproduces_paper(saddle):
    # Measured differences: q1 8e-15, q2 7e-15, lambda 3e-14 (all printed digits agree).
    for key in ("q1", "q2", "lam"):
        assert abs(saddle[key] - PAPER_SADDLE[key]) < 1e-12
    assert saddle["residual"] < 1e-12
    assert abs(saddle["reduced_force"]) < 1e-10  # U'(q1*) = 0 of the reduced model, independently
    assert saddle["lam"] > 0  # same sign as the paper: lambda N pushes into H > 0
    assert abs(saddle["X"] + D_WALL) < 1e-14
    assert -1.0845 < saddle["Y"] < -1.083  # inside the window of Fig. 11(b)


def test_paper_d_sign_is_inconsistent(saddle):
    # eq. (52) with the printed d = -0.5 puts the wall at X = +0.5: H(q*) = -1, no contact.
    q = ca.DM([saddle["q1"], saddle["q2"]])
    assert abs(float(wall_distance(q, PAPER_PARAMS, -0.5)) + 1.0) < 1e-12
    assert abs(float(wall_distance(q, PAPER_PARAMS, +0.5))) < 1e-14


def test_saddle_eigenvalues(saddle):
    mu = saddle["eigenvalues"]
    assert np.allclose(mu, MU_OURS, rtol=0, atol=1e-8)
    # The trace (-D/m) agrees with the paper's mu1 + mu2 to its printed precision ...
    assert abs(mu.sum() - (PAPER_SADDLE["mu1"] + PAPER_SADDLE["mu2"])) < 1e-4
    # ... the product (U''/m) does not: -0.93786 vs -1.10920.
    assert abs(np.prod(mu) - PAPER_SADDLE["mu1"] * PAPER_SADDLE["mu2"]) > 0.1


@pytest.mark.xfail(strict=True, reason="paper prints mu = 0.3366, -3.2953; two independent "
                   "linearisations and a simulation give 0.28879, -3.24752")
def test_saddle_eigenvalues_as_printed(saddle):
    assert np.allclose(saddle["eigenvalues"], [PAPER_SADDLE["mu2"], PAPER_SADDLE["mu1"]],
                       atol=1e-4)


def _sticking_field(e, model="derived"):
    """F' = F - lambda(x) W(x) of eqs. (10)-(12) with W from (58), lambda = -a/(1+e), and
    G = (H_x, v_x) (the normals of the sticking manifold {H = 0, v = 0})."""
    x = ca.SX.sym("x", 4)
    q, qd = x[:2], x[2:]
    terms = {"derived": lagrange_terms, "printed": printed_terms}[model]
    M, f = terms(q, qd, PAPER_PARAMS)
    F = ca.vertcat(qd, ca.solve(M, f))
    N = contact_normal(q, PAPER_PARAMS)
    H = wall_distance(q, PAPER_PARAMS, D_WALL)
    v = ca.jtimes(H, x, F)  # eq. (2)
    a = ca.jtimes(v, x, F)  # eq. (3)
    MiN = ca.solve(M, N)
    W = ca.vertcat(0, 0, -MiN * (1 + e) / ca.dot(N, MiN))
    lam = -a / (1 + e)  # eq. (12), r = e
    Fs = F - lam * W
    G = ca.vertcat(ca.jacobian(H, x), ca.jacobian(v, x))
    return ca.Function("Fs", [x], [Fs, ca.jacobian(Fs, x), G, lam, ca.dot(N, MiN)])


@pytest.mark.parametrize("e, model", [(0.9, "derived"), (0.0, "derived"), (0.9, "printed")])
def test_eigenvalues_from_4d_sticking_field(saddle, e, model):
    xs = np.array([saddle["q1"], saddle["q2"], 0.0, 0.0])
    Fs, J, G, lam_s, NMN = (np.asarray(v, dtype=float) for v in _sticking_field(e, model)(xs))
    lam_s, NMN = lam_s.item(), NMN.item()
    assert np.max(np.abs(Fs)) < 1e-12
    # multiplier of eq. (10) vs that of eq. (53): lam_s = lam N^T M^-1 N / (1 + e)
    assert abs(lam_s - saddle["lam"] * NMN / (1 + e)) < 1e-12
    if e == 0.0:
        assert abs(lam_s - saddle["lam_sticking_e0"]) < 1e-12
    # Tangent directions: an invariant 2-plane ker G; J restricted to it has eigenvalues mu1, mu2.
    Tb = np.linalg.svd(G)[2][2:].T  # orthonormal basis of ker G (4x2)
    A = Tb.T @ J @ Tb
    assert np.max(np.abs(J @ Tb - Tb @ A)) < 1e-12
    mu_t = np.sort(np.linalg.eigvals(A).real)
    assert np.allclose(mu_t, saddle["eigenvalues"], rtol=0, atol=1e-8)  # measured ~1e-15
    # Constraint directions: d/dt (H, v) = (v, 0) exactly, so G J = B G with B = [[0,1],[0,0]]:
    # the other two eigenvalues are 0, 0 in one Jordan block (numerically +-i*1e-8).
    B = np.array([[0.0, 1.0], [0.0, 0.0]])
    assert np.max(np.abs(G @ J - B @ G)) < 1e-12
    ev = np.linalg.eigvals(J)
    near = [ev[np.argmin(np.abs(ev - m))] for m in saddle["eigenvalues"]]
    assert np.allclose(near, saddle["eigenvalues"], rtol=0, atol=1e-8)
    rest = sorted(ev, key=lambda z: min(abs(z - m) for m in saddle["eigenvalues"]))[2:]
    assert max(abs(z) for z in rest) < 1e-6


def test_unstable_rate_by_simulation(saddle):
    """Third check: integrate F' from the saddle displaced along its unstable direction; the
    growth rate of the displacement is mu1 (0.2888), not the printed 0.3366."""
    fun = _sticking_field(0.9)
    xs = np.array([saddle["q1"], saddle["q2"], 0.0, 0.0])
    _, J, G, _, _ = (np.asarray(v, dtype=float) for v in fun(xs))
    Tb = np.linalg.svd(G)[2][2:].T
    w, V = np.linalg.eig(Tb.T @ J @ Tb)
    u = Tb @ V[:, np.argmax(w.real)].real
    sol = solve_ivp(lambda t, x: np.asarray(fun(x)[0]).ravel(), (0.0, 15.0), xs + 1e-9 * u,
                    method="DOP853", rtol=1e-11, atol=1e-15, t_eval=[5.0, 15.0])
    d5, d15 = (np.linalg.norm(sol.y[:, k] - xs) for k in (0, 1))
    rate = np.log(d15 / d5) / 10.0
    assert abs(rate - saddle["eigenvalues"][1]) < 1e-5


def test_reduced_eigenvalues_branch_selection(saddle):
    # q2 shifted by 2 pi selects the same branch; the result is unchanged.
    mu = reduced_eigenvalues(PAPER_PARAMS, D_WALL, saddle["q1"], saddle["q2"] + 2 * np.pi)
    assert np.allclose(mu, saddle["eigenvalues"], rtol=0, atol=1e-12)
