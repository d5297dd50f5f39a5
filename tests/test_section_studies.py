"""Section studies (issue 56, item 2): a ``[section]`` table over a chaos study's map, error-controlled
(``integration.method = "dop853"``), the two bundled section studies end to end small, their physics against
independent references (the planar spin-orbit equation in SciPy; the heavy top's energy level), the chaos indicators
at a tolerance from a study, and bad input refused with one line naming the field."""

import math
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr
from scipy.integrate import solve_ivp

import tumble
from tumble.measure import chaos_scenes
from tumble.pipeline import config, results
from tumble.pipeline.config import StudyError, load_study

# One worker runs the error-controlled tests (--dist loadgroup): their loops are compiled once per process.
pytestmark = pytest.mark.xdist_group("dop853")

TOP = tumble.models.HeavyTop((1.0, 1.5, 2.0), 1.0, centre=(1.0, 0.5, 1.0))
TINY = {
    "hyperion_section": {"scan.angle": [0.0, 1.571], "scan.rate": [0.55, 1.2, 2.7], "integration.horizon": 40.0,
                         "section.crossings": 6},
    "heavy_top_section": {"scan.tilt": [2.6, 2.9, 3.5], "integration.horizon": 60.0, "section.crossings": 5},
}


def _section_study(**section):
    return {"body": {"moments": [1.0, 1.5, 2.0]},
            "model": {"kind": "heavy_top", "mgl": 1.0, "centre": [1.0, 0.5, 1.0]},
            "integration": {"method": "dop853", "horizon": 30.0},
            "chaos": {"start": "swing", "energy": -0.2},
            "scan": {"tilt": [2.6, 2.9]},
            "section": {"surface": "g1", "axes": ["tilt", "w1"], "crossings": 4, **section}}


@pytest.mark.parametrize("name", sorted(TINY))
def test_a_bundled_section_study_runs_end_to_end_small(name, tmp_path):
    ds = tumble.run_study(name, overrides=TINY[name], out=tmp_path, progress=False)
    assert (tmp_path / f"{name}_section.png").stat().st_size > 1000
    stored = xr.load_dataset(tmp_path / f"{name}.nc")
    map_dims = tuple(stored.attrs["map_dims"].split())
    assert stored["section_point"].dims == (*map_dims, "crossing", "section_axis")
    assert stored["section_state"].dims == (*map_dims, "crossing", "component")
    count = stored["crossings"].values
    assert (count >= 1).all() and count.max() == stored.sizes["crossing"] == TINY[name]["section.crossings"]
    assert (stored["status"].values == 0).all() and (stored["steps"].values > 0).all()
    assert list(stored["section_axis"].values) == config.load_study(name)["section"]["axes"]
    assert ds.attrs["method"] == "dop853" and ds.attrs["rtol"] == 1e-10


def test_the_stroboscopic_section_of_the_study_is_the_planar_spin_orbit_equation():
    """``hyperion_section`` at pericentre against theta'' = -(w0^2/2) (a/r)^3 sin 2(theta - f), integrated by SciPy
    (an independent reference: the study's model is the full 3-D gravity-gradient attitude)."""
    overrides = {"scan.angle": [0.0, 1.571], "scan.rate": [0.55, 2.0], "integration.horizon": 40.0,
                 "section.crossings": 6}
    ds = tumble.run_study("hyperion_section", overrides=overrides, progress=False)
    moments, e = ds.attrs["moments"], ds.attrs["parameter_eccentricity"]
    w0 = math.sqrt(3.0 * (moments[0] - moments[2]) / moments[1])

    def planar(t, y):
        theta, rate, f = y
        ar = (1.0 + e * math.cos(f)) / (1.0 - e * e)
        return [rate, -0.5 * w0 ** 2 * ar ** 3 * math.sin(2.0 * (theta - f)),
                (1.0 + e * math.cos(f)) ** 2 / (1.0 - e * e) ** 1.5]

    for angle in overrides["scan.angle"]:
        for rate in overrides["scan.rate"]:
            marks = 2.0 * math.pi * np.arange(1, 7)
            # the map's angle is a turn about pitch axis 2, the negative orbit normal: theta = -angle
            sol = solve_ivp(planar, (0.0, marks[-1]), [-angle, rate, 0.0], method="DOP853", t_eval=marks,
                            rtol=1e-12, atol=1e-13)
            point = ds["section_point"].sel(angle=angle, rate=rate).values
            theta = np.mod(-sol.y[0] + 0.5 * math.pi, math.pi) - 0.5 * math.pi
            np.testing.assert_allclose(point[:, 0], theta, rtol=0, atol=1e-7)
            np.testing.assert_allclose(point[:, 1], sol.y[1], rtol=0, atol=1e-7)


