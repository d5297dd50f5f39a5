"""Generate the systems' kernels: equations (:mod:`tumble.kernels.systems`), steps and dispatch (:mod:`.model_steps`).

**The equations.** Each system's per-sample equations are written once, in its module of
:mod:`tumble.physics.models` (with the model and its scenes): ``Constants``, ``constants``, ``rate``, ``tangent``,
``invariants`` and, where it has them, ``forcing``, ``rate_forced``, ``tangent_forced`` and ``project``, scalar
code that numba compiles. The kernels sit below physics and do not import it, so this generator copies that part of
the module (every statement between its ``__all__`` and its model class), as text, into
``tumble/kernels/systems/<module>.py``, with ``@jit(inline=True)`` on each function but ``constants`` (numpy, run
once per call). The module a kind's equations are in is its registry row's (``registry.Model.equations_module``:
the free body's are the gyrostat's).

**The steps.**
As :mod:`tumble.kernels.steps.codegen` does for the free body: a sample's whole step is spelled out with the tableau's
coefficients as literals (:mod:`tumble.kernels.tableaux`), so that the loop over the samples of a block keeps the
state in registers and vectorises across samples. What is generated, and from what:

* one step per (system module, method) and its block loop (then the module's ``project``, if it has one), from the
  equations sections themselves (run as plain Python here: what a system has, never the generated copies, so that the
  generator runs with none of its outputs present), their state names (``registry.MODELS``) and :data:`METHODS`;
* the dispatch over the codes of a system (a kind's index in ``registry.MODEL_KINDS``) and a method (its index in
  ``registry.STEPPING``): :func:`step`, :func:`invariants`, :func:`drift_suspects`, :func:`rhs_columns`,
  :func:`tangent_columns`, each a chain over the systems with each branch reading the constants array into the
  system's own ``Constants`` record; the Lie–Poisson splittings its registry row names (``registry.Model.splitting``:
  ``<splitting>_splitting_block`` of :mod:`tumble.kernels.steps.model_splittings`). The time loop of
  :mod:`tumble.kernels.loops.model_loop` calls ``step``, ``invariants`` and ``drift_suspects`` with constant codes: they
  are inlined into it and pruned to the one branch taken, so that a driver compiles its own system and method only.

A test checks that the committed module is what this generator writes. Regenerate with::

    python -m tumble.kernels.steps.model_codegen
"""

import ast
import functools
import math
from collections import namedtuple
from pathlib import Path

import numpy as np

from ... import registry
from .. import tableaux
from . import control
from .codegen import combination, regenerate

TARGET = Path(__file__).with_name("model_steps.py")

#: Where the systems' modules are (read as text, not imported) and where their equations' copies go.
PHYSICS_MODELS = Path(__file__).parents[2] / "physics" / "models"
SYSTEMS_DIR = Path(__file__).parents[1] / "systems"

#: The functions of an equations section that run once per call in numpy, not per sample (no ``@jit``).
_NUMPY_SIDE = ("constants",)

#: The imports an equations section may use, by the name it uses.
_IMPORTS = {"math": "import math", "namedtuple": "from collections import namedtuple", "np": "import numpy as np",
            "registry": "from ... import registry"}


def equation_modules():
    """The names of the modules that hold the systems' equations, in the registry's order of kinds."""
    return tuple(dict.fromkeys(m.equations_module for m in registry.MODELS))


def equations_section(name):
    """The text of module ``name``'s equations (:mod:`tumble.physics.models`): every line between its ``__all__``
    and its first class, and the lines of its top-level functions (``{name: first line}``, 0-based in the text)."""
    source = (PHYSICS_MODELS / f"{name}.py").read_text()
    tree = ast.parse(source)
    names = next(node for node in tree.body if isinstance(node, ast.Assign)
                 and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets))
    model = next(node for node in tree.body if isinstance(node, ast.ClassDef))
    start = names.end_lineno
    stop = min([model.lineno, *(d.lineno for d in model.decorator_list)]) - 1
    lines = source.splitlines()[start:stop]
    functions = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and start < node.lineno <= stop:
            if node.decorator_list:
                raise ValueError(f"{name}.py: {node.name} has a decorator; an equations section's functions are plain "
                                 f"(this generator adds @jit)")
            functions[node.name] = node.lineno - 1 - start
    while lines and not lines[0].strip():
        lines.pop(0)
        functions = {key: line - 1 for key, line in functions.items()}
    while lines and not lines[-1].strip():
        lines.pop()
    return lines, functions


