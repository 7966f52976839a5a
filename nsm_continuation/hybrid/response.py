"""What a hybrid system is, for its outputs and its derived quantities (a mixin of
:class:`~nsm_continuation.hybrid.problem.HybridShootingProblem`).

A **forced** system names its clock rate (``forcing_frequency``, e.g. ``omega``); an
**autonomous** one (the double pendulum) does not. The *impacting coordinate* is the first
configuration coordinate (index ``< n_config``) the impact function ``H`` depends on
(``HybridSystem.position``): ``q`` for the impact oscillator, ``q2`` for the two-mass chain. Its
extremes over one period are the derived quantities ``max_<name>`` / ``min_<name>`` of the
simulated orbit, and its response amplitude is ``(max - min) / 2``
(:meth:`ResponseQuantities.response_quantities`). A missing extreme gives NaN (a gap in a
figure, an empty CSV cell), never an error.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from nsm_continuation.hybrid.system import HybridSystem


class ResponseQuantities:
    """What the system is (forced or autonomous, its impacting coordinate) and its response
    quantities, for a hybrid shooting problem (the module docstring)."""

    parameter: str
    parameter_index: int
    #: the symbolic declaration (set by the concrete problem's ``__init__``)
    hybrid: HybridSystem

    @property
    def swept_parameter(self) -> str:
        """The physical parameter along the branch: the continued one (a problem continued in
        its period overrides this with the parameter that became an unknown)."""
        return self.parameter

    @property
    def swept_index(self) -> int:
        """Index of :attr:`swept_parameter` among the unknowns."""
        return self.parameter_index

    @property
    def continued_in_period(self) -> bool:
        """Continued in the period (``continuation.parameter: period``), the swept parameter
        among the unknowns."""
        return self.parameter == "period" and self.swept_parameter != self.parameter

    @property
    def forced(self) -> bool:
        """The system has a clock whose rate is a parameter (``forcing_frequency``)."""
        return self.hybrid.forcing_frequency is not None

    @property
    def frequency_response(self) -> bool:
        """Forced, and continued in its forcing frequency: a frequency-response curve."""
        return self.forced and self.parameter == self.hybrid.forcing_frequency

    @property
    def configuration_names(self) -> list[str]:
        """Names of the configuration coordinates (the first ``n_config`` states; every state
        if the system does not say), without the angles that may turn (``periodic``)."""
        h = self.hybrid
        n = h.n_config if h.n_config is not None else h.n
        return [h.state_names[i] for i in range(n) if i not in h.periodic]

    @property
    def response_coordinate(self) -> str | None:
        """The impacting coordinate: the first configuration coordinate ``H`` depends on (None
        if there is none, e.g. ``H`` depends on a velocity or on a turning angle only)."""
        h = self.hybrid
        n = h.n_config if h.n_config is not None else h.n
        for i in h.position or []:
            if i < n and i not in h.periodic:
                return h.state_names[i]
        return None

    @property
    def response_key(self) -> str | None:
        """The derived key of the response amplitude (``amplitude_<coordinate>``), for a forced
        system with an impacting coordinate; None otherwise (the period is presented)."""
        c = self.response_coordinate
        return f"amplitude_{c}" if (self.forced and c is not None) else None

    def response_quantities(self, derived: Mapping[str, float]) -> dict[str, float]:
        """``amplitude_<c> = (max_<c> - min_<c>) / 2`` for every configuration coordinate ``c``
        from the extremes in ``derived`` (NaN where an extreme is missing or not finite). Meant
        to be merged into the derived quantities at every simulated point."""
        out = {}
        for c in self.configuration_names:
            hi = float(derived.get(f"max_{c}", np.nan))
            lo = float(derived.get(f"min_{c}", np.nan))
            out[f"amplitude_{c}"] = 0.5 * (hi - lo) if np.isfinite(hi - lo) else np.nan
        return out

    def response_value(self, derived: Mapping[str, float]) -> float:
        """The response amplitude at a point: the derived ``amplitude_<c>`` if present, else
        computed from the extremes (NaN if neither is there)."""
        key = self.response_key
        if key is None:
            return float("nan")
        if key in derived:
            return float(derived[key])
        return self.response_quantities(derived).get(key, float("nan"))
