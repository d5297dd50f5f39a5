"""The peers' side of the chaos-map benchmark (issue 41, item 5): MEGNO and λ1 of a heavy top by other tools.

:mod:`benchmarks.chaos` runs tumble's map and the table; this module runs the same map with the peers, one function
each, every one returning ``{"megno": (N,), "lyapunov": (N,), "seconds", "setup_seconds", "settings", ...}``
(``seconds``: the run, compiling and setting up excluded and timed apart as ``setup_seconds``).

The problem, as tumble's ``heavy_top`` system writes it (``tumble/physics/models/heavy_top.py``): the heavy top
(Euler–Poisson) in body axes, moments ``I = (1.0, 1.5, 2.0)`` kg m², ``mgl = 1.0`` N m, the centre of mass's direction
``c = (1, 0.5, 1)/|(1, 0.5, 1)| = (2/3, 1/3, 2/3)``; state ``y = (w1, w2, w3, g1, g2, g3)``, ``g`` the upward vertical::

    I w' = (I w) × w + mgl (g × c),    g' = g × w

One tangent vector ``δ`` per orbit, starting at tumble's (``tumble.engine.chaos.initial_tangents(6, 1)[0]``, except
pynamicalsys, which draws its own); ``ρ = δ·δ'/|δ|²``, MEGNO's ``Ys' = 2 t ρ``, ``Yss' = Ys / t`` and
``<Y>(T) = Yss(T) / T`` (Cincotta & Simó 2000, as REBOUND integrates them); ``λ1 = log(|δ(T)|/|δ(0)|) / T``, the
logs of the renormalisations summed.

The peers:

- :func:`heyoka_map`: heyoka's Taylor integrator in batch mode (``taylor_adaptive_batch``, SIMD batch
  ``heyoka.recommended_simd_size()``), the 14 equations written out with heyoka expressions: the state, the linear
  variational equations ``δ' = J δ`` and MEGNO's two scalars (scaled by ``1/T²`` to stay of order 1: heyoka's error
  control takes the infinity norm of the whole state). ``δ`` is renormalised between ``propagate_until`` calls every
  ``renormalise`` seconds (100 by default: ``|δ|²`` would overflow past ``λ t ≈ 350``). ``Yss' = Ys/t`` has no
  Taylor series at ``t = 0``, so heyoka's clock starts at ``t0 = 1e-6`` s (an autonomous system: the orbit is the
  same; ``<Y>`` changes by ``O(t0/T)``). The batches are split between ``threads`` Python threads, one integrator
  copy each (``propagate_until`` releases the GIL). Carrying ``δ`` at unit length instead (``δ' = J δ − ρ δ``, no
  renormalising) took 1.3 times the steps and 1.7 times the time. heyoka keeps its compiled code in an on-disk
  cache (``~/.cache/heyoka``): ``setup_seconds`` is a few hundredths of a second warm, about 1-2 s cold.
- :func:`heyoka_reference`: the same at ``tol = 1e-15`` in double precision. Long double has no batch mode in heyoka:
  one orbit at a time (order 23 at its epsilon, 1.1e-19) took 0.49 s for T = 1000 where a batch of four took
  0.13 s at 1e-15, about 15 times the cost, hours for a 200 x 200 map: not affordable.
- :func:`numba_rk4_map`: what a user writes with plain numba: one orbit per ``prange`` iteration, classical RK4 at a
  fixed step on the 14 variables (state, tangent, ``Ys``, ``Yss``) in small per-orbit arrays, ``Ys/t`` taken as 0
  at ``t = 0`` (as tumble does), the tangent renormalised every 100 steps.
- :func:`pynamicalsys_map`: pynamicalsys 1.7.0's ``ContinuousDynamicalSystem.lyapunov`` (its RK4 at a fixed step,
  the tangent renormalised after every step; its own random initial tangent, ``seed=13``). pynamicalsys has no MEGNO
  for continuous-time systems (its other indicators there are SALI, LDI and GALI), so ``megno`` is NaN. It takes one
  initial state per call; only the first ``limit`` orbits are run, and the benchmark extrapolates the map's time
  from ``seconds_per_orbit``.
"""

import concurrent.futures
import copy
import math
import time

import heyoka as hy
import numba
import numpy as np
import pynamicalsys
from pynamicalsys import ContinuousDynamicalSystem

