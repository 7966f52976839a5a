"""The saltation matrix (43) and the bouncing ball's Jacobians (secs. 4.2-4.4, eqs. 47-50).

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
kind (``tests/test_hybrid_ball.py`` checks the simulator against (47) for the ball).

**Bouncing ball** (sec. 3.5, 4.4): ``x = (x1, x2) = (q, qd)``, ``F = (x2, -g)``, ``H = x1``,
``W = (0, -(1 + e))``; extended state ``(x1, x2, h, u)`` of sec. 4.3 (``h = H/u``, ``u`` the
latest outgoing velocity). Released from rest at ``s``: first impact velocity
``v0' = -sqrt(2 g s)``, ``v_k' = -v_k = e^k v0'`` (``v_k`` the initial velocity of flight ``k``).

:func:`ball_extended_matrices` gives the printed matrices of eq. (47) (``P_0x``, ``D_k``,
``P_k``); the tests check that ``D_k`` is :func:`saltation_matrix` applied to the extended impact
and that ``P_k`` is the flow Jacobian of the extended field. :func:`ball_pn_closed_form` gives
``p_n`` of eq. (48). **Erratum in (48)**: the chained product of the (correct) matrices (47) has
the ``(4, 1)`` entry (``du/ds``) ``-(g / v0') e^n`` — i.e. ``-(g/v0') e^n (1 - e) / (1 - e)`` —
while the paper prints ``-(g/v0') e^n (1 - e^n) / (1 - e)``. The two agree for ``n = 1`` only.
Direct derivation: after ``n`` impacts ``u = e^n sqrt(2 g s + w^2)``, so
``du/ds = e^n g / sqrt(2 g s) = -(g / v0') e^n``. Every other entry of (48) is right, and so is
(50). ``ball_pn_closed_form(..., as_printed=True)`` returns the printed version for comparison.
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


def ball_extended_matrices(e: float, g: float, v0: float, n: int
                           ) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """The printed matrices of eq. (47) for the bouncing ball released from rest.

    ``v0`` is the first impact velocity ``v0' = -sqrt(2 g s) < 0``. Returns ``(P0x, D, P)``:
    ``P0x`` (4 x 2) the Jacobian of the extended state ``(x1, x2, h, u)`` at the first impact
    with respect to the initial ``(s, w)``; ``D[k]`` (4 x 4, ``k = 0..n-1``) the extended impact
    saltation matrix at impact ``k`` (impact velocity ``v_k' = e^k v0'``); ``P[k - 1]``
    (4 x 4, ``k = 1..n``) the extended flow Jacobian of flight ``k`` (initial velocity
    ``v_k = -v_k'``, duration ``2 v_k / g``).
    """
    P0x = np.array([[1.0, -v0 / g],
                    [0.0, 1.0],
                    [-1.0 / v0, 1.0 / g],
                    [-g / v0, 0.0]])
    D, P = [], []
    for k in range(n):
        vk_ = e**k * v0                                   # impact velocity v_k'
        D.append(np.array([[1.0, 0.0, (1 + e) * vk_, 0.0],
                           [0.0, -e, (1 + e) * g, 0.0],
                           [0.0, 0.0, -1.0, 0.0],
                           [0.0, -e, e * g, 0.0]]))
    for k in range(1, n + 1):
        vk = -(e**k) * v0                                 # initial velocity of flight k
        P.append(np.array([[1.0, 2 * vk / g, 0.0, 0.0],
                           [0.0, 1.0, 0.0, 0.0],
                           [0.0, 2.0 / g, 1.0, 0.0],
                           [0.0, 0.0, 0.0, 1.0]]))
    return P0x, D, P


def ball_pn_chain(e: float, g: float, v0: float, n: int) -> np.ndarray:
    """``p_n = (prod_{k=1}^n P_k D_{k-1}) P_0x`` multiplied out from (47) (4 x 2)."""
    P0x, D, P = ball_extended_matrices(e, g, v0, n)
    p = P0x
    for k in range(1, n + 1):
        p = P[k - 1] @ D[k - 1] @ p
    return p


def ball_pn_closed_form(e: float, g: float, v0: float, n: int,
                        as_printed: bool = False) -> np.ndarray:
    """Closed form of ``p_n`` (eq. 48): Jacobian of ``(x1, x2, h, u)`` just before impact ``n``
    (``n`` impacts done) with respect to the initial ``(s, w)``.

    The ``(4, 1)`` entry is the corrected ``-(g/v0') e^n`` (see the module docstring);
    ``as_printed=True`` returns the paper's ``-(g/v0') e^n (1 - e^n) / (1 - e)`` instead.
    """
    en = e**n
    u_s = en * (1 - en) if as_printed else en * (1 - e)
    return np.array([
        [en * (1 + e - 2 * e ** (n + 1)), -(v0 / g) * en * (1 - e)],
        [-(g / v0) * (1 + e) * (1 - en), 1 - e],
        [-(1 / v0) * (1 + e - 2 * e ** (n + 1)), (1 - e) / g],
        [-(g / v0) * u_s, 0.0],
    ]) / (1 - e)


def ball_chatter_jacobian(e: float, n: int, v0: float) -> np.ndarray:
    """``D_N`` of eq. (50) (2 x 4): the Jacobian of the discontinuity mapping of the exact
    chatter map (49) ``E(x^) = (x1, 0)``, ``e(x^) = -2 e x2 / (g (1 - e))`` applied at impact
    ``N = n`` (impact velocity ``e^n v0'``), dropping the extended variables. ``D_N p_N = 0``:
    the sticking state does not depend on the initial condition."""
    return np.array([[1.0, 0.0, e**n * v0, 0.0],
                     [0.0, 0.0, 0.0, 0.0]])


def ball_chatter_saltation(e: float, g: float, v0: float, n: int) -> np.ndarray:
    """``D_N`` of eq. (50) computed by :func:`saltation_matrix` from the chatter map (49) on the
    extended state (for the tests: equals :func:`ball_chatter_jacobian`)."""
    vn = e**n * v0
    E_x = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    e_x = np.array([0.0, -2 * e / (g * (1 - e)), 0.0, 0.0])
    B1 = np.array([vn, -g, vn / (-vn), 0.0])              # extended field, u = -v_n'
    B2 = np.zeros(2)                                       # F' at the sticking state (0, 0)
    C = np.array([0.0, 0.0, 1.0, 0.0])                     # extended event function h
    return saltation_matrix(E_x, e_x, B1, B2, C)
