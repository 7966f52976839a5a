"""Orbit figures of a run (``output.orbits``): the periodic orbits at chosen points of the
branches, drawn from :meth:`Presentation.orbit
<nsm_continuation.core.presentation.Presentation.orbit>` (an
:class:`~nsm_continuation.core.records.OrbitTrace`) in the views the problem family declares.

* ``orbits_time.png``: each signal of the ``time`` view against the normalised time ``t / T``
  (one panel per signal, one line per chosen point; marked instants such as impacts as dots,
  intervals such as sticking shaded in the line's colour; signals listed in ``log`` as
  ``|value|`` on a log scale);
* ``orbits_phase.png``: the ``phase`` view, one signal against the other (a phase portrait);
* ``manifold.png``: the ``manifold`` view, a 3-D projection of about :data:`MANIFOLD_ORBITS`
  orbits spread along the admissible points of the first branch, coloured by the continued
  parameter: the invariant manifold the family of periodic orbits sweeps (a nonsmooth mode).
  The orbits of the branch's ``grazing`` events at admissible points (where admissibility ends:
  the manifold's boundary, Figs. 7.2 of the chain) are drawn dashed black. A branch along which
  the continued parameter does not vary (a family at one frequency, Fig. 7.4) is coloured by
  the problem's energy quantity instead, and the title gives the parameter's value.

Points (``output.orbits.points``): ``first`` / ``last`` (of each branch), ``events`` (every
located event but the branch ends), an event kind (every event of that kind) or a number (the
point nearest that value of the continued parameter over all branches). A view whose signals
an orbit lacks is skipped for that orbit (a figure with no orbit is not written); a point whose
orbit cannot be computed (:class:`~nsm_continuation.core.problem.EvaluationError`) is left out and
named in the figure. Nothing here knows a problem family: what is drawn is what the trace
declares.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from nsm_continuation.cases.schema import OrbitsSpec
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.records import Branch, OrbitTrace, Point
from nsm_continuation.figures.kit import colormap, figure, subplots
from nsm_continuation.figures.orbit_selection import (
    Chosen,
    branches_of,
    choose,
    nothing_selected,
    parameter_name,
    parameter_value,
    select,
    traces,
)
from nsm_continuation.figures.styles import palette_colour

#: resolution of the figures written to files [dots per inch] (as :mod:`plots`)
DPI = 130
#: orbits drawn along the first branch in ``manifold.png``
MANIFOLD_ORBITS = 20
#: markers of the marked instants, by order of first appearance of their kind
MARK_STYLES = ("o", "^", "s", "D", "v", "P")


def legend_text(ch: Chosen, name: str) -> str:
    """``<branch label> [<id>], <tag>: <parameter> = <value>`` (``name``: the parameter's
    axis label)."""
    return f"{ch.branch.label} [{ch.branch.id}], {ch.tag}: {name} = {ch.value:.6g}"


def parameter_label(res: Any) -> str:
    """The continued parameter's label (its symbol, else its words), for legends."""
    return str(res.problem.presentation.label(parameter_name(res)))


#: longest line of a figure title [characters] (longer ones are wrapped: a title centred over
#: narrower axes would be clipped at both ends of the figure)
TITLE_WIDTH = 80


def _title(res: Any, what: str, spec: OrbitsSpec | None, view: str,
           width: int = TITLE_WIDTH) -> str:
    """``<caption>: <what>``, each line of ``what`` wrapped at ``width`` characters (the
    case is named by the run's folder, not in the title)."""
    caption = spec.figures.get(view) if spec is not None else None
    head = f"{caption}: " if caption else ""
    text = f"{head}{what}"
    return "\n".join(textwrap.fill(line, width, break_on_hyphens=False)
                     for line in text.splitlines())


def _mark_styles(items: list[tuple[Chosen, OrbitTrace]]) -> dict[str, str]:
    kinds = list(dict.fromkeys(kind for _, tr in items for _, kind in tr.marks))
    return {k: MARK_STYLES[i % len(MARK_STYLES)] for i, k in enumerate(kinds)}


