"""Study files: parse, merge over the documented defaults, validate, resolve.

A *study* is a TOML file (or a mapping of the same shape) that states only what differs from
``studies/defaults.toml``, where every key is documented. :func:`load_study` reads it with the standard
library's :mod:`tomllib`, merges it over the defaults, checks every value and returns the *resolved*
study: a plain ``dict`` of plain Python types (str, int, float, list, dict), every key filled, which is
JSON-serialisable and is stored in each result file so the run can be repeated. Loading a resolved study
again gives it back unchanged.

Every problem is a :class:`StudyError` (a ``ValueError``) whose message reads
``"<file>: <field.path>: <what is wrong>"``; list indices in field paths count from 0
(``scan.moments[1]`` is the second body of the scan). Pseudo-fields name problems that are not about one
key: ``<file>`` (the file cannot be found or read) and ``<toml>`` (TOML syntax, with tomllib's line and
column).

Studies are data, never code: nothing here evaluates, executes or unpickles anything; a time-dependent
torque is one of the named :data:`PROFILES` with numeric parameters.

This module validates and resolves; it does not run anything (:mod:`tumble.measure.scans` and
:mod:`tumble.measure.scene` do).
"""

from __future__ import annotations

import copy
import difflib
import inspect
import math
import numbers
import operator
import os
import tomllib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .. import registry
from ..physics import models, shapes
from ..physics.bodies import Body, validate_moments
from . import schema

__all__ = [
    "ARRAYS",
    "DEFAULTS_PATH",
    "FIGURES",
    "FORMATS",
    "K_SCAN_KEYS",
    "METHOD_NAMES",
    "MODEL_FIGURES",
    "MODEL_KINDS",
    "MODEL_METHODS",
    "MODEL_SCAN_KEYS",
    "PROFILES",
    "SCAN_KEYS",
    "SHAPES",
    "STUDIES_DIR",
    "StudyError",
    "TRIANGLE_RANGE",
    "UNTITLED",
    "bundled_studies",
    "load_study",
    "moments_from_k",
    "resolve_body",
    "scan_bodies",
]


def _studies_dir():
    """The folder of bundled studies: ``studies/`` next to the package in a source tree (and an editable
    install), else ``tumble/studies/`` inside an installed package (shipped there as package data)."""
    package = Path(__file__).resolve().parents[1]
    candidates = (package.parent / "studies", package / "studies")
    for folder in candidates:
        if (folder / "defaults.toml").is_file():
            return folder
    return candidates[0]


#: Folder holding the bundled study files and ``defaults.toml``.
STUDIES_DIR = _studies_dir()

#: The documented defaults every study is merged over.
DEFAULTS_PATH = STUDIES_DIR / "defaults.toml"

#: Shape functions of :mod:`tumble.physics.shapes` a study may name in ``body.shape``.
SHAPES = schema.SHAPES

#: ``integration.method``: the planner's choice, the closed form, a fixed-step method, or an error-controlled one.
METHOD_NAMES = (*registry.CHOICES, *registry.ERROR_CONTROLLED)

#: ``torque.profile``: named time dependences of the body-frame torque (see ``defaults.toml``).
PROFILES = schema.PROFILES

#: Which profile needs which time parameter (> 0); the other one must stay 0.
_PROFILE_TIMES = {p.name: p.time for p in registry.TORQUE_PROFILES if p.time}

#: ``outputs.figures``, ``outputs.format`` and ``outputs.arrays`` (from :mod:`tumble.registry`).
FIGURES = registry.FIGURES
#: Figures drawn from the traced attitude of the study's first scene (:func:`tumble.measure.traces.attitude_trace`).
ATTITUDE_FIGURES = registry.ATTITUDE_FIGURES
FORMATS = registry.FORMATS
ARRAYS = registry.PER_SAMPLE_ARRAYS

#: Keys of the ``[scan]`` table, and the field each one replaces (``scan.body`` replaces the whole ``[body]``
#: table: moments, shape and dimensions): :func:`tumble.pipeline.schema.scan_replaces`.
SCAN_KEYS = schema.scan_replaces()

#: ``model.kind``: every model of the registry (the reserved ones are refused with a message naming them).
MODEL_KINDS = registry.MODEL_KINDS

#: The scan keys of the models' numeric parameters (``scan.rotor``, ``scan.mgl``, ...).
MODEL_SCAN_KEYS = tuple(p.key for p in registry.MODEL_PARAMETERS)

#: Stepping methods of a model study (the model kernels'); ``"auto"`` means the first.
MODEL_METHODS = registry.MODEL_STEPPING

#: Figures of a model study (the free body's others read what only free-body scenes record): the registry's model
#: figures (``registry.FIGURE_MODELS``: each with the model kind it needs) and the summary.
MODEL_FIGURES = (*registry.FIGURE_MODELS, "summary")

#: ``scan.k1`` and ``scan.k3``: the gravity-gradient inertia ratios of the scan's bodies (a grid, I2 = 1 kg m²); the
#: kind they belong to says so in its registry row (``scan_keys``).
K_SCAN_KEYS = ("k1", "k3")

#: ``scan.triangle``: the n x n inertia-triangle grid, n in this range.
TRIANGLE_RANGE = (2, 200)

#: Tables and their keys, in the order of the resolved study (:data:`tumble.pipeline.schema.TABLES`).
#: ``body.dimensions`` is a table whose keys are the shape function's arguments; ``scan`` holds only the keys a
#: study gives.
_TABLES = schema.TABLES
_TOP = ("title", *_TABLES)
_SUBTABLES = {("body", "dimensions"), ("scan", "state")}
_TABLE_ARRAYS = {("scan", "body")}

#: Title of a study given as a mapping with ``title = ""`` (a file's default title is its stem).
UNTITLED = "untitled study"

# Shape moments given in a study must agree with the shape's to this relative tolerance.
_SHAPE_RTOL = 1e-9

#: Keys of one entry of ``scan.body`` (an inline table): a shape with its dimensions, or moments.
_SCAN_BODY_KEYS = ("label", "shape", "dimensions", "moments")


class StudyError(ValueError):
    """An invalid study: ``"<file>: <field.path>: <what is wrong>"``.

    Attributes
    ----------
    file : str
        The study file as given (or the bundled file a name resolved to), or ``"<mapping>"``.
    field : str
        Dotted field path, list indices from 0 (``body.moments[2]``); ``<file>`` or ``<toml>`` for problems
        with the file itself.
    problem : str
        What is wrong, and where it helps, what would be right.
    """

    def __init__(self, file, field, problem):
        self.file = str(file)
        self.field = str(field)
        self.problem = str(problem)
        super().__init__(f"{self.file}: {self.field}: {self.problem}")

    def __reduce__(self):
        return type(self), (self.file, self.field, self.problem)


class _Invalid(Exception):
    """A problem at a field path; :func:`load_study` adds the file and raises a :class:`StudyError`."""

    def __init__(self, field, problem):
        super().__init__(field, problem)
        self.field = field
        self.problem = problem


# --------------------------------------------------------------------------------------------------------
# Reading


def _toml_kind(value):
    """How TOML (the user's view) calls the type of ``value``."""
    if isinstance(value, (bool, np.bool_)):
        return f"a boolean ({str(bool(value)).lower()})"
    if isinstance(value, numbers.Integral):
        return f"an integer ({int(value)})"
    if isinstance(value, numbers.Real):
        return f"a float ({float(value)!r})"
    if isinstance(value, str):
        return f"a string ({value!r})"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, (list, tuple)):
        return "an array"
    if hasattr(value, "isoformat"):
        return "a date/time"
    return f"a {type(value).__name__}"


