"""Several impact surfaces ``H_i >= 0`` in the hybrid layer, each with its own restitution.

Oracles: the closed-form free flight of the forced linear oscillator between impacts
(:mod:`tests.oracles.linear_flight`) with the impact times found by a bracketing root finder
(independent of the simulator); the same system declared with one smooth constraint whose
zero set is both stops (``H = d^2 - q^2``); the bouncing ball's geometric accumulation time;
momentum conservation and Newton's law for the impact law of eq. (58) with a mass matrix.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
import pytest
from nsm_continuation.problems.impacting.two_sided_oscillator import TwoSidedOscillatorProblem
from oracles.linear_flight import free_flight
from scipy.optimize import brentq

from nsm_continuation.hybrid.simulate import SimOptions, SimulationError, Simulator
from nsm_continuation.hybrid.system import HybridDeclarationError, HybridSystem

D, ZETA, E = 1.0, 0.05, 0.7


def two_sided(encoding: str, omega: float, d: float = D, e: float | tuple[float, float] = E,
              amp: float = 1.0) -> HybridSystem:
    """``q'' + 2 zeta q' + q = amp cos(phase)``, ``phase' = omega``, stops at ``q = +-d``:
    two surfaces (``upper``: ``d - q``, ``lower``: ``q + d``) or one constraint ``d^2 - q^2``."""
    q, qd, ph = ca.SX.sym("q"), ca.SX.sym("qd"), ca.SX.sym("phase")
    p = {"omega": ca.SX.sym("omega")}
    force = -q - 2 * ZETA * qd + amp * ca.cos(ph)
    if encoding == "surfaces":
        es = list(e) if isinstance(e, tuple) else e
        return HybridSystem.mechanical("two_sided", q, qd, p, ca.SX(1.0), force, [d - q, q + d],
                                       es, surfaces=["upper", "lower"], clock=ph,
                                       clock_rate=p["omega"])
    return HybridSystem.mechanical("two_sided", q, qd, p, ca.SX(1.0), force, d * d - q * q, e,
                                   clock=ph, clock_rate=p["omega"])


def oracle_impacts(x0: tuple[float, float], omega: float, t_end: float, e_up: float,
                   e_low: float) -> list[tuple[float, str, float]]:
    """Impact times, stops and pre-impact velocities from the closed-form flight: each flight
    sampled finely, the first sign change of ``d - q`` or ``q + d`` refined by ``brentq``."""
    t0, q0, v0 = 0.0, *x0
    out: list[tuple[float, str, float]] = []
    while True:
        ts = np.linspace(t0, t_end, int((t_end - t0) * 400) + 2)
        q, _ = free_flight(ts, t0, q0, v0, ZETA, omega)
        # the phase is omega t; the oracle's forcing cos(omega t) matches phase(0) = 0
        hit = None
        for name, g in (("upper", D - q), ("lower", q + D)):
            k = np.nonzero((g[1:] < 0) & (g[:-1] >= 0))[0]
            k = k[ts[k] > t0 + 1e-9]
            if k.size and (hit is None or ts[k[0]] < hit[0]):
                hit = (ts[k[0]], name, k[0])
        if hit is None:
            return out
        _, name, k = hit
        sign = 1.0 if name == "upper" else -1.0
        def gap(t: float, sign: float = sign, t0: float = t0, q0: float = q0,
                v0: float = v0) -> float:
            return D - sign * float(free_flight(np.array([t]), t0, q0, v0, ZETA, omega)[0][0])

        t_imp = brentq(gap, ts[k], ts[k + 1], xtol=1e-15, rtol=1e-15)
        qi, vi = (float(z[0]) for z in free_flight(np.array([t_imp]), t0, q0, v0, ZETA, omega))
        out.append((t_imp, name, vi))
        e = e_up if name == "upper" else e_low
        t0, q0, v0 = t_imp, sign * D, -e * vi


def oracle_margins(x0: tuple[float, float], omega: float, t_end: float, e: float
                   ) -> tuple[list[float], list[float]]:
    """The grazing margins of the closed-form flight (the impacts of :func:`oracle_impacts`):
    ``H`` at every turn of ``q`` between impacts (``D - q`` at a maximum, ``q + D`` at a
    minimum), and ``-v^2 / (2a)`` of every impact with ``a = d^2 H / dt^2 > 0``."""
    impacts = oracle_impacts(x0, omega, t_end, e, e)
    starts = [(0.0, *x0)] + [(t, D if s == "upper" else -D, -e * v) for t, s, v in impacts]
    ends = [t for t, _, _ in impacts] + [t_end]
    near = []
    for (t0, q0, v0), t1 in zip(starts, ends, strict=True):
        def vel(t: float, t0: float = t0, q0: float = q0, v0: float = v0) -> float:
            return float(free_flight(np.array([t]), t0, q0, v0, ZETA, omega)[1][0])

        ts = np.linspace(t0, t1, int((t1 - t0) * 400) + 2)
        v = free_flight(ts, t0, q0, v0, ZETA, omega)[1]
        for k in np.nonzero(v[1:] * v[:-1] < 0)[0]:
            tk = brentq(vel, ts[k], ts[k + 1], xtol=1e-15, rtol=1e-15)
            q = float(free_flight(np.array([tk]), t0, q0, v0, ZETA, omega)[0][0])
            near.append(D - q if v[k] > 0 else q + D)
    decelerating = []
    for t, stop, v in impacts:
        q = D if stop == "upper" else -D
        a = (-1.0 if stop == "upper" else 1.0) * (-q - 2 * ZETA * v + np.cos(omega * t))
        if a > 0:
            decelerating.append(-v * v / (2 * a))
    return near, decelerating


def test_grazing_margin_of_a_point_is_the_margin_closest_to_zero() -> None:
    """The ``grazing_margin`` of a point (a column of ``branch_<id>.csv``, and the event
    function whose zero is a grazing) is the signed margin closest to zero: over one period
    from ``(q, q') = (0.1, 0.4)`` the two-sided oscillator hits both stops (margins ``-v^2 /
    (2a)`` of order -1) and comes within ``H = 2.7e-3`` of a stop in between (closed form);
    the column is that ``H``, not the most negative impact margin."""
    omega, x0 = 1.3, (0.1, 0.4)
    near, decelerating = oracle_margins(x0, omega, 2 * np.pi / omega, E)
    closest = min([*near, *decelerating], key=abs)
    assert 0 < closest < 1e-2 and len(decelerating) == 2
    pb = TwoSidedOscillatorProblem({"zeta": ZETA, "clearance": D, "restitution": E,
                                    "omega": omega})
    values = pb.derived(np.array([*x0, omega]))
    assert values["grazing_margin"] == pytest.approx(closest, rel=1e-7)


@pytest.mark.parametrize("omega, x0, e", [(0.8, (0.3, 0.1), (0.5, 0.5)),
                                          (1.3, (0.0, 0.0), (0.7, 0.4))])
def test_impacts_on_two_stops_match_the_closed_form_flight(omega, x0, e) -> None:
    """Two stops with different restitutions, amplitude 2: every impact (time, stop, velocity)
    of 40 time units equals the closed-form flight's to 1e-9."""
    c = two_sided("surfaces", omega, e=e, amp=1.0).compile({"omega": omega})
    # the oracle's forcing has unit amplitude: use amp = 1 and a clearance it reaches
    res = Simulator(c, SimOptions()).run(np.array([*x0, 0.0]), t_end=40.0)
    want = oracle_impacts(x0, omega, 40.0, *e)
    got = [(ev.t, c.surfaces[ev.surface].name, ev.info["v"]) for ev in res.events
           if ev.kind == "impact"]
    assert len(got) == len(want) >= 10
    for (tg, ng, vg), (tw, nw, vw) in zip(got, want, strict=True):
        assert ng == nw
        assert tg == pytest.approx(tw, abs=1e-9)
        # v = dH/dt: -q' at the upper stop, q' at the lower one
        assert vg == pytest.approx(-vw if nw == "upper" else vw, abs=1e-9)
    assert res.signature.split() == [f"I({n})" for _, n, _ in want]


