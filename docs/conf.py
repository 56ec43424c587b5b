"""Sphinx configuration of the fpr documentation.

Build: ``pip install -e ".[docs]" && python -m sphinx -W --keep-going -b html docs docs/_build/html``.
Pages are Markdown (MyST); the API reference comes from the docstrings (autodoc, Google style through
napoleon); the benchmark tables are rendered from ``docs/bench/bench.json`` by ``_ext/bench_tables.py``.
"""

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import fpr  # noqa: E402  (installed with the docs extra: autodoc imports the package)

project = "fpr"
author = "fpr contributors"
copyright = "fpr contributors"  # noqa: A001 (Sphinx's name)
release = fpr.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "bench_tables",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "README.md"]

myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented"  # types beside documented arguments, no second bare list
autodoc_preserve_defaults = True
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
# "Class attributes:" (fpr.robots.base.RobotKind) reads like "Args:"
napoleon_custom_sections = [("Class attributes", "params_style")]
napoleon_use_ivar = True  # an Attributes section as fields: no second description of a documented property

html_theme = "furo"
html_title = f"fpr {release}"
html_static_path = []
