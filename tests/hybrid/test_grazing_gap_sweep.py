"""The undamped impact oscillator ``q'' + q = cos(omega t)``, ``q >= gap``, restitution 0.8,
reaches its grazing from the impacting side at every gap: its free orbit has the amplitude
``1 / |1 - omega^2|``, so it grazes the stop at ``omega_g = sqrt(1 + 1 / |gap|)`` (closed form);
the low-velocity impacting orbit (Shaw & Holmes, ``tests/oracles/impact_oscillator.py``) ends
there, from below for ``|gap| < 1/3`` (the grazing persists: the free orbit goes on above) and
from above for ``|gap| > 1/3`` (a nonsmooth fold). Each branch starts on the closed-form orbit
next to the grazing and must locate it, to 1e-10, and go on along the free orbit.

On the impacting side the margin ``-v^2 / (2a)`` is quadratic in the arclength, and the step
cap that keeps an event function from being jumped over (its linear prediction) approached
the zero geometrically without reaching it; at gap -0.25 the steps collapsed, ``|mu|`` grew to
1.8e7 and the branch ended at omega = sqrt(5) - 1.3e-8 with no grazing (gaps -0.4 and -0.5, from
above, met a failed step first and were crossed).
"""

from __future__ import annotations

import numpy as np
import pytest
from oracles.impact_oscillator import section_state

import nsm_continuation as nsm

R = 0.8


@pytest.mark.parametrize("gap", [-0.2, -0.25, -0.3, -0.4, -0.6])
def test_grazing_is_located_from_the_impacting_side_at_every_gap(gap: float) -> None:
    wg = np.sqrt(1.0 + 1.0 / abs(gap))
    side = -1.0 if abs(gap) < 1.0 / 3.0 else 1.0      # where the impacting orbit lies
    w0 = wg + side * 0.01
    q, qdot = section_state(w0, gap, R, low_velocity=True)
    case = {"name": "graze", "problem": "impact_oscillator",
            "parameters": {"zeta": 0.0, "omega": w0, "gap": gap, "restitution": R,
                           "section_phase": np.pi},
            "start": {"guess": {"q": float(q), "qdot": float(qdot)},
                      "direction": "decrease" if side > 0 else "increase"},
            "continuation": {"parameter": "omega", "min": wg - 0.05, "max": wg + 0.05,
                             "step": {"initial": 1e-3, "min": 1e-9, "max": 0.01},
                             "max_points": 300, "newton_tol": 1e-10},
            "analysis": {"stability": True, "bifurcations": True},
            "output": {"plots": False, "progress": False}}
    res = nsm.run(case)
    (branch,) = res.branches
    grazing = [e for e in res.events if e.kind == "grazing"]
    assert len(grazing) == 1, [(e.kind, e.parameter) for e in res.events]
    assert abs(grazing[0].parameter - wg) < 1e-10
    # the first orbit is the closed form's; beyond the grazing the orbits are free
    assert branch["n_impacts"][0] == 1
    assert np.abs(branch["y_q"][0] - q) < 1e-8
    k = int(np.argmin(np.abs(branch["omega"] - grazing[0].parameter)))
    assert np.all(branch["n_impacts"][k + 1:] == 0) and k + 5 < len(branch["omega"])
    assert list(branch.termination.values()) == ["bound: omega = max"]
