"""The Floquet multipliers of a run's branches: modulus, real and imaginary parts against the
diagram's horizontal quantity with the unstable intervals shaded (Legrand et al. 2017,
Fig. 6.1), and the multipliers in the complex plane with the unit circle (Fig. 6.2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch
from nsm_continuation.figures.kit import new_figure, quantity, save, scatter, vertical_bands
from nsm_continuation.runs.result import RunResult


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
    xk = pr.presentation.fep_axes[0]
    data = [(br, [p for p in br.points if p.multipliers is not None]) for br in res.branches]
    if not any(pts for _, pts in data):
        return False
    fig, axes = new_figure(nrows=3, ncols=1, figsize=(9, 8), sharex=True)
    spans = [(min(a, b), max(a, b)) for br, pts in data if pts
             for a, b in _unstable_spans(pr, br, xk)]
    for ax in axes:
        vertical_bands(ax, spans, color="tab:red", alpha=0.12)
    allp = [p for _, pts in data for p in pts]
    x = np.concatenate([np.full(p.multipliers.size, quantity(pr, p, xk)) for p in allp])
    m = np.concatenate([p.multipliers for p in allp])
    c = np.abs(m.real)
    for ax, val in zip(axes, (np.abs(m), m.real, m.imag), strict=True):
        scatter(ax, x, val, c, s=4, cmap="viridis", vmin=0, vmax=1)
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
    axes[2].set_xlabel(pr.presentation.fep_labels[0])
    axes[0].set_title("Floquet multipliers (trivial 0 and 1 removed); unstable zones shaded; "
                      r"colour: $|$Re $\lambda|$")
    for ax in axes:
        ax.grid(alpha=0.25)
    fig.tight_layout()
    save(fig, path)
    return True


def multipliers_plane(res: RunResult, path: Path) -> bool:
    """The multipliers in the complex plane, coloured by ``fep_axes[0]``."""
    pr = res.problem
    xk = pr.presentation.fep_axes[0]
    pts = [p for br in res.branches for p in br.points if p.multipliers is not None]
    if not pts:
        return False
    fig, ax = new_figure(figsize=(6.2, 5.6))
    th = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(th), np.sin(th), color="k", lw=0.8)
    z = np.concatenate([p.multipliers for p in pts])
    w = np.concatenate([np.full(p.multipliers.size, quantity(pr, p, xk)) for p in pts])
    sc = scatter(ax, z.real, z.imag, w, s=5, cmap="plasma")
    fig.colorbar(sc, ax=ax, label=pr.presentation.fep_labels[0])
    r = min(max(1.6, float(np.percentile(np.abs(z), 98)) * 1.1), 4.0)
    ax.set_xlim(-r, r)
    ax.set_ylim(-r, r)
    ax.set_aspect("equal")
    ax.set_xlabel(r"Re $\lambda$")
    ax.set_ylabel(r"Im $\lambda$")
    ax.set_title("Floquet multipliers in the complex plane")
    ax.grid(alpha=0.25)
    fig.tight_layout()
    save(fig, path)
    return True
