"""WFEM operators of the elastic bar as signed permutations (Yoong et al. 2017, App. A-B).

The cell update (A.18) with the time step ``dt = dx / c`` transports the two characteristic
variables of the wave equation (A.2) exactly one cell per step::

    a_i = sigma_i + Z v_i   (left-going),   a_i^(n+1) = a_(i+1)^(n)
    b_i = sigma_i - Z v_i   (right-going),  b_i^(n+1) = b_(i-1)^(n),     Z = rho c.

The ghost cells turn the two ends into reflections: at the fixed end x = 0, (A.19) gives
``b_1' = +a_1``; at the free end x = L, (A.19)/(B.4) give ``a_N' = -b_N``; in contact, (B.3) gives
``a_N' = +b_N``. Laid out on a *ring* of ``2N`` slots::

    slot k = i - 1      holds b_i   (i = 1..N, slots 0..N-1, moving towards x = L)
    slot k = 2N - i     holds a_i   (i = N..1, slots N..2N-1, moving towards x = 0)

one WFEM step rotates the ring by one slot, with sign ``s`` on the crossing ``N-1 -> N`` (the
contact end: -1 free, +1 contact) and sign ``s0`` on ``2N-1 -> 0`` (the clamped end, +1; -1 for
a free end, used by the falling-bar benchmark). ``A_f``, ``A_c`` and any product of them are
therefore *signed permutations* of the ring: this module represents them by an index map and a
sign vector, applies them in O(N), and finds ``ker(A_c^p A_f^m - I)`` from the cycles of the
permutation (one kernel vector per cycle whose sign product is +1), with no dense algebra.

The dense matrices of (A.22)-(A.27) are built only as a test oracle. Two printed formulas of
Appendix A are not consistent with (A.18)-(A.19):

* (A.21)/(A.25), the free-end cell ``C_N``: the stress row must read
  ``sigma_N' = (sigma_(N-1) - sigma_N + rho c (v_N - v_(N-1))) / 2`` (the printed ``+ v_(N-1)``
  has the wrong sign; substituting the ghost values (A.19) into (A.18) gives ``-``).
* (A.26)-(A.27): with the printed corner entries ``A_1 = A_g(-1,1,1,1)``, ``A_2 = rho c
  A_g(-1,1,-1,-1)``, ``A_4 = A_g(1,1,1,-1)`` the matrix describes a bar *free at x = 0 and fixed
  at x = L*, the mirror image of the text (Fig. 1 and (A.20)-(A.21)), and so does the printed
  ``A_3 = A_g(1,1,-1,1)/(rho c)``. The corner entries consistent with (A.18)-(A.21) are
  ``A_g(1,1,1,-1)``, ``rho c A_g(1,1,-1,1)``, ``A_g(-1,1,-1,-1)/(rho c)``, ``A_g(-1,1,1,1)``.

Both are checked in ``tests/bar/test_wfem_operators.py`` (energy conservation, which end is fixed,
agreement of the structured and dense operators).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import gcd

import numpy as np

FREE = -1
CONTACT = 1


#: the energies double precision resolves, with room for their squares and ratios
ENERGY_RANGE = (1e-200, 1e200)


def check_reference_energy(E: float, L: float, g0: float) -> None:
    """A bar with ``g0 != 0`` whose reference energy ``pi^2 E g0^2 / (16 L)`` (eq. 14), the scale
    of all its energies, lies outside :data:`ENERGY_RANGE` is refused, naming the gap range
    that holds for these ``E`` and ``L`` (the orbits scale with the gap, the energies with its
    square: the gap is what a user rescales)."""
    if g0 == 0:
        return
    e_ref = np.pi**2 * E * g0**2 / (16 * L)
    lo, hi = ENERGY_RANGE
    if lo <= e_ref <= hi:
        return
    g_lo, g_hi = (float(np.sqrt(e * 16 * L / (np.pi**2 * E))) for e in (lo, hi))
    raise ValueError(
        f"parameters.gap: |gap| = {abs(g0):.3g} is outside [{g_lo:.3g}, {g_hi:.3g}], the gaps "
        f"whose energies (E_ref = pi^2 E g0^2 / (16 L) = {e_ref:.3g}, eq. 14) double precision "
        f"resolves with E = {E:g}, L = {L:g}: the orbits scale with the gap and the energies "
        "with its square, so solve with a gap in that range (other units) and scale the results")


class BarConstants:
    """Wave speed, impedance, mesh size and omega_1 of a bar with fields E, rho, L, N."""

    E: float
    rho: float
    L: float
    N: int

    @property
    def c(self) -> float:
        return float(np.sqrt(self.E / self.rho))

    @property
    def Z(self) -> float:
        """Impedance rho c."""
        return self.rho * self.c

    @property
    def dx(self) -> float:
        return self.L / self.N

    @property
    def omega1(self) -> float:
        """First fixed-free linear frequency (13): pi c / (2L)."""
        return float(np.pi * self.c / (2 * self.L))


# -- state conversions ---------------------------------------------------------------------------
def to_ring(sigma: np.ndarray, v: np.ndarray, Z: float) -> np.ndarray:
    """Cell averages ``(sigma_i, v_i)`` -> ring vector ``w`` of length 2N (module docstring)."""
    a = sigma + Z * v
    b = sigma - Z * v
    return np.concatenate([b, a[::-1]])


def from_ring(w: np.ndarray, Z: float) -> tuple[np.ndarray, np.ndarray]:
    """Ring vector -> ``(sigma, v)`` cell averages."""
    N = len(w) // 2
    b = w[:N]
    a = w[N:][::-1]
    return 0.5 * (a + b), 0.5 * (a - b) / Z


def ring_energy(w: np.ndarray, dx: float, E: float, S: float = 1.0) -> float:
    """Total energy ``sum S dx (sigma^2/(2E) + rho v^2/2) = S dx sum (a^2 + b^2) / (4E)``."""
    return float(S * dx * np.dot(w, w) / (4.0 * E))


# -- phase patterns ------------------------------------------------------------------------------
Pattern = tuple[tuple[int, int], ...]
"""A phase pattern: ((steps, sign), ...) applied in order, sign FREE (-1) or CONTACT (+1)."""


def pattern_from_counts(*counts: int) -> Pattern:
    """``(m, p)`` -> ((m, FREE), (p, CONTACT)); ``(m, p, k, l)`` -> free m, contact p, free k, ...

    Phases alternate free/contact starting with free, as in (11) and (18).
    """
    return tuple((int(c), FREE if j % 2 == 0 else CONTACT) for j, c in enumerate(counts))


def _count_congruent(n0: int, n1: int, r: np.ndarray, period: int) -> np.ndarray:
    """Number of integers n in [n0, n1) with n = r (mod period), vectorised over r."""
    def upto(n: int) -> np.ndarray:  # count in [0, n)
        if n <= 0:
            return np.zeros_like(r)
        return np.where(r < n, (n - 1 - r) // period + 1, 0)
    return upto(n1) - upto(n0)


@dataclass(frozen=True)
class SignedRotation:
    """The operator ``w -> P w`` with ``(P w)[(k + shift) mod 2N] = sign[k] * w[k]``.

    Every product of WFEM steps is of this form (module docstring).
    """

    N: int
    shift: int
    sign: np.ndarray  # shape (2N,), entries +-1

    @property
    def size(self) -> int:
        return 2 * self.N

    def apply(self, w: np.ndarray) -> np.ndarray:
        return np.roll(self.sign * w, self.shift)

    def dense(self) -> np.ndarray:
        """Dense ``2N x 2N`` ring matrix (tests only)."""
        n = self.size
        P = np.zeros((n, n))
        k = np.arange(n)
        P[(k + self.shift) % n, k] = self.sign
        return P

    def cycles(self) -> np.ndarray:
        """Ring slots grouped by cycle: array of shape (g, 2N/g), g = gcd(shift, 2N).

        Row j lists ``j, j + shift, j + 2 shift, ...`` (mod 2N).
        """
        n = self.size
        g = gcd(self.shift % n, n) if self.shift % n else n
        length = n // g
        return (np.arange(g)[:, None] + self.shift * np.arange(length)[None, :]) % n

    def kernel(self) -> np.ndarray:
        """Orthonormal basis of ``ker(P - I)`` as columns (2N x h), from the cycles: O(N).

        On a cycle ``k_0 -> k_1 -> ...`` a fixed vector satisfies ``w[k_(t+1)] = sign[k_t] w[k_t]``:
        it exists (one dimension) iff the product of the signs around the cycle is +1.
        """
        cyc = self.cycles()
        s = self.sign[cyc]
        closing = np.prod(s, axis=1)
        good = np.nonzero(closing > 0)[0]
        n = self.size
        basis = np.zeros((n, len(good)))
        if len(good):
            vals = np.ones((len(good), cyc.shape[1]))
            vals[:, 1:] = np.cumprod(s[good, :-1], axis=1)
            vals /= np.sqrt(cyc.shape[1])
            basis[cyc[good].ravel(), np.repeat(np.arange(len(good)), cyc.shape[1])] = vals.ravel()
        return basis

    def kernel_dimension(self) -> int:
        cyc = self.cycles()
        return int(np.sum(np.prod(self.sign[cyc], axis=1) > 0))


def phase_operator(N: int, pattern: Pattern, left_sign: int = 1) -> SignedRotation:
    """The signed rotation of a phase pattern: e.g. ``A_c^p A_f^m`` for ((m, FREE), (p, CONTACT)).

    The content of slot k crosses the contact end (slot N-1 -> N) at the steps n = N-1-k (mod 2N)
    and the clamped end (slot 2N-1 -> 0) at n = 2N-1-k (mod 2N); the sign is the product of the
    phase signs at those steps. O(N) per phase.
    """
    n = 2 * N
    k = np.arange(n)
    r_end = (N - 1 - k) % n
    r_root = (n - 1 - k) % n
    parity = np.zeros(n, dtype=np.int64)
    t0 = 0
    for steps, s in pattern:
        if steps < 0:
            raise ValueError("phase lengths must be >= 0")
        if s < 0:
            parity += _count_congruent(t0, t0 + steps, r_end, n)
        t0 += steps
    if left_sign < 0:
        parity += _count_congruent(0, t0, r_root, n)
    sign = np.where(parity % 2 == 0, 1.0, -1.0)
    return SignedRotation(N, t0 % n, sign)


def end_series(w0: np.ndarray, pattern: Pattern, left_sign: int = 1) -> np.ndarray:
    """``J[n]``: the right-going characteristic ``b_N`` arriving at the contact end at step n.

    ``J[n] = w^(n)[N-1]``. Over step n the end interface carries stress ``J[n]`` in contact (and
    velocity 0), velocity ``-J[n]/Z`` when free (and stress 0): (A.12) with the ghosts (B.3)-(B.4).
    The content at slot N-1 at step n was there one lap (2N steps) earlier, having crossed both
    ends once, so ``J[n] = s0 * s_(n-2N) * J[n-2N]``: O(steps) in total, no state history.
    """
    n_ring = len(w0)
    N = n_ring // 2
    signs = np.concatenate([np.full(steps, float(s)) for steps, s in pattern]) if pattern else \
        np.zeros(0)
    M = len(signs)
    J = np.empty(M)
    first = min(M, n_ring)
    idx = (N - 1 - np.arange(first)) % n_ring
    J[:first] = w0[idx]
    for start in range(n_ring, M, n_ring):
        stop = min(M, start + n_ring)
        back = slice(start - n_ring, stop - n_ring)
        J[start:stop] = left_sign * signs[back] * J[back]
    return J


def floating_bc_contact(in_contact: bool, gap: float, gap_free_next: float,
                        wall_stress: float, nearest: bool, gap_tol: float = 0.0,
                        stress_tol: float = 0.0) -> bool:
    """The switching decision of Algorithm 2 (App. B): is step n a CONTACT step?

    The one rule of every time stepper of the bar (:func:`problems.bar.wfem_stepping.simulate`
    and :func:`problems.bar.wfem_stability.floating_bc_simulation`; :func:`ring_step` and
    :func:`simulate_ring` apply a *given* phase pattern and decide nothing). Contact is a
    *candidate* if the end was in contact over step n - 1, or the gap (B.2)
    ``g_n = g0 + w(t_n) - u_end`` is ``<= gap_tol``, or (``nearest``) the free step would make
    the gap negative with the crossing in the first half of the step
    (``g_(n+1)^free < 0`` and ``g_n < -g_(n+1)^free``: the closure goes to the nearest grid
    time). A candidate is kept if the stress the wall would carry over the step is compressive,
    ``wall_stress <= stress_tol`` (B.5 with the compressive sign: ``lambda = -S sigma >= 0``;
    ``wall_stress`` is the arriving characteristic ``b_N`` plus ``Z w_t`` for a moving wall);
    otherwise the end is released (free step, B.4).
    """
    if in_contact or gap <= gap_tol or (nearest and gap_free_next < 0.0
                                        and gap < -gap_free_next):
        return bool(wall_stress <= stress_tol)
    return False


def simulate_ring(w0: np.ndarray, pattern: Pattern, left_sign: int = 1) -> np.ndarray:
    """All states ``w^(0..M)`` (rows) under the phase pattern; O(N M) memory, for plots/tests.

    The pattern is given (e.g. a lattice orbit's ``((m, FREE), (p, CONTACT))``): no switching
    decision is made here (the decision is :func:`floating_bc_contact`)."""
    N = len(w0) // 2
    signs = [s for steps, s in pattern for _ in range(steps)]
    out = np.empty((len(signs) + 1, len(w0)))
    out[0] = w0
    w = w0.copy()
    for n, s in enumerate(signs):
        w = ring_step(w, s, left_sign, N)
        out[n + 1] = w
    return out


def ring_step(w: np.ndarray, s: int, left_sign: int = 1, N: int | None = None) -> np.ndarray:
    """One WFEM step (A.18) with the end signs (free -1 / contact +1 at x = L)."""
    N = len(w) // 2 if N is None else N
    out = np.roll(w, 1)
    out[N] *= s
    out[0] *= left_sign
    return out


# -- dense oracle (Appendix A.7) -----------------------------------------------------------------
def A_g(N: int, a: float, b: float, c: float, d: float) -> np.ndarray:
    """The tridiagonal pattern (A.26): diagonal zero except corners a, d; b above, c below; /2."""
    A = np.zeros((N, N))
    A[np.arange(N - 1), np.arange(1, N)] = b
    A[np.arange(1, N), np.arange(N - 1)] = c
    A[0, 0] += a
    A[N - 1, N - 1] += d
    return 0.5 * A


def dense_operator(N: int, Z: float, end: str = "free", corners: str = "derived") -> np.ndarray:
    """Dense ``2N x 2N`` matrix on ``Q = [sigma_1..sigma_N, v_1..v_N]`` (A.27).

    ``end`` is "free" (A_f) or "contact" (A_c). ``corners="derived"`` uses the corner entries
    derived from (A.18) with the ghost cells (A.19)/(B.3); ``corners="printed"`` reproduces the
    printed (A.26)-(A.27) (fixed-free only), kept to document the discrepancy in tests.
    """
    if corners == "printed":
        if end != "free":
            raise ValueError("the paper prints only the fixed-free matrix")
        A1, A2 = A_g(N, -1, 1, 1, 1), Z * A_g(N, -1, 1, -1, -1)
        A3, A4 = A_g(N, 1, 1, -1, 1) / Z, A_g(N, 1, 1, 1, -1)
    else:
        s = -1.0 if end == "free" else 1.0  # ghost sigma_(N+1) = s sigma_N, v_(N+1) = -s v_N
        A1 = A_g(N, 1, 1, 1, s)         # sigma_1 <- sigma_0 = sigma_1 (fixed end)
        A2 = Z * A_g(N, 1, 1, -1, -s)   # sigma_1 <- -rho c v_0 = +rho c v_1
        A3 = A_g(N, -1, 1, -1, s) / Z
        A4 = A_g(N, -1, 1, 1, -s)
    return np.block([[A1, A2], [A3, A4]])


def kernel_dimensions_at_period(N: int, M: int) -> np.ndarray:
    """``h(m)`` for every one-contact-phase node ``(m, M - m)``, m = 1..M-1, in closed form.

    All nodes of a period share the rotation ``s = M mod 2N``, hence the cycles: slots
    ``k = j (mod g)``, ``g = gcd(s, 2N)`` (``g = 2N`` when ``s = 0``). Only the signs differ:
    slot k picks up one -1 for each free step ``n < m`` with ``n = r_k = N-1-k (mod 2N)``
    (:func:`phase_operator`). On the cycle of class j the residues ``r_k`` run over the class
    ``N-1-j (mod g)`` exactly once each, and ``g`` divides ``2N``, so the number of -1 on the
    cycle is the number of ``n`` in ``[0, m)`` in one residue class ``c`` modulo ``g``:
    ``q + [c < rho]`` with ``m = q g + rho``. As j runs over the g cycles, c runs over
    ``0..g-1``; a cycle is in the kernel iff its count is even, so

        ``h(m) = g - rho`` if ``q`` is even, ``rho`` if ``q`` is odd.

    O(M) for the whole period (was an O(M N) sweep over the signs; that sweep,
    :func:`kernel_dimensions_by_sweep`, is the oracle of
    ``tests/bar/test_wfem_scan_screen_equals_per_node_solve.py``,
    with :meth:`SignedRotation.kernel_dimension` per node).
    """
    n = 2 * N
    s = M % n
    g = gcd(s, n) if s else n
    q, rho = np.divmod(np.arange(1, M), g)
    return np.where(q % 2 == 0, g - rho, rho)


def kernel_dimensions_by_sweep(N: int, M: int) -> np.ndarray:
    """:func:`kernel_dimensions_at_period` by the O(M N) sweep it replaced (tests and
    ``benchmarks/bench_wfem_scan.py`` only): every slot's sign counted, every cycle's product
    formed."""
    n = 2 * N
    r = (N - 1 - np.arange(n)) % n
    m = np.arange(1, M)[:, None]
    count = np.where(r[None, :] < m, (m - 1 - r[None, :]) // n + 1, 0)
    sign = 1 - 2 * (count % 2)
    cyc = SignedRotation(N, M % n, np.ones(n)).cycles()
    return np.sum(np.prod(sign[:, cyc], axis=2) > 0, axis=1)
