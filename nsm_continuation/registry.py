"""Problem registry: problems are found through the entry-point group
``nsm_continuation.problems`` (name -> ``module:Class``), so another package registers its own
systems in its metadata without touching this repository:

.. code-block:: toml

    [project.entry-points."nsm_continuation.problems"]
    my_oscillator = "my_package.my_module:MyProblem"

The problems bundled here are also listed in :data:`BUILTIN` so that a source checkout that was
not installed still finds them.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points

from .protocol import Problem

GROUP = "nsm_continuation.problems"
BUILTIN = {"ndof_impact": "nsm_continuation.problems.ndof_impact:NDofImpactProblem",
           "wfem_bar": "nsm_continuation.problems.wfem_bar:WfemBarProblem",
           "bar_continuum": "nsm_continuation.problems.bar_continuum:BarContinuumProblem",
           "double_pendulum":
               "nsm_continuation.problems.double_pendulum:DoublePendulumProblem",
           "impact_oscillator":
               "nsm_continuation.problems.impact_oscillator:ImpactOscillatorProblem",
           "two_mass_chain": "nsm_continuation.problems.two_mass_chain:TwoMassChainProblem",
           "bouncing_ball": "nsm_continuation.problems.bouncing_ball:BouncingBallProblem"}


class UnknownProblemError(LookupError):
    pass


def available() -> dict[str, str]:
    """Registered problem names -> ``module:Class`` targets."""
    found = dict(BUILTIN)
    for ep in entry_points(group=GROUP):
        found[ep.name] = ep.value
    return dict(sorted(found.items()))


def get(name: str) -> type[Problem]:
    """The Problem class registered under ``name``."""
    targets = available()
    if name not in targets:
        raise UnknownProblemError(
            f"unknown problem {name!r}; registered problems: {', '.join(targets) or 'none'}")
    module, _, attr = targets[name].partition(":")
    cls = getattr(importlib.import_module(module), attr)
    if not (isinstance(cls, type) and issubclass(cls, Problem)):
        raise UnknownProblemError(f"entry point {name!r} -> {targets[name]} is not a Problem")
    return cls
