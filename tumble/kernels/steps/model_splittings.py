"""Lie–Poisson splittings, the free body's compositions with exact sub-flows per block, of two kinds of system.

A model's registry row says which steps it (``registry.Model.splitting``): ``"rotor"`` (the gyrostat, the free body
as its ``h = 0``) or ``"gravity"`` (the heavy top); each kind's functions are named after it and read the constants
of the system that has it (``<kind>_splitting_block``, called by the generated dispatch).

The compositions are the free body's (:data:`tumble.kernels.tableaux.SYMPLECTIC_EULER`, ``SPLITTING2``,
``SPLITTING4``), read here as data; every sub-flow is an exact flow, and each is one loop over a block's samples
(one copy of :func:`tumble.kernels.trig.sincos` per axis, as :func:`tumble.kernels.steps.steppers.rotate_block`), so that
the loops vectorise across samples and the compile stays small. ``c`` is the system's ``Constants`` record
(:mod:`tumble.kernels.systems`).

**Gyrostat** (``L = I w + h``, body frame; the free body is ``h = 0``): ``H = sum_a (L_a − h_a)² / (2 I_a)`` and
``L' = L × ∇H = L × w``, which is ``I w' = (I w + h) × w``. The flow of one term ``H_a`` has ``∇H_a = w_a e_a``:
``L_a' = 0`` (so ``w_a`` is constant along it) and, ``(a, b, c)`` cyclic, ``L_b' = w_a L_c``, ``L_c' = −w_a L_b``:
``(L_b, L_c)`` turns by ``theta = w_a tau`` (:func:`tumble.kernels.steps.steppers.rotate`), made on ``L = I w + h``
``u = L / I = w + h / I`` turns with the free body's ratios ``I_c / I_b``, ``I_b / I_c``, and ``w = u − h / I``
again. Every sub-flow turns ``L``, so ``|I w + h|`` is kept; to round-off, as the free body's, by a projection
after each step onto its initial value (:func:`rotor_project_block`).

**Heavy top** (Euler–Poisson, :mod:`tumble.kernels.systems.heavy_top`): with ``H = T + V``, ``T = sum_a L_a² /
(2 I_a)``, ``V = mgl g·c`` (``c`` the centre of mass's direction), the bracket ``L' = L × ∇_L H + g × ∇_g H``, ``g' =
g × ∇_L H`` gives ``I w' = (I w) × w + mgl (g × c)``, ``g' = g × w``. The flow of ``T_a`` turns ``L`` and ``g``
together about body axis ``a`` by ``w_a tau`` (``w_a`` constant); the flow of ``V`` keeps ``g`` and moves ``L``
linearly, ``L += tau mgl (g × c)`` (``c = e3``: ``tau mgl (g2, −g1, 0)``). ``V`` is the compositions' "torque" sub-flow (``tableaux.TORQUE``: half a step at either end of each
Strang step, as the free body's torque), so the tables are used as they are. Every sub-flow keeps ``|g|`` and ``L·g``
(the turns turn both by the same angle; ``V`` changes ``L`` across ``g``); the energy is not kept, only bounded.

The gravity gradient and the damper have no such splitting here: the damper is dissipative (no Hamiltonian), and the
gravity gradient's state (``w`` and an attitude quaternion relative to a turning orbit frame) is no Lie–Poisson
system in these variables.
"""

import math

import numpy as np

from ...registry import MODELS, STEPPING
from ..jit import jit
from ..systems import SYSTEMS
from ..tableaux import SPLITTING2, SPLITTING4, SYMPLECTIC_EULER, TORQUE
from ..trig import sincos
from .steppers import rescale_step, rotate

__all__ = ["GRAVITY_CODE", "SPLITTINGS", "rotor_project_block", "rotor_turn_block",
           "rotor_splitting_block", "gravity_kick_block", "gravity_turn_block", "gravity_splitting_block",
           "splitting_tangent_block", "splitting_tangent_sample"]

