"""A multiplier through +1 named by the tangent test, and crossings that need evidence.

Oracles (closed forms):

* a map symmetric under ``v -> -v`` whose symmetric fixed points ``u = 2 sin(mu), v = 0`` lose
  stability in a symmetry-breaking pitchfork where the antisymmetric multiplier
  ``0.3 + 1.8 sin(mu)`` is +1: ``mu* = arcsin(7 / 18)``; the parameter never turns there. One
  ``branch_point`` (the bordered determinant and the multiplier, merged), no ``fold``;
* the same in a conservative family: the area-preserving map ``v' = v + mu u - u^3,
  u' = u + v'``, whose elliptic fixed point's pair collides at +1 at ``mu = 0`` where
  ``u = +-sqrt(mu)`` branch off: one ``branch_point``, no ``fold``;
* the limit point of ``mu = x^2`` of the map ``x + mu - x^2`` (multiplier ``1 - 2 x``): the
  parameter turns at ``mu = 0``, a ``fold``, no ``branch_point``;
* a complex pair held at ``|lambda| = 1 + 7.9e-5`` while the multipliers' declared noise grows
  through 7.9e-5 at ``p = 0.3``: the count of multipliers outside changes there, but the pair
  never crosses the circle: no ``neimark_sacker``, one ``unresolved_crossing``; a pair that
  does cross (``|lambda| = 1 + (p - 0.5) / 10``) with the same noise is still a located
  ``neimark_sacker``.
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np
from helpers import NoParameters
from pydantic import BaseModel

from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import FloquetData, Problem, StartPoint
from nsm_continuation.core.records import Branch
from nsm_continuation.core.settings import ContinuationSettings

MU_PITCHFORK = float(np.arcsin(7.0 / 18.0))


class _MapFamily(Problem):
    """Fixed points of a 2-d map ``F(x; mu)``: residual ``F - x``, multipliers the eigenvalues
    of the exact Jacobian of ``F``."""

    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self) -> None:
        super().__init__(NoParameters())
        self.variables = ["u", "v", "mu"]
        self.parameter = "mu"
        x, mu = ca.SX.sym("x", 2), ca.SX.sym("mu")
        self._DF = ca.Function("DF", [x, mu], [ca.jacobian(self.map(x, mu), x)])

    def map(self, x: Any, mu: Any) -> Any:
        raise NotImplementedError

    def residual(self, y: Any) -> Any:
        return self.map(y[:2], y[2]) - y[:2]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData:
        DF = np.asarray(self._DF(y[:2], y[2]), dtype=float)
        return FloquetData(np.linalg.eigvals(DF).astype(complex),
                           matrix_norm=float(np.linalg.norm(DF, 2)))


class SymmetricMap(_MapFamily):
    """``F(u, v) = (u / 2 + sin(mu) + v^2 / 3, v (0.3 + 0.9 u) - v^3)``, symmetric under
    ``v -> -v``."""

    name: ClassVar[str] = "symmetric_map"

    def map(self, x: Any, mu: Any) -> Any:
        return ca.vertcat(x[0] / 2 + ca.sin(mu) + x[1] ** 2 / 3,
                          x[1] * (0.3 + 0.9 * x[0]) - x[1] ** 3)


class SaddleNodeMap(_MapFamily):
    """``F(u, v) = (u + mu - u^2, v / 2 + u^2 / 10)``: fixed points ``mu = u^2``."""

    name: ClassVar[str] = "saddle_node_map"

    def map(self, x: Any, mu: Any) -> Any:
        return ca.vertcat(x[0] + mu - x[0] ** 2, x[1] / 2 + x[0] ** 2 / 10)


def _run(problem: Problem, y0: list[float], direction: int, **kw: Any) -> Branch:
    settings = ContinuationSettings(direction=direction, **kw)
    return ContinuationEngine(problem, settings).run(StartPoint(np.asarray(y0, float), "t"))


def test_symmetry_breaking_pitchfork_is_one_branch_point() -> None:
    br = _run(SymmetricMap(), [0.0, 0.0, 0.0], 1, param_max=0.8)
    assert br.termination["forward"] == "bound: mu = max"
    assert not [e for e in br.events if e.kind == "fold"], [e.kind for e in br.events]
    (bp,) = [e for e in br.events if e.kind == "branch_point"]
    (sc,) = [e for e in br.events if e.kind == "stability_change"]
    u, v, mu = bp.point.y
    assert abs(mu - MU_PITCHFORK) <= 2e-12, mu - MU_PITCHFORK
    assert bp.bracket <= 1e-12
    assert abs(v) < 1e-14 and abs(u - 2 * np.sin(mu)) < 1e-12
    # the crossing merged into it: its multiplier is +1 there, stability is lost there
    assert bp.data["test"] == "bordered_determinant"
    assert abs(complex(*bp.data["critical_multiplier"]) - 1.0) < 1e-11
    assert (bp.data["n_outside_before"], bp.data["n_outside_after"]) == (0, 1)
    assert sc.point is bp.point and sc.data["stable_before"] and not sc.data["stable_after"]


def test_limit_point_stays_a_fold() -> None:
    br = _run(SaddleNodeMap(), [-0.5, 0.025, 0.25], -1, param_max=0.3)
    assert not [e for e in br.events if e.kind == "branch_point"], [e.kind for e in br.events]
    (fold,) = [e for e in br.events if e.kind == "fold"]
    assert fold.data["test"] == "tangent"
    assert fold.data["located_on"] == "multiplier_modulus"  # the crossing, merged
    u, _, mu = fold.point.y
    assert abs(u) < 1e-10 and abs(mu) < 1e-12


class NoisyPair(Problem):
    """``x = p`` with a complex pair of modulus ``radius(p)`` at angle 1.1 and a multiplier 0.5,
    declared known to ``noise(p) = 7.9e-5 exp(3 (p - 0.3))`` (as a hybrid orbit's
    ``(rtol + 10 eps) |Phi_T|`` grows near a zero-velocity impact)."""

    name: ClassVar[str] = "noisy_pair"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, radius: Any) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "p"]
        self.parameter = "p"
        self._radius = radius

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData:
        p = float(y[1])
        pair = self._radius(p) * np.exp(1.1j)
        return FloquetData(np.array([pair, np.conj(pair), 0.5]),
                           noise=7.9e-5 * float(np.exp(3.0 * (p - 0.3))))


def test_count_change_within_noise_is_no_crossing() -> None:
    br = _run(NoisyPair(lambda p: 1.0 + 7.9e-5), [0.0, 0.0], 1, param_max=0.6)
    kinds = [e.kind for e in br.events]
    assert "neimark_sacker" not in kinds and "stability_change" not in kinds, kinds
    (ev,) = [e for e in br.events if e.kind == "unresolved_crossing"]
    # where the noise passes the pair's distance to the circle, to the count's bracket
    assert abs(ev.point.y[1] - 0.3) < 1e-8 and ev.bracket <= 1e-9
    assert (ev.data["n_outside_before"], ev.data["n_outside_after"]) == (2, 0)
    assert abs(ev.data["modulus_minus_one"] - 7.9e-5) < 1e-12


def test_resolved_crossing_under_the_same_noise_is_located() -> None:
    br = _run(NoisyPair(lambda p: 1.0 + (p - 0.5) / 10), [0.0, 0.0], 1, param_max=0.6)
    assert "unresolved_crossing" not in [e.kind for e in br.events]
    (ns,) = [e for e in br.events if e.kind == "neimark_sacker"]
    assert ns.data["located_on"] == "multiplier_modulus"
    assert abs(ns.point.y[1] - 0.5) < 1e-10


class SymplecticPitchforkMap(_MapFamily):
    """The area-preserving map ``v' = v + mu u - u^3, u' = u + v'`` (determinant 1, symmetric
    under ``(u, v) -> (-u, -v)``): its fixed point ``u = v = 0`` has the multipliers of trace
    ``2 + mu``, a pair on the unit circle for ``mu < 0`` colliding at +1 at ``mu = 0``, where the
    fixed points ``u = +-sqrt(mu)`` branch off (a pitchfork); the parameter never turns. In a
    conservative family this +1 collision is a ``branch_point``, not a ``fold``."""

    name: ClassVar[str] = "symplectic_pitchfork_map"

    @property
    def conservative(self) -> bool:
        return True

    def map(self, x: Any, mu: Any) -> Any:
        v = x[1] + mu * x[0] - x[0] ** 3
        return ca.vertcat(x[0] + v, v)


def test_conservative_pitchfork_is_one_branch_point() -> None:
    br = _run(SymplecticPitchforkMap(), [0.0, 0.0, -0.4], 1, param_max=0.4)
    assert br.termination["forward"] == "bound: mu = max"
    assert not [e for e in br.events if e.kind == "fold"], [e.kind for e in br.events]
    (bp,) = [e for e in br.events if e.kind == "branch_point"]
    assert abs(bp.point.y[2]) <= 1e-11, bp.point.y
    assert bp.data["test"] == "bordered_determinant"
    # a pair colliding at +1 separates like sqrt|mu|: |lambda - 1| ~ 1e-5 for |mu| ~ 1e-10
    assert abs(complex(*bp.data["critical_multiplier"]) - 1.0) < 1e-4
