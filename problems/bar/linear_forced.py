"""Linear forced responses of the damped bar in closed form (section 7's references).

Yoong, Thorin, Legrand (2017), section 7: ``rho u_tt + eta u_t - E u_xx = f``. Without contact
(clamped-free bar, uniform force ``f = f0 sin(omega t)``): the end amplitude
(:func:`linear_forced_end_amplitude`), the period-averaged energy (:func:`linear_forced_energy`)
and the cell averages of the steady fields (:func:`linear_forced_fields`); in permanent contact
with the moving wall ``w(t) = w0 sin(omega t)`` (g0 < 0, fixed-fixed bar with a moving end): the
energy and the contact margin (:func:`linear_wall_response`). Oracles of the WFEM forced response
far from contact, independent of the time stepping.
"""

from __future__ import annotations

import math

import numpy as np
from nsm_continuation.problems.bar.wfem_stepping import BarParams


def linear_forced_end_amplitude(params: BarParams, f0: float, omega: float,
                                eta: float) -> complex:
    """Complex steady-state end displacement ``U(L)`` of the clamped-free bar without contact
    under ``f = f0 sin(omega t)`` uniform: ``u(L, t) = Im(U(L) e^(i omega t))``.

    ``rho u_tt + eta u_t - E u_xx = f0 sin(omega t)``, ``u(0) = 0``, ``u_x(L) = 0``:
    ``U(x) = f0/(E k^2) (cos(k (L - x)) / cos(k L) - 1)``, ``k^2 = (rho omega^2 - i eta
    omega)/E``. Test oracle, independent of the WFEM.
    """
    k = np.sqrt((params.rho * omega**2 - 1j * eta * omega) / params.E + 0j)
    return complex(f0 / (params.E * k * k) * (1.0 / np.cos(k * params.L) - 1.0))


def _wavenumber(params: BarParams, omega: float, eta: float) -> complex:
    """``k = sqrt((rho omega^2 - i eta omega) / E)`` (principal root) of the damped bar."""
    return complex(np.sqrt((params.rho * omega**2 - 1j * eta * omega) / params.E + 0j))


def _sinh_ratio(y: float) -> float:
    """``sinh(y) / y`` (1 at 0)."""
    return math.sinh(y) / y if abs(y) > 1e-8 else 1.0 + y * y / 6.0


def _sin_ratio(y: float) -> float:
    """``sin(y) / y`` (1 at 0)."""
    return math.sin(y) / y if abs(y) > 1e-8 else 1.0 - y * y / 6.0


def _abs_trig_integrals(k: complex, L: float) -> tuple[float, float]:
    """``int_0^L |cos(k s)|^2 ds`` and ``int_0^L |sin(k s)|^2 ds`` for ``k = a + i b``:
    ``|cos|^2 = (cosh(2 b s) + cos(2 a s)) / 2``, ``|sin|^2 = (cosh(2 b s) - cos(2 a s)) / 2``."""
    h = L * _sinh_ratio(2.0 * k.imag * L)
    c = L * _sin_ratio(2.0 * k.real * L)
    return 0.5 * (h + c), 0.5 * (h - c)


def linear_forced_energy(params: BarParams, f0: float, omega: float, eta: float) -> float:
    """Period-averaged total energy of the steady state of :func:`linear_forced_end_amplitude`
    (clamped-free bar, no contact, ``f = f0 sin(omega t)`` uniform), in closed form.

    With ``U(x) = A (cos(k s) / C - 1)``, ``s = L - x``, ``C = cos(k L)``, ``A = f0 / (E k^2)``:
    ``<E> = S/4 int_0^L (rho omega^2 |U|^2 + E |U'|^2) dx`` (the time average of
    ``Im(X e^(i omega t))^2`` is ``|X|^2 / 2``), ``int |U|^2 = |A|^2 (I_cc / |C|^2
    - 2 Re(tan(k L) / k) + L)`` and ``int |U'|^2 = |A k|^2 I_ss / |C|^2`` with the integrals of
    :func:`_abs_trig_integrals`. Oracle of the forced-response sweep far from contact.
    """
    k = _wavenumber(params, omega, eta)
    L = params.L
    A = f0 / (params.E * k * k)
    C = np.cos(k * L)
    i_cc, i_ss = _abs_trig_integrals(k, L)
    int_u2 = abs(A) ** 2 * (i_cc / abs(C) ** 2 - 2.0 * (np.tan(k * L) / k).real + L)
    int_ux2 = abs(A * k) ** 2 * i_ss / abs(C) ** 2
    return float(params.S / 4.0 * (params.rho * omega**2 * int_u2 + params.E * int_ux2))


def linear_wall_response(params: BarParams, w0: float, omega: float,
                         eta: float) -> tuple[float, float]:
    """Period-averaged energy and contact margin of the bar held in *permanent contact* with
    the wall ``w(t) = w0 sin(omega t)`` (``g0 < 0``, section 7), in closed form.

    Fixed-fixed bar with ``u(L, t) = g0 + w(t)``: static prestress ``sigma = E g0 / L`` plus
    ``Im(W(x) e^(i omega t))``, ``W = w0 sin(k x) / sin(k L)``; the mean energy is
    ``E S g0^2 / (2L) + S/4 int (rho omega^2 |W|^2 + E |W'|^2)`` (the cross terms average to
    0). The contact force stays compressive, hence the contact permanent and this the response
    of the bar with the unilateral wall, iff the margin ``-g0 / L - |W'(L)| >= 0``.
    """
    k = _wavenumber(params, omega, eta)
    L = params.L
    sL = np.sin(k * L)
    i_cc, i_ss = _abs_trig_integrals(k, L)
    dyn = params.S / 4.0 * abs(w0 / sL) ** 2 * (params.rho * omega**2 * i_ss
                                                 + params.E * abs(k) ** 2 * i_cc)
    static = params.E * params.S * params.g0**2 / (2.0 * L)
    margin = -params.g0 / L - abs(w0 * k * np.cos(k * L) / sL)
    return float(static + dyn), float(margin)


def linear_forced_fields(params: BarParams, f0: float, omega: float, eta: float,
                         t: float = 0.0, n_gauss: int = 4) -> tuple[np.ndarray, np.ndarray,
                                                                     float]:
    """Cell averages of ``(sigma, v)`` and ``u(L)`` of the steady state above at time t
    (Gauss quadrature per cell), to start a simulation on the steady orbit."""
    k = np.sqrt((params.rho * omega**2 - 1j * eta * omega) / params.E + 0j)
    A = f0 / (params.E * k * k)
    xg, wg = np.polynomial.legendre.leggauss(n_gauss)
    xl = np.arange(params.N) * params.dx
    xq = xl[:, None] + 0.5 * params.dx * (xg[None, :] + 1.0)
    ph = np.exp(1j * omega * t)
    U = A * (np.cos(k * (params.L - xq)) / np.cos(k * params.L) - 1.0)
    Ux = A * k * np.sin(k * (params.L - xq)) / np.cos(k * params.L)
    sigma = np.imag(params.E * Ux * ph) @ wg / 2.0
    v = np.imag(1j * omega * U * ph) @ wg / 2.0
    uL = float(np.imag(A * (1.0 / np.cos(k * params.L) - 1.0) * ph))
    return sigma, v, uL


__all__ = [
    "linear_forced_end_amplitude",
    "linear_forced_energy",
    "linear_forced_fields",
    "linear_wall_response",
]
