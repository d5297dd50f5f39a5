"""What tumble knows by name, in one place: plain data at the bottom of the layers.

This module imports nothing of tumble. The kernels (a stepping method's kernel id is its index in
:data:`STEPPING`), the engine's choice of path, the study checks, the command line, the docs' tables, the
tests and the benchmarks all read these tables instead of keeping lists of their own; ``tests/test_layers.py``
checks that the kernels' coefficient tables agree with them.
"""

from typing import NamedTuple

__all__ = ["ADAPTIVE_STATUSES", "ATTITUDE_FIGURES", "ACCURATE_STEPPING", "AUTO", "AUTO_STEPPING", "CHAOS_FIGURES", "CHAOS_INDICATORS", "CHAOS_STARTS", "CHOICES",
           "DEFAULT_MODEL", "ERROR_CONTROLLED", "FIGURES", "FREE_BODY", "FIGURE_MODELS", "FIT_NAMES", "FORMATS", "FigureModel", "INDICATOR_STATUSES",
           "LIE_POISSON_MODELS", "METHODS", "MIN_AMPLITUDE", "MODELS",
           "MODEL_KINDS", "MODEL_PARAMETERS", "MODEL_STEPPING", "Method", "Model", "ModelParameter", "PER_SAMPLE_ARRAYS", "SAMPLE_STATUS_NAMES",
           "STATE_BLOCKS", "STATUSES", "STATUS_ABOVE", "STATUS_DRIFT", "STATUS_LIMIT", "STATUS_NAMES", "STATUS_NONFINITE", "STATUS_OK", "STATUS_UNDERFLOW", "STEPPING",
           "Status", "TORQUE_PROFILES", "TORQUE_USER", "TorqueProfile", "amplitude_problem", "choose_method", "method",
           "model_kind", "model_methods", "model_parameter", "state_blocks", "tangent_methods", "torque_profile"]


class Method(NamedTuple):
    """An integration method: its name and what a user may rely on."""

    name: str
    order: int  # nominal order of the global error in the step (0: exact, no step)
    family: str  # "runge_kutta" | "splitting" | "implicit" | "closed_form"
    keeps: str  # what it conserves to round-off, in words
    torque: bool  # can take a body torque
    attitude: bool  # integrates the orientation too (integrate(attitude=True))


#: Every method, the fixed-step ones first, in kernel-id order.
METHODS = (
    Method("rk4", 4, "runge_kutta", "nothing exactly: |L| and energy drift at O(h^4)", True, True),
    Method("rk8", 8, "runge_kutta", "nothing exactly: |L| and energy drift at O(h^8) (DOP853 tableau)", True, True),
    Method("symplectic_euler", 1, "splitting", "|L| (exact sub-rotations); energy bounded, O(h)", True, True),
    Method("splitting2", 2, "splitting", "|L|; energy bounded, O(h^2) (Strang composition)", True, True),
    Method("splitting4", 4, "splitting", "|L|; energy bounded, O(h^4) (Yoshida composition)", True, True),
    Method("implicit_midpoint", 2, "implicit", "|L| and energy (to the fixed-point solver's tolerance)", True,
           True),
    Method("exact", 0, "closed_form", "everything: the torque-free Jacobi-elliptic solution", False, True),
)

_BY_NAME = {m.name: m for m in METHODS}

#: Fixed-step methods by kernel id.
STEPPING = tuple(m.name for m in METHODS if m.family != "closed_form")

#: The word that lets tumble choose (:func:`choose_method`).
AUTO = "auto"

#: Every value a user may give as a method.
CHOICES = (AUTO, *_BY_NAME)

#: The stepping method ``"auto"`` takes when the closed form cannot serve: the fastest fourth-order kernel.
AUTO_STEPPING = "rk4"

#: The stepping method where accuracy, not speed, decides (a damper's flat-spin trace): the highest-order one.
ACCURATE_STEPPING = max((m for m in METHODS if m.family == "runge_kutta"), key=lambda m: m.order).name


