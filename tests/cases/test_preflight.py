"""Preflight of every problem: each bad input that can be recognised without computing
is refused with one line starting with the key (``start.mode: ...``, ``parameters.cells: ...``),
sizes whose memory or time estimate exceeds the limits are refused before anything large is
built, and every bundled case passes."""

from __future__ import annotations

import copy
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import ROOT
from nsm_continuation.problems.bar.continuum import BarContinuumProblem
from nsm_continuation.problems.bar.wfem_bar import WfemBarParameters, WfemBarProblem
from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem
from nsm_continuation.problems.impacting.double_pendulum import DoublePendulumProblem
from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem
from pydantic import ValidationError

from nsm_continuation import cases
from nsm_continuation.core.preflight import GAP_MAX, GAP_MIN, MEMORY_ENV, TIME_ENV

CASES = sorted((ROOT / "yaml_cases").glob("*.yaml"))

CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: T window of omega in [1, 2]
T_WINDOW = (np.pi, 2 * np.pi)
PENDULUM_GUESS = {"q2": -1.14038278, "q1dot": -3.66533148, "q2dot": 0.23345446}


def refused(fn: Any, *args: Any) -> str:
    """The one-line message of the ValueError ``fn(*args)`` raises."""
    with pytest.raises(ValueError) as info:
        fn(*args)
    msg = str(info.value)
    assert "\n" not in msg, msg
    return msg


def refused_case(raw: dict[str, Any]) -> str:
    """The message ``cases.validate`` refuses a raw case with (parameters, start schema)."""
    with pytest.raises(cases.CaseError) as info:
        cases.validate(raw)
    return str(info.value)


def case_of(name: str, **over: Any) -> dict[str, Any]:
    raw = cases.load_raw(ROOT / "yaml_cases" / name)
    for key, value in over.items():
        node = raw
        parts = key.split("__")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = copy.deepcopy(value)
    return raw


# ----------------------------------------------------------------------------- bundled cases
@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_bundled_case_passes_preflight_quickly(path: Path) -> None:
    """Every bundled case validates (construction + preflight) and its preflight (a sweep's:
    ``sweep_preflight``), called directly, accepts it; construction is cheap (< 1 s)."""
    raw = cases.load_raw(path)
    case, problem = cases.validate(raw)
    t0 = time.perf_counter()
    cls = type(problem)
    fresh = cls(cls.Parameters.model_validate(case.parameters))
    assert time.perf_counter() - t0 < 1.0
    c = case.continuation
    window = fresh.parameter_bounds(c.parameter, c.min, c.max)
    # a sweep's start block is checked by the problem's sweep preflight (brute-force cases)
    check = (fresh.sweep_preflight if (c.algorithm or fresh.algorithms[0]) == "sweep"
             else fresh.preflight)
    check(case.start, window, c.max_points)
    for name in c.bounds:
        assert name in fresh.monitor_names()


# ----------------------------------------------------------------------------- ndof_impact
def test_ndof_mode_beyond_n() -> None:
    msg = refused(NDofImpactProblem(CHAIN).preflight, {"mode": 9}, T_WINDOW, 400)
    assert msg.startswith("start.mode: 9 is beyond the 5 modes of the chain (1..5)"), msg
    msg = refused(NDofImpactProblem(CHAIN).preflight, [{"mode": 1}, {"mode": 6}], T_WINDOW, 400)
    assert msg.startswith("start[1].mode: "), msg


def test_ndof_start_outside_the_window() -> None:
    p = NDofImpactProblem(CHAIN)
    msg = refused(p.preflight, {"mode": 1, "subharmonic": 50}, T_WINDOW, 400)
    assert msg.startswith("start.subharmonic: the pole k T_j = 50 T_1"), msg
    msg = refused(p.preflight, {"T": 100.0}, T_WINDOW, 400)
    assert msg.startswith("start.T: "), msg
    msg = refused(p.preflight, {"all": True}, (None, 5.0), 400)
    assert msg.startswith("start.all: needs continuation.min and continuation.max"), msg
    p.preflight({"mode": 1}, T_WINDOW, 400)
    p.preflight({"all": True, "max_subharmonic": 10**9}, (0.5, 9.0), 2000)  # O(N), not O(kmax)


