"""Each built-in system's kernel module (tumble/kernels/systems/, the generated copy of its equations): its rate
compiled by numba against the same equations evaluated on numpy arrays (the physics layer's ``rhs``), its tangent
flow ``J(y) v`` against the physics layer's Jacobian and central differences, and the general heavy top (a centre of
mass off the axes) and the gravity-gradient satellite in an eccentric orbit, end to end."""

import math

import numpy as np
import pytest

import tumble
from tumble.kernels import model_rhs, model_tangent
from tumble.kernels.systems import SYSTEMS, gravity_gradient
from tumble.physics.models import Damper, FreeBody, GravityGradient, Gyrostat, HeavyTop

import hand_written_systems

MODELS = [
    FreeBody((1.0, 2.0, 3.0)),
    Gyrostat((1.0, 2.0, 3.0), (0.1, -0.2, 0.3)),
    HeavyTop((2.0, 2.5, 3.0), 0.7),
    HeavyTop((2.0, 2.5, 3.0), 0.7, centre=(0.3, -0.2, 1.0)),
    GravityGradient((1.0, 2.0, 3.0), 0.1),
    GravityGradient((1.0, 2.0, 3.0), 0.1, eccentricity=0.3),
    Damper((1.0, 2.0, 3.0), 0.2, 0.05),
]
IDS = ["free", "gyrostat", "heavy_top", "heavy_top_off_axis", "gravity_gradient", "gravity_gradient_eccentric",
       "damper"]
TIME = 1.7  # s: an eccentric orbit's equations depend on it


def _states(model, n=6, seed=3):
    y = np.random.default_rng(seed).normal(size=(n, model.state_size))
    if model.kind == "gravity_gradient":
        y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    return y


def _physics(model, name, *args):
    timed = model.kind == "gravity_gradient"
    return getattr(model, name)(*args, TIME) if timed else getattr(model, name)(*args)


def test_every_model_kind_has_its_module():
    assert set(SYSTEMS) == set(tumble.registry.MODEL_KINDS)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_kernel_rate_is_the_physics_rhs_to_round_off(model):
    y = _states(model)
    got = model_rhs(model.kind, y.T, model.moments, t=TIME, **model.parameters).T
    np.testing.assert_allclose(got, _physics(model, "rhs", y), rtol=0, atol=1e-15 * np.abs(y).max() ** 2)


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_the_tangent_flow_is_the_jacobian_times_v_and_the_central_difference(model):
    y, v = _states(model), _states(model, seed=4)
    got = model_tangent(model.kind, y.T, v.T, model.moments, t=TIME, **model.parameters).T
    jacobian = _physics(model, "jacobian", y)
    np.testing.assert_allclose(got, np.einsum("nij,nj->ni", jacobian, v), rtol=0, atol=1e-14)
    eps = 1e-5  # a central difference is exact for the quadratic rates; the orbit's time dependence is not in y
    rhs = [model_rhs(model.kind, (y + s * eps * v).T, model.moments, t=TIME, **model.parameters).T for s in (1, -1)]
    np.testing.assert_allclose(got, (rhs[0] - rhs[1]) / (2 * eps), rtol=0, atol=1e-9)


@pytest.mark.xdist_group(hand_written_systems.GROUP)
def test_an_off_axis_heavy_top_keeps_its_invariants_and_is_the_top_written_by_hand():
    top = HeavyTop((2.0, 2.5, 3.0), 0.7, centre=(0.3, -0.2, 1.0))
    g = np.array([0.1, 0.05, 1.0]) / np.linalg.norm([0.1, 0.05, 1.0])
    y0 = np.array([[0.4, -0.3, 4.0, *g]])
    ds = tumble.integrate(top, y0, 10.0, 0.005, method="rk8", save_every=200)
    states = ds["state"].values[0]
    for name, values in top.invariants(states).items():
        assert np.ptp(values) <= 1e-10 * max(1.0, np.abs(values).max()), name
    centre = top.centre
    by_hand = hand_written_systems.HEAVY_TOP  # compiled once on the worker of its group, for test_user_systems too
    assert by_hand.state == top.spec.state
    parameters = {"I1": 2.0, "I2": 2.5, "I3": 3.0, "mgl": 0.7, "c1": centre[0], "c2": centre[1], "c3": centre[2]}
    np.testing.assert_allclose(tumble.propagate(by_hand, y0, 10.0, 0.005, method="rk8", parameters=parameters),
                               states[-1:], rtol=0, atol=1e-11)
    splitting = tumble.propagate(top, y0, 10.0, 0.005, method="splitting4")
    assert np.max(np.abs(splitting - states[-1:])) < 1e-5  # the splitting's own gravity flow, off axis too


def test_the_default_centre_is_todays_top_to_the_last_bit():
    y0 = np.array([[0.1, 0.0, 5.0, 0.01, 0.0, 1.0]])
    for method in ("rk4", "splitting2"):
        default = tumble.propagate(HeavyTop((2.0, 2.5, 3.0), 0.5), y0, 2.0, 0.01, method=method)
        explicit = tumble.propagate(HeavyTop((2.0, 2.5, 3.0), 0.5, centre=(0.0, 0.0, 2.0)), y0, 2.0, 0.01,
                                    method=method)
        assert np.array_equal(default, explicit)


