"""Instability windows hidden inside one continuation step of a conservative family, found
from the Krein words of the step's ends (``nsm_continuation/core/floquet/krein.py``) and
located on the colliding pair's discriminant (``CrossingLocator.krein_windows``).

Oracles: the linear normal form of a Krein collision (``tests/oracles/krein_normal_form.py``),
whose window ``(w1^2 - w2^2)^2 < 4 w1 w2 eps^2`` and multipliers are closed forms; for the
paper's 5-dof chain, the events of the same branch computed with the default step control
(which keeps every window at least one step wide) and the number of multipliers outside the
circle from the dense eigenvalues of the closed-form orbit (4.2) inside each window found.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from oracles.krein_normal_form import (
    J4,
    KreinNormalForm,
    KreinParameters,
    hessian,
    window_edges,
)
from oracles.scaled_chain import closed_form_y

import nsm_continuation as nsm
from nsm_continuation import cli
from nsm_continuation.core import palc
from nsm_continuation.core.floquet.krein import SEVERAL, discriminant, signature_word, swap_paths

#: steps free to jump over a window: no closing rule, no motion limit
LOOSE = {"max_multiplier_step": 10.0}


@pytest.fixture()
def loose_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(palc.step_control, "krein_closing", lambda *a, **k: False)


def normal_form_map(w2: float, eps: float) -> tuple[np.ndarray, np.ndarray]:
    pb = KreinNormalForm(KreinParameters(eps=eps))
    fl = pb.floquet(np.array([w2, w2]), np.array([1.0, 1.0]))
    return np.asarray(fl.multipliers), np.asarray(fl.krein)


@pytest.mark.parametrize("eps", [0.05, 0.0])
def test_opposite_signatures_are_transposed_across_a_collision(eps: float) -> None:
    """Across the collision at ``w2 = w1``, a window (``eps > 0``) or a passing
    (``eps = 0``), the two multipliers of opposite signature change places in the word; the
    step's ends name the pair, and its discriminant is ``(theta_1 - theta_2)^2`` there."""
    ma, ka = normal_form_map(0.9, eps)
    mb, kb = normal_form_map(1.1, eps)
    wa, wb = signature_word(ma, ka, 1e-9)[1], signature_word(mb, kb, 1e-9)[1]
    assert sorted(wa) == sorted(wb) == ["+", "-"] and wa == wb[::-1]
    paths = swap_paths(ma, ka, mb, kb, 1e-9)
    assert paths is not None and paths != SEVERAL
    (z1a, z1b), (z2a, z2b) = paths
    for z, m in ((z1a, ma), (z2a, ma), (z1b, mb), (z2b, mb)):
        assert np.min(np.abs(m - z)) == 0.0
    assert discriminant(z1a, z2a) == pytest.approx(
        (np.angle(z1a) - np.angle(z2a)) ** 2, rel=1e-12)
    # the same signature at both ends of each path
    k_of = {complex(z): k for m, kk in ((ma, ka), (mb, kb)) for z, k in zip(m, kk, strict=True)}
    assert np.sign(k_of[z1a]) == np.sign(k_of[z1b]) != np.sign(k_of[z2a]) == np.sign(k_of[z2b])


def test_discriminant_is_minus_four_log_r_squared_off_the_circle() -> None:
    """Inside the window the pair is ``r rho, rho / r``: ``d = -4 (log r)^2`` from the
    eigenvalues of ``J S`` in closed form (``lambda = +-a +- i b``, ``r = exp(a tau)``)."""
    m, _ = normal_form_map(1.0, 0.05)
    up = m[m.imag > 0]
    assert up.size == 2 and abs(abs(up[0]) - 1) > 1e-3
    lam = np.linalg.eigvals(J4 @ hessian(1.0, 1.0, 0.05))
    a = float(np.max(lam.real))
    assert discriminant(up[0], up[1]) == pytest.approx(-4 * a**2, rel=1e-12)


def run_normal_form(eps: float, **analysis: Any) -> Any:
    pb = KreinNormalForm(KreinParameters(eps=eps))
    return nsm.continuation(pb, {}, parameter="w2", min=0.6, max=1.4, max_points=200,
                            step={"initial": 0.01, "min": 1e-9, "max": 0.3},
                            analysis=analysis)


