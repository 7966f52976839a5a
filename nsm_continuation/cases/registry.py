"""Problem registry: problems are found through the entry-point group
``nsm_continuation.problems`` (name -> ``module:Class``), so another package registers its own
systems in its metadata without touching this repository:

.. code-block:: toml

    [project.entry-points."nsm_continuation.problems"]
    my_oscillator = "my_package.my_module:MyProblem"

This is the one registration mechanism, for the bundled problems too (``pyproject.toml``): a
source checkout must be installed (``pip install -e .``) for its problems to be found.

A problem of another package (a *plugin*) is its author's code: when it cannot be imported, or
its ``Parameters`` model is not strict, or (:mod:`nsm_continuation.cases.validation`) one of its
hooks fails before computing, the one line says so (:func:`plugin_fault`, a
:class:`~nsm_continuation.core.errors.CaseError`: exit status 2), naming the problem, its
``module:Class`` and the exception, instead of reporting a bug of this package. A name
registered twice is resolved in favour of the bundled problem (else the first registration
found on ``sys.path``), with a :class:`DuplicateProblemWarning` naming both targets.

Scanning the installed distributions takes milliseconds, so the scan is kept
(:func:`registrations`) while ``sys.path`` and the modification times of its folders are
unchanged: installing a package (a new ``*.dist-info`` folder in ``site-packages``) or putting
a folder on ``sys.path`` is seen by the next call. What this key cannot see (an installed
package's ``entry_points.txt`` edited in place) is read again after :func:`refresh`.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
import warnings
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Any

from nsm_continuation.core.errors import CaseError, short_text

if TYPE_CHECKING:  # imported by get(): listing the problems does not load CasADi
    from nsm_continuation.core.problem import Problem

GROUP = "nsm_continuation.problems"
#: the modules of the bundled problems (and of this package): not plugins
BUNDLED_PREFIX = "nsm_continuation."
#: what a plugin's ``Parameters`` model must set (``nsm_continuation.core.preflight.STRICT``)
STRICT_FIX = "model_config = nsm_continuation.core.preflight.STRICT"


class UnknownProblemError(LookupError):
    """No problem is registered under the name (or a bundled one cannot be loaded)."""


class PluginError(CaseError):
    """A plugin (a problem of another package) failed: its fault, not this package's. The one
    line names the problem, its ``module:Class`` and the exception."""


class DuplicateProblemWarning(UserWarning):
    """A problem name registered by two entry points: one is used, the other ignored."""


@dataclass(frozen=True)
class Registration:
    """One entry point of the group: the problem ``name``, its ``module:Class`` ``target``
    and the distribution that declares it."""

    name: str
    target: str
    dist: str

    def __str__(self) -> str:
        return f"{self.target} (from {self.dist})"


def is_bundled(target: str | type) -> bool:
    """Whether ``target`` (``module:Class`` or a class) is a problem of this package, whose
    failures are this package's bugs; anything else is a plugin."""
    module = target if isinstance(target, str) else getattr(target, "__module__", "")
    return f"{module}.".startswith(BUNDLED_PREFIX)


def target_of(cls: type) -> str:
    """The ``module:Class`` of a class, as an entry point names it."""
    return f"{cls.__module__}:{cls.__qualname__}"


def _one_line(exc: BaseException) -> str:
    """``Type: message`` on one line (a SystemExit: its exit code)."""
    if isinstance(exc, SystemExit):
        return f"SystemExit({exc.code!r})"
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {short_text(text, 300)}" if text else type(exc).__name__


def plugin_fault(name: str, target: str | type, what: str,
                 exc: BaseException | None = None) -> PluginError:
    """The error of a plugin that failed ``what`` (``on import``, ``in __init__``, ...): one
    line naming the problem ``name``, its ``module:Class`` ``target`` and ``exc``."""
    where = target if isinstance(target, str) else target_of(target)
    why = f": {_one_line(exc)}" if exc is not None else ""
    return PluginError(f"problem: plugin {name!r} ({where}) failed {what}{why} (a fault of the "
                       "plugin, not of nsm-continuation)")


#: the last scan of the entry points: (its key, :func:`_path_key`; the registrations)
_scan: tuple[tuple[tuple[str, int], ...], dict[str, list[Registration]]] | None = None


def _path_key() -> tuple[tuple[str, int], ...]:
    """What the installed distributions depend on, cheaply: each ``sys.path`` entry with the
    modification time of its folder (-1 when it is not one), which changes when a
    distribution is installed or removed there."""
    key = []
    for entry in sys.path:
        folder = entry or os.getcwd()  # '' is the working directory
        try:
            mtime = os.stat(folder).st_mtime_ns
        except (OSError, ValueError):
            mtime = -1
        key.append((folder, mtime))
    return tuple(key)


def refresh() -> None:
    """Forget the scan of the entry points: the next :func:`registrations` reads them again
    (after a plugin's metadata changed in place while this process runs)."""
    global _scan
    _scan = None


def _scan_entry_points() -> dict[str, list[Registration]]:
    """Every registration of each name found in the installed distributions' metadata."""
    found: dict[str, list[Registration]] = {}
    for ep in entry_points(group=GROUP):
        dist = ep.dist.name if ep.dist is not None else "unknown distribution"
        entry = Registration(ep.name, ep.value, dist)
        if entry not in found.setdefault(ep.name, []):  # one distribution seen twice on the path
            found[ep.name].append(entry)
    for entries in found.values():
        entries.sort(key=lambda e: not is_bundled(e.target))  # stable: else the path's order
    return dict(sorted(found.items()))


