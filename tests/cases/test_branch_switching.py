"""Branch switching (``nsm_continuation/algorithms/switching.py``).

Oracles: closed forms (the transcritical ``x (mu - x) = 0`` and the pitchfork
``x (mu - x^2) = 0``; the chain at ``g = 0``, whose families are vertical at the roots of
``w_N`` with the shape ``(w(T*), 1)`` of Prop. 7.2) and, for the period-2 family of the two-mass
chain, a second method: an event-driven ``scipy`` integration of the equations of motion written
here (not the package's simulator) returns after two forcing periods and not after one, the
half-distance between the two section points vanishes at the flip found on the period-1 branch,
and the multipliers at the first switched point are the squares of the period-1 ones.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import CASES
from oracles.normal_forms import (
    LogisticMap,
    LogisticParameters,
    MuParameters,
    Pitchfork,
    Transcritical,
)
from scipy.integrate import solve_ivp

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.algorithms.switching import other_direction
from nsm_continuation.core.problem import Problem


# ------------------------------------------------------------------ closed-form test problems
def trivial_run(cls: type[Problem]) -> Any:
    problem = cls(MuParameters())
    return nsm.continuation(problem, {}, parameter="mu", min=-0.5, max=0.5, max_points=60,
                            step={"initial": 0.05, "min": 1e-9, "max": 0.05})


def test_other_direction_is_the_kernel_vector_orthogonal_to_the_arriving_one() -> None:
    """A matrix whose kernel is spanned by two known vectors: the direction returned is the
    unit kernel vector orthogonal to the given one; a regular matrix is refused."""
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=5), rng.normal(size=5)
    basis = np.linalg.qr(np.column_stack([a, b, rng.normal(size=(5, 3))]))[0]
    J = rng.normal(size=(4, 3)) @ basis[:, 2:].T  # 4 x 5, kernel span(a, b)
    t1 = a / np.linalg.norm(a)
    w, ratio = other_direction(J, t1)
    assert ratio < 1e-14
    assert abs(w @ t1) < 1e-12 and np.linalg.norm(J @ w) < 1e-12
    assert abs(np.linalg.norm(w) - 1) < 1e-14
    with pytest.raises(ValueError, match="not singular"):
        other_direction(rng.normal(size=(4, 5)), t1)


@pytest.mark.parametrize(("cls", "other"), [(Transcritical, lambda mu: mu),
                                            (Pitchfork, None)])
def test_switch_follows_the_closed_form_other_branch(cls: type[Problem], other: Any) -> None:
    """The branch point of the trivial branch is located at mu = 0; the switched branch is
    ``x = mu`` (transcritical, on both sides of 0) or ``mu = x^2`` (pitchfork, both signs of
    x) at every point, and crosses the trivial branch at the origin again."""
    run = trivial_run(cls)
    [bp] = [e for e in run.events if e.kind == "branch_point"]
    assert abs(bp.parameter) < 1e-10
    switched = run.restart(event="branch_point", switch=True, max_points=30)
    branch = switched.branches[0]
    x, mu = branch.y[:, 0], branch.y[:, 1]
    if other is not None:
        assert np.max(np.abs(x - other(mu))) < 1e-12
        assert mu.min() < -0.2 and mu.max() > 0.2
    else:
        assert np.max(np.abs(mu - x**2)) < 1e-12
        assert x.min() < -0.2 and x.max() > 0.2
    # through the origin again: a branch point of x = mu (located to 1e-12), the fold of
    # mu = x^2 (located where the corrector is singular: only to ~ sqrt of its accuracy)
    crossing = [e for e in switched.events if e.kind in ("branch_point", "fold")]
    assert len(crossing) == 1
    assert np.hypot(*crossing[0].point.y) < (1e-10 if other is not None else 1e-3)
    assert switched.run_result.branches[0].info["switch"] == "branch_point"


# ------------------------------------------------------------------ the chain at g = 0
def test_chain_static_grazing_branch_point_gives_the_vertical_family(tmp_path: Path,
                                                                    write_case: Any) -> None:
    """Fig. 7.3 (g = 0): the trivial branch has a branch point at each root of w_N; the
    switched branch (a YAML case from the saved run) is the vertical family of Prop. 7.2: T
    equal to the closed-form root at every point, (u(0), u_c'(0+)) proportional to
    (w(T*), 1), on both sides of u = 0."""
    base = nsm.run(CASES / "ndof_fig7_3_static_grazing.yaml",
                   {"continuation.min": 1.55, "continuation.max": 1.7, "output.plots": False,
                    "output.progress": False})
    base.save(tmp_path / "g0", plots=False)
    bps = [e for e in base.events if e.kind == "branch_point"]
    assert len(bps) == 3
    case = write_case({
        "start": {"from": str(tmp_path / "g0"), "event": {"kind": "branch_point", "index": 1},
                  "switch": True},
        "continuation": {"max_points": 15}, "output": {"plots": False, "progress": False}},
        "switch.yaml")
    out = tmp_path / "vertical"
    assert cli.main(["run", str(case), "--out", str(out), "--quiet"]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["branches"][0]["info"]["switch"] == "branch_point"
    pr = base.problem
    T_star = pr.polish_root(bps[1].parameter)
    assert abs(pr.w_N(T_star)) < 1e-12
    with open(out / "branch_0.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    ys = np.array([[float(r[f"y_{v}"]) for v in pr.variables] for r in rows])
    assert len(ys) == 29
    assert np.max(np.abs(ys[:, -1] - T_star)) < 1e-10
    shape = np.append(pr.w_vector(T_star), 1.0)
    amplitude = ys[:, -2]  # u_c'(0+)
    assert amplitude.min() < 0 < amplitude.max()
    assert np.max(np.abs(ys[:, :-1] - np.outer(amplitude, shape))) < 1e-9


# ------------------------------------------------------------------ the two-mass chain's flip
TWO_MASS = {"m1": 1.0, "m2": 1.0, "k1": 1.0, "k2": 1.0, "c": 0.05, "F0": 0.5, "gap": 0.5,
            "restitution": 0.8}


def simulate(state: np.ndarray, omega: float, periods: int, phase: float = 0.0
             ) -> np.ndarray:
    """``(q1, q2, q1', q2')`` after ``periods`` forcing periods from ``state`` at forcing
    phase ``phase``: the equations of motion of the two-mass chain integrated with
    ``solve_ivp`` (DOP853), impacts ``q2 = gap`` located as terminal events, Newton's law
    applied there."""
    p = TWO_MASS

    def rhs(t: float, x: np.ndarray) -> list[float]:
        q1, q2, v1, v2 = x
        spring = p["k2"] * (q2 - q1)
        return [v1, v2, (-p["k1"] * q1 + spring + p["F0"] * np.cos(omega * t + phase)
                         - p["c"] * v1)
                / p["m1"], (-spring - p["c"] * v2) / p["m2"]]

    def wall(t: float, x: np.ndarray) -> float:
        return x[1] - p["gap"]

    wall.terminal, wall.direction = True, 1.0  # type: ignore[attr-defined]
    t, x, t_end = 0.0, np.array(state, dtype=float), periods * 2 * np.pi / omega
    while t < t_end:
        sol = solve_ivp(rhs, (t, t_end), x, method="DOP853", rtol=1e-12, atol=1e-13,
                        events=wall)
        t, x = float(sol.t[-1]), sol.y[:, -1].copy()
        if sol.status == 1:
            x[3] = -p["restitution"] * x[3]
            t += 1e-13 * t_end  # step off the wall
    return x


def test_period_doubling_switch_gives_genuine_period_two_orbits(flip_run: tuple[Any, Path]
                                                                ) -> None:
    res, folder = flip_run
    [pd] = [e for e in res.events if e.kind == "period_doubling"]
    omega_pd = pd.parameter
    assert omega_pd == pytest.approx(0.6927610, abs=1e-7)
    two = nsm.run({"start": {"from": str(folder), "event": "period_doubling", "switch": True},
                   "continuation": {"max_points": 6, "step": {"initial": 0.01, "max": 0.02}},
                   "output": {"plots": False}})
    br = two.run_result.branches[0]
    assert br.info["period_multiple"] == 2 and two.problem.returns == 2
    assert len(br.points) == 6 and not [e for e in two.events if e.kind == "fold"]
    # away from the flip (supercritical here: omega grows along the period-2 family)
    omegas = np.array([p.y[-1] for p in br.points])
    assert np.all(np.diff(omegas) > 0) and omegas[0] > omega_pd
    # the multipliers of the first period-2 orbit: the squares of the period-1 ones at the flip
    sq = np.sort_complex(pd.point.multipliers**2)
    m0 = np.sort_complex(br.points[0].multipliers)
    assert np.max(np.abs(m0 - sq)) < 5e-3
    # second method: an independent integration returns after 2 periods, not after 1
    half, shift = [], []
    for p in br.points:
        # the section state at the forcing phase of the point's chart (the section moves off
        # an impact that reaches it: Problem.rechart)
        z, omega, phase = p.y[:4], p.y[-1], (p.chart or {}).get("phase", 0.0)
        one, back = simulate(z, omega, 1, phase), simulate(z, omega, 2, phase)
        assert np.linalg.norm(back - z) < 1e-7
        assert np.linalg.norm(one - z) > 1e-3
        half.append(np.linalg.norm(one - z) / 2)
        shift.append(omega - omega_pd)
    # the period-2 family emanates from the flip: its two section points (half-distance d)
    # merge where d^2, a smooth function of omega, vanishes: at omega_pd of the period-1 run
    d2, dw = np.array(half) ** 2, np.array(shift)
    roots = np.roots(np.polyfit(dw, d2, 2))
    assert np.min(np.abs(roots)) < 1e-9 < dw[0] / 100


# ------------------------------------------------------------------ a map with declared hooks
def test_period_doubling_cascade_of_a_map_with_declared_hooks(tmp_path: Path,
                                                             monkeypatch: Any) -> None:
    """Fixed point -> period 2 (at r = 3) -> period 4 (at r = 1 + sqrt 6) -> its doubling at
    r_3, each switch from the saved folder of the previous run; the period-2 family is the
    closed form, the period-4 points return after 4 iterations and not after 2."""
    one = nsm.continuation(LogisticMap(LogisticParameters()), {}, parameter="r", min=2.8,
                           max=3.3, step={"initial": 0.02, "min": 1e-9, "max": 0.05},
                           max_points=60)
    [pd1] = [e for e in one.events if e.kind == "period_doubling"]
    assert abs(pd1.parameter - 3.0) < 1e-10
    one.save(tmp_path / "one", plots=False)

    from nsm_continuation.cases import registry

    real_get = registry.get  # the saved runs name the problem: make it known by name
    monkeypatch.setattr(registry, "get",
                        lambda name: LogisticMap if name == "test_logistic" else real_get(name))
    two = nsm.run({"start": {"from": str(tmp_path / "one"), "event": "period_doubling",
                             "switch": True},
                   "continuation": {"max": 3.5, "max_points": 300},
                   "analysis": {"max_multiplier_step": 0.1}, "output": {"plots": False}})
    two.save(tmp_path / "two", plots=False)
    four = nsm.run({"start": {"from": str(tmp_path / "two"), "event": "period_doubling",
                              "switch": "period_doubling"},
                    "continuation": {"max": 3.55, "max_points": 400},
                    "analysis": {"max_multiplier_step": 0.1}, "output": {"plots": False}})
    assert two.problem.k == 2 and four.problem.k == 4
    x, r = two.branches[0].y.T
    assert r.min() - 3.0 < 1e-6 and r.max() == pytest.approx(3.5)
    # the period-2 factor of f(f(x)) - x: r^2 x^2 - r (r + 1) x + (r + 1) = 0, whose roots
    # are the closed form above (well conditioned, unlike the square root near r = 3)
    assert np.max(np.abs(r**2 * x**2 - r * (r + 1) * x + (r + 1))) < 1e-12
    assert np.min(np.abs(x - (1 - 1 / r))) > 1e-6  # never the fixed point
    [pd2] = [e for e in two.events if e.kind == "period_doubling"]
    assert abs(pd2.parameter - (1 + np.sqrt(6))) < 1e-9
    x4, r4 = four.branches[0].y.T
    assert r4.min() - (1 + np.sqrt(6)) < 1e-5 and r4.max() == pytest.approx(3.55)
    # the next doubling of the cascade, r_3 = 3.5440903595519... (OEIS A086181)
    [pd4] = [e for e in four.events if e.kind == "period_doubling"]
    assert abs(pd4.parameter - 3.5440903595519) < 1e-9
    for xv, rv in zip(x4, r4, strict=True):
        orbit = [xv]
        for _ in range(4):
            orbit.append(rv * orbit[-1] * (1 - orbit[-1]))
        assert abs(orbit[4] - xv) < 1e-12 and abs(orbit[2] - xv) > 1e-6
