"""The Problem contract: what a system must declare to be continued by the engine.

The engine (:mod:`nsm_continuation.core.palc`) knows nothing about impacts. It continues the
solution curve of an under-determined system ``G(y) = 0`` with ``G: R^(n+1) -> R^n`` and asks the
problem, through optional hooks, for admissibility test functions, Floquet multipliers and derived
quantities at each point.

Adding a problem (the numbered contract, in the spirit of ``scipy.integrate.OdeSolver``):

1. Subclass :class:`Problem`; set ``name`` (the registry key used in YAML ``problem:``) and
   ``Parameters`` (a pydantic model validating the YAML ``parameters:`` block, with
   ``model_config = nsm_continuation.core.preflight.STRICT`` so that typos and ``true`` for a
   number are rejected; the registry refuses a registered problem whose model is not strict).
2. In ``__init__(self, params)`` store the validated parameters and set ``self.variables``: the
   names of the ``n + 1`` components of ``y``, and ``self.parameter``: the name of the component
   that plays the role of the continuation parameter (bounds apply to it).
3. Implement :meth:`Problem.residual` returning ``G(y)`` as a CasADi expression of a CasADi symbol
   ``y`` of length ``n + 1``. The engine builds compiled CasADi Functions for ``G`` and its exact
   Jacobian once per instance (:attr:`Problem.compiled`). A problem without a symbolic residual may
   instead override :meth:`Problem.evaluate` and :meth:`Problem.jacobian` with an exact Jacobian.
4. Everything else is optional: every member the core reads is declared on :class:`Problem`,
   typed, with a default and a docstring, in eight groups (the core never probes for an
   undeclared attribute):

   - *unknowns & parameter*: ``variables``, ``parameter``, ``algorithms`` (the continuation
     algorithms that can continue the problem, :mod:`nsm_continuation.algorithms.base`),
     ``energy_quantity``; charts: :meth:`rechart` (the same orbit in
     other unknowns, where the present ones degenerate: a forced hybrid system's section
     moved off an impact) and :meth:`in_chart` (the problem a point's ``chart`` belongs to);
   - *residual & Jacobian*: :meth:`residual` or :meth:`evaluate` / :meth:`jacobian`; with
     structure, :meth:`bordered_factor` / :meth:`residual_and_factor` (the engine's bordered
     systems, :mod:`nsm_continuation.core.bordered`; dense by default); the Jacobian's
     accuracy, :meth:`jacobian_noise` (rounding by default);
   - *starts*: :meth:`start_points`, ``start_adapter``, :meth:`preflight`,
     :meth:`parameter_bounds`;
   - *monitors*: declared once in ``monitors`` (:mod:`nsm_continuation.core.monitors`: each
     monitor's name, event kind, source, located or not, terminal or not), their values from
     continuous test functions (:meth:`admissibility`, > 0 where the point is
     admissible, a sign change raises its declared event kind, default ``grazing``),
     derived quantities (:meth:`derived`, bounded by ``continuation.bounds``; a bound ends the
     branch with its declared kind, default ``endpoint``), discrete signatures
     (:meth:`signature`, a change raises the signature monitor's kind), event functions
     (:meth:`event_functions`, continuous; a zero raises its declared kind, default
     ``grazing``, and the branch goes on), and ``event_kinds``:
     the kinds the problem family adds to the core ones
     (:data:`nsm_continuation.core.records.CORE_EVENT_KINDS`), each with its one-line meaning for
     ``report.md``;
   - *stability*: :meth:`floquet`, the non-trivial Floquet multipliers (trivial ones removed,
     see :mod:`nsm_continuation.core.floquet`), computed unless ``analysis.stability: false``;
     ``conservative`` (Krein signatures); :meth:`multipliers_near` (a few multipliers without
     the rest: Krein collisions are then located on the colliding pair alone);
   - *presentation*: ``presentation_class``, a
     :class:`~nsm_continuation.core.presentation.Presentation` subclass: the diagram's axes,
     labels, title and scale, CSV and report columns, figures, report extras and the periodic
     orbit at a point sampled in time, all pure functions of the results and of what the
     problem was built from (the contract's second part, apart from the numerics);
   - *capabilities* (:mod:`nsm_continuation.core.capabilities`, the contract's third part):
     :class:`~nsm_continuation.core.capabilities.Sweepable` (solved on a grid of the
     parameter instead of continued: ``sweep_seeds``, ``sweep_point``, ``sweep_preflight``)
     and :class:`~nsm_continuation.core.capabilities.Derivable` (:meth:`iterated`,
     :meth:`with_parameters`, :meth:`curve`, :meth:`period_multiple`,
     :meth:`restart_start`, :meth:`parameters_block` (the parameters written to the restart
     record; default the ``params`` model, dumped) and :meth:`curve_parameters` (the
     parameters a grazing curve may free or continue, in order of preference;
     default none)), each member defaulting to "cannot".
5. Register the class: in this repository in ``pyproject.toml`` under the entry-point group
   ``nsm_continuation.problems``; a third-party package does the same in its own metadata.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import casadi as ca
import numpy as np
from pydantic import BaseModel, TypeAdapter

from nsm_continuation.core.bordered import BorderedFactor, DenseBorderedFactor
from nsm_continuation.core.capabilities import Derivable, Sweepable
from nsm_continuation.core.casadi_buffers import BufferedFunction
from nsm_continuation.core.monitors import Monitors, legacy_monitors
from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.records import CORE_EVENT_KINDS, register_event_kinds

#: :meth:`Problem.jacobian_noise` of a Jacobian evaluated in closed form, in units of
#: ``eps |G_y|_2``: the rounding of a few operations per entry
JACOBIAN_ROUNDING = 10.0


class EvaluationError(RuntimeError):
    """A problem cannot evaluate its residual (or Jacobian, multipliers, ...) at a point, for a
    reason it can name: e.g. the simulator of a hybrid orbit reached its time limit, or an
    impact law left its domain. The engine never lets it escape: the step is retried smaller
    and, if the branch has to end, its termination reason is this message (the real cause),
    not a generic "non-finite residual"."""


@dataclass
class FloquetData:
    """Non-trivial Floquet multipliers at a point, and the accuracy check they came with.

    ``trivial_error`` is the distance of the removed trivial multiplier(s) from 1 (or the residual
    of the known trivial eigenvector): a free accuracy check in the spirit of BifurcationKit.
    """

    multipliers: np.ndarray
    trivial_error: float = 0.0
    #: 2-norm of the matrix whose eigenvalues are ``multipliers``: eigenvalues are only known to
    #: about ``eps * matrix_norm``, so the unit-circle test uses at least ``1e3 * eps * norm``
    matrix_norm: float = 1.0
    #: absolute uncertainty of the multipliers from the computation that produced the matrix
    #: (e.g. a simulator's integration error times the monodromy's norm): a multiplier within
    #: ``noise`` of the unit circle is never counted as having crossed it
    noise: float = 0.0


@dataclass
class KinkCrossing:
    """A kink of a branch crossed by the problem (:meth:`Problem.continue_beyond`): points of
    the branch between the last accepted point and the zero (``approach``, in order; they
    resolve the side where the residual's Jacobian blows up), the ``zero`` and the first point
    ``beyond`` it. ``beyond`` None: the zero is located but the branch cannot be continued
    beyond it, for the reason ``why`` (the engine ends the branch there, with the zero's event
    named as the reason, when it cannot step past it either)."""

    approach: list[np.ndarray]
    zero: np.ndarray
    beyond: np.ndarray | None
    why: str = ""


@dataclass
class Rechart:
    """The same solution in another chart (:meth:`Problem.rechart`): the ``problem`` whose
    unknowns are the new chart's (its :meth:`Problem.chart` names it), the point ``y`` and the
    unit ``tangent`` of the branch in them, and a one-line ``note`` for the report."""

    problem: Problem
    y: np.ndarray
    tangent: np.ndarray
    note: str


@dataclass
class StartPoint:
    """An initial guess ``y`` (corrected by Newton before continuation starts).

    ``direction`` > 0 continues first towards increasing parameter, < 0 towards decreasing,
    0 in both directions (the default). ``label`` names the branch in reports. ``info`` is
    kept with the branch; its ``found`` (what the problem's own search for the start found,
    e.g. the orbit a transient settled on) is added to the reason if the start fails.
    """

    y: np.ndarray
    label: str
    direction: int = 0
    info: dict[str, Any] = field(default_factory=dict)


class CompiledResidual:
    """CasADi Functions for ``G`` and its exact Jacobian ``dG/dy``, built once per problem.

    Evaluated through CasADi's function buffers
    (:class:`~nsm_continuation.core.casadi_buffers.BufferedFunction`): the outputs are written
    straight into numpy arrays. Converting a ``DM`` result with ``np.asarray`` goes through a
    Python list of its elements and cost ten times the evaluation itself for a dense
    1000 x 1001 Jacobian (70 ms against 7 ms; 48 % of a continuation run of the 1000-dof
    chain). The Jacobian is densified at construction (the engine's linear algebra is dense);
    it comes out as the transpose of a C array (the buffer writes column-major)."""

    def __init__(self, G: ca.Function, J: ca.Function, GJ: ca.Function, n: int) -> None:
        self.G, self.J, self.GJ, self.n = G, J, GJ, n
        self._calls = {name: BufferedFunction(f) for name, f in (("G", G), ("J", J),
                                                                 ("GJ", GJ))}

    def _call(self, name: str, y: np.ndarray) -> Any:
        x = np.asarray(y, dtype=float).reshape(-1)
        if x.size != self.n + 1:
            raise ValueError(f"residual evaluated at {x.size} unknowns, expects {self.n + 1}")
        return self._calls[name](x)

    def residual(self, y: np.ndarray) -> np.ndarray:
        return self._call("G", y).ravel()

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return self._call("J", y)

    def both(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, jac = self._call("GJ", y)
        return g.ravel(), jac


class Problem(Sweepable, Derivable, ABC):
    """Base class of all problems: the declared contract (module docstring).

    Every member the core (engines, runner, results, report, plots) reads is declared here,
    typed, with a default; a subclass overrides what it needs. Class-level declarations
    (``monitors``, ``event_kinds``) are checked when the subclass is defined: every event kind
    a problem raises is a core kind or one it declares.
    """

    # == unknowns & parameter ==================================================================
    #: the registry key (YAML ``problem:``)
    name: ClassVar[str] = ""
    #: pydantic model validating the YAML ``parameters:`` block
    Parameters: ClassVar[type[BaseModel]]
    #: the validated parameters of this instance (set by ``__init__``)
    params: BaseModel
    #: symbolic type used to build the residual: "SX" (small, fast calls) or "MX" (large, dense)
    symbolic: str = "SX"
    #: names of the ``n + 1`` unknowns ``y`` (set by ``__init__``)
    variables: list[str]
    #: the unknown that is the continuation parameter (window bounds apply to it)
    parameter: str
    #: the continued quantity of a case that names none (``continuation.parameter``); None:
    #: :attr:`parameter` itself (the chain: ``omega``, which it maps to its unknown ``T``)
    case_parameter: ClassVar[str | None] = None
    #: names of the continuation algorithms that can continue this problem
    #: (:data:`nsm_continuation.algorithms.registry.ALGORITHMS`: ``palc``, ``lattice``,
    #: ``pycont``, ...); the first is the default of YAML ``continuation.algorithm``
    algorithms: ClassVar[tuple[str, ...]] = ("palc",)
    #: the derived quantity that ``continuation.max_energy`` bounds (None: the problem has no
    #: energy, and ``max_energy`` is refused; ``continuation.bounds`` bounds any monitor)
    energy_quantity: ClassVar[str | None] = None
    #: None, or a residual (relative to ``1 + |y|_inf``) at which the corrector accepts an
    #: iterate once three have reached it (the smallest), whatever the Newton step
    #: (:meth:`~nsm_continuation.core.palc.engine.ContinuationEngine.correct`): for a family
    #: known to be nearly singular along its own orbits (the period-``k`` orbits at a weak
    #: resonance, :mod:`~nsm_continuation.algorithms.resonance_switching`), where the step
    #: is the residual's noise over a tiny singular value and never meets ``newton_tol``
    residual_floor: float | None = None

    def __init__(self, params: BaseModel) -> None:
        self.params = params

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Register the family's event kinds and check that every kind the class's monitors
        raise is declared (a core kind or one of ``event_kinds``)."""
        super().__init_subclass__(**kwargs)
        legacy_monitors(cls)
        register_event_kinds(cls.event_kinds, cls.__qualname__)
        known = {**CORE_EVENT_KINDS, **cls.event_kinds}
        for kind in [*cls.monitors.kinds(), cls.monitors.default_kind]:
            if kind not in known:
                raise TypeError(f"{cls.__qualname__}: event kind {kind!r} is neither a core "
                                "kind nor declared in event_kinds")
        if cls.signature is not Problem.signature and cls.monitors.signature_kind is None:
            raise TypeError(f"{cls.__qualname__}: signature() is overridden but no signature "
                            "monitor is declared (monitors: the event kind of a change)")
        if "sweep" in cls.algorithms and not cls.can_sweep():
            raise TypeError(f"{cls.__qualname__}: 'sweep' is among its algorithms but "
                            "sweep_seeds() and sweep_point() are not both implemented")

    # == residual & Jacobian ===================================================================
    @abstractmethod
    def residual(self, y: Any) -> Any:
        """``G(y)`` as a CasADi expression of the symbol ``y`` (length ``n + 1``)."""

    @property
    def dim(self) -> int:
        """Number of unknowns ``n + 1``."""
        return len(self.variables)

    @property
    def parameter_index(self) -> int:
        """Index of the continuation parameter in ``y``."""
        return self.variables.index(self.parameter)

    @cached_property
    def compiled(self) -> CompiledResidual:
        """CasADi Functions of ``G`` and its exact Jacobian, built once from :meth:`residual`
        (a problem that evaluates numerically overrides this with ``None``)."""
        sym = ca.SX if self.symbolic == "SX" else ca.MX
        y = sym.sym("y", self.dim)
        g = self.residual(y)
        n = int(g.shape[0])
        if n != self.dim - 1:
            raise ValueError(
                f"problem {self.name!r}: residual has {n} equations for {self.dim} unknowns "
                "(continuation needs n equations in n + 1 unknowns)"
            )
        g = ca.densify(g)
        jac = ca.densify(ca.jacobian(g, y))
        G = ca.Function("G", [y], [g])
        J = ca.Function("J", [y], [jac])
        GJ = ca.Function("GJ", [y], [g, jac])
        return CompiledResidual(G=G, J=J, GJ=GJ, n=n)

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        """``G(y)`` (length ``n``)."""
        return self.compiled.residual(y)

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        """``G_y(y)`` (``n x (n + 1)``), exact."""
        return self.compiled.jacobian(y)

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(G(y), G_y(y))`` in one call (override together with evaluate/jacobian)."""
        return self.compiled.both(y)

    def jacobian_noise(self, y: np.ndarray, jacobian: np.ndarray) -> float:
        """How far the computed ``G_y(y)`` (``jacobian``, as :meth:`jacobian` gave it) may be
        from the exact one, in the 2-norm. The tangent's parameter component is known only to
        this times the parameter's row of the inverse bordered matrix: below that, its sign
        change is no fold (:mod:`nsm_continuation.core.palc.folds`, (F1)). Default: the
        rounding of a Jacobian evaluated in closed form, ``JACOBIAN_ROUNDING eps |G_y|_2``; a
        problem whose Jacobian is integrated (a shooting problem: the integrator's tolerance)
        overrides it."""
        return JACOBIAN_ROUNDING * float(np.finfo(float).eps) * float(np.linalg.norm(jacobian, 2))

    def bordered_factor(self, y: np.ndarray, row: np.ndarray,
                        jacobian: np.ndarray | None = None) -> BorderedFactor:
        """The factorisation of the bordered matrix ``[G_y(y); row^T]`` the engine solves with
        (Newton, tangent) and whose determinant is its branch-point test function
        (:mod:`nsm_continuation.core.bordered`). Default: the dense matrix (``jacobian`` if the
        caller has it, else :meth:`jacobian`). A problem with structure overrides it."""
        return DenseBorderedFactor(self.jacobian(y) if jacobian is None else jacobian, row)

    def residual_and_factor(self, y: np.ndarray, row: np.ndarray
                            ) -> tuple[np.ndarray, BorderedFactor]:
        """``G(y)`` and :meth:`bordered_factor` (one Newton iteration). Default: ``G`` and
        ``G_y`` in one evaluation (:meth:`evaluate_with_jacobian`)."""
        g, J = self.evaluate_with_jacobian(y)
        return g, self.bordered_factor(y, row, J)

    # == starts ================================================================================
    #: validator of the YAML ``start:`` block, run by ``validate`` before the problem's
    #: preflight so that a malformed start is refused naming its key (None: no schema)
    start_adapter: ClassVar[TypeAdapter[Any] | None] = None

    def start_points(self, start: Any, window: tuple[float | None, float | None] = (None, None)
                     ) -> list[StartPoint]:
        """Initial guesses from the YAML ``start:`` block; ``window`` = parameter bounds."""
        raise ValueError(f"problem {self.name!r} does not generate starting points")

    def preflight(self, start: Any, window: tuple[float | None, float | None],
                  max_points: int) -> None:
        """Check everything about ``start`` (the YAML ``start:`` block) and the sizes of this
        instance that can be checked **without computing**: keys, sizes, ranges, and an estimate
        of the memory and time a run of ``max_points`` points per direction would take.

        Raise :class:`ValueError` with one line naming the key (``start.mode: 7 exceeds the 5
        modes of the chain``) or the limit (``parameters.chain.n: 10000 dofs need ~4.8 GB ...;
        limit 2 GB``). ``nsm-continuation validate`` runs exactly this check and ``run`` runs it
        before anything is computed or written, so the two agree on every input. Must be cheap
        (no simulation, no continuation); the default accepts everything.
        """
        return None

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """Convert user bounds on ``name`` (e.g. ``omega``) to bounds on ``self.parameter``."""
        if name != self.parameter:
            raise ValueError(f"continuation.parameter: cannot continue in {name!r}; this "
                             f"problem continues in {self.parameter!r}")
        return lo, hi

    def parameter_orientation(self, name: str) -> int:
        """+1 if the internal parameter ``self.parameter`` grows with the continued parameter
        ``name`` (YAML ``continuation.parameter``), -1 if it falls (the chain continued in
        ``omega`` has the period ``T = 2 pi / omega`` inside): the runner turns a
        ``direction`` meant along ``name`` into one along the internal parameter."""
        return 1

    # == monitors ==============================================================================
    #: event kinds this problem family raises besides the core ones
    #: (:data:`~nsm_continuation.core.records.CORE_EVENT_KINDS`): kind -> one-line meaning, written
    #: in ``report.md`` under "What the events mean"
    event_kinds: ClassVar[dict[str, str]] = {}
    #: what the problem watches along a branch and the event kind each change raises
    #: (:mod:`nsm_continuation.core.monitors`): admissibility tests (undeclared ones raise
    #: ``grazing``), event functions, bounds on quantities (undeclared ones end the branch
    #: with ``endpoint``), the signature (declared only by a problem with :meth:`signature`)
    #: and the quantities watched for an ``asymptote`` (default: the energy)
    monitors: ClassVar[Monitors] = Monitors()

    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        """Named continuous test functions, ``>= 0`` where ``y`` is admissible (physically
        realisable); a sign change is located and raises the kind :attr:`monitors` gives it."""
        return {}

    def event_functions(self, y: np.ndarray) -> dict[str, float]:
        """Named continuous scalar functions of the point ``y`` whose zeros are events that do
        **not** end the branch (e.g. the grazing margin of a near approach of a hybrid orbit).

        Unlike :meth:`admissibility` the sign carries no meaning of admissibility. Where a
        function changes sign between two accepted points (both values finite) the engine
        locates the zero on the curve (Illinois, to ``event_tol`` in arclength) and records an
        event of the kind :attr:`monitors` gives it (default ``grazing``) with ``data``
        ``{'function', 'value_before', 'value_after'}``; a value missing or NaN at either end
        raises nothing. Steps are capped so that a function is not carried far past a zero
        (as admissibility tests are). Evaluated at every analysed point; default: none."""
        return {}

    def continue_beyond(self, name: str, y: np.ndarray, tangent: np.ndarray, value: float,
                        ds: float, tol: float) -> KinkCrossing | None:
        """Where the branch has a kink at a zero of the event function ``name`` (the residual
        is continuous but not differentiable there, e.g. a grazing of a hybrid orbit, whose
        return map has a square-root singularity), a :class:`KinkCrossing`: points of the
        branch approaching the zero, the zero itself and a first point of the branch beyond it
        at arclength about ``ds``, computed with the problem's own local parametrisation, each
        converged to ``tol``.

        ``y`` is a point of the branch next to the zero (the located zero, or the last accepted
        point when the engine could not step across), ``tangent`` the direction of travel
        there and ``value`` the function's value on the side the branch comes from. The engine
        records the event at ``y_zero`` and goes on from ``y_beyond``. A crossing without
        ``beyond`` (and its ``why``): the zero is located but no branch beyond it can be
        followed (several families meet there, or the one beyond is not isolated); if the
        engine cannot step past the zero either, the branch ends at it with the zero's event
        and that reason. None (the default): the branch is smooth through the zero, or the
        problem cannot resolve it there."""
        return None

    def rechart(self, y: np.ndarray, tangent: np.ndarray) -> Rechart | None:
        """The point ``y`` (unit tangent ``tangent``) in new unknowns where the present ones are
        about to degenerate, or None (the default: one chart for the whole branch). The engine
        asks at every accepted point; after a move it continues with ``Rechart.problem``, whose
        :meth:`chart` every later point records (``Point.chart``). Multipliers, derived
        quantities and event functions are those of the orbit, the same in every chart."""
        return None

    def chart(self) -> dict[str, float] | None:
        """The numbers that name the chart of this problem's unknowns where it is not the
        declared one (e.g. ``{"phase": 3.46}``, a moved section), else None."""
        return None

    def in_chart(self, chart: dict[str, float] | None) -> Problem:
        """The problem whose unknowns are those of ``chart`` (a ``Point.chart``; None: the
        declared one): what reads a point's ``y`` after the run (restarts, orbit figures) asks
        it first."""
        return self

    def derived(self, y: np.ndarray) -> dict[str, float]:
        """Named derived quantities (period, frequency, energy, ...) written with each point."""
        return {}

    def monitor_names(self) -> list[str]:
        """Names of the derived quantities (:meth:`derived`) a ``continuation.bounds`` entry may
        name; a bound on any other name is refused before computing."""
        return []

    def signature(self, y: np.ndarray) -> str | None:
        """A discrete signature of the solution at ``y`` (e.g. the event sequence of a hybrid
        orbit), or None where it is undefined; a change between two points is located and
        raises the kind of the signature monitor. Called only when :attr:`monitors` declares
        one (:func:`~nsm_continuation.core.monitors.signature`)."""
        return None

    def locate_signature(self, before: str | None, after: str | None) -> bool:
        """Whether a change ``before -> after`` of the signature is located by bisection
        (True) or recorded at the end of its step (False: e.g. a tolerance-dependent count)."""
        return True

    def all_event_kinds(self) -> dict[str, str]:
        """Every kind a run of this problem may raise: core kinds and ``event_kinds``, each
        with its one-line meaning."""
        return {**CORE_EVENT_KINDS, **self.event_kinds}

    # == stability =============================================================================
    @property
    def conservative(self) -> bool:
        """Whether the return map is symplectic (a conservative family): its multipliers then
        carry Krein signatures, an instability window opens only where two of opposite
        signature collide, and the engine refines steps only near such collisions
        (``settings.krein_step_control``). Default: False (the generic motion check
        on every multiplier near the circle)."""
        return False

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """Non-trivial Floquet multipliers at ``y`` (``tangent``: unit tangent of the branch);
        None where there are none. Not called when ``analysis.stability`` is false."""
        return None

    def multipliers_near(self, y: np.ndarray, tangent: np.ndarray, guesses: np.ndarray
                         ) -> np.ndarray | None:
        """The multipliers at ``y`` nearest to ``guesses`` (one each, distinct), computed
        without the rest of the spectrum; None if the problem cannot (the default), or could
        not converge. The engine locates a Krein collision of a conservative family on the
        pair alone with it (:meth:`nsm_continuation.core.palc.crossings.CrossingLocator.\
_locate_collision`)."""
        return None

    # == presentation ==========================================================================
    #: how the results are shown: axes, labels, CSV and report columns, figures, orbits
    #: (:class:`~nsm_continuation.core.presentation.Presentation`, built for each problem
    #: instance by :attr:`presentation`)
    presentation_class: ClassVar[type[Presentation]] = Presentation
    #: the figures (branch diagram, multipliers, the presentation's own figures, orbits) depend
    #: only on the run's results and on what the problem was built from, not on state the
    #: computation leaves in the problem: the command line may then draw them in a process
    #: forked before the computation, with its own copy of the problem
    #: (:class:`~nsm_continuation.figures.process.FigureProcess`). Default False: a problem
    #: that keeps run data for its figures is drawn from the problem the run used. The
    #: bundled problems declare True (``tests/output/test_figure_process.py`` compares their
    #: figures).
    figures_from_inputs: ClassVar[bool] = False

    @property
    def presentation(self) -> Presentation:
        """This problem's :attr:`presentation_class`, reading this instance."""
        return self.presentation_class(self)
