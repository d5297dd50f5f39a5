"""The built-in models' tangent flow vectorised across samples (:mod:`tumble.kernels.loops.tangent_blocks`) is the per-sample
loop's run (:mod:`tumble.kernels.loops.tangent_loop`), to round-off.

Each model's generated rk4 (and, slow, rk8) step with its tangent vectors and MEGNO's scalars against the per-sample
loop stepping the same tableau registered under another name (which the generated steps do not have), and the
splittings' blocks against the per-sample loop: the whole
spectrum with a transient and finite-time exponents saved, MEGNO with its early stop, GALI; blocks cut at odd sizes;
a sample that overflows stops alone, keeping the values of its last check, and leaves its block's others as they were.
"""

import numpy as np
import pytest

import tumble
from tumble.engine.chaos import RESCALE_EVERY
from tumble.kernels import TABLEAUX
from tumble.kernels.loops import tangent_blocks
from tumble.registry import STATUS_ABOVE, STATUS_NONFINITE, STATUS_OK

pytestmark = pytest.mark.xdist_group("chaos")

#: An asymmetric heavy top (centre off the principal axes) and states of each model: chaotic and regular releases.
TOP = tumble.models.HeavyTop((1.0, 1.6, 2.2), 1.0, centre=(0.6, 0.3, 1.0))
MODELS = {
    "free": (tumble.Body(1.0, 2.0, 3.0), [[0.1, 2.0, 0.2], [1.0, 0.2, 0.1], [0.3, 0.3, 1.0]]),
    "heavy_top": (TOP, [[0.04, 0.02, -0.86, 0.36, -0.79, 0.51], [0.5, 0.3, 2.0, 0.3, 0.1, 1.0],
                        [0.0, 0.0, 0.5, 0.0, 0.8, 0.6]]),
    "gravity_gradient": (tumble.models.GravityGradient((1.0, 1.5, 2.0), orbit_rate=1.0, eccentricity=0.1),
                         [[0.0, -1.2, 0.0, 0.9, 0.0, 0.44, 0.0], [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0],
                          [0.1, -0.5, 0.1, 0.6, 0.0, 0.8, 0.0]]),
    "gyrostat": (tumble.models.Gyrostat((1.0, 2.0, 3.0), rotor=(0.0, 0.3, 0.1)), [[0.1, 2.0, 0.2], [1.0, 0.2, 0.1]]),
    "damper": (tumble.models.Damper((1.0, 2.0, 3.0), damper_inertia=0.1, damping=0.05),
               [[0.1, 2.0, 0.2, 0.0, 0.0, 0.0], [1.0, 0.2, 0.1, 0.0, 0.0, 0.0]]),
}


