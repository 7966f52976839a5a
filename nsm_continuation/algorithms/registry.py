"""The algorithms by name (YAML ``continuation.algorithm``): a problem declares those it
supports (``Problem.algorithms``, the first is its default)."""

from __future__ import annotations

from nsm_continuation.algorithms.base import Algorithm
from nsm_continuation.algorithms.lattice import Lattice
from nsm_continuation.algorithms.palc import LocatedEvents, PseudoArclength
from nsm_continuation.algorithms.pycont_lite import PycontLite
from nsm_continuation.algorithms.sweep import Sweep
from nsm_continuation.core.problem import Problem
from nsm_continuation.core.settings import ContinuationSettings

#: the algorithms YAML ``continuation.algorithm`` may name
ALGORITHMS: dict[str, type[Algorithm]] = {
    "palc": PseudoArclength,
    "lattice": Lattice,
    "pycont": PycontLite,
    "sweep": Sweep,
    "located_events": LocatedEvents,
}


def unsupported(name: str, problem: type[Problem] | Problem) -> str | None:
    """Why ``problem`` cannot be continued by the algorithm ``name`` (one line), or None."""
    label = problem.name
    if name not in ALGORITHMS:
        return f"unknown algorithm {name!r} (one of {', '.join(ALGORITHMS)})"
    if name not in problem.algorithms:
        return (f"problem {label!r} cannot be continued by {name!r}; it supports "
                f"{', '.join(problem.algorithms)}")
    if name == "pycont":
        from importlib.util import find_spec

        if find_spec("pycont") is None:
            return ("pycont needs pycont-lite (import name 'pycont'): "
                    "pip install nsm-continuation[pycont]")
    return None


def make_algorithm(name: str, problem: Problem, settings: ContinuationSettings) -> Algorithm:
    """The algorithm ``name`` for ``problem`` (check :func:`unsupported` first)."""
    return ALGORITHMS[name](problem, settings)


__all__ = ["ALGORITHMS", "make_algorithm", "unsupported"]
