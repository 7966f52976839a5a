"""YAML cases: the schema (:mod:`.schema`), its validation with the problem's preflight
(:mod:`.validation`), restarts from saved runs (:mod:`.restart`, :mod:`.saved_runs`) and the
problem registry (:mod:`.registry`).

``from nsm_continuation import cases`` gives the functions a script needs (``cases.load``,
``cases.validate``, ``cases.load_raw``, ...), imported on first use: the command line's
``list`` reads the registry without loading pydantic or CasADi.
"""

from importlib import import_module
from typing import Any

#: the names this package gives, and the module that defines each
_PUBLIC = {"Case": "cases.schema", "apply_overrides": "cases.schema", "load_raw": "cases.schema",
           "parse_yaml": "cases.schema", "with_execution": "cases.schema",
           "load": "cases.validation", "validate": "cases.validation",
           "CaseError": "core.errors"}

__all__ = sorted(_PUBLIC)


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        return getattr(import_module(f"nsm_continuation.{_PUBLIC[name]}"), name)
    from nsm_continuation._deprecated import forward

    return forward(__name__, name)
