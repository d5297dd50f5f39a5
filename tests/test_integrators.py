"""Fixed-step integrators: coefficients, closed forms, observed order, invariants, agreement, bad input."""

import math

import numba
import numpy as np
import pytest

import tumble
from tumble import registry
from tumble.kernels import tableaux
from tumble.kernels.loops.methods import METHODS, run
from tumble.physics import theory

STEPPING = ["rk4", "rk8", "symplectic_euler", "splitting2", "splitting4", "implicit_midpoint"]

# One compiled driver per method and torque type (tumble.kernels.loops.drivers): each torque case compiles its method's
# driver once. The default run keeps one method per family: a built-in profile with rk4, splitting4
# and implicit_midpoint, a torque function with rk4 and splitting2; the full method x torque matrix runs with
# `-m slow`.
PROFILE_TIER = {"rk4", "splitting4", "implicit_midpoint"}
FUNCTION_TIER = {"rk4", "splitting2"}


def _tiered(method, torque="constant"):
    """``pytest.param`` of a torque case, marked slow outside the default tier."""
    tier = FUNCTION_TIER if torque == "function" else PROFILE_TIER
    values = (method,) if torque is None else (method, torque)
    return pytest.param(*values, marks=() if method in tier else pytest.mark.slow)


GEOMETRIC = ["symplectic_euler", "splitting2", "splitting4", "implicit_midpoint"]

pytestmark = pytest.mark.usefixtures("warm_kernels")


def energy(moments, w):
    return 0.5 * np.sum(moments * w**2, axis=-1)


def l_squared(moments, w):
    return np.sum((moments * w) ** 2, axis=-1)


def final(ds):
    return ds.omega.values[:, -1, :]


@numba.njit
def wobbling_torque(t, w1, w2, w3):
    """A smooth torque depending on time and spin, for order tests of the torque sub-flow."""
    return 0.2 * math.cos(t), -0.1 * w1, 0.3 * math.sin(2.0 * t)


# --- coefficients --------------------------------------------------------------------------------------

@pytest.mark.parametrize("tableau", [tableaux.RK4, tableaux.RK8], ids=lambda t: t.name)
def test_butcher_tableau_is_explicit_and_consistent(tableau):
    tableau.check()
    assert np.allclose(tableau.A.sum(axis=1), tableau.c, atol=1e-15)


@pytest.mark.parametrize("tableau", [tableaux.RK4, tableaux.RK8], ids=lambda t: t.name)
def test_butcher_weights_integrate_polynomials_up_to_the_order(tableau):
    b, c = tableau.b, tableau.c
    for k in range(1, tableau.order + 1):
        assert abs(b @ c ** (k - 1) - 1.0 / k) < 1e-14, k
    # A c^(k-1) = c^k / k holds for the stages DOP853 uses it on (stage order conditions, k = 2).
    assert abs(b @ (tableau.A @ c) - 1.0 / 6.0) < 1e-14


def test_rk4_satisfies_all_eight_fourth_order_conditions():
    A, b, c = tableaux.RK4.A, tableaux.RK4.b, tableaux.RK4.c
    conditions = [
        (b.sum(), 1), (b @ c, 1 / 2), (b @ c**2, 1 / 3), (b @ A @ c, 1 / 6),
        (b @ c**3, 1 / 4), (b @ (c * (A @ c)), 1 / 8), (b @ A @ c**2, 1 / 12), (b @ A @ A @ c, 1 / 24),
    ]
    for value, expected in conditions:
        assert value == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize("name", ["symplectic_euler", "splitting2", "splitting4"])
def test_every_subflow_runs_for_exactly_one_step(name):
    splitting = METHODS[name].splitting
    splitting.check()
    for flow in (tableaux.ROTATE_1, tableaux.ROTATE_2, tableaux.ROTATE_3, tableaux.TORQUE):
        assert splitting.fractions[splitting.flows == flow].sum() == pytest.approx(1.0, abs=1e-15)
    free = splitting.without_torque()
    assert tableaux.TORQUE not in free.flows
    assert np.all(np.diff(free.flows) != 0), "adjacent equal sub-flows must be merged"


