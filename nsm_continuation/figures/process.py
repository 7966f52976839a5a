"""Processes that draw a run's figures while this one does something else.

Two things cost a small run more than its computation (``benchmarks/bench_startup.py``): the
import of matplotlib (0.55 s on the 2-core machine of ``/work/.library/env``) and the drawing
of the figures (0.9 s for the default case's four). Both are moved off the critical path on a
platform that forks (:data:`FORKS`) with a second core:

* :class:`FigureProcess`, started by the command line before the computation, forks a child
  that imports :mod:`nsm_continuation.figures.kit` and lays out one throw-away figure (fonts,
  mathtext parser) while this process computes; the finished run is then sent to it through a
  pipe (its branches are plain data; the problem is the child's own copy, made at the fork)
  and it draws the figures there while this process writes the CSVs and the report;
* :func:`in_two_processes` splits the figures between a process and a forked child.

The figures are those of one process, byte for byte (``tests/interface/test_startup_imports.py``):
each is
drawn from the same data by the same code. A process that runs another thread (a Dask client's
event loop) is never forked: a lock one of them holds would stay locked in the child.
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from nsm_continuation.cases.schema import Case
    from nsm_continuation.core.problem import Problem
    from nsm_continuation.runs.result import RunResult

#: forks only here (POSIX ``fork`` without the macOS caveats)
FORKS = sys.platform.startswith("linux")

#: draws every figure of a run into a folder, returns their file names
#: (:func:`nsm_continuation.figures.make.make_all`)
Draw = Callable[["RunResult", Path], list[str]]

#: what a child sends back: ``("ok", result)`` or ``("error", "Type: message")``
Outcome = tuple[str, Any]


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says, e.g. under
    ``taskset`` or a container's cpuset), else the machine's."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # no sched_getaffinity (macOS, Windows)
        return os.cpu_count() or 1


def can_fork() -> bool:
    """A forked child may draw: the platform forks, a second core is there for this process
    (a child on the only core would slow the computation it should overlap), and this process
    runs no other thread."""
    return FORKS and usable_cores() > 1 and threading.active_count() == 1


def _run_child(work: Callable[[], Any], write: int) -> None:  # pragma: no cover - the child
    """In a forked child: ``work()``, its outcome pickled into the pipe ``write``, then exit
    without running any of the parent's clean-up (``os._exit``)."""
    try:
        outcome: Outcome = ("ok", work())
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        outcome = ("error", f"{type(exc).__name__}: {exc}")
    try:
        with os.fdopen(write, "wb") as fh:
            pickle.dump(outcome, fh)
    finally:
        os._exit(0)


def _collect(read: int, pid: int) -> Any:
    """The child's result from the pipe ``read``, the child reaped; ``RuntimeError`` with its
    message if it failed or ended without a result."""
    with os.fdopen(read, "rb") as fh:
        data = fh.read()
    os.waitpid(pid, 0)
    status, payload = pickle.loads(data) if data else (
        "error", "the process drawing figures ended without a result")
    if status != "ok":
        raise RuntimeError(f"figures: {payload}")
    return payload


