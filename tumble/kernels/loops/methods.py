"""The fixed-step methods by name, and the call that runs one of them on an ensemble with its observers."""

import math
from typing import NamedTuple

import numpy as np

from ...registry import STEPPING
from .. import tableaux
from ..steps.attitude import FAMILY_MIDPOINT, FAMILY_RUNGE_KUTTA, FAMILY_SPLITTING, propagate_attitude
from ..jit import jit
from .drivers import driver
from ..threads import in_parallel
from ..steps.steppers import TORQUE_CONSTANT, body_constants

__all__ = ["BLOCK", "METHODS", "Method", "Observed", "SPIN_EXPONENT", "attitude_spin_scale", "from_kernel_frame",
           "kernel_frame", "kernel_observed_axis", "run", "run_attitude", "spin_unit"]

# Samples per SIMD block: large enough to amortise the per-step dispatch, small enough to stay in L1.
BLOCK = 256

_NO_STEPS = np.zeros(0, dtype=np.int64)
_UNIT_WEIGHTS = np.ones(3)  # the Euclidean transverse norm (read only by the kernels)
# The outputs of observers a run does not ask for: empty, so the driver never writes them (shared, not allocated
# per call; writable, as the driver's signature has them).
_NO_SAVED = np.empty((0, 3, 0))
_NO_ROWS = np.empty((0, 0))
_NO_ROW = np.empty(0)


class Method(NamedTuple):
    """A fixed-step integrator: its kernel id, nominal order and coefficients."""

    name: str
    kernel_id: int
    order: int
    coefficients: object  # ButcherTableau, Splitting or ImplicitMidpoint

    @property
    def splitting(self):
        """The composition of exact sub-flows, or None for a Runge–Kutta method."""
        return self.coefficients if isinstance(self.coefficients, tableaux.Splitting) else None

    @property
    def geometric(self):
        """Keeps ``|L|**2`` to round-off (the midpoint rule keeps the energy too)."""
        return not isinstance(self.coefficients, tableaux.ButcherTableau)


_COEFFICIENTS = {m.name: m for m in tableaux.ALL_METHODS}

#: The fixed-step methods of :data:`tumble.registry.STEPPING`, with their kernel ids (index in that table) and
#: coefficients; ``tests/test_layers.py`` checks the tables agree (names, orders).
METHODS = {name: Method(name, i, _COEFFICIENTS[name].order, _COEFFICIENTS[name]) for i, name in enumerate(STEPPING)}


class Observed(NamedTuple):
    """What a run returns; an output that was not asked for is None."""

    saved: np.ndarray | None  # (n_saved, 3, N), rad/s
    probes: np.ndarray | None  # (P, N), transverse norm, rad/s
    flips: np.ndarray | None  # (N, F), s
    flip_count: np.ndarray | None  # (N,)
    drift: np.ndarray | None  # (2, N): max |E/E0 - 1|, max ||L|²/|L0|² - 1|
    status: np.ndarray  # (N,) int8
    steps_taken: np.ndarray  # (N,) int64
    growth: tuple | None = None  # the device's growth fit (tumble.kernels.cuda.rigid_body.run): rate, points, first, last (N,)
    phase: tuple | None = None  # the device's phase fit (tumble.kernels.cuda.rigid_body.run): frequency, radius, code (N,)


def _relabelling(method, moments, torque_params, torque_fn):
    """Axis order for the kernel frame: splittings turn about the axes by ascending moment (measured: the
    smallest errors), so their axes are relabelled; ``u = sign * w[perm]`` solves Euler's equations with
    moments ``I[perm]`` (an odd permutation reverses the sense of rotation, hence the sign)."""
    if method.splitting is None or torque_fn is not None:
        return None
    perm = np.argsort(moments, kind="stable")
    if np.array_equal(perm, [0, 1, 2]):
        return None
    sign = float(np.linalg.det(np.eye(3)[perm]))
    return perm, sign


