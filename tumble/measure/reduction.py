"""A scene's sample ranges reduced: the scene record (a flat dict of NumPy values) and the scene's dataset.

:func:`scene_records` joins the ranges each scene's samples ran in (:mod:`tumble.measure.running`) and computes the
statistics over samples (median, confidence interval, spread, fit window, flips) of all scenes of one kind in one
vectorised call each, with the kept curves (:data:`tumble.measure.planning.CURVES`); :func:`scene_result` is one
scene's dataset (:func:`tumble.measure.records.scene_dataset`).
"""

from __future__ import annotations

import warnings

import numpy as np

from .._version import __version__
from ..engine.sampling import drawn_spins
from . import estimators as analysis
from .planning import PROBES
from .records import CONFIDENCE, INTERVAL_TEXT, scene_dataset
from .running import FIT_OFFSET, FLIP_ARRAYS, GROWTH_FIT, SAMPLE_STATUS_NAMES
from .traces import TRACE_POINTS, sample_trace

__all__ = ["scene_records", "scene_result"]


def scene_result(scene, parts):
    """The dataset of :func:`measure` from the :func:`scene_samples` ranges of a scene (in any order, together
    covering every sample once): per-sample arrays concatenated, the scene's values computed from them once."""
    return scene_dataset(scene_records([scene], [parts])[0])


def _joined(scene, parts):
    """The per-sample arrays of a scene's ranges, checked and concatenated, and the ranges' scalars."""
    parts = sorted(parts, key=lambda part: int(part["start"]))
    samples = scene.samples
    covered = 0
    for part in parts:
        if int(part["start"]) != covered:
            raise ValueError(f"the sample ranges of a scene of {samples} samples do not follow each other: one "
                             f"starts at {int(part['start'])}, expected {covered}")
        covered += len(part["rate"])
    if covered != samples:
        raise ValueError(f"the sample ranges of a scene of {samples} samples end at {covered}")
    growth = scene.kind == "exponential"
    names = ("rate", "code", *(GROWTH_FIT if growth else ("radius",)), *(FLIP_ARRAYS if scene.flips else ()))
    joined = {name: np.concatenate([part[name] for part in parts]) for name in names}
    joined.update(computed=sum(int(part["sample_steps_computed"]) for part in parts),
                  skipped=sum(int(part["sample_steps_skipped"]) for part in parts),
                  value=float(parts[0]["rate_theory"]), path=str(parts[-1]["path"]), torque=str(parts[-1]["torque"]))
    if "norm_time" in parts[0]:
        joined["norm"] = tuple(parts[0][f"norm_{name}"] for name in ("time", "q1", "median", "q3"))
    return joined


def _medians(values, mask):
    """Median over the samples of each row where ``mask`` (and the value is finite); NaN for none."""
    return analysis.medians(np.where(mask, values, np.nan))


def scene_records(scenes, parts):
    """The scene records of :func:`scene_plan` results from their :func:`scene_samples` ranges.

    A record is a flat dict of NumPy values — every variable, coordinate and attribute (``@name``) of the scene's
    dataset (:func:`scene_dataset`), nothing else — so that it pickles, checkpoints as plain arrays, and a scan is
    assembled from records in one pass (:func:`assemble_scan`). The statistics over samples (median, interval,
    spread, fit window, flips) of all scenes of one kind are computed in one vectorised call each: the same bits
    as one scene at a time.

    Parameters
    ----------
    scenes : list of dict
        :func:`scene_plan` results.
    parts : list of list of dict
        For each scene, its ranges (together covering every sample once).
    """
    joined = [_joined(scene, ranges) for scene, ranges in zip(scenes, parts)]
    groups = {}
    for i, scene in enumerate(scenes):
        groups.setdefault((scene.kind, scene.flips > 0, scene.samples), []).append(i)
    records = [None] * len(scenes)
    for (kind, flipping, _), members in groups.items():
        stacked = {name: np.stack([joined[i][name] for i in members]) for name in joined[members[0]]
                   if isinstance(joined[members[0]][name], np.ndarray)}
        code = stacked["code"]
        valid = code == 0
        rate = np.where(valid, stacked["rate"], np.nan)
        summary = analysis.summarize(rate, confidence=CONFIDENCE)
        extras = GROWTH_FIT if kind == "exponential" else ("radius",)
        medians = {name: _medians(stacked[name], valid) for name in extras}
        flips = None
        if flipping:
            ok = (code == 0) | (code > FIT_OFFSET)  # flips need a sound trajectory, not a successful rate fit
            first, spacing = stacked["flip_first"], stacked["flip_spacing"]
            has_spacing = ok & np.isfinite(spacing)
            with np.errstate(invalid="ignore", divide="ignore"):
                spacing_error = np.abs(spacing / stacked["flip_exact"] - 1.0)
            worst = np.where(has_spacing, spacing_error, -np.inf).max(axis=1)
            flips = {"first": _medians(first, ok), "asymptote": _medians(stacked["flip_asymptote"], ok),
                     "spacing": _medians(spacing, ok), "exact": _medians(stacked["flip_exact"], ok),
                     "worst": np.where(has_spacing.any(axis=1), worst, np.nan), "timed": has_spacing.sum(axis=1),
                     "sample_first": np.where(ok, first, np.nan), "sample_spacing": np.where(ok, spacing, np.nan)}
        for j, i in enumerate(members):
            records[i] = _scene_record(scenes[i], joined[i], analysis.Summary(*(field[j] for field in summary)), rate[j],
                                       code[j], {name: m[j] for name, m in medians.items()},
                                       None if flips is None else {name: v[j] for name, v in flips.items()})
    return records


