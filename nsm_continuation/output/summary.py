"""A run at a glance, for a notebook or a terminal: its branches (points, the range of the
continued parameter, how each ended) and its special points (every located event with its
branch, parameter value and stability), as text (``repr``), HTML and Markdown
(:class:`nsm_continuation.api.Result`'s ``_repr_html_`` / ``_repr_markdown_``), after
BifurcationKit's ``show(br)``."""

from __future__ import annotations

import html
import math
from typing import Any

from nsm_continuation.output.files import termination_text
from nsm_continuation.runs.result import RunResult

#: rows of the special-points table shown (the rest are counted)
MAX_EVENTS = 30


def parameter_name(res: RunResult) -> str:
    """The continued parameter as the case names it (``omega`` for the chain continued in
    its frequency, whose unknown is the period ``T``)."""
    return res.case.continuation.parameter or res.problem.parameter


def _value(res: RunResult, point: Any, name: str) -> float:
    value = point.value(name, list(res.problem.variables))
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def _num(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.6g}"


def _stable(point: Any) -> str:
    if not point.admissible:
        return "phantom"
    return {None: "-", True: "yes", False: "no"}[point.stable]


def headline(res: RunResult, source: str | None = None) -> str:
    """``Result of <case> (problem <name>): n branches, n points, n events``."""
    n_points = sum(b.n_points for b in res.branches)
    n_events = sum(len(b.events) for b in res.branches)
    where = f", read from {source}" if source else ""
    return (f"Result of {res.case.name} (problem {res.problem.name}{where}): "
            f"{len(res.branches)} branch{'es' if len(res.branches) != 1 else ''}, "
            f"{n_points} points, {n_events} events")


def branch_rows(res: RunResult) -> list[list[str]]:
    """One row per branch: id, label, points, the parameter's range, how it ended."""
    name = parameter_name(res)
    rows = []
    for b in res.branches:
        values = [_value(res, p, name) for p in b.points]
        finite = [v for v in values if math.isfinite(v)]
        span = f"{_num(min(finite))} .. {_num(max(finite))}" if finite else "-"
        rows.append([str(b.id), b.label, str(b.n_points), span, termination_text(b)])
    return rows


def event_rows(res: RunResult) -> tuple[list[list[str]], int]:
    """The special points (every event, branch ends included), at most :data:`MAX_EVENTS`
    rows, and how many were left out."""
    name = parameter_name(res)
    rows = []
    for b in res.branches:
        for ev in b.events:
            rows.append([str(len(rows)), str(b.id), ev.kind, _num(_value(res, ev.point, name)),
                         _stable(ev.point), ev.detail])
    return rows[:MAX_EVENTS], max(0, len(rows) - MAX_EVENTS)


def _columns(res: RunResult) -> tuple[list[str], list[str]]:
    name = parameter_name(res)
    return (["branch", "label", "points", name, "ended"],
            ["#", "branch", "kind", name, "stable", "detail"])


def _clip(text: str, width: int) -> str:
    return text if len(text) <= width else text[:width - 3] + "..."


def _text_table(head: list[str], rows: list[list[str]], widths: list[int]) -> list[str]:
    cells = [[_clip(c, w) for c, w in zip(r, widths, strict=True)] for r in [head, *rows]]
    size = [max(len(r[j]) for r in cells) for j in range(len(head))]
    return ["  " + "  ".join(c.ljust(size[j]) for j, c in enumerate(r)).rstrip()
            for r in cells]


def text(res: RunResult, source: str | None = None) -> str:
    """The summary as plain text (``repr`` of a result)."""
    bhead, ehead = _columns(res)
    lines = [headline(res, source)]
    lines += _text_table(bhead, branch_rows(res), [6, 40, 7, 30, 60])
    rows, more = event_rows(res)
    if rows:
        lines.append("special points:")
        lines += _text_table(ehead, rows, [4, 6, 18, 14, 8, 60])
    if more:
        lines.append(f"  ... and {more} more (Result.events)")
    return "\n".join(lines)


def _html_table(head: list[str], rows: list[list[str]]) -> str:
    th = "".join(f"<th>{html.escape(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
                   for r in rows)
    return f"<table><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"


def as_html(res: RunResult, source: str | None = None) -> str:
    """The summary as HTML (a notebook's display of a result)."""
    bhead, ehead = _columns(res)
    rows, more = event_rows(res)
    parts = [f"<p><b>{html.escape(headline(res, source))}</b></p>",
             _html_table(bhead, branch_rows(res))]
    if rows:
        parts += ["<p>Special points</p>", _html_table(ehead, rows)]
    if more:
        parts.append(f"<p>... and {more} more (<code>Result.events</code>)</p>")
    return "\n".join(parts)


def _md_table(head: list[str], rows: list[list[str]]) -> list[str]:
    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return [line(head), "|" + "---|" * len(head), *(line(r) for r in rows)]


def as_markdown(res: RunResult, source: str | None = None) -> str:
    """The summary as Markdown."""
    bhead, ehead = _columns(res)
    rows, more = event_rows(res)
    lines = [f"**{headline(res, source)}**", "", *_md_table(bhead, branch_rows(res))]
    if rows:
        lines += ["", "Special points:", "", *_md_table(ehead, rows)]
    if more:
        lines += ["", f"... and {more} more (`Result.events`)"]
    return "\n".join(lines)


__all__ = ["as_html", "as_markdown", "text"]
