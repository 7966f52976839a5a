"""The hybrid simulator's shortcuts give the numbers of the plain computation.

The simulator skips work whose outcome is known (an iteration cycle, a step Jacobian that an
event would discard, an interpolant of one sign, an extrapolation level already computed);
each shortcut is checked here against the computation it skips, written out plainly (the
oracles below), on the events of real simulations and on random data. The whole simulation is
checked against recorded values of the plain computation on this machine and against the
tight-tolerance reference of ``benchmarks/README.md`` (sec. 6.1 orbit, DOP853 at 1e-13).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem

from nsm_continuation.hybrid import hermite, transitions
from nsm_continuation.hybrid import simulate as sm
from nsm_continuation.hybrid.simulate import SimOptions, Simulator

Z61 = np.array([-1.140382778680, -3.665331476183, 0.233454455602])  # README reference orbit


def _problem(e: float) -> DoublePendulumProblem:
    pb = DoublePendulumProblem({"restitution": e})
    pb.set_parameter("restitution")
    return pb


def _run(pb: DoublePendulumProblem, opts: SimOptions | None = None) -> sm.SimResult:
    sh = pb.shooting
    s = sh.section
    sim = sh.sim if opts is None else Simulator(sh.c, opts)
    y = np.append(Z61, pb.values["restitution"])
    return sim.run(sh.x0(y), section=(s.index, s.value + s.shift, s.direction))


# ------------------------------------------------------------------ oracles (the plain code)
def plain_refine(sim: Simulator, key: str, Y: np.ndarray, dt: float, tau0: float, name: str,
                 idx: int, section: Any) -> tuple[float, np.ndarray, int]:
    """The event time by the safeguarded Newton iteration, every iteration evaluated (no cycle
    shortcut), g from the full step's outputs: ``(tau, state at tau, iterations run)``."""

    def gval(tau: float) -> tuple[float, float]:
        out = sim._step(key, Y, tau, False)
        if name == "section":
            return out[0][idx] - section[1], out[4][idx]
        return out[3][idx], out[3][idx + 1]

    lo, hi = 0.0, dt
    tau = tau0
    its = 0
    for _ in range(30):
        its += 1
        g, dg = gval(tau)
        if g == 0.0:
            break
        step = -g / dg if dg != 0.0 else 0.0
        new = tau + step
        if not (0.0 < new <= dt) or not np.isfinite(new):
            new = 0.5 * (tau + (lo if step < 0 else hi))
        if abs(new - tau) <= 4e-16 * max(1.0, tau) + 1e-300:
            tau = new
            break
        tau = new
    return tau, sim._step(key, Y, tau, False)[0], its


def plain_extrapolate(entries: list[Any], m: int) -> tuple[Any, ...]:
    """Richardson tableau of eq. (35), every level recomputed over the window."""
    vals = [e[0] for e in entries]
    jacs = [e[1] for e in entries]
    rs = [e[2] for e in entries]
    rjs = [e[3] for e in entries]
    for j in range(1, m):
        nv, nj = [], []
        for i in range(1, len(vals)):
            r = rs[i - 1]
            w = r ** (j + 1)
            nv.append((vals[i] - w * vals[i - 1]) / (1.0 - w))
            if jacs[i] is not None:
                dw = (j + 1) * r ** j * rjs[i - 1]
                nj.append((jacs[i] - w * jacs[i - 1]) / (1.0 - w) + np.outer(
                    (vals[i] - vals[i - 1]) / (1.0 - w) ** 2, dw))
            else:
                nj.append(None)
        vals, jacs = nv, nj
        rs, rjs = rs[1:], rjs[1:]
    return vals[-1], jacs[-1], vals[-2]