#: The splittings the model kernels run, by name: kernel id (index in ``registry.STEPPING``).
SPLITTINGS = {s.name: STEPPING.index(s.name) for s in (SYMPLECTIC_EULER, SPLITTING2, SPLITTING4)}


def _tables(splittings):
    """``(position, start, flows, fractions)``: the sub-flows of every splitting in one array, splitting ``p``'s
    from ``start[p]`` to ``start[p + 1]``; ``position[kernel id]`` is ``p`` (−1 for another method)."""
    position = np.full(len(STEPPING), -1, dtype=np.int64)
    start, flows, fractions = [0], [], []
    for p, splitting in enumerate(splittings):
        position[STEPPING.index(splitting.name)] = p
        flows += [int(f) for f in splitting.flows]
        fractions += [float(x) for x in splitting.fractions]
        start.append(len(flows))
    return position, np.array(start, dtype=np.int64), np.array(flows, dtype=np.int64), np.array(fractions)


# The gyrostat has no torque sub-flow (the free body's tables without it); the heavy top's gravity is the torque's.
_FREE_POSITION, _FREE_START, _FREE_FLOWS, _FREE_FRACTIONS = _tables(
    [s.without_torque() for s in (SYMPLECTIC_EULER, SPLITTING2, SPLITTING4)])
_TOP_POSITION, _TOP_START, _TOP_FLOWS, _TOP_FRACTIONS = _tables([SYMPLECTIC_EULER, SPLITTING2, SPLITTING4])


@jit
def rotor_turn_block(axis, tau, y1, y2, y3, c):
    """The exact flow of ``H_a = (L_a − h_a)² / (2 I_a)`` over ``tau`` for every sample: ``(L_b, L_c)`` turns by
    ``w_a tau``, ``a = axis`` (0-based), ``(a, b, c)`` cyclic; one loop per axis. In ``u = L / I = w + h / I``, with
    the free body's ratios (``h = 0``: the free body's bits)."""
    u1, u2, u3 = c.h1 / c.i1, c.h2 / c.i2, c.h3 / c.i3  # h / I
    n = y1.shape[0]
    if axis == 0:
        r_cb, r_bc = c.i3 / c.i2, c.i2 / c.i3
        for i in range(n):
            b, d = rotate(y1[i] * tau, y2[i] + u2, y3[i] + u3, r_cb, r_bc)
            y2[i], y3[i] = b - u2, d - u3
    elif axis == 1:
        r_cb, r_bc = c.i1 / c.i3, c.i3 / c.i1
        for i in range(n):
            b, d = rotate(y2[i] * tau, y3[i] + u3, y1[i] + u1, r_cb, r_bc)
            y3[i], y1[i] = b - u3, d - u1
    else:
        r_cb, r_bc = c.i2 / c.i1, c.i1 / c.i2
        for i in range(n):
            b, d = rotate(y3[i] * tau, y1[i] + u1, y2[i] + u2, r_cb, r_bc)
            y1[i], y2[i] = b - u1, d - u2


@jit
def rotor_project_block(y1, y2, y3, target, c):
    """Every sample's ``L = I w + h`` rescaled onto ``|L|² = target`` (a few-ulp correction, as the free body's
    :func:`tumble.kernels.steps.steppers.project_l_squared`, applied additively): the turns keep ``|L|`` only to the
    rounding of ``cos(theta)``, which is the same at every step of a steady or periodic motion and so would add up
    linearly (3e-11 of ``|L|²`` in 1e5 splitting4 steps) rather than random-walk."""
    u1, u2, u3 = c.h1 / c.i1, c.h2 / c.i2, c.h3 / c.i3
    for i in range(y1.shape[0]):
        l1, l2, l3 = c.i1 * y1[i] + c.h1, c.i2 * y2[i] + c.h2, c.i3 * y3[i] + c.h3
        d = rescale_step(target[i], l1 * l1 + l2 * l2 + l3 * l3)
        y1[i] += (y1[i] + u1) * d
        y2[i] += (y2[i] + u2) * d
        y3[i] += (y3[i] + u3) * d


