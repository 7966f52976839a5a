"""The branch diagram of a run: for the chain and the bar the frequency-energy plot, for forced
impacting systems the frequency-response curve, for autonomous ones a bifurcation diagram in
the continued parameter. Axes, labels, title and scale come from the problem's declared
presentation members (``fep_axes``, ``fep_labels``, ``diagram_title``, ``diagram_yscale``,
:meth:`~nsm_continuation.core.presentation.Presentation.plot_decorations`,
:meth:`~nsm_continuation.core.presentation.Presentation.legend_handles`); styles from
:mod:`nsm_continuation.figures.kit` (as in Legrand et al. 2017, Fig. 3.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from nsm_continuation.figures.kit import (
    DIAGRAM_SIZE,
    MARKERS,
    branch_line,
    draws_markers,
    markers_legend,
    new_figure,
    quantity,
    save,
    segments,
    subplots,
)
from nsm_continuation.runs.result import RunResult


def fep(res: RunResult, path: Path) -> None:
    """The branch diagram of a run (:func:`diagram`) saved to ``path``."""
    fig, ax = new_figure(figsize=DIAGRAM_SIZE)
    diagram(res, ax)
    save(fig, path)


def diagram(res: RunResult, ax: Axes | None = None) -> Figure:
    """Every branch of a run in the problem's diagram axes (``fep_axes``: for the chain the
    frequency-energy plot of Fig. 3.2), admissible/stable/phantom styled as in the papers,
    located events marked; drawn on ``ax`` (a new figure if None). Returns the figure."""
    pr = res.problem
    show = pr.presentation
    xk, yk = show.fep_axes
    log = show.diagram_yscale == "log"
    if ax is None:
        fig, ax = subplots(figsize=DIAGRAM_SIZE)
    else:
        fig = ax.figure
    xs: list[float] = []
    ys: list[float] = []
    for br in res.branches:
        dots = draws_markers(br)
        for (adm, stable), x, y in segments(pr, br, xk, yk):
            ok = np.isfinite(x) & np.isfinite(y) & ((y > 0) if log else True)
            if not ok.any():
                continue
            xs += list(x[ok])
            ys += list(y[ok])
            if not adm:
                branch_line(ax, x, y, dots, color="0.6", lw=0.8, zorder=2)
            elif stable is False:
                branch_line(ax, x, y, dots, color="tab:red", lw=2.2, zorder=3)
            else:
                branch_line(ax, x, y, dots, color="k", lw=2.2, zorder=3,
                            ls="-" if stable else (0, (4, 1.5)))
    y_top = 1.05 * max(ys) if ys else np.inf
    for br in res.branches:
        for ev in br.events:
            # events of a branch start outside the plotted window (e.g. a linear grazing orbit
            # above the energy bound) are listed in the report, not drawn
            ye = quantity(pr, ev.point, yk)
            if ev.kind in MARKERS and ye <= y_top:
                m, c = MARKERS[ev.kind]
                ax.plot(quantity(pr, ev.point, xk), ye, m, color=c,
                        ms=6, mec="k", mew=0.5, zorder=5)
    if not xs and any(br.points for br in res.branches):
        # e.g. a response quantity the simulation did not provide: say so, not a blank plot
        ax.text(0.5, 0.5, f"no finite values of {yk} on the branches", transform=ax.transAxes,
                ha="center", va="center", color="0.4")
    x_range = (min(xs) if xs else 0.0, max(xs) if xs else 1.0)
    if xs and log:
        ax.set_yscale("log")
    ylim = ax.get_ylim()
    show.plot_decorations(ax, x_range, res.branches)
    ax.set_ylim(ylim)
    xl, yl = show.fep_labels
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(f"{show.diagram_title}: {res.case.name}")
    handles = [Line2D([], [], color="k", lw=2.2, label="admissible, stable"),
               Line2D([], [], color="tab:red", lw=2.2, label="admissible, unstable"),
               Line2D([], [], color="k", lw=2.2, ls=(0, (4, 1.5)),
                      label="admissible, stability not computed"),
               Line2D([], [], color="0.6", lw=0.8, label="phantom (not admissible)")]
    handles = markers_legend(res.branches, handles)
    for k, (m, c) in MARKERS.items():
        if any(ev.kind == k for br in res.branches for ev in br.events):
            handles.append(Line2D([], [], marker=m, color=c, ls="", mec="k", label=k))
    handles += show.legend_handles()
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              framealpha=0.9)
    ax.grid(alpha=0.25, which="both")
    fig.tight_layout()
    return fig


