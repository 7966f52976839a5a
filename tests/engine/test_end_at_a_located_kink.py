"""A branch that lands exactly on the zero of a kink located ahead ends there, named.

The steps towards a grazing shrink geometrically (its margin is quadratic in the arclength on
the impacting side); the last accepted point can sit on the margin's zero itself (0.0 exactly,
as on the impact damper declared with one constraint, ``benchmarks/two_wall_untuned.py``).
The kink located ahead is then *at* that point, not passed: the failing step after it ends the
branch at the located grazing (its event and reason), not as an unnamed Newton failure. The
property checked: a kink is still expected at a point whose event function is zero or keeps
its sign and modulus, and forgotten once the function changed sign or grew.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from nsm_continuation.core.palc.ends import EndLocator
from nsm_continuation.core.palc.kinks import KinkCrossing
from nsm_continuation.core.records import Event, Point


def _point(margin: float) -> Point:
    return Point(y=np.zeros(2), s=0.0, tangent=np.array([0.0, 1.0]), tests={},
                 multipliers=None, trivial_error=0.0, n_unstable=0, derived={},
                 bordered_det=1.0, event_values={"grazing_margin": margin})


@pytest.mark.parametrize(("margin", "expected"), [
    (1e-3, True),    # where it was located from
    (1e-9, True),    # closer, same side
    (0.0, True),     # on the zero itself
    (-1e-12, False),  # passed: the sign changed
    (2e-3, False),   # turned away: farther than where it was located
    (float("nan"), False),
])
def test_a_kink_at_the_last_point_is_still_expected(margin: float, expected: bool) -> None:
    ends = EndLocator(SimpleNamespace())
    start = _point(1e-3)
    zero = _point(0.0)
    crossing = KinkCrossing([zero], [Event("grazing", zero, "",
                                           data={"function": "grazing_margin"})],
                            end="grazing at the zero")
    ends.expect(crossing, start)
    assert ends.expecting(_point(margin)) is expected
