"""The ensemble engine: observers agree with stored trajectories, results do not depend on threads or chunks,
skipping changes no requested result, blow-ups are flagged per sample."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from tumble.engine.ensemble import run_ensemble
from tumble.engine.sampling import perturbed_spins
from tumble.kernels.loops.drivers import CHECK_EVERY, STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK
from tumble.physics import exact

MOMENTS = np.array([1.0, 2.0, 3.0])
AXIS = 2  # the spins below are about the intermediate axis


@pytest.fixture(scope="module")
def spins():
    """Spins tilted 1e-3 rad from the intermediate axis: they flip within the horizon."""
    return perturbed_spins(MOMENTS, 2, 1.0, 1e-3, 300, seed=7)


@pytest.mark.parametrize("method, weights", [("rk4", None), ("splitting2", (0.3, 9.0, 2.0))])
def test_transverse_norm_probes_equal_the_stored_trajectory(spins, method, weights):
    """Plain and weighted norms; the splitting relabels the axes inside the kernel, the weights follow."""
    run = run_ensemble(MOMENTS, spins, 12.0, 0.01, axis=AXIS, method=method, save_every=1,
                       probe_times=[0.0, 2.5, 7.0, 12.0], norm_weights=weights)
    steps = np.rint(run.probe_times / 0.01).astype(int)
    stored = run.trajectory[:, steps]
    g = np.ones(3) if weights is None else np.asarray(weights)
    expected = np.sqrt(g[2] * stored[..., 2] ** 2 + g[0] * stored[..., 0] ** 2)
    np.testing.assert_allclose(run.probes, expected, rtol=4e-16, atol=0)
    closed = run_ensemble(MOMENTS, spins, 12.0, 0.01, axis=AXIS, probe_times=run.probe_times, norm_weights=weights)
    np.testing.assert_allclose(closed.probes, run.probes, rtol=1e-4)  # splitting2 at dt = 0.01: ~4e-5


def test_drift_observer_equals_the_maximum_over_the_stored_trajectory(spins):
    run = run_ensemble(MOMENTS, spins, 5.0, 0.05, axis=AXIS, method="splitting2", save_every=1, drift=True)
    w = run.trajectory
    energy = 0.5 * np.sum(MOMENTS * w**2, axis=-1)
    l2 = np.sum((MOMENTS * w) ** 2, axis=-1)
    np.testing.assert_allclose(run.drift[:, 0], np.abs(energy / energy[:, :1] - 1).max(axis=1), rtol=1e-6,
                               atol=1e-15)
    np.testing.assert_allclose(run.drift[:, 1], np.abs(l2 / l2[:, :1] - 1).max(axis=1), atol=1e-15)


def test_flip_times_match_the_closed_form(spins):
    run = run_ensemble(MOMENTS, spins, 50.0, 0.005, axis=AXIS, method="rk8", max_flips=3, final=False)
    first = exact.first_flip_time(MOMENTS, spins)
    spacing = exact.flip_spacing(MOMENTS, spins)
    two = run.flip_count >= 2  # spins nearest the separatrix flip later
    assert two.mean() > 0.9 and np.all(run.flip_count == (first + spacing <= 50.0) + 1)
    np.testing.assert_allclose(run.flips[:, 0], first, rtol=1e-7)
    np.testing.assert_allclose(run.flips[two, 1] - run.flips[two, 0], spacing[two], rtol=1e-6)


def test_flip_times_agree_with_sign_changes_of_the_stored_trajectory(spins):
    run = run_ensemble(MOMENTS, spins[:20], 20.0, 0.01, axis=AXIS, method="rk4", save_every=1, max_flips=2)
    w2 = run.trajectory[..., 1]
    for i in range(20):
        k = np.flatnonzero(np.signbit(w2[i, 1:]) != np.signbit(w2[i, :-1]))[0]
        assert k * 0.01 <= run.flips[i, 0] <= (k + 1) * 0.01


def test_the_closed_form_path_takes_no_steps_and_agrees_with_stepping(spins):
    probes = np.linspace(0.0, 15.0, 7)
    closed = run_ensemble(MOMENTS, spins, 15.0, 0.01, axis=AXIS, probe_times=probes, max_flips=1, drift=True)
    stepped = run_ensemble(MOMENTS, spins, 15.0, 0.01, axis=AXIS, method="rk8", probe_times=probes, max_flips=1, drift=True)
    assert closed.info["path"] == "closed form" and closed.info["sample_steps_computed"] == 0
    assert closed.info["sample_steps_skipped"] == len(spins) * 1500
    assert stepped.info["path"] == "fixed-step kernel"
    np.testing.assert_allclose(closed.final, stepped.final, atol=1e-10)
    np.testing.assert_allclose(closed.probes, stepped.probes, rtol=1e-7, atol=1e-13)
    np.testing.assert_allclose(closed.flips, stepped.flips, rtol=1e-8)
    assert np.all(closed.drift < 1e-13)


def test_early_stop_changes_no_requested_result(spins):
    probes = np.geomspace(0.01, 30.0, 40)
    kwargs = dict(method="rk4", final=False, probe_times=probes, max_flips=1)
    full = run_ensemble(MOMENTS, spins, 30.0, 0.01, axis=AXIS, **kwargs)
    early = run_ensemble(MOMENTS, spins, 30.0, 0.01, axis=AXIS, stop_norm=0.5, stop_flips=1, **kwargs)
    assert early.info["early_stop"] and early.info["sample_steps_skipped"] > 0
    assert early.info["sample_steps_computed"] < full.info["sample_steps_computed"]
    assert np.all(early.steps_taken < 3000)
    np.testing.assert_array_equal(early.flips, full.flips)
    # every probe taken before a sample stopped is bit-identical; later ones are NaN, not made up
    taken = ~np.isnan(early.probes)
    np.testing.assert_array_equal(early.probes[taken], full.probes[taken])
    assert np.all(np.nanmax(early.probes, axis=1) >= 0.5)


def test_early_stop_is_ignored_when_the_final_state_is_asked_for(spins):
    run = run_ensemble(MOMENTS, spins[:10], 30.0, 0.01, axis=AXIS, method="rk4", final=True, max_flips=1, stop_flips=1)
    assert not run.info["early_stop"] and np.all(run.steps_taken == 3000)


@pytest.mark.parametrize("method", ["rk4", "splitting2", "implicit_midpoint"])
def test_results_do_not_depend_on_the_chunk_size(method, spins):
    kwargs = dict(method=method, probe_times=[1.0, 3.0], max_flips=1, drift=True)
    a = run_ensemble(MOMENTS, spins, 3.0, 0.01, axis=AXIS, chunk=4096, **kwargs)
    b = run_ensemble(MOMENTS, spins, 3.0, 0.01, axis=AXIS, chunk=37, **kwargs)
    for field in ("final", "probes", "flips", "drift", "status", "steps_taken"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


def test_results_are_bit_identical_with_one_or_two_numba_threads(tmp_path):
    # One interpreter with a pool of two threads, run with one and then two (numba.set_num_threads): the
    # interpreter's start-up, not the run, was most of this test's time.
    script = textwrap.dedent("""
        import sys, numba, numpy as np
        from tumble.engine.ensemble import run_ensemble
        from tumble.engine.sampling import perturbed_spins
        w0 = perturbed_spins((1.0, 2.0, 3.0), 2, 1.0, 1e-3, 700, seed=3)
        for threads in (1, 2):
            numba.set_num_threads(threads)
            for method in ("rk4", "splitting2"):
                r = run_ensemble((1.0, 2.0, 3.0), w0, 3.0, 0.01, method=method, axis=2, probe_times=[1.5, 3.0])
                sys.stdout.write(r.final.tobytes().hex() + r.probes.tobytes().hex())
            sys.stdout.write("\\n")
    """)
    env = dict(os.environ, NUMBA_NUM_THREADS="2")
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    outputs = done.stdout.splitlines()
    assert len(outputs) == 2 and outputs[0] == outputs[1] and len(outputs[0]) > 1000


def test_a_sample_that_blows_up_is_flagged_and_stopped_alone():
    w0 = np.array([[0.1, 1.0, 0.1], [1e200, 1e200, 1e200], [0.2, 0.1, 1.0]])
    run = run_ensemble(MOMENTS, w0, 10.0, 0.1, method="rk4", drift_limit=0.0)
    assert run.status.tolist() == [STATUS_OK, STATUS_NONFINITE, STATUS_OK]
    assert run.steps_taken[1] <= CHECK_EVERY and run.steps_taken[0] == 100
    reference = run_ensemble(MOMENTS, w0[[0, 2]], 10.0, 0.1, method="rk4")
    np.testing.assert_array_equal(run.final[[0, 2]], reference.final)


def test_invariant_drift_past_the_limit_is_flagged():
    w0 = np.array([[0.3, 1.0, 0.2], [0.3, 1.0, 0.2]]) * np.array([[0.1], [30.0]])
    run = run_ensemble(MOMENTS, w0, 10.0, 0.05, method="symplectic_euler", drift_limit=1e-2)
    assert run.status.tolist() == [STATUS_OK, STATUS_DRIFT]


def test_a_zero_torque_is_compiled_out_and_changes_nothing(spins):
    free = run_ensemble(MOMENTS, spins, 2.0, 0.01, axis=AXIS, method="rk4", torque=(0.0, 0.0, 0.0))
    assert free.info["torque"] == "none"
    forced = run_ensemble(MOMENTS, spins, 2.0, 0.01, axis=AXIS, method="rk4", torque=(0.0, 0.0, 1e-300))
    np.testing.assert_allclose(free.final, forced.final, rtol=0, atol=1e-250)


@pytest.mark.parametrize("method", ["rk4", pytest.param("rk8", marks=pytest.mark.slow)])
def test_the_per_sample_step_compiles_to_packed_simd_code(method):
    """The block loop of a generated step vectorises across samples (packed FMA on ymm/zmm); rk8 (12 stages)
    as rk4 does, and its packed multiplies and multiply-adds are the count the engine benchmark divides the
    machine's FMA peak by (benchmarks/results/engine.md, the roofline)."""
    import re

    import numba

    from tumble.kernels.steps import fused, steppers
    from tumble.kernels import tableaux
    from tumble.kernels.steps.codegen import multiplies_per_sample_step
    from tumble.kernels.jit import FASTMATH

    if "+fma" not in numba.core.codegen.get_host_cpu_features():
        pytest.skip("this CPU has no FMA")
    block = getattr(fused, f"{method}_block")
    fresh = numba.njit(cache=False, fastmath=set(FASTMATH), error_model="numpy")(block.py_func)
    y = np.ones((3, 64))
    fresh(y[0], y[1], y[2], np.ones(64, dtype=np.bool_), 0.0, 0.01, steppers.body_constants(MOMENTS),
          np.ones(64), np.empty((0, 64)), 0, None, None)
    assembly = "\n".join(fresh.inspect_asm().values())
    packed = re.findall(r"v(?:fmadd\w*|mul)pd\s+[^\n]*%[yz]mm", assembly)
    assert len(packed) == multiplies_per_sample_step(getattr(tableaux, method.upper()))


