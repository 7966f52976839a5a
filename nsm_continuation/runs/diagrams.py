"""Bifurcation diagrams: every branch born at a detected point, followed recursively, in one
run.

``analysis: {branch_switching: {depth: 3, kinds: [period_doubling, branch_point]}}`` makes a
run grow a tree. Generation 0 is the case's own branches. For each generation ``g < depth``,
every event of a listed kind on a branch of generation ``g`` starts a branch of generation
``g + 1`` by branch switching (:mod:`nsm_continuation.algorithms.switching`: the period-``2k``
family at a
period doubling of an orbit of ``k`` periods, the other branch at a branch point), built and
validated exactly as the case ``start: {from: <this run>, branch: <id>, event: {kind, index},
switch: true}`` would be (:func:`nsm_continuation.cases.validation.validate` on the run in
memory), and continued with the case's ``continuation`` settings
(``branch_switching.max_points`` per switched branch if given).

**Deterministic order.** Breadth first: generation by generation, parents in the order of
their ids, events in arclength order along the parent (their ``index`` among the events of
their kind, as in ``report.json``). Branch ids are given in that order, so the same case
gives the same ids.

**What is not followed**, and said so in the tree: the event a branch was born at, seen again
on it (a branch through a branch point meets its parent there; within ``1e-6 (1 + |y|)`` of
the birth point), an event at a point already switched (the same kind within that distance of
an earlier one), a switch whose branch is one already in the run (it crosses it: the rule
that skips a start lying on a computed branch), anything past ``max_branches``, and a switch
that fails (its reason: no new solution at any amplitude, a problem that cannot represent
the family); a failed switch adds no branch.

The tree (``RunResult.tree``) is written to ``report.json`` (``diagram``) and ``report.md``;
:func:`figure` draws every branch in the axes ``output.axes`` (default: the problem's diagram
axes), stability and events marked, each switched branch labelled at its birth point. Like
BifurcationKit's ``bifurcationdiagram`` (a recursion of ``continuation`` from the bifurcation
points of each branch, to a given ``level``), on the problems of this package, hybrid ones
included.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from nsm_continuation.cases.validation import validate
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch, Event
from nsm_continuation.runs.branches import run_branches
from nsm_continuation.runs.execution import DaskSession, Execution, one_line, wait_all
from nsm_continuation.runs.restart_record import record_from_result
from nsm_continuation.runs.result import RunResult

#: two located points closer than this (times ``1 + |y|_inf``) are the same point
SAME_POINT = 1e-6
#: the label of this run as the ``start.from`` of the switches inside it
THIS_RUN = "this run"
#: Feigenbaum's ratio of successive period-doubling intervals of a smooth unimodal map with a
#: quadratic maximum (the limit; the first ratios of the logistic map are 4.75, 4.66, 4.67)
FEIGENBAUM_DELTA = 4.669201609102990


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape:
        return False
    return float(np.linalg.norm(a - b, np.inf)) <= SAME_POINT * (
        1.0 + float(np.linalg.norm(a, np.inf)))


def _ordinals(br: Branch) -> list[tuple[Any, int]]:
    """``(event, index among the events of its kind on the branch)`` in arclength order."""
    counts: dict[str, int] = {}
    out = []
    for ev in br.events:
        n = counts.get(ev.kind, 0)
        counts[ev.kind] = n + 1
        out.append((ev, n))
    return out


def _sub_result(res: RunResult, br: Branch, problem: Problem) -> RunResult:
    """The run reduced to the one branch ``br`` (and the problem it was computed with): what
    :func:`nsm_continuation.runs.restart_record.record_from_result` reads."""
    return RunResult(res.case, problem, [br], res.settings, res.window)


@dataclass
class _Candidate:
    """An event of a listed kind on a branch of the current generation: a node of the tree."""

    parent: Branch
    problem: Problem
    event: Event
    index: int

    @property
    def y(self) -> np.ndarray:
        return np.asarray(self.event.point.y, dtype=float)


def _switch_case(res: RunResult, c: _Candidate) -> tuple[dict[str, Any], Any, type[Problem]]:
    """The switch at ``c`` as a case: ``(raw case, restart record of the parent, problem
    class)``, exactly what ``start: {from: <this run>, branch, event, switch: true}`` reads;
    plain data that a Dask task carries."""
    spec = res.case.analysis.branch_switching
    record = record_from_result(_sub_result(res, c.parent, c.problem), THIS_RUN)
    cont: dict[str, Any] = {}
    if spec is not None and spec.max_points is not None:
        cont["max_points"] = spec.max_points
    raw: dict[str, Any] = {
        "name": res.case.name,
        "start": {"from": THIS_RUN, "branch": c.parent.id,
                  "event": {"kind": c.event.kind, "index": c.index}, "switch": True},
        "continuation": cont, "analysis": {"branch_switching": None},
        "output": {"plots": False, "progress": False}}
    return raw, record, type(res.problem)


def _child_problem(raw: dict[str, Any], record: Any, cls: type[Problem]
                   ) -> tuple[Any, Problem | None, str]:
    """``(case, problem, "")`` of a switch, or ``(None, None, why)`` when the switch cannot
    be a case (a problem that cannot represent the family)."""
    try:
        case, target = validate(raw, restart_record=record, problem_class=cls)
    except CaseError as exc:
        return None, None, str(exc)
    return case, target, ""


def _switch(raw: dict[str, Any], record: Any, cls: type[Problem], poll: Callable[[], None] | None
            ) -> tuple[Branch | None, str, list[float], Problem | None]:
    """One switch in this process: ``(the switched branch, "", its time, its problem)`` or
    ``(None, why, [], None)``. The child runs serially (it is one branch)."""
    case, target, why = _child_problem(raw, record, cls)
    if case is None:
        return None, why, [], None
    child = run_branches(case, target, progress=False, poll=poll, execution=Execution())
    failed = [b for b in child.branches if b.failed_start]
    if failed or not child.branches:
        why = "; ".join(f"{k}: {v}" for b in failed for k, v in b.termination.items())
        return None, why or "no branch", [], None
    (branch,) = child.branches
    return branch, "", list(child.timings.get("per_branch_s", [])), child.problem


def switch_task(raw: dict[str, Any], record: Any, cls: type[Problem]
                ) -> tuple[Branch | None, str, list[float]]:
    """One switch as a Dask task (:func:`_switch` on a worker): the problem is rebuilt by the
    master from the same case, not sent back."""
    branch, why, per_branch, _ = _switch(raw, record, cls, None)
    return branch, why, per_branch


def _not_followed(c: _Candidate, births: dict[int, tuple[str, np.ndarray]],
                  switched: list[tuple[str, np.ndarray]]) -> str | None:
    """Why ``c`` is not followed whatever the run's size (module docstring), else None."""
    birth = births.get(c.parent.id)
    if birth is not None and birth[0] == c.event.kind and _same(birth[1], c.y):
        return "not followed: the point this branch was born at"
    if any(k == c.event.kind and _same(p, c.y) for k, p in switched):
        return "not followed: a point already switched"
    return None