def system_source(name):
    """The whole text of ``tumble/kernels/systems/<name>.py``: module ``name``'s equations section, jitted."""
    lines, functions = equations_section(name)
    jitted = {line for function, line in functions.items() if function not in _NUMPY_SIDE}
    body = []
    for position, line in enumerate(lines):
        if position in jitted:
            body.append("@jit(inline=True)")
        body.append(line)
    text = "\n".join(body)
    used = {word for word in _IMPORTS if f"{word}." in text or f"{word}(" in text}
    return "\n".join([
        f'"""GENERATED by ``python -m tumble.kernels.steps.model_codegen`` from ``tumble/physics/models/{name}.py``.',
        "",
        "The system's per-sample equations for the kernels, copied from the equations section of its module, which",
        "holds them once with the model and its scenes (the kernels sit below physics and do not import it): edit",
        "them there.",
        '"""',
        "",
        *[_IMPORTS[word] for word in ("math", "namedtuple") if word in used],
        *([""] if used & {"math", "namedtuple"} else []),
        *([_IMPORTS["np"], ""] if "np" in used else []),
        *([_IMPORTS["registry"]] if "registry" in used else []),
        "from ..jit import jit",
        "",
        "",
        *body,
        "",
    ])


#: The methods with generated steps (their kernel ids are their indices in ``registry.STEPPING``).
METHODS = tuple(tableaux.TABLEAUX[m.name] for m in registry.METHODS if m.family == "runge_kutta")


def _modules():
    """``[(module name, state components, kinds)]``, each module once, in the registry's order of kinds."""
    found = {}
    for model in registry.MODELS:
        name = model.equations_module
        found.setdefault(name, (name, model.state, []))[2].append(model.name)
    return list(found.values())


def _splitting(kinds):
    """The Lie–Poisson splitting (``registry.Model.splitting``) that steps the models ``kinds`` of one equations
    module ("": none): one for all of them."""
    splittings = {registry.MODELS[registry.MODEL_KINDS.index(kind)].splitting for kind in kinds}
    assert len(splittings) == 1, f"the models {kinds} of one equations module have one splitting"
    return splittings.pop()


@functools.cache
def _equations(name):
    """The names module ``name``'s equations section defines, its text run as plain Python (no ``@jit``): what the
    generator asks of a system (its functions, its ``Constants``' fields)."""
    namespace = {"math": math, "namedtuple": namedtuple, "np": np, "registry": registry}
    exec(compile("\n".join(equations_section(name)[0]), str(PHYSICS_MODELS / f"{name}.py"), "exec"), namespace)
    return namespace


def _has_project(name):
    return "project" in _equations(name)


def _has_forcing(name):
    """Whether the system's rate depends on time through a ``forcing(t, c)`` (the same for every sample): its steps
    then take it per stage, evaluated once per block (``rate_forced(f, *y, c)``)."""
    return "forcing" in _equations(name)


def _fields(name):
    return _equations(name)["Constants"]._fields


def step_source(tableau, name, components, forced=None):
    """Source of ``<name>_<method>_sample(t, *components, h, c)``: one step of a system for one sample (``forced``:
    whether its rate takes a forcing, :func:`_has_forcing`; None: the built-in system's module says)."""
    args = ", ".join(components)
    n = len(components)
    forced = _has_forcing(name) if forced is None else forced
    stages = "".join(f", f{s + 1}" for s in range(len(tableau.b))) if forced else ""
    lines = [
        "@jit(inline=True)",
        f"def {name}_{tableau.name}_sample(t, {args}, h, c{stages}):",
        "    # size: generated from the tableau, every stage spelled out (the state stays in registers)",
        f'    """One step of {tableau.name} (order {tableau.order}, {len(tableau.b)} stages) of the {name} for one '
        f'sample."""',
    ]
    for s in range(len(tableau.b)):
        ks = ", ".join(f"k{s + 1}_{i + 1}" for i in range(n)) + ("," if n == 1 else "")
        time = "t" if tableau.c[s] == 0.0 else f"t + {float(tableau.c[s])!r} * h"
        lines.append(f"    {ks} = {name}.rate_forced(" if forced else f"    {ks} = {name}.rate(")
        lines.append(f"        f{s + 1}," if forced else f"        {time},")
        for i, y in enumerate(components):
            lines.append(f"        {combination(y, enumerate(tableau.A[s, :s]), i + 1)},")
        lines.append("        c)")
    lines.append("    return (")
    for i, y in enumerate(components):
        lines.append(f"        {combination(y, enumerate(tableau.b), i + 1)},")
    lines.append("    )")
    return "\n".join(lines)


