"""The study file, described once: every table and field with its default, units, allowed values and doc.

:data:`FIELDS` is the one description of a study. Derived from it:

- :mod:`tumble.pipeline.config`: the keys each table allows (``_TABLES``), the defaults a study is merged over
  (:func:`defaults`), the allowed values and bounds of the plain fields (their messages are config's);
- ``studies/defaults.toml``: written by :func:`defaults_toml` (``python -m tumble.pipeline.schema`` rewrites it;
  a test checks that the file is current);
- the study-file reference of the docs (``docs/_ext/tumble_docs.py``: units, allowed values, doc text);
- the scene options the runner passes down (:func:`scene_options`, the fields with an ``option``);
- the random studies of ``tests/test_robustness.py``.

Why the defaults file is generated rather than compared: the doc text of a field is part of its description, so
checking the file field by field would leave that text in two places (here and in the file) or in the file alone
(and the docs would read a copy). Generated, the file is a rendering of this module that users read and edit
studies against, and a one-line test says whether it is current.

Plain data, imported by the command line's start-up: nothing here imports numba, xarray or the engine.
"""

from __future__ import annotations

import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

from .. import registry
from ..engine.sampling import DISTRIBUTIONS

__all__ = ["FIELDS", "HEADER", "PROFILES", "SCAN_DOC", "SHAPES", "TABLES", "Field", "defaults", "defaults_toml",
           "field", "main", "scan_replaces", "scene_options", "table_fields"]

#: Shape functions of :mod:`tumble.physics.shapes` a study may name in ``body.shape``.
SHAPES = ("rod", "disc", "cylinder", "cone", "sphere", "ellipsoid", "cuboid", "cube_about_edge", "loaded_die",
          "t_handle")

#: ``torque.profile``: torque-free, or one of the registry's named time dependences.
PROFILES = ("none", *(p.name for p in registry.TORQUE_PROFILES))


@dataclass(frozen=True)
class Field:
    """One key of a study table.

    ``check`` says how config checks the value: ``"string"``, ``"choice"`` (one of ``choices``), ``"names"`` (a
    list of distinct ``choices``; ``nonempty``: at least one), ``"integer"`` / ``"number"`` (``>= minimum``), or the
    name of a field-specific rule in :mod:`tumble.pipeline.config` (``"moments"``, ``"axis"``, ...), which also checks
    the relations between fields. ``option`` names the scene option the field feeds (:func:`scene_options`);
    ``zero_is_auto``: 0 there means the planner's choice (passed down as None). A ``[scan]`` key has no default
    (``default`` None, not in the defaults file) and ``replaces`` the field path its values replace.
    """

    table: str  # "" for the top level
    key: str
    default: object
    doc: str = ""  # the comment above the key in studies/defaults.toml; lines end in "\n"
    units: str = ""
    choices: tuple | None = None  # the allowed values (shown in the docs; checked where check is choice or names)
    check: str = "string"
    minimum: float | None = None
    nonempty: bool = False
    option: str | None = None
    zero_is_auto: bool = False
    replaces: str | None = None

    @property
    def path(self):
        """The field path errors name: ``perturbation.samples`` (``title`` at the top level)."""
        return f"{self.table}.{self.key}" if self.table else self.key

    @property
    def in_defaults(self):
        """Whether the defaults file holds the field (every field but the ``[scan]`` keys)."""
        return self.table != "scan"


def _lines(*lines):
    return "".join(line + "\n" for line in lines)


def _wrapped(prefix, names, suffix, width=110):
    """``prefix`` then ``names`` joined by ", " then ``suffix``, broken into lines of at most ``width`` characters at
    the commas (how the defaults file lists allowed names)."""
    out, line = [], prefix
    for i, name in enumerate(names):
        piece = name + ("," if i < len(names) - 1 else suffix)
        if len(line) + 1 + len(piece) > width and line.strip():
            out.append(line)
            line = piece
        else:
            line = f"{line} {piece}" if line else piece
    return _lines(*out, line)


