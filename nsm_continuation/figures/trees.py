"""The bifurcation diagram of a run grown into a tree (``analysis.branch_switching``,
:mod:`nsm_continuation.runs.diagrams`), or of a run with ``output.axes``: every branch in the
chosen axes, styled as the branch diagram (:func:`nsm_continuation.figures.branches.draw_branches`),
each switched branch joined to its birth point."""

from __future__ import annotations

from pathlib import Path

from nsm_continuation.figures.branches import draw_branches
from nsm_continuation.figures.events import draw_events
from nsm_continuation.figures.kit import (
    draws_markers,
    new_figure,
    outside_legend,
    quantity,
    save,
    set_scale,
)
from nsm_continuation.runs.result import RunResult


def axes_of(res: RunResult) -> tuple[str, str]:
    """``output.axes``, else the problem's diagram axes."""
    axes = res.case.output.axes
    return (axes[0], axes[1]) if axes is not None else tuple(res.problem.presentation.fep_axes)  # type: ignore[return-value]


def figure(res: RunResult, path: Path) -> bool:
    """Every branch of the run in the axes :func:`axes_of` (styled as the branch diagram,
    events marked), each branch of the tree labelled ``#id (period k)`` at its first point and
    joined to its birth point (dotted: the switch's amplitude), saved to ``path``. One point
    per orbit: the quantity at the point's unknowns (for a hybrid orbit of ``k`` returns, its
    first section point). False (and nothing written) when no branch has points."""
    if not any(br.points for br in res.branches):
        return False
    xk, yk = axes_of(res)
    show = res.problem.presentation
    fig, ax = new_figure(figsize=(11, 6))
    draw_branches(ax, res, xk, yk, problems=res.branch_problems)
    draw_events(ax, res.problem, res.branches, xk, yk, problems=res.branch_problems)
    for br in res.branches:
        pr = res.branch_problems.get(br.id, res.problem)
        if res.tree and br.points:
            k = br.info.get("period_multiple", br.info.get("returns"))
            first = min(br.points, key=lambda p: abs(p.s))
            # staggered: branches born at one point are labelled there one above the other
            ax.annotate(f"#{br.id}" + (f" (period {k})" if k else ""),
                        (quantity(pr, first, xk), quantity(pr, first, yk)),
                        textcoords="offset points", xytext=(4, 4 + 9 * (br.id % 3)),
                        fontsize=7, color="tab:blue")
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
                lw=0.8, ls=":", zorder=4, label="switched branch: from its birth point")
    for axis in ("x", "y"):
        set_scale(ax, axis, False)
    ax.set_xlabel(show.label(xk))
    ax.set_ylabel(show.label(yk))
    drawn = [br for br in res.branches if br.points]
    title = ("Brute-force bifurcation diagram (recorded section returns)"
             if drawn and all(draws_markers(br) for br in drawn)
             else "Bifurcation diagram" if res.tree else "Branch diagram")
    depth = max((int(b.info.get("depth", 0)) for b in res.branches), default=0)
    ax.set_title(title + (f" ({len(res.branches)} branches, {depth} generation"
                          f"{'s' if depth != 1 else ''})" if res.tree else ""))
    outside_legend(ax)
    ax.grid(alpha=0.25)
    fig.tight_layout()
    save(fig, path)
    return True


__all__ = ["axes_of", "figure"]