def method(name):
    """The :class:`Method` called ``name``.

    Raises
    ------
    ValueError
        ``name`` is not a method (the message lists the methods).
    """
    found = _BY_NAME.get(name) if isinstance(name, str) else None
    if found is None:
        raise ValueError(f"method must be one of {', '.join(_BY_NAME)}; got {name!r}")
    return found


def choose_method(name, *, torque_free, axis_is_intermediate=True, flips=0):
    """The method a run uses for ``name`` (``"auto"`` or a method), and why: ``(method, reason)``.

    ``"auto"`` is the closed form whenever it can deliver everything asked: the scene is torque-free, and flips
    (sign changes of the spin-axis component) are asked only about the intermediate axis, whose flip times the
    closed form gives exactly. Otherwise it is :data:`AUTO_STEPPING`.

    Raises
    ------
    ValueError
        ``name`` is neither ``"auto"`` nor a method, or is ``"exact"`` with a torque.
    """
    if name == AUTO:
        if torque_free and (flips == 0 or axis_is_intermediate):
            return "exact", "torque-free: closed form, no steps"
        if torque_free:
            return AUTO_STEPPING, "flips of a non-intermediate axis are located by stepping"
        return AUTO_STEPPING, "a torque acts: fixed-step kernel"
    chosen = method(name)
    if not chosen.torque and not torque_free:
        raise ValueError(f"method {name!r} is the torque-free closed form; it cannot take a torque (a scene with a "
                         f"torque needs a fixed-step method, or {AUTO!r})")
    return chosen.name, "closed form requested" if chosen.family == "closed_form" else "method requested"


class Status(NamedTuple):
    """A per-sample outcome of a run: its name (as written in files) and what it means."""

    name: str
    message: str


#: Per-sample statuses of the engine, by code (the kernels write the codes).
STATUSES = (
    Status("ok", "ran to the end, or stopped because its measurement was complete"),
    Status("non-finite", "a component became NaN or infinite (step too large for the spin rate?); error-controlled: "
                         "the rate returned NaN or infinity however short the step, stopped there"),
    Status("invariant drift", "torque-free: |L|^2 or the energy drifted beyond the drift limit"),
)
STATUS_NAMES = tuple(s.name for s in STATUSES)
STATUS_OK, STATUS_NONFINITE, STATUS_DRIFT = (STATUS_NAMES.index(name) for name in ("ok", "non-finite", "invariant drift"))
#: Per-sample statuses of the chaos indicators' runs (``tumble.lyapunov``, ``megno``, ``gali``): the engine's, then
#: MEGNO's stop (apart from a scene's statuses, whose next codes are the fit's).
INDICATOR_STATUSES = (*STATUSES, Status("megno above threshold", "its mean MEGNO <Y> passed stop_above (chaotic): "
                                                                "stopped there (tumble.megno)"))
STATUS_ABOVE = len(STATUSES)
#: Per-sample statuses of an error-controlled run (:data:`ERROR_CONTROLLED`): the indicators', then the step
#: control's two stops (codes apart from every other status's, so that a code means one thing wherever it is read).
ADAPTIVE_STATUSES = (*INDICATOR_STATUSES,
                     Status("step underflow", "the error control asked for a step too small to advance the time (a "
                                              "singularity, or a tolerance the arithmetic cannot meet): stopped there"),
                     Status("step limit", "max_steps steps (accepted and rejected) did not reach t_end: stopped there"))
STATUS_UNDERFLOW, STATUS_LIMIT = len(INDICATOR_STATUSES), len(INDICATOR_STATUSES) + 1
#: The error-controlled methods: each sample takes its own steps to a tolerance (rtol, atol), the outputs read off
#: its dense output (:mod:`tumble.kernels.loops.adaptive_loop`).
ERROR_CONTROLLED = ("dop853",)
#: Outcomes of a sample's rate fit, by code (:mod:`tumble.kernels.fits` writes the codes).
FIT_NAMES = ("ok", "fit window too short", "no signal", "undersampled")
#: Per-sample status of a scene, as written in files: the engine's statuses, then the fit's failures.
SAMPLE_STATUS_NAMES = STATUS_NAMES + FIT_NAMES[1:]


