"""Paper figures: every figure draws from the schema it documents, labels its axes with units, refuses a
dataset it cannot use with a message naming what is missing, and files are written atomically."""

import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from matplotlib.figure import Figure

import tumble
from tumble.output import figures as plots
from tumble.physics import theory

from layout_checks import misplaced

LAMBDA = 1.0 / np.sqrt(3.0)  # growth rate of I = (1, 2, 3) spun at 1 rad/s about axis 2

#: Figures of a traced spin's attitude: tested in test_attitude_plots.py.
ATTITUDE = ("flip_strip", "flip_animation", "polhode", "herpolhode")
SCAN_FIGURES = [name for name in plots.FIGURES if name not in ATTITUDE]


def _scene_vars(moments, axis, spin=1.0):
    """Scene scalars as measure() gives them, for linear theory plus a small measured error."""
    kind, value = theory.linear(moments, axis, spin)
    rate = value * (1.0 + 1e-3)
    return kind, value, rate


@pytest.fixture(scope="module")
def triangle_scan():
    """A 4 × 4 inertia-triangle scan over axes 1–3: growth variables NaN outside exponential scenes."""
    moments, body_coords = tumble.inertia_triangle(4)
    axes = np.array([1, 2, 3])
    t = np.linspace(0.0, 40.0, 81)
    shape = (len(moments), len(axes))
    kind = np.empty(shape, dtype="<U11")
    rate, rate_theory = np.empty(shape), np.empty(shape)
    norm = np.full(shape + (len(t),), np.nan)
    fit = {n: np.full(shape, np.nan) for n in ("fit_t_start", "fit_t_stop", "fit_saturation")}
    for i, m in enumerate(moments):
        for j, a in enumerate(axes):
            kind[i, j], rate_theory[i, j], rate[i, j] = _scene_vars(m, a)
            if kind[i, j] == "exponential":
                lam = rate_theory[i, j]
                norm[i, j] = 1e-3 * np.exp(lam * t) / np.sqrt(1.0 + (1e-3 * np.exp(lam * t)) ** 2)
                fit["fit_t_start"][i, j], fit["fit_t_stop"][i, j] = 1.0, np.log(10.0) / lam
                fit["fit_saturation"][i, j] = 0.01
    dims = ("body", "axis")
    data = {
        "rate": (dims, rate, {"units": "1/s"}), "rate_theory": (dims, rate_theory), "kind": (dims, kind),
        "rel_error": (dims, np.abs(rate / rate_theory - 1.0)),
        "rate_ci_low": (dims, rate * 0.999), "rate_ci_high": (dims, rate * 1.001),
        "growth_norm": (dims + ("growth_time",), norm),
        "growth_norm_q1": (dims + ("growth_time",), 0.8 * norm),
        "growth_norm_q3": (dims + ("growth_time",), 1.25 * norm),
        **{n: (dims, v) for n, v in fit.items()},
    }
    coords = {"axis": axes, "body": np.arange(len(moments)), "growth_time": t, "spin": 1.0, "amplitude": 1e-3,
              "method": "auto", **{f"I{k + 1}": ("body", moments[:, k]) for k in range(3)},
              **{n: ("body", v) for n, v in body_coords.items()}}
    return xr.Dataset(data, coords=coords, attrs={"title": "synthetic triangle scan"})


@pytest.fixture(scope="module")
def amplitude_scan():
    """Flip times over five tilts for two spins (a second scan dimension), with per-sample spread."""
    rng = np.random.default_rng(3)
    eps = np.geomspace(1e-6, 1e-2, 5)
    spins = np.array([1.0, 2.0])
    lam = LAMBDA * spins[:, None] * np.ones((1, len(eps)))
    asymptote = np.log(4.0 / (0.5 * eps))[None, :] / lam
    samples = asymptote[..., None] * (1.0 + 0.02 * rng.standard_normal((2, len(eps), 16)))
    dims = ("spin", "amplitude")
    return xr.Dataset(
        {"flip_first": (dims, np.median(samples, axis=-1)), "flip_first_asymptote": (dims, asymptote),
         "rate_theory": (dims, lam), "rate": (dims, lam * 1.001), "kind": (dims, np.full(lam.shape, "exponential")),
         "rel_error": (dims, np.full(lam.shape, 1e-3)), "sample_first_flip": (dims + ("sample",), samples)},
        coords={"spin": spins, "amplitude": eps, "axis": 2, "sample": np.arange(16)})


@pytest.fixture(scope="module")
def measured():
    """One real scene, closed-form path (kernels load from numba's cache)."""
    return tumble.measure((1.0, 2.0, 3.0), axis=2, samples=32, seed=1)