@pytest.mark.parametrize("omega, x0", [(0.8, (0.3, 0.1)), (1.3, (0.0, 0.0)), (2.1, (-0.5, 1.0))])
def test_two_surfaces_equal_one_constraint_with_both_stops(omega, x0) -> None:
    """The same system declared with two surfaces and with ``H = d^2 - q^2``: the same state,
    the same saltation-chained sensitivities and the same number of impacts after 60 time
    units (to 1e-10: the two encodings locate the events on different functions)."""
    out = {}
    for enc in ("surfaces", "single"):
        c = two_sided(enc, omega, amp=1.5).compile({"omega": omega})
        out[enc] = Simulator(c, SimOptions()).run(np.array([*x0, 0.0]), t_end=60.0)
    a, b = out["surfaces"], out["single"]
    assert a.n_impacts == b.n_impacts >= 10
    assert np.max(np.abs(a.X - b.X)) < 1e-10
    assert np.max(np.abs(a.J - b.J)) < 1e-9
    assert len(a.signature.split()) == len(b.signature)
    # the single constraint's impacts on the other stop are impacts, not a chattering sequence
    assert not any(ev.kind == "chatter" for ev in b.events)


def test_chattering_on_one_of_two_surfaces_completes_at_the_geometric_limit() -> None:
    """A ball under gravity between a floor (``q >= 0``) and a ceiling (``q <= 10``), dropped
    from ``h = 1``: complete chattering on the floor (``C(floor)``), its accumulation time
    ``t1 + 2 v1 e / (g (1 - e))`` (``t1 = sqrt(2h/g)``, ``v1 = g t1``) to 1e-9."""
    g, h, e = 9.81, 1.0, 0.5
    q, qd = ca.SX.sym("q"), ca.SX.sym("qd")
    p = {"g": ca.SX.sym("g")}
    sys = HybridSystem.mechanical("ball", q, qd, p, ca.SX(1.0), -p["g"], [q, 10.0 - q], e,
                                  surfaces=["floor", "ceiling"])
    res = Simulator(sys.compile({"g": g}), SimOptions()).run(np.array([h, 0.0]), t_end=2.0)
    t1 = np.sqrt(2 * h / g)
    chatter = [ev for ev in res.events if ev.kind == "chatter"]
    assert len(chatter) == 1 and chatter[0].surface == 0
    assert chatter[0].info["t_complete"] == pytest.approx(t1 + 2 * g * t1 * e / (g * (1 - e)),
                                                          abs=1e-9)
    assert res.signature == "C(floor)"
    assert res.X[0] == pytest.approx(0.0, abs=1e-12)


