"""Events located on their true condition, and steps that slow only near one.

Oracles (closed forms, or a second method):

* multiplier crossings of 2-d map families whose fixed points and multipliers are known in
  closed form (the residual is exact CasADi, the multipliers are the eigenvalues of the exact
  Jacobian of the map): a real multiplier ``-exp(mu - mu*)`` through -1 (period doubling), the
  limit point of ``mu = x1^2`` where the multiplier ``1 - 2 x1`` passes +1 (fold), and the
  rotation-scaling pair ``exp(mu - mu*) e^{+-i theta}`` (Neimark-Sacker); the flip of the
  bundled two-mass chain against Brent's root of ``lambda(omega) + 1`` on orbits solved at fixed
  ``omega`` (a second method: no arclength, no engine);
* a conservative collision (a pair on the circle meets at -1 and splits along the real axis):
  ``|lambda| - 1`` has no sign change, the count's location is kept and said so;
* branch points: ``det[G_y; t^T]`` keeps its sign along a curve with a full-rank Jacobian
  whatever the direction (no branch point at a start), and the simple branch points of
  ``x (mu - x) = 0`` and ``x (x^2 - mu) = 0`` are at ``mu = 0``;
* multiplier motion: the true displacement of a multiplier through ``|lambda| = 0.5``; a family
  whose multiplier moves from 0.3 to 0.7 takes as many points as one whose multiplier stays at
  0.3; the Neimark-Sacker window 8.6e-4 wide of Fig. 6.1 (docs/results.md: [1.503588,
  1.504449], found identically with a 4x finer motion limit) is still found;
* event functions: the zeros of ``cos(4 p)`` at ``pi/8`` and ``3 pi/8``, a zero pair 0.02 apart
  inside one huge step, and no event where a value is missing or NaN.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import CASES, NoParameters
from pydantic import BaseModel

from nsm_continuation.core.monitors import Monitors, event_function
from nsm_continuation.core.palc import ContinuationEngine, multiplier_motion
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint
from nsm_continuation.core.records import Branch, Event
from nsm_continuation.core.settings import ContinuationSettings


def _run(problem: Problem, y0: Any, direction: int = 1, start_direction: int | None = None,
         **kw: Any) -> Branch:
    """Continue from ``y0``; ``direction`` is the settings' direction (YAML
    ``continuation.direction``) unless ``start_direction`` is given (the start's own)."""
    if start_direction is None:
        settings = ContinuationSettings(direction=direction, **kw)
        start = StartPoint(np.asarray(y0, dtype=float), "t")
    else:
        settings = ContinuationSettings(**kw)
        start = StartPoint(np.asarray(y0, dtype=float), "t", start_direction)
    return ContinuationEngine(problem, settings).run(start)


# ======================================================================== 1. multipliers
MU_STAR = float(np.sqrt(2.0) - 1.0)  # the crossing parameter of the map families
THETA = 0.9                          # angle of the Neimark-Sacker pair
V = np.array([[1.0, 0.5], [0.2, 1.0]])


class MapFamily(Problem):
    """Fixed points of ``F(x; mu) = c(mu) + A(mu) z + (z1 z2, z1^2)``, ``z = x - c(mu)``: the
    fixed points are ``x = c(mu) = (sin mu, mu^2 / 2)`` and ``DF`` there is ``A(mu)`` (the
    quadratic term has no linear part), with

    * ``period_doubling``: ``A = V diag(-exp(mu - mu*), 0.4) V^-1``, a real multiplier through
      -1 at ``mu*`` (slope -1);
    * ``neimark_sacker``: ``A = exp(mu - mu*) R(theta)``, the pair ``exp(mu - mu*) e^{+-i
      theta}`` through the circle at ``mu*``.

    ``G = F - x`` has ``G_x = A - I`` invertible (no multiplier is +1): a regular curve.
    """

    name: ClassVar[str] = "map_family"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, kind: str) -> None:
        super().__init__(NoParameters())
        self.variables = ["x1", "x2", "mu"]
        self.parameter = "mu"
        self.kind = kind
        x, mu = ca.SX.sym("x", 2), ca.SX.sym("mu")
        self._DF = ca.Function("DF", [x, mu], [ca.jacobian(self.map(x, mu), x)])

    @staticmethod
    def c(mu: Any) -> Any:
        return ca.vertcat(ca.sin(mu), mu ** 2 / 2)

    def A(self, mu: Any) -> Any:
        if self.kind == "period_doubling":
            D = ca.diag(ca.vertcat(-ca.exp(mu - MU_STAR), 0.4))
            return ca.mtimes([ca.DM(V), D, ca.DM(np.linalg.inv(V))])
        r = ca.exp(mu - MU_STAR)
        return r * ca.DM([[np.cos(THETA), -np.sin(THETA)], [np.sin(THETA), np.cos(THETA)]])

    def map(self, x: Any, mu: Any) -> Any:
        z = x - self.c(mu)
        return self.c(mu) + ca.mtimes(self.A(mu), z) + ca.vertcat(z[0] * z[1], z[0] ** 2)

    def residual(self, y: Any) -> Any:
        return self.map(y[:2], y[2]) - y[:2]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData:
        DF = np.asarray(self._DF(y[:2], y[2]), dtype=float)
        return FloquetData(np.linalg.eigvals(DF).astype(complex),
                           matrix_norm=float(np.linalg.norm(DF, 2)))


