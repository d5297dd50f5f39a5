"""Models beyond the free body (physics layer): right-hand sides, analytic Jacobians, invariants, and linear theory
from the Jacobian's eigenvalues checked against closed forms and against independent integrations (SciPy's DOP853).

All numpy: no numba kernel is compiled here.
"""

import pickle

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import tumble
from tumble import registry
from tumble.measure.estimators import invariant_weights
from tumble.physics.models import FreeBody, Gyrostat, HeavyTop, Model, from_kind
from tumble.physics.theory import (
    eigenvalues,
    gyrostat_linear,
    linear,
    sleeping_top_linear,
    sleeping_top_precession,
)


def _random_moments(rng):
    """Principal moments obeying the triangle inequality, any order, kg m²."""
    while True:
        moments = rng.uniform(0.2, 3.0, 3)
        if moments.sum() - moments.max() >= moments.max():
            return moments


def _random_models(rng):
    moments = _random_moments(rng)
    return [FreeBody(moments), Gyrostat(moments, rng.normal(size=3)), HeavyTop(moments, rng.uniform(0.1, 3.0))]


def _relative(a, b):
    return abs(a - b) / max(abs(a), abs(b))


def _same(got, expected, rel):
    """Two ``(kind, value)`` answers of linear theory agree: the same kind, values within ``rel``."""
    return got[0] == expected[0] and got[1] == pytest.approx(expected[1], rel=rel)


# --- the registry and the public face -----------------------------------------------------------------------------

def test_the_registry_lists_the_contract_models_and_their_study_keys():
    assert registry.MODEL_KINDS == ("free", "gyrostat", "heavy_top", "gravity_gradient", "damper")
    assert registry.DEFAULT_MODEL == "free"
    assert {p.key for p in registry.MODEL_PARAMETERS} == {"rotor", "mgl", "orbit_rate", "damper_inertia", "damping"}
    assert registry.model_kind("gyrostat").parameters == ("rotor",)
    assert registry.model_kind("heavy_top").parameters == ("mgl",)
    assert registry.model_kind("gravity_gradient").parameters == ("orbit_rate",)
    assert registry.model_kind("damper").parameters == ("damper_inertia", "damping")
    assert registry.model_parameter("rotor").size == 3
    for spec in registry.MODELS:
        assert spec.state[:3] == ("w1", "w2", "w3"), spec.name  # every state starts with the angular velocity
        assert {letter for letter, _, _ in registry.state_blocks(spec.name)} <= {b[0] for b in registry.STATE_BLOCKS}
        assert all(registry.model_parameter(key) for key in spec.parameters)
    assert registry.state_blocks("heavy_top") == (("w", 0, 3), ("g", 3, 6))
    assert registry.state_blocks("gravity_gradient") == (("w", 0, 3), ("q", 3, 7))
    with pytest.raises(ValueError, match="model kind"):
        registry.model_kind("rigid")


def test_every_implemented_model_agrees_with_its_registry_row():
    rng = np.random.default_rng(1)
    implemented = [spec.name for spec in registry.MODELS if spec.implemented]
    assert implemented == ["free", "gyrostat", "heavy_top", "gravity_gradient", "damper"]
    for model in _random_models(rng):
        spec = registry.model_kind(model.kind)
        assert model.state_size == len(spec.state)
        assert tuple(model.parameters) == spec.parameters + model.extras  # the study keys, then the API's own
        state = rng.normal(size=(4, model.state_size))
        assert tuple(model.invariants(state)) == spec.invariants
        assert model.rhs(state).shape == state.shape


def test_the_models_are_reached_as_tumble_models():
    from tumble import models

    assert "models" in tumble.__all__
    assert models.Gyrostat is Gyrostat and tumble.models.HeavyTop is HeavyTop
    assert tumble.theory.linear(FreeBody((1.0, 2.0, 3.0)), 2, 1.0)[0] == "exponential"


