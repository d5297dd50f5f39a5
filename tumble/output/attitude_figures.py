"""Pictures of one traced spin's attitude: the body flipping in space, and Poinsot's polhode and herpolhode.

Reads the attitude of one spin, as :func:`tumble.measure.traces.attitude_trace` stores it:

========================================================  ==============================================
``attitude_time`` (coordinate)                            time, s, increasing
``attitude_quaternion(attitude_time, quaternion_component)``  unit quaternion, scalar first, of the body-to-space
                                                          rotation, ``v_space = q v_body q*``; the space
                                                          frame is the body frame at ``t = 0``
``attitude_omega(attitude_time, component)``              body-frame angular velocity, rad/s
``attitude_moments(component)``                           principal moments, kg m² (``component``: 1, 2, 3)
attributes of ``attitude_quaternion``                     ``method``, ``spin_axis`` (1-based), optional
                                                          ``body_shape`` and ``body_shape_json``
========================================================  ==============================================

Other variables of the dataset are ignored; extra (scan) dimensions are taken at the first scene with a finite
trace. :func:`read_attitude` turns the variables into an :class:`AttitudeTrace`; the drawing functions take
either. :mod:`tumble.output.figures` registers them as the figures ``flip_animation``, ``flip_strip``, ``polhode`` and
``herpolhode`` in the paper style; call them from there.

The body is drawn as the uniform box with the same principal moments (edge ``a_i = sqrt(6 (I_j + I_k − I_i)
/ M)``), or, when ``body_shape`` is ``"t_handle"``, as the T-handle of :func:`tumble.physics.shapes.t_handle` built
from ``body_shape_json``. Every 3-D view is drawn in the *invariable frame*: ``L`` (fixed in space) points up.
The intermediate principal axis is red, so a flip is the red axis turning from up to down.

Poinsot's construction (Landau & Lifshitz, *Mechanics* §37; Goldstein, *Classical Mechanics* §5.6): in the
body frame ``ω(t)`` runs on the intersection (the polhode) of the energy ellipsoid ``Σ I_i ω_i² = 2T`` with
the momentum ellipsoid ``Σ I_i² ω_i² = |L|²``; in space the tip of ``ω`` traces the herpolhode in the
invariable plane ``ω · L̂ = 2T/|L|``.

Nothing here uses pyplot: figures are :class:`matplotlib.figure.Figure` objects; the animation is a
:class:`FlipAnimation` (a :class:`matplotlib.animation.FuncAnimation`) written by :func:`save_animation`.
"""

from __future__ import annotations

import inspect
import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib import animation
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection
from PIL import Image

from ..physics import shapes
from . import io, layout

__all__ = ["ATTITUDE_VARIABLES", "AttitudeTrace", "FlipAnimation", "animation_format", "box_proportions",
           "flip_animation", "flip_strip", "flip_times", "herpolhode", "herpolhode_points", "invariable_frame",
           "missing_attitude", "polhode", "read_attitude", "rotation_matrices", "save_animation",
           "snapshot_times"]

#: The variables an attitude trace is made of.
ATTITUDE_VARIABLES = ("attitude_quaternion", "attitude_omega", "attitude_moments")

#: Figure widths, inches (those of :mod:`tumble.output.figures`: one journal column, two columns).
_SINGLE, _DOUBLE = 3.4, 7.0

#: Animation defaults: frames, frames per second, size (inches) and resolution (dots per inch). 160 frames of
#: 224 × 240 pixels render in a few seconds and make a GIF of a few hundred kB.
FRAMES, FPS, ANIMATION_SIZE, ANIMATION_DPI = 160, 20, (2.8, 3.0), 80

#: Body shapes drawn as themselves (others are drawn as the box of equal moments). Only names listed here are
#: ever looked up in :mod:`tumble.physics.shapes`: a dataset names a shape, it never names code to run.
_DRAWN_SHAPES = ("t_handle",)

_INTERMEDIATE = "#d62728"   # the intermediate axis and what marks it
_INTERMEDIATE_BACK = "#f2b8b3"
_BODY = "#aebdd0"
_L_COLOR = "k"
_LIGHT = np.array([-0.35, -0.55, 0.76]) / np.linalg.norm([-0.35, -0.55, 0.76])
_VIEW = {"elev": 16.0, "azim": -62.0}
_PRISM_SIDES = 14


# ------------------------------------------------------------------------------------------------ reading


