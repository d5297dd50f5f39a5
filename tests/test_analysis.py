"""Estimators of tumble.measure.estimators: scaled coordinates, growth and phase fits, flip timing, scene statistics.

Layers (STYLE.md item 7): properties of the invariant weights → synthetic signals whose answer is known in
closed form → the exact torque-free solution (tumble.exact) against linear theory and the exact period →
edge cases and bad inputs → reproducibility. The estimators' inner loops are the kernels of
tumble.kernels.fits, tested here through the estimators and against their numpy formulations.
"""


import numpy as np
import pytest
from scipy import stats

from tumble.engine import sampling
from tumble.measure import estimators as analysis
from tumble.measure.estimators import FIT_NO_SIGNAL, FIT_OK, FIT_SHORT_WINDOW, FIT_UNDERSAMPLED
from tumble.physics import exact, theory

MOMENTS = np.array([1.0, 2.0, 3.0])
SQRT3 = np.sqrt(3.0)


def transverse(moments, axis):
    """0-based indices (b, c) of the transverse axes and the matching weights (g_b, g_c)."""
    b, c = (i - 1 for i in sampling.transverse_axes(axis))
    return b, c, analysis.invariant_weights(moments, axis)[[b, c]]


def scaled(w, moments, axis):
    """Scaled transverse coordinates (x, y) = (sqrt(g_b) w_b, sqrt(g_c) w_c) of w, shape (..., 3)."""
    b, c, g = transverse(moments, axis)
    return np.sqrt(g[0]) * w[..., b], np.sqrt(g[1]) * w[..., c]


# --- invariant_weights: properties ---------------------------------------------------------------------


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (1.0, 1.1, 3.0), (0.3, 7.0, 2.5), (5.0, 4.0, 0.2)])
@pytest.mark.parametrize("axis", [1, 2, 3])
def test_transverse_weights_multiply_to_one_and_spin_axis_weight_is_zero(moments, axis):
    g = analysis.invariant_weights(moments, axis)
    b, c = (i - 1 for i in sampling.transverse_axes(axis))
    assert g[axis - 1] == 0.0
    assert g[b] * g[c] == pytest.approx(1.0, rel=1e-14)
    assert np.all(g[[b, c]] > 0)


@pytest.mark.parametrize("axis", [1, 2, 3])
def test_weights_are_the_square_root_ratio_of_the_invariant_coefficients(axis):
    moments = np.array([0.3, 7.0, 2.5])
    k = moments * (moments[axis - 1] - moments)
    b, c = (i - 1 for i in sampling.transverse_axes(axis))
    g = analysis.invariant_weights(moments, axis)
    assert g[b] == pytest.approx(np.sqrt(abs(k[b] / k[c])), rel=1e-14)
    assert g[c] == pytest.approx(np.sqrt(abs(k[c] / k[b])), rel=1e-14)


def test_weights_do_not_depend_on_the_scale_of_the_moments():
    for axis in (1, 2, 3):
        np.testing.assert_allclose(analysis.invariant_weights(MOMENTS * 1e6, axis),
                                   analysis.invariant_weights(MOMENTS, axis), rtol=1e-14)


def test_intermediate_axis_weights_of_1_2_3_have_their_closed_form():
    # axis 2: b = 3, c = 1; k_3 = 3 (2 - 3) = -3, k_1 = 1 (2 - 1) = 1 -> g_3 = sqrt(3), g_1 = 1/sqrt(3)
    np.testing.assert_allclose(analysis.invariant_weights(MOMENTS, 2), [1 / SQRT3, 0.0, SQRT3], rtol=1e-15)


@pytest.mark.parametrize("moments, axis", [((1.0, 1.0, 3.0), 1), ((1.0, 1.0, 3.0), 2), ((2.0, 5.0, 5.0), 3),
                                           ((2.0, 2.0, 2.0), 1), ((2.0, 2.0, 2.0), 3)])
def test_degenerate_conic_gives_unit_weights(moments, axis):
    """A symmetric top spun about an axis of its equal pair, or a sphere: k_b or k_c vanishes."""
    expected = np.ones(3)
    expected[axis - 1] = 0.0
    np.testing.assert_array_equal(analysis.invariant_weights(moments, axis), expected)


def test_symmetric_top_about_its_symmetry_axis_has_unit_weights_from_the_formula():
    np.testing.assert_allclose(analysis.invariant_weights((1.0, 1.0, 3.0), 3), [1.0, 1.0, 0.0], rtol=1e-15)


# --- invariant_weights: against the exact solution -----------------------------------------------------


