"""Along an exact modal flow, the watched functions and the state as exponential-trigonometric sums.

Between events the state of a system linear between events is (:mod:`.linear_flow`)

    x(t) = x_p(phi + omega t) + Re(sum_j w_j v_j xi_j e^{lambda_j t}),

so any function of the state that is affine in ``x`` (with a periodic dependence on the clock)
is ``g(t) = q(phi + omega t) + Re(sum_j beta_j e^{lambda_j t})`` with ``q`` a trigonometric sum
in the clock: the watched functions ``H``, ``v``, ``a`` of a constraint affine in the positions
(their gradient ``P = d probe / dx`` is then constant), and each state component (``P = I``).
Such a sum is evaluated at many times by one matrix product, and its derivatives are bounded
by its coefficients, ``|g^(4)| <= sum_k (k omega)^4 |gamma_k| + sum_j |lambda_j|^4 |beta_j|``
(a mode with ``Re lambda > 0`` counted e-fold grown). This module holds the two uses of that:

* :func:`certified_length`: how long a step may be so that no watched function crosses zero
  unseen. The step is cut into cells whose cubic Hermite interpolants (values and slopes at the
  ends, exact) are within ``delta = w^4 / 384 max |g^(4)|`` of ``g``; a cell whose Bernstein
  control points all lie beyond ``delta`` on one side certainly holds no zero. The step runs to
  the first cell that is not certified (at least one cell): a zero is then in the step's last
  cell or beyond, and the simulator's Hermite search over a one-cell step sees it with the
  cell's accuracy. Between events the steps are as long as the watched functions stay clear of
  zero, instead of as short as the interpolants of every state component need.
* :func:`grid_extremes`: the extremes of every state component over a step, on a grid of such
  cells: the values at the edges, and where a component's slope changes sign inside a cell its
  value at the extremum of the cell's interpolant after one Newton step on the true slope (the
  computation :meth:`.simulate.Simulator._extend_extremes` does for one Runge-Kutta step), all
  components and cells at once.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from nsm_continuation.hybrid.linear_flow import ModalFlow

#: cells a step may span (:func:`certified_length`)
MAX_CELLS = 64
#: samples of the watched functions on the particular solution over one period of the clock
Q_SAMPLES = 32


def clock_sum(flow: ModalFlow, Y: np.ndarray, probe: Any) -> tuple[np.ndarray, np.ndarray,
                                                                    np.ndarray] | None:
    """``q(phi) = probe(x_p(phi), phi)`` (the watched functions on the particular solution, at
    the freed parameters of ``Y``) as ``(constant, orders k, coefficients gamma_k)`` (rows:
    harmonics), from ``Q_SAMPLES`` samples; None when they are not such a sum to rounding (a
    clock dependence with higher harmonics: no certificate, short steps). ``probe``: the
    probe at the columns of a matrix of states given column-major (``Q_SAMPLES + 2`` of them
    in one call: the samples and two checks)."""
    fld = flow.field
    phases = np.append(2 * math.pi * np.arange(Q_SAMPLES) / Q_SAMPLES,
                       [0.5772156649015329, 4.669201609102990])
    X = np.repeat(np.asarray(Y, dtype=float)[:, None], phases.size, axis=1)
    if fld.clock is None:
        X[fld.dyn] = flow.x0[:, None]
        rows = probe(X.ravel(order="F"))[:, 0]
        return rows, np.zeros(0, int), np.zeros((0, rows.size), complex)
    X[fld.dyn] = flow.xp(phases).T
    X[fld.clock] = phases
    allv = probe(X.ravel(order="F")).T                           # phases x functions
    vals, checks = allv[:Q_SAMPLES], allv[Q_SAMPLES:]
    hat = np.fft.rfft(vals, axis=0) / Q_SAMPLES
    scale = 1.0 + float(np.max(np.abs(vals)))
    const = hat[0].real
    orders = np.arange(1, hat.shape[0] - 1)
    coef = 2.0 * hat[1:-1]
    model = const + (np.exp(1j * np.outer(phases[Q_SAMPLES:], orders)) @ coef).real
    if float(np.max(np.abs(checks - model))) > 1e-10 * scale:
        return None
    keep = np.max(np.abs(coef), axis=1) > 1e-14 * scale
    return const, orders[keep], coef[keep]


def powers(z: np.ndarray, count: int) -> np.ndarray:
    """Rows ``z^0, z^1, ..., z^(count - 1)`` (elementwise) by repeated doubling: ``e^{lambda
    k h}`` on a grid of equal cells from ``e^{lambda h}`` in ``log2(count)`` products instead of
    ``count`` complex exponentials (relative error about ``log2(count)`` roundings, far below
    the margins the sums are used with)."""
    out = np.empty((count, z.size), dtype=np.result_type(z, 1.0))
    out[0] = 1.0
    if count > 1:
        out[1] = z
    done, zk = 2, z * z
    while done < count:
        k = min(done, count - done)
        np.multiply(out[:k], zk, out=out[done:done + k])
        done += k
        zk = zk * zk
    return out


def _bernstein_clear(g0: np.ndarray, m0: np.ndarray, g1: np.ndarray, m1: np.ndarray,
                     delta: np.ndarray) -> np.ndarray:
    """Whether the cubic Hermite interpolant (values ``g``, slopes ``m`` per cell) is more
    than ``delta`` away from zero on the whole cell, by its Bernstein control points."""
    b1, b2 = g0 + m0 / 3.0, g1 - m1 / 3.0
    lo = np.minimum(np.minimum(g0, g1), np.minimum(b1, b2))
    hi = np.maximum(np.maximum(g0, g1), np.maximum(b1, b2))
    return (lo > delta) | (hi < -delta)


def certified_length(flow: ModalFlow, Y: np.ndarray, rows: list[int], cell: float,
                     q: tuple[np.ndarray, np.ndarray, np.ndarray],
                     section: tuple[int, float] | None = None,
                     fired: tuple[int, ...] = ()) -> tuple[float, int]:
    """The longest step from ``Y`` (whole ``cell`` widths, at least one, at most
    ``MAX_CELLS``) before the first cell where a watched function (probe ``rows``; and the
    section's coordinate minus its value, ``section``, when it is a dynamic component) is not
    certified clear of zero (module docstring), and the index of that cell (``MAX_CELLS`` when
    every cell is clear; 0 when the first is not, and the step is that one cell).
    ``q``: :func:`clock_sum`.

    ``fired``: positions in ``rows`` of functions that fired at ``Y`` (zero there, for the
    simulator): their first cell is clear when ``g`` leaves zero at a rate ``|g'(0)|`` that its
    curvature cannot undo within the cell, ``|g(t)| >= |g'(0)| t - M_2 t^2 / 2 > 0`` for
    ``t <= cell < 2 |g'(0)| / M_2`` (``M_2`` bounds ``|g''|`` like ``M_4`` bounds ``|g^(4)|``),
    instead of the step stopping one cell after every event."""
    omega, phase, xi = flow.modal(Y)
    modes = flow.probe_modes[rows]                               # functions x modes
    const, orders, gamma = q[0][rows], q[1], q[2][:, rows]
    if section is not None:
        row, part = flow.state_sum(section[0])
        modes = np.vstack([modes, row])
        const = np.append(const, part[0] - section[1])
        if orders.size or part[1].size:
            orders, gamma = _merge(orders, gamma, part[1], part[2])
    beta = modes * xi
    nf = beta.shape[0]
    t = cell * np.arange(MAX_CELLS + 1)
    E = powers(np.exp(cell * flow.lam_s), MAX_CELLS + 1)
    both = (E @ np.vstack([beta, beta * flow.lam_s]).T).real    # values, then slopes
    g, dg = both[:, :nf] + const, both[:, nf:]
    absb = np.abs(beta)
    bound4 = absb @ flow.lam4_grown
    bound2 = absb @ flow.lam2_grown if fired else np.zeros(nf)
    if orders.size:
        kw = orders * omega
        e = np.exp(1j * np.outer(phase + omega * t, orders))
        g += (e @ gamma).real
        dg += ((e * (1j * kw)) @ gamma).real
        bound4 += np.abs(kw) ** 4 @ np.abs(gamma)
        if fired:
            bound2 += np.abs(kw) ** 2 @ np.abs(gamma)
    # the interpolants' error, and the rounding of sums of terms of size |beta|, |gamma|
    size = absb.sum(axis=1) + np.abs(const) + (np.abs(gamma).sum(axis=0) if orders.size else 0.0)
    delta = cell ** 4 / 384.0 * bound4 * (1.0 + 1e-12) + 1e-13 * size
    clear = _bernstein_clear(g[:-1], dg[:-1] * cell, g[1:], dg[1:] * cell, delta)
    for r in fired:
        slope, end = dg[0, r], g[1, r]
        clear[0, r] = (bound2[r] * cell * (1.0 + 1e-12) < 2.0 * abs(slope) * (1.0 - 1e-12)
                       and slope * end > 0.0)
    clear = clear.all(axis=1)
    first = int(np.argmin(clear)) if not clear.all() else MAX_CELLS
    return cell * max(first, 1), first


def _merge(o1: np.ndarray, g1: np.ndarray, o2: np.ndarray, g2: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Harmonic coefficients of functions (columns ``g1`` on orders ``o1``) with one more
    function (column ``g2`` on orders ``o2``), on the union of the orders."""
    orders = np.union1d(o1, o2).astype(int)
    out = np.zeros((orders.size, g1.shape[1] + 1), complex)
    out[np.searchsorted(orders, o1), :-1] = g1
    out[np.searchsorted(orders, o2), -1] = g2
    return orders, out


def grid_extremes(flow: ModalFlow, Y0: np.ndarray, dt: float, cell: float, n: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The extremes of the state components ``0 .. n - 1`` over the step of length ``dt``
    from ``Y0`` (module docstring), on cells of width at most ``cell``."""
    fld = flow.field
    G = max(1, math.ceil(dt / cell)) if cell > 0 else 1
    w = dt / G
    t = w * np.arange(G + 1)
    vals, rates = flow.grid(Y0, t)                               # (G + 1) x dynamic
    lo = np.full(n, np.inf)
    hi = np.full(n, -np.inf)
    dyn = fld.dyn
    lo[dyn], hi[dyn] = vals.min(axis=0), vals.max(axis=0)
    if fld.clock is not None and fld.clock < n:
        omega, phase, _xi = flow.modal(Y0)
        ends = (phase, phase + omega * dt)
        lo[fld.clock], hi[fld.clock] = min(ends), max(ends)
    a, b = vals[:-1], vals[1:]
    m0, m1 = rates[:-1] * w, rates[1:] * w
    cells, comps = np.nonzero(m0 * m1 < 0)
    if not cells.size:
        return lo, hi
    a, b, m0, m1 = a[cells, comps], b[cells, comps], m0[cells, comps], m1[cells, comps]
    # p(s) = a + m0 s + c2 s^2 + c3 s^3; p'(s) = m0 + 2 c2 s + 3 c3 s^2 has one zero in (0, 1)
    c2 = -3 * a - 2 * m0 + 3 * b - m1
    c3 = 2 * a + m0 - 2 * b + m1
    s = _slope_zero(m0, c2, c3)
    # only the turns that may hold a component's extreme are evaluated on the true flow: the
    # interpolant is within delta = w^4 / 384 max |x^(4)| of the component on every cell, so
    # a turn (a maximum where the slope falls, a minimum where it rises) whose interpolated
    # value is more than 2 delta short of the best turn or grid value of its component
    # cannot hold the extreme
    delta = w ** 4 / 384.0 * flow.fourth_bounds(Y0)[comps] * (1.0 + 1e-12)
    up = m0 > 0
    score = np.where(up, 1.0, -1.0) * (a + s * (m0 + s * (c2 + s * c3)))
    best = np.column_stack([-vals.min(axis=0), vals.max(axis=0)])    # components x (min, max)
    np.maximum.at(best, (comps, up.astype(int)), score)
    keep = score >= best[comps, up.astype(int)] - 2.0 * delta - 1e-15 * np.abs(score)
    cells, comps, a, b, m0, m1, c2, c3, s = (v[keep] for v in (cells, comps, a, b, m0, m1, c2,
                                                               c3, s))
    curv = 2 * c2 + 6 * c3 * s
    times = t[cells] + s * w
    v, r = flow.components(Y0, times, dyn[comps])
    bent = curv != 0.0
    s1 = np.where(bent, s - r * w / np.where(bent, curv, 1.0), s)
    move = bent & (s1 > 0.0) & (s1 < 1.0)
    if move.any():
        v[move] = flow.components(Y0, t[cells[move]] + s1[move] * w, dyn[comps[move]])[0]
    np.minimum.at(lo, dyn[comps], v)
    np.maximum.at(hi, dyn[comps], v)
    return lo, hi


def _slope_zero(m0: np.ndarray, c2: np.ndarray, c3: np.ndarray) -> np.ndarray:
    """The zero in ``(0, 1)`` of ``m0 + 2 c2 s + 3 c3 s^2`` whose ends differ in sign
    (``m0 (m0 + 2 c2 + 3 c3) < 0``): of the two roots, the one inside (cancellation-free
    formulas); ``-m0 / (2 c2)`` for ``c3 = 0``."""
    A, B, C = 3 * c3, 2 * c2, m0
    disc = np.sqrt(np.maximum(B * B - 4 * A * C, 0.0))
    qq = -0.5 * (B + np.copysign(disc, B))
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(A != 0.0, qq / np.where(A != 0.0, A, 1.0), np.inf)
        r2 = np.where(qq != 0.0, C / np.where(qq != 0.0, qq, 1.0), np.inf)
        lin = np.where(B != 0.0, -C / np.where(B != 0.0, B, 1.0), 0.5)
    inside1 = (r1 > 0.0) & (r1 < 1.0)
    inside2 = (r2 > 0.0) & (r2 < 1.0)
    s = np.where(inside1, r1, np.where(inside2, r2, 0.5))
    return np.clip(np.where(A == 0.0, lin, s), 0.0, 1.0)
