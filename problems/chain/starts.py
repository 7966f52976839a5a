"""Starts, continuation bounds and the checks made before computing, for the chain.

:class:`ChainStarts` (a mixin of
:class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`): the start points of the
YAML ``start`` block (a linear grazing orbit (2.14) at a pole ``k T_j`` of ``w_N``, Theorem 3.1;
the closed form (4.2) at a period; every branch of a window, or the trivial branch for
``g = 0``, sec. 7.2), the bounds on ``omega`` or ``T``, and :meth:`ChainStarts.preflight`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from nsm_continuation.problems.chain.modal import ModalModel
from nsm_continuation.problems.chain.parameters import (
    START_ADAPTER,
    AllStart,
    ModeStart,
    PeriodStart,
)

from nsm_continuation.core.preflight import as_list, start_key
from nsm_continuation.core.problem import StartPoint


class ChainStarts:
    """Start points and bounds of a chain's continuation, and its preflight."""

    N: int
    c: int
    g: float
    formulation: str
    P: np.ndarray
    T_lin: np.ndarray
    a: np.ndarray
    modal: ModalModel
    #: +1 continued in T, -1 in omega (set by :meth:`parameter_bounds`)
    _orientation: int

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Everything checkable before computing (``window``: bounds on ``T``):

        * sizes: the dense matrices within ``NSM_CONTINUATION_MAX_MEMORY_GB``
          (:meth:`memory_estimate`, ``MEMORY_DOUBLES_PER_N2 N^2`` doubles) and the run time
          ``2 x branches x max_points x`` :meth:`seconds_per_point` within
          ``NSM_CONTINUATION_MAX_HOURS``; only then the modal analysis (O(N^3)) is done, here,
          once (it is reused by the run);
        * the modal analysis succeeds (finite matrices, ``K`` positive definite) and resolves
          ``omega_1`` (:attr:`.ModalModel.MODAL_RESOLUTION`); frequencies in ``[1e-100, 1e100]``;
        * ``start.mode <= N``, ``gap != 0`` for a mode start, the start period ``k T_j`` (mode,
          subharmonic) or ``T`` inside the window (a start outside it computes nothing);
          ``all: true`` needs both window ends, and its number of branches (the poles
          ``k T_j`` in the window, ``k <= max_subharmonic``) enters the time estimate.

        The gap range (``0`` or ``1e-100 <= |g| <= 1e100``) is checked with the parameters
        (:func:`nsm_continuation.core.preflight.check_gap`).
        """
        lo, hi = window
        for T in (lo, hi):
            if T is not None and not (np.isfinite(T) and T > 0):
                raise ValueError(f"continuation: continuation.min/max give the period bound "
                                 f"T = {T:g}, not a positive finite number")
        items = as_list(START_ADAPTER.validate_python(start))
        self.check_size()
        for i, s in items:
            if self.formulation == "shooting" and (
                    isinstance(s, ModeStart) or (isinstance(s, AllStart) and self.g != 0.0)):
                key = start_key(i, "mode" if isinstance(s, ModeStart) else "all")
                raise ValueError(f"{key}: this start lies on a pole k T_j (a linear grazing "
                                 "orbit), where the Jacobian of formulation: shooting loses "
                                 "rank and Newton cannot converge; use formulation: half_angle "
                                 "(the default) or start: {T: ...} off the poles")
        for i, s in items:
            if isinstance(s, ModeStart):
                key = start_key(i, "mode")
                if s.mode > self.N:
                    raise ValueError(f"{key}: {s.mode} is beyond the {self.N} modes of the "
                                     f"chain (1..{self.N})")
                if self.g == 0.0:
                    raise ValueError(f"{key}: a start at a linear grazing orbit needs "
                                     "parameters.gap != 0 (for gap = 0 use start: {all: true})")
            elif isinstance(s, AllStart) and (lo is None or hi is None):
                raise ValueError(f"{start_key(i, 'all')}: needs continuation.min and "
                                 "continuation.max (the window whose branches are computed)")
            elif isinstance(s, PeriodStart):
                self._check_in_window(start_key(i, "T"), "the start period T", s.T, window)
        n_explicit = sum(1 for _, s in items if not isinstance(s, AllStart))
        self._check_time(max(n_explicit, 1), max_points)
        self.modal.check_resolution()
        n_all, setup = 0, 0.0
        for i, s in items:
            if isinstance(s, ModeStart):
                j, k = s.mode - 1, s.subharmonic
                self._check_in_window(start_key(i, "subharmonic" if k > 1 else "mode"),
                                      f"the pole k T_j = {k} T_{s.mode}", k * self.T_lin[j],
                                      window)
            elif isinstance(s, AllStart):
                assert lo is not None and hi is not None
                n_all += self.count_poles(lo, hi, s.max_subharmonic) + 1
                # the roots of w_N between the poles (k <= 10 max_subharmonic) seed the gaps:
                # a 400-point grid of w_N (O(N) each) and a root polish per interval
                n_int = self.count_poles(1e-12, hi, 10 * s.max_subharmonic) + 1
                setup += n_int * (4e-6 * self.N + 5e-4)
        if n_all:
            self._check_time(n_explicit + n_all, max_points,
                             ", one per pole k T_j in the window", setup)

    @staticmethod
    def _check_in_window(key: str, what: str, T: float,
                         window: tuple[float | None, float | None]) -> None:
        lo, hi = window
        if (lo is not None and T < lo) or (hi is not None and T > hi):
            show = (f"T in [{lo if lo is not None else -np.inf:.6g}, "
                    f"{hi if hi is not None else np.inf:.6g}]")
            raise ValueError(f"{key}: {what} = {T:.6g} (omega = {2 * np.pi / T:.6g}) lies "
                             f"outside the continuation window ({show}, from "
                             "continuation.min/max): a branch starting there computes nothing")

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """User bounds on ``omega`` or ``T`` -> bounds on ``T`` (both are positive: a bound
        at or below zero has no meaning and is refused)."""
        for key, v in (("min", lo), ("max", hi)):
            if v is not None and v <= 0:
                raise ValueError(f"continuation.{key}: {name} = {v:g} is not positive (a "
                                 f"{'frequency' if name == 'omega' else 'period'} bound)")
        self._orientation = self.parameter_orientation(name)
        if name == "T":
            return lo, hi
        if name == "omega":
            return (None if hi is None else 2 * np.pi / hi,
                    None if lo is None else 2 * np.pi / lo)
        raise ValueError(f"continuation.parameter: {name!r} is not one of 'omega', 'T'")

    def parameter_orientation(self, name: str) -> int:
        """``T = 2 pi / omega`` falls as ``omega`` grows."""
        return -1 if name == "omega" else 1

    def restart_start(self, y: np.ndarray) -> dict[str, Any]:
        """A restart is checked as a start at its period ``{T: ...}`` (window, sizes)."""
        return {"T": float(y[-1])}

    def grazing_start(self, j: int, k: int) -> np.ndarray:
        """The linear grazing orbit (2.14) of mode ``j`` (0-based) at ``T = k T_j``: a point of
        the branch (Theorem 3.1: the Lipschitz extension of the nonlinear family)."""
        Pj = self.P[:, j]
        u0 = self.g / Pj[self.c] * Pj
        return self.y_from_state(u0, np.zeros(self.N), k * self.T_lin[j])

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        """Starts from the YAML ``start`` block; ``window`` = (T_min, T_max) for ``all``."""
        specs = START_ADAPTER.validate_python(start)
        specs = specs if isinstance(specs, list) else [specs]
        out: list[StartPoint] = []
        for s in specs:
            if isinstance(s, ModeStart):
                j, k = s.mode - 1, s.subharmonic
                if j >= self.N:
                    raise ValueError(f"start.mode: {s.mode} is beyond the {self.N} modes of "
                                     f"the chain (1..{self.N})")
                if self.g == 0.0:
                    raise ValueError("start.mode: a start at a linear grazing orbit needs "
                                     "parameters.gap != 0 (for gap = 0 use start: {all: true})")
                direction = 0 if s.side == "both" else -int(np.sign(self.a[j]))
                out.append(StartPoint(self.grazing_start(j, k), f"mode {s.mode}, k = {k}",
                                      direction, {"mode": s.mode, "subharmonic": k,
                                                  "pole_T": k * self.T_lin[j]}))
            elif isinstance(s, PeriodStart):
                u0, du0 = self.closed_form(s.T) if self.g != 0 else (np.zeros(self.N),
                                                                   np.zeros(self.N))
                out.append(StartPoint(self.y_from_state(u0, du0, s.T), f"T = {s.T:g}",
                                      s.direction * self._orientation,
                                      {"T0": s.T}))
            else:
                out.extend(self._all_starts(window, s.max_subharmonic))
        return out

    def _all_starts(self, window: tuple[float | None, float | None], kmax: int
                    ) -> list[StartPoint]:
        """Every branch in the window: for g != 0 one start per pole ``k T_j`` (the branch
        crosses the pole from its phantom to its admissible side) plus seeds in pole-free gaps;
        for g = 0 the trivial branch, whose branch points are the roots of ``w_N``."""
        lo, hi = window
        if lo is None or hi is None:
            raise ValueError("start: {all: true} needs continuation.min and continuation.max")
        if self.g == 0.0:
            y0 = self.y_from_state(np.zeros(self.N), np.zeros(self.N), lo)
            return [StartPoint(y0, "trivial branch (g = 0)", +1, {"trivial": True})]
        starts = [StartPoint(self.grazing_start(j, k), f"pole {k} T_{j + 1}", 0,
                             {"mode": j + 1, "subharmonic": k, "pole_T": T,
                              "skip_if_covered": True})
                  for T, j, k in self.poles(lo, hi, kmax)]
        # seeds between singularities that contain no pole (e.g. high frequencies T < T_N)
        pole_set = [p[0] for p in self.poles(lo, hi, kmax)]
        sing = sorted({lo, hi, *pole_set, *self.zeros_of_w_N(lo, hi, 10 * kmax).tolist()})
        for a, b in zip(sing[:-1], sing[1:], strict=False):
            if any(a - 1e-12 <= p <= b + 1e-12 for p in pole_set):
                continue
            Tm = 0.5 * (a + b)
            u0, du0 = self.closed_form(Tm)
            starts.append(StartPoint(self.y_from_state(u0, du0, Tm), f"T = {Tm:.6g}", 0,
                                     {"T0": Tm, "skip_if_covered": True}))
        return starts

