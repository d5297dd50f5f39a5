"""A user's System on the built-ins' vectorised block path: its rate (and Jacobian) rewritten as the built-ins'
equations are written, and their steps generated from it.

A built-in system's equations are scalar functions, ``rate(t, *y, c)`` returning the derivative as a tuple, that
the generated steps (:mod:`tumble.kernels.steps.model_codegen`) inline into a loop over a block's samples, the state in
registers, vectorised across samples. A user's rate ``rate(t, y, p, dydt)`` writes arrays of one sample. When it
reads the state and writes the derivative at constant indices only (``y[0]``, ``dydt[2] = ...``: straight-line
code, branches allowed, which is how equations of motion are written), :func:`scalar_rate` rewrites its syntax
tree into that scalar form: ``y[j]`` becomes a variable, ``dydt[j] = e`` an assignment to another, and the function
returns them (``p`` stays, a tuple of the parameters that the block step reads once). A Jacobian ``J[i, j] = e``
becomes the tangent flow ``J v`` the same way; without one, the tangent is the per-sample loop's fourth-order
difference (:func:`tumble.kernels.loops.tangent_loop.difference_tangents`) spelled out, its components' scales
literals. The steps are then the built-ins' generated ones, for rk4 and rk8 (``model_codegen.METHODS``).

A rate that does anything else with its arrays (a loop over components, ``len(y)``, a slice, an array passed on)
has no scalar form: :class:`NotScalar` says why, and the engine runs it with the per-sample loop
(:mod:`tumble.kernels.loops.sample_loop`).

**Codes.** Each rewritten system is a code at or above :data:`SYSTEM_CODES` (the built-ins' are their index in
``registry.MODEL_KINDS``, the free body's -1): a hash of the generated source and of what the rate reads from its
module (numbers, arrays, modules, functions by their source). The block loops (:mod:`tumble.kernels.loops.block_loop`,
:mod:`tumble.kernels.loops.tangent_blocks`) take it as the literal they take a built-in's code as, and look its steps up
here (:func:`block_step`, :func:`tangent_step`) when they compile. Their drivers are cached on disk keyed by their
codes (numba's cache keys a closure by its constants): a new process with the same System loads them and compiles
nothing. A rate that reads something that cannot be keyed (an object of another kind) gets a code unique to the
process, and its drivers are not cached (:func:`cacheable`).
"""

import ast
import hashlib
import inspect
import itertools
import linecache
import math
import textwrap
import types
from collections import namedtuple

import numpy as np

from . import control, model_codegen
from ..jit import jit
from .. import tableaux
from ..tableaux import TABLEAUX
from ..trig import _max, _min

__all__ = ["DIFFERENCE_STEP", "NotScalar", "SYSTEM_CODES", "block_attempt", "block_constants", "block_step", "cacheable",
           "functions_key", "reads_by_name", "runs", "scalar_rate", "scalar_tangent", "system_code", "tangent_code",
           "tangent_step"]

#: The relative step of the difference tangents (:func:`tumble.kernels.loops.tangent_loop.difference_tangents` and a
#: System's generated ones): about ``eps ** (1/5)`` (a power of two), where the fourth-order truncation error
#: ``step**4 |f^(5)| / 30`` and the rounding error ``eps |f| / step`` balance, both near 1e-13 of a smooth rate of unit
#: scale.
DIFFERENCE_STEP = 2.0 ** -10

#: The smallest code of a user's System (below: the built-in models' codes and the free body's).
SYSTEM_CODES = 1 << 48

#: Bumped when what this module generates changes, so that the disk cache's old drivers are not reused.
GENERATOR_VERSION = 1

#: The name the generated steps give the system (``system_rk4_block``, ...) and its components (``z1``, ...).
_NAME = "system"

_UNCACHED = itertools.count(1)


class NotScalar(ValueError):
    """A user's function that :func:`scalar_rate` cannot rewrite into the built-ins' scalar form, and why."""


