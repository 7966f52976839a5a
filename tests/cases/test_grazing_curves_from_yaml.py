"""Two-parameter grazing curves from YAML (``start: {..., curve: grazing}``,
``nsm_continuation/hybrid/codim1.py``, eq. C1).

Oracle: the forced impact oscillator ``q'' + 2 zeta q' + q = cos(omega t)``, ``q >= gap``,
whose free periodic orbit has the amplitude ``A(omega) = 1 / sqrt((1 - omega^2)^2 + (2 zeta
omega)^2)`` (closed form, independent of the simulator): the grazing orbits continued by C1 miss
the stop by the documented margin, so every point of the curve satisfies ``A(omega) = -gap -
margin (1 + |y|)``. The base run is a cheap cut of ``yaml_cases/impact_oscillator_grazing.yaml``:
the free orbit (closed form at omega = 1.8) continued down in omega to its grazing.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from helpers import CASES

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.hybrid.codim1 import DEFAULT_MARGIN

GAP = -0.5


def amplitude(omega: float, zeta: float) -> float:
    return 1.0 / np.sqrt((1 - omega ** 2) ** 2 + (2 * zeta * omega) ** 2)


def base_case(zeta: float, omega: float = 1.8) -> dict[str, Any]:
    """The free orbit at ``omega`` (closed form on the phase-pi section) continued down in
    omega through its grazing with the stop at ``q = -0.5``."""
    A, ph = amplitude(omega, zeta), np.arctan2(2 * zeta * omega, 1 - omega ** 2)
    return {"name": f"oscillator_zeta_{zeta}", "problem": "impact_oscillator",
            "parameters": {"zeta": zeta, "omega": omega, "gap": GAP, "restitution": 0.8,
                           "section_phase": float(np.pi)},
            "start": {"guess": {"q": float(A * np.cos(np.pi - ph)),
                                "qdot": float(-omega * A * np.sin(np.pi - ph))}},
            "continuation": {"parameter": "omega", "min": 1.65, "max": 1.8,
                             "direction": "decrease",
                             "step": {"initial": 0.02, "min": 1e-9, "max": 0.05},
                             "max_points": 30, "newton_tol": 1e-10},
            "output": {"plots": False, "progress": False}}


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """``bases(zeta)``: the saved base run of that damping (computed once)."""
    done: dict[float, tuple[float, Any, Path]] = {}

    def get(zeta: float) -> tuple[float, Any, Path]:
        if zeta not in done:
            res = nsm.run(base_case(zeta))
            folder = tmp_path_factory.mktemp("runs") / f"base_{zeta}"
            res.save(folder, plots=False)
            done[zeta] = (zeta, res, folder)
        return done[zeta]

    return get


@pytest.fixture(params=[0.0, 0.1], ids=["zeta0", "zeta0.1"])
def base_run(request: pytest.FixtureRequest, bases: Any) -> tuple[float, Any, Path]:
    return bases(request.param)


@pytest.fixture()
def undamped(bases: Any) -> tuple[float, Any, Path]:
    return bases(0.0)


def run_yaml(case: dict[str, Any], tmp_path: Path, name: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(case))
    out = tmp_path / name
    assert cli.main(["run", str(path), "--out", str(out), "--quiet"]) == 0
    return out


def rows_of(folder: Path, branch: int = 0) -> list[dict[str, str]]:
    with open(folder / f"branch_{branch}.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_grazing_curve_from_yaml_is_the_closed_form(base_run: tuple[float, Any, Path],
                                                    tmp_path: Path) -> None:
    """``start: {from: <run>, event: grazing, curve: grazing, free: omega}`` continued in the
    gap: the CSV starts with (gap, omega), every row satisfies the closed form with the margin
    to 1e-8 (measured: 2e-11) and its orbit does not touch the stop; the run covers the gap
    window; the figure is the curve in the (gap, omega) plane; the restart record names the
    oscillator and the curve."""
    zeta, res, folder = base_run
    [graze] = [e for e in res.events if e.kind == "grazing"]
    assert amplitude(graze.parameter, zeta) == pytest.approx(-GAP, abs=1e-10)
    out = run_yaml({"start": {"from": str(folder), "event": "grazing", "curve": "grazing",
                              "free": "omega"},
                    "continuation": {"parameter": "gap", "min": -0.9, "max": -0.2,
                                     "step": {"initial": 0.01, "min": 1e-9, "max": 0.05},
                                     "max_points": 100},
                    "output": {"progress": False}}, tmp_path, "curve")
    rows = rows_of(out)
    assert list(rows[0])[:4] == ["gap", "omega", "period", "grazing_margin"]
    errors = []
    for r in rows:
        y = np.array([float(r[k]) for k in ("y_q", "y_qdot", "y_omega", "y_gap")])
        omega, gap = y[2], y[3]
        assert (float(r["omega"]), float(r["gap"])) == (omega, gap)
        errors.append(abs(amplitude(omega, zeta) - (-gap - DEFAULT_MARGIN
                                                     * (1 + np.linalg.norm(y)))))
        assert float(r["n_impacts"]) == 0 and float(r["grazing_margin"]) > 0
    assert max(errors) < 1e-8
    gaps = sorted(float(r["gap"]) for r in rows)
    assert gaps[0] == -0.9 and gaps[-1] == -0.2
    rep = json.loads((out / "report.json").read_text())
    assert rep["problem"] == "grazing_curve" and rep["continuation"]["parameter"] == "gap"
    assert rep["restart"]["problem"] == "impact_oscillator"
    assert rep["restart"]["curve"] == {"kind": "grazing", "free": "omega",
                                       "method": "augmented", "margin": DEFAULT_MARGIN}
    assert rep["branches"][0]["info"]["curve"] == "grazing"
    assert rep["branches"][0]["parent"]["event"] == {"kind": "grazing", "index": 0}
    assert "fep.png" in rep["figures"]
    # the curve's figure is in the (continued, free) plane
    assert rep["problem_summary"]["continued"] == "gap" and rep["problem_summary"]["free"] \
        == "omega"


def test_restart_from_a_curve_continues_the_curve(undamped: tuple[float, Any, Path],
                                                  tmp_path: Path) -> None:
    """A restart from a row of a curve run rebuilds the curve (its kind, free parameter and
    margin come from the run): the first point is that row after one Newton iteration."""
    _, _, folder = undamped
    first = run_yaml({"start": {"from": str(folder), "event": "grazing", "curve": "grazing",
                                "free": "omega"},
                      "continuation": {"parameter": "gap", "min": -0.6, "max": -0.4,
                                       "max_points": 10},
                      "output": {"plots": False, "progress": False}}, tmp_path, "first")
    saved = rows_of(first)
    again = nsm.run({"start": {"from": str(first), "point": 3},
                     "continuation": {"max_points": 2}, "output": {"plots": False}})
    assert again.problem.name == "grazing_curve" and again.problem.free == "omega"
    br = again.run_result.branches[0]
    p0 = next(p for p in br.points if p.s == 0.0)
    y3 = np.array([float(saved[3][f"y_{v}"]) for v in ("q", "qdot", "omega", "gap")])
    assert p0.newton_iterations == 1
    assert np.linalg.norm(p0.y - y3, np.inf) < 1e-11


BAD = [
    ("not a grazing", {"event": "endpoint", "curve": "grazing", "free": "omega"},
     {"parameter": "gap"},
     "start.curve: a grazing curve starts from a grazing event of the run (start.event: "
     "grazing), not from an endpoint event"),
    ("from a row", {"point": 2, "curve": "grazing", "free": "omega"}, {"parameter": "gap"},
     "start.curve: a grazing curve starts from a grazing event of the run (start.event: "
     "grazing), not from a CSV row"),
    ("free is continued", {"event": "grazing", "curve": "grazing", "free": "gap"},
     {"parameter": "gap"},
     "start.free: the grazing curve needs two parameters, and 'gap' is the one continued"),
    ("free by default is continued", {"event": "grazing", "curve": "grazing"}, {},
     "start.free: the grazing curve needs two parameters, and 'omega' is the one continued"),
    ("free unknown", {"event": "grazing", "curve": "grazing", "free": "mass"},
     {"parameter": "gap"}, "start.free: 'mass' is not a parameter of 'impact_oscillator'"),
    ("curve and switch", {"event": "grazing", "curve": "grazing", "switch": True}, {},
     "start.switch: switching is defined at period_doubling and branch_point events"),
    ("free without curve", {"event": "grazing", "free": "omega"}, {},
     "start.free: only used with start.curve"),
    ("unknown curve", {"event": "grazing", "curve": "cusp"}, {},
     "start.curve: Input should be 'grazing'"),
    ("curve of another kind", {"event": "grazing", "curve": "fold"}, {},
     "start.curve: a fold curve starts from a fold event of the run"),
]


@pytest.mark.parametrize(("label", "start", "cont", "needle"), BAD, ids=[b[0] for b in BAD])
def test_bad_curve_one_line_exit_2_nothing_written(undamped: tuple[float, Any, Path],
                                                   write_case: Any,
                                                   refused_before_computing: Any, label: str,
                                                   start: dict[str, Any],
                                                   cont: dict[str, Any], needle: str) -> None:
    _, _, folder = undamped
    path = write_case({"start": {"from": str(folder), **start},
                       "continuation": cont, "output": {"progress": False}})
    refused_before_computing(path, needle)


def test_a_chain_curve_from_a_point_that_is_no_grazing_is_refused(tmp_path: Path,
                                                                  write_case: Any,
                                                                  capsys: Any) -> None:
    """The chain (``ndof_impact``, not a hybrid system) has located grazing curves
    (:mod:`nsm_continuation.algorithms.curves`); one asked from the branch's end point (no grazing
    there) is refused before computing, naming start.curve."""
    res = nsm.run(CASES / "ndof_default.yaml",
                  {"continuation.min": 1.42, "continuation.max": 1.49,
                   "continuation.max_points": 3, "output.plots": False,
                   "output.progress": False})
    res.save(tmp_path / "chain", plots=False)
    path = write_case({"start": {"from": str(tmp_path / "chain"),
                                 "event": {"kind": "endpoint", "index": 0},
                                 "curve": "grazing"},
                       "continuation": {"parameter": "stiffness"}})
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("error: start.curve: a grazing curve starts from a grazing event of the run "
                   "(start.event: grazing), not from an endpoint event")


def test_the_reports_grazing_line_pasted_runs_the_curve(undamped: tuple[float, Any, Path],
                                                        tmp_path: Path) -> None:
    """report.json / report.md of the base run give, at its grazing, the ``start:`` and
    ``continuation:`` of the grazing curve; pasted verbatim into a case file (window and
    length set with --set) it runs, and its first point is the grazing orbit at gap = -0.5 on
    the closed form."""
    zeta, _, folder = undamped
    rep = json.loads((folder / "report.json").read_text())
    [hint] = [h for h in rep["continue_from_here"] if h["kind"] == "grazing"]
    assert hint["yaml"] == (f"start: {{from: {folder}, event: {{kind: grazing, index: 0}}, "
                            "curve: grazing, free: omega}\ncontinuation: {parameter: gap}")
    case = tmp_path / "pasted.yaml"
    case.write_text(hint["yaml"] + "\noutput: {plots: false, progress: false}\n")
    out = tmp_path / "pasted"
    assert cli.main(["run", str(case), "--out", str(out), "--quiet",
                     "--set", "continuation.min=-0.55", "--set", "continuation.max=-0.45",
                     "--set", "continuation.max_points=3"]) == 0
    row = next(r for r in rows_of(out) if float(r["s"]) == 0.0)
    y = np.array([float(row[f"y_{v}"]) for v in ("q", "qdot", "omega", "gap")])
    assert y[3] == GAP
    assert abs(amplitude(y[2], zeta) - (-GAP - DEFAULT_MARGIN * (1 + np.linalg.norm(y)))) \
        < 1e-10


def test_the_python_api_continues_the_curve_too(undamped: tuple[float, Any, Path]) -> None:
    """``Result.restart(event="grazing", curve="grazing", free="omega", parameter="gap")``:
    the same curve from the run in memory (closed form at every point)."""
    zeta, res, _ = undamped
    curve = res.restart(event="grazing", curve="grazing", free="omega", parameter="gap",
                        min=-0.6, max=-0.4, max_points=6)
    assert curve.problem.name == "grazing_curve"
    for y in curve.branches[0].y:
        assert abs(amplitude(y[2], zeta) - (-y[3] - DEFAULT_MARGIN * (1 + np.linalg.norm(y)))) \
            < 1e-10
