"""Branch switching at a simple branch point and at a period doubling.

**Simple branch point** (event ``branch_point``: ``det[G_y; t^T]`` changes sign). There ``G_y``
(``n x (n+1)``) has rank ``n - 1``: its kernel is spanned by the tangents of the two branches
that cross. The arriving tangent ``t1`` is stored with the event (restart record); the kernel is
the span of the last two right singular vectors of ``G_y``, and the direction of the other
branch is taken as the unit kernel vector ``w`` orthogonal to ``t1``. Its first point solves

    G(y) = 0,    w . (y - y_b) = eps,

by Newton from ``y_b + eps w`` (the pseudo-arclength condition along ``w``: AUTO's branch
switching, ``ISW = -1`` at a branch point, Doedel, Keller & Kernevez 1991; BifurcationKit's
``continuation(br, ind_bif)`` predicts ``x0 + ampfactor * zeta`` along the kernel vector,
``δp`` / ``ampfactor`` chosen by hand or from the normal form). Instead of the algebraic
branching equation this module scans ``eps`` (:data:`AMPLITUDES` times ``1 + |y_b|``, or
``start.amplitude``) and keeps the first solution that is new: within ``10 eps`` of ``y_b``
and not along ``t1`` (a solution on the arriving branch with ``w . (y - y_b) = eps`` lies
``~ sqrt(eps / curvature)`` away, along ``t1``). The switched branch is continued both ways
from there: through the branch point, it gives both halves of the other branch.

**Period doubling** of an orbit of ``k`` base periods (event ``period_doubling``: a multiplier
through -1). The orbit is also a solution of the ``2k``-periodic problem
(:meth:`~nsm_continuation.core.problem.Problem.iterated`, for a hybrid orbit the twice-iterated
return map, ``start.returns: 2k``), whose Jacobian ``[P^2_z - I, P^2_p]`` there has the
two-dimensional kernel ``{t1, (v, 0)}``: ``t1`` the tangent of the period-``k`` branch, ``v``
the eigenvector of the multiplier -1 of the period-``k`` map (``(P_z^2 - I) v = 0``). The
period-``2k`` family leaves it in a pitchfork of the doubled map. The predictor is the kernel
vector orthogonal to ``t1`` (``(v, 0)`` with its ``t1`` component removed: ``(v, 0)`` itself
would let the corrector slide along the period-``k`` branch when ``v . dz/dp != 0``), the
corrector the same bordered Newton, from the predictor along the family's own direction
``u = (v, 0)`` (the kernel vector without parameter component) scaled to meet the condition,
``y_b + eps u / (w . u)``. The family's first point then lies ``eps / |w . u|`` from the
doubling (:func:`family_reach`): ``w . u`` is the parameter component of ``t1``, which is small
where ``dz/dp`` and ``v`` are nearly parallel, as on the rank-one return map of orbits that
stick (the double pendulum's 4 -> 8 doubling: 0.005, the point 165 eps away). A solution is
new when it lies within ``10 eps / |w . u|`` (at least ``100 eps``) and is no period-``k`` orbit
(``|G_k(y)| > 1e3 newton_tol (1 + |y|)``). The family is flat in the parameter there
(``p - p_b ~ c eps^2``; ``c = 1.2e-3`` on the two-mass chain, so at ``eps = 1e-4`` the offset
is below the corrector's noise, 3e-10, and so is the sign of the start's tangent): the scan
goes on to the first amplitude whose offset is resolved (:data:`PARAMETER_RESOLUTION`). As
DDE-BIFTOOL's ``DoublePsol`` (a deviation ``radius`` along the period-doubling eigenvector,
then a corrector with a step condition) and BifurcationKit's branch switching at ``:pd``
points of periodic orbits. The family is continued away from the period doubling, along the
secant from it (its other half is the same orbits shifted by ``k`` periods), unless
``start.direction`` says otherwise.

**The start must be one the engine can correct.** The switched branch's first point is
corrected once more by the engine on its own condition (:class:`~.base.TangentStart`: the
secant ``s`` from the bifurcation point, ``s . (y - y0) = 0``). Near the bifurcation
``[G_y; s^T]`` is nearly singular (both branches' directions are nearly in the kernel of
``G_y``: its smallest singular value grows like the distance), so the Newton step made of the
residual's noise (rounding, an integrator's tolerance) is that noise over the distance, and
within some distance it exceeds the corrector's step tolerance at any residual. The 5-dof
chain's period-2 families born at ``omega = 1.5386`` and ``1.4884`` are flat in the frequency
(no amplitude resolves their parameter offset, so the scan falls back to a small amplitude):
``2.5e-6`` from the flip at ``1.5386``, ``sigma_min = 1.3e-6`` and the steps are ``1e-10 ..
1e-9`` against the tolerance ``2.5e-11`` at a residual of ``1.6e-14``. The scan therefore
keeps only solutions whose start correction converges (:func:`start_converges`, the engine's
own computation: the same point, condition and corrector) with a margin (one more step at most
:data:`START_MARGIN` of the tolerance: where the noise's step is about the tolerance the
correction converges by chance) and goes on to the next amplitude otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nsm_continuation.algorithms.base import TangentStart
from nsm_continuation.core.palc import NUMERICAL_ERRORS, ContinuationEngine, describe_error
from nsm_continuation.core.problem import Problem

#: amplitudes of the scan, times ``1 + |y_b|_inf``: the first that gives a new solution (at a
#: period doubling: the first whose parameter offset is resolved, :data:`PARAMETER_RESOLUTION`)
AMPLITUDES = (1e-6, 3e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2)
#: largest ``sigma_min / sigma_max`` of ``G_y`` at a branch point (else it is not singular)
SINGULAR_RATIO = 1e-5
#: at a period doubling the scan goes on (when no ``start.amplitude`` is given) to the first
#: amplitude whose parameter offset is this many times ``newton_tol (1 + |p|)``: below it the
#: parameter along the flat family is corrector noise (measured: 3e-10 on the two-mass chain)
PARAMETER_RESOLUTION = 1e2
#: a switched branch's start is taken where one corrector step at the converged start is at
#: most this fraction of the corrector's step tolerance (:func:`start_converges`)
START_MARGIN = 0.1


def null_vector(J: np.ndarray) -> np.ndarray:
    """Unit null vector of the ``n x (n+1)`` matrix ``J`` (its last right singular vector)."""
    return np.linalg.svd(J)[2][-1]


def other_direction(J: np.ndarray, t1: np.ndarray) -> tuple[np.ndarray, float]:
    """``(w, ratio)``: the unit vector of the two-dimensional kernel of ``J`` (at a simple
    branch point) orthogonal to the arriving tangent ``t1``, and ``sigma_n / max(sigma_1, 1)``
    of ``J`` (how singular it is). Raises :class:`ValueError` where ``J`` is not singular or
    ``t1`` is not in its kernel."""
    t1 = np.asarray(t1, dtype=float) / np.linalg.norm(t1)
    _, s, vt = np.linalg.svd(J)
    # relative to the largest singular value, at least 1 (a 1 x 2 Jacobian has one: it
    # vanishes at the branch point)
    top = max(float(s[0]) if s.size else 0.0, 1.0)
    ratio = float(s[-1]) / top if s.size else 0.0
    if ratio > SINGULAR_RATIO:
        raise ValueError(f"G_y is not singular there (smallest singular value {ratio:.2g} of "
                         "the largest): not a branch point of this formulation")
    if s.size >= 2 and float(s[-2]) / top < SINGULAR_RATIO:
        raise ValueError("G_y has a kernel of dimension > 2 there: not a simple branch point")
    K = vt[-2:]
    c = K @ t1
    if np.linalg.norm(t1 - K.T @ c) > 1e-4:
        raise ValueError("the arriving tangent is not in the kernel of G_y: not a branch "
                         "point of this branch")
    w = K.T @ np.array([-c[1], c[0]])
    return w / np.linalg.norm(w), ratio


def family_reach(J: np.ndarray, w: np.ndarray, ip: int) -> float:
    """At a period doubling: how far (in units of ``eps``) the first point of the period-2k
    family may lie from the doubling point when the corrector holds ``w . (y - y_b) = eps``.
    The family leaves along ``u = (v, 0)``, the kernel vector of ``G_y`` (the doubled
    problem's) with no parameter component; its point with ``w . (y - y_b) = eps`` is about
    ``eps / |w . u|`` away. ``|w . u|`` is small where the period-k branch is nearly parallel
    to ``(v, 0)``: on a rank-one return map (orbits that stick, the double pendulum of sec.
    6.2) ``dz/dp`` and ``v`` both lie in the map's one-dimensional range, and ``w . u`` equals
    the parameter component of the period-k tangent (measured 0.005 at the pendulum's
    4 -> 8 doubling: the family's first point lies 165 eps away)."""
    return family_direction(J, w, ip)[0]


def family_direction(J: np.ndarray, w: np.ndarray, ip: int) -> tuple[float, np.ndarray]:
    """``(reach, p)``: :func:`family_reach` and the predictor step per unit ``eps`` along the
    family, ``p = reach u`` with ``u`` signed so that ``w . p = 1`` (``w`` itself where the
    kernel has no vector without parameter component, or where ``|w . u| < 1e-4``)."""
    K = np.linalg.svd(J)[2][-2:]
    c = np.array([K[1, ip], -K[0, ip]])
    if np.linalg.norm(c) == 0.0:
        return 1.0, w
    u = K.T @ c
    u /= np.linalg.norm(u)
    wu = float(w @ u)
    if abs(wu) < 1e-4:
        return 1.0 / max(abs(wu), 1e-6), w
    return 1.0 / abs(wu), u / wu


def start_converges(engine: ContinuationEngine, y: np.ndarray, yb: np.ndarray) -> str:
    """Why the switched branch's start at ``y`` cannot be corrected on its own condition (the
    secant from the bifurcation point ``yb``: :meth:`~.base.StartTangentEngine.correct_start`
    runs the same Newton from the same point), or ``""`` where it converges (module
    docstring: near the bifurcation the bordered Jacobian amplifies the residual's noise past
    the step tolerance)."""
    d = np.asarray(y, dtype=float) - yb
    secant = d / np.linalg.norm(d)
    y1, _, why = engine.correct(y, secant, y, 0.0)
    if y1 is None:
        return why
    # converged with a margin: one more step from the converged point (the residual's noise
    # over the bordered Jacobian's smallest singular value) is within START_MARGIN of the
    # tolerance, so that the convergence is not by chance where that noise is the tolerance
    try:
        g, factor = engine.problem.residual_and_factor(y1, secant)
        step = factor.solve(-np.append(g, secant @ (y1 - y)))
    except (*NUMERICAL_ERRORS, np.linalg.LinAlgError) as exc:
        return describe_error(exc)
    size = float(np.linalg.norm(step, np.inf))
    bound = START_MARGIN * engine.settings.newton_tol * (1.0 + float(np.linalg.norm(y1, np.inf)))
    if not size <= bound:
        return (f"the corrector's step at the converged start, {size:.2g}, is its noise over a "
                f"nearly singular Jacobian (above {bound:.2g})")
    return ""


@dataclass
class Switch:
    """A switch at a located event: the event's unknowns ``y`` on the problem ``base`` it was
    found on (the period-``k`` problem at a period doubling), the kind (``period_doubling``
    or ``branch_point``), the arriving branch's unit tangent there, the amplitude to use (None:
    :data:`AMPLITUDES`), the direction along the internal parameter (None: away from the
    bifurcation at a period doubling, both ways at a branch point) and the start's label and
    record (:class:`~nsm_continuation.cases.restart.Restart` builds it from a saved run)."""

    y: np.ndarray
    kind: str
    base: Problem
    tangent: np.ndarray | None
    amplitude: float | None = None
    direction: int | None = None
    label: str = ""
    info: dict[str, Any] = field(default_factory=dict)


def switch_start(r: Switch, problem: Problem, settings: Any
                 ) -> tuple[list[TangentStart], dict[str, Any]]:
    """The first point of the branch that bifurcates at the restart's event (module
    docstring), as a start of ``problem`` (the doubled problem at a period doubling), and the
    counters of the switch. Raises :class:`ValueError` (a failed start, with the reason)."""
    engine = ContinuationEngine(problem, settings)
    yb = np.array(r.y, dtype=float)
    ip = problem.parameter_index
    scale = 1.0 + float(np.linalg.norm(yb, np.inf))
    where = f"{problem.parameter} = {yb[ip]:.10g}"
    pd = r.kind == "period_doubling"
    reach, step = 1.0, None
    try:
        if pd:
            t1 = null_vector(r.base.jacobian(yb))  # the period-k branch's tangent
        else:
            t = r.tangent
            if t is None:
                raise ValueError("the event has no tangent")
            t1 = t
        J = problem.jacobian(yb)
        w, ratio = other_direction(J, t1)
        if pd:
            reach, step = family_direction(J, w, ip)
    except NUMERICAL_ERRORS as exc:
        raise ValueError(f"switch at {where}: {describe_error(exc)}") from None
    except ValueError as exc:
        raise ValueError(f"switch at {where}: {exc}") from None
    amplitudes = ([r.amplitude] if r.amplitude is not None
                  else [a * scale for a in AMPLITUDES])
    tol = settings.newton_tol
    tried: list[str] = []
    found: tuple[np.ndarray, float, int] | None = None
    for eps in amplitudes:
        y, it, why = engine.correct(yb + eps * (w if step is None else step), w, yb, eps)
        if y is None:
            tried.append(f"{eps:.2g}: {why}")
            continue
        d = y - yb
        dist = float(np.linalg.norm(d))
        if dist > (max(100.0, 10.0 * reach) if pd else 10.0) * eps:
            tried.append(f"{eps:.2g}: the corrector went {dist / eps:.3g} eps away")
            continue
        if not pd:
            if abs(float(t1 @ d)) > 0.999 * dist / np.linalg.norm(t1):
                tried.append(f"{eps:.2g}: the corrector fell back onto the arriving branch")
                continue
            why = start_converges(engine, y, yb)
            if why:
                tried.append(f"{eps:.2g}: too near the branch point to start from ({why})")
                continue
            found = (y, eps, it)
            break
        try:
            g = float(np.linalg.norm(r.base.evaluate(y), np.inf))
        except NUMERICAL_ERRORS as exc:
            tried.append(f"{eps:.2g}: {describe_error(exc)}")
            continue
        if g <= 1e3 * tol * (1.0 + float(np.linalg.norm(y, np.inf))):
            tried.append(f"{eps:.2g}: the solution is a period-{int(r.base.period_multiple())} "
                         "orbit again")
            continue
        # the family is flat in the parameter at a period doubling (p - p_b ~ eps^2): go on
        # to an amplitude whose parameter offset the corrector resolves, so that the start's
        # tangent has the sign of the family's (else a fold is seen at the start)
        resolved = abs(y[ip] - yb[ip]) >= PARAMETER_RESOLUTION * tol * (1.0 + abs(yb[ip]))
        if found is None or resolved:  # a candidate start: one the engine can correct?
            why = start_converges(engine, y, yb)
            if why:
                tried.append(f"{eps:.2g}: too near the period doubling to start from ({why})")
                continue
        if found is None or resolved:
            found = (y, eps, it)
        if resolved:
            break
    if found is None:
        what = (f"period-{2 * int(r.base.period_multiple())} orbit" if pd else "other branch")
        raise ValueError(f"switch at {where}: no {what} found (amplitude {'; '.join(tried)})")
    y, eps, it = found
    # away from a period doubling (the other half is the same orbits shifted by k periods),
    # both ways through a branch point; "away" is along the secant from the bifurcation point
    # (w can point back along a strongly curved family: its parameter component is -t1.v t1_p)
    away = pd and r.direction is None
    direction = 1 if away else (r.direction or 0)
    info = {**r.info, "switch_amplitude": float(eps), "switch_newton_iterations": it,
            "switch_kernel_sigma_ratio": ratio, "period_multiple": int(problem.period_multiple())}
    if pd:
        info["switch_reach"] = reach
    secant = (y - yb) / np.linalg.norm(y - yb)
    start = TangentStart(y, r.label, direction, info, tangent=secant, forward_only=away)
    return [start], {"switch_residual_evaluations": engine.n_evaluations}


__all__ = ["AMPLITUDES", "Switch", "family_reach", "null_vector", "other_direction",
           "start_converges", "switch_start"]
