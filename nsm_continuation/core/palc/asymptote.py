"""Asymptote detection: a branch that runs to infinite amplitude as the parameter approaches
a finite value ``p*`` (e.g. a zero of ``w_N`` of the impacting chain) ends there with an
``asymptote`` event instead of spending every remaining point on the way
(:func:`~nsm_continuation.core.roots.pole_estimate` extrapolates ``p*``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from nsm_continuation.core.palc.part import EnginePart
from nsm_continuation.core.records import Event, Point
from nsm_continuation.core.roots import pole_estimate

if TYPE_CHECKING:
    from nsm_continuation.core.palc.engine import ContinuationEngine

#: asymptote detection (:meth:`AsymptoteMonitor.check`): over the last ASYMPTOTE_POINTS points
#: a monitored quantity fits ``|p - p*|^(-k)``, and it has grown ASYMPTOTE_GROWTH times along
#: the half-branch
ASYMPTOTE_POINTS = 6
ASYMPTOTE_GROWTH = 100.0


class AsymptoteMonitor(EnginePart):
    """Watches the monitored quantities of a half-branch for growth like ``|p - p*|^(-k)``."""

    def __init__(self, engine: ContinuationEngine) -> None:
        super().__init__(engine)
        #: running minimum of each monitored quantity along the current half-branch
        self._monitor_min: dict[str, float] = {}

    def begin(self) -> None:
        """A new half-branch: the running minima start again."""
        self._monitor_min = {}

    def check(self, pts: list[Point]) -> Event | None:
        """An ``asymptote`` event at the last point when a monitored quantity grows like
        ``|p - p*|^(-k)``: the branch runs to infinite amplitude as the parameter approaches
        ``p*`` (e.g. a zero of ``w_N`` of the impacting chain) and would spend every remaining
        point there. ``p*`` is extrapolated by :func:`~nsm_continuation.core.roots.pole_estimate`.

        Monitored: ``|y|`` (the unknowns without the parameter) and the derived quantities
        named by the problem's asymptote monitors (default the energy). The estimate
        must hold on the last ``ASYMPTOTE_POINTS`` points and on those ending three points
        earlier (same ``p*`` within a tenth of the remaining distance), and the quantity must
        have grown ``ASYMPTOTE_GROWTH`` times along the half-branch. A safety net: a user bound
        on a derived quantity (``max_energy``) ends such a branch itself, and the detection is
        then off, so a bounded run ends exactly where it is asked to.
        """
        n, lag = ASYMPTOTE_POINTS, 3
        if len(pts) < n + lag or any(hi is not None
                                     for _, hi in self.settings.derived_bounds.values()):
            return None
        keep = np.arange(len(pts[-1].y)) != self.ip
        monitors: dict[str, Callable[[Point], float]] = {
            "|y|": lambda p: float(np.linalg.norm(p.y[keep]))}
        for name in self.problem.monitors.asymptote_names:
            if name in pts[-1].derived:
                monitors[name] = lambda p, n_=name: float(p.derived.get(n_, np.nan))
        par = np.array([p.y[self.ip] for p in pts[-(n + lag):]])
        for label, fun in monitors.items():
            q_last = fun(pts[-1])
            # cheap test first: a large growth along the half-branch (running minimum, reset
            # by begin() for each half-branch)
            if label not in self._monitor_min:
                self._monitor_min[label] = min(fun(p) for p in pts)
            q_min = self._monitor_min[label] = min(self._monitor_min[label], q_last)
            if not q_last >= ASYMPTOTE_GROWTH * max(q_min, np.finfo(float).tiny):
                continue
            q = np.array([fun(p) for p in pts[-(n + lag):]])
            est = pole_estimate(par[lag:], q[lag:])
            before = pole_estimate(par[:n], q[:n])
            if est is None or before is None:
                continue
            p_star, k = est["parameter_asymptote"], est["exponent"]
            if abs(p_star - before["parameter_asymptote"]) > 0.1 * abs(p_star - par[-1]):
                continue
            name = self.problem.parameter
            return Event("asymptote", pts[-1],
                         f"{label} grows like |{name} - {name}*|^(-{k:.3g}) without bound: "
                         f"{name}* = {p_star:.10g}",
                         data={**est, "monitor": label})
        return None
