"""Continuation on an integer lattice: branches of problems whose solutions sit on lattice nodes.

Some discretisations only have solutions at discrete parameter values: the WFEM bar of Yoong,
Thorin, Legrand (2017) has periodic orbits only at periods ``T = (m + p) dt`` with integer phase
lengths. There is no smooth residual to correct, but a branch is still a one-parameter family,
and the engine's job is the same: predict where the next solution is, correct (here: pick the
lattice solution that continues the previous one), record events where the branch ends or changes
character, and stop with a recorded reason. This module does that generically; it produces the
same :class:`~nsm_continuation.core.records.Branch` / ``Point`` / ``Event`` records as the
pseudo-arclength engine, so results, reports and plots are shared.

A lattice problem (subclass of :class:`LatticeProblem`) implements:

1. :meth:`LatticeProblem.lattice_seeds`: starting solutions from the YAML ``start:`` block.
2. :meth:`LatticeProblem.lattice_next`: predictor + corrector. Given the accepted solutions of
   the branch (last one last) and a direction, return the next solution (or ``None`` and a reason).
3. :meth:`LatticeProblem.lattice_point`: ``(y, tests, derived)`` of a solution for the records.
4. :meth:`LatticeProblem.lattice_character`: named integers (e.g. number of grazing instants);
   a change between consecutive points is reported as an event of the kind the problem maps
   the name to in ``character_kinds`` (default ``pattern_change``, a kind this family
   declares).

On a Dask cluster (:mod:`nsm_continuation.runs.execution`) a problem may also split its seed search
into independent pieces (:meth:`LatticeProblem.lattice_seed_pieces`, e.g. a scan of the window
by chunks of periods) and let the branches of explicit starts run as tasks
(:meth:`LatticeProblem.lattice_distribute_branches`). What a piece or a branch computed on a
worker changes in the problem (e.g. its cache of solved nodes and the counters the report
reads) comes back as data (:meth:`LatticeProblem.lattice_record` /
:meth:`~LatticeProblem.lattice_recorded`) and is replayed on the master in the serial order
(:meth:`~LatticeProblem.lattice_replay`), so the run's outputs are the serial run's. The
defaults split nothing and keep every branch in this process.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core.palc import HOOK_FAULTS, NUMERICAL_ERRORS, describe_error, describe_fault
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import CORE_EVENT_KINDS, Branch, Event, Point
from nsm_continuation.core.roots import pole_estimate
from nsm_continuation.core.settings import ContinuationSettings


@dataclass
class LatticeSeed:
    """A starting solution and the label of its branch."""

    solution: Any
    label: str
    direction: int = 0


class LatticeProblem(Problem):
    """A problem continued on a lattice (see module docstring); no smooth residual."""

    algorithms: ClassVar[tuple[str, ...]] = ("lattice",)
    event_kinds: ClassVar[dict[str, str]] = {
        "pattern_change": "the phase pattern of the orbit changes character along the branch",
    }
    #: name of a :meth:`lattice_character` -> event kind raised where it changes between two
    #: consecutive points (names not listed raise ``pattern_change``)
    character_kinds: ClassVar[dict[str, str]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        known = {**CORE_EVENT_KINDS, **cls.event_kinds}
        for kind in cls.character_kinds.values():
            if kind not in known:
                raise TypeError(f"{cls.__qualname__}: character kind {kind!r} is neither a "
                                "core kind nor declared in event_kinds")

    def residual(self, y: Any) -> Any:  # pragma: no cover - never called by the lattice engine
        raise TypeError(f"problem {self.name!r} is a lattice problem: it has no smooth residual")

    @abstractmethod
    def lattice_seeds(self, start: Any, window: tuple[float | None, float | None],
                      energy_cap: float | None = None) -> list[LatticeSeed]:
        """Starting solutions from the YAML ``start:`` block, in the parameter ``window``;
        ``energy_cap``: the run's ``continuation.max_energy`` (a seed above it would give a
        one-point branch)."""

    @abstractmethod
    def lattice_next(self, history: list[Any], direction: int,
                     window: tuple[float | None, float | None]) -> tuple[Any | None, str]:
        """The solution continuing ``history`` in ``direction`` (+1: increasing parameter)."""

    @abstractmethod
    def lattice_point(self, sol: Any) -> tuple[np.ndarray, dict[str, float], dict[str, Any]]:
        """``(y, tests, derived)`` of a solution."""

    def lattice_character(self, sol: Any) -> dict[str, int]:
        """Named integers of a solution; a change between consecutive points is an event of
        kind ``character_kinds[name]``."""
        return {}

    def lattice_key(self, sol: Any) -> Any:
        """Hashable identity of a solution (used to skip seeds already on a branch). On a
        Dask cluster the keys of a branch computed on a worker are sent to the master: they
        must then be picklable values (e.g. the lattice node), not object ids."""
        return id(sol)

    # -- distributed runs (nsm_continuation.runs.execution); the defaults distribute nothing --
    def lattice_seed_pieces(self, start: Any, window: tuple[float | None, float | None],
                            count: int) -> list[Any]:
        """The seed search of ``start`` split into about ``count`` independent pieces of work
        (small picklable descriptions, e.g. ranges of periods), in the order the serial search
        does them; ``[]``: not split (default). Each piece runs as a Dask task
        (:meth:`lattice_seed_piece`); their records are replayed in this order before
        :meth:`lattice_seeds` runs here, which then finds its work done."""
        return []

    def lattice_seed_piece(self, start: Any, window: tuple[float | None, float | None],
                           piece: Any) -> None:
        """On a worker, between :meth:`lattice_record` and :meth:`lattice_recorded`: the work
        of one piece of :meth:`lattice_seed_pieces`."""
        raise NotImplementedError(f"{type(self).__name__} does not split its seed search")

    def lattice_distribute_branches(self, start: Any) -> bool:
        """Whether the branches of ``start`` are worth one Dask task each: a few seeds, each
        its own branch, that a worker finds again cheaply from the case. Default False: the
        branches are continued in this process, in seed order (e.g. a scan's many seeds, most
        of which lie on the branches of earlier ones and are skipped)."""
        return False

    def lattice_record(self, solutions: bool = True) -> None:
        """Start recording what this problem computes and keeps (default: nothing). With
        ``solutions`` the record carries what the master computes with afterwards (a piece of
        the seed search: the seeds are built from it); without, only what the outputs count
        (a branch task: its branch carries its points), so that it stays small."""
        return None

    def lattice_recorded(self) -> Any:
        """What was computed since :meth:`lattice_record` (picklable; stops recording), for
        :meth:`lattice_replay` on the master."""
        return None

    def lattice_replay(self, record: Any) -> None:
        """Take a record made on a worker as if this problem had computed it (records come in
        the serial order: the pieces of the seed search, then the accepted branches)."""
        return None

    def asymptote(self, points: list[Point]) -> dict[str, float] | None:
        """Estimate of where the energy grows without bound, from the last points. Default:
        :func:`~nsm_continuation.core.roots.pole_estimate` of ``energy_quantity`` (none without
        one) against the parameter (the pseudo-arclength
        engine's asymptote test); a problem with a known law overrides it."""
        key = self.energy_quantity
        if key is None:
            return None
        last = points[-6:]
        try:
            par = np.array([p.y[self.parameter_index] for p in last], dtype=float)
            q = np.array([p.derived.get(key, np.nan) for p in last], dtype=float)
        except (AttributeError, ValueError, IndexError, TypeError):
            return None
        est = pole_estimate(par, q)
        if est is None:
            return None
        return {**est, "detail": f"{key} without bound: asymptote at {self.parameter} = "
                                 f"{est['parameter_asymptote']:.10g}"}


class LatticeContinuation:
    """Continue the branches of a :class:`LatticeProblem`."""

    def __init__(self, problem: LatticeProblem, settings: ContinuationSettings,
                 progress: Callable[[int], None] | None = None) -> None:
        self.problem = problem
        self.settings = settings
        self.progress = progress
        self.n_evaluations = 0
        self.motion_limited_steps = 0
        self.unlocated_events = 0
        self.visited: set[Any] = set()
        #: the keys of the solutions the last branch visited (sent from a worker to the master)
        self.last_keys: set[Any] = set()

    def _visit(self, sol: Any) -> None:
        key = self.problem.lattice_key(sol)
        self.visited.add(key)
        self.last_keys.add(key)

    def _point(self, sol: Any, s: float) -> Point:
        y, tests, derived = self.problem.lattice_point(sol)
        return Point(y=np.asarray(y, float), s=s, tangent=np.zeros(len(y)), tests=tests,
                     multipliers=None, trivial_error=0.0, n_unstable=0, derived=derived,
                     bordered_det=float("nan"))

    def _bounded(self, pt: Point) -> str | None:
        for key, (lo, hi) in self.settings.derived_bounds.items():
            v = pt.derived.get(key)
            if v is None:
                continue
            if hi is not None and v > hi:
                return f"{key} above {hi:g}"
            if lo is not None and v < lo:
                return f"{key} below {lo:g}"
        return None

    def _walk(self, seed: LatticeSeed, direction: int, branch_id: int
              ) -> tuple[list[Point], list[Event], str]:
        """One direction from the seed. Never raises: a problem's hook that fails ends the
        walk with its message as the reason (``internal error: ...`` for an unexpected
        exception), keeping the points found so far."""
        pts: list[Point] = []
        events: list[Event] = []
        try:
            return pts, events, self._walk_in_place(seed, direction, pts, events)
        except NUMERICAL_ERRORS as exc:
            return pts, events, describe_error(exc)
        except HOOK_FAULTS as exc:  # noqa: BLE001 - recorded, never raised
            return pts, events, describe_fault(exc, self.problem.name)

    def _walk_in_place(self, seed: LatticeSeed, direction: int, pts: list[Point],
                       events: list[Event]) -> str:
        pr = self.problem
        window = (self.settings.param_min, self.settings.param_max)
        history = [seed.solution]
        pts.append(self._point(seed.solution, 0.0))
        s = 0.0
        while True:
            if len(pts) >= self.settings.max_points:
                return f"max_points ({self.settings.max_points}) reached"
            sol, reason = pr.lattice_next(history, direction, window)
            self.n_evaluations += 1
            if sol is None:
                return reason
            pt = self._point(sol, 0.0)
            s += direction * float(np.linalg.norm(pt.y - pts[-1].y))
            pt.s = s
            bound = self._bounded(pt)
            if bound is not None:
                asym = pr.asymptote(pts)
                if asym is not None:
                    events.append(Event("asymptote", pts[-1], detail=asym.pop("detail", ""),
                                        data=asym))
                return f"{bound} (next lattice solution not kept)"
            old, new = pr.lattice_character(history[-1]), pr.lattice_character(sol)
            for k in new:
                if k in old and new[k] != old[k]:
                    kind = pr.character_kinds.get(k, "pattern_change")
                    events.append(Event(kind, pt, detail=f"{k}: {old[k]} -> {new[k]}",
                                        data={k: new[k], f"{k}_before": old[k]}))
            history.append(sol)
            self._visit(sol)
            pts.append(pt)
            if self.progress:
                self.progress(1)

    def run(self, seed: LatticeSeed, branch_id: int = 0) -> Branch:
        """Both directions from ``seed`` (or the seed's one); never raises (see ``_walk``)."""
        self.last_keys = set()
        try:
            self._visit(seed.solution)
        except Exception:  # noqa: BLE001 - only the skip-if-visited bookkeeping is lost
            pass
        dirs = [seed.direction] if seed.direction else [-1, 1]
        term: dict[str, str] = {}
        all_pts: list[Point] = []
        all_ev: list[Event] = []
        for d in dirs:
            pts, evs, reason = self._walk(seed, d, branch_id)
            term["increase" if d > 0 else "decrease"] = reason
            if not pts:  # not even the seed could be recorded
                continue
            if not all_pts:
                all_pts = pts
            else:  # the other direction: prepend, reversed, without the shared seed
                all_pts = pts[::-1][:-1] + all_pts
            all_ev += evs
        all_pts.sort(key=lambda p: p.s)
        return Branch(id=branch_id, label=seed.label, points=all_pts, events=all_ev,
                      termination=term)
