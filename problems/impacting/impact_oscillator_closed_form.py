"""Closed forms of the undamped forced impact oscillator ``q'' + q = cos(omega t)``, ``q >=
gap`` (``gap < 0``), Newton restitution ``r`` (Shaw & Holmes 1983; Nordmark & Piiroinen 2009,
sec. 2.2.1 with ``zeta = 0``), drawn over the computed branches
(:class:`ImpactOscillatorPresentation`): the free orbit, the one-impact period-1 orbits, the
grazing curve and the period-doubling curve in ``(gap, omega)``.

Between impacts ``q = Gamma cos(omega t) + u(t)``, ``Gamma = 1 / (1 - omega^2)``, ``u`` a free
oscillation. The free orbit (no impact) is ``u = 0``, amplitude ``|Gamma|``; it touches the stop
where ``|Gamma| = -gap`` (the grazing curve, G1: ``omega^2 = 1 +- 1/|gap|``). With one impact
per period at phase ``phi = omega tau``, ``a = gap - Gamma cos(phi)`` and ``T = 2 pi / omega``,
periodicity gives ``u(tau + s) = a (cos s + tan(T/2) sin s)`` on ``0 <= s <= T``, and ``v+ = -r
v-`` is the phase equation

    Gamma [(1 - r) tan(T/2) cos(phi) + (1 + r) omega sin(phi)] = (1 - r) gap tan(T/2)   (O1)

with ``v- = -a tan(T/2) - Gamma omega sin(phi) < 0``. A multiplier is -1 where

    1 + r^2 - 2 r cos(T) + k sin(T) = 0,   k = (1 + r)(cos(phi) - gap) / v-           (O2)

(the monodromy ``Phi(T - theta) S Phi(theta)``, ``S`` the saltation matrix of the impact:
trace ``-2 r cos T + k sin T``, determinant ``r^2``). The tests compare these with the
independent oracle ``tests/oracles/impact_oscillator.py`` and with the computed branches.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from nsm_continuation.hybrid.presentation import HybridCasePresentation

#: samples of one period when the extremes of an orbit are taken
SAMPLES = 400
#: an orbit dipping below the stop by more than this (relative to its amplitude) is not one
ADMISSIBLE_TOL = 1e-9


def free_amplitude(omega: np.ndarray | float, zeta: float = 0.0) -> np.ndarray:
    """Amplitude of the free (non-impacting) periodic orbit of ``q'' + 2 zeta q' + q =
    cos(omega t)``: ``1 / sqrt((1 - omega^2)^2 + (2 zeta omega)^2)``."""
    w = np.asarray(omega, dtype=float)
    return 1.0 / np.hypot(1.0 - w * w, 2.0 * zeta * w)


def grazing_omegas(gap: float) -> list[float]:
    """The forcing frequencies at which the undamped free orbit grazes the stop at ``gap < 0``
    (``|Gamma| = -gap``): ``sqrt(1 + 1/|gap|)``, and ``sqrt(1 - 1/|gap|)`` for ``|gap| > 1``."""
    if gap >= 0:
        return []
    out = [float(np.sqrt(1.0 + 1.0 / -gap))]
    if -gap > 1.0:
        out.insert(0, float(np.sqrt(1.0 - 1.0 / -gap)))
    return out


def one_impact_orbits(omega: float, gap: float, r: float, samples: int = SAMPLES
                      ) -> list[dict[str, float]]:
    """The admissible period-1 orbits with one impact from above at ``(omega, gap, r)``
    (O1, ``v- < 0``, ``q >= gap`` on ``samples`` instants of the period): phase of the
    impact, ``v-``, the period-doubling function of (O2) and the response amplitude ``(max q -
    min q) / 2`` (the maximum refined between the samples)."""
    if omega == 1.0:
        return []
    G, T = 1.0 / (1.0 - omega ** 2), 2.0 * np.pi / omega
    t2 = np.tan(T / 2.0)
    A, B, C = G * t2 * (1.0 - r), G * omega * (1.0 + r), gap * t2 * (1.0 - r)
    R, psi = float(np.hypot(A, B)), float(np.arctan2(B, A))
    if not R > abs(C):
        return []
    s = np.linspace(0.0, T, samples)
    out = []
    for branch in (1.0, -1.0):
        phi = psi + branch * float(np.arccos(C / R))
        a = gap - G * np.cos(phi)
        v_minus = -a * t2 - G * omega * np.sin(phi)
        if v_minus >= 0:
            continue
        def q_of(x: np.ndarray | float, phi: float = phi, a: float = a) -> np.ndarray:
            return G * np.cos(phi + omega * x) + a * (np.cos(x) + t2 * np.sin(x))

        q = q_of(s)
        i = int(np.argmax(q))
        top = minimize_scalar(lambda x: -float(q_of(x)), bounds=(
            s[max(i - 1, 0)], s[min(i + 1, samples - 1)]), method="bounded",
            options={"xatol": 1e-12 * T})
        span = float(max(q.max(), -top.fun) - q.min())
        if q.min() < gap - ADMISSIBLE_TOL * max(span, 1.0):
            continue
        k = (1.0 + r) * (np.cos(phi) - gap) / v_minus
        out.append({"phase": float(np.mod(phi, 2 * np.pi)), "v_minus": float(v_minus),
                    "pd": float(1.0 + r * r - 2.0 * r * np.cos(T) + k * np.sin(T)),
                    "amplitude": 0.5 * span})
    return out


def impacting_amplitudes(omegas: np.ndarray, gap: float, r: float
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Amplitudes of the high-velocity (largest ``|v-|``) and low-velocity one-impact orbits
    on ``omegas`` (NaN where there is none)."""
    high = np.full(len(omegas), np.nan)
    low = np.full(len(omegas), np.nan)
    for i, w in enumerate(omegas):
        found = sorted(one_impact_orbits(float(w), gap, r), key=lambda o: o["v_minus"])
        if found:
            high[i] = found[0]["amplitude"]
        if len(found) > 1:
            low[i] = found[-1]["amplitude"]
    return high, low


