"""Chaos indicators of any system: :func:`lyapunov` (the Lyapunov spectrum) and :func:`megno` (MEGNO).

Regular or chaotic, and how fast do nearby motions separate? Each sample carries, beside its state, ``k`` tangent
vectors advanced by the variational equations ``δ' = J(t, y) δ`` with the same method and step as the state (the
derivative of the method's own map), orthonormalised by modified Gram–Schmidt every ``renormalise`` seconds
(Benettin, Galgani, Giorgilli & Strelcyn 1980); the exponents are the sums of ``log |R_rr|`` over the time after the
transient. MEGNO's two scalars are integrated alongside (Cincotta & Simó 2000): ``<Y> → 2`` on a quasi-periodic orbit,
``→ 0`` near a stable periodic one, ``≈ λ t / 2`` on a chaotic one. A built-in model stepped by rk4, rk8 or a
splitting runs on the CPU in blocks of samples vectorised across them (:mod:`tumble.kernels.loops.tangent_blocks`);
everything else (the implicit midpoint rule too), and the device, through the per-sample loop of
:mod:`tumble.kernels.loops.tangent_loop` (one CUDA thread per sample).

``system`` is anything the engine accepts: a :class:`~tumble.physics.bodies.Body` (the free body, as
:class:`tumble.models.FreeBody`), a built-in model (its generated rate and tangent, with any Runge–Kutta tableau of
:data:`tumble.kernels.TABLEAUX`), or a user's :class:`~tumble.physics.system.System` (its ``jacobian(t, y, p, J)`` times each tangent vector; without one,
the rate's derivative along each vector by extrapolated central differences, about 1e-12 relative:
:func:`tumble.kernels.loops.tangent_loop.difference_tangents` says why that method).
Every argument is checked once here, each refusal one line (ValueError).
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from .. import registry
from ..kernels import TABLEAUX, device_tangent_loop, rate_sample
from ..kernels import sample_loop, system_steps, tangent_blocks, tangent_loop
from ..physics.bodies import Body, one_body
from ..physics.models import FreeBody, Model
from ..physics.system import System, finite_number, with_parameters
from . import chaos_tolerance, cost
from .adaptive_runs import checked_scalars, fixed_steps_only, no_save_every, output_times
from .device import resolve_device
from .integration import checked_save_every, indexed_dataset
from .system_runs import block_code, compiled, initial_states, model_parameters, probe, system_cache

__all__ = ["RESCALE_EVERY", "STATUS_ABOVE_NAME", "TANGENT_TURN", "TangentRun", "gali", "initial_tangents", "lyapunov",
           "megno", "run_tangents", "tangent_kind"]

#: The name of ``registry.STATUS_ABOVE`` in a Dataset's ``status`` flags.
STATUS_ABOVE_NAME = registry.INDICATOR_STATUSES[registry.STATUS_ABOVE].name

#: The turn that takes the initial tangent vectors off the Hartley matrix's rows (:func:`initial_tangents`), rad.
TANGENT_TURN = -math.pi / 16

#: MEGNO and GALI do not depend on the tangent vectors' lengths (``ρ = δ·δ'/|δ|²``; GALI normalises copies): their
#: vectors are rescaled every this many steps, which keeps them in range unless one step grows them e^44-fold, and
#: costs the steps in between nothing (the spectrum's sums need a factorisation each ``renormalise``).
RESCALE_EVERY = 16

# A ratio within this relative distance of an integer counts as that integer (renormalise / dt, t_end / dt).
_SLACK = 1e-9

_STATUS_NAMES = tuple(status.name for status in registry.INDICATOR_STATUSES)
_FLAG_VALUES = np.arange(len(_STATUS_NAMES), dtype=np.int8)
_FLAG_MEANINGS = " ".join(name.replace(" ", "_") for name in _STATUS_NAMES)


class TangentRun(NamedTuple):
    """What :func:`run_tangents` returns (arrays per sample first)."""

    logs: np.ndarray  # (N, k): sums of log |R_rr| after the transient, in the Gram-Schmidt order
    saved: np.ndarray  # (N, n_saved, k): finite-time exponents, 1/s, NaN after a stop
    scalars: np.ndarray  # (N, 4): <Y>, 2 x slope of <Y> (1/s), time run (s), time the logs cover (s)
    status: np.ndarray  # (N,) int8
    steps_taken: np.ndarray  # (N,) int64


def _as_system(system):
    """``system`` as the engine runs it: a Body (or its three moments, as :func:`tumble.integrate` takes them) becomes
    the free body; a model or a System as it is."""
    if isinstance(system, Body):
        return FreeBody(system.moments)
    if isinstance(system, (Model, System)):
        return system
    if not isinstance(system, str) and np.shape(system) == (3,):
        return FreeBody(one_body(system))  # the moments checked there (positive, the triangle inequality)
    raise ValueError(f"system must be a tumble.Body (or three principal moments), a built-in model (tumble.models) or "
                     f"a tumble.System, got {type(system).__name__}")


def _name(system):
    return system.name if isinstance(system, System) else f"the {system.kind} model"


def _plan(t_end, dt):
    """``(t_end, n_steps, step)``: the horizon and the fixed step that lands on it (the step shortened to
    ``t_end / ceil(t_end / dt)`` when ``t_end / dt`` is not a whole number, as :func:`tumble.integrate`)."""
    t_end, dt = finite_number(t_end, "t_end"), finite_number(dt, "dt")
    if dt <= 0:
        raise ValueError(f"dt must be > 0 s, got {dt:g}")
    if t_end <= 0:
        raise ValueError(f"t_end must be > 0 s (the exponents are averages over time), got {t_end:g}")
    ratio = t_end / dt
    n_steps = round(ratio)
    if n_steps == 0 or abs(ratio - n_steps) > _SLACK * ratio:
        n_steps = math.ceil(ratio)
    return t_end, n_steps, t_end / n_steps


#: The implicit method the tangent flow runs besides the explicit Runge–Kutta methods of :data:`TABLEAUX`.
MIDPOINT = next(m.name for m in registry.METHODS if m.family == "implicit")


def _method(method, system):
    """``method`` checked for ``system``: a Runge–Kutta tableau of :data:`TABLEAUX` (one added at run time too), the
    implicit midpoint rule, or a splitting for the Lie–Poisson models (:func:`tumble.registry.tangent_methods`)."""
    if method == registry.AUTO:
        method = registry.AUTO_STEPPING
    kind = None if isinstance(system, System) else system.kind
    allowed = [*TABLEAUX, *(m for m in registry.tangent_methods(kind) if m not in TABLEAUX)]
    if not isinstance(method, str) or method not in allowed:
        splittings = [m.name for m in registry.METHODS if m.family == "splitting"]
        why = (f"{', '.join(splittings)}: for {', '.join(registry.LIE_POISSON_MODELS)} only, whose exact sub-flows "
               f"they compose" if method in splittings else "each one's tangent is the derivative of its own map")
        owner = f"system {system.name!r}" if isinstance(system, System) else _name(system)
        raise ValueError(f"method must be one of {', '.join(allowed)} for {owner} ({why}), got {method!r}")
    return method


def _exponents(exponents, system, n):
    if exponents is None:
        return n
    if isinstance(exponents, (bool, np.bool_)) or not isinstance(exponents, (int, np.integer)) or not (
            1 <= exponents <= n):
        raise ValueError(f"exponents must be None or an integer from 1 to {n} (the state of {_name(system)} has {n} "
                         f"components: {', '.join(system.spec.state)}), got {exponents!r}")
    return int(exponents)


def _renormalise_steps(renormalise, dt, step):
    """The steps between two factorisations: ``renormalise / step``, a positive whole number (within round-off), of
    the step that runs (``dt`` shortened so that whole steps end at ``t_end``: :func:`_plan`)."""
    value = finite_number(renormalise, "renormalise")
    ratio = value / step
    steps = round(ratio)
    if value <= 0 or steps < 1 or abs(ratio - steps) > _SLACK * max(ratio, 1.0):
        shortened = "" if step == dt else f" (dt = {dt:g} s shortened so that whole steps end at t_end)"
        raise ValueError(f"renormalise must be a positive multiple of the step {step:g} s{shortened}: the tangent "
                         f"vectors are orthonormalised between steps; got {renormalise!r} s ({ratio:.6g} steps)")
    return steps


def _transient_steps(transient, t_end, step):
    """The steps of the transient (rounded up to whole steps), before which nothing is summed: fewer than the run's."""
    value = finite_number(transient, "transient")
    if value < 0 or value >= t_end:
        raise ValueError(f"transient must be >= 0 s and less than t_end = {t_end:g} s (the exponents average over the "
                         f"time after it), got {transient!r} s")
    steps = max(0, math.ceil(value / step - _SLACK))
    if steps >= round(t_end / step):
        raise ValueError(f"transient = {value:g} s leaves no step of {step:g} s before t_end = {t_end:g} s")
    return steps