@pytest.mark.parametrize("name", ["splitting2", "splitting4"])
def test_symmetric_compositions_are_palindromes(name):
    splitting = METHODS[name].splitting
    assert np.array_equal(splitting.flows, splitting.flows[::-1])
    assert np.allclose(splitting.fractions, splitting.fractions[::-1], rtol=0, atol=1e-15)


def test_suzuki_weights_cancel_the_third_order_error():
    g = tableaux._SUZUKI_G
    weights = np.array([g, g, 1 - 4 * g, g, g])
    assert weights.sum() == pytest.approx(1.0, abs=1e-15)
    assert (weights**3).sum() == pytest.approx(0.0, abs=1e-15)


# --- closed forms ----------------------------------------------------------------------------------------

def space_station(t, moments, w0, gamma):
    """DESIGN.md / problem sheet: constant torque gamma about the symmetry axis of I1 = I2."""
    i1, _, i3 = moments
    beta = (i3 - i1) / i1
    w3 = w0[2] + gamma * t / i3
    phase = beta * (w0[2] * t + gamma * t**2 / (2 * i3))
    eta = (w0[0] + 1j * w0[1]) * np.exp(1j * phase)
    return np.stack([eta.real, eta.imag, w3], axis=-1)


@pytest.mark.parametrize("method", [_tiered(m, None) for m in STEPPING])
def test_every_method_matches_the_space_station_closed_form(method):
    moments, w0, gamma = np.array([2.0, 2.0, 1.0]), np.array([0.3, 0.0, 1.0]), 1.0
    dt = {"symplectic_euler": 1e-4}.get(method, 1e-3)
    tol = {"symplectic_euler": 2e-3, "splitting2": 1e-5, "implicit_midpoint": 1e-5}.get(method, 1e-9)
    ds = tumble.integrate(moments, w0[None], 5.0, dt, method=method, torque=(0, 0, gamma), save_every=500)
    expected = space_station(ds.time.values, moments, w0, gamma)
    assert np.abs(ds.omega.values[0] - expected).max() < tol


PROFILES = [("ramp", {"duration": 1.5}), ("sine", {"period": 2.0}), ("pulse", {"duration": 2.5})]


@pytest.mark.parametrize("profile, timing", PROFILES)
@pytest.mark.parametrize("method", ["rk4", "splitting4"])
def test_named_torque_profiles_match_the_spin_up_closed_form(method, profile, timing):
    """Ramp, sine and pulse about the symmetry axis: w3 = w30 + (Γ/I3) S(t), phase β (w30 t + (Γ/I3) ∫S)."""
    moments, w0, gamma = np.array([2.0, 2.0, 1.0]), np.array([0.3, 0.0, 1.0]), 0.8
    torque = {"profile": profile, "vector": (0.0, 0.0, gamma), **timing}
    ds = tumble.integrate(moments, w0[None], 5.0, 1e-3, method=method, torque=torque, save_every=250)
    tau = next(iter(timing.values()))
    expected = theory.constant_torque_symmetric_top(moments, w0, gamma, ds.time.values, profile=profile, tau=tau)
    # A fixed step across the pulse's end errs once by up to h Γ / I3 (first order); smooth profiles keep the
    # method's order.
    tol = 1e-3 * gamma / moments[2] if profile == "pulse" else 1e-9
    assert np.abs(ds.omega.values[0] - expected).max() < tol
    assert ds.attrs["torque"].startswith(profile)


@pytest.mark.parametrize("torque, message", [
    ({"profile": "ramp", "vector": (0, 0, 1)}, "duration > 0"),
    ({"profile": "sine", "vector": (0, 0, 1), "period": -1.0}, "period > 0"),
    ({"profile": "spiral", "vector": (0, 0, 1)}, "profile must be one of"),
    ({"profile": "pulse", "vector": (0, 1), "duration": 1.0}, "shape"),
])
def test_bad_torque_profiles_are_refused(torque, message):
    with pytest.raises(ValueError, match=message):
        tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.1]], 1.0, 0.1, torque=torque)


