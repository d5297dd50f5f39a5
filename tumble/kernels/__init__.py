"""numba kernels: plain float64 arrays and scalars in, arrays written in place; no xarray, no configuration.

This package's face is the one door to the kernels: the engine (:mod:`tumble.engine`), the closed form
(:mod:`tumble.physics.exact`) and the phase fit's inner loop (:mod:`tumble.measure.estimators`) import from here, never from the modules inside (``tests/test_layers.py``
checks it). Tests and benchmarks of the kernels themselves may reach the modules.
"""

from . import elliptic, fits, sample_loop, side_by_side, system_steps, tangent_blocks, tangent_loop
from .drivers import TORQUE_SIGNATURE
from .jit import parallel_block
from .methods import BLOCK, METHODS, Method, Observed, run, run_attitude
from .model_loop import BLOCK as MODEL_BLOCK
from .model_loop import (MODEL_CODES, MODEL_METHODS, ModelObserved, model_methods, model_rhs, model_tangent,
                         rate_sample, rate_sample_parameters, run_model, run_system_blocks, tangent_sample)
from .tableaux import TABLEAUX
from .steppers import TORQUE_CONSTANT, TORQUE_PULSE, TORQUE_RAMP, TORQUE_SINE, TORQUE_USER

__all__ = ["BLOCK", "METHODS", "MODEL_BLOCK", "MODEL_CODES", "MODEL_METHODS", "TORQUE_CONSTANT", "TORQUE_PULSE",
           "TORQUE_RAMP", "TORQUE_SIGNATURE", "TORQUE_SINE", "TORQUE_USER", "device_attitude", "device_closed_form",
           "device_fits", "device_kernels", "device_models", "device_sample_loop", "elliptic", "fits",
           "Method", "TABLEAUX", "model_methods", "model_rhs", "model_tangent", "ModelObserved", "Observed", "parallel_block",
           "rate_sample", "rate_sample_parameters", "run", "run_attitude", "run_model", "run_system_blocks", "sample_loop",
           "side_by_side", "system_steps",
           "device_tangent_loop", "tangent_blocks", "tangent_loop", "tangent_sample"]


def device_kernels():
    """The CUDA kernels, :mod:`tumble.kernels.cuda` (its ``run`` takes :func:`run`'s arguments). Imported on the
    first call, never by ``import tumble``: importing them imports ``numba.cuda`` (``tumble.engine.device`` checks
    first that numba-cuda and a GPU, or its simulator, are there)."""
    from . import cuda

    return cuda


def device_models():
    """The models' CUDA kernels, :mod:`tumble.kernels.cuda_models` (its ``run_model`` takes :func:`run_model`'s
    arguments), imported on the first call as :func:`device_kernels`."""
    from . import cuda_models

    return cuda_models


def device_closed_form():
    """The closed form's CUDA kernels, :mod:`tumble.kernels.cuda_exact`, imported on the first call as
    :func:`device_kernels`."""
    from . import cuda_exact

    return cuda_exact


def device_fits():
    """The phase fit's CUDA kernels, :mod:`tumble.kernels.cuda_fits` (its ``phase_fit`` takes :func:`fits.phase_fit`'s
    arguments, over states on the device), imported on the first call as :func:`device_kernels`."""
    from . import cuda_fits

    return cuda_fits


def device_attitude():
    """The attitude's CUDA kernels, :mod:`tumble.kernels.cuda_attitude` (its ``run_attitude`` takes
    :func:`run_attitude`'s arguments), imported on the first call as :func:`device_kernels`."""
    from . import cuda_attitude

    return cuda_attitude


def device_sample_loop():
    """The CUDA launcher of a system given by its rate, :mod:`tumble.kernels.cuda_sample_loop` (one thread per
    sample running :func:`sample_loop.make_sample_loop`'s loop), imported on the first call as :func:`device_kernels`."""
    from . import cuda_sample_loop

    return cuda_sample_loop


def device_tangent_loop():
    """The CUDA launcher of the tangent flow, :mod:`tumble.kernels.cuda_tangent_loop` (one thread per sample running
    :func:`tangent_loop.make_tangent_loop`'s loop), imported on the first call as :func:`device_kernels`."""
    from . import cuda_tangent_loop

    return cuda_tangent_loop