@pytest.mark.parametrize("moments, axis", [((1.0, 1.1, 2.0), 1), ((1.0, 2.0, 3.0), 3), ((1.0, 2.0, 3.0), 1)])
def test_exact_periodic_motion_is_a_circle_in_scaled_coordinates(moments, axis):
    """k_b w_b² + k_c w_c² is exactly conserved: the scaled radius is constant to round-off, although the
    plain transverse radius of an elongated ellipse (I = (1, 1.1, 2) about axis 1: g_3 ≈ 4.3) swings widely."""
    moments = np.asarray(moments)
    w0 = sampling.perturbed_spins(moments, axis, 1.0, 1e-2, 16, seed=11)
    t = np.linspace(0.0, 60.0, 801)
    w = exact.omega(moments, w0, t)
    x, y = scaled(w, moments, axis)
    r2 = x**2 + y**2
    b, c, g = transverse(moments, axis)
    plain2 = w[..., b] ** 2 + w[..., c] ** 2
    scaled_variation = np.ptp(r2, axis=1) / r2.mean(axis=1)
    plain_variation = np.ptp(plain2, axis=1) / plain2.mean(axis=1)
    assert scaled_variation.max() < 1e-10
    if max(g) > 2:  # an elongated ellipse: the plain radius is far from constant
        assert plain_variation.min() > 1.0


def test_exact_intermediate_axis_motion_is_a_rectangular_hyperbola_in_scaled_coordinates():
    """About the intermediate axis, k_b k_c < 0: x² - y² (that is (x + y)(x - y)) is conserved exactly,
    while x² + y² grows by orders of magnitude."""
    w0 = sampling.perturbed_spins(MOMENTS, 2, 1.0, 1e-4, 16, seed=12)
    t = np.linspace(0.0, 12.0, 401)
    w = exact.omega(MOMENTS, w0, t)
    x, y = scaled(w, MOMENTS, 2)
    h = x**2 - y**2
    r2 = x**2 + y**2
    assert np.max(np.abs(h - h[:, :1]) / r2[:, :1]) < 1e-9
    assert np.min(r2[:, -1] / r2[:, 0]) > 1e2


# --- growth_rates: synthetic signals -------------------------------------------------------------------


def hyperbolic_norm(t, rate, grow, decay):
    """Scaled norm of linear hyperbolic motion, sqrt(2 (A² e^{2λt} + B² e^{-2λt}))."""
    return np.sqrt(2.0 * (grow**2 * np.exp(2 * rate * t) + decay**2 * np.exp(-2 * rate * t)))


def test_pure_exponential_rate_is_recovered_to_round_off():
    t = np.linspace(0.0, 20.0, 401)
    norms = 1e-8 * np.exp(0.7 * t)[None, :]
    fit = analysis.growth_rates(t, norms, 1e-3)
    assert fit.code[0] == FIT_OK
    assert fit.rate[0] == pytest.approx(0.7, rel=1e-12)
    # window: from the initial amplitude to the last time before the norm passes 1e-3
    assert fit.t_start[0] == 0.0 and fit.norm_start[0] == norms[0, 0]
    assert fit.norm_stop[0] <= 1e-3 < norms[0, np.searchsorted(t, fit.t_stop[0]) + 1]
    assert fit.points[0] == np.count_nonzero(t <= fit.t_stop[0])


@pytest.mark.parametrize("decay", [0.0, 1e-8, 1e-7, 1e-6, 1e-5])
def test_linear_prediction_is_exact_whatever_the_decaying_mode(decay):
    """s = 2(A² e^{2λt} + B² e^{-2λt}) obeys s(t+h) + s(t-h) = 2 cosh(2λh) s(t): no transient to skip, even
    for a sample that starts near the stable direction and first shrinks."""
    rate = 0.577
    t = np.linspace(0.0, 40.0, 2001)
    fit = analysis.growth_rates(t, hyperbolic_norm(t, rate, 1e-8, decay)[None, :], 1e-2)
    assert fit.code[0] == FIT_OK and fit.t_start[0] == 0.0
    assert fit.rate[0] == pytest.approx(rate, rel=1e-9)


def test_plain_log_slope_would_be_biased_by_the_decaying_mode():
    """The reason for linear prediction: the log-slope of the same data over the same window is far off."""
    rate, t = 0.5, np.linspace(0.0, 50.0, 2501)
    norm = hyperbolic_norm(t, rate, 1e-8, 1e-6)
    fit = analysis.growth_rates(t, norm[None, :], 1e-2)
    window = t <= fit.t_stop[0]
    log_slope = np.polyfit(t[window], np.log(norm[window]), 1)[0]
    assert abs(fit.rate[0] / rate - 1) < 1e-9 < 1e-3 < abs(log_slope / rate - 1)


def test_unequally_spaced_times_are_refused():
    t = np.geomspace(0.1, 10.0, 50)
    with pytest.raises(ValueError, match="equally spaced"):
        analysis.growth_rates(t, np.exp(t)[None, :], 1e3)


def test_window_closes_before_the_saturation_crossing_per_sample():
    t = np.linspace(0.0, 30.0, 601)
    norms = np.stack([1e-9 * np.exp(0.8 * t), 1e-9 * np.exp(0.8 * t)])
    saturation = np.array([1e-3, 1e-5])
    fit = analysis.growth_rates(t, norms, saturation)
    assert np.all(fit.code == FIT_OK)
    crossing = np.log(saturation / 1e-9) / 0.8
    assert np.all(fit.t_stop <= crossing) and np.all(fit.t_stop > crossing - (t[1] - t[0]))
    assert np.all(fit.norm_stop <= saturation)
    assert fit.points[0] > fit.points[1]