def block_source(tableau, name, components, project, forced=None):
    """Source of ``<name>_<method>_block(t, y1, ..., h, c)``: every sample of a block advanced by one step (then
    projected by the module's ``project`` when it has one; ``forced`` as :func:`step_source`)."""
    arrays = ", ".join(f"y{i + 1}" for i in range(len(components)))
    items = ", ".join(f"y{i + 1}[i]" for i in range(len(components)))
    target = items + ("," if len(components) == 1 else "")
    lines = [
        "@jit",
        f"def {name}_{tableau.name}_block(t, {arrays}, h, c):",
        f'    """Advance every sample of a block by one {tableau.name} step of the {name}'
        f'{", then project it" if project else ""}."""',
    ]
    forcing = ""
    if _has_forcing(name) if forced is None else forced:
        for s in range(len(tableau.b)):
            time = "t" if tableau.c[s] == 0.0 else f"t + {float(tableau.c[s])!r} * h"
            lines.append(f"    f{s + 1} = {name}.forcing({time}, c)")
        forcing = "".join(f", f{s + 1}" for s in range(len(tableau.b)))
    lines.append("    for i in range(y1.shape[0]):")
    if project:
        values = ", ".join(components)
        lines[2:2] = ["    # size: generated: one array per state component (the block's rows), the time, the step, the "
                      "constants"]
        lines += [f"        {values} = {name}_{tableau.name}_sample(t, {items}, h, c{forcing})",
                  f"        {target} = {name}.project({values})"]
    else:
        lines += [f"        {target} = {name}_{tableau.name}_sample(t, {items}, h, c{forcing})"]
    return "\n".join(lines)


def attempt_name(name, rate="rate", method=tableaux.DOP853):
    """The name of :func:`attempt_source`'s function for system module ``name`` and its function ``rate``."""
    return f"{name}_{method.name}_attempt" if rate == "rate" else f"{name}_{rate}_{method.name}_attempt"


def start_name(name, rate="rate", method=tableaux.DOP853):
    """The name of :func:`start_source`'s function: :func:`attempt_name`'s, ``_start`` appended."""
    return f"{attempt_name(name, rate, method)}_start"


