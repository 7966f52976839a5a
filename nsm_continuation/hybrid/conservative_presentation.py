"""Presentation of conservative families (:class:`~.conservative_family.ConservativeFamilyProblem`):
the frequency-energy plot, the CSV columns (the unfolding among them), the model that ran and
the accuracy of each branch (the unfolding and the removal of the family's multiplier).

Pure functions of the results and of what the problem was built from.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from nsm_continuation.core.records import OrbitTrace
from nsm_continuation.hybrid.conservative import UNFOLDING
from nsm_continuation.hybrid.orbit_trace import orbit_trace
from nsm_continuation.hybrid.presentation import HybridPresentation


class ConservativePresentation(HybridPresentation):
    """The frequency-energy plot: the energy (the period when none is declared) against the
    frequency ``omega = 2 pi / T``."""

    diagram_title = "Frequency-energy plot"  # type: ignore[assignment]
    diagram_yscale = "log"  # type: ignore[assignment]

    @property
    def _has_energy(self) -> bool:
        return self.problem.energy_function is not None

    @property
    def fep_axes(self) -> tuple[str, str]:  # type: ignore[override]
        return ("omega", "energy" if self._has_energy else "period")

    @property
    def fep_labels(self) -> tuple[str, str]:  # type: ignore[override]
        return (r"frequency $\omega = 2\pi/T$",
                "energy E" if self._has_energy else "period T")

    @property
    def csv_head(self) -> list[str]:  # type: ignore[override]
        head = ["omega", "period", *(["energy"] if self._has_energy else []), UNFOLDING,
                "unfolding", "n_impacts", "min_impact_normal_velocity", "grazing_margin"]
        return list(dict.fromkeys([self.problem.parameter, *head]))

    @property
    def event_columns(self) -> list[str]:  # type: ignore[override]
        return ["omega", "period", *(["energy"] if self._has_energy else [])]

    def orbit(self, y: np.ndarray, periods: int = 1) -> OrbitTrace:
        """The orbit over ``periods`` periods: ``returns`` crossings of the section each."""
        k = int(self.problem.returns)
        trace = orbit_trace(self.problem, y, int(periods) * k)
        return replace(trace, period=trace.period * k)

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        return []

    def summary(self) -> dict[str, Any]:
        pr = self.problem
        sec = pr.shooting.section
        return {"model": pr.model, "parameters": dict(pr.values),
                "integrator": pr.integrator.model_dump(),
                "section": {"coordinate": pr.hybrid.state_names[sec.index], "value": sec.value,
                            "crossing": "rising" if sec.crossing > 0 else "falling",
                            "returns_per_period": sec.returns},
                "unknowns": list(pr.variables),
                "unfolding": (f"M qdd = f + {UNFOLDING} M qd; |{UNFOLDING}| T must stay below "
                              f"{pr.unfolding_tolerance():.3g} (a branch ends where it does "
                              "not)")}

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Per branch: the ranges of the frequency and the energy, the largest ``|beta|`` and
        ``|beta| T`` (the unfolding's check; the removal of the family's multiplier is the
        branch's ``max_trivial_multiplier_error``)."""
        out = []
        for br in branches:
            pts = [p for p in br.points if np.isfinite(p.derived.get("period", np.nan))]
            if not pts:
                continue
            rec: dict[str, Any] = {"label": br.label}
            for key in ("omega", "period", "energy"):
                v = np.array([p.derived.get(key, np.nan) for p in pts], dtype=float)
                if np.isfinite(v).any():
                    rec[f"{key}_range"] = [float(np.nanmin(v)), float(np.nanmax(v))]
            rec["max_abs_beta"] = float(max(abs(p.derived.get(UNFOLDING, 0.0)) for p in pts))
            rec["max_unfolding"] = float(max(p.derived.get("unfolding", 0.0) for p in pts))
            out.append(rec)
        return {"branches": out}
