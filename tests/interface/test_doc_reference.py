"""The docs site's generated reference pages (``docs/reference/``: the YAML reference from the
pydantic schema, the problems' pages from their ``Parameters`` models, the event glossary from
the declared kinds) are what ``docs/generate_reference.py`` writes from the code now: a changed
model or kind without regenerated pages fails here, without Sphinx. And the pages say what
the schema accepts: every key a case may hold is on them, with the default pydantic gives it.
"""

from __future__ import annotations

import importlib.util
import re
import sys

import pytest
from helpers import ROOT
from pydantic import BaseModel

REFERENCE = ROOT / "docs" / "reference"


@pytest.fixture(scope="module")
def generator():
    spec = importlib.util.spec_from_file_location("generate_reference",
                                                  ROOT / "docs" / "generate_reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["generate_reference"] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("generate_reference", None)


@pytest.fixture(scope="module")
def pages(generator):
    return generator.pages()


def test_generated_pages_are_up_to_date(pages):
    stale = [rel for rel, text in pages.items()
             if not (REFERENCE / rel).is_file() or (REFERENCE / rel).read_text() != text]
    extra = sorted(p.name for p in REFERENCE.glob("*.md") if p.name not in pages)
    assert not stale and not extra, (
        f"docs/reference is out of date (stale: {stale}, not generated: {extra}): run "
        "`python docs/generate_reference.py` and commit the pages")


def _rows(text: str, heading: str) -> dict[str, list[str]]:
    """The table under the section labelled ``heading``: key -> its cells."""
    part = text.split(f"({heading})=\n", 1)[1].split("\n(ref-", 1)[0]
    rows = {}
    for line in part.splitlines():
        m = re.match(r"^\| `([^`]+)` \|(.*)\|$", line)
        if m:
            rows[m.group(1)] = [c.strip() for c in re.split(r"(?<!\\)\|", m.group(2))]
    return rows


def test_every_case_key_is_listed_with_its_default(pages, generator):
    """Each key of each block of a case is a row of its section, with pydantic's default."""
    from nsm_continuation.cases.schema import Case

    text = pages["yaml_case.md"]
    for model, path in generator.walk(Case, ""):
        rows = _rows(text, generator.anchor_of("case", path or "top"))
        assert set(rows) == {f.alias or n for n, f in model.model_fields.items()}, path
        for name, field in model.model_fields.items():
            default = rows[field.alias or name][1]
            if field.is_required():
                assert default == "required", (path, name)
            elif not isinstance(field.get_default(call_default_factory=True), BaseModel):
                shown = generator.literal(field.get_default(call_default_factory=True))
                assert default == f"`{shown}`", (path, name, default)


def test_every_problem_has_its_page_with_its_parameters(pages, generator):
    problems = generator.bundled_problems()
    assert {"ndof_impact", "wfem_bar", "double_pendulum"} <= set(problems)
    for name, cls in problems.items():
        rows = _rows(pages[f"problem_{name}.md"], generator.anchor_of(name, "parameters"))
        assert set(rows) == set(cls.Parameters.model_fields), name


def test_the_glossary_holds_every_kind_with_how_it_is_located(pages, generator):
    from nsm_continuation.core.records import CORE_EVENT_KINDS, CORE_EVENT_LOCATION

    assert set(CORE_EVENT_LOCATION) == set(CORE_EVENT_KINDS), (
        "each core event kind says how it is located (records.CORE_EVENT_LOCATION)")
    text = pages["events.md"]
    kinds = set(CORE_EVENT_KINDS)
    for cls in generator.bundled_problems().values():
        kinds |= set(cls.event_kinds) | {m.kind for m in cls.monitors.declared}
    for kind in kinds:
        assert f"| `{kind}` |" in text, kind


def test_every_key_has_a_description(generator):
    """The reference says what each key means: a ``#:`` comment above the field (or its
    ``Field(description=...)``) for every key of a case and of each bundled problem."""
    missing = generator.undescribed_keys()
    assert not missing, f"keys without a description: {missing}"


def test_comments_are_read_as_autodoc_reads_them(generator):
    """A field's description is the ``#:`` comment right above it (several lines joined), as
    Sphinx's autodoc reads attribute comments; a plain ``#`` comment is not one."""
    from nsm_continuation.cases.schema import ContinuationSpec, StepSpec

    comments = generator.field_comments(ContinuationSpec)
    assert comments["bounds"].startswith("bounds on derived quantities")
    assert "e.g. ``period: [null, 60]``" in comments["bounds"]       # second line joined
    assert "initial" in generator.field_comments(StepSpec)
    assert generator.rst_to_md(":mod:`nsm_continuation.algorithms.base` and :class:`~a.b.C`"
                               " ``x``") == "`nsm_continuation.algorithms.base` and `C` `x`"
