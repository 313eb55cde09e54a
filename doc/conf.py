"""Sphinx configuration of the hystdisc documentation.

Build it from the repository root (the README's docs command)::

    pip install -e ".[docs]" && sphinx-build -W --keep-going -b html doc doc/_build/html

The API pages come from the docstrings (autosummary + numpydoc), the gallery from the
notebooks, executed on small data with their outputs and figures (``_ext/hystdisc_docs.py``
runs them once per change of a notebook or of the package; myst-nb renders them as they
are), the ``results.json`` schema and the warning classes from the code. The generated
sources (``api/generated/``, ``gallery/``) are written beside these files and ignored by
git. ``-D hystdisc_execute_notebooks=0`` renders the notebooks without running them.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: The repository root: README.md and notebooks/ are read from there.
ROOT = HERE.parent
if (ROOT / "hystdisc").is_dir():
    sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE / "_ext"))


import hystdisc  # noqa: E402

project = "hystdisc"
author = "the hystdisc developers"
copyright = "hystdisc developers, MIT licence"
version = release = hystdisc.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_nb",
    "hystdisc_docs",
]

exclude_patterns = ["_build", "_ext", "**.ipynb_checkpoints"]
root_doc = "index"
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

# -- API reference: one page per module (hystdisc_docs.build_api), from the docstrings ----------------------
autosummary_generate = False  # the pages are hystdisc_docs.build_api's
autosummary_imported_members = False
autosummary_ignore_module_all = False
autodoc_default_options = {
    "members": True,
    "member-order": "bysource",
    "show-inheritance": True,
    "no-value": True,  # the reprs of tables (families, effects) would fill pages
}
autodoc_typehints = "none"  # numpydoc's Parameters/Returns say the types
autodoc_inherit_docstrings = True
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = True
numpydoc_xref_param_type = False

# -- notebooks: executed by hystdisc_docs.build_gallery, rendered as they are by myst-nb -------
nb_execution_mode = "off"
myst_enable_extensions = ["colon_fence"]
myst_heading_anchors = 3
hystdisc_notebooks = str(ROOT / "notebooks")

# The README's error tables sit under a level-2 heading and open at level 4.
suppress_warnings = ["myst.header"]

html_theme = "alabaster"
html_title = f"hystdisc {release}"
html_theme_options = {
    "description": "MR-damper hysteresis models discovered from data",
    "page_width": "1100px",
}
html_static_path = ["_static"]
# long code and output lines wrap instead of being cut at the page's edge
html_css_files = ["hystdisc.css"]
