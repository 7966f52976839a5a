"""The bouncing ball (Nordmark & Piiroinen 2009, secs. 3.5 and 4.4; Figs. 1, 3, 4).

``qdd = -g``, ``q >= 0``, ``qd+ = -e qd-`` at ``q = 0``: ``x = (x1, x2) = (q, qd)``, ``H = x1``,
``W = (0, -(1 + e))``, ``a = -g``, ``r = e``, ``F' = (x2, 0)``. Released from rest at height
``s``, the ball hits the floor at ``sqrt(2 s / g)`` with velocity ``v0' = -sqrt(2 g s)``; the
``k``-th impact velocity is ``e^k v0'`` and the complete chattering sequence ends at

    ``t* = sqrt(2 s / g) + 2 e |v0'| / (g (1 - e))``        (eq. 37)

in the sticking state ``(0, 0)``, which does not depend on the initial condition (eq. 50).

This is a **simulation case**, not a continuation: :meth:`BouncingBallProblem.start_points`
returns no start, and the results (the resolved impact times, the chatter completion time
against its closed form, the Jacobian after the chatter map (50), the number of impacts
resolved before the map, the check of eqs. (47)-(48)) are written by :meth:`report_extras`
into ``report.json`` (``problem_results``) and drawn by :meth:`extra_plots` (Fig. 1: position
and velocity; Fig. 3(b)-(c): ``H`` and ``h = H/u`` in the tail of the sequence; Fig. 4: the two
Jacobian components ``dx1(t)/dx1(0)``, ``dx2(t)/dx1(0)``). With ``chatter_order: 1`` and
``chatter_tol: 0.02`` the map is applied after ``N = 15`` impacts as in Fig. 4 (for the ball the
first-order map's time and velocity are exact and its ``O(v^2)`` position error is removed by the
projection onto the sticking set, so the result is still exact).

**Jacobians of secs. 4.2-4.4 (eqs. 47-50).** Extended state ``(x1, x2, h, u)`` of sec. 4.3
(``h = H/u``, ``u`` the latest outgoing velocity), ``F = (x2, -g)``; ``v_k' = -v_k = e^k v0'``
(``v_k`` the initial velocity of flight ``k``). :func:`ball_extended_matrices` gives the printed
matrices of eq. (47) (``P_0x``, ``D_k``, ``P_k``); the tests check that ``D_k`` is
:func:`~nsm_continuation.hybrid.saltation.saltation_matrix` applied to the extended impact and
that ``P_k`` is the flow Jacobian of the extended field. :func:`ball_pn_closed_form` gives
``p_n`` of eq. (48). **Erratum in (48)**: the chained product of the (correct) matrices (47) has
the ``(4, 1)`` entry (``du/ds``) ``-(g / v0') e^n`` — i.e. ``-(g/v0') e^n (1 - e) / (1 - e)`` —
while the paper prints ``-(g/v0') e^n (1 - e^n) / (1 - e)``. The two agree for ``n = 1`` only.
Direct derivation: after ``n`` impacts ``u = e^n sqrt(2 g s + w^2)``, so
``du/ds = e^n g / sqrt(2 g s) = -(g / v0') e^n``. Every other entry of (48) is right, and so is
(50). ``ball_pn_closed_form(..., as_printed=True)`` returns the printed version for comparison.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import casadi as ca
import numpy as np
from pydantic import BaseModel, Field

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.vocabulary import CanonicalNames, CanonicalParameter, as_parameters
from nsm_continuation.hybrid.simulate import SimOptions, SimResult, SimulationError, Simulator
from nsm_continuation.hybrid.system import CompiledHybrid, HybridSystem


class BouncingBallParameters(CanonicalNames):
    """``parameters:`` of ``problem: bouncing_ball`` (defaults: Fig. 4, g = 9.8, s = 1)."""

    model_config = STRICT
    deprecated_names = {"e": "restitution"}
    #: gravity ``g``
    g: float = Field(9.8, gt=0, allow_inf_nan=False)
    restitution: float = Field(0.8, ge=0, lt=1, allow_inf_nan=False,
                               description="e; complete chattering needs 0 <= e < 1")
    s: float = Field(1.0, gt=0, allow_inf_nan=False, description="initial height (at rest)")
    #: the chatter map's order (``parameters.integrator.chatter_order`` of the other
    #: hybrid problems)
    chatter_order: int = Field(2, ge=1, le=4)
    #: the chatter map is applied when its estimated error is below this
    chatter_tol: float = Field(1e-10, gt=0, lt=1)
    #: the simulated time
    t_end: float = Field(5.0, gt=0, allow_inf_nan=False)


def ball_system(clock: bool = False) -> HybridSystem:
    """The ball declared as a mechanical system (``M = 1``, force ``-g``, ``H = q``)."""
    q, qd = ca.SX.sym("q"), ca.SX.sym("qd")
    g, e = ca.SX.sym("g"), ca.SX.sym("e")
    kw: dict[str, Any] = {"state_names": ["x1", "x2"]}
    if clock:
        kw = {"clock": ca.SX.sym("x3"), "state_names": ["x1", "x2", "x3"]}
    return HybridSystem.mechanical("ball", q, qd, {"g": g, "e": e}, ca.SX(1), -g, q, e, **kw)


def ball_extended_matrices(e: float, g: float, v0: float, n: int
                           ) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """The printed matrices of eq. (47) for the bouncing ball released from rest.

    ``v0`` is the first impact velocity ``v0' = -sqrt(2 g s) < 0``. Returns ``(P0x, D, P)``:
    ``P0x`` (4 x 2) the Jacobian of the extended state ``(x1, x2, h, u)`` at the first impact
    with respect to the initial ``(s, w)``; ``D[k]`` (4 x 4, ``k = 0..n-1``) the extended impact
    saltation matrix at impact ``k`` (impact velocity ``v_k' = e^k v0'``); ``P[k - 1]``
    (4 x 4, ``k = 1..n``) the extended flow Jacobian of flight ``k`` (initial velocity
    ``v_k = -v_k'``, duration ``2 v_k / g``).
    """
    P0x = np.array([[1.0, -v0 / g],
                    [0.0, 1.0],
                    [-1.0 / v0, 1.0 / g],
                    [-g / v0, 0.0]])
    D, P = [], []
    for k in range(n):
        vk_ = e**k * v0                                   # impact velocity v_k'
        D.append(np.array([[1.0, 0.0, (1 + e) * vk_, 0.0],
                           [0.0, -e, (1 + e) * g, 0.0],
                           [0.0, 0.0, -1.0, 0.0],
                           [0.0, -e, e * g, 0.0]]))
    for k in range(1, n + 1):
        vk = -(e**k) * v0                                 # initial velocity of flight k
        P.append(np.array([[1.0, 2 * vk / g, 0.0, 0.0],
                           [0.0, 1.0, 0.0, 0.0],
                           [0.0, 2.0 / g, 1.0, 0.0],
                           [0.0, 0.0, 0.0, 1.0]]))
    return P0x, D, P


def ball_pn_chain(e: float, g: float, v0: float, n: int) -> np.ndarray:
    """``p_n = (prod_{k=1}^n P_k D_{k-1}) P_0x`` multiplied out from (47) (4 x 2)."""
    P0x, D, P = ball_extended_matrices(e, g, v0, n)
    p = P0x
    for k in range(1, n + 1):
        p = P[k - 1] @ D[k - 1] @ p
    return p


def ball_pn_closed_form(e: float, g: float, v0: float, n: int,
                        as_printed: bool = False) -> np.ndarray:
    """Closed form of ``p_n`` (eq. 48): Jacobian of ``(x1, x2, h, u)`` just before impact ``n``
    (``n`` impacts done) with respect to the initial ``(s, w)``.

    The ``(4, 1)`` entry is the corrected ``-(g/v0') e^n`` (see the module docstring);
    ``as_printed=True`` returns the paper's ``-(g/v0') e^n (1 - e^n) / (1 - e)`` instead.
    """
    en = e**n
    u_s = en * (1 - en) if as_printed else en * (1 - e)
    return np.array([
        [en * (1 + e - 2 * e ** (n + 1)), -(v0 / g) * en * (1 - e)],
        [-(g / v0) * (1 + e) * (1 - en), 1 - e],
        [-(1 / v0) * (1 + e - 2 * e ** (n + 1)), (1 - e) / g],
        [-(g / v0) * u_s, 0.0],
    ]) / (1 - e)


def ball_chatter_jacobian(e: float, n: int, v0: float) -> np.ndarray:
    """``D_N`` of eq. (50) (2 x 4): the Jacobian of the discontinuity mapping of the exact
    chatter map (49) ``E(x^) = (x1, 0)``, ``e(x^) = -2 e x2 / (g (1 - e))`` applied at impact
    ``N = n`` (impact velocity ``e^n v0'``), dropping the extended variables. ``D_N p_N = 0``:
    the sticking state does not depend on the initial condition."""
    return np.array([[1.0, 0.0, e**n * v0, 0.0],
                     [0.0, 0.0, 0.0, 0.0]])


def closed_form(g: float, e: float, s: float, n: int = 0) -> dict[str, Any]:
    """First impact velocity and time, the first ``n`` impact times, the completion time."""
    v0 = -np.sqrt(2 * g * s)
    t0 = np.sqrt(2 * s / g)
    times = [t0]
    for k in range(1, n):
        times.append(times[-1] + 2 * e**k * abs(v0) / g)
    return {"v0": float(v0), "t0": float(t0), "impact_times": [float(t) for t in times[:n]],
            "t_star": float(t0 + 2 * e * abs(v0) / (g * (1 - e))),
            # d t* / d(s, w) at w = 0 (s = initial height, w = initial velocity)
            "dt_star": [float((1 + e) / (abs(v0) * (1 - e))), float(1 / g)]}


def impact_times(res: SimResult) -> list[float]:
    """Times of the resolved impacts from a recorded trajectory (a jump of ``x2`` at equal
    times; the chatter map's own jump is the last one and is excluded)."""
    tr = res.trajectory or []
    out = []
    t_map = [ev.t for ev in res.events if ev.kind == "chatter"]
    for (ta, xa), (tb, xb) in zip(tr[:-1], tr[1:], strict=True):
        if ta == tb and xa[1] < 0 < xb[1]:
            out.append(float(ta))
    return [t for t in out if not t_map or t < t_map[0]]


class BallPresentation(Presentation):
    """The bouncing ball's report (the simulation's results, :meth:`BouncingBallProblem.results`)
    and its figures: Fig. 1 (position and velocity), Fig. 3(b)-(c) (``H`` and ``h = H/u`` in
    the tail of the sequence) and Fig. 4 (Jacobian components against time)."""

    fep_axes = ("restitution", "t_star")

    def summary(self) -> dict[str, Any]:
        return {"parameters": self.problem.p.model_dump(),
                "kind": "simulation case (no continuation)"}

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        return {"bouncing_ball": self.problem.results()}

    def _dense(self, res: SimResult, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
        """Dense (t, x1, x2) from the recorded points by the exact flow of F (or F')."""
        g = self.problem.p.g
        tr = res.trajectory or []
        jumps = {(ev.t, ev.info["t_complete"]) for ev in res.events if ev.kind == "chatter"}
        ts, xs = [], []
        for (ta, xa), (tb, _xb) in zip(tr[:-1], tr[1:], strict=True):
            if tb <= ta:
                ts.append(ta)
                xs.append(xa[:2])
                continue
            if (ta, tb) in jumps:                      # the chatter map's time jump: no flow
                ts += [ta, 0.5 * (ta + tb)]
                xs += [xa[:2], np.full(2, np.nan)]
                continue
            sticking = abs(xa[0]) < 1e-14 and abs(xa[1]) < 1e-14
            tt = np.linspace(0.0, tb - ta, n)
            gg = 0.0 if sticking else g
            ts += list(ta + tt)
            xs += list(np.column_stack([xa[0] + xa[1] * tt - gg * tt**2 / 2,
                                        xa[1] - gg * tt]))
        return np.array(ts), np.array(xs)

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        from nsm_continuation.figures.kit import subplots

        out = Path(out_dir)
        info = self.problem.results()
        if "simulation_failed" in info:
            return []
        res = self.problem.recorded()
        assert res is not None  # the simulation succeeded (no "simulation_failed" above)
        files = []
        ts, xs = self._dense(res)
        t_c = (info["chatter_map"] or {}).get("completion_time")
        # Fig. 1: position and velocity
        fig, ax = subplots(2, 1, sharex=True, figsize=(7, 5))
        ax[0].plot(ts, xs[:, 0], lw=1)
        ax[1].plot(ts, xs[:, 1], lw=1)
        ax[0].set_ylabel("position $x_1 = q$")
        ax[1].set_ylabel(r"velocity $x_2 = \dot q$")
        ax[1].set_xlabel("t")
        if t_c is not None:
            for a in ax:
                a.axvline(t_c, color="C3", ls=":", lw=1, label="chatter map: t*")
            ax[0].legend()
        p = self.problem.p
        ax[0].set_title(f"Bouncing ball, e = {p.restitution}, s = {p.s} (Fig. 1)")
        fig.tight_layout()
        fig.savefig(out / "ball_fig1_position_velocity.png", dpi=120)
        files.append("ball_fig1_position_velocity.png")
        # Fig. 3(b)-(c): H and h = H/u in the tail of the sequence
        imp = info["impact_times"]
        if len(imp) >= 3:
            t_from = imp[max(0, len(imp) - 8)]
            sel = ts >= t_from
            u = np.full(ts.shape, np.nan)
            for k in range(len(imp)):
                t_next = imp[k + 1] if k + 1 < len(imp) else np.inf
                m = (ts >= imp[k]) & (ts <= t_next)
                u[m] = self.problem.p.restitution ** (k + 1) * abs(
                    info["closed_form"]["first_impact_velocity"])
            t_map = [ev.t for ev in res.events if ev.kind == "chatter"]
            if t_map:
                sel &= ts <= t_map[0]
            fig, ax = subplots(1, 2, figsize=(9, 3.5))
            ax[0].plot(ts[sel], xs[sel, 0], lw=1)
            ax[0].set_title("(b) H(x) in the tail")
            ax[1].plot(ts[sel], xs[sel, 0] / u[sel], lw=1, color="C1")
            ax[1].set_title("(c) h = H/u in the tail")
            for a in ax:
                a.set_xlabel("t")
            fig.tight_layout()
            fig.savefig(out / "ball_fig3bc_H_h_tail.png", dpi=120)
            files.append("ball_fig3bc_H_h_tail.png")
        # Fig. 4: Jacobian components vs time (one simulation per time)
        grid = np.linspace(1e-3, self.problem.p.t_end, 240)
        extra = [t for t0 in imp for t in (t0 - 1e-9, t0 + 1e-9)]
        if t_c is not None:
            extra += [t_c - 1e-9, t_c + 1e-9]
        times = np.unique(np.concatenate([grid, [t for t in extra if 0 < t < p.t_end]]))
        Js = self.problem.jacobian_history(times)
        fig, ax = subplots(1, 2, figsize=(9, 3.5))
        ax[0].plot(times, Js[:, 0, 0], lw=1)
        ax[0].set_title(r"$\partial x_1(t) / \partial x_1(0)$")
        ax[1].plot(times, Js[:, 1, 0], lw=1)
        ax[1].set_title(r"$\partial x_2(t) / \partial x_1(0)$")
        for a in ax:
            a.set_xlabel("t")
            if t_c is not None:
                a.axvline(t_c, color="C3", ls=":", lw=1)
        n_map = (info["chatter_map"] or {}).get("impacts_before_map")
        fig.suptitle(f"Fig. 4: g = {p.g}, s = {p.s}; chatter map after N = {n_map}")
        fig.tight_layout()
        fig.savefig(out / "ball_fig4_jacobian.png", dpi=120)
        files.append("ball_fig4_jacobian.png")
        return files


class BouncingBallProblem(CanonicalParameter, Problem):
    """Bouncing ball: complete chattering, simulated (Nordmark, Piiroinen 2009, sec. 3.5).
    No continuation; see the module docstring."""

    presentation_class = BallPresentation

    name: ClassVar[str] = "bouncing_ball"
    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    Parameters: ClassVar[type[BaseModel]] = BouncingBallParameters

    def __init__(self, params: BaseModel | dict[str, Any]) -> None:
        params = as_parameters(BouncingBallParameters, params)
        super().__init__(params)
        self.p: BouncingBallParameters = params
        self.variables = ["x1", "restitution"]
        self.parameter = "restitution"
        self.c: CompiledHybrid = ball_system().compile({"g": self.p.g, "e": self.p.restitution})
        self._cache: dict[str, Any] = {}

    # -- the Problem contract: a simulation case has no residual and no start ---------------
    def residual(self, y: Any) -> Any:
        raise NotImplementedError("bouncing_ball is a simulation case: it has no residual "
                                  "(results are in report_extras / extra_plots)")

    @property
    def compiled(self) -> Any:  # the run touches ``problem.compiled`` once: nothing to build
        return None

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        return []

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """A simulation case has no start: ``start`` must be empty (``{}``). Its cost is bounded
        without a check: ~250 simulations to ``t_end``, each with at most ``max_chatter_impacts``
        (2000) impacts before the chatter map (a few seconds; 25 s at ``chatter_tol: 1e-300``).
        """
        p = self.p
        # the simulator squares velocities (v0^2 = 2 g s) and energies: keep them far from
        # overflow (closed form, eq. (47) ff.)
        scale = 2 * p.g * abs(p.s)
        if not (np.isfinite(scale) and scale < 1e150):
            raise ValueError(f"parameters.g: with s = {p.s:g} the impact velocity squared "
                             f"2 g s = {scale:g} is beyond what double precision simulates "
                             "(at most 1e150): rescale the units")
        if start is None or start == {}:
            return
        if isinstance(start, dict):
            key = next(iter(start))
            raise ValueError(f"start.{key}: unknown key (bouncing_ball is a simulation case "
                             "without start points: give start: {})")
        raise ValueError("start: bouncing_ball is a simulation case without start points: "
                         "give start: {}")

    # -- simulation ---------------------------------------------------------------------------
    def options(self, **kw: Any) -> SimOptions:
        return SimOptions(chatter_order=self.p.chatter_order, chatter_tol=self.p.chatter_tol,
                          **kw)

    def x0(self) -> np.ndarray:
        return np.array([self.p.s, 0.0])

    def simulate(self, t_end: float | None = None, record: bool = False) -> SimResult:
        return Simulator(self.c, self.options(record=record)).run(
            self.x0(), t_end=self.p.t_end if t_end is None else t_end)

    def jacobian_history(self, times: np.ndarray) -> np.ndarray:
        """``J(t) = dx(t)/dx(0)`` (time-fixed, 2 x 2) at each time: one simulation each."""
        return np.array([self.simulate(t_end=float(t)).J[:2, :2] for t in times])

    def results(self) -> dict[str, Any]:
        if "results" in self._cache:
            return self._cache["results"]
        p = self.p
        try:
            res = self.simulate(record=True)
        except SimulationError as exc:  # recorded in the report, never a traceback
            self._cache["results"] = {"simulation_failed": str(exc)}
            return self._cache["results"]
        imp = impact_times(res)
        cf = closed_form(p.g, p.restitution, p.s, len(imp))
        chatter = [ev for ev in res.events if ev.kind == "chatter"]
        out: dict[str, Any] = {
            "closed_form": {"first_impact_velocity": cf["v0"], "first_impact_time": cf["t0"],
                            "chatter_completion_time": cf["t_star"],
                            "d_t_star_d_initial": cf["dt_star"]},
            "n_impacts_resolved": len(imp),
            "impact_times": imp,
            "impact_times_max_error": (float(np.max(np.abs(np.array(imp) -
                                                          np.array(cf["impact_times"]))))
                                       if imp else None),
            "end_state": res.X.tolist(), "end_time": float(res.t),
            "sticking_intervals": [list(map(float, iv)) for iv in res.sticking_intervals],
        }
        if chatter:
            ev = chatter[0]
            N = int(ev.info["impacts"])
            t_c = float(ev.info["t_complete"])
            out["chatter_map"] = {
                "impacts_before_map": N,
                "completion_time": t_c,
                "completion_time_error": t_c - cf["t_star"],
                "error_estimate": float(ev.info["error_estimate"]),
            }
            if res.t >= t_c:
                # eq. (50): the state after the map does not depend on the initial state
                out["chatter_map"]["jacobian_after_map"] = res.J[:2, :2].tolist()
                out["chatter_map"]["d_t_complete_d_initial"] = res.Jt[:2].tolist()
            v0 = cf["v0"]
            pN = ball_pn_chain(p.restitution, p.g, v0, N)
            out["paper_eqs_47_50"] = {
                "N": N,
                "chain_vs_closed_form_48_max_diff": float(np.abs(
                    pN - ball_pn_closed_form(p.restitution, p.g, v0, N)).max()),
                "printed_48_entry_4_1": float(
                    ball_pn_closed_form(p.restitution, p.g, v0, N, True)[3, 0]),
                "corrected_48_entry_4_1": float(pN[3, 0]),
                "D_N_times_p_N_eq_50": (ball_chatter_jacobian(p.restitution, N, v0) @ pN).tolist(),
            }
        else:
            out["chatter_map"] = None
        self._cache["results"] = out
        self._cache["res"] = res
        return out

    def recorded(self) -> SimResult | None:
        """The simulation of :meth:`results`, with its trajectory (None if it failed)."""
        self.results()
        return self._cache.get("res")
