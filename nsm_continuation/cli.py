"""Command line: ``nsm-continuation run | validate | list``.

Exit status: 0 success, 2 bad input (one line on stderr naming the key), 1 unexpected error.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from importlib import resources
from pathlib import Path

from . import __version__, cases, registry

DEFAULT_CASE = "default_case.yaml"


def _default_case_path() -> Path:
    return Path(str(resources.files("nsm_continuation").joinpath(DEFAULT_CASE)))


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="nsm-continuation",
        description="Continuation of nonsmooth modes of vibration of impacting systems.")
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run a YAML case (no file: the bundled default case)")
    r.add_argument("case", nargs="?", help="YAML case file")
    r.add_argument("--out", help="output directory (default: output.dir or runs/<name>)")
    r.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="KEY=VALUE", help="override a case key, e.g. continuation.max=2.0")
    r.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    v = sub.add_parser("validate", help="check a YAML case without running it")
    v.add_argument("case")
    v.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    sub.add_parser("list", help="list registered problems")
    return p


def _summary(rep: dict, out: Path) -> str:
    lines = [f"wrote {out}/ : {len(rep['branches'])} branches, "
             f"{rep['timings']['n_points']} points in {rep['timings']['total_s']:.2f} s"]
    for b in rep["branches"]:
        kinds: dict[str, int] = {}
        for e in b["events"]:
            kinds[e["kind"]] = kinds.get(e["kind"], 0) + 1
        ev = ", ".join(f"{k} x{n}" for k, n in sorted(kinds.items()))
        lines.append(f"  branch {b['id']} ({b['label']}): {b['n_points']} points; {ev}; "
                     f"{b['termination']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "list":
            for name, target in registry.available().items():
                print(f"{name}\t{target}")
            return 0
        path = getattr(args, "case", None) or str(_default_case_path())
        case, problem = cases.load(path, args.overrides)
        if args.command == "validate":
            print(f"{path}: valid ({case.problem}, {len(problem.variables)} unknowns)")
            for w in problem.warnings():
                print(f"warning: {w}")
            return 0
        from .results import build_report, write_outputs
        from .run import run_case

        out = Path(args.out or case.output.dir or Path("runs") / case.name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = run_case(case, problem, progress=case.output.progress and not args.quiet)
            write_outputs(res, out, plots=case.output.plots)
        if not args.quiet:
            print(_summary(build_report(res), out))
            for w in problem.warnings():
                print(f"warning: {w}")
        return 0
    except cases.CaseError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
