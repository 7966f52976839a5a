"""The bar's forced response (Figs. 20-22) as YAML cases: ``problem: wfem_forced_bar`` swept by
the ``sweep`` algorithm (problems/bar/forced_response.py, nsm_continuation/algorithms/sweep.py).

Oracles:

* far from contact (gap 1, force 4e-3: the end moves by at most ~1e-2) the bar is the linear
  damped clamped-free bar, whose steady state comes from its modal series
  (``q_k'' + (eta/rho) q_k' + omega_k^2 q_k = 2 f0 / (rho L beta_k) sin(omega t)``, no code
  shared with the package: ``oracles/wfem_bar.py``);
* the sweep through the YAML case must give the same numbers as calling
  :func:`forced_response_sweep` directly (a second entry point into the same time stepping);
* the main NSM backbone overlaid on the figures against the closed form of the lattice energy
  ``E / E_ref = 8 / (pi^2 (cT/L - 3)^2)`` (mode 1, docs/results.md: "main backbone energy").
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from helpers import CASES
from nsm_continuation.problems.bar.forced_response import main_backbone
from nsm_continuation.problems.bar.wfem_simulation import BarParams, forced_response_sweep
from oracles.wfem_bar import modal_steady_state

import nsm_continuation as nsm
from nsm_continuation import cli

FORCE = CASES / "wfem_fig20_force_positive_gap.yaml"
WALL = CASES / "wfem_fig20_wall_positive_gap.yaml"
FIG_CASES = sorted(CASES.glob("wfem_fig2[0-2]_*.yaml"))

#: the cheap variant of the force case, far from contact: 4 frequencies avoiding the linear
#: resonances (at omega = omega_k the resonant free transient decays at the forcing frequency and
#: the period-to-period steady criterion stops ~1 % early, independently of N) and commensurate
#: ratios (a transient beating with period 3T is classified as "period 3 T")
FAR = ["parameters.gap=1.0", "parameters.cells=50", "parameters.damping_ratio=0.1",
       "continuation.max_points=4", "continuation.min=0.55", "continuation.max=2.35"]


def read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    # every numeric column (``signature`` is the text name of each point's family)
    return {k: np.array([float(r[k]) if r[k] not in ("", "nan") else np.nan for r in rows])
            for k in rows[0] if k != "signature"}


def test_cli_run_far_from_contact_is_the_linear_response(tmp_path: Path) -> None:
    """``nsm-continuation run`` of the Fig. 20(b) case, made cheap and moved far from contact:
    every point is a T-periodic steady state without contact whose period-averaged energy and
    end amplitude are those of the modal series to 1e-3 and 2e-3 (measured 2.8e-4 and 1.3e-4 at
    N = 50), and the CSV carries the package's closed form to 1e-9 of it."""
    out = tmp_path / "run"
    args = ["run", str(FORCE), "--out", str(out), "--quiet"]
    for s in FAR:
        args += ["--set", s]
    assert cli.main(args) == 0
    for name in ("report.json", "report.md", "branch_0.csv", "fep.png",
                 "frequency_response.png"):
        assert (out / name).is_file(), name
    rep = json.loads((out / "report.json").read_text())
    assert rep["problem"] == "wfem_forced_bar" and len(rep["branches"]) == 1
    col = read_csv(out / "branch_0.csv")
    p = BarParams(N=50, g0=1.0)
    eta = 2 * p.omega1 * 0.1
    np.testing.assert_allclose(col["omega_ratio"], np.linspace(0.55, 2.35, 4), rtol=1e-15)
    np.testing.assert_allclose(col["omega"], col["omega_ratio"] * p.omega1, rtol=1e-15)
    # |U(L)| and the period-averaged energy of the linear bar, from its modal series
    oracle = np.array([(abs(U_L), energy) for U_L, energy in
                       (modal_steady_state(p, 4e-3, om, eta) for om in col["omega"])])
    np.testing.assert_allclose(col["energy"], oracle[:, 1], rtol=1e-3)
    np.testing.assert_allclose(col["energy_ratio"], oracle[:, 1] / p.energy_ref, rtol=1e-3)
    np.testing.assert_allclose(col["amplitude"], oracle[:, 0], rtol=2e-3)
    np.testing.assert_allclose(col["linear_energy_ratio"], oracle[:, 1] / p.energy_ref,
                               rtol=1e-9)
    np.testing.assert_allclose(col["linear_amplitude"], oracle[:, 0], rtol=1e-9)
    assert np.all(col["contact_fraction"] == 0.0)
    assert np.all(col["steady"] == 1.0) and np.all(col["multiple"] == 1.0)
    assert rep["branches"][0]["termination"] == "increase: end of the grid (4 values of " \
                                                "omega_ratio)"


