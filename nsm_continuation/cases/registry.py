"""Problem registry: problems are found through the entry-point group
``nsm_continuation.problems`` (name -> ``module:Class``), so another package registers its own
systems in its metadata without touching this repository:

.. code-block:: toml

    [project.entry-points."nsm_continuation.problems"]
    my_oscillator = "my_package.my_module:MyProblem"

This is the one registration mechanism, for the bundled problems too (``pyproject.toml``): a
source checkout must be installed (``pip install -e .``) for its problems to be found.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported by get(): listing the problems does not load CasADi
    from nsm_continuation.core.problem import Problem

GROUP = "nsm_continuation.problems"
class UnknownProblemError(LookupError):
    pass


def available() -> dict[str, str]:
    """Registered problem names -> ``module:Class`` targets."""
    found: dict[str, str] = {}
    for ep in entry_points(group=GROUP):
        found[ep.name] = ep.value
    return dict(sorted(found.items()))


def get(name: str) -> type[Problem]:
    """The Problem class registered under ``name``."""
    from nsm_continuation.core.problem import Problem

    targets = available()
    if name not in targets:
        raise UnknownProblemError(
            f"unknown problem {name!r}; registered problems: {', '.join(targets) or 'none'}")
    module, _, attr = targets[name].partition(":")
    try:
        cls = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:  # a broken plugin: say which and why
        raise UnknownProblemError(f"entry point {name!r} -> {targets[name]} cannot be loaded "
                                  f"({type(exc).__name__}: {exc})") from None
    if not (isinstance(cls, type) and issubclass(cls, Problem)):
        raise UnknownProblemError(f"entry point {name!r} -> {targets[name]} is not a Problem")
    return cls