def attempt_source(name, components, n_fields=None, method=tableaux.DOP853, rate="rate"):
    # size: generated from the coefficients: every stage, the step, both error estimates and the keeping spelled out
    """Source of ``<name>_<method>_attempt(block, rtol, atol, a)`` (:func:`attempt_name`: with the module's function
    ``rate`` as the rate, ``rate(t, *y, c)``): one try of the error-controlled ``method``
    (:data:`tumble.kernels.tableaux.DOP853`) for every lane of a block (:mod:`tumble.kernels.steps.control`'s flat
    ``block``), each from its own time ``T`` with its own step ``TRIAL_H`` (0: a lane that is done, which keeps its
    state), kept or not by Hairer's control (:func:`tumble.kernels.steps.control.next_step`); the lane's state in
    registers from its load to its store, vectorised across the lanes. The control runs in a second loop over the
    lanes, on the error norms the stages leave in the block (``ERR5``, ``ERR3``): its chain of square roots and
    divisions, last in the stages' loop, held the next lanes' stages back.

    A kept try moves its lane's state ``ys`` and rate ``ks`` (the step's last stage, the next one's first), its time to
    ``T_NEW``; every lane's ``H`` becomes its next step (the same for a lane that is done), ``y0s`` and ``k0s`` the
    state and rate its try started from (for a kept step's dense output), ``KEPT`` 1 or 0, and its tries and kept steps
    are counted. ``a``: the constants array, read into the system's record (its ``n_fields`` fields)."""
    n = len(components)
    tableau = method.tableau
    stages = len(tableau.b)

    def row(which, j):
        return f"block[{control.state_row(which, j, n)} + i]"

    def lane(name):
        return f"block[control.{name} + i]"

    def rate_call(target, time, states):
        call = [f"        {target} = {name}.{rate}(", f"            {time},"]
        return call + [f"            {state}," for state in states] + ["            c)"]

    def names(stage):
        return ", ".join(f"k{stage}_{j + 1}" for j in range(n)) + ("," if n == 1 else "")

    def weighted(weights, j):
        terms = [f"{float(w)!r} * k{s + 1}_{j + 1}" for s, w in enumerate(weights) if w != 0.0]
        return " + ".join(terms)

    lines = [
        "@jit(contract=False)",  # its bits the same compiled alone or in a caller, loaded or not
        f"def {attempt_name(name, rate, method)}(block, rtol, atol, a):",
        "    # size: generated from the coefficients, every stage spelled out (the lanes' states in registers)",
        f'    """One try of {method.name} of the {name} for every lane of a block (each at its own time and step), '
        f'kept or not."""',
        f"    c = {_record(name, n_fields)}",
        *_tolerances(n),
        "    for i in range(control.BLOCK):",
        f"        t, h = {lane('T')}, {lane('TRIAL_H')}",
        f"        {', '.join(components)} = {', '.join(row(0, j) for j in range(n))}",
        f"        {names(1).rstrip(',')} = {', '.join(row(1, j) for j in range(n))}",
    ]
    for stage in range(1, stages):
        lines += rate_call(names(stage + 1), f"t + {float(tableau.c[stage])!r} * h",
                           [f"{y} + h * ({weighted(tableau.A[stage, :stage], j)})" for j, y in enumerate(components)])
    stepped = [f"u{j + 1}" for j in range(n)]
    for j, y in enumerate(components):
        lines += [f"        b_{j + 1} = {weighted(tableau.b, j)}",  # the step's increment over h
                  f"        {stepped[j]} = {y} + h * b_{j + 1}"]
    lines += rate_call(names(stages + 1), "t + h", stepped)
    for j, y in enumerate(components):
        less = "".join(f" - {w!r} * k{s + 1}_{j + 1}" for s, w in method.e3_from_b)
        lines += [f"        s{j + 1} = 1.0 / (atol{j + 1} + rtol{j + 1} * _max(abs({y}), abs({stepped[j]})))",
                  f"        e5_{j + 1} = ({weighted(method.e5, j)}) * s{j + 1}",
                  f"        e3_{j + 1} = (b_{j + 1}{less}) * s{j + 1}"]
    lines += [f"        {lane('ERR5')} = {' + '.join(f'e5_{j + 1} * e5_{j + 1}' for j in range(n))}",
              f"        {lane('ERR3')} = {' + '.join(f'e3_{j + 1} * e3_{j + 1}' for j in range(n))}"]
    for j, y in enumerate(components):  # the try's state and rate, put back below where it is rejected
        lines += [f"        {row(2, j)} = {y}",
                  f"        {row(3, j)} = k1_{j + 1}",
                  f"        {row(0, j)} = {stepped[j]}",
                  f"        {row(1, j)} = k{stages + 1}_{j + 1}"]
    # Hairer's control in a loop of its own: last in the stages' loop, its chain of square roots and divisions held the
    # next lanes' stages back (2 000 free-body spins: 10-15 % slower at rtol 1e-4 ... 1e-12, the same bits)
    lines += [
        "    for i in range(control.BLOCK):",
        # the lane's numbers read once, unconditionally: a read in a choice's arm became a masked load and a scatter
        f"        t, h, on, step = {lane('T')}, {lane('TRIAL_H')}, {lane('ACTIVE')}, {lane('H')}",
        f"        rejected, t_new, facold = {lane('LAST_REJECTED')}, {lane('T_NEW')}, {lane('FACOLD')}",
        f"        err5, err3 = {lane('ERR5')}, {lane('ERR3')}",
        "        deno = err5 + 0.01 * err3",
        # a NaN among the stages (a rate that returned one) is a non-finite error, rejected, never 0
        f"        err = h * err5 / math.sqrt({n}.0 * deno) if deno > 0.0 else (0.0 if deno == 0.0 else math.inf)",
        "        keep = on if err <= 1.0 else 0.0",
        "        h_next, facold_next = control.next_step(err, step, rejected, facold)",
        f"        {lane('H')} = h_next if on != 0.0 else step",
        f"        {lane('FACOLD')} = facold_next if on != 0.0 else facold",
        f"        {lane('LAST_REJECTED')} = (1.0 - keep) if on != 0.0 else rejected",
        f"        {lane('TRIES')} += on",
        f"        {lane('ACCEPTED')} += keep",
        f"        {lane('KEPT')} = keep",
        f"        {lane('T')} = t_new if keep != 0.0 else t",
        "        if keep == 0.0:"]
    for j in range(n):
        lines += [f"            {row(0, j)} = {row(2, j)}",
                  f"            {row(1, j)} = {row(3, j)}"]
    return "\n".join(lines)


def _tolerances(n):
    """Lines reading the tolerances into names before a loop over lanes or samples: read in the loop, they are loads
    LLVM must repeat after every store (the arrays may overlap)."""
    return [f"    {', '.join(f'{kind}{j + 1}' for j in range(n))} = {', '.join(f'{kind}[{j}]' for j in range(n))}"
            for kind in ("rtol", "atol")]


