"""Where the Poincaré section of a conservative family turns tangent to the flow: the section
moved to the impacts on a wall (:class:`SectionCharts`, a part of
:class:`~.conservative_family.ConservativeFamilyProblem`).

A section ``x_k = c`` crossed falling (:class:`~.conservative.CrossingSection`) is transversal
at the orbit's crossing, but the orbit may meet the level ``x_k = c`` elsewhere: where a turn
of ``x_k`` (``x_k' = 0``, a local extremum) inside the period reaches ``c``, a pair of new
crossings is born, the first return to the section jumps to one of them and the return map is
discontinuous (a section tangency: the section coordinate's rate vanishes at a section point).
The family goes on; only the section's chart ends. AUTO and COCO meet the same degeneracy in
a Poincaré phase condition and leave it by moving the condition (COCO's ``po`` toolbox resets
its phase condition to the current orbit at every step; AUTO's integral phase condition
``int <x, x_ref'> dt = 0`` has no fixed hyperplane at all).

Here the section is moved (:meth:`SectionCharts.rechart`) to a section that cannot turn
tangent along a family of impacting orbits: the impacts on a wall ``x_k = w`` of the same
coordinate (:meth:`SectionCharts.impact_section`), whose points are the post-impact states.
There the flow leaves the section with the impact velocity, which is not zero as long as the
orbit impacts the wall (the family's own end, a grazing impact, is where it vanishes). The
move happens once a turn of ``x_k`` comes within :attr:`SectionCharts.SECTION_MARGIN` of the
coordinate's range over the orbit of the section's value (``section_margin``); the turns of
``x_k`` are the near approaches to the walls (the walls are planes of ``x_k``: a local minimum
of ``H = w - x_k`` is a turn of ``x_k``). The state on the new section is the flow of the
present one to the wall (one simulation, whose sensitivity maps the tangent); the orbit, its
multipliers and derived quantities are the same. Where no impact section is declared, a branch
that reaches the tangency ends with the reason ``section tangent to the flow at ...``
(:meth:`SectionCharts.tangency_reason`).
"""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core.problem import Rechart
from nsm_continuation.hybrid.conservative import ConservativeShooting
from nsm_continuation.hybrid.return_map import CrossingSection, ShootingFailure, section_return
from nsm_continuation.hybrid.sim_data import SimResult
from nsm_continuation.hybrid.simulate import SimulationError
from nsm_continuation.hybrid.system import HybridDeclarationError

#: the name of the number of section points per period in a chart (:meth:`SectionCharts.chart`)
RETURNS = "section_returns"
#: a turn of the section coordinate this close to the section's value (relative to the
#: coordinate's range over the orbit) is at the section: the return that found fewer impacts
#: than the family's came back through a section tangency
AT_SECTION = 1e-2