def test_ndof_mode_start_needs_a_gap() -> None:
    msg = refused(NDofImpactProblem({**CHAIN, "gap": 0.0}).preflight, {"mode": 1}, T_WINDOW, 10)
    assert msg.startswith("start.mode: "), msg


@pytest.mark.parametrize("gap", [1e-300, -1e-101, 1e101, 1e308])
def test_ndof_gap_outside_the_resolved_range(gap: float) -> None:
    raw = case_of("ndof_default.yaml", parameters__gap=gap)
    assert refused_case(raw).startswith("parameters.gap: ")


def test_ndof_gap_scale_invariance() -> None:
    """The model is linear in g (g != 0): the unknowns are in units of |g|, so the starts at
    gap 1e-100 (the smallest accepted) have the unknowns of gap 1, their physical state is
    1e-100 times it and they solve the residual; below, the energies (~g^2) leave the resolved
    range and the gap is refused (the whole branch: tests/chain/test_gap_scale_invariance.py)."""
    one = NDofImpactProblem(CHAIN)
    tiny = NDofImpactProblem({**CHAIN, "gap": GAP_MIN})
    NDofImpactProblem({**CHAIN, "gap": -GAP_MAX})
    with pytest.raises(ValidationError, match="outside"):
        NDofImpactProblem({**CHAIN, "gap": GAP_MIN / 10})
    for start in ({"mode": 1}, {"T": 4.0}):
        y1 = one.start_points(start, T_WINDOW)[0].y
        yt = tiny.start_points(start, T_WINDOW)[0].y
        np.testing.assert_allclose(yt, y1, rtol=1e-13)
        for a, b in zip(tiny.state(yt)[:2], one.state(y1)[:2], strict=True):
            np.testing.assert_allclose(a, GAP_MIN * b, rtol=1e-13)
        assert np.abs(tiny.evaluate(yt)).max() <= 1e-13
        assert tiny.derived(yt)["energy"] == pytest.approx(GAP_MIN**2 * one.derived(y1)["energy"],
                                                            rel=1e-12)


def test_ndof_huge_chain_refused_at_construction_without_allocating() -> None:
    t0 = time.perf_counter()
    for n in (10_000, 10**12):
        msg = refused(NDofImpactProblem, {"chain": {"dofs": n, "mass": 1.0, "stiffness": 1.0},
                                          "gap": 1.0})
        assert msg.startswith("parameters.chain.dofs: "), msg
        assert MEMORY_ENV in msg and "GB" in msg
    assert time.perf_counter() - t0 < 1.0
    raw = case_of("ndof_default.yaml", parameters__chain={"dofs": 10_000, "mass": 0.2,
                                                         "stiffness": 5.0})
    t0 = time.perf_counter()
    assert refused_case(raw).startswith("parameters.chain.dofs: ")
    assert time.perf_counter() - t0 < 1.0


