"""What a hybrid shooting case checks before it simulates anything (its preflight).

The continuation window inside the continued parameter's domain (the ``Parameters`` bounds and
the family's physical checks), the start block against the section coordinates and the states,
each start state finite, admissible (``H >= 0``) and with ``M(q)`` positive definite, and the
estimated time of the transients and of the continuation points within the limit (the cost of
an explicit Runge-Kutta integration of a stiff field from the spectral radius of ``dF/dx``);
the same for a brute-force sweep (:mod:`.brute_force`). Mixed into
:class:`~.case.HybridCaseProblem`.
"""

from __future__ import annotations

from typing import Any, ClassVar

import annotated_types as at
import casadi as ca
import numpy as np

from nsm_continuation.core.preflight import as_list, check_budget
from nsm_continuation.hybrid.return_map import PERIOD, HybridShooting
from nsm_continuation.hybrid.specs import START_ADAPTER, HybridStartSpec
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem


class CasePreflight:
    """The preflight checks of :class:`~.case.HybridCaseProblem` (see the module docstring)."""

    # set by the case problem
    params: Any
    values: dict[str, float]
    parameter: str
    variables: list[str]
    hybrid: HybridSystem
    shooting: HybridShooting
    BRUTE_FORCE_RECORD: ClassVar[int]

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
        Hs = c.surface_values(X)
        for i, H in enumerate(Hs):
            if H < -1e-12 * (1.0 + float(np.linalg.norm(X))):
                raise ValueError(f"{key}: the state is on the inadmissible side of "
                                 f"{c.surface_label(i)} (H = {H:.3g} < 0)")
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
