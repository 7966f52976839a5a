"""Closed-form free flight of the forced damped linear oscillator
``q'' + 2 zeta q' + q = cos(omega t)`` (``0 <= zeta < 1``) from a state ``(q0, v0)`` at ``t0``:
the flight of the impact oscillator between impacts (Nordmark & Piiroinen 2009, sec. 2.2.1),
independent of the simulator.

``q = A cos(omega t) + B sin(omega t) + exp(-zeta (t - t0)) (C cos(wd (t - t0)) + D sin(wd (t -
t0)))`` with ``wd = sqrt(1 - zeta^2)``; ``(A, B)`` solve ``(1 - omega^2) A + 2 zeta omega B =
1``, ``(1 - omega^2) B - 2 zeta omega A = 0``, and ``(C, D)`` fit ``q(t0) = q0``, ``q'(t0) =
v0``.
"""

from __future__ import annotations

import numpy as np


def free_flight(t: np.ndarray, t0: float, q0: float, v0: float, zeta: float,
                omega: float) -> tuple[np.ndarray, np.ndarray]:
    """``(q(t), q'(t))`` of the free flight from ``(q0, v0)`` at ``t0``."""
    k, c = 1.0 - omega ** 2, 2.0 * zeta * omega
    A, B = np.linalg.solve(np.array([[k, c], [-c, k]]), np.array([1.0, 0.0]))
    wd = np.sqrt(1.0 - zeta ** 2)
    qp0 = A * np.cos(omega * t0) + B * np.sin(omega * t0)
    vp0 = omega * (-A * np.sin(omega * t0) + B * np.cos(omega * t0))
    C = q0 - qp0
    D = (v0 - vp0 + zeta * C) / wd
    s = np.asarray(t, dtype=float) - t0
    e = np.exp(-zeta * s)
    cs, sn = np.cos(wd * s), np.sin(wd * s)
    q = A * np.cos(omega * t) + B * np.sin(omega * t) + e * (C * cs + D * sn)
    v = (omega * (-A * np.sin(omega * t) + B * np.cos(omega * t))
         + e * ((-zeta * C + wd * D) * cs + (-zeta * D - wd * C) * sn))
    return q, v
