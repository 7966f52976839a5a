"""``report.md``: the human bifurcation report of a run (built from ``report.json``)."""

from __future__ import annotations

from typing import Any

MEANING = {
    "fold": "a Floquet multiplier pair reaches +1 (or a limit point of the parameter); in a "
            "conservative family it signals a bifurcating family of orbits",
    "period_doubling": "a multiplier passes through -1: a family of period-2T orbits bifurcates",
    "neimark_sacker": "a complex pair leaves the unit circle away from +-1 (for a conservative "
                      "system, after a Krein collision): quasi-periodic motion nearby",
    "branch_point": "two solution curves cross (det of the bordered Jacobian changes sign)",
    "stability_change": "the number of multipliers outside the unit circle becomes zero or "
                        "non-zero",
    "grazing": "an admissibility test function vanishes: the orbit touches the obstacle "
               "tangentially (nonlinear grazing) or leaves it with zero velocity (linear "
               "grazing); beyond it the orbit is a phantom",
    "endpoint": "end of the computed branch (bound reached or numerical termination)",
    "asymptote": "the energy grows without bound as the frequency approaches a limit (estimated "
                 "from the last points)",
    "pattern_change": "the phase pattern of the orbit changes character along the branch",
    "sticking_lost": "the sticking time tends to zero: complete chattering turns into "
                     "incomplete chattering (the branch of orbits with sticking ends; located "
                     "where the sticking time reaches its floor, extrapolated to zero)",
    "impact_sequence_change": "the sequence of events over one period changes (an impact is "
                              "gained or lost, or the number of impacts resolved before the "
                              "chatter map changes)",
    "homoclinic_approach": "the period grows without bound: the orbit approaches a homoclinic "
                           "orbit of a saddle (limit parameter from a fit T ~ -ln|p - p*|/mu)",
}


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
    cols = rep.get("event_columns") or ["omega", "T", "energy"]
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
    lines += [f"- **{k}**: {MEANING[k]}" for k in sorted(kinds | {"endpoint"})]
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
