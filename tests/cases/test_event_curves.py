"""Two-parameter curves of located events (nsm_continuation/algorithms/curves.py, eq. L1):
period-doubling and grazing curves of the undamped forced impact oscillator.

Oracle, independent of the simulator and the engine: the closed-form period-1 orbit and its
period-doubling condition (tests/oracles/impact_oscillator.py, eqs. O1-O2), whose zero set in
the (omega, gap) plane is a U-shaped curve with its tip at gap = -0.65176597 (the two period
doublings of the orbit meet there).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
import yaml
from oracles.impact_oscillator import period_doubling_function, section_state
from pydantic import BaseModel
from scipy.optimize import brentq, minimize_scalar

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.algorithms.curves import (
    MULTIPLIER_KINDS,
    LocatedCurve,
    curve_kinds,
    monitor_kinds,
)
from nsm_continuation.core.monitors import Monitors, Source, admissibility, event_function
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Point

R = 0.8
#: the closed-form slope of (O2) in omega is ~3: 1e-7 in (O2) is ~3e-8 in omega
PD_TOL = 1e-7


def base_case(gap: float, omega: float, lo: float, name: str) -> dict[str, Any]:
    """The stable high-velocity orbit at ``omega`` (from its closed form) continued down in
    omega to ``lo``."""
    q, qdot = section_state(omega, gap, R)
    return {"name": name, "problem": "impact_oscillator",
            "parameters": {"zeta": 0.0, "omega": omega, "gap": gap, "restitution": R,
                           "section_phase": float(np.pi)},
            "start": {"guess": {"q": float(q), "qdot": float(qdot)}},
            "continuation": {"parameter": "omega", "min": lo, "max": omega,
                             "direction": "decrease",
                             "step": {"initial": 0.005, "min": 1e-9, "max": 0.01},
                             "max_points": 40, "newton_tol": 1e-10},
            "analysis": {"stability": True, "bifurcations": True, "event_tol": 1e-10},
            "output": {"plots": False, "progress": False}}


def pd_omega(gap: float, lo: float, hi: float) -> float:
    return brentq(lambda w: period_doubling_function(w, gap, R), lo, hi, xtol=1e-14)


@pytest.fixture(scope="module")
def pd_run() -> Any:
    """Gap -0.5: the period doubling at omega = 1.0949764 (closed form)."""
    return nsm.run(base_case(-0.5, 1.11, 1.085, "pd_base"))


def curve_points(res: Any) -> list[tuple[float, float, float]]:
    br = res.run_result.branches[0]
    return [(p.derived["omega"], p.derived["gap"], p.derived["condition"]) for p in br.points]


def test_base_run_period_doubling_on_the_closed_form(pd_run: Any) -> None:
    (ev,) = [e for e in pd_run.events if e.kind == "period_doubling"]
    assert ev.parameter == pytest.approx(pd_omega(-0.5, 1.09, 1.1), abs=1e-8)


def test_period_doubling_curve_lies_on_the_closed_form(pd_run: Any) -> None:
    """Every point of the curve in (gap, omega) satisfies (O2) to 1e-7 (~3e-8 in omega), and
    its multiplier is at -1 to the located tolerance; the curve reaches both bounds."""
    cur = pd_run.restart(event="period_doubling", curve="period_doubling", parameter="gap",
                         min=-0.53, max=-0.47,
                         step={"initial": 0.01, "min": 1e-6, "max": 0.02}, max_points=12)
    br = cur.run_result.branches[0]
    assert set(br.termination.values()) == {"bound reached: gap"}
    pts = curve_points(cur)
    assert len(pts) >= 5
    gaps = [g for _, g, _ in pts]
    assert min(gaps) == pytest.approx(-0.53) and max(gaps) == pytest.approx(-0.47)
    for omega, gap, cond in pts:
        assert abs(period_doubling_function(omega, gap, R)) < PD_TOL, (omega, gap)
        assert cond < 1e-8
    assert cur.run_result.problem.curve_kind == "period_doubling"


def test_period_doubling_curve_goes_round_its_turn() -> None:
    """From the upper period doubling at gap = -0.645 towards larger |gap|: the curve turns
    back in gap at the closed-form tip (-0.6517660, where both period doublings meet) and
    comes back along the lower one, every point on (O2)."""
    base = nsm.run(base_case(-0.645, 1.05, 1.04, "pd_base_turn"))
    cur = base.restart(event="period_doubling", curve="period_doubling", parameter="gap",
                       min=-0.655, max=-0.645, direction="decrease",
                       step={"initial": 0.002, "min": 1e-6, "max": 0.004}, max_points=30)
    pts = curve_points(cur)
    gap_tip = brentq(lambda g: minimize_scalar(
        lambda w: period_doubling_function(w, g, R), bounds=(1.02, 1.06), method="bounded",
        options={"xatol": 1e-12}).fun, -0.66, -0.645, xtol=1e-14)
    omegas = np.array([w for w, _, _ in pts])
    gaps = np.array([g for _, g, _ in pts])
    lower = pd_omega(-0.645, 1.02, 1.0364)
    assert gap_tip <= gaps.min() < gap_tip + 2e-3           # round the tip, not past it
    assert omegas[0] == pytest.approx(pd_omega(-0.645, 1.0364, 1.05), abs=1e-7)
    assert omegas[-1] == pytest.approx(lower, abs=1e-7)     # back at gap = -0.645, below
    assert gaps[-1] == pytest.approx(-0.645)
    for omega, gap, _ in pts:
        assert abs(period_doubling_function(omega, gap, R)) < PD_TOL, (omega, gap)


# ---------------------------------------------------------------------- YAML and refusals
def _yaml(tmp_path: Path, name: str, start: dict[str, Any], **cont: Any) -> int:
    case = {"name": name, "start": start,
            "continuation": {"parameter": "gap", "min": -0.52, "max": -0.48, **cont},
            "output": {"plots": False, "progress": False}}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(case))
    return cli.main(["run", str(path), "--out", str(tmp_path / name), "--quiet"])


@pytest.fixture(scope="module")
def saved(pd_run: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("runs") / "pd_base"
    pd_run.save(folder, plots=False)
    return folder


def test_yaml_period_doubling_curve(saved: Path, tmp_path: Path) -> None:
    """``start: {from, event: period_doubling, curve: period_doubling}`` from YAML: the CSV
    holds the curve, report.json names the curve, and a restart of the curve continues it."""
    start = {"from": str(saved), "event": "period_doubling", "curve": "period_doubling"}
    assert _yaml(tmp_path, "pdc", start, step={"initial": 0.02, "max": 0.02},
                 max_points=6) == 0
    import json

    rep = json.loads((tmp_path / "pdc" / "report.json").read_text())
    assert rep["restart"]["curve"]["kind"] == "period_doubling"
    assert rep["restart"]["problem"] == "impact_oscillator"
    rows = (tmp_path / "pdc" / "branch_0.csv").read_text().splitlines()
    assert rows[0].startswith("gap,omega,condition")
    for row in rows[1:]:
        gap, omega = (float(v) for v in row.split(",")[:2])
        assert abs(period_doubling_function(omega, gap, R)) < PD_TOL
    # a restart from the curve's end continues the curve (its kind, free parameter and the
    # base run's settings are in the curve's report)
    again = {"from": str(tmp_path / "pdc"), "event": {"kind": "endpoint", "index": 1}}
    assert _yaml(tmp_path, "pdc2", again, min=-0.52, max=-0.46, direction="increase",
                 step={"initial": 0.02, "max": 0.02}, max_points=6) == 0
    rows = (tmp_path / "pdc2" / "branch_0.csv").read_text().splitlines()[1:]
    gaps = [float(r.split(",")[0]) for r in rows]
    assert max(gaps) == pytest.approx(-0.46)
    for row in rows:
        gap, omega = (float(v) for v in row.split(",")[:2])
        assert abs(period_doubling_function(omega, gap, R)) < PD_TOL


@pytest.mark.parametrize("extra, key", [
    ({"method": "augmented"}, "start.method"),
    ({"curve": "grazing", "method": "located"}, "start.method"),
    ({"margin": 1e-9}, "start.margin"),
    ({"free": "restitution"}, "start.free"),
])
def test_refused_before_computing(saved: Path, tmp_path: Path, capsys: Any,
                                  extra: dict[str, Any], key: str) -> None:
    start = {"from": str(saved), "event": "period_doubling", "curve": "period_doubling",
             **extra}
    assert _yaml(tmp_path, "bad", start) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0], err
    assert not (tmp_path / "bad").exists()


def test_curve_from_an_event_of_another_kind_is_refused(saved: Path, tmp_path: Path,
                                                       capsys: Any) -> None:
    start = {"from": str(saved), "event": "period_doubling", "curve": "fold"}
    assert _yaml(tmp_path, "bad2", start) == 2
    assert "start.curve" in capsys.readouterr().err


def test_a_curve_kind_the_problem_does_not_offer_is_refused(saved: Path, tmp_path: Path,
                                                           capsys: Any) -> None:
    """Any kind name passes the schema; one that is neither a multiplier kind nor a kind the
    problem maps a test or event function to is refused before computing, in one line naming
    start.curve and the kinds this problem offers."""
    from nsm_continuation.cases.registry import get

    start = {"from": str(saved), "event": "period_doubling", "curve": "endpoint"}
    assert _yaml(tmp_path, "bad3", start) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "start.curve" in err[0] and "'endpoint'" in err[0], err
    offered = curve_kinds(get("impact_oscillator")({}))
    assert err[0].startswith("error: start.curve: Input should be "), err
    assert all(repr(k) in err[0] for k in offered), err
    assert not (tmp_path / "bad3").exists()


# ---------------------------------------------------------------------- the chain's point B
def test_chain_nonlinear_grazing_curve_follows_the_time_scaling() -> None:
    """Point B of Fig. 5.1 (the nonlinear grazing orbit ending branch 1 of the 5-dof chain)
    in (stiffness, omega): a uniform stiffness k scales time by sqrt(k) and leaves the orbits'
    shapes (M u'' + k K1 u = 0 with the same wall), so omega_B(k) = omega_B(5) sqrt(k / 5)
    exactly; every point is at zero clearance (the admissibility test located) and, the
    orbits having B's shape, admissible as B is: the located test's sign is rounding there
    (``Point.on_boundary``), every other test's value is B's."""
    case = {"name": "chain_b", "problem": "ndof_impact",
            "parameters": {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0},
            "start": {"mode": 1, "subharmonic": 1},
            "continuation": {"parameter": "omega", "min": 1.0, "max": 11.0,
                             "step": {"initial": 0.005, "min": 1e-9, "max": 0.5},
                             "max_points": 400},
            "analysis": {"stop_on_inadmissible": True, "stability": False},
            "output": {"plots": False, "progress": False}}
    base = nsm.run(case)
    (ev,) = [e for e in base.events if e.kind == "grazing"]
    omega_b = float(ev.point.derived["omega"])
    cur = base.restart(event="grazing", curve="grazing", parameter="stiffness", min=4.0,
                       max=6.0, step={"initial": 0.1, "min": 1e-6, "max": 0.5}, max_points=30)
    br = cur.run_result.branches[0]
    assert set(br.termination.values()) == {"bound reached: stiffness"}
    ks = [p.derived["stiffness"] for p in br.points]
    assert min(ks) == pytest.approx(4.0) and max(ks) == pytest.approx(6.0)
    for p in br.points:
        k = p.derived["stiffness"]
        assert p.derived["omega"] == pytest.approx(omega_b * np.sqrt(k / 5.0), rel=1e-9)
        assert p.derived["condition"] < 1e-9
        assert p.on_boundary == ("clearance",) and p.admissible
        assert p.tests["outgoing_velocity"] == pytest.approx(
            ev.point.tests["outgoing_velocity"], rel=1e-8)


# ---------------------------------------------------------------------- kinds from the problem
class _MonitorParameters(BaseModel):
    a: float = 1.0
    b: float = 2.0


class _Monitored(Problem):
    """A problem whose test and event functions map to core kinds other than the default
    (declared members only): a located curve follows those kinds, on those functions."""

    name: ClassVar[str] = "monitored"
    Parameters: ClassVar[type[BaseModel]] = _MonitorParameters
    monitors: ClassVar[Monitors] = Problem.monitors.with_(
        admissibility("speed", "stability_change"), event_function("margin", "branch_point"))

    def __init__(self, params: BaseModel) -> None:
        super().__init__(params)
        self.variables = ["x", "a"]
        self.parameter = "a"

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        return {"speed": float(y[0]), "clearance": float(y[0] - 1.0)}

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        return {"margin": float(y[0] + 1.0)}

    def with_parameters(self, values: dict[str, float]) -> Problem | None:
        return _Monitored(self.params.model_copy(update=values))


class _Unmonitored(_Monitored):
    """No test or event functions: only the multiplier kinds."""

    monitors: ClassVar[Monitors] = Problem.monitors
    admissibility = Problem.admissibility
    event_functions = Problem.event_functions


def _point(tests: dict[str, float], events: dict[str, float]) -> Point:
    return Point(y=np.zeros(2), s=0.0, tangent=np.array([0.0, 1.0]), tests=tests,
                 multipliers=np.array([-0.9, 0.5]), trivial_error=0.0, n_unstable=0,
                 derived={}, bordered_det=1.0, event_values=events)


def test_curve_kinds_are_the_multiplier_kinds_and_the_problems_mapped_kinds() -> None:
    multipliers = {"period_doubling", "fold", "neimark_sacker"}
    assert set(MULTIPLIER_KINDS) == multipliers
    pr = _Monitored(_MonitorParameters())
    # unlisted tests ("clearance") raise the default kind
    assert monitor_kinds(pr) == {"stability_change", "branch_point", "grazing"}
    assert curve_kinds(pr) == multipliers | {"stability_change", "branch_point", "grazing"}
    assert curve_kinds(_Unmonitored(_MonitorParameters())) == multipliers
    # a hybrid problem offers the kinds its declared members map monitors to
    from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

    hybrid = DoublePendulumProblem({})
    declared = type(hybrid).monitors
    assert curve_kinds(hybrid) == multipliers | {
        m.kind for m in (*declared.of(Source.TEST), *declared.of(Source.FUNCTION))}


def test_condition_is_the_value_of_the_monitor_mapped_to_the_kind() -> None:
    """The condition of a monitor's kind is the value of the monitors the problem maps to it
    (by its declared members, not by their names), and a multiplier kind keeps its
    multiplier condition."""
    base = _Monitored(_MonitorParameters())
    pt = _point({"speed": -0.25, "clearance": 0.5, "gone": float("nan")}, {"margin": 0.125})
    expected = {"stability_change": 0.25, "branch_point": 0.125, "grazing": 0.5,
                "period_doubling": 0.1}
    for kind, value in expected.items():
        curve = LocatedCurve(base, kind, "a", "b")
        assert curve.condition(pt) == pytest.approx(value)
    # a kind none of the point's monitors maps to: undefined
    assert np.isnan(LocatedCurve(base, "branch_point", "a", "b").condition(_point({}, {})))


def test_a_kind_the_problem_does_not_offer_is_refused_naming_its_kinds() -> None:
    base = _Unmonitored(_MonitorParameters())
    listed = "Input should be 'period_doubling', 'fold' or 'neimark_sacker'"
    with pytest.raises(ValueError, match=rf"^start\.curve: {listed} .*'monitored'.*'grazing'$"):
        LocatedCurve(base, "grazing", "a", "b")


# ---------------------------------------------------------------------- round a sharp tip
#: the tip of the bowl's curve, b = BOWL_TIP + (a - 1)^2
BOWL_TIP = 0.5


class _BowlParameters(BaseModel):
    a: float = 1.0
    b: float = 1.0


class _Bowl(Problem):
    """``x = a`` continued in ``a`` (or, at fixed ``a``, in ``b``), with the event function
    ``b - BOWL_TIP - (x - 1)^2``: its zeros in ``(b, a)`` are the parabola ``b = BOWL_TIP +
    (a - 1)^2``, a U with its tip at ``(BOWL_TIP, 1)`` (curvature 2 there)."""

    name: ClassVar[str] = "bowl"
    Parameters: ClassVar[type[BaseModel]] = _BowlParameters
    monitors: ClassVar[Monitors] = Problem.monitors.with_(event_function("bowl", "branch_point"))

    def __init__(self, params: BaseModel, parameter: str = "a") -> None:
        super().__init__(params)
        self.parameter = parameter
        self.variables = ["x", parameter]

    def residual(self, y: Any) -> Any:
        return y[0] - (y[1] if self.parameter == "a" else self.params.a)

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        b = float(y[1]) if self.parameter == "b" else self.params.b
        return {"bowl": b - BOWL_TIP - (float(y[0]) - 1.0) ** 2}

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        if name not in ("a", "b"):
            return super().parameter_bounds(name, lo, hi)
        self.parameter, self.variables = name, ["x", name]
        return lo, hi

    def with_parameters(self, values: dict[str, float]) -> Problem | None:
        return _Bowl(self.params.model_copy(update=values), self.parameter)


def test_curve_goes_round_a_tip_reached_by_a_long_step() -> None:
    """Steps grown to 0.44 in ``b`` bring the curve to 0.16 above the tip of the U; the next
    step overshoots it, and the halved steps are predicted along a secant 0.5 long that the
    curve has turned away from (its error is linear in the step, so halving alone never brings
    a located point within a quarter step of it). The curve goes round the tip and back up the
    other arm to the bound, every point on the closed-form parabola."""
    from types import SimpleNamespace

    from nsm_continuation.algorithms.curves import CurveTracer
    from nsm_continuation.core.settings import ContinuationSettings

    b0 = 2.0
    a0 = 1.0 + np.sqrt(b0 - BOWL_TIP)
    curve = LocatedCurve(_Bowl(_BowlParameters(a=a0, b=b0)), "branch_point", "a", "b",
                         {"step_initial": 0.05})
    settings = ContinuationSettings(step_initial=0.2, step_min=1e-7, step_max=1.0,
                                    max_points=60, param_min=0.0, param_max=b0, direction=-1,
                                    event_tol=1e-12, stability=False)
    seed = SimpleNamespace(y=np.array([a0, a0, b0]), direction=-1, label="bowl", info={},
                           tangent=None)
    br = CurveTracer(curve, settings).run(seed)
    assert br.termination == {"backward": "bound reached: b"}
    a = np.array([p.y[-2] for p in br.points])
    b = np.array([p.y[-1] for p in br.points])
    np.testing.assert_allclose(b, BOWL_TIP + (a - 1.0) ** 2, atol=1e-10)
    assert b.min() < BOWL_TIP + 0.01                       # round the tip
    assert b[-1] == pytest.approx(b0) and a[-1] == pytest.approx(2.0 - a0)  # the other arm
    assert np.all(np.diff(a) < 0)                           # one way along the U
