"""The spectral norm of a monodromy matrix, the scale of its multipliers' rounding.

``|A|_2`` (the largest singular value) sets the unit-circle tolerance of the multipliers
(``1e3 eps |A|_2``, :class:`~nsm_continuation.core.problem.FloquetData.matrix_norm`) and the
noise of an integrated monodromy (``(rtol + 10 eps) |Phi_T|_2``). It is computed at every
continuation point, where a full singular value decomposition (``np.linalg.norm(A, 2)``)
costs a sizeable share of a point of a large system whose flow is cheap (the exact flows of
:mod:`nsm_continuation.hybrid.linear_flow`): :func:`spectral_norm` takes the largest eigenvalue
of ``A^T A`` alone instead (``|A|_2^2 = lambda_max(A^T A)``; LAPACK's ``dsyevr`` for one
eigenvalue, about half the cost at n = 80). The largest eigenvalue of a symmetric matrix has a
relative error of a few ``n eps`` (it is perfectly conditioned, Weyl's inequality), and so has
its square root: the same value to rounding as the decomposition's.
"""

from __future__ import annotations

import numpy as np


def spectral_norm(A: np.ndarray) -> float:
    """``|A|_2``, the largest singular value of the real or complex matrix ``A``."""
    A = np.asarray(A)
    if A.size == 0:
        return 0.0
    scale = float(np.max(np.abs(A)))
    if not np.isfinite(scale):
        return float("nan")
    if scale == 0.0:
        return 0.0
    A = A / scale                                  # (A^T A would under- or overflow)
    G = A.conj().T @ A if A.shape[0] >= A.shape[1] else A @ A.conj().T
    m = G.shape[0]
    if m == 1:
        return scale * float(np.sqrt(abs(G[0, 0].real)))
    import scipy.linalg as sla  # (not at import: a run of the chain imports no SciPy)

    top = sla.eigh(G, eigvals_only=True, subset_by_index=[m - 1, m - 1], driver="evr",
                   check_finite=False)
    return scale * float(np.sqrt(max(float(top[0]), 0.0)))
