"""Sphinx configuration of quatarray's documentation.

Build: ``python -m sphinx -W -b html docs docs/_build/html`` (warnings are
errors; ``.ci/run`` builds it that way). The API pages come from the
docstrings; the gallery's figures are drawn at build time by the plot
directive, so they always show what the code does today.
"""

import os
import sys

sys.path.insert(0, os.path.abspath(".."))

project = "quatarray"
author = "the quatarray developers"
copyright = "2026, the quatarray developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "matplotlib.sphinxext.plot_directive",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

autosummary_generate = True
autodoc_default_options = {"members": False}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()

plot_include_source = True
plot_html_show_source_link = False
plot_html_show_formats = False
plot_formats = [("png", 90)]
plot_rcparams = {"figure.figsize": (7.0, 3.6), "figure.dpi": 90}

html_theme = "alabaster"
html_theme_options = {"description": "fast batched quaternions", "page_width": "1100px"}
html_static_path = []


# The docstrings are written to read well in ``help()`` too, where |q| is the
# norm of q; reStructuredText would take it for a substitution. Escape the bars
# outside literals, doctests and literal blocks when the docs are built.
import re  # noqa: E402

_LITERAL = re.compile(r"(``.*?``)")


def _escape_bars(app, what, name, obj, options, lines):
    block_indent = None
    for k, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if block_indent is not None:
            if stripped and indent <= block_indent:
                block_indent = None
            else:
                continue
        if stripped.startswith((">>>", "...")) or "|" not in line:
            if line.rstrip().endswith("::"):
                block_indent = indent
            continue
        parts = _LITERAL.split(line)
        lines[k] = "".join(p if p.startswith("``") else re.sub(r"(?<!\\)\|", r"\\|", p) for p in parts)
        if line.rstrip().endswith("::"):
            block_indent = indent


def setup(app):
    app.connect("autodoc-process-docstring", _escape_bars, priority=400)