@jit
def rotor_splitting_block(method, y1, y2, y3, h, c, x0):
    """One step of splitting ``method`` (kernel id) of the gyrostat for every sample of a block, then each sample's
    ``|I w + h|²`` put back on its value at the start (``x0[1]``, the samples' initial invariants)."""
    p = _FREE_POSITION[method]
    for s in range(_FREE_START[p], _FREE_START[p + 1]):
        rotor_turn_block(_FREE_FLOWS[s], _FREE_FRACTIONS[s] * h, y1, y2, y3, c)
    rotor_project_block(y1, y2, y3, x0[1], c)


@jit
def gravity_turn_block(axis, tau, y1, y2, y3, y4, y5, y6, c):
    # size: one array per state component (the block's rows), the axis, the time and the constants
    """The exact flow of ``T_a = L_a² / (2 I_a)`` over ``tau`` for every sample: ``(L_b, L_c)`` and ``(g_b, g_c)``
    turn by ``w_a tau``, ``a = axis`` (0-based), ``(a, b, c)`` cyclic; one loop (one sincos) per axis."""
    if axis == 0:
        _turn_about_axis(tau, y1, y2, y3, y5, y6, c.i3 / c.i2, c.i2 / c.i3)
    elif axis == 1:
        _turn_about_axis(tau, y2, y3, y1, y6, y4, c.i1 / c.i3, c.i3 / c.i1)
    else:
        _turn_about_axis(tau, y3, y1, y2, y4, y5, c.i2 / c.i1, c.i1 / c.i2)


@jit(inline=True)
def _turn_about_axis(tau, wa, wb, wc, gb, gc, r_cb, r_bc):
    """:func:`gravity_turn_block` about the axis whose rows are ``wa`` (the others ``wb, wc`` and ``gb, gc``,
    cyclic order); ``r_cb = I_c/I_b``, ``r_bc = I_b/I_c``."""
    for i in range(wa.shape[0]):
        s, k = sincos(wa[i] * tau)
        b, c, g_b, g_c = wb[i], wc[i], gb[i], gc[i]
        wb[i], wc[i] = k * b + s * r_cb * c, k * c - s * r_bc * b
        gb[i], gc[i] = k * g_b + s * g_c, k * g_c - s * g_b


@jit
def gravity_kick_block(tau, y1, y2, y3, y4, y5, y6, c):
    # size: one array per state component (the block's rows), the time and the constants
    """The exact flow of ``V = mgl g·c`` over ``tau`` for every sample: ``g`` fixed, ``w += tau I⁻¹ mgl (g × c)``;
    with ``c = e3`` only ``w1`` and ``w2`` move (the loop then skips ``w3``, whose increment is 0)."""
    k13, k23 = tau * c.m13, tau * c.m23  # tau (mgl / I_i) c3
    if c.c1 == 0.0 and c.c2 == 0.0:  # the centre on axis 3: w1 += tau m1 c3 g2, w2 -= tau m2 c3 g1
        for i in range(y1.shape[0]):
            y1[i] += k13 * y5[i]
            y2[i] -= k23 * y4[i]
        return
    k12, k21, k31, k32 = tau * c.m12, tau * c.m21, tau * c.m31, tau * c.m32
    for i in range(y1.shape[0]):
        g1, g2, g3 = y4[i], y5[i], y6[i]
        y1[i] += k13 * g2 - k12 * g3
        y2[i] += k21 * g3 - k23 * g1
        y3[i] += k32 * g1 - k31 * g2


@jit
def gravity_splitting_block(method, y1, y2, y3, y4, y5, y6, h, c, x0):
    # size: one array per state component (the block's rows), the method, the step, the constants, the invariants
    """One step of splitting ``method`` (kernel id) of the heavy top for every sample of a block (gravity as the
    composition's torque sub-flow); ``x0`` (the initial invariants) is not used: every sub-flow keeps ``|g|`` and
    ``L·g`` exactly."""
    p = _TOP_POSITION[method]
    for s in range(_TOP_START[p], _TOP_START[p + 1]):
        tau = _TOP_FRACTIONS[s] * h
        if _TOP_FLOWS[s] == TORQUE:
            gravity_kick_block(tau, y1, y2, y3, y4, y5, y6, c)
        else:
            gravity_turn_block(_TOP_FLOWS[s], tau, y1, y2, y3, y4, y5, y6, c)


