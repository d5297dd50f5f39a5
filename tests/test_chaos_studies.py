"""Chaos maps from a study file (issue 41, item 3): the ``[chaos]`` table, the third scene kind, the map's Dataset
and its figures, the two bundled studies end to end, and bad input refused with one line naming the field."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import tumble
from tumble import registry
from tumble.measure import chaos_scenes
from tumble.pipeline import config, runner
from tumble.pipeline.config import StudyError, load_study

# Each bundled study at a tiny size: its map of 2 x 3 points over a short horizon, every indicator and figure.
TINY = {
    "chaos_map": {"scan.tilt": [0.5, 2.0], "scan.rate": [0.5, 1.0, 3.0], "integration.horizon": 4.0,
                  "chaos.indicators": ["megno", "lyapunov", "gali"], "chaos.points": 8},
    "hyperion": {"scan.angle": [0.0, 1.0], "scan.rate": [0.5, 1.0, 2.5], "integration.horizon": 4.0,
                 "chaos.indicators": ["megno", "lyapunov", "gali"], "chaos.points": 8},
}
COORDINATES = {"chaos_map": ("tilt", "rate"), "hyperion": ("angle", "rate")}
FIGURES = ["megno_map", "finite_time", "spectrum"]


def _top(**chaos):
    return {"body": {"moments": [1.0, 1.5, 2.0]},
            "model": {"kind": "heavy_top", "mgl": 1.0, "centre": [1.0, 0.5, 1.0]},
            "integration": {"dt": 0.01, "horizon": 2.0},
            "chaos": {"indicators": ["megno"], **chaos},
            "scan": {"tilt": [0.5, 1.5], "rate": [0.5, 2.0]}}


@pytest.mark.parametrize("name", sorted(TINY))
def test_a_bundled_chaos_study_runs_end_to_end_small(name, tmp_path):
    ds = tumble.run_study(name, overrides=TINY[name], out=tmp_path, progress=False)
    first, second = COORDINATES[name]
    assert (tmp_path / f"{name}.nc").is_file()
    for figure in FIGURES:
        assert (tmp_path / f"{name}_{figure}.png").stat().st_size > 1000, figure
    stored = xr.load_dataset(tmp_path / f"{name}.nc")
    assert stored["megno"].dims == (first, second) and stored["megno"].shape == (2, 3)
    assert stored["exponent"].dims == (first, second, "index")
    assert stored["finite_time"].dims == (first, second, "time", "index")
    assert stored["gali"].dims == (first, second, "gali_time")
    np.testing.assert_array_equal(stored[second].values, TINY[name][f"scan.{second}"])
    for var in ("megno", "megno_lyapunov", "exponent", "finite_time", "gali"):
        assert np.isfinite(stored[var].values).all(), var
        assert stored[var].attrs["units"] and stored[var].attrs["long_name"], var
    assert (stored["status"].values == 0).all()
    assert "tumble" in stored.attrs["source"] and config.load_study(json.loads(stored.attrs["study"]))["chaos"]
    # conservative systems: the spectrum sums to zero (each orbit)
    np.testing.assert_allclose(stored["exponent"].sum("index").values, 0.0, atol=1e-6)
    assert ds["megno"].shape == (2, 3)


def test_the_map_is_the_api_run_point_by_point():
    """A scene's samples are its map's points: each indicator equals tumble.megno / tumble.lyapunov on those states."""
    ds = tumble.run_study(_top(indicators=["megno", "lyapunov"]), progress=False)
    top = tumble.models.HeavyTop((1.0, 1.5, 2.0), 1.0, centre=(1.0, 0.5, 1.0))
    _, _, points = chaos_scenes.map_grid("release", {"tilt": [0.5, 1.5], "rate": [0.5, 2.0]})
    y = chaos_scenes.initial_states("release", points)
    assert np.allclose(y[1], [0.0, 0.0, 2.0, 0.0, math.sin(0.5), math.cos(0.5)])
    np.testing.assert_array_equal(ds["megno"].values.ravel(), tumble.megno(top, y, 2.0, 0.01).megno.values)
    # the study also stores the finite-time exponents (save_every): the same sums, to round-off
    np.testing.assert_allclose(ds["exponent"].values.reshape(4, 6), tumble.lyapunov(top, y, 2.0, 0.01).exponent.values,
                               rtol=1e-12, atol=1e-14)


@pytest.mark.slow  # the implicit rule's per-sample tangent loop compiles in every process
@pytest.mark.parametrize("method", ["implicit_midpoint", "splitting4"])
def test_the_map_of_an_implicit_rule_or_a_splitting_is_the_api_run_point_by_point(method):
    """The implicit rule and a splitting step a map's points as the API does."""
    top = tumble.models.HeavyTop((1.0, 1.5, 2.0), 1.0, centre=(1.0, 0.5, 1.0))
    _, _, points = chaos_scenes.map_grid("release", {"tilt": [0.5, 1.5], "rate": [0.5, 2.0]})
    y = chaos_scenes.initial_states("release", points)
    study = _top()
    study["integration"]["method"] = method
    ds = tumble.run_study(study, progress=False)
    api = tumble.megno(top, y, 2.0, 0.01, method=method)
    np.testing.assert_array_equal(ds["megno"].values.ravel(), api.megno.values)


