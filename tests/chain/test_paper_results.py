"""The paper's statements about its own figures, checked on the bundled YAML cases.

Legrand, Junca, Heng (2017): sec. 5 (Fig. 5.1: branches 1-3 are bounded by a nonlinear grazing
orbit, branch 4 is not), Theorem 3.2 (admissible side a_j (T - T_j) < 0 next to every linear
period, phantom on the other side), sec. 6.2 (Fig. 6.2: along branch 1 stability is lost through
all three scenarios: multipliers leaving at +1, at -1 and as a complex pair).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES

from nsm_continuation import cases
from nsm_continuation.runs.runner import run_case


@pytest.fixture(scope="module")
def fig5_1():
    case, problem = cases.load(CASES / "ndof_fig5_1_branches.yaml")
    return run_case(case, problem, progress=False)


@pytest.fixture(scope="module")
def fep():
    case, problem = cases.load(CASES / "ndof_fig3_2_fep.yaml")
    return run_case(case, problem, progress=False)


def test_fig5_1_branches_1_to_3_end_at_nonlinear_grazing_and_4_is_unbounded(fig5_1):
    ends = [br.termination["forward"] for br in fig5_1.branches]
    assert [br.label for br in fig5_1.branches] == ["mode 1, k = 1", "mode 2, k = 1",
                                                    "mode 3, k = 3", "mode 4, k = 2"]
    for reason in ends[:3]:
        assert reason == "grazing: admissibility lost ('clearance')", reason
    assert ends[3].startswith("bound: energy"), ends[3]
    for br in fig5_1.branches:
        # every point before the end is admissible, and the branch leaves its pole on the
        # admissible side a_j (T - k T_j) < 0 (all a_j > 0 for this chain: T decreases)
        assert all(p.admissible for p in br.points[:-1])
        T = np.array([p.y[-1] for p in br.points])
        assert T[0] == pytest.approx(br.info["pole_T"], rel=1e-12)
        assert np.all(np.diff(T) < 0)
        # the nonlinear grazing orbit is a tangency: clearance -> 0 at the last point
    for br in fig5_1.branches[:3]:
        assert abs(br.points[-1].tests["clearance"]) < 1e-9


def test_fig6_2_three_instability_scenarios_along_branch_1(fig5_1):
    kinds = {ev.kind for ev in fig5_1.branches[0].events}
    assert {"fold", "period_doubling", "neimark_sacker", "stability_change"} <= kinds
    # stability changes alternate (stable -> unstable -> stable ...)
    sc = [ev.data for ev in fig5_1.branches[0].events if ev.kind == "stability_change"]
    assert len(sc) >= 4
    for before, after in zip(sc[:-1], sc[1:], strict=True):
        assert before["stable_after"] == after["stable_before"]


def test_theorem_3_2_admissible_side_of_every_linear_period(fep):
    """Next to T_j (k = 1) the orbit is admissible for a_j (T - T_j) < 0 and a phantom for
    a_j (T - T_j) > 0 (all a_j > 0 here); each branch through a pole is one analytic curve."""
    problem = fep.problem
    seen = 0
    for br in fep.branches:
        if br.info.get("subharmonic") != 1:
            continue
        Tj = br.info["pole_T"]
        for p in br.points:
            d = (p.y[-1] - Tj) / Tj
            if 1e-6 < abs(d) < 2e-3:
                assert p.admissible == (problem.a[br.info["mode"] - 1] * d < 0), (Tj, d)
                seen += 1
    assert seen >= 10


def test_fep_admissible_frequencies_bounded(fep):
    """Prop. 5.2: alpha = sum a_j / w_j^2 > 0, so admissible frequencies are bounded: the
    highest admissible orbit of the window (omega <= 11, energy <= 100) lies on the branch that
    leaves omega_N towards higher omega (a_N > 0), just above omega_N; nothing is admissible in
    (omega_N (1 + 1e-5), 11], where the phantom branches continue."""
    problem = fep.problem
    assert np.sum(problem.a / problem.omega**2) > 0
    best = max(((p.derived["omega"], br) for br in fep.branches for p in br.points
                if p.admissible), key=lambda wb: wb[0])
    w_max, br = best
    assert problem.omega[-1] < w_max < problem.omega[-1] * (1 + 1e-5)
    assert br.info.get("mode") == problem.N and br.info.get("subharmonic") == 1
    assert max(p.derived["omega"] for b in fep.branches for p in b.points) > 10.9


def test_fep_each_linear_grazing_is_one_event(fep):
    """At a linear grazing orbit (the outgoing velocity through zero) a maximum of ``u_c``
    enters at ``t = 0+``: the clearance changes sign at the same point (or only touches
    zero), so the grazing is one event, merged (``vanish together``) or the velocity's alone.
    A ``clearance`` zero of its own is a nonlinear grazing: its maximum lies inside the period
    (``max_on``, independent of the clearance's evaluation), far from every linear one.
    The clearance is computed as a rise from the impact (``TrigSum.rise``): computed
    otherwise, four branches of this case would show a second ``clearance`` zero 5e-10 ...
    4e-9 in T away from their linear grazing, located on rounding noise, and ``report.json``
    would list them as nonlinear grazing orbits."""
    problem = fep.problem
    n_linear = 0
    for br in fep.branches:
        graz = [ev for ev in br.events if ev.kind == "grazing"]
        linear = [ev.point.y[-1] for ev in graz if "outgoing_velocity" in ev.data["tests"]]
        n_linear += len(linear)
        for ev in graz:
            if ev.data["tests"] != ["clearance"]:
                continue
            T = ev.point.y[-1]
            assert all(abs(T - Tl) > 1e-6 * Tl for Tl in linear), (br.label, T)
            _, t_max = problem.displacement_sum(ev.point.y).max_on(0.0, T)
            assert 1e-3 < t_max / T < 1 - 1e-3, (br.label, T, t_max / T)
    assert n_linear >= 10
    listed = problem.presentation.report_extras(fep.branches).get("nonlinear_grazing_orbits", [])
    for entry in listed:
        _, t_max = problem.displacement_sum(
            next(ev.point.y for br in fep.branches if br.id == entry["branch"]
                 for ev in br.events if ev.point.derived["T"] == entry["T"])).max_on(
            0.0, entry["T"])
        assert 1e-3 < t_max / entry["T"] < 1 - 1e-3
