"""A fold is a turn of the parameter, not a sign change of the tangent's noise
(:mod:`nsm_continuation.core.palc.folds`).

Oracles: a family on which the parameter is constant, ``{mu = mu0} x R`` (no fold anywhere),
and the same family bent into a parabola ``mu = mu0 - c x^2`` (one fold, at ``(0, mu0)``),
both with a Jacobian known only to ``delta`` (a deterministic, rounding-like noise of each
entry, declared by the problem as its accuracy); and the definition of a fold for the decision
itself (:func:`is_fold`).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
import pytest
from helpers import NoParameters
from pydantic import BaseModel

from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.palc.folds import Accuracy, accuracy, is_fold
from nsm_continuation.core.problem import Problem, StartPoint
from nsm_continuation.core.settings import ContinuationSettings

MU0 = 1.3


def _jitter(y: np.ndarray, salt: float) -> float:
    """A value in [-1, 1] that changes erratically with ``y`` (a rounding-like noise)."""
    v = np.sin(12.9898 * y[0] + 78.233 * y[1] + salt) * 43758.5453
    return float(2.0 * (v - np.floor(v)) - 1.0)


class NoisyParabola(Problem):
    """``G(x, mu) = (mu - mu0 + c x^2)(1 + x^2)``: the family ``mu = mu0 - c x^2``, vertical
    for ``c = 0``. The residual carries a noise of ``residual_noise`` and each entry of the
    Jacobian one of ``delta`` (declared: :meth:`jacobian_noise` is the noise matrix's
    Frobenius bound ``sqrt(2) delta``). A vertical family's start, corrected at fixed
    ``mu``, is a singular solve that converges only where the residual vanishes exactly:
    it is given none."""

    name: ClassVar[str] = "noisy_parabola"
    Parameters: ClassVar[type[BaseModel]] = NoParameters

    def __init__(self, c: float, delta: float, residual_noise: float) -> None:
        super().__init__(NoParameters())
        self.variables = ["x", "mu"]
        self.parameter = "mu"
        self.c, self.delta, self.residual_noise = c, delta, residual_noise

    def residual(self, y: Any) -> Any:  # pragma: no cover - numeric problem
        raise NotImplementedError

    @property
    def compiled(self) -> Any:
        return None

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        x, mu = float(y[0]), float(y[1])
        g = (mu - MU0 + self.c * x * x) * (1.0 + x * x)
        return np.array([g + self.residual_noise * _jitter(y, 0.0)])

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        x, mu = float(y[0]), float(y[1])
        f = mu - MU0 + self.c * x * x
        exact = np.array([[2.0 * self.c * x * (1.0 + x * x) + 2.0 * x * f, 1.0 + x * x]])
        noise = np.array([[_jitter(y, 1.0), _jitter(y, 2.0)]])
        return exact + self.delta * noise

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.evaluate(y), self.jacobian(y)

    def jacobian_noise(self, y: np.ndarray, jacobian: np.ndarray) -> float:
        return float(np.sqrt(2.0) * self.delta)


DELTA = 1e-8
#: the fixed threshold of the tangent test before it scaled with the tangent's accuracy
OLD_FIXED_THRESHOLD = 1e-9


def _run(problem: Problem, **kw: Any):
    settings = ContinuationSettings(**{"step_initial": 0.02, "step_max": 0.1,
                                       "max_points": 40, "param_min": MU0 - 1.0,
                                       "param_max": MU0 + 1.0, **kw})
    return ContinuationEngine(problem, settings).run(
        StartPoint(np.array([0.3, MU0 - problem.c * 0.09]), "t"))


def test_vertical_family_has_no_fold() -> None:
    """Along ``mu = mu0`` the tangent's ``mu`` component is the Jacobian's noise divided by
    ``1 + x^2``: it changes sign between consecutive points with a modulus far above the old
    fixed threshold (so that threshold reported folds here), and below its accuracy (F1): no
    fold is reported. The points stay on the family to the corrector's accuracy."""
    br = _run(NoisyParabola(0.0, DELTA, 0.0))
    pts = br.points
    assert len(pts) >= 60
    tp = np.array([p.tangent[1] for p in pts])
    flips = [(i, i + 1) for i in range(len(pts) - 1) if np.sign(tp[i]) != np.sign(tp[i + 1])
             and max(abs(tp[i]), abs(tp[i + 1])) > OLD_FIXED_THRESHOLD]
    assert len(flips) >= 10  # what the fixed threshold took for folds
    assert [e.kind for e in br.events if e.kind == "fold"] == []
    assert max(abs(p.y[1] - MU0) for p in pts) < 1e-11
    # the accuracy bounds the noise it accounts for: |t_p| <= sqrt(2) delta / (1 + x^2)
    # (the exact component is 0) and (F1) is exactly that bound here
    for p in pts[:10]:
        acc = accuracy(NoisyParabola(0.0, DELTA, 0.0), p.y, p.tangent, 1e-11)
        assert abs(p.tangent[1]) <= acc.tangent
        assert acc.tangent == pytest.approx(np.sqrt(2.0) * DELTA / (1.0 + p.y[0] ** 2),
                                            rel=1e-3)


