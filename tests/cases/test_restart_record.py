"""A saved run's restart record is input (``nsm_continuation/cases/saved_runs.py``): a
``report.json`` whose ``restart`` block has wrong types, lengths, non-finite numbers or
duplicated entries is refused when it is read, in one line naming ``start.from`` and the
field's path in the record, never with a traceback or a numpy message.

Oracle: the record a run of the chain writes (which loads unchanged), and single mutations of
it written into a run folder whose marker lists the mutated report's SHA-256 (as the tool
would have written it)."""

from __future__ import annotations

import copy
import hashlib
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from helpers import CASES
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import nsm_continuation as nsm
from nsm_continuation.cases.restart import RestartSpec, select
from nsm_continuation.cases.saved_runs import MARKER, load_run
from nsm_continuation.core.errors import CaseError

#: the default chain case cut short: a branch with a fold, period doublings and endpoints
OVERRIDES = {"continuation.min": 1.42, "continuation.max": 1.49, "output.plots": False,
             "output.progress": False}


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run of the chain saved in a folder (once per module)."""
    res = nsm.run(CASES / "ndof_default.yaml", OVERRIDES)
    folder = tmp_path_factory.mktemp("runs") / "chain"
    res.save(folder, plots=False)
    return folder


def record_of(folder: Path) -> dict[str, Any]:
    """The ``restart`` block of the run's report.json."""
    return json.loads((folder / "report.json").read_text())["restart"]


def write_run(src: Path, dst: Path, block: dict[str, Any]) -> Path:
    """``src`` copied to ``dst`` (replacing it) with ``block`` as its restart record, and the
    marker listing the new report's SHA-256: a run folder as the tool would have written it."""
    shutil.rmtree(dst, ignore_errors=True)
    shutil.copytree(src, dst)
    rep = json.loads((dst / "report.json").read_text())
    rep["restart"] = block
    (dst / "report.json").write_text(json.dumps(rep))
    marker = json.loads((dst / MARKER).read_text())
    marker["files"]["report.json"] = hashlib.sha256((dst / "report.json").read_bytes()
                                                    ).hexdigest()
    (dst / MARKER).write_text(json.dumps(marker))
    return dst


def _event(block: dict[str, Any], kind: str) -> int:
    """The position of the first event of ``kind`` in branch 0."""
    return next(k for k, e in enumerate(block["branches"][0]["events"]) if e["kind"] == kind)


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """A mutation setting the dotted ``path`` (list items by ``[n]``) to ``value``."""

    def apply(block: dict[str, Any]) -> None:
        node: Any = block
        keys = [int(p) if p.isdigit() else p for p in path.replace("[", ".").replace("]", "")
                .split(".")]
        for k in keys[:-1]:
            node = node[k]
        node[keys[-1]] = value

    return apply


def _duplicate_event(block: dict[str, Any]) -> None:
    events = block["branches"][0]["events"]
    k = _event(block, "fold")
    events.insert(k + 1, copy.deepcopy(events[k]))


def _event_without_kind(block: dict[str, Any]) -> None:
    del block["branches"][0]["events"][2]["kind"]


def _duplicate_branch(block: dict[str, Any]) -> None:
    block["branches"].append(copy.deepcopy(block["branches"][0]))


def _short_tangent(block: dict[str, Any]) -> None:
    block["branches"][0]["events"][2]["tangent"].pop()


BAD: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("y a string", _set("branches[0].events[2].y", "1, 2"),
     "restart.branches[0].events[2].y: Input should be a valid list"),
    ("events a string", _set("branches[0].events", "fold"),
     "restart.branches[0].events: Input should be a valid list"),
    ("event without kind", _event_without_kind,
     "restart.branches[0].events[2].kind: required key is missing"),
    ("duplicated event", _duplicate_event, "restart.branches[0].events["),
    ("duplicated branch", _duplicate_branch,
     "restart.branches[1].id: branch 0 is listed twice"),
    ("short tangent", _short_tangent, "restart.branches[0].events[2].tangent: "),
    ("nan in y", _set("branches[0].events[2].y[0]", float("nan")),
     "restart.branches[0].events[2].y[0]: Input should be a finite number"),
    ("inf tangent", _set("branches[0].events[2].tangent[1]", float("inf")),
     "restart.branches[0].events[2].tangent[1]: Input should be a finite number"),
    ("branch id a string", _set("branches[0].id", "0"),
     "restart.branches[0].id: Input should be a valid integer (got '0')"),
    ("branch id a float", _set("branches[0].id", 0.5),
     "restart.branches[0].id: Input should be a valid integer"),
    ("csv a path", _set("branches[0].csv", "../../etc/passwd"),
     "restart.branches[0].csv: String should match pattern"),
    ("branches a mapping", _set("branches", {"0": {}}),
     "restart.branches: Input should be a valid list"),
    ("parameters a list", _set("parameters", [1, 2]),
     "restart.parameters: expected a mapping of keys (key: value), got [1, 2]"),
    ("row past the end", _set("branches[0].events[2].row", 10**6),
     "restart.branches[0].events[2].row: 1000000, the branch has"),
]


