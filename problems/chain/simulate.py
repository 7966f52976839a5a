"""An event-driven simulation of the chain, independent of its modal closed form: the oracle
of the return map ``F`` (Definition 2.5), of its Jacobian ``DF`` (A.8) by finite differences,
and of the closed-form orbits (Legrand, Junca, Heng 2017)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem


def simulate_first_return(problem: NDofImpactProblem, u0: np.ndarray, du0: np.ndarray,
                          t_max: float, rtol: float = 1e-13, atol: float = 1e-15
                          ) -> tuple[np.ndarray, np.ndarray, float]:
    """Event-driven simulation of the chain (scipy DOP853 on ``M u'' + K u = 0``) from a state on
    the section to the next impact ``u_c = g`` (crossing upwards), then the impact law.

    Independent of the modal closed form: used as the oracle for ``DF`` (finite differences of
    this map) and for the closed-form orbits.
    """
    from scipy.integrate import solve_ivp

    N, c, g = problem.N, problem.c, problem.g
    Minv_K = np.linalg.solve(problem.M, problem.K)

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        return np.concatenate([z[N:], -Minv_K @ z[:N]])

    def hit(_t: float, z: np.ndarray) -> float:
        return z[c] - g

    hit.terminal = True  # type: ignore[attr-defined]
    hit.direction = 1.0  # type: ignore[attr-defined]
    z0 = np.concatenate([u0, du0])
    # the event function is only checked at step ends: a short excursion above the wall (a
    # near-grazing return) could hide inside one step, so steps are capped well below the
    # shortest linear period
    max_step = float(problem.T_lin.min()) / 200.0
    sol = solve_ivp(rhs, (0.0, t_max), z0, method="DOP853", rtol=rtol, atol=atol,
                    events=hit, dense_output=False, max_step=max_step)
    if not sol.t_events[0].size:
        raise RuntimeError("no impact before t_max")
    T = float(sol.t_events[0][0])
    z = sol.y_events[0][0].copy()
    z[c] = g
    u, du = z[:N], z[N:]
    du = du.copy()
    du[c] = -du[c]
    return u, du, T