def _save_every(save_every):
    return int(checked_save_every(save_every) or 0)


def initial_tangents(n, k):
    """The default initial tangent vectors, (k, n) orthonormal rows: rows 1, 2, ..., n - 1 and then 0 of the discrete
    Hartley matrix ``cas(2π r j / n) / √n`` (``cas = cos + sin``; Bracewell 1983), each then turned by
    :data:`TANGENT_TURN` (-11.25°) in the plane of coordinates 1 and 2, then 2 and 3, and so on to n - 1 and n.

    Why these: a coordinate axis is often special to a system (an angle at a symmetric start, where the axis is a pure
    phase shift; an invariant subspace), and so is the diagonal (1, ..., 1) (the synchronised motion of identical
    units), which is the Hartley matrix's row 0, put last. The Hartley rows spread over all components (none within
    37° of an axis for n ≤ 12); the turn takes them off the diagonal and off the coordinate planes their zero entries
    lie in, and keeps every vector at least 33° from every coordinate axis for n = 2 ... 12 (45° is the most any
    vector can be for n = 2). The first vector has components of both signs: a start in one octant (spins about
    positive axes) can make a vector of one sign special (for the free body at such starts the diagonal's vector
    lies nearly along the period's level set, where MEGNO's approach to 2 takes thousands of periods longer). The
    first k of any run are those of the whole spectrum's run, and evolve alike: Gram-Schmidt never lets a later
    vector change an earlier one. ``tangent=`` on :func:`lyapunov`, :func:`megno` and :func:`gali` gives others."""
    r, j = np.meshgrid((np.arange(n) + 1) % n, np.arange(n), indexing="ij")
    angle = 2.0 * np.pi * r * j / n
    vectors = (np.cos(angle) + np.sin(angle)) / math.sqrt(n)
    c, s = math.cos(TANGENT_TURN), math.sin(TANGENT_TURN)
    for a in range(n - 1):
        vectors[:, a:a + 2] = vectors[:, a:a + 2] @ np.array([[c, s], [-s, c]])
    return np.ascontiguousarray(vectors[:k])


def _tangent_vectors(tangent, k, system, n, orthonormal):
    """The first tangent vectors of a run, (k, n): :func:`initial_tangents`, or ``tangent`` (a user's (k, n) or (n,))
    checked (finite, ``k`` rows of ``n``, independent) and made unit (``orthonormal``: by Gram–Schmidt in their
    order, so the first keeps its direction; else each only normalised, as GALI takes them)."""
    if tangent is None:
        return initial_tangents(n, k)
    names = ", ".join(system.spec.state)
    try:
        vectors = np.array(tangent, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"tangent must be None or an array of numbers of shape ({k}, {n}) (vectors over {names}), "
                         f"got {tangent!r}") from None
    if vectors.ndim == 1:
        vectors = vectors[None, :]
    if vectors.shape != (k, n):
        raise ValueError(f"tangent must have shape ({k}, {n}): {k} vector{'s' * (k > 1)} over the {n} components of "
                         f"{_name(system)} ({names}), got shape {np.shape(tangent)}")
    if not np.all(np.isfinite(vectors)):
        raise ValueError("tangent must be finite (found NaN or inf)")
    q, r = np.linalg.qr(vectors.T)
    lengths = np.abs(np.diag(r))
    if np.any(lengths <= 1e-12 * max(float(np.max(np.abs(vectors))), np.finfo(float).tiny)):
        raise ValueError(f"tangent: the {k} vectors must be independent (none zero, none a combination of the "
                         f"others), got {vectors.tolist()}")
    if orthonormal:
        return np.ascontiguousarray((q * np.sign(np.diag(r))).T)
    return np.ascontiguousarray(vectors / np.linalg.norm(vectors, axis=1)[:, None])


class _Kernels(NamedTuple):
    drive: object  # the CPU driver
    run_sample: object  # the per-sample loop (the device kernel's too)
    stages: int


