"""``report.md``: the human bifurcation report of a run (built from ``report.json``).

**Before -> after in increasing parameter.** An event records what changes across it
(``stable_before`` / ``stable_after``, ``n_outside_*``, ``signature_*``, ``admissible_*``,
``defined_*``, ``value_*``) in the direction the branch was continued, so on a branch continued
towards decreasing parameter both stability changes of one orbit would read "yes -> no".
``report.md`` reads every change in the direction of **increasing continued parameter**: the
event record's ``parameter_direction`` (the sign of the parameter component of the branch's
tangent at the event, :func:`parameter_direction`, written by :func:`annotate_parameter_directions`;
``report.json`` keeps the continuation order) swaps the pairs and the change named in the
detail text where it is -1. Where the parameter does not move at the event (0: a fold) the
change stays in the continuation order, marked "as continued".
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from nsm_continuation.core.records import CORE_EVENT_KINDS
from nsm_continuation.runs.diagrams import link_text

#: meanings of the core event kinds; a run's report adds its problem's (``event_kinds`` of
#: ``report.json``, from ``Problem.event_kinds``)
MEANING = CORE_EVENT_KINDS


def _fmt(x: Any, nd: int = 6) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return f"{x:.{nd}g}"
    return str(x)


def supported_digits(x: Any, uncertainty: Any, most: int = 12) -> int:
    """The significant digits of ``x`` its ``uncertainty`` supports: the last one printed at
    the decimal place of the uncertainty's leading digit, at least one, at most ``most`` (all
    ``most`` when the uncertainty is zero or unknown)."""
    if not isinstance(x, float) or not isinstance(uncertainty, float) or not uncertainty > 0 \
            or not np.isfinite(x) or x == 0.0 or not np.isfinite(uncertainty):
        return most
    return int(min(most, max(1, np.floor(np.log10(abs(x)))
                             - np.floor(np.log10(uncertainty)) + 1)))


#: event data recorded as ``<name>_before`` / ``<name>_after`` (continuation order), in the
#: order the ``change`` column of ``report.md`` looks for them
PAIRED = ("stable", "n_outside", "signature", "admissible", "defined", "value")

#: a tangent parameter component below this (relative to the tangent's norm) is a fold: the
#: parameter does not move at the event, and no parameter order exists there
FOLD_TOL = 1e-9


def parameter_direction(point: Any, parameter_index: int, branch: Any = None) -> int:
    """+1 / -1 if the continuation moved towards increasing / decreasing parameter at ``point``
    (a :class:`~nsm_continuation.core.records.Point`), 0 at a fold or where it cannot be told.

    The sign of ``point.tangent[parameter_index]`` (the unit tangent points in the direction of
    continuation on both halves of a branch). Without a tangent (all zero, e.g. the lattice
    engine): from the neighbouring points of ``branch`` in arclength, ``sign(dp/ds)`` times the
    direction of ``s`` on the half the point lies on (``s < 0``: the half continued backwards,
    whose arclength was negated when the halves were merged)."""
    t = np.asarray(point.tangent, dtype=float).ravel()
    norm = float(np.linalg.norm(t)) if t.size else 0.0
    if np.isfinite(norm) and norm > 0 and parameter_index < t.size:
        tp = float(t[parameter_index])
        return int(np.sign(tp)) if abs(tp) > FOLD_TOL * norm else 0
    if branch is None:
        return 0
    pts = sorted(branch.points, key=lambda q: q.s)
    s = float(point.s)
    below = [q for q in pts if q.s < s]
    above = [q for q in pts if q.s > s]
    lo = below[-1] if below else point
    hi = above[0] if above else point
    if hi.s <= lo.s:
        return 0
    dp = float(hi.y[parameter_index] - lo.y[parameter_index])
    return int(np.sign(dp)) * (-1 if s < 0 else 1)


def annotate_parameter_directions(rep: dict[str, Any], branches: list[Any],
                                  parameter_index: int, orientation: int = 1) -> None:
    """Write ``parameter_direction`` into every event record of ``rep`` (``report.json``'s
    ``branches[i].events[j]``, built from ``branches[i].events[j]`` in the same order): the
    direction along the case's continued parameter, the internal one's times
    ``orientation`` (``Problem.parameter_orientation``: -1 for the chain's omega, whose ``T =
    2 pi / omega`` is continued inside)."""
    for b, br in zip(rep["branches"], branches, strict=True):
        # the parameter turns at a limit point (a fold of the tangent's parameter component,
        # not a multiplier pair at +1 of a conservative family): every event located there
        # (the stability change that comes with it) is in the continuation order, as the
        # fold itself
        folds = [ev.point.s for ev in br.events
                 if ev.kind == "fold" and ev.data.get("test") == "tangent"]
        for e, ev in zip(b["events"], br.events, strict=True):
            s = float(ev.point.s)
            at_fold = any(abs(s - f) <= 1e-9 * (1.0 + abs(f)) for f in folds)
            e["parameter_direction"] = 0 if at_fold else orientation * parameter_direction(
                ev.point, parameter_index, br)


_SWAPPED_PHRASES = [("becomes negative: admissibility lost",
                     "becomes positive: admissibility regained"),
                    ("becomes negative (the orbit was already inadmissible",
                     "becomes positive (the orbit stays inadmissible"),
                    ("ceases to be defined", "becomes defined")]


def reversed_detail(detail: str) -> str:
    """An event's detail text read the other way: ``A -> B`` becomes ``B -> A`` and the paired
    phrases of the engine (admissibility lost / regained, ceases to be / becomes defined) are
    exchanged; anything else is kept."""
    # the two sides of the arrow, without the brackets around the pair: "(+1 -> -2)"
    out = re.sub(r"([^\s()\[\]]+) -> ([^\s()\[\]]+)",
                 lambda m: f"{m.group(2)} -> {m.group(1)}", detail, count=1)
    for a, b in _SWAPPED_PHRASES:
        if a in out:
            return out.replace(a, b)
        if b in out:
            return out.replace(b, a)
    return out


def in_parameter_order(e: dict[str, Any]) -> dict[str, Any]:
    """The event record ``e`` with its before/after pairs and its detail in the direction of
    increasing parameter (swapped where ``parameter_direction`` is -1; unchanged otherwise)."""
    if e.get("parameter_direction") != -1:
        return e
    out = dict(e)
    for k in PAIRED:
        if f"{k}_before" in e or f"{k}_after" in e:
            out[f"{k}_before"], out[f"{k}_after"] = e.get(f"{k}_after"), e.get(f"{k}_before")
    out["detail"] = reversed_detail(str(e.get("detail", "")))
    return out


def change_text(e: dict[str, Any]) -> str:
    """The ``change`` cell of an event (already in parameter order): the first pair of
    :data:`PAIRED` it has, e.g. ``stable: yes -> no (0 -> 2 outside)``."""
    for k in PAIRED:
        if k == "n_outside" or (f"{k}_before" not in e and f"{k}_after" not in e):
            continue
        text = f"{k}: {_fmt(e.get(f'{k}_before'))} -> {_fmt(e.get(f'{k}_after'))}"
        if k == "stable" and "n_outside_before" in e:
            text += (f" ({_fmt(e.get('n_outside_before'))} -> "
                     f"{_fmt(e.get('n_outside_after'))} outside)")
        if e.get("parameter_direction") == 0:
            text += " (as continued: the parameter turns here)"
        return text
    return ""


def flow_yaml(value: Any) -> str:
    """``value`` as one line of YAML flow style (paths quoted where YAML needs it)."""
    import yaml

    return yaml.safe_dump(value, default_flow_style=True, sort_keys=False,
                          width=float("inf")).strip().removesuffix("...").strip()


def continue_hints(restart: dict[str, Any], folder: str, doubling: bool = True,
                   curve_parameters: list[str] | None = None) -> list[dict[str, Any]]:
    """One entry per event of every branch of the restart record: the exact ``start:`` (and,
    for a grazing curve, ``continuation:``) to paste into a case that continues from there
    (:mod:`nsm_continuation.cases.restart`). At a period doubling (when the problem can double its
    period, ``doubling``) and at a branch point: the branch born there (``switch: true``); at a
    grazing in one of ``curve_parameters`` (the parameters the problem's grazing curves may
    free or continue, in order of preference: ``Problem.curve_parameters``): the grazing
    curve freeing the continued parameter and continuing the first other one; at any other
    event: the orbit itself, restarted (in any parameter: add ``continuation.parameter``)."""
    branches = restart.get("branches") or []
    many = len(branches) > 1
    continued = restart.get("continued")
    out = []
    for br in branches:
        k = int(br.get("period_multiple", 1) or 1)
        for ev in br.get("events", []):
            kind, index = ev["kind"], int(ev["index"])
            start: dict[str, Any] = {"from": folder}
            if many:
                start["branch"] = br["id"]
            start["event"] = {"kind": kind, "index": index}
            extra: dict[str, Any] | None = None
            if kind == "period_doubling" and doubling:
                start["switch"] = True
                what = f"the period-{2 * k} family born here"
            elif kind == "branch_point":
                start["switch"] = True
                what = "the other branch through this point"
            elif kind == "grazing" and curve_parameters and continued in curve_parameters:
                others = [q for q in curve_parameters if q != continued]
                # the problem's order of preference (Problem.curve_parameters)
                second = others[0] if others else None
                if second is None:
                    what = "this orbit, restarted"
                else:
                    start.update({"curve": "grazing", "free": continued})
                    extra = {"parameter": second}
                    what = (f"the grazing curve in ({continued}, {second}) through this "
                            f"orbit (set continuation.min/max of {second})")
            elif kind == "endpoint":
                what = "this end of the branch, restarted (e.g. with a wider window)"
            else:
                what = "this orbit, restarted (any parameter: continuation.parameter)"
            line = f"start: {flow_yaml(start)}"
            if extra is not None:
                line += f"\ncontinuation: {flow_yaml(extra)}"
            out.append({"branch": br["id"], "kind": kind, "index": index,
                        "parameter": ev.get("parameter"), "what": what, "yaml": line})
    return out


def family_runs(points: list[Any], parameter_index: int) -> list[dict[str, Any]]:
    """The families along a branch: its runs of consecutive points (in arclength order) with
    the same signature (``Point.signature``: for a hybrid orbit its sequence of events), each
    with its signature, first and last row of ``branch_<id>.csv`` and parameter range; empty
    when the problem has no signature."""
    runs: list[dict[str, Any]] = []
    for k, p in enumerate(points):
        if p.signature is None:
            return []
        par = float(p.y[parameter_index])
        if runs and runs[-1]["signature"] == p.signature:
            run = runs[-1]
            run["rows"][1] = k
            run["parameter_range"] = [min(run["parameter_range"][0], par),
                                      max(run["parameter_range"][1], par)]
        else:
            runs.append({"signature": p.signature, "rows": [k, k],
                         "parameter_range": [par, par]})
    return runs


def _family_lines(rep: dict[str, Any]) -> list[str]:
    """The families each branch went through (``report.json``'s ``branches[i].families``),
    for the branches that went through more than one."""
    par = rep["continuation"].get("case_parameter") or rep["continuation"]["parameter"]
    lines = []
    for b in rep["branches"]:
        runs = b.get("families") or []
        if len(runs) < 2:
            continue
        parts = [f"`{r['signature']}` (rows {r['rows'][0]}-{r['rows'][1]}, {par} "
                 f"{_fmt(r['parameter_range'][0])} .. {_fmt(r['parameter_range'][1])})"
                 for r in runs]
        lines.append(f"- branch {b['id']}: " + ", then ".join(parts))
    if not lines:
        return []
    return ["## Families", "",
            "Branches whose points belong to more than one family of orbits (the event "
            "sequence of each point, column `signature` of the branch CSV, in arclength "
            "order). A change across a grazing the branch was continued through is a "
            "`family_change` event; the rows after it belong to the new family.", "",
            *lines, ""]


def _tree_lines(rep: dict[str, Any]) -> list[str]:
    """The bifurcation diagram's tree (``report.json``'s ``diagram``) and its cascade."""
    d = rep.get("diagram")
    if not d:
        return []
    par = rep["continuation"]["parameter"]
    lines = ["## Bifurcation diagram", "",
             f"Branches born at the detected {', '.join(d['kinds'])} points, followed "
             f"{d['depth']} generation{'s' if d['depth'] != 1 else ''} deep (breadth first; "
             "ids in that order):", "",
             f"| generation | parent branch | event | {par} | child branch | status |",
             "|---|---|---|---|---|---|"]
    for n in d["tree"]:
        ev = n["event"]
        child = n["child"] if n.get("child") is not None else "-"
        lines.append(f"| {n['depth']} | {n['parent']} | {ev['kind']} #{ev['index']} | "
                     f"{_fmt(n['parameter'], 12)} | {child} | {n['status']} |")
    if not d["tree"]:
        lines.append("| - | - | no event of these kinds | - | - | - |")
    reached = {n["depth"] for n in d["tree"]}
    born = [n["child"] for n in d["tree"] if n.get("child") is not None
            and n["depth"] == max(reached, default=0)]
    if reached and max(reached) < d["depth"] and born:
        lines += ["", f"The tree ends at generation {max(reached)}: no "
                  f"{' or '.join(d['kinds'])} event on branch"
                  f"{'es' if len(born) > 1 else ''} {', '.join(map(str, born))} (their "
                  "ends: the termination column of the branches above)."]
    c = d.get("period_doubling_cascade")
    if c:
        lines += ["", "### Period-doubling cascade", "",
                  f"| branch | period | {par} at the doubling | interval to the next | ratio |",
                  "|---|---|---|---|---|"]
        gaps = [*c["intervals"], None]
        ratios = [None, *c["ratios"], None]
        for q, g, r in zip(c["points"], gaps, ratios, strict=False):
            lines.append(f"| {q['branch']} | {q['period_multiple']} -> {q['to']} | "
                         f"{_fmt(q['parameter'], 12)} | {_fmt(g, 6)} | {_fmt(r, 5)} |")
        lines += ["", "ratio: the interval before a doubling over the interval after it "
                  f"(Feigenbaum's delta = {c['feigenbaum_delta']:.4f} is the limit for a smooth "
                  "map with a quadratic critical point; the first ratios are not the limit)."]
    return [*lines, ""]


def _continue_lines(rep: dict[str, Any]) -> list[str]:
    hints = rep.get("continue_from_here") or []
    if not hints:
        return []
    lines = ["## Continue from here", "",
             "Paste the code of a line (`start:`, and the `continuation:` shown) into a new "
             "case file and run it: the problem, its parameters and the numerical settings "
             "are inherited from this run.", ""]
    for h in hints:
        value = h["parameter"]
        at = f" at {_fmt(value, supported_digits(value, _hint_uncertainty(rep, h), 10))}" \
            if value is not None else ""
        code = " + ".join(f"`{part}`" for part in h["yaml"].split("\n"))
        lines.append(f"- branch {h['branch']}, {h['kind']} #{h['index']}{at}: {h['what']}: "
                     f"{code}")
    return [*lines, ""]


def _hint_uncertainty(rep: dict[str, Any], hint: dict[str, Any]) -> float | None:
    """The uncertainty of the continued parameter at the event a ``continue_from_here`` hint
    starts from (its ``location_uncertainty``), or None."""
    branch = next((b for b in rep["branches"] if b["id"] == hint["branch"]), None)
    evs = [e for e in (branch or {}).get("events", []) if e["kind"] == hint["kind"]]
    restart = next((b for b in (rep.get("restart") or {}).get("branches", [])
                    if b["id"] == hint["branch"]), {})
    if hint["index"] >= len(evs) or "parameter" not in restart:
        return None
    return (evs[hint["index"]].get("location_uncertainty") or {}).get(restart["parameter"])


def _table(rows: list[dict[str, Any]]) -> list[str]:
    """A markdown table of records, with the union of their keys as columns (first seen
    first)."""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    return (["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
            + ["| " + " | ".join(_fmt(r.get(c), 12) for c in keys) + " |" for r in rows])


def _header_lines(rep: dict[str, Any]) -> list[str]:
    """The title, the case's description, the problem and its window, the system's facts and
    the warnings."""
    lines = [f"# Bifurcation report: {rep['case']['name']}", ""]
    if rep["case"].get("description"):
        lines += [rep["case"]["description"].strip(), ""]
    internal = rep["continuation"]["parameter"]
    window = [_fmt(w) for w in rep["continuation"]["window"]]
    given = (rep["case"].get("input") or {}).get("continuation") or {}
    name = given.get("parameter") or internal
    if name != internal:  # continued in the case's quantity, the problem's own one inside
        text = (f"continuation parameter `{name}` in window "
                f"{[_fmt(given.get('min')), _fmt(given.get('max'))]} (the problem's own "
                f"`{internal}` in {window})")
    else:
        text = f"continuation parameter `{name}` in window {window}"
    lines += [f"Problem: `{rep['problem']}`; {text}.", ""]
    summ = rep.get("problem_summary") or {}
    if summ:
        lines += ["## System", ""]
        for k, v in summ.items():
            if isinstance(v, list):
                v = ", ".join(_fmt(float(x)) if isinstance(x, float) else str(x) for x in v)
            lines.append(f"- **{k}**: {v}")
        lines.append("")
    if rep.get("warnings"):
        lines += ["## Warnings", ""] + [f"- {w}" for w in rep["warnings"]] + [""]
    return lines


def _branch_lines(rep: dict[str, Any]) -> list[str]:
    """The table of branches (with the chart moves and the tree of a diagram)."""
    t = rep["timings"]
    n_failed = sum(1 for b in rep["branches"] if b["n_points"] == 0)
    lines = ["## Branches", "",
             f"{len(rep['branches'])} branches, {t.get('n_points')} points, "
             f"{_fmt(t.get('total_s'), 3)} s."
             + (f" **{n_failed} start(s) failed**: their rows give the reason."
                if n_failed else ""), "",
             "| id | label | born at | points | admissible points | parameter range | "
             "termination |",
             "|---|---|---|---|---|---|---|"]
    for b in rep["branches"]:
        pr = b["parameter_range"]
        rng = f"{_fmt(pr[0])} .. {_fmt(pr[1])}" if pr else "-"
        lines.append(f"| {b['id']} | {b['label']} | {link_text(b.get('parent'))} | "
                     f"{b['n_points']} | {b['admissible_points']} | {rng} | "
                     f"{b['termination']} |")
    moves = [(b["id"], m) for b in rep["branches"] for m in b.get("info", {}).get(
        "chart_moves", [])]
    if moves:
        lines += ["", "Unknowns moved to another chart on the way (the same orbits; each "
                  "row of the CSV is in the chart its `section_*` column names, and a "
                  "restart reads it there):", ""]
        lines += [f"- branch {i}: {m}" for i, m in moves]
    return [*lines, "", *_family_lines(rep), *_impact_lines(rep), *_tree_lines(rep)]


def _impact_lines(rep: dict[str, Any]) -> list[str]:
    """Impacts per period of each branch of an impacting system (``report.json``'s
    ``branches[i].impacts_per_period``), the orbits with several marked."""
    rows = [b for b in rep["branches"] if b.get("impacts_per_period")]
    if not any(max(b["impacts_per_period"]) > 1 for b in rows):
        return []
    lines = ["## Impacts per period", "",
             "Impacts in one period of each branch's orbits (over the whole period: a family "
             "born at a period doubling of a period-k orbit has period 2k base periods). "
             "Paper 000 assumes one impact per period; branches with **several** go beyond "
             "it.", "", "| branch | period (base periods) | impacts per period | |",
             "|---|---|---|---|"]
    for b in rows:
        n = b["impacts_per_period"]
        text = ", ".join(str(k) for k in n)
        mark = "**several impacts per period**" if max(n) > 1 else "one impact per period"
        if len(n) > 1:
            mark += " (the count changes along the branch)"
        lines.append(f"| {b['id']} | {int(b['info'].get('period_multiple', 1))} | {text} | "
                     f"{mark} |")
    return [*lines, ""]


def _event_lines(rep: dict[str, Any]) -> list[str]:
    """The table of events, read in increasing parameter where every event knows its
    direction, and what each kind means."""
    cols = list(rep.get("event_columns") or [])
    par = rep["continuation"].get("case_parameter") or rep["continuation"]["parameter"]
    shown = [(b["id"], e) for b in rep["branches"] for e in b["events"]
             if e["kind"] != "endpoint"]
    kinds = {e["kind"] for _, e in shown}
    # oriented: every event knows the direction of the parameter (report.json written with
    # annotate_parameter_directions); otherwise the changes stay in the continuation order
    oriented = all("parameter_direction" in e for _, e in shown)
    lines = ["", "## Events", "",
             "| branch | kind | " + " | ".join(cols) + " | max abs multiplier | "
             + (f"change (increasing {par})" if oriented else "change (as continued)")
             + " | detail |",
             "|---|---|" + "---|" * len(cols) + "---|---|---|"]
    for bid, e in shown:
        e = in_parameter_order(e)
        mults = e.get("multipliers") or []
        mam = max((abs(complex(*m)) for m in mults), default=None)
        # each value to the digits its location's accuracy supports (report.json: all)
        unc = e.get("location_uncertainty") or {}
        vals = " | ".join(_fmt(e.get(c), supported_digits(e.get(c), unc.get(c))) for c in cols)
        # an event of a branch born at another point links to it
        branch = f"{bid} (from {link_text(e['parent'])})" if e.get("parent") else f"{bid}"
        hidden = " (a window inside one step: found from the Krein signs of its ends)" \
            if e.get("hidden_in_step") else ""
        lines.append(f"| {branch} | {e['kind']} | {vals} | {_fmt(mam)} | "
                     f"{change_text(e)} | {e['detail']}{hidden} |")
    if shown and oriented:
        lines += ["", f"Every change (before -> after, in the change column and in the detail) "
                  f"reads in the direction of increasing `{par}`, whichever way the branch was "
                  f"continued: on a part of a branch continued towards decreasing `{par}` the "
                  "recorded order is swapped (`report.json` keeps the continuation order, with "
                  "`parameter_direction` -1). Where the branch turns back in the parameter (a "
                  "fold, or a grazing at which it turns) the change is in the continuation "
                  "order, marked \"as continued\"."]
    elif shown:
        lines += ["", "Every change (before -> after) reads in the direction the branch was "
                  "continued."]
    lines += ["", "### What the events mean", ""]
    meaning = {**MEANING, **(rep.get("event_kinds") or {})}
    lines += [f"- **{k}**: {meaning.get(k, '(meaning not declared)')}"
              for k in sorted(kinds | {"endpoint"})]
    return lines


def _extras_lines(rep: dict[str, Any]) -> list[str]:
    """The problem's own results, the figures and the data files."""
    lines: list[str] = []
    extras = rep.get("problem_results") or {}
    if extras:
        lines += ["", "## Problem-specific results", ""]
        for k, v in extras.items():
            if isinstance(v, list) and v and all(isinstance(r, dict) for r in v):
                lines += [f"### {k}", "", *_table(v), ""]
            else:
                lines.append(f"- **{k}**: {v}")
    if rep.get("figures"):
        lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in rep["figures"]]
    lines += ["", "Data: " + ", ".join(f"[{b['csv']}]({b['csv']})" for b in rep["branches"])
              + ", [report.json](report.json).", ""]
    return lines


def markdown(rep: dict[str, Any]) -> str:
    """``report.md`` from the content of ``report.json``."""
    lines = [*_header_lines(rep), *_branch_lines(rep), *_event_lines(rep), "",
             *_continue_lines(rep), *_extras_lines(rep)]
    return "\n".join(lines)
