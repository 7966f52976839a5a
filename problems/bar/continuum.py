"""Continuum limit of the WFEM nonsmooth modes of the bar as a YAML problem (Yoong, Thorin,
Legrand 2017, sec. 5-6): its straight branches ``t_f = a T + b`` in closed form
(:mod:`problems.bar.continuum_orbits`: signatures, jump sets, energy, admissibility) continued
with the generic pseudo-arclength engine.

Continuation unknowns ``y = (omega_ratio, contact_fraction, sig_a, sig_b)``: ``omega_ratio =
omega/omega_1`` (``omega_1 = pi c / (2L)``, eq. 13; ``T = 4/omega_ratio``), ``contact_fraction =
(T - t_f)/T``; the residual is

    G = [ contact_fraction - (1 - a) + b omega_ratio / 4,  sin(pi a / 2),  sin(pi b / 4) ]

(three equations, four unknowns): the switching-time relation, linear in ``y``, and the
integrality of the signature (``a`` even, ``b`` a multiple of 4), whose roots are isolated and
simple. The signature is thus part of the state, so one case can continue several branches
(modes 1 and 2, subharmonics) with one residual; along a branch ``(sig_a, sig_b)`` stay at their
integer values (the tangent has no component along them).
"""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

import casadi as ca
import numpy as np
from nsm_continuation.problems.bar.continuum_orbits import (
    RING_TOL,
    ContinuumOrbit,
    Signature,
    check_signature,
    continuum_orbit,
    jump_set,
    main_signature,
    subharmonic_signature,
)
from nsm_continuation.problems.bar.presentation import BarContinuumPresentation
from nsm_continuation.problems.bar.wfem_operators import check_reference_energy
from pydantic import (
    BaseModel,
    Discriminator,
    Field,
    Tag,
    TypeAdapter,
    field_validator,
)

from nsm_continuation.core.preflight import (
    STRICT,
    as_list,
    check_budget,
    check_gap,
    one_or_many,
    start_key,
)
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.vocabulary import CanonicalNames, as_parameters

PosFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]


# -- YAML ------------------------------------------------------------------------------------------
class BarContinuumParameters(CanonicalNames):
    """YAML ``parameters`` of ``problem: bar_continuum`` (cross-section S = 1, as the lattice);
    ``gap`` is the paper's ``g0``."""


    model_config = STRICT
    #: Young's modulus ``E``
    E: PosFloat = 1.0
    #: density ``rho`` (wave speed ``c = sqrt(E / rho)``)
    rho: PosFloat = 1.0
    #: the bar's length ``L`` (clamped at ``x = 0``, contact at ``x = L``)
    L: PosFloat = 1.0
    #: the gap ``g0``: contact at ``u(L) = gap``; > 0 open, < 0 prestressed (nonzero:
    #: the vertical line of ``gap = 0`` is ``problem: wfem_bar``'s)
    gap: Annotated[float, Field(allow_inf_nan=False)]

    @field_validator("gap")
    @classmethod
    def _nonzero(cls, v: float) -> float:
        if v == 0.0:
            raise ValueError("must be nonzero: for g0 = 0 the branch is the vertical line at the "
                             "asymptote (amplitude free), not a curve in (omega, contact "
                             "fraction); use problem: wfem_bar")
        return check_gap(v)


class _StartBase(BaseModel):
    model_config = STRICT
    #: starting frequency; default: middle of the admissible interval for the sign of g0
    omega_ratio: PosFloat | None = None
    #: which way along ``continuation.parameter`` the branch is followed
    direction: Literal["both", "increase", "decrease"] = "both"


class MainStart(_StartBase):
    """Main backbone of mode k (sec. 6.1)."""

    #: the main backbone
    branch: Literal["main"]
    #: the mode ``k``
    mode: Annotated[int, Field(ge=1, le=100)] = 1


class SubharmonicStart(_StartBase):
    """n-th subharmonic backbone of mode k (sec. 6.2)."""

    #: a subharmonic backbone
    branch: Literal["subharmonic"]
    #: the mode ``k``
    mode: Annotated[int, Field(ge=1, le=100)] = 1
    #: the subharmonic's order ``n``
    n: Annotated[int, Field(ge=1, le=100)] = 1


class SignatureStart(_StartBase):
    """An explicit signature ``[a, b]``: the branch ``t_f = a T + b`` (``m = a M + b N``)."""

    #: ``[a, b]``: the free time ``t_f = a T + b`` in units of ``L / c``
    signature: Annotated[list[int], Field(min_length=2, max_length=2)]

    @field_validator("signature")
    @classmethod
    def _valid(cls, v: list[int]) -> list[int]:
        check_signature(Signature(v[0], v[1]))
        return v