class SectionCharts:
    """The section's charts of a conservative family (see the module docstring). The family
    sets :attr:`shooting`, :attr:`hybrid`, :attr:`parameter` and implements ``section``,
    ``set_parameter`` and :meth:`impact_section`."""

    #: a turn of the section coordinate closer to the section's value than this fraction of
    #: the coordinate's range over the orbit moves the section to the impacts (:meth:`rechart`)
    SECTION_MARGIN: ClassVar[float] = 0.05
    #: the section the unknowns are on where it is not the declared one (a :meth:`rechart`)
    moved_section: CrossingSection | None = None
    shooting: ConservativeShooting
    hybrid: Any
    parameter: str

    def section(self) -> CrossingSection:  # pragma: no cover - the family's
        raise NotImplementedError

    def set_parameter(self, name: str, returns: int | None = None) -> None:  # pragma: no cover
        raise NotImplementedError

    def impact_section(self) -> CrossingSection | None:
        """The section at the impacts on a wall ``x_k = w`` of the declared section's
        coordinate (``surface`` set), to which the section is moved where it turns tangent
        (:meth:`rechart`); the family's surfaces must be planes of ``x_k`` (their near
        approaches are then the turns of ``x_k``). None (the default): none."""
        return None

    def current_section(self) -> CrossingSection:
        """The section of the present chart (the declared one unless moved)."""
        return self.moved_section if self.moved_section is not None else self.section()

    # -- the turns of the section coordinate -----------------------------------------------
    def _turns(self, res: SimResult) -> tuple[list[float], float]:
        """The section coordinate at its turns in the simulated period (the near approaches
        to the walls) and its range over the period."""
        k = self.shooting.section.index
        turns = [float(ev.x[k]) for ev in res.events if ev.kind == "near_approach"]
        ext = res.extremes
        span = float(ext[k, 1] - ext[k, 0]) if ext is not None else np.nan
        return turns, span

    def section_margin(self, y: np.ndarray) -> float | None:
        """The distance of the nearest turn of the section coordinate from the section's value
        as a fraction of the coordinate's range over the orbit (inf without a turn); None on
        a section at the impacts, or without an impact section to move to."""
        sec = self.shooting.section
        if sec.surface is not None or self.impact_section() is None:
            return None
        try:
            res = self.shooting.simulate(y)
        except ShootingFailure:
            return None
        turns, span = self._turns(res)
        if not turns:
            return float("inf")
        if not span > 0:
            return None
        return min(abs(u - sec.value) for u in turns) / span

    def tangency_reason(self, y: np.ndarray, res: SimResult, found: int, family: int
                        ) -> str | None:
        """Why a return found ``found`` impacts where the family has ``family``, where that
        is a section tangency (fewer impacts, a turn of the section coordinate at the
        section's value within :data:`AT_SECTION` of its range): the reason, naming it; else
        None."""
        sec = self.shooting.section
        if sec.surface is not None or found >= family:
            return None
        turns, span = self._turns(res)
        if not turns or not span > 0 or min(abs(u - sec.value) for u in turns) > AT_SECTION * span:
            return None
        name = self.hybrid.state_names[sec.index]
        return (f"section tangent to the flow at {self.parameter} = {float(y[-1]):.10g}: a turn "
                f"of {name} reaches the section {name} = {sec.value:.6g}, and the orbit comes "
                f"back to it after {found} of its {family} impacts (the end of this section's "
                "chart, not of the family)")

    # -- charts ------------------------------------------------------------------------------
    def rechart(self, y: np.ndarray, tangent: np.ndarray) -> Rechart | None:
        """Move the section to the impacts (:meth:`impact_section`) once a turn of its
        coordinate comes within :attr:`SECTION_MARGIN` of it (:meth:`section_margin`): the
        state on the new section is the flow of the present one to the wall, whose sensitivity
        maps the tangent (``dz'/dz``, ``dz'/dbeta`` at the wall; ``beta`` and the continued
        quantity unchanged); the new chart has as many section points per period as the
        orbit has impacts on that wall."""
        margin = self.section_margin(y)
        target = self.impact_section()
        if margin is None or target is None or margin >= self.SECTION_MARGIN:
            return None
        sh = self.shooting
        try:
            period = sh.simulate(y)
            hits = sum(1 for ev in period.events
                       if ev.kind == "impact" and ev.surface == target.surface)
            res = section_return(sh.sim, sh.x0(y), target)
        except (ShootingFailure, SimulationError, HybridDeclarationError):
            return None
        if hits == 0 or res.J is None:
            return None
        new = self._with_section(replace(target, returns=hits))
        c = sh.c
        fi, fn = sh.free_idx, new.shooting.free_idx
        m = len(fi)
        y = np.asarray(y, dtype=float)
        y_new = np.concatenate([res.X[fn], y[m:]])
        D = np.eye(len(y))
        D[:m, : m + 1] = res.J[np.ix_(fn, [*fi, c.n])]
        t_new = D @ np.asarray(tangent, dtype=float)
        norm = float(np.linalg.norm(t_new))
        if not (np.isfinite(norm) and norm > 0 and np.all(np.isfinite(y_new))):
            return None
        name = self.hybrid.state_names[sh.section.index]
        wall = self.hybrid.surface_names[target.surface] if self.hybrid.surface_names else ""
        return Rechart(new, y_new, t_new / norm,
                       f"Poincare section moved from {name} = {sh.section.value:.6g} to the "
                       f"impacts on the {wall} wall ({name} = {target.value:.6g}): a turn of "
                       f"{name} came within {margin:.2g} of its range of the section")

    def _with_section(self, section: CrossingSection) -> Any:
        """A copy of this problem on ``section``."""
        new = copy.copy(self)
        new.moved_section = section
        new.set_parameter(self.parameter, section.returns)
        return new

    def chart(self) -> dict[str, float] | None:
        """``{section coordinate: value, section_returns: k}`` where the section was moved
        (:meth:`rechart`), else None."""
        sec = self.moved_section
        if sec is None:
            return None
        return {self.hybrid.state_names[sec.index]: float(sec.value),
                RETURNS: float(self.shooting.section.returns)}

    def in_chart(self, chart: dict[str, float] | None) -> Any:
        """This problem on the section of ``chart`` (a :meth:`chart`; None: the declared
        one); itself where that is where it is."""
        if chart == self.chart():
            return self
        if not chart:
            new = copy.copy(self)
            new.moved_section = None
            new.set_parameter(self.parameter,
                              self.section().returns * int(getattr(self, "multiple", 1)))
            return new
        declared = self.section()
        value = chart.get(self.hybrid.state_names[declared.index])
        target = self.impact_section()
        returns = int(chart.get(RETURNS, declared.returns))
        if value is None:
            return self
        if target is None or float(value) != target.value:
            target = replace(declared, value=float(value))
        return self._with_section(replace(target, returns=returns))
