"""The chain is linear in the gap: an orbit at gap ``g != 0`` is ``|g|`` times the orbit at
``sign(g)`` (Legrand, Junca, Heng 2017, eq. 4.2: ``u(0) = (g / w_N) w(T)``). So the branch a
case continues at any gap in the accepted range is the gap-1 branch scaled: the same periods,
events and multipliers, energies times ``g^2``. Oracle: the run at ``|g| = 1`` and the scaling
law (exact in the closed form). At gap 1000 the default branch used to cover 1.6 % of itself
(the arclength was measured in the physical unknowns, ~g), from ~1e20 the start failed with a
singular Jacobian, and a gap of ``1e-400``, 0 in double precision, ran the static-grazing
problem (g = 0) without a word.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from helpers import ROOT

import nsm_continuation as nsm
from nsm_continuation.cases import CaseError

DEFAULT = str(ROOT / "yaml_cases" / "ndof_default.yaml")
#: a pre-stressed branch (g < 0, Fig. 7.3) from a root of w_N to its nonlinear grazing orbit
PRESTRESS: dict[str, Any] = {
    "name": "prestress", "problem": "ndof_impact",
    "parameters": {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0}, "gap": -1.0},
    "start": {"T": 1.2}, "continuation": {"parameter": "omega", "min": 4.85, "max": 6.1,
                                          "max_points": 300, "max_energy": 30.0},
    "analysis": {"stability": True, "stop_on_inadmissible": True},
    "output": {"plots": False, "progress": False}}


def run(case: Any, gap: float, **more: Any) -> Any:
    return nsm.run(case, {"parameters.gap": gap, "output.plots": False,
                          "output.progress": False, **more})


def assert_scaled(res: Any, ref: Any, g: float) -> None:
    """``res`` (gap ``g``) is ``ref`` (gap ``sign(g)``) scaled, to 1e-10."""
    assert len(res.branches) == len(ref.branches)
    for b, r in zip(res.branches, ref.branches, strict=True):
        assert b.termination == r.termination
        np.testing.assert_allclose(b["T"], r["T"], rtol=1e-10)
        np.testing.assert_allclose(b["energy"], g**2 * r["energy"], rtol=1e-10)
        np.testing.assert_allclose(b["v_out"], abs(g) * r["v_out"], rtol=1e-10, atol=1e-10 * abs(g))
    kinds = [(e.kind, e.branch) for e in res.events]
    assert kinds == [(e.kind, e.branch) for e in ref.events]
    np.testing.assert_allclose([e.parameter for e in res.events],
                               [e.parameter for e in ref.events], rtol=1e-10)


#: branch 1 from the linear grazing orbit A up to omega = 1.5 (B is at 1.5956)
WINDOW = {"continuation.max": 1.5}


@pytest.fixture(scope="module")
def gap_one() -> Any:
    return run(DEFAULT, 1.0, **WINDOW)


@pytest.mark.parametrize("g", [1e-100, 1e3, 1e100])
def test_default_branch_at_any_gap_is_the_gap_one_branch_scaled(gap_one: Any, g: float) -> None:
    # 14 of its events: multiplier crossings through +1, -1 and complex, stability changes
    assert len([e for e in gap_one.events if e.kind != "endpoint"]) == 14
    assert_scaled(run(DEFAULT, g, **WINDOW), gap_one, g)


def test_prestressed_branch_at_any_gap_is_the_gap_minus_one_branch_scaled() -> None:
    ref = run(PRESTRESS, -1.0)
    assert any(e.kind == "grazing" for e in ref.events)
    g = -1e40
    # the energy bound is the case's, absolute: scaled with the orbits
    assert_scaled(run(PRESTRESS, g, **{"continuation.max_energy": 30.0 * g**2}), ref, g)


@pytest.mark.parametrize(("text", "limit"), [("1e-400", "smallest"), ("-2.5e-330", "smallest"),
                                             ("1e400", "largest")])
def test_a_gap_beyond_double_precision_is_refused_not_rounded(tmp_path: Any, text: str,
                                                                 limit: str) -> None:
    """``1e-400`` is 0 in double precision: read as such it would silently be the
    static-grazing problem. Refused naming the key and quoting the value, from a file and
    from an override."""
    case = (ROOT / "yaml_cases" / "ndof_default.yaml").read_text().replace(
        "gap: 1.0", f"gap: {text}")
    path = tmp_path / "tiny.yaml"
    path.write_text(case)
    for source, overrides in ((str(path), []), (DEFAULT, [f"parameters.gap={text}"])):
        with pytest.raises(CaseError) as err:
            nsm.run(source, overrides)
        msg = str(err.value)
        assert "parameters.gap" in msg and repr(text) in msg and limit in msg, msg
        assert "\n" not in msg