def _speculative(cands: list[_Candidate], births: dict[int, tuple[str, np.ndarray]],
                 switched: list[tuple[str, np.ndarray]]) -> list[int]:
    """The candidates of a generation that the serial walk switches if ``max_branches`` is not
    reached first: in order, those neither at their birth point nor at a point switched
    before them. The walk switches a prefix of them (once the limit is reached it stays
    reached), so their switches can be computed ahead, in parallel."""
    seen = list(switched)
    out = []
    for k, c in enumerate(cands):
        if _not_followed(c, births, seen) is None:
            seen.append((c.event.kind, c.y))
            out.append(k)
    return out


def grow(res: RunResult, poll: Callable[[], None] | None = None,
         session: DaskSession | None = None) -> None:
    """Grow the tree of ``res`` in place (module docstring): switched branches appended to
    ``res.branches`` with the next ids, ``res.tree`` and ``res.branch_problems`` filled,
    the time in ``res.timings['diagram_s']``.

    With a Dask ``session`` the switches of a generation are computed as tasks (those the
    serial walk would make, :func:`_speculative`; a local cluster is used for two or more,
    an existing one for any) and adopted in the serial order, so the tree, ids and branches
    are those of the serial run; switches the walk does not reach (``max_branches``) are
    cancelled. ``res.timings['dask_switch_tasks']`` counts the tasks."""
    spec = res.case.analysis.branch_switching
    if spec is None:
        return
    t0 = time.perf_counter()
    kinds = set(spec.kinds)
    for br in res.branches:
        res.branch_problems.setdefault(br.id, res.problem)
        br.info.setdefault("depth", 0)
    births: dict[int, tuple[str, np.ndarray]] = {}
    switched: list[tuple[str, np.ndarray]] = []
    tasks = 0
    generation = [br for br in res.branches if br.points]
    for depth in range(1, spec.depth + 1):
        cands = [_Candidate(parent, res.branch_problems[parent.id], ev, index)
                 for parent in generation for ev, index in _ordinals(parent)
                 if ev.kind in kinds]
        cases = {k: _switch_case(res, cands[k]) for k in _speculative(cands, births, switched)}
        futures: dict[int, Any] = {}
        if session is not None and (len(cases) > 1 or (
                cases and session.execution.scheduler is not None)):
            futures = {k: session.submit(switch_task, *case, key=f"nsm-switch-{depth}-{k}")
                       for k, case in cases.items()}
            tasks += len(futures)
            wait_all(list(futures.values()), poll, session=session)
        children: list[Branch] = []
        for k, c in enumerate(cands):
            node: dict[str, Any] = {
                "depth": depth, "parent": c.parent.id,
                "event": {"kind": c.event.kind, "index": c.index},
                "parameter": float(c.y[c.problem.parameter_index]), "child": None}
            status = _not_followed(c, births, switched)
            if status is None and len(res.branches) >= spec.max_branches:
                status = (f"not followed: analysis.branch_switching.max_branches = "
                          f"{spec.max_branches} reached")
            if status is not None:
                node["status"] = status
                res.tree.append(node)
                continue
            switched.append((c.event.kind, c.y))
            raw, record, cls = cases[k]
            if k in futures:
                cb, why, per_branch = _task_result(futures.pop(k))
                problem = None
                if cb is not None:  # the child's problem, built here as the worker built it
                    _, problem, why = _child_problem(raw, record, cls)
            else:
                cb, why, per_branch, problem = _switch(raw, record, cls, poll)
            same = None if cb is None or problem is None else _same_branch(res, cb, problem)
            if cb is None or problem is None:
                node["status"] = f"switch failed: {why}"
            elif same is not None:
                node["status"] = f"not followed: the branch born there is branch {same}"
            else:
                _adopt(res, cb, problem, c, depth, per_branch)
                births[cb.id] = (c.event.kind, c.y)
                children.append(cb)
                node.update({"child": cb.id, "status": "followed", "child_label": cb.label})
            res.tree.append(node)
        for f in futures.values():  # switches the walk did not reach (max_branches)
            f.cancel()
        generation = children
        if not generation:
            break
    res.timings["diagram_s"] = time.perf_counter() - t0
    res.timings["n_points"] = int(sum(b.n_points for b in res.branches))
    if session is not None:
        res.timings["dask_switch_tasks"] = tasks


