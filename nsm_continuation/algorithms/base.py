"""Continuation algorithms as objects behind one runner.

An :class:`Algorithm` turns the YAML ``start:`` block of a problem into seeds, continues one
branch per seed and tells whether a seed already lies on a computed branch;
:func:`nsm_continuation.runs.runner.run_case` drives any of them with one loop and counts the same
things for all (branches, points, time per branch, the algorithm's own counters).

* :class:`PseudoArclength` (``palc``): the pseudo-arclength engine
  (:mod:`nsm_continuation.core.palc`) with event location and Floquet stability;
* :class:`Lattice` (``lattice``): the lattice engine (:mod:`nsm_continuation.core.lattice`) for
  problems whose solutions sit on integer lattice nodes (:class:`~nsm_continuation.core.lattice.
  LatticeProblem`);
* :class:`PycontLite` (``pycont``): pycont-lite through :mod:`nsm_continuation.adapters.pycont`
  follows the branch (its own predictor, matrix-free corrector and step control); each of its
  points is then analysed by the problem's hooks exactly as the engine's (admissibility,
  multipliers, derived quantities). Events other than the branch ends are not located
  (pycont-lite's fold/branch-point detection works on ``G_u``, not on the hooks), and bounds on
  derived quantities cut the branch at the last point inside them.
* :class:`Sweep` (``sweep``): no continuation of a solution curve but the solution at each
  value of a grid of the parameter, in order, each warm-started from the previous one (a
  frequency sweep of a forced response, :class:`SweepProblem`): the grid is
  ``continuation.max_points`` values from ``continuation.min`` to ``max``, swept upwards, downwards
  or both (``continuation.direction``).

A problem declares the algorithms it supports (``Problem.algorithms``, the first is the
default); YAML ``continuation.algorithm`` picks one of them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core.lattice import LatticeContinuation, LatticeProblem, LatticeSeed
from nsm_continuation.core.palc import NUMERICAL_ERRORS, ContinuationEngine, describe_error
from nsm_continuation.core.problem import Problem, StartPoint, SweepSeed
from nsm_continuation.core.records import Branch, Event, Point
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


class _CurveAlgorithm(Algorithm):
    """Common part of the algorithms that follow the curve ``G(y) = 0`` from start points."""

    setup_key: ClassVar[str] = "build_casadi_s"

    def starts(self, case_start: Any, window: Window) -> list[Any]:
        return list(self.problem.start_points(case_start, window))

    def prepare(self) -> None:
        _ = self.problem.compiled  # build the CasADi functions once

    def covered(self, seed: Any, branches: list[Branch]) -> bool:
        """Only starts that ask for it (``info['skip_if_covered']``, e.g. the chain's
        ``all: true``) are skipped when they lie on a computed branch."""
        return bool(seed.info.get("skip_if_covered")) and lies_on(
            seed.y, branches, self.problem.parameter_index)


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


class PseudoArclength(_CurveAlgorithm):
    """Pseudo-arclength continuation with event location (:mod:`nsm_continuation.core.palc`)."""

    name: ClassVar[str] = "palc"

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        super().__init__(problem, settings)
        self.engine = StartTangentEngine(problem, settings, progress=self._tick)

    def run_branch(self, seed: Any, branch_id: int) -> Branch:
        return self.engine.run(seed, branch_id=branch_id)

    def counters(self) -> dict[str, Any]:
        return {"residual_evaluations": self.engine.n_evaluations,
                "steps_taken_despite_multiplier_motion": self.engine.motion_limited_steps,
                "events_not_located_on_their_arc": self.engine.unlocated_events,
                "krein_passings": self.engine.krein_passings,
                "sign_changes_through_a_pole": self.engine.sign_changes_without_zero}


class LocatedEvents(_CurveAlgorithm):
    """Two-parameter curves of codimension-one points as sequences of located events
    (:mod:`nsm_continuation.algorithms.curves`, eq. L1): problems of type
    :class:`~nsm_continuation.algorithms.curves.LocatedCurve` only."""

    name: ClassVar[str] = "located_events"

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        from nsm_continuation.algorithms.curves import CurveTracer, LocatedCurve

        super().__init__(problem, settings)
        assert isinstance(problem, LocatedCurve)
        self.tracer = CurveTracer(problem, settings, progress=self._tick)

    def run_branch(self, seed: Any, branch_id: int) -> Branch:
        return self.tracer.run(seed, branch_id=branch_id)

    # a curve is followed both ways from its first point: on Dask the two halves are two
    # tasks, each locating the first point again (counted once, by the first half)
    def branch_pieces(self, seed: Any) -> int:
        return len(self.tracer.signs(seed))

    def run_piece(self, seed: Any, piece: int) -> Any:
        tr = self.tracer
        before = (tr.n_base_runs, tr.n_base_points)
        first, why, width0 = tr.first_point(seed)
        if piece > 0:
            tr.n_base_runs, tr.n_base_points = before
        half = None if first is None else tr.half(first, tr.signs(seed)[piece], width0)
        return why if first is None else "", half, (tr.n_base_runs - before[0],
                                                    tr.n_base_points - before[1])

    def join_pieces(self, seed: Any, pieces: list[Any], branch_id: int) -> Branch:
        failed = pieces[0][0]
        halves = {sign: half for sign, (_, half, _) in zip(self.tracer.signs(seed), pieces,
                                                            strict=True)}
        counts = (sum(c[0] for _, _, c in pieces), sum(c[1] for _, _, c in pieces))
        return self.tracer.branch(seed, branch_id, failed, {} if failed else halves, counts)

    def counters(self) -> dict[str, Any]:
        return {"base_continuations": self.tracer.n_base_runs,
                "base_points": self.tracer.n_base_points}


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
        return list(self.lattice_problem.lattice_seeds(case_start, window))

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


class PycontLite(_CurveAlgorithm):
    """pycont-lite follows the branch; our hooks analyse each of its points (module doc)."""

    name: ClassVar[str] = "pycont"

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        from nsm_continuation.adapters.pycont import import_pycont

        import_pycont()  # ImportError with the install hint when pycont-lite is missing
        super().__init__(problem, settings)
        #: analyses pycont's points (tangent, tests, multipliers, derived) as the engine's
        self.engine = ContinuationEngine(problem, settings)
        self.n_pycont_evaluations = 0

    def run_branch(self, seed: StartPoint, branch_id: int) -> Branch:
        from nsm_continuation.adapters.pycont import run_pycont

        st = self.settings
        info = {**seed.info, "algorithm": "pycont-lite (events other than the ends not located)"}
        sp: dict[str, Any] = {"tolerance": st.newton_tol, "bifurcation_detection": False}
        if st.param_min is not None:
            sp["param_min"] = st.param_min
        if st.param_max is not None:
            sp["param_max"] = st.param_max
        direction = seed.direction or st.direction
        try:
            run = run_pycont(self.problem, np.asarray(seed.y, dtype=float), ds_min=st.step_min,
                             ds_max=st.step_max, ds_0=st.step_initial, n_steps=st.max_points,
                             direction=direction, full_output=True, **sp)
        except Exception as exc:  # noqa: BLE001 - recorded as the start's failure
            return Branch(branch_id, seed.label, [], [],
                          {"start": f"pycont-lite: {describe_error(exc)}"}, info)
        self.n_pycont_evaluations += run.n_evaluations
        ys = np.asarray(run.y, dtype=float)
        ends = _pycont_terminations(run.result)
        k0 = int(np.argmin(np.linalg.norm(ys - np.asarray(seed.y, dtype=float), axis=1)))
        try:
            points = self._analyse(ys, k0)
        except NUMERICAL_ERRORS as exc:
            return Branch(branch_id, seed.label, [], [],
                          {"start": f"pycont-lite point cannot be analysed: "
                                    f"{describe_error(exc)}"}, info)
        # each direction from the start, cut at the first point outside a derived bound
        termination: dict[str, str] = {}
        lo, hi = k0, k0
        sides = [("forward", 1)] + ([("backward", -1)] if k0 > 0 else [])
        for side, step in sides:
            reason = f"pycont-lite: {ends.get(side, 'ended')}"
            k = k0
            while 0 <= k + step < len(points):
                bound = outside_bound(points[k + step], self.settings)
                if bound is not None:
                    reason = f"bound: {bound} (pycont-lite points beyond it dropped)"
                    break
                k += step
            termination[side] = reason
            lo, hi = (lo, k) if step > 0 else (k, hi)
        points = points[lo:hi + 1]
        events = [Event("endpoint", p, f"branch end: {termination[side]}",
                        data={"reason": termination[side]})
                  for p, side in ((points[0], "backward"), (points[-1], "forward"))
                  if side in termination]
        self._tick(len(points))
        return Branch(branch_id, seed.label, points, events, termination, info)

    def _analyse(self, ys: np.ndarray, k0: int) -> list[Point]:
        """Points of pycont's path ``ys``: tangent along the path, arclength (chord length,
        0 at the start ``ys[k0]``), and every hook of the problem."""
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ys, axis=0), axis=1))])
        s = s - s[k0]
        out: list[Point] = []
        t_prev: np.ndarray | None = None
        for k, y in enumerate(ys):
            t = self.engine.tangent(y, t_prev)
            if t_prev is None and len(ys) > 1 and t @ (ys[1] - ys[0]) < 0:
                t = -t
            out.append(self.engine.analyse(y, t, float(s[k])))
            t_prev = t
        return out

    def counters(self) -> dict[str, Any]:
        return {"pycont_residual_evaluations": self.n_pycont_evaluations,
                "residual_evaluations": self.engine.n_evaluations}


def _pycont_terminations(result: Any) -> dict[str, str]:
    """Termination kind (``MAXSTEPS``, ``PARAM_MAX``, ``DSFLOOR``, ...) of each direction
    pycont-lite followed from the start, following its segments restarted at folds: the first
    is the one :func:`~nsm_continuation.adapters.pycont.run_pycont` puts forward, the second
    the one it reverses in front (backward)."""
    out = {}
    for side, b in zip(("forward", "backward"),
                       [b for b in result.branches if b.from_event == 0], strict=False):
        while b.termination_event is not None and b.termination_event.kind == "LP":
            idx = next((k for k, ev in enumerate(result.events) if ev is b.termination_event),
                       None)
            nxt = next((bb for bb in result.branches if bb.from_event == idx), None)
            if idx is None or nxt is None:
                break
            b = nxt
        ev = b.termination_event
        out[side] = "no termination event" if ev is None else str(ev.kind)
    return out


class SweepProblem(Problem):
    """A problem solved at each value of a grid of its parameter (:class:`Sweep`): e.g. the
    steady state of a forced response at each forcing frequency, found by time stepping from
    the steady state at the previous frequency. No residual, no continuation. Implement
    :meth:`sweep_seeds` and :meth:`sweep_point`; a declared ``signature_kind`` raises an event
    where the points' ``signature`` changes between two consecutive grid values. (A problem
    with a residual is swept too when it lists ``"sweep"`` in ``algorithms`` and implements
    the two hooks of :class:`~nsm_continuation.core.problem.Problem`.)"""

    algorithms: ClassVar[tuple[str, ...]] = ("sweep",)

    def residual(self, y: Any) -> Any:  # pragma: no cover - never called by the sweep
        raise TypeError(f"problem {self.name!r} is a sweep problem: it has no residual")

    @abstractmethod
    def sweep_seeds(self, start: Any, window: Window) -> list[SweepSeed]:
        """The sweeps of the YAML ``start:`` block (``window``: the parameter's bounds)."""

    @abstractmethod
    def sweep_point(self, seed: SweepSeed, value: float, state: Any) -> tuple[Point, Any]:
        """The solution at the parameter ``value`` of the sweep ``seed``, from ``state`` (the
        seed's at the first value, then what the previous call returned): the point (its
        ``y[parameter_index]`` is ``value``) and the state the next value starts from. Raises
        :class:`~nsm_continuation.core.problem.EvaluationError` (or a numerical error) if the
        solution cannot be computed: the sweep then ends there with that reason."""


def sweep_point_record(y: np.ndarray, derived: dict[str, float], direction: int,
                       parameter_index: int, signature: str | None = None) -> Point:
    """A sweep's :class:`~nsm_continuation.core.records.Point`: no tests, no multipliers; the
    tangent is the unit vector of the parameter in the sweep's direction (read by the report
    to tell before from after); :class:`Sweep` sets ``s``, the distance swept so far."""
    tangent = np.zeros(len(y))
    tangent[parameter_index] = 1.0 if direction >= 0 else -1.0
    return Point(y=np.asarray(y, dtype=float), s=0.0, tangent=tangent, tests={}, multipliers=None,
                 trivial_error=0.0, n_unstable=0, derived=dict(derived),
                 bordered_det=float("nan"), signature=signature)


class Sweep(Algorithm):
    """The solution at each value of a parameter grid, in order (module docstring).

    The grid is ``numpy.linspace(continuation.min, continuation.max, continuation.max_points)``
    of the problem's parameter, reversed for a decreasing sweep (a seed with an ``origin``
    sweeps the grid values on its side of it, from it: :meth:`grid`); each value starts from
    the state the previous one ended in (:meth:`Problem.sweep_point`), which gives one point
    or a list of points (a brute-force diagram's recorded returns: the branch's
    ``info['draw']`` is then ``markers``, and the figures draw its points as dots, not a
    line). Each value is one tick of progress. A sweep ends at the end of the grid, at the
    first value with a point outside a bound on a derived quantity (``continuation.
    max_energy``, ``continuation.bounds``; that value is not kept) or where a value cannot be
    solved (the reason is the branch's termination). Events: ``endpoint`` at both ends, the
    problem's ``signature_kind`` at the first point of a new signature.
    """

    name: ClassVar[str] = "sweep"
    takes_start_points: ClassVar[bool] = False
    setup_key: ClassVar[str] = "seeds_s"

    def __init__(self, problem: Problem, settings: ContinuationSettings) -> None:
        if "sweep" not in problem.algorithms or not problem.can_sweep():
            raise ValueError(f"the sweep algorithm needs a problem that can be swept ('sweep' "
                             f"in its algorithms, sweep_seeds() and sweep_point()); "
                             f"{problem.name!r} is not one")
        super().__init__(problem, settings)
        self.sweep_problem = problem
        self.n_evaluations = 0

    def grid(self, direction: int, origin: float | None = None) -> np.ndarray:
        """The parameter values of a sweep in ``direction`` (+1 increasing, -1 decreasing);
        with an ``origin`` (:attr:`SweepSeed.origin`), the values on its side of it, preceded
        by ``origin`` itself unless it is one of them (to 1e-9 of the grid step)."""
        lo, hi = self.settings.param_min, self.settings.param_max
        if lo is None or hi is None or not lo < hi:
            raise ValueError("continuation.min: a sweep needs a window min < max of the "
                             "parameter (continuation.min and continuation.max)")
        values = np.linspace(lo, hi, self.settings.max_points)
        values = values if direction > 0 else values[::-1]
        if origin is None:
            return values
        tol = 1e-9 * (hi - lo) / max(self.settings.max_points - 1, 1)
        side = values[(values - origin) * direction > tol]
        return np.concatenate([[origin], side])

    def starts(self, case_start: Any, window: Window) -> list[Any]:
        self.grid(1)  # a window is required: refused here as a failed start
        seeds = []
        both = [1, -1] if self.settings.direction == 0 else [self.settings.direction]
        for seed in self.sweep_problem.sweep_seeds(case_start, window):
            for d in ([seed.direction] if seed.direction else both):
                label = seed.label if seed.direction or len(both) == 1 else \
                    f"{seed.label}, {'increasing' if d > 0 else 'decreasing'}"
                seeds.append(replace(seed, label=label, direction=d, info=dict(seed.info)))
        return seeds

    def seeds_from_points(self, points: list[StartPoint]) -> list[Any]:
        raise ValueError("a sweep problem starts from its start: block only")

    def covered(self, seed: Any, branches: list[Branch]) -> bool:
        return False

    def run_branch(self, seed: SweepSeed, branch_id: int) -> Branch:
        """The sweep ``seed`` over the grid; never raises (a failure ends it with a reason)."""
        seed = replace(seed, info=dict(seed.info))  # what the problem notes is this run's
        points: list[Point] = []
        events: list[Event] = []
        listed: list[bool] = []
        key = "increase" if seed.direction > 0 else "decrease"
        try:
            reason = self._sweep(seed, points, events, listed)
        except NUMERICAL_ERRORS as exc:
            reason = describe_error(exc)
        except Exception as exc:  # noqa: BLE001 - recorded, never raised
            reason = f"internal error: {type(exc).__name__}: {exc}"
        if points:
            events.insert(0, Event("endpoint", points[0], "sweep start: first grid value",
                                   data={"reason": "first grid value"}))
            events.append(Event("endpoint", points[-1], f"sweep end: {reason}",
                                data={"reason": reason}))
        info = {**seed.info, "algorithm": "sweep", "direction": seed.direction}
        if any(listed):
            info["draw"] = "markers"
        return Branch(branch_id, seed.label, points, events, {key: reason}, info)

    def _sweep(self, seed: SweepSeed, points: list[Point], events: list[Event],
               listed: list[bool]) -> str:
        """Fill ``points`` and ``events`` along the grid (``listed``: whether each value gave
        a list of points); returns the termination reason."""
        pr = self.sweep_problem
        grid = self.grid(seed.direction, seed.origin)
        state = seed.state
        kind = pr.signature_kind
        for value in grid:
            solved, state = pr.sweep_point(seed, float(value), state)
            self.n_evaluations += 1
            listed.append(isinstance(solved, list))
            new = solved if isinstance(solved, list) else [solved]
            for point in new:
                point.s = abs(float(value) - float(grid[0]))
                bound = outside_bound(point, self.settings)
                if bound is not None:
                    return f"bound: {bound} at {pr.parameter} = {value:.6g} (value not kept)"
            for point in new:
                if kind is not None and points and point.signature != points[-1].signature:
                    before, after = points[-1].signature, point.signature
                    events.append(Event(kind, point, f"{before} -> {after}",
                                        data={"signature_before": before,
                                              "signature_after": after}))
                points.append(point)
            self._tick(1)
        return f"end of the grid ({len(grid)} values of {pr.parameter})"

    def counters(self) -> dict[str, Any]:
        return {"sweep_points_solved": self.n_evaluations}


#: the algorithms YAML ``continuation.algorithm`` may name
ALGORITHMS: dict[str, type[Algorithm]] = {
    "palc": PseudoArclength,
    "lattice": Lattice,
    "pycont": PycontLite,
    "sweep": Sweep,
    "located_events": LocatedEvents,
}


def unsupported(name: str, problem: type[Problem] | Problem) -> str | None:
    """Why ``problem`` cannot be continued by the algorithm ``name`` (one line), or None."""
    label = problem.name
    if name not in ALGORITHMS:
        return f"unknown algorithm {name!r} (one of {', '.join(ALGORITHMS)})"
    if name not in problem.algorithms:
        return (f"problem {label!r} cannot be continued by {name!r}; it supports "
                f"{', '.join(problem.algorithms)}")
    if name == "pycont":
        from importlib.util import find_spec

        if find_spec("pycont") is None:
            return ("pycont needs pycont-lite (import name 'pycont'): "
                    "pip install nsm-continuation[pycont]")
    return None


def make_algorithm(name: str, problem: Problem, settings: ContinuationSettings) -> Algorithm:
    """The algorithm ``name`` for ``problem`` (check :func:`unsupported` first)."""
    return ALGORITHMS[name](problem, settings)


__all__ = ["ALGORITHMS", "Algorithm", "Lattice", "LocatedEvents", "PseudoArclength", "PycontLite",
           "StartTangentEngine", "Sweep", "SweepProblem", "SweepSeed", "TangentStart",
           "make_algorithm", "sweep_point_record", "unsupported"]
