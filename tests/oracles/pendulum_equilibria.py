"""Saddle equilibria of the double pendulum sticking to the wall (Nordmark & Piiroinen 2009,
sec. 6.3, eqs. (60)-(61)) and their eigenvalues.

Equilibrium. With ``q' = 0`` eq. (53) reduces to ``V(q) = lambda N(q)`` (60) and ``H(q) = 0``
(61). The three unknowns ``(q1, q2, lambda)`` are found by Newton's method with the exact CasADi
Jacobian of the residual ``(f(q, 0) + lambda N(q), H(q))``, where ``f(q, 0) = -V(q)`` comes from
the Euler-Lagrange derivation :func:`tests/oracles/pendulum_lagrange.lagrange_terms`.
``H = X + d`` (``d > 0``: wall at ``X = -d``, admissible side ``H >= 0``),
``N = (L1 c1, L2 c2)^T``, and
``lambda`` is reported in the normalisation of eq. (53)/(60) (force ``lambda N``; ``lambda > 0``
pushes the lower mass away from the wall, into ``H > 0``). The sticking multiplier of
eq. (10)-(12), ``F' = F - lambda_s W``, is a different normalisation of the same force:
``lambda_s = lambda N^T M^-1 N / (1 + e)`` (returned for ``e = 0`` as ``lam_sticking_e0``).

Eigenvalues (reduced 1-dof model, independent of ``M``/``f``). In sticking the lower mass stays
on the wall ``X(q) = L1 s1 + L2 s2 = -d``, a bilateral constraint (the field ``F'`` of eq. (10) is
the Lagrange-multiplier dynamics on ``{H = 0, H' = 0}``). Parametrise it by ``q1``:
``q2(q1) = asin((-d - L1 s1)/L2)`` (or ``pi - asin(.)``, plus ``2 pi k``: the branch of the
solution). The point masses then have ``r_i(q1)``, so

    Lag_red = 1/2 m(q1) q1'^2 - U(q1),   m(q1) = m1 |dr1/dq1|^2 + m2 |dr2/dq1|^2,
    U(q1) = g (m1 y1 + m2 y2) - T q1,      generalised damping force -D q1'

(the upper joint's rotation is ``q1`` itself, so ``D_eff = D``). The equilibrium satisfies
``U'(q1*) = 0``; linearising ``m q1'' + m'/2 q1'^2 + U' = -D q1'`` there gives
``m(q1*) mu^2 + D mu + U''(q1*) = 0``: the two non-trivial eigenvalues ``mu1 > 0 > mu2`` (saddle
for ``U'' < 0``). The other two eigenvalues of the 4-dim sticking field are ``0, 0`` (one Jordan
block: ``H' = v``, ``v' = 0`` off the manifold; tests/hybrid/test_pendulum_model.py).

Paper values (``T = -31.00166609425``, ``g = 9.81``, ``m1 = 1``, ``m2 = 2``, ``L1 = L2 = 1``,
``D = 10``, our ``d = 0.5``; the paper prints ``d = -0.5``, but its ``q*`` has ``X(q*) = -0.5``):
``q1* = 4.91990567552337``, ``q2* = 0.49899755317827``, ``lambda* = 10.69293096743960``,
``mu1 ~ 0.3366``, ``mu2 ~ -3.2953``. Measured: ``q1*``, ``q2*``, ``lambda*`` agree to ~1e-14
(every printed digit; ``lambda`` has the paper's sign), but the eigenvalues come out as
``mu1 = 0.288793``, ``mu2 = -3.247521``, here and from the Jacobian of the 4-dim sticking field
``F'`` (to 1e-15) and from a simulation of ``F'`` (growth rate, to 2e-6). The sums agree
(``-D/m = -2.95873`` vs ``-2.9587``), the products do not (``U''/m = -0.93786`` vs ``-1.10920``).
The printed ``L`` error cannot explain this (velocity-quadratic terms drop out of the
linearisation at ``q' = 0``), and no other torque does either (``mu1 = 0.3366`` at
``T = -30.9597`` comes with ``mu2 = -3.3082``). Unresolved; not tuned.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from .pendulum_lagrange import (
    contact_normal,
    lagrange_terms,
    positions,
    wall_distance,
)

#: Saddle of sec. 6.3 as printed (``d = 0.5`` in our convention).
PAPER_SADDLE: dict[str, float] = {
    "q1": 4.91990567552337,
    "q2": 0.49899755317827,
    "lam": 10.69293096743960,
    "mu1": 0.3366,
    "mu2": -3.2953,
}


def _equilibrium_residual(par: Mapping[str, float], d: float) -> ca.Function:
    z = ca.SX.sym("z", 3)  # (q1, q2, lambda)
    q, lam = z[:2], z[2]
    qd = ca.SX.sym("qd", 2)
    _, f = lagrange_terms(q, qd, par)
    f = ca.substitute(f, qd, ca.SX.zeros(2))  # f(q, 0) = -V(q)
    res = ca.vertcat(f + lam * contact_normal(q, par), wall_distance(q, par, d))
    return ca.Function("res", [z], [res, ca.jacobian(res, z)])


def _reduced_model(par: Mapping[str, float], d: float, q2_branch: float) -> ca.Function:
    """``q1 -> (q2(q1), m(q1), U'(q1), U''(q1))`` on the branch of the constraint through
    ``q2_branch``."""
    g, m1, m2, L1, L2 = (par[k] for k in ("g", "m1", "m2", "L1", "L2"))
    torque = par["torque"]
    q1 = ca.SX.sym("q1")
    asin_z = ca.asin((-d - L1 * ca.sin(q1)) / L2)
    if np.cos(q2_branch) >= 0.0:
        base = asin_z
        base0 = np.arcsin(np.sin(q2_branch))
    else:
        base = np.pi - asin_z
        base0 = np.pi - np.arcsin(np.sin(q2_branch))
    shift = 2.0 * np.pi * np.round((q2_branch - base0) / (2.0 * np.pi))
    q2 = base + shift
    r1, r2 = positions(ca.vertcat(q1, q2), par)
    dr1, dr2 = ca.jacobian(r1, q1), ca.jacobian(r2, q1)
    mass = m1 * ca.dot(dr1, dr1) + m2 * ca.dot(dr2, dr2)
    pot = g * (m1 * r1[1] + m2 * r2[1]) - torque * q1
    dU = ca.gradient(pot, q1)
    d2U = ca.jacobian(dU, q1)
    return ca.Function("reduced", [q1], [q2, mass, dU, d2U])


def reduced_eigenvalues(par: Mapping[str, float], d: float, q1: float, q2: float) -> np.ndarray:
    """Roots of ``m(q1) mu^2 + D mu + U''(q1) = 0`` of the reduced 1-dof sticking model at
    ``(q1, q2)`` (``q2`` selects the branch of the constraint), sorted ascending (complex if the
    equilibrium is an underdamped centre)."""
    red = _reduced_model(par, d, q2)
    _, mass, _, d2U = (float(v) for v in red(q1))
    roots = np.roots([mass, float(par["D"]), d2U])
    return np.sort_complex(roots) if np.iscomplexobj(roots) else np.sort(roots)


def sticking_equilibrium(
    par: Mapping[str, float],
    d: float,
    guess: tuple[float, float, float],
    tol: float = 1e-14,
    max_iter: int = 50,
) -> dict[str, Any]:
    """Equilibrium ``(q1, q2, lambda)`` of eqs. (60)-(61) by Newton from ``guess``, with the
    eigenvalues of the sticking motion there.

    ``par``: keys ``g, m1, m2, L1, L2, torque, D``; ``d``: wall distance (``H = X + d``).
    Returns a dict with ``q1``, ``q2``, ``lam`` (normalisation of eq. (53): force ``lam N``,
    ``N = (L1 c1, L2 c2)``), ``eigenvalues`` (the two non-trivial ones, sorted), ``residual``
    (max-norm of ``(V - lam N, H)`` at the solution), ``iterations``, ``reduced_force``
    (``U'(q1*)`` of the reduced model, an independent check of the equilibrium), ``X``, ``Y``
    (position of the lower mass) and ``lam_sticking_e0`` (multiplier of eq. (10) for ``e = 0``).
    """
    fun = _equilibrium_residual(par, d)
    z = np.asarray(guess, dtype=float).copy()
    res_norm = np.inf
    it = 0
    while it < max_iter:
        it += 1
        r, J = (np.asarray(v, dtype=float) for v in fun(z))
        step = np.linalg.solve(J, -r.ravel())
        z += step
        res_norm = float(np.max(np.abs(np.asarray(fun(z)[0]))))
        if np.max(np.abs(step)) <= tol * (1.0 + np.max(np.abs(z))) or res_norm == 0.0:
            break
    if not res_norm < 1e-10 * (1.0 + np.max(np.abs(z))):
        raise RuntimeError(f"Newton did not converge: residual {res_norm:.3e}")
    q1, q2, lam = (float(v) for v in z)
    red = _reduced_model(par, d, q2)
    q2_red, _, dU, _ = (float(v) for v in red(q1))
    if abs(q2_red - q2) > 1e-9:
        raise RuntimeError("reduced-model branch does not pass through the equilibrium")
    q = ca.DM([q1, q2])
    M_num = np.asarray(_mass(par)(q, ca.DM.zeros(2)), dtype=float)
    Nv = np.asarray(contact_normal(q, par), dtype=float).ravel()
    _, r2 = positions(q, par)
    return {
        "q1": q1,
        "q2": q2,
        "lam": lam,
        "eigenvalues": reduced_eigenvalues(par, d, q1, q2),
        "residual": res_norm,
        "iterations": it,
        "reduced_force": dU,
        "X": float(r2[0]),
        "Y": float(r2[1]),
        "lam_sticking_e0": lam * float(Nv @ np.linalg.solve(M_num, Nv)),
    }


def _mass(par: Mapping[str, float]) -> ca.Function:
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    M, _ = lagrange_terms(q, qd, par)
    return ca.Function("M", [q, qd], [M])