#: line styles of the orbits of one figure, in the order chosen (the first thick and solid
#: under the others: orbits that nearly coincide stay told apart)
ORBIT_LINES = (("-", 2.4), ((0, (5, 2)), 1.5), ((0, (1, 1.2)), 1.5), ((0, (6, 2, 1, 2)), 1.3))
#: height of one orbit's strip of intervals (fraction of the axes) and the narrowest interval
#: drawn (fraction of the period: a shorter one is widened to it and marked by a triangle)
STRIP = 0.035
NARROWEST = 0.004


def orbit_style(i: int) -> dict[str, Any]:
    """Colour, line style, width and drawing order of the ``i``-th orbit of a figure."""
    ls, lw = ORBIT_LINES[i % len(ORBIT_LINES)]
    return {"color": palette_colour(i), "ls": ls, "lw": lw, "zorder": 3 + i}


def interval_text(tr: OrbitTrace) -> str:
    """``, sticking 0.2477 (4.0 % of T)``: the total duration of each kind of interval of
    the orbit (empty without intervals)."""
    total: dict[str, float] = {}
    for t0, t1, kind in tr.intervals:
        total[kind] = total.get(kind, 0.0) + (t1 - t0)
    return "".join(f", {k} {v:.4g} ({100 * v / tr.period:.2g} % of T)"
                   for k, v in total.items())


def draw_strips(ax: Axes, items: list[tuple[Chosen, OrbitTrace]]) -> None:
    """The intervals of each orbit (sticking phases, ...) as a strip along the bottom of
    ``ax`` in the orbit's colour, one row per orbit: an interval shorter than
    :data:`NARROWEST` of the period is widened to it and marked by a triangle, so the
    shrinking of an interval from one orbit to the next is seen."""
    for i, (_, tr) in enumerate(items):
        col = palette_colour(i)
        y0 = 0.01 + STRIP * i
        for t0, t1, _kind in tr.intervals:
            a, w = t0 / tr.period, (t1 - t0) / tr.period
            ax.broken_barh([(a, max(w, NARROWEST))], (y0, 0.8 * STRIP), color=col,
                           transform=ax.get_xaxis_transform(), zorder=6)
            if w < NARROWEST:
                ax.plot(a, y0 + 0.8 * STRIP, marker="v", color=col, ms=5, mec="k", mew=0.4,
                        transform=ax.get_xaxis_transform(), zorder=7)


