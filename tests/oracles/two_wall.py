r"""Closed forms of two forced two-wall impacting systems, their symmetric two-impact orbits,
the orbits' Floquet multipliers and bifurcations, and an independent event-driven simulator
(numpy/scipy only: nothing of the package is imported).

The systems
-----------
Both are linear between impacts, with a state ``X`` and a relative position ``z = n^T X``
confined to ``|z| <= w`` (two walls, ``z = +w`` "upper" and ``z = -w`` "lower"):

    X' = A X + b cos(omega t),          n^T b = 0,                                       (T1)
    X+ = R X-   at  z = +w  or  z = -w  (the same linear impact law at both walls).      (T2)

(a) **Two-sided impact oscillator** ``q'' + 2 zeta q' + q = cos(omega t)``, ``-d <= q <= d``,
    ``q'+ = -e q'-``: ``X = (q, q')``, ``A = [[0, 1], [-1, -2 zeta]]``, ``b = (0, 1)``,
    ``n = (1, 0)``, ``w = d``, ``R = diag(1, -e)``.
(b) **Impact damper** (Masri & Caughey 1966): primary mass 1 at ``x`` on a spring 1 with damping
    ``2 zeta``, forced by ``cos(omega t)``; a free ball of mass ``mu`` at ``y`` in a cavity of
    clearance ``d`` of the primary: ``X = (x, y, x', y')``, ``A = [[0, 0, 1, 0], [0, 0, 0, 1],
    [-1, 0, -2 zeta, 0], [0, 0, 0, 0]]``, ``b = (0, 0, 1, 0)``, ``z = y - x``, ``n = (-1, 1, 0,
    0)``, ``w = d / 2``. Momentum ``x' + mu y'`` is conserved and ``z'+ = -e z'-``, so with
    ``k = (1 + e) / (1 + mu)``

        x'+ = x'- + mu k (y'- - x'-),     y'+ = y'- - k (y'- - x'-),                      (T3)

    a linear ``R = I + k [[0]*4, [0]*4, [0, 0, -mu, mu], [0, 0, 1, -1]]``.

Both are equivariant under ``X -> -X``, ``t -> t + T/2`` (``T = 2 pi / omega``; the forcing
changes sign, the walls swap, ``R`` commutes with ``-I``).

The symmetric two-impact orbit
------------------------------
The forced response ``X_p(t) = Re(c e^{i omega t})``, ``c = (i omega I - A)^{-1} b`` (T4),
satisfies ``X_p(t + T/2) = -X_p(t)``; the homogeneous flow over half a period is
``E = exp(A h)``, ``h = pi / omega``. An orbit with an impact on the upper wall at ``t0 = phi /
omega`` (pre-impact state ``X-``, ``n^T X- = w``) whose flight lasts ``h`` and ends in the
reflected state ``-X-`` (on the lower wall, ``x(t + T/2) = -x(t)``) satisfies
``-X- = X_p(t0 + h) + E (R X- - X_p(t0))``, i.e.

    (E R + I) X- = (E + I) X_p(t0),     X- = G X_p(t0),   G = (E R + I)^{-1} (E + I).     (T5)

``X-`` is linear in ``X_p(t0) = Re(c e^{i phi})``, so the wall condition is one trigonometric
equation in the impact phase: with the complex number ``g = n^T G c``,

    n^T X- = Re(g e^{i phi}) = |g| cos(phi + arg g) = w,
    phi_(+/-) = -arg g +/- arccos(w / |g|),                                              (T6)

two orbits (branches ``+`` and ``-``) for ``|g(omega)| > w``, none for ``|g| < w``. The impact
velocity (towards the wall) is

    v = n^T A X- = Re(n^T A G c e^{i phi}),                                               (T7)

and the orbit is physical where ``v > 0`` and ``|z(t)| < w`` inside each flight. Its boundaries:

* **fold**: ``|g(omega)| = w`` (T8): the two branches meet (``phi_+ = phi_-``), omega turns;
* **impact velocity vanishes** (``v -> 0``): then ``R X- = X-`` and (T5) gives ``X- = X_p(t0)``:
  the forced response touches both walls, ``|n^T c| = w``. For both systems ``n^T c = -+1 /
  (1 - omega^2 + 2 i zeta omega)`` (the damper's ball does not move in the forced response), so

      (1 - omega^2)^2 + (2 zeta omega)^2 = 1 / w^2,
      omega^2 = 1 - 2 zeta^2 +/- sqrt((1 - 2 zeta^2)^2 - 1 + 1 / w^2),                   (T9)

  independent of ``e`` and ``mu``. Undamped: ``omega = sqrt(1 + 1/w)`` (and ``sqrt(1 - 1/w)``
  for ``w > 1``): ``sqrt(3)`` for the oscillator at ``d = 1/2`` and for the damper at any
  ``mu``, ``e`` with clearance ``d = 1`` (``w = 1/2``);
* **grazing**: an interior extremum of ``z(t)`` on a flight reaches a wall (T10); by the
  symmetry one flight covers both walls. Located on the margin ``w - |z(t*)|`` of the extremum
  ``t*`` nearest the walls (``z'(t*) = 0``), which is smooth through the grazing.

Multipliers
-----------
At the upper impact the saltation matrix of (T2) (surface ``n^T X = w``, time-dependent field
``F(X, t) = A X + b cos(omega t)``) is

    S = R + (F+ - R F-) n^T / (n^T F-),   F- = F(X-, t0),  F+ = F(R X-, t0),             (T11)

and at the lower impact, in the reflected state, the same ``S``. The Jacobian of the flight is
``E``; the map from just before an upper impact to just before the next upper impact is
``E S E S``. With the reflection ``-I`` the symmetric half map (flight, reflect) has the
Jacobian ``M_h = -E S``, and the monodromy is

    M = M_h^2,     multipliers mu_k = lambda_k^2,  lambda_k the eigenvalues of M_h.           (T12)

(at another section, e.g. stroboscopic, ``M`` is conjugate: same multipliers). ``det S = e^2``
(relative velocity ``-e`` times the block ``R``), ``det E = exp(-2 zeta h)``. Bifurcations of the
symmetric family along omega (T13):

* ``lambda = +1``: **fold** (omega turns; it is (T8));
* ``lambda = -1``: ``mu = +1`` without a turn of omega: **symmetry-breaking pitchfork**
  (``branch_point``): asymmetric two-impact orbits branch off; located on ``det(I + M_h) = 0``;
* a complex pair ``|lambda| = 1``: ``mu = lambda^2`` a complex pair on the circle:
  **Neimark-Sacker**; located on ``det(C2(M_h) - I) = 0`` (``C2`` the second compound matrix,
  eigenvalues ``lambda_i lambda_j``), checked to be a complex pair;
* **period doubling** (``mu = -1``) needs ``lambda = +/- i``: a Neimark-Sacker of ``M_h`` at the
  angle ``pi / 2``, of codimension two on a family of symmetric orbits (``det(I + M) =
  |det(M_h - i I)|^2 >= 0`` does not change sign): generically absent; a Neimark-Sacker whose
  full-map angle is within 1e-6 of ``pi`` is reported as ``period_doubling``.

For the oscillator ``M_h`` is 2x2 with ``det M_h = e^2 exp(-2 zeta h) < 1``: a complex pair has
``|lambda|^2 = det < 1``, so its symmetric orbit has **no Neimark-Sacker and no period
doubling**: only folds and pitchforks (and its boundaries). The damper's ``M_h`` is 4x4 with
``det M_h = e^2 exp(-2 zeta h)``: Neimark-Sacker is possible.

Independent simulator
---------------------
:func:`simulate`: the exact flight ``X(t) = X_p(t) + exp(A (t - t0)) (X0 - X_p(t0))`` (T14), the
walls found by sampling the two gaps ``w -+ z(t)`` 400 times per half period and
:func:`scipy.optimize.brentq` on the first sign change, then (T2).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

#: samples per half period of a flight (walls and extrema are bracketed on this grid)
SAMPLES = 400


def expm(M: np.ndarray) -> np.ndarray:
    """``exp(M)`` of a small matrix (or a stack of them) by scaling and squaring of the Taylor
    series (order 18 at norm <= 1/4: truncation below 1e-28). Used instead of
    :func:`scipy.linalg.expm`, equal to it to rounding (tested) and a hundred times faster on
    4x4 matrices where OpenBLAS runs threads."""
    M = np.asarray(M, dtype=float)
    norm = float(np.abs(M).sum(axis=-2).max()) if M.size else 0.0
    s = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    X = M / 2.0 ** s
    term = np.broadcast_to(np.eye(M.shape[-1]), M.shape).copy()
    E = term.copy()
    for k in range(1, 19):
        term = term @ X / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


@dataclass(frozen=True)
class TwoWall:
    """A linear two-wall system (T1)-(T2): ``X' = A X + b cos(omega t)``, walls ``n^T X = +-w``,
    impact law ``X+ = R X-``."""

    name: str
    A: np.ndarray
    b: np.ndarray
    n: np.ndarray
    w: float
    R: np.ndarray
    zeta: float
    e: float
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def dim(self) -> int:
        return int(self.A.shape[0])


def oscillator(zeta: float, d: float, e: float) -> TwoWall:
    """(a): ``q'' + 2 zeta q' + q = cos(omega t)``, ``|q| <= d``, ``q'+ = -e q'-``."""
    A = np.array([[0.0, 1.0], [-1.0, -2.0 * zeta]])
    return TwoWall("two_sided_oscillator", A, np.array([0.0, 1.0]), np.array([1.0, 0.0]),
                   float(d), np.diag([1.0, -e]), float(zeta), float(e))


