"""The models' SIMD ensemble kernels (issue 18, part 2) and the engine's run_model_ensemble.

In layers: the generated steps are what the tables say -> the kernels' right-hand side is the physics layer's ->
observed orders against SciPy's DOP853 -> invariants kept to the method's accuracy and reported by the drift
observer -> growth rates and frequencies against the Jacobian's linear theory -> a wheel stabilises the
intermediate axis -> bit-for-bit reproducibility across threads and chunks -> bad arguments and bad states.

One compiled driver per model and method: each compiles (or loads) once per process.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from model_checks import assert_same_bits_on_any_threads_and_chunks, fitted_rate, model_errors, observed_order
import tumble
from tumble.theory import linear

from tumble import registry
from tumble.engine.model_ensemble import run_model_ensemble
from tumble.engine.sampling import perturbed_spins, perturbed_states
from tumble.kernels.steps import model_codegen
from tumble.kernels import model_rhs, tableaux
from tumble.physics.models import FreeBody, Gyrostat, HeavyTop

# one worker: the cases share the models' drivers (each compiled once, not by both workers at once)
pytestmark = pytest.mark.xdist_group("model_kernels")

MODELS = {
    "free": FreeBody((1.0, 2.0, 3.0)),
    "gyrostat": Gyrostat((1.0, 2.0, 3.0), (0.3, -0.2, 0.5)),
    "heavy_top": HeavyTop((2.0, 2.5, 1.0), 1.5),
}


def _parameters(model):
    return {"rotor": getattr(model, "rotor", (0.0, 0.0, 0.0)), "mgl": getattr(model, "mgl", 0.0)}


@pytest.fixture(scope="module")
def warm():
    """Compile (or load from numba's cache) the one model driver and the kernels' right-hand side."""
    model = MODELS["heavy_top"]
    y0 = model.equilibrium(3, 1.0)[None]
    run_model_ensemble(model, y0, 0.02, 0.01, axis=3, save_every=1, probe_times=[0.0], drift=True)
    model_rhs("heavy_top", y0.T.copy(), model.moments, mgl=model.mgl)
    return True


def _general_state(model):
    """A state far from any steady spin (every component O(1)), shape (1, n)."""
    y0 = np.array([[1.0, 1.5, -1.2, 0.3, -0.4, 0.8]])[:, :model.state_size]
    if model.state_size == 6:
        y0[0, 3:] /= np.linalg.norm(y0[0, 3:])
    return y0


# --- the generated steps -------------------------------------------------------------------------------------------

def test_committed_model_steps_are_what_the_generator_writes():
    committed = Path(model_codegen.TARGET).read_text()
    assert committed == model_codegen.module_source(), "run: python -m tumble.kernels.steps.model_codegen"


def test_the_generators_write_every_generated_module_when_none_of_them_is_there(tmp_path):
    """No bootstrap trap: in a copy of the package without its generated modules (the systems' equations, their steps,
    the free body's fused steps), the two generators run and write them again, each as committed."""
    package = Path(tumble.__file__).parent
    shutil.copytree(package, tmp_path / "tumble", ignore=shutil.ignore_patterns("__pycache__"))
    generated = [path.relative_to(package.parent) for path in package.rglob("*.py")
                 if path.read_text().startswith('"""GENERATED')]
    assert len(generated) == 2 + len(model_codegen.equation_modules())
    for path in generated:
        (tmp_path / path).unlink()
    for generator in ("tumble.kernels.steps.codegen", "tumble.kernels.steps.model_codegen"):
        subprocess.run([sys.executable, "-m", generator], cwd=tmp_path, check=True, capture_output=True,
                       env={**os.environ, "PYTHONPATH": str(tmp_path)})
    for path in generated:
        assert (tmp_path / path).read_text() == (package.parent / path).read_text(), path


@pytest.mark.parametrize("name", model_codegen.equation_modules())
def test_the_kernels_equations_are_a_copy_of_the_systems_modules(name):
    """Each system's equations are written once, in its module of tumble.physics.models; the kernels' module is the
    generator's copy of that section, jitted (and nothing else)."""
    committed = (model_codegen.SYSTEMS_DIR / f"{name}.py").read_text()
    assert committed == model_codegen.system_source(name), "run: python -m tumble.kernels.steps.model_codegen"
    section, functions = model_codegen.equations_section(name)
    assert {"Constants", "constants", "rate", "tangent", "invariants"} <= {*functions, "Constants"}
    assert "\n".join(section) in committed.replace("@jit(inline=True)\n", "")


def test_an_equations_section_with_a_decorated_function_is_refused(tmp_path, monkeypatch):
    (tmp_path / "spinner.py").write_text('__all__ = ["rate"]\n\n\n@staticmethod\ndef rate(t, w, c):\n    return w\n\n\n'
                                         'class Spinner:\n    pass\n')
    monkeypatch.setattr(model_codegen, "PHYSICS_MODELS", tmp_path)
    with pytest.raises(ValueError, match="rate has a decorator"):
        model_codegen.equations_section("spinner")


def test_every_nonzero_coefficient_of_rk4_and_rk8_appears_as_an_exact_literal():
    source = model_codegen.module_source()
    for tableau in (tableaux.RK4, tableaux.RK8):
        for value in [*tableau.A[tableau.A != 0], *tableau.b[tableau.b != 0]]:
            assert f"({float(value)!r} * h)" in source


# --- the right-hand side -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", list(MODELS))
def test_kernel_rhs_is_the_physics_rhs_to_round_off(warm, kind):
    model = MODELS[kind]
    y = np.random.default_rng(7).normal(size=(200, model.state_size)) * 3.0
    expected = model.rhs(y)
    got = model_rhs(kind, np.ascontiguousarray(y.T), model.moments, **_parameters(model)).T
    scale = np.abs(y).max() ** 2
    assert np.abs(got - expected).max() <= 8 * np.finfo(float).eps * scale


def test_heavy_top_sign_convention_an_upright_top_at_rest_falls_at_sqrt_mgl_over_i1(warm):
    """``mgl (g x e3)`` tips the top away from upright: a small tilt g1 > 0 makes w2' = -mgl g1 / I2 (kernel and
    physics agree, and the linear rate of a top at rest is sqrt(mgl / I1))."""
    model = HeavyTop((2.0, 2.0, 1.0), 3.0)
    y = np.array([[0.0, 0.0, 0.0, 1e-3, 0.0, 1.0]])
    got = model_rhs("heavy_top", np.ascontiguousarray(y.T), model.moments, mgl=model.mgl).T
    assert got[0, 1] == pytest.approx(-3.0 * 1e-3 / 2.0, rel=1e-14)
    assert np.array_equal(got, model.rhs(y))
    assert linear(model, 3, 1e-9)[1] == pytest.approx(np.sqrt(3.0 / 2.0), rel=1e-6)


# --- observed order -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method, order, steps", [("rk4", 4, (40, 80, 160)), ("rk8", 8, (24, 32, 40, 48))])
@pytest.mark.parametrize("kind", list(MODELS))
def test_rk4_and_rk8_show_their_order_on_every_model(warm, kind, method, order, steps):
    """The error is the largest over 8 checkpoints (a single end point's error can be near a cancellation), all
    above the reference's round-off (1e-13)."""
    model = MODELS[kind]
    y0 = _general_state(model)
    t_end = 4.0
    errors = model_errors(model, y0, t_end, method, steps)
    observed = observed_order(t_end, steps, errors)
    assert observed == pytest.approx(order, abs=0.2), errors


# --- invariants and the drift observer ------------------------------------------------------------------------------

def _numpy_drift(model, trajectory):
    """Running max over a saved trajectory of each invariant's drift, with the kernels' scales (numpy)."""
    values = np.stack(list(model.invariants(trajectory).values()), axis=-1)  # (N, T, n_invariants)
    y = trajectory[:, 0]
    lw = model.moments * y[:, :3]
    if model.kind == "heavy_top":
        g_norm = np.linalg.norm(y[:, 3:], axis=-1)
        kinetic = 0.5 * np.sum(lw * y[:, :3], axis=-1)
        scales = np.stack([kinetic + model.mgl * g_norm, np.linalg.norm(lw, axis=-1) * g_norm, g_norm ** 2], -1)
    else:
        rotor = np.linalg.norm(_parameters(model)["rotor"])
        scales = np.stack([0.5 * np.sum(lw * y[:, :3], axis=-1), (np.linalg.norm(lw, axis=-1) + rotor) ** 2], -1)
    return np.max(np.abs(values - values[:, :1]) / scales[:, None], axis=1)


@pytest.mark.parametrize("method, tolerance", [("rk4", 1e-6), ("rk8", 1e-11)])
@pytest.mark.parametrize("kind", list(MODELS))
def test_invariants_are_kept_to_the_methods_accuracy_and_the_drift_observer_reports_them(warm, kind, method,
                                                                                         tolerance):
    model = MODELS[kind]
    y0 = np.concatenate([_general_state(model), np.random.default_rng(1).normal(size=(3, model.state_size))])
    result = run_model_ensemble(model, y0, 10.0, 0.02, method=method, axis=3, save_every=1, drift=True)
    assert result.drift.shape == (4, len(model.spec.invariants))
    assert (result.status == registry.STATUS_OK).all()
    assert result.drift.max() < tolerance
    expected = _numpy_drift(model, result.trajectory)
    assert np.allclose(result.drift, expected, rtol=1e-6, atol=64 * np.finfo(float).eps)
    final = np.stack(list(model.invariants(result.final).values()), -1)
    initial = np.stack(list(model.invariants(y0).values()), -1)
    assert np.all(np.abs(final - initial) <= (result.drift + 1e-15) * np.maximum(np.abs(initial), 1.0) * 2)


def test_a_drift_beyond_the_limit_stops_the_sample_with_status_drift(warm):
    model = MODELS["heavy_top"]
    y0 = _general_state(model)
    result = run_model_ensemble(model, y0, 10.0, 0.5, axis=3, drift_limit=1e-6, save_every=1)
    assert result.status[0] == registry.STATUS_DRIFT
    assert result.steps_taken[0] < 20
    stopped = result.trajectory[0, result.steps_taken[0]]
    assert np.array_equal(result.final[0], stopped) and np.array_equal(result.trajectory[0, -1], stopped)


# --- linear theory -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("model, spin", [
    (Gyrostat((1.0, 2.0, 3.0), (0.0, 0.1, 0.0)), 1.0),  # intermediate axis, small rotor: exponential
    (HeavyTop((2.0, 2.0, 1.0), 1.0), 2.0),  # below the sleeping threshold I3 w > 2 sqrt(mgl I1): a waking top
], ids=["gyrostat_intermediate_axis", "waking_heavy_top"])
def test_measured_growth_rate_matches_linear_theory_of_the_jacobian(warm, model, spin):
    axis = 2 if model.kind == "gyrostat" else 3
    kind, rate = linear(model, axis, spin)
    assert kind == "exponential"
    y0 = perturbed_states(model, axis, spin, 1e-9, 64, seed=3)
    t_end = 30.0 / rate
    result = run_model_ensemble(model, y0, t_end, 0.01, method="rk8", axis=axis,
                                probe_times=np.linspace(0.0, t_end, 301), final=False)
    assert (result.status == registry.STATUS_OK).all()
    measured = fitted_rate(result.probe_times, result.probes, 1e-7, 1e-4)
    assert measured == pytest.approx(rate, rel=5e-3)


