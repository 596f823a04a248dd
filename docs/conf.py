"""Sphinx configuration of softcurve's documentation site (``python docs/build.py``).

Sphinx with autodoc and numpydoc, rather than MkDocs with mkdocstrings, because of how
the docstrings are written: they cross-reference with Sphinx roles
(:class:`~softcurve.Model`, :func:`...`, :mod:`...`), which Sphinx resolves and checks
and mkdocstrings would print as raw text, and the shared parameter texts
(``softcurve.base.docs``) are substituted into ``__doc__`` at import time, which autodoc
reads (it imports the package) and a reader of the source text would show as
``%(name)s``. The guide pages stay Markdown, read by myst-parser.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
sys.path.insert(0, str(HERE.parent / "src"))  # document the source beside these pages

import softcurve  # noqa: E402

project = "softcurve"
author = "the softcurve authors"
copyright = "the softcurve authors, MIT license"
release = version = softcurve.__version__

extensions = ["sphinx.ext.autodoc", "numpydoc", "myst_parser", "softcurve_docs"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "figures"]

# strict: every cross-reference is checked (docs/build.py adds -W, warnings are errors)
nitpicky = True
default_role = "py:obj"

autodoc_typehints = "none"  # numpy-style docstrings give the types, with units and shapes
autodoc_member_order = "bysource"
autodoc_inherit_docstrings = True
numpydoc_show_class_members = False  # autodoc's :members: lists them
numpydoc_xref_param_type = False  # type lines are prose ("array_like, shape (n,)")
numpydoc_validation_checks: set[str] = set()  # tests/test_docs.py checks the parameters

myst_heading_anchors = 4  # links to sections of a page: statics.md#input-maps-...
myst_enable_extensions = ["deflist"]

html_theme = "alabaster"
html_title = f"softcurve {release}"
html_static_path: list[str] = []
html_show_sourcelink = False
html_theme_options = {"page_width": "1100px", "sidebar_width": "260px"}