class TorqueProfile(NamedTuple):
    """A named time dependence ``s(t)`` of a body torque ``N(t) = vector * s(t)`` (studies are data: a name
    and numbers, never code)."""

    name: str
    code: int  # the kernels' torque_kind
    time: str  # the study key of its time scale tau, s ("" when it has none)
    formula: str  # s(t)
    text: str  # how a run describes it: {v} the vector, N m; {tau} the time scale, s


#: The built-in torque profiles, by kernel code.
TORQUE_PROFILES = (
    TorqueProfile("constant", 0, "", "1", "constant {v} N m"),
    TorqueProfile("ramp", 1, "duration", "min(t / tau, 1)", "ramp {v} N m x min(t / {tau} s, 1)"),
    TorqueProfile("sine", 2, "period", "sin(2 pi t / tau)", "sine {v} N m x sin(2 pi t / {tau} s)"),
    TorqueProfile("pulse", 3, "duration", "1 for 0 <= t < tau, else 0", "pulse {v} N m for 0 <= t < {tau} s"),
)
_PROFILE_BY_NAME = {p.name: p for p in TORQUE_PROFILES}

#: Spin rates a scene can measure, rad/s (magnitude): squares of spins and of transverse components must stay
#: within the float range (beyond, the estimators give NaN). The motion is scale invariant: a spin of w rad/s
#: is the motion of 1 rad/s with times divided by w, so rescale the time unit to study another range.
SPIN_RANGE = (1e-150, 1e150)

#: Smallest tilt a scene measures, rad: below it the transverse components' squares leave float64's range against
#: the spin (1e-170 about the intermediate axis gave no rate at all, 1e-300 also a RuntimeWarning); 1e-160 still
#: measures the linear rate, the bound keeps a margin as :data:`SPIN_RANGE` does.
MIN_AMPLITUDE = 1e-150


def amplitude_problem(amplitude):
    """Why a tilt of ``amplitude`` rad (> 0) cannot be measured (:data:`MIN_AMPLITUDE`), or None when it can."""
    if amplitude >= MIN_AMPLITUDE:
        return None
    return (f"must be >= {MIN_AMPLITUDE:g} rad to be measured, got {amplitude!r}: a smaller tilt's transverse "
            f"components square below float64's range against the spin (no rate can be fitted); the linear rate "
            f"does not depend on the tilt, measure at 1e-6 rad")


#: Steps a sine's period or a pulse's duration must span at least: a fixed step samples the profile only at its
#: stage times, so a shorter one is aliased (sine) or its impulse is off by up to a whole step's worth (pulse).
PROFILE_MIN_STEPS = 8

#: The profiles whose time scale the step must resolve (a ramp shorter than a step is a constant torque).
RESOLVED_PROFILES = ("sine", "pulse")


def profile_step_problem(name, tau, dt, dt_name="dt"):
    """Why a step of ``dt`` s cannot resolve torque profile ``name`` with time scale ``tau`` s, or None when it
    can (:data:`PROFILE_MIN_STEPS`); ``dt_name`` is what the message calls the step."""
    if name not in RESOLVED_PROFILES or not tau > 0 or not dt > 0 or tau >= PROFILE_MIN_STEPS * dt:
        return None
    key = _PROFILE_BY_NAME[name].time
    return (f"{tau:g} s spans {tau / dt:.3g} step(s) of {dt:g} s; a {name}'s {key} must span at least "
            f"{PROFILE_MIN_STEPS} steps to be resolved: set {dt_name} <= {tau / PROFILE_MIN_STEPS:g} s, or a longer "
            f"{key}")


#: The kernels' torque_kind when a user's torque function is called.
TORQUE_USER = -1


