"""Periodic orbits of an impacting system on a Poincaré section, as a continuation Problem.

Unknowns ``y = (z, p)``: ``z`` the state on the section ``x_k = c`` without its fixed component
``x_k``, ``p`` the continuation parameter. The residual is ``G(z, p) = P(x0) - x0 - shift``
restricted to the components other than ``k``, where ``P`` is the return map simulated by
:class:`~nsm_continuation.hybrid.simulate.Simulator` (impacts, chatter map, sticking, release:
the event order is *not* prescribed, sec. 1) and ``shift`` is ``delta`` on the section component
(``-2 pi`` for one revolution of the pendulum's upper bar, ``2 pi m`` for ``m`` forcing periods
of a forced system whose phase is the clock ``x_3 = omega t``). Its Jacobian ``[P_z - I, P_p]``
is the saltation-chained monodromy of the simulation, with the parameter lifted into the state:
no finite differences.

The Floquet multipliers are the eigenvalues of ``P_z`` (the trivial multiplier of an autonomous
orbit is removed by the section); the free accuracy check is the time-fixed monodromy
``Phi_T = P_x - F J_t`` mapping the flow direction to itself (``trivial_error``).
After sticking, ``P_x`` loses rank (``H_x P_x = 0``, ``v_x P_x = 0``, sec. 4.4): such orbits have
zero multipliers, which are exact, not round-off.

**Accuracy of the multipliers** (:meth:`HybridShooting.monodromy_noise`). ``P_x = Phi_T + F(x_T)
J_t`` is formed from the time-fixed monodromy ``Phi_T``; where ``|Phi_T|`` is large and cancels
against ``F J_t`` (an orbit passing near a saddle, whose unstable growth ``exp(mu T)`` is absorbed
in the return time), ``P_x`` carries the integration error of the variational equations relative
to ``|Phi_T|``, not to ``|P_x|``: measured on the pendulum near its homoclinic orbit (sec. 6.3), the
computed nontrivial multiplier is ``~ -0.1 rtol |Phi_T|`` (it scales with ``rtol``; the true one is
``~ 0``), which crossed -1 at period ~72 with ``rtol = 1e-10``: a spurious period doubling. The
multipliers are therefore declared known only to ``(rtol + 10 eps) |Phi_T|``
(``FloquetData.matrix_norm`` is raised so that the engine's unit-circle tolerance
``1e3 eps matrix_norm`` is at least that), and where that noise reaches ``AMBIGUOUS_NOISE`` with a
multiplier inside the noise band of the circle the multipliers are reported unknown (None).

**Continuation in the period** (``continuation.parameter: period``, :class:`PeriodShooting`). Near
a homoclinic orbit the period ``T ~ c - ln|p - p*| / mu`` is a hopelessly ill-conditioned function
of the parameter ``p`` but ``p`` is a well-conditioned function of ``T``: the period becomes the
continuation parameter and the physical parameter (``start.free_parameter``, e.g. the torque) an
unknown. Unknowns ``y = (z, p, T)``, residual ``[G(z, p); t_ret(z, p) - T]`` with the exact
Jacobian ``[[P_z - I, P_p, 0], [J_t,z, J_t,p, -1]]`` (``J_t = dt/dX0`` of the simulation, the
parameter column from the lifted parameter). The Jacobian error above is rank one along ``J_t``
(measured: the part orthogonal to ``J_t`` is 2e-5 of it), i.e. in the row space of the time
equation, which the period formulation enforces separately: it acts as a spurious ``dG/dT``
of size ``~ 0.1 rtol |F|``, and the tangent's ``dp/dT`` is off by the relative amount
``~ 0.1 rtol |Phi_T|`` (the size of the spurious multiplier).

How far in double precision (:func:`period_reach`): ``|p - p*| = exp(-mu (T - c))`` and ``p``
is resolved at best to ``eps |p|`` (6.9e-15 for the torque -31), so the period is uncertain by
``eps |p| / (mu |p - p*|)`` and has no digit left at ``T_max = c + ln(1 / (eps |p|)) / mu``:
109.5 for the pendulum (``mu = 0.28879``, ``c = -3.40``); a period of 150 needs
``|p - p*| ~ 6e-20``, five orders below the spacing of doubles at 31. The simulated return map
limits earlier: its value carries a noise ~ ``rtol + 4 eps (1 + tau)^2`` (round-off drift while
sticking for ``tau``, :meth:`HybridShooting.map_noise`; 1e-10 at the default rtol), which the
fixed point amplifies (x2.6) into the torque: ~1e-11 at rtol <= 1e-11, i.e. ``T_max ~ 85``
(~73 at rtol 1e-10). The derived ``period_uncertainty`` counts both through the Jacobian, and
a bound on it ends the branch (the bundled case at 0.5: period 77). The integration error
(rtol) also limits the Jacobian: relative error ``~ 0.1 rtol |Phi_T|``, 1 near period 75 at
rtol 1e-10 (Newton and the tangent fail there), ~0.02 at period 77 with rtol 1e-13.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, ClassVar

import casadi as ca
import numpy as np

from nsm_continuation.core.preflight import one_or_many
from nsm_continuation.core.problem import (
    EvaluationError,
    FloquetData,
    KinkCrossing,
    Problem,
    Rechart,
)
from nsm_continuation.core.records import OrbitTrace
from nsm_continuation.hybrid.grazing import locate_grazing, step_beyond, tangent_beyond
from nsm_continuation.hybrid.orbit_trace import OrbitDeclarations, orbit_trace, views_of
from nsm_continuation.hybrid.presentation import HybridPresentation
from nsm_continuation.hybrid.simulate import SimOptions, SimResult, SimulationError, Simulator
from nsm_continuation.hybrid.system import CompiledHybrid


@dataclass
class Section:
    """Poincaré section ``x[index] = value``; one period moves ``x[index]`` by ``shift``."""

    index: int
    value: float
    shift: float

    @property
    def direction(self) -> int:
        return 1 if self.shift > 0 else -1


class ShootingFailure(Exception):
    pass


def wrap_periodic(values: np.ndarray, indices: list[int], periodic: dict[int, float]
                  ) -> np.ndarray:
    """``values[j]`` (state component ``indices[j]``) wrapped to ``[-per/2, per/2)`` for the
    periodic components (angles that may turn); others unchanged."""
    out = np.array(values, dtype=float)
    for j, k in enumerate(indices):
        per = periodic.get(k)
        if per:
            out[j] = (out[j] + 0.5 * per) % per - 0.5 * per
    return out


class HybridShooting:
    """Return map, residual and Jacobian of a compiled hybrid system on a section (cached)."""

    def __init__(self, c: CompiledHybrid, section: Section, opts: SimOptions,
                 cache_size: int = 16) -> None:
        self.c = c
        self.section = section
        self.sim = Simulator(c, opts)
        self.free_idx = [i for i in range(c.n) if i != section.index]
        self._cache: OrderedDict[bytes, SimResult | str] = OrderedDict()
        self.cache_size = cache_size
        self.n_simulations = 0

    def x0(self, y: np.ndarray) -> np.ndarray:
        """Full initial state (with the freed parameters) from the unknowns ``y``."""
        c = self.c
        X = np.empty(c.N)
        X[self.free_idx] = y[: c.n - 1]
        X[self.section.index] = self.section.value
        X[c.n:] = y[c.n - 1:]
        return X

    def simulate(self, y: np.ndarray) -> SimResult:
        key = np.asarray(y, dtype=float).tobytes()
        hit = self._cache.get(key)
        if hit is None:
            s = self.section
            try:
                hit = self.sim.run(self.x0(y), section=(s.index, s.value + s.shift,
                                                          s.direction))
            except SimulationError as exc:
                hit = exc.reason
                if hit.startswith("initial state on the inadmissible side"):
                    hit += self._inadmissible_start(y)
            except HybridDeclarationError as exc:  # e.g. r >= 1 at an impact (e past 1)
                hit = str(exc)
            self.n_simulations += 1
            self._cache[key] = hit
            if len(self._cache) > self.cache_size:
                self._cache.popitem(last=False)
        if isinstance(hit, str):
            raise ShootingFailure(hit)
        return hit

    #: an initial state this far inside the obstacle (relative to its size) is a guess off
    #: any orbit; closer, an orbit on the surface at the section's time
    ON_SURFACE = 1e-6

    def _inadmissible_start(self, y: np.ndarray) -> str:
        """Why the state at the section lies inside the obstacle: on the surface (an impact
        or a grazing at the section's time; a forced system's section moves off it, see
        ``HybridShootingProblem.rechart``) or deep inside (a guess or a predicted point far
        from any orbit)."""
        X = self.x0(y)
        H = float(np.asarray(self.c.probe(X), dtype=float).ravel()[0])
        if abs(H) <= self.ON_SURFACE * (1.0 + float(np.max(np.abs(X[: self.c.n])))):
            return ("; the orbit meets the impact surface at the Poincare section (an impact "
                    "or a grazing at the section's time)")
        return ("; the state at the section lies inside the obstacle: the guess (or the "
                "predicted point) is far from any orbit")

    def residual_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c = self.c
        res = self.simulate(y)
        fi = self.free_idx
        g = res.X[fi] - self.x0(y)[fi]
        # angles that may turn (the pendulum's lower bar): periodicity modulo their period
        g = wrap_periodic(g, fi, self.c.system.periodic)
        cols = fi + list(range(c.n, c.N))
        Jm = res.J[np.ix_(fi, cols)].copy()
        Jm[:, : len(fi)] -= np.eye(len(fi))
        return g, Jm

    def poincare_jacobian(self, y: np.ndarray) -> np.ndarray:
        res = self.simulate(y)
        fi = self.free_idx
        return res.J[np.ix_(fi, fi)]

    def trivial_error(self, y: np.ndarray) -> float:
        """``|Phi_T F(x0) - F(x_T)| / |F|`` with ``Phi_T = P_x - F(x_T) J_t``."""
        c = self.c
        res = self.simulate(y)
        X0 = self.x0(y)
        n = c.n
        F0 = np.asarray(c.f(X0), dtype=float).ravel()[:n]
        FT = np.asarray(c.f(res.X), dtype=float).ravel()[:n]
        Phi = res.J[:n, :n] - np.outer(FT, res.Jt[:n])
        return float(np.linalg.norm(Phi @ F0 - FT) / max(np.linalg.norm(F0), 1e-300))

    def monodromy_noise(self, y: np.ndarray) -> float:
        """Absolute accuracy of ``P_z`` (and of its eigenvalues): ``(rtol + 10 eps) |Phi_T|_2``
        with ``Phi_T = P_x - F(x_T) J_t`` the time-fixed monodromy. The sensitivities are
        integrated to about the tolerance *relative to* ``|Phi_T|``; where ``|Phi_T|`` is large
        and cancels in ``P_x = Phi_T + F J_t`` (an orbit lingering near a saddle: ``|Phi_T| ~
        exp(mu T)``) that error stays in ``P_x``. Measured near the pendulum's homoclinic orbit:
        the computed multiplier is ``~ 0.1 rtol |Phi_T|`` (rtol 1e-10) to ``0.3 rtol |Phi_T|``
        (rtol 1e-13), ``~ 5 eps |Phi_T|`` at rtol 1e-14; for an ordinary orbit ``|Phi_T| ~ |P|``
        and this is ``~ rtol |P|``."""
        c = self.c
        res = self.simulate(y)
        n = c.n
        FT = np.asarray(c.f(res.X), dtype=float).ravel()[:n]
        Phi = res.J[:n, :n] - np.outer(FT, res.Jt[:n])
        rtol = float(self.sim.o.rtol)
        return float((rtol + 10.0 * np.finfo(float).eps) * np.linalg.norm(Phi, 2))

    def time_resolution(self, y: np.ndarray) -> float:
        """How finely the return time can be set through the unknowns: ``eps sum_j |dt/dX0_j|
        |X0_j|`` over the section coordinates and the lifted parameters (the rounding of each
        unknown; the fixed section coordinate is a constant of the problem). Near a homoclinic
        orbit it is dominated by the parameter, ``eps |p| / (mu |p - p*|)``."""
        c = self.c
        res = self.simulate(y)
        X0 = self.x0(y)
        cols = self.free_idx + list(range(c.n, c.N))
        return float(np.finfo(float).eps * np.sum(np.abs(res.Jt[cols] * X0[cols])))

    def map_noise(self, y: np.ndarray) -> float:
        """Absolute noise of the simulated section state (the value of ``G``):
        ``rtol + 4 eps (1 + tau)^2`` with ``tau`` the sticking time. The round-off of each
        sticking step kicks the state off the sticking manifold along its neutral Jordan block
        (``H' = v``, ``v' = 0``; the state is not projected back while sticking), so the drift
        grows as ``tau^2``. Measured on the double pendulum near its homoclinic orbit (sec. 6.3:
        deviation from a quadratic of ``G`` along 21 section states 1e-13 apart, at ``tau`` =
        10, 31, 61, for every rtol from 1e-11 to 1e-14): 2 eps ``(1 + tau)^2`` in ``q2`` (the
        coordinate the period depends on most), 0.8 eps in ``q1dot``, 7.5 eps in ``q2dot``;
        ~1e-10 at rtol 1e-10."""
        res = self.simulate(y)
        eps = np.finfo(float).eps
        return float(self.sim.o.rtol + 4.0 * eps * (1.0 + res.sticking_time) ** 2)

    def period_uncertainty(self, y: np.ndarray) -> float:
        """Uncertainty of the period of the orbit through ``y`` as a function of the parameter
        (the periodic orbit at the computed parameter has this period to within it): the
        orbit solved at a prescribed period ``T`` (``[G; t - T] = 0`` in ``(z, p)``, Jacobian
        ``A``) moves by ``-A^-1 dF`` under errors ``dF`` of the residual, its parameter by
        ``w . dF`` (``w = e_p^T A^-1``), which is the period error ``w . dF / w_t`` along the
        branch (``dp/dT = w_t``). With ``dF = (map_noise, ..., time_resolution)``:
        ``dT = time_resolution + map_noise sum_j |w_j| / |w_t|``. Near a homoclinic orbit
        ``dT ~ dp / (mu |p - p*|)`` grows like ``exp(mu T)``."""
        c = self.c
        res = self.simulate(y)
        _, J = self.residual_jacobian(y)
        cols = self.free_idx + list(range(c.n, c.N))
        m = J.shape[0]
        A = np.vstack([J[:, : m + 1], res.Jt[cols][None, : m + 1]])
        e_p = np.zeros(m + 1)
        e_p[m] = 1.0
        try:
            w = np.linalg.solve(A.T, e_p)
        except np.linalg.LinAlgError:
            return float("inf")
        dT = self.time_resolution(y)
        if w[m] == 0.0 or not np.all(np.isfinite(w)):
            return float("inf")
        return float(dT + self.map_noise(y) * np.sum(np.abs(w[:m])) / abs(w[m]))


class PeriodShooting:
    """The shooting problem with the period prescribed (``continuation.parameter: period``).

    Unknowns ``y = (z, p, T)``: the section coordinates ``z``, the freed parameter ``p`` (lifted
    into the state, its column of the Jacobian exact) and the period ``T``, the continuation
    parameter. Residual ``[G(z, p); t_ret(z, p) - T]`` (``G`` of :class:`HybridShooting`,
    ``t_ret`` the simulated return time) with the exact Jacobian
    ``[[G_z, G_p, 0], [J_t,z, J_t,p, -1]]`` (``J_t = dt/dX0``, :attr:`SimResult.Jt`). Every other
    member takes the augmented ``y`` and works on ``y[:-1]`` with the wrapped
    :class:`HybridShooting` (one cache: the same ``(z, p)`` at another ``T`` is not simulated
    again).
    """

    def __init__(self, inner: HybridShooting) -> None:
        self.inner = inner
        self.c = inner.c
        self.section = inner.section
        self.sim = inner.sim
        self.free_idx = inner.free_idx

    @property
    def n_simulations(self) -> int:
        return self.inner.n_simulations

    @staticmethod
    def shooting_unknowns(y: np.ndarray) -> np.ndarray:
        """``(z, p)``: the unknowns of the wrapped problem (``y`` without the period)."""
        return np.asarray(y, dtype=float)[:-1]

    def x0(self, y: np.ndarray) -> np.ndarray:
        return self.inner.x0(self.shooting_unknowns(y))

    def simulate(self, y: np.ndarray) -> SimResult:
        return self.inner.simulate(self.shooting_unknowns(y))

    def residual_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``[G; r_T]`` and its Jacobian. ``r_T`` is ``t_ret - T`` less the resolution of the
        return time (:meth:`HybridShooting.time_resolution`, ``dt``): ``sign(t - T) max(|t - T|
        - dt, 0)``. Where ``dt`` exceeds the Newton tolerance (near a homoclinic orbit, ``dt ~
        eps |p| / (mu |p - p*|)``) no representable unknowns give ``t = T`` more closely; the
        time equation is then satisfied to that resolution (the derived ``period`` is the
        simulated ``t``), and a bound on ``period_uncertainty`` (which also counts the noise of
        the simulated map) ends the branch before the period is lost in it."""
        c = self.c
        yy = self.shooting_unknowns(y)
        g, J = self.inner.residual_jacobian(yy)
        res = self.inner.simulate(yy)
        cols = self.free_idx + list(range(c.n, c.N))
        m = g.size
        A = np.zeros((m + 1, J.shape[1] + 1))
        A[:m, :-1] = J
        A[m, :-1] = res.Jt[cols]
        A[m, -1] = -1.0
        r = res.t - float(np.asarray(y, dtype=float)[-1])
        dT = self.inner.time_resolution(yy)
        return np.append(g, np.sign(r) * max(abs(r) - dT, 0.0)), A

    def poincare_jacobian(self, y: np.ndarray) -> np.ndarray:
        return self.inner.poincare_jacobian(self.shooting_unknowns(y))

    def trivial_error(self, y: np.ndarray) -> float:
        return self.inner.trivial_error(self.shooting_unknowns(y))

    def monodromy_noise(self, y: np.ndarray) -> float:
        return self.inner.monodromy_noise(self.shooting_unknowns(y))

    def period_uncertainty(self, y: np.ndarray) -> float:
        return self.inner.period_uncertainty(self.shooting_unknowns(y))

    def time_resolution(self, y: np.ndarray) -> float:
        return self.inner.time_resolution(self.shooting_unknowns(y))


