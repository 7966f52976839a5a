"""Start-up cost: what the command line imports. Each check runs in a fresh
interpreter (this process has long imported everything) and looks at ``sys.modules``; no timing
is asserted (machines differ: ``benchmarks/bench_startup.py`` measures the times)."""

from __future__ import annotations

import json
from pathlib import Path

import yaml
from helpers import CASES, ROOT, run_fresh

#: packages the command line must not load unless a run needs them
HEAVY = ("matplotlib", "dask", "distributed", "casadi", "pydantic", "scipy")


def _loaded_after(code: str) -> dict:
    """Run ``code`` in a fresh interpreter (from the repository, as the other command-line
    tests); the top-level packages of ``HEAVY`` loaded after it, and what ``code`` put in the
    dict ``out``."""
    script = (
        "import json, sys\nout = {}\n" + code + "\n"
        f"out['loaded'] = sorted({{m.partition('.')[0] for m in sys.modules}} & {set(HEAVY)!r})\n"
        "print(json.dumps(out))\n")
    return json.loads(run_fresh(script, ROOT).strip().splitlines()[-1])


def test_importing_the_cli_and_listing_problems_loads_no_heavy_package():
    out = _loaded_after("import nsm_continuation.cli")
    assert out["loaded"] == []
    # `list` reads the entry points only: no problem module, hence no CasADi
    out = _loaded_after(
        "import contextlib, io\nfrom nsm_continuation.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()) as s:\n"
        "    out['code'] = main(['list'])\n"
        "out['listed'] = s.getvalue()")
    assert out["code"] == 0 and "ndof_impact" in out["listed"]
    assert out["loaded"] == []


def test_a_run_without_plots_imports_neither_matplotlib_nor_dask(tmp_path, write_case):
    case = yaml.safe_load((CASES / "ndof_default.yaml").read_text())
    case["output"] = {"plots": False, "progress": False}
    case["continuation"]["max_points"] = 40  # the import graph is that of the full run
    path = write_case(case)
    run = tmp_path / "run"
    out = _loaded_after(
        "from nsm_continuation.cli import main\n"
        f"out['code'] = main(['run', {str(path)!r}, '--out', {str(run)!r}, '--quiet'])\n"
        "out['before'] = sorted({m.partition('.')[0] for m in sys.modules})\n"
        "import nsm_continuation.figures.branches  # the control: plotting does load matplotlib\n"
        "out['plots'] = 'matplotlib' in sys.modules")
    assert out["code"] == 0
    assert "casadi" in out["before"]  # it did compute (the check is not vacuous)
    assert "matplotlib" not in out["before"]
    assert "dask" not in out["before"] and "distributed" not in out["before"]
    # the chain needs no SciPy (0.3 s of imports): its modal analysis, root finding and
    # bounded minimisation are numpy and nsm_continuation's own
    assert "scipy" not in out["before"]
    assert out["plots"] is True
    written = {p.name for p in run.iterdir()}
    assert "report.json" in written and not any(n.endswith(".png") for n in written)
    assert json.loads((run / "report.json").read_text())["figures"] == []


def test_figures_drawn_in_two_processes_are_those_of_one(tmp_path):
    """``figure_process.in_two_processes`` (a forked child draws every other figure): the same
    files, in the same order in ``report.json``, byte for byte the PNGs of a single process;
    and the child was used (its pid differs)."""
    out = run_fresh(
        "import json, os\n"
        "import nsm_continuation as nsm\n"
        "from nsm_continuation import cli\n"
        "from nsm_continuation.figures import multipliers as plots\n"
        "from nsm_continuation.figures import process as figure_process\n"
        "real = plots.multipliers_along\n"
        "def spy(*a):\n"
        "    open(f'pid_{os.getpid()}', 'w').close()\n"
        "    return real(*a)\n"
        "plots.multipliers_along = spy\n"
        "res = nsm.run(nsm.load_case(cli._default_case_path(), {'output.progress': False}))\n"
        "two = res.save('two')\n"
        "figure_process.FORKS = False\n"
        "one = res.save('one')\n"
        "print(json.dumps({'pid': os.getpid(), 'one': str(one), 'two': str(two)}))\n",
        tmp_path)
    info = json.loads(out.strip().splitlines()[-1])
    one, two = Path(info["one"]), Path(info["two"])
    figures = json.loads((one / "report.json").read_text())["figures"]
    assert len(figures) >= 4
    assert json.loads((two / "report.json").read_text())["figures"] == figures
    for name in figures:
        assert (two / name).read_bytes() == (one / name).read_bytes(), name
    drawn_by = {int(p.name.removeprefix("pid_")) for p in tmp_path.glob("pid_*")}
    assert len(drawn_by) == 2 and info["pid"] in drawn_by  # the child drew one of them


def test_a_figure_failing_in_the_child_process_is_raised_here(tmp_path):
    """A job that raises in the forked child: ``RuntimeError`` naming it, the parent's own
    jobs done, the child reaped; the order of the names is the jobs' order; a process that
    runs another thread is not forked."""
    out = run_fresh(
        "from nsm_continuation.figures import process as figure_process\n"
        "def fails():\n"
        "    raise ValueError('no data for this panel')\n"
        "try:\n"
        "    figure_process.in_two_processes([lambda: ['a.png'], fails, lambda: ['c.png']])\n"
        "except RuntimeError as exc:\n"
        "    print('raised:', exc)\n"
        "print(figure_process.in_two_processes([lambda: ['a'], lambda: ['b'], lambda: [], "
        "lambda: ['d']]))\n"
        "import os, threading, time\n"
        "print('forked', len(set(figure_process.in_two_processes([lambda: [os.getpid()], "
        "lambda: [os.getpid()]]))) == 2)\n"
        "threading.Thread(target=time.sleep, args=(1,)).start()\n"
        "print('with a thread, forked', len(set(figure_process.in_two_processes([lambda: "
        "[os.getpid()], lambda: [os.getpid()]]))) == 2)\n", tmp_path)
    assert "raised: figures: ValueError: no data for this panel" in out
    assert "['a', 'b', 'd']" in out
    # a process with another thread draws everything itself
    assert "forked True" in out and "with a thread, forked False" in out
