"""The Problem contract: what a system must declare to be continued by the engine.

The engine (:mod:`nsm_continuation.palc`) knows nothing about impacts. It continues the
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
4. Optional hooks (defaults do nothing):
   - :meth:`admissibility`: named scalar test functions, ``> 0`` where the point is admissible
     (physically realisable); a sign change is located and reported as a ``grazing`` event.
   - :meth:`floquet`: the non-trivial Floquet multipliers at a point (trivial ones removed, see
     :mod:`nsm_continuation.floquet`), used for stability and bifurcation test functions.
   - :meth:`derived`: named derived quantities (period, frequency, energy, ...), written to CSV.
   - :meth:`start_points`: initial guesses built from the YAML ``start:`` block.
   - :meth:`parameter_from_user` / ``parameter_bounds``: conversion of user bounds.
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
from pydantic import BaseModel


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


@dataclass
class CompiledResidual:
    """CasADi Functions for ``G`` and its exact Jacobian ``dG/dy``, built once per problem."""

    G: ca.Function
    J: ca.Function
    GJ: ca.Function
    n: int

    def residual(self, y: np.ndarray) -> np.ndarray:
        return np.asarray(self.G(y), dtype=float).reshape(-1)

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return np.asarray(self.J(y), dtype=float).reshape(self.n, self.n + 1)

    def both(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, j = self.GJ(y)
        return (np.asarray(g, dtype=float).reshape(-1),
                np.asarray(j, dtype=float).reshape(self.n, self.n + 1))


class Problem(ABC):
    """Base class of all problems; see the module docstring for the contract."""

    name: ClassVar[str] = ""
    Parameters: ClassVar[type[BaseModel]]
    #: symbolic type used to build the residual: "SX" (small, fast calls) or "MX" (large, dense)
    symbolic: str = "SX"

    variables: list[str]
    parameter: str

    def __init__(self, params: BaseModel) -> None:
        self.params = params

    # -- required -------------------------------------------------------------------------------
    @abstractmethod
    def residual(self, y: Any) -> Any:
        """``G(y)`` as a CasADi expression of the symbol ``y`` (length ``n + 1``)."""

    # -- derived from residual ------------------------------------------------------------------
    @property
    def dim(self) -> int:
        """Number of unknowns ``n + 1``."""
        return len(self.variables)

    @property
    def parameter_index(self) -> int:
        return self.variables.index(self.parameter)

    @cached_property
    def compiled(self) -> CompiledResidual:
        sym = ca.SX if self.symbolic == "SX" else ca.MX
        y = sym.sym("y", self.dim)
        g = self.residual(y)
        n = int(g.shape[0])
        if n != self.dim - 1:
            raise ValueError(
                f"problem {self.name!r}: residual has {n} equations for {self.dim} unknowns "
                "(continuation needs n equations in n + 1 unknowns)"
            )
        jac = ca.jacobian(g, y)
        G = ca.Function("G", [y], [g])
        J = ca.Function("J", [y], [jac])
        GJ = ca.Function("GJ", [y], [g, jac])
        return CompiledResidual(G=G, J=J, GJ=GJ, n=n)

    def evaluate(self, y: np.ndarray) -> np.ndarray:
        return self.compiled.residual(y)

    def jacobian(self, y: np.ndarray) -> np.ndarray:
        return self.compiled.jacobian(y)

    def evaluate_with_jacobian(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(G(y), G_y(y))`` in one call (override together with evaluate/jacobian)."""
        return self.compiled.both(y)

    # -- optional hooks -------------------------------------------------------------------------
    def admissibility(self, y: np.ndarray) -> dict[str, float]:
        """Named test functions, positive where ``y`` is admissible."""
        return {}

    def floquet(self, y: np.ndarray, tangent: np.ndarray) -> FloquetData | None:
        """Non-trivial Floquet multipliers at ``y`` (``tangent``: unit tangent of the branch)."""
        return None

    def derived(self, y: np.ndarray) -> dict[str, float]:
        """Named derived quantities written with each point."""
        return {}

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

    def monitor_names(self) -> list[str]:
        """Names of the derived quantities (:meth:`derived`) a ``continuation.bounds`` entry may
        name; a bound on any other name is refused before computing."""
        return []

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        """Convert user bounds on ``name`` (e.g. ``omega``) to bounds on ``self.parameter``."""
        if name != self.parameter:
            raise ValueError(f"continuation.parameter: cannot continue in {name!r}; this "
                             f"problem continues in {self.parameter!r}")
        return lo, hi

    def summary(self) -> dict[str, Any]:
        """Problem facts for the report (linear frequencies, coefficients, ...)."""
        return {}

    def report_extras(self, branches: list[Any]) -> dict[str, Any]:
        """Problem-specific results added to ``report.json`` under ``problem_results``."""
        return {}

    def plot_decorations(self, ax: Any, x_range: tuple[float, float]) -> None:
        """Draw problem-specific references on the frequency-energy plot (no-op by default)."""
        return None

    def extra_plots(self, out_dir: Any, branches: list[Any],
                    window: tuple[float | None, float | None]) -> list[str]:
        """Write problem-specific figures into ``out_dir``; return their file names."""
        return []

    #: derived quantities used as axes of the frequency-energy plot
    fep_axes: tuple[str, str] = ("omega", "energy")
    #: the derived quantity that ``continuation.max_energy`` bounds (None: the problem has no
    #: energy, and ``max_energy`` is refused; ``continuation.bounds`` bounds any monitor)
    energy_quantity: ClassVar[str | None] = None

    def warnings(self) -> list[str]:
        """Warnings about the instance (e.g. a violated assumption) to put in the report."""
        return []
