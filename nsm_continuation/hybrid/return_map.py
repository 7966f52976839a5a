"""The return map of an impacting system on a Poincaré section, its residual and exact Jacobian.

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
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from nsm_continuation.core.floquet.norms import spectral_norm
from nsm_continuation.hybrid.simulate import SimOptions, SimResult, SimulationError, Simulator
from nsm_continuation.hybrid.system import CompiledHybrid, HybridDeclarationError


@dataclass
class Section:
    """Poincaré section ``x[index] = value``; one period moves ``x[index]`` by ``shift`` (an
    angle or a clock that advances), and the section is met where it reaches ``value +
    shift``, moving that way."""

    index: int
    value: float
    shift: float

    @property
    def direction(self) -> int:
        return 1 if self.shift > 0 else -1

    @property
    def crossings(self) -> int:
        """Crossings of the section per period (one: the coordinate reaches ``value +
        shift`` once)."""
        return 1

    @property
    def target(self) -> tuple[int, float, int]:
        """The end of a return, as :meth:`.simulate.Simulator.run` takes it: ``(index, value
        + shift, direction)``."""
        return self.index, self.value + self.shift, self.direction

    def repeated(self, periods: int) -> Section:
        """The section of an orbit of ``periods`` periods (the iterated return map): the
        coordinate moves ``periods`` times as far."""
        return replace(self, shift=self.shift * periods)


@dataclass
class CrossingSection(Section):
    """A Poincaré section ``x[index] = value`` of an autonomous system crossed in ``crossing``
    (``-1`` falling, ``+1`` rising); ``returns`` crossings make one period. The section
    coordinate comes back to its value (``shift = 0``).

    ``surface`` (an index of the system's surfaces, whose impact surface is ``x[index] =
    value``): the section is that surface's impacts, its points the post-impact states (the
    flight leaving the surface crosses ``x[index] = value`` in ``crossing``). It is transversal
    to the flow wherever the impact velocity is not zero, i.e. along a whole family of orbits
    that impact the surface, where a section between the walls turns tangent to the flow as
    soon as the section coordinate has a turning point at the section's value."""

    crossing: int = -1
    returns: int = 1
    surface: int | None = None

    def __post_init__(self) -> None:
        if self.crossing not in (-1, 1):
            raise ValueError(f"section.crossing: {self.crossing} must be -1 (falling) or +1 "
                             "(rising)")
        if int(self.returns) < 1:
            raise ValueError(f"section.returns: {self.returns} must be at least 1")
        if self.shift != 0:
            raise ValueError(f"section.shift: {self.shift}: the coordinate of a crossing section "
                             "comes back to its value (0; a Section takes a shift)")

    @property
    def direction(self) -> int:
        return self.crossing

    @property
    def crossings(self) -> int:
        return int(self.returns)

    def repeated(self, periods: int) -> CrossingSection:
        """``periods`` times as many crossings, in the same direction."""
        return replace(self, returns=int(self.returns) * int(periods))


def chain_returns(parts: list[SimResult]) -> SimResult:
    """One :class:`SimResult` for consecutive returns to a section (each started where the
    previous one ended): times added, events and intervals shifted, ``J`` and ``J_t`` composed
    by the caller (:func:`run_returns`), extremes merged."""
    if len(parts) == 1:
        return parts[0]
    t0 = 0.0
    events, sticking, margins, surfaces = [], [], [], []
    for res in parts:
        for ev in res.events:
            events.append(type(ev)(ev.kind, ev.t + t0, ev.x, ev.info, ev.surface))
        sticking += [(a + t0, b + t0) for a, b in res.sticking_intervals]
        margins += list(res.grazing_margins)
        surfaces += list(res.grazing_surfaces)
        t0 += float(res.t)
    last = parts[-1]
    ext = None
    if all(r.extremes is not None for r in parts):
        ext = np.column_stack([np.min([r.extremes[:, 0] for r in parts], axis=0),
                               np.max([r.extremes[:, 1] for r in parts], axis=0)])
    return SimResult(
        X=last.X, t=t0, J=last.J, Jt=last.Jt, events=events, state=last.state,
        sticking_intervals=sticking,
        chatter_counts=[k for r in parts for k in r.chatter_counts],
        n_impacts=int(sum(r.n_impacts for r in parts)),
        min_impact_velocity=float(min(r.min_impact_velocity for r in parts)),
        grazing_margin=float(min(r.grazing_margin for r in parts)),
        chatter_errors=[e for r in parts for e in r.chatter_errors], trajectory=None,
        n_steps=int(sum(r.n_steps for r in parts)), ended_by=last.ended_by, bounds=ext,
        grazing_margins=margins, grazing_surfaces=surfaces, surface_names=last.surface_names)