@pytest.fixture(scope="module")
def measured_curves():
    """The same scene keeping its curves as measure() stores them: NaN-padded time variables along point
    dimensions (growth_point, trace_point) rather than time coordinates."""
    return tumble.measure((1.0, 2.0, 3.0), axis=2, samples=32, seed=1, curves=("norm", "trace"))


@pytest.fixture(scope="module")
def benchmark_like(measured):
    """The real scene plus what the other figures read: a trace, invariant drift, a work-precision table."""
    t = np.linspace(0.0, 80.0, 801)
    omega = tumble.exact.omega((1.0, 2.0, 3.0), np.array([1e-3, 1.0, 1e-3]), t)
    methods = ["rk4", "splitting4", "exact"]
    drift_time = np.linspace(0.0, 100.0, 21)
    drift = np.array([1e-12 * drift_time, 1e-15 * np.ones_like(drift_time), np.zeros_like(drift_time)])
    solvers = ["rk4", "splitting4", "exact", "scipy_RK45", "scipy_DOP853"]
    settings = np.array([[0.1, 0.05, 0.025], [0.1, 0.05, 0.025], [np.nan] * 3, [1e-6, 1e-8, 1e-10],
                         [1e-8, 1e-10, np.nan]])
    error = np.array([[1e-5, 6e-7, 4e-8], [1e-6, 6e-8, 4e-9], [2e-16, np.nan, np.nan], [1e-5, 1e-7, 1e-9],
                      [1e-8, 1e-10, np.nan]])
    wall = np.array([[1e-3, 2e-3, 4e-3], [1.5e-3, 3e-3, 6e-3], [5e-4, np.nan, np.nan], [0.1, 0.3, 1.0],
                     [0.2, 0.5, np.nan]])
    return measured.assign(
        trace_omega=(("trace_time", "component"), omega), drift_l2=(("drift_method", "drift_time"), drift),
        drift_energy=(("drift_method", "drift_time"), 2 * drift), wp_error=(("solver", "wp_point"), error),
        wp_wall=(("solver", "wp_point"), wall), wp_setting=(("solver", "wp_point"), settings),
    ).assign_coords(trace_time=t, component=[1, 2, 3], drift_method=methods, drift_time=drift_time,
                    solver=solvers, wp_point=np.arange(3))


@pytest.fixture(scope="module")
def drawable(triangle_scan, amplitude_scan, benchmark_like, model_scans):
    """For each figure, a dataset that can give it."""
    return {"stability_map": triangle_scan, "norm_growth": triangle_scan, "flip_law": amplitude_scan,
            "flip_components": benchmark_like, "invariant_drift": benchmark_like,
            "work_precision": benchmark_like, "summary": triangle_scan, **model_scans}


@pytest.fixture(scope="module")
def model_scans():
    """The bundled model studies, run small: the datasets of the models' figures."""
    studies = {"gyrostat_map": "gyrostat_map", "sleeping_top": "sleeping_top", "debra_delp_map": "debra_delp_map",
               "pitch_libration": "gravity_gradient_pitch", "flat_spin": "explorer1"}  # figure: its study
    scans = {figure: tumble.run_study(study, overrides={"perturbation.samples": 8}, progress=False)
             for figure, study in studies.items()}
    chaos = tumble.run_study("chaos_map", overrides={"scan.tilt": [0.5, 2.0], "scan.rate": [0.5, 1.0, 3.0],
                                                     "integration.horizon": 4.0, "chaos.points": 8}, progress=False)
    # a section study's result, as tests/test_bundled_results.py stores it (no run: its kernels compile for seconds)
    section = xr.load_dataset(Path(__file__).parent / "data" / "bundled" / "heavy_top_section.nc")
    return {**scans, "megno_map": chaos, "finite_time": chaos, "spectrum": chaos, "section": section}


def _assert_paper_axes(fig):
    drawn = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert drawn
    for ax in drawn:
        assert ax.get_xlabel(), "every panel labels its x axis"
    assert any(ax.get_ylabel() for ax in drawn)
    width, height = fig.get_size_inches()
    assert 3.3 <= width <= 7.1 and height <= 4.0, "paper size: one or two columns wide"


@pytest.mark.parametrize("name", SCAN_FIGURES)
def test_each_figure_draws_labelled_axes_from_its_schema(name, drawable):
    ds = drawable[name]
    assert plots.can_draw(ds, name) == (True, "")
    fig = getattr(plots, name)(ds)
    assert isinstance(fig, Figure)
    _assert_paper_axes(fig)


@pytest.mark.parametrize("name, label", [("norm_growth", "(rad/s)"), ("flip_law", "(s)"),
                                         ("flip_components", "(rad/s)"), ("invariant_drift", "(s)"),
                                         ("work_precision", "(s)")])
def test_time_and_rate_axes_carry_units(name, label, drawable):
    ax = getattr(plots, name)(drawable[name]).axes[0]
    labels = ax.get_xlabel() + " " + ax.get_ylabel()
    assert label in labels
    assert "time" not in ax.get_xlabel() or "(s)" in ax.get_xlabel()


