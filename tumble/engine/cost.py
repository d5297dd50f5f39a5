"""What a run costs, estimated before anything is allocated, and the one bound every entry point checks.

Every public call that allocates or loops in proportion to the user's numbers — ``tumble.integrate``,
``propagate``, ``run_ensemble``, ``sampling.perturbed_spins`` and ``perturbed_states``, ``tumble.measure``,
``scan`` and a study (``tumble run``, ``run_study``) — estimates its :class:`Cost` first and passes it to
:func:`check` (through :func:`refuse`, which names the arguments that set the size): a run past a bound is a
:class:`TooLarge` (a ``ValueError``; exit 2 on the command line) with the estimate in its message, within a second.
The module sits in the engine, the lowest layer that needs it; ``measure`` and ``pipeline`` use it from here.

The time figures are rough (within a factor of a few); throughputs are this project's measurements on a 2-core
AVX2 machine (``benchmarks/results/engine.md``, ``closed_form.md``, ``attitude.md``). The bound on time counts every
kind of work in proportion to the samples — fixed steps, closed-form evaluations, the attitude, the fits — so that a
study of closed-form scenes (no steps at all) that would run for days is refused as a stepping one is (issue 44).
The memory of a study is modelled from measured peaks (:func:`tumble.pipeline.runner.study_cost`;
``tests/test_memory.py`` holds it within 1.5x of the peak resident memory of a run above an idle ``import tumble``).
"""

import functools
import math
import os
from typing import NamedTuple

__all__ = ["ATTITUDE_COST", "BYTES_PER_SAMPLE", "MAX_DEVICE_SAMPLE_STEPS", "MAX_SAMPLE_STEPS", "MAX_SCENES",
           "MAX_SECONDS", "RUN_FOOTPRINT", "Cost", "TooLarge", "check", "describe", "most_workers", "physical_memory",
           "refuse", "run_cost", "scene_cost"]

#: Bytes held per sample of a scene while it is measured (the state, the observers' arrays, the per-sample
#: results of the fits and the flips; measured with ``benchmarks/engine.py``'s memory part: 594 MiB for a
#: million-sample rk4 scene, a quarter of it numpy's temporaries).
BYTES_PER_SAMPLE = 640

#: More scenes than this in one study are refused (each scene costs ~10 ms of fixed work: hours per million).
MAX_SCENES = 1_000_000

#: More sample-steps than this are refused: about an hour at the ~3e8 sample-steps/s of rk4 on 2 AVX2 cores (a run of
#: more is a batch job: cut it into studies that checkpoint, or use fewer samples or a larger step).
MAX_SAMPLE_STEPS = 1e12

#: The same bound for a run on a CUDA device (``device="cuda"``): about an hour at the ~3e11 sample-steps/s of rk4 on
#: one H100/H200-class GPU (the issue-28 measurement of a plain kernel; not yet measured through tumble).
MAX_DEVICE_SAMPLE_STEPS = 1e15

#: Bytes a study's run holds whatever its size, above an idle ``import tumble``: the kernels loaded from numba's
#: cache, netCDF and xarray at work (measured with a warm cache: 51 MB for studies of 64 samples, closed form or rk4,
#: 2 cores, 2026-12-06; ``tests/test_memory.py`` holds the estimate within 1.5x of five study shapes' peaks).
RUN_FOOTPRINT = 52e6

#: Bytes one local dask worker process holds before it runs anything (an ``import tumble`` and dask's own, measured
#: ~200 MB), and the most such processes per core: more only compete for the cores.
WORKER_FOOTPRINT = 200e6
WORKERS_PER_CORE = 4

#: Bytes per sample of one engine run besides what it stores: the state, its copy and the status.
_BYTES_PER_STATE = 64

#: The share of this machine's memory a run may plan to use.
MEMORY_SHARE = 0.5