from tumble.engine.chaos import initial_tangents

__all__ = ["CENTRE", "MGL", "MOMENTS", "heyoka_map", "heyoka_reference", "numba_rk4_map", "pynamicalsys_map"]

#: The top of the map: moments about the pivot (kg m²), ``mgl`` (N m) and the centre of mass's direction.
MOMENTS = (1.0, 1.5, 2.0)
MGL = 1.0
CENTRE = (1.0, 0.5, 1.0)


def _coefficients():
    """``(a1, a2, a3, m12, m13, m21, m23, m31, m32)``: ``a_i = (I_j − I_k)/I_i`` and ``m_ij = (mgl/I_i) c_j``, the
    products tumble's ``heavy_top.constants`` computes, in the same order of operations."""
    i1, i2, i3 = MOMENTS
    c1, c2, c3 = (float(x) for x in np.asarray(CENTRE) / np.linalg.norm(CENTRE))
    m1, m2, m3 = MGL / i1, MGL / i2, MGL / i3
    return ((i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3,
            m1 * c2, m1 * c3, m2 * c1, m2 * c3, m3 * c1, m3 * c2)


A1, A2, A3, M12, M13, M21, M23, M31, M32 = _coefficients()

#: The initial tangent vector of every orbit (tumble's).
TANGENT = initial_tangents(6, 1)[0]

#: heyoka's clock at the start (s): ``Yss' = Ys / t`` needs ``t > 0``.
_HEYOKA_T0 = 1e-6


def _states(y0):
    """``y0`` as a C-contiguous float (N, 6) array; ValueError for any other shape."""
    y0 = np.ascontiguousarray(y0, dtype=float)
    if y0.ndim != 2 or y0.shape[1] != 6:
        raise ValueError(f"y0 must be (N, 6) heavy-top states, got shape {y0.shape}")
    return y0


def _heyoka_system(t_end):
    """heyoka's 14 equations: the state, the tangent ``δ' = J δ``, ``Ys / T²`` and ``Yss / T²``."""
    w1, w2, w3, g1, g2, g3, v1, v2, v3, u1, u2, u3, ys, yss = hy.make_vars(
        "w1", "w2", "w3", "g1", "g2", "g3", "v1", "v2", "v3", "u1", "u2", "u3", "ys", "yss")
    rate = (A1 * w2 * w3 + (M13 * g2 - M12 * g3),
            A2 * w3 * w1 + (M21 * g3 - M23 * g1),
            A3 * w1 * w2 + (M32 * g1 - M31 * g2),
            g2 * w3 - g3 * w2,
            g3 * w1 - g1 * w3,
            g1 * w2 - g2 * w1)
    flow = (A1 * (v2 * w3 + w2 * v3) + (M13 * u2 - M12 * u3),
            A2 * (v3 * w1 + w3 * v1) + (M21 * u3 - M23 * u1),
            A3 * (v1 * w2 + w1 * v2) + (M32 * u1 - M31 * u2),
            (u2 * w3 - u3 * w2) + (g2 * v3 - g3 * v2),
            (u3 * w1 - u1 * w3) + (g3 * v1 - g1 * v3),
            (u1 * w2 - u2 * w1) + (g1 * v2 - g2 * v1))
    tangent = (v1, v2, v3, u1, u2, u3)
    rho = hy.sum([d * f for d, f in zip(tangent, flow)]) / hy.sum([d * d for d in tangent])
    return (list(zip((w1, w2, w3, g1, g2, g3), rate)) + list(zip(tangent, flow))
            + [(ys, 2.0 * hy.time * rho / t_end ** 2), (yss, ys / hy.time)])


def heyoka_map(y0, t_end, tol=1e-10, threads=2, renormalise=100.0):
    """MEGNO and λ1 of every orbit by heyoka's Taylor integrator in batch mode.

    Parameters
    ----------
    y0 : ndarray (N, 6)
        The initial states ``(w1, w2, w3, g1, g2, g3)``.
    t_end : float
        The horizon ``T`` (s).
    tol : float
        heyoka's tolerance (relative and absolute: heyoka scales it by ``max(1, |x|∞)``).
    threads : int
        Python threads the batches are split between.
    renormalise : float
        The time (s) between renormalisations of ``δ``.

    Returns
    -------
    dict
        ``megno`` and ``lyapunov`` (N,), ``seconds`` (the propagation), ``setup_seconds`` (building and compiling
        the integrator and its copies), ``steps`` (N,) (Taylor steps of each orbit), ``batch_size``, ``order`` and
        ``settings``.
    """
    y0 = _states(y0)
    t_end = float(t_end)
    if not renormalise > 0:
        raise ValueError(f"renormalise must be a time > 0 (s), got {renormalise!r}")
    n = len(y0)
    start = time.perf_counter()
    size = hy.recommended_simd_size()
    batches = -(-n // size)
    extended = np.zeros((batches * size, 14))
    extended[:n, :6] = y0
    extended[n:, :6] = y0[-1]  # the last batch's spare lanes repeat the last orbit
    extended[:, 6:12] = TANGENT
    template = hy.taylor_adaptive_batch(_heyoka_system(t_end), np.zeros((14, size)), time=np.full(size, _HEYOKA_T0),
                                        tol=tol)
    integrators = [copy.deepcopy(template) for _ in range(threads)]
    setup = time.perf_counter() - start

    stops = _HEYOKA_T0 + np.append(np.arange(renormalise, t_end, renormalise), t_end)
    final = np.empty_like(extended)
    log_norm = np.zeros(batches * size)
    steps = np.zeros(batches * size, dtype=np.int64)

    def run(worker):
        ta = integrators[worker]
        for b in range(worker, batches, threads):
            lanes = slice(b * size, (b + 1) * size)
            ta.set_time(np.full(size, _HEYOKA_T0))
            ta.state[:] = extended[lanes].T
            for stop in stops:
                ta.propagate_until(stop)
                for lane, (outcome, *_, count) in enumerate(ta.propagate_res):
                    if outcome != hy.taylor_outcome.time_limit:
                        raise RuntimeError(f"heyoka stopped orbit {b * size + lane} early: {outcome}")
                    steps[b * size + lane] += count
                norm = np.linalg.norm(ta.state[6:12], axis=0)
                log_norm[lanes] += np.log(norm)
                ta.state[6:12] /= norm
            final[lanes] = ta.state.T

    start = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(threads) as pool:
        list(pool.map(run, range(threads)))
    seconds = time.perf_counter() - start
    return {
        "megno": final[:n, 13] * t_end ** 2 / stops[-1],
        "lyapunov": log_norm[:n] / t_end,
        "seconds": seconds,
        "setup_seconds": setup,
        "steps": steps[:n],
        "batch_size": size,
        "order": template.order,
        "settings": (f"heyoka {hy.__version__} taylor_adaptive_batch (double, batch {size}, order {template.order}), "
                     f"tol {tol:g}, {threads} threads over {batches} batches; linear tangent renormalised every "
                     f"{renormalise:g} s, MEGNO's Ys, Yss as ODE variables, clock from t0 = {_HEYOKA_T0:g} s"),
    }


def heyoka_reference(y0, t_end, threads=2):
    """The reference map: :func:`heyoka_map` at ``tol = 1e-15`` in double precision (long double has no batch mode
    and costs about 15 times as much per orbit: see the module docstring).

    Parameters and returns as :func:`heyoka_map`.
    """
    result = heyoka_map(y0, t_end, tol=1e-15, threads=threads)
    result["settings"] = "reference: " + result["settings"]
    return result


@numba.njit
def _rk4_rates(t, x, out):
    """The 14 rates of the augmented system at ``x``: state, tangent, ``Ys' = 2 t ρ`` and ``Yss' = Ys / t``."""
    w1, w2, w3, g1, g2, g3 = x[0], x[1], x[2], x[3], x[4], x[5]
    v1, v2, v3, u1, u2, u3 = x[6], x[7], x[8], x[9], x[10], x[11]
    out[0] = A1 * w2 * w3 + (M13 * g2 - M12 * g3)
    out[1] = A2 * w3 * w1 + (M21 * g3 - M23 * g1)
    out[2] = A3 * w1 * w2 + (M32 * g1 - M31 * g2)
    out[3] = g2 * w3 - g3 * w2
    out[4] = g3 * w1 - g1 * w3
    out[5] = g1 * w2 - g2 * w1
    out[6] = A1 * (v2 * w3 + w2 * v3) + (M13 * u2 - M12 * u3)
    out[7] = A2 * (v3 * w1 + w3 * v1) + (M21 * u3 - M23 * u1)
    out[8] = A3 * (v1 * w2 + w1 * v2) + (M32 * u1 - M31 * u2)
    out[9] = (u2 * w3 - u3 * w2) + (g2 * v3 - g3 * v2)
    out[10] = (u3 * w1 - u1 * w3) + (g3 * v1 - g1 * v3)
    out[11] = (u1 * w2 - u2 * w1) + (g1 * v2 - g2 * v1)
    rho = ((v1 * out[6] + v2 * out[7] + v3 * out[8] + u1 * out[9] + u2 * out[10] + u3 * out[11])
           / (v1 * v1 + v2 * v2 + v3 * v3 + u1 * u1 + u2 * u2 + u3 * u3))
    out[12] = 2.0 * t * rho
    out[13] = x[12] / t if t > 0.0 else 0.0  # Ys ~ t²: Ys / t -> 0 at t = 0


@numba.njit(parallel=True, fastmath=False)
def _rk4_map(y0, tangent, t_end, dt, megno, lyapunov):
    """One orbit per ``prange`` iteration: ``round(t_end/dt)`` RK4 steps of the 14 variables."""
    n_steps = round(t_end / dt)
    for i in numba.prange(y0.shape[0]):
        x = np.zeros(14)
        x[:6] = y0[i]
        x[6:12] = tangent
        k1, k2, k3, k4, stage = np.empty(14), np.empty(14), np.empty(14), np.empty(14), np.empty(14)
        log_norm = 0.0
        for s in range(n_steps):
            t = s * dt
            _rk4_rates(t, x, k1)
            for j in range(14):
                stage[j] = x[j] + 0.5 * dt * k1[j]
            _rk4_rates(t + 0.5 * dt, stage, k2)
            for j in range(14):
                stage[j] = x[j] + 0.5 * dt * k2[j]
            _rk4_rates(t + 0.5 * dt, stage, k3)
            for j in range(14):
                stage[j] = x[j] + dt * k3[j]
            _rk4_rates(t + dt, stage, k4)
            for j in range(14):
                x[j] += dt / 6.0 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])
            if s % 100 == 99 or s == n_steps - 1:
                norm = math.sqrt(x[6] ** 2 + x[7] ** 2 + x[8] ** 2 + x[9] ** 2 + x[10] ** 2 + x[11] ** 2)
                log_norm += math.log(norm)
                for j in range(6, 12):
                    x[j] /= norm
        t_run = n_steps * dt
        megno[i] = x[13] / t_run
        lyapunov[i] = log_norm / t_run


