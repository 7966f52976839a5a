"""Continuum limit of the WFEM bar (problems/bar/continuum.py) against the lattice orbits.

Yoong, Thorin, Legrand (2017): the lattice orbits of (12) with COND1-COND3
(problems/bar/wfem_lattice) must be exact samples of the continuum branches ``t_f = a T + b``:
same energy, same characteristic profile, same admissible side; the asymptotes are those of
sec. 6.1 and eq. (16).
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CASES
from nsm_continuation.problems.bar.continuum import (
    BarContinuumProblem,
    Signature,
    check_signature,
    continuum_orbit,
    main_signature,
    subharmonic_signature,
)
from nsm_continuation.problems.bar.wfem_lattice import BarModel, classify, solve_node

from nsm_continuation.cases.validation import load
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.settings import ContinuationSettings


def lattice_line(N: int, g0: float, sig: Signature, M_range: range
                 ) -> list[tuple[int, str, object]]:
    """solve_node on the lattice line ``m = a M + b N`` (one contact phase)."""
    md = BarModel(1.0, 1.0, 1.0, N, g0)
    out = []
    for M in M_range:
        m = sig.a * M + sig.b * N
        if 1 <= m < M:
            status, sol = solve_node(md, (m, M - m))
            out.append((M, status, sol))
    return out


def continuum_at(problem: BarContinuumProblem, sig: Signature, N: int, M: int
                 ) -> tuple[dict[str, float], dict[str, float], np.ndarray]:
    """Derived values, margins and the physical profile at the ring slot centres."""
    y = problem.point(sig, 4 * N / M)
    d = problem.derived(y)
    xi = (np.arange(2 * N) + 0.5) / N
    profile = problem.continuum_orbit(y).profile(xi)
    return d, problem.admissibility(y), d["stress_amplitude"] * profile


@pytest.mark.parametrize("N", [20, 50, 101])
@pytest.mark.parametrize("g0", [1e-3, -1e-3])
def test_main_backbone_equals_lattice(N: int, g0: float) -> None:
    """Every admissible lattice node on m = 2M - 4N is the continuum orbit (energy and profile
    to round-off), and the continuum margins have the lattice's admissible side."""
    pr = BarContinuumProblem({"gap": g0})
    sig = main_signature(1)
    n_adm = n_inadm = 0
    for M, status, sol in lattice_line(N, g0, sig, range(2 * N + 1, 4 * N)):
        if sol is None:
            continue
        d, margins, w = continuum_at(pr, sig, N, M)
        assert d["energy"] == pytest.approx(sol.energy, rel=1e-11)
        assert np.max(np.abs(w - sol.w0)) <= 1e-11 * np.max(np.abs(sol.w0))
        if status == "admissible":
            n_adm += 1
            assert min(margins.values()) > 0, (M, margins)
            # the admissible side of the asymptote T* = 3: T > 3 iff g0 > 0
            assert (M > 3 * N) == (g0 > 0)
        else:
            n_inadm += 1
            assert margins["cond1_gap"] < 0 and margins["cond2_contact"] < 0
    assert n_adm >= N // 3 and n_inadm >= N // 3


def test_reference_node() -> None:
    """N = 20, g0 = 1e-3, node (78, 1): T = 79/20, E/E_ref = 8/(pi^2 (T - 3)^2) = 0.89814."""
    status, sol = solve_node(BarModel(1.0, 1.0, 1.0, 20, 1e-3), (78, 1))
    assert status == "admissible"
    d, _, _ = continuum_at(BarContinuumProblem({"gap": 1e-3}), main_signature(1), 20, 79)
    T = 79 / 20
    assert d["energy_ratio"] == pytest.approx(8 / (np.pi**2 * (T - 3) ** 2), rel=1e-13)
    assert d["energy_ratio"] == pytest.approx(sol.derived()["energy_ratio"], rel=1e-12)
    assert round(d["energy_ratio"], 5) == 0.89814