def start_source(name, components, n_fields=None, method=tableaux.DOP853, rate="rate"):
    # size: generated: the rate and Hairer's first step spelled out for one sample's state in registers
    """Source of ``<attempt>_start(t0, span, y, rtol, atol, a, k0, h0)`` (:func:`attempt_name`'s, ``_start``
    appended): every sample of ``y`` (N, n) started at once, vectorised across them: its rate ``k0`` (n, N) and
    Hairer's first step ``h0`` (N,) (``hinit`` of dop853.f, as SciPy's ``select_initial_step``: from the sizes of
    ``y``, ``f(t0, y)`` and an estimate of the second derivative, one more evaluation of the rate, within ``span``), the
    root by :func:`tumble.kernels.steps.control.root8`. A sample that is not finite gets numbers no run reads."""
    n = len(components)
    rows = [f"flat[{n} * s + {j}]" for j in range(n)]  # a constant stride: y[s, j]'s is y.shape[1], which LLVM
    # vectorised only for a shape of 1 (the loop ran scalar, 30 ns a sample against 6)

    def rate_call(target, time, states):
        return [f"        {', '.join(target)}{',' if n == 1 else ''} = {name}.{rate}({time}, {', '.join(states)}, c)"]

    def norm(terms):
        return f"math.sqrt(({' + '.join(f'({term}) ** 2' for term in terms)}) / {n}.0)"

    f0 = [f"f{j + 1}" for j in range(n)]
    f1 = [f"g{j + 1}" for j in range(n)]
    scale = [f"sk{j + 1}" for j in range(n)]
    lines = [
        "@jit(contract=False)",  # its bits the same compiled alone or in a caller, loaded or not
        f"def {start_name(name, rate, method)}(t0, span, y, rtol, atol, a, k0, h0):",
        "    # size: generated, the rate and the first step spelled out (a sample's state in registers)",
        f'    """Every sample\'s rate and first step of {method.name} of the {name}, vectorised across the samples."""',
        f"    c = {_record(name, n_fields)}",
        *_tolerances(n),
        "    flat = y.reshape(y.size)",
        "    for s in range(y.shape[0]):",
        f"        {', '.join(components)} = {', '.join(rows)}",
    ]
    lines += rate_call(f0, "t0", components)
    lines += [f"        {scale[j]} = atol{j + 1} + rtol{j + 1} * abs({y})" for j, y in enumerate(components)]
    lines += [f"        d0 = {norm(f'{y} / {scale[j]}' for j, y in enumerate(components))}",
              f"        d1 = {norm(f'{f0[j]} / {scale[j]}' for j in range(n))}",
              "        h = 1e-6 if (d0 < 1e-5) | (d1 < 1e-5) else 0.01 * d0 / d1",
              "        h = _min(h, span)"]
    lines += rate_call(f1, "t0 + h", [f"{y} + h * {f0[j]}" for j, y in enumerate(components)])
    lines += [f"        d2 = {norm(f'({f1[j]} - {f0[j]}) / {scale[j]}' for j in range(n))} / h",
              "        h1 = (_max(1e-6, h * 1e-3) if (d1 <= 1e-15) & (d2 <= 1e-15) else",
              "              control.root8(0.01 / _max(d1, d2)))",
              "        h0[s] = _min(100.0 * h, h1, span)"]
    lines += [f"        k0[{j}, s] = {f0[j]}" for j in range(n)]
    return "\n".join(lines)