def numba_rk4_map(y0, t_end, dt=0.01, threads=2):
    """MEGNO and λ1 of every orbit by a plain numba RK4 at a fixed step, one orbit per ``prange`` iteration.

    Parameters
    ----------
    y0 : ndarray (N, 6)
        The initial states.
    t_end : float
        The horizon (s), a whole number of steps (rounded otherwise).
    dt : float
        The step (s).
    threads : int
        numba's threads for the run.

    Returns
    -------
    dict
        ``megno`` and ``lyapunov`` (N,), ``seconds`` (the run), ``setup_seconds`` (numba's compile, timed on one
        orbit of one step) and ``settings``.
    """
    y0 = _states(y0)
    megno = np.empty(len(y0))
    lyapunov = np.empty(len(y0))
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        start = time.perf_counter()
        _rk4_map(y0[:1], TANGENT, dt, dt, megno[:1], lyapunov[:1])
        setup = time.perf_counter() - start
        start = time.perf_counter()
        _rk4_map(y0, TANGENT, float(t_end), float(dt), megno, lyapunov)
        seconds = time.perf_counter() - start
    finally:
        numba.set_num_threads(before)
    return {
        "megno": megno,
        "lyapunov": lyapunov,
        "seconds": seconds,
        "setup_seconds": setup,
        "settings": (f"numba {numba.__version__} njit(parallel=True), one orbit per prange iteration, {threads} "
                     f"threads; RK4 dt {dt:g} on state + tangent + Ys, Yss (14 variables), tangent renormalised "
                     f"every 100 steps"),
    }


