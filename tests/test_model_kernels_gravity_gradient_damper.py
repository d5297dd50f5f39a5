"""Issue 19's two models in the model kernels and the engine: the gravity-gradient satellite and Kane's damper.

In layers, as ``test_model_kernels.py``: the kernels' right-hand sides are the physics layer's -> rk4 and rk8 show
their orders against SciPy's DOP853 -> invariants (Jacobi integral, |q|² = 1 kept by the renormalisation after each
step, the damper's |L|²) and the drift observer -> the damper's energy decreases monotonically in every sample ->
the probes are the physics layer's transverse norm (the gravity gradient's centre w2 = -n) -> growth rates and the
pitch libration against linear theory -> the initial states -> bit-for-bit reproducibility across threads and chunks.

Both models run through the same compiled driver as the others (the module fixture compiles or loads it once).
"""

import numpy as np
import pytest
from model_checks import assert_same_bits_on_any_threads_and_chunks, fitted_rate, model_errors, observed_order
from tumble.theory import linear

from tumble import registry
from tumble.engine.model_ensemble import run_model_ensemble
from tumble.engine.sampling import perturbed_spins, perturbed_states
from tumble.kernels import MODEL_CODES, model_rhs
from tumble.physics.models import Damper, GravityGradient
from tumble.physics.theory import gravity_gradient_pitch_frequency

EPS = np.finfo(float).eps

MODELS = {
    "gravity_gradient": GravityGradient((2.0, 2.5, 1.0), 1.0),  # Lagrange region: stable
    "damper": Damper((2.0, 2.5, 1.0), 1.0, 0.5),
}


@pytest.fixture(scope="module")
def warm():
    """Compile (or load from numba's cache) the one model driver and the kernels' right-hand side."""
    model = MODELS["gravity_gradient"]
    y0 = model.equilibrium(2)[None]
    run_model_ensemble(model, y0, 0.02, 0.01, axis=2, save_every=1, probe_times=[0.0], drift=True)
    model_rhs(model.kind, y0.T.copy(), model.moments, **model.parameters)
    return True


def _unit(q):
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _general_states(model, samples=1, seed=0):
    """States far from any steady spin (every component O(1)); a gravity gradient's quaternion of norm 1."""
    rng = np.random.default_rng(seed)
    y = np.concatenate([[[1.0, 1.5, -1.2, 0.3, -0.4, 0.8, 0.5][:model.state_size]],
                        rng.normal(size=(samples - 1, model.state_size))])
    if model.kind == "gravity_gradient":
        y[:, 3:] = _unit(y[:, 3:])
    return y


def test_the_kernels_step_every_model_the_studies_run():
    assert set(MODEL_CODES) == set(registry.MODEL_KINDS)
    for kind in MODELS:
        assert registry.model_kind(kind).implemented


# --- the right-hand side -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", list(MODELS))
def test_kernel_rhs_is_the_physics_rhs_to_round_off(warm, kind):
    """At random states (a gravity gradient's quaternion of any norm: the formulas are the physics layer's)."""
    model = MODELS[kind]
    y = np.random.default_rng(7).normal(size=(200, model.state_size)) * 3.0
    expected = model.rhs(y)
    got = model_rhs(kind, np.ascontiguousarray(y.T), model.moments, **model.parameters).T
    w2 = np.sum(y[:, :3] ** 2, axis=1, keepdims=True)
    if kind == "gravity_gradient":  # each rate's largest terms: w², 3 n² |c3|², |q| (|w| + n |c2|), |c| <= 1 + 2 |q|²
        n, q2 = model.orbit_rate, np.sum(y[:, 3:] ** 2, axis=1, keepdims=True)
        scale = np.concatenate([np.repeat(w2 + 3 * n ** 2 * (1 + 2 * q2) ** 2, 3, axis=1),
                                np.repeat(np.sqrt(q2) * (np.sqrt(w2) + n * (1 + 2 * q2)), 4, axis=1)], axis=1)
    else:  # w², |w| |s|, c |s − w| / min(I, J)
        scale = w2 + np.sum(y[:, 3:] ** 2, axis=1, keepdims=True)
    assert np.all(np.abs(got - expected) <= 4 * EPS * scale)