def test_impact_law_conserves_momentum_and_reverses_the_relative_velocity() -> None:
    """Impact damper (primary ``x``, ball ``y`` of mass ``mu``, cavity ``|y - x| <= d/2``):
    eq. (58) with ``M = diag(1, mu)`` keeps ``x' + mu y'`` and maps the relative velocity
    ``w = y' - x'`` to ``-e w``, on each wall with its own restitution."""
    mu, d = 0.3, 1.0
    x, y, xd, yd = (ca.SX.sym(k) for k in ("x", "y", "xd", "yd"))
    p = {"k": ca.SX.sym("k")}
    q, qd = ca.vertcat(x, y), ca.vertcat(xd, yd)
    sys = HybridSystem.mechanical("damper", q, qd, p, ca.diag(ca.vertcat(1.0, mu)),
                                  ca.vertcat(-p["k"] * x, 0.0), [d / 2 - (y - x), d / 2 + (y - x)],
                                  [0.6, 0.8], surfaces=["right", "left"])
    c = sys.compile({"k": 1.0})
    rng = np.random.default_rng(3)
    for surface, side, e in ((0, 1.0, 0.6), (1, -1.0, 0.8)):
        for _ in range(5):
            x0 = rng.normal()
            X = np.array([x0, x0 + side * d / 2, *rng.normal(size=2)])
            R = np.asarray(c.surfaces[surface].impact(X)[0], dtype=float).ravel()
            assert R[2] + mu * R[3] == pytest.approx(X[2] + mu * X[3], abs=1e-14)
            assert R[3] - R[2] == pytest.approx(-e * (X[3] - X[2]), abs=1e-14)
            assert np.array_equal(R[:2], X[:2])


def two_floors() -> Any:
    """Two uncoupled unit masses under gravity ``g = 1``, each above its own floor
    (surfaces ``floor_a``: ``q_1 >= 0``, ``floor_b``: ``q_2 >= 0``), compiled."""
    q, qd = ca.SX.sym("q", 2), ca.SX.sym("qd", 2)
    p = {"g": ca.SX.sym("g")}
    sys = HybridSystem.mechanical("pair", q, qd, p, ca.SX.eye(2), ca.vertcat(-p["g"], -p["g"]),
                                  [q[0], q[1]], 0.5, surfaces=["floor_a", "floor_b"])
    return sys.compile({"g": 1.0})


def test_simultaneous_impacts_are_refused_with_both_surfaces_named() -> None:
    """Two uncoupled masses falling onto their own floors from the same height hit at the same
    instant: no law is declared for that, so the simulation stops and names both."""
    with pytest.raises(SimulationError, match="simultaneous impacts on surface 'floor_a' and "
                                              "surface 'floor_b'"):
        Simulator(two_floors()).run(np.array([1.0, 1.0, 0.0, 0.0]), t_end=3.0)


def test_impact_while_sticking_on_another_surface_is_refused() -> None:
    """Mass a rests on its floor (sticking) while mass b falls onto its own: a contact with
    two surfaces at once, refused with both named (not silently penetrated)."""
    with pytest.raises(SimulationError, match="surface 'floor_b' .* while sticking on "
                                              "surface 'floor_a'"):
        Simulator(two_floors()).run(np.array([0.0, 1.0, 0.0, 0.0]), t_end=3.0)