#: the name of the continuation parameter that prescribes the period (:class:`PeriodShooting`)
PERIOD = "period"

#: multipliers whose accuracy (:meth:`HybridShooting.monodromy_noise`) is at least this, with one
#: of them inside that noise band of the unit circle, cannot be classified: reported unknown
AMBIGUOUS_NOISE = 1e-2


def period_reach(c: float, mu: float, p: float, resolution: float | None = None) -> float:
    """The largest period a periodic orbit near a homoclinic orbit can be given in double
    precision: with ``|p - p*| = exp(-mu (T - c))`` and the parameter resolved only to
    ``resolution`` (default ``eps |p|``, the spacing of doubles near ``p``), the period is
    uncertain by ``resolution / (mu |p - p*|)`` and has no digit left (uncertain by ``1 / mu``)
    at ``T_max = c + ln(1 / resolution) / mu``. The pendulum of sec. 6.3 (``p = -31.0017``,
    ``mu = 0.28879``, ``c = -3.40``): ``T_max = 109.5`` with ``eps |p|``, ~85 with the ~1e-11
    to which the simulated map resolves the torque; a period of 150 needs ``|p - p*| ~ 6e-20``.
    """
    res = float(np.finfo(float).eps * abs(p)) if resolution is None else float(resolution)
    return float(c + np.log(1.0 / res) / mu)


