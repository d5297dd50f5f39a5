"""Chaos indicators: ``tumble.lyapunov``, ``tumble.megno`` and ``tumble.gali`` (issue 41), in layers.

Exact cases first (a linear system ``y' = A y``: the real parts of eig(A); the sum of the exponents is trace A at any
horizon), then the rigid bodies' properties (a conservative system's exponents sum to zero and pair up; an integrable
one's largest decays like ln T / T; at a steady spin about the intermediate axis the finite-time exponent is the linear
growth rate), independence of the renormalisation interval, an independent reference (SciPy's DOP853 at rtol 1e-12 on
the state and the variational equations, QR every second) for a chaotic heavy top, MEGNO (2 on a quasi-periodic orbit,
growing on a chaotic one, the early stop), GALI (falling exponentially on a chaotic orbit only), the device (numba-cuda's simulator: the CPU's numbers), and every bad input
of issue 41 item 6 as one line.
"""

import importlib.util
import math
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import tumble
from tumble.engine.chaos import STATUS_ABOVE_NAME, initial_tangents
from tumble.kernels.loops import sample_loop
from tumble.kernels.loops.tangent_loop import WORK_EXTRA, difference_tangents
from tumble.registry import STATUS_ABOVE

import hand_written_systems
from tumble.registry import STATUS_NAMES, STATUS_NONFINITE, STATUS_OK

# One worker compiles each system's tangent loop once (pyproject's --dist loadgroup).
pytestmark = pytest.mark.xdist_group("chaos")


def linear(t, y, p, dydt):
    """``y' = A y`` with ``A`` (3, 3) row by row in ``p``."""
    for i in range(3):
        total = 0.0
        for j in range(3):
            total += p[3 * i + j] * y[j]
        dydt[i] = total


def linear_jacobian(t, y, p, J):
    for i in range(3):
        for j in range(3):
            J[i, j] = p[3 * i + j]


LINEAR = tumble.System(linear, state=("x1", "x2", "x3"), jacobian=linear_jacobian, name="linear",
                       parameters={f"a{i}{j}": float(i == j) for i in range(1, 4) for j in range(1, 4)})


def linear_scalar(t, y, p, dydt):
    """:func:`linear` written out term by term: the scalar form that runs on the vectorised blocks (its kernels cached
    on disk), where :data:`LINEAR`'s loops run one sample at a time, compiled in every process."""
    dydt[0] = p[0] * y[0] + p[1] * y[1] + p[2] * y[2]
    dydt[1] = p[3] * y[0] + p[4] * y[1] + p[5] * y[2]
    dydt[2] = p[6] * y[0] + p[7] * y[1] + p[8] * y[2]


def linear_jacobian_scalar(t, y, p, J):
    J[0, 0], J[0, 1], J[0, 2] = p[0], p[1], p[2]
    J[1, 0], J[1, 1], J[1, 2] = p[3], p[4], p[5]
    J[2, 0], J[2, 1], J[2, 2] = p[6], p[7], p[8]


LINEAR_BLOCKS = tumble.System(linear_scalar, state=("x1", "x2", "x3"), jacobian=linear_jacobian_scalar, name="linear",
                              parameters=LINEAR.parameters)


def _matrix(A):
    return {f"a{i + 1}{j + 1}": float(A[i, j]) for i in range(3) for j in range(3)}


BODY = tumble.Body(1.0, 2.0, 3.0)
#: An asymmetric heavy top, its centre of mass off the principal axes: not integrable.
TOP = tumble.models.HeavyTop((1.0, 1.6, 2.2), 1.0, centre=(0.6, 0.3, 1.0))
#: A chaotic release of TOP (<Y> ~ 16 at T = 200, lambda_1 ~ 0.1 1/s) and a regular one (<Y> ~ 1.6).
CHAOTIC = np.array([0.04071382, 0.0164995, -0.85749567, 0.35671917, -0.78540276, 0.5058596])
REGULAR = np.array([0.5, 0.3, 2.0, 0.3, 0.1, 1.0])
CHAOTIC[3:] /= np.linalg.norm(CHAOTIC[3:])
REGULAR[3:] /= np.linalg.norm(REGULAR[3:])
#: The Lagrange top: symmetric, the centre of mass on the symmetry axis (integrable).
LAGRANGE = tumble.models.HeavyTop((1.0, 1.0, 2.0), 1.0)


# --- exact cases ----------------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_a_symmetric_linear_system_gives_the_eigenvalues_of_its_matrix():
    rng = np.random.default_rng(7)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    eigenvalues = np.array([0.5, -0.2, -1.0])
    A = Q @ np.diag(eigenvalues) @ Q.T
    ds = tumble.lyapunov(LINEAR, np.zeros(3), 60.0, 0.01, transient=30.0, parameters=_matrix(A))
    np.testing.assert_allclose(ds["exponent"].values[0], eigenvalues, rtol=0, atol=1e-6)
    assert list(ds["index"].values) == [1, 2, 3] and ds["exponent"].attrs["units"] == "1/s"
    assert ds.attrs["method"] == "rk4" and ds.attrs["dt"] == 0.01 and ds.attrs["transient"] == 30.0
    assert ds.attrs["renormalise"] == 1.0 and ds["status"].values[0] == STATUS_OK


@pytest.mark.slow
@pytest.mark.parametrize("t_end", [0.5, 7.0])
def test_the_exponents_of_a_non_normal_linear_system_sum_to_its_trace_at_any_horizon(t_end):
    A = np.array([[0.3, 5.0, -2.0], [0.0, -0.1, 4.0], [0.2, 0.0, -0.7]])
    ds = tumble.lyapunov(LINEAR, [[0.1, 0.2, 0.3]], t_end, 0.01, renormalise=0.5, parameters=_matrix(A))
    assert abs(ds["exponent"].values.sum() - np.trace(A)) < 1e-6


