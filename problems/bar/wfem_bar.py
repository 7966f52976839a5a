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

from dataclasses import replace
from math import ceil
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from nsm_continuation.problems.bar.presentation import BarFrequencyEnergy
from nsm_continuation.problems.bar.wfem_lattice import (
    BarModel,
    LatticeSolution,
    classify,
    grazing_representative,
    node_solutions,
    profile_jumps,
    scan_screen,
)
from nsm_continuation.problems.bar.wfem_operators import kernel_dimensions_at_period
from pydantic import BaseModel, Discriminator, Field, Tag, field_validator

from nsm_continuation.core.lattice import LatticeProblem, LatticeSeed
from nsm_continuation.core.preflight import (
    STRICT,
    as_list,
    check_budget,
    check_gap,
    exactly,
    one_or_many,
    start_key,
)
from nsm_continuation.core.vocabulary import CanonicalNames, as_parameters

PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class WfemBarParameters(CanonicalNames):
    """YAML ``parameters`` of ``problem: wfem_bar``: ``cells`` is the paper's ``N``, ``gap`` its
    ``g0`` (contact at ``u(L) = gap``)."""

    model_config = STRICT
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

    @field_validator("gap")
    @classmethod
    def _gap_range(cls, v: float) -> float:
        return check_gap(v)


class MainStart(BaseModel):
    """The main backbone of mode k (section 6.1)."""

    model_config = STRICT
    branch: Literal["main"]
    mode: Annotated[int, Field(ge=1, le=50)] = 1


class SubharmonicStart(BaseModel):
    """The n-th subharmonic backbone of mode k (g0 > 0), starting near eq. (15)."""

    model_config = STRICT
    branch: Literal["subharmonic"]
    mode: Annotated[int, Field(ge=1, le=50)] = 1
    n: Annotated[int, Field(ge=1, le=50)] = 1


class ScanStart(BaseModel):
    """Every physical admissible orbit in the window seeds a branch (Fig. 12, 16)."""

    model_config = STRICT
    scan: Annotated[Literal[True], exactly(True)]
    #: at most this many seeds (fewest profile jumps, then lowest energy); default every one
    max_seeds: Annotated[int, Field(ge=1)] | None = None


class NodeStart(BaseModel):
    """An explicit lattice node (m, p) or (m, p, k, l) (eq. 18)."""

    model_config = STRICT
    node: list[Annotated[int, Field(ge=1)]]
    direction: Literal["both", "increase", "decrease"] = "both"


def _start_kind(v: Any) -> str:
    """Which start model a mapping is (by its ``branch`` / ``scan`` / ``node`` key), so an error
    names the key of that model only; capitalised tags are left out of error locations."""
    if isinstance(v, dict):
        if "node" in v:
            return "Node"
        if "scan" in v:
            return "Scan"
        return "Subharmonic" if v.get("branch") == "subharmonic" else "Main"
    return {SubharmonicStart: "Subharmonic", ScanStart: "Scan", NodeStart: "Node"}.get(
        type(v), "Main")


OneStart = Annotated[Annotated[MainStart, Tag("Main")]
                     | Annotated[SubharmonicStart, Tag("Subharmonic")]
                     | Annotated[ScanStart, Tag("Scan")] | Annotated[NodeStart, Tag("Node")],
                     Discriminator(_start_kind)]


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