def test_growth_and_error_figures_use_log_scales(drawable):
    assert plots.norm_growth(drawable["norm_growth"]).axes[0].get_yscale() == "log"
    assert all(ax.get_yscale() == "log" for ax in plots.invariant_drift(drawable["invariant_drift"]).axes)
    ax = plots.work_precision(drawable["work_precision"]).axes[0]
    assert (ax.get_xscale(), ax.get_yscale()) == ("log", "log")


def test_stability_map_has_one_panel_per_axis_and_a_growth_colour_bar(triangle_scan):
    fig = plots.stability_map(triangle_scan)
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert len(panels) == 3
    colorbar = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(colorbar) == 1 and "growth rate / spin rate" in colorbar[0].get_ylabel()


def test_real_measurement_gives_a_summary_and_says_why_not_the_rest(measured):
    fig = plots.summary(measured)
    assert "1/s" in fig.axes[0].get_title(), "the theory rate is given with its unit"
    assert "theory" in fig.axes[0].get_xlabel()
    legend = [text.get_text() for text in fig.legends[0].get_texts()]
    assert f"measured median, error {float(measured.rel_error):.2g}" in legend
    for name in set(plots.FIGURES) - {"summary"}:
        ok, reason = plots.can_draw(measured, name)
        assert not ok and reason.startswith(name + " needs ")


@pytest.mark.parametrize("name, missing", [
    ("stability_map", "'body' dimension"), ("norm_growth", "'growth_norm'"),
    ("flip_law", "'amplitude' dimension with at least 2 values"), ("flip_components", "'trace_omega'"),
    ("invariant_drift", "'drift_l2'"), ("work_precision", "'wp_error'"), ("summary", "'rate'"),
    *[(name, "'attitude_quaternion'") for name in ATTITUDE],
])
def test_unsuitable_dataset_is_refused_naming_what_is_missing(name, missing):
    ds = xr.Dataset({"other": ("x", np.zeros(3))})
    ok, reason = plots.can_draw(ds, name)
    assert not ok and missing in reason
    with pytest.raises(ValueError, match=re.escape(missing)):
        getattr(plots, name)(ds)


def test_periodic_only_scan_has_no_norm_growth(triangle_scan):
    periodic = triangle_scan.sel(axis=[1, 3])
    ok, reason = plots.can_draw(periodic, "norm_growth")
    assert not ok and "exponential scene" in reason
    with pytest.raises(ValueError, match="exponential scene"):
        plots.norm_growth(periodic)


def test_stability_map_needs_an_axis_dimension(triangle_scan):
    with pytest.raises(ValueError, match="'axis' dimension"):
        plots.stability_map(triangle_scan.isel(axis=1))


def test_all_nan_series_are_skipped_not_fatal(triangle_scan, benchmark_like, amplitude_scan):
    scan = triangle_scan.copy()
    scan["growth_norm"] = scan["growth_norm"].where(scan["body"] != 5)
    scan["rate"] = scan["rate"].where(scan["axis"] != 3)
    assert isinstance(plots.norm_growth(scan), Figure)
    assert isinstance(plots.summary(scan), Figure)
    bench = benchmark_like.copy()
    bench["drift_l2"] = bench["drift_l2"].where(bench["drift_method"] != "rk4")
    bench["wp_error"] = bench["wp_error"].where(bench["solver"] != "scipy_RK45")
    assert isinstance(plots.invariant_drift(bench), Figure)
    assert isinstance(plots.work_precision(bench), Figure)
    flips = amplitude_scan.copy()
    flips["flip_first"] = flips["flip_first"].where(flips["spin"] != 2.0)
    flips["sample_first_flip"] = flips["sample_first_flip"].where(flips["spin"] != 2.0)
    assert isinstance(plots.flip_law(flips), Figure)
    nothing = benchmark_like.assign(trace_omega=benchmark_like["trace_omega"] * np.nan)
    with pytest.raises(ValueError, match="all NaN"):
        plots.flip_components(nothing)


def test_flip_components_marks_each_sign_change_of_the_spin_axis_component(benchmark_like):
    ax = plots.flip_components(benchmark_like).axes[0]
    w2 = benchmark_like["trace_omega"].sel(component=2).values
    changes = int(np.sum(w2[:-1] * w2[1:] < 0))
    assert changes >= 2
    vertical = [line for line in ax.get_lines() if len(set(line.get_xdata())) == 1 and line.get_ls() == ":"]
    assert len(vertical) == changes


