"""The device kernels (tumble/kernels/cuda/rigid_body.py) give the CPU kernels' answers, and a device that cannot run says why.

They run on numba-cuda's simulator: tests/conftest.py sets ``NUMBA_ENABLE_CUDASIM=1`` before numba is imported
(numba reads it once). With ``NUMBA_ENABLE_CUDASIM=0`` on a GPU machine the same tests run on the GPU. Sizes are
tiny: the simulator runs the kernel body in Python, one thread at a time (the ``@jit`` steps it calls run as
compiled CPU code, so there the results equal the CPU's bit for bit torque-free; with a torque the CPU's vectorised
block loop may fuse a multiply-add differently, about 1e-16 relative).
"""

import importlib.util
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import tumble
from tumble.engine.device import resolve_device

# the device's tests on the simulator share its loops, compiled as CPU code, and the closed form: one worker compiles them
pytestmark = pytest.mark.xdist_group("cuda")

HAS_NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None
NO_NUMBA_CUDA = 'numba-cuda is not installed (pip install -e ".[test]")'
needs_numba_cuda = pytest.mark.skipif(not HAS_NUMBA_CUDA, reason=NO_NUMBA_CUDA)

BODY = (2.0, 1.0, 3.0)  # unsorted: the splittings relabel their axes (an odd permutation, sign -1)
STEPPED = ("rk4", "rk8", "symplectic_euler", "splitting2", "splitting4", "implicit_midpoint")
RELATIVE = 1e-12  # device against CPU, relative to the largest |w|


@pytest.fixture(scope="module")
def cuda_device():
    """The device is usable (the simulator, or a GPU), else the test is skipped with the reason."""
    if not HAS_NUMBA_CUDA:
        pytest.skip(NO_NUMBA_CUDA)
    try:
        return resolve_device("cuda")
    except ValueError as err:
        pytest.skip(str(err))


@pytest.fixture(scope="module")
def spins():
    rng = np.random.default_rng(28)
    return np.array([0.0, 1.0, 0.0]) + 0.3 * rng.normal(size=(24, 3))


def _agree(device, cpu):
    assert device.shape == cpu.shape
    assert np.all(np.isfinite(cpu))
    assert np.max(np.abs(device - cpu)) <= RELATIVE * np.max(np.abs(cpu))


@pytest.mark.default_cases("rk4-torque_free")
@pytest.mark.parametrize("torque", [None, (0.05, -0.1, 0.2)], ids=["torque_free", "constant_torque"])
@pytest.mark.parametrize("method", STEPPED)
def test_every_method_on_the_device_gives_the_cpu_trajectory(cuda_device, spins, method, torque):
    kwargs = dict(method=method, torque=torque, save_every=7)  # 30 steps: the end is stored as an extra state
    cpu = tumble.propagate(BODY, spins, 0.3, 0.01, **kwargs)
    device = tumble.propagate(BODY, spins, 0.3, 0.01, device="cuda", **kwargs)
    assert cpu.shape == (24, 6, 3)
    _agree(device, cpu)


@pytest.mark.parametrize("profile", [
    {"profile": "ramp", "vector": (0.0, 0.1, 0.3), "duration": 0.2},
    {"profile": "sine", "vector": (0.2, 0.0, -0.1), "period": 0.15},
    {"profile": "pulse", "vector": (0.1, 0.1, 0.1), "duration": 0.105},
], ids=lambda p: p["profile"])
@pytest.mark.slow
@pytest.mark.parametrize("method", ["rk4", "splitting2"])
def test_each_torque_profile_on_the_device_gives_the_cpu_final_state(cuda_device, spins, method, profile):
    cpu = tumble.propagate(BODY, spins[:8], 0.3, 0.01, method=method, torque=profile)
    device = tumble.propagate(BODY, spins[:8], 0.3, 0.01, method=method, torque=profile, device="cuda")
    _agree(device, cpu)


def test_integrate_on_the_device_records_it_and_gives_the_cpu_dataset(cuda_device, spins):
    cpu = tumble.integrate(BODY, spins[:8], 0.2, 0.01, method="splitting4", save_every=5)
    device = tumble.integrate(BODY, spins[:8], 0.2, 0.01, method="splitting4", save_every=5, device="cuda")
    assert (cpu.attrs["device"], device.attrs["device"]) == ("cpu", "cuda")
    np.testing.assert_array_equal(device.time, cpu.time)
    _agree(device.omega.values, cpu.omega.values)
    assert (device.status.values == 0).all()


@pytest.mark.default_cases("drift_limit")
@pytest.mark.parametrize("torque, statuses", [(None, {0, 1, 2}), ((0.0, 0.0, 1e-3), {0, 1})],
                         ids=["drift_limit", "nonfinite"])
