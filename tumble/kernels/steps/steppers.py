"""Hand-written pieces of every step: Euler's equations, the torque, the exact sub-flows.

The per-sample step functions in :mod:`tumble.kernels.steps.fused` are generated from the coefficient tables
(:mod:`tumble.kernels.steps.codegen`) and call the small inline functions below. Everything works on scalars of
one sample, so that a loop over the samples of a block compiles to packed SIMD code with the state in
registers.

Euler's equations with body torque ``N`` (Landau & Lifshitz §36):
``I1 w1' = (I2 - I3) w2 w3 + N1`` and cyclic.

``body`` is the tuple made by :func:`body_constants`. The torque is evaluated by :func:`body_torque`;
``torque_params is None`` means torque-free; otherwise ``torque_kind`` picks one of the built-in profiles, or
``torque_fn`` (a user's jitted ``f(t, w1, w2, w3) -> (N1, N2, N3)``) is called. Each choice is made by the types at
compile time (overloads), so a step holds the code of its own torque and no other.
"""

import math
import warnings

import numpy as np
from numba.core import types
from numba.core.errors import NumbaIRAssumptionWarning
from numba.extending import overload

from ...registry import FREE_BODY, TORQUE_USER, rigid_body, torque_profile  # noqa: F401  (TORQUE_USER re-exported)
from ..jit import FASTMATH, jit
from ..systems import SYSTEMS
from ..tableaux import ROTATE_1, ROTATE_2, SPLITTING2, SPLITTING4, SYMPLECTIC_EULER, TORQUE
from ..trig import _min, sincos

# Built-in torque profiles (numeric parameters only, so that studies stay data). params = (N1, N2, N3, tau):
# the vector (N m, body frame) and the profile's time scale tau (s; unused by the constant profile).
# Codes from the registry's table (a pulse: a fixed step across the jump errs O(h) once).
TORQUE_CONSTANT, TORQUE_RAMP, TORQUE_SINE, TORQUE_PULSE = (torque_profile(name).code
                                                           for name in ("constant", "ramp", "sine", "pulse"))

#: Euler's equations (``a_i w_j w_k``) as the free body's system writes them (the gyrostat's module, ``h = 0``).
euler = SYSTEMS[FREE_BODY].euler

# Implicit midpoint: fixed-point iterations stop once the update is below this many ulps of the state.
_MIDPOINT_ULPS = 4.0
_MIDPOINT_MAX_ITERATIONS = 60
_EPS = 2.220446049250313e-16


def body_constants(moments):
    """``(I1, I2, I3, a1, a2, a3, I2/I1, I3/I1, I1/I2, I3/I2, I1/I3, I2/I3)`` for the kernels.

    The first six are every system's (:func:`tumble.registry.rigid_body`: ``a1 = (I2 - I3)/I1`` and cyclic, the
    coefficients of Euler's equations); the ratios serve the exact rotations of the splittings.
    """
    i1, i2, i3 = np.asarray(moments, dtype=float).tolist()
    return (*rigid_body((i1, i2, i3)), i2 / i1, i3 / i1, i1 / i2, i3 / i2, i1 / i3, i2 / i3)


def body_torque(t, w1, w2, w3, torque_kind, torque_params, torque_fn):
    """Body-frame torque (N m) at time ``t`` (s) and angular velocity ``w`` (rad/s): ``torque_fn``'s where one is
    given, else the profile ``torque_kind`` of ``torque_params``; chosen by type (:func:`_body_torque_of`)."""


# Not inline="always": numba-cuda could not type the inlined stand-ins (eq of two omitted arguments), so no device
# kernel compiled for a GPU; compiled out of line, a torque run's results moved by ulps.
_STAND_IN = dict(jit_options=dict(fastmath=set(FASTMATH), error_model="numpy"))
# numba's pedantic check of the profile's branches once inlined (a phi's variable "not in scope"): the compiled step
# is right (its results are the bits of the profile inlined as a plain function), the warning only noise to a user
warnings.filterwarnings("ignore", message="variable '_body_torque_of__locals__profile",
                        category=NumbaIRAssumptionWarning)


@overload(body_torque, **_STAND_IN)
def _body_torque_of(t, w1, w2, w3, torque_kind, torque_params, torque_fn):
    if not isinstance(torque_fn, types.NoneType):
        def users(t, w1, w2, w3, torque_kind, torque_params, torque_fn):
            return torque_fn(t, w1, w2, w3)

        return users

    def profile(t, w1, w2, w3, torque_kind, torque_params, torque_fn):
        return profile_torque(t, torque_kind, torque_params)

    return profile


