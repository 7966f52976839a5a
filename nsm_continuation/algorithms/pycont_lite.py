"""The ``pycont`` algorithm: pycont-lite (through :mod:`nsm_continuation.adapters.pycont`)
follows the branch with its own predictor, matrix-free corrector and step control; each of its
points is then analysed by the problem's hooks exactly as the engine's (admissibility,
multipliers, derived quantities). Events other than the branch ends are not located
(pycont-lite's fold and branch-point detection works on ``G_u``, not on the hooks), and bounds
on derived quantities cut the branch at the last point inside them.

pycont-lite cannot see where an orbit stops being admissible (it follows ``G = 0``, and the
phantom orbits beyond a grazing solve it too), so a branch of a problem that declares
admissibility tests is cut at the first inadmissible point after an admissible one: that
point is kept (the grazing lies between it and the point before, not located), and the
branch's end says so. What pycont-lite does not check is the run's warning
(:attr:`PycontLite.unchecked`: ``report.md`` and the command line's last line)."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from nsm_continuation.algorithms.base import outside_bound
from nsm_continuation.algorithms.palc import _CurveAlgorithm
from nsm_continuation.core.palc import (
    HOOK_FAULTS,
    NUMERICAL_ERRORS,
    ContinuationEngine,
    describe_error,
    describe_fault,
)
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.core.settings import ContinuationSettings


class PycontLite(_CurveAlgorithm):
    """pycont-lite follows the branch; our hooks analyse each of its points (module doc)."""

    name: ClassVar[str] = "pycont"
    unchecked: ClassVar[str | None] = (
        "algorithm pycont: pycont-lite locates no events: no fold, branch point, period "
        "doubling, Neimark-Sacker bifurcation, stability change or grazing is detected between "
        "its points (the only events are the branch ends), and it cannot see where orbits stop "
        "being admissible: a branch is cut at its first inadmissible point, the grazing before "
        "it not located. Use algorithm palc for located events")

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
        except HOOK_FAULTS as exc:  # noqa: BLE001 - recorded as the start's failure
            why = describe_error(exc) if isinstance(exc, Exception) else describe_fault(exc)
            return Branch(branch_id, seed.label, [], [], {"start": f"pycont-lite: {why}"}, info)
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
                left = self._left_admissible(points[k - step], points[k])
                if left is not None:
                    reason = left
                    break
            termination[side] = reason
            lo, hi = (lo, k) if step > 0 else (k, hi)
        points = points[lo:hi + 1]
        events = [Event("endpoint", p, f"branch end: {termination[side]}",
                        data={"reason": termination[side]})
                  for p, side in ((points[0], "backward"), (points[-1], "forward"))
                  if side in termination]
        self._tick(len(points))
        return Branch(branch_id, seed.label, points, events, termination, info)

    def _left_admissible(self, before: Point, after: Point) -> str | None:
        """The end of a branch whose path goes from the admissible ``before`` to the
        inadmissible ``after`` (module docstring), or None."""
        if not before.admissible or after.admissible:
            return None
        name, value = min(after.tests.items(), key=lambda kv: kv[1])
        ip = self.problem.parameter_index
        return (f"admissibility: the orbit at {self.problem.parameter} = {after.y[ip]:.9g} is "
                f"not admissible ({name} = {value:.3g} < 0), the one at "
                f"{before.y[ip]:.9g} is; pycont-lite does not locate the grazing between them "
                "(branch cut at its first inadmissible point)")

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


__all__ = ["PycontLite"]
