"""Error-controlled runs (method="dop853"): coefficients, accuracy against closed forms and SciPy, step counts, stops,
bad input.

One per-sample kernel per system is compiled per process (a closure over the rate), so the systems here are made once
per module and shared.
"""

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.integrate._ivp import dop853_coefficients as reference

import tumble
from tumble import exact, registry
from tumble.engine.adaptive_runs import MIN_RTOL
from tumble.kernels.tableaux import DOP853

from process_checks import run_twice

# One worker runs the error-controlled tests (--dist loadgroup): the built-in models' kernel (the free body's too) is
# compiled once per process, a closure over the models' rate that numba's disk cache cannot keep.
pytestmark = pytest.mark.xdist_group("dop853")

BODY = (1.0, 2.0, 3.0)
SPINS = np.array([[0.1, 1.0, 0.05], [0.3, 0.2, 1.0], [1.0, 0.05, 0.1]])


def _euler(p, w):
    i1, i2, i3 = p
    return [(i2 - i3) / i1 * w[1] * w[2], (i3 - i1) / i2 * w[2] * w[0], (i1 - i2) / i3 * w[0] * w[1]]


def _pendulum_rate(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * math.sin(y[0]) - p[1] * y[1]


def _blow_up_rate(t, y, p, dydt):
    dydt[0] = y[0] * y[0]  # y = 1 / (1 - t): a singularity at t = 1


def _not_finite_after_one_rate(t, y, p, dydt):
    dydt[0] = -y[0] if t < 1.0 else math.nan  # a rate that returns NaN past t = 1


def _not_finite_after_one_rate_looped(t, y, p, dydt):
    for j in range(y.shape[0]):  # an index that is not a constant: no scalar form, the per-sample loop
        dydt[j] = -y[j] if t < 1.0 else math.nan


@pytest.fixture(scope="module")
def pendulum():
    return tumble.System(_pendulum_rate, state=("x", "v"), parameters={"k": 4.0, "c": 0.1}, name="pendulum")


@pytest.fixture(scope="module")
def blow_up():
    return tumble.System(_blow_up_rate, state=("y",), name="blow_up")


def test_the_coefficients_are_hairers_as_scipy_distributes_them():
    n = DOP853.tableau.A.shape[0]
    np.testing.assert_array_equal(DOP853.tableau.A, reference.A[:n, :n])
    np.testing.assert_array_equal(DOP853.tableau.b, reference.B)
    np.testing.assert_array_equal(DOP853.e5, reference.E5)
    np.testing.assert_array_equal(DOP853.e3, reference.E3)
    np.testing.assert_array_equal(DOP853.extra_a, reference.A[n + 1:])
    np.testing.assert_array_equal(DOP853.extra_c, reference.C[n + 1:])
    np.testing.assert_array_equal(DOP853.dense, reference.D)
    # each extra stage is consistent (its row sums to its time), and the error weights of a constant rate vanish
    np.testing.assert_allclose(DOP853.extra_a.sum(axis=1), DOP853.extra_c, atol=1e-14)
    assert abs(DOP853.e5.sum()) < 1e-14 and abs(DOP853.e3.sum()) < 1e-14
    # the third-order estimate as dop853.f makes it: the step's increment less bhh1 k1, bhh2 k9, bhh3 k12
    from_b = np.concatenate([DOP853.tableau.b, [0.0]])
    for stage, weight in DOP853.e3_from_b:
        from_b[stage] -= weight
    np.testing.assert_allclose(from_b, DOP853.e3, rtol=0, atol=1e-15)


def test_a_free_body_meets_its_tolerance_against_the_closed_form_at_dense_output_times():
    times = np.linspace(0.0, 40.0, 57)  # most of them inside steps: the dense output's
    errors = {}
    for rtol in (1e-6, 1e-9, 1e-12):
        ds = tumble.integrate(BODY, SPINS, 40.0, method="dop853", rtol=rtol, atol=rtol * 1e-2, times=times)
        errors[rtol] = np.abs(ds.omega.values - exact.omega(BODY, SPINS, times)).max()
        assert (ds.status.values == registry.STATUS_OK).all()
        assert errors[rtol] < 300 * rtol, (rtol, errors[rtol])  # a global error some steps' worth of the local one
    assert errors[1e-6] > 30 * errors[1e-9] > 30 * 30 * errors[1e-12]  # it follows the tolerance


def test_its_steps_are_near_scipys_dop853_steps_and_its_states_agree():
    ds = tumble.integrate(BODY, SPINS, 50.0, method="dop853", rtol=1e-10, atol=1e-12)
    for i, w0 in enumerate(SPINS):
        sol = solve_ivp(lambda t, w: _euler(BODY, w), (0.0, 50.0), w0, method="DOP853", rtol=1e-10, atol=1e-12)
        accepted, tries = len(sol.t) - 1, (sol.nfev - 2) // 12
        # the same pair and error norm; Hairer's PI control (beta = 1/16, SciPy's has none) keeps up to a tenth more
        # steps, smaller ones, and rejects fewer: it tries no more than SciPy
        assert accepted - 2 <= int(ds.steps[i]) <= 1.12 * accepted + 2
        assert int(ds.steps[i] + ds.rejected_steps[i]) <= tries + 2
        np.testing.assert_allclose(ds.omega.values[i, -1], sol.y[:, -1], rtol=0, atol=2e-9)


@pytest.mark.slow  # a System's kernel's compile (12 s): the tolerance how-to's example runs one by default
def test_a_users_system_agrees_with_scipy_at_its_tightest_tolerance(pendulum):
    y0 = np.array([[2.5, 0.0], [0.1, 1.0], [-3.0, 2.0]])
    times = np.linspace(0.0, 20.0, 9)
    ds = tumble.integrate(pendulum, y0, 20.0, method="dop853", rtol=1e-13, atol=1e-15, times=times)
    assert ds.state.dims == ("sample", "time", "component") and list(ds.component.values) == ["x", "v"]
    for i in range(len(y0)):
        sol = solve_ivp(lambda t, y: [y[1], -4.0 * math.sin(y[0]) - 0.1 * y[1]], (0.0, 20.0), y0[i],
                        method="DOP853", rtol=2.3e-14, atol=1e-16, t_eval=times)
        np.testing.assert_allclose(ds.state.values[i], sol.y.T, rtol=0, atol=1e-10)


@pytest.mark.slow  # the heavy top's own kernel's compile (10 s)
def test_a_built_in_model_agrees_with_its_fixed_step_rk8():
    top = tumble.models.HeavyTop((1.0, 1.0, 0.5), 1.0)
    g = np.array([0.05, 0.0, 1.0]) / math.hypot(0.05, 1.0)
    y0 = np.array([[0.1, 0.0, 3.0, *g], [0.5, -0.2, 1.0, *g]])
    adaptive = tumble.propagate(top, y0, 10.0, method="dop853", rtol=1e-12, atol=1e-14)
    fixed = tumble.propagate(top, y0, 10.0, 2e-3, method="rk8")
    np.testing.assert_allclose(adaptive, fixed, rtol=0, atol=1e-10)


def test_propagate_gives_integrates_final_states_and_a_single_state_stays_single():
    ds = tumble.integrate(BODY, SPINS, 5.0, method="dop853", rtol=1e-9)
    np.testing.assert_array_equal(tumble.propagate(BODY, SPINS, 5.0, method="dop853", rtol=1e-9),
                                  ds.omega.values[:, -1])
    assert tumble.propagate(BODY, SPINS[0], 5.0, method="dop853", rtol=1e-9).shape == (3,)


def test_run_ensemble_gives_integrates_states_and_refuses_a_rigid_bodys_observers():
    ds = tumble.integrate(BODY, SPINS, 5.0, method="dop853", rtol=1e-9, times=[2.5, 5.0])
    run = tumble.run_ensemble(BODY, SPINS, 5.0, None, method="dop853", rtol=1e-9, times=[2.5, 5.0])
    np.testing.assert_array_equal(run.trajectory, ds.omega.values)
    np.testing.assert_array_equal(run.final, ds.omega.values[:, -1])
    np.testing.assert_array_equal(run.steps_taken, ds.steps.values)
    assert run.info["path"] == "error-controlled" and list(run.times) == [2.5, 5.0]
    with pytest.raises(ValueError, match="max_flips observe a rigid body's scene"):
        tumble.run_ensemble(BODY, SPINS, 5.0, None, method="dop853", max_flips=2)
    with pytest.raises(ValueError, match="rtol: for an error-controlled run"):
        tumble.run_ensemble(BODY, SPINS, 5.0, 0.1, method="rk4", rtol=1e-6)


def test_per_component_tolerances_and_a_given_first_step():
    loose = tumble.integrate(BODY, SPINS[:1], 5.0, method="dop853", rtol=[1e-4, 1e-12, 1e-12],
                             atol=[1e-6, 1e-14, 1e-14])
    assert isinstance(loose.attrs["rtol"], np.ndarray) and loose.attrs["rtol"].tolist() == [1e-4, 1e-12, 1e-12]
    tight = tumble.integrate(BODY, SPINS[:1], 5.0, method="dop853", rtol=1e-12, atol=1e-14, dt=1e-3)
    assert int(tight.steps[0]) > int(loose.steps[0]) > 0
    assert tight.attrs["rtol"] == 1e-12


@pytest.mark.slow  # its own System's kernel's compile (4 s)
def test_a_singularity_stops_its_sample_with_step_underflow_and_a_warning(blow_up):
    with pytest.warns(RuntimeWarning, match=r"1 of 2 samples of 'blow_up' stopped before t_end \(1 step underflow"):
        ds = tumble.integrate(blow_up, [[1.0], [-1.0]], 2.0, method="dop853", times=[0.5, 2.0])
    assert ds.status.values.tolist() == [registry.STATUS_UNDERFLOW, registry.STATUS_OK]
    assert "step_underflow" in ds.status.attrs["flag_meanings"].split()
    assert ds.state.values[0, 0, 0] == pytest.approx(2.0, rel=1e-9)  # before the singularity: 1 / (1 - t)
    assert np.isfinite(ds.state.values).all() and ds.state.values[0, 1, 0] > 1e6  # the state it stopped with
    assert ds.state.values[1, 1, 0] == pytest.approx(-1.0 / 3.0, rel=1e-9)


@pytest.mark.slow  # its own System's kernel's compile (4 s)
@pytest.mark.parametrize("rate, path", [(_not_finite_after_one_rate, "error-controlled, vectorised blocks"),
                                        (_not_finite_after_one_rate_looped, "error-controlled, per-sample loop")])
def test_a_rate_that_returns_nan_stops_its_samples_non_finite_with_the_last_finite_state(rate, path):
    system = tumble.System(rate, state=("y",), name="not_finite")
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*scalar form")  # the looped rate's: it runs one sample at a time
        with pytest.warns(RuntimeWarning, match=r"2 of 2 samples of 'not_finite' stopped before t_end \(2 non-finite"):
            ds = tumble.integrate(system, [[1.0], [0.5]], 2.0, method="dop853", times=[0.5, 2.0])
    assert ds.attrs["path"] == path
    # a NaN error is rejected (never an error of 0), the step falls until it cannot advance t, and its stages still
    # hold the NaN: the rate's, not the step's, so the status says non-finite rather than step underflow
    assert ds.status.values.tolist() == [registry.STATUS_NONFINITE] * 2
    np.testing.assert_allclose(ds.state.values[:, 0, 0], np.array([1.0, 0.5]) * math.exp(-0.5), rtol=1e-8)
    np.testing.assert_allclose(ds.state.values[:, -1, 0], np.array([1.0, 0.5]) * math.exp(-1.0), rtol=1e-8)
    assert np.isfinite(ds.state.values).all()


def test_a_steady_spin_is_kept_exactly_to_the_end():
    # its rate is 0, so is every step's error: the step grows by the largest factor, never to a NaN (a steady spin
    # stopped with "step underflow" until 2026-12-07: the block loop blended the rejected step's h / 0 into its step)
    steady = np.array([[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -3.0], [0.0, 0.0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ds = tumble.integrate(BODY, steady, 20.0, method="dop853", times=[1.0, 20.0])
    assert ds.status.values.tolist() == [registry.STATUS_OK] * 4
    np.testing.assert_array_equal(ds.omega.values, np.repeat(steady[:, None, :], 2, axis=1))
    assert (ds.rejected_steps.values == 0).all() and (ds.steps.values < 20).all()
    assert ds.attrs["path"] == "error-controlled, vectorised blocks"


def test_too_few_steps_stop_with_step_limit():
    with pytest.warns(RuntimeWarning, match="step limit"):
        ds = tumble.integrate(BODY, SPINS[:1], 50.0, method="dop853", max_steps=5)
    assert ds.status.values.tolist() == [registry.STATUS_LIMIT]
    assert int(ds.steps[0] + ds.rejected_steps[0]) == 5
    # propagate returns no status: its stopped samples' finite states come with the same warning, never silently
    with pytest.warns(RuntimeWarning, match=r"1 of 1 samples of 'free' stopped before t_end \(1 step limit"):
        final = tumble.propagate(BODY, SPINS[:1], 50.0, method="dop853", max_steps=5)
    np.testing.assert_array_equal(final[0], ds.omega.values[0, -1])


@pytest.mark.parametrize("keywords, message", [
    (dict(rtol=0.0), "rtol must be finite and > 0"),
    (dict(atol=-1.0), "atol must be finite and > 0"),
    (dict(rtol=[1e-8]), r"rtol must be a number or one number per state component \(2: x, v\)"),
    (dict(rtol="1e-10"), r"rtol must be a number or one number per state component \(x, v\), got '1e-10'"),
    (dict(atol=True), r"atol must be a number or one number per state component \(x, v\), got True"),
    (dict(rtol=1e-16), f"rtol must be >= {MIN_RTOL:g}"),
    (dict(times=[1.0, 0.5]), "times must be increasing"),
    (dict(times=[0.0, 9.0]), r"times must lie within \[0, t_end\]"),
    (dict(save_every=10), "save_every counts fixed steps"),
    (dict(dt=-1.0), "dt .the first step of an error-controlled run. must be finite and > 0"),
    (dict(max_steps=0), "max_steps must be an integer >= 1"),
])
def test_bad_input_is_one_line_naming_the_argument(pendulum, keywords, message):
    with pytest.raises(ValueError, match=message):
        tumble.integrate(pendulum, [[1.0, 0.0]], 5.0, method="dop853", **keywords)


def test_a_fixed_step_method_refuses_a_tolerance_and_needs_its_step(pendulum):
    with pytest.raises(ValueError, match="rtol, times: for an error-controlled run"):
        tumble.integrate(pendulum, [[1.0, 0.0]], 5.0, 0.01, method="rk4", rtol=1e-8, times=[1.0])
    with pytest.raises(ValueError, match="dt .s. is required for the fixed-step method 'rk4'"):
        tumble.propagate(BODY, SPINS, 5.0)


def test_a_torque_follows_the_wobbly_space_stations_closed_form_to_the_tolerance():
    # I1 = I2 and a constant torque about the symmetry axis: tumble.theory's closed form (DESIGN.md)
    top, gamma, times = (2.0, 2.0, 1.0), 0.5, np.linspace(0.0, 8.0, 5)
    expected = tumble.theory.constant_torque_symmetric_top(top, SPINS, gamma, times)
    for rtol, bound in ((1e-7, 1e-5), (1e-11, 1e-9)):
        ds = tumble.integrate(top, SPINS, 8.0, method="dop853", rtol=rtol, atol=rtol * 1e-2, times=times,
                              torque=(0.0, 0.0, gamma))
        assert ds.attrs["torque"] == "constant [0.0, 0.0, 0.5] N m" and ds.attrs["attitude"] == 0
        error = np.abs(ds.omega.values - expected).max()
        assert 0 < error < bound
    sine = {"profile": "sine", "vector": (0.1, -0.2, 0.3), "period": 2.0}  # the same System, another profile
    run = tumble.run_ensemble(top, SPINS, 5.0, None, method="dop853", torque=sine, rtol=1e-12, atol=1e-14)
    fixed = tumble.propagate(top, SPINS, 5.0, 1e-3, method="rk8", torque=sine)
    np.testing.assert_allclose(run.final, fixed, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(tumble.propagate(top, SPINS, 5.0, method="dop853", torque=sine, rtol=1e-12,
                                                   atol=1e-14), run.final)


def _no_torque(t, w1, w2, w3):
    return 0.0 * w1, 0.0 * w2, 0.0 * t


@pytest.mark.slow  # the attitude's own System's kernels' compile (30 s on an empty cache): the torque's case runs by default
def test_the_attitude_follows_the_closed_form_and_its_quaternion_is_a_unit_one():
    # a torque function (zero) with the attitude: the closed form's attitude is the reference
    times = np.linspace(0.0, 6.0, 4)
    ds = tumble.integrate(BODY, SPINS, 6.0, method="dop853", rtol=1e-11, atol=1e-13, times=times, attitude=True,
                          torque=_no_torque)
    exact_run = tumble.integrate(BODY, SPINS, 6.0, 2.0, method="exact", attitude=True, save_every=1)
    assert ds.attrs["attitude"] == 1 and ds.quaternion.dims == ("sample", "time", "component")
    np.testing.assert_allclose(ds.omega.values, exact_run.omega.values, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds.quaternion.values, exact_run.quaternion.values, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(ds.quaternion.values, axis=-1), 1.0, rtol=0, atol=4e-16)
    with pytest.raises(ValueError, match="dop853' observes the final state .*attitude observe"):
        tumble.run_ensemble(BODY, SPINS, 5.0, None, method="dop853", attitude=True)


_CACHED = """
import numpy as np
import tumble
from tumble.engine import system_runs, torqued_body
ds = tumble.integrate((1.0, 2.0, 3.0), [[0.1, 1.0, 0.05]], 3.0, method="dop853", attitude=True,
                      torque={"profile": "ramp", "vector": (0.0, 0.1, 0.0), "duration": 1.0})
drive = system_runs.compiled(torqued_body._PROFILE_SYSTEMS[True]).methods["dop853"]
print(repr(float(ds.quaternion[0, -1, 1])), sum(drive.run_share.stats.cache_hits.values()))
"""


@pytest.mark.slow  # two new processes, the first may compile the block loop (15 s)
def test_a_new_process_loads_a_systems_block_loop_from_the_disk_cache(tmp_path):
    """A System's error-controlled block loop (here the free body's with a torque profile and its attitude) is kept
    in numba's disk cache under its System's code, and gives the same bits loaded as compiled."""
    (first, _), (second, hits) = run_twice(tmp_path, _CACHED, "torqued.py")
    assert first == second
    assert int(hits) == 1


def test_a_non_finite_initial_state_is_refused_naming_it(pendulum):
    with pytest.raises(ValueError, match="w0 must be finite: sample 1"):
        tumble.propagate(BODY, [[0.1, 1.0, 0.0], [np.nan, 0.0, 0.0]], 5.0, method="dop853")


@pytest.mark.slow  # a System's kernel's compile (12 s)
def test_the_kernel_is_compiled_once_per_system_and_parameters_replace_its_own(pendulum):
    from tumble.engine.system_runs import compiled

    tumble.propagate(pendulum, [[1.0, 0.0]], 1.0, method="dop853")
    driver = compiled(pendulum).methods["dop853"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        decay = tumble.propagate(pendulum, [[0.0, 1.0]], 1.0, method="dop853", rtol=1e-12, atol=1e-14,
                                 parameters={"k": 0.0, "c": 1.0})  # v' = -v
    assert compiled(pendulum).methods["dop853"] is driver
    np.testing.assert_allclose(decay[0], [1.0 - math.exp(-1.0), math.exp(-1.0)], rtol=1e-11)


@pytest.mark.slow  # the per-sample loop's compile for the device, three times (20 s)
def test_the_device_runs_the_per_sample_loop_and_gives_the_cpus_states(pendulum):
    """On numba-cuda's simulator (tests/conftest.py): one thread per sample, the CPU's per-sample loop compiled."""
    pytest.importorskip("numba_cuda")
    from tumble.engine.device import resolve_device

    try:
        resolve_device("cuda")
    except ValueError as err:
        pytest.skip(str(err))
    y0 = np.array([[1.0, 0.0], [2.5, 0.3], [-0.5, 1.0]])
    times = np.linspace(0.0, 8.0, 5)
    cpu = tumble.integrate(pendulum, y0, 8.0, method="dop853", rtol=1e-12, atol=1e-14, times=times)
    gpu = tumble.integrate(pendulum, y0, 8.0, method="dop853", rtol=1e-12, atol=1e-14, times=times, device="cuda")
    assert gpu.attrs["device"] == "cuda" and (gpu.status.values == 0).all()
    np.testing.assert_allclose(gpu.state.values, cpu.state.values, rtol=0, atol=1e-10)
    assert np.abs(gpu.steps.values - cpu.steps.values).max() <= 2
    section = tumble.section(pendulum, y0, 20.0, surface=("x", 0.0), direction=0, device="cuda", rtol=1e-12)
    on_cpu = tumble.section(pendulum, y0, 20.0, surface=("x", 0.0), direction=0, rtol=1e-12)
    assert section["count"].values.tolist() == on_cpu["count"].values.tolist()
    np.testing.assert_allclose(section.time.values, on_cpu.time.values, rtol=0, atol=1e-9)
    # a rate that returns NaN: the device's stop is the CPU's (non-finite, the last finite state)
    undefined = tumble.System(_not_finite_after_one_rate, state=("y",), name="not_finite")
    with pytest.warns(RuntimeWarning, match=r"\(2 non-finite"):
        gpu = tumble.integrate(undefined, [[1.0], [0.5]], 2.0, method="dop853", device="cuda")
    assert gpu.status.values.tolist() == [registry.STATUS_NONFINITE] * 2
    np.testing.assert_allclose(gpu.state.values[:, -1, 0], np.array([1.0, 0.5]) * math.exp(-1.0), rtol=1e-8)