class WfemBarProblem(BarFrequencyEnergy, LatticeProblem):
    name = "wfem_bar"
    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    Parameters = WfemBarParameters
    start_adapter = one_or_many(OneStart)
    #: a change of the number of grazing instants is a grazing event
    character_kinds: ClassVar[dict[str, str]] = {"grazing_instants": "grazing"}

    def __init__(self, params: WfemBarParameters | dict[str, Any]) -> None:
        params = as_parameters(WfemBarParameters, params)
        super().__init__(params)
        self.model = BarModel(params.E, params.rho, params.L, params.cells, params.gap)
        self.variables = ["omega_ratio", "contact_fraction"]
        self.parameter = "omega_ratio"
        self._cache: dict[tuple[int, ...], list[LatticeSolution]] = {}
        #: the filter's reasons for the orbits it removed at a node (replayed with the node)
        self._removed: dict[tuple[int, ...], list[str]] = {}
        #: the m of the scan's nodes (m, M - m) at each period M (those with 1 <= h <= 8)
        self._scan_nodes: dict[int, np.ndarray] = {}
        #: what a Dask task computed (nodes, periods scanned), in order: lattice_record
        self._record: tuple[dict[tuple[int, ...], None], dict[int, None]] | None = None
        self._record_solutions = True
        #: nodes solved on a worker whose orbits were not sent (a branch task's): counted in
        #: node_evaluations and filter_counts already, solved again here if ever needed
        self._solved_elsewhere: set[tuple[int, ...]] = set()
        #: periods a Dask task scanned (lattice_replay): the m (sorted) of their nodes that the
        #: task solved with nothing (most of a scan's: 4.7e6 at N = 1000), known solved here
        #: without being listed node by node, and the period's physical orbits in the order of
        #: m (what _scan_period returns)
        self._scanned_empty: dict[int, np.ndarray] = {}
        self._period_orbits: dict[int, list[LatticeSolution]] = {}
        #: periods with a one-phase node in the cache or solved elsewhere (node by node)
        self._periods_touched: set[int] = set()
        self.filter_counts: dict[str, int] = {}
        self.node_evaluations = 0
        #: energy-ratio bound of the case (set by the runner; seeds above it are not used)
        self.energy_cap = None
        self._seed_cache: dict[tuple[str, Any], list[LatticeSeed]] = {}
        #: what the report should say about the seeds (a scan cut at start.max_seeds)
        self._seed_notes: list[str] = []
        self._check_model()

    # -- preflight (issue 9): everything checkable before the lattice is explored -----------------
    #: peak bytes per period step M of one lattice node: the sign combinations of a kernel with
    #: h <= 12 cycles (2^11 of them, :func:`problems.bar.wfem_lattice.node_solutions`) times the
    #: end series (M values each) and their partial sums
    NODE_BYTES_PER_STEP: ClassVar[float] = 8.0 * (2.5 * 2**11 + 30)
    #: bytes per scanned node kept by the master (the node cache, solved or screened out: the
    #: N = 1000 scan of Fig. 12, 4.7e6 nodes, peaked at 1.4 GB)
    SCAN_BYTES_PER_NODE: ClassVar[float] = 300.0
    #: seconds per lattice node tried by the corrector (filter included): 0.7 ms + 3 us per
    #: cell (measured: 23 ms per point at N = 1000, 80 ms at 4000, 320 ms at 16000; 7 nodes
    #: per point with corrector_window = 3)
    NODE_SECONDS: ClassVar[tuple[float, float]] = (7e-4, 3e-6)
    #: seconds of the seed search of one backbone, per cells^2 (16 s at N = 16000; for g0 = 0
    #: a linear programme per node tried: 1.4 s at N = 1000, 19 s at N = 4000)
    SEED_SECONDS_PER_N2: ClassVar[tuple[float, float]] = (6e-8, 1.5e-6)
    #: seconds per scanned node and cell of the batch screen
    #: (:func:`problems.bar.wfem_lattice.scan_screen`), per node it keeps (solved: 0.3 ms +
    #: 0.1 us per cell, for the 15 % it keeps at most: 12 % measured at N = 400, 2-3 % at
    #: N = 1000), and per scanned node for the branches of its seeds (at most one point,
    #: ~5 ms, per physical orbit: 2.3e-3 of the nodes at N = 200): the N = 1000 scan of
    #: Fig. 12 measured 5.0e-5 s per node in all (237 s for 4.7e6 nodes)
    SCAN_SECONDS: ClassVar[tuple[float, float, float]] = (5e-8, 0.15 * 3e-4, 2.5e-3 * 5e-3)
    #: the seed search itself runs in the preflight up to this many cells (~0.1 s per start at
    #: N = 1000, 0.3 s at N = 4000; for g0 = 0, 1.4 s at N = 1000); beyond it only its
    #: necessary conditions are checked. Its seeds are kept for the run.
    PREFLIGHT_SEED_CELLS: ClassVar[tuple[int, int]] = (4000, 1000)

    def _check_model(self) -> None:
        """The bar's scales are representable and the filter can keep an orbit at all."""
        md, p = self.model, self.params
        for name, v in (("omega_1 = pi c / (2L)", md.omega1), ("dt = L / (N c)", md.dt)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"parameters.E: E, rho and L give {name} = {v:.3g}, not a "
                                 "positive finite number: rescale them")
        if md.g0 != 0:
            if not 1e-200 <= md.energy_ref <= 1e200:
                raise ValueError(
                    f"parameters.gap: the reference energy pi^2 E g0^2 / (16 L) = "
                    f"{md.energy_ref:.3g} (eq. 14) is outside [1e-200, 1e200], where double "
                    "precision resolves the energies: rescale E, L or the gap")
            need = ceil(2 / p.max_jumps_fraction - 1e-12)
            if md.N < need:
                raise ValueError(
                    f"parameters.cells: {md.N} cells are too few: every orbit of the bar with "
                    "g0 != 0 has at least 2 profile jumps and the filter keeps at most "
                    f"max_jumps_fraction x cells = {p.max_jumps_fraction * md.N:g} (need cells "
                    f">= {need})")

    def _start_ratio(self, spec: BaseModel) -> float | None:
        """omega / omega_1 where a start's seed search begins (None for a scan)."""
        md = self.model
        if isinstance(spec, NodeStart):
            return 4 * md.N / sum(spec.node)
        if isinstance(spec, SubharmonicStart):
            return subharmonic_start(spec.mode, spec.n)
        if isinstance(spec, MainStart):
            k = spec.mode
            return (main_asymptote(k) if md.g0 == 0 else 2 * k - 1 if md.g0 > 0 else 2 * k)
        return None

    @staticmethod
    def _jumps(spec: BaseModel) -> int:
        """Profile jumps of a backbone's orbits (bar_continuum: a = 2k(n + 1)); 2 otherwise."""
        if isinstance(spec, SubharmonicStart):
            return 2 * spec.mode * (spec.n + 1)
        if isinstance(spec, MainStart):
            return 2 * spec.mode
        return 2

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Everything checkable before the lattice is explored (``window``: omega_ratio):

        * each start: a node has 2 or 4 entries (eq. 12 / 18) and its frequency 4N/M lies in
          the window; a subharmonic needs gap > 0 (eq. 15); the filter can keep the start's
          orbits (a backbone of mode k, subharmonic n, has 2k(n + 1) profile jumps: needs
          ``cells >= 2k(n + 1) / max_jumps_fraction``); a backbone's start frequency (omega_k,
          Omega_k, eq. 15, the g0 = 0 asymptote) lies in the window;
        * memory: one lattice node (``NODE_BYTES_PER_STEP`` x the largest period M the run can
          reach: 4N / continuation.min, else 8N + 2 max_points), the scan's sweep
          (``SCAN_BYTES_PER_STEP_CELL x M x N``) and the solutions kept along the branches of
          explicit starts ((2N + M) doubles per point); time: the scan (a sweep O(M N) per
          period, then the nodes) and ``2 max_points`` (at most one point per period of the
          window) x ``(2 corrector_window + 1)^phases`` nodes per point per branch;
        * then, up to ``PREFLIGHT_SEED_CELLS`` cells, the seed search of every non-scan start
          itself (cached: the run reuses it), so a backbone without a physical orbit near its
          start is refused here, not after the run started.
        """
        items = as_list(self.start_adapter.validate_python(start))
        M_lo, M_seed = self._check_starts(items, window)
        self._check_start_budget(items, window, max_points, M_lo, M_seed)
        if self.model.N <= self.PREFLIGHT_SEED_CELLS[self.model.g0 == 0]:
            self._check_seeds(items, window)

    #: periods (in steps) beyond any budget: keeps the budget arithmetic finite
    PERIOD_CAP: ClassVar[float] = 1e15

    def _check_starts(self, items: list[tuple[int | None, Any]],
                      window: tuple[float | None, float | None]) -> tuple[float, int]:
        """Each start alone (node entries, subharmonic gap, the filter, the window); returns
        the shortest period ``M_lo`` the window allows and the longest start period
        ``M_seed`` (in steps)."""
        md, p = self.model, self.params
        N = md.N
        lo, hi = window
        cap = self.PERIOD_CAP
        M_lo = max(2.0, min(np.ceil(4 * N / hi), cap)) if hi else 2.0
        M_seed = 8 * N
        for i, s in items:
            key = start_key(i)
            if isinstance(s, NodeStart):
                if len(s.node) not in (2, 4):
                    raise ValueError(
                        f"{start_key(i, 'node')}: {s.node} has {len(s.node)} entries; a lattice "
                        "node is [m, p] (free and contact steps, eq. 12) or [m, p, k, l] (two "
                        "contact phases, eq. 18)")
                M_seed = max(M_seed, sum(s.node))
                key = start_key(i, "node")
            if isinstance(s, SubharmonicStart) and md.g0 <= 0:
                raise ValueError(f"{start_key(i, 'branch')}: subharmonic starts are defined for "
                                 f"gap > 0 (eq. 15); gap = {md.g0:g}")
            if isinstance(s, MainStart | SubharmonicStart) and md.g0 != 0:
                jumps = self._jumps(s)
                need = ceil(jumps / p.max_jumps_fraction - 1e-12)
                if N < need:
                    raise ValueError(
                        f"parameters.cells: {N} cells are too few for {key} ({s.branch} "
                        f"backbone of mode {s.mode}): its orbits have {jumps} profile jumps and "
                        f"the filter keeps at most max_jumps_fraction x cells = "
                        f"{p.max_jumps_fraction * N:g} (need cells >= {need})")
            r = self._start_ratio(s)
            if r is not None and ((lo is not None and r < lo - 1e-12)
                                  or (hi is not None and r > hi + 1e-12)):
                what = (f"node {s.node} (M = {sum(s.node)} steps)" if isinstance(s, NodeStart)
                        else f"the {s.branch} backbone of mode {s.mode}")
                raise ValueError(
                    f"{key}: {what} starts at omega/omega_1 = {r:.6g}, outside the window "
                    f"[{lo if lo is not None else 0:g}, {hi if hi is not None else np.inf:g}] "
                    "(continuation.min/max): a branch starting there computes nothing")
        return M_lo, M_seed

    def _check_start_budget(self, items: list[tuple[int | None, Any]],
                            window: tuple[float | None, float | None], max_points: int,
                            M_lo: float, M_seed: int) -> None:
        """Memory and time of the run (see :meth:`preflight`) against the limits."""
        md, p = self.model, self.params
        N = md.N
        lo, _ = window
        cap = self.PERIOD_CAP
        M_hi = min(np.floor(4 * N / lo), cap) if lo else float(M_seed + 2 * max_points)
        M_hi = max(M_hi, M_lo)
        periods = int(M_hi - M_lo + 1)
        scans = [s for _, s in items if isinstance(s, ScanStart)]
        explicit = [s for _, s in items if not isinstance(s, ScanStart)]
        per_branch = min(2 * max_points, periods)
        t_node = self.NODE_SECONDS[0] + self.NODE_SECONDS[1] * N

        def nodes_per_point(s: BaseModel) -> int:
            phases = 2 if isinstance(s, NodeStart) and len(s.node) == 4 else 1
            return (2 * p.corrector_window + 1) ** phases

        memory = self.NODE_BYTES_PER_STEP * M_hi
        memory += 8.0 * len(explicit) * per_branch * (2 * N + M_hi)
        seconds = sum(per_branch * nodes_per_point(s) * t_node for s in explicit)
        seconds += len([s for s in explicit if not isinstance(s, NodeStart)]) * \
            self.SEED_SECONDS_PER_N2[md.g0 == 0] * N**2
        if scans:
            # the nodes of the periods (sum of M), ~60 % of them with 1 <= h <= 8, scanned
            nodes = 0.6 * 0.5 * (float(M_hi) ** 2 - float(M_lo) ** 2)
            memory += self.SCAN_BYTES_PER_NODE * nodes
            screen, solve, branches = self.SCAN_SECONDS
            seconds += nodes * (screen * N + solve * (1.0 + 3e-4 * N) + branches)
        big_nodes = [i for i, s in items if isinstance(s, NodeStart) and sum(s.node) > 8 * N]
        check_budget(start_key(big_nodes[0], "node") if big_nodes and not lo else
                     "parameters.cells",
                     f"{N} cells with periods up to M = {M_hi:.0f} steps and "
                     f"continuation.max_points = {max_points} ({len(items)} "
                     f"start{'s' if len(items) != 1 else ''}"
                     f"{', a scan of the window' if scans else ''})",
                     memory_bytes=memory, seconds=seconds)

    def _check_seeds(self, items: list[tuple[int | None, Any]],
                     window: tuple[float | None, float | None]) -> None:
        """The seed search of every non-scan start (cached: the run reuses it)."""
        N = self.model.N
        lo, hi = window
        for i, s in items:
            if isinstance(s, ScanStart):
                continue
            try:
                seeds = self.lattice_seeds(s, window)
            except ValueError as exc:
                key = start_key(i, "node") if isinstance(s, NodeStart) else "parameters.cells"
                raise ValueError(f"{key}: {exc}") from None
            for seed in seeds:
                r = 4 * N / seed.solution.M
                if (lo is not None and r < lo - 1e-12) or (hi is not None and r > hi + 1e-12):
                    raise ValueError(
                        f"{start_key(i)}: the first physical orbit of this start, "
                        f"{seed.label} at (m, p) = {seed.solution.counts}, has omega/omega_1 = "
                        f"{r:.6g}, outside the window (continuation.min/max)")

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

    # -- solutions at a node (cached), with the filter ---------------------------------------
    def physical(self, counts: tuple[int, ...], screened_out: bool = False
                 ) -> list[LatticeSolution]:
        """The physical orbits at a node (cached, counted once). ``screened_out``: the node is
        known to carry no admissible candidate (:func:`problems.bar.wfem_lattice.scan_screen`),
        so it is counted and cached as solved with nothing, as :func:`node_solutions` would
        leave it, without solving it."""
        counts = tuple(int(c) for c in counts)
        if self._record is not None:
            self._record[0][counts] = None
        if counts in self._cache:
            return self._cache[counts]
        if self._scanned_empty and self._known_empty(counts):
            self._cache[counts] = []  # solved with nothing by a task: counted then
            return self._cache[counts]
        if len(counts) == 2:
            self._periods_touched.add(counts[0] + counts[1])
        counted = counts in self._solved_elsewhere
        if not counted:
            self.node_evaluations += 1
        sols = [] if screened_out else node_solutions(self.model, counts)[1]
        keep = []
        removed = []
        max_jumps = self.params.max_jumps_fraction * self.model.N
        for s in sols:
            reason = classify(s)
            if reason == "physical" and profile_jumps(s.w0) > max_jumps:
                reason = "grid-scale (profile jumps > max_jumps_fraction * N)"
            if reason == "physical":
                keep.append(s)
            else:
                if not counted:
                    self.filter_counts[reason] = self.filter_counts.get(reason, 0) + 1
                removed.append(reason)
        self._cache[counts] = keep
        if removed:
            self._removed[counts] = removed
        return keep

    def _known_empty(self, counts: tuple[int, ...]) -> bool:
        """A one-phase node of a period a task scanned, solved there with nothing."""
        if len(counts) != 2:
            return False
        ms = self._scanned_empty.get(counts[0] + counts[1])
        if ms is None:
            return False
        i = int(np.searchsorted(ms, counts[0]))
        return i < ms.size and int(ms[i]) == counts[0]

    def _scan_periods(self, window: tuple[float | None, float | None]) -> tuple[int, int]:
        """First and last period (in steps) of the scan of the window."""
        lo, hi = window
        N = self.model.N
        M_hi = int(np.floor(4 * N / lo)) if lo else 8 * N
        M_lo = int(np.ceil(4 * N / hi)) if hi else 2
        return max(M_lo, 2), M_hi

    def _scan_period(self, M: int) -> list[LatticeSolution]:
        """The physical orbits of the scan's nodes at period M."""
        if self._record is not None:
            self._record[1][M] = None
        elif M in self._period_orbits:  # scanned by a task (lattice_replay)
            return list(self._period_orbits[M])
        ms = self._scan_nodes.get(M)
        if ms is None:
            h = kernel_dimensions_at_period(self.model.N, M)
            ms = self._scan_nodes[M] = (np.nonzero((h >= 1) & (h <= 8))[0] + 1).astype(np.int32)
        return self._physical_at_period(M, ms)

    def _physical_at_period(self, M: int, ms: np.ndarray) -> list[LatticeSolution]:
        """The physical orbits of the nodes ``(m, M - m)``, ``m`` in ``ms``, in that order.

        A node with an empty kernel (``h = 0`` in closed form,
        :func:`problems.bar.wfem_operators.kernel_dimensions_at_period`: half the nodes of a
        period where ``gcd(M, 2N) = 1``) has no orbit. At g0 != 0 most others fail COND2 on
        every candidate: they are screened in one batch
        (:func:`problems.bar.wfem_lattice.scan_screen`; at g0 = 0 a candidate's coefficients
        may vanish and the screen does not apply). Nodes already solved (adopted from Dask
        tasks, or by an earlier scan) are neither screened nor solved again."""
        nodes = ms.tolist()
        empty = self._scanned_empty.get(M)
        if empty is not None and empty.size:  # solved with nothing by a task (lattice_replay)
            at = np.minimum(np.searchsorted(empty, ms), empty.size - 1)
            for m in ms[empty[at] == ms].tolist():
                self._cache.setdefault((m, M - m), [])
        new = np.array([(m, M - m) not in self._cache for m in nodes], dtype=bool)
        may = np.ones(len(nodes), dtype=bool)
        if new.any():
            may[new] = kernel_dimensions_at_period(self.model.N, M)[ms[new] - 1] > 0
            test = np.nonzero(new & may)[0]
            if self.model.g0 != 0 and test.size:
                may[test] = scan_screen(self.model.N, M, ms[test])
        out = []
        for m, keep in zip(nodes, may.tolist(), strict=True):
            out += self.physical((m, M - m), screened_out=not keep)
        return out

    def scan_window(self, window: tuple[float | None, float | None]) -> list[LatticeSolution]:
        """All physical one-contact-phase orbits with omega_ratio in the window.

        The kernel dimension of every node of a period comes from one vectorised sweep
        (:func:`problems.bar.wfem_operators.kernel_dimensions_at_period`); only nodes with
        ``1 <= h <= 8`` are solved.
        """
        M_lo, M_hi = self._scan_periods(window)
        out = []
        for M in range(M_lo, M_hi + 1):
            out += self._scan_period(M)
        return out

    # -- on a Dask cluster (nsm_continuation.runs.execution, LatticeProblem's protocol) --
    def lattice_seed_pieces(self, start: Any, window: tuple[float | None, float | None],
                            count: int) -> list[Any]:
        """A scan (the only costly seed search) by contiguous ranges of periods ``(M_a, M_b)``
        of about equal cost (the nodes of a period grow like M)."""
        spec = self.start_adapter.validate_python(start) if not isinstance(
            start, BaseModel) else start
        if not any(isinstance(s, ScanStart) for _, s in as_list(spec)):
            return []
        M_lo, M_hi = self._scan_periods(window)
        if M_hi < M_lo:
            return []
        cost = np.cumsum(np.arange(M_lo, M_hi + 1, dtype=float))  # nodes per period ~ M
        cuts = np.searchsorted(cost, cost[-1] * np.arange(1, count) / count, side="right")
        bounds = [M_lo, *sorted({int(M_lo + c) for c in cuts if 0 < c < len(cost)}), M_hi + 1]
        return [(a, b - 1) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]

    def lattice_seed_piece(self, start: Any, window: tuple[float | None, float | None],
                           piece: Any) -> None:
        for M in range(int(piece[0]), int(piece[1]) + 1):
            self._scan_period(M)

    def lattice_distribute_branches(self, start: Any) -> bool:
        """Backbones and nodes: one task per branch; a scan's seeds: here, in order."""
        spec = self.start_adapter.validate_python(start) if not isinstance(
            start, BaseModel) else start
        return not any(isinstance(s, ScanStart) for _, s in as_list(spec))

    def lattice_record(self, solutions: bool = True) -> None:
        self._record = ({}, {})
        self._record_solutions = solutions

    def lattice_recorded(self) -> Any:
        """The nodes touched since :meth:`lattice_record` (solved here or found in the
        cache), in order of first touch, and the periods scanned with their nodes. A node with
        filter reasons or (``solutions``) physical orbits comes with them; the others are
        listed by their counts only, except (``solutions``) the nodes of a scanned period
        (every one was touched): those are implied by the period (most of a scan's nodes: the
        master neither receives nor stores them one by one, :meth:`lattice_replay`)."""
        if self._record is None:
            return None
        nodes, periods = self._record
        self._record = None
        sols = self._record_solutions
        scanned = {M: set(self._scan_nodes[M].tolist()) for M in periods} if sols else {}
        detailed, plain = [], []
        for c in nodes:
            removed = self._removed.get(c, ())
            keep = self._cache[c] if sols else None
            if removed or keep:
                detailed.append((c, keep, removed))
            elif not (len(c) == 2 and c[0] in scanned.get(c[0] + c[1], ())):
                plain.append(c)
        return sols, detailed, plain, [(M, self._scan_nodes[M]) for M in periods]

    def lattice_replay(self, record: Any) -> None:
        """The nodes of a record not solved here yet count as solved here (the counters of
        ``report_extras``; those with filter reasons in the record's order, as the serial run
        solves them); their orbits, if sent, are cached.

        The nodes a scanned period implies (:meth:`lattice_recorded`) are kept as the sorted
        ``m`` of the period's nodes solved with nothing (:meth:`physical` finds them there)
        and the period's physical orbits as :meth:`_scan_period` returns them; a period of
        which this process already knows a node (rare: a seed's own search) is adopted node
        by node instead, so that nothing is counted twice."""
        if record is None:
            return
        sols, detailed, plain, periods = record
        cache, elsewhere = self._cache, self._solved_elsewhere
        whole = {M for M, _ in periods if M not in self._periods_touched
                 and M not in self._scanned_empty} if sols else set()
        plain = list(plain)
        for counts, keep, removed in detailed:
            if counts in cache or counts in elsewhere or self._known_empty(counts):
                continue
            self.node_evaluations += 1
            for reason in removed:
                self.filter_counts[reason] = self.filter_counts.get(reason, 0) + 1
            if removed:
                self._removed[counts] = list(removed)
            if len(counts) == 2:
                self._periods_touched.add(counts[0] + counts[1])
            if keep is None:
                self._solved_elsewhere.add(counts)
            else:
                self._cache[counts] = [replace(s, model=self.model) for s in keep]
        if sols:
            at_period: dict[int, list[int]] = {}
            for counts, _, _ in detailed:
                if len(counts) == 2:
                    at_period.setdefault(counts[0] + counts[1], []).append(counts[0])
            for M, ms in periods:
                detailed_ms = at_period.get(M, [])
                empty = np.setdiff1d(ms, detailed_ms).astype(np.int32)  # sorted
                if M not in whole:
                    plain += [(m, M - m) for m in empty.tolist()]
                    continue
                self._scanned_empty[M] = empty
                self.node_evaluations += int(empty.size)
                in_scan = set(ms.tolist())
                self._period_orbits[M] = [s for m in sorted(detailed_ms) if m in in_scan
                                          for s in self._cache[(m, M - m)]]
        new = [c for c in plain if c not in cache and c not in elsewhere
               and not self._known_empty(c)]
        self.node_evaluations += len(new)
        if sols:
            self._cache.update((c, []) for c in new)
        else:
            self._solved_elsewhere.update(new)
        for c in new:
            if len(c) == 2:
                self._periods_touched.add(c[0] + c[1])
        for M, ms in periods:
            self._scan_nodes.setdefault(M, ms)

    # -- seeds ---------------------------------------------------------------------------------
    def lattice_seeds(self, start: Any, window: tuple[float | None, float | None]
                      ) -> list[LatticeSeed]:
        spec = self.start_adapter.validate_python(start) if not isinstance(
            start, BaseModel) else start
        if isinstance(spec, list):
            return [seed for one in spec for seed in self.lattice_seeds(one, window)]
        if isinstance(spec, ScanStart):  # depends on energy_cap: never cached
            return self._lattice_seeds(spec, window)
        key = (spec.model_dump_json(), window)
        if key not in self._seed_cache:  # the preflight's seed search is reused by the run
            self._seed_cache[key] = self._lattice_seeds(spec, window)
        return list(self._seed_cache[key])

    def _lattice_seeds(self, spec: BaseModel, window: tuple[float | None, float | None]
                       ) -> list[LatticeSeed]:
        md = self.model
        if isinstance(spec, NodeStart):
            if len(spec.node) not in (2, 4):
                raise ValueError(f"start.node: {spec.node} has {len(spec.node)} entries; a "
                                 "lattice node is [m, p] (eq. 12) or [m, p, k, l] (eq. 18)")
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
            if spec.max_seeds is not None and len(sols) > spec.max_seeds:
                note = (f"start.scan: {len(sols)} physical orbits in the window (below "
                        f"continuation.max_energy), only the first "
                        f"max_seeds = {spec.max_seeds} (fewest profile jumps, then lowest "
                        "energy) seed branches; a branch none of them lies on is not computed "
                        "(raise start.max_seeds: a seed on a branch already computed costs "
                        "one lookup)")
                if note not in self._seed_notes:
                    self._seed_notes.append(note)
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
        return None, (f"no physical admissible lattice orbit within {max_gap} period steps "
                      "of the prediction")

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

    # -- report and plots -------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        md = self.model
        return {"c": md.c, "dt": md.dt, "omega_1": md.omega1, "E_ref": md.energy_ref,
                "cells": md.N, "gap": md.g0}

    def warnings(self) -> list[str]:
        return list(self._seed_notes)

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

    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """omega_k (fixed-free), Omega_k (fixed-fixed) and the g0 = 0 asymptotes."""
        lo, hi = x_range
        for k in range(1, 20):
            for x, ls, col in ((2 * k - 1, ":", "tab:blue"), (2 * k, ":", "tab:orange"),
                               (main_asymptote(k), "--", "0.5")):
                if lo - 0.05 <= x <= hi + 0.05:
                    ax.axvline(x, ls=ls, color=col, lw=0.8, zorder=1)

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Space-time fields (Fig. 8a, 10a, 13, 17), contact-end series, manifold (Fig. 9)."""
        from nsm_continuation.problems.bar import plots

        return plots.extra_plots(out_dir, branches, self)

    def legend_handles(self) -> list[Any]:
        from matplotlib.lines import Line2D
        return [Line2D([], [], ls=":", color="tab:blue", label=r"$\omega_k$ (fixed-free)"),
                Line2D([], [], ls=":", color="tab:orange", label=r"$\Omega_k$ (fixed-fixed)"),
                Line2D([], [], ls="--", color="0.5", label=r"$g_0=0$ asymptote (sec. 6.1)")]
