"""Located events on a figure: every kind drawn with its declared marker and named in words
(:mod:`nsm_continuation.figures.styles`, a family's own styles from
:meth:`~nsm_continuation.core.presentation.Presentation.event_styles`), and the window where
events crowd together (:func:`cluster_window`), which the branch diagram repeats as a zoom.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.records import Branch
from nsm_continuation.figures.styles import EventStyle, event_style

#: two markers closer than this in both directions (fractions of the axes) overlap
OVERLAP = (0.012, 0.025)
#: events closer than this (fractions of the axes) are at one point
COINCIDE = 1e-4
#: events closer than this horizontally (fraction of the axis) belong to one crowd
CROWDED = 0.03
#: a crowd is zoomed when it spans at most this fraction of the horizontal axis (a wider one
#: is readable as it is)
CROWD_SPAN = 0.25


@dataclass(frozen=True)
class Located:
    """One event where a figure draws it: its kind, style and coordinates."""

    kind: str
    style: EventStyle
    x: float
    y: float
    #: on a phantom (not admissible) stretch of its branch: the branch's points on both sides
    #: of the event (on its one side at an end of the branch) are not admissible
    phantom: bool = False


def on_phantom(br: Branch, s: float) -> bool:
    """Whether the branch ``br`` is phantom on both sides of arclength ``s`` (on its one side
    at an end): the nearest points before and after ``s`` are not admissible. The event's own
    point is not asked (at a grazing its test is zero, to rounding either side)."""
    ss = np.array([p.s for p in br.points], dtype=float)
    tol = 1e-9 * (1.0 + float(np.max(np.abs(ss)))) if ss.size else 0.0
    near = [int(np.argmax(np.where(ss < s - tol, ss, -np.inf))) if (ss < s - tol).any()
            else None,
            int(np.argmin(np.where(ss > s + tol, ss, np.inf))) if (ss > s + tol).any()
            else None]
    sides = [br.points[i] for i in near if i is not None]
    return bool(sides) and not any(p.admissible for p in sides)


def declared_styles(problem: Problem) -> dict[str, EventStyle | None]:
    """The family's own event styles (``Presentation.event_styles``: ``kind -> (marker,
    colour, name)``, or None for the kinds it draws otherwise)."""
    raw = problem.presentation.event_styles()
    return {k: (EventStyle(*v) if v is not None else None) for k, v in raw.items()}


def located(problem: Problem, branches: Sequence[Branch], xk: str, yk: str,
            problems: Mapping[int, Problem] | None = None) -> list[Located]:
    """The events of ``branches`` drawn as markers (kinds with a style: every kind but the
    branch ends and those the family draws otherwise), at their ``(xk, yk)`` values (NaN where
    the event's point lacks one). ``problems``: the problem of a branch made during the run
    (a switched branch), by branch id."""
    out = []
    for br in branches:
        pr = (problems or {}).get(br.id, problem)
        styles = declared_styles(pr)
        for ev in br.events:
            st = event_style(ev.kind, styles)
            if st is not None:
                out.append(Located(ev.kind, st, float(ev.point.value(xk, pr.variables)),
                                   float(ev.point.value(yk, pr.variables)),
                                   on_phantom(br, ev.point.s)))
    return out


def declutter(events: Sequence[Located]) -> tuple[list[Located], dict[str, int]]:
    """The events a crowded diagram marks, and the counts of those it does not: the events on
    phantom stretches of their branches (:attr:`Located.phantom`; Legrand et al. 2017,
    Fig. 3.2, marks none there), and the hollow rings (stability changes) around a filled
    marker at their point (the branch's line changes style there)."""
    kept = [e for e in events if not e.phantom]
    filled = [e for e in kept if e.style.filled]
    ringed = [e for e in kept if not e.style.filled and any(
        np.isclose(f.x, e.x, rtol=1e-9, atol=0.0) and np.isclose(f.y, e.y, rtol=1e-9, atol=0.0)
        for f in filled)]
    counts = {"on phantom orbits": len(events) - len(kept)}
    for e in ringed:
        name = f"{e.style.name}s at a marker\nof another kind"
        counts[name] = counts.get(name, 0) + 1
    return [e for e in kept if e not in ringed], {k: v for k, v in counts.items() if v}


def drawable(events: Sequence[Located], y_max: float = np.inf, log: bool = False
             ) -> tuple[list[Located], list[Located]]:
    """``(drawn, left out)``: events with finite coordinates at or below ``y_max`` (and a
    positive ordinate on a log axis) are drawn; the others are listed in the report only."""
    ok, out = [], []
    for e in events:
        inside = np.isfinite(e.x) and np.isfinite(e.y) and e.y <= y_max and (e.y > 0 or not log)
        (ok if inside else out).append(e)
    return ok, out


def draw_located(ax: Axes, events: Sequence[Located], size: float = 6.0) -> None:
    """The events on ``ax``, labelled with their kind's name once (hollow kinds as larger
    rings around the point). Events of other kinds at the point of one drawn before are
    drawn smaller, on top: both markers are seen."""
    rank = []
    for i, e in enumerate(events):
        rank.append(sum(1 for f in events[:i] if f.kind != e.kind and f.style.filled
                        and np.isclose(f.x, e.x, rtol=1e-9, atol=0.0)
                        and np.isclose(f.y, e.y, rtol=1e-9, atol=0.0)))
    named: set[str] = set()
    for kind, r in dict.fromkeys((e.kind, k) for e, k in zip(events, rank, strict=True)):
        pts = [e for e, k in zip(events, rank, strict=True) if e.kind == kind and k == r]
        st = pts[0].style
        ms = max(size * (1.0 - 0.3 * r), 2.5)
        face = {"mec": "k", "mew": 0.5, "ms": ms, "zorder": 5 + r} if st.filled else {
            "mfc": "none", "mec": st.colour, "mew": 0.7, "ms": size + 3, "zorder": 9}
        ax.plot([e.x for e in pts], [e.y for e in pts], ls="", marker=st.marker,
                color=st.colour, label="_nolegend_" if kind in named else st.name, **face)
        named.add(kind)


def draw_events(ax: Axes, problem: Problem, branches: Sequence[Branch], xk: str, yk: str,
                problems: Mapping[int, Problem] | None = None, y_max: float = np.inf,
                log: bool = False) -> tuple[list[Located], list[Located]]:
    """Every event of ``branches`` that can be drawn at ``(xk, yk)`` on ``ax``
    (:func:`located`, :func:`drawable`): ``(drawn, left out)``."""
    shown, left = drawable(located(problem, branches, xk, yk, problems), y_max, log)
    draw_located(ax, shown)
    return shown, left


def _fractions(v: np.ndarray, lo: float, hi: float, log: bool) -> np.ndarray:
    if log:
        v, lo, hi = np.log10(v), np.log10(lo), np.log10(hi)
    return (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)


def _overlapping(pts: Sequence[Located], x_range: tuple[float, float],
                 y_range: tuple[float, float], ylog: bool) -> np.ndarray:
    """For each of ``pts``, whether its marker overlaps another's (:data:`OVERLAP`, axes
    fractions; two at one point, :data:`COINCIDE`, do not count: events located at one point
    stay together in any zoom, the markers of the second kind drawn smaller instead)."""
    if len(pts) < 2 or not x_range[1] > x_range[0]:
        return np.zeros(len(pts), dtype=bool)
    fx = _fractions(np.array([e.x for e in pts]), *x_range, False)
    fy = _fractions(np.array([e.y for e in pts]), *y_range, ylog)
    dx, dy = np.abs(fx[:, None] - fx[None, :]), np.abs(fy[:, None] - fy[None, :])
    same = (dx < COINCIDE) & (dy < COINCIDE)
    close = (dx < OVERLAP[0]) & (dy < OVERLAP[1]) & ~same
    np.fill_diagonal(close, False)
    return close.any(axis=1)


def markers_overlap(events: Sequence[Located], x_range: tuple[float, float],
                    y_range: tuple[float, float], ylog: bool = False) -> bool:
    """Whether two filled markers of ``events`` overlap on axes over these ranges."""
    return bool(_overlapping([e for e in events if e.style.filled], x_range, y_range,
                             ylog).any())


def cluster_window(events: Sequence[Located], x_range: tuple[float, float],
                   y_range: tuple[float, float], ylog: bool = False
                   ) -> tuple[float, float] | None:
    """The horizontal window where event markers overlap: if two filled markers lie within
    :data:`OVERLAP` of each other (axes fractions; two at one point, :data:`COINCIDE`, do
    not count: no zoom parts them), the events joined to them by horizontal
    gaps under :data:`CROWDED` form a crowd; the crowd with most overlapping markers, if it
    spans at most :data:`CROWD_SPAN` of the axis, padded by a third of its span (at least
    1 % of the axis). None when no markers overlap."""
    pts = [e for e in events if e.style.filled]
    overlapping = _overlapping(pts, x_range, y_range, ylog)
    if not overlapping.any():
        return None
    x = np.array([e.x for e in pts])
    fx = _fractions(x, *x_range, False)
    order = np.argsort(fx)
    crowds: list[list[int]] = [[int(order[0])]]
    for a, b in zip(order, order[1:], strict=False):
        if fx[b] - fx[a] < CROWDED:
            crowds[-1].append(int(b))
        else:
            crowds.append([int(b)])
    crowd = max(crowds, key=lambda c: int(overlapping[c].sum()))
    lo, hi = float(x[crowd].min()), float(x[crowd].max())
    width = x_range[1] - x_range[0]
    if hi - lo > CROWD_SPAN * width:
        return None
    pad = max((hi - lo) / 3.0, 0.01 * width)
    return lo - pad, hi + pad


def values_in(xs: Any, ys: Any, window: tuple[float, float]) -> np.ndarray:
    """The finite ``ys`` whose ``xs`` lie in ``window``."""
    xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
    keep = (xs >= window[0]) & (xs <= window[1]) & np.isfinite(ys)
    return ys[keep]


__all__ = ["Located", "cluster_window", "declared_styles", "declutter", "draw_events",
           "draw_located", "drawable", "located", "markers_overlap", "on_phantom",
           "values_in"]
