"""Symmetry-breaking pitchforks of two-wall systems: each one ``branch_point`` at its closed-form
frequency, no ``fold``.

The symmetric two-impact orbits of the impact damper and of the two-sided impact oscillator
(the bundled problems, with the walls declared as one smooth constraint or as two surfaces)
lose their symmetry where a multiplier of the full map is +1 while omega does not turn
(``tests/oracles/two_wall.py``, (T13): ``det(I + M_h) = 0``). Near such a point the bordered
Jacobian is singular and the corrector cannot converge within ~3e-7 of it (rtol 1e-10): each
pitchfork was a ``fold`` located on the count of multipliers (0.5e-6 to 1.4e-6 off) plus a
``branch_point`` 0.4e-6 to 1.4e-6 off. The orbits are within ~1e-11 of the closed form and the
multipliers within ~1e-9 (the multiplier moves by ~7 per unit of omega): the branch point is
asserted within 1e-9.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.impacting.impact_damper import ImpactDamperProblem
from nsm_continuation.problems.impacting.two_sided_oscillator import TwoSidedOscillatorProblem
from oracles import two_wall as tw
from scipy.optimize import brentq

import nsm_continuation as nsm

#: the bundled cases' systems (yaml_cases/impact_damper.yaml, two_sided_oscillator.yaml)
DAMPER = tw.damper(0.0, 0.2, 1.0, 0.6)
OSCILLATOR = tw.oscillator(0.05, 0.5, 0.6)


def _pitchfork(sys: tw.TwoWall, lo: float, hi: float) -> float:
    """The closed form's pitchfork of branch -1 of (T6) in ``[lo, hi]``."""
    return brentq(lambda om: tw.pitchfork_function(tw.orbit(sys, om, -1)), lo, hi,
                  xtol=1e-15, rtol=1e-15)


def _problem(sys: tw.TwoWall, omega: float, encoding: str):
    common = {"zeta": sys.zeta, "omega": omega, "restitution": sys.e, "encoding": encoding}
    if sys is OSCILLATOR:
        return TwoSidedOscillatorProblem({**common, "clearance": sys.w})
    return ImpactDamperProblem({**common, "mass_ratio": sys.extra["mu"], "clearance": 2 * sys.w})


@pytest.mark.parametrize(("sys", "lo", "hi", "encoding"), [
    (DAMPER, 1.87, 1.88, "single"), (DAMPER, 1.87, 1.88, "surfaces"),
    (OSCILLATOR, 1.16, 1.17, "single"), (OSCILLATOR, 1.35, 1.37, "surfaces")],
    ids=["damper-single", "damper-surfaces", "oscillator-single", "oscillator-surfaces"])
def test_pitchfork_is_one_branch_point_at_the_closed_form(sys: tw.TwoWall, lo: float,
                                                          hi: float, encoding: str) -> None:
    w_star = _pitchfork(sys, lo, hi)
    w0 = w_star - 0.01
    pb = _problem(sys, w0, encoding)
    start = np.append(tw.state_at(tw.orbit(sys, w0, -1), 0.0), w0)
    res = nsm.continuation(pb, start, min=w0, max=w_star + 0.01, max_points=40,
                           step={"initial": 0.004, "min": 1e-7, "max": 0.004},
                           newton_tol=1e-10)
    kinds = [e.kind for e in res.events]
    assert "fold" not in kinds, kinds
    (bp,) = [e for e in res.events if e.kind == "branch_point"]
    (sc,) = [e for e in res.events if e.kind == "stability_change"]
    assert abs(bp.parameter - w_star) < 1e-9, bp.parameter - w_star
    assert bp.record["location_bracket"] < 1e-9
    assert abs(complex(*bp.record["critical_multiplier"]) - 1.0) < 1e-8
    # the crossing's stability change sits at the branch point
    assert sc.parameter == bp.parameter
