"""The layers are folders and imports point down only (docs/architecture.md).

Every module of the package is parsed (never imported) and each of its imports of tumble — at the top or
inside a function — is checked against the layer order below. ``output`` sits above ``measure`` in the
order but may not import it, nor the engine: a dataset or a figure is built from records and arrays alone.
"""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "tumble"

# Bottom to top; a module may import its own layer and the layers below it. `_interrupt` (Ctrl-C while the command
# starts), `_startup` (the command's imports without the garbage collector) and `_disk` (a failed write's diagnosis)
# import nothing of tumble, like `_version`. `warm` imports only the registry (the methods' names): it runs the public
# API's calls in new interpreters, so it sits above every layer those calls reach, below the command line that offers
# it.
LAYERS = ("_version", "_interrupt", "_startup", "_disk", "registry", "kernels", "physics", "engine", "measure", "output",
          "pipeline", "warm", "cli", "__main__", "__init__")
# The face's short paths (tumble/exact.py, ...): each puts a layer's module in its place (tumble._ALIASES), so they
# are the face, like __init__.
FACE_ALIASES = {path.stem for path in PACKAGE.glob("*.py")
                if path.read_text().rstrip().endswith(f"sys.modules[__name__] = {path.stem}")}
FORBIDDEN = {"output": {"engine", "measure"}}
# Third-party packages a layer must not import.
FORBIDDEN_EXTERNAL = {"kernels": {"xarray", "matplotlib", "tqdm", "dask", "netCDF4", "scipy"},
                      "physics": {"xarray", "matplotlib", "dask"}}


def _layer(parts):
    """Layer of a module given as the parts of its dotted path below ``tumble``."""
    return "__init__" if not parts or (len(parts) == 1 and parts[0] in FACE_ALIASES) else parts[0]


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        yield path, parts


