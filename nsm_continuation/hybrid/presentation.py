"""Presentation of hybrid orbits: diagram axes, CSV columns, figures and report extras.

Pure functions of the results: the ``presentation_class``
(:class:`~nsm_continuation.core.presentation.Presentation`) of
:class:`~nsm_continuation.hybrid.problem.HybridShootingProblem`. What is presented follows the
system (:class:`~nsm_continuation.hybrid.system.HybridSystem`):

* a **forced** system (``forcing_frequency`` names the clock rate, e.g. ``omega``) continued in
  its forcing frequency: the **frequency-response curve**, the response amplitude
  ``(max - min) / 2`` of the impacting coordinate against the forcing frequency (the period,
  ``2 pi m / omega``, would only repeat the parameter), and a second figure
  ``impacts_vs_<parameter>.png`` (extremes of the impacting coordinate, the smallest normal
  impact velocity ``|N^T qdot| / |N|``, impacts per period, sticking time);
* a forced system continued in another parameter (the gap, the restitution, ...): a
  **bifurcation diagram** of the same response amplitude against that parameter, with the same
  second figure;
* an **autonomous** system (``forcing_frequency`` None: the double pendulum): a **bifurcation
  diagram** of the period (return time to the section, log scale) against the continued
  parameter.

The impacting coordinate and its response amplitude are the problem's
(:mod:`nsm_continuation.hybrid.response`).

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

from pathlib import Path
from typing import Any

import numpy as np

from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.records import OrbitTrace
from nsm_continuation.core.symbols import math_symbol
from nsm_continuation.hybrid.homoclinic import homoclinic_fit
from nsm_continuation.hybrid.orbit_trace import orbit_trace, views_of
from nsm_continuation.hybrid.return_map import PERIOD
from nsm_continuation.hybrid.system import FLOWS

#: the event kind of a branch ended by its period bound (``HybridShootingProblem.monitors``)
HOMOCLINIC_KIND = "homoclinic_approach"


class HybridPresentation(Presentation):
    """Presentation of hybrid shooting problems (see the module docstring); what the system is
    comes from the problem (:class:`~nsm_continuation.hybrid.response.ResponseQuantities`)."""

    # ------------------------------------------------------------------ the branch diagram
    @property
    def diagram_title(self) -> str:  # type: ignore[override]
        """"Frequency-response curve" when continued in the forcing frequency, else
        "Bifurcation diagram"."""
        pr = self.problem
        return "Frequency-response curve" if pr.frequency_response and pr.response_key \
            else "Bifurcation diagram"

    @property
    def diagram_yscale(self) -> str:  # type: ignore[override]
        """Linear for an amplitude, log for a period (it may grow without bound)."""
        return "linear" if self.problem.response_key else "log"

    @property
    def fep_axes(self) -> tuple[str, str]:
        """The continued parameter against the response amplitude of the impacting coordinate
        (forced systems) or the period (autonomous systems); continued in the period, the
        parameter that became an unknown against the period."""
        return (self.problem.swept_parameter, self.problem.response_key or "period")

    @property
    def fep_labels(self) -> tuple[str, str]:
        """The forcing frequency / the continued parameter, and the response amplitude or the
        period (return time to the section), labelled by :attr:`quantity_labels`."""
        x, y = self.fep_axes
        return (self.label(x), self.label(y))

    @property
    def quantity_labels(self) -> dict[str, str]:
        """Labels of the quantities of the figures: the family's declared ``parameter_labels``
        (:class:`~nsm_continuation.hybrid.orbit_trace.OrbitDeclarations`), the forcing
        frequency, the restitution, the period, the response amplitude and extremes of the
        impacting coordinate (its symbol), the impact velocity, the impact counts and the
        sticking time."""
        pr = self.problem
        c = pr.response_coordinate
        sym = math_symbol(c) or c if c is not None else None
        out = {"period": "period (return time to the section)",
               "restitution": "restitution $e$",
               "sticking_time": r"sticking time $\tau$",
               "min_impact_velocity": "smallest impact velocity $|v|$",
               "min_impact_normal_velocity": r"smallest normal impact velocity "
                                             r"$|N^T \dot q| / |N|$",
               "n_impacts": "impacts per period",
               "n_impacts_before_chatter": "impacts before the chatter map",
               "n_sticking_phases": "sticking phases per period",
               "grazing_margin": "grazing margin"}
        if pr.hybrid.forcing_frequency is not None:
            f = pr.hybrid.forcing_frequency
            out[f] = f"forcing frequency ${math_symbol(f) or f}$"
        if sym is not None:
            out[f"amplitude_{c}"] = rf"response amplitude $(\max {sym} - \min {sym})/2$"
            out[f"max_{c}"] = rf"$\max {sym}$"
            out[f"min_{c}"] = rf"$\min {sym}$"
        out.update(pr.parameter_labels)
        return out

    @property
    def csv_head(self) -> list[str]:
        """The parameter, then (forced) the response amplitude and the extremes of the impacting
        coordinate and the impact velocity, the period, then the chattering quantities
        (continued in the period: the parameter that became an unknown first)."""
        head = [self.problem.swept_parameter]
        c = self.problem.response_coordinate
        if self.problem.response_key is not None:
            head += [f"amplitude_{c}", f"max_{c}", f"min_{c}", "min_impact_normal_velocity"]
        return head + ["period", "sticking_time", "n_impacts_before_chatter"]

    # ------------------------------------------------------------------ figures
    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Forced systems: ``impacts_vs_<parameter>.png``, the extremes of the impacting
        coordinate, the smallest normal impact velocity (log where it spans decades: it
        vanishes at a grazing), the impacts per period and the sticking time against the continued
        parameter. Autonomous systems whose orbits stick: ``sticking_vs_<parameter>.png``, the
        sticking time (its vanishing is the loss of sticking, ``sticking_lost``), the impacts
        before the chatter map and the period. Styled as the branch diagram, events marked."""
        if not any(br.points for br in branches):
            return []
        from nsm_continuation.figures.kit import quantity_panels

        x = self.problem.swept_parameter
        if self.problem.response_key is not None:
            c = self.problem.response_coordinate
            name = f"impacts_vs_{x}.png"
            ok = quantity_panels(
                self.problem, branches, self.fep_labels[0],
                [([f"max_{c}", f"min_{c}"], f"extremes of ${math_symbol(c) or c}$"),
                 (["min_impact_normal_velocity"], self.label("min_impact_normal_velocity")),
                 (["n_impacts"], self.label("n_impacts")),
                 (["sticking_time"], self.label("sticking_time"))],
                title=("Impacts along the frequency response" if self.problem.frequency_response
                       else "Impacts along the branch"),
                path=Path(out_dir) / name, log=("min_impact_normal_velocity",), x=x)
            return [name] if ok else []
        sticking = [p.derived.get("sticking_time", np.nan) for br in branches for p in br.points]
        if not np.nanmax(np.asarray(sticking, dtype=float), initial=0.0) > 0:
            return []
        name = f"sticking_vs_{x}.png"
        ok = quantity_panels(
            self.problem, branches, self.label(x),
            [(["sticking_time"], self.label("sticking_time")),
             (["n_impacts_before_chatter"], self.label("n_impacts_before_chatter")),
             (["period"], self.label("period"))],
            title="Sticking along the branch (complete chattering while it lasts)",
            path=Path(out_dir) / name, x=x)
        return [name] if ok else []

    # ------------------------------------------------------------------ report
    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Per branch: parameter range, period range (autonomous) or response-amplitude range
        (forced), and the homoclinic fit where the module docstring's rule allows it."""
        out = []
        for br in branches:
            pts = [p for p in br.points if np.isfinite(p.derived.get("period", np.nan))]
            if not pts:
                continue
            ps = np.array([p.y[self.problem.swept_index] for p in pts])
            Ts = np.array([p.derived["period"] for p in pts])
            rec: dict[str, Any] = {"label": br.label,
                                   "parameter_range": [float(ps.min()), float(ps.max())],
                                   "period_range": [float(Ts.min()), float(Ts.max())]}
            if self.problem.response_key is not None:
                amp = np.array([self.problem.response_value(p.derived) for p in pts])
                amp = amp[np.isfinite(amp)]
                rec[f"{self.problem.response_key}_range"] = ([float(amp.min()), float(amp.max())]
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
        return not self.problem.forced and (self.problem.continued_in_period or any(
            ev.kind == HOMOCLINIC_KIND for ev in branch.events))

    # ------------------------------------------------------------------ orbits
    def orbit(self, y: np.ndarray, periods: int = 1) -> OrbitTrace:
        """The orbit at ``y`` simulated again with its trajectory recorded over ``periods``
        periods, impacts marked and sticking phases as intervals
        (:func:`~nsm_continuation.hybrid.orbit_trace.orbit_trace`)."""
        return orbit_trace(self.problem, y, periods)

    def orbit_view_names(self) -> tuple[str, ...]:
        """The family's declared ``orbit_views`` (:class:`~.orbit_trace.OrbitDeclarations`),
        else the default time and phase views (:func:`~.orbit_trace.views_of`)."""
        return tuple(views_of(self.problem))


class HybridCasePresentation(HybridPresentation):
    """Presentation of a hybrid case problem
    (:class:`~nsm_continuation.hybrid.case.HybridCaseProblem`): the report also lists the
    parameters, the integrator, the section and the unknowns; with ``integrator.method``
    ``auto`` or ``exact``, the free flight that ran (``flow``: the exact flow, or the
    Runge-Kutta method and why the exact flow does not apply)."""

    def summary(self) -> dict[str, Any]:
        pr = self.problem
        sec = pr.shooting.section
        out = {"parameters": dict(pr.values), "integrator": pr.integrator.model_dump(),
               "section": {"coordinate": pr.hybrid.state_names[sec.index],
                           "value": sec.value, "shift_per_period": sec.shift},
               "unknowns": list(pr.variables)}
        if sec.shift == 0:
            # a crossing section: the direction it is crossed in, and the crossings a period
            out["section"].update(crossing="rising" if sec.direction > 0 else "falling",
                                  crossings_per_period=sec.crossings)
        if not pr.hybrid.m:
            out["contacts"] = "none (a smooth system)"
        if pr.integrator.method in FLOWS:
            out["flow"] = pr.shooting.c.flow_description()
        if pr.parameter == PERIOD:
            out["continued_in_period"] = {"free_parameter": pr.free_parameter}
        return out
