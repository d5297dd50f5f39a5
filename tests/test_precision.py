"""Work-precision data (tumble.measure.precision): schema, convergence orders, the closed form's accuracy, SciPy's
tolerances, and reading speed-ups off the curves."""

import math

import numpy as np
import pytest
import xarray as xr

from tumble.measure import precision
from tumble.measure.precision import default_steps, speedups, time_to_error, work_precision

TINY_STEPS = {"rk4": [8, 16, 32, 64], "splitting2": [8, 16, 32]}
TINY_RTOLS = [1e-3, 1e-6, 1e-9]


@pytest.fixture(scope="module")
def tiny():
    """64 spins about the intermediate axis of (1, 2, 3) to t = 2 s: rk4, splitting2, exact, RK45, DOP853
    (heyoka left out, whether installed or not: the closed form is the reference)."""
    return work_precision(samples=64, t_end=2.0, repeats=1, methods=["rk4", "splitting2"], steps=TINY_STEPS,
                          rtols=TINY_RTOLS, heyoka_tols=())


def test_tiny_run_has_the_documented_schema(tiny):
    assert list(tiny.solver.values) == ["rk4", "splitting2", "exact", "scipy_RK45", "scipy_DOP853"]
    assert dict(tiny.sizes) == {"solver": 5, "wp_point": 4}
    for name in ("wp_error", "wp_error_median", "wp_wall", "wp_setting", "wp_steps", "wp_nfev"):
        assert tiny[name].dims == ("solver", "wp_point")
    assert tiny.compile_time.dims == ("solver",)
    for var in tiny.variables.values():
        assert "units" in var.attrs and "long_name" in var.attrs
    for key in ("I1", "I2", "I3", "axis", "spin", "amplitude", "samples", "t_end", "seed", "repeats", "machine",
                "numba_threads", "date"):
        assert key in tiny.attrs
    assert tiny.attrs["samples"] == 64 and tiny.attrs["t_end"] == 2.0


def test_short_curves_are_padded_with_nan(tiny):
    err = tiny.wp_error
    assert np.isfinite(err.sel(solver="rk4")).all()
    assert np.isfinite(err.sel(solver="splitting2")).sum() == 3 and np.isnan(err.sel(solver="splitting2")[3])
    assert np.isfinite(err.sel(solver="exact")).sum() == 1 and np.isnan(tiny.wp_setting.sel(solver="exact")).all()
    assert np.isnan(tiny.wp_wall.sel(solver="scipy_DOP853")[3])


def test_settings_are_steps_for_tumble_and_rtol_for_scipy(tiny):
    np.testing.assert_allclose(tiny.wp_setting.sel(solver="rk4"), [0.25, 0.125, 0.0625, 0.03125])
    np.testing.assert_array_equal(tiny.wp_steps.sel(solver="rk4"), [8, 16, 32, 64])
    np.testing.assert_allclose(tiny.wp_setting.sel(solver="scipy_RK45")[:3], TINY_RTOLS)
    assert (tiny.wp_nfev.sel(solver="scipy_RK45")[:3] > 0).all()
    assert (tiny.compile_time.sel(solver=["scipy_RK45", "scipy_DOP853"]) == 0).all()
    assert (tiny.wp_wall.sel(solver="rk4") > 0).all()


def test_rk4_error_falls_at_fourth_order(tiny):
    err = tiny.wp_error.sel(solver="rk4").values
    slopes = np.log2(err[1:-1] / err[2:])  # halving dt: error / 2**4
    np.testing.assert_allclose(slopes, 4.0, atol=0.1)
    median = tiny.wp_error_median.sel(solver="rk4").values
    assert (median <= err).all()


def test_splitting2_error_falls_at_second_order(tiny):
    err = tiny.wp_error.sel(solver="splitting2").values[:3]
    np.testing.assert_allclose(np.log2(err[:-1] / err[1:]), 2.0, atol=0.1)


def test_closed_form_is_accurate_to_round_off(tiny):
    assert 0 <= float(tiny.wp_error.sel(solver="exact")[0]) <= 1e-12


def test_without_heyoka_the_closed_form_is_the_reference(tiny):
    assert tiny.attrs["reference"].startswith("closed form")
    assert tiny.attrs["heyoka"] in ("left out", "not installed (pip install 'tumble[bench]')")
    assert math.isnan(tiny.attrs["reference_vs_exact_max"])


def test_missing_heyoka_leaves_its_rows_out_with_a_note(monkeypatch):
    monkeypatch.setattr(precision, "_import_heyoka", lambda: None)
    ds = work_precision(samples=8, t_end=1.0, repeats=1, methods=["rk4"], steps=[8], scipy_methods=())
    assert list(ds.solver.values) == ["rk4", "exact"]
    assert ds.attrs["heyoka"].startswith("not installed")
    assert ds.attrs["reference"].startswith("closed form")
    with pytest.raises(ImportError, match="heyoka"):
        work_precision(samples=8, t_end=1.0, repeats=1, methods=["rk4"], steps=[8], scipy_methods=(),
                       heyoka_tols=[1e-6])


