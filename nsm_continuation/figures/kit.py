"""The drawing kit shared by every figure of a run and by the problems' own figures: the
resolution and sizes, the event markers, the branch-diagram styles (admissible stable black,
unstable red, phantom thin grey; Legrand et al. 2017, Figs. 3.2, 6.1, 6.2), panels of
quantities along the branches (:func:`quantity_panels`), and drawing helpers that give the
picture ``scatter`` and ``axvspan`` give at less cost. It imports matplotlib and the core
records only, so a family's presentation may draw with it.

Figures are made with matplotlib's object API (:func:`subplots`, :func:`figure`: a
:class:`~matplotlib.figure.Figure` with its own Agg canvas), never through ``pyplot``: drawing
a run's figures, from the command line or from a notebook, neither chooses a backend nor
adds figures to ``pyplot``'s list (the user's ``plt.plot`` keeps working as before). The
command line chooses the Agg backend for itself (:func:`nsm_continuation.cli.main`).

A figure written to a file is created at its file resolution (:data:`DPI`), so the layout
pass (``tight_layout``) and ``savefig`` share one renderer and its text and mathtext caches
instead of laying every label out twice.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import LogFormatterSciNotation

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Point
from nsm_continuation.figures.styles import (
    ADMISSIBLE_WIDTH,
    EVENT_STYLES,
    NOT_COMPUTED_DASHES,
    PHANTOM,
    PHANTOM_WIDTH,
    STABLE,
    STATE_NAMES,
    UNSTABLE,
)

#: resolution of the figures written to files [dots per inch]
DPI = 130


#: size of the branch diagram [inches]
DIAGRAM_SIZE = (11, 5.5)


#: ``kind: (marker, colour)`` of the event kinds with a declared style
#: (:data:`~nsm_continuation.figures.styles.EVENT_STYLES`; any other kind is drawn too, with
#: :func:`~nsm_continuation.figures.styles.event_style`'s default marker)
MARKERS = {k: (st.marker, st.colour) for k, st in EVENT_STYLES.items()}

#: data spanning at most this ratio (max / min) are drawn on a linear axis even where the
#: family prefers a log one: a log axis over less than a decade only bends the curve and
#: labels its ticks "6x10^0"
LOG_MIN_RATIO = 10.0


def quantity(problem: Problem, p: Point, name: str) -> float:
    """The value of ``name`` at ``p``: a derived quantity, else an unknown, else NaN."""
    return p.value(name, problem.variables)


def draws_markers(br: Branch) -> bool:
    """Whether the branch's points are drawn as dots rather than joined by lines: a cloud of
    points, not a curve (the recorded section returns of a brute-force bifurcation diagram,
    Figs. 8(b), 9(b)-(c) of Nordmark & Piiroinen 2009), which the algorithm declares in
    ``Branch.info['draw'] == 'markers'`` (:class:`~nsm_continuation.algorithms.sweep.Sweep`)."""
    return br.info.get("draw") == "markers"


def branch_line(ax: Axes, x: np.ndarray, y: np.ndarray, markers: bool, **kw: Any) -> None:
    """``ax.plot(x, y, **kw)``, or with ``markers`` small dots of ``kw``'s colour at the
    points (no line: :func:`draws_markers`)."""
    if markers:
        kw = {k: v for k, v in kw.items() if k not in ("ls", "lw", "linestyle", "linewidth")}
        kw.update(ls="", marker=".", ms=3.0, mew=0)
    ax.plot(x, y, **kw)


def markers_legend(branches: list[Branch], handles: list[Any]) -> list[Any]:
    """The legend entries of a branch diagram: ``handles`` (the line styles), with an entry
    for the dots of :func:`draws_markers` branches when there are some (alone when every
    branch with points is drawn so)."""
    drawn = [br for br in branches if br.points]
    dotted = [br for br in drawn if draws_markers(br)]
    if not dotted:
        return handles
    dot = Line2D([], [], color="k", ls="", marker=".", ms=5,
                 label="recorded section returns (brute force; stability not computed)")
    return [dot] if len(dotted) == len(drawn) else [*handles, dot]


def segments(problem: Problem, br: Branch, xk: str, yk: str):
    """Consecutive runs of points with the same (admissible, stable) state."""
    pts = br.points
    if not pts:
        return
    key = [(p.admissible, p.stable) for p in pts]
    start = 0
    for i in range(1, len(pts) + 1):
        if i == len(pts) or key[i] != key[start]:
            seg = pts[start:min(i + 1, len(pts))]
            x = np.array([quantity(problem, p, xk) for p in seg], dtype=float)
            y = np.array([quantity(problem, p, yk) for p in seg], dtype=float)
            yield key[start], x, y
            start = i


#: keyword arguments of :func:`subplots` that lay out the axes (the rest make the figure)
_GRID_KEYS = ("sharex", "sharey", "squeeze", "width_ratios", "height_ratios", "subplot_kw",
              "gridspec_kw")


class NotebookFigure(Figure):
    """A :class:`~matplotlib.figure.Figure` that Jupyter shows as a PNG when it is a cell's
    value, also where ``pyplot`` (which registers matplotlib's own display) was never
    imported."""

    def _repr_png_(self) -> bytes:
        buf = io.BytesIO()
        self.savefig(buf, format="png", bbox_inches="tight")
        return buf.getvalue()


def figure(**kw: Any) -> Figure:
    """A new figure (``kw``: its ``figsize``, ``dpi``, ``layout``, ...) with its own Agg
    canvas, outside ``pyplot``: no backend is chosen and ``pyplot``'s figures are not touched
    (module docstring). It can be saved (``fig.savefig``), drawn (``fig.canvas.draw()``) and
    shown by Jupyter as the value of a cell (:class:`NotebookFigure`)."""
    fig = NotebookFigure(**kw)
    FigureCanvasAgg(fig)
    return fig


def subplots(nrows: int = 1, ncols: int = 1, **kw: Any) -> tuple[Figure, Any]:
    """``plt.subplots(nrows, ncols, **kw)`` without ``pyplot`` (:func:`figure`): the figure
    and its axes (an array of them as ``plt.subplots`` gives)."""
    grid = {k: kw.pop(k) for k in list(kw) if k in _GRID_KEYS}
    fig = figure(**kw)
    return fig, fig.subplots(nrows, ncols, **grid)


def colormap(name: str) -> Any:
    """The registered colormap ``name`` (``plt.get_cmap(name)`` without ``pyplot``)."""
    return mpl.colormaps[name]


def new_figure(**kw: Any) -> tuple[Figure, Any]:
    """:func:`subplots` for a figure written to a file: created at the file's resolution."""
    return subplots(dpi=DPI, **kw)


def save(fig: Figure, path: Path) -> None:
    """Save ``fig`` to ``path`` at :data:`DPI`."""
    fig.savefig(path, dpi=DPI)


def scatter(ax: Axes, x: np.ndarray, y: np.ndarray, c: np.ndarray, s: float, **kw):
    """``ax.scatter(x, y, c=c, s=s, **kw)``, the same picture at less cost:

    * of points with identical ``(x, y, c)`` only the last, the one on top, is drawn (a
      complex-conjugate pair has the same modulus and real part: the two upper multiplier
      panels of Fig. 3.2 draw 13,891 markers instead of 23,360); what changes is the
      anti-aliased rim of such a marker, which two coincident draws made a little more opaque.
      Points with a non-finite coordinate or colour are dropped, as ``scatter`` drops them;
    * each marker is a filled disc of the default marker's outer diameter (``sqrt(s)`` plus
      the 1 pt edge ``scatter`` strokes in the face colour), so Agg fills each marker instead
      of filling and stroking it.

    On the Fig. 3.2 multipliers (three panels) the drawing takes 0.21 s instead of 0.58 s.
    """
    x, y, c = (np.asarray(a, dtype=float) for a in (x, y, c))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(c)
    x, y, c = x[ok], y[ok], c[ok]
    if x.size > 1:
        rows = np.stack([x, y, c], axis=1)[::-1]
        _, first = np.unique(rows, axis=0, return_index=True)
        keep = np.sort(x.size - 1 - first)  # last occurrences, in drawing order
        x, y, c = x[keep], y[keep], c[keep]
    edge = mpl.rcParams["patch.linewidth"]  # scatter's default edge width [pt]
    return ax.scatter(x, y, c=c, s=(np.sqrt(s) + edge) ** 2, linewidths=0, **kw)


def vertical_bands(ax: Axes, spans: list[tuple[float, float]], **kw) -> None:
    """``ax.axvspan(lo, hi, lw=0, **kw)`` for every ``(lo, hi)`` of ``spans``: the same pixels
    and the same autoscaling of x, as one artist instead of one patch per interval (Fig. 3.2:
    38 intervals on each of three panels)."""
    if not spans:
        return
    verts = [[(lo, 0.0), (lo, 1.0), (hi, 1.0), (hi, 0.0)] for lo, hi in spans]
    ax.add_collection(PolyCollection(verts, transform=ax.get_xaxis_transform(), linewidths=0,
                                     **kw), autolim=False)
    ax.update_datalim([(min(lo for lo, _ in spans), 0.0), (max(hi for _, hi in spans), 0.0)],
                      updatey=False)
    ax.autoscale_view(scaley=False)


def wants_log(values: Any, preferred: str = "log") -> bool:
    """Whether an axis of ``values`` is drawn on a log scale: the family prefers it
    (``preferred == "log"``) and the finite positive values span more than a decade
    (:data:`LOG_MIN_RATIO`); a linear axis otherwise, with plain tick labels."""
    if preferred != "log":
        return False
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    return bool(v.size >= 2 and v.max() > LOG_MIN_RATIO * v.min())


class PlainLogFormatter(LogFormatterSciNotation):
    """The tick labels of a log axis: where the axis spans at most :data:`PLAIN_DECADES`
    decades, the ticks matplotlib labels (decades, and some minor ticks when there are few
    decades) written as plain numbers (``0.6``, ``4``, ``20``) instead of ``6x10^-1``;
    matplotlib's powers of ten over wider spans."""

    def __call__(self, x: float, pos: int | None = None) -> str:
        label = super().__call__(x, pos)
        lo, hi = sorted(self.axis.get_view_interval()) if self.axis is not None else (0, 0)
        if not label or not (lo > 0 and np.log10(hi / lo) <= PLAIN_DECADES):
            return label
        return f"{x:g}"


#: a log axis spanning at most this many decades has plain tick labels
PLAIN_DECADES = 3.0


def set_scale(ax: Axes, axis: str, log: bool) -> None:
    """The ``axis`` ("x" or "y") of ``ax`` on a log scale (tick labels by
    :class:`PlainLogFormatter`), or linear with plain tick labels (no offset, no scientific
    factor for values between 1e-4 and 1e6)."""
    target = ax.xaxis if axis == "x" else ax.yaxis
    if log:
        (ax.set_xscale if axis == "x" else ax.set_yscale)("log")
        target.set_major_formatter(PlainLogFormatter(labelOnlyBase=False))
        target.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False))
        return
    fmt = (ax.xaxis if axis == "x" else ax.yaxis).get_major_formatter()
    if hasattr(fmt, "set_useOffset"):
        fmt.set_useOffset(False)
        fmt.set_powerlimits((-4, 6))


