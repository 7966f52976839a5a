"""Command line: ``nsm-continuation run | validate | list | cases | recover`` (also
``python -m nsm_continuation``). A case is a YAML file or the name of a bundled case
(:mod:`nsm_continuation.cases.bundled`); figures are drawn with matplotlib's Agg backend, which
the command line chooses for itself (:func:`main`).

Exit status (docs/runs.md, "Runs: output folders, exit status, limits"):

* 0: every start gave a branch (``validate``: the case is valid);
* 2: bad input: one line on stderr naming the key (or the output path), nothing written, found
  before any computation (``validate`` runs exactly the same checks);
* 3: the report was written but some start failed (said in the summary and the report);
* 4: no space left (or the disk quota exhausted) while the results were written: one line naming
  the folder and the bytes the results need; they were kept in a new folder of the system's
  temporary directory, which the line names, when it had room;
* 130 / 143: interrupted by SIGINT / SIGTERM: no partial output, the previous result intact;
* 1: a bug (an exception that should not happen): one line, the traceback saved to a file.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from nsm_continuation import __version__

if TYPE_CHECKING:
    from nsm_continuation.cases.schema import Case
    from nsm_continuation.output.folders import OutputTarget

# Everything else is imported where it is used: ``--version``, ``--help`` and ``list`` start
# without pydantic, CasADi or NumPy, and no path imports matplotlib or Dask unless it plots
# (:mod:`nsm_continuation.figures.branches`, from ``results.write_files``) or distributes
# (:mod:`nsm_continuation.runs.execution`); ``tests/interface/test_startup_imports.py`` checks it.

#: the bundled case ``run`` runs when given no file (``yaml_cases/ndof_default.yaml``, the
#: package data of ``nsm_continuation.yaml_cases``: :mod:`nsm_continuation.cases.bundled`)
DEFAULT_CASE = "ndof_default.yaml"


def _default_case_path() -> Path:
    from importlib import resources

    return Path(str(resources.files("nsm_continuation.yaml_cases").joinpath(DEFAULT_CASE)))


class _Parser(argparse.ArgumentParser):
    """argparse with the tool's error convention: one line on stderr, exit status 2."""

    def error(self, message: str) -> NoReturn:
        print(f"error: {self.prog}: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


#: the examples of ``--help``
EXAMPLES = """\
examples:
  nsm-continuation run                          the bundled default case -> runs/ndof_default/
  nsm-continuation run ndof_fig3_2_fep          a bundled case by name (Fig. 3.2 of the chain)
  nsm-continuation run my_case.yaml --out runs/study --set continuation.max=2.0
  nsm-continuation run restart/chain_two_mass_switch_period2
                                                a restart case (after: run chain_two_mass_wall)
  nsm-continuation validate my_case.yaml        check a case without running it
  nsm-continuation list                         the problems a case may name
  nsm-continuation cases                        the bundled cases
  nsm-continuation cases --copy my_cases        copy them to edit them
  python -c "import nsm_continuation as nsm; print(nsm.load('runs/ndof_default'))"
                                                a saved run read back in Python
"""


def _parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="nsm-continuation",
        description="Continuation of nonsmooth modes of vibration of impacting systems. A case "
                    "is a YAML file, or the name of a bundled case (nsm-continuation cases).",
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a YAML case (no file: the bundled default case)",
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("case", nargs="?", help="YAML case file, or the name of a bundled case "
                                           "(an existing path wins)")
    r.add_argument("--out", help="output directory (default: output.dir or runs/<name>)")
    r.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="KEY=VALUE", help="override a case key, e.g. continuation.max=2.0")
    r.add_argument("--overwrite", action="store_true",
                   help="replace a previous run in the output directory (only the files it "
                        "wrote; never files this tool did not write)")
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    cluster = r.add_mutually_exclusive_group()
    cluster.add_argument("--workers", type=_positive_int, metavar="N",
                         help="compute the branches on a local Dask cluster of N worker "
                              "processes (same results as serial)")
    cluster.add_argument("--scheduler", metavar="ADDRESS",
                         help="compute the branches on the Dask cluster at ADDRESS "
                              "(tcp://HOST:8786)")
    v = sub.add_parser("validate", help="check a YAML case (and where it would write) without "
                                        "running it")
    v.add_argument("case", help="YAML case file, or the name of a bundled case")
    v.add_argument("--out", help="output directory the run would use")
    v.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    v.add_argument("--overwrite", action="store_true", help="as for run")
    sub.add_parser("list", help="list the registered problems, with what each one is")
    c = sub.add_parser("cases", help="list the bundled cases (run one by its name)")
    c.add_argument("--copy", metavar="DIR", help="copy every bundled case into DIR (a new "
                                                 "file each; never over an existing one)")
    rec = sub.add_parser("recover", help="settle what a killed run left in a folder: put back "
                                         "a previous run whose replacement was cut, remove "
                                         "the temporary folders and locks of killed runs")
    rec.add_argument("folder", help="an output folder, or the folder holding output folders")
    return p


