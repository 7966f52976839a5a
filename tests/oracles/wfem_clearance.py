"""A direct WFEM simulation of the bar clamped at x = 0 with its end in a clearance
``-g1 <= u_end <= g0``, deciding the boundary condition at x = L every step (numpy only: the
oracle of :mod:`nsm_continuation.problems.bar.wfem_clearance`, which solves for the orbits of a
given phase pattern and decides nothing).

State: the characteristic ring ``w = [b_1..b_N, a_N..a_1]`` (``a = sigma + Z v``, ``b = sigma -
Z v``); one step with ``dt = dx / c`` moves every characteristic one cell (A.18): ``b``
reflects at the clamped end with sign ``+1``, ``a`` is born at x = L from the arriving
``J = b_N`` with sign ``-1`` (free end, stress 0) or ``+1`` (held end, velocity 0). The end
displacement is the time integral of the end velocity, ``-J / Z`` on a free step and 0 on a held
one, from ``u_end(0) = g0``.

The rule: a free step is taken unless it carries ``u_end`` beyond a wall (by more than
``tol``); then the end is held by that wall. A held end stays held while the wall's force has
the right sign (the upper wall pushes, ``J <= 0``; the lower wall pulls back, ``J >= 0``) and is
released otherwise.
"""

from __future__ import annotations

import numpy as np


def simulate_clearance(w0: np.ndarray, steps: int, E: float, rho: float, dx: float, g0: float,
                       g1: float, tol: float = 1e-12) -> tuple[np.ndarray, list[str],
                                                               np.ndarray, np.ndarray]:
    """``steps`` steps from ``w0`` (the end on the upper wall, leaving it): the final ring, the
    state of each step (``free``, ``upper``, ``lower``), ``u_end`` after each step and the
    energy after each step."""
    N = len(w0) // 2
    c = np.sqrt(E / rho)
    Z, dt = rho * c, dx / c
    w = np.asarray(w0, dtype=float).copy()
    u, held = g0, "free"
    scale = tol * (g0 + g1)
    states, us, energies = [], [], []
    for _ in range(steps):
        J = w[N - 1]
        if held == "upper" and J > 0 or held == "lower" and J < 0:
            held = "free"
        if held == "free":
            nxt = u - dt * J / Z
            if nxt > g0 + scale:
                held = "upper"
            elif nxt < -g1 - scale:
                held = "lower"
        if held == "free":
            u -= dt * J / Z
        out = np.roll(w, 1)
        out[N] = J if held != "free" else -J
        w = out
        states.append(held)
        us.append(u)
        b, a = w[:N], w[N:][::-1]
        sigma, v = 0.5 * (a + b), 0.5 * (a - b) / Z
        energies.append(float(dx * np.sum(sigma ** 2 / (2 * E) + rho * v ** 2 / 2)))
    return w, states, np.array(us), np.array(energies)