# --- the tangent map: each sub-flow with its derivative ---------------------------------------------------------------
#
# The chaos indicators (:mod:`tumble.kernels.loops.tangent_loop`, :mod:`tumble.kernels.loops.tangent_blocks`) need the derivative
# of the splitting's map ``y0 -> y1``, which is the product of its sub-flows' derivatives. A turn about axis ``a`` by
# ``theta = w_a tau`` is linear in the components it turns, and ``theta`` depends on the state through ``w_a`` alone
# (constant along that sub-flow): with ``(b, c)`` the turned pair and ``R(theta)`` the turn,
#     δ(b, c)' = R(theta) δ(b, c) + tau δw_a ∂(b', c')/∂theta,   ∂(u_b', u_c')/∂theta = (r_cb u_c', −r_bc u_b')
# (``r_cb r_bc = 1``), and ``δw_a`` (the heavy top's ``δg_a`` too) is kept. The heavy top's gravity kick is linear in
# ``g``: ``δw += tau I⁻¹ mgl (δg × c)``, ``δg`` kept. Every factor has determinant 1, so the map keeps volume and the
# exponents sum to zero to round-off. The state follows the block sub-flows' formulas without the gyrostat's projection
# onto its initial ``|L|`` (a few-ulp correction whose derivative would remove the tangent's radial part).
#
# The arithmetic is written once, per sample and per sub-flow (:func:`_turned`, :func:`_turned_tangent`,
# :func:`_kick`); :func:`splitting_tangent_sample` applies it to one sample (the per-sample loop, either device),
# :func:`splitting_tangent_block` to a block's samples in SIMD lanes (one loop over them per sub-flow).


def _slot(module, *names):
    """The position in a system's constants array (its ``Constants`` fields in order) of the first named field, the
    others checked to follow it (the kernels read ``a[first + axis]``)."""
    first = module.Constants._fields.index(names[0])
    assert [module.Constants._fields.index(name) for name in names] == list(range(first, first + len(names)))
    return first


def _system(splitting):
    """The equations module (:mod:`tumble.kernels.systems`) of the models that ``splitting`` steps (one)."""
    modules = {SYSTEMS[model.name] for model in MODELS if model.splitting == splitting}
    assert len(modules) == 1, f"one system has the {splitting!r} splitting"
    return modules.pop()


_ROTOR_SYSTEM, _GRAVITY_SYSTEM = _system("rotor"), _system("gravity")
_MOMENTS = _slot(_ROTOR_SYSTEM, "i1", "i2", "i3")
assert _MOMENTS == _slot(_GRAVITY_SYSTEM, "i1", "i2", "i3")
_ROTOR = _slot(_ROTOR_SYSTEM, "h1", "h2", "h3")
_M12, _M13, _M21, _M23, _M31, _M32 = (_slot(_GRAVITY_SYSTEM, name) for name in ("m12", "m13", "m21", "m23", "m31",
                                                                                   "m32"))
#: The model code (``registry.MODEL_KINDS``) of the system the gravity splitting steps; the others (the rotor
#: splitting's) share the rotor's flows.
GRAVITY_CODE = next(code for code, model in enumerate(MODELS) if model.splitting == "gravity")


@jit(inline=True)
def _rotated(s, k, ub, uc, r_cb, r_bc):
    """``(u_b, u_c)`` turned by the angle whose sine and cosine are ``s``, ``k``, with the free body's ratios
    (``r_cb = r_bc = 1``: a plain turn, the heavy top's ``g``)."""
    return k * ub + s * r_cb * uc, k * uc - s * r_bc * ub


