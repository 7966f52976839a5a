"""The WFEM simulation of the bar, one import path for its three parts (names only):

* :mod:`.wfem_stepping`: the time stepping (Algorithm 2, Appendix B) with forces, damping and
  the moving wall of section 7;
* :mod:`.forced_steady_state`: the steady forced responses found by time stepping (section 7);
* :mod:`.linear_forced`: the linear forced responses in closed form (their references).
"""

from nsm_continuation.problems.bar.forced_steady_state import (
    ForcedPoint,
    ForcedSweep,
    SteadyStateRule,
    forced_response_point,
    forced_response_sweep,
    period_averages,
    steady_multiple,
    steady_state_rule,
)
from nsm_continuation.problems.bar.linear_forced import (
    linear_forced_end_amplitude,
    linear_forced_energy,
    linear_forced_fields,
    linear_wall_response,
)
from nsm_continuation.problems.bar.wfem_operators import from_ring
from nsm_continuation.problems.bar.wfem_stepping import (
    BarParams,
    BarState,
    Loading,
    SimulationResult,
    rest_state,
    ring_displacement,
    simulate,
    state_from_fields,
    step_source_terms,
)

__all__ = [
    "BarParams",
    "BarState",
    "ForcedPoint",
    "ForcedSweep",
    "Loading",
    "SimulationResult",
    "SteadyStateRule",
    "forced_response_point",
    "forced_response_sweep",
    "from_ring",
    "linear_forced_end_amplitude",
    "linear_forced_energy",
    "linear_forced_fields",
    "linear_wall_response",
    "period_averages",
    "rest_state",
    "ring_displacement",
    "simulate",
    "state_from_fields",
    "steady_multiple",
    "steady_state_rule",
    "step_source_terms",
]
