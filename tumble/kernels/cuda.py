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

__all__ = ["THREADS", "kernel", "make_kernel", "refusal", "run"]

#: Threads per block of a launch (one sample each).
THREADS = 128

_NOT_YET = "not yet on the device"
_NO_TORQUE = (0.0, 0.0, 0.0, 0.0)  # the torque argument of a torque-free kernel (never read)


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
    def propagate(w, body, t0, h, n_steps, save_every, saved, axis, weights, probe_steps, probes, flips, flip_count,
                  drift, status, steps_taken, stop_norm, stop_flips, drift_limit, torque_kind, torque_params,
                  fit_saturation, fit_min_points, fit_h, fit, fit_points):
        # size: a kernel's flat arguments (DESIGN.md: arrays and scalars below the kernels' door), packed by run(),
        # and one time loop with its observers, status checks and stores in the CPU driver's order
        """Advance sample ``cuda.grid(1)`` by ``n_steps`` steps of ``h`` from ``t0``, observing as asked; the arguments
        up to ``torque_params`` are those of :func:`tumble.kernels.drivers.make_propagate`'s driver that the device
        serves (:func:`run` packs them; ``weights`` is a tuple, and ``probes`` may be empty while ``probe_steps`` is
        not: the norms then only feed the growth fit). The observers are the CPU's per-sample ones
        (:func:`flip_in_step`, :func:`invariant_errors`, :func:`transverse_norm`, :func:`measurement_complete`),
        called in the CPU driver's order, so that a sample stops at the same step with the same status; the flip
        count and the drift maxima stay in registers.

        ``fit_saturation > 0`` fits the growth rate of the norms at the probes (``fit_h`` apart) in registers as they
        come (:func:`tumble.kernels.fits.growth_window_add`, the CPU fit's own step): ``fit`` (3, N) receives the rate
        (1/s, NaN unless the window has ``fit_min_points``), the first and the last norm of the window, ``fit_points``
        its length (0 unless the fit is good).
        """
        i = cuda.grid(1)
        if i >= w.shape[1]:
            return
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
    ...``) for what the device does not do yet (:func:`refusal`).
    """
    problem = refusal(method, torque_fn=torque_fn)
    if problem:
        raise ValueError(problem)
    n = w.shape[1]
    torque_free = torque_params is None
    kernel_w, constants, torque_params, relabel = kernel_frame(method, w, moments, torque_params, None)
    kernel_axis, weights = kernel_observed_axis(relabel, axis, norm_weights)
    n_saved = 0
    if save_every > 0:
        n_saved = 1 + n_steps // save_every + (1 if n_steps % save_every else 0)
    probe_steps = np.zeros(0, dtype=np.int64) if probe_steps is None else np.asarray(probe_steps, dtype=np.int64)
    n_probes = len(probe_steps)
    device_w = cuda.to_device(np.ascontiguousarray(kernel_w))
    saved = cuda.device_array((n_saved, 3, n)) if n_saved else cuda.device_array((0, 3, 1))
    flips = cuda.device_array((n, max_flips)) if max_flips > 0 else cuda.device_array((1, 0))
    flip_count = cuda.device_array(n if max_flips > 0 else 0, dtype=np.int64)
    drifts = cuda.device_array((2, n)) if drift else cuda.device_array((0, 1))
    keep_probes = n_probes > 0 and (keep_probes or growth_window is None)
    if keep_probes:
        probes = cuda.device_array((n_probes, n))
    else:
        probes = cuda.device_array((0, 1))
    saturation, min_points, fit_h = growth_window or (0.0, 0, 0.0)
    fit = cuda.device_array((3, n)) if growth_window else cuda.device_array((0, 1))
    fit_points = cuda.device_array(n if growth_window else 0, dtype=np.int64)
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    threads = THREADS if n >= THREADS else 32 * -(-n // 32)
    params = _NO_TORQUE if torque_free else tuple(float(x) for x in torque_params)
    kernel(method, torque_free)[-(-n // threads), threads](
        device_w, constants, float(t0), float(h), int(n_steps), int(save_every), saved, int(kernel_axis),
        tuple(float(g) for g in weights), cuda.to_device(np.ascontiguousarray(probe_steps)), probes, flips,
        flip_count, drifts, status, steps_taken, float(stop_norm), int(stop_flips),
        float(drift_limit) if torque_free else 0.0, int(torque_kind), params, float(saturation), int(min_points),
        float(fit_h), fit, fit_points)
    w[:] = from_kernel_frame(relabel, device_w.copy_to_host())
    growth = None
    if growth_window:
        rate, first, last = fit.copy_to_host()
        growth = (rate, fit_points.copy_to_host(), first, last)
    phase = None
    if phase_window is not None:
        phase = _phase_fit(saved, relabel, n, *phase_window)
    keep_saved = n_saved and (keep_saved or phase_window is None)
    return Observed(from_kernel_frame(relabel, saved.copy_to_host(), axis=1) if keep_saved else None,
                    probes.copy_to_host() if keep_probes else None, flips.copy_to_host() if max_flips > 0 else None,
                    flip_count.copy_to_host() if max_flips > 0 else None, drifts.copy_to_host() if drift else None,
                    status.copy_to_host(), steps_taken.copy_to_host(), growth, phase)


def _phase_fit(saved, relabel, n, times, plane, weights, floor, max_step):
    """The phase fit of the trajectory ``saved`` (n_saved, 3, n) the kernel left on the device, in its frame
    (``relabel``: the plane's columns there, and the sign of every component): ``(frequency, radius, code)``."""
    from .cuda_fits import phase_fit

    sign = 1.0
    columns = np.asarray(plane, dtype=np.int64)
    if relabel is not None:
        perm, sign = relabel
        columns = np.argsort(perm)[columns]
    return phase_fit(np.reshape(times, (1, -1)), np.zeros(1, dtype=np.int64), saved, np.tile(columns, (n, 1)),
                     np.tile(np.asarray(weights, dtype=float), (n, 1)), np.full(n, float(floor)), max_step,
                     time_major=True, sign=float(sign))
