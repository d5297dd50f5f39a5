"""Numerical stress cases (issue 6, part 2) — the fast ones; the full sweep is ``benchmarks/stress.py``.

Stability limits against linear theory, invariants over long runs, RK4's energy drift against its stability
polynomial, scale invariance over 16 decades of spin rate, extreme and near-degenerate bodies, the
separatrix, and a step far too large flagged per sample rather than returned as silent garbage.

Only kernel variants the rest of the suite compiles are used (plain ``tumble.integrate`` of every method;
``run_ensemble`` final-state-only for rk4 and symplectic_euler; rk4 with probes, flips and the drift
observer), so this file adds no compile time.
"""

import importlib.util
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import tumble
from tumble.engine.ensemble import run_ensemble
from tumble.engine.integration import METHOD_NAMES
from tumble.engine.sampling import perturbed_spins
from tumble.kernels import tableaux
from tumble.kernels.loops.drivers import STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK
from tumble.physics import exact, theory

STEPPERS = [m for m in METHOD_NAMES if m != "exact"]
BODY = np.array([1.0, 2.0, 3.0])


def invariants(moments, w):
    return 0.5 * np.sum(moments * w * w, axis=-1), np.sum((moments * w) ** 2, axis=-1)


def rk_amplification(tableau, y):
    """|R(iy)| of an explicit Runge–Kutta method, R(z) = 1 + Σ_k bᵀ A^(k-1) 1 z^k."""
    gamma, v = [1.0], np.ones(len(tableau.b))
    for _ in range(len(tableau.b)):
        gamma.append(float(tableau.b @ v))
        v = tableau.A @ v
    return np.abs(np.polyval(gamma[::-1], 1j * np.asarray(y, dtype=float)))


# --- step size: stability limits against linear theory ---------------------------------------------------

def test_rk4_stability_polynomial_reaches_2_sqrt_2_on_the_imaginary_axis():
    y = np.linspace(1e-3, 4.0, 4001)
    amp = rk_amplification(tableaux.RK4, y)
    edge = 2.0 * math.sqrt(2.0)
    assert np.all(amp[y < edge - 1e-9] <= 1.0 + 1e-15)
    assert np.all(amp[y > edge + 1e-9] > 1.0)
    np.testing.assert_allclose(rk_amplification(tableaux.RK4, [edge]), 1.0, rtol=1e-14)


@pytest.mark.parametrize("axis", [1, 3])
def test_rk4_step_limit_on_the_linearised_problem_brackets_2_sqrt_2(axis):
    """Spins tilted 1e-6 rad from a stable axis: just below hΩ = 2√2 RK4 damps the tilt, just above it grows
    until the sample is non-finite — and flagged as such."""
    omega = theory.linear(BODY, axis, 1.0)[1]
    w0 = perturbed_spins(BODY, axis, 1.0, 1e-6, 4, seed=1)
    others = [k for k in range(3) if k != axis - 1]
    below = tumble.integrate(BODY, w0, 2000 * 2.80 / omega, 2.80 / omega, method="rk4")
    assert np.all(below.status.values == STATUS_OK)
    tilt = np.linalg.norm(below.omega.values[:, -1][:, others], axis=1)
    assert np.all(tilt < 1e-6 * 1e-3)  # |R(2.8 i)|^2000 ~ 1e-63: the precession is damped away
    with pytest.warns(RuntimeWarning, match="non-finite"):
        above = tumble.integrate(BODY, w0, 2000 * 2.86 / omega, 2.86 / omega, method="rk4")
    assert np.all(above.status.values == STATUS_NONFINITE)  # |R(2.86 i)| = 1.08: grows 1e68-fold, then blows up


def test_implicit_midpoint_is_limited_by_its_fixed_point_iteration():
    """The midpoint rule is A-stable, but the kernel's fixed-point iteration (iteration matrix (h/2) J,
    spectral radius hΩ/2) converges ever slower towards hΩ = 2 and diverges above: a step it has not solved
    within its sweeps is flagged non-finite, below that every sample is ok."""
    omega = theory.linear(BODY, 3, 1.0)[1]
    w0 = perturbed_spins(BODY, 3, 1.0, 1e-6, 4, seed=2)
    below = tumble.integrate(BODY, w0, 500 * 1.0 / omega, 1.0 / omega, method="implicit_midpoint")
    assert np.all(below.status.values == STATUS_OK)
    for h_omega in (1.9, 2.2):
        with pytest.warns(RuntimeWarning, match="non-finite"):
            above = tumble.integrate(BODY, w0, 500 * h_omega / omega, h_omega / omega, method="implicit_midpoint")
        assert np.all(above.status.values == STATUS_NONFINITE)


