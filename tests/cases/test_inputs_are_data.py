"""Who may do what: a YAML case and a run folder are data, never code. A YAML tag that would
build a Python object, and a run folder whose report.json holds a pickle, are refused in one line
(exit 2) without running their payload; a plain scheduler address to another machine is said to
be unauthenticated (docs/runs.md, "Who may do what")."""

from __future__ import annotations

import hashlib
import json
import pickle
import shutil
import warnings
from pathlib import Path

import pytest
from helpers import CASES

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.cases.saved_runs import MARKER
from nsm_continuation.runs.execution import UnauthenticatedClusterWarning, warn_if_unauthenticated


class _Payload:
    """Creates the file ``path`` when unpickled or constructed (the attack's proof)."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self) -> tuple:
        return (Path.touch, (Path(self.path),))


def test_a_yaml_tag_that_builds_a_python_object_is_refused_and_not_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    proof = tmp_path / "PWNED"
    case = (CASES / "ndof_default.yaml").read_text() + (
        f"\nnote: !!python/object/apply:pathlib.Path.touch [!!python/object/apply:pathlib.Path "
        f"[{str(proof)!r}]]\n")
    path = tmp_path / "case.yaml"
    path.write_text(case)
    for command in ("validate", "run"):
        assert cli.main([command, str(path), "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and err.startswith("error: "), err
    assert not proof.exists() and not (tmp_path / "out").exists()


def test_a_run_folder_holding_a_pickle_is_refused_and_not_unpickled(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    res = nsm.run(CASES / "ndof_default.yaml", {"continuation.max_points": 20,
                                                "output.plots": False, "output.progress": False})
    folder = res.save(tmp_path / "run", plots=False)
    proof = tmp_path / "PWNED"
    (folder / "report.json").write_bytes(pickle.dumps(_Payload(str(proof))))
    marker = json.loads((folder / MARKER).read_text())
    marker["files"]["report.json"] = hashlib.sha256((folder / "report.json").read_bytes()
                                                    ).hexdigest()
    (folder / MARKER).write_text(json.dumps(marker))
    case = tmp_path / "restart.yaml"
    case.write_text(f"name: again\nstart: {{from: {folder}, point: 3}}\n")
    assert cli.main(["validate", str(case)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: start.from:"), err
    assert not proof.exists()
    shutil.rmtree(folder)


@pytest.mark.parametrize("address, warned", [
    ("tcp://10.1.2.3:8786", True), ("ws://cluster.example.org:8786", True),
    ("tcp://127.0.0.1:8786", False), ("tcp://localhost:8786", False),
    ("tcp://[::1]:8786", False), ("tls://cluster.example.org:8786", False),
])
def test_a_plain_address_to_another_machine_is_said_to_be_unauthenticated(
        address: str, warned: bool) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_if_unauthenticated(address)
    found = [w for w in caught if issubclass(w.category, UnauthenticatedClusterWarning)]
    assert bool(found) is warned
    if warned:
        assert address in str(found[0].message) and "tls://" in str(found[0].message)
