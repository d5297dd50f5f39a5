"""The tangent flow of the built-in models and of a user's System on the CPU, a block of samples at a time
(vectorised across samples).

The same run as :mod:`tumble.kernels.loops.tangent_loop`'s per-sample loop (a state, ``k`` tangent vectors and MEGNO's two
scalars per sample; modified Gram–Schmidt every ``every`` steps, at the transient, at each saved step and at the end;
``log |R_rr|`` summed after the transient; MEGNO's least-squares slope; the same statuses, stops and outputs), laid out
for SIMD lanes: a block's samples are the columns of ``Z`` (k, 2 n + 2, m), and one generated step per system and
method (:data:`tumble.kernels.steps.model_steps.TANGENT_STEPS`, rk4 or rk8 with the system's rate and tangent spelled out;
for the Lie–Poisson models' splittings, their sub-flows each looped over the block:
:func:`tumble.kernels.steps.model_splittings.splitting_tangent_block`; a user's System's, generated from its rewritten rate
and Jacobian: :mod:`tumble.kernels.steps.system_steps`) moves them all at once. The per-sample loop stays the path of a
System without a scalar form, of a tableau added at run time, of the implicit midpoint rule and of the device (one
thread per sample); this one is the CPU's: the heavy
top's MEGNO, rk4, 2000 samples, 6.6e7 sample-steps/s against the per-sample loop's 2.7e6 (24 times; 2 cores, AVX2,
2026-11-28; the whole map: ``benchmarks/chaos.py``).

**One compiled driver per (system, method).** :func:`make_propagate_tangents`'s driver holds the model's and the
method's codes as constants of its closure, and passes them to the loop as literal values: each pair compiles (once,
then from the disk cache) a driver with its one step in it (:func:`_tangent_step`).

**Checks.** The running samples of a block are screened for values that are not finite, branch-free, every
:data:`CHECK_EVERY` steps and at every factorisation (where a tangent vector that collapsed is caught too); the block
is kept then. A sample caught stops with the values of the last check before (the per-sample loop keeps those of the
step before: here that would cost a copy of the block every step); a sample whose ``<Y>`` passes ``stop_above``
stops after that step. A stopped sample's outputs are written when it stops; its columns go on stepping with the
others (their values unused) until every sample of the block has stopped. Samples never interact, and each column's
arithmetic is the per-sample loop's, so results match it to round-off (``tests/test_tangent_blocks.py``).
"""

import math

import numpy as np
from numba import types
from numba.extending import overload

from ...registry import LIE_POISSON_MODELS, MODEL_STEPPING, STATUS_ABOVE, STATUS_NONFINITE, STATUS_OK, STEPPING
from ..jit import FASTMATH, jit, subroutine
from ..threads import in_parallel
from ..steps.model_splittings import GRAVITY_CODE, SPLITTINGS, splitting_tangent_block
from ..steps.model_steps import TANGENT_STEPS
from ..steps.system_steps import SYSTEM_CODES, cacheable, tangent_step
from ..tableaux import TABLEAUX
from .tangent_loop import orthonormalise_row
from ..trig import _min

__all__ = ["BLOCK", "CHECK_EVERY", "METHODS", "make_propagate_tangents", "run", "runs"]

#: The methods with generated tangent steps, name -> (the tableau they were generated from, kernel id): the models'
#: explicit Runge–Kutta methods (a tableau replaced at run time under one of these names is not theirs). The
#: Lie–Poisson models' splittings (:data:`tumble.kernels.steps.model_splittings.SPLITTINGS`) run here too.
METHODS = {name: (TABLEAUX[name], STEPPING.index(name)) for name in MODEL_STEPPING if name in TABLEAUX}

#: Steps between two checks for values that are not finite (and at every factorisation): a sample caught keeps its
#: values of the check before.
CHECK_EVERY = 32

#: Samples per block: ``Z`` of a heavy top with one tangent vector, 14 rows x 256 x 8 bytes, and its copy stay in
#: the core's L2 cache. Results do not depend on it.
BLOCK = 256


def _tangent_step(model, method, Z, t, t0, h, a):
    """One step of every sample of a block with its tangent vectors and MEGNO's scalars (``Z`` as
    :func:`_run_block` holds it): the generated step of ``(model, method)``
    (:data:`tumble.kernels.steps.model_steps.TANGENT_STEPS`), chosen when the caller is compiled."""