def test_a_splitting_sub_flow_turns_the_block_with_packed_simd_code():
    """Each sub-flow of a splitting (steppers.rotate_block: sincos and the rotation) vectorises across the
    samples of a block, for every axis."""
    import re

    import numba

    from tumble.kernels.steps import steppers
    from tumble.kernels.jit import FASTMATH

    if "+fma" not in numba.core.codegen.get_host_cpu_features():
        pytest.skip("this CPU has no FMA")
    fresh = numba.njit(cache=False, fastmath=set(FASTMATH), error_model="numpy")(steppers.rotate_block.py_func)
    y = np.ones((3, 64))
    fresh(0, 0.01, y[0], y[1], y[2], steppers.body_constants(MOMENTS))
    assembly = "\n".join(fresh.inspect_asm().values())
    assert len(re.findall(r"vfmadd\w*pd\s+[^\n]*%[yz]mm", assembly)) >= 3 * 10  # three loops, sincos in each


@pytest.mark.parametrize("path", ["closed form", "kernel"])
def test_ctrl_c_stops_between_chunks(spins, monkeypatch, path):
    """SIGINT during the second chunk lets that chunk finish, starts no other, and restores the handler."""
    import signal

    from tumble.engine import ensemble as engine

    target = "exact" if path == "closed form" else "run"
    real = engine.exact.solve_rows if target == "exact" else engine.run
    calls = []

    def pressed_during_second_chunk(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            signal.raise_signal(signal.SIGINT)
        return real(*args, **kwargs)

    method = "auto" if target == "exact" else "rk4"
    run_ensemble(MOMENTS, spins[:1], 0.01, 0.01, axis=AXIS, method=method)  # compiled: no warm-up call below
    if target == "exact":
        monkeypatch.setattr(engine.exact, "solve_rows", pressed_during_second_chunk)
    else:
        monkeypatch.setattr(engine, "run", pressed_during_second_chunk)
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(engine.Interrupted, match="after 200 of 300 samples") as stopped:
        run_ensemble(MOMENTS, spins, 1.0, 0.01, axis=AXIS, method=method, chunk=100, progress=False)
    assert len(calls) == 2 and stopped.value.done == 200
    assert isinstance(stopped.value, KeyboardInterrupt)
    assert signal.getsignal(signal.SIGINT) is before
