"""Compile the kernels a run needs side by side, one process per core, when numba's cache does not hold them yet.

numba compiles one function at a time in one process (its compiler lock), and the closed form's two big kernels take
about 5 s each on the first run after an install; on two cores they compile in the time of one. Each job below
compiles one kernel for the exact signature a run calls it with, in a worker process that writes numba's on-disk
cache; the run itself then loads them from the cache. With a warm cache nothing is started: whether a kernel is
cached is read off the cache's index file (numba's own locator, ``NUMBA_CACHE_DIR`` included), a file test per kernel.

Nothing here changes a result: a kernel a job did not compile (a signature that drifted from the run's, a cache
that cannot be written, a worker that failed) is compiled by the run as it would have been, only later. A test
(``tests/test_latency.py``) holds that the default study compiles nothing more after :func:`compile_side_by_side`.
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

_SET_UP = ("elliptic.torque_free_solve_share", (_F2, _F2, _F2, _I2, _F1, _F2, _I1, _F2, _I2, _F2, _F2, *_SHARE))
_EVALUATE = ("elliptic.torque_free_omega_share", (_I1, _F2, _I2, _F1, _F1, _F2, _F1, _F1, _F2, _I1, _F3, *_SHARE))

#: Kernel and the signature a closed-form scene calls it with (``tumble.physics.exact``, ``tumble.measure``), by the
#: scene's kind; in the order they are dealt out to the processes (the longest first: on two cores, omega and the
#: norms in one, the set-up and the growth fit in the other, about 6 s each).
CLOSED_FORM = {
    "exponential": (_EVALUATE, _SET_UP, ("fits.transverse_norms_share", (_F3, _I2, _F2, _F2, *_SHARE)),
                    ("fits.growth_fit_share", (_F2, _I1, _F2, _array(types.float64, 1, readonly=True), types.int64, _F1,
                                         _I1, _CODES, *_SHARE))),
    "periodic": (_EVALUATE, _SET_UP, ("fits.phase_fit_share", (_F2, _I1, _F3, _I2, _array(types.float64, 2, readonly=True),
                                                         _F1, types.float64, _F1, _F1, _CODES, *_SHARE))),
    "neutral": (_EVALUATE, _SET_UP),  # a degenerate axis: no rate to fit
    # tumble check: the closed form on a recording's times (the grid kernel, about 10 s to compile; the set-up 3.5 s);
    # with ATTITUDE dealt out on two cores as grid and attitude rows, set-up and attitude set-up
    "grid": (("elliptic.torque_free_omega_grid_share", (_F1, _F2, _F1, _F3, *_SHARE)), _SET_UP),
}

#: The closed form's attitude (:func:`tumble.physics.exact.attitude`): its rows, then its set-up (3.7 s and 0.9 s to
#: compile), appended to a list of :data:`CLOSED_FORM` where a run draws an attitude.
ATTITUDE = (("elliptic_attitude.attitude_rows_share", (_F2, _F2, _F2, _F1, _F3, _F3, *_SHARE)),
            ("elliptic_attitude.attitude_setup", (_F2, _F2, _I1, _F2, _I2, _F1, _F1, _F1, _F1, _F2, _F2, _F2, _F2)))

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


def compile_side_by_side(jobs, workers=None):
    """Compile the kernels of ``jobs`` (a list of :data:`CLOSED_FORM`, perhaps with :data:`ATTITUDE`: names and
    signatures) that are not cached,
    this process and worker processes at once; returns the names compiled.

    ``workers`` defaults to numba's thread count: the cores tumble may use (1 where a user or the test suite limits
    numba to one thread, and then nothing is started). Does nothing when fewer than two are cold. The cold kernels are dealt out in turn
    (the longest first) to this process and to ``workers - 1`` new interpreters (``python -m
    tumble.kernels.side_by_side NAME ...``: a plain subprocess, so a user's script is never imported again, as
    ``multiprocessing`` would, and no thread of this process is forked); this process compiles its share, then waits
    for the workers, whose kernels the run loads from the cache. A worker that fails leaves its kernels to the run.
    """
    cold = [name for name, signature in jobs if not is_cached(name, signature)]
    workers = min(len(cold), workers or numba.get_num_threads())
    if len(cold) < 2 or workers < 2:
        return []
    shares = [cold[k::workers] for k in range(workers)]
    started = [subprocess.Popen([sys.executable, "-m", __name__, *share], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for share in shares[1:]]
    try:
        _compile(shares[0])
        for process in started:
            process.wait()
    finally:
        for process in started:  # Ctrl-C or an error here: no worker outlives the run
            if process.poll() is None:
                process.kill()
                process.wait()
    return [name for name in cold if is_cached(name, _SIGNATURES[name]) or name in shares[0]]


def _compile(names):
    for name in names:
        _dispatcher(name).compile(_SIGNATURES[name])  # cache=True: numba writes it to its cache


_SIGNATURES = {name: signature for jobs in (*CLOSED_FORM.values(), ATTITUDE) for name, signature in jobs}

if __name__ == "__main__":
    _compile(sys.argv[1:])
