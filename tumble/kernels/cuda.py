"""The ensemble on a CUDA device: one thread per sample, its state in registers, float64.

A method is written once. numba-cuda compiles the ``@jit`` functions a kernel calls for the device, so a thread
steps its sample with the CPU's own per-sample functions: a Runge–Kutta method's ``<name>_sample``, generated from
its tableau into :mod:`tumble.kernels.fused`; a splitting's table from :mod:`tumble.kernels.tableaux`, run by
:func:`tumble.kernels.steppers.splitting_free_sample` (the sub-flows of :func:`tumble.kernels.steppers.rotate_about`
and the projection onto the sample's own ``|L|**2``, as the CPU's block loop) or, with a torque,
:func:`tumble.kernels.steppers.splitting_with_torque`. A new method in the tables runs here without a line added.
The frame (moments in units, a splitting's axes relabelled) is prepared by the CPU path's own
:func:`tumble.kernels.methods.kernel_frame`.

What the device computes: the final state, the stored trajectory (``save_every``), the status (non-finite, checked
every :data:`tumble.kernels.drivers.CHECK_EVERY` steps, every step while flips are observed, and at the end, as on
the CPU; invariant drift past ``drift_limit``, torque-free), the steps each sample took, and the observers of the CPU
driver: the transverse norm at probe steps, the times of the spin-axis component's sign changes, the running maxima
of the invariants' drift and the early stop once a sample's measurement is complete (``stop_norm``, ``stop_flips``).
The observers are the CPU's per-sample ``@jit`` functions (:func:`tumble.kernels.drivers.transverse_norm`,
:func:`~tumble.kernels.drivers.flip_in_step`, :func:`~tumble.kernels.drivers.invariant_errors`,
:func:`~tumble.kernels.drivers.measurement_complete`), called in the CPU driver's order, so a sample stops at the
same step with the same status as on the CPU; the flip count and the drift maxima stay in registers, and only the
outputs asked for are copied back. A growth scene's fit runs in registers too: each probe norm is fed to the CPU fit's
own window step (:func:`tumble.kernels.fits.growth_window_add`) as it comes, and only four numbers per sample come
back instead of its probes. A sample that stops keeps its state, as on the CPU. The implicit midpoint rule runs
as the CPU's, at most the same fixed number of fixed-point sweeps per step
(:func:`tumble.kernels.steppers.implicit_midpoint_sample`). Torque functions are refused with a ``ValueError`` that
starts ``device 'cuda':``.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_kernels`). With ``NUMBA_ENABLE_CUDASIM=1`` (set before numba is imported) the
kernels run on numba-cuda's simulator, which executes the kernel body in Python and the ``@jit`` functions it
calls as compiled CPU code.
"""

import math

import numpy as np
from numba import cuda

from ..registry import STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK
from . import fused, steppers, tableaux
from .drivers import CHECK_EVERY, drifted, flip_in_step, invariant_errors, measurement_complete, transverse_norm
from .fits import GROWTH_WINDOW_START, growth_window_add, growth_window_rate
from .jit import cuda_jit
from .methods import Observed, from_kernel_frame, kernel_frame, kernel_observed_axis
from .steppers import TORQUE_CONSTANT, energy, l_squared, splitting_free_sample, splitting_with_torque

__all__ = ["THREADS", "kernel", "make_kernel", "refusal", "run", "run_scenes"]

#: Threads per block of a launch (one sample each).
THREADS = 128


def refusal(method, *, torque_fn=None):
    """The one-line reason why a run cannot go to the device, or None when it can."""
    if torque_fn is not None:
        return ("device 'cuda': a Python torque function cannot run on the device; use a constant torque or a "
                "named profile (constant, ramp, sine, pulse)")
    return None