# --- failures are flagged per sample --------------------------------------------------------------------

def test_a_step_far_too_large_is_flagged_per_sample_not_returned_silently():
    omega = theory.linear(BODY, 3, 1.0)[1]
    good = perturbed_spins(BODY, 3, 1.0, 1e-3, 3, seed=3)
    fast = 30.0 * good  # the same spins 30x faster: hΩ = 0.3 for the first three, 9 for the others
    w0 = np.concatenate([good, fast])
    run = run_ensemble(BODY, w0, 200 * 0.3 / omega, 0.3 / omega, method="rk4")
    assert run.status[:3].tolist() == [STATUS_OK] * 3
    assert np.all(run.status[3:] != STATUS_OK)
    assert np.all(run.steps_taken[3:] < 200)  # stopped where caught, the others ran on
    reference = exact.omega(BODY, good, np.array([200 * 0.3 / omega]))[:, 0]
    np.testing.assert_allclose(run.final[:3], reference, atol=1e-5)


def test_a_splitting_in_its_unstable_band_is_flagged_as_invariant_drift():
    """symplectic_euler keeps |L|² by construction, so its linear instability (hΩ > 0.82 about axis 3 of
    (1, 2, 3)) can only show in the energy: the samples are flagged ``invariant drift``, never non-finite."""
    omega = theory.linear(BODY, 3, 1.0)[1]
    w0 = perturbed_spins(BODY, 3, 1.0, 1e-3, 4, seed=4)
    run = run_ensemble(BODY, w0, 2000 * 1.5 / omega, 1.5 / omega, method="symplectic_euler")
    assert run.status.tolist() == [STATUS_DRIFT] * 4
    assert np.all(np.isfinite(run.final))
    stable = run_ensemble(BODY, w0, 2000 * 0.5 / omega, 0.5 / omega, method="symplectic_euler")
    assert stable.status.tolist() == [STATUS_OK] * 4


def test_an_implicit_midpoint_step_whose_iteration_did_not_converge_is_not_silent():
    """A step the fixed-point iteration cannot solve (h|w| = 2.2) is flagged, never kept half-solved."""
    w0 = perturbed_spins(BODY, 2, 1.0, 0.3, 4, seed=5)
    with pytest.warns(RuntimeWarning, match="became non-finite"):  # said, not only flagged
        ds = tumble.integrate(BODY, w0, 1000 * 2.2, 2.2, method="implicit_midpoint")
    e0, l0 = invariants(BODY, w0)
    e1, l1 = invariants(BODY, ds.omega.values[:, -1])
    kept = (np.abs(e1 / e0 - 1) < 1e-12) & (np.abs(l1 / l0 - 1) < 1e-12)
    assert np.all(kept | (ds.status.values != STATUS_OK))


# --- long time: invariants -----------------------------------------------------------------------------

