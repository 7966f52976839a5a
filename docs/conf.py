"""Sphinx configuration of the documentation site.

Build (after ``pip install -e ".[docs]"``), warnings as errors::

    sphinx-build -W -b html docs docs/_build/html

The pages are Markdown (MyST); the notebooks under ``notebooks/`` are MyST-NB text notebooks,
executed at every build (a cell that raises fails the build); the API reference is read from the
docstrings (reST) by autodoc;
the YAML reference and the event glossary under ``reference/`` are generated from the code by
``docs/generate_reference.py`` (``tests/interface/test_doc_reference.py`` keeps them in sync).
"""

from __future__ import annotations

import nsm_continuation

project = "nsm-continuation"
author = "The nsm-continuation authors"
copyright = "the nsm-continuation authors (MIT licence)"
release = nsm_continuation.__version__
version = release

extensions = [
    "myst_nb",  # MyST Markdown (it includes myst_parser) and executed notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "jupyter_execute"]

# MyST: ::: fences for directives (the snippet test checks every ``` fence as code), $...$ math,
# anchors for ## and ### headings (links such as yaml_case.md#continuation)
myst_enable_extensions = ["colon_fence", "dollarmath", "deflist"]
myst_heading_anchors = 3

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_default_options = {"show-inheritance": True}
autosummary_generate = False

html_theme = "furo"
html_title = f"nsm-continuation {release}"

# MyST-NB: a Markdown page with a ``kernelspec`` in its front matter is a notebook, executed at
# every build in a temporary folder (the runs it writes go there); an error in a cell fails the
# build
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_timeout = 300
nb_execution_in_temp = True
nb_merge_streams = True
