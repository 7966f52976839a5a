"""Elastic bar with a unilateral contact, WFEM: nonsmooth modes on the (m, p) lattice.

Yoong, Thorin, Legrand (2017). The bar (E, rho, L, N cells) is clamped at x = 0 and meets a rigid
obstacle at x = L across the signed gap ``g0``. Periodic orbits of the WFEM discretisation solve
``(A_c^p A_f^m - I) Q = 0`` (12) with COND1-COND3; they exist only at lattice periods
``T = (m + p) dt``. The lattice engine (:mod:`nsm_continuation.core.lattice`) continues them: the
predictor extrapolates the phase lengths linearly along the branch (exact for these branches:
the free time is an affine function of the period, see :mod:`problems.bar.continuum_orbits`), the
corrector picks, among the admissible *physical* solutions (filter of
:func:`problems.bar.wfem_lattice.classify`) near the predicted node, the one continuing the previous
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

from math import ceil
from typing import Annotated, Any, ClassVar

import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import (
    main_asymptote,
    subharmonic_asymptote,
    subharmonic_start,
)
from nsm_continuation.problems.bar.presentation import WfemBarPresentation
from nsm_continuation.problems.bar.wfem_lattice import (
    BarModel,
    LatticeSolution,
    profile_jumps,
    solve_node,
)
from nsm_continuation.problems.bar.wfem_nodes import WfemLatticeNodes
from nsm_continuation.problems.bar.wfem_operators import check_reference_energy
from nsm_continuation.problems.bar.wfem_preflight import WfemBarPreflight
from nsm_continuation.problems.bar.wfem_starts import (
    MainStart,
    NodeStart,
    OneStart,
    ScanStart,
    SubharmonicStart,
    WfemBarSeeds,
)
from pydantic import Field, field_validator

from nsm_continuation.core.lattice import LatticeProblem, LatticeSeed
from nsm_continuation.core.preflight import STRICT, check_gap, one_or_many
from nsm_continuation.core.vocabulary import CanonicalNames, as_parameters

PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class WfemBarParameters(CanonicalNames):
    """YAML ``parameters`` of ``problem: wfem_bar``: ``cells`` is the paper's ``N``, ``gap`` its
    ``g0`` (contact at ``u(L) = gap``)."""


    model_config = STRICT
    #: Young's modulus ``E``
    E: PosFloat = 1.0
    #: density ``rho`` (wave speed ``c = sqrt(E / rho)``)
    rho: PosFloat = 1.0
    #: the bar's length ``L`` (clamped at ``x = 0``, contact at ``x = L``)
    L: PosFloat = 1.0
    #: the number of WFEM cells (the paper's ``N``)
    cells: Annotated[int, Field(ge=2, le=200_000)] = 200
    #: the gap ``g0``: contact at ``u(L) = gap``; > 0 open, 0 static grazing (vertical
    #: backbones), < 0 prestressed
    gap: Annotated[float, Field(allow_inf_nan=False)] = 1e-3
    #: filter: largest number of profile jumps kept, as a fraction of N (grid-scale orbits jump at
    #: O(N) places); persistence under N -> 2N is always checked
    max_jumps_fraction: Annotated[float, Field(gt=0, le=2)] = 0.25
    #: search half-width (in steps of m) around the predicted node
    corrector_window: Annotated[int, Field(ge=0, le=1000)] = 3
    #: largest gap in M (period steps) bridged between two lattice solutions of one branch,
    #: as a fraction of N
    max_gap_fraction: Annotated[float, Field(gt=0, le=1)] = 0.05

    @field_validator("gap")
    @classmethod
    def _gap_range(cls, v: float) -> float:
        return check_gap(v)


class WfemBarProblem(WfemBarPreflight, WfemBarSeeds, WfemLatticeNodes, LatticeProblem):
    """Elastic bar with a unilateral contact, WFEM on the (m, p) lattice (Yoong et al. 2017).
    Nonsmooth modes (module docstring): the starts and their seeds (:mod:`.wfem_starts`), the
    preflight (:mod:`.wfem_preflight`), the node store and the scan (:mod:`.wfem_nodes`) and
    the presentation (:mod:`.presentation`) are mixins; this class holds the model, the window
    and the predictor / corrector."""

    presentation_class = WfemBarPresentation
    #: the figures depend on the results and the parameters only
    figures_from_inputs: ClassVar[bool] = True

    name = "wfem_bar"
    Parameters = WfemBarParameters
    start_adapter = one_or_many(OneStart)
    energy_quantity: ClassVar[str | None] = "energy_ratio"
    #: a change of the number of grazing instants is a grazing event
    character_kinds: ClassVar[dict[str, str]] = {"grazing_instants": "grazing"}

    def __init__(self, params: WfemBarParameters | dict[str, Any]) -> None:
        params = as_parameters(WfemBarParameters, params)
        super().__init__(params)
        self.model = BarModel(params.E, params.rho, params.L, params.cells, params.gap)
        self.variables = ["omega_ratio", "contact_fraction"]
        self.parameter = "omega_ratio"
        self._init_nodes()
        #: the seeds of each start block and window (the preflight's search, reused by the run)
        self._seed_cache: dict[tuple[str, Any], list[LatticeSeed]] = {}
        #: what the report should say about the seeds (a scan cut at start.max_seeds)
        self._seed_notes: list[str] = []
        self._check_model()

    def _check_model(self) -> None:
        """The bar's scales are representable and the filter can keep an orbit at all."""
        md, p = self.model, self.params
        for name, v in (("omega_1 = pi c / (2L)", md.omega1), ("dt = L / (N c)", md.dt)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"parameters.E: E, rho and L give {name} = {v:.3g}, not a "
                                 "positive finite number: rescale them")
        if md.g0 != 0:
            check_reference_energy(md.E, md.L, md.g0)
            if abs(md.g0) > md.L:
                raise ValueError(
                    f"parameters.gap: |gap| = {abs(md.g0):g} exceeds the bar's length L = "
                    f"{md.L:g}: no orbit meets COND3 (strain |sigma| / E <= 1), since the end's "
                    "displacement g0 is the integral of the strain over the bar")
            need = ceil(2 / p.max_jumps_fraction - 1e-12)
            if md.N < need:
                raise ValueError(
                    f"parameters.cells: {md.N} cells are too few: every orbit of the bar with "
                    "g0 != 0 has at least 2 profile jumps and the filter keeps at most "
                    f"max_jumps_fraction x cells = {p.max_jumps_fraction * md.N:g} (need cells "
                    f">= {need})")

    def monitor_names(self) -> list[str]:
        """The derived values of a lattice point (:meth:`lattice_point`)."""
        return ["M", "m", "p", "k", "l", "omega", "omega_ratio", "period", "T", "energy",
                "energy_ratio", "contact_fraction", "h", "contact_phases", "grazing_instants",
                "profile_jumps"]

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
            ms = np.arange(max(1, m_c - width), min(M - 1, m_c + width) + 1)
            if len(last.counts) == 2:
                cands = self._physical_at_period(M, ms)
            else:  # two contact phases: keep the p = l symmetry (section 6.4), search p too
                cands = []
                p_c = int(round(pred[1])) if slopes is not None else last.counts[1]
                for m in ms.tolist():
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
        if len(last.counts) == 2 and self._strained(last, dM, W + jumps):
            return None, ("COND3: the next orbits strain the bar beyond |sigma| = E (the "
                          "small-strain model ends here; the strain grows with the energy and "
                          "the gap)")
        return None, (f"no physical admissible lattice orbit within {max_gap} period steps "
                      "of the prediction")

    def _strained(self, last: LatticeSolution, dM: int, width: int) -> bool:
        """Whether an orbit of the next three periods (``M + dM j``) near ``last`` fails COND3
        alone (where the branch's next orbits are: the search found none admissible)."""
        m0 = last.counts[0]
        for j in (1, 2, 3):
            M = last.M + dM * j
            for m in range(max(1, m0 - width * j), min(M - 1, m0 + width * j) + 1):
                if solve_node(self.model, (m, M - m))[0] == "inadmissible: cond3_strain":
                    return True
        return False

    @staticmethod
    def _energy_predict(history: list[LatticeSolution], M: int) -> float:
        """Extrapolate E^(-1/2) linearly in M (exact on the continuum branches, eq. in
        :mod:`problems.bar.continuum_orbits`: E ~ (T - T*)^-2)."""
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


__all__ = ["MainStart", "NodeStart", "ScanStart", "SubharmonicStart",
           "WfemBarParameters", "WfemBarProblem", "main_asymptote", "subharmonic_asymptote",
           "subharmonic_start"]
