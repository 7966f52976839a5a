"""Exact extrema of a finite sum of sinusoids ``f(t) = sum_l a_l cos(w_l t) + b_l sin(w_l t)``.

Used to decide admissibility (Legrand et al. 2017, Definition 2.2) without trusting a sampling:
the maximum of ``f`` on ``[t0, t1]`` is attained at an end or at a root of ``f'``. Roots of ``f'``
are isolated by a certified subdivision: on a cell ``[a, b]`` the bound
``|f''| <= L = sum_l w_l^2 sqrt(a_l^2 + b_l^2)`` gives ``|f'(t)| >= max(|f'(a)| - L (t - a),
|f'(b)| - L (b - t))``, so a cell whose end values share a sign and satisfy
``|f'(a)| + |f'(b)| > L (b - a)`` contains no root. Cells with a sign change are solved by
safeguarded Newton/bisection to machine precision; cells that are neither certified nor bracketed
are split (vectorised) until they are shorter than ``min_width``, where the remaining candidate
(a tangential root of ``f'``) is taken at the point of smallest ``|f'|``. A cell is also
certified root-free when ``f'`` is monotone on it (``f''`` of one sign, certified with
``|f'''| <= L3 = sum_l w_l^3 sqrt(a_l^2 + b_l^2)``) with the same sign at both ends, which settles
the cells next to a simple root in one pass. The result is exact up to round-off and
``L * min_width^2``.

Cost: the first pass evaluates ``f'`` and ``f''`` at the ``n + 1 ~ 2 w_max (t1 - t0)`` edges of
a uniform grid by one matrix product (:meth:`TrigSum.d12_grid`: ``O(N n)`` flops at BLAS 3
speed, ``O((N + n) sqrt n)`` exponentials), which settles almost every cell; only the few
uncertified cells are split and evaluated pointwise. Measured on the ``m = 1/N, k = N`` chain next
to its linear grazing orbit (``N`` modes, ``n = 3208`` / ``16008`` cells): 1.9 ms at
``N = 200`` and 26 ms at ``N = 1000`` (pointwise sines and cosines: 0.18 s and 4.2 s).

Small sums (the 5-dof chain calls this ~7000 times per frequency-energy plot, on
16-100 cells and ~5 brackets, where numpy's per-call overhead, not arithmetic, is the cost):
up to ``POINTWISE_GRID`` edge-mode pairs the first pass takes the sines and cosines at the
edges directly (:meth:`TrigSum.d12`, one evaluation that includes ``t1``), and up to
``SCALAR_MODES`` modes everything after the first pass (the safeguarded Newton iteration of
each bracket, the subdivision of the few uncertified cells) runs on Python floats
(:meth:`TrigSum._scalar_d12`: ``f'`` and ``f''`` by the same formulas, summed in a fixed order;
the ``f''`` of a split cell's edges is computed with its ``f'`` and shared by the two cells that
meet there). The cells, certificates, brackets, tolerances and convergence tests are those of
the vectorised path, which large sums keep: the two agree to the rounding of ``f'`` and ``f''``
(``tests/chain/test_trig_sum_small_path_equals_vectorised_path.py``). On the 5-dof chain's Fig. 3.2
calls: ~3x faster.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_EPS = float(np.finfo(float).eps)
#: :meth:`TrigSum.critical_points`: the first pass evaluates ``f'`` and ``f''`` pointwise (sines
#: and cosines at every edge, :meth:`TrigSum.d12`) up to this many edge-mode pairs, above by the
#: matrix product of :meth:`TrigSum.d12_grid` (measured crossover: ~500-600 pairs)
POINTWISE_GRID = 512
#: :meth:`TrigSum.critical_points`: up to this many modes the work after the first pass (Newton
#: on the brackets, subdivision of the uncertified cells) runs on Python floats ...
SCALAR_MODES = 16
#: ... when there is little of it: ``brackets (N + 4) + uncertified cells (N + 2)`` at most
#: this (measured on Python floats: ~``N + 4`` us per bracket, ~``N + 2`` per uncertified cell;
#: the vectorised loop: ~200 us for a few iterations over all of them at once; crossover ~28
#: brackets at ``N = 5``, ~14 at ``N = 16``)
SCALAR_WORK = 300


def _sign(x: float) -> float:
    """``numpy.sign`` of a Python float (``nan`` for ``nan``, so that it equals nothing)."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else x * 0.0)