def _uncached_jit(fn=None, **options):
    """:func:`tumble.kernels.jit.jit` without the disk cache: the generated functions have no file (their callers,
    the block loops' drivers, are cached with them compiled in)."""
    return jit(fn, cache=False, **options)


def _function_tree(fn, what):
    """The syntax tree of ``fn``'s definition (a numba function: its Python function's), its decorators removed;
    NotScalar when its source cannot be read or is not a plain function of four arguments."""
    fn = getattr(fn, "py_func", fn)
    try:
        source = textwrap.dedent(inspect.getsource(fn))
    except (OSError, TypeError):
        raise NotScalar(f"the source of {what} cannot be read") from None
    tree = ast.parse(source).body[0]
    if not isinstance(tree, ast.FunctionDef):
        raise NotScalar(f"{what} is not a def (a lambda)")
    if not _source_is_current(fn):
        raise NotScalar(f"the source of {what} on disk is no longer the function that runs (its file was edited "
                        f"since it was defined)")
    tree.decorator_list = []
    arguments = tree.args
    if (len(arguments.args) != 4 or arguments.vararg or arguments.kwarg or arguments.kwonlyargs
            or arguments.posonlyargs):
        raise NotScalar(f"{what} does not take exactly four arguments")
    for node in ast.walk(tree):
        if node is not tree and isinstance(node, (ast.FunctionDef, ast.Lambda, ast.ClassDef, ast.AsyncFunctionDef)):
            raise NotScalar(f"{what} defines a function inside")
        if isinstance(node, (ast.Global, ast.Nonlocal, ast.Yield, ast.YieldFrom)):
            raise NotScalar(f"{what} uses {type(node).__name__.lower()}")
    return tree


def _source_is_current(fn):
    """Whether the source :mod:`inspect` reads for ``fn`` is the code that runs: its file (or notebook cell) compiled
    again holds a function of its name and first line with its bytecode (a file edited since it was imported does
    not; the rewrite would run the edited equations)."""
    target = fn.__code__
    lines = linecache.getlines(target.co_filename, fn.__globals__)
    try:
        stack = [compile("".join(lines), target.co_filename, "exec", dont_inherit=True)]
    except (SyntaxError, ValueError):
        return False
    while stack:
        code = stack.pop()
        if code.co_name == target.co_name and code.co_firstlineno == target.co_firstlineno:
            return (code.co_code, code.co_consts, code.co_names) == (target.co_code, target.co_consts, target.co_names)
        stack.extend(c for c in code.co_consts if isinstance(c, types.CodeType))
    return False


def _index(node, size, array, what):
    """The constant index ``node`` (an int; negative from the end) into ``array`` of ``size``, else NotScalar."""
    value = node.value if isinstance(node, ast.Constant) else None
    if (isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub) and isinstance(node.operand, ast.Constant)):
        value = -node.operand.value if isinstance(node.operand.value, int) else None
    if not isinstance(value, int) or isinstance(value, bool) or not -size <= value < size:
        raise NotScalar(f"{what} indexes {array} with {ast.unparse(node)}, not a constant index in range")
    return value % size


