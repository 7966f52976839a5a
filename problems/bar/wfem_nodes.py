"""The lattice nodes of ``wfem_bar``: their physical orbits, cached, and the scan of a window.

At a node ``(m, p)`` (or ``(m, p, k, l)``, eq. 18) the orbits of eq. (12) with COND1-COND3
(:func:`problems.bar.wfem_lattice.node_solutions`) pass the filter of
:func:`problems.bar.wfem_lattice.classify` (plus the bound on profile jumps) or are counted with
the filter's reason. A scan of the window solves every node of every period with a kernel
(``1 <= h <= 8``), after a batch screen of COND2 (:func:`problems.bar.wfem_lattice.scan_screen`).
On a Dask cluster the scan is cut into ranges of periods and the nodes a task solved are
recorded and replayed on the master (:mod:`nsm_continuation.runs.execution`), so that the
counters of the report are those of the serial run.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from nsm_continuation.problems.bar.wfem_lattice import (
    LatticeSolution,
    classify,
    node_solutions,
    profile_jumps,
    scan_screen,
)
from nsm_continuation.problems.bar.wfem_operators import kernel_dimensions_at_period
from nsm_continuation.problems.bar.wfem_starts import ScanStart
from pydantic import BaseModel

from nsm_continuation.core.preflight import as_list


class WfemLatticeNodes:
    """The node store of :class:`problems.bar.wfem_bar.WfemBarProblem` (a mixin placed before
    :class:`~nsm_continuation.core.lattice.LatticeProblem` in its bases: it implements the
    protocol's Dask hooks)."""

    def _init_nodes(self) -> None:
        """The empty store (no node solved, nothing recorded)."""
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


__all__ = ["WfemLatticeNodes"]