def _same_branch(res: RunResult, cb: Branch, problem: Problem) -> int | None:
    """The id of a branch of the run, of the same problem (class and period multiple), on
    which the switched branch ``cb`` lies (its points at a third and two thirds of its length:
    away from the switch point, which lies on its parent), or None. Two branches through
    one point meet again where they cross: the switch at the crossing of ``x = mu`` and
    ``x = 1 - mu`` reached from the first gives the second, already in the tree."""
    from nsm_continuation.algorithms.base import lies_on

    pts = cb.points
    if len(pts) < 3:
        return None
    probes = [pts[len(pts) // 3].y, pts[2 * len(pts) // 3].y]
    for br in res.branches:
        other = res.branch_problems.get(br.id, res.problem)
        if (type(other) is not type(problem) or other.dim != problem.dim
                or other.period_multiple() != problem.period_multiple()):
            continue
        if all(lies_on(y, [br], problem.parameter_index) for y in probes):
            return br.id
    return None


def _task_result(future: Any) -> tuple[Branch | None, str, list[float]]:
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - recorded in the tree, never raised
        return None, one_line(f"task failed on a worker: {type(exc).__name__}: {exc}"), []


def _adopt(res: RunResult, cb: Branch, problem: Problem, c: _Candidate, depth: int,
           per_branch: list[float]) -> None:
    """Append the switched branch ``cb`` to the run with the next id and its parent link."""
    cb.id = len(res.branches)
    for key in ("restart_from", "restart_branch", "restart_event", "restart_event_index"):
        cb.info.pop(key, None)
    cb.info.update({"depth": depth, "parent_branch": c.parent.id,
                    "parent_event": c.event.kind, "parent_event_index": c.index})
    res.branches.append(cb)
    res.branch_problems[cb.id] = problem
    res.timings["per_branch_s"] = [*res.timings.get("per_branch_s", []), *per_branch]


def parent_link(br: Branch) -> dict[str, Any] | None:
    """Where a branch was born: in this run (``{"branch", "event", "depth"}``) or in a
    previous one (a restart or a switch from a saved run: ``{"run", "branch", "event"}``);
    None for a branch started from the case's ``start:``."""
    info = br.info
    if "parent_branch" in info:
        return {"branch": int(info["parent_branch"]),
                "event": {"kind": info["parent_event"],
                          "index": int(info["parent_event_index"])},
                "depth": int(info.get("depth", 1))}
    if "restart_from" in info:
        link: dict[str, Any] = {"run": info["restart_from"],
                                "branch": int(info.get("restart_branch", 0))}
        if "restart_event" in info:
            link["event"] = {"kind": info["restart_event"],
                             "index": int(info.get("restart_event_index", 0))}
        else:
            link["point"] = info.get("restart_point")
        for key in ("switch", "curve"):
            if key in info:
                link[key] = info[key]
        return link
    return None


def link_text(link: dict[str, Any] | None) -> str:
    """``branch 0, period_doubling #1`` (in this run) or ``runs/x branch 0, fold #0``."""
    if not link:
        return "-"
    where = f"{link['run']} " if "run" in link else ""
    ev = link.get("event")
    at = (f"{ev['kind']} #{ev['index']}" if ev is not None
          else f"row {link.get('point')}")
    how = f" ({link['switch']} switch)" if link.get("switch") else ""
    how += f" ({link['curve']} curve)" if link.get("curve") else ""
    return f"{where}branch {link['branch']}, {at}{how}"


def summary(res: RunResult) -> dict[str, Any] | None:
    """``report.json``'s ``diagram`` block: the settings, the tree, and per kind the located
    points of the switches in the order of the parameter with the ratios of successive
    intervals (``(p_k - p_{k-1}) / (p_{k+1} - p_k)``: Feigenbaum's ``delta`` for a period-
    doubling cascade)."""
    spec = res.case.analysis.branch_switching
    if spec is None:
        return None
    out: dict[str, Any] = {"depth": spec.depth, "kinds": list(spec.kinds),
                           "max_branches": spec.max_branches, "tree": list(res.tree)}
    cascade = cascade_points(res)
    if cascade:
        out["period_doubling_cascade"] = cascade
    return out


def cascade_points(res: RunResult) -> dict[str, Any] | None:
    """The period doublings along the chain of period-doubled branches: the first root
    branch, the branch born at its first followed period doubling, that one's, ... Each point
    with the branch it lies on, the period multiple there and the parameter; the last branch's
    own first period doubling (not followed: the depth is reached) ends the list. With the
    intervals between successive points and their ratios. None without two such points."""
    by_id = {b.id: b for b in res.branches}
    links: dict[int, dict[str, Any]] = {}
    for node in res.tree:
        if node.get("child") is not None and node["event"]["kind"] == "period_doubling":
            links.setdefault(node["parent"], node)
    roots = [b for b in res.branches if b.info.get("depth", 0) == 0 and b.points]
    if not roots:
        return None

    def multiple(br: Branch) -> int:
        return int(br.info.get("period_multiple", br.info.get("returns", 1)) or 1)

    points = []
    br = roots[0]
    while br.id in links:
        node = links[br.id]
        k = multiple(br)
        points.append({"branch": br.id, "period_multiple": k, "to": 2 * k,
                       "parameter": node["parameter"]})
        br = by_id[node["child"]]
    ip = res.branch_problems.get(br.id, res.problem).parameter_index
    for ev in br.events:
        value = float(ev.point.y[ip])
        if ev.kind != "period_doubling" or (points and abs(value - points[-1]["parameter"])
                                            <= SAME_POINT * (1.0 + abs(value))):
            continue  # not a doubling, or the one this branch was born at
        k = multiple(br)
        points.append({"branch": br.id, "period_multiple": k, "to": 2 * k,
                       "parameter": value, "followed": False})
        break
    if len(points) < 2:
        return None
    p = [q["parameter"] for q in points]
    gaps = [b - a for a, b in zip(p, p[1:], strict=False)]
    ratios = [g0 / g1 if g1 != 0 else None for g0, g1 in zip(gaps, gaps[1:], strict=False)]
    return {"points": points, "intervals": gaps, "ratios": ratios,
            "feigenbaum_delta": FEIGENBAUM_DELTA}


__all__ = ["THIS_RUN", "cascade_points", "grow", "link_text", "parent_link", "summary"]
