"""Step control of the pseudo-arclength engine: how long the next step is, and whether a
corrected step is admitted for analysis.

* the length: ``step_initial``, then adapted to the Newton iterations and the turning angle of
  the last accepted step (:func:`_adapted_step`) and capped by the ratio of the multipliers'
  motion to its limit (:func:`_motion_capped_step`); shortened so that it never carries the
  parameter past an edge of the window (it then ends on the edge) nor an admissibility test
  function or an event function far past a zero (``TEST_STEP_FACTOR``);
* the checks of a corrected step: the tangent turns by at most ``max_angle``; the multipliers
  near the unit circle move at most ``max_multiplier_step`` (:func:`~.motion.multiplier_motion`),
  in a conservative family only those near a collision with a partner of the other Krein
  signature (:func:`~.motion.krein_motion_ratio`), and the nearest such collision closes by at
  most half with the multipliers outside the circle the same ones at both ends
  (:func:`~.motion.krein_closing`); a refused step is retried with half its length.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from nsm_continuation.core.floquet import collision_distances, krein_of
from nsm_continuation.core.palc.motion import krein_closing, krein_motion_ratio, multiplier_motion
from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.problem import FloquetData
from nsm_continuation.core.records import Point
from nsm_continuation.core.settings import ContinuationSettings

if TYPE_CHECKING:
    from nsm_continuation.core.palc.engine import ContinuationEngine

#: a step shorter than this times ``1 + |y|_inf`` does not move the point in floating point
STEP_RESOLUTION = 1e-14

#: a step may move an admissibility test function towards zero by at most this many times its
#: value (predicted linearly from the secant of the last step): a zero is crossed and located,
#: never jumped over with the test changing sign twice inside one step. Must exceed 1 (a cap
#: at a fraction of the value would approach the zero geometrically and never reach it).
TEST_STEP_FACTOR = 2.0


#: :func:`_motion_capped_step`: the motion ratio a step is aimed at, and the lattice of its
#: factors (powers of ``2^(1 / MOTION_LATTICE)``)
MOTION_TARGET = 0.9
MOTION_LATTICE = 4


def _motion_capped_step(h_step: float, ratio: float) -> float:
    """The longest step after an accepted one whose multiplier motion ratio
    (:meth:`StepController._multiplier_motion`) was ``ratio``: displacements grow
    linearly with a short step, so ``h_step * MOTION_TARGET / ratio`` is aimed just inside
    the limit; it caps the growth of :func:`_adapted_step`, and spares the attempts that the
    check would refuse. A refused step is still halved: the closing rule approaches a
    collision geometrically
    (:func:`~nsm_continuation.core.palc.motion.krein_closing`), and larger cuts, tried, skipped a
    Neimark-Sacker window 1.5e-7 wide on the 200-dof branch
    (``benchmarks/bench_chain_large.py``).

    The factor is rounded down to a power of ``2^(1/4)``: like the fixed factors of
    :func:`_adapted_step`, it then does not follow the rounding errors of the multipliers,
    so two runs whose multipliers differ by rounding (another BLAS, a structured and a dense
    solve) take the same steps, unless a ratio lies on a boundary of the lattice."""
    factor = MOTION_TARGET / ratio
    return h_step * 2.0 ** (np.floor(MOTION_LATTICE * np.log2(factor)) / MOTION_LATTICE)


def _adapted_step(h: float, iterations: int, angle: float, st: ContinuationSettings) -> float:
    """Next step length after an accepted step: few Newton iterations and a small turning
    angle grow it (x 1.6, up to ``step_max``), many iterations or a large angle shrink it
    (x 0.6, down to ``step_min``)."""
    if iterations <= 3 and angle < 0.4 * st.max_angle:
        return min(h * 1.6, st.step_max)
    if iterations >= 6 or angle > 0.8 * st.max_angle:
        return max(h * 0.6, st.step_min)
    return h


@dataclass(frozen=True)
class Step:
    """A planned step from the last point: its length ``h`` and, when it ends on an edge of
    the parameter window, that edge's parameter value (``edge``; None otherwise); ``kink``:
    the event function whose predicted zero shortened it (:meth:`StepController._test_cap`),
    or None."""

    h: float
    edge: float | None
    kink: str | None = None


@dataclass(frozen=True)
class Trial:
    """A corrected step admitted for analysis: the new point's unknowns, tangent, Newton
    iterations and arclength, the tangent's turning angle, the multipliers computed at the
    point (reused by its analysis) and the motion ratio (0 when the check did not apply)."""

    step: Step
    y: np.ndarray
    tangent: np.ndarray
    iterations: int
    s: float
    angle: float
    floquet: FloquetData | None
    ratio: float


class StepController(EnginePart):
    """The step length along a half-branch and the checks of each corrected step.

    State of the current half-branch (:meth:`begin`): the next step length ``h``, the last
    failure ``why`` (named in the termination reason) and the number of successive refusals
    by the multipliers' motion ``halvings``. Kept over the run: the multipliers (and their
    Krein data) of the last few trial points (:meth:`remember`, :meth:`krein_at`)."""

    def __init__(self, engine: ContinuationEngine) -> None:
        super().__init__(engine)
        self.h = engine.settings.step_initial
        self.why = ""
        self.halvings = 0
        #: the event function that shortened the last accepted step (Step.kink)
        self.kink: str | None = None
        #: the Floquet data of the last few points, by their unknowns (:meth:`krein_at`)
        self._floquet_memo: dict[bytes, FloquetData] = {}
        #: the Krein data of the last point a step started from (:meth:`krein_at`)
        self._krein_base: tuple[bytes, np.ndarray] | None = None

    def begin(self) -> None:
        """A new half-branch: the first step is ``step_initial``."""
        self.h = self.settings.step_initial
        self.why = ""
        self.halvings = 0
        self.kink = None

    def approaching_kink(self, step: Step) -> bool:
        """Whether ``step`` and the last accepted one were both shortened by the predicted
        zero of the same event function: its linear prediction keeps receding, the zero is
        approached geometrically and never reached (a grazing margin ``-v^2 / (2a)`` on the
        impacting side is quadratic in the arclength). A kink of the branch may lie there
        (:meth:`~nsm_continuation.core.palc.kinks.KinkCrosser.ahead`)."""
        return step.kink is not None and step.kink == self.kink

    def inside_window(self, p: Point) -> bool:
        """Whether ``p``'s parameter lies inside the window ``[param_min, param_max]``."""
        st = self.settings
        par = p.y[self.ip]
        return not ((st.param_min is not None and par < st.param_min) or (
            st.param_max is not None and par > st.param_max))

    def plan(self, pts: list[Point]) -> Step | str | None:
        """The next step from ``pts[-1]`` (:meth:`_step_length`); the termination reason when
        the step no longer moves the point in floating point; None when the point lies on the
        window edge its tangent points out of."""
        a = pts[-1]
        h, why = self.h, self.why
        res = STEP_RESOLUTION * (1.0 + float(np.linalg.norm(a.y, np.inf)))
        if h < res:
            return (f"step_below_resolution (a step of {h:.3g} does not move a point of "
                    f"size {res / STEP_RESOLUTION - 1:.3g} in floating point"
                    + (f"; last failure: {why})" if why else ")"))
        length = self._step_length(pts, h, res)
        if length is None:
            return None
        return Step(*length)

    def refuse(self, step: Step, why: str | None = None) -> None:
        """The step is retried with half its length; ``why``: the failure, if it has one."""
        self.h = 0.5 * step.h
        if why is not None:
            self.why = why

    def fail(self, step: Step, why: str) -> str | None:
        """The step failed (no corrected point, or a numerical error in its analysis): it is
        retried with half its length, and the branch ends (the returned reason) when that is
        below ``step_min``."""
        self.refuse(step, why)
        if self.h < self.settings.step_min:
            return f"step_below_minimum ({why})"
        return None

    def admit(self, a: Point, step: Step, y: np.ndarray, t: np.ndarray, iterations: int
              ) -> Trial | None:
        """The corrected step ``a -> y`` checked before its analysis: None (the step is
        retried with half its length) when the tangent turned by more than ``max_angle``,
        the multipliers moved too far (:meth:`_multiplier_motion`) or the corrector on the
        window edge went backwards."""
        st = self.settings
        h_step = step.h
        angle = float(np.arccos(float(np.clip(t @ a.tangent, -1.0, 1.0))))
        if angle > st.max_angle and h_step > 2 * st.step_min:
            self.refuse(step)
            return None
        pre, ratio = self._multiplier_motion(a, y, t, h_step, self.halvings)
        if ratio > 1.0:
            self.refuse(step)
            self.halvings += 1
            if self.halvings == st.max_multiplier_halvings:
                self.engine.motion_limited_steps += 1
            return None
        s_new = a.s + (h_step if step.edge is None else float(a.tangent @ (y - a.y)))
        if not s_new > a.s:  # the corrector at the edge went backwards: not this branch
            self.refuse(step, "corrector at the window edge went backwards")
            return None
        return Trial(step, y, t, iterations, s_new, angle, pre, ratio)

    def accept(self, trial: Trial) -> None:
        """The next step after the accepted ``trial``: adapted to its Newton iterations and
        turning angle (:func:`_adapted_step`), its growth capped by its motion ratio
        (:func:`_motion_capped_step`)."""
        self.halvings = 0
        self.kink = trial.step.kink
        self.h = _adapted_step(self.h, trial.iterations, trial.angle, self.settings)
        if trial.ratio > 0.0:
            self.h = min(self.h, _motion_capped_step(trial.step.h, trial.ratio))

    def _step_length(self, pts: list[Point], h: float, res: float
                     ) -> tuple[float, float | None, str | None] | None:
        """``(h_step, edge, kink)``: the step from ``pts[-1]`` shortened so that it never
        carries the parameter past an edge of the window (it then ends on the edge, whose
        parameter value is ``edge``) nor a test or event function far past a zero
        (:meth:`_test_cap`; ``kink``: the event function that shortened it); None when the
        point already lies on the edge its tangent points out of."""
        st = self.settings
        a = pts[-1]
        h_step, edge, kink = h, None, None
        cap = self._window_cap(a)
        if cap is not None:
            dist, value = cap
            if abs(value - a.y[self.ip]) <= STEP_RESOLUTION * (1.0 + abs(value)):
                return None
            if dist <= h_step:
                h_step, edge = dist, value
        tcap, by = self._test_cap(pts)
        tcap = max(tcap, st.step_min, 4 * res)
        if tcap < h_step:
            h_step, edge, kink = tcap, None, by
        return h_step, edge, kink

    def _window_cap(self, a: Point) -> tuple[float, float] | None:
        """``(arclength along a's tangent to the window edge ahead, that edge's parameter)``,
        or None when no edge lies ahead."""
        st = self.settings
        tp = float(a.tangent[self.ip])
        if tp > 0 and st.param_max is not None:
            value = st.param_max
        elif tp < 0 and st.param_min is not None:
            value = st.param_min
        else:
            return None
        return max((value - float(a.y[self.ip])) / tp, 0.0), value

    def _test_cap(self, pts: list[Point]) -> tuple[float, str | None]:
        """Longest step that moves no admissibility test function and no event function
        towards zero by more than ``TEST_STEP_FACTOR`` times its value, predicted from the
        secant of the last step. A huge step could otherwise jump over a zero pair (out of
        admissibility and back; an event function's two zeros) or land on another solution
        beyond a grazing point, with no sign change to see. Also the event function that
        sets the cap (None when a test function does, or none)."""
        if len(pts) < 2:
            return np.inf, None
        a, prev = pts[-1], pts[-2]
        ds = a.s - prev.s
        cap, by = np.inf, None
        if not ds > 0:
            return cap, by
        for event, now, before in ((False, a.tests, prev.tests),
                                   (True, a.event_values, prev.event_values)):
            for name, fa in now.items():
                fp = before.get(name)
                if fp is None or fa == 0 or not (np.isfinite(fa) and np.isfinite(fp)):
                    continue
                slope = (fa - fp) / ds
                if slope * fa < 0 and TEST_STEP_FACTOR * abs(fa / slope) < cap:
                    cap, by = TEST_STEP_FACTOR * abs(fa / slope), (name if event else None)
        return cap, by

    def _multiplier_motion(self, a: Point, y_new: np.ndarray, t_new: np.ndarray,
                           h_step: float, halvings: int) -> tuple[FloquetData | None, float]:
        """``(multipliers at the trial point, motion ratio)``: the step is refused when the
        ratio exceeds 1. Multipliers near the unit circle must not move too far in one step
        (:func:`~.motion.multiplier_motion`, :func:`~.motion.krein_motion_ratio`): a collision
        and a narrow instability window (out and back in) could hide inside it; in a
        conservative family a step must not close the nearest collision too fast either
        (:func:`~.motion.krein_closing`); the larger ratio counts. The ratio is 0 when the
        check does not apply. Checked before the (costlier) admissibility tests of the new
        point, whose analysis reuses the multipliers."""
        st = self.settings
        if a.multipliers is None or not h_step > 4 * st.step_min \
                or halvings >= st.max_multiplier_halvings:
            return None, 0.0
        pre = self.engine.floquet(y_new, t_new)
        if pre is None:
            return None, 0.0
        b_mult = np.asarray(pre.multipliers)
        # Krein-aware check (conservative families): only multipliers that may collide with a
        # partner of the other signature within the step are bounded
        krein_a = self.krein_at(a)
        krein_b = krein_of(pre) if krein_a is not None else None
        self.remember(y_new, pre)
        if krein_a is not None and krein_b is not None:
            tol = max(st.unit_circle_tol, a.circle_tol,
                      1e3 * np.finfo(float).eps * pre.matrix_norm)
            dist = (collision_distances(a.multipliers, krein_a, tol),
                    collision_distances(b_mult, krein_b, tol))
            closing = krein_closing(a.multipliers, krein_a, b_mult, krein_b, tol,
                                    st.max_multiplier_step, dist)
            return pre, max(closing, krein_motion_ratio(
                a.multipliers, krein_a, b_mult, krein_b, tol, st.krein_fraction,
                st.max_multiplier_step, distances=dist))
        return pre, multiplier_motion(a.multipliers, b_mult) / st.max_multiplier_step

    def remember(self, y: np.ndarray, fl: FloquetData | None) -> None:
        """Keep the multipliers (and their Krein data) of the last few trial points: the
        step checks and :meth:`~nsm_continuation.core.palc.crossings.CrossingLocator.
        krein_windows` read those of both ends of a step."""
        if fl is None:
            return
        memo = self._floquet_memo
        if len(memo) >= 4:
            memo.pop(next(iter(memo)))
        memo[np.asarray(y, dtype=float).tobytes()] = fl

    def krein_at(self, a: Point) -> np.ndarray | None:
        """Krein definiteness of the multipliers of ``a`` (:class:`~nsm_continuation.core.floquet.
        KreinFloquetData`), or None (generic motion check). Only for a problem that declares
        itself conservative (:attr:`Problem.conservative`: its map is symplectic) and when
        ``settings.krein_step_control``. Remembered from the trial point that became ``a``;
        otherwise (a start, a located or kink point) the multipliers are computed again."""
        st = self.settings
        if not (st.krein_step_control and self.problem.conservative):
            return None
        key = np.asarray(a.y, dtype=float).tobytes()
        # the step from ``a`` may be halved more times than the memo holds trial points: the
        # Krein data of the last ``a`` are kept aside (the same values, not computed again)
        base = self._krein_base
        if base is not None and base[0] == key and base[1].shape == np.shape(a.multipliers):
            return base[1]
        fl = self._floquet_memo.get(key)
        if fl is None:
            fl = self.engine.floquet(a.y, a.tangent)
            self.remember(a.y, fl)
        krein = krein_of(fl)
        if krein is None or np.asarray(fl.multipliers).shape != np.asarray(a.multipliers).shape:
            return None
        self._krein_base = (key, krein)
        return krein
