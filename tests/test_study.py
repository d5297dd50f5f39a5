"""tumble.measure, scans and their regressions: rates against linear theory and the exact solution, the
skipping a scene does, degenerate bodies, dataset contract and files."""

import numpy as np
import pytest
import xarray as xr

import tumble
from tumble.engine import sampling
from tumble.measure import planning, reduction, running, scans, traces
from tumble.measure.regression import flip_time_law, regress_scan
from tumble.measure.running import SAMPLE_STATUS_NAMES
from tumble.measure.scans import inertia_triangle, scan
from tumble.measure.scene import measure
from tumble.output import io
from tumble.physics import exact, shapes, theory

MOMENTS = (1.0, 2.0, 3.0)


@pytest.fixture(scope="module")
def intermediate_rk4(warm_kernels):
    return measure(MOMENTS, 2, spin=1.5, amplitude=1e-4, samples=96, seed=3, method="rk4")


@pytest.fixture(scope="module")
def intermediate_exact():
    return measure(MOMENTS, 2, spin=1.5, amplitude=1e-4, samples=96, seed=3)


def test_measure_follows_the_contract():
    ds = tumble.measure(MOMENTS, 2)
    for name in ("rate", "rate_theory", "rel_error", "kind"):
        assert ds[name].ndim == 0, name
    assert ds["sample_rate"].dims == ("sample",) and ds.sizes["sample"] == 1024
    assert str(ds["kind"].values) == "exponential"
    assert float(ds["rate_theory"]) == pytest.approx(theory.linear(MOMENTS, 2, 1.0)[1], rel=1e-15)
    assert float(ds["rel_error"]) == pytest.approx(abs(float(ds.rate) / float(ds.rate_theory) - 1), rel=1e-12)
    for name, variable in ds.variables.items():
        assert "units" in variable.attrs and "long_name" in variable.attrs, name


@pytest.mark.parametrize("axis", [1, 2, 3])
@pytest.mark.parametrize("body", [MOMENTS, shapes.t_handle(), (1.0, 1.5, 1.7)], ids=["lamina", "t_handle", "generic"])
def test_closed_form_rates_meet_the_accuracy_targets(body, axis):
    ds = measure(body, axis, amplitude=1e-3, samples=128)
    kind = str(ds.kind.values)
    assert kind == theory.linear(body, axis)[0]
    assert float(ds.rel_error) < (1e-3 if kind == "periodic" else 5e-3)
    assert int(ds.samples_used) >= 120
    assert float(ds.rate_ci_low) <= float(ds.rate) <= float(ds.rate_ci_high)
    assert int(ds.sample_steps_computed) == 0 and str(ds.path.values) == "closed form"


def test_periodic_rate_error_is_the_nonlinear_correction_of_order_amplitude_squared():
    errors = [float(measure(MOMENTS, 1, amplitude=eps, samples=32).rel_error) for eps in (1e-3, 1e-2)]
    assert errors[1] / errors[0] == pytest.approx(100.0, rel=0.05)


def test_periodic_sample_rates_are_the_exact_frequencies():
    """The invariant phase advances by 2π per period of the exact motion: each sample's rate is 2π/period."""
    ds = measure(MOMENTS, 3, amplitude=0.05, samples=64, seed=5)
    w0 = sampling.perturbed_spins(MOMENTS, 3, 1.0, 0.05, 64, seed=5)
    np.testing.assert_allclose(ds.sample_rate, 2 * np.pi / exact.period(MOMENTS, w0), rtol=2e-3)


def test_stepping_agrees_with_the_closed_form_and_times_flips_to_a_millionth(intermediate_rk4, intermediate_exact):
    stepped, closed = intermediate_rk4, intermediate_exact
    assert str(stepped.path.values) == "fixed-step kernel"
    # Probe times are rounded to whole steps, so the windows differ by a probe here and there: 1e-5.
    np.testing.assert_allclose(stepped.sample_rate, closed.sample_rate, rtol=3e-5)
    assert float(stepped.rate) == pytest.approx(float(closed.rate), rel=1e-5)
    assert float(stepped.flip_spacing_rel_error) < 1e-6
    assert float(stepped.flip_spacing) == pytest.approx(float(stepped.flip_spacing_exact), rel=1e-6)
    assert float(stepped.flip_spacing) == pytest.approx(float(stepped.flip_spacing_asymptote), rel=1e-3)
    assert int(stepped.flips_timed) >= 90