def plain_hermite_first_root(g0: float, d0: float, g1: float, d1: float, dt: float,
                             direction: int, floor: float = 0.0,
                             verify: Any = None) -> float | None:
    """The first crossing of the cubic Hermite interpolant, without the one-sign shortcut."""
    m0, m1 = d0 * dt, d1 * dt
    c0, c1 = g0, m0
    c2 = -3 * g0 - 2 * m0 + 3 * g1 - m1
    c3 = 2 * g0 + m0 - 2 * g1 + m1
    knots = [0.0]
    if c3 != 0.0:
        disc = c2 * c2 - 3 * c3 * c1
        if disc >= 0:
            sq = np.sqrt(disc)
            knots += sorted(s for s in ((-c2 - sq) / (3 * c3), (-c2 + sq) / (3 * c3))
                            if 0.0 < s < 1.0)
    elif c2 != 0.0:
        s = -c1 / (2 * c2)
        if 0.0 < s < 1.0:
            knots.append(s)
    knots.append(1.0)

    def p(s: float) -> float:
        return c0 + s * (c1 + s * (c2 + s * c3))

    vals = [p(s) for s in knots]
    vals[0] = g0 if g0 != 0.0 else (0.0 if m0 == 0 else np.sign(m0) * 1e-300)
    pairs = list(zip(knots, vals, strict=True))
    for (sa, va), (sb, vb) in zip(pairs[:-1], pairs[1:], strict=True):
        if direction < 0 and va > floor and vb <= -floor * (sb < 1.0) \
                or direction > 0 and va < -floor and vb >= floor * (sb < 1.0):
            if sb < 1.0 and verify is not None and not verify(sb, direction):
                continue
            lo, hi = sa, sb
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if (p(mid) > 0) == (direction < 0):
                    lo = mid
                else:
                    hi = mid
            return hi
    return None


# ------------------------------------------------------------------ event times
@pytest.fixture(scope="module")
def refine_calls() -> list[tuple[Any, ...]]:
    """Every event located in the simulation of the 6.1 orbit near the loss of sticking
    (e = 0.8944: 105 impacts, some event iterations jitter on round-off)."""
    pb = _problem(0.8944)
    sim = pb.shooting.sim
    calls: list[tuple[Any, ...]] = []
    orig = Simulator._refine

    def spy(self: Simulator, *args: Any) -> Any:
        out = orig(self, *args)
        calls.append((self, args, out))
        return out

    Simulator._refine = spy  # type: ignore[method-assign]
    try:
        _run(pb)
    finally:
        Simulator._refine = orig  # type: ignore[method-assign]
    assert sim is calls[0][0]
    return calls


def test_event_times_equal_the_plain_newton_iteration(refine_calls) -> None:
    limit = 0
    for sim, args, out in refine_calls:
        tau, Ye, its = plain_refine(sim, *args)
        assert out[0] == tau
        assert np.array_equal(out[1], Ye)
        limit += its == 30
    # the cycle shortcut was exercised: some iterations ran to the limit in the plain code
    assert limit >= 5
    assert len(refine_calls) > 200


class _JumpingProbe:
    """Stands for a probe-only step Function: ``g = -(next(tau) - tau)``, ``g' = 1``, so that
    Newton's update from ``tau`` is ``next(tau)`` (a made-up round-off jitter)."""

    def __init__(self, nxt: dict[float, float]) -> None:
        self.nxt = nxt
        self.calls = 0

    def flat(self, Y: np.ndarray, tau: float) -> np.ndarray:
        self.calls += 1
        out = np.zeros(4)
        out[0] = -(self.nxt[tau] - tau)
        out[1] = 1.0
        return out


def test_cycle_shortcut_on_a_made_up_jitter() -> None:
    """A Newton map that cycles through 3 values (round-off noise of g): the shortcut ends
    on the iterate the 30 plain iterations end on, for every entry point into the cycle."""
    pb = _problem(0.89)
    sim = pb.shooting.sim
    Y = pb.shooting.x0(np.append(Z61, 0.89))
    # dyadic values: tau + (next - tau) is next exactly
    cycle = [0.25, 0.25 + 2.0**-10, 0.25 + 3 * 2.0**-10]
    for start in range(len(cycle)):
        for pre in range(4):
            seq = [0.125 + k * 2.0**-8 for k in range(pre)] + cycle[start:] + cycle[:start]
            nxt = {seq[k]: seq[k + 1] if k + 1 < len(seq) else seq[pre] for k in
                   range(len(seq))}
            # a step Function whose probe makes Newton jump to the next value of the sequence
            fake = _JumpingProbe(nxt)
            real = sim.calls.steps["free"]
            sim.calls.steps["free"] = (real[0], real[1], fake)
            try:
                tau = sim._refine("free", Y, 1.0, seq[0], "H", 0, None)[0]
            finally:
                sim.calls.steps["free"] = real
            # the plain iteration: 30 steps along the sequence, then its cycle
            t = seq[0]
            for _ in range(30):
                t = nxt[t]
            assert tau == t
            assert fake.calls <= len(seq)  # each value evaluated once