def test_saturation_ends_the_window_even_when_the_norm_keeps_changing_afterwards():
    """Past saturation the (nonlinear) norm does anything; none of it may enter the fit."""
    t = np.linspace(0.0, 30.0, 601)
    norm = 1e-9 * np.exp(0.8 * t)
    wild = np.where(norm > 1e-3, 1e-3 * np.cos(5 * t) ** 2 + 1e-3, norm)
    fit = analysis.growth_rates(t, np.stack([norm, wild]), 1e-3)
    assert np.all(fit.code == FIT_OK)
    assert fit.rate[1] == fit.rate[0] == pytest.approx(0.8, rel=1e-12)


def test_stopped_sample_nan_tail_closes_its_window_and_leaves_others_alone():
    t = np.linspace(0.0, 30.0, 601)
    full = 1e-9 * np.exp(0.8 * t)
    stopped = full.copy()
    stopped[300:] = np.nan  # the engine stopped this sample at t = 15 s (norm ~ 1.6e-4 < saturation)
    fit = analysis.growth_rates(t, np.stack([full, stopped]), 1e-2)
    assert np.all(fit.code == FIT_OK)
    np.testing.assert_allclose(fit.rate, 0.8, rtol=1e-12)
    assert fit.t_stop[1] == t[299]
    assert fit.t_stop[0] > t[299]


def test_all_nan_sample_is_a_short_window():
    t = np.linspace(0.0, 30.0, 601)
    norms = np.stack([1e-9 * np.exp(0.8 * t), np.full_like(t, np.nan)])
    fit = analysis.growth_rates(t, norms, 1e-2)
    assert list(fit.code) == [FIT_OK, FIT_SHORT_WINDOW]
    assert np.isnan(fit.rate[1]) and np.isnan(fit.t_start[1]) and fit.points[1] == 0


def test_window_needs_min_points_seven_is_short_and_eight_is_ok():
    # rate 2/s, dt = 0.5 s, saturation e^{2 t_sat} keeps the points up to t_sat: 3.1 -> 7 points, 3.6 -> 8
    t = np.arange(0.0, 10.0, 0.5)
    norms = (1e-6 * np.exp(2.0 * t))[None, :]
    assert analysis.MIN_POINTS == 8
    short = analysis.growth_rates(t, norms, 1e-6 * np.exp(2.0 * 3.1))
    assert short.code[0] == FIT_SHORT_WINDOW
    assert np.isnan(short.rate[0]) and np.isnan(short.t_stop[0]) and short.points[0] == 0
    ok = analysis.growth_rates(t, norms, 1e-6 * np.exp(2.0 * 3.6))
    assert ok.code[0] == FIT_OK and ok.points[0] == 8
    assert (ok.t_start[0], ok.t_stop[0]) == (0.0, 3.5)
    assert ok.rate[0] == pytest.approx(2.0, rel=1e-12)


def test_constant_norm_is_short_and_a_pure_decay_gives_the_mode_rate():
    """A sample exactly on the stable direction decays at the same |λ|: linear prediction reports it."""
    t = np.linspace(0.0, 10.0, 201)
    norms = np.stack([np.full_like(t, 1e-6), 1e-6 * np.exp(-t)])
    fit = analysis.growth_rates(t, norms, 1e-2)
    assert fit.code[0] == FIT_SHORT_WINDOW and np.isnan(fit.rate[0])
    assert fit.code[1] == FIT_OK and fit.rate[1] == pytest.approx(1.0, rel=1e-9)


def test_sample_saturated_from_the_start_is_short():
    t = np.linspace(0.0, 10.0, 201)
    fit = analysis.growth_rates(t, (1e-1 * np.exp(t))[None, :], 1e-2)
    assert fit.code[0] == FIT_SHORT_WINDOW


# --- growth_rates: the exact solution about the intermediate axis ---------------------------------------


def test_intermediate_axis_grows_at_linear_rate_in_the_exact_solution():
    """Exact motion near the intermediate axis of (1, 2, 3): the scaled-norm fit matches linear theory to
    far better than 1e-3, and better than the plain norm does (its cross term breaks the two-exponential
    form)."""
    kind, rate = theory.linear(MOMENTS, 2, 1.0)
    assert kind == "exponential"
    w0 = sampling.perturbed_spins(MOMENTS, 2, 1.0, 1e-6, 32, seed=5)
    t = np.arange(0.0, 30.0, 0.05)
    w = exact.omega(MOMENTS, w0, t)
    x, y = scaled(w, MOMENTS, 2)
    fit = analysis.growth_rates(t, np.hypot(x, y), 1e-2)
    assert np.all(fit.code == FIT_OK)
    assert abs(np.median(fit.rate) - rate) < 1e-5 * rate
    assert np.max(np.abs(fit.rate - rate)) < 2e-5 * rate
    plain = np.hypot(w[..., 0], w[..., 2])
    plain_fit = analysis.growth_rates(t, plain, 1e-2)
    assert np.max(np.abs(plain_fit.rate - rate)) > 5 * np.max(np.abs(fit.rate - rate))