def test_samples_stop_once_their_measurement_is_complete(intermediate_rk4, intermediate_exact):
    """Early stop skipped steps and changed no requested result (previous test: same rates as closed form)."""
    ds = intermediate_rk4
    total = int(ds.n_steps) * ds.sizes["sample"]
    assert int(ds.sample_steps_skipped) > 0.1 * total
    np.testing.assert_array_equal(np.isnan(ds.sample_first_flip), np.isnan(intermediate_exact.sample_first_flip))


def test_stepping_periodic_rates_match_the_closed_form(warm_kernels):
    stepped = measure(MOMENTS, 1, amplitude=1e-2, samples=16, method="rk4")
    closed = measure(MOMENTS, 1, amplitude=1e-2, samples=16)
    np.testing.assert_allclose(stepped.sample_rate, closed.sample_rate, rtol=1e-7)


@pytest.mark.parametrize("body, axis, kind", [
    ((1.0, 1.0, 1.0), 1, "neutral"), ((1.0, 1.0, 1.0), 3, "neutral"),
    ((1.0, 1.0, 2.0), 1, "neutral"), ((1.0, 1.0, 2.0), 3, "periodic"),
    ((1.0, 2.0, 2.0), 1, "periodic"), ((1.0, 2.0, 2.0), 3, "neutral"),
    ((2.0, 2.0, 1.0), 2, "neutral"), ((1.0, 2.0, 3.0), 2, "exponential")])
def test_degenerate_bodies_get_a_clear_answer(body, axis, kind):
    """Symmetric tops, a sphere, a flat lamina: a kind and finite numbers, never NaN."""
    ds = measure(body, axis, amplitude=1e-3, samples=32)
    assert str(ds.kind.values) == kind
    for name in ("rate", "rate_theory", "rel_error"):
        assert np.isfinite(float(ds[name])), name
    if kind == "neutral":
        assert float(ds.rate_theory) == 0.0
        assert float(ds.rate) < 2e-3  # the slow O(amplitude) precession of the degenerate pair
    else:
        assert float(ds.rel_error) < 5e-3


def test_neutral_symmetric_top_measures_the_precession_of_its_equal_pair():
    """I1 = I2: w3 is constant and (w1, w2) turns at w3 (I3 - I1)/I1 — the rate a neutral scene reports."""
    ds = measure((1.0, 1.0, 2.0), 1, amplitude=1e-2, samples=64, seed=2)
    w0 = sampling.perturbed_spins((1.0, 1.0, 2.0), 1, 1.0, 1e-2, 64, seed=2)
    np.testing.assert_allclose(ds.sample_rate, np.abs(w0[:, 2]) * (2.0 - 1.0) / 1.0, rtol=1e-6)


def test_bad_samples_are_excluded_and_counted(monkeypatch):
    def on_the_axis(moments, axis, spin, amplitude, entropy, distribution, start, stop):  # no tilt: the phase is noise
        w = np.zeros((stop - start, 3))
        w[:, axis - 1] = spin
        return w

    monkeypatch.setattr(running, "drawn_spins", on_the_axis)  # (amplitude = 0 itself is refused)
    with pytest.warns(RuntimeWarning, match="no sample"):
        ds = measure(MOMENTS, 1, amplitude=1e-3, samples=8)
    assert int(ds.samples_used) == 0 and int(ds.samples_excluded) == 8
    assert np.all(ds.sample_status == SAMPLE_STATUS_NAMES.index("no signal"))


@pytest.mark.parametrize("kwargs, message", [
    (dict(axis=4), "axis"), (dict(axis=2, samples=0), "samples"), (dict(axis=2, method="euler"), "method"),
    (dict(axis=2, spin=0.0), "spin"), (dict(axis=2, amplitude=-1.0), "amplitude"), (dict(axis=2, seed=-3), "seed"),
    (dict(axis=2, dt=0.0), "dt"), (dict(axis=2, flips=-1), "flips")])
def test_bad_scene_parameters_name_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        measure(MOMENTS, **kwargs)


def test_the_same_seed_gives_the_same_dataset():
    a, b = measure(MOMENTS, 2, samples=50, seed=11), measure(MOMENTS, 2, samples=50, seed=11)
    xr.testing.assert_identical(a, b)
    c = measure(MOMENTS, 2, samples=50, seed=12)
    assert not np.array_equal(a.sample_rate, c.sample_rate)


@pytest.fixture(scope="module")
def small_scan():
    moments, coords = inertia_triangle(3)
    return scan(moments, axis=[1, 2, 3], amplitude=[1e-4, 1e-3, 1e-2], samples=48, body_coords=coords)


