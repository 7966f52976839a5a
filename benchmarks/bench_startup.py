"""Start-up and output cost of a run: wall time against compute time.

Prints
1. the import time of ``nsm_continuation.cli`` in a fresh interpreter (best of ``--repeat``),
   next to a bare ``python -c pass``, the imports a run of the chain needs (cases, runner,
   results, the ``ndof_impact`` problem) and the figure module (matplotlib); and which heavy
   packages ``import nsm_continuation.cli`` loads (none is the goal);
2. for the bundled default case (``nsm-continuation run``, no argument) and Fig. 3.2
   (``yaml_cases/ndof_fig3_2_fep.yaml``), with and without figures (``output.plots: false`` in
   a copy of the case in a temporary folder): the wall time of the command in a fresh process,
   the compute time the report states (``report.json``: ``timings.total_s``), and the rest
   (interpreter and imports, case and problem set-up, report, figures, the final move); the
   figures cost the difference of the rest with and without them.

Each command is ``python -c "from nsm_continuation.cli import main; main()" run CASE --out TMP
--quiet`` (what the ``nsm-continuation`` script runs, without a shim in front), run
``--repeat`` times: the best wall time, the best compute time and the least rest (wall minus
compute of one run, which the noise of the computation does not reach). OpenBLAS is pinned to
one thread (``OPENBLAS_NUM_THREADS=1`` unless set), as in the other benchmarks. The load
average is printed before and after: the numbers are only comparable on an otherwise idle
machine.

Run: ``python benchmarks/bench_startup.py [--repeat 3] [--skip-fep]`` (2 cores, Python 3.11;
the machine in ``/work/.library/env``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "yaml_cases" / "ndof_default.yaml"
FEP = ROOT / "yaml_cases" / "ndof_fig3_2_fep.yaml"
HEAVY = ("matplotlib", "dask", "distributed", "casadi", "pydantic", "scipy", "numpy", "tqdm")
MAIN = "import sys; from nsm_continuation.cli import main; sys.exit(main())"


def env() -> dict[str, str]:
    e = dict(os.environ)
    e.setdefault("OPENBLAS_NUM_THREADS", "1")
    return e


def python(code: str, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          env=env(), cwd=cwd, check=True)


def import_time(modules: str, repeat: int) -> float:
    """Best wall time [s] of ``import <modules>`` in a fresh interpreter (after its start-up)."""
    code = (f"import time; t = time.perf_counter(); import {modules}; "
            "print(time.perf_counter() - t)")
    return min(float(python(code).stdout) for _ in range(repeat))


def startup(repeat: int) -> float:
    """Best wall time [s] of a bare interpreter, ``python -c pass``."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        python("pass")
        best = min(best, time.perf_counter() - t0)
    return best


def loaded_by_cli() -> list[str]:
    code = ("import sys, json; import nsm_continuation.cli; "
            "print(json.dumps(sorted({m.partition('.')[0] for m in sys.modules})))")
    return sorted(set(json.loads(python(code).stdout)) & set(HEAVY))


def run(case: Path | None, tmp: Path, repeat: int) -> tuple[float, float, float]:
    """Over ``repeat`` runs of the command: the best wall time [s], the best compute time [s]
    its report states, and the least difference of the two in one run [s] (the rest: what
    start-up and output cost, without the noise of the computation)."""
    runs = []
    for k in range(repeat):
        out = tmp / f"out-{case.stem if case else 'default'}-{k}"
        t0 = time.perf_counter()
        python(MAIN, "run", *([str(case)] if case else []), "--out", str(out), "--quiet",
               cwd=tmp)
        wall = time.perf_counter() - t0
        runs.append((wall, json.loads((out / "report.json").read_text())["timings"]["total_s"]))
    return (min(w for w, _ in runs), min(c for _, c in runs), min(w - c for w, c in runs))


def without_plots(case: Path, tmp: Path) -> Path:
    data = yaml.safe_load(case.read_text())
    data.setdefault("output", {})["plots"] = False
    copy = tmp / f"{case.stem}_noplots.yaml"
    copy.write_text(yaml.safe_dump(data, sort_keys=False))
    return copy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-fep", action="store_true", help="only the default case")
    a = ap.parse_args()
    print(f"machine: {os.cpu_count()} cores, {platform.machine()}, {platform.platform()}, "
          f"Python {platform.python_version()}; load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")

    print(f"1. imports, fresh interpreter, best of {a.repeat} [s]")
    rows = [("python -c pass (whole process)", startup(a.repeat)),
            ("import nsm_continuation.cli", import_time("nsm_continuation.cli", a.repeat)),
            ("+ what a chain run needs (cases, runner, results, ndof_impact)",
             import_time("nsm_continuation.cli, nsm_continuation.cases.schema, "
                         "nsm_continuation.runs.runner,"
                         " nsm_continuation.output.files, "
                         "nsm_continuation.problems.chain.ndof_impact", a.repeat)),
            ("import nsm_continuation.figures.branches (with matplotlib)",
             import_time("nsm_continuation.figures.branches", a.repeat))]
    for name, t in rows:
        print(f"   {name:66s} {t:6.3f}")
    heavy = loaded_by_cli()
    print(f"   heavy packages loaded by `import nsm_continuation.cli`: "
          f"{', '.join(heavy) if heavy else 'none'}")

    print(f"2. nsm-continuation run, fresh process, {a.repeat} runs: best wall, best compute, "
          "least rest [s]")
    print(f"   {'case':34s} {'plots':>5s} {'wall':>7s} {'compute':>8s} {'rest':>6s} "
          f"{'rest/wall':>9s}")
    cases = [("default (no argument)", None, DEFAULT)]
    if not a.skip_fep:
        cases.append(("Fig. 3.2 (ndof_fig3_2_fep.yaml)", FEP, FEP))
    with tempfile.TemporaryDirectory(prefix="bench-startup-") as d:
        tmp = Path(d)
        for label, case, source in cases:
            rest = {}
            for plots, path in ((True, case), (False, without_plots(source, tmp))):
                wall, compute, rest[plots] = run(path, tmp, a.repeat)
                print(f"   {label:34s} {'yes' if plots else 'no':>5s} {wall:7.2f} "
                      f"{compute:8.2f} {rest[plots]:6.2f} {rest[plots] / wall:9.0%}")
            print(f"   {'':34s} figures cost {rest[True] - rest[False]:.2f} s (rest with "
                  "plots - rest without)")
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