class _Scalars(ast.NodeTransformer):
    """``array[i]`` (``array[i, j]`` for the matrix) of the given arrays into the variables ``names[array](i)``."""

    def __init__(self, arrays, what, parameters, n_parameters):
        self.arrays = arrays  # name -> (shape, variable name of an index tuple)
        self.what = what
        self.parameters, self.n_parameters = parameters, n_parameters
        self.written = {}  # name -> set of index tuples stored

    def visit_BinOp(self, node):
        """``x / p[k]`` into ``x * p[k + K]``: the parameters' record holds their reciprocals after them
        (:func:`block_constants`), a division per sample and stage made one per step."""
        node = self.generic_visit(node)
        right = node.right
        if (isinstance(node.op, ast.Div) and isinstance(right, ast.Subscript) and isinstance(right.value, ast.Name)
                and right.value.id == self.parameters and isinstance(right.slice, ast.Constant)
                and isinstance(right.slice.value, int) and 0 <= right.slice.value < self.n_parameters):
            reciprocal = ast.Subscript(value=ast.Name(id=self.parameters, ctx=ast.Load()),
                                       slice=ast.Constant(right.slice.value + self.n_parameters), ctx=ast.Load())
            return ast.copy_location(ast.BinOp(left=node.left, op=ast.Mult(), right=reciprocal), node)
        return node

    def visit_Subscript(self, node):
        if isinstance(node.value, ast.Name) and node.value.id in self.arrays:
            array = node.value.id
            shape, variable = self.arrays[array]
            items = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
            if len(items) != len(shape):
                raise NotScalar(f"{self.what} indexes {array} with {ast.unparse(node.slice)}, not {len(shape)} "
                                f"constant index(es)")
            index = tuple(_index(item, size, array, self.what) for item, size in zip(items, shape))
            if isinstance(node.ctx, ast.Store):
                self.written.setdefault(array, set()).add(index)
            return ast.copy_location(ast.Name(id=variable(index), ctx=node.ctx), node)
        return self.generic_visit(node)

    def visit_Name(self, node):
        if node.id in self.arrays:
            raise NotScalar(f"{self.what} uses the array {node.id} other than by a constant index (line "
                            f"{node.lineno} of its definition)")
        return node

    def visit_Return(self, node):
        if node.value is not None and not (isinstance(node.value, ast.Constant) and node.value.value is None):
            raise NotScalar(f"{self.what} returns a value")
        return node


def _rewrite(fn, what, arrays, result, arguments, n_parameters):
    """The source of ``fn``'s definition named ``_tumble_<what>``: its ``arrays`` (argument position -> (shape,
    variable name of an index tuple)) made variables, its arguments ``arguments(names)`` (``names``: its own), every
    ``return`` returning ``result(names, written)`` (``written``: array name -> the index tuples it stores)."""
    tree = _function_tree(fn, what)
    names = [a.arg for a in tree.args.args]
    used = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
    transformer = _Scalars({names[position]: spec for position, spec in arrays.items()}, what, names[2], n_parameters)
    body = [transformer.visit(statement) for statement in tree.body]
    clash = sorted(used & (set(arguments(names)) - set(names)))
    if clash:
        raise NotScalar(f"{what} uses the name {clash[0]}, which its rewrite needs")
    returned = result(names, transformer.written)
    tree.body = body + [ast.parse(f"return {returned}").body[0]]
    for node in ast.walk(tree):
        if isinstance(node, ast.Return) and node is not tree.body[-1]:
            node.value = ast.parse(returned, mode="eval").body
    tree.name = f"_tumble_{what}"
    tree.args = ast.parse(f"def f({', '.join(arguments(names))}): pass").body[0].args
    return ast.unparse(ast.fix_missing_locations(tree))


def _state(n):
    return [f"_y{j}" for j in range(n)]


def scalar_rate(rate, n, n_parameters):
    """The source of ``_tumble_rate(t, _y0, ..., _y{n-1}, p)``: ``rate(t, y, p, dydt)`` of ``n`` components and
    ``n_parameters`` parameters rewritten to return the derivative as a tuple (a division by a parameter a product
    with its reciprocal, ``p[n_parameters + k]``).

    Raises
    ------
    NotScalar
        The rate uses its state or derivative other than by constant indices, or leaves a component unset.
    """
    def result(names, written):
        missing = sorted(set(range(n)) - {j for (j,) in written.get(names[3], ())})
        if missing:
            raise NotScalar(f"rate sets no dydt[{missing[0]}] as a constant index")
        return f"({', '.join(f'_d{j}' for j in range(n))},)"

    return _rewrite(rate, "rate", {1: ((n,), lambda j: f"_y{j[0]}"), 3: ((n,), lambda j: f"_d{j[0]}")}, result,
                    lambda names: [names[0], *_state(n), names[2]], n_parameters)


