"""Monitors: what a problem watches along a branch, declared as values.

A monitor is a quantity whose change is an event: an admissibility test (``> 0`` where the
orbit is physically realisable; a sign change is located and raises its kind), an event
function (a zero is located and raises its kind; the branch goes on), a bounded quantity (its
bound ends the branch with its kind), the discrete signature of the orbit (a change raises its
kind; a change across a kink the branch is continued through, a family change, raises the
``family`` monitor's), a quantity watched for growth without bound (an ``asymptote``) or a
positive quantity whose zero ends the family of solutions (``vanishing``: located where the
branch cannot go on towards it, by extrapolation to zero). The values come from
the problem's methods (:meth:`~nsm_continuation.core.problem.Problem.admissibility`,
``event_functions``, ``derived``, ``signature``); which kind each raises, whether it is located
and whether it ends the branch are declared once, in the problem's :class:`Monitors`, like
BifurcationKit's ``ContinuousEvent`` / ``DiscreteEvent`` in a ``SetOfEvents``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from enum import StrEnum


class Source(StrEnum):
    """Where a monitor's values come from."""

    #: an admissibility test (``Problem.admissibility``): a sign change is located
    TEST = "test"
    #: an event function (``Problem.event_functions``): a zero is located, the branch goes on
    FUNCTION = "function"
    #: a bounded quantity (the parameter or a derived quantity): its bound ends the branch
    BOUND = "bound"
    #: the discrete signature (``Problem.signature``): a change is located by bisection
    SIGNATURE = "signature"
    #: a derived quantity watched for growth without bound as the parameter nears a limit
    ASYMPTOTE = "asymptote"
    #: a positive derived quantity whose zero ends the family (the solutions beyond it are not
    #: physical): where the branch fails approaching it, its zero is extrapolated
    VANISHING = "vanishing"
    #: the signature on the two sides of a kink the branch is continued through: a change is
    #: a change of family
    FAMILY = "family"


@dataclass(frozen=True)
class Monitor:
    """One declared monitor: ``name`` (the test, function or quantity it reads), the event
    ``kind`` a change raises, its ``source``, whether the change is ``located`` on the curve
    (else recorded at the end of its step) and whether it is ``terminal`` (ends the branch;
    an admissibility test ends it only with ``analysis.stop_on_inadmissible``)."""

    name: str
    kind: str
    source: Source
    located: bool = True
    terminal: bool = False


def admissibility(name: str, kind: str) -> Monitor:
    """An admissibility test ``name`` whose sign change raises ``kind``."""
    return Monitor(name, kind, Source.TEST)


def event_function(name: str, kind: str) -> Monitor:
    """An event function ``name`` whose zeros raise ``kind`` (the branch goes on)."""
    return Monitor(name, kind, Source.FUNCTION)


def bound(name: str, kind: str) -> Monitor:
    """A bound on the quantity ``name`` (``continuation.bounds``) that ends the branch with
    ``kind`` (unlisted quantities end it with ``endpoint``)."""
    return Monitor(name, kind, Source.BOUND, terminal=True)


def signature(kind: str) -> Monitor:
    """The problem's discrete signature, whose changes raise ``kind``."""
    return Monitor("signature", kind, Source.SIGNATURE)


def asymptote(name: str) -> Monitor:
    """The derived quantity ``name`` watched (with ``|y|``) for an ``asymptote``."""
    return Monitor(name, "asymptote", Source.ASYMPTOTE, terminal=True)


def vanishing(name: str, kind: str) -> Monitor:
    """The positive derived quantity ``name``, whose zero ends the family of solutions (e.g.
    the impact velocity of a family of impacting orbits): where the branch fails while the
    quantity falls towards zero, the zero is extrapolated from the last resolved points
    (:mod:`~nsm_continuation.core.palc.ends`) and the branch ends there with ``kind``."""
    return Monitor(name, kind, Source.VANISHING, terminal=True)


def family(kind: str) -> Monitor:
    """The problem's signature compared across a kink the branch is continued through
    (:meth:`~nsm_continuation.core.problem.Problem.continue_beyond`): a change raises ``kind``
    (the branch goes on along another family of solutions)."""
    return Monitor("signature", kind, Source.FAMILY)