#: The defaults file's opening comment.
HEADER = _lines(
    "Documented defaults of every tumble study.",
    "",
    "A study file states only what differs from this file; `tumble.pipeline.config.load_study` merges it over these",
    "defaults, checks every value and returns the *resolved* study (all keys filled), which is stored with",
    "each result so that the run can be repeated. A key that is not listed here is an error that names its",
    "field path (e.g. `perturbation.sampels: unknown key; did you mean 'samples'?`).",
    "",
    "Studies are data, never code: a time-dependent torque is one of the named profiles below with numeric",
    "parameters. Arbitrary torque functions belong to the Python API (`tumble.integrate(..., torque=f)`).",
    "Field paths in error messages index lists from 0: `body.moments[2]` is the third moment.",
)

#: The ``[scan]`` table's comment: what a scan is and every key with an example.
SCAN_DOC = _lines(
    "Empty: the study is a single scene. Each key given here lists values; the study then runs every",
    "combination of them (a Cartesian product), each value replacing the single-valued field above.",
    "Lists must be non-empty and free of duplicates; every value is checked like the field it replaces.",
    '  body      = [{shape = "rod", dimensions = {mass = 1.0, length = 0.5, radius = 0.01}, label = "rod"},',
    '               {moments = [1.0, 2.0, 3.0], label = "brick"}]',
    "                          bodies, each an inline table checked exactly like [body]: a shape with its",
    "                          dimensions (defaults filled in) or moments; replaces the whole [body] table.",
    "                          label (optional) names the body in results; default: the shape's name, or",
    '                          "body <i>" (i from 0) for moments; labels must be distinct. Needs',
    '                          body.shape = ""; not with `moments` or `triangle`',
    "  moments   = [[1.0, 2.0, 3.0], [1.0, 1.5, 1.7]]   bodies (lists of 3 principal moments, kg m²),",
    '                                                    replacing body.moments; needs body.shape = ""',
    "  triangle  = 20          an integer n in [2, 200]: the n x n grid of the inertia triangle",
    "                          (tumble.inertia_triangle(n)) instead of a list of moments; not with `moments`",
    '  axis      = [1, 2, 3]   replaces spin.axis; not with a torque (torque.profile other than "none")',
    "  rate      = [0.5, 1.0]  replaces spin.rate, rad/s",
    "  amplitude = [1e-4, 1e-3]                          replaces perturbation.amplitude, rad",
    '  method    = ["rk4", "splitting4"]                 replaces integration.method',
    "  rotor     = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]    replaces model.rotor (gyrostat), N m s: 3-vectors, or",
    "                          numbers h meaning h along each scene's spin axis (e.g. rotor = [0.0, 0.5, 1.0]",
    "                          with axis = [1, 2, 3])",
    "  mgl       = [0.5, 1.0]  replaces model.mgl (heavy_top), N m, each > 0",
    "  orbit_rate = [0.5, 1.0]        replaces model.orbit_rate (gravity_gradient), rad/s, each > 0",
    "  damping = [0.001, 0.002]       replaces model.damping (damper), N m s, each > 0",
    "  damper_inertia = [0.05, 0.1]   replaces model.damper_inertia (damper), kg m^2, each > 0",
    "  k1 = [-0.5, 0.5]  k3 = [-0.5, 0.5]",
    "                          gravity_gradient only, both together: the grid k1 x k3 of bodies with the inertia",
    "                          ratios k1 = (I2 - I3)/I1, k3 = (I2 - I1)/I3, each in (-1, 1), I2 = 1 kg m²",
    "                          (I1 = (1 - k3)/(1 - k1 k3), I3 = (1 - k1)/(1 - k1 k3): every point of the open square",
    "                          is a body); the result's body dimension has coordinates k1, k3. Not with body,",
    "                          moments, triangle or body.shape",
    "  tilt = [0.1, 0.2]  angle = [0.0, 0.5]",
    "                          chaos studies only: the initial-state coordinates of chaos.start (release: tilt, rad,",
    "                          in [0, pi]; spin_orbit: angle, rad); with scan.rate (the initial spin) they span the",
    "                          map: one orbit per point, run together in one scene (the other scan keys: scenes)",
    "  state = {w1 = [0.1, 0.2], w3 = [0.5, 1.0]}",
    "                          chaos.start = \"state\" only: named components of the model's state, each a list of",
    "                          values replacing that component of chaos.state; the map spans them in the order given",
)

