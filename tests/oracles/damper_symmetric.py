"""Closed forms of the impact damper's symmetric two-impact orbit (independent of the simulator
and of the engine).

A primary mass ``x'' + 2 zeta x' + x = cos(omega t)`` carries a cavity of clearance ``d`` in
which a ball of mass ratio ``mu`` moves freely (``y'' = 0``); at ``|z| = d/2``, ``z = y - x``,
momentum is conserved and the relative velocity reversed with restitution ``e``:
``x'+ = x'- + mu (1 + e) zdot- / (1 + mu)``, ``y'+ = y'- - (1 + e) zdot- / (1 + mu)``.

**The symmetric orbit** (Masri & Caughey 1966): one impact per half period ``tau = pi /
omega`` on alternate walls, the state after ``tau`` the negative of the state now. Take an
impact on the wall ``z = +d/2`` at forcing phase ``phi`` (time 0), the primary there at ``x0``
with velocity ``v0`` just after it; the ball starts at ``y0 = x0 + d/2`` and, by the symmetry
``y(tau) = -y0``, flies with ``V = -2 y0 / tau``. Between impacts ``x`` is the forced linear
response plus a free one fixed by ``(x0, v0)`` (:func:`flight`). The symmetry and the impact
law at ``tau`` give (:func:`residual`)

    x(tau) = -x0,                                  (S1: the primary's position)
    x'(tau-) = -v0 - 2 mu V,                       (S2: momentum through the impact)
    (v0 - V) + e (V + v0 + 2 mu V) = 0,            (S3: restitution of the relative velocity)

three equations in ``(x0, v0, phi)``.

**Its ends.** Where the impact velocity vanishes the ball rests at the centre (``V = 0``) and
the primary swings with the linear response's amplitude ``A = 1 / sqrt((1 - w^2)^2 + (2 zeta
w)^2)``, touching both walls: ``A = d/2`` (:func:`end_frequency`; ``sqrt(3)`` for ``zeta = 0,
d = 1``). Where the relative motion touches a wall between impacts (an interior contact: on
the high-velocity orbit the primary overtakes the ball and the wall it left, ``z = +d/2``,
comes back to it with ``zdot = 0`` at some ``t*`` in ``(0, tau)``), (S1)-(S3) with ``z(t*) =
d/2`` and ``zdot(t*) = 0`` are five equations in ``(x0, v0, phi, omega, t*)``
(:func:`interior_grazing`); by the symmetry the other wall is touched half a period later.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.optimize import brentq, fsolve


def _solve(fun, guess, args=()):  # type: ignore[no-untyped-def]
    """``fsolve`` to its limit (its warning that 1e-14 cannot be met is the point: the
    caller checks the residual)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return fsolve(fun, guess, args=args, xtol=1e-14)


def flight(x0: float, v0: float, phi: float, t: float, omega: float, zeta: float
           ) -> tuple[float, float]:
    """``(x, x')`` at time ``t`` of ``x'' + 2 zeta x' + x = cos(omega t + phi)`` from ``(x0,
    v0)`` at ``t = 0``."""
    G = 1.0 / (1.0 - omega ** 2 + 2j * zeta * omega)

    def forced(s: float) -> tuple[float, float]:
        e = G * np.exp(1j * (omega * s + phi))
        return float(e.real), float((1j * omega * e).real)

    wd = np.sqrt(1.0 - zeta ** 2)
    xp0, vp0 = forced(0.0)
    a = x0 - xp0
    b = (v0 - vp0 + zeta * a) / wd
    decay = np.exp(-zeta * t)
    xh = decay * (a * np.cos(wd * t) + b * np.sin(wd * t))
    vh = -zeta * xh + decay * wd * (-a * np.sin(wd * t) + b * np.cos(wd * t))
    xp, vp = forced(t)
    return float(xh + xp), float(vh + vp)


def residual(u: np.ndarray, omega: float, zeta: float, mu: float, e: float, d: float
             ) -> list[float]:
    """(S1)-(S3) at ``u = (x0, v0, phi)``."""
    x0, v0, phi = u
    tau = np.pi / omega
    V = -2.0 * (x0 + d / 2.0) / tau
    xt, vt = flight(x0, v0, phi, tau, omega, zeta)
    return [xt + x0, vt + v0 + 2.0 * mu * V, (v0 - V) + e * (V + v0 + 2.0 * mu * V)]


def orbit(omega: float, zeta: float, mu: float, e: float, d: float,
          guess: tuple[float, float, float]) -> np.ndarray:
    """``(x0, v0, phi)`` of the symmetric orbit nearest ``guess`` (solved to 1e-13)."""
    u = _solve(residual, guess, (omega, zeta, mu, e, d))
    assert np.max(np.abs(residual(u, omega, zeta, mu, e, d))) < 1e-12
    return np.asarray(u, dtype=float)


def impact_velocity(u: np.ndarray, omega: float, zeta: float, mu: float, d: float) -> float:
    """The relative velocity ``zdot-`` just before the impact at ``tau`` (on ``z = -d/2``:
    negative for a ball that hits that wall)."""
    x0, v0, phi = u
    tau = np.pi / omega
    V = -2.0 * (x0 + d / 2.0) / tau
    return float(V - flight(x0, v0, phi, tau, omega, zeta)[1])


def section_state(u: np.ndarray, omega: float, zeta: float, d: float, phase: float
                  ) -> np.ndarray:
    """``(x, y, x', y')`` where the forcing phase is ``phase`` (mod 2 pi)."""
    x0, v0, phi = u
    tau = np.pi / omega
    y0 = x0 + d / 2.0
    V = -2.0 * y0 / tau
    s = ((phase - phi) % (2.0 * np.pi)) / omega
    sign = 1.0
    if s > tau:  # after the second impact the state is the negative of the first half's
        s, sign = s - tau, -1.0
    x, v = flight(x0, v0, phi, s, omega, zeta)
    return sign * np.array([x, y0 + V * s, v, V])


def end_frequency(zeta: float, d: float, bracket: tuple[float, float]) -> float:
    """The forcing frequency in ``bracket`` where the linear response's amplitude is ``d/2``:
    the impact velocity of the symmetric orbit vanishes there."""
    def f(w: float) -> float:
        return 1.0 / np.sqrt((1.0 - w * w) ** 2 + (2.0 * zeta * w) ** 2) - d / 2.0

    return float(brentq(f, *bracket, xtol=1e-15, rtol=4 * np.finfo(float).eps))


def interior_grazing(zeta: float, mu: float, e: float, d: float,
                     guess: tuple[float, float, float, float, float]) -> np.ndarray:
    """``(x0, v0, phi, omega, t*)`` of the symmetric orbit whose relative motion touches the
    wall ``z = d/2`` again at ``t*`` in ``(0, tau)`` after its impact there at time 0."""
    def eqs(w: np.ndarray) -> list[float]:
        x0, v0, phi, omega, ts = w
        tau = np.pi / omega
        V = -2.0 * (x0 + d / 2.0) / tau
        x, v = flight(x0, v0, phi, ts, omega, zeta)
        z, zdot = x0 + d / 2.0 + V * ts - x, V - v
        return [*residual(np.array([x0, v0, phi]), omega, zeta, mu, e, d), z - d / 2.0, zdot]

    w = _solve(eqs, guess)
    assert np.max(np.abs(eqs(w))) < 1e-12 and 0.0 < w[4] < np.pi / w[3]
    return np.asarray(w, dtype=float)
