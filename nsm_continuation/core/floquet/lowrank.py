"""Multipliers of a low-rank update of a normal map and the Krein definiteness of their
eigenvectors.

Structured spectra (:func:`low_rank_update_eigen`). A return map that is a known normal map plus
a low-rank term, ``A = Q (diag(mu) + X Y^T) Q^H`` (the impacting chain: a rotation by the
flight and rank two from the impact and the period gradient), has the characteristic
polynomial ``prod (mu_m - lam) det(I_k + Y^T (diag(mu) - lam)^-1 X)``
(:mod:`~nsm_continuation.core.floquet.secular`): all its roots in O(n^2) by the Ehrlich-Aberth
iteration (:mod:`~nsm_continuation.core.floquet.aberth`; for a real map on one member of each
conjugate pair, the spectrum exactly conjugate-closed:
:mod:`~nsm_continuation.core.floquet.pairs`), known roots divided out exactly, and for each root
the Krein definiteness of its eigenvector (:func:`krein_definiteness`), whose sign on the unit
circle is the Krein signature (:class:`~nsm_continuation.core.floquet.krein.KreinFloquetData`).
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.floquet.aberth import _aberth, _cold_start, _separate
from nsm_continuation.core.floquet.pairs import (
    _aberth_pairs,
    _cold_start_pairs,
    _conjugate_slots,
    _separate_pairs,
)
from nsm_continuation.core.floquet.secular import (
    _CHUNK,
    _adj,
    _cauchy_chunk,
    _closed_under_conjugation,
    _conjugation,
    _Poles,
)


def low_rank_update_eigen(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, *,
                       removed: tuple[complex, ...] = (), guess: np.ndarray | None = None,
                       krein_weights: np.ndarray | None = None, max_sweeps: int = 100
                       ) -> tuple[np.ndarray, np.ndarray | None, dict[str, float]] | None:
    """Eigenvalues of ``A = diag(mu) + X Y^T`` (``n x n``, ``X, Y``: ``n x k``, ``k <= 3``)
    other than the known ones ``removed``, in O(n^2), by the Ehrlich-Aberth iteration on the
    secular equation; and, with ``krein_weights``, the Krein definiteness of each eigenvector.

    **Secular equation.** By the matrix determinant lemma

    ``chi(lam) = det(A - lam) = prod_m (mu_m - lam) det(I_k + Y^T (diag(mu) - lam)^-1 X)``,

    a k x k determinant of Cauchy sums (O(n) per ``lam``; the nearest pole is split off, see
    :func:`~._secular_terms`). The known eigenvalues ``r`` are removed *exactly* by iterating on
    ``q(lam) = chi(lam) / prod_r (lam - r)``: its logarithmic derivative is
    ``chi'/chi - sum_r 1/(lam - r)``, so the iteration never converges to a removed root
    (a computed root ``r + delta`` is cancelled by the pole at ``r`` except within
    ``|delta|`` of it). Each sweep of the Aberth iteration

    ``lam_k <- lam_k - N_k / (1 - N_k sum_{j != k} 1/(lam_k - lam_j))``,
    ``N_k = q(lam_k)/q'(lam_k)``

    costs O(n^2) for all ``n - len(removed)`` roots at once (cubic convergence for simple
    roots, linear at a double root; only the roots not yet converged are updated). Start:
    ``guess`` (e.g. the roots at a nearby point of a branch) or the poles ``mu`` rotated by a
    fraction of their spacing.

    **Real maps.** When ``A`` is a real map in a basis closed under conjugation (a
    permutation ``p`` with ``mu[p] = conj(mu)``, ``X[p] = conj(X)``, ``Y[p] = conj(Y)``
    exactly, :func:`~._conjugation`: the chain's return map) and ``removed`` is closed under
    conjugation, so is the spectrum: the iteration runs on one member of each conjugate pair
    and on the real roots (:func:`~._aberth_pairs`, about half the work of a sweep), a pair
    moving as its real quadratic factor, which splits into two real roots on the axis (a
    period doubling at -1, a fold at +1) and forms again from two real ones; the result is
    exactly conjugate-closed (``info['pairs'] = 1``; should the pairs not converge, the
    general iteration answers and its result is made so). Each root keeps the slot of the
    starting value it came from.

    **Eigenvectors and Krein signature.** ``A v = lam v`` gives
    ``v = -(diag(mu) - lam)^-1 X w`` with ``S(lam) w = 0`` (``w``: a column of ``adj S``); with
    real ``krein_weights`` ``s``
    (the Hermitian form ``g(v) = sum_m s_m |v_m|^2`` of a symplectic map in this basis) the
    *Krein definiteness* of each eigenvalue is ``g(v) / sum_m |s_m| |v_m|^2`` in ``[-1, 1]``:
    ``+-1`` for a pure mode, its sign the Krein signature of an eigenvalue on the unit circle,
    ``0`` off the circle, and it tends to 0 for both eigenvalues as two of opposite signature
    collide (the eigenvectors become ``g``-isotropic).

    Returns ``(eigenvalues, definiteness or None, info)`` with ``info['sweeps']`` and
    ``info['correction']`` (the largest last Newton correction), or None when the iteration
    did not converge in ``max_sweeps`` sweeps (the caller falls back to a dense solver).
    """
    mu = np.asarray(mu, dtype=complex)
    X = np.asarray(X, dtype=complex)
    Y = np.asarray(Y, dtype=complex)
    n = mu.size
    k = n - len(removed)
    if k <= 0:
        return np.empty(0, complex), (None if krein_weights is None else np.empty(0)), {
            "sweeps": 0, "correction": 0.0}
    rem = np.asarray(removed, dtype=complex)
    warm = guess is not None and np.asarray(guess).size == k and np.all(np.isfinite(guess))
    # a real map: pairs, and the result exactly conjugate-closed (also when the pairs fail)
    real = _conjugation(mu, X, Y) is not None and _closed_under_conjugation(rem)
    out = None
    if real:
        start = _conjugate_slots(np.asarray(guess, dtype=complex)) if warm \
            else _cold_start_pairs(mu, rem, k)
        if start is not None:
            # identical starting values stall the iteration: separate them, slightly
            lam = _separate_pairs(start[0], start[1], 1e-6 if warm else 0.3)
            out = _aberth_pairs(mu, X, Y, lam, start[1], rem, max_sweeps)
            if out is not None:
                out[1]["pairs"] = 1.0
    if out is None:
        lam = _separate(np.array(guess, dtype=complex), 1e-6) if warm \
            else _separate(_cold_start(mu, rem, k), 0.3)
        out = _aberth(mu, X, Y, lam, rem, max_sweeps)
        if out is None:
            return None
        if real:
            out = (_conjugate_slots(out[0])[0], out[1])
    lam, info = out
    if krein_weights is None:
        return lam, None, info
    return lam, krein_definiteness(mu, X, Y, lam, np.asarray(krein_weights, dtype=float)), info


def krein_definiteness(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                       s: np.ndarray, off_circle: float | None = None) -> np.ndarray:
    """Krein definiteness ``g(v)/sum |s_m| |v_m|^2`` of the eigenvector ``v`` of each
    eigenvalue ``lam`` of ``diag(mu) + X Y^T`` (see :func:`low_rank_update_eigen`; ``lam`` from
    any solver): :func:`_krein_kernel`, O(n) per eigenvalue. For a real map (a permutation
    ``p`` with ``mu[p] = conj(mu)``, ``X[p] = conj(X)``, ``Y[p] = conj(Y)``:
    :func:`~._conjugation`) whose form is odd under it
    (``s[p] = -s``: the Hermitian form ``-i omega(conj v, v)`` of a real symplectic form), the
    eigenvector of ``conj(lam)`` is ``conj(v)[p]`` and ``kappa(conj lam) = -kappa(lam)``
    exactly: only one member of each pair of exact conjugates in ``lam`` is computed (half the
    work when the spectrum is exactly conjugate-closed, as :func:`low_rank_update_eigen` makes
    it). ``off_circle``: the map is symplectic for the form ``s``, so that an eigenvalue off
    the unit circle has ``g(v, v) = |lam|^2 g(v, v) = 0``; those farther than ``off_circle``
    from it (certainly off it: the eigenvalues are accurate to far less) get their exact
    ``kappa = 0`` without being computed (the computed value is rounding noise)."""
    mu = np.asarray(mu, dtype=complex)
    X = np.asarray(X, dtype=complex)
    Y = np.asarray(Y, dtype=complex)
    lam = np.asarray(lam, dtype=complex)
    s = np.asarray(s, dtype=float)
    p = _conjugation(mu, X, Y)
    own = np.ones(lam.size, dtype=bool)
    out = np.zeros(lam.size)
    up, lo = np.empty(0, dtype=int), np.empty(0, dtype=int)
    if p is not None and np.array_equal(s[p], -s):
        up, lo = _exact_pairs(lam)
        own[lo] = False
    if off_circle is not None:
        own &= np.abs(np.abs(lam) - 1.0) <= off_circle
    out[own] = _krein_kernel(mu, X, Y, lam[own], s)
    out[lo] = -out[up]
    return out


def _exact_pairs(lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(up, lo)``: indices with ``lam[lo] = conj(lam[up])`` exactly, ``Im lam[up] > 0``,
    pairing every non-real value (sorted by real and imaginary part), or two empty arrays
    when ``lam`` is not exactly conjugate-closed."""
    up, lo = np.nonzero(lam.imag > 0)[0], np.nonzero(lam.imag < 0)[0]
    up = up[np.lexsort((lam[up].imag, lam[up].real))]
    lo = lo[np.lexsort((-lam[lo].imag, lam[lo].real))]
    if up.size == lo.size and np.array_equal(lam[lo], np.conj(lam[up])):
        return up, lo
    return np.empty(0, dtype=int), np.empty(0, dtype=int)


def _krein_kernel(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                  s: np.ndarray) -> np.ndarray:
    """:func:`krein_definiteness` of each ``lam``, computed from
    ``(mu_* - lam) v = -(mu_* - lam)(diag(mu) - lam)^-1 X w``
    (bounded near a pole), ``w`` the largest column of ``adj((mu_* - lam) S(lam))``. O(n) per
    eigenvalue, in one pass over the Cauchy matrix ``G_km = 1/(mu_m - lam_k)`` (chunks of
    rows): ``S_r = I + Y^T diag(G_k) X`` (the pole ``*`` split off as in
    :func:`~._secular_terms`), then with ``d = mu_* - lam`` the weights
    ``|d v_m|^2 = |d|^2 |G_km (X w)_m|^2`` (``m != *``) and ``|d v_*|^2 = |(X w)_*|^2``."""
    k = X.shape[1]
    Z = (Y[:, :, None] * X[:, None, :]).reshape(-1, k * k)
    XT = np.ascontiguousarray(X.T)
    weights = np.stack([s, np.abs(s)], axis=1)
    weights2 = np.repeat(weights, 2, axis=0)  # for the (re, im) pairs of a complex row
    num = np.empty(lam.size)
    den = np.empty(lam.size)
    star = np.empty(lam.size, dtype=int)
    poles = _Poles(mu)
    for a in range(0, lam.size, _CHUNK):
        sl = slice(a, a + _CHUNK)
        G, st = _cauchy_chunk(poles, lam[sl])
        star[sl] = st
        rows = np.arange(st.size)
        S = (G @ Z).reshape(-1, k, k) + np.eye(k)
        d_star = mu[st] - lam[sl]
        # M = (mu_* - lam) S = d S_r + y_* x_*^T is singular at an eigenvalue: its null
        # vector is the largest column of adj(M) (rank one)
        M = d_star[:, None, None] * S + Y[st][:, :, None] * X[st][:, None, :]
        A = _adj(M)
        col = np.argmax(np.linalg.norm(A, axis=1), axis=1)
        w = A[rows, :, col]
        Xw = w @ XT  # (X w)_m for each root
        xw_star = Xw[rows, st]
        # sum_m w_m |G_km (X w)_m|^2 over re and im parts at once (G_k* = 0 leaves * out)
        G *= Xw
        V = G.view(float)
        np.multiply(V, V, out=V)
        nd = (V @ weights2) * (np.abs(d_star) ** 2)[:, None]
        nd += (xw_star.real**2 + xw_star.imag**2)[:, None] * weights[st]
        num[sl], den[sl] = nd[:, 0], nd[:, 1]
    # an eigenvalue at an uncoupled pole (its row of X vanishes) has that pole's unit vector
    # as eigenvector, which -(diag(mu) - lam)^-1 X w does not see
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.sign(s[star]))
