"""One run of a validated case: its branches (:mod:`nsm_continuation.runs.branches`), grown
into a bifurcation diagram when the case asks for one (``analysis.branch_switching``,
:mod:`nsm_continuation.runs.diagrams`). The command line and the Python API run cases here."""

from __future__ import annotations

from collections.abc import Callable

from nsm_continuation.cases.schema import Case
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.runs.branches import run_branches
from nsm_continuation.runs.diagrams import grow
from nsm_continuation.runs.execution import Execution
from nsm_continuation.runs.result import RunResult


def run_case(case: Case, problem: Problem, progress: bool = True,
             starts: list[StartPoint] | None = None,
             poll: Callable[[], None] | None = None,
             execution: Execution | None = None) -> RunResult:
    """Continue every start of ``case`` (or the given ``starts``) and, when the case asks for a
    bifurcation diagram, every branch born at its detected points, recursively
    (:func:`~nsm_continuation.runs.branches.run_branches`, with the same arguments)."""
    tree = grow if case.analysis.branch_switching is not None else None
    return run_branches(case, problem, progress, starts, poll, execution, grow=tree)
