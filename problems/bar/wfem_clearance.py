"""The WFEM bar with a second contact: its end in a clearance between two walls, on the lattice.

Yoong, Thorin, Legrand (2017) compute the nonsmooth modes of the bar clamped at x = 0 with one
obstacle at x = L (``u_end <= g0``). Here the end meets a second wall, ``u_end >= -g1``
(``g1``: ``lower_gap``), and an orbit alternates ``m`` free steps (leaving the upper wall),
``p`` steps on the lower wall, ``k`` free steps, ``l`` steps on the upper wall: the pattern
``(m, p, k, l)`` of the paper's two contact phases (eq. 18), with its second contact phase on
the other wall.

**What carries over unchanged.** A contact phase on either wall holds the end still, so it is
the same reflection ``a_N' = +b_N`` (B.3) whatever the wall's position: the operator
``A_c^l A_f^k A_c^p A_f^m`` is the paper's, a signed permutation of the characteristic ring
(:func:`~problems.bar.wfem_operators.phase_operator`), and its kernel has a basis of cycle
vectors (O(N) per node) as for one wall.

**What changes: the conditions fixing a kernel vector** (derived here as in
:mod:`problems.bar.wfem_lattice`, with ``J[n]`` the characteristic arriving at the end and
``u_end`` falling by ``dt J[n] / Z`` over a free step):

* normalisation at the upper wall: ``u_end(0) = g0``, i.e. ``sum_k w_k = 2 E g0 / dx`` (C1);
* the first free phase crosses the clearance: ``sum_(free 1) J = Z (g0 + g1) / dt`` (C2),
  inhomogeneous where the one-wall closure ``sum J = 0`` is homogeneous (the second free phase
  closes by periodicity). So (C1)-(C2) fix a *unique* candidate where ``h = 2``, and its energy
  is a quadratic form in ``(g0, g1)``: no longer ``g0^2`` times a number of the node;
* COND1 two-sided: ``0 <= sum_(first j steps) J <= Z (g0 + g1) / dt`` inside free phase 1,
  ``-Z (g0 + g1) / dt <= ... <= 0`` inside free phase 2;
* COND2 by wall: the upper wall pushes (``J <= 0``: compression, as for one wall), the lower
  wall pulls the end back (``J >= 0``: the end stress is tensile while the end is held);
* COND3 unchanged (strains ``> -1``).

:func:`solve_clearance_node` returns the orbit at a node; :func:`symmetric_clearance_nodes`
scans the symmetric nodes ``(m, p, m, p)`` of a window of periods.
"""

from __future__ import annotations

import numpy as np
from nsm_continuation.problems.bar.wfem_lattice import (
    BarModel,
    LatticeSolution,
    minimal_period_divisor,
    zero_interaction_steps,
)
from nsm_continuation.problems.bar.wfem_operators import (
    end_series,
    pattern_from_counts,
    phase_operator,
    ring_energy,
)

#: round-off (relative, per step) below which a margin is zero, as in
#: :func:`problems.bar.wfem_lattice.admissibility_margins`
ROUND_OFF = 1e-9


def clearance_margins(model: BarModel, w0: np.ndarray, J: np.ndarray,
                      counts: tuple[int, int, int, int], lower_gap: float
                      ) -> tuple[dict[str, float], list[int]]:
    """COND1-COND3 of the clearance as margins (>= 0 admissible; scaled by the characteristic
    amplitude) and the grazing steps (interior free steps where ``u_end`` touches a wall)."""
    m, p, k, l_ = counts
    A = float(np.max(np.abs(w0))) or 1.0
    D = model.Z * (model.g0 + lower_gap) / model.dt / A
    cond1, grazing = np.inf, []
    for a, b, lo, hi in ((0, m, 0.0, D), (m + p, m + p + k, -D, 0.0)):
        P = np.cumsum(J[a:b]) / A
        inner = P[:-1]
        if inner.size:
            cond1 = min(cond1, float(np.min(inner - lo)), float(np.min(hi - inner)))
            near = np.minimum(np.abs(inner - lo), np.abs(hi - inner))
            grazing += [a + 1 + int(i) for i in np.nonzero(near <= ROUND_OFF * (b - a))[0]]
        target = hi if lo == 0.0 else lo  # the free phase ends on the other wall
        cond1 = min(cond1, -abs(float(P[-1]) - target) + ROUND_OFF * (b - a))
    upper = J[m + p + k:]
    lower = J[m:m + p]
    cond2 = float(min(-upper.max(), lower.min()) / A)
    cond3 = float(1.0 - A / model.E)
    margins = {"cond1_gap": cond1, "cond2_contact_force": cond2, "cond3_strain": cond3}
    margins = {key: (0.0 if -ROUND_OFF <= v < 0 else v) for key, v in margins.items()}
    return margins, grazing


