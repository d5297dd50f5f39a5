"""The tangent flow of a system: one per-sample time loop (state, k tangent vectors, MEGNO) for the CPU and the device.

The chaos indicators (:func:`tumble.lyapunov`, :func:`tumble.megno`) follow, with each sample's state ``y`` (n,), ``k``
tangent vectors ``V`` (k, n) advanced by the variational equations ``δ' = J(t, y) δ``. Its kernels are made here, once
per (system, method):

* :func:`make_tangent_step`: one explicit Runge–Kutta step of the augmented system ``(y, V, Ys, Yss)`` from a Butcher
  tableau of :mod:`tumble.kernels.tableaux`. The tableau applied to ``(y, δ)`` with ``δ' = J(y) δ`` gives for ``δ`` the
  derivative of the method's own map ``y_n -> y_{n+1}``: the tangent is the exact linearisation of the discrete flow
  (Hairer, Nørsett & Wanner I, sect. II.4 "the derivative of the numerical solution"), so the exponents are those of the
  map the method computes, and ``V`` never drifts from the state it belongs to. MEGNO's two scalars ride along
  (Cincotta & Simó 2000, A&AS 147, 205, eqs. 9-11, as REBOUND integrates them: ``Ys' = 2 t ρ``, ``Yss' = Ys / t`` with
  ``ρ = δ·δ' / |δ|²`` of the first tangent vector; ``Y = Ys / t``, ``<Y> = Yss / t``); ``ρ`` does not depend on ``|δ|``,
  so renormalising ``δ`` leaves them alone.
* :func:`make_midpoint_tangent_step` and :func:`make_splitting_tangent_step`: the implicit midpoint rule's step and a
  Lie–Poisson splitting's (free body, gyrostat, heavy top), each with the derivative of its own map.
* :func:`make_tangent_loop`: the per-sample time loop. Every ``every`` steps (and where the transient ends, where a
  finite-time value is saved, and at the end) the tangent vectors are orthonormalised by modified Gram–Schmidt (Benettin
  et al. 1980; Golub & Van Loan sect. 5.2.8), ``V = Q R``; after the transient ``log |R_rr|`` is added to the sample's
  sums (the exponents are the sums over the time they cover). The product of the ``R`` of successive factorisations is
  the ``R`` of one factorisation of the whole tangent map, so the sums do not depend on ``every`` beyond round-off.
  A least-squares slope of ``<Y>`` against ``t`` is kept as REBOUND keeps it (Welford updates after every step); in the
  chaotic regime ``<Y> ≈ λ t / 2``, so the loop writes ``λ = 2 × slope`` (REBOUND's ``lyapunov()`` returns the slope).
  A state, tangent or MEGNO scalar that is not finite, or a tangent vector that collapses to zero, stops the sample with
  ``STATUS_NONFINITE`` (state and tangents kept from before the step); ``<Y>`` above ``stop_above`` stops it with
  :data:`tumble.registry.STATUS_ABOVE`. Written once: the CPU's driver (:func:`make_cpu_driver`, a share of the
  samples per thread) and the device's (:mod:`tumble.kernels.cuda.tangent_flow`, one thread per sample) both call it.

The tangent of a system is given as ``tangents(t, y, V, p, out, work)``: ``out[r] = J(t, y) V[r]`` for each row of ``V``
(``work``: an (n, n) scratch). :func:`model_tangents` makes it for the built-in models
(:func:`tumble.kernels.steps.model_steps.tangent_sample`), :func:`jacobian_tangents` for a user's ``jacobian(t, y, p, J)``
(the matrix once per stage, then ``k`` products), :func:`difference_tangents` for a System without one (a directional
derivative of its rate by Richardson-extrapolated central differences, to about 1e-12 relative).

The kernels are closures over the system's functions (as :mod:`tumble.kernels.loops.sample_loop`'s), compiled in each new
process on first use.
"""

import math

import numpy as np

