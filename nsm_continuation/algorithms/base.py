"""Continuation algorithms as objects behind one runner: the :class:`Algorithm` contract.

An :class:`Algorithm` turns the YAML ``start:`` block of a problem into seeds, continues one
branch per seed and tells whether a seed already lies on a computed branch;
:func:`nsm_continuation.runs.branches.run_branches` drives any of them with one loop and counts
the same things for all (branches, points, time per branch, the algorithm's own counters).
The algorithms, by name (:mod:`nsm_continuation.algorithms.registry`): ``palc`` and
``located_events`` (:mod:`.palc`), ``lattice`` (:mod:`.lattice`), ``pycont``
(:mod:`.pycont_lite`), ``sweep`` (:mod:`.sweep`). Also here: the start points that carry their
tangent (:class:`TangentStart`, a restart or a switched branch) and the engine that corrects
them along it."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core.palc import NUMERICAL_ERRORS, ContinuationEngine, describe_error
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import Branch, Point
from nsm_continuation.core.settings import ContinuationSettings

Window = tuple[float | None, float | None]


def outside_bound(p: Point, settings: ContinuationSettings) -> str | None:
    """The bound on a derived quantity (``continuation.bounds``) that ``p`` violates, as
    ``"name = max"`` / ``"name = min"``, or None: for the algorithms that do not locate bounds
    on the curve (pycont-lite's points, a sweep's grid values)."""
    for name, (lo, hi) in settings.derived_bounds.items():
        v = p.derived.get(name, np.nan)
        if hi is not None and v > hi:
            return f"{name} = max"
        if lo is not None and v < lo:
            return f"{name} = min"
    return None


class Algorithm(ABC):
    """A continuation algorithm for one problem and one set of settings.

    The runner calls :meth:`starts` (or :meth:`seeds_from_points`), then :meth:`prepare`, then
    for each seed :meth:`covered` and :meth:`run_branch`; ``progress`` (set by the runner) is
    called with the number of new points as they are accepted.
    """

    #: the name used in YAML ``continuation.algorithm`` and ``Problem.algorithms``
    name: ClassVar[str]
    #: whether explicit start points (a guess ``y`` from the Python API) can seed it
    takes_start_points: ClassVar[bool] = True
    #: what the algorithm does not check that the engine would (said in the run's warnings,
    #: hence in ``report.md``, and on the command line's last line); None: nothing
    unchecked: ClassVar[str | None] = None
    #: key of ``report.json``'s ``timings`` for the time to build the seeds and prepare
    setup_key: ClassVar[str] = "setup_s"
    #: whether its branches can be computed as independent Dask tasks, each rebuilding the
    #: seeds from the case (:mod:`nsm_continuation.runs.execution`); an algorithm may decide it per
    #: run in :meth:`starts` (the lattice engine: :class:`Lattice`)
    distributable: bool = True

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        self.problem = problem
        self.settings = settings
        self.progress: Callable[[int], None] | None = None

    def _tick(self, n: int) -> None:
        """Per-point callback handed to the engines."""
        if self.progress is not None:
            self.progress(n)

    @abstractmethod
    def starts(self, case_start: Any, window: Window) -> list[Any]:
        """The seeds of the YAML ``start:`` block (``window``: bounds on the parameter). Raises
        :class:`ValueError` when they cannot be built (the run then records a failed start)."""

    def seeds_from_points(self, points: list[StartPoint]) -> list[Any]:
        """Seeds from explicit start points (only if ``takes_start_points``)."""
        return list(points)

    def prepare(self) -> None:
        """Work done once before the first branch (e.g. build the CasADi functions)."""
        return None

    @abstractmethod
    def run_branch(self, seed: Any, branch_id: int) -> Branch:
        """The branch through ``seed``; never raises (failures end it with a reason)."""

    @abstractmethod
    def covered(self, seed: Any, branches: list[Branch]) -> bool:
        """Whether ``seed`` lies on one of ``branches`` (then it is skipped)."""

    def label(self, seed: Any) -> str:
        """The seed's label (reports list skipped seeds by it)."""
        return str(seed.label)

    def counters(self) -> dict[str, Any]:
        """Counters of the run for ``report.json``'s ``timings``."""
        return {}

    # -- on a Dask cluster (nsm_continuation.runs.execution); the defaults distribute the branches
    # -- only, each task's branch being all the master needs
    def seed_pieces(self, case_start: Any, window: Window, count: int) -> list[Any]:
        """The search for the seeds of ``case_start`` split into about ``count`` independent
        pieces (Dask tasks), in the order a serial search does them; ``[]``: not split
        (default), :meth:`starts` does it all in this process."""
        return []

    def seed_piece(self, case_start: Any, window: Window, piece: Any) -> Any:
        """On a worker: the work of one piece of :meth:`seed_pieces`, as picklable data for
        :meth:`adopt_seed_piece`."""
        raise NotImplementedError(f"the {self.name} algorithm does not split its seed search")

    def adopt_seed_piece(self, result: Any) -> None:
        """On the master, in piece order: take what :meth:`seed_piece` computed, so that
        :meth:`starts` then finds it done."""
        return None

    def branch_pieces(self, seed: Any) -> int:
        """How many independent Dask tasks the branch through ``seed`` is computed in
        (default 1: the whole branch, :meth:`run_branch`); more, and each task computes
        :meth:`run_piece` and the master joins them (:meth:`join_pieces`)."""
        return 1

    def run_piece(self, seed: Any, piece: int) -> Any:
        """On a worker: piece ``piece`` of the branch through ``seed`` (picklable), of
        :meth:`branch_pieces`; by default the whole branch."""
        return self.run_branch(seed, 0)

    def join_pieces(self, seed: Any, pieces: list[Any], branch_id: int) -> Branch:
        """On the master: the branch through ``seed`` from its pieces, in piece order: the
        branch the serial run computes; by default the one piece is the branch."""
        (branch,) = pieces
        branch.id = branch_id
        return branch

    def begin_task(self) -> None:
        """On a worker, before the branch of a task."""
        return None

    def task_state(self) -> Any:
        """On a worker, after the branch of a task: what the master needs besides the branch
        to continue as if it had computed it (:meth:`adopt_branch`); picklable."""
        return None

    def adopt_branch(self, branch: Branch, state: Any) -> None:
        """On the master, when the merge (in seed order) accepts a branch computed on a
        worker with ``state`` (:meth:`task_state`): what computing it here would have changed
        (what :meth:`covered` reads for the next seeds)."""
        return None