#: Kernels of the built-in models (one rate and tangent for all: the generated dispatch): method -> (tableau, kernels),
#: and their device kernels under ``(run_sample, n, k, len(p))``.
_MODEL_KERNELS = {}
#: System -> {method: (tableau, _Kernels)}, its compiled Jacobian (and the Jacobian with bounds checked) under the key
#: None, its device kernels under ``(run_sample, n, k, len(p))``: they go with the system.
_SYSTEM_KERNELS = system_cache()


def _system_functions(system):
    """A System's rate (compiled once per process for every engine call: :func:`tumble.engine.system_runs.compiled`)
    and its Jacobian (None when it has none) compiled, as ``(rate, jacobian, jacobian with bounds checked)``; one
    line naming the system when numba cannot compile either."""
    made = _SYSTEM_KERNELS.setdefault(system, {})
    if None not in made:
        owner, what = f"system {system.name!r}", "jacobian(t, y, p, J)"
        made[None] = (None, None) if system.jacobian is None else tuple(
            sample_loop.compile_function(system.jacobian, sample_loop.JACOBIAN_SIGNATURE, owner, what, boundscheck=check)
            for check in (False, True))
    return (compiled(system).rate, *made[None])


def tangent_kind(system):
    """How the tangent flow of ``system`` (as :func:`_as_system` gives it) is computed: ``"generated"`` (a built-in
    model's ``tangent`` in :mod:`tumble.kernels.systems`), ``"jacobian"`` (a System's), or ``"differences"`` (a System
    without one: :func:`tumble.kernels.loops.tangent_loop.difference_tangents`)."""
    if not isinstance(system, System):
        return "generated"
    return "differences" if system.jacobian is None else "jacobian"


def _kernels(system, method):
    """The tangent loop of ``system`` stepped by ``method``: a tableau's (a tableau replaced at run time under the same
    name is a new method: the kernels are kept with the tableau they were made of), the implicit midpoint rule's (its
    scratch grows with the state: the built-in models' are kept per state size) or a splitting's (the built-in
    Lie–Poisson models only: :func:`_method`), made once."""
    tableau = TABLEAUX.get(method)
    n = len(system.spec.state)
    made = _SYSTEM_KERNELS.setdefault(system, {}) if isinstance(system, System) else _MODEL_KERNELS
    key = (method, n) if method == MIDPOINT else method
    if key not in made or made[key][0] is not tableau:
        if isinstance(system, System):
            rate, jacobian, _ = _system_functions(system)
            tangents = (tangent_loop.difference_tangents(rate) if jacobian is None
                        else tangent_loop.jacobian_tangents(jacobian))
        else:
            rate, tangents = rate_sample, tangent_loop.model_tangents()
        if tableau is not None:
            step, stages = tangent_loop.make_tangent_step(rate, tangents, tableau), len(tableau.b)
        elif method == MIDPOINT:
            step, stages = tangent_loop.make_midpoint_tangent_step(rate, tangents), tangent_loop.midpoint_stages(n)
        else:
            step, stages = tangent_loop.make_splitting_tangent_step(registry.STEPPING.index(method)), 0
        run_sample = tangent_loop.make_tangent_loop(step)
        made[key] = (tableau, _Kernels(tangent_loop.make_cpu_driver(run_sample, stages), run_sample, stages))
    return made[key][1]


def _block_code(system, method):
    """The code of ``system``'s tangent steps on the CPU's block path (a built-in model's kind, a System's generated
    steps: :func:`tumble.kernels.steps.system_steps.tangent_code`), or None where it runs one sample at a time."""
    if isinstance(system, Model):
        return registry.MODEL_KINDS.index(system.kind) if tangent_blocks.runs(method, system.kind) else None
    return block_code(system, method, tangents=True)


def _parameters(system, parameters):
    """``(system with parameters, p for the kernels, {name: value})``."""
    system, values = with_parameters(system, parameters)
    if isinstance(system, System):
        return system, system.parameter_values(parameters), values
    return system, model_parameters(system), values


def _probe(system, y, p):
    """A System's rate as :func:`tumble.integrate` probes it (:func:`tumble.engine.system_runs.probe`: bounds checked,
    every component set and finite), and its Jacobian at the first finite initial state, bounds checked: one line
    naming the system when either misbehaves there (a later non-finite value is a sample's status)."""
    probe(system, y, p, 0.0)
    _, _, checked = _system_functions(system)
    finite = np.flatnonzero(np.all(np.isfinite(y), axis=1))
    if checked is None or not len(finite):
        return
    i = int(finite[0])
    n = y.shape[1]
    J = np.full((n, n), np.nan)
    try:
        checked(0.0, y[i].copy(), p, J)
    except IndexError:
        raise ValueError(f"system {system.name!r}: its jacobian indexes beyond J ({n} x {n}), the state or the "
                         f"parameters") from None
    if not np.all(np.isfinite(J)):
        raise ValueError(f"system {system.name!r}: its jacobian left a value unset, NaN or infinite at sample {i}'s "
                         f"initial state {y[i].tolist()} (t = 0 s)")


def run_tangents(system, y, p, method, first, step, n_steps, every, transient, save_every, stop_above, device,
                 orthogonalise=True):
    # size: the checked plan of one tangent run, handed down as the kernels take it (flat numbers, arrays)
    """Run the tangent loop over the samples ``y`` (N, n) of a checked ``system`` (``p``: its kernels' parameters);
    the ``k`` tangent vectors ``first`` (k, n) to start every sample from, ``n_steps`` steps of ``step`` s, a
    factorisation every ``every`` steps, sums from step ``transient``, finite-time exponents every ``save_every`` steps
    (0: none), the MEGNO stop ``stop_above`` (inf: none); without ``orthogonalise`` the vectors are only normalised and
    ``saved[..., 0]`` holds GALI_k. A System without a Jacobian gets its components' scales after ``p`` here, and the
    warnings where its differences cannot be vouched for. Returns :class:`TangentRun`. The arguments are trusted
    (:func:`lyapunov`, :func:`megno` and :func:`gali` check them)."""
    n_samples, n = y.shape
    k = len(first)
    differences = tangent_kind(system) == "differences"
    if differences:  # the components' scales ride after the parameters (difference_tangents reads them there)
        scales = system.difference_scales()
        _warn_unsteady_difference(system, y, p, first, scales)
        p = np.concatenate([p, scales])
    state = np.array(y, order="C")
    tangents = np.array(np.broadcast_to(first, (n_samples, k, n)), order="C")
    n_saved = 0
    if save_every:
        n_saved = len(_saved_marks(n_steps, transient, save_every))
    saved = np.full((n_samples, n_saved, k), np.nan)
    if device == "cpu":
        logs = np.zeros((n_samples, k))
        scalars = np.zeros((n_samples, tangent_loop.SCALARS))
        status = np.zeros(n_samples, dtype=np.int8)
        steps_taken = np.zeros(n_samples, dtype=np.int64)
        outputs = (logs, saved, scalars, status, steps_taken)
        code = _block_code(system, method)
        if code is not None:  # vectorised across samples
            constants = p[1:] if isinstance(system, Model) else system_steps.block_constants(p[:len(system.parameters)])
            tangent_blocks.run(code, registry.STEPPING.index(method), constants, state, tangents, 0.0,
                               float(step), int(n_steps), int(every), int(transient), int(save_every),
                               float(stop_above), bool(orthogonalise), *outputs)
        else:
            _kernels(system, method).drive(state, tangents, p, 0.0, step, n_steps, every, transient, save_every,
                                           stop_above, bool(orthogonalise), *outputs)
    else:
        kernels = _kernels(system, method)
        cuda = device_tangent_loop()
        made = _SYSTEM_KERNELS[system] if isinstance(system, System) else _MODEL_KERNELS
        key = (kernels.run_sample, n, k, len(p))
        if key not in made:
            made[key] = cuda.make_kernel(kernels.run_sample, n, k, kernels.stages, len(p))
        logs, saved, scalars, status, steps_taken = cuda.run(made[key], state, tangents, p, 0.0, step, n_steps,
                                                               every, transient, save_every, stop_above,
                                                               orthogonalise, saved)
    if differences and device == "cpu":  # the CPU driver leaves the final states in `state`
        _warn_beyond_scale(system, state, scales)
    return TangentRun(logs, saved, scalars, status, steps_taken)


