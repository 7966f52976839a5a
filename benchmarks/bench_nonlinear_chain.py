"""Cost per continuation point against the size of a nonlinear impacting chain (Runge-Kutta
path), and where it goes: the forced chain of ``bench_exact_flow.py`` with cubic springs.

System: ``N`` unit masses, mass ``i`` tied to mass ``i - 1`` (mass 1 to the ground) by a spring
of force ``d + k3 d^3`` (``d`` its elongation, ``k3 = 0.5``), viscous damping ``c = 0.05`` of
every mass to the ground, mass 1 forced by ``cos(omega t)``, mass ``N`` hitting a rigid wall at
its rest position (restitution 0.8), declared with ``HybridSystem.mechanical``. It is not
linear between events: the exact flow does not apply, the free flight is integrated by DOP853
with its variational equations (the step's exact Jacobian, ``(2N + 1)^2`` entries).

For each ``N``: a period-1 orbit (the first start frequency of ``bench_exact_flow`` whose
transient converges by Newton), then the continuation in omega over ``[omega_0, omega_0 +
0.03]`` (12 points, the settings of ``bench_exact_flow``) with the sensitivities of each step
chained as dense products (``sparse_products: false``, the path before the cut) and as sparse
ones (the default, :mod:`nsm_continuation.hybrid.sparse_steps`), alternately in one run;
the marginal cost of a point (the difference to a two-point continuation, per extra point)
in wall and CPU time. One simulation of the start orbit is then taken apart by timers around
the simulator's parts (``--parts``): the CasADi step with its Jacobian (the variational
equations), the other CasADi steps and probes (error control, event location), the products
``J <- J_step J``, and the rest (Python bookkeeping, transitions).

BLAS is pinned to one thread (two shared cores); the load average is printed.

    python benchmarks/bench_nonlinear_chain.py [--sizes 2 5 10 20 40] [--points 12]
                                               [--out FILE.png] [--docs FILE.png]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, ClassVar  # noqa: E402

import casadi as ca  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
from pydantic import BaseModel  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from bench_exact_flow import (  # noqa: E402
    START_FREQUENCIES,
    TRANSIENT,
    ChainParameters,
    ForcedChain,
    _continue,
)

from nsm_continuation.hybrid.simulate import Simulator  # noqa: E402
from nsm_continuation.hybrid.system import HybridSystem  # noqa: E402


class CubicParameters(ChainParameters):
    """``parameters:`` of the cubic chain (those of the linear one and ``k3``)."""

    k3: float = 0.5
    #: chain each step's sensitivities by sparse products (False: dense, the path before)
    sparse_products: bool = True


class CubicChain(ForcedChain):
    """The chain of the module docstring (not registered: a benchmark's system)."""

    name: ClassVar[str] = "cubic_chain"
    Parameters: ClassVar[type[BaseModel]] = CubicParameters
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "n", "sparse_products")

    def set_parameter(self, name: str, returns: int | None = None) -> None:
        super().set_parameter(name, returns)
        # dense (the rule's choice below 250 state components) or sparse products, as asked
        self.shooting.sim.o.sparse_products = self.params.sparse_products  # type: ignore

    def system(self) -> HybridSystem:
        N = self.params.n  # type: ignore[attr-defined]
        q, qd, ph = ca.SX.sym("q", N), ca.SX.sym("qd", N), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("omega", "gap", "restitution", "c", "F0", "k3")}

        def spring(d: Any) -> Any:
            return d + p["k3"] * d ** 3

        force = []
        for i in range(N):
            left = spring(q[i] - (q[i - 1] if i > 0 else 0))
            right = spring(q[i + 1] - q[i]) if i < N - 1 else 0
            force.append(-left + right - p["c"] * qd[i]
                         + (p["F0"] * ca.cos(ph) if i == 0 else 0))
        return HybridSystem.mechanical(f"cubic_chain{N}", q, qd, p, ca.SX.eye(N),
                                       ca.vertcat(*force), p["gap"] - q[N - 1],
                                       p["restitution"], clock=ph, clock_rate=p["omega"])


def start_orbit(n: int) -> tuple[float, np.ndarray] | None:
    """``(omega_0, y)``: the first start frequency whose transient converges by Newton to a
    period-1 orbit, or None."""
    for omega in START_FREQUENCIES:
        pb = CubicChain({"n": n, "omega": omega})
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


def continue_chain(n: int, sparse: bool, omega0: float, y: np.ndarray, points: int
                   ) -> dict[str, Any]:
    """One continuation: its points, section states and the marginal cost of a point."""
    t0 = time.perf_counter()
    pb = CubicChain({"n": n, "omega": omega0, "sparse_products": sparse})
    build = time.perf_counter() - t0
    wall2, cpu2, res2 = _continue(pb, y, omega0, 2)
    wall, cpu, res = _continue(pb, y, omega0, points)
    br = res.branches[0]
    npts, npts2 = len(br["omega"]), len(res2.branches[0]["omega"])
    extra = max(1, npts - npts2)
    Y = np.column_stack([br[f"y_{v}"] for v in pb.variables]) if npts else None
    return {"build": build, "points": npts, "per_point": wall / max(1, npts),
            "marginal": (wall - wall2) / extra, "cpu_marginal": (cpu - cpu2) / extra,
            "y": Y, "events": [e.kind for e in res.events]}


