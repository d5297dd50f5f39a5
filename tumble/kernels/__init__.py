"""numba kernels: plain float64 arrays and scalars in, arrays written in place; no xarray, no configuration.

This package's face is the one door to the kernels: the engine (:mod:`tumble.engine`), the closed form
(:mod:`tumble.physics.exact`) and the phase fit's inner loop (:mod:`tumble.measure.estimators`) import from here, never from the modules inside (``tests/test_layers.py``
checks it). Tests and benchmarks of the kernels themselves may reach the modules. The rooms: ``steps/`` (one step of
each method for each system), ``loops/`` (the time loops and their CPU drivers), ``closed_form/`` (the Jacobi-elliptic
solution), ``cuda/`` (the CUDA launchers) and ``systems/`` (the built-in systems' equations); at the top what they
all use (``jit``, ``tableaux``, ``trig``) and the fits' inner loops.
"""

#: The door's names -> (module below this package, attribute; None: the module itself). Imported on first use (PEP
#: 562), so that importing one module inside (``python -m tumble.kernels.steps.model_codegen``, which writes the
#: generated modules the loops import) runs none of the others.
_DOOR = {
    **{name: (name, None) for name in ("fits", "side_by_side")},
    **{name: (f"closed_form.{name}", None) for name in ("elliptic", "elliptic_attitude")},
    **{name: (f"loops.{name}", None) for name in ("adaptive_blocks", "adaptive_loop", "sample_loop",
                                                             "tangent_blocks", "tangent_loop", "variational")},
    "system_steps": ("steps.system_steps", None),
    "parallel_block": ("threads", "parallel_block"),
    "TABLEAUX": ("tableaux", "TABLEAUX"),
    "TORQUE_SIGNATURE": ("loops.drivers", "TORQUE_SIGNATURE"),
    **{name: ("loops.methods", name) for name in ("BLOCK", "METHODS", "Method", "Observed", "run", "run_attitude")},
    "MODEL_BLOCK": ("loops.model_loop", "BLOCK"),
    **{name: ("loops.model_loop", name) for name in (
        "MODEL_CODES", "MODEL_METHODS", "ModelObserved", "model_methods", "model_rhs", "model_tangent", "rate_sample",
        "rate_sample_parameters", "run_model", "run_system_blocks", "tangent_sample")},
    **{name: ("steps.steppers", name) for name in ("TORQUE_CONSTANT", "TORQUE_PULSE", "TORQUE_RAMP", "TORQUE_SINE",
                                                    "TORQUE_USER", "euler_rate")},
    "attitude_rate": ("steps.attitude", "attitude_rate"),
}


def __getattr__(name):
    try:
        module, attribute = _DOOR[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    from importlib import import_module

    value = import_module(f"{__name__}.{module}")
    if attribute is not None:
        value = getattr(value, attribute)
    globals()[name] = value
    return value


__all__ = ["BLOCK", "METHODS", "adaptive_blocks", "adaptive_loop", "MODEL_BLOCK", "MODEL_CODES", "MODEL_METHODS", "TORQUE_CONSTANT", "TORQUE_PULSE",
           "TORQUE_RAMP", "TORQUE_SIGNATURE", "TORQUE_SINE", "TORQUE_USER", "attitude_rate", "device_attitude", "device_closed_form",
           "device_adaptive_loop", "device_fits", "device_kernels", "device_models", "device_sample_loop", "elliptic",
           "elliptic_attitude", "euler_rate", "fits",
           "Method", "TABLEAUX", "model_methods", "model_rhs", "model_tangent", "ModelObserved", "Observed", "parallel_block",
           "rate_sample", "rate_sample_parameters", "run", "run_attitude", "run_model", "run_system_blocks", "sample_loop",
           "side_by_side", "system_steps",
           "device_tangent_loop", "tangent_blocks", "tangent_loop", "tangent_sample", "variational"]


def device_kernels():
    """The CUDA kernels, :mod:`tumble.kernels.cuda.rigid_body` (its ``run`` takes :func:`run`'s arguments). Imported on the
    first call, never by ``import tumble``: importing them imports ``numba.cuda`` (``tumble.engine.device`` checks
    first that numba-cuda and a GPU, or its simulator, are there)."""
    from .cuda import rigid_body

    return rigid_body


def device_models():
    """The models' CUDA kernels, :mod:`tumble.kernels.cuda.models` (its ``run_model`` takes :func:`run_model`'s
    arguments), imported on the first call as :func:`device_kernels`."""
    from .cuda import models

    return models


def device_closed_form():
    """The closed form's CUDA kernels, :mod:`tumble.kernels.cuda.closed_form`, imported on the first call as
    :func:`device_kernels`."""
    from .cuda import closed_form

    return closed_form


def device_fits():
    """The phase fit's CUDA kernels, :mod:`tumble.kernels.cuda.phase_fit` (its ``phase_fit`` takes :func:`fits.phase_fit`'s
    arguments, over states on the device), imported on the first call as :func:`device_kernels`."""
    from .cuda import phase_fit

    return phase_fit


def device_attitude():
    """The attitude's CUDA kernels, :mod:`tumble.kernels.cuda.attitude_steps` (its ``run_attitude`` takes
    :func:`run_attitude`'s arguments), imported on the first call as :func:`device_kernels`."""
    from .cuda import attitude_steps

    return attitude_steps


def device_adaptive_loop():
    """The CUDA launcher of an error-controlled run, :mod:`tumble.kernels.cuda.adaptive` (one thread per sample running
    :func:`adaptive_loop.make_dop853_sample`'s loop), imported on the first call as :func:`device_kernels`."""
    from .cuda import adaptive

    return adaptive


def device_sample_loop():
    """The CUDA launcher of a system given by its rate, :mod:`tumble.kernels.cuda.rate_loop` (one thread per
    sample running :func:`sample_loop.make_sample_loop`'s loop), imported on the first call as :func:`device_kernels`."""
    from .cuda import rate_loop

    return rate_loop


def device_tangent_loop():
    """The CUDA launcher of the tangent flow, :mod:`tumble.kernels.cuda.tangent_flow` (one thread per sample running
    :func:`tangent_loop.make_tangent_loop`'s loop), imported on the first call as :func:`device_kernels`."""
    from .cuda import tangent_flow

    return tangent_flow


def __dir__():
    return sorted(set(globals()) | set(_DOOR))
