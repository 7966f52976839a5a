"""What the forced two-wall systems share (:mod:`.two_sided_oscillator`, :mod:`.impact_damper`):
a coordinate ``z`` (the oscillator's position, the ball's position relative to the primary)
kept within ``|z| <= w`` by two symmetric walls with restitution ``e``, the forcing phase
``omega t`` as the last state component, and the stroboscopic Poincaré section
``phase = section_phase`` (mod ``2 pi``).

``encoding`` (a setting of both) says how the walls are declared:

* ``surfaces``: two unilateral constraints ``H_upper = w - z >= 0`` and
  ``H_lower = w + z >= 0``, each with restitution ``e``;
* ``single``: one smooth constraint ``H = w^2 - z^2 >= 0`` whose zero set is both walls
  (``N^T qd = -2 z z'``: the impact law is the same, the impact velocity reads ``2 w |z'|``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import casadi as ca
import numpy as np

from nsm_continuation.hybrid.case import HybridCaseProblem, Section
from nsm_continuation.hybrid.system import HybridSystem

#: the names of the two walls (``z = +w``, ``z = -w``) in the ``surfaces`` encoding
SURFACES = ["upper", "lower"]


class TwoWallForcedProblem(HybridCaseProblem):
    """A forced system between two symmetric walls (see the module docstring); a subclass
    declares its equations and builds its system with :meth:`between_walls`."""

    #: the figures depend on the results and the parameters only (Problem.figures_from_inputs)
    figures_from_inputs: ClassVar[bool] = True
    default_parameter: ClassVar[str] = "omega"
    setting_fields: ClassVar[tuple[str, ...]] = ("integrator", "section_phase", "encoding")
    curve_preference: ClassVar[tuple[str, ...]] = ("clearance",)
    #: the index of the forcing phase ``omega t`` in the state
    phase_index: ClassVar[int]

    def between_walls(self, name: str, q: ca.SX, qd: ca.SX, p: dict[str, ca.SX], M: Any,
                      force: ca.SX, z: ca.SX, w: ca.SX, e: ca.SX, **kw: Any) -> HybridSystem:
        """The mechanical system ``M q'' = force`` with ``|z| <= w`` in the case's
        ``encoding`` (module docstring); ``kw`` as :meth:`HybridSystem.mechanical`."""
        if self.params.encoding == "single":  # type: ignore[attr-defined]
            return HybridSystem.mechanical(name, q, qd, p, M, force, w ** 2 - z ** 2, e, **kw)
        return HybridSystem.mechanical(name, q, qd, p, M, force, [w - z, w + z], [e, e],
                                       surfaces=SURFACES, **kw)

    def section(self) -> Section:
        """The stroboscopic section ``phase = section_phase`` (mod ``2 pi``)."""
        return Section(self.phase_index, self.params.section_phase,  # type: ignore[attr-defined]
                       2 * np.pi)
