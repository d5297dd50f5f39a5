"""Where an ensemble runs: the CPU (default) or a CUDA device, decided once by :func:`resolve_device`.

``numba.cuda`` is imported only here and only when ``"cuda"`` is asked for, so that ``import tumble`` never pays for
it. Asking for ``"cuda"`` where it cannot run is a ``ValueError`` whose one line starts ``device 'cuda':`` and says
what is missing: there is no silent fallback to the CPU. numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``, set
before numba is imported) counts as a device: it runs the device kernels in Python, which is how the tests check
them without a GPU.
"""

import importlib

import numpy as np

from ..kernels import METHODS, device_kernels, run
from ..registry import DEVICES

__all__ = ["DEVICES", "DeviceError", "INSTALL", "LAUNCH_SAMPLES", "WARP", "check_on_device", "resolve_device",
           "stepper"]


class DeviceError(ValueError):
    """``device 'cuda': ...``: the device cannot run here, or cannot run this yet (the command line's exit 2)."""

#: Fewest samples per launch on the device (where a run has that many): a GPU needs hundreds of thousands of threads
#: to be busy (an H100 holds 132 SMs x 2048 resident threads), far more than a CPU chunk
#: (:data:`tumble.engine.sampling.CHUNK`); a scene's growth probes of this many samples take 0.5 GB.
LAUNCH_SAMPLES = 1 << 18

#: Threads that step together on the device (a warp): each takes as many steps as its slowest sample, which is what
#: a run's ``sample_steps_computed`` counts there.
WARP = 32

#: How to install what the device needs (the ``gpu`` extra of pyproject.toml).
INSTALL = 'pip install "tumble[gpu]"'


def resolve_device(device):
    """``"cpu"`` or ``"cuda"``, checked: a ``device`` argument as every public call takes it.

    Parameters
    ----------
    device : str
        ``"cpu"`` (default everywhere) or ``"cuda"``.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        ``device`` is not one of :data:`DEVICES` (the message names the argument and the values); or ``"cuda"``
        where numba-cuda is not installed or no GPU (nor the simulator) is usable (``device 'cuda': ...``, one line
        with the reason and :data:`INSTALL`).
    """
    if isinstance(device, str) and device in DEVICES:
        if device == "cuda":
            problem = _cuda_problem()
            if problem:
                raise DeviceError(f"device 'cuda': {problem}")
        return device
    raise ValueError(f"device must be one of {', '.join(repr(d) for d in DEVICES)}; got {device!r}")


def _cuda_problem():
    """Why the CUDA device cannot run here, or None."""
    try:
        importlib.import_module("numba_cuda")  # numba's own numba.cuda (deprecated, still shipped) is not enough
    except ImportError:
        return f"numba-cuda is not installed; install it with {INSTALL}"
    from numba import cuda

    if cuda.is_available():  # a driver, a GPU and NVVM; always True on the simulator
        return _numpy_problem()
    error = cuda.cuda_error()
    if error is not None:
        reason = " ".join(str(error).split()).rstrip(":")
        return (f"no usable GPU ({reason}); it needs an NVIDIA GPU with its driver and numba-cuda ({INSTALL}), or "
                "NUMBA_ENABLE_CUDASIM=1 for numba-cuda's simulator")
    return (f"the CUDA compiler (NVVM) is not found; install it with {INSTALL} (or set NUMBA_ENABLE_CUDASIM=1 "
            "to run on numba-cuda's simulator)")


def _numpy_problem():
    """numba-cuda 0.30.4 registers ``numpy.row_stack``, which numpy 2.5 removed, when it first compiles for a GPU;
    the simulator does not compile. Found here rather than as an AttributeError inside the first launch."""
    from numba.core import config

    if config.ENABLE_CUDASIM or hasattr(np, "row_stack"):
        return None
    return (f"numba-cuda cannot compile with numpy {np.__version__} (it calls numpy.row_stack, removed in numpy "
            f"2.5); install the versions that work together with {INSTALL}")


def stepper(device):
    """The fixed-step kernels' run of ``device`` (resolved): :func:`tumble.kernels.run` or its device counterpart,
    which takes the same arguments and returns the same record."""
    return run if device == "cpu" else device_kernels().run


def check_on_device(method, *, torque_fn=None):
    """Raise the ``device 'cuda':`` ``ValueError`` for a run the device cannot do yet, before anything runs.

    Parameters
    ----------
    method : str
        The chosen method (``"auto"`` already resolved). The closed form (``"exact"``) runs on the device with every
        observer, its flips (analytic in the set-up, timed on the host) and its attitude included.
    torque_fn : callable or None
        A user's torque function (:func:`tumble.kernels.cuda.rigid_body.refusal`). Every observer runs on the device.
    """
    if method == "exact":
        return
    problem = device_kernels().refusal(METHODS[method], torque_fn=torque_fn)
    if problem:
        raise DeviceError(problem)
