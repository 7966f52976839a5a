"""Named ends of a branch of impacting orbits, and the families it goes through.

A system of one's own, written as a plugin would be: the impact damper (a forced primary mass
with a ball in a cavity of clearance ``d``, the two walls declared as one smooth surface ``H =
d^2/4 - z^2``, ``z = y - x``). Its symmetric two-impact orbit (closed form,
``oracles.damper_symmetric``) ends where the ball comes to rest at the centre (the impact
velocity vanishes, ``A(omega) = d/2``) and where the relative motion touches the wall it left
between impacts (an interior contact on both walls at once, by symmetry): each end is an
event at its closed-form location, and the branch's termination names it. The forced impact
oscillator's grazing (``sqrt(3)``, ``tests/hybrid/test_grazing.py``) is a family change: its
event, the ``signature`` column and the families of the report.
"""

from __future__ import annotations

from typing import ClassVar

import casadi as ca
import numpy as np
import pytest
from oracles import damper_symmetric as sym
from oracles import impact_oscillator as oscillator
from pydantic import BaseModel, ConfigDict, Field

import nsm_continuation as nsm
from nsm_continuation.core.palc import ContinuationEngine
from nsm_continuation.core.palc.ends import extrapolate_to_zero, zero_order
from nsm_continuation.core.palc.kinks import KinkCrosser
from nsm_continuation.core.palc.locate import EventSource
from nsm_continuation.core.problem import StartPoint
from nsm_continuation.core.records import Event, Point
from nsm_continuation.core.settings import ContinuationSettings
from nsm_continuation.hybrid.case import HybridCaseProblem, IntegratorSpec, Section
from nsm_continuation.hybrid.system import HybridSystem
from nsm_continuation.output.report import family_runs, markdown

MU, E, D = 0.2, 0.8, 1.0


class DamperParameters(BaseModel):
    model_config = ConfigDict(extra="forbid")
    mu: float = Field(MU, gt=0)
    zeta: float = Field(0.0, ge=0)
    omega: float = Field(1.5, gt=0)
    d: float = Field(D, gt=0)
    restitution: float = Field(E, ge=0, lt=1)
    section_phase: float = 0.0
    integrator: IntegratorSpec = IntegratorSpec()


class SingleSurfaceDamper(HybridCaseProblem):
    """The impact damper with both walls as one smooth surface ``H = d^2/4 - z^2``."""

    name: ClassVar[str] = "test_impact_damper_single_h"
    Parameters: ClassVar[type[BaseModel]] = DamperParameters
    default_parameter: ClassVar[str] = "omega"
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "section_phase")

    def system(self) -> HybridSystem:
        q, qd, ph = ca.SX.sym("q", 2), ca.SX.sym("qd", 2), ca.SX.sym("phase")
        p = {k: ca.SX.sym(k) for k in ("mu", "zeta", "omega", "d", "restitution")}
        force = ca.vertcat(-q[0] - 2 * p["zeta"] * qd[0] + ca.cos(ph), 0)
        z = q[1] - q[0]
        return HybridSystem.mechanical(
            "impact_damper", q, qd, p, ca.diag(ca.vertcat(1, p["mu"])), force,
            p["d"] ** 2 / 4 - z ** 2, p["restitution"], clock=ph, clock_rate=p["omega"],
            state_names=["x", "y", "xdot", "ydot", "phase"])

    def section(self) -> Section:
        return Section(4, self.params.section_phase, 2 * np.pi)  # type: ignore[attr-defined]

    def default_initial(self) -> np.ndarray:
        return np.array([0.0, 0.0, 0.0, 0.0, self.section().value])


def symmetric_start(omega: float, zeta: float, guess: tuple[float, float, float],
                    phase: float) -> tuple[SingleSurfaceDamper, StartPoint]:
    """The damper at ``omega`` with its section at ``phase`` and the closed-form symmetric
    orbit there as the start (corrected by Newton)."""
    u = sym.orbit(omega, zeta, MU, E, D, guess)
    pr = SingleSurfaceDamper(DamperParameters(zeta=zeta, omega=omega, section_phase=phase))
    X = sym.section_state(u, omega, zeta, D, phase)
    return pr, StartPoint(np.append(X, omega), "symmetric orbit", -1)


