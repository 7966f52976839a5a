"""One vocabulary across the problem families: canonical parameter names, old names deprecated.

The same quantity has the same key in every problem's ``parameters:`` (docs/case_files.md,
"Vocabulary"):

* ``gap``: the obstacle's position in the impacting coordinate, measured from the contact-free
  rest position (chain: ``u_c <= gap``, ``g`` in Legrand et al.; two-mass chain: ``q2 <= gap``;
  bar: ``u(L) <= gap``, ``g0`` in Yoong et al.; impact oscillator: ``q >= gap``, ``sigma`` in
  Nordmark & Piiroinen sec. 2.2.1). The double pendulum keeps ``d``: the wall's distance from
  the upper joint (the wall is ``X = -d``), whose position would be ``-d``;
* ``restitution``: Newton's coefficient of restitution (``e`` in the papers);
* ``dofs``: the chain's number of degrees of freedom (``N``);
* ``cells``: the bar's number of WFEM cells (``N``).

An old key still works for a while: a ``Parameters`` model derives from :class:`CanonicalNames`
and lists its old keys in ``deprecated_names = {old: new}``; its before-validator renames an old
key, warns once with a :class:`ParameterDeprecationWarning` (``parameters.sigma is deprecated:
use parameters.gap``) and refuses the old and the new key together (one line naming both).
:func:`canonical_keys` applies the same renaming to a raw mapping, nested models included (so
that an error of a renamed key names the new key), :func:`canonical_name` to the name of the
continued parameter (``continuation.parameter: sigma``), which :class:`CanonicalParameter`
applies in the problem (``parameter_bounds``, ``set_parameter``). :func:`as_parameters` is the
constructors' conversion: a mapping is validated, the model is taken as it is.

:class:`ParameterDeprecationWarning` is a :class:`DeprecationWarning` shown by default (a case's
author is the tool's end user, not a Python developer), once per message and process, unless the
warning filters were set on the command line (``-W``, ``PYTHONWARNINGS``).
"""

from __future__ import annotations

import sys
import typing
import warnings
from collections.abc import Mapping
from typing import Any, ClassVar, TypeVar

from pydantic import BaseModel, model_validator


class ParameterDeprecationWarning(DeprecationWarning):
    """A deprecated parameter key or name (renamed to the one vocabulary)."""


if not sys.warnoptions:  # the user's -W / PYTHONWARNINGS decide otherwise
    warnings.filterwarnings("default", category=ParameterDeprecationWarning)


#: the "once per message" memory of :func:`_deprecated` (reset when the filters change)
_REGISTRY: dict[Any, Any] = {}


def _deprecated(where: str, old: str, new: str) -> None:
    # one location for every such warning (the "default" action shows each message once), and
    # no source line: on stderr it is one line, "nsm-continuation:0: ParameterDeprecation...".
    warnings.warn_explicit(f"{where}.{old} is deprecated: use {where}.{new}",
                           ParameterDeprecationWarning, "nsm-continuation", 0,
                           module=__name__, registry=_REGISTRY)


def rename_keys(data: Any, renames: Mapping[str, str], where: str = "parameters") -> Any:
    """``data`` with every old key of ``renames`` replaced by its new key (a new dict; the
    input is not modified), with a warning per old key; an old key given together with its new
    key is a ``ValueError`` naming both. Anything but a mapping is returned unchanged."""
    if not isinstance(data, Mapping) or not any(old in data for old in renames):
        return data
    out = dict(data)
    for old, new in renames.items():
        if old not in out:
            continue
        if new in out:
            raise ValueError(f"{where}.{old} and {where}.{new} given together: {old} is the "
                             f"deprecated name of {new}, keep only {new}")
        _deprecated(where, old, new)
        out[new] = out.pop(old)
    return out


class CanonicalNames(BaseModel):
    """Base of a ``Parameters`` model (or of a nested block of one) with deprecated keys."""

    #: ``{old key: new key}`` of this model's level (nested models declare their own)
    deprecated_names: ClassVar[dict[str, str]] = {}
    #: dotted location of this model's keys in a case, as warnings and errors name them
    key_path: ClassVar[str] = "parameters"

    @model_validator(mode="before")
    @classmethod
    def _canonical_keys(cls, data: Any) -> Any:
        return rename_keys(data, cls.deprecated_names, cls.key_path)


def _models(annotation: Any) -> list[type[CanonicalNames]]:
    """The :class:`CanonicalNames` models an annotation admits (``X | None``, ``list[X]``, ...)."""
    if isinstance(annotation, type):
        return [annotation] if issubclass(annotation, CanonicalNames) else []
    out: list[type[CanonicalNames]] = []
    for arg in typing.get_args(annotation):
        out += _models(arg)
    return out


def canonical_keys(model: type[BaseModel], data: Any) -> Any:
    """``data`` (a raw ``parameters:`` mapping for ``model``) with the deprecated keys of
    ``model`` and of its nested :class:`CanonicalNames` models renamed (warning once per key);
    see :func:`rename_keys`."""
    if not isinstance(data, Mapping):
        return data
    if issubclass(model, CanonicalNames):
        data = rename_keys(data, model.deprecated_names, model.key_path)
    out = dict(data)
    for name, field in model.model_fields.items():
        for sub in _models(field.annotation):
            if isinstance(out.get(name), Mapping):
                out[name] = canonical_keys(sub, out[name])
    return out


def canonical_name(model: type[BaseModel], name: str, where: str = "parameters") -> str:
    """The current name of the parameter ``name`` of ``model`` (a deprecated name is mapped,
    with a warning: ``continuation.parameter: sigma`` continues in ``gap``)."""
    renames = getattr(model, "deprecated_names", {})
    if name in renames and name not in model.model_fields:
        _deprecated(where, name, renames[name])
        return renames[name]
    return name


class CanonicalParameter:
    """Mixin of a problem whose continued parameter has deprecated names: ``parameter_bounds``
    (what ``continuation.parameter`` goes through) and ``set_parameter`` accept them."""

    Parameters: ClassVar[type[BaseModel]]

    def parameter_bounds(self, name: str, lo: float | None, hi: float | None
                         ) -> tuple[float | None, float | None]:
        name = canonical_name(self.Parameters, name)
        return super().parameter_bounds(name, lo, hi)  # type: ignore[misc]

    def set_parameter(self, name: str, returns: int | None = None) -> None:
        name = canonical_name(self.Parameters, name)
        return super().set_parameter(name, returns)  # type: ignore[misc]


ModelT = TypeVar("ModelT", bound=BaseModel)


def as_parameters(model: type[ModelT], params: Any) -> ModelT:
    """The constructors' argument: a mapping (the YAML ``parameters:`` block, validated; old
    keys accepted with a warning) or an instance of ``model`` (taken as it is)."""
    if isinstance(params, model):
        return params
    if isinstance(params, Mapping):
        return model.model_validate(dict(params))
    raise TypeError(f"parameters must be a mapping or a {model.__name__}, got "
                    f"{type(params).__name__}")


__all__ = ["CanonicalNames", "CanonicalParameter", "ParameterDeprecationWarning",
           "as_parameters", "canonical_keys", "canonical_name", "rename_keys"]
