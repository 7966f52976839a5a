"""What one simulation of an impacting system is given and gives back.

:class:`SimOptions` (tolerances, the chatter map's order and tolerance, guards),
:class:`SimulationError` (a simulation that cannot go on, with its reason), :class:`SimEvent` (an
event met on the way: an impact, a completed chattering sequence, a release, a near approach,
the section) and :class:`SimResult` (the end state with its sensitivities ``J = dX/dX0`` and
``J_t = dt/dX0``, the chain (40) of flows and saltation matrices (43), the events, the sticking
intervals and what is derived from them: the signature of the event sequence, the sticking time,
the signed grazing margin). The simulation itself is :class:`.simulate.Simulator`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


class SimulationError(RuntimeError):
    """A simulation that cannot go on; ``reason`` is recorded by callers (never a hang)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass
class SimOptions:
    """Tolerances and guards of one simulation."""

    rtol: float = 1e-10
    atol: float = 1e-12
    h_init: float = 1e-3
    h_max: float = np.inf
    #: tolerance on the chatter map's estimated error (scaled by ``1 + |x|``, sec. 3.4)
    chatter_tol: float = 1e-10
    #: 1: eqs. (30)-(31); 2: the improved estimate of eq. (35); 3: one more extrapolation level
    chatter_order: int = 3
    #: "map": the chatter map; "cut": the naive baseline that stops the sequence after
    #: ``cut_after`` impacts by a perfectly plastic impact (no map)
    chatter: str = "map"
    cut_after: int = 20
    #: a chattering sequence longer than this without meeting the tolerance is a failure
    max_chatter_impacts: int = 2000
    max_events: int = 200_000
    #: wall-clock guard (seconds) on every simulation
    wall_time: float = 30.0
    #: simulated-time guard: a return to a section that takes longer fails (e.g. an orbit
    #: trapped at a stable equilibrium on the sticking surface)
    max_time: float | None = None
    sensitivities: bool = True
    #: the step error test covers the sensitivities ``J`` too (CVODES' ``errconS``,
    #: :mod:`.step_error`), so that the multipliers are as accurate as
    #: the state at the same tolerances
    sensitivity_error: bool = True
    record: bool = False
    #: validate r and W at every impact (sec. 2.3-2.4)
    validate: bool = True
    #: chain the Runge-Kutta steps' sensitivities ``J <- J_step J`` by a sparse product
    #: (True), a dense one (False), or by the rule of :mod:`.sparse_steps` (None: sparse for
    #: large systems whose step Jacobian is sparse, dense below, so that small systems'
    #: numbers stay those of the dense product)
    sparse_products: bool | None = None


@dataclass
class SimEvent:
    """An event met by a simulation: its kind, time, state (without freed parameters), what
    the transition recorded, and the index of the surface it happened on."""

    kind: str
    t: float
    x: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)
    surface: int = 0


