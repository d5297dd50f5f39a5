"""Orientation: the closed form against an independent integration, every method against the closed form, and
the physics in space — L fixed, the disc's wobble, the Dzhanibekov flip, Montgomery's rotation per period."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import tumble
from tumble.kernels.loops import methods as kernel_methods
from tumble.kernels.loops.methods import METHODS
from tumble.physics import exact, rotations, shapes

BODY = tumble.Body(1.0, 2.0, 3.0)
# both regimes, near the separatrix, a negative component, a spin near the largest axis
SPINS = np.array([[0.1, 1.0, 0.05], [1.0, 0.2, 0.1], [0.05, 0.3, -1.0], [-0.3, 0.2, 0.9], [1e-3, 1.0, 1e-3]])


def reference(moments, w0, times, torque=(0.0, 0.0, 0.0)):
    """(omega, q) by SciPy's DOP853 at tight tolerances: Euler's equations with q' = ½ q ⊗ (0, w)."""
    I = np.asarray(moments, dtype=float)
    N = np.asarray(torque, dtype=float)

    def rhs(t, y):
        w, q = y[:3], y[3:]
        dw = (np.cross(I * w, w) + N) / I
        dq = 0.5 * rotations.product(q, np.concatenate([[0.0], w]))
        return np.concatenate([dw, dq])

    sol = solve_ivp(rhs, (0.0, times[-1]), np.concatenate([w0, [1.0, 0.0, 0.0, 0.0]]), method="DOP853",
                    t_eval=times, rtol=1e-13, atol=1e-14)
    return sol.y[:3].T, sol.y[3:].T / np.linalg.norm(sol.y[3:].T, axis=1, keepdims=True)


def angle_about(q, axis):
    """Signed rotation angle of ``q`` about the unit vector ``axis`` (q must turn about that axis)."""
    return 2.0 * np.arctan2(q[..., 1:] @ axis, q[..., 0])


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (2.0, 2.0, 3.0)])
def test_closed_form_matches_an_independent_integration(moments):
    times = np.linspace(0.0, 12.0, 25)
    q = exact.attitude(moments, SPINS, times)
    for w0, q_i in zip(SPINS, q):
        _, q_ref = reference(moments, w0, times)
        assert rotations.angle_between(q_i, q_ref).max() < 1e-10


def test_closed_form_is_continuous_and_starts_at_the_identity():
    times = np.linspace(0.0, 40.0, 4001)
    q = exact.attitude(BODY, SPINS, times)
    np.testing.assert_allclose(q[:, 0], [[1.0, 0.0, 0.0, 0.0]] * len(SPINS), atol=1e-15)
    assert np.abs(np.diff(q, axis=1)).max() < 0.05  # no sign jumps between neighbouring times
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-14)
    # any single time gives the value of the whole series
    np.testing.assert_allclose(exact.attitude(BODY, SPINS[1], 17.3), exact.attitude(BODY, SPINS[1], [0.0, 17.3])[1],
                               atol=1e-13)


def test_closed_form_steady_spins_turn_uniformly():
    w0 = np.array([[0.0, 2.0, 0.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.0]])
    times = np.array([0.0, 0.3, 1.0])
    q = exact.attitude(BODY, w0, times)
    np.testing.assert_allclose(q[0], rotations.about_axis(2.0 * times, 1), atol=1e-15)
    np.testing.assert_allclose(q[1], [[1.0, 0.0, 0.0, 0.0]] * 3)
    np.testing.assert_allclose(q[2], rotations.about_axis(0.5 * times, 0), atol=1e-15)


def test_closed_form_on_the_separatrix():
    # I1 (I2 - I1) w1² = I3 (I3 - I2) w3² exactly for I = (3, 4, 6) and w1 = 2 w3: L² = 2E I2
    body = tumble.Body(3.0, 4.0, 6.0)
    w0 = np.array([2.0, 0.7, 1.0])
    assert exact.parameters(body, w0).regime == 0
    times = np.linspace(0.0, 6.0, 13)
    _, q_ref = reference(body.moments, w0, times)
    assert rotations.angle_between(exact.attitude(body, w0, times), q_ref).max() < 1e-9