# --- oscillation_frequencies: synthetic signals --------------------------------------------------------


def ellipse(t, omega, a, b, phase):
    """(w_b, w_c) = (a cos(ωt + φ), b sin(ωt + φ)) per sample: shape (N, T, 2)."""
    arg = omega * t[None, :] + np.atleast_1d(phase)[:, None]
    return np.stack([a * np.cos(arg), b * np.sin(arg)], axis=-1)


def test_elliptic_oscillation_frequency_is_exact_with_circularising_weights():
    t = np.linspace(0.0, 10.0, 1001)
    a, b, omega = 3e-3, 4e-4, 1.7
    phases = np.linspace(0.0, 2 * np.pi, 7)
    fit = analysis.oscillation_frequencies(t, ellipse(t, omega, a, b, phases), np.array([b / a, a / b]), 1.0)
    assert np.all(fit.code == FIT_OK)
    np.testing.assert_allclose(fit.frequency, omega, rtol=1e-12)
    np.testing.assert_allclose(fit.radius, np.sqrt(a * b), rtol=1e-12)  # sqrt(g_b) a = sqrt(a b)


def test_plain_weights_on_an_ellipse_miss_the_frequency_unless_whole_periods():
    """Without the scaled coordinates the phase of an ellipse is non-uniform: the fit is biased."""
    t = np.linspace(0.0, 10.3, 1001)
    omega = 1.7
    w = ellipse(t, omega, 3e-3, 4e-4, 0.4)
    circular = analysis.oscillation_frequencies(t, w, np.array([4 / 30, 30 / 4]), 1.0)
    plain = analysis.oscillation_frequencies(t, w, np.ones(2), 1.0)
    assert circular.frequency[0] == pytest.approx(omega, rel=1e-12)
    assert abs(plain.frequency[0] / omega - 1) > 1e-3


def test_frequency_is_non_negative_whatever_the_sense_of_rotation():
    t = np.linspace(0.0, 10.0, 1001)
    forward = ellipse(t, 2.3, 1e-3, 1e-3, 0.1)
    backward = ellipse(t, -2.3, 1e-3, 1e-3, 0.1)
    fit = analysis.oscillation_frequencies(t, np.concatenate([forward, backward]), np.ones(2), 1.0)
    assert np.all(fit.code == FIT_OK)
    np.testing.assert_allclose(fit.frequency, 2.3, rtol=1e-12)


def test_phase_step_above_a_quarter_turn_is_undersampled():
    dt = 0.1
    t = np.arange(0.0, 20.0, dt)
    omegas = np.array([0.45 * np.pi / dt, 0.55 * np.pi / dt, 0.9 * np.pi / dt])  # steps 0.45π, 0.55π, 0.9π
    w = np.concatenate([ellipse(t, om, 1e-3, 1e-3, 0.0) for om in omegas])
    fit = analysis.oscillation_frequencies(t, w, np.ones(2), 1.0)
    assert list(fit.code) == [FIT_OK, FIT_UNDERSAMPLED, FIT_UNDERSAMPLED]
    assert fit.frequency[0] == pytest.approx(omegas[0], rel=1e-12)
    assert np.all(np.isnan(fit.frequency[1:]))


def test_round_off_level_signal_is_no_signal():
    t = np.linspace(0.0, 10.0, 501)
    spin = 2.0
    w = np.concatenate([ellipse(t, 1.0, 1e-13, 1e-13, 0.0),  # radius 5e-14 |w| < 1e-11 |w|
                        np.zeros((1, t.size, 2)),
                        ellipse(t, 1.0, 1e-9, 1e-9, 0.0)])
    fit = analysis.oscillation_frequencies(t, w, np.ones(2), spin)
    assert list(fit.code) == [FIT_NO_SIGNAL, FIT_NO_SIGNAL, FIT_OK]
    assert np.all(np.isnan(fit.frequency[:2]))
    assert fit.frequency[2] == pytest.approx(1.0, rel=1e-10)


def test_signal_passing_through_zero_once_is_no_signal():
    t = np.linspace(0.0, 10.0, 501)
    w = ellipse(t, 1.0, 1e-3, 1e-3, 0.0)
    w[0, 250] = 0.0
    assert analysis.oscillation_frequencies(t, w, np.ones(2), 1.0).code[0] == FIT_NO_SIGNAL


def test_nan_in_one_sample_fails_it_and_leaves_the_others_exact():
    t = np.linspace(0.0, 10.0, 501)
    w = ellipse(t, 1.3, 1e-3, 2e-3, np.array([0.0, 1.0, 2.0]))
    w[1, 400:] = np.nan  # stopped
    fit = analysis.oscillation_frequencies(t, w, np.array([2.0, 0.5]), 1.0)
    assert fit.code[1] != FIT_OK and np.isnan(fit.frequency[1])
    assert fit.code[0] == fit.code[2] == FIT_OK
    np.testing.assert_allclose(fit.frequency[[0, 2]], 1.3, rtol=1e-12)


