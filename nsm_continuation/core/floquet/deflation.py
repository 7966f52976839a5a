"""Floquet multipliers: removal of trivial multipliers, classification of crossings, stability.

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

Stability and crossings. :func:`count_outside` counts the multipliers outside the unit circle;
:func:`classify_crossing` names the kind of a crossing (fold at +1, period doubling at -1,
Neimark-Sacker for a complex pair) from the multipliers at two close points.
"""

from __future__ import annotations

import numpy as np

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
    return classify_outside(side, tol, angle_tol)


def classify_outside(side: np.ndarray, tol: float, angle_tol: float = 1e-3
                     ) -> tuple[str, np.ndarray]:
    """The kind of a crossing seen from its unstable side ``side`` alone (the multipliers of
    the point with more of them outside ``|lambda| = 1 + tol``, ``tol`` that point's own noise
    threshold), and the multipliers outside there: the one that has just crossed is the
    outside one closest to the circle (:func:`classify_crossing`)."""
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