def test_a_profile_with_zero_vector_is_torque_free():
    ds = tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.1]], 1.0, 0.1,
                          torque={"profile": "sine", "vector": (0, 0, 0), "period": 1.0})
    assert ds.attrs["torque"] == "none"


@pytest.mark.parametrize("method", [*STEPPING, "exact"])
def test_thin_disc_transverse_spin_turns_at_the_spin_rate(method):
    """I3 = 2 I1: (w1, w2) rotates at Omega = w3 (I3 - I1) / I1 = w3 in the body frame."""
    moments = np.array([1.0, 1.0, 2.0])
    w0 = np.array([[0.05, 0.0, 2.0]])
    ds = tumble.integrate(moments, w0, 3.0, 1e-3, method=method, save_every=100)
    t = ds.time.values
    expected = 0.05 * np.stack([np.cos(2.0 * t), np.sin(2.0 * t)], axis=-1)
    tol = {"symplectic_euler": 5e-4, "splitting2": 1e-6, "implicit_midpoint": 1e-6}.get(method, 1e-8)
    assert np.abs(ds.omega.values[0, :, :2] - expected).max() < tol
    # w3 is constant for the symmetric top; the splittings keep it only to their truncation error.
    w3_tol = tol if method in ("symplectic_euler", "splitting2", "splitting4") else 1e-14
    assert np.abs(ds.omega.values[0, :, 2] - 2.0).max() < w3_tol


# --- observed order --------------------------------------------------------------------------------------

MOMENTS = np.array([1.0, 2.0, 3.0])
TORQUES = {"free": (0.0, 0.0, 0.0), "constant": (0.2, -0.1, 0.3), "function": wobbling_torque}
# Observed order is an asymptotic property: each case below uses steps inside the asymptotic range (local
# order settled) and errors well above the reference's ~1e-14.
# Torque-free: spins near the stable third axis over 60 s, smooth motion whose error constants settle early.
FREE = dict(spins=np.array([[0.1, 0.2, 1.0], [0.2, 0.1, -1.0]]), horizon=60.0, steps={
    "rk4": [0.05, 0.04, 0.032, 0.025],
    "rk8": [0.5, 0.4, 0.32, 0.25],
    "symplectic_euler": [0.004, 0.0032, 0.0025, 0.002],
    "splitting2": [0.05, 0.04, 0.032, 0.025],
    "splitting4": [0.1, 0.08, 0.064, 0.05],
    "implicit_midpoint": [0.05, 0.04, 0.032, 0.025],
})
# With a torque the spin changes size, so a shorter horizon and generic spins.
FORCED = dict(spins=np.array([[0.4, 1.0, 0.3], [-0.7, 0.2, 0.5]]), horizon=4.0, steps={
    "rk4": [0.1, 0.05, 0.025, 0.0125],
    "symplectic_euler": [0.01, 0.005, 0.0025, 0.00125],
    "splitting2": [0.05, 0.025, 0.0125, 0.00625],
    "splitting4": [0.1, 0.05, 0.025, 0.0125],
    "implicit_midpoint": [0.05, 0.025, 0.0125, 0.00625],
})


def observed_order(method, torque_label):
    case = FREE if torque_label == "free" else FORCED
    torque = TORQUES[torque_label]
    # rk8 at a step far below the tested ones: error below 1e-14.
    reference = final(tumble.integrate(MOMENTS, case["spins"], case["horizon"], 0.004, method="rk8",
                                       torque=torque))
    steps, errors = [], []
    for dt in case["steps"][method]:
        ds = tumble.integrate(MOMENTS, case["spins"], case["horizon"], dt, method=method, torque=torque)
        steps.append(ds.attrs["dt"])
        errors.append(np.abs(final(ds) - reference).max())
    assert min(errors) > 1e-12, "errors must stay well above round-off for a meaningful fit"
    return np.polyfit(np.log(steps), np.log(errors), 1)[0]


