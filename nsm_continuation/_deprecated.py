"""Import paths of the previous layout, kept for one release.

Before the package was layered into ``core/``, ``algorithms/``, ``cases/``, ``runs/``, ``output/``
and ``figures/``, every module sat directly in ``nsm_continuation/``. A plugin written against
those paths (``from nsm_continuation.protocol import Problem``) still imports: the old module is a
thin alias whose attributes are read from the new modules, and importing it emits one
``DeprecationWarning`` naming the new path. The objects are the same (``isinstance`` and
``issubclass`` hold across old and new paths).
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from importlib import import_module
from types import ModuleType
from typing import Any

#: old module -> the modules (first is the one to import now) that hold its public names
OLD_PATHS: dict[str, tuple[str, ...]] = {
    "nsm_continuation.protocol": ("nsm_continuation.core.problem",),
    "nsm_continuation.records": ("nsm_continuation.core.records",),
    "nsm_continuation.settings": ("nsm_continuation.core.settings",),
    "nsm_continuation.bordered": ("nsm_continuation.core.bordered",),
    "nsm_continuation.casadi_buffers": ("nsm_continuation.core.casadi_buffers",),
    "nsm_continuation.events": ("nsm_continuation.core.roots",),
    "nsm_continuation.scalar_search": ("nsm_continuation.core.scalar_search",),
    "nsm_continuation.floquet": ("nsm_continuation.core.floquet",),
    "nsm_continuation.krein": ("nsm_continuation.core.krein",),
    "nsm_continuation.palc": ("nsm_continuation.core.palc",),
    "nsm_continuation.lattice": ("nsm_continuation.core.lattice",),
    "nsm_continuation.preflight": ("nsm_continuation.core.preflight",),
    "nsm_continuation.vocabulary": ("nsm_continuation.core.vocabulary",),
    "nsm_continuation.algorithms": ("nsm_continuation.algorithms.base",),
    "nsm_continuation.event_curves": ("nsm_continuation.algorithms.curves",),
    "nsm_continuation.switching": ("nsm_continuation.algorithms.switching",),
    "nsm_continuation.restart": ("nsm_continuation.cases.restart",),
    "nsm_continuation.registry": ("nsm_continuation.cases.registry",),
    "nsm_continuation.runner": ("nsm_continuation.runs.runner",),
    "nsm_continuation.execution": ("nsm_continuation.runs.execution",),
    "nsm_continuation.diagrams": ("nsm_continuation.runs.diagrams",),
    "nsm_continuation.results": ("nsm_continuation.output.files",),
    "nsm_continuation.report": ("nsm_continuation.output.report",),
    "nsm_continuation.plots": ("nsm_continuation.figures.branches",),
    "nsm_continuation.orbits": ("nsm_continuation.figures.orbits",),
    "nsm_continuation.orbit_selection": ("nsm_continuation.figures.orbit_selection",),
    "nsm_continuation.figure_process": ("nsm_continuation.figures.process",),
    "nsm_continuation.hybrid.shooting": ("nsm_continuation.hybrid.case",
                                         "nsm_continuation.hybrid.return_map",
                                         "nsm_continuation.hybrid.problem",
                                         "nsm_continuation.hybrid.specs",
                                         "nsm_continuation.hybrid.case_preflight",
                                         "nsm_continuation.hybrid.case_period"),
}

#: old modules whose name is now a package: the package forwards their names (see ``forward``)
OLD_PACKAGES: dict[str, tuple[str, ...]] = {
    "nsm_continuation.cases": ("nsm_continuation.cases.schema",),
    "nsm_continuation.output": ("nsm_continuation.output.folders",),
}


def _caller_level() -> int:
    """The ``stacklevel`` that attributes the warning to the importing code, not to importlib."""
    frame, level = sys._getframe(1), 1
    while frame is not None:
        name = frame.f_code.co_filename
        if not (name.startswith("<frozen importlib") or name == __file__
                or name.endswith(("cases/__init__.py", "output/__init__.py"))):
            return level
        frame, level = frame.f_back, level + 1
    return 2


def _warn(old: str, new: str) -> None:
    warnings.warn(f"{old} is deprecated and will be removed in the next release: import from "
                  f"{new} instead", DeprecationWarning, stacklevel=_caller_level())


def _lookup(targets: tuple[str, ...], name: str, old: str) -> Any:
    for target in targets:
        module = import_module(target)
        if hasattr(module, name):
            return getattr(module, name)
    raise AttributeError(f"module {old!r} has no attribute {name!r}")


def forward(package: str, name: str) -> Any:
    """``__getattr__`` of a package that replaced a module: the old module's names, with a
    warning."""
    targets = OLD_PACKAGES[package]
    value = _lookup(targets, name, package)
    _warn(f"{package}.{name}", targets[0])
    return value


class _AliasFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old module names and makes each an alias of its new modules."""

    def find_spec(self, fullname: str, path: Any, target: Any = None
                  ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in OLD_PATHS:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        old = module.__name__
        targets = OLD_PATHS[old]
        _warn(old, targets[0])
        module.__getattr__ = lambda name: _lookup(targets, name, old)  # type: ignore[method-assign]


def install() -> None:
    """Put the alias finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