def test_declarations_name_what_is_wrong() -> None:
    q, qd = ca.SX.sym("q"), ca.SX.sym("qd")
    p = {"d": ca.SX.sym("d")}
    with pytest.raises(HybridDeclarationError, match="uses fabs, which is not smooth"):
        HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q, p["d"] - ca.fabs(q), 0.5)
    with pytest.raises(HybridDeclarationError, match="uses fmin"):
        HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q,
                                ca.fmin(p["d"] - q, p["d"] + q), 0.5)
    with pytest.raises(HybridDeclarationError, match="3 restitutions for 2 surfaces"):
        HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q, [p["d"] - q, p["d"] + q],
                                [0.5, 0.5, 0.5])
    with pytest.raises(HybridDeclarationError, match="needs 2 distinct names"):
        HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q, [p["d"] - q, p["d"] + q], 0.5,
                                surfaces=["wall", "wall"])
    with pytest.raises(HybridDeclarationError, match="H of surface 'H2' does not depend"):
        HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q, [p["d"] - q, p["d"]], 0.5)
    with pytest.raises(HybridDeclarationError, match="a list of scalars"):
        HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q, ca.vertcat(q, -q), 0.5)
    # a column of constraints in the generic constructor, one W column per surface
    two = HybridSystem.mechanical("s", q, qd, p, ca.SX(1.0), -q, [p["d"] - q, p["d"] + q], 0.5)
    assert two.m == 2 and two.surface_names == ["H1", "H2"] and two.W.shape == (2, 2)


def test_grazing_margin_names_its_surface() -> None:
    """The grazing margin closest to zero is attributed to its surface: recomputed from the
    events (a turn of ``v`` off a surface: ``H`` there; an impact with ``a > 0``:
    ``-v^2 / (2a)``), each on the surface the event names."""
    c = two_sided("surfaces", 0.8, amp=1.5).compile({"omega": 0.8})
    res = Simulator(c, SimOptions()).run(np.array([0.3, 0.1, 0.0]), t_end=60.0)
    margins = []
    for ev in res.events:
        if "H" in ev.info:
            margins.append((float(ev.info["H"]), ev.surface))
        elif ev.kind == "impact" and ev.info["a"] > 0:
            margins.append((-ev.info["v"] ** 2 / (2 * ev.info["a"]), ev.surface))
    assert len(margins) == len(res.grazing_margins) >= 5
    assert {s for _, s in margins} == {0, 1}
    value, surface = min(margins, key=lambda m: abs(m[0]))
    assert res.grazing_surface() == ["upper", "lower"][surface]
    assert abs(value) == pytest.approx(min(abs(m) for m in res.grazing_margins), rel=1e-15)


def test_near_approach_of_one_surface_during_a_chattering_flight_on_another() -> None:
    """A ball thrown down from ``q = 0.2`` with the energy of a drop from ``h = 1`` onto a floor
    (``e = 0.5``) rises to ``e^2 h = 0.25`` below a ceiling at 0.3: the ceiling's near approach
    (``H = 0.05``) happens inside the floor's chattering flight (the extended state of sec.
    4.3), and its sensitivities are those of the state (``N x N``), not of the extended
    state."""
    q, qd = ca.SX.sym("q"), ca.SX.sym("qd")
    p = {"g": ca.SX.sym("g")}
    sys = HybridSystem.mechanical("ball", q, qd, p, ca.SX(1.0), -p["g"], [q, 0.3 - q], 0.5,
                                  surfaces=["floor", "ceiling"])
    c = sys.compile({"g": 9.81})
    res = Simulator(c, SimOptions()).run(np.array([0.2, -np.sqrt(2 * 9.81 * 0.8)]), t_end=0.5)
    near = [ev for ev in res.events if ev.kind == "near_approach"]
    assert len(near) == 1 and near[0].surface == 1
    assert near[0].info["H"] == pytest.approx(0.3 - 0.25, abs=1e-10)
    assert near[0].info["J"].shape == (c.N, c.N)
    assert res.grazing_surface() == "ceiling"


@pytest.mark.parametrize("omega, x0", [(0.8, (0.3, 0.1)), (1.3, (0.0, 0.0))])
def test_exact_flow_between_two_stops_equals_the_runge_kutta_flow(omega, x0) -> None:
    """The two-stop oscillator is linear between impacts: its exact modal flow
    (``method="exact"``) and DOP853 at rtol 1e-12 give the same impacts on the same surfaces,
    the same state and the same sensitivities after 60 time units (to 1e-11)."""
    out = {}
    for method in ("dop853", "exact"):
        c = two_sided("surfaces", omega, amp=1.5).compile({"omega": omega}, method=method)
        out[method] = Simulator(c, SimOptions(rtol=1e-12, atol=1e-14)).run(
            np.array([*x0, 0.0]), t_end=60.0)
    rk, exact = out["dop853"], out["exact"]
    assert rk.signature == exact.signature and rk.n_impacts >= 10
    assert np.max(np.abs(rk.X - exact.X)) < 1e-11
    assert np.max(np.abs(rk.J - exact.J)) < 1e-11
