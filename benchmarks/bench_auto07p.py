"""Our package side by side with AUTO-07p (through PyPI ``bifpy``) on a smooth system and on
impacting ones, the impacts regularised for AUTO by a smooth penalty force.

Optional: without ``gfortran`` or ``bifpy`` it prints one line naming what is missing and exits
0 (``apt-get install gfortran``, then ``pip install bifpy``: it compiles the vendored AUTO-07p at
install). Never part of the test suite.

Sections (``--sections``; each prints a table, all feed one chart):

1. **Stuart-Landau** ``x' = mu x - y - x r^2``, ``y' = x + mu y - y r^2``: periodic orbits of
   radius ``sqrt(mu)``, period ``2 pi``, non-trivial multiplier ``exp(-4 pi mu)``, continued in
   ``mu`` from 0.1 to 1. AUTO: the Cartesian field, ``IPS=2``, free ``(mu, T)``, several NTST.
   Ours: the same Cartesian field through the hybrid layer
   (:mod:`nsm_continuation.problems.impacting.stuart_landau`: no contact, the section ``x = 0``
   crossed with ``x`` rising), several ``rtol``.
2. **The paper-000 5-dof chain** (``chain: {dofs: 5, mass: 0.2, stiffness: 5}``, ``gap: 1``),
   branch 1 over ``T in [0.90, 0.99] T_1``. Ours: the exact closed-form branch (problem
   ``ndof_impact``, engine with event detection). AUTO, as its user would pose it: the wall
   replaced by the penalty force ``k_c eps softplus((u_N - g) / eps)`` (``softplus(z) = max(z,
   0) + log(1 + exp(-|z|))``, overflow-safe; ``eps = w g sqrt(k / k_c)``, ``w = 0.01``: a fixed
   fraction of the penetration scale), the conservative family unfolded by ``beta M u'`` (zero
   on a periodic orbit; AUTO's demo ``r3b`` does the same), started on the linear mode 1 below
   the wall (``T = T_1``) and continued in the period (free ``T, beta``); ``k_c`` and NTST swept.
   Measured: energy error at ``T = 0.98, 0.96, 0.94, 0.92 T_1`` (AUTO's labelled orbits, from
   the mesh points away from the wall) against the closed form, ``|beta|``, the multipliers at
   the same periods against the exact ones, and how many of the exact branch's 12 stability
   changes AUTO reproduces (a change of AUTO's own stability flag, or of ``max |mu| > 1 +
   1e-3``, within ``2e-3 T_1`` and in the same direction). ``--hybrid-chain`` adds the same
   branch through our hybrid layer (problem ``ndof_impact_hybrid``, continued in ``omega``).
3. **The forced impact oscillator** ``q'' + q = cos(omega t)``, ``q >= -0.5``, ``e = 0.8`` (the
   bundled ``impact_oscillator_grazing.yaml`` and ``impact_oscillator_period_doubling.yaml``).
   Ours: both cases as bundled (exact hybrid). AUTO: the stop as a Kelvin-Voigt penalty
   (softplus spring ``k_c``, damper ``2 zeta_c sqrt(k_c)`` switched by the softplus's sigmoid,
   ``zeta_c`` from ``e = exp(-pi zeta_c / sqrt(1 - zeta_c^2))``), the forcing written as the
   autonomous oscillator ``(cos, -sin)(omega t)``, free ``(omega, T)``, started on the free orbit
   at ``omega = 2`` and continued down to 1.005 (one branch: the free orbit, the grazing, the
   low-velocity impacting orbit, the fold, the high-velocity orbit and its two period
   doublings). Errors against the closed forms of
   :mod:`nsm_continuation.problems.impacting.impact_oscillator_closed_form`.

Wall time is what a user waits for (AUTO: tracing the Python model with sympy, gfortran, the
run, reading its files; also AUTO's own ``Total Time``); CPU time counts this process and its
finished children (the machine is shared: see the load printed first).

Run: ``python benchmarks/bench_auto07p.py`` (a few minutes); ``--full`` sweeps every
``k_c x NTST`` pair; ``--kc``, ``--ntst``, ``--sections`` choose the runs.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # see bench_scaling.py: 2 threads thrash here

import argparse  # noqa: E402
import importlib.util  # noqa: E402
import re  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "figures" / "auto07p_speed_accuracy.png"
PAPER_CHAIN = {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": 1.0}
#: periods (in T_1) where AUTO labels its orbits (uzr) and the energy is compared
CHAIN_CHECK = (0.98, 0.96, 0.94, 0.92)
CHAIN_WINDOW = (0.90, 0.99)
#: an AUTO stability change within this distance (in T_1) of an exact one reproduces it
MATCH_TOL = 2e-3
#: the penalty's smoothing length in units of the penetration scale g sqrt(k / k_c)
SOFTPLUS_WIDTH = 0.01
OSC = {"gap": -0.5, "restitution": 0.8, "omega_lo": 1.005, "omega_hi": 2.0}


def missing_tools() -> str | None:
    """Why the benchmark cannot run here (None: it can)."""
    if shutil.which("gfortran") is None:
        return "gfortran is not on PATH (Debian: apt-get install gfortran)"
    if importlib.util.find_spec("bifpy") is None:
        return "bifpy is not installed (pip install bifpy; it compiles AUTO-07p with gfortran)"
    return None


# ----------------------------------------------------------------------------- measuring
def cpu_seconds() -> float:
    """CPU time of this process and of its finished children (gfortran, AUTO's executable)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def timed(fun: Callable[[], Any]) -> tuple[Any, float, float]:
    """``(fun(), wall seconds, CPU seconds)``."""
    w0, c0 = time.perf_counter(), cpu_seconds()
    out = fun()
    return out, time.perf_counter() - w0, cpu_seconds() - c0


@dataclass
class Row:
    """One run of one method: its cost and its error (the chart's point)."""

    section: str
    method: str
    config: str
    wall: float
    cpu: float
    error: float
    points: int
    extra: dict[str, Any] = field(default_factory=dict)


def auto_run(func: Callable, stpnt: Callable, settings: dict[str, Any], icu: list[int],
             **kw: Any) -> tuple[Any, float, str]:
    """One AUTO run through bifpy's compiled path: ``(result or None, AUTO's own Total Time,
    failure reason or '')``. The output folder is read, then removed."""
    from bifpy import auto
    try:
        res = auto.run(func, stpnt, settings, icu=icu, keep_output=True, **kw)
    except Exception as exc:  # AutoError, TranspileError: the reason is the result
        text = str(exc)
        folder = re.search(r"left in (\S+) for", text)
        if folder:
            shutil.rmtree(folder.group(1).rstrip("."), ignore_errors=True)
        return None, float("nan"), f"{type(exc).__name__}: {' '.join(text.split())[:160]}"
    folder = Path(res.output_directory)
    out = (folder / "stdout.txt").read_text() if (folder / "stdout.txt").exists() else ""
    shutil.rmtree(folder, ignore_errors=True)
    found = re.findall(r"Total Time\s+([0-9.Ee+-]+)", out)
    return res, sum(float(t) for t in found) if found else float("nan"), ""


def termination(branch: Any) -> str:
    """Our branch's end(s), one line."""
    return termination_text(branch.termination)


def termination_text(t: Any) -> str:
    return "; ".join(f"{k}: {v}" for k, v in t.items()) if isinstance(t, dict) else str(t)


def fmt(x: float, spec: str) -> str:
    """A number, or '-' where it was not measured."""
    return format(x, spec) if np.isfinite(x) else "-".rjust(int(spec.split(".")[0] or 1))


def auto_points(res: Any) -> list[Any]:
    return [pt for br in res.branches for pt in br.points]


def ended(points: list[Any], index: int, scale: float = 1.0) -> str:
    """How an AUTO branch ended: its last point's type and continued parameter."""
    last = points[-1]
    return f"{last.point_type.name} at {last.parameters[index] / scale:.4f}"


# ----------------------------------------------------------------------------- 1. Stuart-Landau
MU0, MU1 = 0.1, 1.0


def sl_auto(ntst: int, transpile: bool) -> Row:
    from bifpy import auto

    def func(u: Any, p: Any) -> list[Any]:
        r2 = u[0] ** 2 + u[1] ** 2
        return [p[0] * u[0] - u[1] - u[0] * r2, u[0] + p[0] * u[1] - u[1] * r2]

    def stpnt(u: Any, p: Any, t: Any) -> None:
        p[0], p[10] = MU0, 2 * np.pi
        u[0] = np.sqrt(MU0) * np.cos(2 * np.pi * t)
        u[1] = np.sqrt(MU0) * np.sin(2 * np.pi * t)

    settings = dict(ips=auto.IPS_PERIODIC_ORBIT, ndim=2, npar=11, nmx=500, ntst=ntst, ncol=4,
                    ds=0.01, dsmin=1e-5, dsmax=0.1, rl0=MU0, rl1=MU1, epsl=1e-10, epsu=1e-10,
                    epss=1e-6, npr=1, jac=1 if transpile else 0)
    kw: dict[str, Any] = {"transpile": True, "jac": auto.AUTO_JACOBIAN} if transpile else {}
    (res, t_auto, why), wall, cpu = timed(lambda: auto_run(func, stpnt, settings, [1, 11], **kw))
    name = "AUTO-07p (compiled)" if transpile else "AUTO-07p (Python callbacks)"
    if res is None:
        return Row("stuart_landau", name, f"NTST {ntst}", wall, cpu, float("nan"), 0,
                   {"failure": why})
    pts = auto_points(res)
    rad = per = mult = 0.0
    for pt in pts:
        mu = pt.parameters[0]
        if pt.periodic_orbit is not None:
            X = np.asarray(pt.periodic_orbit.state)
            r = np.hypot(X[:, 0], X[:, 1])
            rad = max(rad, float(np.max(np.abs(r - np.sqrt(mu)))) / np.sqrt(mu))
            per = max(per, abs(pt.periodic_orbit.period - 2 * np.pi) / (2 * np.pi))
        m = np.asarray(pt.floquet_multipliers or [], dtype=complex)
        if m.size:
            nontrivial = m[np.argmax(np.abs(m - 1))]
            mult = max(mult, abs(nontrivial - np.exp(-4 * np.pi * mu)))
    return Row("stuart_landau", name, f"NTST {ntst}", wall, cpu, max(rad, per, mult), len(pts),
               {"radius": rad, "period": per, "multiplier": mult, "auto_time": t_auto,
                "ended": ended(pts, 0)})


def sl_ours(rtol: float) -> Row:
    from nsm_continuation.problems.impacting.stuart_landau import StuartLandauProblem

    import nsm_continuation as nsm
    problem = StuartLandauProblem({"mu": MU0, "integrator": {"rtol": rtol, "atol": rtol * 1e-2}})

    def go() -> Any:
        # on the section x = 0 crossed rising the orbit is at y = -sqrt(mu)
        return nsm.continuation(problem, {"guess": {"y": -np.sqrt(MU0)}}, parameter="mu",
                                min=MU0, max=MU1, max_points=400)

    res, wall, cpu = timed(go)
    b = res.branches[0]
    mu, y, T = (np.asarray(b[k], dtype=float) for k in ("mu", "y_y", "period"))
    r = np.abs(y)
    m = np.asarray(b["mu1_re"], dtype=float) + 1j * np.asarray(b["mu1_im"], dtype=float)
    rad = float(np.max(np.abs(r - np.sqrt(mu)) / np.sqrt(mu)))
    per = float(np.max(np.abs(T - 2 * np.pi)) / (2 * np.pi))
    mult = float(np.max(np.abs(m - np.exp(-4 * np.pi * mu))))
    return Row("stuart_landau", "ours (hybrid layer)", f"rtol {rtol:.0e}", wall, cpu,
               max(rad, per, mult), len(mu), {"radius": rad, "period": per,
                                              "multiplier": mult, "ended": termination(b)})


def section_stuart_landau(args: argparse.Namespace) -> list[Row]:
    rows = [sl_auto(n, True) for n in (4, 8, 20)]
    rows.append(sl_auto(20, False))
    rows += [sl_ours(t) for t in (1e-6, 1e-8, 1e-10, 1e-12)]
    print(f"\n1. Stuart-Landau, mu from {MU0} to {MU1}: errors against radius sqrt(mu), "
          "period 2 pi, multiplier exp(-4 pi mu)")
    print("   (errors: radius and period relative, multiplier absolute; AUTO writes orbits "
          "with 11 digits, multipliers with 6)")
    head = (f"   {'method':<30}{'config':<11}{'points':>7}{'wall [s]':>9}{'CPU [s]':>9}"
            f"{'AUTO [s]':>9}{'radius':>10}{'period':>10}{'multiplier':>11}  end")
    print(head)
    for r in rows:
        e = r.extra
        if "failure" in e:
            print(f"   {r.method:<30}{r.config:<11}  failed: {e['failure']}")
            continue
        print(f"   {r.method:<30}{r.config:<11}{r.points:>7d}{r.wall:>9.2f}{r.cpu:>9.2f}"
              f"{fmt(e.get('auto_time', np.nan), '9.2f')}{e['radius']:>10.1e}"
              f"{e['period']:>10.1e}{e['multiplier']:>11.1e}  {e['ended']}")
    return rows


# ----------------------------------------------------------------------------- 2. the chain
def chain_exact() -> tuple[Any, dict[str, Any], Row]:
    """Our exact branch 1 (engine with detection) and the reference data AUTO is measured by."""
    from nsm_continuation.problems.chain.ndof_impact import NDofImpactProblem

    from nsm_continuation.core.palc import ContinuationEngine
    from nsm_continuation.core.problem import StartPoint
    from nsm_continuation.core.settings import ContinuationSettings

    p = NDofImpactProblem(PAPER_CHAIN)
    _ = p.compiled
    T1 = float(p.T_lin[0])

    def y_at(T: float) -> np.ndarray:
        u0, du0 = p.closed_form(T)
        return p.y_from_state(u0, du0, T)

    def go() -> Any:
        s = ContinuationSettings(step_initial=1e-2, step_max=0.2, step_min=1e-6,
                                 newton_tol=1e-10, param_min=CHAIN_WINDOW[0] * T1,
                                 max_points=10_000, direction=-1, detect_bifurcations=True)
        start = StartPoint(y_at(CHAIN_WINDOW[1] * T1), "branch 1", -1)
        return ContinuationEngine(p, s).run(start)

    br, wall, cpu = timed(go)
    changes = [(float(ev.point.y[-1]) / T1, ev.detail) for ev in br.events
               if ev.kind == "stability_change"]
    err = max(abs(p.energy(pt.y) - p.energy(y_at(float(pt.y[-1])))) / p.energy(pt.y)
              for pt in br.points)
    ref: dict[str, Any] = {"problem": p, "T1": T1, "changes": changes, "energy": {},
                           "multipliers": {}}
    for r in CHAIN_CHECK:
        T = r * T1
        ref["energy"][r] = p.energy(y_at(T))
        h = 1e-6 * T
        tangent = y_at(T + h) - y_at(T - h)
        fd = p.floquet_dense(y_at(T), tangent / np.linalg.norm(tangent))
        ref["multipliers"][r] = np.asarray(fd.multipliers, dtype=complex)
    kinds: dict[str, int] = {}
    for ev in br.events:
        kinds[ev.kind] = kinds.get(ev.kind, 0) + 1
    row = Row("chain", "ours (closed form + engine)", "tol 1e-10", wall, cpu, err,
              len(br.points), {"changes": len(changes), "ended": br.termination,
                               "kinds": ", ".join(f"{k} {v}" for k, v in kinds.items())})
    return br, ref, row


def chain_hybrid(ref: dict[str, Any]) -> Row:
    """The same branch through our hybrid layer (problem ``ndof_impact_hybrid``: event-driven
    shooting, the family unfolded by ``beta``), continued in ``omega`` over the same window."""
    import nsm_continuation as nsm
    p, T1 = ref["problem"], ref["T1"]
    hybrid = nsm.problem("ndof_impact_hybrid", PAPER_CHAIN)
    w_lo, w_hi = (2 * np.pi / (r * T1) for r in (CHAIN_WINDOW[1], CHAIN_WINDOW[0]))

    def go() -> Any:
        return nsm.continuation(hybrid, {"omega": float(w_lo * (1 + 1e-4))}, parameter="omega",
                                min=float(w_lo), max=float(w_hi), max_points=2000,
                                step={"initial": 0.01, "min": 1e-9, "max": 0.05},
                                analysis={"stability": True, "bifurcations": True})

    res, wall, cpu = timed(go)
    b = res.branches[0]
    T = 2 * np.pi / np.asarray(b["omega"], dtype=float)
    E = np.asarray(b["energy"], dtype=float)
    exact = np.array([p.energy(p.y_from_state(*p.closed_form(t), t)) for t in T])
    # by location only: the branch is followed both ways from its start, and each half words
    # its changes in its own direction
    found = sorted(((2 * np.pi / ev.parameter / T1, ev.detail) for ev in res.events
                    if ev.kind == "stability_change"), reverse=True)
    hits = sum(any(abs(t - f) <= MATCH_TOL for f, _ in found) for t, _ in ref["changes"])
    kinds: dict[str, int] = {}
    for ev in res.events:
        kinds[ev.kind] = kinds.get(ev.kind, 0) + 1
    worst = max((min(abs(t - f) for f, _ in found) for t, _ in ref["changes"]),
                default=float("nan")) if found else float("nan")
    return Row("chain", "ours (hybrid layer)", "rtol 1e-10", wall, cpu,
               float(np.max(np.abs(E - exact) / exact)), len(T),
               {"hits": hits, "found": len(found), "worst_change": worst,
                "kinds": ", ".join(f"{k} {v}" for k, v in kinds.items()),
                "ended": termination_text(b.termination)})


def chain_auto(ref: dict[str, Any], kc: float, ntst: int) -> Row:
    from bifpy import auto
    p = ref["problem"]
    T1, N, c, g = ref["T1"], p.N, p.c, p.g
    Minv, K = np.linalg.inv(p.M), p.K
    eps = SOFTPLUS_WIDTH * g * np.sqrt(float(K[-1, -1]) / kc)
    mode = p.P[:, 0] / p.P[c, 0]
    w1, amp = float(p.omega[0]), 0.95 * g

    def func(x: Any, par: Any) -> list[Any]:
        u, v = x[:N], x[N:]
        z = (u[c] - g) / par[2]
        softplus = np.maximum(z, 0.0) + np.log(1.0 + np.exp(-np.abs(z)))
        force = [-sum(float(K[i, j]) * u[j] for j in range(N)) for i in range(N)]
        force[c] = force[c] - par[1] * par[2] * softplus
        return list(v) + [sum(float(Minv[i, j]) * force[j] for j in range(N)) + par[0] * v[i]
                          for i in range(N)]

    def stpnt(x: Any, par: Any, t: Any) -> None:  # the linear mode 1 below the wall
        par[0], par[1], par[2], par[10] = 0.0, kc, eps, T1
        for i in range(N):
            x[i] = amp * float(mode[i]) * np.cos(2 * np.pi * t)
            x[N + i] = -amp * float(mode[i]) * w1 * np.sin(2 * np.pi * t)

    settings = dict(ips=auto.IPS_PERIODIC_ORBIT, ndim=2 * N, npar=11, nmx=20_000, ntst=ntst,
                    ncol=4, ds=1e-3, dsmin=1e-7, dsmax=0.02, rl0=float(CHAIN_WINDOW[0] * T1),
                    rl1=float(1.01 * T1), epsl=1e-8, epsu=1e-8, epss=1e-5, npr=100_000)
    uzr = {11: [float(r * T1) for r in CHAIN_CHECK]}
    (res, t_auto, why), wall, cpu = timed(
        lambda: auto_run(func, stpnt, settings, [11, 1], uzr=uzr, transpile=True))
    config = f"k_c {kc:.0e}, NTST {ntst}"
    if res is None:
        return Row("chain", "AUTO-07p (penalty)", config, wall, cpu, float("nan"), 0,
                   {"failure": why, "kc": kc, "ntst": ntst})
    return chain_auto_measure(ref, auto_points(res), config, wall, cpu, t_auto, kc, ntst, eps)


def chain_auto_measure(ref: dict[str, Any], pts: list[Any], config: str, wall: float,
                       cpu: float, t_auto: float, kc: float, ntst: int, eps: float) -> Row:
    """Energy and multiplier errors at the labelled periods, |beta|, stability changes."""
    from scipy.optimize import linear_sum_assignment
    p, T1, N, c, g = ref["problem"], ref["T1"], ref["problem"].N, ref["problem"].c, 1.0
    e_err: dict[float, float] = {}
    m_err: dict[float, float] = {}
    for pt in pts:
        if pt.point_type.name != "USER_SPECIFIED_VALUE" or pt.periodic_orbit is None:
            continue
        r = min(CHAIN_CHECK, key=lambda x: abs(x * T1 - pt.parameters[0]))
        X = np.asarray(pt.periodic_orbit.state)
        u, v = X[:, :N], X[:, N:]
        free = u[:, c] < g - 30 * eps  # the penalty's potential is below exp(-30) there
        E = 0.5 * np.einsum("ij,jk,ik->i", v, p.M, v) + 0.5 * np.einsum("ij,jk,ik->i", u, p.K, u)
        e_err[r] = abs(float(np.median(E[free])) - ref["energy"][r]) / ref["energy"][r]
        m = np.asarray(pt.floquet_multipliers or [], dtype=complex)
        if m.size == 2 * N:  # drop the two trivial ones (time shift, family) nearest to +1
            m = m[np.argsort(np.abs(m - 1))[2:]]
            ex = ref["multipliers"][r]
            cost = np.abs(m[:, None] - ex[None, :])
            i, j = linear_sum_assignment(cost)
            m_err[r] = float(cost[i, j].max())
    inside = [pt for pt in pts if CHAIN_WINDOW[0] * T1 <= pt.parameters[0] <= CHAIN_WINDOW[1] * T1]
    beta = max((abs(pt.parameters[1]) * pt.parameters[0] for pt in inside), default=float("nan"))
    finite = all(np.all(np.isfinite(np.asarray(pt.floquet_multipliers or [0.0], dtype=complex)))
                 and np.all(np.isfinite(pt.parameters)) for pt in pts)
    flag = [(pt.parameters[0] / T1, pt.stability.name == "STABLE") for pt in inside]
    modulus = [(pt.parameters[0] / T1, float(np.max(np.abs(np.asarray(
        pt.floquet_multipliers, dtype=complex)))) <= 1 + 1e-3) for pt in inside
        if pt.floquet_multipliers]
    err = max(e_err.values()) if len(e_err) == len(CHAIN_CHECK) else float("nan")
    return Row("chain", "AUTO-07p (penalty)", config, wall, cpu, err, len(pts), {
        "kc": kc, "ntst": ntst, "energy": e_err, "multipliers": m_err, "beta_T": beta,
        "finite": finite, "auto_time": t_auto, "ended": ended(pts, 0, T1),
        "match_flag": match_changes(ref["changes"], flag),
        "match_modulus": match_changes(ref["changes"], modulus),
        "labels": label_counts(pts, T1) + f", stable {sum(f for _, f in flag)}/{len(flag)}"})


def match_changes(exact: list[tuple[float, str]], stable: list[tuple[float, bool]]
                  ) -> tuple[int, int]:
    """(exact changes reproduced, AUTO changes in all): a change of ``stable`` between two
    consecutive points (at their mid period, in the direction of decreasing T) within
    ``MATCH_TOL`` of an exact one of the same direction, each used once."""
    found = [(0.5 * (a[0] + b[0]), "stable -> unstable" if a[1] and not b[1]
              else "unstable -> stable") for a, b in zip(stable[:-1], stable[1:], strict=True)
             if a[1] != b[1]]
    used: set[int] = set()
    hits = 0
    for T, kind in exact:
        best = [(abs(T - f[0]), k) for k, f in enumerate(found)
                if k not in used and f[1] == kind and abs(T - f[0]) <= MATCH_TOL]
        if best:
            used.add(min(best)[1])
            hits += 1
    return hits, len(found)


def label_counts(pts: list[Any], T1: float) -> str:
    """AUTO's special points inside the window, by its type codes."""
    codes = {"FOLD": "LP", "PERIOD_DOUBLING": "PD", "TORUS": "TR", "BRANCH_POINT": "BP"}
    seen: dict[str, int] = {}
    for pt in pts:
        name = codes.get(pt.point_type.name)
        if name and CHAIN_WINDOW[0] * T1 <= pt.parameters[0] <= CHAIN_WINDOW[1] * T1:
            seen[name] = seen.get(name, 0) + 1
    return " ".join(f"{k} {v}" for k, v in sorted(seen.items())) or "none"


def section_chain(args: argparse.Namespace) -> list[Row]:
    _, ref, ours = chain_exact()
    if args.full:
        pairs = [(k, n) for k in args.kc for n in args.ntst]
    else:  # k_c swept at the finest mesh, the mesh swept at the middle k_c
        mid = args.kc[len(args.kc) // 2]
        pairs = [(k, max(args.ntst)) for k in args.kc]
        pairs += [(mid, n) for n in args.ntst if n != max(args.ntst)]
    rows = [ours] + [chain_auto(ref, k, n) for k, n in pairs]
    if args.hybrid_chain:
        rows.append(chain_hybrid(ref))
    T1 = ref["T1"]
    print(f"\n2. The 5-dof chain, branch 1, T from {CHAIN_WINDOW[1]} to {CHAIN_WINDOW[0]} T_1 "
          f"(T_1 = {T1:.6f}); exact: {len(ref['changes'])} stability changes")
    print(f"   ours: {ours.points} points, wall {ours.wall:.2f} s, CPU {ours.cpu:.2f} s, energy "
          f"error vs closed form {ours.error:.1e}, events: {ours.extra['kinds']}; "
          f"{termination_text(ours.extra['ended'])}")
    print("   AUTO on the penalty model (energy: relative error at T = "
          + ", ".join(f"{r}" for r in CHAIN_CHECK) + " T_1; mult: largest distance of the 8 "
          "non-trivial multipliers to the exact ones; changes: exact ones reproduced / AUTO's "
          "own, by AUTO's stability flag and by max|mu| > 1 + 1e-3)")
    head = (f"   {'k_c':>7}{'NTST':>6}{'points':>7}{'wall [s]':>9}{'CPU [s]':>8}{'AUTO [s]':>9}"
            f"{'energy':>9}{'mult':>9}{'|beta|T':>9}{'flag':>8}{'|mu|':>8}  labels, end")
    print(head)
    for r in rows[1:]:
        e = r.extra
        if r.method == "ours (hybrid layer)":
            print(f"   ours, hybrid layer: {r.points} points, wall {r.wall:.1f} s, CPU "
                  f"{r.cpu:.1f} s, energy error {r.error:.1e}, stability changes {e['hits']}/"
                  f"{e['found']} (farthest {e['worst_change']:.1e} T_1), events: {e['kinds']}; "
                  f"{e['ended']}")
            continue
        if "failure" in e:
            print(f"   {e['kc']:>7.0e}{e['ntst']:>6d}  failed: {e['failure']}")
            continue
        mult = max(e["multipliers"].values()) if e["multipliers"] else float("nan")
        print(f"   {e['kc']:>7.0e}{e['ntst']:>6d}{r.points:>7d}{r.wall:>9.2f}{r.cpu:>8.2f}"
              f"{e['auto_time']:>9.2f}{r.error:>9.1e}{mult:>9.1e}{e['beta_T']:>9.1e}"
              f"{'{}/{}'.format(*e['match_flag']):>8}{'{}/{}'.format(*e['match_modulus']):>8}  "
              f"{e['labels']}; {e['ended']}{'' if e['finite'] else '; NaN'}")
    print_kc_slope([r for r in rows[1:] if r.method.startswith("AUTO")])
    return rows


def print_kc_slope(rows: list[Row]) -> None:
    """The energy error's power of k_c at the finest mesh (least squares in log-log)."""
    if not rows:
        return
    fine = max(r.extra.get("ntst", 0) for r in rows)
    sel = [r for r in rows if r.extra.get("ntst") == fine and np.isfinite(r.error)]
    if len(sel) >= 2:
        x = np.log([r.extra["kc"] for r in sel])
        y = np.log([r.error for r in sel])
        slope = np.polyfit(x, y, 1)[0]
        print(f"   energy error ~ k_c^{slope:.2f} at NTST {fine} (penalty model: expected -0.5)")


# ----------------------------------------------------------------------------- 3. the oscillator
def oscillator_reference() -> dict[str, Any]:
    """Closed forms: the fold of the one-impact family, the grazing, the two period doublings."""
    from nsm_continuation.problems.impacting.impact_oscillator_closed_form import (
        grazing_omegas,
        period_doubling_omegas,
    )
    from scipy.optimize import brentq
    gap, r = OSC["gap"], OSC["restitution"]

    def exists(w: float) -> float:  # R - |C| of the one-impact orbit (O1): zero at the fold
        G, t2 = 1.0 / (1.0 - w * w), np.tan(np.pi / w)
        return float(np.hypot(G * t2 * (1 - r), G * w * (1 + r)) - abs(gap * t2 * (1 - r)))

    return {"fold": brentq(exists, 1.9, 1.96, xtol=1e-14),
            "grazing": grazing_omegas(gap)[0],
            "period_doubling": period_doubling_omegas(gap, r, hi=1.6)}


#: the response is compared up to this omega: the high-velocity orbit and its doublings (near
#: the fold and the grazing the amplitude is steep in omega, and a shifted fold dominates)
RESPONSE_MAX_OMEGA = 1.6


def response_error(omegas: np.ndarray, amplitudes: np.ndarray) -> float:
    """Largest relative distance of each (omega, amplitude), ``omega <= RESPONSE_MAX_OMEGA``,
    to the closed-form period-1 responses at that omega (the one-impact orbits, the free orbit
    where it clears the stop)."""
    from nsm_continuation.problems.impacting.impact_oscillator_closed_form import (
        free_amplitude,
        one_impact_orbits,
    )
    worst, compared = 0.0, 0
    for w, a in zip(omegas, amplitudes, strict=True):
        if w > RESPONSE_MAX_OMEGA:
            continue
        cands = [o["amplitude"] for o in one_impact_orbits(float(w), OSC["gap"],
                                                           OSC["restitution"], 400)]
        free = float(free_amplitude(w))
        if free <= -OSC["gap"] * (1 + 1e-9):  # grazing: within its rounding
            cands.append(free)
        if cands:
            worst = max(worst, min(abs(a - x) / x for x in cands))
            compared += 1
    return worst if compared else float("nan")


def oscillator_ours() -> Row:
    import nsm_continuation as nsm
    omegas, amps, events, wall, cpu, points = [], [], {}, 0.0, 0.0, 0
    for case in ("impact_oscillator_grazing", "impact_oscillator_period_doubling"):
        res, w, c = timed(lambda case=case: nsm.run(ROOT / "yaml_cases" / f"{case}.yaml"))
        wall, cpu = wall + w, cpu + c
        for b in res.branches:
            omegas += list(np.asarray(b["omega"], dtype=float))
            amps += list(np.asarray(b["amplitude_q"], dtype=float))
            points += len(np.asarray(b["omega"]))
        for ev in res.events:
            events.setdefault(ev.kind, []).append(float(ev.parameter))
    err = response_error(np.array(omegas), np.array(amps))
    return Row("oscillator", "ours (exact hybrid)", "bundled cases", wall, cpu, err, points,
               {"events": events})


def oscillator_auto(kc: float, ntst: int) -> Row:
    from bifpy import auto
    gap, e = OSC["gap"], OSC["restitution"]
    zeta_c = -np.log(e) / np.hypot(np.pi, np.log(e))
    eps = SOFTPLUS_WIDTH * abs(gap) / np.sqrt(kc)
    w0 = OSC["omega_hi"]
    G = 1.0 / (1.0 - w0 * w0)

    def func(x: Any, par: Any) -> list[Any]:
        q, qd, c, s = x[0], x[1], x[2], x[3]
        z = (gap - q) / par[2]
        softplus = np.maximum(z, 0.0) + np.log(1.0 + np.exp(-np.abs(z)))
        sigmoid = 0.5 * (1.0 + np.tanh(0.5 * z))
        contact = par[1] * par[2] * softplus - par[3] * qd * sigmoid
        r2 = c * c + s * s
        return [qd, -q + c + contact, c + par[0] * s - c * r2, -par[0] * c + s - s * r2]

    def stpnt(x: Any, par: Any, t: Any) -> None:  # the free orbit at omega = 2, off the stop
        par[0], par[1], par[2], par[10] = w0, kc, eps, 2 * np.pi / w0
        par[3] = 2 * zeta_c * np.sqrt(kc)
        x[0] = G * np.cos(2 * np.pi * t)
        x[1] = -G * w0 * np.sin(2 * np.pi * t)
        x[2] = np.cos(2 * np.pi * t)
        x[3] = -np.sin(2 * np.pi * t)

    settings = dict(ips=auto.IPS_PERIODIC_ORBIT, ndim=4, npar=11, nmx=20_000, ntst=ntst, ncol=4,
                    ds=-1e-3, dsmin=1e-8, dsmax=0.02, rl0=OSC["omega_lo"], rl1=w0 + 1e-3,
                    epsl=1e-8, epsu=1e-8, epss=1e-5, npr=1)
    (res, t_auto, why), wall, cpu = timed(
        lambda: auto_run(func, stpnt, settings, [1, 11], transpile=True))
    config = f"k_c {kc:.0e}, NTST {ntst}"
    if res is None:
        return Row("oscillator", "AUTO-07p (penalty)", config, wall, cpu, float("nan"), 0,
                   {"failure": why, "kc": kc, "ntst": ntst})
    pts = auto_points(res)
    om, amp, low = [], [], []
    for pt in pts:
        if pt.periodic_orbit is None:
            continue
        q = np.asarray(pt.periodic_orbit.state)[:, 0]
        om.append(pt.parameters[0])
        amp.append(0.5 * (q.max() - q.min()))
        low.append(q.min())
    events: dict[str, list[float]] = {}
    for pt in pts:
        kind = {"FOLD": "fold", "PERIOD_DOUBLING": "period_doubling", "TORUS": "torus",
                "BRANCH_POINT": "branch_point"}.get(pt.point_type.name)
        if kind:
            events.setdefault(kind, []).append(float(pt.parameters[0]))
    for i in range(len(low) - 1):  # the stop first touched: min q through the gap
        if (low[i] - gap) * (low[i + 1] - gap) < 0:
            s = (gap - low[i]) / (low[i + 1] - low[i])
            events.setdefault("grazing", []).append(om[i] + s * (om[i + 1] - om[i]))
    err = response_error(np.array(om), np.array(amp))
    return Row("oscillator", "AUTO-07p (penalty)", config, wall, cpu, err, len(pts),
               {"kc": kc, "ntst": ntst, "events": events, "auto_time": t_auto,
                "ended": ended(pts, 0)})


def event_errors(events: dict[str, list[float]], ref: dict[str, Any]) -> str:
    """Each exact event's omega error (the nearest located event of the same kind)."""
    out = []
    for kind, exact in (("fold", [ref["fold"]]), ("grazing", [ref["grazing"]]),
                        ("period_doubling", ref["period_doubling"])):
        got = events.get(kind, [])
        for x in exact:
            out.append(f"{kind} {min(abs(g - x) for g in got):.1e}" if got else f"{kind} missed")
        if len(got) > len(exact):
            out.append(f"({len(got)} {kind} located)")
    return ", ".join(out)


def section_oscillator(args: argparse.Namespace) -> list[Row]:
    ref = oscillator_reference()
    mid = args.kc[len(args.kc) // 2]
    pairs = ([(k, n) for k in args.kc for n in args.ntst] if args.full else
             [(k, max(args.ntst)) for k in args.kc]
             + [(mid, n) for n in args.ntst if n != max(args.ntst)])
    rows = [oscillator_ours()] + [oscillator_auto(k, n) for k, n in pairs]
    print(f"\n3. Forced impact oscillator (gap {OSC['gap']}, e {OSC['restitution']}): "
          f"closed forms fold {ref['fold']:.6f}, grazing {ref['grazing']:.6f}, period "
          "doublings " + ", ".join(f"{x:.7f}" for x in ref["period_doubling"]))
    print("   response: largest relative distance of an orbit's amplitude to the closed-form "
          f"response at its omega, omega <= {RESPONSE_MAX_OMEGA}; events: |omega - exact| "
          "(nearest located event of the kind; AUTO's grazing: min q through the gap)")
    head = (f"   {'method':<22}{'config':<19}{'points':>7}{'wall [s]':>9}{'CPU [s]':>8}"
            f"{'AUTO [s]':>9}{'response':>10}  events")
    print(head)
    for r in rows:
        e = r.extra
        if "failure" in e:
            print(f"   {r.method:<22}{r.config:<19}  failed: {e['failure']}")
            continue
        extra = "" if "torus" not in e["events"] else f"; spurious TR {len(e['events']['torus'])}"
        print(f"   {r.method:<22}{r.config:<19}{r.points:>7d}{r.wall:>9.2f}{r.cpu:>8.2f}"
              f"{fmt(e.get('auto_time', np.nan), '9.2f')}{fmt(r.error, '10.1e')}  "
              f"{event_errors(e['events'], ref)}{extra}"
              + (f"; {e['ended']}" if "ended" in e else ""))
    return rows


# ----------------------------------------------------------------------------- chart, main
def chart(rows: list[Row], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter
    titles = {"stuart_landau": "1. Stuart-Landau (radius, period, multiplier)",
              "chain": "2. 5-dof chain, branch 1 (energy)",
              "oscillator": "3. impact oscillator (response amplitude)"}
    load = os.getloadavg()[0]
    present = [s for s in titles if any(r.section == s for r in rows)]
    fig, axes = plt.subplots(1, len(present), figsize=(5.2 * len(present), 4.6), squeeze=False)
    floor = 1e-17
    for ax, sec in zip(axes[0], present, strict=True):
        methods = list(dict.fromkeys(r.method for r in rows if r.section == sec))
        for k, method in enumerate(methods):
            sel = [r for r in rows if r.section == sec and r.method == method
                   and np.isfinite(r.error)]
            if not sel:
                continue
            marker = "o" if method.startswith("ours") else "s^v"[k % 3]
            ax.loglog([r.wall for r in sel], [max(r.error, floor) for r in sel], marker=marker,
                      linestyle="none", label=method)
            for r in sel:
                ax.annotate(r.config.replace("NTST ", "N").replace("k_c ", ""),
                            (r.wall, max(r.error, floor)), textcoords="offset points",
                            xytext=(4, 3), fontsize=6)
        ax.set_title(titles[sec], fontsize=10)
        ax.set_xlabel("wall time per run [s]")
        ax.set_ylabel("largest error against the closed form")
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle("Speed against accuracy: our package vs AUTO-07p (bifpy; impacts as penalty "
                 f"forces for AUTO); 2 shared cores, load {load:.0f}", fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> list[Row]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", type=int, nargs="+", default=[1, 2, 3], choices=[1, 2, 3])
    ap.add_argument("--kc", type=float, nargs="+", default=[1e3, 1e4, 1e5],
                    help="penalty stiffnesses (sections 2, 3)")
    ap.add_argument("--ntst", type=int, nargs="+", default=[50, 100, 200],
                    help="AUTO mesh intervals (sections 2, 3)")
    ap.add_argument("--full", action="store_true", help="every k_c x NTST pair")
    ap.add_argument("--hybrid-chain", action="store_true",
                    help="section 2 also through our hybrid layer (~75 s of CPU)")
    ap.add_argument("--out", type=Path, default=OUT, help="chart file")
    args = ap.parse_args(argv)
    why = missing_tools()
    if why:
        print(f"bench_auto07p: skipped: {why}")
        return []
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    from importlib.metadata import version
    print(f"bifpy {version('bifpy')}, Python {sys.version.split()[0]}, "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    rows: list[Row] = []
    sections = {1: section_stuart_landau, 2: section_chain, 3: section_oscillator}
    for k in args.sections:
        rows += sections[k](args)
    chart(rows, args.out)
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}; chart: {args.out}")
    return rows


if __name__ == "__main__":
    main()
