"""The generic continuation engine on toy problems with analytic answers (no impacts involved).

Oracles: the fold of a circle at p = +-1, the branch point of a pitchfork at p = 0, multipliers
prescribed as functions of the parameter (crossings at known parameter values), a test function
with a hidden double zero inside one step, a residual that becomes NaN.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from helpers import NoParameters
from pydantic import BaseModel

from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint
from nsm_continuation.core.settings import ContinuationSettings


class _Toy(Problem):
    """One unknown x and the parameter p."""

    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"


class Circle(_Toy):
    """x^2 + p^2 = 1: folds (limit points in p) at (0, +-1)."""

    name: ClassVar[str] = "circle"

    def residual(self, y: Any) -> Any:
        return y[0] ** 2 + y[1] ** 2 - 1


class Pitchfork(_Toy):
    """x (x^2 - p) = 0: the trivial branch x = 0 has a branch point at p = 0."""

    name: ClassVar[str] = "pitchfork"

    def residual(self, y: Any) -> Any:
        return y[0] * (y[0] ** 2 - y[1])


class Line(Problem):
    """x = p, with multipliers and a test function given as functions of p."""

    name: ClassVar[str] = "line"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, mult=None, test=None) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self._mult = mult
        self._test = test

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        if self._mult is None:
            return None
        return FloquetData(np.asarray(self._mult(float(y[1])), dtype=complex))

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {} if self._test is None else {"phi": float(self._test(float(y[1])))}


class NaNBeyond(_Toy):
    """x = p for p < 1, NaN residual beyond: the branch must end with a recorded reason."""

    name: ClassVar[str] = "nan_beyond"

    def residual(self, y: Any) -> Any:
        return y[0] - y[1] + ca.if_else(y[1] > 1, np.nan, 0)


def _run(problem: Problem, y0, direction=1, **kw):
    settings = ContinuationSettings(**{"step_initial": 0.05, "step_max": 0.1, "max_points": 200,
                                       **kw})
    return ContinuationEngine(problem, settings).run(StartPoint(np.array(y0, float), "t",
                                                                direction))


def test_circle_folds_located_and_passed():
    br = _run(Circle(), [1.0, 0.0], direction=1, max_points=150)
    folds = [e for e in br.events if e.kind == "fold"]
    assert len(folds) >= 2, [e.kind for e in br.events]
    ps = sorted(abs(e.point.y[1]) for e in folds)
    # the limit point in p is (x, p) = (0, +-1)
    for e in folds:
        assert abs(abs(e.point.y[1]) - 1.0) < 1e-12
        assert abs(e.point.y[0]) < 1e-6
    assert ps[0] > 0.999
    # points stay on the circle (the corrector passes the folds)
    for p in br.points:
        assert abs(p.y[0] ** 2 + p.y[1] ** 2 - 1) < 1e-10


def test_pitchfork_branch_point_located():
    br = _run(Pitchfork(), [0.0, -0.5], direction=1, param_max=0.5)
    bps = [e for e in br.events if e.kind == "branch_point"]
    assert len(bps) == 1
    assert abs(bps[0].point.y[1]) < 1e-10
    assert br.termination["forward"].startswith("bound")
    assert abs(br.points[-1].y[1] - 0.5) < 1e-12  # endpoint located at the bound


# a real multiplier through +1 where the parameter does not turn (the line x = p) is a branch
# point, not a fold (the fold is the tangent test's: test_circle_folds_located_and_passed)
@pytest.mark.parametrize("mult, kind, p_star", [
    (lambda p: [1.0 + p, 0.5], "branch_point", 0.1),
    (lambda p: [-(1.0 + p), 0.5j, -0.5j], "period_doubling", 0.1),
    (lambda p: [(1 + p) * np.exp(0.7j), (1 + p) * np.exp(-0.7j), 0.5], "neimark_sacker", 0.1),
])
def test_multiplier_crossings_classified_and_located(mult, kind, p_star):
    problem = Line(mult=lambda p: mult(p - p_star))
    br = _run(problem, [-0.3, -0.3], direction=1, param_max=0.6)
    ev = [e for e in br.events if e.kind == kind]
    sc = [e for e in br.events if e.kind == "stability_change"]
    assert len(ev) == 1 and len(sc) == 1
    # detected by the count outside |lambda| = 1 + tol (which sits at p_star + tol), located
    # on |lambda_c| = 1: at p_star itself
    assert ev[0].data["located_on"] == "multiplier_modulus"
    assert abs(ev[0].point.y[1] - p_star) < 1e-10
    assert abs(ev[0].data["modulus_minus_one"]) < 1e-10
    assert sc[0].data["stable_before"] is True and sc[0].data["stable_after"] is False


def test_hidden_double_crossing_inside_one_step_is_found():
    """phi = (p - 0.5)^2 - 1e-4 is negative only on (0.49, 0.51); with steps of 0.1 both ends
    of the step around p = 0.5 are positive: the parabola check must find both crossings."""
    problem = Line(test=lambda p: (p - 0.5) ** 2 - 1e-4)
    br = _run(problem, [0.0, 0.0], direction=1, param_max=1.0, step_initial=0.1, step_max=0.1,
              step_min=0.1)
    graz = sorted(e.point.y[1] for e in br.events if e.kind == "grazing")
    assert len(graz) == 2, graz
    assert abs(graz[0] - 0.49) < 1e-10 and abs(graz[1] - 0.51) < 1e-10


def test_stop_on_inadmissible_ends_branch_at_grazing():
    problem = Line(test=lambda p: 0.3 - p)
    br = _run(problem, [0.0, 0.0], direction=1, param_max=1.0, stop_on_inadmissible=True)
    assert br.termination["forward"].startswith("grazing")
    assert abs(br.points[-1].y[1] - 0.3) < 1e-11


def test_nan_residual_ends_with_reason_not_exception():
    br = _run(NaNBeyond(), [0.0, 0.0], direction=1, max_points=100)
    reason = br.termination["forward"]
    assert reason.startswith("step_below_minimum"), reason
    assert all(np.isfinite(p.y).all() for p in br.points)
    assert br.points[-1].y[1] <= 1.0 + 1e-9


def test_start_that_does_not_converge_is_recorded():
    br = _run(Circle(), [np.nan, 0.0])
    assert br.points == [] and "start" in br.termination


def test_both_directions_merge_with_signed_arclength():
    """A branch run both ways is ordered by arclength: negative backwards, each event at the
    arclength of its point (no point negated twice)."""
    br = _run(Line(test=lambda p: 0.25 - abs(p)), [0.0, 0.0], direction=0, param_max=0.5,
              param_min=-0.5)
    s = np.array([p.s for p in br.points])
    assert np.all(np.diff(s) > 0) and s[0] < 0 < s[-1]
    for ev in br.events:
        assert np.sign(ev.point.s) == np.sign(ev.point.y[1]), (ev.kind, ev.point.s, ev.point.y)
    ends = sorted(ev.point.y[1] for ev in br.events if ev.kind == "endpoint")
    assert ends == pytest.approx([-0.5, 0.5], abs=1e-12)
    graz = sorted(ev.point.y[1] for ev in br.events if ev.kind == "grazing")
    assert graz == pytest.approx([-0.25, 0.25], abs=1e-11)


# ---------------------------------------------------------------------------------------------
# Krein-aware step control: a synthetic conservative family
# ---------------------------------------------------------------------------------------------
class KreinPair(Problem):
    """x = p with two multiplier pairs of a symplectic 4-d map, prescribed in closed form:
    ``exp(+-i theta_1)``, ``theta_1 = 1.5 + c (p - 1)``, and ``exp(+-i theta_2)``, ``theta_2 =
    1.5 - c (p - 1)``, crossing at ``p = 1``. With ``opposite`` the upper multipliers have
    opposite Krein signatures and the crossing is a Krein collision opening a window
    ``|p - 1| < w``: ``theta_(1,2) = 1.5 +- c sqrt((p - 1)^2 - w^2)`` outside it, and the
    quadruple ``exp(1.5 i +- c sqrt(w^2 - (p - 1)^2))`` (and conjugates) inside it. The Krein
    definiteness of each upper multiplier is ``+-sqrt((p-1)^2 - w^2)/|p - 1|`` (-> 0 at the
    collision), of its conjugate the opposite; without ``opposite`` both upper ones are +1 and
    pass through each other. ``conservative`` is the declared capability the engine reads."""

    name: ClassVar[str] = "krein_pair"
    Parameters: ClassVar[type[BaseModel]] = NoParameters
    conservative = True

    def __init__(self, opposite: bool, w: float = 1e-3, c: float = 1.0,
                 krein: bool = True) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self.opposite, self.w, self.c, self.krein = opposite, w, c, krein

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        from nsm_continuation.core.floquet import KreinFloquetData

        d = float(y[1]) - 1.0
        if not self.opposite:
            z1, z2 = np.exp(1j * (1.5 + self.c * d)), np.exp(1j * (1.5 - self.c * d))
            m = np.array([z1, np.conj(z1), z2, np.conj(z2)])
            k = np.array([1.0, -1.0, 1.0, -1.0])
        elif d * d >= self.w**2:
            r = np.sqrt(d * d - self.w**2)
            z1, z2 = np.exp(1j * (1.5 + self.c * r)), np.exp(1j * (1.5 - self.c * r))
            kk = r / abs(d)
            m = np.array([z1, np.conj(z1), z2, np.conj(z2)])
            k = np.array([kk, -kk, -kk, kk])
        else:
            g = self.c * np.sqrt(self.w**2 - d * d)
            z = np.exp(1.5j)
            m = np.array([z * np.exp(g), z * np.exp(-g), np.conj(z) * np.exp(g),
                          np.conj(z) * np.exp(-g)])
            k = np.zeros(4)
        return KreinFloquetData(m, krein=k if self.krein else None)


def test_krein_window_found_and_same_signature_crossing_not_refined() -> None:
    """The 2e-3-wide window of an opposite-signature collision whose pair comes back on the
    side it came from (the collision distance dips to 0 and recovers inside one step) is found
    by the Krein-aware control, both edges located at ``p = 1 -+ w`` to 1e-9; on the same
    family with same-signature multipliers (no window) it takes no more points than with no
    multipliers at all. The generic motion check (every multiplier near the circle moves at
    most 0.02 per step) takes >= 4x more points there, and misses this window: at the ends of
    the step that hides it, each multiplier is within 0.02 of where it started."""
    kw = {"step_initial": 0.05, "step_max": 0.2, "max_points": 2000, "param_max": 2.0}
    bare = _run(Line(), [0.0, 0.0], **kw)
    br = _run(KreinPair(opposite=True), [0.0, 0.0], **kw)
    ns = sorted(e.point.y[1] for e in br.events if e.kind == "neimark_sacker")
    assert len(ns) == 2, ns
    assert abs(ns[0] - (1 - 1e-3)) < 1e-9 and abs(ns[1] - (1 + 1e-3)) < 1e-9
    same = _run(KreinPair(opposite=False), [0.0, 0.0], **kw)
    assert not [e for e in same.events if e.kind in ("neimark_sacker", "stability_change")]
    assert len(same.points) <= len(bare.points) + 1, (len(same.points), len(bare.points))
    generic = _run(KreinPair(opposite=False), [0.0, 0.0], krein_step_control=False, **kw)
    assert len(generic.points) >= 4 * len(bare.points), (len(generic.points), len(bare.points))
    missed = _run(KreinPair(opposite=True), [0.0, 0.0], krein_step_control=False, **kw)
    assert not [e for e in missed.events if e.kind == "neimark_sacker"]


def test_krein_control_falls_back_to_the_generic_check_without_signatures() -> None:
    """A conservative problem whose multipliers carry no Krein data (``krein=None``) gets the
    generic motion check: the same number of points as with the control switched off."""
    kw = {"step_initial": 0.05, "step_max": 0.2, "max_points": 2000, "param_max": 2.0}
    a = _run(KreinPair(opposite=False, krein=False), [0.0, 0.0], **kw)
    b = _run(KreinPair(opposite=False), [0.0, 0.0], krein_step_control=False, **kw)
    assert len(a.points) == len(b.points)


def test_a_crossing_without_a_kind_is_one_stability_change() -> None:
    """A crossing the multipliers do not classify (kind ``stability_change``) is one event with
    the change in its detail; a classified one (a flip) is the crossing plus its stability
    change (the report listed such a change twice at one point)."""
    from nsm_continuation.core.palc import crossing_events
    from nsm_continuation.core.records import Point

    p = Point(y=np.zeros(2), s=0.0, tangent=np.array([0.0, 1.0]), tests={}, multipliers=None,
              trivial_error=0.0, n_unstable=0, derived={}, bordered_det=1.0)
    (only,) = crossing_events("stability_change", p, 0.0, 1, 0, np.array([]), None, "count")
    assert (only.kind, only.detail) == ("stability_change", "unstable -> stable")
    flip = crossing_events("period_doubling", p, 0.0, 0, 1, np.array([-1.0 + 0j]), -1.0 + 0j,
                            "multiplier_modulus")
    assert [e.kind for e in flip] == ["period_doubling", "stability_change"]
    assert flip[1].detail == "stable -> unstable"
