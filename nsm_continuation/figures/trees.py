"""The bifurcation diagram of a run grown into a tree (``analysis.branch_switching``,
:mod:`nsm_continuation.runs.diagrams`), or of a run with ``output.axes``: every branch in the
chosen axes, each switched branch joined to its birth point."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D

from nsm_continuation.figures.kit import (
    MARKERS,
    branch_line,
    draws_markers,
    markers_legend,
    quantity,
    subplots,
)
from nsm_continuation.runs.result import RunResult


def axes_of(res: RunResult) -> tuple[str, str]:
    """``output.axes``, else the problem's diagram axes."""
    axes = res.case.output.axes
    return (axes[0], axes[1]) if axes is not None else tuple(res.problem.presentation.fep_axes)  # type: ignore[return-value]


def figure(res: RunResult, path: Path) -> bool:
    """Every branch of the run in the axes :func:`axes_of` (admissible stable black,
    unstable red, phantom grey, stability not computed dashed; events marked), each branch
    of the tree labelled ``#id (period k)`` at its first point and joined to its birth point
    (dotted: the switch's amplitude), saved to ``path``. One point per orbit: the quantity at
    the point's unknowns (for a hybrid orbit of ``k`` returns, its first section point). False
    (and nothing written) when no branch has points."""
    if not any(br.points for br in res.branches):
        return False
    xk, yk = axes_of(res)
    fig, ax = subplots(figsize=(11, 6))
    for br in res.branches:
        pr = res.branch_problems.get(br.id, res.problem)
        pts = br.points
        if not pts:
            continue
        x = np.array([quantity(pr, p, xk) for p in pts], dtype=float)
        y = np.array([quantity(pr, p, yk) for p in pts], dtype=float)
        state = [(p.admissible, p.stable) for p in pts]
        dots = draws_markers(br)
        start = 0
        for i in range(1, len(pts) + 1):
            if i == len(pts) or state[i] != state[start]:
                adm, stable = state[start]
                sl = slice(start, min(i + 1, len(pts)))
                if not adm:
                    branch_line(ax, x[sl], y[sl], dots, color="0.6", lw=0.8, zorder=2)
                elif stable is False:
                    branch_line(ax, x[sl], y[sl], dots, color="tab:red", lw=1.8, zorder=3)
                else:
                    branch_line(ax, x[sl], y[sl], dots, color="k", lw=1.8, zorder=3,
                                ls="-" if stable else (0, (4, 1.5)))
                start = i
        for ev in br.events:
            if ev.kind in MARKERS:
                m, c = MARKERS[ev.kind]
                ax.plot(quantity(pr, ev.point, xk), quantity(pr, ev.point, yk), m, color=c,
                        ms=6, mec="k", mew=0.5, zorder=5)
        if res.tree:
            k = br.info.get("period_multiple", br.info.get("returns"))
            first = min(pts, key=lambda p: abs(p.s))
            ax.annotate(f"#{br.id}" + (f" (period {k})" if k else ""),
                        (quantity(pr, first, xk), quantity(pr, first, yk)),
                        textcoords="offset points", xytext=(4, 4), fontsize=7,
                        color="tab:blue")
    by_id = {b.id: b for b in res.branches}
    for node in res.tree:
        # the switched branch's first point lies eps from its birth point: join them
        child = by_id.get(node["child"]) if node.get("child") is not None else None
        parent = by_id.get(node["parent"])
        if child is None or parent is None or not child.points:
            continue
        same = [ev for ev in parent.events if ev.kind == node["event"]["kind"]]
        if node["event"]["index"] >= len(same):
            continue
        birth = same[node["event"]["index"]].point
        first = min(child.points, key=lambda p: abs(p.s))
        ppr = res.branch_problems.get(parent.id, res.problem)
        cpr = res.branch_problems.get(child.id, res.problem)
        ax.plot([quantity(ppr, birth, xk), quantity(cpr, first, xk)],
                [quantity(ppr, birth, yk), quantity(cpr, first, yk)], color="tab:blue",
                lw=0.8, ls=":", zorder=4)
    ax.set_xlabel(xk)
    ax.set_ylabel(yk)
    drawn = [br for br in res.branches if br.points]
    title = ("Brute-force bifurcation diagram (recorded section returns)"
             if drawn and all(draws_markers(br) for br in drawn)
             else "Bifurcation diagram" if res.tree else "Branch diagram")
    depth = max((int(b.info.get("depth", 0)) for b in res.branches), default=0)
    ax.set_title(f"{title}: {res.case.name}" + (f" ({len(res.branches)} branches, "
                                                 f"{depth} generations)" if res.tree else ""))
    handles = [Line2D([], [], color="k", lw=1.8, label="admissible, stable"),
               Line2D([], [], color="tab:blue", lw=0.8, ls=":",
                      label="switched branch: from its birth point"),
               Line2D([], [], color="tab:red", lw=1.8, label="admissible, unstable"),
               Line2D([], [], color="k", lw=1.8, ls=(0, (4, 1.5)),
                      label="stability not computed"),
               Line2D([], [], color="0.6", lw=0.8, label="phantom (not admissible)")]
    handles = markers_legend(res.branches, handles)
    for kind, (m, c) in MARKERS.items():
        if any(ev.kind == kind for br in res.branches for ev in br.events):
            handles.append(Line2D([], [], marker=m, color=c, ls="", mec="k", label=kind))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.25)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    return True