@dataclass
class TrigSum:
    a: np.ndarray  # cosine coefficients
    b: np.ndarray  # sine coefficients
    w: np.ndarray  # angular frequencies (> 0)

    def value(self, t: np.ndarray) -> np.ndarray:
        wt = np.multiply.outer(np.asarray(t, dtype=float), self.w)
        return np.cos(wt) @ self.a + np.sin(wt) @ self.b

    def rise(self, t: np.ndarray, ref: np.ndarray | float) -> np.ndarray:
        """``f(t) - f(ref)`` without cancellation: ``sum_l 2 sin(w_l (t - ref) / 2)
        (b_l cos(w_l (t + ref) / 2) - a_l sin(w_l (t + ref) / 2))``, every term proportional
        to ``t - ref``. Next to ``ref`` the difference of two values of ``f`` would keep only
        its rounding (``eps |f|``) where this keeps ``eps |f(t) - f(ref)|``."""
        t = np.asarray(t, dtype=float)
        ref = np.broadcast_to(np.asarray(ref, dtype=float), t.shape)
        half_d = np.multiply.outer((t - ref) / 2, self.w)
        half_s = np.multiply.outer((t + ref) / 2, self.w)
        return (2 * np.sin(half_d) * (np.cos(half_s) * self.b - np.sin(half_s) * self.a)).sum(
            axis=-1)

    def d1(self, t: np.ndarray) -> np.ndarray:
        wt = np.multiply.outer(np.asarray(t, dtype=float), self.w)
        return np.cos(wt) @ (self.b * self.w) - np.sin(wt) @ (self.a * self.w)

    def d2(self, t: np.ndarray) -> np.ndarray:
        wt = np.multiply.outer(np.asarray(t, dtype=float), self.w)
        w2 = self.w**2
        return -(np.cos(wt) @ (self.a * w2) + np.sin(wt) @ (self.b * w2))

    def d12(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(f', f'')`` sharing one evaluation of the sines and cosines."""
        wt = np.multiply.outer(np.asarray(t, dtype=float), self.w)
        c, s = np.cos(wt), np.sin(wt)
        w2 = self.w**2
        d1 = c @ (self.b * self.w) - s @ (self.a * self.w)
        return d1, -(c @ (self.a * w2) + s @ (self.b * w2))

    def d12_grid(self, t0: float, h: float, n: int, block: int = 64
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``(f', f'')`` at the ``n + 1`` points ``t_k = t0 + k h`` of a uniform grid, in
        O(N n) flops done by one matrix product (BLAS 3) instead of ``2 N n`` sines and
        cosines: with ``k = q B + r`` (``B = block``),

        ``f^(j)(t_k) = Re sum_l c_l^(j) exp(i w_l (t0 + q B h)) exp(i w_l r h)``,
        ``c^(1) = i w (a - i b)``, ``c^(2) = -w^2 (a - i b)``,

        i.e. ``Re[(A o c) B^T]`` with ``A_ql = exp(i w_l (t0 + q B h))`` (``n/B x N``) and
        ``B_rl = exp(i w_l r h)`` (``B x N``): only ``(n/B + B) N`` exponentials. Each value
        is a sum of products of two correctly rounded exponentials, as accurate as
        :meth:`d12` at ``t_k``."""
        k = np.arange(n + 1)
        Q = (n + block) // block
        tq = t0 + (np.arange(Q) * block) * h
        A = np.exp(1j * np.multiply.outer(tq, self.w))
        Bm = np.exp(1j * np.multiply.outer(np.arange(block) * h, self.w))
        c = self.a - 1j * self.b
        C = np.concatenate([A * (1j * self.w * c), A * (-(self.w**2) * c)], axis=0)
        M = (C @ Bm.T).real
        d1 = M[:Q].reshape(-1)[k]
        d2 = M[Q:].reshape(-1)[k]
        return d1, d2

    @property
    def d2_bound(self) -> float:
        return float(np.sum(self.w**2 * np.hypot(self.a, self.b)))

    #: :meth:`critical_points`: passes over the cells (the first one and the subdivisions;
    #: a cell still uncertified after the last pass is dropped) and sub-cells per split
    LEVELS = 60
    SPLIT = 4

    def critical_points(self, t0: float, t1: float, cells_per_radian: float = 2.0,
                        min_width: float | None = None) -> np.ndarray:
        """All roots of ``f'`` in ``(t0, t1)`` (sorted), certified as described above."""
        span = t1 - t0
        if span <= 0:
            return np.empty(0)
        w, w2 = self.w, self.w**2
        wmax = float(w.max())
        cells = span * wmax * cells_per_radian
        n = max(16, math.ceil(cells)) if cells == cells else 16  # NaN: 16, as max(16, nan)
        min_width = 1e-13 * max(span, 1.0) if min_width is None else min_width
        amp = np.hypot(self.a, self.b)
        L = float((w2 * amp).sum())  # = d2_bound
        L3 = float((w**3 * amp).sum())
        noise = self._noise(w2)
        h = span / n
        edges = t0 + h * np.arange(n + 1)
        edges[-1] = t1
        lo, hi = edges[:-1], edges[1:]
        # f' and f'' at every edge at once: the first pass, which settles almost every cell;
        # few edges and modes: sines and cosines at each edge (t1 included: the formulas of
        # d12, its coefficients computed once), else one matrix product, O(N n) flops at BLAS
        # speed
        if w.size * (n + 1) <= POINTWISE_GRID:
            coef = (self.b * w, self.a * w, self.a * w2, self.b * w2)
            wt = np.multiply.outer(edges, w)
            c, s = np.cos(wt), np.sin(wt)
            e1 = c @ coef[0] - s @ coef[1]
            e2 = -(c @ coef[2] + s @ coef[3])
        else:
            coef = None
            e1, e2 = self.d12_grid(t0, h, n)
            end1, end2 = self.d12(np.array([t1]))
            e1[-1], e2[-1] = end1[0], end2[0]
        if w.size <= SCALAR_MODES:
            out = self._critical_points_scalar(edges, e1, e2, L, L3, min_width, t0, t1, noise,
                                               coef)
            if out is not None:
                return out
        flo, fhi = e1[:-1], e1[1:]
        g_first: tuple[np.ndarray, np.ndarray] | None = (e2[:-1], e2[1:])
        roots: list[np.ndarray] = []
        tangential: list[np.ndarray] = []
        for _ in range(self.LEVELS):
            if lo.size == 0:
                break
            sign_change = np.sign(flo) != np.sign(fhi)
            if np.any(sign_change):
                roots.append(self._bracketed_roots(lo[sign_change], hi[sign_change],
                                                   flo[sign_change], fhi[sign_change], noise))
            rest = ~sign_change
            lo, hi, flo, fhi = lo[rest], hi[rest], flo[rest], fhi[rest]
            # no root: |f'| bounded away from 0 (|f''| <= L), or f' monotone on the cell
            # (f'' of one sign, certified with |f'''| <= L3) with the same sign at both ends
            if g_first is not None:
                g_lo, g_hi = g_first[0][rest], g_first[1][rest]
                g_first = None
            else:
                g_lo, g_hi = self.d2(lo), self.d2(hi)
            monotone = (np.sign(g_lo) == np.sign(g_hi)) & (
                np.abs(g_lo) + np.abs(g_hi) > L3 * (hi - lo))
            certified = (np.abs(flo) + np.abs(fhi) > L * (hi - lo)) | monotone
            lo, hi, flo, fhi = lo[~certified], hi[~certified], flo[~certified], fhi[~certified]
            small = (hi - lo) <= min_width
            if np.any(small):
                tangential.append(np.where(np.abs(flo[small]) < np.abs(fhi[small]),
                                           lo[small], hi[small]))
                lo, hi, flo, fhi = lo[~small], hi[~small], flo[~small], fhi[~small]
            if lo.size == 0:
                break
            # split each remaining cell in SPLIT
            frac = np.linspace(0.0, 1.0, self.SPLIT + 1)
            new_edges = lo[:, None] + (hi - lo)[:, None] * frac[None, :]
            fe = self.d1(new_edges.ravel()).reshape(new_edges.shape)
            fe[:, 0], fe[:, -1] = flo, fhi
            lo, hi = new_edges[:, :-1].ravel(), new_edges[:, 1:].ravel()
            flo, fhi = fe[:, :-1].ravel(), fe[:, 1:].ravel()
        out = np.concatenate(roots + tangential) if (roots or tangential) else np.empty(0)
        out = out[(out > t0) & (out < t1)]
        # a root on an edge where f' is exactly 0 ends both cells' iterations: reported once
        return np.unique(out)

    def _noise(self, w2: np.ndarray | None = None) -> tuple[float, float]:
        """``(noise0, noise1)``: ``f'(t)`` vanishes to its own rounding error when
        ``|f'(t)| <= noise0 + noise1 |t|`` (:meth:`_bracketed_roots`); ``w2``: ``w**2`` if
        already computed."""
        amp = np.abs(self.a) + np.abs(self.b)
        w2 = self.w**2 if w2 is None else w2
        return (4 * _EPS * float((self.w * amp).sum()), 4 * _EPS * float((w2 * amp).sum()))

    def _scalar_terms(self, coef: tuple[np.ndarray, ...] | None = None
                      ) -> list[tuple[float, float, float, float, float]]:
        """``(w_l, b_l w_l, a_l w_l, a_l w_l^2, b_l w_l^2)`` of each mode as Python floats
        (:meth:`_scalar_d12`); ``coef``: the last four as arrays, if already computed."""
        w = self.w
        if coef is None:
            w2 = w**2
            coef = (self.b * w, self.a * w, self.a * w2, self.b * w2)
        return list(zip(w.tolist(), *(x.tolist() for x in coef), strict=True))

    @staticmethod
    def _scalar_d12(terms: list[tuple[float, float, float, float, float]], t: float
                    ) -> tuple[float, float]:
        """``(f'(t), f''(t))`` at one point on Python floats, by the formulas of :meth:`d12`:
        ``f' = sum_l cos(w_l t) b_l w_l - sum_l sin(w_l t) a_l w_l`` and
        ``f'' = -(sum_l cos(w_l t) a_l w_l^2 + sum_l sin(w_l t) b_l w_l^2)``, each sum in the
        order of the modes (equal to :meth:`d12` to rounding: BLAS may sum in another order)."""
        s1 = s2 = s3 = s4 = 0.0
        for wl, bw, aw, aw2, bw2 in terms:
            x = wl * t
            c = math.cos(x)
            s = math.sin(x)
            s1 += c * bw
            s2 += s * aw
            s3 += c * aw2
            s4 += s * bw2
        return s1 - s2, -(s3 + s4)

    def _critical_points_scalar(self, edges: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                                L: float, L3: float, min_width: float, t0: float, t1: float,
                                noise: tuple[float, float],
                                coef: tuple[np.ndarray, ...] | None = None
                                ) -> np.ndarray | None:
        """:meth:`critical_points` after the first pass's evaluation (``f'``, ``f''`` at the
        ``edges``), for few modes: the first pass's sign changes and first-order certificate
        vectorised over the cells, the monotonicity certificate on the few cells left, then
        each bracket (:meth:`_scalar_newton`) and each uncertified cell
        (:meth:`_subdivide_scalar`) on Python floats: the same certificates, splits and
        Newton iteration as the vectorised loop. None when that is more work than the
        vectorised loop (``SCALAR_WORK``)."""
        width = edges[1:] - edges[:-1]
        s1, a1 = np.sign(e1), np.abs(e1)
        sign_change = s1[:-1] != s1[1:]
        brackets = np.flatnonzero(sign_change)
        n_modes = self.w.size
        if brackets.size * (n_modes + 4) > SCALAR_WORK:
            return None
        # neither bracketed nor certified by |f'(lo)| + |f'(hi)| > L (hi - lo) ...
        cand = np.flatnonzero(~(sign_change | (a1[:-1] + a1[1:] > L * width)))
        open_cells: list[int] = []
        if 0 < cand.size <= 8:
            # ... nor by the monotonicity of f' (f'' of one sign, |f''(lo)| + |f''(hi)| >
            # L3 (hi - lo)): the test of the vectorised loop, elementwise
            g = e2.tolist()
            for i, wd in zip(cand.tolist(), width[cand].tolist(), strict=True):
                glo, ghi = g[i], g[i + 1]
                if not (_sign(glo) == _sign(ghi) and abs(glo) + abs(ghi) > L3 * wd):
                    open_cells.append(i)
        elif cand.size:
            g_lo, g_hi = e2[cand], e2[cand + 1]
            monotone = (np.sign(g_lo) == np.sign(g_hi)) & (
                np.abs(g_lo) + np.abs(g_hi) > L3 * width[cand])
            open_cells = cand[~monotone].tolist()
        if brackets.size == 0 and not open_cells:
            return np.empty(0)
        if brackets.size * (n_modes + 4) + len(open_cells) * (n_modes + 2) > SCALAR_WORK:
            return None
        terms = self._scalar_terms(coef)
        found: list[float] = []
        if brackets.size:
            ed, f1 = edges.tolist(), e1.tolist()
            for i in brackets.tolist():
                found.append(self._scalar_newton(terms, noise, ed[i], ed[i + 1], f1[i],
                                                 f1[i + 1]))
        if open_cells:
            ed, f1, g = edges.tolist(), e1.tolist(), e2.tolist()
            cells = [(ed[i], ed[i + 1], f1[i], f1[i + 1], g[i], g[i + 1]) for i in open_cells]
            found.extend(self._subdivide_scalar(terms, noise, cells, L, L3, min_width))
        # a root on an edge where f' is exactly 0 ends both cells' iterations: reported once
        return np.array(sorted({t for t in found if t0 < t < t1}), dtype=float)

    def _subdivide_scalar(self, terms: list[tuple[float, float, float, float, float]],
                          noise: tuple[float, float],
                          cells: list[tuple[float, float, float, float, float, float]],
                          L: float, L3: float, min_width: float) -> list[float]:
        """Roots and tangential candidates in the cells of the first pass that are neither
        bracketed nor certified (each ``(lo, hi, f'(lo), f'(hi), f''(lo), f''(hi))``), as in
        the vectorised loop of :meth:`critical_points`: a cell no longer than ``min_width``
        gives its end of smaller ``|f'|`` (a tangential candidate); a longer one is split in
        ``SPLIT`` (edges ``lo + (hi - lo) k / SPLIT``, ``f'`` and ``f''`` at the new ones, each
        computed once for the two sub-cells that share it), and each sub-cell is bracketed
        (:meth:`_scalar_newton`), certified (``|f'(lo)| + |f'(hi)| > L (hi - lo)``, or ``f''``
        of one sign at both ends with ``|f''(lo)| + |f''(hi)| > L3 (hi - lo)``) or kept for
        the next pass; cells split by the last of the ``LEVELS`` passes are dropped."""
        out: list[float] = []
        split = self.SPLIT
        frac = np.linspace(0.0, 1.0, split + 1).tolist()
        level = cells
        for depth in range(1, self.LEVELS + 1):
            nxt: list[tuple[float, float, float, float, float, float]] = []
            for lo, hi, flo, fhi, glo, ghi in level:
                if hi - lo <= min_width:
                    out.append(lo if abs(flo) < abs(fhi) else hi)
                    continue
                if depth == self.LEVELS:
                    continue
                size = hi - lo
                xs = [lo + size * q for q in frac]
                ev = [(flo, glo)]
                ev.extend(self._scalar_d12(terms, x) for x in xs[1:-1])
                ev.append((fhi, ghi))
                for j in range(split):
                    a, b = xs[j], xs[j + 1]
                    (fa, ga), (fb, gb) = ev[j], ev[j + 1]
                    if _sign(fa) != _sign(fb):
                        out.append(self._scalar_newton(terms, noise, a, b, fa, fb))
                        continue
                    wd = b - a
                    if abs(fa) + abs(fb) > L * wd or (
                            _sign(ga) == _sign(gb) and abs(ga) + abs(gb) > L3 * wd):
                        continue
                    nxt.append((a, b, fa, fb, ga, gb))
            if not nxt:
                break
            level = nxt
        return out

    @staticmethod
    def _scalar_newton(terms: list[tuple[float, float, float, float, float]],
                       noise: tuple[float, float], lo: float, hi: float, flo: float,
                       fhi: float) -> float:
        """:meth:`_bracketed_roots` on one bracket on Python floats: the same start, steps,
        safeguard and convergence tests, ``f'`` and ``f''`` by :meth:`_scalar_d12`."""
        noise0, noise1 = noise
        if abs(flo) <= noise0 + noise1 * abs(lo):
            return lo
        if abs(fhi) <= noise0 + noise1 * abs(hi):
            return hi
        slo = _sign(flo)
        t = 0.5 * (lo + hi)
        for _ in range(100):
            f, fp = TrigSum._scalar_d12(terms, t)
            if _sign(f) == slo:
                lo = t
            else:
                hi = t
            tol = 8 * _EPS * max(abs(t), 1.0)
            if fp != 0.0:
                step = f / fp
                tn = t - step
                newton_done = math.isfinite(step) and abs(step) <= tol
            else:  # numpy's f / 0: +-inf or nan, never converged; the safeguard bisects
                tn, newton_done = math.nan, False
            if not newton_done and not lo <= tn <= hi:  # also catches a non-finite tn
                tn = 0.5 * (lo + hi)
            conv = (newton_done or hi - lo <= tol or f == 0.0
                    or abs(f) <= noise0 + noise1 * abs(t))
            if f != 0.0:
                t = tn
            if conv:
                break
        return t

    def _bracketed_roots(self, lo: np.ndarray, hi: np.ndarray, flo: np.ndarray,
                         fhi: np.ndarray, noise: tuple[float, float] | None = None
                         ) -> np.ndarray:
        """Safeguarded Newton on ``f'`` inside brackets with a sign change (vectorised; only the
        brackets not yet converged are iterated).

        A root is converged when the Newton step is below ``8 eps |t|``, the bracket is that
        narrow, or ``f'`` vanishes to its own rounding error, bounded by
        ``4 eps sum_l w_l (|a_l| + |b_l|) (1 + w_l |t|)`` (the products, the sum, and the
        argument ``w_l t`` of the sine and cosine, rounded). An end of a bracket where ``f'``
        vanishes so is the root, taken as it is: there, every Newton step from inside
        overshoots the bracket and the safeguard bisects towards the end, one bit per
        evaluation (14-19 evaluations for the critical point at ``T / 2`` of a symmetric
        orbit, which is an edge of the first pass's even grid: ``tests/chain/test_trig_sum.py``).
        ``noise``: :meth:`_noise`, if already computed."""
        noise0, noise1 = self._noise() if noise is None else noise
        lo, hi = lo.copy(), hi.copy()
        slo = np.sign(flo)
        t = 0.5 * (lo + hi)
        at_lo = np.abs(flo) <= noise0 + noise1 * np.abs(lo)
        at_hi = ~at_lo & (np.abs(fhi) <= noise0 + noise1 * np.abs(hi))
        t[at_lo], t[at_hi] = lo[at_lo], hi[at_hi]
        active = np.nonzero(~(at_lo | at_hi))[0]
        for _ in range(100):
            if active.size == 0:
                break
            ta = t[active]
            f, fp = self.d12(ta)
            same = np.sign(f) == slo[active]
            la = np.where(same, ta, lo[active])
            ha = np.where(same, hi[active], ta)
            lo[active], hi[active] = la, ha
            with np.errstate(divide="ignore", invalid="ignore"):
                step = f / fp
            tn = ta - step
            tol = 8 * _EPS * np.maximum(np.abs(ta), 1.0)
            newton_done = np.isfinite(step) & (np.abs(step) <= tol)
            bad = ~np.isfinite(tn) | (tn < la) | (tn > ha)
            tn = np.where(bad & ~newton_done, 0.5 * (la + ha), tn)
            conv = (newton_done | (ha - la <= tol) | (f == 0.0)
                    | (np.abs(f) <= noise0 + noise1 * np.abs(ta)))
            t[active] = np.where(f == 0.0, ta, tn)
            active = active[~conv]
        return t

    def max_on(self, t0: float, t1: float) -> tuple[float, float]:
        """``(max, argmax)`` of ``f`` over the critical points in the open interval ``(t0, t1)``;
        ``(-inf, nan)`` when there are none."""
        tc = self.critical_points(t0, t1)
        if tc.size == 0:
            return -np.inf, float("nan")
        v = self.value(tc)
        i = int(np.argmax(v))
        return float(v[i]), float(tc[i])