def make_kernel(method, torque_free):
    # size: the closure holds the one kernel below (see there)
    """The device kernel of ``method``, torque-free or with a built-in torque profile: one thread per sample.

    The step is the CPU's: a Runge–Kutta method's generated ``<name>_sample``; a splitting's table (its sub-flows
    without the torque ones when torque-free) run by :func:`tumble.kernels.steppers.splitting_free_sample` or
    :func:`tumble.kernels.steppers.splitting_with_torque`. ``splitting`` and ``torque_free`` are constants of the
    closure, so numba compiles only the branch the kernel takes.
    """
    coefficients = method.coefficients
    splitting = isinstance(coefficients, tableaux.Splitting)
    sample = flows = fractions = None
    if splitting:
        table = coefficients.without_torque() if torque_free else coefficients
        flows, fractions = table.flows, table.fractions
    else:
        # generated from the tableau (kernels/codegen.py); the implicit midpoint rule's is written by hand
        sample = getattr(fused, f"{method.name}_sample", None) or steppers.implicit_midpoint_sample

    @cuda_jit
    def propagate(w, scene, bodies, t0, hs, step_counts, saves, saved, axes, weight_rows, probe_step_rows, probes,
                  flips, flip_count, drift, status, steps_taken, stop_norms, stop_flips, drift_limit, torque_kind,
                  torque_rows, fit_saturations, fit_min_points, fit_hs, fit, fit_points):
        # size: a kernel's flat arguments (DESIGN.md: arrays and scalars below the kernels' door), packed by
        # run_scenes(), and one time loop with its observers, status checks and stores in the CPU driver's order
        """Advance sample ``i = cuda.grid(1)`` of scene ``s = scene[i]`` (0 when ``scene`` is empty: one scene) by
        ``step_counts[s]`` steps of ``hs[s]`` from ``t0``, observing as asked. Each scene's quantities are a row of a
        per-scene table, read once into registers: ``bodies`` (S, 12) the body constants, ``axes``, ``saves``
        (steps between stored states), ``weight_rows`` (S, 3), ``probe_step_rows`` (S, P), ``stop_norms``,
        ``torque_rows`` (S, 4), ``fit_saturations`` and ``fit_hs``; for one scene they are the arguments of
        :func:`tumble.kernels.drivers.make_propagate`'s driver that the device serves (``probes`` may be empty
        while the probe steps are not: the norms then only feed the growth fit). The observers are the CPU's
        per-sample ones (:func:`flip_in_step`, :func:`invariant_errors`, :func:`transverse_norm`,
        :func:`measurement_complete`), called in the CPU driver's order, so that a sample stops at the same step with
        the same status; the flip count and the drift maxima stay in registers.

        ``fit_saturations[s] > 0`` fits the growth rate of the norms at the probes (``fit_hs[s]`` apart) in registers
        as they come (:func:`tumble.kernels.fits.growth_window_add`, the CPU fit's own step): ``fit`` (3, N) receives
        the rate (1/s, NaN unless the window has ``fit_min_points``), the first and the last norm of the window,
        ``fit_points`` its length (0 unless the fit is good).
        """
        i = cuda.grid(1)
        if i >= w.shape[1]:
            return
        s = scene[i] if scene.shape[0] > 0 else 0
        body = (bodies[s, 0], bodies[s, 1], bodies[s, 2], bodies[s, 3], bodies[s, 4], bodies[s, 5], bodies[s, 6],
                bodies[s, 7], bodies[s, 8], bodies[s, 9], bodies[s, 10], bodies[s, 11])  # registers, as a tuple
        h, n_steps, save_every, axis = hs[s], step_counts[s], saves[s], axes[s]
        weights = (weight_rows[s, 0], weight_rows[s, 1], weight_rows[s, 2])
        probe_steps = probe_step_rows[s]
        stop_norm, fit_saturation, fit_h = stop_norms[s], fit_saturations[s], fit_hs[s]
        torque_params = (torque_rows[s, 0], torque_rows[s, 1], torque_rows[s, 2], torque_rows[s, 3])
        w1, w2, w3 = w[0, i], w[1, i], w[2, i]
        target = l_squared(w1, w2, w3, body)
        e0 = energy(w1, w2, w3, body)
        store = saved.shape[0] > 0
        n_probes = probe_steps.shape[0]
        keep_probes = probes.shape[0] > 0
        fitting = fit_saturation > 0.0
        n_flips = flips.shape[1]
        track_drift = drift.shape[0] > 0
        early_stop = stop_norm > 0.0 or stop_flips > 0
        slot = 0
        if store:
            saved[0, 0, i], saved[0, 1, i], saved[0, 2, i] = w1, w2, w3
            slot = 1
        for j in range(n_flips):
            flips[i, j] = math.nan
        reached = False
        window = GROWTH_WINDOW_START
        probe = 0
        count = 0
        max_de = max_dl = 0.0
        code = STATUS_OK
        ran = 0
        while True:  # observe the state after `ran` steps (probes, early stop), then take the next step
            while probe < n_probes and probe_steps[probe] == ran:
                norm = transverse_norm(w1, w2, w3, axis, weights)
                if keep_probes:
                    probes[probe, i] = norm
                if fitting:
                    window = growth_window_add(probe, norm, fit_saturation, window)
                reached = reached or (stop_norm > 0.0 and norm >= stop_norm)
                probe += 1
            if ran == n_steps or (ran > 0 and early_stop and measurement_complete(reached, stop_norm, stop_flips,
                                                                                   count)):
                break
            t = t0 + ran * h
            p1, p2, p3 = w1, w2, w3
            if splitting and torque_free:
                w1, w2, w3 = splitting_free_sample(w1, w2, w3, h, body, target, flows, fractions)
            elif splitting:
                w1, w2, w3 = splitting_with_torque(w1, w2, w3, t, h, body, flows, fractions, torque_kind,
                                                   torque_params, None)
            elif torque_free:
                w1, w2, w3 = sample(w1, w2, w3, t, h, body, torque_kind, None, None)
            else:
                w1, w2, w3 = sample(w1, w2, w3, t, h, body, torque_kind, torque_params, None)
            ran += 1
            if n_flips > 0:
                if torque_free:
                    flipped, time = flip_in_step(axis, t, h, p1, p2, p3, w1, w2, w3, body, torque_kind, None, None)
                else:
                    flipped, time = flip_in_step(axis, t, h, p1, p2, p3, w1, w2, w3, body, torque_kind,
                                                 torque_params, None)
                if flipped:
                    if count < n_flips:
                        flips[i, count] = time
                    count += 1
            if track_drift or drift_limit > 0.0:
                de, dl = invariant_errors(w1, w2, w3, body, e0, target)
                max_de, max_dl = max(max_de, de), max(max_dl, dl)
                if drifted(de, dl, drift_limit):
                    code = STATUS_DRIFT
            if code == STATUS_OK and (n_flips > 0 or ran % CHECK_EVERY == 0 or ran == n_steps):
                if not (math.isfinite(w1) and math.isfinite(w2) and math.isfinite(w3)):
                    code = STATUS_NONFINITE
            if store and (ran % save_every == 0 or ran == n_steps):
                saved[slot, 0, i], saved[slot, 1, i], saved[slot, 2, i] = w1, w2, w3
                slot += 1
            if code != STATUS_OK:
                break
        # A sample that stopped keeps its state for the rest of its trajectory and has no norm after it, as on the CPU
        if store:
            for k in range(ran, n_steps):
                if (k + 1) % save_every == 0 or k + 1 == n_steps:
                    saved[slot, 0, i], saved[slot, 1, i], saved[slot, 2, i] = w1, w2, w3
                    slot += 1
        if fitting:
            if probe < n_probes:  # the first probe after the sample stopped (NaN) closes the window
                window = growth_window_add(probe, math.nan, fit_saturation, window)
            fit[0, i], fit_points[i], fit[1, i], fit[2, i] = growth_window_rate(window, n_probes, fit_h,
                                                                                fit_min_points)
        while keep_probes and probe < n_probes:
            probes[probe, i] = math.nan
            probe += 1
        if n_flips > 0:
            flip_count[i] = count
        if track_drift:
            drift[0, i], drift[1, i] = max_de, max_dl
        w[0, i], w[1, i], w[2, i] = w1, w2, w3
        status[i] = code
        steps_taken[i] = ran

    return propagate


