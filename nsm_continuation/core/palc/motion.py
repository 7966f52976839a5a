"""How far the Floquet multipliers move in one step: the measures the step control bounds.

* :func:`multiplier_motion`: the largest displacement of a multiplier near the unit circle (the
  generic check of damped and hybrid problems);
* :func:`krein_motion`, :func:`krein_motion_ratio`: in a conservative family (multipliers with
  Krein signatures, MacKay 1986) only the motion of multipliers near a collision with a partner
  of the other signature counts;
* :func:`krein_closing`: how fast a step closes the nearest such collision, and whether the
  multipliers outside the circle are the same ones at both ends (:func:`_outside_travel`).
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.floquet import (
    collision_distances,
    count_outside,
    definite_sign,
    nearest_distances,
)


def _krein_displacements(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                         krein_b: np.ndarray, circle_tol: float, lo: float, hi: float,
                         distances: tuple[np.ndarray, np.ndarray] | None
                         ) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(displacement, collision distance)]`` of the multipliers of ``a`` and of ``b`` in
    the annulus ``lo < |lambda| < hi`` (one pair of arrays per end), as
    :func:`krein_motion` defines them."""
    if distances is None:
        distances = (collision_distances(a, krein_a, circle_tol),
                     collision_distances(b, krein_b, circle_tol))
    out = []
    sa, sb = definite_sign(a, krein_a, circle_tol), definite_sign(b, krein_b, circle_tol)
    for sx, sz, x, z, cx in ((sa, sb, a, b, distances[0]), (sb, sa, b, a, distances[1])):
        watch = (np.abs(x) > lo) & (np.abs(x) < hi)
        if not watch.any():
            continue
        xw, sw = x[watch], sx[watch]
        # nearest multiplier of the other point among those of signature +1, -1 and of no
        # definite signature (off the circle or indefinite), each set searched on its own
        # (k-d tree, O(n log n)): a definite multiplier's displacement is the distance to
        # the nearest one that is not definite of the opposite sign, or to the nearest of
        # all when there is no such one; any other multiplier's, to the nearest of all
        d_pos, d_neg, d_none = (nearest_distances(xw, z[sel])
                                for sel in (sz > 0, sz < 0, sz == 0))
        nearest = np.minimum(np.minimum(d_pos, d_neg), d_none)
        disp = np.where(sw > 0, np.minimum(d_pos, d_none),
                        np.where(sw < 0, np.minimum(d_neg, d_none), nearest))
        out.append((np.where(np.isfinite(disp), disp, nearest), cx[watch]))
    return out


