"""Periodic orbits of the WFEM bar on the (m, p) lattice: kernel, admissibility, filter.

Yoong, Thorin, Legrand (2017), section 5. For a phase pattern (m free steps, p contact steps; or
m, p, k, l for two contact phases, eq. 18) a periodic orbit is a vector ``Q`` in the kernel of
``S_T = A_c^p A_f^m - I`` (12) that also satisfies COND1-COND3. Here ``S_T`` is a signed
permutation of the characteristic ring (:mod:`problems.bar.wfem_operators`), so its kernel has a
basis of cycle vectors and everything below costs O(N) per lattice node.

Conditions fixing a kernel vector (derived here; the paper states them only as COND1-COND3):

* *Normalisation by the gap.* With the bar clamped at x = 0 the end displacement is
  ``u_end = int_0^L sigma / E dx = dx / (2E) * sum_k w_k``; at t = 0 the end leaves the obstacle,
  so ``u_end(0) = g0``: one inhomogeneous linear condition. It sets the amplitude, and the energy
  scales as ``g0^2`` on every lattice node. For ``g0 = 0`` it is homogeneous: the amplitude is free
  and the branch is a vertical line in the frequency-energy plot (section 6).
* *Gap closure.* ``u_end`` is also the time integral of the end velocity ``-J[n]/Z`` over free
  steps (``J[n]``: the characteristic arriving at the end, :func:`end_series`); the two
  reconstructions agree exactly (conservation of ``sum sigma`` with zero flux at the clamped end,
  tested). Contact steps keep ``sum sigma`` constant, so for one contact phase the closure at
  step m follows from periodicity; with q contact phases the first q - 1 free phases need an
  explicit closure ``sum J = 0``. Together: q linear conditions on the h kernel coefficients.
  Hence a *unique* candidate when ``h == q`` (the paper's observation "admissible solutions only
  when h equals the number of contact phases"), a polytope when ``h > q`` (checked by a linear
  programme, :func:`feasible_cone`).
* COND1: ``u_end <= g0`` in free phases, i.e. partial sums of ``J`` over each free phase >= 0.
  COND2: the wall is compressed, ``J[n] <= 0`` in contact steps (the paper's (3) says ``r >= 0``
  with ``sigma(L) = r/S`` but COND2 says ``r <= 0``: we use the compressive contact force
  ``lambda = -S sigma(L) >= 0``). COND3: strains ``sigma/E > -1``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from nsm_continuation.problems.bar.wfem_operators import (
    BarConstants,
    Pattern,
    SignedRotation,
    end_series,
    pattern_from_counts,
    phase_operator,
    ring_energy,
)


@dataclass(frozen=True)
class BarModel(BarConstants):
    """Bar data: E, rho, L, cells N, signed gap g0 (S = 1)."""

    E: float
    rho: float
    L: float
    N: int
    g0: float

    @property
    def dt(self) -> float:
        return self.dx / self.c

    @property
    def energy_ref(self) -> float:
        """Energy of the first linear mode's grazing orbit (14): pi^2 E S g0^2 / (16 L).

        ``u = g0 sin(pi x / 2L) cos(omega_1 t)`` has ``max u(L, t) = g0``; its energy is the strain
        energy at maximum displacement. For ``g0 = 0`` the reference is 1 (absolute energy).
        """
        return float(np.pi**2 * self.E * self.g0**2 / (16 * self.L)) if self.g0 else 1.0

    def refined(self, factor: int = 2) -> BarModel:
        return BarModel(self.E, self.rho, self.L, self.N * factor, self.g0)


@dataclass
class LatticeSolution:
    """One admissible periodic orbit of the WFEM bar at a lattice node."""

    model: BarModel
    counts: tuple[int, ...]
    w0: np.ndarray
    J: np.ndarray
    h: int
    energy: float
    margins: dict[str, float]
    grazing_steps: list[int] = field(default_factory=list)
    amplitude_free: bool = False

    @property
    def pattern(self) -> Pattern:
        return pattern_from_counts(*self.counts)

    @property
    def M(self) -> int:
        return int(sum(self.counts))

    @property
    def period(self) -> float:
        return self.M * self.model.dt

    @property
    def omega(self) -> float:
        return 2 * np.pi / self.period

    @property
    def contact_steps(self) -> int:
        return int(sum(self.counts[1::2]))

    def derived(self) -> dict[str, Any]:
        md = self.model
        return {
            "M": self.M, "m": self.counts[0], "p": self.counts[1],
            **({"k": self.counts[2], "l": self.counts[3]} if len(self.counts) == 4 else {}),
            "omega": self.omega, "omega_ratio": self.omega / md.omega1,
            "period": self.period, "energy": self.energy,
            "energy_ratio": self.energy / md.energy_ref,
            "contact_fraction": self.contact_steps / self.M, "h": self.h,
            "contact_phases": len(self.counts) // 2, "grazing_instants": len(self.grazing_steps),
            "profile_jumps": profile_jumps(self.w0),
        }


def profile_jumps(w: np.ndarray) -> int:
    """Number of sign/level changes of the characteristic profile around the ring."""
    scale = np.max(np.abs(w)) if w.size else 0.0
    if scale == 0:
        return 0
    return int(np.sum(np.abs(w - np.roll(w, 1)) > 1e-9 * scale))


def _closure_rows(Js: np.ndarray, counts: tuple[int, ...]) -> np.ndarray:
    """Rows ``sum_{n in free phase j} J[n]`` for the first q - 1 free phases."""
    rows = []
    t = 0
    for j, c in enumerate(counts):
        if j % 2 == 0 and j < len(counts) - 2:
            rows.append(Js[:, t:t + c].sum(axis=1))
        t += c
    return np.array(rows).reshape(-1, Js.shape[0])


def _masks(counts: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int]]]:
    M = sum(counts)
    free = np.zeros(M, bool)
    t = 0
    phases = []
    for j, c in enumerate(counts):
        if j % 2 == 0:
            free[t:t + c] = True
            phases.append((t, t + c))
        t += c
    return free, ~free, phases


def admissibility_margins(model: BarModel, w0: np.ndarray, J: np.ndarray,
                          counts: tuple[int, ...]) -> tuple[dict[str, float], list[int]]:
    """COND1-COND3 as margins (>= 0 admissible), scaled by the characteristic amplitude.

    Returns the margins and the grazing instants: interior free steps where ``u_end = g0``.
    """
    A = float(np.max(np.abs(w0))) or 1.0
    free, contact, phases = _masks(counts)
    cond1 = np.inf
    grazing: list[int] = []
    for a, b in phases:
        P = np.cumsum(J[a:b]) / A  # (g0 - u_end) * Z / (dt A) after each free step
        inner = P[:-1]
        if inner.size:
            cond1 = min(cond1, float(inner.min()))
            grazing += [a + 1 + int(i) for i in np.nonzero(np.abs(inner) <= 1e-9 * (b - a))[0]]
        cond1 = min(cond1, -abs(float(P[-1])) + 1e-9 * (b - a))  # closure
    cond2 = float(-J[contact].max() / A) if contact.any() else np.inf
    # |sigma| <= max|w| (sigma is the mean of two characteristics): exact bound for COND3
    cond3 = float(1.0 - A / model.E)
    margins = {"cond1_gap": cond1, "cond2_contact_force": cond2, "cond3_strain": cond3}
    # a grazing instant or the closure has margin 0 in exact arithmetic: round-off of order
    # 1e-9 (relative, per step) is not a violation
    margins = {k: (0.0 if -1e-9 <= v < 0 else v) for k, v in margins.items()}
    return margins, grazing


def solve_node(model: BarModel, counts: tuple[int, ...], *, tol: float = 1e-9
               ) -> tuple[str, LatticeSolution | None]:
    """The orbit at a lattice node, if any: ``(status, solution)``.

    ``status`` is one of ``"admissible"``, ``"empty kernel"``, ``"h < q"``, ``"h > q"`` (not a
    unique candidate; see :func:`feasible_cone`), ``"singular normalisation"`` and
    ``"inadmissible: <condition>"``. The solution is returned also when inadmissible (for reports).
    """
    if any(c < 1 for c in counts) or len(counts) % 2:
        raise ValueError(f"phase lengths must be an even number of positive integers: {counts}")
    pattern = pattern_from_counts(*counts)
    op = phase_operator(model.N, pattern)
    h = op.kernel_dimension()
    q = len(counts) // 2
    if h == 0:
        return "empty kernel", None
    if h < q:
        return "h < q", None
    if h > q + (model.g0 == 0):
        return "h > q", None
    K = op.kernel()
    Js = np.array([end_series(K[:, j], pattern) for j in range(h)])
    rows = [K.sum(axis=0)]
    closure = _closure_rows(Js, counts)
    if closure.size:
        rows += list(closure)
    C = np.array(rows)
    amplitude_free = model.g0 == 0
    if amplitude_free:
        # homogeneous conditions: need a one-dimensional null space of C
        _, sv, Vt = np.linalg.svd(C)
        sv = np.concatenate([sv, np.zeros(h - sv.size)])
        if np.sum(sv <= tol * max(sv[0], 1.0)) != 1:
            return "singular normalisation", None
        alpha = Vt[-1]
        alpha *= 1e-3 * model.E / np.abs(K @ alpha).max()  # |characteristic| <= 1e-3 E
        J = alpha @ Js
        if J[_masks(counts)[1]].sum() > 0:  # orient: compressive contact
            alpha = -alpha
    else:
        d = np.zeros(len(rows))
        d[0] = 2 * model.E * model.g0 / model.dx
        if abs(np.linalg.det(C)) <= tol * max(1.0, np.abs(C).max()) ** h:
            return "singular normalisation", None
        alpha = np.linalg.solve(C, d)
    w0 = K @ alpha
    J = alpha @ Js
    margins, grazing = admissibility_margins(model, w0, J, counts)
    sol = LatticeSolution(model, tuple(counts), w0, J, h, ring_energy(w0, model.dx, model.E),
                          margins, grazing, amplitude_free)
    failed = [k for k, v in margins.items() if v < -tol]
    return ("inadmissible: " + ", ".join(failed) if failed else "admissible"), sol


def feasible_cone(model: BarModel, counts: tuple[int, ...]) -> bool:
    """Whether some vector of an ``h > q`` kernel satisfies the conditions (linear programme).

    Used to check the paper's claim that admissible orbits need ``h`` = number of contact phases.
    Variables: the h kernel coefficients; equalities: normalisation and closures; inequalities:
    COND1 partial sums >= 0 and COND2 contact stress <= 0 (COND3 is a scale bound, ignored).
    For ``g0 = 0`` the normalisation is replaced by ``sum_contact J = -1`` (nonzero force).
    """
    from scipy.optimize import linprog

    pattern = pattern_from_counts(*counts)
    op = phase_operator(model.N, pattern)
    K = op.kernel()
    h = K.shape[1]
    if h == 0:
        return False
    Js = np.array([end_series(K[:, j], pattern) for j in range(h)])
    free, contact, phases = _masks(counts)
    A_ub = []
    for a, b in phases:
        P = np.cumsum(Js[:, a:b], axis=1)
        A_ub += list(-P[:, :-1].T)
    A_ub += list(Js[:, contact].T)
    rows = [K.sum(axis=0)]
    closure = _closure_rows(Js, counts)
    rows += list(closure) if closure.size else []
    d = [2 * model.E * model.g0 / model.dx] + [0.0] * (len(rows) - 1)
    if model.g0 == 0:
        rows.append(Js[:, contact].sum(axis=1))
        d.append(-1.0)
    res = linprog(np.zeros(h), A_ub=np.array(A_ub) if A_ub else None,
                  b_ub=np.zeros(len(A_ub)) if A_ub else None, A_eq=np.array(rows),
                  b_eq=np.array(d), bounds=[(None, None)] * h, method="highs")
    return bool(res.status == 0)


# -- the filter: distinct physical orbits ------------------------------------------------------
def zero_interaction_steps(sol: LatticeSolution) -> int:
    """Steps where the end neither moves (free) nor pushes (contact): ``J[n] = 0``.

    On such a step a free step and a contact step coincide, so the same orbit is a solution of
    other patterns (the end rests on the obstacle with zero force): a relabelling.
    """
    A = np.max(np.abs(sol.J)) or 1.0
    return int(np.sum(np.abs(sol.J) <= 1e-12 * A))


def minimal_period_divisor(sol: LatticeSolution) -> int:
    """Largest q > 1 such that the orbit repeats after M/q steps (1 if minimal)."""
    M = sol.M
    pattern = sol.pattern
    best = 1
    for q in range(2, M + 1):
        if M % q:
            continue
        steps = M // q
        # state after `steps` steps of the pattern
        part: list[tuple[int, int]] = []
        left = steps
        for n, s in pattern:
            take = min(n, left)
            if take:
                part.append((take, s))
            left -= take
            if left == 0:
                break
        w = phase_operator(sol.model.N, tuple(part)).apply(sol.w0)
        if np.allclose(w, sol.w0, atol=1e-10 * np.max(np.abs(sol.w0))):
            best = q
    return best


def persists_under_refinement(sol: LatticeSolution, factor: int = 2, tol: float = 1e-9) -> bool:
    """Whether the orbit survives ``N -> factor N``: same times, same profile, still admissible.

    A continuum-limit orbit has a characteristic profile that is piecewise constant on O(1)
    intervals of the ring: on the refined mesh (node ``factor * counts``) the profile with every
    slot repeated ``factor`` times is again a fixed point, with the same gap normalisation and
    energy, and still admissible. (The refined node may have a larger kernel, e.g. M even on 2N
    slots splits a cycle in two; the test is on the orbit, not on h.) A grid-scale orbit, whose
    cycles follow the residues of M modulo 2N, is not a fixed point of the refined operator.
    """
    fine = sol.model.refined(factor)
    counts = tuple(factor * c for c in sol.counts)
    pattern = pattern_from_counts(*counts)
    w = np.repeat(sol.w0, factor)
    op = phase_operator(fine.N, pattern)
    scale = np.max(np.abs(w))
    if not np.allclose(op.apply(w), w, atol=tol * scale):
        return False
    margins, _ = admissibility_margins(fine, w, end_series(w, pattern), counts)
    return all(v >= -tol for v in margins.values())


def classify(sol: LatticeSolution, check_refinement: bool = True) -> str:
    """``"physical"`` or the reason the filter removes the solution."""
    if zero_interaction_steps(sol):
        return "relabelled (zero end interaction)"
    if minimal_period_divisor(sol) > 1:
        return "not minimal period"
    if check_refinement and not persists_under_refinement(sol):
        return "grid-scale (does not persist under N -> 2N)"
    return "physical"


def contact_sign_conflict(Js_contact: np.ndarray) -> bool:
    """Whether COND2 (compressive contact, ``J <= 0`` on every contact step) fails for *every*
    sign combination of an ``h > q`` kernel, read from the cycle vectors' end series alone.

    ``Js_contact[j, n]``: the end series of cycle vector j at the contact steps. Each step reads
    one slot of the ring (``J[n] = w[N-1]``, and ``J[n] = +-J[n - 2N]`` a lap later,
    :func:`~problems.bar.wfem_operators.end_series`), so each column has at most one nonzero,
    of the modulus ``1/sqrt(L)`` all cycle vectors share (cycles of one rotation have one
    length L). A combination ``alpha = c eps / total(eps)`` (``eps_j = +-1``) gives
    ``J[n] = c eps_j Js[j, n] / total``: one sign per cycle over all its contact steps. A cycle
    whose contact steps carry both signs therefore makes ``J > 0`` at modulus ``max |J|`` on some
    contact step, whatever ``eps``: the screen of :func:`node_solutions` (``J <= 1e-9 max|J|``)
    rejects every combination, and the ``2^(h-1)`` of them need not be formed. O(h p)."""
    if Js_contact.size == 0:
        return False
    return bool(np.any((Js_contact > 0).any(axis=1) & (Js_contact < 0).any(axis=1)))


def scan_screen(N: int, M: int, ms: np.ndarray, chunk: int = 256) -> np.ndarray:
    """Which one-contact-phase nodes ``(m, M - m)`` of a period may carry an admissible orbit
    when ``g0 != 0``: False where COND2 certainly fails, for every candidate of the node.

    The batch form of :func:`contact_sign_conflict` for all nodes of a period, without forming
    any kernel basis or end series: at ``g0 != 0`` every candidate of a node (the unique one of
    :func:`solve_node` when ``h = 1``, every sign combination of :func:`node_solutions` when
    ``h > 1``) is a sum of the node's kernel cycle vectors with nonzero coefficients of one
    modulus, so a kernel cycle whose contact steps carry both signs puts ``J = max|J| > 0`` on a
    contact step. The signs come in closed form, vectorised over the nodes (O(M N) per period
    in a few array operations instead of ~200 small ones per node):

    * slot k has the sign ``(-1)^c``, ``c`` the number of free steps ``n < m`` with
      ``n = N-1-k (mod 2N)`` (:func:`~problems.bar.wfem_operators.phase_operator`);
    * the cycles of the rotation ``M mod 2N`` are the slot classes modulo ``g``
      (:meth:`~problems.bar.wfem_operators.SignedRotation.cycles`); a cycle is in the kernel iff
      its signs multiply to +1, and its vector along the cycle is the running product of the
      signs (:meth:`~problems.bar.wfem_operators.SignedRotation.kernel`);
    * ``J[n]`` reads slot ``N-1-n (mod 2N)`` and changes sign once per earlier lap that crossed
      the end in a free step (:func:`~problems.bar.wfem_operators.end_series`).

    ``tests/bar/test_wfem_scan_screen_equals_per_node_solve.py`` checks that no rejected node has a
    solution and that a
    scan with the screen equals the scan without it, node for node.
    """
    n2 = 2 * N
    ms = np.asarray(ms, dtype=np.int64)
    out = np.ones(ms.size, dtype=bool)
    if ms.size == 0:
        return out
    cyc = SignedRotation(N, M % n2, np.ones(n2)).cycles()  # (g, L) slots
    g, length = cyc.shape
    r_cyc = ((N - 1 - cyc) % n2).astype(np.int64)  # the residue at which each slot flips
    where = np.empty(n2, dtype=np.int64)  # slot -> its place in the cycle-ordered layout
    where[cyc.ravel()] = np.arange(n2)
    steps = np.arange(M)
    read = (N - 1 - steps) % n2  # slot read by J[n]
    order = np.argsort(read % g, kind="stable")  # steps grouped by the cycle they read
    groups, starts = np.unique((read % g)[order], return_index=True)
    place = where[read[order]]
    steps_g = steps[order]
    for a in range(0, ms.size, chunk):
        m = ms[a:a + chunk]
        q, rho = np.divmod(m, n2)
        # sign bit of each slot: the free steps n < m with n = r (mod 2N) number q + [r < rho]
        bit = ((q[:, None, None] + (r_cyc[None] < rho[:, None, None])) & 1).astype(np.uint8)
        run = np.bitwise_xor.accumulate(bit, axis=2)  # (B, g, L) inclusive, along the cycles
        kernel = run[:, :, -1] == 0  # (B, g)
        sign = (run ^ bit).reshape(m.size, n2)[:, place]  # (B, M) exclusive: 1 means J < 0
        contact = steps_g[None, :] >= m[:, None]
        for lap in range(1, (M - 1) // n2 + 1):
            back = steps_g - lap * n2  # one more sign change per earlier lap in a free step
            sign ^= ((back[None, :] >= 0) & (back[None, :] < m[:, None])).astype(np.uint8)
        pos = np.maximum.reduceat((contact & (sign == 0)).view(np.uint8), starts, axis=1)
        neg = np.maximum.reduceat((contact & (sign == 1)).view(np.uint8), starts, axis=1)
        out[a:a + chunk] = ~np.any(kernel[:, groups] & (pos > 0) & (neg > 0), axis=1)
    return out


def node_solutions(model: BarModel, counts: tuple[int, ...], *, max_enumerated_h: int = 12
                   ) -> tuple[str, list[LatticeSolution]]:
    """All admissible candidates at a node, including nodes with ``h > q``.

    ``h == q``: the unique candidate of :func:`solve_node`. ``h > q`` (``g0 != 0``): the kernel is
    spanned by cycle vectors of equal modulus; continuum-limit orbits have a characteristic profile
    of constant modulus (an irrational rotation is ergodic), so the candidates are the sign
    combinations ``sum_j eps_j e_j`` (``eps_j = +-1``), normalised by the gap and checked for
    COND1-COND3; enumerated when ``h <= max_enumerated_h``. When gcd(M, 2N) > 1 the cycle of the
    continuum orbit splits into several, and this is where it is found (the paper's claim that
    admissible orbits need h = q does not hold on these nodes: see tests).
    """
    status, sol = solve_node(model, counts)
    if status != "h > q":
        return status, ([sol] if status == "admissible" and sol is not None else [])
    if model.g0 == 0:
        return status, []
    pattern = pattern_from_counts(*counts)
    op = phase_operator(model.N, pattern)
    K = op.kernel()
    h = K.shape[1]
    if h > max_enumerated_h:
        return f"h > q (h = {h}, not enumerated)", []
    Js = np.array([end_series(K[:, j], pattern) for j in range(h)])
    free, contact, phases = _masks(counts)
    if contact_sign_conflict(Js[:, contact]):
        return "h > q: no admissible sign combination", []
    closure = _closure_rows(Js, counts)
    signs = np.array(np.meshgrid(*([[1.0, -1.0]] * (h - 1)), indexing="ij")).reshape(h - 1, -1)
    alphas = np.vstack([np.ones((1, signs.shape[1])), signs])  # (h, 2^(h-1)) combinations
    total = K.sum(axis=0) @ alphas
    ok = np.abs(total) > 1e-12
    if closure.size:
        ok &= np.all(np.abs(closure @ alphas) <= 1e-9 * np.abs(Js).max() * sum(counts), axis=0)
    alphas = alphas[:, ok] * (2 * model.E * model.g0 / model.dx / total[ok])
    Jall = Js.T @ alphas  # (M, combos): vectorised COND1 / COND2 screening
    A = np.abs(Jall).max(axis=0)
    good = np.all(Jall[contact] <= 1e-9 * A, axis=0) if contact.any() else np.ones_like(A, bool)
    for a, b in phases:
        P = np.cumsum(Jall[a:b], axis=0)
        good &= np.all(P[:-1] >= -1e-9 * A * (b - a), axis=0)
    out = []
    for alpha in alphas[:, good].T:
        w0 = K @ alpha
        J = alpha @ Js
        margins, grazing = admissibility_margins(model, w0, J, counts)
        if all(v >= -1e-9 for v in margins.values()):
            out.append(LatticeSolution(model, tuple(counts), w0, J, h,
                                       ring_energy(w0, model.dx, model.E), margins, grazing))
    return ("admissible" if out else "h > q: no admissible sign combination"), out


def grazing_representative(model: BarModel, counts: tuple[int, ...]) -> LatticeSolution | None:
    """A representative orbit of a ``g0 = 0`` node whose kernel is larger than ``q + 1``.

    For ``g0 = 0`` all conditions are homogeneous: the admissible set of a node is a cone and the
    amplitude is free (the vertical backbones of section 6). A representative is chosen by a
    linear programme over the kernel coefficients in the box ``[-1, 1]^h``: maximise the contact
    impulse subject to ``sum w = 0``, the closures, COND1 and COND2. Its optimum sits at a vertex,
    where almost every coefficient is +-1: a profile of (nearly) constant modulus, the structure of
    the continuum-limit orbits. Returns None when the cone is empty.
    """
    from scipy.optimize import linprog

    if model.g0 != 0:
        raise ValueError("grazing_representative is for g0 = 0")
    pattern = pattern_from_counts(*counts)
    K = phase_operator(model.N, pattern).kernel()
    h = K.shape[1]
    if h == 0:
        return None
    K = K / np.abs(K).max(axis=0)  # cycle vectors of modulus 1
    Js = np.array([end_series(K[:, j], pattern) for j in range(h)])
    _, contact, phases = _masks(counts)
    A_ub = []
    for a, b in phases:
        A_ub += list(-np.cumsum(Js[:, a:b], axis=1)[:, :-1].T)
    A_ub += list(Js[:, contact].T)
    rows = [K.sum(axis=0)]
    closure = _closure_rows(Js, counts)
    rows += list(closure) if closure.size else []
    res = linprog(Js[:, contact].sum(axis=1), A_ub=np.array(A_ub), b_ub=np.zeros(len(A_ub)),
                  A_eq=np.array(rows), b_eq=np.zeros(len(rows)), bounds=[(-1, 1)] * h,
                  method="highs")
    if res.status != 0 or -res.fun <= 1e-9:
        return None
    alpha = res.x * 1e-3 * model.E / np.abs(K @ res.x).max()  # |characteristic| <= 1e-3 E
    w0 = K @ alpha
    J = alpha @ Js
    margins, grazing = admissibility_margins(model, w0, J, counts)
    return LatticeSolution(model, tuple(counts), w0, J, h, ring_energy(w0, model.dx, model.E),
                           margins, grazing, amplitude_free=True)
