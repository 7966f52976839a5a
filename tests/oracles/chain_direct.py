"""The 5-dof chain of Legrand, Junca, Heng (2017) simulated directly, with no part of the
package: SciPy's DOP853 on ``M u'' + K u = 0`` between impacts, the wall ``u_c = g`` located as
an event (the root of the gap) and the elastic impact ``u_c' -> -u_c'`` applied there (paper
000, sec. 2: ``e = 1``). The oracle of the chain's multi-impact orbits found by the hybrid layer:
periodic over the reported period, the energy ``E = (u'^T M u' + u^T K u) / 2`` conserved at each
impact, the impacts as many and in the order reported."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def chain_energy(M: np.ndarray, K: np.ndarray, z: np.ndarray) -> float:
    """``(u'^T M u' + u^T K u) / 2`` of the state ``z = (u, u')``."""
    n = M.shape[0]
    return 0.5 * float(z[n:] @ M @ z[n:] + z[:n] @ K @ z[:n])


def direct_period(M: np.ndarray, K: np.ndarray, c: int, g: float, x0: np.ndarray, T: float
                  ) -> tuple[np.ndarray, list[float], list[float]]:
    """The chain from ``x0`` over ``T``: the end state, the impact times (in time order) and the
    energy at the start and after each impact.

    The wall is found two ways: a crossing ``u_c = g`` seen between two steps (a terminal
    event), and at each maximum of ``u_c`` (``u_c' = 0`` falling, recorded): a maximum above
    the wall means a crossing in and out within one step (an impact of small velocity ``v``
    lasts ``~2 v / |u_c''|`` inside the wall), found by a root-finder (``brentq``) on the dense
    output between that maximum and a point before it below the wall."""
    n = M.shape[0]
    A = np.linalg.solve(M, K)

    def rhs(_t: float, z: np.ndarray) -> np.ndarray:
        return np.concatenate([z[n:], -A @ z[:n]])

    def wall(_t: float, z: np.ndarray) -> float:
        return z[c] - g

    def apex(_t: float, z: np.ndarray) -> float:
        return z[n + c]

    wall.terminal = True  # type: ignore[attr-defined]
    wall.direction = 1.0  # type: ignore[attr-defined]
    apex.direction = -1.0  # type: ignore[attr-defined]

    t, z = 0.0, np.asarray(x0, dtype=float)
    impacts: list[float] = []
    energies = [chain_energy(M, K, z)]
    while True:
        sol = solve_ivp(rhs, (t, T), z, method="DOP853", rtol=1e-13, atol=1e-15,
                        events=[wall, apex], max_step=0.01, dense_output=True)
        end = float(sol.t_events[0][0]) if sol.status == 1 else T
        inside = [float(ta) for ta, za in zip(sol.t_events[1], sol.y_events[1], strict=True)
                  if ta < end and za[c] > g]
        if inside:  # a crossing in and out within one step, before the maximum
            top = inside[0]
            h = 1e-9
            while float(sol.sol(max(top - h, t))[c]) >= g and top - h > t:
                h *= 2.0
            lo = max(top - h, t)
            end = float(brentq(lambda s, f=sol.sol: float(f(s)[c]) - g, lo, top, xtol=1e-15,
                               rtol=4 * np.finfo(float).eps))
            z = sol.sol(end)
        elif sol.status != 1:
            return sol.y[:, -1], impacts, energies
        else:
            z = sol.y_events[0][0].copy()
        t = end
        z[c], z[n + c] = g, -abs(z[n + c])
        impacts.append(t)
        energies.append(chain_energy(M, K, z))
