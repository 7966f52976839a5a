"""The Ehrlich-Aberth iteration for a real map, on conjugate pairs.

When ``A = diag(mu) + X Y^T`` is a real map written in a basis closed under conjugation
(:func:`~nsm_continuation.core.floquet.secular._conjugation`) and the removed roots are closed
under conjugation, so is the spectrum: the iteration runs on one member of each conjugate pair
and on the real roots (:func:`_aberth_pairs`, about half the work of a sweep of
:func:`~nsm_continuation.core.floquet.aberth._aberth`), a pair moving as its real quadratic
factor (:func:`_quadratic_through`), which splits into two real roots on the axis (a period
doubling at -1, a fold at +1) and forms again from two real ones (:func:`_merge_neighbours`).
The result is exactly conjugate-closed, each root in the slot of the starting value
(:func:`_conjugate_slots`, :func:`_cold_start_pairs`) it came from.
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.floquet.aberth import (
    _neighbour_gaps,
    _settled,
    _sweep_info,
    _sweep_start,
)
from nsm_continuation.core.floquet.secular import _CHUNK, _log_derivative


def _conjugate_slots(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A conjugate-closed set of starting values next to the approximations ``g`` (each of
    its members stays in the slot of the approximation it replaces): ``(lam, partner)`` with
    ``lam[partner[k]] = conj(lam[k])`` exactly, ``partner[k] = k`` for a real ``lam[k]``.
    Values in the upper half plane are paired with those of the lower half plane whose
    conjugate is their nearest and vice versa (mutual nearest neighbours, repeated on the
    rest; a k-d tree, O(n log n) a round) and replaced by the mean of the two, if they are
    nearer to each other's conjugate than to the real axis; the values left unpaired (real
    ones, approximations of real ones off the axis, or an unequal split between the half
    planes) start on the real axis at their real part."""
    from scipy.spatial import cKDTree

    g = np.asarray(g, dtype=complex)
    lam = g.real.astype(complex)
    partner = np.arange(g.size)
    up, lo = np.nonzero(g.imag > 0)[0], np.nonzero(g.imag < 0)[0]
    while up.size and lo.size:  # the closest pair left is always mutual: one round or more
        pu = np.column_stack([g[up].real, g[up].imag])
        pl = np.column_stack([g[lo].real, -g[lo].imag])
        nu = np.asarray(cKDTree(pl).query(pu)[1]).reshape(-1)
        nl = np.asarray(cKDTree(pu).query(pl)[1]).reshape(-1)
        mutual = nl[nu] == np.arange(up.size)
        u, lw = up[mutual], lo[nu[mutual]]
        # nearer to each other's conjugate than to the real axis, else two real values
        near = np.abs(g[u] - np.conj(g[lw])) <= g[u].imag - g[lw].imag
        u, lw = u[near], lw[near]
        z = 0.5 * (g[u] + np.conj(g[lw]))
        lam[u], lam[lw] = z, np.conj(z)
        partner[u], partner[lw] = lw, u
        left = np.ones(lo.size, dtype=bool)
        left[nu[mutual]] = False
        up, lo = up[~mutual], lo[left]
    return lam, partner