@overload(_tangent_step, inline="always", jit_options=dict(fastmath=set(FASTMATH), error_model="numpy"))
def _tangent_step_of(model, method, Z, t, t0, h, a):
    """The model's and the method's codes are literal types (constants of :func:`make_propagate_tangents`): each pair
    compiles its own driver, with its one step in it, and is cached as such (a chain of branches over every system and
    method compiled all of them into one driver: 150 s on 2 cores, measured)."""
    if not (isinstance(model, types.IntegerLiteral) and isinstance(method, types.IntegerLiteral)):
        return None
    code, method_id = model.literal_value, method.literal_value
    if method_id in SPLITTINGS.values():  # the sub-flows' loops over the block (model_splittings)
        top = code == GRAVITY_CODE

        def splitting_step(model, method, Z, t, t0, h, a):
            splitting_tangent_block(method_id, top, Z, t, t0, h, a)

        return splitting_step
    step = tangent_step(code, method_id) if code >= SYSTEM_CODES else TANGENT_STEPS[code, method_id]

    def generated_step(model, method, Z, t, t0, h, a):
        step(Z, t, t0, h, a)

    return generated_step


def runs(method, kind):
    """Whether :func:`run` runs ``method`` for model ``kind``: rk4 or rk8 (the tableau of that name now is the one its
    steps were generated from), or a splitting of a Lie–Poisson model."""
    if method in SPLITTINGS:
        return kind in LIE_POISSON_MODELS
    return method in METHODS and TABLEAUX[method] is METHODS[method][0]


@subroutine
def _screen(Z, live, flags):
    """How many running samples of a block hold a value that is not finite (the state and MEGNO's scalars of ``Z[0]``,
    every tangent vector): ``flags`` (m,) gets ``0 × value`` summed over each sample's values (NaN where one is not
    finite), in a branch-free pass that vectorises (component rows outer, samples inner)."""
    k, rows, m = Z.shape
    n = (rows - 2) // 2
    for i in range(m):
        flags[i] = 0.0
    for r in range(k):
        for j in range(0 if r == 0 else n, rows if r == 0 else 2 * n):
            for i in range(m):
                flags[i] += 0.0 * Z[r, j, i]
    bad = 0
    for i in range(m):
        if live[i] and flags[i] != 0.0:
            bad += 1
    return bad


@subroutine
def _share_state(Z):
    """The sample's state (``Z[0]``'s) into the rows that the step of each further tangent vector reads."""
    n = (Z.shape[1] - 2) // 2
    for r in range(1, Z.shape[0]):
        for j in range(n):
            for i in range(Z.shape[2]):
                Z[r, j, i] = Z[0, j, i]


@subroutine
def _copy(Z, to):
    for r in range(Z.shape[0]):
        for j in range(Z.shape[1]):
            for i in range(Z.shape[2]):
                to[r, j, i] = Z[r, j, i]


@subroutine
def _orthonormalise(Z, orthogonalise, norms, proj):
    """Modified Gram–Schmidt of every sample's tangent vectors at once (``V = Q R``; without ``orthogonalise`` each
    vector only normalised): ``norms`` (k, m) gets ``R_rr``; a norm that is 0 or not finite leaves its vector as it
    is (the caller stops the sample). ``proj`` (m,): scratch."""
    k, rows, m = Z.shape
    n = (rows - 2) // 2
    for r in range(k):
        for q in range(r if orthogonalise else 0):
            for i in range(m):
                proj[i] = 0.0
            for j in range(n, 2 * n):
                for i in range(m):
                    proj[i] += Z[q, j, i] * Z[r, j, i]
            for j in range(n, 2 * n):
                for i in range(m):
                    Z[r, j, i] -= proj[i] * Z[q, j, i]
        for i in range(m):
            proj[i] = 0.0
        for j in range(n, 2 * n):
            for i in range(m):
                proj[i] += Z[r, j, i] * Z[r, j, i]
        for i in range(m):
            norm = math.sqrt(proj[i])
            norms[r, i] = norm
            proj[i] = 1.0 / norm if norm > 0.0 and math.isfinite(norm) else 1.0
        for j in range(n, 2 * n):
            for i in range(m):
                Z[r, j, i] *= proj[i]


@subroutine
def _gali(Z, i, vectors):
    """GALI_k of sample ``i``: the volume its k unit tangent vectors span (the product of ``R_rr`` of a Gram–Schmidt of
    a copy, ``vectors`` (k, n))."""
    k, rows, _ = Z.shape
    n = (rows - 2) // 2
    for r in range(k):
        for j in range(n):
            vectors[r, j] = Z[r, n + j, i]
    volume = 1.0
    for r in range(k):
        norm = orthonormalise_row(vectors, r, r)
        volume *= norm
        if norm == 0.0:
            break  # the vectors became dependent (to round-off): GALI is 0 from here
    return volume


