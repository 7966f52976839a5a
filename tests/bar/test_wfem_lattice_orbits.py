"""WFEM bar lattice orbits (Yoong et al. 2017, sections 5-6): oracles are closed forms derived
independently (continuum-limit energy of the main backbone), time stepping with the floating
boundary condition of Algorithm 2, and the paper's exact g0 = 0 periods."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from nsm_continuation.problems.bar.wfem_lattice import (
    BarModel,
    classify,
    feasible_cone,
    node_solutions,
    profile_jumps,
    solve_node,
)
from nsm_continuation.problems.bar.wfem_operators import CONTACT, FREE, phase_operator, ring_step

from nsm_continuation import cases
from nsm_continuation.cli import main as cli_main
from nsm_continuation.runs.runner import run_case


def main_energy(model: BarModel, T: float) -> float:
    """Continuum main backbone of mode 1: E = E S g0^2 / (2 L (cT/L - 3)^2) (derived in
    problems/bar/continuum.py; independent of the lattice code)."""
    tau = model.c * T / model.L
    return model.E * model.g0**2 / (2 * model.L * (tau - 3) ** 2)


def floating_bc_orbit(model: BarModel, w0: np.ndarray, steps: int) -> tuple[list[int], np.ndarray]:
    """Algorithm 2 on the ring: start free at u = g0; switch to contact when the gap closes,
    back to free when the wall would be in tension. Returns the phase signs and the final state."""
    N, Z, dt = model.N, model.Z, model.dt
    u, state, w, signs = model.g0, FREE, w0.copy(), []
    tol = 1e-9 * np.abs(w0).max() * dt / Z
    for n in range(steps):
        b_end = w[N - 1]
        if state == CONTACT and b_end > tol * Z / dt:
            state = FREE
        if n == 0:
            state = FREE
        signs.append(state)
        if state == FREE:
            u -= dt * b_end / Z
            if u >= model.g0 - tol * (n + 1):
                state = CONTACT
                u = model.g0
        w = ring_step(w, signs[-1], 1, N)
    return signs, w


@pytest.mark.parametrize("N", [20, 21])
@pytest.mark.parametrize("g0", [1e-3, -1e-3])
def test_main_backbone_nodes_are_exact_samples_of_the_continuum(N: int, g0: float) -> None:
    md = BarModel(1.0, 1.0, 1.0, N, g0)
    found = 0
    M_range = range(3 * N + 1, 4 * N) if g0 > 0 else range(2 * N + 1, 3 * N)
    for M in M_range:
        status, sols = node_solutions(md, (2 * M - 4 * N, 4 * N - M))
        for s in sols:
            found += 1
            assert s.energy == pytest.approx(main_energy(md, s.period), rel=1e-12)
            assert profile_jumps(s.w0) == 2
    assert found >= N // 3
    # the wrong side of the asymptote is never admissible
    wrong = range(2 * N + 1, 3 * N) if g0 > 0 else range(3 * N + 1, 4 * N)
    assert not any(node_solutions(md, (2 * M - 4 * N, 4 * N - M))[1] for M in wrong)


def test_lattice_orbit_is_reproduced_by_floating_boundary_time_stepping() -> None:
    for N, counts in [(40, (2 * 151 - 160, 160 - 151)), (20, (52, 1)), (10, (26, 1, 38, 1))]:
        md = BarModel(1.0, 1.0, 1.0, N, 1e-3)
        (s,) = node_solutions(md, counts)[1]
        assert classify(s) == "physical"
        if len(counts) == 2:
            assert solve_node(md, counts)[0] == "admissible"
        signs, w = floating_bc_orbit(md, s.w0, 3 * s.M)
        expected = [sg for n, sg in s.pattern for _ in range(n)] * 3
        assert signs == expected
        assert np.allclose(w, s.w0, atol=1e-12 * np.abs(s.w0).max())


def test_end_displacement_from_stresses_equals_integrated_end_velocity() -> None:
    md = BarModel(1.0, 1.0, 1.0, 30, 2e-3)
    status, s = solve_node(md, (2 * 113 - 120, 120 - 113))
    assert status == "admissible"
    w = s.w0.copy()
    u_int = md.g0
    for n in range(s.M):
        u_sigma = md.dx / (2 * md.E) * w.sum()  # int sigma/E dx with sigma = (a + b)/2
        assert u_sigma == pytest.approx(u_int, abs=1e-15)
        sign = FREE if n < s.counts[0] else CONTACT
        if sign == FREE:
            u_int -= md.dt * w[md.N - 1] / md.Z
        w = ring_step(w, sign, 1, md.N)


@pytest.mark.parametrize("N", [20, 24])
def test_g0_zero_periods_are_exact(N: int) -> None:
    """Section 6.1: g0 = 0 backbones have T = 3L/c (contact L/c) and 5L/(4c) (contact L/(4c))."""
    from nsm_continuation.problems.bar.wfem_bar import WfemBarParameters, WfemBarProblem

    pr = WfemBarProblem(WfemBarParameters(cells=N, gap=0.0))
    s1 = pr.lattice_seeds({"branch": "main", "mode": 1}, (None, None))[0].solution
    assert s1.counts == (2 * N, N)
    assert s1.period == pytest.approx(3.0, abs=1e-14)
    s2 = pr.lattice_seeds({"branch": "main", "mode": 2}, (None, None))[0].solution
    assert s2.counts == (N, N // 4)
    assert s1.amplitude_free and s2.amplitude_free


@pytest.mark.parametrize("g0", [1e-12, 1e-3, 1e-1])
def test_energy_ratio_is_gap_invariant_down_to_round_off(g0: float) -> None:
    md = BarModel(1.0, 1.0, 1.0, 20, g0)
    status, s = solve_node(md, (78, 1))
    assert status == "admissible"
    assert s.energy / md.energy_ref == pytest.approx(8 / np.pi**2 / 0.95**2 * 0.5 * 2,
                                                     rel=1e-12)


def test_huge_gap_violates_material_impenetrability() -> None:
    """COND3 (strain > -1) fails when the gap is comparable to the bar length."""
    md = BarModel(1.0, 1.0, 1.0, 20, 2.0)
    status, s = solve_node(md, (78, 1))
    assert status.startswith("inadmissible") and "cond3" in status


def test_filter_removes_relabelled_and_grid_scale_orbits() -> None:
    md = BarModel(1.0, 1.0, 1.0, 20, 1e-3)
    removed = {}
    kept = 0
    for M in range(41, 81):
        for p in range(1, M):
            status, sols = node_solutions(md, (M - p, p))
            for s in sols:
                r = classify(s)
                removed[r] = removed.get(r, 0) + 1
                kept += r == "physical"
    assert removed.get("relabelled (zero end interaction)", 0) > 10
    assert kept >= 10
    # a grid-scale family: profile jumping at every slot, energy ~ jumps^2 (g0 < 0, M = 2N + 1)
    md_neg = BarModel(1.0, 1.0, 1.0, 20, -1e-3)
    _, sols = node_solutions(md_neg, (38, 3))
    assert sols and profile_jumps(sols[0].w0) == 38
    from nsm_continuation.problems.bar.wfem_bar import WfemBarParameters, WfemBarProblem

    pr = WfemBarProblem(WfemBarParameters(cells=20, gap=-1e-3))
    assert pr.physical((38, 3)) == []
    assert pr.physical((2, 39))  # the main backbone's node at the same period is kept


def test_paper_claim_h_equals_contact_phases_fails_where_cycles_split() -> None:
    """At M = 75, N = 20 (gcd(75, 40) = 5) the main backbone's orbit lies in a 5-dimensional
    kernel, is admissible and sits exactly on the continuum curve: admissible orbits with h > q
    exist. The paper only found h = q = 1."""
    md = BarModel(1.0, 1.0, 1.0, 20, 1e-3)
    status, _ = solve_node(md, (70, 5))
    assert status == "h > q"
    assert phase_operator(20, ((70, FREE), (5, CONTACT))).kernel_dimension() == 5
    assert feasible_cone(md, (70, 5))
    _, sols = node_solutions(md, (70, 5))
    assert len(sols) == 1 and classify(sols[0]) == "physical"
    assert sols[0].energy == pytest.approx(main_energy(md, sols[0].period), rel=1e-12)


def test_two_contact_phase_orbit_near_three_fifths() -> None:
    """Eq. (18) with p = l: an orbit near 3 omega_1 / 5 with two grazing instants (Fig. 18)."""
    md = BarModel(1.0, 1.0, 1.0, 10, 1e-3)
    _, sols = node_solutions(md, (26, 1, 38, 1))
    assert len(sols) == 1
    s = sols[0]
    assert classify(s) == "physical" and s.h == 2
    assert 0.6 <= s.derived()["omega_ratio"] < 2 / 3
    assert len(s.grazing_steps) == 2
    # no orbit when the two contact phases differ (section 6.4)
    assert not node_solutions(md, (26, 1, 37, 2))[1]


def _case(tmp_path: Path, **over) -> Path:
    raw = {"name": "bar", "problem": "wfem_bar",
           "parameters": {"E": 1, "rho": 1, "L": 1, "cells": 100, "gap": 1e-3},
           "start": {"branch": "main", "mode": 1},
           "continuation": {"parameter": "omega_ratio", "min": 0.9, "max": 2.1,
                            "max_energy": 1e3, "max_points": 1000},
           "output": {"dir": str(tmp_path / "out"), "progress": False}}
    for k, v in over.items():
        raw[k] = v
    p = tmp_path / "case.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


def test_lattice_continuation_of_the_main_backbone(tmp_path: Path) -> None:
    case, problem = cases.load(_case(tmp_path))
    res = run_case(case, problem, progress=False)
    (br,) = res.branches
    d = [p.derived for p in br.points]
    md = problem.model
    assert all(x["energy"] == pytest.approx(main_energy(md, x["period"]), rel=1e-12) for x in d)
    assert d[0]["omega_ratio"] < 1.01
    assert all(b["omega_ratio"] > a["omega_ratio"] and b["energy"] > a["energy"]
               for a, b in zip(d, d[1:], strict=False))
    (asym,) = [e for e in br.events if e.kind == "asymptote"]
    assert asym.data["omega_ratio"] == pytest.approx(4 / 3, abs=1e-9)
    assert "energy_ratio above" in br.termination["increase"]


@pytest.mark.parametrize("key,value,msg", [
    ("parameters", {"cells": 0}, "parameters.cells"),
    ("parameters", {"E": -1.0}, "parameters.E"),
    ("parameters", {"rho": 0.0}, "parameters.rho"),
    ("parameters", {"L": float("nan")}, "parameters.L"),
    ("start", {"node": [10, 0]}, "start"),
    ("start", {"branch": "main", "mode": 0}, "start"),
])
def test_bad_input_is_one_clear_error(tmp_path: Path, capsys, key, value, msg) -> None:
    path = _case(tmp_path)
    raw = yaml.safe_load(path.read_text())
    if key == "parameters":
        raw["parameters"].update(value)
    else:
        raw[key] = value
    path.write_text(yaml.safe_dump(raw))
    assert cli_main(["run", str(path)]) == 2
    err = capsys.readouterr().err
    assert msg in err
    assert not (tmp_path / "out").exists()
