"""The chain with two contacts (``yaml_cases/ndof_two_walls_modes.yaml``) against the closed
form of its symmetric orbits, point by point and event by event.

Runs the case (or reads a finished run: ``--from DIR``) and compares every continued orbit with
the closed form at its frequency (``tests/oracles/chain_two_walls.py``: the kernel of
``expm(A T/2) + S``, the saltation monodromy): the energy (relative), the multipliers (the
largest distance of an optimal pairing), the stability; and every change of the number of
multipliers outside the unit circle of the closed form on a fine grid of each branch's range,
refined by bisection, against the events reported there. Prints the table and the run's time.

Run: ``python benchmarks/bench_two_walls.py [--from DIR]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# the closed form's small dense algebra is slower on a threaded BLAS than on one thread
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from helpers import msd  # noqa: E402
from oracles.chain_two_walls import TwoWallChain  # noqa: E402

import nsm_continuation as nsm  # noqa: E402

#: a multiplier farther than this outside the unit circle counts as outside
OUTSIDE = 1e-6
#: the kinds of event at which the number of multipliers outside the circle changes
CROSSINGS = ("fold", "branch_point", "neimark_sacker", "period_doubling", "stability_change")


def n_outside(oracle: TwoWallChain, omega: float) -> int:
    return int(np.sum(np.abs(oracle.multipliers(2 * np.pi / omega)) > 1 + OUTSIDE))


def oracle_changes(oracle: TwoWallChain, lo: float, hi: float, n: int = 4000) -> list[float]:
    """Where the closed form's count of multipliers outside the circle changes in [lo, hi]."""
    grid = np.linspace(lo, hi, n)
    counts = [n_outside(oracle, w) for w in grid]
    out = []
    for k in range(n - 1):
        if counts[k] != counts[k + 1]:
            a, b = grid[k], grid[k + 1]
            for _ in range(50):
                mid = 0.5 * (a + b)
                a, b = (mid, b) if n_outside(oracle, mid) == counts[k] else (a, mid)
            out.append(0.5 * (a + b))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--from", dest="folder", default=None, help="a finished run's folder")
    args = parser.parse_args()
    if args.folder:
        res, dt = nsm.Result.load(args.folder), float("nan")
    else:
        t0 = time.perf_counter()
        res = nsm.run(ROOT / "yaml_cases" / "ndof_two_walls_modes.yaml", {"output.plots": False})
        dt = time.perf_counter() - t0
    oracle = TwoWallChain(5, 0.2, 5.0, 1.0)
    print(f"ndof_two_walls_modes: {sum(len(b.y) for b in res.branches)} points, {dt:.1f} s")
    for b in res.branches:
        cols = b.columns()
        om, en = np.asarray(cols["omega"]), np.asarray(cols["energy"])
        e_err, m_err, disagree = np.zeros(len(om)), np.zeros(len(om)), 0
        for i, (w, e, mult) in enumerate(zip(om, en, b.multipliers, strict=True)):
            T = 2 * np.pi / w
            e_ref = oracle.energy(oracle.symmetric_orbit(T))
            e_err[i] = abs(e - e_ref) / e_ref
            lam = oracle.multipliers(T)
            if mult is not None and len(mult):
                # relative to the largest multiplier (|lambda| ~ 1 / v near a linear grazing)
                m_err[i] = msd(np.asarray(mult), lam) / max(1.0, float(np.abs(lam).max()))
                disagree += int((np.sum(np.abs(mult) > 1 + OUTSIDE) > 0)
                                != (np.sum(np.abs(lam) > 1 + OUTSIDE) > 0))
        print(f"\nbranch {b.id} ({b.label}): omega {om.min():.6f} .. {om.max():.6f}, "
              f"{len(om)} points; ends: {b.termination}")
        v = np.abs(np.asarray(cols["min_impact_normal_velocity"]))
        for name, err in (("energy (relative)", e_err),
                          ("multipliers (pairing distance / max(1, |lambda|))", m_err)):
            k = int(np.argmax(err))
            far = v >= 0.1
            print(f"  {name}: max {err[k]:.2e} at omega = {om[k]:.6f} (impact velocity "
                  f"{v[k]:.2e}); max {err[far].max():.2e} where the impact velocity >= 0.1")
        print(f"  stability differs from the closed form's at {disagree} points")
        moved = np.asarray(cols.get("section_u5", np.full(len(om), 0.5))) == oracle.g
        if moved.any():
            # the rows on the section at the impacts on the upper wall (moved there before the
            # section u5 = 1/2 turns tangent to the flow)
            print(f"  on the impacts' section: {int(moved.sum())} points, omega "
                  f"{om[moved].min():.6f} .. {om[moved].max():.6f}; energy max "
                  f"{e_err[moved].max():.2e}, multipliers max {m_err[moved].max():.2e}")
        reported = sorted(ev.parameter for ev in res.events
                          if ev.branch == b.id and ev.kind in CROSSINGS)
        for w in oracle_changes(oracle, float(om.min()), float(om.max())):
            near = min(reported, key=lambda r, w=w: abs(r - w)) if reported else np.nan
            print(f"  closed form: count outside the circle changes at omega = {w:.10f}; "
                  f"nearest reported crossing {near:.10f} (difference {abs(near - w):.1e})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
