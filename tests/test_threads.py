"""The kernels' parallelism (tumble/kernels/threads.py): shares of whole blocks, one per numba thread, and the same
bits on any number of threads (the free body's driver: tests/test_engine.py; the models': tests/model_checks.py)."""

import threading

import numba
import numpy as np
import pytest

import tumble
from tumble.kernels import threads


def test_the_shares_are_whole_granules_that_cover_the_samples_once_and_the_counts_add_up():
    seen = []

    def share(lo, hi):
        seen.append((lo, hi, threading.current_thread() is threading.main_thread()))
        return hi - lo, 1

    before = numba.get_num_threads()
    try:
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        assert threads.in_parallel(share, 1000, granule=256) == (1000, numba.get_num_threads())
        bounds = sorted(seen)
        assert bounds[0][0] == 0 and bounds[-1][1] == 1000
        assert all(a[1] == b[0] for a, b in zip(bounds, bounds[1:]))
        assert all(lo % 256 == 0 for lo, _, _ in bounds)
        assert bounds[-1][2], "the last share runs in the calling thread"
        seen.clear()
        assert threads.in_parallel(share, 100, granule=256) == (100, 1)  # one granule: one share, no pool
        assert seen == [(0, 100, True)]
        assert threads.in_parallel(lambda lo, hi: None, 10) is None
    finally:
        numba.set_num_threads(before)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba runs one thread on this machine")
def test_the_closed_form_its_attitude_a_scene_and_megno_give_the_same_bits_on_one_or_two_threads():
    body = tumble.shapes.t_handle()
    spins = np.random.default_rng(3).normal(size=(600, 3)) * 0.05 + (0.0, 10.0, 0.0)
    top = tumble.models.HeavyTop((1.0, 1.6, 2.2), mgl=1.0, centre=(0.6, 0.3, 1.0))
    tops = np.tile([0.5, 0.3, 2.0, 0.1, 0.2, np.sqrt(0.95)], (300, 1))
    tops[:, :3] += np.linspace(0.0, 1e-3, 300)[:, None]
    times = np.linspace(0.0, 3.0, 9)

    def results():
        return [np.asarray(tumble.exact.omega(body, spins, times)),
                np.asarray(tumble.exact.attitude(body, spins[:200], times)),
                tumble.integrate(body, spins[:300], 0.2, 1e-3, attitude=True).quaternion.values,
                tumble.measure(body, axis=2, spin=10.0, samples=600).sample_rate.values,
                tumble.megno(top, tops, t_end=1.0, dt=0.01).megno.values]

    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = results()
        numba.set_num_threads(2)
        two = results()
    finally:
        numba.set_num_threads(before)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba runs one thread on this machine")
def test_the_spinning_workers_hand_back_results_and_errors_and_runs_from_two_threads_at_once_all_run():
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(2)

        def share(lo, hi):
            if lo == 0 and hi == 13:
                raise ZeroDivisionError("a share's error")
            return lo, hi, threading.current_thread().name

        results = threads.in_shares(lambda *bounds: share(*bounds), 200, lambda lo, hi: (lo, hi))
        assert [r[:2] for r in results] == [(0, 100), (100, 200)]
        assert results[0][2] == "tumble" and results[1][2] == threading.current_thread().name
        with pytest.raises(ZeroDivisionError, match="a share's error"):  # raised on the worker, handed back
            threads.in_shares(share, 26, lambda lo, hi: (lo, hi))
        assert threads.in_shares(share, 400, lambda lo, hi: (lo, hi))[0][:2] == (0, 200)  # the worker still runs

        def started_share(lo, hi, starts):  # handoff: the caller's share starts the others' (an empty starts: none)
            if hi == 10 and lo > 0:
                raise ValueError("before it started the others")
            threads.start_shares(starts)
            return lo, hi, len(starts)

        assert threads.in_shares(started_share, 40, lambda lo, hi: (lo, hi), handoff=True) == [(0, 20, 0), (20, 40, 1)]
        with pytest.raises(ValueError, match="before it started"):  # the others started all the same, no hang
            threads.in_shares(started_share, 10, lambda lo, hi: (lo, hi), handoff=True)
        assert threads.in_shares(started_share, 40, lambda lo, hi: (lo, hi), handoff=True)[1] == (20, 40, 1)

        totals = []
        spins = np.random.default_rng(0).normal(size=(400, 3)) + (0.0, 3.0, 0.0)
        expected = tumble.propagate((1.0, 2.0, 3.0), spins, 5.0, method="dop853")

        def run():  # two callers at once: one holds the workers, the other takes the pool's threads
            totals.append(tumble.propagate((1.0, 2.0, 3.0), spins, 5.0, method="dop853"))

        callers = [threading.Thread(target=run) for _ in range(4)]
        for caller in callers:
            caller.start()
        for caller in callers:
            caller.join()
        assert len(totals) == 4
        for total in totals:
            np.testing.assert_array_equal(total, expected)
    finally:
        numba.set_num_threads(before)
