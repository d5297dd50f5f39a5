"""A system given by its rate ``rate(t, y, p, dydt)``: one per-sample time loop for the CPU and the CUDA device.

A user's system (:class:`tumble.System`) is plain Python that numba compiles: ``rate(t, y, p, dydt)`` writes the
time derivative of the state ``y`` (float64, shape (n,)) at time ``t`` into ``dydt`` (n,), with the parameters ``p``
(float64, shape (k,)). Its kernels are made here, once per (rate, method):

* :func:`make_step`: one explicit Runge–Kutta step of a sample from a Butcher tableau of
  :mod:`tumble.kernels.tableaux` (the coefficients are data: any tableau runs, with the time of each stage
  ``t + c_s h`` passed to the rate, so a rate may depend on time);
* :func:`make_sample_loop`: the per-sample time loop — steps, the state stored every ``save_every`` steps, the
  non-finite check after every step, the early stop of a sample that became non-finite (it keeps the state it had
  when it was caught and its later stores repeat it), its status and the steps it took. Written once: the CPU's
  driver (:func:`make_cpu_driver`, a share of the samples per thread) and the device's (:mod:`tumble.kernels.cuda.rate_loop`, one
  thread per sample) both call it.

The kernels are closures over the user's function, so numba compiles them in each new process (its disk cache
cannot key a closure over another function: numba issue #6264) — a few seconds on the first call.
"""

import inspect
import math
import os
import re

import numpy as np
from numba import types
from numba.core.errors import NumbaError

from ...registry import STATUS_NONFINITE, STATUS_OK
from ..jit import jit, keyed_copy
from ..threads import in_shares

__all__ = ["JACOBIAN_SIGNATURE", "RATE_SIGNATURE", "combine", "compile_function", "make_cpu_driver", "make_sample_loop",
           "make_step", "saved_count"]

_VECTOR = types.Array(types.float64, 1, "C")

#: ``rate(t, y, p, dydt)`` as the loop calls it: time, state, parameters, derivative (float64, C-contiguous).
RATE_SIGNATURE = (types.float64, _VECTOR, _VECTOR, _VECTOR)

#: ``jacobian(t, y, p, J)``, ``J`` (n, n) C-contiguous.
JACOBIAN_SIGNATURE = (types.float64, _VECTOR, _VECTOR, types.Array(types.float64, 2, "C"))

_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _reason(err):
    """The line of a numba error that says what is wrong (not its "Failed in nopython mode pipeline" heading), and
    where, as one line."""
    lines = [_ANSI.sub("", line).strip() for line in str(err).splitlines()]
    lines = [line for line in lines if line and not line.startswith(("Failed in ", "During: ", "^"))]
    what = next((line for line in lines if not line.startswith("File ")), "numba could not type it")
    where = next((line for line in lines if line.startswith("File ")), "")
    match = re.match(r'File "([^"]+)", line (\d+)', where)
    return f"{what} ({match.group(1).rsplit('/', 1)[-1]}, line {match.group(2)})" if match else what


def compile_function(fn, signature, owner, what, boundscheck=False):
    """``fn`` (plain Python, or a numba function: its Python source is compiled again with tumble's options)
    compiled in nopython mode for ``signature``; with ``boundscheck`` an index out of bounds raises ``IndexError`` (for
    one checking call).

    Kept in numba's disk cache (beside ``fn``'s file, or in ``NUMBA_CACHE_DIR``) where ``fn`` comes from a file and what
    it computes can be keyed
    (:func:`tumble.kernels.steps.system_steps.functions_key`: its source and what it reads), under its name with that
    key appended (a copy of ``fn``: numba names its cache files by the qualified name and does not key them by the
    globals read), so that a new process loads it; else compiled in each process.

    Raises
    ------
    ValueError
        numba cannot compile it: one line, ``"{owner}: numba cannot compile {what} in nopython mode: {reason}
        ({file}, line {n})"``, never numba's traceback; or it takes another number of arguments than
        ``signature``.
    """
    from ..steps.system_steps import functions_key  # (system_steps imports the loops)

    source = getattr(fn, "py_func", fn)
    code = getattr(source, "__code__", None)
    if code is None or code.co_argcount != len(signature) or code.co_flags & (inspect.CO_VARARGS |
                                                                                  inspect.CO_VARKEYWORDS):
        takes = "is not a Python function" if code is None else f"takes {code.co_argcount} positional argument(s)"
        raise ValueError(f"{owner}: {what} must be a function of {len(signature)} arguments; it {takes}")
    # numba keeps a function's cache beside its file: one typed at a prompt or in a doctest has none
    key = functions_key(source) if os.path.isfile(source.__code__.co_filename) else None
    if key is not None:
        source = keyed_copy(source, source.__globals__, f"{key}{'_checked' if boundscheck else ''}")
    dispatcher = jit(source, cache=key is not None, boundscheck=boundscheck)
    try:
        dispatcher.compile(signature)
    except NumbaError as err:
        raise ValueError(f"{owner}: numba cannot compile {what} in nopython mode: {_reason(err)}") from None
    except (AttributeError, NameError, TypeError) as err:  # raised from numba's passes by the function's own code
        raise ValueError(f"{owner}: numba cannot compile {what} in nopython mode: {type(err).__name__}: "
                         f"{str(err).splitlines()[0] if str(err) else ''}") from None
    return dispatcher


