"""The Illinois iteration where trial points fail (``f`` is NaN: the corrector did not converge).

The oracle is the known zero of a test function; the property: the returned location is within
the returned width of the true zero (never a confident wrong location), and failures away from
the zero do not cost its accuracy.
"""

from __future__ import annotations

import numpy as np
import pytest

from nsm_continuation.core.roots import illinois


def _with_failures(z: float, lo: float, hi: float):
    """A smooth function with its only zero at ``z``, failing (NaN) on ``(lo, hi)``."""
    calls: list[float] = []

    def f(x: float) -> tuple[float, float | None]:
        calls.append(x)
        if lo < x < hi:
            return float("nan"), None
        return float(np.tanh(3.0 * (x - z)) + 0.2 * (x - z) ** 3), x
    return f, calls


@pytest.mark.parametrize("z, lo, hi", [(0.3, 0.25, 0.35), (0.3, 0.2, 0.31), (0.62, 0.55, 0.6),
                                       (0.8, 0.1, 0.4), (0.05, 0.0, 0.2)])
def test_location_within_its_width_of_the_true_zero(z: float, lo: float, hi: float) -> None:
    f, _ = _with_failures(z, lo, hi)
    fa, fb = f(0.0)[0], f(1.0)[0]
    tol = 1e-10
    sig, _, width = illinois(f, 0.0, fa, 1.0, fb, tol, close=True)
    assert abs(sig - z) <= max(width, tol) * (1 + 1e-9)
    if not lo <= z <= hi:
        # the failed zone does not hold the zero: located to the tolerance
        assert width <= tol and abs(sig - z) <= 2 * tol
    else:
        # it does: the width covers the part of the failed zone next to the zero
        assert width >= min(z - lo, hi - z) > 0


def test_random_failed_zones_never_mislead() -> None:
    rng = np.random.default_rng(7)
    for _ in range(200):
        z = rng.uniform(0.01, 0.99)
        lo = rng.uniform(0.0, 0.9)
        hi = lo + rng.uniform(0.0, 0.3)
        f, _ = _with_failures(z, lo, hi)
        fa, fb = f(0.0)[0], f(1.0)[0]
        if not (np.isfinite(fa) and np.isfinite(fb)):
            continue
        sig, _, width = illinois(f, 0.0, fa, 1.0, fb, 1e-9, close=True)
        assert abs(sig - z) <= max(width, 1e-9) * (1 + 1e-9)


def test_no_failure_same_iterates_as_plain_illinois() -> None:
    # without failures the iteration is the Illinois method: the zero to tol in few calls
    f, calls = _with_failures(0.37, 2.0, 3.0)
    sig, _, width = illinois(f, 0.0, f(0.0)[0], 1.0, f(1.0)[0], 1e-12, close=True)
    assert abs(sig - 0.37) <= 1e-12 and width <= 1e-12
    assert len(calls) < 20
