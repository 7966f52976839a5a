"""Contacts of a system with several impact surfaces (or one constraint whose zero set has
several parts), mixed into :class:`~nsm_continuation.hybrid.simulate.Simulator`.

After an impact on one surface the others' free-flight states follow the sign of their ``v``
(:meth:`SurfaceContacts._reclassify_others`); turns of ``v`` of parallel surfaces at one instant
are fired together (:meth:`SurfaceContacts._coincident_turns`); an impact on another surface,
or on another part of the same constraint, ends a chattering flight
(:meth:`SurfaceContacts._break_chatter`, :meth:`SurfaceContacts._same_contact`); two surfaces
met at once have no declared law and are refused, named
(:meth:`SurfaceContacts._check_single_contact`, and sticking on one while hitting another).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from nsm_continuation.hybrid.modes import S1, S2, S3, S4, S5, S6
from nsm_continuation.hybrid.sim_data import SimEvent, SimulationError
from nsm_continuation.hybrid.system import CompiledHybrid
from nsm_continuation.hybrid.walk import _Walk

__all__ = ["SurfaceContacts"]


class SurfaceContacts:
    """The bookkeeping of several surfaces (see the module docstring)."""

    c: CompiledHybrid
    #: the compiled Functions, called through their buffers (``CompiledHybrid.calls``)
    calls: Any

    def _relayout(self, w: _Walk, probe: bool = True) -> None:  # pragma: no cover
        raise NotImplementedError

    def _apply_transition(self, w: _Walk, name: str, pre: np.ndarray, surface: int,
                          coincident: bool = True) -> None:  # pragma: no cover
        raise NotImplementedError

    def _reclassify_others(self, w: _Walk, surface: int) -> None:
        """After an impact on ``surface`` (a jump of the velocities) the other surfaces'
        free-flight states follow the sign of their ``v``: an approach (``s2``) may have become
        a departure (``s1``) or conversely, without any crossing of ``v``."""
        changed = False
        for j, mode in enumerate(w.modes):
            if j == surface or j == w.active or mode not in (S1, S2, S3):
                continue
            v = float(w.pr[w.offsets[j] + 1])
            new = S2 if v < 0 else (S1 if v > 0 else mode)
            if new != mode:
                w.modes[j], changed = new, True
        if changed:
            self._relayout(w, probe=False)

    def _coincident_turns(self, w: _Walk, surface: int) -> None:
        """Turns of ``v`` of other surfaces at the instant of the turn on ``surface`` (parallel
        constraints such as a floor and a ceiling turn together: ``v_floor = -v_ceiling``).
        At the located turn their ``v`` is zero to round-off, and a round-off sign would hide
        their crossing from the next step (a lost near approach): each is fired here, in the
        direction its ``a`` gives."""
        tiny = 1e-12 * (1.0 + float(np.max(np.abs(w.Y[: self.c.n]))))
        fired = set(w.just)
        for j, mode in enumerate(w.modes):
            if j == surface or mode not in (S1, S2, S5, S6) or ("v", j) in fired:
                continue
            off = w.offsets[j]
            v, a = float(w.pr[off + 1]), float(w.pr[off + 2])
            if abs(v) > tiny:
                continue
            if (mode in (S1, S5) and a < 0) or (mode in (S2, S6) and a > 0):
                self._apply_transition(w, "v", w.pr, j, coincident=False)
                fired |= w.just
        w.just = fired

    #: cosine of the angle between the surface's normals beyond which two impacts of one
    #: constraint are on different parts of it (:meth:`Simulator._same_contact`)
    SAME_CONTACT_COSINE = 0.5

    def _contact_normal(self, Y: np.ndarray, surface: int) -> np.ndarray:
        """Unit normal of ``surface`` at ``Y`` in the position components ``H`` depends on."""
        pos = self.c.system.position or []
        g = np.asarray(self.calls.surfaces[surface].grads(Y[: self.c.N])[0])[pos]
        norm = float(np.linalg.norm(g))
        return g / norm if norm > 0.0 else g

    def _same_contact(self, w: _Walk) -> bool:
        """Whether an impact of a chattering flight meets the surface where the sequence
        began. A chattering sequence accumulates at one point of the surface, so its impacts
        share the normal; one constraint whose zero set has several parts (``H = d^2 - q^2``
        for two stops at ``+-d``) is met on another part when the normals differ (by more than
        60 degrees): that impact ends the sequence, as an impact on another surface would."""
        if w.seq_normal is None or w.active is None:
            return True
        nrm = self._contact_normal(w.Y, w.active)
        return float(nrm @ w.seq_normal) >= self.SAME_CONTACT_COSINE

    def _break_chatter(self, w: _Walk, surface: int) -> None:
        """An impact on ``surface`` while another surface (or another part of the same one)
        sticks or chatters. Sticking on one surface while hitting another is a contact with two
        surfaces at once, which is not modelled (refused, named); a chattering flight is a
        free flight: its sequence breaks off there (transition X of Table 1, as if it had
        turned) and the impact follows as one of a free flight."""
        c, act = self.c, w.active
        assert act is not None
        if w.modes[act] == S4:
            raise SimulationError(
                f"impact on {c.surface_label(surface)} at t = {w.t:.6g} while sticking on "
                f"{c.surface_label(act)}: contact with two surfaces at once is not modelled")
        N = c.N
        w.events.append(SimEvent("chatter_broken", w.t, w.Y[: c.n].copy(),
                                 {"impacts": len(w.seq)}, surface=act))
        w.seq.clear()
        w.seq_normal = None
        w.Y = w.Y[:N].copy()
        w.J = None if w.J is None else w.J[:N].copy()
        v = float(c.q(w.Y, act)["v"])
        w.modes[act] = S1 if v > 0 else S2
        w.active = None
        if surface == act:
            w.modes[surface] = S2
        self._relayout(w)

    def _check_single_contact(self, w: _Walk, surface: int) -> None:
        """An impact on ``surface`` while another surface is met at the same instant (within
        round-off, moving inwards): simultaneous impacts have no declared law (refused)."""
        c = self.c
        if c.m == 1:
            return
        X = w.Y[: c.N]
        tiny = 1e-10 * (1.0 + float(np.max(np.abs(X))))
        for j in range(c.m):
            if j == surface:
                continue
            qj = c.q(X, j)
            if qj["H"] <= tiny and qj["v"] < 0:
                raise SimulationError(
                    f"simultaneous impacts on {c.surface_label(surface)} and "
                    f"{c.surface_label(j)} at t = {w.t:.6g}: no impact law is declared for "
                    "two surfaces at once")