class HybridShootingProblem(HybridPresentation, OrbitDeclarations, Problem):
    """Base class of shooting problems on a hybrid system (the concrete problem builds
    ``self.shooting`` in ``__init__`` and sets ``variables`` / ``parameter``).

    Hooks: ``derived`` (period, sticking time, impacts before the chatter map, ...), the
    admissibility tests (the sticking time ``tau`` for orbits with sticking: its zero is the
    transition to incomplete chattering, reported as ``sticking_lost``), and the event signature
    (a change is ``impact_sequence_change``).
    """

    shooting: HybridShooting
    event_kinds: ClassVar[dict[str, str]] = {
        "sticking_lost": "the sticking time tends to zero: complete chattering turns into "
                         "incomplete chattering (the branch of orbits with sticking ends; "
                         "located where the sticking time reaches its floor, extrapolated to "
                         "zero)",
        "impact_sequence_change": "the sequence of events over one period changes other than "
                                  "at a grazing (notation: I an impact, C a completed "
                                  "chattering sequence with the impacts just before it, S a "
                                  "release from sticking, - no event; how many impacts the "
                                  "simulator resolves before the chatter map is no change)",
        "homoclinic_approach": "the period grows without bound: the orbit approaches a "
                               "homoclinic orbit of a saddle (limit parameter from a fit "
                               "T ~ -ln|p - p*|/mu)",
    }
    #: the sticking time (an admissibility test of orbits with sticking) vanishes where
    #: complete chattering is lost
    test_kinds: ClassVar[dict[str, str]] = {"sticking_time": "sticking_lost"}
    #: the signed grazing margin closest to zero (``SimResult.grazing_function``): a near
    #: approach that becomes an impact, or an impact that vanishes
    event_function_kinds: ClassVar[dict[str, str]] = {"grazing_margin": "grazing"}
    signature_kind: ClassVar[str | None] = "impact_sequence_change"
    #: a bound on the period ends the branch near a homoclinic orbit, one on the sticking time
    #: where sticking is lost
    bound_kinds: ClassVar[dict[str, str]] = {"period": "homoclinic_approach",
                                             "sticking_time": "sticking_lost",
                                             # continued in the period: where it is no
                                             # longer resolved in double precision
                                             "period_uncertainty": "homoclinic_approach"}
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
        discontinuous there (issue 11, F1/F2)."""
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
        import copy

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
                           matrix_norm=float(np.linalg.norm(P, 2)), noise=float(noise))

    def orbit(self, y: np.ndarray, periods: int = 1) -> OrbitTrace:
        """The orbit at ``y`` simulated again with its trajectory recorded over ``periods``
        periods, impacts marked and sticking phases as intervals
        (:func:`~nsm_continuation.hybrid.orbit_trace.orbit_trace`)."""
        return orbit_trace(self, y, periods)

    def orbit_view_names(self) -> tuple[str, ...]:
        """The family's declared ``orbit_views`` (:class:`~.orbit_trace.OrbitDeclarations`),
        else the default time and phase views (:func:`~.orbit_trace.views_of`)."""
        return tuple(views_of(self))

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
            "n_sticking_phases": float(len(res.sticking_intervals)),
            "n_impacts": float(res.n_impacts),
            "min_impact_velocity": (float(res.min_impact_velocity)
                                    if np.isfinite(res.min_impact_velocity) else np.nan),
            # signed grazing margin: min H of the near approaches (> 0) or -v^2/(2a) of a
            # decelerating impact (< 0); crosses zero at a grazing bifurcation
            "grazing_margin": (float(res.grazing_margin) if np.isfinite(res.grazing_margin)
                               else np.nan),
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
        impact that vanished."""
        if name != "grazing_margin":
            return None
        y = np.asarray(y, dtype=float)
        tangent = np.asarray(tangent, dtype=float)
        path: list[np.ndarray] = []
        yg = locate_grazing(self.shooting, y, tol, path_out=path)
        if yg is None:
            return None
        y1 = step_beyond(self.shooting, yg, tangent, from_impacting=value < 0, ds=ds, tol=tol)
        if y1 is None:
            return None
        # the approach, kept while it still moves (|v| halves per orbit: down to 1e-3 of the
        # first one it resolves the side where the Jacobian grows like 1/|v|)
        keep = [z for k, z in enumerate(path) if k < 10]
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
        import re

        def strip(sig: str | None) -> str:
            return re.sub(r"\d+", "", sig or "")

        return strip(before) != strip(after)

    def signature(self, y: np.ndarray) -> str | None:
        res = self.sim(y)
        return None if res is None else res.signature


