"""Issue 19, physics layer: the gravity-gradient satellite and Kane's spherical damper.

Analytic Jacobians against complex-step derivatives of the right-hand sides; the automatic linearisation (the
Jacobian's eigenvalues) against the closed forms, on both sides of every stability boundary; invariants and the
damper's energy along SciPy DOP853 integrations of the right-hand sides; bad parameters. All numpy: no numba kernel
is compiled here.
"""

import pickle

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tumble import registry
from tumble.physics.models import (
    CLASSES,
    IMPLEMENTED,
    Damper,
    FreeBody,
    GravityGradient,
    from_kind,
)
from tumble.physics.theory import (
    GRAVITY_GRADIENT_REGIONS,
    damper_nutation_rate,
    eigenvalues,
    gravity_gradient_k,
    gravity_gradient_pitch_frequency,
    gravity_gradient_region,
    gravity_gradient_roll_yaw,
    gravity_gradient_stable,
    linear,
)


def _qmul(a, b):
    """Hamilton product, scalar first, complex allowed (``rotations.product`` casts to float)."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0])


def _conj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _complex_step_jacobian(f, y, h=1e-30):
    """``∂f/∂y`` column by column: ``Im f(y + i h e_j) / h`` (exact to round-off for an analytic ``f``)."""
    cols = []
    for j in range(len(y)):
        dy = np.zeros(len(y), dtype=complex)
        dy[j] = 1j * h
        cols.append(np.imag(f(y + dy)) / h)
    return np.stack(cols, axis=-1)


def _moments_from_k(k1, k3, scale=1.0):
    """Principal moments with the given gravity-gradient ratios: with ``I2 = 1``, ``I1 = (1 − k3)/(1 − k1 k3)``,
    ``I3 = (1 − k1)/(1 − k1 k3)`` (every point of ``|k1|, |k3| < 1`` obeys the triangle inequality)."""
    d = 1.0 - k1 * k3
    return scale * np.array([(1.0 - k3) / d, 1.0, (1.0 - k1) / d])


def _random_unit_quaternion(rng, angle=None):
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    a = rng.uniform(0, np.pi) if angle is None else angle
    return np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * axis])


def _random_gravity_gradient(rng):
    while True:
        k1, k3 = rng.uniform(-0.95, 0.95, 2)
        if abs(k1 - k3) > 0.05:
            break
    return GravityGradient(_moments_from_k(k1, k3, rng.uniform(0.5, 500.0)), rng.uniform(1e-4, 2e-3))


def _random_damper(rng):
    while True:
        moments = rng.uniform(0.5, 3.0, 3)
        if moments.sum() - moments.max() >= moments.max():
            return Damper(moments, rng.uniform(0.01, 0.3), rng.uniform(1e-3, 0.1))


def _closed_form_exponents(moments, n):
    """The six exponents of the linear gravity-gradient motion from the closed forms: pitch ``±i w_p`` (or
    ``±rate``), then the roll-yaw quartic's four roots."""
    kind, value = gravity_gradient_pitch_frequency(moments, n)
    pitch = np.array([1j * value, -1j * value]) if kind == "periodic" else np.array([value, -value], dtype=complex)
    return np.concatenate([pitch, gravity_gradient_roll_yaw(moments, n)])


def _matched(a, b):
    """Largest distance between the members of two sets of complex numbers, paired greedily (nearest first)."""
    a, b = list(a), list(b)
    worst = 0.0
    for z in a:
        j = int(np.argmin([abs(z - w) for w in b]))
        worst = max(worst, abs(z - b.pop(j)))
    return worst


# --- registry, construction ------------------------------------------------------------------------------------------

def test_the_new_models_follow_their_registry_rows():
    rng = np.random.default_rng(19)
    assert set(CLASSES) == set(registry.MODEL_KINDS)
    assert set(IMPLEMENTED) == set(registry.MODEL_KINDS)  # every model runs in studies (issue 19's studies landed)
    for model in (_random_gravity_gradient(rng), _random_damper(rng)):
        spec = registry.model_kind(model.kind)
        assert spec.physics and spec.implemented
        assert model.state_size == len(spec.state)
        assert tuple(model.parameters) == spec.parameters + model.extras  # the study keys, then the API's own
        state = rng.normal(size=(4, model.state_size))
        assert tuple(model.invariants(state)) == spec.invariants
        assert model.rhs(state).shape == state.shape
        assert model.jacobian(state).shape == (4, model.state_size, model.state_size)
        assert model.tangent_jacobian(state).shape == (4, model.tangent_size, model.tangent_size)
        assert pickle.loads(pickle.dumps(model)) == model
        assert from_kind(model.kind, model.moments, **model.parameters) == model


