"""The bar's gap: what the models scale with, and where that ends (Yoong, Thorin, Legrand 2017).

The bar is linear in the gap ``g0`` (the kernel vector of a lattice node is normalised by it,
eq. 12), so a branch at ``g0`` is the branch at any other gap of the same sign scaled: the same
frequencies and ``E / E_ref`` (oracle: the run at ``|g0| = 1e-3``). Two things end that:

* COND3, the small-strain bound ``|sigma| <= E``. The end's displacement is the integral of the
  strain, so no orbit exists for ``|g0| > L``; on the continuum main backbone the strain reaches
  1 where ``|mu| = 2 |g0| / L`` (``cond3 = mu^2/4 - |g0| |mu| / (2L)``), i.e. at the energy
  ``2 E g0^2 / (L mu^2) = E L / 2``, ``E / E_ref = 8 L^2 / (pi^2 g0^2)``: a branch at a large
  gap ends there, and the message says COND3 (it said "no physical admissible lattice orbit",
  and at gap 1 the start blamed ``cells``);
* double precision: the energies scale as ``g0^2``; a gap whose reference energy
  ``pi^2 E g0^2 / (16 L)`` leaves ``[1e-200, 1e200]`` is refused naming the gap range that holds
  for the case's ``E`` and ``L`` (1e-100 was refused on "the reference energy" although the
  documented range included it).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import nsm_continuation as nsm
from nsm_continuation.cases import CaseError

CASE: dict[str, Any] = {
    "name": "bar", "problem": "wfem_bar", "parameters": {"cells": 100, "gap": 1e-3},
    "start": [{"branch": "main", "mode": 1}, {"branch": "main", "mode": 2}],
    "continuation": {"parameter": "omega_ratio", "min": 1.0, "max": 4.0, "max_energy": 1e3},
    "output": {"plots": False, "progress": False}}


def run(gap: float, case: dict[str, Any] = CASE) -> Any:
    return nsm.run(case, {"parameters.gap": gap})


@pytest.mark.parametrize(("ref", "gaps"), [(1e-3, (1e-60, 0.02)), (-1e-3, (-1e-60,))])
def test_lattice_branches_scale_with_the_gap(ref: float, gaps: tuple[float, ...]) -> None:
    base = run(ref)
    assert "asymptote" in [e.kind for e in base.events]
    for g in gaps:
        res = run(g)
        assert [e.kind for e in res.events] == [e.kind for e in base.events]
        np.testing.assert_allclose([e.parameter for e in res.events],
                                   [e.parameter for e in base.events], rtol=1e-12)
        for b, r in zip(res.branches, base.branches, strict=True):
            np.testing.assert_allclose(b["omega_ratio"], r["omega_ratio"], rtol=1e-12)
            np.testing.assert_allclose(b["energy_ratio"], r["energy_ratio"], rtol=1e-10)
            np.testing.assert_allclose(b["energy"], (g / ref) ** 2 * r["energy"], rtol=1e-10)


def test_continuum_branches_scale_with_the_gap() -> None:
    """The continuum's points are placed by the step control, which also watches COND3 (a
    function of ``g0 / L``: the points differ), but the branch and its events do not."""
    case = {"name": "cont", "problem": "bar_continuum", "parameters": {"gap": 1e-3},
            "start": {"branch": "main", "mode": 1},
            "continuation": {"parameter": "omega_ratio", "min": 0.9, "max": 1.4,
                             "max_energy": 1e3},
            "analysis": {"stability": False, "bifurcations": False},
            "output": {"plots": False, "progress": False}}
    base, tiny = run(1e-3, case), run(1e-90, case)
    assert tiny.branches[0].termination == base.branches[0].termination
    assert [e.kind for e in tiny.events] == [e.kind for e in base.events]
    np.testing.assert_allclose([e.parameter for e in tiny.events],
                               [e.parameter for e in base.events], rtol=1e-10)
    for res in (base, tiny):   # on the closed form E / E_ref = 8 / (pi^2 (T - 3)^2) (mode 1)
        b = res.branches[0]
        T = 4.0 / b["omega_ratio"]
        ok = b["admissible"] > 0
        np.testing.assert_allclose(b["energy_ratio"][ok], 8 / (np.pi**2 * (T[ok] - 3) ** 2),
                                   rtol=1e-10)


def test_a_branch_at_a_large_gap_ends_at_cond3_where_the_continuum_strain_reaches_one() -> None:
    g0, L = 0.1, 1.0
    res, small = run(g0), run(1e-3)
    bound = 8 * L**2 / (np.pi**2 * g0**2)        # E / E_ref where |sigma| = E
    for b, s in zip(res.branches, small.branches, strict=True):
        (why,) = b.termination.values()
        assert why.startswith("COND3"), why
        last = b["energy_ratio"][-1]
        assert last <= bound
        # the same branch at a small gap goes on: its next orbit is beyond the bound
        (k,) = np.nonzero(s["omega_ratio"] == b["omega_ratio"][-1])[0]
        assert s["energy_ratio"][k] == pytest.approx(last, rel=1e-12)
        assert s["energy_ratio"][k + 1] > bound


@pytest.mark.parametrize(("gap", "words"), [
    (1e-100, ["parameters.gap", "1.27e-100", "E = 1, L = 1"]),
    (1.5, ["parameters.gap", "L = 1", "COND3"]),
    (0.9, ["parameters.gap", "COND3", "mode 2", "below 0.26"]),
])
def test_a_gap_outside_the_range_is_refused_naming_its_cause(gap: float,
                                                             words: list[str]) -> None:
    with pytest.raises(CaseError) as err:
        nsm.run(CASE, {"parameters.gap": gap, "parameters.cells": 200})
    msg = str(err.value)
    assert "\n" not in msg and "cells" not in msg, msg
    for w in words:
        assert w in msg, msg
