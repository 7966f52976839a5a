"""Event locations printed to the digits their bracket supports (report.md), full floats kept
in report.json.

Oracle: on the line ``x = p`` continued with unit tangent ``(1, 1) / sqrt(2)``, with a derived
quantity ``q = 3 p``, an event located to a bracket ``w`` in arclength is uncertain by ``w /
sqrt(2)`` in ``p`` and ``3 w / sqrt(2)`` in ``q``; the printed value ends at the decimal place of
its uncertainty's leading digit (``q = 3.703703673`` with ``w = 1e-6``: uncertainty 2.1e-6,
printed ``3.703704``, six decimals).
"""

from __future__ import annotations

import numpy as np

from nsm_continuation.core.records import Branch, Event, Point
from nsm_continuation.output import report
from nsm_continuation.output.files import event_record, location_uncertainty

T = np.array([1.0, 1.0]) / np.sqrt(2.0)


def _point(p: float) -> Point:
    return Point(y=np.array([p, p]), s=float(np.sqrt(2.0) * p), tangent=T, tests={},
                 multipliers=None, trivial_error=0.0, n_unstable=0, derived={"q": 3.0 * p},
                 bordered_det=1.0)


def _row(bracket: float, p: float = 1.234567891234) -> tuple[list[str], dict]:
    pts = [_point(v) for v in (0.5, 1.0, 1.5, 2.0)]
    ev = Event("branch_point", _point(p), "x", bracket=bracket)
    br = Branch(0, "b", pts, [ev], {})
    rec = event_record(ev)
    rec["p"] = p
    rec["location_uncertainty"] = location_uncertainty(br, ev, ["p", "q"], ["x", "p"])
    rep = {"case": {"name": "t", "description": ""}, "problem": "toy",
           "continuation": {"parameter": "p", "window": [None, None]},
           "timings": {"n_points": 4, "total_s": 0.0}, "event_columns": ["p", "q"],
           "branches": [{"id": 0, "label": "b", "n_points": 4, "admissible_points": 4,
                         "parameter_range": None, "termination": "", "csv": "branch_0.csv",
                         "events": [rec]}]}
    line = next(x for x in report.markdown(rep).splitlines() if "| branch_point |" in x)
    return [c.strip() for c in line.strip("|").split("|")][2:4], rec


def test_uncertainty_is_the_bracket_times_the_rate_along_the_branch() -> None:
    _, rec = _row(1e-6)
    unc = rec["location_uncertainty"]
    assert abs(unc["p"] - 1e-6 / np.sqrt(2.0)) < 1e-18
    assert abs(unc["q"] - 3e-6 / np.sqrt(2.0)) < 1e-18


def test_printed_to_the_decimal_place_of_the_uncertainty() -> None:
    p = 1.234567891234
    (sp, sq), rec = _row(1e-6, p)
    assert sp == f"{p:.7f}"            # uncertainty 7.1e-7: the 7th decimal
    assert sq == f"{3 * p:.6f}"        # uncertainty 2.1e-6: the 6th decimal
    assert rec["q"] == 3 * p           # report.json keeps the full float
    (sp, sq), _ = _row(0.0, p)        # located exactly (a bound): 12 significant digits
    assert (sp, sq) == (f"{p:.12g}", f"{3 * p:.12g}")
