"""Closed forms of the undamped forced impact oscillator ``q'' + q = cos(omega t)``, ``q >=
gap``, Newton restitution ``r``: its period-1 orbits with one impact per forcing period and
their Floquet multipliers (independent of the simulator and of the engine).

Between impacts ``q = Gamma cos(omega t) + u``, ``Gamma = 1 / (1 - omega^2)``, ``u`` a free
oscillation. With the impact at phase ``phi = omega tau`` and ``a = gap - Gamma cos(phi)``,
periodicity over ``T = 2 pi / omega`` gives ``u'(tau) = a tan(T/2) = -u'(tau + T)``, so the
velocities before and after the impact are ``v- = -a tan(T/2) - Gamma omega sin(phi)`` and
``v+ = a tan(T/2) - Gamma omega sin(phi)``; ``v+ = -r v-`` is the phase equation

    Gamma [(1 - r) tan(T/2) cos(phi) + (1 + r) omega sin(phi)] = (1 - r) gap tan(T/2).   (O1)

The monodromy matrix is ``Phi(T - theta) S Phi(theta)``, ``Phi`` the rotation of the free
oscillator, ``S = [[-r, 0], [(1 + r) a- / v-, -r]]`` the saltation matrix of the impact
(``a- = cos(phi) - gap``, the acceleration at the impact): its trace is ``-2 r cos(T) + k
sin(T)`` with ``k = (1 + r) a- / v-`` and its determinant ``r^2``. A multiplier is -1 where

    1 + r^2 - 2 r cos(T) + k sin(T) = 0.                                              (O2)
"""

from __future__ import annotations

import numpy as np


def orbits(omega: float, gap: float, r: float) -> list[dict[str, float]]:
    """The period-1 one-impact orbits at ``(omega, gap, r)`` with an impact from above
    (``v- < 0``): phase, ``v-``, and the period-doubling function of (O2)
    (``pd = 1 + trace + det``, zero at a period doubling)."""
    G, T = 1.0 / (1.0 - omega ** 2), 2.0 * np.pi / omega
    t2 = np.tan(T / 2.0)
    A, B, C = G * t2 * (1.0 - r), G * omega * (1.0 + r), gap * t2 * (1.0 - r)
    R, psi = float(np.hypot(A, B)), float(np.arctan2(B, A))
    if abs(C) > R:
        return []
    out = []
    for branch in (1.0, -1.0):
        phi = psi + branch * float(np.arccos(C / R))
        a = gap - G * np.cos(phi)
        v_minus = -a * t2 - G * omega * np.sin(phi)
        if v_minus >= 0:
            continue
        k = (1.0 + r) * (np.cos(phi) - gap) / v_minus
        trace = -2.0 * r * np.cos(T) + k * np.sin(T)
        out.append({"phase": float(np.mod(phi, 2 * np.pi)), "v_minus": float(v_minus),
                    "pd": float(1.0 + trace + r * r), "trace": float(trace)})
    return out


def period_doubling_function(omega: float, gap: float, r: float) -> float:
    """(O2) on the orbit with an impact from above nearest resonance (the high-velocity one
    for ``omega`` near 1): ``1 + trace + det``."""
    found = orbits(omega, gap, r)
    if not found:
        return float("nan")
    return min(found, key=lambda o: o["v_minus"])["pd"]


def section_state(omega: float, gap: float, r: float, phase: float = np.pi,
                  low_velocity: bool = False) -> np.ndarray:
    """``(q, q')`` of the orbit of :func:`period_doubling_function` (``low_velocity``: of the
    orbit whose impact velocity is nearest zero, the one that ends at a grazing) where
    ``omega t = phase`` (the stroboscopic section of the bundled problem)."""
    orbit = (max if low_velocity else min)(orbits(omega, gap, r), key=lambda o: o["v_minus"])
    G, T = 1.0 / (1.0 - omega ** 2), 2.0 * np.pi / omega
    phi = orbit["phase"]
    tau = phi / omega
    t = (phase / omega - tau) % T              # time since the impact
    a = gap - G * np.cos(phi)
    du = a * np.tan(T / 2.0)
    u, v = a * np.cos(t) + du * np.sin(t), -a * np.sin(t) + du * np.cos(t)
    return np.array([G * np.cos(phase) + u, -G * omega * np.sin(phase) + v])
