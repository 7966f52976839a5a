"""Every wrong argument of the Python API (``nsm_continuation/api.py``) is refused in one line
naming the argument, as a ``ValueError`` (:class:`CaseError`) or ``TypeError``, before anything
is computed or written, and in the API's words: no command-line advice (``--set``,
``--overwrite``, ``--out``).

Oracle: the argument's name in the message; the exception types the API documents."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import nsm_continuation as nsm

SMALL = {
    "name": "api_arguments",
    "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 2, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
    "start": {"mode": 1},
    "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 4},
    "output": {"plots": False, "progress": False},
}
PARAMETERS = SMALL["parameters"]


@pytest.fixture(scope="module")
def result() -> Any:
    """A run of a few points of the two-mass chain (once per module)."""
    return nsm.run(SMALL)


def _problem() -> Any:
    return nsm.problem("ndof_impact", PARAMETERS)


#: (label, call on the module's result, the argument the one line must start with, before
#: ``:``, or the start of its dotted path when it ends with ``.``)
CALLS: list[tuple[str, Callable[[Any], Any], str]] = [
    ("run: overrides a string", lambda r: nsm.run(SMALL, "continuation.max=0.8"),
     "overrides"),
    ("run: overrides a number", lambda r: nsm.run(SMALL, 5), "overrides"),
    ("run: an override not key=value", lambda r: nsm.run(SMALL, ["continuation.max"]),
     "overrides"),
    ("run: an override not a string", lambda r: nsm.run(SMALL, [5]), "overrides"),
    ("run: a mapping override key not a string", lambda r: nsm.run(SMALL, {5: 1}),
     "overrides"),
    ("run: a mapping override into a value", lambda r: nsm.run(SMALL, {"name.x": 1}),
     "overrides"),
    ("run: progress a string", lambda r: nsm.run(SMALL, progress="yes"), "progress"),
    ("load_case: overrides a string", lambda r: nsm.load_case(SMALL, "x=1"), "overrides"),
    ("load_case: a source of no kind", lambda r: nsm.load_case(5), "case"),
    ("problem: a number for the name", lambda r: nsm.problem(5), "problem"),
    ("problem: parameters a string", lambda r: nsm.problem("ndof_impact", "gap=1"),
     "parameters"),
    ("problem: parameters a list", lambda r: nsm.problem("ndof_impact", [1]), "parameters"),
    ("problem: a look-alike letter", lambda r: nsm.problem("ndof_imp\u0430ct", PARAMETERS),
     "problem"),
    ("continuation: a problem name for a Problem",
     lambda r: nsm.continuation("ndof_impact", {"mode": 1}), "problem"),
    ("continuation: start None", lambda r: nsm.continuation(_problem(), None), "start"),
    ("continuation: start a string", lambda r: nsm.continuation(_problem(), "mode 1"),
     "start"),
    ("continuation: a start key misspelt", lambda r: nsm.continuation(_problem(), {"mod": 1}),
     "start."),
    ("continuation: a guess with nan",
     lambda r: nsm.continuation(_problem(), [math.nan] * _problem().dim), "start"),
    ("continuation: a guess of words",
     lambda r: nsm.continuation(_problem(), ["a"] * _problem().dim), "start"),
    ("continuation: analysis a string",
     lambda r: nsm.continuation(_problem(), {"mode": 1}, analysis="stability"), "analysis"),
    ("continuation: a name that is a path",
     lambda r: nsm.continuation(_problem(), {"mode": 1}, name="a/b"), "name"),
    ("orbit: a branch as a string", lambda r: r.orbit("0"), "branch"),
    ("orbit: a row as a string", lambda r: r.orbit(0, "last"), "point"),
    ("orbit: no periods", lambda r: r.orbit(0, -1, 0), "periods"),
    ("plot_orbits: a nan point", lambda r: r.plot_orbits([math.nan]),
     "plot_orbits.points[0]"),
    ("plot_orbits: points a string", lambda r: r.plot_orbits("first"), "plot_orbits.points"),
    ("plot_orbits: ax a string", lambda r: r.plot_orbits(ax="x"), "plot_orbits.ax"),
    ("plot_orbits: log a string", lambda r: r.plot_orbits(log="u2"), "plot_orbits.log"),
    ("plot_orbits: a view number", lambda r: r.plot_orbits(view=3), "plot_orbits.view"),
    ("save: None", lambda r: r.save(None), "directory"),
    ("save: a number", lambda r: r.save(5), "directory"),
    ("save: overwrite a string", lambda r: r.save("x", overwrite="yes"), "overwrite"),
    ("restart: parameters a string", lambda r: r.restart(event="endpoint", parameters="x"),
     "parameters"),
    ("restart: analysis a string", lambda r: r.restart(event="endpoint", analysis="x"),
     "analysis"),
    ("restart: an event number", lambda r: r.restart(event=5), "start.event"),
    ("restart: a name that is a path", lambda r: r.restart(event="endpoint", name="a/b"),
     "name"),
]


@pytest.mark.parametrize(("label", "call", "argument"), CALLS, ids=[c[0] for c in CALLS])
def test_a_wrong_argument_is_one_line_naming_it(result: Any, tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch, label: str,
                                                call: Callable[[Any], Any],
                                                argument: str) -> None:
    monkeypatch.chdir(tmp_path)  # save("x") would write here
    with pytest.raises((ValueError, TypeError)) as exc:
        call(result)
    msg = str(exc.value)
    assert "\n" not in msg, msg
    assert msg.startswith(argument if argument.endswith(".") else f"{argument}:"), msg
    assert "--" not in msg, msg  # no command-line advice
    assert msg.isascii(), msg  # look-alike letters escaped
    assert not any(tmp_path.iterdir()), "nothing is written"


def test_saving_over_a_run_says_overwrite_true(result: Any, tmp_path: Path) -> None:
    """The output policy's refusal in this API's words."""
    result.save(tmp_path / "run", plots=False)
    with pytest.raises(ValueError) as exc:
        result.save(tmp_path / "run", plots=False)
    msg = str(exc.value)
    assert "overwrite=True" in msg and "--" not in msg and "\n" not in msg, msg