from ...registry import STATUS_ABOVE, STATUS_NONFINITE, STATUS_OK
from ..jit import jit
from ..steps.model_splittings import splitting_tangent_sample
from ..steps.model_steps import tangent_sample
from ..threads import in_shares
from .sample_loop import combine
from ..steps.steppers import _EPS, _MIDPOINT_MAX_ITERATIONS, _MIDPOINT_ULPS
from ..steps.system_steps import DIFFERENCE_STEP  # also a System's generated difference tangents'
from ..trig import _max

__all__ = ["DIFFERENCE_STEP", "SCALARS", "difference_tangents", "jacobian_tangents", "make_cpu_driver",
           "make_midpoint_tangent_step", "make_splitting_tangent_step", "make_tangent_loop", "make_tangent_step",
           "midpoint_stages", "model_tangents",
           "orthonormalise_row", "scratch_shapes"]


#: Scalars per sample a run writes: ``<Y>`` at the end (or at the stop), ``λ`` from its slope (1/s), the time the sample
#: ran (s), the time its sums of ``log |R_rr|`` cover (s: from the transient to its last orthonormalisation).
SCALARS = 4


#: Rows of the tangents' scratch ``work`` beyond the Jacobian's ``n``: the shifted state and four rates of
#: :func:`difference_tangents`.
WORK_EXTRA = 5



def scratch_shapes(n, k, stages):
    """The shapes of a sample's scratch arrays, ``(scratch, tangent_scratch, work, megno_scratch)``: the state's stage
    rates, stage state and copy before the step; the same for the ``k`` tangent vectors; the tangents' scratch (an
    (n, n) Jacobian and :data:`WORK_EXTRA` rows more); MEGNO's stage rates and its two scalars (and their copy before
    the step)."""
    return (stages + 2, n), (stages + 2, k, n), (n + WORK_EXTRA, n), (stages + 2, 2)


def model_tangents():
    """``tangents(t, y, V, p, out, work)`` of the built-in models: ``out[r] = J(t, y) V[r]`` by the generated
    :func:`tumble.kernels.steps.model_steps.tangent_sample` (``p`` from :func:`tumble.kernels.rate_sample_parameters`)."""

    @jit(cache=False)
    def tangents(t, y, V, p, out, work):
        for r in range(V.shape[0]):
            tangent_sample(t, y, V[r], p, out[r])

    return tangents


def jacobian_tangents(jacobian):
    """``tangents(t, y, V, p, out, work)`` of a user's ``jacobian(t, y, p, J)`` (compiled): ``J`` written into ``work``
    once, then ``out[r] = J V[r]`` for each tangent vector."""

    @jit(cache=False)
    def tangents(t, y, V, p, out, work):
        n = y.shape[0]
        jacobian(t, y, p, work)
        for r in range(V.shape[0]):
            for a in range(n):
                total = 0.0
                for b in range(n):
                    total += work[a, b] * V[r, b]
                out[r, a] = total

    return tangents


def difference_tangents(rate):
    """``tangents(t, y, V, p, out, work)`` of a system known only by its (compiled) ``rate(t, y, p, dydt)``:
    ``out[r] ≈ J(t, y) V[r]``, the derivative of the rate along ``V[r]`` by central differences with one Richardson
    extrapolation, ``(8 (f(y + e v) - f(y - e v)) - (f(y + 2 e v) - f(y - 2 e v))) / (12 e)`` (fourth order; Fornberg
    1988). The last ``n`` entries of ``p`` are the components' scales ``s`` (the rate reads the ones before); the step
    ``e = DIFFERENCE_STEP / max_j(|v_j| / s_j)`` moves no component by more than ``DIFFERENCE_STEP`` of its scale,
    however far the state has gone: the step follows the scale on which the rate varies, not the size of ``y`` (an
    angle of 1e4 rad varies its sine on the scale 1, not 1e4).

    Why this one: the rate is float64 machine code, so no complex step or dual numbers can pass through it, and a plain
    central difference stops at ``eps ** (2/3)`` ≈ 4e-11 relative; the extrapolated one reaches ``eps ** (4/5)`` ≈
    3e-13 for a smooth rate of unit scale, at four rate calls per tangent vector and stage. A component far beyond its
    scale adds the rounding of ``y + e v``, ``eps |y_j| / (e v_j)`` relative. It is not the exact derivative of the
    method's map (as a Jacobian's product is), but differs from it by that much."""

    @jit(cache=False)
    def tangents(t, y, V, p, out, work):
        n = y.shape[0]
        scales = p[p.shape[0] - n:]
        shifted = work[n]
        for r in range(V.shape[0]):
            size = 0.0
            for j in range(n):
                size = _max(size, abs(V[r, j]) / scales[j])
            if size == 0.0:
                for j in range(n):
                    out[r, j] = 0.0
                continue
            e = DIFFERENCE_STEP / size
            for m in range(4):  # +e, -e, +2e, -2e
                shift = (1.0 if m < 2 else 2.0) * (1.0 if m % 2 == 0 else -1.0) * e
                for j in range(n):
                    shifted[j] = y[j] + shift * V[r, j]
                rate(t, shifted, p, work[n + 1 + m])
            for j in range(n):
                near = work[n + 1, j] - work[n + 2, j]
                far = work[n + 3, j] - work[n + 4, j]
                out[r, j] = (8.0 * near - far) / (12.0 * e)

    return tangents


