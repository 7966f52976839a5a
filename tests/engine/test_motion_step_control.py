"""The multiplier-motion step control as a ratio (the Krein-aware step control).

A step is refused when its motion ratio exceeds 1 (:meth:`StepController._multiplier_motion`);
the ratio also caps the next step
(:func:`nsm_continuation.core.palc.step_control._motion_capped_step`), since displacements grow
linearly with a short step. Oracles:

* closed forms of the closing rule (:func:`nsm_continuation.core.palc.motion.krein_closing`) on
  sets of multipliers built by hand: chords between points of the unit circle, displacements of a
  quadruple off it;
* the engine with the step control of plain halving (no ratio): the same
  events on the bundled default case, located to their tolerance, in fewer step attempts.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from nsm_continuation import api
from nsm_continuation.core import palc
from nsm_continuation.core.floquet import collision_distances
from nsm_continuation.core.palc import KREIN_CLOSING, KREIN_NEAR, OUTSIDE_TRAVEL, krein_closing

TOL = 1e-9
MATCH = 0.02


def _on_circle(theta_plus: float, theta_minus: float) -> tuple[np.ndarray, np.ndarray]:
    """``e^{i theta_plus}`` of signature +1, ``e^{i theta_minus}`` of signature -1, and their
    conjugates (which carry the other signature)."""
    z = np.exp(1j * np.array([theta_plus, theta_minus]))
    return np.concatenate([z, np.conj(z)]), np.array([1.0, -1.0, -1.0, 1.0])


def _closing(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> float:
    return krein_closing(a[0], a[1], b[0], b[1], TOL, MATCH)


def test_the_closing_ratio_is_the_fraction_of_the_collision_distance_closed() -> None:
    """Two multipliers of opposite signature approach on the circle: their chord
    ``2 sin(gap / 2)`` is the smallest collision distance. Below ``KREIN_NEAR`` the ratio is
    the fraction of it the step closed over ``1 - KREIN_CLOSING``; it exceeds 1 exactly
    when the distance fell below ``KREIN_CLOSING`` times its value."""
    chord = [2.0 * np.sin(0.5 * g) for g in (0.08, 0.03, 0.05)]
    a, b, c = _on_circle(1.0, 1.08), _on_circle(1.0, 1.03), _on_circle(1.0, 1.05)
    assert collision_distances(a[0], a[1], TOL).min() == pytest.approx(chord[0], rel=1e-12)
    ratio = _closing(a, b)
    assert ratio == pytest.approx((1.0 - chord[1] / chord[0]) / (1.0 - KREIN_CLOSING),
                                  rel=1e-10)
    assert ratio > 1.0 and chord[1] < KREIN_CLOSING * chord[0]
    assert 0.0 < _closing(a, c) < 1.0 and chord[2] > KREIN_CLOSING * chord[0]
    # moving apart closes nothing; far from any collision the rule does not apply
    assert _closing(b, a) == 0.0
    far_a, far_b = _on_circle(1.0, 1.5), _on_circle(1.0, 1.3)
    assert collision_distances(far_b[0], far_b[1], TOL).min() > KREIN_NEAR
    assert _closing(far_a, far_b) == 0.0


def _quadruple(r: float, theta: float) -> np.ndarray:
    z = r * np.exp(1j * theta)
    return np.array([z, np.conj(z), 1.0 / z, 1.0 / np.conj(z)])


@pytest.mark.parametrize(("r", "shift"), [(1.3, 0.01), (1.3, 0.1), (1.3, 0.14), (1.3, 0.16),
                                        (1.3, 0.3), (1.025, 0.005), (1.025, 0.019),
                                        (1.025, 0.021), (1.025, 0.05)])
def test_multipliers_outside_move_at_most_their_allowance(r: float, shift: float) -> None:
    """A quadruple off the circle (the same count at both ends) moved radially outwards by
    ``shift``: the ratio is ``shift`` over the allowance ``max(match, OUTSIDE_TRAVEL
    (r - 1))`` (r the nearer end's modulus), ``shift / 0.15`` at ``r = 1.3``, ``shift /
    match`` at ``r = 1.025``, and the step is refused beyond 1 (the count could not tell
    that window from a new one)."""
    a, b = _quadruple(r, 0.7), _quadruple(r + shift, 0.7)
    krein = np.zeros(4)  # off the circle: no signature
    allowance = max(MATCH, OUTSIDE_TRAVEL * (r - 1.0))
    ratio = krein_closing(a, krein, b, krein, TOL, MATCH)
    assert ratio == pytest.approx(shift / allowance, rel=1e-9)
    assert (ratio > 1.0) == (shift > allowance)


def test_an_allowed_outside_motion_never_reaches_the_circle() -> None:
    """The geometric fact the allowance rests on: a straight path between two multipliers
    outside the circle that :func:`krein_closing` matches (within their allowance) stays
    outside the circle, sampled densely, over random pairs; and a multiplier that went back
    to the circle and out again (the window the count cannot see) is never matched."""
    rng = np.random.default_rng(7)
    for _ in range(2000):
        x = (1.0 + rng.uniform(1e-3, 1.0)) * np.exp(1j * rng.uniform(-np.pi, np.pi))
        y = x + rng.uniform(0.0, 1.0) * np.exp(1j * rng.uniform(-np.pi, np.pi))
        if abs(y) <= 1.0 + 1e-3:
            continue
        allowance = max(MATCH, OUTSIDE_TRAVEL * (min(abs(x), abs(y)) - 1.0))
        if abs(x - y) > allowance:
            continue
        path = x + np.linspace(0.0, 1.0, 401) * (y - x)
        # within ``match`` of the circle only the absolute rule holds: nothing to check
        if min(abs(x), abs(y)) - 1.0 > 2 * MATCH:
            assert np.abs(path).min() > 1.0
    # out and back in one step: the multiplier at 1.2 e^{0.3i} reached the circle at 0.3i
    # and left again at 1.15 e^{0.45i}; its motion 0.16 > 0.5 (1.15 - 1)
    a, b = _quadruple(1.2, 0.3), _quadruple(1.15, 0.45)
    assert krein_closing(a, np.zeros(4), b, np.zeros(4), TOL, MATCH) > 1.0


def test_several_crossings_in_one_step_halve_it() -> None:
    """Two quadruples leave the circle in one step (two Neimark-Sacker crossings; the count
    goes from 0 to 4): ratio 2. One quadruple alone is the step's own crossing, located by
    the count: not refused."""
    theta = np.array([0.7, 0.71, 1.5, 1.51])
    a = np.exp(1j * np.concatenate([theta, -theta]))
    ka = np.array([1.0, -1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0])
    two = np.concatenate([_quadruple(1.2, 0.705), _quadruple(1.2, 1.505)])
    assert krein_closing(a, ka, two, np.zeros(8), TOL, MATCH) == 2.0
    one = np.concatenate([_quadruple(1.2, 0.705), np.exp(1j * np.array([1.5, 1.51, -1.5,
                                                                         -1.51]))])
    k_one = np.array([0.0, 0.0, 0.0, 0.0, 1.0, -1.0, -1.0, 1.0])
    assert krein_closing(a, ka, one, k_one, TOL, MATCH) < 1.0


@pytest.fixture()
def attempts(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """Counts the engine's step attempts (predictor-corrector calls)."""
    count = [0]
    engine = palc.ContinuationEngine
    original = engine._predict_correct

    def counted(self: Any, *args: Any) -> Any:
        count[0] += 1
        return original(self, *args)

    monkeypatch.setattr(engine, "_predict_correct", counted)
    yield count


def _events(result: api.Result) -> list[tuple[str, float]]:
    return sorted(((ev.kind, ev.parameter) for ev in result.events),
                  key=lambda e: e[1])


def test_steps_capped_by_the_ratio_keep_every_event_in_fewer_attempts(
        attempts: list[int], monkeypatch: pytest.MonkeyPatch) -> None:
    """The default case with the growth of a step capped by the motion ratio against no cap
    (the rule before): the same events, located to their tolerance, in at least 5 % fewer
    step attempts (352 against 381 measured, since multipliers outside the circle may move
    by half their distance to it: fewer refusals are left for the cap to save; 428 against
    531 before that)."""
    sized = api.run("yaml_cases/ndof_default.yaml", {"output.plots": False})
    n_sized = attempts[0]
    attempts[0] = 0
    monkeypatch.setattr(palc.step_control, "_motion_capped_step", lambda h, ratio: np.inf)
    halved = api.run("yaml_cases/ndof_default.yaml", {"output.plots": False})
    n_halved = attempts[0]
    ev_sized, ev_halved = _events(sized), _events(halved)
    assert [k for k, _ in ev_sized] == [k for k, _ in ev_halved]
    assert len(ev_sized) >= 25
    np.testing.assert_allclose([t for _, t in ev_sized], [t for _, t in ev_halved],
                               rtol=0, atol=1e-9)
    assert n_sized < 0.95 * n_halved