def test_stable_gyrostat_oscillates_at_the_linear_frequency(warm):
    model = Gyrostat((1.0, 2.0, 3.0), (0.0, 0.0, 0.5))
    kind, frequency = linear(model, 3, 1.0)
    assert kind == "periodic"
    period = 2 * np.pi / frequency
    y0 = perturbed_states(model, 3, 1.0, 1e-4, 8, seed=4)
    result = run_model_ensemble(model, y0, 20 * period, period / 200, axis=3, save_every=1)
    t = result.times
    measured = []
    for x in result.trajectory[:, :, 0]:  # w1, a transverse component: its zero crossings, half a period apart
        i = np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]
        crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
        measured.append(np.pi / np.mean(np.diff(crossings)))
    assert np.mean(measured) == pytest.approx(frequency, rel=5e-3)


def test_a_large_enough_wheel_stabilises_the_intermediate_axis(warm):
    """Linearised about w = W e2 with the rotor along e2, both k_b = I_b ((I2 − I_b) W + h) are positive once
    h > (I3 − I2) W = 1: the norm stays bounded; without the wheel it grows by orders of magnitude."""
    grown = {}
    for h in (0.0, 2.0):
        model = Gyrostat((1.0, 2.0, 3.0), (0.0, h, 0.0))
        y0 = perturbed_states(model, 2, 1.0, 1e-6, 16, seed=5)
        result = run_model_ensemble(model, y0, 40.0, 0.01, axis=2, probe_times=np.linspace(0, 40, 81), final=False)
        grown[h] = result.probes.max() / result.probes[:, 0].max()
    assert linear(Gyrostat((1.0, 2.0, 3.0), (0.0, 2.0, 0.0)), 2, 1.0)[0] == "periodic"
    assert grown[2.0] < 3.0
    assert grown[0.0] > 1e4