def test_save_figures_writes_every_file_atomically(drawable, tmp_path):
    ds = drawable["flip_components"]
    names = ["flip_components", "summary"]
    written = plots.save_figures(ds, names, tmp_path / "figs", "run", formats=("png", "pdf"), dpi=80)
    expected = {tmp_path / "figs" / f"run_{n}.{f}" for n in names for f in ("png", "pdf")}
    assert set(written) == expected and len(written) == len(expected)
    assert set((tmp_path / "figs").iterdir()) == expected, "no temporary file is left"
    for path in written:
        head = path.read_bytes()[:8]
        assert head == b"\x89PNG\r\n\x1a\n" if path.suffix == ".png" else head.startswith(b"%PDF")


def test_save_figures_refuses_before_writing_anything(measured, tmp_path):
    with pytest.raises(ValueError, match="unknown figure 'histogram'"):
        plots.save_figures(measured, ["summary", "histogram"], tmp_path, "run")
    with pytest.raises(ValueError, match="flip_law needs"):
        plots.save_figures(measured, ["summary", "flip_law"], tmp_path, "run")
    with pytest.raises(ValueError, match="format"):
        plots.save_figures(measured, ["summary"], tmp_path, "run", formats=("gif",))
    assert list(tmp_path.iterdir()) == []


def test_failed_save_leaves_neither_file_nor_temporary(measured, tmp_path, monkeypatch):
    def broken(self, *args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(OSError, match="disk full"):
        plots.save_figures(measured, ["summary"], tmp_path, "run")
    assert list(tmp_path.iterdir()) == []


def test_can_draw_rejects_unknown_names(measured):
    with pytest.raises(ValueError, match="unknown figure"):
        plots.can_draw(measured, "nope")
    assert plots.FIGURES == ("stability_map", "norm_growth", "flip_law", "flip_components", "invariant_drift",
                             "work_precision", "summary", "flip_strip", "flip_animation", "polhode", "herpolhode",
                             "gyrostat_map", "sleeping_top", "debra_delp_map", "pitch_libration", "flat_spin",
                             "megno_map", "finite_time", "spectrum", "section")
    assert set(plots.ANIMATIONS) <= set(plots.FIGURES)


def test_one_scene_draws_single_column_and_a_scan_names_the_scene_it_shows(triangle_scan):
    one = triangle_scan.isel(body=5, axis=1)
    assert plots.norm_growth(one).get_figwidth() == pytest.approx(plots.SINGLE)
    two_spins = xr.concat([triangle_scan, triangle_scan.assign_coords(spin=2.0)], dim="spin")
    fig = plots.stability_map(two_spins)
    assert "1 rad/s" in fig.get_suptitle(), "the map takes the first spin and says so"


def test_plots_module_keeps_to_its_layer():
    import ast
    import inspect

    tree = ast.parse(inspect.getsource(plots))
    imported = {node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert "matplotlib.pyplot" not in imported
    assert not {"config", "cli", "tumble.pipeline.config", "tumble.cli", "..pipeline"} & imported


@pytest.mark.parametrize("name", ["norm_growth", "flip_components", "summary"])
def test_real_curves_as_measure_keeps_them_draw(name, measured_curves):
    assert plots.can_draw(measured_curves, name) == (True, "")
    _assert_paper_axes(getattr(plots, name)(measured_curves))


# --------------------------------------------------------------------------------------------- layout


@pytest.mark.parametrize("name", SCAN_FIGURES)
def test_each_figure_keeps_its_texts_inside_and_apart_without_a_layout_engine(name, drawable):
    fig = getattr(plots, name)(drawable[name])
    assert fig.get_layout_engine() is None, "savefig draws the figure once: no layout engine draws it first"
    assert misplaced(fig) == []


def test_the_layout_holds_legends_at_the_right_a_suptitle_and_one_scene(triangle_scan, measured_curves):
    two_spins = xr.concat([triangle_scan, triangle_scan.assign_coords(spin=2.0)], dim="spin")
    for fig in (plots.norm_growth(triangle_scan), plots.stability_map(two_spins), plots.summary(measured_curves),
                plots.norm_growth(measured_curves), plots.flip_components(measured_curves)):
        assert misplaced(fig) == [], fig.axes[0].get_title()


def test_a_legend_below_takes_as_many_columns_as_the_width_holds(triangle_scan):
    from tumble.output import layout

    wide, narrow = plots.stability_map(triangle_scan), plots.norm_growth(triangle_scan.isel(body=5, axis=1))
    assert wide.legends[0]._ncols == 3 and narrow.legends[0]._ncols == 1
    fig = Figure(figsize=(3.0, 2.0))
    ax = fig.subplots()
    handles = ax.plot([0, 1], [0, 1], label="a") + ax.plot([0, 1], [1, 0], label="b")
    assert layout.legend(fig, handles)._ncols == 2
    assert misplaced(layout.fit(fig)) == []
    assert fig.get_figheight() > 2.0, "the figure grows by the legend's height"