def test_models_are_frozen_records_equal_by_value():
    a, b = Gyrostat((1.0, 2.0, 3.0), (0.0, 0.5, 0.0)), Gyrostat([1, 2, 3], [0, 0.5, 0])
    assert a == b and hash(a) == hash(b) and a != Gyrostat((1.0, 2.0, 3.0), (0.0, 0.6, 0.0))
    assert FreeBody(tumble.Body(1.0, 2.0, 3.0)) == FreeBody((1.0, 2.0, 3.0))
    with pytest.raises(AttributeError):
        a.rotor = np.zeros(3)
    with pytest.raises(ValueError):
        a.rotor[0] = 1.0  # read-only
    assert from_kind("gyrostat", (1.0, 2.0, 3.0), rotor=(0.0, 0.5, 0.0)) == a
    for model in (a, HeavyTop((1.0, 1.0, 0.5), 2.0), FreeBody((1.0, 2.0, 3.0))):  # a scene travels to dask workers
        copy = pickle.loads(pickle.dumps(model))
        assert copy == model and not copy.moments.flags.writeable


# --- (a) analytic Jacobians ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", range(5))
def test_analytic_jacobian_equals_the_complex_step_jacobian(seed):
    """Complex-step differentiation is exact to round-off for these polynomial right-hand sides."""
    rng = np.random.default_rng(seed)
    step = 1e-30
    for model in _random_models(rng):
        n = model.state_size
        states = rng.normal(size=(3, 2, n))
        jac = model.jacobian(states)
        assert jac.shape == (3, 2, n, n)
        numeric = np.stack([model.rhs(states + 1j * step * np.eye(n)[j]).imag / step for j in range(n)], axis=-1)
        np.testing.assert_allclose(jac, numeric, rtol=0, atol=1e-14 * np.abs(numeric).max(), err_msg=model.kind)


def test_analytic_jacobian_equals_central_differences_at_the_steady_spins():
    rng = np.random.default_rng(7)
    moments = _random_moments(rng)
    for model, axis in ((FreeBody(moments), 1), (Gyrostat(moments, (0.0, 0.0, 0.7)), 3), (HeavyTop(moments, 1.3), 3)):
        y = model.equilibrium(axis, 1.7)
        h = 1e-6
        numeric = np.stack([(model.rhs(y + h * e) - model.rhs(y - h * e)) / (2 * h) for e in np.eye(len(y))], -1)
        np.testing.assert_allclose(model.jacobian(y), numeric, atol=1e-8)


# --- (b) gyrostat: closed form and automatic linearisation ---------------------------------------------------------

@pytest.mark.parametrize("axis", [1, 2, 3])
def test_gyrostat_closed_form_equals_the_linearisation_on_both_sides_of_the_threshold(axis):
    rng = np.random.default_rng(100 + axis)
    kinds = set()
    for _ in range(150):
        moments = _random_moments(rng)
        spin = rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 5.0)
        h = rng.uniform(-3.0, 3.0) * moments.max() * abs(spin)
        b, c = axis % 3, (axis + 1) % 3
        factors = np.array([(moments[axis - 1] - moments[b]) * spin + h, (moments[axis - 1] - moments[c]) * spin + h])
        if np.abs(factors).min() < 1e-3 * (moments.max() * abs(spin) + abs(h)):
            continue  # too close to the threshold P = 0, where the eigenvalues collide
        rotor = np.zeros(3)
        rotor[axis - 1] = h
        expected = gyrostat_linear(moments, h, axis, spin)
        got = linear(Gyrostat(moments, rotor), axis, spin)
        assert got[0] == expected[0]
        assert _relative(got[1], expected[1]) < 1e-10, (moments, h, spin)
        kinds.add(got[0])
    assert kinds == {"periodic", "exponential"}


def test_gyrostat_without_rotor_is_the_free_body():
    moments = (1.0, 2.0, 3.0)
    for axis in (1, 2, 3):
        assert _same(gyrostat_linear(moments, 0.0, axis, 1.5), linear(moments, axis, 1.5), rel=1e-15)


def test_a_wheel_stabilises_the_intermediate_axis():
    """I = (1, 2, 3), spin W = 1 about axis 2: P = [(2 - 3) + h][(2 - 1) + h] < 0 for -1 < h < 1."""
    moments = (1.0, 2.0, 3.0)
    assert linear(Gyrostat(moments, (0.0, 0.0, 0.0)), 2, 1.0)[0] == "exponential"
    assert linear(Gyrostat(moments, (0.0, 0.5, 0.0)), 2, 1.0)[0] == "exponential"
    kind, frequency = linear(Gyrostat(moments, (0.0, 2.0, 0.0)), 2, 1.0)
    assert kind == "periodic"
    assert frequency == pytest.approx(np.sqrt(1.0 * 3.0 / 3.0), rel=1e-12)
    # exactly at the threshold the pair is neutral, in both the closed form and the eigenvalues
    assert gyrostat_linear(moments, 1.0, 2, 1.0) == ("neutral", 0.0)
    assert linear(Gyrostat(moments, (0.0, 1.0, 0.0)), 2, 1.0) == ("neutral", 0.0)