def test_the_model_kernels_and_the_studies_run_the_new_models():
    """Issue 19's kernels step both models (tests/test_model_kernels_gravity_gradient_damper.py) and studies run them
    (tests/test_model_studies_gravity_gradient_damper.py)."""
    from tumble.kernels import MODEL_CODES

    assert {"gravity_gradient", "damper"} <= set(MODEL_CODES)
    assert registry.model_kind("gravity_gradient").implemented and registry.model_kind("damper").implemented


@pytest.mark.parametrize("build, field", [
    (lambda: GravityGradient((2.0, 3.0, 1.5), 0.0), "orbit_rate"),
    (lambda: GravityGradient((2.0, 3.0, 1.5), -1e-3), "orbit_rate"),
    (lambda: GravityGradient((2.0, 3.0, 1.5), np.nan), "orbit_rate"),
    (lambda: GravityGradient((2.0, 3.0, 1.5), (1e-3, 1e-3)), "orbit_rate"),
    (lambda: GravityGradient((2.0, 3.0, 9.0), 1e-3), "triangle"),
    (lambda: GravityGradient((2.0, 3.0, 1.5), 1e-3).equilibrium(4), "axis"),
    (lambda: GravityGradient((2.0, 3.0, 1.5), 1e-3).rhs(np.zeros(6)), "state"),
    (lambda: Damper((1.0, 2.0, 2.5), 0.0, 0.1), "damper_inertia"),
    (lambda: Damper((1.0, 2.0, 2.5), np.inf, 0.1), "damper_inertia"),
    (lambda: Damper((1.0, 2.0, 2.5), 0.1, -0.1), "damping"),
    (lambda: Damper((1.0, 2.0, 2.5), 0.1, "sticky"), "damping"),
    (lambda: Damper((1.0, 2.0, 2.5), 0.1, 0.1).equilibrium(0, 1.0), "axis"),
    (lambda: from_kind("gravity_gradient", (2.0, 3.0, 1.5)), "orbit_rate"),
    (lambda: from_kind("gravity_gradient", (2.0, 3.0, 1.5), orbit_rate=1e-3, mgl=1.0), "mgl"),
    (lambda: from_kind("damper", (1.0, 2.0, 2.5), damping=0.1), "damper_inertia"),
    (lambda: gravity_gradient_pitch_frequency((2.0, 3.0, 1.5), 0.0), "orbit_rate"),
    (lambda: gravity_gradient_roll_yaw((2.0, 3.0, 1.5), -1.0), "orbit_rate"),
    (lambda: damper_nutation_rate((1.0, 2.0, 2.5), 0.1, 0.0, 3), "damping"),
    (lambda: damper_nutation_rate((1.0, 2.0, 2.5), -0.1, 0.1, 3), "damper_inertia"),
])
def test_bad_parameters_raise_errors_naming_the_field(build, field):
    with pytest.raises(ValueError, match=field):
        build()


# --- gravity gradient: Jacobians -----------------------------------------------------------------------------------

def test_gravity_gradient_jacobian_is_the_complex_step_derivative_of_its_rhs():
    rng = np.random.default_rng(1)
    for _ in range(5):
        model = _random_gravity_gradient(rng)
        y = np.concatenate([rng.normal(scale=model.orbit_rate, size=3), _random_unit_quaternion(rng)])
        expected = _complex_step_jacobian(model.rhs, y)
        scale = np.abs(expected).max()
        assert np.abs(model.jacobian(y) - expected).max() <= 1e-13 * scale
        assert np.abs(model.jacobian(y[None])[0] - model.jacobian(y)).max() == 0.0


