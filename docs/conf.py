"""Sphinx configuration of pincal's documentation: MyST Markdown pages, the notebooks rendered by
myst-nb, the command-line reference from pincal's own parser (sphinx-argparse) and the API from
the docstrings (autodoc + napoleon, Google style).

Build: ``sphinx-build -W -b html docs docs/_build/html`` (``pip install '.[docs]'`` first).
"""

from __future__ import annotations

import logging
import shutil
from importlib import metadata
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent

project = "pincal"
author = "the pincal authors"
copyright = "the pincal authors, BSD-3-Clause"
release = metadata.version("pincal")
version = release

extensions = [
    "myst_nb",  # Markdown pages (it includes myst-parser) and notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinxarg.ext",
]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "jupyter_execute", "**.ipynb_checkpoints"]
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# The notebooks live in notebooks/ (the test suite executes them); they are copied here at each
# build. They store no outputs, so myst-nb runs each one once (about a minute for all six) and
# keeps the outputs in a cache under _build; a notebook whose code has not changed is not run again.
NOTEBOOKS = DOCS / "reference" / "notebooks"
shutil.rmtree(NOTEBOOKS, ignore_errors=True)
NOTEBOOKS.mkdir()
for _nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
    shutil.copy2(_nb, NOTEBOOKS / _nb.name)
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_timeout = 300
nb_execution_raise_on_error = True
nb_execution_show_tb = True

# The API reference: Google-style docstrings, members in source order, type hints in the text.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}
# Type names in signatures that Sphinx cannot link (NumPy, Pinocchio, forward references).
nitpicky = False
suppress_warnings = ["myst.header", "mystnb.unknown_mime_type"]

# The toctrees end with a glob that lists any page not named in them (index.md says why). When
# every page is named, the glob matches nothing and Sphinx warns, with no warning type that
# suppress_warnings could name (Sphinx 9.0): that one message is dropped, nothing else.
logging.getLogger("sphinx.sphinx.directives.other").addFilter(
    lambda record: "didn't match any documents" not in record.getMessage()
)

html_theme = "furo"
html_title = f"pincal {release}"
