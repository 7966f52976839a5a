"""Inputs a new user tried from the README that got a confusing answer: each is now refused
before computing with one line naming the key and the real cause (exit status 2 on the
command line, a ``CaseError`` from the Python API).

* ``formulation: shooting`` with a start on a pole (``mode``, ``all``): its Jacobian loses rank
  there (docs/theory.md), and the start failed with "Newton did not converge
  (residual 4.4e-16)";
* ``newton_tol`` below double precision's resolution: "did not converge (residual 7e-18)";
* a list value of a ``float | list`` key with one bad entry (``stiffness: [1, 0, 1]``): "Input
  should be a valid number" for the whole key, instead of the entry and its bound;
* ``continuation: null`` (or a number for a block): pydantic's "instance of ContinuationSpec";
* ``--set start[0].mode=2``: "start[0]: unknown key" (a list index in a dotted key);
* ``--out ''``: silently ignored, the run written to ``runs/<name>``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers import ROOT

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases import CaseError

DEFAULT = str(ROOT / "yaml_cases" / "ndof_default.yaml")


def refused(overrides: dict) -> str:
    with pytest.raises(CaseError) as err:
        nsm.load_case(DEFAULT, overrides)
    msg = str(err.value)
    assert "\n" not in msg
    return msg


@pytest.mark.parametrize(("start", "key"), [({"mode": 1}, "start.mode"),
                                            ({"all": True}, "start.all")])
def test_shooting_from_a_pole_is_refused(start: dict, key: str) -> None:
    msg = refused({"parameters.formulation": "shooting", "start": start})
    assert msg.startswith(f"{key}: this start lies on a pole k T_j") and "half_angle" in msg
    nsm.load_case(DEFAULT, {"parameters.formulation": "shooting", "start": {"T": 4.2}})


@pytest.mark.parametrize("tol", [1e-16, 1e-20, 5e-324])
def test_a_newton_tolerance_below_double_precision_is_refused(tol: float) -> None:
    msg = refused({"continuation.newton_tol": tol})
    assert msg.startswith("continuation.newton_tol: ") and "below 1e-15" in msg
    nsm.load_case(DEFAULT, {"continuation.newton_tol": 1e-15})


@pytest.mark.parametrize(("value", "expected"), [
    ([1.0, 0.0, 1.0], "parameters.chain.stiffness[1]: Input should be greater than 0"),
    ([1.0, True, 1.0], "parameters.chain.stiffness[1]: Input should be a valid number (got True)"),
    (0.0, "parameters.chain.stiffness: Input should be greater than 0"),
    ("abc", "parameters.chain.stiffness: Input should be a valid number (got 'abc')"),
])
def test_the_entry_of_a_list_is_named(value: object, expected: str) -> None:
    assert refused({"parameters.chain": {"dofs": 3, "mass": 1.0, "stiffness": value}}) == expected


@pytest.mark.parametrize(("key", "value", "shown"), [
    ("continuation", None, "None"), ("output", "x", "'x'"), ("continuation.step", [], "[]")])
def test_a_block_that_is_not_a_mapping_says_so(key: str, value: object, shown: str) -> None:
    assert refused({key: value}) == f"{key}: expected a mapping of keys (key: value), got {shown}"


def test_a_list_index_in_a_dotted_key_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["validate", DEFAULT, "--set", "parameters.chain.mass[1]=2"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("error: --set parameters.chain.mass[1]: mass[1] indexes a list, which a "
                   "dotted key cannot; set the whole list instead, e.g. --set "
                   "'parameters.chain.mass=[...]'")
    assert refused({"start[0].mode": 2}).startswith("overrides: start[0].mode: start[0] indexes "
                                                   "a list")


def test_an_empty_out_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    for command in ("validate", "run"):
        assert cli.main([command, DEFAULT, "--out", ""]) == 2
        assert capsys.readouterr().err.startswith("error: --out: the path is empty")
    assert not any(tmp_path.iterdir())