# --- reproducibility ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["gyrostat", "heavy_top"])
def test_results_are_bit_identical_on_any_number_of_threads_and_for_any_chunk(warm, kind):
    model = Gyrostat((1.0, 2.0, 3.0), (0.0, 0.0, 0.4)) if kind == "gyrostat" else MODELS[kind]
    y0 = np.random.default_rng(6).normal(size=(600, model.state_size))
    assert_same_bits_on_any_threads_and_chunks(model, y0)


def test_perturbed_states_are_reproducible_by_index_and_tilt_g_independently():
    model = MODELS["heavy_top"]
    states = perturbed_states(model, 3, 2.0, 1e-2, 10, seed=11, up_amplitude=3e-2)
    assert states.shape == (10, 6)
    assert np.array_equal(perturbed_states(model, 3, 2.0, 1e-2, 10, seed=11, up_amplitude=3e-2, start=4, stop=7),
                          states[4:7])
    assert np.array_equal(states[:, :3], perturbed_spins(model.moments, 3, 2.0, 1e-2, 10, seed=11))
    assert np.allclose(np.linalg.norm(states[:, 3:], axis=1), 1.0, rtol=0, atol=1e-15)
    assert np.allclose(np.arccos(states[:, 5]), 3e-2)  # g tilted from e3 by the cone angle
    tilt_w = np.arctan2(states[:, 1], states[:, 0])
    tilt_g = np.arctan2(states[:, 4], states[:, 3])
    assert not np.allclose(tilt_w, tilt_g)  # independent azimuths
    gyro = perturbed_states(Gyrostat((1.0, 2.0, 3.0), (0.0, 1.0, 0.0)), 2, 1.0, 1e-3, 5, seed=2)
    assert np.array_equal(gyro, perturbed_spins((1.0, 2.0, 3.0), 2, 1.0, 1e-3, 5, seed=2))
    with pytest.raises(ValueError, match="axis"):
        perturbed_states(model, 1, 1.0)
    with pytest.raises(ValueError, match="rotor"):
        perturbed_states(Gyrostat((1.0, 2.0, 3.0), (1.0, 0.0, 0.0)), 2, 1.0)
    with pytest.raises(ValueError, match="model"):
        perturbed_states((1.0, 2.0, 3.0), 2)