#: samples of the period when only the admissibility of an orbit is checked
CHECK_SAMPLES = 64


def _pd(omega: float, gap: float, r: float) -> float:
    """(O2) on the high-velocity orbit (NaN where there is none)."""
    found = one_impact_orbits(omega, gap, r, CHECK_SAMPLES)
    return min(found, key=lambda o: o["v_minus"])["pd"] if found else float("nan")


def period_doubling_omegas(gap: float, r: float, lo: float = 1.0 + 1e-6, hi: float = 1.6,
                           n: int = 160) -> list[float]:
    """The forcing frequencies in ``(lo, hi)`` where the high-velocity orbit at ``gap`` has
    a multiplier -1 (roots of (O2), bracketed on ``n`` samples, closed by Brent's method)."""
    w = np.linspace(lo, hi, n)
    f = np.array([_pd(float(x), gap, r) for x in w])
    roots = []
    for i in range(n - 1):
        if np.isfinite(f[i]) and np.isfinite(f[i + 1]) and f[i] * f[i + 1] < 0:
            roots.append(float(brentq(_pd, w[i], w[i + 1], args=(gap, r), xtol=1e-13)))
    return roots


def _tip(gap_with: float, gap_without: float, r: float, steps: int = 30) -> float:
    """The gap where the two period doublings meet (the U's tip), between ``gap_with`` (two
    roots of O2) and ``gap_without`` (none), by bisection."""
    for _ in range(steps):
        mid = 0.5 * (gap_with + gap_without)
        if len(period_doubling_omegas(mid, r)) >= 2:
            gap_with = mid
        else:
            gap_without = mid
    return gap_with


