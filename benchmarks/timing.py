"""What every benchmark here shares: the median of timed runs and the machine line of a report."""

import os
import platform
import time

import numba
import numpy as np


def median_seconds(fn, repeats):
    """Median wall time of ``repeats`` calls of ``fn`` (the caller runs it once first: compile time is apart)."""
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return float(np.median(times))


def machine():
    """``"<processor>, <cores> cores, AVX2 | AVX-512, numba <version>"``: the vector width goes beside every
    throughput figure (machines here differ)."""
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, {vector_width()}, numba {numba.__version__}"


def vector_width():
    """``"AVX-512"`` (8 doubles a register), ``"AVX2"`` (4) or ``"unknown"``: :func:`provenance.vector_width`."""
    import provenance  # benchmarks/provenance.py, beside this file

    return provenance.vector_width()