@subroutine
def _finish(i, lo, Z, code, ran, h, average, slope, covered, block_logs, y, V, logs, megno, status, steps_taken):
    # size: one sample's outputs, each from where the loop holds it
    """Write sample ``lo + i``'s outputs from the block ``Z`` (the values after its last step): its state and tangent
    vectors, the sums of ``log |R_rr|``, MEGNO's scalars (``<Y>``, ``2 × slope``, the time run, the time the sums
    cover), its status and the steps it took."""
    k, rows, _ = Z.shape
    n = (rows - 2) // 2
    for j in range(n):
        y[lo + i, j] = Z[0, j, i]
    for r in range(k):
        for j in range(n):
            V[lo + i, r, j] = Z[r, n + j, i]
        logs[lo + i, r] = block_logs[r, i]
    megno[lo + i, 0] = average
    megno[lo + i, 1] = slope
    megno[lo + i, 2] = ran * h
    megno[lo + i, 3] = covered
    status[lo + i] = code
    steps_taken[lo + i] = ran


@jit(inline=True)  # into its driver at numba's IR level: its code is generated once, not alone and again there
def _run_block(model, method, a, y, V, lo, m, t0, h, n_steps, every, transient, save_every, stop_above,
               orthogonalise, logs, saved, megno, status, steps_taken):
    # size: the whole run of one block: the model, the plan, the outputs (tangent_loop.make_tangent_loop's arguments)
    """Samples ``lo .. lo + m - 1`` through the whole run (see the module docstring and
    :func:`tumble.kernels.loops.tangent_loop.make_tangent_loop`, whose order of step, factorisation, sums, slope, stores and
    stop this keeps)."""
    n = y.shape[1]
    k = V.shape[1]
    Z = np.zeros((k, 2 * n + 2, m))  # the MEGNO rows of Z[r > 0] too: never stepped from garbage
    kept = np.empty((k, 2 * n + 2, m))  # Z at the last check
    live = np.ones(m, dtype=np.bool_)
    flags = np.empty(m)
    block_logs = np.zeros((k, m))
    norms = np.empty((k, m))
    mean_y = np.zeros(m)  # MEGNO's running least-squares fit, per sample (its times are the block's)
    cov = np.zeros(m)
    kept_mean_y = np.zeros(m)
    kept_cov = np.zeros(m)
    vectors = np.empty((k, n))
    for i in range(m):
        for j in range(n):
            Z[0, j, i] = y[lo + i, j]
        for r in range(k):
            for j in range(n):
                Z[r, n + j, i] = V[lo + i, r, j]
    n_live = m
    for i in range(m):
        finite = True
        for j in range(n):
            finite = finite and math.isfinite(Z[0, j, i])
        if not finite:
            live[i] = False
            n_live -= 1
            # int64 codes and counts, not literals: one compiled variant of _finish
            _finish(i, lo, Z, np.int64(STATUS_NONFINITE), np.int64(0), h, np.nan, np.nan, 0.0, block_logs, y, V, logs,
                    megno, status, steps_taken)
    _copy(Z, kept)
    store = saved.shape[1] > 0
    slot = 0
    count = 0  # the fit's sums shared by the running samples (they have stepped as often)
    mean_t = 0.0
    var = 0.0
    summed = 0
    checked = np.int64(0)  # the step of the last check, and the fit's shared sums then (int64: one _finish)
    kept_count = 0
    kept_var = 0.0
    for s in range(n_steps):
        if n_live == 0:
            break
        if k > 1:
            _share_state(Z)
        _tangent_step(model, method, Z, t0 + s * h, t0, h, a)
        done = s + 1
        factorise = (done == transient or done % every == 0 or done == n_steps
                     or (store and done > transient and done % save_every == 0))
        if factorise:
            _orthonormalise(Z, orthogonalise, norms, flags)
        if factorise or done % CHECK_EVERY == 0:
            # a sample with a value that is not finite, or a tangent vector that collapsed, stops with its values
            # at the last check
            bad = _screen(Z, live, flags)
            if factorise:
                for r in range(k):
                    for i in range(m):
                        if live[i] and not (norms[r, i] > 0.0 and math.isfinite(norms[r, i])):
                            flags[i] = np.nan
                            bad += 1
            if bad:
                slope_scale = 2.0 / kept_var if kept_count > 1 and kept_var > 0.0 else np.nan
                covered = (summed - transient) * h if summed > 0 else 0.0
                for i in range(m):
                    if live[i] and flags[i] != 0.0:
                        live[i] = False
                        n_live -= 1
                        average = kept[0, 2 * n + 1, i] / (checked * h) if checked > 0 else np.nan
                        _finish(i, lo, kept, np.int64(STATUS_NONFINITE), checked, h, average, kept_cov[i] * slope_scale,
                                covered, block_logs, y, V, logs, megno, status, steps_taken)
        if factorise and done > transient:
            for r in range(k):
                for i in range(m):
                    if live[i]:
                        block_logs[r, i] += math.log(norms[r, i])
            summed = done
        elapsed = done * h
        count += 1  # the running least-squares slope of <Y> against t (Welford's updates, as REBOUND's)
        d_t = elapsed - mean_t
        mean_t += d_t / count
        var += d_t * (elapsed - mean_t)
        to_average = 1.0 / elapsed
        to_mean = 1.0 / count
        above = 0
        for i in range(m):
            average = Z[0, 2 * n + 1, i] * to_average
            mean_y[i] += (average - mean_y[i]) * to_mean
            cov[i] += d_t * (average - mean_y[i])
            above += live[i] and average > stop_above
        if factorise or done % CHECK_EVERY == 0:
            _copy(Z, kept)
            for i in range(m):
                kept_mean_y[i] = mean_y[i]
                kept_cov[i] = cov[i]
            checked = done
            kept_count = count
            kept_var = var
        if store and done > transient and (done % save_every == 0 or done == n_steps):
            for i in range(m):
                if live[i]:
                    if orthogonalise:
                        for r in range(k):
                            saved[lo + i, slot, r] = block_logs[r, i] / ((done - transient) * h)
                    else:
                        saved[lo + i, slot, 0] = _gali(Z, i, vectors)
            slot += 1
        if above > 0 or done == n_steps:
            slope_scale = 2.0 / var if count > 1 and var > 0.0 else np.nan
            covered = (summed - transient) * h if summed > 0 else 0.0
            for i in range(m):
                if not live[i]:
                    continue
                average = Z[0, 2 * n + 1, i] * to_average
                code = STATUS_ABOVE if average > stop_above else STATUS_OK
                if code != STATUS_OK or done == n_steps:
                    live[i] = False
                    n_live -= 1
                    _finish(i, lo, Z, code, done, h, average, cov[i] * slope_scale, covered, block_logs, y, V, logs,
                            megno, status, steps_taken)


