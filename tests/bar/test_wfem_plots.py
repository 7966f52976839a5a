"""Reconstructions and figures of the WFEM bar orbits (:mod:`problems.bar.plots`).

Yoong, Thorin, Legrand (2017), section 6, Figs. 8, 9, 13. Oracles:

* the end displacement from the stresses, ``u_(N+1/2) = (dx/E) sum sigma_j``, against the time
  integral of the end velocity ``-J[n]/Z`` (free) / 0 (contact) from ``u = g0`` at t = 0;
* the field against cell averages from :func:`problems.bar.wfem_operators.simulate_ring` and
  :func:`~problems.bar.wfem_operators.from_ring` (a second, independent stepping);
* the admissibility of the plotted orbit: ``u_end <= g0`` free, ``u_end = g0`` in contact (Fig. 8),
  a compressive and (main backbone, section 6.1) piecewise-constant contact force.
"""

from __future__ import annotations

import time
from math import gcd
from pathlib import Path
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from nsm_continuation.problems.bar.plots import (  # noqa: E402
    contact_force,
    contact_mask,
    displacement_field,
    end_time_series,
    extra_plots,
    manifold_section,
    orbit_section,
    resolve_point,
    space_time,
)
from nsm_continuation.problems.bar.wfem_bar import WfemBarParameters, WfemBarProblem  # noqa: E402
from nsm_continuation.problems.bar.wfem_lattice import (  # noqa: E402
    BarModel,
    LatticeSolution,
    node_solutions,
)
from nsm_continuation.problems.bar.wfem_operators import from_ring, simulate_ring  # noqa: E402
from oracles.wfem_bar import integrated_end_displacement  # noqa: E402


def orbit(N: int, g0: float, counts: tuple[int, ...]) -> LatticeSolution:
    status, sols = node_solutions(BarModel(1.0, 1.0, 1.0, N, g0), counts)
    assert status == "admissible" and sols, (counts, status)
    return sols[0]


CASES = {
    # main backbone mode 1: (2M - 4N, 4N - M), M odd in (3N, 4N) (g0 > 0) or (2N, 3N) (g0 < 0)
    "mode1 g0>0": (200, 1e-3, (602, 99)),
    "mode1 g0<0": (200, -1e-3, (202, 299)),
    "mode2 g0<0": (200, -1e-3, (112, 116)),  # near 3.5 omega_1, Fig. 10
    "subharmonic 3/2": (20, 1e-3, (52, 1)),  # one grazing instant, Fig. 13a
}


@pytest.fixture(scope="module", params=list(CASES))
def sol(request: pytest.FixtureRequest) -> LatticeSolution:
    N, g0, counts = CASES[request.param]
    return orbit(N, g0, counts)