def test_a_scanned_parameter_is_a_dimension_before_the_map():
    ds = tumble.run_study({**_top(), "scan": {"tilt": [0.5, 1.5], "rate": [0.5, 2.0], "mgl": [0.5, 1.0, 2.0]}},
                          progress=False)
    assert ds["megno"].dims == ("mgl", "tilt", "rate") and ds["megno"].shape == (3, 2, 2)
    assert np.isfinite(ds["megno"].values).all()


def test_the_chaos_scene_kind_is_chosen_once_by_the_study():
    assert isinstance(runner._scene_kind(load_study(_top())), runner.ChaosScenes)
    assert isinstance(runner._scene_kind(load_study({})), runner.FreeScenes)
    for method in ("plan", "layout", "planner", "scene", "batch", "samples", "records", "first_samples", "cost",
                   "result_shape"):
        for kind in (runner.FreeScenes, runner.ModelScenes, runner.ChaosScenes):
            assert callable(getattr(kind, method)), (kind, method)


def test_a_stability_study_resolves_as_before():
    assert "chaos" not in load_study({})
    assert "centre" not in load_study({"model": {"kind": "heavy_top", "mgl": 1.0}, "spin": {"axis": 3}})["model"]


BAD = [
    ({"chaos": {"indicators": ["megno", "lyapunov"], "exponents": 7}}, "chaos.exponents", "at most 6"),
    ({"chaos": {"indicators": ["megno"], "renormalise": 0.015}}, "chaos.renormalise", "multiple of integration.dt"),
    ({"chaos": {"indicators": ["megno"], "transient": 5.0}}, "chaos.transient", "less than integration.horizon"),
    ({"chaos": {"indicators": ["megnoo"]}}, "chaos.indicators[0]", "did you mean 'megno'"),
    ({"chaos": {"indicators": ["megno"], "start": "spin_orbit"}}, "chaos.start", "gravity_gradient"),
    ({"integration": {"dt": 0.0, "horizon": 2.0}}, "integration.dt", "fixed step"),
    ({"integration": {"dt": 0.01, "horizon": 0.0}}, "integration.horizon", "> 0 s"),
    ({"model": {"kind": "gravity_gradient", "orbit_rate": 1.0},
      "chaos": {"indicators": ["megno"], "start": "spin_orbit"}, "scan": {"angle": [0.0], "rate": [1.0]},
      "integration": {"dt": 0.01, "horizon": 2.0, "method": "splitting4"}},
     "integration.method", "the splittings for free, gyrostat, heavy_top only"),
    ({"scan": {"tilt": [0.5, 4.0], "rate": [1.0]}}, "scan.tilt[1]", "[0, pi]"),
    ({"scan": {"angle": [0.5], "rate": [1.0]}}, "scan.angle", "no coordinate"),
    ({"scan": {"tilt": [0.5], "rate": [1.0], "axis": [1, 2]}}, "scan.axis", "not in a chaos study"),
    ({"outputs": {"figures": ["spectrum"]}}, "outputs.figures[0]", "'lyapunov' in chaos.indicators"),
    ({"outputs": {"figures": ["stability_map"]}}, "outputs.figures[0]", "not a chaos study's figure"),
    ({"model": {"kind": "heavy_top", "mgl": 1.0, "centre": [0.0, 0.0, 0.0]}}, "model.centre", "non-zero"),
    ({"model": {"kind": "heavy_top", "mgl": 1.0, "eccentricity": 0.1}}, "model.eccentricity", "not a parameter"),
]