def _shown(path: str | Path) -> str:
    """A path for stdout: bytes that are not UTF-8 (surrogates, ``os.fsdecode``) as ``\\xff``."""
    return str(path).encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


def _summary(rep: dict, out: Path) -> str:
    lines = [f"wrote {_shown(out)}/ : {len(rep['branches'])} branches, "
             f"{rep['timings']['n_points']} points in {rep['timings']['total_s']:.2f} s"]
    for b in rep["branches"]:
        kinds: dict[str, int] = {}
        for e in b["events"]:
            kinds[e["kind"]] = kinds.get(e["kind"], 0) + 1
        ev = ", ".join(f"{k} x{n}" for k, n in sorted(kinds.items()))
        lines.append(f"  branch {b['id']} ({b['label']}): {b['n_points']} points; {ev}; "
                     f"{b['termination']}")
    return "\n".join(lines)


class Interrupted(BaseException):
    """SIGTERM received: unwinds like KeyboardInterrupt (not caught by ``except Exception``)."""


#: signals received during this run (an exception raised by a handler inside a CasADi call is
#: swallowed by its wrapper: :func:`_poll` raises it again at the next point)
_received: list[int] = []


#: the run's output target (a signal after its final move is recorded, not raised)
_current: OutputTarget | None = None


def _on_signal(signum: int, frame: object) -> None:
    _received.append(signum)
    if _current is not None and _current.committed:
        return
    _raise_for(signum)