def crossing_failure(c: CompiledHybrid, section: Section, X0: np.ndarray, res: SimResult,
                     atol: float) -> str | None:
    """Why the orbit from ``X0`` does not cross a section whose coordinate returns to its
    value (``shift = 0``, :class:`CrossingSection`) as a periodic orbit must, or None. The
    section coordinate's rate ``F_k(X0)`` must have the section's sign (an orbit through the
    section the other way returns only after half a turn) and move it by more than the
    integrator's absolute tolerance over the period, ``|F_k| t > atol``: below that the orbit
    has shrunk onto an equilibrium on the section (a Hopf point, where the family of a smooth
    system is born) and the crossing is no longer resolved; past it the shooting would go on
    along the equilibrium, which the return map fixes without being a periodic orbit."""
    if section.shift != 0:
        return None  # the coordinate advances by |shift| a period: a crossing, always
    rate = section.direction * float(np.asarray(c.calls().f.flat(X0))[section.index])
    name = c.system.state_names[section.index]
    if rate <= 0.0:
        return (f"the state on the section moves against the section's crossing direction "
                f"(d{name}/dt = {section.direction * rate:.3g}): not on an orbit crossing it "
                f"{'rising' if section.direction > 0 else 'falling'} (a guess off the orbit, "
                "or past the equilibrium on the section that the orbit shrinks onto at a Hopf "
                "point)")
    if rate * float(res.t) <= atol:
        return (f"the orbit has shrunk onto an equilibrium on the section (d{name}/dt = "
                f"{rate:.3g} there, moving {name} by {rate * float(res.t):.3g} over the period, "
                f"below atol = {atol:.3g}): a Hopf point, where the family is born")
    return None


def section_return(sim: Simulator, X: np.ndarray, section: Section) -> SimResult:
    """The simulation from ``X`` to the next point of ``section``: its next crossing, or, for a
    :class:`CrossingSection` on a surface, just after the next impact on it."""
    if isinstance(section, CrossingSection) and section.surface is not None:
        return sim.run(X, stop_impact=section.surface)
    return sim.run(X, section=section.target)


def run_returns(sim: Simulator, X0: np.ndarray, section: Section) -> SimResult:
    """One period from ``X0`` on ``section``: its :attr:`~Section.crossings` returns, chained
    (one simulation for a section met once per period). ``J = J_k ... J_1`` and ``J_t =
    sum_k J_t,k J_(k-1) ... J_1``; each return restarts exactly on the section, its row of
    ``J`` zero (the time to the section absorbs it)."""
    k_all = section.crossings
    if k_all == 1:
        return section_return(sim, X0, section)
    parts: list[SimResult] = []
    X = X0
    J = Jt = None
    for k in range(k_all):
        res = section_return(sim, X, section)
        if res.J is not None:
            Jt = res.Jt.copy() if J is None else Jt + res.Jt @ J  # type: ignore[operator]
            J = res.J.copy() if J is None else res.J @ J
        parts.append(res)
        if k + 1 < k_all:
            X = res.X.copy()
            X[section.index] = section.value
            if J is not None:
                J[section.index, :] = 0.0
    out = chain_returns(parts)
    if J is not None:
        out.J, out.Jt = J, Jt
    return out


class ShootingFailure(Exception):
    pass


