"""The bundled cases: the YAML files of the repository's ``yaml_cases/`` folder, shipped with
the package (the package data of ``nsm_continuation.yaml_cases``) and run by name.

A case is named by its file name without ``.yaml`` (``ndof_fig3_2_fep``); the cases that
restart from a saved run are in ``restart/`` (``restart/chain_two_mass_switch_period2``, or
the bare name when no other case has it). :func:`resolve` turns what a user typed into a
file: an existing path always wins; else a bundled name, with or without ``.yaml``, also
written as the repository path (``yaml_cases/ndof_fig3_2_fep.yaml``, so the README's commands
work in any folder); else a :class:`~nsm_continuation.core.errors.CaseError` naming the close
matches.
"""

from __future__ import annotations

import difflib
import shutil
import textwrap
from importlib import resources
from pathlib import Path

from nsm_continuation.core.errors import CaseError, short_text

#: the package holding the bundled cases (``yaml_cases/`` of the repository)
PACKAGE = "nsm_continuation.yaml_cases"

#: the folder name of the bundled cases in the repository (and in a path a user copies)
FOLDER = "yaml_cases"


def folder() -> Path:
    """The folder of the bundled cases (in the installed package, or the repository's
    ``yaml_cases/`` for an editable install)."""
    return Path(str(resources.files(PACKAGE)))


def cases() -> dict[str, Path]:
    """Every bundled case by name (``name`` or ``restart/name``), in the order of
    :func:`sorted` within each folder, the top folder first."""
    root = folder()
    out: dict[str, Path] = {}
    for path in sorted(root.rglob("*.yaml"), key=lambda p: (len(p.relative_to(root).parts),
                                                             str(p))):
        out[path.relative_to(root).with_suffix("").as_posix()] = path
    return out


def _by_name(cases_: dict[str, Path]) -> dict[str, Path]:
    """The names a case may be called by: its name, and its bare file name where no other
    case has it."""
    stems: dict[str, list[str]] = {}
    for name in cases_:
        stems.setdefault(name.rsplit("/", 1)[-1], []).append(name)
    aliases = {stem: cases_[names[0]] for stem, names in stems.items()
               if len(names) == 1 and stem not in cases_}
    return {**cases_, **aliases}


def find(text: str) -> Path | None:
    """The bundled case ``text`` names (module docstring), or None."""
    key = text.strip().replace("\\", "/")
    key = key.removeprefix("./").removeprefix(f"{FOLDER}/")
    key = key.removesuffix(".yaml").removesuffix(".yml")
    return _by_name(cases()).get(key)


def close_matches(text: str, n: int = 4) -> list[str]:
    """The names of the bundled cases closest to ``text`` (best first)."""
    key = Path(text).name.removesuffix(".yaml")
    names = list(_by_name(cases()))
    return difflib.get_close_matches(key, names, n=n, cutoff=0.5)


def resolve(source: str | Path) -> Path:
    """The case file ``source`` names: the path itself when it exists, else the bundled case of
    that name (:func:`find`); a :class:`CaseError` naming ``source`` and the close matches
    when neither exists."""
    path = Path(source)
    if path.exists():
        return path
    found = find(str(source)) if str(source).strip() else None
    if found is not None:
        return found
    shown = short_text(str(source))
    close = close_matches(str(source))
    hint = (f"; bundled cases with a close name: {', '.join(close)}" if close
            else "; nsm-continuation cases lists the bundled cases")
    raise CaseError(f"case file: {shown} does not exist, and no bundled case has that "
                    f"name{hint}")


def description(path: Path, width: int = 110) -> str:
    """The case's ``description:`` on one line of at most ``width`` characters, or ''."""
    import yaml

    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, yaml.YAMLError):
        return ""
    text = str(raw.get("description") or "") if isinstance(raw, dict) else ""
    return textwrap.shorten(text, width, placeholder=" ...")


def copy_to(target: str | Path) -> list[Path]:
    """Copy every bundled case into the folder ``target`` (created; ``restart/`` kept), never
    over an existing file: a :class:`CaseError` naming the first file that exists, before
    anything is copied. Returns the files written."""
    root, dest = folder(), Path(target)
    plan = [(src, dest / src.relative_to(root)) for src in cases().values()]
    taken = [d for _, d in plan if d.exists()]
    if taken:
        raise CaseError(f"cases --copy: {short_text(str(taken[0]))} exists (copy into another "
                        "folder; nothing was copied)")
    for src, dst in plan:
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dst)
    return [d for _, d in plan]


__all__ = ["cases", "close_matches", "copy_to", "description", "find", "folder", "resolve"]