def test_gravity_gradient_tangent_jacobian_is_the_derivative_of_the_attitude_error_flow():
    # theta(t) = 2 vec(q_ref(t)* q_pert(t)) with q_pert(0) = q (1, theta/2): d/dt (dw, theta) at t = 0, complex step
    rng = np.random.default_rng(2)
    for _ in range(5):
        model = _random_gravity_gradient(rng)
        y = np.concatenate([rng.normal(scale=model.orbit_rate, size=3), _random_unit_quaternion(rng)])
        f_ref = model.rhs(y)

        def flow(delta, y=y, f_ref=f_ref, model=model):
            q_pert = _qmul(y[3:], np.concatenate([[1.0], 0.5 * delta[3:]]))
            f = model.rhs(np.concatenate([y[:3] + delta[:3], q_pert]))
            d_theta = 2 * (_qmul(_conj(f_ref[3:]), q_pert) + _qmul(_conj(y[3:]), f[3:]))[1:]
            return np.concatenate([f[:3], d_theta])

        expected = _complex_step_jacobian(flow, np.zeros(6, dtype=complex))
        assert np.abs(model.tangent_jacobian(y) - expected).max() <= 1e-13 * np.abs(expected).max()


def test_the_quaternion_jacobian_adds_only_the_norm_constraints_zero_eigenvalue():
    rng = np.random.default_rng(3)
    for _ in range(5):
        model = _random_gravity_gradient(rng)
        y = model.equilibrium(2)
        assert np.array_equal(model.rhs(y), np.zeros(7))
        full = model.jacobian(y)
        assert not full[3].any() and not full[:, 3].any()  # q0: the norm direction, decoupled
        tangent = eigenvalues(model, 2)
        assert _matched(np.linalg.eigvals(full), np.concatenate([tangent, [0.0]])) <= 1e-12 * model.orbit_rate


# --- gravity gradient: linear theory against the closed forms ------------------------------------------------------

def test_automatic_linearisation_matches_the_closed_forms_at_random_bodies():
    rng = np.random.default_rng(4)
    for _ in range(40):
        model = _random_gravity_gradient(rng)
        n = model.orbit_rate
        lam = eigenvalues(model, 2)
        assert _matched(lam, _closed_form_exponents(model.moments, n)) <= 1e-10 * n
        stable = gravity_gradient_stable(*gravity_gradient_k(model.moments))
        kind, value = linear(model, 2)
        assert (kind == "periodic") == stable
        assert kind in ("periodic", "exponential")
        closed = _closed_form_exponents(model.moments, n)
        expected = np.abs(closed.imag).max() if stable else closed.real.max()
        assert value == pytest.approx(expected, rel=1e-10)


# A point on each boundary of the stable set, and the direction that crosses it: (name, k1, k3, direction).
_DEBRA_DELP_K1 = -0.1
# 1 + 3 k1 + k1 k3 = 4 sqrt(k1 k3) at k1 = -0.1: with k3 = -x^2, 0.1 x^2 - 4 sqrt(0.1) x + 0.7 = 0 (smaller root)
_DEBRA_DELP_K3 = -((4 * np.sqrt(0.1) - np.sqrt(1.6 - 0.28)) / 0.2) ** 2
_BOUNDARIES = [
    ("pitch k1 = k3, Lagrange side", 0.5, 0.5, (0.0, 1.0)),
    ("pitch k1 = k3, DeBra-Delp side", -0.05, -0.05, (0.0, 1.0)),  # the strip is narrow: |k| < 0.146 there
    ("roll-yaw k3 = 0", 0.5, 0.0, (0.0, 1.0)),
    ("roll-yaw k1 = 0", 0.0, -0.5, (1.0, 0.0)),
    ("roll-yaw DeBra-Delp curve", _DEBRA_DELP_K1, _DEBRA_DELP_K3, (0.0, 1.0)),
]