def _parameter_doc(p):
    """The docs of model parameter ``p`` (a row of :data:`tumble.registry.MODEL_PARAMETERS`, which holds them once)."""
    text = f"{p.text}, {p.units} ({'> 0' if p.positive else 'finite'}). {p.study}".rstrip()
    return _lines(*textwrap.wrap(text, 110))


def _model_fields():
    """``[model]``: the kind, then each model parameter of the registry (default 0: a kind's own keys are checked
    by config against the kind)."""
    fields = [Field("model", "kind", registry.DEFAULT_MODEL, _lines(
        'The system studied: "free" (the torque-free rigid body, every study without a [model] table),',
        '"gyrostat" (a body carrying a rotor of constant relative angular momentum), "heavy_top" (a top on a',
        'fixed pivot, centre of mass on body axis 3), "gravity_gradient" (a satellite in a circular orbit under the',
        'gravity-gradient torque; axes 1 roll, 2 pitch, 3 yaw) and "damper" (a body with a viscously coupled damper',
        "sphere: energy dissipates, |L| is kept).",
        'Model studies step with rk4 or rk8 (integration.method "auto" is rk4), torque-free (torque.profile "none"),',
        "time no flips, and draw the figures gyrostat_map, sleeping_top, debra_delp_map, pitch_libration, flat_spin",
        'and summary (default: ["summary"]).',
        "Only the kind's own keys below may be given; another kind's key is an error."),
        choices=registry.MODEL_KINDS, check="model_kind")]
    for p in registry.MODEL_PARAMETERS:
        default = [0.0] * p.size if p.size > 1 else 0.0
        fields.append(Field("model", p.key, default, _parameter_doc(p), units=p.units, check="model_parameter"))
    fields += [
        Field("model", "centre", [0.0, 0.0, 1.0], _lines(
            "heavy_top: direction of the centre of mass from the pivot, body axes (a non-zero 3-vector, normalised).",
            "Off body axis 3 only in a chaos study (chaos.indicators): the sleeping top needs it on axis 3."),
            units="1", check="model_extra"),
        Field("model", "eccentricity", 0.0, _lines(
            "gravity_gradient: eccentricity e of the orbit, in [0, 1) (perigee at t = 0; orbit_rate is the mean",
            "motion). Above 0 only in a chaos study (chaos.indicators): no attitude is then an equilibrium."),
            units="1", check="model_extra"),
    ]
    return fields


