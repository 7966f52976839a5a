"""Shared pieces of the problems' preflight checks (refuse every bad input before computing;
see :meth:`nsm_continuation.core.problem.Problem.preflight`), for the bundled problems and plugins.

* **Strict YAML types.** :data:`STRICT` (a pydantic config) makes ``true`` an error where a
  number is expected and ``"3"`` or ``2.0`` an error where an integer is expected (an integer is
  still a valid float). :func:`exactly` does the same for ``Literal`` choices of numbers or
  booleans, which pydantic otherwise matches by equality (``True == 1``, ``1 == True``).
* **Resource budget.** :func:`check_budget` refuses a case whose memory or run-time estimate
  exceeds the limits, read at each check from the environment variables
  ``NSM_CONTINUATION_MAX_MEMORY_GB`` (default :data:`DEFAULT_MEMORY_GB`) and
  ``NSM_CONTINUATION_MAX_HOURS`` (default :data:`DEFAULT_HOURS`). The estimates are rough upper
  bounds calibrated on a 2-core machine; each problem documents its own in ``preflight``.
* **Gap range.** The impacting chain and the bar are linear models without a length scale of
  their own: an orbit for the gap ``g != 0`` is ``|g|`` times the orbit for ``sign(g)``, and
  its energy scales as ``g^2``. Any gap is physically meaningful, but in double precision the
  energies (``~ g^2``), their ratios and the corrector's squared norms must stay far from
  underflow and overflow; below ``1e-100`` (energies ``~1e-200``) the runs silently go wrong
  (a 1e-300 gap ends the chain's first branch after 14 points at a spurious branch point instead
  of 500 points at its nonlinear grazing orbit) and above ``1e100`` they overflow.
  :func:`check_gap` therefore accepts ``0`` or ``1e-100 <= |g| <= 1e100``: scale the gap (and
  read the results scaled) outside that range. Inside it a problem keeps its numerics
  independent of the scale (the chain's unknowns are in units of ``|g|``; the bar's energies
  are ratios to its reference energy, whose own range depends on ``E`` and ``L``).
"""

from __future__ import annotations

import math
import os
from typing import Annotated, Any

from pydantic import BeforeValidator, ConfigDict, Discriminator, Tag, TypeAdapter

#: pydantic config of every YAML-facing model of the problems: unknown keys and coercions refused
STRICT = ConfigDict(extra="forbid", strict=True)

MEMORY_ENV = "NSM_CONTINUATION_MAX_MEMORY_GB"
TIME_ENV = "NSM_CONTINUATION_MAX_HOURS"
#: default memory limit of one run (GB)
DEFAULT_MEMORY_GB = 4.0
#: default run-time limit of one run (hours): a run estimated longer is refused
DEFAULT_HOURS = 12.0

#: smallest and largest nonzero gap magnitude (module docstring)
GAP_MIN, GAP_MAX = 1e-100, 1e100


def one_or_many(spec: Any) -> TypeAdapter:
    """The validator of a ``start:`` block: one ``spec`` mapping or a list of them, tagged by
    type so that an error names the key of the one model it concerns (capitalised tags are
    left out of error locations by :func:`nsm_continuation.cases.validation.validate`)."""
    return TypeAdapter(Annotated[
        Annotated[spec, Tag("One")] | Annotated[list[spec], Tag("Many")],  # type: ignore[valid-type]
        Discriminator(lambda v: "Many" if isinstance(v, list) else "One")])


def exactly(*allowed: Any) -> BeforeValidator:
    """A before-validator for ``Literal`` choices that accepts only values of the same type as
    one of ``allowed`` (so ``true`` is not ``1`` and ``1`` is not ``true``)."""

    def check(v: Any) -> Any:
        if not any(type(v) is type(a) and v == a for a in allowed):
            choices = ", ".join(repr(a).replace("True", "true").replace("False", "false")
                                for a in allowed)
            raise ValueError(f"must be one of {choices} (got {v!r})")
        return v

    return BeforeValidator(check)


def check_gap(v: float) -> float:
    """``0`` or ``GAP_MIN <= |v| <= GAP_MAX`` (module docstring); for field validators."""
    if v != 0.0 and not GAP_MIN <= abs(v) <= GAP_MAX:
        raise ValueError(
            f"|gap| = {abs(v):.3g} is outside [{GAP_MIN:g}, {GAP_MAX:g}]: the model is linear "
            "in the gap (orbits scale with |gap|, energies with gap^2), so solve with a gap "
            "in that range and scale the results; at this magnitude the energies leave the "
            "range where double precision resolves them")
    return v


def _limit(env: str, default: float, unit: str) -> float:
    raw = os.environ.get(env)
    if raw is None or not raw.strip():
        return default
    try:
        value = float(raw)
    except ValueError:
        value = float("nan")
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{env}: {raw!r} is not a positive number of {unit}")
    return value


def memory_limit_gb() -> float:
    """The memory limit of a run in GB (``NSM_CONTINUATION_MAX_MEMORY_GB``)."""
    return _limit(MEMORY_ENV, DEFAULT_MEMORY_GB, "GB")


def time_limit_hours() -> float:
    """The run-time limit of a run in hours (``NSM_CONTINUATION_MAX_HOURS``)."""
    return _limit(TIME_ENV, DEFAULT_HOURS, "hours")


def format_bytes(n: float) -> str:
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def format_seconds(s: float) -> str:
    if s >= 86400 * 365:
        return f"{s / (86400 * 365):.3g} years"
    if s >= 86400:
        return f"{s / 86400:.3g} days"
    if s >= 3600:
        return f"{s / 3600:.3g} h"
    if s >= 60:
        return f"{s / 60:.3g} min"
    return f"{s:.3g} s"


def check_budget(key: str, what: str, memory_bytes: float = 0.0,
                 seconds: float = 0.0) -> None:
    """Raise ``ValueError("<key>: <what> need(s) ~X; the limit is Y (<ENV>)")`` when an
    estimate exceeds its limit. ``what`` names the sizes, e.g. ``"10000 dofs"``."""
    mem_limit = memory_limit_gb()
    if memory_bytes > mem_limit * 1e9:
        raise ValueError(
            f"{key}: {what} need ~{format_bytes(memory_bytes)} of memory; the limit is "
            f"{mem_limit:g} GB (raise it with the environment variable {MEMORY_ENV})")
    hours = time_limit_hours()
    if seconds > hours * 3600:
        raise ValueError(
            f"{key}: {what} need ~{format_seconds(seconds)} (a rough upper estimate); the "
            f"limit is {hours:g} h (raise it with the environment variable {TIME_ENV})")


def start_key(index: int | None, field: str | None = None) -> str:
    """``start.field`` for a single start, ``start[i].field`` for the i-th of a list."""
    base = "start" if index is None else f"start[{index}]"
    return f"{base}.{field}" if field else base


def as_list(specs: Any) -> list[tuple[int | None, Any]]:
    """``[(index, spec)]`` of a validated start block: index None for a single mapping."""
    if isinstance(specs, list):
        return list(enumerate(specs))
    return [(None, specs)]


__all__ = ["STRICT", "one_or_many", "as_list", "check_budget", "check_gap", "exactly",
           "memory_limit_gb", "start_key", "time_limit_hours"]