@pytest.mark.parametrize("method", STEPPING)
def test_torque_free_observed_order_matches_nominal(method):
    assert observed_order(method, "free") == pytest.approx(METHODS[method].order, abs=0.1)


@pytest.mark.parametrize("method, torque", [_tiered(m, t) for t in ("constant", "function")
                                            for m in ("rk4", "symplectic_euler", "splitting2", "splitting4",
                                                      "implicit_midpoint")])
def test_observed_order_holds_with_a_torque(method, torque):
    assert observed_order(method, torque) == pytest.approx(METHODS[method].order, abs=0.1)


def test_rk8_agrees_with_scipy_dop853_at_tight_tolerance():
    from scipy.integrate import solve_ivp

    def euler(t, w):
        i1, i2, i3 = MOMENTS
        return [(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2, (i1 - i2) * w[0] * w[1] / i3]

    spins, horizon = FORCED["spins"], 20.0
    ours = final(tumble.integrate(MOMENTS, spins, horizon, 0.02, method="rk8"))
    for w, mine in zip(spins, ours):
        theirs = solve_ivp(euler, (0, horizon), w, method="DOP853", rtol=1e-13, atol=1e-15).y[:, -1]
        assert np.abs(mine - theirs).max() < 1e-11


# --- invariants over long runs ---------------------------------------------------------------------------

@pytest.mark.parametrize("method", GEOMETRIC)
def test_geometric_methods_keep_l_squared_to_round_off_over_a_million_steps(method):
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.array([[0.3, 1.0, 0.2], [0.05, 1.0, -0.05], [1.0, 0.1, 0.3], [0.1, 0.2, 1.0]])
    n_steps = 1_000_000 if method != "implicit_midpoint" else 200_000
    ds = tumble.integrate(moments, w0, n_steps * 0.01, 0.01, method=method, save_every=n_steps // 200)
    w = ds.omega.values
    l2 = l_squared(moments, w)
    # The splittings are projected onto the initial |L|^2 each step; the midpoint rule's error random-walks.
    assert np.abs(l2 / l2[:, :1] - 1).max() <= (1e-13 if method != "implicit_midpoint" else 1e-12)
    # Energy: bounded, no secular growth — the error in the second half is no larger than in the first.
    e = energy(moments, w)
    drift = np.abs(e / e[:, :1] - 1)
    half = drift.shape[1] // 2
    assert drift.max() < 0.05
    assert np.all(drift[:, half:].max(axis=1) <= 1.5 * drift[:, :half].max(axis=1) + 1e-11)


def test_implicit_midpoint_keeps_the_energy_to_round_off():
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.array([[0.3, 1.0, 0.2], [1.0, 0.1, 0.3]])
    ds = tumble.integrate(moments, w0, 500.0, 0.05, method="implicit_midpoint", save_every=100)
    e = energy(moments, ds.omega.values)
    assert np.abs(e / e[:, :1] - 1).max() < 1e-13


# --- agreement, invariance, reproducibility ---------------------------------------------------------------

def test_all_methods_agree_at_small_steps(rng):
    moments = np.array([1.0, 2.0, 3.0])
    w0 = rng.normal(size=(16, 3))
    reference = final(tumble.integrate(moments, w0, 2.0, 0.01, method="rk8"))
    for method, dt, tol in [("rk4", 0.002, 1e-10), ("splitting4", 0.002, 1e-9), ("splitting2", 0.0005, 1e-5),
                            ("implicit_midpoint", 0.0005, 1e-5), ("symplectic_euler", 0.0001, 2e-3)]:
        assert np.abs(final(tumble.integrate(moments, w0, 2.0, dt, method=method)) - reference).max() < tol, method


@pytest.mark.parametrize("method", STEPPING)
def test_permuting_the_axes_permutes_the_solution(method, rng):
    moments = np.array([1.0, 2.5, 3.0])
    w0 = rng.normal(size=(8, 3))
    base = final(tumble.integrate(moments, w0, 3.0, 0.01, method=method))
    for perm in ([1, 2, 0], [2, 0, 1], [0, 2, 1]):
        # An odd permutation reverses handedness: Euler's equations keep their form with w -> -w.
        sign = 1.0 if perm in ([1, 2, 0], [2, 0, 1]) else -1.0
        w0_moved = w0[:, perm] * sign
        moved = final(tumble.integrate(moments[perm], w0_moved, 3.0, 0.01, method=method)) * sign
        assert np.abs(moved - base[:, perm]).max() < 1e-12 * np.abs(base).max() + 1e-13


@pytest.mark.parametrize("method", STEPPING)
def test_scaling_all_moments_leaves_the_motion_unchanged(method, rng):
    moments = np.array([1.0, 2.0, 2.7])
    w0 = rng.normal(size=(8, 3))
    base = final(tumble.integrate(moments, w0, 3.0, 0.01, method=method))
    for scale in (1e-6, 7.0, 1e9):
        scaled = final(tumble.integrate(moments * scale, w0, 3.0, 0.01, method=method))
        assert np.abs(scaled - base).max() < 1e-12


@pytest.mark.parametrize("method", STEPPING)
def test_results_are_bit_identical_for_any_block_size(method, rng):
    moments = np.array([1.0, 2.0, 3.0])
    w0 = rng.normal(size=(3, 300))
    results = []
    for block in (1, 7, 64, 128, 512):
        w = w0.copy()
        run(METHODS[method], w, moments, 0.0, 0.01, 200, block=block)
        results.append(w)
    for other in results[1:]:
        assert np.array_equal(other, results[0])


# --- the Dataset -----------------------------------------------------------------------------------------

def test_integrate_returns_omega_by_sample_time_axis_with_units():
    ds = tumble.integrate(tumble.Body(1.0, 2.0, 3.0), [[0.1, 1.0, 0.1], [1.0, 0.0, 0.0]], 1.0, 0.1,
                          save_every=3)
    assert ds.omega.dims == ("sample", "time", "axis")
    assert ds.omega.shape == (2, 5, 3)
    assert ds.omega.attrs["units"] == "rad/s" and ds.time.attrs["units"] == "s"
    np.testing.assert_allclose(ds.time.values, [0.0, 0.3, 0.6, 0.9, 1.0])
    np.testing.assert_array_equal(ds.omega.values[:, 0], [[0.1, 1.0, 0.1], [1.0, 0.0, 0.0]])
    assert list(ds.axis.values) == [1, 2, 3]
    assert ds.attrs["method"] == "rk4" and ds.attrs["n_steps"] == 10


@pytest.mark.parametrize("method", ["rk4", "exact"])
def test_integrate_never_modifies_the_callers_spins(method):
    w0 = np.array([[0.1, 1.0, 0.1]])
    tumble.integrate((1.0, 2.0, 3.0), w0, 1.0, 0.1, method=method)
    tumble.integrate((1.0, 2.0, 3.0), w0[0], 1.0, 0.1, method=method)
    assert w0.tolist() == [[0.1, 1.0, 0.1]]


def test_without_save_every_only_the_final_state_is_stored():
    ds = tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.1]], 1.0, 0.1)
    assert ds.omega.shape == (1, 1, 3)
    assert ds.time.values.tolist() == [1.0]


