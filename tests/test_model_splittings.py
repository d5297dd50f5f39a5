"""The Lie–Poisson splittings of the gyrostat and the heavy top in the model driver (issue 18).

Observed orders against SciPy's DOP853 -> the Casimirs (|I w + h|², a heavy top's |g|² and L·g) kept to round-off over
1e5 steps -> the energy error bounded, no drift -> growth rates against the Jacobian's linear theory -> the
compositions are the free body's tables -> the models they do not apply to are refused naming ``method``.
"""

import numpy as np
import pytest
from model_checks import fitted_rate, model_errors, observed_order
from tumble.theory import linear

from tumble import registry
from tumble.engine.model_ensemble import run_model_ensemble
from tumble.engine.sampling import perturbed_states
from tumble.kernels import model_methods, tableaux
from tumble.kernels.steps import model_splittings
from tumble.physics.models import Damper, FreeBody, GravityGradient, Gyrostat, HeavyTop

# one worker: the cases share the models' drivers (each compiled once, not by both workers at once)
pytestmark = pytest.mark.xdist_group("model_splittings")

MODELS = {
    "free": FreeBody((1.0, 2.0, 3.0)),
    "gyrostat": Gyrostat((1.0, 2.0, 3.0), (0.3, -0.2, 0.5)),
    "heavy_top": HeavyTop((2.0, 2.5, 1.0), 1.5),
}
SPLITTINGS = ("symplectic_euler", "splitting2", "splitting4")


def _state(model, n=1, seed=None):
    """States far from any steady spin (every component O(1); a heavy top's g a unit vector), shape (n, size)."""
    y0 = np.array([[1.0, 1.5, -1.2, 0.3, -0.4, 0.8]])[:, :model.state_size]
    if seed is not None:
        y0 = np.concatenate([y0, np.random.default_rng(seed).normal(size=(n - 1, model.state_size))])
    if model.state_size == 6:
        y0[:, 3:] /= np.linalg.norm(y0[:, 3:], axis=1, keepdims=True)
    return y0


@pytest.mark.parametrize("method, order, steps", [
    ("symplectic_euler", 1, (800, 1600, 3200)), ("splitting2", 2, (96, 192, 384)), ("splitting4", 4, (40, 80, 160))])
@pytest.mark.parametrize("kind", list(MODELS))
def test_each_splitting_shows_its_order_against_dop853(kind, method, order, steps):
    """The error is the largest over 8 checkpoints, all well above the reference's round-off."""
    model = MODELS[kind]
    y0 = _state(model)
    t_end = 2.0
    errors = model_errors(model, y0, t_end, method, steps)
    observed = observed_order(t_end, steps, errors)
    assert observed == pytest.approx(order, abs=0.2), errors


@pytest.mark.parametrize("method", SPLITTINGS)
@pytest.mark.parametrize("kind", ["gyrostat", "heavy_top"])
def test_casimirs_are_kept_to_round_off_over_1e5_steps(kind, method):
    """|I w + h|² (a gyrostat: projected back after every step, as the free body's |L|²) and a heavy top's |g|² and
    L·g (every sub-flow keeps them; round-off only random-walks) over 1e5 steps, relative to the drift scales."""
    model = MODELS[kind]
    y0 = _state(model, 4, seed=1)
    result = run_model_ensemble(model, y0, 1000.0, 0.01, method=method, axis=3, drift=True)
    assert (result.status == registry.STATUS_OK).all()
    assert result.info["n_steps"] == 100_000
    casimirs = result.drift[:, 1:]  # gyrostat: |I w + h|²; heavy top: L·g, |g|²
    assert casimirs.max() < (1e-14 if kind == "gyrostat" else 1e-12), casimirs
    final = model.invariants(result.final)
    initial = model.invariants(y0)
    for name in model.spec.invariants[1:]:
        assert np.allclose(final[name], initial[name], rtol=0, atol=1e-12 * np.abs(initial[name]).max())


@pytest.mark.parametrize("method, dt, bound", [("splitting2", 0.01, 1e-3), ("splitting4", 0.05, 1e-6)])
@pytest.mark.parametrize("kind", ["gyrostat", "heavy_top"])
def test_energy_error_is_bounded_without_drift_over_a_long_run(kind, method, dt, bound):
    """The energy error of a symplectic splitting oscillates (backward error analysis): over 5e4 steps the largest
    error of the last quarter is within twice that of the first (a linear drift would make it 4 times), and small.
    The heavy top is Lagrange's (symmetric, integrable): the asymmetric top's orbits are chaotic, its error stays
    bounded but its maximum over a window wanders with the part of the chaotic sea the orbit visits."""
    model = MODELS[kind] if kind == "gyrostat" else HeavyTop((2.0, 2.0, 1.0), 1.5)
    y0 = _state(model, 4, seed=2)
    result = run_model_ensemble(model, y0, 50_000 * dt, dt, method=method, axis=3, save_every=100)
    energy = model.invariants(result.trajectory)["energy"]
    error = np.abs(energy - energy[:, :1]) / np.abs(energy[:, :1]).max()
    quarter = error.shape[1] // 4
    assert error.max() < bound
    assert error[:, -quarter:].max() < 2.0 * error[:, :quarter].max()