#: Throughputs for the time estimate, on 2 cores: fixed-step sample-steps/s (rk4); closed-form evaluations (one sample
#: at one time) per second (2.0e8 measured, ``closed_form.md``) and samples drawn and set up for them per second; the
#: fits' sample-times per second (the phase and growth fits of a closed-form scene took as long as its evaluations,
#: profiled: the bound takes half their rate); and the fixed cost of a scene (planning, summaries, dataset), s.
_STEPS_PER_SECOND = 3e8
_EXACT_PER_SECOND = 2e8
_SETUP_PER_SECOND = 2e6
_FITS_PER_SECOND = 1e8
_SCENE_SECONDS = 0.03

#: How much more the same steps or closed-form evaluations cost with the attitude carried (measured 2.4x for the
#: implicit midpoint to 29x for rk8 and 27x for the closed form, ``benchmarks/results/attitude.md``): the largest.
ATTITUDE_COST = 30.0

#: More seconds of work than this on 2 cores (steps, closed-form evaluations, attitude and fits; the fixed cost of each
#: scene is :data:`MAX_SCENES`' business) are refused: the hour :data:`MAX_SAMPLE_STEPS` stands for. On a CUDA device
#: the bound is the device's, :data:`MAX_DEVICE_SAMPLE_STEPS` / :data:`MAX_SAMPLE_STEPS` times larger.
MAX_SECONDS = MAX_SAMPLE_STEPS / _STEPS_PER_SECOND


class Cost(NamedTuple):
    """The estimated size of a run."""

    scenes: int
    samples: int  # per scene
    sample_steps: float  # fixed steps over all samples and scenes (0 on the closed-form path)
    peak_bytes: float
    seconds: float  # all of it on 2 cores: the work below and each scene's fixed cost
    evaluations: float = 0.0  # closed-form evaluations (one sample at one time) over all samples and scenes
    work_seconds: float = 0.0  # the work in proportion to the samples on 2 cores: steps, evaluations, attitude, fits