# step pairs chosen so the error is far above round-off and in the asymptotic regime
_STEPS = {"rk4": (0.05, 0.025), "rk8": (0.25, 0.125), "symplectic_euler": (0.01, 0.005), "splitting2": (0.05, 0.025),
          "splitting4": (0.1, 0.05), "implicit_midpoint": (0.05, 0.025)}


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_carries_the_attitude_at_its_order(method):
    w0 = np.array([[0.4, 1.0, 0.3], [1.0, 0.2, 0.5]])
    q_exact = exact.attitude(BODY, w0, [5.0])
    errors = [rotations.angle_between(q_exact, tumble.integrate(BODY, w0, 5.0, dt, method=method,
                                                                attitude=True).quaternion.values).max()
              for dt in _STEPS[method]]
    order = np.log2(errors[0] / errors[1])
    assert abs(order - METHODS[method].order) < 0.3, (method, errors)


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (2.0, 3.0, 1.0)])
@pytest.mark.parametrize("method", list(METHODS))
def test_angular_momentum_stays_fixed_in_space(method, moments):
    """Geometric methods keep L in space to round-off; the Runge–Kutta methods to their truncation error.
    The angular velocity of an attitude run is the plain run's up to rounding."""
    body = tumble.Body(*moments)
    w0 = SPINS[:4]
    dt = 1e-3 if method == "symplectic_euler" else 1e-2
    ds = tumble.integrate(body, w0, 10.0, dt, method=method, save_every=100, attitude=True)
    L_space = rotations.rotate(ds.quaternion.values, body.moments * ds.omega.values)
    drift = np.abs(L_space - (body.moments * w0)[:, None]).max() / np.abs(body.moments * w0).max()
    assert drift < (1e-13 if METHODS[method].geometric else 1e-8), drift
    plain = tumble.integrate(body, w0, 10.0, dt, method=method, save_every=100)
    np.testing.assert_allclose(ds.omega.values, plain.omega.values, rtol=0, atol=1e-13)


@pytest.mark.parametrize("method", ["rk4", "splitting4", "implicit_midpoint"])
def test_attitude_with_a_torque_matches_an_independent_integration(method):
    torque = (0.02, -0.01, 0.05)
    w0 = np.array([0.3, 1.0, 0.2])
    ds = tumble.integrate(BODY, w0, 4.0, 1e-3, method=method, torque=torque, save_every=1000, attitude=True)
    w_ref, q_ref = reference(BODY.moments, w0, ds.time.values, torque)
    tol = 1e-9 if METHODS[method].order >= 4 else 1e-5
    assert rotations.angle_between(ds.quaternion.values[0], q_ref).max() < tol
    np.testing.assert_allclose(ds.omega.values[0], w_ref, atol=tol)


