"""The events of the bundled two-wall cases against their closed forms: the acceptance table.

For each bundled two-wall case (``yaml_cases/two_sided_oscillator.yaml``,
``yaml_cases/impact_damper.yaml``) and each way of declaring the two walls the hybrid layer
accepts (``parameters.encoding``: ``single``, one constraint whose zero set is both walls, and
``surfaces``, two constraints), runs the case and prints

* the expected events of the symmetric two-impact family in the case's window, from the closed
  form (``tests/oracles/two_wall.py``: fold (T8), pitchfork ``branch_point``, Neimark-Sacker,
  period doubling (T13), interior ``grazing`` (T10), ``impact_velocity_vanishes`` (T7, T9)),
  located to 1e-13;
* against each, the reported event of the same kind nearest to it and the difference in omega
  (``ok`` within ``--tol``, default 1e-8), or the event of another kind reported there
  (``reported as ...``), or ``missing``;
* every reported event no expected one accounts for (``spurious``), except a
  ``stability_change`` at an expected event (a crossing, or a grazing where the multipliers
  jump), an ``endpoint`` at the window's edge or at an expected event (a named end: the branch
  ends there, e.g. at the interior grazing) and an ``unresolved_crossing`` (a count of
  multipliers changed within their noise: listed, no bifurcation claimed). Events on another
  family, after a branch went on through a grazing, are not the closed form's: they count as
  spurious.

Exit status 0 when every expected event is found to ``--tol`` with its kind and nothing is
spurious, 1 otherwise. Run: ``python benchmarks/two_wall_events.py [--tol 1e-8]
[--cases two_sided_oscillator impact_damper] [--encodings single surfaces]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from oracles import two_wall as tw  # noqa: E402

import nsm_continuation as nsm  # noqa: E402

CASES = ("two_sided_oscillator", "impact_damper")
#: how far (in omega) an event of another kind may sit to be called the expected one misnamed
NEAR = 1e-3


def oracle_system(values: dict[str, float]) -> tw.TwoWall:
    """The closed form's system with the case's parameter values."""
    if "mass_ratio" in values:
        return tw.damper(values["zeta"], values["mass_ratio"], values["clearance"],
                         values["restitution"])
    return tw.oscillator(values["zeta"], values["clearance"], values["restitution"])


def compare(expected: list[tw.Event], reported: list[Any], window: tuple[float, float],
            tol: float) -> tuple[list[tuple[str, ...]], bool]:
    """Rows ``(expected kind, expected omega, reported kind, reported omega, difference,
    verdict)`` and whether everything matched."""
    rows: list[tuple[str, ...]] = []
    used: set[int] = set()
    good = True
    for ev in expected:
        same = [(abs(r.parameter - ev.omega), i) for i, r in enumerate(reported)
                if r.kind == ev.kind and i not in used]
        near = [(abs(r.parameter - ev.omega), i) for i, r in enumerate(reported)
                if i not in used and r.kind not in ("stability_change",)]
        if same and min(same)[0] <= NEAR:
            d, i = min(same)
            verdict = "ok" if d <= tol else "off"
        elif near and min(near)[0] <= NEAR:
            d, i = min(near)
            verdict = f"reported as {reported[i].kind}"
            if reported[i].kind == "endpoint":
                verdict += f" ({reported[i].detail})"
        else:
            rows.append((ev.kind, f"{ev.omega:.12f}", "-", "-", "-", "missing"))
            good = False
            continue
        used.add(i)
        good &= verdict == "ok"
        r = reported[i]
        rows.append((ev.kind, f"{ev.omega:.12f}", r.kind, f"{r.parameter:.12f}",
                     f"{r.parameter - ev.omega:+.1e}", verdict))
    for i, r in enumerate(reported):
        if i in used:
            continue
        if r.kind == "stability_change" and any(abs(r.parameter - ev.omega) <= NEAR
                                                for ev in expected):
            continue
        if r.kind == "endpoint" and (min(abs(r.parameter - w) for w in window) <= 1e-9 or any(
                r.parameter == reported[j].parameter for j in used)):
            continue  # the window's edge, or a named end: the branch ends at an expected event
        if r.kind == "unresolved_crossing":  # no bifurcation claimed: listed, not spurious
            rows.append(("-", "-", r.kind, f"{r.parameter:.12f}", "-",
                         "unresolved: no bifurcation claimed"))
            continue
        detail = r.detail if r.kind == "endpoint" else ""
        rows.append(("-", "-", r.kind, f"{r.parameter:.12f}", "-", f"spurious {detail}".strip()))
        good = False
    return rows, good


def print_table(rows: list[tuple[str, ...]]) -> None:
    head = ("expected", "omega (closed form)", "reported", "omega (package)", "difference",
            "verdict")
    widths = [max(len(str(r[j])) for r in [head, *rows]) for j in range(len(head))]
    for r in [head, tuple("-" * w for w in widths), *rows]:
        print("  " + "  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)))


def run_one(case: str, encoding: str, tol: float) -> bool | None:
    """One case with one encoding: the table; None if the encoding cannot be declared."""
    path = ROOT / "yaml_cases" / f"{case}.yaml"
    try:
        loaded = nsm.load_case(path, {"parameters.encoding": encoding, "output.plots": False})
    except Exception as exc:  # an encoding this version's hybrid layer does not take
        print(f"\n{case} [{encoding}]: not run: {str(exc).splitlines()[0]}")
        return None
    t0 = time.perf_counter()
    res = nsm.run(loaded)
    dt = time.perf_counter() - t0
    cont = res.case.continuation
    window = (float(cont.min), float(cont.max))
    expected = tw.family_events(oracle_system(res.problem.values), *window)
    points = sum(len(b) for b in res.branches)
    print(f"\n{case} [{encoding}]: omega in [{window[0]}, {window[1]}], {points} points, "
          f"{dt:.1f} s; {len(expected)} expected events, {len(res.events)} reported")
    rows, good = compare(expected, res.events, window, tol)
    print_table(rows)
    for b in res.branches:
        print(f"  branch {b.id} ends: {b.termination}")
    return good


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tol", type=float, default=1e-8)
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    parser.add_argument("--encodings", nargs="+", default=["single", "surfaces"],
                        choices=["single", "surfaces"])
    args = parser.parse_args()
    results = [run_one(c, e, args.tol) for c in args.cases for e in args.encodings]
    ran = [r for r in results if r is not None]
    print(f"\n{sum(ran)} of {len(ran)} runs give exactly the closed form's events "
          f"(to {args.tol:g})")
    return 0 if ran and all(ran) else 1


if __name__ == "__main__":
    raise SystemExit(main())
