"""Cost per continuation point against the size of a piecewise-linear impact system: the exact
flow (``integrator: {method: exact}``, :mod:`nsm_continuation.hybrid.linear_flow`) against the
Runge-Kutta path (DOP853 at ``rtol = 1e-10``, the default), measured in one run.

System: a forced chain of ``N`` unit masses, mass ``i`` tied to mass ``i - 1`` by a unit spring
(mass 1 to the ground), viscous damping ``c = 0.05`` of every mass to the ground, mass 1
forced by ``cos(omega t)``, mass ``N`` hitting a rigid wall at its rest position
(``H = gap - q_N``, ``gap = 0``, restitution 0.8), declared with
``HybridSystem.mechanical`` as the README shows (:class:`ForcedChain`; state ``(q, qdot,
phase)``, stroboscopic section ``phase = 0 mod 2 pi``).

For each ``N``: the start frequency ``omega_0`` is the first of ``START_FREQUENCIES`` at which
the orbit reached after ``TRANSIENT`` forcing periods (simulated by the exact path) converges
by Newton to a period-1 orbit (at some frequencies the steady state is not period-1, or grazes
the wall); from that orbit both paths continue in omega over ``[omega_0, omega_0 + WINDOW]``
with the same settings (``max_points``, steps, ``newton_tol 1e-9``, stability and bifurcation
detection on). Time per point = wall time of ``nsm.continuation`` / points on the branch (both
paths find the same points: the largest difference of their section states is printed); also
in CPU time of the process (the cores are shared: wall time counts the other jobs' turns), and
the marginal cost of a point, the difference to a two-point continuation of the same start
per extra point (without the run's fixed setup: case validation, the problem registry). The
start orbits of the sizes in ``--accuracy`` are also solved by DOP853 at ``rtol = 1e-13``:
the distance of each path's section state to it is printed. The
Runge-Kutta path is skipped above ``--rk-max`` (default 40: at N = 200 its compile alone takes
minutes and its points tens of seconds).

BLAS is pinned to one thread (two shared cores). The machine's load average is printed before
and after: the cores are shared with other jobs, so absolute times drift; the ratio of the two
paths, measured alternately in one run, is the number to read.

    python benchmarks/bench_exact_flow.py [--sizes 2 5 10 20 40 200] [--rk-max 40]
                                          [--accuracy 10 20 40] [--points 12]
                                          [--out FILE.png] [--docs FILE.png]

Writes the chart (time per point against N, log-log, both paths) to ``--out`` (default
``benchmarks/results/exact_flow.png``) and, with ``--docs``, a copy for the README. The
measured numbers are in benchmarks/README.md ("Exact flows of piecewise-linear systems").
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, ClassVar  # noqa: E402

import casadi as ca  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
from pydantic import BaseModel, Field  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import nsm_continuation.api as nsm  # noqa: E402
from nsm_continuation.core.preflight import STRICT  # noqa: E402
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section  # noqa: E402
from nsm_continuation.hybrid.system import HybridSystem  # noqa: E402

#: candidate start frequencies, tried in this order
START_FREQUENCIES = (0.32, 0.30, 0.34, 0.28)
#: forcing periods simulated to reach the stable orbit
TRANSIENT = 150
#: width of the continuation window in omega
WINDOW = 0.03


class ChainParameters(BaseModel):
    """``parameters:`` of the benchmark's chain."""

    model_config = STRICT
    n: int = Field(2, ge=1)
    omega: float = 0.32
    gap: float = 0.0
    restitution: float = 0.8
    c: float = 0.05
    F0: float = 1.0
    integrator: IntegratorSpec = IntegratorSpec()


class ForcedChain(HybridCaseProblem):
    """The forced chain of the module docstring (not registered: a benchmark's system)."""

    name: ClassVar[str] = "forced_chain"
    Parameters: ClassVar[type[BaseModel]] = ChainParameters
    default_parameter: ClassVar[str] = "omega"
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "n")

    def system(self) -> HybridSystem:
        N = self.params.n  # type: ignore[attr-defined]
        q, qd, ph = ca.SX.sym("q", N), ca.SX.sym("qd", N), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("omega", "gap", "restitution", "c", "F0")}
        force = []
        for i in range(N):
            left = q[i] - (q[i - 1] if i > 0 else 0)
            right = q[i + 1] - q[i] if i < N - 1 else 0
            force.append(-left + right - p["c"] * qd[i]
                         + (p["F0"] * ca.cos(ph) if i == 0 else 0))
        return HybridSystem.mechanical(f"chain{N}", q, qd, p, ca.SX.eye(N), ca.vertcat(*force),
                                       p["gap"] - q[N - 1], p["restitution"], clock=ph,
                                       clock_rate=p["omega"])

    def section(self) -> Section:
        return Section(2 * self.params.n, 0.0, 2 * np.pi)  # type: ignore[attr-defined]

    def default_initial(self) -> np.ndarray:
        """At rest, every mass 0.1 clear of the wall's side."""
        n = self.params.n  # type: ignore[attr-defined]
        x = np.zeros(2 * n + 1)
        x[:n] = self.values["gap"] - 0.1
        return x


