"""The Python API agrees with the command line and with the closed form it continues."""

from __future__ import annotations

import json

import numpy as np
import pytest

import nsm_continuation as nsm
from nsm_continuation import cli

SMALL = {
    "name": "api",
    "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 40},
    "output": {"plots": False, "progress": False},
}


def test_run_from_a_dict_matches_the_cli_files(tmp_path):
    result = nsm.run(SMALL)
    case = tmp_path / "c.json"
    case.write_text(json.dumps(SMALL))  # JSON is YAML
    assert cli.main(["run", str(case), "--out", str(tmp_path / "cli"), "--quiet"]) == 0
    report = json.loads((tmp_path / "cli" / "report.json").read_text())
    assert len(result.branches) == len(report["branches"]) == 1
    b = result.branches[0]
    assert len(b) == report["branches"][0]["n_points"]
    # the same events, at the same parameter values, as the CLI's report
    kinds = [e.kind for e in result.events]
    assert kinds == [e["kind"] for e in report["branches"][0]["events"]]
    cli_T = [e["T"] for e in report["branches"][0]["events"]]
    assert np.allclose([e.record["T"] for e in result.events], cli_T, rtol=1e-12)
    # columns are the CSV's, as arrays; the parameter column is the continued unknown T
    assert np.allclose(b["omega"], 2 * np.pi / b["T"], rtol=1e-13)
    assert np.array_equal(b.parameter, b["T"])


def test_branch_points_solve_the_closed_form():
    """Every point returned by the API is a zero of the problem's residual (an independent
    evaluation, not the engine's own convergence flag)."""
    problem = nsm.problem("ndof_impact", SMALL["parameters"])
    result = nsm.continuation(problem, {"mode": 1}, parameter="omega", min=0.3, max=0.9,
                              max_points=40)
    b = result.branches[0]
    assert len(b) > 10
    for y in b.y:
        assert np.linalg.norm(problem.evaluate(y), np.inf) < 1e-9
    # the window is respected and the parameter column is the unknown T = 2 pi / omega
    assert np.all((b["omega"] >= 0.3 - 1e-12) & (b["omega"] <= 0.9 + 1e-12))


def test_continuation_from_a_guess_array_follows_the_same_branch():
    problem = nsm.problem("ndof_impact", SMALL["parameters"])
    first = nsm.continuation(problem, {"mode": 1}, parameter="omega", min=0.3, max=0.9,
                             max_points=40)
    y0 = first.branches[0].y[len(first.branches[0]) // 2]
    guess = y0 + 1e-6
    guess[problem.parameter_index] = y0[problem.parameter_index]  # corrected at this parameter
    again = nsm.continuation(problem, guess, parameter="omega", min=0.3, max=0.9,
                             max_points=40)
    b = again.branches[0]
    assert len(b) > 10
    # the corrected start is the point it was perturbed from
    assert np.min(np.linalg.norm(b.y - y0, axis=1)) < 1e-8


def test_overrides_and_bad_input_raise_case_error_naming_the_key():
    before = json.dumps(SMALL, sort_keys=True)
    result = nsm.run(SMALL, {"continuation.max_points": 5})
    assert json.dumps(SMALL, sort_keys=True) == before  # the caller's dict is not changed
    assert len(result.branches[0]) <= 2 * 5
    with pytest.raises(nsm.CaseError, match=r"^continuation\.max_points"):
        nsm.load_case(SMALL, {"continuation.max_points": True})
    with pytest.raises(nsm.CaseError, match=r"^parameters\.gap"):
        nsm.problem("ndof_impact", {**SMALL["parameters"], "gap": "wide"})
    with pytest.raises(nsm.CaseError, match=r"^start"):
        nsm.continuation(nsm.problem("ndof_impact", SMALL["parameters"]), [1.0, 2.0])


def test_save_uses_the_output_policy(tmp_path):
    result = nsm.run(SMALL)
    out = result.save(tmp_path / "run", plots=False)
    assert (out / "report.json").is_file()
    with pytest.raises(nsm.CaseError, match="previous run"):
        result.save(tmp_path / "run", plots=False)
    assert result.save(tmp_path / "run", plots=False, overwrite=True) == out


def test_plot_draws_on_a_given_axes():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    result = nsm.run(SMALL)
    fig, ax = plt.subplots()
    assert result.plot(ax) is fig
    lines = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 1]
    omega = result.branches[0]["omega"]
    drawn = np.concatenate([ln.get_xdata() for ln in lines])
    assert np.isclose(drawn.min(), omega.min()) and np.isclose(drawn.max(), omega.max())
    plt.close(fig)


def test_save_refusal_speaks_the_api(tmp_path) -> None:
    """Saving twice into one folder is refused with the API's own advice (overwrite=True),
    and overwrite=True then replaces the run."""
    import pytest

    import nsm_continuation as nsm

    case = {"name": "d", "problem": "ndof_impact",
            "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
            "start": {"T": 5.0},
            "continuation": {"parameter": "omega", "min": 0.5, "max": 3.0, "max_points": 4},
            "analysis": {"stability": False}}
    res = nsm.run(case)
    res.save(tmp_path / "o", plots=False)
    with pytest.raises(nsm.CaseError, match="pass overwrite=True"):
        res.save(tmp_path / "o", plots=False)
    assert res.save(tmp_path / "o", plots=False, overwrite=True) == tmp_path / "o"
