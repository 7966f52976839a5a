"""Internal resonances of the chain's one-impact families: where a multiplier of the linearised
first return map (A.8) is a ``k``-th root of unity ``exp(+-2 pi i m / k)``.

**Why only there.** The one-impact orbits of period ``T`` with the impact at ``t = 0`` are the
solutions of a *linear* system: with ``q, p`` the modal displacement and velocity after the
impact, ``b = P^-1 e_c`` and ``beta = u_c'(0+)``, periodicity (2.28), linear at fixed ``T``,
reads, mode by mode,

    ``[[cos w_j T - 1, sin(w_j T) / w_j], [-w_j sin w_j T, cos w_j T - 1]] (q_j, p_j) =
    (0, -2 beta b_j)``,

a ``2 x 2`` block of determinant ``4 sin^2(w_j T / 2)``. Off the poles ``T = l T_j`` every
block is invertible: ``p = beta b`` (the velocity after the impact is ``beta e_c``), ``q_j =
beta b_j cot(w_j T / 2) / w_j`` and ``u_c(0) = beta w_N(T) = g`` fix ``beta`` (eq. 4.2). So at
each period there is exactly one one-impact orbit: no other one-impact family can branch off a
one-impact family (a ``+1`` multiplier pair there is a fold of the energy along the family, not
a branch point), and the one-impact family meets mode ``j``'s subharmonic ``l T_j`` only at the
pole itself, where the block of mode ``j`` vanishes, ``beta = 0`` and the orbit is the linear
grazing orbit of mode ``j`` (the end of the family, Theorem 3.1). What the family can meet
inside is a *multiplier* resonance: a pair ``exp(+-i theta)`` on the unit circle with
``theta = 2 pi m / k`` (``k >= 3``; ``k = 2`` is a period doubling). There the ``k``-times
iterated map has the double eigenvalue ``1`` besides the family's, and a family of orbits of
period ``k T`` (``k`` impacts per period, one near each impact of the parent) branches off
(the ``k``-fold bifurcation of a Hamiltonian family). Far from the impact the pair is the
flight ``exp(+-i w_j T)`` of mode ``j``, so ``theta = 2 pi m / k`` is the impacting orbit's
version of ``w = k w_j / l`` (``l = k n + m``); the impact couples the modes and moves it.

**The condition.** ``DF`` (2N x 2N, physical coordinates) has the eigenvalue ``0`` (its row
``c`` vanishes: the section), the family's ``1`` and ``N - 1`` reciprocal pairs
``lam_i, 1 / lam_i`` (Prop. 6.1), so with ``z = exp(i theta)``

    ``F_{k,m}(T) = det(z I - DF(T)) / (z^N (z - 1)) = prod_i (2 cos theta - rho_i)``,
    ``rho_i = lam_i + 1 / lam_i``,                                                    (R1)

is real, smooth in ``T`` and vanishes exactly where a pair is ``exp(+-i theta)``: the closed-form
condition of the resonance, solved by the Illinois iteration (no eigenvalue is tracked).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsm_continuation.core.roots import illinois


def resonance_function(problem: Any, T: float, k: int, m: int) -> float:
    """``F_{k,m}(T)`` of (R1) on the closed-form orbit (4.2) of period ``T`` of ``problem``
    (an :class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`); its
    imaginary part, rounding, is dropped."""
    u0, du0 = problem.closed_form(T)
    DF = problem.return_map_jacobian(problem.y_from_state(u0, du0, T))
    n = DF.shape[0] // 2
    z = np.exp(2j * np.pi * m / k)
    val = np.linalg.det(z * np.eye(2 * n) - DF) / (z**n * (z - 1.0))
    return float(val.real)


def resonance_frequencies(problem: Any, k: int, m: int, omega_lo: float, omega_hi: float,
                          grid: int = 400) -> list[float]:
    """The frequencies ``omega = 2 pi / T`` in ``[omega_lo, omega_hi]`` where (R1) vanishes on
    the closed-form family: the sign changes of ``F_{k,m}`` on a grid of ``grid`` points,
    closed by the Illinois iteration to ``1e-15 + 4 eps omega``."""
    if not (k >= 3 and 1 <= m < k and np.gcd(m, k) == 1):
        raise ValueError(f"resonance order k = {k}, rotation m = {m}: need k >= 3, "
                         "1 <= m < k, gcd(m, k) = 1")

    def f(w: float) -> float:
        return resonance_function(problem, 2 * np.pi / w, k, m)

    ws = np.linspace(omega_lo, omega_hi, grid)
    vals = np.array([f(w) for w in ws])
    out = []
    for i in np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)[0]:
        w = illinois(lambda x: (f(x), None), ws[i], vals[i], ws[i + 1], vals[i + 1],
                     tol=1e-15 + 4 * np.finfo(float).eps * ws[i + 1], close=True)[0]
        out.append(float(w))
    return out


def nearest_resonance(problem: Any, k: int, m: int, omega: float, width: float = 0.01
                      ) -> float:
    """The zero of (R1) nearest ``omega`` within ``omega (1 +- width)``; raises
    :class:`ValueError` naming the window where there is none."""
    roots = resonance_frequencies(problem, k, m, omega * (1 - width), omega * (1 + width))
    if not roots:
        raise ValueError(f"no {m}/{k} resonance (a multiplier exp(2 pi i {m}/{k})) on the "
                         f"one-impact family within omega = {omega:g} (1 +- {width:g})")
    return min(roots, key=lambda w: abs(w - omega))
