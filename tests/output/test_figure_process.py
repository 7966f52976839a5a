"""The process that draws a run's figures, started by the command line before the computation
(:class:`nsm_continuation.figures.process.FigureProcess`): the same files as
drawing in this process, byte for byte, for each kind of problem (its copy of the problem is
the one made at the fork); this process never imports matplotlib; the child is ended and
reaped when the run fails, is interrupted or draws itself. Each run is in a fresh interpreter
(this test process may run Dask's threads, which turn the fork off)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import ROOT, run_fresh

from nsm_continuation.figures import process as figure_process

pytestmark = pytest.mark.skipif(not figure_process.FORKS or figure_process.usable_cores() < 2,
                                reason="the figures are drawn by a forked child on Linux "
                                       "with two cores")


#: one case per problem family that declares ``figures_from_inputs`` and per kind of figure:
#: the chain (w_N), hybrid forced systems declared in YAML (impacts panels; the double
#: pendulum is of the same class family), the bar's lattice (space-time fields, re-simulated
#: from the problem), the bar's continuum, the bouncing ball, orbit figures
CASES = [("ndof_default.yaml", 60), ("impact_oscillator_grazing.yaml", 12),
         ("chain_two_mass_wall.yaml", 10), ("wfem_fig18_two_contact_phases.yaml", 12),
         ("bar_continuum_main.yaml", 20), ("ball_fig1_fig4_chatter.yaml", 8),
         ("ndof_fig5_1_branches.yaml", 25)]


@pytest.mark.parametrize("name, points", CASES)
def test_figures_drawn_while_computing_are_those_drawn_after(tmp_path, name, points):
    """The command line's run (child started before the computation) against the same run
    with forking off (every figure drawn by this process after the computation): the same
    figure list in ``report.json`` and the same bytes in every PNG; the figures were drawn
    by other processes, and the main process never imported matplotlib."""
    case = ROOT / "yaml_cases" / name
    out = run_fresh(
        "import json, os, sys\n"
        "from nsm_continuation import cli\n"
        "from nsm_continuation.figures import process as figure_process\n"
        f"args = ['--quiet', '--set', 'continuation.max_points={points}']\n"
        "send = figure_process.FigureProcess.send\n"
        "used = []\n"
        "def spy(self, res, d):\n"
        "    used.append(self.pid)\n"
        "    return send(self, res, d)\n"
        "figure_process.FigureProcess.send = spy\n"
        f"assert cli.main(['run', {str(case)!r}, '--out', 'forked', *args]) == 0\n"
        "parent_mpl = 'matplotlib' in sys.modules\n"
        "figure_process.FORKS = False\n"
        f"assert cli.main(['run', {str(case)!r}, '--out', 'here', *args]) == 0\n"
        "print(json.dumps({'child': used[0], 'me': os.getpid(), 'parent_mpl': parent_mpl,\n"
        "                  'mpl_after': 'matplotlib' in sys.modules}))\n", tmp_path)
    info = json.loads(out.strip().splitlines()[-1])
    assert info["child"] is not None and info["child"] != info["me"]
    assert info["parent_mpl"] is False and info["mpl_after"] is True  # the control
    forked, here = tmp_path / "forked", tmp_path / "here"
    figures = json.loads((here / "report.json").read_text())["figures"]
    assert len(figures) >= 1
    assert json.loads((forked / "report.json").read_text())["figures"] == figures
    for f in figures:
        assert (forked / f).read_bytes() == (here / f).read_bytes(), f


def test_a_problem_that_does_not_declare_figures_from_inputs_is_drawn_here(tmp_path):
    """A problem class without ``figures_from_inputs`` (the default: its figures may use
    state the run leaves in it) starts no child: the figures are drawn by the process that
    computed, from the problem the run used (a figure reading that state sees it)."""
    out = run_fresh(
        "import json, os\n"
        "from nsm_continuation import cli\n"
        "from nsm_continuation.figures import multipliers as plots\n"
        "from nsm_continuation.figures import process as figure_process\n"
        "from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem\n"
        "NDofImpactProblem.figures_from_inputs = False\n"
        "started = []\n"
        "start = figure_process.FigureProcess.__init__\n"
        "def spy(self, case, problem, draw):\n"
        "    started.append(1)\n"
        "    start(self, case, problem, draw)\n"
        "figure_process.FigureProcess.__init__ = spy\n"
        "derived = NDofImpactProblem.derived\n"
        "def counted(self, y):\n"
        "    # state the run leaves in this problem object: the points it analysed\n"
        "    self.seen = getattr(self, 'seen', 0) + 1\n"
        "    return derived(self, y)\n"
        "NDofImpactProblem.derived = counted\n"
        "from nsm_continuation.problems.chain.presentation import ChainPresentation\n"
        "real = ChainPresentation.extra_plots\n"
        "def extra(self, out_dir, branches, window):\n"
        "    (out_dir / 'seen.txt').write_text(f'{getattr(self.problem, \"seen\", 0)}')\n"
        "    return [*real(self, out_dir, branches, window), 'seen.txt']\n"
        "ChainPresentation.extra_plots = extra\n"
        "code = cli.main(['run', '--out', 'run', '--quiet', '--set',\n"
        "                 'continuation.max_points=10', '--set', 'continuation.max_energy=7'])\n"
        "print(json.dumps({'code': code, 'started': len(started), 'me': os.getpid()}))\n",
        tmp_path)
    info = json.loads(out.strip().splitlines()[-1])
    assert info["code"] == 0 and info["started"] == 0
    # left by the run, seen by the figure; a copy made before the run has seen no point
    assert int((tmp_path / "run" / "seen.txt").read_text()) > 0
    assert "fep.png" in json.loads((tmp_path / "run" / "report.json").read_text())["figures"]


def test_the_child_is_ended_when_it_does_not_draw(tmp_path):
    """``close`` before drawing kills and reaps the child (it wrote nothing); a run holding
    problems made during it (a diagram's switched branches) or objects that do not pickle is
    drawn by the caller: ``send`` returns False and the child is gone; without fork, with one
    core for this process (its affinity), or when the system refuses a process, nothing is
    started."""
    out = run_fresh(
        "import dataclasses, json, os\n"
        "import nsm_continuation as nsm\n"
        "from nsm_continuation.figures import process as figure_process\n"
        "from nsm_continuation.figures.make import make_all\n"
        "res = nsm.run('yaml_cases/ndof_default.yaml', {'continuation.max_points': 5,\n"
        "              'output.plots': False}).run_result\n"
        "def gone(pid):\n"
        "    try:\n"
        "        os.waitpid(pid, os.WNOHANG)\n"
        "    except ChildProcessError:\n"
        "        return True\n"
        "    return False\n"
        "fp = figure_process.FigureProcess(res.case, res.problem, make_all)\n"
        "a = fp.pid\n"
        "fp.close()\n"
        "fp.close()  # twice is harmless\n"
        "fp = figure_process.FigureProcess(res.case, res.problem, make_all)\n"
        "b = fp.pid\n"
        "switched = dataclasses.replace(res, branch_problems={1: res.problem})\n"
        "drawn = fp.send(switched, 'nowhere')\n"
        "fp = figure_process.FigureProcess(res.case, res.problem, make_all)\n"
        "c = fp.pid\n"
        "unsendable = fp.send(dataclasses.replace(res, timings={'f': lambda: 0}), 'nowhere')\n"
        "cores = os.sched_getaffinity(0)\n"
        "os.sched_setaffinity(0, {min(cores)})  # as under taskset -c 0\n"
        "one_core = figure_process.FigureProcess(res.case, res.problem, make_all)\n"
        "os.sched_setaffinity(0, cores)\n"
        "real_fork = os.fork\n"
        "def no_fork():\n"
        "    raise BlockingIOError(11, 'Resource temporarily unavailable')\n"
        "os.fork = no_fork\n"
        "refused = figure_process.FigureProcess(res.case, res.problem, make_all)\n"
        "os.fork = real_fork\n"
        "figure_process.FORKS = False\n"
        "idle = figure_process.FigureProcess(res.case, res.problem, make_all)\n"
        "print(json.dumps({'a': [a, gone(a)], 'b': [b, gone(b)], 'drawn': drawn,\n"
        "                  'c': [c, gone(c)], 'unsendable': unsendable,\n"
        "                  'idle': [idle.pid, idle.send(res, 'nowhere')],\n"
        "                  'refused': [refused.pid, refused.send(res, 'nowhere')],\n"
        "                  'one_core': [one_core.pid, one_core.send(res, 'nowhere')],\n"
        "                  'files': sorted(os.listdir('.'))}))\n", ROOT)
    info = json.loads(out.strip().splitlines()[-1])
    assert info["a"][0] and info["a"][1] is True
    assert info["b"][0] and info["b"][1] is True and info["drawn"] is False
    assert info["c"][0] and info["c"][1] is True and info["unsendable"] is False
    assert info["idle"] == [None, False]
    assert info["refused"] == [None, False]  # no process to spare: the caller draws
    assert info["one_core"] == [None, False]  # one core for this process: no child
    assert "nowhere" not in info["files"]


def test_a_failure_in_the_child_is_reported_by_the_run(tmp_path):
    """A figure that raises in the child: the run ends with the command line's bug report
    (exit 1, the message names the figure's error), nothing is written, the child reaped."""
    out = run_fresh(
        "import contextlib, io, json, os\n"
        "from nsm_continuation import cli\n"
        "from nsm_continuation.figures import multipliers as plots\n"
        "def broken(res, path):\n"
        "    raise ValueError('no data for this panel')\n"
        "plots.multipliers_plane = broken\n"
        "with contextlib.redirect_stderr(io.StringIO()) as err:\n"
        "    code = cli.main(['run', '--out', 'run', '--quiet', '--set',\n"
        "                     'continuation.max_points=10'])\n"
        "print(json.dumps({'code': code, 'err': err.getvalue(),\n"
        "                  'files': sorted(os.listdir('.'))}))\n", tmp_path)
    info = json.loads(out.strip().splitlines()[-1])
    assert info["code"] == 1
    assert "figures: ValueError: no data for this panel" in info["err"]
    assert not any(f == "run" or f.startswith(".run") for f in info["files"])
    Path(info["err"].rsplit("traceback in ", 1)[1].split(")")[0].strip()).unlink()


def test_a_failure_while_the_child_draws_ends_it(tmp_path):
    """The run fails after the child received the branches (writing the report raises): exit
    1 with the error named, nothing written, and the child that was drawing is killed and
    reaped (it does not go on writing into the removed folder)."""
    out = run_fresh(
        "import contextlib, io, json, os\n"
        "from nsm_continuation import cli\n"
        "from nsm_continuation.figures import process as figure_process\n"
        "from nsm_continuation.output import files as results\n"
        "pids = []\n"
        "start = figure_process.FigureProcess.__init__\n"
        "def spy(self, case, problem, draw):\n"
        "    start(self, case, problem, draw)\n"
        "    pids.append(self.pid)\n"
        "figure_process.FigureProcess.__init__ = spy\n"
        "def broken(*a, **k):\n"
        "    raise ValueError('the report broke')\n"
        "results.build_report = broken\n"
        "with contextlib.redirect_stderr(io.StringIO()) as err:\n"
        "    code = cli.main(['run', '--out', 'run', '--quiet', '--set',\n"
        "                     'continuation.max_points=10'])\n"
        "print(json.dumps({'code': code, 'err': err.getvalue(), 'child': pids[0],\n"
        "                  'alive': os.path.exists(f'/proc/{pids[0]}'),\n"
        "                  'files': sorted(os.listdir('.'))}))\n", tmp_path)
    info = json.loads(out.strip().splitlines()[-1])
    assert info["code"] == 1 and "the report broke" in info["err"]
    assert info["child"] and info["alive"] is False
    assert not any(f == "run" or f.startswith(".run") for f in info["files"])
    Path(info["err"].rsplit("traceback in ", 1)[1].split(")")[0].strip()).unlink()


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_while_computing_ends_the_child_too(tmp_path, sig, code):
    """SIGINT / SIGTERM during the computation: the run exits as usual (130 / 143, nothing
    written) and the child that waited to draw is gone, not left behind."""
    pid_file = tmp_path / "child.pid"
    script = (
        "import sys\n"
        "from nsm_continuation import cli\n"
        "from nsm_continuation.figures import process as figure_process\n"
        "start = figure_process.FigureProcess.__init__\n"
        "def spy(self, case, problem, draw):\n"
        "    start(self, case, problem, draw)\n"
        f"    open({str(pid_file)!r}, 'w').write(str(self.pid))\n"
        "figure_process.FigureProcess.__init__ = spy\n"
        "sys.exit(cli.main(sys.argv[1:]))\n")
    slow = ROOT / "yaml_cases" / "ndof_fig3_2_fep.yaml"
    proc = subprocess.Popen(
        [sys.executable, "-c", script, "run", str(slow), "--out", str(tmp_path / "out"),
         "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.time()
    while not pid_file.exists() or not pid_file.read_text():
        assert proc.poll() is None, proc.communicate()
        assert time.time() - t0 < 60
        time.sleep(0.05)
    child = int(pid_file.read_text())
    assert Path(f"/proc/{child}").exists()
    time.sleep(1.0)  # inside the computation
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert not (tmp_path / "out").exists()
    # reaped by the run (not a zombie waiting for init): no such process any more
    assert not Path(f"/proc/{child}").exists()
