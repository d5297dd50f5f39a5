"""Scenes of a user's System: perturbations of an equilibrium, their growth or oscillation measured against the
linear theory there (``tumble.measure(system, state=y_eq, ...)``).

A System scene is a model scene (:mod:`tumble.measure.model_scenes`) with the system's whole state as its mode space:

* linear theory from the Jacobian at ``y_eq`` (:func:`tumble.physics.theory.system_linearisation`: the System's
  ``jacobian``, else its rate differentiated): ``"exponential"`` with the largest real part of the eigenvalues when
  that is growth beyond round-off, else ``"periodic"`` with the least damped oscillation's frequency; a neutral
  equilibrium has nothing to measure and is refused;
* the measured mode's **left** eigenvector ``u`` (an eigenvector of ``J^T``; no full inverse of the eigenvectors,
  which a neutral direction's defective pair would make singular) gives ``z(t) = u . (y(t) - y_eq) = c exp(λ t)``
  in linear theory, whatever the mix of modes the perturbation starts with; ``u`` is scaled so that ``|z|`` is the
  amplitude of the mode of unit norm (in the state's units);
* the ensemble: ``y_eq + amplitude d``, ``d`` isotropic unit directions of the state (normalised Gaussian vectors
  drawn from the seed);
* exponential: ``|z|`` stored at :data:`~tumble.measure.planning.PROBES` + 1 equally spaced times up to 2 e-foldings
  past the end of the linear regime (``|z|`` reaching ``max(SATURATION, SATURATION_TILTS amplitude)`` in the state's
  units) and fitted by :func:`~tumble.measure.estimators.growth_rates`; periodic: ``(Re z, Im z)`` stored
  :data:`~tumble.measure.planning.SAVES_PER_PERIOD` times a period over :data:`~tumble.measure.model_scenes.PERIODS` periods and its phase fitted
  by :func:`~tumble.measure.estimators.oscillation_frequencies`;
* the step resolves the fastest eigenvalue (:data:`~tumble.measure.planning.STEPS_PER_RADIAN` of the method's
  order); the samples step in :data:`~tumble.measure.model_scenes.SLICE`-sized engine calls
  (:func:`tumble.engine.system_runs.run_system`), so the memory of the stored states is bounded, and the cost is
  refused past the engine's bound before anything runs.

The reduction is the free body's (:func:`tumble.measure.reduction.scene_records`): the same variables, interval and
statuses; the body's coordinates (moments, axis, spin) give way to the system's name, and the equilibrium and the
parameters are attributes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import registry
from ..engine.sampling import seed_entropy
from ..engine.system_runs import initial_states, method_order, run_system, system_methods, system_name
from ..physics import theory
from ..physics.system import System, with_parameters
from ..registry import STATUS_OK
from . import estimators as analysis
from . import planning, reduction
from .model_scenes import SLICE, measured_eigenvalue, periodic_plan
from .records import scene_dataset

__all__ = ["SystemScene", "measure_system", "system_scene_plan"]


@dataclass(frozen=True, eq=False)
class SystemScene:
    """One System scene, planned (:func:`system_scene_plan`). The fields after ``device`` are those
    :func:`tumble.measure.reduction.scene_records` reads of a body's scene, fixed for a System."""

    system: System
    equilibrium: np.ndarray  # (n,)
    parameters: dict  # name -> value, as run
    amplitude: float  # in the state's units
    samples: int
    method: str  # as asked
    chosen: str  # the tableau run
    kind: str  # "periodic" or "exponential"
    value: float  # rate_theory: frequency (rad/s) or growth rate (1/s)
    plan: planning.StepPlan
    entropy: int
    left: np.ndarray  # (n,) complex: the measured mode's left eigenvector, scaled (module docstring)
    eigenvalue: complex
    unit_norm: float  # |z| of a perturbation of unit size (the phase fit's no-signal scale)
    device: str = "cpu"
    moments: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    axis: int = 0
    spin: float = 0.0
    distribution: str = "sphere"
    flips: int = 0
    curves: tuple = ()
    spin_up: None = None
    torque: None = None


def _left_mode(jac, kind):
    """``(left eigenvector, eigenvalue)`` of the mode a scene of ``kind`` measures (as
    :func:`tumble.measure.model_scenes.mode` chooses it), scaled so that ``u . v = 1`` for the mode's unit right
    eigenvector ``v``: ``|u . x|`` is then the mode's amplitude in units of a unit perturbation."""
    lam, right = np.linalg.eig(jac)
    m = measured_eigenvalue(lam, kind)
    lam_t, left = np.linalg.eig(jac.T)
    v = right[:, m] / np.linalg.norm(right[:, m])
    u = left[:, int(np.argmin(np.abs(lam_t - lam[m])))]
    return u / (u @ v), complex(lam[m])


def _order(method):
    order = method_order(method)
    return max(k for k in planning.STEPS_PER_RADIAN if k <= order)


