"""``tumble warm``: compile the kernels of the common first calls once, ahead of the work that counts, side by side.

numba compiles a kernel at its first call and keeps the machine code in its disk cache (:mod:`tumble.kernels.jit`);
every later call, in that process or a new one, loads it. The first call after an install, an upgrade or on a new
machine therefore pays the compile: on 2 cores (AVX2) about 25 s for ``tumble.integrate`` with rk4 and 20 s for
``tumble.exact.omega`` (``benchmarks/first_call.py`` measures each entry point). :func:`warm` pays it up front: it runs
each entry point's first call with tiny inputs (:data:`CALLS`) in new interpreters, as many at once as numba may use
cores, the longest first, so that they compile side by side and write the cache the user's calls then load.

The warm-up changes no result and needs no input of the user's: a kernel compiles for the types of its arguments,
not their sizes, so a call on one sample warms the call on a million. A job that fails leaves its kernels to be
compiled at their first call, as without it; its error comes back in the report.
"""

import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from typing import NamedTuple

from .registry import AUTO, AUTO_STEPPING, CHOICES

__all__ = ["CALLS", "DEFAULT", "Warmed", "warm"]

_BODY = "body = tumble.Body(1.0, 2.0, 3.0)\nW = np.array([[0.01, 1.0, 0.01]])\n"
_TOP = "top = tumble.models.HeavyTop((1.0, 1.6, 2.2), mgl=1.0)\ny0 = np.array([[0.5, 0.3, 2.0, 0.0, 0.0, 1.0]])\n"


def _integrate(method):
    return (f"tumble.integrate and tumble.propagate with {method}",
            _BODY + f"tumble.integrate(body, W, 0.01, 1e-3, method={method!r})")


#: Name -> (what the call warms, its Python source: ``np`` and ``tumble`` imported), the longest compile first.
CALLS = {
    "integrate": _integrate(AUTO_STEPPING),
    "measure": ("tumble.measure and tumble.scan (the closed form and the growth fit)",
                _BODY + "tumble.measure(body, axis=2, spin=1.0, samples=16)"),
    # a spin of each regime of the evaluation, which compiles a kernel per regime met: near the intermediate axis, near
    # the largest one, and on the separatrix (exactly, for the moments (3, 5, 6): 6 (6 - 5) w3^2 = 3 (5 - 3) w1^2)
    "exact": ("tumble.exact.omega on a grid of times",
              _BODY + "t = np.linspace(0.0, 1.0, 3)\ntumble.exact.omega(body, [[0.01, 1.0, 0.01], [0.01, 0.02, 1.0]], t); "
              "tumble.exact.omega((3.0, 5.0, 6.0), [0.5, 1.0, 0.5], t)"),
    "attitude": ("tumble.exact.attitude", _BODY + "tumble.exact.attitude(body, W, np.linspace(0.0, 1.0, 3))"),
    **{f"integrate-{method}": _integrate(method)
       for method in CHOICES if method not in (AUTO, AUTO_STEPPING)},
    "heavy-top": ("tumble.run_ensemble with a heavy top, rk4", _TOP + "tumble.run_ensemble(top, y0, 0.01, 0.005)"),
    "megno": ("tumble.megno and tumble.lyapunov with a heavy top, rk4",
              _TOP + "tumble.megno(top, y0, t_end=0.1, dt=0.01)"),
}

#: What ``tumble warm`` warms without names: the calls of the Python API's first examples (README, tutorials).
DEFAULT = ("integrate", "measure", "exact")


class Warmed(NamedTuple):
    """One job of :func:`warm`."""

    name: str
    seconds: float
    error: str  # "" when the call ran; else its last line of error output


def _run(name):
    source = "import numpy as np\nimport tumble\n" + CALLS[name][1]
    # one thread: the job's kernels are the same, and measure does not start its own side-by-side compiles
    environment = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", source], env=environment, stdin=subprocess.DEVNULL,
                          capture_output=True, text=True)
    lines = done.stderr.strip().splitlines()
    error = "" if done.returncode == 0 else (lines[-1] if lines else f"exit status {done.returncode}")
    return Warmed(name, time.perf_counter() - start, error)


def warm(names=DEFAULT, workers=None, report=None):
    """Compile the kernels of the calls ``names`` (keys of :data:`CALLS`) into numba's disk cache, ``workers`` new
    interpreters at a time (default: the cores numba may use, ``numba.get_num_threads()``); returns a
    :class:`Warmed` per call, in the order of ``names``. ``report(warmed)`` is called as each job ends.

    Raises
    ------
    ValueError
        A name that is not a key of :data:`CALLS`.
    """
    names = list(dict.fromkeys(names))
    unknown = [name for name in names if name not in CALLS]
    if unknown:
        raise ValueError(f"nothing to warm called {', '.join(map(repr, unknown))}; the calls are "
                         f"{', '.join(CALLS)}")
    if workers is None:
        import numba

        workers = numba.get_num_threads()
    order = sorted(names, key=list(CALLS).index)  # the longest compile first
    results = {}
    with ThreadPoolExecutor(max_workers=max(1, min(int(workers), len(order)))) as pool:
        for job in as_completed([pool.submit(_run, name) for name in order]):
            warmed = job.result()
            results[warmed.name] = warmed
            if report is not None:
                report(warmed)
    return [results[name] for name in names]
