"""``report.md``: the human bifurcation report of a run (built from ``report.json``)."""

from __future__ import annotations

from typing import Any

from .records import CORE_EVENT_KINDS

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


def markdown(rep: dict[str, Any]) -> str:
    lines = [f"# Bifurcation report: {rep['case']['name']}", ""]
    if rep["case"].get("description"):
        lines += [rep["case"]["description"].strip(), ""]
    lines += [f"Problem: `{rep['problem']}`; continuation parameter "
              f"`{rep['continuation']['parameter']}` in window "
              f"{[_fmt(w) for w in rep['continuation']['window']]}.", ""]
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
    t = rep["timings"]
    n_failed = sum(1 for b in rep["branches"] if b["n_points"] == 0)
    lines += ["## Branches", "",
              f"{len(rep['branches'])} branches, {t.get('n_points')} points, "
              f"{_fmt(t.get('total_s'), 3)} s."
              + (f" **{n_failed} start(s) failed**: their rows give the reason."
                 if n_failed else ""), "",
              "| id | label | points | admissible points | parameter range | termination |",
              "|---|---|---|---|---|---|"]
    for b in rep["branches"]:
        pr = b["parameter_range"]
        rng = f"{_fmt(pr[0])} .. {_fmt(pr[1])}" if pr else "-"
        lines.append(f"| {b['id']} | {b['label']} | {b['n_points']} | {b['admissible_points']}"
                     f" | {rng} | {b['termination']} |")
    cols = list(rep.get("event_columns") or [])
    lines += ["", "## Events", "",
              "| branch | kind | " + " | ".join(cols) + " | max abs multiplier | "
              "stable before -> after | detail |",
              "|---|---|" + "---|" * len(cols) + "---|---|---|"]
    kinds = set()
    for b in rep["branches"]:
        for e in b["events"]:
            if e["kind"] == "endpoint":
                continue
            kinds.add(e["kind"])
            mults = e.get("multipliers") or []
            mam = max((abs(complex(*m)) for m in mults), default=None)
            sb = e.get("stable_before")
            stab = f"{_fmt(sb)} -> {_fmt(e.get('stable_after'))}" if sb is not None else ""
            vals = " | ".join(_fmt(e.get(c), 12) for c in cols)
            lines.append(f"| {b['id']} | {e['kind']} | {vals} | {_fmt(mam)} | "
                         f"{stab} | {e['detail']} |")
    lines += ["", "### What the events mean", ""]
    meaning = {**MEANING, **(rep.get("event_kinds") or {})}
    lines += [f"- **{k}**: {meaning.get(k, '(meaning not declared)')}"
              for k in sorted(kinds | {"endpoint"})]
    extras = rep.get("problem_results") or {}
    if extras:
        lines += ["", "## Problem-specific results", ""]
        for k, v in extras.items():
            if isinstance(v, list) and v and isinstance(v[0], dict):
                keys = list(v[0])
                lines += [f"### {k}", "", "| " + " | ".join(keys) + " |",
                          "|" + "---|" * len(keys)]
                lines += ["| " + " | ".join(_fmt(r.get(c), 12) for c in keys) + " |" for r in v]
                lines.append("")
            else:
                lines.append(f"- **{k}**: {v}")
    if rep.get("figures"):
        lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in rep["figures"]]
    lines += ["", "Data: " + ", ".join(f"[{b['csv']}]({b['csv']})" for b in rep["branches"])
              + ", [report.json](report.json).", ""]
    return "\n".join(lines)