class FoldMap(Problem):
    """``F(x; mu) = (x1 + mu - x1^2, x2 / 2 + x1^2 / 10)``: fixed points ``mu = x1^2``,
    ``x2 = x1^2 / 5``, a limit point at ``x = 0, mu = 0`` where the multiplier ``1 - 2 x1``
    passes +1 (the other is 1/2): unstable for ``x1 < 0``, stable for ``x1 > 0``."""

    name: ClassVar[str] = "fold_map"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["x1", "x2", "mu"]
        self.parameter = "mu"
        x, mu = ca.SX.sym("x", 2), ca.SX.sym("mu")
        self._DF = ca.Function("DF", [x, mu], [ca.jacobian(self.map(x, mu), x)])

    @staticmethod
    def map(x: Any, mu: Any) -> Any:
        return ca.vertcat(x[0] + mu - x[0] ** 2, x[1] / 2 + x[0] ** 2 / 10)

    def residual(self, y: Any) -> Any:
        return self.map(y[:2], y[2]) - y[:2]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData:
        DF = np.asarray(self._DF(y[:2], y[2]), dtype=float)
        return FloquetData(np.linalg.eigvals(DF).astype(complex),
                           matrix_norm=float(np.linalg.norm(DF, 2)))


def _crossings(br: Branch, kind: str) -> list[Event]:
    return [e for e in br.events if e.kind == kind and "located_on" in e.data]


@pytest.mark.parametrize("unit_circle_tol", [None, 1e-4])
@pytest.mark.parametrize("kind", ["period_doubling", "neimark_sacker"])
def test_map_crossing_located_on_the_circle(kind: str, unit_circle_tol: float | None) -> None:
    """Default settings (and a coarse detector, tol 1e-4): the crossing is at ``mu*`` to
    1e-10, on the family, with ``|lambda_c| = 1``; the count alone put it at ``|lambda| = 1 +
    tol``, i.e. ``mu* + tol`` (1e-7 off with the default tol)."""
    pb = MapFamily(kind)
    mu0 = MU_STAR - 0.3
    y0 = [np.sin(mu0), mu0 ** 2 / 2, mu0]
    kw = {} if unit_circle_tol is None else {"unit_circle_tol": unit_circle_tol}
    br = _run(pb, y0, param_max=MU_STAR + 0.3, **kw)
    assert br.termination["forward"] == "bound: mu = max"
    (ev,) = _crossings(br, kind)
    (sc,) = [e for e in br.events if e.kind == "stability_change"]
    assert sc.point is ev.point and sc.data["stable_before"] and not sc.data["stable_after"]
    mu = ev.point.y[2]
    assert ev.data["located_on"] == "multiplier_modulus"
    assert abs(mu - MU_STAR) < 1e-10, mu - MU_STAR
    assert np.abs(ev.point.y[:2] - [np.sin(mu), mu ** 2 / 2]).max() < 1e-12
    assert abs(ev.data["modulus_minus_one"]) < 1e-10
    lam = complex(*ev.data["critical_multiplier"])
    if kind == "period_doubling":
        assert abs(lam + 1.0) < 1e-10
    else:
        assert abs(abs(np.angle(lam)) - THETA) < 1e-10


def test_fold_multiplier_through_plus_one_at_the_limit_point() -> None:
    br = _run(FoldMap(), [-0.5, 0.05, 0.25], start_direction=-1, param_max=0.3)
    (ev,) = _crossings(br, "fold")
    assert ev.data["located_on"] == "multiplier_modulus"
    assert ev.data["stable_after"] and not ev.data["stable_before"]
    x1, x2, mu = ev.point.y
    assert abs(x1) < 1e-10 and abs(mu) < 1e-10 and abs(x2 - x1 ** 2 / 5) < 1e-12
    assert abs(complex(*ev.data["critical_multiplier"]) - 1.0) < 1e-10
    # the limit point in the parameter (the tangent test) is the same point
    (lp,) = [e for e in br.events if e.kind == "fold" and e.data.get("test") == "tangent"]
    assert abs(lp.point.y[0]) < 1e-10


