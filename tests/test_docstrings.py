"""The docstrings of the public API (what the API index lists, ``docs/_ext/tumble_docs.py``): every function and class
has an Examples section that runs as written and a See Also section, and the pages with an equation typeset it and
cite its source. The examples run group by group of the index (one test case per group), as doctest runs them: the
output compared with ``...`` matching anything and runs of white space alike."""

import doctest
import inspect
import sys
from pathlib import Path

import pytest
from numpydoc.docscrape import NumpyDocString

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs" / "_ext"))
import tumble_docs  # noqa: E402 - docs/_ext is not a package

tumble_docs._public_module_aliases()  # noqa: SLF001 - `import tumble.exact`, as the site's build does

GROUPS = {title: [name for module, names in parts for name in names] for title, _, parts in tumble_docs.api_groups()}

#: The pages with an equation: their Notes typeset it (``.. math::`` or ``:math:``) and References cite its source.
WITH_EQUATIONS = ("tumble.integrate", "tumble.measure", "tumble.flip_time_law", "tumble.lyapunov", "tumble.megno",
                  "tumble.gali", "tumble.exact.omega", "tumble.exact.period", "tumble.exact.attitude",
                  "tumble.exact.flip_spacing", "tumble.exact.first_flip_time", "tumble.exact.rotation_per_period",
                  "tumble.theory.linear", "tumble.theory.stability_exponent", "tumble.theory.flip_time_asymptote")


def _sections(obj):
    return NumpyDocString(inspect.getdoc(obj) or "")


def test_every_public_function_and_class_has_examples_and_see_also():
    objects = tumble_docs.public_objects()
    assert len(objects) >= 70 and "tumble.exact.omega" in objects and "tumble.exact.omega_on_device" not in objects
    missing = {name: [section for section in ("Examples", "See Also") if not _sections(obj)[section]]
               for name, obj in objects.items()}
    missing = {name: sections for name, sections in missing.items() if sections}
    assert not missing, f"public names without these docstring sections: {missing}"
    without = [name for name in WITH_EQUATIONS
               if not (":math:" in "\n".join(_sections(objects[name])["Notes"])
                       or ".. math::" in "\n".join(_sections(objects[name])["Notes"]))
               or not _sections(objects[name])["References"]]
    assert not without, f"pages with an equation whose Notes typeset none or that cite no References: {without}"


@pytest.mark.parametrize("group", list(GROUPS))
def test_the_examples_of_every_public_name_run(group):
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    ran = []
    for name in GROUPS[group]:
        obj = tumble_docs._resolve(name)  # noqa: SLF001
        for test in finder.find(obj, name, module=inspect.getmodule(obj)):
            if test.examples:
                runner.run(test)
                ran.append(name)
    results = runner.summarize(verbose=False)
    assert ran, f"no examples in the group {group!r}"
    assert results.failed == 0, f"{results.failed} of {results.attempted} examples of {group!r} failed (above)"
