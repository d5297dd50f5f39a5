"""The models and the closed form on the CUDA device give the CPU's answers (issue 28).

On numba-cuda's simulator (tests/conftest.py sets ``NUMBA_ENABLE_CUDASIM=1``): the kernel body runs in Python, one
thread at a time, and the ``@jit`` functions it calls (the CPU's own per-sample steps and closed form) as compiled
CPU code, so sizes are tiny (ten samples, thirty steps). There the models' results equal the CPU driver's to the
last bits or nearly (the CPU's block loops are vectorised, a thread's loop is one sample: a multiply-add may fuse
differently).
"""

import importlib.util
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import tumble
from tumble.engine.model_ensemble import run_model_ensemble
from tumble.engine.sampling import perturbed_states
from tumble.physics import models

# the device's tests on the simulator share its loops, compiled as CPU code, and the closed form: one worker compiles them
pytestmark = pytest.mark.xdist_group("cuda")

RELATIVE = 1e-12  # device against CPU, relative to the largest value compared


def _agree(device, cpu, relative=RELATIVE):
    assert device.shape == cpu.shape
    np.testing.assert_array_equal(np.isnan(device), np.isnan(cpu))
    finite = ~np.isnan(cpu)
    assert np.all(np.isfinite(cpu[finite]))
    assert np.max(np.abs(device[finite] - cpu[finite]), initial=0.0) <= relative * np.max(np.abs(cpu[finite]))


# (model, spin axis, methods): every model once, every splitting of the models that have them once
MODELS = [
    (models.Gyrostat((1.0, 2.0, 3.0), (0.0, 0.2, 0.0)), 2, ("rk8", "splitting2")),
    (models.HeavyTop((2.0, 2.5, 3.0), 0.5), 3, ("rk4", "symplectic_euler", "splitting4")),
    (models.GravityGradient((1.0, 2.0, 3.0), 0.1), 2, ("rk4",)),
    (models.Damper((1.0, 2.0, 3.0), 0.2, 0.05), 3, ("rk8",)),
    (models.FreeBody((1.0, 2.0, 3.0)), 2, ("rk4",)),
]
CASES = [(model, axis, method) for model, axis, methods in MODELS for method in methods]


@pytest.mark.default_cases("heavy_top-splitting4")
@pytest.mark.parametrize("model, axis, method", CASES, ids=[f"{m.kind}-{method}" for m, _, method in CASES])
def test_every_model_on_the_device_gives_the_cpu_run_and_observers(cuda_device, model, axis, method):
    y0 = perturbed_states(model, axis, 1.0, 1e-2, 10, seed=28)
    kwargs = dict(method=method, axis=axis, spin=1.0, save_every=7, probe_times=[0.0, 0.05, 0.3], drift=True)
    cpu = run_model_ensemble(model, y0, 0.3, 0.01, **kwargs)
    device = run_model_ensemble(model, y0, 0.3, 0.01, device="cuda", **kwargs)
    assert (cpu.info["device"], device.info["device"]) == ("cpu", "cuda")
    assert cpu.trajectory.shape == (10, 6, model.state_size)
    for name in ("final", "trajectory", "probes"):
        _agree(getattr(device, name), getattr(cpu, name))
    np.testing.assert_allclose(device.drift, cpu.drift, rtol=1e-9, atol=1e-14)  # relative drifts of a few eps
    assert (device.status == 0).all() and (device.steps_taken == 30).all()


def test_stopped_model_samples_keep_their_state_status_and_steps_as_on_the_cpu(cuda_device):
    """A sample with a non-finite component does not run, one whose invariants drift past ``drift_limit`` stops
    where the CPU driver stops it: the same statuses, steps taken, frozen trajectory and NaN probes after it."""
    model = models.HeavyTop((2.0, 2.5, 3.0), 0.5)
    y0 = perturbed_states(model, 3, 1.0, 1e-2, 6, seed=3)
    y0[1, 0] = np.nan
    y0[2, :3] *= 40.0  # a fast spin: rk4's drift at this step passes the limit within a few steps
    kwargs = dict(method="rk4", axis=3, spin=1.0, save_every=5, probe_times=[0.0, 0.1, 0.3], drift_limit=1e-9)
    cpu = run_model_ensemble(model, y0, 0.3, 0.01, **kwargs)
    device = run_model_ensemble(model, y0, 0.3, 0.01, device="cuda", **kwargs)
    assert set(cpu.status.tolist()) >= {0, 1, 2} and 0 < cpu.steps_taken[2] < 30 and cpu.steps_taken[1] == 0
    np.testing.assert_array_equal(device.status, cpu.status)
    np.testing.assert_array_equal(device.steps_taken, cpu.steps_taken)
    for name in ("final", "trajectory", "probes"):
        _agree(getattr(device, name), getattr(cpu, name))