@pytest.mark.slow
def test_the_implicit_midpoint_rules_exponents_are_those_of_its_own_map():
    """The rule's map of ``y' = A y`` is the Cayley transform ``(I - h A/2)^-1 (I + h A/2)``: with orthogonal
    eigenvectors its exponents are ``log |(1 + h λ/2) / (1 - h λ/2)| / h`` (λ to O(h²)), and for any A they sum to
    the log of its determinant over h, at any horizon: the tangent is the derivative of the method's map."""
    h = 0.01
    Q, _ = np.linalg.qr(np.random.default_rng(7).standard_normal((3, 3)))
    eigenvalues = np.array([0.5, -0.2, -1.0])
    ds = tumble.lyapunov(LINEAR, np.zeros(3), 60.0, h, transient=30.0, method="implicit_midpoint",
                         parameters=_matrix(Q @ np.diag(eigenvalues) @ Q.T))
    cayley = np.log(np.abs((1 + h * eigenvalues / 2) / (1 - h * eigenvalues / 2))) / h
    np.testing.assert_allclose(ds["exponent"].values[0], cayley, rtol=0, atol=1e-12)
    assert ds.attrs["method"] == "implicit_midpoint" and ds["status"].values[0] == STATUS_OK
    A = np.array([[0.3, 5.0, -2.0], [0.0, -0.1, 4.0], [0.2, 0.0, -0.7]])
    ds = tumble.lyapunov(LINEAR, [[0.1, 0.2, 0.3]], 7.0, h, renormalise=0.5, method="implicit_midpoint",
                         parameters=_matrix(A))
    eigenvalues = np.linalg.eigvals(A)
    determinant = np.sum(np.log(np.abs((1 + h * eigenvalues / 2) / (1 - h * eigenvalues / 2)))) / h
    assert abs(ds["exponent"].values.sum() - determinant) < 1e-12


@pytest.mark.slow
def test_the_implicit_midpoint_rule_gives_rk4s_exponents_and_megno_of_a_chaotic_top():
    states = [CHAOTIC, REGULAR]
    midpoint = tumble.lyapunov(TOP, states, 10.0, 0.002, method="implicit_midpoint")
    rk4 = tumble.lyapunov(TOP, states, 10.0, 0.002)
    np.testing.assert_allclose(midpoint["exponent"].values, rk4["exponent"].values, rtol=0, atol=1e-5)
    # the top's rate has no divergence, but the midpoint map keeps volume only to O(h^3) a step (its determinant is
    # exp(h^3 tr J^3 / 12 + ...)): the sum is h^2 <tr J^3> / 12, a few 1e-9 here (rk4's: 1e-15)
    assert np.all(np.abs(midpoint["exponent"].values.sum(axis=1)) < 1e-7)
    midpoint = tumble.megno(TOP, states, 30.0, 0.005, method="implicit_midpoint")
    rk4 = tumble.megno(TOP, states, 30.0, 0.005)
    np.testing.assert_allclose(midpoint["megno"].values, rk4["megno"].values, rtol=1e-3)


SPLITTINGS = ("symplectic_euler", "splitting2", "splitting4")


@pytest.mark.parametrize("method", SPLITTINGS)
@pytest.mark.parametrize("model, y0", [
    (tumble.models.FreeBody((1.0, 2.0, 3.0)), [0.3, 1.0, 0.2]),
    (tumble.models.Gyrostat((1.0, 2.0, 3.0), (0.1, -0.2, 0.4)), [0.3, 1.0, 0.2]),
    (TOP, CHAOTIC),
    (LAGRANGE, REGULAR),
], ids=["free", "gyrostat", "heavy_top", "lagrange"])
def test_a_splittings_tangent_is_the_derivative_of_its_map(model, y0, method):
    """The tangent of one splitting step (each exact sub-flow's derivative, composed) against a fourth-order central
    difference of the same step's map, at a step long enough that the map is far from the identity."""
    from tumble.kernels import rate_sample_parameters
    from tumble.kernels.steps.model_splittings import SPLITTINGS as CODES, splitting_tangent_sample

    p = rate_sample_parameters(model.kind, model.moments, model.parameters)
    y = np.array(y0, dtype=float)
    n, h, e = len(y), 0.3, 1e-4

    def step(x):
        x = x.copy()
        splitting_tangent_sample(CODES[method], x, np.zeros((0, n)), p, h)
        return x

    state, jacobian = y.copy(), np.eye(n)
    splitting_tangent_sample(CODES[method], state, jacobian, p, h)  # rows: the derivative along each unit vector
    np.testing.assert_array_equal(state, step(y))  # the tangent leaves the state's bits alone
    for j in range(n):
        v = np.eye(n)[j]
        difference = (8.0 * (step(y + e * v) - step(y - e * v)) - (step(y + 2 * e * v) - step(y - 2 * e * v))) / (
            12.0 * e)
        np.testing.assert_allclose(jacobian[j], difference, rtol=0, atol=1e-9)
    assert abs(np.linalg.det(jacobian) - 1.0) < 1e-12  # every sub-flow keeps volume


def test_the_splittings_exponents_are_rk4s_sum_to_zero_and_their_megno_agrees():
    """splitting4 and rk4 at the same small step give the same spectrum of a chaotic top and of the free body; the
    splittings' maps keep volume exactly, so their exponents sum to zero to round-off (rk4's: to its error)."""
    states = [CHAOTIC, REGULAR]
    rk4 = tumble.lyapunov(TOP, states, 10.0, 0.002)
    for method, tolerance in (("splitting4", 1e-6), ("splitting2", 1e-3)):
        split = tumble.lyapunov(TOP, states, 10.0, 0.002, method=method)
        assert split.attrs["method"] == method and np.all(split["status"].values == STATUS_OK)
        np.testing.assert_allclose(split["exponent"].values, rk4["exponent"].values, rtol=0, atol=tolerance)
        assert np.all(np.abs(split["exponent"].values.sum(axis=1)) < 1e-13)
    body = tumble.lyapunov(BODY, [[0.0, 1.0, 1e-3]], 15.0, 0.01, transient=5.0, method="splitting4")
    np.testing.assert_allclose(body["exponent"].values,
                               tumble.lyapunov(BODY, [[0.0, 1.0, 1e-3]], 15.0, 0.01, transient=5.0)["exponent"].values,
                               rtol=0, atol=1e-7)
    split = tumble.megno(TOP, states, 30.0, 0.005, method="splitting4")
    np.testing.assert_allclose(split["megno"].values, tumble.megno(TOP, states, 30.0, 0.005)["megno"].values,
                               rtol=1e-3)