@dataclass(frozen=True)
class AttitudeTrace:
    """One traced spin: its attitude, body-frame angular velocity and body.

    Attributes
    ----------
    time : ndarray, shape (T,)
        Times, s, increasing.
    quaternion : ndarray, shape (T, 4)
        Unit quaternions, scalar first, of the body-to-space rotation (``v_space = q v_body q*``).
    omega : ndarray, shape (T, 3)
        Body-frame angular velocity, rad/s.
    moments : ndarray, shape (3,)
        Principal moments, kg m², in the order of the body axes 1, 2, 3.
    spin_axis : int
        The nominal spin axis, 1-based (0 when unknown).
    method : str
        How the trace was computed.
    body_shape : str
        Name of a :mod:`tumble.physics.shapes` constructor, or "" when only the moments are known.
    shape_params : dict
        Keyword arguments of that constructor.
    label : str
        The scene of a scan the trace was taken from ("" for a single trace).
    """

    time: np.ndarray
    quaternion: np.ndarray
    omega: np.ndarray
    moments: np.ndarray
    spin_axis: int = 0
    method: str = ""
    body_shape: str = ""
    shape_params: dict = field(default_factory=dict)
    label: str = ""

    @property
    def intermediate_axis(self):
        """The 1-based axis of the intermediate moment (the spin axis, or axis 2, when moments tie)."""
        order = np.argsort(self.moments, kind="stable")
        lo, mid, hi = self.moments[order]
        if np.isclose(lo, mid, rtol=1e-9) or np.isclose(mid, hi, rtol=1e-9):
            return self.spin_axis or 2
        return int(order[1]) + 1


def missing_attitude(ds):
    """What ``ds`` lacks to be drawn as an attitude trace ("" when nothing).

    Parameters
    ----------
    ds : xarray.Dataset

    Returns
    -------
    str
        A phrase completing "<figure> needs ...", or "".
    """
    absent = [name for name in ATTITUDE_VARIABLES if name not in ds.variables]
    if absent:
        have = "has none" if len(absent) == len(ATTITUDE_VARIABLES) else f"lacks {', '.join(map(repr, absent))}"
        return ("the attitude of one traced spin: 'attitude_quaternion' (attitude_time, quaternion_component), "
                "'attitude_omega' (attitude_time, component) and 'attitude_moments' (component), as "
                f"tumble.attitude_trace gives; this dataset {have}")
    for name, dims in (("attitude_quaternion", ("attitude_time", "quaternion_component")),
                       ("attitude_omega", ("attitude_time", "component")), ("attitude_moments", ("component",))):
        lacking = [d for d in dims if d not in ds[name].dims]
        if lacking:
            return f"{name!r} along the dimension(s) {', '.join(map(repr, lacking))}"
    if ds.sizes["quaternion_component"] != 4 or ds.sizes["component"] != 3:
        return ("4 quaternion components and 3 vector components (sizes of 'quaternion_component' and "
                f"'component'), got {ds.sizes['quaternion_component']} and {ds.sizes['component']}")
    if "attitude_time" not in ds.variables:
        return "the coordinate 'attitude_time' (s)"
    finite = _finite_rows(ds)
    if int(finite.sum("attitude_time").max()) < 2:
        return "an attitude trace with at least 2 finite times ('attitude_quaternion' is NaN or too short)"
    return ""


def _finite_rows(ds):
    """Boolean DataArray: times (per scene of a scan) where the quaternion and omega are finite."""
    quaternion = np.isfinite(ds["attitude_quaternion"]).all("quaternion_component")
    omega = np.isfinite(ds["attitude_omega"]).all("component")
    return quaternion & omega & np.isfinite(ds["attitude_time"])


def read_attitude(ds):
    """The attitude trace held by ``ds``.

    Parameters
    ----------
    ds : xarray.Dataset
        With the variables of the module's schema; scan dimensions are taken at the first scene with a finite
        trace, NaN-padded times are dropped.

    Returns
    -------
    AttitudeTrace

    Raises
    ------
    ValueError
        ``ds`` has no usable attitude (the message says what is missing).
    """
    reason = missing_attitude(ds)
    if reason:
        raise ValueError(f"an attitude plot needs {reason}")
    rows = _finite_rows(ds)
    extra = [d for d in rows.dims if d != "attitude_time"]
    where = {}
    if extra:
        enough = rows.sum("attitude_time") >= 2
        index = np.argwhere(np.asarray(enough.transpose(*extra).values))[0]
        where = dict(zip(extra, map(int, index)))

    def at(name, *core):
        da = ds[name].isel({d: i for d, i in where.items() if d in ds[name].dims})
        return np.asarray(da.transpose(*core).values, dtype=float)

    keep = np.asarray(rows.isel(where).values, dtype=bool)
    time = np.broadcast_to(at("attitude_time", "attitude_time"), keep.shape)[keep]
    quaternion = at("attitude_quaternion", "attitude_time", "quaternion_component")[keep]
    quaternion = quaternion / np.linalg.norm(quaternion, axis=1, keepdims=True)
    omega = at("attitude_omega", "attitude_time", "component")[keep]
    moments = at("attitude_moments", "component")
    if not np.all(np.isfinite(moments) & (moments > 0)):
        raise ValueError(f"an attitude plot needs positive principal moments in 'attitude_moments', got {moments}")
    attrs = ds["attitude_quaternion"].attrs
    shape = str(attrs.get("body_shape", "") or "")
    params = {}
    if shape:
        try:
            params = json.loads(str(attrs.get("body_shape_json", "") or "{}"))
        except json.JSONDecodeError:
            params = None
        if not isinstance(params, dict):
            warnings.warn(f"attitude_quaternion.body_shape_json is not a JSON object; drawing {shape!r} as a box",
                          stacklevel=2)
            shape, params = "", {}
    try:
        spin_axis = int(attrs.get("spin_axis", 0))
    except (TypeError, ValueError):
        spin_axis = 0
    label = ", ".join(f"{d} = {_coord_text(ds, d, i)}" for d, i in where.items())
    return AttitudeTrace(time=time, quaternion=quaternion, omega=omega, moments=moments, spin_axis=spin_axis,
                         method=str(attrs.get("method", "")), body_shape=shape, shape_params=params, label=label)