@dataclass(frozen=True)
class Monitors:
    """The monitors a problem declares, in order, and the kind of the tests and event
    functions it does not list (``default_kind``). Default: the energy watched for an
    asymptote, unlisted tests and functions raise ``grazing``."""

    declared: tuple[Monitor, ...] = field(default=(asymptote("energy"),))
    default_kind: str = "grazing"

    def of(self, source: Source) -> tuple[Monitor, ...]:
        """The declared monitors of ``source``, in order."""
        return tuple(m for m in self.declared if m.source is source)

    def kind(self, source: Source | str, name: str) -> str:
        """The event kind a change of the monitor ``name`` of ``source`` raises: its declared
        kind, else :attr:`default_kind` for a test or event function and ``endpoint`` for a
        bound (the last declaration of a name wins)."""
        source = Source(source)
        kind = "endpoint" if source is Source.BOUND else self.default_kind
        for m in self.of(source):
            if m.name == name:
                kind = m.kind
        return kind

    def bound_kind(self, label: str) -> str:
        """The kind of the bound reached at ``label`` (``"<quantity> = min|max"``)."""
        kind = "endpoint"
        for m in self.of(Source.BOUND):
            if label.startswith(f"{m.name} ="):
                kind = m.kind
        return kind

    @property
    def signature_kind(self) -> str | None:
        """The kind of a change of the signature (None: the problem declares no signature)."""
        found = self.of(Source.SIGNATURE)
        return found[-1].kind if found else None

    @property
    def family_kind(self) -> str | None:
        """The kind of a change of the signature across a kink (None: not declared)."""
        found = self.of(Source.FAMILY)
        return found[-1].kind if found else None

    @property
    def asymptote_names(self) -> tuple[str, ...]:
        """The derived quantities watched for an asymptote."""
        return tuple(m.name for m in self.of(Source.ASYMPTOTE))

    def kinds(self) -> list[str]:
        """Every kind a declared monitor raises, in order."""
        return [m.kind for m in self.declared]

    def with_(self, *monitors: Monitor) -> Monitors:
        """These monitors and ``monitors`` (a subclass adding to its base's)."""
        return Monitors((*self.declared, *monitors), self.default_kind)


#: the class-level maps that declared monitors before :class:`Monitors`, and their sources
LEGACY = {"test_kinds": Source.TEST, "event_function_kinds": Source.FUNCTION,
          "bound_kinds": Source.BOUND}


def legacy_monitors(cls: type) -> None:
    """A problem class written with the earlier class-level maps (``test_kinds``,
    ``event_function_kinds``, ``bound_kinds``, ``signature_kind``, ``asymptote_monitors``,
    ``default_monitor_kind``) gets the same :class:`Monitors`, with a ``DeprecationWarning``
    naming the maps (kept for one release)."""
    own = vars(cls)
    names = [n for n in (*LEGACY, "signature_kind", "asymptote_monitors",
                         "default_monitor_kind") if n in own]
    if not names:
        return
    warnings.warn(f"{cls.__qualname__}: {', '.join(names)} are deprecated and will be removed "
                  "in the next release: declare monitors = Monitors((...)) "
                  "(nsm_continuation.core.monitors)", DeprecationWarning, stacklevel=3)
    base: Monitors = cls.monitors  # inherited
    declared = list(base.declared)
    # a map the class defines replaces the inherited one of its source, as it did
    if "asymptote_monitors" in own:
        declared = [m for m in declared if m.source is not Source.ASYMPTOTE]
        declared += [asymptote(n) for n in own["asymptote_monitors"]]
    for attr, source in LEGACY.items():
        if attr in own:
            declared = [m for m in declared if m.source is not source]
            declared += [Monitor(name, kind, source, terminal=source is Source.BOUND)
                         for name, kind in own[attr].items()]
    if "signature_kind" in own:
        declared = [m for m in declared if m.source is not Source.SIGNATURE]
        if own["signature_kind"] is not None:
            declared.append(signature(own["signature_kind"]))
    cls.monitors = Monitors(tuple(declared), own.get("default_monitor_kind", base.default_kind))