@jit(inline=True)
def profile_torque(t, torque_kind, torque_params):
    """The built-in profile ``torque_kind`` of ``torque_params`` at time ``t`` (s), N m."""
    scale = 1.0
    if torque_kind == TORQUE_RAMP:
        scale = _min(t / torque_params[3], 1.0)
    elif torque_kind == TORQUE_SINE:
        scale = math.sin(2.0 * math.pi * t / torque_params[3])
    elif torque_kind == TORQUE_PULSE:
        scale = 1.0 if t < torque_params[3] else 0.0
    return scale * torque_params[0], scale * torque_params[1], scale * torque_params[2]


@jit(inline=True)
def euler_rate(t, w1, w2, w3, body, torque_kind, torque_params, torque_fn):
    """``w'`` (rad/s²): Euler's equations as the free body's system writes them
    (:func:`tumble.kernels.systems.gyrostat.euler`, the gyrostat's ``h = 0``), plus the torque over ``I``."""
    d1, d2, d3 = euler(w1, w2, w3, body[3], body[4], body[5])
    return _plus_torque(t, w1, w2, w3, d1, d2, d3, body, torque_kind, torque_params, torque_fn)


def _plus_torque(t, w1, w2, w3, d1, d2, d3, body, torque_kind, torque_params, torque_fn):
    """``d + N / I`` (:func:`body_torque`), or ``d`` itself when ``torque_params`` is None: chosen by type, so that a
    torque-free step never holds the torque's code (a branch on ``is not None`` inlined into each stage of a step
    was typed before it was pruned: 0.4 s of an rk4 first call)."""


@overload(_plus_torque, **_STAND_IN)
def _plus_torque_of(t, w1, w2, w3, d1, d2, d3, body, torque_kind, torque_params, torque_fn):
    if isinstance(torque_params, types.NoneType):
        def torque_free(t, w1, w2, w3, d1, d2, d3, body, torque_kind, torque_params, torque_fn):
            return d1, d2, d3

        return torque_free

    def torqued(t, w1, w2, w3, d1, d2, d3, body, torque_kind, torque_params, torque_fn):
        n1, n2, n3 = body_torque(t, w1, w2, w3, torque_kind, torque_params, torque_fn)
        return d1 + n1 / body[0], d2 + n2 / body[1], d3 + n3 / body[2]

    return torqued


@jit(inline=True)
def rotate(theta, wb, wc, r_cb, r_bc):
    """Exact flow of ``H_a = L_a**2 / (2 I_a)``: ``(L_b, L_c)`` turns by ``theta = w_a tau``.

    With ``(a, b, c)`` cyclic, ``L_b <- cos(theta) L_b + sin(theta) L_c`` and
    ``L_c <- -sin(theta) L_b + cos(theta) L_c`` (McLachlan 1993); in ``w``, with ``r_cb = I_c/I_b`` and
    ``r_bc = I_b/I_c``. ``|L|`` is kept to round-off.
    """
    s, c = sincos(theta)
    return c * wb + s * r_cb * wc, c * wc - s * r_bc * wb


@jit(inline=True)
def rotate_about(flow, tau, w1, w2, w3, body):
    """The exact flow of ``H_a`` (:func:`rotate`) over ``tau`` for one sample, ``a`` = ``flow``
    (:data:`tumble.kernels.tableaux.ROTATE_1` ... ``ROTATE_3``): the per-sample sub-flow of every splitting, with a
    torque (:func:`splitting_with_torque`) and on the device (:mod:`tumble.kernels.cuda.rigid_body`)."""
    if flow == ROTATE_1:
        w2, w3 = rotate(w1 * tau, w2, w3, body[9], body[11])
    elif flow == ROTATE_2:
        w3, w1 = rotate(w2 * tau, w3, w1, body[10], body[7])
    else:
        w1, w2 = rotate(w3 * tau, w1, w2, body[6], body[8])
    return w1, w2, w3


@jit
def rotate_block(axis, tau, y1, y2, y3, body):
    """The exact flow of ``H_a`` (:func:`rotate`) over ``tau`` for every sample of a block: ``(w_b, w_c)`` turns
    by ``w_a tau``, ``a = axis`` (0-based), ``(a, b, c)`` cyclic. One loop per axis, each vectorised across the
    samples; a splitting's step is a sequence of these (:mod:`tumble.kernels.steps.fused`)."""
    n = y1.shape[0]
    if axis == 0:
        for i in range(n):
            y2[i], y3[i] = rotate(y1[i] * tau, y2[i], y3[i], body[9], body[11])
    elif axis == 1:
        for i in range(n):
            y3[i], y1[i] = rotate(y2[i] * tau, y3[i], y1[i], body[10], body[7])
    else:
        for i in range(n):
            y1[i], y2[i] = rotate(y3[i] * tau, y1[i], y2[i], body[6], body[8])