# --- the rigid bodies -----------------------------------------------------------------------------------------------

def test_a_steady_spin_about_the_intermediate_axis_grows_at_the_linear_rate():
    kind, rate = tumble.theory.linear(BODY, 2, 1.5)
    assert kind == "exponential"
    ds = tumble.lyapunov(BODY, [0.0, 1.5, 0.0], 12.0, 0.01, transient=4.0, save_every=100)
    assert abs(ds["exponent"].values[0, 0] / rate - 1) < 0.03
    assert abs(ds["exponent"].values[0, 2] / rate + 1) < 0.03  # and the stable direction at minus it
    finite_time = ds["finite_time"].values[0, :, 0]  # every second past the transient, converging
    assert ds["time"].values[0] == 5.0 and ds["time"].values[-1] == 12.0
    assert abs(finite_time[-1] / rate - 1) < abs(finite_time[0] / rate - 1) + 1e-12


def test_a_body_and_its_three_moments_are_the_free_body():
    spins = [[0.3, 1.0, 0.1]]
    by_body = tumble.lyapunov(BODY, spins, 5.0, 0.01)
    by_moments = tumble.lyapunov((1.0, 2.0, 3.0), spins, 5.0, 0.01)
    by_model = tumble.lyapunov(tumble.models.FreeBody((1.0, 2.0, 3.0)), spins, 5.0, 0.01)
    np.testing.assert_array_equal(by_body["exponent"].values, by_moments["exponent"].values)
    np.testing.assert_array_equal(by_body["exponent"].values, by_model["exponent"].values)
    assert by_body.attrs["system"] == "free"


def test_the_free_bodys_exponents_sum_to_zero_pair_up_and_decay_like_log_t_over_t():
    spins = [[0.3, 1.0, 0.1], [1.0, 0.2, 0.4]]
    largest = []
    for t_end in (100.0, 1000.0):
        exponents = tumble.lyapunov(BODY, spins, t_end, 0.01)["exponent"].values
        np.testing.assert_allclose(exponents.sum(axis=1), 0.0, atol=1e-8)
        assert np.all(np.abs(exponents[:, 0] + exponents[:, 2]) <= np.abs(exponents[:, 1]) + 1e-8)  # (l, ~0, -l)
        assert np.all(exponents[:, 0] < 2 * math.log(t_end) / t_end)
        largest.append(exponents[:, 0])
    assert np.all(largest[1] < largest[0] / 4)


def test_the_lagrange_tops_exponents_sum_to_zero_and_decay_like_log_t_over_t():
    largest = []
    for t_end in (100.0, 1000.0):
        exponents = tumble.lyapunov(LAGRANGE, REGULAR, t_end, 0.01)["exponent"].values[0]
        assert abs(exponents.sum()) < 1e-8
        assert np.all(np.abs(exponents + exponents[::-1]) < 0.5 * exponents[0])  # pairs, within their O(1/T)
        assert exponents[0] < 2 * math.log(t_end) / t_end
        largest.append(exponents[0])
    assert largest[1] < largest[0] / 4


def test_the_kovalevskaya_top_is_regular_megno_near_two_and_its_exponent_falling_like_log_t_over_t():
    """The Kovalevskaya top (I1 = I2 = 2 I3, the centre of mass in the equatorial plane) is integrable: a generic
    release is quasi-periodic, <Y> near 2 and lambda_1 below 1.5 ln T / T, falling with the horizon."""
    kovalevskaya = tumble.models.HeavyTop((2.0, 2.0, 1.0), 1.0, centre=(1.0, 0.0, 0.0))
    y0 = _unit_tail([0.7, -0.2, 1.3, 0.3, -0.4, 0.8])
    largest = []
    for t_end in (100.0, 400.0):
        exponent = tumble.lyapunov(kovalevskaya, y0, t_end, 0.01, exponents=1)["exponent"].values[0, 0]
        assert exponent < 1.5 * math.log(t_end) / t_end
        largest.append(exponent)
    assert largest[1] < largest[0] / 2
    assert 1.5 < tumble.megno(kovalevskaya, y0, 400.0, 0.01)["megno"].values[0] < 2.5


@pytest.mark.parametrize("model, y0", [
    (tumble.models.FreeBody((1.0, 2.0, 3.0)), [0.3, 1.0, 0.2]),
    (tumble.models.Gyrostat((1.0, 2.0, 3.0), (0.1, -0.2, 0.4)), [0.3, 1.0, 0.2]),
    (tumble.models.HeavyTop((1.0, 1.6, 2.2), 1.0, centre=(0.6, 0.3, 1.0)), [0.5, 0.3, 2.0, 0.3, 0.1, 1.0]),
    (tumble.models.GravityGradient((1.0, 2.0, 3.0), 1.0, eccentricity=0.3), [0.2, -1.1, 0.1, 1.0, 0.1, 0.2, 0.05]),
    (tumble.models.Damper((1.0, 2.0, 3.0), 0.5, 0.3), [0.3, 1.0, 0.2, 0.1, 0.0, -0.1]),
], ids=lambda value: getattr(value, "kind", ""))
def test_each_models_tangent_is_the_central_difference_of_its_rate(model, y0):
    """The kernels' tangent flow ``J(t, y) v`` of each built-in model (what the chaos indicators step) against a
    fourth-order central difference of the kernels' own rate along ``v``, at a time inside the eccentric orbit."""
    from tumble.kernels import rate_sample, rate_sample_parameters, tangent_sample

    p = rate_sample_parameters(model.kind, model.moments, model.parameters)
    y = np.array(y0, dtype=float)
    t = 0.37
    rng = np.random.default_rng(3)
    for _ in range(5):
        v = rng.standard_normal(len(y))
        tangent = np.empty(len(y))
        tangent_sample(t, y, v, p, tangent)
        rates = []
        for shift in (1e-4, -1e-4, 2e-4, -2e-4):
            out = np.empty(len(y))
            rate_sample(t, y + shift * v, p, out)
            rates.append(out)
        difference = (8.0 * (rates[0] - rates[1]) - (rates[2] - rates[3])) / (12.0 * 1e-4)
        np.testing.assert_allclose(tangent, difference, rtol=1e-9, atol=1e-9 * np.abs(tangent).max())


