"""Branch switching at a ``k``-fold resonance of a conservative family (``k >= 3``).

At an orbit of a conservative family whose section map has a multiplier pair
``exp(+-2 pi i m / k)`` (``gcd(m, k) = 1``), the ``k``-times iterated problem
(:meth:`~nsm_continuation.core.problem.Problem.iterated`: ``k`` returns to the section per
period) has the Jacobian ``G_y = [P^k_z - I, P^k_s]`` (``n x (n + 1)``) of rank ``n - 2``: its
kernel is three-dimensional, spanned by the family's tangent ``t1`` and the real and imaginary
parts ``(v_r, 0), (v_i, 0)`` of the pair's eigenvector (both fixed by ``D P^k``). Families of
period-``k`` orbits branch off in that plane: in the normal form of the ``k``-fold bifurcation
of a Hamiltonian family (Meyer, "Generic bifurcation of periodic points", Trans. AMS 149 (1970)
95-107) a period-``k`` orbit's ``k`` section points lie at radius ``r`` in the plane at angles
``phi* + 2 pi j / k``, with the parameter offset ``~ r`` for ``k = 3`` (one family through the
resonance, on both sides) and ``~ r^2`` for ``k >= 4``; ``phi*`` is set by the normal form's
coefficients, which are not computed here. Instead the plane is scanned: for each angle ``phi``
of :data:`ANGLES` (a half turn: ``phi + pi`` is the point of amplitude ``-eps``) and amplitude
``eps`` the corrector solves

    ``G(y) = 0``,   ``d_phi . (y - y_b) = eps``,   ``d_phi = cos(phi) e_1 + sin(phi) e_2``,

(``e_1, e_2`` an orthonormal basis of the kernel vectors without parameter component) from
``y_b + eps d_phi``; a solution is kept when it lies within ``10 eps`` of ``y_b`` and is no
orbit of the base family (``|G_base(y)| > 1e3 newton_tol (1 + |y|)``: a period-``k`` orbit
that is not ``k`` copies of one period). The first new solution is the start, and where the
amplitude ``-eps`` at the same angle gives another one on the other side of the resonance
(parameter offset of the other sign: ``k = 3``) that is a second start. Each start carries
``+-d_phi`` as its tangent: the run corrects it again on the row it was found with, and
continues it away from the resonance (along ``+-d_phi``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsm_continuation.algorithms.base import TangentStart
from nsm_continuation.core.palc import NUMERICAL_ERRORS, ContinuationEngine, describe_error
from nsm_continuation.core.problem import Problem

#: amplitudes of the scan, times ``1 + |y_b|_inf``
AMPLITUDES = (3e-3, 1e-2)
#: angles of the scan in the kernel plane (a half turn; ``-eps`` covers the other half)
ANGLES = tuple(np.linspace(0.0, np.pi, 12, endpoint=False))
#: a kernel direction counts as singular below this ``sigma / sigma_max`` of ``G_y``
SINGULAR_RATIO = 1e-6


def resonance_plane(J: np.ndarray, ip: int) -> tuple[np.ndarray, float]:
    """``(E, gap)``: an orthonormal basis ``E`` (2 rows) of the kernel vectors of ``J``
    (``n x (n+1)``, the ``k``-times iterated problem at the resonance) without parameter
    component (index ``ip``), and ``sigma_{n-2} / sigma_max`` (the first non-zero singular
    value: how isolated the three-dimensional kernel is). Raises :class:`ValueError` where the
    kernel is not three-dimensional."""
    _, s, vt = np.linalg.svd(J)
    top = max(float(s[0]), 1.0)
    if s.size < 3 or float(s[-2]) / top > SINGULAR_RATIO:
        raise ValueError(f"the iterated problem's Jacobian has not a three-dimensional kernel "
                         f"there (singular values {s[-2] / top:.2g}, {s[-1] / top:.2g} of the "
                         "largest): no multiplier exp(2 pi i m / k)")
    gap = float(s[-3]) / top
    if gap < SINGULAR_RATIO:
        raise ValueError("the iterated problem's kernel has dimension > 3 there: two "
                         "resonances at once")
    K = vt[-3:]
    a = np.linalg.svd(K[:, ip][None, :])[2][1:]  # combinations without parameter component
    E = np.linalg.qr((a @ K).T)[0].T
    return E, gap


def resonance_starts(base: Problem, problem: Problem, yb: np.ndarray, settings: Any,
                     label: str = "", info: dict[str, Any] | None = None,
                     amplitudes: tuple[float, ...] = AMPLITUDES,
                     angles: tuple[float, ...] = ANGLES) -> tuple[list[TangentStart], dict]:
    """The first points of the period-``k`` family at the resonance ``yb`` of ``base`` (module
    docstring) as starts of ``problem`` (``base.iterated(k)``), and the switch's record.
    Raises :class:`ValueError` (no period-``k`` orbit found, with what each try gave)."""
    yb = np.asarray(yb, dtype=float)
    ip = problem.parameter_index
    where = f"{problem.parameter} = {yb[ip]:.10g}"
    try:
        E, gap = resonance_plane(problem.jacobian(yb), ip)
    except NUMERICAL_ERRORS as exc:
        raise ValueError(f"switch at {where}: {describe_error(exc)}") from None
    except ValueError as exc:
        raise ValueError(f"switch at {where}: {exc}") from None
    engine = ContinuationEngine(problem, settings)
    scale = 1.0 + float(np.linalg.norm(yb, np.inf))
    tol = settings.newton_tol
    tried: dict[str, int] = {}

    def solve(d: np.ndarray, eps: float) -> np.ndarray | None:
        y, _, why = engine.correct(yb + eps * d, d, yb, eps)
        if y is None:
            tried[why.split(" (")[0]] = tried.get(why.split(" (")[0], 0) + 1
            return None
        if float(np.linalg.norm(y - yb)) > 10.0 * abs(eps):
            tried["too far"] = tried.get("too far", 0) + 1
            return None
        try:
            g = float(np.linalg.norm(base.evaluate(y), np.inf))
        except NUMERICAL_ERRORS:
            g = np.inf
        if g <= 1e3 * tol * (1.0 + float(np.linalg.norm(y, np.inf))):
            tried["an orbit of the base family"] = tried.get("an orbit of the base family",
                                                            0) + 1
            return None
        return y

    found: list[tuple[np.ndarray, np.ndarray]] = []
    used: tuple[float, float] | None = None
    for a in amplitudes:
        eps = a * scale
        for phi in angles:
            d = np.cos(phi) * E[0] + np.sin(phi) * E[1]
            y = solve(d, eps)
            if y is None:
                continue
            found.append((y, d))
            used = (eps, float(phi))
            y2 = solve(d, -eps)
            if y2 is not None and (y2[ip] - yb[ip]) * (y[ip] - yb[ip]) < 0:
                found.append((y2, -d))
            break
        if found:
            break
    if not found or used is None:
        what = "; ".join(f"{v} x {k}" for k, v in tried.items())
        raise ValueError(f"switch at {where}: no period-{problem.period_multiple()} orbit "
                         f"found ({what})")
    rec = {**(info or {}), "switch_amplitude": used[0], "switch_angle": used[1],
           "switch_kernel_gap": gap, "period_multiple": int(problem.period_multiple())}
    starts = []
    for i, (y, d) in enumerate(found):
        side = "" if len(found) == 1 else (" (above)" if y[ip] > yb[ip] else " (below)")
        # the start is corrected again on the row it was found with (d . y fixed), and the
        # branch leaves along +d: away from the resonance
        starts.append(TangentStart(y, f"{label}{side}", 1, {**rec, "side": i}, tangent=d,
                                   forward_only=True))
    return starts, {"switch_residual_evaluations": engine.n_evaluations}


__all__ = ["AMPLITUDES", "ANGLES", "resonance_plane", "resonance_starts"]