class Line(Problem):
    """``x = p``; multipliers, admissibility tests and event functions given as functions of
    ``p`` (a function returning None: the name is missing there)."""

    name: ClassVar[str] = "line"
    Parameters: ClassVar[type[BaseModel]] = NoParameters
    event_kinds: ClassVar[dict[str, str]] = {
        "fidelity_test_crossing": "an event function of the event-fidelity tests vanishes"}
    monitors: ClassVar[Monitors] = Problem.monitors.with_(
        event_function("g", "fidelity_test_crossing"))

    def __init__(self, mult: Any = None, tests: Any = None, functions: Any = None) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self._mult, self._tests, self._functions = mult, tests, functions

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        if self._mult is None:
            return None
        return FloquetData(np.asarray(self._mult(float(y[1])), dtype=complex))

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {} if self._tests is None else self._tests(float(y[1]))

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        if self._functions is None:
            return {}
        values = {k: f(float(y[1])) for k, f in self._functions.items()}
        return {k: v for k, v in values.items() if v is not None}


def test_conservative_collision_keeps_the_count_location() -> None:
    """A pair on the circle collides at -1 at p* = 0.2 and splits as (-r, -1/r), r =
    exp(sqrt(p - p*)): ``|lambda| - 1`` is 0 on the whole stable side (no sign change), the
    event is located by the count, whose threshold ``|lambda| = 1 + tol`` lies (tol)^2 = 1e-14
    past the collision: accurate to the bisection tolerance."""
    p_star = 0.2

    def mult(p: float) -> list[complex]:
        d = p - p_star
        if d < 0:
            z = np.exp(1j * (np.pi - np.sqrt(-d)))
            return [z, np.conj(z), 0.5]
        r = np.exp(np.sqrt(d))
        return [-r, -1 / r, 0.5]

    br = _run(Line(mult=mult), [0.0, 0.0], param_max=0.5)
    (ev,) = _crossings(br, "period_doubling")
    assert ev.data["located_on"] == "count"
    tol = ContinuationSettings().multiplier_event_tol
    assert 0.0 <= ev.point.y[1] - p_star < tol


def test_two_mass_chain_flip_against_fixed_frequency_root() -> None:
    """Second method: orbits solved by Newton at fixed omega, the multiplier closest to -1
    followed by Brent's method to round-off, vs. the flip the engine locates on the branch
    (continued with default settings from omega = 0.686). The count alone was 5e-9 off."""
    from nsm_continuation.problems.impacting.two_mass_chain import TwoMassChainProblem
    from scipy.optimize import brentq

    pb = TwoMassChainProblem({"m1": 1.0, "m2": 1.0, "k1": 1.0, "k2": 1.0, "c": 0.05,
                              "F0": 0.5, "gap": 0.5, "restitution": 0.8, "omega": 0.69})
    y = pb.start_points({"transient": 40})[0].y.copy()

    def solve(omega: float) -> np.ndarray:
        y[-1] = omega
        for _ in range(20):
            g, J = pb.evaluate_with_jacobian(y)
            dy = np.linalg.solve(J[:, :-1], -g)
            y[:-1] += dy
            if np.abs(dy).max() < 1e-15 * (1 + np.abs(y).max()):
                break
        return y.copy()

    def flip(omega: float) -> float:
        mu = pb.floquet(solve(omega), None).multipliers
        return float(-mu[np.abs(mu.imag) < 1e-12].real.min() - 1.0)

    omega_star = brentq(flip, 0.69, 0.695, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    assert abs(flip(omega_star)) < 1e-12
    br = _run(pb, solve(0.686), start_direction=1, param_min=0.685, param_max=0.70)
    (ev,) = _crossings(br, "period_doubling")
    assert ev.data["located_on"] == "multiplier_modulus"
    assert abs(ev.point.y[-1] - omega_star) < 1e-10, ev.point.y[-1] - omega_star


# ======================================================================== 2. branch points
class _Curve(Problem):
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "mu"]
        self.parameter = "mu"


class Transcritical(_Curve):
    """``x (mu - x) = 0``: the branches x = 0 and x = mu cross at mu = 0."""

    name: ClassVar[str] = "transcritical"

    def residual(self, y: Any) -> Any:
        return y[0] * (y[1] - y[0])


