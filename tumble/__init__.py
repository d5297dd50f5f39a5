"""tumble: Monte Carlo stability studies of rigid-body rotation.

Which spins of a rigid body are stable, and how fast do perturbations grow (intermediate axis) or
oscillate (largest and smallest axes)? tumble integrates Euler's equations for large ensembles of perturbed
spins with numba kernels and compares them with linear theory and the exact Jacobi-elliptic solution.

This module is the public face: it re-exports what users call. The implementation lives in layers, bottom
to top (imports point down only; see ``docs/architecture.md``): ``kernels`` (numba), ``physics`` (bodies,
shapes, theory, the closed form), ``engine`` (ensemble runs, sampling, ``integrate``), ``measure``
(estimators, scenes, scans, work precision), ``output`` (datasets, netCDF, figures) and ``pipeline``
(study files, runs, checkpoints, dask), with ``cli`` on top.

The face imports lazily (PEP 562): ``import tumble`` loads none of numba, xarray, matplotlib, netCDF4 or dask;
each name is imported on its first use (``tumble.integrate`` loads the engine, ``tumble.run_study`` the
pipeline), so that the command line answers at once and a script pays only for what it calls
(``tests/test_latency.py`` holds it).

Note that ``tumble.measure`` is the function :func:`tumble.measure.scene.measure`; the ``tumble/measure/``
package's modules are reached with ``from tumble.measure import scans`` (or ``import tumble.measure.scans``
followed by ``sys.modules``), never by attribute access through the face.
"""

# First: Ctrl-C while the tumble command imports the rest is one line and exit 130 (see tumble._interrupt).
from . import _interrupt  # noqa: F401
from ._version import __version__

#: Public name -> (module, attribute); attribute None: the name is the module itself.
_FACE = {
    "Body": ("tumble.physics.bodies", "Body"),
    "System": ("tumble.physics.system", "System"),
    "run_ensemble": ("tumble.engine.ensemble", "run_ensemble"),
    "integrate": ("tumble.engine.integration", "integrate"),
    "propagate": ("tumble.engine.integration", "propagate"),
    "section": ("tumble.engine.sections", "section"),
    "lyapunov": ("tumble.engine.chaos", "lyapunov"),
    "megno": ("tumble.engine.chaos", "megno"),
    "gali": ("tumble.engine.chaos", "gali"),
    "run_study": ("tumble.pipeline.runner", "run_study"),
    "check": ("tumble.measure.check", "check"),
    "measure": ("tumble.measure.scene", "measure"),
    "scan": ("tumble.measure.scans", "scan"),
    "inertia_triangle": ("tumble.measure.scans", "inertia_triangle"),
    "regress_scan": ("tumble.measure.regression", "regress_scan"),
    "flip_time_law": ("tumble.measure.regression", "flip_time_law"),
    "attitude_trace": ("tumble.measure.traces", "attitude_trace"),
}

# The physics modules of the public contract keep their short import paths (`import tumble.exact`,
# `from tumble.theory import linear`): each short path is a module of four lines here (tumble/exact.py, ...) that puts
# the layer's module in its place, so that both names are one module object; `tumble.models` (the systems beyond the
# free body, `tumble.models.Gyrostat`) is the package physics/models/ under the same kind of short path.
_ALIASES = {"exact": "tumble.physics.exact", "theory": "tumble.physics.theory", "models": "tumble.physics.models",
            "shapes": "tumble.physics.shapes", "rotations": "tumble.physics.rotations", "io": "tumble.output.io",
            "sampling": "tumble.engine.sampling"}
_FACE.update({name: (module, None) for name, module in _ALIASES.items()})

# The package tumble.measure is imported now so that importing its modules later never rebinds the face's
# `tumble.measure` (the function) to the package: the import system sets a package as its parent's attribute only
# when the package itself is first imported. Its __init__ imports nothing.
from . import measure as _measure_package  # noqa: E402,F401

del measure  # noqa: F821 - bound by the import above; the face's `measure` is the function, from __getattr__


def __getattr__(name):
    try:
        module, attribute = _FACE[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    from importlib import import_module  # here, not at the top: `import tumble` shows only the public names

    value = import_module(module)
    if attribute is not None:
        value = getattr(value, attribute)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__():
    return sorted(set(globals()) | set(_FACE))


__all__ = ["Body", "System", "attitude_trace", "check", "exact", "flip_time_law", "gali", "inertia_triangle", "integrate", "io",
           "lyapunov", "measure", "megno", "models", "propagate", "regress_scan", "rotations", "run_ensemble", "run_study", "sampling", "scan", "section",
           "shapes", "theory", "__version__"]
