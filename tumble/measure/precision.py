"""Work-precision diagrams: run time against error for every tumble integrator and SciPy, in one run.

:func:`work_precision` integrates one ensemble of perturbed spins to ``t_end`` with

* every fixed-step tumble method (:data:`tumble.registry.STEPPING`) over a geometric ladder of step
  counts, each run through :func:`tumble.propagate` (the array API: the final spins, no Dataset, as the
  peers return arrays);
* the closed form (``tumble.propagate(..., method="exact")``, one point);
* SciPy's ``solve_ivp`` (``RK45``, ``DOP853``) over a ladder of relative tolerances, on the *stacked*
  ensemble (one state vector of length ``3 N``) with a right-hand side written in numpy array operations —
  the fastest way a SciPy user has to integrate many spins at once;
* heyoka's Taylor integrator in SIMD batch mode (``heyoka.taylor_adaptive_batch``, Biscani & Izzo 2021),
  when heyoka is installed (the optional ``bench`` extra), over a ladder of tolerances,

and measures, per point, the error at ``t_end`` against a reference solution and the wall time (median of
``repeats`` runs, compile time excluded and reported separately; each timed run right after untimed runs of
the same solver lasting :data:`WARM_UP_SECONDS`, so that thread pools are awake and the cores up to speed for
every solver alike). :func:`speedups` reads the resulting
curves off at given errors and forms ratios against a baseline.

Error measure
-------------
Per sample ``i``: ``e_i = |w_i(t_end) - w_ref,i(t_end)| / |w_i(0)|`` (Euclidean norms, dimensionless).
``wp_error`` is ``max_i e_i``, ``wp_error_median`` the median. The perturbed spins lie on a cone about the
intermediate axis; the cone crosses the separatrix, so the worst sample is one whose motion is nearly
heteroclinic and whose phase error is amplified most — the max is the hard, honest measure.

The reference, when heyoka is used, is heyoka's (non-batch) Taylor integrator in x87 *long double*
(64-bit significand) at its default tolerance, the type's epsilon (1.1e-19), rounded to double: accurate to
about 1e-16 (it agrees with the same run in heyoka's ``high_accuracy`` mode to 2e-16). It is computed once,
not timed; its agreement with the closed form is recorded (attribute ``reference_vs_exact_max``, about 5e-15
here), and the closed form's point carries its true error against it.

Without heyoka the closed form (:func:`tumble.physics.exact.omega`) is the reference, so its error against
itself is zero by construction. Its point carries instead an *estimate* of its own error: the closed form
composed over two halves, ``omega(omega(w0, t_end/2), t_end/2)``, against ``omega(w0, t_end)`` (the flow
property, which any round-off or parameter error breaks): about 1e-14 … 1e-13 here, pessimistic beside the
long-double reference's 5e-15.

SciPy settings
--------------
``solve_ivp(rhs, (0, t_end), y0, method=..., rtol=rtol, atol=rtol * ATOL_FACTOR * |spin|)``, no ``t_eval``,
no dense output (the last accepted step ends exactly on ``t_end``). The error norm SciPy controls is the RMS
over all ``3 N`` components, so one tolerance governs the whole ensemble: that is what a user of the stacked
form gets. ``vectorized=False`` (the flag means several *time points* per call, not several samples), but
the right-hand side computes all samples at once. SciPy runs in one thread; tumble's kernels use
``numba.get_num_threads()`` threads (recorded in the attributes).

heyoka settings
---------------
``taylor_adaptive_batch`` on Euler's equations written as heyoka expressions (:func:`euler_heyoka`), batch
size ``heyoka.recommended_simd_size()`` (4 doubles on AVX2), ``tol`` from the ladder (heyoka's one
tolerance, relative and absolute; it also picks the Taylor order), ``propagate_until(t_end)`` per batch. The
batches run over ``numba.get_num_threads()`` Python threads, one integrator each (heyoka releases the GIL
while it integrates), so heyoka has the cores tumble has. Building the integrators (LLVM compilation) is
the compile time, excluded from the wall time like numba's. A batch whose sample count does not fill the
last batch is padded with copies of the last spin.
"""

from __future__ import annotations

import copy
import datetime
import math
import os
import platform
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numba
import numpy as np
import xarray as xr

from .. import registry
from .._version import __version__
from ..engine.integration import _step_plan, integrate, propagate
from ..engine.sampling import perturbed_spins
from ..physics import exact
from ..physics.bodies import one_body
from ..registry import ERROR_CONTROLLED, STEPPING

__all__ = ["ATOL_FACTOR", "DEFAULT_HEYOKA_TOLS", "DEFAULT_RTOLS", "SCIPY_METHODS", "default_steps", "euler_heyoka",
           "euler_rhs_stacked", "heyoka_reference", "speedups", "time_to_error", "work_precision"]

#: SciPy's absolute tolerance is ``rtol * ATOL_FACTOR * |spin|`` (rad/s): the transverse components start
#: at ``amplitude * |spin|`` and the relative tolerance should govern, so atol sits well below them.
ATOL_FACTOR = 1e-3

#: Default relative tolerances for SciPy: 1e-3 … 1e-13, one per decade.
DEFAULT_RTOLS = tuple(10.0 ** -k for k in range(3, 14))

#: Default tolerances for heyoka's Taylor integrator: 1e-3 … 1e-15, one per decade.
DEFAULT_HEYOKA_TOLS = tuple(10.0 ** -k for k in range(3, 16))

#: SciPy methods accepted: the explicit Runge–Kutta pairs (implicit ones would build a 3N × 3N Jacobian).
SCIPY_METHODS = ("RK23", "RK45", "DOP853")