@dataclass
class SimResult:
    X: np.ndarray
    t: float
    J: np.ndarray | None
    Jt: np.ndarray | None
    events: list[SimEvent]
    state: str
    sticking_intervals: list[tuple[float, float]]
    chatter_counts: list[int]
    n_impacts: int
    min_impact_velocity: float
    grazing_margin: float
    chatter_errors: list[float]
    trajectory: list[tuple[float, np.ndarray]] | None
    n_steps: int
    ended_by: str
    #: ``(n, 2)``: minimum and maximum of each state component over the steps whose extremes
    #: were found as they were taken (the Runge-Kutta steps, the step ends and the events);
    #: :attr:`extremes` adds those of ``deferred_extremes``
    bounds: np.ndarray | None = None
    #: signed grazing margin of every near approach (its ``H_min > 0``) and of every impact
    #: with ``a > 0`` (``-v^2 / (2a) < 0``: where the free flight continued through the wall
    #: would turn), in time order; each crosses zero where that approach becomes an impact
    grazing_margins: list[float] = field(default_factory=list)
    #: the surface of each grazing margin (index into the system's surfaces)
    grazing_surfaces: list[int] = field(default_factory=list)
    #: the surfaces' names of a system with several (None: one surface)
    surface_names: list[str] | None = None
    #: steps of an exact flow whose interior extremes are found when first asked for
    #: (:attr:`extremes`): ``(extremes, Y0, dt)`` with ``extremes(Y0, dt) -> (lo, hi)``
    #: (:meth:`.linear_flow.ExactStep.extremes`). A Newton iteration's simulations that no one
    #: reports never pay for them.
    deferred_extremes: list[tuple[Any, np.ndarray, float]] = field(default_factory=list,
                                                                   repr=False)

    @property
    def extremes(self) -> np.ndarray | None:
        """``(n, 2)``: minimum and maximum of each state component over the simulated
        trajectory (step ends, events and the interior extrema of each step: of its cubic
        Hermite interpolant for a Runge-Kutta step, :func:`.modal_sums.grid_extremes` for an
        exact one), those of the deferred steps merged in on first use."""
        if self.deferred_extremes and self.bounds is not None:
            lo, hi = self.bounds[:, 0].copy(), self.bounds[:, 1].copy()
            for extremes, Y0, dt in self.deferred_extremes:
                a, b = extremes(Y0, dt)
                np.minimum(lo, a, out=lo)
                np.maximum(hi, b, out=hi)
            self.bounds = np.column_stack([lo, hi])
            self.deferred_extremes = []
        return self.bounds

    def closest_margin(self) -> float:
        """The signed grazing margin closest to zero (of a near approach, ``H_min > 0``, or of
        a decelerating impact, ``-v^2/(2a) < 0``): the ``grazing_margin`` of a point; NaN if
        there is none."""
        m = np.asarray(self.grazing_margins, dtype=float)
        m = m[np.isfinite(m)]
        return float(m[int(np.argmin(np.abs(m)))]) if m.size else float("nan")

    def grazing_function(self, separation: float = 4.0) -> float:
        """The signed grazing margin closest to zero (:meth:`closest_margin`), a continuous
        function of the orbit that vanishes at a grazing (smooth in the parameter: ``-v^2/(2a)``
        is linear in the depth where ``v`` has the square-root singularity). NaN if there is
        none, or if a margin of the opposite sign lies within ``separation`` times its distance
        to zero (the closest one could then switch sides without any grazing: no event is
        raised on it)."""
        g = self.closest_margin()
        if not np.isfinite(g):
            return g
        m = np.asarray(self.grazing_margins, dtype=float)
        m = m[np.isfinite(m)]
        rivals = m[np.sign(m) != np.sign(g)]
        if rivals.size and np.min(np.abs(rivals)) < separation * abs(g):
            return float("nan")
        return g

    def grazing_surface(self) -> str | None:
        """Name of the surface whose grazing margin is closest to zero (the margin of
        :meth:`grazing_function`); None for a one-surface system or without margins."""
        if self.surface_names is None or not self.grazing_margins:
            return None
        m = np.abs(np.asarray(self.grazing_margins, dtype=float))
        m[~np.isfinite(m)] = np.inf
        return self.surface_names[self.grazing_surfaces[int(np.argmin(m))]]

    @property
    def sticking_time(self) -> float:
        return float(sum(b - a for a, b in self.sticking_intervals))

    @property
    def n_sticking_phases(self) -> int:
        """Sticking phases: the intervals, one that began at the start and one that lasts to
        the end counted once (on a periodic orbit they are one phase, cut by the section)."""
        iv = self.sticking_intervals
        wraps = len(iv) > 1 and iv[0][0] == 0.0 and iv[-1][1] == self.t
        return len(iv) - int(wraps)

    @property
    def n_impacts_before_chatter(self) -> int:
        return int(sum(self.chatter_counts))

    @property
    def signature(self) -> str:
        """The sequence of events over the simulated time, in a structural notation that does
        not depend on tolerances: ``I`` an impact (each impact of a chattering sequence that
        breaks off counts), ``C`` a chattering sequence completed by the chatter map (an
        accumulation of impacts ending in sticking: how many impacts were resolved before the
        map is a numerical choice, ``chatter_counts``), ``S`` a release from sticking.

        Impacts just before a completed sequence are part of it (``IIC`` is ``C``).
        E.g. ``I``: one impact per period; ``II``: two; ``CS``: complete chattering, sticking
        and release (Fig. 2); ``-``: no event (a free orbit). With several surfaces each symbol
        names its surface, separated by spaces: ``I(upper) I(lower)``."""
        out: list[tuple[str, int]] = []
        for ev in self.events:
            if ev.kind == "impact":
                out.append(("I", ev.surface))
            elif ev.kind in ("chatter", "chatter_broken"):
                # the sequence began with the impact recorded last
                if out and out[-1] == ("I", ev.surface):
                    out.pop()
                if ev.kind == "chatter":
                    out.append(("C", ev.surface))
                else:
                    out.extend([("I", ev.surface)] * int(ev.info["impacts"]))
            elif ev.kind == "release":
                out.append(("S", ev.surface))
        # impacts resolved one by one just before an accumulation belong to it: whether the
        # first of them already starts the geometric sequence (a < 0 at it) or bounces once
        # more (a > 0) is no structural change of the orbit (it happens smoothly, at a = 0)
        merged: list[tuple[str, int]] = []
        for sym, surf in out:
            if sym == "C":
                while merged and merged[-1] == ("I", surf):
                    merged.pop()
            merged.append((sym, surf))
        if not merged:
            return "-"
        if self.surface_names is None:
            return "".join(sym for sym, _ in merged)
        return " ".join(f"{sym}({self.surface_names[surf]})" for sym, surf in merged)
