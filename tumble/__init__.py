"""tumble: Monte Carlo stability studies of rigid-body rotation.

Which spins of a rigid body are stable, and how fast do perturbations grow (intermediate axis) or
oscillate (largest and smallest axes)? tumble integrates Euler's equations for large ensembles of perturbed
spins with numba kernels and compares them with linear theory and the exact Jacobi-elliptic solution.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("tumble")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0+unknown"

from . import analysis, exact, io, rotations, sampling, shapes, study, theory  # noqa: E402  (modules read __version__)
from .bodies import Body  # noqa: E402
from .engine import run_ensemble  # noqa: E402
from .integration import integrate  # noqa: E402
from .study import flip_time_law, inertia_triangle, measure, regress_scan, scan  # noqa: E402
from .runner import run_study  # noqa: E402

__all__ = ["Body", "analysis", "exact", "flip_time_law", "inertia_triangle", "integrate", "io", "measure",
           "regress_scan", "rotations", "run_ensemble", "run_study", "sampling", "scan", "shapes", "study", "theory",
           "__version__"]