def damper(zeta: float, mu: float, d: float, e: float) -> TwoWall:
    """(b): the impact damper, ``X = (x, y, x', y')``, ``|y - x| <= d/2``, law (T3)."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 0], A[2, 2] = -1.0, -2.0 * zeta
    k = (1.0 + e) / (1.0 + mu)
    R = np.eye(4)
    R[2, 2:] += k * np.array([-mu, mu])
    R[3, 2:] += k * np.array([1.0, -1.0])
    return TwoWall("impact_damper", A, np.array([0.0, 0.0, 1.0, 0.0]),
                   np.array([-1.0, 1.0, 0.0, 0.0]), 0.5 * float(d), R, float(zeta), float(e),
                   {"mu": float(mu)})


# ------------------------------------------------------------------------------ closed forms
def forced_response(sys: TwoWall, omega: float) -> np.ndarray:
    """``c`` of (T4): ``X_p(t) = Re(c e^{i omega t})``."""
    return np.linalg.solve(1j * omega * np.eye(sys.dim) - sys.A, sys.b.astype(complex))


def _xp(c: np.ndarray, phase: float) -> np.ndarray:
    return np.real(c * np.exp(1j * phase))


def _gain(sys: TwoWall, omega: float) -> tuple[np.ndarray, np.ndarray, complex]:
    """``(E, G c, g)`` of (T5)-(T6)."""
    E = expm(sys.A * (np.pi / omega))
    c = forced_response(sys, omega)
    I = np.eye(sys.dim)
    Gc = np.linalg.solve(E @ sys.R + I, (E + I) @ c)
    return E, Gc, complex(sys.n @ Gc)


def fold_function(sys: TwoWall, omega: float) -> float:
    """``|g(omega)| - w``: the symmetric orbits exist where it is >= 0, folds at its zeros (T8)."""
    return abs(_gain(sys, omega)[2]) - sys.w


def velocity_vanishing_frequencies(zeta: float, w: float) -> list[float]:
    """The frequencies of (T9), where the forced response's relative amplitude is ``w``."""
    a = 1.0 - 2.0 * zeta ** 2
    disc = a * a - 1.0 + 1.0 / w ** 2
    if disc < 0:
        return []
    out = [a + s * np.sqrt(disc) for s in (1.0, -1.0)]
    return sorted(float(np.sqrt(x)) for x in out if x > 0)


