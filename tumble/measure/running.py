"""A planned scene's samples run: per-sample fits, no reduction (``parts``, plain arrays that pickle).

:func:`scene_samples` runs any range of a scene's samples (:func:`tumble.measure.planning.scene_plan`) that starts
at a multiple of :data:`tumble.engine.sampling.CHUNK`, in slices of :data:`tumble.measure.planning.SLICE`:
stepped through :func:`tumble.engine.ensemble.run_planned` (the engine's run of checked arguments: the scene's method,
torque, device and cost were checked when it was planned), or in closed form. :func:`closed_form_samples` runs the
samples of many torque-free scenes together (one set-up, one kernel call, one call of each estimator) and
:func:`stepping_samples_on_device` those of many fixed-step scenes in one device launch; each sample's arithmetic
is the one it gets alone. :mod:`tumble.measure.reduction` reduces the parts to records.

The samples' status codes are :data:`SAMPLE_STATUS_NAMES`: the engine's, then the fit's (offset by
:data:`FIT_OFFSET`).
"""

from __future__ import annotations

import warnings

import numpy as np

from .. import registry
from ..engine.device import LAUNCH_SAMPLES
from ..engine.ensemble import flip_times, observation_times, run_planned, run_scene_table, torque_spec
from ..engine.sampling import CHUNK, drawn_spins
from ..physics import exact, theory
from ..registry import STATUS_NAMES, STATUS_OK
from . import estimators as analysis
from . import planning

__all__ = ["FIT_OFFSET", "FLIP_ARRAYS", "GROWTH_FIT", "SAMPLE_STATUS_NAMES", "closed_form_samples", "scene_samples",
           "stepping_samples_on_device"]


#: Per-sample status in a measurement: the engine's (ok, non-finite, invariant drift), then the fit's.
SAMPLE_STATUS_NAMES = registry.SAMPLE_STATUS_NAMES
FIT_OFFSET = len(STATUS_NAMES) - 1

#: Per-sample arrays of a :func:`scene_samples` range, by scene kind (and the flip times, when timed).
GROWTH_FIT = ("t_start", "t_stop", "norm_start", "norm_stop")
FLIP_ARRAYS = ("flip_first", "flip_spacing", "flip_exact", "flip_asymptote")


def scene_samples(scene, start, stop, *, progress=False):
    """Run samples ``[start, stop)`` of a :func:`scene_plan`: per-sample fits, no reduction.

    ``start`` must be a multiple of :data:`tumble.engine.sampling.CHUNK` (the engine and the sampler work in whole
    chunks, so that the samples of a range are the same bits as in the unsplit scene); the range holding sample
    0 keeps the norm curve (``curves`` with ``"norm"``), which needs the first
    :data:`tumble.measure.planning.SLICE` samples, so it must then reach ``min(SLICE, samples)``.

    Returns
    -------
    dict of ndarray
        ``start``; per sample (length ``stop - start``): ``rate``, ``code`` (int8, :data:`SAMPLE_STATUS_NAMES`),
        the fit's
        ``t_start``/``t_stop``/``norm_start``/``norm_stop`` (exponential) or ``radius``, the flip times
        (exponential with ``flips``); scalars ``sample_steps_computed``, ``sample_steps_skipped``,
        ``rate_theory``, ``path`` and ``torque``; from sample 0 the ``norm_*`` curve. Only plain arrays: it
        pickles and stores in a NumPy archive.
    """
    samples, kind, plan = scene.samples, scene.kind, scene.plan
    if not (0 <= start < stop <= samples and start % CHUNK == 0):
        raise ValueError(f"a sample range must lie in [0, {samples}) and start at a multiple of {CHUNK}, "
                         f"got [{start}, {stop})")
    keep_norm = start == 0 and "norm" in scene.curves and kind == "exponential"
    if keep_norm and stop < min(planning.SLICE, samples):
        raise ValueError(f"the sample range holding sample 0 keeps the norm curve: it must reach "
                         f"{min(planning.SLICE, samples)}, got [{start}, {stop})")
    if scene.chosen == "exact":
        return closed_form_samples([scene], start, stop)[0]
    moments, axis, spin = scene.moments, scene.axis, scene.spin
    growth, n_flips = kind == "exponential", scene.flips
    out = _empty_part(scene, start, stop)
    value = scene.value
    torque = torque_spec(scene.torque)  # as the kernels take it; checked when the scene was planned
    computed = skipped = 0
    # a device launch needs many samples
    step = planning.SLICE if scene.device == "cpu" else max(planning.SLICE, LAUNCH_SAMPLES)
    for lo in range(start, stop, step):
        hi = min(lo + step, stop)
        w0 = drawn_spins(moments, axis, spin, scene.amplitude, scene.entropy, scene.distribution, lo, hi)
        phase = analysis.phase_window(moments, axis, kind, plan.plane, spin) if scene.device == "cuda" else None
        # the planned scene's method, torque, device and cost were checked when it was planned: trusted here
        result = run_planned(moments, w0, plan.t_end, plan.dt, method=scene.chosen, axis=axis, final=False,
                             save_every=None if growth else plan.save_every,
                             probe_times=plan.probe_times if growth else None,
                             norm_weights=plan.weights if growth else None, max_flips=n_flips,
                             stop_norm=plan.saturation if growth else 0.0, stop_flips=n_flips,
                             torque=torque, progress=progress, device=scene.device,
                             growth_window=(plan.saturation, analysis.MIN_POINTS) if growth else None,
                             keep_probes=keep_norm and lo == 0, phase_window=phase, keep_trajectory=phase is None,
                             reason="chosen by the scene's plan")
        value = _observed(scene, result, w0, out, slice(lo - start, hi - start))
        info = result.info
        computed, skipped = computed + info["sample_steps_computed"], skipped + info["sample_steps_skipped"]
    out.update(sample_steps_computed=np.int64(computed), sample_steps_skipped=np.int64(skipped),
               rate_theory=np.float64(value), path=np.array(info["path"]), torque=np.array(info.get("torque", "")))
    return out


