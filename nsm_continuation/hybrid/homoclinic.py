"""The period law of periodic orbits near a homoclinic orbit to a saddle, fitted on a branch.

``T = c - ln|p - p*| / mu`` with its next order (:func:`homoclinic_fit`), reported by
:meth:`~.presentation.HybridPresentation.report_extras` where the presentation's rule allows it
(an autonomous system whose branch followed the divergence of the period). ``mu`` is the
saddle's unstable eigenvalue, ``p*`` the parameter of the homoclinic orbit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from nsm_continuation.core.scalar_search import bounded_minimum

#: relative accuracy floor of a point of the branch in the homoclinic fit (the Newton
#: tolerance on the period, terms beyond the fitted expansion)
FIT_RELATIVE_FLOOR = 1e-6

@dataclass(frozen=True)
class _Points:
    """The points of the branch the fit uses: parameters ``p``, periods ``T`` and their
    uncertainties ``dT``; ``T0`` the smallest period, ``eps_p`` the spacing of doubles at the
    largest ``|p|``."""

    p: np.ndarray
    T: np.ndarray
    dT: np.ndarray
    T0: float
    eps_p: float


def _fit_points(ps: np.ndarray, Ts: np.ndarray, n_last: int | None,
                uncertainty: np.ndarray | None) -> _Points | None:
    """The finite points with ``T`` in the upper three quarters of the period range (the last
    ``n_last`` of them if given); None with fewer than 6 finite points, a period that does not
    double, or fewer than 5 points kept."""
    ps = np.asarray(ps, dtype=float)
    Ts = np.asarray(Ts, dtype=float)
    dTs = (np.zeros_like(Ts) if uncertainty is None
           else np.nan_to_num(np.asarray(uncertainty, dtype=float), nan=0.0))
    ok = np.isfinite(ps) & np.isfinite(Ts)
    ps, Ts, dTs = ps[ok], Ts[ok], dTs[ok]
    if len(Ts) < 6 or Ts.max() < 2 * Ts.min():
        return None
    keep = Ts >= Ts.min() + 0.25 * (Ts.max() - Ts.min())
    if n_last is not None:
        keep &= Ts >= np.sort(Ts)[-min(n_last, len(Ts))]
    p, T, dT = ps[keep], Ts[keep], dTs[keep]
    if len(T) < 5:
        return None
    eps_p = np.finfo(float).eps * float(np.max(np.abs(p)))
    return _Points(p, T, dT, float(T.min()), eps_p)


def _basis(pts: _Points, mu: float, terms: int) -> np.ndarray:
    """Columns ``1, x, x^2, (T - T0) x^2`` (the first ``terms + 1``), ``x = exp(-mu (T - T0))``."""
    T, T0 = pts.T, pts.T0
    x = np.exp(-mu * (T - T0))
    cols = [np.ones_like(T), x, x * x, (T - T0) * x * x][: terms + 1]
    return np.column_stack(cols)


def _solve(pts: _Points, mu: float, w: np.ndarray, terms: int) -> tuple[float, np.ndarray]:
    """The weighted linear least-squares fit at a given ``mu``: squared residual, coefficients
    ``(p*, a1, ...)``."""
    p = pts.p
    B = _basis(pts, mu, terms)
    coef, *_ = np.linalg.lstsq(B * w[:, None], p * w, rcond=None)
    r = (B @ coef - p) * w
    return float(r @ r), coef


def _fit(pts: _Points, terms: int, lo: float, hi: float, mu: float
         ) -> tuple[float, np.ndarray, np.ndarray, float] | None:
    """``(mu, coefficients, weights, squared residual)`` with ``mu`` in ``[lo, hi]`` minimising
    the weighted residual (a grid, then bounded Brent), the weights iterated with ``p*``; None
    if the fit degenerates (``a1 = 0``, ``mu`` not positive)."""
    p, dT, eps_p = pts.p, pts.dT, pts.eps_p
    p_star = p[np.argmax(pts.T)]
    w = np.ones_like(p)
    for _ in range(4):
        w = 1.0 / (np.maximum(eps_p, mu * np.abs(p - p_star) * dT)
                   + FIT_RELATIVE_FLOOR * np.abs(p - p_star) + 1e-300)
        grid = np.geomspace(lo, hi, 120)
        vals = [_solve(pts, m, w, terms)[0] for m in grid]
        k = int(np.argmin(vals))
        mu = bounded_minimum(lambda m, w=w: _solve(pts, m, w, terms)[0], grid[max(k - 1, 0)],
                             grid[min(k + 1, len(grid) - 1)], xatol=1e-12 * hi)[0]
        r2, coef = _solve(pts, mu, w, terms)
        p_star = float(coef[0])
    if not (coef[1] != 0.0 and np.isfinite(mu) and mu > 0):
        return None
    return mu, coef, w, r2


def _mu_stderr(pts: _Points, mu: float, coef: np.ndarray, w: np.ndarray, terms: int,
               rms: float) -> float:
    """Standard error of ``mu`` from the linearised weighted problem in ``(p*, a_k, mu)``."""
    T, T0 = pts.T, pts.T0
    B = _basis(pts, mu, terms)
    dB = np.zeros_like(B)
    x = np.exp(-mu * (T - T0))
    tau = T - T0
    dcols = [np.zeros_like(T), -tau * x, -2 * tau * x * x, -2 * tau * tau * x * x]
    for j in range(1, terms + 1):
        dB[:, j] = dcols[j]
    Jm = np.column_stack([B, dB @ coef]) * w[:, None]
    try:
        cov = np.linalg.inv(Jm.T @ Jm) * rms**2
        return float(np.sqrt(max(cov[-1, -1], 0.0)))
    except np.linalg.LinAlgError:
        return float("nan")


def homoclinic_fit(ps: np.ndarray, Ts: np.ndarray, n_last: int | None = None,
                   uncertainty: np.ndarray | None = None) -> dict[str, Any] | None:
    """Fit the period law near a homoclinic orbit to a saddle with unstable eigenvalue ``mu``,
    ``T = c - ln|p - p*| / mu``, with its next order; None unless the period at least doubles
    along the branch (where it is attempted at all:
    :meth:`HybridPresentation.homoclinic_fit_applies`).

    **Model.** Near the homoclinic orbit the orbit enters the saddle's neighbourhood at a
    distance ``u = k (p - p*) (1 + O(p - p*))`` from its stable manifold and spends
    ``-ln(u / U) / mu(p) + O(u)`` there (smooth linearisation, no resonance: the saddle's
    stable eigenvalue enters only through ``u^(|mu_s| / mu)``, negligible); ``mu(p) = mu (1 +
    gamma (p - p*))``. Inverted for ``p`` (the period is the continuation parameter, or is
    simply the better-conditioned variable):

        ``p - p* = a1 exp(-mu T) + (a2 + a3 T) exp(-2 mu T) + O(T^2 exp(-3 mu T))``,

    the leading term being ``T = c - ln|p - p*| / mu`` with ``c = ln|a1| / mu``; ``a2`` comes
    from the nonlinearity of the passage and of the entry, ``a3`` from ``d mu / dp``. Linear in
    ``(p*, a1, a2, a3)`` for a given ``mu``: ``mu`` minimises the weighted residual (a grid,
    then bounded Brent), the weights iterated with ``p*``; first with the leading term alone
    (``mu`` anywhere in ``[0.05, 50] / (T range)``), then with the next order within a factor
    0.7-1.4 of that (a free exponent with the corrections aliases: ``mu / 2`` with ``a1 ~ 0``
    fits as well).

    **Points and weights.** The points with ``T`` in the upper three quarters of the branch's
    period range (the expansion fails near the start), all of them up to the largest period:
    each weighted by ``1 / sigma``, ``sigma = max(eps |p|, mu |p - p*| dT) + 1e-6 |p - p*|``
    (``dT``: ``uncertainty``, the branch's ``period_uncertainty``, 0 if not given; the relative
    floor ``FIT_RELATIVE_FLOOR`` covers the Newton tolerance and the neglected terms). With
    fewer than 8 points the ``a3`` term, with fewer than 7 also ``a2``, is dropped. ``n_last``
    keeps only the points of largest period.

    Returns ``p_star``, ``mu_unstable`` (with ``mu_unstable_stderr`` from the weighted
    residual), ``c``, ``rms_residual`` (weighted: ~1 where the weights are the points' real
    accuracy), ``mu_leading_only`` (the law without the next order, same points), ``n_points``,
    ``period_range`` (the points used) and ``model``.
    """
    pts = _fit_points(ps, Ts, n_last, uncertainty)
    if pts is None:
        return None
    T, T0 = pts.T, pts.T0
    span = float(np.ptp(T))
    # the leading law first (mu over a wide range); the next order then refines mu near it
    # (with a free exponent the corrections alias: mu/2 with a1 ~ 0 fits as well)
    lead = _fit(pts, 1, 0.05 / span, 50.0 / span, 3.0 / span)
    if lead is None:
        return None
    terms = 3 if len(T) >= 8 else (2 if len(T) >= 7 else 1)
    out = lead if terms == 1 else _fit(pts, terms, 0.7 * lead[0], 1.4 * lead[0], lead[0])
    if out is None:
        return None
    mu, coef, w, r2 = out
    dof = max(len(T) - (terms + 2), 1)
    rms = float(np.sqrt(r2 / dof))
    mu_err = _mu_stderr(pts, mu, coef, w, terms, rms)
    model = ["a1 exp(-mu T)", "a2 exp(-2 mu T)", "a3 T exp(-2 mu T)"][:terms]
    return {"p_star": float(coef[0]), "mu_unstable": mu, "mu_unstable_stderr": mu_err,
            "c": float(T0 + np.log(abs(coef[1])) / mu), "rms_residual": rms,
            "mu_leading_only": float(lead[0]),
            "n_points": int(len(T)), "period_range": [T0, float(T.max())],
            "model": "p - p* = " + " + ".join(model)}
