"""A user's own system: ``tumble.System(rate, state=..., parameters=..., name=..., jacobian=None)``.

Any system of ordinary differential equations ``y' = f(t, y; p)`` that the engine steps like the built-in ones
(:func:`tumble.integrate`, :func:`tumble.propagate`) and that linear theory expands about any state
(:func:`tumble.theory.eigenvalues_at`), in the spirit of DynamicalSystems.jl's ``rule(u, p, t)``:

* ``rate(t, y, p, dydt)``: plain Python that numba compiles in nopython mode; it writes ``f`` at time ``t`` (s) and
  state ``y`` (float64, shape (n,)) into ``dydt`` (float64, shape (n,)), with the parameters ``p`` (float64, shape
  (k,)) in the order of ``parameters``. It returns nothing.
* ``jacobian(t, y, p, J)`` (optional), the same convention: writes ``∂f/∂y`` into ``J`` (n, n).
* ``scale`` (optional): the scale on which the rate varies along each component, for the tangents of a system
  without a Jacobian (central differences step by a fixed share of it).

The record holds the description only, checked once here (names, numbers); the engine compiles the functions on
first use (:mod:`tumble.engine.system_runs`) and says in one line, naming the system, what numba or a first call of the
rate found wrong.
"""

from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["System", "SystemSpec", "finite_number", "with_parameters"]


class SystemSpec(NamedTuple):
    """What a system says of itself (as a model's ``spec``, its row of ``registry.MODELS``): its name, the names of
    its state's components and of its parameters, in order."""

    name: str
    state: tuple
    parameters: tuple