def test_end_displacement_two_reconstructions_agree(sol: LatticeSolution) -> None:
    f = displacement_field(sol)
    assert f.u.shape == (sol.M + 1, sol.model.N + 1)
    u_stress = f.u[:, -1]
    u_vel = integrated_end_displacement(sol)
    scale = np.abs(u_stress).max()
    np.testing.assert_allclose(u_stress, u_vel, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(f.u[-1], f.u[0], rtol=0, atol=1e-12 * scale)  # periodic
    assert f.u[0, -1] == pytest.approx(sol.model.g0, abs=1e-12 * scale)


def test_field_matches_independent_stepping(sol: LatticeSolution) -> None:
    md = sol.model
    W = simulate_ring(sol.w0, sol.pattern)
    f = displacement_field(sol)
    for n in range(0, sol.M + 1, max(1, sol.M // 17)):
        sigma, _ = from_ring(W[n], md.Z)
        np.testing.assert_allclose(f.u[n, 1:], np.cumsum(sigma) * md.dx / md.E, rtol=0,
                                   atol=1e-13 * np.abs(f.u).max())
    # u_(3/2) = dx sigma_1 / E
    sig1 = np.array([from_ring(w, md.Z)[0][0] for w in W])
    np.testing.assert_allclose(f.u[:, 1], md.dx * sig1 / md.E, atol=1e-13 * np.abs(f.u).max())


def test_plotted_orbit_is_admissible(sol: LatticeSolution) -> None:
    g0 = sol.model.g0
    u = displacement_field(sol).u[:, -1]
    tiny = 1e-12 * np.abs(u).max()
    contact = contact_mask(sol)
    # node n ends step n - 1: in contact at both ends of a contact step
    in_contact = np.zeros(sol.M + 1, bool)
    in_contact[:-1] |= contact
    in_contact[1:] |= contact
    assert np.all(u <= g0 + tiny)
    np.testing.assert_allclose(u[in_contact], g0, rtol=0, atol=tiny)
    assert np.all(u[~in_contact] < g0 + tiny)
    for n in sol.grazing_steps:  # grazing: touches g0 inside a free phase
        assert not in_contact[n] and u[n] == pytest.approx(g0, abs=tiny)
    lam = contact_force(sol)
    assert np.all(lam >= 0) and np.all(lam[~contact] == 0) and lam[contact].min() > 0


def test_contact_force_piecewise_constant_on_main_backbone() -> None:
    """Section 6.1: 'the contact force associated to all the depicted motions is piecewise
    constant on a period' (one value per contact phase on the mode-1 backbone)."""
    N, g0 = 40, 1e-3
    for M in (123, 131, 139, 149, 157):
        assert gcd(M, N) == 1
        s = orbit(N, g0, (2 * M - 4 * N, 4 * N - M))
        lam = contact_force(s)[contact_mask(s)]
        assert np.ptp(lam) <= 1e-12 * lam.max()


def test_orbit_section_closes_and_jumps_only_in_velocity(sol: LatticeSolution) -> None:
    U, V, U3 = orbit_section(sol)
    assert len(U) == 2 * sol.M
    # displacements are continuous (segment ends meet), the velocity is constant on each step
    np.testing.assert_allclose(U[2::2], U[1:-1:2], atol=0)
    np.testing.assert_allclose(U3[2::2], U3[1:-1:2], atol=0)
    assert np.all(V[0::2] == V[1::2])
    np.testing.assert_allclose([U[0], U3[0]], [U[-1], U3[-1]], atol=1e-12 * np.abs(U).max())


def test_axes_functions_draw_events() -> None:
    s = orbit(*CASES["subharmonic 3/2"])
    fig = Figure()
    ax1, ax2 = fig.subplots(1, 2)
    space_time(ax1, s, periods=2)
    dotted = [ln for ln in ax1.lines if ln.get_linestyle() == ":"]
    closures = [ln for ln in ax1.lines if ln.get_linestyle() == "--" and ln.get_color() == "w"]
    assert len(dotted) == 2 * len(s.grazing_steps) == 2
    assert len(closures) == 2
    twin = end_time_series(ax2, s, periods=2)
    assert twin is not None
    fig3 = Figure()
    manifold_section(fig3.add_subplot(projection="3d"), [s], s.model.g0)


def _branch(problem: WfemBarProblem, nodes: list[tuple[int, int]]) -> SimpleNamespace:
    pts = []
    for counts in nodes:
        sols = problem.physical(counts)
        assert sols, counts
        pts.append(SimpleNamespace(derived=sols[0].derived()))
    return SimpleNamespace(points=pts)


def test_extra_plots_writes_files(tmp_path: Path) -> None:
    t0 = time.perf_counter()
    N = 40
    pr = WfemBarProblem(WfemBarParameters(cells=N, gap=1e-3))
    nodes = [(2 * M - 4 * N, 4 * N - M) for M in range(157, 121, -2) if gcd(M, N) == 1]
    br = _branch(pr, nodes)
    files = extra_plots(tmp_path, [br, SimpleNamespace(points=[])], pr)
    assert files == ["space_time.png", "end_displacement.png", "manifold_section.png"]
    for name in files:
        assert (tmp_path / name).stat().st_size > 10_000
    assert extra_plots(tmp_path / "none", [], pr) == []
    assert extra_plots(tmp_path / "none", [SimpleNamespace(points=[])], pr) == []
    assert time.perf_counter() - t0 < 10


def test_resolve_point_grazing_bar_scales_to_energy() -> None:
    """g0 = 0: amplitude-free node re-solved by its representative, scaled to the stored energy
    (T = 3L/c, contact L/c: section 6.1)."""
    N = 40
    pr = WfemBarProblem(WfemBarParameters(cells=N, gap=0.0))
    seed = pr.lattice_seeds({"branch": "main", "mode": 1}, (1.0, 2.0))[0].solution
    d = seed.derived()
    d["energy"] *= 1e4
    s = resolve_point(pr, d)
    assert s is not None and s.counts == seed.counts == (80, 40)
    assert s.energy == pytest.approx(d["energy"], rel=1e-12)
    u = displacement_field(s).u[:, -1]
    np.testing.assert_allclose(u, integrated_end_displacement(s), atol=1e-12 * np.abs(u).max())


# -- forced response figures (section 7, Figs. 20-22) ---------------------------------------------
def test_frequency_response_figure_draws_curves_references_and_backbones(tmp_path: Path) -> None:
    """The figures of a ``wfem_forced_bar`` run: the amplitude response (one curve per sweep,
    steady points filled and the others hollow, the linear reference dashed) and, on the
    branch diagram of the energy, the references and the backbones (a vertical line at the
    asymptote for g0 = 0); the problem's extra_plots file."""
    from nsm_continuation.problems.bar.forced_response import WfemForcedBarProblem
    from nsm_continuation.problems.bar.plots_forced import (
        frequency_response_figure,
        response_curves,
    )

    from nsm_continuation.figures.kit import subplots

    pr = WfemForcedBarProblem({"cells": 20, "gap": 0.0, "force_amplitude": 4e-3,
                               "damping_ratio": 0.1})
    x = np.array([0.5, 1.0, 1.5, 2.0])
    pts = [SimpleNamespace(derived={"omega_ratio": xi, "energy_ratio": 1e-6 * (1 + i),
                                    "amplitude": 1e-3, "steady": float(i % 2)})
           for i, xi in enumerate(x)]
    curves = response_curves([SimpleNamespace(points=pts, label="s"),
                              SimpleNamespace(points=[], label="empty")])
    assert len(curves) == 1 and curves[0].steady.tolist() == [False, True, False, True]
    xr, e, a = pr.presentation.reference_curve(pr.eta(0.1), (0.5, 2.0), n=50)
    assert np.isfinite(e).all() and np.isfinite(a).all()
    backbones = pr.presentation.backbones((0.5, 2.0))
    assert [b[2] for b in backbones] == ["NSM backbone, mode 1"]  # 4/3; mode 2's 16/5 is out
    fig = frequency_response_figure(curves, [(xr, e, a, "zeta_1 = 0.1")], title="t")
    (ax_a,) = fig.axes
    assert "omega" in ax_a.get_xlabel()
    assert ax_a.get_yscale() == "linear"  # the amplitudes do not span a decade
    ref = [ln for ln in ax_a.lines if ln.get_label() == "zeta_1 = 0.1"]
    assert len(ref) == 1 and np.array_equal(ref[0].get_ydata(), a)  # the linear reference
    hollow = [ln for ln in ax_a.lines if ln.get_marker() == "o" and ln.get_markerfacecolor()
              == "none"]
    assert len(hollow) == 1 and len(hollow[0].get_xdata()) == 2
    # the energy: the diagram's decorations, each kind labelled once
    _, ax_e = subplots()
    pr.presentation.plot_decorations(ax_e, (0.5, 2.0), [])
    labels = [ln.get_label() for ln in ax_e.lines if not ln.get_label().startswith("_")]
    assert len(labels) == len(set(labels))
    assert any(np.allclose(ln.get_xdata(), 4 / 3) for ln in ax_e.lines)  # g0 = 0 backbone
    e_fine = pr.presentation.reference_curve(pr.eta(0.1), (0.5, 2.0))[1]
    assert any(np.array_equal(ln.get_ydata(), e_fine) for ln in ax_e.lines)  # the reference
    br = SimpleNamespace(points=pts, label="s")
    assert pr.presentation.extra_plots(tmp_path, [br], (0.5, 2.0)) == ["frequency_response.png"]
    assert (tmp_path / "frequency_response.png").stat().st_size > 10_000
    assert pr.presentation.extra_plots(tmp_path / "none", [], (0.5, 2.0)) == []