def _raise_for(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt()
    raise Interrupted()


def _poll() -> None:
    if _received:
        _raise_for(_received[0])


def _bug(exc: BaseException) -> int:
    import tempfile
    import traceback

    fd, path = tempfile.mkstemp(prefix="nsm-continuation-crash-", suffix=".txt")
    with os.fdopen(fd, "w") as fh:
        traceback.print_exception(exc, file=fh)
    print(f"error: internal error, this is a bug ({type(exc).__name__}: {exc}); "
          f"traceback in {path}", file=sys.stderr)
    return 1


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if not 1 <= n <= 1024:
        raise argparse.ArgumentTypeError(f"{n} is not in 1..1024")
    return n




def _target(args: argparse.Namespace, case: Case) -> OutputTarget:
    from nsm_continuation.output.folders import OutputTarget

    if args.out is not None and not args.out.strip():
        from nsm_continuation.core.errors import CaseError

        raise CaseError("--out: the path is empty; give the output folder (or leave --out "
                        "out: output.dir, else runs/<name>)")
    out = Path(args.out or case.output.dir or Path("runs") / case.name)
    return OutputTarget(out, "overwrite" if args.overwrite else case.output.if_exists)


def _run(args: argparse.Namespace, path: str) -> int:
    from nsm_continuation import cases
    from nsm_continuation.figures.make import make_all
    from nsm_continuation.figures.process import FigureProcess
    from nsm_continuation.output.files import (
        build_report,
        is_no_space,
        keep_elsewhere,
        presentation_warnings,
        start_warnings,
        termination_text,
        unchecked_note,
        write_files,
    )
    from nsm_continuation.runs.runner import run_case

    global _current
    case, problem = cases.load(path, args.overrides)
    # --workers / --scheduler replace the case's execution: block (and are recorded with it)
    case = cases.with_execution(case, args.workers, args.scheduler,
                                ("--workers", "--scheduler"))
    target = _current = _target(args, case)
    target.prepare()  # exit 2 here: nothing computed, nothing written
    for line in target.recovered:  # what killed runs had left next to it
        print(f"note: {line}", file=sys.stderr)
    # matplotlib is imported (and the figures drawn) by a child while this process computes
    draw = make_all if case.output.plots else None
    drawer = (FigureProcess(case, problem, draw)
              if draw is not None and problem.figures_from_inputs else None)
    res = None
    try:
        # a bar on a terminal only: a log file gets the summary, not the bar's redraws
        res = run_case(case, problem, progress=case.output.progress and not args.quiet
                       and sys.stderr.isatty(),
                       poll=_poll)
        assert target.tmp is not None
        failures = write_files(res, target.tmp, draw, drawer)
        _poll()
        out = target.commit()
    except BaseException as exc:
        if drawer is not None:  # first: it may be drawing into the folder abort removes
            drawer.close()
        where = target.path
        target.abort()  # frees the space the temporary folder took
        if res is not None and isinstance(exc, OSError) and is_no_space(exc):
            raise keep_elsewhere(res, where, exc) from None
        raise
    for line in failures:  # a plugin's hook: its part was left out, the rest written
        print(f"warning: {line}", file=sys.stderr)
    if _received:  # arrived during the final move, held until it was complete
        print(f"interrupted: the results were complete and are in {out}", file=sys.stderr)
        return 130 if _received[0] == signal.SIGINT else 143
    failed = [b for b in res.branches if b.failed_start]
    if case.output.orbits is not None:
        from nsm_continuation.figures.orbit_selection import spec_warnings

        for w in spec_warnings(res):  # also in report.md; stderr even with --quiet
            print(f"warning: {w}", file=sys.stderr)
    for w in start_warnings(res.branches):  # also in report.md; stderr even with --quiet
        print(f"warning: {w}", file=sys.stderr)
    if not args.quiet:
        print(_summary(build_report(res, failures=[]), out))
        for w in presentation_warnings(problem, []):
            print(f"warning: {w}")
    note = unchecked_note(res)
    if note is not None:  # what the algorithm cannot check: the last line, even with --quiet
        print(f"warning: {note}")
    if failed:
        print(f"{len(failed)} of {len(res.branches)} starts failed: "
              + "; ".join(f"branch {b.id} ({b.label}): {termination_text(b)}" for b in failed),
              file=sys.stderr)
        return 3
    return 0


def _recover(folder: str) -> int:
    """``recover FOLDER``: settle what killed runs left in ``FOLDER`` (as the parent of output
    folders) and next to it (for the output folder ``FOLDER`` itself)."""
    from nsm_continuation.output.folders import OutputError, recover

    path = Path(os.path.abspath(folder))
    if not path.is_dir():
        raise OutputError(f"recover: {path} is not a folder")
    done = recover(path) + recover(path.parent, path.name)
    for line in done:
        print(line)
    if not done:
        print(f"nothing to recover in {path}")
    return 0


def _list() -> int:
    """``list``: each registered problem and what it is (its class docstring's first
    sentence, :func:`~nsm_continuation.cases.registry.describe`)."""
    from nsm_continuation.cases import registry

    regs = registry.registrations()
    width = max((len(name) for name in regs), default=0)
    for name, entries in regs.items():
        print(f"{name:<{width}}  {registry.describe(entries[0].target) or entries[0].target}")
        for other in entries[1:]:  # a second registration of the name: say it is ignored
            print(f"{name:<{width}}  {other.target} (duplicate from {other.dist}, ignored: "
                  f"{entries[0].target} is used)")
    return 0


def _cases(copy: str | None) -> int:
    """``cases [--copy DIR]``: the bundled cases and their descriptions, or copied."""
    from nsm_continuation.cases import bundled

    if copy is not None:
        written = bundled.copy_to(copy)
        print(f"copied {len(written)} cases into {_shown(copy)}/ (run one: "
              f"nsm-continuation run {_shown(copy)}/ndof_default.yaml)")
        return 0
    found = bundled.cases()
    width = max((len(name) for name in found), default=0)
    # the terminal's width; piped: descriptions of up to 110 characters
    room = max(shutil.get_terminal_size((width + 113, 24)).columns - width - 3, 40)
    for name, path in found.items():
        print(f"{name:<{width}}  {bundled.description(path, room)}")
    print(f"\nrun one by name: nsm-continuation run NAME ({len(found)} cases in "
          f"{_shown(bundled.folder())}; the restart/ cases need the run they start from)")
    return 0


def _dispatch(args: argparse.Namespace) -> int:
    if args.command == "recover":
        return _recover(args.folder)
    if args.command == "list":
        return _list()
    if args.command == "cases":
        return _cases(args.copy)
    path = args.case or str(_default_case_path())
    if args.command == "validate":
        from nsm_continuation import cases

        case, problem = cases.load(path, args.overrides)
        _target(args, case).check()  # where the run would write (nothing is created)
        print(f"{_shown(path)}: valid ({case.problem}, {len(problem.variables)} unknowns)")
        for w in problem.presentation.warnings():
            print(f"warning: {w}")
        return 0
    return _run(args, path)


def _is_case_error(exc: Exception) -> bool:
    """Bad input (:class:`~nsm_continuation.core.errors.CaseError`, exit status 2). Without
    importing the module when nothing did: then no CaseError can have been raised."""
    errors = sys.modules.get(f"{__package__}.core.errors")
    return errors is not None and isinstance(exc, errors.CaseError)


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring); returns the exit status. It draws into files only:
    matplotlib is told to use its Agg backend (``MPLBACKEND``, read when matplotlib is first
    imported here or in a process started here; restored on return), so a problem's figure
    drawn with ``pyplot`` never opens a window. The library itself never chooses a backend."""
    previous_backend = os.environ.get("MPLBACKEND")
    os.environ["MPLBACKEND"] = "Agg"
    try:
        return _main(argv)
    finally:
        if previous_backend is None:
            os.environ.pop("MPLBACKEND", None)
        else:
            os.environ["MPLBACKEND"] = previous_backend


def _main(argv: list[str] | None) -> int:
    global _current
    args = _parser().parse_args(argv)
    _received.clear()
    _current = None
    previous: dict[int, Any] = {}
    for sig in (signal.SIGTERM, signal.SIGINT):
        handler = signal.getsignal(sig)
        if handler is signal.SIG_IGN:  # e.g. SIGINT of a background job: respect it
            continue
        try:
            signal.signal(sig, _on_signal)
            previous[sig] = handler
        except ValueError:  # not the main thread (e.g. called from a worker): keep them
            break
    try:
        with warnings.catch_warnings():
            # numpy's RuntimeWarnings are numerical noise here: results carry their reasons
            warnings.simplefilter("ignore", RuntimeWarning)
            return _dispatch(args)
    except KeyboardInterrupt:
        print("interrupted: nothing written (any previous result is intact)", file=sys.stderr)
        return 130
    except Interrupted:
        print("terminated: nothing written (any previous result is intact)", file=sys.stderr)
        return 143
    except BrokenPipeError:  # stdout closed early (`nsm-continuation cases | head`): done
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # no second error when Python flushes stdout
        os.close(devnull)
        return 0
    except Exception as exc:
        if _is_case_error(exc):
            print(f"error: {_shown(str(exc))}", file=sys.stderr)
            return 2
        files = sys.modules.get(f"{__package__}.output.files")
        if files is not None and isinstance(exc, files.NoSpaceError):
            print(f"error: {exc}", file=sys.stderr)
            return 4
        return _bug(exc)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
