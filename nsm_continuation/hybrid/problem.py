"""Periodic orbits of an impacting system on a Poincaré section, as a continuation Problem.

:class:`HybridShootingProblem` adapts the return map (:mod:`.return_map`: unknowns ``y = (z,
p)``, residual ``G(z, p) = P(x0) - x0 - shift`` with its exact Jacobian ``[P_z - I, P_p]``) to the
Problem contract (:mod:`nsm_continuation.core.problem`): the Floquet multipliers (the
eigenvalues of ``P_z``, known to :meth:`~.return_map.HybridShooting.monodromy_noise`), the
derived quantities of the simulated orbit, the admissibility test of orbits with sticking (the
sticking time, whose zero is the loss of complete chattering), the event signature, the grazing
margin with the passage through a grazing (:mod:`.grazing`, eqs. G1-G2), and the charts of a
section on the clock of a forced system (moved off the orbit's impacts). The presentation
(axes, CSV columns, figures) is :class:`~.presentation.HybridPresentation`; a concrete family
read from YAML is :class:`~.case.HybridCaseProblem`.
"""

from __future__ import annotations

import copy
import re
from typing import Any, ClassVar

import numpy as np

from nsm_continuation.core import monitors as monitor
from nsm_continuation.core.floquet.norms import spectral_norm
from nsm_continuation.core.monitors import Monitors
from nsm_continuation.core.problem import (
    EvaluationError,
    FloquetData,
    KinkCrossing,
    Problem,
    Rechart,
)
from nsm_continuation.hybrid.grazing import (
    MARGIN_FLOOR,
    grazing_contacts,
    locate_grazing,
    margin_gradient,
    step_beyond,
    tangent_beyond,
)
from nsm_continuation.hybrid.orbit_trace import OrbitDeclarations
from nsm_continuation.hybrid.presentation import HybridPresentation
from nsm_continuation.hybrid.response import ResponseQuantities
from nsm_continuation.hybrid.return_map import (
    AMBIGUOUS_NOISE,
    HybridShooting,
    Section,
    ShootingFailure,
    shooting_jacobian_noise,
)
from nsm_continuation.hybrid.simulate import SimResult, SimulationError
from nsm_continuation.hybrid.system import HybridDeclarationError


