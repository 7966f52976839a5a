"""A grazing crossed where an impact of a period-2 orbit vanishes: a gear pair with backlash
(two contact surfaces), checked against an independent event-driven simulator with the
closed-form flight (:mod:`oracles.backlash`).

The system: ``x'' + 2 zeta x' + x = fm + cos(phase)``, ``phase' = omega``, between the walls
``x = +-b`` with Newton restitution ``e`` (``zeta = 0.05, fm = 0.2, b = 0.5, e = 0.8``), a
stroboscopic section at phase 0. Its period-2 family (8 impacts per two forcing periods) loses
a slow impact on the lower wall at omega = 0.78868 and goes on with 7 (the oracle's fixed
points of the twice-iterated map beyond it). The family does not end there: the margin-fixed
solves that locate the grazing (:func:`nsm_continuation.hybrid.grazing.locate_grazing`) must
converge from orbits whose vanishing impact is slow, where the map is strongly curved.
"""

from __future__ import annotations

from typing import ClassVar

import casadi as ca
import numpy as np
import pytest
from oracles.backlash import Gear, simulate
from pydantic import BaseModel, Field

import nsm_continuation as nsm
from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.system import HybridSystem

GEAR = Gear(zeta=0.05, fm=0.2, b=0.5, e=0.8)


class GearParameters(BaseModel):
    model_config = STRICT
    zeta: float = Field(GEAR.zeta, ge=0)
    fm: float = GEAR.fm
    b: float = Field(GEAR.b, gt=0)
    omega: float = Field(0.79, gt=0)
    restitution: float = Field(GEAR.e, ge=0, lt=1)
    integrator: IntegratorSpec = IntegratorSpec()


class GearPairProblem(HybridCaseProblem):
    """The gear pair declared as a user would (two surfaces as a list)."""

    name: ClassVar[str] = "gear_pair_test"
    Parameters: ClassVar[type[BaseModel]] = GearParameters
    default_parameter: ClassVar[str] = "omega"

    def system(self) -> HybridSystem:
        x, xd, ph = ca.SX.sym("x"), ca.SX.sym("xdot"), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("zeta", "fm", "b", "omega", "restitution")}
        force = -x - 2 * p["zeta"] * xd + p["fm"] + ca.cos(ph)
        return HybridSystem.mechanical(
            "gear_pair_test", x, xd, p, ca.SX(1.0), force, [p["b"] - x, x + p["b"]],
            [p["restitution"], p["restitution"]], surfaces=["upper", "lower"],
            clock=ph, clock_rate=p["omega"], state_names=["x", "xdot", "phase"])

    def section(self) -> Section:
        return Section(2, 0.0, 2 * np.pi)

    def default_initial(self) -> np.ndarray:
        return np.zeros(3)


def test_period_two_family_crosses_the_grazing_where_an_impact_vanishes() -> None:
    """Continued towards the vanishing impact, the period-2 family has a grazing event (no
    ``impact_velocity_vanishes`` end) and goes on past it with one impact fewer. Oracle
    (independent simulation of two forcing periods): every point's grazing margin is the
    package's to 1e-11 (measured 8e-13: the integration error of ``H``) and the point is a
    fixed point of the twice-iterated map, with 8 impacts before the grazing and 7 beyond;
    the residual is below 1e-9 plus ``1e-11 / sqrt|m|`` (an error ``dm`` in the margin of a
    slow impact moves the map by ``dm / sqrt|m|``, eq. G1); the grazing orbit's margin is 0
    to 1e-11, and the zero of the quadratic through the oracle's margins of the orbits beyond
    it (smooth on that side) is its frequency to 1e-9."""
    pb = GearPairProblem({"omega": 0.79})
    pb.set_parameter("omega", 2)
    # an orbit of the period-2 family near the grazing (Newton converges from it)
    y0 = np.array([0.07839845, -0.29828995, 0.78873958])
    res = nsm.continuation(pb, StartPoint(y0, "period-2 orbit", 0), min=0.788, max=0.7895,
                           direction="decrease", max_points=13, newton_tol=1e-10,
                           step={"initial": 1e-4, "min": 1e-9, "max": 5e-4},
                           analysis={"stability": False, "bifurcations": False})
    (br,) = res.run_result.branches
    assert "impact_velocity_vanishes" not in [ev.kind for ev in br.events]
    (ev,) = [ev for ev in br.events if ev.kind == "grazing"]
    yg = np.asarray(ev.point.y, dtype=float)
    assert abs(simulate(GEAR, yg[2], yg[0], yg[1], 2).margin) < 1e-11
    before = [p for p in br.points if p.s < ev.point.s - 1e-12]
    beyond = [p for p in br.points if p.s > ev.point.s + 1e-12]
    assert len(before) >= 3 and len(beyond) >= 3
    assert all(p.y[2] < yg[2] for p in beyond)          # the family goes on to lower omega
    margins = []
    for p, n_impacts in [(q, 8) for q in before] + [(q, 7) for q in beyond]:
        x, v, omega = (float(c) for c in p.y)
        fl = simulate(GEAR, omega, x, v, 2)
        assert len(fl.impacts) == n_impacts and p.derived["n_impacts"] == n_impacts
        assert (fl.margin < 0) == (n_impacts == 8)
        assert p.event_values["grazing_margin"] == pytest.approx(fl.margin, abs=1e-11)
        bound = 1e-9 + 1e-11 / np.sqrt(abs(fl.margin))
        assert abs(fl.x - x) < bound and abs(fl.v - v) < bound
        margins.append((omega, fl.margin))
    w, m = np.array(margins[-len(beyond):]).T
    roots = np.roots(np.polyfit(w - yg[2], m, 2)) + yg[2]
    assert np.min(np.abs(roots - yg[2])) < 1e-9