_KERNELS = {}


def kernel(method, torque_free):
    """The device kernel of ``method`` (:func:`make_kernel`, made once; compiled on its first launch)."""
    key = (method.name, torque_free)
    if key not in _KERNELS:
        _KERNELS[key] = make_kernel(method, torque_free)
    return _KERNELS[key]


def run(method, w, moments, t0, h, n_steps, *, save_every=0, axis=0, norm_weights=None, probe_steps=None,
        max_flips=0, drift=False, stop_norm=0.0, stop_flips=0, drift_limit=0.0, torque_kind=TORQUE_CONSTANT,
        torque_params=None, torque_fn=None, block=None, growth_window=None, keep_probes=True, phase_window=None,
        keep_saved=True):
    # size: the keywords of tumble.kernels.methods.run, so that the engine calls either the same way, and the fits
    """:func:`tumble.kernels.methods.run` on the device: the same arguments and the same :class:`Observed`.

    Only what was asked comes back from the device: the final state, and the trajectory, probe norms, flips and drift
    records when asked (an output not asked for is a zero-length device array, never copied). ``block`` is not used
    (a thread is a sample). ``growth_window=(saturation, min_points, h)`` fits each sample's growth rate from its
    norms at the probes (``h`` apart) in the kernel (:func:`tumble.kernels.fits.growth_fit`'s window, fed as they
    come): ``Observed.growth`` is ``(rate, points, first, last)`` (N,) each, and with ``keep_probes=False`` the probe
    norms stay on the device. ``phase_window=(times, plane, weights, floor, max_step)`` fits each sample's
    oscillation frequency from the phase of its stored components on the device (:mod:`tumble.kernels.cuda_fits`,
    the CPU's per-sample fit), ``times`` (n_saved,) the stored times (s), ``plane`` the two columns ``(b, c)``
    (0-based, body frame), ``weights`` ``(g_b, g_c)``, ``floor`` the no-signal radius (rad/s) and ``max_step`` (rad)
    as :func:`tumble.kernels.fits.phase_fit` takes them: ``Observed.phase`` is ``(frequency, radius, code)`` (N,)
    each, and with ``keep_saved=False`` the trajectory stays on the device. Raises ``ValueError`` (``device 'cuda':
    ...``) for what the device does not do yet (:func:`refusal`). One scene of :func:`run_scenes`.
    """
    problem = refusal(method, torque_fn=torque_fn)
    if problem:
        raise ValueError(problem)
    probe_steps = np.zeros(0, dtype=np.int64) if probe_steps is None else np.asarray(probe_steps, dtype=np.int64)
    saturation, min_points, fit_h = growth_window or (0.0, 0, 0.0)
    return run_scenes(method, w, np.array([w.shape[1]]), np.asarray(moments, dtype=float)[None], float(t0),
                      np.array([float(h)]), np.array([int(n_steps)]), save_every=np.array([int(save_every)]),
                      axis=np.array([int(axis)]), norm_weights=None if norm_weights is None else
                      np.asarray(norm_weights, dtype=float)[None], probe_steps=probe_steps[None],
                      max_flips=max_flips, drift=drift, stop_norm=np.array([float(stop_norm)]), stop_flips=stop_flips,
                      drift_limit=drift_limit, torque_kind=torque_kind, torque_params=torque_params,
                      growth_window=(np.array([float(saturation)]), min_points, np.array([float(fit_h)]))
                      if growth_window else None, keep_probes=keep_probes,
                      phase_window=None if phase_window is None else _one_row(*phase_window), keep_saved=keep_saved)


