"""Two-wall systems against their closed forms (``tests/oracles/two_wall.py``).

The symmetric two-impact orbits of the two-sided impact oscillator and of the impact damper,
their multipliers and bifurcations, in closed form (T5)-(T13), checked first against the oracle's
own independent event-driven simulator (exact linear flight, walls by root finding), then the
package's plugins ``problems/impacting/two_sided_oscillator.py`` and ``impact_damper.py``
against the closed form: states at the section, period and multipliers along continued
branches, for each way of declaring the two walls the hybrid layer accepts.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import msd
from nsm_continuation.problems.impacting.impact_damper import ImpactDamperProblem
from nsm_continuation.problems.impacting.two_sided_oscillator import TwoSidedOscillatorProblem
from oracles import two_wall as tw
from pydantic import ValidationError

import nsm_continuation as nsm
from nsm_continuation.cases import registry

#: the bundled cases' parameters (yaml_cases/two_sided_oscillator.yaml, impact_damper.yaml)
OSC = {"zeta": 0.05, "clearance": 0.5, "restitution": 0.6}
DAMPER = {"zeta": 0.0, "mass_ratio": 0.2, "clearance": 1.0, "restitution": 0.6}
PHASE = 0.3


def osc(p: dict[str, float] = OSC) -> tw.TwoWall:
    return tw.oscillator(p["zeta"], p["clearance"], p["restitution"])


def damper(p: dict[str, float] = DAMPER) -> tw.TwoWall:
    return tw.damper(p["zeta"], p["mass_ratio"], p["clearance"], p["restitution"])


DAMPED_DAMPER = {**DAMPER, "zeta": 0.05}
#: (system, omega, branch of (T6)) of physical orbits: stable and unstable, both branches,
#: damped and undamped
ORBITS = [(osc(), 1.3, -1), (osc(), 2.5, -1), (osc(), 2.5, 1), (osc(), 3.4, 1),
          (damper(), 1.5, -1), (damper(), 2.0, -1), (damper(), 3.0, -1), (damper(), 2.5, 1),
          (damper(DAMPED_DAMPER), 2.0, -1)]
IDS = [f"{s.name}-zeta{s.zeta}-{om}-{'+' if b > 0 else '-'}" for s, om, b in ORBITS]


# ------------------------------------------------------------- closed form vs simulator
@pytest.mark.parametrize("sys", [osc(), damper()], ids=["oscillator", "damper"])
def test_oracle_exponential_is_scipys(sys: tw.TwoWall) -> None:
    from scipy.linalg import expm

    for t in (1e-3, 0.7, 3.0, 12.0):
        E = expm(sys.A * t)
        assert np.abs(tw.expm(sys.A * t) - E).max() < 1e-13 * max(1.0, np.abs(E).max())


@pytest.mark.parametrize(("sys", "omega", "branch"), ORBITS, ids=IDS)
def test_closed_form_orbit_is_periodic_in_the_simulator(sys: tw.TwoWall, omega: float,
                                                        branch: int) -> None:
    o = tw.orbit(sys, omega, branch)
    assert o is not None and tw.admissible(o)
    x = tw.state_at(o, PHASE)
    xT, impacts = tw.period_map(sys, omega, PHASE, x)
    assert np.abs(xT - x).max() < 1e-9 * max(1.0, np.abs(x).max())      # ~1e-12 observed
    # one impact on each wall, half a period apart, at the closed form's phase and velocity
    assert [i.wall for i in impacts] in ([1, -1], [-1, 1])
    assert impacts[1].t - impacts[0].t == pytest.approx(np.pi / omega, abs=1e-9)
    upper = next(i for i in impacts if i.wall == 1)
    assert np.mod(omega * upper.t - o.phase + 1.0, 2 * np.pi) == pytest.approx(1.0, abs=1e-9)
    assert all(i.velocity == pytest.approx(o.velocity, abs=1e-9) for i in impacts)


@pytest.mark.parametrize(("sys", "omega", "branch"), ORBITS, ids=IDS)
def test_multipliers_are_those_of_the_simulated_period_map(sys: tw.TwoWall, omega: float,
                                                           branch: int) -> None:
    o = tw.orbit(sys, omega, branch)
    P = tw.fd_monodromy(sys, omega, PHASE, tw.state_at(o, PHASE))
    scale = max(1.0, np.abs(o.multipliers).max())
    assert msd(np.linalg.eigvals(P), o.multipliers) < 1e-6 * scale      # ~1e-9 observed


def test_oscillator_half_map_area_contraction() -> None:
    """``det M_h = e^2 exp(-2 zeta h)`` (T12): with a 2x2 half map a complex pair has modulus
    below 1, so the symmetric orbit has no Neimark-Sacker and no period doubling."""
    sys = osc()
    for omega in (1.3, 2.5, 3.4):
        for o in tw.orbits(sys, omega):
            det = np.linalg.det(o.half_map)
            assert det == pytest.approx(sys.e ** 2 * np.exp(-2 * sys.zeta * np.pi / omega),
                                        rel=1e-12)
    kinds = {k for k, _ in tw.expected_events(sys, 0.7, 4.0, points=300)}
    assert kinds <= {"fold", "branch_point", "grazing", "impact_velocity_vanishes"}


@pytest.mark.parametrize("sys", [osc(), damper(), damper(DAMPED_DAMPER)],
                         ids=["oscillator", "damper", "damped-damper"])
def test_velocity_vanishes_where_the_forced_response_touches_the_walls(sys: tw.TwoWall
                                                                       ) -> None:
    """The zero of the impact velocity (T7) along the family is (T9), ``sqrt(3)`` undamped
    with ``w = 1/2``."""
    events = tw.family_events(sys, 1.2, 2.6, points=200)
    found = [ev.omega for ev in events if ev.kind == "impact_velocity_vanishes"]
    closed = [om for om in tw.velocity_vanishing_frequencies(sys.zeta, sys.w) if 1.2 < om < 2.6]
    assert len(found) == len(closed) == 1
    assert found[0] == pytest.approx(closed[0], abs=1e-10)
    if sys.zeta == 0.0:
        assert found[0] == pytest.approx(np.sqrt(3.0), abs=1e-10)


@pytest.mark.parametrize(("mu", "e"), [(0.05, 0.3), (1.0, 0.8)])
def test_damper_velocity_vanishes_at_sqrt3_for_any_mass_ratio_and_restitution(
        mu: float, e: float) -> None:
    sys = tw.damper(0.0, mu, 1.0, e)
    branch = [o for o in (tw.orbit(sys, om, 1) for om in (np.sqrt(3) - 1e-3, np.sqrt(3) + 1e-3))]
    assert all(o is not None for o in branch)
    assert branch[0].velocity * branch[1].velocity < 0   # (T7) changes sign at sqrt(3)


def _monodromy_eigenvalues(sys: tw.TwoWall, omega: float, branch: int) -> np.ndarray:
    o = tw.orbit(sys, omega, branch)
    return np.linalg.eigvals(tw.fd_monodromy(sys, omega, PHASE, tw.state_at(o, PHASE)))


@pytest.fixture(scope="module")
def damper_events() -> list[tw.Event]:
    return tw.family_events(damper(), 1.1, 4.0, points=400)


def test_damper_events_are_those_of_the_simulated_period_map(damper_events) -> None:
    """Each located bifurcation of the closed form is one of the simulator's period map: at a
    fold and a pitchfork it has the multiplier 1, at a Neimark-Sacker a complex pair on the
    circle (finite differences, 1e-5); the family turns at the fold only."""
    kinds = [ev.kind for ev in damper_events]
    assert {"fold", "branch_point", "neimark_sacker"} <= set(kinds)
    for ev in damper_events:
        if ev.kind == "fold":
            o = tw.orbit(damper(), ev.omega - 1e-12, 1)   # lambda - 1 ~ sqrt(distance)
            assert np.abs(o.half_eigenvalues - 1.0).min() < 1e-4     # (T13): lambda = +1
            mu = _monodromy_eigenvalues(damper(), ev.omega - 1e-12, 1)
            assert np.abs(mu - 1.0).min() < 1e-4
            assert tw.fold_function(damper(), ev.omega + 1e-6) < 0 < tw.fold_function(
                damper(), ev.omega - 1e-6)
        elif ev.kind == "branch_point":
            mu = _monodromy_eigenvalues(damper(), ev.omega, ev.branch)
            assert np.abs(mu - 1.0).min() < 1e-5
            assert all(tw.orbit(damper(), ev.omega + s, ev.branch) is not None
                       for s in (-1e-4, 1e-4))                       # no turn of omega
        elif ev.kind == "neimark_sacker":
            mu = _monodromy_eigenvalues(damper(), ev.omega, ev.branch)
            on_circle = mu[np.abs(np.abs(mu) - 1.0) < 1e-5]
            assert on_circle.size == 2 and np.abs(on_circle.imag).min() > 1e-3   # a pair


def test_grazing_ends_the_physical_family(damper_events) -> None:
    """At the located interior grazing the simulator sees the flight touch a wall: 1e-4 on the
    physical side the closed-form orbit returns after one period with two impacts, 1e-4 beyond
    it the same construction crosses a wall in flight (a third impact) and does not return."""
    sys = damper()
    ev = next(e for e in damper_events if e.kind == "grazing")
    o = tw.orbit(sys, ev.omega, ev.branch)
    assert abs(tw.grazing_margin(o)) < 1e-9
    side = 1.0 if tw.grazing_margin(tw.orbit(sys, ev.omega + 1e-4, ev.branch)) > 0 else -1.0
    for omega, physical in ((ev.omega + side * 1e-4, True), (ev.omega - side * 1e-4, False)):
        o = tw.orbit(sys, omega, ev.branch)
        x = tw.state_at(o, o.phase + 0.01)               # just after the upper impact
        xT, impacts = tw.period_map(sys, omega, o.phase + 0.01, x)
        assert (len(impacts) == 2) is physical
        assert bool(np.abs(xT - x).max() < 1e-9) is physical


# ------------------------------------------------------------- the package's plugins
#: the two walls as two constraints, or as one whose zero set is both
ENCODINGS = ["surfaces", "single"]


def test_registered() -> None:
    assert registry.get("two_sided_oscillator") is TwoSidedOscillatorProblem
    assert registry.get("impact_damper") is ImpactDamperProblem


@pytest.mark.parametrize(("cls", "field", "value"), [
    (TwoSidedOscillatorProblem, "clearance", 0.0), (TwoSidedOscillatorProblem, "restitution", 1.0),
    (TwoSidedOscillatorProblem, "encoding", "both"), (ImpactDamperProblem, "mass_ratio", 0.0),
    (ImpactDamperProblem, "clearance", -1.0), (ImpactDamperProblem, "gap", 1.0)])
def test_parameters_name_the_field(cls, field: str, value) -> None:
    with pytest.raises(ValidationError) as err:
        cls({"encoding": "single", field: value})
    assert err.value.errors()[0]["loc"] == (field,)


def _problem(sys: tw.TwoWall, omega: float, encoding: str):
    common = {"zeta": sys.zeta, "omega": omega, "restitution": sys.e, "section_phase": PHASE,
              "encoding": encoding}
    if sys.name == "two_sided_oscillator":
        return TwoSidedOscillatorProblem({**common, "clearance": sys.w})
    return ImpactDamperProblem({**common, "mass_ratio": sys.extra["mu"], "clearance": 2 * sys.w})


#: (system, start omega, branch of (T6), window, the branches the run visits): the oscillator
#: through both pitchforks, the damper through its pitchfork and Neimark-Sacker, and round its
#: fold onto the other branch
RUNS = [(osc(), 2.0, -1, (1.1, 2.5), {-1}), (damper(), 2.0, -1, (1.8, 2.4), {-1}),
        (damper(), 3.6, -1, (3.55, 3.9), {-1, 1})]
RUN_IDS = ["oscillator-pitchforks", "damper-pitchfork-ns", "damper-fold"]


@pytest.mark.parametrize("encoding", ENCODINGS)
@pytest.mark.parametrize(("sys", "omega", "branch", "window", "visits"), RUNS, ids=RUN_IDS)
def test_continued_orbits_are_the_closed_form(sys: tw.TwoWall, omega: float, branch: int,
                                              window: tuple[float, float], visits: set[int],
                                              encoding: str) -> None:
    """Every point of a continuation with the package (its Python API) is a symmetric orbit
    of the closed form: its state at the point's section phase to 1e-9 (1e-11 over the
    distance of the nearest multiplier from 1 next to a fold or pitchfork), period ``2 pi /
    omega``, multipliers to 1e-8 (relative to the largest)."""
    pb = _problem(sys, omega, encoding)
    start = np.append(tw.state_at(tw.orbit(sys, omega, branch), PHASE), omega)
    res = nsm.continuation(pb, start, min=window[0], max=window[1], max_points=150,
                           newton_tol=1e-11)
    b = res.branches[0]
    names = pb.variables[:-1]
    assert len(b) > 20
    assert all(t.startswith("bound: omega") for t in b.termination.values()), b.termination
    branches = set()
    for i in range(len(b)):
        om = b["omega"][i]
        y = np.array([b[f"y_{n}"][i] for n in names])
        dist, o = min(((np.abs(tw.state_at(o, b["section_phase"][i]) - y).max(), o)
                       for o in tw.orbits(sys, om)), key=lambda t: t[0])
        branches.add(o.branch)
        # a fixed point's error is the period map's (integration, ~1e-12) over the distance of
        # the multipliers from 1: 1e-9 but within 1e-2 of a fold or pitchfork (~1e-9 at 1e-3)
        gap = np.abs(o.multipliers - 1.0).min()
        assert dist * min(1.0, 100 * gap) < 1e-9, (
            f"omega = {om}: state {y} is {dist:.2e} from the closed form ({gap:.1e} from 1)")
        assert b["period"][i] == pytest.approx(2 * np.pi / om, rel=1e-12)
        mu = np.asarray(b.multipliers[i])
        scale = max(1.0, np.abs(o.multipliers).max())
        assert msd(mu, o.multipliers) < 1e-8 * scale, f"omega = {om}: {mu} vs {o.multipliers}"
    assert branches == visits


@pytest.mark.parametrize(("cls", "params", "sys"), [
    (ImpactDamperProblem, {}, damper()), (ImpactDamperProblem, {"zeta": 0.05},
                                          damper(DAMPED_DAMPER)),
    (TwoSidedOscillatorProblem, {}, osc())], ids=["damper", "damped-damper", "oscillator"])
def test_default_start_settles_on_the_symmetric_orbit(cls, params: dict[str, float],
                                                      sys: tw.TwoWall) -> None:
    """From ``default_initial`` (the ball moving in the middle of its cavity; the oscillator at
    rest) a transient of 100 periods at the default omega = 2 ends on the stable symmetric
    orbit of the closed form."""
    pb = cls({"omega": 2.0, **params})
    res = nsm.continuation(pb, {"transient": 100}, min=1.99, max=2.01, max_points=3)
    b = res.branches[0]
    names = pb.variables[:-1]
    for i in range(len(b)):
        y = np.array([b[f"y_{n}"][i] for n in names])
        o = tw.orbit(sys, b["omega"][i], -1)
        assert np.abs(tw.state_at(o, b["section_phase"][i]) - y).max() < 1e-9