def lies_on(y: np.ndarray, branches: list[Branch], ip: int) -> bool:
    """Whether the point ``y`` lies on one of ``branches`` (on the chord between two of its
    points with ``y``'s parameter, within 1e-6 relative and a thousandth of the chord): the
    rule that skips a start on an already computed branch, and a switched branch that is one
    already in a bifurcation diagram."""
    y0 = np.asarray(y)
    p0 = y0[ip]
    for br in branches:
        ys = np.array([p.y for p in br.points]) if br.points else np.empty((0, len(y0)))
        for k in range(len(ys) - 1):
            a, b = ys[k, ip], ys[k + 1, ip]
            if min(a, b) <= p0 <= max(a, b) and a != b:
                lam = (p0 - a) / (b - a)
                yi = (1 - lam) * ys[k] + lam * ys[k + 1]
                if np.linalg.norm(yi - y0) <= 1e-6 * (1 + np.linalg.norm(y0)) + \
                        1e-3 * np.linalg.norm(ys[k + 1] - ys[k]):
                    return True
    return False


@dataclass
class TangentStart(StartPoint):
    """A start point that knows the tangent of its branch there (a restart from a saved point,
    the first point of a switched branch: :mod:`nsm_continuation.cases.restart`). It is corrected by
    Newton on ``[G(y); t . (y - y0)] = 0`` instead of at fixed parameter (well posed at a fold,
    where the parameter cannot be held), and its tangent is oriented along ``t``. With
    ``forward_only`` the branch is continued in that one direction (``direction`` must then be
    nonzero; its sign is not used): e.g. away from a period doubling, where the parameter along
    the new family is flat to the corrector's accuracy and cannot give the direction."""

    tangent: np.ndarray | None = None
    forward_only: bool = False


class StartTangentEngine(ContinuationEngine):
    """The pseudo-arclength engine, with starts that carry their tangent
    (:class:`TangentStart`) corrected along it."""

    def correct_start(self, start: StartPoint) -> tuple[Point | None, str]:
        t0 = getattr(start, "tangent", None)
        if t0 is None:
            return super().correct_start(start)
        y0 = np.asarray(start.y, dtype=float)
        t0 = np.asarray(t0, dtype=float)
        if not (np.all(np.isfinite(y0)) and np.all(np.isfinite(t0))
                and np.linalg.norm(t0) > 0):
            return None, "start guess or its tangent is not finite"
        t0 = t0 / np.linalg.norm(t0)
        y, it, why = self.correct(y0, t0, y0, 0.0)
        if y is None:
            return None, f"start point did not converge ({why})"
        try:
            t = self.tangent(y, t0)
        except np.linalg.LinAlgError:
            return None, "singular Jacobian at start point"
        except NUMERICAL_ERRORS as exc:
            return None, f"no tangent at start point ({describe_error(exc)})"
        if start.direction != 0 and not getattr(start, "forward_only", False) \
                and np.sign(t[self.ip]) != np.sign(start.direction):
            t = -t
        try:
            return self.analyse(y, t, 0.0, it), ""
        except NUMERICAL_ERRORS as exc:
            return None, f"start point cannot be analysed ({describe_error(exc)})"


__all__ = ["Algorithm", "StartTangentEngine", "TangentStart", "Window", "lies_on",
           "outside_bound"]