def _one_row(times, plane, weights, floor, max_step):
    """:func:`run`'s ``phase_window`` as :func:`run_scenes` takes it (one scene)."""
    return (np.asarray(times, dtype=float)[None], np.asarray(plane, dtype=np.int64)[None],
            np.asarray(weights, dtype=float)[None], np.array([float(floor)]), float(max_step))


def run_scenes(method, w, sizes, moments, t0, h, n_steps, *, save_every, axis, norm_weights=None, probe_steps,
               max_flips=0, drift=False, stop_norm, stop_flips=0, drift_limit=0.0, torque_kind=TORQUE_CONSTANT,
               torque_params=None, growth_window=None, keep_probes=True, phase_window=None, keep_saved=True):
    # size: run()'s keywords with a row per scene: the scene table of one launch
    """The samples of many scenes in one launch: :func:`run` with a row per scene.

    Parameters
    ----------
    method : Method
    w : ndarray, shape (3, N)
        The samples of every scene, scene after scene; overwritten with the final states.
    sizes : ndarray of int, shape (S,)
        Samples of each scene (summing to N).
    moments : ndarray, shape (S, 3)
    t0 : float
    h, n_steps, save_every, axis, stop_norm : ndarray, shape (S,)
        Per scene, as :func:`run` takes them; ``save_every`` (0: no trajectory) must give every scene the same number
        of stored states.
    norm_weights : ndarray (S, 3) or None
    probe_steps : ndarray of int, shape (S, P)
        Every scene has the same number ``P`` of probes (``P = 0``: none).
    max_flips, drift, stop_flips, drift_limit, torque_kind, torque_params, keep_probes
        As :func:`run`, the same for every scene (``torque_params`` in the body frame of every scene's moments).
    growth_window : tuple (saturation (S,), min_points, h (S,)), optional
    phase_window : tuple (times (S, T), plane (S, 2), weights (S, 2), floor (S,), max_step), optional
        :func:`run`'s, a row per scene; with ``keep_saved=False`` the trajectories stay on the device.

    Returns
    -------
    Observed
        As :func:`run`, samples in the order of ``w``.
    """
    sizes = np.asarray(sizes, dtype=np.int64)
    n, count = w.shape[1], len(sizes)
    starts = np.concatenate(([0], np.cumsum(sizes)))
    torque_free = torque_params is None
    frames = []
    bodies, torque_rows = np.empty((count, 12)), np.zeros((count, 4))
    axes, weight_rows = np.empty(count, dtype=np.int64), np.empty((count, 3))
    kernel_w = np.empty((3, n))
    for k in range(count):  # each scene in its kernel frame (a splitting relabels the axes by its moments)
        rows = slice(starts[k], starts[k + 1])
        scene_w, constants, params, relabel = kernel_frame(method, w[:, rows], moments[k], torque_params, None)
        kernel_w[:, rows] = scene_w
        bodies[k] = constants
        if not torque_free:
            torque_rows[k] = params
        axes[k], weight_rows[k] = kernel_observed_axis(relabel, int(axis[k]), None if norm_weights is None
                                                       else norm_weights[k])
        frames.append((rows, relabel))
    save_every = np.asarray(save_every, dtype=np.int64)
    n_steps = np.asarray(n_steps, dtype=np.int64)
    stored = {1 + int(m) // int(e) + (1 if int(m) % int(e) else 0) if e > 0 else 0 for m, e in zip(n_steps, save_every)}
    if len(stored) > 1:
        raise ValueError(f"the scenes of one launch store different numbers of states: {sorted(stored)}")
    n_saved = stored.pop()
    probe_steps = np.ascontiguousarray(probe_steps, dtype=np.int64)
    n_probes = probe_steps.shape[1]
    device_w = cuda.to_device(kernel_w)
    saved = cuda.device_array((n_saved, 3, n)) if n_saved else cuda.device_array((0, 3, 1))
    flips = cuda.device_array((n, max_flips)) if max_flips > 0 else cuda.device_array((1, 0))
    flip_count = cuda.device_array(n if max_flips > 0 else 0, dtype=np.int64)
    drifts = cuda.device_array((2, n)) if drift else cuda.device_array((0, 1))
    keep_probes = n_probes > 0 and (keep_probes or growth_window is None)
    probes = cuda.device_array((n_probes, n)) if keep_probes else cuda.device_array((0, 1))
    saturation, min_points, fit_h = growth_window or (np.zeros(count), 0, np.zeros(count))
    fit = cuda.device_array((3, n)) if growth_window else cuda.device_array((0, 1))
    fit_points = cuda.device_array(n if growth_window else 0, dtype=np.int64)
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    scene = np.repeat(np.arange(count, dtype=np.int64), sizes) if count > 1 else np.zeros(0, dtype=np.int64)
    threads = THREADS if n >= THREADS else 32 * -(-n // 32)
    kernel(method, torque_free)[-(-n // threads), threads](
        device_w, cuda.to_device(scene), cuda.to_device(bodies), float(t0), cuda.to_device(np.asarray(h, float)),
        cuda.to_device(n_steps), cuda.to_device(save_every), saved, cuda.to_device(axes),
        cuda.to_device(weight_rows), cuda.to_device(probe_steps), probes, flips, flip_count, drifts, status,
        steps_taken, cuda.to_device(np.asarray(stop_norm, float)), int(stop_flips),
        float(drift_limit) if torque_free else 0.0, int(torque_kind), cuda.to_device(torque_rows),
        cuda.to_device(np.asarray(saturation, float)), int(min_points), cuda.to_device(np.asarray(fit_h, float)),
        fit, fit_points)
    final = device_w.copy_to_host()
    keep_saved = n_saved and (keep_saved or phase_window is None)
    trajectory = saved.copy_to_host() if keep_saved else None
    for rows, relabel in frames:
        w[:, rows] = from_kernel_frame(relabel, final[:, rows])
        if trajectory is not None and relabel is not None:
            trajectory[:, :, rows] = from_kernel_frame(relabel, trajectory[:, :, rows], axis=1)
    growth = None
    if growth_window:
        rate, first, last = fit.copy_to_host()
        growth = (rate, fit_points.copy_to_host(), first, last)
    phase = None if phase_window is None else _phase_fit(saved, frames, sizes, *phase_window)
    return Observed(trajectory, probes.copy_to_host() if keep_probes else None,
                    flips.copy_to_host() if max_flips > 0 else None,
                    flip_count.copy_to_host() if max_flips > 0 else None, drifts.copy_to_host() if drift else None,
                    status.copy_to_host(), steps_taken.copy_to_host(), growth, phase)


def _phase_fit(saved, frames, sizes, times, planes, weights, floors, max_step):
    """The phase fit of the trajectories ``saved`` (n_saved, 3, N) the kernel left on the device, each scene's in its
    kernel frame (``frames``: its samples and relabelling, which moves the plane's columns and may flip the sign of
    every component): ``(frequency, radius, code)``."""
    from .cuda_fits import phase_fit

    columns, signs = np.empty((len(sizes), 2), dtype=np.int64), np.ones(len(sizes))
    for k, (_, relabel) in enumerate(frames):
        columns[k] = planes[k]
        if relabel is not None:
            perm, signs[k] = relabel
            columns[k] = np.argsort(perm)[planes[k]]

    def each(values):
        return np.repeat(values, sizes, axis=0)

    return phase_fit(times, each(np.arange(len(sizes))), saved, each(columns), each(weights), each(floors), max_step,
                     time_major=True, sign=each(signs))
