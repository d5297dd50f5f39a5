"""Sphinx configuration of tumble's documentation site.

Build: ``sphinx-build -W --keep-going -b html docs docs/_build/html`` (``pip install ".[docs]"`` first).
Warnings are errors: a broken cross-reference, a page outside every toctree or a public name without a
docstring (``_ext/tumble_docs.py``) fails the build. ``tests/test_docs.py`` runs that build in the test suite.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

from tumble import __version__  # noqa: E402 - after the path of the local extension

project = "tumble"
author = "the tumble developers"
copyright = "2026, the tumble developers"  # noqa: A001 - the name Sphinx reads
release = version = __version__

extensions = [
    "myst_parser",           # the Markdown pages (docs/*.md) as they are
    "sphinx.ext.autodoc",    # the Python API from the docstrings
    "sphinx.ext.viewcode",   # [source] links: the code of each function and class, highlighted, on the site
    "sphinx.ext.intersphinx",  # links to NumPy, SciPy and xarray names, from inventories in docs/inventories/
    "numpydoc",              # ... which are numpydoc style
    "sphinx.ext.mathjax",    # the equations, with a MathJax the site carries (_ext/tumble_docs.py: no CDN)
    "sphinx_copybutton",     # a copy button on every code block that leaves out >>> prompts and output
    "sphinxarg.ext",         # the command line from tumble.cli's parser
    "tumble_docs",           # generated reference tables and the docstring check (_ext/tumble_docs.py)
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "inventories"]

myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3  # the pages link to their sections by GitHub-style anchors (#growth-rates-against-...)

autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpydoc Parameters sections give types, shapes and units
numpydoc_show_class_members = False
# The types in numpydoc's Parameters and Returns sections link to NumPy and xarray (ndarray, xarray.Dataset, ...);
# other words (shape, of, optional, tumble's own records) stay text.
numpydoc_xref_param_type = True
numpydoc_xref_ignore = "all"
numpydoc_xref_aliases = {
    "ndarray": "numpy.ndarray",
    "array_like": ":term:`numpy:array_like`",
    "array-like": ":term:`numpy:array_like`",
    "Generator": "numpy.random.Generator",
    "Dataset": "xarray.Dataset",
    "DataArray": "xarray.DataArray",
    "xarray.Dataset": ":class:`xarray.Dataset`",  # a name that is its own target: as a role (numpydoc's rule)
    "xarray.DataArray": ":class:`xarray.DataArray`",
    "numpy.ndarray": ":class:`numpy.ndarray`",
    "np.ndarray": "numpy.ndarray",
    "Body": "tumble.Body",
    "System": "tumble.System",
}

# Intersphinx (Python, NumPy, SciPy, xarray) from inventories kept in the repository (docs/inventories/make_inventories.py writes them from the
# installed packages): the build never fetches anything.
_INVENTORIES = Path(__file__).parent / "inventories"
intersphinx_mapping = {
    "python": ("https://docs.python.org/3/", str(_INVENTORIES / "python.inv")),
    "numpy": ("https://numpy.org/doc/stable/", str(_INVENTORIES / "numpy.inv")),
    "scipy": ("https://docs.scipy.org/doc/scipy/", str(_INVENTORIES / "scipy.inv")),
    "xarray": ("https://docs.xarray.dev/en/stable/", str(_INVENTORIES / "xarray.inv")),
}

# Nitpicky: a Python cross-reference to a name of the public face (tumble.integrate, tumble.exact.omega, ...) that
# does not resolve fails the build. The docstrings also name internals the site does not document (the layers'
# other modules, e.g. tumble.kernels.closed_form.elliptic, and unqualified helpers such as scene_batch): those are let through.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"tumble\.(kernels|engine|measure|pipeline|output|physics|registry)(\..*)?"),
    (r"py:.*", r"(?!tumble\.)[A-Za-z_]\w*(\.\w+)?"),
]

# Furo rather than the PyData theme of NumPy and xarray: a site of some thirty pages reads best with the whole
# Diataxis tree in one left sidebar (PyData's header tabs and per-section sidebars suit hundreds of pages), it has a
# dark mode and a readable mobile layout without configuration, and it needs no theme options to be right.
html_theme = "furo"
html_title = f"tumble {release}"
html_static_path = [str(Path(__file__).parent / "_static")]  # absolute: tests/test_docs.py builds other folders too
html_css_files = ["tumble.css"]  # phone-width tables, equations and code blocks; the gallery's grid

# Copy buttons: a pycon block's prompts (>>>, ...) and output are left out by their highlighting classes; the regular
# expression does the same for prompts written in a plain block.
copybutton_prompt_text = r">>> |\.\.\. |\$ "
copybutton_prompt_is_regexp = True