@pytest.mark.parametrize(("label", "mutate", "needle"), BAD, ids=[b[0] for b in BAD])
def test_malformed_record_is_one_line_naming_the_field(
        saved: Path, tmp_path: Path, write_case: Any,
        refused_before_computing: Callable[[Path, str], None], label: str,
        mutate: Callable[[dict[str, Any]], None], needle: str) -> None:
    """``validate`` and ``run`` of a restart from the malformed run: exit 2, one line
    ``start.from: <run>/report.json: restart.<path>: ...``, nothing written."""
    block = record_of(saved)
    mutate(block)
    run = write_run(saved, tmp_path / "bad_run", block)
    case = write_case({"name": "again", "start": {"from": str(run), "point": 0},
                       "output": {"progress": False}})
    refused_before_computing(case, f"start.from: {run}/report.json: {needle}")


def test_the_record_a_run_writes_loads_unchanged(saved: Path) -> None:
    """The schema accepts every record the tool writes, and keeps it as written."""
    assert load_run(str(saved)).restart == record_of(saved)


def test_a_curve_records_its_derived_bounds_as_json_pairs(saved: Path) -> None:
    """A located curve's ``base_settings.derived_bounds`` (written from tuples, read back from
    JSON as lists) is accepted as the pair it was (the sticking-lost curve of the double
    pendulum bounds ``sticking_time``); a pair of another length or of text is refused."""
    from nsm_continuation.cases.saved_runs import RestartRecord, check_record

    block = record_of(saved)
    curve = {"kind": "sticking_lost", "free": "restitution", "method": "located",
             "base_settings": {"newton_tol": 1e-9, "step_initial": 1e-3,
                               "derived_bounds": {"sticking_time": [1e-4, None]}}}
    good = json.loads(json.dumps({**block, "curve": curve}))
    check_record(good, "run/report.json")
    rec = RestartRecord.model_validate(good)
    assert rec.curve.base_settings.derived_bounds == {"sticking_time": (1e-4, None)}
    for bad in ([1e-4], [1e-4, None, 1.0], ["1e-4", None]):
        curve["base_settings"]["derived_bounds"]["sticking_time"] = bad
        with pytest.raises(CaseError, match="restart.curve.base_settings.derived_bounds."
                                            "sticking_time"):
            check_record(json.loads(json.dumps({**block, "curve": curve})), "run/report.json")


# --------------------------------------------------------------------------- mutations
def _paths(node: Any, at: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key and list index of ``node``, as paths from the root."""
    out = [at] if at else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, (*at, k))
    elif isinstance(node, list):
        for k, v in enumerate(node):
            out += _paths(v, (*at, k))
    return out


JSON_SCALARS = (st.none() | st.booleans() | st.integers(-3, 10**6) | st.floats()
                | st.text(max_size=6))
JSON_VALUES = JSON_SCALARS | st.lists(JSON_SCALARS, max_size=4) \
    | st.dictionaries(st.text(max_size=4), JSON_SCALARS, max_size=3)
MUTATIONS = st.sampled_from(["replace", "delete", "duplicate"])
FUZZ = settings(max_examples=150, deadline=None, derandomize=True, database=None,
                phases=[Phase.explicit, Phase.generate],
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


@FUZZ
@given(data=st.data())
def test_mutated_record_loads_identically_or_is_one_line(saved: Path, tmp_path: Path,
                                                          data: st.DataObject) -> None:
    """One field of a valid record replaced by any JSON value (types, non-finite numbers),
    deleted, or (a list item) duplicated: the record either loads as written, and the point
    of a restart from it is selected without error or with a one-line ``start.`` error, or
    it is refused with one line starting ``start.from:``; never another exception."""
    block = record_of(saved)
    path = data.draw(st.sampled_from(_paths(block)))
    how = data.draw(MUTATIONS)
    *head, last = path
    node: Any = block
    for k in head:
        node = node[k]
    if how == "replace":
        node[last] = data.draw(JSON_VALUES)
    elif how == "delete":
        del node[last]
    elif isinstance(node, list):
        node.insert(last, copy.deepcopy(node[last]))
    else:
        node[last] = [node[last], node[last]]
    run = write_run(saved, tmp_path / "mutated", block)
    try:
        record = load_run(str(run))
    except CaseError as exc:
        line = str(exc)
        assert "\n" not in line and line.startswith("start.from:"), line
        return
    assert json.dumps(record.restart, sort_keys=True) == json.dumps(block, sort_keys=True)
    for spec in ({"from": str(run), "point": 0}, {"from": str(run), "event": "fold"}):
        try:
            sel = select(record, RestartSpec.model_validate(spec))
        except CaseError as exc:
            line = str(exc)
            assert "\n" not in line and line.startswith("start."), line
        else:
            assert sel.y.size == len(sel.variables)
