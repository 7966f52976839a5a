"""A multiplier crossing inside a step that also crosses a grazing point
(:meth:`nsm_continuation.core.palc.crossings.CrossingLocator.ends`).

Past a grazing point a problem may have no multipliers (its return map is not linearised
there): the end of such a step cannot show a crossing between the last point and the grazing.
The crossing is located between the step's start and the near side of the grazing event (on
the 200-dof chain of ``benchmarks/bench_chain_large.py``, a Neimark-Sacker crossing 1.4e-9 in T
before the grazing that ends the branch's instability windows, whenever one step spans both).

Oracle: the logistic map's fixed point ``x = 1 - 1/r`` has the multiplier ``2 - r``, through
``-1`` (a period doubling) at ``r = 3`` exactly; the problem below declares a grazing at
``r = R_GRAZE`` (its admissibility ``R_GRAZE - r``) and no multipliers beyond it.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
from oracles.normal_forms import LogisticMap, LogisticParameters

import nsm_continuation as nsm
from nsm_continuation.core.problem import FloquetData, StartPoint

R_GRAZE = 3.02


class GrazingLogistic(LogisticMap):
    """The logistic map's fixed point, admissible for ``r <= R_GRAZE`` only, with no
    multipliers beyond (as an impacting orbit past its grazing)."""

    name: ClassVar[str] = "test_grazing_logistic"

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {"margin": R_GRAZE - float(y[1])}

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> Any:
        if float(y[1]) > R_GRAZE:
            return None
        return FloquetData(np.array([2.0 - float(y[1])]))


def _run(r0: float, first_step: float) -> nsm.Result:
    return nsm.continuation(GrazingLogistic(LogisticParameters(r=r0)), {}, parameter="r",
                            min=2.5, max=3.5, max_points=20,
                            step={"initial": first_step, "min": 1e-9, "max": first_step},
                            analysis={"stability": True, "bifurcations": True})


@pytest.mark.parametrize(("r0", "first_step"), [(2.9, 0.135), (2.95, 0.08), (2.99, 0.035)])
def test_a_crossing_between_the_last_point_and_a_grazing_is_located(r0: float,
                                                                     first_step: float) -> None:
    res = _run(r0, first_step)
    pts = res.branches[0]["r"]
    # the first step itself jumps from before the crossing to beyond the grazing
    assert pts[0] < 3.0 and pts[1] > R_GRAZE
    kinds = {ev.kind: ev for ev in res.events}
    assert "grazing" in kinds
    assert kinds["grazing"].parameter == pytest.approx(R_GRAZE, abs=1e-6)
    pd = kinds.get("period_doubling")
    assert pd is not None, [ev.kind for ev in res.events]
    # on the true condition: the multiplier 2 - r through -1
    assert pd.parameter == pytest.approx(3.0, abs=1e-6)
    assert pd.parameter < kinds["grazing"].parameter


def test_a_step_with_multipliers_at_both_ends_is_unchanged() -> None:
    """Without the grazing in the step, the same crossing from the step's own ends."""
    res = _run(2.9, 0.1)
    pds = [ev for ev in res.events if ev.kind == "period_doubling"]
    assert len(pds) == 1 and pds[0].parameter == pytest.approx(3.0, abs=1e-6)


class TwoTests(LogisticMap):
    """The logistic fixed point with two admissibility tests, ``3.1 - r`` and ``3.2 - r``:
    admissible below ``r = 3.1`` only."""

    name: ClassVar[str] = "test_two_tests_logistic"

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {"first": 3.1 - float(y[1]), "second": 3.2 - float(y[1])}


def test_a_test_changing_sign_on_an_inadmissible_orbit_says_so() -> None:
    """Up in ``r``: 'first' loses admissibility at 3.1; 'second' changes sign at 3.2 on an
    orbit 'first' already makes inadmissible, which its detail says (not "admissibility
    lost"); read the other way (``report.reversed_detail``), 'second' becomes positive on an
    orbit that stays inadmissible. Down in ``r`` the engine's own words are those."""
    from nsm_continuation.output.report import reversed_detail

    def run(r0: float, direction: int) -> nsm.Result:
        start = StartPoint(np.array([1 - 1 / r0, r0]), "fixed point", direction)
        return nsm.continuation(TwoTests(LogisticParameters(r=r0)), start, parameter="r",
                                min=2.5, max=3.5, max_points=200,
                                analysis={"stability": False})

    up, down = run(2.9, 1), run(3.45, -1)
    for res in (up, down):
        graz = {ev.record["test"]: ev for ev in res.events if ev.kind == "grazing"}
        assert graz["first"].parameter == pytest.approx(3.1, abs=1e-9)
        assert graz["second"].parameter == pytest.approx(3.2, abs=1e-9)
    up_graz = {ev.record["test"]: ev.detail for ev in up.events if ev.kind == "grazing"}
    down_graz = {ev.record["test"]: ev.detail for ev in down.events if ev.kind == "grazing"}
    assert up_graz["first"].endswith("becomes negative: admissibility lost")
    assert up_graz["second"].endswith(
        "becomes negative (the orbit was already inadmissible: ['first'])")
    assert down_graz["second"].endswith(
        "becomes positive (the orbit stays inadmissible: ['first'])")
    assert down_graz["first"].endswith("becomes positive: admissibility regained")
    assert reversed_detail(up_graz["second"]) == down_graz["second"]
    assert reversed_detail(down_graz["first"]) == up_graz["first"]