def test_sign_conventions_a_pitched_satellite_is_pulled_back_and_a_slipping_sphere_drags_the_body(warm):
    """Gravity gradient: a pitch θ2 > 0 of a body with I1 > I3 gives w2' = -3 n² (I1 − I3)/I2 θ2 < 0 (restoring);
    damper: a sphere faster than the body about axis 1 accelerates it, w1' = c (s1 − w1)/I1."""
    gg = MODELS["gravity_gradient"]
    theta = 1e-4
    y = np.array([[0.0, -1.0, 0.0, np.cos(theta / 2), 0.0, np.sin(theta / 2), 0.0]])
    got = model_rhs(gg.kind, np.ascontiguousarray(y.T), gg.moments, **gg.parameters).T
    assert got[0, 1] == pytest.approx(-3 * (2.0 - 1.0) / 2.5 * theta, rel=1e-7)
    assert np.allclose(got, gg.rhs(y), rtol=0, atol=4 * EPS)
    damper = MODELS["damper"]
    y = np.array([[1.0, 0.0, 0.0, 1.5, 0.0, 0.0]])
    got = model_rhs(damper.kind, np.ascontiguousarray(y.T), damper.moments, **damper.parameters).T
    assert got[0, 0] == pytest.approx(0.5 * 0.5 / 2.0, rel=1e-15)
    assert got[0, 3] == pytest.approx(-0.5 * 0.5 / 1.0, rel=1e-15)
    assert np.array_equal(got, damper.rhs(y))


# --- observed order -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("method, order, steps", [("rk4", 4, (40, 80, 160)), ("rk8", 8, (16, 24, 32))])
@pytest.mark.parametrize("kind", list(MODELS))
def test_rk4_and_rk8_show_their_order_on_both_models(warm, kind, method, order, steps):
    """The largest error over 8 checkpoints against DOP853 (rtol 1e-13); the gravity gradient's steps include the
    renormalisation of the quaternion (a projection: the order is kept)."""
    model = MODELS[kind]
    y0 = _general_states(model)
    t_end = 4.0
    errors = model_errors(model, y0, t_end, method, steps)
    assert min(errors) > 1e-12  # above the reference's own error
    observed = observed_order(t_end, steps, errors)
    assert observed == pytest.approx(order, abs=0.25), errors


# --- invariants, the drift observer, the damper's energy -----------------------------------------------------------

def _numpy_drift(model, trajectory):
    """Running max over a saved trajectory of each invariant's drift, with the kernels' scales (numpy)."""
    values = np.stack(list(model.invariants(trajectory).values()), axis=-1)  # (N, T, n_invariants)
    y = trajectory[:, 0]
    moments = model.moments
    if model.kind == "gravity_gradient":
        n2 = model.orbit_rate ** 2
        c2 = model.following_velocity(y[:, 3:]) / -model.orbit_rate
        w_r = y[:, :3] + model.orbit_rate * c2
        jacobi = values[:, 0, 0]
        # scale: T_r + V_g + V_c = Jacobi + 2 V_c
        scales = np.stack([jacobi + n2 * np.sum(moments * c2 * c2, -1), np.sum(y[:, 3:] ** 2, -1)], -1)
        assert np.all(scales[:, 0] >= 0.5 * np.sum(moments * w_r * w_r, -1))
    else:
        lw = np.linalg.norm(moments * y[:, :3], axis=-1)
        scales = ((lw + model.damper_inertia * np.linalg.norm(y[:, 3:], axis=-1)) ** 2)[:, None]
    return np.max(np.abs(values - values[:, :1]) / scales[:, None], axis=1)


