"""tumble: Monte Carlo stability studies of rigid-body rotation.

Which spins of a rigid body are stable, and how fast do perturbations grow (intermediate axis) or
oscillate (largest and smallest axes)? tumble integrates Euler's equations for large ensembles of perturbed
spins with numba kernels and compares them with linear theory and the exact Jacobi-elliptic solution.

This module is the public face: it re-exports what users call. The implementation lives in layers, bottom
to top (imports point down only; see ``docs/architecture.md``): ``kernels`` (numba), ``physics`` (bodies,
shapes, theory, the closed form), ``engine`` (ensemble runs, sampling, ``integrate``), ``measure``
(estimators, scenes, scans, work precision), ``output`` (datasets, netCDF, figures) and ``pipeline``
(study files, runs, checkpoints, dask), with ``cli`` on top.

Note that ``tumble.measure`` is the function :func:`tumble.measure.scenes.measure`; the ``tumble/measure/``
package's modules are reached with ``from tumble.measure import scenes`` (or ``import tumble.measure.scenes``
followed by ``sys.modules``), never by attribute access through the face.
"""

import sys

# First: Ctrl-C while the tumble command imports the rest is one line and exit 130 (see tumble._interrupt).
from . import _interrupt  # noqa: F401
from ._version import __version__
from .engine import sampling
from .engine.ensemble import run_ensemble
from .engine.integration import integrate, propagate
from .measure.scenes import attitude_trace, flip_time_law, inertia_triangle, measure, regress_scan, scan
from .output import io
from .physics import exact, models, rotations, shapes, theory
from .physics.bodies import Body
from .pipeline.runner import run_study

# The physics modules of the public contract keep their short import paths (`import tumble.exact`,
# `from tumble.theory import linear`), as they had before the layers became folders; `tumble.models` (the systems
# beyond the free body, `tumble.models.Gyrostat`) is physics/models.py under the same kind of short path.
for _name, _module in (("exact", exact), ("theory", theory), ("models", models), ("shapes", shapes),
                       ("rotations", rotations), ("io", io), ("sampling", sampling)):
    sys.modules[f"{__name__}.{_name}"] = _module
del _name, _module

__all__ = ["Body", "attitude_trace", "exact", "flip_time_law", "inertia_triangle", "integrate", "io", "measure",
           "models", "propagate", "regress_scan", "rotations", "run_ensemble", "run_study", "sampling", "scan", "shapes", "theory",
           "__version__"]
