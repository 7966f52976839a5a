"""The ``lattice`` algorithm: the lattice engine (:mod:`nsm_continuation.core.lattice`) for
problems whose solutions sit on integer lattice nodes
(:class:`~nsm_continuation.core.lattice.LatticeProblem`: the WFEM bar's phase lengths)."""

from __future__ import annotations

from typing import Any, ClassVar

from nsm_continuation.algorithms.base import Algorithm, Window
from nsm_continuation.core.lattice import LatticeContinuation, LatticeProblem, LatticeSeed
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import Branch
from nsm_continuation.core.settings import ContinuationSettings


class Lattice(Algorithm):
    """Continuation on an integer lattice (:mod:`nsm_continuation.core.lattice`).

    On a Dask cluster, the problem may split its seed search into pieces (a scan of the window
    by chunks of periods:
    :meth:`~nsm_continuation.core.lattice.LatticeProblem.lattice_seed_pieces`),
    each a task whose record (the nodes it solved) is replayed here in order, after which the
    seeds are found here by the serial code; and the branches are tasks only where the problem
    says they are worth it (:meth:`~nsm_continuation.core.lattice.LatticeProblem.
    lattice_distribute_branches`: explicit starts, not a scan's seeds, most of which lie on an
    earlier branch). A branch task returns the keys of the nodes it visited and the problem's
    record, which the merge adopts in seed order: the skipped seeds, and the problem's
    counters, are the serial run's.
    """

    name: ClassVar[str] = "lattice"
    takes_start_points: ClassVar[bool] = False
    setup_key: ClassVar[str] = "seeds_s"
    #: decided per run by :meth:`starts`
    distributable: bool = False

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        if not isinstance(problem, LatticeProblem):
            raise ValueError(f"the lattice algorithm needs a lattice problem (a "
                             f"LatticeProblem); {problem.name!r} is not one")
        super().__init__(problem, settings)
        self.lattice_problem = problem
        self.engine = LatticeContinuation(problem, settings, progress=self._tick)

    def starts(self, case_start: Any, window: Window) -> list[Any]:
        self.distributable = self.lattice_problem.lattice_distribute_branches(case_start)
        return list(self.lattice_problem.lattice_seeds(case_start, window,
                                                       self.settings.energy_cap))

    def seeds_from_points(self, points: list[StartPoint]) -> list[Any]:
        raise ValueError("a lattice problem starts from its start: block only")

    def run_branch(self, seed: LatticeSeed, branch_id: int) -> Branch:
        return self.engine.run(seed, branch_id=branch_id)

    def covered(self, seed: LatticeSeed, branches: list[Branch]) -> bool:
        """A seed whose lattice solution a branch has visited."""
        return self.lattice_problem.lattice_key(seed.solution) in self.engine.visited

    def counters(self) -> dict[str, Any]:
        return {"lattice_steps": self.engine.n_evaluations}

    def seed_pieces(self, case_start: Any, window: Window, count: int) -> list[Any]:
        return list(self.lattice_problem.lattice_seed_pieces(case_start, window, count))

    def seed_piece(self, case_start: Any, window: Window, piece: Any) -> Any:
        pr = self.lattice_problem
        pr.lattice_record()
        try:
            pr.lattice_seed_piece(case_start, window, piece)
        finally:
            record = pr.lattice_recorded()
        return record

    def adopt_seed_piece(self, result: Any) -> None:
        self.lattice_problem.lattice_replay(result)

    def begin_task(self) -> None:
        self.lattice_problem.lattice_record(solutions=False)

    def task_state(self) -> Any:
        return set(self.engine.last_keys), self.lattice_problem.lattice_recorded()

    def adopt_branch(self, branch: Branch, state: Any) -> None:
        keys, record = state
        self.engine.visited |= keys
        self.lattice_problem.lattice_replay(record)


__all__ = ["Lattice"]