# ------------------------------------------------------------------ chatter extrapolation
@pytest.mark.parametrize("m", [1, 2, 3, 4])
@pytest.mark.parametrize("sens", [True, False])
def test_memoised_extrapolation_equals_the_whole_tableau(m: int, sens: bool) -> None:
    rng = np.random.default_rng(10 * m + sens)
    N = 5
    for _ in range(40):
        seq: list[list[Any]] = []
        for _k in range(m + 1 + int(rng.integers(0, 6))):
            seq.append([rng.normal(size=N + 1),
                        rng.normal(size=(N + 1, N)) if sens else None,
                        float(rng.uniform(0.3, 0.97)),
                        rng.normal(size=N) if sens else None, {}])
            if len(seq) < m + 1:
                continue
            window = seq[-(m + 1):]
            got = transitions.extrapolate(window, m)
            ref = plain_extrapolate([tuple(e[:4]) for e in window], m)
            assert np.array_equal(got[0], ref[0]) and np.array_equal(got[2], ref[2])
            assert (got[1] is None) == (ref[1] is None)
            if sens:
                assert np.array_equal(got[1], ref[1])
            # entries without a memo (the benchmark's wrapper passes them through) work too
            bare = transitions.extrapolate([tuple(e[:4]) for e in window], m)
            assert np.array_equal(bare[0], ref[0])


# ------------------------------------------------------------------ interpolants and extremes
def test_quadratic_roots_are_numpy_roots_bitwise() -> None:
    rng = np.random.default_rng(3)
    for _ in range(5000):
        a, b, c = rng.normal(size=3) * 10.0 ** rng.uniform(-12, 4, size=3)
        if rng.random() < 0.1:
            b = 0.0
        ref, got = np.roots([a, b, c]), hermite.quadratic_roots(a, b, c)
        assert ref.dtype == got.dtype and np.array_equal(ref, got)


def _random_hermite(rng: np.random.Generator) -> tuple[float, float, float, float, float]:
    """Data of an interpolant, often near a tangency or a crossing (small values, dips)."""
    scale = 10.0 ** rng.uniform(-14, 1)
    g0, g1 = rng.normal(size=2) * scale
    if rng.random() < 0.3:
        g0 = abs(g0)
        g1 = abs(g1)
    if rng.random() < 0.1:
        g0 = 0.0
    dt = 10.0 ** rng.uniform(-8, 0)
    d0, d1 = rng.normal(size=2) * scale / dt * 10.0 ** rng.uniform(-3, 1)
    return float(g0), float(d0), float(g1), float(d1), float(dt)


def test_first_root_equals_the_plain_search() -> None:
    rng = np.random.default_rng(4)
    found = 0
    for _ in range(20000):
        g0, d0, g1, d1, dt = _random_hermite(rng)
        direction = int(rng.choice([-1, 1]))
        floor = 0.0 if rng.random() < 0.5 else 1e-13 * (1.0 + abs(g0) + abs(g1))
        # numpy scalars as the simulator's arrays give them, and Python floats
        args = (np.float64(g0), np.float64(d0), np.float64(g1), np.float64(d1), dt)
        ref = plain_hermite_first_root(*args, direction, floor)
        assert hermite.hermite_first_root(*args, direction, floor) == ref
        assert hermite.hermite_first_root(g0, d0, g1, d1, dt, direction, floor) == ref
        found += ref is not None
    assert found > 2000


def test_one_sign_interpolant_has_no_crossing_on_a_dense_grid() -> None:
    """Independent of the plain search: where the shortcut says 'one sign', the cubic has no
    zero on 2001 points of [0, 1] (evaluated in extended precision)."""
    rng = np.random.default_rng(5)
    s = np.linspace(0.0, 1.0, 2001, dtype=np.longdouble)
    hits = 0
    for _ in range(5000):
        g0, d0, g1, d1, dt = _random_hermite(rng)
        m0, m1 = d0 * dt, d1 * dt
        if not hermite.hermite_one_sign(g0, m0, g1, m1):
            continue
        hits += 1
        G0, G1, M0, M1 = (np.longdouble(v) for v in (g0, g1, m0, m1))
        p = (G0 * (2 * s**3 - 3 * s**2 + 1) + M0 * (s**3 - 2 * s**2 + s)
             + G1 * (-2 * s**3 + 3 * s**2) + M1 * (s**3 - s**2))
        assert np.all(p > 0) or np.all(p < 0)
    assert hits > 1000


