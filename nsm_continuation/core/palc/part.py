"""The base of the engine's parts (step control, event and crossing location, kinks and
charts, asymptotes): each keeps a reference to its :class:`~nsm_continuation.core.palc.engine.
ContinuationEngine` and reads the engine's current problem, which a move to another chart
(:meth:`~nsm_continuation.core.palc.kinks.KinkCrosser.rechart`) replaces during a branch."""

from __future__ import annotations

from typing import TYPE_CHECKING

from nsm_continuation.core.problem import Problem
from nsm_continuation.core.settings import ContinuationSettings

if TYPE_CHECKING:
    from nsm_continuation.core.palc.engine import ContinuationEngine


class EnginePart:
    """A part of the continuation engine: its problem, settings and parameter index are the
    engine's."""

    def __init__(self, engine: ContinuationEngine) -> None:
        self.engine = engine

    @property
    def problem(self) -> Problem:
        """The problem the engine continues now (in the chart of the current point)."""
        return self.engine.problem

    @property
    def settings(self) -> ContinuationSettings:
        """The engine's continuation settings."""
        return self.engine.settings

    @property
    def ip(self) -> int:
        """Index of the continuation parameter among the unknowns."""
        return self.engine.ip
