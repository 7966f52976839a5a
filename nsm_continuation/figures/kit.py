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

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Point

#: resolution of the figures written to files [dots per inch]
DPI = 130


#: size of the branch diagram [inches]
DIAGRAM_SIZE = (11, 5.5)


MARKERS = {"fold": ("s", "tab:blue"), "period_doubling": ("D", "tab:purple"),
           "neimark_sacker": ("o", "tab:green"), "branch_point": ("X", "tab:orange"),
           "grazing": ("v", "tab:red")}


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


def quantity_panels(problem: Problem, branches: list[Branch], xlabel: str,
                    panels: list[tuple[list[str], str]], title: str, path: Path) -> None:
    """One panel per ``(keys, ylabel)`` of ``panels``: each quantity of ``keys`` against the
    continued parameter along every branch, styled as the branch diagram (admissible stable
    black, unstable red, phantom thin grey; the second and later keys of a panel dashed), saved
    to ``path``. Quantities missing at a point are NaN: a gap, never an error."""
    xk = problem.parameter
    fig, axes = new_figure(nrows=len(panels), ncols=1, figsize=(9, 2.3 * len(panels) + 0.8),
                        sharex=True, squeeze=False)
    for ax, (keys, ylabel) in zip(axes[:, 0], panels, strict=True):
        for j, yk in enumerate(keys):
            ls = "-" if j == 0 else (0, (4, 1.5))
            for br in branches:
                for (adm, stable), x, y in segments(problem, br, xk, yk):
                    if not adm:
                        branch_line(ax, x, y, draws_markers(br), color="0.6", lw=0.8, ls=ls)
                    else:
                        branch_line(ax, x, y, draws_markers(br),
                                    color="tab:red" if stable is False else "k", lw=1.8, ls=ls)
        ax.set_ylabel(ylabel if len(keys) == 1 else f"{ylabel}\n(" + ", ".join(
            f"{k} {'solid' if j == 0 else 'dashed'}" for j, k in enumerate(keys)) + ")",
                      fontsize=8)
        ax.grid(alpha=0.25)
    axes[-1, 0].set_xlabel(xlabel)
    axes[0, 0].set_title(f"{title}: black stable, red unstable, grey phantom", fontsize=10)
    fig.tight_layout()
    save(fig, path)
