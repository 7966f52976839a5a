"""Which orbits the orbit figures of a run draw (``output.orbits``,
:mod:`nsm_continuation.figures.orbits`):
the points chosen on the branches, their orbits (:meth:`Presentation.orbit
<nsm_continuation.core.presentation.Presentation.orbit>`), and what the case asks for that the run
cannot
draw (:func:`spec_warnings`, part of the report). Without matplotlib: the report is written
by a process that does not draw (:mod:`nsm_continuation.figures.process`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from nsm_continuation.cases.schema import OrbitsSpec
from nsm_continuation.core.problem import EvaluationError, Problem
from nsm_continuation.core.records import Branch, OrbitTrace, Point


@dataclass
class Chosen:
    """A point chosen for the orbit figures: its branch, the point, what chose it (``first``,
    an event kind, ``omega = 3``, ...) and the continued parameter's value there."""

    branch: Branch
    point: Point
    tag: str
    value: float


def parameter_name(res: Any) -> str:
    """The quantity the case continued (``continuation.parameter``; the problem's parameter
    when the case names none)."""
    name = res.case.continuation.parameter
    return name if name else res.problem.parameter


def parameter_value(problem: Problem, p: Point, name: str) -> float:
    """``name`` at ``p``: a derived quantity, else an unknown, else NaN."""
    return float(p.value(name, problem.variables))


def branches_of(res: Any, ids: Sequence[int] | None = None) -> list[Branch]:
    """The branches with points: every one in the run's order, or those of ``ids`` in that
    order."""
    if ids is None:
        return [br for br in res.branches if br.points]
    by_id = {br.id: br for br in res.branches if br.points}
    return [by_id[i] for i in ids if i in by_id]


def choose(res: Any, points: Sequence[str | float], ids: Sequence[int] | None = None
           ) -> list[Chosen]:
    """The points named by ``points`` (see the module docstring) on the branches ``ids``
    (default all), each once, in the order named; branches without points are skipped."""
    return select(res, points, ids)[0]


def select(res: Any, points: Sequence[str | float], ids: Sequence[int] | None = None
           ) -> tuple[list[Chosen], list[int]]:
    """:func:`choose`, and the indices of the entries of ``points`` that select no point of
    the branches (an event kind the run did not locate there, or no branch with points)."""
    pr, name = res.problem, parameter_name(res)
    branches = branches_of(res, ids)
    out: list[Chosen] = []
    seen: set[tuple[int, int]] = set()
    empty: list[int] = []

    def add(br: Branch, p: Point, tag: str) -> None:
        key = (br.id, id(p))
        if key not in seen:
            seen.add(key)
            out.append(Chosen(br, p, tag, parameter_value(pr, p, name)))

    for i, entry in enumerate(points):
        found = False
        if isinstance(entry, int | float) and not isinstance(entry, bool):
            pts = [(br, p) for br in branches for p in br.points]
            if pts:
                dist = [abs(parameter_value(pr, p, name) - float(entry)) for _, p in pts]
                br, p = pts[int(np.nanargmin(dist))]
                add(br, p, f"nearest {name} = {float(entry):g}")
                found = True
        else:
            for br in branches:
                if entry == "first":
                    add(br, br.points[0], "first")
                    found = True
                elif entry == "last":
                    add(br, br.points[-1], "last")
                    found = True
                else:
                    for ev in br.events:
                        if ev.kind != "endpoint" and entry in ("events", ev.kind):
                            add(br, ev.point, ev.kind)
                            found = True
        if not found:
            empty.append(i)
    return out, empty


def event_kinds_of(res: Any, ids: Sequence[int] | None = None) -> list[str]:
    """The kinds of the events located on the branches ``ids`` (default all), branch ends
    excepted, each once."""
    return list(dict.fromkeys(ev.kind for br in branches_of(res, ids) for ev in br.events
                              if ev.kind != "endpoint"))


