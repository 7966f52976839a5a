"""The mutable state of one simulation (:class:`.simulate.Simulator`): the surfaces' discrete
states, the (extended) state with its sensitivities, and what the result reports."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nsm_continuation.hybrid.modes import S1
from nsm_continuation.hybrid.sim_data import SimEvent


@dataclass
class _Walk:
    """Mutable state of one simulation (:meth:`Simulator.run`): the discrete state of each
    surface ``modes`` (``active``: the surface that sticks or chatters, if any; ``key``: the
    field integrated, :meth:`Simulator._key`; ``watch``: the watched functions,
    :func:`.modes.watches`), the (extended) state ``Y`` with its sensitivities ``J = dY/dX0`` and
    ``Jt = dt/dX0``, the time, the next step size, the probe and field at ``Y``, and what the
    result reports."""

    modes: list[str]
    Y: np.ndarray
    J: np.ndarray | None
    Jt: np.ndarray | None
    h: float
    pr: np.ndarray
    F: np.ndarray
    #: running extremes of the state components (Simulator._extend_extremes)
    lo: np.ndarray
    hi: np.ndarray
    traj: list[tuple[float, np.ndarray]] | None
    stick_start: float | None
    active: int | None = None
    key: str = "free"
    watch: list[tuple[int, int, str, int]] = field(default_factory=list)
    #: offset of each surface's block in the probe (:func:`.system.probe_layout`)
    offsets: list[int] = field(default_factory=list)
    t: float = 0.0
    #: the watched functions that fired last, with their surfaces (exactly zero at the step
    #: start)
    just: set[tuple[str, int]] = field(default_factory=set)
    n_steps: int = 0
    n_imp: int = 0
    vmin: float = np.inf
    graze: float = np.inf
    events: list[SimEvent] = field(default_factory=list)
    stick_iv: list[tuple[float, float]] = field(default_factory=list)
    chatter_counts: list[int] = field(default_factory=list)
    chatter_errors: list[float] = field(default_factory=list)
    #: first-order chatter estimates of the current chattering sequence
    seq: list[Any] = field(default_factory=list)
    #: signed grazing margins of the near approaches and decelerating impacts, in time order
    margins: list[float] = field(default_factory=list)
    #: the surface of each margin
    margin_surfaces: list[int] = field(default_factory=list)
    #: unit normal (position components) of the surface at the impact that began the current
    #: chattering flight (:meth:`Simulator._same_contact`)
    seq_normal: np.ndarray | None = None
    #: the steps of an exact flow taken since the last event: the field, the state they
    #: started from and their total time (:meth:`Simulator._deferred`)
    defer: tuple[str, np.ndarray, float] | None = None
    #: the length of the next step of an exact flow when the last step's certificate fixed it
    #: (:meth:`.linear_flow.ExactStep.max_step`); cleared when the watched functions change
    next_exact: float | None = None
    #: whether the current step of an exact flow is certified free of watched zeros
    certified: bool = False
    #: exact steps whose interior extremes are left to the result (:attr:`.sim_data.SimResult.
    #: extremes`): ``(extremes, Y0, dt)``
    deferred_extremes: list[tuple[Any, np.ndarray, float]] = field(default_factory=list)
    #: the state the last of them ended at (the next step from it extends it)
    extremes_end: np.ndarray | None = None

    @property
    def mode(self) -> str:
        """The state of the active surface (sticking or chattering), else of the first; free
        flight (``s1``) for a system without contact."""
        if not self.modes:
            return S1
        return self.modes[0 if self.active is None else self.active]

    def record(self) -> None:
        if self.traj is not None:
            self.traj.append((self.t, self.Y[: self.lo.size].copy()))