class Pitchfork(_Curve):
    """``x^3 - mu x = 0``: the branch x = 0 meets x^2 = mu at mu = 0."""

    name: ClassVar[str] = "pitchfork"

    def residual(self, y: Any) -> Any:
        return y[0] ** 3 - y[1] * y[0]


class Circle(_Curve):
    """``x^2 + mu^2 = 1``: full-rank Jacobian everywhere on the curve, no branch point."""

    name: ClassVar[str] = "circle_bp"

    def residual(self, y: Any) -> Any:
        return y[0] ** 2 + y[1] ** 2 - 1


@pytest.mark.parametrize("how", ["settings", "start"])
@pytest.mark.parametrize("direction", [1, -1, 0])
def test_no_branch_point_at_the_start(direction: int, how: str) -> None:
    """A curve whose Jacobian has full rank everywhere has no branch point, whatever the
    direction: det[G_y; t^T] keeps its sign along each half-branch, and the start is no branch
    point, also when ``direction: decrease`` reverses the tangent."""
    kw: dict[str, Any] = ({"direction": direction} if how == "settings"
                          else {"start_direction": direction})
    if how == "start" and direction == 0:
        kw = {"start_direction": 0}
    br = _run(Circle(), [np.sqrt(1 - 0.04), 0.2], param_min=-0.8, param_max=0.8, **kw)
    assert not [e for e in br.events if e.kind == "branch_point"], [
        (e.kind, e.point.y) for e in br.events]
    mus = [p.y[1] for p in br.points]
    if direction == 1:
        assert min(mus) == 0.2 and max(mus) == 0.8
    elif direction == -1:
        assert max(mus) == 0.2 and min(mus) == -0.8
    else:
        assert min(mus) == -0.8 and max(mus) == 0.8
    # each half-branch (backward: negative arclength) keeps one sign (its tangents are
    # oriented continuously along its own direction of travel)
    halves = [[p for p in br.points if p.s >= 0], [p for p in br.points if p.s < 0]]
    assert len(halves[0]) > 5
    for half in halves:
        signs = {np.sign(p.bordered_det) for p in half}
        assert len(signs) <= 1, signs


@pytest.mark.parametrize("problem", [Transcritical(), Pitchfork()], ids=["trans", "pitch"])
@pytest.mark.parametrize("direction", [1, -1])
def test_simple_branch_point_located_at_zero(problem: Problem, direction: int) -> None:
    br = _run(problem, [0.0, 0.5 * -direction], direction=direction, param_min=-0.5,
              param_max=0.5)
    bps = [e for e in br.events if e.kind == "branch_point"]
    assert len(bps) == 1, [e.point.y for e in bps]
    assert abs(bps[0].point.y[1]) < 1e-10 and abs(bps[0].point.y[0]) < 1e-12


# ======================================================================== 3. step control
def test_multiplier_motion_is_the_displacement_through_the_annulus_edge() -> None:
    """A multiplier moving from 0.49 to 0.51 moves by 0.02, not by its distance to the other
    multiplier in the annulus (0.39: the Hausdorff distance of the restricted sets)."""
    a, b = np.array([0.49, 0.9]), np.array([0.51, 0.9])
    assert multiplier_motion(a, b) == pytest.approx(0.02, abs=1e-15)
    assert multiplier_motion(b, a) == pytest.approx(0.02, abs=1e-15)
    assert multiplier_motion(np.array([2.05, 0.9]), np.array([1.95, 0.9])) == pytest.approx(
        0.1, abs=1e-15)
    # outside the annulus at both ends: not watched
    assert multiplier_motion(np.array([0.1, 0.9]), np.array([0.3, 0.9])) == 0.0
    # inside it: the displacement of the pair
    z = np.exp(1j * np.array([1.0, -1.0]))
    assert multiplier_motion(z, z * np.exp(0.03j)) == pytest.approx(2 * np.sin(0.015),
                                                                    rel=1e-12)


def test_multiplier_through_half_does_not_collapse_the_step() -> None:
    """``|lambda|`` from 0.3 to 0.7 (0.1 per unit p: 0.014 per step of 0.2, below the motion
    limit 0.02) costs as many points as a multiplier that stays at 0.3."""
    pair = [0.9 * np.exp(1j), 0.9 * np.exp(-1j)]
    moving = _run(Line(mult=lambda p: [0.3 + 0.1 * p, *pair]), [0.0, 0.0], param_max=4.0)
    static = _run(Line(mult=lambda p: [0.3, *pair]), [0.0, 0.0], param_max=4.0)
    for br in (moving, static):
        assert br.termination["forward"] == "bound: p = max"
    assert len(moving.points) <= len(static.points) + 2, (len(moving.points),
                                                          len(static.points))