def test_a_step_that_does_not_divide_the_horizon_is_shortened_to_land_on_it():
    ds = tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.1]], 1.0, 0.3)
    assert ds.attrs["n_steps"] == 4 and ds.attrs["dt"] == pytest.approx(0.25)


def test_a_blow_up_is_reported_not_silent():
    with pytest.warns(RuntimeWarning, match="non-finite"):
        ds = tumble.integrate((1.0, 2.0, 3.0), [[1e200, 1e200, 1e200], [0.1, 1.0, 0.1]], 1.0, 0.1)
    assert ds.attrs["n_nonfinite"] == 1


# --- bad input -------------------------------------------------------------------------------------------

GOOD = dict(body=(1.0, 2.0, 3.0), w0=[[0.1, 1.0, 0.1]], t_end=1.0, dt=0.1)


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(body=(0.0, 2.0, 3.0)), "> 0"),
        (dict(body=(-1.0, 2.0, 3.0)), "> 0"),
        (dict(body=(np.nan, 2.0, 3.0)), "finite"),
        (dict(body=(np.inf, 2.0, 3.0)), "finite"),
        (dict(body=(1.0, 2.0, 5.0)), "triangle inequality"),
        (dict(body=(1.0, 2.0)), "shape"),
        (dict(w0=[0.1, 1.0]), "shape"),
        (dict(w0=[[0.1, 1.0, 0.1, 0.0]]), "shape"),
        (dict(w0=[[np.nan, 1.0, 0.1]]), "finite"),
        (dict(w0=np.zeros((0, 3))), "no spins"),
        (dict(dt=0.0), "dt must be > 0"),
        (dict(dt=-0.1), "dt must be > 0"),
        (dict(dt=np.nan), "dt must be finite"),
        (dict(dt=np.inf), "dt must be finite"),
        (dict(t_end=-1.0), "t_end must be >= 0"),
        (dict(t_end=np.inf), "t_end must be finite"),
        (dict(t_end="soon"), "t_end must be a number"),
        (dict(method="rk5"), "method must be one of"),
        (dict(torque=(1.0, 2.0)), "torque must have shape"),
        (dict(torque=(np.nan, 0, 0)), "torque must be finite"),
        (dict(method="exact", torque=(0.0, 0.0, 1.0)), "'exact'.*torque"),
        (dict(save_every=0), "save_every"),
        (dict(save_every=1.5), "save_every"),
    ],
)
def test_bad_input_raises_a_value_error_that_says_what_is_wrong(change, message):
    kwargs = {**GOOD, **change}
    with pytest.raises(ValueError, match=message):
        tumble.integrate(kwargs.pop("body"), kwargs.pop("w0"), kwargs.pop("t_end"), kwargs.pop("dt"), **kwargs)