@jit(inline=True)
def _turned(theta, ub, uc, r_cb, r_bc):
    """``(u_b, u_c)`` turned by ``theta`` with the free body's ratios, and the turn's ``(sin, cos)``."""
    s, k = sincos(theta)
    nb, nc = _rotated(s, k, ub, uc, r_cb, r_bc)
    return nb, nc, s, k


@jit(inline=True)
def _turned_tangent(d_theta, db, dc, nb, nc, s, k, r_cb, r_bc):
    """The turn's derivative applied to a tangent's ``(δb, δc)``, with ``δtheta = tau δw_a`` and ``(nb, nc)`` the
    turned state (``r_cb = r_bc = 1``: the heavy top's plain turn of ``g``)."""
    return k * db + s * r_cb * dc + d_theta * r_cb * nc, k * dc - s * r_bc * db - d_theta * r_bc * nb


@jit(inline=True)
def _kick(tau, a, g1, g2, g3):
    """Gravity's kick of ``w`` over ``tau``, ``tau I⁻¹ mgl (g × c)``: linear in ``g``, so the same for a tangent."""
    return (tau * a[_M13] * g2 - tau * a[_M12] * g3, tau * a[_M21] * g3 - tau * a[_M23] * g1,
            tau * a[_M32] * g1 - tau * a[_M31] * g2)


@jit(inline=True)
def _composition(top, method):
    """``(start, end, flows, fractions)``: where splitting ``method``'s sub-flows lie in the gyrostat's or the heavy
    top's tables."""
    if top:
        q = _TOP_POSITION[method]
        return _TOP_START[q], _TOP_START[q + 1], _TOP_FLOWS, _TOP_FRACTIONS
    q = _FREE_POSITION[method]
    return _FREE_START[q], _FREE_START[q + 1], _FREE_FLOWS, _FREE_FRACTIONS


@jit(inline=True)
def _ratios(a, axis):
    """``(b, c, r_cb, r_bc)`` of a turn about ``axis``: the turned pair and the free body's ratios ``I_c/I_b``,
    ``I_b/I_c``."""
    b, c = (axis + 1) % 3, (axis + 2) % 3
    return b, c, a[_MOMENTS + c] / a[_MOMENTS + b], a[_MOMENTS + b] / a[_MOMENTS + c]


@jit
def splitting_tangent_sample(method, y, V, p, h):
    """One step of splitting ``method`` (kernel id) of one sample of a free body, gyrostat or heavy top (``p[0]`` its
    code, then its constants, as :func:`tumble.kernels.steps.model_steps.rate_sample`'s ``p``): the state ``y`` (n,) and,
    by the derivative of the same map, the tangent vectors ``V`` (k, n), in place (see the section's comment)."""
    top = int(p[0]) == GRAVITY_CODE
    a = p[1:]
    first, end, flows, fractions = _composition(top, method)
    for s in range(first, end):
        tau = fractions[s] * h
        if flows[s] == TORQUE:
            for row in range(-1, V.shape[0]):
                x = y if row < 0 else V[row]
                k1, k2, k3 = _kick(tau, a, x[3], x[4], x[5])
                x[0] += k1
                x[1] += k2
                x[2] += k3
            continue
        axis = flows[s]
        b, c, r_cb, r_bc = _ratios(a, axis)
        shift_b = 0.0 if top else a[_ROTOR + b] / a[_MOMENTS + b]  # the gyrostat's u = w + h / I turns
        shift_c = 0.0 if top else a[_ROTOR + c] / a[_MOMENTS + c]
        gb = gc = 0.0
        nb, nc, sn, k = _turned(y[axis] * tau, y[b] + shift_b, y[c] + shift_c, r_cb, r_bc)
        y[b], y[c] = nb - shift_b, nc - shift_c
        if top:  # g turns by the same angle, plainly
            gb, gc = _rotated(sn, k, y[3 + b], y[3 + c], 1.0, 1.0)
            y[3 + b], y[3 + c] = gb, gc
        for r in range(V.shape[0]):
            d_theta = tau * V[r, axis]
            V[r, b], V[r, c] = _turned_tangent(d_theta, V[r, b], V[r, c], nb, nc, sn, k, r_cb, r_bc)
            if top:
                V[r, 3 + b], V[r, 3 + c] = _turned_tangent(d_theta, V[r, 3 + b], V[r, 3 + c], gb, gc, sn, k, 1.0,
                                                           1.0)


