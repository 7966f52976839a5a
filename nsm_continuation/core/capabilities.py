"""The optional capabilities of a Problem, declared as two groups with their defaults.

A :class:`~nsm_continuation.core.problem.Problem` is continued from its numerics alone; these
groups say what more it can do, each member defaulting to "cannot":

* :class:`Sweepable`: solved at each value of a grid of its parameter instead of continued
  (:class:`~nsm_continuation.algorithms.sweep.Sweep`, YAML ``continuation.algorithm: sweep``): a
  problem that lists ``"sweep"`` in ``algorithms`` implements :meth:`Sweepable.sweep_seeds`
  and :meth:`Sweepable.sweep_point` (checked when its class is defined);
* :class:`Derivable`: other problems derived from this one: the orbits of several base
  periods (:meth:`Derivable.iterated`, a switch at a period doubling), the same problem at other
  parameter values (:meth:`Derivable.with_parameters`, located two-parameter curves), a curve of
  codimension-one points by the problem's own augmented system (:meth:`Derivable.curve`), and
  what a restart needs to rebuild it (:meth:`Derivable.parameters_block`,
  :meth:`Derivable.restart_start`, :meth:`Derivable.period_multiple`).

Both are composed into :class:`~nsm_continuation.core.problem.Problem`, so a plugin overrides
what it can do and the run layers ask the declared members (no attribute is probed).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel

if TYPE_CHECKING:
    from nsm_continuation.core.problem import Problem
    from nsm_continuation.core.records import Point


@dataclass
class SweepSeed:
    """One sweep (:meth:`Problem.sweep_seeds`): its label, the state the first grid value
    starts from (the problem's own object, e.g. a state of a time stepper), and its direction
    (+1: increasing parameter, -1: decreasing, 0: as ``continuation.direction``, both giving
    two sweeps). ``origin``: the parameter value the sweep starts at, like a continuation from
    its start (the grid values on the sweep's side of it, preceded by ``origin`` itself when it
    is not a grid value); None: the whole grid (e.g. a frequency sweep)."""

    label: str
    state: Any = None
    direction: int = 0
    info: dict[str, Any] = field(default_factory=dict)
    origin: float | None = None


class Sweepable:
    """Solved at each value of a grid of the parameter (the module docstring)."""

    name: str
    algorithms: tuple[str, ...]

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """The problem's checks of its start block (:meth:`Problem.preflight`)."""

    @classmethod
    def can_sweep(cls) -> bool:
        """Whether the class implements the sweep hooks (:meth:`sweep_seeds` and
        :meth:`sweep_point` overridden): the capability that ``"sweep"`` in ``algorithms``
        declares (checked when the class is defined)."""
        return (cls.sweep_seeds is not Sweepable.sweep_seeds
                and cls.sweep_point is not Sweepable.sweep_point)

    def sweep_seeds(self, start: Any, window: tuple[float | None, float | None]
                    ) -> list[SweepSeed]:
        """The sweeps of the YAML ``start:`` block (``window``: the parameter's bounds), for
        the sweep algorithm. Raises :class:`ValueError` when they cannot be built (the run
        records a failed start). Default: the problem cannot be swept."""
        raise ValueError(f"problem {self.name!r} cannot be swept: it does not implement "
                         "sweep_seeds() and sweep_point() (continuation.algorithm: one of "
                         f"{', '.join(self.algorithms)})")

    def sweep_point(self, seed: SweepSeed, value: float, state: Any
                    ) -> tuple[Point | list[Point], Any]:
        """The solution at the parameter ``value`` of the sweep ``seed``, from ``state`` (the
        seed's at the first value, then what the previous call returned): one point (its
        ``y[parameter_index]`` is ``value``) or a list of points (e.g. the section returns a
        brute-force bifurcation diagram records at one value; the branch is then drawn with
        markers, not lines), and the state the next value starts from. Raises
        :class:`EvaluationError` (or a numerical error) if the solution cannot be computed:
        the sweep then ends there with that reason. A problem may note what happened at a
        value in ``seed.info`` (copied into the branch's ``info``, e.g. failures it recovered
        from). Default: the problem cannot be swept."""
        raise ValueError(f"problem {self.name!r} cannot be swept: it does not implement "
                         "sweep_point()")

    def sweep_preflight(self, start: Any, window: tuple[float | None, float | None],
                        max_points: int) -> None:
        """:meth:`preflight` for a run of the sweep algorithm (``max_points`` grid values per
        sweep): the same promise (one line naming the key, no computation). Default:
        :meth:`preflight`; a problem that is both continued and swept overrides it where its
        start block means something else for a sweep."""
        self.preflight(start, window, max_points)


class Derivable:
    """Other problems derived from this one, and what a restart needs (the module
    docstring)."""

    params: BaseModel

    def period_multiple(self) -> int:
        """How many base periods an orbit of this instance spans (the returns to the section of
        a hybrid orbit, ``start.returns``); stored in the restart record of each run."""
        return 1

    def iterated(self, multiple: int) -> Problem | None:
        """A new instance of this problem, with the same parameters, unknowns and continued
        parameter, for orbits of ``multiple`` base periods (the residual of the
        ``multiple``-times iterated return map); its solutions include this instance's. A
        switch at a period doubling continues ``iterated(2 * period_multiple())``. None: the
        problem cannot represent them (the switch is refused before computing)."""
        return None

    def with_parameters(self, values: dict[str, float]) -> Problem | None:
        """A new instance of this problem with the parameters ``values`` (name -> value)
        changed and the same unknowns, continued parameter and period multiple: the base
        problem at one value of the second parameter of a two-parameter curve
        (:mod:`nsm_continuation.algorithms.curves`). None: the problem cannot (the curve is refused
        before computing)."""
        return None

    def parameters_block(self) -> dict[str, Any] | None:
        """The instance's parameters as the YAML ``parameters:`` block that rebuilds it
        (JSON values), written to the restart record of every run (``report.json``'s
        ``restart.parameters``, :func:`nsm_continuation.runs.restart_record.restart_block`) so
        that a restart builds the same problem. Default: ``params`` (the validated ``Parameters``
        model) dumped in JSON mode; None if ``params`` is not a pydantic model (the record then
        keeps the case's ``parameters:`` block as written)."""
        if isinstance(self.params, BaseModel):
            return self.params.model_dump(mode="json")
        return None

    def curve_parameters(self) -> list[str]:
        """The parameters of this problem that a grazing curve through a grazing event of its
        orbits may free or continue (``start: {curve: grazing, free: ...}`` with
        ``continuation.parameter``; the augmented system C1 of
        :class:`~nsm_continuation.hybrid.codim1.GrazingCurve`, which continues the orbits of
        hybrid problems), in order of preference as the curve's second parameter.

        Read by the ``continue_from_here`` hints of ``report.json`` / ``report.md``
        (:func:`nsm_continuation.output.files.hint_context`,
        :func:`nsm_continuation.output.report.continue_hints`: at a grazing event of a run continued
        in one of them, the curve freeing the continued parameter and continuing the first
        other one) and by a restart (:func:`nsm_continuation.cases.restart.configure` /
        :func:`~nsm_continuation.cases.restart.grazing_curve`: a grazing curve is continued by C1
        only for a problem that declares some, and ``start.free`` / ``continuation.parameter``
        must be among them). Default: none (``[]``): the problem's grazing events restart the
        orbit, and a grazing curve of it can only be located (``start.method: located``,
        :meth:`with_parameters`)."""
        return []

    def curve(self, kind: str, free: str, parameter: str, margin: float | None = None
              ) -> Problem | None:
        """The two-parameter curve of ``kind`` points through this problem's orbits, continued
        by the problem's own augmented system with ``free`` solved for and ``parameter``
        continued (``margin``: the curve's own offset, None: its default); ``ValueError`` (one
        line) where it cannot be built. Default None: no augmented system for ``kind`` (its
        curves are located ones, :class:`~nsm_continuation.algorithms.curves.LocatedCurve`)."""
        return None

    def restart_start(self, y: np.ndarray) -> Any:
        """The problem's own ``start:`` block that starts from the unknowns ``y`` (e.g. a
        hybrid ``{guess: {...}}``): a restart runs :meth:`preflight` on it, so the checks of
        an ordinary start (window, state, budget) apply. None: only the continued parameter's
        value is checked against the window."""
        return None