def test_exact_path_with_a_torque_function_is_refused():
    with pytest.raises(ValueError, match="exact"):
        tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.1]], 1.0, 0.1, method="exact", torque=wobbling_torque)


# --- user torque functions: one compiled driver, whatever the function and the method ------------------------

def test_torque_functions_share_one_compiled_driver_and_match_the_constant_profile():
    from tumble.kernels.loops import drivers

    @numba.njit
    def constant_spin_up(t, w1, w2, w3):
        return 0.0, 0.0, 0.25

    def same_as_python(t, w1, w2, w3):  # not jitted: tumble jits it
        return 0.0, 0.0, 0.25

    w0 = [[0.1, 0.05, 1.0], [-0.2, 0.1, 0.8]]
    profile = tumble.integrate((1.0, 1.0, 2.0), w0, 2.0, 0.01, method="rk4", torque=(0.0, 0.0, 0.25))
    for fn in (constant_spin_up, same_as_python, wobbling_torque):
        ds = tumble.integrate((1.0, 1.0, 2.0), w0, 2.0, 0.01, method="rk4", torque=fn)
        if fn is not wobbling_torque:
            np.testing.assert_allclose(ds.omega.values, profile.omega.values, rtol=1e-14, atol=1e-15)
    assert len(drivers._DRIVERS[registry.STEPPING.index("rk4"), "function", False].signatures) == 1, "one variant serves every torque function"


@pytest.mark.parametrize("fn, words", [
    (lambda t, w1, w2, w3: (0.0, 1.0), "f(t, w1, w2, w3) -> (N1, N2, N3)"),
    (lambda t, w1, w2, w3: "torque", "f(t, w1, w2, w3) -> (N1, N2, N3)"),
    (lambda t, w1: (0.0, 0.0, 1.0), "f(t, w1, w2, w3) -> (N1, N2, N3)"),
])
def test_a_torque_function_of_the_wrong_form_is_refused_with_a_message(fn, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")):
        tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.1]], 1.0, 0.1, torque=fn)
