"""Frequency-response figures of the forced bar (section 7, Figs. 20-22).

Yoong, Thorin, Legrand (2017): the total energy of the steady state averaged over one forcing
period is plotted against the forcing frequency, normalised by ``omega_1 = pi c / (2L)`` (13)
and by the energy of the first linear mode's grazing orbit ``E_ref = pi^2 E S g0^2 / (16 L)``
(14); for ``g0 = 0`` the energy is absolute. The linear response (closed form) is the reference
curve, and the NSM backbones (frequency-energy branches of the nonsmooth modes) can be overlaid:
the paper's point is that the resonance peaks of the forced response follow them.

Two entry points: :func:`plot_forced_response` draws :class:`ForcedSweep` objects
(``benchmarks/bench_wfem_forced_response.py``), :func:`frequency_response_figure` the branches of
a ``wfem_forced_bar`` run (:func:`response_curves`); both draw each curve with
:func:`draw_response`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from nsm_continuation.problems.bar.forced_steady_state import ForcedSweep

Backbone = tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, str]
#: a linear reference: ``(omega / omega_1, E / E_ref, end amplitude, label)``
Reference = tuple[np.ndarray, np.ndarray, np.ndarray, str]
#: colours of the sweeps of :func:`plot_forced_response` (the palette of the run's figures:
#: neither the stability red nor the Neimark-Sacker green)
COLORS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink")


@dataclass
class ResponseCurve:
    """One frequency sweep: ``x = omega / omega_1``, ``energy`` (normalised), end
    ``amplitude``, ``steady`` flags (periodic or subharmonic steady state) and a label."""

    x: np.ndarray
    energy: np.ndarray
    amplitude: np.ndarray
    steady: np.ndarray
    label: str


def energy_scale(sweep: ForcedSweep) -> tuple[float, str]:
    """``(E_ref, label)``: (14) for ``g0 != 0``, ``(1, "E")`` for ``g0 = 0``."""
    p = sweep.params
    if p.g0 == 0.0:
        return 1.0, r"$\bar E$"
    return p.energy_ref, r"$\bar E / E_{ref}$"


def draw_response(ax: Any, x: np.ndarray, y: np.ndarray, steady: np.ndarray, color: str,
                  label: str | None) -> None:
    """One response curve: steady points filled and joined by a thin line, points flagged
    not steady (quasi-periodic or chaotic within the time budget) hollow."""
    steady = np.asarray(steady, dtype=bool)
    ax.plot(x, y, "-", color=color, lw=0.8, alpha=0.6, label=label)
    ax.plot(x[steady], y[steady], "o", ms=3, color=color)
    ax.plot(x[~steady], y[~steady], "o", ms=3, mfc="none", color=color)


def draw_backbones(ax: Any, backbones: Sequence[Backbone], color: str = "k") -> None:
    """Backbones as solid lines; one whose energies are all NaN (g0 = 0: energy free at a
    fixed frequency) as a vertical line at its frequency."""
    for j, bb in enumerate(backbones):
        xb, yb = np.asarray(bb[0]), np.asarray(bb[1])
        lab = bb[2] if len(bb) > 2 else ("backbone (NSM)" if j == 0 else None)
        if np.all(np.isnan(yb)):
            ax.axvline(float(xb[0]), color=color, lw=1.2, label=lab)
        else:
            ax.plot(xb, yb, "-", color=color, lw=1.2, label=lab)


def draw_linear_resonances(ax: Any, x_range: tuple[float, float]) -> None:
    """The linear resonances ``omega_k = (2k - 1) omega_1`` (fixed-free, eq. 13, dotted blue)
    and ``Omega_k = 2k omega_1`` (fixed-fixed, dotted orange) inside ``x_range``."""
    lo, hi = x_range
    for k in range(1, 50):
        for x, col in ((2 * k - 1, "tab:blue"), (2 * k, "tab:orange")):
            if lo - 0.05 <= x <= hi + 0.05:
                ax.axvline(x, ls=":", color=col, lw=0.8, zorder=1)


def plot_forced_response(ax: Any, sweeps: Sequence[ForcedSweep],
                         backbones: Sequence[Backbone] | None = None,
                         labels: Sequence[str] | None = None,
                         colors: Sequence[str] | None = None) -> None:
    """Draw forced-response sweeps (one curve each) and backbones on a matplotlib ``ax``.

    ``backbones``: ``(omega / omega_1, energy / E_ref)`` arrays, optionally with a label, drawn
    as black lines (use the same normalisation as the sweeps: absolute energy for g0 = 0).
    """
    colors = COLORS if colors is None else colors
    ylabel = r"$\bar E / E_{ref}$"
    for i, sw in enumerate(sweeps):
        scale, ylabel = energy_scale(sw)
        lab = labels[i] if labels is not None else rf"$\eta$ = {sw.eta:.3g}"
        draw_response(ax, sw.omegas / sw.params.omega1, sw.energies / scale, sw.steady,
                      colors[i % len(colors)], lab)
    if backbones:
        draw_backbones(ax, backbones)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\omega / \omega_1$")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)


def response_curves(branches: Sequence[Any]) -> list[ResponseCurve]:
    """The sweeps of a ``wfem_forced_bar`` run (its branches, points with the derived
    ``omega_ratio``, ``energy_ratio``, ``amplitude``, ``steady``)."""
    out = []
    for br in branches:
        if not br.points:
            continue
        d = [p.derived for p in br.points]
        out.append(ResponseCurve(np.array([q["omega_ratio"] for q in d]),
                                 np.array([q["energy_ratio"] for q in d]),
                                 np.array([q["amplitude"] for q in d]),
                                 np.array([q["steady"] > 0 for q in d]), br.label))
    return out


def frequency_response_figure(curves: Sequence[ResponseCurve], references: Sequence[Reference],
                              title: str = "") -> Any:
    """The end amplitude ``(max u - min u) / 2`` against ``omega / omega_1``: one curve per
    sweep (steady points filled, the others hollow, :func:`draw_response`), coloured by sweep
    from the palette of :mod:`nsm_continuation.figures.styles`, the linear ``references``
    dark, one dash pattern per damping ratio, over the sweeps. Log axis
    where the amplitudes span more than a decade. (The period-averaged energy of the same
    sweeps is the run's branch diagram.)"""
    from nsm_continuation.figures.kit import (
        new_figure,
        outside_legend,
        set_scale,
        wants_log,
    )
    from nsm_continuation.figures.styles import palette_colour

    fig, ax = new_figure(figsize=(11, 5.2))
    for i, c in enumerate(curves):
        draw_response(ax, c.x, c.amplitude, c.steady, palette_colour(i), c.label)
    dashes = ((0, (4, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))
    for i, (x, _, a, lab) in enumerate(references):
        if np.isfinite(a).any():
            ax.plot(x, a, ls=dashes[i % len(dashes)], color="0.15", lw=0.9, zorder=4,
                    label=lab)
    amp = np.concatenate([c.amplitude for c in curves])
    set_scale(ax, "y", wants_log(amp))
    set_scale(ax, "x", False)
    ax.set_xlabel(r"forcing frequency $\omega / \omega_1$ (eq. 13)")
    ax.set_ylabel(r"end amplitude $(\max u(L) - \min u(L)) / 2$")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Frequency response: end displacement amplitude (filled: steady, hollow: "
                 "not steady)" + (f"\n{title}" if title else ""), fontsize=10)
    outside_legend(ax)
    fig.tight_layout()
    return fig
