"""The bar's lattice scan at less than O(N^3): the kernel dimensions of a period in closed
form, the batch COND2 screen and the per-cycle sign test of ``h > q`` nodes, each against the
per-node computation."""

from __future__ import annotations

import nsm_continuation.problems.bar.wfem_lattice as wfem_lattice
import nsm_continuation.problems.bar.wfem_nodes as wfem_nodes
import numpy as np
import pytest
from nsm_continuation.problems.bar.wfem_bar import WfemBarProblem
from nsm_continuation.problems.bar.wfem_lattice import BarModel, node_solutions, scan_screen
from nsm_continuation.problems.bar.wfem_operators import (
    kernel_dimensions_at_period,
    kernel_dimensions_by_sweep,
    pattern_from_counts,
    phase_operator,
)


@pytest.mark.parametrize("N", [3, 4, 7, 12, 30])
def test_kernel_dimensions_closed_form(N: int) -> None:
    for M in range(2, 9 * N):  # every shift, several laps, multiples of 2N included
        h = kernel_dimensions_at_period(N, M)
        assert np.array_equal(h, kernel_dimensions_by_sweep(N, M)), (N, M)
    for M, m in ((5 * N + 1, 3), (4 * N, N), (2 * N, 1), (6 * N - 1, 2 * N + 1)):
        op = phase_operator(N, pattern_from_counts(m, M - m))
        assert kernel_dimensions_at_period(N, M)[m - 1] == op.kernel_dimension()


def scan_nodes(N: int, M: int) -> np.ndarray:
    h = kernel_dimensions_at_period(N, M)
    return np.nonzero((h >= 1) & (h <= 8))[0] + 1


@pytest.mark.parametrize("g0", [1e-3, -1e-3])
def test_screened_nodes_have_no_admissible_candidate(g0: float) -> None:
    """A node the screen rejects has no solution (by the full per-node solve), and the screen
    rejects most nodes (it is not vacuous)."""
    total = rejected = 0
    for N in (5, 8, 13, 24):
        md = BarModel(1.0, 1.0, 1.0, N, g0)
        for M in range(N, 5 * N):
            ms = scan_nodes(N, M)
            keep = scan_screen(N, M, ms, chunk=7)  # several chunks
            total += ms.size
            for m in ms[~keep].tolist():
                rejected += 1
                assert not node_solutions(md, (m, M - m))[1], (N, M, m)
    assert rejected > 0.5 * total


def test_screen_keeps_every_node_with_an_orbit() -> None:
    """Every node with an admissible candidate passes (these carry the scan's orbits)."""
    kept = 0
    for N in (6, 10, 21):
        md = BarModel(1.0, 1.0, 1.0, N, 1e-3)
        for M in range(N, 4 * N + 1):
            ms = scan_nodes(N, M)
            may = scan_screen(N, M, ms)
            for m, ok in zip(ms.tolist(), may.tolist(), strict=True):
                if node_solutions(md, (m, M - m))[1]:
                    kept += 1
                    assert ok, (N, M, m)
    assert kept > 20


def _scan(N: int, monkeypatch: pytest.MonkeyPatch, screen: bool
          ) -> tuple[WfemBarProblem, list]:
    with monkeypatch.context() as mp:
        if not screen:
            mp.setattr(wfem_nodes, "scan_screen",
                       lambda N, M, ms: np.ones(np.asarray(ms).size, dtype=bool))
        pb = WfemBarProblem({"E": 1.0, "rho": 1.0, "L": 1.0, "cells": N, "gap": 1e-3})
        return pb, pb.scan_window((1.0, 4.0))


def test_scan_with_screen_equals_scan_without(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Fig. 12 scan (window [omega_1, Omega_2]) at N = 60: the same orbits in the same
    order, the same counters and filter reasons, node for node."""
    (fast, found_fast), (slow, found_slow) = (_scan(60, monkeypatch, True),
                                              _scan(60, monkeypatch, False))
    assert len(found_fast) == len(found_slow) > 0
    for a, b in zip(found_fast, found_slow, strict=True):
        assert a.counts == b.counts and np.array_equal(a.w0, b.w0) and a.energy == b.energy
    assert fast.node_evaluations == slow.node_evaluations
    assert fast.filter_counts == slow.filter_counts and fast._removed == slow._removed
    assert list(fast._cache) == list(slow._cache)  # the same nodes solved, in order
    for key, sols in fast._cache.items():
        assert [s.counts for s in sols] == [s.counts for s in slow._cache[key]]


def test_per_cycle_sign_test_changes_no_enumeration(monkeypatch: pytest.MonkeyPatch) -> None:
    """``h > q`` nodes: stopping at a cycle whose contact steps carry both signs gives what
    enumerating every sign combination gives."""
    checked = 0
    for N in (6, 9, 16):
        md = BarModel(1.0, 1.0, 1.0, N, 1e-3)
        for M in range(N, 4 * N + 1):
            h = kernel_dimensions_at_period(N, M)
            for m in (np.nonzero((h > 1) & (h <= 8))[0] + 1).tolist():
                fast = node_solutions(md, (m, M - m))
                with monkeypatch.context() as mp:
                    mp.setattr(wfem_lattice, "contact_sign_conflict", lambda Js: False)
                    slow = node_solutions(md, (m, M - m))
                assert fast[0] == slow[0] and len(fast[1]) == len(slow[1])
                for a, b in zip(fast[1], slow[1], strict=True):
                    assert np.array_equal(a.w0, b.w0)
                checked += 1
    assert checked > 100


def test_every_physical_orbit_seeds_a_branch_unless_cut_with_a_warning() -> None:
    """``start: {scan: true}`` seeds a branch at every physical orbit below the energy bound
    (the docstring's promise; a default cut at 200 hid Fig. 12's subharmonics n = 2-4); a
    ``max_seeds`` that cuts keeps the first ones and says so in the report's warnings."""
    def seeds(max_seeds: int | None) -> tuple[list, list[str]]:
        pb = WfemBarProblem({"E": 1.0, "rho": 1.0, "L": 1.0, "cells": 40, "gap": 1e-3})
        spec = {"scan": True} if max_seeds is None else {"scan": True, "max_seeds": max_seeds}
        return pb.lattice_seeds(spec, (1.0, 4.0), 1e3), pb.presentation.warnings()

    every, quiet = seeds(None)
    # the independent count: the scan's physical orbits below the energy bound
    pb = WfemBarProblem({"E": 1.0, "rho": 1.0, "L": 1.0, "cells": 40, "gap": 1e-3})
    below = [s for s in pb.scan_window((1.0, 4.0))
             if s.energy / pb.model.energy_ref <= 1e3]
    assert len(every) == len(below) > 5 and quiet == []
    cut, said = seeds(3)
    assert [s.solution.counts for s in cut] == [s.solution.counts for s in every[:3]]
    assert len(said) == 1 and f"{len(below)} physical orbits" in said[0]
    assert "max_seeds = 3" in said[0]