def make_tangent_step(rate, tangents, tableau):
    """``step(t, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch)``: advance one sample's state ``y``
    (n,), tangent vectors ``V`` (k, n) and MEGNO scalars ``m`` (2,) (``Ys``, ``Yss``; ``t0`` the time they start from)
    in place by one step ``h`` of the explicit Runge–Kutta method ``tableau`` applied to the augmented system.

    Scratch arrays of :func:`scratch_shapes`; the step allocates nothing. A zero coefficient is skipped."""
    a, b, c = tableau.A.copy(), tableau.b.copy(), tableau.c.copy()
    stages = len(b)

    @jit(cache=False)
    def step(t, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch):
        n = y.shape[0]
        k = V.shape[0]
        stage = scratch[stages]
        tangent_stage = tangent_scratch[stages]
        for s in range(stages):
            for j in range(n):
                stage[j] = y[j]
            for r in range(k):
                for j in range(n):
                    tangent_stage[r, j] = V[r, j]
            ys = m[0]
            for q in range(s):
                if a[s, q] != 0.0:
                    weight = h * a[s, q]
                    for j in range(n):
                        stage[j] += weight * scratch[q, j]
                    for r in range(k):
                        for j in range(n):
                            tangent_stage[r, j] += weight * tangent_scratch[q, r, j]
                    ys += weight * megno_scratch[q, 0]
            time = t + c[s] * h
            rate(time, stage, p, scratch[s])
            tangents(time, stage, tangent_stage, p, tangent_scratch[s], work)
            # MEGNO (Cincotta & Simó 2000): rho = d.d' / |d|^2 of the first tangent vector at the stage
            dot = 0.0
            norm2 = 0.0
            for j in range(n):
                dot += tangent_stage[0, j] * tangent_scratch[s, 0, j]
                norm2 += tangent_stage[0, j] * tangent_stage[0, j]
            elapsed = time - t0
            megno_scratch[s, 0] = 2.0 * elapsed * dot / norm2
            megno_scratch[s, 1] = ys / elapsed if elapsed > 0.0 else 0.0  # Ys ~ t^2: Ys / t -> 0 at t0
        combine(y, h, b, scratch)
        for r in range(k):
            combine(V[r], h, b, tangent_scratch[:, r])
        combine(m, h, b, megno_scratch)

    return step


def midpoint_stages(n):
    """The ``stages`` of :func:`scratch_shapes` that :func:`make_midpoint_tangent_step` needs for a state of ``n``
    components: its scratch rows hold the identity, the Jacobian's columns, the factorised ``I - (h/2) J``, the
    midpoint, its rate and the pivots."""
    return 3 * n + 3


