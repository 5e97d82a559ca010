"""Sphinx configuration of the flocksweep documentation site.

Build it (warnings are errors, as CI builds it in tests/test_docs_site.py)::

    python -m pip install -e '.[docs]'
    python -m sphinx -W --keep-going -b html docs docs/_build/html

The pages are the Markdown files of docs/ (MyST), the API reference is generated from the docstrings
(autodoc + napoleon, numpy style) of the packages' public names, and the example notebooks
(docs/notebooks/, executed by tests/test_notebooks.py) are linked from the index as files.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))   # this checkout first; its layers resolve through the editable install

project = "flocksweep"
author = "the flocksweep developers"
copyright = "the flocksweep developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "myst_parser"]
source_suffix = {".md": "markdown"}
root_doc = "index"
# Not pages of the site: docs/examples/ holds a stored report (its own Markdown with figures),
# docs/notebooks/ the notebooks, and calibration/sbc_uniformity*.md are the SBC study's output tables
# (written by `flocksweep sbc`, shown in calibration/sbc.md), not documents with a title.
exclude_patterns = ["_build", "examples", "notebooks", "calibration/sbc_uniformity*.md"]
html_theme = "alabaster"
html_static_path: list[str] = []

myst_heading_anchors = 3          # links to section headings (page.md#a-section) resolve

autodoc_typehints = "description"   # the signature's types appear with each parameter
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "show-inheritance": False}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
