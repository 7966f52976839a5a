"""The error norms of an embedded Runge-Kutta step of the hybrid simulator
(:meth:`.simulate.Simulator._attempt` accepts a step when the larger is at most 1).

:func:`state_error_norm` is SciPy's for the state (DOP853: its two estimates combined as in
``scipy.integrate.DOP853``; DOPRI5: the RMS norm). :func:`sensitivity_error_norm` covers the
sensitivities ``J`` carried over the step, as CVODES' ``errconS`` does: the step integrates the
variational equations along with the state, and its error estimate for them is the estimate's
own derivative, ``d err / dY @ J`` (the step of the variational equations is the derivative of
the step); each column (the sensitivity to one initial component or freed parameter) is scaled
like the state (``atol + rtol |J|``, CVODES' ``atolS = atol / pbar`` with ``pbar = 1``) and
the worst column counts. Without it the step size follows the state alone, which on an orbit
where the state has no local error (a constant radius) leaves the transverse contraction
``dr/dr0``, hence the multipliers, to steps as long as a fraction of the period
(``tests/hybrid/test_multiplier_error_control.py``).
"""

from __future__ import annotations

import math

import numpy as np


def state_error_norm(Y: np.ndarray, Yn: np.ndarray, err: np.ndarray, err3: np.ndarray,
                     rtol: float, atol: float, dop853: bool) -> float:
    """The scaled error norm of the step from ``Y`` to ``Yn`` with the estimates ``err``
    (and ``err3``, DOP853's second)."""
    scale = atol + rtol * np.maximum(np.abs(Y), np.abs(Yn))
    e5 = err.ravel() / scale
    if dop853:
        e3 = err3.ravel() / scale
        n5, n3 = float(e5 @ e5), float(e3 @ e3)
        if n5 == 0.0 and n3 == 0.0:
            return 0.0
        return n5 / np.sqrt((n5 + 0.01 * n3) * len(scale))
    return float(np.sqrt(e5 @ e5 / len(scale)))


def sensitivity_error_norm(J: np.ndarray, Jn: np.ndarray, dE: np.ndarray, rtol: float,
                           atol: float) -> float:
    """The scaled error norm of the sensitivities carried by the step from ``J`` to ``Jn``
    (``m x N``), ``dE`` the Jacobians of the step's error estimates stacked (``k m x m``:
    ``d err / dY`` and, for DOP853, ``d err3 / dY``); the worst column's."""
    scale = np.abs(J)
    np.maximum(scale, np.abs(Jn), out=scale)
    scale *= rtol
    scale += atol
    m = J.shape[0]
    # one m x m product per estimate, as the chaining's own (a product twice as tall crosses
    # BLAS's threading threshold at large m: milliseconds on shared cores)
    sq = []
    for k in range(0, dE.shape[0], m):
        e = dE[k:k + m] @ J
        e /= scale
        sq.append(np.square(e, out=e).sum(axis=0))      # per column
    if len(sq) == 1:
        # DOPRI5: the RMS norm of each column
        return math.sqrt(float(sq[0].max()) / m)
    # DOP853: each column's two estimates combined as for the state; a column whose both
    # estimates vanish has norm 0
    n5 = sq[0]
    return float(np.max(n5 / np.sqrt(np.maximum(n5 + 0.01 * sq[1], 1e-300) * m)))