@jit(inline=True)
def _factorise(lu, pivots):
    """``lu`` (n, n) in place: its LU factors by Gaussian elimination with partial pivoting (rows swapped whole, the
    row chosen at column ``c`` in ``pivots[c]``)."""
    n = lu.shape[0]
    for c in range(n):
        pivot = c
        for a in range(c + 1, n):
            if abs(lu[a, c]) > abs(lu[pivot, c]):
                pivot = a
        pivots[c] = pivot
        if pivot != c:
            for b in range(n):
                lu[c, b], lu[pivot, b] = lu[pivot, b], lu[c, b]
        for a in range(c + 1, n):
            lu[a, c] /= lu[c, c]
            for b in range(c + 1, n):
                lu[a, b] -= lu[a, c] * lu[c, b]


@jit(inline=True)
def _solve(lu, pivots, x):
    """``x`` (n,) in place: the solution of ``A x = x`` for the ``A`` that :func:`_factorise` factorised into
    ``lu``, ``pivots``."""
    n = lu.shape[0]
    for c in range(n):
        pivot = int(pivots[c])
        if pivot != c:
            x[c], x[pivot] = x[pivot], x[c]
    for a in range(n):
        for c in range(a):
            x[a] -= lu[a, c] * x[c]
    for a in range(n - 1, -1, -1):
        for c in range(a + 1, n):
            x[a] -= lu[a, c] * x[c]
        x[a] /= lu[a, a]


def make_midpoint_tangent_step(rate, tangents):
    # size: the closure holds the step and its fixed-point solve (see there)
    """``step(t, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch)`` (as :func:`make_tangent_step`'s):
    one step of the implicit midpoint rule ``y1 = y0 + h f(t + h/2, (y0 + y1)/2)`` applied to the augmented system.

    The state: the midpoint ``z = y0 + (h/2) f(t + h/2, z)`` by fixed-point iteration until the update is below a few
    ulps of the state, as the free body's and the models' midpoint rule (:func:`tumble.kernels.steps.steppers.
    implicit_midpoint_sample`), then ``y1 = 2 z - y0``; a step whose iteration does not converge makes the state NaN
    (the loop stops the sample, ``STATUS_NONFINITE``). The tangent vectors: the same rule for ``δ' = J δ``,
    ``(I - (h/2) J) δ1 = (I + (h/2) J) δ0`` with ``J = J(t + h/2, z)``, which is the derivative of the state's map
    ``y0 -> y1`` (differentiate ``y1 = y0 + h f(z)``: ``δ1 = δ0 + h J (δ0 + δ1) / 2``), so the exponents are those of
    the map the method computes, as the explicit methods' are. ``J`` is built once per step from ``n`` tangent
    products with the unit vectors and factorised by Gaussian elimination with partial pivoting (``n`` is small: a
    rigid body's 3 to 7 components). MEGNO's scalars by the same rule: ``Ys1 = Ys0 + h 2 (t + h/2 - t0) ρ`` with ``ρ``
    of the mean tangent vector ``(δ0 + δ1)/2`` at the midpoint, ``Yss1 = Yss0 + h (Ys0 + Ys1) / 2 / (t + h/2 - t0)``.

    Scratch arrays of :func:`scratch_shapes` with ``stages = midpoint_stages(n)``; the step allocates nothing."""

    @jit(cache=False)
    def midpoint(t, y, p, half, z, rate_z):
        """``z = y + half f(t, z)`` into ``z`` by fixed-point iteration; NaN when it does not converge."""
        n = y.shape[0]
        for j in range(n):
            z[j] = y[j]
        for _ in range(_MIDPOINT_MAX_ITERATIONS):
            rate(t, z, p, rate_z)
            change = 0.0
            size = 0.0
            for j in range(n):
                new = y[j] + half * rate_z[j]
                change += abs(new - z[j])
                size += abs(new)
                z[j] = new
            if not change > _MIDPOINT_ULPS * _EPS * size:  # converged (or NaN: caught by the loop)
                return
        for j in range(n):
            z[j] = math.nan

    @jit(cache=False)
    def step(t, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch):
        n = y.shape[0]
        unit, columns, lu = scratch[:n], scratch[n:2 * n], scratch[2 * n:3 * n]
        z, rate_z, pivots = scratch[3 * n], scratch[3 * n + 1], scratch[3 * n + 2]
        half = 0.5 * h
        tm = t + half
        midpoint(tm, y, p, half, z, rate_z)
        # J at the midpoint, column by column (columns[c] = J e_c); lu = I - (h/2) J, factorised
        for a in range(n):
            for c in range(n):
                unit[a, c] = 1.0 if a == c else 0.0
        tangents(tm, z, unit, p, columns, work)
        for a in range(n):
            for c in range(n):
                lu[a, c] = unit[a, c] - half * columns[c, a]
        _factorise(lu, pivots)
        right = tangent_scratch[0]
        for r in range(V.shape[0]):
            for a in range(n):  # (I + (h/2) J) δ0, then solved for δ1
                total = 0.0
                for c in range(n):
                    total += columns[c, a] * V[r, c]
                right[r, a] = V[r, a] + half * total
            _solve(lu, pivots, right[r])
        # MEGNO: rho of the first tangent vector's mean (δ0 + δ1)/2 at the midpoint, J (δ0 + δ1)/2 = (δ1 - δ0) / h
        dot = 0.0
        norm2 = 0.0
        for a in range(n):
            mean = 0.5 * (V[0, a] + right[0, a])
            dot += mean * (right[0, a] - V[0, a]) / h
            norm2 += mean * mean
        elapsed = tm - t0
        ys = m[0] + h * 2.0 * elapsed * dot / norm2
        m[1] += h * 0.5 * (m[0] + ys) / elapsed
        m[0] = ys
        for j in range(n):
            y[j] = 2.0 * z[j] - y[j]
        V[:, :] = right

    return step