def test_sweep_gives_the_numbers_of_forced_response_sweep() -> None:
    """The YAML sweep (with contact: moving wall, g0 = 1e-3) reproduces
    forced_response_sweep called directly, number for number: increasing and decreasing grids
    (continuation.direction both), two damping ratios, warm start (state and forcing phase
    carried) and cold start (continuation=False)."""
    over = {"parameters.cells": 20, "parameters.damping_ratio": [0.05, 0.1],
            "start": [{"warm_start": True}, {"warm_start": False}],
            "continuation.max_points": 5, "continuation.min": 0.5, "continuation.max": 3.0,
            "continuation.direction": "both", "output.plots": False, "output.progress": False}
    res = nsm.run(WALL, over)
    assert len(res.branches) == 8
    p = BarParams(N=20, g0=1e-3)
    grid = np.linspace(0.5, 3.0, 5)
    seen = set()
    for br in res.branches:
        info = br.raw.info
        eta, warm, d = info["eta"], info["warm_start"], info["direction"]
        assert eta == 2 * p.omega1 * info["damping_ratio"]
        omegas = (grid if d > 0 else grid[::-1]) * p.omega1
        ref = forced_response_sweep(p, omegas, eta, w0=2e-3, continuation=warm)
        assert np.array_equal(br["omega"], ref.omegas)
        assert np.array_equal(br["energy"], ref.energies)
        for name, attr in (("multiple", "multiple"), ("contact_fraction", "contact_fraction"),
                           ("u_max", "u_max"), ("u_min", "u_min"), ("steps", "n_steps")):
            assert np.array_equal(br[name], [getattr(q, attr) for q in ref.points]), name
        assert br["contact_fraction"].max() > 0  # the wall is reached: contact is exercised
        seen.add((info["damping_ratio"], warm, d))
    assert len(seen) == 8


def test_sweep_events_bounds_and_direction() -> None:
    """A response_change event at each change of the kind of steady state (from the CSV's
    ``multiple`` column), endpoint events at both ends, and continuation.max_energy ends a sweep
    at the first frequency above it (not kept) with the reason."""
    over = {"parameters.cells": 20, "parameters.damping_ratio": 0.05,
            "continuation.max_points": 8, "continuation.min": 0.5, "continuation.max": 3.0,
            "output.plots": False, "output.progress": False}
    res = nsm.run(WALL, over)
    br = res.branches[0]
    kinds = np.array(br["multiple"])
    changes = int(np.sum(kinds[1:] != kinds[:-1]))
    events = [e for e in res.events if e.branch == 0]
    assert sum(e.kind == "response_change" for e in events) == changes > 0
    assert [e.kind for e in events if e.kind == "endpoint"] == ["endpoint", "endpoint"]
    assert np.all(np.diff(br["omega_ratio"]) > 0)
    cap = float(np.median(br["energy_ratio"]))
    capped = nsm.run(WALL, {**over, "continuation.max_energy": cap})
    cb = capped.branches[0]
    first_above = int(np.argmax(br["energy_ratio"] > cap))
    assert len(cb) == first_above
    np.testing.assert_array_equal(cb["energy"], br["energy"][:first_above])
    assert cb.termination["increase"].startswith("bound: energy_ratio = max")
    down = nsm.run(WALL, {**over, "continuation.direction": "decrease"}).branches[0]
    assert np.all(np.diff(down["omega_ratio"]) < 0)