def test_an_eccentric_orbit_follows_keplers_equation_and_its_torque_is_periodic():
    e, n = 0.3, 0.1
    constants = gravity_gradient.constants((1.0, 2.0, 3.0), n, e)
    model = GravityGradient((1.0, 2.0, 3.0), n, eccentricity=e)
    period = 2 * math.pi / n
    for t in (0.0, 7.0, 31.0, 50.0):
        nu_dot, strength = gravity_gradient.orbit(t, constants)
        assert (nu_dot, strength) == pytest.approx(tuple(float(x) for x in model.orbit(t)), rel=1e-14)
        assert gravity_gradient.orbit(t + 3 * period, constants) == pytest.approx((nu_dot, strength), rel=1e-12)
    # perigee and apogee: nu' = n sqrt(1 - e^2) / (1 -+ e)^2, strength = 3 n^2 / (1 -+ e)^3
    assert gravity_gradient.orbit(0.0, constants) == pytest.approx(
        (n * math.sqrt(1 - e * e) / (1 - e) ** 2, 3 * n * n / (1 - e) ** 3), rel=1e-14)
    assert gravity_gradient.orbit(period / 2, constants) == pytest.approx(
        (n * math.sqrt(1 - e * e) / (1 + e) ** 2, 3 * n * n / (1 + e) ** 3), rel=1e-12)
    # the true anomaly integrated over one orbit is 2 pi
    times = np.linspace(0.0, period, 20001)
    nu_dot = model.orbit(times)[0]
    assert np.trapezoid(nu_dot, times) == pytest.approx(2 * math.pi, rel=1e-8)


def test_an_eccentric_satellite_integrates_on_the_unit_sphere_and_a_circular_one_is_unchanged():
    y0 = np.array([[0.01, -0.1, 0.02, 1.0, 0.0, 0.0, 0.0]])
    circular = tumble.propagate(GravityGradient((1.0, 2.0, 3.0), 0.1), y0, 50.0, 0.05, method="rk4")
    zero = tumble.propagate(GravityGradient((1.0, 2.0, 3.0), 0.1, eccentricity=0.0), y0, 50.0, 0.05, method="rk4")
    assert np.array_equal(circular, zero)
    eccentric = tumble.integrate(GravityGradient((1.0, 2.0, 3.0), 0.1), y0, 50.0, 0.05, method="rk8",
                                 save_every=100, parameters={"eccentricity": 0.2})
    q = eccentric["state"].values[0, :, 3:]
    np.testing.assert_allclose(np.sum(q * q, axis=-1), 1.0, rtol=0, atol=1e-14)
    assert eccentric.attrs["parameter_eccentricity"] == 0.2
    assert not np.allclose(eccentric["state"].values[0, -1], circular[0], atol=1e-3)


@pytest.mark.parametrize("make, message", [
    (lambda: HeavyTop((2.0, 2.5, 3.0), 0.7, centre=(0.0, 0.0, 0.0)), r"centre must be a non-zero 3-vector"),
    (lambda: GravityGradient((1.0, 2.0, 3.0), 0.1, eccentricity=1.0), r"eccentricity must be a number in \[0, 1\)"),
    (lambda: HeavyTop((2.0, 2.5, 3.0), 0.7, centre=(0.1, 0.0, 1.0)).equilibrium(3),
     r"a steady spin about axis 3 \(the sleeping top\) needs the centre of mass on body axis 3"),
    (lambda: GravityGradient((1.0, 2.0, 3.0), 0.1, eccentricity=0.1).equilibrium(),
     r"an equilibrium needs a circular orbit"),
    (lambda: tumble.propagate(HeavyTop((2.0, 2.5, 3.0), 0.7), np.zeros((1, 6)), 1.0, 0.1, parameters={"l": 1.0}),
     r"'l' is not a parameter of the heavy_top model \(it has: mgl, centre\)"),
])
def test_the_new_parameters_are_checked(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_a_cache_entry_is_stamped_with_the_modules_its_kernel_imports_so_an_edited_callee_recompiles(tmp_path,
                                                                                                     monkeypatch):
    """numba stamps a cache entry with its own function's file; a driver holds a system's rate inlined, so an edit of
    a module the driver's module imports, directly or not (``from .systems import x``, ``from ..registry import (...)``
    over lines), must invalidate it too (it used to run the old equations from the cache). A module it does not import
    leaves it alone: an edit of one kernel recompiles the kernels that depend on it, not all of them."""
    from tumble.kernels import jit

    package = tmp_path / "tumble"
    (package / "kernels" / "systems").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "registry.py").write_text("A = 1\n")
    (package / "kernels" / "__init__.py").write_text("")
    (package / "kernels" / "driver.py").write_text("from .systems import rate\nfrom ..registry import (  # (x)\n    A,\n)\n"
                                                   "def f():\n    from . import fused\n")
    (package / "kernels" / "fused.py").write_text("C = 1\n")
    (package / "kernels" / "other.py").write_text("x = 1\n")
    (package / "kernels" / "systems" / "__init__.py").write_text("")
    (package / "kernels" / "systems" / "rate.py").write_text("from .._rigid import B\n")
    (package / "kernels" / "_rigid.py").write_text("B = 1\n")
    monkeypatch.setattr(jit, "_PACKAGE", str(package))
    driver = str(package / "kernels" / "driver.py")

    def stamp():
        monkeypatch.setattr(jit, "_STAMPS", {})
        return jit._source_stamp(driver)

    before = stamp()
    (package / "kernels" / "other.py").write_text("x = 22\n")
    assert stamp() == before
    for edited in ("kernels/systems/rate.py", "kernels/_rigid.py", "registry.py", "kernels/systems/__init__.py",
                   "kernels/fused.py"):
        (package / edited).write_text((package / edited).read_text() + "# edited\n")
        after = stamp()
        assert after != before, edited
        before = after
