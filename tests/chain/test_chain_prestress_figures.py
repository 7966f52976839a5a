"""Figs. 7.2 (g < 0) and 7.4 (g = 0) of Legrand, Junca, Heng (2017) from the bundled cases
``yaml_cases/ndof_fig7_2_prestress_manifolds.yaml`` and
``yaml_cases/ndof_fig7_4_static_grazing_manifolds.yaml``, each checked against an oracle
independent of what it checks:

* the modal data are recomputed here (``numpy.linalg.eigh`` of ``M^-1/2 K M^-1/2``, not the
  problem's ``scipy`` generalised eigenproblem) and ``u_N(t; T, g)`` is evaluated from the
  paper's closed form (7.2)-(7.3) directly, sampled densely in time (no
  :class:`~problems.chain.trig_sum.TrigSum`, no critical-point search);
* Fig. 7.2: the nonlinear grazing orbit that ends each g < 0 branch (omega_nl1, omega_nl2) is
  the period at which ``max_t u_N(t) = g`` on the sampled closed form (root in ``T``); the
  admissible part runs from there to the root of ``w_N`` (omega_nl3, omega_nl4: the energy
  grows without bound), every sampled orbit on it satisfying ``u_N <= g``; an event-driven
  simulation (``simulate_first_return``, DOP853) returns at ``T`` just inside the boundary and
  hits the wall early just beyond it (the extra contact);
* Fig. 7.4: the switched branches are vertical at the roots of ``w_N`` (Prop. 7.2, root found
  here by ``brentq`` on (3.1)), their points are ``v (w(T*), e_N)``, and exactly the half
  ``v < 0`` stays behind the wall on the sampled closed form;
* the figures (``manifold.png``, ``orbits_time.png``) are written by the cases.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import CASES
from nsm_continuation.problems.chain.ndof_impact import simulate_first_return
from scipy.optimize import brentq, minimize_scalar

import nsm_continuation as nsm
from nsm_continuation.core.records import Event, Point
from nsm_continuation.figures.orbits import Chosen, bounds_admissible_part, colour_quantity, traces

FIG72 = CASES / "ndof_fig7_2_prestress_manifolds.yaml"
FIG74 = CASES / "ndof_fig7_4_static_grazing_manifolds.yaml"
QUIET = {"output.progress": False}


# ------------------------------------------------------------------ the independent oracle
class ClosedForm:
    """The paper's chain (2.17), N = 5, m = 1/N, k = N, with its own modal data, and the
    closed-form orbit (7.1)-(7.3) of period ``T`` for the gap ``g``."""

    def __init__(self, n: int = 5) -> None:
        m, k = 1.0 / n, float(n)
        K = np.zeros((n, n))
        for i in range(n):
            K[i, i] += k
            if i > 0:
                K[i - 1, i - 1] += k
                K[i - 1, i] -= k
                K[i, i - 1] -= k
        w2, V = np.linalg.eigh(K / m)  # M = m I: M^-1/2 K M^-1/2 = K / m
        self.w = np.sqrt(w2)
        self.P = V / np.sqrt(m)           # P^T M P = I
        self.Pinv = V.T * np.sqrt(m)      # P^-1 = P^T M
        self.a = self.P[-1, :] * self.Pinv[:, -1]

    def w_N(self, T: float) -> float:
        """(3.1): ``sum_j a_j cot(w_j T / 2) / w_j``."""
        return float(np.sum(self.a / (self.w * np.tan(self.w * T / 2))))

    def u_N(self, t: np.ndarray, T: float, g: float) -> np.ndarray:
        """(7.3): ``u_N(t) = g / w_N(T) sum_j a_j (cos(w_j t) cot(w_j T / 2) + sin(w_j t)) /
        w_j`` (``Phi = Omega^-1 cot(T Omega / 2)``, diagonal in modal coordinates)."""
        t = np.asarray(t, dtype=float)[..., None]
        terms = self.a * (np.cos(self.w * t) / np.tan(self.w * T / 2) + np.sin(self.w * t))
        return g / self.w_N(T) * np.sum(terms / self.w, axis=-1)

    def max_u_N(self, T: float, g: float, samples: int = 4000) -> float:
        """``max u_N`` over ``(0, T)``: dense sampling, then the sampled maximum polished by a
        bounded scalar search on its neighbouring samples."""
        t = np.linspace(0.0, T, samples)[1:-1]
        u = self.u_N(t, T, g)
        i = int(np.argmax(u))
        lo, hi = t[max(i - 1, 0)], t[min(i + 1, t.size - 1)]
        res = minimize_scalar(lambda s: -float(self.u_N(s, T, g)), bounds=(lo, hi),
                              method="bounded", options={"xatol": 1e-14})
        return max(float(u[i]), -float(res.fun))

    def state(self, T: float, g: float) -> tuple[np.ndarray, np.ndarray]:
        """(7.1): ``(u(0), u'(0+)) = g / w_N(T) (w(T), e_N)``, ``w(T) = P Phi P^-1 e_N``."""
        wT = self.P @ (self.Pinv[:, -1] / (self.w * np.tan(self.w * T / 2)))
        v = g / self.w_N(T)
        du = np.zeros_like(wT)
        du[-1] = v
        return v * wT, du


ORACLE = ClosedForm()


# ------------------------------------------------------------------ Fig. 7.2 (g < 0)
def run_and_save(case: Path, tmp_path_factory: pytest.TempPathFactory
                 ) -> tuple[nsm.Result, Path]:
    """The bundled case run as it is (figures included) and saved into a fresh folder."""
    res = nsm.run(case, QUIET)
    return res, res.save(tmp_path_factory.mktemp(case.stem) / "run")


@pytest.fixture(scope="module")
def fig72(tmp_path_factory: pytest.TempPathFactory) -> tuple[nsm.Result, Path]:
    return run_and_save(FIG72, tmp_path_factory)


def test_fig7_2_branches_end_at_the_sampled_nonlinear_grazing(fig72) -> None:
    """Each branch ends (stop_on_inadmissible) at a 'clearance' grazing whose period is the
    root of ``max_t u_N(t; T, g) - g`` on the independently sampled closed form."""
    res, _ = fig72
    g = -1.0
    found = []
    for br in res.run_result.branches:
        graz = [ev for ev in br.events if ev.kind == "grazing"]
        assert len(graz) == 1 and graz[0].data["test"] == "clearance"
        assert bounds_admissible_part(graz[0])
        T_ev = float(graz[0].point.derived["T"])
        T_or = brentq(lambda T: ORACLE.max_u_N(T, g) - g, 0.995 * T_ev, 1.005 * T_ev,
                      xtol=1e-14)
        assert abs(T_ev - T_or) < 1e-9 * T_or
        found.append(2 * np.pi / T_or)
    # omega_nl1 < omega_nl2 (branches 1 and 2 of Fig. 7.3 as the case chose them)
    assert found == pytest.approx([5.99456356, 8.13482159], abs=1e-7)


def test_fig7_2_admissible_part_runs_from_a_root_of_w_N_to_the_grazing(fig72) -> None:
    """Every point of each branch is admissible on the sampled closed form (``u_N <= g`` and
    ``v < 0``); the far end lies just above a root of ``w_N`` (omega_nl3, omega_nl4), the
    energy rising towards it (the manifold is unbounded there)."""
    res, _ = fig72
    g = -1.0
    roots = []
    for br in res.run_result.branches:
        pts = sorted(br.points, key=lambda p: p.derived["T"])
        for p in pts[:: max(len(pts) // 25, 1)]:
            T = float(p.derived["T"])
            if not p.admissible:  # the located grazing point itself (clearance ~ -1e-13)
                assert abs(p.tests["clearance"]) < 1e-10
                continue
            assert ORACLE.max_u_N(T, g) < g + 1e-12
            assert g / ORACLE.w_N(T) < 0  # outgoing velocity
        T_far = float(pts[-1].derived["T"])  # the low-frequency end: the energy bound
        assert pts[-1].derived["energy"] == pytest.approx(30.0, rel=1e-6)
        assert pts[-1].derived["energy"] > 5 * pts[0].derived["energy"]
        # w_N > 0 there (v = g / w_N < 0) and -> -inf at the next pole l T_j above T_far
        poles = [l * 2 * np.pi / w for w in ORACLE.w for l in range(1, 10)]
        pole = min(q for q in poles if q > T_far)
        root = brentq(ORACLE.w_N, T_far, pole * (1 - 1e-9), xtol=1e-15)
        roots.append(2 * np.pi / root)
        assert 0 < 2 * np.pi / T_far - 2 * np.pi / root < 0.25
    assert roots == pytest.approx([4.84935058, 6.76884567], abs=1e-7)


def test_fig7_2_grazing_against_an_event_driven_simulation(fig72) -> None:
    """Just inside the boundary the simulated flight returns to the wall after exactly ``T``;
    just beyond it the mass touches the wall early (the extra contact near t = T / 2)."""
    res, _ = fig72
    pr = res.problem
    g = -1.0
    for br in res.run_result.branches:
        T_g = float(next(ev for ev in br.events if ev.kind == "grazing").point.derived["T"])
        for factor, early in ((1.002, False), (0.998, True)):  # larger T: lower omega
            T = T_g * factor
            u0, du0 = ORACLE.state(T, g)
            _, _, t_hit = simulate_first_return(pr, u0, du0, 2 * T)
            if early:
                assert 0.3 * T < t_hit < 0.7 * T
            else:
                assert abs(t_hit - T) < 1e-8 * T


def test_fig7_2_figures_are_written(fig72) -> None:
    _, out = fig72
    for name in ("manifold.png", "orbits_time.png", "fep.png"):
        assert (out / name).stat().st_size > 10_000


def test_a_pole_grazing_for_g_negative_bounds_no_admissible_part() -> None:
    """Prop. 7.1.2: at a pole (the linear grazing orbit, v = 0) the g < 0 orbit lies above the
    wall (``max u_N = -g``, sampled); the outgoing-velocity zero there is no boundary of an
    admissible part, the nonlinear grazing (every other test satisfied) is."""
    pr = nsm.problem("ndof_impact", {"chain": {"dofs": 5, "mass": 0.2, "stiffness": 5.0},
                                     "gap": -1.0})
    T3 = 2 * np.pi / ORACLE.w[2]
    for T in (T3 * (1 - 1e-4), T3 * (1 + 1e-4)):
        u0, du0 = pr.closed_form(T)
        tests = pr.admissibility(pr.y_from_state(u0, du0, T))
        assert tests["clearance"] == pytest.approx(-2.0, abs=1e-2)
        assert ORACLE.max_u_N(T, -1.0) == pytest.approx(1.0, abs=1e-2)

    def event(tests: dict[str, float], vanishing: str) -> Event:
        p = Point(y=np.zeros(7), s=0.0, tangent=np.zeros(7), tests=tests, multipliers=None,
                  trivial_error=0.0, n_unstable=0, derived={}, bordered_det=1.0)
        return Event("grazing", p, "", data={"test": vanishing, "tests": [vanishing]})

    assert not bounds_admissible_part(event({"outgoing_velocity": 0.0, "clearance": -2.0},
                                            "outgoing_velocity"))
    assert bounds_admissible_part(event({"outgoing_velocity": 2.3, "clearance": -3e-13},
                                        "clearance"))


# ------------------------------------------------------------------ Fig. 7.4 (g = 0)
@pytest.fixture(scope="module")
def fig74(tmp_path_factory: pytest.TempPathFactory) -> tuple[nsm.Result, Path]:
    return run_and_save(FIG74, tmp_path_factory)


def test_fig7_4_switched_branches_are_the_one_frequency_families(fig74) -> None:
    """Branches 1, 2 (switched at the trivial branch's branch points) keep ``T`` at a root of
    ``w_N`` (brentq on (3.1)), their points are ``v (w(T*), e_N)`` (7.5)-(7.6), and a point is
    admissible iff ``v < 0``, which is also where the sampled orbit stays behind the wall."""
    res, _ = fig74
    branches = res.run_result.branches
    assert [p.tests for p in branches[0].points] == [{}] * len(branches[0].points)
    omegas = []
    for br in branches[1:]:
        T = np.array([p.derived["T"] for p in br.points])
        root = brentq(ORACLE.w_N, T[0] * (1 - 1e-3), T[0] * (1 + 1e-3), xtol=1e-15)
        assert np.max(np.abs(T - root)) < 1e-10
        omegas.append(2 * np.pi / root)
        wT = ORACLE.state(root, 1.0)[0] * ORACLE.w_N(root)  # w(T*)
        for p in br.points:
            v = float(p.y[5])
            assert np.max(np.abs(p.y[:5] - v * wT)) < 1e-9 * max(abs(v), 1.0)
            if abs(v) < 1e-6:
                continue
            assert p.admissible == (v < 0)
            t = np.linspace(0.0, root, 3001)[1:-1]
            u = v * ORACLE.u_N(t, root, 1.0) * ORACLE.w_N(root)  # (7.3) with g / w_N -> v
            assert (u.max() < 0) == (v < 0)
        assert sum(p.admissible for p in br.points) >= 15
    assert omegas == pytest.approx([6.76884567, 4.84935058], abs=1e-7)


def test_fig7_4_vertical_branches_have_no_fold(fig74) -> None:
    """Along a branch of constant T the tangent's T component is rounding noise whose sign
    flips at random: no fold may be reported there (it was, 34 times, without a noise level:
    the component is below its accuracy, :mod:`nsm_continuation.core.palc.folds`); the only
    event inside is the crossing with the trivial branch (a branch point, at zero energy)."""
    res, _ = fig74
    for br in res.run_result.branches[1:]:
        kinds = [e.kind for e in br.events if e.kind not in ("endpoint", "grazing")]
        assert kinds == ["branch_point"]
        (bp,) = [e for e in br.events if e.kind == "branch_point"]
        assert bp.point.derived["energy"] < 1e-20


def test_fig7_4_manifold_is_coloured_by_energy_at_one_frequency(fig74) -> None:
    res, out = fig74
    assert (out / "manifold.png").stat().st_size > 10_000
    br = res.run_result.branches[2]
    pts = [p for p in br.points if p.admissible]
    items, _ = traces(res.run_result, [Chosen(br, p, "", p.derived["omega"]) for p in pts], 1)
    quantity, value = colour_quantity(res.run_result, items, "omega")
    assert quantity == "energy" and value == pytest.approx(4.84935058, abs=1e-7)
    # scaled copies: every orbit is v / v_ref times the reference one
    ref = items[-1][1].signals["u5"] / float(items[-1][0].point.y[5])
    for ch, tr in items:
        assert np.allclose(tr.signals["u5"], float(ch.point.y[5]) * ref, atol=1e-9)


def test_no_linear_flat_part_is_drawn_for_g_negative() -> None:
    """Sec. 7.1 / Prop. 7.1: for g < 0 the contact-free linear orbits (around u = 0, beyond the
    wall u_N <= g < 0) do not exist: the FEP draws no flat linear segment (g > 0 does)."""
    import matplotlib.pyplot as plt

    chain = {"dofs": 5, "mass": 0.2, "stiffness": 5.0}
    for g, flat in ((-1.0, 0), (1.0, 5)):
        pr = nsm.problem("ndof_impact", {"chain": chain, "gap": g})
        fig, ax = plt.subplots()
        pr.presentation.plot_decorations(ax, (1.0, 11.0), [])
        thick = [ln for ln in ax.get_lines() if ln.get_linewidth() == 3.2]
        labels = [ln.get_label() for ln in ax.get_lines()]
        plt.close(fig)
        assert len(thick) == flat
        # the legend entry exists exactly where the flat parts are drawn
        assert any(lab.startswith("linear (flat) part") for lab in labels) == (g > 0)