def test_narrow_neimark_sacker_window_of_fig_6_1_is_found() -> None:
    """Fig. 6.1 (5-dof chain, branch 1): the complex-pair window [1.503588, 1.504449], 8.6e-4
    wide in omega, hides inside a step when multipliers may move 0.05 per step; the default
    limit 0.02 finds it, at the omega a 4x finer limit (0.005) gives (docs/results.md table)."""

    from nsm_continuation import cases
    from nsm_continuation.runs.runner import run_case

    path = CASES / "ndof_fig6_1_stability.yaml"
    case, problem = cases.load(path)
    res = run_case(case, problem, progress=False)
    ns = [ev.point.derived["omega"] for ev in res.branches[0].events
          if ev.kind == "neimark_sacker"]
    assert min(abs(w - 1.503588) for w in ns) < 1e-6, ns
    assert min(abs(w - 1.504449) for w in ns) < 1e-6, ns


# ======================================================================== 4. event functions
def test_event_function_zeros_located_and_branch_goes_on() -> None:
    """``g = cos(4 p)`` vanishes at pi/8 and 3 pi/8 (kind declared by the problem), ``h = 0.7
    - p`` at 0.7 (default kind grazing): located to 1e-10 with default settings, and the branch
    reaches its bound (an event function never ends it)."""
    pb = Line(functions={"g": lambda p: np.cos(4 * p), "h": lambda p: 0.7 - p})
    br = _run(pb, [0.0, 0.0], param_max=1.5)
    assert br.termination["forward"] == "bound: p = max"
    g = sorted((e for e in br.events if e.data.get("function") == "g"),
               key=lambda e: e.point.s)
    assert [e.kind for e in g] == ["fidelity_test_crossing"] * 2
    assert np.abs([e.point.y[1] for e in g] - np.array([np.pi / 8, 3 * np.pi / 8])).max() \
        < 1e-10
    assert g[0].data["value_before"] > 0 > g[0].data["value_after"]
    assert g[1].data["value_before"] < 0 < g[1].data["value_after"]
    (h,) = [e for e in br.events if e.data.get("function") == "h"]
    assert h.kind == "grazing" and abs(h.point.y[1] - 0.7) < 1e-10
    assert all(p.event_values.keys() == {"g", "h"} for p in br.points)


@pytest.mark.parametrize("step_max", [1.0, 10.0])
def test_steps_do_not_jump_over_a_zero_pair_of_an_event_function(step_max: float) -> None:
    """``g = ((p - 0.6) / 0.1)^4 - 1e-4`` is negative only on (0.59, 0.61): a huge step would
    jump the dip (positive at both ends; the parabola through three samples of a quartic stays
    positive); the step cap of the tests applies to event functions too."""
    pb = Line(functions={"g": lambda p: ((p - 0.6) / 0.1) ** 4 - 1e-4})
    br = _run(pb, [0.0, 0.0], param_max=1.0, step_initial=0.05, step_max=step_max)
    zeros = sorted(e.point.y[1] for e in br.events if e.data.get("function") == "g")
    assert zeros == pytest.approx([0.59, 0.61], abs=1e-9)


@pytest.mark.parametrize("undefined", [None, np.nan])
def test_event_function_missing_or_nan_at_one_end_raises_nothing(undefined: Any) -> None:
    """``g = p - 0.5`` is defined (negative) only for p < 0.45: no sign change is ever seen
    between two defined values, so no event, whether it is missing or NaN beyond."""
    pb = Line(functions={"g": lambda p: p - 0.5 if p < 0.45 else undefined})
    br = _run(pb, [0.0, 0.0], param_max=1.0)
    assert br.termination["forward"] == "bound: p = max"
    assert not [e for e in br.events if e.data.get("function") == "g"]
    assert any(p.y[1] < 0.45 for p in br.points) and any(p.y[1] > 0.45 for p in br.points)


def test_event_function_and_test_vanishing_together_are_one_grazing_event() -> None:
    pb = Line(tests=lambda p: {"phi": 0.3 - p}, functions={"h": lambda p: p - 0.3})
    br = _run(pb, [0.0, 0.0], param_max=0.6)
    graz = [e for e in br.events if e.kind == "grazing"]
    assert len(graz) == 1 and graz[0].data["tests"] == ["h", "phi"]
    assert abs(graz[0].point.y[1] - 0.3) < 1e-10
