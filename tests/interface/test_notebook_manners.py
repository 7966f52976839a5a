"""The package in a notebook: it never chooses matplotlib's backend nor touches ``pyplot``'s
figures, ``progress=True`` shows a bar without a terminal, warnings go through ``logging``
(never printed by the library), and a result displays as a summary of its branches and
special points."""

from __future__ import annotations

import html.parser
import json
import logging
import re
import sys

import pytest
from helpers import PACKAGE, ROOT, run_fresh

import nsm_continuation as nsm
from nsm_continuation.core.progress import progress_bar

SMALL = {"name": "small", "problem": "ndof_impact",
         "parameters": {"chain": {"dofs": 3, "mass": 1.0, "stiffness": 1.0}, "gap": 1.0},
         "start": {"mode": 1},
         "continuation": {"parameter": "omega", "min": 0.3, "max": 0.9, "max_points": 40},
         "output": {"plots": False}}


def _sources() -> list:
    return [p for top in (PACKAGE, ROOT / "problems") for p in top.rglob("*.py")]


def test_no_module_chooses_a_backend_or_uses_pyplot() -> None:
    """The library's figures are made with the object API (``figures.kit.subplots``): no
    ``matplotlib.use`` and no ``pyplot`` anywhere in the package or its problems."""
    for path in _sources():
        text = path.read_text()
        assert not re.search(r"matplotlib\.use\(|\bimport matplotlib\.pyplot|"
                             r"from matplotlib import pyplot", text), path


def test_plotting_leaves_the_backend_and_pyplots_figures_alone(tmp_path) -> None:
    """In a fresh interpreter whose user chose a backend and drew a figure: importing the
    package, drawing a result's diagram and orbits and saving its figures leave the backend
    and ``pyplot``'s list of figures as they were."""
    code = f"""
import json, matplotlib
matplotlib.use("svg")
import matplotlib.pyplot as plt
plt.plot([0, 1], [0, 1])
before = (matplotlib.get_backend(), plt.get_fignums())
import nsm_continuation, nsm_continuation.api
import nsm_continuation.figures.make, nsm_continuation.figures.orbits
import nsm_continuation.problems.impacting.bouncing_ball
case = {SMALL!r}
res = nsm_continuation.run(case)
fig = res.plot()
orbits = res.plot_orbits(points=["first", "last"], view="phase")
res.save({str(tmp_path / "run")!r})  # every figure of the run, the problem's own included
png = fig._repr_png_()  # what Jupyter shows of a cell's value
after = (matplotlib.get_backend(), plt.get_fignums())
print(json.dumps({{"before": before, "after": after, "drawn": len(fig.axes[0].get_lines()),
                  "orbits": len(orbits.axes[0].get_lines()), "png": png[:8].hex()}}))
"""
    out = json.loads(run_fresh(code, tmp_path).strip().splitlines()[-1])
    assert out["before"] == ["svg", [1]]
    assert out["after"] == out["before"]
    assert out["drawn"] > 0 and out["orbits"] > 0
    assert bytes.fromhex(out["png"]) == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "run" / "fep.png").stat().st_size > 10_000


def test_progress_shows_a_bar_without_a_terminal(capsys: pytest.CaptureFixture[str]) -> None:
    """Under pytest stderr is no terminal (as in a notebook): asked for, the bar is shown."""
    assert not sys.stderr.isatty()
    bar = progress_bar("shown", 10)
    assert not bar.disable and type(bar).__module__.startswith("tqdm")
    bar.update(10)
    bar.close()
    nsm.run(SMALL, progress=True)
    assert "small" in capsys.readouterr().err  # the bar's description: the case's name


def test_without_tqdm_progress_is_a_plain_line(monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)  # `from tqdm.auto import` fails
    bar = progress_bar("plain", 7)
    bar.update(3)
    bar.update(4)
    bar.close()
    assert capsys.readouterr().err.endswith("\rplain: 7 points\n")


def test_warnings_are_logged_and_returned(caplog: pytest.LogCaptureFixture,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """A chain whose frequencies are in the ratio 3 (K = [[5, -4], [-4, 5]]: omega = 1, 3)
    violates the paper's Assumption 3.1: the run's warning is logged to ``nsm_continuation``
    and listed in ``Result.warnings`` as in ``report.json``, its failed start logged too;
    nothing is printed on stdout."""
    case = {**SMALL, "name": "resonant",
            "parameters": {"M": [[1, 0], [0, 1]], "K": [[5, -4], [-4, 5]], "gap": 1.0},
            "continuation": {"parameter": "omega", "min": 0.5, "max": 2.0, "max_points": 8},
            "analysis": {"stability": False}}
    with caplog.at_level(logging.WARNING, logger="nsm_continuation"):
        res = nsm.run(case)
    logged = [r.getMessage() for r in caplog.records if r.name == "nsm_continuation"]
    assert res.warnings == res.report()["warnings"]
    assert len(res.warnings) == 1 and "3 T_2 = 1 T_1" in res.warnings[0]
    # its start fails (a singular Jacobian at the resonance): said as the command line does
    assert [b.id for b in res.failed_starts] == [0]
    assert logged == [f"resonant: {res.warnings[0]}",
                      f"resonant: 1 of 1 starts failed: branch 0 ({res.branches[0].label}): "
                      f"start: {res.branches[0].raw.termination['start']}"]
    assert capsys.readouterr().out == ""


class _Cells(html.parser.HTMLParser):
    """The rows of the tables of an HTML text."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[list[list[str]]] = []

    def handle_starttag(self, tag: str, attrs: list) -> None:
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self.tables[-1][-1].append("")

    def handle_data(self, data: str) -> None:
        if self.tables and self.tables[-1] and self.tables[-1][-1]:
            self.tables[-1][-1][-1] += data


def test_a_result_displays_its_branches_and_special_points() -> None:
    res = nsm.run(SMALL)
    text = repr(res)
    assert text.splitlines()[0] == (f"Result of small (problem ndof_impact): 1 branch, "
                                    f"{len(res.branches[0])} points, {len(res.events)} events")
    cells = _Cells()
    cells.feed(res._repr_html_())
    branches, events = cells.tables
    assert branches[0] == ["branch", "label", "points", "omega", "ended"]
    assert branches[1][:3] == ["0", res.branches[0].label, str(len(res.branches[0]))]
    omega = res.branches[0]["omega"]
    assert branches[1][3] == f"{omega.min():.6g} .. {omega.max():.6g}"
    assert [row[2] for row in events[1:]] == [e.kind for e in res.events]
    assert [float(row[3]) for row in events[1:]] == pytest.approx(
        [e.record["omega"] for e in res.events], rel=1e-5)
    md = res._repr_markdown_()
    assert md.count("\n| ") == 1 + 1 + 1 + len(res.events)  # two heads, one branch, events
    for e in res.events:
        assert e.kind in text
