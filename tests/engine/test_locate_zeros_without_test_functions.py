"""Zeros of functions that read neither the admissibility tests nor the multipliers (a bound
on the parameter or on a derived quantity, a fold, the bordered determinant) are located on
trial points analysed without them (``tests=False``), and every zero by the Illinois
iteration with Dekker's closing step
(:meth:`nsm_continuation.core.palc.locate.EventLocator._locate_continuous`).

Oracle: the fold normal form ``G(x, mu) = mu - x^2``, whose fold is at ``x = 0`` and whose
derived quantity ``q = x`` reaches a bound ``q = Q`` at ``(Q, Q^2)``, closed forms. Each trial
point of those locations is counted, with whether its tests were evaluated; the admissibility
test function of the problem counts its own calls.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
from oracles.normal_forms import MuParameters, Transcritical

from nsm_continuation.core import palc
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.core.settings import ContinuationSettings

Q = 0.5


class Fold(Transcritical):
    """``G(x, mu) = mu - x^2``; admissibility ``2 - x`` (never lost here), ``q = x``."""

    name: ClassVar[str] = "test_fold"

    def __init__(self, params: Any) -> None:
        super().__init__(params)
        self.test_calls = 0

    def residual(self, y: Any) -> Any:
        return y[1] - y[0] ** 2

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        self.test_calls += 1
        return {"margin": 2.0 - float(y[0])}

    def derived(self, y: np.ndarray) -> dict[str, float]:
        return {"q": float(y[0])}

    def monitor_names(self) -> list[str]:
        return ["q"]


@pytest.fixture()
def located(monkeypatch: pytest.MonkeyPatch) -> list[tuple[bool, int, int]]:
    """``(tests, trial points, admissibility calls)`` of every ``_locate_continuous`` call of
    the run."""
    calls: list[tuple[bool, int, int]] = []
    locate, point_at = palc.EventLocator._locate_continuous, palc.ContinuationEngine.point_at
    inside: list[int] = []

    def counted_point_at(self: Any, *args: Any, **kwargs: Any) -> Any:
        if inside:
            inside[-1] += 1
        return point_at(self, *args, **kwargs)

    def counted_locate(self: Any, *args: Any, tests: bool = True, **kwargs: Any) -> Any:
        inside.append(0)
        before = self.problem.test_calls
        try:
            return locate(self, *args, tests=tests, **kwargs)
        finally:
            calls.append((tests, inside.pop(), self.problem.test_calls - before))

    monkeypatch.setattr(palc.ContinuationEngine, "point_at", counted_point_at)
    monkeypatch.setattr(palc.EventLocator, "_locate_continuous", counted_locate)
    return calls


def _run(bound: bool) -> tuple[Fold, Any]:
    pb = Fold(MuParameters())
    st = ContinuationSettings(step_initial=0.05, step_max=0.3, param_min=-1.0, param_max=1.0,
                              max_points=60, stability=False, direction=-1,
                              derived_bounds={"q": (None, Q)} if bound else {})
    # from x = -0.9 towards decreasing mu: through the fold at x = 0, then x grows to the
    # bound q = Q (or to mu = 1)
    start = StartPoint(np.array([-0.9, 0.81]), "fold", -1)
    return pb, palc.ContinuationEngine(pb, st).run(start)


def test_a_fold_is_located_on_trial_points_without_tests(
        located: list[tuple[bool, int, int]]) -> None:
    pb, br = _run(bound=False)
    folds = [ev for ev in br.events if ev.kind == "fold"]
    assert len(folds) == 1
    x, mu = folds[0].point.y
    # on the true condition: the tangent's mu component vanishes at x = 0
    assert abs(x) < 1e-10 and abs(mu) < 1e-12
    assert located and all(not tests for tests, _, _ in located)
    # the located point alone is analysed with its tests (in full)
    assert all(calls == 1 for _, _, calls in located)
    # Dekker's closing step: a few trial points, not ~20 halvings to event_tol
    assert max(n for _, n, _ in located) <= 12


def test_a_derived_bound_is_located_without_the_tests(
        located: list[tuple[bool, int, int]]) -> None:
    pb, br = _run(bound=True)
    ends = [ev for ev in br.events if ev.kind == "endpoint"]
    assert len(ends) == 1
    x, mu = ends[0].point.y
    assert x == pytest.approx(Q, abs=1e-10) and mu == pytest.approx(Q**2, abs=1e-10)
    # the fold and the bound: trial points without tests, the located point in full
    assert len(located) == 2 and all(not tests for tests, _, _ in located)
    assert all(n > 1 and calls == 1 for _, n, calls in located)


class Clearance(Fold):
    """The fold normal form with the admissibility ``margin = 0.3 - x``: lost at
    ``(x, mu) = (0.3, 0.09)``."""

    name: ClassVar[str] = "test_fold_clearance"

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        self.test_calls += 1
        return {"margin": 0.3 - float(y[0])}


def test_an_admissibility_zero_is_located_in_a_few_trial_points(
        located: list[tuple[bool, int, int]]) -> None:
    pb = Clearance(MuParameters())
    st = ContinuationSettings(step_initial=0.05, step_max=0.3, param_min=-1.0, param_max=1.0,
                              max_points=60, stability=False, direction=-1)
    br = palc.ContinuationEngine(pb, st).run(StartPoint(np.array([-0.9, 0.81]), "fold", -1))
    (graz,) = [ev for ev in br.events if ev.kind == "grazing"]
    x, mu = graz.point.y
    assert x == pytest.approx(0.3, abs=1e-10) and mu == pytest.approx(0.09, abs=1e-10)
    with_tests = [n for tests, n, _ in located if tests]
    assert len(with_tests) == 1 and with_tests[0] <= 12