#: a piece of branch smaller than this fraction of the drawn extent in both directions is not
#: seen on the figure (one point, or a step between two points at a branch's end)
SEEN = 0.015


def seen_pieces(pieces: list[tuple[Any, Any]], log: bool = False) -> list[bool]:
    """Whether each piece ``(x, y)`` of branch is seen: at least two points spanning
    :data:`SEEN` of the extent of all pieces in one direction (the ordinate in decades on a
    log axis). A piece not seen is drawn but not listed in the legend."""
    def span(v: np.ndarray) -> float:
        v = v[np.isfinite(v)]
        return float(v.max() - v.min()) if v.size else 0.0

    def tr(y: Any) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        return np.log10(np.where(y > 0, y, np.nan)) if log else y

    if not pieces:
        return []
    wx = span(np.concatenate([np.asarray(x, dtype=float) for x, _ in pieces]))
    wy = span(np.concatenate([tr(y) for _, y in pieces]))
    return [len(x) > 1 and (span(np.asarray(x, dtype=float)) > SEEN * wx
                            or span(tr(y)) > SEEN * wy) for x, y in pieces]


def state_style(admissible: bool, stable: bool | None, width: float = ADMISSIBLE_WIDTH
                ) -> dict[str, Any]:
    """Line keywords of a piece of branch in the stability state ``(admissible, stable)``
    (:mod:`nsm_continuation.figures.styles`), labelled with the state's legend text."""
    label = STATE_NAMES[(bool(admissible), stable if admissible else None)]
    if not admissible:
        return {"color": PHANTOM, "lw": PHANTOM_WIDTH, "zorder": 2, "label": label}
    if stable is False:
        return {"color": UNSTABLE, "lw": width, "zorder": 3, "label": label}
    return {"color": STABLE, "lw": width, "zorder": 3, "label": label,
            "ls": "-" if stable else NOT_COMPUTED_DASHES}