def test_ndof_construction_is_lazy() -> None:
    t0 = time.perf_counter()
    p = NDofImpactProblem({"chain": {"dofs": 2000, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0})
    assert time.perf_counter() - t0 < 0.5
    assert "decomposition" not in p.modal.__dict__ and "matrices" not in p.modal.__dict__
    assert p.dim == 2002


def test_ndof_run_time_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    chain = {"chain": {"dofs": 1000, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0}
    msg = refused(NDofImpactProblem(chain).preflight, {"mode": 1}, (None, None), 400)
    assert msg.startswith("parameters.chain.dofs: 1000 dofs with continuation.max_points = 400")
    assert TIME_ENV in msg
    small = {"chain": {"dofs": 20, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0}
    NDofImpactProblem(small).preflight({"mode": 1}, (None, None), 400)
    monkeypatch.setenv(TIME_ENV, "1e-6")
    msg = refused(NDofImpactProblem(small).preflight, {"mode": 1}, (None, None), 400)
    assert msg.startswith("parameters.chain.dofs: ") and "limit is 1e-06 h" in msg
    monkeypatch.setenv(MEMORY_ENV, "1e-6")
    msg = refused(NDofImpactProblem, small)
    assert msg.startswith("parameters.chain.dofs: ") and "limit is 1e-06 GB" in msg
    monkeypatch.setenv(MEMORY_ENV, "lots")
    assert refused(NDofImpactProblem, small).startswith(f"{MEMORY_ENV}: 'lots'")


def test_ndof_unresolved_modal_analysis() -> None:
    p = NDofImpactProblem({"chain": {"dofs": 3, "mass": [1.0, 1e-12, 1.0], "stiffness": 1.0},
                           "gap": 1.0})
    msg = refused(p.preflight, {"mode": 1}, (None, None), 10)
    assert msg.startswith("parameters.chain: the linear frequencies span"), msg
    p = NDofImpactProblem({"chain": {"dofs": 3, "mass": 0.2, "stiffness": 1e308}, "gap": 1.0})
    assert refused(p.preflight, {"mode": 1}, (None, None), 10).startswith("parameters.chain: ")


@pytest.mark.parametrize("key, value, where", [
    ("parameters__chain__dofs", True, "parameters.chain.dofs"),
    ("parameters__chain__dofs", 5.0, "parameters.chain.dofs"),
    ("parameters__gap", True, "parameters.gap"),
    ("parameters__impacting_dof", True, "parameters.impacting_dof"),
    ("start", {"mode": True}, "start.mode"),
    ("start", {"T": 4.0, "direction": True}, "start.direction"),
    ("start", {"all": 1}, "start.all"),
    ("start", {"mode": 1, "subharmonic": False}, "start.subharmonic"),
])
def test_ndof_booleans_are_not_numbers(key: str, value: Any, where: str) -> None:
    msg = refused_case(case_of("ndof_default.yaml", **{key: value}))
    assert msg.startswith(f"{where}: "), msg


# ----------------------------------------------------------------------------- wfem_bar
def bar(**kw: Any) -> WfemBarProblem:
    return WfemBarProblem(WfemBarParameters(**{"cells": 40, "gap": 1e-3, **kw}))


def test_wfem_node_of_the_wrong_length() -> None:
    msg = refused(bar().preflight, {"node": [1, 2, 3]}, (0.5, 0.7), 500)
    assert msg.startswith("start.node: [1, 2, 3] has 3 entries"), msg
    msg = refused(bar().preflight, [{"branch": "main"}, {"node": [5]}], (None, None), 500)
    assert msg.startswith("start[1].node: "), msg


def test_wfem_too_few_cells() -> None:
    """The filter keeps orbits with at most max_jumps_fraction x cells profile jumps; every
    orbit (g0 != 0) has at least 2, a backbone of mode k, subharmonic n, 2k(n + 1)."""
    msg = refused(lambda: bar(cells=2))
    assert msg.startswith("parameters.cells: 2 cells are too few") and "cells >= 8" in msg
    msg = refused(bar(cells=8).preflight, {"branch": "main", "mode": 2}, (1.0, 4.0), 100)
    assert msg.startswith("parameters.cells: ") and "cells >= 16" in msg
    bar(cells=8).preflight({"branch": "main", "mode": 1}, (1.0, 4.0), 100)
    bar(cells=2, gap=0.0)  # g0 = 0: the vertical backbones have no jump filter
    # the seed search runs in the preflight: no physical orbit near the start -> refused there
    msg = refused(bar(cells=20, gap=-1e-3).preflight, {"branch": "main"}, (1.0, 4.0), 100)
    assert msg.startswith("parameters.cells: no physical orbit found near the start"), msg
    msg = refused(bar(cells=60).preflight, {"branch": "main", "mode": 2}, (1.0, 4.0), 100)
    assert msg.startswith("parameters.cells: no physical orbit"), msg


def test_wfem_preflight_seeds_are_reused_by_the_run() -> None:
    p = bar(cells=200)
    p.preflight({"branch": "main", "mode": 1}, (1.0, 4.0), 100)
    evaluated = p.node_evaluations
    (seed,) = p.lattice_seeds({"branch": "main", "mode": 1}, (1.0, 4.0))
    assert p.node_evaluations == evaluated
    assert p.lattice_seeds({"branch": "main", "mode": 1}, (1.0, 4.0))[0] is seed


def test_wfem_sizes_beyond_the_limits(monkeypatch: pytest.MonkeyPatch) -> None:
    t0 = time.perf_counter()
    msg = refused(bar(cells=200_000).preflight, {"branch": "main"}, (1.0, 4.0), 5000)
    assert msg.startswith("parameters.cells: 200000 cells") and MEMORY_ENV in msg, msg
    # the scan keeps every node it tried (300 B each: 1.3 GB at N = 1000): 5.7 GB at N = 2000
    msg = refused(bar(cells=2000).preflight, {"scan": True}, (1.0, 4.0), 5000)
    assert msg.startswith("parameters.cells: 2000 cells") and MEMORY_ENV in msg, msg
    with monkeypatch.context() as mp:  # with the memory: the scan's O(N^3) time at N = 8000
        mp.setenv(MEMORY_ENV, "1000")
        msg = refused(bar(cells=8000).preflight, {"scan": True}, (1.0, 4.0), 5000)
        assert msg.startswith("parameters.cells: 8000 cells") and TIME_ENV in msg, msg
    msg = refused(bar().preflight, {"node": [10**9, 10**9]}, (None, None), 500)
    assert msg.startswith("start.node: ") and "TB" in msg, msg
    assert time.perf_counter() - t0 < 1.0
    bar(cells=1000).preflight({"scan": True}, (1.0, 4.0), 5000)  # N = 1000 passes


def test_wfem_start_checks() -> None:
    msg = refused(bar(gap=-1e-3).preflight, {"branch": "subharmonic"}, (1.0, 4.0), 10)
    assert msg.startswith("start.branch: subharmonic starts are defined for gap > 0"), msg
    msg = refused(bar().preflight, {"branch": "main"}, (2.0, 4.0), 10)
    assert msg.startswith("start: the main backbone of mode 1 starts at omega/omega_1 = 1"), msg
    msg = refused(bar().preflight, {"node": [104, 4, 152, 4]}, (1.0, 2.0), 10)
    assert msg.startswith("start.node: node [104, 4, 152, 4]"), msg


@pytest.mark.parametrize("key, value, where", [
    ("parameters__cells", True, "parameters.cells"),
    ("parameters__gap", 1e-300, "parameters.gap"),
    ("parameters__corrector_window", 3.0, "parameters.corrector_window"),
    ("start", [{"branch": "main", "mode": False}], "start[0].mode"),
    ("start", {"scan": 1}, "start.scan"),
    ("start", {"node": [True, 3]}, "start.node[0]"),
])
def test_wfem_strict_types(key: str, value: Any, where: str) -> None:
    msg = refused_case(case_of("wfem_fig5_6_backbones_gap_positive.yaml", **{key: value}))
    assert msg.replace(".[", "[").startswith(f"{where}: "), msg


# ----------------------------------------------------------------------------- bar_continuum
def test_continuum_huge_signatures() -> None:
    p = BarContinuumProblem({"gap": 1e-3})
    t0 = time.perf_counter()
    for sig, unit in (([2_000_000, -4], "days"), ([2, -4_000_000], "days")):
        msg = refused(p.preflight, {"signature": sig}, (0.9, 4.1), 800)
        assert msg.startswith("start.signature: the branch") and TIME_ENV in msg, msg
        assert unit in msg
    msg = refused(p.preflight, [{"branch": "main"}, {"signature": [2_000_000, -4]}], (None, None),
                  800)
    assert msg.startswith("start[1].signature: "), msg
    assert time.perf_counter() - t0 < 1.0


def test_continuum_start_checks() -> None:
    p = BarContinuumProblem({"gap": 1e-3})
    msg = refused(p.preflight, {"branch": "main", "omega_ratio": 3.0}, (0.9, 4.1), 10)
    assert msg.startswith("start.omega_ratio: 3 is outside the range of the branch"), msg
    msg = refused(p.preflight, {"branch": "main", "mode": 2}, (0.9, 2.0), 10)
    assert msg.startswith("start.mode: the branch t_f = 4 T - 4 starts at"), msg
    msg = refused(p.preflight, {"signature": [-2, 4]}, (None, None), 10)
    assert msg.startswith("start.signature: the branch t_f = -2 T + 4 has no admissible"), msg
    p.preflight({"signature": [-2, 4], "omega_ratio": 2.5}, (None, None), 10)
    p.preflight({"signature": [8, -24]}, (None, None), 10)


def test_continuum_parameter_scales() -> None:
    assert refused_case(case_of("bar_continuum_main.yaml", parameters__gap=1e-300)).startswith(
        "parameters.gap: ")
    msg = refused(BarContinuumProblem, {"gap": 1e-90, "E": 1e-30})
    assert msg.startswith("parameters.gap: |gap| = 1e-90 is outside [1.27e-85, "), msg
    msg = refused_case(case_of("bar_continuum_main.yaml", parameters__E=True))
    assert msg.startswith("parameters.E: "), msg


# ----------------------------------------------------------------------------- hybrid problems
@pytest.fixture(scope="module")
def pendulum() -> DoublePendulumProblem:
    p = DoublePendulumProblem({"restitution": 0.89})
    p.parameter_bounds("restitution", 0.8, 0.95)
    return p


def test_hybrid_guess_keys(pendulum: DoublePendulumProblem) -> None:
    W = (0.8, 0.95)
    msg = refused(pendulum.preflight, {"guess": {**PENDULUM_GUESS, "foo": 1.0}}, W, 10)
    assert msg.startswith("start.guess: unknown state 'foo'"), msg
    msg = refused(pendulum.preflight, {"guess": {"q2": 0.1}}, W, 10)
    assert msg.startswith("start.guess: missing q1dot, q2dot"), msg
    msg = refused(pendulum.preflight, [{"transient": 3}, {"guess": {"q1": 0.1}}], W, 10)
    assert msg.startswith("start[1].guess: unknown state 'q1'"), msg
    msg = refused(pendulum.preflight, {"guess": PENDULUM_GUESS, "initial": {"q2": 0.1}}, W, 10)
    assert msg.startswith("start.initial: not used with start.guess"), msg
    msg = refused(pendulum.preflight, {"guess": PENDULUM_GUESS, "transient": 3}, W, 10)
    assert msg.startswith("start.transient: not used with start.guess"), msg
    pendulum.preflight({"guess": PENDULUM_GUESS}, W, 10)


def test_hybrid_initial_state(pendulum: DoublePendulumProblem) -> None:
    W = (0.8, 0.95)
    msg = refused(pendulum.preflight, {"initial": {"foo": 1.0}}, W, 10)
    assert msg.startswith("start.initial: unknown state 'foo'"), msg
    # the lower mass behind the wall X = -d
    msg = refused(pendulum.preflight, {"initial": {"q1": -np.pi / 2, "q2": -np.pi / 2}}, W, 10)
    assert msg.startswith("start.initial: the state is on the inadmissible side"), msg
    osc = ImpactOscillatorProblem({"omega": 0.4})
    osc.parameter_bounds("omega", 0.35, 0.7)
    msg = refused(osc.preflight, {"initial": {"q": -1.0}}, (0.35, 0.7), 10)
    assert msg.startswith("start.initial: the state is on the inadmissible side of the impact "
                          "surface (H = -1 < 0)"), msg


def test_hybrid_restitution_window() -> None:
    """e = 0.999 crashed a run where the branch reached r > 1 (HybridDeclarationError): the
    window of a continued parameter must lie in its declared domain (e in [0, 1)) and be closed
    where the domain is bounded; the start value must lie in the window."""
    p = DoublePendulumProblem({"restitution": 0.999})
    for lo, hi, key in ((0.8, None, "continuation.max: continuing in restitution needs"),
                        (0.8, 1.0, "continuation.max: restitution = 1 is outside the domain"),
                        (None, 0.9999, "continuation.min: continuing in restitution needs"),
                        (0.8, 0.95, "parameters.restitution: the start value 0.999 lies "
                                    "outside")):
        p.parameter_bounds("restitution", lo, hi)
        msg = refused(p.preflight, {"transient": 3}, (lo, hi), 10)
        assert msg.startswith(key), msg
    p.parameter_bounds("restitution", 0.8, 0.9999)
    p.preflight({"transient": 3}, (0.8, 0.9999), 10)
    q = DoublePendulumProblem({"d": 0.5})
    q.parameter_bounds("d", 0.4, 2.5)
    msg = refused(q.preflight, {"transient": 3}, (0.4, 2.5), 10)
    assert msg.startswith("continuation.max: d = 2.5 leaves the domain"), msg
    q.parameter_bounds("torque", None, None)
    q.preflight({"transient": 3}, (None, None), 10)  # the torque has no bounds


def test_hybrid_time_limit(pendulum: DoublePendulumProblem,
                           monkeypatch: pytest.MonkeyPatch) -> None:
    msg = refused(pendulum.preflight, {"transient": 10**9}, (0.8, 0.95), 10)
    assert msg.startswith("start: 1 start with their transient") and TIME_ENV in msg, msg
    monkeypatch.setenv(TIME_ENV, "1e-6")
    msg = refused(pendulum.preflight, [{"guess": PENDULUM_GUESS}] * 2, (0.8, 0.95), 10)
    assert msg.startswith("start[0]: 2 starts"), msg


@pytest.mark.parametrize("source, key, value, where", [
    ("pendulum_sec6_1_complete_to_incomplete.yaml", "start__guess__q2", True, "start.guess.q2"),
    ("pendulum_sec6_1_complete_to_incomplete.yaml", "parameters__restitution", True,
     "parameters.restitution"),
    ("pendulum_sec6_1_complete_to_incomplete.yaml", "parameters__integrator",
     {"wall_time": True}, "parameters.integrator.wall_time"),
    ("pendulum_sec6_1_complete_to_incomplete.yaml", "parameters__integrator",
     {"chatter_order": 2.0}, "parameters.integrator.chatter_order"),
    ("impact_oscillator_fig2_sticking.yaml", "start__transient", True, "start.transient"),
    ("impact_oscillator_fig2_sticking.yaml", "start__returns", 1.0, "start.returns"),
    ("chain_two_mass_wall.yaml", "parameters__restitution", True, "parameters.restitution"),
    ("chain_two_mass_wall.yaml", "start__label", 3, "start.label"),
    ("ball_fig1_fig4_chatter.yaml", "parameters__chatter_order", True,
     "parameters.chatter_order"),
])
def test_hybrid_strict_types(source: str, key: str, value: Any, where: str) -> None:
    msg = refused_case(case_of(source, **{key: value}))
    assert msg.startswith(f"{where}: "), msg


def test_ball_start_must_be_empty() -> None:
    msg = refused_case(case_of("ball_fig1_fig4_chatter.yaml", start={"zz": 1}))
    assert msg.startswith("start.zz: unknown key"), msg


# ----------------------------------------------------------------------------- monitor names
def test_monitor_names_are_the_derived_keys(pendulum: DoublePendulumProblem) -> None:
    """``continuation.bounds`` may name exactly what ``derived`` returns at a point."""
    nd = NDofImpactProblem(CHAIN)
    y = nd.start_points({"mode": 1}, T_WINDOW)[0].y
    assert set(nd.derived(y)) <= set(nd.monitor_names())
    bc = BarContinuumProblem({"gap": 1e-3})
    y = bc.start_points({"branch": "main"})[0].y
    assert set(bc.derived(y)) == set(bc.monitor_names())
    wb = bar(cells=40)
    (seed,) = wb.lattice_seeds({"node": [104, 4, 152, 4]}, (0.5, 0.7))
    assert set(wb.lattice_point(seed.solution)[2]) <= set(wb.monitor_names())
    y = np.array([PENDULUM_GUESS[n] for n in ("q2", "q1dot", "q2dot")] + [0.89])
    assert set(pendulum.derived(y)) == set(pendulum.monitor_names())


@pytest.mark.parametrize("key, value", [("min", -1.0), ("min", 0.0), ("max", -2.0)])
def test_chain_frequency_window_must_be_positive(key, value):
    """omega = 2 pi / T: a non-positive bound maps to no period at all (it was accepted and
    shown as a window ['6.98', '-'] in the report)."""
    pr = NDofImpactProblem({"chain": {"dofs": 2, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0})
    lo, hi = (value, None) if key == "min" else (None, value)
    with pytest.raises(ValueError, match=rf"^continuation\.{key}: omega"):
        pr.parameter_bounds("omega", lo, hi)
    assert pr.parameter_bounds("omega", 0.5, 2.0) == pytest.approx((np.pi, 4 * np.pi))


def test_hybrid_start_state_of_absurd_size_is_refused():
    """A guess q2 = 1e300 is refused before computing: Newton's tolerance is relative to
    1 + |y|, so from there it would "correct" the guess to an orbit with residual 44 and report
    it as an admissible point."""
    root = ROOT / "yaml_cases"
    case = root / "pendulum_sec6_1_complete_to_incomplete.yaml"
    with pytest.raises(cases.CaseError, match=r"^start\.guess: a state component of 1e\+300"):
        cases.load(case, ["start.guess.q2=1.0e300"])
    cases.load(case, ["start.guess.q2=1.0"])  # an ordinary guess passes