def _rate(system, y, values):
    """The rate of ``system`` at one state ``y`` (n,): a System's function, a built-in model's ``rhs``."""
    if not isinstance(system, System):
        return system.rhs(y)
    out = np.zeros_like(y)
    system.rate(0.0, y.copy(), system.parameter_values(values), out)
    return out


def _checked(system, state, amplitude, samples, method, parameters):
    """``(system, equilibrium (n,), p values, chosen method)``: the scene's arguments checked, ValueError naming each
    (``system`` with ``parameters`` in place: a built-in model's own)."""
    y, _ = initial_states(system, state, "state")
    if len(y) != 1:
        raise ValueError(f"state must be one equilibrium of shape ({len(system.spec.state)},) "
                         f"({', '.join(system.spec.state)} of system {system_name(system)!r}), got shape "
                         f"{np.shape(state)}")
    if isinstance(amplitude, (bool, np.bool_)) or not isinstance(amplitude, (int, float, np.integer, np.floating)) \
            or not math.isfinite(amplitude) or amplitude <= 0:
        raise ValueError(f"amplitude must be a number > 0 (the size of the perturbations, in the state's units), got "
                         f"{amplitude!r}")
    planning.check_amplitude(amplitude)
    if isinstance(samples, (bool, np.bool_)) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
    methods = system_methods(system)
    chosen = methods[0] if method == "auto" else method
    if chosen not in methods:
        raise ValueError(f"method must be auto or one of {', '.join(methods)} for system {system_name(system)!r}, "
                         f"got {method!r}")
    system, values = with_parameters(system, parameters)
    return system, y[0], values, chosen


def _plan(kind, value, lam, start, amplitude, order, dt, horizon):
    """The :class:`~tumble.measure.planning.StepPlan` of a System scene (the model scenes' plan with the whole state
    as its mode: :func:`tumble.measure.model_scenes._plan`)."""
    if dt is None:
        dt = 1.0 / np.abs(lam).max() / planning.STEPS_PER_RADIAN[order]
    if kind == "exponential":
        saturation = max(planning.SATURATION, planning.SATURATION_TILTS * amplitude) * start / amplitude
        t_growth = (math.log(max(saturation / start, math.e)) + 2.0) / value
        if horizon:
            t_growth = min(t_growth, horizon)
        every = max(1, math.ceil(t_growth / planning.PROBES / dt))
        dt = t_growth / planning.PROBES / every
        n_steps = planning.PROBES * every
        return planning.StepPlan(t_end=n_steps * dt, dt=dt, n_steps=n_steps,
                                 probe_times=np.arange(planning.PROBES + 1) * every * dt, saturation=saturation,
                                 save_every=every)
    return periodic_plan(value, dt, horizon)


def _perturbed(scene, count):
    """The first ``count`` states of the scene's ensemble: the equilibrium plus ``amplitude`` times isotropic unit
    directions drawn from the seed (a prefix is the same samples whatever ``count``)."""
    directions = np.random.default_rng(scene.entropy).standard_normal((count, len(scene.equilibrium)))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return scene.equilibrium + scene.amplitude * directions


def system_scene_plan(system, state, amplitude=1e-3, samples=1024, seed=0, method="auto", *, dt=None, horizon=None,
                      parameters=None, device="cpu"):
    # size: the public call's arguments (tumble.measure on a System), each checked once
    """Plan a System scene (nothing runs but the rate and Jacobian at the equilibrium): :class:`SystemScene`.

    Raises
    ------
    ValueError
        An invalid argument; a state that is not an equilibrium (its rate beyond round-off there); a neutral
        equilibrium (no growth or oscillation to measure); a plan past the cost bound.
    """
    system, equilibrium, values, chosen = _checked(system, state, amplitude, samples, method, parameters)
    linear = theory.system_linearisation(system, equilibrium, values)
    rate = _rate(system, equilibrium, values)
    size = max(1.0, float(np.abs(equilibrium).max()))
    if not np.abs(rate).max() <= 1e-9 * max(1.0, float(np.abs(linear.jacobian).max())) * size:
        raise ValueError(f"state is not an equilibrium of system {system_name(system)!r}: its rate there is "
                         f"{rate.tolist()} (measure perturbations of a state whose rate is 0)")
    if linear.kind == "neutral":
        raise ValueError(f"the equilibrium {equilibrium.tolist()} of system {system_name(system)!r} is neutral in "
                         f"linear theory (eigenvalues {np.round(linear.eigenvalues, 12).tolist()}: no growth or "
                         f"oscillation to measure)")
    left, eigenvalue = _left_mode(linear.jacobian, linear.kind)
    amplitude, entropy = float(amplitude), seed_entropy(seed)
    scene = SystemScene(system, equilibrium, values, amplitude, int(samples), method, chosen, linear.kind,
                        linear.value, None, entropy, left, eigenvalue, 0.0, device)
    first = _perturbed(scene, min(int(samples), 256))
    start = float(np.median(np.abs((first - equilibrium) @ left)))
    plan = _plan(linear.kind, linear.value, linear.eigenvalues, start, amplitude, _order(chosen), dt, horizon)
    planning.check_fit_span(linear.kind, linear.value, plan.t_end, horizon)
    planning.refuse_plan(int(samples), plan, True, linear.kind == "exponential", 0, device)
    return SystemScene(system, equilibrium, values, amplitude, int(samples), method, chosen, linear.kind,
                       linear.value, plan, entropy, left, eigenvalue, start / amplitude, device)


