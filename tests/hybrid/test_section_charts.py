"""Charts: a branch moved to other unknowns where its own degenerate (``Problem.rechart``), and
event functions whose sign changes through a pole.

The unknowns of a forced hybrid orbit are its state at a stroboscopic section. Where an impact
or a grazing of the orbit reaches the section's phase, the section state jumps along the branch
(pre- to post-impact), or lies on the impact surface, and the shooting residual is
discontinuous. The problem then moves its section to the middle of the longest stretch of the
orbit free of impacts (``HybridShootingProblem.rechart``). Each point records its chart
(``Point.chart``), and a restart reads the point in that chart.

Oracles: the closed-form orbits of the undamped oscillator at any forcing phase
(``tests/oracles/impact_oscillator.py``), an independent ``solve_ivp`` integration of the damped
one, a finite-difference check of the mapped tangent, and toy problems with exact answers.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
from helpers import NoParameters
from oracles.impact_oscillator import orbits, section_state
from pydantic import BaseModel
from scipy.integrate import solve_ivp

import nsm_continuation as nsm
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import KinkCrossing, Problem, Rechart, StartPoint
from nsm_continuation.core.settings import ContinuationSettings
from nsm_continuation.hybrid.problem import HybridShootingProblem

R = 0.8


def oscillator_case(zeta: float, phase: float, lo: float, hi: float, omega: float,
                    direction: str) -> dict[str, Any]:
    return {"name": "charts", "problem": "impact_oscillator",
            "parameters": {"zeta": zeta, "omega": omega, "gap": -0.5, "restitution": R,
                           "section_phase": phase},
            "start": {"transient": 60, "direction": direction},
            "continuation": {"parameter": "omega", "min": lo, "max": hi, "max_points": 300,
                             "step": {"initial": 0.01, "min": 1e-9, "max": 0.1},
                             "newton_tol": 1e-10},
            "output": {"plots": False, "progress": False}}


def flow(q: float, qdot: float, omega: float, zeta: float, phase: float,
         periods: float = 1.0) -> np.ndarray:
    """``(q, q')`` after ``periods`` forcing periods (any fraction) from the state at forcing
    phase ``phase``: ``q'' + 2 zeta q' + q = cos(omega t + phase)`` integrated by
    ``solve_ivp`` (DOP853), the stop ``q = -0.5`` a terminal event, ``q'+ = -r q'-`` there."""
    def rhs(t: float, x: np.ndarray) -> list[float]:
        return [x[1], -x[0] - 2 * zeta * x[1] + np.cos(omega * t + phase)]

    def stop(t: float, x: np.ndarray) -> float:
        return x[0] + 0.5

    stop.terminal, stop.direction = True, -1.0  # type: ignore[attr-defined]
    t, x, t_end = 0.0, np.array([q, qdot], dtype=float), periods * 2 * np.pi / omega
    while t < t_end:
        sol = solve_ivp(rhs, (t, t_end), x, method="DOP853", rtol=1e-12, atol=1e-13,
                        events=stop)
        t, x = float(sol.t[-1]), sol.y[:, -1].copy()
        if sol.status == 1:
            x[1] = -R * x[1]
            t += 1e-12 * t_end
    return x


@pytest.fixture(scope="module")
def grazing_on_the_section() -> Any:
    """F1: the undamped oscillator's grazing at omega = sqrt(3) lies at forcing phase 0, the
    problem's default section phase."""
    return nsm.run(oscillator_case(0.0, 0.0, 1.2, 2.0, 1.5, "increase"))


def test_grazing_at_the_section_phase_is_located_with_no_false_event(
        grazing_on_the_section: Any) -> None:
    """The same events as with the section away from the grazing (docs/events_and_grazing.md, case
    ``impact_oscillator_grazing``): the fold, the grazing at sqrt(3) to 1e-10 with the
    sequence ``I -> -`` (a family change there), the stability changes there, and nothing
    else (no branch point, no false fold, no sequence change from the section at the grazing
    phase)."""
    res = grazing_on_the_section
    (br,) = res.run_result.branches
    kinds = sorted(e.kind for e in br.events)
    assert kinds == ["endpoint", "family_change", "fold", "grazing", "stability_change",
                     "stability_change"]
    (g,) = [e for e in br.events if e.kind == "grazing"]
    assert abs(g.point.y[-1] - np.sqrt(3.0)) < 1e-10
    assert (g.data["signature_before"], g.data["signature_after"]) == ("I", "-")
    # the branch goes on along the free orbits: a family change at the grazing
    (f,) = [e for e in br.events if e.kind == "family_change"]
    assert f.point is g.point
    assert (f.data["signature_before"], f.data["signature_after"]) == ("I", "-")
    assert br.termination["forward"] == "bound: omega = max"
    assert any(p.chart for p in br.points)  # the section moved off the grazing phase


def test_points_in_the_moved_chart_are_the_closed_form_orbits(
        grazing_on_the_section: Any) -> None:
    """Every impacting point, in its own chart (section phase ``chart['phase']``), is one of
    the closed-form one-impact orbits at that phase, to 1e-7; both charts occur."""
    (br,) = grazing_on_the_section.run_result.branches
    fold = max(float(p.y[-1]) for p in br.points if p.derived.get("n_impacts") == 1.0)
    phases = set()
    checked = 0
    for p in br.points:
        omega = float(p.y[-1])
        # not next to the grazing or the fold, where the closed form's phase equation has a
        # square-root sensitivity to omega
        if p.derived.get("n_impacts") != 1.0 or abs(omega - np.sqrt(3.0)) < 1e-3 \
                or fold - omega < 1e-3:
            continue
        phase = (p.chart or {}).get("phase", 0.0)
        phases.add(phase)
        found = orbits(omega, -0.5, R)
        states = []
        for orbit in found:  # both one-impact orbits: the high- and the low-velocity one
            G, T = 1.0 / (1.0 - omega ** 2), 2.0 * np.pi / omega
            phi, t2 = orbit["phase"], np.tan(np.pi / omega)
            a = -0.5 - G * np.cos(phi)
            t = (phase / omega - phi / omega) % T
            u, v = a * np.cos(t) + a * t2 * np.sin(t), -a * np.sin(t) + a * t2 * np.cos(t)
            states.append(np.array([G * np.cos(phase) + u, -G * omega * np.sin(phase) + v]))
        err = min(float(np.max(np.abs(s - p.y[:2]))) for s in states)
        assert err < 1e-7, (omega, phase, err)
        checked += 1
    assert checked > 50 and len(phases) == 2


def test_closed_form_oracle_agrees_with_its_own_section_state() -> None:
    """The oracle's two expressions of the high-velocity orbit (``section_state`` and the
    free-flight formula of the test above) agree at an arbitrary phase."""
    omega, phase = 1.5, 1.234
    orbit = min(orbits(omega, -0.5, R), key=lambda o: o["v_minus"])
    G, T = 1.0 / (1.0 - omega ** 2), 2.0 * np.pi / omega
    phi, t2 = orbit["phase"], np.tan(np.pi / omega)
    a = -0.5 - G * np.cos(phi)
    t = (phase / omega - phi / omega) % T
    mine = np.array([G * np.cos(phase) + a * np.cos(t) + a * t2 * np.sin(t),
                     -G * omega * np.sin(phase) - a * np.sin(t) + a * t2 * np.cos(t)])
    assert np.allclose(mine, section_state(omega, -0.5, R, phase), atol=1e-12)


@pytest.fixture(scope="module")
def impact_through_the_section() -> Any:
    """F2: with damping 0.05, continued down from omega = 1.5 with the section at phase pi,
    the impact's phase reaches the section's near omega = 0.9649."""
    return nsm.run(oscillator_case(0.05, float(np.pi), 0.9, 1.6, 1.5, "decrease"))


def test_impact_through_the_section_does_not_stop_the_branch(
        impact_through_the_section: Any) -> None:
    """The branch reaches the window's bound with no step below 1e-5 (the section moves once,
    before the impact reaches it); the orbits on both sides of the move are periodic under an
    independent integration from their own chart's phase."""
    (br,) = impact_through_the_section.run_result.branches
    assert br.termination["forward"] == "bound: omega = min"
    assert [e.kind for e in br.events] == ["endpoint"]
    s = np.array([p.s for p in br.points])
    assert np.min(np.diff(s)) > 1e-5
    moves = [k for k in range(1, len(br.points)) if br.points[k].chart != br.points[k - 1].chart]
    assert len(moves) == 1
    k = moves[0]
    for p in (br.points[k - 1], br.points[k], br.points[-1]):
        phase = (p.chart or {}).get("phase", np.pi)
        back = flow(p.y[0], p.y[1], float(p.y[-1]), 0.05, phase)
        assert np.max(np.abs(back - p.y[:2])) < 1e-7
    assert "Poincare section moved" in br.info["chart_moves"][0]


def forced_move(res: Any, monkeypatch: pytest.MonkeyPatch) -> tuple[Any, Any, Rechart]:
    """Point 10 of ``res``'s branch, its problem (in the point's chart) and the move of its
    section that ``rechart`` makes when forced (every event counts as too close)."""
    (br,) = res.run_result.branches
    p = br.points[10]
    pb = res.run_result.problem.in_chart(p.chart)
    monkeypatch.setattr(HybridShootingProblem, "SECTION_CLEARANCE", 1.0)
    moved = pb.rechart(p.y, p.tangent)
    assert moved is not None
    return p, pb, moved


def test_a_move_keeps_the_orbit(impact_through_the_section: Any,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A move (forced here at a point far from any impact) gives the state an independent
    integration reaches from the old section state after the phase difference, and the same
    derived quantities and multipliers."""
    p, pb, moved = forced_move(impact_through_the_section, monkeypatch)
    old, new = pb.shooting.section.value, moved.problem.chart()["phase"]
    omega = float(p.y[-1])
    ahead = flow(p.y[0], p.y[1], omega, 0.05, old, ((new - old) % (2 * np.pi)) / (2 * np.pi))
    assert np.max(np.abs(ahead - moved.y[:2])) < 1e-8
    assert moved.y[-1] == p.y[-1]
    assert np.max(np.abs(moved.problem.evaluate(moved.y))) < 1e-8
    a, b = pb.derived(p.y), moved.problem.derived(moved.y)
    for key in ("amplitude_q", "min_impact_normal_velocity", "min_impact_dH_dt", "period"):
        assert b[key] == pytest.approx(a[key], rel=1e-8, abs=1e-10)
    ma = np.sort_complex(pb.floquet(p.y, p.tangent).multipliers)
    mb = np.sort_complex(moved.problem.floquet(moved.y, moved.tangent).multipliers)
    assert np.allclose(ma, mb, atol=1e-7)


def test_without_moving_the_section_the_branch_ends_there(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The same continuation with the section never moved ends where the impact reaches
    it, with the reason naming the section (the test above can fail)."""
    monkeypatch.setattr(HybridShootingProblem, "SECTION_CLEARANCE", 0.0)
    res = nsm.run(oscillator_case(0.05, float(np.pi), 0.9, 1.6, 1.5, "decrease"))
    (br,) = res.run_result.branches
    reason = br.termination["forward"]
    assert reason.startswith("step_below_minimum") and "Poincare section" in reason
    assert br.points[-1].y[-1] > 0.96


def test_moved_tangent_is_the_derivative_of_the_moved_state(
        impact_through_the_section: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """``rechart``'s tangent (mapped by the simulator's sensitivities) against central
    differences of the moved state along the branch's tangent (a move forced at a point)."""
    p, pb, moved = forced_move(impact_through_the_section, monkeypatch)
    sec = pb.shooting.section
    shift = (moved.problem.shooting.section.value - sec.value) % (2 * np.pi)

    def state_ahead(y: np.ndarray) -> np.ndarray:
        x = pb.shooting.sim.run(pb.shooting.x0(y), section=(sec.index, sec.value + shift, 1))
        return np.append(x.X[[0, 1]], y[-1])

    h = 1e-6
    fd = (state_ahead(p.y + h * p.tangent) - state_ahead(p.y - h * p.tangent)) / (2 * h)
    assert np.allclose(moved.tangent, fd / np.linalg.norm(fd), atol=1e-6)


def test_restart_from_a_point_in_a_moved_chart(impact_through_the_section: Any) -> None:
    """A restart from the branch's last point (in the moved chart) starts on that orbit."""
    res = impact_through_the_section
    (br,) = res.run_result.branches
    last = br.points[-1]
    assert last.chart
    again = res.restart(point=-1, max_points=3, direction="increase",
                        analysis={"stability": False})
    first = again.run_result.branches[0].points[0]
    assert first.derived["amplitude_q"] == pytest.approx(last.derived["amplitude_q"],
                                                         rel=1e-8)
    assert np.allclose(first.y, last.y, atol=1e-9)
    assert again.run_result.problem.chart() == last.chart


# ---------------------------------------------------------------------- the engine, on toys
def toy_settings(direction: int = 0) -> ContinuationSettings:
    """Steps of 0.05 over p in [0, 1], no multipliers."""
    return ContinuationSettings(param_min=0.0, param_max=1.0, step_initial=0.05, step_max=0.05,
                                max_points=200, stability=False, direction=direction)


class ShiftedLine(Problem):
    """``x = p + c`` in the chart ``c`` (0 declared); it asks to move to ``c + 1`` once
    ``p > 0.5`` in every chart below 1: the engine's bookkeeping on an exact answer."""

    name: ClassVar[str] = "shifted_line"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, c: float = 0.0) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self.c = c

    def residual(self, y: Any) -> Any:
        return y[0] - y[1] - self.c

    def chart(self) -> dict[str, float] | None:
        return {"c": self.c} if self.c else None

    def in_chart(self, chart: dict[str, float] | None) -> ShiftedLine:
        c = (chart or {}).get("c", 0.0)
        return self if c == self.c else ShiftedLine(c)

    def rechart(self, y: np.ndarray, tangent: np.ndarray) -> Rechart | None:
        if y[1] <= 0.5 or self.c >= 1.0:
            return None
        return Rechart(ShiftedLine(self.c + 1.0), y + np.array([1.0, 0.0]), tangent,
                       "shifted by one")


def test_engine_records_each_point_in_its_chart() -> None:
    settings = toy_settings()
    engine = ContinuationEngine(ShiftedLine(), settings)
    br = engine.run(StartPoint(np.array([0.2, 0.2]), "toy"))
    charts = {None if p.chart is None else p.chart["c"] for p in br.points}
    assert charts == {None, 1.0}
    for p in br.points:
        c = (p.chart or {}).get("c", 0.0)
        assert p.y[0] == pytest.approx(p.y[1] + c, abs=1e-12)
        assert (c == 1.0) == (p.y[1] > 0.5 + 1e-12) or abs(p.y[1] - 0.5) < 0.06
    # the backward half starts again from the start point, in the declared chart
    assert all(p.chart is None for p in br.points if p.y[1] < 0.2)
    assert len(engine.rechart_notes) == 1 and "shifted by one" in engine.rechart_notes[0]
    assert engine.problem.chart() is None


class PoleAndZero(Problem):
    """``x = p`` with two event functions: ``1 / (p - 0.3)`` changes sign through a pole (no
    event), ``p - 0.7`` through a zero (an event at 0.7)."""

    name: ClassVar[str] = "pole_and_zero"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        return {"pole": 1.0 / (float(y[1]) - 0.3), "zero": float(y[1]) - 0.7}


def test_a_sign_change_through_a_pole_is_no_event() -> None:
    settings = toy_settings(direction=1)
    engine = ContinuationEngine(PoleAndZero(), settings)
    br = engine.run(StartPoint(np.array([0.01, 0.01]), "toy", direction=1))
    events = [e for e in br.events if e.kind != "endpoint"]
    assert [e.data["function"] for e in events] == ["zero"]
    assert events[0].point.y[1] == pytest.approx(0.7, abs=1e-10)
    assert engine.sign_changes_without_zero == 1


class KinkAt(Problem):
    """``x = p`` with the event function ``p - 0.5``, whose zero the problem says is a kink:
    its ``continue_beyond`` returns ``zero`` and ``beyond`` as given (a true answer, or a
    wrong one: a point where the function is not zero, or a step back onto the approach)."""

    name: ClassVar[str] = "kink_at"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, zero: float, beyond: float) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self.zero, self.beyond = zero, beyond

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        return {"f": float(y[1]) - 0.5}

    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> KinkCrossing | None:
        return KinkCrossing([], np.array([self.zero] * 2), np.array([self.beyond] * 2))


@pytest.mark.parametrize(("zero", "beyond", "crossed"), [
    (0.5, 0.55, True),     # the problem's crossing: taken
    (0.45, 0.55, False),   # its "zero" is not one (f = -0.05): refused
    (0.5, 0.40, False),    # its "beyond" turns back onto the approach: refused
])
def test_a_kink_is_crossed_only_at_a_zero_and_forwards(zero: float, beyond: float,
                                                       crossed: bool) -> None:
    settings = toy_settings(direction=1)
    br = ContinuationEngine(KinkAt(zero, beyond), settings).run(
        StartPoint(np.array([0.1, 0.1]), "toy", direction=1))
    (ev,) = [e for e in br.events if e.kind != "endpoint"]
    assert ev.point.y[1] == pytest.approx(0.5, abs=1e-10)
    assert bool(ev.data.get("kink")) == crossed
    assert br.termination["forward"] == "bound: p = max"


def test_a_two_parameter_curve_moves_with_its_base(monkeypatch: pytest.MonkeyPatch) -> None:
    """The period-doubling curve of the undamped oscillator in (omega, gap), with moves forced
    often (``SECTION_CLEARANCE`` 0.45: the section moves once the impact drifts 5 % of a
    period off the middle of its free stretch), so that the curve's points lie in ever new
    charts (the base run's event included). Every point is on the closed-form condition (O2)
    to 1e-9, and its unknowns are the closed-form section state at its own chart's phase to
    1e-9: each chart is recorded with the unknowns that belong to it."""
    from oracles.impact_oscillator import period_doubling_function

    monkeypatch.setattr(HybridShootingProblem, "SECTION_CLEARANCE", 0.45)
    case = oscillator_case(0.0, float(np.pi), 1.085, 1.11, 1.11, "decrease")
    case["start"] = {"guess": dict(zip(("q", "qdot"), section_state(1.11, -0.5, R).tolist(),
                                       strict=True))}
    case["continuation"].update(step={"initial": 0.005, "min": 1e-9, "max": 0.01},
                                max_points=40)
    base = nsm.run(case)
    cur = base.restart(event="period_doubling", curve="period_doubling", parameter="gap",
                       min=-0.5, max=-0.3, direction="increase",
                       step={"initial": 0.02, "min": 1e-6, "max": 0.06}, max_points=5)
    (br,) = cur.run_result.branches
    assert len(br.points) == 5
    charts = {p.chart["phase"] for p in br.points if p.chart}
    assert len(charts) >= 3
    for p in br.points:
        omega, gap = float(p.y[-2]), float(p.y[-1])
        assert abs(period_doubling_function(omega, gap, R)) < 1e-9
        phase = (p.chart or {}).get("phase", np.pi)
        assert np.max(np.abs(section_state(omega, gap, R, phase) - p.y[:2])) < 1e-9


def test_a_state_deep_inside_the_obstacle_is_named_a_bad_guess() -> None:
    """A section state deep inside the stop is a guess far from any orbit, not an impact at the
    section's time, whatever the depth; on the surface it is the section's."""
    from nsm_continuation.hybrid.return_map import ShootingFailure

    pb = nsm.problem("impact_oscillator", {"zeta": 0.1, "omega": 1.5, "gap": -0.5,
                                           "restitution": 0.8})
    pb.set_parameter("omega")
    with pytest.raises(ShootingFailure, match="far from any orbit"):
        pb.shooting.simulate(np.array([-3.0, 0.0, 1.5]))
    with pytest.raises(ShootingFailure, match="meets the impact surface at the Poincare"):
        pb.shooting.simulate(np.array([-0.5 - 1e-9, -1.0, 1.5]))


def test_a_sign_change_located_through_a_pole_is_told_from_a_zero() -> None:
    """``EventLocator._locate_continuous`` flags a sign change through a pole (the last
    values next to it exceed both ends), not one through a zero, even a zero next to an end
    (the branch point of a pitchfork at its start): what keeps a determinant blowing up at a
    grazing from being a branch point."""
    engine = ContinuationEngine(PoleAndZero(), toy_settings(direction=1))
    br = engine.run(StartPoint(np.array([0.01, 0.01]), "toy", direction=1))
    a = max((q for q in br.points if q.y[1] < 0.25), key=lambda q: q.y[1])
    b = min((q for q in br.points if q.y[1] > 0.35), key=lambda q: q.y[1])
    locator = engine.locator
    locator._locate_continuous(a, b, lambda q: 1.0 / (float(q.y[1]) - 0.3))
    assert locator.last_was_pole
    locator._locate_continuous(a, b, lambda q: float(q.y[1]) - 0.3)
    assert not locator.last_was_pole
    locator._locate_continuous(a, b, lambda q: float(q.y[1]) - float(a.y[1]) - 1e-16)
    assert not locator.last_was_pole
