"""The two-mass chain at the ends of the restitution's range, e = 0 (plastic: stick or release)
and e -> 1, against an independent event-driven simulation by SciPy (``tests/oracles/
two_mass_wall.py``): every recorded return of a brute-force sweep and every continued orbit is
the oracle's flow over one forcing period from the recorded state, and no recorded orbit
crosses the wall.

At e = 0 the damping force on the second mass vanishes with its velocity at the impact, so the
acceleration that decides between sticking and release changes sign across the impact where
the spring's pull on the mass is weaker than the damping's (omega = 0.64 here): decided on the
pre-impact state, the mass was released into the wall and flew through it (``max_q2`` 0.80
against the wall at 0.5, recorded as an orbit).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from oracles.two_mass_wall import simulate

import nsm_continuation as nsm

PARAMS = {"m1": 1.0, "m2": 1.0, "k1": 1.0, "k2": 1.0, "c": 0.05, "F0": 0.5, "omega": 0.6,
          "gap": 0.5}
STATE = ("y_q1", "y_q2", "y_q1dot", "y_q2dot")


def case(restitution: float, continuation: dict[str, Any], start: dict[str, Any]
         ) -> dict[str, Any]:
    return {"name": "plastic", "problem": "two_mass_chain",
            "parameters": {**PARAMS, "restitution": restitution}, "start": start,
            "continuation": {"parameter": "omega", **continuation},
            "analysis": {"stability": False, "bifurcations": False},
            "output": {"plots": False, "progress": False}}


def one_period(row: dict[str, float], x0: np.ndarray, restitution: float) -> Any:
    omega = row["omega"]
    t0 = row["section_phase"] / omega
    return simulate(x0, t0, t0 + 2 * np.pi / omega,
                    {**PARAMS, "omega": omega, "restitution": restitution})


#: the boolean columns (stable: masked where a point has no multipliers)
FLAGS = ("admissible", "stable")


@pytest.mark.parametrize("restitution", [0.0, 0.99])
def test_sweep_returns_are_the_oracles_flow(restitution: float) -> None:
    res = nsm.run(case(restitution, {"algorithm": "sweep", "min": 0.6, "max": 0.68,
                                     "max_points": 5, "direction": "increase"},
                       {"transient": 12, "record": 3}))
    cols = res.branches[0].columns()
    rows = [{k: float(v[i]) for k, v in cols.items() if k not in FLAGS}
            for i in range(len(cols["omega"]))]
    assert max(r["max_q2"] for r in rows) <= PARAMS["gap"] * (1 + 1e-12)
    assert {round(r["omega"], 12) for r in rows} == {0.6, 0.62, 0.64, 0.66, 0.68}
    assert not any(r["failures"] for r in rows)
    sticking = 0
    for prev, row in zip(rows, rows[1:], strict=False):
        if row["omega"] != prev["omega"] or row["return_index"] != prev["return_index"] + 1:
            continue
        x0 = np.array([prev[k] for k in STATE])
        flight = one_period(row, x0, restitution)
        assert np.abs(flight.x - [row[k] for k in STATE]).max() < 1e-7
        assert flight.impacts == row["n_impacts"]
        assert flight.sticking_time == pytest.approx(row["sticking_time"], abs=1e-7)
        assert flight.sticking_phases == row["n_sticking_phases"]
        assert flight.max_q2 <= row["max_q2"] + 1e-9
        sticking += flight.sticking_time > 0
    # e = 0: the mass sticks once per period at every value (at 0.62 across the section, where
    # the sweep records the state); e = 0.99: it never sticks
    assert sticking == (10 if restitution == 0.0 else 0)


def test_plastic_orbits_continued_are_periodic_for_the_oracle() -> None:
    res = nsm.run(case(0.0, {"min": 0.6, "max": 0.7, "max_points": 25,
                             "step": {"initial": 0.01, "max": 0.01}},
                       {"transient": 40}))
    cols = res.branches[0].columns()
    assert len(cols["omega"]) >= 10
    for i in range(len(cols["omega"])):
        row = {k: float(v[i]) for k, v in cols.items()
               if k not in (*FLAGS, "signature")}  # text
        x0 = np.array([row[k] for k in STATE])
        flight = one_period(row, x0, 0.0)
        assert np.abs(flight.x - x0).max() < 1e-7
        assert flight.sticking_time == pytest.approx(row["sticking_time"], abs=1e-7)
        assert flight.sticking_phases == row["n_sticking_phases"]
        assert row["max_q2"] <= PARAMS["gap"] * (1 + 1e-12)