def test_window_hidden_in_a_step_is_located_on_its_closed_form_edges(
        loose_steps: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """With steps free to jump over it, the window ``w2`` in (0.9500164, 1.0499851) lies
    inside one step (the count is 0 at both ends: without the Krein words it is missed);
    found from the words and located on the discriminant to 1e-10 of the closed forms, and
    marked so in report.md (both crossings, each with its stability change)."""
    lo, hi = window_edges(1.0, 0.05)
    res = run_normal_form(0.05, **LOOSE)
    ns = [e for e in res.events if e.kind == "neimark_sacker"]
    assert [e.record["hidden_in_step"] for e in ns] == [True, True]
    assert [e.record["located_on"] for e in ns] == ["krein_discriminant"] * 2
    assert abs(ns[0].point.y[1] - lo) < 1e-10 and abs(ns[1].point.y[1] - hi) < 1e-10
    assert [(e.record["n_outside_before"], e.record["n_outside_after"]) for e in ns] == [
        (0, 2), (2, 0)]
    w2 = res.branches[0]["w2"]
    assert any(a < lo and b > hi for a, b in zip(w2[:-1], w2[1:], strict=False))
    md = (res.save(tmp_path / "nf", plots=False) / "report.md").read_text()
    assert md.count("(a window inside one step: found from the Krein signs of its ends)") == 4
    monkeypatch.setattr(palc.CrossingLocator, "krein_windows", lambda self, a, b: [])
    assert not [e for e in run_normal_form(0.05, **LOOSE).events
                if e.kind == "neimark_sacker"]


def test_a_passing_is_not_an_event(loose_steps: None) -> None:
    """``eps = 0``: the two frequencies pass through each other at ``w2 = 1`` (the word
    changes) and the discriminant only touches 0: no event, one passing counted."""
    res = run_normal_form(0.0, **LOOSE)
    assert [e.kind for e in res.events] == ["endpoint"]
    assert res.run_result.timings["krein_passings"] == 1


def test_chain_windows_hidden_in_steps_are_the_reference_events(loose_steps: None) -> None:
    """The paper's 5-dof chain, branch 1 (the default case) with steps free to jump over
    windows (53 points instead of 325 here): every crossing of the run with the default step
    control, at the same period to 1e-9, some found inside a step; inside each of those the
    dense eigenvalues of the closed-form orbit have the count the events say."""
    over = {"output.progress": False, "output.plots": False}
    ref = nsm.run(nsm.load_case(cli._default_case_path(), over)).run_result
    loose = nsm.run(nsm.load_case(cli._default_case_path(),
                                  {**over, "analysis.max_multiplier_step": 10.0})).run_result
    assert loose.timings["n_points"] < ref.timings["n_points"] / 3

    def crossings(run: Any) -> list[tuple[str, float]]:
        return [(e.kind, float(e.point.y[-1])) for e in run.branches[0].events
                if e.kind in ("neimark_sacker", "period_doubling", "fold")]

    a, b = crossings(ref), crossings(loose)
    assert [k for k, _ in a] == [k for k, _ in b]
    assert np.max(np.abs(np.array([t for _, t in a]) - np.array([t for _, t in b]))) < 1e-9
    hidden = [e for e in loose.branches[0].events
              if e.kind == "neimark_sacker" and e.data.get("hidden_in_step")]
    assert len(hidden) >= 2
    pb = loose.problem
    for e1, e2 in zip(hidden[::2], hidden[1::2], strict=True):
        t_mid = 0.5 * (e1.point.y[-1] + e2.point.y[-1])
        y = closed_form_y(pb, t_mid)
        fl = pb.floquet_dense(y, np.linalg.svd(pb.jacobian(y))[2][-1])
        inside = int(np.sum(np.abs(fl.multipliers) > 1 + 1e-7))
        assert inside == e1.data["n_outside_after"] == e2.data["n_outside_before"] > \
            e1.data["n_outside_before"]
