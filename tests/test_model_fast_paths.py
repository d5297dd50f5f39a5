"""The fast paths of model scans (issue 19's DeBra-Delp target) give the bits of the paths they replaced: the drift
screen stops exactly the samples, at exactly the steps, that the exact per-step checks stop -> a time-major trajectory
is the sample-major one transposed -> the modal amplitudes are the bits of the stacked ``matmul`` -> one linearisation
is linear theory's kind, value, eigenvalues and Jacobian -> a scene's blocks spread over the threads.
"""

import numba
import numpy as np
import pytest

from tumble.engine.model_ensemble import run_model_ensemble
from tumble.kernels import MODEL_BLOCK, parallel_block
from tumble.measure import estimators
from tumble.measure.model_scenes import mode
from tumble.physics import theory
from tumble.physics.models import Damper, GravityGradient, HeavyTop
from tumble.registry import STATUS_DRIFT, STATUS_OK

# one worker: the cases share the models' drivers (each compiled once, not by both workers at once)
pytestmark = pytest.mark.xdist_group("model_fast_paths")

MODELS = {
    "gravity_gradient": GravityGradient((2.0, 2.5, 1.0), 1.0),
    "damper": Damper((2.0, 2.5, 1.0), 1.0, 0.5),
    "heavy_top": HeavyTop((1.0, 2.0, 3.0), 0.5),
}


def _states(model, samples, seed=0):
    """States far from any steady spin (O(1) components; unit quaternions and up vectors)."""
    y = np.random.default_rng(seed).normal(size=(samples, model.state_size))
    if model.kind in ("gravity_gradient", "heavy_top"):  # a unit quaternion, a unit up vector
        y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    return y


@pytest.mark.parametrize("kind", list(MODELS))
def test_the_drift_screen_stops_the_same_samples_at_the_same_steps_as_the_exact_checks(kind):
    model = MODELS[kind]
    y0 = _states(model, 300, seed=3)
    y0[:, :3] *= np.geomspace(0.05, 3.0, len(y0))[:, None]  # rates over two decades: drifts over ten
    y0[7, 1] = np.nan  # a non-finite sample is stopped before the first step either way
    run = dict(method="rk4", axis=3, save_every=3, probe_times=[0.0, 2.0, 4.0], drift_limit=1e-5)
    dt = 0.1 if kind == "gravity_gradient" else 0.2
    screened = run_model_ensemble(model, y0, 6.0, dt, **run)  # drifts not recorded: the screen decides
    exact = run_model_ensemble(model, y0, 6.0, dt, drift=True, **run)  # recorded: the exact checks every step
    stopped = screened.status == STATUS_DRIFT
    assert 10 < stopped.sum() < 290 and (screened.status == STATUS_OK).sum() > 10  # a mix, stopped at many steps
    assert len(np.unique(screened.steps_taken[stopped])) > 3
    for name in ("final", "trajectory", "probes", "status", "steps_taken"):
        assert np.array_equal(getattr(screened, name), getattr(exact, name), equal_nan=name != "status"), name


@pytest.mark.parametrize("kind", ["gravity_gradient", "damper"])
@pytest.mark.parametrize("chunk", [4096, 7])
def test_a_time_major_trajectory_is_the_sample_major_one_transposed(kind, chunk):
    model = MODELS[kind]
    y0 = _states(model, 40, seed=1)
    run = dict(method="rk8", axis=3, save_every=4, chunk=chunk, final=False)
    sample_major = run_model_ensemble(model, y0, 1.0, 0.05, **run)
    time_major = run_model_ensemble(model, y0, 1.0, 0.05, time_major=True, **run)
    assert time_major.trajectory.shape == (len(time_major.times), model.state_size, len(y0))
    assert np.array_equal(time_major.trajectory.transpose(2, 0, 1), sample_major.trajectory)
    with pytest.raises(ValueError, match="time_major"):
        run_model_ensemble(model, y0, 1.0, 0.05, axis=3, time_major="yes")


@pytest.mark.parametrize("samples", [256, 37, 3000])
def test_the_modal_amplitudes_are_the_bits_of_the_stacked_matmul(samples):
    model = MODELS["gravity_gradient"]
    scene_mode = mode(model, 2, model.orbit_rate, "periodic")
    y0 = model.equilibrium(2) + 1e-3 * _states(model, samples, seed=2)
    result = run_model_ensemble(model, y0, 3.0, 0.05, axis=2, save_every=1, final=False)
    expected = (result.trajectory[..., scene_mode.columns] - scene_mode.centre) @ scene_mode.left
    time_major = np.ascontiguousarray(result.trajectory.transpose(1, 2, 0))
    z = estimators.modal_amplitudes(time_major, scene_mode.columns, scene_mode.centre, scene_mode.left)
    assert z.shape == expected.shape
    assert np.array_equal(z, expected)


@pytest.mark.parametrize("model, axis, spin", [(MODELS["gravity_gradient"], 2, 1.0), (MODELS["damper"], 1, 0.7),
                                               (MODELS["heavy_top"], 3, 4.0)])
def test_one_linearisation_is_linear_theorys_kind_value_eigenvalues_and_jacobian(model, axis, spin):
    lin = theory.linearisation(model, axis, spin)
    assert (lin.kind, lin.value) == theory.linear(model, axis, spin)
    assert np.array_equal(lin.eigenvalues, theory.eigenvalues(model, axis, spin))
    assert np.array_equal(lin.jacobian, model.tangent_jacobian(model.equilibrium(axis, spin)))
    kind = lin.kind if lin.kind != "neutral" else "periodic"
    assert np.array_equal(mode(model, axis, spin, kind, jacobian=lin.jacobian).left, mode(model, axis, spin, kind).left)
    with pytest.raises(ValueError, match="one axis"):
        theory.linearisation(model, [1, 2], spin)


def test_a_scenes_blocks_are_at_least_as_many_as_the_threads():
    threads = numba.get_num_threads()
    for n in (1, 16, 100, 256, 1000, 5000):
        block = parallel_block(n, MODEL_BLOCK)
        assert block % 8 == 0 and 64 <= block <= max(64, MODEL_BLOCK)
        assert -(-n // block) >= min(threads, -(-n // 64)) or block == MODEL_BLOCK
