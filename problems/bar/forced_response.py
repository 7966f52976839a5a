"""Forced response of the damped bar with contact as a YAML problem (section 7, Figs. 20-22).

Yoong, Thorin, Legrand (2017), section 7: the bar of section 2 with a small viscous damping
(``rho u_tt + eta u_t - E u_xx = f``), forced by a harmonically moving wall
``w(t) = w0 sin(omega t)`` (the gap becomes ``g = g0 + w(t) - u(L, t)``) and/or a uniform
distributed force ``f = f0 sin(omega t)``; the total energy of the steady state averaged over
one forcing period is plotted against the forcing frequency for increasing frequencies and
several dampings (Figs. 20-22 (a): moving wall, (b): distributed force; Fig. 20: g0 > 0,
21: g0 = 0, 22: g0 < 0). The steady state at each frequency is found by time stepping
(Algorithm 2, :func:`problems.bar.forced_steady_state.forced_response_point`), warm-started from
the steady state at the previous frequency, by the ``sweep`` algorithm
(:class:`nsm_continuation.algorithms.sweep.Sweep`), one sweep (branch) per damping ratio.

YAML::

    problem: wfem_forced_bar
    parameters: {cells: 100, gap: 1.0e-3, wall_amplitude: 2.0e-3, force_amplitude: 0.0,
                 damping_ratio: [0.01, 0.02, 0.05]}
    start: {warm_start: true}
    continuation: {parameter: omega_ratio, min: 0.25, max: 4.0, max_points: 40,
                   direction: increase}

``damping_ratio`` is the modal damping ratio ``zeta_1`` of the first fixed-free mode,
``eta = 2 rho omega_1 zeta_1`` (mass-proportional: the same amplitude decay time
``2 rho / eta`` for every mode); ``continuation.max_points`` is the number of forcing
frequencies (``numpy.linspace(min, max, max_points)``), ``parameter`` is ``omega_ratio``
(``omega / omega_1``, eq. 13) or ``omega``. Optional: ``transient_periods`` (10),
``average_periods`` (8), ``transient_time`` (3 decay times), ``max_time`` (12 decay times;
required with a zero damping), ``steady_tol`` (2e-3), ``switching`` (``subcell`` or ``grid``):
:func:`problems.bar.forced_steady_state.steady_state_rule`.

Each point: ``energy_ratio`` (the period-averaged energy over ``E_ref`` of eq. 14; absolute for
g0 = 0), ``amplitude`` (half the peak-to-peak end displacement), ``steady`` and ``multiple``
(1: T-periodic, k: kT-periodic, 0: not steady within ``max_time``, quasi-periodic or chaotic as
in the paper between the NSM branches), ``contact_fraction`` and the linear references in
closed form: without contact (clamped-free, force: :func:`linear_forced_energy`,
:func:`linear_forced_end_amplitude`) or, for the wall alone with g0 < 0, in permanent contact
(fixed-fixed with a moving end, :func:`linear_wall_response`, where the contact force stays
compressive).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import main_backbone
from nsm_continuation.problems.bar.forced_steady_state import (
    ForcedPoint,
    SteadyStateRule,
    forced_response_point,
    steady_state_rule,
)
from nsm_continuation.problems.bar.linear_forced import (
    linear_forced_end_amplitude,
    linear_forced_energy,
    linear_wall_response,
)
from nsm_continuation.problems.bar.presentation import ForcedBarPresentation
from nsm_continuation.problems.bar.wfem_operators import check_reference_energy
from nsm_continuation.problems.bar.wfem_stepping import BarParams, Loading, rest_state
from pydantic import BaseModel, BeforeValidator, Field, field_validator, model_validator

from nsm_continuation.algorithms.sweep import SweepProblem, sweep_point_record
from nsm_continuation.core.capabilities import SweepSeed
from nsm_continuation.core.monitors import Monitors, signature
from nsm_continuation.core.preflight import STRICT, as_list, check_budget, check_gap, one_or_many
from nsm_continuation.core.records import Point
from nsm_continuation.core.vocabulary import CanonicalNames, as_parameters

PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
#: a damping ratio of the first mode (``zeta_1``); 1 is critical damping of that mode
DampingRatio = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]


def _as_list(v: Any) -> Any:
    """A single value as a one-element list (``damping_ratio: 0.01`` or ``[0.01, 0.02]``)."""
    return v if isinstance(v, list) else [v]


class ForcedBarParameters(CanonicalNames):
    """The ``parameters:`` block of ``wfem_forced_bar`` (module docstring): ``cells`` is the
    paper's ``N``, ``gap`` its ``g0``, ``wall_amplitude`` its ``w0``, ``force_amplitude`` its
    ``f0``."""


    model_config = STRICT
    #: Young's modulus ``E``
    E: PosFloat = 1.0
    #: density ``rho``
    rho: PosFloat = 1.0
    #: the bar's length ``L``
    L: PosFloat = 1.0
    #: the number of WFEM cells (the paper's ``N``)
    cells: Annotated[int, Field(ge=2, le=100_000)] = 100
    #: the gap ``g0`` at rest: contact at ``u(L) = g0 + w(t)``
    gap: Finite = 1e-3
    #: ``w0`` of the wall ``w(t) = w0 sin(omega t)`` (section 7)
    wall_amplitude: Finite = 0.0
    #: ``f0`` of the uniform force ``f = f0 sin(omega t)`` (section 7)
    force_amplitude: Finite = 0.0
    #: ``zeta_1``, a number or a list (one sweep per value): ``eta = 2 rho omega_1 zeta_1``
    damping_ratio: Annotated[list[DampingRatio], BeforeValidator(_as_list),
                             Field(min_length=1, max_length=10)] = [0.01]
    #: forcing periods simulated before the averages are compared (at least
    #: ``transient_time`` too)
    transient_periods: Annotated[int, Field(ge=0, le=1_000_000)] = 10
    #: forcing periods per block of period averages (blocks are simulated until the
    #: averages repeat, k-periodic to ``steady_tol``)
    average_periods: Annotated[int, Field(ge=2, le=10_000)] = 8
    #: the shortest transient (time; default 3 decay times ``2 rho / eta``)
    transient_time: NonNegFloat | None = None
    #: the longest simulation per frequency (time; default 12 decay times; required
    #: with a zero damping): beyond it the response is recorded as not steady
    max_time: PosFloat | None = None
    #: relative tolerance of the k-periodicity of the period averages
    steady_tol: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 2e-3
    #: contact switches on the time grid (``grid``, the paper's algorithm, exactly
    #: energy-conserving without damping) or inside the step (``subcell``)
    switching: Literal["grid", "subcell"] = "subcell"

    @field_validator("gap")
    @classmethod
    def _gap_range(cls, v: float) -> float:
        return check_gap(v)

    @model_validator(mode="after")
    def _excited_and_bounded(self) -> ForcedBarParameters:
        if self.wall_amplitude == 0.0 and self.force_amplitude == 0.0:
            raise ValueError("force_amplitude: wall_amplitude and force_amplitude are both 0: "
                             "nothing forces the bar (section 7 moves the wall or applies a "
                             "distributed force)")
        if self.max_time is None and 0.0 in self.damping_ratios:
            raise ValueError("max_time: required with a zero damping_ratio (without damping "
                             "there is no decay time to scale the time budget per frequency)")
        return self

    @property
    def damping_ratios(self) -> list[float]:
        return list(self.damping_ratio)


class ForcedStart(BaseModel):
    """A sweep: warm-started from the previous frequency's steady state (default), or from
    rest at every frequency."""

    model_config = STRICT
    #: start each frequency from the previous one's steady state (else from rest)
    warm_start: bool = True


def response_kind(multiple: int) -> str:
    """The signature of a steady state: periodic, period k T (subharmonic) or not steady."""
    if multiple == 1:
        return "periodic"
    return f"period {multiple} T" if multiple > 1 else "not steady"


class WfemForcedBarProblem(SweepProblem):
    """Elastic bar with a unilateral contact, WFEM: steady forced response (Yoong et al. 2017).
    Over a frequency grid (sec. 7; module docstring)."""

    presentation_class = ForcedBarPresentation
    #: the figures depend on the results and the parameters only
    figures_from_inputs: ClassVar[bool] = True

    name: ClassVar[str] = "wfem_forced_bar"
    Parameters: ClassVar[type[BaseModel]] = ForcedBarParameters
    start_adapter = one_or_many(ForcedStart)
    energy_quantity: ClassVar[str | None] = "energy_ratio"
    event_kinds: ClassVar[dict[str, str]] = {
        "response_change": "the kind of steady response changes between two consecutive "
                           "forcing frequencies of the sweep (periodic, period k T: "
                           "subharmonic, not steady: quasi-periodic or chaotic within the time "
                           "budget); recorded at the first frequency of the new kind",
    }
    monitors: ClassVar[Monitors] = SweepProblem.monitors.with_(signature("response_change"))
    #: seconds per simulated step (a + b N, measured on the shared 2-core machine under load:
    #: 12 us at N = 100, 18 us at N = 1600; an upper estimate)
    STEP_SECONDS: ClassVar[tuple[float, float]] = (1.5e-5, 5e-9)
    #: bytes per simulated step of one call of ``simulate`` (time, end displacement, energy,
    #: velocity, force, contact; period averages of a block)
    STEP_BYTES: ClassVar[float] = 64.0

    def __init__(self, params: ForcedBarParameters | dict[str, Any]) -> None:
        params = as_parameters(ForcedBarParameters, params)
        super().__init__(params)
        p = params
        self.bar = BarParams(E=p.E, rho=p.rho, L=p.L, N=p.cells, g0=p.gap)
        self.variables = ["omega_ratio", "energy_ratio"]
        self.parameter = "omega_ratio"
        self._check_scales()

    # -- model ------------------------------------------------------------------------------
    def _check_scales(self) -> None:
        """The bar's scales are representable (as for ``wfem_bar``)."""
        bar = self.bar
        for name, v in (("omega_1 = pi c / (2L)", bar.omega1), ("dt = L / (N c)",
                                                                bar.time_step)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"parameters.E: E, rho and L give {name} = {v:.3g}, not a "
                                 "positive finite number: rescale them")
        check_reference_energy(bar.E, bar.L, bar.g0)

    @property
    def energy_scale(self) -> float:
        """``E_ref`` of eq. (14), or 1 for g0 = 0 (absolute energies, as for ``wfem_bar``)."""
        return self.bar.energy_ref if self.bar.g0 != 0 else 1.0

    def eta(self, zeta: float) -> float:
        """``eta = 2 rho omega_1 zeta_1`` (decay time ``2 rho / eta`` for every mode)."""
        return 2.0 * self.bar.rho * self.bar.omega1 * zeta

    def rule(self, eta: float) -> SteadyStateRule:
        """The steady-state rule of the parameters at damping ``eta``."""
        p = self.params
        return steady_state_rule(self.bar, eta, p.transient_periods, p.average_periods,
                                 p.transient_time, p.max_time, p.steady_tol, p.switching)

    def loading(self, eta: float) -> Loading:
        """Amplitudes and damping (the frequency is set per point)."""
        return Loading(f0=self.params.force_amplitude, w0=self.params.wall_amplitude,
                       eta=float(eta))

    def linear_reference(self, omega: float, eta: float) -> tuple[float, float]:
        """``(E / E_ref, end amplitude)`` of the linear reference in closed form (module
        docstring), NaN where there is none (the wall alone with g0 >= 0: the bar stays at
        rest without contact; g0 < 0 where the contact would not be permanent)."""
        p, bar = self.params, self.bar
        if p.force_amplitude != 0.0:
            return (linear_forced_energy(bar, p.force_amplitude, omega, eta) / self.energy_scale,
                    abs(linear_forced_end_amplitude(bar, p.force_amplitude, omega, eta)))
        if bar.g0 < 0.0:
            energy, margin = linear_wall_response(bar, p.wall_amplitude, omega, eta)
            if margin >= 0.0:
                return energy / self.energy_scale, abs(p.wall_amplitude)
        return math.nan, math.nan

    # -- preflight --------------------------------------------------------------------------
    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """``omega_ratio`` or ``omega`` (divided by omega_1); forcing frequencies are > 0."""
        if name not in ("omega_ratio", "omega"):
            raise ValueError(f"continuation.parameter: wfem_forced_bar sweeps the forcing "
                             f"frequency 'omega_ratio' (omega / omega_1) or 'omega', not "
                             f"{name!r}")
        if lo is not None and lo <= 0:
            raise ValueError(f"continuation.min: forcing frequencies must be > 0 (got {lo:g})")
        scale = self.bar.omega1 if name == "omega" else 1.0
        return (None if lo is None else lo / scale, None if hi is None else hi / scale)

    def steps_per_frequency(self, eta: float, omega_ratio: float) -> tuple[int, int]:
        """Upper bound on the steps simulated at one frequency, and on the longest single
        call of ``simulate`` (transient or block), from :class:`SteadyStateRule`."""
        rule = self.rule(eta)
        dt = self.bar.time_step
        T = 2.0 * math.pi / (omega_ratio * self.bar.omega1)
        n_tr = math.ceil(max(rule.n_periods_transient * T, rule.min_transient_time) / dt)
        n_blk = math.ceil(rule.n_periods_average * T / dt) + 1
        return max(n_tr, math.ceil(rule.max_time / dt)) + n_blk, max(n_tr, n_blk)

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """The window (both ends, > 0), the starts, and the budget: ``max_points`` frequencies
        per sweep, one sweep per start and damping ratio, both directions counted (the
        direction is not known here), each frequency at most :meth:`steps_per_frequency`
        steps at the lowest frequency, ``STEP_SECONDS`` per step; memory ``STEP_BYTES`` per
        step of the longest ``simulate`` call."""
        lo, hi = window
        for key, v in (("continuation.min", lo), ("continuation.max", hi)):
            if v is None:
                raise ValueError(f"{key}: a frequency sweep needs both ends of the window "
                                 "(continuation.min and continuation.max)")
        assert lo is not None
        specs = as_list(self.start_adapter.validate_python(start))
        steps = longest = 0
        for zeta in self.params.damping_ratios:
            try:
                total, call = self.steps_per_frequency(self.eta(zeta), lo)
            except ValueError as exc:
                raise ValueError(f"parameters: {exc}") from None
            steps += total
            longest = max(longest, call)
        sweeps = 2 * len(specs)
        N = self.bar.N
        check_budget("parameters.transient_time", f"a single simulation of {longest:.3g} "
                     f"steps ({N} cells, lowest frequency {lo:g} omega_1)",
                     memory_bytes=self.STEP_BYTES * longest + 16.0 * N)
        per_step = self.STEP_SECONDS[0] + self.STEP_SECONDS[1] * N
        check_budget("continuation.max_points",
                     f"{sweeps} x {max_points} frequencies of up to {steps:.3g} steps "
                     f"({N} cells, {len(self.params.damping_ratios)} damping ratios)",
                     seconds=sweeps * max_points * steps * per_step)

    # -- the sweep --------------------------------------------------------------------------
    def sweep_seeds(self, start: Any, window: tuple[float | None, float | None]
                    ) -> list[SweepSeed]:
        """One sweep per start and damping ratio, from rest (:func:`rest_state`: unstressed
        for g0 >= 0, compressed against the wall for g0 < 0) with forcing phase 0."""
        specs = start if isinstance(start, ForcedStart) else \
            self.start_adapter.validate_python(start)
        seeds = []
        for _, spec in as_list(specs):
            for zeta in self.params.damping_ratios:
                eta = self.eta(zeta)
                label = f"zeta_1 = {zeta:g} (eta = {eta:.4g})"
                if not spec.warm_start:
                    label += ", from rest at each frequency"
                seeds.append(SweepSeed(label, (rest_state(self.bar), 0.0), 0,
                                       {"damping_ratio": zeta, "eta": eta,
                                        "warm_start": spec.warm_start}))
        return seeds

    def sweep_point(self, seed: SweepSeed, value: float, state: Any) -> tuple[Point, Any]:
        """The steady state at ``omega = value * omega_1`` from ``state = (BarState, forcing
        phase)`` (:func:`forced_response_point`; from rest with phase 0 without warm start)."""
        eta = float(seed.info["eta"])
        st, phase = state if seed.info["warm_start"] else (rest_state(self.bar), 0.0)
        omega = value * self.bar.omega1
        pt, st, phase = forced_response_point(self.bar, self.loading(eta), omega, st, phase,
                                              self.rule(eta))
        derived = self.point_quantities(pt, value, seed.info)
        point = sweep_point_record(np.array([value, derived["energy_ratio"]]), derived,
                                   seed.direction, self.parameter_index,
                                   response_kind(pt.multiple))
        return point, (st, phase)

    def point_quantities(self, pt: ForcedPoint, omega_ratio: float,
                         info: dict[str, Any]) -> dict[str, float]:
        """The derived quantities of a steady state (module docstring)."""
        lin_e, lin_a = self.linear_reference(pt.omega, float(info["eta"]))
        return {"omega": pt.omega, "omega_ratio": omega_ratio, "energy": pt.energy_mean,
                "energy_ratio": pt.energy_mean / self.energy_scale,
                "linear_energy_ratio": lin_e, "amplitude": 0.5 * (pt.u_max - pt.u_min),
                "linear_amplitude": lin_a, "u_max": pt.u_max, "u_min": pt.u_min,
                "steady": float(pt.steady), "multiple": float(pt.multiple),
                "contact_fraction": pt.contact_fraction, "steps": float(pt.n_steps),
                "damping_ratio": float(info["damping_ratio"]), "eta": float(info["eta"])}

    def monitor_names(self) -> list[str]:
        return ["omega", "omega_ratio", "energy", "energy_ratio", "amplitude", "u_max", "u_min",
                "contact_fraction", "steps"]


__all__ = ["ForcedBarParameters", "ForcedStart", "WfemForcedBarProblem", "main_backbone",
           "response_kind"]