def nothing_selected(entry: str | float, res: Any, ids: Sequence[int] | None) -> str:
    """Why the point entry ``entry`` selects nothing: no event of that kind on the branches
    ``ids`` (with the kinds there are), or no branch with points."""
    if not branches_of(res, ids):
        return f"{entry!r} selects no point: no branch drawn has points"
    kinds = event_kinds_of(res, ids)
    what = "event" if entry == "events" else f"{entry!r} event"
    return (f"{entry!r} selects no point: the branches drawn have no {what} (events located: "
            f"{', '.join(kinds) or 'none'})")


def time_signals(res: Any, chosen: list[Chosen], periods: int) -> list[str] | None:
    """The signals of the ``time`` view of the first of ``chosen`` whose orbit can be
    computed; None if none can."""
    for ch in chosen:
        items, _ = traces(res, [ch], periods)
        if items:
            tr = items[0][1]
            return [s for s in tr.views.get("time", ()) if s in tr.signals]
    return None


def spec_warnings(res: Any) -> list[str]:
    """What ``output.orbits`` asks for that the run cannot draw, one line each (known only
    after computing; the views and point kinds were checked before,
    :func:`~nsm_continuation.cases.validation.check_orbits`): a branch of ``branches`` the run
    does not have (or without points), a point entry that selects nothing, a signal of ``log`` that
    the time view does not draw (read from the first chosen orbit), ``log`` without the time
    view. Computed once per run (kept in ``res.orbit_warnings``); none without
    ``output.orbits``."""
    if res.orbit_warnings is not None:
        return list(res.orbit_warnings)
    spec: OrbitsSpec | None = res.case.output.orbits
    out: list[str] = []
    if spec is not None:
        have = [br.id for br in res.branches if br.points]
        for i, b in enumerate(spec.branches or []):
            if b not in have:
                out.append(f"output.orbits.branches[{i}]: the run has no branch {b} with "
                           f"points (branches with points: "
                           f"{', '.join(map(str, have)) or 'none'}): nothing of it is drawn")
        chosen: list[Chosen] = []
        if {"time", "phase"} & set(spec.views):
            chosen, empty = select(res, spec.points, spec.branches)
            out += [f"output.orbits.points[{i}]: "
                    f"{nothing_selected(spec.points[i], res, spec.branches)}" for i in empty]
        if spec.log and "time" not in spec.views:
            out.append("output.orbits.log: the time view is not among output.orbits.views: "
                       "nothing is drawn on a log scale")
        elif spec.log and chosen:
            signals = time_signals(res, chosen, spec.periods)
            if signals is not None:
                out += [f"output.orbits.log[{i}]: {s!r} is not a signal of the time view "
                        f"(its signals: {', '.join(signals)}): ignored"
                        for i, s in enumerate(spec.log) if s not in signals]
    res.orbit_warnings = list(out)
    return out


def problem_of(res: Any, br: Branch, p: Point) -> Problem:
    """The problem whose unknowns ``p.y`` are: the one branch ``br`` was computed with (a
    switched branch of a bifurcation diagram has its own, e.g. orbits of twice the period),
    in the point's chart (:meth:`Problem.in_chart
    <nsm_continuation.core.problem.Problem.in_chart>`)."""
    return res.branch_problems.get(br.id, res.problem).in_chart(p.chart)


def traces(res: Any, chosen: list[Chosen], periods: int
           ) -> tuple[list[tuple[Chosen, OrbitTrace]], list[str]]:
    """``(chosen point, its orbit)`` for every point whose orbit could be computed, and a
    one-line note for each that could not."""
    out, failed = [], []
    for ch in chosen:
        try:
            tr = problem_of(res, ch.branch, ch.point).presentation.orbit(ch.point.y,
                                                                          periods)
        except EvaluationError as exc:
            failed.append(f"{ch.branch.label} {ch.tag}: {str(exc).splitlines()[0][:80]}")
            continue
        if tr is not None:
            out.append((ch, tr))
    return out, failed
