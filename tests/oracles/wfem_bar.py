"""Test-only oracles of the WFEM bar (Yoong, Thorin, Legrand 2017).

``ring_basis``: the change of basis from ``Q = [sigma; v]`` to the ring layout of
:mod:`nsm_continuation.problems.bar.wfem_operators` (the dense operators of (A.22)-(A.27) vs
the signed rotations); ``integrated_end_displacement``: the contact-end displacement as the time
integral of the end velocity (vs the stress sum of
:mod:`nsm_continuation.problems.bar.plots`); ``falling_bar_exact``: the Table 1 bouncing bar
from the back-traced characteristics of
:class:`~nsm_continuation.problems.bar.bouncing_bar_exact.BouncingBarExact` (vs
:mod:`nsm_continuation.problems.bar.wfem_simulation`); ``modal_steady_state``: the steady state
of the damped, forced, clamped-free linear bar from its modal series
``q_k'' + (eta/rho) q_k' + omega_k^2 q_k = 2 f0 / (rho L beta_k) sin(omega t)`` (no code shared
with the package)."""

from __future__ import annotations

import numpy as np
from nsm_continuation.problems.bar.bouncing_bar_exact import BouncingBarExact
from nsm_continuation.problems.bar.plots import end_velocity
from nsm_continuation.problems.bar.wfem_lattice import LatticeSolution
from nsm_continuation.problems.bar.wfem_simulation import BarParams


def ring_basis(N: int, Z: float) -> np.ndarray:
    """Matrix ``T`` with ``w = T Q`` for ``Q = [sigma; v]`` (tests: ``A_ring = T A T^-1``)."""
    T = np.zeros((2 * N, 2 * N))
    for i in range(N):
        T[i, i], T[i, N + i] = 1.0, -Z                  # b_i
        T[2 * N - 1 - i, i], T[2 * N - 1 - i, N + i] = 1.0, Z  # a_i
    return T


def integrated_end_displacement(sol: LatticeSolution) -> np.ndarray:
    """``u_(N+1/2)(t_n)``, n = 0..M, as ``g0 + dt sum_(j<n) v_(N+1/2)[j]`` (gap normalisation).

    For amplitude-free orbits (``g0 = 0``) the start is 0 as well: ``sum w = 0`` there.
    """
    v = end_velocity(sol)
    return sol.model.g0 + sol.model.dt * np.concatenate([[0.0], np.cumsum(v)])


def falling_bar_exact(t: np.ndarray | float, t_end: float | None = None,
                      **params: float | str) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                      np.ndarray]:
    """``(u_end, v_end, contact_force, energy)`` of the Table 1 bouncing bar at times ``t``.

    ``params`` override the Table 1 values (E, rho, L, g0, F0, S, left). ``energy`` is the
    elastic + kinetic energy of the bar (the body-force potential is
    :meth:`BouncingBarExact.potential`).
    """
    tt = np.atleast_1d(np.asarray(t, dtype=float))
    horizon = float(np.max(tt)) + 1.0 if t_end is None else t_end
    sol = BouncingBarExact(t_end=horizon, **params)  # type: ignore[arg-type]
    en = np.array([sol.energy(float(ti)) for ti in tt])
    return sol.u_end(tt), sol.v_end(tt), sol.contact_force(tt), en


def modal_steady_state(p: BarParams, f0: float, omega: float, eta: float,
                       n_modes: int = 4000) -> tuple[complex, float]:
    """``U(L)`` and the period-averaged energy from the modal series of the bar ``p``."""
    k = np.arange(1, n_modes + 1)
    beta = (2 * k - 1) * np.pi / (2 * p.L)
    om_k = p.c * beta
    Q = (2 * f0 / (p.rho * p.L * beta)) / (om_k**2 - omega**2 + 1j * eta / p.rho * omega)
    U_L = complex(np.sum(Q * (-1.0) ** (k + 1)))
    m_k = p.rho * p.S * p.L / 2
    energy = float(np.sum(m_k / 4 * (omega**2 + om_k**2) * np.abs(Q) ** 2))
    return U_L, energy