def krein_motion(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray, krein_b: np.ndarray,
                 circle_tol: float, fraction: float, lo: float = 0.5, hi: float = 2.0,
                 distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The motion that matters in a conservative family: the largest displacement, between
    two points, of a multiplier in the annulus ``lo < |lambda| < hi`` that is *near a
    collision that can open or close an instability window*, 0 if there is none.

    Krein's theorem (MacKay 1986, "Stability of equilibria of Hamiltonian systems"): a
    multiplier on the unit circle with a definite Krein signature stays on it under small
    symplectic perturbations; the circle can only be left where two multipliers of *opposite*
    signature collide (a conjugate pair at ``+-1``: ``conj`` flips the signature), and
    re-entered where the pair ``lambda, 1/conj(lambda)`` meets again on it. So a window can
    hide inside a step only if some multiplier moves by at least ``fraction`` of its
    *collision distance* (:func:`~nsm_continuation.core.floquet.collision_distances`: to the
    nearest multiplier of the other signature on the circle, or to any multiplier off it;
    0 for a multiplier of indefinite signature). Multipliers of one signature may pass
    through each other at any speed. The displacement of a multiplier on the circle with a
    definite signature is measured to the nearest multiplier *of the same signature* at the
    other point (two of opposite signature that swapped places moved, whatever their
    positions); any other multiplier to the whole other set (as :func:`multiplier_motion`).

    With ``fraction = 0`` this is :func:`multiplier_motion` (every multiplier in the annulus
    counts), the generic check of damped and hybrid problems. ``distances``: the collision
    distances of ``a`` and ``b`` if already computed.
    """
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    motion = 0.0
    for disp, cx in _krein_displacements(a, krein_a, b, krein_b, circle_tol, lo, hi,
                                         distances):
        counts = disp >= fraction * cx
        if counts.any():
            motion = max(motion, float(disp[counts].max()))
    return motion


def krein_motion_ratio(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray,
                       krein_b: np.ndarray, circle_tol: float, fraction: float, step: float,
                       lo: float = 0.5, hi: float = 2.0,
                       distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """The Krein-aware motion check as one number: ``max_i d_i / max(step, fraction c_i)``
    over the multipliers in the annulus (displacement ``d_i`` and collision distance ``c_i``
    as in :func:`krein_motion`), 0 if there is none. It exceeds 1 exactly when
    :func:`krein_motion` exceeds ``step`` (up to the tie ``d_i = fraction c_i``): some
    multiplier moved by more than ``step`` *and* by at least ``fraction`` of its collision
    distance. Displacements grow linearly with a short step, so the ratio also predicts the
    step that would bring it to a target
    (:func:`~nsm_continuation.core.palc.step_control._motion_capped_step`)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    ratio = 0.0
    for disp, cx in _krein_displacements(a, krein_a, b, krein_b, circle_tol, lo, hi,
                                         distances):
        ratio = max(ratio, float((disp / np.maximum(step, fraction * cx)).max()))
    return ratio


#: :func:`krein_closing`: a step may shrink the smallest collision distance at most by this
#: factor, once it is below ``KREIN_NEAR``
KREIN_CLOSING = 0.5
KREIN_NEAR = 0.1
#: :func:`krein_closing`: a multiplier outside the circle is the same one at both ends of a
#: step if it moved by at most ``match`` or by this fraction of its distance to the circle
OUTSIDE_TRAVEL = 0.5


def _outside_travel(x: np.ndarray, y: np.ndarray, match: float) -> np.ndarray:
    """How far a multiplier outside the unit circle may move between ``x`` and its match
    ``y`` at the other end of a step and still be the same one, never on the circle in
    between: ``max(match, OUTSIDE_TRAVEL (min(|x|, |y|) - 1))``. Every point ``z`` of the
    segment from ``x`` to ``y`` has ``|z| >= |x| - |x - y|``, so a motion below
    ``|x| - 1`` (and below ``|y| - 1``) cannot have reached the circle: no window closed and
    opened again on the way, as the count at the two ends cannot show. Far from the circle
    this lets a multiplier move by half its distance to it, instead of ``match``; near it
    (within ``2 match``) the rule is ``match`` as before."""
    return np.maximum(match, OUTSIDE_TRAVEL * (np.minimum(np.abs(x), np.abs(y)) - 1.0))


def krein_closing(a: np.ndarray, krein_a: np.ndarray, b: np.ndarray, krein_b: np.ndarray,
                  circle_tol: float, match: float = 0.02,
                  distances: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """How fast a step from ``a`` to ``b`` (multipliers with their Krein definiteness)
    closes the nearest collision, as a ratio that exceeds 1 when the step is refused: the
    smallest collision distance
    (:func:`~nsm_continuation.core.floquet.collision_distances`, over the annulus
    ``0.5 < |lambda| < 2``) falls below ``KREIN_NEAR`` and below ``KREIN_CLOSING`` times its
    value at ``a``, with the same number of multipliers outside the circle at both ends.

    This catches the window that the endpoints of a step cannot show: two multipliers of
    opposite signature that approach, collide, leave the circle and come back *on the same
    side* within one step (the collision distance dips to 0 and recovers; each multiplier
    ends close to where it started, so no displacement is large). Halving the step until the
    distance shrinks at most by half per step approaches a collision geometrically: either
    the multipliers leave the circle at the end of a step (the count changes, the crossing is
    located) or the distance turns and grows again (a near miss, no window). In a step whose
    count changes, the multipliers of that crossing (and their partners) are left out of the
    test: it is located by the count.

    Also refused: a step whose multipliers *outside* the circle (and inside ``|lambda| < 2``)
    are not the same ones at both ends (one outside at one end has none outside within its
    allowance at the other end: ``match``, or half its distance to the circle,
    :func:`_outside_travel`) beyond a single crossing: with the same count at both ends a
    window closed and another opened within the step, two crossings the count cannot see;
    more than two such multipliers, more crossings than one (a conjugate pair, or a real
    multiplier, leaves or enters at a crossing) in the step.

    The ratio (linear in a short step, so it also predicts the next step): for a refusal of
    the second kind, the largest distance from a multiplier outside (inside ``|lambda| <
    2``) to the nearest one outside at the other end over its allowance (2 when one end has
    none outside: the step is halved); otherwise the larger of that ratio when every such
    multiplier is matched within its allowance, and, once the smallest distance ``c_b`` at
    ``b`` is below ``KREIN_NEAR``, of the fraction of the smallest distance ``c_a`` at
    ``a`` that the step closed over the fraction allowed, ``(1 - c_b / c_a) / (1 -
    KREIN_CLOSING)`` (``> 1`` exactly when ``c_b < KREIN_CLOSING c_a``)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    n_a, n_b = count_outside(a, circle_tol), count_outside(b, circle_tol)
    if abs(n_a - n_b) > 2:
        return 2.0  # more than one crossing (a complex pair, or a real multiplier) at once
    same_count = n_a == n_b
    out_a, out_b = a[np.abs(a) > 1.0 + circle_tol], b[np.abs(b) > 1.0 + circle_tol]
    # multipliers outside the circle (and near it: only those can have come from it or gone
    # back to it) at one end with none outside within ``match`` at the other end
    near_a, near_b = np.abs(out_a) < 2.0, np.abs(out_b) < 2.0
    moved = 0.0  # the largest motion of a multiplier outside over the motion it may have
    if out_a.size and out_b.size:
        d = np.abs(out_a[:, None] - out_b[None, :])
        ia, ib = d.argmin(axis=1), d.argmin(axis=0)
        da, db = d[np.arange(out_a.size), ia], d[ib, np.arange(out_b.size)]
        ra, rb = da / _outside_travel(out_a, out_b[ia], match), \
            db / _outside_travel(out_b, out_a[ib], match)
        crossed = np.concatenate([out_a[(ra > 1.0) & near_a], out_b[(rb > 1.0) & near_b]])
        moved = max(float(ra[near_a].max(initial=0.0)), float(rb[near_b].max(initial=0.0)))
    else:
        crossed = np.concatenate([out_a[near_a], out_b[near_b]])
    if (same_count and crossed.size) or crossed.size > 2:
        # a window closed and another opened (same count), or more than one crossing (a
        # complex pair or a real multiplier) in the step: the count cannot show them all
        return moved if moved > 1.0 else 2.0
    matched = moved if not crossed.size and moved <= 1.0 else 0.0
    ca, cb = distances if distances is not None else (
        collision_distances(a, krein_a, circle_tol), collision_distances(b, krein_b, circle_tol))
    wa = (np.abs(a) > 0.5) & (np.abs(a) < 2.0)
    wb = (np.abs(b) > 0.5) & (np.abs(b) < 2.0)
    if crossed.size:
        # the crossing of the step itself (located by the count) is not a hidden window: its
        # multipliers, their partners 1/conj and conjugates are left out
        near = np.concatenate([crossed, 1.0 / np.conj(crossed)])
        near = np.concatenate([near, np.conj(near)])
        wa &= np.abs(a[:, None] - near[None, :]).min(axis=1) > match
        wb &= np.abs(b[:, None] - near[None, :]).min(axis=1) > match
    if not (wa.any() and wb.any()):
        return matched
    min_a, min_b = float(ca[wa].min()), float(cb[wb].min())
    if not (min_b < KREIN_NEAR and min_a > 0.0):
        return matched
    return max(matched, max(1.0 - min_b / min_a, 0.0) / (1.0 - KREIN_CLOSING))


def multiplier_motion(a: np.ndarray, b: np.ndarray, lo: float = 0.5, hi: float = 2.0) -> float:
    """How far the multipliers near the unit circle move between two points: the largest
    distance from a multiplier of either point lying in the annulus ``lo < |lambda| < hi`` to
    the nearest multiplier of the other point, over the *whole* other set,

    ``max( max_{alpha in A, lo<|alpha|<hi} min_{beta in B} |alpha - beta|,
    max_{beta in B, lo<|beta|<hi} min_{alpha in A} |alpha - beta| )``.

    Instability windows of conservative systems open and close where two multipliers collide on
    the unit circle; if a step moves multipliers by more than the width of such a window, the
    window (out and back in) hides inside the step with the same count at both ends. Bounding
    this motion per step keeps the count test honest. Only the multipliers in the annulus are
    watched, but each is matched against the full other set, so a multiplier entering or
    leaving the annulus (``|lambda|`` through 0.5 or 2) moves by its true displacement, not by
    the distance to another multiplier (the Hausdorff distance of the two restricted sets
    jumped there and collapsed the step for tens of points).
    """
    a = np.asarray(a)
    b = np.asarray(b)
    if a.size == 0 or b.size == 0:
        return 0.0
    d = np.abs(a[:, None] - b[None, :])
    in_a = (np.abs(a) > lo) & (np.abs(a) < hi)
    in_b = (np.abs(b) > lo) & (np.abs(b) < hi)
    motion = 0.0
    if in_a.any():
        motion = max(motion, float(d[in_a].min(axis=1).max()))
    if in_b.any():
        motion = max(motion, float(d[:, in_b].min(axis=0).max()))
    return motion
