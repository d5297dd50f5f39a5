"""Models: the systems tumble studies, one module each, its equations written once (numpy and numba alike).

A model is a frozen record of a body's principal moments (kg m², body frame = principal axes) and the model's
parameters, validated once when it is built. Its module holds, before the class, the system's per-sample equations as
scalar code (``Constants``, ``constants``, ``rate``, ``tangent``, ``invariants``: :mod:`.base` says how); the kernels
compile a generated copy of them (:mod:`tumble.kernels.systems`), the methods here evaluate them on arrays. Its state
is a flat vector ``y`` of :attr:`Model.state_size` components; every function here is vectorised over leading axes,
``y`` of shape ``(..., n)``:

* :meth:`Model.rhs` ``y' = f(t, y)``, :meth:`Model.jacobian` ``∂f/∂y`` (exact: the tangent flow along each unit
  vector, ``(..., n, n)``);
* :meth:`Model.invariants`: the quantities the motion conserves, by name (``registry.MODELS``);
* :meth:`Model.equilibrium`: the steady spin about a principal axis, the point linear theory expands about
  (:func:`tumble.physics.theory.linear` of a model: eigenvalues of the Jacobian there);
* :meth:`Model.transverse`: which components of a state measure a perturbation of that spin, and their
  weights, as plain arrays (a kernel or an estimator takes them as columns and numbers).

State layout (``registry.MODELS``, ``registry.STATE_BLOCKS``): the first three components are always the
body-frame angular velocity ``w`` (rad/s); the model's own blocks follow, each named by the first letter of its
components: ``g`` the unit vector pointing up in the body frame (heavy top), ``q`` an attitude quaternion,
scalar first (gravity gradient), ``s`` an internal body's angular velocity (damper). A kernel finds a block by
the offsets of ``registry.state_blocks(kind)``.

One module a system: the base (:mod:`.base`: :class:`Model`, :class:`Transverse`, the evaluation of a module's
equations on arrays and the helpers the models share), then :mod:`.gyrostat` (with the free body, the gyrostat with no
rotor), :mod:`.heavy_top`, :mod:`.gravity_gradient` and :mod:`.damper`, each the one place its kinds are named; this
package finds each model's class in the module its registry row names (no list of imports) and re-exports them,
:data:`CLASSES` and :func:`from_kind`. Adding a system is its module here and its row in the registry.

Models (Landau & Lifshitz, *Mechanics*, §35-§37; Wittenburg, *Dynamics of Multibody Systems*, §3.6 for the
gyrostat; Arnold, *Mathematical Methods of Classical Mechanics*, §30 and Goldstein §5.7 for the heavy top):

* :class:`FreeBody`: ``I w' = (I w) × w``.
* :class:`Gyrostat`: a rotor of constant angular momentum ``h`` relative to the body (N m s, body frame),
  ``L = I w + h``, ``I w' = (I w + h) × w``.
* :class:`HeavyTop` (Euler-Poisson): moments about the fixed pivot, centre of mass in the direction ``c`` (body
  axis 3 by default) at distance ``l`` from the pivot, ``mgl = M g l`` (N m); ``g`` the unit up vector in the body
  frame: ``I w' = (I w) × w + mgl (g × c)``, ``g' = g × w``. The torque ``r × F = l c × (−M g g) = mgl (g × c)``
  tips the top away from upright: a top at rest upright falls at the rate ``sqrt(mgl / I1)`` (``I1 <= I2``).
* :class:`GravityGradient`: a satellite in a circular orbit of rate ``n`` (or an elliptic one); ``w`` and the
  attitude ``q`` relative to the orbit frame (roll, pitch, yaw): ``I w' = (I w) × w + 3 n² (c3 × I c3)``,
  ``q' = ½ q ⊗ (0, w + n c2)``. Linear theory in a 3-angle attitude error (:meth:`Model.tangent_jacobian`), not the
  quaternion's 4 components.
* :class:`Damper` (Kane's spherical damper): ``I w' = (I w) × w + c (s − w)``, ``J (s' + w × s) = −c (s − w)``;
  ``|I w + J s|`` is kept, the energy decays.
"""

from __future__ import annotations

from importlib import import_module

from ... import registry
from .base import Model, Transverse


def _class_of(model):
    """The class of model ``model`` (a row of ``registry.MODELS``): the one of its kind in the module that holds its
    equations (``registry.Model.equations_module``)."""
    module = import_module(f"{__name__}.{model.equations_module}")
    return next(value for value in vars(module).values()
                if isinstance(value, type) and issubclass(value, Model) and value.kind == model.name)


#: Every model with a class here, by kind, found by the registry's rows (``registry.MODELS``' ``physics`` flag): no list
#: of imports to keep.
CLASSES = {model.name: _class_of(model) for model in registry.MODELS if model.physics}

#: The models studies run (``registry.MODELS``' ``implemented`` flag); the others have no studies yet (:func:`from_kind`
#: builds them, ``theory.linear`` linearises them, the kernels step them: ``tumble.kernels.MODEL_CODES``).
IMPLEMENTED = {kind: cls for kind, cls in CLASSES.items() if registry.model_kind(kind).implemented}

globals().update({cls.__name__: cls for cls in CLASSES.values()})
__all__ = ["CLASSES", "IMPLEMENTED", "Model", "Transverse", "from_kind", *sorted(cls.__name__ for cls in CLASSES.values())]


def from_kind(kind, body, **parameters):
    """The model ``kind`` of ``body`` with its parameters, as a study's ``[model]`` table names them.

    Parameters
    ----------
    kind : str
        One of ``registry.MODEL_KINDS``: the ``kind`` of a class of :data:`CLASSES` (:class:`FreeBody`,
        :class:`Gyrostat`, :class:`HeavyTop`, :class:`GravityGradient`, :class:`Damper`).
    body : Body or array_like, shape (3,)
        Principal moments, kg m².
    **parameters
        The kind's numeric parameters by study key (``rotor`` N m s, ``mgl`` N m, ``orbit_rate`` rad/s,
        ``damper_inertia`` kg m², ``damping`` N m s), all of them, no others.

    Returns
    -------
    Model

    Raises
    ------
    ValueError
        An unknown kind; a kind with no class yet (``registry.MODELS``' ``physics``); a parameter the kind does
        not have, or lacks;
        an invalid parameter or body. The message names the kind or the key.

    See Also
    --------
    tumble.models.Model : What every model offers.
    tumble.run_study : A study's ``[model]`` table, run.

    Examples
    --------
    >>> top = from_kind(HeavyTop.kind, (1.0, 1.0, 0.5), mgl=2.0)
    >>> top == HeavyTop((1.0, 1.0, 0.5), 2.0), top.state_size
    (True, 6)
    """
    spec = registry.model_kind(kind)
    if not spec.physics or kind not in CLASSES:
        keys = ", ".join(spec.parameters)
        raise ValueError(f"model kind {kind!r} is reserved but not implemented yet (parameters {keys}); "
                         f"implemented: {', '.join(CLASSES)}")
    allowed = (*spec.parameters, *CLASSES[kind].extras)  # the study keys (required), then the API's own (optional)
    for key in parameters:
        if key not in allowed:
            raise ValueError(f"{key}: not a parameter of model kind {kind!r} "
                             f"(its parameters: {', '.join(allowed) or 'none'})")
    for key in spec.parameters:
        if key not in parameters:
            raise ValueError(f"{key}: model kind {kind!r} needs it")
    return CLASSES[kind](body, **parameters)