@pytest.mark.parametrize("zeta", [0.0, 0.05])
def test_the_symmetric_orbit_ends_where_its_impact_velocity_vanishes(zeta: float) -> None:
    """Continued down from omega = 1.76 (the low-velocity orbit), the branch ends with
    ``impact_velocity_vanishes`` at ``A(omega) = d/2`` (sqrt(3) undamped) to 1e-8, within the
    uncertainty it states, and its termination names it; the normal impact velocity
    ``|zdot| / sqrt 2`` of the points is the closed form's (the single smooth ``H`` scales
    ``dH/dt`` by ``d``, the normal velocity does not see it)."""
    pr, start = symmetric_start(1.76, zeta, (-0.48, 0.0, 6.28), np.pi / 2)
    res = nsm.continuation(pr, start, min=1.6, max=1.8, max_points=400,
                           step={"initial": 0.01, "min": 1e-9, "max": 0.05}, newton_tol=1e-10)
    br = res.branches[0].raw
    ends = [ev for ev in br.events if ev.kind == "impact_velocity_vanishes"]
    w_end = sym.end_frequency(zeta, D, (1.5, 1.8))
    assert len(ends) == 1 and ends[0].point is br.points[-1]
    err = abs(ends[0].point.y[-1] - w_end)
    assert err < 1e-8 and err <= ends[0].data["parameter_uncertainty"]
    assert br.termination["forward"].startswith("impact_velocity_vanishes at omega = 1.7")
    assert ends[0].data["zero_order"] == pytest.approx(1.0, abs=0.2)
    u = np.array([-0.48, 0.0, 6.28])
    for p in br.points[:-1:20]:
        u = sym.orbit(float(p.y[-1]), zeta, MU, E, D, tuple(u))
        v = sym.impact_velocity(u, float(p.y[-1]), zeta, MU, D)
        assert p.derived["min_impact_normal_velocity"] == pytest.approx(
            abs(v) / np.sqrt(2), rel=1e-6)
        assert p.derived["min_impact_dH_dt"] == pytest.approx(D * abs(v), rel=1e-6)


def test_an_interior_contact_on_both_walls_ends_the_branch_named() -> None:
    """The high-velocity symmetric orbit continued down to its interior contact (the wall it
    left comes back to touch the ball, on both walls at once): the branch ends with a
    ``grazing`` event (not crossed) at the closed-form frequency to 1e-10, the reason naming
    the two contacts, and no Newton failure as the termination."""
    guess = (0.4736, 0.062, 3.245)
    u = np.array(guess)
    for w in np.linspace(1.5, 1.13, 38):
        u = sym.orbit(w, 0.0, MU, E, D, tuple(u))
    pr, start = symmetric_start(1.13, 0.0, tuple(u), 0.0)
    res = nsm.continuation(pr, start, min=1.0, max=1.2, max_points=200,
                           step={"initial": 0.005, "min": 1e-9, "max": 0.02}, newton_tol=1e-10)
    br = res.branches[0].raw
    w_g = sym.interior_grazing(0.0, MU, E, D, (*u, 1.1, 2.0))[3]
    graz = [ev for ev in br.events if ev.kind == "grazing"]
    assert len(graz) == 1 and graz[0].point is br.points[-1]
    assert graz[0].point.y[-1] == pytest.approx(w_g, abs=1e-10)
    assert graz[0].data["crossed"] is False
    assert "2 contacts graze at once" in graz[0].data["reason"]
    assert br.termination["forward"].startswith("grazing at omega = 1.09928")


def test_a_grazing_crossed_is_a_family_change_labelled_on_the_points() -> None:
    """The undamped impact oscillator continued down from its free orbit through the grazing
    at sqrt(3) onto the low-velocity impacting orbit: a ``family_change`` event at the
    grazing (sequence ``- -> I``), every point before it in family ``-`` and after it in
    ``I`` (the ``signature`` column), two runs in the report's families, said in
    report.md."""
    pr = nsm.problem("impact_oscillator", {"zeta": 0.0, "omega": 1.8, "gap": -0.5,
                                           "restitution": 0.8, "section_phase": np.pi})
    A0 = 1.0 / (1.8 ** 2 - 1.0)
    res = nsm.continuation(pr, {"guess": {"q": A0, "qdot": 0.0}, "direction": "decrease"},
                           min=1.2, max=2.0, max_points=40, newton_tol=1e-10,
                           step={"initial": 0.01, "min": 1e-9, "max": 0.1})
    data = res.branches[0]
    br = data.raw
    fam = [ev for ev in br.events if ev.kind == "family_change"]
    graz = [ev for ev in br.events if ev.kind == "grazing"]
    assert len(fam) == 1 and len(graz) == 1 and fam[0].point is graz[0].point
    assert fam[0].point.y[-1] == pytest.approx(np.sqrt(3.0), abs=1e-10)
    assert (fam[0].data["signature_before"], fam[0].data["signature_after"]) == ("-", "I")
    s_g = fam[0].point.s
    sig = data["signature"]
    assert all(sig[k] == "-" for k, p in enumerate(br.points) if p.s < s_g - 1e-9)
    assert all(sig[k] == "I" for k, p in enumerate(br.points) if p.s > s_g + 1e-9)
    runs = family_runs(br.points, pr.parameter_index)
    assert [r["signature"] for r in runs] == ["-", "I"]
    text = markdown(res.report())
    assert "## Families" in text and "`-` (rows 0-" in text and "then `I`" in text


