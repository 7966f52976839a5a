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
COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")


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
    ax.plot(x, y, "-", color=color, lw=0.8, alpha=0.6)
    ax.plot(x[steady], y[steady], "o", ms=3, color=color, label=label)
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
                              backbones: Sequence[Backbone], energy_label: str,
                              reference_label: str, title: str = "") -> Any:
    """Two panels against ``omega / omega_1``: the period-averaged energy (log scale, with
    the backbones and the linear references) and the end amplitude ``(max u - min u) / 2``
    (with the linear references); curves coloured by sweep, references dashed in the colour of
    the sweep with the same index (one reference per damping ratio)."""
    from nsm_continuation.figures.kit import subplots

    fig, (ax_e, ax_a) = subplots(1, 2, figsize=(13, 5.2), constrained_layout=True)
    for i, c in enumerate(curves):
        col = COLORS[i % len(COLORS)]
        draw_response(ax_e, c.x, c.energy, c.steady, col, c.label)
        draw_response(ax_a, c.x, c.amplitude, c.steady, col, c.label)
    e_all = np.concatenate([c.energy for c in curves])
    e_all = e_all[np.isfinite(e_all) & (e_all > 0)]
    for i, (x, e, a, lab) in enumerate(references):
        col = COLORS[i % len(COLORS)]
        if np.isfinite(e).any():
            ax_e.plot(x, e, "--", color=col, lw=0.9, alpha=0.8,
                      label=f"{reference_label}, {lab}")
            ax_a.plot(x, a, "--", color=col, lw=0.9, alpha=0.8,
                      label=f"{reference_label}, {lab}")
    if e_all.size:  # references and backbones (poles) must not hide the computed curves
        ax_e.set_ylim(e_all.min() / 10.0, e_all.max() * 10.0)
    draw_backbones(ax_e, backbones)
    x_all = np.concatenate([c.x for c in curves])
    for ax in (ax_e, ax_a):
        draw_linear_resonances(ax, (float(x_all.min()), float(x_all.max())))
        ax.set_xlabel(r"forcing frequency $\omega / \omega_1$")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    ax_e.set_ylabel(energy_label)
    ax_a.set_ylabel(r"end amplitude $(\max u(L) - \min u(L)) / 2$")
    ax_e.set_title("frequency response: period-averaged energy (filled: steady, hollow: not)",
                   fontsize=9)
    ax_a.set_title("frequency response: end displacement amplitude", fontsize=9)
    if title:
        fig.suptitle(title)
    return fig