@pytest.mark.slow  # 200 orbits of SciPy per island
@pytest.mark.parametrize("angle, rate, spin", [(0.0, 0.55, 1.0), (1.571, 0.87, 0.5), (0.0, 2.32, 2.0),
                                               (1.571, 2.0, 2.25), (0.0, 2.7, 2.5)])
def test_hyperion_sections_islands_are_the_resonances_its_study_file_names(angle, rate, spin):
    """The islands hyperion_section.toml names, by the mean spin <theta'>/n of an orbit from inside each, over 200
    orbits of the planar equation (SciPy)."""
    e, w0 = 0.1, 0.89

    def planar(t, y):
        ar = (1.0 + e * math.cos(y[2])) / (1.0 - e * e)
        return [y[1], -0.5 * w0 ** 2 * ar ** 3 * math.sin(2.0 * (y[0] - y[2])),
                (1.0 + e * math.cos(y[2])) ** 2 / (1.0 - e * e) ** 1.5]

    t_end = 200 * 2.0 * math.pi
    sol = solve_ivp(planar, (0.0, t_end), [-angle, rate, 0.0], method="DOP853", rtol=1e-10, atol=1e-12)
    assert (sol.y[0, -1] + angle) / t_end == pytest.approx(spin, abs=2e-3)


def test_a_swing_section_keeps_its_energy_level_and_lies_on_the_surface():
    ds = tumble.run_study(_section_study(), progress=False)
    states = ds["section_state"].values.reshape(-1, 6)
    states = states[np.isfinite(states).all(axis=1)]  # NaN past each orbit's count
    assert len(states) >= 6
    energy, vertical_momentum, _ = TOP.invariants(states).values()
    np.testing.assert_allclose(energy, -0.2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(vertical_momentum, 0.0, rtol=0, atol=1e-9)
    assert np.abs(states[:, 3]).max() < 1e-12  # g1 = 0, to the root finder's width
    # the study's crossings are tumble.section's on the same initial states
    tilt = np.array([2.6, 2.9])
    points = {"tilt": tilt, "energy": -0.2, "I1": 1.0, "potential": chaos_scenes.swing_potential(tilt, 1.0, TOP.centre)}
    direct = tumble.section(TOP, chaos_scenes.initial_states("swing", points), 30.0, surface=("g1", 0.0),
                            max_crossings=4)
    np.testing.assert_array_equal(ds["section_time"].values, direct["time"].values)


def test_a_chaos_study_at_a_tolerance_is_the_api_run_point_by_point():
    study = {"body": {"moments": [1.0, 1.5, 2.0]}, "model": {"kind": "heavy_top", "mgl": 1.0, "centre": [1.0, 0.5, 1.0]},
             "integration": {"method": "dop853", "rtol": 1e-9, "horizon": 3.0},
             "chaos": {"indicators": ["megno", "lyapunov"], "points": 3}, "scan": {"tilt": [0.5, 1.5], "rate": [0.5, 2.0]}}
    ds = tumble.run_study(study, progress=False)
    _, _, points = chaos_scenes.map_grid("release", {"tilt": [0.5, 1.5], "rate": [0.5, 2.0]})
    y = chaos_scenes.initial_states("release", points)
    api = tumble.megno(TOP, y, 3.0, method="dop853", rtol=1e-9)
    np.testing.assert_array_equal(ds["megno"].values.ravel(), api["megno"].values)
    spectrum = tumble.lyapunov(TOP, y, 3.0, method="dop853", rtol=1e-9, times=[1.0, 2.0, 3.0])
    np.testing.assert_array_equal(ds["exponent"].values.reshape(4, 6), spectrum["exponent"].values)
    assert ds["finite_time"].sizes["time"] == 3


def test_orbits_out_of_steps_keep_their_crossings_and_the_summary_says_why():
    study = _section_study()
    study["integration"]["max_steps"] = 60  # the two orbits need 166 and 140 steps (accepted and rejected)
    with pytest.warns(RuntimeWarning, match="step limit"):
        ds = tumble.run_study(study, progress=False)
    assert (ds["status"].values == tumble.registry.STATUS_LIMIT).all()
    assert (ds["steps"].values == 60).all() and (ds["crossings"].values >= 1).all()
    summary = results.chaos_summary(ds)
    assert "2 orbit(s) stopped early (2 step limit; see status)" in summary, summary


def test_a_section_too_large_for_the_memory_names_its_crossings():
    from tumble.pipeline import runner

    with pytest.raises(StudyError) as refused:
        runner.check_cost(load_study(_section_study(crossings=10**9)))
    assert refused.value.field == "section.crossings" and "memory" in refused.value.problem


BAD = [
    ({"integration": {"method": "rk4", "dt": 0.01, "horizon": 30.0}}, "integration.method", "dense output"),
    ({"section": {"surface": "g1", "period": 1.0}}, "section.period", "not with section.surface"),
    ({"section": {"period": 1.0, "direction": -1}}, "section.direction", "does not apply to a section by "
                                                                        "section.period"),
    ({"section": {"surface": "g1", "phase": 0.5}}, "section.phase", "does not apply to a section by section.surface"),
    ({"section": {"surface": "x1"}}, "section.surface", "component of a heavy_top's state"),
    ({"section": {"surface": "g1", "direction": 2}}, "section.direction", "one of 1, -1, 0"),
    ({"section": {"surface": "g1", "crossings": 0}}, "section.crossings", ">= 1"),
    ({"section": {"surface": "g1", "axes": ["tilt"]}}, "section.axes", "two coordinates"),
    ({"section": {"surface": "g1", "axes": ["tilt", "angle"]}}, "section.axes[1]", "coordinate of chaos.start"),
    ({"section": {"surface": "g1", "axes": ["tilt", "w1"], "colour": "megno"}}, "section.colour", "megno"),
    ({"section": {"surface": "", "crossings": 3}}, "section.crossings", "used by a section only"),
    ({"chaos": {"start": "swing", "energy": -0.9}}, "chaos.energy", "at least the potential"),
    ({"integration": {"method": "dop853", "horizon": 30.0, "rtol": 1e-15}}, "integration.rtol", ">= 1e-14"),
    ({"integration": {"method": "dop853", "horizon": 30.0, "atol": 0.0}}, "integration.atol", "> 0"),
    ({"integration": {"method": "dop853", "horizon": 30.0, "max_steps": 0}}, "integration.max_steps", ">= 1"),
]


@pytest.mark.parametrize("change, field, words", BAD, ids=[b[1] for b in BAD])
def test_bad_section_input_is_one_line_naming_the_field(change, field, words):
    study = _section_study()
    for table, values in change.items():
        study[table] = values
    with pytest.raises(StudyError) as refused:
        load_study(study)
    assert refused.value.field == field and words in refused.value.problem, str(refused.value)
    assert "\n" not in str(refused.value)


def test_an_error_controlled_method_runs_chaos_and_section_studies_only():
    with pytest.raises(StudyError, match="integration.method: 'dop853' .* the stability scenes"):
        load_study({"integration": {"method": "dop853"}})


def test_a_refused_section_study_exits_2_from_the_cli_and_writes_nothing(tmp_path):
    study = tmp_path / "bad.toml"
    study.write_text('[model]\nkind = "heavy_top"\nmgl = 1.0\n[integration]\nmethod = "dop853"\nhorizon = 2.0\n'
                     '[chaos]\nstart = "swing"\nenergy = -0.2\n[scan]\ntilt = [2.6]\n'
                     '[section]\nsurface = "g1"\nperiod = 2.0\n')
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "tumble", "run", str(study), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "section.period" in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not out.exists() or not any(out.iterdir())
