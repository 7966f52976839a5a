"""The exact flow's step certificates as the simulator uses them, and the spectral norm of the
multipliers' tolerances.

A step of an exact flow that :meth:`nsm_continuation.hybrid.linear_flow.ExactStep.max_step`
certifies (:func:`nsm_continuation.hybrid.modal_sums.certified_length`) is not searched for
events by the simulator, and the one cell the certificate could not clear is taken next
without a new certificate. Oracle: the watched functions on the true flow, sampled densely over
every certified step (the state by the exact step, the functions by the compiled CasADi probe,
not by the modal sums the certificate is computed from), never change sign; and the whole
simulation gives the events of the Runge-Kutta path. The spectral norm
(:func:`nsm_continuation.core.floquet.norms.spectral_norm`) is checked against the singular
value decomposition.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nsm_continuation.core.floquet.norms import spectral_norm
from nsm_continuation.hybrid import simulate as sm
from nsm_continuation.hybrid.simulate import SimOptions, Simulator
from nsm_continuation.hybrid.system import HybridSystem


def chain(n: int) -> HybridSystem:
    """``n`` unit masses and springs, damping 0.05, the first forced by ``cos(phase)``, the
    last at a wall at ``q_n = gap``."""
    q, qd, ph = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("phase")
    p = {"omega": ca.SX.sym("omega"), "gap": ca.SX.sym("gap")}
    f = []
    for i in range(n):
        left = q[i] - (q[i - 1] if i > 0 else 0)
        right = q[i + 1] - q[i] if i < n - 1 else 0
        f.append(-left + right - 0.05 * qd[i] + (ca.cos(ph) if i == 0 else 0))
    return HybridSystem.mechanical(f"chain{n}", q, qd, p, ca.SX.eye(n), ca.vertcat(*f),
                                   p["gap"] - q[n - 1], 0.8, clock=ph, clock_rate=p["omega"])


def record_steps(monkeypatch: pytest.MonkeyPatch) -> list[tuple]:
    """Every step the simulator searches (or skips as certified): ``(key, Y, dt, watch,
    certified)``."""
    steps: list[tuple] = []
    plain = sm.Simulator._first_crossing

    def spy(self, w, dt, outs, section, t_min_section):
        steps.append((w.key, w.Y.copy(), float(dt), list(w.watch), w.certified))
        return plain(self, w, dt, outs, section, t_min_section)

    monkeypatch.setattr(sm.Simulator, "_first_crossing", spy)
    return steps


@pytest.mark.parametrize(("n", "omega", "gap"), [(4, 0.35, 0.0), (4, 0.62, 0.25),
                                                 (6, 0.30, 0.15)])
def test_certified_steps_hold_no_zero_and_events_equal_runge_kutta(
        monkeypatch: pytest.MonkeyPatch, n: int, omega: float, gap: float) -> None:
    sys_ = chain(n)
    X0 = np.zeros(2 * n + 2)
    X0[:n], X0[-1] = gap - 0.2, omega                       # at rest, clear of the wall
    t_end = 12 * 2 * np.pi / omega                          # transients: impacts, approaches
    steps = record_steps(monkeypatch)
    ex = sys_.compile({"gap": gap}, free=["omega"], method="exact")
    sim = Simulator(ex, SimOptions(sensitivities=False))
    res = sim.run(X0, t_end=t_end)
    certified = [s for s in steps if s[4]]
    assert len(certified) >= 10 and res.n_impacts >= 3
    worst = np.inf
    for key, Y, dt, watch, _ in certified:
        t = np.linspace(0.0, dt, 121)[1:]
        probes = np.array([sim._step_probe(key, Y, tk) for tk in t])
        for idx, *_ in watch:
            g = probes[:, idx]
            assert np.all(g > 0) or np.all(g < 0), (key, dt, idx)
            worst = min(worst, float(np.min(np.abs(g))))
    assert worst > 0
    rk = Simulator(sys_.compile({"gap": gap}, free=["omega"], method="dop853"),
                   SimOptions(sensitivities=False, rtol=1e-12, atol=1e-14))
    ref = rk.run(X0, t_end=t_end)
    assert [e.kind for e in res.events] == [e.kind for e in ref.events]
    for a, b in zip(res.events, ref.events, strict=True):
        if a.kind == "near_approach":
            # a minimum of H: its time is ill-conditioned (sqrt of the error), its value not
            assert a.info["H"] == pytest.approx(b.info["H"], rel=0, abs=1e-9)
        else:
            assert a.t == pytest.approx(b.t, rel=0, abs=1e-9)
    assert np.max(np.abs(res.X - ref.X)) <= 1e-9


def test_spectral_norm_equals_the_largest_singular_value() -> None:
    rng = np.random.default_rng(7)
    U, _ = np.linalg.qr(rng.standard_normal((60, 60)))
    V, _ = np.linalg.qr(rng.standard_normal((60, 60)))
    cases = [rng.standard_normal((81, 81)),
             rng.standard_normal((40, 40)) + 1j * rng.standard_normal((40, 40)),
             rng.standard_normal((5, 80)), rng.standard_normal((80, 5)),
             U @ np.diag(np.logspace(3, -12, 60)) @ V.T,               # ill-conditioned
             np.outer(rng.standard_normal(30), rng.standard_normal(30)),  # rank one
             np.array([[-3.5]]), 1e-200 * rng.standard_normal((10, 10)),
             1e200 * rng.standard_normal((10, 10))]
    for A in cases:
        ref = np.linalg.norm(A, 2)
        assert spectral_norm(A) == pytest.approx(ref, rel=1e-13, abs=0)
    assert spectral_norm(np.zeros((6, 6))) == 0.0
    assert np.isnan(spectral_norm(np.array([[1.0, np.nan], [0.0, 1.0]])))
