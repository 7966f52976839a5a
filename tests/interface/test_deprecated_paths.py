"""The previous layout's import paths keep working for one release: every old module (and
every old module that is now a package) gives the same objects as the new ones, and reading a
name through it emits a DeprecationWarning naming the module that holds it now."""

from __future__ import annotations

import importlib
import warnings

import pytest

from nsm_continuation import _deprecated

#: one public name of each old module (what plugins and scripts imported)
SAMPLE = {
    "protocol": "Problem", "records": "Branch", "settings": "ContinuationSettings",
    "bordered": "DenseBorderedFactor", "casadi_buffers": "BufferedFunction",
    "events": "illinois", "scalar_search": "bounded_minimum", "floquet": "count_outside",
    "krein": "swap_paths", "palc": "ContinuationEngine", "lattice": "LatticeProblem",
    "preflight": "STRICT", "vocabulary": "canonical_keys", "event_curves": "LocatedCurve",
    "switching": "switch_start", "restart": "load_run", "registry": "get",
    "runner": "run_case", "execution": "rebuild_case", "diagrams": "grow",
    "results": "write_outputs", "report": "markdown", "plots": "make_all",
    "orbits": "make_figures", "orbit_selection": "spec_warnings",
    "figure_process": "FigureProcess", "hybrid.shooting": "HybridCaseProblem",
}


def test_every_old_module_is_sampled() -> None:
    assert {k.removeprefix("nsm_continuation.") for k in _deprecated.OLD_PATHS} == set(SAMPLE)


@pytest.mark.parametrize("old", sorted(SAMPLE))
def test_old_module_gives_the_new_object_with_a_warning(old: str) -> None:
    name = SAMPLE[old]
    module = importlib.import_module(f"nsm_continuation.{old}")
    with pytest.warns(DeprecationWarning, match=rf"nsm_continuation\.{old}\.{name} is "
                                                  r"deprecated.*import it from") as record:
        value = getattr(module, name)
    new = str(record[0].message).rsplit("import it from ", 1)[1]
    assert new in _deprecated.OLD_PATHS[f"nsm_continuation.{old}"]
    assert getattr(importlib.import_module(new), name) is value


@pytest.mark.parametrize("package, name, new", [
    ("cases", "validate", "nsm_continuation.cases.validation"),
    ("cases", "CaseError", "nsm_continuation.core.errors"),
    ("algorithms", "make_algorithm", "nsm_continuation.algorithms.registry"),
    ("output", "OutputTarget", "nsm_continuation.output.folders"),
])
def test_old_modules_that_became_packages_forward_their_names(package: str, name: str,
                                                                new: str) -> None:
    pkg = importlib.import_module(f"nsm_continuation.{package}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = getattr(pkg, name)
    assert value is getattr(importlib.import_module(new), name)
    if name not in ("validate", "CaseError"):  # the package's own public names: no warning
        assert any(new in str(w.message) for w in caught
                   if issubclass(w.category, DeprecationWarning))


def test_a_plugin_of_the_previous_layout_still_defines_its_problem() -> None:
    """The import line of ``docs/adding_an_impact_system.md`` before the layout changed."""
    with pytest.warns(DeprecationWarning):
        from nsm_continuation.hybrid.shooting import HybridCaseProblem, IntegratorSpec, Section
    from nsm_continuation.hybrid.case import HybridCaseProblem as New

    assert HybridCaseProblem is New and IntegratorSpec.__name__ == "IntegratorSpec"
    assert Section.__name__ == "Section"


def test_an_unknown_name_of_an_old_module_is_an_attribute_error() -> None:
    module = importlib.import_module("nsm_continuation.palc")
    with pytest.raises(AttributeError, match="nsm_continuation.palc.*no_such_name"):
        module.no_such_name  # noqa: B018


def test_module_attributes_of_an_old_module_are_not_forwarded_nor_warned() -> None:
    """Tools that walk ``sys.modules`` (hypothesis, debuggers) read ``__file__``: no warning,
    no forwarding (the alias has no file of its own)."""
    module = importlib.import_module("nsm_continuation.results")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert getattr(module, "__file__", None) is None