def _coord_text(ds, dim, index):
    if dim in ds.coords:
        value = ds[dim].values[index]
        return f"{value:.3g}" if isinstance(value, (float, np.floating)) else str(value)
    return str(index)


def _trace(source):
    return source if isinstance(source, AttitudeTrace) else read_attitude(source)


# --------------------------------------------------------------------------------------------- kinematics


def rotation_matrices(quaternion):
    """Rotation matrices of scalar-first quaternions: ``R q`` maps body vectors to space, ``v_s = q v_b q*``.

    Parameters
    ----------
    quaternion : array_like, shape (..., 4)
        Quaternions ``(w, x, y, z)``; normalised here.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = np.asarray(quaternion, dtype=float)
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def _momentum_space(trace):
    """Space-frame angular momentum per time, shape (T, 3), kg m²/s."""
    return np.einsum("tij,tj->ti", rotation_matrices(trace.quaternion), trace.moments * trace.omega)


def invariable_frame(source):
    """Orthonormal space-frame basis with ``L`` as its third vector.

    ``L`` is the mean over the trace of ``R(t) I ω(t)`` (constant without torque). The first vector is the
    space basis vector least aligned with ``L``, made perpendicular to it.

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset

    Returns
    -------
    ndarray, shape (3, 3)
        Rows ``ê_1, ê_2, L̂``; ``frame @ v`` gives a space vector's invariable-frame components.
    """
    trace = _trace(source)
    momentum = _momentum_space(trace).mean(axis=0)
    norm = np.linalg.norm(momentum)
    if not np.isfinite(norm) or norm == 0:
        raise ValueError("the trace has no angular momentum: no invariable plane")
    up = momentum / norm
    seed = np.eye(3)[np.argmin(np.abs(up))]
    first = seed - (seed @ up) * up
    first /= np.linalg.norm(first)
    return np.stack([first, np.cross(up, first), up])


def herpolhode_points(source):
    """The herpolhode: the tip of the space-frame angular velocity ``ω_s(t) = R(t) ω(t)``.

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset

    Returns
    -------
    omega_space : ndarray, shape (T, 3)
        ``ω_s(t)`` in the space frame, rad/s.
    plane : ndarray, shape (T, 2)
        Its components along ``ê_1, ê_2`` of :func:`invariable_frame` (coordinates in the invariable plane),
        rad/s.
    height : ndarray, shape (T,)
        Its component along ``L̂``, rad/s: ``2T/|L|``, the same at every time (Poinsot).
    """
    trace = _trace(source)
    omega_space = np.einsum("tij,tj->ti", rotation_matrices(trace.quaternion), trace.omega)
    projected = omega_space @ invariable_frame(trace).T
    return omega_space, projected[:, :2], projected[:, 2]


def _spin_cosine(trace):
    """Cosine of the angle between the intermediate axis and ``L``: ``I_k ω_k / |L|`` in the body frame."""
    k = trace.intermediate_axis - 1
    momentum = trace.moments * trace.omega
    return momentum[:, k] / np.linalg.norm(momentum, axis=1)


def flip_times(source):
    """Times of the flips: when the intermediate axis lies in the invariable plane (its angle to ``L`` passes
    90°), s.

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset

    Returns
    -------
    ndarray, shape (F,)
        Linear interpolation between stored times.
    """
    trace = _trace(source)
    t, c = trace.time, _spin_cosine(trace)
    i = np.nonzero(c[:-1] * c[1:] < 0)[0]
    return t[i] - c[i] * (t[i + 1] - t[i]) / (c[i + 1] - c[i])


def snapshot_times(source, panels=8):
    """Times for a strip of snapshots: through the first flip when there is one, else evenly over the trace.

    Around the first flip the window runs from the last time before it where the intermediate axis is within
    about 11° of ``L`` (cosine 0.98), to the first time after it where it is within 11° of ``−L``, widened by a
    quarter on each side and clipped to the trace.

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset
    panels : int
        Number of snapshots, ≥ 2.

    Returns
    -------
    ndarray, shape (panels,)
        Times, s.
    """
    trace = _trace(source)
    t, c = trace.time, _spin_cosine(trace)
    flips = flip_times(trace)
    start, stop = t[0], t[-1]
    if len(flips):
        sign = np.sign(c[np.searchsorted(t, flips[0]) - 1]) or 1.0
        before = np.nonzero((t < flips[0]) & (sign * c > 0.98))[0]
        after = np.nonzero((t > flips[0]) & (sign * c < -0.98))[0]
        lo = t[before[-1]] if len(before) else t[0]
        hi = t[after[0]] if len(after) else t[-1]
        pad = 0.25 * (hi - lo)
        start, stop = max(t[0], lo - pad), min(t[-1], hi + pad)
    return np.linspace(start, stop, max(2, int(panels)))


def _nearest(t, times):
    """Indices of the stored times nearest to ``times``."""
    i = np.clip(np.searchsorted(t, times), 1, len(t) - 1)
    return np.where(np.abs(times - t[i - 1]) <= np.abs(t[i] - times), i - 1, i)


# ----------------------------------------------------------------------------------------------- the body


def box_proportions(moments):
    """Edges of the uniform box with principal moments ``moments``, scaled so the longest is 1.

    ``a_i = sqrt(6 (I_j + I_k − I_i) / M)`` inverts ``I_i = M (a_j² + a_k²) / 12``; the mass only scales
    the box. A flat lamina (``I_i = I_j + I_k``) has a zero edge (round-off negatives are clipped to 0).

    Parameters
    ----------
    moments : array_like, shape (3,)
        Principal moments, kg m².

    Returns
    -------
    ndarray, shape (3,)
        Edge along each principal axis, longest = 1.
    """
    moments = np.asarray(moments, dtype=float)
    if moments.shape != (3,) or not np.all(np.isfinite(moments)) or np.any(moments <= 0):
        raise ValueError(f"moments must be 3 positive numbers, got {moments!r}")
    edges = np.sqrt(np.clip(6.0 * (moments.sum() - 2.0 * moments), 0.0, None))
    return edges / edges.max()


@dataclass(frozen=True)
class _Solid:
    """Faces of the drawn body in its principal frame, scaled to fit the unit sphere."""

    faces: list            # ndarray (n_f, 3) per face, body frame
    normals: np.ndarray    # (F, 3) outward normals, body frame
    colors: np.ndarray     # (F, 4) base colours
    marker: np.ndarray     # (3,) body-frame unit vector along the intermediate axis, out of the red part
    reach: float           # distance from the centre to the body's surface along ``marker``
    what: str              # "box of equal moments" or the shape's name


def _box(moments, intermediate):
    half = 0.5 * np.maximum(box_proportions(moments), 0.03)
    half /= np.linalg.norm(half)
    faces, normals, colors = [], [], []
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        for sign in (1.0, -1.0):
            face = np.zeros((4, 3))
            face[:, i] = sign * half[i]
            face[:, j], face[:, k] = corners[:, 0] * half[j], corners[:, 1] * half[k]
            faces.append(face)
            normals.append(sign * np.eye(3)[i])
            colors.append(_INTERMEDIATE if (i == intermediate and sign > 0)
                          else _INTERMEDIATE_BACK if i == intermediate else _BODY)
    return _Solid(faces, np.array(normals), np.array([to_rgba(c) for c in colors]), np.eye(3)[intermediate],
                  float(half[intermediate]), "box of equal moments")


def _prism(centre, direction, radius, length, sides=_PRISM_SIDES):
    """Faces and outward normals of a ``sides``-gon prism approximating a cylinder."""
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    seed = np.eye(3)[np.argmin(np.abs(direction))]
    u = np.cross(direction, seed)
    u /= np.linalg.norm(u)
    v = np.cross(direction, u)
    angle = 2 * np.pi * np.arange(sides) / sides
    ring = radius * (np.cos(angle)[:, None] * u + np.sin(angle)[:, None] * v)
    bottom, top = centre - 0.5 * length * direction + ring, centre + 0.5 * length * direction + ring
    faces, normals = [], []
    for n in range(sides):
        m = (n + 1) % sides
        faces.append(np.array([bottom[n], bottom[m], top[m], top[n]]))
        middle = 0.5 * (angle[n] + angle[m]) + (np.pi if m == 0 else 0.0)
        normals.append(np.cos(middle) * u + np.sin(middle) * v)
    faces += [top, bottom[::-1]]
    normals += [direction, -direction]
    return faces, normals


def _t_handle(trace, intermediate):
    """The T-handle of :func:`tumble.physics.shapes.t_handle` in the trace's principal frame, or None when its moments
    are not the trace's (up to the order of the axes)."""
    params = {k: float(v) for k, v in trace.shape_params.items()}
    body = shapes.t_handle(**params)
    defaults = {name: p.default for name, p in inspect.signature(shapes.t_handle).parameters.items()}
    p = {**defaults, **params}
    lb, rb, ls, rs = p["bar_length"], p["bar_radius"], p["stem_length"], p["stem_radius"]
    # which principal axis of the shape is which axis of the trace: match the moments
    order = [int(np.argmin(np.abs(body.moments - m))) for m in trace.moments]
    if sorted(order) != [0, 1, 2] or not np.allclose(body.moments[order], trace.moments, rtol=1e-6):
        return None
    axes = body.axes[:, order]
    if np.linalg.det(axes) < 0:  # an odd reordering: flip one axis to stay right-handed
        axes[:, 0] = -axes[:, 0]
    vol_bar, vol_stem = rb**2 * lb, rs**2 * ls  # equal densities: masses in proportion to volumes (shapes.t_handle)
    centre = np.array([0.0, 0.0, -vol_stem * (rb + ls / 2) / (vol_bar + vol_stem)])
    bar_faces, bar_normals = _prism(np.zeros(3), (1, 0, 0), rb, lb)
    stem_faces, stem_normals = _prism(np.array([0.0, 0.0, -(rb + ls / 2)]), (0, 0, -1), rs, ls)
    to_body = axes.T
    faces = [(f - centre) @ to_body.T for f in bar_faces + stem_faces]
    normals = np.array(bar_normals + stem_normals) @ to_body.T
    stem = to_body @ np.array([0.0, 0.0, -1.0])
    along = int(np.argmax(np.abs(stem)))
    colors = [_BODY] * len(bar_faces) + [_INTERMEDIATE if along == intermediate else "#8c8c8c"] * len(stem_faces)
    points = np.concatenate(faces)
    scale = np.linalg.norm(points, axis=1).max()
    faces = [f / scale for f in faces]
    # the intermediate axis leaves the body through the stem's end when the stem lies along it
    marker = np.sign(stem[intermediate]) * np.eye(3)[intermediate] if along == intermediate else np.eye(3)[intermediate]
    reach = np.max(np.concatenate(faces) @ marker)
    return _Solid(faces, normals, np.array([to_rgba(c) for c in colors]), marker, float(reach), "T-handle")


