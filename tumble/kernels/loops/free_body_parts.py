"""The free body's parts of the one time loop (:func:`tumble.kernels.loops.block_loop.run_block`): its step of each method,
torque-free or with a torque, its invariants and their drift screen, and the flips of its spin axis.

Inlined into the loop's overloads where they can be (``inline=True``): each function compiled on its own costs a first
call about a second more of numba's pipeline (``benchmarks/first_call.py``).

The free body is the one system whose steps are not generated from a rate: :mod:`tumble.kernels.steps.fused` spells each
method out on ``(w1, w2, w3)`` (the splittings ending on each sample's own ``|L|**2``), and with a torque the
splittings run as compositions of sub-flows (:mod:`tumble.kernels.steps.steppers`). Its state is the body-frame angular
velocity, its constants the tuple :func:`tumble.kernels.steps.steppers.body_constants`.
"""

from ...registry import STEPPING
from ..steps import fused, steppers
from ..steps.drift_screen import suspect
from ..jit import jit
from ..steps.steppers import energy, euler_rate, implicit_midpoint_block, l_squared
from ..tableaux import ALL_METHODS, IMPLICIT_MIDPOINT, Splitting
from ..trig import _max, _min

__all__ = ["TORQUE_SPLITTINGS", "drift_suspects", "invariants", "method_step", "observe_flips"]

#: Each method's step of a block, by kernel id (a method's index in the registry's table of fixed-step methods): the
#: generated ones (:mod:`tumble.kernels.steps.fused`, ``<method>_block``: torque-free, and the Runge–Kutta methods with a
#: torque too), and the splittings' compositions of sub-flows with a torque (:mod:`tumble.kernels.steps.steppers`,
#: ``<method>_torque_block``).
_FUSED_STEPS = {STEPPING.index(m.name): getattr(fused, f"{m.name}_block") for m in ALL_METHODS
                if hasattr(fused, f"{m.name}_block")}
TORQUE_SPLITTINGS = {STEPPING.index(m.name): getattr(steppers, f"{m.name}_torque_block") for m in ALL_METHODS
                     if isinstance(m, Splitting)}
_IMPLICIT_MIDPOINT = STEPPING.index(IMPLICIT_MIDPOINT.name)


def method_step(method, torque_free):
    """The step of a block of method ``method`` (its index in :data:`tumble.registry.STEPPING`), torque-free or with a
    torque: ``step(y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params, torque_fn)``, ``target``
    each sample's initial ``|L|**2`` (the torque-free splittings end on it)."""
    if method == _IMPLICIT_MIDPOINT:
        return _midpoint_step
    if not torque_free and method in TORQUE_SPLITTINGS:
        return _TORQUE_SPLITTING_STEPS[method]
    return _FUSED_STEPS[method]


@jit(inline=True)
def _midpoint_step(y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params, torque_fn):
    implicit_midpoint_block(y1, y2, y3, active, t, h, body, work, torque_kind, torque_params, torque_fn)


def _torque_splitting_step(splitting):
    @jit(inline=True)
    def step(y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params, torque_fn):
        splitting(y1, y2, y3, t, h, body, torque_kind, torque_params, torque_fn)

    return step


_TORQUE_SPLITTING_STEPS = {method: _torque_splitting_step(splitting) for method, splitting in TORQUE_SPLITTINGS.items()}


@jit(inline=True)
def invariants(w1, w2, w3, body):
    """The loop's three invariants and their scales: the energy ``½ sum I_i w_i²`` (J), ``|L|²`` ((kg m² rad/s)²),
    and nothing (0, scale 1); each its own scale (both are sign-definite)."""
    e, l2 = energy(w1, w2, w3, body), l_squared(w1, w2, w3, body)
    return e, l2, 0.0, e, l2, 1.0


@jit(inline=True)
def drift_suspects(ys, active, body, x0, inverse_scale, screen):
    """Whether any active sample of a block is non-finite or has drifted beyond ``screen``: one branch-free pass that
    vectorises across samples (:func:`tumble.kernels.steps.drift_screen.suspect`)."""
    suspects = 0
    for i in range(ys.shape[1]):
        w1, w2, w3 = ys[0, i], ys[1, i], ys[2, i]
        suspects += suspect(i, active, x0, inverse_scale, screen, energy(w1, w2, w3, body),
                            l_squared(w1, w2, w3, body), 0.0, w1 + w2 + w3)
    return suspects > 0


# Newton iterations on the cubic Hermite interpolant that locates a sign change inside a step.
_FLIP_NEWTON = 4


@jit(inline=True)
def _hermite_root(y0, d0, y1, d1, h):
    """Fraction ``s`` in [0, 1] of the step where the cubic Hermite interpolant of ``(y0, d0), (y1, d1)``
    vanishes; linear interpolation refined by Newton steps (O(h**4) accurate in time)."""
    s = y0 / (y0 - y1)
    for _ in range(_FLIP_NEWTON):
        s2 = s * s
        s3 = s2 * s
        p = ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * h * d0 + (-2 * s3 + 3 * s2) * y1
             + (s3 - s2) * h * d1)
        dp = ((6 * s2 - 6 * s) * y0 + (3 * s2 - 4 * s + 1) * h * d0 + (-6 * s2 + 6 * s) * y1
              + (3 * s2 - 2 * s) * h * d1)
        if dp != 0.0:
            s = s - p / dp
        s = _min(1.0, _max(0.0, s))
    return s


@jit(inline=True)
def _component(w1, w2, w3, k):
    """Component ``k`` (0-based) of ``(w1, w2, w3)``."""
    if k == 0:
        return w1
    return w2 if k == 1 else w3


@jit(inline=True)
def _flip_in_step(axis, t, h, p1, p2, p3, w1, w2, w3, body, torque_kind, torque_params, torque_fn):
    """``(flipped, time)``: whether the ``axis`` component changed sign during the step ``[t, t + h]`` from
    ``(p1, p2, p3)`` to ``(w1, w2, w3)``, and when (cubic Hermite interpolation, s; 0.0 when it did not)."""
    ya, yp = _component(w1, w2, w3, axis), _component(p1, p2, p3, axis)
    if (ya < 0.0 < yp) or (yp < 0.0 < ya) or (ya == 0.0 and yp != 0.0):
        r1, r2, r3 = euler_rate(t, p1, p2, p3, body, torque_kind, torque_params, torque_fn)
        d0 = _component(r1, r2, r3, axis)
        r1, r2, r3 = euler_rate(t + h, w1, w2, w3, body, torque_kind, torque_params, torque_fn)
        d1 = _component(r1, r2, r3, axis)
        return True, t + h * _hermite_root(yp, d0, ya, d1, h)
    return False, 0.0


@jit  # not inlined: compiled on its own, numba prunes the torque function's branch when there is none
def observe_flips(ys, previous, active, axis, t, h, body, flips, flip_count, lo, torque_kind, torque_params,
                  torque_fn):
    """Record sign changes of the ``axis`` component during the step ``[t, t + h]``: their times into ``flips`` (N, F)
    (the first F), their number into ``flip_count`` (N,)."""
    for i in range(ys.shape[1]):
        if active[i]:
            flipped, time = _flip_in_step(axis, t, h, previous[0, i], previous[1, i], previous[2, i], ys[0, i],
                                          ys[1, i], ys[2, i], body, torque_kind, torque_params, torque_fn)
            if flipped:
                count = flip_count[lo + i]
                if count < flips.shape[1]:
                    flips[lo + i, count] = time
                flip_count[lo + i] = count + 1
