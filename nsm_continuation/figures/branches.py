"""The branch diagram of a run: for the chain and the bar the frequency-energy plot, for forced
impacting systems the frequency-response curve, for autonomous ones a bifurcation diagram in
the continued parameter, for a two-parameter curve the curve in its two parameters. Axes,
labels, title and preferred scale come from the problem's declared presentation members
(``fep_axes``, ``fep_labels``, ``diagram_title``, ``diagram_yscale``, ``two_parameter``,
:meth:`~nsm_continuation.core.presentation.Presentation.plot_decorations`,
:meth:`~nsm_continuation.core.presentation.Presentation.closed_forms`); styles from
:mod:`nsm_continuation.figures.styles` (as in Legrand et al. 2017, Fig. 3.2).

What is drawn is what the legend lists: every artist carries its meaning as its label and the
legend is made of the labelled artists (:func:`~nsm_continuation.figures.kit.legend_entries`),
so a style that is not drawn is not listed. The branches are drawn

* by stability (admissible stable black, unstable red, stability not computed dashed,
  phantom thin grey) when the run computed multipliers;
* by branch (a colour and the branch's label each, up to :data:`NAMED_BRANCHES` branches;
  black beyond) when it did not: a dashed "not computed" style on every branch says nothing;
* as a curve with its start point for a two-parameter curve (no stability legend: each point
  is a bifurcation of the base family);
* as dots for recorded section returns (a brute-force diagram).

The vertical axis is logarithmic only where the family prefers it and the values span more
than a decade (:func:`~nsm_continuation.figures.kit.wants_log`). Where located events crowd
a small part of the axis (:func:`~nsm_continuation.figures.events.cluster_window`) a second
panel repeats the diagram over that window.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch
from nsm_continuation.figures.events import (
    Located,
    cluster_window,
    declutter,
    draw_located,
    drawable,
    markers_overlap,
)
from nsm_continuation.figures.events import located as located_events
from nsm_continuation.figures.kit import (
    DIAGRAM_SIZE,
    branch_line,
    draws_markers,
    legend_entries,
    new_figure,
    outside_legend,
    quantity,
    save,
    seen_pieces,
    segments,
    set_scale,
    state_style,
    subplots,
    wants_log,
)
from nsm_continuation.figures.styles import PHANTOM, PHANTOM_WIDTH, palette_colour, readable
from nsm_continuation.runs.result import RunResult

#: at most this many branches are told apart by colour and named in the legend
NAMED_BRANCHES = 8
#: colours of the closed forms drawn over the branches (dashed)
CLOSED_FORM_COLOURS = ("tab:cyan", "tab:olive", "tab:brown", "tab:pink")
#: the start point of a two-parameter curve
START_STYLE = {"marker": "*", "color": "gold", "ms": 14, "mec": "k", "mew": 0.7, "zorder": 6}
#: size of the figure with a zoom panel [inches]
ZOOM_SIZE = (11, 8.8)


def fep(res: RunResult, path: Path) -> None:
    """The branch diagram of a run (:func:`diagram`) saved to ``path``."""
    save(diagram(res, dpi=True), path)


def computed_stability(branches: list[Branch]) -> bool:
    """Whether the stability of some point of ``branches`` was computed."""
    return any(p.stable is not None for br in branches for p in br.points)


def draw_branches(ax: Axes, res: Any, xk: str, yk: str, log: bool = False,
                  problems: dict[int, Problem] | None = None) -> tuple[list[float], list[float]]:
    """Every branch of ``res`` in ``(xk, yk)`` on ``ax`` in the style of the run (module
    docstring), each style labelled; the finite coordinates drawn ``(xs, ys)`` (positive
    ordinates only on a log axis)."""
    pr = res.problem
    show = pr.presentation
    by_stability = computed_stability(res.branches)
    drawn = [br for br in res.branches if br.points]
    named = len(drawn) <= NAMED_BRANCHES
    fill = show.point_fill()
    xs: list[float] = []
    ys: list[float] = []
    pieces = [(k, br, state, x, y) for k, br in enumerate(drawn)
              for state, x, y in segments((problems or {}).get(br.id, pr), br, xk, yk)]
    visible = seen_pieces([(p[3], p[4]) for p in pieces], log)
    for (k, br, (adm, stable), x, y), seen in zip(pieces, visible, strict=True):
        dots = draws_markers(br)
        colour = palette_colour(k) if named else "k"
        ok = np.isfinite(x) & np.isfinite(y) & ((y > 0) if log else True)
        if not ok.any():
            continue
        xs += list(x[ok])
        ys += list(y[ok])
        if dots:
            kw = {"color": "k", "label": "recorded section returns (brute force)"}
        elif show.two_parameter:
            kw = {"color": colour, "lw": 2.0, "zorder": 3, "label": show.branch_name(br)}
        elif by_stability or not adm:
            kw = state_style(adm, stable)
        else:
            kw = {"color": colour, "lw": 2.0 if fill is None else 1.2, "zorder": 3,
                  "label": show.branch_name(br) if named
                  else "admissible (stability not computed)"}
        if not adm and not by_stability and not dots:
            kw.update(color=PHANTOM, lw=PHANTOM_WIDTH, ls=":" if named else "-")
        if not seen and not dots:  # drawn, too small to be seen: not a legend entry
            kw["label"] = "_nolegend_"
        branch_line(ax, x, y, dots, **kw)
    for k, br in enumerate(drawn):
        bpr = (problems or {}).get(br.id, pr)
        if fill is not None:
            _fill_points(ax, bpr, br, xk, yk, fill, palette_colour(k) if named else "k")
        p0 = show.start_point(br) if show.two_parameter else None
        if p0 is not None:
            ax.plot(quantity(bpr, p0, xk), quantity(bpr, p0, yk), ls="", **START_STYLE,
                    label=_start_label(br))
    return xs, ys


def _fill_points(ax: Axes, pr: Problem, br: Branch, xk: str, yk: str,
                 fill: tuple[str, str, str], colour: str) -> None:
    """The points of ``br`` as dots: filled where the derived ``fill[0]`` is positive, hollow
    elsewhere (``Presentation.point_fill``)."""
    key, full, hollow = fill
    x = np.array([quantity(pr, p, xk) for p in br.points], dtype=float)
    y = np.array([quantity(pr, p, yk) for p in br.points], dtype=float)
    on = np.array([p.derived.get(key, 0.0) > 0 for p in br.points])
    for mask, face, name in ((on, colour, full), (~on, "none", hollow)):
        if mask.any():
            ax.plot(x[mask], y[mask], ls="", marker="o", ms=3.5, color=colour, mfc=face,
                    zorder=4, label=name)


def _start_label(br: Branch) -> str:
    """``start: grazing #0 of runs/x`` for a curve restarted from an event, else ``start``."""
    info = br.info
    if "restart_event" in info:
        return (f"start: {readable(str(info['restart_event']))} "
                f"#{info.get('restart_event_index', 0)} of {info.get('restart_from', 'the run')}")
    return "start"