def _in_moment_units(moments, torque_params, torque_fn):
    """Moments (and a built-in torque's vector) divided by the power of two nearest the largest moment.

    Euler's equations ``I w' = (I w) x w + N`` do not change when ``I`` and ``N`` are multiplied by one number,
    and a power of two changes no bit of the kernels' coefficients or relative drifts; it keeps ``|L|^2`` and the
    energy of moments of 1e-170 or 1e200 kg m² in range. A torque function returns newton metres: then nothing
    is rescaled.
    """
    moments = np.asarray(moments, dtype=float)
    if torque_fn is not None:
        return moments, torque_params
    unit = math.ldexp(1.0, -math.frexp(float(moments.max()))[1])
    if torque_params is not None:
        torque_params = np.asarray(torque_params, dtype=float).copy()
        torque_params[:3] *= unit
    return moments * unit, torque_params


# Moments in units (and their kernel constants) of the bodies torque-free Runge–Kutta runs have seen: a user's loop
# of small calls on one body computes them once (the same numbers as _in_moment_units and body_constants give).
_TORQUE_FREE_CONSTANTS = {}


def _torque_free_constants(moments):
    """``(moments in units, body_constants of them)`` of :func:`_in_moment_units` for a torque-free run, cached by
    the moments' bytes (at most 64 bodies kept)."""
    moments = np.asarray(moments, dtype=float)
    key = moments.tobytes()
    found = _TORQUE_FREE_CONSTANTS.get(key)
    if found is None:
        scaled = _in_moment_units(moments, None, None)[0]
        scaled.setflags(write=False)
        found = (scaled, body_constants(scaled))
        if len(_TORQUE_FREE_CONSTANTS) >= 64:
            _TORQUE_FREE_CONSTANTS.clear()
        _TORQUE_FREE_CONSTANTS[key] = found
    return found


#: A torque-free run whose largest spin component lies beyond ``2**±SPIN_EXPONENT`` rad/s is stepped rescaled
#: (:func:`spin_unit`); within, no bit changes.
SPIN_EXPONENT = 256


@jit
def _magnitudes(w):
    """``(largest, smallest)`` of the samples' largest spin components ``max_i |w[i, j]|`` (the smallest over the
    samples that spin; a NaN is passed over), in one pass: numpy's reductions took 3 us of a small call."""
    top = 0.0
    low = math.inf
    for j in range(w.shape[1]):
        size = max(max(abs(w[0, j]), abs(w[1, j])), abs(w[2, j]))
        top = max(top, size)
        low = min(low, size) if size > 0.0 else low
    return top, low


def spin_unit(w):
    """1.0, or the power of two ``s`` that brings the largest spin component of a torque-free run near 1 rad/s when it
    lies beyond ``2**±SPIN_EXPONENT`` rad/s and every sample that spins stays within that range after it.

    ``u(tau) = s w(s tau)`` solves Euler's equations too (and the attitude ``q(s tau)`` its own), so :func:`run` and
    :func:`run_attitude` (and the device's, :mod:`tumble.kernels.cuda.rigid_body`) step ``s w`` with the step ``h / s``
    and give back the states, norms, times and rates exactly (a power of two). Unscaled, the products ``w_i w_j`` of spins
    below about 1e-154 rad/s underflow (the spin stands still with status ok) and ``|L|^2`` above about 1e154 rad/s
    overflows (``benchmarks/stress.py``). An ensemble that spans more than ``2**SPIN_EXPONENT`` is not rescaled (one
    scale cannot keep both ends)."""
    top, low = _magnitudes(w)
    if not 0.0 < top < math.inf:  # at rest, or an infinite component (the kernels flag it)
        return 1.0
    exponent = math.frexp(top)[1]
    if abs(exponent) <= SPIN_EXPONENT or math.frexp(low)[1] < exponent - SPIN_EXPONENT:
        return 1.0
    return math.ldexp(1.0, -exponent)


def attitude_spin_scale(w, t0, h, torque_free):
    """``(w, t0, h, unit)`` of an attitude run (``w`` (N, 3)) as :func:`spin_unit` rescales it, for :func:`run_attitude`
    and the device's: ``s w``, ``t0 / s``, ``h / s`` (the attitude ``q(s tau)`` is the same); unchanged, with
    ``unit`` 1.0, within ``2**±SPIN_EXPONENT`` rad/s or with a torque."""
    w = np.asarray(w, dtype=float)
    unit = spin_unit(np.ascontiguousarray(w.T)) if torque_free else 1.0
    return (w * unit, t0 / unit, h / unit, unit) if unit != 1.0 else (w, t0, h, unit)