def test_stopped_samples_keep_their_state_and_status_as_on_the_cpu(cuda_device, torque, statuses):
    """A sample that drifts past drift_limit (torque-free, checked every step) or blows up (non-finite: found at the
    step it happens while drifts are screened, else every 32 steps) stops where the CPU driver stops it, with the same
    status, steps taken and frozen trajectory."""
    w0 = np.array([[0.1, 1.0, 0.1], [1e150, 1e150, 1e150], [40.0, 30.0, 20.0], [0.1, 0.1, 1.0]])
    kwargs = dict(method="rk4", torque=torque, final=True, save_every=10, progress=False)
    cpu = tumble.run_ensemble(BODY, w0, 0.8, 0.02, **kwargs)
    device = tumble.run_ensemble(BODY, w0, 0.8, 0.02, device="cuda", **kwargs)
    assert set(cpu.status.tolist()) == statuses
    assert cpu.steps_taken.min() < 40  # some sample stopped early
    np.testing.assert_array_equal(device.status, cpu.status)
    np.testing.assert_array_equal(device.steps_taken, cpu.steps_taken)
    np.testing.assert_array_equal(np.isfinite(device.trajectory), np.isfinite(cpu.trajectory))
    finite = np.isfinite(cpu.trajectory)
    _agree(device.trajectory[finite], cpu.trajectory[finite])
    np.testing.assert_array_equal(device.final, device.trajectory[:, -1])
    assert device.info["device"] == "cuda"


# --- observers on the device: the CPU driver's records, sample by sample ------------------------------------------

# About the intermediate axis (moment 2, axis 1) of BODY: the spins flip within the horizon.
FLIPPING = np.array([1.0, 0.0, 0.0])
HORIZON, STEP = 30.0, 0.05


@pytest.fixture(scope="module")
def flipping():
    rng = np.random.default_rng(281)
    return FLIPPING + 0.05 * rng.normal(size=(6, 3))


def _same_records(device, cpu, names):
    """Equal statuses, steps and flip counts; probes, flips and drift within 1e-10 relative (NaN where the CPU's)."""
    for name in ("status", "steps_taken", "flip_count"):
        if name in names:
            np.testing.assert_array_equal(getattr(device, name), getattr(cpu, name), err_msg=name)
    for name in ("probes", "flips", "drift"):
        if name in names:
            d, c = getattr(device, name), getattr(cpu, name)
            np.testing.assert_array_equal(np.isnan(d), np.isnan(c), err_msg=name)
            np.testing.assert_allclose(d, c, rtol=1e-10, atol=1e-15, err_msg=name)


@pytest.mark.default_cases("symplectic_euler-constant_torque")
@pytest.mark.parametrize("torque", [None, (0.02, -0.01, 0.03)], ids=["torque_free", "constant_torque"])
@pytest.mark.parametrize("method", STEPPED)
def test_probes_flips_and_drift_on_the_device_are_the_cpu_records(cuda_device, flipping, method, torque):
    kwargs = dict(method=method, torque=torque, axis=1, probe_times=np.linspace(0.0, HORIZON, 9), max_flips=1,
                  drift=True, norm_weights=(1.0, 0.5, 2.0), progress=False)
    cpu = tumble.run_ensemble(BODY, flipping, HORIZON, STEP, **kwargs)
    device = tumble.run_ensemble(BODY, flipping, HORIZON, STEP, device="cuda", **kwargs)
    # every sample flips, some more often than recorded; symplectic_euler drifts past drift_limit, torque-free
    assert np.all((cpu.flip_count >= 1) | (cpu.status == 2)) and (cpu.flip_count.max() > 1 or cpu.status.all())
    assert np.all(cpu.drift > 0)
    _same_records(device, cpu, ("status", "steps_taken", "flip_count", "probes", "flips", "drift"))
    _agree(device.final, cpu.final)


@pytest.mark.parametrize("stop", [dict(stop_norm=0.2), dict(stop_flips=1), dict(stop_norm=0.2, stop_flips=2)],
                         ids=["norm", "flips", "both"])