# --- oscillation_frequencies: the exact solution -------------------------------------------------------


@pytest.mark.parametrize("axis", [1, 3])
def test_stable_axis_oscillates_at_the_exact_period_not_only_the_linear_frequency(axis):
    """The scaled phase advances by exactly 2π per exact period; over whole periods the least-squares slope
    is 2π/T up to the bias of its O(ε²) non-uniformity, O(ε²/n²) (here ~1e-8 for ε = 1e-2, n = 10 periods),
    well below the nonlinear shift of the frequency from linear theory (~1e-5 here)."""
    kind, linear = theory.linear(MOMENTS, axis, 1.0)
    assert kind == "periodic"
    w0 = sampling.perturbed_spins(MOMENTS, axis, 1.0, 1e-2, 6, seed=3)
    b, c, g = transverse(MOMENTS, axis)
    periods = exact.period(MOMENTS, w0)
    for w0_i, period in zip(w0, periods):
        t = np.linspace(0.0, 10 * period, 401)
        w = exact.omega(MOMENTS, w0_i[None, :], t)
        fit = analysis.oscillation_frequencies(t, w[..., [b, c]], g, 1.0)
        assert fit.code[0] == FIT_OK
        assert fit.frequency[0] == pytest.approx(2 * np.pi / period, rel=2e-7)
        assert abs(2 * np.pi / period / linear - 1) > 1e-5  # the test tells exact from linear


def test_stable_axis_frequencies_of_an_ensemble_match_linear_theory_at_small_amplitude():
    w0 = sampling.perturbed_spins(MOMENTS, 1, 2.0, 1e-4, 64, seed=4)
    b, c, g = transverse(MOMENTS, 1)
    t = np.linspace(0.0, 40.0, 801)
    fit = analysis.oscillation_frequencies(t, exact.omega(MOMENTS, w0, t)[..., [b, c]], g, 2.0)
    assert np.all(fit.code == FIT_OK)
    np.testing.assert_allclose(fit.frequency, theory.linear(MOMENTS, 1, 2.0)[1], rtol=1e-6)


# --- flip_statistics -----------------------------------------------------------------------------------


def test_first_flip_and_mean_spacing_with_nan_tails():
    nan = np.nan
    flips = np.array([[1.0, 3.0, 6.0, 10.0],  # spacings 2, 3, 4 -> mean 3
                      [2.5, 4.5, nan, nan],  # one spacing of 2
                      [7.0, nan, nan, nan],  # one flip: no spacing
                      [nan, nan, nan, nan]])  # no flip
    stats = analysis.flip_statistics(flips)
    np.testing.assert_array_equal(stats.first, [1.0, 2.5, 7.0, nan])
    np.testing.assert_allclose(stats.spacing, [3.0, 2.0, nan, nan], rtol=1e-15)


def test_flip_spacing_of_the_exact_solution_is_its_half_period():
    """The engine records sign changes of w_mid: equally spaced by exact.flip_spacing."""
    w0 = sampling.perturbed_spins(MOMENTS, 2, 1.0, 1e-3, 5, seed=8)
    first, spacing = exact.first_flip_time(MOMENTS, w0), exact.flip_spacing(MOMENTS, w0)
    flips = first[:, None] + np.arange(6)[None, :] * spacing[:, None]
    flips[1, 3:] = np.nan
    stats = analysis.flip_statistics(flips)
    np.testing.assert_allclose(stats.first, first, rtol=1e-15)
    np.testing.assert_allclose(stats.spacing, spacing, rtol=1e-12)


def test_flip_statistics_returns_copies_not_views():
    flips = np.array([[1.0, 2.0]])
    stats = analysis.flip_statistics(flips)
    stats.first[0] = 99.0
    assert flips[0, 0] == 1.0


def test_no_recorded_flip_columns_give_nan_statistics():
    stats = analysis.flip_statistics(np.empty((3, 0)))
    assert np.all(np.isnan(stats.first)) and np.all(np.isnan(stats.spacing))


# --- summarize -----------------------------------------------------------------------------------------


def test_median_and_half_interquartile_range_of_known_data():
    s = analysis.summarize(np.arange(1.0, 101.0))
    assert s.median == 50.5
    assert s.spread == pytest.approx(0.5 * (75.25 - 25.75), rel=1e-15)  # numpy's linear percentiles
    assert (s.used, s.excluded) == (100, 0)


def test_median_and_spread_are_numpys_bit_for_bit_on_random_rows_with_nan():
    rng = np.random.default_rng(0)
    for _ in range(200):
        values = rng.lognormal(size=int(rng.integers(1, 300)))
        values[rng.random(values.size) < 0.2] = np.nan
        good = values[np.isfinite(values)]
        s = analysis.summarize(values)
        if good.size:
            q1, q3 = np.percentile(good, [25.0, 75.0])
            assert s.median == np.median(good) and s.spread == 0.5 * (q3 - q1)