def test_a_vanishing_impact_velocity_at_a_single_grazing_is_crossed_not_an_end() -> None:
    """The impact velocity of the undamped oscillator's low-velocity orbit falls to a simple
    zero at its grazing (sqrt(3)) too, but there the branch goes on along the free orbit: with
    the approach's last point unresolved, the end locator asks the kink crosser first, and
    the branch is continued across the grazing (a ``family_change`` ``I -> -`` at sqrt(3) to
    1e-10, the point beyond it free, amplitude ``1/(omega^2 - 1)``), not ended. The impact
    damper's end, asked the same, ends (no family beyond it)."""
    params = {"zeta": 0.0, "omega": 1.76, "gap": -0.5, "restitution": 0.8,
              "section_phase": np.pi}
    pr = nsm.problem("impact_oscillator", params)
    # the low-velocity orbit from its closed form (oracles.impact_oscillator): the flight
    # from the impact at phase phi (q = gap, qdot = -r v-) to the section at phase pi
    w, r, gap = 1.76, 0.8, -0.5
    orbit = min(oscillator.orbits(w, gap, r), key=lambda o: abs(o["v_minus"]))
    G, phi = 1.0 / (1.0 - w * w), orbit["phase"]
    a, b = gap - G * np.cos(phi), -r * orbit["v_minus"] + G * w * np.sin(phi)
    t = ((np.pi - phi) % (2 * np.pi)) / w
    q = G * np.cos(np.pi) + a * np.cos(t) + b * np.sin(t)
    qdot = -G * w * np.sin(np.pi) - a * np.sin(t) + b * np.cos(t)
    impacting = nsm.continuation(pr, {"guess": {"q": q, "qdot": qdot}, "direction": "decrease"},
                                 min=1.2, max=1.8, max_points=200, newton_tol=1e-10,
                                 step={"initial": 0.005, "min": 1e-9, "max": 0.02})
    # the branch up to the grazing it went through (the approach, impacting orbits only)
    br = impacting.branches[0].raw
    s_g = next(ev.point.s for ev in br.events if ev.kind == "grazing")
    pts = [p for p in br.points if p.s < s_g - 1e-12]
    assert all(p.derived["n_impacts"] == 1 for p in pts)
    engine = ContinuationEngine(pr, ContinuationSettings(newton_tol=1e-10, param_min=1.2,
                                                         param_max=2.0))
    engine.ends.begin()
    pts[-1].residual_norm = 1e-6  # as if the last orbit of the approach were not resolved
    events: list[Event] = []
    assert engine.ends.unresolved_end(pts, events) is None
    fam = [ev for ev in events if ev.kind == "family_change"]
    assert len(fam) == 1 and fam[0].point.y[-1] == pytest.approx(np.sqrt(3.0), abs=1e-10)
    assert (fam[0].data["signature_before"], fam[0].data["signature_after"]) == ("I", "-")
    assert pts[-1].derived["n_impacts"] == 0 and pts[-1].y[-1] > np.sqrt(3.0)
    assert pts[-1].derived["max_q"] == pytest.approx(1.0 / (pts[-1].y[-1] ** 2 - 1.0),
                                                     abs=1e-9)
    damper, start = symmetric_start(1.76, 0.0, (-0.48, 0.0, 6.28), np.pi / 2)
    approach = nsm.continuation(damper, start, min=1.6, max=1.8, max_points=200,
                                step={"initial": 0.01, "min": 1e-9, "max": 0.05},
                                newton_tol=1e-10)
    pts = list(approach.branches[0].raw.points)[:-1]  # without the end it found
    engine = ContinuationEngine(damper, ContinuationSettings(newton_tol=1e-10))
    engine.ends.begin()
    pts[-1].residual_norm = 1e-6
    events = []
    why = engine.ends.unresolved_end(pts, events)
    assert why is not None and why.startswith("impact_velocity_vanishes at omega = 1.73205")
    assert [ev.kind for ev in events] == ["impact_velocity_vanishes"]
    assert abs(pts[-1].y[-1] - np.sqrt(3.0)) <= events[0].data["parameter_uncertainty"]