class SimulationCache:
    """The last ``size`` simulations by the unknowns they were run from: the run, or the reason
    it failed (a :class:`ShootingFailure` at each lookup, without simulating again), so that
    the residual, its Jacobian and the derived quantities at one point simulate once."""

    def __init__(self, size: int = 16) -> None:
        self.size = size
        #: simulations run (lookups that found nothing)
        self.n_simulations = 0
        self._runs: OrderedDict[bytes, SimResult | str] = OrderedDict()

    def clear(self) -> None:
        """Forget every simulation."""
        self._runs.clear()

    def get(self, y: np.ndarray, run: Callable[[], SimResult],
            explain: Callable[[str], str] | None = None) -> SimResult:
        """The simulation from the unknowns ``y``: kept, else ``run()`` (a
        :class:`SimulationError`'s reason, completed by ``explain``, or a
        :class:`HybridDeclarationError` is kept as the failure)."""
        key = np.asarray(y, dtype=float).tobytes()
        hit = self._runs.get(key)
        if hit is None:
            try:
                hit = run()
            except SimulationError as exc:
                hit = exc.reason if explain is None else explain(exc.reason)
            except HybridDeclarationError as exc:  # e.g. r >= 1 at an impact (e past 1)
                hit = str(exc)
            self.n_simulations += 1
            self._runs[key] = hit
            if len(self._runs) > self.size:
                self._runs.popitem(last=False)
        if isinstance(hit, str):
            raise ShootingFailure(hit)
        return hit


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
        self._cache = SimulationCache(cache_size)

    @property
    def cache_size(self) -> int:
        """How many simulations are kept (a copy of this shooting keeps as many)."""
        return self._cache.size

    @property
    def n_simulations(self) -> int:
        """Simulations run."""
        return self._cache.n_simulations

    def x0(self, y: np.ndarray) -> np.ndarray:
        """Full initial state (with the freed parameters) from the unknowns ``y``."""
        c = self.c
        X = np.empty(c.N)
        X[self.free_idx] = y[: c.n - 1]
        X[self.section.index] = self.section.value
        X[c.n:] = y[c.n - 1:]
        return X

    def simulate(self, y: np.ndarray) -> SimResult:
        """The return from ``y`` (:class:`SimulationCache`): :func:`run_returns` on the
        section, refused with the reason of :func:`crossing_failure`; a start inside the
        obstacle says how far (:meth:`_inadmissible_start`)."""

        def run() -> SimResult:
            X0 = self.x0(y)
            res = run_returns(self.sim, X0, self.section)
            why = crossing_failure(self.c, self.section, X0, res, self.sim.o.atol)
            if why is not None:
                raise SimulationError(why)
            return res

        def explain(reason: str) -> str:
            if reason.startswith("initial state on the inadmissible side"):
                return reason + self._inadmissible_start(y)
            return reason

        return self._cache.get(y, run, explain)

    #: an initial state this far inside the obstacle (relative to its size) is a guess off
    #: any orbit; closer, an orbit on the surface at the section's time
    ON_SURFACE = 1e-6

    def _inadmissible_start(self, y: np.ndarray) -> str:
        """Why the state at the section lies inside the obstacle: on the surface (an impact
        or a grazing at the section's time; a forced system's section moves off it, see
        ``HybridShootingProblem.rechart``) or deep inside (a guess or a predicted point far
        from any orbit)."""
        X = self.x0(y)
        H = float(np.min(self.c.surface_values(X)))
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
        return float((rtol + 10.0 * np.finfo(float).eps) * spectral_norm(Phi))

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


class IntegratedShooting(Protocol):
    """A shooting problem whose Jacobian is integrated (:class:`HybridShooting`,
    :class:`PeriodShooting`, the conservative families' shooting)."""

    sim: Simulator

    def monodromy_noise(self, y: np.ndarray) -> float: ...


def shooting_jacobian_noise(shooting: IntegratedShooting, y: np.ndarray,
                            jacobian: np.ndarray) -> float:
    """The accuracy of a shooting Jacobian ``jacobian`` at ``y`` in the 2-norm
    (:meth:`~nsm_continuation.core.problem.Problem.jacobian_noise`): the sensitivities are
    integrated to about the tolerance relative to the larger of the time-fixed monodromy
    (:meth:`HybridShooting.monodromy_noise`) and the Jacobian itself (its parameter column),
    ``(rtol + 10 eps) max(|Phi_T|_2, |G_y|_2)``."""
    rtol = float(shooting.sim.o.rtol)
    scaled = (rtol + 10.0 * np.finfo(float).eps) * spectral_norm(jacobian)
    return max(float(shooting.monodromy_noise(y)), scaled)


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