@functools.lru_cache(maxsize=1)
def physical_memory():
    """This machine's physical memory, bytes (0 where the system does not say); asked once per process (a scan
    checks the bound for every scene it plans)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def scene_cost(samples, steps, *, scenes=1, kept_per_sample=0, working=None, times=1, fits=False, attitude=False):
    # size: the factors of a run's cost, each a keyword the doors fill from what they know
    """:class:`Cost` of ``scenes`` scenes of ``samples`` samples and ``steps`` fixed steps each (0: closed
    form, evaluated at ``times`` times), keeping ``kept_per_sample`` bytes per sample and scene in the result
    (per-sample arrays); ``working`` is the largest working set held at once, bytes (default ``samples *
    BYTES_PER_SAMPLE``). ``fits``: each sample's growth or phase is fitted over its ``times`` observations;
    ``attitude``: the attitude is carried along (:data:`ATTITUDE_COST` times the steps or evaluations)."""
    sample_steps = float(scenes) * float(samples) * float(steps)
    working = float(samples) * BYTES_PER_SAMPLE if working is None else float(working)
    peak = working + float(scenes) * float(samples) * kept_per_sample + scenes * 4096.0
    evaluations = 0.0 if steps else float(scenes) * float(samples) * float(times)
    work = (sample_steps / _STEPS_PER_SECOND + evaluations / _EXACT_PER_SECOND
            + (0.0 if steps else float(scenes) * float(samples) / _SETUP_PER_SECOND))
    work *= ATTITUDE_COST if attitude else 1.0
    if fits:
        work += float(scenes) * float(samples) * float(times) / _FITS_PER_SECOND
    return Cost(int(scenes), int(samples), sample_steps, peak, work + scenes * _SCENE_SECONDS, evaluations, work)


def run_cost(samples, steps, stored=0, *, times=1, attitude=False):
    """:class:`Cost` of one engine run: ``samples`` spins over ``steps`` fixed steps (0: the closed form, evaluated at
    ``times`` times), each keeping ``stored`` float64 values (a trajectory, probes, flip times) for the whole run;
    ``attitude``: the attitude is carried too."""
    return scene_cost(samples, steps, working=float(samples) * (_BYTES_PER_STATE + 8.0 * float(stored)), times=times,
                      attitude=attitude)


def refuse(estimate, what, device="cpu"):
    """:func:`check` ``estimate`` (of a run on ``device``); a refusal's message starts with ``what``: the arguments,
    as the caller named them, that set the size (``"w0 (10 spins) over t_end / dt = 1e+14 steps"``)."""
    try:
        return check(estimate, device)
    except TooLarge as err:
        raise TooLarge(err.bound, f"{what}: {err}") from None


def most_workers():
    """The most local worker processes this machine can hold: :data:`WORKERS_PER_CORE` per core, and their
    :data:`WORKER_FOOTPRINT` within :data:`MEMORY_SHARE` of its memory."""
    cores = os.cpu_count() or 1
    memory = physical_memory()
    by_memory = int(MEMORY_SHARE * memory // WORKER_FOOTPRINT) if memory else cores * WORKERS_PER_CORE
    return max(1, min(cores * WORKERS_PER_CORE, by_memory))


def _size(n_bytes):
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n_bytes < 1000 or unit == "PB":
            return f"{n_bytes:.3g} {unit}"
        n_bytes /= 1000.0
    return f"{n_bytes:.3g} PB"  # pragma: no cover


def _duration(seconds):
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.2g} s"


def describe(cost):
    """One line: scenes, sample-steps (and closed-form evaluations, if any), peak memory, a rough time on a 2-core
    machine."""
    evaluations = f"{cost.evaluations:.3g} closed-form evaluations, " if cost.evaluations else ""
    return (f"{cost.scenes:,} scene(s) of {cost.samples:,} samples, {cost.sample_steps:.3g} sample-steps, {evaluations}"
            f"peak memory ~{_size(cost.peak_bytes)}, roughly {_duration(cost.seconds)} on 2 cores")


class TooLarge(ValueError):
    """A run past a bound; ``bound`` is ``"scenes"``, ``"steps"``, ``"memory"``, ``"time"`` or ``"size"``."""

    def __init__(self, bound, message):
        super().__init__(message)
        self.bound = bound


def check(cost, device="cpu"):
    """Refuse a run that cannot fit or would not end: :class:`TooLarge` with the estimate and the bound. The bound on
    sample-steps is :data:`MAX_SAMPLE_STEPS` on the CPU, :data:`MAX_DEVICE_SAMPLE_STEPS` on ``device="cuda"``; the
    bound on time (:data:`MAX_SECONDS`, the device's as many times larger) counts the closed form's evaluations, the
    attitude and the fits besides the steps."""
    memory = physical_memory()
    most_steps = MAX_DEVICE_SAMPLE_STEPS if device == "cuda" else MAX_SAMPLE_STEPS
    most_seconds = MAX_SECONDS * most_steps / MAX_SAMPLE_STEPS
    if cost.scenes > MAX_SCENES:
        raise TooLarge("scenes", f"{cost.scenes:,} scenes is more than the {MAX_SCENES:,} a study may hold "
                         f"({describe(cost)}); split the scan")
    if cost.sample_steps > most_steps:
        raise TooLarge("steps", f"{cost.sample_steps:.3g} sample-steps is more than the {most_steps:.0e} a run may "
                         f"take ({describe(cost)}); use fewer samples, a larger step or a shorter horizon")
    if memory and cost.peak_bytes > MEMORY_SHARE * memory:
        raise TooLarge("memory", f"needs ~{_size(cost.peak_bytes)} of memory, more than half of this machine's "
                         f"{_size(memory)} ({describe(cost)}); use fewer samples or keep fewer per-sample arrays")
    if cost.work_seconds > most_seconds:
        raise TooLarge("time", f"needs roughly {_duration(cost.work_seconds)} of work on 2 cores (fixed steps, "
                         f"closed-form evaluations, attitude and fits), more than the {_duration(most_seconds)} a run "
                         f"may take {'on the device ' if device == 'cuda' else ''}({describe(cost)}); use fewer "
                         f"samples or scenes, a shorter horizon, or cut the work into several runs (a scan into "
                         f"several studies)")
    if not math.isfinite(cost.seconds):
        raise TooLarge("size", f"the run's size is not finite ({describe(cost)})")
    return cost
