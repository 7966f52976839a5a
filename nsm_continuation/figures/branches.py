"""Figures of a run: the branch diagram (for the chain and the bar the frequency-energy plot, for
forced impacting systems the frequency-response curve, for autonomous ones a bifurcation
diagram), multipliers along the branch, multipliers in the plane, and panels of quantities
along the branches (:func:`quantity_panels`, used by problems' extra figures). Axes, labels,
title and scale come from the problem's declared presentation members (``fep_axes``,
``fep_labels``, ``diagram_title``, ``diagram_yscale``,
:meth:`~nsm_continuation.core.problem.Problem.plot_decorations`,
:meth:`~nsm_continuation.core.problem.Problem.legend_handles`).

Conventions (as in Legrand et al. 2017, Fig. 3.2, 6.1, 6.2): admissible orbits thick, phantom
(non-admissible) orbits thin grey; admissible-stable black, admissible-unstable red; unstable
intervals shaded light red on the multiplier plots; the unit circle drawn in the complex plane.

Cost (issue 13, ``benchmarks/bench_startup.py``): this module, hence matplotlib, is imported only
when a run writes figures. A figure written to a file is created at its file resolution
(:data:`DPI`), so the layout pass (``tight_layout``) and ``savefig`` share one renderer and its
text and mathtext caches instead of laying every label out twice. The multiplier clouds (23,360
markers per panel for Fig. 3.2) are drawn by :func:`_scatter`, the same picture up to the
anti-aliasing of marker rims at about a third of the drawing time, and the unstable intervals
by :func:`_vertical_bands`, pixel for pixel what ``axvspan`` draws, as one artist per panel.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from nsm_continuation.core.problem import Problem  # noqa: E402
from nsm_continuation.core.records import Branch, Point  # noqa: E402
from nsm_continuation.figures.process import in_two_processes  # noqa: E402
from nsm_continuation.runs.runner import RunResult  # noqa: E402

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
    ``Branch.info['draw'] == 'markers'`` (:class:`~nsm_continuation.algorithms.base.Sweep`)."""
    return br.info.get("draw") == "markers"


def branch_line(ax: plt.Axes, x: np.ndarray, y: np.ndarray, markers: bool, **kw: Any) -> None:
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


def _segments(problem: Problem, br: Branch, xk: str, yk: str):
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


def _figure(**kw):
    """``plt.subplots`` for a figure written to a file: created at the file's resolution."""
    return plt.subplots(dpi=DPI, **kw)


def _save(fig: plt.Figure, path: Path) -> None:
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _scatter(ax: plt.Axes, x: np.ndarray, y: np.ndarray, c: np.ndarray, s: float, **kw):
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
    edge = plt.rcParams["patch.linewidth"]  # scatter's default edge width [pt]
    return ax.scatter(x, y, c=c, s=(np.sqrt(s) + edge) ** 2, linewidths=0, **kw)


def _vertical_bands(ax: plt.Axes, spans: list[tuple[float, float]], **kw) -> None:
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


def fep(res: RunResult, path: Path) -> None:
    """The branch diagram of a run (:func:`diagram`) saved to ``path``."""
    fig, ax = _figure(figsize=DIAGRAM_SIZE)
    diagram(res, ax)
    _save(fig, path)


