"""The package as a user installs it: build the wheel and the sdist, install the wheel in a
fresh virtual environment, and from an empty folder run what the README says.

    python benchmarks/check_wheel.py [--keep]      # a few minutes; not part of the test suite

Checks, each printed with its time:

1. ``python -m build`` (else ``pip wheel``, the wheel only) builds
   ``dist/*.whl`` and ``dist/*.tar.gz``; the wheel holds every bundled case
   (``nsm_continuation/yaml_cases/**.yaml``), ``py.typed`` and the licence;
2. a fresh venv under the system's temporary folder installs the wheel (dependencies from the
   configured index);
3. in an empty folder: ``nsm-continuation --version``, ``cases``, ``run ndof_fig3_2_fep``
   (a bundled case by name), ``python -m nsm_continuation list``, the README's Python
   example as written, and ``nsm.load`` of the run written by (3);
4. the sdist unpacked: its tests are collected without an error by the installed package
   (``pytest --collect-only``, the console script) and its packaging and loading tests pass.

Exit status 0 when everything passed; 1 with the failing step named. ``--keep`` keeps the
temporary folders. Offline without the build backend in the index, step 1 says so and the
script exits 0 having checked nothing (``SKIPPED``).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def step(title: str, cmd: list[str], cwd: Path, timeout: float = 1800) -> str:
    """Run ``cmd`` in ``cwd``; its stdout; exit 1 naming ``title`` when it fails."""
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    print(f"{title}: exit {proc.returncode} in {time.perf_counter() - t0:.1f} s")
    if proc.returncode != 0:
        print(proc.stdout[-3000:], proc.stderr[-3000:], sep="\n")
        sys.exit(1)
    return proc.stdout


def build(out: Path) -> tuple[Path, Path] | None:
    """The wheel and the sdist built into ``out``; None when no build frontend works
    offline."""
    for cmd in ([sys.executable, "-m", "build", "--outdir", str(out), str(ROOT)],):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
        if proc.returncode == 0:
            break
    else:
        proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-w",
                               str(out), str(ROOT)], capture_output=True, text=True,
                              timeout=1800)
        if proc.returncode != 0:
            print("SKIPPED: cannot build the wheel here:", proc.stderr[-1000:])
            return None
    wheels, sdists = sorted(out.glob("*.whl")), sorted(out.glob("*.tar.gz"))
    if not wheels:
        return None
    return wheels[0], (sdists[0] if sdists else Path())


def readme_example() -> str:
    """The README's first ``python`` block (the Python API example), as written."""
    text = (ROOT / "README.md").read_text()
    m = re.search(r"```python\n(.*?)```", text, re.S)
    assert m is not None, "README.md has no python block"
    return m.group(1)


def main() -> int:
    keep = "--keep" in sys.argv
    tmp = Path(tempfile.mkdtemp(prefix="nsm-wheel-"))
    try:
        t0 = time.perf_counter()
        built = build(tmp / "dist")
        if built is None:
            return 0
        wheel, sdist = built
        print(f"built {wheel.name} and {sdist.name or 'no sdist'} in "
              f"{time.perf_counter() - t0:.1f} s")
        names = zipfile.ZipFile(wheel).namelist()
        cases = [n for n in names if n.startswith("nsm_continuation/yaml_cases/")
                 and n.endswith(".yaml")]
        expected = sorted(p for p in (ROOT / "yaml_cases").rglob("*.yaml"))
        assert len(cases) == len(expected), (len(cases), len(expected))
        assert "nsm_continuation/py.typed" in names
        assert any(n.endswith("licenses/LICENSE") for n in names), "no LICENSE in the wheel"
        print(f"wheel: {len(cases)} bundled cases, py.typed, LICENSE")
        venv = tmp / "venv"
        step("fresh venv", [sys.executable, "-m", "venv", str(venv)], tmp)
        py = str(venv / "bin" / "python")
        exe = str(venv / "bin" / "nsm-continuation")
        step("pip install the wheel", [py, "-m", "pip", "install", "-q", f"{wheel}[test]"], tmp)
        work = tmp / "empty"
        work.mkdir()
        print(step("--version", [exe, "--version"], work).strip())
        step("cases", [exe, "cases"], work)
        print(step("run ndof_fig3_2_fep (by name)", [exe, "run", "ndof_fig3_2_fep"],
                   work).splitlines()[0])
        step("python -m nsm_continuation list", [py, "-m", "nsm_continuation", "list"], work)
        (work / "readme_example.py").write_text(readme_example())
        step("the README's Python example", [py, "readme_example.py"], work)
        print(step("nsm.load of the run", [py, "-c", "import nsm_continuation as nsm; "
                   "print(repr(nsm.load('runs/ndof_fig3_2_fep')).splitlines()[0])"],
                   work).strip())
        if sdist.name:
            with tarfile.open(sdist) as tar:
                tar.extractall(tmp / "sdist", filter="data")
            src = next((tmp / "sdist").iterdir())
            # the console script, as the README says: `python -m pytest` would put the
            # unpacked sources (without nsm_continuation.problems) before the installed wheel
            pytest = str(venv / "bin" / "pytest")
            out = step("sdist: pytest --collect-only", [pytest, "--collect-only", "-q", "-p",
                                                        "no:cacheprovider"], src)
            print(out.strip().splitlines()[-1])
            step("sdist: packaging and loading tests",
                 [pytest, "-q", "-p", "no:cacheprovider", "tests/interface/test_packaging.py",
                  "tests/output/test_loading.py"], src)
        print("OK")
        return 0
    finally:
        if keep:
            print(f"kept {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