def _start_kind(v: Any) -> str:
    """Which start model a YAML mapping is: by its ``signature`` or ``branch`` key."""
    if isinstance(v, dict):
        kind = "signature" if "signature" in v else v.get("branch", "main")
    else:
        kind = "signature" if isinstance(v, SignatureStart) else getattr(v, "branch", "main")
    # any other branch value is validated (and refused, naming start.branch) as a main start;
    # capitalised tags are left out of error locations (cases._format)
    return kind.capitalize() if kind in ("signature", "main", "subharmonic") else "Main"


StartSpec = Annotated[Annotated[MainStart, Tag("Main")]
                      | Annotated[SubharmonicStart, Tag("Subharmonic")]
                      | Annotated[SignatureStart, Tag("Signature")], Discriminator(_start_kind)]
#: ``start:`` is one start mapping or a list of them
START_ADAPTER = one_or_many(StartSpec)


# -- the problem -----------------------------------------------------------------------------------
class BarContinuumProblem(Problem):
    """Elastic bar with a unilateral contact, continuum limit (Yoong, Thorin, Legrand 2017).
    Its nonsmooth modes are straight branches ``t_f = a T + b``
    (:mod:`problems.bar.continuum_orbits`)."""

    presentation_class = BarContinuumPresentation
    #: the figures depend on the results and the parameters only
    figures_from_inputs: ClassVar[bool] = True

    name: ClassVar[str] = "bar_continuum"
    energy_quantity: ClassVar[str | None] = "energy_ratio"
    Parameters: ClassVar[type[BaseModel]] = BarContinuumParameters
    start_adapter: ClassVar[TypeAdapter] = START_ADAPTER

    def __init__(self, params: BarContinuumParameters | dict[str, Any]) -> None:
        params = as_parameters(BarContinuumParameters, params)
        super().__init__(params)
        self.E, self.rho, self.L, self.g0 = params.E, params.rho, params.L, params.gap
        self.c = float(np.sqrt(self.E / self.rho))
        self.omega1 = float(np.pi * self.c / (2 * self.L))
        #: eq. (14): energy of the first linear mode's grazing orbit
        self.energy_ref = float(np.pi**2 * self.E * self.g0**2 / (16 * self.L))
        #: energy at |mu| = 2 (both phase-end limits of g0 < 0 branches): the margin scale
        self.energy_0 = float(self.E * self.g0**2 / (2 * self.L))
        self.variables = ["omega_ratio", "contact_fraction", "sig_a", "sig_b"]
        self.parameter = "omega_ratio"
        if not (np.isfinite(self.omega1) and self.omega1 > 0):
            raise ValueError(f"parameters.E: E, rho and L give omega_1 = pi c / (2L) = "
                             f"{self.omega1:.3g}, not a positive finite number: rescale them")
        check_reference_energy(self.E, self.L, self.g0)

    # ------------------------------------------------------------------ preflight
    #: seconds of one orbit evaluation (jump set, end series, margins) ~ A + B |a| (laps + 1)
    #: + C laps, with laps = floor(T/2) + 1 the turns of the characteristics in one period
    #: (measured: 1.3 ms for t_f = 8T - 24, 0.7 s for |a| = 20000, 88 ms for T = 3000)
    ORBIT_SECONDS: ClassVar[tuple[float, float, float]] = (1e-3, 2e-5, 6e-5)
    #: bytes of one orbit evaluation per (jump x lap) (Python lists of breakpoints)
    ORBIT_BYTES: ClassVar[float] = 100.0
    #: orbit evaluations per continuation point (corrector, derived values, events)
    EVALUATIONS_PER_POINT: ClassVar[int] = 10
    #: a non-backbone signature's admissible intervals are sampled at this many periods
    SAMPLES: ClassVar[int] = 2001
    #: one admissibility sample ~ A + B |a| (laps + 1) + C laps seconds (0.12 ms for
    #: t_f = 4 - 2T, 0.8 ms for t_f = 2T - 400, 1.4 ms for t_f = 200 T - 4000)
    SAMPLE_SECONDS: ClassVar[tuple[float, float, float]] = (1e-4, 2e-6, 4e-6)
    #: the preflight samples a non-backbone's admissible intervals itself (to refuse a start
    #: without admissible orbit; the run reuses them) when the estimate is at most this
    PREFLIGHT_SAMPLING_SECONDS: ClassVar[float] = 5.0

    def orbit_cost(self, sig: Signature, T_max: float) -> tuple[float, float]:
        """(seconds, bytes) of one orbit evaluation of ``sig`` at periods up to ``T_max``."""
        laps = np.floor(T_max / 2.0) + 1.0
        work = abs(sig.a) * (laps + 1.0)
        A, B, C = self.ORBIT_SECONDS
        return A + B * work + C * laps, self.ORBIT_BYTES * (work + 3 * laps)

    def sampling_seconds(self, sig: Signature) -> float:
        """Estimated seconds of :meth:`admissible_intervals` for a non-backbone ``sig``."""
        laps = np.floor(sig.T_range[1] / 2.0) + 1.0
        A, B, C = self.SAMPLE_SECONDS
        return self.SAMPLES * (A + B * abs(sig.a) * (laps + 1.0) + C * laps)

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Everything checkable before computing (``window``: omega_ratio):

        * the size of each branch: one orbit evaluation costs ``~|a| (laps + 1)`` (jumps times
          turns of the characteristics in the longest period the run reaches: the branch's
          range, the window, the start) in time and memory (:meth:`orbit_cost`); the run needs
          ``EVALUATIONS_PER_POINT x 2 max_points`` of them per branch (plus ``SAMPLES`` to place
          the start of a non-backbone), within the memory and time limits;
        * ``start.omega_ratio`` inside the branch's range (``0 <= t_f <= T``) and the start
          (given, or the middle of the admissible interval) inside the window;
        * a non-backbone signature without admissible orbit for the sign of the gap and no
          ``omega_ratio`` is refused (its intervals are sampled here when that is cheap).
        """
        lo, hi = window
        items = as_list(START_ADAPTER.validate_python(start))
        seconds, memory = 0.0, 0.0
        for i, s in items:
            sig = self.signature_from_spec(s)
            field = "signature" if isinstance(s, SignatureStart) else "mode"
            key = start_key(i, field)
            T_lo, T_hi = sig.T_range
            T_max = max(T_hi, 4.0 / lo if lo else T_hi, 4.0 / s.omega_ratio if s.omega_ratio
                        else T_hi)
            t_orbit, bytes_orbit = self.orbit_cost(sig, T_max)
            seconds += self.EVALUATIONS_PER_POINT * 2 * max_points * t_orbit + (
                0.0 if sig.is_backbone else self.sampling_seconds(sig))
            memory = max(memory, bytes_orbit)
            what = f"the branch {sig.label()} ({abs(sig.a)} profile jumps, periods up to " \
                   f"{T_max:.4g} L/c)"
            check_budget(key, f"{what} with continuation.max_points = {max_points}",
                         memory_bytes=memory, seconds=seconds)
            r_lo, r_hi = 4.0 / T_hi, 4.0 / T_lo
            if s.omega_ratio is not None:
                if not r_lo * (1 - 1e-12) <= s.omega_ratio <= r_hi * (1 + 1e-12):
                    raise ValueError(
                        f"{start_key(i, 'omega_ratio')}: {s.omega_ratio:g} is outside the range "
                        f"of the branch {sig.label()}: omega/omega_1 in [{r_lo:.6g}, "
                        f"{r_hi:.6g}] (where 0 <= t_f <= T)")
                r0 = s.omega_ratio
            elif sig.is_backbone or \
                    self.sampling_seconds(sig) <= self.PREFLIGHT_SAMPLING_SECONDS:
                intervals = self.admissible_intervals(sig)
                if not intervals:
                    raise ValueError(f"{key}: the branch {sig.label()} has no admissible orbit "
                                     f"for gap = {self.g0:g}; give start.omega_ratio to "
                                     "continue its phantom orbits")
                a, b = max(intervals, key=lambda iv: iv[1] - iv[0])
                r0 = 0.5 * (a + b)
            else:
                continue
            if (lo is not None and r0 < lo) or (hi is not None and r0 > hi):
                raise ValueError(
                    f"{start_key(i, 'omega_ratio') if s.omega_ratio is not None else key}: the "
                    f"branch {sig.label()} starts at omega/omega_1 = {r0:.6g}, outside the "
                    f"window [{lo if lo is not None else 0:g}, "
                    f"{hi if hi is not None else np.inf:g}] (continuation.min/max): a branch "
                    "starting there computes nothing")

    def monitor_names(self) -> list[str]:
        return ["omega", "omega_ratio", "T", "t_free", "t_contact", "contact_fraction",
                "energy", "energy_ratio", "mu", "stress_amplitude", "grazing_instants",
                "profile_jumps", "sig_a", "sig_b"]

    # ------------------------------------------------------------------ residual
    def residual(self, y: Any) -> Any:
        """Switching-time relation ``t_f = a T + b`` in ``(omega_ratio, contact_fraction)`` and
        the integrality of ``(a, b)`` (module docstring)."""
        r, phi, a, b = y[0], y[1], y[2], y[3]
        return ca.vertcat(phi - (1 - a) + b * r / 4, ca.sin(np.pi * a / 2),
                          ca.sin(np.pi * b / 4))

    # ------------------------------------------------------------------ state
    @staticmethod
    def signature_of(y: np.ndarray) -> Signature:
        return Signature(int(round(float(y[2]))), int(round(float(y[3]))))

    def continuum_orbit(self, y: np.ndarray) -> ContinuumOrbit:
        """The normalised orbit at ``y`` (period ``4/omega_ratio`` in units L/c)."""
        return continuum_orbit(self.signature_of(y), 4.0 / float(y[0]))

    def point(self, sig: Signature, omega_ratio: float) -> np.ndarray:
        """The solution ``y`` of branch ``sig`` at ``omega_ratio`` (exact: G is linear)."""
        return np.array([omega_ratio, (1 - sig.a) - sig.b * omega_ratio / 4, sig.a, sig.b],
                        dtype=float)

    def energy_of_mu(self, mu: float) -> float:
        """``E_tot = 2 S E g0^2 / (L mu^2)`` (inf at the asymptote)."""
        return 2 * self.E * self.g0**2 / (self.L * mu**2) if mu != 0 else float("inf")

    # ------------------------------------------------------------------ hooks
    def derived(self, y: np.ndarray) -> dict[str, float]:
        orb = self.continuum_orbit(y)
        unit = self.L / self.c
        mu = orb.mu
        energy = self.energy_of_mu(mu)
        graz = np.abs(orb.free_partial_sums[1]) <= RING_TOL * max(orb.T, 1.0)
        return {
            "omega": float(y[0]) * self.omega1, "omega_ratio": float(y[0]),
            "T": orb.T * unit, "t_free": orb.sig.t_free(orb.T) * unit,
            "t_contact": (orb.T - orb.sig.t_free(orb.T)) * unit,
            "contact_fraction": float(y[1]),
            "energy": energy, "energy_ratio": energy / self.energy_ref,
            "mu": mu, "stress_amplitude": 2 * self.E * self.g0 / (self.L * mu) if mu else np.inf,
            "grazing_instants": int(np.sum(graz)), "profile_jumps": len(orb.jumps),
            "sig_a": orb.sig.a, "sig_b": orb.sig.b,
        }

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        """COND1-COND3 (sec. 5.1) of the continuum orbit, exact, plus the phase durations.

        Each condition's natural margin (``>= 0`` admissible) is multiplied by
        ``kappa = E_0/E_tot = mu^2/4`` (``E_0 = E g0^2/(2L)``): the natural margins scale with the
        amplitude ``A ~ 1/mu`` and jump through infinity at the energy asymptote, the scaled ones
        cross zero there linearly (``sign(g0) mu / 2`` times a bounded factor), so the engine
        locates the change of admissible side exactly. With ``P(t) = int_0^t J/A``:

        * ``cond1_gap = kappa min_t (g0 - u_end(t))/|g0| = min_t sign(g0) mu/2 P(t)`` over the
          breakpoints of the piecewise-linear ``u_end`` inside the free phase, excluding grazing
          instants (``P = 0``: the end touches the obstacle, admissible; counted in ``derived``);
        * ``cond2_contact = kappa min (-sigma_end) L/(E |g0|) = min -sign(g0) mu/2 J/A`` over the
          segments of the contact phase (``sigma_end = J`` there);
        * ``cond3_strain = kappa (1 - max|sigma|/E) = mu^2/4 - |g0| |mu| / (2L)``;
        * ``free_phase = t_f/T`` and ``contact_phase = (T - t_f)/T``: the ends of the branch.
        """
        orb = self.continuum_orbit(y)
        mu = orb.mu
        scale = float(np.sign(self.g0)) * mu / 2  # kappa * (natural unit) * sign(A)
        _, P = orb.free_partial_sums
        P = P[np.abs(P) > RING_TOL * max(orb.T, 1.0)]  # grazing instants P = 0 are admissible
        cond1 = float(np.min(scale * P)) if P.size else 0.0
        Jc = orb.contact_values()
        cond2 = float(np.min(-scale * Jc)) if Jc.size else abs(scale)
        return {
            "free_phase": orb.sig.t_free(orb.T) / orb.T,
            "contact_phase": float(y[1]),
            "cond1_gap": cond1,
            "cond2_contact": cond2,
            "cond3_strain": mu**2 / 4 - abs(self.g0) * abs(mu) / (2 * self.L),
        }

    # ------------------------------------------------------------------ starts and bounds
    def signature_from_spec(self, spec: BaseModel) -> Signature:
        if isinstance(spec, MainStart):
            return main_signature(spec.mode)
        if isinstance(spec, SubharmonicStart):
            return subharmonic_signature(spec.mode, spec.n)
        return Signature(*spec.signature)

    def admissible_intervals(self, sig: Signature, samples: int = 2001
                             ) -> list[tuple[float, float]]:
        """``omega_ratio`` intervals where the branch is admissible for the sign of g0.

        Backbones (closed form): ``(T*, T_contact_end)`` for g0 > 0 (hardening from omega_k),
        ``(T_free_end, T*)`` for g0 < 0 (softening from Omega_k). Other signatures: sampled on
        ``samples`` periods (only used to place a start; the engine locates the ends exactly).
        """
        if sig.is_backbone:
            T_lo, T_hi = ((sig.T_asymptote, sig.T_contact_end) if self.g0 > 0
                          else (sig.T_free_end, sig.T_asymptote))
            return [(4.0 / T_hi, 4.0 / T_lo)]
        memo = self.__dict__.setdefault("_intervals", {})
        if (sig, samples) in memo:  # sampled once (the preflight's result serves the run)
            return list(memo[(sig, samples)])
        memo[(sig, samples)] = out = self._sampled_intervals(sig, samples)
        return list(out)

    def _sampled_intervals(self, sig: Signature, samples: int) -> list[tuple[float, float]]:
        lo, hi = sig.T_range
        Ts = np.linspace(lo, hi, samples)[1:-1]
        ok = np.array([min(self.admissibility(self.point(sig, 4.0 / T)).values()) > 0
                       for T in Ts])
        out = []
        i = 0
        while i < len(Ts):
            if ok[i]:
                j = i
                while j + 1 < len(Ts) and ok[j + 1]:
                    j += 1
                out.append((4.0 / Ts[j], 4.0 / Ts[i]))
                i = j + 1
            else:
                i += 1
        return out

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        specs = START_ADAPTER.validate_python(start)
        specs = specs if isinstance(specs, list) else [specs]
        out = []
        for s in specs:
            sig = self.signature_from_spec(s)
            check_signature(sig)
            intervals = self.admissible_intervals(sig)
            if s.omega_ratio is None and not intervals:
                raise ValueError(f"signature {tuple(sig)}: no admissible orbit for gap = "
                                 f"{self.g0:g}; give start.omega_ratio to continue phantoms")
            inside = [iv for iv in intervals
                      if s.omega_ratio is not None and iv[0] <= s.omega_ratio <= iv[1]]
            lo, hi = (inside or sorted(intervals, key=lambda iv: iv[0] - iv[1]) or
                      [(np.nan, np.nan)])[0]
            r0 = s.omega_ratio if s.omega_ratio is not None else 0.5 * (lo + hi)
            if isinstance(s, MainStart):
                label = f"main backbone, mode {s.mode}"
            elif isinstance(s, SubharmonicStart):
                label = f"subharmonic n = {s.n} of mode {s.mode}"
            else:
                label = f"signature {tuple(sig)}"
            d = {"both": 0, "increase": 1, "decrease": -1}[s.direction]
            out.append(StartPoint(self.point(sig, r0), f"{label} ({sig.label()})", d,
                                  {"signature": [sig.a, sig.b],
                                   "omega_ratio_asymptote": (sig.omega_ratio_asymptote
                                                             if sig.is_backbone else None),
                                   "admissible_omega_ratio": [lo, hi]}))
        return out

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """Bounds on ``omega_ratio`` from bounds on ``omega_ratio``, ``omega`` or ``T``."""
        if name == "omega_ratio":
            return lo, hi
        if name == "omega":
            return (None if lo is None else lo / self.omega1,
                    None if hi is None else hi / self.omega1)
        if name == "T":
            conv = 2 * np.pi / self.omega1
            return (None if hi is None else conv / hi,
                    None if lo is None or lo <= 0 else conv / lo)
        raise ValueError(f"continuation.parameter: {name!r} is not one of 'omega_ratio', "
                         "'omega', 'T'")


__all__ = ["BarContinuumProblem", "ContinuumOrbit", "Signature", "check_signature",
           "continuum_orbit", "jump_set", "main_signature", "subharmonic_signature"]
