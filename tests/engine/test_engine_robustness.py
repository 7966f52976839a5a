"""The engine never crashes and gives no silent wrong result.

Toy problems with closed-form curves (the circle x^2 + p^2 = 1, the line x = p) whose hooks
fail on purpose; oracles are exact properties: no exception escapes ``engine.run``, the
termination reason carries the problem's own message, every recorded point lies in the
parameter window, a step below the floating-point resolution creates no point, a pole of the
amplitude is extrapolated to its known position.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import NoParameters
from pydantic import BaseModel

from nsm_continuation.core.lattice import LatticeContinuation, LatticeProblem, LatticeSeed
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import EvaluationError, Problem, StartPoint
from nsm_continuation.core.roots import pole_estimate
from nsm_continuation.core.settings import ContinuationSettings

SIM_MESSAGE = "simulation: time limit: no end condition reached by t = 1000 (state s6)"


class Circle(Problem):
    """x^2 + p^2 = 1, with hooks that can be told to raise at their k-th call."""

    name: ClassVar[str] = "circle"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, hook: str | None = None, k: int = 0, exc: Exception | None = None,
                 persistent: bool = False) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self.hook, self.k, self.exc, self.persistent = hook, k, exc, persistent
        self.calls: dict[str, int] = {}

    def _maybe_raise(self, hook: str) -> None:
        n = self.calls[hook] = self.calls.get(hook, 0) + 1
        if hook == self.hook and (n == self.k or (self.persistent and n >= self.k)):
            assert self.exc is not None
            raise self.exc

    def residual(self, y: Any) -> Any:
        return y[0] ** 2 + y[1] ** 2 - 1

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        self._maybe_raise("evaluate")
        return super().evaluate(y)

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        self._maybe_raise("jacobian")
        return super().jacobian(y)

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self._maybe_raise("evaluate_with_jacobian")
        return super().evaluate_with_jacobian(y)

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        self._maybe_raise("admissibility")
        return {"phi": 0.9 - float(y[1])}

    def derived(self, y: np.ndarray) -> dict[str, float]:
        self._maybe_raise("derived")
        return {"energy": float(y[0] ** 2)}

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> Any:
        self._maybe_raise("floquet")
        return None


class Line(Problem):
    """x = p; ``tests`` and ``derived`` given as functions of p (a missing name: None)."""

    name: ClassVar[str] = "line"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, tests=None, derived=None, fail_beyond: float | None = None) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self._tests, self._derived, self.fail_beyond = tests, derived, fail_beyond

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.fail_beyond is not None and y[1] > self.fail_beyond:
            raise EvaluationError(SIM_MESSAGE)
        return super().evaluate_with_jacobian(y)

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {} if self._tests is None else self._tests(float(y[1]))

    def derived(self, y: np.ndarray) -> dict[str, float]:
        return {} if self._derived is None else self._derived(float(y[1]))


class Pole(Problem):
    """x (p* - p) = 1: |x| grows like 1 / |p - p*| (a branch running to infinite amplitude,
    as the impacting chain's at a zero of w_N), p* = 2."""

    name: ClassVar[str] = "pole"
    Parameters: ClassVar[type[BaseModel]] = NoParameters
    P_STAR = 2.0

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"

    def residual(self, y: Any) -> Any:
        return y[0] * (self.P_STAR - y[1]) - 1


def _run(problem: Problem, y0, direction=1, **kw):
    settings = ContinuationSettings(**{"step_initial": 0.05, "step_max": 0.1, "max_points": 200,
                                       **kw})
    return ContinuationEngine(problem, settings).run(
        StartPoint(np.array(y0, float), "t", direction))


# ------------------------------------------------------------------ 1. no traceback, ever
HOOKS = ["evaluate", "jacobian", "evaluate_with_jacobian", "admissibility", "derived",
         "floquet"]


@pytest.mark.parametrize("hook", HOOKS)
@pytest.mark.parametrize("exc", [KeyError("x"), EvaluationError(SIM_MESSAGE),
                                 np.linalg.LinAlgError("singular"), RuntimeError("casadi"),
                                 ZeroDivisionError("division by zero")],
                         ids=["KeyError", "EvaluationError", "LinAlgError", "RuntimeError",
                              "ZeroDivisionError"])
@pytest.mark.parametrize("k", [1, 7, 40])
def test_no_exception_escapes_when_a_hook_raises_at_its_kth_call(hook, exc, k):
    problem = Circle(hook, k, exc)
    br = _run(problem, [1.0, 0.0], direction=0, param_min=-0.8, param_max=0.8)
    assert br.termination, "a termination reason is always recorded"
    reasons = " | ".join(br.termination.values())
    if "start" in br.termination:
        assert br.points == []
    else:
        assert br.points, reasons
        for p in br.points:
            assert abs(p.y[0] ** 2 + p.y[1] ** 2 - 1) < 1e-9
    if problem.calls.get(hook, 0) >= k:  # it did raise
        if type(exc) in (KeyError, RuntimeError):
            # a bug ends the half-branch (or the start), named with its type and message
            assert "internal error" in reasons and f"{type(exc).__name__}: {exc}" in reasons, \
                reasons


def test_bug_in_a_hook_ends_the_half_branch_and_keeps_its_points():
    problem = Circle("admissibility", 12, KeyError("x"))
    br = _run(problem, [1.0, 0.0], direction=1, param_max=0.95, step_max=0.05)
    assert br.termination["forward"] == "internal error: KeyError: 'x'"
    assert len(br.points) >= 5  # the points before the failure are kept
    assert all(abs(p.y[0] ** 2 + p.y[1] ** 2 - 1) < 1e-9 for p in br.points)


def test_transient_evaluation_error_is_a_failed_step_not_an_end():
    problem = Circle("evaluate_with_jacobian", 9, EvaluationError(SIM_MESSAGE))
    br = _run(problem, [1.0, 0.0], direction=1, param_max=0.8)
    assert br.termination["forward"] == "bound: p = max"
    assert br.points[-1].y[1] == 0.8


def test_evaluation_error_message_is_the_termination_reason():
    """Beyond p = 0.5 the problem cannot evaluate: the branch ends there with the problem's
    message, not 'non-finite residual'."""
    br = _run(Line(fail_beyond=0.5), [0.0, 0.0], direction=1, param_max=1.0)
    reason = br.termination["forward"]
    assert reason == f"step_below_minimum ({SIM_MESSAGE})", reason
    assert all(p.y[1] <= 0.5 for p in br.points)
    assert br.points[-1].y[1] > 0.5 - 1e-6


def test_evaluation_error_at_the_start_is_reported():
    br = _run(Line(fail_beyond=-1.0), [0.0, 0.0])
    assert br.points == [] and SIM_MESSAGE in br.termination["start"]


def test_hybrid_shooting_raises_the_simulators_message():
    """HybridShootingProblem.evaluate raises EvaluationError("simulation: <reason>") instead of
    returning NaN, and the engine records that reason."""
    from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem

    pb = ImpactOscillatorProblem({"integrator": {"max_return_time": 1e-3}})
    (start,) = pb.start_points({"guess": {n: 0.1 for n in pb.variables[:-1]}})
    with pytest.raises(EvaluationError, match="^simulation: time limit"):
        pb.evaluate(start.y)
    with pytest.raises(EvaluationError, match="^simulation: time limit"):
        pb.jacobian(start.y)
    d = pb.derived(start.y)  # the report still gets NaN
    assert np.isnan(d["period"])
    br = ContinuationEngine(pb, ContinuationSettings()).run(start)
    assert br.points == []
    assert "simulation: time limit" in br.termination["start"], br.termination


# ------------------------------------------------------------------ 2. missing names
def test_bound_on_a_derived_quantity_missing_at_some_points():
    """'energy' is missing from the derived values where p > 0.3 (a point the problem could
    not characterise): no KeyError, the bound is simply not tested there."""
    br = _run(Line(derived=lambda p: {"energy": p} if p <= 0.3 else {}), [0.0, 0.0],
              param_max=1.0, derived_bounds={"energy": (None, 0.5)})
    assert br.termination["forward"] == "bound: p = max"


def test_test_function_undefined_inside_a_step_is_located_not_a_keyerror():
    """The test 'tau' exists only where (p - 0.5)^2 > 1e-4 (like the sticking time, defined
    only while the orbit sticks); with steps of 0.1 its gap (0.49, 0.51) lies inside one step,
    both ends defined and positive. The engine locates where it ceases and where it is
    defined again (no KeyError)."""
    def tau(p: float) -> dict[str, float]:
        v = (p - 0.5) ** 2 - 1e-4
        return {"tau": v} if v > 0 else {}

    br = _run(Line(tests=tau), [0.0, 0.0], direction=1, param_max=1.0, step_initial=0.1,
              step_max=0.1, step_min=0.1)
    assert br.termination["forward"] == "bound: p = max"
    ev = sorted((e for e in br.events if e.data.get("test") == "tau"),
                key=lambda e: e.point.s)
    assert [e.data["defined_after"] for e in ev] == [False, True], [e.detail for e in ev]
    assert ev[0].point.y[1] == pytest.approx(0.49, abs=1e-5)
    assert ev[1].point.y[1] == pytest.approx(0.51, abs=1e-5)


def test_test_function_that_disappears_is_an_event():
    """A test that exists at one end of a step only (sticking lost) is reported where it
    ceases to exist (it does not vanish silently)."""
    br = _run(Line(tests=lambda p: {"tau": 0.3 - p} if p < 0.3 else {}), [0.0, 0.0],
              param_max=0.6)
    ev = [e for e in br.events if e.data.get("test") == "tau"]
    assert len(ev) == 1 and ev[0].data["defined_before"] and not ev[0].data["defined_after"]
    assert ev[0].point.y[1] == pytest.approx(0.3, abs=1e-5)


# ------------------------------------------------------------------ 3. window and events
@pytest.mark.parametrize("direction", [1, -1])
def test_huge_steps_never_leave_the_window(direction):
    """Steps far larger than the window: every point lies in it, the end point on its edge."""
    lo, hi = -0.3, 0.45
    br = _run(Circle(), [1.0, 0.0], direction=direction, param_min=lo, param_max=hi,
              step_initial=5.0, step_max=10.0)
    ps = [p.y[1] for p in br.points]
    assert all(lo <= p <= hi for p in ps), ps
    edge = hi if direction == 1 else lo
    assert ps[-1] == edge
    assert br.termination["forward"] == f"bound: p = {'max' if direction == 1 else 'min'}"
    assert all(abs(p.y[0] ** 2 + p.y[1] ** 2 - 1) < 1e-9 for p in br.points)


def test_huge_steps_on_the_paper_chain_stop_at_the_nonlinear_grazing_point():
    """Default case (5-dof chain, branch 1) with steps of 5..10: the grazing point B is
    located, as with small steps, and every point lies in the window (no point outside it
    labelled 'bound: T = min' past B)."""
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    pb = NDofImpactProblem({"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0})
    lo, hi = pb.parameter_bounds("omega", 1.0, 2.0)
    (start,) = pb.start_points({"mode": 1, "subharmonic": 1}, (lo, hi))
    ends = []
    for step in ({"step_initial": 0.01, "step_max": 0.05}, {"step_initial": 5.0,
                                                            "step_max": 10.0}):
        st = ContinuationSettings(**step, max_points=600, param_min=lo, param_max=hi,
                                  stop_on_inadmissible=True, max_angle=3.0)
        br = ContinuationEngine(pb, st).run(start)
        assert br.termination["forward"] == "grazing: admissibility lost ('clearance')"
        assert all(lo <= p.y[pb.parameter_index] <= hi for p in br.points)
        ends.append(br.points[-1].y[pb.parameter_index])
    assert ends[1] == pytest.approx(ends[0], abs=1e-9)


@pytest.mark.parametrize("step_max", [1.0, 10.0])
def test_steps_do_not_jump_over_a_zero_pair_of_a_test_function(step_max):
    """phi = ((p - 0.6) / 0.1)^4 - 1e-4 is negative only on (0.59, 0.61): with large steps one
    step jumped the whole dip (positive at both ends, and the parabola through three samples of
    a quartic stays positive); the steps are capped by phi's secant so both zeros are found."""
    br = _run(Line(tests=lambda p: {"phi": ((p - 0.6) / 0.1) ** 4 - 1e-4}), [0.0, 0.0],
              param_max=1.0, step_initial=0.05, step_max=step_max)
    graz = sorted(e.point.y[1] for e in br.events if e.kind == "grazing")
    assert graz == pytest.approx([0.59, 0.61], abs=1e-9)


class Band(Line):
    """x = p, but the residual cannot be evaluated (NaN) for 0.1 < p < 3."""

    name: ClassVar[str] = "band"

    def residual(self, y: Any) -> Any:
        return y[0] - y[1] + ca.if_else(ca.logic_and(y[1] > 0.1, y[1] < 3.0), np.nan, 0)


def test_no_bound_reported_off_the_bound():
    """A step of 5 from p = 0 would land at p = 3.5, beyond the window edge 0.5 and beyond a
    band where the problem cannot evaluate, where the bound cannot be located (and a point at
    p < 0.1 would be recorded as 'bound: p = max'). The step is capped at the edge, and the
    branch ends where the problem stops evaluating, with that reason."""
    br = _run(Band(), [0.0, 0.0], param_max=0.5, step_initial=5.0, step_max=10.0)
    reason = br.termination["forward"]
    ps = [p.y[1] for p in br.points]
    assert reason == "step_below_minimum (non-finite residual)", (reason, ps)
    assert all(0.0 <= p <= 0.1 for p in ps)
    assert ps[-1] == pytest.approx(0.1, abs=1e-6)


# ------------------------------------------------------------------ 4. degenerate steps
def test_step_below_resolution_creates_no_point():
    br = _run(Circle(), [1.0, 0.0], step_initial=1e-300, step_min=1e-300, step_max=1e-300)
    assert len(br.points) == 1
    assert br.termination["forward"].startswith("step_below_resolution")


def test_step_min_below_resolution_ends_at_resolution():
    """Newton fails everywhere beyond p = 0.5; halving from step_min = 1e-300 would create
    identical points for ever: the branch ends at the resolution, with the real cause."""
    br = _run(Line(fail_beyond=0.5), [0.0, 0.0], param_max=1.0, step_min=1e-300)
    reason = br.termination["forward"]
    assert reason.startswith("step_below_resolution") and SIM_MESSAGE in reason, reason
    ys = np.array([p.y for p in br.points])
    assert np.all(np.any(np.diff(ys, axis=0) != 0, axis=1))  # no two identical points


# ------------------------------------------------------------------ 5. asymptote
def test_runaway_to_infinite_amplitude_ends_with_located_asymptote():
    br = _run(Pole(), [1.0, 1.0], direction=1, step_max=1.0, max_points=400)
    assert br.termination["forward"].startswith("asymptote"), br.termination
    (ev,) = [e for e in br.events if e.kind == "asymptote"]
    assert ev.data["parameter_asymptote"] == pytest.approx(Pole.P_STAR, abs=1e-6)
    assert ev.data["exponent"] == pytest.approx(1.0, abs=1e-3)
    assert len(br.points) < 200  # not every point spent near the pole


def test_no_asymptote_on_bounded_or_power_growth():
    """|y| growing like a power of p (no finite pole) or a user energy bound: no asymptote."""
    br = _run(Line(), [1.0, 1.0], direction=1, step_max=5.0, max_points=400, param_max=100.0)
    assert br.termination["forward"] == "bound: p = max"
    br = _run(Pole(), [1.0, 1.0], direction=1, step_max=1.0, max_points=60,
              derived_bounds={"energy": (None, 1e30)})
    assert not [e for e in br.events if e.kind == "asymptote"]


def test_pole_estimate_exact_on_a_power_law():
    p = 3.0 - np.geomspace(0.5, 0.01, 7)
    for k in (0.5, 1.0, 2.0, 3.0):
        est = pole_estimate(p, 4.0 * (3.0 - p) ** -k)
        assert est is not None
        assert est["parameter_asymptote"] == pytest.approx(3.0, abs=1e-6)
        assert est["exponent"] == pytest.approx(k, rel=0.03)
    assert pole_estimate(p, np.exp(p)) is None  # exponential growth: no finite pole


# ------------------------------------------------------------------ lattice engine
class _BadLattice(LatticeProblem):
    name: ClassVar[str] = "bad_lattice"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, exc: Exception) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self.exc = exc

    def lattice_seeds(self, start, window, energy_cap=None):
        return [LatticeSeed(0, "seed")]

    def lattice_next(self, history, direction, window):
        if len(history) >= 4:
            raise self.exc
        return history[-1] + direction, ""

    def lattice_point(self, sol):
        return np.array([float(sol), float(sol)]), {}, {"energy": 1.0}


@pytest.mark.parametrize("exc, reason", [
    (EvaluationError(SIM_MESSAGE), SIM_MESSAGE),
    (KeyError("x"), "internal error: KeyError: 'x'"),
])
def test_lattice_engine_never_raises(exc, reason):
    pr = _BadLattice(exc)
    (seed,) = pr.lattice_seeds(None, (None, None))
    br = LatticeContinuation(pr, ContinuationSettings(max_points=50)).run(seed)
    assert set(br.termination.values()) == {reason}
    assert [p.y[1] for p in br.points] == [-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0]