def _states(y, copies):
    """``copies`` perturbed copies of the states (odd block sizes: 300 samples are a block of 256 and one of 44)."""
    y = np.asarray(y, dtype=float)
    rng = np.random.default_rng(3)
    return np.repeat(y, -(-copies // len(y)), axis=0)[:copies] * (1.0 + 1e-3 * rng.standard_normal((copies, 1)))


def _unit(system, states):
    """The states with the heavy top's vertical and the quaternion made unit vectors (the models check them)."""
    states = states.copy()
    names = system.spec.state if isinstance(system, tumble.models.Model) else ("w1", "w2", "w3")
    for group in (("g1", "g2", "g3"), ("q0", "q1", "q2", "q3")):
        if set(group) <= set(names):
            columns = [names.index(name) for name in group]
            states[:, columns] /= np.linalg.norm(states[:, columns], axis=1, keepdims=True)
    return states


@pytest.fixture
def per_sample(monkeypatch):
    """``method`` registered again as ``<method>_per_sample``: the same coefficients, run by the per-sample loop."""
    def register(method):
        name = f"{method}_per_sample"
        monkeypatch.setitem(TABLEAUX, name, TABLEAUX[method]._replace(name=name))
        assert tangent_blocks.runs(method, "free") and not tangent_blocks.runs(name, "free")
        return name
    return register


def _runs(system, y0, method):
    """The spectrum (transient, finite-time exponents), MEGNO (with its early stop) and GALI of ``y0`` by ``method``."""
    return (tumble.lyapunov(system, y0, 12.0, 0.02, method=method, transient=2.0, renormalise=0.5, save_every=100),
            tumble.megno(system, y0, 12.0, 0.02, method=method, stop_above=0.9),
            tumble.gali(system, y0, 12.0, 0.02, method=method, save_every=100))


def _equal(runs, others):
    (a, m, g), (b, n, h) = runs, others
    np.testing.assert_allclose(a["exponent"].values, b["exponent"].values, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a["finite_time"].values, b["finite_time"].values, rtol=1e-9, atol=1e-12)
    assert np.array_equal(a["status"].values, b["status"].values)
    for name in ("megno", "lyapunov", "time_run"):
        np.testing.assert_allclose(m[name].values, n[name].values, rtol=1e-9, atol=1e-12, err_msg=name)
    assert np.array_equal(m["status"].values, n["status"].values)
    np.testing.assert_allclose(g["gali"].values, h["gali"].values, rtol=1e-8, atol=1e-14)


def _compare(system, y0, method, other):
    _equal(_runs(system, y0, method), _runs(system, y0, other))


@pytest.mark.slow  # the per-sample loop compiles in every process
@pytest.mark.parametrize("kind", ["heavy_top", "gravity_gradient"])
def test_the_vectorised_rk4_is_the_per_sample_loop(kind, per_sample):
    system, y = MODELS[kind]
    y0 = _unit(system, _states(y, 300))
    _compare(system, y0, "rk4", per_sample("rk4"))


@pytest.mark.slow
@pytest.mark.parametrize("kind, method", [("free", "rk4"), ("gyrostat", "rk4"), ("damper", "rk4"), ("free", "rk8"),
                                          ("heavy_top", "rk8"), ("gravity_gradient", "rk8"), ("gyrostat", "rk8"),
                                          ("damper", "rk8")])
def test_every_model_and_method_vectorised_is_the_per_sample_loop(kind, method, per_sample):
    system, y = MODELS[kind]
    _compare(system, _unit(system, _states(y, 40)), method, per_sample(method))


@pytest.mark.slow  # the per-sample loop compiles in every process
@pytest.mark.parametrize("method", ["symplectic_euler", "splitting2", "splitting4"])
@pytest.mark.parametrize("kind", ["free", "gyrostat", "heavy_top"])
def test_the_vectorised_splittings_are_the_per_sample_loop(kind, method, monkeypatch):
    """The Lie–Poisson models' splittings, their sub-flows looped over a block's samples, against the per-sample loop
    (the blocks switched off): the same arithmetic per sample (model_splittings' helpers), MEGNO's logarithm taken
    as a difference rather than a ratio."""
    system, y = MODELS[kind]
    y0 = _unit(system, _states(y, 300))
    blocks = _runs(system, y0, method)
    monkeypatch.setattr(tangent_blocks, "runs", lambda method, kind: False)
    _equal(blocks, _runs(system, y0, method))


def test_the_early_stop_and_the_status_of_each_sample():
    system, y = MODELS["heavy_top"]
    y0 = _unit(system, _states(y, 300))
    ds = tumble.megno(system, y0, 20.0, 0.02, stop_above=1.0)
    stopped = ds["status"].values == STATUS_ABOVE
    assert 0 < stopped.sum() < len(y0) and set(ds["status"].values) == {STATUS_OK, STATUS_ABOVE}
    assert np.all(ds["megno"].values[stopped] > 1.0) and np.all(ds["time_run"].values[stopped] < 20.0)
    assert np.all(ds["time_run"].values[~stopped] == 20.0)


def test_a_sample_that_overflows_stops_alone_with_the_values_of_its_last_check():
    """A fast spin that rk4 at this step cannot follow overflows; it stops with the values of the last check before
    (for MEGNO: the last rescaling of its tangent vector), and its block's other samples run as without it."""
    system, y = MODELS["heavy_top"]
    y0 = _unit(system, _states(y, 10))
    fast = y0.copy()
    fast[4, :3] = [45.15, 30.1, 60.2]  # rk4 at 0.05 s is unstable at this spin: it overflows within 50 s
    with pytest.warns(RuntimeWarning, match="1 of 10 samples"):
        ds = tumble.megno(system, fast, 50.0, 0.05)
    status = ds["status"].values
    assert status[4] == STATUS_NONFINITE and np.all(np.delete(status, 4) == STATUS_OK)
    steps = round(float(ds["time_run"].values[4]) / 0.05)
    assert steps < 1000 and steps % RESCALE_EVERY == 0 and np.isfinite(ds["megno"].values[4]) == (steps > 0)
    alone = tumble.megno(system, np.delete(y0, 4, axis=0), 50.0, 0.05)
    np.testing.assert_array_equal(np.delete(ds["megno"].values, 4), alone["megno"].values)