# --- bad arguments, bad states -------------------------------------------------------------------------------------

@pytest.mark.parametrize("change, name", [
    (dict(model=(1.0, 2.0, 3.0)), "model"),
    (dict(y0=np.zeros((4, 3))), "y0"),
    (dict(y0=np.zeros((0, 6))), "y0"),
    (dict(y0=[["a"] * 6]), "y0"),
    (dict(t_end=-1.0), "t_end"),
    (dict(t_end=np.nan), "t_end"),
    (dict(dt=0.0), "dt"),
    (dict(dt=np.inf), "dt"),
    (dict(method="implicit_midpoint"), "method"),
    (dict(method="auto"), "method"),
    (dict(axis=0), "axis"),
    (dict(axis=1), "axis"),  # a heavy top spins about axis 3
    (dict(axis=True), "axis"),
    (dict(spin=np.nan), "spin"),
    (dict(save_every=-1), "save_every"),
    (dict(save_every=1.5), "save_every"),
    (dict(probe_times=[-1.0]), "probe_times"),
    (dict(probe_times=[[0.0]]), "probe_times"),
    (dict(probe_times=[np.nan]), "probe_times"),
    (dict(drift="yes"), "drift"),
    (dict(drift_limit=-1.0), "drift_limit"),
    (dict(final=None), "final"),
    (dict(chunk=0), "chunk"),
])
def test_bad_arguments_raise_value_errors_naming_them(change, name):
    call = dict(model=MODELS["heavy_top"], y0=np.zeros((2, 6)), t_end=1.0, dt=0.1, axis=3)
    call.update(change)
    model, y0, t_end, dt = (call.pop(k) for k in ("model", "y0", "t_end", "dt"))
    with pytest.raises(ValueError, match=name):
        run_model_ensemble(model, y0, t_end, dt, **call)


def test_a_gyrostat_probed_about_an_axis_across_its_rotor_is_refused():
    with pytest.raises(ValueError, match="rotor"):
        run_model_ensemble(MODELS["gyrostat"], np.ones((1, 3)), 1.0, 0.1, axis=2, probe_times=[0.5])


def test_non_finite_initial_states_and_blow_ups_get_status_non_finite_not_silent_nan(warm):
    model = MODELS["heavy_top"]
    y0 = np.tile(model.equilibrium(3, 1.0), (4, 1))
    y0[1, 4] = np.nan
    y0[2, 0] = np.inf
    result = run_model_ensemble(model, y0, 1.0, 0.1, axis=3, probe_times=[0.0, 1.0], drift=True)
    assert result.status.tolist() == [registry.STATUS_OK, registry.STATUS_NONFINITE, registry.STATUS_NONFINITE,
                                      registry.STATUS_OK]
    assert result.steps_taken.tolist() == [10, 0, 0, 10]
    assert np.isnan(result.probes[1:3]).all() and np.isfinite(result.probes[[0, 3]]).all()
    assert np.isfinite(result.final[[0, 3]]).all()
    # a step far too large for the spin: the state overflows, the sample is caught and frozen
    fast = np.array([[1e3, 2e3, -1.5e3]])
    blown = run_model_ensemble(MODELS["free"], fast, 100.0, 1.0, method="rk4", axis=3, drift_limit=0.0)
    assert blown.status[0] == registry.STATUS_NONFINITE
    assert blown.steps_taken[0] < 100  # caught at a check (every 32 steps) and frozen there
