"""Compile the kernels a run needs side by side, one process per core, when numba's cache does not hold them yet.

numba compiles one function at a time in one process (its compiler lock), and the closed form's set-up and its
evaluation's rows take about 2 s and 0.5-1.5 s a regime to compile on the first run after an install (2 cores,
AVX-512); on two cores they compile in the time of the longer. Each job below compiles one kernel for the exact
signature a run calls it with, in this process or in a worker process that writes numba's on-disk cache; the run
itself then loads them from the cache. With a warm cache nothing is started: whether a kernel is cached is read off
the cache's index file (numba's own locator, ``NUMBA_CACHE_DIR`` included), a file test per kernel.

Nothing here changes a result: a kernel a job did not compile (a signature that drifted from the run's, a cache
that cannot be written, a worker that failed) is compiled by the run as it would have been, only later.
``tests/test_latency.py`` holds that the jobs' signatures are those the runs call.
"""

import os
import subprocess
import sys

import numba
from numba import types

from .closed_form import elliptic, elliptic_attitude
from . import fits


def _array(dtype, ndim, readonly=False):
    return types.Array(dtype, ndim, "C", readonly=readonly)


_F1, _F2, _F3 = (_array(types.float64, n) for n in (1, 2, 3))
_I1, _I2 = (_array(types.int64, n) for n in (1, 2))
_CODES = _array(types.int8, 1)
_SHARE = (types.int64, types.int64)  # start, stop: the share of samples (tumble.kernels.threads.in_parallel)

# Each job: a kernel, the signature a run calls it with, and about how many seconds it takes to compile alone (2 cores,
# AVX-512, an empty cache: what compile_side_by_side balances the processes by).
_SET_UP = ("elliptic.torque_free_solve_share", (_F2, _F2, _F2, _I2, _F1, _F2, _I1, _F2, _I2, _F2, _F2, *_SHARE), 1.7)
#: The evaluation, a kernel per regime (:func:`tumble.kernels.closed_form.elliptic.torque_free_omega`): a run compiles
#: those of the regimes its samples meet.
ROWS = {
    "landen": ("elliptic.omega_landen_share", (_I1, _F2, _I2, _F1, _F1, _F1, _F1, _F2, _I1, _F3, *_SHARE), 0.9),
    "hyperbolic": ("elliptic.omega_hyperbolic_share", (_I1, _F2, _I2, _F1, _F1, _F2, _F1, _F1, _F2, _I1, _F3, *_SHARE),
                   1.3),
    "separatrix": ("elliptic.omega_separatrix_share", (_I1, _F2, _I2, _F1, _F1, _F2, _I1, _F3, *_SHARE), 0.5),
}

#: The kernels a closed-form scene's run compiles (``tumble.physics.exact``, ``tumble.measure``) beside the rows, by the
#: scene's kind: name, signature and seconds (see above).
CLOSED_FORM = {
    "exponential": (_SET_UP, ("fits.transverse_norms_share", (_F3, _I2, _F2, _F2, *_SHARE), 0.15),
                    ("fits.growth_fit_share", (_F2, _I1, _F2, _array(types.float64, 1, readonly=True), types.int64, _F1,
                                               _I1, _CODES, *_SHARE), 0.3)),
    "periodic": (_SET_UP, ("fits.phase_fit_share", (_F2, _I1, _F3, _I2, _array(types.float64, 2, readonly=True),
                                                   _F1, types.float64, _F1, _F1, _CODES, *_SHARE), 2.1)),
    "neutral": (_SET_UP,),  # a degenerate axis: no rate to fit
    "grid": (_SET_UP,),  # exact.omega on a time grid, tumble check
}

#: The closed form's attitude (:func:`tumble.physics.exact.attitude`): its rows and its set-up, added to a list of
#: :data:`CLOSED_FORM` where a run draws an attitude.
ATTITUDE = (("elliptic_attitude.attitude_rows_share", (_F2, _F2, _F2, _F1, _F3, _F3, *_SHARE), 2.4),
            ("elliptic_attitude.attitude_setup", (_F2, _F2, _I1, _F2, _I2, _F1, _F1, _F1, _F1, _F2, _F2, _F2, _F2), 3.3))

_MODULES = {"elliptic": elliptic, "elliptic_attitude": elliptic_attitude, "fits": fits}


def _dispatcher(name):
    module, function = name.split(".")
    return getattr(_MODULES[module], function)


def is_cached(name, signature=None):
    """Whether numba's on-disk cache holds an index for kernel ``name`` (and, given ``signature``, that signature is
    compiled in this process or indexed there: the index lists its signatures, the test is the file's presence only).

    Reads numba's cache object (``Dispatcher._cache``, not public API): where it is not as expected, the answer is
    True, so that nothing is started on a doubt.
    """
    dispatcher = _dispatcher(name)
    if signature is not None and tuple(signature) in dispatcher.overloads:
        return True
    try:
        return os.path.exists(dispatcher._cache._cache_file._index_path)
    except AttributeError:
        return True


#: About how many seconds later than this process a worker starts compiling: a new interpreter, its imports and
#: numba's target set-up.
WORKER_START = 0.7


def deal(jobs, workers):
    """The names of ``jobs`` (as in :data:`CLOSED_FORM`) dealt out to ``workers`` processes, this one first: the
    longest first, each to the process that would finish it soonest (a worker starts :data:`WORKER_START` late)."""
    ends = [0.0] + [WORKER_START] * (workers - 1)
    shares = [[] for _ in range(workers)]
    for name, _, seconds in sorted(jobs, key=lambda job: -job[2]):
        k = min(range(workers), key=lambda k: ends[k] + seconds)
        ends[k] += seconds
        shares[k].append(name)
    return shares


def compile_side_by_side(jobs, workers=None):
    """Compile the kernels of ``jobs`` (a list of :data:`CLOSED_FORM`, perhaps with :data:`ATTITUDE`: names,
    signatures and seconds) that are not cached, this process and worker processes at once; returns the names
    compiled.

    ``workers`` defaults to numba's thread count: the cores tumble may use (1 where a user or the test suite limits
    numba to one thread, and then nothing is started). Does nothing when fewer than two are cold. The cold kernels are
    dealt out (:func:`deal`) to this process and to new interpreters (``python -m tumble.kernels.side_by_side NAME
    ...``: a plain subprocess, so a user's script is never imported again, as ``multiprocessing`` would, and no thread
    of this process is forked); this process compiles its share, then waits for the workers, whose kernels the run
    loads from the cache. A worker that fails leaves its kernels to the run.
    """
    cold = [job for job in jobs if not is_cached(*job[:2])]
    workers = min(len(cold), workers or numba.get_num_threads())
    if len(cold) < 2 or workers < 2:
        return []
    mine, *theirs = deal(cold, workers)
    started = [subprocess.Popen([sys.executable, "-m", __name__, *share], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for share in theirs if share]
    try:
        _compile(mine)
        for process in started:
            process.wait()
    finally:
        for process in started:  # Ctrl-C or an error here: no worker outlives the run
            if process.poll() is None:
                process.kill()
                process.wait()
    return [name for name, signature, _ in cold if name in mine or is_cached(name, signature)]


def _compile(names):
    for name in names:
        _dispatcher(name).compile(_SIGNATURES[name])  # cache=True: numba writes it to its cache


_SIGNATURES = {name: signature for jobs in (*CLOSED_FORM.values(), ATTITUDE, ROWS.values())
               for name, signature, _ in jobs}

if __name__ == "__main__":
    _compile(sys.argv[1:])
