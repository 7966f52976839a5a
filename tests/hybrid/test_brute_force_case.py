"""Brute-force bifurcation diagrams as a YAML case (``continuation.algorithm: sweep`` on a hybrid
problem, :mod:`nsm_continuation.hybrid.brute_force`; Figs. 8(b), 9(b)-(c) of Nordmark &
Piiroinen 2009), checked against independent oracles:

* the recorded points are returns to the Poincaré section: each recorded state of the impact
  oscillator, integrated over one forcing period by scipy (its own impact law, no chatter map,
  no saltation), gives the next recorded state;
* where the continuation (palc, Newton on the shooting residual) has a stable period-1 orbit,
  the brute-force returns (from the default initial state, no Newton) collapse onto its section
  state;
* ``start.record`` outside a sweep is refused by the CLI with one line (exit 2);
* the sweep contract: a problem that declares ``sweep`` must implement it, lists of points per
  value are drawn as dots, a simulation failure restarts the value and is recorded.

Measured (this machine, 2 shared cores): ~15 s for the whole file.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest
from helpers import CASES
from scipy.integrate import solve_ivp

import nsm_continuation as nsm
from nsm_continuation import cases
from nsm_continuation.core.problem import Problem

#: a forced impact oscillator (sec. 2.2.1) above resonance hitting its stop with finite
#: velocities (no chattering, no sticking): an attractor that is not periodic, so every
#: recorded return is a new state
OSC = {"zeta": 0.1, "omega": 2.5, "gap": -0.1, "restitution": 0.8}


def _osc_case(**continuation: Any) -> dict[str, Any]:
    return {"name": "osc_bf", "problem": "impact_oscillator", "parameters": dict(OSC),
            "start": {"transient": 5, "record": 4, "direction": "increase"},
            "continuation": {"algorithm": "sweep", "parameter": "omega", "min": 2.5,
                             "max": 2.6, "max_points": 3, **continuation},
            "output": {"plots": False, "progress": False}}


def _scipy_return(q: float, qd: float, omega: float) -> np.ndarray:
    """One forcing period of ``q'' + 2 zeta q' + q = cos(omega t)``, ``q >= gap``,
    ``q'+ = -e q'-``, from phase 0: by scipy, event by event."""
    zeta, gap, e = OSC["zeta"], OSC["gap"], OSC["restitution"]
    T = 2 * np.pi / omega

    def field(t: float, x: np.ndarray) -> list[float]:
        return [x[1], -x[0] - 2 * zeta * x[1] + np.cos(omega * t)]

    def hit(t: float, x: np.ndarray) -> float:
        return x[0] - gap

    hit.terminal, hit.direction = True, -1  # type: ignore[attr-defined]
    t, x = 0.0, np.array([q, qd])
    while True:
        sol = solve_ivp(field, (t, T), x, method="DOP853", rtol=1e-12, atol=1e-13,
                        events=hit)
        if sol.status != 1:
            return sol.y[:, -1]
        t, x = float(sol.t_events[0][0]), sol.y_events[0][0].copy()
        assert abs(x[1]) > 1e-3, "a low-velocity impact: the oracle would chatter"
        x[0], x[1] = gap, -e * x[1]


def test_recorded_points_are_section_returns() -> None:
    """Each recorded state, integrated over one return by scipy, is the next recorded one;
    the unknowns are the section coordinates and the parameter (the shooting's layout)."""
    res = nsm.run(_osc_case())
    br = res.branches[0]
    assert res.problem.variables == ["q", "qdot", "omega"]
    assert br.raw.info["draw"] == "markers" and br.raw.info["algorithm"] == "sweep"
    assert len(br) == 3 * 4                       # 3 values x 4 recorded returns
    assert br["return_index"].tolist() == [1, 2, 3, 4] * 3
    assert np.all(br["sticking_time"] == 0)
    assert all(p.signature is None for p in br.raw.points)
    y = br.y
    checked = 0
    for k in range(len(y) - 1):
        if y[k, 2] != y[k + 1, 2]:                # the next value: not one return later
            continue
        nxt = _scipy_return(y[k, 0], y[k, 1], y[k, 2])
        assert np.max(np.abs(nxt - y[k + 1, :2])) < 1e-7, (k, nxt, y[k + 1])
        checked += 1
    assert checked == 9
    # not a fixed point: the check compares different states
    assert np.ptp(y[:4, 0]) > 0.05
    # each value started from the previous one's final state: the first recorded return of
    # the second value is (transient + 1) returns from the last one of the first value, not
    # from the default state (checked with scipy on the same grid value)
    x = y[3, :2]
    for _ in range(5 + 1):
        x = _scipy_return(x[0], x[1], y[4, 2])
    assert np.max(np.abs(x - y[4, :2])) < 1e-6


def test_brute_force_collapses_on_the_continued_stable_orbit() -> None:
    """Double pendulum, sec. 6.1 (d = 0.5, T = -31.15, e = 0.89, Fig. 8(a)): the stable
    period-1 orbit of the continuation (Newton on the shooting residual, multipliers inside
    the unit circle) and the brute-force returns from the default initial state agree."""
    params = {"g": 9.81, "m1": 1.0, "m2": 2.0, "L1": 1.0, "L2": 1.0, "D": 10.0,
              "torque": -31.15, "restitution": 0.89, "d": 0.5}
    palc = nsm.run({"name": "p", "problem": "double_pendulum", "parameters": params,
                    "start": {"guess": {"q2": -1.1404, "q1dot": -3.6653, "q2dot": 0.2334},
                              "direction": "increase"},
                    "continuation": {"parameter": "restitution", "min": 0.85, "max": 0.95,
                                     "max_points": 2, "newton_tol": 1e-11},
                    "output": {"plots": False, "progress": False}})
    first = palc.branches[0].raw.points[0]
    assert first.y[-1] == pytest.approx(0.89) and first.stable is True
    bf = nsm.run({"name": "b", "problem": "double_pendulum", "parameters": params,
                  "start": {"transient": 12, "record": 4, "direction": "increase"},
                  "continuation": {"algorithm": "sweep", "parameter": "restitution",
                                   "min": 0.89, "max": 0.895, "max_points": 2},
                  "output": {"plots": False, "progress": False}})
    br = bf.branches[0]
    at = br.y[br["restitution"] == 0.89]
    assert at.shape == (4, 4)
    assert np.max(np.abs(at - first.y)) < 1e-6
    assert np.all(br["sticking_time"][:4] > 0)     # complete chattering, sticking each return
    assert br["period"][0] == pytest.approx(first.derived["period"], abs=1e-6)


def test_cli_refuses_record_outside_a_sweep(tmp_path: Path) -> None:
    case = CASES / "pendulum_sec6_1_complete_to_incomplete.yaml"
    proc = subprocess.run([sys.executable, "-m", "nsm_continuation.cli", "validate",
                           str(case), "--set", "start.record=5"],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].count("start.record") >= 1, proc.stderr
    assert "sweep" in lines[0]


@pytest.mark.parametrize("name", ["pendulum_fig8b_brute_force.yaml",
                                  "pendulum_fig9bc_brute_force.yaml"])
def test_bundled_cases_validate(name: str) -> None:
    case, problem = cases.validate(cases.load_raw(CASES / name))
    assert case.continuation.algorithm == "sweep" and "sweep" in problem.algorithms


def test_sweep_refusals() -> None:
    """The period is not a sweep parameter; returns > 1 means nothing to a sweep."""
    with pytest.raises(nsm.CaseError, match=r"^start\.returns"):
        nsm.run({**_osc_case(), "start": {"transient": 5, "returns": 2}})


def test_declaring_sweep_needs_the_hooks() -> None:
    with pytest.raises(TypeError, match="sweep_seeds"):
        class NoSweep(Problem):  # noqa: F841 - the class statement is the test
            name: ClassVar[str] = "no_sweep_test"
            algorithms: ClassVar[tuple[str, ...]] = ("palc", "sweep")

            def residual(self, y: Any) -> Any:
                return y[:1]


def test_markers_in_the_diagram_and_failures_restart() -> None:
    """Past the homoclinic torque (sec. 6.3) the pendulum comes to rest on the wall: the value
    records nothing and the reason is kept; the next value restarts from the default state
    (flag ``restarted``). The branch is drawn as dots."""
    import matplotlib

    matplotlib.use("Agg")
    res = nsm.run({"name": "f", "problem": "double_pendulum",
                   "parameters": {"restitution": 0.9, "d": 0.5, "torque": -31.001,
                                  "integrator": {"max_return_time": 100.0}},
                   "start": {"transient": 3, "record": 2, "direction": "decrease"},
                   "continuation": {"algorithm": "sweep", "parameter": "torque",
                                    "min": -31.3, "max": -31.001, "max_points": 2},
                   "output": {"plots": False, "progress": False}})
    br = res.branches[0]
    failures = br.raw.info["failures"]
    assert len(failures) == 1 and "torque = -31.001" in failures[0]
    assert "no return to the section" in failures[0] and "nothing recorded" in failures[0]
    assert br["torque"].tolist() == [-31.3, -31.3] and br["restarted"].tolist() == [1, 1]
    fig = res.plot()
    lines = [ln for ln in fig.axes[0].get_lines() if len(ln.get_xdata()) > 1]
    assert lines and all(ln.get_linestyle() == "None" and ln.get_marker() == "."
                         for ln in lines)