def test_a_chaotic_tops_exponents_sum_to_zero_and_come_in_plus_minus_pairs():
    exponents = tumble.lyapunov(TOP, CHAOTIC, 400.0, 0.01)["exponent"].values[0]
    assert abs(exponents.sum()) < 1e-8
    assert exponents[0] > 0.05  # chaotic: well above ln T / T = 0.015
    assert abs(exponents[0] + exponents[5]) < 0.02 * exponents[0]
    assert np.all(np.abs(exponents[1:5]) < 0.2 * exponents[0])  # the integrals' and the flow's directions: ~0


def _unit_tail(y):
    """``y`` with its components after the angular velocity (an up vector, a quaternion) made a unit vector."""
    y = np.array(y, float)
    y[3:] /= np.linalg.norm(y[3:])
    return y


@pytest.mark.parametrize("model, y0", [
    (tumble.models.Gyrostat((1.0, 2.0, 3.0), (0.1, -0.2, 0.4)), [0.3, 1.0, 0.2]),
    (tumble.models.GravityGradient((1.0, 2.0, 3.0), 1.0, eccentricity=0.3), _unit_tail([0.2, -1.1, 0.1, 1.0,
                                                                                               0.1, 0.2, 0.05])),
    (tumble.models.Damper((1.0, 2.0, 3.0), 0.5, 0.3), [0.3, 1.0, 0.2, 0.1, 0.0, -0.1]),
    (TOP, CHAOTIC),
], ids=["gyrostat", "gravity_gradient_eccentric", "damper", "heavy_top"])
def test_every_built_in_models_exponents_sum_to_the_time_average_of_trace_j(model, y0):
    """Liouville: the whole spectrum sums to the mean divergence of the flow, which is constant for these models (0
    but for the damper's dissipation), at any horizon."""
    trace = np.trace(model.jacobian(np.array(y0)))
    exponents = tumble.lyapunov(model, y0, 20.0, 0.01)["exponent"].values[0]
    assert abs(exponents.sum() - trace) < 1e-8 * max(1.0, abs(trace))
    assert np.all(np.isfinite(exponents)) and np.all(np.diff(exponents) <= 0)


def test_the_exponents_do_not_depend_on_how_often_the_tangents_are_renormalised():
    a = tumble.lyapunov(TOP, [CHAOTIC, REGULAR], 60.0, 0.01, renormalise=0.25)["exponent"].values
    b = tumble.lyapunov(TOP, [CHAOTIC, REGULAR], 60.0, 0.01, renormalise=4.0)["exponent"].values
    np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8 * np.abs(a).max())


def test_the_first_exponents_alone_are_those_of_the_whole_spectrum():
    whole = tumble.lyapunov(TOP, CHAOTIC, 30.0, 0.01)
    two = tumble.lyapunov(TOP, CHAOTIC, 30.0, 0.01, exponents=2)
    assert two["exponent"].shape == (1, 2) and list(two["index"].values) == [1, 2]
    # the first k Gram-Schmidt vectors start and evolve as in the whole set: the same sums, to round-off (both sorted
    # descending, so two distinct exponents of the whole spectrum; the first its largest, the second's finite-time sum
    # at 30 s not yet its second largest)
    matches = [int(np.argmin(np.abs(whole["exponent"].values[0] - value))) for value in two["exponent"].values[0]]
    np.testing.assert_allclose(two["exponent"].values[0], whole["exponent"].values[0, matches], rtol=0, atol=1e-12)
    assert matches[0] == 0 and len(set(matches)) == 2