def curve_in_plane(kind: str, gaps: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """The ``kind`` curve (``grazing``: G1, ``period_doubling``: O2) in ``(gap, omega)`` over
    ``gaps`` (increasing). Period doubling: one line, the upper doubling towards the U's tip
    (located by bisection where the two meet) and the lower one back; grazing: the branches
    ``omega^2 = 1 +- 1/|gap|`` separated by NaN."""
    gaps = np.asarray(gaps, dtype=float)
    if kind == "grazing":
        up = np.array([grazing_omegas(float(g))[-1] if g < 0 else np.nan for g in gaps])
        low = np.array([grazing_omegas(float(g))[0] if g < -1 else np.nan for g in gaps])
        return np.concatenate([gaps, [np.nan], gaps]), np.concatenate([up, [np.nan], low])
    roots = [period_doubling_omegas(float(g), r) for g in gaps]
    two = np.array([len(x) >= 2 for x in roots])
    if not two.any():
        return np.array([]), np.array([])
    g_in = [float(g) for g in gaps[two]]
    up = [max(x) for x in roots if len(x) >= 2]
    low = [min(x) for x in roots if len(x) >= 2]
    first = int(np.argmax(two))
    if first > 0:  # the tip lies between the last gap without and the first with two roots
        tip = _tip(float(gaps[first]), float(gaps[first - 1]), r)
        w = period_doubling_omegas(tip, r)
        g_in.insert(0, tip)
        up.insert(0, max(w))
        low.insert(0, min(w))
    g_arr = np.array(g_in)
    return (np.concatenate([g_arr[::-1], g_arr]),
            np.concatenate([np.array(up)[::-1], np.array(low)]))


#: samples of the forcing frequency (frequency-response curve) or of the gap (curves)
CURVE_SAMPLES = 500
PLANE_SAMPLES = 60


class ImpactOscillatorPresentation(HybridCasePresentation):
    """The impact oscillator's figures with its closed forms where it has them (undamped,
    ``zeta = 0``): over a frequency-response curve in the forcing frequency, the one-impact
    orbits (O1) and the free orbit where it misses the stop; over a two-parameter curve in
    ``(gap, omega)``, the grazing curve (G1) or the period-doubling curve (O2)."""

    def closed_forms(self, x_range: tuple[float, float], branches: list[Any]
                     ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        pr = self.problem
        v = pr.values
        if v["zeta"] != 0.0 or pr.parameter != "omega" or pr.response_key != "amplitude_q":
            return []
        w = np.linspace(max(x_range[0], 1e-6), x_range[1], CURVE_SAMPLES)
        w = w[w != 1.0]
        high, low = impacting_amplitudes(w, v["gap"], v["restitution"])
        out = []
        if np.isfinite(high).any():
            out.append((np.concatenate([w, w[::-1]]), np.concatenate([high, low[::-1]]),
                        "one-impact orbits, closed form (O1)"))
        free = free_amplitude(w)
        free[free > -v["gap"]] = np.nan  # it reaches the stop: not an orbit of the system
        if np.isfinite(free).any():
            out.append((w, free, r"free orbit $1/|1-\omega^2|$, closed form"))
        return out

    def curve_closed_forms(self, kind: str, parameter: str, free: str,
                           x_range: tuple[float, float]
                           ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """The grazing (G1) or period-doubling (O2) curve of the undamped oscillator in
        ``(gap, omega)``, in the order of the axes ``(parameter, free)``."""
        v = self.problem.values
        if v["zeta"] != 0.0 or {parameter, free} != {"gap", "omega"} or kind not in (
                "grazing", "period_doubling"):
            return []
        lo, hi = (x_range if parameter == "gap" else (-1.5, -0.05))
        g, w = curve_in_plane(kind, np.linspace(lo, hi, PLANE_SAMPLES), v["restitution"])
        if not np.isfinite(w).any():
            return []
        name = "grazing curve (G1)" if kind == "grazing" else "period-doubling curve (O2)"
        return [(g, w, f"{name}, closed form") if parameter == "gap"
                else (w, g, f"{name}, closed form")]


__all__ = ["ImpactOscillatorPresentation", "curve_in_plane", "free_amplitude", "grazing_omegas",
           "impacting_amplitudes", "one_impact_orbits", "period_doubling_omegas"]
