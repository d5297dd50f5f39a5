"""Hold another simulator's free rigid-body trajectory against the exact torque-free solution.

:func:`check` takes a recorded trajectory (times, body-frame or world-frame angular velocity and/or the
body-to-world attitude quaternion) and the body (principal moments, or an inertia tensor in the recording's
body frame), starts the exact solution (:mod:`tumble.physics.exact`: Landau & Lifshitz §37 for the angular
velocity, §35 and §37 for the attitude) from the recording's first state, evaluates it at the recording's
times and measures, over time:

* ``omega_error``: ``|w - w_exact| / |w_exact|``, body (principal) frame;
* ``attitude_error``: the angle of the rotation between the recorded and the exact attitude, rad;
* ``energy_drift`` and ``momentum_drift``: ``E / E0 - 1`` and ``|L| / |L0| - 1``;
* ``momentum_direction``: the angle between the space-frame angular momentum and its first value, rad;
* the flips: sign changes of the intermediate-axis component (counted with a hysteresis of half that
  component's exact amplitude, so round-off about a steady spin is no flip), each measured flip time against
  the exact one (found the same way in the exact motion at the same times), and the mean measured flip
  spacing against the exact ``2K / nu``.

Each criterion of :data:`DEFAULT_TOLERANCES` gives a verdict; known failure patterns are named
(:data:`DIAGNOSES`). The arrays come in already validated by :func:`validate_trajectory`, which names the
column and row of what is wrong; reading files is :mod:`tumble.output.trajectory`'s job.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import xarray as xr

from .. import registry
from ..physics import exact, rotations
from ..physics.bodies import Body

__all__ = ["DEFAULT_TOLERANCES", "DIAGNOSES", "QUATERNION_NORM_TOLERANCE", "check", "resolve_tolerances", "summary",
           "validate_trajectory"]

#: Criterion -> default threshold (:data:`tumble.registry.CHECK_TOLERANCES`).
DEFAULT_TOLERANCES = dict(registry.CHECK_TOLERANCES)

#: Criterion -> (long name, units) for the dataset and the summary.
CRITERIA = {
    "omega_error": ("max relative angular velocity error |w - w_exact| / |w_exact|", "1"),
    "attitude_error": ("max attitude error angle", "rad"),
    "energy_drift": ("max |E / E0 - 1|", "1"),
    "momentum_drift": ("max ||L| / |L0| - 1|", "1"),
    "momentum_direction": ("max angle of the space-frame angular momentum from its first direction", "rad"),
    "period_error": ("|measured flip spacing / exact flip spacing 2K/nu - 1|", "1"),
    "flip_count": ("|measured flips - exact flips|", "1"),
}

#: Failure pattern -> what it usually means.
DIAGNOSES = {
    "no_flip": "no flip about the intermediate axis where the exact motion flips: the gyroscopic term w x (I w) "
               "is missing",
    "energy_decay": "the kinetic energy decays: numerical damping (e.g. an implicit gyroscopic step)",
    "energy_growth": "the kinetic energy grows: an explicit (forward Euler) step",
    "momentum_drift": "the angular momentum drifts (|L| or its direction in space): numerical damping or an "
                      "integrator that does not conserve it",
    "period_error": "the flip period is off by {percent:+.2f}%: the step is too long for the spin rate",
}

#: Largest accepted ``| |q| - 1 |`` of a recorded quaternion (it is then normalised).
QUATERNION_NORM_TOLERANCE = 1e-6

_OMEGA_FRAMES = ("body", "world")
_QUATERNION_ORDERS = ("wxyz", "xyzw")
_DEFAULT_LABELS = {"t": "t", "omega": "omega", "quaternion": "quaternion"}


def _first_bad_row(mask):
    return int(np.argmax(mask)) + 1


def _column_array(value, label, width):
    """``value`` as a finite float64 array of shape (N,) (width None) or (N, width); errors name ``label``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{label}: not numbers") from None
    shape = "(N,)" if width is None else f"(N, {width})"
    if (arr.ndim != 1) if width is None else (arr.ndim != 2 or arr.shape[1] != width):
        raise ValueError(f"{label}: must have shape {shape}, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        row, col = np.argwhere(bad)[0] if arr.ndim == 2 else (np.argmax(bad), None)
        where = label if col is None else f"{label} column {col + 1}"
        raise ValueError(f"{where}, row {row + 1}: {float(arr[tuple(np.argwhere(bad)[0])])} (every value must be finite)")
    return arr


def validate_trajectory(t, omega=None, quaternion=None, *, labels=None):
    """Check a recorded trajectory's arrays; return them as float64 arrays.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s: finite, strictly increasing, at least two.
    omega : array_like, shape (N, 3), optional
        Angular velocity, rad/s, finite.
    quaternion : array_like, shape (N, 4), optional
        Attitude quaternions, finite and of unit length within :data:`QUATERNION_NORM_TOLERANCE`.
    labels : mapping, optional
        How messages name ``t``, ``omega`` and ``quaternion`` (e.g. the file's column names).

    Returns
    -------
    (t, omega, quaternion) : ndarrays (None where not given)

    Raises
    ------
    ValueError
        One line naming the array (or column) and the 1-based row: not finite, times not increasing, a
        non-unit quaternion, lengths that differ, neither ``omega`` nor ``quaternion``.
    """
    labels = {**_DEFAULT_LABELS, **(labels or {})}
    if omega is None and quaternion is None:
        raise ValueError(f"give the angular velocity ({labels['omega']}) or the attitude ({labels['quaternion']}) "
                         "or both; the trajectory has neither")
    t = _column_array(t, labels["t"], None)
    if t.size < 2:
        raise ValueError(f"{labels['t']}: {t.size} sample(s); a trajectory needs at least two")
    steps = np.diff(t)
    if (steps <= 0).any():
        row = _first_bad_row(steps <= 0) + 1
        raise ValueError(f"{labels['t']}, row {row}: times not increasing ({float(t[row - 2])!r} then {float(t[row - 1])!r})")
    arrays = []
    for key, width in (("omega", 3), ("quaternion", 4)):
        value = omega if key == "omega" else quaternion
        if value is not None:
            value = _column_array(value, labels[key], width)
            if value.shape[0] != t.size:
                raise ValueError(f"{labels[key]}: {value.shape[0]} rows, but {labels['t']} has {t.size}")
        arrays.append(value)
    omega, quaternion = arrays
    if quaternion is not None:
        off = np.abs(np.linalg.norm(quaternion, axis=1) - 1.0)
        if (off > QUATERNION_NORM_TOLERANCE).any():
            row = _first_bad_row(off > QUATERNION_NORM_TOLERANCE)
            raise ValueError(f"{labels['quaternion']}, row {row}: |q| = {float(np.linalg.norm(quaternion[row - 1]))!r} is "
                             f"not a unit quaternion (tolerance {QUATERNION_NORM_TOLERANCE:g})")
    return t, omega, quaternion


def resolve_tolerances(tolerances):
    """The thresholds: the defaults updated by ``tolerances``; ValueError naming an unknown or invalid one."""
    merged = dict(DEFAULT_TOLERANCES)
    if tolerances is None:
        return merged
    if not isinstance(tolerances, Mapping):
        raise ValueError(f"tolerances must be a mapping of criterion name to threshold, got "
                         f"{type(tolerances).__name__}")
    for name, value in tolerances.items():
        if name not in DEFAULT_TOLERANCES:
            raise ValueError(f"tolerance {name!r}: unknown criterion (criteria: {', '.join(DEFAULT_TOLERANCES)})")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not math.isfinite(value) or value < 0:
            raise ValueError(f"tolerance {name!r}: must be a finite number >= 0, got {value!r}")
        if name == "flip_count" and float(value) != int(value):
            raise ValueError(f"tolerance 'flip_count': must be a whole number of flips, got {value!r}")
        merged[name] = float(value)
    return merged


def _body(moments, inertia):
    """(moments (3,), rotation quaternion taking principal to recording body coordinates or None, axes or None)."""
    if (moments is None) == (inertia is None):
        raise ValueError("give the body as moments (three principal moments, kg m²) or inertia (a 3x3 tensor in the "
                         "trajectory's body frame), exactly one of them")
    if moments is not None:
        values = np.asarray(moments, dtype=float)
        if values.shape != (3,):
            raise ValueError(f"moments must be three principal moments (kg m²), got shape {values.shape}")
        return Body(*values).moments, None, None
    from scipy.spatial.transform import Rotation

    body = Body.from_tensor(inertia)
    axes = body.axes  # columns: principal axes in the recording's body frame, right-handed
    return body.moments, Rotation.from_matrix(axes).as_quat(scalar_first=True), axes


def _continuous(q):
    """``q`` with signs chosen so that neighbouring quaternions are on the same side (``q ≡ -q``)."""
    flips = np.cumprod(np.where(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0, -1.0, 1.0))
    return q * np.concatenate([[1.0], flips])[:, None]


def _omega_from_attitude(t, q):
    """Body-frame angular velocity ``2 vec(q* ⊗ q')`` with ``q'`` by second-order finite differences."""
    q = _continuous(q)
    dq = np.gradient(q, t, axis=0, edge_order=2)
    return 2.0 * rotations.product(rotations.conjugate(q), dq)[:, 1:]


def _flips(t, w_mid, band):
    """Times of the sign changes of ``w_mid`` that go from beyond ``+band`` to beyond ``-band`` or back: each the
    linear interpolation of the first zero crossing after the component left its side."""
    side = np.where(w_mid > band, 1, np.where(w_mid < -band, -1, 0))
    armed = np.flatnonzero(side)
    change = np.flatnonzero(np.diff(side[armed]) != 0)
    if change.size == 0:
        return np.empty(0)
    start = armed[change]
    sign = np.sign(w_mid)
    crossings = np.flatnonzero(sign[:-1] * sign[1:] <= 0)  # between j and j + 1
    j = crossings[np.searchsorted(crossings, start)]
    a, b = w_mid[j], w_mid[j + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(a != b, a / (a - b), 0.0)
    return t[j] + fraction * (t[j + 1] - t[j])


def check(t, omega=None, quaternion=None, *, moments=None, inertia=None, omega_frame="body", quaternion_order="wxyz",
          tolerances=None):
    """Compare a recorded free rigid-body trajectory with the exact torque-free solution from its first state.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s, strictly increasing.
    omega : array_like, shape (N, 3), optional
        Angular velocity, rad/s, in the frame ``omega_frame``. Without it, it is derived from ``quaternion``
        (``w = 2 vec(q* ⊗ q')``, ``q'`` by second-order finite differences: an error of order ``(w dt)²``).
    quaternion : array_like, shape (N, 4), optional
        Body-to-world attitude (``v_world = q v_body q*``), unit quaternions in the order ``quaternion_order``.
    moments : array_like, shape (3,), optional
        Principal moments, kg m², along the trajectory's body axes x, y, z (any order of size).
    inertia : array_like, shape (3, 3), optional
        Instead of ``moments``: the inertia tensor in the trajectory's body frame, kg m²; the principal axes
        are found (:meth:`tumble.Body.from_tensor`) and the data rotated onto them.
    omega_frame : {"body", "world"}
        Frame of ``omega``; ``"world"`` needs ``quaternion``.
    quaternion_order : {"wxyz", "xyzw"}
        Scalar first (tumble, MuJoCo) or scalar last (PyBullet, scipy).
    tolerances : mapping, optional
        Criterion -> threshold overriding :data:`DEFAULT_TOLERANCES`.

    Returns
    -------
    xarray.Dataset
        Over ``time`` (s, from the first sample): ``omega`` and ``omega_exact`` (principal body frame, rad/s),
        ``omega_error``, ``energy_drift``, ``momentum_drift`` and, with the attitude, ``attitude_error`` and
        ``momentum_direction`` (rad); ``flip_time`` (measured) and ``flip_time_exact``, s; per ``criterion``:
        ``value``, ``tolerance``, ``passed``. Attributes: ``verdict`` (``"pass"``/``"fail"``), ``diagnosis``
        (comma-separated names of :data:`DIAGNOSES`, empty when none), ``not_checked``, ``moments``,
        ``flip_spacing_exact``, ``flip_spacing``, ``omega_frame``.

    Raises
    ------
    ValueError
        Invalid arrays (:func:`validate_trajectory`), body, option or tolerance; a zero initial spin.

    See Also
    --------
    tumble.exact.omega : The exact solution it compares with.
    tumble.rotations.angle_between : The attitude error.

    Examples
    --------
    The exact solution passes; a trajectory that loses energy fails and says how:

    >>> import numpy as np, tumble
    >>> body, t = tumble.Body(1.0, 2.0, 3.0), np.linspace(0.0, 20.0, 201)
    >>> w = tumble.exact.omega(body, [0.01, 1.0, 0.0], t)
    >>> ds = tumble.check(t, w, moments=body.moments)
    >>> ds.attrs["verdict"], ds.attrs["diagnosis"]
    ('pass', '')
    >>> bad = tumble.check(t, w * np.exp(-0.01 * t)[:, None], moments=body.moments)
    >>> bad.attrs["verdict"], "energy_decay" in bad.attrs["diagnosis"]
    ('fail', True)
    """
    thresholds = resolve_tolerances(tolerances)
    t, moments, omega, quaternion, recording = _on_principal_axes(t, omega, quaternion, moments, inertia, omega_frame,
                                                                 quaternion_order)
    w0 = omega[0]
    tau = t - t[0]
    exact.compile_kernels_side_by_side("grid", attitude=quaternion is not None,  # a cold cache: two processes
                                       regimes=exact.regimes_to_compile(moments, w0))
    w_exact = exact.omega(moments, w0, tau)
    series = _drifts(moments, omega, quaternion, w_exact, tau)
    flips = _flip_record(moments, tau, omega, w_exact)
    values, passed, not_checked = _criteria(series, flips, thresholds)
    names = list(values)
    criteria = {
        "value": xr.DataArray([values[n] for n in names], dims="criterion",
                              attrs={"long_name": "measured value of each criterion", "units": "1 or rad (see "
                                     "criterion_units)"}),
        "tolerance": xr.DataArray([thresholds[n] for n in names], dims="criterion",
                                  attrs={"long_name": "threshold: the criterion passes when value <= tolerance",
                                         "units": "as value"}),
        "passed": xr.DataArray(np.array([passed[n] for n in names], dtype=np.int8), dims="criterion",
                               attrs={"long_name": "1 where the criterion passes, 0 where it fails", "units": "1"}),
        "criterion_units": xr.DataArray(np.array([CRITERIA[n][1] for n in names]), dims="criterion",
                                        attrs={"long_name": "units of value and tolerance"}),
    }
    over_time = {
        "omega": (("time", "axis"), omega, "angular velocity of the trajectory, principal body frame", "rad/s"),
        "omega_exact": (("time", "axis"), w_exact, "exact torque-free angular velocity from the first state, "
                        "principal body frame", "rad/s"),
        **{name: ("time", series.get(name), long_name, units) for name, (long_name, units) in _SERIES.items()},
        "flip_time": ("flip", flips["measured"], "measured flips: sign changes of the intermediate-axis angular "
                      "velocity, from the first sample", "s"),
        "flip_time_exact": ("flip_exact", flips["exact"], "exact flips at the same times, from the first sample", "s"),
    }
    variables = {name: xr.DataArray(data, dims=dims, attrs={"long_name": long_name, "units": units})
                 for name, (dims, data, long_name, units) in over_time.items() if data is not None}
    return xr.Dataset(
        {**variables, **criteria},
        coords={"time": ("time", tau, {"long_name": "time from the first sample", "units": "s"}),
                "axis": ("axis", np.arange(1, 4), {"long_name": "principal axis (1-based)", "units": "1"}),
                "criterion": ("criterion", np.array(names), {"long_name": "criterion"})},
        attrs={
            "title": "tumble check: a trajectory against the exact torque-free solution",
            "verdict": "pass" if all(passed.values()) else "fail",
            "diagnosis": ",".join(_diagnosis(series, values, passed, flips)),
            "not_checked": ",".join(not_checked),
            "moments": moments,
            **recording,
            "omega_frame": omega_frame,
            "quaternion_order": quaternion_order if quaternion is not None else "",
            "start_time": float(t[0]),
            "intermediate_axis": flips["axis"] + 1,
            "flip_spacing_exact": flips["spacing_exact"],
            "flip_spacing": flips["spacing"],
        })


#: Variables over time besides the angular velocities: name -> (long name, units).
_SERIES = {
    "omega_error": ("|w - w_exact| / |w_exact|", "1"),
    "energy_drift": ("kinetic energy relative to the first sample, E / E0 - 1", "1"),
    "momentum_drift": ("|L| relative to the first sample, |L| / |L0| - 1", "1"),
    "attitude_error": ("angle of the rotation from the exact attitude to the trajectory's", "rad"),
    "momentum_direction": ("angle of the space-frame angular momentum from its first direction", "rad"),
}


def _on_principal_axes(t, omega, quaternion, moments, inertia, omega_frame, quaternion_order):
    """Validated arrays with the angular velocity in the body frame and everything turned onto the principal axes:
    ``(t, principal moments, omega, quaternion or None, attributes saying how)``."""
    if omega_frame not in _OMEGA_FRAMES:
        raise ValueError(f"omega_frame must be one of {', '.join(_OMEGA_FRAMES)}, got {omega_frame!r}")
    if quaternion_order not in _QUATERNION_ORDERS:
        raise ValueError(f"quaternion_order must be one of {', '.join(_QUATERNION_ORDERS)}, got {quaternion_order!r}")
    if omega_frame == "world" and quaternion is None and omega is not None:
        raise ValueError("omega_frame 'world' needs the attitude quaternion to turn the angular velocity into the "
                         "body frame")
    principal_moments, to_recording, axes = _body(moments, inertia)
    t, omega, quaternion = validate_trajectory(t, omega, quaternion)
    if quaternion is not None:
        if quaternion_order == "xyzw":
            quaternion = quaternion[:, [3, 0, 1, 2]]
        quaternion = quaternion / np.linalg.norm(quaternion, axis=1, keepdims=True)
    if omega is None:
        omega = _omega_from_attitude(t, quaternion)
        source = "derived from the attitude quaternion"
    elif omega_frame == "world":
        omega = rotations.rotate(rotations.conjugate(quaternion), omega)
        source = "recorded in the world frame, turned into the body frame"
    else:
        source = "recorded in the body frame"
    if to_recording is not None:  # onto the principal axes
        omega = omega @ axes
        if quaternion is not None:
            quaternion = rotations.product(quaternion, to_recording)
    if not np.any(omega[0]):
        raise ValueError("the first angular velocity is zero: a body at rest has no motion to check")
    recording = {"principal_axes": axes.tolist() if axes is not None else "the trajectory's body axes",
                 "omega_source": source}
    return t, principal_moments, omega, quaternion, recording


def _drifts(moments, omega, quaternion, w_exact, tau):
    """The series over time of :data:`_SERIES` (the attitude's only with ``quaternion``)."""
    momentum = moments * omega
    energy = 0.5 * np.einsum("ij,ij->i", momentum, omega)
    size = np.linalg.norm(momentum, axis=1)
    series = {"omega_error": np.linalg.norm(omega - w_exact, axis=1) / np.linalg.norm(w_exact, axis=1),
              "energy_drift": energy / energy[0] - 1.0, "momentum_drift": size / size[0] - 1.0}
    if quaternion is not None:
        q_exact = rotations.product(quaternion[0], exact.attitude(moments, omega[0], tau))
        series["attitude_error"] = rotations.angle_between(quaternion, q_exact)
        space = rotations.rotate(quaternion, momentum)
        series["momentum_direction"] = np.arctan2(np.linalg.norm(np.cross(space, space[0]), axis=1), space @ space[0])
    return series


def _flip_record(moments, tau, omega, w_exact):
    """The flips about the intermediate axis, measured and exact (:func:`_flips`), and their spacings."""
    params = exact.parameters(moments, omega[0])
    mid = int(params.mid_axis)
    band = 0.5 * float(params.amplitude[mid]) + 1e-9 * float(np.linalg.norm(omega[0]))
    measured = _flips(tau, omega[:, mid], band)
    return {"axis": mid, "measured": measured, "exact": _flips(tau, w_exact[:, mid], band),
            "spacing": float(np.diff(measured).mean()) if measured.size >= 2 else math.inf,
            "spacing_exact": float(exact.flip_spacing(moments, omega[0]))}


def _criteria(series, flips, thresholds):
    """``(values, passed, not_checked)``: each criterion's value and verdict, and the criteria the data cannot give."""
    values = {name: float(np.max(np.abs(series[name]))) for name in
              ("omega_error", "attitude_error", "energy_drift", "momentum_drift", "momentum_direction")
              if name in series}
    not_checked = [name for name in ("attitude_error", "momentum_direction") if name not in series]
    measured, expected = flips["measured"].size, flips["exact"].size
    if expected >= 2 and math.isfinite(flips["spacing_exact"]):
        spacing = flips["spacing"]
        values["period_error"] = abs(spacing / flips["spacing_exact"] - 1.0) if math.isfinite(spacing) else math.inf
    else:
        not_checked.append("period_error")
    values["flip_count"] = float(abs(measured - expected))
    passed = {name: value <= thresholds[name] for name, value in values.items()}
    passed["flip_count"] = passed["flip_count"] and not (expected > 0 and measured == 0)
    return values, passed, not_checked


def _diagnosis(series, values, passed, flips):
    """The names of :data:`DIAGNOSES` that the data show."""
    no_flip = flips["exact"].size > 0 and flips["measured"].size == 0
    found = ["no_flip"] if no_flip else []
    final = series["energy_drift"][-1]
    if not passed["energy_drift"] and abs(final) >= 0.5 * values["energy_drift"]:  # a trend, not an oscillation
        found.append("energy_decay" if final < 0 else "energy_growth")
    if not (passed["momentum_drift"] and passed.get("momentum_direction", True)):
        found.append("momentum_drift")
    if not passed.get("period_error", True) and not no_flip:
        found.append("period_error")
    return found


def summary(ds):
    """A one-screen text report of a :func:`check` result: the verdict, each criterion, the flips, the diagnosis."""
    lines = [f"verdict: {ds.attrs['verdict'].upper()}"]
    width = max(map(len, DEFAULT_TOLERANCES))
    for name, value, tolerance, ok in zip(ds.criterion.values, ds.value.values, ds.tolerance.values,
                                          ds.passed.values):
        lines.append(f"  {'pass' if ok else 'FAIL'}  {name:{width}s} {value:11.3e} <= {tolerance:9.3g}  "
                     f"({CRITERIA[str(name)][0]})")
    if ds.attrs["not_checked"]:
        lines.append(f"  not checked: {ds.attrs['not_checked'].replace(',', ', ')} (no attitude or too few flips)")
    flips, exact_flips = ds.flip_time.values, ds.flip_time_exact.values
    lines.append(f"flips about axis {ds.attrs['intermediate_axis']}: {flips.size} measured, {exact_flips.size} exact; "
                 f"spacing {ds.attrs['flip_spacing']:.6g} s measured, {ds.attrs['flip_spacing_exact']:.6g} s exact "
                 "(2K/nu)")
    shared = min(flips.size, exact_flips.size)
    if shared:
        lag = flips[:shared] - exact_flips[:shared]
        lines.append(f"  flip time - exact: first {lag[0]:+.3e} s, last {lag[-1]:+.3e} s")
    for name in filter(None, ds.attrs["diagnosis"].split(",")):
        percent = 100.0 * (ds.attrs["flip_spacing"] / ds.attrs["flip_spacing_exact"] - 1.0)
        lines.append(f"diagnosis: {name}: {DIAGNOSES[name].format(percent=percent)}")
    return "\n".join(lines)
