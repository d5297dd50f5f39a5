"""The ensemble on a CUDA device: one thread per sample, float64.

The time loop is written once: each thread runs the CPU's own loop (:func:`tumble.kernels.loops.block_loop.run_block`:
steps, flips, drift, status, stores, probes, early stop, the growth fit) on a block of one sample held in the thread's
local memory; numba-cuda compiles it and the ``@jit`` functions it calls (the generated steps of
:mod:`tumble.kernels.steps.fused`, the splittings' sub-flows of :mod:`tumble.kernels.steps.steppers`) for the device. A method, an
observer or a stop rule added to the CPU's loop runs here without a line added, and a sample stops at the same step
with the same status as on the CPU. The frame (moments in units, a splitting's axes relabelled) is prepared by the CPU
path's own :func:`tumble.kernels.loops.methods.kernel_frame`.

What the device adds: many scenes in one launch (a row per scene of the bodies, steps, probes, torques) and the
growth fit in the loop (the loop's ``fit_saturation``): each probe norm is fed to the CPU fit's own window step
(:func:`tumble.kernels.fits.growth_window_add`) as it comes, and only four numbers per sample come back instead of its
probes. Only the outputs asked for are copied back. Torque functions are refused with a ``ValueError`` that starts
``device 'cuda':``.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_kernels`). With ``NUMBA_ENABLE_CUDASIM=1`` (set before numba is imported) the
kernels run on numba-cuda's simulator, which executes the kernel body in Python and the loop it calls as compiled CPU
code (:func:`tumble.kernels.cuda.launch.loop_array`).
"""

import numpy as np
from numba import boolean, cuda, float64, int64

from .launch import THREADS, launch_shape, loop_array, loop_with_codes
from ..loops.block_loop import FREE_BODY, N_INVARIANTS, PROBE_ROWS, run_block
from ..jit import cuda_jit
from ..loops.methods import Observed, from_kernel_frame, kernel_frame, kernel_observed_axis, spin_unit
from ..steps.steppers import TORQUE_CONSTANT

__all__ = ["THREADS", "kernel", "make_kernel", "refusal", "run", "run_scenes"]


def refusal(method, *, torque_fn=None):
    """The one-line reason why a run cannot go to the device, or None when it can."""
    if torque_fn is not None:
        return ("device 'cuda': a Python torque function cannot run on the device; use a constant torque or a "
                "named profile (constant, ramp, sine, pulse)")
    return None


