"""The presentation part of the Problem contract: how a problem's results are shown.

A :class:`~nsm_continuation.core.problem.Problem` declares its numerics (residual and Jacobian,
starts, monitors, stability); its ``presentation_class``, a subclass of :class:`Presentation`,
declares what the outputs show: the branch diagram's axes, labels, title and scale, the first
columns of the CSV and of the report's event table, the problem's own figures and report facts,
and the periodic orbit at a point sampled in time (drawn by ``output.orbits``,
:mod:`nsm_continuation.figures.orbits`). Every member is a pure function of the results and of
what the problem was built from: it reads the problem (:attr:`Presentation.problem`) and never
writes into it, so the figures may be drawn by a process forked before the computation
(:class:`~nsm_continuation.figures.process.FigureProcess`).

Each member has a default here; a family overrides what it shows differently.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from nsm_continuation.core.records import OrbitTrace
from nsm_continuation.core.symbols import quantity_label

if TYPE_CHECKING:
    from nsm_continuation.core.problem import Problem


class Presentation:
    """How the results of :attr:`problem` are shown (the module docstring); built by
    :attr:`Problem.presentation <nsm_continuation.core.problem.Problem.presentation>`."""

    #: title of the branch diagram (``fep.png``)
    diagram_title: ClassVar[str] = "Branch diagram"
    #: preferred scale of the branch diagram's vertical axis: "linear" or "log" (log drops
    #: values <= 0, and is used only where the values span more than a decade)
    diagram_yscale: ClassVar[str] = "linear"
    #: the branches are two-parameter curves (each point a codimension-one point of a base
    #: family): drawn as curves with their start, not with the stability legend
    two_parameter: ClassVar[bool] = False

    def __init__(self, problem: Problem) -> None:
        #: the problem whose results are shown
        self.problem = problem

    @property
    def fep_axes(self) -> tuple[str, str]:
        """Quantities (derived quantities or unknowns) on the branch diagram's axes and, for
        the first, on the multiplier plots' horizontal axis. Default: the parameter and the
        first other unknown."""
        pr = self.problem
        others = [v for v in pr.variables if v != pr.parameter]
        return (pr.parameter, others[0] if others else pr.parameter)

    @property
    def fep_labels(self) -> tuple[str, str]:
        """Axis labels of the two ``fep_axes`` quantities (default: :meth:`label`)."""
        x, y = self.fep_axes
        return (self.label(x), self.label(y))

    @property
    def quantity_labels(self) -> dict[str, str]:
        """Axis labels of quantities (unknowns, parameters, derived quantities) the family
        declares: words and symbol in mathtext, with units where there are some (e.g.
        ``{"omega": "forcing frequency $\\omega$"}``). Default none."""
        return {}

    def label(self, name: str) -> str:
        """The axis label of quantity ``name``: declared (:attr:`quantity_labels`), else the
        symbol its identifier spells, else its words
        (:func:`~nsm_continuation.core.symbols.quantity_label`)."""
        return quantity_label(name, self.quantity_labels)

    def event_styles(self) -> dict[str, tuple[str, str, str] | None]:
        """How the family's own event kinds are drawn: ``kind -> (marker, colour, name)``
        (matplotlib marker and colour, the name in the legend), or None for a kind the
        figures show otherwise (then not as a marker). Kinds not listed take the styles of
        :mod:`nsm_continuation.figures.styles` (a default marker for a kind it does not
        know). Default none."""
        return {}

    def closed_forms(self, x_range: tuple[float, float], branches: list[Any]
                     ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """Known closed forms in the branch diagram's axes over ``x_range``: ``(x, y,
        label)`` curves drawn thin over the computed branches (NaN: a gap). Default none."""
        return []

    def curve_closed_forms(self, kind: str, parameter: str, free: str,
                           x_range: tuple[float, float]
                           ) -> list[tuple[np.ndarray, np.ndarray, str]]:
        """Known closed forms of the two-parameter curve of ``kind`` points (``grazing``,
        ``period_doubling``, ...) in the plane ``(parameter, free)`` over ``x_range`` of
        ``parameter``: ``(x, y, label)`` curves drawn over a computed curve of this family
        (the curve's presentation asks its base problem's). Default none."""
        return []

    def branch_name(self, branch: Any) -> str:
        """A branch's name in a legend (default its label, identifiers in words)."""
        return str(branch.label).replace("_", " ")

    def start_point(self, branch: Any) -> Any:
        """The point ``branch`` was started from: the one at arclength 0 (the nearest), or
        None for a branch without points. A two-parameter curve's presentation marks it."""
        return min(branch.points, key=lambda p: abs(p.s)) if branch.points else None

    def point_fill(self) -> tuple[str, str, str] | None:
        """Points of the branch diagram marked filled or hollow: ``(derived key, name of
        filled, name of hollow)``, filled where the derived quantity is positive (e.g. a
        steady forced response). Default None: the branches are lines."""
        return None

    @property
    def csv_head(self) -> list[str]:
        """First columns of ``branch_<id>.csv`` (derived quantities or unknowns); the other
        derived quantities, tests, unknowns and multipliers follow. Default: the parameter
        and the diagram axes."""
        return list(dict.fromkeys([self.problem.parameter, *self.fep_axes]))

    @property
    def event_columns(self) -> list[str]:
        """Quantities shown for each event in the table of ``report.md`` (default:
        ``csv_head``)."""
        return list(self.csv_head)

    def legend_handles(self) -> list[Any]:
        """Extra legend entries (matplotlib artists) for what :meth:`plot_decorations`
        draws."""
        return []

    def plot_decorations(self, ax: Any, x_range: tuple[float, float],
                         branches: list[Any]) -> None:
        """Draw problem-specific references on the branch diagram (e.g. linear frequencies);
        ``branches`` are the run's :class:`~nsm_continuation.core.records.Branch` records. A pure
        function of its arguments (no state shared with other hooks)."""
        return None

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Write problem-specific figures into ``out_dir``; return their file names."""
        return []

    def orbit(self, y: np.ndarray, periods: int = 1) -> OrbitTrace | None:
        """The periodic orbit at the unknowns ``y``, sampled densely over ``periods`` periods
        from ``t = 0`` (the state ``y`` describes): named signals with their axis labels,
        marked instants (impacts), intervals (sticking) and the family's default views
        (``time``, ``phase``, optionally ``manifold``), drawn by the orbit figures of
        ``output.orbits`` (:mod:`nsm_continuation.figures.orbits`) and ``Result.orbit``. May
        raise :class:`~nsm_continuation.core.problem.EvaluationError` where the orbit cannot be
        computed (the figure skips that point). Default None: the problem has no orbit figures
        (``output.orbits`` is refused before computing). Its ``views`` are those
        :meth:`orbit_view_names` declares."""
        return None

    def orbit_view_names(self) -> tuple[str, ...]:
        """The views (``time``, ``phase``, ``manifold``) that the traces of :meth:`orbit` have:
        what ``output.orbits.views`` and ``Result.plot_orbits(view=...)`` may ask of this
        problem, checked before computing. Default none (no orbit figures)."""
        return ()

    @property
    def draws_orbits(self) -> bool:
        """:meth:`orbit` is implemented (``output.orbits`` may be asked for)."""
        return type(self).orbit is not Presentation.orbit

    def summary(self) -> dict[str, Any]:
        """Problem facts for the report (linear frequencies, coefficients, ...)."""
        return {}

    def warnings(self) -> list[str]:
        """Warnings about the instance (e.g. a violated assumption) to put in the report."""
        return []

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Problem-specific results added to ``report.json`` under ``problem_results``: a pure
        function of the branches (no state shared with other hooks)."""
        return {}