def make_splitting_tangent_step(method):
    """``step(t, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch)`` (as :func:`make_tangent_step`'s):
    one step of the Lie–Poisson splitting ``method`` (kernel id) of a free body, gyrostat or heavy top (``p`` as
    :func:`model_tangents`'), the tangent vectors by the derivative of the splitting's map
    (:func:`tumble.kernels.steps.model_splittings.splitting_tangent_sample`: each exact sub-flow's derivative).

    A splitting has no stages at which ``ρ = δ·δ'/|δ|²`` could be evaluated; over a step ``∫ ρ = ln(|δ1| / |δ0|)``
    exactly, and MEGNO's first scalar takes it at the step's middle, ``Ys1 = Ys0 + 2 (t + h/2 - t0) ln(|δ1| / |δ0|)``
    (MEGNO of a map, Cincotta & Simó 2000 sect. 3, with the time of the step's middle; an error of the splitting's
    second order), the second as the midpoint rule's, ``Yss1 = Yss0 + h (Ys0 + Ys1) / 2 / (t + h/2 - t0)``. No
    scratch is used (``stages = 0``)."""

    @jit(cache=False)
    def step(t, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch):
        n = y.shape[0]
        before = 0.0
        for j in range(n):
            before += V[0, j] * V[0, j]
        splitting_tangent_sample(method, y, V, p, h)
        after = 0.0
        for j in range(n):
            after += V[0, j] * V[0, j]
        elapsed = t + 0.5 * h - t0
        ys = m[0] + elapsed * math.log(after / before)  # 2 (t + h/2 - t0) ln(|δ1| / |δ0|)
        m[1] += h * 0.5 * (m[0] + ys) / elapsed
        m[0] = ys

    return step


@jit(inline=True)
def orthonormalise_row(V, r, against):
    """Row ``r`` of ``V`` less its projections on the rows ``0 .. against - 1`` (orthonormal already), then divided by
    its norm where that is > 0 and finite: one step of modified Gram–Schmidt. Returns the norm (``R_rr``)."""
    n = V.shape[1]
    for q in range(against):
        proj = 0.0
        for j in range(n):
            proj += V[q, j] * V[r, j]
        for j in range(n):
            V[r, j] -= proj * V[q, j]
    norm = 0.0
    for j in range(n):
        norm += V[r, j] * V[r, j]
    norm = math.sqrt(norm)
    if norm > 0.0 and math.isfinite(norm):
        for j in range(n):
            V[r, j] /= norm
    return norm