@pytest.mark.slow
@pytest.mark.parametrize("method", ["rk4", "splitting4"])
def test_early_stop_on_the_device_stops_each_sample_at_the_cpu_step(cuda_device, flipping, method, stop):
    """A sample stops once its norm reached stop_norm at a probe and it flipped stop_flips times; its later probes
    are NaN, its trajectory is not kept (final=False), as the CPU driver does it."""
    kwargs = dict(method=method, axis=1, final=False, probe_times=np.linspace(0.0, 40.0, 41), max_flips=3,
                  progress=False, **stop)
    cpu = tumble.run_ensemble(BODY, flipping, 40.0, STEP, **kwargs)
    device = tumble.run_ensemble(BODY, flipping, 40.0, STEP, device="cuda", **kwargs)
    assert cpu.info["early_stop"] and 0 < cpu.steps_taken.max() < 40.0 / STEP  # every sample stopped early
    assert len(set(cpu.steps_taken.tolist())) > 1
    _same_records(device, cpu, ("status", "steps_taken", "flip_count", "probes", "flips"))
    assert device.info["sample_steps_skipped"] == cpu.info["sample_steps_skipped"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rk4", "splitting2"])
def test_the_growth_fit_in_the_kernel_is_the_cpu_fit_of_the_probes(cuda_device, flipping, method):
    """growth_window: the device feeds each probe norm to the fit in registers (keep_probes=False: no norm comes back);
    the CPU fits the stored probes. Some windows end at saturation, some at the early stop, some are too short."""
    kwargs = dict(method=method, axis=1, final=False, probe_times=np.linspace(0.0, 12.0, 41), max_flips=1,
                  norm_weights=(1.0, 0.5, 2.0), stop_norm=0.3, stop_flips=1, growth_window=(0.25, 8), progress=False)
    cpu = tumble.run_ensemble(BODY, flipping, 12.0, STEP, **kwargs)
    device = tumble.run_ensemble(BODY, flipping, 12.0, STEP, device="cuda", keep_probes=False, **kwargs)
    assert device.probes is None and cpu.probes is not None
    rate, points, first, last = cpu.growth
    assert (points > 0).any() and (points < 41).any()
    np.testing.assert_array_equal(device.growth[1], points)
    for name, d, c in zip(("rate", "first", "last"), device.growth[::2] + device.growth[3:], (rate, first, last)):
        good = points > 0
        np.testing.assert_allclose(d[good], c[good], rtol=1e-10, err_msg=name)
    assert np.isnan(device.growth[0][points == 0]).all()


@pytest.mark.slow  # the simulator steps each method at two scales, with every observer and both fits (20 s)
@pytest.mark.parametrize("method", ["rk4", "splitting2"])
def test_extreme_spins_on_the_device_are_stepped_rescaled_as_on_the_cpu(cuda_device, flipping, method):
    """Beyond 2^±256 rad/s the device steps ``s w`` with ``dt / s`` as the CPU does (where Euler's products would
    underflow and the spin stand still): at 2^-700 rad/s every state, record and fit is the one at 1 rad/s scaled,
    bit for bit (a power of two), and the CPU's."""
    scale = 2.0 ** -700

    def records(w):
        kwargs = dict(method=method, axis=1, probe_times=np.linspace(0.0, 12.0 / w, 41), max_flips=2, drift=True,
                      growth_window=(0.25 * w, 8), keep_probes=True, progress=False)
        return tumble.run_ensemble(BODY, w * flipping, 12.0 / w, STEP / w, device="cuda", **kwargs)

    def phases(w, device):
        kwargs = dict(method=method, axis=3, save_every=4, phase_window=((0, 1), (1.2, 0.8), 1e-11 * w, np.pi / 2),
                      progress=False)
        w0 = np.array([0.0, 0.0, w]) + 0.05 * w * np.random.default_rng(2813).normal(size=(8, 3))
        return tumble.run_ensemble(BODY, w0, 6.0 / w, 0.05 / w, device=device, **kwargs)

    base, tiny = records(1.0), records(scale)
    assert (tiny.status == 0).all() and (base.flip_count > 0).any() and (base.growth[1] > 0).any()
    for name in ("final", "probes"):
        np.testing.assert_array_equal(getattr(tiny, name) / scale, getattr(base, name), err_msg=name)
    np.testing.assert_array_equal(tiny.flips * scale, base.flips)
    np.testing.assert_array_equal(tiny.drift, base.drift)
    np.testing.assert_array_equal(tiny.growth[0] / scale, base.growth[0])  # 1/s: the rate of s w at t / s
    np.testing.assert_array_equal(tiny.growth[1], base.growth[1])
    np.testing.assert_array_equal(tiny.growth[2] / scale, base.growth[2])
    base, tiny, cpu = phases(1.0, "cuda"), phases(scale, "cuda"), phases(scale, "cpu")
    assert (base.phase[2] == 0).all()
    np.testing.assert_array_equal(tiny.trajectory / scale, base.trajectory)
    np.testing.assert_array_equal(tiny.phase[0] / scale, base.phase[0])
    np.testing.assert_array_equal(tiny.phase[1] / scale, base.phase[1])
    np.testing.assert_array_equal(tiny.phase[2], cpu.phase[2])  # the CPU's radii by hypot there: an ulp apart
    np.testing.assert_allclose(np.array(tiny.phase[:2]), np.array(cpu.phase[:2]), rtol=1e-13)
    turned = [tumble.integrate(BODY, w * flipping[:2], 2.0 / w, STEP / w, method=method, attitude=True,
                               device="cuda") for w in (1.0, scale)]
    np.testing.assert_array_equal(turned[1].omega.values / scale, turned[0].omega.values)
    np.testing.assert_array_equal(turned[1].quaternion.values, turned[0].quaternion.values)


def test_flips_check_every_step_for_a_blow_up_as_on_the_cpu(cuda_device):
    """With flips observed the non-finite check runs every step (not every 32): the same step and status."""
    w0 = np.array([[1.0, 0.05, 0.05], [1e150, 1e150, 1e150]])
    kwargs = dict(method="rk4", torque=(0.0, 0.0, 1e-3), axis=1, max_flips=1, progress=False)
    cpu = tumble.run_ensemble(BODY, w0, 0.8, 0.02, **kwargs)
    device = tumble.run_ensemble(BODY, w0, 0.8, 0.02, device="cuda", **kwargs)
    assert cpu.status.tolist() == [0, 1] and cpu.steps_taken[1] < 32
    _same_records(device, cpu, ("status", "steps_taken", "flip_count"))


# --- the phase fit on the device: the CPU's per-sample fit, run where the states are -------------------------------

def _simulated():
    from numba.core import config

    return bool(config.ENABLE_CUDASIM)


def _same_fit(device, cpu):
    """Equal codes and NaNs; frequencies and radii equal on the simulator (the fit runs as the CPU's compiled code),
    within 1e-13 relative on a GPU (NVVM may fuse a multiply-add the CPU's fit does not)."""
    np.testing.assert_array_equal(device[2], cpu[2])
    for d, c in zip(device[:2], cpu[:2]):
        if _simulated():
            np.testing.assert_array_equal(d, c)
        np.testing.assert_allclose(d, c, rtol=1e-13)


def _phase_fit_states():
    """Stored states (n, T, 3) of oscillations of several frequencies, radii and ellipticities, and four that the fit
    must tell apart: a NaN (no signal), one at round-off level (no signal), one beyond 1e150 (radii by hypot, still
    fitted), one whose phase steps by more than pi/2 between stored times (undersampled)."""
    rng = np.random.default_rng(2811)
    times = np.linspace(0.0, 8.0, 40)
    phase = rng.uniform(0.3, 1.5, (10, 1)) * times + rng.uniform(0.0, 6.0, (10, 1))
    phase[4] = 9.0 * times  # 1.85 rad between stored times
    radius = rng.uniform(0.5, 2.0, (10, 1))
    states = np.stack([radius * np.cos(phase), 1.3 * radius * np.sin(phase), rng.normal(size=(10, 40))], axis=2)
    states[1, 7, 0] = np.nan
    states[2, :, :2] *= 1e-14
    states[3] *= 1e200
    return times, states


@pytest.mark.parametrize("time_major, sign", [(False, 1.0), (True, -1.0)],
                         ids=["closed_form_layout", "stepping_layout"])
def test_the_phase_fit_on_the_device_is_the_cpu_fit_of_the_same_states(cuda_device, time_major, sign):
    """The device's fit (kernels/cuda/phase_fit.py) reads the closed form's (n, T, 3) or a stepping kernel's (T, 3, n)
    states, in a splitting's relabelled frame (every component times -1), and gives the CPU's fit of them."""
    from tumble.kernels import device_fits, fits

    times, states = _phase_fit_states()
    n = len(states)
    columns = np.array([[0, 1], [1, 0]] * (n // 2), dtype=np.int64)
    weights = np.random.default_rng(28).uniform(0.5, 2.0, (n, 2))
    floor = np.full(n, 1e-11)
    cpu = np.empty(n), np.empty(n), np.empty(n, dtype=np.int8)
    fits.phase_fit(times[None, :], np.zeros(n, dtype=np.int64), states, columns, weights, floor, np.pi / 2, *cpu)
    assert set(cpu[2].tolist()) == {0, 2, 3} and cpu[2][3] == 0
    stored = np.ascontiguousarray(sign * (states.transpose(1, 2, 0) if time_major else states))
    device = device_fits().phase_fit(times[None, :], np.zeros(1, dtype=np.int64), stored, columns, weights, floor,
                                     np.pi / 2, time_major=time_major, sign=sign)
    _same_fit(device, cpu)


def test_a_periodic_closed_form_batch_is_fitted_on_the_device_and_only_its_fits_come_back(cuda_device):
    """Two scenes of one batch (each its body and time grid): the device's fit of its own evaluation equals the host's
    fit of that evaluation copied back; a launch with a spin within 1e-151 of an axis is evaluated and fitted on the
    CPU, as the CPU does it."""
    from tumble.measure import estimators
    from tumble.physics import exact

    bodies = np.array([[1.0, 2.0, 3.0], [1.0, 1.5, 2.2]])
    row = np.repeat([0, 1], 6)
    w0 = np.array([0.0, 0.0, 1.0]) + 0.02 * np.random.default_rng(2812).normal(size=(12, 3))
    times = np.stack([np.linspace(0.0, 20.0, 65), np.linspace(0.0, 15.0, 65)])
    columns = np.tile([0, 1], (12, 1))
    weights = np.stack([estimators.invariant_weights(b, 3)[[0, 1]] for b in bodies])[row]
    on_host = estimators.oscillation_frequencies(times, exact.omega_rows_on_device(bodies, w0, times, row), weights,
                                                 1.0, columns=columns, row=row)
    on_device = estimators.closed_form_frequencies_on_device(bodies, w0, times, weights, 1.0, columns=columns, row=row)
    assert (on_host.code == 0).all()
    _same_fit(on_device, on_host)
    w0[5] = (1e-160, -1e-160, 1.0)  # tiny: the invariants underflow, the CPU's lifted set-up takes the launch
    cpu = estimators.oscillation_frequencies(times, exact.omega_rows(exact.solve_rows(bodies[row], w0), times, row),
                                             weights, 1.0, columns=columns, row=row)
    on_device = estimators.closed_form_frequencies_on_device(bodies, w0, times, weights, 1.0, columns=columns, row=row)
    for d, c in zip(on_device, cpu):
        np.testing.assert_array_equal(d, c)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["rk4", "splitting2"])
def test_the_phase_fit_of_a_run_on_the_device_is_the_cpu_fit(cuda_device, method):
    """phase_window: the device fits the trajectory where its kernel stored it (keep_trajectory=False: it never comes
    back); the CPU fits it after the run. BODY is unsorted: a splitting's frame is relabelled, its sign -1. Then the
    same with the closed form."""
    w0 = np.array([0.0, 0.0, 1.0]) + 0.05 * np.random.default_rng(2813).normal(size=(8, 3))
    kwargs = dict(method=method, axis=3, save_every=4, phase_window=((0, 1), (1.2, 0.8), 1e-11, np.pi / 2),
                  progress=False)
    cpu = tumble.run_ensemble(BODY, w0, 6.0, 0.05, **kwargs)
    device = tumble.run_ensemble(BODY, w0, 6.0, 0.05, device="cuda", keep_trajectory=False, **kwargs)
    assert device.trajectory is None and cpu.trajectory is not None and (cpu.phase[2] == 0).all()
    _same_fit(device.phase, cpu.phase)
    kwargs.update(method="exact")  # the closed form, evaluated and fitted on the device (phase_fit_rows_on_device)
    cpu = tumble.run_ensemble(BODY, w0, 6.0, 0.05, **kwargs)
    device = tumble.run_ensemble(BODY, w0, 6.0, 0.05, device="cuda", keep_trajectory=False, **kwargs)
    assert device.trajectory is None
    np.testing.assert_array_equal(device.phase[2], cpu.phase[2])
    np.testing.assert_allclose(device.phase[0], cpu.phase[0], rtol=1e-13)  # a few ulps of |w| apart (omega_on_device)


def test_a_phase_window_needs_a_stored_trajectory_and_a_plane():
    with pytest.raises(ValueError, match="phase_window fits the phase of the stored trajectory: it needs save_every"):
        tumble.run_ensemble(BODY, [[0.0, 0.0, 1.0]], 1.0, 0.1, phase_window=((0, 1), (1, 1), 0.0, 1.0))
    with pytest.raises(ValueError, match="plane must be two different columns"):
        tumble.run_ensemble(BODY, [[0.0, 0.0, 1.0]], 1.0, 0.1, save_every=1, phase_window=((1, 1), (1, 1), 0.0, 1.0))


# --- asking for what cannot run is an error, never a silent CPU run ----------------------------------------------

@pytest.mark.parametrize("device", ["gpu", "CUDA", None, 0])
def test_an_unknown_device_is_refused_naming_the_argument_and_the_values(device):
    with pytest.raises(ValueError, match=r"^device must be one of 'cpu', 'cuda'; got "):
        tumble.propagate(BODY, [0.0, 1.0, 0.0], 0.1, 0.01, device=device)


def _one_line(err):
    message = str(err.value)
    assert "\n" not in message
    return message


def test_cuda_without_numba_cuda_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "numba_cuda", None)  # makes `import numba_cuda` fail, as when not installed
    with pytest.raises(ValueError) as err:
        tumble.integrate(BODY, [[0.0, 1.0, 0.0]], 0.1, 0.01, device="cuda")
    assert _one_line(err) == ("device 'cuda': numba-cuda is not installed; install it with "
                              'pip install "tumble[gpu]"')


@needs_numba_cuda
def test_cuda_without_a_gpu_says_what_is_missing(monkeypatch):
    from numba import cuda

    monkeypatch.setattr(cuda, "is_available", lambda: False)
    monkeypatch.setattr(cuda, "cuda_error", lambda: RuntimeError("CUDA driver library cannot be found.\n"))
    with pytest.raises(ValueError) as err:
        tumble.run_ensemble(BODY, [[0.0, 1.0, 0.0]], 0.1, 0.01, method="rk4", device="cuda")
    assert _one_line(err).startswith("device 'cuda': no usable GPU (CUDA driver library cannot be found.)")
    assert 'pip install "tumble[gpu]"' in str(err.value)


@needs_numba_cuda
def test_cuda_with_a_numpy_numba_cuda_cannot_compile_with_says_so(monkeypatch):
    from numba import cuda
    from numba.core import config

    monkeypatch.setattr(cuda, "is_available", lambda: True)
    monkeypatch.setattr(config, "ENABLE_CUDASIM", 0)
    monkeypatch.delattr(np, "row_stack", raising=False)
    with pytest.raises(ValueError) as err:
        resolve_device("cuda")
    assert _one_line(err).startswith("device 'cuda': numba-cuda cannot compile with numpy ")


@pytest.mark.parametrize("kwargs, message", [
    (dict(method="rk4", torque=lambda t, w1, w2, w3: (0.0, 0.0, 0.1)), "a Python torque function cannot run"),
], ids=["torque_function"])
def test_what_the_device_does_not_do_yet_is_refused(cuda_device, kwargs, message):
    with pytest.raises(ValueError) as err:
        tumble.run_ensemble(BODY, [[0.0, 1.0, 0.0]], 0.1, 0.01, device="cuda", progress=False, **kwargs)
    assert _one_line(err).startswith("device 'cuda': ")
    assert message in str(err.value)


def test_propagate_refuses_the_same_on_the_device(cuda_device):
    with pytest.raises(ValueError, match=r"^device 'cuda': "):
        tumble.propagate(BODY, [0.0, 1.0, 0.0], 0.1, 0.01, device="cuda", torque=lambda t, w1, w2, w3: (0.0, 0.0, 0.1))


def test_importing_tumble_does_not_import_numba_cuda():
    code = ("import sys, tumble; "
            "print(sorted(m for m in sys.modules if m == 'numba.cuda' or m.startswith(('numba.cuda.', 'numba_cuda'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


# --- the same kernels compile for a real GPU (NVVM, no GPU needed) -----------------------------------------------

_PTX = textwrap.dedent("""
    import types
    import numba.cuda.dispatcher as dispatcher
    from numba import cuda, types as nt
    from tumble.kernels import METHODS, device_kernels

    # Device functions are compiled for the current GPU's compute capability; without a GPU, name one (H100).
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))
    f8, i8 = nt.float64, nt.int64
    a2 = f8[:, ::1]
    signature = (a2, i8[::1], a2, f8, f8[::1], i8[::1], i8[::1], f8[:, :, ::1], i8[::1], i8[:, ::1], a2, f8[::1],
                 i8[:, ::1], a2, a2, i8[::1], a2, nt.int8[::1], i8[::1], f8[::1], i8, f8, i8, a2, f8[::1], i8, f8[::1],
                 a2, i8[::1])
    # the kernel hands its method's id to the loop as a literal: each kernel holds its own method's step only, the
    # splittings' torque-free or torque form by the constant torque_free
    steps = ("rk4_block", "rk8_block", "implicit_midpoint_block", "splitting4_block", "splitting_torque_block")
    for name, torque_free, step in (("rk4", True, "rk4_block"), ("rk4", False, "rk4_block"),
                                    ("splitting4", True, "splitting4_block"),
                                    ("splitting4", False, "splitting_torque_block")):
        kernel = device_kernels().make_kernel(METHODS[name], torque_free)
        ptx, _ = cuda.compile_ptx(kernel.py_func, signature, cc=(9, 0))
        assert "div.approx" not in ptx and "fma.rn.f64" in ptx, torque_free
        assert [s for s in steps if s in ptx] == [step], (name, torque_free)
        print(name, torque_free, ptx.count("\\n"))
""")


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("nvidia") is None, reason="no NVVM wheel (pip install nvidia-nvvm "
                    "nvidia-cuda-nvrtc, or the gpu extra)")
def test_every_device_kernel_compiles_to_ptx_for_a_gpu():
    """numba-cuda compiles the device kernel, the CPU's time loop and the kernel's method's step (only that one), to
    PTX for sm_90 with IEEE division and fused multiply-adds, torque-free and with a torque (about 60 s; a private hook
    stands in for the GPU's compute capability)."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0")
    result = subprocess.run([sys.executable, "-c", _PTX], capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    assert len(result.stdout.splitlines()) == 4


# --- the device choice beyond the engine: measure, scan, studies, the command line ---------------------------------

@pytest.mark.parametrize("axis, method, kwargs", [
    (2, "auto", dict(flips=2, curves=("norm",))),
    (1, "exact", {}),
    (3, "auto", {}),
], ids=["growth_flips", "periodic_exact", "periodic_auto"])
def test_a_closed_form_scene_on_the_device_measures_the_cpu_rates(cuda_device, axis, method, kwargs):
    """The set-up and the time grid on the device (exact.omega_on_device), the fits and the flips on the host."""
    cpu = tumble.measure((1.0, 2.0, 3.0), axis, samples=8, method=method, **kwargs)
    device = tumble.measure((1.0, 2.0, 3.0), axis, samples=8, method=method, device="cuda", **kwargs)
    assert device.path.item() == "closed form"
    _same_scene(device, cpu)
    for name in ("flip_first", "flip_spacing", "norm_median"):
        if name in cpu:
            np.testing.assert_allclose(device[name].values, cpu[name].values, rtol=1e-10, err_msg=name)


def test_a_closed_form_scan_on_the_device_launches_per_batch_of_scenes_not_per_scene(cuda_device, monkeypatch):
    from tumble.kernels import device_closed_form

    kernels = device_closed_form()
    launches = []
    real = kernels._omega_rows
    monkeypatch.setattr(kernels, "_omega_rows", lambda *args: launches.append(len(args[1])) or real(*args))
    monkeypatch.setattr(kernels, "omega_rows", None)  # a periodic scene's states never come back to the host
    bodies = np.column_stack([np.ones(64), np.linspace(1.6, 2.0, 64), np.full(64, 2.5)])
    cpu = tumble.scan(bodies, axis=1, samples=4)
    device = tumble.scan(bodies, axis=1, samples=4, device="cuda")
    _same_scene(device, cpu)
    assert launches == [2 * 4] * 32  # 64 periodic scenes of 4 samples: the scan's 32 batches, one launch each


@pytest.mark.parametrize("method, axis, torque, launched", [("rk4", (1, 2), None, [3, 3]),
                                                            ("splitting2", (2, 3), None, [3, 3]),
                                                            # a torque spins each body up at its own rate: each
                                                            # stores its own number of states, one launch each
                                                            ("splitting2", (3,), (0.0, 0.0, 0.01), [1, 1, 1])],
                         ids=["rk4", "splitting2", "splitting2-torque"])
@pytest.mark.slow
def test_a_fixed_step_scan_on_the_device_launches_per_batch_of_scenes_with_the_bits_of_one_scene_a_launch(
        cuda_device, monkeypatch, method, axis, torque, launched):
    """Fixed-step scenes of a scan share launches (a row of the scene table each; splitting2 relabels each scene's axes
    by its own moments): the same bits as each scene alone on the device, and the CPU's rates."""
    from tumble.kernels import device_kernels
    from tumble.measure import running, scans
    from tumble.measure.records import assemble_scan

    kernels = device_kernels()
    launches = []
    real = kernels.run_scenes
    monkeypatch.setattr(kernels, "run_scenes", lambda *args, **kw: launches.append(len(args[2])) or real(*args, **kw))
    bodies = [(1.0, 2.0, 3.0), (1.0, 1.5, 2.2), (2.0, 2.5, 3.5)]
    kwargs = dict(axis=axis, method=method, samples=6, flips=1, torque=torque)
    layout = scans.scan_layout(bodies, axis, method=method)
    planner = scans.ScenePlanner(layout, samples=6, flips=1, torque=torque, device="cuda")
    plans = [planner(index) for index in range(layout["scenes"])]
    records = scans.scene_batch(plans)
    assert launches == launched  # scenes a launch: the periodic ones in one, the growing ones in another
    for scene, record in zip(plans, records):
        alone = running.scene_samples(scene, 0, 6)  # one launch of its own (run_ensemble on the device)
        np.testing.assert_array_equal(record["sample_status"], alone["code"])
        np.testing.assert_array_equal(record["sample_rate"], np.where(alone["code"] == 0, alone["rate"], np.nan))
        assert record["sample_steps_computed"] == alone["sample_steps_computed"]
    _same_scene(assemble_scan(layout, records), tumble.scan(bodies, **kwargs))


def test_the_device_counts_the_steps_of_each_warp_as_computed(cuda_device):
    """A warp's threads step together: a sample that stopped early still waits for its warp's slowest one."""
    from tumble.engine import ensemble
    from tumble.engine.sampling import perturbed_spins

    w0 = perturbed_spins((1.0, 2.0, 3.0), 2, samples=40)
    w0[::3] *= 1.0 + np.linspace(0.0, 0.5, 14)[:, None]  # spins of other rates: other stopping steps
    result = tumble.run_ensemble((1.0, 2.0, 3.0), w0, 30.0, 0.05, method="rk4", axis=2, final=False,
                                 probe_times=np.linspace(0.0, 30.0, 31), stop_norm=0.1, device="cuda")
    assert len(set(result.steps_taken)) > 1
    assert result.info["sample_steps_computed"] == ensemble._block_steps(result.steps_taken, 32)
    assert result.info["sample_steps_computed"] < ensemble._block_steps(result.steps_taken)  # not a CPU block's


@pytest.mark.slow
def test_tumble_run_device_cuda_runs_the_default_closed_form_study_as_the_cpu_does(cuda_device, tmp_path):
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")  # the simulator: the device is there
    runs = {}
    for device in ("cpu", "cuda"):
        done = subprocess.run([sys.executable, "-m", "tumble", "run", "--device", device, "--samples", "8", "--out",
                               str(tmp_path / device)], capture_output=True, text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stderr
        runs[device] = tumble.io.read_dataset(tmp_path / device / "intermediate_axis.nc")
    _same_scene(runs["cuda"], runs["cpu"])


@pytest.mark.slow
@pytest.mark.parametrize("name", ["sleeping_top", "gravity_gradient_pitch"])
def test_a_model_study_on_the_device_gives_the_cpu_results(cuda_device, name):
    """A heavy top's growth and precession, a gravity-gradient pitch libration: the model's samples step on the
    device (run_model_ensemble), the modal fits run on the host."""
    overrides = {"perturbation.samples": 8, "outputs.arrays": ["sample_rate", "sample_status"]}
    cpu = tumble.run_study(name, overrides=overrides)
    device = tumble.run_study(name, overrides=overrides, device="cuda")
    _same_scene(device, cpu)


def test_scenes_asking_for_cuda_without_numba_cuda_say_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "numba_cuda", None)
    with pytest.raises(ValueError) as err:
        tumble.measure((1.0, 2.0, 3.0), 2, samples=8, device="cuda")
    assert _one_line(err) == 'device \'cuda\': numba-cuda is not installed; install it with pip install "tumble[gpu]"'


def test_a_study_names_a_bad_device_field():
    from tumble.pipeline.config import StudyError

    with pytest.raises(StudyError, match=r"integration\.device: unknown value 'gpu'.*one of 'cpu', 'cuda'"):
        tumble.run_study({"integration": {"device": "gpu"}})
    with pytest.raises(StudyError, match=r"integration\.device: must be a string"):
        tumble.run_study({"integration": {"device": 1}})


def test_tumble_run_device_cuda_exits_2_with_the_device_line_and_writes_nothing(tmp_path):
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0")  # as on a machine without a GPU (CI): no simulator
    done = subprocess.run([sys.executable, "-m", "tumble", "run", "--device", "cuda", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tumble: error: device 'cuda':"), done.stderr
    assert not (tmp_path / "out").exists()


# --- scenes on the device: measure, scan, studies and the command line ---------------------------------------------

def _same_scene(device, cpu):
    """Kinds and per-sample statuses equal, rates within 1e-10 relative (scene and per sample)."""
    assert device.kind.values.tolist() == cpu.kind.values.tolist()
    np.testing.assert_array_equal(device.sample_status.values, cpu.sample_status.values)
    np.testing.assert_allclose(device.rate.values, cpu.rate.values, rtol=1e-10)
    np.testing.assert_allclose(device.sample_rate.values, cpu.sample_rate.values, rtol=1e-10)
    np.testing.assert_array_equal(device.rate_theory.values, cpu.rate_theory.values)


@pytest.mark.parametrize("axis, method, kwargs", [
    (2, "rk4", dict(curves=("norm",))),
    (2, "splitting4", dict(flips=2)),
    (1, "rk8", {}),
    (3, "auto", dict(torque={"profile": "constant", "vector": (0.0, 0.0, 0.05)}, horizon=20.0)),
], ids=["growth_rk4", "growth_splitting4_flips", "periodic_rk8", "periodic_torque_auto"])
@pytest.mark.default_cases("growth_splitting4_flips")
def test_a_stepping_scene_on_the_device_measures_the_cpu_rates(cuda_device, axis, method, kwargs):
    cpu = tumble.measure((1.0, 2.0, 3.0), axis, samples=12, method=method, **kwargs)
    device = tumble.measure((1.0, 2.0, 3.0), axis, samples=12, method=method, device="cuda", **kwargs)
    _same_scene(device, cpu)
    for name in ("flip_first", "sample_steps_computed", "sample_steps_skipped", "growth_norm", "fit_t_stop",
                 "fit_norm_stop"):
        if name in cpu:
            np.testing.assert_allclose(device[name].values, cpu[name].values, rtol=1e-10, err_msg=name)


@pytest.mark.slow
def test_a_scan_on_the_device_measures_the_cpu_rates(cuda_device):
    kwargs = dict(axis=(1, 2), method="splitting2", samples=8, flips=1)
    cpu = tumble.scan([(1.0, 2.0, 3.0), (1.0, 1.5, 2.2)], **kwargs)
    device = tumble.scan([(1.0, 2.0, 3.0), (1.0, 1.5, 2.2)], device="cuda", **kwargs)
    assert cpu.rate.shape == (2, 2)
    _same_scene(device, cpu)


@pytest.mark.slow
def test_a_bundled_torque_study_on_the_device_gives_the_cpu_results(cuda_device):
    """space_station steps (a torque acts): the whole study, its flip_components trace included, runs on the device."""
    overrides = {"perturbation.samples": 8, "outputs.arrays": ["sample_rate", "sample_status"]}
    cpu = tumble.run_study("space_station", overrides=overrides)
    device = tumble.run_study("space_station", overrides=overrides, device="cuda")
    _same_scene(device, cpu)
    np.testing.assert_allclose(device.trace_omega.values, cpu.trace_omega.values, rtol=1e-10, atol=1e-14)


def test_the_bound_on_sample_steps_is_the_devices_own():
    # 1e13 sample-steps: hours on two CPU cores, half a minute on one GPU
    from tumble.engine import cost

    estimate = cost.run_cost(10**7, 10**6)
    with pytest.raises(ValueError, match="more than the 1e\\+12 a run may take"):
        cost.check(estimate)
    assert cost.check(estimate, "cuda") is estimate
    with pytest.raises(ValueError, match="more than the 1e\\+15 a run may take"):
        cost.check(cost.run_cost(10**9, 10**7), "cuda")
