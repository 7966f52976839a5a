"""Continuation through a grazing of a hybrid periodic orbit (the normal-form tangent).

At a grazing the return map ``P`` is continuous but not differentiable: an orbit that misses the
surface by ``H_min > 0`` has the smooth map ``P_ns``; one that reaches ``H_min < 0`` (free flight
continued through the wall) impacts with ``|v| = sqrt(-2 a H_min)`` and, to leading order
(Nordmark's discontinuity map),

    P_imp(x) = P_ns(x) + u |v(x)| + O(v^2),      u = Phi_tail (-W(x_g)),                (G1)

where ``W`` is the jump of the impact law ``R = x + W v`` (eq. 5) per unit normal velocity and
``Phi_tail`` the sensitivity of the return to the section from the grazing point ``x_g``. The
square-root singularity lives in ``|v|`` as a function of the state, not in the branch: on the
impacting side the branch is smooth in ``|v|``, and differentiating ``G_ns(y) + u |v| = 0``,
``-H_min(y) = v^2 / (2a)`` at ``v = 0`` gives its one-sided tangent ``t`` and ``kappa = d|v|/ds``:

    [ G_ns,y   u ] [ t     ]
    [ -grad H_min^T   0 ] [ kappa ] = 0,      kappa > 0,                                (G2)

(the branch leaves tangent to the grazing manifold ``H_min = 0``). The non-impacting side is the
null vector of ``G_ns,y`` oriented with ``grad H_min . t > 0``. The branch at a grazing may go
on to the other side of the parameter (persistence) or turn back (a nonsmooth fold, e.g. the
undamped impact oscillator, :mod:`tests.test_grazing`); (G2) says which, with no search.

Everything is exact: ``G_ns,y`` and ``grad H_min = H_x J(t_g)`` (``dH/dt = v = 0`` at the turn)
come from the saltation-chained sensitivities of one simulation, ``Phi_tail`` from one more from
``x_g`` to the section.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nsm_continuation.hybrid.return_map import HybridShooting, ShootingFailure
from nsm_continuation.hybrid.simulate import SimResult, SimulationError

#: how far (relative) the evaluation point of ``G_ns`` may be moved off the located grazing
#: point to the non-impacting side: G_ns,y is smooth, the move changes it by O(delta)
MAX_NUDGE = 1e-7


def grazing_approach(res: SimResult) -> int | None:
    """Index in ``res.events`` of the near approach closest to the surface (the grazing one):
    an event recording ``H`` at a turn of ``v`` (``near_approach``, or the turn that breaks off
    a chattering sequence)."""
    near = [(ev.info["H"], k) for k, ev in enumerate(res.events) if "H" in ev.info]
    return min(near)[1] if near else None


def grazing_contacts(res: SimResult, floor: float = 0.0, factor: float = 1.5) -> int:
    """How many contacts graze together: the signed grazing margins of ``res`` (near
    approaches and decelerating impacts) within ``factor`` times the smallest one in
    magnitude, or below ``floor`` (at the grazing point itself, where they are all at the
    level of the integration error). One for a generic grazing; two or more where several
    approaches reach the surface at once (e.g. both walls of a symmetric orbit), where the
    single-grazing normal form (G1-G2) does not describe the branch beyond."""
    m = np.abs(np.asarray(res.grazing_margins, dtype=float))
    m = m[np.isfinite(m)]
    if not m.size:
        return 0
    return int(np.sum(m <= factor * float(m.min()) + floor))


def _non_impacting_point(sh: HybridShooting, y: np.ndarray, tangent: np.ndarray
                         ) -> tuple[np.ndarray, SimResult] | None:
    """``y``, or a point within ``MAX_NUDGE`` of it along ``+-tangent``, whose orbit misses the
    surface at the grazing approach (``grazing_function > 0``)."""
    scale = 1.0 + float(np.linalg.norm(y))
    for delta in (0.0, *np.geomspace(1e-12, MAX_NUDGE, 11)):
        for sign in ((1.0,) if delta == 0.0 else (-1.0, 1.0)):
            yt = y + sign * delta * scale * tangent
            try:
                res = sh.simulate(yt)
            except ShootingFailure:
                continue
            if res.grazing_function() > 0 and grazing_approach(res) is not None:
                return yt, res
    return None


@dataclass
class NormalForm:
    """The two one-sided tangents at a grazing point (eq. G2) and what the corrector needs."""

    #: unit tangent into the impacting side, and ``kappa = d|v|/ds`` along it
    impacting: np.ndarray
    kappa: float
    #: unit tangent into the non-impacting side
    free: np.ndarray
    #: gradient of ``H_min`` with respect to the unknowns, and ``a = L_F^2 H`` at the touch
    grad_h: np.ndarray
    a: float


def normal_form(sh: HybridShooting, y: np.ndarray, tangent: np.ndarray) -> NormalForm | None:
    """Eqs. (G1)-(G2) at the grazing point ``y`` (located; ``tangent``: the branch's direction
    there, used only to find a non-impacting evaluation point next to ``y``); None when the
    grazing cannot be resolved (no near approach next to ``y``, a failed simulation), and for
    a section crossed several times a period (the flow from the touch to the end of the period
    would need the crossings left after it, which the chained returns do not keep)."""
    if sh.section.crossings > 1:
        return None
    found = _non_impacting_point(sh, y, tangent)
    if found is None:
        return None
    yn, res = found
    c, sec = sh.c, sh.section
    fi = sh.free_idx
    cols = fi + list(range(c.n, c.N))
    try:
        _, Gy = sh.residual_jacobian(yn)
        ev = res.events[grazing_approach(res)]  # type: ignore[index]
        Xg = np.concatenate([ev.x, sh.x0(yn)[c.n:]])
        sf = c.surfaces[ev.surface]
        grad_h = (np.asarray(sf.grads(Xg), dtype=float)[0] @ ev.info["J"])[cols]
        tail = sh.sim.run(Xg, section=(sec.index, sec.value + sec.shift, sec.direction))
    except (ShootingFailure, SimulationError, np.linalg.LinAlgError):
        return None
    a = float(np.asarray(c.probe(Xg), dtype=float).ravel()[4 * ev.surface + 2])
    u = (tail.J @ (-np.asarray(sf.jump(Xg), dtype=float).ravel()))[fi]
    n = len(fi)
    A = np.zeros((n + 1, n + 2))
    A[:n, : n + 1] = Gy
    A[:n, n + 1] = u
    A[n, : n + 1] = -grad_h
    z = np.linalg.svd(A)[2][-1]
    z = z if z[-1] > 0 else -z
    norm = float(np.linalg.norm(z[: n + 1]))
    t_free = np.linalg.svd(Gy)[2][-1]
    t_free = t_free if grad_h @ t_free > 0 else -t_free
    return NormalForm(z[: n + 1] / norm, float(z[-1] / norm), t_free, grad_h, a)


def tangent_beyond(sh: HybridShooting, y: np.ndarray, tangent: np.ndarray,
                   from_impacting: bool) -> np.ndarray | None:
    """Unit tangent of the branch leaving the grazing point ``y`` on the side the branch did
    not come from (``from_impacting``: it arrived with the grazing impact, so it leaves without
    it), from (G1)-(G2); None when the grazing cannot be resolved."""
    nf = normal_form(sh, y, tangent)
    if nf is None:
        return None
    return nf.free if from_impacting else nf.impacting


def margin_gradient(sh: HybridShooting, y: np.ndarray) -> tuple[float, np.ndarray] | None:
    """The signed grazing margin closest to zero (``SimResult.grazing_function``) and its
    exact gradient with respect to the unknowns: ``H_x J`` at a near approach (``dH/dt = 0``
    there), ``-(v/a) v_x J + (v^2 / 2a^2) a_x J`` at an impact (``J`` including the impact
    time's dependence, eq. 40)."""
    try:
        res = sh.simulate(y)
    except ShootingFailure:
        return None
    c = sh.c
    cols = sh.free_idx + list(range(c.n, c.N))
    best: tuple[float, np.ndarray] | None = None
    for ev in res.events:
        if ev.info.get("J") is None:
            continue
        X = np.concatenate([ev.x, sh.x0(y)[c.n:]])
        if "H" in ev.info:  # a turn of v off the surface
            value = float(ev.info["H"])
            row = np.asarray(c.surfaces[ev.surface].grads(X), dtype=float)[0]
        elif "v" in ev.info and ev.info["a"] > 0:  # a decelerating impact
            v, a = float(ev.info["v"]), float(ev.info["a"])
            value = -v * v / (2 * a)
            gr = np.asarray(c.surfaces[ev.surface].grads(X), dtype=float)
            row = (-v / a) * gr[1] + (v * v / (2 * a * a)) * gr[2]
        else:
            continue
        if best is None or abs(value) < abs(best[0]):
            best = (value, (row @ ev.info["J"])[cols])
    return best


@dataclass
class _Iterate:
    """An iterate of :func:`solve_margin`: the grazing margin ``m`` and its gradient, the
    periodicity residual ``g`` and its Jacobian, and the system ``F = [g; m - target]``."""

    m: float
    dm: np.ndarray
    g: np.ndarray
    Gy: np.ndarray
    target: float

    @property
    def F(self) -> np.ndarray:
        return np.append(self.g, self.m - self.target)

    @property
    def J(self) -> np.ndarray:
        return np.vstack([self.Gy, self.dm])


#: smallest damping factor of a margin-fixed Newton step (:func:`solve_margin`)
MIN_DAMPING = 1e-4


def _damped_step(evaluate: Callable[[np.ndarray], _Iterate | None], z: np.ndarray,
                 cur: _Iterate, side: float, prior: tuple[float, float, np.ndarray] | None
                 ) -> tuple[float, np.ndarray, _Iterate, np.ndarray] | None:
    """One globalised Newton step on ``F = 0`` from ``z`` (:class:`_Iterate` ``cur``),
    damped by the natural monotonicity test (Deuflhard, *Newton Methods for Nonlinear
    Problems*, 2004, sec. 3.3, NLEQ-ERR): the trial ``z + lam dz`` passes when its simplified
    Newton correction ``dz_bar = -J(z)^{-1} F(z + lam dz)`` satisfies
    ``|dz_bar| <= (1 - lam/4) |dz|`` and, if ``z`` is on the side ``side`` of the kink (the
    sign of the margin), the trial stays there: the linearisation of one side says nothing
    of the other, and a step across the kink and back can cycle. A rejected ``lam`` is cut to
    the predicted ``lam^2 |dz| / (2 |dz_bar - (1 - lam) dz|)`` (between a tenth and a half of
    it). The first ``lam`` is 1, or after a damped step (``prior = (lam, |dz|, dz_bar)`` of
    it) the a-priori estimate ``lam |dz_prev| |dz_bar| / (|dz_bar - dz| |dz|)``, capped at 1.

    The level function ``|J^{-1} F|`` is invariant under a scaling of the equations. A merit
    such as ``|G| + |m - target|`` is not: next to a grazing it weighs the residual after a
    step (of the order of the error in the impact velocity ``|v|``, eq. G1: the step
    linearises ``|v| = sqrt(-2 a m)``) against the margin (of the order of ``v^2``), and it
    rejects every step but tiny ones once ``|v|`` is small, though Newton converges from the
    full step. Returns ``(lam, dz, trial, dz_bar)``, or None when no ``lam >= MIN_DAMPING``
    passes."""
    J = cur.J
    dz = np.linalg.solve(J, -cur.F)
    ndz = float(np.linalg.norm(dz))
    lam = 1.0
    if prior is not None and prior[0] < 1.0:
        lam_prev, ndz_prev, bar_prev = prior
        off = float(np.linalg.norm(bar_prev - dz)) * ndz
        if off > 0:
            lam = min(1.0, lam_prev * ndz_prev * float(np.linalg.norm(bar_prev)) / off)
        lam = max(lam, MIN_DAMPING)
    on_side = np.sign(cur.m) == side
    while lam >= MIN_DAMPING:
        trial = evaluate(z + lam * dz)
        if trial is None:
            lam *= 0.5
            continue
        dz_bar = np.linalg.solve(J, -trial.F)
        if not on_side or (np.sign(trial.m) == side
                           and np.linalg.norm(dz_bar) <= (1.0 - lam / 4.0) * ndz):
            return lam, dz, trial, dz_bar
        off = float(np.linalg.norm(dz_bar - (1.0 - lam) * dz))
        mu = 0.5 * lam * lam * ndz / off if off > 0 else 0.5 * lam
        lam = float(np.clip(mu, 0.1 * lam, 0.5 * lam))
    return None


def solve_margin(sh: HybridShooting, z: np.ndarray, target: float, tol: float,
                 max_iter: int = 30) -> np.ndarray | None:
    """Newton on ``F(y) = [G(y); m(y) - target]`` from ``z`` (``m`` the grazing margin
    closest to zero, :func:`margin_gradient`): the orbit of the branch whose grazing margin
    is ``target``. The margin's sign says on which side of the kink the solution lies (an
    impact when ``target < 0``). Each step is damped by the natural monotonicity test, which
    also keeps an iterate on that side once there (:func:`_damped_step`).

    Converged when ``|G| <= tol`` and ``|m - target| <= 1e-8 |target| + 1e-14``, or when the
    Newton correction falls below ``1e-11 (1 + |y|)`` with ``|G| <= 1e3 tol``: next to a
    grazing the residual's noise (the integration error times the ``1/|v|`` sensitivities)
    can exceed ``tol`` while the orbit is resolved."""
    def evaluate(zt: np.ndarray) -> _Iterate | None:
        mg = margin_gradient(sh, zt)
        if mg is None:
            return None
        try:
            g, Gy = sh.residual_jacobian(zt)
        except ShootingFailure:
            return None
        return _Iterate(mg[0], mg[1], g, Gy, target)

    side = float(np.sign(target))
    cur = evaluate(z)
    step = np.inf
    prior: tuple[float, float, np.ndarray] | None = None
    for _ in range(max_iter):
        if cur is None:
            return None
        res = float(np.abs(cur.g).max())
        if abs(cur.m - target) <= 1e-8 * abs(target) + 1e-14 and (
                res <= tol or (res <= 1e3 * tol and step <= 1e-11 * (1.0 + np.linalg.norm(z)))):
            return z
        try:
            out = _damped_step(evaluate, z, cur, side, prior)
        except np.linalg.LinAlgError:
            return None
        if out is None:
            return None
        lam, dz, cur, dz_bar = out
        step = float(lam * np.linalg.norm(dz))
        prior = (lam, float(np.linalg.norm(dz)), dz_bar)
        z = z + lam * dz
    return None


def _smooth_coordinate(m: float) -> float:
    """A coordinate in which the branch is smooth next to the grazing: ``m`` (the free
    side, ``H_min``) or ``-sqrt(-m)`` (the impacting side: ``|v| = sqrt(-2 a m)``)."""
    return m if m >= 0 else -np.sqrt(-m)


def _tangent_guess(sh: HybridShooting, y: np.ndarray, target: float) -> np.ndarray | None:
    """``y + ds t`` with ``t`` the branch's unit tangent at the orbit ``y`` (the null vector of
    ``G_y``) and ``ds`` the arclength at which the smooth coordinate ``w`` of the margin
    (:func:`_smooth_coordinate`, linear in the arclength on either side of the grazing)
    reaches its value at ``target``; None where that cannot be evaluated."""
    mg = margin_gradient(sh, y)
    try:
        _, Gy = sh.residual_jacobian(y)
    except ShootingFailure:
        return None
    if mg is None:
        return None
    m, grad_m = mg
    t = np.linalg.svd(Gy)[2][-1]
    dm = float(grad_m @ t)
    dw = dm if m >= 0 else dm / (2.0 * np.sqrt(-m))
    if dw == 0.0 or not np.isfinite(dw):
        return None
    return y + (_smooth_coordinate(target) - _smooth_coordinate(m)) / dw * t


#: a margin below this (relative to ``1 + |y|``) is within the integration error of ``H``
#: over one period (rtol 1e-10, atol 1e-12 by default): fixing it would chase noise
MARGIN_FLOOR = 1e-10


def locate_grazing(sh: HybridShooting, y: np.ndarray, tol: float, levels: int = 40,
                   path_out: list[np.ndarray] | None = None) -> np.ndarray | None:
    """The grazing point of the branch through ``y`` (a point near it on either side): a
    sequence of margin-fixed solves with the margin divided by 4 each time (the impacting
    side's ``|v|`` halves), predicted along the branch in the coordinate in which it is smooth
    (:func:`_smooth_coordinate`) down to ``MARGIN_FLOOR``, then extrapolated to the margin 0
    by the quadratic through the last three orbits (error ``O(w^3)``, ``w`` that coordinate:
    below 1e-14 in ``y``). Each solve is well conditioned (the ``1/|v|`` term of eq. G1 is
    cancelled by the margin's own gradient); the grazing point itself, where ``|v| = 0``, is
    never an iterate. The orbits solved on the way (the branch approaching the grazing, the
    margin falling fourfold each) are appended to ``path_out``.

    A solve that fails from that guess starts again from the last orbit moved along the
    branch's tangent there by the step that reaches the target in the smooth coordinate
    (:func:`_tangent_guess`): on the impacting side the orbit a quarter of the margin away
    lies where ``|v|`` is halved, a move of the order of ``|v|`` itself, and the ``1/|v|``
    terms of the Jacobian can leave Newton a basin smaller than the guess's error (a secant
    extrapolation of the next level can land off the branch by more than that basin)."""
    mg = margin_gradient(sh, y)
    if mg is None:
        return None
    z, m = y, mg[0]
    path: list[tuple[float, np.ndarray]] = []
    floor = MARGIN_FLOOR * (1.0 + float(np.linalg.norm(y)))
    for _ in range(levels):
        if abs(m) <= floor and len(path) >= 2:
            break
        target = m / 4.0
        w, wt = _smooth_coordinate(m), _smooth_coordinate(target)
        path.append((w, z))
        if len(path) >= 2:
            (w0, z0), (w1, z1) = path[-2:]
            guess = z1 + (z1 - z0) * (wt - w1) / (w1 - w0)
        else:
            guess = z
        zn = solve_margin(sh, guess, target, tol)
        if zn is None:
            retry = _tangent_guess(sh, z, target)
            zn = None if retry is None else solve_margin(sh, retry, target, tol)
        if zn is None:
            return None
        if path_out is not None:
            path_out.append(zn)
        z, m = zn, target
    path.append((_smooth_coordinate(m), z))
    (wa, za), (wb, zb), (wc, zc) = path[-3:]
    # Lagrange quadratic through the last three orbits, evaluated at w = 0
    la = wb * wc / ((wa - wb) * (wa - wc))
    lb = wa * wc / ((wb - wa) * (wb - wc))
    lc = wa * wb / ((wc - wa) * (wc - wb))
    return la * za + lb * zb + lc * zc


def step_beyond(sh: HybridShooting, y: np.ndarray, tangent: np.ndarray, from_impacting: bool,
                ds: float, tol: float = 1e-10) -> np.ndarray | None:
    """A point of the branch beyond the grazing point ``y``, at arclength about ``ds`` on the
    side it did not come from, or None.

    The corrector fixes the grazing margin instead of the arclength (:func:`solve_margin`) from
    the predictor ``y + ds t`` (``t`` from eq. G2), with ``m* = -(kappa ds)^2 / (2a)`` into the
    impacting side (``|v| = kappa ds``) and ``m* = (grad H_min . t) ds`` into the free one.
    Along the branch ``m`` is smooth and monotone in ``ds`` on each side, so the iterates stay
    on the intended side of the kink, where an arclength corrector oscillates across it (the
    impacting side's Jacobian has the ``1/|v|`` term of eq. G1, the free side's has not)."""
    nf = normal_form(sh, y, tangent)
    if nf is None:
        return None
    if from_impacting:
        t, target = nf.free, float(nf.grad_h @ nf.free) * ds
    else:
        t, target = nf.impacting, -((nf.kappa * ds) ** 2) / (2 * nf.a)
    z = y + ds * t
    # the tangent leaves along the grazing manifold (m = O(ds^2) on it, of either sign): move
    # the predictor across to the target margin along grad m, so that it lies on the intended
    # side with the intended impact velocity (second order in ds)
    mg = margin_gradient(sh, z)
    if mg is None:
        return None
    z = z - (mg[0] - target) * mg[1] / float(mg[1] @ mg[1])
    z = solve_margin(sh, z, target, tol)
    if z is None:
        return None
    res = sh.simulate(z)
    return z if (res.grazing_function() < 0) != from_impacting else None