def diagram(res: RunResult, ax: plt.Axes | None = None) -> plt.Figure:
    """Every branch of a run in the problem's diagram axes (``fep_axes``: for the chain the
    frequency-energy plot of Fig. 3.2), admissible/stable/phantom styled as in the papers,
    located events marked; drawn on ``ax`` (a new figure if None). Returns the figure."""
    pr = res.problem
    xk, yk = pr.fep_axes
    log = pr.diagram_yscale == "log"
    if ax is None:
        fig, ax = plt.subplots(figsize=DIAGRAM_SIZE)
    else:
        fig = ax.figure
    xs: list[float] = []
    ys: list[float] = []
    for br in res.branches:
        dots = draws_markers(br)
        for (adm, stable), x, y in _segments(pr, br, xk, yk):
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
    pr.plot_decorations(ax, x_range, res.branches)
    ax.set_ylim(ylim)
    xl, yl = pr.fep_labels
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(f"{pr.diagram_title}: {res.case.name}")
    handles = [Line2D([], [], color="k", lw=2.2, label="admissible, stable"),
               Line2D([], [], color="tab:red", lw=2.2, label="admissible, unstable"),
               Line2D([], [], color="k", lw=2.2, ls=(0, (4, 1.5)),
                      label="admissible, stability not computed"),
               Line2D([], [], color="0.6", lw=0.8, label="phantom (not admissible)")]
    handles = markers_legend(res.branches, handles)
    for k, (m, c) in MARKERS.items():
        if any(ev.kind == k for br in res.branches for ev in br.events):
            handles.append(Line2D([], [], marker=m, color=c, ls="", mec="k", label=k))
    handles += pr.legend_handles()
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              framealpha=0.9)
    ax.grid(alpha=0.25, which="both")
    fig.tight_layout()
    return fig


def quantity_panels(problem: Problem, branches: list[Branch], xlabel: str,
                    panels: list[tuple[list[str], str]], title: str, path: Path) -> None:
    """One panel per ``(keys, ylabel)`` of ``panels``: each quantity of ``keys`` against the
    continued parameter along every branch, styled as the branch diagram (admissible stable
    black, unstable red, phantom thin grey; the second and later keys of a panel dashed), saved
    to ``path``. Quantities missing at a point are NaN: a gap, never an error."""
    xk = problem.parameter
    fig, axes = _figure(nrows=len(panels), ncols=1, figsize=(9, 2.3 * len(panels) + 0.8),
                        sharex=True, squeeze=False)
    for ax, (keys, ylabel) in zip(axes[:, 0], panels, strict=True):
        for j, yk in enumerate(keys):
            ls = "-" if j == 0 else (0, (4, 1.5))
            for br in branches:
                for (adm, stable), x, y in _segments(problem, br, xk, yk):
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
    _save(fig, path)


def _unstable_spans(problem: Problem, br: Branch, xk: str) -> list[tuple[float, float]]:
    spans, cur = [], None
    for p in br.points:
        x = quantity(problem, p, xk)
        if p.stable is False:
            cur = [x, x] if cur is None else [cur[0], x]
        elif cur is not None:
            spans.append(tuple(cur))
            cur = None
    if cur is not None:
        spans.append(tuple(cur))
    return spans


def multipliers_vs_frequency(res: RunResult, path: Path) -> bool:
    """The multipliers (modulus, real and imaginary parts) against the diagram's horizontal
    quantity ``fep_axes[0]`` (the file keeps its historical name)."""
    pr = res.problem
    xk = pr.fep_axes[0]
    data = [(br, [p for p in br.points if p.multipliers is not None]) for br in res.branches]
    if not any(pts for _, pts in data):
        return False
    fig, axes = _figure(nrows=3, ncols=1, figsize=(9, 8), sharex=True)
    spans = [(min(a, b), max(a, b)) for br, pts in data if pts
             for a, b in _unstable_spans(pr, br, xk)]
    for ax in axes:
        _vertical_bands(ax, spans, color="tab:red", alpha=0.12)
    allp = [p for _, pts in data for p in pts]
    x = np.concatenate([np.full(p.multipliers.size, quantity(pr, p, xk)) for p in allp])
    m = np.concatenate([p.multipliers for p in allp])
    c = np.abs(m.real)
    for ax, val in zip(axes, (np.abs(m), m.real, m.imag), strict=True):
        _scatter(ax, x, val, c, s=4, cmap="viridis", vmin=0, vmax=1)
    axes[0].axhline(1.0, color="k", lw=0.8)
    axes[0].set_yscale("log")
    # multipliers of near-grazing orbits grow like 1/v: keep the unit circle readable
    lim = float(np.clip(np.nanmax(np.abs(m)) if m.size else 1.0, 1.2, 3.0))
    axes[1].set_ylim(-lim, lim)
    axes[2].set_ylim(-lim, lim)
    big = np.nanmax(np.abs(m)) if m.size else 0.0
    if big > 1e3:
        axes[0].set_ylim(max(np.nanmin(np.abs(m)), 1e-4), 1e4)
        axes[1].text(0.01, 0.95, f"clipped: max |lambda| = {big:.2g}", transform=axes[1].transAxes,
                     fontsize=7, va="top")
    axes[0].set_ylabel(r"$|\lambda|$")
    axes[1].set_ylabel(r"Re $\lambda$")
    axes[2].set_ylabel(r"Im $\lambda$")
    axes[2].set_xlabel(pr.fep_labels[0])
    axes[0].set_title("Floquet multipliers (trivial 0 and 1 removed); unstable zones shaded; "
                      r"colour: $|$Re $\lambda|$")
    for ax in axes:
        ax.grid(alpha=0.25)
    fig.tight_layout()
    _save(fig, path)
    return True


