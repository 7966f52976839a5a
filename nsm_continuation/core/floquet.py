"""Floquet multipliers: removal of trivial multipliers, classification, stability.

Trivial multipliers. For an autonomous system the monodromy matrix (or the Jacobian of a Poincaré
map written in the full state space) carries eigenvalues that say nothing about stability:

* ``0`` when the map is written in the whole state space but its image lies in the section (the
  impact oscillator of Legrand et al. 2017, sec. 6.1): removed *exactly* by restricting the map to
  section coordinates (:func:`restrict_to_section`), which is legitimate because the row of the
  map normal to the section vanishes;
* ``1`` with a known right eigenvector ``v`` (the direction of the family, ``dQ/dT``, eq. 6.5):
  removed by a Householder deflation (:func:`deflate_known_eigenvector`). The residual
  ``|DF v - v| / |v|`` is returned as an accuracy check (it should be ~1e-12; a large value means
  the multipliers themselves are not to be trusted).

Deflation by a known eigenvector is preferred to "remove the eigenvalue closest to 1": near a
bifurcation through +1 another multiplier is also close to 1 and picking by distance swaps them.

Structured spectra (:func:`low_rank_update_eigen`). A return map that is a known normal map plus
a low-rank term, ``A = Q (diag(mu) + X Y^T) Q^H`` (the impacting chain: a rotation by the
flight and rank two from the impact and the period gradient), has the characteristic
polynomial ``prod (mu_m - lam) det(I_k + Y^T (diag(mu) - lam)^-1 X)``: all its roots in O(n^2)
by the Ehrlich-Aberth iteration (for a real map on one member of each conjugate pair, the
spectrum exactly conjugate-closed), known roots divided out exactly, and for each root the Krein
definiteness of its eigenvector (:func:`krein_definiteness`), whose sign on the unit circle is
the Krein signature (:class:`KreinFloquetData`). :func:`collision_distances` turns signatures
into the distance of each multiplier to a collision that can open or close an instability
window; the engine's step control uses it (:func:`nsm_continuation.core.palc.krein_motion`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nsm_continuation.core.problem import FloquetData

#: kinds of a multiplier crossing the unit circle
CROSSING_PLUS_ONE = "fold"
CROSSING_MINUS_ONE = "period_doubling"
CROSSING_COMPLEX = "neimark_sacker"


def restrict_to_section(DF: np.ndarray, normal_index: int) -> np.ndarray:
    """Drop row and column ``normal_index`` of a map whose row ``normal_index`` is zero.

    If ``e_k^T DF = 0`` the spectrum of ``DF`` is ``{0}`` plus the spectrum of ``DF`` with row
    and column ``k`` removed (expand the characteristic determinant along row ``k``).
    """
    keep = np.array([i for i in range(DF.shape[0]) if i != normal_index])
    return DF[np.ix_(keep, keep)]


def householder_basis(v: np.ndarray) -> np.ndarray:
    """Orthogonal symmetric ``H`` whose first column is ``+-v / |v|`` (a Householder reflector)."""
    v = np.asarray(v, dtype=float)
    nv = np.linalg.norm(v)
    if nv == 0.0 or not np.isfinite(nv):
        raise ValueError("cannot deflate a zero or non-finite vector")
    u = v / nv
    w = u.copy()
    w[0] += 1.0 if u[0] >= 0 else -1.0  # no cancellation: |w| >= 1
    return np.eye(len(v)) - 2.0 * np.outer(w, w) / (w @ w)


def deflate_known_eigenvector(A: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Remove the eigenvalue of ``A`` whose eigenvector is ``v``.

    Returns ``(B, lam, residual)``: ``B`` is ``A`` in a basis whose first vector is ``v`` with
    that first row/column removed, so ``spec(A) = {lam} U spec(B)`` up to ``residual``;
    ``lam = v^T A v / v^T v``; ``residual = |A v - lam v| / |v|``.
    """
    H = householder_basis(v)
    C = H @ A @ H
    u = H[:, 0]
    lam = float(u @ A @ u)
    residual = float(np.linalg.norm(A @ u - lam * u))
    return C[1:, 1:], lam, residual


def count_outside(multipliers: np.ndarray, tol: float) -> int:
    """Number of multipliers with modulus above ``1 + tol``."""
    return int(np.sum(np.abs(multipliers) > 1.0 + tol))