@pytest.mark.parametrize("model, spin", [
    (Gyrostat((1.0, 2.0, 3.0), (0.0, 0.1, 0.0)), 1.0),  # intermediate axis, small rotor: exponential
    (HeavyTop((2.0, 2.0, 1.0), 1.0), 2.0),  # below the sleeping threshold I3 w > 2 sqrt(mgl I1): a waking top
], ids=["gyrostat_intermediate_axis", "waking_heavy_top"])
def test_splitting4_growth_rate_matches_linear_theory(model, spin):
    axis = 2 if model.kind == "gyrostat" else 3
    kind, rate = linear(model, axis, spin)
    assert kind == "exponential"
    y0 = perturbed_states(model, axis, spin, 1e-9, 64, seed=3)
    t_end = 30.0 / rate
    result = run_model_ensemble(model, y0, t_end, 0.01, method="splitting4", axis=axis,
                                probe_times=np.linspace(0.0, t_end, 301), final=False)
    assert (result.status == registry.STATUS_OK).all()
    measured = fitted_rate(result.probe_times, result.probes, 1e-7, 1e-4)
    assert measured == pytest.approx(rate, rel=5e-3)


def test_the_compositions_are_the_free_bodys_tables():
    """The gyrostat's sub-flows are the tables without the torque; the heavy top's gravity takes the torque's place."""
    for p, splitting in enumerate((tableaux.SYMPLECTIC_EULER, tableaux.SPLITTING2, tableaux.SPLITTING4)):
        kernel_id = registry.STEPPING.index(splitting.name)
        assert model_splittings.SPLITTINGS[splitting.name] == kernel_id
        for prefix, table in (("_FREE", splitting.without_torque()), ("_TOP", splitting)):
            position = getattr(model_splittings, prefix + "_POSITION")[kernel_id]
            start = getattr(model_splittings, prefix + "_START")
            lo, hi = start[position], start[position + 1]
            assert np.array_equal(getattr(model_splittings, prefix + "_FLOWS")[lo:hi], table.flows)
            assert np.array_equal(getattr(model_splittings, prefix + "_FRACTIONS")[lo:hi], table.fractions)


def test_a_free_body_model_splitting_is_the_gyrostat_without_rotor():
    y0 = _state(MODELS["free"], 5, seed=4)
    free = run_model_ensemble(MODELS["free"], y0, 5.0, 0.01, method="splitting4", axis=3)
    gyrostat = run_model_ensemble(Gyrostat((1.0, 2.0, 3.0), (0.0, 0.0, 0.0)), y0, 5.0, 0.01, method="splitting4",
                                  axis=3)
    assert np.array_equal(free.final, gyrostat.final)


@pytest.mark.parametrize("model", [GravityGradient((1.0, 2.0, 3.0), 1e-3), Damper((1.0, 2.0, 3.0), 0.1, 0.05)],
                         ids=["gravity_gradient", "damper"])
@pytest.mark.parametrize("method", SPLITTINGS)
def test_models_that_are_not_lie_poisson_here_refuse_the_splittings_naming_method(model, method):
    assert method not in model_methods(model.kind) and "rk4" in model_methods(model.kind)
    y0 = np.zeros((1, model.state_size))
    y0[0, 3] = 1.0
    with pytest.raises(ValueError, match="method.*Lie–Poisson"):
        run_model_ensemble(model, y0, 1.0, 0.1, method=method, axis=3)


@pytest.mark.parametrize("kind, axis", [("gyrostat", 2), ("heavy_top", 3)])
def test_a_model_study_steps_with_a_splitting_and_measures_the_linear_rate(kind, axis):
    from tumble.measure import model_scenes
    from tumble.pipeline.config import load_study

    table = {"kind": kind} if kind == "gyrostat" else {"kind": kind, "mgl": 1.0}
    study = {"model": table, "integration": {"method": "splitting4"}, "spin": {"axis": axis}}
    resolved = load_study(study)
    assert resolved["integration"]["method"] == "splitting4"
    model = Gyrostat((1.0, 2.0, 3.0), (0.0, 0.1, 0.0)) if kind == "gyrostat" else HeavyTop((2.0, 2.0, 1.0), 1.0)
    spin = 1.0 if kind == "gyrostat" else 2.0
    scene = model_scenes.scene_plan(model, axis, spin, samples=64, method="splitting4")
    record = model_scenes.scene_batch([scene])[0]
    assert str(record["method"]) == "splitting4"
    assert float(record["rate"]) == pytest.approx(linear(model, axis, spin)[1], rel=5e-3)