class Orbit(NamedTuple):
    """A symmetric two-impact orbit: branch ``+1``/``-1`` of (T6), the upper impact's phase
    ``phi`` (in ``[0, 2 pi)``), pre-impact state, impact velocity (T7), the half-map Jacobian
    ``M_h`` (T12), the half map's eigenvalues and the multipliers ``lambda^2``."""

    omega: float
    branch: int
    phase: float
    x_minus: np.ndarray
    velocity: float
    half_map: np.ndarray
    half_eigenvalues: np.ndarray
    multipliers: np.ndarray
    system: TwoWall


def orbit(sys: TwoWall, omega: float, branch: int) -> Orbit | None:
    """The orbit of (T5)-(T7), (T11)-(T12) on ``branch`` (``+1`` or ``-1``), None where
    ``|g| < w`` (no symmetric orbit). Physical or not: see :func:`admissible`."""
    E, Gc, g = _gain(sys, omega)
    if abs(g) < sys.w:
        return None
    phi = float(np.mod(-np.angle(g) + branch * np.arccos(sys.w / abs(g)), 2 * np.pi))
    xm = _xp(Gc, phi)
    v = float(sys.n @ sys.A @ xm)
    Fm = sys.A @ xm + sys.b * np.cos(phi)
    xp = sys.R @ xm
    Fp = sys.A @ xp + sys.b * np.cos(phi)
    with np.errstate(divide="ignore", invalid="ignore"):   # v = 0: no saltation matrix
        S = sys.R + np.outer(Fp - sys.R @ Fm, sys.n) / (sys.n @ Fm)      # (T11)
    Mh = -E @ S                                                           # (T12)
    lam = np.linalg.eigvals(Mh) if np.isfinite(Mh).all() else np.full(sys.dim, np.nan)
    return Orbit(float(omega), branch, phi, xm, v, Mh, lam, lam ** 2, sys)