@pytest.mark.parametrize("method, dt, tolerances", [
    ("rk4", 0.01, {"jacobi_integral": 1e-7, "quaternion_squared": 4 * EPS, "momentum_squared": 1e-7}),
    ("rk8", 0.02, {"jacobi_integral": 1e-11, "quaternion_squared": 4 * EPS, "momentum_squared": 1e-10}),
])
@pytest.mark.parametrize("kind", list(MODELS))
def test_invariants_are_kept_and_the_drift_observer_reports_them(warm, kind, method, dt, tolerances):
    model = MODELS[kind]
    y0 = _general_states(model, 4, seed=1)
    result = run_model_ensemble(model, y0, 10.0, dt, method=method, axis=3, save_every=1, drift=True)
    assert result.drift.shape == (4, len(model.spec.invariants))
    assert (result.status == registry.STATUS_OK).all()
    for j, name in enumerate(model.spec.invariants):
        assert result.drift[:, j].max() < tolerances[name], name
    expected = _numpy_drift(model, result.trajectory)
    assert np.allclose(result.drift, expected, rtol=1e-6, atol=64 * EPS)
    if kind == "gravity_gradient":  # |q| = 1 at every step, to round-off
        assert np.abs(np.linalg.norm(result.trajectory[..., 3:], axis=-1) - 1.0).max() <= 2 * EPS


def test_a_non_unit_quaternion_is_put_on_the_unit_sphere_by_the_first_step_and_the_drift_reports_it(warm):
    model = MODELS["gravity_gradient"]
    y0 = _general_states(model)
    y0[0, 3:] *= 1.001
    result = run_model_ensemble(model, y0, 0.1, 0.01, axis=2, drift=True, drift_limit=0.0)
    assert np.linalg.norm(result.final[0, 3:]) == pytest.approx(1.0, abs=2 * EPS)
    assert result.drift[0, 1] == pytest.approx(1 - 1 / 1.001 ** 2, rel=1e-9)


@pytest.mark.parametrize("method", ["rk4", "rk8"])
def test_the_damper_energy_decreases_monotonically_in_every_sample(warm, method):
    """The issue's target: "the damper's energy decreases monotonically to round-off in every sample; |L| conserved
    to 1e-10". Spins near the minor axis (which turn over towards the major axis, losing energy) and general states
    (the sphere slipping from the start); every step saved."""
    model = MODELS["damper"]
    y0 = np.concatenate([perturbed_states(model, 3, 2.0, 0.2, 8, seed=9), _general_states(model, 8, seed=2)])
    result = run_model_ensemble(model, y0, 60.0, 0.01, method=method, axis=3, save_every=1, drift=True)
    assert (result.status == registry.STATUS_OK).all()
    energy = model.energy(result.trajectory)  # (N, T)
    steps = np.diff(energy, axis=1)
    assert np.all(steps <= 4 * EPS * energy[:, :1]), steps.max(axis=1) / energy[:, 0]
    assert np.all(energy[:, -1] < (1 - 1e-3) * energy[:, 0])  # a real loss in every sample
    if method == "rk8":
        assert result.drift.max() < 1e-10


# --- the probes: the physics layer's transverse norm -----------------------------------------------------------------

@pytest.mark.parametrize("kind, axis", [("gravity_gradient", 2), ("damper", 3)])
def test_the_probes_are_the_physics_transverse_norm_about_the_equilibrium(warm, kind, axis):
    """The kernels subtract the equilibrium ``y_eq`` from the norm's columns: for the gravity gradient that is the
    ``Transverse.centre`` (w2 = -n, the quaternion's vector part 0) with the weights (1, 1, 1, 4n², 4n², 4n²)."""
    model = MODELS[kind]
    transverse = model.transverse(axis, 2.0)
    y_eq = model.equilibrium(axis, 2.0)
    if kind == "gravity_gradient":
        assert np.array_equal(y_eq[transverse.columns], transverse.centre)
    y0 = perturbed_states(model, axis, 2.0, 1e-2, 6, seed=4)
    result = run_model_ensemble(model, y0, 2.0, 0.01, axis=axis, spin=2.0, save_every=50,
                                probe_times=[0.0, 0.5, 1.0, 1.5, 2.0])
    assert np.allclose(result.probes, model.transverse_norm(result.trajectory, axis, 2.0), rtol=1e-13, atol=0)
    assert np.all(result.probes[:, 0] > 0)


