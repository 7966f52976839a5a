"""The N-dof chain of the paper's scaling (2.17), ``m = 1/N``, ``k = N``, gap 1, and its
closed-form periodic orbit (4.2) as unknowns ``y`` (with the branch's tangent there): shared by
the tests of the chain's multipliers and linear algebra."""

from __future__ import annotations

import numpy as np
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem


def scaled_chain(n: int) -> NDofImpactProblem:
    return NDofImpactProblem({"chain": {"dofs": n, "mass": 1.0 / n, "stiffness": float(n)},
                              "gap": 1.0})


def closed_form_y(pb: NDofImpactProblem, T: float) -> np.ndarray:
    """The unknowns of the closed-form orbit (4.2) of period ``T``."""
    u0, du0 = pb.closed_form(T)
    return pb.y_from_state(u0, du0, T)


def closed_form_point(pb: NDofImpactProblem, T: float) -> tuple[np.ndarray, np.ndarray]:
    """The closed-form orbit (4.2) at ``T`` and the unit tangent of the branch there (the null
    vector of the Jacobian)."""
    y = closed_form_y(pb, T)
    t = np.linalg.svd(pb.jacobian(y))[2][-1]
    return y, t