def saved_count(n_steps, save_every):
    """States a run stores: the initial one, every ``save_every``-th and the final one (0 when ``save_every`` is 0)."""
    if save_every <= 0:
        return 0
    return 1 + n_steps // save_every + (1 if n_steps % save_every else 0)


def make_step(rate, tableau):
    """``step(t, y, p, h, scratch)``: advance one sample's state ``y`` (n,) in place by one step ``h`` of the
    explicit Runge–Kutta method ``tableau`` (:class:`tumble.kernels.tableaux.ButcherTableau`) of ``rate``.

    ``scratch`` (at least s + 1, n), owned by the caller (``s`` the tableau's stages): its rows ``0..s-1`` take the
    stages' rates, row ``s`` the stage's state; the step allocates nothing. A zero coefficient is skipped."""
    a, b, c = tableau.A.copy(), tableau.b.copy(), tableau.c.copy()
    stages = len(b)

    @jit(cache=False)
    def step(t, y, p, h, scratch):
        n = y.shape[0]
        k = scratch
        stage = scratch[stages]
        for s in range(stages):
            for j in range(n):
                stage[j] = y[j]
            for r in range(s):
                if a[s, r] != 0.0:
                    weight = h * a[s, r]
                    for j in range(n):
                        stage[j] += weight * k[r, j]
            rate(t + c[s] * h, stage, p, k[s])
        combine(y, h, b, k)

    return step


@jit(inline=True)
def combine(y, h, b, k):
    """``y += h sum_s b[s] k[s]``, a zero weight skipped: the end of an explicit Runge–Kutta step of the components
    ``y`` (n,) from their stage rates ``k`` (at least s rows, n) (:func:`make_step`, and the tangent flow's step of
    :mod:`tumble.kernels.loops.tangent_loop`)."""
    for j in range(y.shape[0]):
        total = 0.0
        for s in range(b.shape[0]):
            if b[s] != 0.0:
                total += b[s] * k[s, j]
        y[j] += h * total


def make_sample_loop(step):
    """``run_sample(i, y, p, t0, h, n_steps, save_every, saved, scratch) -> (status, steps taken)``: sample ``i``'s
    whole run (``scratch``: (s + 2, n), the step's rows and one more for the state before each step).

    ``y`` (n,) is the sample's state, advanced in place (its own scratch copy: the caller copies it in and out);
    ``saved`` (N, n_saved, n) the stores of every sample (``n_saved = 0``: none), of which the loop writes row ``i``:
    the initial state, every ``save_every``-th step and the final one (:func:`saved_count`). A state that is not
    finite (checked before the first step and after every step) stops the sample with ``STATUS_NONFINITE``: it keeps
    the state it had then, and its remaining stores repeat it."""

    @jit(cache=False)
    def run_sample(i, y, p, t0, h, n_steps, save_every, saved, scratch):
        n = y.shape[0]
        before = scratch[scratch.shape[0] - 1]
        store = saved.shape[1] > 0
        code = STATUS_OK
        for j in range(n):
            if not math.isfinite(y[j]):
                code = STATUS_NONFINITE
        slot = 0
        if store:
            for j in range(n):
                saved[i, 0, j] = y[j]
            slot = 1
        ran = 0
        for s in range(n_steps):
            if code == STATUS_OK:
                for j in range(n):
                    before[j] = y[j]  # kept if the step is not finite
                step(t0 + s * h, y, p, h, scratch)
                finite = True
                for j in range(n):
                    finite = finite and math.isfinite(y[j])
                if finite:
                    ran = s + 1
                else:
                    code = STATUS_NONFINITE
                    for j in range(n):
                        y[j] = before[j]
            elif not store:
                break  # nothing left to store: the stopped sample's state is final
            if store and ((s + 1) % save_every == 0 or s + 1 == n_steps):
                for j in range(n):
                    saved[i, slot, j] = y[j]
                slot += 1
        return code, ran

    return run_sample


def make_cpu_driver(run_sample, stages):
    """``drive(y, p, t0, h, n_steps, save_every, saved, status, steps_taken)``: every sample of ``y`` (N, n) run by
    ``run_sample``, ``y`` overwritten with the final (or frozen) states, ``status`` (N,) int8 and ``steps_taken``
    (N,) int64 written. ``stages``: the method's number of stages (the scratch has two rows more).

    The samples are cut into one contiguous share per numba thread, each run by a serial loop that releases the GIL
    on a thread of its own (:func:`tumble.kernels.threads.in_shares`, the parallelism of every CPU driver)."""

    @jit(cache=False)
    def run_share(y, p, t0, h, n_steps, save_every, saved, status, steps_taken):
        n_samples, n = y.shape
        state = np.empty(n)
        scratch = np.empty((stages + 2, n))
        for i in range(n_samples):
            state[:] = y[i]
            code, ran = run_sample(i, state, p, t0, h, n_steps, save_every, saved, scratch)
            y[i] = state
            status[i] = code
            steps_taken[i] = ran

    def drive(y, p, t0, h, n_steps, save_every, saved, status, steps_taken):
        in_shares(run_share, len(y), lambda lo, hi: (y[lo:hi], p, t0, h, n_steps, save_every, saved[lo:hi],
                                                     status[lo:hi], steps_taken[lo:hi]))

    return drive