def _cold_start_pairs(mu: np.ndarray, removed: np.ndarray, k: int
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """The start of :func:`~._cold_start` for a conjugate-closed pole set (:func:`~._conjugation`)
    and removed roots, itself conjugate-closed: the poles of the upper half plane and the real
    ones as ``(lam, partner)`` (:func:`_conjugate_slots`), less for each removed root in the
    upper half plane the pair nearest to it, for each real one the nearest real pole, and,
    for two real removed roots without a real pole left, the pair nearest to their mean (one
    left over: that pair becomes a real start at its real part). None if that does not leave
    ``k`` values."""
    keep_up, keep_re = mu.imag > 0, mu.imag == 0
    owed: list[float] = []
    for r in removed:
        keep = keep_up if r.imag > 0 else keep_re if r.imag == 0 else None
        if keep is None:
            continue  # a removed root in the lower half plane: its conjugate did it
        if keep.any():
            d = np.where(keep, np.abs(mu - r), np.inf)
            keep[int(np.argmin(d))] = False
        elif r.imag == 0:
            owed.append(float(r.real))
    extra: list[float] = []
    for j in range(0, len(owed), 2):
        if not keep_up.any():
            return None
        i = int(np.argmin(np.where(keep_up, np.abs(mu - np.mean(owed[j:j + 2])), np.inf)))
        keep_up[i] = False
        if j + 1 == len(owed):
            extra.append(float(mu[i].real))
    z = mu[keep_up]
    g = np.concatenate([z, np.conj(z), mu[keep_re].real, extra])
    if g.size != k:
        return None
    return _conjugate_slots(g)


def _separate_pairs(lam: np.ndarray, partner: np.ndarray, fraction: float) -> np.ndarray:
    """:func:`~._separate` keeping the conjugate symmetry of ``(lam, partner)``: each member of
    the upper half plane moves by ``fraction`` of its neighbour gap (by at most half its
    distance to the real axis, so that it stays there), its conjugate with it; each real value
    along the real axis by a pseudo-random fraction of that (coincident values part)."""
    if lam.size < 2:
        return lam.copy()
    near, turn = _neighbour_gaps(lam)
    real = partner == np.arange(lam.size)
    up = np.nonzero(~real & (lam.imag > 0))[0]
    out = lam.copy()
    move = fraction * near[up] * turn[up]
    move *= np.minimum(1.0, 0.5 * lam[up].imag / np.abs(move))
    out[up] = lam[up] + move
    out[partner[up]] = np.conj(out[up])
    out[real] = lam[real].real + fraction * near[real] * turn[real].real
    return out


def _quadratic_through(z1: np.ndarray, z2: np.ndarray, L1: np.ndarray, L2: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """The quadratic factor ``x^2 - sigma x + pi`` of the secular function that two
    approximations ``z1, z2`` stand for, as Aberth's step for a cluster of two roots.

    ``L_i`` is the logarithmic derivative at ``z_i`` of the secular function with every other
    approximate root divided out (``z1`` and ``z2`` too): if those are exact (Aberth's
    assumption) what is left is ``c (x^2 - sigma x + pi)``, whose logarithmic derivative
    ``(2x - sigma)/(x^2 - sigma x + pi)`` equals ``L_i`` at ``x = z_i``: two equations linear
    in ``sigma, pi``, ``L_i (zeta_i^2 - sigma zeta_i + pi) = 2 zeta_i - sigma``, written at
    ``zeta_i = z_i - c`` about the midpoint ``c`` (``zeta_1 = -zeta_2 = h``; no cancellation
    once both are close to their roots). Unlike two Aberth steps, which take each other's
    partner as exact, it moves the two together: a pair that stands across the line of its
    two roots (two approximations on the unit circle of roots that left it at a Krein
    collision; a conjugate pair of two real roots) is not trapped there. Returns
    ``(c + sigma/2, sigma^2/4 - pi)``: the roots are ``c + sigma/2 +- sqrt`` of the second
    (``nan`` where an ``L_i`` is not finite)."""
    c, h = 0.5 * (z1 + z2), 0.5 * (z1 - z2)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        r1, r2 = 2.0 * h - L1 * h * h, -2.0 * h - L2 * h * h
        det = L2 - L1 - 2.0 * h * L1 * L2
        sigma = (r1 * L2 - r2 * L1) / det
        pi = ((1.0 - L1 * h) * r2 - (1.0 + L2 * h) * r1) / det
        return c + 0.5 * sigma, 0.25 * sigma * sigma - pi


def _aberth_pairs(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                  partner: np.ndarray, rem: np.ndarray, max_sweeps: int
                  ) -> tuple[np.ndarray, dict[str, float]] | None:
    """:func:`~._aberth` for a spectrum closed under conjugation (:func:`~._conjugation`) from a
    conjugate-closed start ``(lam, partner)`` (:func:`_conjugate_slots`): the secular
    function is evaluated at one member of each pair (the upper half plane) and at the real
    roots only, about half the O(n) evaluations and half the Aberth sums
    (:func:`_pair_sums`) of :func:`~._aberth`. A pair ``z, conj z`` moves as the quadratic
    factor ``(x - z)(x - conj z)`` (:func:`_quadratic_through`: the conjugate's share of the
    Aberth correction in closed form), which splits into two real roots when its
    discriminant says so; two members of the upper half plane nearer to each other than to
    anything else move as one quadratic factor too (:func:`_isolated_pairs`); a real root
    moves by the Aberth step along the real axis, and two neighbouring real roots whose
    quadratic factor has complex roots become a pair (:func:`_merge_neighbours`). The result
    is exactly conjugate-closed (a pair's second member is the conjugate of the first, a real
    root has no imaginary part), each root in the slot of the start it came from. None if not
    converged."""
    K = lam.size
    slots = np.arange(K)
    lam, partner = lam.copy(), partner.copy()
    active, last, poles = _sweep_start(mu, K)
    for sweeps in range(1, max_sweeps + 1):
        real = partner == slots
        reps = np.nonzero(~real & (lam.imag > 0))[0]
        reals = np.nonzero(real)[0]
        zi, ri = np.nonzero(active[reps])[0], np.nonzero(active[reals])[0]
        ez, er = reps[zi], reals[ri]
        L, exact = _log_derivative(poles, X, Y, np.concatenate([lam[ez], lam[er]]), rem)
        sz, sr = _pair_sums(lam[reps], lam[reals].real, zi, ri)
        new, old_partner = lam.copy(), partner.copy()
        _step_pairs(lam, ez, L[:ez.size] - sz, new, partner)
        # real roots: the Aberth step on the axis; neighbours that are a pair merge
        Lr = (L[ez.size:] - sr).real
        with np.errstate(divide="ignore"):
            step = 1.0 / Lr
        step[~np.isfinite(step)] = 0.0
        new[er] = lam[er].real - step
        _merge_neighbours(lam, er, Lr, new, partner)
        # convergence, the same for both members of a pair
        touched = np.unique(np.concatenate([ez, old_partner[ez], er]))
        ex = np.zeros(K, dtype=bool)
        ex[ez], ex[er] = exact[:ez.size], exact[ez.size:]
        ex[old_partner[ez]] = ex[ez]
        size = np.abs(new[touched] - lam[touched])
        done = np.ones(K, dtype=bool)
        done[touched] = _settled(size, last[touched], np.maximum(1.0, np.abs(new[touched])),
                                 ex[touched])
        done &= done[partner]
        last[touched] = size
        active[touched] = ~done[touched]
        lam = new
        if not active.any():
            return lam, _sweep_info(sweeps, last)
    return None


def _step_pairs(lam: np.ndarray, ez: np.ndarray, Lz: np.ndarray, new: np.ndarray,
                partner: np.ndarray) -> None:
    """The step of the pairs whose members ``lam[ez]`` lie in the upper half plane, into
    ``new`` and ``partner`` (in place), from the logarithmic derivatives ``Lz`` at them with
    every other root divided out but their own conjugates: isolated close pairs of members
    move together (:func:`_isolated_pairs`, :func:`_quadratic_through`) unless that takes one
    out of the upper half plane; every other member moves with its conjugate as the factor
    ``(x - z)(x - conj z)``, which splits into two real roots when its discriminant is not
    negative (the larger one stays in the member's slot)."""
    z = lam[ez]
    own = np.ones(ez.size, dtype=bool)
    a, b = _isolated_pairs(lam, ez)
    if a.size:
        with np.errstate(divide="ignore", invalid="ignore"):
            # the cluster's own conjugates are other roots here, the partner is not
            La = Lz[a] - 1.0 / (z[a] - np.conj(z[a])) + 1.0 / (z[a] - z[b])
            Lb = Lz[b] - 1.0 / (z[b] - np.conj(z[b])) + 1.0 / (z[b] - z[a])
        c, q = _quadratic_through(z[a], z[b], La, Lb)
        root = np.sqrt(q)
        p1, p2 = c + root, c - root
        swap = np.abs(p1 - z[a]) + np.abs(p2 - z[b]) > np.abs(p2 - z[a]) + np.abs(p1 - z[b])
        p1, p2 = np.where(swap, p2, p1), np.where(swap, p1, p2)
        ok = (p1.imag > 0) & (p2.imag > 0) & np.isfinite(p1) & np.isfinite(p2)
        a, b, p1, p2 = a[ok], b[ok], p1[ok], p2[ok]
        new[ez[a]], new[partner[ez[a]]] = p1, np.conj(p1)
        new[ez[b]], new[partner[ez[b]]] = p2, np.conj(p2)
        own[a] = own[b] = False
    e, z, Lz = ez[own], z[own], Lz[own]
    c, q = _quadratic_through(z, np.conj(z), Lz, np.conj(Lz))
    c, q = c.real, q.real
    keep = ~(np.isfinite(c) & np.isfinite(q))
    c[keep], q[keep] = z[keep].real, -z[keep].imag ** 2
    pair = q < 0
    zn = c[pair] + 1j * np.sqrt(-q[pair])
    new[e[pair]], new[partner[e[pair]]] = zn, np.conj(zn)
    split, d = e[~pair], np.sqrt(q[~pair])
    new[split], new[partner[split]] = c[~pair] + d, c[~pair] - d
    partner[partner[split]] = partner[split]
    partner[split] = split


def _isolated_pairs(lam: np.ndarray, cand: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions ``(a, b)`` in ``cand`` (slots of ``lam``) of the pairs of candidates that are
    each other's nearest among all of ``lam`` and at most half as far from each other as
    either is from any third value (a k-d tree, O(n log n)): clusters of two roots, which
    :func:`_quadratic_through` moves together."""
    if cand.size < 2:
        return np.empty(0, dtype=int), np.empty(0, dtype=int)
    from scipy.spatial import cKDTree

    pts = np.column_stack([lam.real, lam.imag])
    d, i = cKDTree(pts).query(pts[cand], k=3)
    near = np.where(i[:, 0] == cand, i[:, 1], i[:, 0])
    pos = np.full(lam.size, -1)
    pos[cand] = np.arange(cand.size)
    other = pos[near]
    alone = d[:, 1] <= 0.5 * d[:, 2]
    a = np.nonzero((other > np.arange(cand.size)) & alone)[0]
    b = other[a]
    mutual = (near[b] == cand[a]) & alone[b]
    return a[mutual], b[mutual]


def _merge_neighbours(lam: np.ndarray, er: np.ndarray, Lr: np.ndarray, new: np.ndarray,
                      partner: np.ndarray) -> None:
    """Neighbouring active real roots ``lam[er]`` (sorted) whose quadratic factor
    (:func:`_quadratic_through`, from the logarithmic derivatives ``Lr`` with every other
    root divided out but the partner) has complex roots become a pair in ``new`` and
    ``partner`` (in place; left to right, each root in one pair at most): the larger one's
    slot holds the member of the upper half plane (as a pair that splits leaves the larger
    real root in that slot)."""
    if er.size < 2:
        return
    order = np.argsort(lam[er].real)
    x, Lx, slot = lam[er].real[order], Lr[order], er[order]
    with np.errstate(divide="ignore"):
        inv = 1.0 / (x[:-1] - x[1:])
    c, q = _quadratic_through(x[:-1], x[1:], Lx[:-1] + inv, Lx[1:] - inv)
    taken = -1
    for i in np.nonzero(q < 0)[0]:
        if i <= taken:
            continue
        a, b = slot[i], slot[i + 1]
        z = c[i] + 1j * np.sqrt(-q[i])
        new[b], new[a] = z, np.conj(z)
        partner[a], partner[b] = b, a
        taken = i + 1


def _pair_sums(z: np.ndarray, r: np.ndarray, zi: np.ndarray, ri: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The Aberth sums ``sum_j 1/(lam_k - lam_j)`` of a conjugate-closed set of roots, the
    pairs ``z, conj z`` and the real roots ``r``, at the members ``z[zi]`` (over every root but
    ``z_k`` and its conjugate, whose share :func:`_step_pairs` holds) and at ``r[ri]`` (every
    root but itself; real: ``1/(x - z) + 1/(x - conj z) = 2 Re 1/(x - z)``). For all the pairs
    at once :func:`_pair_sums_all` halves the work again."""
    if zi.size == z.size and z.size > _CHUNK:
        sz = _pair_sums_all(z)
    else:
        sz = np.empty(zi.size, dtype=complex)
        zc = np.conj(z)
        for a in range(0, zi.size, _CHUNK):
            rows = zi[a:a + _CHUNK]
            sz[a:a + _CHUNK] = (_cauchy_rows(z[rows], z, rows)
                                + _cauchy_rows(z[rows], zc, rows)).sum(axis=1)
    if r.size == 0:
        return sz, np.zeros(ri.size)
    with np.errstate(divide="ignore"):
        sz += (1.0 / (z[zi, None] - r[None, :])).sum(axis=1)
        sr = 2.0 * (1.0 / (r[ri, None] - z[None, :])).real.sum(axis=1)
    sr += _cauchy_rows(r[ri], r, ri).sum(axis=1)
    return sz, sr


def _cauchy_rows(x: np.ndarray, y: np.ndarray, own: np.ndarray) -> np.ndarray:
    """``1/(x_k - y_j)`` with the entries ``j = own_k`` set to 0."""
    G = np.subtract(x[:, None], y[None, :])
    r = np.arange(x.size)
    G[r, own] = 1.0
    with np.errstate(divide="ignore"):
        np.reciprocal(G, out=G)
    G[r, own] = 0.0
    return G


def _pair_sums_all(z: np.ndarray) -> np.ndarray:
    """:func:`_pair_sums` over the pairs at every ``z_k``: ``sum_{j != k} 1/(z_k - z_j)
    + 1/(z_k - conj z_j)``, from the upper block triangles of the antisymmetric
    ``1/(z_k - z_j)`` and of ``1/(z_k - conj z_j)``, whose transpose is minus its conjugate
    (``z_j - conj z_k = -conj(z_k - conj z_j)``): a block's column sums enter the rows below
    as ``-sum`` and ``-conj(sum)`` (a quarter of the reciprocals of all ``2n`` roots')."""
    P = z.size
    zc = np.conj(z)
    out = np.zeros(P, dtype=complex)
    for a in range(0, P, _CHUNK):
        e = min(a + _CHUNK, P)
        own = np.arange(e - a)
        A = _cauchy_rows(z[a:e], z[a:], own)
        B = _cauchy_rows(z[a:e], zc[a:], own)
        out[a:e] += A.sum(axis=1) + B.sum(axis=1)
        out[e:] -= A[:, e - a:].sum(axis=0) + np.conj(B[:, e - a:].sum(axis=0))
    return out