@pytest.mark.parametrize("c", [1e-3, 1.0])
def test_true_fold_is_located_through_the_noise(c: float) -> None:
    """On ``mu = mu0 - c x^2`` the one fold, at ``(0, mu0)``, is reported once, located where
    the computed tangent's ``mu`` component vanishes: ``2 c x`` against the noise, so
    ``|x| <= sqrt(2) delta / (2 c)`` (plus ``event_tol``), and ``mu`` is ``mu0 - c x^2``."""
    br = _run(NoisyParabola(c, DELTA, 1e-13))
    folds = [e for e in br.events if e.kind == "fold"]
    assert len(folds) == 1, [(e.kind, e.point.y) for e in br.events]
    x, mu = folds[0].point.y
    tol_x = np.sqrt(2.0) * DELTA / (2.0 * c) + 1e-12
    assert abs(x) <= tol_x
    assert abs(mu - MU0) <= c * tol_x ** 2 + 1e-12


def _acc(tangent: float, parameter: float) -> Accuracy:
    return Accuracy(tangent=tangent, parameter=parameter)


@pytest.mark.parametrize("tangents, accs, params, expected, why", [
    # the component below its accuracy at both ends: noise
    ((1e-9, -1e-12), (_acc(1e-8, 1e-11), _acc(1e-10, 1e-11)), (1.0, 1.0 + 3e-13, 1.0 - 1e-13),
     False, "unknown at both ends"),
    # known at one end only, the parameter flat within its accuracy: not confirmed
    ((1e-6, -1e-12), (_acc(1e-8, 1e-11), _acc(1e-10, 1e-11)), (1.0, 1.0 + 3e-13, 1.0 - 1e-13),
     False, "one end, unconfirmed"),
    # known at one end only, the located parameter beyond both ends on the same side
    ((1e-6, -1e-12), (_acc(1e-8, 1e-11), _acc(1e-10, 1e-11)), (1.0, 1.0 + 1e-8, 1.0 + 5e-9),
     True, "one end, confirmed"),
    # known at both ends, the located point next to one end (within the noise of it)
    ((1e-6, -1e-3), (_acc(1e-10, 1e-11), _acc(1e-10, 1e-11)), (1.0, 1.0 + 1e-12, 1.0 - 0.0),
     True, "both ends, the fold next to one"),
    ((1e-6, -1e-3), (_acc(1e-10, 1e-11), _acc(1e-10, 1e-11)), (1.0, 1.0 + 1e-12, 1.0 + 1e-6),
     True, "both ends, the fold next to one (the far one beyond)"),
    # known at both ends but the located point lies between the ends: the parameter is
    # monotone over the step
    ((1e-6, -1e-3), (_acc(1e-10, 1e-11), _acc(1e-10, 1e-11)), (1.0, 1.0 + 1e-6, 1.0 + 2e-6),
     False, "contradicted"),
])
def test_is_fold_follows_the_definition(tangents, accs, params, expected, why) -> None:
    assert is_fold(tangents, accs, params, _acc(1e-10, 1e-11)) is expected, why
