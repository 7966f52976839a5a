"""Two-parameter continuation of the grazing of a hybrid periodic orbit.

A grazing is a codimension-one condition on a periodic orbit: its closest approach to the
surface is zero, ``H_min = 0``. With two parameters ``(p, q)`` free, the grazing orbits form a
curve, the solution set of the augmented system

    G(z; p, q) = 0,      m(z; p, q) = margin,                                        (C1)

``G`` the shooting residual (:mod:`.return_map`) and ``m`` the signed grazing margin closest to
zero (``H_min`` of a near approach, :func:`.grazing.margin_gradient`), with its exact gradient
from the saltation-chained sensitivities of the same simulation. The curve sits exactly on the
kink of the return map; ``margin`` (default ``1e-9``, relative to ``1 + |y|``) keeps it on the
free side, where ``G`` is smooth: the continued orbits miss the surface by ``margin``, whose
closed form is that of the grazing orbit with the gap moved by ``margin`` (the margin is
documented and tested, not hidden: ``tests/hybrid/test_grazing.py`` and
``tests/cases/test_grazing_curves_from_yaml.py``
compare with the closed form *including* it).

**The free side, extended.** A predicted point lies ``O(ds^2)`` off the curve, on either side;
on the impacting side ``G`` has the square-root term of the discontinuity map (eq. G1) and
Newton crawls back at a linear rate (measured on the impact oscillator: 5 iterations per
point and steps held at 5e-4). Where the grazing approach is the orbit's only contact (one
impact, no chattering, no sticking), (C1) is evaluated there on the *virtual* orbit instead:
the same system with its surface moved out of the way (``H + s``, ``s`` a lifted parameter
larger than the dip), whose return map is the smooth continuation of the free side's and whose
near approach gives ``H_min = H_min^virtual - s < 0``. Both agree exactly where the orbit
misses the surface, so the solutions are unchanged and Newton converges quadratically from
either side. An orbit with other contacts is evaluated as it is (correct, slower).

The unknowns are ``y = (z, p, q)``; ``q`` is the continuation parameter and ``p`` is solved
for. Like TC-HAT's and COCO's grazing curves (``coco`` ``'hspo'`` demos), but on the automatic
event sequence of the simulator rather than a prescribed segment sequence. From YAML:
``start: {from: <run>, event: grazing, curve: grazing, free: <p>}`` with
``continuation.parameter: <q>`` (:mod:`nsm_continuation.cases.restart`).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, ClassVar

import casadi as ca
import numpy as np
from pydantic import BaseModel

from nsm_continuation.algorithms.curves import CodimOneCurve
from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.problem import EvaluationError
from nsm_continuation.hybrid.grazing import margin_gradient
from nsm_continuation.hybrid.return_map import (
    HybridShooting,
    ShootingFailure,
    shooting_jacobian_noise,
)
from nsm_continuation.hybrid.system import HybridDeclarationError

if TYPE_CHECKING:
    from nsm_continuation.hybrid.case import HybridCaseProblem

#: the lifted parameter of the virtual system (the surface moved to ``H + s = 0``)
SHIFT = "_grazing_curve_shift"
#: the default distance the continued orbits keep from the surface (relative to ``1 + |y|``)
DEFAULT_MARGIN = 1e-9


class GrazingCurvePresentation(Presentation):
    """A grazing curve: the continued parameter against the free one, with the period and the
    grazing margin."""

    diagram_title: ClassVar[str] = "Grazing curve"
    two_parameter: ClassVar[bool] = True

    @property
    def fep_axes(self) -> tuple[str, str]:
        return (self.problem.parameter, self.problem.free)

    @property
    def fep_labels(self) -> tuple[str, str]:
        """The two parameters as the base family labels them."""
        base = self.problem.base.presentation
        return (base.label(self.problem.parameter),
                f"{base.label(self.problem.free)} at the grazing")

    def start_point(self, branch: Any) -> Any:
        """The point of the curve at the base run's value of the continued parameter (the
        codimension-one point it was started from; the curve's arclength starts at one of its
        ends)."""
        value = self.problem.base.values.get(self.problem.parameter)
        if value is None or not branch.points:
            return super().start_point(branch)
        i = self.problem.variables.index(self.problem.parameter)
        return min(branch.points, key=lambda p: abs(p.y[i] - value))

    def branch_name(self, branch: Any) -> str:
        return "grazing curve (computed)"

    def closed_forms(self, x_range: tuple[float, float], branches: list[Any]
                     ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """The base family's closed form of its grazing curve, if it has one."""
        pr = self.problem
        return pr.base.presentation.curve_closed_forms("grazing", pr.parameter, pr.free,
                                                       x_range)

    @property
    def csv_head(self) -> list[str]:
        return [self.problem.parameter, self.problem.free, "period", "grazing_margin"]

    def summary(self) -> dict[str, Any]:
        pr = self.problem
        return {"curve": f"grazing orbits of {pr.base.name} (eq. C1 of "
                         "nsm_continuation.hybrid.codim1)",
                "continued": pr.parameter, "free": pr.free,
                "margin": f"{pr.margin:g} (1 + |y|): the orbits miss the surface by this",
                "returns": pr.returns, "parameters": dict(pr.base.values),
                "unknowns": list(pr.variables)}