# --- linear theory -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("model, axis, spin", [
    (GravityGradient((2.1, 2.0, 2.2), 1.0), 2, 1.0),  # I3 > I1: pitch unstable (DeBra-Delp side: roll-yaw stable)
    (GravityGradient((3.0, 2.5, 1.0), 1.0), 2, 1.0),  # I1 > I2 > I3: pitch stable, roll-yaw unstable (k1 k3 < 0)
    (Damper((2.0, 2.5, 1.0), 1.0, 0.5), 3, 2.0),  # minor axis with a damper: the nutation grows (major-axis rule)
], ids=["gravity_gradient_pitch_unstable", "gravity_gradient_roll_yaw_unstable", "damper_minor_axis"])
def test_measured_growth_rate_matches_linear_theory_of_the_jacobian(warm, model, axis, spin):
    kind, rate = linear(model, axis, spin)
    assert kind == "exponential"
    y0 = perturbed_states(model, axis, spin, 1e-9, 64, seed=3)
    t_end = 30.0 / rate
    result = run_model_ensemble(model, y0, t_end, min(0.01, 0.05 / rate), method="rk8", axis=axis, spin=spin,
                                probe_times=np.linspace(0.0, t_end, 601), final=False)
    assert (result.status == registry.STATUS_OK).all()
    scale = model.orbit_rate if model.kind == "gravity_gradient" else spin
    measured = fitted_rate(result.probe_times, result.probes, 1e-7 * scale, 1e-4 * scale)
    assert measured == pytest.approx(rate, rel=5e-3)


def test_a_stable_satellite_librates_in_pitch_at_the_closed_form_frequency(warm):
    """Lagrange region (I2 > I1 > I3): the pitch angle θ2 ≈ 2 q2 (decoupled from roll and yaw to first order)
    oscillates at w_p = n sqrt(3 (I1 − I3)/I2); measured from the zero crossings of q2 in the saved trajectory."""
    model = MODELS["gravity_gradient"]
    kind, frequency = gravity_gradient_pitch_frequency(model.moments, model.orbit_rate)
    assert kind == "periodic" and linear(model, 2, 1.0)[0] == "periodic"
    period = 2 * np.pi / frequency
    y0 = perturbed_states(model, 2, 1.0, 1e-4, 8, seed=4)
    result = run_model_ensemble(model, y0, 20 * period, period / 200, axis=2, save_every=1)
    assert (result.status == registry.STATUS_OK).all()
    t = result.times
    measured = []
    for x in result.trajectory[:, :, 5]:  # q2
        i = np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]
        crossings = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
        measured.append(np.pi / np.mean(np.diff(crossings)))
    assert np.mean(measured) == pytest.approx(frequency, rel=5e-3)
    assert np.max(np.abs(result.trajectory[..., 4:])) < 1e-3  # it stays near the orbit-following attitude


# --- initial states -------------------------------------------------------------------------------------------------