def _imports(path, parts):
    """(dotted module below tumble as parts, line) for every tumble import; external roots separately."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = parts[:-1] if parts[-1] != "__init__" else parts[:-1]
    inside, outside = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                target = list(base) + (node.module.split(".") if node.module else [])
                if not node.module:  # from . import a, b: each name may be a module
                    for alias in node.names:
                        inside.append((tuple(target + [alias.name]), node.lineno))
                    continue
                inside.append((tuple(target), node.lineno))
            elif node.module and node.module.split(".")[0] == "tumble":
                inside.append((tuple(node.module.split(".")[1:]), node.lineno))
            elif node.module:
                outside.append((node.module.split(".")[0], node.lineno))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                root = alias.name.split(".")
                if root[0] == "tumble":
                    inside.append((tuple(root[1:]), node.lineno))
                else:
                    outside.append((root[0], node.lineno))
    return inside, outside


MODULES = list(_modules())


def test_every_module_sits_in_a_known_layer():
    assert MODULES
    unknown = [str(p) for p, parts in MODULES if _layer(parts) not in LAYERS]
    assert not unknown, f"modules outside the layers of docs/architecture.md: {unknown}"


@pytest.mark.parametrize("path, parts", MODULES, ids=[".".join(parts) for _, parts in MODULES])
def test_imports_point_down(path, parts):
    own = _layer(parts)
    inside, outside = _imports(path, parts)
    wrong = []
    for target, line in inside:
        layer = _layer(target)
        if layer not in LAYERS:
            wrong.append(f"line {line}: tumble.{'.'.join(target)} is in no layer")
        elif LAYERS.index(layer) > LAYERS.index(own) or layer in FORBIDDEN.get(own, ()):
            wrong.append(f"line {line}: {own} imports {layer} (tumble.{'.'.join(target)})")
        elif own != "__init__" and layer == "__init__":
            wrong.append(f"line {line}: imports the package face")
    for root, line in outside:
        if root in FORBIDDEN_EXTERNAL.get(own, ()):
            wrong.append(f"line {line}: {own} imports {root}")
    assert not wrong, f"{path.relative_to(PACKAGE.parent)}: " + "; ".join(wrong)


def test_the_checker_sees_an_upward_import(tmp_path):
    """The test above can fail: an engine module importing the pipeline is caught."""
    bad = tmp_path / "bad.py"
    bad.write_text("from ..pipeline import config\nfrom . import sampling\nimport xarray\n")
    inside, outside = _imports(bad, ("engine", "bad"))
    assert (("pipeline",), 1) in inside and (("engine", "sampling"), 2) in inside
    assert ("xarray", 3) in outside
    layers = {_layer(target) for target, _ in inside}
    assert any(LAYERS.index(layer) > LAYERS.index("engine") for layer in layers)



@pytest.mark.parametrize("layer", ("kernels", "physics", "engine", "measure", "output", "pipeline"))
def test_every_layer_states_its_public_names(layer):
    """Each layer's ``__init__.py`` has an ``__all__``; each name in it is a module of the layer, a name its
    ``__init__`` binds or, for a lazy door (``tumble.kernels``), a name its ``_DOOR`` maps to a module that holds it
    (parsed, not imported, but for the door's map: ``tumble.measure``'s must stay empty of imports)."""
    path = PACKAGE / layer / "__init__.py"
    tree = ast.parse(path.read_text())
    stated = [ast.literal_eval(node.value) for node in tree.body if isinstance(node, ast.Assign)
              and any(isinstance(target, ast.Name) and target.id == "__all__" for target in node.targets)]
    assert stated, f"tumble/{layer}/__init__.py has no __all__"
    bound = {alias.asname or alias.name for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))
             for alias in node.names}
    bound |= {node.name for node in tree.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
    bound |= {target.id for node in tree.body if isinstance(node, ast.Assign) for target in node.targets
              if isinstance(target, ast.Name)}
    unknown = [name for name in stated[-1] if name not in bound and not (PACKAGE / layer / f"{name}.py").exists()
               and not (PACKAGE / layer / name / "__init__.py").exists()]  # a module, or a package of modules
    if "_DOOR" in bound:
        import importlib

        door = importlib.import_module(f"tumble.{layer}")._DOOR
        unknown = [name for name in unknown if name not in door]
        for name, (module, attribute) in door.items():  # each name the door maps is there
            found = importlib.import_module(f"tumble.{layer}.{module}")
            assert attribute is None or hasattr(found, attribute), f"tumble.{layer}._DOOR[{name!r}]"
    assert not unknown, f"tumble/{layer}/__init__.py's __all__ names what it neither binds nor holds: {unknown}"

# --- one owner per concept: the registry's tables and the kernels agree ---------------------------------------

def test_the_kernels_coefficient_tables_are_the_registrys_stepping_methods():
    from tumble import registry
    from tumble.kernels import METHODS, tableaux

    assert tuple(METHODS) == registry.STEPPING
    assert sorted(tableaux.METHOD_ORDER) == sorted(registry.STEPPING)
    for name, kernel in METHODS.items():
        assert kernel.order == registry.method(name).order == kernel.coefficients.order, name
        assert registry.STEPPING[kernel.kernel_id] == name
    assert registry.STATUS_NAMES[registry.STATUS_OK] == "ok"


def test_only_the_engine_the_closed_form_and_the_estimators_open_the_kernels_door():
    """Outside tumble/kernels/, modules import `tumble.kernels` itself (its __init__), never a module inside,
    and only the engine, physics/exact.py and measure/estimators.py (the phase fit's loop) do."""
    wrong = []
    for path, parts in MODULES:
        if parts[0] == "kernels":
            continue
        inside, _ = _imports(path, parts)
        for target, line in inside:
            if target[:1] != ("kernels",):
                continue
            door = len(target) == 1 or (len(target) == 2 and target[1] == "elliptic" and parts == ("physics", "exact"))
            allowed = parts[0] == "engine" or parts in (("physics", "exact"), ("measure", "estimators"))
            if not (door and allowed):
                wrong.append(f"{'.'.join(parts)} line {line}: tumble.{'.'.join(target)}")
    assert not wrong, wrong


@pytest.mark.parametrize("name, torque_free, intermediate, flips, chosen", [
    ("auto", True, True, 3, "exact"),
    ("auto", True, False, 0, "exact"),
    ("auto", True, False, 3, "rk4"),
    ("auto", False, True, 0, "rk4"),
    ("splitting4", False, True, 0, "splitting4"),
    ("exact", True, False, 3, "exact"),
])
def test_auto_is_decided_in_one_place(name, torque_free, intermediate, flips, chosen):
    from tumble import registry

    assert registry.choose_method(name, torque_free=torque_free, axis_is_intermediate=intermediate,
                                  flips=flips)[0] == chosen


@pytest.mark.parametrize("name, torque_free, message", [
    ("exact", False, "cannot take a torque"), ("rk5", True, "method must be one of"), (None, True, "method must be")])
def test_choose_method_refuses_what_cannot_run(name, torque_free, message):
    from tumble import registry

    with pytest.raises(ValueError, match=message):
        registry.choose_method(name, torque_free=torque_free)


# --- function size (issue 16: no function over ~60 lines or ~8 parameters without a reason beside it) ----------
MAX_LINES, MAX_PARAMETERS = 60, 8


def _oversized(source):
    """``(name, line, why)`` of each function whose code (docstring excluded) runs over MAX_LINES lines or which
    takes more than MAX_PARAMETERS parameters (``self`` aside), and has no ``# size:`` comment before its code."""
    tree = ast.parse(source)
    lines = source.splitlines()
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        body = node.body
        if (len(body) > 1 and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            body = body[1:]
        length = body[-1].end_lineno - body[0].lineno + 1
        args = node.args
        count = sum(a.arg not in ("self", "cls") for a in args.posonlyargs + args.args + args.kwonlyargs)
        head = lines[node.lineno - 1:body[0].lineno - 1]
        if (length > MAX_LINES or count > MAX_PARAMETERS) and not any(
                line.strip().startswith("# size:") for line in head):
            found.append((node.name, node.lineno, f"{length} lines, {count} parameters"))
    return found


def test_long_functions_and_long_argument_lists_say_why():
    """Kernels take flat arrays and scalars by design (DESIGN.md: records above the kernels' door, arrays below;
    ``kernels.loops.methods`` packs them), so a short kernel function may take many; anything else over the limits
    carries a ``# size:`` comment saying why."""
    offenders = []
    for path, _ in _modules():
        if path.name == "fused.py":  # generated from the coefficient tables (kernels/steps/codegen.py)
            continue
        for name, line, why in _oversized(path.read_text()):
            if "kernels" in path.relative_to(PACKAGE).parts and "lines" in why and int(why.split()[0]) <= MAX_LINES:
                continue
            offenders.append(f"{path.relative_to(PACKAGE)}:{line} {name} ({why})")
    assert not offenders, "functions over the size limits with no '# size:' reason:\n" + "\n".join(offenders)


def test_the_size_check_sees_a_long_argument_list():
    source = "def f(a, b, c, d, e, f, g, h, i):\n    return a\n\n\ndef g(a, b, c, d, e, f, g, h, i):\n    # size: ok\n    return a\n"
    assert [name for name, _, _ in _oversized(source)] == ["f"]


def test_every_subpackage_is_installed():
    """pyproject.toml lists the packages by hand (studies/ is installed as tumble/studies/): a folder of the package
    missing from the list installs without its modules (tumble.kernels.systems once did: `tumble run` failed)."""
    import tomllib

    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(("tumble", *path.relative_to(PACKAGE).parent.parts)) for path in PACKAGE.rglob("__init__.py")}
    assert found - listed == set(), "add them to [tool.setuptools] packages in pyproject.toml"


def test_no_two_hand_written_modules_share_a_name():
    """A module's name says what it holds, once (issue 40): no two hand-written modules of the package share a file
    name (``__init__.py`` aside). A generated module (its first line says GENERATED) may carry the name of the one it
    is copied from: ``kernels/systems/heavy_top.py`` is the kernels' copy of ``physics/models/heavy_top.py``'s
    equations; a short path of the face (``tumble/exact.py``) is the module it names."""
    names = {}
    for path, _ in MODULES:
        if (path.name != "__init__.py" and path.stem not in FACE_ALIASES
                and not path.read_text().startswith('"""GENERATED')):
            names.setdefault(path.name, []).append(path.relative_to(PACKAGE).as_posix())
    shared = {name: paths for name, paths in names.items() if len(paths) > 1}
    assert not shared, shared