def solve_clearance_node(model: BarModel, counts: tuple[int, int, int, int], lower_gap: float,
                         *, tol: float = 1e-9) -> tuple[str, LatticeSolution | None]:
    """The orbit at the node ``(m, p, k, l)`` of the clearance ``-lower_gap <= u_end <= g0``:
    ``(status, solution)`` with ``status`` one of ``"admissible"``, ``"empty kernel"``,
    ``"h < 2"``, ``"h > 2"`` (no unique candidate), ``"singular normalisation"`` and
    ``"inadmissible: <conditions>"`` (the solution is returned also when inadmissible)."""
    if len(counts) != 4 or any(int(c) < 1 for c in counts):
        raise ValueError(f"a clearance node is four positive phase lengths: {counts}")
    if not (model.g0 > 0 and lower_gap > 0):
        raise ValueError("the clearance needs both gaps positive (g0 > 0, lower_gap > 0)")
    counts = tuple(int(c) for c in counts)  # type: ignore[assignment]
    pattern = pattern_from_counts(*counts)
    op = phase_operator(model.N, pattern)
    h = op.kernel_dimension()
    if h == 0:
        return "empty kernel", None
    if h != 2:
        return ("h < 2" if h < 2 else "h > 2"), None
    K = op.kernel()
    Js = np.array([end_series(K[:, j], pattern) for j in range(h)])
    C = np.array([K.sum(axis=0), Js[:, :counts[0]].sum(axis=1)])
    d = np.array([2 * model.E * model.g0 / model.dx,
                  model.Z * (model.g0 + lower_gap) / model.dt])
    if abs(np.linalg.det(C)) <= tol * max(1.0, np.abs(C).max()) ** h:
        return "singular normalisation", None
    alpha = np.linalg.solve(C, d)
    w0 = K @ alpha
    J = alpha @ Js
    margins, grazing = clearance_margins(model, w0, J, counts, lower_gap)  # type: ignore[arg-type]
    sol = LatticeSolution(model, counts, w0, J, h, ring_energy(w0, model.dx, model.E),
                          margins, grazing, False)
    failed = [key for key, v in margins.items() if v < -tol]
    return ("inadmissible: " + ", ".join(failed) if failed else "admissible"), sol


def persists_under_refinement(sol: LatticeSolution, lower_gap: float, factor: int = 2,
                              tol: float = 1e-9) -> bool:
    """Whether the orbit survives ``N -> factor N`` (the profile with every slot repeated is a
    fixed point of the refined node, still admissible): the test of
    :func:`problems.bar.wfem_lattice.persists_under_refinement` with the clearance's
    conditions."""
    fine = sol.model.refined(factor)
    counts = tuple(factor * c for c in sol.counts)
    pattern = pattern_from_counts(*counts)
    w = np.repeat(sol.w0, factor)
    if not np.allclose(phase_operator(fine.N, pattern).apply(w), w,
                       atol=tol * np.max(np.abs(w))):
        return False
    margins, _ = clearance_margins(fine, w, end_series(w, pattern), counts,  # type: ignore[arg-type]
                                   lower_gap)
    return all(v >= -tol for v in margins.values())


def classify(sol: LatticeSolution, lower_gap: float) -> str:
    """``"physical"`` or the reason the filter of :func:`problems.bar.wfem_lattice.classify`
    removes the orbit (a step of zero end interaction makes it a relabelling of other nodes,
    a shorter period, a grid-scale orbit)."""
    if zero_interaction_steps(sol):
        return "relabelled (zero end interaction)"
    if minimal_period_divisor(sol) > 1:
        return "not minimal period"
    if not persists_under_refinement(sol, lower_gap):
        return "grid-scale (does not persist under N -> 2N)"
    return "physical"


def symmetric_clearance_nodes(model: BarModel, lower_gap: float, M_min: int, M_max: int
                              ) -> list[LatticeSolution]:
    """The admissible physical orbits (:func:`classify`) at the symmetric nodes
    ``(m, p, m, p)`` with period ``M = 2 (m + p)`` steps in ``[M_min, M_max]``, by increasing
    period."""
    out = []
    for M in range(max(4, M_min + M_min % 2), M_max + 1, 2):
        for p in range(1, M // 2):
            status, sol = solve_clearance_node(model, (M // 2 - p, p, M // 2 - p, p), lower_gap)
            if status == "admissible" and sol is not None and classify(sol, lower_gap) == \
                    "physical":
                out.append(sol)
    return out