@pytest.mark.parametrize("name, k1, k3, direction", _BOUNDARIES, ids=[b[0] for b in _BOUNDARIES])
def test_both_sides_of_every_stability_boundary(name, k1, k3, direction):
    """5 % away from each boundary on either side (5 % of the boundary point's |k|, or 0.025 at k = 0): the closed
    forms and the automatic linearisation agree to 1e-10 and change their verdict together."""
    size = 0.05 * max(abs(k1), abs(k3))
    on_boundary = gravity_gradient_stable(k1, k3)
    assert not on_boundary  # a boundary is marginal
    verdicts = []
    for side in (-1.0, 1.0):
        kk1, kk3 = k1 + side * size * direction[0], k3 + side * size * direction[1]
        for n in (1e-3, 0.7):
            model = GravityGradient(_moments_from_k(kk1, kk3, 3.0), n)
            assert gravity_gradient_k(model.moments) == pytest.approx((kk1, kk3), abs=1e-14)
            closed = _closed_form_exponents(model.moments, n)
            assert _matched(eigenvalues(model, 2), closed) <= 1e-10 * n
            stable = gravity_gradient_stable(kk1, kk3)
            kind, value = linear(model, 2)
            assert kind == ("periodic" if stable else "exponential")
            expected = np.abs(closed.imag).max() if stable else closed.real.max()
            assert value == pytest.approx(expected, rel=1e-10)
        verdicts.append(stable)
    assert verdicts[0] != verdicts[1], name


def test_the_stable_regions_are_lagrange_and_debra_delp():
    assert GRAVITY_GRADIENT_REGIONS == ("lagrange", "debra_delp", "unstable")
    assert gravity_gradient_region(0.5, 0.2) == "lagrange"  # I2 > I1 > I3
    assert gravity_gradient_region(-0.1, -0.2) == "debra_delp"  # I1 > I3 > I2, next to k1 = 0
    assert gravity_gradient_region(-0.1, -0.5) == "unstable"  # beyond the DeBra-Delp curve
    assert gravity_gradient_region(0.2, 0.5) == "unstable"  # pitch: I1 < I3
    assert gravity_gradient_region(0.5, -0.2) == "unstable"  # k1 k3 < 0
    k1, k3 = np.meshgrid(np.linspace(-0.99, 0.99, 67), np.linspace(-0.99, 0.99, 67))
    regions = gravity_gradient_region(k1, k3)
    assert np.array_equal(regions == "lagrange", (k1 > k3) & (k3 > 0))  # the whole Lagrange triangle is stable
    debra = regions == "debra_delp"
    assert debra.any() and (k1[debra] < 0).all() and (k3[debra] < k1[debra]).all()
    body = _moments_from_k(-0.1, -0.2)
    assert body[0] > body[2] > body[1]


def test_pitch_oscillation_of_an_integration_has_the_linear_frequency():
    model = GravityGradient((2.0, 3.0, 1.5), 1e-3)
    _, w_p = gravity_gradient_pitch_frequency(model.moments, model.orbit_rate)
    y0 = model.equilibrium(2)
    y0[3:] = [np.cos(0.5e-4), 0.0, np.sin(0.5e-4), 0.0]  # pitch 1e-4 rad
    period = 2 * np.pi / w_p
    sol = solve_ivp(lambda t, y: model.rhs(y), (0, 3 * period), y0, method="DOP853", rtol=1e-12, atol=1e-15,
                    dense_output=True)
    t = np.linspace(0, 3 * period, 30001)
    pitch = sol.sol(t)[5]
    ups = t[1:][(pitch[:-1] < 0) & (pitch[1:] >= 0)]
    assert len(ups) == 3
    assert np.diff(ups).mean() == pytest.approx(period, rel=1e-3)
    assert np.abs(sol.sol(t)[[4, 6]]).max() < 1e-12  # roll and yaw stay unexcited


# --- gravity gradient: invariants ----------------------------------------------------------------------------------

