"""nsm_continuation: continuation of nonsmooth modes of vibration of impacting systems.

The Python API (:mod:`nsm_continuation.api`): :func:`load_case`, :func:`run`, :func:`problem`,
:func:`continuation`, :func:`load` (a saved run read back) and the :class:`Result` they return
(its data as a pandas DataFrame, an xarray Dataset and a netCDF file read back by
:func:`open_netcdf`: :mod:`nsm_continuation.output.datasets`);
the problem protocol
(:mod:`nsm_continuation.core.problem`): :class:`Problem`, :class:`StartPoint`, :class:`FloquetData`,
:class:`EvaluationError`. Imported lazily, so the command line starts without loading CasADi
and matplotlib for ``--version`` or ``list``.

Warnings meant for a user of the API (the problem's, e.g. a model outside the paper's
assumptions) are logged to the logger ``nsm_continuation`` (:data:`logger`; without any
logging configuration Python prints them on stderr) and listed in ``Result.warnings``.
"""

from __future__ import annotations

import logging
from importlib import import_module
from typing import Any

from nsm_continuation import _deprecated

_deprecated.install()

#: the package's version (the only place it is written: pyproject.toml reads it from here)
__version__ = "0.1.0"

#: the package's logger (warnings for API users; the command line prints its own)
logger = logging.getLogger("nsm_continuation")

_LAZY = {
    "load_case": "api", "run": "api", "problem": "api", "continuation": "api",
    "Result": "api", "BranchData": "api", "EventRecord": "api", "load": "api",
    "open_netcdf": "output.datasets",
    "CaseError": "core.errors",
    "Problem": "core.problem", "StartPoint": "core.problem", "FloquetData": "core.problem",
    "EvaluationError": "core.problem",
}

__all__ = ["__version__", "logger", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'nsm_continuation' has no attribute {name!r}")
