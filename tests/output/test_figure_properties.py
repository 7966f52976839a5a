"""What a referee checks on a figure, checked on cheap runs and on branches built by hand:

* the legend lists exactly the labelled artists drawn, each once (no style that is not drawn);
* every located event is drawn, with a marker per kind, a readable name, and a default marker
  for a kind no style is declared for (the hybrid kinds included);
* a log axis only where the data span more than a decade, plain tick labels otherwise;
  multipliers that are zero to rounding are not plotted at 1e-17 on a log axis;
* axis labels are symbols or words, never raw identifiers; titles are not the case's name;
* mode colours leave out the stability red and the Neimark-Sacker green; the poles of w_N
  break its curve; events that crowd are zoomed; orbits that nearly coincide are told apart;
* the closed forms drawn over the impact oscillator agree with a continuation of the
  simulator and with the independent oracle of its period doublings.
"""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers import CASES
from matplotlib.collections import PathCollection
from matplotlib.colors import to_rgba
from matplotlib.lines import Line2D
from oracles import impact_oscillator as oracle
from scipy.optimize import brentq

import nsm_continuation as nsm
from nsm_continuation.core.records import Branch, Event, OrbitTrace, Point, register_event_kinds
from nsm_continuation.figures import branches, multipliers, orbits
from nsm_continuation.figures.orbit_selection import Chosen
from nsm_continuation.figures.styles import DEFAULT_MARKER, EVENT_STYLES, PALETTE

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

#: a kind no style is declared for (registered as a family would declare it)
NEW_KIND = "figure_test_new_kind"
register_event_kinds({NEW_KIND: "a kind the figures have no style for"}, "test_figure_properties")

#: a label that is an identifier: letters, digits and underscores with an underscore or a
#: digit, or a Greek letter spelled out (independent of nsm_continuation.core.symbols)
RAW = re.compile(r"^(?=.*[_0-9])[A-Za-z][A-Za-z0-9_]*$|^(omega|zeta|mu|sigma|tau|lambda)$")


def point(y, s: float, derived=None, stable: bool | None = True, mult=None,
          trivial_error: float = 0.0) -> Point:
    y = np.asarray(y, dtype=float)
    if mult is None:
        mult = None if stable is None else np.array([0.5 if stable else 2.0])
    return Point(y=y, s=s, tangent=np.zeros_like(y), tests={}, multipliers=mult,
                 trivial_error=trivial_error, n_unstable=0 if stable in (True, None) else 1,
                 derived=dict(derived or {}), bordered_det=1.0)


def labelled(ax) -> list[str]:
    """Labels of the drawn artists of ``ax`` (lines with data, collections, patches)."""
    out = []
    for a in [*ax.lines, *ax.collections, *ax.patches]:
        lab = a.get_label()
        if lab.startswith("_"):
            continue
        if isinstance(a, Line2D) and not np.isfinite(
                np.asarray(a.get_xdata(), dtype=float)).any():
            continue
        out.append(lab)
    return out


def assert_legend_is_what_is_drawn(fig) -> None:
    axes = [ax for ax in fig.axes if ax.get_legend() is not None]
    assert axes, "no legend"
    drawn = {lab for ax in fig.axes for lab in labelled(ax)}
    for ax in axes:
        entries = [t.get_text() for t in ax.get_legend().get_texts()]
        assert len(entries) == len(set(entries)), entries
        assert set(entries) == drawn, (set(entries) ^ drawn)


def assert_labels_readable(fig, case_name: str = "") -> None:
    for ax in fig.axes:
        for text in (ax.get_xlabel(), ax.get_ylabel()):
            assert not RAW.match(text.strip()), text
        if case_name:
            assert case_name not in ax.get_title()


def event_lines(ax, kind_name: str) -> list[Line2D]:
    return [ln for ln in ax.lines if ln.get_label() == kind_name]


