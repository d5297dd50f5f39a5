"""Write the intersphinx inventories the site links Python, NumPy, SciPy and xarray names with: ``python.inv``,
``numpy.inv``, ``scipy.inv``, ``xarray.inv`` beside this file, read by ``docs/conf.py`` (``intersphinx_mapping``), so that the
build never needs the internet.

Each inventory lists the public names of the installed package under the address its documentation gives them:
NumPy, SciPy and xarray document one object per page under ``generated/<dotted name>.html`` (NumPy's random
generator and its glossary excepted, written out below); of Python, the built-in types, functions and constants
that numpydoc links a docstring's types to (``int``, ``float``, ``None``, ``callable``, ...). Run from the repository's root after a change of the
packages' versions, and commit the files::

    python docs/inventories/make_inventories.py
"""

import importlib
import inspect
import zlib
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: SciPy's subpackages whose public functions and classes are listed (those tumble and its pages use, and their
#: neighbours).
SCIPY_SUBPACKAGES = ("differentiate", "integrate", "interpolate", "linalg", "optimize", "special", "stats")
#: Classes whose methods and attributes get entries of their own.
CLASSES_WITH_MEMBERS = {"numpy": ("ndarray",), "xarray": ("Dataset", "DataArray")}
#: NumPy glossary terms (std:term), as the numpydoc "Parameters" sections use them.
NUMPY_TERMS = ("array_like", "array", "dtype", "broadcast", "ufunc", "view")


def _role(obj):
    if inspect.isclass(obj):
        return "py:class"
    if callable(obj):
        return "py:function"
    return None


def _members(prefix, cls, page):
    """Entries for the public methods and attributes of ``cls`` (``prefix``: its dotted name)."""
    rows = []
    for name, member in inspect.getmembers(cls):
        if name.startswith("_"):
            continue
        role = "py:method" if callable(member) else "py:attribute"
        rows.append((f"{prefix}.{name}", role, page.format(name=f"{prefix}.{name}")))
    return rows


def python_rows():
    import builtins
    import sys

    rows = []
    for name in dir(builtins):
        obj = getattr(builtins, name)
        if name.startswith("_") or (inspect.isclass(obj) and issubclass(obj, BaseException)):
            continue
        if inspect.isclass(obj):
            rows.append((name, "py:class", "library/functions.html#$"))
        elif callable(obj):
            rows.append((name, "py:function", "library/functions.html#$"))
    rows += [(name, "py:data", "library/constants.html#$") for name in ("None", "True", "False", "Ellipsis")]
    rows += [(term, "std:term", f"glossary.html#term-{term}") for term in ("iterable", "sequence", "generator",
                                                                           "mapping", "callable")]
    rows.append(("bltin-boolean-values", "std:label", "library/stdtypes.html#$"))
    return "Python", f"{sys.version_info.major}.{sys.version_info.minor}", rows


def numpy_rows():
    import numpy as np

    rows = []
    for name in dir(np):
        if name.startswith("_"):
            continue
        role = _role(getattr(np, name))
        if role:
            rows.append((f"numpy.{name}", role, f"reference/generated/numpy.{name}.html#$"))
    for cls in CLASSES_WITH_MEMBERS["numpy"]:
        rows += _members(f"numpy.{cls}", getattr(np, cls), "reference/generated/{name}.html#$")
    rows += [("numpy.random.Generator", "py:class", "reference/random/generator.html#$"),
             ("numpy.random.default_rng", "py:function", "reference/random/generator.html#$")]
    rows += _members("numpy.random.Generator", np.random.Generator, "reference/random/generated/{name}.html#$")
    rows += [(term, "std:term", f"glossary.html#term-{term}") for term in NUMPY_TERMS]
    rows.append(("arrays.scalars", "std:label", "reference/arrays.scalars.html#$"))  # numpydoc's "scalar"
    return "NumPy", np.__version__, rows


def scipy_rows():
    import scipy

    rows = []
    for sub in SCIPY_SUBPACKAGES:
        module = importlib.import_module(f"scipy.{sub}")
        rows.append((f"scipy.{sub}", "py:module", f"reference/{sub}.html#module-$"))
        for name in getattr(module, "__all__", ()):
            role = _role(getattr(module, name, None))
            if role:
                rows.append((f"scipy.{sub}.{name}", role, f"reference/generated/scipy.{sub}.{name}.html#$"))
    return "SciPy", scipy.__version__, rows


def xarray_rows():
    import xarray as xr

    rows = [("xarray", "py:module", "api.html#module-$")]
    for name in xr.__all__:
        role = _role(getattr(xr, name))
        if role:
            rows.append((f"xarray.{name}", role, f"generated/xarray.{name}.html#$"))
    for cls in CLASSES_WITH_MEMBERS["xarray"]:
        rows += _members(f"xarray.{cls}", getattr(xr, cls), "generated/{name}.html#$")
    return "xarray", xr.__version__, rows


def write(path, project, version, rows):
    """An intersphinx inventory (Sphinx's format, version 2) of ``rows``: (name, domain:role, address)."""
    header = (f"# Sphinx inventory version 2\n# Project: {project}\n# Version: {version}\n"
              "# The remainder of this file is compressed using zlib.\n")
    body = "".join(f"{name} {role} {1 if role.startswith('py:') else -1} {uri} -\n"
                   for name, role, uri in sorted(set(rows)))
    path.write_bytes(header.encode() + zlib.compress(body.encode()))
    return len(set(rows))


def main():
    for stem, rows in (("python", python_rows), ("numpy", numpy_rows), ("scipy", scipy_rows), ("xarray", xarray_rows)):
        project, version, entries = rows()
        count = write(HERE / f"{stem}.inv", project, version, entries)
        print(f"{HERE / f'{stem}.inv'}: {count} names of {project} {version}")


if __name__ == "__main__":
    main()