def _names(value, what, name):
    if isinstance(value, str):
        value = (value,)
    try:
        names = tuple(value)
    except TypeError:
        raise ValueError(f"system {name!r}: {what} must be a sequence of names, got {value!r}") from None
    for item in names:
        if not isinstance(item, str) or not item.isidentifier():
            raise ValueError(f"system {name!r}: {what} must be names (identifiers), got {item!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"system {name!r}: {what} has a name twice: {', '.join(names)}")
    return names


def finite_number(value, what):
    """``value`` as a float; ValueError naming ``what`` when it is no number (a bool is none) or not finite."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} must be a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return x


@dataclass(frozen=True, eq=False)
class System:
    """A system of ODEs ``y' = rate(t, y, p)`` that the engine integrates like the built-in ones.

    Parameters
    ----------
    rate : callable
        ``rate(t, y, p, dydt)``: plain Python numba can compile in nopython mode (or a ``numba.njit`` function);
        writes the derivative of the state ``y`` (float64, (n,)) at time ``t`` (s) into ``dydt`` (float64, (n,));
        ``p`` (float64, (k,)) holds the parameters in the order of ``parameters``. A rate that reads ``y[j]`` and
        writes ``dydt[j]`` at constant indices (straight-line code, branches allowed) runs on the CPU vectorised
        across samples, as the built-in models do, its kernels cached on disk; one that loops over the components or
        passes its arrays on runs one sample at a time, and a warning says so. A number, array or function it reads
        from its module is compiled in as a constant: changed, the next run compiles again (a warning says so); what
        varies belongs in ``parameters``.
    state : sequence of str
        Names of the state's components, in order (n >= 1): the ``component`` coordinate of
        :func:`tumble.integrate`'s ``state(sample, time, component)``.
    parameters : mapping of str to float, optional
        Named parameters and their default values, in the order ``p`` holds them (a run's ``parameters=``
        overrides some of them).
    name : str
        What messages and files call the system.
    jacobian : callable, optional
        ``jacobian(t, y, p, J)``, the same convention, writing ``∂f/∂y`` into ``J`` (float64, (n, n)). Without it,
        :func:`tumble.theory.eigenvalues_at` differentiates ``rate`` numerically (adaptive central differences
        with Richardson extrapolation, :func:`scipy.differentiate.jacobian`), and the chaos indicators' tangents are
        central differences of ``rate`` (:func:`tumble.kernels.loops.tangent_loop.difference_tangents`).
    scale : mapping of str to float, or sequence of float, optional
        Without a ``jacobian``: the scale on which ``rate`` varies along each component (a positive number per
        component, by name or in order; unnamed components keep the default 1), for the difference tangents, which
        move no component by more than 2^-10 of its scale, wherever the state is: an angle keeps the scale 1 however
        far it turns (its sine varies on that scale). A component that varies on another scale (a position in metres
        of order 7e6, a concentration of order 1e-6) needs its own. The chaos indicators warn in one line where they
        cannot vouch for a difference: at the first state, when the difference changes with a quarter of the step
        (the scale too large), and at the end, when a component went so far beyond its scale that rounding
        dominates (beyond about 1e7 times it).

    Raises
    ------
    ValueError
        A rate or Jacobian that is not callable, names that are not identifiers or repeat, a parameter that is not
        a finite number; the message names the system.

    See Also
    --------
    tumble.models.Model : The built-in systems.
    tumble.propagate : Step a System's states.
    tumble.theory.eigenvalues_at : Its Jacobian's eigenvalues at a state.

    Examples
    --------
    >>> import math, tumble
    >>> def pendulum(t, y, p, dydt):
    ...     dydt[0] = y[1]
    ...     dydt[1] = -p[0] * math.sin(y[0]) - p[1] * y[1]
    >>> sys = tumble.System(pendulum, state=("x", "v"), parameters={"k": 1.0, "c": 0.1}, name="pendulum")
    >>> sys.spec.state
    ('x', 'v')
    """

    rate: object
    state: tuple = ()
    parameters: dict = None
    name: str = "system"
    jacobian: object = None
    scale: object = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"a system's name must be a non-empty string, got {self.name!r}")
        name = self.name
        if not callable(self.rate):
            raise ValueError(f"system {name!r}: rate must be a function rate(t, y, p, dydt), got {self.rate!r}")
        if self.jacobian is not None and not callable(self.jacobian):
            raise ValueError(f"system {name!r}: jacobian must be None or a function jacobian(t, y, p, J), got "
                             f"{self.jacobian!r}")
        state = _names(self.state, "state", name)
        if not state:
            raise ValueError(f"system {name!r}: state must name at least one component")
        given = {} if self.parameters is None else self.parameters
        if not hasattr(given, "items"):
            raise ValueError(f"system {name!r}: parameters must be a mapping of names to numbers, got {given!r}")
        keys = _names(list(given), "parameters", name)
        values = {key: finite_number(given[key], f"system {name!r}: parameter {key!r}") for key in keys}
        object.__setattr__(self, "state", state)
        object.__setattr__(self, "parameters", values)
        object.__setattr__(self, "scale", self._checked_scale(self.scale))

    def _checked_scale(self, scale):
        """``scale`` as ``{component: value}`` (the declared ones; None: none), each a finite number > 0."""
        if scale is None:
            return None
        name = self.name
        if hasattr(scale, "items"):
            unknown = [key for key in scale if key not in self.state]
            if unknown:
                raise ValueError(f"system {name!r}: scale names {unknown[0]!r}, which is not a component of its state "
                                 f"({', '.join(self.state)})")
            given = dict(scale)
        else:
            try:
                values = list(scale)
            except TypeError:
                raise ValueError(f"system {name!r}: scale must be a mapping of components to numbers or one number "
                                 f"per component ({', '.join(self.state)}), got {scale!r}") from None
            if len(values) != len(self.state):
                raise ValueError(f"system {name!r}: scale must have one number per component "
                                 f"({', '.join(self.state)}), got {len(values)}")
            given = dict(zip(self.state, values))
        checked = {}
        for key, value in given.items():
            checked[key] = finite_number(value, f"system {name!r}: scale of {key!r}")
            if checked[key] <= 0:
                raise ValueError(f"system {name!r}: scale of {key!r} must be > 0, got {value!r}")
        return checked

    def difference_scales(self):
        """The components' scales for difference tangents: the declared :attr:`scale`, else 1; float64 (n,)."""
        declared = self.scale or {}
        return np.array([declared.get(key, 1.0) for key in self.state])

    @property
    def spec(self):
        """:class:`SystemSpec`: the name, the state's component names and the parameters' names."""
        return SystemSpec(self.name, self.state, tuple(self.parameters))

    @property
    def state_size(self):
        """``n``, the number of state components."""
        return len(self.state)

    def parameter_values(self, overrides=None):
        """The parameters as the kernels take them: float64 array (k,) in the order of :attr:`parameters`, with
        ``overrides`` (a mapping of some of the names to numbers) in place of the defaults.

        Raises
        ------
        ValueError
            An override that names no parameter of the system, or is not a finite number.
        """
        values = dict(self.parameters)
        if overrides is not None:
            if not hasattr(overrides, "items"):
                raise ValueError(f"parameters must be a mapping of names to numbers, got {overrides!r}")
            for key, value in overrides.items():
                if key not in values:
                    known = ", ".join(self.parameters) or "none"
                    raise ValueError(f"parameters: {key!r} is not a parameter of system {self.name!r} (it has: "
                                     f"{known})")
                values[key] = finite_number(value, f"parameters: {key!r}")
        return np.array(list(values.values()), dtype=float)

    def __repr__(self):
        params = ", ".join(f"{k}={v:g}" for k, v in self.parameters.items())
        return f"System({self.name!r}, state={self.state}, parameters={{{params}}})"


def with_parameters(system, parameters=None):
    """``(system, {name: value})``: a built-in model (:mod:`tumble.physics.models`) or a :class:`System` with
    ``parameters`` (a mapping of some of its parameters' names to values, or None) in place of its own, and the values
    it then has (a model's vector parameters as lists).

    Raises
    ------
    ValueError
        A name that is not one of the system's parameters (the message lists them), or a value the system refuses.
    """
    if isinstance(system, System):
        values = system.parameter_values(parameters)
        return system, dict(zip(system.parameters, (float(v) for v in values)))
    if parameters:
        if not hasattr(parameters, "items"):
            raise ValueError(f"parameters must be a mapping of names to numbers, got {parameters!r}")
        for key in parameters:
            if key not in system.parameters:
                known = ", ".join(system.parameters) or "none"
                raise ValueError(f"parameters: {key!r} is not a parameter of the {system.kind} model (it has: "
                                 f"{known})")
        system = dataclasses.replace(system, **dict(parameters))  # checked again by the model's constructor
    return system, {key: np.asarray(value, dtype=float).tolist() for key, value in system.parameters.items()}