# --- (c) sleeping top ------------------------------------------------------------------------------------------------

def test_sleeping_top_closed_form_equals_the_linearisation_on_both_sides_of_the_threshold():
    rng = np.random.default_rng(3)
    kinds = set()
    for _ in range(200):
        a = rng.uniform(0.3, 3.0)
        c = rng.uniform(0.1, 2.0) * a  # triangle inequality: C <= 2A
        mgl = rng.uniform(0.1, 5.0)
        ratio = rng.uniform(0.0, 3.0)  # L3 / sqrt(4 A mgl)
        if abs(ratio - 1.0) < 0.01:
            continue  # the eigenvalue pairs collide at the threshold
        w3 = rng.choice([-1.0, 1.0]) * ratio * np.sqrt(4 * a * mgl) / c
        moments = (a, a, c)
        expected = sleeping_top_linear(moments, mgl, w3)
        got = linear(HeavyTop(moments, mgl), 3, w3)
        assert got[0] == expected[0] == ("periodic" if ratio > 1 else "exponential")
        assert _relative(got[1], expected[1]) < 1e-10, (a, c, mgl, w3)
        kinds.add(got[0])
        if ratio > 1:  # the body-frame eigenfrequencies are the space-frame precession rates minus the spin
            plus, minus = sleeping_top_precession(moments, mgl, w3)
            assert a * plus * minus == pytest.approx(mgl, rel=1e-12)
            expected_imag = np.sort(np.abs([0.0, 0.0, plus - w3, plus - w3, minus - w3, minus - w3]))
            lam = eigenvalues(HeavyTop(moments, mgl), 3, w3)
            np.testing.assert_allclose(np.sort(np.abs(lam.imag)), expected_imag, rtol=0,
                                       atol=1e-11 * np.abs(lam).max())
            np.testing.assert_allclose(lam.real, 0.0, atol=1e-11 * np.abs(lam).max())
    assert kinds == {"periodic", "exponential"}


def test_sleeping_top_precession_rates_are_the_textbook_roots():
    """A = 1, C = 0.5, mgl = 2, w3 = 6: L3 = 3, Ω = (3 ± 1) / 2 = 2, 1 rad/s; body frame -4, -5 rad/s."""
    assert sleeping_top_precession((1.0, 1.0, 0.5), 2.0, 6.0) == pytest.approx((2.0, 1.0), rel=1e-15)
    assert _same(sleeping_top_linear((1.0, 1.0, 0.5), 2.0, 6.0), ("periodic", 5.0), rel=1e-15)
    plus, minus = sleeping_top_precession((1.0, 1.0, 0.5), 2.0, [6.0, -6.0, 1.0])
    np.testing.assert_allclose(plus, [2.0, -1.0, np.nan])
    np.testing.assert_allclose(minus, [1.0, -2.0, np.nan])


def test_an_upright_top_at_rest_falls_at_sqrt_mgl_over_i():
    """Gravity destabilises: with w3 = 0 the largest eigenvalue is +sqrt(mgl / min(I1, I2)), real."""
    moments, mgl = (1.0, 1.5, 0.8), 2.0
    lam = eigenvalues(HeavyTop(moments, mgl), 3, 0.0)
    np.testing.assert_allclose(np.sort(lam.real), [-np.sqrt(2.0), -np.sqrt(2 / 1.5), 0, 0, np.sqrt(2 / 1.5),
                                                   np.sqrt(2.0)], atol=1e-14)
    np.testing.assert_allclose(lam.imag, 0.0, atol=1e-14)
    assert _same(linear(HeavyTop(moments, mgl), 3, 0.0), ("exponential", np.sqrt(mgl / 1.0)), rel=1e-14)