def test_the_jacobi_integral_and_the_quaternion_norm_are_conserved_by_the_rhs():
    rng = np.random.default_rng(5)
    model = GravityGradient((2.0, 3.0, 1.5), 1e-3)
    n = model.orbit_rate
    y0 = np.concatenate([np.array([0.0, -n, 0.0]) + rng.normal(scale=0.5 * n, size=3),
                         _random_unit_quaternion(rng, angle=0.8)])
    t_end = 3 * 2 * np.pi / n
    sol = solve_ivp(lambda t, y: model.rhs(y), (0, t_end), y0, method="DOP853", rtol=1e-12, atol=1e-14,
                    t_eval=np.linspace(0, t_end, 400))
    assert sol.success
    inv = model.invariants(sol.y.T)
    scale = n * n * model.moments.max()
    assert np.abs(inv["jacobi_integral"] - inv["jacobi_integral"][0]).max() <= 1e-9 * scale
    assert np.abs(inv["quaternion_squared"] - 1.0).max() <= 1e-10
    kinetic = 0.5 * np.sum(model.moments * sol.y[:3].T ** 2, axis=-1)  # not conserved: the test can see drift
    assert np.ptp(kinetic) > 1e-2 * scale


def test_the_jacobi_integral_is_stationary_along_the_rhs_at_any_state():
    rng = np.random.default_rng(6)
    model = _random_gravity_gradient(rng)
    for _ in range(5):
        y = np.concatenate([rng.normal(scale=model.orbit_rate, size=3), _random_unit_quaternion(rng)])
        f = model.rhs(y)
        h = 1e-30
        rate = np.imag(model.invariants(y + 1j * h * f)["jacobi_integral"]) / h
        scale = model.orbit_rate ** 3 * model.moments.max()
        assert abs(rate) <= 1e-12 * scale


def test_gravity_gradient_transverse_norm_measures_w_and_the_attitude_error():
    model = GravityGradient((2.0, 3.0, 1.5), 1e-3)
    y = model.equilibrium(2, np.ones(4))
    assert y.shape == (4, 7) and np.array_equal(model.equilibrium(1, 5.0), model.equilibrium(3, -2.0))
    assert np.array_equal(model.transverse_norm(y, 2), np.zeros(4))
    t = model.transverse(2)
    assert np.array_equal(model.equilibrium(2)[t.columns], t.centre)
    perturbed = model.equilibrium(2)
    perturbed[0] += 3e-6
    perturbed[3:] = [np.cos(2e-3), np.sin(2e-3), 0.0, 0.0]  # roll 4e-3 rad
    expected = np.hypot(3e-6, model.orbit_rate * 2 * np.sin(2e-3))  # n theta, theta = 2 q1
    assert model.transverse_norm(perturbed, 2) == pytest.approx(expected, rel=1e-12)


# --- damper ----------------------------------------------------------------------------------------------------------

def test_damper_jacobian_is_the_complex_step_derivative_of_its_rhs():
    rng = np.random.default_rng(7)
    for _ in range(5):
        model = _random_damper(rng)
        y = rng.normal(size=6)
        expected = _complex_step_jacobian(model.rhs, y)
        assert np.abs(model.jacobian(y) - expected).max() <= 1e-13 * np.abs(expected).max()


def test_damper_energy_decays_at_the_dissipation_rate():
    rng = np.random.default_rng(8)
    model = _random_damper(rng)
    for _ in range(5):
        y = rng.normal(size=6)
        h = 1e-30
        rate = np.imag(model.energy(y + 1j * h * model.rhs(y))) / h
        assert rate == pytest.approx(-model.dissipation(y), rel=1e-12)
        assert abs(np.imag(model.invariants(y + 1j * h * model.rhs(y))["momentum_squared"]) / h) <= 1e-13


def test_damper_keeps_its_momentum_and_loses_energy_monotonically():
    rng = np.random.default_rng(9)
    model = Damper((2.0, 2.5, 1.0), 0.1, 0.02)
    y0 = np.concatenate([rng.normal(size=3), rng.normal(size=3)])
    sol = solve_ivp(lambda t, y: model.rhs(y), (0, 60.0), y0, method="DOP853", rtol=1e-12, atol=1e-14,
                    t_eval=np.linspace(0, 60.0, 1201))
    assert sol.success
    l2 = model.invariants(sol.y.T)["momentum_squared"]
    assert np.abs(l2 / l2[0] - 1).max() <= 1e-10
    energy = model.energy(sol.y.T)
    assert (np.diff(energy) < 0).all()
    assert energy[-1] < 0.99 * energy[0]
    # the energy lost is the dissipation integrated (trapezoid on the fine grid)
    lost = np.trapezoid(model.dissipation(sol.y.T), sol.t) if hasattr(np, "trapezoid") else np.trapz(
        model.dissipation(sol.y.T), sol.t)
    assert energy[0] - energy[-1] == pytest.approx(lost, rel=1e-4)


