"""One vocabulary across the problem families (``nsm_continuation.core.vocabulary``): an old key
gives
the same problem with a deprecation warning naming both keys, an old key with its new one is one
error naming both, the command line shows a deprecation once, and every registered problem is
the same built from a dict or from its ``Parameters`` model."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from typing import Any

import numpy as np
import pytest
import yaml
from helpers import CASES
from pydantic import ValidationError

from nsm_continuation import cases, cli
from nsm_continuation.api import problem as api_problem
from nsm_continuation.cases import registry
from nsm_continuation.core.errors import CaseError
from nsm_continuation.core.vocabulary import ParameterDeprecationWarning, as_parameters

CHAIN = {"chain": {"dofs": 3, "mass": 1.0, "stiffness": [1.0, 2.0, 1.5]}, "gap": 0.7}

#: (problem, parameters with the current keys, the same with an old key, old, new)
RENAMES = [
    ("ndof_impact", CHAIN, {**CHAIN, "chain": {"n": 3, "mass": 1.0, "stiffness": [1.0, 2.0, 1.5]}},
     "parameters.chain.n", "parameters.chain.dofs"),
    ("impact_oscillator", {"gap": -0.2}, {"sigma": -0.2}, "parameters.sigma", "parameters.gap"),
    ("impact_oscillator", {"restitution": 0.7}, {"e": 0.7}, "parameters.e",
     "parameters.restitution"),
    ("two_mass_chain", {"restitution": 0.7}, {"e": 0.7}, "parameters.e",
     "parameters.restitution"),
    ("double_pendulum", {"restitution": 0.89}, {"e": 0.89}, "parameters.e",
     "parameters.restitution"),
    ("bouncing_ball", {"restitution": 0.7}, {"e": 0.7}, "parameters.e", "parameters.restitution"),
]
IDS = [f"{p}:{old}" for p, _, _, old, _ in RENAMES]


def a_point(pb: Any) -> np.ndarray | None:
    """A point of the unknowns where the residual is defined (None: no residual)."""
    if pb.name == "ndof_two_walls":  # its symmetric orbit at omega = 1.5: two impacts
        return np.asarray(pb.start_points({"omega": 1.5})[0].y, dtype=float)
    if pb.name == "ndof_impact_hybrid":  # on its section u_c = 0, falling fast: an impact
        return np.concatenate([np.zeros(pb.dim - 3), [-5.0, 0.0, 1.5]])
    if hasattr(pb, "shooting"):  # hybrid: the default initial state on the section
        return np.append(pb.default_initial()[pb.shooting.free_idx], pb.values[pb.parameter])
    if pb.name in ("ndof_impact", "bar_continuum"):
        return np.linspace(0.3, 1.1, pb.dim)
    return None


def assert_same_problem(a: Any, b: Any) -> None:
    assert type(a) is type(b)
    assert a.params == b.params
    assert a.variables == b.variables and a.parameter == b.parameter
    y = a_point(a)
    if y is not None:
        np.testing.assert_array_equal(a.evaluate(y), b.evaluate(y))


def deprecations(record: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in record if issubclass(w.category, DeprecationWarning)]


@pytest.mark.parametrize("name, new, old, old_key, new_key", RENAMES, ids=IDS)
def test_old_key_gives_the_same_problem_with_a_warning(name, new, old, old_key, new_key):
    cls = registry.get(name)
    with pytest.warns(ParameterDeprecationWarning) as record:
        legacy = cls(old)
    assert deprecations(record) == [f"{old_key} is deprecated: use {new_key}"]
    assert issubclass(ParameterDeprecationWarning, DeprecationWarning)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the current keys warn about nothing
        current = cls(new)
    assert_same_problem(legacy, current)


@pytest.mark.parametrize("name, new, old, old_key, new_key", RENAMES, ids=IDS)
def test_old_and_new_key_together_is_an_error_naming_both(name, new, old, old_key, new_key):
    both = yaml.safe_load(yaml.safe_dump(old))  # a deep copy
    node, leaf = both, new_key.split(".")[1:]
    for part in leaf[:-1]:
        node = node[part]
    node[leaf[-1]] = node[old_key.split(".")[-1]]
    with pytest.raises(ValidationError) as err:
        registry.get(name)(both)
    assert old_key in str(err.value) and new_key in str(err.value)
    with pytest.raises(CaseError) as err2:  # the Python API: one line naming both
        api_problem(name, both)
    msg = str(err2.value)
    assert "\n" not in msg and msg.startswith(old_key) and new_key in msg


def test_the_continued_parameter_old_name_maps_to_the_new_one():
    from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem

    a, b = ImpactOscillatorProblem({}), ImpactOscillatorProblem({})
    with pytest.warns(ParameterDeprecationWarning, match="parameters.sigma is deprecated: use "
                                                         "parameters.gap"):
        assert a.parameter_bounds("sigma", -0.5, 0.5) == (-0.5, 0.5)
    b.parameter_bounds("gap", -0.5, 0.5)
    assert a.parameter == b.parameter == "gap" and a.variables == b.variables
    y = a_point(a)
    np.testing.assert_array_equal(a.evaluate(y), b.evaluate(y))
    with pytest.warns(ParameterDeprecationWarning):
        a.set_parameter("e")
    assert a.parameter == "restitution"


def case_with(source: str, parameters: dict[str, Any], **continuation: Any) -> dict[str, Any]:
    raw = cases.load_raw(CASES / source)
    raw["parameters"] = parameters
    raw["continuation"].update(continuation)
    return raw


def test_a_case_with_old_keys_validates_to_the_same_problem():
    raw_new = cases.load_raw(CASES / "pendulum_sec6_1_complete_to_incomplete.yaml")
    params = dict(raw_new["parameters"])
    params["e"] = params.pop("restitution")
    with pytest.warns(ParameterDeprecationWarning) as record:
        case, legacy = cases.validate(case_with("pendulum_sec6_1_complete_to_incomplete.yaml",
                                                params, parameter="e"))
    assert set(deprecations(record)) == {"parameters.e is deprecated: use parameters.restitution"}
    _, current = cases.validate(raw_new)
    assert legacy.parameter == "restitution"
    assert_same_problem(legacy, current)


def test_errors_of_a_renamed_key_name_the_new_key():
    raw = case_with("chain_two_mass_wall.yaml", {"e": 1.2})
    with pytest.warns(ParameterDeprecationWarning), pytest.raises(CaseError) as err:
        cases.validate(raw)
    assert str(err.value).startswith("parameters.restitution: Input should be less than 1")


def test_validate_refuses_both_keys_with_one_line(write_case, capsys):
    raw = case_with("impact_oscillator_fig2_sticking.yaml",
                    {"zeta": 0.1, "omega": 0.4, "sigma": 0.0, "gap": 0.0})
    path = write_case(raw, "both.yaml")
    capsys.readouterr()
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: parameters.sigma and parameters.gap given together")


def test_cli_prints_the_deprecation_once(tmp_path, write_case):
    raw = case_with("impact_oscillator_fig2_sticking.yaml",
                    {"zeta": 0.1, "omega": 0.4, "sigma": 0.0, "e": 0.6},
                    parameter="sigma", min=-0.1, max=0.1)
    path = write_case(raw, "old.yaml")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    proc = subprocess.run([sys.executable, "-m", "nsm_continuation.cli", "validate", str(path),
                           "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    # sigma is used twice (a key and the continued parameter), e once: one line each
    assert proc.stderr.count("parameters.sigma is deprecated: use parameters.gap") == 1, \
        proc.stderr
    assert proc.stderr.count("parameters.e is deprecated: use parameters.restitution") == 1
    assert len(proc.stderr.strip().splitlines()) == 2, proc.stderr


def first_case_parameters(name: str) -> dict[str, Any]:
    for path in sorted(CASES.glob("*.yaml")):
        raw = cases.load_raw(path)
        if raw["problem"] == name:
            return raw["parameters"]
    raise AssertionError(f"no bundled case of {name}")


@pytest.mark.parametrize("name", sorted(k for k, v in registry.available().items()
                                        if v.startswith("nsm_continuation.problems.")))
def test_dict_and_model_give_the_same_problem(name):
    cls = registry.get(name)
    params = first_case_parameters(name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the bundled cases use the current keys only
        from_dict = cls(params)
        from_model = cls(cls.Parameters.model_validate(params))
    assert_same_problem(from_dict, from_model)


def test_as_parameters_refuses_anything_else():
    from nsm_continuation.problems.bar.wfem_bar import WfemBarParameters

    model = WfemBarParameters(cells=100)
    assert as_parameters(WfemBarParameters, model) is model
    assert as_parameters(WfemBarParameters, {"cells": 100}) == model
    with pytest.raises(TypeError, match="mapping or a WfemBarParameters"):
        as_parameters(WfemBarParameters, [("cells", 100)])