@jit
def splitting_tangent_block(method, top, Z, t, t0, h, a):
    # size: one loop over the block's samples per sub-flow and per tangent vector, the MEGNO update around them
    """One step of splitting ``method`` (kernel id) of every sample of a block of a free body or gyrostat (``top``
    False) or a heavy top, laid out as :mod:`tumble.kernels.loops.tangent_blocks` holds it: ``Z[r]`` (2 n + 2, m) the state,
    tangent vector ``r`` and MEGNO's two scalars of each sample (``a``: the system's constants). Each row ``r`` steps
    its own copy of the state, as the generated Runge–Kutta steps do. MEGNO as
    :func:`tumble.kernels.loops.tangent_loop.make_splitting_tangent_step`: ``Ys += 2 (t + h/2 - t0) ln(|δ1| / |δ0|)``,
    ``Yss`` by the trapezoid."""
    k_vectors, rows, m = Z.shape
    n = (rows - 2) // 2
    elapsed = t + 0.5 * h - t0
    first, end, flows, fractions = _composition(top, method)
    for r in range(k_vectors):
        Y = Z[r]
        for i in range(m):  # MEGNO before the step: Ys0's half of the trapezoid, less ln |δ0|²
            norm2 = 0.0
            for j in range(n, 2 * n):
                norm2 += Y[j, i] * Y[j, i]
            Y[rows - 1, i] += 0.5 * h * Y[rows - 2, i] / elapsed
            Y[rows - 2, i] -= elapsed * math.log(norm2)
        for s in range(first, end):
            tau = fractions[s] * h
            if flows[s] == TORQUE:
                for offset in (0, n):  # the state, then the tangent: the same linear kick
                    for i in range(m):
                        k1, k2, k3 = _kick(tau, a, Y[offset + 3, i], Y[offset + 4, i], Y[offset + 5, i])
                        Y[offset, i] += k1
                        Y[offset + 1, i] += k2
                        Y[offset + 2, i] += k3
                continue
            axis = flows[s]
            b, c, r_cb, r_bc = _ratios(a, axis)
            shift_b = 0.0 if top else a[_ROTOR + b] / a[_MOMENTS + b]
            shift_c = 0.0 if top else a[_ROTOR + c] / a[_MOMENTS + c]
            for i in range(m):
                gb = gc = 0.0
                nb, nc, sn, k = _turned(Y[axis, i] * tau, Y[b, i] + shift_b, Y[c, i] + shift_c, r_cb, r_bc)
                d_theta = tau * Y[n + axis, i]
                Y[b, i], Y[c, i] = nb - shift_b, nc - shift_c
                Y[n + b, i], Y[n + c, i] = _turned_tangent(d_theta, Y[n + b, i], Y[n + c, i], nb, nc, sn, k, r_cb,
                                                           r_bc)
                if top:
                    gb, gc = _rotated(sn, k, Y[3 + b, i], Y[3 + c, i], 1.0, 1.0)
                    Y[3 + b, i], Y[3 + c, i] = gb, gc
                    Y[n + 3 + b, i], Y[n + 3 + c, i] = _turned_tangent(d_theta, Y[n + 3 + b, i], Y[n + 3 + c, i], gb,
                                                                       gc, sn, k, 1.0, 1.0)
        for i in range(m):  # MEGNO after: plus ln |δ1|², then Ys1's half of the trapezoid
            norm2 = 0.0
            for j in range(n, 2 * n):
                norm2 += Y[j, i] * Y[j, i]
            Y[rows - 2, i] += elapsed * math.log(norm2)
            Y[rows - 1, i] += 0.5 * h * Y[rows - 2, i] / elapsed
