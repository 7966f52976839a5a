"""The Ehrlich-Aberth iteration on the secular equation of a low-rank update.

All the roots of the secular function of :mod:`~nsm_continuation.core.floquet.secular` at once,
O(n^2) a sweep (:func:`_aberth`), or a few of them from close starting values
(:func:`refine_roots`, O(n k^2) per root and sweep); the starting values (:func:`_cold_start`,
:func:`_separate`), the Aberth sums (:func:`_aberth_sums`) and the convergence test
(:func:`_settled`), which the iteration on conjugate pairs
(:mod:`~nsm_continuation.core.floquet.pairs`) shares. The entry point choosing between the two
is :func:`~nsm_continuation.core.floquet.lowrank.low_rank_update_eigen`.
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.floquet.secular import _CHUNK, _log_derivative, _Poles


def _settled(size: np.ndarray, last: np.ndarray, scale: np.ndarray, exact: np.ndarray
             ) -> np.ndarray:
    """Whether a root whose last correction was ``size`` (the one before: ``last``) has
    converged: a correction of 1e-12 (relative to ``scale``), an exact root (``exact``), or a
    correction that predicts (at the at least quadratic convergence of a simple root,
    ``e_next ~ e^3 / e_prev^2``) a next one below 1e-14; near a multiple root (linear
    convergence) the corrections keep decreasing; one that no longer decreases is the rounding
    noise of the secular function: the root is as accurate as it evaluates."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        predicted = size**3 / last**2
    return (size <= 1e-12 * scale) | exact | ((size <= 1e-8 * scale) & (size >= last)) \
        | ((size <= 1e-6 * scale) & (last <= 1e-3 * scale) & (size <= 1e-2 * last)
           & (predicted <= 1e-14 * scale))


def _aberth(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, lam: np.ndarray, rem: np.ndarray,
            max_sweeps: int) -> tuple[np.ndarray, dict[str, float]] | None:
    """The Ehrlich-Aberth sweeps of :func:`~.low_rank_update_eigen` from the starting values
    ``lam`` (all the roots, or a subset: :func:`refine_roots`); None if not converged."""
    active, last, poles = _sweep_start(mu, lam.size)
    for sweeps in range(1, max_sweeps + 1):
        idx = np.nonzero(active)[0]
        la = lam[idx]
        L, exact = _log_derivative(poles, X, Y, la, rem)
        with np.errstate(divide="ignore", invalid="ignore"):
            Nk = 1.0 / L
            step = Nk / (1.0 - Nk * _aberth_sums(lam, idx))
        step[~np.isfinite(step)] = 0.0
        lam[idx] = la - step
        size = np.abs(step)
        done = _settled(size, last[idx], np.maximum(1.0, np.abs(lam[idx])), exact)
        last[idx] = size
        active[idx[done]] = False
        if not active.any():
            return lam, _sweep_info(sweeps, last)
    return None


def _sweep_start(mu: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, _Poles]:
    """``(active, last, poles)`` of an iteration on ``k`` roots before its first sweep: all
    active, no correction yet, the poles prepared once (:func:`~._log_derivative`)."""
    return np.ones(k, dtype=bool), np.full(k, np.inf), _Poles(mu)


def _sweep_info(sweeps: int, last: np.ndarray) -> dict[str, float]:
    """``info`` of :func:`~.low_rank_update_eigen`: sweeps and the largest last correction."""
    return {"sweeps": float(sweeps),
            "correction": float(np.max(last[np.isfinite(last)], initial=0.0))}


def refine_roots(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, guesses: np.ndarray, *,
                 removed: tuple[complex, ...] = (), max_sweeps: int = 100
                 ) -> np.ndarray | None:
    """A few eigenvalues of ``A = diag(mu) + X Y^T``: those the starting values ``guesses``
    converge to under the Aberth iteration of :func:`~.low_rank_update_eigen` restricted to them
    (O(n k^2) per root and sweep instead of O(n^2) for the whole spectrum). Each converges to
    the eigenvalue nearest to it (Newton's basin) while the others repel it (the Aberth
    term): two guesses next to a pair of close eigenvalues find both, not one twice. The
    caller must start close (e.g. eigenvalues at a nearby point of a branch). None if the
    iteration did not converge."""
    lam = np.array(guesses, dtype=complex)
    if lam.size == 0:
        return lam
    out = _aberth(np.asarray(mu, dtype=complex), np.asarray(X, dtype=complex),
                  np.asarray(Y, dtype=complex), _separate(lam, 1e-6),
                  np.asarray(removed, dtype=complex), max_sweeps)
    return None if out is None else out[0]


