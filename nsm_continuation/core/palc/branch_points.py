"""Branch points: a multiplier through +1 named fold or branch point, and a branch point located
where the corrector cannot converge.

**Fold or branch point** (:func:`plus_one_events`). A real multiplier through +1 makes
``G_z = P_z - I`` singular (``G = P(z, p) - z``, the return map's fixed points). Where ``G_z``
is regular the tangent is ``t_z = -G_z^{-1} G_p t_p`` and, with ``|t| = 1``,
``det[G_z G_p; t_z^T t_p] = det(G_z) / t_p``: at a +1 crossing ``det(G_z)`` changes sign, and
either the parameter turns (``t_p`` changes sign too: a limit point, the bordered determinant
keeps its sign) or it does not (the bordered determinant changes sign: a second curve crosses,
a transcritical point, or a symmetry-breaking pitchfork of a symmetric orbit). These are the
two test functions of AUTO-07p for periodic orbits (LP: the parameter component of the
normalised direction vector, ``FNLPBV`` returning ``FLDF`` in ``toolboxbv.f90`` / ``bvp.f90``;
BP: the determinant of the reduced Jacobian, ``FNBPBV``) and of MatCont (``limitcycle.m``:
the LPC test is ``v(end)``, the tangent's parameter component; BPC comes from a bordered
system of the Jacobian); BifurcationKit detects a fold on the parameter's monotony
(``detect_fold``) and calls a single real eigenvalue crossing (``δn_unstable = 1``,
``δn_imag = 0``) ``:bp`` in ``get_bifurcation_type``. Here the tangent test decides, because
it is the one that does not depend on the multipliers' accuracy: a +1 crossing that coincides
with a sign change of the tangent's parameter component is that fold (one event); in a
dissipative family one without a turn is a ``branch_point``, merged with the bordered
determinant's sign change of the same step into one event (with the crossing's multipliers
and its stability change). In a conservative family a pair colliding at +1 (a Krein
collision) stays a ``fold``: there the family turns in energy (a saddle-centre, measured on
the chain of Legrand et al. 2017: the energy has an extremum at each such collision of
Fig. 3.2, where their sec. 6.2 names it a fold) while the period does not, and the bordered
determinant of the chain's formulation keeps its sign. A +1 collision of a conservative
family where the bordered determinant does change sign in the same place is a symmetry-breaking
pitchfork (a second family crosses: the chain between two walls, ``problems/chain/two_walls``,
where its symmetric mode meets the one-wall mode), a ``branch_point``, merged as in a
dissipative family.

**Location where the corrector is blind** (:func:`stencil_zero`). At a simple branch point
``[G_y; t^T]`` is singular; near it the corrector's error is the residual's noise over the
smallest singular value ``~ c |sigma - sigma*|``. Within a zone around ``sigma*`` Newton does
not meet ``newton_tol`` (the impact damper's pitchfork with rtol 1e-10: no point within ~3e-7
of it), or meets it by chance on a point off the branch (its determinant of the wrong size,
even of the wrong sign): the Illinois iteration, which steps round the trial points that fail
(:func:`~nsm_continuation.core.roots.illinois`), ends with a bracket covering that zone, or
inside it on a point off the branch (measured before the failed points were stepped round:
2.6e-7 off with a bracket of 5e-14). The test function is analytic on both sides, so its zero
is also found from resolved points away from it: the cubic through the determinant at four
corrected points ``c + r (-2, -1, 1, 2)`` (``c`` the iteration's location, ``r = h / 16``, at
least 8 widths of the zone where trial points failed) and the cubic through ``c + r (-1,
-1/2, 1/2, 1)``; the first is the location, the distance between the two its accuracy (the
truncation ``~ r^4`` and the points' noise, which decays like ``1 / |sigma - sigma*|``). Where
that accuracy reaches ``multiplier_event_tol`` and either beats the iteration's bracket or the
iteration's location differs from it by more than both accuracies, the interpolated zero is
the event, its point the cubic
interpolation of the four points (unknowns and tangent). The check is made only where a trial
point of the iteration failed: elsewhere the corrector resolved the zero, and the iteration's
point stands (the stencil, ``r`` wide, is then the less accurate of the two).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nsm_continuation.core.records import Event, Point

#: the stencil's half-width as a fraction of the step (then a quarter of it if a point of the
#: stencil cannot be corrected)
STENCIL_FRACTION = 1.0 / 16.0


@dataclass(frozen=True)
class StencilZero:
    """A zero located on a stencil of corrected points (:func:`stencil_zero`): its arclength
    from the step's start, the interpolated unknowns and unit tangent there, and its
    accuracy."""

    sigma: float
    y: np.ndarray
    tangent: np.ndarray
    accuracy: float


def stencil_zero(c: float, h: float, point_at: Callable[[float], Point | None],
                 value: Callable[[Point], float], sign_left: float,
                 min_half_width: float = 0.0) -> StencilZero | None:
    """The zero of a test function near arclength ``c`` of a step of length ``h`` from
    resolved points around it (module docstring): ``point_at(sigma)`` is the corrected point
    at arclength ``sigma`` (None where the corrector fails), ``value`` the test function,
    ``sign_left`` its sign before the zero; the stencil's half-width is ``h / 16``, at least
    ``min_half_width``. None where no stencil can be evaluated."""
    cache: dict[float, Point | None] = {}

    def at(sig: float) -> Point | None:
        if sig not in cache:
            cache[sig] = point_at(sig)
        return cache[sig]

    r = max(STENCIL_FRACTION * abs(h), min_half_width)
    for _ in range(2):
        wide = _stencil_zero(c, r, (-2.0, -1.0, 1.0, 2.0), at, value, sign_left)
        narrow = _stencil_zero(c, r, (-1.0, -0.5, 0.5, 1.0), at, value, sign_left)
        if wide is not None and narrow is not None:
            sigma, y, t = wide
            return StencilZero(sigma, y, t, abs(sigma - narrow[0]))
        r /= 4.0
    return None


def _stencil_zero(c: float, r: float, nodes: tuple[float, ...],
                  at: Callable[[float], Point | None], value: Callable[[Point], float],
                  sign_left: float) -> tuple[float, np.ndarray, np.ndarray] | None:
    """The zero of the cubic through the test function at ``c + r * nodes`` (two nodes on
    each side, the values with the signs of their sides) between the inner nodes, with the
    cubic interpolation of the unknowns and unit tangent there; None if a point cannot be
    corrected or the values do not change sign across ``c`` alone."""
    x = np.asarray(nodes, dtype=float)
    pts = [at(c + r * xi) for xi in x]
    if any(p is None for p in pts):
        return None
    v = np.array([value(p) for p in pts if p is not None])
    if not np.all(np.isfinite(v)) or np.any(np.sign(v) != np.where(x < 0, sign_left,
                                                                    -sign_left)):
        return None
    roots = np.roots(np.polyfit(x, v, len(x) - 1))
    inner = (x[x < 0].max(), x[x > 0].min())
    real = [z.real for z in roots if abs(z.imag) <= 1e-12 * max(1.0, abs(z))
            and inner[0] <= z.real <= inner[1]]
    if len(real) != 1:
        return None
    xs = real[0]
    # Lagrange weights of the nodes at xs
    w = np.array([np.prod([(xs - xk) / (xj - xk) for k, xk in enumerate(x) if k != j])
                  for j, xj in enumerate(x)])
    y = sum(wj * p.y for wj, p in zip(w, pts, strict=True) if p is not None)
    t = sum(wj * p.tangent for wj, p in zip(w, pts, strict=True) if p is not None)
    return c + r * xs, np.asarray(y, dtype=float), np.asarray(t) / np.linalg.norm(t)


def _coincident(ev: Event, others: list[Event]) -> Event | None:
    """The event of ``others`` located at the same point as ``ev`` (within round-off of the
    arclength, or twice either's bracket), if any."""
    return next((o for o in others if o is not ev and abs(ev.point.s - o.point.s) <= max(
        1e-8 * (1.0 + abs(o.point.s)), 2 * ev.bracket, 2 * o.bracket)), None)


#: the detail of a branch point found by a multiplier through +1
PLUS_ONE_BRANCH_POINT = ("a real multiplier crosses +1 where the parameter does not turn: two "
                         "solution curves cross (a symmetry-breaking pitchfork or a "
                         "transcritical point)")


def plus_one_events(events: list[Event], conservative: bool) -> list[Event]:
    """The events of one step with each multiplier crossing at +1 (a ``fold`` of the crossing
    locator, ``data['located_on']`` set) named as the module docstring says: merged into the
    limit point of the tangent test it coincides with; kept as a ``fold`` in a conservative
    family unless the bordered determinant changes sign there too; else a ``branch_point``,
    merged into the bordered determinant's branch point of the step (the nearest if several:
    the determinant's location is kept, the crossing's multiplier is read there, and its
    stability change is moved there)."""
    folds = [e for e in events if e.kind == "fold" and e.data.get("test") == "tangent"]
    points = [e for e in events if e.kind == "branch_point"
              and e.data.get("test") == "bordered_determinant"]
    out: list[Event] = []
    for ev in events:
        if ev.kind != "fold" or "located_on" not in ev.data or ev.data.get("test") == "tangent":
            out.append(ev)
            continue
        twin = _coincident(ev, folds)
        if twin is not None:
            twin.data.update({k: v for k, v in ev.data.items() if k != "test"})
            continue
        if conservative and _coincident(ev, points) is None:
            out.append(ev)  # a Krein collision at +1: the family turns in energy
            continue
        if not points:
            ev.kind, ev.detail = "branch_point", PLUS_ONE_BRANCH_POINT
            ev.data["test"] = "multiplier"
            out.append(ev)
            continue
        # the same point: where the parameter does not turn, a real multiplier through +1 is
        # what changes the determinant's sign (module docstring); its location is kept (the
        # crossing's, on |lambda_c| - 1, suffers the corrector's noise near the branch point
        # as the determinant's iteration does, without the resolved points' check)
        bp = min(points, key=lambda q: abs(q.point.s - ev.point.s))
        crossing = {k: v for k, v in ev.data.items() if k != "test"}
        crossing["located_on"] = "bordered_determinant"
        crossing.update(_critical_at(bp.point, ev.data.get("critical_multiplier")))
        bp.data.update(crossing)
        bp.detail = "simple branch point: det[G_y; t^T] changes sign and " + PLUS_ONE_BRANCH_POINT
        for e in events:  # the crossing's stability change sits at the branch point
            if e.kind == "stability_change" and e.point is ev.point:
                e.point, e.bracket = bp.point, bp.bracket
                e.data.update(crossing)
    return out


def _critical_at(p: Point, critical: list[float] | None) -> dict[str, object]:
    """The crossing multiplier at ``p`` (the one nearest to ``critical``, ``[re, im]``, where
    the crossing was located) and its distance to the circle there, as crossing data."""
    if critical is None or p.multipliers is None or not np.size(p.multipliers):
        return {}
    m = np.asarray(p.multipliers)
    lam = complex(m[int(np.argmin(np.abs(m - complex(*critical))))])
    return {"critical_multiplier": [lam.real, lam.imag], "modulus_minus_one": abs(lam) - 1.0}