def _observed(scene, result, w0, out, rows):
    """Fill ``out[...][rows]`` (a :func:`scene_samples` part) from a run of the scene's samples ``w0`` (an
    :class:`tumble.engine.ensemble.EnsembleResult` with its growth fit, or its trajectory), the norm curve from its
    probes when they were kept; returns the theory's value (a torque's spin-up changes it)."""
    moments, kind, a, value = scene.moments, scene.kind, scene.axis - 1, scene.value
    if kind == "exponential":  # fitted by the engine (on the device in the kernel: no norm comes back but the curve's)
        fit = analysis.growth_window_fit(result.probe_times, *result.growth)
        if result.probes is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns after every sample stopped
                quartiles = np.nanquantile(result.probes[:planning.SLICE], [0.25, 0.5, 0.75], axis=0)  # as on the CPU
            out.update(norm_time=result.probe_times, norm_q1=quartiles[0], norm_median=quartiles[1],
                       norm_q3=quartiles[2])
        out["rate"][rows] = fit.rate
        for name in GROWTH_FIT:
            out[name][rows] = getattr(fit, name)
    else:
        if result.phase is not None:  # fitted on the device, where the trajectory stayed
            fit = analysis.PhaseFit(*result.phase)
        else:
            b, c = scene.plan.plane or ((a + 1) % 3, (a + 2) % 3)
            weights = analysis.invariant_weights(moments, scene.axis)[[b, c]] if kind == "periodic" else np.ones(2)
            fit = analysis.oscillation_frequencies(result.times, result.trajectory[..., [b, c]], weights, scene.spin)
        out["rate"][rows] = fit.frequency
        out["radius"][rows] = fit.radius
        if scene.spin_up is not None:
            value = planning.spin_up_rate(scene.spin_up, scene.value, scene.spin, result.times)
    out["code"][rows] = np.where(result.status != STATUS_OK, result.status,
                                 np.where(fit.code != analysis.FIT_OK, fit.code + FIT_OFFSET, 0))
    if scene.flips:
        stats = analysis.flip_statistics(result.flips)
        out["flip_first"][rows], out["flip_spacing"][rows] = stats.first, stats.spacing
        out["flip_exact"][rows] = exact.flip_spacing(moments, w0)
        out["flip_asymptote"][rows] = theory.flip_time_asymptote(moments, w0)
    return value