def torque_profile(name):
    """The :class:`TorqueProfile` called ``name``; ValueError naming the profiles otherwise."""
    found = _PROFILE_BY_NAME.get(name) if isinstance(name, str) else None
    if found is None:
        raise ValueError(f"torque profile must be one of none, {', '.join(_PROFILE_BY_NAME)}; got {name!r}")
    return found


#: Figures of a result, in the order a report shows them (``outputs.figures``).
FIGURES = ("stability_map", "norm_growth", "flip_law", "flip_components", "invariant_drift", "work_precision",
           "summary", "flip_strip", "flip_animation", "polhode", "herpolhode", "gyrostat_map", "sleeping_top",
           "debra_delp_map", "pitch_libration", "flat_spin", "megno_map", "finite_time", "spectrum", "section")



class FigureModel(NamedTuple):
    """What a figure only a model study draws needs of its study: the model kind, the scan key its axis is (None:
    none) and that scan in words (for the message that refuses a study without it)."""

    kind: str
    scan: str | None
    text: str


#: The figures of a model study, each with the model and the scan it needs (``outputs.figures``).
FIGURE_MODELS = {
    "gyrostat_map": FigureModel("gyrostat", "rotor", "scan.rotor (rotor momentum along the spin axis)"),
    "sleeping_top": FigureModel("heavy_top", "rate", "scan.rate (the spin w3 through the threshold)"),
    "debra_delp_map": FigureModel("gravity_gradient", "k1", "scan.k1 and scan.k3 (the grid of inertia ratios)"),
    "pitch_libration": FigureModel("gravity_gradient", "orbit_rate", "scan.orbit_rate (the orbital rates)"),
    "flat_spin": FigureModel("damper", None, ""),
}

#: The chaos indicators a study may ask for (``chaos.indicators``): :func:`tumble.megno`, :func:`tumble.lyapunov`,
#: :func:`tumble.gali`.
CHAOS_INDICATORS = ("megno", "lyapunov", "gali")

#: The figures of a chaos study (``chaos.indicators`` not empty), each with the indicator it reads.
#: ``section`` reads a section study's crossings (a ``[section]`` table), not an indicator.
CHAOS_FIGURES = {"megno_map": "megno", "finite_time": "lyapunov", "spectrum": "lyapunov", "section": "section"}


class ChaosStart(NamedTuple):
    """A parametrisation of a chaos study's initial states (``chaos.start``): the model kind it applies to ("": any)
    and its coordinates (study keys: ``chaos.<key>`` and ``scan.<key>``; ``rate`` is ``spin.rate``; none: the state's
    components named in ``scan.state``)."""

    name: str
    kind: str
    keys: tuple  # the initial-state coordinates, in the order of the map's dimensions
    text: str


#: The parametrisations of a chaos study's initial states (``chaos.start``).
CHAOS_STARTS = (
    ChaosStart("release", "heavy_top", ("tilt", "rate"),
               "a heavy top released with body axis 3 tilted by chaos.tilt from the vertical (about body axis 1) and "
               "spinning at spin.rate about body axis 3"),
    ChaosStart("swing", "heavy_top", ("tilt",),
               "a heavy top with the vertical in its body 2-3 plane at chaos.tilt from body axis 3 (turned about body "
               "axis 1), turning about body axis 1 alone with the total energy chaos.energy: every orbit on one "
               "energy level, with L.g = 0"),
    ChaosStart("spin_orbit", "gravity_gradient", ("angle", "rate"),
               "a satellite in the orbit plane at perigee, turned by chaos.angle about the orbit normal from the orbit "
               "frame and spinning at spin.rate (inertial) about it: the planar spin-orbit problem"),
    ChaosStart("state", "", (),
               "the state chaos.state (the model's components in order), its components named in "
               "scan.state replaced by each point of their grid"),
)

#: Figures drawn from the traced attitude of a study's first scene.
ATTITUDE_FIGURES = ("flip_animation", "flip_strip", "polhode", "herpolhode")

#: Image formats of the figures (``outputs.format``).
FORMATS = ("png", "pdf")