def _finish_legend(ax: Axes, styles: dict[str, str], intervals: list[str],
                   notes: list[str]) -> None:
    handles, labels = ax.get_legend_handles_labels()
    for kind, m in styles.items():
        handles.append(Line2D([], [], marker=m, color="0.3", ls="", ms=5))
        labels.append(kind)
    for kind in intervals:
        handles.append(Rectangle((0, 0), 1, 1, color="0.5", alpha=0.4))
        labels.append(f"{kind}: shaded, and a strip per orbit along the bottom")
    if handles:
        ax.legend(handles, labels, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if notes:
        ax.text(0.0, -0.16, "not drawn: " + "; ".join(notes), transform=ax.transAxes,
                fontsize=6, color="0.4", va="top")


def draw_time(res: Any, items: list[tuple[Chosen, OrbitTrace]], log: Sequence[str] = (),
              axes: Sequence[Axes] | None = None, spec: OrbitsSpec | None = None,
              notes: Sequence[str] = ()) -> Figure | None:
    """The ``time`` view: each of its signals against ``t / T`` (one panel each, on ``axes``
    or a new figure), one line per orbit; marks as dots, intervals shaded. None if no orbit
    has the view's signals."""
    shown = parameter_label(res)
    signals = list(dict.fromkeys(s for _, tr in items for s in tr.views.get("time", ())
                                 if s in tr.signals))
    if not signals:
        return None
    if axes is None:
        fig, ax_arr = subplots(len(signals), 1, figsize=(10, 1.2 + 2.6 * len(signals)),
                                   sharex=True, squeeze=False, dpi=DPI)
        axes = list(ax_arr[:, 0])
    fig = axes[0].figure
    styles = _mark_styles(items)
    interval_kinds = list(dict.fromkeys(k for _, tr in items for *_, k in tr.intervals))
    for ax, sig in zip(axes, signals, strict=False):
        is_log = sig in log
        for i, (ch, tr) in enumerate(items):
            if sig not in tr.signals:
                continue
            st = orbit_style(i)
            x = tr.t / tr.period
            val = np.abs(tr.signals[sig]) if is_log else tr.signals[sig]
            ax.plot(x, val, **st, label=legend_text(ch, shown) + interval_text(tr))
            for t0, t1, _kind in tr.intervals:
                ax.axvspan(t0 / tr.period, t1 / tr.period, color=st["color"], alpha=0.12, lw=0)
            for tm, kind in tr.marks:
                vm = tr.at(sig, tm)
                ax.plot(tm / tr.period, abs(vm) if is_log else vm, styles[kind],
                        color=st["color"], ms=4, mec="k", mew=0.4, zorder=20)
        if interval_kinds:
            draw_strips(ax, items)
        if is_log:
            ax.set_yscale("log")
        label = tr_label(items, sig)
        ax.set_ylabel(f"$|${label}$|$ (log)" if is_log else label)
        ax.grid(alpha=0.25, which="both")
    axes[min(len(signals), len(axes)) - 1].set_xlabel("normalised time $t / T$")
    extra = [f"log: {s!r} is not a signal of the time view" for s in log if s not in signals]
    _finish_legend(axes[0], styles, interval_kinds, [*notes, *extra])
    axes[0].set_title(_title(res, "periodic orbits against normalised time", spec, "time"),
                      fontsize=10)
    fig.tight_layout()
    return fig


def tr_label(items: list[tuple[Chosen, OrbitTrace]], sig: str) -> str:
    """The label of signal ``sig`` declared by the first orbit that has it."""
    return next((tr.label(sig) for _, tr in items if sig in tr.signals), sig)


def draw_phase(res: Any, items: list[tuple[Chosen, OrbitTrace]], ax: Axes | None = None,
               spec: OrbitsSpec | None = None, notes: Sequence[str] = ()
               ) -> Figure | None:
    """The ``phase`` view: ``(x, y)`` of each orbit (a projected phase portrait), marks as
    dots. None if no orbit has a phase view with its signals."""
    shown = parameter_label(res)
    drawn = [(ch, tr) for ch, tr in items
             if len(tr.views.get("phase", ())) == 2
             and all(s in tr.signals for s in tr.views["phase"])]
    if not drawn:
        return None
    if ax is None:
        fig, ax = subplots(figsize=(9.5, 5.6), dpi=DPI)
    fig = ax.figure
    styles = _mark_styles(drawn)
    for i, (ch, tr) in enumerate(drawn):
        xs, ys = tr.views["phase"]
        st = orbit_style(i)
        ax.plot(tr.signals[xs], tr.signals[ys], **st, label=legend_text(ch, shown))
        for tm, kind in tr.marks:
            ax.plot(tr.at(xs, tm), tr.at(ys, tm), styles[kind], color=st["color"], ms=4,
                    mec="k", mew=0.4, zorder=20)
    xs, ys = drawn[0][1].views["phase"]
    ax.set_xlabel(drawn[0][1].label(xs))
    ax.set_ylabel(drawn[0][1].label(ys))
    ax.grid(alpha=0.25)
    _finish_legend(ax, styles, [], list(notes))
    ax.set_title(_title(res, "phase portrait", spec, "phase"), fontsize=10)
    fig.tight_layout()
    return fig


def spread(branch: Branch, count: int = MANIFOLD_ORBITS) -> list[Point]:
    """About ``count`` points spread evenly (by index) along the admissible points of
    ``branch`` (every point if none is admissible), ends included: the physical part of the
    invariant manifold, not its phantom continuation."""
    pts = [p for p in branch.points if p.admissible] or branch.points
    n = len(pts)
    idx = sorted(set(np.linspace(0, n - 1, min(count, n)).round().astype(int).tolist()))
    return [pts[i] for i in idx]


#: relative spread of the continued parameter below which a branch is taken as one family at
#: a single parameter value (a vertical branch: rounding noise only, ~1e-15)
CONSTANT_PARAMETER_RTOL = 1e-9


def colour_quantity(res: Any, items: list[tuple[Chosen, OrbitTrace]], name: str
                    ) -> tuple[str, float | None]:
    """What colours the manifold's orbits: the continued parameter ``name``, or, where it does
    not vary along them (spread below :data:`CONSTANT_PARAMETER_RTOL`), the problem's energy
    quantity, with the parameter's common value (None when it varies)."""
    values = np.array([ch.value for ch, _ in items], dtype=float)
    energy = res.problem.energy_quantity
    if values.size < 2 or not np.all(np.isfinite(values)) or energy is None:
        return name, None
    mid = float(np.median(values))
    if np.ptp(values) > CONSTANT_PARAMETER_RTOL * max(abs(mid), 1.0):
        return name, None
    if not all(energy in ch.point.derived for ch, _ in items):
        return name, None
    return energy, mid


def bounds_admissible_part(ev: Any) -> bool:
    """Whether the event ``ev`` is a boundary of its branch's admissible part: a ``grazing``
    of admissibility tests (``data['test']`` / ``data['tests']``, zero there up to the location
    accuracy, so their sign at the located point is rounding) at which every other test is
    satisfied. A test's zero where another test fails (the chain's outgoing velocity at a pole
    for g < 0, Prop. 7.1.2) bounds no admissible part."""
    if ev.kind != "grazing":
        return False
    vanishing = set(ev.data.get("tests") or []) | ({ev.data["test"]} if "test" in ev.data
                                                    else set())
    if not vanishing:
        return False
    return all(v >= 0.0 for k, v in ev.point.tests.items() if k not in vanishing)


def draw_boundaries(res: Any, branch: Branch, periods: int, ax: Any, name: str,
                    extent: float) -> int:
    """The orbits of ``branch``'s events that bound its admissible part
    (:func:`bounds_admissible_part`: e.g. the nonlinear grazing orbit of Fig. 7.2) drawn dashed
    black on the 3-D axes ``ax``, unless one is a point (smaller than ``1e-9 extent``, the
    extent of the manifold's orbits: a family that ends at an equilibrium, Fig. 7.4); how many
    were drawn."""
    chosen = [Chosen(branch, ev.point, ev.kind, parameter_value(res.problem, ev.point, name))
              for ev in branch.events if bounds_admissible_part(ev)]
    items, _ = traces(res, chosen, periods)
    drawn = 0
    for ch, tr in items:
        view = tr.views.get("manifold", ())
        if len(view) != 3 or not all(s in tr.signals for s in view):
            continue
        a, b, c = (tr.signals[s] for s in view)
        if max(np.ptp(a), np.ptp(b), np.ptp(c)) <= 1e-9 * extent:
            continue
        ax.plot(a, b, c, color="k", lw=1.4, ls="--",
                label=f"{ch.tag} (boundary): {parameter_label(res)} = {ch.value:.6g}")
        drawn += 1
    return drawn


def draw_manifold(res: Any, periods: int = 1, ax: Any = None, spec: OrbitsSpec | None = None
                  ) -> Figure | None:
    """The ``manifold`` view: the 3-D projection ``(a, b, c)`` of about
    :data:`MANIFOLD_ORBITS` orbits spread along the first branch with points (of
    ``spec.branches`` if given), coloured by the continued parameter (by the energy where the
    parameter is constant: :func:`colour_quantity`), the boundary orbits dashed
    (:func:`draw_boundaries`). None if the family declares no manifold view."""
    branch = next(iter(branches_of(res, spec.branches if spec is not None else None)), None)
    if branch is None:
        return None
    name = parameter_name(res)
    chosen = [Chosen(branch, p, "", parameter_value(res.problem, p, name))
              for p in spread(branch)]
    items, notes = traces(res, chosen, periods)
    items = [(ch, tr) for ch, tr in items if len(tr.views.get("manifold", ())) == 3
             and all(s in tr.signals for s in tr.views["manifold"])]
    if not items:
        return None
    if ax is None:
        fig = figure(figsize=(8.5, 6.8), dpi=DPI)
        ax = fig.add_subplot(projection="3d")
    fig = ax.figure
    values = np.array([ch.value for ch, _ in items], dtype=float)
    colour_by, constant = colour_quantity(res, items, name)
    if colour_by != name:
        values = np.array([ch.point.derived.get(colour_by, np.nan) for ch, _ in items],
                          dtype=float)
    finite = values[np.isfinite(values)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    norm = Normalize(lo, hi if hi > lo else lo + 1.0)
    cmap = colormap("viridis")
    for (_, tr), value in zip(items, values, strict=True):
        a, b, c = (tr.signals[s] for s in tr.views["manifold"])
        ax.plot(a, b, c, color=cmap(norm(value)), lw=0.9)
    extent = max(float(np.ptp(tr.signals[s])) for _, tr in items for s in tr.views["manifold"])
    bounds = draw_boundaries(res, branch, periods, ax, name, extent)
    a, b, c = items[0][1].views["manifold"]
    ax.set_xlabel(items[0][1].label(a))
    ax.set_ylabel(items[0][1].label(b))
    ax.set_zlabel(items[0][1].label(c))
    sm = ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, shrink=0.6, pad=0.12, label=res.problem.presentation.label(colour_by))
    at = f", all at {name} = {constant:.6g}" if constant is not None else ""
    what = (f"invariant manifold: {len(items)} admissible periodic orbits{at}\nalong branch "
            f"{branch.id} ({branch.label})")
    if bounds:
        ax.legend(fontsize=7, loc="upper left")
    ax.set_title(_title(res, what, spec, "manifold", width=70), fontsize=10)
    if notes:
        ax.text2D(0.0, 0.0, "not drawn: " + "; ".join(notes), transform=ax.transAxes,
                  fontsize=6, color="0.4")
    return fig


def make_figures(res: Any, out: Path) -> list[str]:
    """Every orbit figure of ``res.case.output.orbits`` written into ``out``: their file
    names (none when the case asks for none)."""
    spec: OrbitsSpec | None = res.case.output.orbits
    if spec is None:
        return []
    names: list[str] = []
    items, notes = ([], [])
    if {"time", "phase"} & set(spec.views):
        items, notes = traces(res, choose(res, spec.points, spec.branches), spec.periods)
    for view, file, draw in (
            ("time", "orbits_time.png",
             lambda: draw_time(res, items, spec.log, spec=spec, notes=notes)),
            ("phase", "orbits_phase.png",
             lambda: draw_phase(res, items, spec=spec, notes=notes)),
            ("manifold", "manifold.png", lambda: draw_manifold(res, spec.periods, spec=spec))):
        if view not in spec.views:
            continue
        fig = draw()
        if fig is not None:
            fig.savefig(out / file, dpi=DPI)
            names.append(file)
    return names


def plot(res: Any, points: Sequence[str | float], view: str = "time", ax: Any = None,
         periods: int = 1, log: Sequence[str] = ()) -> Figure:
    """One orbit figure of a run in memory (``Result.plot_orbits``, whose checks before
    computing have passed: a view the problem draws, known point kinds): the ``view`` of the
    orbits at ``points`` (``manifold``: along the first branch, ``points`` unused) on ``ax``
    (a new figure if None; the time view then draws only its first signal). Raises a
    :class:`~nsm_continuation.cases.schema.CaseError` (a ``ValueError``) naming the argument for a
    point entry that selects nothing, a ``log`` signal the time view does not draw, and if
    there is nothing to draw (no orbit could be computed)."""
    if log and view != "time":
        raise CaseError(f"plot_orbits.log: only the time view draws signals on a log scale "
                        f"(view is {view!r})")
    if view == "manifold":
        fig = draw_manifold(res, periods, ax=ax)
        if fig is None:
            raise CaseError("plot_orbits.view: 'manifold': no admissible orbit of the first "
                            "branch with points could be computed")
        return fig
    if not points:
        raise CaseError("plot_orbits.points: empty; give first, last, events, an event kind "
                        "or a value of the continued parameter")
    chosen, empty = select(res, points)
    if empty:
        i = empty[0]
        raise CaseError(f"plot_orbits.points[{i}]: {nothing_selected(points[i], res, None)}")
    items, notes = traces(res, chosen, periods)
    if view == "time":
        signals = list(dict.fromkeys(s for _, tr in items for s in tr.views.get("time", ())
                                     if s in tr.signals))
        for i, sig in enumerate(log):
            if items and sig not in signals:
                raise CaseError(f"plot_orbits.log[{i}]: {sig!r} is not a signal of the time "
                                f"view (its signals: {', '.join(signals)})")
        fig = draw_time(res, items, log, axes=None if ax is None else [ax], notes=notes)
    elif view == "phase":
        fig = draw_phase(res, items, ax=ax, notes=notes)
    else:
        raise CaseError(f"plot_orbits.view: {view!r} is not one of time, phase, manifold")
    if fig is None:
        why = "; ".join(notes) or "their traces have no such view"
        raise CaseError(f"plot_orbits.view: {view!r}: no orbit at the chosen points could be "
                        f"drawn ({why})")
    return fig