#: The relative error of a difference tangent that tumble still vouches for: beyond it, :func:`_warn_unsteady_difference`
#: and :func:`_warn_beyond_scale` say so.
VOUCHED = 1e-6


def _difference(rate, y, p, v, e):
    """:func:`tumble.kernels.loops.tangent_loop.difference_tangents`' product along ``v`` with the step ``e``, on the host."""
    f = [np.zeros_like(y) for _ in range(4)]
    for m, shift in enumerate((e, -e, 2 * e, -2 * e)):
        rate(0.0, y + shift * v, p, f[m])
    return (8.0 * (f[0] - f[1]) - (f[2] - f[3])) / (12.0 * e)


def _warn_unsteady_difference(system, y, p, vectors, scales):
    """One warning when, at the first finite initial state, a difference tangent changes by more than :data:`VOUCHED`
    of its size when the step is made four times shorter: the rate varies on a scale shorter than the one declared
    (the fourth-order error falls 256-fold, so the change is the error of the step run; rounding moves it by 1e-12)."""
    finite = np.flatnonzero(np.all(np.isfinite(y), axis=1))
    if not len(finite):
        return
    rate = compiled(system).rate
    y0 = y[finite[0]].copy()
    dydt = np.zeros_like(y0)
    rate(0.0, y0, p, dydt)
    for v in vectors:
        e = tangent_loop.DIFFERENCE_STEP / np.max(np.abs(v) / scales)
        coarse, fine = _difference(rate, y0, p, v, e), _difference(rate, y0, p, v, e / 4)
        size = max(np.max(np.abs(fine)), np.max(np.abs(dydt) / scales), np.finfo(float).tiny)
        change = np.max(np.abs(coarse - fine)) / size
        if change > VOUCHED:
            warnings.warn(f"system {system.name!r} has no jacobian, and its difference tangent at the first state "
                          f"changes by {change:.0e} of itself with a step four times shorter: its rate varies on a "
                          f"shorter scale than its components' scales ({', '.join(f'{s:g}' for s in scales)}): give "
                          f"the system a jacobian, or a smaller scale=", RuntimeWarning, stacklevel=4)
            return


def _warn_beyond_scale(system, final, scales):
    """One warning when a component of a System without a Jacobian ended so far beyond its scale that the rounding of
    ``y + e v`` (``eps |y| / (2^-10 scale)`` of the difference) passes :data:`VOUCHED`."""
    with np.errstate(invalid="ignore"):
        ratio = np.nanmax(np.where(np.isfinite(final), np.abs(final), np.nan), axis=0, initial=0.0) / scales
    j = int(np.argmax(ratio))
    error = ratio[j] * np.finfo(float).eps / 2 / tangent_loop.DIFFERENCE_STEP
    if error > VOUCHED:
        name = system.spec.state[j]
        warnings.warn(f"system {system.name!r} has no jacobian: its tangents are central differences stepping 2^-10 of "
                      f"each component's scale, and {name!r} reached {ratio[j]:.1e} times its scale {scales[j]:g}, "
                      f"where a difference is accurate to about {error:.0e} relative only: give the system a jacobian, "
                      f"or a scale for {name!r}", RuntimeWarning, stacklevel=4)


def _saved_marks(n_steps, transient, save_every):
    """The steps after which finite-time exponents are stored: each multiple of ``save_every`` past the transient,
    and the last."""
    marks = np.arange(save_every, n_steps + 1, save_every)
    marks = marks[marks > transient]
    return np.append(marks, n_steps) if not len(marks) or marks[-1] != n_steps else marks


def _checked(system, y0, t_end, dt, method, parameters, device, tolerance):
    # size: every indicator's common arguments, checked once here
    """What every indicator checks first: ``(device, system, y, p, parameter values, method, t_end, n_steps, step)``;
    for an error-controlled ``method`` (``tolerance``: ``(rtol, atol, times, max_steps)``) ``n_steps`` is the most
    steps a sample may take and ``step`` the first step (0: chosen)."""
    device = resolve_device(device)
    system = _as_system(system)
    system, p, values = _parameters(system, parameters)
    if method in registry.ERROR_CONTROLLED:
        if device != "cpu":
            raise ValueError(f"device {device!r}: the chaos indicators at a tolerance (method={method!r}) run on the "
                             f"CPU; on the device use a fixed-step method (rk4, rk8)")
        t_end, step, n_steps = checked_scalars(t_end, dt, tolerance[3])
        if t_end <= 0:
            raise ValueError(f"t_end must be > 0 s (the indicators are averages over time), got {t_end:g}")
    else:
        fixed_steps_only(method, dt, *tolerance)
        method = _method(method, system)
        t_end, n_steps, step = _plan(t_end, dt)
    y, _ = initial_states(system, y0)
    problem = system.state_problem(y) if isinstance(system, Model) else None
    if problem:
        raise ValueError(f"y0: {problem}")
    return device, system, y, p, values, method, t_end, n_steps, step


