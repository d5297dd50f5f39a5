"""A user's own system (``tumble.System``) and the built-in models run through ``tumble.integrate`` / ``propagate``.

The systems are written here, in the test file, as a user writes them: a damped pendulum and the free rigid body
by hand. They are checked against SciPy's DOP853 at rtol 1e-12, against tumble's own free body, on the CPU and on
numba-cuda's simulator (tests/conftest.py sets ``NUMBA_ENABLE_CUDASIM=1``), with a Runge–Kutta tableau added at
test time; and every mistake a user can make gets one line naming the system.
"""

import importlib.util
import math
import os
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import tumble
from tumble.kernels import TABLEAUX
from tumble.kernels.tableaux import ButcherTableau

import hand_written_systems

# Every test here runs on one worker (pyproject's --dist loadgroup): PENDULUM, FREE_BODY and the hand-written heavy
# top are compiled once per process, so on one worker they are compiled once, not once on each.
pytestmark = pytest.mark.xdist_group(hand_written_systems.GROUP)


def pendulum(t, y, p, dydt):
    """A damped pendulum: x'' = -k sin x - c x'."""
    dydt[0] = y[1]
    dydt[1] = -p[0] * math.sin(y[0]) - p[1] * y[1]


def pendulum_jacobian(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[0] * math.cos(y[0])
    J[1, 1] = -p[1]


def free_body(t, y, p, dydt):
    """Euler's equations, I1 w1' = (I2 - I3) w2 w3 and cyclic; p = (I1, I2, I3)."""
    dydt[0] = (p[1] - p[2]) * y[1] * y[2] / p[0]
    dydt[1] = (p[2] - p[0]) * y[2] * y[0] / p[1]
    dydt[2] = (p[0] - p[1]) * y[0] * y[1] / p[2]


PENDULUM = tumble.System(pendulum, state=("x", "v"), parameters={"k": 2.0, "c": 0.1}, name="pendulum")
FREE_BODY = tumble.System(free_body, state=("w1", "w2", "w3"), parameters={"I1": 1.0, "I2": 2.0, "I3": 3.0},
                          name="free body by hand")
MOMENTS = (1.0, 2.0, 3.0)
SPINS = np.array([[0.01, 1.0, 0.02], [0.3, 0.1, 1.0], [1.0, 0.2, -0.1]])


def _dop853(rate, y0, t_end, p):
    def f(t, y):
        out = np.empty_like(y)
        rate(t, y, p, out)
        return out

    return np.array([solve_ivp(f, (0.0, t_end), y, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1] for y in y0])


def test_a_damped_pendulum_agrees_with_dop853_and_its_dataset_names_the_components():
    y0 = np.array([[0.5, 0.0], [2.5, -0.3], [-1.0, 1.5]])
    ds = tumble.integrate(PENDULUM, y0, 10.0, 0.01, method="rk8", save_every=100)
    assert ds["state"].dims == ("sample", "time", "component")
    assert list(ds["component"].values) == ["x", "v"]
    assert ds.attrs["system"] == "pendulum" and ds.attrs["parameter_k"] == 2.0 and ds.attrs["method"] == "rk8"
    np.testing.assert_allclose(ds["time"].values, np.linspace(0.0, 10.0, 11), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(ds["state"].values[:, 0], y0)
    reference = _dop853(pendulum, y0, 10.0, np.array([2.0, 0.1]))
    np.testing.assert_allclose(ds["state"].values[:, -1], reference, rtol=0, atol=1e-11)
    assert np.all(ds["status"].values == 0)


def test_parameters_override_the_systems_defaults_and_unknown_ones_are_refused():
    y0 = np.array([[1.0, 0.0]])
    undamped = tumble.propagate(PENDULUM, y0, 5.0, 0.01, method="rk8", parameters={"c": 0.0})
    np.testing.assert_allclose(undamped, _dop853(pendulum, y0, 5.0, np.array([2.0, 0.0])), rtol=0, atol=1e-11)
    with pytest.raises(ValueError, match=r"'damping' is not a parameter of system 'pendulum' \(it has: k, c\)"):
        tumble.propagate(PENDULUM, y0, 1.0, 0.01, parameters={"damping": 0.0})


def test_the_free_body_by_hand_gives_tumbles_free_body_and_dop853():
    mine = tumble.propagate(FREE_BODY, SPINS, 20.0, 0.01, method="rk4")
    builtin = tumble.propagate(tumble.Body(*MOMENTS), SPINS, 20.0, 0.01, method="rk4")
    np.testing.assert_allclose(mine, builtin, rtol=0, atol=1e-12)
    reference = _dop853(free_body, SPINS, 20.0, np.array(MOMENTS))
    np.testing.assert_allclose(mine, reference, rtol=0, atol=1e-6)  # rk4 at 10 ms over 20 s


def test_a_system_on_the_device_gives_the_cpu_run(cuda_device):
    y0 = np.array([[0.5, 0.0], [2.5, -0.3], [0.0, 1e308]])  # the last overflows in rk8's first stages
    with pytest.warns(RuntimeWarning, match="1 of 3 samples of 'pendulum' became non-finite"):
        cpu = tumble.integrate(PENDULUM, y0, 1.0, 0.05, method="rk8", save_every=4)
    with pytest.warns(RuntimeWarning, match="1 of 3 samples"):
        device = tumble.integrate(PENDULUM, y0, 1.0, 0.05, method="rk8", save_every=4, device=cuda_device)
    # the finite samples agree (the CPU's blocks keep a sample's state from the check that caught it, the device's
    # per-sample loop the last finite one: either way its status says it is not a result)
    np.testing.assert_allclose(device["state"].values[:2], cpu["state"].values[:2], rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(device["status"].values, cpu["status"].values)
    assert list(cpu["status"].values) == [0, 0, 1]  # the sample that overflows says so
    assert device.attrs["device"] == "cuda"


def _ralston3():
    """Ralston's third-order method (Ralston 1962): the tableau with minimum error bound."""
    return ButcherTableau.build("ralston3", 3, [[], [0.5], [0.0, 0.75]], [2 / 9, 1 / 3, 4 / 9], [0.0, 0.5, 0.75])


#: An asymmetric heavy top, its centre off axis 3: the generated steps do not know ralston3, the per-sample loop does.
HEAVY_TOP = tumble.models.HeavyTop((2.0, 2.5, 3.0), 0.7, centre=(0.3, 0.0, 1.0))
HEAVY_TOP_STATE = np.array([[0.4, -0.3, 2.0, 0.1, 0.2, math.sqrt(1.0 - 0.05)]])


def _observed_order(system, y0, reference, device, method):
    errors = [np.max(np.abs(tumble.propagate(system, y0, 2.0, dt, method=method, device=device) - reference))
              for dt in (0.04, 0.02, 0.01)]
    return np.polyfit(np.log([0.04, 0.02, 0.01]), np.log(errors), 1)[0]


@pytest.mark.slow
def test_a_tableau_registered_at_test_time_runs_at_its_order_on_the_cpu_and_the_device(monkeypatch, cuda_device):
    """A method is its coefficients: Ralston's third-order tableau, added at test time, runs on a user's System, on
    the built-in free body and on a built-in heavy top (whose generated SIMD steps know rk4 and rk8 only: they run it
    through the per-sample loop, their rate from the generated dispatch) at order 3, on the CPU and the device."""
    monkeypatch.setitem(TABLEAUX, "ralston3", _ralston3())
    y0 = SPINS[:1]
    exact = tumble.exact.omega(tumble.Body(*MOMENTS), y0, np.array([2.0]))[:, -1]
    top = tumble.propagate(HEAVY_TOP, HEAVY_TOP_STATE, 2.0, 0.002, method="rk8")
    cases = [(FREE_BODY, y0, exact), (tumble.models.FreeBody(MOMENTS), y0, exact), (tumble.Body(*MOMENTS), y0, exact),
             (HEAVY_TOP, HEAVY_TOP_STATE, top)]
    for system, state, reference in cases:
        for device in ("cpu", cuda_device):
            order = _observed_order(system, state, reference, device, "ralston3")
            assert abs(order - 3.0) < 0.1, (system, device, order)
    assert tumble.integrate(HEAVY_TOP, HEAVY_TOP_STATE, 0.1, 0.05, method="ralston3").attrs["order"] == 3
    np.testing.assert_allclose(  # the same per-sample code on both devices
        tumble.propagate(HEAVY_TOP, HEAVY_TOP_STATE, 1.0, 0.05, method="ralston3", device=cuda_device),
        tumble.propagate(HEAVY_TOP, HEAVY_TOP_STATE, 1.0, 0.05, method="ralston3"), rtol=1e-13, atol=1e-15)


@pytest.mark.slow  # a tableau added at run time compiles its loop in every process
def test_a_body_steps_a_tableau_added_at_run_time_as_the_free_body_model_does(monkeypatch):
    """A tumble.Body with a tableau added at run time runs it through the per-sample loop (its fused steps know the
    built-in methods only): the free-body Dataset of integrate, the same bits as tumble.models.FreeBody, torque-free
    and without the attitude (each refused in one line), and run_ensemble's final states."""
    monkeypatch.setitem(TABLEAUX, "ralston3", _ralston3())
    body, y0 = tumble.Body(*MOMENTS), SPINS[:2]
    ds = tumble.integrate(body, y0, 1.0, 0.1, method="ralston3", save_every=5)
    assert ds["omega"].dims == ("sample", "time", "axis") and ds["omega"].shape == (2, 3, 3)
    assert ds.attrs["method"] == "ralston3" and ds.attrs["order"] == 3 and ds.attrs["path"] == "per-sample loop"
    assert ds.attrs["sample_steps_computed"] == 20 and list(ds["time"].values) == [0.0, 0.5, 1.0]
    model = tumble.integrate(tumble.models.FreeBody(MOMENTS), y0, 1.0, 0.1, method="ralston3", save_every=5)
    np.testing.assert_array_equal(ds["omega"].values, model["state"].values)
    final = tumble.propagate(body, y0, 1.0, 0.1, method="ralston3")
    np.testing.assert_array_equal(final, ds["omega"].values[:, -1])
    np.testing.assert_array_equal(tumble.run_ensemble(body, y0, 1.0, 0.1, method="ralston3").final, final)
    for extra in ({"torque": (0.0, 0.0, 0.1)}, {"attitude": True}):
        with pytest.raises(ValueError, match="a tableau added at run time, steps a free body torque-free") as refused:
            tumble.integrate(body, y0, 1.0, 0.1, method="ralston3", **extra)
        assert "\n" not in str(refused.value)
    with pytest.raises(ValueError, match="max_flips observe a rigid body's scene with the built-in methods"):
        tumble.run_ensemble(body, y0, 1.0, 0.1, method="ralston3", max_flips=2)


def test_a_built_in_model_integrates_by_name_with_its_state_components():
    top = tumble.models.HeavyTop((2.0, 2.5, 3.0), 0.5)
    y0 = np.array([[0.1, 0.0, 5.0, 0.05, 0.0, 1.0]])
    y0[:, 3:] /= np.linalg.norm(y0[:, 3:], axis=1, keepdims=True)
    ds = tumble.integrate(top, y0, 2.0, 0.01, method="rk8", save_every=50, parameters={"mgl": 0.6})
    assert list(ds["component"].values) == ["w1", "w2", "w3", "g1", "g2", "g3"]
    assert list(ds["component_units"].values) == ["rad/s"] * 3 + ["1"] * 3
    assert ds.attrs["system"] == "heavy_top" and ds.attrs["parameter_mgl"] == 0.6
    by_hand = hand_written_systems.HEAVY_TOP  # the centre of mass on axis 3: (0, 0, 1), the defaults
    assert list(by_hand.state) == list(ds["component"].values)
    mine = tumble.propagate(by_hand, y0, 2.0, 0.01, method="rk8", parameters={"mgl": 0.6})
    np.testing.assert_allclose(ds["state"].values[:, -1], mine, rtol=0, atol=1e-12)
    splitting = tumble.propagate(top, y0, 2.0, 0.01, method="splitting4")
    np.testing.assert_allclose(splitting, mine, rtol=0, atol=1e-2)  # mgl 0.5 against 0.6: the parameter acted
    assert not np.allclose(splitting, mine, atol=1e-6)


def test_eigenvalues_at_any_state_from_the_jacobian_or_differentiated_rate():
    with_jacobian = tumble.System(pendulum, state=("x", "v"), parameters={"k": 2.0, "c": 0.1}, name="pendulum",
                                  jacobian=pendulum_jacobian)
    for state in ([0.0, 0.0], [math.pi, 0.0], [0.7, 0.3]):
        k, c = 2.0, 0.1
        exact = np.linalg.eigvals(np.array([[0.0, 1.0], [-k * math.cos(state[0]), -c]]))
        for system in (PENDULUM, with_jacobian):
            found = np.sort_complex(tumble.theory.eigenvalues_at(system, state))
            np.testing.assert_allclose(found, np.sort_complex(exact), rtol=1e-10, atol=1e-12)
    # the free body at a steady spin about its intermediate axis: +-sqrt(-q) w and 0, as linear theory says
    rate = tumble.theory.linear(tumble.Body(*MOMENTS), 2, 1.0)[1]
    for system in (tumble.Body(*MOMENTS), FREE_BODY):
        found = np.sort(tumble.theory.eigenvalues_at(system, [0.0, 1.0, 0.0]).real)
        np.testing.assert_allclose(found, [-rate, 0.0, rate], rtol=0, atol=1e-10)


def _uncompilable(t, y, p, dydt):
    dydt[0] = y[0] + {"a": 1}["a"] * undefined_name  # noqa: F821 - a user's mistake


def _out_of_bounds(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = y[2]


def _unset(t, y, p, dydt):
    dydt[0] = y[1]


def _nan(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = math.sqrt(y[0] - 10.0)


@pytest.mark.parametrize("rate, message", [
    (_uncompilable, r"^system 'bad': numba cannot compile rate\(t, y, p, dydt\) in nopython mode: .*undefined_name"),
    (_out_of_bounds, r"^system 'bad': its rate indexes beyond the state or the parameters \(state has 2 components"),
    (_unset, r"^system 'bad': its rate left dydt\[1\] \(v\) unset or NaN at sample 0's initial state"),
    (_nan, r"^system 'bad': its rate left dydt\[1\] \(v\) unset or NaN"),
])
def test_a_rate_that_cannot_run_is_one_line_naming_the_system(rate, message):
    bad = tumble.System(rate, state=("x", "v"), name="bad")
    with pytest.raises(ValueError, match=message) as caught:
        tumble.propagate(bad, [[1.0, 0.0]], 1.0, 0.1)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("call, message", [
    (lambda: tumble.propagate(PENDULUM, [[1.0, 0.0, 0.0]], 1.0, 0.1),
     r"y0 must have shape \(N, 2\) with N >= 1 \(x, v of 'pendulum'\), got shape \(1, 3\)"),
    (lambda: tumble.propagate(PENDULUM, [[1.0, 0.0]], 1.0, 0.1, method="splitting2"),
     r"method must be one of rk4, rk8 for 'pendulum', got 'splitting2' \(a System runs the explicit Runge-Kutta"),
    (lambda: tumble.integrate(PENDULUM, [[1.0, 0.0]], 1.0, 0.1, torque=(0.0, 0.0, 1.0)),
     r"torque acts on a free body; 'pendulum' has its torques in its own equations"),
    (lambda: tumble.integrate(PENDULUM, [[1.0, 0.0]], 1.0, 0.1, attitude=True), r"attitude=True integrates a free"),
    (lambda: tumble.integrate(tumble.Body(*MOMENTS), SPINS, 1.0, 0.1, parameters={"k": 1.0}),
     r"parameters are a model's or a System's; a free body has none"),
    (lambda: tumble.System(pendulum, state=("x", "x"), name="p"), r"system 'p': state has a name twice: x, x"),
    (lambda: tumble.System(pendulum, state=("x", "v"), parameters={"k": math.nan}, name="p"),
     r"system 'p': parameter 'k' must be finite"),
    (lambda: tumble.System("not a function", state=("x",), name="p"), r"system 'p': rate must be a function"),
    (lambda: tumble.integrate(PENDULUM, [[1.0, 0.0], [math.nan, 0.0]], 1.0, 0.1),
     r"y0 must be finite: sample 1 holds NaN or inf \(x, v = \[nan, 0.0\]\)"),
    (lambda: tumble.propagate(PENDULUM, [[math.inf, 0.0]] * 3, 1.0, 0.1),
     r"y0 must be finite: sample 0 holds NaN or inf \(x, v = \[inf, 0.0\]\), and 2 more"),
    (lambda: tumble.propagate(tumble.models.HeavyTop((2.0, 2.5, 3.0), 0.7), [[0, 0, 1, 0, 0, math.nan]], 1.0, 0.1),
     r"y0 must be finite: sample 0 holds NaN or inf"),
    (lambda: tumble.integrate(PENDULUM, [[1.0, 0.0]], 1.0, 0.1, parameters={"k": math.inf}),
     r"parameters: 'k' must be finite"),
    (lambda: tumble.theory.eigenvalues_at(PENDULUM, [1.0]), r"state must have shape \(\.\.\., 2\) \(x, v of system"),
])
def test_a_users_mistake_is_one_clear_line(call, message):
    with pytest.raises(ValueError, match=message):
        call()


_PTX = textwrap.dedent("""
    import math, types
    import numba.cuda.dispatcher as dispatcher
    from numba import cuda, types as nt
    import tumble
    from tumble.engine.system_runs import _kernels
    from tumble.kernels import device_sample_loop

    # Device functions are compiled for the current GPU's compute capability; without a GPU, name one (H100).
    dispatcher.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))

    def pendulum(t, y, p, dydt):
        dydt[0] = y[1]
        dydt[1] = -p[0] * math.sin(y[0]) - p[1] * y[1]

    system = tumble.System(pendulum, state=("x", "v"), parameters={"k": 2.0, "c": 0.1}, name="pendulum")
    f8, i8 = nt.float64, nt.int64
    signature = (f8[:, ::1], f8[::1], f8, f8, i8, i8, f8[:, :, ::1], nt.int8[::1], i8[::1])
    for method in ("rk4", "rk8"):
        kernels = _kernels(system, method)
        kernel = device_sample_loop().make_kernel(kernels.run_sample, 2, kernels.stages, 2)
        ptx, _ = cuda.compile_ptx(kernel.py_func, signature, cc=(9, 0))
        assert "div.approx" not in ptx and "fma.rn.f64" in ptx, method
        print(method, ptx.count("\\n"))
""")


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("nvidia") is None, reason="no NVVM wheel (pip install nvidia-nvvm "
                    "nvidia-cuda-nvrtc-cu12, or the gpu extra)")
def test_a_systems_device_kernel_compiles_to_ptx_for_a_gpu():
    """The per-sample loop, the tableau's step and the user's rate compile for sm_90 (the simulator runs the loop as
    Python: this is what a GPU would compile)."""
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0")
    result = subprocess.run([sys.executable, "-c", _PTX], capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    assert len(result.stdout.splitlines()) == 2


def test_run_ensemble_runs_a_system_and_refuses_a_scenes_observers():
    result = tumble.run_ensemble(PENDULUM, np.array([[1.0, 0.0]]), 5.0, 0.01, method="rk8", save_every=100,
                                 parameters={"c": 0.0})
    np.testing.assert_allclose(result.final, _dop853(pendulum, np.array([[1.0, 0.0]]), 5.0, np.array([2.0, 0.0])),
                               rtol=0, atol=1e-11)
    assert result.trajectory.shape == (1, 6, 2) and result.info["path"] == "system"
    with pytest.raises(ValueError, match=r"observes its final state and trajectory; max_flips, drift observe"):
        tumble.run_ensemble(PENDULUM, np.array([[1.0, 0.0]]), 5.0, 0.01, max_flips=2, drift=True)


def test_a_system_is_compiled_once_per_process_not_per_call(monkeypatch):
    from tumble.kernels.loops import sample_loop

    tumble.propagate(PENDULUM, np.array([[1.0, 0.0]]), 0.1, 0.01, method="rk8")
    calls = []
    monkeypatch.setattr(sample_loop, "compile_function", lambda *args, **kwargs: calls.append(args))
    monkeypatch.setattr(sample_loop, "make_sample_loop", lambda *args: calls.append(args))
    tumble.propagate(PENDULUM, np.array([[1.0, 0.0]]), 0.1, 0.01, method="rk8")
    tumble.integrate(PENDULUM, np.array([[0.5, 0.0]]), 0.2, 0.01, method="rk8", save_every=5)
    assert calls == []


#: The decay rate a rate reads from this module (a user's global, not a parameter): changed by the test below.
DECAY = 1.0


def decay(t, y, p, dydt):
    dydt[0] = -DECAY * y[0]


@pytest.mark.parametrize("method", ["rk4", "dop853"])
def test_a_global_the_rate_reads_changed_since_it_was_compiled_is_compiled_again_and_said(monkeypatch, method):
    # numba compiles a module's names in as constants: a System kept its kernels for the old value and ran them
    system = tumble.System(decay, state=("x",), name="decay")
    options = {"dt": 1e-3} if method == "rk4" else {"rtol": 1e-12, "atol": 1e-14}
    run = lambda: tumble.propagate(system, np.array([[1.0]]), 1.0, method=method, **options)[0, 0]
    assert run() == pytest.approx(math.exp(-1.0), rel=1e-10)
    monkeypatch.setattr(sys.modules[__name__], "DECAY", 2.0)
    with pytest.warns(RuntimeWarning, match=r"system 'decay': DECAY, read by its functions, changed since"):
        assert run() == pytest.approx(math.exp(-2.0), rel=1e-10)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # said once: the kernels are now those of the new value
        assert run() == pytest.approx(math.exp(-2.0), rel=1e-10)


# --- the mission's job on any system: tumble.measure(system, state=y_eq) ----------------------------------------------

@pytest.mark.parametrize("equilibrium, kind", [([math.pi, 0.0], "exponential"), ([0.0, 0.0], "periodic")])
def test_a_pendulum_measured_about_its_equilibria_gives_linear_theory(equilibrium, kind):
    """Upright, perturbations grow at sqrt(k + c²/4) - c/2; hanging, they oscillate at sqrt(k - c²/4)."""
    k, c = 1.0, 0.1
    ds = tumble.measure(PENDULUM, state=equilibrium, samples=128, parameters={"k": k, "c": c})
    exact = math.sqrt(k + c * c / 4) - c / 2 if kind == "exponential" else math.sqrt(k - c * c / 4)
    assert ds["kind"].item() == kind
    assert ds["rate_theory"].item() == pytest.approx(exact, rel=1e-9)
    assert ds["rel_error"].item() < 1e-5 and ds["samples_used"].item() == 128
    assert ds["rate_ci_low"].item() <= ds["rate"].item() <= ds["rate_ci_high"].item()
    assert ds["system"].item() == "pendulum" and list(ds.attrs["equilibrium"]) == equilibrium
    assert ds.attrs["parameter_c"] == c and ds["sample_rate"].shape == (128,)


def test_a_system_scene_has_a_body_scenes_variables():
    body = tumble.measure(tumble.Body(*MOMENTS), 2, samples=64, flips=0)
    mine = tumble.measure(FREE_BODY, state=[0.0, 1.0, 0.0], samples=64)
    assert set(body.data_vars) == set(mine.data_vars)
    assert set(body.coords) - set(mine.coords) == {"I1", "I2", "I3", "axis", "spin"}


def test_a_hand_written_free_body_at_its_intermediate_axis_grows_at_the_linear_rate():
    ds = tumble.measure(FREE_BODY, state=[0.0, 2.0, 0.0], samples=256)
    kind, rate = tumble.theory.linear(tumble.Body(*MOMENTS), axis=2, spin=2.0)
    assert ds["kind"].item() == kind == "exponential"
    assert ds["rate_theory"].item() == pytest.approx(rate, rel=1e-9)
    assert ds["rel_error"].item() < 1e-4  # the O(amplitude²) nonlinear correction


@pytest.mark.parametrize("w3", [3.0, 0.5])
def test_a_hand_written_heavy_top_about_its_sleeping_spin_follows_the_built_in_theory(w3):
    """Above the threshold (w3² > 4 I1 mgl / I3²) the sleeping top precesses; below, it falls."""
    model = tumble.models.HeavyTop((2.0, 2.5, 3.0), 0.5)
    kind, value = tumble.theory.linear(model, 3, w3)
    ds = tumble.measure(hand_written_systems.HEAVY_TOP, state=[0.0, 0.0, w3, 0.0, 0.0, 1.0], samples=128)
    assert (ds["kind"].item(), kind) == (("periodic",) * 2 if w3 == 3.0 else ("exponential",) * 2)
    assert ds["rate_theory"].item() == pytest.approx(value, rel=1e-7)
    assert ds["rel_error"].item() < 1e-3


def test_a_built_in_model_is_measured_about_an_axis_or_a_state_like_a_system():
    """tumble.measure takes a built-in model both ways: about axis at spin (a study's scene) and about state= (the
    System scene, with the model's exact Jacobian and its own parameters replaced by parameters=)."""
    top = tumble.models.HeavyTop((2.0, 2.5, 3.0), 0.5)
    for w3 in (3.0, 0.5):
        kind, value = tumble.theory.linear(top, 3, w3)
        by_axis = tumble.measure(top, 3, w3, samples=64)
        by_state = tumble.measure(top, state=top.equilibrium(3, w3), samples=64)
        for ds in (by_axis, by_state):
            assert ds["kind"].item() == kind and ds["rate_theory"].item() == pytest.approx(value, rel=1e-9)
            assert ds["rel_error"].item() < 1e-3
        assert by_state["system"].item() == "heavy_top" and by_axis["model"].item() == "heavy_top"
    lighter = tumble.measure(top, state=top.equilibrium(3, 0.5), samples=64, parameters={"mgl": 0.05})
    assert lighter["rate_theory"].item() == pytest.approx(
        tumble.theory.linear(tumble.models.HeavyTop((2.0, 2.5, 3.0), 0.05), 3, 0.5)[1], rel=1e-9)
    with pytest.raises(ValueError, match=r"torque: not for a built-in model \(heavy_top\)"):
        tumble.measure(top, 3, torque=(0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match=r"axis is required for a heavy_top .* or state="):
        tumble.measure(top)
    with pytest.raises(ValueError, match=r"parameters: 'k' is not a parameter of the heavy_top model"):
        tumble.measure(top, state=top.equilibrium(3, 3.0), parameters={"k": 1.0})


def _drift(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = 0.0


@pytest.mark.parametrize("call, message", [
    (lambda: tumble.measure(PENDULUM, state=[1.0, 0.0]), r"state is not an equilibrium of system 'pendulum'"),
    (lambda: tumble.measure(tumble.System(_drift, state=("x", "v"), name="drift"), state=[0.0, 0.0]),
     r"the equilibrium \[0.0, 0.0\] of system 'drift' is neutral in linear theory"),
    (lambda: tumble.measure(PENDULUM, 2, state=[0.0, 0.0]), r"axis is a body's spin axis"),
    (lambda: tumble.measure(PENDULUM), r"state is required for system 'pendulum'"),
    (lambda: tumble.measure(tumble.Body(*MOMENTS), state=[0.0, 1.0, 0.0]), r"state= measures a tumble.System"),
    (lambda: tumble.measure(tumble.Body(*MOMENTS), 2, parameters={"k": 1.0}), r"parameters are a System's"),
    (lambda: tumble.measure(PENDULUM, state=[math.nan, 0.0]), r"state must be finite: sample 0 holds NaN"),
    (lambda: tumble.measure(PENDULUM, state=[[0.0, 0.0]] * 2), r"state must be one equilibrium of shape \(2,\)"),
    (lambda: tumble.measure(PENDULUM, state=[0.0, 0.0], amplitude=-1.0), r"amplitude must be a number > 0"),
    (lambda: tumble.measure(PENDULUM, state=[0.0, 0.0], method="splitting2"), r"method must be auto or one of"),
    (lambda: tumble.measure(PENDULUM, state=[0.0, 0.0], parameters={"q": 1.0}), r"'q' is not a parameter"),
])
def test_a_system_scenes_bad_input_is_one_line(call, message):
    with pytest.raises(ValueError, match=message) as caught:
        call()
    assert "\n" not in str(caught.value)