#: Per-sample variables a result may keep (``outputs.arrays``); the rest are dropped after the fit.
PER_SAMPLE_ARRAYS = ("sample_rate", "sample_status", "sample_first_flip", "sample_flip_spacing")


class ModelParameter(NamedTuple):
    """A numeric parameter of a model: its study key (``[model]`` table, ``scan.<key>``) and what it must be."""

    key: str
    size: int  # 1: a number; 3: a body-frame vector
    units: str
    positive: bool  # must be > 0 (else: any finite value)
    text: str  # "<kind>: what it is" (a result's long_name)
    study: str = ""  # what a study does with it, beyond the text (the docs of studies/defaults.toml)




class Model(NamedTuple):
    """A system tumble can study (a study's ``[model]`` table, ``kind``).

    The state of every model is a flat float64 vector whose first three components are the body-frame angular
    velocity ``w1, w2, w3`` (rad/s); the model's own blocks follow, named by :data:`STATE_BLOCKS` (an attitude
    quaternion, the direction of gravity, internal degrees of freedom). Kernels see the state as plain columns and
    find a block by its offsets (:func:`state_blocks`).
    """

    name: str
    parameter_rows: tuple  # its numeric parameters (ModelParameter rows: key, size, units, sign, texts), in order
    state: tuple  # names of the state components, in order (w1, w2, w3 first)
    invariants: tuple  # names of the quantities the motion conserves
    implemented: bool  # True: studies run it; False: reserved there (name, keys, state fixed; kernels.MODEL_CODES
    # says which models the kernels step, these included)
    physics: bool  # True: a class in physics/models/ (its equations, rhs, exact Jacobian, invariants, linear theory)
    text: str
    scan_keys: tuple = ()  # scan keys of its own beyond its parameters (a grid of bodies in its own terms)
    equations: str = ""  # the module of tumble/physics/models/ that holds its equations ("": the one named as the kind)
    splitting: str = ""  # the Lie–Poisson splitting that steps it (kernels.steps.model_splittings): "rotor" (the
    # sub-flows turn L = I w + h), "gravity" (they turn L and g together, gravity kicks L); "": none
    rate: str = "rate"  # the function of its equations module its error-controlled step calls (``rate(t, *y, c)``)

    @property
    def parameters(self):
        """The study keys of its numeric parameters, in order."""
        return tuple(p.key for p in self.parameter_rows)

    @property
    def equations_module(self):
        """The name of the module (``tumble/physics/models/<name>.py``, copied into ``tumble/kernels/systems/``) that
        holds the model's per-sample equations: :attr:`equations`, or the kind's own name."""
        return self.equations or self.name


#: The first fields of every system's ``Constants`` (the record of named numbers its equations read): the moments
#: ``i1 i2 i3`` (kg m²) and Euler's coefficients ``a_i = (I_j − I_k)/I_i`` (``(i, j, k)`` cyclic), the differences of
#: the moments first (exact for close moments).
RIGID_BODY = ("i1", "i2", "i3", "a1", "a2", "a3")