def test_a_non_symmetric_top_has_a_linearisation_but_no_closed_form():
    top = HeavyTop((1.0, 1.2, 0.6), 1.0)
    assert linear(top, 3, 10.0)[0] == "periodic"
    assert linear(top, 3, 1.0)[0] == "exponential"
    with pytest.raises(ValueError, match="symmetric"):
        sleeping_top_linear((1.0, 1.2, 0.6), 1.0, 10.0)


# --- (d) the free-body model is the free body ----------------------------------------------------------------------

def test_free_body_model_linear_equals_the_free_body_linear():
    rng = np.random.default_rng(4)
    for _ in range(200):
        moments = _random_moments(rng)
        spin = rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-2, 2)
        for axis in (1, 2, 3):
            expected = linear(moments, axis, spin)
            got = linear(FreeBody(moments), axis, spin)
            assert got[0] == expected[0]
            assert _relative(got[1], expected[1]) < 1e-12


def test_free_body_model_linear_keeps_its_digits_for_nearly_symmetric_bodies():
    """The Jacobian is built from differences of moments, as Euler's equations are: two moments 1e-10 apart still
    give the free body's rate to round-off (products ``I_j w - I_k w`` would lose ten digits)."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        moments = _random_moments(rng)
        moments[1] = moments[0] * (1.0 + rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-10, -3))
        if moments.sum() - moments.max() < moments.max():
            continue
        for axis in (1, 2, 3):
            expected = linear(moments, axis, 2.0)
            got = linear(FreeBody(moments), axis, 2.0)
            assert got[0] == expected[0]
            assert _relative(got[1], expected[1]) < 1e-12, (moments, axis)


def test_linear_of_a_model_broadcasts_over_axes_and_spins():
    model = FreeBody((1.0, 2.0, 3.0))
    axes, spins = np.array([[1], [2], [3]]), np.array([0.5, 1.0, -2.0, 4.0])
    kind, value = linear(model, axes, spins)
    assert kind.shape == value.shape == (3, 4)
    for i, axis in enumerate((1, 2, 3)):
        for j, spin in enumerate(spins):
            assert (kind[i, j], value[i, j]) == linear(model, axis, float(spin))
    assert eigenvalues(model, 2, spins).shape == (4, 3)


def test_a_degenerate_axis_of_the_free_body_model_is_neutral():
    assert linear(FreeBody((1.0, 1.0, 2.0)), 1, 1.0) == ("neutral", 0.0)
    assert linear(FreeBody((1.0, 1.0, 1.0)), 2, 3.0) == ("neutral", 0.0)
    assert linear(FreeBody((1.0, 2.0, 3.0)), 2, 0.0) == ("neutral", 0.0)


# --- (e) invariants under an independent integration ---------------------------------------------------------------

def _integrate(model, y0, t_end, t_eval=None):
    sol = solve_ivp(lambda t, y: model.rhs(y), (0.0, t_end), y0, method="DOP853", rtol=1e-12,
                    atol=1e-14 * np.abs(y0).max(), t_eval=t_eval)
    assert sol.success
    return sol


def _invariant_scales(model, y):
    """A magnitude per invariant (its terms' size), so that invariants near 0 get a meaningful relative error."""
    w = y[:3]
    lw = model.moments * w
    if isinstance(model, HeavyTop):
        return {"energy": 0.5 * lw @ w + model.mgl, "vertical_momentum": np.linalg.norm(lw), "up_squared": 1.0}
    return {"energy": 0.5 * lw @ w, "momentum_squared": np.sum((lw + model._rotor()) ** 2)}


@pytest.mark.parametrize("seed", range(3))
def test_invariants_are_conserved_by_an_independent_integration(seed):
    rng = np.random.default_rng(50 + seed)
    for model in _random_models(rng):
        y0 = rng.normal(size=model.state_size)
        if isinstance(model, HeavyTop):
            y0[3:] /= np.linalg.norm(y0[3:])
        sol = _integrate(model, y0, 20.0)
        start, end = model.invariants(y0), model.invariants(sol.y[:, -1])
        scales = _invariant_scales(model, y0)
        for name in start:
            assert abs(end[name] - start[name]) <= 1e-9 * scales[name], (model.kind, name, start[name], end[name])
        if isinstance(model, HeavyTop):  # |L|² is not conserved: gravity's torque changes it
            l0, l1 = model.moments * y0[:3], model.moments * sol.y[:3, -1]
            assert abs(l1 @ l1 - l0 @ l0) > 1e-3 * (l0 @ l0)


# --- (f) measured growth of a small perturbation --------------------------------------------------------------------

def _measured_rate(model, axis, spin, amplitude, t_end, window):
    rng = np.random.default_rng(11)
    y0 = model.equilibrium(axis, spin) + amplitude * rng.normal(size=model.state_size)
    times = np.linspace(*window, 2)
    sol = _integrate(model, y0, t_end, t_eval=times)
    norm = model.transverse_norm(sol.y.T, axis, spin)
    return np.log(norm[1] / norm[0]) / (times[1] - times[0])


def test_a_gyrostat_perturbation_grows_at_the_linear_rate():
    model = Gyrostat((1.0, 2.0, 3.0), (0.0, 0.2, 0.0))
    kind, rate = linear(model, 2, 1.0)
    assert kind == "exponential"  # P = (-1 + 0.2)(1 + 0.2) < 0
    assert rate == pytest.approx(np.sqrt(0.8 * 1.2 / 3.0), rel=1e-12)
    measured = _measured_rate(model, 2, 1.0, 1e-10, 22.0, (8.0, 22.0))
    assert measured == pytest.approx(rate, rel=5e-3)


def test_a_waking_heavy_top_falls_at_the_linear_rate():
    model = HeavyTop((1.0, 1.0, 0.5), 2.0)  # L3 = 2.5 < sqrt(4 A mgl) = sqrt(8)
    kind, rate = linear(model, 3, 5.0)
    assert kind == "exponential" and rate == pytest.approx(np.sqrt(8 - 6.25) / 2, rel=1e-12)
    measured = _measured_rate(model, 3, 5.0, 1e-10, 26.0, (8.0, 26.0))
    assert measured == pytest.approx(rate, rel=5e-3)


# --- the transverse projection -----------------------------------------------------------------------------------

def test_the_free_body_projection_is_the_estimators_weights():
    rng = np.random.default_rng(9)
    for _ in range(20):
        moments = _random_moments(rng)
        for axis in (1, 2, 3):
            t = FreeBody(moments).transverse(axis)
            b, c = axis % 3, (axis + 1) % 3
            assert t.columns.tolist() == t.phase.tolist() == [b, c]
            np.testing.assert_allclose(t.weights, invariant_weights(moments, axis)[[b, c]], rtol=1e-15)


def test_the_projection_sees_nothing_of_the_steady_spin():
    rng = np.random.default_rng(10)
    for model in _random_models(rng):
        axes = (3,) if isinstance(model, HeavyTop) else (1, 2, 3)
        for axis in axes:
            if isinstance(model, Gyrostat):
                rotor = np.zeros(3)
                rotor[axis - 1] = 0.8
                model = Gyrostat(model.moments, rotor)
            y = model.equilibrium(axis, np.array([-2.0, 0.5]))
            assert y.shape == (2, model.state_size)
            np.testing.assert_array_equal(model.rhs(y), 0.0)
            assert np.all(model.transverse_norm(y, axis, np.array([-2.0, 0.5])) == 0.0)
    top = HeavyTop((1.0, 1.5, 0.8), 2.0).transverse(3)
    assert top.columns.tolist() == [0, 1, 3, 4] and top.phase.tolist() == [3, 4]
    np.testing.assert_allclose(top.weights, [1.0, 1.0, 2.0, 2.0 / 1.5])


def test_the_gyrostat_weights_make_a_linear_oscillation_circular():
    """With the weights the norm of a small periodic perturbation stays constant (to the perturbation's square);
    the plain norm swings with the ellipse."""
    model = Gyrostat((1.0, 2.0, 3.0), (0.0, 5.0, 0.0))  # k_3 = 3 (-1 + 5) = 12, k_1 = 1 (1 + 5) = 6
    assert linear(model, 2, 1.0)[0] == "periodic"
    np.testing.assert_allclose(model.transverse(2, 1.0).weights, [np.sqrt(2), np.sqrt(0.5)])
    y0 = model.equilibrium(2, 1.0) + np.array([1e-5, 0.0, 0.0])
    sol = _integrate(model, y0, 20.0, t_eval=np.linspace(0, 20.0, 200))
    weighted = model.transverse_norm(sol.y.T, 2, 1.0)
    plain = np.hypot(sol.y[0], sol.y[2])
    assert np.ptp(weighted) / weighted.mean() < 1e-4
    assert np.ptp(plain) / plain.mean() > 0.1


def test_angular_velocity_from_momentum_subtracts_the_rotor():
    model = Gyrostat((1.0, 2.0, 3.0), (0.1, -0.2, 0.3))
    w = np.array([[0.5, 1.0, -2.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(model.angular_velocity(model.moments * w + model.rotor), w, rtol=1e-15)
    np.testing.assert_allclose(HeavyTop((1.0, 2.0, 3.0), 1.0).angular_velocity([1.0, 2.0, 3.0]), [1.0, 1.0, 1.0])


# --- (g) bad parameters ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("build, field", [
    (lambda: HeavyTop((1.0, 1.0, 0.5), 0.0), "mgl"),
    (lambda: HeavyTop((1.0, 1.0, 0.5), -1.0), "mgl"),
    (lambda: HeavyTop((1.0, 1.0, 0.5), np.nan), "mgl"),
    (lambda: HeavyTop((1.0, 1.0, 0.5), (1.0, 2.0)), "mgl"),
    (lambda: Gyrostat((1.0, 2.0, 3.0), (0.0, np.inf, 0.0)), "rotor"),
    (lambda: Gyrostat((1.0, 2.0, 3.0), (0.0, 1.0)), "rotor"),
    (lambda: Gyrostat((1.0, 2.0, 3.0), "wheel"), "rotor"),
    (lambda: FreeBody((1.0, 2.0, 5.0)), "triangle"),
    (lambda: FreeBody((1.0, -2.0, 2.0)), "moments"),
    (lambda: HeavyTop((1.0, 1.0, 0.5), 1.0).equilibrium(1, 1.0), "axis"),
    (lambda: linear(HeavyTop((1.0, 1.0, 0.5), 1.0), 2, 1.0), "axis"),
    (lambda: Gyrostat((1.0, 2.0, 3.0), (0.0, 1.0, 0.0)).equilibrium(3, 1.0), "rotor"),
    (lambda: FreeBody((1.0, 2.0, 3.0)).equilibrium(4, 1.0), "axis"),
    (lambda: FreeBody((1.0, 2.0, 3.0)).equilibrium(2, np.nan), "spin"),
    (lambda: FreeBody((1.0, 2.0, 3.0)).rhs(np.zeros(6)), "state"),
    (lambda: from_kind("gravity_gradient", (1.0, 2.0, 3.0), orbit_rate=-1e-3), "orbit_rate"),
    (lambda: from_kind("damper", (1.0, 2.0, 3.0), damper_inertia=0.1, damping=0.0), "damping"),
    (lambda: from_kind("rigid", (1.0, 2.0, 3.0)), "model kind"),
    (lambda: from_kind("heavy_top", (1.0, 1.0, 0.5), mgl=1.0, rotor=(0, 0, 1)), "rotor"),
    (lambda: from_kind("heavy_top", (1.0, 1.0, 0.5)), "mgl"),
    (lambda: sleeping_top_linear((1.0, 1.0, 0.5), 0.0, 3.0), "mgl"),
])
def test_bad_parameters_raise_errors_naming_the_field(build, field):
    with pytest.raises(ValueError, match=field):
        build()


def test_eigenvalues_need_a_model():
    with pytest.raises(TypeError, match="model"):
        eigenvalues((1.0, 2.0, 3.0), 2, 1.0)


def test_issue_19_models_are_built_from_their_parameters_and_run_in_studies():
    # the gravity gradient and the damper: classes, kernels (kernels.MODEL_CODES) and studies
    for kind in ("gravity_gradient", "damper"):
        spec = registry.model_kind(kind)
        assert spec.physics and spec.implemented
        with pytest.raises(ValueError, match="needs it"):
            from_kind(kind, (1.0, 2.0, 3.0))
    assert all(spec.physics for spec in registry.MODELS)
    assert isinstance(from_kind("free", (1.0, 2.0, 3.0)), Model)