#: Default step-count ladders per nominal order, ``2**lo … 2**hi``: wide enough to go from errors of about
#: 1e-2 (the coarse end, for the scene of the benchmark: t_end = 20 s at 1 rad/s) down to round-off
#: (about 1e-13) or until the next run would take longer than :data:`MAX_POINT_SECONDS`.
_LADDER_EXPONENTS = {1: (8, 17), 2: (6, 16), 4: (4, 15), 8: (3, 11)}

#: Default ladders stop refining once the error is this small (round-off reached) ...
ROUND_OFF = 1e-12
#: ... or once the error is below 1e-9 and refining the step no longer halves it (the round-off floor) ...
_FLOOR_ERROR, _FLOOR_GAIN = 1e-9, 0.5
#: ... or once the next (twice longer) run is predicted to take more than this many seconds.
MAX_POINT_SECONDS = 3.0

_EXACT = "exact"
_SCIPY_PREFIX = "scipy_"
_HEYOKA = "heyoka"


# ------------------------------------------------------------------------------------------------- helpers
def default_steps(method, t_end=20.0):
    """Default step counts for a fixed-step tumble method: a geometric ladder chosen by its order.

    Parameters
    ----------
    method : str
        A key of :data:`tumble.registry.STEPPING`.
    t_end : float
        Horizon, s. The ladders are tuned for ``t_end = 20 s`` at about 1 rad/s; they are scaled by
        ``t_end / 20`` (and kept >= 4 steps) so that the step sizes, not the counts, stay comparable.

    Returns
    -------
    ndarray of int
        Increasing step counts, doubling from one to the next.
    """
    order = registry.method(method).order
    lo, hi = _LADDER_EXPONENTS.get(order, _LADDER_EXPONENTS[min(_LADDER_EXPONENTS, key=lambda k: abs(k - order))])
    counts = (2.0 ** np.arange(lo, hi + 1)) * (t_end / 20.0)
    return np.unique(np.maximum(4, np.round(counts)).astype(np.int64))


def _machine():
    """CPU model and vector width (from /proc/cpuinfo where there is one), architecture and core count."""
    model, flags = None, set()
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key = line.split(":", 1)[0].strip().lower()
                if key == "model name" and model is None:
                    model = line.split(":", 1)[1].strip()
                elif key == "flags" and not flags:
                    flags = set(line.split(":", 1)[1].split())
    except OSError:
        pass
    width = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
    arch = platform.processor() or platform.machine()
    cpu = f"{model or 'unknown CPU'}, {width}" if flags else model or "unknown CPU"
    return f"{cpu} ({arch}), {os.cpu_count()} logical cores, {platform.system()}"


def _errors(w, reference, norm0):
    """(max, median) over samples of ``|w - reference| / |w0|``; inf where a sample is not finite."""
    e = np.linalg.norm(w - reference, axis=1) / norm0
    e = np.where(np.isfinite(e), e, np.inf)
    return float(e.max()), float(np.median(e))


