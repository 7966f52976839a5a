"""The preflight of ``wfem_bar``: everything checkable before the lattice is explored.

Each start alone (a lattice node's entries, eq. 12 / 18; a subharmonic needs g0 > 0, eq. 15; the
filter can keep a backbone's orbits; the start frequency lies in the window), the memory and
time of the run against the limits (from measured costs per lattice node, per scanned node and
per seed search), then the seed search itself on meshes where it is cheap (its seeds are kept
for the run).
"""

from __future__ import annotations

from math import ceil
from typing import Any, ClassVar

import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import main_asymptote, subharmonic_start
from nsm_continuation.problems.bar.wfem_starts import (
    MainStart,
    NodeStart,
    ScanStart,
    SubharmonicStart,
)
from pydantic import BaseModel

from nsm_continuation.core.preflight import as_list, check_budget, start_key


class WfemBarPreflight:
    """The preflight of :class:`problems.bar.wfem_bar.WfemBarProblem` (a mixin placed before
    :class:`~nsm_continuation.core.lattice.LatticeProblem` in its bases) and the costs it
    estimates the run with."""

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
                if str(exc).startswith("parameters."):  # the search named its cause
                    raise
                key = start_key(i, "node") if isinstance(s, NodeStart) else "parameters.cells"
                raise ValueError(f"{key}: {exc}") from None
            for seed in seeds:
                r = 4 * N / seed.solution.M
                if (lo is not None and r < lo - 1e-12) or (hi is not None and r > hi + 1e-12):
                    raise ValueError(
                        f"{start_key(i)}: the first physical orbit of this start, "
                        f"{seed.label} at (m, p) = {seed.solution.counts}, has omega/omega_1 = "
                        f"{r:.6g}, outside the window (continuation.min/max)")


__all__ = ["WfemBarPreflight"]
