"""The YAML blocks of a hybrid shooting case: ``parameters.integrator`` and ``start``.

:class:`IntegratorSpec` (the simulator's numerics, :class:`~.simulate.SimOptions`) and
:class:`HybridStartSpec` (a guess on the section, or an initial state simulated over a transient
to a stable orbit; the returns per period; the free parameter of a continuation in the period;
the recorded returns of a brute-force sweep), validated strictly by pydantic.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from nsm_continuation.core.preflight import one_or_many
from nsm_continuation.hybrid.simulate import SimOptions


class IntegratorSpec(BaseModel):
    """``parameters.integrator``: numerics of the hybrid simulator (defaults are the ones the
    speed-accuracy chart in ``benchmarks/bench_chatter.py`` recommends).

    ``method``: ``dop853`` or ``dopri5`` (Runge-Kutta for every field), ``exact`` (the free
    flight by its closed-form flow, :mod:`.linear_flow`, for a system linear between events;
    refused with the reason otherwise) or ``auto`` (``exact`` where it applies and pays:
    from six dynamic state components on, ``AUTO_MIN_DYNAMIC`` in :mod:`.system`, else
    ``dop853``; the report names the flow that ran and why). The default stays ``dop853``:
    the exact flow changes a run's numbers at the integration tolerance, and the bundled
    cases keep theirs; ``auto`` or ``exact`` is chosen in the case
    (``parameters: {integrator: {method: auto}}``)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    #: the free flight's integrator: ``dop853`` or ``dopri5`` (Runge-Kutta), ``exact`` (the
    #: closed-form flow of a system linear between events) or ``auto`` (``exact`` where it
    #: applies and pays, from six dynamic state components on, else ``dop853``)
    method: Literal["dop853", "dopri5", "exact", "auto"] = "dop853"
    #: at least 1e-14: below, the step error test asks for less than the round-off of a step
    rtol: float = Field(1e-10, ge=1e-14, lt=1e-2)
    #: absolute tolerance of the step error test
    atol: float = Field(1e-12, gt=0, lt=1e-2)
    #: the chatter map is applied when its estimated error (scaled by 1 + |x|) is below this
    #: (sec. 5.2)
    chatter_tol: float = Field(1e-10, gt=0, lt=1e-2)
    #: the chatter map's order: 1, eqs. (30)-(31); 2, the improved estimate of eq. (35); 3
    #: and 4, further extrapolation levels
    chatter_order: int = Field(3, ge=1, le=4)
    #: a chattering sequence longer than this without meeting ``chatter_tol`` ends the
    #: simulation (a failure, with its reason)
    max_chatter_impacts: int = Field(2000, ge=2)
    #: wall-clock guard (seconds) on every simulation
    wall_time: float = Field(30.0, gt=0)
    #: a return to the Poincare section taking longer than this (simulated time) fails
    max_return_time: float = Field(1000.0, gt=0)
    #: the step error test covers the sensitivities (the Jacobian of the return, hence the
    #: multipliers) as well as the state (CVODES' ``errconS``); ``false`` controls the state
    #: alone: fewer steps, multipliers in error by far more than ``rtol`` where the state has
    #: little local error (an orbit of constant amplitude)
    sensitivity_error: bool = True

    def options(self, sensitivities: bool = True) -> SimOptions:
        return SimOptions(rtol=self.rtol, atol=self.atol, chatter_tol=self.chatter_tol,
                          max_time=self.max_return_time,
                          chatter_order=self.chatter_order,
                          max_chatter_impacts=self.max_chatter_impacts,
                          wall_time=self.wall_time, sensitivities=sensitivities,
                          sensitivity_error=self.sensitivity_error)


class HybridStartSpec(BaseModel):
    """``start:`` of a hybrid shooting case. ``guess`` gives the section coordinates of a
    periodic orbit; without it the orbit is found by simulation from ``initial`` (a full state,
    default: the problem's) over ``transient`` returns to the section (a stable orbit)."""

    #: strict: ``true`` is not a number, ``"3"`` or ``2.0`` not an integer
    model_config = ConfigDict(extra="forbid", strict=True)
    #: the section coordinates of a periodic orbit (the unknowns by name)
    guess: dict[str, float] | None = None
    #: a full initial state by name (default: the problem's), simulated over
    #: ``transient`` returns to a stable orbit
    initial: dict[str, float] | None = None
    #: returns to the section simulated before the orbit is solved for
    transient: int = Field(40, ge=0)
    #: returns to the section per period (2 for a period-2 orbit)
    returns: int = Field(1, ge=1)
    #: which way along ``continuation.parameter`` the branch is followed
    direction: Literal["both", "increase", "decrease"] = "both"
    #: the branch's label in the report
    label: str | None = None
    #: with ``continuation.parameter: period``: the parameter that becomes an unknown (the
    #: period is prescribed along the branch), e.g. ``torque``; default the problem's
    #: ``period_partner``. Not allowed when continuing in a parameter.
    free_parameter: str | None = None
    #: with ``continuation.algorithm: sweep`` (a brute-force bifurcation diagram,
    #: :mod:`~nsm_continuation.hybrid.brute_force`): the returns to the section recorded at
    #: each value after ``transient`` ones (default ``BRUTE_FORCE_RECORD``). Refused otherwise.
    record: int | None = Field(None, ge=1)


#: one start mapping or a list of them
START_ADAPTER = one_or_many(HybridStartSpec)