class _Timed:
    """A step Function whose ``flat`` calls are timed into ``bucket``."""

    def __init__(self, inner: Any, bucket: str, clock: dict[str, float]) -> None:
        self.inner, self.bucket, self.clock = inner, bucket, clock
        self.exact = False

    def flat(self, *args: Any) -> np.ndarray:
        t0 = time.process_time()
        out = self.inner.flat(*args)
        self.clock[self.bucket] += time.process_time() - t0
        return out


def parts(n: int, sparse: bool, omega0: float, y: np.ndarray, repeat: int = 5
          ) -> dict[str, float]:
    """CPU time of one simulation of the start orbit (with sensitivities) and of its parts,
    best of ``repeat``."""
    pb = CubicChain({"n": n, "omega": omega0, "sparse_products": sparse})
    sh = pb.shooting
    sim: Simulator = sh.sim
    X0 = sh.x0(y)
    s = sh.section
    best: dict[str, float] | None = None
    for _ in range(repeat):
        clock = {"variational step": 0.0, "other steps and probes": 0.0, "products": 0.0}
        saved = dict(sim.calls.steps)
        for key, fs in saved.items():
            sim.calls.steps[key] = (_Timed(fs[0], "other steps and probes", clock),
                                    _Timed(fs[1], "variational step", clock),
                                    _Timed(fs[2], "other steps and probes", clock))
        chain = sim._chain

        def timed_chain(key: str, Jstep: Any, J: np.ndarray, chain: Any = chain,
                        clock: dict[str, float] = clock) -> np.ndarray:
            t0 = time.process_time()
            out = chain(key, Jstep, J)
            clock["products"] += time.process_time() - t0
            return out

        sim._chain = timed_chain  # type: ignore[method-assign]
        try:
            t0 = time.process_time()
            res = sim.run(X0, section=(s.index, s.value + s.shift, s.direction))
            total = time.process_time() - t0
        finally:
            sim.calls.steps.update(saved)
            del sim._chain
        clock["rest"] = total - sum(clock.values())
        clock["total"] = total
        clock["steps"] = res.n_steps
        clock["events"] = len(res.events)
        if best is None or total < best["total"]:
            best = clock
    assert best is not None
    return best


#: the parts of a simulation drawn on the chart, in stacking order
PARTS = ("variational step", "products", "other steps and probes", "rest")


def chart(rows: list[dict[str, Any]], out: Path) -> None:
    """Left: CPU time per point (marginal) against N, log-log, dense and sparse products.
    Right: one simulation's CPU time and its parts against N (dense products)."""
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    for key, style, label in (("dense", "o-", "dense products (the rule below 250 components)"),
                              ("sparse", "s--", "sparse products (forced)")):
        pts = [(r["N"], r[key]["cpu_marginal"]) for r in rows if key in r]
        if pts:
            x, yv = zip(*pts, strict=True)
            ax.loglog(x, yv, style, label=label)
    ax.set_xlabel("N (masses)")
    ax.set_ylabel("CPU time per continuation point [s]")
    ax.set_title("Cubic N-mass chain with a wall (DOP853)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    sizes = [r["N"] for r in rows if "dense" in r]
    for part, style in zip(PARTS, ("o-", "s-", "^-", "v-"), strict=True):
        vals = [r["dense"]["parts"][part] * 1e3 for r in rows if "dense" in r]
        bx.loglog(sizes, np.maximum(vals, 1e-2), style, label=part)
    bx.loglog(sizes, [r["dense"]["parts"]["total"] * 1e3 for r in rows if "dense" in r], "k:",
              label="whole simulation")
    bx.set_xlabel("N (masses)")
    bx.set_ylabel("CPU time of one simulation [ms]")
    bx.set_title("Where a simulation's time goes")
    bx.grid(True, which="both", alpha=0.3)
    bx.legend(fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[2, 5, 10, 20, 40])
    ap.add_argument("--points", type=int, default=12)
    ap.add_argument("--out", type=Path,
                    default=Path(__file__).parent / "results" / "nonlinear_chain.png")
    ap.add_argument("--docs", type=Path, default=None)
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
        for key, sparse in (("dense", False), ("sparse", True)):
            row[key] = r = continue_chain(n, sparse, omega0, y, args.points)
            pr = parts(n, sparse, omega0, y)
            r["parts"] = pr
            print(f"N = {n:3d} {key:6s} omega0 {omega0:.2f}: {r['points']} points, marginal "
                  f"{r['marginal']:.4f} s/point (CPU {r['cpu_marginal']:.4f}; build "
                  f"{r['build']:.1f} s); one simulation {pr['total'] * 1e3:.1f} ms CPU, "
                  f"{pr['steps']} steps, {pr['events']} events: variational step "
                  f"{pr['variational step'] * 1e3:.1f}, other steps and probes "
                  f"{pr['other steps and probes'] * 1e3:.1f}, products "
                  f"{pr['products'] * 1e3:.1f}, rest {pr['rest'] * 1e3:.1f} ms")
        a, b = row["dense"], row["sparse"]
        same = a["y"] is not None and b["y"] is not None and a["y"].shape == b["y"].shape
        diff = float(np.max(np.abs(a["y"] - b["y"]))) if same else float("nan")
        print(f"          dense / sparse {a['cpu_marginal'] / b['cpu_marginal']:.2f}x (CPU); "
              f"section states: max difference {diff:.1e}; same events: "
              f"{a['events'] == b['events']}")
        rows.append(row)
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at the end")
    chart(rows, args.out)
    print(f"chart: {args.out}")
    if args.docs is not None:
        chart(rows, args.docs)
        print(f"chart: {args.docs}")


if __name__ == "__main__":
    main()
