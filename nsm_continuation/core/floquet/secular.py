"""The secular equation of a low-rank update of a normal map.

A return map that is a known normal map plus a low-rank term, ``A = Q (diag(mu) + X Y^T) Q^H``
(the impacting chain: a rotation by the flight and rank two from the impact and the period
gradient), has the characteristic polynomial
``prod (mu_m - lam) det(I_k + Y^T (diag(mu) - lam)^-1 X)`` (matrix determinant lemma): a
``k x k`` determinant of Cauchy sums, O(n) per ``lam``. This module evaluates it with the pole
nearest to ``lam`` split off (:func:`_secular_terms`, no cancellation next to a pole; the
nearest pole found fast when the poles lie on the unit circle, :class:`_Poles`), its
logarithmic derivative with known roots divided out (:func:`_log_derivative`, what the
Ehrlich-Aberth iterations of :mod:`~nsm_continuation.core.floquet.aberth` and
:mod:`~nsm_continuation.core.floquet.pairs` step on), and recognises a real map written in a
basis closed under conjugation (:func:`_conjugation`), whose spectrum is conjugate-closed.
"""

from __future__ import annotations

import numpy as np

#: rows of the Cauchy matrix ``1/(mu_m - lam_k)`` formed at once (keeps it in cache)
_CHUNK = 64


class _Poles:
    """The poles ``mu`` of a secular equation with what finds the pole nearest to a point
    fast: when every pole lies on the unit circle (to rounding: the spectrum of a rotation),
    the distance ``|mu_m - lam|^2 = 1 + |lam|^2 - 2 |lam| cos(arg mu_m - arg lam)`` grows with
    the angle between them, so the nearest pole is among the neighbours of ``arg lam`` in the
    poles sorted by angle (``np.searchsorted``, O(log n) per point; two on each side are
    compared by distance, which settles ties and the wrap at ``+-pi``). Otherwise the nearest
    pole is the minimum over all of them (O(n) per point)."""

    #: poles within this of the unit circle are "on it" (``exp(i x)`` is within a few ulp)
    ON_CIRCLE = 1e-14

    def __init__(self, mu: np.ndarray) -> None:
        self.mu = mu
        self.on_circle = bool(mu.size >= 4 and np.all(np.abs(np.abs(mu) - 1.0)
                                                       <= self.ON_CIRCLE))
        if self.on_circle:
            phi = np.angle(mu)
            self.order = np.argsort(phi, kind="stable")
            self.phi = phi[self.order]

    def nearest(self, lam: np.ndarray) -> np.ndarray | None:
        """Index of the pole nearest to each ``lam``, or None when the poles are not on the
        unit circle (the caller takes the minimum over all of them)."""
        if not self.on_circle:
            return None
        n = self.mu.size
        j = np.searchsorted(self.phi, np.angle(lam))
        cand = self.order[(j[:, None] + np.arange(-2, 2)[None, :]) % n]
        D = self.mu[cand] - lam[:, None]
        d2 = D.real**2 + D.imag**2
        return cand[np.arange(lam.size), np.argmin(d2, axis=1)]


