"""Krein collisions inside a step: what the multipliers at its two ends say about it.

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
(``tests/test_krein_windows.py`` checks the transposition across a bubble).

So a step whose two ends have the same number of multipliers outside the circle but
different words contains a collision that the count cannot see. :func:`swap_paths` says
which pair collided (one transposition, or one flip at an end) and how it moved; the engine
then decides on the pair's *discriminant* (:func:`discriminant`), a real analytic function
of the arclength: positive while the pair is on the circle, negative while it is off it, so
a window hidden in the step is where its minimum over the step is negative
(:meth:`nsm_continuation.core.palc.ContinuationEngine._krein_windows`).
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.floquet import KREIN_DEFINITE

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
    ContinuationEngine._locate_collision`)."""
    return float((-(np.log(complex(l1) / complex(l2))) ** 2).real)