def test_a_model_method_the_kernels_do_not_run_is_refused_on_the_device_too(cuda_device):
    with pytest.raises(ValueError, match=r"^method must be one of rk4, rk8 for a damper model"):
        run_model_ensemble(models.Damper((1.0, 2.0, 3.0), 0.2, 0.05), np.ones((2, 6)), 0.1, 0.01,
                           method="splitting2", axis=3, device="cuda")
    with pytest.raises(ValueError, match=r"^device must be one of 'cpu', 'cuda'; got 'gpu'"):
        run_model_ensemble(models.FreeBody((1.0, 2.0, 3.0)), np.ones((2, 3)), 0.1, 0.01, axis=3, device="gpu")


# --- the closed form -------------------------------------------------------------------------------------------------

CLOSED_FORM_RELATIVE = 1e-13  # device against CPU, relative to the largest |w|: a few ulps of |w|


@pytest.fixture(scope="module")
def closed_form_spins():
    """Random spins of both regimes, a steady spin, a spin 1e-9 from the intermediate axis, and a spin exactly on the
    separatrix of moments (3, 4, 6) (``I1 (I2 - I1) w1² = I3 (I3 - I2) w3²`` with ``w1 = 2 w3``)."""
    spins = np.random.default_rng(28).normal(size=(12, 3))
    spins[0] = (0.0, 0.0, 1.5)
    spins[1] = (1e-9, 1.0, -1e-9)
    spins[2] = (2.0, 0.5, 1.0)
    return spins


@pytest.mark.parametrize("body", [(3.0, 4.0, 6.0), (4.0, 6.0, 3.0),
                                  # the symmetric body's own set-up kernels on the simulator: 15 s on an empty cache
                                  pytest.param((2.0, 2.0, 3.0), marks=pytest.mark.slow)],
                         ids=["sorted", "unsorted", "symmetric"])
def test_the_closed_form_on_the_device_gives_the_cpu_values_at_one_time_and_on_a_grid(cuda_device, closed_form_spins,
                                                                                      body):
    times = np.array([-0.7, 0.0, 0.3, 2.5, 11.0])
    for save_every in (None, 3):  # one time (the fused one-time path), then a grid of stored times
        cpu = tumble.propagate(body, closed_form_spins, 1.1, 0.1, method="exact", save_every=save_every)
        device = tumble.propagate(body, closed_form_spins, 1.1, 0.1, method="exact", save_every=save_every,
                                  device="cuda")
        _agree(device, cpu, CLOSED_FORM_RELATIVE)
    from tumble.physics import exact

    on_device = exact.omega_on_device(np.array(body), closed_form_spins, times)
    _agree(on_device, exact.omega(body, closed_form_spins, times), CLOSED_FORM_RELATIVE)
    near_an_axis = np.vstack([closed_form_spins[:3], [1e-160, 1.0, 1e-160]])  # invariants underflow: lifted as on
    _agree(exact.omega_on_device(np.array(body), near_an_axis, times),  # the CPU (omega_apart)
           exact.omega(body, near_an_axis, times), CLOSED_FORM_RELATIVE)


def test_run_ensemble_auto_on_the_device_runs_the_closed_form_with_its_observers(cuda_device, closed_form_spins):
    kwargs = dict(method="auto", axis=2, save_every=4, probe_times=[0.0, 0.4, 1.0], drift=True, progress=False)
    cpu = tumble.run_ensemble((3.0, 4.0, 6.0), closed_form_spins, 1.0, 0.1, **kwargs)
    device = tumble.run_ensemble((3.0, 4.0, 6.0), closed_form_spins, 1.0, 0.1, device="cuda", **kwargs)
    assert (device.info["path"], device.info["device"]) == ("closed form", "cuda")
    for name in ("final", "trajectory", "probes"):
        _agree(getattr(device, name), getattr(cpu, name), CLOSED_FORM_RELATIVE)
    np.testing.assert_allclose(device.drift, cpu.drift, atol=1e-14)
    np.testing.assert_array_equal(device.status, cpu.status)
    dataset = tumble.integrate((3.0, 4.0, 6.0), closed_form_spins, 1.0, 0.1, method="exact", device="cuda")
    assert dataset.attrs["device"] == "cuda"
    _agree(dataset.omega.values[:, -1], cpu.final, CLOSED_FORM_RELATIVE)


