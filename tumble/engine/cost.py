"""What a measurement costs, estimated before anything is allocated, and the bounds a run must stay within.

The figures are deliberately rough (within a factor of a few): they exist to refuse, within a second and with
the estimate in the message, what cannot fit in this machine's memory or would run for days, and to let
``tumble run --dry-run`` say what a study will take. Throughputs are this project's measurements on a
2-core AVX2 machine (``benchmarks/results/engine.md``).
"""

import math
import os
from typing import NamedTuple

__all__ = ["BYTES_PER_SAMPLE", "MAX_SAMPLE_STEPS", "MAX_SCENES", "Cost", "TooLarge", "check", "describe",
           "physical_memory", "scene_cost"]

#: Bytes held per sample of a scene while it is measured (the state, the observers' arrays, the per-sample
#: results of the fits and the flips; measured with ``benchmarks/engine.py``'s memory part: 594 MiB for a
#: million-sample rk4 scene, a quarter of it numpy's temporaries).
BYTES_PER_SAMPLE = 640

#: More scenes than this in one study are refused (each scene costs ~10 ms of fixed work: hours per million).
MAX_SCENES = 1_000_000

#: More sample-steps than this are refused (days at the ~3e8 sample-steps/s of rk4 on 2 AVX2 cores).
MAX_SAMPLE_STEPS = 1e14

#: The share of this machine's memory a run may plan to use.
MEMORY_SHARE = 0.5

#: Throughputs for the time estimate: fixed-step sample-steps/s, closed-form sample evaluations/s, and the
#: fixed cost of a scene (planning, fits, summaries, dataset), s.
_STEPS_PER_SECOND = 3e8
_EXACT_PER_SECOND = 2e6
_SCENE_SECONDS = 0.03


class Cost(NamedTuple):
    """The estimated size of a run."""

    scenes: int
    samples: int  # per scene
    sample_steps: float  # fixed steps over all samples and scenes (0 on the closed-form path)
    peak_bytes: float
    seconds: float


def physical_memory():
    """This machine's physical memory, bytes (0 where the system does not say)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 0


def scene_cost(samples, steps, *, scenes=1, kept_per_sample=0):
    """:class:`Cost` of ``scenes`` scenes of ``samples`` samples and ``steps`` fixed steps each (0: closed
    form), keeping ``kept_per_sample`` bytes per sample and scene in the result (per-sample arrays)."""
    sample_steps = float(scenes) * float(samples) * float(steps)
    peak = float(samples) * BYTES_PER_SAMPLE + float(scenes) * float(samples) * kept_per_sample + scenes * 4096.0
    seconds = (sample_steps / _STEPS_PER_SECOND + (0 if steps else float(scenes) * samples / _EXACT_PER_SECOND)
               + scenes * _SCENE_SECONDS)
    return Cost(int(scenes), int(samples), sample_steps, peak, seconds)


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
    """One line: scenes, sample-steps, peak memory, a rough time on a 2-core machine."""
    return (f"{cost.scenes:,} scene(s) of {cost.samples:,} samples, {cost.sample_steps:.3g} sample-steps, "
            f"peak memory ~{_size(cost.peak_bytes)}, roughly {_duration(cost.seconds)} on 2 cores")


class TooLarge(ValueError):
    """A run past a bound; ``bound`` is ``"scenes"``, ``"steps"``, ``"memory"`` or ``"size"``."""

    def __init__(self, bound, message):
        super().__init__(message)
        self.bound = bound


def check(cost):
    """Refuse a run that cannot fit or would not end: :class:`TooLarge` with the estimate and the bound."""
    memory = physical_memory()
    if cost.scenes > MAX_SCENES:
        raise TooLarge("scenes", f"{cost.scenes:,} scenes is more than the {MAX_SCENES:,} a study may hold "
                         f"({describe(cost)}); split the scan")
    if cost.sample_steps > MAX_SAMPLE_STEPS:
        raise TooLarge("steps", f"{cost.sample_steps:.3g} sample-steps is more than the {MAX_SAMPLE_STEPS:.0e} a run may "
                         f"take ({describe(cost)}); use fewer samples, a larger step or a shorter horizon")
    if memory and cost.peak_bytes > MEMORY_SHARE * memory:
        raise TooLarge("memory", f"needs ~{_size(cost.peak_bytes)} of memory, more than half of this machine's "
                         f"{_size(memory)} ({describe(cost)}); use fewer samples or keep fewer per-sample arrays")
    if not math.isfinite(cost.seconds):
        raise TooLarge("size", f"the run's size is not finite ({describe(cost)})")
    return cost