def _solid(trace):
    intermediate = trace.intermediate_axis - 1
    if trace.body_shape in _DRAWN_SHAPES:
        try:
            solid = _t_handle(trace, intermediate)
        except (TypeError, ValueError) as err:
            warnings.warn(f"cannot build the {trace.body_shape!r} of the dataset ({err}); drawing the box of "
                          "equal moments", stacklevel=3)
            solid = None
        else:
            if solid is None:
                warnings.warn(f"the {trace.body_shape!r} of the dataset does not have the dataset's moments; "
                              "drawing the box of equal moments", stacklevel=3)
        if solid is not None:
            return solid
    return _box(trace.moments, intermediate)


class _BodyView:
    """The body, its intermediate axis and ``L`` in one 3-D axes, drawn in the invariable frame (``L`` up)."""

    def __init__(self, ax, trace, solid, frame):
        self.ax, self.solid, self.frame = ax, solid, frame
        self.rotations = rotation_matrices(trace.quaternion)
        ax.set_axis_off()
        ax.set_xlim(-1, 1)
        ax.set_ylim(-1, 1)
        ax.set_zlim(-1, 1.35)
        ax.set_box_aspect((1, 1, 1.175), zoom=1.25)
        ax.view_init(**_VIEW)
        self.poly = Poly3DCollection(solid.faces, edgecolors=(0, 0, 0, 0.35), linewidths=0.3)
        ax.add_collection3d(self.poly)
        self.axis_line = Line3DCollection([np.zeros((2, 3))], colors=[_INTERMEDIATE], linewidths=1.8)
        ax.add_collection3d(self.axis_line)
        ax.plot([0, 0], [0, 0], [1.02, 1.3], color=_L_COLOR, lw=1.4)
        ax.plot([0], [0], [1.3], color=_L_COLOR, marker="^", ms=5)
        ax.text(0.08, 0.0, 1.28, "L", fontsize=9, fontweight="bold")

    def show(self, index):
        """Pose the body as at stored time ``index``."""
        to_display = self.frame @ self.rotations[index]
        self.poly.set_verts([f @ to_display.T for f in self.solid.faces])
        normals = self.solid.normals @ to_display.T
        light = 0.5 + 0.5 * np.clip(normals @ _LIGHT, 0.0, 1.0)
        colors = self.solid.colors.copy()
        colors[:, :3] *= light[:, None]
        self.poly.set_facecolor(colors)
        axis, reach = to_display @ self.solid.marker, self.solid.reach
        self.axis_line.set_segments([np.array([reach * axis, (reach + 0.4) * axis])])
        return self.poly, self.axis_line