def _refuse_cost(y, n_steps, k, n_saved, device):
    n = y.shape[1]
    cost.refuse(cost.run_cost(len(y), n_steps * (k + 1), n + k * n + k * (n_saved + 1)),
                f"y0 ({len(y):,} states) with {k} tangent vector{'s' * (k > 1)} over {n_steps:,} steps", device)


def _warn_stopped(status, name):
    bad = int(np.count_nonzero(status == registry.STATUS_NONFINITE))
    if bad:
        warnings.warn(f"{bad} of {len(status)} samples of {name} became non-finite or lost a tangent direction (their "
                      f"values cover the time before; status says which)", RuntimeWarning, stacklevel=3)


def _status_variable(status):
    return ("sample", status, {"long_name": "sample status", "flag_values": _FLAG_VALUES.copy(),
                               "flag_meanings": _FLAG_MEANINGS})


def _system_attrs(system, values, method, step, n_steps, t_end, device):
    return {"system": system.name if isinstance(system, System) else system.kind, "tangent": tangent_kind(system),
            "method": method, "dt": step,
            "n_steps": n_steps, "t_end": t_end, "device": device,
            **{f"parameter_{key}": value for key, value in values.items()}}


def _tangent_functions(system):
    """``(rate, tangents, key)`` of ``system`` for the variational equations at a tolerance
    (:func:`tumble.kernels.variational.make_variational_rate`), made once; ``key`` names them for numba's disk cache
    (:func:`tumble.kernels.system_steps.functions_key`; None: a System whose functions cannot be keyed, compiled in
    each process)."""
    if isinstance(system, System):
        made = _SYSTEM_KERNELS.setdefault(system, {})
        if "variational" not in made:
            rate, jacobian, _ = _system_functions(system)
            made["variational"] = (rate, tangent_loop.difference_tangents(rate) if jacobian is None
                                   else tangent_loop.jacobian_tangents(jacobian),
                                   system_steps.functions_key(system.rate, system.jacobian))
        return made["variational"]
    if "variational" not in _MODEL_KERNELS:
        _MODEL_KERNELS["variational"] = (rate_sample, tangent_loop.model_tangents(), "models")
    return _MODEL_KERNELS["variational"]


def _at_tolerance(system, y, p, vectors, run, **options):
    """``run`` (:func:`tumble.engine.chaos_tolerance.run_unit` or ``run_spectrum``) of the checked samples ``y`` with
    the tangent ``vectors``: a System probed first and, without its Jacobian, the components' scales after ``p`` and
    the warnings where its differences cannot be vouched for."""
    n, k = y.shape[1], len(vectors)
    cost.refuse(cost.run_cost(len(y), 0, (k + 2) * n * (np.size(options["times"]) + 1)),
                f"y0 ({len(y):,} states) with {k} tangent vector{'s' * (k > 1)}", "cpu")
    if isinstance(system, System):
        _probe(system, y, p)
    differences = tangent_kind(system) == "differences"
    if differences:
        scales = system.difference_scales()
        _warn_unsteady_difference(system, y, p, vectors, scales)
        p = np.concatenate([p, scales])
    result = run(_tangent_functions(system), y, p, vectors, components=system.spec.state, **options)
    if differences:
        _warn_beyond_scale(system, result.final[:, :n], scales)
    return result


def _tolerance_dataset(system, values, t_end, device, more, pieces):
    """The Dataset of an indicator at a tolerance from its ``(variables, attributes)`` and ``more`` attributes."""
    variables, attrs = pieces
    return _dataset(variables, {"system": system.name if isinstance(system, System) else system.kind,
                                "tangent": tangent_kind(system), **attrs, **more, "t_end": t_end, "device": device,
                                **{f"parameter_{key}": value for key, value in values.items()}})