def euler_rhs_stacked(moments):
    """The right-hand side of Euler's equations on a stacked ensemble, for ``scipy.integrate.solve_ivp``.

    Parameters
    ----------
    moments : ndarray, shape (3,)
        Principal moments, kg m².

    Returns
    -------
    callable
        ``rhs(t, y) -> dy`` with ``y`` of shape ``(3 N,)``, laid out as ``(w1 of all samples, w2 of all,
        w3 of all)`` (rad/s) and ``dy`` in rad/s²: ``I1 w1' = (I2 - I3) w2 w3`` and cyclic, all samples in
        three numpy expressions.
    """
    i1, i2, i3 = (float(x) for x in moments)
    c1, c2, c3 = (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3

    def rhs(t, y):
        w1, w2, w3 = y.reshape(3, -1)
        out = np.empty_like(y)
        d1, d2, d3 = out.reshape(3, -1)
        np.multiply(w2, w3, out=d1)
        d1 *= c1
        np.multiply(w3, w1, out=d2)
        d2 *= c2
        np.multiply(w1, w2, out=d3)
        d3 *= c3
        return out

    return rhs


def _import_heyoka():
    """heyoka, or None when it is not installed (it is an optional benchmark dependency: the ``bench`` extra)."""
    try:
        import heyoka
    except ImportError:
        return None
    return heyoka


def euler_heyoka(moments, fp_type=float):
    """Euler's equations as a heyoka ODE system, ``[(w1, (I2 - I3) / I1 * w2 * w3), ...]`` (cyclic).

    Parameters
    ----------
    moments : ndarray, shape (3,)
        Principal moments, kg m².
    fp_type : type
        Floating-point type of the integrator (``float`` or ``numpy.longdouble``). The coefficients
        ``(I2 - I3) / I1`` and cyclic are computed in that type, so that a long-double integrator solves the
        equations of the given moments, not those of coefficients rounded to double.

    Returns
    -------
    list of (heyoka.expression, heyoka.expression)
        The system over state variables ``w1, w2, w3`` (rad/s), for ``heyoka.taylor_adaptive[_batch]``.
    """
    hy = _import_heyoka()
    if hy is None:
        raise ImportError("euler_heyoka needs heyoka (pip install 'tumble[bench]' or pip install heyoka)")
    i1, i2, i3 = (fp_type(x) for x in moments)
    w1, w2, w3 = hy.make_vars("w1", "w2", "w3")
    c1, c2, c3 = (hy.expression(fp_type(c)) for c in ((i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3))
    return [(w1, c1 * w2 * w3), (w2, c2 * w3 * w1), (w3, c3 * w1 * w2)]


def heyoka_reference(moments, w0, t_end):
    """Reference solution: heyoka's Taylor integrator in long double, one spin at a time, rounded to double.

    Parameters
    ----------
    moments : ndarray, shape (3,)
        Principal moments, kg m².
    w0 : ndarray, shape (n, 3)
        Initial body-frame angular velocities, rad/s.
    t_end : float
        Horizon, s.

    Returns
    -------
    ndarray, shape (n, 3)
        ``w(t_end)``, rad/s, from ``heyoka.taylor_adaptive(..., fp_type=numpy.longdouble)`` at heyoka's default
        tolerance (the epsilon of long double, 1.1e-19 on x86); accurate to about 1e-16 relative here.

    Raises
    ------
    ImportError
        Without heyoka.
    RuntimeError
        If a propagation stops before ``t_end``.
    """
    hy = _import_heyoka()
    if hy is None:
        raise ImportError("heyoka_reference needs heyoka (pip install 'tumble[bench]' or pip install heyoka)")
    ld = np.longdouble
    ta = hy.taylor_adaptive(euler_heyoka(moments, ld), np.zeros(3, dtype=ld), fp_type=ld)
    out = np.empty((len(w0), 3))
    for i, w in enumerate(np.asarray(w0, dtype=float)):
        ta.time = ld(0)
        ta.state[:] = w
        outcome = ta.propagate_until(ld(t_end))[0]
        if outcome != hy.taylor_outcome.time_limit:
            raise RuntimeError(f"heyoka long-double reference: sample {i} stopped with {outcome}")
        out[i] = ta.state
    return out


def _heyoka_ensemble(moments, w0, t_end, tol, pool, threads):
    """heyoka's batch-mode Taylor integrator over the ensemble: build (compile) now, run later on ``threads``
    threads of ``pool`` (a ``ThreadPoolExecutor``, or None for one thread).

    Returns ``run(record=False)``, which integrates every spin to ``t_end`` and returns ``w(t_end)`` of shape
    ``(n, 3)``; with ``record=True`` it returns ``(w, steps, order)``: the most steps any sample took and the
    Taylor order, and raises if a batch stopped before ``t_end``. ``run`` is timed without ``record``.
    """
    hy = _import_heyoka()
    size = hy.recommended_simd_size()
    n = len(w0)
    batches = -(-n // size)
    padded = np.concatenate([w0, np.repeat(w0[-1:], batches * size - n, axis=0)])
    states = np.ascontiguousarray(padded.reshape(batches, size, 3).transpose(0, 2, 1))  # (batch, 3, lane)
    first = hy.taylor_adaptive_batch(euler_heyoka(moments), np.zeros((3, size)), tol=tol)
    integrators = [first] + [copy.deepcopy(first) for _ in range(threads - 1)]
    out = np.empty_like(states)

    def lane(k, record):
        ta, steps = integrators[k], 0
        for b in range(k, batches, threads):
            ta.set_time(0.0)
            ta.state[:] = states[b]
            ta.propagate_until(t_end)
            out[b] = ta.state
            if record:
                if any(r[0] != hy.taylor_outcome.time_limit for r in ta.propagate_res):
                    raise RuntimeError(f"heyoka batch {b} (tol {tol:g}) stopped early: {ta.propagate_res}")
                steps = max(steps, *(r[3] for r in ta.propagate_res))
        return steps

    def run(record=False):
        if pool is None or threads == 1:
            steps = [lane(0, record)]
        else:
            steps = list(pool.map(lane, range(threads), [record] * threads))
        w = out.transpose(0, 2, 1).reshape(-1, 3)[:n]
        return (w.copy(), max(steps), first.order) if record else w

    return run


def _check_positive_int(value, name):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _step_ladders(methods, steps, t_end):
    """Per fixed-step method: (step counts, adaptive stop?); an error-controlled one runs at the tolerances."""
    methods = [m for m in methods if m not in ERROR_CONTROLLED]
    if steps is None:
        return {m: (default_steps(m, t_end), True) for m in methods}
    if isinstance(steps, dict):
        unknown = set(steps) - set(methods)
        if unknown:
            raise ValueError(f"steps names methods that are not run: {sorted(unknown)}")
        ladders = {}
        for m in methods:
            ladders[m] = (default_steps(m, t_end), True) if m not in steps else (_counts(steps[m], m), False)
        return ladders
    counts = _counts(steps, "steps")
    return {m: (counts, False) for m in methods}


def _counts(values, name):
    counts = np.atleast_1d(np.asarray(values))
    if counts.ndim != 1 or counts.size == 0 or counts.dtype.kind not in "iu" or np.any(counts < 1):
        raise ValueError(f"step counts for {name} must be a non-empty sequence of integers >= 1, got {values!r}")
    return np.unique(counts.astype(np.int64))


def _say(progress, text):
    if progress:
        print(text, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------------------- the benchmark
def work_precision(body=(1.0, 2.0, 3.0), axis=2, spin=1.0, amplitude=0.05, samples=2000, t_end=20.0, seed=0,
                   methods=None, steps=None, rtols=None, repeats=3, scipy_methods=("RK45", "DOP853"),
                   heyoka_tols=None, progress=False):
    # size: a public call: each keyword is one option of the benchmark (the scene, the ladders, the peers)
    """Work-precision data: wall time against error at ``t_end`` for tumble's integrators, SciPy and heyoka.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        Principal moments, kg m².
    axis : {1, 2, 3}
        Axis of the unperturbed spin, 1-based (default 2: the intermediate axis of (1, 2, 3)).
    spin : float
        Spin rate, rad/s.
    amplitude : float
        Tilt of every spin from the axis, rad (``perturbed_spins``' ``"cone"``).
    samples : int
        Ensemble size.
    t_end : float
        Horizon, s (> 0).
    seed : int
        Seed of the ensemble.
    methods : sequence of str, optional
        tumble's methods (default: all of :data:`~tumble.registry.STEPPING`, fixed steps, and of
        :data:`~tumble.registry.ERROR_CONTROLLED`, run at ``rtols`` as SciPy). The closed form
        ``"exact"`` is always measured (one point); naming it here is allowed and changes nothing.
    steps : sequence of int, or dict {method: sequence of int}, optional
        Step counts ``n`` (``dt = t_end / n``). Default (and for methods a dict leaves out): a doubling
        ladder chosen by the method's order (:func:`default_steps`) that stops early once the error reaches
        round-off (< :data:`ROUND_OFF`, or below 1e-9 and no longer halving) or when the next run would take
        longer than :data:`MAX_POINT_SECONDS`. Step counts given explicitly are all run.
    rtols : sequence of float, optional
        SciPy relative tolerances (default :data:`DEFAULT_RTOLS`, 1e-3 … 1e-13); ``atol = rtol *
        ATOL_FACTOR * |spin|``.
    repeats : int
        Each point's wall time is the median of this many runs. The runs are interleaved: a first pass
        walks every solver's curve (deciding its points), then ``repeats - 1`` further passes time every
        point of every solver in turn, so that load from other processes falls on all solvers alike.
    scipy_methods : sequence of str
        ``solve_ivp`` methods (of :data:`SCIPY_METHODS`); empty to leave SciPy out.
    heyoka_tols : sequence of float, optional
        Tolerances of heyoka's batch-mode Taylor integrator. Default: :data:`DEFAULT_HEYOKA_TOLS` (1e-3 …
        1e-15) when heyoka is installed, else heyoka is left out (attribute ``heyoka`` says so). Empty to
        leave heyoka out; tolerances given explicitly need heyoka. With heyoka, the reference of every error
        is heyoka's long-double run (:func:`heyoka_reference`); without, the closed form.
    progress : bool
        Print one line per point to standard error.

    Returns
    -------
    xarray.Dataset
        Dimensions ``solver`` (tumble method names, ``"exact"``, ``"scipy_<method>"``, ``"heyoka"``) and
        ``wp_point`` (index along each solver's curve, NaN-padded):

        * ``wp_error(solver, wp_point)``: max over samples of ``|w - w_ref| / |w0|`` at ``t_end``;
        * ``wp_error_median(solver, wp_point)``: the median over samples;
        * ``wp_wall(solver, wp_point)``: wall time, s (median of ``repeats``, compile time excluded);
        * ``wp_setting(solver, wp_point)``: ``dt`` (s) for tumble's fixed steps, ``rtol`` for SciPy and dop853,
          ``tol`` for heyoka, NaN for exact;
        * ``wp_steps(solver, wp_point)``: steps taken (accepted steps for SciPy, most steps of any sample for
          heyoka; NaN for exact);
        * ``wp_nfev(solver, wp_point)``: right-hand-side evaluations (SciPy only, else NaN);
        * ``compile_time(solver)``: first call of each tumble method (compile or cache load), s; building
          every integrator of heyoka's ladder (LLVM); 0 for SciPy;
        * ``solver_kind(solver)``: ``"tumble"``, ``"exact"``, ``"scipy"`` or ``"heyoka"``; ``order(solver)``:
          nominal order (NaN for exact, SciPy and heyoka, whose Taylor order follows the tolerance).

        Attributes describe the ensemble, the machine, threads, versions and the date; the reference
        (``reference``, ``reference_wall_s``, ``reference_vs_exact_max`` and ``_median``: its distance to the
        closed form, NaN when the closed form is the reference); heyoka's use (``heyoka``) and what the
        closed-form point's time is made of: ``exact_omega_wall_s`` (:func:`tumble.physics.exact.omega`
        alone, at the one time ``t_end``) and ``integrate_one_step_rk4_wall_s`` (``tumble.integrate`` with one rk4 step: its fixed cost;
        NaN without rk4).

    Raises
    ------
    ValueError
        Invalid body, ensemble, horizon, methods, step counts, tolerances or repeats.
    ImportError
        ``heyoka_tols`` given (not empty) without heyoka installed.
    """
    moments = one_body(body)
    samples = _check_positive_int(samples, "samples")
    repeats = _check_positive_int(repeats, "repeats")
    t_end = float(t_end)
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be a finite number > 0 s, got {t_end!r}")
    methods, scipy_methods, rtols = _check_solvers(methods, scipy_methods, rtols)
    hy, heyoka_tols = _check_heyoka(heyoka_tols)
    ladders = _step_ladders(methods, steps, t_end)

    w0 = perturbed_spins(moments, axis, spin, amplitude, samples, seed=seed)
    started = time.perf_counter()
    if heyoka_tols.size:
        reference = heyoka_reference(moments, w0, t_end)
        about_reference = "heyoka taylor_adaptive in long double (tol = its epsilon), rounded to double"
    else:
        reference = exact.omega(moments, w0, np.array([t_end]))[:, -1, :]
        about_reference = "closed form (tumble.physics.exact.omega); heyoka " + (
            "left out" if hy is not None else "not installed")
    reference_wall = time.perf_counter() - started
    _say(progress, f"  reference: {about_reference} ({reference_wall:.2f} s)")
    run = _Ensemble(moments, w0, t_end, reference, np.linalg.norm(w0, axis=1), progress)

    # Pass 1 walks every solver's ladder once: it decides which points exist (errors, round-off, time cap)
    # and gives each point its first wall time. Passes 2 … repeats then time every point again, all solvers
    # in turn, so that a change of machine load during the run hits all solvers alike; each point's wall
    # time is the median over the passes.
    curves = {m: (_adaptive_curve(run, m, rtols, ATOL_FACTOR * abs(float(spin))) if m in ERROR_CONTROLLED else
                  _tumble_curve(run, m, *ladders[m])) for m in methods}
    curves[_EXACT], reference_vs_exact = _exact_curve(run, heyoka_tols.size > 0)
    # Beside the points (timed through the array API): the bare closed form, and what tumble.integrate (a
    # Dataset) costs on top of the kernels, measured on a one-step rk4 run of the same ensemble.
    parts = {"exact_omega": _Curve([], [(lambda: exact.omega(moments, w0, t_end), [])], 0.0)}
    if "rk4" in methods:
        parts["integrate_one_step_rk4"] = _Curve([], [(lambda: integrate(moments, w0, t_end, t_end, method="rk4"),
                                                      [])], 0.0)
    for sm in scipy_methods:
        curves[_SCIPY_PREFIX + sm] = _scipy_curve(run, sm, rtols, atol_scale=ATOL_FACTOR * abs(float(spin)))
    threads = int(numba.get_num_threads())
    if heyoka_tols.size:
        with ThreadPoolExecutor(threads) as pool:
            curves[_HEYOKA] = _heyoka_curve(run, heyoka_tols, pool if threads > 1 else None, threads)
            extra = _retime(curves, parts, repeats, progress)
    else:
        extra = _retime(curves, parts, repeats, progress)

    ds = _dataset({name: c.points for name, c in curves.items()}, {name: c.compile_time for name, c in curves.items()},
                  methods, moments, axis, spin, amplitude, samples, t_end, seed, repeats)
    ds.attrs.update(exact_omega_wall_s=extra["exact_omega"],
                    integrate_one_step_rk4_wall_s=extra.get("integrate_one_step_rk4", math.nan),
                    reference=about_reference, reference_wall_s=reference_wall,
                    reference_vs_exact_max=reference_vs_exact[0], reference_vs_exact_median=reference_vs_exact[1])
    if heyoka_tols.size:
        ds.attrs.update(heyoka=f"heyoka {hy.__version__}: taylor_adaptive_batch, batch size "
                               f"{hy.recommended_simd_size()}, {threads} thread(s)",
                        heyoka_threads=threads, heyoka_batch_size=int(hy.recommended_simd_size()))
    else:
        ds.attrs["heyoka"] = "left out" if hy is not None else "not installed (pip install 'tumble[bench]')"
    return ds


def _check_solvers(methods, scipy_methods, rtols):
    """tumble's methods (without ``"exact"``, always measured), SciPy's and its tolerances (loose to tight)."""
    known = (*STEPPING, *ERROR_CONTROLLED)
    methods = list(known) if methods is None else [m for m in dict.fromkeys(methods) if m != _EXACT]
    unknown = [m for m in methods if m not in known]
    if unknown:
        raise ValueError(f"methods must be among {', '.join((*known, _EXACT))}; got {unknown}")
    scipy_methods = list(dict.fromkeys(scipy_methods or ()))
    bad = [m for m in scipy_methods if m not in SCIPY_METHODS]
    if bad:
        raise ValueError(f"scipy_methods must be among {', '.join(SCIPY_METHODS)}; got {bad}")
    rtols = np.asarray(DEFAULT_RTOLS if rtols is None else rtols, dtype=float).reshape(-1)
    if (scipy_methods or set(methods) & set(ERROR_CONTROLLED)) and (rtols.size == 0 or not np.all(np.isfinite(rtols)) or np.any(rtols <= 0)):
        raise ValueError(f"rtols must be a non-empty sequence of finite numbers > 0, got {rtols!r}")
    return methods, scipy_methods, np.sort(rtols)[::-1]


def _check_heyoka(heyoka_tols):
    """heyoka's module (None when not installed) and its tolerances, tight last (empty: heyoka left out)."""
    hy = _import_heyoka()
    if heyoka_tols is None:
        heyoka_tols = DEFAULT_HEYOKA_TOLS if hy is not None else ()
    heyoka_tols = np.sort(np.asarray(heyoka_tols, dtype=float).reshape(-1))[::-1]
    if heyoka_tols.size and not (np.all(np.isfinite(heyoka_tols)) and np.all(heyoka_tols > 0)):
        raise ValueError(f"heyoka_tols must be finite numbers > 0, got {heyoka_tols!r}")
    if heyoka_tols.size and hy is None:
        raise ImportError("heyoka_tols given but heyoka is not installed (pip install 'tumble[bench]')")
    return hy, heyoka_tols


class _Ensemble(NamedTuple):
    """What every solver of :func:`work_precision` is measured on."""

    moments: np.ndarray
    w0: np.ndarray  # (N, 3) rad/s
    t_end: float
    reference: np.ndarray  # (N, 3) rad/s at t_end
    norm0: np.ndarray  # (N,) |w0|
    progress: bool

    def point(self, w_end, wall, setting, steps, nfev=np.nan):
        err, err_med = _errors(w_end, self.reference, self.norm0)
        return dict(error=err, error_median=err_med, wall=wall, setting=setting, steps=steps, nfev=nfev)


class _Curve(NamedTuple):
    """A solver's points (dicts of :meth:`_Ensemble.point`), the runs that time them again and its compile time."""

    points: list
    runs: list  # (callable, wall times of its runs), one per point
    compile_time: float


def _timed(fn):
    started = time.perf_counter()
    result = fn()
    return time.perf_counter() - started, result


# Untimed calls before each timed one last at least this long (s).
WARM_UP_SECONDS = 0.02


def _timed_warm(fn):
    """``fn``'s wall time on a call right after untimed calls of it lasting :data:`WARM_UP_SECONDS` (at least
    one): the thread pools (numba's, heyoka's) sleep while another solver runs, and on a virtual machine the
    cores take several calls, milliseconds, to come back to speed (a 0.1 ms call measured 0.4-0.8 ms right after
    one warm-up call). Every solver and point is timed so, the long ones too (one untimed call each: it roughly
    doubles the benchmark's run time, and keeps every point measured the same way)."""
    started = time.perf_counter()
    fn()
    while time.perf_counter() - started < WARM_UP_SECONDS:
        fn()
    return _timed(fn)


def _tumble_curve(run, method, counts, adaptive):
    """A fixed-step method along its ladder of step counts; an adaptive (default) ladder stops at round-off
    or before a run longer than :data:`MAX_POINT_SECONDS`."""
    moments, w0, t_end = run.moments, run.w0, run.t_end
    compile_time, _ = _timed(lambda: propagate(moments, w0[:2], t_end / 4, t_end / 4, method=method))
    points, runs = [], []
    for n in map(int, counts):
        if adaptive and points and points[-1]["wall"] * n / points[-1]["steps"] > MAX_POINT_SECONDS:
            _say(run.progress, f"  {method}: stop before n={n} (next run would exceed {MAX_POINT_SECONDS} s)")
            break
        dt = t_end / n

        def one_run(dt=dt):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # coarse steps may blow up: error inf
                return propagate(moments, w0, t_end, dt, method=method)

        wall, w_end = _timed_warm(one_run)
        steps, step = _step_plan(t_end, dt)
        points.append(run.point(w_end, wall, step, steps))
        runs.append((one_run, [wall]))
        err = points[-1]["error"]
        _say(run.progress, f"  {method:18s} n={n:7d} dt={dt:.3e} s  error {err:.2e} "
                           f"(median {points[-1]['error_median']:.2e})  {wall:.4f} s")
        if adaptive and (err < ROUND_OFF or (len(points) > 1 and err < _FLOOR_ERROR
                                             and err > _FLOOR_GAIN * points[-2]["error"])):
            break
    return _Curve(points, runs, compile_time)


def _adaptive_curve(run, method, rtols, atol_scale):
    """An error-controlled tumble method (``dop853``) at each relative tolerance, as SciPy's (``atol = rtol *
    atol_scale``); its steps: the most any sample took."""
    moments, w0, t_end = run.moments, run.w0, run.t_end
    compile_time, _ = _timed(lambda: propagate(moments, w0[:2], t_end / 4, method=method))
    points, runs = [], []
    for rtol in rtols:
        def one_run(rtol=rtol):
            return propagate(moments, w0, t_end, method=method, rtol=rtol, atol=rtol * atol_scale)

        wall, w_end = _timed_warm(one_run)
        steps = int(integrate(moments, w0, t_end, method=method, rtol=rtol, atol=rtol * atol_scale)["steps"].max())
        points.append(run.point(w_end, wall, float(rtol), steps))
        runs.append((one_run, [wall]))
        _say(run.progress, f"  {method:18s} rtol={rtol:.0e}  error {points[-1]['error']:.2e} "
                           f"(median {points[-1]['error_median']:.2e})  {wall:.4f} s  ({steps} steps at most)")
    return _Curve(points, runs, compile_time)


def _exact_curve(run, heyoka_is_reference):
    """The closed form's one point, and its distance to the reference (NaN, NaN when it is the reference: its
    error is then estimated by the flow property over two halves of ``t_end``)."""
    moments, w0, t_end = run.moments, run.w0, run.t_end
    compile_time, _ = _timed(lambda: propagate(moments, w0[:2], t_end, t_end, method=_EXACT))

    def exact_run():
        return propagate(moments, w0, t_end, t_end, method=_EXACT)

    wall, w_exact = _timed_warm(exact_run)
    if heyoka_is_reference:  # the closed form's true error
        point = run.point(w_exact, wall, np.nan, np.nan)
        reference_vs_exact = (point["error"], point["error_median"])
    else:
        halves = exact.omega(moments, exact.omega(moments, w0, np.array([0.5 * t_end]))[:, -1, :],
                             np.array([0.5 * t_end]))[:, -1, :]
        point = _Ensemble(moments, w0, t_end, w_exact, run.norm0, run.progress).point(halves, wall, np.nan, np.nan)
        reference_vs_exact = (math.nan, math.nan)
    what = "error" if heyoka_is_reference else "error estimate"
    _say(run.progress, f"  {_EXACT:18s} {what} {point['error']:.2e} (median {point['error_median']:.2e})  {wall:.4f} s")
    return _Curve([point], [(exact_run, [wall])], compile_time), reference_vs_exact


def _scipy_curve(run, method, rtols, atol_scale):
    """``solve_ivp(method)`` on the stacked ensemble at each relative tolerance (``atol = rtol * atol_scale``)."""
    from scipy.integrate import solve_ivp

    rhs = euler_rhs_stacked(run.moments)
    y0 = np.ascontiguousarray(run.w0.T).reshape(-1)
    points, runs = [], []
    for rtol in rtols:
        def one_run(rtol=rtol):
            return solve_ivp(rhs, (0.0, run.t_end), y0, method=method, rtol=rtol, atol=rtol * atol_scale)

        wall, sol = _timed_warm(one_run)
        if sol.status != 0:
            raise RuntimeError(f"solve_ivp({method}, rtol={rtol:g}) failed: {sol.message}")
        points.append(run.point(sol.y[:, -1].reshape(3, -1).T, wall, float(rtol), len(sol.t) - 1, int(sol.nfev)))
        runs.append((one_run, [wall]))
        _say(run.progress, f"  {_SCIPY_PREFIX + method:18s} rtol={rtol:.0e}  error {points[-1]['error']:.2e} "
                           f"(median {points[-1]['error_median']:.2e})  {wall:.4f} s  ({len(sol.t) - 1} steps, "
                           f"{sol.nfev} f-evals)")
    return _Curve(points, runs, 0.0)


def _heyoka_curve(run, tols, pool, threads):
    """heyoka's batch-mode Taylor integrator at each tolerance; building the integrators is its compile time."""
    points, runs, compile_time = [], [], 0.0
    for tol in tols:
        build, one_run = _timed(lambda tol=tol: _heyoka_ensemble(run.moments, run.w0, run.t_end, float(tol), pool,
                                                                 threads))
        compile_time += build
        w_end, n_steps, order = one_run(record=True)  # not timed: with bookkeeping
        wall, _ = _timed_warm(one_run)
        points.append(run.point(w_end, wall, float(tol), n_steps))
        runs.append((one_run, [wall]))
        _say(run.progress, f"  {_HEYOKA:18s} tol={tol:.0e}  error {points[-1]['error']:.2e} "
                           f"(median {points[-1]['error_median']:.2e})  {wall:.4f} s  (order {order}, {n_steps} "
                           f"steps, build {build:.3f} s)")
    return _Curve(points, runs, compile_time)


def _retime(curves, parts, repeats, progress):
    """Passes 2 … ``repeats`` over every point of every solver in turn; each point's wall time becomes the
    median of its passes. Returns the median time of each of ``parts`` (timed in every pass, no first one)."""
    for part in parts.values():
        for fn, walls in part.runs:
            walls.append(_timed_warm(fn)[0])
    for k in range(1, repeats):
        _say(progress, f"  timing pass {k + 1} of {repeats}")
        for curve in (*curves.values(), *parts.values()):
            for fn, walls in curve.runs:
                walls.append(_timed_warm(fn)[0])
    for curve in curves.values():
        for point, (_, walls) in zip(curve.points, curve.runs):
            point["wall"] = float(np.median(walls))
    return {name: float(np.median(part.runs[0][1])) for name, part in parts.items()}


def _kind(solver):
    if solver in STEPPING or solver in ERROR_CONTROLLED:
        return "tumble"
    if solver in (_EXACT, _HEYOKA):
        return solver
    return "scipy"


def _dataset(curves, compile_time, methods, moments, axis, spin, amplitude, samples, t_end, seed, repeats):
    # size: the benchmark's curves and the scene's parameters, all recorded as the dataset's coordinates and
    # attributes
    solvers = list(curves)
    width = max(len(p) for p in curves.values())
    fields = ("error", "error_median", "wall", "setting", "steps", "nfev")
    table = {f: np.full((len(solvers), width), np.nan) for f in fields}
    for i, s in enumerate(solvers):
        for j, point in enumerate(curves[s]):
            for f in fields:
                table[f][i, j] = point[f]
    kind = [_kind(s) for s in solvers]
    order = [float(registry.method(s).order) if s in STEPPING else 8.0 if s in ERROR_CONTROLLED else np.nan
             for s in solvers]
    dims = ("solver", "wp_point")
    data = {
        "wp_error": (dims, table["error"], {
            "units": "1", "long_name": "max over samples of |w - w_ref| / |w0| at t_end",
            "comment": "reference: attribute 'reference'; when it is the closed form, the error of 'exact' is "
                       "an estimate, the closed form composed over two halves of t_end against one evaluation "
                       "over t_end"}),
        "wp_error_median": (dims, table["error_median"], {
            "units": "1", "long_name": "median over samples of |w - w_ref| / |w0| at t_end"}),
        "wp_wall": (dims, table["wall"], {
            "units": "s", "long_name": "wall time of one ensemble run",
            "comment": f"median of {repeats} runs (time.perf_counter) taken in {repeats} interleaved passes "
                       "over all solvers, each right after untimed runs of the same solver "
                       f"({WARM_UP_SECONDS * 1e3:g} ms at least); compile time excluded"}),
        "wp_setting": (dims, table["setting"], {
            "units": "s (tumble methods: step dt); 1 (scipy: rtol; heyoka: tol)",
            "long_name": "step dt (tumble), relative tolerance rtol (scipy) or tolerance tol (heyoka); NaN "
                         "for exact",
            "comment": f"scipy atol = rtol * {ATOL_FACTOR:g} * |spin| rad/s"}),
        "wp_steps": (dims, table["steps"], {
            "units": "1", "long_name": "steps (fixed steps for tumble, accepted steps for scipy, most steps of "
                                       "any sample for heyoka)"}),
        "wp_nfev": (dims, table["nfev"], {
            "units": "1", "long_name": "right-hand-side evaluations (scipy only)"}),
        "compile_time": ("solver", np.array([compile_time.get(s, 0.0) for s in solvers]), {
            "units": "s", "long_name": "first call (compile or cache load), excluded from wp_wall; 0 for scipy",
            "comment": "heyoka: building the integrators of its whole tolerance ladder (LLVM)"}),
        "solver_kind": ("solver", np.array(kind), {"units": "1", "long_name": "tumble, exact, scipy or heyoka"}),
        "order": ("solver", np.array(order), {"units": "1", "long_name": "nominal order of the fixed-step method"}),
    }
    coords = {
        "solver": ("solver", np.array(solvers), {"units": "1", "long_name": "integrator"}),
        "wp_point": ("wp_point", np.arange(width), {"units": "1", "long_name": "index along a solver's curve"}),
    }
    import scipy

    attrs = {
        "title": "tumble work-precision benchmark",
        "I1": float(moments[0]), "I2": float(moments[1]), "I3": float(moments[2]),
        "moments_units": "kg m2",
        "axis": int(axis), "spin": float(spin), "spin_units": "rad/s",
        "amplitude": float(amplitude), "amplitude_units": "rad", "distribution": "cone",
        "samples": int(samples), "t_end": float(t_end), "t_end_units": "s", "seed": int(seed),
        "repeats": int(repeats), "machine": _machine(), "numba_threads": int(numba.get_num_threads()),
        "scipy_threads": 1, "scipy_atol_factor": ATOL_FACTOR,
        "versions": f"tumble {__version__}, numba {numba.__version__}, numpy {np.__version__}, "
                    f"scipy {scipy.__version__}, python {platform.python_version()}",
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "tumble_methods": list(methods),
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


# ----------------------------------------------------------------------------------------- reading off
def _pareto(walls, errors):
    """The work-precision front: points sorted by time whose error beats every faster point's."""
    ok = np.isfinite(walls) & np.isfinite(errors) & (walls > 0)
    order = np.argsort(walls[ok], kind="stable")
    w, e = walls[ok][order], errors[ok][order]
    front_w, front_e = [], []
    for wi, ei in zip(w, e):
        if not front_e or ei < front_e[-1]:
            front_w.append(wi)
            front_e.append(ei)
    return np.array(front_w), np.array(front_e)


def time_to_error(walls, errors, target):
    """Least wall time at which a solver's curve reaches ``error <= target``, by log-log interpolation.

    The curve is first reduced to its front (sorted by time, keeping only points more accurate than every
    faster one: "the best time achieving at least that error"). Between the last front point with error
    above ``target`` and the first at or below it, ``log(time)`` is interpolated linearly in
    ``log(error)``. A target looser than the fastest point's error gives that point's time (an upper
    bound: the curve is not extrapolated); a target tighter than every point's error gives NaN.

    Parameters
    ----------
    walls, errors : array_like, shape (P,)
        Wall times (s) and errors of one solver's points; NaN entries are ignored.
    target : float
        Error to reach (> 0).

    Returns
    -------
    float
        Seconds, or NaN when the solver never reaches ``target``.
    """
    w, e = _pareto(np.asarray(walls, dtype=float), np.asarray(errors, dtype=float))
    reached = np.nonzero(e <= target)[0]
    if reached.size == 0:
        return math.nan
    k = int(reached[0])
    if k == 0 or e[k] <= 0:
        return float(w[k])
    le0, le1 = math.log(e[k - 1]), math.log(e[k])
    lw0, lw1 = math.log(w[k - 1]), math.log(w[k])
    return float(math.exp(lw0 + (math.log(target) - le0) * (lw1 - lw0) / (le1 - le0)))


def speedups(ds, errors=(1e-4, 1e-7, 1e-10), baseline="scipy_DOP853"):
    """Wall time each solver needs to reach given errors, and its speed-up over a baseline solver.

    Parameters
    ----------
    ds : xarray.Dataset
        From :func:`work_precision` (reads ``wp_error``, ``wp_wall`` and, if present, ``solver_kind``).
    errors : sequence of float
        Target errors (same measure as ``wp_error``: max over samples, relative).
    baseline : str
        Solver whose time is the numerator of the ratio.

    Returns
    -------
    xarray.Dataset
        * ``time_to_error(solver, error)``, s — :func:`time_to_error` along each solver's curve; NaN where
          the solver never reaches that error within the measured points;
        * ``speedup(solver, error)`` — ``baseline time / solver time``; NaN where either never reaches it;
        * ``best_tumble(error)`` — the fixed-step tumble method with the least time (``""`` if none reaches
          it), ``best_tumble_speedup(error)`` its speed-up;
        * ``exact_speedup(error)`` — the closed form's speed-up (NaN if absent or not accurate enough).

    Raises
    ------
    ValueError
        If ``baseline`` is not a solver of ``ds`` or an error is not > 0.
    """
    solvers = [str(s) for s in ds["solver"].values]
    if baseline not in solvers:
        raise ValueError(f"baseline {baseline!r} is not a solver of the dataset ({', '.join(solvers)})")
    targets = np.asarray(errors, dtype=float).reshape(-1)
    if targets.size == 0 or not np.all(np.isfinite(targets) & (targets > 0)):
        raise ValueError(f"errors must be finite numbers > 0, got {errors!r}")
    walls = ds["wp_wall"].transpose("solver", "wp_point").values
    errs = ds["wp_error"].transpose("solver", "wp_point").values
    times = np.array([[time_to_error(walls[i], errs[i], t) for t in targets] for i in range(len(solvers))])
    base = times[solvers.index(baseline)]
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = base[None, :] / times
    if "solver_kind" in ds:
        kinds = [str(k) for k in ds["solver_kind"].values]
    else:
        kinds = [_kind(s) for s in solvers]
    tumble_rows = [i for i, k in enumerate(kinds) if k == "tumble"]
    best, best_ratio = [], []
    for j in range(targets.size):
        finite = [i for i in tumble_rows if np.isfinite(times[i, j])]
        if finite:
            i = min(finite, key=lambda r: times[r, j])
            best.append(solvers[i])
            best_ratio.append(ratio[i, j])
        else:
            best.append("")
            best_ratio.append(np.nan)
    exact_ratio = ratio[solvers.index(_EXACT)] if _EXACT in solvers else np.full(targets.size, np.nan)
    note = "NaN: the solver (or the baseline) never reaches that error within the measured points"
    return xr.Dataset(
        {
            "time_to_error": (("solver", "error"), times, {
                "units": "s", "long_name": "least wall time to reach the error (log-log interpolation)",
                "comment": note}),
            "speedup": (("solver", "error"), ratio, {
                "units": "1", "long_name": f"{baseline} time / solver time", "comment": note}),
            "best_tumble": ("error", np.array(best), {
                "units": "1", "long_name": "fastest fixed-step tumble method at that error ('' if none)"}),
            "best_tumble_speedup": ("error", np.array(best_ratio, dtype=float), {
                "units": "1", "long_name": f"speed-up of the best tumble method over {baseline}"}),
            "exact_speedup": ("error", np.asarray(exact_ratio, dtype=float), {
                "units": "1", "long_name": f"speed-up of the closed form over {baseline}"}),
        },
        coords={"solver": ("solver", np.array(solvers), {"units": "1", "long_name": "integrator"}),
                "error": ("error", targets, {"units": "1", "long_name": "target error (max over samples)"})},
        attrs={"baseline": baseline},
    )