def classify_crossing(before: np.ndarray, after: np.ndarray, tol: float,
                      angle_tol: float = 1e-3) -> tuple[str, np.ndarray]:
    """Classify how multipliers crossed the unit circle between two close points.

    Returns the kind (``fold`` for +1, ``period_doubling`` for -1, ``neimark_sacker`` for a
    complex pair) and the multipliers responsible (those outside the circle on the unstable
    side). For conservative systems a pair leaves the circle at +1 or -1 after a collision, or a
    complex quadruple leaves after a Krein collision; the angle of the leaving multiplier decides.
    """
    side = after if count_outside(after, tol) > count_outside(before, tol) else before
    leaving = side[np.abs(side) > 1.0 + tol]
    if leaving.size == 0:
        return "stability_change", leaving
    # the multiplier that has just crossed is the outside one closest to the circle (others
    # may have been outside for a while)
    lam = leaving[np.argmin(np.abs(leaving))]
    ang = float(np.angle(lam))
    if abs(lam.imag) <= angle_tol * abs(lam) and lam.real > 0:
        return CROSSING_PLUS_ONE, leaving
    if abs(lam.imag) <= angle_tol * abs(lam) and lam.real < 0:
        return CROSSING_MINUS_ONE, leaving
    if abs(ang) < angle_tol or abs(abs(ang) - np.pi) < angle_tol:
        return (CROSSING_PLUS_ONE if lam.real > 0 else CROSSING_MINUS_ONE), leaving
    return CROSSING_COMPLEX, leaving


# ============================================================================ Krein signatures
#: a multiplier on the unit circle whose Krein definiteness (:func:`low_rank_update_eigen`) is
#: below this in modulus has no trustworthy signature: it is at (or numerically within) a
#: collision of opposite signatures, and is treated as indefinite
KREIN_DEFINITE = 1e-6


@dataclass
class KreinFloquetData(FloquetData):
    """Multipliers of a conservative (symplectic) return map with, for each, its *Krein
    definiteness* ``kappa = g(v, v) / |v|^2`` in ``[-1, 1]`` (``g`` the Hermitian form
    ``-i omega(conj v, v)`` of the map's symplectic form ``omega``, ``|v|^2`` a positive
    definite norm for which ``|g(v, v)| <= |v|^2``). On the unit circle ``sign(kappa)`` is the
    Krein signature of the multiplier; off the circle ``kappa = 0`` (``g(v, v) = |lambda|^2
    g(v, v)``); two multipliers of opposite signature that collide both have ``kappa -> 0``.
    """

    krein: np.ndarray | None = None
    #: computes ``krein`` when first asked (:func:`krein_of`): the multipliers of the points
    #: of an event location never need it
    krein_source: Callable[[], np.ndarray] | None = field(default=None, repr=False)


def krein_of(fl: FloquetData | None) -> np.ndarray | None:
    """The Krein definiteness of ``fl``'s multipliers (computed once, on first use), or None
    when ``fl`` carries none (not a conservative family)."""
    if fl is None:
        return None
    krein = getattr(fl, "krein", None)
    source = getattr(fl, "krein_source", None)
    if krein is None and source is not None:
        krein = fl.krein = np.asarray(source(), dtype=float)  # type: ignore[attr-defined]
        fl.krein_source = None  # type: ignore[attr-defined]
    return krein