def multipliers_plane(res: RunResult, path: Path) -> bool:
    """The multipliers in the complex plane, coloured by ``fep_axes[0]``."""
    pr = res.problem
    xk = pr.fep_axes[0]
    pts = [p for br in res.branches for p in br.points if p.multipliers is not None]
    if not pts:
        return False
    fig, ax = _figure(figsize=(6.2, 5.6))
    th = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(th), np.sin(th), color="k", lw=0.8)
    z = np.concatenate([p.multipliers for p in pts])
    w = np.concatenate([np.full(p.multipliers.size, quantity(pr, p, xk)) for p in pts])
    sc = _scatter(ax, z.real, z.imag, w, s=5, cmap="plasma")
    fig.colorbar(sc, ax=ax, label=pr.fep_labels[0])
    r = min(max(1.6, float(np.percentile(np.abs(z), 98)) * 1.1), 4.0)
    ax.set_xlim(-r, r)
    ax.set_ylim(-r, r)
    ax.set_aspect("equal")
    ax.set_xlabel(r"Re $\lambda$")
    ax.set_ylabel(r"Im $\lambda$")
    ax.set_title("Floquet multipliers in the complex plane")
    ax.grid(alpha=0.25)
    fig.tight_layout()
    _save(fig, path)
    return True


def make_all(res: RunResult, out: Path) -> list[str]:
    """Every figure of a run written into ``out`` (the branch diagram, the multipliers, the
    problem's own figures, the bifurcation diagram of a tree, the orbit figures of
    ``output.orbits``, :mod:`nsm_continuation.figures.orbits`): their file names, in this order.
    Drawn in two processes where that is possible
    (:func:`nsm_continuation.figures.process.in_two_processes`)."""

    def branch_diagram() -> list[str]:
        if res.branches and any(br.points for br in res.branches):
            fep(res, out / "fep.png")
            return ["fep.png"]
        return []

    def along() -> list[str]:
        ok = multipliers_vs_frequency(res, out / "multipliers_vs_frequency.png")
        return ["multipliers_vs_frequency.png"] if ok else []

    def plane() -> list[str]:
        ok = multipliers_plane(res, out / "multipliers_complex_plane.png")
        return ["multipliers_complex_plane.png"] if ok else []

    def problem_figures() -> list[str]:
        return list(res.problem.extra_plots(out, res.branches, res.window))

    def tree() -> list[str]:
        if res.case.output.axes is None and not res.tree:
            return []
        from nsm_continuation.runs.diagrams import figure

        return ["diagram.png"] if figure(res, out / "diagram.png") else []

    def orbit_figures() -> list[str]:
        if res.case.output.orbits is None:
            return []
        from nsm_continuation.figures.orbits import make_figures

        return make_figures(res, out)

    return in_two_processes([branch_diagram, along, plane, problem_figures, tree,
                             orbit_figures])
