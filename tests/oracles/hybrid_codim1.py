"""Test-only oracle of the grazing curves of :mod:`nsm_continuation.hybrid.codim1`.

``grazing_curve_start``: the unknowns of a :class:`~nsm_continuation.hybrid.codim1.GrazingCurve`
from a grazing orbit of its base problem (the tests start the curve at a closed-form grazing
orbit)."""

from __future__ import annotations

import numpy as np

from nsm_continuation.hybrid.codim1 import GrazingCurve


def grazing_curve_start(curve: GrazingCurve, y_grazing: np.ndarray) -> np.ndarray:
    """The curve's unknowns from a grazing orbit of the base problem (unknowns ``(z, p)`` with
    ``p`` = ``curve.free``): the continued parameter's value is the base problem's."""
    y = np.asarray(y_grazing, dtype=float)
    return np.append(y, curve.base.values[curve.parameter])