def rigid_body(moments):
    """The :data:`RIGID_BODY` values of moments ``(I1, I2, I3)`` (kg m²), as plain floats."""
    i1, i2, i3 = (float(x) for x in moments)
    return i1, i2, i3, (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3


#: The blocks a model's state is made of, by the letter its component names start with: (letter, meaning, units).
STATE_BLOCKS = (
    ("w", "body-frame angular velocity", "rad/s"),
    ("g", "unit vector pointing up (against gravity), body frame", "1"),
    ("q", "attitude: unit quaternion body to reference frame, scalar first", "1"),
    ("s", "angular velocity of an internal body (damper sphere), body frame", "rad/s"),
)

#: Every model, the default first: one row each, its parameters' rows inside it.
MODELS = (
    Model("free", (), ("w1", "w2", "w3"), ("energy", "momentum_squared"), True, True,  # the gyrostat with no rotor
          "torque-free rigid body: I w' = (I w) x w", equations="gyrostat", splitting="rotor", rate="free_rate"),
    Model("gyrostat", (
        ModelParameter("rotor", 3, "N m s", False,
                       "gyrostat: rotor angular momentum relative to the body, body frame",
                       "A 3-vector; for a steady spin it must lie along spin.axis. In a scan, scan.rotor lists "
                       "3-vectors, or numbers: h along each scene's spin axis (so that scan.axis can be scanned with "
                       "it)."),),
          ("w1", "w2", "w3"), ("energy", "momentum_squared"), True, True,
          "rigid body with a rotor of constant relative angular momentum h: I w' = (I w + h) x w", splitting="rotor"),
    Model("heavy_top", (
        ModelParameter("mgl", 1, "N m", True, "heavy_top: M g l, weight times the pivot-to-centre-of-mass distance",
                       "body.moments are about the fixed point; spin.axis must be 3 (the sleeping top). The "
                       "perturbation tilts the spin by perturbation.amplitude / 1000 and the up direction by "
                       "perturbation.amplitude."),),
          ("w1", "w2", "w3", "g1", "g2", "g3"), ("energy", "vertical_momentum", "up_squared"), True, True,
          "top on a fixed pivot, centre of mass on body axis 3 (Euler-Poisson): I w' = (I w) x w + mgl (g x e3), "
          "g' = g x w", splitting="gravity"),
    Model("gravity_gradient", (
        ModelParameter("orbit_rate", 1, "rad/s", True, "gravity_gradient: orbital angular rate n of a circular orbit",
                       "spin.axis and spin.rate are not used: the equilibrium follows the orbit (w = (0, -n, 0), body "
                       "axes along the orbit's); the resolved study keeps them as given (defaults: 2, 1.0), scenes "
                       "record spin = n, and scan.axis, scan.rate and spin.momentum are errors. The perturbation tilts "
                       "the attitude by perturbation.amplitude about a uniformly random axis, w at the orbit frame's "
                       "rate."),),
          ("w1", "w2", "w3", "q0", "q1", "q2", "q3"), ("jacobi_integral", "quaternion_squared"), True, True,
          "satellite in a circular orbit under the gravity-gradient torque (axes: 1 roll, 2 pitch, 3 yaw): "
          "I w' = (I w) x w + 3 n^2 (c3 x I c3), q' = q (0, w + n c2) / 2, c2, c3 the orbit's pitch and nadir axes",
          ("k1", "k3")),
    Model("damper", (
        ModelParameter("damper_inertia", 1, "kg m2", True, "damper: moment of inertia J of the damper sphere",
                       "body.moments exclude the sphere. Any spin.axis: about the minor axis the nutation grows "
                       "slowly (exponential), about the major one it decays (periodic: the least damped nutation "
                       "frequency); the sphere starts moving with the body."),
        ModelParameter("damping", 1, "N m s", True, "damper: viscous coupling c between the sphere and the body")),
          ("w1", "w2", "w3", "s1", "s2", "s3"), ("momentum_squared",), True, True,
          "rigid body with a viscously coupled spherical damper (energy dissipates, |L| is kept): "
          "I w' = (I w) x w + c (s - w), J (s' + w x s) = -c (s - w)"),
)
_MODEL_BY_NAME = {m.name: m for m in MODELS}

#: Every numeric parameter of the models (keys of the ``[model]`` table other than ``kind``), from their rows.
MODEL_PARAMETERS = tuple(p for m in MODELS for p in m.parameter_rows)
_PARAMETER_BY_KEY = {p.key: p for p in MODEL_PARAMETERS}
assert len(_PARAMETER_BY_KEY) == len(MODEL_PARAMETERS), "a study key names one model's parameter"

#: Model kinds, in the order of :data:`MODELS`.
MODEL_KINDS = tuple(_MODEL_BY_NAME)

#: The kind of the torque-free body (the gyrostat's equations with no rotor: its fused steps use them too).
FREE_BODY = MODELS[0].name

#: The model of a study that names none.
DEFAULT_MODEL = FREE_BODY

#: The models the Lie–Poisson splittings (symplectic_euler, splitting2, splitting4) step: Lie–Poisson systems in the
#: model kernels' variables (the free body as the gyrostat with h = 0). Not the damper (dissipative) nor the gravity
#: gradient (w and a quaternion relative to the turning orbit frame). The others step with rk4 and rk8.
LIE_POISSON_MODELS = tuple(m.name for m in MODELS if m.splitting)

#: The fixed-step methods the models' kernels run: the explicit Runge–Kutta ones for every model, the splittings for
#: :data:`LIE_POISSON_MODELS` (:func:`model_methods`); the implicit midpoint is the free body's own.
MODEL_STEPPING = tuple(m.name for m in METHODS if m.family in ("runge_kutta", "splitting"))


def model_methods(kind):
    """The names of the methods the models' kernels run for model ``kind``, the Runge–Kutta ones first."""
    return tuple(m.name for m in METHODS if m.family == "runge_kutta" or
                 (m.family == "splitting" and kind in LIE_POISSON_MODELS))


def tangent_methods(kind):
    """The methods whose tangent map the chaos indicators compute for model ``kind`` (None: a user's ``System``): the
    Runge–Kutta ones and the implicit midpoint rule for every system, the splittings for :data:`LIE_POISSON_MODELS`
    (the derivatives of their exact sub-flows; a System has no sub-flows, only a rate)."""
    return tuple(m.name for m in METHODS if m.family in ("runge_kutta", "implicit") or
                 (m.family == "splitting" and kind in LIE_POISSON_MODELS))


def model_kind(name):
    """The :class:`Model` called ``name`` (implemented or reserved); ValueError naming the kinds otherwise."""
    found = _MODEL_BY_NAME.get(name) if isinstance(name, str) else None
    if found is None:
        raise ValueError(f"model kind must be one of {', '.join(MODEL_KINDS)}; got {name!r}")
    return found


def model_parameter(key):
    """The :class:`ModelParameter` with study key ``key``; ValueError naming the keys otherwise."""
    found = _PARAMETER_BY_KEY.get(key) if isinstance(key, str) else None
    if found is None:
        raise ValueError(f"model parameter must be one of {', '.join(_PARAMETER_BY_KEY)}; got {key!r}")
    return found


def state_blocks(name):
    """The blocks of model ``name``'s state as ``(letter, start, stop)``: the components ``start:stop`` are the
    block :data:`STATE_BLOCKS` names by ``letter`` (plain ints, for kernels that take a state as columns)."""
    blocks = []
    for i, component in enumerate(model_kind(name).state):
        if blocks and blocks[-1][0] == component[0]:
            blocks[-1][2] = i + 1
        else:
            blocks.append([component[0], i, i + 1])
    return tuple(tuple(b) for b in blocks)


#: Where an ensemble runs (``device`` of every engine call, ``integration.device`` of a study, ``tumble run
#: --device``): the CPU's cores, or a CUDA GPU through numba-cuda (:mod:`tumble.engine.device`).
DEVICES = ("cpu", "cuda")

#: ``tumble check`` / :func:`tumble.check`: criterion -> default threshold; each passes when its measured value is at
#: most the threshold (:mod:`tumble.measure.check`; ``--tolerance NAME=VALUE`` overrides one).
CHECK_TOLERANCES = {
    "omega_error": 0.05,         # max over time of |w - w_exact| / |w_exact|
    "attitude_error": 0.05,      # max attitude error angle, rad (needs the quaternion)
    "energy_drift": 1e-3,        # max |E / E0 - 1|
    "momentum_drift": 1e-3,      # max ||L| / |L0| - 1|
    "momentum_direction": 1e-3,  # max angle of the space-frame L from its first direction, rad (needs the quaternion)
    "period_error": 1e-2,        # |mean measured flip spacing / (2K/nu) - 1| (needs two exact flips)
    "flip_count": 1,             # |measured flips - exact flips|; no flip at all where the exact motion flips fails
}