@pytest.mark.parametrize("change, field, words", BAD, ids=[b[1] for b in BAD])
def test_bad_chaos_input_is_one_line_naming_the_field(change, field, words):
    study = _top()
    for table, values in change.items():
        study[table] = {**study.get(table, {}), **values} if table not in ("scan", "model") else values
    with pytest.raises(StudyError) as refused:
        load_study(study)
    assert refused.value.field == field and words in refused.value.problem, str(refused.value)
    assert "\n" not in str(refused.value)


def test_chaos_keys_need_a_chaos_study():
    with pytest.raises(StudyError, match="chaos.tilt"):
        load_study({"chaos": {"tilt": 0.3}})
    with pytest.raises(StudyError, match="scan.tilt"):
        load_study({"scan": {"tilt": [0.3]}})
    with pytest.raises(StudyError, match="model.centre"):
        load_study({"model": {"kind": "heavy_top", "mgl": 1.0, "centre": [1.0, 0.0, 1.0]}, "spin": {"axis": 3}})
    with pytest.raises(StudyError, match="model.eccentricity"):
        load_study({"model": {"kind": "gravity_gradient", "orbit_rate": 1.0, "eccentricity": 0.1}})


def test_bad_chaos_study_exits_2_from_the_cli_and_writes_nothing(tmp_path):
    study = tmp_path / "bad.toml"
    study.write_text('[model]\nkind = "heavy_top"\nmgl = 1.0\n[integration]\ndt = 0.01\nhorizon = 2.0\n'
                     '[chaos]\nindicators = ["megno", "lyapunov"]\nexponents = 9\n'
                     '[scan]\ntilt = [0.5, 1.0]\nrate = [1.0, 2.0]\n')
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "tumble", "run", str(study), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "chaos.exponents" in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not out.exists() or not any(out.iterdir())


def test_the_figures_are_drawn_from_the_dataset_alone(tmp_path):
    ds = tumble.run_study(_top(indicators=["megno", "lyapunov"]), progress=False)
    from tumble.output import figures

    for name in FIGURES:
        assert figures.can_draw(ds, name) == (True, "")
    assert not figures.can_draw(ds.drop_vars("megno"), "megno_map")[0]
    paths = figures.save_figures(ds, FIGURES, tmp_path, "map")
    assert [p.name for p in paths] == [f"map_{name}.png" for name in FIGURES]


def test_the_registry_lists_the_chaos_figures_and_starts():
    assert set(registry.CHAOS_FIGURES) <= set(registry.FIGURES)
    assert {s.kind for s in registry.CHAOS_STARTS} - {""} <= set(registry.MODEL_KINDS)  # "": any model


def test_a_map_cut_into_sample_ranges_gives_the_same_bits(tmp_path):
    """A scene of more points than --chunk-samples runs as ranges of points (checkpointed apart), joined in order."""
    study = {**_top(), "integration": {"dt": 0.01, "horizon": 0.05},
             "scan": {"tilt": np.linspace(0.1, 3.0, 41).tolist(), "rate": np.linspace(0.2, 4.0, 101).tolist()}}
    whole = tumble.run_study(study, progress=False)
    cut = tumble.run_study(study, progress=False, chunk_samples=4096, out=tmp_path)
    assert whole["megno"].shape == (41, 101)
    np.testing.assert_array_equal(whole["megno"].values, cut["megno"].values)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(TINY))
def test_a_bundled_chaos_map_on_the_device_is_the_cpu_map(name):
    """integration.device = "cuda" runs the map's tangent loops on the device (numba-cuda's simulator in CI)."""
    first, second = COORDINATES[name]
    small = {f"scan.{first}": TINY[name][f"scan.{first}"], f"scan.{second}": [0.5, 3.0], "integration.horizon": 0.1,
             "chaos.indicators": ["megno", "lyapunov"]}
    cpu = tumble.run_study(name, overrides=small, progress=False)
    device = tumble.run_study(name, overrides={**small, "integration.device": "cuda"}, progress=False)
    assert device.attrs.get("study") is None or "cuda" in device.attrs["study"]
    np.testing.assert_allclose(device["megno"].values, cpu["megno"].values, rtol=1e-10)
    np.testing.assert_allclose(device["exponent"].values, cpu["exponent"].values, rtol=1e-10, atol=1e-14)


