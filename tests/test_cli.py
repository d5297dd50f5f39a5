"""The command line and the study runner: exit codes, messages, files written (and not written)."""

import subprocess
import sys

import numpy as np
import pytest

import tumble
from tumble import cli
from tumble.output import io
from tumble.pipeline import config, results, runner

# A study small enough to run in a second on the closed-form path.
TINY = """
title = "tiny"
[body]
moments = [1.0, 2.0, 3.0]
[perturbation]
samples = 48
[outputs]
figures = ["norm_growth", "flip_components", "summary"]
arrays = ["sample_rate", "sample_first_flip"]
"""

# (TOML text, field path the message must name). Each is wrong in one place; every one must exit 2 and
# leave no file behind.
MALFORMED = [
    ("[body]\nmoments = [1.0, 2.0]", "body.moments"),
    ("[body]\nmoments = [1.0, 2.0, -3.0]", "body.moments"),
    ("[body]\nmoments = [1.0, 1.0, 5.0]", "body.moments"),
    ("[body]\nmoments = [1.0, 'a', 3.0]", "body.moments[1]"),
    ("[body]\nshape = 'pyramid'", "body.shape"),
    ("[body]\nshape = 'cuboid'\ndimensions = {mass = 1.0, a = 0.3, b = 0.2}", "body.dimensions"),
    ("[body]\nshape = 'disc'\ndimensions = {mass = -1.0, radius = 0.1}", "body.dimensions.mass"),
    ("[body]\nmomets = [1.0, 2.0, 3.0]", "body.momets"),
    ("[spin]\naxis = 4", "spin.axis"),
    ("[spin]\naxis = 0", "spin.axis"),
    ("[spin]\naxis = 'x'", "spin.axis"),
    ("[spin]\nrate = 0.0", "spin.rate"),
    ("[spin]\nrate = 'fast'", "spin.rate"),
    ("[perturbation]\namplitude = -0.1", "perturbation.amplitude"),
    ("[perturbation]\namplitude = 2.0", "perturbation.amplitude"),
    ("[perturbation]\nsamples = 0", "perturbation.samples"),
    ("[perturbation]\nsamples = 1.5", "perturbation.samples"),
    ("[perturbation]\nseed = -1", "perturbation.seed"),
    ("[perturbation]\ndistribution = 'uniform'", "perturbation.distribution"),
    ("[perturbation]\nsampels = 10", "perturbation.sampels"),
    ("[integration]\nmethod = 'rk5'", "integration.method"),
    ("[integration]\ndt = -0.1", "integration.dt"),
    ("[integration]\nhorizon = -1.0", "integration.horizon"),
    ("[integration]\nflips = -2", "integration.flips"),
    ("[torque]\nprofile = 'spiral'", "torque.profile"),
    ("[torque]\nprofile = 'constant'\nvector = [1.0, 0.0, 0.0]", "torque.vector"),
    ("[torque]\nprofile = 'sine'\nvector = [0.0, 1.0, 0.0]", "torque.period"),
    ("[torque]\nvector = [0.0, 1.0, 0.0]", "torque.vector"),
    ("[scan]\naxis = [1, 1]", "scan.axis"),
    ("[scan]\naxis = []", "scan.axis"),
    ("[scan]\namplitude = [1e-3, -1e-3]", "scan.amplitude[1]"),
    ("[scan]\ntriangle = 1", "scan.triangle"),
    ("[scan]\nmoments = [[1.0, 2.0, 3.0], [1.0, 2.0, 9.0]]", "scan.moments[1]"),
    ("[scan]\nspeed = [1.0]", "scan.speed"),
    ("[outputs]\nfigures = ['pie_chart']", "outputs.figures"),
    ("[outputs]\nformat = ['gif']", "outputs.format"),
    ("[outputs]\narrays = ['everything']", "outputs.arrays"),
    ("[outputs]\nfigures = ['flip_law']", "outputs.figures[0]"),
    ("[outputs]\nfigures = ['stability_map']", "outputs.figures[0]"),
    ("[spin]\naxis = 1\n[outputs]\nfigures = ['norm_growth']", "outputs.figures[0]"),
    ("[spin]\naxis = 2\n[torque]\nprofile = 'constant'\nvector = [0.0, 1.0, 0.0]", "spin.axis"),
    ("title = 3", "title"),
    ("[body\nmoments = [1.0, 2.0, 3.0]", "<toml>"),
    ("body = 5", "body"),
]


def run_cli(capsys, *args):
    status = cli.main(list(args))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.parametrize("text, field", MALFORMED)
def test_a_malformed_study_exits_2_naming_the_field_and_writes_nothing(tmp_path, capsys, text, field):
    study = tmp_path / "bad.toml"
    study.write_text(text)
    out = tmp_path / "out"
    status, _, err = run_cli(capsys, "run", str(study), "--out", str(out))
    assert status == 2
    assert f"bad.toml: {field}" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_there_are_at_least_30_malformed_cases():
    assert len(MALFORMED) >= 30


@pytest.mark.parametrize("args, words", [
    (("run", "no_such_study"), "no_such_study"),
    (("run", "intermediate_axis", "--samples", "0"), "perturbation.samples"),
    (("run", "intermediate_axis", "--seed", "-4"), "perturbation.seed"),
    (("plot", "missing.nc"), "no such file"),
])
def test_invalid_command_line_input_exits_2(tmp_path, capsys, monkeypatch, args, words):
    monkeypatch.chdir(tmp_path)
    status, _, err = run_cli(capsys, *args)
    assert status == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "data").exists()