def test_nan_and_inf_values_are_excluded_and_counted():
    values = np.array([3.0, np.nan, 1.0, np.inf, 2.0, np.nan, -np.inf])
    s = analysis.summarize(values)
    assert s.median == 2.0
    assert (s.used, s.excluded) == (3, 4)
    assert s.ci_low == 1.0 and s.ci_high == 3.0  # three values: the interval is their range


def test_rows_are_summarised_as_each_row_alone_bit_for_bit():
    rng = np.random.default_rng(1)
    rows = rng.normal(size=(4, 5, 64))
    rows[rng.random(rows.shape) < 0.1] = np.nan
    rows[1, 2] = np.nan  # a row with no valid value
    together = analysis.summarize(rows)
    assert together.median.shape == (4, 5)
    for i, j in np.ndindex(4, 5):
        alone = analysis.summarize(rows[i, j])
        for field, value in zip(together, alone):
            np.testing.assert_array_equal(field[i, j], value)
    assert together.used[1, 2] == 0 and np.isnan(together.ci_low[1, 2])


@pytest.mark.parametrize("n", [6, 7, 10, 31, 64, 255, 256, 1000])
def test_interval_is_scipys_exact_order_statistic_interval_of_the_median(n):
    x = np.random.default_rng(n).normal(size=n)
    reference = stats.quantile_test(x, q=np.median(x), p=0.5).confidence_interval(0.95)
    s = analysis.summarize(x)
    assert (s.ci_low, s.ci_high) == (reference.low, reference.high)


def test_interval_covers_the_true_median_at_least_as_often_as_asked():
    """Cauchy samples (no mean, heavy tails): the order-statistic interval is distribution-free."""
    rng = np.random.default_rng(2)
    s = analysis.summarize(rng.standard_cauchy(size=(4000, 64)))
    coverage = np.mean((s.ci_low <= 0.0) & (0.0 <= s.ci_high))
    assert 0.95 <= coverage < 0.98  # exact coverage at n = 64: 1 - 2 P(B <= 23) = 0.9649


def test_interval_narrows_as_one_over_root_n_and_has_the_normal_theory_width():
    """Median of N standard normals: standard error sqrt(π/2)/sqrt(N); a 95 % interval spans ±1.96 of it."""
    rng = np.random.default_rng(2)
    widths = {}
    for n in (400, 6400):
        s = analysis.summarize(rng.normal(size=n))
        widths[n] = s.ci_high - s.ci_low
        expected = 2 * 1.96 * np.sqrt(np.pi / 2 / n)
        assert 0.6 * expected < widths[n] < 1.5 * expected
    assert 2.5 < widths[400] / widths[6400] < 6.0  # sqrt(16) = 4


def test_narrower_confidence_gives_a_nested_interval():
    values = np.random.default_rng(3).normal(size=500)
    wide = analysis.summarize(values, confidence=0.95)
    narrow = analysis.summarize(values, confidence=0.5)
    assert wide.ci_low < narrow.ci_low < narrow.median < narrow.ci_high < wide.ci_high


def test_confidence_outside_zero_one_is_refused():
    with pytest.raises(ValueError, match="confidence"):
        analysis.summarize([1.0, 2.0], confidence=1.0)


def test_no_valid_value_gives_nan_statistics_and_zero_used():
    for values in ([], [np.nan, np.nan]):
        s = analysis.summarize(values)
        assert all(np.isnan(v) for v in s[:4])
        assert s.used == 0 and s.excluded == len(values)


def test_single_value_summary_is_that_value():
    s = analysis.summarize([4.2, np.nan])
    assert (s.median, s.spread, s.ci_low, s.ci_high, s.used, s.excluded) == (4.2, 0.0, 4.2, 4.2, 1, 1)


# --- regression ----------------------------------------------------------------------------------------


def test_exact_line_is_recovered():
    x = np.linspace(0.5, 3.0, 11)
    r = analysis.regression(x, 2.5 * x - 0.75)
    assert r.slope == pytest.approx(2.5, rel=1e-12)
    assert r.intercept == pytest.approx(-0.75, rel=1e-12)
    assert r.r2 == pytest.approx(1.0, abs=1e-14)
    assert r.points == 11


def test_worst_point_is_the_largest_relative_deviation_by_flat_index():
    x = np.array([[1.0, 2.0, 4.0], [8.0, 10.0, 0.5]])
    y = x * np.array([[1.01, 0.99, 1.02], [1.00, 0.97, 1.05]])
    r = analysis.regression(x, y)
    assert r.worst == 5
    assert r.worst_error == pytest.approx(0.05, rel=1e-12)
    assert 0.99 < r.r2 < 1.0