def _title(trace, sep=", "):
    parts = [f"{'T-handle' if trace.body_shape == 't_handle' else 'body'} spun about axis {trace.spin_axis}"
             if trace.spin_axis else "", trace.method, trace.label]
    return sep.join(p for p in parts if p)


def _key(solid, trace):
    k = trace.intermediate_axis
    return [Line2D([], [], color=_INTERMEDIATE, lw=1.8,
                   label=f"intermediate axis {k} ($I_{k}$ = {trace.moments[k - 1]:.3g} kg m²)"),
            Line2D([], [], color=_L_COLOR, lw=1.4, marker="^", ms=4, label="$\\mathbf{L}$, fixed in space"),
            Patch(facecolor=_BODY, edgecolor="0.4", lw=0.3, label=solid.what)]


# ---------------------------------------------------------------------------------------------- animation


class FlipAnimation(animation.FuncAnimation):
    """The body turning in the invariable frame, one stored time per frame.

    A :class:`matplotlib.animation.FuncAnimation` on a pyplot-free figure; write it with
    :func:`save_animation` (or ``.save``, ``.to_jshtml()`` in a notebook) at the figure's own dpi: its fixed text
    is one pixel image, laid out for that resolution.

    Attributes
    ----------
    figure : matplotlib.figure.Figure
    frame_times : ndarray, shape (frames,)
        Stored times shown, s.
    fps : float
        Frames per second it is written at.
    """

    def __init__(self, fig, view, indices, time, fps, clock):
        self.figure, self.frame_times, self.fps = fig, time[indices], fps
        self._view, self._time, self._clock = view, time, clock
        self._frame(indices[0])
        super().__init__(fig, self._frame, frames=[int(i) for i in indices], interval=1000.0 / fps, blit=False,
                         cache_frame_data=False)
        # posed at its first frame already; and with no pyplot window behind it, matplotlib's "deleted without
        # rendering" warning (meant for plt.show) would only be noise
        self._draw_was_started = True

    def _frame(self, index):
        artists = self._view.show(index)
        self._clock.set_text(f"t = {self._time[index]:6.2f} s")  # plain text: mathtext costs a parse per frame
        return (*artists, self._clock)


