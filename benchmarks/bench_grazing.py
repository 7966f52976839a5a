"""Continuation to, at and through grazing: times and accuracies, one run.

Prints, for the forced impact oscillator ``q'' + 2 zeta q' + q = cos(omega t)``, ``q >= -0.5``,
restitution 0.8:

1. the bundled case ``yaml_cases/impact_oscillator_grazing.yaml`` (zeta = 0): wall time, points,
   the grazing frequency against ``sqrt(3)``;
2. the grazing located by margin-fixed solves from both sides against the closed form
   ``1/sqrt((1 - w^2)^2 + (2 zeta w)^2) = 0.5`` for zeta = 0, 0.05, 0.1;
3. the two-mass chain case ``yaml_cases/chain_two_mass_wall.yaml``: wall time and its grazing.

Target: an impacting orbit to and through grazing in < 10 s on this machine
(2 cores, Python 3.11). Run: ``python benchmarks/bench_grazing.py``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from nsm_continuation.problems.impacting.impact_oscillator import ImpactOscillatorProblem  # noqa: E402

import nsm_continuation as nsm  # noqa: E402
from nsm_continuation.hybrid.grazing import locate_grazing, step_beyond  # noqa: E402

GAP = -0.5


def amplitude(w: float, zeta: float) -> float:
    return 1.0 / np.sqrt((1 - w * w) ** 2 + (2 * zeta * w) ** 2)


def free_point(w: float, zeta: float) -> np.ndarray:
    A, ph = amplitude(w, zeta), np.arctan2(2 * zeta * w, 1 - w * w)
    return np.array([A * np.cos(np.pi - ph), -w * A * np.sin(np.pi - ph), w])


def run_case(name: str) -> tuple[float, object]:
    t0 = time.perf_counter()
    res = nsm.run(nsm.load_case(ROOT / "yaml_cases" / name))
    return time.perf_counter() - t0, res


def main() -> None:
    print("1. yaml_cases/impact_oscillator_grazing.yaml (zeta = 0)")
    dt, res = run_case("impact_oscillator_grazing.yaml")
    br = res.run_result.branches[0]
    for ev in br.events:
        if ev.kind == "grazing":
            print(f"   grazing at omega = {ev.point.y[-1]:.13f}, error vs sqrt(3): "
                  f"{ev.point.y[-1] - np.sqrt(3):+.2e}")
    print(f"   {br.n_points} points, {dt:.1f} s wall, termination {br.termination}")

    print("2. grazing located from both sides (margin-fixed solves) vs the closed form")
    print("   zeta   omega_g (closed form)   error (free side)   error (impacting side)   s")
    for zeta in (0.0, 0.05, 0.1):
        pb = ImpactOscillatorProblem({"zeta": zeta, "omega": 1.8, "gap": GAP,
                                      "restitution": 0.8, "section_phase": float(np.pi)})
        pb.set_parameter("omega")
        sh = pb.shooting
        wg = brentq(lambda w, z=zeta: amplitude(w, z) + GAP, 1.2, 3.0, xtol=1e-15)
        t0 = time.perf_counter()
        yg = locate_grazing(sh, free_point(wg + 0.02, zeta), 1e-11)
        t_in = free_point(wg - 1e-6, zeta) - free_point(wg + 1e-6, zeta)
        z = step_beyond(sh, yg, t_in / np.linalg.norm(t_in), False, 0.05)
        yg2 = locate_grazing(sh, z, 1e-11)
        print(f"   {zeta:4.2f}   {wg:.13f}       {yg[2] - wg:+.2e}           "
              f"{yg2[2] - wg:+.2e}                {time.perf_counter() - t0:.2f}")

    print("3. yaml_cases/chain_two_mass_wall.yaml")
    dt, res = run_case("chain_two_mass_wall.yaml")
    br = res.run_result.branches[0]
    for ev in br.events:
        if ev.kind == "grazing":
            print(f"   grazing at omega = {ev.point.y[-1]:.10f} "
                  f"({ev.data['signature_before']} -> {ev.data['signature_after']})")
    print(f"   {br.n_points} points, {dt:.1f} s wall")


if __name__ == "__main__":
    main()