def test_mode2_signature_from_lattice_scan() -> None:
    """Scan of [omega_2, Omega_2] (N < M < 4N/3) at N = 40: the physical admissible orbits with
    the fewest profile jumps (4) lie on m = 4M - 4N, for both signs of g0; the continuum energy
    of signature (4, -4) equals theirs."""
    N = 40
    for g0 in (1e-3, -1e-3):
        md = BarModel(1.0, 1.0, 1.0, N, g0)
        pr = BarContinuumProblem({"gap": g0})
        found = []
        for M in range(N + 1, 4 * N // 3 + 1):
            for p in range(1, M):
                status, sol = solve_node(md, (M - p, p))
                if status == "admissible" and classify(sol) == "physical":
                    found.append(sol)
        fewest = min(s.derived()["profile_jumps"] for s in found)
        low = [s for s in found if s.derived()["profile_jumps"] == fewest]
        assert fewest == 4 and len(low) >= 2
        for s in low:
            m, p = s.counts
            assert m == 4 * s.M - 4 * N
            d, margins, _ = continuum_at(pr, main_signature(2), N, s.M)
            assert d["energy"] == pytest.approx(s.energy, rel=1e-11)
            assert min(margins.values()) > 0


@pytest.mark.parametrize("sig", [subharmonic_signature(1, 1), subharmonic_signature(1, 2),
                                 subharmonic_signature(2, 1), main_signature(3)])
def test_other_branches_equal_lattice(sig: Signature) -> None:
    """Subharmonic (sec. 6.2) and mode-3 lattice orbits are continuum samples too."""
    N = 40
    n = 0
    for g0 in (1e-3, -1e-3):
        pr = BarContinuumProblem({"gap": g0})
        M_lo = int(np.floor(N * sig.T_free_end)) + 1
        M_hi = int(np.ceil(N * sig.T_contact_end))
        for M, status, sol in lattice_line(N, g0, sig, range(M_lo, M_hi)):
            if status != "admissible":
                continue
            n += 1
            d, margins, w = continuum_at(pr, sig, N, M)
            assert d["energy"] == pytest.approx(sol.energy, rel=1e-11)
            assert np.max(np.abs(w - sol.w0)) <= 1e-11 * np.max(np.abs(sol.w0))
            assert min(margins.values()) >= 0
    assert n >= 2


def test_closed_forms_and_periodicity() -> None:
    """Profiles are fixed points of the period map; mu is affine in T (closed form); the gap
    closes at t_f; n grazing instants on the n-th subharmonic."""
    for sig in (main_signature(1), main_signature(2), main_signature(3),
                subharmonic_signature(1, 1), subharmonic_signature(1, 3),
                subharmonic_signature(2, 1)):
        n = -sig.b // 4 - 1
        pr = BarContinuumProblem({"gap": 1e-3})
        for T in np.linspace(sig.T_free_end, sig.T_contact_end, 11)[1:-1]:
            orb = continuum_orbit(sig, T)
            assert orb.periodicity_defect() == 0.0
            assert orb.mu == pytest.approx(sig.mu(T), abs=1e-12)
            assert abs(orb.closure) < 1e-12
            assert len(orb.jumps) == sig.a
            y = pr.point(sig, 4 / T)
            assert pr.derived(y)["grazing_instants"] == n
        # a profile with b = 2 mod 4 closes with the wrong sign: anti-periodic
        odd = Signature(sig.a, sig.b + 2)
        bad = continuum_orbit(odd, 0.5 * (odd.T_free_end + odd.T_contact_end))
        assert bad.periodicity_defect() == 1.0


def test_asymptotes() -> None:
    """Main backbones: (w_k + 1)^2/(w_k + 2) omega_1 (sec. 6.1): 4/3, 16/5, 36/7; subharmonics:
    eq. (16); mu vanishes there (infinite energy) and the branch ends (t_c = 0) at eq. (15)."""
    for k in (1, 2, 3):
        wk = 2 * k - 1
        assert main_signature(k).omega_ratio_asymptote == pytest.approx((wk + 1) ** 2 / (wk + 2))
        for n in (1, 2, 3):
            s = subharmonic_signature(k, n)
            assert s.omega_ratio_asymptote == pytest.approx(
                (n + 1) * (wk + 1) ** 2 / (wk * (n + 1) + n + 2))
            assert 4 / s.T_contact_end == pytest.approx((2 * k * (n + 1) - 1) / (n + 1))
    assert main_signature(1).omega_ratio_asymptote == pytest.approx(4 / 3, rel=1e-15)
    assert main_signature(2).omega_ratio_asymptote == pytest.approx(16 / 5, rel=1e-15)
    for sig in (main_signature(1), main_signature(2)):
        pr = BarContinuumProblem({"gap": 1e-3})
        Ts = sig.T_asymptote
        assert abs(continuum_orbit(sig, Ts).mu) < 1e-12
        e = [pr.derived(pr.point(sig, 4 / (Ts * (1 + h))))["energy_ratio"] for h in (1e-2, 1e-3)]
        assert e[1] / e[0] == pytest.approx(100, rel=1e-6)  # double pole
    # g0 = 0 at T = 3: free phase 2L/c, contact L/c; mode 2: period 5/4, contact 1/4 (sec. 6.1)
    assert main_signature(1).t_free(3.0) == 2.0
    assert main_signature(2).t_free(1.25) == 1.0


def test_engine_stops_where_the_strain_limit_is_reached_before_the_asymptote() -> None:
    """Without an energy bound the branch ends just before the asymptote, where the strain
    margin ``cond3 = mu^2/4 - |g0||mu|/(2L)`` vanishes: ``|mu| = 2|g0|/L``, with ``mu(T)``
    affine (closed form ``Signature.mu``). The inadmissible interval is short, ``4.4e-4`` wide
    in omega/omega_1 for mode 1: the step cap on the test functions keeps a step from jumping
    over it to the asymptote."""
    for k, g0 in ((1, 1e-3), (2, -1e-3)):
        pr = BarContinuumProblem({"gap": g0})
        sig = main_signature(k)
        st = ContinuationSettings(step_initial=0.01, step_max=0.05, max_points=400,
                                  stop_on_inadmissible=True, detect_bifurcations=False)
        (start,) = pr.start_points({"branch": "main", "mode": k,
                                    "direction": "increase" if g0 > 0 else "decrease"})
        br = ContinuationEngine(pr, st).run(start)
        end = br.points[-1]
        assert "cond3_strain" in br.termination["forward"]
        a, b = sig
        T_star, slope = sig.T_asymptote, -2.0 * a**2 / b
        T_start = 4.0 / start.y[0]
        T_end = T_star + np.sign(T_start - T_star) * 2 * abs(g0) / pr.L / abs(slope)
        assert abs(sig.mu(T_end)) == pytest.approx(2 * abs(g0) / pr.L, rel=1e-12)
        assert end.y[0] == pytest.approx(4.0 / T_end, abs=1e-9)
        assert 0 < abs(end.y[0] - sig.omega_ratio_asymptote) < 1e-3


def test_admissibility_sign_flips_with_gap() -> None:
    """T > T* needs g0 > 0 (hardening from omega_k), T < T* needs g0 < 0 (softening)."""
    for sig in (main_signature(1), main_signature(2), subharmonic_signature(1, 1)):
        Ts = sig.T_asymptote
        for T, side in ((0.5 * (Ts + sig.T_contact_end), 1), (0.5 * (Ts + sig.T_free_end), -1)):
            for g0 in (1e-3, -1e-3):
                pr = BarContinuumProblem({"gap": g0})
                m = pr.admissibility(pr.point(sig, 4 / T))
                if np.sign(g0) == side:
                    assert min(m.values()) > 0
                else:
                    assert m["cond1_gap"] < 0 and m["cond2_contact"] < 0
                    assert m["free_phase"] > 0 and m["contact_phase"] > 0


def test_residual_jacobian_matches_finite_differences() -> None:
    pr = BarContinuumProblem({"gap": 1e-3})
    rng = np.random.default_rng(1)
    for _ in range(5):
        y = np.array([rng.uniform(1, 4), rng.uniform(0, 1), 2 * rng.integers(1, 5),
                      -4 * rng.integers(1, 4)]) + rng.normal(0, 1e-3, 4)
        J = pr.jacobian(y)
        h = 1e-6
        fd = np.column_stack([(pr.evaluate(y + h * e) - pr.evaluate(y - h * e)) / (2 * h)
                              for e in np.eye(4)])
        assert np.allclose(J, fd, atol=1e-8)
    # on a branch: G = 0 exactly, rank 3, tangent along (1, -b/4, 0, 0)
    y = pr.point(main_signature(2), 3.1)
    assert np.max(np.abs(pr.evaluate(y))) < 1e-14
    _, sv, vt = np.linalg.svd(pr.jacobian(y))
    assert sv[-1] > 0.5  # rank 3: the three equations are independent
    t = vt[-1] / vt[-1][0]
    assert np.allclose(t, [1, 1, 0, 0], atol=1e-12)


def test_invalid_inputs() -> None:
    with pytest.raises(ValueError):
        BarContinuumProblem({"gap": 0.0})
    for bad in ((3, -4), (2, -2), (0, 4), (2, 0), (4, 4)):
        with pytest.raises(ValueError):
            check_signature(Signature(*bad))
    # t_f = 4 - 2T (omega in (2, 3) omega_1, between Omega_1 and omega_2) is a family of periodic
    # profiles, never admissible (sec. 6.2: no branch in [Omega_k, omega_(k+1)])
    check_signature(Signature(-2, 4))
    for g0 in (1e-3, -1e-3):
        pr = BarContinuumProblem({"gap": g0})
        assert pr.admissible_intervals(Signature(-2, 4)) == []
        with pytest.raises(ValueError, match="no admissible orbit"):
            pr.start_points({"signature": [-2, 4]})


def test_admissibility_agrees_with_lattice_for_all_signatures() -> None:
    """On every lattice node (N = 40, h = 1) of every line m = a M + b N with a small signature,
    the continuum orbit has the lattice energy and the lattice's admissibility (COND1-COND3)."""
    N = 40
    agree = {True: 0, False: 0}
    admissible_sigs = set()
    for a in (-4, -2, 2, 4, 6, 8):
        for b in range(-24, 9, 4):
            sig = Signature(a, b)
            try:
                check_signature(sig)
            except ValueError:
                continue
            lo, hi = sig.T_range
            for g0 in (1e-3, -1e-3):
                pr = BarContinuumProblem({"gap": g0})
                for M, status, sol in lattice_line(N, g0, sig, range(int(N * lo), int(N * hi) + 2)):
                    if sol is None:
                        continue
                    y = pr.point(sig, 4 * N / M)
                    assert pr.continuum_orbit(y).periodicity_defect() == 0.0
                    assert pr.derived(y)["energy"] == pytest.approx(sol.energy, rel=1e-10)
                    cont = min(pr.admissibility(y).values()) > -1e-12
                    assert cont == (status == "admissible"), (sig, g0, M, status)
                    agree[cont] += 1
                    if cont:
                        admissible_sigs.add((a, b, g0 > 0))
    assert agree[True] >= 40 and agree[False] >= 400
    # beyond the backbones: t_f = 6T - 16 (g0 > 0, omega in (5/4, 4/3)) and t_f = 8T - 24
    # (g0 > 0, omega in (7/6, 6/5): leaves the main backbone at 6/5 omega_1, eq. 17 with k = 3)
    assert {(6, -16, True), (8, -24, True)} <= admissible_sigs


def test_internal_resonance_branch_leaves_main_backbone() -> None:
    """t_f = 8T - 24 crosses t_f = 2T - 4 at T = 10/3 (omega = 6/5 omega_1, eq. 17): there both
    signatures give the same orbit; (8, -24) is admissible for g0 > 0 on (7/6, 6/5)."""
    T = 10 / 3
    a, b = continuum_orbit(Signature(8, -24), T), continuum_orbit(main_signature(1), T)
    assert np.array_equal(a.jumps, b.jumps) and a.mu == pytest.approx(b.mu)
    pr = BarContinuumProblem({"gap": 1e-3})
    ((lo, hi),) = pr.admissible_intervals(Signature(8, -24), samples=4001)
    assert lo == pytest.approx(7 / 6, abs=1e-3) and hi == pytest.approx(6 / 5, abs=1e-3)
    assert pr.derived(pr.point(Signature(8, -24), 1.19))["grazing_instants"] == 2


@pytest.mark.parametrize("case", ["bar_continuum_main.yaml",
                                  "bar_continuum_main_negative_gap.yaml",
                                  "bar_continuum_subharmonics.yaml"])
def test_cases_run(case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The YAML cases validate and run; each branch ends at its phase end (grazing event) and at
    the energy bound just before its asymptote; energies follow the closed form."""
    from nsm_continuation.runs.runner import run_case

    c, pr = load(CASES / case)
    res = run_case(c, pr, progress=False)
    for br in res.branches:
        sig = Signature(*br.info["signature"])
        lo, hi = br.info["admissible_omega_ratio"]
        r = np.array([p.y[0] for p in br.points])
        e = np.array([p.derived["energy_ratio"] for p in br.points])
        assert np.allclose(e, 32 / (np.pi**2 * sig.mu(4 / r) ** 2), rtol=1e-12)
        assert r.min() >= lo - 1e-9 and r.max() <= hi + 1e-9
        if "energy_ratio" in res.settings.derived_bounds:  # max_energy bounds fep_axes[1]
            assert e.max() == pytest.approx(c.continuation.max_energy, rel=1e-6)
        assert any(ev.kind == "grazing" for ev in br.events)
        assert all(p.admissible for p in br.points[1:-1])