def _aberth_sums(lam: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``sum_{j != k} 1/(lam_k - lam_j)`` for each ``k`` in ``idx`` (chunks of rows). For all
    the roots at once the matrix ``G_kj = 1/(lam_k - lam_j)`` is antisymmetric: only its
    blocks on and right of the diagonal are formed, a block's column sums entering the rows
    below with the opposite sign (half the reciprocals)."""
    if idx.size == lam.size and idx.size > _CHUNK and np.array_equal(idx, np.arange(lam.size)):
        return _aberth_sums_all(lam)
    out = np.empty(idx.size, dtype=complex)
    for a in range(0, idx.size, _CHUNK):
        rows = idx[a:a + _CHUNK]
        G = np.subtract(lam[rows, None], lam[None, :])
        r = np.arange(rows.size)
        G[r, rows] = 1.0
        np.reciprocal(G, out=G)
        G[r, rows] = 0.0
        out[a:a + _CHUNK] = G.sum(axis=1)
    return out


def _aberth_sums_all(lam: np.ndarray) -> np.ndarray:
    """:func:`_aberth_sums` of every root, from the upper block triangle of the
    antisymmetric ``G_kj = 1/(lam_k - lam_j)`` (``G_jk = -G_kj`` exactly)."""
    K = lam.size
    out = np.zeros(K, dtype=complex)
    for a in range(0, K, _CHUNK):
        e = min(a + _CHUNK, K)
        G = np.subtract(lam[a:e, None], lam[None, a:])
        r = np.arange(e - a)
        G[r, r] = 1.0
        np.reciprocal(G, out=G)
        G[r, r] = 0.0
        out[a:e] += G.sum(axis=1)
        out[e:] -= G[:, e - a:].sum(axis=0)
    return out


def _cold_start(mu: np.ndarray, removed: np.ndarray, k: int) -> np.ndarray:
    """``k`` starting values: the poles, without those nearest to the removed roots, moved by
    a third of the distance to their nearest neighbour (off the poles, and off any symmetry
    of the pole set: a conjugate-symmetric start cannot split into two real roots)."""
    keep = np.ones(mu.size, dtype=bool)
    for r in removed:
        d = np.abs(mu - r)
        d[~keep] = np.inf
        keep[int(np.argmin(d))] = False
    start = mu[keep][:k]
    if start.size < k:
        start = np.concatenate([start, np.exp(2j * np.pi * (np.arange(k - start.size) + 0.5)
                                              / max(k - start.size, 1))])
    return start


def _separate(lam: np.ndarray, fraction: float) -> np.ndarray:
    """Starting values moved off each other and off exact symmetry by ``fraction`` of the
    distance to their nearest neighbour, in a fixed pseudo-random direction (a
    conjugate-symmetric start cannot split into two real roots; coincident starts stall)."""
    if lam.size < 2:
        return lam * (1.0 + fraction * 1j) if lam.size else lam.copy()
    near, turn = _neighbour_gaps(lam)
    return lam + fraction * near * turn


def _neighbour_gaps(lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For the moves of starting values (:func:`_separate`, :func:`~._separate_pairs`): the
    distance of each value to its neighbours in angle (at most 0.1; 1e-3 where it is 0 or not
    finite) and a fixed pseudo-random unit complex number per value (results do not depend on
    the call history)."""
    order = np.argsort(np.angle(lam))
    ang = lam[order]
    gap = np.abs(np.diff(np.concatenate([ang, ang[:1]])))
    near = np.empty(lam.size)
    near[order] = np.minimum(gap, np.roll(gap, 1))
    near = np.where(np.isfinite(near) & (near > 0), near, 1e-3)
    rng = np.random.default_rng(12345)
    return np.minimum(near, 0.1), np.exp(2j * np.pi * rng.random(lam.size))