def _cauchy_chunk(poles: _Poles, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(G, star)``: ``G_km = 1/(mu_m - lam_k)`` with the entry of the pole nearest to each
    ``lam_k`` (index ``star_k``) set to 0."""
    mu = poles.mu
    rows = np.arange(lam.size)
    G = np.subtract(mu[None, :], lam[:, None])
    star = poles.nearest(lam)
    if star is None:
        star = np.argmin(G.real**2 + G.imag**2, axis=1)
    G[rows, star] = 1.0  # no division by zero when lam_k is (numerically) at a pole
    np.reciprocal(G, out=G)
    G[rows, star] = 0.0
    return G, star


def _adj(A: np.ndarray) -> np.ndarray:
    """Adjugates of a batch ``(K, k, k)`` of ``k x k`` matrices, ``k`` = 1, 2 or 3 (explicit
    cofactors: polynomial in the entries, no inverse)."""
    k = A.shape[-1]
    if k == 1:
        return np.ones_like(A)
    if k == 2:
        out = np.empty_like(A)
        out[:, 0, 0], out[:, 1, 1] = A[:, 1, 1], A[:, 0, 0]
        out[:, 0, 1], out[:, 1, 0] = -A[:, 0, 1], -A[:, 1, 0]
        return out
    cof = np.empty_like(A)
    for i in range(3):
        for j in range(3):
            i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
            cof[:, i, j] = A[:, i1, j1] * A[:, i2, j2] - A[:, i1, j2] * A[:, i2, j1]
    return np.swapaxes(cof, 1, 2)


def _dadj(A: np.ndarray, dA: np.ndarray) -> np.ndarray:
    """Derivative of :func:`_adj` along ``dA``."""
    k = A.shape[-1]
    if k == 1:
        return np.zeros_like(A)
    if k == 2:
        return _adj(dA)
    cof = np.empty_like(A)
    for i in range(3):
        for j in range(3):
            i1, i2, j1, j2 = (i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3
            cof[:, i, j] = (dA[:, i1, j1] * A[:, i2, j2] + A[:, i1, j1] * dA[:, i2, j2]
                            - dA[:, i1, j2] * A[:, i2, j1] - A[:, i1, j2] * dA[:, i2, j1])
    return np.swapaxes(cof, 1, 2)


def _secular_terms(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                   poles: _Poles | None = None) -> tuple[np.ndarray, ...]:
    """The secular quantities of ``A = diag(mu) + X Y^T`` (``X, Y``: n x k, k <= 3) at each
    ``lam``.

    ``det(A - lam) = prod_m (mu_m - lam) det S(lam)``, ``S = I_k + Y^T diag(1/(mu - lam)) X``
    (matrix determinant lemma). The pole ``mu_*`` nearest to ``lam`` is split off,
    ``S = S_r + g_* y_* x_*^T`` with ``g_* = 1/(mu_* - lam)`` and ``S_r`` summed over the other
    poles, so that ``(mu_* - lam) det S = F(lam) = (mu_* - lam) det S_r + x_*^T adj(S_r) y_*``
    is formed without the cancellation of the ``g_*^2`` terms of ``det S`` (``adj`` is a
    polynomial in the entries). Returns ``(Gsum, star, F, dF, S_r, d_star)``:
    ``sum_{m != *} 1/(mu_m - lam)``, the index of ``*``, ``F``, ``dF/dlam``, ``S_r``
    (``K x k x k``) and ``mu_* - lam``. O(n k^2) per ``lam``, in chunks of rows; ``poles``:
    ``_Poles(mu)`` when the caller keeps it across calls.
    """
    k = X.shape[1]
    Z = (Y[:, :, None] * X[:, None, :]).reshape(-1, k * k)
    K = lam.size
    S = np.empty((K, k * k), dtype=complex)
    dS = np.empty((K, k * k), dtype=complex)
    Gsum = np.empty(K, dtype=complex)
    star = np.empty(K, dtype=int)
    poles = _Poles(mu) if poles is None else poles
    for a in range(0, K, _CHUNK):
        G, st = _cauchy_chunk(poles, lam[a:a + _CHUNK])
        star[a:a + _CHUNK] = st
        S[a:a + _CHUNK] = G @ Z
        Gsum[a:a + _CHUNK] = G.sum(axis=1)
        np.multiply(G, G, out=G)
        dS[a:a + _CHUNK] = G @ Z
    S = S.reshape(K, k, k) + np.eye(k)
    dS = dS.reshape(K, k, k)
    xs, ys = X[star], Y[star]
    adj = _adj(S)
    det_r = np.einsum("kj,kj->k", S[:, 0, :], adj[:, :, 0])  # expansion along row 0
    ddet_r = np.einsum("kij,kji->k", adj, dS)
    q = np.einsum("ki,kij,kj->k", xs, adj, ys)
    dq = np.einsum("ki,kij,kj->k", xs, _dadj(S, dS), ys)
    d_star = mu[star] - lam
    F = d_star * det_r + q
    dF = -det_r + d_star * ddet_r + dq
    return Gsum, star, F, dF, S, d_star


def _log_derivative(poles: _Poles, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                    rem: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(q'/q, q == 0)`` at each ``lam``: the logarithmic derivative of the secular function
    ``q(lam) = prod_m (mu_m - lam) det S(lam) / prod_r (lam - r)`` with the removed roots ``r``
    divided out (:func:`~.low_rank_update_eigen`), from :func:`_secular_terms` (the poles
    ``mu`` prepared once per solve); ``inf``/``nan`` where ``lam`` is (numerically) a root."""
    Gsum, _, F, dF, _, _ = _secular_terms(poles.mu, X, Y, lam, poles)
    with np.errstate(divide="ignore", invalid="ignore"):
        L = -Gsum + dF / F
        if rem.size:
            L = L - (1.0 / (lam[:, None] - rem[None, :])).sum(axis=1)
    return L, F == 0.0


def _conjugation(mu: np.ndarray, X: np.ndarray, Y: np.ndarray) -> np.ndarray | None:
    """A permutation ``p`` with ``mu[p] = conj(mu)``, ``X[p] = conj(X)``, ``Y[p] = conj(Y)``
    exactly, or None. With it ``A = diag(mu) + X Y^T`` satisfies ``P A P^T = conj(A)``: ``A``
    is a real map written in a basis closed under conjugation (the chain: the eigenvectors
    ``(1, +-i)/sqrt 2`` of each rotation block), so its spectrum is closed under conjugation
    (an eigenvector ``v`` of ``lam`` gives the eigenvector ``conj(v)[p]`` of ``conj(lam)``).
    Found by sorting ``mu`` and ``conj(mu)`` (O(n log n)) and checked entry by entry."""
    if not (np.all(np.isfinite(mu)) and mu.size):
        return None
    p = np.empty(mu.size, dtype=int)
    p[np.lexsort((-mu.imag, mu.real))] = np.lexsort((mu.imag, mu.real))
    if np.array_equal(mu[p], np.conj(mu)) and np.array_equal(X[p], np.conj(X)) \
            and np.array_equal(Y[p], np.conj(Y)):
        return p
    return None


def _closed_under_conjugation(values: np.ndarray) -> bool:
    """Whether the multiset ``values`` equals its conjugate exactly."""
    key = np.sort_complex(values)
    return bool(np.array_equal(key, np.sort_complex(np.conj(values))))