def start_orbit(n: int) -> tuple[float, np.ndarray] | None:
    """``(omega_0, y)``: the first start frequency whose transient converges by Newton to a
    period-1 orbit (the exact path), or None."""
    for omega in START_FREQUENCIES:
        pb = ForcedChain({"n": n, "omega": omega, "integrator": {"method": "exact"}})
        try:
            X = pb.transient(np.append(pb.default_initial(), [omega]), TRANSIENT)
            sh = pb.shooting
            y = np.append(X[sh.free_idx], omega)
            for _ in range(8):
                r, J = sh.residual_jacobian(y)
                if np.max(np.abs(r)) <= 1e-11:
                    return omega, y
                y[:-1] -= np.linalg.solve(J[:, :-1], r)
        except Exception as exc:  # noqa: BLE001 - a failed candidate: try the next
            print(f"  N = {n}, omega = {omega}: no start ({exc})")
    return None


def _continue(pb: ForcedChain, y: np.ndarray, omega0: float, points: int
              ) -> tuple[float, float, Any]:
    """Wall and CPU time of one continuation of ``pb`` from ``y`` over the window, and its
    result."""
    t0, c0 = time.perf_counter(), time.process_time()
    res = nsm.continuation(pb, y.copy(), parameter="omega", min=omega0 - 1e-9,
                           max=omega0 + WINDOW, max_points=points,
                           step={"initial": WINDOW / points, "max": 2 * WINDOW / points},
                           newton_tol=1e-9)
    return time.perf_counter() - t0, time.process_time() - c0, res


def continue_chain(n: int, method: str, omega0: float, y: np.ndarray, points: int
                   ) -> dict[str, Any]:
    """One continuation by ``method``: wall time (build excluded), points, section states,
    events; and the marginal cost of a point (``marginal``, ``cpu_marginal``): the difference
    to a two-point continuation of the same start, per extra point (what a point costs
    without the run's fixed setup: case validation, the problem registry, the first
    simulations)."""
    t0 = time.perf_counter()
    pb = ForcedChain({"n": n, "omega": omega0, "integrator": {"method": method}})
    build = time.perf_counter() - t0
    wall2, cpu2, res2 = _continue(pb, y, omega0, 2)
    wall, cpu, res = _continue(pb, y, omega0, points)
    br = res.branches[0]
    npts, npts2 = len(br["omega"]), len(res2.branches[0]["omega"])
    extra = max(1, npts - npts2)
    Y = np.column_stack([br[f"y_{v}"] for v in pb.variables]) if npts else None
    return {"flow": pb.shooting.c.flow, "build": build, "wall": wall,
            "points": npts, "per_point": wall / max(1, npts),
            "cpu_per_point": cpu / max(1, npts),
            "marginal": (wall - wall2) / extra, "cpu_marginal": (cpu - cpu2) / extra,
            "y": Y, "events": [(e.kind, e.parameter) for e in res.events]}


def newton(pb: ForcedChain, y: np.ndarray) -> np.ndarray:
    """The orbit near ``y`` at fixed omega (Newton on the shooting residual to its floor)."""
    y = y.copy()
    sh = pb.shooting
    best = np.inf
    for _ in range(8):
        r, J = sh.residual_jacobian(y)
        res = float(np.max(np.abs(r)))
        if res >= best:
            break
        best = res
        y[:-1] -= np.linalg.solve(J[:, :-1], r)
    return y


def accuracy(n: int, omega0: float, y: np.ndarray) -> tuple[float, float]:
    """Section state of the start orbit by the exact flow and by DOP853 at its default
    ``rtol`` 1e-10, each against DOP853 at ``rtol = 1e-13`` (``atol`` 1e-15, chatter tolerance
    1e-13): the largest differences."""
    ref = newton(ForcedChain({"n": n, "omega": omega0, "integrator": {
        "method": "dop853", "rtol": 1e-13, "atol": 1e-15, "chatter_tol": 1e-13}}), y)
    out = []
    for method in ("exact", "dop853"):
        z = newton(ForcedChain({"n": n, "omega": omega0, "integrator": {"method": method}}), y)
        out.append(float(np.max(np.abs(z - ref))))
    return out[0], out[1]