def kernel_frame(method, w, moments, torque_params, torque_fn):
    """The frame a kernel runs in, shared by the CPU driver and the device (:mod:`tumble.kernels.cuda.rigid_body`).

    Moments (and a built-in torque's vector) in units of :func:`_in_moment_units`, and for a splitting the axes
    relabelled by :func:`_relabelling`.

    Parameters
    ----------
    method : Method
    w : ndarray, shape (3, N)
        Body-frame angular velocities, rad/s (structure of arrays).
    moments : ndarray, shape (3,)
        Principal moments, kg m².
    torque_params, torque_fn
        As :func:`run`.

    Returns
    -------
    kernel_w : ndarray, shape (3, N)
        ``w`` itself, or its relabelled copy.
    constants : tuple
        :func:`tumble.kernels.steps.steppers.body_constants` of the moments in the kernel frame.
    torque_params : ndarray (4,) or None
        In moment units and the kernel frame.
    relabel : tuple or None
        ``(perm, sign)``, undone by :func:`from_kernel_frame`.
    """
    if torque_params is None and torque_fn is None and method.splitting is None:
        return w, _torque_free_constants(moments)[1], None, None  # the common case, without numpy round trips
    moments, torque_params = _in_moment_units(moments, torque_params, torque_fn)
    relabel = _relabelling(method, moments, torque_params, torque_fn)
    if relabel is not None:
        perm, sign = relabel
        w = np.ascontiguousarray(sign * w[perm])
        moments = moments[perm]
        if torque_params is not None:
            torque_params = np.asarray(torque_params, dtype=float).copy()  # (N1, N2, N3, tau): turn the vector
            torque_params[:3] = sign * torque_params[perm]
    return w, body_constants(moments), torque_params, relabel


def kernel_observed_axis(relabel, axis, norm_weights):
    """The spin axis (0-based) and the transverse norm's weights (ndarray (3,)) in the kernel frame of
    :func:`kernel_frame` (``relabel``), from ``axis`` and ``norm_weights`` (None: all 1) in the body's; shared by the
    CPU driver and the device."""
    weights = _UNIT_WEIGHTS if norm_weights is None else np.ascontiguousarray(norm_weights, dtype=float)
    if relabel is None:
        return axis, weights
    perm, _ = relabel
    return int(np.argsort(perm)[axis]), weights[perm]


def from_kernel_frame(relabel, x, axis=0):
    """``x`` (components along ``axis``) back from the kernel frame of :func:`kernel_frame`."""
    if relabel is None:
        return x
    perm, sign = relabel
    return sign * np.take(x, np.argsort(perm), axis=axis)


