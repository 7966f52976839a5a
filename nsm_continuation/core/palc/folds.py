"""Folds (limit points) of a branch: when a sign change of the tangent's parameter component
is one.

A fold is a point where the continuation parameter ``p`` reaches an extremum along the branch.
Its test function is the parameter component ``t_p`` of the unit tangent, the solution of the
bordered system ``A t = e_(n+1)``, ``A = [G_y; r^T]`` (AUTO-07p's ``FNLPAE`` and MatCont's
limit-point test function are this component; BifurcationKit detects a fold by the parameter's
monotony over three consecutive points). Along a family on which the parameter is constant (a
vertical family: the chain's modes at ``g = 0``, Prop. 7.2; families of period-2 orbits of the
impacting chain) ``t_p`` is the tangent's noise and changes sign at random, and where ``G_y`` is
nearly singular (the start of a family next to the bifurcation it is born at) that noise is
large. A sign change of ``t_p`` between two points is therefore a fold only if
(:func:`is_fold`):

* ``t_p`` is known there: its modulus exceeds its accuracy (:class:`Accuracy`, eq. (F1)) at
  both ends, or at one end with the parameter confirming the turn; and
* the parameter does not contradict it: the located point's parameter is an extremum with
  respect to both ends (on the same side of both), beyond the accuracy of the points'
  parameters (eq. (F2)), at least where the tangent is known at one end only.

Accuracy of the tangent (F1). A perturbation ``dA`` of ``A`` moves ``t`` by ``dt = -A^-1 dA t``
to first order, whose parameter component is at most ``|dA|_2 |A^-T e_p|_2`` (``|t| = 1``;
the bound is attained for ``dA`` aligned with ``A^-T e_p t^T``). ``|dA|`` is the Jacobian's
accuracy (:meth:`~nsm_continuation.core.problem.Problem.jacobian_noise`: rounding for a
closed-form Jacobian, the integrator's tolerance for a simulated one) plus the backward error
of the LU solve, ``SOLVE_ROUNDING eps |A|_2``. ``|A^-T e_p|`` is the parameter's row of
``A^-1``: about ``1 / sigma_min(A)`` where the near-null direction of ``A`` moves the
parameter (a nearly singular ``G_y``), small on a well-conditioned stretch of the branch.

Accuracy of a point's parameter (F2). The corrector stopped once its update was below
``newton_tol (1 + |y|_inf)``; the residual ``G(y)`` left would move the point by
``A^-1 [G; 0]``, whose parameter component is at most ``|G|_2 |A^-T e_p|_2``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from nsm_continuation.core.floquet.norms import spectral_norm
from nsm_continuation.core.palc.errors import NUMERICAL_ERRORS

if TYPE_CHECKING:
    from nsm_continuation.core.problem import Problem

#: the backward error of the LU solve of the bordered system, in units of ``eps |A|_2``
SOLVE_ROUNDING = 10.0


@dataclass(frozen=True)
class Accuracy:
    """How well a point's tangent and parameter are known (module docstring, (F1), (F2));
    infinite where the bordered matrix cannot be formed or solved there."""

    #: bound on the error of the tangent's parameter component (F1)
    tangent: float
    #: bound on the error of the point's parameter (F2)
    parameter: float


def accuracy(problem: Problem, y: np.ndarray, tangent: np.ndarray,
             newton_tol: float) -> Accuracy:
    """The accuracy (F1), (F2) of the point ``y`` with unit tangent ``tangent`` on a branch of
    ``problem`` (one evaluation of ``G`` and ``G_y`` and one dense solve with ``A^T``)."""
    ip = problem.parameter_index
    try:
        g, jac = problem.evaluate_with_jacobian(np.asarray(y, dtype=float))
        A = np.vstack([np.asarray(jac, dtype=float), np.asarray(tangent, dtype=float)[None, :]])
        e = np.zeros(A.shape[0])
        e[ip] = 1.0
        row = float(np.linalg.norm(np.linalg.solve(A.T, e)))
        noise = problem.jacobian_noise(y, jac) \
            + SOLVE_ROUNDING * float(np.finfo(float).eps) * spectral_norm(A)
    except NUMERICAL_ERRORS:
        return Accuracy(np.inf, np.inf)
    if not (np.isfinite(row) and np.isfinite(noise)):
        return Accuracy(np.inf, np.inf)
    placed = newton_tol * (1.0 + float(np.max(np.abs(y)))) + float(np.linalg.norm(g)) * row
    return Accuracy(noise * row, placed)


def known_ends(tangents: tuple[float, float], accuracies: tuple[Accuracy, Accuracy]) -> int:
    """At how many of the two ends the tangent's parameter component exceeds its accuracy."""
    return sum(abs(t) > acc.tangent for t, acc in zip(tangents, accuracies, strict=True))


def is_fold(tangents: tuple[float, float], accuracies: tuple[Accuracy, Accuracy],
            parameters: tuple[float, float, float], located: Accuracy) -> bool:
    """Whether the sign change of the tangent's parameter component between two points is a
    fold (module docstring). ``tangents``: the component at the two ends; ``accuracies``:
    theirs (:func:`accuracy`); ``parameters``: the parameter at the first end, at the located
    zero of the component and at the second end; ``located``: the located point's accuracy.

    With ``d_i = p_located - p_i`` and ``nu_i`` the sum of the two points' parameter accuracies:
    the turn is *confirmed* when ``|d_a| > nu_a``, ``|d_b| > nu_b`` and ``d_a d_b > 0`` (the
    located point lies beyond both ends on the same side), *contradicted* when both exceed
    their ``nu`` with opposite signs (it lies between them: the parameter is monotone over the
    step). A fold: the component known at both ends and not contradicted, or known at one end
    and confirmed."""
    known = known_ends(tangents, accuracies)
    if known == 0:
        return False
    pa, pf, pb = parameters
    da, db = pf - pa, pf - pb
    beyond_a = abs(da) > accuracies[0].parameter + located.parameter
    beyond_b = abs(db) > accuracies[1].parameter + located.parameter
    if beyond_a and beyond_b:
        return da * db > 0
    return known == 2
