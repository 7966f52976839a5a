"""Presentation of hybrid orbits: diagram axes, CSV columns, figures and report extras.

Pure functions of the results (the Problem contract's *presentation* group,
:mod:`nsm_continuation.core.problem`), mixed into
:class:`~nsm_continuation.hybrid.problem.HybridShootingProblem`. What is presented follows the
system (:class:`~nsm_continuation.hybrid.system.HybridSystem`):

* a **forced** system (``forcing_frequency`` names the clock rate, e.g. ``omega``) continued in
  its forcing frequency: the **frequency-response curve**, the response amplitude
  ``(max - min) / 2`` of the impacting coordinate against the forcing frequency (the period,
  ``2 pi m / omega``, would only repeat the parameter), and a second figure
  ``impacts_vs_<parameter>.png`` (extremes of the impacting coordinate, impact velocity, impacts
  per period, sticking time);
* a forced system continued in another parameter (the gap, the restitution, ...): a
  **bifurcation diagram** of the same response amplitude against that parameter, with the same
  second figure;
* an **autonomous** system (``forcing_frequency`` None: the double pendulum): a **bifurcation
  diagram** of the period (return time to the section, log scale) against the continued
  parameter.

The *impacting coordinate* is the first configuration coordinate (index ``< n_config``) the
impact function ``H`` depends on (``HybridSystem.position``): ``q`` for the impact oscillator,
``q2`` for the two-mass chain. Its extremes over one period are the derived quantities
``max_<name>`` / ``min_<name>`` of the simulated orbit; the amplitude is
:meth:`HybridPresentation.response_quantities`. A missing extreme gives NaN (a gap in the
figure, an empty CSV cell), never an error.

**Homoclinic fit.** ``T = c - ln|p - p*| / mu`` (with its next order, :func:`homoclinic_fit`)
is fitted on a branch only when (i) the system is autonomous (for a forced system the period is
fixed by the clock, ``2 pi m / omega``, and grows as ``omega`` decreases without any homoclinic
orbit) and (ii) the branch was ended by the period bound (``continuation.bounds: {period: [..,
Tmax]}``, the event ``homoclinic_approach``) or was continued in the period itself
(``continuation.parameter: period``, the parameter that became an unknown is ``p``): the fit
describes how the period diverges, so it is attempted only where the run was asked to follow,
and did follow, that divergence. It is reported when it succeeds (the period at least doubles
along the branch and the fitted ``mu`` is positive). The points are weighted by their accuracy,
from the derived ``period_uncertainty`` of a branch continued in the period.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from nsm_continuation.hybrid.homoclinic import homoclinic_fit

if TYPE_CHECKING:
    from nsm_continuation.hybrid.system import HybridSystem

#: the event kind of a branch ended by its period bound (``HybridShootingProblem.bound_kinds``)
HOMOCLINIC_KIND = "homoclinic_approach"


class HybridPresentation:
    """Presentation members of hybrid shooting problems (see the module docstring)."""

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

    # ------------------------------------------------------------------ what the system is
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

    # ------------------------------------------------------------------ the branch diagram
    @property
    def diagram_title(self) -> str:  # type: ignore[override]
        """"Frequency-response curve" when continued in the forcing frequency, else
        "Bifurcation diagram"."""
        return "Frequency-response curve" if self.frequency_response and self.response_key \
            else "Bifurcation diagram"

    @property
    def diagram_yscale(self) -> str:  # type: ignore[override]
        """Linear for an amplitude, log for a period (it may grow without bound)."""
        return "linear" if self.response_key else "log"

    @property
    def fep_axes(self) -> tuple[str, str]:
        """The continued parameter against the response amplitude of the impacting coordinate
        (forced systems) or the period (autonomous systems); continued in the period, the
        parameter that became an unknown against the period."""
        return (self.swept_parameter, self.response_key or "period")

    @property
    def fep_labels(self) -> tuple[str, str]:
        """The forcing frequency / the continued parameter, and the response amplitude or the
        period (return time to the section)."""
        key, c = self.response_key, self.response_coordinate
        if key is None:
            return (self.swept_parameter, "period (return time to the section)")
        x = (f"forcing frequency {self.parameter}" if self.frequency_response
             else self.parameter)
        return (x, f"response amplitude of {c}: (max {c} - min {c}) / 2")

    @property
    def csv_head(self) -> list[str]:
        """The parameter, then (forced) the response amplitude and the extremes of the impacting
        coordinate and the impact velocity, the period, then the chattering quantities
        (continued in the period: the parameter that became an unknown first)."""
        head = [self.swept_parameter]
        c = self.response_coordinate
        if self.response_key is not None:
            head += [f"amplitude_{c}", f"max_{c}", f"min_{c}", "min_impact_velocity"]
        return head + ["period", "sticking_time", "n_impacts_before_chatter"]

    # ------------------------------------------------------------------ figures
    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Forced systems: ``impacts_vs_<parameter>.png``, the extremes of the impacting
        coordinate, the smallest impact velocity, the impacts per period and the sticking time
        against the continued parameter (styled as the branch diagram)."""
        if self.response_key is None or not any(br.points for br in branches):
            return []
        from nsm_continuation.figures.kit import quantity_panels

        c = self.response_coordinate
        name = f"impacts_vs_{self.parameter}.png"
        quantity_panels(
            self, branches, self.fep_labels[0],
            [([f"max_{c}", f"min_{c}"], f"max and min of {c}"),
             (["min_impact_velocity"], "smallest impact velocity |v|"),
             (["n_impacts"], "impacts per period"),
             (["sticking_time"], "sticking time")],
            title=("Impacts along the frequency response" if self.frequency_response
                   else "Impacts along the branch"),
            path=Path(out_dir) / name)
        return [name]

    # ------------------------------------------------------------------ report
    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Per branch: parameter range, period range (autonomous) or response-amplitude range
        (forced), and the homoclinic fit where the module docstring's rule allows it."""
        out = []
        for br in branches:
            pts = [p for p in br.points if np.isfinite(p.derived.get("period", np.nan))]
            if not pts:
                continue
            ps = np.array([p.y[self.swept_index] for p in pts])
            Ts = np.array([p.derived["period"] for p in pts])
            rec: dict[str, Any] = {"label": br.label,
                                   "parameter_range": [float(ps.min()), float(ps.max())],
                                   "period_range": [float(Ts.min()), float(Ts.max())]}
            if self.response_key is not None:
                amp = np.array([self.response_value(p.derived) for p in pts])
                amp = amp[np.isfinite(amp)]
                rec[f"{self.response_key}_range"] = ([float(amp.min()), float(amp.max())]
                                                      if amp.size else None)
            elif self.homoclinic_fit_applies(br):
                fit = homoclinic_fit(ps, Ts, uncertainty=np.array(
                    [p.derived.get("period_uncertainty", np.nan) for p in pts]))
                if fit is not None:
                    rec["homoclinic_fit"] = fit
            out.append(rec)
        return {"branches": out}

    def homoclinic_fit_applies(self, branch: Any) -> bool:
        """The declared rule: an autonomous system, and a branch ended by its period bound
        (a ``homoclinic_approach`` event) or continued in the period itself (the run was asked
        to follow the divergence of the period by construction)."""
        return not self.forced and (self.continued_in_period or any(
            ev.kind == HOMOCLINIC_KIND for ev in branch.events))
