#!/usr/bin/env python3
"""Compare two folders of runs of the bundled cases, e.g. before and after a change that must keep
every number: every CSV byte for byte (else the largest relative difference of its numbers),
report.json without its timings (numbers bitwise, else the largest relative difference),
report.md without its timing lines, and every PNG figure byte for byte. Prints one line per case:
``identical``, ``named-only`` (equal once the named differences below are applied) or ``DIFF``
with what differs; exit status 1 if any case differs.

Produce the two folders by running every case (``yaml_cases/*.yaml`` then
``yaml_cases/restart/*.yaml``, which read their parents from ``runs/``) from an empty working
folder with each version installed, e.g. ``cd /tmp/before && for f in .../yaml_cases/*.yaml
.../yaml_cases/restart/*.yaml; do nsm-continuation run $f; done``.

usage: python benchmarks/compare_runs.py BEFORE/runs AFTER/runs [case ...]
"""

import json
import math
import sys
from pathlib import Path

#: named differences of the layered layout: the settings list the run's energy cap and the case's
#: execution block its no-worker timeout (both ignored below); texts quoted in reports name the
#: new module of located curves, ``Problem.monitors`` and the test folders
KNOWN = {
    "nsm_continuation.algorithms.curves": "nsm_continuation.event_curves",
    "(Problem.monitors)": "(Problem.test_kinds, Problem.event_function_kinds)",
    "tests/hybrid/test_pendulum_model.py": "tests/test_pendulum_model.py",
}


def norm(text):
    for a, b in KNOWN.items():
        text = text.replace(a, b)
    return text


def strip(d, path=""):
    if isinstance(d, dict):
        return {
            k: strip(v, f"{path}.{k}")
            for k, v in d.items()
            if k not in ("timings", "total_s", "elapsed_s")
            and not (k == "energy_cap" and path.endswith("settings"))
            and not (k == "no_workers_timeout" and path.endswith("execution"))
        }
    if isinstance(d, list):
        return [strip(v, path) for v in d]
    if isinstance(d, str):
        return norm(d)
    return d


def numdiff(a, b, path="", out=None):
    if out is None:
        out = {"max_rel": 0.0, "struct": []}
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            out["struct"].append(f"{path}: keys {sorted(set(a) ^ set(b))}")
        for k in set(a) & set(b):
            numdiff(a[k], b[k], f"{path}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out["struct"].append(f"{path}: len {len(a)} != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            numdiff(x, y, f"{path}[{i}]", out)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if a != b and not (isinstance(a, float) and math.isnan(a) and math.isnan(b)):
            r = abs(a - b) / max(abs(a), abs(b), 1e-300)
            out["max_rel"] = max(out["max_rel"], r)
            if r > 1e-12:
                out["struct"].append(f"{path}: {a!r} != {b!r}")
    elif a != b:
        out["struct"].append(f"{path}: {str(a)[:80]!r} != {str(b)[:80]!r}")
    return out


def csvdiff(pa, pb):
    la, lb = pa.read_text().splitlines(), pb.read_text().splitlines()
    if len(la) != len(lb):
        return f"rows {len(la)} != {len(lb)}"
    worst = 0.0
    for x, y in zip(la, lb, strict=True):
        if x == y:
            continue
        for u, v in zip(x.split(","), y.split(","), strict=False):
            if u == v:
                continue
            try:
                fu, fv = float(u), float(v)
                worst = max(worst, abs(fu - fv) / max(abs(fu), abs(fv), 1e-300))
            except ValueError:
                return f"text {u!r} != {v!r}"
    return worst


base, new = Path(sys.argv[1]), Path(sys.argv[2])
cases = sys.argv[3:] or sorted(p.name for p in base.iterdir() if p.is_dir())
bad = 0
for c in cases:
    a, b = base / c, new / c
    if not b.exists():
        print(f"{c:45s} MISSING in new")
        bad += 1
        continue
    notes = []
    fa = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    fb = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    if fa != fb:
        notes.append(f"files differ: {sorted(set(map(str, fa)) ^ set(map(str, fb)))}")
    worst = 0.0
    figs_diff = []
    named = []
    for rel in set(fa) & set(fb):
        pa, pb = a / rel, b / rel
        if pa.read_bytes() == pb.read_bytes():
            continue
        if rel.suffix == ".csv":
            d = csvdiff(pa, pb)
            if isinstance(d, str):
                notes.append(f"{rel}: {d}")
            else:
                worst = max(worst, d)
        elif rel.name == "report.json":
            named.append(str(rel))
            d = numdiff(strip(json.loads(pa.read_text())), strip(json.loads(pb.read_text())))
            worst = max(worst, d["max_rel"])
            notes += [f"{rel}: {s}" for s in d["struct"][:5]]
        elif rel.suffix == ".png":
            figs_diff.append(str(rel))
        elif rel.suffix == ".md":
            da = [
                norm(l)
                for l in pa.read_text().splitlines()
                if " s" not in l and "time" not in l.lower()
            ]
            db = [
                norm(l)
                for l in pb.read_text().splitlines()
                if " s" not in l and "time" not in l.lower()
            ]
            if da != db:
                notes.append(f"{rel}: text differs")
            else:
                named.append(str(rel))
    status = (
        ("identical" if not named else "named-only")
        if not notes and worst == 0 and not figs_diff
        else ("numbers-equal" if not notes and worst <= 1e-12 else "DIFF")
    )
    if status == "DIFF":
        bad += 1
    print(
        f"{c:45s} {status:14s} max_rel={worst:.1e} figs_changed={len(figs_diff)} "
        f"{'; '.join(notes)[:300]}"
    )
sys.exit(1 if bad else 0)