@numba.njit
def _pynamicalsys_rate(time, u, parameters):
    """The heavy top's rate, as pynamicalsys takes it: ``f(time, u, parameters) -> du/dt``."""
    a1, a2, a3, m12, m13, m21, m23, m31, m32 = parameters
    w1, w2, w3, g1, g2, g3 = u
    rate = np.empty(6)
    rate[0] = a1 * w2 * w3 + (m13 * g2 - m12 * g3)
    rate[1] = a2 * w3 * w1 + (m21 * g3 - m23 * g1)
    rate[2] = a3 * w1 * w2 + (m32 * g1 - m31 * g2)
    rate[3] = g2 * w3 - g3 * w2
    rate[4] = g3 * w1 - g1 * w3
    rate[5] = g1 * w2 - g2 * w1
    return rate


@numba.njit
def _pynamicalsys_jacobian(time, u, parameters):
    """The rate's Jacobian ``J[i, j] = ∂f_i/∂u_j``, as pynamicalsys takes it."""
    a1, a2, a3, m12, m13, m21, m23, m31, m32 = parameters
    w1, w2, w3, g1, g2, g3 = u
    jac = np.zeros((6, 6))
    jac[0, 1], jac[0, 2], jac[0, 4], jac[0, 5] = a1 * w3, a1 * w2, m13, -m12
    jac[1, 0], jac[1, 2], jac[1, 3], jac[1, 5] = a2 * w3, a2 * w1, -m23, m21
    jac[2, 0], jac[2, 1], jac[2, 3], jac[2, 4] = a3 * w2, a3 * w1, m32, -m31
    jac[3, 1], jac[3, 2], jac[3, 4], jac[3, 5] = -g3, g2, w3, -w2
    jac[4, 0], jac[4, 2], jac[4, 3], jac[4, 5] = g3, -g1, -w3, w1
    jac[5, 0], jac[5, 1], jac[5, 3], jac[5, 4] = -g2, g1, w2, -w1
    return jac