def test_the_closed_form_flips_on_the_device_are_the_cpus(cuda_device, closed_form_spins):
    """The flips are analytic in the set-up (the first flip time and the spacing), timed on the host from the same
    set-up on either device: the same bits; the state at the end evaluated on the device."""
    kwargs = dict(method="exact", axis=1, max_flips=3, progress=False)
    spins = np.vstack([closed_form_spins, [[1.0, 0.05, 0.02], [1.0, -0.01, 0.03]]])  # about the intermediate axis
    cpu = tumble.run_ensemble((4.0, 3.0, 6.0), spins, 30.0, 0.1, **kwargs)
    device = tumble.run_ensemble((4.0, 3.0, 6.0), spins, 30.0, 0.1, device="cuda", **kwargs)
    assert cpu.flip_count.max() > 3 and (cpu.flip_count == 0).any()
    np.testing.assert_array_equal(device.flips, cpu.flips)
    np.testing.assert_array_equal(device.flip_count, cpu.flip_count)
    _agree(device.final, cpu.final, CLOSED_FORM_RELATIVE)


@pytest.mark.parametrize("body", [(3.0, 4.0, 6.0), (4.0, 6.0, 3.0),
                                  # the symmetric body's own set-up kernels on the simulator: 15 s on an empty cache
                                  pytest.param((2.0, 2.0, 3.0), marks=pytest.mark.slow)],
                         ids=["sorted", "unsorted", "symmetric"])
def test_the_closed_form_attitude_on_the_device_gives_the_cpu_quaternions(cuda_device, closed_form_spins, body):
    """A thread sets up its sample, evaluates its angular velocity at t = 0 and at each time, and runs the CPU's
    per-sample attitude code (kernels/closed_form/elliptic_attitude.py): both regimes, a steady spin, a spin 1e-9 from the
    intermediate axis, the separatrix; a launch with a spin within 1e-151 of an axis goes to the CPU (lifted)."""
    cpu = tumble.integrate(body, closed_form_spins, 1.1, 0.1, method="exact", save_every=3, attitude=True)
    device = tumble.integrate(body, closed_form_spins, 1.1, 0.1, method="exact", save_every=3, attitude=True,
                              device="cuda")
    assert device.attrs["device"] == "cuda" and device.quaternion.shape == (12, 5, 4)
    _agree(device.quaternion.values, cpu.quaternion.values, CLOSED_FORM_RELATIVE)
    _agree(device.omega.values, cpu.omega.values, CLOSED_FORM_RELATIVE)
    from tumble.physics import exact

    times = np.array([-0.7, 0.0, 0.3, 2.5, 11.0])
    near_an_axis = np.vstack([closed_form_spins[:3], [1e-160, 1.0, 1e-160]])
    for spins in (closed_form_spins, near_an_axis):
        _agree(exact.attitude_on_device(np.array(body), spins, times), exact.attitude(body, spins, times),
               CLOSED_FORM_RELATIVE)


# --- the attitude ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method, torque", [("rk4", None), ("splitting2", None), ("implicit_midpoint", None),
                                            ("rk8", (0.05, -0.1, 0.2)), ("splitting4", {"profile": "sine", "vector":
                                                                         (0.2, 0.0, -0.1), "period": 0.15})],
                         ids=["rk4", "splitting2", "implicit_midpoint", "rk8-constant_torque", "splitting4-sine"])
def test_the_attitude_on_the_device_gives_the_cpu_quaternions(cuda_device, method, torque):
    spins = np.array([0.0, 1.0, 0.0]) + 0.3 * np.random.default_rng(28).normal(size=(8, 3))
    kwargs = dict(method=method, torque=torque if torque is not None else (0, 0, 0), save_every=7, attitude=True)
    cpu = tumble.integrate((2.0, 1.0, 3.0), spins, 0.3, 0.01, **kwargs)  # unsorted: a splitting relabels its axes
    device = tumble.integrate((2.0, 1.0, 3.0), spins, 0.3, 0.01, device="cuda", **kwargs)
    assert device.attrs["device"] == "cuda" and device.quaternion.shape == (8, 6, 4)
    _agree(device.omega.values, cpu.omega.values)
    _agree(device.quaternion.values, cpu.quaternion.values)
    np.testing.assert_array_equal(device.status.values, cpu.status.values)


# --- the same kernels compile for a real GPU (NVVM, no GPU needed) -------------------------------------------------