def scalar_tangent(n, n_parameters, jacobian=None, scales=None):
    """The source of ``_tumble_tangent(t, _y0, ..., _v0, ..., p)``, ``J(t, y) v``: from ``jacobian(t, y, p, J)``
    rewritten (an entry it never sets is 0), or without it the fourth-order difference of ``_tumble_rate`` along
    ``v`` whose step moves no component by more than :data:`DIFFERENCE_STEP` of its scale (``scales``, (n,)), as
    :func:`tumble.kernels.loops.tangent_loop.difference_tangents` does per sample (the same shifts, the same bits)."""
    along = [f"_v{j}" for j in range(n)]
    if jacobian is None:
        sizes = [f"abs(_v{j}) / {float(s)!r}" for j, s in enumerate(scales)]
        lines = [f"def _tumble_tangent(t, {', '.join(_state(n))}, {', '.join(along)}, p):",
                 f"    size = {sizes[0] if n == 1 else '_tumble_max(' + ', '.join(sizes) + ')'}",
                 f"    e = {DIFFERENCE_STEP!r} / _tumble_max(size, 2.2250738585072014e-308)  # v = 0: a zero difference"]
        for label, shift in (("a", "e"), ("b", "-e"), ("c", "2.0 * e"), ("d", "-2.0 * e")):
            lines.append(f"    {', '.join(f'{label}{j}' for j in range(n))}, = _tumble_rate(t, "
                         f"{', '.join(f'_y{j} + ({shift}) * _v{j}' for j in range(n))}, p)")
        lines.append(f"    return ({', '.join(f'(8.0 * (a{j} - b{j}) - (c{j} - d{j})) / (12.0 * e)' for j in range(n))},)")
        return "\n".join(lines)

    def result(names, written):
        entries = written.get(names[3], set())
        rows = [" + ".join(f"_J{i}_{j} * _v{j}" for j in range(n) if (i, j) in entries) or "0.0" for i in range(n)]
        return f"({', '.join(rows)},)"

    return _rewrite(jacobian, "tangent", {1: ((n,), lambda j: f"_y{j[0]}"), 3: ((n, n), lambda ij: f"_J{ij[0]}_{ij[1]}")},
                    result, lambda names: [names[0], *_state(n), *along, names[2]], n_parameters)


def _reads(fn, seen=None):
    """What ``fn`` reads from its module and closure, as text that keys it: numbers and strings by value, arrays by
    their bytes, modules by name, functions by their source (and what they read); None when something else."""
    named = reads_by_name(fn, seen)
    return None if named is None else "\n".join(f"{name} = {text}" for name, text in named.items())


def reads_by_name(fn, seen=None):
    """:func:`_reads` name by name: ``{name: text}`` for each name ``fn`` reads from its module and closure (sorted),
    None when one cannot be keyed; ``{}`` for None."""
    if fn is None:
        return {}
    fn = getattr(fn, "py_func", fn)
    seen = set() if seen is None else seen
    seen.add(fn)
    values = inspect.getclosurevars(fn)
    keyed = {}
    for name, value in sorted({**values.globals, **values.nonlocals}.items()):
        function = getattr(value, "py_func", value)
        if isinstance(value, types.ModuleType):
            text = f"module {value.__name__}"
        elif isinstance(value, (bool, int, float, complex, str, np.number)) or value is None:
            text = repr(value)
        elif isinstance(value, tuple) and all(isinstance(v, (bool, int, float, str)) for v in value):
            text = repr(value)
        elif isinstance(value, np.ndarray):
            text = f"array {value.dtype} {value.shape} {hashlib.sha256(value.tobytes()).hexdigest()}"
        elif inspect.isfunction(function):
            if function in seen:
                text = "(read above)"  # a recursion, or a helper two functions call
            else:
                try:
                    inner = _reads(function, seen)
                    text = None if inner is None else inspect.getsource(function) + inner
                except (OSError, TypeError):
                    text = None
        else:
            text = None
        if text is None:
            return None
        keyed[name] = text
    return keyed


