"""Brute-force attractors of the double pendulum (sec. 6) as an independent oracle for the
shooting orbits: simulation only (no sensitivities, no Newton), vs the Newton-converged orbit.

Measured (this machine, 2 shared cores): ~8-10 s for the whole file.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.impacting.brute_force import (
    brute_force,
    n_distinct,
    sequence_period,
    sweep,
    wrap,
)

#: shooting / continuation orbit of sec. 6.1 at e = 0.89 (y = [q2, q1dot, q2dot, e])
Q2_FIG8A = -1.14038278


def test_wrap_and_period_helpers() -> None:
    assert wrap(np.pi) == pytest.approx(np.pi)
    assert wrap(-np.pi) == pytest.approx(np.pi)
    assert wrap(3 * np.pi / 2) == pytest.approx(-np.pi / 2)
    assert wrap(-1.0 - 4 * np.pi) == pytest.approx(-1.0)
    seq = np.array([1.0, 2.0, 1.0, 2.0, 1.0, 2.0])
    assert sequence_period(seq) == 2
    assert n_distinct(seq) == 2
    assert sequence_period(np.array([1.0, 2.0, 3.0, 4.0])) is None
    # clusters straddling +-pi are one value
    assert n_distinct(np.array([np.pi - 1e-9, -np.pi + 1e-9])) == 1


def test_period1_attractor_matches_shooting_orbit() -> None:
    """e = 0.89, d = 0.5, T = -31.15, from the default initial state: the attractor is the
    period-1 orbit with complete chattering found by Newton on the shooting residual."""
    [(e, q2)] = brute_force("restitution", [0.89], {"d": 0.5, "torque": -31.15},
                            transient_returns=12, recorded_returns=4)
    assert e == 0.89
    assert q2.shape == (4,)
    assert np.ptp(q2) < 1e-8                        # a single point
    assert np.max(np.abs(q2 - Q2_FIG8A)) < 1e-6     # = the shooting orbit


def test_period2_attractor_at_d_05009() -> None:
    """e = 0.19, T = -40, d = 0.5009 (Fig. 9(a)): a period-2 orbit, two sticking intervals per
    two revolutions."""
    [pt] = sweep("d", [0.5009], {"restitution": 0.19, "torque": -40.0}, transient_returns=80,
                 recorded_returns=8)
    assert pt.q2.size == 8
    assert pt.n_distinct(1e-6) == 2
    assert pt.period(1e-7) == 2
    assert pt.all_sticking
    assert np.all(pt.n_sticking == 1)


def test_failure_is_recorded_and_restarted() -> None:
    """Past the homoclinic torque (sec. 6.3) the pendulum comes to rest on the wall: no return
    to the section. The reason is recorded, the value restarted from the default state (which
    also comes to rest), the q2 array is empty, and the sweep goes on."""
    pts = sweep("torque", [-31.001, -31.3], {"restitution": 0.9, "d": 0.5}, transient_returns=3,
                recorded_returns=2, max_time=100.0)
    assert not pts[0].ok and pts[0].q2.size == 0
    assert pts[0].failures and "no return to the section" in pts[0].failures[0]
    assert pts[1].ok and pts[1].q2.size == 2 and pts[1].restarted


def test_progress_is_a_bar_and_logged_lines_never_stdout(capsys, caplog) -> None:
    """``progress=True``: one INFO line a value on the module's logger naming the value and
    its period (1 at e = 0.89, as above) and a progress bar on stderr; nothing on stdout."""
    import logging

    values = [0.89, 0.8905]
    with caplog.at_level(logging.INFO, logger="nsm_continuation.hybrid.brute_force"):
        pts = sweep("restitution", values, {"d": 0.5, "torque": -31.15},
                    transient_returns=12, recorded_returns=4, progress=True)
    out, err = capsys.readouterr()
    assert out == ""
    lines = [r.getMessage() for r in caplog.records
             if r.name == "nsm_continuation.hybrid.brute_force"]
    assert len(lines) == len(values) == len(pts)
    for line, v, p in zip(lines, values, pts, strict=True):
        assert line.startswith(f"restitution = {v:.7g}: 4 returns, period {p.period()}")
    assert "brute force restitution" in err