def _reference(model, y0, t_end, every=1.0):
    """Benettin's method on SciPy: DOP853 at rtol 1e-12 on the state and the variational equations (the physics
    layer's numpy Jacobian), QR every ``every`` s, from tumble's initial tangent vectors."""
    n = len(y0)

    def f(t, z):
        y, V = z[:n], z[n:].reshape(n, n)
        return np.concatenate([model.rhs(y), (model.jacobian(y) @ V).ravel()])

    y, V, logs = np.array(y0, float), initial_tangents(n, n).T, np.zeros(n)
    for _ in range(round(t_end / every)):
        z = solve_ivp(f, (0.0, every), np.concatenate([y, V.ravel()]), method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        y = z[:n]
        q, r = np.linalg.qr(z[n:].reshape(n, n))
        logs += np.log(np.abs(np.diag(r)))
        V = q * np.sign(np.diag(r))
    return np.sort(logs / t_end)[::-1]


def test_the_spectrum_of_a_chaotic_top_agrees_with_scipys_dop853_and_the_variational_equations():
    reference = _reference(TOP, CHAOTIC, 30.0)
    got = tumble.lyapunov(TOP, CHAOTIC, 30.0, 0.005)["exponent"].values[0]
    np.testing.assert_allclose(got, reference, rtol=0, atol=1e-8 * reference[0] + 1e-10)


def _top_parameters(model):
    return dict(zip(("I1", "I2", "I3"), model.moments), mgl=model.mgl, **dict(zip(("c1", "c2", "c3"), model.centre)))


def test_a_system_without_a_jacobian_differentiates_its_rate_to_round_off():
    """The directional derivative by extrapolated central differences against the physics layer's Jacobian."""
    rate = sample_loop.compile_function(hand_written_systems.heavy_top, sample_loop.RATE_SIGNATURE, "test", "rate")
    tangents = difference_tangents(rate)
    p = np.array(list(_top_parameters(TOP).values()) + [1.0] * 6)  # the parameters, then the components' scales
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(20):
        y = rng.standard_normal(6) * rng.choice([1e-3, 1.0, 30.0])
        V = rng.standard_normal((6, 6)) * rng.choice([1e-6, 1.0, 1e6])
        out, work = np.empty((6, 6)), np.empty((6 + WORK_EXTRA, 6))
        tangents(0.0, y, V, p, out, work)
        exact = V @ TOP.jacobian(y).T
        worst = max(worst, np.abs(out - exact).max() / np.abs(exact).max())
    assert worst < 1e-10


def test_a_system_without_a_jacobian_gives_the_built_in_models_exponents():
    by_hand = tumble.lyapunov(hand_written_systems.HEAVY_TOP, CHAOTIC, 30.0, 0.01, parameters=_top_parameters(TOP))
    built_in = tumble.lyapunov(TOP, CHAOTIC, 30.0, 0.01)
    assert by_hand.attrs["tangent"] == "differences" and built_in.attrs["tangent"] == "generated"
    np.testing.assert_allclose(by_hand["exponent"].values, built_in["exponent"].values, rtol=0,
                               atol=1e-9 * built_in["exponent"].values.max())


rotor, ROTOR = hand_written_systems.rotor, hand_written_systems.ROTOR
ROTOR_EXACT = tumble.System(rotor, state=("theta", "omega"), parameters=ROTOR,
                            jacobian=hand_written_systems.rotor_jacobian, name="rotor")
ROTOR_DIFFERENCES = tumble.System(rotor, state=("theta", "omega"), parameters=ROTOR, name="rotor")


@pytest.mark.parametrize("theta", [0.0, 1e4])
def test_difference_tangents_step_by_the_components_scale_not_by_the_size_of_the_state(theta):
    """An angle of 1e4 rad varies its sine on the scale 1: the exponents of the differences are those of the exact
    Jacobian (a step that grew with |y| would be 10 rad there)."""
    exact = tumble.lyapunov(ROTOR_EXACT, [theta, 2.0], 50.0, 0.01)["exponent"].values
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing to warn of: the differences are vouched for
        by_differences = tumble.lyapunov(ROTOR_DIFFERENCES, [theta, 2.0], 50.0, 0.01)["exponent"].values
    np.testing.assert_allclose(by_differences, exact, rtol=0, atol=1e-8)


def test_a_difference_tumble_cannot_vouch_for_is_one_warning():
    # a scale far larger than the one the rate varies on: the difference changes with a shorter step
    coarse = tumble.System(rotor, state=("theta", "omega"), parameters=ROTOR, name="rotor", scale=[1e3, 1e3])
    with pytest.warns(RuntimeWarning, match=r"system 'rotor' has no jacobian, and its difference tangent at the first "
                                            r"state changes by .* with a step four times shorter"):
        tumble.megno(coarse, [0.0, 2.0], 0.1, 0.01)
    # an angle that turns to 1e9 rad: beyond its scale, where rounding y + e v dominates
    spinning = tumble.System(rotor, state=("theta", "omega"), parameters={"k": 0.0, "c": 0.0, "a": 0.0, "w": 0.0},
                             name="spinner")
    with pytest.warns(RuntimeWarning, match=r"'theta' reached 1.0e\+09 times its scale 1, where a difference is "
                                            r"accurate to about .* relative only"):
        tumble.megno(spinning, [0.0, 1e9], 1.0, 0.01)


def test_the_first_tangent_vectors_are_orthonormal_and_far_from_every_coordinate_axis():
    diagonal_angles = []
    for n in range(2, 13):
        vectors = initial_tangents(n, n)
        np.testing.assert_allclose(vectors @ vectors.T, np.eye(n), atol=1e-14)
        axis_angle = np.degrees(np.arccos(np.max(np.abs(vectors))))
        assert axis_angle > 33.0, n
        diagonal_angles.append(np.degrees(np.arccos(np.max(np.abs(vectors.sum(axis=1))) / math.sqrt(n))))
        np.testing.assert_array_equal(initial_tangents(n, 2), vectors[:2])
    assert min(diagonal_angles) > 4.0  # nor along (1, ..., 1), the synchronised motion of identical units


def pendulum(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * math.sin(y[0])


def pendulum_jacobian(t, y, p, J):
    J[0, 0], J[0, 1] = 0.0, 1.0
    J[1, 0], J[1, 1] = -p[0] * math.cos(y[0]), 0.0


PENDULUM = tumble.System(pendulum, state=("x", "v"), parameters={"k": 1.0}, jacobian=pendulum_jacobian,
                         name="pendulum")


def test_a_regular_orbit_from_a_symmetric_start_reads_megno_two_and_a_tangent_along_the_flow_does_not_grow():
    """At x = 0 the first coordinate axis is the flow's own direction (a phase shift): a vector near it would read
    <Y> near 1 by T = 1e3, where a generic one tends to 2 on a torus."""
    assert tumble.megno(PENDULUM, [0.0, 1.0], 1000.0, 0.01)["megno"].values[0] == pytest.approx(2.0, abs=0.25)
    along_the_flow = tumble.megno(PENDULUM, [0.0, 1.0], 1000.0, 0.01, tangent=[3.0, 0.0])["megno"].values[0]
    assert abs(along_the_flow) < 0.01  # a periodic orbit's own direction does not grow


def test_given_tangent_vectors_are_those_a_run_starts_from():
    default = tumble.lyapunov(LINEAR_BLOCKS, [1.0, 0.0, 0.0], 1.0, 0.01, exponents=2)
    given = tumble.lyapunov(LINEAR_BLOCKS, [1.0, 0.0, 0.0], 1.0, 0.01, tangent=2.0 * initial_tangents(3, 2))
    np.testing.assert_allclose(given["exponent"].values, default["exponent"].values, rtol=1e-14)
    A = np.diag([0.5, 0.2, -1.0])  # a vector in the slow eigenspace reads the slow exponent only
    slow = tumble.lyapunov(LINEAR_BLOCKS, [0.0, 0.0, 0.0], 4.0, 0.01, tangent=[0.0, 1.0, 0.0], parameters=_matrix(A))
    assert slow["exponent"].values[0] == pytest.approx([0.2], rel=1e-9)
    gali = tumble.gali(LINEAR_BLOCKS, [0.0, 0.0, 0.0], 1.0, 0.01, tangent=[[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
                       parameters=_matrix(np.zeros((3, 3))))
    assert gali["gali"].values[0, -1] == pytest.approx(math.sqrt(0.5), rel=1e-12)  # unit, not orthogonalised


# --- MEGNO ----------------------------------------------------------------------------------------------------------

def test_megno_tends_to_two_on_a_quasi_periodic_orbit_of_the_free_body():
    ds = tumble.megno(BODY, [[0.3, 1.0, 0.1], [1.0, 0.2, 0.4]], 2000.0, 0.01)
    np.testing.assert_allclose(ds["megno"].values, 2.0, atol=0.1)
    assert np.all(np.abs(ds["lyapunov"].values) < 2e-3)
    assert list(ds["status"].values) == [STATUS_OK] * 2 and np.all(ds["time_run"].values == 2000.0)


def test_megno_grows_on_a_chaotic_orbit_and_its_slope_gives_the_exponent():
    short = tumble.megno(TOP, [CHAOTIC, REGULAR], 100.0, 0.01)
    long = tumble.megno(TOP, [CHAOTIC, REGULAR], 200.0, 0.01)
    assert long["megno"].values[0] > 1.5 * short["megno"].values[0] > 8
    assert long["megno"].values[1] < 2.5
    largest = tumble.lyapunov(TOP, CHAOTIC, 200.0, 0.01, exponents=1)["exponent"].values[0, 0]
    assert abs(long["lyapunov"].values[0] / largest - 1) < 0.5  # <Y> ~ lambda t / 2


def test_megno_stops_a_sample_above_the_threshold_and_says_so():
    ds = tumble.megno(TOP, [CHAOTIC, REGULAR], 200.0, 0.01, stop_above=5.0)
    assert list(ds["status"].values) == [STATUS_ABOVE, STATUS_OK]
    assert 5.0 < ds["megno"].values[0] < 5.5 and ds["time_run"].values[0] < 200.0
    assert ds["time_run"].values[1] == 200.0
    meanings = ds["status"].attrs["flag_meanings"].split()
    assert meanings[STATUS_ABOVE] == STATUS_ABOVE_NAME.replace(" ", "_") and len(meanings) == len(STATUS_NAMES) + 1


def test_a_sample_that_becomes_non_finite_stops_with_a_status_not_a_silent_nan():
    A = np.diag([800.0, 0.0, -1.0])  # rk4 steps the state by R(8) = 297 a step: it overflows at 1.25 s
    with pytest.warns(RuntimeWarning, match="1 of 2 samples of linear became non-finite"):
        ds = tumble.lyapunov(LINEAR_BLOCKS, [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]], 3.0, 0.01, renormalise=0.5,
                             parameters=_matrix(A))
    assert list(ds["status"].values) == [STATUS_NONFINITE, STATUS_OK]
    first_second = tumble.lyapunov(LINEAR_BLOCKS, [1.0, 0.0, 0.0], 1.0, 0.01, renormalise=0.5, parameters=_matrix(A))
    # the stopped sample keeps the exponents of the time up to its last renormalisation (1 s)
    np.testing.assert_allclose(ds["exponent"].values[0], first_second["exponent"].values[0], rtol=1e-12)
    assert ds["exponent"].values[0, 0] > 500  # the discrete map's: log R(8) / h of rk4's stability function R
    with pytest.warns(RuntimeWarning, match="1 of 1 samples of linear"):  # exp(800) overflows before a renormalisation
        overflow = tumble.lyapunov(LINEAR_BLOCKS, [0.0, 0.0, 0.0], 3.0, 0.01, renormalise=1.0, parameters=_matrix(A))
    assert overflow["status"].values[0] == STATUS_NONFINITE and np.all(np.isnan(overflow["exponent"].values))
    with pytest.raises(ValueError, match=r"y0 must be finite: sample 0 holds NaN or inf \(x1, x2, x3 = \[nan, 0.0"):
        tumble.lyapunov(LINEAR_BLOCKS, [np.nan, 0.0, 0.0], 1.0, 0.01, parameters=_matrix(A))


@pytest.mark.slow
def test_a_tableau_replaced_under_the_same_name_is_a_new_method(monkeypatch):
    """The kernels are kept with the tableau they were made of: registering another tableau under a name already run
    runs the new coefficients (a System and a built-in model, the tangent loop and integrate's per-sample loop)."""
    from tumble.kernels import TABLEAUX
    from tumble.kernels.tableaux import ButcherTableau

    euler = ButcherTableau.build("custom", 1, [[]], [1.0], [0.0])
    heun = ButcherTableau.build("custom", 2, [[], [1.0]], [0.5, 0.5], [0.0, 1.0])
    A = np.diag([-1.0, 0.0, 0.0])
    for system, y0, parameters in ((LINEAR, [1.0, 0.0, 0.0], _matrix(A)), (TOP, REGULAR, None)):
        results = []
        for tableau in (euler, heun):
            monkeypatch.setitem(TABLEAUX, "custom", tableau)
            results.append((tumble.lyapunov(system, y0, 1.0, 0.1, method="custom", parameters=parameters,
                                            exponents=1)["exponent"].values,
                            tumble.propagate(system, np.atleast_2d(y0), 1.0, 0.1, method="custom",
                                             parameters=parameters)))
        assert not np.array_equal(results[0][0], results[1][0]) and not np.array_equal(results[0][1], results[1][1])
    # y' = -y by Heun: (1 - h + h^2 / 2)^10 at h = 0.1
    np.testing.assert_allclose(tumble.propagate(LINEAR, [[1.0, 0.0, 0.0]], 1.0, 0.1, method="custom",
                                                parameters=_matrix(A))[0, 0], 0.905 ** 10, rtol=1e-14)


# --- GALI -----------------------------------------------------------------------------------------------------------

def test_gali_falls_exponentially_on_a_chaotic_orbit_and_stays_on_a_regular_one():
    ds = tumble.gali(TOP, [CHAOTIC, REGULAR], 200.0, 0.01, save_every=2000)
    assert list(ds["time"].values) == [20.0 * i for i in range(1, 11)] and ds.attrs["k"] == 2
    chaotic, regular = ds["gali"].values
    assert chaotic[-1] < 1e-6 < 1e-2 < regular.min() <= regular.max() <= 1.0
    exponents = tumble.lyapunov(TOP, CHAOTIC, 200.0, 0.01)["exponent"].values[0]
    slope = np.polyfit(ds["time"].values[2:], np.log(chaotic[2:]), 1)[0]
    assert abs(slope / -(exponents[0] - exponents[1]) - 1) < 0.5  # GALI_2 ~ exp(-(l1 - l2) t)
    whole = tumble.gali(TOP, CHAOTIC, 20.0, 0.01, k=6)["gali"].values[0, 0]  # k = n: the tangent map's determinant
    assert 0 < whole < tumble.gali(TOP, CHAOTIC, 20.0, 0.01, k=3)["gali"].values[0, 0] < 1


# --- the device -----------------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_the_device_gives_the_cpus_exponents_and_megno(cuda_device):
    states = [CHAOTIC, REGULAR]
    cpu = tumble.lyapunov(TOP, states, 5.0, 0.01, save_every=100, transient=1.0)
    device = tumble.lyapunov(TOP, states, 5.0, 0.01, save_every=100, transient=1.0, device=cuda_device)
    np.testing.assert_allclose(device["exponent"].values, cpu["exponent"].values, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(device["finite_time"].values, cpu["finite_time"].values, rtol=1e-10, atol=1e-14)
    cpu = tumble.megno(TOP, states, 20.0, 0.01, stop_above=3.0)
    device = tumble.megno(TOP, states, 20.0, 0.01, stop_above=3.0, device=cuda_device)
    for name in ("megno", "lyapunov", "time_run"):
        np.testing.assert_allclose(device[name].values, cpu[name].values, rtol=1e-10, atol=1e-14)
    np.testing.assert_array_equal(device["status"].values, cpu["status"].values)
    A = _matrix(np.array([[0.3, 5.0, -2.0], [0.0, -0.1, 4.0], [0.2, 0.0, -0.7]]))
    cpu = tumble.lyapunov(LINEAR, [[0.1, 0.2, 0.3]], 2.0, 0.01, parameters=A, exponents=2)
    device = tumble.lyapunov(LINEAR, [[0.1, 0.2, 0.3]], 2.0, 0.01, parameters=A, exponents=2, device=cuda_device)
    np.testing.assert_allclose(device["exponent"].values, cpu["exponent"].values, rtol=1e-10)
    assert device.attrs["device"] == "cuda"
    cpu = tumble.gali(TOP, states, 5.0, 0.01, save_every=100)
    device = tumble.gali(TOP, states, 5.0, 0.01, save_every=100, device=cuda_device)
    np.testing.assert_allclose(device["gali"].values, cpu["gali"].values, rtol=1e-10)
    by_hand = hand_written_systems.HEAVY_TOP, CHAOTIC, 2.0, 0.01  # no jacobian: the differences on the device too
    cpu = tumble.lyapunov(*by_hand, parameters=_top_parameters(TOP))
    device = tumble.lyapunov(*by_hand, parameters=_top_parameters(TOP), device=cuda_device)
    np.testing.assert_allclose(device["exponent"].values, cpu["exponent"].values, rtol=1e-10)
    for system, kwargs in ((TOP, {}), (by_hand[0], dict(parameters=_top_parameters(TOP)))):  # the midpoint rule
        cpu = tumble.megno(system, states, 2.0, 0.01, method="implicit_midpoint", **kwargs)
        device = tumble.megno(system, states, 2.0, 0.01, method="implicit_midpoint", device=cuda_device, **kwargs)
        np.testing.assert_allclose(device["megno"].values, cpu["megno"].values, rtol=1e-10)
    cpu = tumble.lyapunov(TOP, states, 2.0, 0.01, method="splitting4")  # a splitting's sub-flows and their derivatives
    device = tumble.lyapunov(TOP, states, 2.0, 0.01, method="splitting4", device=cuda_device)
    np.testing.assert_allclose(device["exponent"].values, cpu["exponent"].values, rtol=1e-10, atol=1e-14)


_PTX = """
import sys, types as pytypes
from numba import cuda, types
from numba.cuda.cudadrv import nvvm
if not nvvm.is_available():
    print("no NVVM"); sys.exit(0)
# No driver here: the device functions' compute capability is given, as a GPU's would be (an H100/H200's).
sys.modules[cuda.jit.__module__.rsplit(".", 1)[0] + ".dispatcher"].get_current_device = (
    lambda: pytypes.SimpleNamespace(compute_capability=(9, 0)))
sys.path.insert(0, "tests")
from tumble.engine import chaos
from tumble.kernels import device_tangent_loop
from test_chaos import TOP, LINEAR
f, i = types.float64, types.int64
A1, A2, A3 = (types.Array(f, d, "C") for d in (1, 2, 3))
# (y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved, megno, status,
#  steps_taken), as tumble.kernels.cuda.tangent_flow.run launches it
signature = (A2, A3, A1, f, f, i, i, i, i, f, types.boolean, A2, A3, A2, types.Array(types.int8, 1, "C"),
             types.Array(i, 1, "C"))
for system, method in ((TOP, "rk4"), (LINEAR, "rk4"), (TOP, "splitting4")):
    _, p, _ = chaos._parameters(system, None)
    n, n_p = len(system.spec.state), len(p)
    kernels = chaos._kernels(system, method)
    kernel = device_tangent_loop().make_kernel(kernels.run_sample, n, n, kernels.stages, n_p)
    ptx, _ = cuda.compile_ptx(kernel.py_func, signature, cc=(9, 0))
    assert ".entry" in ptx
print("compiled")
"""


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("nvidia") is None, reason="no NVVM wheel (pip install nvidia-nvvm "
                    "nvidia-cuda-nvrtc-cu12, or the gpu extra)")
def test_the_device_kernel_compiles_for_a_gpu():
    """The simulator runs the kernel's body as Python: numba-cuda's own compiler is what a GPU would run (a local
    array's shape must be constants, ...). Compiled to PTX for sm_90 without a driver, where NVVM is installed."""
    done = subprocess.run([sys.executable, "-c", _PTX], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NUMBA_ENABLE_CUDASIM": "0"}, cwd=os.path.dirname(os.path.dirname(__file__)))
    if "no NVVM" in done.stdout:
        pytest.skip("numba-cuda's NVVM is not installed")
    assert done.returncode == 0 and "compiled" in done.stdout, done.stderr[-3000:]


# --- bad input: one line each (issue 41 item 6) ---------------------------------------------------------------------

def _no_jacobian(t, y, p, dydt):
    dydt[0] = y[0]


@pytest.mark.parametrize("call, message", [
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, exponents=4),
     r"exponents must be None or an integer from 1 to 3 \(the state of the free model has 3 components: w1, w2, w3\)"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, exponents=0), "exponents must be None or an integer"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, renormalise=0.015),
     r"renormalise must be a positive multiple of the step 0.01 s: .* got 0.015 s \(1.5 steps\)"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.3, renormalise=0.6),
     r"renormalise must be a positive multiple of the step 0.25 s \(dt = 0.3 s shortened so that whole steps end at "
     r"t_end\): .* got 0.6 s \(2.4 steps\)"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, renormalise=-1.0), "renormalise must be a positive"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, transient=1.0),
     r"transient must be >= 0 s and less than t_end = 1 s"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 0.0, 0.01), r"t_end must be > 0 s"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, -0.01), r"dt must be > 0 s"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], math.nan, 0.01), r"t_end must be finite"),
    (lambda: tumble.lyapunov(TOP, [[0, 1, 0]], 1.0, 0.01),
     r"y0 must have shape \(N, 6\) with N >= 1 \(w1, w2, w3, g1, g2, g3 of 'heavy_top'\), got shape \(1, 3\)"),
    (lambda: tumble.lyapunov(TOP, [[0, 0, 1, 0, 0, 1], [0, 0, 1, 0, 0.6, 0.7]], 1.0, 0.01),
     r"y0: \(g1, g2, g3\) of a heavy_top model must be a unit vector in every state; sample 1 has norm 0.92"),
    (lambda: tumble.megno(tumble.models.GravityGradient((1.0, 2.0, 3.0), 1.0), [[0, -1, 0, 1, 0, 0, 0.1]], 1.0, 0.01),
     r"y0: \(q0, q1, q2, q3\) of a gravity_gradient model must be a unit vector in every state; sample 0 has norm"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, save_every=0), "save_every must be None or an integer"),
    (lambda: tumble.lyapunov(tumble.models.Damper((1.0, 2.0, 3.0), 0.5, 0.3), [[0, 1, 0, 0, 0, 0]], 1.0, 0.01,
                             method="splitting4"),
     r"method must be one of rk4, .*implicit_midpoint for the damper model \(symplectic_euler, splitting2, "
     r"splitting4: for free, gyrostat, heavy_top only, whose exact sub-flows they compose\), got 'splitting4'"),
    (lambda: tumble.megno(LINEAR, [[0, 1, 0]], 1.0, 0.01, method="splitting2"),
     r"method must be one of rk4, .* for system 'linear' \(.*\), got 'splitting2'"),
    (lambda: tumble.megno(BODY, [[0, 1, 0]], 1.0, 0.01, method="rk5"), r"method must be one of .*got 'rk5'"),
    (lambda: tumble.lyapunov("body", [[0, 1, 0]], 1.0, 0.01), "system must be a tumble.Body"),
    (lambda: tumble.lyapunov((1.0, 2.0, 5.0), [[0, 1, 0]], 1.0, 0.01), "triangle"),
    (lambda: tumble.lyapunov(LINEAR, [[0, 0, 0]], 1.0, 0.01, parameters={"b": 1.0}),
     r"parameters: 'b' is not a parameter of system 'linear'"),
    (lambda: tumble.megno(BODY, [[0, 1, 0]], 1.0, 0.01, stop_above=0.0), "stop_above must be None or a number > 0"),
    (lambda: tumble.megno(BODY, [[0, 1, 0]], 1.0, 0.01, device="tpu"), "device"),
    (lambda: tumble.gali(BODY, [[0, 1, 0]], 1.0, 0.01, k=4), r"k must be an integer from 2 to 3 \(GALI_k"),
    (lambda: tumble.gali(BODY, [[0, 1, 0]], 1.0, 0.01, k=1), "k must be an integer from 2 to 3"),
    (lambda: tumble.lyapunov(BODY, [[0, 1, 0]], 1.0, 0.01, exponents=2, tangent=[1, 0, 0]),
     r"tangent must have shape \(2, 3\): 2 vectors over the 3 components of the free model \(w1, w2, w3\), got "
     r"shape \(3,\)"),
    (lambda: tumble.megno(BODY, [[0, 1, 0]], 1.0, 0.01, tangent=[1, math.nan, 0]), r"tangent must be finite"),
    (lambda: tumble.gali(BODY, [[0, 1, 0]], 1.0, 0.01, tangent=[[1, 2, 0], [2, 4, 0]]),
     r"tangent: the 2 vectors must be independent"),
    (lambda: tumble.megno(BODY, [[0, 1, 0]], 1.0, 0.01, tangent=[0, 0, 0]), r"tangent: the 1 vectors must be indep"),
    (lambda: tumble.megno(TOP, [[0, 0, 1, 0, 0, math.inf]], 1.0, 0.01), r"y0 must be finite: sample 0 holds NaN"),
    (lambda: tumble.System(rotor, state=("theta", "omega"), scale={"phi": 1.0}),
     r"system 'system': scale names 'phi', which is not a component of its state \(theta, omega\)"),
    (lambda: tumble.System(rotor, state=("theta", "omega"), scale=[1.0]), r"scale must have one number per component"),
    (lambda: tumble.System(rotor, state=("theta", "omega"), scale=[1.0, 0.0]), r"scale of 'omega' must be > 0"),
    (lambda: tumble.System(rotor, state=("theta", "omega"), scale=[1.0, math.nan]), r"scale of 'omega' must be finite"),
])
def test_each_bad_input_is_refused_in_one_line(call, message):
    with pytest.raises(ValueError, match=message) as err:
        call()
    assert "\n" not in str(err.value)


def test_a_jacobian_numba_cannot_compile_is_one_line_naming_the_system():
    def bad_jacobian(t, y, p, J):
        J[0, 0] = {"a": 1}

    system = tumble.System(_no_jacobian, state=("x",), jacobian=bad_jacobian, name="uncompilable")
    with pytest.raises(ValueError, match=r"system 'uncompilable': numba cannot compile jacobian\(t, y, p, J\)") as err:
        tumble.lyapunov(system, [[1.0]], 1.0, 0.01)
    assert "\n" not in str(err.value)