class _Made(types.SimpleNamespace):
    """A code's generated steps: ``steps`` (method id -> block step) or ``tangents`` (method id -> tangent step)."""


#: Code -> :class:`_Made`, filled by :func:`system_code` and :func:`tangent_code` (once per process and System).
_MADE = {}


def _code(texts, reads):
    """A code for the generated texts: their hash (with what the functions read), or a code unique to the process."""
    if reads is None:
        return SYSTEM_CODES + (1 << 60) + next(_UNCACHED)
    digest = hashlib.sha256("\n".join([str(GENERATOR_VERSION), *texts, reads]).encode()).hexdigest()
    return SYSTEM_CODES + int(digest[:12], 16)


def functions_key(*functions):
    """A string naming what ``functions`` (a user's rate and Jacobian; None for one it has not) compute, the same in
    every process: a hash of their source and of what they read (:func:`_reads`), for the loops compiled over them
    (:func:`tumble.kernels.jit.rebound`); None when one cannot be keyed (its file edited since it was imported, a lambda
    or a notebook cell without source, a read of an object of another kind)."""
    texts = [str(GENERATOR_VERSION)]
    for fn in functions:
        fn = getattr(fn, "py_func", fn)
        if fn is None:
            texts.append("None")
            continue
        reads = _reads(fn)
        try:
            current = _source_is_current(fn)
            source = inspect.getsource(fn)
        except (OSError, TypeError, AttributeError):
            return None
        if reads is None or not current:
            return None
        texts.append(source + reads)
    return hashlib.sha256("\n".join(texts).encode()).hexdigest()[:16]


def cacheable(code):
    """Whether the drivers of ``code`` may be cached on disk (its code keys what it computes)."""
    return code < SYSTEM_CODES + (1 << 60)


def _namespace(fn, sources, n_parameters):
    """The module ``system`` the generated steps call: the rewritten functions, executed among ``fn``'s module's
    names and closure (what the user's functions read), and the parameters' record ``Constants``."""
    original = getattr(fn, "py_func", fn)
    scope = dict(original.__globals__)
    scope.update(inspect.getclosurevars(original).nonlocals)
    scope["jit"] = _uncached_jit
    scope["_tumble_max"] = _max  # numba's max() would compile an overload per signature
    module = types.ModuleType(f"tumble_system_{id(scope)}")
    for source in sources:
        exec(compile("@jit(inline=True)\n" + source, f"<tumble System {original.__name__}>", "exec"), scope)
    module.rate = scope.get("_tumble_rate")
    module.tangent = scope.get("_tumble_tangent")
    module.Constants = namedtuple("Constants", [f"{kind}{i}" for kind in "pr" for i in range(n_parameters)])
    return module


def _steps(module, n, n_parameters, tangents):
    """The generated block steps (or tangent steps) of rk4 and rk8, by method id (``registry.STEPPING``)."""
    components = tuple(f"z{j + 1}" for j in range(n))
    rows = ", ".join(f"ys[{j}]" for j in range(n))
    lines = []
    made = {}
    for tableau in model_codegen.METHODS:
        method = tableau.name
        if tangents:
            lines += [model_codegen.tangent_step_source(tableau, _NAME, components, forced=False), "",
                      model_codegen.tangent_block_source(tableau, _NAME, components, forced=False,
                                                         n_fields=2 * n_parameters), ""]
            made[method] = f"{_NAME}_{method}_tangent_step"
        else:
            record = model_codegen._record(_NAME, 2 * n_parameters)
            lines += [model_codegen.step_source(tableau, _NAME, components, forced=False), "",
                      model_codegen.block_source(tableau, _NAME, components, False, forced=False), "",
                      "@jit(inline=True)",
                      f"def {method}_step(ys, t, h, a):",
                      f"    {_NAME}_{method}_block(t, {rows}, h, {record})", ""]
            made[method] = f"{method}_step"
    if not tangents:  # the error-controlled try over a block's lanes (tumble.kernels.loops.adaptive_blocks)
        lines += [model_codegen.attempt_source(_NAME, components, n_fields=2 * n_parameters), "",
                  model_codegen.start_source(_NAME, components, n_fields=2 * n_parameters), ""]
        made[tableaux.DOP853.name] = model_codegen.attempt_name(_NAME)
        made["start"] = model_codegen.start_name(_NAME)
    scope = {"jit": _uncached_jit, "math": math, "_max": _max, "_min": _min, "control": control, _NAME: module}
    exec(compile("\n".join(lines), "<tumble System steps>", "exec"), scope)
    from ...registry import STEPPING

    return {STEPPING.index(method) if method in STEPPING else method: scope[name] for method, name in made.items()}


