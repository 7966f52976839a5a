"""Test-only oracle for the bouncing ball (Nordmark & Piiroinen 2009, sec. 4.4, eq. 50).

``ball_chatter_saltation``: ``D_N`` of eq. (50) rebuilt from the generic saltation matrix (43)
applied to the exact chatter map (49) on the extended state ``(x1, x2, h, u)``; the tests compare
it with the printed ``D_N`` (``ball_chatter_jacobian`` of
:mod:`nsm_continuation.problems.impacting.bouncing_ball`)."""

from __future__ import annotations

import numpy as np

from nsm_continuation.hybrid.saltation import saltation_matrix


def ball_chatter_saltation(e: float, g: float, v0: float, n: int) -> np.ndarray:
    """``D_N`` of eq. (50) computed by :func:`saltation_matrix` from the chatter map (49) on the
    extended state (equals
    :func:`~nsm_continuation.problems.impacting.bouncing_ball.ball_chatter_jacobian`)."""
    vn = e**n * v0
    E_x = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    e_x = np.array([0.0, -2 * e / (g * (1 - e)), 0.0, 0.0])
    B1 = np.array([vn, -g, vn / (-vn), 0.0])              # extended field, u = -v_n'
    B2 = np.zeros(2)                                       # F' at the sticking state (0, 0)
    C = np.array([0.0, 0.0, 1.0, 0.0])                     # extended event function h
    return saltation_matrix(E_x, e_x, B1, B2, C)
