"""An impact damper with parameters the code was not tuned to: the events of both symmetric
orbit families (started from the closed form at omega = 2.6), with both declarations of the
walls, against the closed form (``tests/oracles/two_wall.py``). Run from the repository root:
``python benchmarks/two_wall_untuned.py`` (about a minute)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "benchmarks")]

import two_wall_events as bench  # noqa: E402
from oracles import two_wall as tw  # noqa: E402

import nsm_continuation as nsm  # noqa: E402

VALUES = {"zeta": 0.03, "mass_ratio": 0.5, "clearance": 1.4, "restitution": 0.45}
OMEGA0, WINDOW = 2.6, (0.8, 5.0)


def main() -> int:
    system = tw.damper(VALUES["zeta"], VALUES["mass_ratio"], VALUES["clearance"],
                       VALUES["restitution"])
    expected = tw.family_events(system, *WINDOW)
    exact = runs = 0
    for encoding in ("surfaces", "single"):
        for orbit in tw.orbits(system, OMEGA0):
            x = tw.state_at(orbit, 0.0)
            case = nsm.load_case(ROOT / "yaml_cases" / "impact_damper.yaml", {
                **{f"parameters.{k}": v for k, v in VALUES.items()},
                "parameters.omega": OMEGA0, "parameters.encoding": encoding,
                "output.plots": False, "continuation.min": WINDOW[0],
                "continuation.max": WINDOW[1], "continuation.max_points": 1500,
                "start": {"guess": dict(zip(["x", "y", "xdot", "ydot"], map(float, x),
                                            strict=True))}})
            t0 = time.perf_counter()
            res = nsm.run(case)
            print(f"\n[{encoding}] start on the orbit of branch {orbit.branch}: "
                  f"{sum(len(b) for b in res.branches)} points, {time.perf_counter() - t0:.1f} s")
            rows, good = bench.compare(expected, res.events, WINDOW, 1e-8)
            bench.print_table(rows)
            runs += 1
            exact += bool(good)
    print(f"\n{exact} of {runs} runs give exactly the closed form's events (to 1e-08)")
    return 0 if exact == runs else 1


if __name__ == "__main__":
    raise SystemExit(main())