def pynamicalsys_map(y0, t_end, dt=0.01, limit=40):
    """λ1 of the first ``limit`` orbits by pynamicalsys's ``ContinuousDynamicalSystem.lyapunov`` (RK4, fixed step).

    Parameters
    ----------
    y0 : ndarray (N, 6)
        The initial states; only ``y0[:limit]`` are run.
    t_end : float
        The horizon (s).
    dt : float
        The RK4 step (s).
    limit : int or None
        How many orbits to run (None: all).

    Returns
    -------
    dict
        ``megno`` (NaN: pynamicalsys has none for flows) and ``lyapunov`` (run,), ``seconds`` (the run),
        ``setup_seconds`` (numba's compile of pynamicalsys's loop, timed on one orbit of one step),
        ``seconds_per_orbit``, ``orbits`` (run), ``estimated_seconds`` (``seconds_per_orbit × N``: the whole map's)
        and ``settings``.
    """
    y0 = _states(y0)
    run = y0 if limit is None else y0[:limit]
    start = time.perf_counter()
    system = ContinuousDynamicalSystem(equations_of_motion=_pynamicalsys_rate, jacobian=_pynamicalsys_jacobian,
                                       system_dimension=6, parameters=np.array(_coefficients()))
    system.integrator("rk4", time_step=dt)
    system.lyapunov(run[0], dt, num_exponents=1, endpoint=False)
    setup = time.perf_counter() - start
    lyapunov = np.empty(len(run))
    start = time.perf_counter()
    for i, state in enumerate(run):
        lyapunov[i] = system.lyapunov(state, float(t_end), num_exponents=1, endpoint=False)
    seconds = time.perf_counter() - start
    per_orbit = seconds / len(run)
    return {
        "megno": np.full(len(run), np.nan),
        "lyapunov": lyapunov,
        "seconds": seconds,
        "setup_seconds": setup,
        "seconds_per_orbit": per_orbit,
        "orbits": len(run),
        "estimated_seconds": per_orbit * len(y0),
        "settings": (f"pynamicalsys {pynamicalsys.__version__} ContinuousDynamicalSystem.lyapunov(num_exponents=1, "
                     f"endpoint=False), rk4 dt {dt:g}, one orbit per call, serial (1 thread), its own random initial "
                     f"tangent (seed 13), renormalised every step; no MEGNO for flows (NaN); {len(run)} of "
                     f"{len(y0)} orbits run, the map's time extrapolated as {per_orbit:.3g} s x {len(y0)} = "
                     f"{per_orbit * len(y0):.4g} s"),
    }
