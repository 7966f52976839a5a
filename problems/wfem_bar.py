"""Elastic bar with a unilateral contact, WFEM: nonsmooth modes on the (m, p) lattice.

Yoong, Thorin, Legrand (2017). The bar (E, rho, L, N cells) is clamped at x = 0 and meets a rigid
obstacle at x = L across the signed gap ``g0``. Periodic orbits of the WFEM discretisation solve
``(A_c^p A_f^m - I) Q = 0`` (12) with COND1-COND3; they exist only at lattice periods
``T = (m + p) dt``. The lattice engine (:mod:`nsm_continuation.lattice`) continues them: the
predictor extrapolates the phase lengths linearly along the branch (exact for these branches:
the free time is an affine function of the period, see :mod:`problems.bar_continuum`), the
corrector picks, among the admissible *physical* solutions (filter of
:func:`problems.wfem_lattice.classify`) near the predicted node, the one continuing the previous
one (same number of profile jumps, energy closest to the extrapolated energy).

YAML::

    problem: wfem_bar
    parameters: {E: 1, rho: 1, L: 1, cells: 1000, gap: 1.0e-3}
    start: {branch: main, mode: 1}        # or {scan: true}, or {node: [m, p]}
    continuation: {parameter: omega_ratio, min: 1.0, max: 2.0, max_energy: 1.0e3}

``omega_ratio`` is omega / omega_1 with omega_1 = pi c / (2L); ``max_energy`` bounds the energy
ratio E / E_ref (E_ref of eq. 14; absolute energy when g0 = 0).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from nsm_continuation.lattice import LatticeProblem, LatticeSeed

from .wfem_lattice import (
    BarModel,
    LatticeSolution,
    classify,
    grazing_representative,
    node_solutions,
    profile_jumps,
)
from .wfem_operators import kernel_dimensions_at_period

PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class WfemBarParameters(BaseModel):
    model_config = ConfigDict(extra="forbid")
    E: PosFloat = 1.0
    rho: PosFloat = 1.0
    L: PosFloat = 1.0
    cells: Annotated[int, Field(ge=2, le=200_000)] = 200
    gap: Annotated[float, Field(allow_inf_nan=False)] = 1e-3
    #: filter: largest number of profile jumps kept, as a fraction of N (grid-scale orbits jump at
    #: O(N) places); persistence under N -> 2N is always checked
    max_jumps_fraction: Annotated[float, Field(gt=0, le=2)] = 0.25
    #: search half-width (in steps of m) around the predicted node
    corrector_window: Annotated[int, Field(ge=0, le=1000)] = 3
    #: largest gap in M (period steps) bridged between two lattice solutions of one branch,
    #: as a fraction of N
    max_gap_fraction: Annotated[float, Field(gt=0, le=1)] = 0.05


class MainStart(BaseModel):
    """The main backbone of mode k (section 6.1)."""

    model_config = ConfigDict(extra="forbid")
    branch: Literal["main"]
    mode: Annotated[int, Field(ge=1, le=50)] = 1


class SubharmonicStart(BaseModel):
    """The n-th subharmonic backbone of mode k (g0 > 0), starting near eq. (15)."""

    model_config = ConfigDict(extra="forbid")
    branch: Literal["subharmonic"]
    mode: Annotated[int, Field(ge=1, le=50)] = 1
    n: Annotated[int, Field(ge=1, le=50)] = 1


class ScanStart(BaseModel):
    """Every physical admissible orbit in the window seeds a branch (Fig. 12, 16)."""

    model_config = ConfigDict(extra="forbid")
    scan: Literal[True]
    max_seeds: Annotated[int, Field(ge=1)] = 200


class NodeStart(BaseModel):
    """An explicit lattice node (m, p) or (m, p, k, l) (eq. 18)."""

    model_config = ConfigDict(extra="forbid")
    node: list[Annotated[int, Field(ge=1)]]
    direction: Literal["both", "increase", "decrease"] = "both"


OneStart = MainStart | SubharmonicStart | ScanStart | NodeStart
StartSpec = OneStart | list[OneStart]


def main_asymptote(k: int) -> float:
    """omega / omega_1 of the g0 = 0 main backbone of mode k (section 6.1): (w_k+1)^2/(w_k+2)."""
    wk = 2 * k - 1
    return (wk + 1) ** 2 / (wk + 2)


def subharmonic_start(k: int, n: int) -> float:
    """omega / omega_1 where the n-th subharmonic of mode k starts for g0 > 0, eq. (15)."""
    return (2 * k * (n + 1) - 1) / (n + 1)


def subharmonic_asymptote(k: int, n: int) -> float:
    """omega / omega_1 of the subharmonic asymptote, eq. (16)."""
    wk = 2 * k - 1
    return (n + 1) * (wk + 1) ** 2 / (wk * (n + 1) + n + 2)


def internal_resonance(k: int) -> float:
    """omega / omega_1 of the internal-resonance branches, eq. (17): 2k / (2k - 1)."""
    return 2 * k / (2 * k - 1)


class WfemBarProblem(LatticeProblem):
    name = "wfem_bar"
    Parameters = WfemBarParameters
    start_adapter = TypeAdapter(StartSpec)
    fep_axes = ("omega_ratio", "energy_ratio")
    energy_quantity = "energy_ratio"

    def __init__(self, params: WfemBarParameters) -> None:
        super().__init__(params)
        self.model = BarModel(params.E, params.rho, params.L, params.cells, params.gap)
        self.variables = ["omega_ratio", "contact_fraction"]
        self.parameter = "omega_ratio"
        self._cache: dict[tuple[int, ...], list[LatticeSolution]] = {}
        self.filter_counts: dict[str, int] = {}
        self.node_evaluations = 0
        #: energy-ratio bound of the case (set by the runner; seeds above it are not used)
        self.energy_cap: float | None = None

    # -- lattice <-> frequency -------------------------------------------------------------
    def M_of(self, omega_ratio: float) -> float:
        """Number of steps of a period with frequency omega_ratio * omega_1: 4N / ratio."""
        return 4 * self.model.N / omega_ratio

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        if name != "omega_ratio":
            raise ValueError(f"continuation.parameter: wfem_bar continues in 'omega_ratio' "
                             f"(omega / omega_1), not {name!r}")
        if lo is not None and lo <= 0:
            raise ValueError("continuation.min: omega_ratio must be > 0")
        return lo, hi

    def _in_window(self, M: int, window: tuple[float | None, float | None]) -> bool:
        r = 4 * self.model.N / M
        lo, hi = window
        return (lo is None or r >= lo - 1e-12) and (hi is None or r <= hi + 1e-12)

    # -- solutions at a node (cached), with the filter ---------------------------------------
    def physical(self, counts: tuple[int, ...]) -> list[LatticeSolution]:
        counts = tuple(int(c) for c in counts)
        if counts in self._cache:
            return self._cache[counts]
        self.node_evaluations += 1
        status, sols = node_solutions(self.model, counts)
        keep = []
        max_jumps = self.params.max_jumps_fraction * self.model.N
        for s in sols:
            reason = classify(s)
            if reason == "physical" and profile_jumps(s.w0) > max_jumps:
                reason = "grid-scale (profile jumps > max_jumps_fraction * N)"
            if reason == "physical":
                keep.append(s)
            else:
                self.filter_counts[reason] = self.filter_counts.get(reason, 0) + 1
        self._cache[counts] = keep
        return keep

    def scan_window(self, window: tuple[float | None, float | None]) -> list[LatticeSolution]:
        """All physical one-contact-phase orbits with omega_ratio in the window.

        The kernel dimension of every node of a period comes from one vectorised sweep
        (:func:`problems.wfem_operators.kernel_dimensions_at_period`); only nodes with
        ``1 <= h <= 8`` are solved.
        """
        lo, hi = window
        N = self.model.N
        M_hi = int(np.floor(4 * N / lo)) if lo else 8 * N
        M_lo = int(np.ceil(4 * N / hi)) if hi else 2
        out = []
        for M in range(max(M_lo, 2), M_hi + 1):
            h = kernel_dimensions_at_period(N, M)
            for m in np.nonzero((h >= 1) & (h <= 8))[0] + 1:
                out += self.physical((int(m), M - int(m)))
        return out

    # -- seeds ---------------------------------------------------------------------------------
    def lattice_seeds(self, start: Any, window: tuple[float | None, float | None]
                      ) -> list[LatticeSeed]:
        spec = self.start_adapter.validate_python(start) if not isinstance(
            start, BaseModel) else start
        if isinstance(spec, list):
            return [seed for one in spec for seed in self.lattice_seeds(one, window)]
        md = self.model
        if isinstance(spec, NodeStart):
            if len(spec.node) not in (2, 4):
                raise ValueError("node must be [m, p] or [m, p, k, l]")
            sols = self.physical(tuple(spec.node))
            if not sols:
                raise ValueError(f"node {spec.node}: no physical admissible orbit")
            d = {"both": 0, "increase": 1, "decrease": -1}[spec.direction]
            return [LatticeSeed(sols[0], f"node {tuple(spec.node)}", d)]
        if isinstance(spec, ScanStart):
            sols = self.scan_window(window)
            sols.sort(key=lambda s: (profile_jumps(s.w0), s.energy))
            cap = self.energy_cap
            if cap is not None:  # seeds above the energy bound would give one-point branches
                sols = [s for s in sols if s.energy / md.energy_ref <= cap]
            return [LatticeSeed(s, f"scan seed (m, p) = {s.counts}", 0)
                    for s in sols[:spec.max_seeds]]
        k = spec.mode
        N = md.N
        if isinstance(spec, SubharmonicStart):
            if md.g0 <= 0:
                raise ValueError("branch: subharmonic starts are defined for gap > 0 (eq. 15)")
            r0 = subharmonic_start(k, spec.n)
            return self._first_seed(int(np.floor(4 * N / r0)) - 1, -1, 1,
                                    f"subharmonic n = {spec.n} of mode {k} (eq. 15: "
                                    f"{r0:.4f} omega_1)")
        if md.g0 == 0:
            return self._grazing_seeds(k)
        if md.g0 > 0:  # hardening from omega_k = (2k - 1) omega_1: periods just below T_k
            return self._first_seed(int(np.floor(4 * N / (2 * k - 1))) - 1, -1, 1,
                                    f"main backbone, mode {k}")
        # softening from Omega_k = 2k omega_1: periods just above
        return self._first_seed(int(np.ceil(2 * N / k)) + 1, 1, -1, f"main backbone, mode {k}")

    def _first_seed(self, M0: int, dM: int, direction: int, label: str) -> list[LatticeSeed]:
        """First physical orbit met from period M0 on (step dM), fewest jumps then lowest energy.

        Near the start of a backbone one phase is short (contact for g0 > 0, free for g0 < 0),
        so only nodes whose short phase is at most 5 % of the period are tried.
        """
        N = self.model.N
        for j in range(max(4, int(0.1 * N))):
            M = M0 + dM * j
            short = max(2, int(0.05 * M))
            pairs = ([(M - p, p) for p in range(1, short)] if direction > 0
                     else [(m, M - m) for m in range(1, short)])
            cands = [s for c in pairs for s in self.physical(c)]
            if cands:
                best = min(cands, key=lambda s: (profile_jumps(s.w0), s.energy))
                return [LatticeSeed(best, label, direction)]
        raise ValueError(f"no physical orbit found near the start of the {label} (N = {N}); "
                         "increase cells")

    def _grazing_seeds(self, k: int) -> list[LatticeSeed]:
        """g0 = 0: the vertical backbone of mode k at its asymptote (section 6.1).

        Nodes at the asymptote's period are tried in order of closeness of the contact fraction
        to 1/(2k + 1) (1/3 for mode 1: contact L/c in 3L/c; 1/5 for mode 2: L/(4c) in 5L/(4c)).
        """
        N = self.model.N
        M = int(round(4 * N / main_asymptote(k)))
        for p in sorted(range(1, M), key=lambda p: abs(p - M / (2 * k + 1))):
            sol = grazing_representative(self.model, (M - p, p))
            if sol is not None and classify(sol) == "physical":
                return [LatticeSeed(sol, f"main backbone, mode {k} (g0 = 0)", 1)]
        raise ValueError(f"g0 = 0, mode {k}: no admissible node at M = {M} "
                         f"(4N/M = {4 * N / M:.6f} omega_1)")

    # -- predictor / corrector ------------------------------------------------------------------
    def lattice_next(self, history: list[LatticeSolution], direction: int,
                     window: tuple[float | None, float | None]) -> tuple[Any, str]:
        last = history[-1]
        if last.amplitude_free:
            if len(history) == 1:  # the vertical line: same orbit, scaled
                scale = 1e2  # |characteristic| from 1e-3 E to 0.1 E: strains well below 1
                sol = LatticeSolution(last.model, last.counts, last.w0 * scale, last.J * scale,
                                      last.h, last.energy * scale**2, last.margins,
                                      last.grazing_steps, True)
                return sol, ""
            return None, "g0 = 0: vertical branch (amplitude free at a fixed period)"
        N = self.model.N
        dM = -direction
        max_gap = max(4, int(self.params.max_gap_fraction * N))
        W = self.params.corrector_window
        if len(history) >= 2:
            prev = history[-2]
            slopes = [(a - b) / (last.M - prev.M) for a, b in zip(last.counts, prev.counts,
                                                                   strict=True)]
        else:
            slopes = None
        jumps = profile_jumps(last.w0)
        for j in range(1, max_gap + 1):
            M = last.M + dM * j
            if M < 2 or not self._in_window(M, window):
                return None, "parameter bound (omega_ratio window)"
            if slopes is not None:
                pred = [c + s * (M - last.M) for c, s in zip(last.counts, slopes, strict=True)]
                m_c = int(round(pred[0]))
                width = W
                e_pred = self._energy_predict(history, M)
            else:
                # continuum limit: t_f = k T + const with k = number of profile jumps (the jump
                # set is a chain of k points spaced by the period, bar_continuum), so dm/dM = k
                m_c = last.counts[0] + jumps * (M - last.M)
                width = W + 2 * j
                e_pred = last.energy
            cands = []
            for m in range(max(1, m_c - width), min(M - 1, m_c + width) + 1):
                if len(last.counts) == 2:
                    cands += self.physical((m, M - m))
                    continue
                # two contact phases: keep the p = l symmetry (section 6.4), search p as well
                p_c = int(round(pred[1])) if slopes is not None else last.counts[1]
                for p in range(max(1, p_c - width), p_c + width + 1):
                    k = M - m - 2 * p
                    if k >= 1:
                        cands += self.physical((m, p, k, p))
            # continuity: same characteristic profile structure (number of jumps) and, once the
            # branch direction is known, an energy within 25 % of the extrapolated one
            cands = [c for c in cands if profile_jumps(c.w0) == jumps
                     and (slopes is None or abs(np.log(c.energy / e_pred)) < 0.25)]
            if cands:
                best = min(cands, key=lambda s: (abs(np.log(s.energy / e_pred)),
                                                 abs(s.counts[0] - m_c)))
                return best, ""
        return None, (f"no physical admissible lattice orbit within {max_gap} period steps "
                      "of the prediction")

    @staticmethod
    def _energy_predict(history: list[LatticeSolution], M: int) -> float:
        """Extrapolate E^(-1/2) linearly in M (exact on the continuum branches, eq. in
        :mod:`problems.bar_continuum`: E ~ (T - T*)^-2)."""
        a, b = history[-2], history[-1]
        ya, yb = a.energy ** -0.5, b.energy ** -0.5
        y = yb + (yb - ya) * (M - b.M) / (b.M - a.M)
        return float(y ** -2) if y > 0 else b.energy

    def lattice_point(self, sol: LatticeSolution) -> tuple[np.ndarray, dict[str, float],
                                                           dict[str, Any]]:
        d = sol.derived()
        y = np.array([d["omega_ratio"], d["contact_fraction"]])
        d["T"] = d["period"]
        return y, dict(sol.margins), d

    def lattice_character(self, sol: LatticeSolution) -> dict[str, int]:
        return {"grazing_instants": len(sol.grazing_steps)}

    def lattice_key(self, sol: LatticeSolution) -> Any:
        return sol.counts

    def asymptote(self, points: list[Any]) -> dict[str, float] | None:
        """Where E^(-1/2), linear in the period on these branches, reaches 0."""
        if len(points) < 2:
            return None
        a, b = points[-2].derived, points[-1].derived
        ya, yb = a["energy"] ** -0.5, b["energy"] ** -0.5
        if ya == yb:
            return None
        T_star = b["period"] + (a["period"] - b["period"]) * yb / (yb - ya)
        ratio = 2 * np.pi / T_star / self.model.omega1
        return {"omega_ratio": float(ratio), "period": float(T_star),
                "detail": f"energy without bound: asymptote at omega/omega_1 = {ratio:.6f}"}

    # -- report and plots -------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        md = self.model
        return {"c": md.c, "dt": md.dt, "omega_1": md.omega1, "E_ref": md.energy_ref,
                "cells": md.N, "gap": md.g0}

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
        return {"asymptotes_vs_paper": asym, "filter_removed": dict(self.filter_counts),
                "lattice_nodes_evaluated": self.node_evaluations,
                "main_asymptotes_omega_ratio": [main_asymptote(k) for k in (1, 2, 3)]}

    def plot_decorations(self, ax: Any, x_range: tuple[float, float]) -> None:
        lo, hi = x_range
        for k in range(1, 20):
            for x, ls, col in ((2 * k - 1, ":", "tab:blue"), (2 * k, ":", "tab:orange"),
                               (main_asymptote(k), "--", "0.5")):
                if lo - 0.05 <= x <= hi + 0.05:
                    ax.axvline(x, ls=ls, color=col, lw=0.8, zorder=1)

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Space-time fields (Fig. 8a, 10a, 13, 17), contact-end series, manifold (Fig. 9)."""
        from . import wfem_plots

        return wfem_plots.extra_plots(out_dir, branches, self)

    def legend_handles(self) -> list[Any]:
        from matplotlib.lines import Line2D
        return [Line2D([], [], ls=":", color="tab:blue", label=r"$\omega_k$ (fixed-free)"),
                Line2D([], [], ls=":", color="tab:orange", label=r"$\Omega_k$ (fixed-fixed)"),
                Line2D([], [], ls="--", color="0.5", label=r"$g_0=0$ asymptote (sec. 6.1)")]

    fep_labels = (r"$\omega/\omega_1$", r"energy $E/E_{ref}$ (eq. 14)")