def test_thin_disc_wobbles_at_L_over_I1_and_at_twice_the_spin_only_at_small_tilt():
    """The lecture's disc (I3 = 2 I1): its symmetry axis precesses about L at |L|/I1 exactly; that is 2 w_s
    only in the small-tilt limit."""
    disc = shapes.disc(1.0, 1.0)
    I1, _, I3 = disc.moments
    assert I3 == pytest.approx(2.0 * I1)
    spin = 3.0
    rates = {}
    for tilt in (1e-3, 0.3):
        w0 = spin * np.array([np.sin(tilt), 0.0, np.cos(tilt)])
        L = disc.moments * w0
        size = np.linalg.norm(L)
        t = np.linspace(0.0, 4.0, 81)
        for method in ("exact", "splitting4"):
            q = tumble.integrate(disc, w0, 4.0, 1e-3, method=method, save_every=50, attitude=True).quaternion.values[0]
            symmetry_axis = rotations.rotate(q, [0.0, 0.0, 1.0])
            # exact relation: a(t) = Rot(L, |L| t / I1) a(0)
            expected = rotations.rotate(rotations.about_axis(size * t / I1, L)[:, :], symmetry_axis[0])
            assert np.abs(symmetry_axis - expected).max() < (1e-12 if method == "exact" else 1e-9)
        # the precession rate measured from the attitude: the symmetry axis's azimuth about L against time
        L_hat = L / size
        e1 = np.cross(L_hat, [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(L_hat, e1)
        azimuth = np.unwrap(np.arctan2(symmetry_axis @ e2, symmetry_axis @ e1))
        measured = np.polyfit(t, azimuth, 1)[0]
        assert measured == pytest.approx(size / I1, rel=1e-9)
        rates[tilt] = measured / (2.0 * w0[2])  # precession rate against twice the spin about the axis
    assert rates[1e-3] == pytest.approx(1.0, rel=1e-6)  # the lecture's 2 w_s
    assert abs(rates[0.3] - 1.0) > 1e-2  # not at a large tilt


@pytest.mark.parametrize("method", ["exact", "rk4"])
def test_dzhanibekov_flip_reverses_the_intermediate_axis_in_space_while_L_stays_put(method):
    handle = shapes.t_handle()
    I = handle.moments
    tilt = 1e-3
    w0 = 10.0 * np.array([np.sin(tilt), np.cos(tilt), 0.0])  # about the intermediate axis (moments ascending)
    first, spacing = exact.first_flip_time(handle, w0), exact.flip_spacing(handle, w0)
    t_end = first + 2.5 * spacing
    ds = tumble.integrate(handle, w0, t_end, 1e-4, method=method, save_every=10, attitude=True)
    q, w, t = ds.quaternion.values[0], ds.omega.values[0], ds.time.values
    L0 = I * w0
    L_hat = L0 / np.linalg.norm(L0)
    np.testing.assert_allclose(rotations.rotate(q, I * w), np.broadcast_to(L0, w.shape), atol=1e-12 * np.abs(L0).max())
    projection = rotations.rotate(q, [0.0, 1.0, 0.0]) @ L_hat  # the intermediate axis along L, in space
    np.testing.assert_allclose(projection, I[1] * w[:, 1] / np.linalg.norm(L0), atol=1e-9)
    crossings = t[:-1][np.diff(np.sign(projection)) != 0]
    expected = first + spacing * np.arange(3)
    assert len(crossings) == 3
    np.testing.assert_allclose(crossings, expected, atol=2e-3)  # the save grid is 1e-3 s
    # it reverses: nearly along +L, then nearly along -L, and back
    assert projection.max() > 0.999 and projection.min() < -0.999


def test_montgomery_rotation_per_period_matches_the_attitude():
    w0 = SPINS[:4]
    delta, solid = exact.rotation_per_period(BODY, w0)
    T = exact.period(BODY, w0)
    assert np.all(np.abs(solid) < 2.0 * np.pi)  # the smaller cap
    for i, w in enumerate(w0):
        L_hat = BODY.moments * w / np.linalg.norm(BODY.moments * w)
        wrap = lambda x: np.angle(np.exp(1j * x))  # noqa: E731
        q_exact = exact.attitude(BODY, w, T[i])
        # after one period the body has turned about L only
        assert np.linalg.norm(q_exact[1:] - (q_exact[1:] @ L_hat) * L_hat) < 1e-12
        assert wrap(angle_about(q_exact, L_hat) - delta[i]) == pytest.approx(0.0, abs=1e-10)
        for method, steps in (("splitting4", 4000), ("rk8", 500)):
            q = tumble.integrate(BODY, w, T[i], T[i] / steps, method=method, attitude=True).quaternion.values[0, -1]
            assert wrap(angle_about(q, L_hat) - delta[i]) == pytest.approx(0.0, abs=1e-9), method


def test_rotation_per_period_is_nan_where_the_motion_is_not_periodic():
    delta, solid = exact.rotation_per_period(BODY, [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    assert np.isnan(delta).all() and np.isnan(solid).all()


def test_integrate_attitude_dataset():
    ds = tumble.integrate(BODY, SPINS[:2], 1.0, 0.01, method="rk4", save_every=10, attitude=True)
    assert ds["quaternion"].dims == ("sample", "time", "component")
    assert ds["quaternion"].shape == (2, 11, 4)
    assert list(ds["component"].values) == [0, 1, 2, 3]
    assert ds["quaternion"].attrs["long_name"].startswith("body-to-space")
    plain = tumble.integrate(BODY, SPINS[:2], 1.0, 0.01, method="rk4")
    assert "quaternion" not in plain and plain.attrs["attitude"] == 0 and ds.attrs["attitude"] == 1
    final = tumble.integrate(BODY, SPINS[:2], 1.0, 0.01, method="rk4", attitude=True)
    np.testing.assert_array_equal(final.quaternion.values[:, 0], ds.quaternion.values[:, -1])
    with pytest.raises(ValueError, match="torque"):
        tumble.integrate(BODY, SPINS[:2], 1.0, 0.01, method="exact", torque=(0, 0, 1), attitude=True)


def test_no_attitude_code_runs_unless_asked(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("the attitude kernel ran")

    monkeypatch.setattr(kernel_methods, "propagate_attitude", refuse)
    monkeypatch.setattr(exact, "attitude", refuse)
    for method in ("rk4", "splitting4", "exact"):
        tumble.integrate(BODY, SPINS[:2], 1.0, 0.01, method=method, save_every=10)
    with pytest.raises(AssertionError, match="attitude kernel"):
        tumble.integrate(BODY, SPINS[:2], 1.0, 0.01, method="rk4", attitude=True)


def test_a_failed_implicit_midpoint_step_is_flagged_with_its_attitude():
    w0 = np.array([[0.0, 22.0, 0.1]])
    with pytest.warns(RuntimeWarning, match="non-finite"):
        ds = tumble.integrate(BODY, w0, 1.0, 0.1, method="implicit_midpoint", attitude=True)
    assert ds.status.values[0] == 1
    assert np.isnan(ds.quaternion.values).all()


def test_the_dzhanibekov_flip_study_draws_its_attitude_figures_and_plot_redraws_them(tmp_path, capsys):
    from tumble import cli

    assert cli.main(["run", "dzhanibekov_flip", "--samples", "16", "--out", str(tmp_path / "run")]) == 0
    names = ("flip_animation.gif", "flip_strip.png", "polhode.png", "herpolhode.png")
    for name in names:
        assert (tmp_path / "run" / f"dzhanibekov_flip_{name}").stat().st_size > 1000
    import xarray as xr

    with xr.open_dataset(tmp_path / "run" / "dzhanibekov_flip.nc") as ds:
        q = ds["attitude_quaternion"].values
        assert ds["attitude_quaternion"].attrs["body_shape"] == "t_handle"
        assert ds["axis"].size == 1  # the spin axis stays the scene's coordinate
    L = rotations.rotate(q, shapes.t_handle().moments * ds["attitude_omega"].values)
    assert np.ptp(L, axis=0).max() < 1e-12 * np.abs(L).max()
    assert cli.main(["plot", str(tmp_path / "run" / "dzhanibekov_flip.nc"), "--figures", "flip_strip", "polhode",
                     "--out", str(tmp_path / "again")]) == 0
    assert sorted(p.name for p in (tmp_path / "again").iterdir()) == ["dzhanibekov_flip_flip_strip.png",
                                                                      "dzhanibekov_flip_polhode.png"]


def test_attitude_trace_by_a_fixed_step_method_matches_the_closed_form():
    from tumble.measure import traces

    handle = shapes.t_handle()
    closed = traces.attitude_trace(handle, 2, 10.0, 1e-3)
    stepped = traces.attitude_trace(handle, 2, 10.0, 1e-3, method="splitting4")
    assert closed["attitude_quaternion"].attrs["method"] == "exact"
    assert stepped.attitude_time.values[-1] == pytest.approx(closed.attitude_time.values[-1])
    end = rotations.angle_between(closed.attitude_quaternion.values[-1], stepped.attitude_quaternion.values[-1])
    assert end < 1e-8
    # three flips: the horizon is the first flip time plus 2.5 flip spacings
    w0 = closed.attitude_omega.values[0]
    assert closed.attitude_time.values[-1] == pytest.approx(exact.first_flip_time(handle, w0)
                                                            + 2.5 * exact.flip_spacing(handle, w0))
