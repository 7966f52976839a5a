"""Frequency-energy plot of forced responses with optional NSM backbones (section 7, Figs. 20-22).

Yoong, Thorin, Legrand (2017): the total energy of the steady state averaged over one forcing
period is plotted against the forcing frequency, normalised by ``omega_1 = pi c / (2L)`` (13)
and by the energy of the first linear mode's grazing orbit ``E_ref = pi^2 E S g0^2 / (16 L)``
(14); for ``g0 = 0`` the energy is absolute. Backbone curves (frequency-energy branches of the
nonsmooth modes, computed elsewhere) can be overlaid.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .wfem_simulation import ForcedSweep

Backbone = tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, str]


def energy_scale(sweep: ForcedSweep) -> tuple[float, str]:
    """``(E_ref, label)``: (14) for ``g0 != 0``, ``(1, "E")`` for ``g0 = 0``."""
    p = sweep.params
    if p.g0 == 0.0:
        return 1.0, r"$\bar E$"
    return p.energy_ref, r"$\bar E / E_{ref}$"


def plot_forced_response(ax: Any, sweeps: Sequence[ForcedSweep],
                         backbones: Sequence[Backbone] | None = None,
                         labels: Sequence[str] | None = None,
                         colors: Sequence[str] | None = None) -> None:
    """Draw forced-response sweeps (one curve each) and backbones on a matplotlib ``ax``.

    Steady (periodic or subharmonic) points are filled markers joined by a line; points flagged
    not steady (quasi-periodic/chaotic within the time budget) are drawn as hollow markers.
    ``backbones``: ``(omega / omega_1, energy / E_ref)`` arrays, optionally with a label, drawn
    as black lines (use the same normalisation as the sweeps: absolute energy for g0 = 0).
    """
    if colors is None:
        colors = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    ylabel = r"$\bar E / E_{ref}$"
    for i, sw in enumerate(sweeps):
        scale, ylabel = energy_scale(sw)
        x = sw.omegas / sw.params.omega1
        y = sw.energies / scale
        st = sw.steady
        col = colors[i % len(colors)]
        lab = labels[i] if labels is not None else rf"$\eta$ = {sw.eta:.3g}"
        ax.plot(x, y, "-", color=col, lw=0.8, alpha=0.6)
        ax.plot(x[st], y[st], "o", ms=3, color=col, label=lab)
        ax.plot(x[~st], y[~st], "o", ms=3, mfc="none", color=col)
    if backbones:
        for j, bb in enumerate(backbones):
            xb, yb = np.asarray(bb[0]), np.asarray(bb[1])
            lab = bb[2] if len(bb) > 2 else ("backbone (NSM)" if j == 0 else None)
            ax.plot(xb, yb, "k-", lw=1.2, label=lab)
    ax.set_yscale("log")
    ax.set_xlabel(r"$\omega / \omega_1$")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