def tangent_step_source(tableau, name, components, forced=None):
    # size: generated from the tableau, every stage of the state, one tangent vector and MEGNO's scalars spelled out
    """Source of ``<name>_<method>_tangent_sample(t, t0, *y, *d, ys, yss, h, c)``: one step of a system's state
    ``y``, one tangent vector ``d`` and MEGNO's two scalars for one sample (the augmented system of
    :func:`tumble.kernels.loops.tangent_loop.make_tangent_step`, the same arithmetic with the state in registers). A
    forced system's stage forcings come as one tuple: CPython passes a call of more than 30 arguments as ``*args``,
    which numba cannot inline."""
    n = len(components)
    tangent = [f"d_{y}" for y in components]
    forced = _has_forcing(name) if forced is None else forced
    # Ys' = 2 t rho of a stage is needed where the step's combination or the Ys of a stage with Yss' takes it
    ys_rate = [tableau.b[s] != 0.0 or any(tableau.b[q] != 0.0 and tableau.A[q, s] != 0.0 for q in range(len(tableau.b)))
               for s in range(len(tableau.b))]
    lines = [
        "@jit(inline=True)",
        f"def {name}_{tableau.name}_tangent_sample(t, t0, {', '.join(components)}, {', '.join(tangent)}, ys, yss, "
        f"h, c{', forcings' if forced else ''}):",
        "    # size: generated from the tableau, every stage spelled out (state, tangent and MEGNO in registers)",
        f'    """One step of {tableau.name} of the {name}, its tangent vector and MEGNO\'s scalars for one sample'
        f'{" (``forcings``: the forcing of each stage)" if forced else ""}."""',
    ]
    if forced:
        lines.append(f"    {', '.join(f'f{s + 1}' for s in range(len(tableau.b)))} = forcings")
    for s in range(len(tableau.b)):
        a = list(enumerate(tableau.A[s, :s]))
        time = "t" if tableau.c[s] == 0.0 else f"t + {float(tableau.c[s])!r} * h"
        stage = [f"y{s + 1}_{i + 1}" for i in range(n)]
        along = [f"e{s + 1}_{i + 1}" for i in range(n)]
        lines += [f"    {stage[i]} = {combination(y, a, i + 1)}" for i, y in enumerate(components)]
        lines += [f"    {along[i]} = {combination(d, a, i + 1).replace('* k', '* l')}" for i, d in enumerate(tangent)]
        at = f"f{s + 1}" if forced else time
        suffix = "_forced" if forced else ""
        lines.append(f"    {', '.join(f'k{s + 1}_{i + 1}' for i in range(n))}{',' * (n == 1)} = {name}.rate{suffix}({at}, "
                     f"{', '.join(stage)}, c)")
        lines.append(f"    {', '.join(f'l{s + 1}_{i + 1}' for i in range(n))}{',' * (n == 1)} = {name}.tangent{suffix}({at}, "
                     f"{', '.join(stage)}, {', '.join(along)}, c)")
        lines.append(f"    elapsed = {time} - t0")
        if ys_rate[s]:
            lines.append(f"    rho = ({' + '.join(f'{along[i]} * l{s + 1}_{i + 1}' for i in range(n))}) / "
                         f"({' + '.join(f'{e} * {e}' for e in along)})")
            lines.append(f"    m{s + 1}_1 = 2.0 * elapsed * rho")
        if tableau.b[s] != 0.0:  # Yss' = Ys / t enters the step's combination only
            lines.append(f"    m{s + 1}_2 = ({combination('ys', a, 1).replace('* k', '* m')}) / elapsed if elapsed > 0.0 "
                         f"else 0.0  # Ys ~ t^2: Ys / t -> 0 at t0")
    b = list(enumerate(tableau.b))
    lines.append("    return (")
    lines += [f"        {combination(y, b, i + 1)}," for i, y in enumerate(components)]
    lines += [f"        {combination(d, b, i + 1).replace('* k', '* l')}," for i, d in enumerate(tangent)]
    lines += [f"        {combination('ys', b, 1).replace('* k', '* m')},",
              f"        {combination('yss', b, 2).replace('* k', '* m')},", "    )"]
    return "\n".join(lines)


def tangent_block_source(tableau, name, components, forced=None, n_fields=None):
    """Source of ``<name>_<method>_tangent_step(Z, t, t0, h, a)``: every sample of a block advanced in place by one
    step with its tangent vectors and MEGNO's scalars (``Z`` (k, 2 n + 2, m): for each vector the state's rows, the
    vector's, ``Ys`` and ``Yss``; the state and MEGNO of ``Z[r > 0]`` are copies of ``Z[0]``'s that the caller makes
    and that the step overwrites), no projection (the tangent is the derivative of the step itself). ``a``: the
    constants array (``n_fields`` of them read into the system's record; None: the built-in's ``Constants``; ``forced``
    as :func:`step_source`). Rows by constant index, updated in place: the form LLVM vectorises across samples
    (separate input and output arrays, or rows at a runtime offset, leave the loop scalar: measured with numba
    0.68.1)."""
    rows = ", ".join(f"Y[{j}, i]" for j in range(2 * len(components) + 2))
    lines = [
        "@jit",
        f"def {name}_{tableau.name}_tangent_step(Z, t, t0, h, a):",
        f'    """Every sample of a block, its tangent vectors and MEGNO\'s scalars advanced in place by one '
        f'{tableau.name} step of\n    the {name}."""',
        f"    c = {_record(name, n_fields)}",
    ]
    forced = _has_forcing(name) if forced is None else forced
    if forced:
        times = ["t" if c == 0.0 else f"t + {float(c)!r} * h" for c in tableau.c]
        lines.append(f"    forcings = ({', '.join(f'{name}.forcing({time}, c)' for time in times)},)")
    lines += ["    for r in range(Z.shape[0]):",
              "        Y = Z[r]",
              "        for i in range(Y.shape[1]):",
              f"            {rows} = {name}_{tableau.name}_tangent_sample(",
              f"                t, t0, {rows}, h, c{', forcings' if forced else ''})"]
    return "\n".join(lines)


