"""The linear normal form of a Krein collision (MacKay 1986) as a one-parameter family of
symplectic maps: the time-``tau`` map of ``H = w1 I1 - w2 I2 + eps q1 q2``
(``I_j = (q_j^2 + p_j^2) / 2``), continued in ``w2`` along the trivial branch ``x = w2``.

Closed forms: with ``q'' = -D K q`` (``D = diag(w1, -w2)``, ``K = [[w1, eps], [eps, -w2]]``)
the squared frequencies are the roots of ``mu^2 - (w1^2 + w2^2) mu + w1^2 w2^2 + w1 w2 eps^2``,
complex (a quadruple of multipliers off the circle: an instability window) exactly where
``(w1^2 - w2^2)^2 < 4 w1 w2 eps^2``. With ``eps = 0`` the two frequencies (of opposite
signature) pass through each other at ``w2 = w1``: no window.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel
from scipy.linalg import expm
from scipy.optimize import brentq

from nsm_continuation.core.floquet import KreinFloquetData
from nsm_continuation.core.preflight import STRICT
from nsm_continuation.core.problem import Problem, StartPoint

J4 = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])


class KreinParameters(BaseModel):
    model_config = STRICT
    w1: float = 1.0
    eps: float = 0.05
    tau: float = 1.0
    start: float = 0.6


def hessian(w1: float, w2: float, eps: float) -> np.ndarray:
    """``S`` of ``H = z^T S z / 2``, ``z = (q1, q2, p1, p2)``."""
    S = np.diag([w1, -w2, w1, -w2]).astype(float)
    S[0, 1] = S[1, 0] = eps
    return S


def window_edges(w1: float, eps: float) -> tuple[float, float]:
    """The two values of ``w2`` where ``(w1^2 - w2^2)^2 = 4 w1 w2 eps^2`` around ``w1``."""
    def g(w2: float) -> float:
        return (w1**2 - w2**2) ** 2 - 4 * w1 * w2 * eps**2
    return brentq(g, 0.5 * w1, w1, xtol=1e-15), brentq(g, w1, 2.0 * w1, xtol=1e-15)


class KreinNormalForm(Problem):
    """Unknowns ``(x, w2)``, residual ``x - w2``; the multipliers are those of the time-``tau``
    map of the normal form at ``w2``, with their Krein definiteness ``v^H S v / (|v|^2 |S|)``
    (on the circle the sign of the mode's energy, the Krein signature)."""

    name: ClassVar[str] = "test_krein_normal_form"
    Parameters: ClassVar[type[BaseModel]] = KreinParameters

    def __init__(self, params: BaseModel) -> None:
        super().__init__(params)
        self.variables = ["x", "w2"]
        self.parameter = "w2"

    @property
    def conservative(self) -> bool:
        return True

    def residual(self, y: Any) -> Any:
        return y[0] - y[1]

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> KreinFloquetData:
        p = self.params
        S = hessian(p.w1, float(y[1]), p.eps)
        lam, V = np.linalg.eig(J4 @ S)
        mult = np.exp(p.tau * lam)
        norm = np.linalg.norm(S, 2)
        krein = np.array([float((v.conj() @ S @ v).real / ((v.conj() @ v).real * norm))
                          for v in V.T])
        M = expm(p.tau * J4 @ S)
        return KreinFloquetData(mult, matrix_norm=float(np.linalg.norm(M, 2)), krein=krein)

    def start_points(self, start: Any, window: Any = (None, None)) -> list[StartPoint]:
        w = self.params.start
        return [StartPoint(np.array([w, w]), "trivial", 1)]
