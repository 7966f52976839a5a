"""Continuation of a hybrid case in the period (``continuation.parameter: period``).

Near a homoclinic orbit the period is a hopelessly ill-conditioned function of the parameter but
the parameter a well-conditioned function of the period: the period becomes the continuation
parameter and a physical parameter (``start.free_parameter``, default the family's
``period_partner``) an unknown, the shooting problem a :class:`~.return_map.PeriodShooting`
(see :mod:`.return_map`). This mixin of :class:`~.case.HybridCaseProblem` sets that layout up,
checks and finds its starts (each orbit found as for a continuation in the free parameter, then
its simulated period appended).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core.preflight import as_list
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.core.vocabulary import canonical_name
from nsm_continuation.hybrid.return_map import (
    PERIOD,
    HybridShooting,
    PeriodShooting,
    ShootingFailure,
)
from nsm_continuation.hybrid.specs import START_ADAPTER
from nsm_continuation.hybrid.system import HybridSystem


class PeriodContinuation:
    """Continuation in the period, for :class:`~.case.HybridCaseProblem` (see the module
    docstring)."""

    # set by the case problem
    Parameters: Any
    name: str
    values: dict[str, float]
    parameter: str
    variables: list[str]
    returns: int
    hybrid: HybridSystem
    shooting: HybridShooting
    free_parameter: str | None
    period_partner: ClassVar[str | None]
    _compiled_for: str | None

    def _set_period(self, partner: str | None, returns: int | None = None) -> None:
        """Continue in the period with ``partner`` (a parameter) among the unknowns:
        ``variables = (section coordinates, partner, period)``, ``parameter = period``, the
        shooting problem a :class:`PeriodShooting` around the one of ``partner``. With
        ``partner`` None (no ``period_partner``, the start block not read yet) the layout is
        set and the partner is chosen by :meth:`start_points` / :meth:`preflight`."""
        if self.forced:
            raise ValueError(f"continuation.parameter: {PERIOD}: the period of a forced system "
                             f"is fixed by its clock ({self.hybrid.forcing_frequency}); continue "
                             f"in {self.hybrid.forcing_frequency} instead")
        names = self.hybrid.state_names
        if partner is None:
            self.parameter = PERIOD
            self.returns = self.returns if returns is None else returns
            self.variables = ([names[i] for i in self.shooting.free_idx]
                              + ["free_parameter", PERIOD])
            self._compiled_for = f"{PERIOD}:"
            return
        partner = canonical_name(self.Parameters, partner)
        if partner == PERIOD or partner not in self.values:
            raise ValueError(f"start.free_parameter: {partner!r} is not a parameter of "
                             f"{self.name!r} (one of {sorted(self.values)})")
        returns = self.returns if returns is None else returns
        if self._compiled_for == f"{PERIOD}:{partner}" and returns == self.returns:
            return
        self.set_parameter(partner, returns)          # the shooting problem in the partner
        self.shooting = PeriodShooting(self.shooting)  # type: ignore[assignment]
        self.parameter = PERIOD
        self.free_parameter = partner
        self.variables = [names[i] for i in self.shooting.free_idx] + [partner, PERIOD]
        self._compiled_for = f"{PERIOD}:{partner}"

    @property
    def swept_parameter(self) -> str:
        """The physical parameter along the branch: the continued one, or the free parameter
        when continued in the period."""
        if self.parameter == PERIOD and self.free_parameter is not None:
            return self.free_parameter
        return self.parameter

    @property
    def swept_index(self) -> int:
        return self.variables.index(self.swept_parameter)

    def _period_partner_of(self, start: Any) -> str:
        """The free parameter of a period continuation named by the start block (every start
        the same), or the problem's ``period_partner``."""
        items = as_list(START_ADAPTER.validate_python(start if start is not None else {}))
        named = {s.free_parameter for _, s in items if s.free_parameter is not None}
        if len(named) > 1:
            raise ValueError(f"start.free_parameter: every start of a continuation in the period "
                             f"frees the same parameter (got {sorted(named)})")
        partner = named.pop() if named else self.period_partner
        partner = None if partner is None else canonical_name(self.Parameters, partner)
        if partner is None:
            raise ValueError(f"start.free_parameter: continuing in the {PERIOD} needs the "
                             "parameter that becomes an unknown (e.g. free_parameter: torque)")
        if partner == PERIOD or partner not in self.values:
            raise ValueError(f"start.free_parameter: {partner!r} is not a parameter of "
                             f"{self.name!r} (one of {sorted(self.values)})")
        return partner

    def _period_preflight(self, start: Any, window: tuple[float | None, float | None],
                          max_points: int) -> None:
        """Preflight of a continuation in the period: a positive window, one free parameter
        for every start, and the starts checked as starts of a continuation in that parameter
        at its value (the orbit is found there, its period is the first value of the
        branch)."""
        for side, bound in (("min", window[0]), ("max", window[1])):
            if bound is not None and not bound > 0:
                raise ValueError(f"continuation.{side}: the period must be positive "
                                 f"(got {bound:g})")
        partner = self._period_partner_of(start)
        p0 = self.values[partner]
        items = [s.model_copy(update={"free_parameter": None}) for _, s in
                 as_list(START_ADAPTER.validate_python(start if start is not None else {}))]
        try:
            self.set_parameter(partner)
            self.preflight(items if len(items) > 1 else items[0], (p0, p0), max_points)
        finally:
            self._set_period(partner)

    def _period_start_points(self, start: Any) -> list[StartPoint]:
        """Starts of a continuation in the period: each orbit as for a continuation in the
        free parameter at its value (``parameters.<free>``), corrected there by Newton on the
        section coordinates, then ``y = (z, p0, T0)`` with ``T0`` its simulated period."""
        partner = self._period_partner_of(start)
        specs = START_ADAPTER.validate_python(start if start is not None else {})
        specs = specs if isinstance(specs, list) else [specs]
        out = []
        for s in specs:
            self.set_parameter(partner, s.returns)
            (sp,) = self._parameter_start_points(
                s.model_copy(update={"free_parameter": None}))
            y = np.asarray(sp.y, dtype=float).copy()
            sh = self.shooting
            m = len(sh.free_idx)
            for _ in range(8):  # Newton at fixed parameter on the section coordinates
                try:
                    g, J = sh.residual_jacobian(y)
                    dz = np.linalg.solve(J[:, :m], -g)
                except (ShootingFailure, np.linalg.LinAlgError):
                    break
                y[:m] += dz
                if np.linalg.norm(dz, np.inf) <= 1e-12 * (1.0 + np.linalg.norm(y, np.inf)):
                    break
            try:
                T0 = float(sh.simulate(y).t)
            except ShootingFailure:
                y = np.asarray(sp.y, dtype=float)
                try:
                    T0 = float(sh.simulate(y).t)
                except ShootingFailure as exc:
                    raise ValueError(f"start: the start orbit does not return to the section "
                                     f"({exc})") from None
            self._set_period(partner, s.returns)
            out.append(StartPoint(np.append(y, [T0]), sp.label, sp.direction,
                                  {**sp.info, "free_parameter": partner, PERIOD: T0}))
        return out
