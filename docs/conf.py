"""Sphinx configuration of mitlc's documentation site (``make docs``).

The pages are Markdown (MyST); the API reference is generated from the docstrings (autodoc with
napoleon) and the CLI reference from the Typer app (``docs/_ext/cli_reference.py``, which writes
``docs/cli.md`` at each build). Nothing here reaches the network.
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(DOCS.parent))

from mitlc import __version__  # noqa: E402

project = "mitlc"
author = "the mitlc authors"
copyright = "the mitlc authors"
release = __version__
version = __version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "prose_attributes",
    "cli_reference",
    "existing_refs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "figures/*.py", "Thumbs.db", ".DS_Store"]

# MyST: `:::` fences, and anchors for headings down to ### so that `page.md#section` links
# resolve (GitHub's slugs).
myst_enable_extensions = ["colon_fence"]
myst_heading_anchors = 3
# Quotes as typed: a command-line value such as '-' is shown as it is typed.
smartquotes = False

# autodoc: members in source order, types in the signatures (a pydantic model's fields would list
# their validators' metadata as types in the description).
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"show-inheritance": True}
# The docstrings are reST: napoleon reads Args:/Returns: sections where a function has them, and
# leaves attribute docstrings to reST (prose_attributes).
napoleon_google_docstring = True
napoleon_numpy_docstring = False

html_theme = "furo"
html_title = f"mitlc {__version__}"
html_static_path: list[str] = []
