"""The built-in systems' per-sample equations for the kernels: constants, rate, tangent flow, invariants (numba).

Each system's equations are written once, in its module of :mod:`tumble.physics.models` (with the model and its
scenes); the module here of the same name is a GENERATED copy of them (``python -m tumble.kernels.steps.model_codegen``;
the kernels sit below physics and do not import it): a ``Constants`` record of named numbers built from the physical
parameters by ``constants(moments, ...)`` (keywords: the model's parameters), the rate ``rate(t, *y, c)``, the
tangent flow ``tangent(t, *y, *v, c)`` (``J(y) v``, the derivative of the rate along ``v``: linear theory and the
chaos indicators' variational equations), the invariants ``invariants(*y, c)`` and, where the state carries a
constraint, a ``project(*y)`` applied after each step. The free body runs as the gyrostat with ``h = 0``.

:data:`SYSTEMS` maps each model kind (``registry.MODEL_KINDS``) to its module; the generated steps and the dispatch of
:mod:`tumble.kernels.steps.model_steps`, the kernels' constants and :data:`N_CONSTANTS` derive from it, so adding a system
is its module in :mod:`tumble.physics.models` and its row in the registry (then ``python -m
tumble.kernels.steps.model_codegen``): the modules here are found by the registry's rows, not a list of imports.
"""

import functools
import inspect
from importlib import import_module

import numpy as np

from ...registry import MODELS

__all__ = ["N_CONSTANTS", "N_INVARIANTS", "SYSTEMS", "constants"]  # and a module per system

#: Model kind -> its module (``registry.Model.equations_module``), in the registry's order.
SYSTEMS = {model.name: import_module(f"{__name__}.{model.equations_module}") for model in MODELS}

#: Length of the constants array every system's driver takes (each reads its own first fields).
N_CONSTANTS = max(len(module.Constants._fields) for module in SYSTEMS.values())

#: Invariants the kernels track per sample (each system's own, then zeros).
N_INVARIANTS = 3


def constants(kind, moments, parameters):
    """The constants of system ``kind`` as the one driver takes them: float64 array (:data:`N_CONSTANTS`,), the
    module's ``Constants`` fields first, zeros after. ``parameters``: the model's keywords (its own, by name; a key
    the system does not have is ignored)."""
    module = SYSTEMS[kind]
    fields = module.constants(moments, **{key: parameters[key] for key in _parameter_names(kind) if key in parameters})
    out = np.zeros(N_CONSTANTS)
    out[:len(fields)] = fields
    return out


@functools.cache
def _parameter_names(kind):
    """The keywords of system ``kind``'s ``constants`` after the moments (read once: ``inspect.signature`` takes
    tens of microseconds, a noticeable part of a small run)."""
    return tuple(inspect.signature(SYSTEMS[kind].constants).parameters)[1:]