_PTX = textwrap.dedent("""
    import types
    import numpy as np
    import numba.cuda.dispatcher as dispatcher
    from numba import cuda, types as nt
    from tumble.kernels import METHODS, device_closed_form, device_kernels, device_models
    from tumble.kernels.loops.model_loop import MODEL_CODES, MODEL_METHODS
    from tumble.registry import model_kind

    # Device functions are compiled for the current GPU's compute capability; without a GPU, name one (H100).
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))
    f8, i8 = nt.float64, nt.int64
    kernels = []
    for kind, method in (("gyrostat", "splitting2"), ("heavy_top", "rk4"), ("gravity_gradient", "rk8"),
                         ("damper", "rk4")):
        kernels.append((device_models().make_kernel(MODEL_CODES[kind], MODEL_METHODS[method],
                                                    len(model_kind(kind).state)),
                        (f8[:, ::1], nt.UniTuple(f8, 26), f8, i8, i8, f8[:, :, ::1], i8[::1], f8[::1], f8[::1],
                         i8[::1], f8[:, ::1], f8[:, ::1], f8, nt.int8[::1], i8[::1])))
    for torque_free in (True, False):  # the free body's implicit midpoint rule (kernels/cuda/rigid_body.py)
        a2 = f8[:, ::1]  # the arguments of kernels/cuda/rigid_body.py's kernel, its observers included (as in test_cuda.py)
        kernels.append((device_kernels().make_kernel(METHODS["implicit_midpoint"], torque_free),
                        (a2, i8[::1], a2, f8, f8[::1], i8[::1], i8[::1], f8[:, :, ::1], i8[::1], i8[:, ::1], a2,
                         f8[::1], i8[:, ::1], a2, a2, i8[::1], a2, nt.int8[::1], i8[::1], f8[::1], i8, f8, i8, a2,
                         f8[::1], i8, f8[::1], a2, i8[::1])))
    from tumble.kernels import device_attitude
    from tumble.kernels.loops.methods import attitude_frame

    for name, torque_free in (("rk4", True), ("splitting2", False), ("implicit_midpoint", True)):  # the attitude
        frame = attitude_frame(METHODS[name], np.ones((1, 3)), np.array([1.0, 2.0, 3.0]),
                               None if torque_free else np.zeros(4), None, 1, 1)
        kernels.append((device_attitude().make_kernel(frame, torque_free),
                        (i8, f8[:, ::1], f8[::1], f8[::1], i8[::1], f8[::1], i8[::1], f8, f8[:, ::1], f8[:, ::1],
                         nt.UniTuple(f8, 12), f8, f8, i8, i8, f8[:, :, ::1], f8[:, :, ::1], nt.int8[::1], i8,
                         f8[::1])))
    exact = device_closed_form()
    kernels.append((exact._omega_at_kernel, (f8, f8, f8, f8[:, ::1], f8, f8[:, ::1], nt.int8[::1])))
    kernels.append((exact._omega_grid_kernel, (f8[:, ::1], f8[:, ::1], f8[:, ::1], nt.int64[::1], f8[:, ::1],
                                               nt.int8[::1])))
    kernels.append((exact._attitude_grid_kernel, (f8[:, ::1], f8[:, ::1], f8[:, ::1], nt.int64[::1], f8[:, :, ::1],
                                                  nt.int8[::1])))
    from tumble.kernels import device_fits

    for time_major in (False, True):  # the phase fit, over the closed form's and a stepping kernel's layouts
        kernels.append((device_fits().make_kernel(65, time_major),
                        (f8[:, ::1], nt.int64[::1], f8[:, :, ::1], nt.int64[:, ::1], f8[:, ::1], f8[::1], f8[::1],
                         f8, f8[::1], f8[::1], nt.int8[::1])))
    for kernel, signature in kernels:
        ptx, _ = cuda.compile_ptx(kernel.py_func, signature, cc=(9, 0))
        assert "div.approx" not in ptx and "fma.rn.f64" in ptx
        print(ptx.count("\\n"))
""")


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("nvidia") is None, reason="no NVVM wheel (pip install nvidia-nvvm "
                    "nvidia-cuda-nvrtc, or the gpu extra)")
def test_the_model_closed_form_midpoint_and_attitude_kernels_compile_to_ptx_for_a_gpu():
    """numba-cuda compiles the models' kernels (the CPU's _step, invariants and splittings inside), the closed
    form's (the CPU's set-up and elliptic cores, its attitude code), the phase fit's (the CPU's per-sample fit), the
    free body's implicit midpoint rule and the attitude's kernels (the CPU's attitude steps, the coefficients as
    constants) to PTX for sm_90 with IEEE division and fused multiply-adds (about
    90 s on 2 cores; a private hook stands in for the GPU's compute capability)."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0")
    result = subprocess.run([sys.executable, "-c", _PTX], capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    assert len(result.stdout.splitlines()) == 14