def orbits(sys: TwoWall, omega: float) -> list[Orbit]:
    """Both branches of (T6) at ``omega`` (none where ``|g| < w``)."""
    found = [orbit(sys, omega, s) for s in (1, -1)]
    return [o for o in found if o is not None]


def flow(sys: TwoWall, omega: float, t0: float, x0: np.ndarray, tau: np.ndarray | float
         ) -> np.ndarray:
    """The exact flight (T14) from ``(t0, x0)`` at the times ``t0 + tau`` (rows)."""
    c = forced_response(sys, omega)
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    y0 = x0 - _xp(c, omega * t0)
    hom = np.array([expm(sys.A * s) @ y0 for s in tau])
    return np.real(c[None, :] * np.exp(1j * omega * (t0 + tau))[:, None]) + hom


def flow_grid(sys: TwoWall, omega: float, t0: float, x0: np.ndarray, span: float, steps: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """``(tau, X)``: (T14) on ``steps + 1`` equally spaced times of ``[0, span]`` (the
    homogeneous part by powers of one step's ``exp(A dt)``)."""
    c = forced_response(sys, omega)
    tau = np.linspace(0.0, span, steps + 1)
    step = expm(sys.A * (span / steps))
    y = x0 - _xp(c, omega * t0)
    hom = np.empty((steps + 1, sys.dim))
    for k in range(steps + 1):
        hom[k] = y
        y = step @ y
    return tau, np.real(c[None, :] * np.exp(1j * omega * (t0 + tau))[:, None]) + hom


def state_at(o: Orbit, phase: float) -> np.ndarray:
    """The orbit's state where ``omega t = phase`` (mod ``2 pi``): the stroboscopic section."""
    sys, omega = o.system, o.omega
    since = float(np.mod(phase - o.phase, 2 * np.pi))
    sign = 1.0
    if since >= np.pi:                      # in the flight after the lower impact: reflect
        since -= np.pi
        sign = -1.0
    return sign * flow(sys, omega, o.phase / omega, sys.R @ o.x_minus, since / omega)[0]


def flight_extrema(o: Orbit) -> tuple[list[tuple[float, float]], float]:
    """``(tau, z)`` of the interior extrema of ``z = n^T X`` on the flight from the upper impact
    (``z'(tau) = 0``, roots by :func:`brentq` on the sampled sign changes), and the largest
    ``|z|`` of the interior samples."""
    sys, omega = o.system, o.omega
    t0, x0 = o.phase / omega, sys.R @ o.x_minus
    tau, X = flow_grid(sys, omega, t0, x0, np.pi / omega, SAMPLES)
    tau, X = tau[1:-1], X[1:-1]
    dn = sys.A.T @ sys.n
    zd = X @ dn

    def dz(s: float) -> float:
        return float(flow(sys, omega, t0, x0, s)[0] @ dn)

    out = []
    for k in np.nonzero(np.sign(zd[:-1]) * np.sign(zd[1:]) < 0)[0]:
        s = brentq(dz, tau[k], tau[k + 1], xtol=1e-10)   # z(s) to rounding: z quadratic at s
        out.append((s, float(sys.n @ flow(sys, omega, t0, x0, s)[0])))
    return out, float(np.abs(X @ sys.n).max())


def grazing_margin(o: Orbit) -> float:
    """``w - max |z|`` over the interior extrema (and samples) of a flight (T10). Negative: the
    orbit crosses a wall between its impacts (not physical); zero at an interior grazing."""
    ext, sampled = flight_extrema(o)
    return o.system.w - max([sampled, *(abs(z) for _, z in ext)])


def admissible(o: Orbit, tol: float = 0.0) -> bool:
    """``v > -tol`` and no wall crossed between the impacts (margin ``> -tol``)."""
    return o.velocity > -tol and grazing_margin(o) > -tol


# --------------------------------------------------------------------------------- simulator
class Impact(NamedTuple):
    t: float
    wall: int            # +1 upper, -1 lower
    velocity: float      # |z'| before the impact


def simulate(sys: TwoWall, omega: float, x0: np.ndarray, t0: float, t1: float,
             max_impacts: int = 1000) -> tuple[np.ndarray, list[Impact]]:
    """Event-driven simulation from ``(t0, x0)`` to ``t1`` with the exact flight (T14): the
    state at ``t1`` and the impacts. ``x0`` must be admissible (``|z| <= w``)."""
    t, x = float(t0), np.asarray(x0, dtype=float).copy()
    impacts: list[Impact] = []
    dt = (np.pi / omega) / SAMPLES
    zrow = sys.n
    while t < t1 and len(impacts) <= max_impacts:
        span = min(t1 - t, 2 * np.pi / omega)
        tau, X = flow_grid(sys, omega, t, x, span, int(np.ceil(span / dt)))
        z = X @ zrow
        gaps = np.minimum(sys.w - z, sys.w + z)
        bad = np.nonzero(gaps[1:] < 0)[0]
        if bad.size == 0:
            t, x = t + span, X[-1]
            continue
        k = int(bad[0])
        wall = 1 if z[k + 1] > 0 else -1

        def gap(s: float, wall: int = wall, t: float = t, x: np.ndarray = x) -> float:
            return sys.w - wall * float(zrow @ flow(sys, omega, t, x, s)[0])

        lo = tau[k]
        if gap(lo) <= 0.0:                  # leaves a wall into it: no flight (chatter, v = 0)
            raise RuntimeError(f"no flight from t = {t}: z = {z[0]}, z' = {zrow @ sys.A @ x}")
        s = brentq(gap, lo, tau[k + 1], xtol=1e-15, rtol=1e-15)
        xm = flow(sys, omega, t, x, s)[0]
        impacts.append(Impact(t + s, wall, abs(float(zrow @ sys.A @ xm))))
        t, x = t + s, sys.R @ xm
    return x, impacts


def period_map(sys: TwoWall, omega: float, phase: float, x: np.ndarray
               ) -> tuple[np.ndarray, list[Impact]]:
    """The stroboscopic map of one forcing period from ``omega t = phase``."""
    t0 = phase / omega
    return simulate(sys, omega, x, t0, t0 + 2 * np.pi / omega)


def fd_monodromy(sys: TwoWall, omega: float, phase: float, x: np.ndarray, h: float = 1e-6
                 ) -> np.ndarray:
    """The Jacobian of :func:`period_map` by central differences (a cross-check only)."""
    cols = []
    for j in range(x.size):
        dx = np.zeros_like(x)
        dx[j] = h
        cols.append((period_map(sys, omega, phase, x + dx)[0]
                     - period_map(sys, omega, phase, x - dx)[0]) / (2 * h))
    return np.column_stack(cols)


# ------------------------------------------------------------------------------------ events
def compound2(M: np.ndarray) -> np.ndarray:
    """The second compound matrix ``C2(M)`` (eigenvalues ``lambda_i lambda_j``, ``i < j``)."""
    n = M.shape[0]
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    C = np.empty((len(pairs), len(pairs)))
    for a, (i, j) in enumerate(pairs):
        for b_, (k, l) in enumerate(pairs):
            C[a, b_] = M[i, k] * M[j, l] - M[i, l] * M[j, k]
    return C


def pitchfork_function(o: Orbit) -> float:
    """``det(I + M_h)``: zero where ``lambda = -1`` (T13)."""
    return float(np.linalg.det(np.eye(o.half_map.shape[0]) + o.half_map))


def ns_function(o: Orbit) -> float:
    """``det(C2(M_h) - I)``: zero where ``lambda_i lambda_j = 1`` (T13)."""
    C = compound2(o.half_map)
    return float(np.linalg.det(C - np.eye(C.shape[0])))


class Event(NamedTuple):
    kind: str
    omega: float
    branch: int          # +1 / -1 of (T6); 0 for a fold (both)
    multipliers: np.ndarray


def _roots(f, grid: np.ndarray, vals: np.ndarray, tol: float) -> list[float]:
    """Zeros of ``f`` bracketed by sign changes of its values ``vals`` on ``grid``; a sign
    change through a pole (``|f|`` at the limit larger than at the bracket's ends, e.g. the
    saltation matrix's ``1 / v`` where the impact velocity vanishes) is no zero."""
    out = []
    for k in range(grid.size - 1):
        a, b = vals[k], vals[k + 1]
        if np.isfinite(a) and np.isfinite(b) and a * b < 0:
            x = float(brentq(f, grid[k], grid[k + 1], xtol=tol, rtol=1e-15))
            if abs(f(x)) <= 1e-6 * max(abs(a), abs(b)):
                out.append(x)
        elif a == 0.0:
            out.append(float(grid[k]))
    return out


def _classify_unit_pair(o: Orbit) -> str | None:
    """The kind of a zero of :func:`ns_function`: a complex pair of ``M_h`` on the circle is a
    Neimark-Sacker (or period doubling at the full-map angle pi); a real reciprocal pair is no
    bifurcation."""
    lam = o.half_eigenvalues
    cplx = lam[np.abs(lam.imag) > 1e-9]
    if cplx.size == 0:
        return None
    top = cplx[np.argmin(np.abs(np.abs(cplx) - 1.0))]
    if abs(abs(top) - 1.0) > 1e-6:
        return None
    return "period_doubling" if abs(abs(np.angle(top ** 2)) - np.pi) < 1e-6 else "neimark_sacker"


def _minus_one(o: Orbit) -> str | None:
    """A zero of :func:`pitchfork_function` is a pitchfork where ``M_h`` has the eigenvalue -1
    (not a pole of ``M_h``: the saltation matrix's ``1 / v`` changes sign where ``v`` does)."""
    return "branch_point" if np.abs(o.half_eigenvalues + 1.0).min() < 1e-6 else None


#: the test functions along a branch (T7), (T10), (T13): kind -> (function, the kind at a zero)
BRANCH_TESTS = {
    "impact_velocity_vanishes": (lambda o: o.velocity, lambda o: "impact_velocity_vanishes"),
    "grazing": (grazing_margin, lambda o: "grazing"),
    "branch_point": (pitchfork_function, _minus_one),
    "neimark_sacker": (ns_function, _classify_unit_pair),
}


def _branch_events(sys: TwoWall, branch: int, grid: np.ndarray, tol: float) -> list[Event]:
    """The zeros of :data:`BRANCH_TESTS` on the physical part of one branch."""
    found = [orbit(sys, om, branch) for om in grid]
    out = []
    for name, (fn, kind_at) in BRANCH_TESTS.items():
        vals = np.array([np.nan if o is None else fn(o) for o in found])

        def f(om: float, fn=fn) -> float:
            o = orbit(sys, om, branch)
            return float("nan") if o is None else float(fn(o))

        for om in _roots(f, grid, vals, tol):
            o = orbit(sys, om, branch)
            if o is None:
                continue
            margin_ok = name == "grazing" or grazing_margin(o) > -1e-9
            velocity_ok = name == "impact_velocity_vanishes" or o.velocity > -1e-9
            kind = kind_at(o)
            if margin_ok and velocity_ok and kind is not None:
                out.append(Event(kind, om, branch, o.multipliers))
    return out


def family_events(sys: TwoWall, omega_min: float, omega_max: float, points: int = 800,
                  tol: float = 1e-13) -> list[Event]:
    """Every event of the symmetric family for ``omega`` in ``[omega_min, omega_max]`` (T8)-(T13),
    on the physical part of each branch only, sorted by omega: ``fold``, ``branch_point``
    (pitchfork), ``neimark_sacker``, ``period_doubling``, ``grazing`` (an interior contact
    between impacts), ``impact_velocity_vanishes``. Located by :func:`brentq` to ``tol`` from
    the sign changes on a grid of ``points`` frequencies."""
    grid = np.linspace(omega_min, omega_max, points)
    fold_vals = np.array([fold_function(sys, om) for om in grid])
    folds = _roots(lambda om: fold_function(sys, om), grid, fold_vals, tol)
    out: list[Event] = []
    for om in folds:
        o = next((o for o in (orbit(sys, om + d, 1) for d in (0.0, 1e-12, -1e-12))
                  if o is not None), None)
        if o is not None and admissible(o, 1e-9):
            out.append(Event("fold", om, 0, o.multipliers))
    for branch in (1, -1):
        out += [ev for ev in _branch_events(sys, branch, grid, tol)
                if all(abs(ev.omega - f) > 1e-9 for f in folds)]
    return sorted(out, key=lambda ev: ev.omega)


def expected_events(sys: TwoWall, omega_min: float, omega_max: float, **kw
                    ) -> list[tuple[str, float]]:
    """``(kind, omega)`` of :func:`family_events`."""
    return [(ev.kind, ev.omega) for ev in family_events(sys, omega_min, omega_max, **kw)]
