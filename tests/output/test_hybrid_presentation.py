"""Reports that fit the system.

* forced hybrid systems continued in their forcing frequency are presented as frequency-response
  curves (response amplitude of the impacting coordinate vs the forcing frequency), in another
  parameter as bifurcation diagrams of that amplitude; autonomous ones (the double pendulum) as
  bifurcation diagrams of the period in their parameter, never labelled as frequencies;
* the homoclinic fit ``T = c - ln|p - p*| / mu`` only for autonomous systems on a branch ended by
  its period bound (for a forced system the period is ``2 pi / omega``: a fit would invent a
  ``p*``);
* ``report.md`` reads every before -> after in increasing continued parameter.

Oracles: ``period = 2 pi / omega`` (the clock), the closed-form amplitude ``1 / |1 - omega^2|`` of
the non-impacting orbit of ``q'' + q = cos(omega t)``, a synthetic logarithmic law with known
``p*`` and ``mu``, and the stability of the branch points on either side of each event.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import CASES

import nsm_continuation as nsm
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.figures import branches as plots
from nsm_continuation.figures import kit, multipliers
from nsm_continuation.hybrid.homoclinic import homoclinic_fit
from nsm_continuation.output import report
from nsm_continuation.output.files import build_report, event_record

FIG2 = CASES / "impact_oscillator_fig2_sticking.yaml"

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def point(y, s: float, tangent=None, derived=None, stable: bool | None = True) -> Point:
    y = np.asarray(y, dtype=float)
    mult = None if stable is None else np.array([0.5 if stable else 2.0])
    return Point(y=y, s=s, tangent=np.zeros_like(y) if tangent is None else
                 np.asarray(tangent, dtype=float), tests={}, multipliers=mult,
                 trivial_error=0.0, n_unstable=0 if stable in (True, None) else 1,
                 derived=dict(derived or {}), bordered_det=1.0)


def texts(fig) -> str:
    """Every text a figure shows (titles, axis labels, legend entries)."""
    out = []
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        leg = ax.get_legend()
        if leg is not None:
            out += [t.get_text() for t in leg.get_texts()]
    return "\n".join(out)


# ---------------------------------------------------------------------- forced systems
def test_forced_oscillator_in_omega_is_a_frequency_response_curve() -> None:
    pr = nsm.problem("impact_oscillator", {})
    assert pr.hybrid.forcing_frequency == "omega" and pr.parameter == "omega"
    assert pr.response_coordinate == "q"          # H = q - gap depends on q
    assert pr.presentation.diagram_title == "Frequency-response curve"
    assert pr.presentation.fep_axes == ("omega", "amplitude_q")
    assert pr.presentation.fep_labels == (r"forcing frequency $\omega$",
                                          r"response amplitude $(\max q - \min q)/2$")
    assert pr.presentation.diagram_yscale == "linear"
    assert pr.presentation.csv_head == ["omega", "amplitude_q", "max_q", "min_q",
                                        "min_impact_normal_velocity", "period",
                                        "sticking_time",
                                        "n_impacts_before_chatter"]
    # the impacting coordinate of the two-mass chain is q2 (H = gap - q2), not q1
    chain = nsm.problem("two_mass_chain", {})
    assert chain.response_coordinate == "q2"
    assert chain.presentation.fep_axes == ("omega", "amplitude_q2")
    assert chain.presentation.diagram_title == "Frequency-response curve"


def test_forced_oscillator_in_the_gap_is_a_bifurcation_diagram_of_the_amplitude() -> None:
    pr = nsm.problem("impact_oscillator", {})
    pr.parameter_bounds("gap", -1.0, 1.0)
    assert pr.presentation.diagram_title == "Bifurcation diagram"
    assert pr.presentation.fep_axes == ("gap", "amplitude_q")
    assert pr.presentation.fep_labels[0] == r"stop position $\sigma$ (gap)"  # no frequency
    assert pr.presentation.csv_head[:2] == ["gap", "amplitude_q"]


def test_amplitude_comes_from_the_extremes_and_degrades_to_nan() -> None:
    pr = nsm.problem("impact_oscillator", {})
    assert pr.response_quantities({"max_q": 1.5, "min_q": -0.25}) == {"amplitude_q": 0.875}
    assert np.isnan(pr.response_quantities({"max_q": 1.5})["amplitude_q"])
    assert np.isnan(pr.response_value({}))
    assert pr.response_value({"amplitude_q": 0.3, "max_q": 9.0, "min_q": 0.0}) == 0.3


@pytest.fixture(scope="module")
def fig2_run(tmp_path_factory: pytest.TempPathFactory):
    res = nsm.run(FIG2, {"continuation.max_points": 4, "start.transient": 10})
    out = res.save(tmp_path_factory.mktemp("fig2") / "out")
    return res, out


def test_short_forced_run_writes_a_frequency_response(fig2_run) -> None:
    res, out = fig2_run
    pr = res.run_result.problem
    rep = json.loads((out / "report.json").read_text())
    assert "fep.png" in rep["figures"] and "impacts_vs_omega.png" in rep["figures"]
    assert (out / "impacts_vs_omega.png").stat().st_size > 0
    with open(out / "branch_0.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) >= 3
    assert list(rows[0])[:8] == pr.presentation.csv_head
    # the period of a forced period-1 orbit is the forcing period: an independent check that
    # the columns are what they say
    for r in rows:
        assert float(r["period"]) == pytest.approx(2 * np.pi / float(r["omega"]), rel=1e-9)
        assert float(r["sticking_time"]) > 0
    # no homoclinic fit for a forced system, though its period varies along the branch
    assert all("homoclinic_fit" not in b for b in rep["problem_results"]["branches"])
    if rows[0]["max_q"] not in ("", "nan"):  # the extremes are simulated
        for r in rows:
            # the sticking orbits rest on the stop q = gap = 0: min q is the gap
            assert float(r["min_q"]) == pytest.approx(0.0, abs=1e-8)
            assert float(r["amplitude_q"]) == pytest.approx(
                0.5 * (float(r["max_q"]) - float(r["min_q"])), rel=1e-12)
    # the drawn diagram
    fig = plots.diagram(res.run_result)
    ax = fig.axes[0]
    assert ax.get_title() == "Frequency-response curve"
    assert (ax.get_xlabel(), ax.get_ylabel()) == pr.presentation.fep_labels
    assert ax.get_yscale() == "linear"


def test_amplitude_of_a_non_impacting_orbit_is_the_closed_form() -> None:
    """``zeta = 0`` and the stop far away (``gap = -10``): the only ``2 pi / omega``-periodic
    orbit of ``q'' + q = cos(omega t)`` (``1 / omega`` not an integer) is
    ``q = cos(omega t) / (1 - omega^2)``, amplitude ``1 / |1 - omega^2|``."""
    pr = nsm.problem("impact_oscillator", {"zeta": 0.0, "gap": -10.0, "omega": 0.4})
    res = nsm.continuation(pr, [1 / (1 - 0.16), 0.0, 0.4], parameter="omega", min=0.37,
                           max=0.46, max_points=5, newton_tol=1e-9,
                           analysis={"stability": False})
    (br,) = res.run_result.branches
    assert len(br.points) >= 5
    for p in br.points:
        w = p.y[pr.parameter_index]
        assert p.y[0] == pytest.approx(1 / (1 - w * w), rel=1e-9)   # the orbit itself
        assert p.derived["n_impacts"] == 0
    for p in br.points:
        w = p.y[pr.parameter_index]
        assert p.derived["max_q"] == pytest.approx(1 / abs(1 - w * w), rel=1e-8)
        assert pr.response_value(p.derived) == pytest.approx(1 / abs(1 - w * w), rel=1e-8)
        # what the CSV, the diagram and the report show
        assert kit.quantity(pr, p, "amplitude_q") == pytest.approx(1 / abs(1 - w * w),
                                                                      rel=1e-8)


# ---------------------------------------------------------------------- autonomous systems
@pytest.mark.parametrize("parameter", ["d", "torque", "restitution"])
def test_pendulum_is_a_bifurcation_diagram_in_its_parameter(parameter: str,
                                                            tmp_path: Path) -> None:
    pr = nsm.problem("double_pendulum", {})
    pr.parameter_bounds(parameter, None, None)
    assert pr.hybrid.forcing_frequency is None and pr.response_key is None
    assert pr.presentation.diagram_title == "Bifurcation diagram"
    assert pr.presentation.fep_axes == (parameter, "period")
    assert pr.presentation.fep_labels == (pr.presentation.label(parameter),
                                          "period (return time to the section)")
    assert pr.presentation.diagram_yscale == "log"
    assert pr.presentation.extra_plots(tmp_path, [], (None, None)) == []
    # drawn: titled and labelled by the parameter, nothing about frequencies
    ip = pr.parameter_index
    pts = []
    for k, p in enumerate(np.linspace(0.4, 0.6, 6)):
        y = np.zeros(pr.dim)
        y[ip] = p
        pts.append(point(y, 0.1 * k, derived={"period": 7.0 + k}))
    res = SimpleNamespace(problem=pr, branches=[Branch(0, "b", pts, [], {})],
                          case=SimpleNamespace(name="pendulum"))
    fig = plots.diagram(res)
    assert fig.axes[0].get_title() == "Bifurcation diagram"
    assert fig.axes[0].get_xlabel() == pr.presentation.label(parameter)
    assert "frequency" not in texts(fig).lower()
    assert multipliers.multipliers_along(res, tmp_path / "m.png")
    # the multiplier figure's axis is the parameter too, and its file is named for it
    assert multipliers.along_name(res) == f"multipliers_vs_{parameter}.png"
    assert multipliers.multipliers_plane(res, tmp_path / "p.png")


# ---------------------------------------------------------------------- homoclinic fit
def _branch(pr, ps, Ts, kinds=()) -> Branch:
    ip = pr.parameter_index
    pts = []
    for k, (p, T) in enumerate(zip(ps, Ts, strict=True)):
        y = np.zeros(pr.dim)
        y[ip] = p
        pts.append(point(y, 0.01 * k, derived={"period": float(T)}))
    return Branch(0, "b", pts, [Event(k, pts[-1]) for k in kinds], {})


def test_homoclinic_fit_only_for_autonomous_branches_ended_by_the_period_bound() -> None:
    # autonomous: a synthetic logarithmic law with known p* and mu is recovered
    pend = nsm.problem("double_pendulum", {})
    pend.parameter_bounds("torque", None, None)
    p_star, mu, c = -31.0017, 0.29, 2.0
    ps = p_star - np.geomspace(0.05, 1e-7, 30)
    Ts = c - np.log(np.abs(ps - p_star)) / mu
    (rec,) = pend.presentation.report_extras(
        [_branch(pend, ps, Ts, ["homoclinic_approach"])])["branches"]
    fit = rec["homoclinic_fit"]
    assert fit["p_star"] == pytest.approx(p_star, abs=1e-8)
    assert fit["mu_unstable"] == pytest.approx(mu, rel=1e-3)
    # the same data without the period bound having ended the branch: no fit
    (rec,) = pend.presentation.report_extras([_branch(pend, ps, Ts)])["branches"]
    assert "homoclinic_fit" not in rec
    # forced: period 2 pi / omega doubles as omega halves; the fit would "succeed" (p* ~ 0
    # reported before) but is never attempted, even with a homoclinic_approach event
    osc = nsm.problem("impact_oscillator", {})
    ws = np.linspace(0.6, 0.25, 30)
    assert homoclinic_fit(ws, 2 * np.pi / ws) is not None
    (rec,) = osc.presentation.report_extras([_branch(osc, ws, 2 * np.pi / ws,
                                        ["homoclinic_approach"])])["branches"]
    assert "homoclinic_fit" not in rec and "amplitude_q_range" in rec


# ---------------------------------------------------------------------- before -> after
def _rep(branches: list[Branch], parameter: str) -> dict:
    return {"case": {"name": "t", "description": ""}, "problem": "toy",
            "continuation": {"parameter": parameter, "window": [None, None]},
            "timings": {"n_points": 0, "total_s": 0.0}, "event_columns": ["p"],
            "branches": [{"id": b.id, "label": b.label, "n_points": len(b.points),
                          "admissible_points": len(b.points), "parameter_range": None,
                          "termination": "", "csv": f"branch_{b.id}.csv",
                          "events": [event_record(ev) for ev in b.events]}
                         for b in branches]}


def _rows(md: str) -> dict[float, str]:
    """Event rows of report.md keyed by the value of the column ``p``."""
    out = {}
    for line in md.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) > 3 and cells[1] == "stability_change":
            out[float(cells[2])] = line
    return out


def test_before_after_read_in_increasing_parameter_constructed() -> None:
    """A branch continued from p = 3 towards decreasing p; the orbit is stable above 2,
    unstable on (1, 2), stable below 1. In continuation order the change at p = 2 reads
    "yes -> no" and the one at p = 1 "no -> yes"; in increasing p (report.md) the change at
    p = 1 reads "yes -> no" and the one at p = 2 "no -> yes", details included."""
    t = [0.0, -1.0]                     # (x, p): moving towards decreasing p
    pts = [point([0.0, p], s, t, {"p": p}, stable=(p > 2 or p < 1))
           for s, p in enumerate([3.0, 2.5, 1.5, 0.5])]

    def ev(p: float, s: float, before: bool) -> Event:
        q = point([0.0, p], s, t, {"p": p}, stable=not before)
        return Event("stability_change", q, "stable -> unstable" if before else
                     "unstable -> stable", data={"stable_before": before,
                                                 "stable_after": not before,
                                                 "n_outside_before": int(not before),
                                                 "n_outside_after": int(before)})
    br = Branch(0, "b", pts, [ev(2.0, 1.0, True), ev(1.0, 2.0, False)], {})
    assert [report.parameter_direction(e.point, 1) for e in br.events] == [-1, -1]
    rep = _rep([br], "p")
    md_raw = report.markdown(rep)   # without directions: continuation order, and says so
    assert "change (as continued)" in md_raw
    report.annotate_parameter_directions(rep, [br], 1)
    md = report.markdown(rep)
    rows = _rows(md)
    assert "stable: yes -> no (0 -> 1 outside)" in rows[1.0]
    assert "| stable -> unstable |" in rows[1.0]
    assert "stable: no -> yes (1 -> 0 outside)" in rows[2.0]
    assert "| unstable -> stable |" in rows[2.0]
    assert "change (increasing p)" in md and "direction of increasing `p`" in md
    # report.json keeps the continuation order
    assert rep["branches"][0]["events"][0]["stable_before"] is True

    # a branch continued towards increasing p is left as recorded
    t_up = [0.0, 1.0]
    up = Branch(1, "u", pts[::-1], [Event("stability_change",
                                          point([0.0, 1.0], 1.0, t_up, {"p": 1.0}),
                                          "stable -> unstable",
                                          data={"stable_before": True,
                                                "stable_after": False})], {})
    rep = _rep([up], "p")
    report.annotate_parameter_directions(rep, [up], 1)
    assert "stable: yes -> no" in _rows(report.markdown(rep))[1.0]


def test_parameter_direction_without_tangent_and_at_a_fold() -> None:
    # no tangent (the lattice engine): from the neighbours, with the half's arclength sign
    pts = [point([0.0, p], s) for s, p in [(-2.0, 0.0), (-1.0, 1.0), (0.0, 2.0), (1.0, 1.5),
                                            (2.0, 1.0)]]
    br = Branch(0, "b", pts, [], {})
    # backward half (s < 0), continued towards s = -2, p decreasing 1 -> 0
    assert report.parameter_direction(point([0.0, 0.5], -1.5), 1, br) == -1
    # forward half, continued towards s = 2, p decreasing 2 -> 1
    assert report.parameter_direction(point([0.0, 1.2], 1.5), 1, br) == -1
    rising = Branch(0, "r", [point([0.0, p], s) for s, p in [(0.0, 0.0), (1.0, 1.0)]], [], {})
    assert report.parameter_direction(point([0.0, 0.5], 0.5), 1, rising) == 1
    # a fold: the tangent has no parameter component; no order, the change is kept as
    # continued and marked
    fold = point([0.0, 1.0], 0.0, [1.0, 1e-13])
    assert report.parameter_direction(fold, 1) == 0
    e = {"stable_before": True, "stable_after": False, "parameter_direction": 0}
    assert report.change_text(report.in_parameter_order(e)) == \
        "stable: yes -> no (as continued: the parameter turns here)"


def test_reversed_detail() -> None:
    assert report.reversed_detail("event sequence IC83S -> I (not located: within the step)") \
        == "event sequence I -> IC83S (not located: within the step)"
    assert report.reversed_detail("test function 'clearance' becomes negative: admissibility "
                                  "lost") == ("test function 'clearance' becomes positive: "
                                              "admissibility regained")
    assert report.reversed_detail("test function 'sticking_time' becomes defined") == \
        "test function 'sticking_time' ceases to be defined"
    # a pair in brackets keeps its brackets (it read "+1.59e-08) -> (-1.25e-12")
    assert report.reversed_detail("event function 'grazing_margin' vanishes (+1.59e-08 -> "
                                  "-1.25e-12)") == ("event function 'grazing_margin' vanishes "
                                                    "(-1.25e-12 -> +1.59e-08)")
    e = {"signature_before": "I", "signature_after": "IC3S", "parameter_direction": -1,
         "detail": "event sequence I -> IC3S"}
    o = report.in_parameter_order(e)
    assert (o["signature_before"], o["signature_after"], o["detail"]) == \
        ("IC3S", "I", "event sequence IC3S -> I")
    assert report.change_text(o) == "signature: IC3S -> I"


def test_before_after_on_a_real_run_agree_with_the_branch_points() -> None:
    """The default chain case runs towards decreasing T (the continued parameter): each
    stability change, read in increasing T in report.md, must match the stability of the
    branch points on either side of it (the point of lower T before, higher T after)."""
    res = nsm.run(CASES / "ndof_default.yaml", {"output.plots": False})
    rr = res.run_result
    pr = rr.problem
    ip = pr.parameter_index
    (br,) = rr.branches
    rep = build_report(rr)
    report.annotate_parameter_directions(rep, rr.branches, ip)
    records = rep["branches"][0]["events"]
    changes = [(ev, rec) for ev, rec in zip(br.events, records, strict=True)
               if ev.kind == "stability_change"]
    assert len(changes) >= 6
    assert all(rec["parameter_direction"] == -1 for _, rec in changes)
    # the tangent and the neighbouring points tell the same direction
    for ev, rec in changes:
        bare = Point(**{**ev.point.__dict__, "tangent": np.zeros_like(ev.point.tangent)})
        assert report.parameter_direction(bare, ip, br) == rec["parameter_direction"]
    md = report.markdown(rep)
    checked = 0
    ss = np.array([p.s for p in br.points])
    for ev, rec in changes:
        s = ev.point.s
        lo = br.points[int(np.searchsorted(ss, s)) - 1]
        hi = br.points[int(np.searchsorted(ss, s, side="right"))]
        others = [e for e in changes if e[0] is not ev and lo.s < e[0].point.s < hi.s]
        if others or lo.stable is None or hi.stable is None:
            continue   # two crossings between the same two points: no neighbour oracle
        low, high = sorted((lo, hi), key=lambda q: q.y[ip])
        o = report.in_parameter_order(rec)
        assert (o["stable_before"], o["stable_after"]) == (low.stable, high.stable)
        T = float(ev.point.y[ip])
        row = next(line for line in md.splitlines() if "stability_change" in line
                   and re.search(rf"\| {re.escape(report._fmt(T, 12))} \|", line))
        word = {True: "yes", False: "no"}
        assert f"stable: {word[low.stable]} -> {word[high.stable]}" in row
        checked += 1
    assert checked >= 5


def test_events_at_a_limit_point_read_in_the_continuation_order() -> None:
    """The parameter turns at a limit point (a fold of the tangent's parameter component):
    a stability change located there with it reads in the continuation order too, whatever
    the parameter component of its own point's tangent (that read the other way round: "no ->
    yes" next to the fold's "yes -> no"). A fold of the multipliers (a pair at +1, the tangent
    not involved) leaves the others alone."""
    from nsm_continuation.core.records import Branch, Event, Point

    def point(s: float, tp: float) -> Point:
        return Point(y=np.array([0.0, 1.0]), s=s, tangent=np.array([np.sqrt(1 - tp * tp), tp]),
                     tests={}, multipliers=None, trivial_error=0.0, n_unstable=0, derived={},
                     bordered_det=1.0)

    for test, expected in (("tangent", 0), (None, -1)):
        fold = Event("fold", point(1.0, 0.0), "", data={"test": test} if test else {})
        change = Event("stability_change", point(1.0, -0.3), "stable -> unstable")
        br = Branch(0, "b", [point(0.0, -0.5), point(2.0, 0.5)], [fold, change], {}, {})
        rep = {"branches": [{"events": [{}, {}]}]}
        report.annotate_parameter_directions(rep, [br], 1)
        assert rep["branches"][0]["events"][0]["parameter_direction"] == 0
        assert rep["branches"][0]["events"][1]["parameter_direction"] == expected
