"""Conservative families in the hybrid layer (:mod:`nsm_continuation.hybrid.conservative`).

Oracles: the energy balance of the unfolding (U1), ``dE/dt = beta qd^T M qd`` (derived
symbolically, independently of the simulator); the elastic bouncing ball, whose family of
periodic orbits is known in closed form (released at height ``h``: energy ``g h``, period
``2 sqrt(2 h / g)``); central differences of the shooting residual (a cross-check of its exact
Jacobian); a damped chain, whose unfolding cannot vanish (the check must end the start with its
reason).
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.chain.hybrid_model import NDofImpactHybridProblem
from pydantic import BaseModel, Field

import nsm_continuation as nsm
from nsm_continuation.core.preflight import STRICT
from nsm_continuation.hybrid.conservative import unfold
from nsm_continuation.hybrid.conservative_family import ConservativeFamilyProblem
from nsm_continuation.hybrid.return_map import CrossingSection
from nsm_continuation.hybrid.specs import IntegratorSpec
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem

G = 9.8
CHAIN = {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0}


class BallParameters(BaseModel):
    model_config = STRICT
    g: float = Field(G, gt=0)
    integrator: IntegratorSpec = IntegratorSpec(rtol=1e-12, atol=1e-14)


class ElasticBall(ConservativeFamilyProblem):
    """The ball bouncing elastically on the floor; section at the apex (``qd = 0`` falling)."""

    name: ClassVar[str] = "elastic_ball"
    Parameters: ClassVar[type[BaseModel]] = BallParameters
    case_parameter: ClassVar[str | None] = "energy"

    def conservative_system(self) -> tuple[HybridSystem, Any]:
        q, qd, g = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("g")
        system = HybridSystem.mechanical("ball", q, qd, {"g": g}, ca.SX(1), -g, q, 1.0,
                                         state_names=["q", "qd"])
        return system, 0.5 * qd ** 2 + g * q

    def section(self) -> CrossingSection:
        return CrossingSection(1, 0.0, 0.0, crossing=-1, returns=1)


def test_unfolding_injects_energy_at_the_rate_beta_qd_M_qd() -> None:
    """(U1): along ``x' = F + beta (0, qd)`` the chain's energy changes at ``beta qd^T M qd``
    (the force ``-K u`` is conservative), whatever the state."""
    pb = NDofImpactHybridProblem(CHAIN)
    h = pb.hybrid
    x = h.x
    M, K = pb.modal.M, pb.modal.K
    n = M.shape[0]
    q, qd = x[:n], x[n:]
    E = 0.5 * (ca.dot(qd, ca.mtimes(ca.DM(M), qd)) + ca.dot(q, ca.mtimes(ca.DM(K), q)))
    rate = ca.Function("rate", [x, *h.params.values()], [ca.jtimes(E, x, h.F)])
    rng = np.random.default_rng(0)
    for _ in range(5):
        X, b = rng.normal(size=2 * n), rng.normal()
        args = [X, *[{"beta": b, "restitution": 1.0, "damping": 0.0}.get(k, 0.3)
                     for k in h.params]]
        assert float(rate(*args)) == pytest.approx(b * X[n:] @ M @ X[n:], rel=1e-12)


def test_unfold_refuses_forced_and_general_systems() -> None:
    q, qd, ph, w = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("ph"), ca.SX.sym("w")
    forced = HybridSystem.mechanical("forced", q, qd, {"w": w}, ca.SX(1), -q + ca.cos(ph),
                                     1 - q, 1.0, clock=ph, clock_rate=w)
    with pytest.raises(HybridDeclarationError, match="autonomous"):
        unfold(forced)
    x = ca.SX.sym("x", 2)
    general = HybridSystem("general", x, {}, ca.vertcat(x[1], -x[0]), 1 - x[0],
                           ca.vertcat(0, -2), ["x", "v"])
    with pytest.raises(HybridDeclarationError, match="mechanical"):
        unfold(general)


def test_elastic_ball_family_in_energy_matches_its_closed_form() -> None:
    """The family of the elastic ball continued in the energy from the apex ``q = 1``: at
    every orbit the period is ``2 sqrt(2 E) / g`` and the apex ``E / g``, and ``beta``
    vanishes to rounding; the section map's only multiplier is the family's ``+1`` (nothing
    is left after its removal, which is accurate to rounding)."""
    pb = ElasticBall({})
    res = nsm.continuation(pb, {"guess": {"q": 1.0}, "direction": "increase"},
                           parameter="energy", min=G, max=2 * G, max_points=30,
                           step={"initial": 0.5, "max": 2.0})
    pts = res.branches[0].raw.points
    assert len(pts) >= 5 and pts[-1].derived["energy"] == pytest.approx(2 * G, rel=1e-12)
    for p in pts:
        E = p.derived["energy"]
        assert p.derived["period"] == pytest.approx(2 * np.sqrt(2 * E) / G, rel=1e-11)
        assert p.y[0] == pytest.approx(E / G, rel=1e-11)
        assert abs(p.derived["beta"]) * p.derived["period"] < 1e-12
        assert p.multipliers is not None and p.multipliers.size == 0
        assert p.trivial_error < 1e-9


def test_shooting_jacobian_matches_central_differences() -> None:
    """The exact Jacobian of (U2), in each quantity, against central differences of the
    residual at a point off the family (``beta != 0``, not periodic)."""
    pb = NDofImpactHybridProblem(CHAIN)
    (sp,) = pb.start_points({"omega": 0.5})
    y = np.asarray(sp.y, dtype=float)
    y[:-1] += 1e-3 * np.sin(np.arange(y.size - 1))
    for quantity in ("omega", "period", "energy"):
        pb.set_parameter(quantity)
        y[-1] = {"omega": 0.51, "period": 12.0, "energy": 0.8}[quantity]
        _, J = pb.evaluate_with_jacobian(y)
        fd = np.empty_like(J)
        for k in range(y.size):
            h = 1e-6 * (1.0 + abs(y[k]))
            e = np.zeros_like(y)
            e[k] = h
            fd[:, k] = (pb.evaluate(y + e) - pb.evaluate(y - e)) / (2 * h)
        assert np.max(np.abs(J - fd)) < 1e-6 * max(1.0, np.max(np.abs(J))), quantity


def test_unfolding_that_does_not_vanish_ends_the_start_with_its_reason() -> None:
    """A damped chain has no family: the unfolding balances the damping (``beta > 0``), and the
    check refuses the orbit, naming the cause."""
    pb = NDofImpactHybridProblem({**CHAIN, "damping": 1e-3})
    res = nsm.continuation(pb, {"omega": 0.5}, parameter="omega", min=0.45, max=0.55,
                           max_points=5)
    (reason,) = set(res.branches[0].termination.values())
    assert "unfolding: beta" in reason and "not conservative" in reason, reason
    assert not res.branches[0].raw.points