def _chaos_fields():
    """``[chaos]``: the indicators a study maps and how each point of its map becomes an initial state."""
    starts = registry.CHAOS_STARTS
    return (
        Field("chaos", "indicators", [], _lines(
            "Chaos indicators to map, any of: megno (mean MEGNO <Y>: 2 regular, 0 near a stable periodic orbit,",
            "growing like lambda t / 2 when chaotic), lyapunov (the Lyapunov spectrum, and its finite-time",
            "exponents over time), gali (GALI_k over time). [] (the default): not a chaos study, every key below",
            "unused (but with a [section]). A chaos study needs a [model] with a chaos.start of its kind,",
            "integration.horizon > 0 (the time each orbit runs) and either a fixed integration.dt > 0 with a method",
            "whose map tumble differentiates (rk4, rk8, implicit_midpoint; the splittings for free, gyrostat and",
            "heavy_top; \"auto\": rk4) or integration.method = \"dop853\" with integration.rtol and atol (dt then the",
            "first step, 0: chosen; the finite-time curves at chaos.points evenly spaced times). It draws megno_map,",
            "finite_time, spectrum and, with a [section], section (default: section, then megno_map when megno is",
            "asked for, else finite_time when lyapunov is). Each point of the map (scan.<coordinate> x scan.rate, see",
            "[scan]) is one initial state, run with every other; the perturbation table is not used."),
            choices=registry.CHAOS_INDICATORS, check="names"),
        Field("chaos", "start", starts[0].name, "How a point of the map becomes an initial state:\n" + "".join(
            _lines(f'  "{s.name}" ({s.kind or "any model"}; coordinates '
                   f'{", ".join(s.keys) or "the components scan.state names"}): {s.text}') for s in starts),
            choices=tuple(s.name for s in starts), check="choice"),
        Field("chaos", "tilt", 0.5, _lines(
            'release and swing: tilt of body axis 3 from the vertical, rad, in [0, pi] ([0, 2 pi] for swing: the',
            'turn about body axis 1; scan.tilt scans it).'),
            units="rad", check="chaos_tilt"),
        Field("chaos", "angle", 0.0, _lines(
            "spin_orbit: angle of the body's roll axis from the orbit frame's about the orbit normal, rad, any finite",
            "number (scan.angle scans it). The rate (spin.rate, scan.rate) is the body's inertial spin about the",
            "orbit normal, rad/s (the synchronous spin at perigee is n (1 + e)^2 / (1 - e^2)^(3/2))."),
            units="rad", check="chaos_angle"),
        Field("chaos", "state", [], _lines(
            "state: the initial state, the model's components in order (model.kind's state: w1 w2 w3 then g1 g2 g3",
            "for a heavy_top, q0 q1 q2 q3 for a gravity_gradient, s1 s2 s3 for a damper; w rad/s, the others as the",
            "model defines them, used as given: a g or q must be of unit length at every point of the map, never",
            "normalised). scan.state names the components the map replaces, e.g. scan.state = {w1 = [0.1, 0.2],",
            "w3 = [0.5, 1.0]}."),
            units="state units", check="chaos_state"),
        Field("chaos", "energy", 0.0, _lines(
            "swing: the total energy of every orbit of the map, J (1/2 w.Iw + mgl c.g, c the centre's unit",
            "direction), at least the potential mgl c.g at each tilt of the map (where the top would be at rest)."),
            units="J", check="chaos_energy"),
        Field("chaos", "renormalise", 1.0, _lines(
            "lyapunov: seconds between two orthonormalisations of the tangent vectors, a positive multiple of",
            "integration.dt (any > 0 with dop853; the exponents do not depend on it beyond round-off)."),
            units="s", check="chaos_renormalise"),
        Field("chaos", "transient", 0.0, _lines(
            "lyapunov: seconds before the exponents' sums start, >= 0 and less than integration.horizon."),
            units="s", check="chaos_transient"),
        Field("chaos", "exponents", 0, _lines(
            "lyapunov: how many exponents (the largest first), 1 to the state's size; 0: the whole spectrum."),
            units="1 (count)", check="integer", minimum=0),
        Field("chaos", "gali_k", 2, _lines("gali: the number k of tangent vectors of GALI_k, 2 to the state's size."),
              units="1 (count)", check="integer", minimum=2),
        Field("chaos", "points", 40, _lines(
            "lyapunov and gali: about how many times the finite-time exponents and GALI are stored, >= 1 (evenly in",
            "steps; the finite_time figure draws them on log axes)."),
            units="1 (count)", check="integer", minimum=1),
    )