def _signatures(m: np.ndarray, krein: np.ndarray, circle_tol: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(on, sign)``: which multipliers ``m`` lie on the unit circle (``||m| - 1| <=
    circle_tol``) and :func:`definite_sign` of each (computed once for both)."""
    on = np.abs(np.abs(m) - 1.0) <= circle_tol
    k = np.asarray(krein, dtype=float)
    return on, np.where(on & (np.abs(k) >= KREIN_DEFINITE), np.sign(k), 0.0)


def definite_sign(m: np.ndarray, krein: np.ndarray, circle_tol: float) -> np.ndarray:
    """``sign(kappa)`` of the multipliers on the circle (to ``circle_tol``) whose Krein
    definiteness is at least ``KREIN_DEFINITE`` in modulus, else 0 (few multipliers: the
    tests on Python lists, :func:`_signs_small`)."""
    m = np.asarray(m)
    if m.size <= _SMALL_SPECTRUM:
        am = np.abs(m).ravel().tolist()
        kr = np.asarray(krein, dtype=float).ravel().tolist()
        if len(kr) == len(am):
            return np.array(_signs_small(am, kr, circle_tol)).reshape(m.shape)
    return _signatures(m, krein, circle_tol)[1]


#: :func:`collision_distances`, :func:`definite_sign`: up to this many multipliers the
#: bookkeeping runs on Python lists (numpy's per-call overhead dominates there; measured
#: crossover ~28); above, on arrays, with k-d tree searches
_SMALL_SPECTRUM = 24


def collision_distances(mult: np.ndarray, krein: np.ndarray | None, circle_tol: float
                        ) -> np.ndarray:
    """For each multiplier, the distance to the nearest multiplier it can *collide* with so
    that an instability window opens or closes (Krein, MacKay 1986):

    * on the unit circle with a definite signature ``s = sign(kappa)``: the nearest multiplier
      of the other signature on the circle (its own conjugate among them: ``conj(v)`` has
      ``kappa(conj v) = -kappa(v)``, so a multiplier near ``+-1`` is near a collision), or off
      it; multipliers of the same signature pass through each other on the circle without
      leaving it (definite collisions are strongly stable);
    * on the circle without a definite signature (``|kappa| < KREIN_DEFINITE``): 0 (at a
      collision);
    * off the circle: the distance to its partner ``1/conj(lambda)`` (they meet on the circle
      when the window closes) or to any other multiplier, whichever is smaller.

    Without ``krein`` (not a conservative family) every distance is 0: every multiplier near
    the circle may leave it.

    The chord to the nearest multiplier of the other signature is ``2 sin(gap / 2)``, ``gap``
    the smaller of the wrapped angles ``|arg exp(i (phi - phi_left))|``,
    ``|arg exp(i (phi_right - phi))|`` to its two neighbours ``phi_left``, ``phi_right``
    among the other signature's angles sorted (a search in them, O(K log K)). Up to
    ``_SMALL_SPECTRUM`` finite multipliers (the 5-dof chain's 8) the bookkeeping runs on
    Python lists and the nearest multipliers of the loose ones come from one ``K x K``
    distance matrix (:func:`_collision_distances_small`): the same numbers, by fewer numpy
    calls.
    """
    m = np.asarray(mult, dtype=complex)
    if krein is None or m.size == 0:
        return np.zeros(m.size)
    if m.ndim == 1 and m.size <= _SMALL_SPECTRUM:
        small = _collision_distances_small(m, krein, circle_tol)
        if small is not None:
            return small
    on, sign = _signatures(m, krein, circle_tol)
    out = np.full(m.size, np.inf)
    # definite multipliers on the circle: the nearest one of the other signature, found on
    # the circle sorted by angle (the chord grows with the angle): O(K log K)
    for sgn in (1.0, -1.0):
        mine, other = np.nonzero(sign == sgn)[0], np.nonzero(sign == -sgn)[0]
        if mine.size and other.size:
            phi_o = np.sort(np.angle(m[other]))
            phi = np.angle(m[mine])
            j = np.searchsorted(phi_o, phi)
            left = phi_o[(j - 1) % phi_o.size]
            right = phi_o[j % phi_o.size]
            gap = np.minimum(np.abs(np.angle(np.exp(1j * (phi - left)))),
                             np.abs(np.angle(np.exp(1j * (right - phi)))))
            out[mine] = 2.0 * np.sin(0.5 * gap)
    # anything can collide with a multiplier off the circle or of no definite signature
    loose = np.nonzero(sign == 0)[0]
    if loose.size:
        # nearest loose multiplier to each (itself excluded), and nearest multiplier to each
        # loose one (itself excluded): k-d tree searches (:func:`nearest_distances`)
        pos = np.full(m.size, -1)
        pos[loose] = np.arange(loose.size)
        out = np.minimum(out, nearest_distances(m, m[loose], exclude=pos))
        out[loose] = np.minimum(out[loose], nearest_distances(m[loose], m, exclude=loose))
    off = ~on
    with np.errstate(divide="ignore", invalid="ignore"):
        partner = np.abs(m - 1.0 / np.conj(m))
    out[off] = np.minimum(out[off], partner[off])
    out[on & (sign == 0)] = 0.0
    return out


def _signs_small(am: list[float], krein: list[float], circle_tol: float) -> list[float]:
    """:func:`definite_sign` on Python lists: ``am`` the moduli ``|m|`` (numpy's), ``krein``
    the definiteness (same elementwise tests)."""
    return [(1.0 if k > 0.0 else -1.0) if abs(a - 1.0) <= circle_tol and abs(k) >= KREIN_DEFINITE
            else 0.0 for a, k in zip(am, krein, strict=True)]


def _collision_distances_small(m: np.ndarray, krein: np.ndarray, circle_tol: float
                               ) -> np.ndarray | None:
    """:func:`collision_distances` of a few finite multipliers, the bookkeeping on Python
    lists and the numbers from numpy's formulas (``|m|``, ``angle``, the wrapped angles and
    chords, ``|m_i - m_j|``, ``|m - 1/conj(m)|``), so equal to the large path's: the nearest
    multiplier of the other signature by bisection in the sorted angles of each signature
    (``bisect_left`` is ``numpy.searchsorted``); the nearest multiplier of each loose one
    (itself excluded) and the nearest loose one of each other one from the distance matrix
    ``|m_i - m_j|``; the off-circle partners. None (use the large path) when a multiplier is
    not finite (numpy's NaN propagation through the minima is not reproduced) or ``krein``
    does not match ``m`` one to one."""
    from bisect import bisect_left

    am = np.abs(m).tolist()
    kr = np.asarray(krein, dtype=float).ravel().tolist()
    if len(kr) != len(am) or not all(a - a == 0.0 for a in am):  # a - a: nan for inf, nan
        return None
    sg = _signs_small(am, kr, circle_tol)
    K = len(am)
    out = [np.inf] * K
    if 1.0 in sg and -1.0 in sg:
        phi = np.angle(m).tolist()
        ang = {s: sorted(p for p, q in zip(phi, sg, strict=True) if q == s) for s in (1.0, -1.0)}
        idx: list[int] = []
        to_left: list[float] = []
        to_right: list[float] = []
        for i, (p, s) in enumerate(zip(phi, sg, strict=True)):
            if s != 0.0:
                other = ang[-s]
                j = bisect_left(other, p)
                idx.append(i)
                to_left.append(p - other[j - 1])  # j = 0: the last one (wrapped)
                to_right.append(other[j % len(other)] - p)
        k = len(idx)
        d = np.abs(np.angle(np.exp(1j * np.array(to_left + to_right))))
        for i, c in zip(idx, (2.0 * np.sin(0.5 * np.minimum(d[:k], d[k:]))).tolist(),
                        strict=True):
            out[i] = c
    loose = [i for i, s in enumerate(sg) if s == 0.0]
    if loose:
        inf = np.inf
        for i, row in enumerate(np.abs(m[:, None] - m[None, :]).tolist()):
            # a loose one: the nearest of all (itself excluded); another: the nearest loose one
            if sg[i] == 0.0:
                row[i] = inf
                near = min(row)
            else:
                near = min([row[j] for j in loose])
            if near < out[i]:
                out[i] = near
    off = [i for i, a in enumerate(am) if not abs(a - 1.0) <= circle_tol]
    if off:
        mo = m[off]
        if min(am[i] for i in off) > 0.0:
            partner = np.abs(mo - 1.0 / np.conj(mo)).tolist()
        else:
            with np.errstate(divide="ignore", invalid="ignore"):  # 1 / 0
                partner = np.abs(mo - 1.0 / np.conj(mo)).tolist()
        for i, p in zip(off, partner, strict=True):
            out[i] = p if p != p else min(out[i], p)  # numpy.minimum: nan wins
    for i, (a, s) in enumerate(zip(am, sg, strict=True)):
        if s == 0.0 and abs(a - 1.0) <= circle_tol:
            out[i] = 0.0
    return np.array(out)


#: :func:`nearest_distances`: below this many pairs the distance matrix is formed at once
_BRUTE_PAIRS = 4096


def nearest_distances(x: np.ndarray, pts: np.ndarray, exclude: np.ndarray | None = None
                      ) -> np.ndarray:
    """``min_j |x_i - pts_j|`` for each ``x_i`` over ``j != exclude_i`` (``inf`` when no
    point is left): the value of ``np.abs(x[:, None] - pts[None, :]).min(axis=1)`` (with
    ``d[i, exclude_i] = inf``) without the ``len(x) x len(pts)`` matrix. The candidates are
    the four nearest points of a k-d tree of ``pts`` in the plane (O((n + m) log m)), less the
    excluded one; the distance to each is then evaluated as ``|x - p|`` (complex modulus, as
    in the dense formula), so the result is the dense one unless more than three points are
    within rounding of the same distance (then equal to it within rounding). Small inputs
    (at most ``_BRUTE_PAIRS`` pairs: the formula at once) and non-finite ones (the formula in
    row blocks) use the dense formula."""
    x = np.asarray(x, dtype=complex).ravel()
    pts = np.asarray(pts, dtype=complex).ravel()
    if pts.size == 0:
        return np.full(x.size, np.inf)
    if x.size == 0:
        return np.empty(0)
    if x.size * pts.size <= _BRUTE_PAIRS:
        d = np.abs(x[:, None] - pts[None, :])
        if exclude is not None:
            excl = np.asarray(exclude, dtype=int).ravel()
            r = np.flatnonzero(excl >= 0)
            d[r, excl[r]] = np.inf
        return d.min(axis=1)
    excl = np.full(x.size, -1) if exclude is None else np.asarray(exclude, dtype=int).ravel()
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(pts))):
        out = np.empty(x.size)
        rows = max(1, _BRUTE_PAIRS // pts.size)
        for a in range(0, x.size, rows):
            d = np.abs(x[a:a + rows, None] - pts[None, :])
            e = excl[a:a + rows]
            r = np.nonzero(e >= 0)[0]
            d[r, e[r]] = np.inf
            out[a:a + rows] = d.min(axis=1)
        return out
    from scipy.spatial import cKDTree

    kk = min(4, pts.size)
    tree = cKDTree(np.column_stack([pts.real, pts.imag]))
    _, idx = tree.query(np.column_stack([x.real, x.imag]), k=kk)
    idx = np.asarray(idx).reshape(x.size, kk)
    d = np.abs(x[:, None] - pts[idx])
    d[idx == excl[:, None]] = np.inf
    return d.min(axis=1)


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
    :func:`_secular_terms`). The known eigenvalues ``r`` are removed *exactly* by iterating on
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
    exactly, :func:`_conjugation`: the chain's return map) and ``removed`` is closed under
    conjugation, so is the spectrum: the iteration runs on one member of each conjugate pair
    and on the real roots (:func:`_aberth_pairs`, about half the work of a sweep), a pair
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


def _log_derivative(poles: _Poles, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                    rem: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(q'/q, q == 0)`` at each ``lam``: the logarithmic derivative of the secular function
    ``q(lam) = prod_m (mu_m - lam) det S(lam) / prod_r (lam - r)`` with the removed roots ``r``
    divided out (:func:`low_rank_update_eigen`), from :func:`_secular_terms` (the poles
    ``mu`` prepared once per solve); ``inf``/``nan`` where ``lam`` is (numerically) a root."""
    Gsum, _, F, dF, _, _ = _secular_terms(poles.mu, X, Y, lam, poles)
    with np.errstate(divide="ignore", invalid="ignore"):
        L = -Gsum + dF / F
        if rem.size:
            L = L - (1.0 / (lam[:, None] - rem[None, :])).sum(axis=1)
    return L, F == 0.0


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
    """The Ehrlich-Aberth sweeps of :func:`low_rank_update_eigen` from the starting values
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
    active, no correction yet, the poles prepared once (:func:`_log_derivative`)."""
    return np.ones(k, dtype=bool), np.full(k, np.inf), _Poles(mu)


def _sweep_info(sweeps: int, last: np.ndarray) -> dict[str, float]:
    """``info`` of :func:`low_rank_update_eigen`: sweeps and the largest last correction."""
    return {"sweeps": float(sweeps),
            "correction": float(np.max(last[np.isfinite(last)], initial=0.0))}


# ---------------------------------------------------------------- real maps: conjugate pairs
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
    """The start of :func:`_cold_start` for a conjugate-closed pole set (:func:`_conjugation`)
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
    """:func:`_separate` keeping the conjugate symmetry of ``(lam, partner)``: each member of
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
    """:func:`_aberth` for a spectrum closed under conjugation (:func:`_conjugation`) from a
    conjugate-closed start ``(lam, partner)`` (:func:`_conjugate_slots`): the secular
    function is evaluated at one member of each pair (the upper half plane) and at the real
    roots only, about half the O(n) evaluations and half the Aberth sums
    (:func:`_pair_sums`) of :func:`_aberth`. A pair ``z, conj z`` moves as the quadratic
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


def refine_roots(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, guesses: np.ndarray, *,
                 removed: tuple[complex, ...] = (), max_sweeps: int = 100
                 ) -> np.ndarray | None:
    """A few eigenvalues of ``A = diag(mu) + X Y^T``: those the starting values ``guesses``
    converge to under the Aberth iteration of :func:`low_rank_update_eigen` restricted to them
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
    """For the moves of starting values (:func:`_separate`, :func:`_separate_pairs`): the
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


def krein_definiteness(mu: np.ndarray, X: np.ndarray, Y: np.ndarray, lam: np.ndarray,
                       s: np.ndarray, off_circle: float | None = None) -> np.ndarray:
    """Krein definiteness ``g(v)/sum |s_m| |v_m|^2`` of the eigenvector ``v`` of each
    eigenvalue ``lam`` of ``diag(mu) + X Y^T`` (see :func:`low_rank_update_eigen`; ``lam`` from
    any solver): :func:`_krein_kernel`, O(n) per eigenvalue. For a real map (a permutation
    ``p`` with ``mu[p] = conj(mu)``, ``X[p] = conj(X)``, ``Y[p] = conj(Y)``:
    :func:`_conjugation`) whose form is odd under it
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
    :func:`_secular_terms`), then with ``d = mu_* - lam`` the weights
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
