"""Admissibility of the chain's orbits (Legrand, Junca, Heng 2017, Definition 2.2).

:class:`ChainAdmissibility` (a mixin of
:class:`~nsm_continuation.problems.chain.ndof_impact.NDofImpactProblem`) decides it from the
closed form, without sampling: the outgoing velocity (H+) and the clearance of ``u_c`` below
the wall, from the exact critical points of the sum of sinusoids (5.4)
(:class:`~nsm_continuation.problems.chain.trig_sum.TrigSum`); for ``g = 0`` the orbit's own
amplitude is the scale (sec. 7.2, Prop. 7.2).
"""

from __future__ import annotations

import numpy as np


class ChainAdmissibility:
    """The admissibility tests (Definition 2.2) of an orbit of the chain."""

    c: int
    g: float
    omega: np.ndarray

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        """Definition 2.2 decided from the closed form (no sampling):

        * ``outgoing_velocity = -u_c'(0+) / (|g| w_1)`` > 0: the mass leaves the wall (H+);
        * ``clearance = (g - max u_c(t_k)) / |g|`` over the critical points ``t_k`` of ``u_c`` in
          ``(0, T)``, located exactly (:class:`~problems.chain.trig_sum.TrigSum`); it vanishes at a
          nonlinear grazing orbit (an extra tangential contact, Fig. 5.2). Computed as
          ``-max (u_c(t_k) - u_c(t_ref)) / |g|``, the rise from the nearer impact ``t_ref = 0``
          or ``T`` (:meth:`~problems.chain.trig_sum.TrigSum.rise`; ``u_c(0) = u_c(T) = g`` on
          the branch, the residual's last row and the periodicity, so the value is the same to
          the residual, ~1e-16). The difference ``g - u_c(t_k)`` would keep only its rounding
          for a critical point next to an impact: past a linear grazing orbit (the outgoing
          velocity through zero) a maximum enters at ``t = 0+`` above the wall by
          ``O(v^2)``, and the clearance's sign there would be noise, its zero located up to
          ~1e-9 in ``T`` away from the grazing as a second event.

        For ``g = 0`` (sec. 7.2) the gap gives no scale: the orbit's own amplitude
        ``A = max(|u(0)|_inf, |u_c'(0+)| / w_1)`` does (:meth:`_static_grazing_scale`), so both
        tests are homogeneous of degree 0 in ``(u(0), v)``: constant along each half ``v < 0``,
        ``v > 0`` of a vertical family (7.5)-(7.6), admissible on the half ``v < 0`` of an
        admissible root only (Prop. 7.2, sign corrected: :mod:`.ndof_impact`). The static
        equilibrium ``u = 0`` (``A = 0``, the trivial branch) has no test: it is admissible
        (proof of Prop. 7.2).
        """
        u0, du0, T = self.state(y)
        scale = abs(self.g) if self.g != 0.0 else self._static_grazing_scale(u0, du0)
        if scale == 0.0:
            return {}
        f = self.displacement_sum(y)
        tc = f.critical_points(0.0, T)
        clearance = 1.0
        if tc.size:
            rise = f.rise(tc, np.where(tc < 0.5 * T, 0.0, T))
            clearance = -float(rise.max()) / scale
        return {"outgoing_velocity": -du0[self.c] / (scale * self.omega[0]),
                "clearance": float(clearance)}

    def _static_grazing_scale(self, u0: np.ndarray, du0: np.ndarray) -> float:
        """Amplitude ``A = max(|u(0)|_inf, |u_c'(0+)| / w_1)`` of a ``g = 0`` orbit, the scale
        of its admissibility tests (0 at the static equilibrium)."""
        return float(max(np.max(np.abs(u0)), abs(du0[self.c]) / self.omega[0]))

    def static_grazing_admissible(self, T: float) -> bool:
        """For ``g = 0``: the orbit ``x = v (w(T), e_c)`` with ``v < 0`` (Prop. 7.2, sign
        corrected) is admissible iff ``u_c <= 0`` on ``(0, T)``; its shape is ``v``-independent."""
        u0, du0 = self.closed_form(T, g=1.0)  # direction only: scale by v = -1
        scale = -1.0 / du0[self.c]
        y = self.y_from_state(u0 * scale, du0 * scale, T)
        umax, _ = self.displacement_sum(y).max_on(0.0, T)
        return bool(umax <= 1e-12 * np.max(np.abs(u0 * scale)))