class GrazingCurve(CodimOneCurve):
    """Grazing orbits of ``base`` with ``free`` solved for and ``parameter`` continued (C1)."""

    name: ClassVar[str] = "grazing_curve"
    #: the kind of codimension-one point the curve follows (``start.curve``)
    curve_kind: ClassVar[str] = "grazing"
    #: the base problem's parameters are the curve's (its model is the base's)
    Parameters: ClassVar[type[BaseModel]] = BaseModel
    presentation_class = GrazingCurvePresentation

    def __init__(self, base: HybridCaseProblem, free: str, parameter: str,
                 margin: float = DEFAULT_MARGIN) -> None:
        super().__init__(base.params)
        if free == parameter:
            raise ValueError(f"continuation.parameter: the grazing curve needs two parameters "
                             f"(free {free!r} and continued {parameter!r} are the same)")
        for key, name in (("free", free), ("parameter", parameter)):
            if name not in base.values:
                raise ValueError(f"{key}: {name!r} is not a parameter of {base.name!r} "
                                 f"(one of {sorted(base.values)})")
        self.base = base
        self.returns = int(base.returns)
        c = base.hybrid.compile(base.values, free=[free, parameter],
                                method=base.integrator.method)
        sec = base.section()
        # an orbit of ``returns`` base periods (:meth:`~.return_map.Section.repeated`)
        self.section = sec.repeated(self.returns)
        self.shooting = HybridShooting(c, self.section, base.integrator.options())
        names = base.hybrid.state_names
        self.variables = [names[i] for i in self.shooting.free_idx] + [free, parameter]
        self.parameter = parameter
        self.free = free
        self.margin = float(margin)
        self._virtual: HybridShooting | None = None
        #: evaluations on the impacting side, and how many used the virtual orbit
        self.n_impacting = 0
        self.n_virtual = 0

    def residual(self, y: Any) -> Any:  # pragma: no cover - numeric problem
        raise NotImplementedError("the grazing curve evaluates numerically")

    @property
    def compiled(self) -> Any:
        return None

    def jacobian_noise(self, y: np.ndarray, jacobian: np.ndarray) -> float:
        """The integrated Jacobian's accuracy (:func:`~.return_map.shooting_jacobian_noise`)."""
        try:
            return shooting_jacobian_noise(self.shooting, y, jacobian)
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None

    def period_multiple(self) -> int:
        return self.returns

    def target(self, y: np.ndarray) -> float:
        """The margin the continued orbits keep from the surface at ``y`` (C1)."""
        return self.margin * (1.0 + float(np.linalg.norm(y)))

    # ------------------------------------------------------------------ the virtual orbit
    def virtual_shooting(self) -> HybridShooting:
        """The shooting problem of the system with its surface at ``H + s = 0`` (``s`` lifted
        into the state after ``free`` and ``parameter``), compiled once."""
        if self._virtual is None:
            hyb = self.base.hybrid
            if hyb.m > 1:
                raise HybridDeclarationError(
                    f"{hyb.name}: a grazing curve moves the grazing surface; for a system "
                    f"with several surfaces ({', '.join(hyb.surface_names or [])}) it is not "
                    "available")
            s = ca.SX.sym(SHIFT)
            virtual = dataclasses.replace(hyb, H=hyb.H + s, params={**hyb.params, SHIFT: s},
                                          position=hyb.position)
            c = virtual.compile({**self.base.values, SHIFT: 0.0},
                                free=[self.free, self.parameter, SHIFT],
                                method=self.base.integrator.method)
            self._virtual = HybridShooting(c, self.section, self.base.integrator.options())
        return self._virtual

    @staticmethod
    def _single_contact(sh: HybridShooting, y: np.ndarray) -> bool:
        """Whether the orbit at ``y`` touches the surface once (one impact, no chattering, no
        sticking): then its grazing approach is its only contact."""
        res = sh.simulate(y)
        kinds = {ev.kind for ev in res.events}
        return (res.n_impacts == 1 and not res.sticking_intervals and not res.chatter_counts
                and kinds <= {"impact", "near_approach", "section"})

    def _virtual_evaluation(self, y: np.ndarray, depth: float
                            ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray] | None:
        """``(G, G_y, m, m_y)`` of the virtual orbit at ``y`` (module docstring), or None when
        it cannot be had (a shift that still meets the surface, a failed simulation)."""
        sh = self.virtual_shooting()
        c = sh.c
        cols = sh.free_idx + list(range(c.n, c.N))
        s = 4.0 * depth + 1e-6 * (1.0 + float(np.linalg.norm(y)))
        for _ in range(4):
            ys = np.append(y, s)
            try:
                res = sh.simulate(ys)
                if res.n_impacts or res.sticking_intervals:
                    s *= 16.0
                    continue
                g, J = sh.residual_jacobian(ys)
            except ShootingFailure:
                return None
            best: tuple[float, np.ndarray] | None = None
            for ev in res.events:
                if "H" not in ev.info or ev.info.get("J") is None:
                    continue
                value = float(ev.info["H"]) - s
                if best is None or abs(value) < abs(best[0]):
                    X = np.concatenate([ev.x, sh.x0(ys)[c.n:]])
                    row = np.asarray(c.grads(X), dtype=float)[0]
                    best = (value, (row @ ev.info["J"])[cols][:-1])
            if best is None:
                return None
            return g, J[:, :-1], best[0], best[1]
        return None

    # ------------------------------------------------------------------ (C1)
    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``[G; m - margin]`` and its exact Jacobian (C1), on the virtual orbit where the
        grazing approach is an impact and the orbit's only contact (module docstring)."""
        y = np.asarray(y, dtype=float)
        try:
            g, Gy = self.shooting.residual_jacobian(y)
        except ShootingFailure as exc:
            raise EvaluationError(f"simulation: {exc}") from None
        mg = margin_gradient(self.shooting, y)
        if mg is None:
            raise EvaluationError("no near approach to the surface: the orbit is not near a "
                                  "grazing")
        m, dm = mg
        if m < 0:
            self.n_impacting += 1
            if self._single_contact(self.shooting, y):
                virtual = self._virtual_evaluation(y, -m)
                if virtual is not None:
                    self.n_virtual += 1
                    g, Gy, m, dm = virtual
        target = self.target(y)
        # d target / dy is margin * y / |y|: included so that the Jacobian is exact
        ny = float(np.linalg.norm(y))
        dt = self.margin * y / ny if ny > 0 else np.zeros_like(y)
        return np.append(g, m - target), np.vstack([Gy, dm - dt])

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[0]

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return self.evaluate_with_jacobian(y)[1]

    # ------------------------------------------------------------------ presentation
    def derived(self, y: np.ndarray) -> dict[str, float]:
        out = {self.free: float(y[-2]), self.parameter: float(y[-1])}
        try:
            res = self.shooting.simulate(np.asarray(y, dtype=float))
        except ShootingFailure:
            return out
        out["period"] = float(res.t)
        out["grazing_margin"] = res.grazing_function()
        out["n_impacts"] = float(res.n_impacts)
        return out

    def monitor_names(self) -> list[str]:
        return [self.free, self.parameter, "period", "grazing_margin", "n_impacts"]

    def restart_curve(self) -> dict[str, Any]:
        """What a restart record keeps to build this curve again."""
        return {**super().restart_curve(), "method": "augmented", "margin": self.margin}