# ---------------------------------------------------------------------- YAML-facing base class
from abc import abstractmethod  # noqa: E402
from typing import Literal  # noqa: E402

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter  # noqa: E402

from nsm_continuation.core.problem import StartPoint  # noqa: E402
from nsm_continuation.core.vocabulary import canonical_name  # noqa: E402
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem  # noqa: E402


class IntegratorSpec(BaseModel):
    """``parameters.integrator``: numerics of the hybrid simulator (defaults are the ones the
    speed-accuracy chart in ``benchmarks/bench_chatter.py`` recommends)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    method: Literal["dop853", "dopri5"] = "dop853"
    #: at least 1e-14: below, the step error test asks for less than the round-off of a step
    rtol: float = Field(1e-10, ge=1e-14, lt=1e-2)
    atol: float = Field(1e-12, gt=0, lt=1e-2)
    chatter_tol: float = Field(1e-10, gt=0, lt=1e-2)
    chatter_order: int = Field(3, ge=1, le=4)
    max_chatter_impacts: int = Field(2000, ge=2)
    wall_time: float = Field(30.0, gt=0)
    #: a return to the Poincare section taking longer than this (simulated time) fails
    max_return_time: float = Field(1000.0, gt=0)

    def options(self, sensitivities: bool = True) -> SimOptions:
        return SimOptions(rtol=self.rtol, atol=self.atol, chatter_tol=self.chatter_tol,
                          max_time=self.max_return_time,
                          chatter_order=self.chatter_order,
                          max_chatter_impacts=self.max_chatter_impacts,
                          wall_time=self.wall_time, sensitivities=sensitivities)


class HybridStartSpec(BaseModel):
    """``start:`` of a hybrid shooting case. ``guess`` gives the section coordinates of a
    periodic orbit; without it the orbit is found by simulation from ``initial`` (a full state,
    default: the problem's) over ``transient`` returns to the section (a stable orbit)."""

    #: strict: ``true`` is not a number, ``"3"`` or ``2.0`` not an integer
    model_config = ConfigDict(extra="forbid", strict=True)
    guess: dict[str, float] | None = None
    initial: dict[str, float] | None = None
    transient: int = Field(40, ge=0)
    #: returns to the section per period (2 for a period-2 orbit)
    returns: int = Field(1, ge=1)
    direction: Literal["both", "increase", "decrease"] = "both"
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


class HybridCaseProblem(HybridShootingProblem):
    """A hybrid system with a Poincaré section, continued in any of its parameters.

    A concrete problem sets ``name``, ``Parameters`` (with an ``integrator`` field of type
    :class:`IntegratorSpec`) and implements :meth:`system` (the CasADi declaration),
    :meth:`section` and :meth:`default_initial`. Everything else (residual, Jacobian,
    multipliers, starts, events) is generic.
    """

    start_adapter: ClassVar[TypeAdapter] = START_ADAPTER
    symbolic = "SX"
    #: continued (``palc``), or swept into a brute-force bifurcation diagram (``sweep``:
    #: :mod:`~nsm_continuation.hybrid.brute_force`, Figs. 8(b), 9(b)-(c) of the paper)
    algorithms: ClassVar[tuple[str, ...]] = ("palc", "sweep")
    #: recorded returns per value of a brute-force sweep when ``start.record`` is not given
    BRUTE_FORCE_RECORD: ClassVar[int] = 10

    def __init__(self, params: BaseModel | dict[str, Any]) -> None:
        from nsm_continuation.core.vocabulary import as_parameters

        params = as_parameters(self.Parameters, params)
        super().__init__(params)
        dumped = params.model_dump()
        self.integrator: IntegratorSpec = params.integrator  # type: ignore[attr-defined]
        self.values = {k: float(v) for k, v in dumped.items()
                       if k not in self.setting_fields}
        self.check_parameters(self.values)
        self.hybrid: HybridSystem = self.system()
        self.returns = 1
        self._compiled_for: str | None = None
        #: continuing in the period: the parameter that is an unknown (:meth:`_set_period`)
        self.free_parameter: str | None = None
        self.set_parameter(self.default_parameter)

    # -- to implement -----------------------------------------------------------------------
    default_parameter: ClassVar[str] = ""
    #: ``continuation.parameter: period``: the parameter that becomes an unknown when the start
    #: block names none (``start.free_parameter``); None: the start must name it
    period_partner: ClassVar[str | None] = None
    #: fields of ``Parameters`` that set up the computation (numerics, the section) rather
    #: than the system: not CasADi parameters, and not continued
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator",)
    #: parameters :meth:`curve_parameters` puts first (the preferred second parameter of a
    #: grazing curve's ``continue_from_here`` hint): the vocabulary's obstacle position
    #: (``gap``); a family whose obstacle is placed otherwise overrides it (the double
    #: pendulum: its wall distance ``d``)
    curve_preference: ClassVar[tuple[str, ...]] = ("gap",)

    @abstractmethod
    def system(self) -> HybridSystem:
        """The CasADi declaration of the impacting system."""

    @abstractmethod
    def section(self) -> Section:
        """The Poincaré section and the shift of its coordinate per period."""

    @abstractmethod
    def default_initial(self) -> np.ndarray:
        """A state to simulate from when ``start`` gives no guess."""

    def check_parameters(self, values: dict[str, float]) -> None:
        """Physical checks with messages naming the field (override; call super)."""
        e = values.get("restitution")
        if e is not None and not 0.0 <= e < 1.0:
            raise ValueError(f"parameters.restitution: {e} must lie in [0, 1) "
                             "(complete chattering needs r = e < 1, sec. 3)")

    # -- preflight (issue 9) ------------------------------------------------------------------
    #: rough upper costs (s, 2-core machine) of one return to the section without
    #: sensitivities (the transient that finds a start) and of one continuation point per
    #: return of the period (shooting with sensitivities, multipliers, events; the pendulum
    #: takes ~0.2 s per point)
    TRANSIENT_SECONDS_PER_RETURN: ClassVar[float] = 0.05
    SECONDS_PER_POINT: ClassVar[float] = 1.0
    #: cost of the explicit Runge-Kutta integration of a stiff field: about
    #: ``STEPS_PER_STIFFNESS * rho * T`` steps per return (``rho`` the spectral radius of
    #: ``dF/dx``, ``T`` the return time) at ``SECONDS_PER_STEP`` each, and a continuation point
    #: costs about ``RETURNS_PER_POINT`` returns with sensitivities. Measured on the two-mass
    #: chain, k2 = 1e4 and 1e6 (2.2 steps per unit of rho T, 0.75-1.5e-4 s per step).
    #: largest magnitude of a start state's component (|x| beyond it: a Newton step relative to
    #: 1 + |y| no longer resolves the orbit; 1e300 was "converged" with a residual of 44)
    MAX_STATE: ClassVar[float] = 1e12
    STEPS_PER_STIFFNESS: ClassVar[float] = 2.2
    SECONDS_PER_STEP: ClassVar[float] = 1e-4
    RETURNS_PER_POINT: ClassVar[float] = 15.0

    def parameter_domain(self, name: str) -> tuple[float | None, bool, float | None, bool]:
        """``(lo, lo_open, hi, hi_open)``: the bounds the ``Parameters`` model declares for
        ``name`` (None: unbounded on that side; open: the bound itself is excluded)."""
        import annotated_types as at

        lo = hi = None
        lo_open = hi_open = False
        field = type(self.params).model_fields.get(name)
        for m in (field.metadata if field is not None else []):
            if isinstance(m, at.Gt):
                lo, lo_open = float(m.gt), True
            elif isinstance(m, at.Ge):
                lo, lo_open = float(m.ge), False
            elif isinstance(m, at.Lt):
                hi, hi_open = float(m.lt), True
            elif isinstance(m, at.Le):
                hi, hi_open = float(m.le), False
        return lo, lo_open, hi, hi_open

    def _check_window(self, lo: float | None, hi: float | None) -> None:
        """The continuation window of the continued parameter lies inside its domain (the
        ``Parameters`` bounds and :meth:`check_parameters`), and is closed on every side where
        the domain is bounded: a branch leaving the domain (e.g. ``e >= 1``, where the impact
        law has no chatter map) would fail inside the simulator."""
        name = self.parameter
        d_lo, lo_open, d_hi, hi_open = self.parameter_domain(name)
        rng = (f"{'(' if lo_open else '['}{d_lo if d_lo is not None else -np.inf:g}, "
               f"{d_hi if d_hi is not None else np.inf:g}{')' if hi_open else ']'}")
        for side, bound, d, is_open, below in (("max", hi, d_hi, hi_open, True),
                                               ("min", lo, d_lo, lo_open, False)):
            if d is None:
                continue
            if bound is None:
                raise ValueError(
                    f"continuation.{side}: continuing in {name} needs continuation.{side} "
                    f"(parameters.{name} must lie in {rng}; a branch leaving that domain "
                    "cannot be simulated)")
            outside = (bound >= d if is_open else bound > d) if below else \
                (bound <= d if is_open else bound < d)
            if outside:
                raise ValueError(f"continuation.{side}: {name} = {bound:g} is outside the "
                                 f"domain of parameters.{name}, {rng}")
        for side, bound in (("min", lo), ("max", hi)):
            if bound is None:
                continue
            try:
                self.check_parameters({**self.values, name: float(bound)})
            except ValueError as exc:
                raise ValueError(f"continuation.{side}: {name} = {bound:g} leaves the domain "
                                 f"of the parameters ({exc})") from None

    def _check_state(self, key: str, X: np.ndarray) -> None:
        """A start state (with the parameter appended) is finite, on the admissible side of the
        impact surface (``H >= 0``) and, for a mechanical system, has ``M(q)`` positive
        definite."""
        c = self.shooting.c
        if not np.all(np.isfinite(X)):
            raise ValueError(f"{key}: the state is not finite")
        big = float(np.max(np.abs(X[: c.n])))
        if big > self.MAX_STATE:
            raise ValueError(f"{key}: a state component of {big:.3g} is beyond "
                             f"{self.MAX_STATE:g}: the corrector's relative tolerance would "
                             "accept any orbit there; rescale the model")
        H = float(np.asarray(c.probe(X), dtype=float).ravel()[0])
        if H < -1e-12 * (1.0 + float(np.linalg.norm(X))):
            raise ValueError(f"{key}: the state is on the inadmissible side of the impact "
                             f"surface (H = {H:.3g} < 0)")
        try:
            c.mass_check(X)
        except HybridDeclarationError as exc:
            raise ValueError(f"{key}: {exc}") from None

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Everything checkable without simulating (``window``: bounds on the continued
        parameter, already chosen by :meth:`parameter_bounds`):

        * the window lies in the parameter's domain and is closed where the domain is bounded
          (:meth:`_check_window`); the start value ``parameters.<name>`` lies in the window;
        * ``start.guess`` names exactly the section coordinates (and comes without ``initial``
          or ``transient``, which it makes unused); ``start.initial`` names only states;
        * the start state (the guess on the section, or the initial state) is finite,
          admissible (``H >= 0``) and has ``M(q)`` positive definite;
        * time: ``transient x returns`` returns plus ``2 max_points x returns`` points
          (``TRANSIENT_SECONDS_PER_RETURN``, ``SECONDS_PER_POINT``) within the limit.
        """
        from nsm_continuation.core.preflight import as_list, check_budget

        for i, s in as_list(START_ADAPTER.validate_python(start if start is not None else {})):
            if s.record is not None:
                raise ValueError(f"start{'' if i is None else f'[{i}]'}.record: the returns "
                                 "recorded at each value of a brute-force diagram, only with "
                                 "continuation.algorithm: sweep")
        if self.parameter == PERIOD:
            self._period_preflight(start, window, max_points)
            return
        for i, s in as_list(START_ADAPTER.validate_python(start if start is not None else {})):
            if s.free_parameter is not None:
                raise ValueError(f"start{'' if i is None else f'[{i}]'}.free_parameter: only "
                                 "with continuation.parameter: period (the parameter that "
                                 f"becomes an unknown); this case continues in {self.parameter}")
        lo, hi = window
        name = self.parameter
        self._check_window(lo, hi)
        p0 = self.values[name]
        if (lo is not None and p0 < lo) or (hi is not None and p0 > hi):
            raise ValueError(
                f"parameters.{name}: the start value {p0:g} lies outside the continuation "
                f"window [{lo if lo is not None else -np.inf:g}, "
                f"{hi if hi is not None else np.inf:g}] (continuation.min/max): a branch "
                "starting there computes nothing")
        items = as_list(START_ADAPTER.validate_python(start if start is not None else {}))
        names = self.hybrid.state_names
        fi = self.shooting.free_idx
        coords = [names[j] for j in fi]
        sec = self.shooting.section
        seconds = 0.0
        for i, s in items:
            def key(field: str, i: int | None = i) -> str:
                return "start" + ("" if i is None else f"[{i}]") + f".{field}"

            if s.guess is not None:
                unknown = sorted(set(s.guess) - set(coords))
                missing = [n for n in coords if n not in s.guess]
                if unknown or missing:
                    what = (f"unknown state {unknown[0]!r}" if unknown
                            else f"missing {', '.join(missing)}")
                    raise ValueError(
                        f"{key('guess')}: {what}; a guess gives exactly the section coordinates "
                        f"{', '.join(coords)} ({names[sec.index]} = {sec.value:g} is fixed by "
                        "the section)")
                for unused in ("initial", "transient"):
                    if unused in s.model_fields_set:
                        raise ValueError(f"{key(unused)}: not used with start.guess (the guess "
                                         "is corrected directly, nothing is simulated "
                                         "before): remove one of them")
                y = np.append([s.guess[n] for n in coords], [p0])
                self._check_state(key("guess"), self.shooting.x0(y))
            else:
                X = np.append(np.asarray(self.default_initial(), dtype=float), [p0])
                for k, v in (s.initial or {}).items():
                    if k not in names:
                        raise ValueError(f"{key('initial')}: unknown state {k!r} (the states "
                                         f"are {', '.join(names)})")
                    X[names.index(k)] = v
                self._check_state(key("initial") if s.initial else "start", X)
                per_return = max(self.TRANSIENT_SECONDS_PER_RETURN, self._return_seconds(X))
                seconds += s.transient * s.returns * per_return
            per_point = self.RETURNS_PER_POINT * self._return_seconds(
                self.shooting.x0(y) if s.guess is not None else X)
            seconds += 2 * max_points * s.returns * max(self.SECONDS_PER_POINT, per_point)
        check_budget("start" if len(items) == 1 else "start[0]",
                     f"{len(items)} start{'s' if len(items) != 1 else ''} with their transient "
                     f"and continuation.max_points = {max_points}", seconds=seconds)

    def sweep_preflight(self, start: Any, window: tuple[float | None, float | None],
                        max_points: int) -> None:
        """:meth:`preflight` of a brute-force sweep (:mod:`~nsm_continuation.hybrid.
        brute_force`): a parameter of the system (not the period) over a closed window
        holding ``parameters.<name>``, one return per period (``returns: 1``, no
        ``free_parameter``), the start states checked as :meth:`preflight` does (``transient``
        is the per-value transient, allowed with ``guess``), and the time of
        ``(transient + record)`` returns per grid value within the limit."""
        from nsm_continuation.core.preflight import as_list, check_budget

        if self.parameter == PERIOD:
            raise ValueError(f"continuation.parameter: {PERIOD}: a brute-force sweep varies a "
                             "parameter of the system (the period is what it records)")
        for side, bound in (("min", window[0]), ("max", window[1])):
            if bound is None:
                raise ValueError(f"continuation.{side}: a sweep needs both ends of the window")
        items = as_list(START_ADAPTER.validate_python(start if start is not None else {}))
        checked = []
        for i, s in items:
            at = "start" + ("" if i is None else f"[{i}]")
            for key, bad in (("returns", s.returns != 1), ("free_parameter",
                                                          s.free_parameter is not None)):
                if bad:
                    raise ValueError(f"{at}.{key}: not used by a brute-force sweep (every "
                                     "return to the section is recorded)")
            # the transient is per grid value: the sweep's own budget below counts it
            drop = {"record", "transient"}
            checked.append(HybridStartSpec.model_validate(
                s.model_dump(exclude=drop, exclude_unset=True)))
        # the states and the window, as for a continuation (no continuation points)
        self.preflight(checked if len(checked) > 1 else checked[0], window, 0)
        seconds = 0.0
        p0 = self.values[self.parameter]
        for _, s in items:
            X = (self.shooting.x0(np.append([s.guess[n] for n in self.variables[:-1]], [p0]))
                 if s.guess is not None else np.append(self.default_initial(), [p0]))
            per_return = max(self.TRANSIENT_SECONDS_PER_RETURN, self._return_seconds(X))
            record = s.record if s.record is not None else self.BRUTE_FORCE_RECORD
            sweeps = 2 if s.direction == "both" else 1
            seconds += sweeps * max_points * (s.transient + record) * per_return
        check_budget("continuation.max_points",
                     f"{len(items)} brute-force start{'s' if len(items) != 1 else ''} of "
                     f"{max_points} values, transient and recorded returns", seconds=seconds)

    def sweep_seeds(self, start: Any, window: tuple[float | None, float | None]
                    ) -> list[Any]:
        """The brute-force sweeps of the start block
        (:func:`~nsm_continuation.hybrid.brute_force.sweep_seeds`)."""
        from nsm_continuation.core.preflight import as_list
        from nsm_continuation.hybrid import brute_force

        items = as_list(START_ADAPTER.validate_python(start if start is not None else {}))
        return brute_force.sweep_seeds(self, [s.model_copy(update={
            "record": s.record or self.BRUTE_FORCE_RECORD}) for _, s in items])

    def sweep_point(self, seed: Any, value: float, state: Any) -> tuple[Any, Any]:
        """The recorded section returns at ``value``
        (:func:`~nsm_continuation.hybrid.brute_force.sweep_point`)."""
        from nsm_continuation.hybrid import brute_force

        return brute_force.sweep_point(self, seed, value, state)

    def _return_seconds(self, X: np.ndarray) -> float:
        """Estimated cost of one return to the section from the full state ``X`` for an explicit
        integrator: ``STEPS_PER_STIFFNESS * rho * T`` steps, with ``rho`` the spectral radius of
        the exact ``dF/dx`` at ``X`` and ``T = |shift| / |F_index(X)|`` the return time of a
        section coordinate moving at its present rate (a clock: exact); 1 when it is at rest."""
        c = self.shooting.c
        Xs = ca.SX.sym("X", c.N)
        field = ca.Function("Fj", [Xs], [c.f(Xs), ca.jacobian(c.f(Xs), Xs)])
        try:
            F, J = (np.asarray(v, dtype=float) for v in field(X))
            rho = float(np.max(np.abs(np.linalg.eigvals(J[: c.n, : c.n]))))
        except (RuntimeError, np.linalg.LinAlgError):
            return 0.0
        sec = self.shooting.section
        rate = abs(float(F.reshape(-1)[sec.index]))
        T = abs(sec.shift) / rate if rate > 1e-12 else 1.0
        if not np.isfinite(rho * T):
            return float("inf")
        return self.SECONDS_PER_STEP * self.STEPS_PER_STIFFNESS * rho * T

    def monitor_names(self) -> list[str]:
        """The keys of :meth:`derived` at a simulated point."""
        extremes = [f"{m}_{name}" for name in self.hybrid.state_names for m in ("min", "max")]
        names = [self.parameter, "period", "sticking_time", "n_impacts_before_chatter",
                 "n_sticking_phases", "n_impacts", "min_impact_velocity", "grazing_margin",
                 *extremes, *(f"amplitude_{c}" for c in self.configuration_names)]
        if self.parameter == PERIOD:
            # the free parameter (any parameter may be named by the start block, which is read
            # after the bounds are checked; a bound on one that stays fixed never fires) and the
            # resolution of the period
            names += [k for k in self.values if k not in names] + ["period_uncertainty"]
        return names

    # -- generic ----------------------------------------------------------------------------
    def set_parameter(self, name: str, returns: int | None = None) -> None:
        if name == PERIOD and PERIOD not in self.values:
            self._set_period(self.free_parameter or self.period_partner, returns)
            return
        if name not in self.values:
            also = "" if self.forced else f", or {PERIOD}"
            raise ValueError(f"continuation.parameter: {name!r} is not a parameter of "
                             f"{self.name!r} (one of {sorted(self.values)}{also})")
        returns = self.returns if returns is None else returns
        if self._compiled_for == name and returns == self.returns:
            return
        self.parameter = name
        self.returns = returns
        try:
            c = self.hybrid.compile(self.values, free=[name], method=self.integrator.method)
        except HybridDeclarationError as exc:
            raise ValueError(f"parameters: {exc}") from None
        # a problem moved to another chart (rechart) keeps it when continued in another
        # parameter (a two-parameter curve's base problem, swapped round a turn)
        moved = self.chart() if self._compiled_for is not None else None
        sec = self.section()
        sec = Section(sec.index, sec.value, sec.shift * returns)
        self.shooting = HybridShooting(c, sec, self.integrator.options())
        self.declared_section = sec.value
        if moved is not None:
            self.shooting = self.in_chart(moved).shooting
        names = self.hybrid.state_names
        self.variables = [names[i] for i in self.shooting.free_idx] + [name]
        self._compiled_for = name

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        self.set_parameter(name)
        return lo, hi

    # -- continuation in the period (PeriodShooting) ------------------------------------------
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
        from nsm_continuation.core.preflight import as_list

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
        from nsm_continuation.core.preflight import as_list

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
            (sp,) = HybridCaseProblem.start_points(
                self, s.model_copy(update={"free_parameter": None}))
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

    def derived(self, y: np.ndarray) -> dict[str, float]:
        """The hybrid derived quantities; continued in the period, also the free parameter
        (its value at the point) and ``period_uncertainty``
        (:meth:`HybridShooting.period_uncertainty`)."""
        out = super().derived(y)
        if self.parameter == PERIOD and self.free_parameter is not None:
            out[self.free_parameter] = float(np.asarray(y, dtype=float)[-2])
            try:
                out["period_uncertainty"] = self.shooting.period_uncertainty(
                    np.asarray(y, dtype=float))
            except ShootingFailure:
                out["period_uncertainty"] = np.nan
        return out

    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> Any:
        """Through a grazing as :meth:`HybridShootingProblem.continue_beyond`; not when
        continued in the period (the grazing normal form works on ``(z, p)``)."""
        if self.parameter == PERIOD:
            return None
        return super().continue_beyond(name, y, tangent, value, ds, tol)

    def tangent_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray,
                       value_before: float) -> np.ndarray | None:
        if self.parameter == PERIOD:
            return None
        return super().tangent_beyond(name, y, tangent, value_before)

    def transient(self, X: np.ndarray, returns: int) -> np.ndarray:
        """State on the section after ``returns`` section crossings from ``X`` (no
        sensitivities): the orbit a stable periodic orbit is found from."""
        c = self.shooting.c
        sim = Simulator(c, self.integrator.options(sensitivities=False))
        sec = self.section()
        Xc = X.copy()
        if abs(Xc[sec.index] - sec.value) > 1e-12:
            # first reach the section
            target = sec.value
            if sec.shift < 0 and Xc[sec.index] < target:
                target -= abs(sec.shift)
            if sec.shift > 0 and Xc[sec.index] > target:
                target += abs(sec.shift)
            res = sim.run(Xc, section=(sec.index, target, sec.direction))
            Xc = res.X.copy()
            Xc[sec.index] = sec.value
        for _ in range(returns):
            res = sim.run(Xc, section=(sec.index, sec.value + sec.shift, sec.direction))
            Xc = res.X.copy()
            Xc[sec.index] = sec.value
        return Xc

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        if self.parameter == PERIOD:
            return self._period_start_points(start)
        specs = START_ADAPTER.validate_python(start if start is not None else {})
        specs = specs if isinstance(specs, list) else [specs]
        out = []
        names = self.hybrid.state_names
        for s in specs:
            self.set_parameter(self.parameter, s.returns)
            c = self.shooting.c
            fi = self.shooting.free_idx
            p0 = self.values[self.parameter]
            if s.guess is not None:
                unknown = set(s.guess) - {names[i] for i in fi}
                missing = {names[i] for i in fi} - set(s.guess)
                if unknown or missing:
                    raise ValueError(f"start.guess: needs exactly {[names[i] for i in fi]} "
                                     f"(unknown {sorted(unknown)}, missing {sorted(missing)})")
                z = np.array([s.guess[names[i]] for i in fi])
                how = "guess"
            else:
                X = np.append(self.default_initial(), [p0])
                if s.initial is not None:
                    for k, v in s.initial.items():
                        if k not in names:
                            raise ValueError(f"start.initial: unknown state {k!r} (one of "
                                             f"{names})")
                        X[names.index(k)] = v
                try:
                    Xs = self.transient(X, s.transient * s.returns)
                except (SimulationError, HybridDeclarationError) as exc:
                    raise ValueError(f"start: transient simulation failed ({exc})") from None
                z = wrap_periodic(Xs[fi], fi, self.hybrid.periodic)
                how = f"simulation ({s.transient} periods)"
            y = np.append(z, [p0])
            d = {"both": 0, "increase": 1, "decrease": -1}[s.direction]
            label = s.label or (f"period-{s.returns} orbit" if s.returns > 1 else
                                "period-1 orbit")
            out.append(StartPoint(y, label, d, {"start": how, "returns": s.returns,
                                                "n_state": c.n}))
        return out

    # -- restart & branch switching (nsm_continuation.cases.restart) -------------------------------
    def period_multiple(self) -> int:
        """The returns to the section per period (``start.returns``)."""
        return int(self.returns)

    def iterated(self, multiple: int) -> HybridCaseProblem:
        """The same system, continued in the same parameter, with ``multiple`` returns to the
        section per period (the ``multiple``-times iterated return map)."""
        new = type(self)(self.params)
        new.set_parameter(self.parameter, multiple)
        return new.in_chart(self.chart())

    def with_parameters(self, values: dict[str, float]) -> HybridCaseProblem:
        """The same system with ``values`` changed, continued in the same parameter (or in the
        period with the same free parameter) with the same number of returns."""
        data = self.params.model_dump()
        for name, value in values.items():
            if name not in self.values:
                raise ValueError(f"{name!r} is not a parameter of {self.name!r} (one of "
                                 f"{sorted(self.values)})")
            data[name] = float(value)
        new = type(self)(self.Parameters.model_validate(data))
        if self.parameter == PERIOD and self.free_parameter is not None:
            new.free_parameter = self.free_parameter
            new._set_period(self.free_parameter, self.returns)
        else:
            new.set_parameter(self.parameter, self.returns)
        return new.in_chart(self.chart())

    def curve_parameters(self) -> list[str]:
        """Every parameter of the system (not the ``setting_fields``): a grazing curve
        (:class:`~nsm_continuation.hybrid.codim1.GrazingCurve`) may free or continue any of
        them; those of ``curve_preference`` first (in its order), then the others in the
        order of ``Parameters``."""
        first = [q for q in self.curve_preference if q in self.values]
        return first + [q for q in self.values if q not in first]

    def restart_start(self, y: np.ndarray) -> dict[str, Any]:
        """``{guess: <section coordinates of y>, returns: k}`` (and ``free_parameter`` for a
        continuation in the period, whose unknowns end with that parameter and the period)."""
        in_period = self.parameter == PERIOD and self.free_parameter is not None
        n_state = len(self.variables) - (2 if in_period else 1)
        names = list(self.variables[:n_state])
        block: dict[str, Any] = {
            "guess": {n: float(v) for n, v in zip(names, y[:n_state], strict=True)},
            "returns": self.period_multiple()}
        if in_period:
            block["free_parameter"] = self.free_parameter
        return block

    def summary(self) -> dict[str, Any]:
        sec = self.shooting.section
        out = {"parameters": dict(self.values), "integrator": self.integrator.model_dump(),
               "section": {"coordinate": self.hybrid.state_names[sec.index],
                           "value": sec.value, "shift_per_period": sec.shift},
               "unknowns": list(self.variables)}
        if self.parameter == PERIOD:
            out["continued_in_period"] = {"free_parameter": self.free_parameter}
        return out