def test_non_finite_points_are_skipped_for_the_fit_and_the_worst_point():
    x = np.array([1.0, 2.0, np.nan, 4.0, 5.0, 6.0])
    y = np.array([2.0, 4.0, 100.0, 8.0, np.inf, 12.1])
    r = analysis.regression(x, y)
    assert r.points == 4
    assert r.worst == 5
    assert r.worst_error == pytest.approx(6.1 / 6.0, rel=1e-12)
    good = np.isfinite(x) & np.isfinite(y)
    slope, intercept = np.polyfit(x[good], y[good], 1)
    assert (r.slope, r.intercept) == pytest.approx((slope, intercept), rel=1e-12)


def test_zero_theory_with_nonzero_measurement_is_infinitely_wrong():
    r = analysis.regression([0.0, 1.0, 2.0], [0.1, 1.0, 2.0])
    assert r.worst == 0 and r.worst_error == np.inf


def test_point_where_measurement_equals_zero_theory_is_not_the_worst():
    r = analysis.regression([0.0, 1.0, 2.0], [0.0, 1.0, 2.1])
    assert r.worst == 2 and r.worst_error == pytest.approx(0.05, rel=1e-12)


@pytest.mark.parametrize("x, y", [([], []), ([1.0], [2.0]), ([1.0, np.nan, 3.0], [np.nan, 2.0, 4.0]),
                                  ([2.0, 2.0, 2.0], [1.0, 2.0, 3.0])])
def test_fewer_than_two_usable_points_or_constant_x_give_nan_fields(x, y):
    r = analysis.regression(x, y)
    assert np.isnan(r.slope) and np.isnan(r.intercept) and np.isnan(r.r2) and np.isnan(r.worst_error)
    assert r.worst == -1
    assert r.points == np.count_nonzero(np.isfinite(x) & np.isfinite(y))


def test_mismatched_sizes_raise_a_clear_error():
    with pytest.raises(ValueError, match="same size"):
        analysis.regression([1.0, 2.0, 3.0], [1.0, 2.0])


# --- the phase fit's kernel against its numpy formulation --------------------------------------------------


def _phase_fit_numpy(times, transverse, weights, spin):
    """The numpy formulation the kernel replaced (np.unwrap, least squares about the means, np.median)."""
    x = np.sqrt(weights[0]) * transverse[..., 0]
    y = np.sqrt(weights[1]) * transverse[..., 1]
    radius = np.hypot(x, y)
    phase = np.unwrap(np.arctan2(y, x), axis=1)
    finite = np.all(np.isfinite(phase), axis=1)
    signal = np.min(np.where(np.isfinite(radius), radius, 0.0), axis=1) > analysis.NO_SIGNAL * abs(spin)
    with np.errstate(invalid="ignore"):
        steps_ok = np.all(np.abs(np.diff(phase, axis=1)) <= analysis.MAX_PHASE_STEP, axis=1)
    y_fit = np.where(np.isfinite(phase), phase, 0.0)
    dt = times - times.mean()
    slope = ((y_fit - y_fit.mean(axis=1, keepdims=True)) * dt).sum(axis=1) / (dt * dt).sum()
    code = np.where(~signal | ~finite, FIT_NO_SIGNAL, np.where(steps_ok, FIT_OK, FIT_UNDERSAMPLED))
    return np.where(code == FIT_OK, np.abs(slope), np.nan), np.median(radius, axis=1), code


def test_phase_fit_kernel_agrees_with_its_numpy_formulation_on_every_outcome():
    rng = np.random.default_rng(5)
    times = np.sort(rng.uniform(0.0, 20.0, 200))
    omega = rng.uniform(0.2, 3.0, (300, 1))
    phase = omega * times + rng.uniform(-np.pi, np.pi, (300, 1)) + 0.05 * np.sin(3 * times)
    transverse = np.stack([np.cos(phase), 0.3 * np.sin(phase)], axis=-1) * rng.uniform(1e-6, 1.0, (300, 1, 1))
    transverse[0] *= 1e-14  # round-off: no signal
    transverse[1, 50:] = np.nan  # a broken sample
    transverse[2] = np.stack([np.cos(9 * phase[2]), np.sin(9 * phase[2])], axis=-1)  # aliased: undersampled
    weights, spin = np.array([3.0, 1 / 3.0]), 2.0
    fit = analysis.oscillation_frequencies(times, transverse, weights, spin)
    frequency, radius, code = _phase_fit_numpy(times, transverse, weights, spin)
    np.testing.assert_array_equal(fit.code, code)
    assert {FIT_OK, FIT_NO_SIGNAL, FIT_UNDERSAMPLED} <= set(code.tolist())
    np.testing.assert_allclose(fit.frequency, frequency, rtol=1e-12, atol=0.0, equal_nan=True)
    np.testing.assert_allclose(fit.radius, radius, rtol=1e-15, atol=0.0, equal_nan=True)


