"""nsm_continuation: continuation of nonsmooth modes of vibration of impacting systems.

The Python API (:mod:`nsm_continuation.api`): :func:`load_case`, :func:`run`, :func:`problem`,
:func:`continuation` and the :class:`Result` they return; the problem protocol
(:mod:`nsm_continuation.core.problem`): :class:`Problem`, :class:`StartPoint`, :class:`FloquetData`,
:class:`EvaluationError`. Imported lazily, so the command line starts without loading CasADi
and matplotlib for ``--version`` or ``list``.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

from nsm_continuation import _deprecated

_deprecated.install()

__version__ = "0.1.0"

_LAZY = {
    "load_case": "api", "run": "api", "problem": "api", "continuation": "api",
    "Result": "api", "BranchData": "api", "EventRecord": "api",
    "CaseError": "core.errors",
    "Problem": "core.problem", "StartPoint": "core.problem", "FloquetData": "core.problem",
    "EvaluationError": "core.problem",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'nsm_continuation' has no attribute {name!r}")