def run(method, w, moments, t0, h, n_steps, *, save_every=0, axis=0, norm_weights=None, probe_steps=None,
        max_flips=0,
        drift=False, stop_norm=0.0, stop_flips=0, drift_limit=0.0, torque_kind=TORQUE_CONSTANT,
        torque_params=None, torque_fn=None, block=BLOCK):
    # size: the kernels' door for the engine: keywords per observer and stop request, packed here into the driver's
    # flat arrays
    """Integrate an ensemble with a named fixed-step method, observing only what is asked.

    Parameters
    ----------
    method : Method
    w : ndarray, shape (3, N), float64, C-contiguous
        Initial body-frame angular velocities, rad/s (structure of arrays); overwritten with the final state.
    moments : ndarray, shape (3,)
        Principal moments, kg m².
    t0, h : float
        Start time and step, s.
    n_steps : int
    save_every : int
        0 stores no trajectory; k > 0 stores the initial state, every k-th step and the final state.
    axis : int
        0-based spin axis for the transverse norm and the flips.
    norm_weights : array_like (3,), optional
        Weights ``g`` of the transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` (default all 1: the Euclidean norm).
    probe_steps : array_like of int, optional
        Steps after which to record the transverse norm (0 = initial state), increasing.
    max_flips : int
        Record the times of the first ``max_flips`` sign changes of the ``axis`` component (0: off).
    drift : bool
        Record the running maximum of the relative energy and ``|L|**2`` errors.
    stop_norm, stop_flips, drift_limit
        Early stop and blow-up detection, see :func:`tumble.kernels.loops.drivers.make_propagate`.
    torque_kind, torque_params, torque_fn
        ``torque_params=None`` and ``torque_fn=None``: torque-free (compiled out).
    block : int
        Samples per SIMD block; results do not depend on it.

    Returns
    -------
    Observed
    """
    n = w.shape[1]
    torque_free = torque_params is None and torque_fn is None
    unit = spin_unit(w) if torque_free else 1.0  # beyond 2**±256 rad/s: stepped as s w, with h / s
    if unit != 1.0:
        w *= unit
        t0, h, stop_norm = t0 / unit, h / unit, stop_norm * unit
    kernel_w, constants, torque_params, relabel = kernel_frame(method, w, moments, torque_params, torque_fn)
    kernel_axis, weights = kernel_observed_axis(relabel, axis, norm_weights)
    if torque_fn is not None and torque_params is None:
        torque_params = np.zeros(0)

    n_saved = 0
    if save_every > 0:
        n_saved = 1 + n_steps // save_every + (1 if n_steps % save_every else 0)
    # Outputs not asked for are empty arrays: the driver's observers are runtime switches (one compiled variant).
    saved = np.empty((n_saved, 3, n)) if n_saved else _NO_SAVED
    probe_steps = _NO_STEPS if probe_steps is None else np.ascontiguousarray(probe_steps, dtype=np.int64)
    probes = np.empty((len(probe_steps), n)) if len(probe_steps) else _NO_ROWS
    flips = _NO_ROWS
    if max_flips > 0:
        flips = np.empty((n, int(max_flips)))  # the loop sets every output it is given
    flip_count = np.zeros(n, dtype=np.int64)
    drifts = np.empty((2, n)) if drift else _NO_ROWS
    status = np.zeros(n, dtype=np.int8)
    steps_taken = np.zeros(n, dtype=np.int64)
    observing = len(probe_steps) > 0 or max_flips > 0 or drift or stop_norm > 0.0 or stop_flips > 0 or drift_limit > 0.0
    args = (kernel_w, constants, float(t0), float(h), int(n_steps), int(block),
            int(save_every), saved, int(kernel_axis), weights, probe_steps, probes, flips, flip_count, drifts, status,
            steps_taken, float(stop_norm), int(stop_flips), float(drift_limit), int(torque_kind), torque_params,
            torque_fn)
    in_parallel(driver(method.kernel_id, torque_free, torque_fn, observing), n, *args, granule=int(block))
    if relabel is not None:
        w[:] = from_kernel_frame(relabel, kernel_w)
        saved = from_kernel_frame(relabel, saved, axis=1)
    if unit != 1.0:  # back from s w at time t / s
        w /= unit
        saved /= unit
        probes /= unit
        flips *= unit
    return Observed(saved if save_every > 0 else None, probes if len(probe_steps) else None,
                    flips if max_flips > 0 else None, flip_count if max_flips > 0 else None, drifts if drift else None,
                    status, steps_taken)


def run_attitude(method, w, q, moments, t0, h, n_steps, *, save_every, torque_kind=TORQUE_CONSTANT,
                 torque_params=None, torque_fn=None):
    # size: the kernels' door for attitude runs: keywords packed here into the kernel's flat arrays
    """Integrate angular velocity and attitude together (:mod:`tumble.kernels.steps.attitude`).

    Parameters
    ----------
    method : Method
    w : ndarray, shape (N, 3)
        Initial body-frame angular velocities, rad/s.
    q : ndarray, shape (N, 4)
        Initial unit quaternions (scalar first) of the body-to-space rotation.
    moments : ndarray, shape (3,)
    t0, h : float
        Start time and step, s.
    n_steps, save_every : int
        Steps; the initial state, every ``save_every``-th state and the final one are stored.
    torque_kind, torque_params, torque_fn
        As :func:`run`.

    Returns
    -------
    saved_w : ndarray, shape (N, n_saved, 3)
    saved_q : ndarray, shape (N, n_saved, 4)
    status : ndarray, shape (N,), int8
    """
    w, t0, h, unit = attitude_spin_scale(w, t0, h, torque_params is None and torque_fn is None)  # as run
    frame = attitude_frame(method, w, moments, torque_params, torque_fn, n_steps, save_every)
    n = w.shape[0]
    saved_w = np.empty((frame.n_saved, n, 3))
    saved_q = np.empty((frame.n_saved, n, 4))
    status = np.zeros(n, dtype=np.int8)
    kernel_q = np.array(q, dtype=float)
    in_parallel(propagate_attitude, n, frame.family, frame.A, frame.b, frame.c, frame.flows, frame.fractions,
                np.asarray(frame.axes, dtype=np.int64), frame.sign, frame.w, kernel_q, frame.body, float(t0),
                float(h), int(n_steps), int(save_every), saved_w, saved_q, status, int(torque_kind),
                frame.torque_params, torque_fn)
    if unit != 1.0:
        saved_w /= unit
    return from_attitude_frame(frame, saved_w), saved_q.transpose(1, 0, 2), status