def test_phase_fit_rows_of_several_time_grids_are_each_grid_alone():
    rng = np.random.default_rng(6)
    grids = np.stack([np.linspace(0.0, 10.0, 65), np.linspace(0.0, 3.0, 65)])
    phase = rng.uniform(0.5, 2.0, (8, 1)) * grids[np.arange(8) % 2]
    transverse = np.stack([np.cos(phase), np.sin(phase)], axis=-1)
    together = analysis.oscillation_frequencies(grids[np.arange(8) % 2], transverse, np.ones(2), 1.0)
    for i in range(8):
        alone = analysis.oscillation_frequencies(grids[i % 2], transverse[i:i + 1], np.ones(2), 1.0)
        assert together.frequency[i] == alone.frequency[0] and together.radius[i] == alone.radius[0]


def _growth_numpy(times, norms, saturation):
    """The numpy formulation the growth kernel replaced: (rate, points, code)."""
    n, p = norms.shape
    h = (times[-1] - times[0]) / (p - 1)
    finite = np.isfinite(norms) & (norms > 0)
    beyond = ~finite | (norms > saturation)
    stop = np.where(beyond.any(axis=1), beyond.argmax(axis=1), p)
    s = np.where(finite, norms, 1.0) ** 2
    interior = np.arange(1, p - 1)[None, :] + 1 < stop[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        d = (s[:, 2:] + s[:, :-2] - 2.0 * s[:, 1:-1]) / (2.0 * s[:, 1:-1])
        mean = np.where(interior, d, 0.0).sum(axis=1) / interior.sum(axis=1)
        rate = np.arcsinh(np.sqrt(mean / 2.0)) / h
    good = (stop >= analysis.MIN_POINTS) & (mean > 0) & np.isfinite(rate)
    return np.where(good, rate, np.nan), np.where(good, stop, 0), np.where(good, FIT_OK, FIT_SHORT_WINDOW)


def test_growth_kernel_agrees_with_its_numpy_formulation_on_every_outcome():
    rng = np.random.default_rng(7)
    times = np.arange(257) * 0.05
    lam = rng.uniform(0.3, 2.0, (400, 1))
    a, b = rng.uniform(1e-6, 1e-3, (400, 1)), rng.uniform(0.0, 1e-3, (400, 1))
    norms = np.sqrt(2 * (a**2 * np.exp(2 * lam * times) + b**2 * np.exp(-2 * lam * times)))
    norms[0, 3:] = np.nan  # stopped early: too short a window
    norms[1] = 1e-3  # no growth at all
    norms[2, 100:] = np.nan  # stopped inside its window
    saturation = 1e-2
    fit = analysis.growth_rates(times, norms, saturation)
    rate, points, code = _growth_numpy(times, norms, saturation)
    np.testing.assert_array_equal(fit.code, code)
    np.testing.assert_array_equal(fit.points, points)
    assert {FIT_OK, FIT_SHORT_WINDOW} <= set(code.tolist())
    np.testing.assert_allclose(fit.rate, rate, rtol=1e-11, atol=0.0, equal_nan=True)


def test_the_phase_fits_median_by_selection_is_numpys_median_with_ties_and_even_lengths():
    from tumble.kernels.fits import _median_in_place

    rng = np.random.default_rng(8)
    for n in [*range(1, 30), 256, 257]:
        for _ in range(20):
            values = np.round(rng.normal(size=n), 1)  # many ties
            assert _median_in_place(values.copy()) == np.median(values)
        ramp = np.arange(n, dtype=float)
        for values in (np.full(n, 0.5), ramp, ramp[::-1], np.sin(ramp), np.r_[np.zeros(n // 2), np.ones(n - n // 2)]):
            assert _median_in_place(values.copy()) == np.median(values)


def test_transverse_norms_are_the_numpy_expression_bit_for_bit():
    """The kernel's norms equal ``np.sqrt(g_b w_b**2 + g_c w_c**2)`` bit for bit (no fused multiply-add), for
    each sample's own columns and weights, over magnitudes from 1e-160 to 1e150 (inf where the squares overflow, as
    numpy's)."""
    rng = np.random.default_rng(3)
    n, t = 97, 13
    states = rng.normal(size=(n, t, 3)) * 10.0 ** rng.uniform(-160, 150, size=(n, t, 3))
    b = rng.integers(0, 3, size=n)
    c = (b + rng.integers(1, 3, size=n)) % 3
    weights = rng.uniform(0.1, 10.0, size=(n, 2))
    everyone = np.arange(n)
    with np.errstate(over="ignore", under="ignore"):
        expected = np.sqrt(weights[:, :1] * states[everyone, :, b] ** 2 + weights[:, 1:] * states[everyone, :, c] ** 2)
    got = analysis.transverse_norms(states, np.stack([b, c], axis=1), weights)
    assert got.shape == (n, t)
    assert np.array_equal(got, expected)


def test_median_interval_rank_is_scipy_binomial_rank_without_importing_scipy_special():
    from scipy.special import bdtr

    for confidence in (0.9, 0.95, 0.99):
        for n in [*range(1, 2001), 4096, 65536, 2**20, 1000003]:
            expected = max(1, int(np.count_nonzero(bdtr(np.arange(n), n, 0.5) <= 0.5 * (1.0 - confidence))))
            assert analysis.median_interval_rank(n, confidence) == expected, (n, confidence)
