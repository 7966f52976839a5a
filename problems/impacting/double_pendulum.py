"""Forced double pendulum with a unilateral wall (Nordmark & Piiroinen 2009, sec. 6).

Upper bar (length L1, point mass m1) driven by a constant torque ``T`` with viscous damping
``D q1dot``; lower bar (L2, m2), free joint; absolute angles ``q1``, ``q2``. The lower mass is at
``X = L1 sin q1 + L2 sin q2``, ``Y = -(L1 cos q1 + L2 cos q2)``.

Conventions (documented choices where the paper is inconsistent):

* **Wall**: ``H(q) = X(q) + d`` (eq. 52) with ``d > 0`` the wall's horizontal distance from the
  upper joint: the wall is the plane ``X = -d`` and the admissible side is ``X >= -d``.
  Sec. 6.3 prints ``d = -0.5``, but its saddle ``q*`` has ``X(q*) = -0.49997``, i.e. the wall
  at ``X = -0.5``: the same wall as ``d = +0.5`` here (and as secs. 6.1-6.2). We use ``d = 0.5``
  for all three scenarios.
* **Equations of motion** derived by Lagrange (``tests/oracles/pendulum_lagrange.py`` is the
  independent symbolic derivation the tests compare with): ``M(q) qdd = f(q, qd)`` with the
  printed ``M`` and ``V`` of eq. (53) but the Coriolis vector
  ``m2 L1 L2 sin(q1 - q2) (qd2^2, -qd1^2)``: the printed ``L(q, qd) = L1 L2 s12 (m1 qd2^2,
  m2 qd1^2)`` has ``m1`` for ``m2`` in its first row and the wrong sign in its second, and
  fails the energy test (``tests/hybrid/test_pendulum_model.py``).
* **Torque** enters as ``+T`` on ``q1`` (``V_1 = (m1 + m2) g L1 sin q1 - T``): ``T < 0`` drives
  ``q1`` downwards, one period is one revolution ``q1 -> q1 - 2 pi``.
* **Poincaré section** ``q1 = pi/2`` (mod 2 pi), as in Fig. 9; the shift is ``-2 pi`` per
  revolution for ``T < 0``.
* **Impact law** (54)-(58) with restitution ``e`` (the key ``restitution``; the old key ``e``
  is deprecated): ``r = e`` (eq. 8).
* **d** keeps the paper's name: it is the wall's distance from the upper joint (the wall is
  ``X = -d``), not the obstacle's position ``gap`` of the other problems (that would be ``-d``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
from pydantic import BaseModel, Field

from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.vocabulary import CanonicalNames, CanonicalParameter
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.presentation import HybridCasePresentation
from nsm_continuation.hybrid.system import HybridSystem

PARAMS = ("g", "m1", "m2", "L1", "L2", "D", "torque", "restitution", "d")


class DoublePendulumParameters(CanonicalNames):
    """``parameters:`` of ``problem: double_pendulum`` (defaults: sec. 6, scenario 6.1)."""

    model_config = STRICT
    deprecated_names = {"e": "restitution"}
    #: gravity ``g``
    g: float = Field(9.81, gt=0, allow_inf_nan=False)
    #: the upper bar's point mass ``m1``
    m1: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: the lower bar's point mass ``m2``
    m2: float = Field(2.0, gt=0, allow_inf_nan=False)
    #: the upper bar's length ``L1``
    L1: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: the lower bar's length ``L2``
    L2: float = Field(1.0, gt=0, allow_inf_nan=False)
    #: viscous damping ``D`` of the upper joint (``D q1dot``)
    D: float = Field(10.0, ge=0, allow_inf_nan=False)
    #: the constant torque ``T`` on the upper bar (``T < 0`` turns it downwards: one
    #: period is one revolution)
    torque: float = Field(-31.15, allow_inf_nan=False)
    #: coefficient of restitution ``e`` of the impact law (54)-(58)
    restitution: float = Field(0.89, ge=0, lt=1, allow_inf_nan=False)
    #: the wall's distance from the upper joint: the wall is the plane ``X = -d``, the
    #: admissible side ``H = X + d >= 0`` (eq. 52)
    d: float = Field(0.5, gt=0, allow_inf_nan=False)
    #: the hybrid simulator's numerics (defaults as the speed-accuracy chart recommends)
    integrator: IntegratorSpec = IntegratorSpec()


def pendulum_terms(q: Any, qd: Any, p: dict[str, Any]) -> tuple[Any, Any, Any]:
    """``M(q)``, ``f(q, qd)`` with ``M qdd = f`` (Lagrange), and ``H(q) = X + d`` (eq. 52)."""
    q1, q2 = q[0], q[1]
    s12, c12 = ca.sin(q1 - q2), ca.cos(q1 - q2)
    m1, m2, L1, L2, g = p["m1"], p["m2"], p["L1"], p["L2"], p["g"]
    M = ca.vertcat(ca.horzcat((m1 + m2) * L1**2, m2 * L1 * L2 * c12),
                   ca.horzcat(m2 * L1 * L2 * c12, m2 * L2**2))
    coriolis = m2 * L1 * L2 * s12 * ca.vertcat(qd[1] ** 2, -qd[0] ** 2)
    V = ca.vertcat((m1 + m2) * g * L1 * ca.sin(q1) - p["torque"], m2 * g * L2 * ca.sin(q2))
    damping = ca.vertcat(-p["D"] * qd[0], 0)
    H = L1 * ca.sin(q1) + L2 * ca.sin(q2) + p["d"]
    return M, -coriolis - V + damping, H


class PendulumPresentation(HybridCasePresentation):
    """The double pendulum's report adds the equilibria on the sticking surface (sec. 6.3)."""

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Generic hybrid extras plus the equilibria on the sticking surface (sec. 6.3) next to
        the orbit of largest period of each branch (the one closest to a homoclinic orbit)."""
        out = super().report_extras(branches)
        eqs = []
        for br in branches:
            pts = [p for p in br.points if np.isfinite(p.derived.get("period", np.nan))]
            if not pts:
                continue
            p = max(pts, key=lambda q: q.derived["period"])
            eq = self.problem.sticking_equilibria(p.y)
            if eq is not None:
                eqs.append({"branch": br.label, "period": p.derived["period"], **eq})
        if eqs:
            out["sticking_equilibria"] = eqs
            out["sticking_equilibria_paper_sec6_3"] = {
                "torque": -31.00166609425, "q1": 4.91990567552337, "q2": 0.49899755317827,
                "lambda_eq60": 10.69293096743960, "eigenvalues": [0.3366, -3.2953],
                "note": "paper's eigenvalues; ours (two independent linearisations, "
                        "tests/hybrid/test_pendulum_model.py) are 0.28879, -3.24752 at that torque"}
        return out


class DoublePendulumProblem(CanonicalParameter, HybridCaseProblem):
    """Forced double pendulum hitting a wall, chattering and sticking (Nordmark, Piiroinen 2009).
    Its periodic orbits (sec. 6)."""

    name: ClassVar[str] = "double_pendulum"
    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    presentation_class = PendulumPresentation
    Parameters: ClassVar[type[BaseModel]] = DoublePendulumParameters
    default_parameter: ClassVar[str] = "restitution"
    #: continued in the period (``continuation.parameter: period``, sec. 6.3), the torque is
    #: solved for unless ``start.free_parameter`` names another parameter
    period_partner: ClassVar[str | None] = "torque"
    #: the wall distance is the preferred second parameter of a grazing curve's hint
    curve_preference: ClassVar[tuple[str, ...]] = ("d",)

    def system(self) -> HybridSystem:
        q = ca.SX.sym("q", 2)
        qd = ca.SX.sym("qd", 2)
        p = {k: ca.SX.sym(k) for k in PARAMS}
        M, f, H = pendulum_terms(q, qd, p)
        return HybridSystem.mechanical("double_pendulum", q, qd, p, M, f, H, p["restitution"],
                                       state_names=["q1", "q2", "q1dot", "q2dot"],
                                       periodic={0: 2 * np.pi, 1: 2 * np.pi})

    def section(self) -> Section:
        return Section(0, np.pi / 2, -2 * np.pi if self.values["torque"] < 0 else 2 * np.pi)

    def default_initial(self) -> np.ndarray:
        """Upper bar horizontal, rotating at the torque-damping speed, lower bar hanging."""
        w = self.values["torque"] / max(self.values["D"], 1e-9)
        return np.array([np.pi / 2, 0.0, w, 0.0])

    def check_parameters(self, values: dict[str, float]) -> None:
        super().check_parameters(values)
        if values["d"] >= values["L1"] + values["L2"]:
            raise ValueError(f"parameters.d: the wall at X = -{values['d']} is out of reach "
                             f"(L1 + L2 = {values['L1'] + values['L2']})")

    # ------------------------------------------------------------------ orbit figures
    #: Figs. 8(a), 9(a), 10(a): X(t); Fig. 12: |dY/dt| (log); Fig. 11: the projected phase
    #: portrait (Y, dY/dt); the manifold view: the lower mass's path with its velocity
    orbit_views: ClassVar[dict[str, tuple[str, ...]] | None] = {
        "time": ("X", "dY"), "phase": ("Y", "dY"), "manifold": ("X", "Y", "dY")}
    parameter_labels: ClassVar[dict[str, str]] = {
        "restitution": "restitution $e$", "d": "wall position $d$", "torque": "torque $T$",
        "D": "damping $D$"}
    orbit_labels: ClassVar[dict[str, str]] = {
        "X": r"lower mass $X = L_1 \sin q_1 + L_2 \sin q_2$",
        "Y": r"lower mass $Y = -(L_1 \cos q_1 + L_2 \cos q_2)$",
        "dX": r"lower mass velocity $\dot X$", "dY": r"lower mass velocity $\dot Y$",
        "q1": r"$q_1$ [rad]", "q2": r"$q_2$ [rad]",
        "q1dot": r"$\dot q_1$ [rad/s]", "q2dot": r"$\dot q_2$ [rad/s]"}

    def orbit_outputs(self, states: np.ndarray, parameters: dict[str, float]
                      ) -> dict[str, np.ndarray]:
        """The lower mass's position ``X, Y`` (sec. 6: ``X = L1 sin q1 + L2 sin q2``, the
        wall is ``X = -d``) and velocity ``dX, dY`` along the states (rows ``q1, q2, q1dot,
        q2dot``) at the lengths in ``parameters``: the quantities of Figs. 8-12."""
        L1, L2 = parameters["L1"], parameters["L2"]
        q1, q2, w1, w2 = (states[:, k] for k in range(4))
        X, Y = self.lower_mass(states, (L1, L2))
        return {"X": X, "Y": Y,
                "dX": L1 * np.cos(q1) * w1 + L2 * np.cos(q2) * w2,
                "dY": L1 * np.sin(q1) * w1 + L2 * np.sin(q2) * w2}

    def lower_mass(self, X: np.ndarray, lengths: tuple[float, float] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal and vertical position of the lower mass along states ``X`` (rows), with
        the bars' ``lengths`` (default the parameters' ``L1, L2``)."""
        X = np.atleast_2d(X)
        L1, L2 = lengths if lengths is not None else (self.values["L1"], self.values["L2"])
        return (L1 * np.sin(X[:, 0]) + L2 * np.sin(X[:, 1]),
                -(L1 * np.cos(X[:, 0]) + L2 * np.cos(X[:, 1])))

    # ------------------------------------------------------------------ report
    def sticking_equilibria(self, y: np.ndarray) -> dict[str, Any] | None:
        """The equilibrium on the sticking surface nearest the orbit at ``y`` (eqs. 60-61),
        from the point where its chattering completes; ``None`` if the orbit has no sticking."""
        from nsm_continuation.hybrid.equilibria import sticking_equilibrium

        res = self.sim(y)
        if res is None:
            return None
        starts = [ev.x for ev in res.events if ev.kind == "chatter"]
        if not starts:
            return None
        c = self.shooting.c
        name = self.swept_parameter  # the lifted parameter (the torque when continued in T)
        p = float(y[self.swept_index])
        guess = np.append(starts[0], [p])
        eq = sticking_equilibrium(c, guess)
        x = np.asarray(eq["x"])
        Mq = np.asarray(c.system._mass(x[:2], *[
            self.values[k] if k != name else p for k in c.system.params]), dtype=float)
        L1, L2 = self.values["L1"], self.values["L2"]
        N = np.array([L1 * np.cos(x[0]), L2 * np.cos(x[1])])
        e = self.values["restitution"] if name != "restitution" else p
        # eq. (60) multiplies N by lambda; eq. (10) multiplies W: lambda_60 = lambda_10 (1 + e)
        # / (N^T M^-1 N)
        lam60 = eq["lambda"] * (1 + e) / float(N @ np.linalg.solve(Mq, N))
        X, Y = self.lower_mass(x)
        return {name: p, "q1": float(x[0]), "q2": float(x[1]),
                "lambda_eq60": lam60, "X": float(X[0]), "Y": float(Y[0]),
                "eigenvalues": [float(v.real) for v in eq["eigenvalues"]],
                "saddle": eq["saddle"], "converged": eq["converged"],
                "residual": eq["residual"]}
