"""Closed loops: a branch that returns to where it started ends there, walked once.

A family of periodic orbits may be a closed curve in (unknowns, parameter) space (an isola, or
a loop through folds and grazings). Followed by pseudo-arclength continuation it would be walked
round and round until ``max_points``, every event repeated on each lap, and walked again the
other way by the backward half of the branch. A half-branch therefore ends when one of its
steps ``a -> b`` passes through a *target*: a point on the branch that it would otherwise walk
through again in the same direction,

* its own start (with the half's orientation), and
* the last point of each half-branch already computed from the same start, with its tangent
  reversed (the backward half, walking the loop the other way round, meets the forward half's
  end from beyond: the two halves together cover the loop once).

The step passes through a target ``(y_T, t_T)`` when

1. the half-branch has left the target's neighbourhood first: one of its points lay farther
   from ``y_T`` than ``LEAVE`` times the step that reached it (this excludes the start's own
   first steps), and it has at least ``MIN_POINTS`` points;
2. the step crosses the target's normal hyperplane ``t_T . (y - y_T) = 0`` forwards (from
   negative to non-negative), with both tangents ``t_a``, ``t_b`` pointing along ``t_T``
   (``t . t_T > 0``): the branch goes the same way there;
3. the chord's point on that hyperplane lies within ``NEAR`` step lengths of ``y_T`` (a cheap
   filter), and Newton on ``[G(y); t_T . (y - y_T)] = 0`` from it (the branch's point on the
   hyperplane) lands within ``CLOSE`` (relative to ``1 + |y_T|``) of ``y_T``, and on this step's
   arc (within half the step of the chord's point). A branch that only passes near its start (a
   spiral, a figure of eight touching itself in the parameter's projection, a neighbouring
   loop) has its own point on that hyperplane, as far from ``y_T`` as it passes; a closed one
   returns to ``y_T`` itself, the solution of the regular system there being unique.

The curve through a regular point with a given tangent direction is unique, so a branch that
passes through such a target walks on exactly the way it came: the half-branch ends at the
target (a copy of it appended at the arclength of the closing, the step's point beyond it
dropped), and the events that the step located beyond the closing (repeats of the events of
the branch's first steps) are dropped. The reason names the closing
(:data:`~nsm_continuation.core.records.CLOSED_LOOP`). A forward half that closed the loop
leaves no backward half to compute.

Peers: BifurcationKit's ``ContinuationPar(detect_loop = true)`` compares each newly located
*special point* with those already found (``norminf`` within ``rtol = 1e-3``): a loop is
recognised only when a bifurcation is found a second time, about a lap late, and a loop without
special points is not; MatCont stops only at ``MaxNumPoints``; COCO's 1-d atlas ends when a new
chart covers the other end of the atlas (its boundary becomes empty), by the chart radius. The
test here is per step, verified by Newton to the corrector's accuracy, and dedups the events.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from nsm_continuation.core.palc.errors import NUMERICAL_ERRORS
from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.records import CLOSED_LOOP, Event, Point

#: a half-branch must have this many points before it can close a loop
MIN_POINTS = 4
#: the half-branch has left a target's neighbourhood once a point lay farther from it than this
#: many times the step that reached it
LEAVE = 2.0
#: the chord's point on the target's hyperplane must lie within this many step lengths of it
NEAR = 1.0
#: the branch's point on the target's hyperplane coincides with the target within this,
#: relative to ``1 + |y_T|`` (the corrector resolves points to ``newton_tol ~ 1e-11``; a branch
#: that passes its start closer than this is not told from a closed one)
CLOSE = 1e-7


@dataclass
class _Target:
    """A point the half-branch ends at if it passes through it again (module docstring)."""

    point: Point
    #: what reaching it means, for the reason
    what: str
    #: whether the half-branch has left its neighbourhood
    left: bool = False


class LoopCloser(EnginePart):
    """Ends a half-branch that closes a loop through its start (module docstring)."""

    def begin(self, start: Point, earlier_ends: list[Point]) -> None:
        """A new half-branch from ``start`` (with its own orientation); ``earlier_ends``: the
        last points of the half-branches already computed from the same start."""
        self._targets = [_Target(start, "returned to its start")]
        self._targets += [_Target(replace(p, tangent=-p.tangent, bordered_det=-p.bordered_det),
                                  "met the end of its other half")
                          for p in earlier_ends if p is not start]

    def closes(self, pts: list[Point], events: list[Event], first_new: int) -> str | None:
        """Whether a step among the points appended from index ``first_new`` on closes a loop:
        if so the half-branch is cut at the closing (``pts`` and ``events`` in place) and the
        reason is returned; else None."""
        for k in range(max(first_new, 1), len(pts)):
            a, b = pts[k - 1], pts[k]
            for target in self._targets:
                if not target.left:
                    target.left = _left(target.point, a, b)
                    continue
                if k + 1 < MIN_POINTS:
                    continue
                y = self._through(target.point, a, b)
                if y is None:
                    continue
                s_close = a.s + float(a.tangent @ (y - a.y))
                del pts[k:]
                events[:] = [ev for ev in events if ev.point.s <= s_close]
                pts.append(replace(target.point, s=s_close))
                n = len(pts)
                return (f"{CLOSED_LOOP}: the branch {target.what} after {n} points, arc length "
                        f"{abs(s_close):.6g}")
        return None

    def _through(self, target: Point, a: Point, b: Point) -> np.ndarray | None:
        """The branch's point on the target's normal hyperplane in the step ``a -> b`` if it
        coincides with the target (criteria 2 and 3 of the module docstring), else None."""
        if a.chart != target.chart or b.chart != target.chart:
            return None
        t = target.tangent
        sa, sb = float(t @ (a.y - target.y)), float(t @ (b.y - target.y))
        if not (sa < 0.0 <= sb) or float(a.tangent @ t) <= 0.0 or float(b.tangent @ t) <= 0.0:
            return None
        chord = float(np.linalg.norm(b.y - a.y))
        guess = a.y + (sa / (sa - sb)) * (b.y - a.y)
        if float(np.linalg.norm(guess - target.y)) > NEAR * chord:
            return None
        try:
            y, _, _ = self.engine.correct(guess, t, target.y, 0.0)
        except NUMERICAL_ERRORS:
            return None
        scale = 1.0 + float(np.linalg.norm(target.y, np.inf))
        if y is None or float(np.linalg.norm(y - guess)) > 0.5 * chord \
                or float(np.linalg.norm(y - target.y, np.inf)) > CLOSE * scale:
            return None
        return y


def _left(target: Point, a: Point, b: Point) -> bool:
    """Whether ``b`` lies farther from the target than ``LEAVE`` times the step ``a -> b``."""
    return float(np.linalg.norm(b.y - target.y)) > LEAVE * float(np.linalg.norm(b.y - a.y))