def _section_fields():
    """``[section]``: the Poincaré section of every orbit of a chaos study's map."""
    return (
        Field("section", "surface", "", _lines(
            "A Poincaré section of every orbit of the map (chaos.start's initial states; chaos.indicators may be",
            "empty): the crossings of a component of the model's state (model.kind's state, e.g. \"g1\") through",
            "`value`, located on the dense output of integration.method = \"dop853\", which a section needs. \"\"",
            "(the default) with period 0: not a section study, every key below unused."),
            check="section_surface"),
        Field("section", "value", 0.0, _lines("The value the surface's component crosses (its units)."),
              units="state units", check="number_any"),
        Field("section", "direction", 1, _lines(
            "The crossings counted: 1 (the component rising through `value`), -1 (falling) or 0 (both)."),
            units="1", check="section_direction"),
        Field("section", "period", 0.0, _lines(
            "> 0: the stroboscopic section instead of a surface, the states at phase + k period (k = 1, 2, ...),",
            "s; 0: none. Not with `surface`."),
            units="s", check="number", minimum=0),
        Field("section", "phase", 0.0, _lines("The stroboscopic section's phase, s, >= 0."),
              units="s", check="number", minimum=0),
        Field("section", "crossings", 200, _lines(
            "Crossings kept per orbit, >= 1; an orbit stops once it has them (or at integration.horizon)."),
            units="1 (count)", check="integer", minimum=1),
        Field("section", "axes", [], _lines(
            "The two coordinates the section figure plots, each a coordinate of chaos.start (its inverse at the",
            "crossing: spin_orbit's angle, mod pi, and rate; release's and swing's tilt; release's rate) or a",
            "component of the state; [] (the default): the start's two coordinates."),
            check="section_axes"),
        Field("section", "colour", "orbit", _lines(
            'Colour of the section\'s points: "orbit" (each orbit its own) or "megno" (its mean MEGNO <Y>; needs',
            '"megno" in chaos.indicators).'),
            choices=("orbit", "megno"), check="choice"),
    )


