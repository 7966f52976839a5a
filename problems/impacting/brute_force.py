"""Brute-force bifurcation diagrams of the double pendulum (Nordmark & Piiroinen 2009, sec. 6).

An independent cross-check of the continuation: for each parameter value the attractor is
simulated return by return on the Poincaré section ``q1 = pi/2`` (mod ``2 pi``), without
sensitivities, and ``q2`` (wrapped to ``(-pi, pi]``) is recorded at every return after a
transient. The sweep continues the attractor: each value starts from the previous value's final
state. A :class:`~nsm_continuation.hybrid.simulate.SimulationError` is recorded (its reason)
and the value is restarted from the problem's default initial state.

The computation is the generic one of :mod:`nsm_continuation.hybrid.brute_force` (which also
makes these diagrams a YAML case: ``continuation.algorithm: sweep``,
``yaml_cases/pendulum_fig8b_brute_force.yaml``, ``yaml_cases/pendulum_fig9bc_brute_force.yaml``);
this module keeps the pendulum's interface of ``benchmarks/brute_force_pendulum.py``: the
problem built from a dict of parameters, ``q2`` as the recorded coordinate, the simulator's
default options.

Usage::

    from nsm_continuation.problems.impacting.brute_force import brute_force
    out = brute_force("e", np.linspace(0.85, 0.92, 71), {"d": 0.5, "torque": -31.15})
    for e, q2 in out: ...
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

from nsm_continuation.hybrid import brute_force as generic
from nsm_continuation.hybrid.brute_force import (  # noqa: F401 - the module's interface
    TWO_PI,
    ReturnMap,
    n_distinct,
    sequence_period,
    wrap,
)
from nsm_continuation.hybrid.simulate import SimOptions


@dataclass
class SweepPoint(generic.SweepPoint):
    """The recorded attractor at one parameter value (:class:`nsm_continuation.hybrid.
    brute_force.SweepPoint`), its recorded coordinate ``section`` named ``q2``."""

    @property
    def q2(self) -> np.ndarray:
        return self.section


class PendulumSweeper(ReturnMap):
    """Section-to-section simulation of the double pendulum with one parameter lifted into the
    state (compiled once for the whole sweep), ``q2`` recorded; ``options`` default to the
    simulator's (:class:`SimOptions`)."""

    def __init__(self, param_name: str, fixed: dict[str, float], value: float,
                 options: SimOptions | None = None) -> None:
        self.pb = DoublePendulumProblem({**fixed, param_name: value})
        super().__init__(self.pb, param_name, options if options is not None else SimOptions(),
                         coordinate=1)


def sweep(param_name: str, values: Any, fixed: dict[str, float], transient_returns: int = 30,
          recorded_returns: int = 30, options: SimOptions | None = None,
          initial: np.ndarray | None = None, converge_tol: float | None = None,
          max_period: int = 8, max_time: float | None = 1000.0,
          progress: bool = False) -> list[SweepPoint]:
    """Brute-force sweep with the per-return details (see :class:`SweepPoint`):
    :func:`nsm_continuation.hybrid.brute_force.sweep` on the pendulum with ``fixed``
    parameters. ``initial``: state ``(q1, q2, q1dot, q2dot)`` on the section to start the first
    value from (default: the problem's :meth:`default_initial`). ``converge_tol``: if given, the
    transient ends early once the state on the section repeats (period ``p <= max_period``) to
    this relative tolerance, and then only ``max(4 p, 8)`` returns (at most
    ``recorded_returns``) are recorded; otherwise exactly ``transient_returns`` and
    ``recorded_returns`` are simulated. ``max_time``: a return that takes longer is a failure
    (the pendulum at rest)."""
    values = [float(v) for v in np.atleast_1d(values)]
    sw = PendulumSweeper(param_name, fixed, values[0], options)
    pts = generic.sweep(sw, values, transient_returns, recorded_returns, initial, converge_tol,
                        max_period, max_time, progress)
    return [SweepPoint(**vars(p)) for p in pts]


def brute_force(param_name: str, values: Any, fixed: dict[str, float],
                transient_returns: int = 30, recorded_returns: int = 30,
                options: SimOptions | None = None, **kwargs: Any
                ) -> list[tuple[float, np.ndarray]]:
    """``[(value, q2 at the section q1 = pi/2 mod 2 pi, wrapped to (-pi, pi]), ...]``: the
    recorded returns after ``transient_returns`` returns, each value started from the previous
    one's final state (an empty array where the simulation failed twice). ``kwargs``: the
    further options of :func:`sweep`."""
    return [(p.value, p.q2) for p in sweep(param_name, values, fixed, transient_returns,
                                           recorded_returns, options, **kwargs)]