def flip_animation(source, *, frames=None, fps=None, dpi=None):
    """An animation of the body turning in space, ``L`` up, the intermediate axis red.

    Frames show the stored times nearest to ``frames`` evenly spaced times over the trace (all of them when
    there are fewer). Small (2.8 × 3 in at 80 dpi) so that 160 frames render in seconds: the text that does not
    change is drawn once, into an image laid over every frame.

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset
    frames : int, optional
        Most frames, ≥ 2; :data:`FRAMES` by default.
    fps : float, optional
        Frames per second; :data:`FPS` by default.
    dpi : float, optional
        Resolution, dots per inch (the animation is written at it); :data:`ANIMATION_DPI` by default.

    Returns
    -------
    FlipAnimation
    """
    trace = _trace(source)
    frames, fps, dpi = (FRAMES if frames is None else frames, FPS if fps is None else fps,
                        ANIMATION_DPI if dpi is None else dpi)
    if frames < 2 or not fps > 0 or not dpi > 0:
        raise ValueError(f"an animation needs frames >= 2, fps > 0 and dpi > 0, got {frames}, {fps} and {dpi}")
    indices = np.unique(_nearest(trace.time, np.linspace(trace.time[0], trace.time[-1], int(frames))))
    solid = _solid(trace)
    fig = Figure(figsize=ANIMATION_SIZE, dpi=dpi)
    ax = fig.add_axes((0.0, 0.1, 1.0, 0.8), projection="3d")
    view = _BodyView(ax, trace, solid, invariable_frame(trace))
    k = trace.intermediate_axis
    title = _title(trace, "\n")
    _freeze_text(fig, [fig.text(0.03, 0.97, title, fontsize=7, va="top", linespacing=1.1),
                       fig.text(0.03, 0.02, f"red: intermediate axis {k}\nL (up): fixed in space", fontsize=7),
                       *ax.texts])
    clock = fig.text(0.03, 0.97 - 0.04 * (title.count("\n") + 1), "", fontsize=8, va="top")
    return FlipAnimation(fig, view, indices, trace.time, fps, clock)


def _freeze_text(fig, texts):
    """Replace ``texts`` by one image of them laid over the figure: Agg takes milliseconds per line of text, an
    image costs one blend per frame. Exact when the figure is rendered at its own dpi."""
    canvas = FigureCanvasAgg(fig)
    others = [a for a in fig.get_children() if a not in texts and a is not fig.patch and a not in fig.axes]
    others += [a for ax in fig.axes for a in ax.get_children() if a not in texts]
    others = [a for a in others if a.get_visible()]
    for artist in others:
        artist.set_visible(False)
    fig.patch.set_alpha(0.0)
    canvas.draw()
    overlay = np.asarray(canvas.buffer_rgba()).copy()
    for artist in others:
        artist.set_visible(True)
    for text in texts:
        text.set_visible(False)
    fig.patch.set_alpha(1.0)
    fig.figimage(overlay, origin="upper", zorder=10)
    FigureCanvasBase(fig)  # back to a canvas whose draw_idle is a no-op: the animation's writer renders each frame


def animation_format():
    """The movie format :func:`save_animation` writes: "mp4" when matplotlib finds ffmpeg, else "gif"."""
    return "mp4" if animation.writers.is_available("ffmpeg") else "gif"


