"""A start from a transient says what the transient found: where its returns to the section
have not settled on a period-1 orbit, the report warns with the numbers and with the stability
of the orbit Newton then converged to.

Oracle: the closed-form period-1 orbits of the undamped impact oscillator and their
multipliers (``tests/oracles/impact_oscillator.py``, Shaw & Holmes 1983): at ``omega = 1.05``
(gap -0.5, restitution 0.8) the one-impact orbit has a multiplier below -1 (past its period
doubling), so no transient can settle on it; at ``omega = 0.9`` it is stable (multipliers of
modulus ``r = 0.8``) and attracts the motion from rest.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from oracles.impact_oscillator import orbits, section_state

import nsm_continuation as nsm
from nsm_continuation.hybrid.case import SETTLED

GAP, R = -0.5, 0.8


def _start(omega: float):
    """The start of a continuation from 40 forcing periods of simulation from rest (the
    problem's default initial state), its branch and the run's warnings."""
    pb = nsm.problem("impact_oscillator", {"zeta": 0.0, "omega": omega, "gap": GAP,
                                           "restitution": R, "section_phase": 0.0})
    res = nsm.continuation(pb, {"transient": 40}, parameter="omega", min=omega - 0.01,
                           max=omega + 0.01, max_points=2)
    (br,) = res.branches
    start = min(br.raw.points, key=lambda p: abs(p.s))
    return start, res.warnings


def _largest_multiplier(omega: float) -> float:
    """The closed-form largest |multiplier| of the one-impact orbit: the roots of
    ``lambda^2 - trace lambda + r^2``."""
    (orbit,) = orbits(omega, GAP, R)
    return float(np.max(np.abs(np.roots([1.0, -orbit["trace"], R * R]))))


def test_unsettled_transient_warns_and_names_the_unstable_orbit_newton_found():
    omega = 1.05
    assert _largest_multiplier(omega) > 1.05  # the oracle: the period-1 orbit is unstable
    start, warnings = _start(omega)
    # Newton converged to the closed-form (unstable) orbit
    assert np.allclose(start.y[:2], section_state(omega, GAP, R, 0.0), atol=1e-8)
    assert abs(start.max_abs_multiplier - _largest_multiplier(omega)) < 1e-6
    (w,) = [w for w in warnings if "has not settled" in w]
    assert w.startswith("branch 0 (period-1 orbit): the transient (40 periods from the "
                        "initial state) has not settled on a period-1 orbit")
    assert "converged to an orbit that is unstable (1 multiplier outside the unit circle" in w
    lam = float(re.search(r"the largest \|lambda\| = ([0-9.]+)", w).group(1))
    assert abs(lam - _largest_multiplier(omega)) < 1e-3
    # the distance it states is that of the two returns it prints, and beyond SETTLED
    d = float(re.search(r"differ by ([0-9.e+-]+) ", w).group(1))
    pairs = re.findall(r"(q|qdot) ([-0-9.e+]+) -> ([-0-9.e+]+)", w)
    assert len(pairs) == 2
    printed = max(abs(float(b) - float(a)) for _, a, b in pairs)
    assert d == pytest.approx(printed, rel=5e-3)  # d is printed with 3 digits
    assert d > SETTLED * (1 + max(abs(float(a)) for _, a, _ in pairs))


def test_settled_transient_gives_no_warning():
    omega = 0.9
    assert _largest_multiplier(omega) < 1.0  # the oracle: the period-1 orbit is stable
    start, warnings = _start(omega)
    assert np.allclose(start.y[:2], section_state(omega, GAP, R, 0.0), atol=1e-8)
    assert start.n_unstable == 0
    assert not [w for w in warnings if "settled" in w], warnings


def test_the_command_line_prints_the_warning_even_quiet(tmp_path, capsys):
    """The YAML run of the unsettled start: the warning is a ``warning:`` line on stderr
    (with ``--quiet``) and a line of report.md's Warnings."""
    from nsm_continuation import cli

    case = tmp_path / "unsettled.yaml"
    case.write_text(
        "name: unsettled\nproblem: impact_oscillator\n"
        f"parameters: {{zeta: 0.0, omega: 1.05, gap: {GAP}, restitution: {R}, "
        "section_phase: 0.0}\nstart: {transient: 40}\n"
        "continuation: {parameter: omega, min: 1.04, max: 1.06, max_points: 2}\n"
        "output: {plots: false}\n")
    assert cli.main(["run", str(case), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    err = capsys.readouterr().err
    line = "warning: branch 0 (period-1 orbit): the transient (40 periods from the initial state)"
    assert line in err
    assert "it converged to an orbit that is unstable" in err
    report = (tmp_path / "out" / "report.md").read_text()
    assert "has not settled on a period-1 orbit" in report.split("## Warnings", 1)[1]
