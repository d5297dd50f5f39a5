"""Issue 19's studies: gravity-gradient and damper studies (config, scene measurement, bundled studies end to end)."""

import math

import numpy as np
import pytest
import xarray as xr
from scipy.optimize import brentq

from tumble import cli
from tumble.measure import model_scenes
from tumble.physics import models, theory
from tumble.pipeline.config import StudyError, load_study, moments_from_k

GG = {"model": {"kind": "gravity_gradient", "orbit_rate": 1.0}}
DAMPER = {"model": {"kind": "damper", "damper_inertia": 0.05, "damping": 0.004}, "spin": {"axis": 3},
          "body": {"moments": [1.0, 1.05, 0.25]}}


def _with(base, **tables):
    out = {key: dict(value) for key, value in base.items()}
    for key, value in tables.items():
        out.setdefault(key, {}).update(value)
    return out


def test_gravity_gradient_and_damper_studies_resolve():
    gg = load_study(_with(GG, scan={"k1": [0.5, -0.1], "k3": [0.2, -0.5], "orbit_rate": [0.5, 1.0]}))
    assert gg["model"] == {"kind": "gravity_gradient", "orbit_rate": 1.0}
    assert gg["scan"]["k1"] == [0.5, -0.1] and gg["scan"]["orbit_rate"] == [0.5, 1.0]
    damper = load_study(_with(DAMPER, scan={"damping": [0.001, 0.002], "damper_inertia": [0.05, 0.1]}))
    assert damper["model"] == {"kind": "damper", "damper_inertia": 0.05, "damping": 0.004}


@pytest.mark.parametrize("study, field", [
    (_with(GG, model={"orbit_rate": 0.0}), "model.orbit_rate"),
    (_with(GG, model={"orbit_rate": -1.0}), "model.orbit_rate"),
    (_with(DAMPER, model={"damping": 0.0}), "model.damping"),
    (_with(DAMPER, model={"damper_inertia": -0.1}), "model.damper_inertia"),
    (_with(DAMPER, model={"orbit_rate": 1.0}), "model.orbit_rate"),
    (_with(GG, model={"damping": 1.0}), "model.damping"),
    (_with(GG, model={"mgl": 1.0}), "model.mgl"),
    (_with(DAMPER, scan={"orbit_rate": [1.0]}), "scan.orbit_rate"),
    (_with(GG, scan={"damping": [1.0]}), "scan.damping"),
    (_with(DAMPER, scan={"damping": [0.1, -0.1]}), "scan.damping[1]"),
    (_with(GG, scan={"orbit_rate": [1.0, 0.0]}), "scan.orbit_rate[1]"),
    (_with(GG, scan={"k1": [0.5, 1.0], "k3": [0.1]}), "scan.k1[1]"),
    (_with(GG, scan={"k1": [0.5]}), "scan.k3"),
    (_with(GG, scan={"k1": [0.5], "k3": [0.1], "moments": [[1.0, 2.0, 2.5]]}), "scan.k1"),
    (_with(DAMPER, scan={"k1": [0.5], "k3": [0.1]}), "scan.k1"),
    (_with(GG, scan={"axis": [1, 2]}), "scan.axis"),
    (_with(GG, scan={"rate": [1.0, 2.0]}), "scan.rate"),
])
def test_an_invalid_gravity_gradient_or_damper_study_names_the_field(study, field):
    with pytest.raises(StudyError) as err:
        load_study(study)
    assert err.value.field == field


def test_moments_from_k_give_the_ratios_and_obey_the_triangle_inequality():
    k1, k3 = np.meshgrid(np.linspace(-0.99, 0.99, 23), np.linspace(-0.99, 0.99, 23))
    moments = moments_from_k(k1, k3)
    got = theory.gravity_gradient_k(moments)
    np.testing.assert_allclose(got[0], k1, atol=1e-13)
    np.testing.assert_allclose(got[1], k3, atol=1e-13)
    s = np.sort(moments, axis=-1)
    assert np.all(s[..., 0] + s[..., 1] >= s[..., 2])
    with pytest.raises(ValueError):
        moments_from_k(1.0, 0.0)


def _curve_k1(k3):
    """The k1 of the roll-yaw boundary 1 + 3 k1 + k1 k3 = 4 sqrt(k1 k3) at k3 < 0 (DeBra-Delp's edge)."""
    return brentq(lambda k1: 1 + 3 * k1 + k1 * k3 - 4 * math.sqrt(k1 * k3), -0.3, -1e-9)


def _boundary_pairs():
    """Points 5 % away on each side of every boundary of the (k1, k3) map."""
    c = _curve_k1(-0.6)
    return [
        ("k1 = k3", (0.5, 0.5 * 0.95), (0.5, 0.5 * 1.05)),  # Lagrange | pitch unstable
        ("k3 = 0", (0.5, 0.05), (0.5, -0.05)),  # Lagrange | roll-yaw unstable
        ("k1 = 0", (-0.05, -0.6), (0.05, -0.6)),  # DeBra-Delp | unstable
        ("roll-yaw curve", (c * 0.95, -0.6), (c * 1.05, -0.6)),  # DeBra-Delp | unstable
        ("k1 = k3, DeBra-Delp", (-0.05, -0.05 * 1.05), (-0.05, -0.05 * 0.95)),
    ]