def _closed_forms(ax: Axes, res: Any, x_range: tuple[float, float]) -> None:
    """The family's closed forms (``Presentation.closed_forms``), thin and dashed: cyan
    (then olive, ...) over branches drawn by stability, black over branches drawn in colours."""
    colours = (CLOSED_FORM_COLOURS if computed_stability(res.branches)
               or res.problem.presentation.two_parameter else ("k", "0.4"))
    for k, (x, y, label) in enumerate(res.problem.presentation.closed_forms(
            x_range, res.branches)):
        ax.plot(x, y, color=colours[k % len(colours)], lw=1.0, ls=(0, (4, 3)), zorder=4,
                label=label)


def _draw_all(ax: Axes, res: Any, xk: str, yk: str, log: bool, x_range: tuple[float, float],
              events: list[Located]) -> None:
    """The branches, the family's closed forms and references, and the events on ``ax``; the
    view is that of the branches (and of the closed form of a two-parameter curve: the arm
    of a curve the run did not compute is seen); the references do not widen it."""
    show = res.problem.presentation
    draw_branches(ax, res, xk, yk, log)
    if show.two_parameter:  # the curve's closed form is what it is compared with: all shown
        _closed_forms(ax, res, x_range)
    set_scale(ax, "y", log)
    set_scale(ax, "x", False)
    ax.autoscale_view()
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    if not show.two_parameter:
        _closed_forms(ax, res, x_range)
    show.plot_decorations(ax, x_range, res.branches)
    draw_located(ax, events)
    ax.set_xlim(xlim)
    ax.set_ylim(ylim)
    ax.grid(alpha=0.25, which="both")