def test_a_satellites_initial_attitudes_are_tilted_by_the_amplitude_about_uniform_axes_following_the_orbit():
    model = GravityGradient((2.0, 2.5, 1.0), 0.3)
    states = perturbed_states(model, 2, 1.0, 0.05, 5000, seed=11)
    assert states.shape == (5000, 7)
    q = states[:, 3:]
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() <= 2 * EPS
    assert np.allclose(2 * np.arctan2(np.linalg.norm(q[:, 1:], axis=1), q[:, 0]), 0.05, rtol=1e-12)
    axes = q[:, 1:] / np.linalg.norm(q[:, 1:], axis=1, keepdims=True)
    assert np.abs(axes.mean(axis=0)).max() < 0.05  # uniform on the sphere: mean 0, second moments 1/3
    assert np.allclose(np.mean(axes ** 2, axis=0), 1 / 3, atol=0.02)
    assert np.allclose(states[:, :3], model.following_velocity(q), rtol=0, atol=0)  # w = -n c2
    assert np.abs(model.rhs(states)[:, 3:]).max() <= 4 * EPS * 0.3  # q' = 0: no turn relative to the orbit
    # slices across a chunk boundary (4096) are the same bits; the draw depends on the seed only
    assert np.array_equal(perturbed_states(model, 2, 1.0, 0.05, 5000, seed=11, start=4090, stop=4100),
                          states[4090:4100])
    assert np.array_equal(perturbed_states(model, 1, 3.0, 0.05, 10, seed=11), states[:10])  # axis, spin unused
    assert not np.array_equal(perturbed_states(model, 2, 1.0, 0.05, 10, seed=12), states[:10])
    with pytest.raises(ValueError, match="amplitude"):
        perturbed_states(model, 2, 1.0, -1.0, 10)
    with pytest.raises(ValueError, match="axis"):
        perturbed_states(model, 4, 1.0, 0.1, 10)


@pytest.mark.parametrize("distribution", ["filled_cone", "gaussian"])
def test_a_satellites_tilts_follow_the_other_distributions_laws(distribution):
    # filled cone: uniform in solid angle on the cap theta <= a, P(theta <= x) = (1 - cos x)/(1 - cos a);
    # gaussian: two N(0, a^2) tilt components, so theta is Rayleigh, P(theta <= x) = 1 - exp(-x^2 / (2 a^2))
    a = 0.05
    model = GravityGradient((2.0, 2.5, 1.0), 0.3)
    q = perturbed_states(model, 2, 1.0, a, 20000, seed=3, distribution=distribution)[:, 3:]
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() <= 2 * EPS
    theta = np.sort(2 * np.arctan2(np.linalg.norm(q[:, 1:], axis=1), q[:, 0]))
    if distribution == "filled_cone":
        assert theta[-1] <= a * (1 + 1e-12)
        cdf = (1 - np.cos(theta)) / (1 - np.cos(a))
    else:
        cdf = -np.expm1(-theta ** 2 / (2 * a ** 2))
    ks = np.max(np.abs(cdf - np.arange(1, theta.size + 1) / theta.size))
    assert ks < 1.63 / np.sqrt(theta.size)  # Kolmogorov-Smirnov at the 1 % level
    axes = q[:, 1:] / np.linalg.norm(q[:, 1:], axis=1, keepdims=True)
    assert np.abs(axes.mean(axis=0)).max() < 0.03 and np.allclose(np.mean(axes ** 2, axis=0), 1 / 3, atol=0.015)
    assert np.array_equal(perturbed_states(model, 2, 1.0, a, 20000, seed=3, distribution=distribution, start=4090,
                                           stop=4100)[:, 3:], q[4090:4100])


def test_a_damper_starts_with_its_sphere_moving_with_the_tilted_body():
    model = MODELS["damper"]
    states = perturbed_states(model, 1, -2.0, 1e-2, 10, seed=5)
    w = perturbed_spins(model.moments, 1, -2.0, 1e-2, 10, seed=5)
    assert np.array_equal(states[:, :3], w) and np.array_equal(states[:, 3:], w)
    assert np.array_equal(perturbed_states(model, 1, -2.0, 1e-2, 10, seed=5, start=3, stop=6), states[3:6])


# --- reproducibility ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", list(MODELS))
def test_results_are_bit_identical_on_any_number_of_threads_and_for_any_chunk(warm, kind):
    model = MODELS[kind]
    y0 = _general_states(model, 600, seed=6)
    assert_same_bits_on_any_threads_and_chunks(model, y0)