def stepping_samples_on_device(scenes, start, stop):
    """:func:`scene_samples` of fixed-step scenes on the device, many scenes a launch
    (:func:`tumble.engine.ensemble.run_scene_table`): a scan's scenes, each too small to fill a GPU, run in batches
    of up to :data:`tumble.engine.device.LAUNCH_SAMPLES` samples of scenes that store or probe as many times; the
    parts are the same bits as scene by scene.

    Parameters
    ----------
    scenes : list of Scene
        :func:`scene_plan` results with ``device == "cuda"``, a fixed-step method, the same ``samples`` and method,
        flips and torque, and no norm curve (whose probes a launch does not keep).
    start, stop : int
        The sample range of every scene (as :func:`scene_samples`).
    """
    parts = [_empty_part(scene, start, stop) for scene in scenes]
    groups = {}
    for k, scene in enumerate(scenes):
        plan = scene.plan
        n, every = plan.n_steps, plan.save_every
        stored = len(plan.probe_times) if scene.kind == "exponential" else 1 + n // every + (n % every > 0)
        key = (scene.kind == "exponential", stored, scene.chosen, scene.flips, repr(scene.torque))
        groups.setdefault(key, []).append(k)
    size = stop - start
    per_launch = max(1, LAUNCH_SAMPLES // size)
    for (growth, *_), members in groups.items():
        for lo in range(0, len(members), per_launch):
            _stepping_batch([scenes[k] for k in members[lo:lo + per_launch]],
                            [parts[k] for k in members[lo:lo + per_launch]], growth, start, stop)
    return parts


def _stepping_batch(scenes, parts, growth, start, stop):
    """Run the samples ``[start, stop)`` of ``scenes`` (see :func:`stepping_samples_on_device`) in one launch."""
    first, plans = scenes[0], [scene.plan for scene in scenes]
    w0 = [drawn_spins(s.moments, s.axis, s.spin, s.amplitude, s.entropy, s.distribution, start, stop) for s in scenes]
    phase = None
    if not growth:  # fitted on the device, where the trajectories stay
        windows = [analysis.phase_window(s.moments, s.axis, s.kind, s.plan.plane, s.spin) for s in scenes]
        phase = (np.array([wi[0] for wi in windows]), np.array([wi[1] for wi in windows]),
                 np.array([wi[2] for wi in windows]), windows[0][3])
    results = run_scene_table(
        first.chosen, np.stack([s.moments for s in scenes]), np.concatenate(w0), [stop - start] * len(scenes),
        np.array([p.t_end for p in plans]), np.array([p.dt for p in plans]), axis=np.array([s.axis for s in scenes]),
        save_every=None if growth else np.array([p.save_every for p in plans]),
        probe_times=np.stack([p.probe_times for p in plans]) if growth else None,
        norm_weights=np.stack([p.weights for p in plans]) if growth else None, max_flips=first.flips,
        stop_norm=np.array([p.saturation for p in plans]) if growth else None, torque=first.torque,
        growth_window=(np.array([p.saturation for p in plans]), analysis.MIN_POINTS) if growth else None,
        phase_window=phase)
    for scene, part, result, spins in zip(scenes, parts, results, w0):
        value = _observed(scene, result, spins, part, slice(0, stop - start))
        info = result.info
        part.update(sample_steps_computed=np.int64(info["sample_steps_computed"]),
                    sample_steps_skipped=np.int64(info["sample_steps_skipped"]), rate_theory=np.float64(value),
                    path=np.array(info["path"]), torque=np.array(info["torque"]))


def _empty_part(scene, start, stop):
    n = stop - start
    out = {"start": np.int64(start), "rate": np.empty(n), "code": np.empty(n, dtype=np.int8)}
    out.update((name, np.empty(n)) for name in (GROWTH_FIT if scene.kind == "exponential" else ("radius",)))
    out.update((name, np.full(n, np.nan)) for name in (FLIP_ARRAYS if scene.flips else ()))
    return out


def _observation_grid(scene):
    """The times the closed form evaluates a scene at: its probe times (exponential) or stored times."""
    plan = scene.plan
    if scene.kind == "exponential":
        return observation_times(plan.t_end, plan.dt, probe_times=plan.probe_times)[2]
    return observation_times(plan.t_end, plan.dt, save_every=plan.save_every)[0]


def closed_form_samples(scenes, start, stop):
    """:func:`scene_samples` of torque-free scenes run in closed form, many scenes at once.

    The samples of every scene go through one set-up (:func:`tumble.physics.exact.solve_rows`), one kernel call
    (:func:`tumble.physics.exact.omega_rows`, each scene on its own time grid) and one call of each estimator,
    in batches of at most :data:`tumble.measure.planning.SLICE` samples of scenes with the same kind and number of
    times: a scan pays no per-scene kernel launch or estimator call. Each sample's arithmetic is the one it gets
    alone, so the parts are the same bits as scene by scene (``scene_samples`` of a closed-form scene is this with one scene).

    Parameters
    ----------
    scenes : list of dict
        :func:`scene_plan` results with ``chosen == "exact"`` and the same ``samples``.
    start, stop : int
        The sample range of every scene (as :func:`scene_samples`).

    Returns
    -------
    list of dict
        One part per scene, as :func:`scene_samples` returns it.
    """
    parts = [_empty_part(scene, start, stop) for scene in scenes]
    grids = [_observation_grid(scene) for scene in scenes]
    groups = {}
    for k, scene in enumerate(scenes):
        key = (scene.kind == "exponential", len(grids[k]), scene.flips, scene.device)
        groups.setdefault(key, []).extend((k, lo, min(lo + planning.SLICE, stop))
                                          for lo in range(start, stop, planning.SLICE))
    for items in groups.values():
        batch, size = [], 0
        for item in items:
            if batch and size + item[2] - item[1] > planning.BATCH:
                _closed_form_batch(scenes, grids, batch, parts, start)
                batch, size = [], 0
            batch.append(item)
            size += item[2] - item[1]
        _closed_form_batch(scenes, grids, batch, parts, start)
    for scene, part in zip(scenes, parts):
        part.update(sample_steps_computed=np.int64(0),
                    sample_steps_skipped=np.int64((stop - start) * scene.plan.n_steps),
                    rate_theory=np.float64(scene.value), path=np.array("closed form"),
                    torque=np.array(torque_spec(None)[3]))
    return parts


def _closed_form_batch(scenes, grids, batch, parts, start):
    """Run the sample slices ``batch`` (``(scene, lo, hi)``) of :func:`closed_form_samples` together."""
    sizes = [hi - lo for _, lo, hi in batch]
    row = np.repeat(np.arange(len(batch)), sizes)
    per_sample = [scenes[k] for k, _, _ in batch]

    def each(values):
        return np.repeat(np.asarray(values), sizes, axis=0)

    moments = each([scene.moments for scene in per_sample])
    w0 = np.concatenate([drawn_spins(scene.moments, scene.axis, scene.spin, scene.amplitude, scene.entropy,
                                     scene.distribution, lo, hi) for scene, (_, lo, hi) in zip(per_sample, batch)])
    times = np.stack([grids[k] for k, _, _ in batch])
    first = per_sample[0]
    on_device = first.device == "cuda"
    # the set-up on the host: the CPU's evaluation, and the flips' times and spacings whatever the device
    sol = exact.solve_rows(moments, w0) if first.flips or not on_device else None
    if on_device and first.kind != "exponential":  # evaluated and phase-fitted on the device (below)
        omega = None
    elif on_device:  # set-up and time grids on the device: one launch, one thread per sample
        omega = exact.omega_rows_on_device(np.stack([scene.moments for scene in per_sample]), w0, times, row)
    else:
        omega = exact.omega_rows(sol, times, row)
    if first.kind == "exponential":
        columns = each([(s.axis % 3, (s.axis + 1) % 3) for s in per_sample])
        weights = each([s.plan.weights for s in per_sample])
        probes = analysis.transverse_norms(omega, columns, np.take_along_axis(weights, columns, axis=1))
        fit = analysis.growth_rates(times, probes, each([s.plan.saturation for s in per_sample]), row=row)
        results = {"rate": fit.rate, **{name: getattr(fit, name) for name in GROWTH_FIT}}
        if first.flips:
            spacing = exact.flip_spacings(sol)
            flips, _ = flip_times(exact.first_flips(sol), spacing, first.flips,
                                  each([s.plan.t_end for s in per_sample]))
            stats = analysis.flip_statistics(flips)
            results.update(flip_first=stats.first, flip_spacing=stats.spacing, flip_exact=spacing,
                           flip_asymptote=theory.flip_asymptote_from(moments, w0, sol.kc))
    else:
        planes = [s.plan.plane or (s.axis % 3, (s.axis + 1) % 3) for s in per_sample]
        b, c = each(planes).T
        weights = each([analysis.invariant_weights(s.moments, s.axis)[list(plane)] if s.kind == "periodic"
                        else np.ones(2) for s, plane in zip(per_sample, planes)])
        if omega is None:  # on the device: the states stay there, only the fits come back
            fit = analysis.closed_form_frequencies_on_device(np.stack([scene.moments for scene in per_sample]), w0,
                                                             times, weights, each([s.spin for s in per_sample]),
                                                             columns=np.stack([b, c], axis=1), row=row)
        else:
            fit = analysis.oscillation_frequencies(times, omega, weights, each([s.spin for s in per_sample]),
                                                   columns=np.stack([b, c], axis=1), row=row)
        results = {"rate": fit.frequency, "radius": fit.radius}
    code = np.where(fit.code != analysis.FIT_OK, fit.code + FIT_OFFSET, 0)
    offset = 0
    for (k, lo, hi), size in zip(batch, sizes):
        rows, into = slice(offset, offset + size), slice(lo - start, hi - start)
        part, scene = parts[k], scenes[k]
        for name, values in results.items():
            part[name][into] = values[rows]
        part["code"][into] = code[rows]
        if lo == 0 and "norm" in scene.curves and scene.kind == "exponential":
            quartiles = np.nanquantile(probes[rows], [0.25, 0.5, 0.75], axis=0)
            part.update(norm_time=times[row[offset]], norm_q1=quartiles[0], norm_median=quartiles[1],
                        norm_q3=quartiles[2])
        offset += size