def registrations() -> dict[str, list[Registration]]:
    """Every registration of each name, the one used first: the bundled problem if one is
    registered under the name, else the first found (``sys.path`` order). The scan is kept
    while :func:`_path_key` is unchanged (:func:`refresh` forgets it)."""
    global _scan
    key = _path_key()
    if _scan is None or _scan[0] != key:
        _scan = (key, _scan_entry_points())
    return {name: list(entries) for name, entries in _scan[1].items()}


def describe(target: str, width: int = 90) -> str:
    """What the problem ``target`` (``module:Class``) is, in one line: the first sentence of
    its class docstring, read from the module's source without importing it (listing the
    problems loads no CasADi); '' when the source or the docstring cannot be read."""
    import ast
    from importlib.util import find_spec

    module, _, attr = target.partition(":")
    try:
        spec = find_spec(module)
        if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
            return ""
        with open(spec.origin, encoding="utf-8") as fh:
            tree = ast.parse(fh.read())
    except (ImportError, OSError, ValueError, SyntaxError):
        return ""
    node: ast.AST = tree
    for part in attr.split("."):
        node = next((n for n in getattr(node, "body", []) if isinstance(n, ast.ClassDef)
                     and n.name == part), ast.Module(body=[], type_ignores=[]))
    doc = ast.get_docstring(node) if isinstance(node, ast.ClassDef) else None
    text = " ".join((doc or "").split("\n\n", 1)[0].split())
    text = re.sub(r":[a-z]+:`~?\.?([^`<]*?)(?: <[^`]*>)?`", r"\1", text).replace("``", "")
    # the first sentence: up to a full stop before a capital (not "et al. 2017", "sec. 3")
    first = re.split(r"(?<!\bal)\.\s+(?=[A-Z])", text, maxsplit=1)[0].rstrip(".")
    return first if len(first) <= width else first[:width - 4].rstrip() + " ..."


def available() -> dict[str, str]:
    """Registered problem names -> the ``module:Class`` used for each."""
    return {name: entries[0].target for name, entries in registrations().items()}


def duplicates() -> dict[str, list[Registration]]:
    """The names registered more than once -> their registrations, the one used first."""
    return {name: entries for name, entries in registrations().items() if len(entries) > 1}


def duplicate_note(name: str, entries: list[Registration]) -> str:
    """One line saying which registration of ``name`` is used and which are ignored."""
    ignored = "; ".join(str(e) for e in entries[1:])
    return (f"problem {name!r} is registered {len(entries)} times: {entries[0]} is used, "
            f"{ignored} ignored (rename the plugin's entry point)")


#: the duplicate notes already given by this process (a run finds its problem more than once)
_warned: set[str] = set()


def _warn_duplicate(name: str, entries: list[Registration]) -> None:
    """Warn once per process that ``name`` is registered more than once. One location and no
    source line, so that on stderr it is one line (as the vocabulary's deprecation warnings):
    ``nsm-continuation:0: DuplicateProblemWarning: ...``."""
    note = duplicate_note(name, entries)
    if note in _warned:
        return
    _warned.add(note)
    warnings.warn_explicit(note, DuplicateProblemWarning, "nsm-continuation", 0,
                           module=__name__)


def get(name: str) -> type[Problem]:
    """The Problem class registered under ``name`` (warning when another registration of the
    name is ignored). A plugin that cannot be imported, or whose ``Parameters`` model is not
    strict, is a :class:`PluginError`."""
    from nsm_continuation.core.problem import Problem

    entries = registrations().get(name)
    if not entries:
        raise UnknownProblemError(
            f"unknown problem {name!r}; registered problems: {', '.join(available()) or 'none'}")
    if len(entries) > 1:
        _warn_duplicate(name, entries)
    target = entries[0].target
    module, _, attr = target.partition(":")
    bundled = is_bundled(target)
    try:
        cls: Any = importlib.import_module(module)
        for part in attr.split(".") if attr else []:
            cls = getattr(cls, part)
    except (ImportError, AttributeError) as exc:
        if not bundled:
            raise plugin_fault(name, target, "on import", exc) from None
        raise UnknownProblemError(f"entry point {name!r} -> {target} cannot be loaded "
                                  f"({type(exc).__name__}: {exc})") from None
    except (Exception, SystemExit) as exc:  # a SyntaxError, an error or exit() at import
        if bundled:
            raise
        raise plugin_fault(name, target, "on import", exc) from None
    if not (isinstance(cls, type) and issubclass(cls, Problem)):
        if not bundled:
            raise plugin_fault(name, target, "to provide a Problem subclass")
        raise UnknownProblemError(f"entry point {name!r} -> {target} is not a Problem")
    _check_strict(name, target, cls)
    return cls


def _check_strict(name: str, target: str, cls: type) -> None:
    """A problem's ``Parameters`` must be a strict pydantic model (``extra="forbid"``,
    ``strict=True``): else a misspelt key would be dropped and ``true`` read as 1.0 without
    a word. Refused (rather than made strict behind the author's back, which would change what
    the model accepts in the plugin's own tests), naming the class and the fix."""
    from pydantic import BaseModel

    model = getattr(cls, "Parameters", None)
    if not (isinstance(model, type) and issubclass(model, BaseModel)):
        raise plugin_fault(name, target, "to declare Parameters (a pydantic model)")
    config = model.model_config
    if config.get("extra") != "forbid" or config.get("strict") is not True:
        raise PluginError(
            f"problem: {name!r} ({target}): its Parameters model {target_of(model)} is not "
            "strict (a misspelt key or true for a number would pass unnoticed); set "
            f"{STRICT_FIX}")