def test_inertia_triangle_points_are_valid_ordered_bodies():
    moments, coords = inertia_triangle(20)
    assert moments.shape == (400, 3)
    i1, i2, i3 = moments.T
    assert np.all((i1 < i2) & (i2 < i3) & (i1 + i2 > i3))
    for body in moments[::37]:
        tumble.Body(*body)


def test_scan_parameters_are_coordinates(small_scan):
    ds = small_scan
    assert ds["rate"].dims == ("body", "axis", "amplitude")
    assert ds["sample_rate"].dims == ("body", "axis", "amplitude", "sample")
    for name in ("I1", "I2", "I3", "i2_over_i3"):
        assert ds[name].dims == ("body",)
    assert list(ds.axis.values) == [1, 2, 3] and ds["method"].ndim == 0
    one = measure((ds.I1[4].item(), ds.I2[4].item(), ds.I3[4].item()), 2, amplitude=1e-3, samples=48)
    np.testing.assert_array_equal(ds.sample_rate.sel(axis=2, amplitude=1e-3).isel(body=4), one.sample_rate)


def test_scan_regression_finds_slope_one(small_scan):
    fit = regress_scan(small_scan.sel(amplitude=[1e-4, 1e-3]))
    assert set(fit.kind.values) == {"periodic", "exponential"}
    np.testing.assert_allclose(fit.slope, 1.0, atol=2e-3)
    assert np.all(fit.r2 > 0.9999)
    periodic = fit.sel(kind="periodic")
    assert float(periodic.worst_rel_error) == pytest.approx(
        float(small_scan.rel_error.where(small_scan.kind == "periodic").sel(amplitude=[1e-4, 1e-3]).max()), rel=1e-9)


def test_flip_time_law_has_slope_one_over_lambda(small_scan):
    law = flip_time_law(small_scan.sel(axis=2, amplitude=[1e-4, 1e-3]))  # 1e-2: not small for every body
    assert law.slope.dims == ("body",)
    np.testing.assert_allclose(law.slope, law.slope_theory, rtol=1e-3)
    with pytest.raises(ValueError, match="amplitude"):
        flip_time_law(small_scan.isel(amplitude=0))


def test_scan_writes_and_reads_back_identically(small_scan, tmp_path):
    written = io.write_dataset(small_scan, tmp_path / "scan.nc", study={"scan": "triangle"}, seed_entropy=0)
    back = io.read_dataset(tmp_path / "scan.nc", require_tumble=True)
    xr.testing.assert_identical(back, written)
    for attr in ("Conventions", "title", "history", "source", "study", "seed_entropy"):
        assert attr in back.attrs


# --- torque, horizon, curves, invariant drift ------------------------------------------------------------

SPIN_UP = [None, (0.0, 0.0, 0.5), {"profile": "ramp", "vector": (0, 0, 0.5), "duration": 3.0},
           {"profile": "sine", "vector": (0, 0, -0.3), "period": 4.0},
           {"profile": "pulse", "vector": (0, 0, 0.5), "duration": 2.0}]


@pytest.mark.parametrize("torque", SPIN_UP, ids=["free", "constant", "ramp", "sine", "pulse"])
def test_a_torque_about_the_spin_axis_is_measured_against_the_spun_up_theory(warm_kernels, torque):
    """Symmetric top (2, 2, 1) about its axis: the phase of (w1, w2) advances by β ∫ w3 dt."""
    ds = measure((2.0, 2.0, 1.0), 3, samples=32, torque=torque, horizon=20.0)
    free = measure((2.0, 2.0, 1.0), 3, samples=32, horizon=20.0)
    # The pulse's switch-off falls inside a fixed step: a first-order error there, documented.
    assert float(ds.rel_error) < (1e-3 if isinstance(torque, dict) and torque["profile"] == "pulse" else 1e-5)
    if torque is not None:
        assert ds.attrs["method_run"] == "rk4"
        assert abs(float(ds.rate_theory) - float(free.rate_theory)) > 1e-2  # the torque changed the answer


@pytest.mark.parametrize("kwargs, message", [
    (dict(axis=3, torque=(0.1, 0.0, 0.5)), "about the spin axis"),
    (dict(axis=2, torque=(0.0, 0.5, 0.0)), "stable"),
    (dict(axis=3, torque=(0.0, 0.0, 0.5), method="exact"), "closed form"),
    (dict(axis=3, torque=(0.0, 0.0, -5.0), horizon=20.0), "reverses the spin"),
    (dict(axis=3, horizon=-1.0), "horizon"),
    (dict(axis=3, curves=("movie",)), "curves"),
])
def test_bad_torque_scenes_are_refused(warm_kernels, kwargs, message):
    with pytest.raises(ValueError, match=message):
        measure((1.0, 2.0, 3.0) if kwargs["axis"] == 2 else (2.0, 2.0, 1.0), samples=8, **kwargs)