@jit  # not inlined: six inlined copies in splitting4 cost minutes of compile time for torque scenes
def torque_subflow(t, tau, w1, w2, w3, body, torque_kind, torque_params, torque_fn):
    """Torque sub-flow ``w' = N(t, w) / I`` over ``tau`` by one classical RK4 step.

    Exact for a constant torque; its local error O(tau**5) keeps the documented order of every composition up
    to four.
    """
    i1, i2, i3 = body[0], body[1], body[2]
    half = 0.5 * tau
    a1, a2, a3 = body_torque(t, w1, w2, w3, torque_kind, torque_params, torque_fn)
    b1, b2, b3 = body_torque(t + half, w1 + half * a1 / i1, w2 + half * a2 / i2, w3 + half * a3 / i3,
                             torque_kind, torque_params, torque_fn)
    c1, c2, c3 = body_torque(t + half, w1 + half * b1 / i1, w2 + half * b2 / i2, w3 + half * b3 / i3,
                             torque_kind, torque_params, torque_fn)
    d1, d2, d3 = body_torque(t + tau, w1 + tau * c1 / i1, w2 + tau * c2 / i2, w3 + tau * c3 / i3,
                             torque_kind, torque_params, torque_fn)
    sixth = tau / 6.0
    return (w1 + sixth * (a1 + 2.0 * (b1 + c1) + d1) / i1,
            w2 + sixth * (a2 + 2.0 * (b2 + c2) + d2) / i2,
            w3 + sixth * (a3 + 2.0 * (b3 + c3) + d3) / i3)


@jit
def splitting_with_torque(w1, w2, w3, t, h, body, flows, fractions, torque_kind, torque_params, torque_fn):
    """One step of a composition of exact sub-flows with torque sub-flows, for one sample.

    ``flows[i]`` (:data:`tumble.kernels.tableaux.ROTATE_1` ... ``ROTATE_3`` or ``TORQUE``) runs for
    ``fractions[i] * h``. A loop rather than a spelled-out step: with a torque the step is bound by the torque
    calls, and the loop compiles in seconds instead of minutes, to the same bits.
    """
    clock = t
    for i in range(flows.shape[0]):
        tau = fractions[i] * h
        flow = flows[i]
        if flow == TORQUE:
            w1, w2, w3 = torque_subflow(clock, tau, w1, w2, w3, body, torque_kind, torque_params, torque_fn)
            clock += tau
        else:
            w1, w2, w3 = rotate_about(flow, tau, w1, w2, w3, body)
    return w1, w2, w3


@jit
def splitting_free_sample(w1, w2, w3, h, body, target, flows, fractions):
    """One torque-free step of a composition of exact sub-flows for one sample, ending on ``|L|**2 = target``.

    The sample-by-sample form of the generated torque-free block steps of :mod:`tumble.kernels.steps.fused` (which turn
    the whole block sub-flow by sub-flow, then project each sample): the same sub-flows (:func:`rotate_about`) in
    the same order, for the device's one thread per sample (:mod:`tumble.kernels.cuda.rigid_body`).
    """
    for i in range(flows.shape[0]):
        w1, w2, w3 = rotate_about(flows[i], fractions[i] * h, w1, w2, w3, body)
    return project_l_squared(w1, w2, w3, target, body)


def make_splitting_torque_block(splitting):
    """One step of ``splitting`` with torque sub-flows (:func:`splitting_with_torque`) for every sample of a block.

    The drivers call these for the splittings with a torque, so that the spelled-out torque-free steps of
    :mod:`tumble.kernels.steps.fused` are compiled only for torque-free runs. The sub-flows and fractions are constants
    of the closure (as the generated steps' tables are globals), so the compiler unrolls the loop over them.
    """
    flows, fractions = splitting.flows, splitting.fractions

    @jit
    def splitting_torque_block(y1, y2, y3, t, h, body, torque_kind, torque_params, torque_fn):
        for i in range(y1.shape[0]):
            y1[i], y2[i], y3[i] = splitting_with_torque(y1[i], y2[i], y3[i], t, h, body, flows, fractions,
                                                        torque_kind, torque_params, torque_fn)

    return splitting_torque_block