def chart(rows: list[dict[str, Any]], out: Path) -> None:
    """CPU time per point (marginal) against N, log-log, both paths: on shared cores the wall
    time counts the other jobs' turns, the process's CPU time does not."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for method, style in (("dop853", "o-"), ("exact", "s-")):
        pts = [(r["N"], r[method]["cpu_marginal"]) for r in rows if method in r]
        if pts:
            x, y = zip(*pts, strict=True)
            label = "Runge-Kutta (DOP853, rtol 1e-10)" if method == "dop853" else "exact flow"
            ax.loglog(x, y, style, label=label)
    for r in rows:
        if "dop853" in r and "exact" in r:
            ratio = r["dop853"]["cpu_marginal"] / r["exact"]["cpu_marginal"]
            ax.annotate(f"{ratio:.1f}x", (r["N"], r["exact"]["cpu_marginal"]),
                        textcoords="offset points", xytext=(4, -12), fontsize=8)
    ax.set_xlabel("N (masses)")
    ax.set_ylabel("CPU time per continuation point [s]")
    ax.set_title("Forced N-mass chain with a wall: cost per point")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2, 5, 10, 20, 40, 200])
    ap.add_argument("--rk-max", type=int, default=40)
    ap.add_argument("--points", type=int, default=12)
    ap.add_argument("--out", type=Path,
                    default=Path(__file__).parent / "results" / "exact_flow.png")
    ap.add_argument("--docs", type=Path, default=None)
    ap.add_argument("--accuracy", type=int, nargs="*", default=[10, 20, 40],
                    help="sizes whose start orbit is also solved by DOP853 at rtol 1e-13")
    args = ap.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f} (1 min) at the start")
    rows = []
    for n in args.sizes:
        found = start_orbit(n)
        if found is None:
            print(f"N = {n}: no period-1 start found, skipped")
            continue
        omega0, y = found
        row: dict[str, Any] = {"N": n, "omega0": omega0}
        orbit = ForcedChain({"n": n, "omega": omega0,
                             "integrator": {"method": "exact"}}).shooting.simulate(y)
        print(f"N = {n:4d} start orbit at omega0 = {omega0}: events "
              f"{[e.kind for e in orbit.events]} (sticking and chattering flights: "
              "Runge-Kutta in both paths)")
        methods = ["exact", "dop853"] if n <= args.rk_max else ["exact"]
        for method in methods:
            row[method] = continue_chain(n, method, omega0, y, args.points)
            r = row[method]
            print(f"N = {n:4d} {method:7s} omega0 {omega0:.2f}: {r['points']} points, "
                  f"{r['per_point']:.4f} s/point (CPU {r['cpu_per_point']:.4f}; marginal "
                  f"{r['marginal']:.4f}, CPU {r['cpu_marginal']:.4f}; build {r['build']:.1f} s), "
                  f"events {[k for k, _ in r['events']]}")
        if n in args.accuracy:
            ea, eb = accuracy(n, omega0, y)
            print(f"           start orbit against DOP853 at rtol 1e-13: exact {ea:.1e}, "
                  f"DOP853 at rtol 1e-10 {eb:.1e}")
        if "dop853" in row:
            a, b = row["exact"], row["dop853"]
            same = a["y"] is not None and b["y"] is not None and a["y"].shape == b["y"].shape
            diff = float(np.max(np.abs(a["y"] - b["y"]))) if same else float("nan")
            print(f"           ratio RK / exact {b['per_point'] / a['per_point']:.1f}x "
                  f"(CPU {b['cpu_per_point'] / a['cpu_per_point']:.1f}x; marginal "
                  f"{b['marginal'] / a['marginal']:.1f}x, CPU "
                  f"{b['cpu_marginal'] / a['cpu_marginal']:.1f}x); "
                  f"section states: max difference {diff:.1e}; "
                  f"same events: {[k for k, _ in a['events']] == [k for k, _ in b['events']]}")
        rows.append(row)
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at the end")
    chart(rows, args.out)
    print(f"chart: {args.out}")
    if args.docs is not None:
        chart(rows, args.docs)
        print(f"chart: {args.docs}")


if __name__ == "__main__":
    main()
