"""YAML cases: the schema (:mod:`.schema`), its validation with the problem's preflight
(:mod:`.validate`), restarts from saved runs (:mod:`.restart`, :mod:`.saved_runs`) and the
problem registry (:mod:`.registry`)."""

from typing import Any

from nsm_continuation.cases.schema import (
    Case,
    apply_overrides,
    load_raw,
    parse_yaml,
    with_execution,
)
from nsm_continuation.cases.validate import load, validate
from nsm_continuation.core.errors import CaseError

__all__ = ["Case", "CaseError", "apply_overrides", "load", "load_raw", "parse_yaml", "validate",
           "with_execution"]


def __getattr__(name: str) -> Any:
    from nsm_continuation._deprecated import forward

    return forward(__name__, name)
