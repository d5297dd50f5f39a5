"""tumble: Monte Carlo stability studies of rigid-body rotation.

Which spins of a rigid body are stable, and how fast do perturbations grow (intermediate axis) or
oscillate (largest and smallest axes)? tumble integrates Euler's equations for large ensembles of perturbed
spins with numba kernels and compares them with linear theory and the exact Jacobi-elliptic solution.
"""

from importlib.metadata import PackageNotFoundError, version

from . import exact, sampling, shapes, theory
from .bodies import Body
from .engine import run_ensemble
from .integration import integrate

try:
    __version__ = version("tumble")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0+unknown"

__all__ = ["Body", "exact", "integrate", "run_ensemble", "sampling", "shapes", "theory", "__version__"]
