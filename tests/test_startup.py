"""Start-up cost (issue 13): what the command line imports. Each check runs in a fresh
interpreter (this process has long imported everything) and looks at ``sys.modules``; no timing
is asserted (machines differ: ``benchmarks/bench_startup.py`` measures the times)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]

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
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


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


def test_a_run_without_plots_imports_neither_matplotlib_nor_dask(tmp_path):
    case = yaml.safe_load((ROOT / "yaml_cases" / "ndof_default.yaml").read_text())
    case["output"] = {"plots": False, "progress": False}
    case["continuation"]["max_points"] = 40  # the import graph is that of the full run
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    run = tmp_path / "run"
    out = _loaded_after(
        "from nsm_continuation.cli import main\n"
        f"out['code'] = main(['run', {str(path)!r}, '--out', {str(run)!r}, '--quiet'])\n"
        "out['before'] = sorted({m.partition('.')[0] for m in sys.modules})\n"
        "import nsm_continuation.plots  # the control: plotting does load matplotlib\n"
        "out['plots'] = 'matplotlib' in sys.modules")
    assert out["code"] == 0
    assert "casadi" in out["before"]  # it did compute (the check is not vacuous)
    assert "matplotlib" not in out["before"]
    assert "dask" not in out["before"] and "distributed" not in out["before"]
    assert out["plots"] is True
    written = {p.name for p in run.iterdir()}
    assert "report.json" in written and not any(n.endswith(".png") for n in written)
    assert json.loads((run / "report.json").read_text())["figures"] == []