def system_code(rate, n, n_parameters):
    """The code of the block steps of ``rate`` (a user's ``rate(t, y, p, dydt)`` of ``n`` components and
    ``n_parameters`` parameters), made once per process: their rk4 and rk8 steps for :func:`block_step`.

    Raises
    ------
    NotScalar
        The rate has no scalar form (:func:`scalar_rate`).
    """
    source = scalar_rate(rate, n, n_parameters)
    code = _code([source, f"{n} {n_parameters}"], _reads(rate))
    if code not in _MADE:
        module = _namespace(rate, [source], n_parameters)
        _MADE[code] = _Made(steps=_steps(module, n, n_parameters, tangents=False))
    return code


def tangent_code(rate, n, n_parameters, jacobian=None, scales=None):
    """The code of the tangent steps of ``rate`` with ``jacobian`` (or, without it, the differences on ``scales``),
    made once per process: their rk4 and rk8 steps for :func:`tangent_step`. Raises NotScalar as
    :func:`system_code`, or when the Jacobian has no scalar form."""
    rate_source = scalar_rate(rate, n, n_parameters)
    tangent_source = scalar_tangent(n, n_parameters, jacobian, scales)
    reads = _reads(rate)
    more = _reads(jacobian)
    code = _code([rate_source, tangent_source, f"{n} {n_parameters}"],
                 None if reads is None or more is None else reads + more)
    if code not in _MADE:
        if jacobian is None:  # the difference calls the rate: one scope
            module = _namespace(rate, [rate_source, tangent_source], n_parameters)
        else:
            module = _namespace(rate, [rate_source], n_parameters)
            module.tangent = _namespace(jacobian, [tangent_source], n_parameters).tangent
        _MADE[code] = _Made(tangents=_steps(module, n, n_parameters, tangents=True))
    return code


def block_constants(p):
    """The constants a System's block steps take: its parameters ``p`` (k,), then their reciprocals (the rewrite's
    ``x / p[j]``, :class:`_Scalars`); float64 (2 k,)."""
    p = np.asarray(p, dtype=float)
    with np.errstate(divide="ignore"):
        return np.concatenate([p, 1.0 / p])


def runs(method):
    """Whether the generated steps run ``method``: rk4 or rk8, the tableau of that name now being the one they were
    generated from (one added or replaced at run time runs per sample)."""
    return any(tableau.name == method and TABLEAUX.get(method) is tableau for tableau in model_codegen.METHODS)


def block_step(code, method):
    """The block step ``step(ys, t, h, a)`` of System ``code`` (:func:`system_code`) and method id ``method``."""
    return _MADE[code].steps[method]


def block_attempt(code):
    """The error-controlled try over a block's lanes of System ``code`` (:func:`system_code`) and the samples' start:
    ``attempt(block, rtol, atol, a)``, ``start(t0, span, y, rtol, atol, a, k0, h0)``
    (:func:`tumble.kernels.steps.model_codegen.attempt_source`, :func:`~tumble.kernels.steps.model_codegen.start_source`)."""
    return _MADE[code].steps[tableaux.DOP853.name], _MADE[code].steps["start"]


def tangent_step(code, method):
    """The tangent step ``step(Z, t, t0, h, a)`` of System ``code`` (:func:`tangent_code`) and method id ``method``."""
    return _MADE[code].tangents[method]
