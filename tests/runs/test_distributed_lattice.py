"""The lattice engine on Dask (nsm_continuation/runs/execution.py): the bar's scan (Fig. 12)
with its seed search in pieces, and the backbones of the bar with one task per branch, give the
outputs of a serial run, to the last digit: every branch and its CSV, the skipped seeds, and
the problem's counters in the report (``lattice_nodes_evaluated``, ``filter_removed``).

Oracle: the serial run of the same case. Small N (a scan of 30 cells: ~2 s serially).
"""

from __future__ import annotations

import csv
import io
import json
from importlib.util import find_spec
from typing import Any

import pytest
from helpers import CASES

import nsm_continuation as nsm
from nsm_continuation.core.lattice import LatticeProblem
from nsm_continuation.output.files import branch_rows, build_report
from nsm_continuation.runs.execution import merge_in_seed_order
from nsm_continuation.runs.setup import rebuild_case

FIG12 = CASES / "wfem_fig12_fep.yaml"
FIG13 = CASES / "wfem_fig13_subharmonics.yaml"
QUIET = {"output.plots": False, "output.progress": False}
needs_dask = pytest.mark.skipif(find_spec("distributed") is None,
                                reason="dask.distributed is not installed")


def outputs(res: Any) -> tuple[dict[str, Any], dict[int, str]]:
    """What a run writes, as written (report.json without its timings, one CSV per branch)."""
    rr = res.run_result
    report = json.loads(json.dumps(build_report(rr, "run"), default=str))
    report.pop("timings")
    report["case"]["input"].pop("execution")  # where it ran (recorded), not what it computed
    csvs = {}
    for br in rr.branches:
        cols, rows = branch_rows(br, rr.problem.variables, rr.problem.presentation.csv_head)
        fh = io.StringIO()
        writer = csv.writer(fh)
        writer.writerow(cols)
        writer.writerows(rows)
        csvs[br.id] = fh.getvalue()
    return report, csvs


def assert_same_outputs(a: Any, b: Any) -> None:
    ra, ca = outputs(a)
    rb, cb = outputs(b)
    assert [br["label"] for br in ra["branches"]] == [br["label"] for br in rb["branches"]]
    for key in ra:
        assert ra[key] == rb[key], key
    assert ca == cb
    assert a.run_result.skipped == b.run_result.skipped


def _replays(problem: Any) -> bool:
    """Whether the problem sends its node cache back from the workers (else the counters of
    its report may differ from a serial run's; the branches never do)."""
    return type(problem).lattice_replay is not LatticeProblem.lattice_replay


def test_merge_of_independent_branches_reproduces_the_serial_skips() -> None:
    """Every seed of a scan continued on its own (as tasks do, here in one process): merged in
    seed order, the seeds lying on an accepted branch are skipped and the branches, their ids
    and the problem's counters are the serial run's. Most of the scan's seeds are skipped."""
    case = nsm.load_case(FIG12, {**QUIET, "parameters.cells": 24})
    serial = nsm.run(case).run_result
    assert len(serial.skipped) > len(serial.branches) >= 3
    raw = case.model_dump(mode="json")
    wcase, _, wwindow, worker = rebuild_case(raw)  # the worker: one algorithm, many tasks
    wseeds = worker.starts(wcase.start, wwindow)
    results = []
    for i, seed in enumerate(wseeds):
        worker.begin_task()
        branch = worker.run_branch(seed, branch_id=i)
        results.append((branch, 0.0, {}, None, worker.task_state()))
    mcase, master_problem, mwindow, master = rebuild_case(raw)  # the master: seeds only
    seeds = master.starts(mcase.start, mwindow)
    branches, skipped, _, _ = merge_in_seed_order(master, seeds, results)
    assert skipped == serial.skipped
    assert [(b.id, b.label, b.n_points) for b in branches] == \
        [(b.id, b.label, b.n_points) for b in serial.branches]
    assert [[p.y.tolist() for p in b.points] for b in branches] == \
        [[p.y.tolist() for p in b.points] for b in serial.branches]
    if _replays(master_problem):
        serial_extras = serial.problem.presentation.report_extras(serial.branches)
        assert master_problem.presentation.report_extras(branches) == serial_extras