#: Every field of a study, table by table, in the order of the defaults file and of the resolved study.
FIELDS = (
    Field("", "title", "", _lines(
        "Human-readable title of the study, stored in the output file.",
        '"" (the default) means: the study file\'s stem, e.g. "intermediate_axis" for intermediate_axis.toml.')),
    Field("body", "moments", [1.0, 2.0, 3.0], _lines(
        "Principal moments of inertia (I1, I2, I3), kg m², in any order; all > 0 and obeying the triangle",
        'inequality Ia + Ib >= Ic (equality: a flat lamina). Used when `shape` is "". When `shape` is set, the',
        "resolved study holds the shape's moments here; a study may state them only if they agree."),
        units="kg m²", check="moments"),
    Field("body", "shape", "", 'A body from tumble.shapes instead of raw moments: "" (use `moments`) or one of\n'
          + _wrapped("", SHAPES, "."), choices=("", *SHAPES), check="shape"),
    Field("body", "dimensions", {}, _lines(
        "Keyword arguments of the shape function, SI units (kg, m), e.g. {mass = 1.0, a = 0.3, b = 0.2, c = 0.1}",
        'for a cuboid; numbers, except `about` (rod: "centre" | "end"; cone: "apex" | "centre_of_mass").',
        "Arguments left out take the function's defaults, which the resolved study then lists. Only with `shape`."),
        check="dimensions"),
    Field("spin", "axis", 2, _lines(
        "Principal axis of the steady spin: 1, 2 or 3 (1-based, in the order of `body.moments`)."),
        units="1 (1-based axis)", choices=(1, 2, 3), check="axis"),
    Field("spin", "rate", 1.0, _lines(
        "Spin rate about that axis, rad/s; any finite non-zero number (the sign is the sense of rotation)."),
        units="rad/s", check="rate"),
    Field("spin", "momentum", [], _lines(
        "Initial angular momentum (L1, L2, L3), N m s, body frame, instead of axis and rate: [] (use axis and rate)",
        "or three numbers. The unperturbed spin is w = I^-1 (L - h) (h: the gyrostat's rotor, else 0); it must lie",
        "along a principal axis, which then gives spin.axis and spin.rate (stated as well, they must agree). Not",
        "with scan.axis, scan.rate, scan.rotor or a scan of bodies (each would change w)."),
        units="N m s", check="momentum"),
    *_model_fields(),
    Field("perturbation", "amplitude", 1e-3, _lines(
        "Tilt of the perturbed spins away from the axis, rad: >= 0; < pi/2 for the cone distributions",
        '(for "gaussian" it is the standard deviation of the tilt).'),
        units="rad", check="amplitude"),
    Field("perturbation", "samples", 1024, _lines(
        "Number of perturbed spins (Monte Carlo samples) per scene, >= 1."),
        units="1 (count)", check="integer", minimum=1),
    Field("perturbation", "seed", 0, _lines(
        "Seed of the sample streams, an integer >= 0; the same seed gives the same samples bit for bit."),
        units="1", check="integer", minimum=0),
    Field("perturbation", "distribution", "cone", _lines(
        'How the tilt is drawn: "cone" (every spin tilted by exactly `amplitude`, azimuth uniform),',
        '"filled_cone" (uniform over the spherical cap of half-angle `amplitude`) or "gaussian".'),
        choices=DISTRIBUTIONS, check="choice", option="distribution"),
    Field("integration", "method", "auto", _lines(
        '"auto" (the exact closed form when torque-free, else a fixed-step method picked by the planner),',
        '"exact" (Jacobi elliptic functions; torque-free only), a fixed-step method:')
        + _wrapped("", registry.STEPPING, ",") + _lines(
        'or "dop853" (error-controlled to integration.rtol and atol, each orbit its own steps; a chaos or section',
        "study's only: see [chaos] and [section])."),
        choices=(*registry.CHOICES, *registry.ERROR_CONTROLLED), check="method"),
    Field("integration", "dt", 0.0, _lines(
        "Time step, s, >= 0; 0 means chosen from the method's order and the body's time scales."),
        units="s", check="number", minimum=0, option="dt", zero_is_auto=True),
    Field("integration", "rtol", 1e-10, _lines(
        'method "dop853": the relative tolerance of each step\'s error estimate, >= 1e-14 (with atol: |err| <=',
        "atol + rtol |y| per component, in Hairer's norm). integration.dt is then the first step (0: chosen)."),
        units="1", check="tolerance"),
    Field("integration", "atol", 1e-12, _lines(
        'method "dop853": the absolute tolerance, > 0 (in the state\'s units; the tangent vectors, of unit size, take',
        "the same rtol and atol)."),
        units="state units", check="tolerance"),
    Field("integration", "max_steps", 1000000, _lines(
        'method "dop853": the steps (accepted and rejected) each orbit may take, an integer >= 1; an orbit that',
        'needs more stops with status "step limit" (a section keeps the crossings found before).'),
        units="1 (count)", check="integer", minimum=1),
    Field("integration", "horizon", 0.0, _lines(
        "Horizon of each scene, s, >= 0 and finite; 0 means chosen by the planner from the scene's time scales.",
        "For a periodic scene (spin about the largest or smallest axis) it is the span of the phase fit that",
        "measures the frequency; about the intermediate axis, the span over which the norm of the perturbation",
        "is probed (growth rate) and the flips are timed."),
        units="s", check="number", minimum=0, option="horizon", zero_is_auto=True),
    Field("integration", "flips", 3, _lines(
        "Number of flips to time when spinning about the intermediate axis, an integer >= 0 (0: none)."),
        units="1 (count)", check="integer", minimum=0, option="flips"),
    Field("integration", "device", "cpu", _lines(
        'Where the scenes run: "cpu" (numba on every core) or "cuda" (an NVIDIA GPU through numba-cuda; install it',
        'with pip install "tumble[gpu]"). Every study\'s scenes run there (stepping, closed form, [model]); where the '
        "GPU or",
        'numba-cuda is missing, "cuda" is refused with a line that starts "device \'cuda\':" and says why; nothing '
        "falls",
        "back to the CPU silently. tumble run --device overrides it."),
        choices=registry.DEVICES, check="choice", option="device"),
    *_chaos_fields(),
    *_section_fields(),
    Field("torque", "profile", "none", _lines(
        "Body-frame torque N(t), one of the named profiles (no code in studies):",
        '  "none"     N = 0 (torque-free; `vector` must then be zero)',
        '  "constant" N = vector',
        '  "ramp"     N = vector * min(t / duration, 1)            (rises linearly, then holds)',
        '  "sine"     N = vector * sin(2 pi t / period)',
        '  "pulse"    N = vector for 0 <= t < duration, then 0'),
        choices=PROFILES, check="torque"),
    Field("torque", "vector", [0.0, 0.0, 0.0], _lines(
        "Torque vector (N1, N2, N3), N m, body frame: the constant torque, or the profile's amplitude.",
        'With a profile other than "none" the torque acts about the spin axis only (the "wobbly space',
        'station"): the component on spin.axis must be non-zero and the other two 0, because measured rates',
        "are compared with linear theory for that case; e.g. vector = [0, 0, 1e-3] with spin.axis = 3.",
        "scan.axis is then not allowed (the torque fixes the axis). Arbitrary torques belong to the Python API."),
        units="N m", check="torque"),
    Field("torque", "period", 0.0, _lines(
        'Period of the "sine" profile, s; must be > 0 for "sine" and 0 (unused) for every other profile.'),
        units="s", check="torque", minimum=0),
    Field("torque", "duration", 0.0, _lines(
        'Rise time of "ramp" / length of "pulse", s; must be > 0 for those and 0 (unused) otherwise.'),
        units="s", check="torque", minimum=0),
    *(Field("scan", key, None, units=units, check="scan", replaces=replaces) for key, replaces, units in (
        ("body", "body", ""), ("moments", "body.moments", "kg m²"), ("triangle", "body.moments", "1 (grid size n)"),
        ("axis", "spin.axis", "1 (1-based axis)"), ("rate", "spin.rate", "rad/s"),
        ("amplitude", "perturbation.amplitude", "rad"), ("method", "integration.method", ""),
        *((p.key, f"model.{p.key}", p.units) for p in registry.MODEL_PARAMETERS),
        ("k1", "body.moments", "1"), ("k3", "body.moments", "1"),
        ("tilt", "chaos.tilt", "rad"), ("angle", "chaos.angle", "rad"), ("state", "chaos.state", "state units"))),
    Field("outputs", "figures", ["norm_growth", "summary"], _lines(
        "Figures to draw, any of: stability_map, norm_growth, flip_law, flip_components, invariant_drift,",
        "work_precision, summary ([] for none); and from the traced attitude of the first scene (one spin, its",
        "orientation in space): flip_animation (GIF, or MP4 when ffmpeg is installed, whatever `format` says),",
        "flip_strip (snapshots), polhode (body frame), herpolhode (space frame). Model studies (model.kind other",
        "than \"free\"): gyrostat_map (a gyrostat's scan.rotor, against scan.axis), sleeping_top (a heavy top's",
        "scan.rate), debra_delp_map (a gravity_gradient's scan.k1 x scan.k3 grid), pitch_libration (a "
        "gravity_gradient's",
        "scan.orbit_rate), flat_spin (a damper: the first scene's samples traced from a minor-axis spin to the flat "
        "spin,",
        "with the integrator's drift at c ~ 0, and the growth rate against scan.damping) and summary; their default "
        "is",
        '["summary"].'),
        choices=registry.FIGURES, check="names"),
    Field("outputs", "format", ["png"], _lines(
        'File formats of every figure: "png" and/or "pdf" (at least one).'),
        choices=registry.FORMATS, check="names", nonempty=True),
    Field("outputs", "arrays", ["sample_rate"], _lines(
        "Per-sample arrays kept in the netCDF file, any of: sample_rate, sample_status, sample_first_flip,",
        "sample_flip_spacing ([] keeps only the per-scene results)."),
        choices=registry.PER_SAMPLE_ARRAYS, check="names"),
    Field("outputs", "directory", "", _lines(
        'Folder the run writes its netCDF file and figures to; "" means data/runs/<study stem>/ under the',
        "current directory. `tumble run --out` overrides it.")),
)