class AttitudeFrame(NamedTuple):
    """What an attitude run's kernel takes (:func:`attitude_frame`), on either device."""

    family: int  # attitude.FAMILY_*
    A: np.ndarray  # the tableau (Runge–Kutta; else empty)
    b: np.ndarray
    c: np.ndarray
    flows: np.ndarray  # the sub-flows and their fractions (splittings; else empty)
    fractions: np.ndarray
    axes: tuple  # the body axis (0-based) of each kernel axis
    sign: float  # the relabelling's sign
    w: np.ndarray  # (N, 3) C-contiguous, in the kernel's frame
    body: tuple  # steppers.body_constants of the moments in units and the kernel's frame
    torque_params: np.ndarray | None  # in units and the kernel's frame
    perm: np.ndarray | None  # the relabelling (None: none)
    n_saved: int  # states stored: the initial one, every save_every-th and the last


def attitude_frame(method, w, moments, torque_params, torque_fn, n_steps, save_every):
    """The kernel's frame and arguments of an attitude run (:func:`run_attitude`'s and the device's,
    :mod:`tumble.kernels.cuda.attitude_steps`): moments in units, a splitting's axes relabelled, the method's family
    and coefficients, the number of stored states."""
    moments, torque_params = _in_moment_units(moments, torque_params, torque_fn)
    coefficients = method.coefficients
    relabel = _relabelling(method, moments, torque_params, torque_fn)
    axes, sign, perm = (0, 1, 2), 1.0, None
    kernel_w = np.array(w, dtype=float)
    if relabel is not None:
        perm, sign = relabel
        axes = tuple(int(a) for a in perm)
        kernel_w = sign * kernel_w[:, perm]
        moments = moments[perm]
        if torque_params is not None:
            torque_params = np.asarray(torque_params, dtype=float).copy()
            torque_params[:3] = sign * torque_params[perm]
    if torque_fn is not None and torque_params is None:
        torque_params = np.zeros(0)
    A, b, c, flows, fractions = _NO_ROWS, _NO_ROW, _NO_ROW, _NO_STEPS, _NO_ROW
    if isinstance(coefficients, tableaux.ButcherTableau):
        family = FAMILY_RUNGE_KUTTA
        A, b, c = coefficients.A, coefficients.b, coefficients.c
    elif isinstance(coefficients, tableaux.Splitting):
        family = FAMILY_SPLITTING
        if torque_params is None:
            coefficients = coefficients.without_torque()
        flows, fractions = coefficients.flows, coefficients.fractions
    else:
        family = FAMILY_MIDPOINT
    return AttitudeFrame(family, A, b, c, flows, fractions, axes, float(sign), np.ascontiguousarray(kernel_w),
                         body_constants(moments), torque_params, perm,
                         1 + n_steps // save_every + (1 if n_steps % save_every else 0))


def from_attitude_frame(frame, saved_w):
    """The stored angular velocities (n_saved, N, 3) of an attitude run back in the body's axes, (N, n_saved, 3)."""
    if frame.perm is not None:
        saved_w = frame.sign * saved_w[:, :, np.argsort(frame.perm)]
    return saved_w.transpose(1, 0, 2)

