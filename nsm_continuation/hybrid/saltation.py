"""The saltation matrix (43) and its chaining into the Jacobian of the time-T map (40)-(43).

**Saltation matrix.** An event ``k`` (impact ``E = R, e = 0``; complete chattering ``E = Q,
e = q``; release ``E = Id, e = 0`` on ``H_k = a``) between a flow of ``F_k`` that reaches the
event surface ``H_k = 0`` at ``x'_k`` and a flow of ``F_{k+1}`` that starts at
``x_{k+1} = E(x'_k)`` has the discontinuity-mapping Jacobian (eq. 43)::

    D = A + (B2 - A B1) C / d,    A = E_x - B2 e_x,   B1 = F_k(x'_k),   B2 = F_{k+1}(x_{k+1}),
                                  d = H_x B1 = L_{F_k} H_k (x'_k),   C = H_x(x'_k),

and the Jacobian of the time-``T`` map is the product (40)-(43)
``P_x = P_N D_{N-1} P_{N-1} ... D_0 P_0`` of flow Jacobians and saltation matrices.

**The simulator computes the same product** (:mod:`.simulate`), in event-parametrised form. It
carries ``J = dx/dx0`` and ``J_t = dt/dx0`` of the state "a fixed flow time after the latest
event", and at an event::

    dtau = -(C J) / d                     (event-time sensitivity from H_k(x(tau)) = 0)
    J    <- J + B1 dtau                   (the pre-event point x'_k(x0) on the surface)
    J_t  <- J_t + dtau + e_x J            (time jump of the event, e = q for the chatter map)
    J    <- E_x J

and, at a fixed end time, returns the time-fixed Jacobian ``J - F(x_end) J_t``. The quantity
``K = J - F(x(t)) J_t`` is exactly the time-fixed Jacobian: along a flow both ``J`` and
``F(x(t)) J_t`` are transported by the flow Jacobian ``Phi`` (``Phi F(x_start) = F(x_end)`` for
an autonomous field), and across an event (``K = J - B1 J_t`` just before it) the four lines
above give ``K_new = E_x J' - B2 (J_t + dtau + e_x J') = A J' - B2 (J_t + dtau)`` with
``J' = J - B1 (C J)/d``, which expands to ``A K + (B2 - A B1) (C K)/d = D K`` (using
``C B1 = d``): the saltation matrix (43). So the simulated ``J`` (time-fixed) is the chain (40),
and for a Poincaré section the section crossing is one more event-time correction of the same
kind (``tests/hybrid/test_saltation_and_bouncing_ball.py`` checks the simulator against (47) for
the ball).

The bouncing ball's printed matrices (47)-(50) and the erratum in (48) live with the
ball itself, in :mod:`nsm_continuation.problems.impacting.bouncing_ball` (problem-specific
helpers ``ball_*``; this module keeps only the generic saltation matrix).
"""

from __future__ import annotations

import numpy as np


def saltation_matrix(E_x: np.ndarray, e_x: np.ndarray, F_before: np.ndarray,
                     F_after: np.ndarray, H_x: np.ndarray) -> np.ndarray:
    """Jacobian of the discontinuity mapping of a (possibly non-instantaneous) event, eq. (43).

    ``E_x`` (m x n): Jacobian of the event map at ``x'_k``; ``e_x`` (n): gradient of its time
    jump (zeros for an impact or a release); ``F_before`` = ``B1 = F_k(x'_k)`` (n);
    ``F_after`` = ``B2 = F_{k+1}(x_{k+1})`` (m); ``H_x`` = ``C``, gradient of the event
    function at ``x'_k`` (n). Returns ``D = A + (B2 - A B1) C / d`` with ``A = E_x - B2 e_x``,
    ``d = C B1`` (the transversality, non-zero for a transversal event).
    """
    E_x = np.atleast_2d(np.asarray(E_x, dtype=float))
    e_x = np.asarray(e_x, dtype=float).ravel()
    B1 = np.asarray(F_before, dtype=float).ravel()
    B2 = np.asarray(F_after, dtype=float).ravel()
    C = np.asarray(H_x, dtype=float).ravel()
    d = float(C @ B1)
    if d == 0.0:
        raise ValueError("saltation_matrix: non-transversal event (H_x . F_before = 0)")
    A = E_x - np.outer(B2, e_x)
    return A + np.outer(B2 - A @ B1, C) / d