#: The tables in order, each with the keys a study may give there (``scan``: the scan keys).
TABLES = {}
for _field in FIELDS:
    if _field.table:
        TABLES.setdefault(_field.table, []).append(_field.key)
TABLES = {table: tuple(keys) for table, keys in TABLES.items()}
del _field

_BY_PATH = {f.path: f for f in FIELDS}


def field(path):
    """The :class:`Field` at ``path`` (``"integration.dt"``; ``"title"``)."""
    return _BY_PATH[path]


def table_fields(table):
    """The fields of ``table`` ("" for the top level), in order."""
    return tuple(f for f in FIELDS if f.table == table)


def scan_replaces():
    """``{scan key: the field path its values replace}`` (``scan.body`` replaces the whole ``[body]`` table)."""
    return {f.key: f.replaces for f in table_fields("scan")}


def scene_options(resolved):
    """``{option: value}`` of the fields of a resolved study that feed its scenes (those with an ``option``; 0 is None
    where it means the planner's choice): what :class:`tumble.pipeline.runner.SceneOptions` is built from."""
    out = {}
    for f in FIELDS:
        if f.option:
            value = resolved[f.table][f.key]
            out[f.option] = (value or None) if f.zero_is_auto else value
    return out


def defaults():
    """The defaults every study is merged over, as the defaults file holds them: ``{"title": "", "body": {...},
    ..., "scan": {}, ...}`` (a new copy each call)."""
    import copy

    out = {}
    for f in FIELDS:
        if not f.table:
            out[f.key] = copy.deepcopy(f.default)
            continue
        table = out.setdefault(f.table, {})
        if f.in_defaults:
            table[f.key] = copy.deepcopy(f.default)
    return out


