"""The algorithms that follow the solution curve ``G(y) = 0`` from start points with the
pseudo-arclength engine (:mod:`nsm_continuation.core.palc`): :class:`PseudoArclength`
(``palc``: event location and Floquet stability) and :class:`LocatedEvents`
(``located_events``: a two-parameter curve of located codimension-one points,
:mod:`nsm_continuation.algorithms.curves`)."""

from __future__ import annotations

from typing import Any, ClassVar

from nsm_continuation.algorithms.base import Algorithm, StartTangentEngine, Window, lies_on
from nsm_continuation.algorithms.curves import CurveTracer, LocatedCurve
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch
from nsm_continuation.core.settings import ContinuationSettings


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


__all__ = ["LocatedEvents", "PseudoArclength"]
