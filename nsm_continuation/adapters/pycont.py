"""Hand any :class:`~nsm_continuation.core.problem.Problem` to pycont-lite.

`pycont-lite <https://pypi.org/project/pycont-lite/>`_ (``import pycont``) continues the solutions
of ``G(u, p) = 0`` with ``u`` in ``R^M`` and a scalar parameter ``p``, matrix-free (Newton-Krylov
with finite-difference Jacobian-vector products). A :class:`Problem` instead declares
``G(y) = 0`` with ``y`` in ``R^(n+1)`` and names the component of ``y`` that plays the role of the
parameter (``problem.parameter``). The adapter splits ``y`` into

* ``u = y`` without the parameter component (``M = n`` unknowns, as many as equations),
* ``p = y[problem.parameter_index]``,

and evaluates ``G(u, p) = problem.evaluate(join(u, p))``. Only the residual crosses the boundary:
pycont-lite never sees the exact Jacobian (it has no slot for one), the admissibility tests nor
the Floquet multipliers.

Usage::

    from nsm_continuation.adapters.pycont import run_pycont

    ys = run_pycont(problem, y0, ds_max=0.1, n_steps=50, direction=-1, tolerance=1e-10,
                    bifurcation_detection=False)
    # ys[k] is a point y of the problem (length problem.dim), ordered along the branch

pycont-lite is imported lazily: importing this module never fails, calling :func:`run_pycont`
without pycont-lite raises an :class:`ImportError` that says how to install it.

Notes on pycont-lite 0.6 (read from its source):

* a corrector is accepted when ``scipy.optimize.newton_krylov`` reaches ``tolerance`` in the max
  norm on ``[G; arclength equation]``, or, failing that, when the 2-norm of that residual is below
  ``10 * max(tolerance, rdiff)``: with the default ``rdiff = 6.6e-6`` a point may carry a
  residual up to ~``6.6e-5`` even for a tiny ``tolerance``;
* ``analyze_stability`` computes the right-most eigenvalue of ``G_u`` (stability of an equilibrium
  of ``u' = G(u, p)``). For a fixed-point residual such as the return-map equations of
  :mod:`nsm_continuation.problems.chain.ndof_impact` that number has no dynamical meaning
  (stability is given by the Floquet multipliers, ``problem.floquet``), so :func:`run_pycont`
  switches it off unless asked for;
* a fold (``LP``) is placed on the chord between the two points that bracket it
  (``x_left + alpha (x_right - x_left)``) and is not corrected back onto the curve: that one point
  of the returned branch is ``O(ds^2)`` off the solution set. Fold and bifurcation tests are
  evaluated every fifth step only;
* ``hopf_detection`` evaluates ``G`` at complex arguments; CasADi residuals are real, so the
  adapter rejects complex input with a :class:`TypeError`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any, NamedTuple

import numpy as np

from nsm_continuation.core.problem import Problem

#: message of the ImportError raised when pycont-lite is missing
PYCONT_MISSING = (
    "pycont-lite (import name 'pycont') is required for nsm_continuation.adapters.pycont; "
    "install the 'pycont' extra: pip install nsm-continuation[pycont]"
)


def import_pycont() -> ModuleType:
    """Import and return the ``pycont`` module, or raise an ImportError saying how to get it."""
    try:
        import pycont
    except ImportError as exc:  # ModuleNotFoundError, or a broken installation
        raise ImportError(PYCONT_MISSING) from exc
    return pycont


class PycontResidual:
    """``G(u, p) -> ndarray`` for pycont-lite, built on ``problem.evaluate``.

    Counts its calls in :attr:`n_calls` (pycont-lite is matrix-free: every Jacobian-vector product
    is one or two residual evaluations, so the count is its cost measure).
    """

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.index = problem.parameter_index
        self.dim = problem.dim
        self.n_calls = 0

    def join(self, u: np.ndarray, p: float) -> np.ndarray:
        """The point ``y`` of the problem with ``p`` inserted at ``problem.parameter_index``."""
        u = np.asarray(u)
        if u.shape != (self.dim - 1,):
            raise ValueError(f"u has shape {u.shape}, expected ({self.dim - 1},) for problem "
                             f"{self.problem.name!r}")
        if np.iscomplexobj(u) or np.iscomplexobj(p):
            if np.any(np.imag(u) != 0.0) or np.imag(p) != 0.0:
                raise TypeError("the residual of an nsm_continuation Problem is real: complex "
                                "arguments are not supported (do not enable pycont's "
                                "'hopf_detection' with this adapter)")
            u, p = np.real(u), np.real(p)
        i = self.index
        y = np.empty(self.dim)
        y[:i] = u[:i]
        y[i] = p
        y[i + 1:] = u[i:]
        return y

    def split(self, y: np.ndarray) -> tuple[np.ndarray, float]:
        """``(u, p)``: ``y`` without its parameter component, and that component."""
        y = np.asarray(y, dtype=float)
        if y.shape != (self.dim,):
            raise ValueError(f"y has shape {y.shape}, expected ({self.dim},)")
        return np.delete(y, self.index), float(y[self.index])

    def __call__(self, u: np.ndarray, p: float) -> np.ndarray:
        self.n_calls += 1
        return self.problem.evaluate(self.join(u, p))


class PycontSystem(NamedTuple):
    """What pycont-lite needs, unpackable as ``G, split, join = as_pycont_system(problem)``."""

    #: ``G(u, p) -> ndarray`` of length ``len(u)``
    G: PycontResidual
    #: ``split(y) -> (u, p)``
    split: Callable[[np.ndarray], tuple[np.ndarray, float]]
    #: ``join(u, p) -> y``
    join: Callable[[np.ndarray, float], np.ndarray]


def as_pycont_system(problem: Problem) -> PycontSystem:
    """Wrap ``problem`` as ``(G, split, join)`` for pycont-lite (does not import pycont)."""
    G = PycontResidual(problem)
    return PycontSystem(G, G.split, G.join)


def correct_at_fixed_parameter(problem: Problem, y0: np.ndarray, tol: float = 1e-14,
                               max_iter: int = 20) -> np.ndarray:
    """Newton on ``G(y) = 0`` with the parameter component of ``y`` frozen.

    Uses the problem's exact Jacobian (its columns without the parameter one). pycont-lite
    expects a converged start (it only corrects the points it predicts); this polishes a guess
    such as a closed form. Raises RuntimeError when the iteration does not converge.
    """
    y = np.array(y0, dtype=float)
    ip = problem.parameter_index
    keep = np.array([k for k in range(problem.dim) if k != ip])
    g = problem.evaluate(y)
    for _ in range(max_iter):
        if np.linalg.norm(g, np.inf) <= tol * (1.0 + np.linalg.norm(y, np.inf)):
            return y
        J = problem.jacobian(y)[:, keep]
        try:
            dy = np.linalg.solve(J, -g)
        except np.linalg.LinAlgError:
            dy = np.linalg.lstsq(J, -g, rcond=None)[0]
        y[keep] += dy
        g_new = problem.evaluate(y)
        if np.linalg.norm(dy, np.inf) <= 4 * np.finfo(float).eps * (1 + np.linalg.norm(y, np.inf)):
            return y  # converged to round-off
        g = g_new
    if np.linalg.norm(g, np.inf) <= 1e3 * tol * (1.0 + np.linalg.norm(y, np.inf)):
        return y
    raise RuntimeError(f"start point did not converge at fixed {problem.parameter} "
                       f"(|G| = {np.linalg.norm(g, np.inf):.3e})")


@dataclass
class PycontRun:
    """Everything :func:`run_pycont` knows after a run (``full_output=True``)."""

    #: the branch through the start, points ``y`` of the problem ordered along the branch
    y: np.ndarray
    #: the raw ``pycont`` ContinuationResult (all branches, events)
    result: Any
    #: every pycont branch converted to points ``y`` (same order as ``result.branches``)
    branches: list[np.ndarray] = field(default_factory=list)
    #: residual evaluations made by pycont-lite (its whole cost, it never forms a Jacobian)
    n_evaluations: int = 0


def branch_to_y(system: PycontSystem | PycontResidual, branch: Any) -> np.ndarray:
    """Points ``y`` (rows) of one pycont ``Branch`` (``u_path``: n_pts x M, ``p_path``)."""
    G = system.G if isinstance(system, PycontSystem) else system
    u = np.asarray(branch.u_path, dtype=float)
    p = np.asarray(branch.p_path, dtype=float)
    if u.shape[0] == 0:
        return np.empty((0, G.dim))
    return np.insert(u, G.index, p, axis=1)


def _chain(result: Any, first: int, converted: list[np.ndarray]) -> np.ndarray:
    """Branch ``first`` followed by the segments pycont started at the folds that ended it."""
    parts = [converted[first]]
    b = result.branches[first]
    while b.termination_event is not None and b.termination_event.kind == "LP":
        idx = next((k for k, ev in enumerate(result.events) if ev is b.termination_event), None)
        nxt = next((k for k, bb in enumerate(result.branches) if bb.from_event == idx), None)
        if idx is None or nxt is None:
            break
        seg = converted[nxt]
        parts.append(seg[1:] if len(seg) and np.array_equal(seg[0], parts[-1][-1]) else seg)
        b = result.branches[nxt]
    return np.concatenate(parts, axis=0)


def run_pycont(problem: Problem, y0: np.ndarray, *, ds_min: float = 1e-6, ds_max: float = 0.1,
               ds_0: float = 1e-2, n_steps: int = 100, direction: int = 0,
               correct_start: bool = True, verbosity: str | int = "off",
               full_output: bool = False, **solver_parameters: Any
               ) -> np.ndarray | PycontRun:
    """Continue the branch of ``problem`` through ``y0`` with pycont-lite.

    Parameters
    ----------
    problem:
        Any :class:`~nsm_continuation.core.problem.Problem`.
    y0:
        A point of the branch (length ``problem.dim``); polished first by Newton at fixed
        parameter with the exact Jacobian when ``correct_start`` (pycont-lite assumes a
        converged start).
    ds_min, ds_max, ds_0, n_steps:
        Passed to ``pycont.arclengthContinuation`` (arclength bounds, first step, maximum number
        of steps per pycont branch).
    direction:
        ``0``: both directions, ``> 0`` towards increasing parameter, ``< 0`` decreasing (mapped
        to pycont's ``initial_directions`` unless that key is given explicitly).
    verbosity:
        pycont's verbosity (``"off"``, ``"info"``, ``"verbose"``); pycont prints every step at
        ``"info"``.
    full_output:
        Return a :class:`PycontRun` instead of the array of points.
    **solver_parameters:
        pycont ``solver_parameters`` (``tolerance``, ``rdiff``, ``nk_maxiter``, ``param_min``,
        ``param_max``, ``bifurcation_detection``, ``analyze_stability``, ...).
        ``analyze_stability`` defaults to ``False`` here (see the module docstring).

    Returns
    -------
    ndarray of shape ``(n_points, problem.dim)``: the branch through ``y0`` ordered along the
    arclength (both directions merged, segments restarted by pycont at folds appended). Branches
    that pycont switched to at branch points are only in ``PycontRun.branches``.
    """
    pycont = import_pycont()
    system = as_pycont_system(problem)
    y0 = np.asarray(y0, dtype=float)
    if correct_start:
        y0 = correct_at_fixed_parameter(problem, y0)
    u0, p0 = system.split(y0)
    sp = dict(solver_parameters)
    sp.setdefault("analyze_stability", False)
    if "initial_directions" not in sp:
        sp["initial_directions"] = ("both" if direction == 0
                                    else "increase_p" if direction > 0 else "decrease_p")
    result = pycont.arclengthContinuation(system.G, u0, p0, ds_min, ds_max, ds_0, n_steps,
                                          solver_parameters=sp, verbosity=verbosity)
    converted = [branch_to_y(system, b) for b in result.branches]
    roots = [k for k, b in enumerate(result.branches) if b.from_event == 0]
    if not roots:
        ys = y0[None, :].copy()
    else:
        ys = _chain(result, roots[0], converted)
        if len(roots) > 1:  # the second direction, reversed in front (shared start dropped)
            back = _chain(result, roots[1], converted)
            ys = np.concatenate([back[:0:-1], ys], axis=0)
    if full_output:
        return PycontRun(y=ys, result=result, branches=converted, n_evaluations=system.G.n_calls)
    return ys


__all__ = [
    "PYCONT_MISSING",
    "PycontResidual",
    "PycontRun",
    "PycontSystem",
    "as_pycont_system",
    "branch_to_y",
    "correct_at_fixed_parameter",
    "import_pycont",
    "run_pycont",
]
