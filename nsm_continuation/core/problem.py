"""The Problem contract: what a system must declare to be continued by the engine.

The engine (:mod:`nsm_continuation.core.palc`) knows nothing about impacts. It continues the
solution curve of an under-determined system ``G(y) = 0`` with ``G: R^(n+1) -> R^n`` and asks the
problem, through optional hooks, for admissibility test functions, Floquet multipliers and derived
quantities at each point.

Adding a problem (the numbered contract, in the spirit of ``scipy.integrate.OdeSolver``):

1. Subclass :class:`Problem`; set ``name`` (the registry key used in YAML ``problem:``) and
   ``Parameters`` (a pydantic model validating the YAML ``parameters:`` block; use
   ``model_config = ConfigDict(extra="forbid")`` so typos are rejected).
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
     systems, :mod:`nsm_continuation.core.bordered`; dense by default);
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
   - *sweeps* (an optional capability, :class:`~nsm_continuation.algorithms.sweep.Sweep`, YAML
     ``continuation.algorithm: sweep``): a problem that lists ``"sweep"`` in ``algorithms``
     implements :meth:`sweep_seeds` (the sweeps of its ``start:`` block, :class:`SweepSeed`)
     and :meth:`sweep_point` (the solution at one grid value of the parameter from the state
     the previous value ended in: one :class:`~nsm_continuation.core.records.Point`, or a list of
     them, e.g. the section returns recorded by a brute-force bifurcation diagram,
     :mod:`nsm_continuation.hybrid.brute_force`); :meth:`sweep_preflight` checks a sweep's
     start block before computing (default: :meth:`preflight`). A problem with a residual may
     be both continued and swept; one without (:class:`~nsm_continuation.algorithms.base.
     SweepProblem`) is only swept. The defaults raise: the class check refuses ``"sweep"`` in
     ``algorithms`` without :meth:`sweep_seeds` and :meth:`sweep_point`;
   - *restart & two-parameter curves*: :meth:`period_multiple`, :meth:`iterated`,
     :meth:`with_parameters`, :meth:`restart_start`, :meth:`parameters_block` (the
     parameters written to the restart record; default the ``params`` model, dumped) and
     :meth:`curve_parameters` (the parameters a grazing curve may free or continue, in order
     of preference; default none).
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
from nsm_continuation.core.casadi_buffers import BufferedFunction
from nsm_continuation.core.monitors import Monitors, legacy_monitors
from nsm_continuation.core.presentation import Presentation
from nsm_continuation.core.records import CORE_EVENT_KINDS, Point, register_event_kinds


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
    ``beyond`` it."""

    approach: list[np.ndarray]
    zero: np.ndarray
    beyond: np.ndarray


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


@dataclass
class StartPoint:
    """An initial guess ``y`` (corrected by Newton before continuation starts).

    ``direction`` > 0 continues first towards increasing parameter, < 0 towards decreasing,
    0 in both directions (the default). ``label`` names the branch in reports.
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


class Problem(ABC):
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

    # == sweeps (optional capability; :class:`nsm_continuation.algorithms.sweep.Sweep`) ==
    @classmethod
    def can_sweep(cls) -> bool:
        """Whether the class implements the sweep hooks (:meth:`sweep_seeds` and
        :meth:`sweep_point` overridden): the capability that ``"sweep"`` in ``algorithms``
        declares (checked when the class is defined)."""
        return (cls.sweep_seeds is not Problem.sweep_seeds
                and cls.sweep_point is not Problem.sweep_point)

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
        records the event at ``y_zero`` and goes on from ``y_beyond``. None (the default): the
        branch is smooth through the zero, or the problem cannot resolve it there."""
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
    #: only on
    #: the run's results and on what the problem was built from, not on state the computation
    #: leaves in the problem: the command line may then draw them in a process forked before
    #: the computation, with its own copy of the problem
    #: (:class:`~nsm_continuation.figures.process.FigureProcess`). Default False: a problem
    #: that keeps run data for its figures is drawn from the problem the run used. The
    #: bundled problems declare True (``tests/test_figure_process.py`` compares their figures).
    figures_from_inputs: ClassVar[bool] = False

    @property
    def presentation(self) -> Presentation:
        """This problem's :attr:`presentation_class`, reading this instance."""
        return self.presentation_class(self)

    # == restart & branch switching (:mod:`nsm_continuation.cases.restart`) ===============
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

    def restart_start(self, y: np.ndarray) -> Any:
        """The problem's own ``start:`` block that starts from the unknowns ``y`` (e.g. a
        hybrid ``{guess: {...}}``): a restart runs :meth:`preflight` on it, so the checks of
        an ordinary start (window, state, budget) apply. None: only the continued parameter's
        value is checked against the window."""
        return None
