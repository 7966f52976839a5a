"""Periodic orbits of hybrid shooting problems sampled in time (``Presentation.orbit``).

From the state on the Poincaré section that the unknowns ``y`` describe, the orbit is simulated
again (:class:`~nsm_continuation.hybrid.simulate.Simulator`, the problem's tolerances, no
sensitivities) with its trajectory recorded (``SimOptions.record``): every accepted step end
and the states before and after each event. The step is capped (``h_max = period /``
:data:`SAMPLES_PER_PERIOD`) so that the recorded points draw a smooth curve; the events are
located as in the continuation (the chatter map, sticking and release, sec. 5 of Nordmark &
Piiroinen 2009). Every impact is marked (``impact``, :func:`impact_times`): those resolved one
by one, those of a chattering sequence that breaks off (which the simulator reports together in
one ``chatter_broken`` event) and the one a completed sequence's chatter map replaces, so that
the ``impact`` marks of a period are as many as the derived ``n_impacts``; completed chattering
sequences (the accumulation instant of the chatter map, ``chattering completed``) and releases
from sticking (``release``) are marked too; sticking phases are the intervals. Over
``periods`` periods the simulation goes on from each return (the section coordinate keeps
running, e.g. the upper bar of the pendulum turns ``-2 pi`` per period), so it also shows
whether the orbit is periodic.

What a family presents is declared in its problem module (:class:`OrbitDeclarations`):
``orbit_outputs`` (quantities computed from the state, e.g. the pendulum's lower-mass position
``X, Y`` and velocity ``dY``, Figs. 8-12), ``orbit_labels`` and ``orbit_views``; without them
the signals are the state components and the views the impacting coordinate against time and
its phase portrait.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from nsm_continuation.core.problem import EvaluationError
from nsm_continuation.core.records import OrbitTrace
from nsm_continuation.hybrid.simulate import SimResult, SimulationError, Simulator
from nsm_continuation.hybrid.system import HybridDeclarationError

if TYPE_CHECKING:
    from nsm_continuation.hybrid.problem import HybridShootingProblem

#: largest integration step of the recorded orbit: its period over this
SAMPLES_PER_PERIOD = 1500
#: the mark of each kind of simulator event (kinds not listed are not marked); the impacts are
#: marked from the recorded trajectory (:func:`impact_times`), not from these events
MARKED_EVENTS = {"chatter": "chattering completed", "release": "release"}


class OrbitDeclarations:
    """What a hybrid family's figures show (declared in the family's problem module): the
    views and labels of its orbits, the labels of its parameters."""

    #: the views of :class:`~nsm_continuation.core.records.OrbitTrace` (``time``, ``phase``,
    #: ``manifold``); None: the impacting coordinate against time and its phase portrait
    orbit_views: ClassVar[dict[str, tuple[str, ...]] | None] = None
    #: axis labels of the signals (state names and ``orbit_outputs``); default their names
    orbit_labels: ClassVar[dict[str, str]] = {}
    #: axis labels of the parameters in the branch diagram and the multiplier figures (words
    #: and the paper's symbol in mathtext); default the symbol the name spells, else its words
    #: (:func:`~nsm_continuation.core.symbols.quantity_label`)
    parameter_labels: ClassVar[dict[str, str]] = {}

    def orbit_outputs(self, states: np.ndarray, parameters: dict[str, float]
                      ) -> dict[str, np.ndarray]:
        """Quantities computed from the states (rows of ``states``, the state components in
        the order of ``state_names``) at the parameter values ``parameters``: extra signals
        of the orbit figures. Default none."""
        return {}


def default_views(problem: HybridShootingProblem) -> dict[str, tuple[str, ...]]:
    """The impacting coordinate (else the first state) against time, and its phase portrait
    with its velocity (the state ``n_config`` places after it; else the next state)."""
    h = problem.hybrid
    names = h.state_names
    first = problem.response_coordinate or names[0]
    i = names.index(first)
    j = i + h.n_config if h.n_config is not None and i + h.n_config < h.n else (i + 1) % h.n
    return {"time": (first,), "phase": (first, names[j])}


def views_of(problem: HybridShootingProblem) -> dict[str, tuple[str, ...]]:
    """The views of ``problem``'s orbits: its declared ``orbit_views``, else
    :func:`default_views`."""
    return dict(problem.orbit_views if problem.orbit_views is not None
                else default_views(problem))


def impact_times(run: SimResult) -> list[float]:
    """The instants of every impact of the simulation ``run`` (recorded with
    ``SimOptions.record``), in time order, as many as ``run.n_impacts``: where the recorded
    trajectory jumps (the simulator records the state before and after each event: the state
    changes at one time only through the impact law or a projection onto the sticking
    surface; flight transitions such as a release record it twice unchanged), and the instant
    of each impact that a completed chattering sequence's chatter map replaces (its ``chatter``
    event's ``t``: the state after it is recorded at the accumulation instant
    ``t_complete``)."""
    traj = run.trajectory or []
    out = [float(t1) for (t0, x0), (t1, x1) in zip(traj[:-1], traj[1:], strict=True)
           if t1 == t0 and not np.array_equal(x0, x1)]
    out += [float(ev.t) for ev in run.events
            if ev.kind == "chatter" and "t_complete" in ev.info]
    return sorted(out)


def orbit_trace(problem: HybridShootingProblem, y: np.ndarray, periods: int = 1) -> OrbitTrace:
    """The periodic orbit at ``y`` over ``periods`` periods (see the module docstring).
    Raises :class:`~nsm_continuation.core.problem.EvaluationError` if it cannot be simulated."""
    sh = problem.shooting
    y = np.asarray(y, dtype=float)
    c, sec = sh.c, sh.section
    res = problem.sim(y)
    if res is None:
        raise EvaluationError("simulation: the orbit does not return to the Poincare section")
    opts = replace(sh.sim.o, sensitivities=False, record=True,
                   h_max=float(res.t) / SAMPLES_PER_PERIOD)
    sim = Simulator(c, opts)
    X = sh.x0(y)
    # the parameters (Problem.parameters_block), the lifted ones at their values in y
    block = problem.parameters_block() or {}
    parameters = {**{k: float(v) for k, v in block.items()
                     if isinstance(v, int | float) and not isinstance(v, bool)},
                  **dict(zip(c.free, X[c.n:].tolist(), strict=True))}
    times: list[float] = []
    states: list[np.ndarray] = []
    marks: list[tuple[float, str]] = []
    intervals: list[tuple[float, float, str]] = []
    t0, target = 0.0, sec.value
    # one run per return to the section: a crossing section is met ``crossings`` times a period
    for _ in range(int(periods) * sec.crossings):
        target += sec.shift
        try:
            run = sim.run(X, section=(sec.index, target, sec.direction))
        except (SimulationError, HybridDeclarationError) as exc:
            raise EvaluationError(f"simulation: {exc}") from None
        for t, x in run.trajectory or []:
            times.append(t0 + t)
            states.append(x)
        marks += [(t0 + t, "impact") for t in impact_times(run)]
        for ev in run.events:
            if ev.kind in MARKED_EVENTS:
                te = ev.info.get("t_complete", ev.t)
                marks.append((t0 + float(te), MARKED_EVENTS[ev.kind]))
        intervals += [(t0 + a, t0 + b, "sticking") for a, b in run.sticking_intervals]
        t0 += float(run.t)
        X = run.X
        if sec.shift == 0:
            # a crossing section: the next return starts exactly on it (its round-off on the
            # far side would end the next run where it starts)
            X = X.copy()
            X[sec.index] = sec.value
    marks.sort(key=lambda m: m[0])
    S = np.array(states, dtype=float).reshape(len(states), c.n)
    names = problem.hybrid.state_names
    signals = {name: S[:, k] for k, name in enumerate(names)}
    signals.update(problem.orbit_outputs(S, parameters))
    views = views_of(problem)
    labels = {name: problem.orbit_labels.get(name, name) for name in signals}
    return OrbitTrace(t=np.array(times), period=t0 / int(periods), signals=signals,
                      labels=labels, marks=marks, intervals=intervals, views=views)


__all__ = ["OrbitDeclarations", "default_views", "impact_times", "orbit_trace", "views_of"]