def test_a_map_over_named_state_components_of_any_system():
    """chaos.start = "state": the model's state with the components scan.state names replaced; the free body too."""
    ds = tumble.run_study({"body": {"moments": [1.0, 2.0, 3.0]}, "integration": {"dt": 0.01, "horizon": 1.0},
                           "chaos": {"indicators": ["megno"], "start": "state", "state": [0.0, 1.0, 0.0]},
                           "scan": {"state": {"w1": [0.01, 0.1], "w3": [0.01, 0.02, 0.1]}}}, progress=False)
    assert ds["megno"].dims == ("w1", "w3") and ds["w3"].attrs["units"] == "rad/s"
    y = [[w1, 1.0, w3] for w1 in (0.01, 0.1) for w3 in (0.01, 0.02, 0.1)]
    expected = tumble.megno(tumble.Body(1.0, 2.0, 3.0), y, 1.0, 0.01).megno.values
    np.testing.assert_array_equal(ds["megno"].values.ravel(), expected)


STATE_BAD = [
    ({"state": [0.0, 1.0]}, {"w1": [0.1]}, "chaos.state", "3 components"),
    ({"state": [0.0, 1.0, 0.0]}, {"g1": [0.1]}, "scan.state.g1", "no component"),
    ({"state": [0.0, 1.0, 0.0]}, {"w1": []}, "scan.state.w1", "must not be empty"),
]


@pytest.mark.parametrize("chaos, state, field, words", STATE_BAD, ids=[b[2] for b in STATE_BAD])
def test_bad_state_maps_name_the_field(chaos, state, field, words):
    study = {"integration": {"dt": 0.01, "horizon": 1.0},
             "chaos": {"indicators": ["megno"], "start": "state", **chaos}, "scan": {"state": state},
             "outputs": {"figures": []}}
    with pytest.raises(StudyError) as refused:
        load_study(study)
    assert refused.value.field == field and words in refused.value.problem, str(refused.value)


@pytest.mark.parametrize("state, scanned, field", [
    ([0.0, 0.0, 1.0, 0.0, 0.6, 0.7], {"w3": [0.5, 1.0]}, "chaos.state"),
    ([0.0, 0.0, 1.0, 0.0, 0.6, 0.8], {"g2": [0.6, 0.7]}, "scan.state.g2"),
])
def test_a_state_map_of_a_heavy_top_keeps_g_a_unit_vector_at_every_point(state, scanned, field):
    """tumble never normalises g: a map point where it is not of unit length is refused at load, naming the field
    (not in the chaos indicators' run, with exit 1, nor silently in a section's)."""
    study = {"model": {"kind": "heavy_top", "mgl": 1.0}, "integration": {"dt": 0.01, "horizon": 1.0},
             "chaos": {"indicators": ["megno"], "start": "state", "state": state}, "scan": {"state": scanned}}
    with pytest.raises(StudyError) as refused:
        load_study(study)
    assert refused.value.field == field and "(g1, g2, g3) of a heavy_top must be a unit vector" in str(refused.value)
    load_study({**study, "chaos": {**study["chaos"], "state": [0.0, 0.0, 1.0, 0.0, 0.6, 0.8]},
                "scan": {"state": {"w3": [0.5, 1.0]}}})  # unit at every point: accepted


def test_a_line_of_initial_states_and_gali_alone(tmp_path):
    """One coordinate scanned: megno_map draws <Y> against it; GALI alone draws no figure by default."""
    line = {"model": {"kind": "heavy_top", "mgl": 1.0}, "integration": {"dt": 0.01, "horizon": 1.0},
            "chaos": {"indicators": ["megno"]}, "scan": {"rate": [0.5, 1.0, 2.0]}}
    ds = tumble.run_study(line, out=tmp_path, progress=False)
    assert ds["megno"].dims == ("rate",) and (tmp_path / "untitled_study_megno_map.png").is_file()
    alone = load_study({**line, "chaos": {"indicators": ["gali"], "gali_k": 3}})
    assert alone["outputs"]["figures"] == []
    with pytest.raises(StudyError, match="scan.tilt"):
        load_study({**line, "scan": {}})
