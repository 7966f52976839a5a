"""The styles every figure of a run shares, declared once: the stability styles of a branch
(admissible stable black, unstable red, phantom thin grey: Legrand et al. 2017, Figs. 3.2,
6.1, 6.2), the marker, colour and readable name of every event kind, and the palettes of
modes and of branches, which leave out the colours that carry a meaning in the legend of a
branch diagram (the unstable red, the Neimark-Sacker green).

An event kind a family declares without a style here is drawn with :data:`DEFAULT_EVENT`
and named after its identifier (a new kind never crashes a figure and never vanishes from
it); a family may declare styles of its own kinds
(:meth:`~nsm_continuation.core.presentation.Presentation.event_styles`). Without matplotlib:
the report and the test of a figure read the names here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class EventStyle:
    """How the events of one kind are drawn: matplotlib ``marker`` and ``colour``, the
    ``name`` shown in legends (words, with the symbol of the crossing where there is one), and
    whether the marker is ``filled`` (a hollow ring, drawn larger, surrounds the event it
    accompanies at the same point instead of hiding it)."""

    marker: str
    colour: str
    name: str
    filled: bool = True


#: admissible and stable
STABLE = "k"
#: admissible and unstable (at least one multiplier outside the unit circle)
UNSTABLE = "tab:red"
#: not admissible (a phantom orbit: it crosses the obstacle)
PHANTOM = "0.6"
#: line width of admissible and phantom branches in the branch diagram
ADMISSIBLE_WIDTH = 2.2
PHANTOM_WIDTH = 0.8
#: dash pattern of an admissible branch whose stability was not computed
NOT_COMPUTED_DASHES = (0, (4, 1.5))

#: legend text of each stability state ``(admissible, stable)``
STATE_NAMES: dict[tuple[bool, bool | None], str] = {
    (True, True): "admissible, stable",
    (True, False): "admissible, unstable",
    (True, None): "admissible, stability not computed",
    (False, True): "phantom (not admissible)",
    (False, False): "phantom (not admissible)",
    (False, None): "phantom (not admissible)",
}

#: the events of the core and of the families shipped with the package
EVENT_STYLES: dict[str, EventStyle] = {
    "fold": EventStyle("s", "tab:blue", r"fold ($\lambda = +1$)"),
    "branch_point": EventStyle("X", "tab:orange", r"branch point ($\lambda = +1$)"),
    "period_doubling": EventStyle("D", "tab:purple", r"period doubling ($\lambda = -1$)"),
    "neimark_sacker": EventStyle("o", "tab:green",
                                 r"Neimark-Sacker ($\lambda = e^{\pm i\theta}$)"),
    # it accompanies another event at the same point (a bifurcation, a grazing): a ring
    "stability_change": EventStyle("o", "k", "stability change", filled=False),
    "unresolved_crossing": EventStyle("d", "0.75", "multiplier crossing (not resolved)"),
    "grazing": EventStyle("v", "tab:red", "grazing"),
    "asymptote": EventStyle(">", "tab:brown", "asymptote"),
    "sticking_lost": EventStyle("^", "tab:cyan", r"sticking lost ($\tau \to 0$)"),
    "impact_sequence_change": EventStyle("h", "tab:pink", "impact sequence change"),
    "homoclinic_approach": EventStyle("*", "gold", r"homoclinic approach (period $\to \infty$)"),
    "family_change": EventStyle("p", "tab:pink", "family change (through a grazing)"),
    "impact_velocity_vanishes": EventStyle("<", "tab:brown",
                                           r"impact velocity vanishes ($v_n \to 0$)"),
    "pattern_change": EventStyle("h", "tab:cyan", "contact pattern change"),
    "response_change": EventStyle("h", "tab:cyan", "response kind changes"),
}

#: the ends of a branch: listed in the report, not drawn as events (a branch's ends are seen)
UNDRAWN_KINDS = frozenset({"endpoint"})

#: marker and colour of a kind without a declared style (named after its identifier)
DEFAULT_MARKER = "8"
DEFAULT_COLOUR = "0.35"


def readable(kind: str) -> str:
    """An identifier in words: ``impact_sequence_change`` -> ``impact sequence change``."""
    return kind.replace("_", " ")


def event_style(kind: str, declared: Mapping[str, EventStyle | None] | None = None
                ) -> EventStyle | None:
    """The style of events of ``kind``: the family's declared one (``declared``; None there:
    the family draws those events otherwise), else :data:`EVENT_STYLES`, else the default
    marker named after the identifier. None for the kinds not drawn as markers
    (:data:`UNDRAWN_KINDS`)."""
    if declared is not None and kind in declared:
        return declared[kind]
    if kind in UNDRAWN_KINDS:
        return None
    return EVENT_STYLES.get(kind) or EventStyle(DEFAULT_MARKER, DEFAULT_COLOUR, readable(kind))


#: colours of modes and of branches told apart by colour: neither the unstable red, nor the
#: Neimark-Sacker green, nor the phantom grey of the branch diagram's legend
PALETTE: tuple[str, ...] = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink",
                            "tab:olive", "tab:cyan", "#1b3a8c", "#b8860b", "#6a3d9a")


def palette_colour(index: int) -> str:
    """The ``index``-th colour of :data:`PALETTE` (cyclic)."""
    return PALETTE[index % len(PALETTE)]


__all__ = ["DEFAULT_COLOUR", "DEFAULT_MARKER", "EVENT_STYLES", "PALETTE", "STATE_NAMES",
           "EventStyle", "event_style", "palette_colour", "readable"]