def _scene_record(scene, joined, summary, rate, code, medians, flips):
    """The record (see :func:`scene_records`) of one scene from its joined arrays and statistics."""
    moments, axis, spin, amplitude = scene.moments, scene.axis, scene.spin, scene.amplitude
    kind, plan, value = scene.kind, scene.plan, joined["value"]
    if summary.used == 0:
        counts = np.bincount(code, minlength=len(SAMPLE_STATUS_NAMES))
        warnings.warn(f"no sample of the scene (axis {axis}, amplitude {amplitude}) gave a rate; statuses: "
                      + ", ".join(f"{SAMPLE_STATUS_NAMES[k]} {n}" for k, n in enumerate(counts) if n),
                      RuntimeWarning, stacklevel=4)
    theory_scale = value if value > 0 else abs(spin)
    record = {"rate": summary.median, "rate_theory": value, "rel_error": abs(summary.median - value) / theory_scale,
              "kind": kind, "rate_ci_low": summary.ci_low, "rate_ci_high": summary.ci_high,
              "rate_spread": summary.spread, "samples_used": summary.used, "samples_excluded": summary.excluded,
              "sample_rate": rate, "sample_status": code, "dt": plan.dt, "t_end": plan.t_end,
              "n_steps": np.int64(plan.n_steps), "sample_steps_computed": np.int64(joined["computed"]),
              "sample_steps_skipped": np.int64(joined["skipped"]), "path": joined["path"]}
    if kind == "exponential":
        record.update({f"fit_{name}": medians[name] for name in GROWTH_FIT}, fit_saturation=plan.saturation)
    else:
        record["signal_radius"] = medians["radius"]
    record["flips_timed"] = np.int64(0)
    if flips is not None:
        record.update(flip_first=flips["first"], flip_first_asymptote=flips["asymptote"], flip_spacing=flips["spacing"],
                      flip_spacing_exact=flips["exact"], flip_spacing_asymptote=2 * flips["asymptote"],
                      flip_spacing_rel_error=flips["worst"], flips_timed=np.int64(flips["timed"]),
                      sample_first_flip=flips["sample_first"], sample_flip_spacing=flips["sample_spacing"])
    kept = {"norm": joined["norm"]} if "norm" in joined else {}
    if "trace" in scene.curves:
        w_trace = drawn_spins(moments, axis, spin, amplitude, scene.entropy, scene.distribution, 0, 1)
        kept["trace"] = sample_trace(moments, w_trace, plan, scene.chosen, scene.torque, scene.device)
    record.update(_curves(kept, scene.curves))
    record.update(I1=moments[0], I2=moments[1], I3=moments[2], axis=np.int64(axis), spin=spin, amplitude=amplitude,
                  method=scene.method, sample=np.arange(scene.samples, dtype=np.int64))
    if "trace" in scene.curves:
        record["component"] = np.array([1, 2, 3])
    record.update({"@title": f"tumble measurement: {kind} rate about axis {axis}", "@method_run": scene.chosen,
                   "@samples": scene.samples, "@seed_entropy": str(scene.entropy),
                   "@distribution": scene.distribution, "@median_interval": INTERVAL_TEXT,
                   "@source": f"tumble {__version__}"})
    if scene.spin_up is not None:
        record["@torque"] = joined["torque"]
    return {name: np.asarray(v) for name, v in record.items()}


def _curves(kept, curves):
    """Values of the kept curves (NaN where the scene has none, so that scans stack)."""
    out = {}
    if "norm" in curves:
        nan = np.full(PROBES + 1, np.nan)
        times, q1, median, q3 = kept.get("norm", (nan, nan, nan, nan))
        out.update(growth_time=times, growth_norm=median, growth_norm_q1=q1, growth_norm_q3=q3)
    if "trace" in curves:
        times, omega = kept["trace"]
        n = TRACE_POINTS + 2  # fixed length (NaN padded), so that scenes of a scan stack
        t_pad, w_pad = np.full(n, np.nan), np.full((n, 3), np.nan)
        t_pad[:len(times)], w_pad[:len(times)] = times, omega
        out.update(trace_time=t_pad, trace_omega=w_pad)
    return out
