"""One scene measured: :func:`measure`, growth rate or frequency of a perturbed steady spin against linear theory.

:func:`measure` runs one *scene* — an ensemble of spins about one principal axis of one body, perturbed by a
small tilt — and measures, per sample and for the scene, how fast the perturbation oscillates or grows,
next to linear theory: planned (:mod:`tumble.measure.planning`), run (:mod:`tumble.measure.running`) and reduced
(:mod:`tumble.measure.reduction`). What the scene skipped is on the dataset (``path``, ``sample_steps_computed``,
``sample_steps_skipped``).
"""

from __future__ import annotations

from ..engine.device import resolve_device
from ..physics.models import Model
from ..physics.system import System
from .planning import scene_plan
from .reduction import scene_result
from .running import scene_samples

__all__ = ["measure"]


def measure(body, axis=None, spin=1.0, amplitude=1e-3, samples=1024, seed=0, method="auto", *, dt=None, flips=3,
            distribution="cone", torque=None, horizon=None, curves=(), progress=None, state=None, parameters=None,
            device="cpu"):
    # size: a public call (tumble.measure): each keyword is a documented scene option
    r"""Measure one scene: how fast perturbations of a steady spin oscillate or grow, against linear theory.

    ``measure(system, state=y_eq, amplitude, samples, seed, *, dt, horizon, parameters, device)`` does the same for
    any :class:`tumble.System` about an equilibrium ``y_eq`` (n,): perturbations of size ``amplitude`` (in the
    state's units) in isotropic directions, the measured mode's amplitude (its left eigenvector) fitted, against the
    eigenvalues of the Jacobian there (:func:`tumble.theory.eigenvalues_at`); the Dataset has the same variables,
    with the coordinate ``system`` in place of the body's (:mod:`tumble.measure.system_scenes`).

    Parameters
    ----------
    body : Body, array_like (3,), Model or System
        Principal moments, kg m²; a built-in model (:mod:`tumble.models`: measured about ``axis`` at ``spin`` as a
        study's scene, or about ``state``), or a :class:`tumble.System` (then ``state`` and no ``axis``).
    axis : {1, 2, 3}
        Spin axis, 1-based.
    spin : float
        Unperturbed spin about ``axis``, rad/s (non-zero).
    amplitude : float
        Tilt of the perturbed spins from the axis, rad (see :func:`tumble.engine.sampling.perturbed_spins`).
    samples : int
        Ensemble size.
    seed : int >= 0 or None
        Entropy of the ensemble (``None``: fresh, stored on the dataset).
    method : str
        ``"auto"`` (closed form: the scene is torque-free), ``"exact"`` or a fixed-step method name.
    dt : float, optional
        Step of a fixed-step method, s (default: from the method's order, :data:`STEPS_PER_RADIAN`).
    flips : int
        Exponential scenes: flips of the spin axis to time (first flip and spacing); 0 skips them.
    distribution : str
        Tilt distribution, see :func:`tumble.engine.sampling.perturbed_spins`.
    torque : None, array_like (3,) or mapping, optional
        A torque about the spin axis — three numbers (N m) or a named profile (see
        :func:`tumble.engine.ensemble.torque_spec`) — for periodic scenes: the spin then changes as
        ``w_a(t) = spin + (N_a/I_a) S(t)`` and linear theory's phase advances by ``sqrt(q) ∫|w_a| dt``; the
        theory rate is the least-squares slope of that phase over the observation times, exactly what the
        phase fit measures. (The wobbly space station of the problem sheet.)
    horizon : float, optional
        Span of the scene, s (default: :data:`PERIODS` periods, or growth to saturation and ``flips`` flips).
    curves : iterable of str
        Optional curves to keep for figures, from :data:`CURVES`: ``"norm"`` (median and quartiles of the
        scaled transverse norm at the probe times, exponential scenes) and ``"trace"`` (the body-frame ω of
        the first sample over the horizon).
    progress : bool, optional
        Progress bar (default: on a terminal only).
    state : array_like, shape (n,), optional
        A System's equilibrium (its rate 0 there).
    parameters : mapping, optional
        A System's parameters, by name, in place of its own.
    device : {"cpu", "cuda"}
        Where the scene's samples step. On ``"cuda"`` a stepping scene (a named fixed-step method, or a torque) runs
        its samples and their observers (probe norms, flips, early stop) on the device and only the per-sample
        arrays the fits need come back; a closed-form scene (``"exact"``, or ``"auto"`` torque-free) sets up and
        evaluates its samples on the device (:func:`tumble.physics.exact.omega_on_device`) and times its flips on the
        host; the fits and the reduction run on the host. A device that is missing raises the ``ValueError``
        ``device 'cuda': ...`` (saying what is), never a silent run on the CPU.

    Returns
    -------
    xarray.Dataset
        Scalars ``rate`` (median over valid samples), ``rate_theory``, ``rel_error``
        (``|rate − rate_theory| / rate_theory``; for a neutral scene, whose theory is 0, relative to
        ``|spin|``), ``kind``; its 95 % confidence interval (order statistics) ``rate_ci_low``/``rate_ci_high`` and ``rate_spread``;
        ``samples_used``/``samples_excluded``; the fit window (exponential); flip statistics (exponential,
        ``flips > 0``); per sample ``sample_rate(sample)`` and ``sample_status(sample)``; the scene's
        parameters as scalar coordinates (``I1``, ``I2``, ``I3``, ``axis``, ``spin``, ``amplitude``,
        ``method``) ready to be stacked by :func:`scan`.

    Raises
    ------
    ValueError
        Invalid body, axis, spin, amplitude, samples, seed, method, flips, torque, horizon or curves.

    See Also
    --------
    tumble.scan : Every combination of scene parameters.
    tumble.theory.linear : The rate the scene is compared with.
    tumble.sampling.perturbed_spins : The ensemble of perturbed spins.

    Notes
    -----
    The estimators work in coordinates that an exact invariant makes simple. For a torque-free spin about
    axis :math:`a`, :math:`2 T I_a - |L|^2 = \sum_i I_i (I_a - I_i)\,\omega_i^2` is conserved and its
    :math:`i = a` term vanishes, so with :math:`k_i = I_i (I_a - I_i)` the transverse components stay on the conic
    :math:`k_b \omega_b^2 + k_c \omega_c^2 = \text{const}`. In the scaled coordinates
    :math:`x = \sqrt{g_b}\,\omega_b`, :math:`y = \sqrt{g_c}\,\omega_c`, :math:`g_b = \sqrt{|k_b / k_c|} = 1 / g_c`,
    the linearised motion [1]_ is

    .. math::

        x + i y \propto e^{\pm i \omega t} \quad (q > 0), \qquad
        x^2 + y^2 = 2 \left(A^2 e^{2 \lambda t} + B^2 e^{-2 \lambda t}\right) \quad (q < 0):

    a periodic scene's rate is the least-squares slope of the phase :math:`\arctan(y / x)` over time, an
    exponential one's the rate :math:`\lambda` of the sum of two exponentials, recovered by linear prediction
    however much of the decaying mode a sample starts with. ``rate`` is the median over the samples, with a 95 %
    confidence interval from order statistics.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    >>> ds = measure((1.0, 2.0, 3.0), axis=2, samples=64)
    >>> str(ds.kind.values), bool(ds.rel_error < 5e-3)
    ('exponential', True)
    >>> ds = measure((1.0, 2.0, 3.0), axis=3, samples=16)
    >>> str(ds.kind.values), bool(ds.rel_error < 1e-3)
    ('periodic', True)
    """
    device = resolve_device(device)  # once, here at the door: the scene below trusts it
    if isinstance(body, Model) and state is None:
        unused = {"flips": flips != 3, "torque": torque is not None, "curves": bool(curves),
                  "parameters": parameters is not None}
        return _measure_model(body, axis, spin, amplitude, samples, seed, method, dt=dt, horizon=horizon,
                              distribution=distribution, device=device, unused=unused)
    if isinstance(body, (System, Model)) or state is not None:
        if not isinstance(body, (System, Model)):
            raise ValueError(f"state= measures a tumble.System about an equilibrium; a body is measured about an axis "
                             f"(measure(body, axis, spin)), got {body!r}")
        if axis is not None:
            raise ValueError("axis is a body's spin axis: a System is measured about state=, its equilibrium")
        if state is None:
            raise ValueError(f"state is required for system {body.name!r}: the equilibrium (one state of "
                             f"{', '.join(body.state)}) whose perturbations to measure")
        from .system_scenes import measure_system

        return measure_system(body, state, amplitude, samples, seed, method, dt=dt, horizon=horizon,
                              parameters=parameters, device=device)
    if parameters is not None:
        raise ValueError("parameters are a System's; a body has none")
    scene = scene_plan(body, axis, spin, amplitude, samples, seed, method, dt=dt, flips=flips,
                       distribution=distribution, torque=torque, horizon=horizon, curves=curves, device=device)
    return scene_result(scene, [scene_samples(scene, 0, scene.samples, progress=progress)])


def _measure_model(model, axis, spin, amplitude, samples, seed, method, *, dt, horizon, distribution, device, unused):
    # size: measure's keywords for a built-in model, and those it refuses
    """:func:`measure` of a built-in model about ``axis`` at ``spin``: one scene as a model study runs it
    (:func:`tumble.measure.model_scenes.scene_plan`), its Dataset as a free body's."""
    from .model_scenes import scene_batch
    from .model_scenes import scene_plan as model_scene_plan
    from .records import scene_dataset

    refused = [name for name, given in unused.items() if given]
    if refused:
        raise ValueError(f"{', '.join(refused)}: not for a built-in model ({model.kind}); a model's scene measures its "
                         f"rate about axis at spin (or state=, its equilibrium)")
    if axis is None:
        raise ValueError(f"axis is required for a {model.kind} (the spin axis of its steady state), or state= (an "
                         f"equilibrium of its {', '.join(model.spec.state)})")
    plan = model_scene_plan(model, axis, spin, amplitude, samples, seed, method, dt=dt, horizon=horizon,
                            distribution=distribution, device=device)
    return scene_dataset(scene_batch([plan])[0])
