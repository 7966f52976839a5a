"""Forced double pendulum of Nordmark & Piiroinen (2009), sec. 6: an independent Euler-Lagrange
derivation of eq. (53)/(59), checked against the equations as printed.

Model. ``q1``, ``q2`` are the absolute angles (from the downward vertical) of two massless bars
of lengths ``L1``, ``L2`` carrying point masses ``m1`` (end of bar 1) and ``m2`` (end of bar 2);
gravity ``g``; a constant torque ``T`` (``par["torque"]``) and a viscous torque ``-D q1'`` act at
the upper joint, the lower joint is frictionless. Positions relative to the upper joint:

    mass 1:  (L1 s1, -L1 c1),      mass 2:  (X, Y) = (L1 s1 + L2 s2, -(L1 c1 + L2 c2)).

Kinetic energy ``K = 1/2 m1 |r1'|^2 + 1/2 m2 |r2'|^2``, potential ``U = g (m1 y1 + m2 y2)``
(torque excluded), Lagrangian ``Lag = K - U``, generalized non-conservative forces
``Q_nc = (T - D q1', 0)`` (the virtual power of the joint torques, ``q1`` being the rotation of the
upper joint). Euler-Lagrange, with ``p = dLag/dq'``:

    M(q) q'' = f(q, q'),   M = d2 Lag / dq'2,   f = dLag/dq - (d p / dq) q' + Q_nc,

formed here with ``ca.hessian``/``ca.jacobian`` on SX, with no hand algebra.

Wall (our convention). ``H(q) = X(q) + d`` with ``d > 0`` the horizontal distance of the wall from
the upper joint: the wall is the line ``X = -d``, the admissible side is ``H >= 0`` (eq. 52) and
``N = (dH/dq)^T = (L1 c1, L2 c2)^T``; a contact force ``lambda N`` with ``lambda >= 0`` pushes the
lower mass towards ``H > 0``. (Sec. 6.3 prints ``d = -0.5``, but its saddle ``q*`` has
``X(q*) = -0.5``, which is the wall of ``d = +0.5`` under eq. (52); we use ``d = +0.5``.)

Result of the comparison with the printed eq. (53)
``M q'' + L(q, q') + V(q) = K q' + lambda N``:

* ``M`` is correct: ``[[(m1+m2) L1^2, m2 L1 L2 c12], [m2 L1 L2 c12, m2 L2^2]]``.
* ``V = ((m1+m2) g L1 s1 - T, m2 g L2 s2)^T``, ``K = diag(-D, 0)`` and ``N`` are correct.
* The Coriolis/centripetal vector ``L`` is **wrong in both components**. Printed:
  ``L = L1 L2 s12 (m1 q2'^2, m2 q1'^2)^T``. Correct (derived):

      L = m2 L1 L2 s12 (q2'^2, -q1'^2)^T,

  i.e. the first component carries ``m2``, not ``m1`` (only the lower mass couples the bars), and
  the second component has the opposite sign. The velocity terms are fixed by ``M`` (Christoffel
  symbols), and the printed ones are not those of this ``M``: they break energy conservation
  (``D = T = 0``, 10 time units, DOP853 at 1e-12: relative drift 4.4e-1 vs 7.8e-12 for the
  derived model from the same state; tests/hybrid/test_pendulum_model.py).
  Eq. (59) inherits the printed ``L``. With ``m1 = m2`` the first component would be right but the
  sign error in the second remains; the sign error alone already destroys conservation.

At ``q' = 0`` both ``L`` vanish, so equilibria (eqs. 60-61) and their ``V`` are unaffected; the
eigenvalues of an equilibrium are unaffected too (``L`` is quadratic in ``q'``). The errors matter
for every trajectory with motion, i.e. for all simulations of sec. 6.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import casadi as ca
import numpy as np

Scalar = float | ca.SX

PARAM_KEYS = ("g", "m1", "m2", "L1", "L2", "torque", "D")

#: Parameters of sec. 6 (``torque`` of sec. 6.3).
PAPER_PARAMS: dict[str, float] = {
    "g": 9.81, "m1": 1.0, "m2": 2.0, "L1": 1.0, "L2": 1.0, "D": 10.0,
    "torque": -31.00166609425,
}


def _unpack(par: Mapping[str, Any]) -> tuple[Any, ...]:
    missing = [k for k in PARAM_KEYS if k not in par]
    if missing:
        raise KeyError(f"missing pendulum parameters: {missing}")
    return tuple(par[k] for k in PARAM_KEYS)


def positions(q: ca.SX, par: Mapping[str, Scalar]) -> tuple[ca.SX, ca.SX]:
    """Positions ``r1``, ``r2`` of the two masses (2-vectors from the upper joint, y upwards)."""
    _, _, _, L1, L2, _, _ = _unpack(par)
    r1 = ca.vertcat(L1 * ca.sin(q[0]), -L1 * ca.cos(q[0]))
    r2 = r1 + ca.vertcat(L2 * ca.sin(q[1]), -L2 * ca.cos(q[1]))
    return r1, r2


def _kinetic_potential(q: ca.SX, qd: ca.SX, par: Mapping[str, Scalar]) -> tuple[ca.SX, ca.SX]:
    g, m1, m2, _, _, _, _ = _unpack(par)
    r1, r2 = positions(q, par)
    v1 = ca.jtimes(r1, q, qd)  # velocities by the chain rule, dr/dq q'
    v2 = ca.jtimes(r2, q, qd)
    kin = 0.5 * m1 * ca.dot(v1, v1) + 0.5 * m2 * ca.dot(v2, v2)
    pot = g * (m1 * r1[1] + m2 * r2[1])
    return kin, pot


def energy(q: ca.SX, qd: ca.SX, par: Mapping[str, Scalar]) -> ca.SX:
    """Mechanical energy ``K + U`` (kinetic + gravitational; the torque's work is not included).

    Along the derived model, ``dE/dt = T q1' - D q1'^2`` (the power of the upper-joint torques).
    """
    kin, pot = _kinetic_potential(q, qd, par)
    return kin + pot


def lagrange_terms(q: ca.SX, qd: ca.SX, par: Mapping[str, Scalar]) -> tuple[ca.SX, ca.SX]:
    """``(M, f)`` of ``M(q) q'' = f(q, q')`` by Euler-Lagrange (the correct form of eq. (53)).

    ``q``, ``qd``: SX 2-vectors (symbols). ``par``: keys ``g, m1, m2, L1, L2, torque, D`` (floats
    or SX). ``M = d2 Lag/dq'2`` and ``f = dLag/dq - d(dLag/dq')/dq q' + (T - D q1', 0)``; in the
    notation of eq. (53)/(59), ``f = -L(q, q') - V(q) + K q'`` with the *corrected* ``L`` (module
    docstring). The contact term ``lambda N`` is not included.
    """
    _, _, _, _, _, torque, D = _unpack(par)
    kin, pot = _kinetic_potential(q, qd, par)
    lag = kin - pot
    M, p = ca.hessian(lag, qd)  # p = dLag/dq' (gradient), M = its Jacobian w.r.t. q'
    dlag_dq = ca.gradient(lag, q)
    q_nc = ca.vertcat(torque - D * qd[0], 0)
    f = dlag_dq - ca.mtimes(ca.jacobian(p, q), qd) + q_nc
    return ca.simplify(M), ca.simplify(f)


def printed_terms(q: ca.SX, qd: ca.SX, par: Mapping[str, Scalar]) -> tuple[ca.SX, ca.SX]:
    """``(M, f)`` of eq. (53)/(59) exactly as printed: ``f = -L - V + K q'`` with the printed
    ``L = L1 L2 s12 (m1 q2'^2, m2 q1'^2)^T`` (which is wrong, see the module docstring)."""
    g, m1, m2, L1, L2, torque, D = _unpack(par)
    s1, s2 = ca.sin(q[0]), ca.sin(q[1])
    s12, c12 = ca.sin(q[0] - q[1]), ca.cos(q[0] - q[1])
    M = ca.vertcat(
        ca.horzcat((m1 + m2) * L1**2, m2 * L1 * L2 * c12),
        ca.horzcat(m2 * L1 * L2 * c12, m2 * L2**2),
    )
    L = L1 * L2 * s12 * ca.vertcat(m1 * qd[1] ** 2, m2 * qd[0] ** 2)
    V = ca.vertcat((m1 + m2) * g * L1 * s1 - torque, m2 * g * L2 * s2)
    Kqd = ca.vertcat(-D * qd[0], 0)
    return M, -L - V + Kqd


def contact_normal(q: ca.SX, par: Mapping[str, Scalar]) -> ca.SX:
    """``N = (dH/dq)^T = (L1 c1, L2 c2)^T`` for ``H = X + d`` (independent of ``d``)."""
    _, _, _, L1, L2, _, _ = _unpack(par)
    return ca.vertcat(L1 * ca.cos(q[0]), L2 * ca.cos(q[1]))


def wall_distance(q: ca.SX, par: Mapping[str, Scalar], d: Scalar) -> ca.SX:
    """``H(q) = X(q) + d`` (eq. 52 with ``d > 0``: wall at ``X = -d``, admissible ``H >= 0``)."""
    _, r2 = positions(q, par)
    return r2[0] + d


def acceleration_function(par: Mapping[str, Scalar], model: str = "derived") -> ca.Function:
    """CasADi function ``(q, qd) -> qdd`` of the free-flight field (``model``: derived/printed)."""
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    terms = {"derived": lagrange_terms, "printed": printed_terms}[model]
    M, f = terms(q, qd, par)
    return ca.Function(f"qdd_{model}", [q, qd], [ca.solve(M, f)])


def vector_field(par: Mapping[str, Scalar], model: str = "derived") -> ca.Function:
    """CasADi function ``x -> F(x)`` of eq. (59), ``x = (q, q')``, ``F = (q', M^-1 f)``
    (``model``: ``"derived"`` = corrected ``L``, ``"printed"`` = eq. (59) as printed)."""
    x = ca.SX.sym("x", 4)
    terms = {"derived": lagrange_terms, "printed": printed_terms}[model]
    M, f = terms(x[:2], x[2:], par)
    return ca.Function(f"F_{model}", [x], [ca.vertcat(x[2:], ca.solve(M, f))])


def rhs_functions(
    par: Mapping[str, float],
) -> tuple[Callable[[float, np.ndarray], np.ndarray], Callable[[float, np.ndarray], np.ndarray]]:
    """Numeric right-hand sides ``(derived, printed)`` of eq. (59), ``x' = (q', q'')``, for
    :func:`scipy.integrate.solve_ivp`: each is ``rhs(t, x) -> ndarray(4)`` with ``x = (q, q')``."""
    out = []
    for model in ("derived", "printed"):
        fun = vector_field(par, model)

        def rhs(t: float, x: np.ndarray, _fun: ca.Function = fun) -> np.ndarray:
            return np.asarray(_fun(x), dtype=float).ravel()

        out.append(rhs)
    return out[0], out[1]


def energy_function(par: Mapping[str, float]) -> Callable[[np.ndarray], float]:
    """Numeric ``E(x)``, ``x = (q, q')`` (see :func:`energy`)."""
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    fun = ca.Function("E", [q, qd], [energy(q, qd, par)])

    def E(x: np.ndarray) -> float:
        x = np.asarray(x, dtype=float)
        return float(fun(x[:2], x[2:]))

    return E