symplectic_euler_torque_block = make_splitting_torque_block(SYMPLECTIC_EULER)
splitting2_torque_block = make_splitting_torque_block(SPLITTING2)
splitting4_torque_block = make_splitting_torque_block(SPLITTING4)


@jit(inline=True)
def l_squared(w1, w2, w3, body):
    """``|L|**2 = sum (I_i w_i)**2``, (kg m² rad/s)²."""
    l1, l2, l3 = body[0] * w1, body[1] * w2, body[2] * w3
    return l1 * l1 + l2 * l2 + l3 * l3


@jit(inline=True)
def energy(w1, w2, w3, body):
    """Kinetic energy ``½ sum I_i w_i**2``, J."""
    return 0.5 * (body[0] * w1 * w1 + body[1] * w2 * w2 + body[2] * w3 * w3)


@jit(inline=True)
def project_l_squared(w1, w2, w3, target, body):
    """Rescale ``w`` onto ``|L|**2 = target`` (a few-ulp correction that stops round-off random-walking).

    The factor ``sqrt(target/now)`` is within an ulp of 1, where doubles are too coarse to hold it: ``w *
    (1 - 2**-53)`` drops each component by one of *its own* ulps, a relative change of 1.1e-16 ... 2.2e-16
    set by its mantissa, so the rescaling would not be uniform and would bias the energy (splitting4's drifted
    linearly, ~3e-18 per step). The correction is applied additively instead, ``w + w d`` with ``d =
    sqrt(target/now) - 1 = (target - now) / (now + sqrt(target now))`` formed without cancellation.
    """
    d = rescale_step(target, l_squared(w1, w2, w3, body))
    return w1 + w1 * d, w2 + w2 * d, w3 + w3 * d


@jit(inline=True)
def rescale_step(target, now):
    """``d = sqrt(target / now) − 1`` formed without cancellation, ``(target − now) / (now + sqrt(target now))``
    (0 where ``now`` is 0): a state's additive correction ``y + y d`` onto a squared norm ``target``
    (:func:`project_l_squared`)."""
    return (target - now) / (now + math.sqrt(target * now)) if now > 0.0 else 0.0


@jit(inline=True)
def implicit_midpoint_sample(w1, w2, w3, t, h, body, torque_kind, torque_params, torque_fn):
    """One implicit-midpoint step ``y1 = y0 + h f(t + h/2, (y0 + y1)/2)`` of one sample (the signature of the
    generated ``<method>_sample`` steps of :mod:`tumble.kernels.steps.fused`, so that the device kernel runs it as theirs).

    The midpoint ``z = y0 + (h/2) f(t + h/2, z)`` is found by fixed-point iteration (Hairer, Lubich & Wanner, sect.
    VIII.6), stopping once the update is below a few ulps of the state (a NaN compares false and stops too); then
    ``y1 = 2 z - y0``. A sample whose iteration has not converged after ``_MIDPOINT_MAX_ITERATIONS`` sweeps (the step
    is too large for the fixed-point solver, ``h |ω|`` near 2 or above) is NaN, so that the engine flags it
    non-finite rather than keep a half-solved step.
    """
    half = 0.5 * h
    tm = t + half
    z1, z2, z3 = w1, w2, w3
    for _ in range(_MIDPOINT_MAX_ITERATIONS):
        f1, f2, f3 = euler_rate(tm, z1, z2, z3, body, torque_kind, torque_params, torque_fn)
        n1 = w1 + half * f1
        n2 = w2 + half * f2
        n3 = w3 + half * f3
        change = abs(n1 - z1) + abs(n2 - z2) + abs(n3 - z3)
        size = abs(n1) + abs(n2) + abs(n3)
        z1, z2, z3 = n1, n2, n3
        if not change > _MIDPOINT_ULPS * _EPS * size:
            return 2.0 * z1 - w1, 2.0 * z2 - w2, 2.0 * z3 - w3
    return math.nan, math.nan, math.nan


@jit
def implicit_midpoint_block(y1, y2, y3, active, t, h, body, work, torque_kind, torque_params, torque_fn):
    """The implicit midpoint rule on a block (:func:`implicit_midpoint_sample` for each active sample; keeps
    quadratic invariants). Each sample iterates until its own update is below a few ulps, so its result does not
    depend on its neighbours in the block. ``work`` is not used (the driver calls every block alike)."""
    for i in range(y1.shape[0]):
        if active[i]:
            y1[i], y2[i], y3[i] = implicit_midpoint_sample(y1[i], y2[i], y3[i], t, h, body, torque_kind,
                                                           torque_params, torque_fn)


