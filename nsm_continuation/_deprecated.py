"""Import paths of the previous layout, kept for one release.

Before the package was layered into ``core/``, ``algorithms/``, ``cases/``, ``runs/``, ``output/``
and ``figures/``, every module sat directly in ``nsm_continuation/``. A plugin written against
those paths (``from nsm_continuation.protocol import Problem``) still imports: the old module is a
thin alias whose attributes are read from the new modules, and reading a name from it emits a
``DeprecationWarning`` naming the module that holds the name now. The objects are the same
(``isinstance`` and ``issubclass`` hold across old and new paths).
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

#: old module -> the modules that hold its names now (relative to ``nsm_continuation``)
_MOVED: dict[str, tuple[str, ...]] = {
    "protocol": ("core.problem",),
    "records": ("core.records",),
    "settings": ("core.settings",),
    "bordered": ("core.bordered",),
    "casadi_buffers": ("core.casadi_buffers",),
    "events": ("core.roots",),
    "scalar_search": ("core.scalar_search",),
    "floquet": ("core.floquet", "core.floquet.deflation", "core.floquet.krein",
                "core.floquet.lowrank", "core.floquet.aberth", "core.floquet.pairs",
                "core.floquet.secular"),
    "krein": ("core.floquet.krein",),
    "palc": ("core.palc",),
    "lattice": ("core.lattice",),
    "preflight": ("core.preflight",),
    "vocabulary": ("core.vocabulary",),
    "event_curves": ("algorithms.curves",),
    "switching": ("algorithms.switching",),
    "restart": ("cases.restart", "cases.saved_runs", "runs.restart_record"),
    "registry": ("cases.registry",),
    "runner": ("runs.runner", "runs.result", "runs.setup", "runs.branches"),
    "execution": ("runs.execution", "runs.setup"),
    "diagrams": ("runs.diagrams", "figures.trees"),
    "results": ("output.files",),
    "report": ("output.report",),
    "plots": ("figures.branches", "figures.kit", "figures.multipliers", "figures.make"),
    "orbits": ("figures.orbits",),
    "orbit_selection": ("figures.orbit_selection",),
    "figure_process": ("figures.process",),
    "hybrid.shooting": ("hybrid.case", "hybrid.return_map", "hybrid.problem", "hybrid.specs",
                        "hybrid.case_preflight", "hybrid.case_period"),
}
#: old modules whose name is now a package: the package forwards their names (:func:`forward`)
_NOW_PACKAGES: dict[str, tuple[str, ...]] = {
    "cases": ("cases.schema", "cases.validation", "cases.saved_runs", "core.errors"),
    "algorithms": ("algorithms.base", "algorithms.registry", "algorithms.palc",
                   "algorithms.lattice", "algorithms.pycont_lite", "algorithms.sweep"),
    "output": ("output.folders", "cases.saved_runs"),
}


def _full(table: dict[str, tuple[str, ...]]) -> dict[str, tuple[str, ...]]:
    return {f"nsm_continuation.{k}": tuple(f"nsm_continuation.{m}" for m in v)
            for k, v in table.items()}


OLD_PATHS = _full(_MOVED)
OLD_PACKAGES = _full(_NOW_PACKAGES)


def _caller_level() -> int:
    """The ``stacklevel`` that attributes the warning to the importing code, not to importlib."""
    frame, level = sys._getframe(1), 1
    while frame is not None:
        name = frame.f_code.co_filename
        if not (name.startswith("<frozen importlib") or name == __file__
                or name.endswith(("cases/__init__.py", "output/__init__.py",
                                  "algorithms/__init__.py"))):
            return level
        frame, level = frame.f_back, level + 1
    return 2


def _moved(old: str, name: str, targets: tuple[str, ...]) -> Any:
    """``name`` of the old module ``old``, read from the first of ``targets`` that has it, with
    a warning naming that module. Module attributes (``__file__``, ``__path__``, ...) are not
    forwarded: tools that walk ``sys.modules`` ask for them."""
    if name.startswith("__") and name.endswith("__"):
        raise AttributeError(f"module {old!r} has no attribute {name!r}")
    for target in targets:
        module = import_module(target)
        if hasattr(module, name):
            value = getattr(module, name)
            home = getattr(value, "__module__", None)
            where = home if home in targets else target  # where it is defined, if listed
            warnings.warn(f"{old}.{name} is deprecated and will be removed in the next release: "
                          f"import it from {where}", DeprecationWarning,
                          stacklevel=_caller_level())
            return value
    raise AttributeError(f"module {old!r} has no attribute {name!r}")


def forward(package: str, name: str) -> Any:
    """``__getattr__`` of a package that replaced a module: the old module's names, with a
    warning. A submodule's name is not forwarded (``from package import submodule`` asks the
    package first, then imports the submodule)."""
    if importlib.util.find_spec(f"{package}.{name}") is not None:
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    return _moved(package, name, OLD_PACKAGES[package])


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
        module.__getattr__ = lambda name: _moved(old, name, OLD_PATHS[old])  # type: ignore


def install() -> None:
    """Put the alias finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
        sys.meta_path.append(_AliasFinder())