def make_propagate_tangents(model, method):
    """The driver of ``model``'s and ``method``'s codes, constants of the closure (the step is chosen when it is
    compiled: :func:`_tangent_step`); numba's disk cache tells the closures apart by their constants (a user's System's
    code that keys nothing is not cached: :func:`tumble.kernels.steps.system_steps.cacheable`)."""

    @jit(cache=cacheable(model))
    def propagate_tangents(a, y, V, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs,
                           saved, megno, status, steps_taken, start, stop):
        # size: tangent_loop's driver's arguments, with the model's constants first
        """Every sample of ``y`` (N, n) with its tangent vectors ``V`` (N, k, n) through the whole run, blocks of
        :data:`BLOCK` samples, the share ``start:stop`` of :func:`tumble.kernels.threads.in_parallel`: ``y`` and ``V`` overwritten with the final (or stopped) values,
        ``logs`` (N, k) (zeros in), ``saved`` (N, n_saved, k), ``megno`` (N, 4), ``status`` (N,) int8 and
        ``steps_taken`` (N,) int64 written, as :func:`tumble.kernels.loops.tangent_loop.make_cpu_driver`'s driver. ``a``:
        the model's constants (:func:`tumble.kernels.systems.constants`)."""
        for lo in range(start, stop, BLOCK):
            _run_block(model, method, a, y, V, lo, _min(BLOCK, stop - lo), t0, h, n_steps, every, transient,
                       save_every, stop_above, orthogonalise, logs, saved, megno, status, steps_taken)

    return propagate_tangents


#: The drivers made so far, by (model code, method id); each compiles (or loads) on its first call.
_DRIVERS = {}


def run(model, method, *arguments):
    """The driver of the codes ``model`` (the model's, ``registry.MODEL_KINDS``) and ``method`` (rk4's or rk8's,
    ``registry.STEPPING``) on ``arguments`` (:func:`make_propagate_tangents`'s driver's), made once per pair."""
    driver = _DRIVERS.get((model, method))
    if driver is None:
        driver = _DRIVERS[model, method] = make_propagate_tangents(model, method)
    in_parallel(driver, len(arguments[1]), *arguments, granule=BLOCK)
