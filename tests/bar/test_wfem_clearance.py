"""The WFEM bar with a second contact: its end between two walls (``-g1 <= u_end <= g0``), on
the lattice (:mod:`nsm_continuation.problems.bar.wfem_clearance`).

Oracle: a direct WFEM simulation that decides the boundary condition at x = L every step
(:mod:`oracles.wfem_clearance`: the end displacement integrated from its velocity, released by
the sign of each wall's force). Every orbit the lattice returns is that simulation's: the same
sequence of free, lower-wall and upper-wall steps, back on its initial state after one period,
the energy conserved, the end between the walls and on each of them.
"""

from __future__ import annotations

import numpy as np
import pytest
from nsm_continuation.problems.bar.wfem_clearance import (
    classify,
    solve_clearance_node,
    symmetric_clearance_nodes,
)
from nsm_continuation.problems.bar.wfem_lattice import BarModel
from oracles.wfem_clearance import simulate_clearance

G0 = 1e-3
MODEL = BarModel(1.0, 1.0, 1.0, 40, G0)


@pytest.fixture(scope="module")
def orbits():
    """The physical orbits of the symmetric nodes with periods of 150 to 160 steps (the main
    backbone near omega_1 and the grazing families there), and two nodes of the main backbone
    farther up in frequency."""
    sols = symmetric_clearance_nodes(MODEL, G0, 150, 160)
    for counts in [(26, 27, 26, 27), (14, 33, 14, 33)]:
        status, sol = solve_clearance_node(MODEL, counts, G0)
        assert status == "admissible" and classify(sol, G0) == "physical"
        sols.append(sol)
    return sols


def test_lattice_orbits_are_the_direct_simulation(orbits) -> None:
    """Each orbit, simulated step by step with the switching decided by the walls, keeps its
    pattern (m free, p on the lower wall, k free, l on the upper one), returns to its initial
    ring after M steps (1e-12), conserves its energy (1e-12) and stays between the walls,
    touching both."""
    assert len(orbits) >= 4
    for sol in orbits:
        m, p, k, l_ = sol.counts
        w, states, u, energy = simulate_clearance(sol.w0, sol.M, MODEL.E, MODEL.rho, MODEL.dx,
                                                  G0, G0)
        assert states == ["free"] * m + ["lower"] * p + ["free"] * k + ["upper"] * l_
        scale = np.max(np.abs(sol.w0))
        assert np.max(np.abs(w - sol.w0)) <= 1e-12 * scale
        assert np.ptp(energy) <= 1e-12 * sol.energy
        assert abs(energy[0] - sol.energy) <= 1e-12 * sol.energy
        assert u.max() <= G0 * (1 + 1e-12) and u.min() >= -G0 * (1 + 1e-12)
        assert abs(u.min() + G0) <= 1e-12 * G0 and abs(u[-1] - G0) <= 1e-12 * G0


def test_unequal_gaps_are_the_direct_simulation() -> None:
    """A non-symmetric node with the lower wall twice as far (``g1 = 2 g0``, N = 20): the orbit
    the lattice returns is the direct simulation's (pattern, periodicity, both walls)."""
    model, g1 = BarModel(1.0, 1.0, 1.0, 20, G0), 2 * G0
    status, sol = solve_clearance_node(model, (2, 13, 14, 13), g1)
    assert status == "admissible" and classify(sol, g1) == "physical"
    m, p, k, l_ = sol.counts
    w, states, u, energy = simulate_clearance(sol.w0, sol.M, model.E, model.rho, model.dx,
                                              G0, g1)
    assert states == ["free"] * m + ["lower"] * p + ["free"] * k + ["upper"] * l_
    assert np.max(np.abs(w - sol.w0)) <= 1e-12 * np.max(np.abs(sol.w0))
    assert np.ptp(energy) <= 1e-12 * sol.energy
    assert abs(u.min() + g1) <= 1e-12 * g1 and abs(u[-1] - G0) <= 1e-12 * G0


def test_main_backbone_hardens_from_omega_1(orbits) -> None:
    """On the main backbone (``m + 2p = 2N``: each free phase lasts ``2L/c - 2 tau_c``, the
    period ``4L/c - 2 tau_c``) the frequency rises above omega_1 with the contact time
    ``tau_c = p dt``, and the energy with it (hardening, as for one wall)."""
    main = sorted((s for s in orbits if s.counts[0] + 2 * s.counts[1] == 2 * MODEL.N),
                  key=lambda s: s.omega)
    assert len(main) >= 3
    om = [s.derived()["omega_ratio"] for s in main]
    en = [s.energy for s in main]
    assert om[0] > 1.0 and np.all(np.diff(om) > 0) and np.all(np.diff(en) > 0)


def test_bad_nodes_are_named() -> None:
    with pytest.raises(ValueError, match="four positive"):
        solve_clearance_node(MODEL, (3, 1, 3), G0)
    with pytest.raises(ValueError, match="both gaps positive"):
        solve_clearance_node(BarModel(1.0, 1.0, 1.0, 40, 0.0), (78, 1, 78, 1), G0)
