"""How a YAML case is read (``nsm_continuation/cases/schema.py``: ``parse_yaml``, ``_format``):
numbers YAML 1.1 reads differently from YAML 1.2 are refused with the key named and the value as
written, a key written next to a merge key (``<<:``) overrides the merged one, and keys that
are no names or hold invisible characters are shown so that the user sees them.

Oracle: the YAML specifications (1.1 reads ``010`` as 8 and ``1:00`` as 60, 1.2 reads them as 10
and a string; the merge rule lets a mapping's own key override a merged one) and the one-line,
exit-2, nothing-written promise of the command line."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from helpers import CASES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases.schema import parse_yaml
from nsm_continuation.core.errors import CaseError

#: the default chain case with ``{dofs}`` and ``{max_points}`` to fill in (a run of it would
#: take seconds, but every case here is refused before computing)
TEMPLATE = """\
name: yaml_input
problem: ndof_impact
parameters:
  chain: {{dofs: {dofs}, mass: 0.2, stiffness: 5.0}}
  gap: 1.0
start: {{mode: 1}}
continuation: {{parameter: omega, min: 1.0, max: 2.0, max_points: {max_points}}}
output: {{plots: false, progress: false}}
"""

YAML11 = [
    ("octal", {"dofs": "010", "max_points": 3},
     "parameters.chain.dofs: '010' is an octal number in YAML 1.1 (read as 8) and 10 in YAML "
     "1.2; write 10 (or 8) without the leading zero"),
    ("base 60", {"dofs": 5, "max_points": "1:00"},
     "continuation.max_points: '1:00' is a base-60 number in YAML 1.1 (read as 60) and a "
     "string in YAML 1.2; write 60"),
    ("base 60 float", {"dofs": 5, "max_points": "1:30.5"},
     "continuation.max_points: '1:30.5' is a base-60 number in YAML 1.1 (read as 90.5)"),
    ("signed octal", {"dofs": "-0_7", "max_points": 3},
     "parameters.chain.dofs: '-0_7' is an octal number in YAML 1.1 (read as -7)"),
]


@pytest.mark.parametrize(("label", "fill", "needle"), YAML11, ids=[c[0] for c in YAML11])
def test_yaml11_numbers_are_refused_naming_the_key(
        write_case: Callable[..., Path], refused_before_computing: Callable[[Path, str], None],
        label: str, fill: dict[str, Any], needle: str) -> None:
    refused_before_computing(write_case(TEMPLATE.format(**fill)), needle)


def test_yaml11_number_in_a_set_override_names_the_override(
        write_case: Callable[..., Path], capsys: pytest.CaptureFixture[str]) -> None:
    path = write_case(TEMPLATE.format(dofs=5, max_points=3))
    assert cli.main(["validate", str(path), "--set", "continuation.max_points=0100"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("error: --set continuation.max_points: '0100' is an octal number in YAML "
                   "1.1 (read as 64) and 100 in YAML 1.2; write 100 (or 64) without the "
                   "leading zero, or quote it for a string"), err


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(digits=st.from_regex(r"\A[0-7][0-7_]{0,6}\Z"), sign=st.sampled_from(["", "-", "+"]),
       key=st.from_regex(r"\A[a-z][a-z_]{0,8}\Z"))
def test_a_leading_zero_is_never_read_as_octal(digits: str, sign: str, key: str) -> None:
    """``<key>: <sign>0<digits>`` is refused naming the key and quoting the text; quoted, it
    is the string."""
    text = f"{sign}0{digits}"
    with pytest.raises(CaseError) as exc:
        parse_yaml(f"outer:\n  {key}: {text}\n", "case file c.yaml")
    assert str(exc.value).startswith(f"outer.{key}: {text!r} is an octal number in YAML 1.1")
    assert "\n" not in str(exc.value)
    assert parse_yaml(f"outer:\n  {key}: '{text}'\n", "f") == {"outer": {key: text}}


@pytest.mark.parametrize("text", ["0", "10", "-3", "0.5", "1.0e-9", "0x10", "1_000"])
def test_numbers_both_versions_agree_on_are_read(text: str) -> None:
    assert isinstance(parse_yaml(f"x: {text}", "f")["x"], int | float)


# --------------------------------------------------------------------------- merge keys
def test_a_key_written_next_to_a_merge_key_overrides_the_merged_one() -> None:
    text = ("base: &b {min: 1.0, max: 2.0, max_points: 3}\n"
            "continuation:\n  <<: *b\n  max: 1.5\n"
            "other: {max: 1.2, <<: *b}\n")
    data = parse_yaml(text, "f")
    assert data["continuation"] == {"min": 1.0, "max": 1.5, "max_points": 3}
    assert data["other"] == {"min": 1.0, "max": 1.2, "max_points": 3}


def test_a_case_overriding_a_merged_key_runs_validation(write_case: Callable[..., Path],
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    text = TEMPLATE.format(dofs=5, max_points=3).replace(
        "continuation: {parameter: omega, min: 1.0, max: 2.0, max_points: 3}",
        "defaults: &d {parameter: omega, min: 1.0, max: 2.0, max_points: 3}\n"
        "continuation:\n  <<: *d\n  max: 1.9\n").replace("name: yaml_input\n", "")
    raw = parse_yaml(text, "f")
    del raw["defaults"]
    case = nsm.load_case(raw)
    assert case.continuation.max == 1.9


@pytest.mark.parametrize("text", ["m: {x: 1, x: 2}", "m:\n  x: 1\n  x: 2\n",
                                  "b: &b {y: 1}\nm: {<<: *b, <<: *b}"])
def test_a_key_written_twice_in_one_mapping_is_still_refused(text: str) -> None:
    with pytest.raises(CaseError, match=r"^f: not valid YAML \(line \d\): duplicate key"):
        parse_yaml(text, "f")


# --------------------------------------------------------------------------- key display
KEYS = [
    ("number key", {"parameters": {5: 1}},
     "parameters: the key 5 is not a name (keys are strings; quote it, '5', if it is meant "
     "as one)"),
    ("number key deeper", {"continuation": {"bounds": {3: [0, 1]}}},
     "continuation.bounds: the key 3 is not a name"),
    ("zero-width space", {"parameters": {"ga\u200bp": 1.0}},
     "parameters.'ga\\u200bp': unknown key"),
    ("control character", {"continuation": {"ma\x07x": 2.0}},
     "continuation.'ma\\x07x': unknown key"),
    ("cyrillic letter", {"output": {"pl\u043ets": False}},
     "output.'pl\\u043ets': unknown key"),
    ("cyrillic problem", {"problem": "ndof_imp\u0430ct"},
     "problem: unknown problem 'ndof_imp\\u0430ct': it holds the character '\\u0430'"),
    ("trailing space", {"problem": "ndof_impact "},
     "problem: unknown problem 'ndof_impact '"),
    ("empty problem", {"problem": ""}, "problem: unknown problem ''"),
]


@pytest.mark.parametrize(("label", "change", "needle"), KEYS, ids=[c[0] for c in KEYS])
def test_keys_and_problem_names_are_shown_as_they_are(label: str, change: dict[str, Any],
                                                      needle: str) -> None:
    """The one line names the key itself (not its value), with invisible and look-alike
    characters escaped; the problem name likewise."""
    raw = parse_yaml(TEMPLATE.format(dofs=5, max_points=3), "f")
    for k, v in change.items():
        raw[k] = {**raw[k], **v} if isinstance(v, dict) and isinstance(raw.get(k), dict) else v
    with pytest.raises(CaseError) as exc:
        nsm.load_case(raw)
    assert str(exc.value).startswith(needle), str(exc.value)
    assert "\n" not in str(exc.value) and str(exc.value).isascii()


#: characters a key must not hide: invisible (format, control, odd spaces) or a letter of
#: another script that looks like a Latin one
HIDDEN = st.characters(categories=["Cf", "Cc", "Zs", "Zl", "Zp"], exclude_characters=" ") \
    | st.sampled_from(
    ["\u0430", "\u043e", "\u0440", "\u0435", "\u03bf", "\u0391"])


@settings(max_examples=40, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(head=st.from_regex(r"\A[a-z]{1,4}\Z"), hidden=HIDDEN,
       tail=st.from_regex(r"\A[a-z_]{1,4}\Z"))
def test_an_unknown_key_hiding_a_character_is_shown_escaped(head: str, hidden: str,
                                                            tail: str) -> None:
    key = head + hidden + tail
    raw = parse_yaml(TEMPLATE.format(dofs=5, max_points=3), "f")
    raw["continuation"][key] = 1
    with pytest.raises(CaseError) as exc:
        nsm.load_case(raw)
    assert str(exc.value) == f"continuation.{ascii(key)}: unknown key"


@pytest.mark.parametrize("key", ["zz_\u00fcn\u00ef", "\u043f\u0430\u0440\u0430\u043c",
                                 "max points"])
def test_a_key_of_one_script_is_shown_as_written(key: str) -> None:
    """Accented Latin, or all Cyrillic, is what the user sees: shown as written."""
    raw = parse_yaml(TEMPLATE.format(dofs=5, max_points=3), "f")
    raw["continuation"][key] = 1
    with pytest.raises(CaseError, match=f"^continuation.{key}: unknown key$"):
        nsm.load_case(raw)


def test_bundled_case_still_reads() -> None:
    """The bundled cases use none of these forms (a regression guard for the loader)."""
    for path in sorted(CASES.glob("*.yaml")):
        assert isinstance(parse_yaml(path.read_text(), str(path)), dict)
