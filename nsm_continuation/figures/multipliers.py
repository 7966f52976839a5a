"""The Floquet multipliers of a run's branches: modulus, real and imaginary parts against the
diagram's horizontal quantity with the unstable intervals shaded (Legrand et al. 2017,
Fig. 6.1), and the multipliers in the complex plane with the unit circle (Fig. 6.2).

The file of the first is named for its horizontal axis, ``multipliers_vs_<quantity>.png``
(:func:`along_name`). A multiplier below the accuracy of the multipliers at its point
(:func:`zero_floor`: the zero multipliers of an orbit with sticking, exact in theory, computed
as rounding noise of ~1e-16) is zero: drawn at 0 in the real and imaginary parts, left out of
the modulus panel, which is logarithmic only where the drawn moduli span more than a decade.
The colour of a point is a value, with its colourbar; clipped axes say what they clip."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Point
from nsm_continuation.figures.kit import (
    new_figure,
    quantity,
    save,
    scatter,
    set_scale,
    vertical_bands,
    wants_log,
)
from nsm_continuation.runs.result import RunResult

#: a multiplier smaller than this many machine epsilons times the largest modulus at its
#: point (at least 1) is zero to rounding
ZERO_EPS = 1000.0
#: the real and imaginary parts are drawn within +-(the largest modulus) clipped to this
PART_LIMIT = 3.0
#: above this modulus the modulus panel is clipped
MODULUS_LIMIT = 1e4


def along_name(res: Any) -> str:
    """``multipliers_vs_<quantity>.png``, the quantity of the horizontal axis
    (``fep_axes[0]``: the continued parameter, or the frequency of the chain's plot)."""
    return f"multipliers_vs_{res.problem.presentation.fep_axes[0]}.png"


def zero_floor(p: Point) -> float:
    """The modulus below which a multiplier of ``p`` is zero to rounding: the error of the
    trivial multiplier where it was checked, at least :data:`ZERO_EPS` machine epsilons,
    times the largest modulus (at least 1)."""
    m = p.multipliers
    scale = max(1.0, float(np.max(np.abs(m)))) if m is not None and m.size else 1.0
    err = getattr(p, "trivial_error", None)
    err = float(err) if err is not None and np.isfinite(err) else 0.0
    return max(err, ZERO_EPS * np.finfo(float).eps) * scale


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


def _note(ax: Axes, text: str) -> None:
    """``text`` above ``ax``, left (what the panel leaves out or clips)."""
    ax.set_title(text, fontsize=7, loc="left", color="0.25")


def multipliers_along(res: RunResult, path: Path) -> bool:
    """The multipliers (modulus, real and imaginary parts) against the diagram's horizontal
    quantity ``fep_axes[0]`` (module docstring), saved to ``path``; False (nothing written)
    when no point has multipliers."""
    pr = res.problem
    show = pr.presentation
    xk = show.fep_axes[0]
    data = [(br, [p for p in br.points if p.multipliers is not None]) for br in res.branches]
    allp = [p for _, pts in data for p in pts]
    if not any(p.multipliers.size for p in allp):
        return False
    fig, axes = new_figure(nrows=3, ncols=1, figsize=(9.5, 8), sharex=True,
                           layout="constrained")
    spans = [(min(a, b), max(a, b)) for br, pts in data if pts
             for a, b in _unstable_spans(pr, br, xk)]
    for ax in axes:
        vertical_bands(ax, spans, color="tab:red", alpha=0.12)
    x = np.concatenate([np.full(p.multipliers.size, quantity(pr, p, xk)) for p in allp])
    m = np.concatenate([p.multipliers for p in allp])
    zero = np.abs(m) < np.concatenate([np.full(p.multipliers.size, zero_floor(p))
                                       for p in allp])
    m = np.where(zero, 0.0, m)
    c = np.abs(m.real)
    modulus = np.abs(m)
    sc = None
    for ax, val, keep in zip(axes, (modulus, m.real, m.imag), (~zero, None, None),
                             strict=True):
        xs, vs, cs = (x, val, c) if keep is None else (x[keep], val[keep], c[keep])
        sc = scatter(ax, xs, vs, cs, s=4, cmap="viridis", vmin=0, vmax=1)
    axes[0].axhline(1.0, color="k", lw=0.8)
    shown = modulus[~zero]
    set_scale(axes[0], "y", wants_log(np.append(shown, 1.0)))
    notes = []
    if zero.any():
        notes.append(f"{int(zero.sum())} multipliers zero to rounding (|λ| below the "
                     "trivial multiplier's error) not drawn")
    big = float(np.nanmax(modulus)) if modulus.size else 0.0
    if big > MODULUS_LIMIT:
        axes[0].set_ylim(max(float(np.nanmin(shown)), 1e-4) if shown.size else 1e-4,
                         MODULUS_LIMIT)
        notes.append(f"clipped at {MODULUS_LIMIT:g}: max |λ| = {big:.3g}")
    if notes:
        _note(axes[0], "; ".join(notes))
    # multipliers of near-grazing orbits grow like 1/v: keep the unit circle readable
    lim = float(np.clip(big if modulus.size else 1.0, 1.2, PART_LIMIT))
    outside = int(np.sum(np.maximum(np.abs(m.real), np.abs(m.imag)) > lim))
    for ax in axes[1:]:
        ax.set_ylim(-lim, lim)
    if outside:
        _note(axes[1], f"clipped at ±{lim:g}: {outside} values outside")
    axes[0].set_ylabel(r"$|\lambda|$")
    axes[1].set_ylabel(r"Re $\lambda$")
    axes[2].set_ylabel(r"Im $\lambda$")
    set_scale(axes[2], "x", False)
    axes[2].set_xlabel(show.fep_labels[0])
    fig.suptitle("Floquet multipliers (trivial 0 and 1 removed); unstable zones shaded")
    for ax in axes:
        ax.grid(alpha=0.25)
    fig.colorbar(sc, ax=list(axes), label=r"$|\mathrm{Re}\,\lambda|$", shrink=0.6, pad=0.02)
    save(fig, path)
    return True


def multipliers_plane(res: RunResult, path: Path) -> bool:
    """The multipliers in the complex plane, coloured by ``fep_axes[0]`` (its colourbar),
    those zero to rounding at 0; False (nothing written) when no point has multipliers."""
    pr = res.problem
    show = pr.presentation
    xk = show.fep_axes[0]
    pts = [p for br in res.branches for p in br.points if p.multipliers is not None]
    if not any(p.multipliers.size for p in pts):
        return False
    fig, ax = new_figure(figsize=(6.6, 5.6))
    th = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(th), np.sin(th), color="k", lw=0.8)
    z = np.concatenate([np.where(np.abs(p.multipliers) < zero_floor(p), 0.0, p.multipliers)
                        for p in pts])
    w = np.concatenate([np.full(p.multipliers.size, quantity(pr, p, xk)) for p in pts])
    sc = scatter(ax, z.real, z.imag, w, s=5, cmap="plasma")
    cb = fig.colorbar(sc, ax=ax, label=show.fep_labels[0])
    cb.formatter.set_useOffset(False)
    r = min(max(1.6, float(np.percentile(np.abs(z), 98)) * 1.1), 4.0)
    outside = int(np.sum(np.maximum(np.abs(z.real), np.abs(z.imag)) > r))
    ax.set_xlim(-r, r)
    ax.set_ylim(-r, r)
    ax.set_aspect("equal")
    ax.set_xlabel(r"Re $\lambda$" + (f"   (clipped at ±{r:.2g}: {outside} multipliers outside)"
                                     if outside else ""))
    ax.set_ylabel(r"Im $\lambda$")
    ax.set_title("Floquet multipliers in the complex plane (unit circle)")
    ax.grid(alpha=0.25)
    fig.tight_layout()
    save(fig, path)
    return True