def _long_run(method, steps, dt, save=10):
    moments = np.array([2.0, 3.0, 4.0])
    w0 = np.concatenate([perturbed_spins(moments, 2, 1.0, 0.1, 2, seed=6),
                         perturbed_spins(moments, 1, 1.0, 0.2, 1, seed=7),
                         perturbed_spins(moments, 3, 1.0, 0.2, 1, seed=8)])
    ds = tumble.integrate(moments, w0, steps * dt, dt, method=method, save_every=steps // save)
    e, l2 = invariants(moments, ds.omega.values)
    return ds, e / e[:, :1] - 1, l2 / l2[:, :1] - 1


@pytest.mark.parametrize("method, energy_bound", [("symplectic_euler", 2e-2), ("splitting2", 1e-4),
                                                  ("splitting4", 1e-9)])
def test_splittings_keep_L2_to_round_off_and_the_energy_bounded_over_1e5_steps(method, energy_bound):
    ds, de, dl = _long_run(method, 100_000, 0.01)
    assert np.all(ds.status.values == STATUS_OK)
    assert np.abs(dl).max() < 8e-15  # a few ulps: the kernel rescales onto the initial |L|²
    assert np.abs(de).max() < energy_bound
    # bounded, not drifting: the second half of the run strays no further than ~ the first
    assert np.abs(de[:, 6:]).max() < 3.0 * np.abs(de[:, 1:6]).max()


def test_splitting4_energy_round_off_does_not_drift_over_2e6_steps():
    """The |L|² projection is applied additively (``w + w d``): a multiplicative factor within an ulp of 1 drops
    each component by one of its own ulps and made the energy drift linearly (6.5e-12 here, ~3e-18 a step);
    now the error random-walks (measured 4e-13 after 2e6 steps, three seeds)."""
    w0 = perturbed_spins(BODY, 1, 1.0, 0.2, 1, seed=12)
    ds = tumble.integrate(BODY, w0, 2_000_000 * 0.01, 0.01, method="splitting4", save_every=1_000_000)
    e, _ = invariants(BODY, ds.omega.values)
    assert np.abs(e[0, -1] / e[0, 0] - 1) < 2e-12  # a random walk of ~1e-16 per step: ~1e-13


def test_implicit_midpoint_keeps_both_quadratic_invariants_to_round_off_over_1e5_steps():
    ds, de, dl = _long_run("implicit_midpoint", 100_000, 0.01)
    assert np.abs(de).max() < 1e-12 and np.abs(dl).max() < 1e-12


def test_rk4_energy_drift_rate_is_the_damping_of_its_stability_polynomial():
    """About a stable axis the conic invariant D = 2E·I_a − |L|² (the squared distance from the steady spin)
    decays by 1 − |R(ihΩ)|² = (hΩ)⁶/72 − (hΩ)⁸/576 per step: RK4's energy drift, quantified."""
    omega = theory.linear(BODY, 3, 1.0)[1]
    h, steps = 0.1 / omega, 100_000
    w0 = perturbed_spins(BODY, 3, 1.0, 1e-3, 2, seed=9)
    ds = tumble.integrate(BODY, w0, steps * h, h, method="rk4", save_every=steps // 10)
    e, l2 = invariants(BODY, ds.omega.values)
    d = 2.0 * e * BODY[2] - l2
    change = d / d[:, :1] - 1
    predicted = 1.0 - rk_amplification(tableaux.RK4, [0.1])[0] ** 2
    np.testing.assert_allclose(predicted, 0.1**6 / 72 - 0.1**8 / 576, rtol=1e-6)
    np.testing.assert_allclose(change[:, -1], (1.0 - predicted) ** steps - 1, rtol=0.02)
    # linear in time (the decay is 0.14 % over the run), and the energy itself goes down
    np.testing.assert_allclose(change[:, 5], 0.5 * change[:, -1], rtol=0.01)
    assert np.all(e[:, -1] < e[:, 0])


# --- spin rates: scale invariance ----------------------------------------------------------------------

SCALE_SPINS = np.concatenate([perturbed_spins(BODY, a, 1.0, 0.1, 2, seed=10 + a) for a in (1, 2, 3)])


def test_the_closed_form_is_scale_invariant_from_1e_minus_8_to_1e8_rad_per_s():
    """w(t; W) = W w(W t; 1): to round-off for powers of ten, bit for bit for powers of two."""
    t = np.linspace(0.0, 50.0, 11)
    reference = exact.omega(BODY, SCALE_SPINS, t)
    for W in 10.0 ** np.arange(-8, 9):
        scaled = exact.omega(BODY, W * SCALE_SPINS, t / W) / W
        assert np.abs(scaled - reference).max() <= 2e-14 * np.abs(reference).max(), W
    for W in (2.0**-26, 2.0**26):
        np.testing.assert_array_equal(exact.omega(BODY, W * SCALE_SPINS, t / W) / W, reference)


@pytest.mark.parametrize("method", STEPPERS)
def test_every_stepper_is_scale_invariant_with_its_step_scaled_by_1_over_W(method):
    """From 1e-200 to 1e200 rad/s: beyond 2^±256 the kernels step ``s w`` with ``dt / s`` (s a power of two), where
    Euler's products would underflow (the spin stood still, status ok) or ``|L|^2`` overflow."""
    base = tumble.integrate(BODY, SCALE_SPINS, 5.0, 0.01, method=method).omega.values[:, -1]
    for W in (1e-200, 1e-160, 1e-8, 1e8, 1e160, 1e200):
        ds = tumble.integrate(BODY, W * SCALE_SPINS, 5.0 / W, 0.01 / W, method=method)
        assert np.abs(ds.omega.values[:, -1] / W - base).max() <= 1e-12 * np.abs(base).max(), W
        assert np.all(ds.status.values == 0), W
    for W in (2.0**-700, 2.0**-26, 2.0**26, 2.0**700):
        scaled = tumble.integrate(BODY, W * SCALE_SPINS, 5.0 / W, 0.01 / W, method=method).omega.values[:, -1] / W
        np.testing.assert_array_equal(scaled, base)
    # the observers come back in rad/s and s: a flip's time, a probe's transverse norm
    runs = [run_ensemble(BODY, W * SCALE_SPINS, 5.0 / W, 0.01 / W, method=method, axis=2, max_flips=2,
                         probe_times=[0.0, 2.5 / W], drift=True, progress=False) for W in (1.0, 2.0**-700)]
    np.testing.assert_array_equal(runs[1].flips * 2.0**-700, runs[0].flips)
    np.testing.assert_array_equal(runs[1].probes / 2.0**-700, runs[0].probes)
    # and the phase fit over 1e211 s, whose squares overflow unscaled (a frequency of 0 with status ok)
    fits = [run_ensemble(BODY, W * SCALE_SPINS, 5.0 / W, 0.01 / W, method=method, axis=3, save_every=10,
                         phase_window=((0, 1), (1.0, 1.0), 1e-12 * W, np.pi / 2), progress=False).phase
            for W in (1.0, 2.0**-700)]
    assert (fits[0][2] == 0).any()
    np.testing.assert_array_equal(fits[1][2], fits[0][2])
    np.testing.assert_array_equal(fits[1][0] / 2.0**-700, fits[0][0])
    np.testing.assert_allclose(fits[1][1] / 2.0**-700, fits[0][1], rtol=4e-16)  # there by hypot, within an ulp
    # and with the attitude: the same quaternions
    turned = [tumble.integrate(BODY, W * SCALE_SPINS[:2], 5.0 / W, 0.01 / W, method=method, attitude=True)
              for W in (1.0, 2.0**-700)]
    np.testing.assert_array_equal(turned[1].omega.values / 2.0**-700, turned[0].omega.values)
    np.testing.assert_array_equal(turned[1].quaternion.values, turned[0].quaternion.values)


# --- extreme bodies ------------------------------------------------------------------------------------

P, E, N = "periodic", "exponential", "neutral"
EXTREME_BODIES = [
    pytest.param((1e-6, 1.0 - 5e-7, 1.0), (P, E, P), id="ratio 1e6"),
    pytest.param((1e-6, 1.0, 1.0 + 1e-6), (P, E, P), id="ratio 1e6 flat lamina"),
    pytest.param((1e-6, 1.0, 1.0), (P, N, N), id="ratio 1e6 rod"),
    pytest.param((1.0, 1.0 + 1e-9, 2.0), (P, E, P), id="I2 - I1 = 1e-9"),
    pytest.param((1.0, 1.0 + 1e-13, 2.0), (N, N, P), id="I2 - I1 = 1e-13 (degenerate)"),
    pytest.param((1.0, 2.0, 2.0 + 1e-9), (P, E, P), id="I3 - I2 = 1e-9"),
    pytest.param((1.0, 2.0, 2.0 + 1e-13), (P, N, N), id="I3 - I2 = 1e-13 (degenerate)"),
    pytest.param((1.0, 2.0, 3.0), (P, E, P), id="flat lamina"),
    pytest.param((1.0, 1.0, 2.0), (N, N, P), id="flat symmetric lamina"),
    pytest.param((3.0, 3.0, 3.0), (N, N, N), id="sphere"),
    pytest.param((1.0, 1.0 + 1e-9, 1.0 + 2e-9), (P, E, P), id="near sphere"),
]


@pytest.mark.parametrize("moments, kinds", EXTREME_BODIES)
def test_extreme_bodies_give_a_clear_kind_and_finite_answers_that_agree(moments, kinds):
    moments = np.array(moments)
    for axis, expected in zip((1, 2, 3), kinds):
        kind, value = theory.linear(moments, axis, 1.0)
        assert kind == expected and math.isfinite(value) and (value == 0.0) == (kind == N), (axis, kind, value)
    w0 = np.concatenate([perturbed_spins(moments, a, 1.0, 0.1, 2, seed=20 + a) for a in (1, 2, 3)]
                        + [np.random.default_rng(23).normal(size=(2, 3))])
    w0 /= np.linalg.norm(w0, axis=1, keepdims=True)
    closed = exact.omega(moments, w0, np.array([10.0]))[:, 0]
    period = exact.period(moments, w0)
    assert np.all(np.isfinite(closed)) and not np.any(np.isnan(period)) and np.all(period > 0)
    (e0, l0), (e1, l1) = invariants(moments, w0), invariants(moments, closed)
    assert np.abs(e1 / e0 - 1).max() < 4e-15 and np.abs(l1 / l0 - 1).max() < 4e-15
    for method, tol in (("rk4", 1e-8), ("rk8", 1e-11)):
        ds = tumble.integrate(moments, w0, 10.0, 0.01, method=method)
        assert np.all(ds.status.values == STATUS_OK)
        np.testing.assert_allclose(ds.omega.values[:, -1], closed, atol=tol)


def test_lie_poisson_splittings_lose_accuracy_on_extreme_moment_ratios_while_rk4_does_not():
    """Documented limitation (see benchmarks/results/stress.md): the splitting's sub-flow about a large-moment
    axis moves I_large/I_small times a component into the small-moment one, so its error constant grows with
    the moment ratio; Euler's coefficients (Ia − Ib)/Ic stay bounded by 1, so RK4's does not."""
    errors = {}
    for name, moments in (("generic", (2.0, 3.0, 4.0)), ("ratio 1e4", (1e-4, 1.0 - 5e-5, 1.0))):
        w = perturbed_spins(moments, 2, 1.0, 0.1, 2, seed=24)
        closed = exact.omega(moments, w, np.array([5.0]))[:, 0]
        for method in ("rk4", "splitting4"):
            ds = tumble.integrate(moments, w, 5.0, 0.01, method=method)
            assert np.all(ds.status.values == STATUS_OK)  # nothing flags it
            errors[name, method] = np.abs(ds.omega.values[:, -1] - closed).max()
    # measured: rk4 6e-13 -> 7e-11, splitting4 9e-12 -> 9e-8 (1e4 times worse, and 1e3 times rk4's error)
    assert errors["ratio 1e4", "rk4"] < 1e-9
    assert errors["ratio 1e4", "splitting4"] > 1e3 * errors["generic", "splitting4"]
    assert errors["ratio 1e4", "splitting4"] > 1e2 * errors["ratio 1e4", "rk4"]


# --- near the separatrix -------------------------------------------------------------------------------

@pytest.mark.parametrize("eps", [1e-4, 1e-6, 1e-8, 1e-10, 1e-12])
def test_near_the_separatrix_the_flip_spacing_is_finite_and_matches_its_asymptote(eps):
    """2K/ν against (2/λ) ln(4/k'), which it approaches as O(k'²): for k' down to ~1e-12."""
    w0 = perturbed_spins(BODY, 2, 1.0, eps, 8, seed=30)
    kc = exact.parameters(BODY, w0).kc
    assert np.all((kc > 0.1 * eps) & (kc < 10 * eps))
    spacing = exact.flip_spacing(BODY, w0)
    asymptote = 2.0 * theory.flip_time_asymptote(BODY, w0)
    assert np.all(np.isfinite(spacing)) and np.all(np.isfinite(exact.first_flip_time(BODY, w0)))
    assert np.abs(spacing / asymptote - 1).max() <= eps**2 + 2e-15


def test_rk4_times_the_first_flip_from_a_tilt_of_1e_minus_12():
    w0 = perturbed_spins(BODY, 2, 1.0, 1e-12, 4, seed=31)
    first = exact.first_flip_time(BODY, w0)
    t_end = math.ceil(first.max() / 0.01 + 10) * 0.01
    run = run_ensemble(BODY, w0, t_end, 0.01, method="rk4", axis=2, max_flips=1, drift=True, probe_times=[0.0])
    assert run.status.tolist() == [STATUS_OK] * 4 and np.all(run.flip_count == 1)
    np.testing.assert_allclose(run.flips[:, 0], first, rtol=1e-9)


# --- the full sweep ------------------------------------------------------------------------------------

@pytest.mark.slow
def test_the_stress_benchmark_writes_its_report(tmp_path, monkeypatch):
    path = Path(__file__).resolve().parent.parent / "benchmarks" / "stress.py"
    monkeypatch.syspath_prepend(str(path.parent))  # as when run as a script: its sibling modules (provenance)
    spec = importlib.util.spec_from_file_location("stress_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert module.main(["--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "stress.md").read_text()
    assert "## Summary: where each method stops being trustworthy" in text
    assert all(f"| {m} |" in text for m in STEPPERS)
    assert (tmp_path / "stress.json").stat().st_size > 1000