def assert_events_drawn(ax, res, xk: str, yk: str) -> None:
    """Every event of a kind drawn as a marker sits on a marker of its kind's line."""
    pr = res.problem
    for br in res.branches:
        for ev in br.events:
            if ev.kind == "endpoint":
                continue
            name = EVENT_STYLES[ev.kind].name if ev.kind in EVENT_STYLES else \
                ev.kind.replace("_", " ")
            x, y = ev.point.value(xk, pr.variables), ev.point.value(yk, pr.variables)
            lines = event_lines(ax, name)
            assert lines, f"{ev.kind} not drawn"
            assert any(np.any(np.isclose(ln.get_xdata(), x) & np.isclose(ln.get_ydata(), y))
                       for ln in lines), ev.kind


# ---------------------------------------------------------------------- a hybrid family
def pendulum_result(periods: np.ndarray, kinds: list[str]) -> SimpleNamespace:
    """A branch of the double pendulum continued in ``d`` with ``periods``, unstable on its
    second half, with one event of each of ``kinds`` at successive points."""
    pr = nsm.problem("double_pendulum", {})
    pr.parameter_bounds("d", None, None)
    ip = pr.parameter_index
    pts = []
    for k, T in enumerate(periods):
        y = np.zeros(pr.dim)
        y[ip] = 0.5 + 0.001 * k
        pts.append(point(y, 0.1 * k, {"period": float(T), "sticking_time": 0.1},
                         stable=k < len(periods) // 2))
    events = [Event(kind, pts[2 + 2 * i]) for i, kind in enumerate(kinds)]
    events.append(Event("endpoint", pts[-1]))
    return SimpleNamespace(problem=pr, branches=[Branch(0, "b", pts, events, {})],
                           case=SimpleNamespace(name="pendulum_case_slug"))


HYBRID_KINDS = ["sticking_lost", "impact_sequence_change", "homoclinic_approach", "grazing",
                "asymptote", "period_doubling", NEW_KIND]


def test_hybrid_diagram_draws_every_event_and_lists_only_what_it_draws() -> None:
    res = pendulum_result(np.linspace(6.17, 6.20, 30), HYBRID_KINDS)
    fig = branches.diagram(res)
    ax = fig.axes[0]
    assert_legend_is_what_is_drawn(fig)
    assert_events_drawn(ax, res, "d", "period")
    assert_labels_readable(fig, "pendulum_case_slug")
    entries = [t.get_text() for t in ax.get_legend().get_texts()]
    # both states drawn; no phantom, no "not computed" entry: those styles are not drawn
    assert "admissible, stable" in entries and "admissible, unstable" in entries
    assert not any("phantom" in e or "not computed" in e for e in entries)
    # the kind without a declared style: the default marker, named in words
    (new,) = event_lines(ax, NEW_KIND.replace("_", " "))
    assert new.get_marker() == DEFAULT_MARKER
    # a period over 0.5 %: linear, plain ticks (no "6x10^0")
    assert ax.get_yscale() == "linear"
    fig.canvas.draw()
    assert not any("times" in t.get_text() for t in ax.get_yticklabels())


def test_log_axis_only_over_more_than_a_decade() -> None:
    wide = branches.diagram(pendulum_result(np.geomspace(1.0, 200.0, 30), ["grazing"]))
    narrow = branches.diagram(pendulum_result(np.geomspace(1.0, 9.0, 30), ["grazing"]))
    assert wide.axes[0].get_yscale() == "log"
    assert narrow.axes[0].get_yscale() == "linear"


def test_crowded_events_are_zoomed_and_spread_ones_are_not() -> None:
    res = pendulum_result(np.linspace(6.17, 6.20, 30), ["grazing", "period_doubling"])
    assert len(branches.diagram(res).axes) == 1          # 2 points apart: readable
    pts = res.branches[0].points
    ip = res.problem.parameter_index
    near = point(pts[10].y + 2e-4 * np.eye(len(pts[10].y))[ip], 1.01,
                 {"period": pts[10].derived["period"] + 2e-4})
    res.branches[0].events = [Event("grazing", pts[10]), Event("period_doubling", near),
                              Event("sticking_lost", pts[25])]
    fig = branches.diagram(res)
    main, zoom = fig.axes[0], fig.axes[1]
    lo, hi = zoom.get_xlim()
    assert lo < pts[10].y[res.problem.parameter_index] < hi
    assert (hi - lo) < 0.25 * np.ptp(main.get_xlim())
    assert_events_drawn(main, res, "d", "period")
    assert_legend_is_what_is_drawn(fig)
    # two kinds at one point: no zoom parts them; the second is drawn smaller, on top
    res.branches[0].events = [Event("grazing", pts[10]), Event("period_doubling", pts[10])]
    fig = branches.diagram(res)
    assert len(fig.axes) == 1
    (g,) = event_lines(fig.axes[0], EVENT_STYLES["grazing"].name)
    (d,) = event_lines(fig.axes[0], EVENT_STYLES["period_doubling"].name)
    assert d.get_markersize() < g.get_markersize() and d.get_zorder() > g.get_zorder()


def test_multipliers_zero_to_rounding_are_not_drawn_on_a_log_axis(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Orbits with sticking: two multipliers exact zeros computed as 1e-17, one 7e-4."""
    res = pendulum_result(np.linspace(6.17, 6.20, 8), [])
    for p in res.branches[0].points:
        p.multipliers = np.array([7e-4, 3e-17, -1e-16 + 0j])
        p.trivial_error = 3e-13
    saved: list = []
    monkeypatch.setattr(multipliers, "save", lambda fig, path: saved.append(fig))
    assert multipliers.multipliers_along(res, tmp_path / "m.png")
    (fig,) = saved
    modulus = fig.axes[0]
    drawn = np.concatenate([c.get_offsets()[:, 1] for c in modulus.collections
                            if isinstance(c, PathCollection)])
    np.testing.assert_allclose(drawn, 7e-4)
    assert modulus.get_yscale() == "log"  # 7e-4 to the unit circle: three decades
    assert multipliers.along_name(res) == "multipliers_vs_d.png"
    assert fig.axes[-1].get_ylabel()  # the colour carries |Re lambda|: a colour bar


# ---------------------------------------------------------------------- the chain
@pytest.fixture(scope="module")
def chain_run():
    return nsm.run(CASES / "ndof_default.yaml", {"output.plots": False}).run_result


def test_chain_diagram_lists_what_it_draws_and_marks_every_event(chain_run) -> None:
    fig = branches.diagram(chain_run)
    assert_legend_is_what_is_drawn(fig)
    assert_events_drawn(fig.axes[0], chain_run, "omega", "energy")
    assert_labels_readable(fig, chain_run.case.name)
    # the references of the modes: no colour of the stability legend (red) or of the
    # Neimark-Sacker marker (green)
    forbidden = {to_rgba("tab:red"), to_rgba("tab:green")}
    from nsm_continuation.figures.kit import subplots

    _, ax = subplots()
    chain_run.problem.presentation.plot_decorations(ax, (1.0, 11.0), chain_run.branches)
    assert len(ax.lines) > 10
    assert all(to_rgba(ln.get_color()) not in forbidden for ln in ax.lines)
    assert all(to_rgba(c) not in forbidden for c in PALETTE)


def test_chain_w_n_is_broken_at_its_poles(chain_run, tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Fig. 3.1: w_N goes to +-infinity at each pole k T_j; the drawn curve has a gap there,
    no segment joining the two sides."""
    from nsm_continuation.figures import kit

    pr = chain_run.problem
    saved: list = []
    monkeypatch.setattr(kit, "save", lambda fig, path: saved.append(fig))
    assert pr.presentation.extra_plots(tmp_path, chain_run.branches, (None, None)) == ["w_N.png"]
    lo, hi = 0.05 * pr.T_lin[-1], 1.2 * pr.T_lin[0]
    poles = [t for t, _, _ in pr.poles(lo, hi, 10**6)]
    assert len(poles) > 10
    (curve,) = [ln for ln in saved[0].axes[0].lines if ln.get_label() == "$w_N(T)$"]
    t, w = np.asarray(curve.get_xdata()), np.asarray(curve.get_ydata())
    for tp in poles:
        k = int(np.searchsorted(t, tp))
        assert t[k] == tp and np.isnan(w[k]), tp


# ---------------------------------------------------------------------- closed forms
def test_impact_oscillator_closed_form_is_the_continued_orbit() -> None:
    """A short continuation of the simulated oscillator (zeta = 0, gap = -0.5, e = 0.8) from
    the high-velocity orbit at omega = 1.5: its response amplitude is the closed form's drawn
    over the frequency-response curve, to 1e-6."""
    from nsm_continuation.problems.impacting.impact_oscillator_closed_form import (
        impacting_amplitudes,
    )

    pr = nsm.problem("impact_oscillator", {"zeta": 0.0, "omega": 1.5, "gap": -0.5,
                                           "restitution": 0.8,
                                           "section_phase": float(np.pi)})
    q, qd = oracle.section_state(1.5, -0.5, 0.8, phase=np.pi)
    res = nsm.continuation(pr, [q, qd, 1.5], parameter="omega", min=1.45, max=1.55,
                           max_points=4, newton_tol=1e-10, analysis={"stability": False})
    (br,) = res.run_result.branches
    w = np.array([p.y[pr.parameter_index] for p in br.points])
    amp = np.array([p.derived["amplitude_q"] for p in br.points])
    high, _ = impacting_amplitudes(w, -0.5, 0.8)
    np.testing.assert_allclose(high, amp, rtol=1e-6)
    curves = pr.presentation.closed_forms((1.45, 1.55), [br])
    assert [c[2] for c in curves] == ["one-impact orbits, closed form (O1)"]


def test_period_doubling_curve_closed_form_against_the_oracle() -> None:
    """The drawn U of period doublings in (gap, omega): at gap = -0.5 both arms are the
    roots of the oracle's (O2) function (independent root finding), and its tip lies where
    the case's comment puts it (-0.65177)."""
    from nsm_continuation.problems.impacting.impact_oscillator_closed_form import (
        curve_in_plane,
    )

    f = oracle.period_doubling_function
    upper = brentq(f, 1.05, 1.12, args=(-0.5, 0.8), xtol=1e-14)
    lower = brentq(f, 1.005, 1.03, args=(-0.5, 0.8), xtol=1e-14)
    g, w = curve_in_plane("period_doubling", np.array([-0.7, -0.5]), 0.8)
    at = np.isclose(g, -0.5)
    np.testing.assert_allclose(sorted(w[at]), [lower, upper], rtol=1e-9)
    assert float(np.nanmin(g)) == pytest.approx(-0.65177, abs=1e-3)


# ---------------------------------------------------------------------- orbits
def test_orbits_that_nearly_coincide_are_told_apart() -> None:
    """Two orbits equal to 1e-6 whose sticking lasts 0.25 T and 1e-4 T: different line
    styles, each interval in its own strip, the short one widened and marked."""
    t = np.linspace(0.0, 6.0, 601)
    traces = [OrbitTrace(t=t, period=6.0, signals={"X": np.sin(t) + d}, views={"time": ("X",)},
                         intervals=[(5.0, 5.0 + w, "sticking")])
              for d, w in ((0.0, 1.5), (1e-6, 6e-4))]
    br = Branch(0, "b", [], [], {})
    items = [(Chosen(br, None, tag, v), tr) for tag, v, tr in
             zip(("first", "last"), (0.89, 0.8945), traces, strict=True)]
    res = SimpleNamespace(problem=nsm.problem("double_pendulum", {}),
                          case=SimpleNamespace(name="c", continuation=SimpleNamespace(
                              parameter="restitution")))
    fig = orbits.draw_time(res, items)
    ax = fig.axes[0]
    lines = [ln for ln in ax.lines if ln.get_label().startswith("b [0]")]
    assert len(lines) == 2 and lines[0].get_linestyle() != lines[1].get_linestyle()
    assert "sticking 1.5 (25 % of T)" in lines[0].get_label()
    strips = [c for c in ax.collections if len(c.get_paths()) == 1]
    widths = sorted(float(np.ptp(c.get_paths()[0].vertices[:, 0])) for c in strips)
    assert widths == pytest.approx([orbits.NARROWEST, 0.25])


# ---------------------------------------------------------------------- bundled cases
@pytest.mark.parametrize("case", ["ndof_default", "bar_continuum_subharmonics",
                                  "ndof_fig7_4_static_grazing_manifolds",
                                  "ndof_fig7_3_static_grazing",
                                  "impact_oscillator_period_doubling",
                                  "wfem_fig18_two_contact_phases"])
def test_bundled_case_draws_without_warnings_and_lists_only_drawn_artists(
        case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every figure of a bundled case drawn (in this process) with warnings as errors; in
    each, every legend entry names a drawn artist, once."""
    import warnings

    from matplotlib.figure import Figure

    from nsm_continuation.figures import process
    from nsm_continuation.figures.make import make_all

    res = nsm.run(CASES / f"{case}.yaml", {"output.plots": False}).run_result
    drawn: list = []
    real = Figure.savefig
    monkeypatch.setattr(process, "FORKS", False)
    monkeypatch.setattr(Figure, "savefig",
                        lambda fig, path, **kw: (drawn.append(fig), real(fig, path, **kw)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        names = make_all(res, tmp_path)
    assert names and len(drawn) == len(names)
    for fig in drawn:
        labels = {lab for ax in fig.axes for lab in labelled(ax)}
        for ax in fig.axes:
            leg = ax.get_legend()
            if leg is None:
                continue
            entries = [t.get_text() for t in leg.get_texts()]
            assert len(entries) == len(set(entries)), entries
            assert set(entries) <= labels, set(entries) - labels
        assert_labels_readable(fig, case)


def test_fig3_2_marks_the_admissible_events_and_counts_the_others(tmp_path: Path) -> None:
    """Fig. 3.2 (every branch of the 5-dof chain, omega in [1.3, 11]): too many events for one
    zoom. The diagram marks every event on an admissible stretch of its branch (each at its
    place, with its kind's marker) and no event on a phantom stretch (Legrand et al. mark
    none there); it says how many it leaves out, and report.md lists every event."""
    res = nsm.run(CASES / "ndof_fig3_2_fep.yaml", {"output.plots": False})
    run = res.run_result
    pr = run.problem
    fig = branches.diagram(run)
    main = fig.axes[0]
    phantom = kept = rings = 0
    for br in run.branches:
        s = np.array([p.s for p in br.points])
        for ev in br.events:
            if ev.kind == "endpoint":
                continue
            before, after = s[s < ev.point.s - 1e-9], s[s > ev.point.s + 1e-9]
            sides = [br.points[int(np.argmin(np.abs(s - v)))]
                     for v in ([before.max()] if before.size else [])
                     + ([after.min()] if after.size else [])]
            x, y = ev.point.value("omega", pr.variables), ev.point.value("energy", pr.variables)
            name = EVENT_STYLES[ev.kind].name
            at = [ln for ln in event_lines(main, name)
                  if np.any(np.isclose(ln.get_xdata(), x) & np.isclose(ln.get_ydata(), y))]
            if sides and not any(p.admissible for p in sides):
                phantom += 1
                assert not at, (ev.kind, x, y)
            elif ev.kind == "stability_change":
                rings += not at
            else:
                kept += 1
                assert at, (ev.kind, x, y)
    assert phantom > 0 and kept > 50 and rings > 0
    note = next(t.get_text() for t in main.texts if t.get_text().startswith("events not"))
    assert f"{phantom} on phantom orbits" in note
    assert f"{rings} stability changes at a marker" in note
    assert_legend_is_what_is_drawn(fig)
    res.save(tmp_path / "fig3_2", plots=False)
    rows = [line for line in (tmp_path / "fig3_2" / "report.md").read_text().splitlines()
            if line.startswith("| ") and line.split("|")[2].strip() in EVENT_STYLES]
    assert len(rows) >= phantom + kept + rings