def in_two_processes(jobs: list[Callable[[], list[str]]]) -> list[str]:
    """``[name for job in jobs for name in job()]``, the jobs shared with a forked child
    where :func:`can_fork`: the child draws every other job (it inherits the run and
    matplotlib, nothing is sent) and reports its file names through a pipe. A job that raises
    in the child raises here, as ``RuntimeError`` with its message."""
    if len(jobs) < 2 or not can_fork():
        return [name for job in jobs for name in job()]
    mine, theirs = jobs[0::2], jobs[1::2]
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child (its coverage is not collected)
        os.close(read)
        _run_child(lambda: [job() for job in theirs], write)
    os.close(write)
    try:
        own = [job() for job in mine]
    finally:
        payload = _collect(read, pid)
    names: list[str] = []
    for k in range(len(jobs)):
        names += own[k // 2] if k % 2 == 0 else payload[k // 2]
    return names


def _warm_up() -> None:  # pragma: no cover - runs in the child
    """Import :mod:`nsm_continuation.figures.kit` (matplotlib) and lay out one figure with text
    and mathtext, so that fonts, the text caches and the mathtext parser are ready when the run
    arrives."""
    import io

    from nsm_continuation.figures import kit as plots

    fig, ax = plots.new_figure(figsize=(2, 2))
    ax.set_xlabel(r"$\omega$ [rad/s]")
    ax.set_yscale("log")
    ax.plot([1.0, 2.0], [1.0, 10.0])
    fig.tight_layout()
    fig.savefig(io.BytesIO(), format="png")


class FigureProcess:
    """A child process, forked now (before the computation), that prepares matplotlib and
    then draws the figures of the run :meth:`send` sends it.

    The child keeps copies of the run's inputs, ``case`` and ``problem``, as they are at the
    fork (only the run's results are sent: a case may hold CasADi objects, which do not
    pickle): the figures use the problem only through its declared members and methods
    (labels, decorations, closed forms, simulations), which the computation does not change
    (``tests/output/test_figure_process.py`` compares the figures of each kind of problem). It
    ignores SIGINT and SIGTERM (the command line handles them here and :meth:`close` ends
    it) and exits when the pipe closes, also when this process dies. Where :func:`can_fork`
    is false nothing is started and :meth:`send` returns False (the caller draws)."""

    def __init__(self, case: Case, problem: Problem, draw: Draw) -> None:
        self.pid: int | None = None
        self._send: int | None = None
        self._read: int | None = None
        if not can_fork():
            return
        to_child, from_parent = os.pipe()
        from_child, to_parent = os.pipe()
        try:
            pid = os.fork()
        except OSError:  # no process to spare (EAGAIN, ENOMEM): the figures are drawn here
            for fd in (to_child, from_parent, from_child, to_parent):
                os.close(fd)
            return
        if pid == 0:  # pragma: no cover - the child
            os.close(from_parent)
            os.close(from_child)
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            _run_child(lambda: _draw_in_child(case, problem, draw, to_child), to_parent)
        os.close(to_child)
        os.close(to_parent)
        self.pid, self._send, self._read = pid, from_parent, from_child

    def send(self, res: RunResult, directory: Path) -> bool:
        """Send the run to the child, which starts drawing its figures into ``directory``
        while this process writes the rest (:meth:`figures` collects them): True. False if
        there is no child, if the run holds problems made during it (a diagram's switched
        branches), which the child does not have, or objects that cannot be sent: the caller
        then draws the figures itself (the child is ended)."""
        if self.pid is None or self._send is None:
            return False
        payload = None
        if not res.branch_problems:
            try:
                payload = pickle.dumps((dataclasses.replace(res, case=None, problem=None),
                                        Path(directory)))
            except Exception:  # noqa: BLE001 - pickle raises many types (CasADi: Exception)
                payload = None
        if payload is None:
            self.close()
            return False
        send, self._send = self._send, None
        try:
            with os.fdopen(send, "wb") as fh:
                fh.write(payload)
        except BrokenPipeError:
            pass  # the child ended early: figures() reports why
        return True

    def figures(self) -> list[str]:
        """The file names of the figures the child drew after :meth:`send`, in the order of
        :func:`nsm_continuation.figures.make.make_all`; ``RuntimeError`` with its message if it
        failed."""
        assert self.pid is not None and self._read is not None and self._send is None
        read, pid = self._read, self.pid
        self._read = self.pid = None
        return _collect(read, pid)

    def close(self) -> None:
        """End the child if its figures were not collected (the run failed, was interrupted
        or draws itself): it is killed (what it drew is in the run's own temporary folder,
        which the run then removes) and reaped."""
        if self.pid is None:
            return
        for fd in (self._send, self._read):
            if fd is not None:
                os.close(fd)
        os.kill(self.pid, signal.SIGKILL)
        os.waitpid(self.pid, 0)
        self._send = self._read = self.pid = None


def _draw_in_child(case: Case, problem: Problem, draw: Draw, read: int
                   ) -> list[str] | None:  # pragma: no cover
    """The child's work: warm up, wait for the run (None if the pipe closes first: nothing is
    drawn), draw its figures (``draw``) with the child's copies of the case and the problem."""
    _warm_up()
    with os.fdopen(read, "rb") as fh:
        data = fh.read()
    if not data:
        os._exit(0)
    res, directory = pickle.loads(data)
    return draw(dataclasses.replace(res, case=case, problem=problem), directory)