def _toml(value):
    """``value`` written as TOML (the few types a default takes)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float):
        return _float(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no TOML for {value!r}")


def _float(x):
    """A float as TOML, small ones in exponent form (``1e-3``, as a person writes it) where that gives it back."""
    text = repr(x)
    if x and abs(x) < 1e-2 and "e" not in text:
        mantissa, exponent = f"{x:e}".split("e")
        short = f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"
        if float(short) == x:
            return short
    return text


def _comment(doc):
    return [("# " + line).rstrip() if line else "#" for line in doc.splitlines()]


def defaults_toml():
    """The text of ``studies/defaults.toml``: :data:`HEADER`, then every field of :data:`FIELDS` with its doc as the
    comment above it, table by table (``[scan]``: :data:`SCAN_DOC`)."""
    lines = _comment(HEADER)
    table = None
    for f in FIELDS:
        if f.table != table:
            table = f.table
            lines.append("")
            if table:
                lines.append(f"[{table}]")
            if table == "scan":
                lines += [*_comment(SCAN_DOC), ""]
                table = "scan"
        if not f.in_defaults:
            continue
        lines += [*_comment(f.doc), f"{f.key} = {_toml(f.default)}"]
    text = "\n".join(lines) + "\n"
    return text.replace("\n\n\n", "\n\n")


def main(argv=None):
    """``python -m tumble.pipeline.schema [--check]``: write ``studies/defaults.toml`` from :data:`FIELDS` (or, with
    ``--check``, exit 1 when the file is not current)."""
    from .config import DEFAULTS_PATH

    argv = sys.argv[1:] if argv is None else argv
    text = defaults_toml()
    path = Path(DEFAULTS_PATH)
    if "--check" in argv:
        current = path.read_text(encoding="utf-8") == text
        print(f"{path}: {'current' if current else 'not current: run python -m tumble.pipeline.schema'}")
        return 0 if current else 1
    path.write_text(text, encoding="utf-8")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