class _GifWriter(animation.PillowWriter):
    """Pillow's GIF writer with one palette for all frames, taken from a sample of them: quicker than Pillow's
    palette per frame, no colour flicker, and smaller files (unchanged pixels stay unchanged)."""

    def finish(self):
        if not self._frames:  # a frame failed (matplotlib calls finish on the way out): let its error through
            return
        frames = [f.convert("RGB") for f in self._frames]
        sample = frames[:: max(1, len(frames) // 8)]
        width, height = sample[0].size
        mosaic = Image.new("RGB", (width, height * len(sample)))
        for n, frame in enumerate(sample):
            mosaic.paste(frame, (0, n * height))
        palette = mosaic.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
        frames[0].save(self.outfile, save_all=True, append_images=frames[1:], duration=round(1000 / self.fps),
                       loop=0)


def _writer(fmt, fps):
    if fmt == "mp4":
        return animation.FFMpegWriter(fps=fps, codec="h264", extra_args=["-pix_fmt", "yuv420p"])
    return _GifWriter(fps=fps)


def save_animation(anim, path):
    """Write ``anim`` to ``path`` at its figure's dpi, atomically: into a temporary file beside it, then renamed
    onto it.

    Parameters
    ----------
    anim : FlipAnimation
    path : path-like
        Ends in ".gif" (Pillow) or ".mp4" (ffmpeg, H.264).

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    if fmt not in ("gif", "mp4"):
        raise ValueError(f"an animation is written as .gif or .mp4, got {path.name!r}")
    # the temporary file keeps the extension: Pillow and ffmpeg pick the container from it
    with io.replaced_atomically(path, suffix=f".part.{fmt}") as tmp:
        anim.save(tmp, writer=_writer(fmt, anim.fps), dpi=anim.figure.dpi)
    return path


# ------------------------------------------------------------------------------------------ snapshot strip


def flip_strip(source, *, panels=8, width=_DOUBLE):
    """A row of snapshots of the body through its first flip (:func:`snapshot_times`), ``L`` up, the
    intermediate axis red; each panel names its time and the angle between that axis and ``L``.

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset
    panels : int
        Number of snapshots.
    width : float
        Figure width, inches.

    Returns
    -------
    matplotlib.figure.Figure
    """
    trace = _trace(source)
    indices = _nearest(trace.time, snapshot_times(trace, panels))
    solid, frame = _solid(trace), invariable_frame(trace)
    # the angle of the drawn (red) half of the intermediate axis to L: for the T-handle the stem's side
    momentum = trace.moments * trace.omega
    cosine = momentum @ solid.marker / np.linalg.norm(momentum, axis=1)
    angle = np.degrees(np.arccos(np.clip(cosine, -1, 1)))
    height = width / len(indices) * 1.25 + 0.75
    fig = Figure(figsize=(width, height))
    step = 1.0 / len(indices)
    bottom, top = 0.42 / height, 1 - 0.3 / height
    for n, index in enumerate(indices):
        ax = fig.add_axes((n * step, bottom, step, top - bottom), projection="3d")
        _BodyView(ax, trace, solid, frame).show(index)
        fig.text((n + 0.5) * step, bottom, f"$t$ = {trace.time[index]:.3g} s\n"
                 f"$\\theta_{trace.intermediate_axis}$ = {angle[index]:.0f}°", ha="center", va="top", fontsize=7)
    title = _title(trace)
    flips = flip_times(trace)
    if len(flips):
        title += f"; first flip at {flips[0]:.3g} s"
    fig.text(0.5, 1 - 0.04 / height, title, ha="center", va="top", fontsize=8)
    key = _key(solid, trace)
    key[0].set_label(key[0].get_label() + f", at angle $\\theta_{trace.intermediate_axis}$ to $\\mathbf{{L}}$")
    fig.legend(handles=key, loc="lower center", ncols=3, fontsize=7, frameon=False, borderaxespad=0.1)
    return fig


# ------------------------------------------------------------------------------------ polhode / herpolhode


def _energy(trace):
    """Median kinetic energy ``½ Σ I ω²`` and median ``|L|²`` over the trace."""
    energy = 0.5 * np.sum(trace.moments * trace.omega**2, axis=1)
    momentum2 = np.sum((trace.moments * trace.omega) ** 2, axis=1)
    return float(np.median(energy)), float(np.median(momentum2))


def _polhodes(moments, energy, ratios, points=181):
    """Closed polhodes on the energy ellipsoid ``Σ I ω² = 2T`` for ``D = |L|²/2T`` at ``ratios`` between the
    smallest and largest moments; each D gives two curves (shape (points, 3), rad/s) around its axis.

    With moments sorted ``A < B < C``: for ``D < B`` the curve circles the A axis, ``B(B−A) ω_B² +
    C(C−A) ω_C² = 2T (D − A)``, an ellipse parametrised by angle, ``ω_A = ±sqrt((2T − B ω_B² − C ω_C²)/A)``;
    for ``D > B`` likewise about the C axis. ``D = B`` is the separatrix."""
    order = np.argsort(moments)
    a, b, c = moments[order]
    phi = np.linspace(0, 2 * np.pi, points)
    curves = []
    for ratio in ratios:
        d = a + ratio * (c - a)
        if d <= b:  # about the smallest axis
            (i, j, k), (ia, ij, ik) = (0, 1, 2), (a, b, c)
        else:
            (i, j, k), (ia, ij, ik) = (2, 1, 0), (c, b, a)
        sj = math.sqrt(2 * energy * (d - ia) / (ij * (ij - ia)))
        sk = math.sqrt(2 * energy * (d - ia) / (ik * (ik - ia)))
        wj, wk = sj * np.cos(phi), sk * np.sin(phi)
        wi = np.sqrt(np.clip((2 * energy - ij * wj**2 - ik * wk**2) / ia, 0.0, None))
        for sign in (1.0, -1.0):
            sorted_w = np.empty((points, 3))
            sorted_w[:, i], sorted_w[:, j], sorted_w[:, k] = sign * wi, wj, wk
            curve = np.empty_like(sorted_w)
            curve[:, order] = sorted_w
            curves.append(curve)
    return curves


def polhode(source, *, width=_SINGLE):
    """The polhode: ``ω(t)`` in the body frame on its energy ellipsoid (light wireframe), with the family of
    closed polhodes at the same energy (grey) and the separatrix through the intermediate axis (dashed).

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset
    width : float
        Figure width, inches.

    Returns
    -------
    matplotlib.figure.Figure
    """
    trace = _trace(source)
    energy, momentum2 = _energy(trace)
    semi = np.sqrt(2 * energy / trace.moments)
    height = width * 0.8 + 0.45
    fig = Figure(figsize=(width, height))
    ax = fig.add_axes((0.0, 0.45 / height, 0.9, 1 - 0.85 / height), projection="3d")
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
    ax.plot_wireframe(semi[0] * np.cos(u) * np.sin(v), semi[1] * np.sin(u) * np.sin(v), semi[2] * np.cos(v),
                      color="0.75", lw=0.3)
    distinct = np.all(np.abs(np.diff(np.sort(trace.moments))) > 1e-9 * trace.moments.max())
    handles = []
    if distinct:
        a, b, c = np.sort(trace.moments)
        separatrix = (b - a) / (c - a)
        ratios = [r for r in (0.08, 0.3, 0.6, 0.85, 0.96) if abs(r - separatrix) > 0.06]
        for curve in _polhodes(trace.moments, energy, ratios):
            ax.plot(*curve.T, color="0.55", lw=0.5)
        for curve in _polhodes(trace.moments, energy, [separatrix]):
            ax.plot(*curve.T, color="k", lw=0.7, ls="--")
        handles += [Line2D([], [], color="0.55", lw=0.5, label="polhodes at the same energy"),
                    Line2D([], [], color="k", lw=0.7, ls="--", label="separatrix")]
    handles.insert(0, ax.plot(*trace.omega.T, color=_INTERMEDIATE, lw=1.2, label="$\\omega(t)$ of the trace")[0])
    ax.plot(*trace.omega[0], color=_INTERMEDIATE, marker="o", ms=3.5, ls="none")
    for setter, extent in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), 1.04 * semi):
        setter(-extent, extent)
    ax.set_box_aspect(semi, zoom=1.1)  # the ellipsoid's true shape
    ax.view_init(elev=22, azim=-50)
    for n, setter in enumerate((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), start=1):
        setter(f"$\\omega_{n}$ (rad/s)", labelpad=-7, fontsize=8)
    ax.tick_params(labelsize=6, pad=-3)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_pane_color((1, 1, 1, 0))
        axis.set_major_locator(MaxNLocator(4, symmetric=True))
    ax.grid(False)
    fig.text(0.5, 1 - 0.05 / height, f"polhode on the energy ellipsoid (body frame)\n$T$ = {energy:.3g} J, "
             f"$|L|^2/2T$ = {momentum2 / (2 * energy):.3g} kg m²", ha="center", va="top", fontsize=8)
    fig.legend(handles=handles, loc="lower center", ncols=2, fontsize=7, frameon=False, borderaxespad=0.2)
    return fig


def herpolhode(source, *, width=_SINGLE):
    """The herpolhode: the tip of the space-frame ``ω`` in the invariable plane, with the circles bounding it
    and the point where ``L`` pierces the plane (+).

    Parameters
    ----------
    source : AttitudeTrace or xarray.Dataset
    width : float
        Figure width, inches.

    Returns
    -------
    matplotlib.figure.Figure
    """
    trace = _trace(source)
    _, plane, height = herpolhode_points(trace)
    fig = Figure(figsize=(width, width * 0.92 + 0.4))
    ax = fig.subplots()
    radius = np.hypot(*plane.T)
    circle = np.linspace(0, 2 * np.pi, 241)
    for r in (radius.min(), radius.max()):
        ax.plot(r * np.cos(circle), r * np.sin(circle), color="0.7", lw=0.5, ls=":")
    curve, = ax.plot(*plane.T, color=_INTERMEDIATE, lw=0.7, label="tip of $\\omega$")
    ax.plot(*plane[0], color=_INTERMEDIATE, marker="o", ms=3.5, ls="none")
    ax.plot([0], [0], color="k", marker="+", ms=8, ls="none")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("$\\omega \\cdot \\hat e_1$ (rad/s)")
    ax.set_ylabel("$\\omega \\cdot \\hat e_2$ (rad/s)")
    ax.set_title(f"herpolhode in the invariable plane (space frame)\n$\\omega \\cdot \\hat L$ = 2T/|L| = "
                 f"{np.median(height):.4g} rad/s", fontsize=8)
    handles = [curve, Line2D([], [], color="k", marker="+", ms=8, ls="none", label="$\\mathbf{L}$ (normal)"),
               Line2D([], [], color="0.7", lw=0.5, ls=":", label="bounding circles")]
    layout.legend(fig, handles, "below", ncols=3, fontsize=7, frameon=False, columnspacing=1.0, handlelength=1.5)
    return layout.fit(fig)