def _window_limits(res: Any, xk: str, yk: str, window: tuple[float, float],
                   events: list[Located], log: bool) -> tuple[float, float] | None:
    """The vertical range of the branches and events inside ``window``, padded."""
    vals = [quantity(res.problem, p, yk) for br in res.branches for p in br.points
            if window[0] <= quantity(res.problem, p, xk) <= window[1]]
    vals += [e.y for e in events if window[0] <= e.x <= window[1]]
    v = np.array(vals, dtype=float)
    v = v[np.isfinite(v) & ((v > 0) if log else True)]
    if not v.size:
        return None
    lo, hi = float(v.min()), float(v.max())
    if log:
        f = (hi / lo) ** 0.08 if hi > lo else 1.5
        return lo / f, hi * f
    pad = 0.08 * (hi - lo) if hi > lo else 0.05 * max(abs(hi), 1e-12)
    return lo - pad, hi + pad


#: candidate places of an inset in a zoom panel (axes fractions: x0, y0, width, height)
INSET_PLACES = ((0.06, 0.52, 0.34, 0.42), (0.60, 0.52, 0.34, 0.42), (0.06, 0.08, 0.34, 0.42),
                (0.60, 0.08, 0.34, 0.42))


def _inset(zoom: Axes, res: Any, xk: str, yk: str, log: bool, events: list[Located]) -> None:
    """Where markers still overlap in the zoom panel, an inset over their window, placed in
    the corner of the panel that holds the fewest drawn points, joined to its window."""
    xlim, ylim = zoom.get_xlim(), zoom.get_ylim()
    inside = [e for e in events if xlim[0] <= e.x <= xlim[1]]
    window = cluster_window(inside, xlim, ylim, log)
    if window is None:
        return
    pts = np.array([(quantity(res.problem, p, xk), quantity(res.problem, p, yk))
                    for br in res.branches for p in br.points], dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = zoom.transAxes.inverted().transform(zoom.transData.transform(pts))

    def crowd(place: tuple[float, ...]) -> int:
        x0, y0, w, h = place
        return int(np.sum((frac[:, 0] > x0) & (frac[:, 0] < x0 + w)
                          & (frac[:, 1] > y0) & (frac[:, 1] < y0 + h)))

    ins = zoom.inset_axes(min(INSET_PLACES, key=crowd))
    _draw_all(ins, res, xk, yk, log, window, events)
    ins.set_xlim(window)
    lim = _window_limits(res, xk, yk, window, events, log)
    if lim is not None:
        ins.set_ylim(lim)
    ins.tick_params(labelsize=6)
    zoom.indicate_inset_zoom(ins, edgecolor="goldenrod")


def _crowded_zoom(res: Any, xk: str, yk: str, log: bool, window: tuple[float, float],
                  events: list[Located], depth: int = 2) -> bool:
    """Whether markers overlap in the zoom over ``window`` and still in its inset (``depth``
    levels) or where no inset can part them (a crowd wider than an inset): the crowd of
    Legrand et al. 2017, Fig. 3.2 below omega = 3."""
    inside = [e for e in events if window[0] <= e.x <= window[1]]
    lim = _window_limits(res, xk, yk, window, inside, log)
    if lim is None or not markers_overlap(inside, window, lim, log):
        return False
    inner = cluster_window(inside, window, lim, log)
    return depth <= 1 or inner is None or _crowded_zoom(res, xk, yk, log, inner, inside,
                                                        depth - 1)


def diagram(res: RunResult, ax: Axes | None = None, dpi: bool = False) -> Figure:
    """Every branch of a run in the problem's diagram axes (``fep_axes``: for the chain the
    frequency-energy plot of Fig. 3.2), styled as the module docstring says, located events
    marked, on ``ax`` (a new figure if None, at the files' resolution with ``dpi``; with a
    zoom panel where events crowd). Returns the figure."""
    pr = res.problem
    show = pr.presentation
    xk, yk = show.fep_axes
    ys_all = [quantity(pr, p, yk) for br in res.branches for p in br.points]
    log = wants_log(ys_all, show.diagram_yscale)
    xs_all = np.array([quantity(pr, p, xk) for br in res.branches for p in br.points],
                      dtype=float)
    xs_all = xs_all[np.isfinite(xs_all)]
    x_range = (float(xs_all.min()), float(xs_all.max())) if xs_all.size else (0.0, 1.0)
    finite_y = np.array(ys_all, dtype=float)
    finite_y = finite_y[np.isfinite(finite_y) & ((finite_y > 0) if log else True)]
    # events of a branch start outside the drawn window (e.g. a linear grazing orbit above
    # the energy bound) are listed in the report, and counted on the figure
    y_top = 1.05 * float(finite_y.max()) if finite_y.size else np.inf
    events, left = drawable(located_events(pr, res.branches, xk, yk), y_top, log)
    y_range = (float(finite_y.min()), float(finite_y.max())) if finite_y.size else (0.0, 1.0)
    window = (cluster_window(events, x_range, y_range, log)
              if ax is None and not show.two_parameter else None)
    unmarked: dict[str, int] = {}
    if window is not None and _crowded_zoom(res, xk, yk, log, window, events):
        # too crowded for a zoom: the events on phantom orbits and doubled rings left out
        events, unmarked = declutter(events)
        window = cluster_window(events, x_range, y_range, log)
    if window is not None:  # no wider than the data and a margin for the markers
        margin = 0.01 * (x_range[1] - x_range[0])
        window = (max(window[0], x_range[0] - margin), min(window[1], x_range[1] + margin))
    extra = {"dpi": 130} if dpi else {}
    zoom = None
    if ax is None and window is not None:
        fig, (ax, zoom) = (new_figure if dpi else subplots)(
            nrows=2, ncols=1, figsize=ZOOM_SIZE, height_ratios=[3, 2])
    elif ax is None:
        fig, ax = subplots(figsize=DIAGRAM_SIZE, **extra)
    else:
        fig = ax.figure
    _draw_all(ax, res, xk, yk, log, x_range, events)
    if not xs_all.size and any(br.points for br in res.branches) or (
            any(br.points for br in res.branches) and not finite_y.size):
        # e.g. a response quantity the simulation did not provide: say so, not a blank plot
        ax.text(0.5, 0.5, f"no finite values of {show.label(yk)} on the branches",
                transform=ax.transAxes, ha="center", va="center", color="0.4")
    xl, yl = show.fep_labels
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(show.diagram_title)
    notes = [f"{len(left)} outside the drawn range"] if left else []
    notes += [f"{n} {what}" for what, n in unmarked.items()]
    if notes:  # under the legend, off the data
        ax.text(1.01, 0.0, "events not marked\n(all in report.md):\n" + "\n".join(notes),
                transform=ax.transAxes, fontsize=7, color="0.35", va="bottom", ha="left")
    if zoom is not None and window is not None:
        xlim = ax.get_xlim()  # the window's frame within the drawn range
        ax.axvspan(max(window[0], xlim[0]), min(window[1], xlim[1]), facecolor="none",
                   edgecolor="goldenrod", lw=1.4, ls="--", zorder=1, label="window zoomed below")
        ax.set_xlim(xlim)
        _draw_all(zoom, res, xk, yk, log, window, events)
        zoom.set_xlim(window)
        lim = _window_limits(res, xk, yk, window, events, log)
        if lim is not None:
            zoom.set_ylim(lim)
        zoom.set_xlabel(xl)
        zoom.set_ylabel(yl)
        zoom.set_title(f"zoom: {xl} from {window[0]:.6g} to {window[1]:.6g}", fontsize=9)
        if not unmarked:  # else no inset parts the crowd (_crowded_zoom)
            _inset(zoom, res, xk, yk, log, events)
    handles, labels = legend_entries([ax] if zoom is None else [ax, zoom])
    extra_handles = show.legend_handles()  # a plugin's own decorations (declared, not found)
    handles += extra_handles
    labels += [h.get_label() for h in extra_handles]
    outside_legend(ax, handles, labels)
    fig.tight_layout()
    return fig