@needs_dask
def test_scan_on_two_workers_gives_the_serial_outputs() -> None:
    """Fig. 12's scan (30 cells) serially and with ``workers=2``: identical outputs; the scan
    ran as several tasks (the bar splits it by ranges of periods)."""
    case = nsm.load_case(FIG12, {**QUIET, "parameters.cells": 30})
    serial = nsm.run(case)
    dist = nsm.run(case, workers=2)
    assert len(serial.run_result.branches) >= 3 and serial.run_result.skipped
    assert_same_outputs(serial, dist)
    assert dist.run_result.timings["seed_pieces"] > 2
    assert len(dist.run_result.timings["seed_pieces_s"]) == dist.run_result.timings["seed_pieces"]


@needs_dask
def test_backbones_as_tasks_give_the_serial_outputs() -> None:
    """Fig. 13's five backbones (200 cells) serially and with ``workers=2`` (one task per
    branch where the problem allows it): identical outputs, the counters included."""
    case = nsm.load_case(FIG13, {**QUIET, "parameters.cells": 200})
    serial = nsm.run(case)
    dist = nsm.run(case, workers=2)
    assert len(serial.run_result.branches) == 5
    assert_same_outputs(serial, dist)


def _scan_seeds(algorithm: Any, case: Any, window: Any) -> list[tuple[Any, ...]]:
    return [(s.solution.counts, s.solution.energy, s.label)
            for s in algorithm.starts(case.start, window)]


@pytest.mark.parametrize("known_before", [False, True])
def test_a_scan_adopted_from_compact_records_is_the_serial_scan(known_before: bool) -> None:
    """The scan's pieces (one worker, in piece order) adopted by a master: the records list
    no node of a scanned period that has neither orbits nor filter reasons (most nodes: the
    period implies them), yet the master's seeds, its counters and every node of the scanned
    periods (:meth:`physical`) are the serial run's. With a node of a period solved on the
    master before (``known_before``), that period is adopted node by node and nothing is
    counted twice. Oracle: the serial scan of the same case."""
    case = nsm.load_case(FIG12, {**QUIET, "parameters.cells": 24})
    raw = case.model_dump(mode="json")
    scase, serial_problem, swindow, serial = rebuild_case(raw)
    serial_seeds = _scan_seeds(serial, scase, swindow)
    wcase, _, wwindow, worker = rebuild_case(raw)
    mcase, master_problem, mwindow, master = rebuild_case(raw)
    M_lo, M_hi = serial_problem._scan_periods(swindow)
    if known_before:  # a node of a scanned period with no orbit, solved here first
        M = (M_lo + M_hi) // 2
        m = int(serial_problem._scan_nodes[M][0])
        assert master_problem.physical((m, M - m)) == serial_problem.physical((m, M - m))
    implied = listed = 0
    for piece in worker.seed_pieces(wcase.start, wwindow, 5):
        record = worker.seed_piece(wcase.start, wwindow, piece)
        sols, detailed, plain, periods = record
        scanned = {M for M, _ in periods}
        assert not any(len(c) == 2 and c[0] + c[1] in scanned for c in plain)
        implied += sum(len(ms) for _, ms in periods) - len(detailed)
        listed += len(detailed) + len(plain)
        master.adopt_seed_piece(record)
    assert implied > 10 * listed  # the records are compact
    assert _scan_seeds(master, mcase, mwindow) == serial_seeds
    assert master_problem.node_evaluations == serial_problem.node_evaluations
    assert master_problem.filter_counts == serial_problem.filter_counts
    for M in range(M_lo, M_hi + 1):
        for m in serial_problem._scan_nodes[M].tolist():
            a, b = master_problem.physical((m, M - m)), serial_problem.physical((m, M - m))
            assert [(s.counts, s.energy) for s in a] == [(s.counts, s.energy) for s in b]
    assert master_problem.node_evaluations == serial_problem.node_evaluations  # no re-solve
