"""What the sensitivities' step error test (``integrator: {sensitivity_error: true}``, the
default; CVODES' ``errconS``) buys and costs, measured in one run.

1. Accuracy: the Stuart-Landau oscillator in polar form (``r' = r (mu - r^2)``, ``theta' = 1``,
   a wall at ``r = 10`` never reached, section on the angle; the case class of
   ``tests/hybrid/test_multiplier_error_control.py``), whose multiplier is ``exp(-4 pi mu)``:
   its relative error and the steps of one return, with and without the test, at several
   ``rtol`` (``atol = rtol / 100``).
2. Cost: one return with its Jacobian (a fresh simulation each time) on the start orbit of
   each bundled hybrid case (its ``start``, at the case's parameters), both settings
   alternately, ``--repeat`` times; the steps of a return and the trivial multiplier's drift
   from 1 (an oracle: exactly 1 for the period map of a forced system's orbit) for each.

BLAS is pinned to one thread; the cores are shared, so read the ratios, not the times.

    python benchmarks/bench_sensitivity_error.py [--repeat 20]

Prints two tables (no chart); the measured numbers are in benchmarks/README.md ("Error control
of the sensitivities").
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import yaml  # noqa: E402

import nsm_continuation as nsm  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CASES = ("impact_oscillator_grazing", "impact_oscillator_period_doubling", "chain_two_mass_wall",
         "two_sided_oscillator", "pendulum_sec6_1_complete_to_incomplete")


def stuart_landau_class() -> type:
    """The test's case class (one declaration of the oracle system)."""
    path = ROOT / "tests" / "hybrid" / "test_multiplier_error_control.py"
    spec = importlib.util.spec_from_file_location("sl_case", path)
    mod = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules[spec.name] = mod  # type: ignore[union-attr]  # pydantic resolves its names there
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod.StuartLandauPolar


def accuracy() -> None:
    cls = stuart_landau_class()
    print("1. Stuart-Landau (polar), multiplier exp(-4 pi mu): relative error (steps per return)")
    print(f"{'mu':>5} {'rtol':>7} | {'with the test':>22} | {'state alone':>22}")
    for mu in (0.1, 0.5, 1.0):
        exact = np.exp(-4 * np.pi * mu)
        for rtol in (1e-6, 1e-8, 1e-10, 1e-12):
            cells = []
            for flag in (True, False):
                pb = cls({"mu": mu, "integrator": {"rtol": rtol, "atol": rtol / 100,
                                                   "sensitivity_error": flag}})
                pb.set_parameter("mu")
                y = np.array([np.sqrt(mu), mu])
                m = np.linalg.eigvals(pb.shooting.poincare_jacobian(y))
                err = float(np.min(np.abs(m - exact))) / exact
                cells.append(f"{err:10.1e} ({pb.sim(y).n_steps:3d} steps)")
            print(f"{mu:5.2f} {rtol:7.0e} | {cells[0]:>22} | {cells[1]:>22}")


def cost(repeat: int) -> None:
    print("\n2. One return with its Jacobian on each bundled case's start orbit "
          f"(median of {repeat}, alternately)")
    print(f"{'case':40s} {'ms with':>8} {'ms state':>8} {'ratio':>6} {'steps':>11} "
          f"{'|triv - 1| with / state alone':>30}")
    for case in CASES:
        spec = yaml.safe_load((ROOT / "yaml_cases" / f"{case}.yaml").read_text())
        pbs, ys = {}, {}
        for flag in (True, False):
            params = dict(spec["parameters"])
            params["integrator"] = {**params.get("integrator", {}), "sensitivity_error": flag}
            pb = nsm.problem(spec["problem"], params)
            pb.set_parameter(spec["continuation"]["parameter"])
            guess = spec["start"].get("guess")
            if guess is not None:
                ys[flag] = np.array([guess[v] if v in guess else pb.values[v]
                                     for v in pb.variables], dtype=float)
            else:  # the orbit the case starts from (found by simulation)
                ys[flag] = ys.get(True, pb.start_points(spec["start"])[0].y)
            pbs[flag] = pb
        times: dict[bool, list[float]] = {True: [], False: []}
        for _ in range(repeat):
            for flag in (True, False):
                sh = pbs[flag].shooting
                sh._cache.clear()
                t0 = time.perf_counter()
                sh.poincare_jacobian(ys[flag])
                times[flag].append(time.perf_counter() - t0)
        steps = [pbs[f].sim(ys[f]).n_steps for f in (True, False)]
        triv = [pbs[f].shooting.trivial_error(ys[f]) for f in (True, False)]
        a, b = (1e3 * float(np.median(times[f])) for f in (True, False))
        print(f"{case:40s} {a:8.2f} {b:8.2f} {a / b:6.2f} {steps[0]:5d}/{steps[1]:<5d} "
              f"{triv[0]:14.1e} / {triv[1]:.1e}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()}")
    accuracy()
    cost(args.repeat)
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
