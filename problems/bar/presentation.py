"""Presentation of the bar's three problems, one class per problem (Yoong, Thorin, Legrand
2017): what the diagrams, CSV files, reports and extra figures show, all pure functions of the
results and the parameters. Each class is its problem's ``presentation_class`` (a
:class:`~nsm_continuation.core.presentation.Presentation`) and reads the problem through
``self.problem``:

* :class:`WfemBarPresentation` (``wfem_bar``) and :class:`BarContinuumPresentation`
  (``bar_continuum``): the frequency-energy plot of the paper's figures, in ``omega / omega_1``
  (eq. 13) and ``E / E_ref`` (eq. 14), with the linear frequencies omega_k (fixed-free) and
  Omega_k (fixed-fixed) and the energy asymptotes (sec. 6.1, eq. 16);
* :class:`ForcedBarPresentation` (``wfem_forced_bar``): the frequency response of section 7
  (Figs. 20-22) with its linear references in closed form and the NSM backbones.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import (
    Signature,
    continuum_orbit,
    main_asymptote,
    main_backbone,
    main_signature,
    subharmonic_asymptote,
)

from nsm_continuation.core.presentation import Presentation


class BarFepPresentation(Presentation):
    """The frequency-energy plot of the bar's free vibrations (Figs. 5-7, 12): ``omega /
    omega_1`` against ``E / E_ref`` on a log scale, shared by the WFEM lattice and its
    continuum limit."""

    fep_axes = ("omega_ratio", "energy_ratio")
    fep_labels = (r"frequency $\omega/\omega_1$ (eq. 13)", r"energy $E/E_{ref}$ (eq. 14)")
    diagram_title: ClassVar[str] = "Frequency-energy plot"
    diagram_yscale: ClassVar[str] = "log"
    csv_head = ["T", "omega", "energy"]
    event_columns = ["omega", "T", "energy"]

    @property
    def quantity_labels(self) -> dict[str, str]:
        return dict(zip(self.fep_axes, self.fep_labels, strict=True))

    @staticmethod
    def draw_frequencies(ax: Any, x_range: tuple[float, float], asymptotes: set[float],
                         asymptote_label: str) -> None:
        """The linear frequencies omega_k = (2k - 1) omega_1 (fixed-free, dotted blue) and
        Omega_k = 2k omega_1 (fixed-fixed, dotted orange), and the ``asymptotes`` (dashed
        grey) inside ``x_range``, the first of each kind labelled."""
        lo, hi = x_range
        names = {"ff": r"$\omega_k$ (linear, fixed-free)",
                 "FF": r"$\Omega_k$ (linear, fixed-fixed)", "as": asymptote_label}
        for k in range(1, 40):
            for x, col, key in ((2 * k - 1, "tab:blue", "ff"), (2 * k, "tab:orange", "FF")):
                if lo - 0.05 <= x <= hi + 0.05:
                    ax.axvline(x, ls=":", color=col, lw=0.8, zorder=1,
                               label=names.pop(key, "_nolegend_"))
        for x in sorted(asymptotes):
            if lo - 0.05 <= x <= hi + 0.05:
                ax.axvline(x, ls="--", color="0.5", lw=0.8, zorder=1,
                           label=names.pop("as", "_nolegend_"))


class WfemBarPresentation(BarFepPresentation):
    """Presentation of ``wfem_bar`` (:class:`problems.bar.wfem_bar.WfemBarProblem`): the
    frequency-energy plot, the lattice asymptotes against the paper's formulas, the filter's
    counters and the orbit figures of :mod:`problems.bar.plots`. Reads the problem's ``model`` (the
    :class:`~problems.bar.wfem_lattice.BarModel`), the seed notes and the node counters
    (``_seed_notes``, ``filter_counts``, ``node_evaluations``)."""

    def summary(self) -> dict[str, Any]:
        md = self.problem.model
        return {"c": md.c, "dt": md.dt, "omega_1": md.omega1, "E_ref": md.energy_ref,
                "cells": md.N, "gap": md.g0}

    def warnings(self) -> list[str]:
        return list(self.problem._seed_notes)

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        formulas = {f"main mode {k} (sec. 6.1)": main_asymptote(k) for k in range(1, 6)}
        formulas.update({f"subharmonic k={k}, n={n} (eq. 16)": subharmonic_asymptote(k, n)
                         for k in range(1, 5) for n in range(1, 8)})
        asym = []
        for br in branches:
            for ev in br.events:
                if ev.kind == "asymptote":
                    r = ev.data["omega_ratio"]
                    name, val = min(formulas.items(), key=lambda kv: abs(kv[1] - r))
                    asym.append({"branch": br.id, "label": br.label, "lattice": r,
                                 "nearest_formula": name, "formula": val, "difference": r - val})
        return {"asymptotes_vs_paper": asym, "filter_removed": dict(self.problem.filter_counts),
                "lattice_nodes_evaluated": self.problem.node_evaluations,
                "main_asymptotes_omega_ratio": [main_asymptote(k) for k in (1, 2, 3)]}

    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """omega_k (fixed-free), Omega_k (fixed-fixed) and the g0 = 0 asymptotes."""
        self.draw_frequencies(ax, x_range, {main_asymptote(k) for k in range(1, 20)},
                              r"$g_0=0$ asymptote (sec. 6.1)")

    def closed_forms(self, x_range: tuple[float, float], branches: list[Any]
                     ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """The main backbones of the continuum limit in closed form (sec. 6.1,
        :func:`~problems.bar.continuum_orbits.main_backbone`) for this gap's sign, those that
        start inside ``x_range``: the curves the WFEM branches approach as the cells
        shrink (Figs. 5-7). None for g0 = 0 (vertical: the asymptotes)."""
        sign = float(np.sign(self.problem.model.g0))
        if sign == 0.0:
            return []
        xs, ys = [], []
        for k in range(1, 20):
            x, y = main_backbone(k, sign)
            if x.size and x_range[0] - 0.05 <= x.min() <= x_range[1] + 0.05:
                xs += [x, [np.nan]]
                ys += [y, [np.nan]]
        if not xs:
            return []
        return [(np.concatenate(xs), np.concatenate(ys),
                 "main backbones of the continuum (closed form, sec. 6.1)")]

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Space-time fields (Fig. 8a, 10a, 13, 17), contact-end series, manifold (Fig. 9)."""
        from nsm_continuation.problems.bar import plots

        return plots.extra_plots(out_dir, branches, self.problem)