def lyapunov(system, y0, t_end, dt=None, *, method="rk4", exponents=None, renormalise=1.0, transient=0.0,
             parameters=None, save_every=None, tangent=None, device="cpu", rtol=None, atol=None, times=None,
             max_steps=None):
    # size: the contract's arguments (DESIGN.md, "Chaos indicators"); each checked once, then one run, one Dataset
    r"""The Lyapunov spectrum of an ensemble of initial states: the ``k`` largest exponents per sample.

    Each sample's state and ``k`` tangent vectors are stepped together by ``method`` (the tangent is the derivative of
    the method's map); every ``renormalise`` seconds the vectors are orthonormalised by modified Gram–Schmidt and, after
    ``transient``, ``log |R_rr|`` summed (Benettin et al. 1980). Exponent ``r`` is its sum over ``t_end - transient``.

    Parameters
    ----------
    system : Body, model or System
        A ``tumble.Body`` (the free body), a built-in model (:mod:`tumble.models`) or a :class:`tumble.System` (with
        its ``jacobian``, else central differences of its rate: ``attrs["tangent"]`` says which).
    y0 : array_like, shape (N, n) or (n,)
        Initial states, the system's components in its order (a Body: ``w`` rad/s).
    t_end, dt : float
        Horizon (> 0) and step (> 0), s; the step is shortened to ``t_end / ceil(t_end / dt)`` when ``t_end / dt`` is
        not a whole number (``attrs["dt"]``).
    method : str
        An explicit Runge–Kutta method of :data:`tumble.kernels.TABLEAUX` (``"rk4"``, ``"rk8"``, or one added at run
        time), ``"implicit_midpoint"`` (its tangent solved from ``(I - h/2 J) δ1 = (I + h/2 J) δ0``: the derivative
        of its map too; it keeps quadratic invariants such as ``|g|²`` exactly), a Lie–Poisson splitting
        (``"symplectic_euler"``, ``"splitting2"``, ``"splitting4"``) for the free body, the gyrostat and the heavy top
        (the derivative of each exact sub-flow, composed: a map that keeps volume, so the exponents sum to zero to
        round-off), or ``"auto"`` (rk4).
    exponents : int, optional
        ``k``, how many (1 to n; default n, the whole spectrum, or as many as ``tangent`` has vectors).
    renormalise : float
        Seconds between two orthonormalisations, a positive multiple of ``dt`` (within round-off). The result does not
        depend on it beyond round-off, as long as ``exp(λ renormalise)`` stays within the floating-point range.
    transient : float
        Seconds before the sums start (0 <= transient < t_end; rounded up to whole steps).
    parameters : mapping, optional
        A model's or System's parameters, by name, in place of its own.
    save_every : int, optional
        Also the finite-time exponents ``finite_time(sample, time, index)`` after every ``save_every``-th step past the
        transient and at the end (the sums so far over the time since the transient).
    tangent : array_like, shape (k, n) or (n,), optional
        The first tangent vectors, the same for every sample (independent; orthonormalised by Gram–Schmidt in their
        order, so the first keeps its direction). Default: :func:`initial_tangents`, a fixed orthonormal set whose
        every vector lies at least 33° from every coordinate axis (n ≤ 12).
    device : str
        ``"cpu"`` or ``"cuda"`` (one thread per sample; the fixed steps only).
    rtol, atol, times, max_steps
        ``method="dop853"`` only (``dt``: the first step, None: chosen): the tolerance of the augmented state's steps
        (as :func:`tumble.integrate`; :mod:`tumble.engine.chaos_tolerance` says what it controls), the times of the
        finite-time exponents (s, after the transient, in place of ``save_every``) and the steps a sample may take
        over the whole run (None: 1 000 000). The vectors are orthonormalised every ``renormalise`` seconds as with
        a fixed step, each segment between started with a chosen first step.

    Returns
    -------
    xarray.Dataset
        ``exponent(sample, index)`` 1/s, sorted descending per sample, ``index`` 1..k; ``status(sample)`` (a sample
        that became non-finite, or whose tangent vectors collapsed, keeps the exponents of the time up to its last
        orthonormalisation and says so; NaN when there was none past the transient); with ``save_every`` ``finite_time(sample, time, index)``, 1/s,
        each row sorted descending (NaN after a stop). Attributes ``method``, ``dt``, ``renormalise``, ``transient``
        (as run: whole steps), ``exponents``, ``system``, ``tangent`` (:func:`tangent_kind`), ``t_end``,
        ``n_steps``, ``device`` and the parameters; with ``method="dop853"`` ``rtol``, ``atol`` and ``order`` in place
        of ``dt`` and ``n_steps``, and each sample's ``steps`` and ``rejected_steps``.

    Raises
    ------
    ValueError
        One line each: an unknown system or method, ``y0`` of the wrong shape (the message names the state's
        components), ``t_end`` or ``dt`` not positive, ``exponents`` not in 1..n, ``renormalise`` not a positive
        multiple of ``dt``, a transient past the horizon, ``save_every`` not a positive integer, an unknown parameter,
        a System numba cannot compile or whose rate or Jacobian is not finite at the first initial state, a run too
        large, a device that cannot run.

    See Also
    --------
    tumble.megno : A cheaper indicator: one tangent vector, its growth averaged.
    tumble.gali : The alignment of several tangent vectors.
    tumble.theory.eigenvalues_at : The exponents' linear theory at an equilibrium.

    Notes
    -----
    Every :math:`\tau` = ``renormalise`` seconds the tangent vectors :math:`V = (\delta_1, \dots, \delta_k)` are
    orthonormalised, :math:`V = Q R` (modified Gram–Schmidt), and the logarithms of the diagonal of :math:`R`
    summed [1]_:

    .. math::

        \lambda_r = \frac{1}{t_\mathrm{end} - t_\mathrm{transient}} \sum_j \ln \left|R^{(j)}_{rr}\right|,
        \qquad r = 1, \dots, k,

    over the orthonormalisations :math:`j` after the transient. For a volume-preserving map the spectrum sums to
    zero.

    References
    ----------
    .. [1] G. Benettin, L. Galgani, A. Giorgilli and J.-M. Strelcyn, "Lyapunov characteristic exponents for
       smooth dynamical systems and for Hamiltonian systems; a method for computing all of them",
       Meccanica 15, 9 and 21 (1980).

    Examples
    --------
    >>> import tumble
    >>> ds = tumble.lyapunov(tumble.Body(1.0, 2.0, 3.0), [[0.0, 1.0, 0.0]], 15.0, 0.01, transient=5.0)
    >>> round(float(ds["exponent"][0, 0]), 2)  # a steady spin about the intermediate axis: its linear growth rate
    0.58
    >>> bool(abs(ds["exponent"][0].sum()) < 1e-6)  # the free body's flow keeps volume
    True
    """
    tolerance = (rtol, atol, times, max_steps)
    device, system, y, p, values, method, t_end, n_steps, step = _checked(system, y0, t_end, dt, method, parameters,
                                                                          device, tolerance)
    n = y.shape[1]
    if exponents is None and tangent is not None:
        exponents = len(np.atleast_2d(np.asarray(tangent, dtype=object)))
    k = _exponents(exponents, system, n)
    vectors = _tangent_vectors(tangent, k, system, n, orthonormal=True)
    if method in registry.ERROR_CONTROLLED:
        no_save_every(save_every)
        start = finite_number(transient, "transient")
        if not 0.0 <= start < t_end:
            raise ValueError(f"transient must be >= 0 s and less than t_end = {t_end:g} s, got {transient!r}")
        finite = np.zeros(0) if times is None else output_times(times, t_end)
        if len(finite) and finite[0] <= start:
            raise ValueError(f"times must lie after the transient ({start:g} s): the finite-time exponents average "
                             f"over the time since it, got {finite[0]:g}")
        every = finite_number(renormalise, "renormalise")
        if every <= 0:
            raise ValueError(f"renormalise must be > 0 s, got {renormalise!r}")
        run = _at_tolerance(system, y, p, vectors, chaos_tolerance.run_spectrum, t_end=t_end, renormalise=every,
                            transient=start, times=finite, tolerance=tolerance[:2], first_step=step,
                            max_steps=n_steps)
        return _tolerance_dataset(system, values, t_end, device, {"renormalise": every},
                                  chaos_tolerance.lyapunov_variables(run, k, start, _name(system)))
    every = _renormalise_steps(renormalise, dt, step)
    first = _transient_steps(transient, t_end, step)
    save = _save_every(save_every)
    marks = _saved_marks(n_steps, first, save) if save else np.zeros(0, dtype=int)
    _refuse_cost(y, n_steps, k, len(marks), device)
    if isinstance(system, System):
        _probe(system, y, p)
    run = run_tangents(system, y, p, method, vectors, step, n_steps, every, first, save, math.inf, device)
    covered = run.scalars[:, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        exponent = np.where(covered[:, None] > 0, run.logs / covered[:, None], np.nan)
    exponent = -np.sort(-exponent, axis=1)
    _warn_stopped(run.status, _name(system))
    variables = {
        "exponent": (("sample", "index"), exponent,
                     {"units": "1/s", "long_name": "Lyapunov exponent, sorted descending"}),
        "status": _status_variable(run.status),
        "sample": ("sample", np.arange(len(y)), {"long_name": "ensemble member"}),
        "index": ("index", np.arange(1, k + 1), {"long_name": "exponent index (1: the largest)"}),
    }
    if save:
        times = marks * step
        times[-1] = t_end
        variables["finite_time"] = (("sample", "time", "index"), -np.sort(-run.saved, axis=2),
                                    {"units": "1/s", "long_name": "finite-time Lyapunov exponent since the transient, "
                                                                  "sorted descending"})
        variables["time"] = ("time", times, {"units": "s", "long_name": "time"})
    attrs = {**_system_attrs(system, values, method, step, n_steps, t_end, device),
             "renormalise": every * step, "transient": first * step, "exponents": k}
    return _dataset(variables, attrs)


def megno(system, y0, t_end, dt=None, *, method="rk4", stop_above=None, parameters=None, tangent=None, device="cpu",
          rtol=None, atol=None, max_steps=None):
    # size: the contract's arguments (DESIGN.md, "Chaos indicators")
    r"""MEGNO, the mean exponential growth factor of nearby orbits (Cincotta & Simó 2000), of an ensemble of states.

    One tangent vector ``δ`` rides with each sample (stepped by ``method``, the derivative of its map); with
    ``ρ = δ·δ'/|δ|²``, ``Y(t) = (2/t) ∫ s ρ(s) ds`` and its mean ``<Y>(t) = (1/t) ∫ Y``, integrated as two extra
    variables of the same steps. ``<Y> → 2`` on a quasi-periodic orbit, ``→ 0`` near a stable periodic one, and grows
    like ``λ t / 2`` on a chaotic one: ``lyapunov`` is twice the least-squares slope of ``<Y>`` against ``t`` over the
    run (REBOUND's ``lyapunov()`` returns the slope itself).

    Parameters
    ----------
    system, y0, t_end, dt, method, parameters, device
        As :func:`lyapunov`.
    stop_above : float, optional
        A sample stops once ``<Y>`` exceeds it (> 0): chaotic enough; its status then says so
        (``"megno above threshold"``) and its values are those at the stop.
    tangent : array_like, shape (n,) or (1, n), optional
        The first tangent vector, the same for every sample (normalised). Default: the first of
        :func:`initial_tangents`.
    rtol, atol, max_steps
        ``method="dop853"`` only, as :func:`lyapunov` (the vector is kept at unit length continuously; ``<Y>``'s slope
        is the least-squares line over the run's continuous ``<Y>(t)``; no ``stop_above``).

    Returns
    -------
    xarray.Dataset
        ``megno(sample)`` (``<Y>`` at the end or at the stop), ``lyapunov(sample)`` 1/s, ``time_run(sample)`` s and
        ``status(sample)``; attributes ``method``, ``dt``, ``stop_above`` (inf: none), ``system``, ``t_end``,
        ``n_steps``, ``device`` and the parameters (``method="dop853"``: as :func:`lyapunov` says).

    Raises
    ------
    ValueError
        As :func:`lyapunov`, and a ``stop_above`` that is not a number > 0.

    See Also
    --------
    tumble.lyapunov : The whole spectrum.
    tumble.gali : The alignment of several tangent vectors.

    Notes
    -----
    With :math:`\delta` the tangent vector [1]_,

    .. math::

        Y(t) = \frac{2}{t} \int_0^t \frac{\dot\delta(s) \cdot \delta(s)}{|\delta(s)|^2}\, s \, ds, \qquad
        \langle Y \rangle(t) = \frac{1}{t} \int_0^t Y(s)\, ds,

    :math:`\langle Y \rangle \to 2` on a quasi-periodic orbit, :math:`\to 0` near a stable periodic one, and
    :math:`\langle Y \rangle \approx \lambda t / 2` on a chaotic one.

    References
    ----------
    .. [1] P. M. Cincotta and C. Simó, "Simple tools to study global dynamics in non-axisymmetric galactic
       potentials – I", Astron. Astrophys. Suppl. Ser. 147, 205 (2000).

    Examples
    --------
    Near the stable largest axis :math:`\langle Y \rangle` stays near 0; at the unstable intermediate axis it
    grows as :math:`\lambda t / 2`, here :math:`\lambda = 1/\sqrt{3}`:

    >>> import tumble
    >>> ds = tumble.megno(tumble.Body(1.0, 2.0, 3.0), [[0.1, 0.0, 1.0], [0.0, 1.0, 0.0]], 20.0, 0.01)
    >>> [round(float(y), 1) for y in ds["megno"]]
    [0.3, 5.8]
    >>> round(float(ds["lyapunov"][1]), 2)
    0.58
    """
    tolerance = (rtol, atol, None, max_steps)
    device, system, y, p, values, method, t_end, n_steps, step = _checked(system, y0, t_end, dt, method, parameters,
                                                                          device, tolerance)
    limit = math.inf
    if stop_above is not None:
        limit = finite_number(stop_above, "stop_above")
        if limit <= 0:
            raise ValueError(f"stop_above must be None or a number > 0 (a threshold of <Y>, 2 on a regular orbit), "
                             f"got {stop_above!r}")
    vectors = _tangent_vectors(tangent, 1, system, y.shape[1], orthonormal=True)
    if method in registry.ERROR_CONTROLLED:
        if stop_above is not None:
            raise ValueError("stop_above stops a fixed-step run (its loop checks <Y> after every step); method "
                             "'dop853' runs every sample to t_end")
        run = _at_tolerance(system, y, p, vectors, chaos_tolerance.run_unit, megno=True, t_end=t_end, times=None,
                            tolerance=tolerance[:2], first_step=step, max_steps=n_steps)
        return _tolerance_dataset(system, values, t_end, device, {},
                                  chaos_tolerance.megno_variables(run, y.shape[1], _name(system)))
    _refuse_cost(y, n_steps, 1, 0, device)
    if isinstance(system, System):
        _probe(system, y, p)
    run = run_tangents(system, y, p, method, vectors, step, n_steps, RESCALE_EVERY, 0, 0, limit, device)
    _warn_stopped(run.status, _name(system))
    variables = {
        "megno": ("sample", run.scalars[:, 0], {"units": "1", "long_name": "mean MEGNO <Y>"}),
        "lyapunov": ("sample", run.scalars[:, 1], {"units": "1/s", "long_name": "maximal Lyapunov exponent from the "
                                                                              "slope of <Y> (2 x slope)"}),
        "time_run": ("sample", run.scalars[:, 2], {"units": "s", "long_name": "time the sample ran"}),
        "status": _status_variable(run.status),
        "sample": ("sample", np.arange(len(y)), {"long_name": "ensemble member"}),
    }
    attrs = {**_system_attrs(system, values, method, step, n_steps, t_end, device), "stop_above": limit}
    return _dataset(variables, attrs)


def gali(system, y0, t_end, dt=None, *, k=2, method="rk4", parameters=None, save_every=None, tangent=None, device="cpu",
         rtol=None, atol=None, times=None, max_steps=None):
    # size: the contract's arguments (DESIGN.md, "Chaos indicators")
    r"""GALI_k, the generalised alignment index (Skokos, Bountis & Antonopoulos 2007, Physica D 231, 30), over time.

    ``k`` tangent vectors ride with each sample (stepped by ``method``, the derivative of its map), each normalised
    every :data:`RESCALE_EVERY` steps and at each saved time but never orthogonalised; GALI_k is the volume of the
    parallelepiped the k unit vectors span (the product of their singular values; 1 at the start, from orthonormal
    vectors). On a chaotic orbit it falls
    exponentially, ``~ exp(-[(λ1 - λ2) + ... + (λ1 - λk)] t)``; on a regular one on an N-torus it stays near a constant
    for ``k <= N`` and falls as a power of ``t`` beyond.

    Parameters
    ----------
    system, y0, t_end, dt, method, parameters, device
        As :func:`lyapunov`.
    k : int
        The number of vectors, 2 to n.
    save_every : int, optional
        GALI after every ``save_every``-th step and at the end; None: at the end only.
    tangent : array_like, shape (k, n), optional
        The first tangent vectors, the same for every sample (independent; each normalised, not orthogonalised: GALI
        then starts below 1). Default: the first k of :func:`initial_tangents`.
    rtol, atol, times, max_steps
        ``method="dop853"`` only, as :func:`lyapunov`: GALI at ``times`` (s; None: ``t_end``), each vector kept at
        unit length continuously.

    Returns
    -------
    xarray.Dataset
        ``gali(sample, time)`` (0 once the vectors are dependent to round-off), ``status(sample)`` (NaN after a stop),
        coordinate ``time`` (s); attributes ``method``, ``dt``, ``k``, ``system``, ``tangent``, ``t_end``, ``n_steps``,
        ``device`` and the parameters (``method="dop853"``: as :func:`lyapunov` says).

    Raises
    ------
    ValueError
        As :func:`lyapunov`, and ``k`` not an integer from 2 to n.

    See Also
    --------
    tumble.lyapunov : The exponents whose differences set GALI's fall.
    tumble.megno : A one-vector indicator.

    Notes
    -----
    With :math:`\hat w_1, \dots, \hat w_k` the unit tangent vectors [1]_ (GALI_2 behaves as the SALI of [2]_),

    .. math::

        \mathrm{GALI}_k(t) = \left\| \hat w_1(t) \wedge \dots \wedge \hat w_k(t) \right\|
        \propto e^{-[(\lambda_1 - \lambda_2) + \dots + (\lambda_1 - \lambda_k)]\, t}

    on a chaotic orbit; on a regular one on an :math:`N`-torus it stays near a constant for :math:`k \le N`.

    References
    ----------
    .. [1] Ch. Skokos, T. C. Bountis and C. Antonopoulos, "Geometrical properties of local dynamics in
       Hamiltonian systems: the Generalized Alignment Index (GALI) method", Physica D 231, 30 (2007).
    .. [2] Ch. Skokos, "Alignment indices: a new, simple method for determining the ordered or chaotic nature of
       orbits", J. Phys. A 34, 10029 (2001).

    Examples
    --------
    The vectors stay apart near the stable largest axis and align at the unstable intermediate one:

    >>> import tumble
    >>> ds = tumble.gali(tumble.Body(1.0, 2.0, 3.0), [[0.1, 0.0, 1.0], [0.0, 1.0, 0.0]], 20.0, 0.01)
    >>> ds["gali"].shape, [bool(g > 0.5) for g in ds["gali"][:, -1]]
    ((2, 1), [True, False])
    """
    tolerance = (rtol, atol, times, max_steps)
    device, system, y, p, values, method, t_end, n_steps, step = _checked(system, y0, t_end, dt, method, parameters,
                                                                          device, tolerance)
    n = y.shape[1]
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or not 2 <= k <= n:
        raise ValueError(f"k must be an integer from 2 to {n} (GALI_k of k tangent vectors; the state of {_name(system)} "
                         f"has {n} components: {', '.join(system.spec.state)}), got {k!r}")
    vectors = _tangent_vectors(tangent, int(k), system, n, orthonormal=False)
    if method in registry.ERROR_CONTROLLED:
        no_save_every(save_every)
        run = _at_tolerance(system, y, p, vectors, chaos_tolerance.run_unit, megno=False, t_end=t_end, times=times,
                            tolerance=tolerance[:2], first_step=step, max_steps=n_steps)
        return _tolerance_dataset(system, values, t_end, device, {},
                                  chaos_tolerance.gali_variables(run, n, int(k), _name(system)))
    save = _save_every(save_every) or n_steps
    marks = _saved_marks(n_steps, 0, save)
    _refuse_cost(y, n_steps, int(k), len(marks), device)
    if isinstance(system, System):
        _probe(system, y, p)
    run = run_tangents(system, y, p, method, vectors, step, n_steps, RESCALE_EVERY, 0, save, math.inf, device,
                       orthogonalise=False)
    _warn_stopped(run.status, _name(system))
    times = marks * step
    times[-1] = t_end
    variables = {
        "gali": (("sample", "time"), run.saved[:, :, 0], {"units": "1", "long_name": f"GALI_{k}"}),
        "status": _status_variable(run.status),
        "sample": ("sample", np.arange(len(y)), {"long_name": "ensemble member"}),
        "time": ("time", times, {"units": "s", "long_name": "time"}),
    }
    attrs = {**_system_attrs(system, values, method, step, n_steps, t_end, device), "k": int(k)}
    return _dataset(variables, attrs)


def _dataset(variables, attrs):
    """The indicators' Dataset, built as :func:`integrate`'s (:func:`tumble.engine.integration.indexed_dataset`: from
    numpy arrays directly, so that xarray does not import dask to look for its arrays in a new process)."""
    coords = [name for name, spec in variables.items() if spec[0] in (name, (name,))]
    data = [name for name in variables if name not in coords]
    return indexed_dataset({name: variables[name] for name in data + coords}, attrs)  # xr.Dataset's order