# ------------------------------------------------------------------ whole simulations
def test_simulation_equals_the_recorded_values() -> None:
    """Values the simulator without shortcuts gives (recorded on this machine): the step counts
    exactly, the return time, sticking time, state and extremes to 1e-12, the multiplier to
    1e-9 (the rounding of the BLAS products of a 70-impact chain may differ on another
    machine)."""
    for e, T, tau, steps, impacts, counts, X, mu, psum, ext in (
            (0.89, 6.170196098831219, 0.24771450442884646, 279, 70, [69],
             [-4.71238898038469, -1.140382778746314, -3.665331475617608, 0.23345445610949306],
             -0.0007221344832578012, 0.004061320618900313,
             [[-4.71238898038469, 1.5707963267948966], [-1.1420884275588685, 1.1686147856284634],
              [-8.147761594478155, 1.0909892263976533], [-2.9067298229382463, 9.54995250091082]]),
            (0.8944, 6.1951513023109746, 0.018213243633131704, 350, 105, [104],
             [-4.71238898038469, -1.1403809720920208, -3.6653305159040164,
              0.2334598741623933], -0.00042548092285835896, 0.0023918506005379957,
             [[-4.71238898038469, 1.5707963267948966], [-1.1420867005524766, 1.1686147856284634],
              [-8.147761594478155, 1.0952640032467356], [-2.9067298229382463, 9.54995250091082]])):
        pb = _problem(e)
        # recorded with the step error test on the state alone (the sensitivities' own test
        # changes the steps, not the shortcuts)
        pb.shooting.sim.o = replace(pb.shooting.sim.o, sensitivity_error=False)
        res = _run(pb)
        assert (res.n_steps, res.n_impacts, res.chatter_counts, res.signature) == \
            (steps, impacts, counts, "CS")
        assert math.isclose(res.t, T, rel_tol=1e-12)
        assert math.isclose(res.sticking_time, tau, rel_tol=1e-12)
        np.testing.assert_allclose(res.X[:4], X, rtol=1e-12, atol=1e-13)
        # the extremes: interior ones (min q2, max q1dot) located inside steps
        np.testing.assert_allclose(res.extremes, ext, rtol=1e-12, atol=0)
        P = pb.shooting.poincare_jacobian(np.append(Z61, e))
        m = np.linalg.eigvals(P)
        got = m[np.argmax(np.abs(m))]
        assert abs(got.imag) == 0.0
        assert math.isclose(got.real, mu, rel_tol=1e-9)
        assert math.isclose(float(np.abs(P).sum()), psum, rel_tol=1e-9)


def test_simulation_against_the_tight_reference() -> None:
    """README reference (DOP853, rtol = atol = chatter_tol = 1e-13, order 4) of the 6.1 orbit:
    the default numerics' errors are 3.2e-9 s (T), 5.6e-9 s (tau), 1.2e-6 (mu, relative)."""
    pb = _problem(0.89)
    res = _run(pb)
    assert abs(res.t - 6.170196095481) < 1e-8
    assert abs(res.sticking_time - 0.247714498492) < 2e-8
    m = np.linalg.eigvals(pb.shooting.poincare_jacobian(np.append(Z61, 0.89)))
    mu = m[np.argmax(np.abs(m))]
    assert abs(mu - (-7.2213533550e-04)) / 7.2213533550e-04 < 1e-5


def test_trajectory_does_not_depend_on_the_sensitivities() -> None:
    """A step tried without its Jacobian and taken with it: the trajectory (every event, the
    end state and time) is the same with and without sensitivities, bit for bit."""
    pb = _problem(0.8944)
    # with the step error test on the state alone; the sensitivities' own test (the default)
    # shortens steps, so that the trajectory then agrees to the tolerance, not bit for bit
    base = replace(pb.integrator.options(), sensitivity_error=False)
    with_j = _run(pb, base)
    without = _run(pb, SimOptions(**{**base.__dict__, "sensitivities": False}))
    assert without.J is None and with_j.J is not None
    assert with_j.t == without.t and np.array_equal(with_j.X, without.X)
    assert with_j.n_steps == without.n_steps
    assert [(ev.kind, ev.t) for ev in with_j.events] == [(ev.kind, ev.t) for ev in
                                                         without.events]
    assert np.array_equal(with_j.extremes, without.extremes)
    controlled = _run(pb, pb.integrator.options())
    assert controlled.n_steps > with_j.n_steps
    assert abs(controlled.t - without.t) < 1e-8
    np.testing.assert_allclose(controlled.X, without.X, rtol=0, atol=1e-8)