def _fit(scene, times, z, status):
    """Per-sample ``(rate, code, extras)`` of one engine call (the model scenes' :func:`_fit_group` for one
    scene)."""
    row = np.zeros(len(z), dtype=np.int64)
    if scene.kind == "exponential":
        saturation = np.full(len(z), scene.plan.saturation)
        fit = analysis.growth_rates(times[None], np.abs(z), saturation, row=row)
        rate, extras = fit.rate, {name: getattr(fit, name) for name in ("t_start", "t_stop", "norm_start", "norm_stop")}
    else:
        signal = np.stack([z.real, z.imag], axis=-1)
        fit = analysis.oscillation_frequencies(times[None], signal, np.ones(2), np.full(len(z), scene.unit_norm),
                                               row=row)
        rate, extras = fit.frequency, {"radius": fit.radius}
    offset = len(registry.STATUS_NAMES) - 1
    code = np.where(status != STATUS_OK, status, np.where(fit.code != analysis.FIT_OK, fit.code + offset, 0))
    return rate, code.astype(np.int8), extras


def system_scene_samples(scene):
    """Run every sample of a planned scene, in engine calls of :data:`~tumble.measure.model_scenes.SLICE` samples:
    the part :func:`tumble.measure.reduction.scene_records` takes (the keys of a model scene's)."""
    plan, n = scene.plan, scene.samples
    names = ("t_start", "t_stop", "norm_start", "norm_stop") if scene.kind == "exponential" else ("radius",)
    out = {"start": np.int64(0), "rate": np.empty(n), "code": np.empty(n, dtype=np.int8),
           **{name: np.empty(n) for name in names}}
    computed, states = 0, _perturbed(scene, n)
    for lo in range(0, n, SLICE):
        hi = min(lo + SLICE, n)
        run, _ = run_system(scene.system, states[lo:hi], plan.t_end, plan.n_steps, plan.dt, scene.chosen,
                            save_every=plan.save_every, device=scene.device,
                            parameters=scene.parameters if isinstance(scene.system, System) else None)
        z = (run.trajectory - scene.equilibrium) @ scene.left
        out["rate"][lo:hi], out["code"][lo:hi], extras = _fit(scene, run.times, z, run.status)
        for name, values in extras.items():
            out[name][lo:hi] = values
        computed += int(run.steps_taken.sum())
    out.update(sample_steps_computed=np.int64(computed), sample_steps_skipped=np.int64(n * plan.n_steps - computed),
               rate_theory=np.float64(scene.value), path=np.array(f"system per-sample loop ({scene.chosen})"),
               torque=np.array(""))
    return out


def measure_system(system, state, amplitude=1e-3, samples=1024, seed=0, method="auto", *, dt=None, horizon=None,
                   parameters=None, device="cpu"):
    # size: the public call's arguments (tumble.measure on a System)
    """``tumble.measure(system, state=y_eq, ...)``: the scene's Dataset (:func:`tumble.measure`'s variables; the
    system's name as the coordinate ``system``, ``amplitude`` in the state's units, attributes ``equilibrium``,
    ``eigenvalue`` (the measured mode's, real and imaginary parts) and ``parameter_<name>``)."""
    scene = system_scene_plan(system, state, amplitude, samples, seed, method, dt=dt, horizon=horizon,
                              parameters=parameters, device=device)
    record = reduction.scene_records([scene], [[system_scene_samples(scene)]])[0]
    for name in ("I1", "I2", "I3", "axis", "spin"):
        del record[name]
    record["system"] = np.asarray(system_name(system))
    record["@title"] = np.asarray(f"tumble measurement: system {system_name(system)!r}, {scene.kind} rate about "
                                  f"{scene.equilibrium.tolist()}")
    record["@equilibrium"] = scene.equilibrium
    record["@state_components"] = np.asarray(" ".join(system.spec.state))
    record["@eigenvalue"] = np.array([scene.eigenvalue.real, scene.eigenvalue.imag])
    record["@distribution"] = np.asarray("isotropic directions of the state, size amplitude")
    for name, value in scene.parameters.items():
        record[f"@parameter_{name}"] = np.asarray(value)
    ds = scene_dataset(record)
    ds["amplitude"].attrs.update(units="state units", long_name="size of the perturbations of the equilibrium")
    return ds
