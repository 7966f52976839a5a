"""Fixtures shared by the tests of YAML cases: a saved run through the two-mass chain's flip,
and the check that a case is refused before anything is computed."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from helpers import CASES

import nsm_continuation as nsm
from nsm_continuation import cli


@pytest.fixture(scope="module")
def flip_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path]:
    """The two-mass chain's period-1 orbit from omega = 0.69 up to 0.695: through its flip at
    omega = 0.6927610 (yaml_cases/chain_two_mass_wall.yaml); the result and the folder it is
    saved in (once per test module)."""
    res = nsm.run(CASES / "chain_two_mass_wall.yaml",
                  {"parameters.omega": 0.69, "continuation.min": 0.69,
                   "continuation.max": 0.695, "continuation.direction": "increase",
                   "continuation.step.initial": 0.005, "output.plots": False,
                   "output.progress": False})
    folder = tmp_path_factory.mktemp("runs") / "flip"
    res.save(folder, plots=False)
    return res, folder


@pytest.fixture()
def refused_before_computing(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                             ) -> Callable[[Path, str], None]:
    """``check(path, needle)``: ``validate`` and ``run`` of the case file ``path`` (with
    ``--out tmp_path / "out"``) each exit with status 2 and one line on stderr starting with
    ``error: <needle>``, and nothing is written next to the case."""

    def check(path: Path, needle: str) -> None:
        before = sorted(p.name for p in tmp_path.iterdir())
        for command in ("validate", "run"):
            assert cli.main([command, str(path), "--out", str(tmp_path / "out")]) == 2
            err = capsys.readouterr().err.strip()
            assert "\n" not in err, err
            assert err.startswith(f"error: {needle}"), err
        assert sorted(p.name for p in tmp_path.iterdir()) == before

    return check