@jit(inline=True)
def _copy_sample(y, V, m, to_y, to_V, to_m):
    """A sample's state ``y`` (n,), tangent vectors ``V`` (k, n) and MEGNO scalars ``m`` (2,) into ``to_y``, ``to_V``,
    ``to_m``."""
    for j in range(y.shape[0]):
        to_y[j] = y[j]
    for r in range(V.shape[0]):
        for j in range(V.shape[1]):
            to_V[r, j] = V[r, j]
    to_m[0] = m[0]
    to_m[1] = m[1]


def make_tangent_loop(step):
    # size: the one time loop of the tangent flow, written once for both devices: steps, checks, Gram-Schmidt, sums,
    # MEGNO's slope, stores
    """``run_sample(i, y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved,
    megno, scratch, tangent_scratch, work, megno_scratch) -> (status, steps taken)``: sample ``i``'s whole run
    (``megno``: its scalars).

    ``y`` (n,) and ``V`` (k, n, orthonormal rows) are the sample's state and tangent vectors, advanced in place (its own
    copies: the caller copies them in and out). Every ``every`` steps, at step ``transient`` (where the sums start: the
    factorisation there only orthonormalises), at each saved step and at the last, ``V`` is orthonormalised by modified
    Gram–Schmidt and, after the transient, ``log |R_rr|`` added to ``logs[i, r]`` (``logs`` (N, k)). With ``saved`` (N,
    n_saved, k) of ``n_saved > 0``, the finite-time exponents ``logs / (t - t_transient)`` are written to row ``i`` after
    every ``save_every``-th step past the transient and at the last (rows after a stop are left as they are).
    ``megno`` (N, :data:`SCALARS`): row ``i`` gets ``<Y>``, ``2 × slope`` of ``<Y>`` against ``t`` (1/s), the time
    run and the time the sums cover. ``stop_above`` > 0 stops the sample once ``<Y>`` exceeds it
    (:data:`tumble.registry.STATUS_ABOVE`; ``inf``: never).

    Without ``orthogonalise`` (GALI, Skokos, Bountis & Antonopoulos 2007) each vector is only normalised at those
    steps, so that they keep their directions, and ``saved[i, slot, 0]`` is ``GALI_k``, the volume of the
    parallelepiped the k unit vectors span (the product of ``R_rr`` of a Gram–Schmidt of a copy: the product of their
    singular values)."""

    @jit(cache=False)
    def run_sample(i, y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved,
                   megno, scratch, tangent_scratch, work, megno_scratch):
        # size: the loop itself (see make_tangent_loop)
        n = y.shape[0]
        k = V.shape[0]
        rows = scratch.shape[0]
        before = scratch[rows - 1]
        tangent_before = tangent_scratch[rows - 1]
        m = megno_scratch[rows - 2]
        m_before = megno_scratch[rows - 1]
        store = saved.shape[1] > 0
        slot = 0
        m[0] = 0.0
        m[1] = 0.0
        code = STATUS_OK
        for j in range(n):
            if not math.isfinite(y[j]):
                code = STATUS_NONFINITE
        count = 0
        mean_t = 0.0
        mean_y = 0.0
        cov = 0.0
        var = 0.0
        average = 0.0
        ran = 0
        summed = 0
        for s in range(n_steps):
            if code != STATUS_OK:
                break
            _copy_sample(y, V, m, before, tangent_before, m_before)  # kept if the step is not finite
            step(t0 + s * h, t0, y, V, m, p, h, scratch, tangent_scratch, work, megno_scratch)
            finite = math.isfinite(m[0]) and math.isfinite(m[1])
            for j in range(n):
                finite = finite and math.isfinite(y[j])
            for r in range(k):
                for j in range(n):
                    finite = finite and math.isfinite(V[r, j])
            done = s + 1
            if finite and (done == transient or done % every == 0 or done == n_steps
                           or (store and done > transient and done % save_every == 0)):
                for r in range(k):  # modified Gram-Schmidt: V = Q R, rows of V the vectors
                    norm = orthonormalise_row(V, r, r if orthogonalise else 0)  # GALI: each vector only normalised
                    if not (norm > 0.0 and math.isfinite(norm)):
                        finite = False  # a tangent vector collapsed (or overflowed): no direction left to follow
                        break
                    work[0, r] = norm  # the Jacobian's scratch is free between steps (k <= n)
                if finite and done > transient:
                    for r in range(k):  # added only once all k are factorised
                        logs[i, r] += math.log(work[0, r])
                    summed = done
            if not finite:
                code = STATUS_NONFINITE
                _copy_sample(before, tangent_before, m_before, y, V, m)
                break
            ran = done
            elapsed = done * h
            average = m[1] / elapsed
            count += 1  # the running least-squares slope of <Y> against t (Welford's updates, as REBOUND's)
            d_t = elapsed - mean_t
            mean_t += d_t / count
            mean_y += (average - mean_y) / count
            cov += d_t * (average - mean_y)
            var += d_t * (elapsed - mean_t)
            if store and done > transient and (done % save_every == 0 or done == n_steps):
                if orthogonalise:
                    for r in range(k):
                        saved[i, slot, r] = logs[i, r] / ((done - transient) * h)
                else:  # GALI_k: the volume the k unit vectors span, the product of R_rr of a copy's Gram-Schmidt
                    volume = 1.0
                    for r in range(k):
                        for j in range(n):
                            tangent_before[r, j] = V[r, j]
                    for r in range(k):
                        norm = orthonormalise_row(tangent_before, r, r)
                        volume *= norm
                        if norm == 0.0:
                            break  # the vectors became dependent (to round-off): GALI is 0 from here
                    saved[i, slot, 0] = volume
                slot += 1
            if average > stop_above:
                code = STATUS_ABOVE
                break
        megno[i, 0] = average if ran > 0 else np.nan  # a sample that never stepped has no <Y>, not a regular 0
        megno[i, 1] = 2.0 * cov / var if count > 1 and var > 0.0 else np.nan  # a slope needs two points
        megno[i, 2] = ran * h
        megno[i, 3] = (summed - transient) * h if summed > 0 else 0.0
        return code, ran

    return run_sample


