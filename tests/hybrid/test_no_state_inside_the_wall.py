"""No recorded state lies inside the wall, whatever the integration tolerance.

With a loose tolerance (``integrator.rtol: 1e-3``) a step of the two-mass chain could cross the
wall and the stroboscopic section together, and the cubic interpolant of ``H`` placed the
impact after the section: the section fired first, with the true ``H < 0``, and the state
recorded there lay inside the wall (the next return then refused it as "initial state on the
inadmissible side"). ``H`` is monotone while the mass approaches the wall, so a section reached
with ``H < 0`` brackets the impact it passed: the impact is located first. Oracle: the wall
itself (``q2 <= gap`` at every recorded state and over every recorded return), and the same
sweep at the default tolerance (the attractor does not depend on the tolerance).
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

import nsm_continuation as nsm

PARAMS = {"m1": 1.0, "m2": 1.0, "k1": 1.0, "k2": 1.0, "c": 0.05, "F0": 0.5, "omega": 0.6,
          "gap": 0.5, "restitution": 0.8}


@cache
def sweep(rtol: float) -> dict[str, np.ndarray]:
    res = nsm.run({"name": "loose", "problem": "two_mass_chain",
                   "parameters": {**PARAMS, "integrator": {"rtol": rtol}},
                   "start": {"transient": 20, "record": 3},
                   "continuation": {"algorithm": "sweep", "parameter": "omega", "min": 0.6,
                                    "max": 0.7, "max_points": 6, "direction": "increase"},
                   "output": {"plots": False, "progress": False}})
    return res.branches[0].columns()


@pytest.mark.parametrize("rtol", [1e-3, 1e-4, 1e-6])
def test_loose_tolerances_record_no_state_inside_the_wall(rtol: float) -> None:
    cols = sweep(rtol)
    assert not np.any(cols["failures"]) and not np.any(cols["restarted"])
    # at the wall to the impact's location (round-off), never inside
    assert np.all(cols["y_q2"] <= PARAMS["gap"] * (1 + 1e-12))
    assert np.all(cols["max_q2"] <= PARAMS["gap"] * (1 + 1e-12))
    # the same attractor (one impact per period) as at the default tolerance
    ref = sweep(1e-10)
    np.testing.assert_array_equal(cols["n_impacts"], ref["n_impacts"])
    np.testing.assert_allclose(cols["y_q2"], ref["y_q2"], atol=3e3 * rtol)