def legend_entries(axes: Any) -> tuple[list[Any], list[str]]:
    """The labelled artists of ``axes`` (one Axes or several), each label once: the
    stability states first (in the order of
    :data:`~nsm_continuation.figures.styles.STATE_NAMES`), then in drawing order. A legend
    made of them lists only what is drawn."""
    handles: list[Any] = []
    labels: list[str] = []
    for ax in np.atleast_1d(axes):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    states = list(dict.fromkeys(STATE_NAMES.values()))
    order = sorted(range(len(labels)), key=lambda i: (
        states.index(labels[i]) if labels[i] in states else len(states), i))
    return [handles[i] for i in order], [labels[i] for i in order]


def outside_legend(ax: Axes, handles: list[Any] | None = None,
                   labels: list[str] | None = None, **kw: Any) -> Any:
    """The legend of ``ax`` (its labelled artists, :func:`legend_entries`, unless given) to
    the right of the axes; None when nothing is labelled."""
    if handles is None or labels is None:
        handles, labels = legend_entries(ax)
    if not handles:
        return None
    opts = {"fontsize": 7, "loc": "upper left", "bbox_to_anchor": (1.01, 1.0),
            "framealpha": 0.9}
    opts.update(kw)
    return ax.legend(handles, labels, **opts)


def quantity_panels(problem: Problem, branches: list[Branch], xlabel: str,
                    panels: list[tuple[list[str], str]], title: str, path: Path,
                    log: tuple[str, ...] = (), x: str | None = None) -> bool:
    """One panel per ``(keys, ylabel)`` of ``panels``: each quantity of ``keys`` against the
    quantity ``x`` (default the continued parameter) along every branch, styled as the branch
    diagram (admissible stable black, unstable red, phantom thin grey; the second and later
    keys of a panel dashed), the branches' located events marked where the quantity is
    defined, saved to ``path``. The
    quantities of ``log`` are drawn on a log axis where they span more than a decade
    (:func:`wants_log`). Quantities missing at a point are NaN: a gap, never an error; a panel
    whose quantities are missing everywhere is left out. False (nothing written) when no
    panel has a value."""
    from nsm_continuation.figures.events import draw_events

    xk = x or problem.parameter
    values = {k: np.array([quantity(problem, p, k) for br in branches for p in br.points],
                          dtype=float) for keys, _ in panels for k in keys}
    panels = [(keys, yl) for keys, yl in panels
              if any(np.isfinite(values[k]).any() for k in keys)]
    if not panels:
        return False
    fig, axes = new_figure(nrows=len(panels), ncols=1, figsize=(9.5, 2.3 * len(panels) + 0.9),
                           sharex=True, squeeze=False)
    for ax, (keys, ylabel) in zip(axes[:, 0], panels, strict=True):
        for j, yk in enumerate(keys):
            ls = "-" if j == 0 else (0, (4, 1.5))
            pieces = [(br, st, x, y) for br in branches
                      for st, x, y in segments(problem, br, xk, yk)]
            for (br, (adm, stable), x, y), seen in zip(
                    pieces, seen_pieces([(x, y) for _, _, x, y in pieces]), strict=True):
                kw = state_style(adm, stable, width=1.8)
                if j > 0 or not seen:  # the panel's ylabel names the dashed quantity
                    kw.update(label="_nolegend_")
                if j > 0:
                    kw.update(ls=ls)
                branch_line(ax, x, y, draws_markers(br), **kw)
            draw_events(ax, problem, branches, xk, yk)
        ax.set_ylabel(ylabel if len(keys) == 1 else f"{ylabel}\n(" + ", ".join(
            f"{problem.presentation.label(k)} {'solid' if j == 0 else 'dashed'}"
            for j, k in enumerate(keys)) + ")", fontsize=8)
        set_scale(ax, "y", any(k in log for k in keys)
                  and wants_log(np.concatenate([values[k] for k in keys])))
        ax.grid(alpha=0.25, which="both")
    set_scale(axes[-1, 0], "x", False)
    axes[-1, 0].set_xlabel(xlabel)
    axes[0, 0].set_title(title, fontsize=10)
    outside_legend(axes[0, 0], *legend_entries(axes[:, 0]))
    fig.tight_layout()
    save(fig, path)
    return True