def test_curves_are_kept_only_when_asked_and_follow_the_theory():
    plain = measure(MOMENTS, 2, samples=64, seed=3)
    assert not {"growth_norm", "trace_omega"} & set(plain.data_vars)
    ds = measure(MOMENTS, 2, samples=64, seed=3, curves=("norm", "trace"))
    assert float(ds.rate) == float(plain.rate)  # keeping curves changes no result
    t, norm = ds.growth_time.values, ds.growth_norm.values
    # Late in the window the growing mode dominates the decaying one: the plain log-slope is the rate.
    start, stop = float(ds.fit_t_start), float(ds.fit_t_stop)
    inside = (t >= 0.5 * (start + stop)) & (t <= stop) & np.isfinite(norm)
    slope = np.polyfit(t[inside], np.log(norm[inside]), 1)[0]
    assert slope == pytest.approx(float(ds.rate_theory), rel=0.01)
    trace_t, trace_w = ds.trace_time.values, ds.trace_omega.values
    finite = np.isfinite(trace_t)
    w0 = trace_w[0]
    expected = exact.omega(MOMENTS, w0, trace_t[finite])
    np.testing.assert_allclose(trace_w[finite], expected, atol=1e-12)
    assert np.any(np.diff(np.sign(trace_w[finite, 1])) != 0)  # the traced spin flips within the horizon


def test_invariant_drift_separates_geometric_methods_from_runge_kutta(warm_kernels):
    ds = traces.invariant_drift(MOMENTS, 2, methods=("rk4", "splitting2"), samples=4)
    assert ds.drift_l2.dims == ("drift_method", "drift_time") and ds.drift_time.size == 201
    worst = ds.drift_l2.max("drift_time")
    assert float(worst.sel(drift_method="splitting2")) < 1e-14 < float(worst.sel(drift_method="rk4"))
    assert float(ds.drift_energy.isel(drift_time=0).max()) == 0.0


# --- scans in batches ------------------------------------------------------------------------------------------


def _same_records(a, b):
    assert list(a) == list(b)
    for name in a:
        assert a[name].dtype == b[name].dtype, name
        assert np.array_equal(a[name], b[name], equal_nan=a[name].dtype.kind == "f"), name


def test_closed_form_scenes_batched_are_the_same_bits_as_one_by_one():
    """Periodic, exponential (with flips and the norm curve) and neutral scenes of several bodies, mixed in one
    batch, against each scene alone and against a scene cut into sample ranges."""
    bodies = [(0.6, 0.8, 1.0), (1.0, 2.0, 3.0), (1.0, 1.0, 2.0), (2.0, 3.0, 4.5)]
    plans = [planning.scene_plan(body, axis, 1.5, amplitude, 96, 3, flips=2, curves=("norm",))
             for body in bodies for axis in (1, 2, 3) for amplitude in (1e-3, 1e-2)]
    assert {plan.kind for plan in plans} == {"periodic", "exponential", "neutral"}
    batched = scans.scene_batch(plans)
    for plan, record in zip(plans, batched):
        _same_records(record, scans.scene_batch([plan])[0])
    plan = planning.scene_plan((1.0, 2.0, 3.0), 2, 1.0, 1e-3, 3 * sampling.CHUNK, 0, flips=2)
    cut = reduction.scene_records([plan], [[running.scene_samples(plan, lo, lo + sampling.CHUNK)
                                            for lo in range(0, 3 * sampling.CHUNK, sampling.CHUNK)]])[0]
    _same_records(cut, scans.scene_batch([plan])[0])


def test_a_scan_is_its_scenes_measured_alone():
    moments, coords = inertia_triangle(2)
    ds = scan(moments, axis=[1, 2, 3], samples=64, seed=1, body_coords=coords)
    for b, axis in [(0, 1), (1, 2), (3, 3)]:
        alone = measure(moments[b], axis, samples=64, seed=1)
        for name in ("rate", "rate_ci_low", "rate_ci_high", "rate_spread", "sample_rate", "sample_status"):
            np.testing.assert_array_equal(ds[name].sel(body=b, axis=axis).values, alone[name].values)
        assert ds.rate.attrs == measure(moments[0], 1, samples=8).rate.attrs  # metadata of the first scene