def test_a_transient_without_impacts_is_named_when_the_start_fails() -> None:
    """A damped damper started from rest where the primary's response (0.19) stays inside
    the cavity: the transient settles on an orbit without impacts whose ball may rest anywhere
    (a singular Jacobian); the start's failure says what the transient found."""
    pr = SingleSurfaceDamper(DamperParameters(zeta=0.05, omega=2.5))
    res = nsm.continuation(pr, {"transient": 40}, min=2.0, max=3.0, max_points=5)
    why = res.branches[0].termination["start"]
    assert "singular Jacobian" in why
    assert "settled on an orbit without impacts: it does not touch the impact surface" in why


def _point(s: float, y: np.ndarray, q: float, signature: str = "II") -> Point:
    return Point(y=y, s=s, tangent=np.array([1.0, 0.0]), tests={}, multipliers=None,
                 trivial_error=0.0, n_unstable=0, derived={"q": q}, bordered_det=1.0,
                 signature=signature)


def test_extrapolation_to_a_simple_zero_is_exact_for_polynomial_branches() -> None:
    """Second method: a branch whose arclength and unknowns are cubics in the quantity ``q``
    is extrapolated to ``q = 0`` exactly (to round-off), and the order of the zero of ``q``
    along the arclength is 1 for ``q ~ s* - s`` and 1/2 for ``q ~ sqrt(s* - s)``."""
    q = np.geomspace(1e-3, 1e-2, 9)[::-1]
    s = 2.0 - 3.0 * q + 0.5 * q ** 2
    y = np.column_stack([1.0 + q - 4.0 * q ** 3, 0.3 - 2.0 * q ** 2])
    at = extrapolate_to_zero(q, np.column_stack([s, y]), 3)
    assert np.allclose(at, [2.0, 1.0, 0.3], atol=1e-12)
    ss = np.linspace(0.0, 0.9, 10)
    assert zero_order(ss, 1.0 - ss) == pytest.approx(1.0, abs=0.02)
    assert zero_order(ss, np.sqrt(1.0 - ss)) == pytest.approx(0.5, abs=0.02)


def test_a_signature_change_across_a_zero_crossed_by_the_corrector_is_a_family_change(
        ) -> None:
    """A step that went across a zero of an event function (the corrector, not the
    problem's parametrisation) with the signature changing over it: the located signature
    change becomes a ``family_change`` at the zero; without a zero in the step, or with the
    same signature at both ends, the step's events are unchanged."""
    pr = SingleSurfaceDamper(DamperParameters())

    class Engine:
        problem = pr

    crosser = KinkCrosser(Engine())  # type: ignore[arg-type]
    a, b = _point(0.0, np.zeros(2), 1.0, "III"), _point(1.0, np.ones(2), 1.0, "II")
    zero = Event("grazing", _point(0.4, np.full(2, 0.4), 1.0), "zero",
                 data={"function": "grazing_margin"}, bracket=1e-12)
    change = Event("impact_sequence_change", _point(0.41, np.full(2, 0.41), 1.0),
                   "event sequence III -> II",
                   data={"signature_before": "III", "signature_after": "II"}, bracket=1e-6)
    out = crosser.family_events(a, b, [(EventSource.FUNCTION, zero),
                                       (EventSource.SIGNATURE, change)])
    kinds = sorted(ev.kind for ev in out)
    assert kinds == ["family_change", "grazing"]
    fam = next(ev for ev in out if ev.kind == "family_change")
    assert fam.point is zero.point and fam.data["signature_after"] == "II"
    same = crosser.family_events(a, a, [(EventSource.FUNCTION, zero),
                                        (EventSource.SIGNATURE, change)])
    assert [ev.kind for ev in same] == ["grazing", "impact_sequence_change"]
    alone = crosser.family_events(a, b, [(EventSource.SIGNATURE, change)])
    assert [ev.kind for ev in alone] == ["impact_sequence_change"]