class BarContinuumPresentation(BarFepPresentation):
    """Presentation of ``bar_continuum`` (:class:`problems.bar.continuum.BarContinuumProblem`):
    the frequency-energy plot and, per branch, its signature, asymptote and end energies.
    Reads the problem's scales (``c``, ``omega1``, ``energy_ref``, ``energy_0``, ``g0``,
    ``L``)."""

    def summary(self) -> dict[str, Any]:
        pr = self.problem
        return {"c": pr.c, "omega_1": pr.omega1, "E_ref": pr.energy_ref, "E_0": pr.energy_0,
                "gap": pr.g0, "time_unit_L_over_c": pr.L / pr.c}

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Per branch: signature, asymptote, admissible interval and the end energies."""
        out = []
        for br in branches:
            sig = br.info.get("signature")
            if sig is None:
                continue
            s = Signature(*sig)
            ends = {}
            for name, T in (("contact_end", s.T_contact_end), ("free_end", s.T_free_end)):
                mu = continuum_orbit(s, T).mu
                ends[f"energy_ratio_at_{name}"] = 32 / (np.pi**2 * mu**2) if mu else np.inf
                ends[f"omega_ratio_at_{name}"] = 4.0 / T
            out.append({"label": br.label, "signature": sig,
                        "omega_ratio_asymptote": br.info.get("omega_ratio_asymptote"),
                        "admissible_omega_ratio": br.info.get("admissible_omega_ratio"),
                        **ends})
        return {"branches": out}

    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """omega_k, Omega_k, and the asymptotes of the main backbones and of every backbone
        the run continued (its start's ``omega_ratio_asymptote``)."""
        asym = {main_signature(k).omega_ratio_asymptote for k in range(1, 20)}
        asym |= {br.info["omega_ratio_asymptote"] for br in branches
                 if br.info.get("omega_ratio_asymptote") is not None}
        self.draw_frequencies(ax, x_range, asym, r"asymptote ($g_0 = 0$ branch)")


#: dash patterns of the linear references, one per damping ratio (drawn dark over the sweeps,
#: which follow them where the contact is absent or permanent)
REFERENCE_DASHES = ((0, (4, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))


class ForcedBarPresentation(Presentation):
    """Presentation of ``wfem_forced_bar``
    (:class:`problems.bar.forced_response.WfemForcedBarProblem`): the frequency response of
    section 7 against the linear references (:meth:`linear_reference` of the problem) and the
    main NSM backbones (:func:`problems.bar.continuum_orbits.main_backbone`). Reads the
    problem's ``params``, ``bar`` (the :class:`~problems.bar.wfem_stepping.BarParams`), ``eta``
    and ``linear_reference``."""

    diagram_title: ClassVar[str] = "Frequency response (steady state, section 7)"
    diagram_yscale: ClassVar[str] = "log"
    fep_axes = ("omega_ratio", "energy_ratio")
    csv_head = ["omega_ratio", "omega", "energy_ratio", "linear_energy_ratio", "amplitude",
                "linear_amplitude", "steady", "multiple", "contact_fraction", "damping_ratio"]
    event_columns = ["omega_ratio", "energy_ratio", "amplitude", "multiple", "damping_ratio"]

    def reference_label(self) -> str:
        if self.problem.params.force_amplitude != 0.0:
            return "linear, no contact (closed form)"
        if self.problem.bar.g0 < 0.0:
            return "linear, permanent contact (closed form)"
        return "none (without contact the bar stays at rest)"

    @property
    def fep_labels(self) -> tuple[str, str]:  # type: ignore[override]
        y = (r"period-averaged energy $\bar E/E_{ref}$ (eq. 14)" if self.problem.bar.g0 != 0
             else r"period-averaged energy $\bar E$ (g0 = 0: absolute)")
        return (r"forcing frequency $\omega/\omega_1$", y)

    def reference_curve(self, eta: float, x_range: tuple[float, float],
                        n: int = 600) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The linear reference on a fine grid of ``omega / omega_1``: ``(x, E/E_ref,
        amplitude)`` (NaN where there is none)."""
        x = np.linspace(x_range[0], x_range[1], n)
        pr = self.problem
        ref = np.array([pr.linear_reference(xi * pr.bar.omega1, eta) for xi in x])
        return x, ref[:, 0], ref[:, 1]

    def backbones(self, x_range: tuple[float, float]) -> list[tuple[np.ndarray, np.ndarray,
                                                                    str]]:
        """The main NSM backbones (modes 1, 2) inside ``x_range`` (:func:`main_backbone`)."""
        out = []
        for k in (1, 2):
            x, y = main_backbone(k, np.sign(self.problem.bar.g0))
            keep = (x >= x_range[0]) & (x <= x_range[1])
            if keep.any():
                out.append((x[keep], y[keep], f"NSM backbone, mode {k}"))
        return out

    @property
    def quantity_labels(self) -> dict[str, str]:
        return {**dict(zip(self.fep_axes, self.fep_labels, strict=True)),
                "amplitude": r"end amplitude $(\max u(L) - \min u(L))/2$"}

    def event_styles(self) -> dict[str, tuple[str, str, str] | None]:
        """``response_change`` is drawn as the change from filled to hollow points (or back),
        not as a marker of its own (:meth:`point_fill`)."""
        return {"response_change": None}

    def branch_name(self, branch: Any) -> str:
        """``zeta_1 = 0.02 (eta = 0.06283)`` in symbols (the damping ratio of the sweep)."""
        pts = branch.points
        if not pts or "damping_ratio" not in pts[0].derived:
            return str(branch.label)
        d = pts[0].derived
        return (rf"damping $\zeta_1$ = {d['damping_ratio']:g} ($\eta$ = {d['eta']:.4g})"
                if "eta" in d else rf"damping $\zeta_1$ = {d['damping_ratio']:g}")

    def point_fill(self) -> tuple[str, str, str] | None:
        """Steady responses filled, the others hollow."""
        return ("steady", "steady response (periodic or subharmonic): filled",
                "not steady within the time budget (quasi-periodic or chaotic): hollow")

    def references(self, x_range: tuple[float, float]
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, str]]:
        """The linear references with a value in ``x_range``, one per damping ratio in the
        order of the sweeps: ``(x, E/E_ref, amplitude, label)``."""
        out = []
        for zeta in self.problem.params.damping_ratios:
            x, e, a = self.reference_curve(self.problem.eta(zeta), x_range)
            if np.isfinite(e).any():
                out.append((x, e, a, f"{self.reference_label()}, " + rf"$\zeta_1$ = {zeta:g}"))
        return out

    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """The linear references where there are some (dashed, in the colour of the sweep of
        their damping ratio), the main NSM backbones (closed form) and the linear resonances
        omega_k (fixed-free) and Omega_k (fixed-fixed), each kind labelled once."""
        from nsm_continuation.problems.bar.plots_forced import draw_backbones


        for k, (x, e, _, label) in enumerate(self.references(x_range)):
            ax.plot(x, e, ls=REFERENCE_DASHES[k % len(REFERENCE_DASHES)], color="0.15",
                    lw=0.9, zorder=4, label=label)
        draw_backbones(ax, [(x, y, "NSM backbones, modes 1-2 (closed form, sec. 6.1)"
                             if k == 0 else "_nolegend_")
                            for k, (x, y, _) in enumerate(self.backbones(x_range))],
                       color="k")
        BarFepPresentation.draw_frequencies(ax, x_range, set(), "")

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """``frequency_response.png``: the end amplitude against the forcing frequency, one
        curve per sweep (steady filled, not steady hollow), with the linear references (the
        energy is the branch diagram, ``fep.png``)."""
        from pathlib import Path

        from nsm_continuation.problems.bar.plots_forced import (
            frequency_response_figure,
            response_curves,
        )

        from nsm_continuation.figures.kit import outside_legend, save

        curves = [dataclasses.replace(c, label=self.branch_name(b)) for c, b in zip(
            response_curves(branches), [b for b in branches if b.points], strict=True)]
        if not curves:
            return []
        xs = np.concatenate([c.x for c in curves])
        x_range = (float(xs.min()), float(xs.max()))
        fig = frequency_response_figure(curves, self.references(x_range),
                                        title=self.figure_title())
        BarFepPresentation.draw_frequencies(fig.axes[0], x_range, set(), "")
        outside_legend(fig.axes[0])
        fig.tight_layout()
        save(fig, Path(out_dir) / "frequency_response.png")
        return ["frequency_response.png"]

    def figure_title(self) -> str:
        p = self.problem.params
        what = ("moving wall" if p.force_amplitude == 0 else "distributed force"
                if p.wall_amplitude == 0 else "moving wall and distributed force")
        return (f"Forced response, {what} (w0 = {p.wall_amplitude:g}, f0 = "
                f"{p.force_amplitude:g}), g0 = {p.gap:g}, N = {p.cells}")

    def summary(self) -> dict[str, Any]:
        bar, p = self.problem.bar, self.problem.params
        return {"omega_1": bar.omega1, "dt": bar.time_step, "E_ref": bar.energy_ref,
                "cells": bar.N, "gap": bar.g0, "wall_amplitude": p.wall_amplitude,
                "force_amplitude": p.force_amplitude, "damping_ratios": p.damping_ratios,
                "eta": [self.problem.eta(z) for z in p.damping_ratios],
                "linear_reference": self.reference_label(), "switching": p.switching}

    def warnings(self) -> list[str]:
        p = self.problem.params
        if p.force_amplitude == 0.0 and 0.0 <= p.wall_amplitude <= p.gap:
            return [f"wall_amplitude = {p.wall_amplitude:g} <= gap = {p.gap:g}: the wall never "
                    "reaches the bar at rest (section 7 takes w0 > g0)"]
        return []

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Per sweep: the resonance peak, the count of periodic / subharmonic / not steady
        responses, the simulated steps, and the largest deviation from the linear reference."""
        out = []
        for br in branches:
            pts = br.points
            if not pts:
                continue
            d = [p.derived for p in pts]
            peak = max(d, key=lambda q: q["energy_ratio"])
            lin = np.array([q["linear_energy_ratio"] for q in d])
            en = np.array([q["energy_ratio"] for q in d])
            dev = np.abs(en / lin - 1.0)[np.isfinite(lin)]
            out.append({"branch": br.id, "label": br.label,
                        "peak_omega_ratio": peak["omega_ratio"],
                        "peak_energy_ratio": peak["energy_ratio"],
                        "periodic": sum(q["multiple"] == 1 for q in d),
                        "subharmonic": sum(q["multiple"] > 1 for q in d),
                        "not_steady": sum(q["multiple"] == 0 for q in d),
                        "steps": int(sum(q["steps"] for q in d)),
                        "max_relative_deviation_from_linear": (float(dev.max()) if dev.size
                                                               else None)})
        return {"sweeps": out, "linear_reference": self.reference_label()}


__all__ = ["BarContinuumPresentation", "ForcedBarPresentation", "WfemBarPresentation"]