def test_major_axis_rule_in_the_damper_linearisation():
    rng = np.random.default_rng(10)
    for _ in range(10):
        model = _random_damper(rng)
        order = np.argsort(model.moments)
        minor, major = int(order[0]) + 1, int(order[2]) + 1
        for spin in (0.7, -2.0):
            lam_major = eigenvalues(model, major, spin)
            scale = np.abs(lam_major).max()
            assert (lam_major.real <= 1e-12 * scale).all()
            assert np.sum(np.abs(lam_major) <= 1e-12 * scale) == 1  # the neutral line of steady spins
            kind, value = linear(model, major, spin)
            assert kind == "periodic" and value > 0
            lam_minor = eigenvalues(model, minor, spin)
            assert np.sum(lam_minor.real > 1e-12 * np.abs(lam_minor).max()) == 2  # the nutation pair grows
            kind, value = linear(model, minor, spin)
            assert kind == "exponential"
            assert 0 < value < model.damping * 2 / model.moments.min()


def test_weakly_damped_nutation_rate_matches_the_first_order_formula():
    moments, j = np.array([2.0, 2.5, 1.0]), 0.1
    for axis, spin in ((3, 1.0), (3, -1.3), (2, 0.8), (2, -2.0)):  # minor, major (axis 1 is the intermediate)
        for c in (1e-3, 1e-4):
            model = Damper(moments, j, c)
            lam = eigenvalues(model, axis, spin)
            nutation = lam[np.argmin(np.abs(np.abs(lam.imag) - linear(FreeBody(moments), axis, spin)[1]))]
            expected = damper_nutation_rate(moments, j, c, axis)
            assert nutation.real == pytest.approx(expected, rel=10 * (c / (j * abs(spin))) ** 2)
    assert damper_nutation_rate(moments, j, 1e-3, 3) > 0 > damper_nutation_rate(moments, j, 1e-3, 2)
    # the weakly damped nutation about the major axis is the free body's
    model = Damper(moments, j, 1e-4)
    assert linear(model, 2, 1.0)[1] == pytest.approx(linear(FreeBody(moments), 2, 1.0)[1], rel=1e-6)


def test_minor_axis_nutation_of_an_integration_grows_at_the_linear_rate():
    model = Damper((2.0, 2.5, 1.0), 0.1, 0.05)  # damping strong enough that e^8 takes a few hundred nutations
    kind, rate = linear(model, 3, 1.0)
    assert kind == "exponential"
    y0 = model.equilibrium(3, 1.0)
    y0[0] += 1e-7
    t_end = 8.0 / rate  # the norm grows by e^8, to about 3e-4 rad/s: still linear
    t = np.linspace(0.3 * t_end, t_end, 800)  # after the damper's relative motion (rate ~ c / J) has decayed
    sol = solve_ivp(lambda t, y: model.rhs(y), (0, t_end), y0, method="DOP853", rtol=1e-11, atol=1e-16, t_eval=t)
    assert sol.success
    norm = model.transverse_norm(sol.y.T, 3, 1.0)
    measured = np.polyfit(t, np.log(norm), 1)[0]
    assert measured == pytest.approx(rate, rel=1e-3)
    assert norm[-1] < 1e-2


def test_damper_transverse_and_equilibrium():
    model = Damper((2.0, 2.5, 1.0), 0.1, 0.01)
    y = model.equilibrium(2, np.array([1.0, -3.0]))
    assert np.array_equal(y, [[0, 1.0, 0, 0, 1.0, 0], [0, -3.0, 0, 0, -3.0, 0]])
    assert np.array_equal(model.rhs(y), np.zeros((2, 6)))
    t = model.transverse(2)
    assert t.columns.tolist() == [2, 0] and t.centre is None
    assert np.array_equal(model.transverse_norm(y, 2), [0.0, 0.0])
    lm = np.array([0.0, 0.0, 2.2])
    assert np.allclose(model.angular_velocity(lm), [0.0, 0.0, 2.0])
