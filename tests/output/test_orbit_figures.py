"""Orbit figures (``output.orbits``, ``Problem.orbit``, :mod:`nsm_continuation.figures.orbits`),
each
against an oracle independent of what it checks:

* the chain's closed-form orbit (free flight from the post-impact state, eqs. 2.9-2.10/5.4)
  against a numerical integration of ``M u'' + K u = 0`` (scipy, no modal data), the impact law
  mapping its state at ``T-`` to the one at ``0``, ``u_N(0) = g`` and ``u_N <= g`` on admissible
  orbits (Definition 2.2);
* a hybrid orbit (impact oscillator, Fig. 2; double pendulum, Fig. 8(a)) ends where it started
  (a converged periodic orbit), its sticking intervals add up to the problem's derived
  ``sticking_time``, the oscillator's flight up to its first impact is the closed-form solution
  of ``q'' + 2 zeta q' + q = cos(omega t)`` (``tests/oracles/linear_flight.py``) and the
  pendulum's ``dY`` is the time derivative of its ``Y``;
* every impact of a hybrid orbit is marked, those of a chattering sequence that breaks off
  too (the two-mass chain past its grazing): as many as the derived ``n_impacts``, at the
  velocity reversals on the wall of the sampled orbit;
* the schema: an unknown view or point kind, a view the problem does not draw, or a problem
  that draws no orbits, is refused by the CLI with exit status 2 and one line naming the key,
  nothing written; what can only be known after computing (a branch the run does not have, a
  point kind it did not locate, a ``log`` signal the time view does not draw) is a warning in
  report.md and on stderr; the figures are written by a small case, and only when asked for;
* the API (``Result.orbit``, ``Result.plot_orbits``) refuses a bad argument with one line
  naming it and what it may be; a long title is wrapped inside the figure.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from oracles.linear_flight import free_flight
from scipy.integrate import solve_ivp

import nsm_continuation as nsm
from nsm_continuation import cli

CHAIN = "yaml_cases/ndof_default.yaml"
FAST = {"output.plots": False, "continuation.max_points": 25, "analysis.stability": False}


@pytest.fixture(scope="module")
def chain_result():
    return nsm.run(CHAIN, FAST)


def test_chain_orbit_is_the_integrated_free_flight(chain_result):
    pr = chain_result.problem
    p = chain_result.run_result.branches[0].points[-1]
    tr = pr.presentation.orbit(p.y, periods=1)
    u0, du0, T = pr.state(p.y)
    N = pr.N
    A = np.linalg.solve(pr.M, pr.K)

    def rhs(_t, z):
        return np.concatenate([z[N:], -A @ z[:N]])

    sol = solve_ivp(rhs, (0.0, T), np.concatenate([u0, du0]), method="DOP853", rtol=1e-13,
                    atol=1e-14, t_eval=tr.t)
    assert sol.success
    for i in range(N):
        assert np.max(np.abs(tr.signals[f"u{i + 1}"] - sol.y[i])) < 1e-8
        assert np.max(np.abs(tr.signals[f"du{i + 1}"] - sol.y[N + i])) < 1e-8
    assert tr.period == T and tr.t[0] == 0.0 and tr.t[-1] == pytest.approx(T, abs=1e-14)


def test_chain_orbit_is_periodic_through_the_impact_law(chain_result):
    pr = chain_result.problem
    g, c = pr.g, pr.c
    for p in chain_result.run_result.branches[0].points[::6]:
        tr = pr.presentation.orbit(p.y, periods=2)
        n = tr.t.size // 2
        before = np.array([tr.signals[f"u{i + 1}"][n - 1] for i in range(pr.N)])
        vel = np.array([tr.signals[f"du{i + 1}"][n - 1] for i in range(pr.N)])
        vel[c] = -vel[c]  # e = 1: u_c'+ = -u_c'-
        after = np.array([tr.signals[f"u{i + 1}"][n] for i in range(pr.N)])
        vel0 = np.array([tr.signals[f"du{i + 1}"][n] for i in range(pr.N)])
        scale = 1.0 + np.abs(vel).max()
        assert np.max(np.abs(before - after)) < 1e-9 * scale
        assert np.max(np.abs(vel - vel0)) < 1e-9 * scale
        uc = tr.signals[f"u{c + 1}"]
        assert uc[0] == pytest.approx(g, abs=1e-12)
        if p.admissible:
            assert uc.max() <= g + 1e-9 * abs(g)
        assert tr.marks == [(0.0, "impact"), (tr.period, "impact"), (2 * tr.period, "impact")]
        assert tr.views["phase"] == (f"u{c + 1}", f"du{c + 1}")


@pytest.fixture(scope="module")
def oscillator():
    res = nsm.run("yaml_cases/impact_oscillator_fig2_sticking.yaml",
                  {"output.plots": False, "continuation.max_points": 2,
                   "analysis.stability": False})
    return res


def test_hybrid_orbit_is_closed_and_sticks_as_derived(oscillator):
    pr = oscillator.problem
    p = oscillator.run_result.branches[0].points[0]
    tr = oscillator.orbit(branch=0, point=0)
    assert tr.period == pytest.approx(2 * np.pi / p.y[pr.parameter_index], rel=1e-12)
    for name in ("q", "qdot"):
        s = tr.signals[name]
        assert abs(s[-1] - s[0]) < 1e-7 * (1.0 + np.abs(s).max())
    stick = sum(b - a for a, b, kind in tr.intervals if kind == "sticking")
    assert stick == pytest.approx(p.derived["sticking_time"], rel=1e-7)
    assert stick > 0
    kinds = [k for _, k in tr.marks]
    assert "impact" in kinds and "release" in kinds
    # Fig. 2: the orbit never crosses the stop q = gap and sticks on it
    assert tr.signals["q"].min() >= -1e-9
    a, b, _ = tr.intervals[0]
    on = (tr.t > a) & (tr.t < b)
    assert np.all(np.abs(tr.signals["q"][on]) < 1e-8)


def test_oscillator_flight_is_its_closed_form(oscillator):
    pr = oscillator.problem
    tr = oscillator.orbit(branch=0, point=-1)
    p = oscillator.run_result.branches[0].points[-1]
    omega = float(p.y[pr.parameter_index])
    t_hit = min(t for t, k in tr.marks if k == "impact")
    flight = tr.t < t_hit
    q, v = free_flight(tr.t[flight], 0.0, tr.signals["q"][0], tr.signals["qdot"][0],
                       zeta=0.1, omega=omega)
    assert np.max(np.abs(q - tr.signals["q"][flight])) < 1e-7
    assert np.max(np.abs(v - tr.signals["qdot"][flight])) < 1e-7
    # the phase is the clock omega t (eq. 4)
    assert np.allclose(tr.signals["phase"], omega * tr.t, atol=1e-9)


def test_pendulum_orbit_outputs_and_closure():
    res = nsm.run("yaml_cases/pendulum_sec6_1_complete_to_incomplete.yaml",
                  {"output.plots": False, "continuation.max_points": 2,
                   "analysis.stability": False})
    p = res.run_result.branches[0].points[0]
    tr = res.orbit(0, 0)
    for name in ("q2", "q1dot", "q2dot"):
        s = tr.signals[name]
        assert abs(s[-1] - s[0]) < 1e-7 * (1.0 + np.abs(s).max())
    assert tr.signals["q1"][-1] - tr.signals["q1"][0] == pytest.approx(-2 * np.pi, abs=1e-12)
    assert sum(b - a for a, b, _ in tr.intervals) == pytest.approx(
        p.derived["sticking_time"], rel=1e-7)
    # dY is the time derivative of Y: Y(t) - Y(0) is the integral of dY (trapezoid rule) over
    # the free flight before the first impact
    t, Y, dY = tr.t, tr.signals["Y"], tr.signals["dY"]
    flight = t < min(tm for tm, _ in tr.marks)
    tf, Yf, dYf = t[flight], Y[flight], dY[flight]
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (dYf[1:] + dYf[:-1]) * np.diff(tf))])
    # (the rule's error h^2/12 int |Y'''| ~ 2e-4 at the recorded steps; a wrong dY: O(1))
    assert np.max(np.abs(Yf - Yf[0] - integral)) < 1e-3 * np.abs(Y).max()
    # the wall X = -d is never crossed
    assert tr.signals["X"].min() >= -0.5 - 1e-9
    assert tr.views["time"] == ("X", "dY")


@pytest.mark.parametrize("orbits, key", [
    ("{views: [sideways]}", "output.orbits.views[0]"),
    ("{points: [first, collision]}", "output.orbits.points[1]"),
    ("{periods: 0}", "output.orbits.periods"),
])
def test_bad_orbits_are_refused(tmp_path, capsys, orbits, key):
    out = tmp_path / "out"
    code = cli.main(["run", CHAIN, "--out", str(out), "--quiet", "--set",
                     f"output.orbits={orbits}"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and key in err
    assert not out.exists()


def test_a_problem_without_orbits_is_refused(capsys):
    code = cli.main(["validate", "yaml_cases/bar_continuum_main.yaml", "--set",
                     "output.orbits={}"])
    assert code == 2
    assert "output.orbits: problem 'bar_continuum' does not draw its orbits" in \
        capsys.readouterr().err


def test_the_figures_are_written_when_asked(tmp_path):
    orbits = {"points": ["first", "grazing", 1.0], "views": ["time", "phase", "manifold"],
              "figures": {"time": "Fig. 5.2"}}
    res = nsm.run(CHAIN, {**FAST, "output.orbits": orbits})
    res.save(tmp_path / "with")
    for name in ("orbits_time.png", "orbits_phase.png", "manifold.png"):
        assert (tmp_path / "with" / name).stat().st_size > 10_000
    plain = nsm.run(CHAIN, {**FAST, "continuation.max_points": 4})
    plain.save(tmp_path / "without")
    assert not list((tmp_path / "without").glob("orbits_*.png"))
    assert not (tmp_path / "without" / "manifold.png").exists()
    # the API draws the same views; a point it does not know is a CaseError naming it
    fig = res.plot_orbits(points=["last"], view="phase")
    assert fig.axes[0].get_xlabel() == "displacement $u_{5}$"
    with pytest.raises(nsm.CaseError, match=r"plot_orbits.points\[0\]"):
        res.plot_orbits(points=["nowhere"])


@pytest.fixture(scope="module")
def two_mass():
    """The two-mass chain just past its grazing at omega = 0.7720 (two impacts per period,
    the first with the wall's acceleration pushing the mass back: a chattering sequence that
    the second impact breaks off)."""
    return nsm.run("yaml_cases/chain_two_mass_wall.yaml",
                   {"parameters.omega": 0.7735, "continuation.max_points": 2,
                    "analysis.stability": False, "analysis.bifurcations": False,
                    "output.plots": False})


def test_every_impact_is_marked(two_mass):
    p = two_mass.run_result.branches[0].points[0]
    assert p.derived["n_impacts"] == 2
    tr = two_mass.orbit(0, 0, periods=2)
    impacts = [t for t, kind in tr.marks if kind == "impact"]
    # independent of the simulator's events: the sampled orbit's velocity reversals on the
    # wall q2 = gap (moving in, then out, at one instant)
    q2, v2 = tr.signals["q2"], tr.signals["q2dot"]
    on = np.abs(q2 - 0.5) < 1e-9
    rev = np.nonzero(on[:-1] & on[1:] & (v2[:-1] > 0) & (v2[1:] < 0))[0]
    assert len(impacts) == len(rev) == 2 * p.derived["n_impacts"]
    assert impacts == pytest.approx(tr.t[rev].tolist(), abs=1e-12)


def test_a_view_the_problem_does_not_draw_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", "yaml_cases/chain_two_mass_wall.yaml", "--out", str(out), "--quiet",
                     "--set", "output.orbits={views: [time, manifold]}"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "output.orbits.views[1]" in err
    assert "'manifold'" in err and "time, phase" in err
    assert not out.exists()


def test_what_cannot_be_drawn_is_a_warning(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", CHAIN, "--out", str(out), "--quiet",
                     "--set", "continuation.max_points=4", "--set", "analysis.stability=false",
                     "--set", "output.plots=false", "--set",
                     "output.orbits={branches: [0, 5], points: [first, period_doubling], "
                     "log: [u1, u5]}"])
    assert code == 0
    err = capsys.readouterr().err
    report = (out / "report.md").read_text()
    for key, what in (("output.orbits.branches[1]", "no branch 5"),
                      ("output.orbits.points[1]", "'period_doubling'"),
                      ("output.orbits.log[0]", "'u1' is not a signal of the time view")):
        line = next(ln for ln in err.splitlines() if key in ln)
        assert line.startswith("warning: ") and what in line
        assert f"- {line.removeprefix('warning: ')}" in report
    assert "log[1]" not in err  # u5 is drawn


def test_bad_api_arguments_name_themselves(chain_result, two_mass):
    n = len(chain_result.run_result.branches[0].points)
    for call, match in (
            (lambda: chain_result.orbit(branch=0, point=0, periods=0), r"^periods: 0 .* 1 to 50"),
            (lambda: chain_result.orbit(0, point=99), rf"^point: 99 .*{n} points"),
            (lambda: chain_result.orbit(3, 0), r"^branch: 3 .*ids: 0"),
            (lambda: two_mass.plot_orbits(view="manifold"),
             r"^plot_orbits.view: .*'manifold'.*time, phase"),
            (lambda: two_mass.plot_orbits(points=["first", "sticking_lost"]),
             r"^plot_orbits.points\[1\]: 'sticking_lost' selects no point"),
            (lambda: two_mass.plot_orbits(points=[]), r"^plot_orbits.points: empty"),
            (lambda: two_mass.plot_orbits(log=["q1"]), r"^plot_orbits.log\[0\]: 'q1'.*q2"),
            (lambda: chain_result.plot_orbits(periods=0), r"^plot_orbits.periods: 0")):
        with pytest.raises(ValueError, match=match) as info:
            call()
        assert len(str(info.value).splitlines()) == 1
    plt.close("all")


def test_a_long_manifold_title_stays_in_the_figure(chain_result):
    br = chain_result.run_result.branches[0]
    label = br.label
    try:
        br.label = "other branch at the branch_point #1 of branch 0 of this run " * 2
        fig = chain_result.plot_orbits(view="manifold")
        fig.canvas.draw()
        box = fig.axes[0].title.get_window_extent()
        assert 0 <= box.x0 and box.x1 <= fig.bbox.width
    finally:
        br.label = label
        plt.close("all")
