"""Krein collisions of a conservative family located on the pair's discriminant.

:meth:`CrossingLocator._locate_collision` locates where two multipliers of a symplectic
return map collide on the unit circle on ``d = (nu_1 - nu_2)^2`` (``lambda = rho e^{i nu}``),
computing only the pair (:meth:`NDofImpactProblem.multipliers_near`). Oracles: the dense
eigenvalues of the return map (:meth:`NDofImpactProblem.floquet_dense`) for the pair; the
engine's other method (bisection of the number of multipliers outside the circle, then
``|lambda| - 1``) for the events, which must be the same events at the same periods.
"""

from __future__ import annotations

import collections

import numpy as np
import pytest
from oracles.scaled_chain import closed_form_point, scaled_chain

from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.core.settings import ContinuationSettings


@pytest.mark.parametrize("n", [60, 200])
def test_multipliers_near_are_dense_eigenvalues(n: int) -> None:
    pb = scaled_chain(n)
    y, t = closed_form_point(pb, pb.T_lin[0] * 0.999)
    dense = np.asarray(pb.floquet_dense(y, t).multipliers)
    rng = np.random.default_rng(n)
    for i in rng.choice(dense.size, 4, replace=False):
        # the multiplier and its nearest neighbour, from guesses 1e-6 off
        j = int(np.argsort(np.abs(dense - dense[i]))[1])
        guess = dense[[i, j]] + 1e-6 * np.exp(2j * np.pi * rng.random(2))
        near = pb.multipliers_near(y, t, guess)
        assert near is not None
        assert np.abs(np.sort_complex(near) - np.sort_complex(dense[[i, j]])).max() <= 1e-9
    # small chains: the dense eigenvalues nearest to the guesses
    small = scaled_chain(5)
    ys, ts = closed_form_point(small, small.T_lin[0] * 0.999)
    m5 = np.asarray(small.floquet_dense(ys, ts).multipliers)
    assert np.array_equal(small.multipliers_near(ys, ts, m5[[1, 0]] + 1e-9), m5[[1, 0]])


def _run(n: int, points: int, discriminant: bool) -> object:
    pb = scaled_chain(n)
    st = ContinuationSettings(max_points=points, step_initial=1e-3, direction=-1,
                              stability_on_phantom=True)
    T = pb.T_lin[0] * (1 - 1e-4)
    u0, du0 = pb.closed_form(T)
    eng = ContinuationEngine(pb, st)
    if not discriminant:
        eng.crossings._locate_collision = lambda a, b: None  # the count's bisection only
    return pb, eng.run(StartPoint(pb.y_from_state(u0, du0, T), "b1", -1))


def test_collisions_on_the_discriminant_are_the_counts_events() -> None:
    pb, fast = _run(60, 45, True)
    _, slow = _run(60, 45, False)
    ev_f = [e for e in fast.events if e.kind != "endpoint"]
    ev_s = [e for e in slow.events if e.kind != "endpoint"]
    on = collections.Counter(e.data["located_on"] for e in ev_f)
    assert on["krein_discriminant"] >= 5
    assert [e.kind for e in ev_f] == [e.kind for e in ev_s]
    assert max(abs(a.point.y[-1] - b.point.y[-1]) for a, b in zip(ev_f, ev_s, strict=True)) \
        <= 1e-9
    for e in ev_f:
        if e.data["located_on"] != "krein_discriminant":
            continue
        # at the located point the dense eigenvalues hold a (nearly) double pair next to the
        # critical multiplier: far closer than the spacing of the 118 multipliers (~0.05)
        p = e.point
        dense = np.asarray(pb.floquet_dense(p.y, p.tangent).multipliers)
        lam = complex(e.data["critical_multiplier"][0] + 1j * e.data["critical_multiplier"][1])
        d = np.sort(np.abs(dense - lam))
        assert d[1] <= 1e-4 and d[2] >= 10 * d[1]


@pytest.mark.parametrize("root", [1e-7, 0.3, 1 - 3e-8])
def test_illinois_closes_the_bracket_with_dekker_steps(root: float) -> None:
    """:func:`nsm_continuation.core.roots.illinois` with ``close``: the zero of a smooth function
    (here with curvature, so that the secant approaches from one side) bracketed to ``tol``
    in a handful of evaluations, where the plain method creeps by halvings."""
    from nsm_continuation.core.roots import illinois

    def counted(calls: list[float]):  # noqa: ANN202 - a test helper
        def f(x: float) -> tuple[float, None]:
            calls.append(x)
            return (x - root) * (1.0 + 5.0 * x) + 0.3 * (x - root) ** 3, None
        return f

    tol = 1e-12
    fast: list[float] = []
    plain: list[float] = []
    f0 = counted([])(0.0)[0]
    f1 = counted([])(1.0)[0]
    x, _, width = illinois(counted(fast), 0.0, f0, 1.0, f1, tol, close=True)
    xp, _, width_p = illinois(counted(plain), 0.0, f0, 1.0, f1, tol)
    assert abs(x - root) <= tol and width <= tol
    assert abs(xp - root) <= tol and width_p <= tol
    assert len(fast) <= 12 and len(fast) < len(plain)