@pytest.mark.parametrize("name, inside, outside", _boundary_pairs())
def test_gravity_gradient_kinds_are_right_on_both_sides_of_every_boundary(name, inside, outside):
    for (k1, k3), expected in ((inside, True), (outside, False)):
        assert theory.gravity_gradient_stable(k1, k3) is expected, (name, k1, k3)
        scene = model_scenes.scene_plan(models.GravityGradient(moments_from_k(k1, k3), 1.0), 2, 1.0, 1e-4, 16)
        assert scene.kind == ("periodic" if expected else "exponential"), (name, k1, k3)
        record = model_scenes.scene_batch([scene])[0]
        assert float(record["rel_error"]) < 5e-3, (name, k1, k3, float(record["rel_error"]))


@pytest.mark.parametrize("k1, k3", [(0.2, 0.5), (0.3, -0.3), (-0.3, 0.3), (-0.1, -0.6)])
def test_an_unstable_gravity_gradient_scene_grows_at_its_linear_rate_within_half_a_percent(k1, k3):
    model = models.GravityGradient(moments_from_k(k1, k3), 0.7)
    scene = model_scenes.scene_plan(model, 2, 1.0, 1e-4, 32)
    assert scene.kind == "exponential" and scene.spin == 0.7
    record = model_scenes.scene_batch([scene])[0]
    assert abs(float(record["rate"]) / theory.linear(model, 2)[1] - 1) < 5e-3


def test_a_gravity_gradient_pitch_scene_librates_at_w_p():
    moments = moments_from_k(-0.02, -0.9)
    model = models.GravityGradient(moments, 2.0)
    kind, w_p = theory.gravity_gradient_pitch_frequency(moments, 2.0)
    assert kind == "periodic" and math.isclose(theory.linear(model, 2)[1], w_p, rel_tol=1e-9)
    record = model_scenes.scene_batch([model_scenes.scene_plan(model, 2, 1.0, 1e-4, 16)])[0]
    assert abs(float(record["rate"]) / w_p - 1) < 1e-4


@pytest.mark.parametrize("axis, kind", [(3, "exponential"), (2, "periodic")])
def test_a_damper_scene_measures_its_linear_rate_within_half_a_percent(axis, kind):
    model = models.Damper((1.0, 1.05, 0.25), 0.05, 0.001)  # c / (J W) = 0.02: first order within ~1 %
    scene = model_scenes.scene_plan(model, axis, 1.0, 1e-4, 32)
    assert scene.kind == kind
    record = model_scenes.scene_batch([scene])[0]
    assert float(record["rel_error"]) < 5e-3
    if kind == "exponential":  # the slow minor-axis growth, first order in c
        assert math.isclose(scene.value, theory.damper_nutation_rate(model.moments, 0.05, 0.001, 3), rel_tol=0.02)


def test_the_flat_spin_trace_keeps_l_and_the_energy_falls_monotonically_to_the_flat_spin():
    model = models.Damper((1.0, 1.05, 0.25), 0.05, 0.008)
    ds = model_scenes.flat_spin_trace(model, 3, 1.0, 1e-3, samples=4, points=600)
    assert float(ds.trace_energy_rise) <= 1e-14  # every sample: no rise beyond round-off between stored times
    assert float(ds.trace_momentum_drift) < 1e-10
    energy = ds.trace_energy.values
    lost = 1 - energy[:, -1] / energy[:, 0]
    assert float(ds.trace_undamped_drift) < 1e-6 * lost.min()  # the integrator's drift far below the damper's loss
    np.testing.assert_allclose(energy[:, -1], ds.trace_flat_energy.values, rtol=1e-5)
    assert np.all(ds.trace_nutation.values[:, -1] > np.radians(89.0))


def _run_cli(capsys, *args):
    status = cli.main(list(args))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.parametrize("name, figure", [
    pytest.param("debra_delp_map", "debra_delp_map", marks=pytest.mark.slow),
    ("gravity_gradient_pitch", "pitch_libration"),
    ("explorer1", "flat_spin"),
])
def test_a_bundled_study_of_issue_19_runs_through_tumble_run_into_netcdf(tmp_path, capsys, name, figure):
    status, out, err = _run_cli(capsys, "run", name, "--out", str(tmp_path), "--samples", "16")
    assert status == 0, err
    ds = xr.load_dataset(tmp_path / f"{name}.nc")
    for var in ("rate", "rate_theory", "rel_error", "kind"):
        assert var in ds and "units" in ds[var].attrs and "long_name" in ds[var].attrs
    assert float(np.nanmax(ds.rel_error.values)) < 5e-3
    assert (tmp_path / f"{name}_{figure}.png").is_file() and (tmp_path / f"{name}_summary.png").is_file()
    if name == "explorer1":
        assert float(ds.trace_momentum_drift) < 1e-10 and float(ds.trace_energy_rise) <= 1e-14
    if name == "debra_delp_map":
        k1, k3 = ds.k1.values, ds.k3.values
        off = k1 != k3  # cells centred on the pitch boundary are marginal (pitch neutral): either kind
        stable = theory.gravity_gradient_stable(k1, k3)
        assert np.array_equal(stable[off], ds.kind.values.astype(str)[off] == "periodic")


def test_tumble_studies_lists_the_studies_of_issue_19(capsys):
    status, out, _ = _run_cli(capsys, "studies")
    assert status == 0 and all(name in out for name in ("debra_delp_map", "gravity_gradient_pitch", "explorer1"))


@pytest.mark.parametrize("model", [{"kind": "gravity_gradient", "orbit_rate": 1.0},
                                   {"kind": "damper", "damper_inertia": 0.1, "damping": 0.01}])
def test_a_splitting_is_refused_for_the_models_it_does_not_apply_to(model):
    """The Lie-Poisson splittings step the free body, the gyrostat and the heavy top only (registry)."""
    with pytest.raises(StudyError, match="integration.method"):
        load_study({"model": model, "integration": {"method": "splitting4"}})
