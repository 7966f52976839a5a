"""Continuum limit of the WFEM nonsmooth modes of the bar (Yoong, Thorin, Legrand 2017, sec. 5-6).

The elastic bar (E, rho, L; S = 1) is clamped at x = 0 and meets a rigid obstacle at x = L across
the signed gap ``g0`` (eq. 1-3). Its WFEM orbits (12) are exact samples of continuum orbits; this
module describes those continuum orbits in closed form (:mod:`problems.bar.continuum` continues
them with the generic pseudo-arclength engine).

Characteristic ring (the limit of :mod:`problems.bar.wfem_operators`). Time is measured in units of
``L/c``. The characteristics ``b = sigma - Z v`` (at ring coordinate ``xi = x/L``) and
``a = sigma + Z v`` (at ``xi = 2 - x/L``) form a ring ``xi in [0, 2)`` whose content moves
``xi -> xi + t``. The contact end is ``xi = 1``: content crossing it changes sign while the end is
free (``a = -b``: zero stress) and keeps it in contact (``a = +b``: zero velocity); the clamped end
``xi = 0`` keeps the sign. A periodic orbit of period ``T`` with one free phase ``[0, t_f)`` and
one contact phase ``[t_f, T)`` (eq. 11-12 with ``m dt -> t_f``, ``p dt -> T - t_f``) is a profile
``f`` with ``f(xi + T) = s(xi) f(xi)``, ``s(xi) = (-1)^(number of free-phase crossings of xi = 1)``.

Branches. For ``T/2`` irrational the rotation by ``T`` is ergodic, so ``|f|`` is constant:
``f = A p`` with ``p = +-1`` piecewise constant (the paper's "contact force piecewise constant",
sec. 6.1), jumping on a finite set ``D``. ``s`` jumps on ``S = {1, 1 - t_f}`` (the characteristics
that reach the end at the two switches) and periodicity requires ``S = D (+) (D - T)`` (symmetric
difference). That is possible iff ``t_f = a T + b`` with integers ``a`` (the number of jumps
of ``p``, even) and ``b`` (a multiple of 4, else the profile closes with the wrong sign), constant
along a branch: the branch is a *straight line* in ``(T, t_f)``, with ``D = {1 - j T : j = 0..a-1}``
(mod 2; ``{1 + j T : j = 1..|a|}`` for ``a < 0``). Signatures checked against the lattice
(:func:`problems.bar.wfem_lattice.solve_node`, N = 40, tests/bar/test_bar_continuum.py):

* main backbone of mode k (sec. 6.1, from omega_k for g0 > 0, from Omega_k for g0 < 0):
  ``(a, b) = (2k, -4)``, i.e. ``m = 2k M - 4N`` on the lattice; mode 1: ``t_f = 2T - 4``, mode 2:
  ``t_f = 4T - 4`` (at ``g0 = 0``: ``T = 5/4``, contact ``1/4``, free ``1``, as in sec. 6.1);
* n-th subharmonic of mode k (sec. 6.2, from eq. 15's ``(2k(n+1) - 1)/(n+1) omega_1``):
  ``(a, b) = (2k(n+1), -4(n+1))``.

Energy (closed form). With ``mu = int_0^2 p dxi`` (``p`` normalised to +1 on the arc that reaches
the contact end first, ``xi -> 1^-``) the gap normalisation ``u_end(0) = (1/E) int_0^L sigma dx =
L A mu / (2E) = g0`` gives ``A = 2 E g0 / (L mu)`` and the energy ``E_tot = S L A^2 / (2E) =
2 S E g0^2 / (L mu^2)``, i.e. ``E_tot / E_ref = 32 / (pi^2 mu^2)`` with ``E_ref`` of eq. (14).
``mu`` is affine in ``T`` along a branch, ``mu = -(2a^2/b) T - 2(a + 1)``, so ``E^(-1/2)`` is
linear in ``T`` and the energy has a double pole at ``T* = -b (a + 1) / a^2``:
``omega*/omega_1 = -4 a^2 / (b (a + 1))``; for the main backbones ``4k^2/(2k+1) =
(w_k + 1)^2/(w_k + 2)`` (sec. 6.1, ``w_k = omega_k/omega_1``: 4/3, 16/5, 36/7) and for the
subharmonics eq. (16). ``g0 = 0`` needs ``mu = 0``: the vertical branch at ``T*``.

Admissibility. ``g0 - u_end(t) = (L/E) int_0^t J`` in the free phase, with ``J`` the characteristic
arriving at the end (piecewise constant, so ``u_end`` is piecewise linear and COND1 is checked
exactly at its breakpoints); in contact the end stress is ``J`` (COND2: ``J <= 0``). On the
backbones ``J/A`` alternates ``+1, -1, ...`` in the free phase (touching ``u_end = g0`` at n grazing
instants on the n-th subharmonic, sec. 6.2) and is ``-1`` in contact, so with ``A = 2 E g0/(L mu)``
an orbit is admissible iff ``sign(g0) = sign(mu)`` (and COND3, ``|A| <= E``): ``T > T*``
(hardening from omega_k) for ``g0 > 0``, ``T < T*`` (softening from Omega_k) for ``g0 < 0``.

Other signatures. Any ``(a, b)`` with ``a`` even and ``b`` a multiple of 4 gives periodic profiles
(``a < 0`` included); off the backbone family ``mu`` is only piecewise affine and admissibility
must be checked (:meth:`problems.bar.continuum.BarContinuumProblem.admissibility`, exact; it
agrees with the lattice's COND1-COND3 on every node tested). Examples for ``g0 > 0``:
``t_f = 8T - 24``, admissible for ``omega/omega_1`` in (7/6, 6/5), two grazing instants, crosses
the main backbone (same orbit) at ``T = 10/3``, i.e. 6/5 omega_1: an internal-resonance branch of
eq. (17) (k = 3, cf. Fig. 16-17); ``t_f = 6T - 16`` on (5/4, 4/3), up to the main asymptote.
``t_f = 4 - 2T`` (between Omega_1 and omega_2) is never admissible (sec. 6.2: no branch in
``[Omega_k, omega_(k+1)]``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np

#: coincidence tolerance on the ring (jump points closer than this cancel) and grazing tolerance
RING_TOL = 1e-10


# -- signatures ------------------------------------------------------------------------------------
class Signature(NamedTuple):
    """A branch ``t_f = a T + b`` (times in units of L/c); on the lattice ``m = a M + b N``."""

    a: int
    b: int

    @property
    def T_free_end(self) -> float:
        """Period where the free phase vanishes (``t_f = 0``): ``-b/a`` (Omega_k for a backbone)."""
        return -self.b / self.a

    @property
    def T_contact_end(self) -> float:
        """Period where the contact phase vanishes (``t_f = T``): ``-b/(a - 1)`` (omega_k, eq. 15
        for a backbone)."""
        return -self.b / (self.a - 1)

    @property
    def T_range(self) -> tuple[float, float]:
        """Periods with ``0 <= t_f <= T``."""
        lo, hi = sorted((self.T_free_end, self.T_contact_end))
        return lo, hi

    @property
    def is_backbone(self) -> bool:
        """Main (n = 0) or subharmonic backbone: ``(a, b) = (2k(n+1), -4(n+1))``, k, n + 1 >= 1."""
        a, b = self
        return a > 0 and b < 0 and b % 4 == 0 and (2 * a) % b == 0

    @property
    def mode(self) -> int:
        """k of a backbone: ``-2a/b``."""
        self._need_backbone()
        return -2 * self.a // self.b

    @property
    def subharmonic(self) -> int:
        """n of a backbone (0: main backbone): ``-b/4 - 1``."""
        self._need_backbone()
        return -self.b // 4 - 1

    @property
    def T_asymptote(self) -> float:
        """Root of ``mu(T) = -(2a^2/b) T - 2(a + 1)`` (backbones): the energy asymptote."""
        self._need_backbone()
        return -self.b * (self.a + 1) / self.a**2

    @property
    def omega_ratio_asymptote(self) -> float:
        """``omega*/omega_1 = 4/T* = -4a^2/(b (a+1))``: ``4k^2/(2k+1)`` for the main backbones
        (sec. 6.1), eq. (16) for the subharmonics."""
        return 4.0 / self.T_asymptote

    def mu(self, T: float | np.ndarray) -> float | np.ndarray:
        """Closed form of the normalised profile mean along a backbone (affine in T). Other
        signatures have a piecewise-affine ``mu``: use :attr:`ContinuumOrbit.mu`."""
        self._need_backbone()
        return -2.0 * self.a**2 / self.b * T - 2.0 * (self.a + 1)

    def t_free(self, T: float) -> float:
        return self.a * T + self.b

    def label(self) -> str:
        return f"t_f = {self.a} T {'+' if self.b >= 0 else '-'} {abs(self.b)}"

    def _need_backbone(self) -> None:
        if not self.is_backbone:
            raise ValueError(f"signature {tuple(self)} is not a main/subharmonic backbone "
                             "(2k(n+1), -4(n+1)): no closed form")


def main_signature(mode: int) -> Signature:
    """Main backbone of mode k (sec. 6.1): ``t_f = 2k T - 4``."""
    return Signature(2 * mode, -4)


def subharmonic_signature(mode: int, n: int) -> Signature:
    """n-th subharmonic backbone of mode k (sec. 6.2, eq. 15-16): ``t_f = 2k(n+1) (T - 2/k)``."""
    return Signature(2 * mode * (n + 1), -4 * (n + 1))


def check_signature(sig: Signature) -> None:
    """Raise ``ValueError`` unless ``sig`` carries continuum orbits (module docstring)."""
    a, b = sig
    if a == 0 or a % 2:
        raise ValueError(f"signature {tuple(sig)}: a must be a nonzero even integer (the "
                         "number of jumps of the characteristic profile)")
    if b % 4:
        raise ValueError(f"signature {tuple(sig)}: b must be a multiple of 4 (otherwise the "
                         "profile closes with the wrong sign after one period)")
    lo, hi = sig.T_range
    if not 0 < lo < hi:
        raise ValueError(f"signature {tuple(sig)}: no period with 0 < t_f < T")


# -- the continuum orbit ---------------------------------------------------------------------------
def jump_set(sig: Signature, T: float) -> np.ndarray:
    """Sorted jump points ``D`` of the profile in ``[0, 2)``; coincident pairs cancel."""
    a = sig.a
    j = np.arange(a) if a > 0 else np.arange(1, -a + 1)
    pts = np.sort(np.mod(1.0 - j * T if a > 0 else 1.0 + j * T, 2.0))
    pts[pts > 2.0 - RING_TOL] = 0.0
    pts = np.sort(pts)
    keep: list[float] = []
    for x in pts:  # symmetric difference of a multiset: equal points cancel in pairs
        if keep and abs(x - keep[-1]) <= RING_TOL:
            keep.pop()
        else:
            keep.append(float(x))
    if len(keep) >= 2 and keep[0] + 2.0 - keep[-1] <= RING_TOL:  # across xi = 0
        keep = keep[1:-1]
    return np.array(keep)


@dataclass(frozen=True)
class ContinuumOrbit:
    """The normalised continuum orbit of a branch at period ``T`` (units L/c).

    ``p(xi)`` is the characteristic profile at ``t = 0`` (start of the free phase) normalised to
    ``+1`` on the arc reaching the contact end first; the physical profile is ``A p`` with the
    stress amplitude ``A = 2 E g0 / (L mu)``.
    """

    sig: Signature
    T: float
    jumps: np.ndarray

    @property
    def t_free(self) -> float:
        """Free-phase duration, clipped to ``[0, T]`` (outside, the branch has ended)."""
        return min(max(self.sig.t_free(self.T), 0.0), self.T)

    @cached_property
    def arcs(self) -> tuple[np.ndarray, np.ndarray]:
        """Arc boundaries ``0 = x_0 < ... < x_K = 2`` and the value of ``p`` on each arc."""
        x = np.concatenate([[0.0], self.jumps, [2.0]])
        parity = np.arange(len(x) - 1) % 2
        vals = np.where(parity == 0, 1.0, -1.0)
        # normalise: p = +1 just left of xi = 1 (the content reaching the end at t = 0+)
        i_ref = int(np.searchsorted(x, 1.0, side="left")) - 1
        return x, vals * vals[max(i_ref, 0)]

    def profile(self, xi: np.ndarray) -> np.ndarray:
        """``p(xi)``, evaluated at ``xi`` mod 2 (points off the jump set)."""
        x, vals = self.arcs
        i = np.searchsorted(x, np.mod(np.asarray(xi, dtype=float), 2.0), side="right") - 1
        return vals[np.clip(i, 0, len(vals) - 1)]

    @cached_property
    def mu(self) -> float:
        """``int_0^2 p dxi`` (exact sum over arcs)."""
        x, vals = self.arcs
        return float(np.sum(np.diff(x) * vals))

    @cached_property
    def end_series(self) -> tuple[np.ndarray, np.ndarray]:
        """Breakpoints ``0 = t_0 < ... < t_K = T`` and ``J/A`` on each segment.

        ``J(t) = A p(1 - t) prod_{j >= 1, t - 2j >= 0} s_phase(t - 2j)``: the content reaching the
        end at ``t`` started at ``xi = 1 - t`` and crossed the contact end at ``t - 2, t - 4, ...``
        with sign -1 in the free phase (the continuum form of
        :func:`problems.bar.wfem_operators.end_series`).
        """
        T, tf = self.T, self.t_free
        laps = int(np.floor(T / 2.0)) + 1
        bps = [0.0, tf, T]
        for d in self.jumps:
            bps += [t for t in (np.mod(1.0 - d, 2.0) + 2.0 * np.arange(laps + 1)) if t < T]
        bps += [t for t in 2.0 * np.arange(1, laps + 1) if t < T]
        bps += [t for t in tf + 2.0 * np.arange(1, laps + 1) if t < T]
        b = np.unique(np.array(bps))
        b = b[np.concatenate([[True], np.diff(b) > RING_TOL])]
        b[-1] = T
        mid = 0.5 * (b[:-1] + b[1:])
        J = self.profile(1.0 - mid)
        for j in range(1, laps + 1):
            prev = mid - 2.0 * j
            J = J * np.where((prev >= 0.0) & (prev < tf), -1.0, 1.0)
        return b, J

    @cached_property
    def free_partial_sums(self) -> tuple[np.ndarray, np.ndarray]:
        """Interior breakpoints ``t`` of the free phase and ``P(t) = int_0^t J/A`` there.

        ``g0 - u_end(t) = (L/E) A P(t)``: ``u_end`` is piecewise linear, so COND1 holds on the
        whole free phase iff ``A P >= 0`` at these breakpoints.
        """
        b, J = self.end_series
        P = np.concatenate([[0.0], np.cumsum(J * np.diff(b))])
        inner = (b > RING_TOL) & (b < self.t_free - RING_TOL)
        return b[inner], P[inner]

    @property
    def closure(self) -> float:
        """``int_0^{t_f} J/A`` (zero: the end is back on the obstacle at ``t_f``)."""
        b, J = self.end_series
        P = np.concatenate([[0.0], np.cumsum(J * np.diff(b))])
        return float(np.interp(self.t_free, b, P))

    def contact_values(self) -> np.ndarray:
        """``J/A`` on the segments of the contact phase."""
        b, J = self.end_series
        return J[b[:-1] >= self.t_free - RING_TOL]

    def periodicity_defect(self, n: int = 4001) -> float:
        """Fraction of sample points where ``p(xi + T) != s(xi) p(xi)`` (0 for an orbit)."""
        xi = (np.arange(n) + 0.5) * (2.0 / n) + 1e-7
        r = np.mod(1.0 - xi, 2.0)
        crossings = np.where(r < self.t_free, np.ceil((self.t_free - r) / 2.0), 0.0)
        s = np.where(crossings % 2 == 0, 1.0, -1.0)
        return float(np.mean(self.profile(xi + self.T) != s * self.profile(xi)))


def continuum_orbit(sig: Signature, T: float) -> ContinuumOrbit:
    """The orbit of branch ``sig`` at period ``T`` (units L/c)."""
    return ContinuumOrbit(Signature(int(sig[0]), int(sig[1])), float(T), jump_set(sig, T))


# -- the backbone frequencies (sec. 6.1, eq. 15, 16) ----------------------------------------------
def main_asymptote(k: int) -> float:
    """omega / omega_1 of the g0 = 0 main backbone of mode k (section 6.1): (w_k+1)^2/(w_k+2)."""
    wk = 2 * k - 1
    return (wk + 1) ** 2 / (wk + 2)


def subharmonic_start(k: int, n: int) -> float:
    """omega / omega_1 where the n-th subharmonic of mode k starts for g0 > 0, eq. (15)."""
    return (2 * k * (n + 1) - 1) / (n + 1)


def subharmonic_asymptote(k: int, n: int) -> float:
    """omega / omega_1 of the subharmonic asymptote, eq. (16)."""
    wk = 2 * k - 1
    return (n + 1) * (wk + 1) ** 2 / (wk * (n + 1) + n + 2)


def main_backbone(mode: int, gap_sign: float, n: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """``(omega / omega_1, E / E_ref)`` of the main backbone of mode k (the exact continuum
    limit): ``E / E_ref = 32 / (pi^2 mu(T)^2)`` with ``mu`` affine in the period
    ``T = 4 / omega_ratio`` (units L/c), admissible where
    ``sign(mu) = sign(g0)`` (hardening from omega_k for g0 > 0, softening from Omega_k for
    g0 < 0). For ``g0 = 0`` the vertical line at the asymptote (energy free): ``x`` twice the
    asymptote and ``y = (nan, nan)``, to be drawn as a vertical line."""
    sig = main_signature(mode)
    if gap_sign == 0:
        x = sig.omega_ratio_asymptote
        return np.array([x, x]), np.full(2, np.nan)
    lo, hi = sig.T_range
    T = np.linspace(lo, hi, n)
    mu = np.asarray(sig.mu(T), dtype=float)
    ok = np.sign(mu) == np.sign(gap_sign)
    with np.errstate(divide="ignore"):
        energy = 32.0 / (math.pi**2 * mu[ok] ** 2)
    return 4.0 / T[ok], energy


__all__ = ["RING_TOL", "ContinuumOrbit", "Signature", "check_signature", "continuum_orbit",
           "jump_set", "main_asymptote", "main_backbone", "main_signature",
           "subharmonic_asymptote", "subharmonic_signature", "subharmonic_start"]
