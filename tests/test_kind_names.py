"""Each built-in model's kind name stands in at most its own module, the registry and the study schema (issue 40).

Code elsewhere asks the model what it is (its class's attributes and methods, :mod:`tumble.physics.models`) or reads
a registry row (``registry.MODELS``, ``registry.FIGURE_MODELS``); it never switches on a kind's name. Every module of
the package is parsed (never imported), and a string literal that *is* a kind name (``"damper"``) or quotes one
(``"model kind 'damper'"``, the way a message or a docstring would write it) fails, wherever it stands: code,
f-string parts and docstrings alike (a docstring that spells out the kinds goes stale when one is added; it can name
the registry or the classes instead). Prose that uses a kind's word unquoted ("a heavy top", "the damper") is not a
kind name and passes.

Exempt: ``registry.py`` and ``pipeline/schema.py`` (the data and the study's documented fields), the generated modules
(``kernels/steps/fused.py``, ``kernels/steps/model_steps.py``, ``kernels/systems/<module>.py``: their first line says GENERATED),
and a kind's own modules for its own kind: its model class's (``physics/models/heavy_top.py`` for ``"heavy_top"``,
...) and the one that holds its equations (its registry row's ``equations_module``: the free body's are the
gyrostat's).
"""

import ast
from pathlib import Path

from tumble import registry
from tumble.physics import models

PACKAGE = Path(__file__).resolve().parents[1] / "tumble"

EXEMPT = {"registry.py", "pipeline/schema.py"}


def _generated(path):
    return path.read_text().startswith('"""GENERATED')


def _file(module):
    """The file (relative to the package, posix) of the dotted ``module``."""
    return Path(*module.split(".")[1:]).with_suffix(".py").as_posix()


def _own_module(kind):
    """The file that defines the class of model ``kind``."""
    return _file(models.CLASSES[kind].__module__)


def _own_modules(kind):
    """The files that may name ``kind``: its class's module and its equations' (one file for every kind but the free
    body)."""
    return {_own_module(kind), _file(models.CLASSES[kind].equations().__name__)}


def _kind_literals(path):
    """``(line, kind, literal)`` for every string literal of ``path`` that is a kind name or quotes one."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Constant) and isinstance(node.value, str)):
            continue
        for kind in registry.MODEL_KINDS:
            if node.value == kind or f"'{kind}'" in node.value or f'"{kind}"' in node.value:
                found.append((node.lineno, kind, node.value if len(node.value) < 80 else node.value[:77] + "..."))
    return found


def _offences():
    own = {kind: _own_modules(kind) for kind in registry.MODEL_KINDS}
    offences = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel in EXEMPT or _generated(path):
            continue
        for line, kind, literal in _kind_literals(path):
            if rel not in own[kind]:
                offences.append(f"{rel}:{line}: {kind!r} in {literal!r}")
    return offences


def test_every_kind_has_a_class_whose_module_is_a_file_of_the_package():
    for kind in registry.MODEL_KINDS:
        assert models.CLASSES[kind].kind == kind
        assert (PACKAGE / _own_module(kind)).is_file()


def test_the_detector_finds_a_kind_name_as_a_literal_and_quoted_in_a_message(tmp_path):
    source = tmp_path / "example.py"
    source.write_text('"""A heavy top, unquoted: fine."""\n'
                      'if model.kind == "damper":\n'
                      '    raise ValueError(f"needs model kind \'gyrostat\', got {kind!r}")\n')
    assert [(line, kind) for line, kind, _ in _kind_literals(source)] == [(2, "damper"), (3, "gyrostat")]


def test_no_module_switches_on_a_model_kind_name():
    offences = _offences()
    assert offences == [], ("kind names outside their model's module, the registry and the schema (ask the model "
                            "class or read a registry row instead):\n" + "\n".join(offences))


def test_the_exempt_generated_modules_are_the_models_steps_and_equations():
    generated = {path.relative_to(PACKAGE).as_posix() for path in PACKAGE.rglob("*.py") if _generated(path)}
    equations = {f"kernels/systems/{m.equations_module}.py" for m in registry.MODELS}
    assert generated == {"kernels/steps/fused.py", "kernels/steps/model_steps.py", *equations}


def _named_in(path, names):
    """The names of ``names`` that module ``path`` holds as an identifier (a variable, attribute, function, argument,
    keyword or imported module) or as a string that is not a docstring."""
    tree = ast.parse(path.read_text(), filename=str(path))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            words = [node.id]
        elif isinstance(node, ast.Attribute):
            words = [node.attr]
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            words = [node.name]
        elif isinstance(node, (ast.arg, ast.keyword)):
            words = [node.arg]
        elif isinstance(node, ast.alias):
            words = [*node.name.split("."), node.asname]
        elif isinstance(node, ast.ImportFrom):
            words = (node.module or "").split(".")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            words = [node.value]
        else:
            continue
        found.update(word for word in words if word in names)
    return found


def test_a_model_or_a_method_is_named_in_at_most_three_files():
    """A built-in system is its file and its registry row (issue 55): each model kind and each method, the defaults
    aside (``free``, ``rk4``: named where a default is chosen), stands in the code of at most 3 files of the package
    (its own, the registry, and the generated dispatch for a model; the coefficient tables and the registry for a
    method), never in a loop, a scene or a figure that must then learn it. Unlike the test above, this one reads
    identifiers too (a variable, a function, an imported module named after a kind) and not docstrings."""
    names = {*registry.MODEL_KINDS, *registry.STEPPING} - {registry.FREE_BODY, "rk4"}
    files = {name: [] for name in names}
    for path in sorted(PACKAGE.rglob("*.py")):
        for name in _named_in(path, names):
            files[name].append(path.relative_to(PACKAGE).as_posix())
    assert {name: where for name, where in files.items() if len(where) > 3} == {}
    assert all(files.values()), "each name is found somewhere (the search works)"
