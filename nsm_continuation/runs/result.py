"""The result of one run in memory: the case, the problem, the branches and what the run
measured; written by :mod:`nsm_continuation.output`, drawn by :mod:`nsm_continuation.figures`,
wrapped for the Python API by :class:`nsm_continuation.api.Result`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from nsm_continuation.cases.schema import Case
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch
from nsm_continuation.core.settings import ContinuationSettings


@dataclass
class RunResult:
    """One run: its validated case and problem, the branches in the order computed, the
    settings and parameter window they were computed with, and the run's timings."""

    case: Case
    problem: Problem
    branches: list[Branch]
    settings: ContinuationSettings
    window: tuple[float | None, float | None]
    timings: dict[str, Any] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    #: the tree of a bifurcation diagram (``analysis.branch_switching``,
    #: :mod:`nsm_continuation.runs.diagrams`): one record per event considered
    tree: list[dict[str, Any]] = field(default_factory=list)
    #: the problem each branch was computed with, where it is not ``problem`` (a switched
    #: branch of a diagram: the period-2k problem at a period doubling)
    branch_problems: dict[int, Problem] = field(default_factory=dict)
    #: what ``output.orbits`` asks for that the run cannot draw, one line each, once checked
    #: (:func:`nsm_continuation.figures.orbit_selection.spec_warnings`; None: not yet)
    orbit_warnings: list[str] | None = None
    #: the ``report.json`` this run was read back from (:mod:`nsm_continuation.output.loading`;
    #: None for a run computed here): what the problem said at the end of the run (its
    #: summary, its results, the warnings, the restart record with the parameters as they
    #: were), which a problem rebuilt from the case cannot say again
    saved_report: dict[str, Any] | None = None
