"""Checks the model kernels' tests share: observed orders against DOP853, growth rates fitted to the probes, the same
bits on any threads and chunks."""

import numba
import numpy as np
from scipy.integrate import solve_ivp

from tumble.engine.model_ensemble import run_model_ensemble


def model_errors(model, y0, t_end, method, steps):
    """The largest error over 8 equally spaced checkpoints of ``method`` with each step count of ``steps``, against
    SciPy's DOP853 at rtol 1e-13 (a single end point's error can sit near a cancellation)."""
    checkpoints = np.linspace(0.0, t_end, 9)
    reference = solve_ivp(lambda t, y: model.rhs(y), (0.0, t_end), y0[0], method="DOP853", rtol=1e-13, atol=1e-15,
                          t_eval=checkpoints).y.T
    errors = []
    for n in steps:
        result = run_model_ensemble(model, y0, t_end, t_end / n, method=method, axis=3, save_every=n // 8)
        assert np.allclose(result.times, checkpoints)
        errors.append(np.abs(result.trajectory[0] - reference).max())
    return errors


def observed_order(t_end, steps, errors):
    """The slope of log(error) against log(step)."""
    return np.polyfit(np.log(t_end / np.array(steps)), np.log(errors), 1)[0]


def fitted_rate(times, probes, low, high):
    """Least-squares slope of the ensemble's mean log norm over the times where it lies in (low, high)."""
    mean = np.log(probes).mean(axis=0)
    inside = (mean > np.log(low)) & (mean < np.log(high))
    assert inside.sum() >= 20
    return np.polyfit(times[inside], mean[inside], 1)[0]


def assert_same_bits_on_any_threads_and_chunks(model, y0):
    """An rk8 run of ``model`` from ``y0`` with every observer gives the same bits on 1 and 2 numba threads and for
    any chunk of samples."""
    run = dict(method="rk8", axis=3, save_every=7, probe_times=[0.0, 1.0, 2.0], drift=True)
    before = numba.get_num_threads()
    results = []
    try:
        for threads, chunk in ((1, 4096), (2, 4096), (2, 7), (1, 300)):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            results.append(run_model_ensemble(model, y0, 2.0, 0.01, chunk=chunk, **run))
    finally:
        numba.set_num_threads(before)
    first = results[0]
    for other in results[1:]:
        for name in ("final", "trajectory", "probes", "drift", "status", "steps_taken"):
            assert np.array_equal(getattr(first, name), getattr(other, name)), name