def tangent_table_source(modules):
    """Source of ``TANGENT_STEPS``: ``(model code, method id) -> <name>_<method>_tangent_step``."""
    lines = ["#: The generated tangent steps by (model code, method id): a kind's index in ``registry.MODEL_KINDS``, a",
             "#: method's in ``registry.STEPPING``.",
             "TANGENT_STEPS = {"]
    for name, _, kinds in modules:
        for kind in kinds:
            for tableau in METHODS:
                lines.append(f"    ({registry.MODEL_KINDS.index(kind)}, {registry.STEPPING.index(tableau.name)}): "
                             f"{name}_{tableau.name}_tangent_step,  # {kind}, {tableau.name}")
    lines.append("}")
    return "\n".join(lines)


def _record(name, n_fields=None):
    """``<name>.Constants(a[0], ..., a[k])``: the constants array (or tuple) read into the system's record (its
    ``n_fields`` fields; None: the built-in system's ``Constants``)."""
    n_fields = len(_fields(name)) if n_fields is None else n_fields
    return f"{name}.Constants({', '.join(f'a[{i}]' for i in range(n_fields))})"


def _codes(kinds):
    return " or ".join(f"model == {registry.MODEL_KINDS.index(kind)}" for kind in kinds)


def _chain(modules, body, indent="    "):
    """An if/elif/else chain over the modules (the last one the ``else``), ``body(name, components)`` each branch's
    lines."""
    lines = []
    for position, (name, components, kinds) in enumerate(modules):
        if position == len(modules) - 1:
            lines.append(f"{indent}else:  # {', '.join(kinds)}")
        else:
            lines.append(f"{indent}{'if' if position == 0 else 'elif'} {_codes(kinds)}:  # {', '.join(kinds)}")
        lines += [indent + "    " + line for line in body(name, components, kinds)]
    return lines


def dispatch_source(modules):
    # size: seven generated functions, each a chain over the systems, written out as the text they are
    """Source of the dispatch functions (see the module docstring)."""
    method_ids = {m.name: registry.STEPPING.index(m.name) for m in METHODS}

    def step(name, components, kinds):
        rows = ", ".join(f"ys[{i}]" for i in range(len(components)))
        lines = [f"c_{name} = {_record(name)}"]
        for position, tableau in enumerate(METHODS):
            keyword = "if" if position == 0 else "elif"
            lines += [f"{keyword} method == {method_ids[tableau.name]}:  # {tableau.name}",
                      f"    {name}_{tableau.name}_block(t, {rows}, h, c_{name})"]
        if _splitting(kinds):
            lines += ["else:  # a Lie-Poisson splitting",
                      f"    {_splitting(kinds)}_splitting_block(method, {rows}, h, c_{name}, x0)"]
        return lines

    def invariants(name, components, kinds):
        items = ", ".join(f"ys[{i}, i]" for i in range(len(components)))
        return [f"return {name}.invariants({items}, {_record(name)})"]

    def suspects(name, components, kinds):
        items = ", ".join(f"ys[{i}, i]" for i in range(len(components)))
        return [f"c_{name} = {_record(name)}",
                "for i in range(ys.shape[1]):",
                f"    x1, x2, x3, _, _, _ = {name}.invariants({items}, c_{name})",
                f"    total = {' + '.join(f'ys[{i}, i]' for i in range(len(components)))}",
                "    suspects += suspect(i, active, x0, inverse_scale, screen, x1, x2, x3, total)"]

    def call(function, at, constants):
        """A branch that calls the system's ``function`` (rate or tangent) on the components ``y[j{at}]`` (and ``v``)
        and writes ``out[j{at}]``: ``at`` is ``", i"`` for states as columns, ``""`` for one sample's state."""
        def body(name, components, kinds):
            items = ", ".join(f"y[{i}{at}]" for i in range(len(components)))
            along = "".join(f", v[{i}{at}]" for i in range(len(components))) if function == "tangent" else ""
            return [f"r_{name} = {name}.{function}(t, {items}{along}, {constants(name)})",
                    f"for j in range({len(components)}):",
                    f"    out[j{at}] = r_{name}[j]"]
        return body

    lines = [
        "@jit(inline=True)",
        "def step(model, method, ys, t, h, a, x0):",
        "    # size: generated: the dispatch of every system and method",
        '    """Advance every sample of a block (``ys``, shape (n_state, m)) by one step at time ``t``; branches outside '
        'the\n    sample loop. ``a``: the constants array (or tuple); ``x0``: the samples\' initial invariants (a '
        'gyrostat\'s\n    splittings put ``|I w + h|²`` back on them)."""',
        *_chain(modules, step),
        "",
        "",
        "@jit(inline=True)",
        "def invariants(model, ys, i, a):",
        '    """``(x1, x2, x3, scale1, scale2, scale3)`` of sample ``i`` of a block."""',
        *_chain(modules, invariants),
        "",
        "",
        "@jit(inline=True)",
        "def drift_suspects(model, ys, active, a, x0, inverse_scale, screen):",
        '    """Whether any active sample of a block is non-finite or has an invariant\'s drift beyond ``screen``: one '
        'pass\n    per system without stores, calls or inner loops, so that it vectorises across samples (see\n'
        '    :func:`tumble.kernels.loops.block_loop.run_block`)."""',
        "    suspects = 0",
        *_chain(modules, suspects),
        "    return suspects > 0",
    ]
    for function in ("rate", "tangent"):
        arguments = "t, y, p, out" if function == "rate" else "t, y, v, p, out"
        what = ("A built-in system's rate as a user's ``System`` writes it (``rate(t, y, p, dydt)``): ``out = f(t, y)``"
                if function == "rate" else "A built-in system's tangent flow ``out = J(t, y) v``")
        lines += [
            "",
            "",
            "@jit",
            f"def {function}_sample({arguments}):",
            f'    """{what} of one sample\'s state\n    ``y`` (n,): ``p`` holds the model\'s code, then its constants '
            '(:func:`tumble.kernels.loops.model_loop.rate_sample_parameters`)."""',
            "    model = int(p[0])",
            "    a = p[1:]",
            *_chain(modules, call(function, "", _record)),
        ]
    for function in ("rate", "tangent"):
        arguments = "y, a, t, out" if function == "rate" else "y, v, a, t, out"
        what = "``out = f(t, y)``" if function == "rate" else "``out = J(t, y) v``"
        lines += [
            "",
            "",
            "@jit",  # serial: numba's parallel lowering cannot name a record type of another module (NameError)
            f"def {function}_columns(model, {arguments}):",
            f'    """{what} for states as columns ``y`` (n_state, N){", along ``v`` (n_state, N)" if function == "tangent" else ""}."""',
            *[f"    c_{name} = {_record(name)}" for name, _, _ in modules],
            "    for i in range(y.shape[1]):",
            *_chain(modules, call(function, ", i", lambda name: f"c_{name}"), indent="        "),
        ]
    return "\n".join(lines)