@pytest.mark.parametrize("override, key", [
    ("continuation.min=4.0", "continuation: need min < max"),
    ("continuation.max_points=0", "continuation.max_points"),
    ("continuation.max_points=1", "continuation.max_points"),
    ("continuation.min=null", "continuation.min"),
    ("continuation.max=null", "continuation.max"),
    ("continuation.min=-1.0", "continuation.min"),
    ("continuation.parameter=T", "continuation.parameter"),
    ("parameters.force_amplitude=0.0", "parameters.force_amplitude"),
    ("parameters.damping_ratio=[]", "parameters.damping_ratio"),
    ("parameters.damping_ratio=2.0", "parameters.damping_ratio"),
    ("parameters.damping_ratio=0.0", "parameters.max_time"),
    ("parameters.cells=1", "parameters.cells"),
    ("parameters.switching=exact", "parameters.switching"),
    ("start.warm=true", "start.warm"),
    ("continuation.max_points=100000", "continuation.max_points"),  # > 12 h
])
def test_validate_refuses_bad_sweeps(override: str, key: str, capsys) -> None:
    """``nsm-continuation validate``: exit 2 and one line naming the field."""
    assert cli.main(["validate", str(FORCE), "--set", override]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"error: {key}"), err


def test_sweep_case_against_palc_and_omega_parameter(capsys) -> None:
    """Only the sweep algorithm can run it; ``parameter: omega`` is the same window divided by
    omega_1."""
    assert cli.main(["validate", str(FORCE), "--set", "continuation.algorithm=palc"]) == 2
    assert "supports sweep" in capsys.readouterr().err
    case = nsm.load_case(FORCE, {"continuation.parameter": "omega",
                                 "continuation.min": math.pi / 2, "continuation.max": math.pi})
    pr = nsm.problem("wfem_forced_bar", case.parameters)
    assert pr.parameter_bounds("omega", math.pi / 2, math.pi) == pytest.approx((1.0, 2.0))


@pytest.mark.parametrize("path", FIG_CASES, ids=[p.stem for p in FIG_CASES])
def test_figure_cases_validate(path: Path) -> None:
    """The six cases of Figs. 20-22 (moving wall, distributed force; g0 > 0, = 0, < 0)."""
    case = nsm.load_case(path)  # validated as by nsm-continuation validate
    problem = nsm.problem(case.problem, case.parameters)
    assert problem.name == "wfem_forced_bar" and case.continuation.max_points == 40
    assert (problem.params.wall_amplitude == 0) != (problem.params.force_amplitude == 0)
    assert len(FIG_CASES) == 6


def test_main_backbone_energy_is_the_lattice_closed_form() -> None:
    """The mode-1 backbone drawn on the figures is E/E_ref = 8 / (pi^2 (cT/L - 3)^2): from
    omega_1 (8/pi^2) hardening to the asymptote 4/3 for g0 > 0, softening from Omega_1 = 2
    omega_1 to 4/3 for g0 < 0; a vertical line at 4/3 for g0 = 0."""
    for sign, lo, hi in ((1.0, 1.0, 4 / 3), (-1.0, 4 / 3, 2.0)):
        x, e = main_backbone(1, sign)
        T = 4.0 / x
        np.testing.assert_allclose(e, 8 / (math.pi**2 * (T - 3.0) ** 2), rtol=1e-12)
        assert lo - 1e-12 <= x.min() and x.max() <= hi + 1e-12
        end = x == (lo if sign > 0 else hi)
        assert end.any() and e[end] == pytest.approx(8 / math.pi**2)
    x, e = main_backbone(1, 0.0)
    assert np.all(x == pytest.approx(4 / 3)) and np.all(np.isnan(e))