class HybridShootingProblem(ResponseQuantities, OrbitDeclarations, Problem):
    """Base class of shooting problems on a hybrid system (the concrete problem builds
    ``self.shooting`` in ``__init__`` and sets ``variables`` / ``parameter``).

    Hooks: ``derived`` (period, sticking time, impacts before the chatter map, the impact
    velocities, ...), the admissibility tests (the sticking time ``tau`` for orbits with
    sticking: its zero is the transition to incomplete chattering, reported as
    ``sticking_lost``), and the event signature (a change is ``impact_sequence_change``; across
    a grazing the branch is continued through, ``family_change``). The ends of a family are
    named: a grazing the branch cannot be continued across (several contacts grazing at once,
    say) ends it there, with the grazing; an impact velocity falling to zero
    (``min_impact_normal_velocity``, a ``vanishing`` monitor) ends it at the extrapolated
    zero, ``impact_velocity_vanishes``.
    """

    presentation_class = HybridPresentation

    shooting: HybridShooting
    event_kinds: ClassVar[dict[str, str]] = {
        "sticking_lost": "the sticking time tends to zero: complete chattering turns into "
                         "incomplete chattering (the branch of orbits with sticking ends; "
                         "located where the sticking time reaches its floor, extrapolated to "
                         "zero)",
        "impact_sequence_change": "the sequence of events over one period changes other than "
                                  "across a grazing the branch is continued through (that is "
                                  "a family_change) (notation: I an impact, C a completed "
                                  "chattering sequence with the impacts just before it, S a "
                                  "release from sticking, - no event; how many impacts the "
                                  "simulator resolves before the chatter map is no change)",
        "family_change": "the branch is continued through a grazing onto another family of "
                         "orbits: the event sequence differs on the two sides (signature "
                         "before -> after); the points after it belong to the new family "
                         "(column signature of the branch CSV)",
        "impact_velocity_vanishes": "the normal velocity of an impact (|N^T qdot| / |N|, "
                                    "N = dH/dq) falls to zero: the family of impacting orbits "
                                    "ends (beyond it the impact would leave the surface). "
                                    "Located by extrapolating the last resolved orbits to "
                                    "zero velocity (the return map's Jacobian grows without "
                                    "bound there); the branch ends at it",
        "homoclinic_approach": "the period grows without bound: the orbit approaches a "
                               "homoclinic orbit of a saddle (limit parameter from a fit "
                               "T ~ -ln|p - p*|/mu)",
    }
    monitors: ClassVar[Monitors] = Problem.monitors.with_(
        # the sticking time (an admissibility test of orbits with sticking) vanishes where
        # complete chattering is lost
        monitor.admissibility("sticking_time", "sticking_lost"),
        # the signed grazing margin closest to zero (SimResult.grazing_function): a near
        # approach that becomes an impact, or an impact that vanishes
        monitor.event_function("grazing_margin", "grazing"),
        monitor.signature("impact_sequence_change"),
        # the event sequence on the two sides of a grazing the branch is continued through
        monitor.family("family_change"),
        # the smallest normal impact velocity: its zero ends a family of impacting orbits
        monitor.vanishing("min_impact_normal_velocity", "impact_velocity_vanishes"),
        # a bound on the period ends the branch near a homoclinic orbit, one on the sticking
        # time where sticking is lost; continued in the period, the period's uncertainty
        # where it is no longer resolved in double precision
        monitor.bound("period", "homoclinic_approach"),
        monitor.bound("sticking_time", "sticking_lost"),
        monitor.bound("period_uncertainty", "homoclinic_approach"))
    #: a section on the clock of a forced system is moved (:meth:`rechart`) once an event of
    #: the orbit (an impact, a chattering sequence, a release, a near approach, a sticking
    #: phase) comes within this fraction of the period of it
    SECTION_CLEARANCE: ClassVar[float] = 0.002
    #: the events that put the orbit on, or next to, the impact surface
    SURFACE_EVENTS: ClassVar[tuple[str, ...]] = (
        "impact", "chatter", "chatter_broken", "release", "near_approach", "plastic_stick")
    #: a near approach closer to the surface than this fraction of the orbit's extent (the
    #: largest range of a position over the period) counts among them
    NEAR_APPROACH: ClassVar[float] = 0.05

    def residual(self, y: Any) -> Any:  # pragma: no cover - numeric problem
        raise NotImplementedError("hybrid shooting problems evaluate numerically")

    # ------------------------------------------------------------------ charts
    def _clock_section(self) -> Section | None:
        """The section when it lies on the clock of a forced system (it can then be placed at
        any phase), else None."""
        sh = self.shooting
        clock = self.hybrid.clock_index
        if type(sh) is not HybridShooting or clock is None or sh.section.index != clock:
            return None
        return sh.section

    def section_clearance(self, y: np.ndarray) -> tuple[float, float] | None:
        """``(clearance, phase)``: the time from the section to the nearest event that puts
        the orbit on or next to the impact surface (:data:`SURFACE_EVENTS`, and every sticking
        phase), as a fraction of the period, and the fraction of the period at the middle of
        the longest stretch free of them. None without a clock section, a simulation or such
        an event.

        A section must not sit on such an event: the state at the section then jumps along the
        branch (pre- to post-impact as the impact time crosses the section's), or the section
        state lies on the surface (a grazing at the section), and the shooting residual is
        discontinuous there."""
        if self._clock_section() is None:
            return None
        res = self.sim(y)
        if res is None or not res.t > 0:
            return None
        P = float(res.t)
        # a near approach far from the surface is no event of the surface: one counts where
        # its distance H_min is below NEAR_APPROACH of the orbit's extent in its positions
        span = np.inf
        if res.extremes is not None:
            k = self.hybrid.n_config or self.hybrid.n
            span = float(np.max(res.extremes[:k, 1] - res.extremes[:k, 0]))
        busy = [(ev.t / P, ev.t / P) for ev in res.events if ev.kind in self.SURFACE_EVENTS
                and not (ev.kind == "near_approach"
                         and ev.info.get("H", 0.0) > self.NEAR_APPROACH * span)]
        busy += [(a / P, b / P) for a, b in res.sticking_intervals]
        if not busy:
            return None
        busy.sort()
        clearance = min(min(a, 1.0 - b) for a, b in busy)
        merged = [list(busy[0])]
        for a, b in busy[1:]:
            if a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        # the free stretches between busy ones, the last one round the end of the period
        gaps = [(merged[k + 1][0] - merged[k][1], merged[k][1])
                for k in range(len(merged) - 1)]
        gaps.append((merged[0][0] + 1.0 - merged[-1][1], merged[-1][1]))
        width, left = max(gaps)
        return max(clearance, 0.0), float((left + 0.5 * width) % 1.0)

    def rechart(self, y: np.ndarray, tangent: np.ndarray) -> Rechart | None:
        """Move a clock section off the orbit's impacts (:meth:`section_clearance` below
        :data:`SECTION_CLEARANCE`) to the middle of the longest stretch without one: the state
        there is the flow of the present section state (one simulation, whose sensitivity maps
        the tangent: ``dz'/dz = P_z``, ``dz'/dp = P_p`` at the new section, the parameters
        unchanged). The orbit, its multipliers and derived quantities are the same."""
        sec = self._clock_section()
        found = self.section_clearance(y)
        if sec is None or found is None or found[0] >= self.SECTION_CLEARANCE:
            return None
        fraction = found[1]
        sh = self.shooting
        value = sec.value + sec.shift * fraction
        period = abs(sec.shift)
        new_value = float(value % period) if period > 0 else float(value)
        try:
            res = sh.sim.run(sh.x0(y), section=(sec.index, value, sec.direction))
        except (SimulationError, HybridDeclarationError):
            return None
        if res.J is None:
            return None
        c = sh.c
        fi = sh.free_idx
        cols = fi + list(range(c.n, c.N))
        y_new = np.concatenate([res.X[fi], np.asarray(y, dtype=float)[c.n - 1:]])
        D = np.eye(len(y))
        D[: len(fi), :] = res.J[np.ix_(fi, cols)]
        t_new = D @ np.asarray(tangent, dtype=float)
        norm = float(np.linalg.norm(t_new))
        if not (np.isfinite(norm) and norm > 0 and np.all(np.isfinite(y_new))):
            return None
        name = self.hybrid.state_names[sec.index]
        return Rechart(self.in_chart({name: new_value}), y_new, t_new / norm,
                       f"Poincare section moved from {name} = {sec.value:.6g} to "
                       f"{new_value:.6g}: an event of the orbit came within "
                       f"{found[0]:.2g} of a period of it")

    #: the value of the section coordinate that the problem declares (:meth:`chart` is None
    #: there); set where the shooting problem is built
    declared_section: float | None = None

    def chart(self) -> dict[str, float] | None:
        """``{clock name: section value}`` where a clock section was moved (:meth:`rechart`)
        from the declared one, else None."""
        sec = self._clock_section()
        if sec is None or self.declared_section is None or sec.value == self.declared_section:
            return None
        return {self.hybrid.state_names[sec.index]: float(sec.value)}

    def in_chart(self, chart: dict[str, float] | None) -> HybridShootingProblem:
        """This problem with its clock section at ``chart``'s value of the clock (a
        :meth:`rechart`), or at the declared one for None; itself where that is where it is,
        or for a chart of another coordinate."""
        sec = self._clock_section()
        if sec is None:
            return self
        name = self.hybrid.state_names[sec.index]
        target = (self.declared_section if not chart else chart.get(name))
        if target is None or float(target) == sec.value:
            return self
        chart = {name: float(target)}
        new = copy.copy(self)
        sh = self.shooting
        new.shooting = HybridShooting(sh.c, Section(sec.index, float(chart[name]), sec.shift),
                                      sh.sim.o, sh.cache_size)
        return new

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[0]

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[1]

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian from one (cached) simulation. A simulation that fails raises
        :class:`~nsm_continuation.core.problem.EvaluationError` with the simulator's reason (e.g.
        ``simulation: time limit: ...``): the engine retries the step smaller and, if the branch
        has to end, records that reason, not a NaN residual."""
        try:
            return self.shooting.residual_jacobian(np.asarray(y, dtype=float))
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None

    def jacobian_noise(self, y: np.ndarray, jacobian: np.ndarray) -> float:
        """The integrated Jacobian's accuracy (:func:`~.return_map.shooting_jacobian_noise`)."""
        try:
            return shooting_jacobian_noise(self.shooting, y, jacobian)
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None

    @property
    def compiled(self) -> Any:  # the engine touches ``problem.compiled`` once: nothing to build
        return None

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """The eigenvalues of ``P_z``, known to ``noise`` =
        :meth:`HybridShooting.monodromy_noise` (``FloquetData.noise``: the engine counts a
        multiplier outside the circle only beyond ``1 + noise``, so no crossing is reported
        that the integration error could make),
        and where ``noise >= AMBIGUOUS_NOISE`` with a multiplier inside ``||lambda| - 1| <=
        noise`` stability cannot be decided: None (unknown)."""
        try:
            P = self.shooting.poincare_jacobian(y)
            triv = self.shooting.trivial_error(y)
            noise = self.shooting.monodromy_noise(y)
        except ShootingFailure:
            return None
        mult = np.linalg.eigvals(P)
        if noise >= AMBIGUOUS_NOISE and np.any(np.abs(np.abs(mult) - 1.0) <= noise):
            return None
        return FloquetData(multipliers=mult, trivial_error=triv,
                           matrix_norm=spectral_norm(P), noise=float(noise))

    def sim(self, y: np.ndarray) -> SimResult | None:
        try:
            return self.shooting.simulate(np.asarray(y, dtype=float))
        except ShootingFailure:
            return None

    def derived(self, y: np.ndarray) -> dict[str, float]:
        res = self.sim(y)
        p = float(y[self.parameter_index])
        if res is None:
            return {self.parameter: p, "period": np.nan, "sticking_time": np.nan,
                    "n_impacts_before_chatter": np.nan}
        return self.result_quantities(res, p)

    def result_quantities(self, res: SimResult, p: float) -> dict[str, float]:
        """The derived quantities of the simulation ``res`` at the parameter value ``p`` (of
        the orbit at a point, :meth:`derived`; of one recorded return of a brute-force
        diagram, :mod:`nsm_continuation.hybrid.brute_force`)."""
        out = {
            self.parameter: p,
            "period": float(res.t),
            "sticking_time": res.sticking_time,
            "n_impacts_before_chatter": float(res.n_impacts_before_chatter),
            "n_sticking_phases": float(res.n_sticking_phases),
            "n_impacts": float(res.n_impacts),
            # the physical impact velocity: |N^T qdot| / |N| of the slowest recorded impact
            "min_impact_normal_velocity": self.min_normal_velocity(res),
            # |dH/dt| of the slowest impact (chattering ones included): in units of H per time
            "min_impact_dH_dt": (float(res.min_impact_velocity)
                                 if np.isfinite(res.min_impact_velocity) else np.nan),
            # signed grazing margin closest to zero, in units of H: H_min of a near approach
            # (> 0) or -v^2/(2a) of a decelerating impact (< 0); crosses zero at a grazing
            "grazing_margin": res.closest_margin(),
        }
        sec = self._clock_section()
        if sec is not None:  # where the section state was taken (it moves: rechart)
            out[f"section_{self.hybrid.state_names[sec.index]}"] = float(sec.value)
        if res.extremes is not None:
            names = self.shooting.c.system.state_names
            for k, name in enumerate(names):
                out[f"min_{name}"] = float(res.extremes[k, 0])
                out[f"max_{name}"] = float(res.extremes[k, 1])
            out.update(self.response_quantities(out))
        return out

    def min_normal_velocity(self, res: SimResult) -> float:
        """The smallest normal velocity ``|v| / |dH/dx|`` of the impacts ``res`` records (an
        impact from free flight, or the one that breaks off a chattering sequence), ``v = dH/dt``
        (eq. 2) and ``dH/dx`` the gradient of ``H`` over the state without the clock: for a
        mechanical system ``|N^T qdot| / |N|`` with ``N = dH/dq``, the velocity of the
        configuration normal to the surface (Euclidean in ``q``), the same for any ``H`` with
        the same zero set (``H`` and ``f(H)``, ``f(0) = 0 < f'``). ``H = gap - q``: ``|qdot|``;
        a relative coordinate ``z = y - x`` (``H = d/2 - z`` or ``d^2/4 - z^2``): ``|zdot| /
        sqrt 2``. With several surfaces, each impact's own ``H_i``. Impacts inside a chattering
        sequence completed by the chatter map are not recorded (their velocities accumulate at
        zero by construction). NaN without impacts."""
        c = self.shooting.c
        surfaces = c.calls().surfaces
        params = np.asarray(res.X, dtype=float)[c.n:]
        clock = self.hybrid.clock_index
        best = np.inf
        for ev in res.events:
            if ev.kind not in ("impact", "chatter_broken") or "v" not in ev.info:
                continue
            grads = surfaces[ev.surface].grads
            g = np.array(grads(np.concatenate([ev.x, params])), dtype=float)[0, : c.n]
            if clock is not None:
                g[clock] = 0.0
            norm = float(np.linalg.norm(g))
            if norm > 0:
                best = min(best, abs(float(ev.info["v"])) / norm)
        return float(best) if np.isfinite(best) else np.nan

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        """``grazing_margin``: the signed margin (near approach ``H_min > 0``, decelerating
        impact ``-v^2/(2a) < 0``) closest to zero; its zero is a grazing, located on this
        smooth function (the square-root singularity is in ``v``, not in ``v^2``)."""
        res = self.sim(y)
        if res is None:
            return {}
        g = res.grazing_function()
        return {} if not np.isfinite(g) else {"grazing_margin": g}

    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> KinkCrossing | None:
        """At a grazing (zero of ``grazing_margin``): the grazing orbit, located on the margin
        by margin-fixed solves from ``y`` (:func:`.grazing.locate_grazing`), and the first
        orbit beyond it from the discontinuity-map normal form (:func:`.grazing.step_beyond`,
        eqs. G1-G2): the impacting orbit born at the grazing, or the free one that follows an
        impact that vanished.

        Where two contacts graze at once (both walls of a symmetric orbit:
        :func:`.grazing.grazing_contacts`) several families meet and the single-grazing normal
        form does not apply, and where no orbit beyond it converges: the located grazing
        without one, and why. The engine then ends the branch at the grazing (from a step
        that went across it, at once; ahead of a step that failed, if it cannot step past
        it)."""
        if name != "grazing_margin":
            return None
        y = np.asarray(y, dtype=float)
        tangent = np.asarray(tangent, dtype=float)
        path: list[np.ndarray] = []
        yg = locate_grazing(self.shooting, y, tol, path_out=path)
        if yg is None:
            # ``y`` may already be the grazing point (a zero located on the margin in a step),
            # from which the margin-fixed solves have nowhere to go
            mg = margin_gradient(self.shooting, y)
            if mg is None or abs(mg[0]) > MARGIN_FLOOR * (1.0 + float(np.linalg.norm(y))):
                return None
            yg = y
        # the approach, kept while it still moves (|v| halves per orbit: down to 1e-3 of the
        # first one it resolves the side where the Jacobian grows like 1/|v|)
        keep = [z for k, z in enumerate(path) if k < 10]
        near = path[-1] if path else y
        res = self.sim(near)
        floor = MARGIN_FLOOR * (1.0 + float(np.linalg.norm(near)))
        n = 0 if res is None else grazing_contacts(res, floor)
        if n >= 2:  # the single-grazing normal form does not describe the branch beyond
            return KinkCrossing(keep, yg, None, (
                f"{n} contacts graze at once (their grazing margins vanish together, e.g. by "
                "symmetry): several families of orbits meet here, and the normal form of a "
                "single grazing (eq. G2) does not give the branch beyond"))
        y1 = step_beyond(self.shooting, yg, tangent, from_impacting=value < 0, ds=ds, tol=tol)
        if y1 is None:
            return KinkCrossing(keep, yg, None, (
                "no orbit beyond it converged from the normal form of the grazing (eq. G2): "
                "the orbits beyond may not form an isolated family"))
        return KinkCrossing(keep, yg, y1)

    def tangent_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray,
                       value_before: float) -> np.ndarray | None:
        """The tangent of the branch beyond the grazing point ``y`` (eq. G2), on the side the
        branch did not come from (``value_before`` < 0: it arrived impacting)."""
        if name != "grazing_margin":
            return None
        return tangent_beyond(self.shooting, np.asarray(y, dtype=float),
                              np.asarray(tangent, dtype=float), from_impacting=value_before < 0)

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        res = self.sim(y)
        if res is None:
            return {}
        tests: dict[str, float] = {}
        if res.sticking_intervals:
            tests["sticking_time"] = res.sticking_time
        return tests

    def locate_signature(self, before: str | None, after: str | None) -> bool:
        """Locate (by bisection) only structural changes: an impact gained or lost, a sticking
        phase gained or lost. A change of the number of impacts resolved before the chatter
        map alone depends on the chatter tolerance and is recorded within its step."""
        def strip(sig: str | None) -> str:
            return re.sub(r"\d+", "", sig or "")

        return strip(before) != strip(after)

    def signature(self, y: np.ndarray) -> str | None:
        res = self.sim(y)
        return None if res is None else res.signature