def module_source():
    """The whole text of :mod:`tumble.kernels.steps.model_steps`."""
    modules = _modules()
    splittings = sorted(f"{_splitting(kinds)}_splitting_block" for _, _, kinds in modules if _splitting(kinds))
    blocks = [
        '"""GENERATED by ``python -m tumble.kernels.steps.model_codegen``; do not edit.',
        "",
        "The systems' rk4 and rk8 steps, the loop over a block for each, their dop853 attempts (a block's lanes, each",
        "at its own time and step), and the dispatch over systems and methods, from",
        ":mod:`tumble.kernels.tableaux`, :mod:`tumble.kernels.systems` and the registry.",
        '"""',
        "",
        "import math",
        "",
        "from ..jit import jit",
        f"from .model_splittings import {', '.join(splittings)}",
        "from . import control",
        "from .drift_screen import suspect",
        f"from ..systems import {', '.join(sorted(name for name, _, _ in modules))}",
        "from ..trig import _max, _min",
    ]
    for name, components, kinds in modules:
        for tableau in METHODS:
            blocks += ["", "", step_source(tableau, name, components), "", "",
                       block_source(tableau, name, components, _has_project(name)), "", "",
                       tangent_step_source(tableau, name, components), "", "",
                       tangent_block_source(tableau, name, components)]
        for rate in sorted({registry.MODELS[registry.MODEL_KINDS.index(kind)].rate for kind in kinds}):
            blocks += ["", "", attempt_source(name, components, rate=rate), "", "",
                       start_source(name, components, rate=rate)]
    blocks += ["", "", dispatch_source(modules), "", "", tangent_table_source(modules), ""]
    return "\n".join(blocks)


def write_all():
    """Write every system's equations (:func:`system_source`) and the steps (:func:`module_source`), both from the
    physics modules' text alone (the generated modules need not exist, nor import)."""
    for name in equation_modules():
        regenerate(SYSTEMS_DIR / f"{name}.py", system_source(name))
    regenerate(TARGET, module_source())


if __name__ == "__main__":
    write_all()