def _read_toml(path, shown):
    """The table in TOML file ``path``; errors name the file as ``shown``."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as err:
        raise StudyError(shown, "<toml>", f"not valid TOML: {err}") from None
    except UnicodeDecodeError as err:
        raise StudyError(shown, "<toml>", f"not UTF-8 text ({err.reason} at byte {err.start})") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise StudyError(shown, "<toml>", "arrays or tables nested too deeply (a study nests a few levels at "
                                          "most)") from None
    except OSError as err:
        raise StudyError(shown, "<file>", f"cannot be read: {err.strerror or err}") from None


def _is_bare_name(text):
    return bool(text) and Path(text).name == text and "/" not in text and os.sep not in text \
        and not text.endswith(".toml") and text not in (".", "..")


def _locate(source):
    """``(path, shown)`` of a study file given as a path or a bundled name."""
    text = os.fspath(source)
    path = Path(text)
    if path.is_file():
        return path, text
    if _is_bare_name(text):  # a bundled name wins over a folder of the same name (e.g. an output folder)
        bundled = STUDIES_DIR / f"{text}.toml"
        if bundled.is_file():
            return bundled, str(bundled)
    if path.exists():
        raise StudyError(text, "<file>", "is not a file (a study is a TOML file or a bundled study name)")
    bundled = _bundled_names()
    close = difflib.get_close_matches(text, bundled, n=1, cutoff=0.6) if _is_bare_name(text) else []
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise StudyError(text, "<file>", f"no such file, and no bundled study of that name ({hint}bundled: "
                                     f"{', '.join(bundled) or 'none'})")


#: Deepest nesting of tables and arrays a study may have (a study nests three levels at most).
_MAX_DEPTH = 16


def _plain(value, field, depth=0):
    """A copy of a mapping-given study with tuples as lists, ndarrays as lists, numpy scalars as Python
    scalars and mappings as dicts (keys must be strings)."""
    if depth > _MAX_DEPTH and isinstance(value, (Mapping, list, tuple, np.ndarray)):
        raise _Invalid(field or "<study>", f"nested more than {_MAX_DEPTH} levels deep")
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise _Invalid(field or "<study>", f"keys must be strings, got {key!r}")
            out[key] = _plain(item, f"{field}.{key}" if field else key, depth + 1)
        return out
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(item, f"{field}[{i}]", depth + 1) for i, item in enumerate(value)]
    if isinstance(value, np.generic):
        return value.item()
    return value


# --------------------------------------------------------------------------------------------------------
# Structure: known keys, tables where tables belong


def _leaf_paths():
    paths = ["title"]
    for table, keys in _TABLES.items():
        paths += [f"{table}.{key}" for key in keys]
    return paths


def _unknown(field, key, known):
    """An _Invalid for unknown ``key`` in the table at ``field``, suggesting a close or relocated key."""
    path = f"{field}.{key}" if field else key
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    entry = field.endswith("]")  # an entry of an array of tables (scan.body[1]): no relocated-key hints
    if close:
        hint = f"did you mean {close[0]!r}?"
    elif entry:
        hint = f"known keys: {', '.join(known)}"
    else:
        others = {p.rsplit(".", 1)[-1]: p for p in reversed(_leaf_paths()) if p != path}
        near = difflib.get_close_matches(key, list(others), n=1, cutoff=0.8)
        elsewhere = [others[near[0]]] if near else []
        hint = f"did you mean {elsewhere[0]}?" if elsewhere else f"known keys: {', '.join(known)}"
    where = (f"in {field}" if entry else f"in [{field}]") if field else "at the top level"
    return _Invalid(path, f"unknown key {where}; {hint}")


def _check_structure(study):
    """Every key known, every table a table."""
    if not isinstance(study, Mapping):
        raise _Invalid("<study>", f"a study is a table of settings, got {_toml_kind(study)}")
    for key, value in study.items():
        if key not in _TOP:
            raise _unknown("", key, _TOP)
        if key not in _TABLES:
            continue
        if not isinstance(value, Mapping):
            raise _Invalid(key, f"must be a table ([{key}] section), got {_toml_kind(value)}")
        for sub, item in value.items():
            if sub not in _TABLES[key]:
                raise _unknown(key, sub, _TABLES[key])
            if (key, sub) in _TABLE_ARRAYS:
                continue  # an array of tables (scan.body), checked entry by entry
            if (key, sub) in _SUBTABLES:
                if not isinstance(item, Mapping):
                    raise _Invalid(f"{key}.{sub}", f"must be a table, got {_toml_kind(item)}")
            elif isinstance(item, Mapping):
                raise _Invalid(f"{key}.{sub}", "must be a value, got a table")


def _merge(defaults, study):
    """``study`` over ``defaults`` (two levels; ``body.dimensions`` and scan lists are replaced whole)."""
    merged = copy.deepcopy(defaults)
    for key, value in study.items():
        if key in _TABLES:
            merged.setdefault(key, {}).update(copy.deepcopy(value))
        else:
            merged[key] = copy.deepcopy(value)
    return merged


# --------------------------------------------------------------------------------------------------------
# Values


def _number(value, field):
    """A finite real number as a float (ints accepted; booleans are not numbers)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise _Invalid(field, f"must be a number, got {_toml_kind(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise _Invalid(field, f"must be finite, got {x}")
    return x


def _at_least(value, field, low, unit=""):
    x = _number(value, field)
    if x < low:
        raise _Invalid(field, f"must be >= {low:g}{unit}, got {x!r}")
    return x


def _integer(value, field):
    """An integer as a Python int (floats are not integers, even integral ones; booleans neither)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise _Invalid(field, f"must be an integer, got {_toml_kind(value)}")
    return operator.index(value)


def _string(value, field):
    if not isinstance(value, str):
        raise _Invalid(field, f"must be a string, got {_toml_kind(value)}")
    return value


def _choice(value, field, allowed):
    _string(value, field)
    if value not in allowed:
        close = difflib.get_close_matches(value, [a for a in allowed if a], n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        shown = ", ".join(repr(a) for a in allowed)
        raise _Invalid(field, f"unknown value {value!r}{hint} (one of {shown})")
    return value


def _array(value, field, *, length=None, empty=True):
    if not isinstance(value, list):
        raise _Invalid(field, f"must be an array, got {_toml_kind(value)}")
    if length is not None and len(value) != length:
        raise _Invalid(field, f"must have {length} elements, got {len(value)}")
    if not empty and not value:
        raise _Invalid(field, "must not be empty")
    return value


def _vector(value, field):
    return [_number(x, f"{field}[{i}]") for i, x in enumerate(_array(value, field, length=3))]


def _moments(value, field):
    """Three principal moments, kg m², positive and obeying the triangle inequality."""
    moments = _vector(value, field)
    for i, x in enumerate(moments):
        if x <= 0:
            raise _Invalid(f"{field}[{i}]", f"a principal moment must be > 0 kg m², got {x!r}")
    try:
        validate_moments(moments, name="the moments")
    except ValueError as err:
        raise _Invalid(field, str(err)) from None
    return moments


def _distinct(values, field, raw):
    """No value twice in a scan list (each scene would be run twice)."""
    seen = {}
    for i, v in enumerate(values):
        key = tuple(v) if isinstance(v, list) else v
        if key in seen:
            raise _Invalid(f"{field}[{i}]", f"duplicates {field}[{seen[key]}] ({raw[i]!r}); list each value "
                                            f"once")
        seen[key] = i
    return values


def _names(value, field, allowed, *, empty=True):
    items = _array(value, field, empty=empty)
    names = [_choice(x, f"{field}[{i}]", allowed) for i, x in enumerate(items)]
    return _distinct(names, field, items)


# --------------------------------------------------------------------------------------------------------
# Fields


def _axis(value, field):
    a = _integer(value, field)
    if a not in (1, 2, 3):
        raise _Invalid(field, f"must be 1, 2 or 3 (a principal axis, 1-based), got {a}")
    return a


def _rate(value, field):
    x = _number(value, field)
    if x == 0:
        raise _Invalid(field, "must be non-zero, rad/s (the spin rate; its sign is the sense of rotation)")
    low, high = registry.SPIN_RANGE
    if not low <= abs(x) <= high:
        raise _Invalid(field, f"must be within {low:g} to {high:g} rad/s in magnitude, got {x!r}: beyond, squares "
                              f"leave the float range; the motion is scale invariant (w rad/s is 1 rad/s with "
                              f"times / w)")
    return x


def _amplitude(value, field, distribution):
    x = _at_least(value, field, 0, " rad")
    if x == 0:
        raise _Invalid(field, "must be > 0 rad: a growth rate or frequency is measured on perturbed spins, and "
                              "a spin exactly on its axis never moves off it")
    problem = registry.amplitude_problem(x)
    if problem:
        raise _Invalid(field, problem)
    if distribution != "gaussian" and x >= 0.5 * math.pi:
        raise _Invalid(field, f"must be < pi/2 rad for distribution {distribution!r} (the tilt of the "
                              f"perturbed spins), got {x!r}")
    return x


def _method(value, field, profile):
    name = _choice(value, field, METHOD_NAMES)
    if name == "exact" and profile != "none":
        raise _Invalid(field, f"'exact' is the torque-free closed form, but torque.profile is {profile!r}; "
                              f"use 'auto' or a fixed-step method ({', '.join(registry.STEPPING)})")
    return name


def _tolerance(value, field):
    """``integration.rtol`` / ``atol``: a number > 0 (rtol at least the smallest a double's error estimate can meet)."""
    from ..engine.adaptive_runs import MIN_RTOL

    x = _number(value, field)
    if field.endswith("rtol") and not x >= MIN_RTOL:
        raise _Invalid(field, f"must be >= {MIN_RTOL:g} (below it a double's rounding is the error estimate), got {x!r}")
    if x <= 0.0:
        raise _Invalid(field, f"must be > 0, got {x!r}")
    return x


def _methods(resolved):
    """``[(field, method)]``: the study's methods (``scan.method``'s, else ``integration.method``)."""
    scan = resolved["scan"]
    return ([(f"scan.method[{i}]", m) for i, m in enumerate(scan["method"])] if "method" in scan
            else [("integration.method", resolved["integration"]["method"])])


def _no_tolerance(resolved):
    """An error-controlled method runs a chaos or a section study's orbits only."""
    for field, method in _methods(resolved):
        if method in registry.ERROR_CONTROLLED:
            raise _Invalid(field, f"{method!r} (error-controlled) runs the orbits of a chaos or section study "
                                  f"(chaos.indicators, or a [section] table with chaos.start's map); the stability "
                                  f"scenes take the closed form or a fixed step ({', '.join(registry.STEPPING)})")


def _shape_parameters(shape):
    """Keyword parameters of ``tumble.physics.shapes.<shape>``: name -> default (``inspect.Parameter.empty``)."""
    params = inspect.signature(getattr(shapes, shape)).parameters.values()
    return {p.name: p.default for p in params
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}


def _dimensions(shape, dims, field="body.dimensions"):
    """The shape's keyword arguments (given ones checked, defaults filled in) and the resulting Body;
    ``field`` is the path of the dimensions table (``scan.body[2].dimensions`` for an entry of a scan)."""
    params = _shape_parameters(shape)
    resolved = {}
    for key, value in dims.items():
        path = f"{field}.{key}"
        if key not in params:
            raise _Invalid(path, f"unknown key: {shape}() has no argument {key!r}{_hint(key, params)}")
        if isinstance(params[key], str):
            resolved[key] = _string(value, path)
        else:
            resolved[key] = _number(value, path)
    missing = [k for k, d in params.items() if d is inspect.Parameter.empty and k not in resolved]
    if missing:
        raise _Invalid(field, f"missing {', '.join(missing)}: {shape}() takes {', '.join(params)} (SI units)")
    for key, default in params.items():
        if key not in resolved and isinstance(default, (str, int, float)) and not isinstance(default, bool):
            resolved[key] = default if isinstance(default, str) else float(default)
    body = _shape_body(shape, resolved, field)
    ordered = {key: resolved[key] for key in params if key in resolved}
    return ordered, body


def _hint(key, params):
    close = difflib.get_close_matches(key, list(params), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else f" (arguments: {', '.join(params)})"


def _shape_body(shape, dims, field="body.dimensions"):
    try:
        return getattr(shapes, shape)(**dims)
    except ValueError as err:
        message = str(err)
        named = [k for k in dims if message.startswith(f"{k} ")]
        raise _Invalid(f"{field}.{named[0]}" if named else field, f"{shape}(): {message}") from None


def _body(table, given, field="body"):
    """A body table (merged ``table``; ``given``: as the study states it) resolved to moments, shape and
    dimensions; ``field`` is its path (``body``, or ``scan.body[2]`` for an entry of a scan)."""
    shape = _choice(table["shape"], f"{field}.shape", ("", *SHAPES))
    dims = table["dimensions"]
    if not shape:
        if dims:
            raise _Invalid(f"{field}.dimensions", f"given, but {field}.shape is \"\"; dimensions describe a "
                                                  f"shape: set {field}.shape or give {field}.moments instead")
        return {"moments": _moments(table["moments"], f"{field}.moments"), "shape": "", "dimensions": {}}
    dims, body = _dimensions(shape, dims, f"{field}.dimensions")
    moments = [float(x) for x in body.moments]
    if "moments" in given:
        stated = _moments(given["moments"], f"{field}.moments")
        if not np.allclose(stated, moments, rtol=_SHAPE_RTOL, atol=0.0):
            raise _Invalid(f"{field}.moments", f"{stated} disagree with {field}.shape = {shape!r}, whose "
                                               f"moments are {moments}; state the shape or the moments, not both")
    return {"moments": moments, "shape": shape, "dimensions": dims}


def _scan_body(entry, field, index):
    """One entry of ``scan.body``: ``{shape = ..., dimensions = {...}, label = ...}`` or
    ``{moments = [...], label = ...}``, checked exactly like the ``[body]`` table."""
    if not isinstance(entry, Mapping):
        raise _Invalid(field, f"must be a table ({{shape = \"rod\", dimensions = {{...}}}} or "
                              f"{{moments = [I1, I2, I3]}}), got {_toml_kind(entry)}")
    for key in entry:
        if key not in _SCAN_BODY_KEYS:
            raise _unknown(field, key, _SCAN_BODY_KEYS)
    dims = entry.get("dimensions", {})
    if not isinstance(dims, Mapping):
        raise _Invalid(f"{field}.dimensions", f"must be a table, got {_toml_kind(dims)}")
    shape = entry.get("shape", "")
    if not shape and "moments" not in entry and not dims:
        raise _Invalid(field, "names no body: give shape (with dimensions) or moments = [I1, I2, I3]")
    table = {"shape": shape, "dimensions": dims, "moments": entry.get("moments")}
    body = _body(table, entry, field)
    label = _string(entry.get("label", ""), f"{field}.label") or body["shape"] or f"body {index}"
    return {"label": label, "shape": body["shape"], "dimensions": body["dimensions"], "moments": body["moments"]}


def _scan_body_list(value, field):
    """``scan.body``: a non-empty list of bodies with distinct labels."""
    items = _array(value, field, empty=False)
    bodies = [_scan_body(entry, f"{field}[{i}]", i) for i, entry in enumerate(items)]
    seen = {}
    for i, body in enumerate(bodies):
        label = body["label"]
        if label in seen:
            raise _Invalid(f"{field}[{i}].label", f"{label!r} duplicates the label of {field}[{seen[label]}]; "
                                                  f"labels name the bodies of the scan and must be distinct "
                                                  f"(set label = \"...\" on one of them)")
        seen[label] = i
    return bodies


def _torque(table, axis):
    """The torque table; a torque (profile other than 'none') must act about the spin axis ``axis``."""
    profile = _choice(table["profile"], "torque.profile", PROFILES)
    vector = _vector(table["vector"], "torque.vector")
    times = {f.key: _at_least(table[f.key], f.path, f.minimum, f" {f.units}")
             for f in map(schema.field, ("torque.period", "torque.duration"))}
    if profile == "none" and any(vector):
        raise _Invalid("torque.vector", f"is {vector} but torque.profile is 'none' (torque-free); set "
                                        f"torque.profile (e.g. 'constant') or remove the vector")
    if profile != "none":
        for i, x in enumerate(vector):
            if i != axis - 1 and x != 0:
                raise _Invalid(f"torque.vector[{i}]", f"must be 0, got {x!r}: measured rates are compared with "
                                                      f"linear theory for a torque about the spin axis "
                                                      f"(spin.axis = {axis}) only; arbitrary torques belong to "
                                                      f"tumble.integrate")
        if vector[axis - 1] == 0:
            raise _Invalid(f"torque.vector[{axis - 1}]", f"must be non-zero for profile {profile!r}: the torque "
                                                         f"acts about the spin axis (spin.axis = {axis}); for no "
                                                         f"torque use torque.profile = 'none'")
    needed = _PROFILE_TIMES.get(profile)
    for key, value in times.items():
        if key == needed and value <= 0:
            raise _Invalid(f"torque.{key}", f"must be > 0 s for profile {profile!r}, got {value!r}")
        if key != needed and value != 0:
            raise _Invalid(f"torque.{key}", f"is unused by profile {profile!r} and must stay 0, got {value!r}")
    return {"profile": profile, "vector": vector, **times}


def _scan(table, resolved):
    """The scan lists (only the keys given), each element checked like the field it replaces."""
    out = {}
    shape = resolved["body"]["shape"]
    distribution = resolved["perturbation"]["distribution"]
    profile = resolved["torque"]["profile"]
    for other in ("moments", "triangle"):
        if "body" in table and other in table:
            raise _Invalid("scan.body", f"not together with scan.{other}: each gives the bodies of the scan")
    if "axis" in table and profile != "none":
        axis = resolved["spin"]["axis"]
        raise _Invalid("scan.axis", f"not with a torque (torque.profile = {profile!r}): the torque acts about the "
                                    f"spin axis (spin.axis = {axis}), which is therefore fixed; scan the axis "
                                    f"torque-free (torque.profile = 'none')")
    if "triangle" in table and "moments" in table:
        raise _Invalid("scan.triangle", "not together with scan.moments: each gives the bodies of the scan")
    for key in SCAN_KEYS:
        if key not in table or key in MODEL_SCAN_KEYS or key in K_SCAN_KEYS:  # the models' keys: _model_scan
            continue
        if key == "state":  # a chaos map's components: checked against the model's state (_chaos_state_scan)
            out[key] = _state_scan(table[key])
            continue
        field = f"scan.{key}"
        value = table[key]
        if key in ("body", "moments", "triangle") and shape:
            raise _Invalid(field, f"scans bodies, but body.shape = {shape!r} fixes the body; use one of them")
        if key == "body":
            out[key] = _scan_body_list(value, field)
            continue
        if key == "triangle":
            n = _integer(value, field) if not isinstance(value, list) else None
            if n is None:
                raise _Invalid(field, "must be an integer n (the n x n inertia-triangle grid), got an array")
            low, high = TRIANGLE_RANGE
            if not low <= n <= high:
                raise _Invalid(field, f"must be in [{low}, {high}] (the n x n inertia-triangle grid), got {n}")
            out[key] = n
            continue
        items = _array(value, field, empty=False)
        check = {
            "moments": _moments,
            "axis": _axis,
            "rate": _rate,
            "amplitude": lambda v, f: _amplitude(v, f, distribution),
            "method": lambda v, f: _method(v, f, profile),
            "tilt": _tilt,
            "angle": _number,
        }[key]
        out[key] = _distinct([check(v, f"{field}[{i}]") for i, v in enumerate(items)], field, items)
    return out


def _model(table, given, scan):
    """The ``[model]`` table: its kind and the kind's own parameters (None for the free body, so that a study
    without ``[model]`` resolves, hashes and runs as before). ``given``: the table as the study states it."""
    kind = _choice(table["kind"], "model.kind", MODEL_KINDS)
    spec = registry.model_kind(kind)
    implemented = [m.name for m in registry.MODELS if m.implemented]
    if not spec.implemented:
        raise _Invalid("model.kind", f"{kind!r} is reserved for a later issue and not implemented yet; "
                                     f"implemented: {', '.join(implemented)}")
    extras = models.CLASSES[kind].extras if kind in models.CLASSES else ()
    for key in given:
        if key != "kind" and key not in spec.parameters and key not in extras:
            raise _Invalid(f"model.{key}", f"not a parameter of model kind {kind!r} (its parameters: "
                                           f"{', '.join((*spec.parameters, *extras)) or 'none'}); remove it or change "
                                           f"model.kind")
    for key in MODEL_SCAN_KEYS:
        if key in scan and key not in spec.parameters:
            owner = next(m.name for m in registry.MODELS if key in m.parameters)
            reserved = "" if registry.model_kind(owner).implemented else f" ({owner}: reserved, not implemented yet)"
            raise _Invalid(f"scan.{key}", f"not a parameter of model kind {kind!r} (its parameters: "
                                          f"{', '.join(spec.parameters) or 'none'}){reserved}")
    for key in K_SCAN_KEYS:
        if key in scan and key not in spec.scan_keys:
            owner = next(m.name for m in registry.MODELS if key in m.scan_keys)
            raise _Invalid(f"scan.{key}", f"scans the gravity-gradient inertia ratios; not with model kind {kind!r} "
                                          f"(set model.kind = {owner!r}, or scan bodies with scan.moments)")
    if kind == registry.DEFAULT_MODEL:
        return None
    out = {"kind": kind}
    if "rotor" in spec.parameters:
        out["rotor"] = _vector(table["rotor"], "model.rotor")
    for key in _POSITIVE_PARAMETERS:
        if key in spec.parameters:
            out[key] = _number(table[key], f"model.{key}")
            if out[key] <= 0 and key not in scan:
                parameter = registry.model_parameter(key)
                raise _Invalid(f"model.{key}", f"must be > 0 {parameter.units} for a {kind} ({parameter.text.split(': ', 1)[1]}), "
                                               f"got {out[key]!r}")
    for key in extras:  # the physics class's own keys (centre, eccentricity): kept only where a study gives them
        if key in given:
            out[key] = _model_extra(kind, key, table[key])
    return out


def _model_extra(kind, key, value):
    """``model.centre`` (a heavy top's centre of mass, a non-zero 3-vector) or ``model.eccentricity`` (a gravity
    gradient's orbit, in [0, 1)), checked by the model's own class."""
    field = f"model.{key}"
    value = _vector(value, field) if isinstance(value, list) else _number(value, field)
    try:
        models.CLASSES[kind]([1.0, 1.0, 1.0], *([1.0] * len(registry.model_kind(kind).parameters)), **{key: value})
    except ValueError as err:
        raise _Invalid(field, str(err)) from None
    return value


# The models' scalar parameters that must be > 0 (registry data: mgl, orbit_rate, damper_inertia, damping).
_POSITIVE_PARAMETERS = tuple(p.key for p in registry.MODEL_PARAMETERS if p.positive)


def _model_scan(table):
    """``scan.rotor`` (3-vectors, or numbers: h along each scene's spin axis) and ``scan.<key>`` (> 0) of the positive
    scalar parameters (:data:`_POSITIVE_PARAMETERS`)."""
    out = {}
    if "rotor" in table:
        items = _array(table["rotor"], "scan.rotor", empty=False)
        vectors = isinstance(items[0], list)
        values = []
        for i, item in enumerate(items):
            field = f"scan.rotor[{i}]"
            if isinstance(item, list) != vectors:
                raise _Invalid(field, "scan.rotor lists 3-vectors (N m s, body frame) or numbers (h along each "
                                      "scene's spin axis, N m s), not both")
            values.append(_vector(item, field) if vectors else _number(item, field))
        out["rotor"] = _distinct(values, "scan.rotor", items)
    for key in _POSITIVE_PARAMETERS:
        if key in table:
            units = registry.model_parameter(key).units
            items = _array(table[key], f"scan.{key}", empty=False)
            values = []
            for i, item in enumerate(items):
                x = _number(item, f"scan.{key}[{i}]")
                if x <= 0:
                    raise _Invalid(f"scan.{key}[{i}]", f"must be > 0 {units}, got {x!r}")
                values.append(x)
            out[key] = _distinct(values, f"scan.{key}", items)
    given = [key for key in K_SCAN_KEYS if key in table]
    if given and len(given) != 2:
        missing = next(key for key in K_SCAN_KEYS if key not in table)
        raise _Invalid(f"scan.{missing}", f"needed with scan.{given[0]}: scan.k1 and scan.k3 give the grid of "
                                          f"gravity-gradient bodies together")
    for key in given:
        for other in ("body", "moments", "triangle"):
            if other in table:
                raise _Invalid(f"scan.{key}", f"not together with scan.{other}: each gives the bodies of the scan")
        items = _array(table[key], f"scan.{key}", empty=False)
        values = []
        for i, item in enumerate(items):
            x = _number(item, f"scan.{key}[{i}]")
            if not -1.0 < x < 1.0:
                raise _Invalid(f"scan.{key}[{i}]", f"must lie in (-1, 1) (the triangle inequality bounds k1 and k3 "
                                                   f"to [-1, 1]; the corners are no body), got {x!r}")
            values.append(x)
        out[key] = _distinct(values, f"scan.{key}", items)
    return out


def _spin(table, given, moments, model, scan):
    """The ``[spin]`` table: axis and rate, or ``momentum`` (``w = I^-1 (L - h)`` along a principal axis, which
    gives the axis and the rate; stated as well, they must agree)."""
    axis, rate = _axis(table["axis"], "spin.axis"), _rate(table["rate"], "spin.rate")
    momentum = _array(table["momentum"], "spin.momentum")
    if not momentum:
        return {"axis": axis, "rate": rate}
    momentum = _vector(momentum, "spin.momentum")
    for key in ("axis", "rate", "rotor", "body", "moments", "triangle"):
        if key in scan:
            raise _Invalid(f"scan.{key}", "not with spin.momentum: the scan would change the steady spin "
                                          "w = I^-1 (L - h); give spin.axis and spin.rate instead")
    rotor = (model or {}).get("rotor", [0.0, 0.0, 0.0])
    w = models.Gyrostat(moments, rotor).angular_velocity(momentum)
    scale = float(np.abs(w).max())
    along = [i for i in range(3) if abs(w[i]) > 1e-12 * scale]
    if len(along) != 1:
        shown = ", ".join(f"{x:.6g}" for x in w)
        raise _Invalid("spin.momentum", f"gives the spin w = I^-1 (L - h) = [{shown}] rad/s, which is not along a "
                                        f"principal axis; a stability scene spins about one (e.g. L = [0, I2 w, 0] "
                                        f"plus the rotor h)")
    axis_from, rate_from = along[0] + 1, _rate(float(w[along[0]]), "spin.momentum")
    if "axis" in given and axis != axis_from:
        raise _Invalid("spin.axis", f"is {axis}, but spin.momentum spins the body about axis {axis_from}; state "
                                    f"one of them")
    if "rate" in given and not math.isclose(rate, rate_from, rel_tol=1e-9):
        raise _Invalid("spin.rate", f"is {rate!r}, but spin.momentum gives {rate_from!r} rad/s; state one of them")
    return {"axis": axis_from, "rate": rate_from, "momentum": momentum}


def _check_model_scenes(resolved, given):
    """What a model study's scenes need: a heavy top about axis 3, a gyrostat's rotor along the spin axis, a
    model kernel's method, no torque, the models' figures (default ``["summary"]``)."""
    model, scan, spin = resolved["model"], resolved["scan"], resolved["spin"]
    kind = model["kind"]
    cls = models.CLASSES[kind]  # what the model says about its steady spins
    axes = [(f"scan.axis[{i}]", a) for i, a in enumerate(scan["axis"])] if "axis" in scan else [
        ("spin.axis", spin["axis"])]
    for field, a in axes:
        if a not in cls.spin_axes:
            raise _Invalid(field, f"must be {' or '.join(map(str, cls.spin_axes))} for a {kind} "
                                  f"({cls.spin_axes_reason}), got {a}")
    if "rotor" in registry.model_kind(kind).parameters:  # a rotor across the spin axis breaks the steady spin
        rotors = ([(f"scan.rotor[{i}]", h) for i, h in enumerate(scan["rotor"])] if "rotor" in scan
                  else [("model.rotor", model["rotor"])])
        for field, h in rotors:
            if not isinstance(h, list):
                continue  # a number: along each scene's axis
            for axis_field, a in axes:
                across = [x for i, x in enumerate(h) if i != a - 1]
                if max(abs(x) for x in across) > cls.rotor_rtol * math.hypot(*h):  # the model's own
                    raise _Invalid(field, f"{h} N m s lies across the spin axis ({axis_field} = {a}); a steady "
                                          f"spin needs the rotor along it (give h along axis {a} only, or numbers "
                                          f"in scan.rotor: h along each scene's axis)")
    if any(x != 0.0 for x in model.get("centre", [0.0, 0.0, 1.0])[:2]):
        raise _Invalid("model.centre", f"{model['centre']} is off body axis 3: no steady spin for a stability scene "
                                       f"(the sleeping top needs it on axis 3); map it in a chaos study "
                                       f"(chaos.indicators)")
    if model.get("eccentricity", 0.0) > 0.0:
        raise _Invalid("model.eccentricity", f"{model['eccentricity']!r} > 0: no attitude is an equilibrium of an "
                                             f"eccentric orbit, so no stability scene; map it in a chaos study "
                                             f"(chaos.indicators)")
    if "k1" in scan and resolved["body"]["shape"]:
        raise _Invalid("scan.k1", f"scans bodies, but body.shape = {resolved['body']['shape']!r} fixes the body; use "
                                  f"one of them")
    fixed_by = cls.equilibrium_parameter  # a parameter fixes the equilibrium: spin.axis and spin.rate are not used
    if fixed_by:
        for key in ("axis", "rate"):
            if key in scan:
                raise _Invalid(f"scan.{key}", f"not used by a {kind} ({cls.equilibrium_reason}); scan "
                                              f"model.{fixed_by} with scan.{fixed_by}")
        if "momentum" in spin:
            raise _Invalid("spin.momentum", f"not used by a {kind} ({cls.equilibrium_reason}); give model.{fixed_by}")
    if resolved["torque"]["profile"] != "none":
        raise _Invalid("torque.profile", f"must be 'none' for model kind {kind!r}: model studies are torque-free "
                                         f"(the model's own forces act)")
    methods = ([(f"scan.method[{i}]", m) for i, m in enumerate(scan["method"])] if "method" in scan
               else [("integration.method", resolved["integration"]["method"])])
    allowed = registry.model_methods(kind)
    for field, m in methods:
        if m not in ("auto", *allowed):
            raise _Invalid(field, f"model kind {kind!r} steps with {', '.join(allowed)} ('auto': "
                                  f"{allowed[0]}), got {m!r}")
    outputs = resolved["outputs"]
    if "figures" not in given.get("outputs", {}):
        outputs["figures"] = ["summary"]
    for i, name in enumerate(outputs["figures"]):
        if name not in MODEL_FIGURES:
            raise _Invalid(f"outputs.figures[{i}]", f"{name!r} reads what only free-body scenes record; a model "
                                                    f"study draws {', '.join(MODEL_FIGURES)}")


def _tilt(value, field):
    """``chaos.tilt`` / ``scan.tilt``: in [0, 2 pi] rad (``release`` takes [0, pi]: :func:`_check_release`)."""
    x = _number(value, field)
    if not 0.0 <= x <= 2.0 * math.pi:
        raise _Invalid(field, f"must lie in [0, pi] rad (the tilt of body axis 3 from the vertical; [0, 2 pi] for "
                              f"chaos.start = 'swing'), got {x!r}")
    return x


def _check_release(resolved):
    """chaos.start = "release": each tilt in [0, pi] (a tilt past pi is the release tilted the other way)."""
    scan, chaos = resolved["scan"], resolved["chaos"]
    tilts = scan.get("tilt", [chaos["tilt"]])
    for i, x in enumerate(tilts):
        if x > math.pi:
            field = f"scan.tilt[{i}]" if "tilt" in scan else "chaos.tilt"
            raise _Invalid(field, f"must lie in [0, pi] rad (the tilt of body axis 3 from the vertical), got {x!r}")


#: The scan keys of a chaos study's initial states (chaos.indicators not empty).
_CHAOS_SCAN_KEYS = (*(key for start in registry.CHAOS_STARTS for key in start.keys if key != "rate"), "state")


def _state_scan(value):
    """``scan.state``: a table of state components, each a non-empty list of distinct numbers (the names are checked
    against the model's state by :func:`_check_chaos_study`)."""
    if not isinstance(value, Mapping) or not value:
        raise _Invalid("scan.state", "must be a table of state components, each a list of values, e.g. "
                                     "{w1 = [0.1, 0.2], w3 = [0.5, 1.0]}")
    out = {}
    for name, items in value.items():
        field = f"scan.state.{name}"
        items = _array(items, field, empty=False)
        out[name] = _distinct([_number(v, f"{field}[{i}]") for i, v in enumerate(items)], field, items)
    return out


def _chaos_state(value, field):
    """``chaos.state``: numbers (the length is checked against the model's state by :func:`_check_chaos_study`)."""
    return [_number(x, f"{field}[{i}]") for i, x in enumerate(_array(value, field))]


def _chaos(study, given, resolved):
    """The ``[chaos]`` table (None when ``chaos.indicators`` is empty: not a chaos study, which then may give none of
    its keys nor scan.tilt / scan.angle)."""
    indicators = _described(study, schema.field("chaos.indicators"))
    if not indicators and resolved["section"] is None:
        for key in given.get("chaos", {}):
            if key != "indicators":
                raise _Invalid(f"chaos.{key}", "is used by a chaos study only; set chaos.indicators (e.g. "
                                               "[\"megno\"]) or remove it")
        for key in _CHAOS_SCAN_KEYS:
            if key in resolved["scan"]:
                raise _Invalid(f"scan.{key}", "scans a chaos study's initial states; set chaos.indicators (e.g. "
                                              "[\"megno\"])")
        return None
    dt, horizon = resolved["integration"]["dt"], resolved["integration"]["horizon"]
    fixed = any(m not in registry.ERROR_CONTROLLED for _, m in _methods(resolved))
    if dt <= 0 and fixed:
        raise _Invalid("integration.dt", "a chaos study steps its orbits and their tangents with a fixed step: give "
                                         "one > 0 s (0, the planner's choice, is the stability scenes'), or "
                                         "integration.method = \"dop853\" and a tolerance")
    if horizon <= 0:
        raise _Invalid("integration.horizon", "a chaos study needs the time each orbit runs: give one > 0 s")

    def multiple(value, field):
        x = _number(value, field)
        if not fixed:  # error-controlled: the segments between orthonormalisations end anywhere
            if x <= 0:
                raise _Invalid(field, f"must be > 0 s, got {x!r}")
            return x
        ratio = x / dt
        if x <= 0 or round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * max(ratio, 1.0):
            raise _Invalid(field, f"must be a positive multiple of integration.dt = {dt:g} s, got {x!r}")
        return x

    def transient(value, field):
        x = _number(value, field)
        if not 0.0 <= x < horizon:
            raise _Invalid(field, f"must be >= 0 s and less than integration.horizon = {horizon:g} s, got {x!r}")
        return x

    return _table(study, "chaos", {"indicators": lambda value, field: indicators, "tilt": _tilt, "angle": _number,
                                   "state": _chaos_state, "renormalise": multiple, "transient": transient,
                                   "energy": _number})


def _check_chaos_study(resolved, given):
    """What a chaos study's map needs: a model of its start's kind, a Runge-Kutta method, no torque, no
    scan of bodies' axes, an exponent count and a GALI k within the state, its own figures."""
    chaos, scan, model = resolved["chaos"], resolved["scan"], resolved["model"]
    start = next(s for s in registry.CHAOS_STARTS if s.name == chaos["start"])
    kind = model["kind"] if model is not None else registry.DEFAULT_MODEL
    if start.kind and kind != start.kind:
        raise _Invalid("chaos.start", f"{start.name!r} starts a {start.kind} (model.kind = {start.kind!r}), not a "
                                      f"{kind}; the starts: " + ", ".join(f"{s.name} ({s.kind})"
                                                                          for s in registry.CHAOS_STARTS))
    for key in _CHAOS_SCAN_KEYS:
        if key in scan and key not in start.keys and not (key == "state" and start.name == "state"):
            raise _Invalid(f"scan.{key}", f"is no coordinate of chaos.start = {start.name!r} (its coordinates: "
                                          f"{', '.join(start.keys) or 'the components named in scan.state'})")
    names = registry.model_kind(kind).state
    if start.name == "state":
        _check_state_map(chaos, scan, kind, names)
    for key in ("axis", "amplitude", "body", "moments", "triangle", "k1", "k3"):
        if key in scan:
            raise _Invalid(f"scan.{key}", "not in a chaos study: its map scans the initial states of chaos.start "
                                          f"({', '.join(start.keys)}) and the model's parameters")
    if resolved["torque"]["profile"] != "none":
        raise _Invalid("torque.profile", "must be 'none' in a chaos study (the model's own forces act)")
    tangent_methods = (*registry.tangent_methods(kind), *registry.ERROR_CONTROLLED)
    for field, m in _methods(resolved):
        if m not in ("auto", *tangent_methods):
            raise _Invalid(field, f"a chaos study of a {kind} steps its tangents with a method whose map tumble "
                                  f"differentiates, one of {', '.join(tangent_methods)} ('auto': rk4; the splittings "
                                  f"for {', '.join(registry.LIE_POISSON_MODELS)} only), got {m!r}")
    if start.name == "swing":
        _check_energy(resolved)
    if start.name == "release":
        _check_release(resolved)
    n = len(registry.model_kind(kind).state)
    if chaos["exponents"] > n:
        raise _Invalid("chaos.exponents", f"must be at most {n} (the state of a {kind}: "
                                          f"{', '.join(registry.model_kind(kind).state)}), got {chaos['exponents']}")
    if chaos["gali_k"] > n:
        raise _Invalid("chaos.gali_k", f"must be at most {n} (the state of a {kind} has {n} components), got "
                                       f"{chaos['gali_k']}")
    outputs = resolved["outputs"]
    made = (*chaos["indicators"], *(["section"] if resolved["section"] is not None else []))
    if "figures" not in given.get("outputs", {}):
        drawn = [name for name, need in registry.CHAOS_FIGURES.items() if need in chaos["indicators"]]
        # the section, and megno_map, else finite_time, else none (GALI has no figure of its own)
        outputs["figures"] = (["section"] if "section" in made else []) + drawn[:1]
    for i, name in enumerate(outputs["figures"]):
        need = registry.CHAOS_FIGURES.get(name)
        if need is None:
            raise _Invalid(f"outputs.figures[{i}]", f"{name!r} is not a chaos study's figure; a chaos study draws "
                                                    f"{', '.join(registry.CHAOS_FIGURES)}")
        if need not in made:
            raise _Invalid(f"outputs.figures[{i}]", "section needs a [section] table (section.surface or "
                                                    "section.period)" if need == "section" else
                                                    f"{name} needs {need!r} in chaos.indicators")
    if "megno_map" in outputs["figures"] and start.keys and not any(k in scan for k in start.keys):
        raise _Invalid(f"scan.{start.keys[0]}", f"megno_map needs a map: scan.{start.keys[0]} and/or "
                                                f"scan.{start.keys[1]} (a list of values each)")


def _section(study, given, resolved):
    """The ``[section]`` table (None when it asks for no section: no surface and no period; then it may give none
    of its keys). Checked against the model's state and the map by :func:`_check_section`."""
    table = _table(study, "section", {
        "surface": _string, "value": _number, "axes": lambda value, field: [
            _string(x, f"{field}[{i}]") for i, x in enumerate(_array(value, field))],
        "direction": lambda value, field: _choice_of(value, field, (1, -1, 0))})
    if not table["surface"] and table["period"] == 0:
        for key in given.get("section", {}):
            if key not in ("surface", "period"):
                raise _Invalid(f"section.{key}", "is used by a section only; give section.surface (a component of "
                                                 "the state, e.g. \"g1\") or section.period (s), or remove it")
        return None
    if table["surface"] and table["period"] > 0:
        raise _Invalid("section.period", "not with section.surface: a section is the crossings of a surface or the "
                                         "states once per period, one of them")
    own, other = ("period", ("value", "direction")) if table["period"] > 0 else ("surface", ("phase",))
    for key in other:  # the other kind of section's key, given other than its default: it would be ignored
        if key in given.get("section", {}) and table[key] != schema.field(f"section.{key}").default:
            raise _Invalid(f"section.{key}", f"does not apply to a section by section.{own}; remove it")
    return table


def _choice_of(value, field, allowed):
    """One of the integers ``allowed``."""
    x = _integer(value, field)
    if x not in allowed:
        raise _Invalid(field, f"must be one of {', '.join(map(str, allowed))}, got {x}")
    return x


def _check_section(resolved):
    """A section study's section: its surface a component of the model's state, an error-controlled method (its
    crossings are read off the dense output), two plotted coordinates the map's start or the state has, and a MEGNO
    colour only with MEGNO."""
    section, chaos = resolved["section"], resolved["chaos"]
    kind = resolved["model"]["kind"]
    names = registry.model_kind(kind).state
    if section["surface"] and section["surface"] not in names:
        raise _Invalid("section.surface", f"must be a component of a {kind}'s state ({', '.join(names)}), got "
                                          f"{section['surface']!r}")
    for field, method in _methods(resolved):
        if method not in registry.ERROR_CONTROLLED:
            raise _Invalid(field, f"a section is read off the dense output of an error-controlled run: set "
                                  f"integration.method = {registry.ERROR_CONTROLLED[0]!r} (and integration.rtol, "
                                  f"atol), got {method!r}")
    start = next(s for s in registry.CHAOS_STARTS if s.name == chaos["start"])
    coordinates = (*start.keys, *names)
    if not section["axes"]:
        if len(start.keys) != 2:
            raise _Invalid("section.axes", f"chaos.start = {start.name!r} has {len(start.keys)} coordinates: name the "
                                           f"two the section plots, of {', '.join(coordinates)}")
        section["axes"] = list(start.keys)
    if len(section["axes"]) != 2:
        raise _Invalid("section.axes", f"must name two coordinates, got {len(section['axes'])}")
    for i, name in enumerate(section["axes"]):
        if name not in coordinates:
            raise _Invalid(f"section.axes[{i}]", f"must be a coordinate of chaos.start = {start.name!r} "
                                                 f"({', '.join(start.keys) or 'none'}) or a component of the state "
                                                 f"({', '.join(names)}), got {name!r}")
    if section["colour"] == "megno" and "megno" not in chaos["indicators"]:
        raise _Invalid("section.colour", "'megno' colours each orbit by its <Y>: add \"megno\" to chaos.indicators")


def _check_energy(resolved):
    """chaos.start = "swing": the energy at least the potential at every tilt of the map, for every M g l."""
    from ..measure import chaos_scenes

    model, scan, chaos = resolved["model"], resolved["scan"], resolved["chaos"]
    tilts = np.atleast_1d(scan.get("tilt", chaos["tilt"]))
    centre = np.asarray(model.get("centre", [0.0, 0.0, 1.0]), dtype=float)
    for mgl in np.atleast_1d(scan.get("mgl", model["mgl"])):
        potential = chaos_scenes.swing_potential(tilts, mgl, centre)
        worst = int(np.argmax(potential))
        if chaos["energy"] < potential[worst]:
            raise _Invalid("chaos.energy", f"must be at least the potential mgl c.g = {potential[worst]:.6g} J at "
                                           f"tilt {tilts[worst]:g} rad (mgl = {mgl:g} N m), where the top would be at "
                                           f"rest; got {chaos['energy']:g} J")


def _check_state_map(chaos, scan, kind, names):
    """chaos.start = "state": chaos.state is a whole state of the model, scan.state names its components, and
    spin.rate is not a coordinate of the map."""
    if len(chaos["state"]) != len(names):
        raise _Invalid("chaos.state", f"must hold the {len(names)} components of a {kind}'s state "
                                      f"({', '.join(names)}), got {len(chaos['state'])}")
    if "rate" in scan:
        raise _Invalid("scan.rate", "not with chaos.start = 'state': scan the spin's components in scan.state "
                                    "(e.g. w3)")
    if "state" not in scan:
        raise _Invalid("scan.state", "chaos.start = 'state' maps the components named here, e.g. "
                                     "{w1 = [0.1, 0.2], w3 = [0.5, 1.0]}")
    for name in scan["state"]:
        if name not in names:
            raise _Invalid(f"scan.state.{name}", f"is no component of a {kind}'s state ({', '.join(names)})")
    unit = models.CLASSES[kind].unit_blocks if kind in models.CLASSES else ()
    for letter, start, stop in registry.state_blocks(kind):  # g, q: unit vectors at every point of the map
        if letter not in unit:
            continue
        block = names[start:stop]
        values = [np.atleast_1d(np.asarray(scan["state"].get(c, chaos["state"][start + i]), dtype=float))
                  for i, c in enumerate(block)]
        # the map spans every combination of the values: each is unit only if the first point is and each
        # component's square is the same in all its values (checked by the first point with that component at its
        # value whose square differs most), without making the map
        first = np.array([v[0] for v in values])
        points = [first] + [np.where(np.arange(len(block)) == i, v[np.argmax(np.abs(v * v - v[0] * v[0]))], first)
                            for i, v in enumerate(values)]
        point = next((p for p in points if not abs(np.linalg.norm(p) - 1.0) <= 1e-9), None)
        if point is not None:
            norm = float(np.linalg.norm(point))
            scanned = [c for c in block if c in scan["state"]]
            raise _Invalid(f"scan.state.{scanned[0]}" if scanned else "chaos.state",
                           f"({', '.join(block)}) of a {kind} must be a unit vector at every point of the map (tumble "
                           f"does not normalise it); {point.tolist()} has norm {norm:.9g}")


def _described(study, field):
    """The value of ``field`` (a :class:`tumble.pipeline.schema.Field` checked by its description alone: a string, a
    choice, a list of names, an integer or a number with a lower bound) in the merged ``study``, checked."""
    value, path = study[field.table][field.key] if field.table else study[field.key], field.path
    if field.check == "string":
        return _string(value, path)
    if field.check == "choice":
        return _choice(value, path, field.choices)
    if field.check == "names":
        return _names(value, path, field.choices, empty=not field.nonempty)
    if field.check == "integer":
        n = _integer(value, path)
        if field.minimum is not None and n < field.minimum:
            raise _Invalid(path, f"must be >= {field.minimum}, got {n}")
        return n
    if field.check == "number":
        return _at_least(value, path, field.minimum, f" {field.units}")
    raise AssertionError(f"{path}: check {field.check!r} is a rule of its own, not a description")


def _table(study, table, rules=None):
    """Table ``table`` of the merged ``study`` resolved in the order of its description: each field by its own rule
    (``rules[key](value, path)``, for the values that depend on others) or else by its description
    (:func:`_described`)."""
    rules = rules or {}
    return {f.key: rules[f.key](study[table][f.key], f.path) if f.key in rules else _described(study, f)
            for f in schema.table_fields(table)}


def _resolve(study, given, title):
    """The resolved study from the merged mapping ``study`` (``given``: the study before merging)."""
    resolved = {"title": _described(study, schema.field("title")) or title}
    resolved["body"] = _body(study["body"], given.get("body", {}))
    scan_given = study["scan"]
    resolved["model"] = _model(study["model"], given.get("model", {}), scan_given)
    resolved["spin"] = _spin(study["spin"], given.get("spin", {}), resolved["body"]["moments"], resolved["model"],
                             scan_given)
    distribution = _described(study, schema.field("perturbation.distribution"))
    resolved["perturbation"] = _table(study, "perturbation", {
        "amplitude": lambda value, field: _amplitude(value, field, distribution)})
    resolved["torque"] = _torque(study["torque"], resolved["spin"]["axis"])
    profile = resolved["torque"]["profile"]
    resolved["integration"] = _table(study, "integration", {
        "method": lambda value, field: _method(value, field, profile), "rtol": _tolerance, "atol": _tolerance})
    torque = resolved["torque"]
    if torque["profile"] in registry.RESOLVED_PROFILES:  # a given step must resolve a sine or a pulse
        key = _PROFILE_TIMES[torque["profile"]]
        problem = registry.profile_step_problem(torque["profile"], torque[key], resolved["integration"]["dt"],
                                                "integration.dt")
        if problem:
            raise _Invalid(f"torque.{key}", problem)
    resolved["scan"] = _scan(study["scan"], resolved)
    resolved["scan"].update(_model_scan(study["scan"]))
    resolved["outputs"] = _table(study, "outputs")
    resolved["section"] = _section(study, given, resolved)
    resolved["chaos"] = _chaos(study, given, resolved)
    if resolved["chaos"] is not None:
        _check_chaos_study(resolved, given)
        if resolved["section"] is not None:
            _check_section(resolved)
    else:
        _no_tolerance(resolved)
        if resolved["model"] is not None:
            _check_model_scenes(resolved, given)
    return {key: resolved[key] for key in _TOP if resolved[key] is not None}


# --------------------------------------------------------------------------------------------------------
# Public


def _apply_overrides(study, overrides):
    """Set dotted ``overrides`` (``{"perturbation.samples": 64}``) in the (unmerged) study."""
    study = copy.deepcopy(study)
    for path, value in overrides.items():
        parts = str(path).split(".")
        if len(parts) == 1:
            study[parts[0]] = _plain(value, path)
            continue
        if len(parts) != 2 or parts[0] not in _TABLES:
            raise _Invalid(str(path), "an override names a field as 'table.key', e.g. 'perturbation.samples'")
        table = study.setdefault(parts[0], {})
        if not isinstance(table, dict):
            raise _Invalid(parts[0], f"must be a table ([{parts[0]}] section), got {_toml_kind(table)}")
        table[parts[1]] = _plain(value, path)
    return study


def load_study(source, *, overrides=None):
    """Read, merge over the defaults, validate and resolve a study.

    Parameters
    ----------
    source : str, os.PathLike or Mapping
        A TOML file; a bundled study's name (``"intermediate_axis"`` for
        ``studies/intermediate_axis.toml``, see :func:`bundled_studies`); or a mapping of the same shape
        as the file (e.g. a resolved study).
    overrides : Mapping[str, object], optional
        Values that replace the study's, by dotted field path (``{"perturbation.samples": 64}``), as the
        command line's ``--samples``, ``--seed`` and ``--out`` do; checked like the study itself.

    Returns
    -------
    dict
        The resolved study: every key of ``defaults.toml`` filled (``title`` defaults to the file's stem;
        with ``body.shape`` set, ``body.moments`` holds the shape's moments and ``body.dimensions`` also
        the arguments left at their defaults, except ``None`` ones), ``scan`` only the keys given
        (``scan.body`` as a list of ``{"label", "shape", "dimensions", "moments"}``, each body resolved like
        ``body``, ``shape`` ``""`` for moments; see :func:`scan_bodies`). Plain Python types only
        (JSON-serialisable); ``load_study(load_study(x)) == load_study(x)``.

    Raises
    ------
    StudyError
        If the file cannot be read or parsed, or any key or value is invalid; the message names the file,
        the field path and what is wrong.
    """
    if isinstance(source, Mapping):
        shown, title = "<mapping>", UNTITLED
        try:
            given = _plain(source, "")
        except _Invalid as err:
            raise StudyError(shown, err.field, err.problem) from None
    elif isinstance(source, (str, os.PathLike)):
        path, shown = _locate(source)
        title = path.stem
        given = _read_toml(path, shown)
    else:
        raise TypeError(f"a study is a path, a bundled study name or a mapping, got {type(source).__name__}")
    defaults = schema.defaults()
    try:
        if overrides:
            given = _apply_overrides(given, overrides)
        _check_structure(given)
        return _resolve(_merge(defaults, given), given, title)
    except _Invalid as err:
        raise StudyError(shown, err.field, err.problem) from None


def _bundled_names():
    folder = Path(STUDIES_DIR)
    if not folder.is_dir():
        return []
    return sorted(p.stem for p in folder.glob("*.toml") if p.name != "defaults.toml" and p.is_file())


def bundled_studies():
    """The bundled studies: ``{name: title}``, sorted by name (``defaults.toml`` is not a study).

    The title is the file's ``title`` or, when it has none, its name. Raises :class:`StudyError` for a
    bundled file that is not valid TOML.
    """
    out = {}
    for name in _bundled_names():
        path = Path(STUDIES_DIR) / f"{name}.toml"
        title = _read_toml(path, str(path)).get("title", "")
        out[name] = title if isinstance(title, str) and title else name
    return out


def resolve_body(study):
    """The :class:`~tumble.physics.bodies.Body` of ``study``, a resolved study (:func:`load_study`), not of its
    scan: ``tumble.physics.shapes.<body.shape>(**body.dimensions)`` when a shape is named, else
    ``Body(*body.moments)``."""
    body = study["body"]
    if body.get("shape"):
        return getattr(shapes, body["shape"])(**body.get("dimensions", {}))
    return Body(*body["moments"])


def scan_bodies(study):
    """The bodies a resolved study's scan runs, from ``scan.body`` or ``scan.moments``.

    Parameters
    ----------
    study : Mapping
        A resolved study (:func:`load_study`).

    Returns
    -------
    tuple of (ndarray, list of str), or None
        ``(moments, labels)``: ``moments`` of shape (B, 3), principal moments in kg m² (float64), one row
        per body in the order of the scan; ``labels`` the B body labels (``scan.body``'s labels, or
        ``"body 0"``, ``"body 1"``, ... for ``scan.moments``). ``None`` when the scan lists no bodies, and
        for ``scan.triangle``, whose grid the caller builds (``tumble.inertia_triangle(n)``).
    """
    scan = study.get("scan", {})
    if "body" in scan:
        entries = scan["body"]
        moments = np.array([entry["moments"] for entry in entries], dtype=np.float64).reshape(-1, 3)
        return moments, [entry["label"] for entry in entries]
    if "moments" in scan:
        moments = np.array(scan["moments"], dtype=np.float64).reshape(-1, 3)
        return moments, [f"body {i}" for i in range(len(moments))]
    if "k1" in scan:
        k1, k3 = np.meshgrid(np.asarray(scan["k1"], dtype=float), np.asarray(scan["k3"], dtype=float), indexing="ij")
        moments = moments_from_k(k1.ravel(), k3.ravel())
        return moments, [f"k1={a:.6g}, k3={b:.6g}" for a, b in zip(k1.ravel(), k3.ravel())]
    return None


def moments_from_k(k1, k3):
    """Principal moments ``(I1, I2, I3)`` (kg m², shape (..., 3)) with ``I2 = 1`` and the gravity-gradient ratios
    ``k1 = (I2 - I3)/I1``, ``k3 = (I2 - I1)/I3``: ``I1 = (1 - k3)/(1 - k1 k3)``, ``I3 = (1 - k1)/(1 - k1 k3)``.
    Every ``(k1, k3)`` of the open square ``(-1, 1)²`` is a body (the triangle inequalities reduce to
    ``(1 - k1)(1 - k3) >= 0``, ``(1 + k1)(1 - k3) >= 0`` and ``(1 - k1)(1 + k3) >= 0``); ValueError outside it."""
    k1, k3 = np.asarray(k1, dtype=float), np.asarray(k3, dtype=float)
    if not (np.all(np.abs(k1) < 1) and np.all(np.abs(k3) < 1)):
        raise ValueError(f"k1 and k3 must lie in (-1, 1), got k1 = {k1}, k3 = {k3}")
    d = 1.0 - k1 * k3
    return np.stack(np.broadcast_arrays((1.0 - k3) / d, np.ones_like(d), (1.0 - k1) / d), axis=-1)