def test_heyoka_is_a_peer_and_its_long_double_run_the_reference():
    hy = pytest.importorskip("heyoka")
    tols = [1e-3, 1e-7, 1e-11, 1e-15]
    ds = work_precision(samples=50, t_end=5.0, repeats=1, methods=["rk4"], steps=[16, 64], scipy_methods=(),
                        heyoka_tols=tols)
    assert list(ds.solver.values) == ["rk4", "exact", "heyoka"]
    assert str(ds.solver_kind.sel(solver="heyoka").values) == "heyoka"
    assert ds.attrs["reference"].startswith("heyoka") and ds.attrs["heyoka_batch_size"] == hy.recommended_simd_size()
    # the long-double reference and the closed form agree to round-off; the closed form's error is that distance
    assert 0 < ds.attrs["reference_vs_exact_max"] < 1e-13
    assert float(ds.wp_error.sel(solver="exact")[0]) == ds.attrs["reference_vs_exact_max"]
    np.testing.assert_allclose(ds.wp_setting.sel(solver="heyoka")[:4], tols)
    err = ds.wp_error.sel(solver="heyoka").values[:4]
    assert (np.diff(err) < 0).all() and err[-1] < 1e-13, err
    assert (ds.wp_steps.sel(solver="heyoka")[:4] > 0).all() and (ds.wp_wall.sel(solver="heyoka")[:4] > 0).all()
    assert float(ds.compile_time.sel(solver="heyoka")) > 0
    table = speedups(ds, errors=(1e-6,), baseline="heyoka")
    assert np.isfinite(table.exact_speedup).all()


def test_scipy_error_falls_as_rtol_tightens(tiny):
    for solver in ("scipy_RK45", "scipy_DOP853"):
        err = tiny.wp_error.sel(solver=solver).values[:3]
        assert (np.diff(err) < 0).all(), (solver, err)


def _synthetic():
    """Curves with known log-log interpolants: DOP853 1 s -> 1e-2, 10 s -> 1e-8 (1e-5 at sqrt(10) s); rk4
    0.01 s -> 1e-3, 0.1 s -> 1e-7 (1e-5 at sqrt(10)/100 s): a ratio of exactly 100."""
    nan = np.nan
    solvers = ["rk4", "splitting2", "exact", "scipy_DOP853"]
    wall = np.array([[0.01, 0.1, 0.2], [0.01, 1.0, nan], [1e-3, nan, nan], [1.0, 10.0, nan]])
    # rk4's third point is slower and worse than its second: dominated, it must not matter.
    error = np.array([[1e-3, 1e-7, 1e-6], [1e-1, 1e-3, nan], [1e-14, nan, nan], [1e-2, 1e-8, nan]])
    dims = ("solver", "wp_point")
    return xr.Dataset({"wp_wall": (dims, wall), "wp_error": (dims, error)},
                      coords={"solver": solvers, "wp_point": np.arange(3)})


def test_speedup_is_read_off_by_log_log_interpolation():
    table = speedups(_synthetic(), errors=(1e-5,), baseline="scipy_DOP853")
    np.testing.assert_allclose(table.time_to_error.sel(solver="scipy_DOP853"), [math.sqrt(10)], rtol=1e-12)
    np.testing.assert_allclose(table.time_to_error.sel(solver="rk4"), [math.sqrt(10) / 100], rtol=1e-12)
    np.testing.assert_allclose(table.speedup.sel(solver="rk4"), [100.0], rtol=1e-12)
    np.testing.assert_allclose(table.exact_speedup, [math.sqrt(10) / 1e-3], rtol=1e-12)
    assert str(table.best_tumble.values[0]) == "rk4"
    np.testing.assert_allclose(table.best_tumble_speedup, [100.0], rtol=1e-12)


def test_a_solver_that_never_reaches_an_error_gives_nan():
    table = speedups(_synthetic(), errors=(1e-5, 1e-9, 1e-15), baseline="scipy_DOP853")
    assert np.isnan(table.time_to_error.sel(solver="splitting2")).all()
    assert np.isnan(table.speedup.sel(solver="splitting2")).all()
    # the baseline itself never reaches 1e-9: no ratio for anyone there; nobody reaches 1e-15
    assert np.isnan(table.speedup.sel(error=1e-9)).all()
    assert str(table.best_tumble.sel(error=1e-15).values) == ""
    assert np.isnan(table.best_tumble_speedup.sel(error=1e-15))


def test_a_loose_error_costs_the_fastest_point_that_reaches_it():
    assert time_to_error([0.5, 2.0], [1e-6, 1e-9], 1e-3) == 0.5
    assert math.isnan(time_to_error([0.5, 2.0], [1e-6, 1e-9], 1e-12))
    assert math.isnan(time_to_error([np.nan], [np.nan], 1e-3))


def test_speedups_rejects_an_unknown_baseline():
    with pytest.raises(ValueError, match="baseline"):
        speedups(_synthetic(), baseline="scipy_RK23")


def test_bad_settings_raise_clear_errors():
    with pytest.raises(ValueError, match="methods"):
        work_precision(samples=4, methods=["rk5"])
    with pytest.raises(ValueError, match="scipy_methods"):
        work_precision(samples=4, scipy_methods=["Radau"])
    with pytest.raises(ValueError, match="repeats"):
        work_precision(samples=4, repeats=0)


def test_default_ladders_are_shorter_for_higher_order():
    assert len(default_steps("rk8")) < min(len(default_steps("rk4")), len(default_steps("splitting2")))
    steps = default_steps("rk4")
    np.testing.assert_array_equal(steps[1:] // steps[:-1], 2)