def test_plot_refuses_a_netcdf_file_that_is_not_a_tumble_result(tmp_path, capsys):
    import xarray as xr

    path = tmp_path / "other.nc"
    xr.Dataset({"x": ("t", np.arange(3.0))}).to_netcdf(path)
    status, _, err = run_cli(capsys, "plot", str(path))
    assert status == 2 and "not a tumble result" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.nc"]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tiny")
    study = folder / "tiny.toml"
    study.write_text(TINY)
    status = cli.main(["run", str(study), "--out", str(folder / "out"), "--format", "png", "pdf"])
    return status, folder / "out"


def test_run_writes_the_netcdf_file_and_every_figure(tiny_run):
    status, out = tiny_run
    assert status == 0
    names = sorted(p.name for p in out.iterdir())
    figures = [f"tiny_{name}.{fmt}" for name in ("flip_components", "norm_growth", "summary") for fmt in ("pdf", "png")]
    assert names == sorted(["tiny.nc", *figures])
    for name in figures:
        assert (out / name).stat().st_size > 1000
    ds = io.read_dataset(out / "tiny.nc", require_tumble=True)
    for name in ("rate", "rate_theory", "rel_error", "kind", "sample_rate", "sample_first_flip"):
        assert name in ds and "units" in ds[name].attrs and "long_name" in ds[name].attrs
    assert "sample_status" not in ds  # not asked for in outputs.arrays
    assert str(ds.kind.values) == "exponential" and float(ds.rel_error) < 5e-3
    # The stored study re-runs to the same numbers.
    again = tumble.run_study(config.load_study(__import__("json").loads(ds.attrs["study"])))
    assert float(again.rate) == float(ds.rate)


def test_plot_redraws_the_figures_of_a_result(tiny_run, tmp_path, capsys):
    _, out = tiny_run
    status, printed, _ = run_cli(capsys, "plot", str(out / "tiny.nc"), "--out", str(tmp_path))
    assert status == 0
    drawn = sorted(p.name for p in tmp_path.iterdir())
    assert "tiny_summary.png" in drawn and "tiny_norm_growth.png" in drawn
    assert all(name in printed for name in drawn)


def test_an_output_folder_under_a_file_exits_2_with_a_message(tmp_path, capsys):
    study = tmp_path / "tiny.toml"
    study.write_text(TINY.replace('figures = ["norm_growth", "flip_components", "summary"]', "figures = []"))
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    status, _, err = run_cli(capsys, "run", str(study), "--out", str(blocker / "sub"))
    assert status == 2 and "tumble: error: --out:" in err and "Traceback" not in err


def test_studies_lists_every_bundled_study(capsys):
    status, out, _ = run_cli(capsys, "studies")
    assert status == 0
    for name in ("intermediate_axis", "stability_map", "amplitude_sweep", "space_station", "disc_wobble", "shapes",
                 "work_precision", "stress"):
        assert name in out


@pytest.mark.parametrize("name", sorted(config.bundled_studies()))
def test_every_bundled_study_is_valid_and_plannable(name):
    resolved = config.load_study(name)
    runner.plan(resolved, name)


def test_python_dash_m_tumble_works():
    done = subprocess.run([sys.executable, "-m", "tumble", "studies"], capture_output=True, text=True, check=False)
    assert done.returncode == 0 and "intermediate_axis" in done.stdout


def test_run_study_takes_a_mapping_and_writes_only_when_asked(tmp_path):
    study = {"body": {"moments": [1.0, 2.0, 3.0]}, "spin": {"axis": 1}, "perturbation": {"samples": 32},
             "outputs": {"figures": [], "arrays": []}}
    ds = tumble.run_study(study)
    assert str(ds.kind.values) == "periodic" and float(ds.rel_error) < 1e-3 and "sample" not in ds.dims
    stored = tumble.run_study(study, out=tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["untitled_study.nc"]
    assert float(stored.rate) == float(ds.rate) and "study" in stored.attrs


def test_a_scan_study_puts_its_parameters_in_coordinates():
    study = {"body": {"moments": [1.0, 2.0, 3.0]}, "perturbation": {"samples": 32},
             "scan": {"axis": [1, 2, 3], "amplitude": [1e-4, 1e-3]}, "outputs": {"figures": [], "arrays": []}}
    ds = tumble.run_study(study)
    assert ds.rate.dims == ("axis", "amplitude") or set(ds.rate.dims) == {"body", "axis", "amplitude"}
    assert list(ds.axis.values) == [1, 2, 3] and list(ds.kind.sel(amplitude=1e-3).values.ravel()) == [
        "periodic", "exponential", "periodic"]
    assert float(ds.rel_error.max()) < 5e-3
    assert "1 scene" not in results.summary_table(ds)


def test_the_space_station_spin_up_matches_linear_theory(warm_kernels):
    ds = tumble.run_study("space_station", overrides={"perturbation.samples": 16, "outputs.figures": []})
    assert ds.attrs["method_run"] == "rk4" and ds.attrs["torque"].startswith("constant")
    assert float(ds.rel_error) < 1e-3  # the 0.01 rad wobble: nonlinear O(amplitude²) correction ~2e-5