def make_kernel(method, torque_free):
    """The device kernel of ``method``, torque-free or with a built-in torque profile: one thread per sample, running
    the CPU's time loop (:func:`tumble.kernels.loops.block_loop.run_block`) on a block of one sample in the thread's local
    memory. The free body's code, the method and ``torque_free`` are constants of the closure, handed to the loop as
    literals, so that the kernel compiles that method's step only, torque-free or with a torque (on the simulator
    through :func:`tumble.kernels.cuda.launch.loop_with_codes`: the CPU's compiled loop of those codes)."""
    kernel_id = method.kernel_id
    loop = loop_with_codes(run_block, FREE_BODY, kernel_id, torque_free, True)

    @cuda_jit
    def propagate(w, scene, bodies, t0, hs, step_counts, saves, saved, axes, column_rows, weight_rows, y_eq,
                  probe_step_rows, probes, flips, flip_count, drift, status, steps_taken, stop_norms, stop_flips,
                  drift_limit, torque_kind, torque_rows, fit_saturations, fit_min_points, fit_hs, fit, fit_points):
        # size: a kernel's flat arguments (DESIGN.md: arrays and scalars below the kernels' door), packed by
        # run_scenes(), each scene's row read here and handed to the one time loop
        """Advance sample ``i = cuda.grid(1)`` of scene ``s = scene[i]`` (0 when ``scene`` is empty: one scene) by
        ``step_counts[s]`` steps of ``hs[s]`` from ``t0``, observing as asked. Each scene's quantities are a row of a
        per-scene table: ``bodies`` (S, 12) the body constants, ``axes``, ``saves`` (steps between stored states),
        the transverse norm's ``column_rows`` (S, 2) and ``weight_rows`` (S, 2) (``y_eq`` zeros), ``probe_step_rows``
        (S, P), ``stop_norms``, ``torque_rows`` (S, 4),
        ``fit_saturations`` and ``fit_hs``; for one scene they are the arguments of
        :func:`tumble.kernels.loops.drivers.make_propagate`'s driver that the device serves (``probes`` may be empty while
        the probe steps are not: the norms then only feed the growth fit)."""
        i = cuda.grid(1)
        if i >= w.shape[1]:
            return
        s = scene[i] if scene.shape[0] > 0 else 0
        body = (bodies[s, 0], bodies[s, 1], bodies[s, 2], bodies[s, 3], bodies[s, 4], bodies[s, 5], bodies[s, 6],
                bodies[s, 7], bodies[s, 8], bodies[s, 9], bodies[s, 10], bodies[s, 11])  # registers, as a tuple
        if torque_free:  # a constant: numba compiles one of the two
            torque_params = None
        else:
            torque_params = loop_array(torque_rows)[s]
        # every argument spelled out, at most 30 (see the loop's note): a star-call would pass the codes on as plain
        # ints, a typing error
        scratch = (cuda.local.array((3, 1), float64), cuda.local.array((3, 1), float64),
                   cuda.local.array((3, 1), float64), cuda.local.array((N_INVARIANTS, 1), float64),
                   cuda.local.array((N_INVARIANTS, 1), float64), cuda.local.array((PROBE_ROWS, 1), float64),
                   cuda.local.array((2, 1), boolean), cuda.local.array(1, int64))
        norm = (loop_array(column_rows)[s], loop_array(weight_rows)[s], loop_array(y_eq))
        growth = (fit_saturations[s], fit_min_points, fit_hs[s], loop_array(fit), loop_array(fit_points))
        loop(FREE_BODY, kernel_id, torque_free, True, loop_array(w), i, scratch, body, t0, hs[s], step_counts[s], saves[s],
             loop_array(saved), norm, loop_array(probe_step_rows)[s], loop_array(probes),
             (axes[s], loop_array(flips), loop_array(flip_count)), loop_array(drift), drift_limit, loop_array(status),
             loop_array(steps_taken), (stop_norms[s], stop_flips), (torque_kind, torque_params, None), growth)

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
    # size: the keywords of tumble.kernels.loops.methods.run, so that the engine calls either the same way, and the fits
    """:func:`tumble.kernels.loops.methods.run` on the device: the same arguments and the same :class:`Observed`.

    Only what was asked comes back from the device: the final state, and the trajectory, probe norms, flips and drift
    records when asked (an output not asked for is a zero-length device array, never copied). ``block`` is not used
    (a thread is a sample). ``growth_window=(saturation, min_points, h)`` fits each sample's growth rate from its
    norms at the probes (``h`` apart) in the kernel (:func:`tumble.kernels.fits.growth_fit`'s window, fed as they
    come): ``Observed.growth`` is ``(rate, points, first, last)`` (N,) each, and with ``keep_probes=False`` the probe
    norms stay on the device. ``phase_window=(times, plane, weights, floor, max_step)`` fits each sample's
    oscillation frequency from the phase of its stored components on the device (:mod:`tumble.kernels.cuda.phase_fit`,
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
    # as the CPU's run: beyond 2**±256 rad/s stepped as s w with h / s, its times, norms and rates given back exactly
    unit = spin_unit(w) if torque_free else 1.0
    spins = w * unit if unit != 1.0 else w
    if unit != 1.0:
        t0, h, stop_norm = t0 / unit, np.asarray(h, float) / unit, np.asarray(stop_norm, float) * unit
        if growth_window:
            growth_window = (np.asarray(growth_window[0], float) * unit, growth_window[1],
                             np.asarray(growth_window[2], float) / unit)
        if phase_window is not None:
            times, planes, weights, floors, max_step = phase_window
            phase_window = (np.asarray(times, float) / unit, planes, weights, np.asarray(floors, float) * unit, max_step)
    frames = []
    bodies, torque_rows = np.empty((count, 12)), np.zeros((count, 4))
    axes, column_rows = np.empty(count, dtype=np.int64), np.empty((count, 2), dtype=np.int64)
    weight_rows = np.empty((count, 2))
    kernel_w = np.empty((3, n))
    for k in range(count):  # each scene in its kernel frame (a splitting relabels the axes by its moments)
        rows = slice(starts[k], starts[k + 1])
        scene_w, constants, params, relabel = kernel_frame(method, spins[:, rows], moments[k], torque_params, None)
        kernel_w[:, rows] = scene_w
        bodies[k] = constants
        if not torque_free:
            torque_rows[k] = params
        axes[k], weights = kernel_observed_axis(relabel, int(axis[k]), None if norm_weights is None
                                                else norm_weights[k])
        column_rows[k] = (axes[k] + 1) % 3, (axes[k] + 2) % 3  # the transverse norm's two components
        weight_rows[k] = weights[column_rows[k]]
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
    flip_count = cuda.device_array(n, dtype=np.int64)
    drifts = cuda.device_array((2, n)) if drift else cuda.device_array((0, 1))
    keep_probes = n_probes > 0 and (keep_probes or growth_window is None)
    probes = cuda.device_array((n_probes, n)) if keep_probes else cuda.device_array((0, 1))
    saturation, min_points, fit_h = growth_window or (np.zeros(count), 0, np.zeros(count))
    fit = cuda.device_array((3 if growth_window else 0, n))
    fit_points = cuda.device_array(n if growth_window else 0, dtype=np.int64)
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    scene = np.repeat(np.arange(count, dtype=np.int64), sizes) if count > 1 else np.zeros(0, dtype=np.int64)
    kernel(method, torque_free)[launch_shape(n)](
        device_w, cuda.to_device(scene), cuda.to_device(bodies), float(t0), cuda.to_device(np.asarray(h, float)),
        cuda.to_device(n_steps), cuda.to_device(save_every), saved, cuda.to_device(axes),
        cuda.to_device(column_rows), cuda.to_device(weight_rows), cuda.to_device(np.zeros(3)),
        cuda.to_device(probe_steps), probes, flips, flip_count, drifts, status,
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
        rate, first, last = fit.copy_to_host() / unit  # 1/s and rad/s
        growth = (rate, fit_points.copy_to_host(), first, last)
    phase = None
    if phase_window is not None:
        frequency, radius, code = _phase_fit(saved, frames, sizes, *phase_window)
        phase = (frequency / unit, radius / unit, code)
    if unit != 1.0:  # back from s w at time t / s
        w /= unit
        if trajectory is not None:
            trajectory /= unit
    return Observed(trajectory, probes.copy_to_host() / unit if keep_probes else None,
                    flips.copy_to_host() * unit if max_flips > 0 else None,
                    flip_count.copy_to_host() if max_flips > 0 else None, drifts.copy_to_host() if drift else None,
                    status.copy_to_host(), steps_taken.copy_to_host(), growth, phase)


def _phase_fit(saved, frames, sizes, times, planes, weights, floors, max_step):
    """The phase fit of the trajectories ``saved`` (n_saved, 3, N) the kernel left on the device, each scene's in its
    kernel frame (``frames``: its samples and relabelling, which moves the plane's columns and may flip the sign of
    every component): ``(frequency, radius, code)``."""
    from .phase_fit import phase_fit

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
