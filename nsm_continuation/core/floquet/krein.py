"""Krein signatures of Floquet multipliers: the geometry of collisions on the unit circle.

The multipliers of a conservative (symplectic) return map come with the Krein definiteness of
each eigenvector (:class:`KreinFloquetData`, computed by
:func:`~nsm_continuation.core.floquet.lowrank.krein_definiteness`), whose sign on the unit
circle is the Krein signature. :func:`collision_distances` turns signatures into the distance
of each multiplier to a collision that can open or close an instability window; the engine's
step control uses it (:func:`nsm_continuation.core.palc.motion.krein_motion`).

Krein collisions inside a step: what the multipliers at its two ends say about it.
In a conservative (symplectic) family, a multiplier on the unit circle with a definite Krein
signature stays on it until it meets one of the *other* signature (MacKay 1986). Sorted by
angle, the definite multipliers of the upper half circle spell a word of signs, e.g.
``--++``; multipliers of one signature pass through each other without changing it. Two
multipliers of opposite signature that meet change it, whether they pass each other on the
circle (no instability) or leave it as a quadruple and come back (an instability *window*):
either way the two letters are transposed when they are on the circle again (the one of
signature ``+`` ends on the other side of its partner). A collision at ``+1`` or ``-1`` is
one between a multiplier and its own conjugate (``kappa(conj v) = -kappa(v)``): the letter at
that end of the word flips. The normal form ``H = w1 I1 - w2 I2 + eps q1 q2`` shows both
(``tests/engine/test_krein_windows.py`` checks the transposition across a bubble).

So a step whose two ends have the same number of multipliers outside the circle but
different words contains a collision that the count cannot see. :func:`swap_paths` says
which pair collided (one transposition, or one flip at an end) and how it moved; the engine
then decides on the pair's *discriminant* (:func:`discriminant`), a real analytic function
of the arclength: positive while the pair is on the circle, negative while it is off it, so
a window hidden in the step is where its minimum over the step is negative
(:meth:`nsm_continuation.core.palc.crossings.CrossingLocator.krein_windows`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nsm_continuation.core.problem import FloquetData

#: a multiplier on the unit circle whose Krein definiteness (:func:`~.low_rank_update_eigen`) is
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


#: :func:`swap_paths`: the words differ in more than one collision (or the multipliers on the
#: circle are not the same population at both ends): the step must be split
SEVERAL = "several"


def signature_word(m: np.ndarray, krein: np.ndarray, circle_tol: float
                   ) -> tuple[np.ndarray, str]:
    """The definite multipliers of the upper half circle sorted by angle, and their signs as
    a word (``'+'`` / ``'-'``)."""
    m = np.asarray(m, dtype=complex)
    k = np.asarray(krein, dtype=float)
    on = ((np.abs(np.abs(m) - 1.0) <= circle_tol) & (m.imag > 0.0)
          & (np.abs(k) >= KREIN_DEFINITE))
    idx = np.nonzero(on)[0]
    idx = idx[np.argsort(np.angle(m[idx]))]
    return m[idx], "".join("+" if k[i] > 0 else "-" for i in idx)


def swap_paths(ma: np.ndarray, ka: np.ndarray, mb: np.ndarray, kb: np.ndarray,
               circle_tol: float
               ) -> tuple[tuple[complex, complex], tuple[complex, complex]] | str | None:
    """The collision of opposite signatures inside a step, from the multipliers ``ma``, ``mb``
    at its ends and their Krein definiteness ``ka``, ``kb``:

    * None: the same word at both ends (no such collision, or an even number of them between
      the same two multipliers, which no step check can tell from none);
    * ``((z1a, z1b), (z2a, z2b))``: one collision, of the multiplier at ``z1a`` at the start
      (``z1b`` at the end: the same signature) with the one at ``z2a`` (``z2b``); for a
      collision at ``+-1`` the second is the conjugate of the first;
    * :data:`SEVERAL`: anything else (two transpositions, a letter that moved past two
      others, a multiplier that joined or left the definite ones on the circle)."""
    za, wa = signature_word(ma, ka, circle_tol)
    zb, wb = signature_word(mb, kb, circle_tol)
    if wa == wb:
        return None
    if len(wa) != len(wb):
        return SEVERAL
    diff = [i for i in range(len(wa)) if wa[i] != wb[i]]
    if len(diff) == 2 and diff[1] == diff[0] + 1:
        i = diff[0]
        if wa[i] != wa[i + 1] and wa[i] == wb[i + 1] and wa[i + 1] == wb[i]:
            return ((complex(za[i]), complex(zb[i + 1])), (complex(za[i + 1]), complex(zb[i])))
    if len(diff) == 1 and diff[0] in (0, len(wa) - 1):
        # a flip at the end of the word: the multiplier nearest +1 (first) or -1 (last) met
        # its conjugate there; the one of the start's signature is the conjugate at the end
        i = diff[0]
        z1 = (complex(za[i]), complex(np.conj(zb[i])))
        return z1, (z1[0].conjugate(), z1[1].conjugate())
    return SEVERAL


def discriminant(l1: complex, l2: complex) -> float:
    """``d = (nu_1 - nu_2)^2`` of a pair of multipliers ``l_j = rho exp(i nu_j)``:
    ``-(log(l1 / l2))^2``, real for a pair of a symplectic map near a collision:
    ``(theta_1 - theta_2)^2 > 0`` on the circle, ``-4 (log r)^2 < 0`` for the pair
    ``r rho, rho / r`` off it (also a conjugate pair at ``+-1``: ``-r, -1/r``), zero at the
    collision, and analytic through it (eq. of :meth:`~nsm_continuation.core.palc.
    crossings.CrossingLocator._locate_collision`)."""
    return float((-(np.log(complex(l1) / complex(l2))) ** 2).real)