def make_cpu_driver(run_sample, stages):
    """``drive(y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved, megno,
    status, steps_taken)``: every sample of ``y`` (N, n) with its tangent vectors ``V`` (N, k, n) run by ``run_sample``
    (:func:`make_tangent_loop`), ``y`` and ``V`` overwritten with the final (or frozen) values, ``logs`` (N, k) (zeros
    in), ``saved``, ``megno``, ``status`` (N,) int8 and ``steps_taken`` (N,) int64 written. ``stages``: the method's.

    One contiguous share of the samples per numba thread, each a serial loop that releases the GIL, as
    :func:`tumble.kernels.loops.sample_loop.make_cpu_driver`."""

    @jit(cache=False)
    def run_share(y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved, megno,
                  status, steps_taken):
        n_samples, n = y.shape
        k = V.shape[1]
        state = np.empty(n)
        tangent = np.empty((k, n))
        scratch = np.empty((stages + 2, n))
        tangent_scratch = np.empty((stages + 2, k, n))
        work = np.empty((n + WORK_EXTRA, n))
        megno_scratch = np.empty((stages + 2, 2))
        for i in range(n_samples):
            state[:] = y[i]
            tangent[:, :] = V[i]
            code, ran = run_sample(i, state, tangent, p, t0, h, n_steps, every, transient, save_every, stop_above,
                                   orthogonalise, logs, saved, megno, scratch, tangent_scratch, work, megno_scratch)
            y[i] = state
            V[i] = tangent
            status[i] = code
            steps_taken[i] = ran

    def drive(y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved, megno,
              status, steps_taken):
        in_shares(run_share, len(y), lambda lo, hi: (
            y[lo:hi], V[lo:hi], p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise,
            logs[lo:hi], saved[lo:hi], megno[lo:hi], status[lo:hi], steps_taken[lo:hi]))

    return drive
