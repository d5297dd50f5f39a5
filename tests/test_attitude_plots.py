"""Attitude pictures: the flip animation, the snapshot strip, the polhode and the herpolhode are drawn from a
traced spin's attitude, files are valid and written atomically, and the geometry is right: the herpolhode lies in
the plane perpendicular to L (which fixes the quaternion convention), polhodes lie on both ellipsoids, and the
drawn box has the body's proportions.

The trace is made here, independently of tumble's integrators: Euler's equations and the quaternion kinematics
``q' = ½ q ⊗ (0, ω)`` (body-to-space, scalar first) integrated by SciPy's DOP853 at rtol 1e-10."""

import ast
import inspect
import json
import warnings

import numpy as np
import pytest
import xarray as xr
from matplotlib import animation
from matplotlib.figure import Figure
from PIL import Image
from scipy.integrate import solve_ivp

from tumble.output import attitude_figures as attitude_plots
from tumble.output import figures as plots
from tumble.physics import shapes

from layout_checks import misplaced

ATTITUDE_FIGURES = ("flip_strip", "flip_animation", "polhode", "herpolhode")
SPIN = 10.0  # rad/s, about the T-handle's intermediate axis
TILT = 1e-3  # rad
T_END = 8.5  # s: three flips (at about 1.5, 4.6 and 7.7 s)


def _multiply(p, q):
    """Hamilton product of scalar-first quaternions, shapes (..., 4)."""
    a, u = p[..., :1], p[..., 1:]
    b, v = q[..., :1], q[..., 1:]
    return np.concatenate([a * b - np.sum(u * v, axis=-1, keepdims=True),
                           a * v + b * u + np.cross(u, v)], axis=-1)


def _rotate(q, v):
    """``q v q*`` for scalar-first quaternions q (T, 4) and vectors v (T, 3)."""
    conjugate = q * np.array([1.0, -1.0, -1.0, -1.0])
    pure = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    return _multiply(_multiply(q, pure), conjugate)[..., 1:]


def reference_trace(moments, w0, t_end, points):
    """Euler's equations with ``q' = ½ q ⊗ (0, ω_body)``, DOP853, rtol 1e-10: times (T,), ω (T, 3), q (T, 4)."""
    moments = np.asarray(moments, dtype=float)
    i1, i2, i3 = moments

    def rhs(_, y):
        w, q = y[:3], y[3:]
        dw = [(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2, (i1 - i2) * w[0] * w[1] / i3]
        dq = 0.5 * _multiply(q, np.concatenate([[0.0], w]))
        return np.concatenate([dw, dq])

    t = np.linspace(0.0, t_end, points)
    solution = solve_ivp(rhs, (0.0, t_end), np.concatenate([w0, [1.0, 0.0, 0.0, 0.0]]), method="DOP853",
                         t_eval=t, rtol=1e-10, atol=1e-12)
    assert solution.success
    return t, solution.y[:3].T, solution.y[3:].T


def attitude_dataset(moments, w0, t_end, points, *, shape="", params=None, method="scipy DOP853 (reference)",
                     spin_axis=2):
    """A dataset in the attitude schema of tumble.attitude_trace, plus an unrelated scan variable."""
    t, w, q = reference_trace(moments, w0, t_end, points)
    attrs = {"method": method, "spin_axis": spin_axis, "body_shape": shape,
             "body_shape_json": json.dumps(params or {})}
    return xr.Dataset(
        {"attitude_quaternion": (("attitude_time", "quaternion_component"), q, attrs),
         "attitude_omega": (("attitude_time", "component"), w, {"units": "rad/s"}),
         "attitude_moments": ("component", np.asarray(moments, dtype=float), {"units": "kg m2"}),
         "rate": ((), 0.5, {"units": "1/s"})},
        coords={"attitude_time": ("attitude_time", t, {"units": "s"}), "quaternion_component": [0, 1, 2, 3],
                "component": [1, 2, 3]})


@pytest.fixture(scope="module")
def t_handle_flip():
    """The Dzhanibekov T-handle (default dimensions) spun at 10 rad/s about its intermediate axis, tilted 1e-3
    rad, through three flips."""
    body = shapes.t_handle(mass=0.05)
    return attitude_dataset(body.moments, SPIN * np.array([TILT, 1.0, 0.0]), T_END, 600, shape="t_handle",
                            params={"mass": 0.05})


@pytest.fixture
def few_frames(monkeypatch):
    """Animations of 12 frames, so that tests render them in a fraction of a second."""
    monkeypatch.setattr(attitude_plots, "FRAMES", 12)


def _kind(path):
    head = path.read_bytes()[:8]
    if head == b"\x89PNG\r\n\x1a\n":
        return "png"
    if head.startswith(b"%PDF"):
        return "pdf"
    if head[:6] in (b"GIF87a", b"GIF89a"):
        return "gif"
    return "?"


# ------------------------------------------------------------------------------------------ files


def test_each_attitude_figure_is_written_as_png_and_pdf_and_the_animation_as_a_gif(t_handle_flip, tmp_path,
                                                                                     few_frames, monkeypatch):
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    written = plots.save_figures(t_handle_flip, ATTITUDE_FIGURES, tmp_path, "dz", formats=("png", "pdf"),
                                 dpi=60)
    expected = {tmp_path / f"dz_{name}.{fmt}" for name in ("flip_strip", "polhode", "herpolhode")
                for fmt in ("png", "pdf")} | {tmp_path / "dz_flip_animation.gif"}
    assert set(written) == expected and len(written) == len(expected)
    assert set(tmp_path.iterdir()) == expected, "no temporary file is left"
    for path in written:
        assert _kind(path) == path.suffix[1:]
    with Image.open(tmp_path / "dz_flip_animation.gif") as gif:
        assert gif.n_frames == 12 > 1
        assert gif.size == (224, 240)
        assert gif.info["loop"] == 0


def test_the_animation_is_a_gif_whatever_image_formats_are_asked_for(t_handle_flip, tmp_path, few_frames,
                                                                      monkeypatch):
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    written = plots.save_figures(t_handle_flip, ["flip_animation"], tmp_path, "run", formats=("pdf",))
    assert written == [tmp_path / "run_flip_animation.gif"]


def test_mp4_when_ffmpeg_is_found_gif_otherwise(monkeypatch):
    monkeypatch.setattr(animation.writers, "is_available", lambda name: name == "ffmpeg")
    assert attitude_plots.animation_format() == "mp4"
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    assert attitude_plots.animation_format() == "gif"


class _FakeFFMpeg(animation.AbstractMovieWriter):
    """Stands in for ffmpeg: records where it was asked to write, writes the frame count there."""

    outfiles = []

    def __init__(self, fps=5, codec=None, extra_args=None, **kwargs):
        super().__init__(fps=fps)
        self.codec, self.extra_args, self.frames = codec, extra_args, 0

    def setup(self, fig, outfile, dpi=None):
        super().setup(fig, outfile, dpi=dpi)
        _FakeFFMpeg.outfiles.append(str(outfile))

    def grab_frame(self, **savefig_kwargs):
        self.frames += 1

    def finish(self):
        with open(self.outfile, "w") as file:
            file.write(f"{self.codec} {self.frames}")


def test_save_figures_writes_an_mp4_through_a_temporary_mp4_when_ffmpeg_is_found(t_handle_flip, tmp_path,
                                                                                  few_frames, monkeypatch):
    monkeypatch.setattr(animation.writers, "is_available", lambda name: name == "ffmpeg")
    monkeypatch.setattr(animation, "FFMpegWriter", _FakeFFMpeg)
    _FakeFFMpeg.outfiles.clear()
    written = plots.save_figures(t_handle_flip, ["flip_animation", "herpolhode"], tmp_path, "run")
    assert written == [tmp_path / "run_flip_animation.mp4", tmp_path / "run_herpolhode.png"]
    assert set(tmp_path.iterdir()) == set(written)
    assert (tmp_path / "run_flip_animation.mp4").read_text() == "h264 12"
    (temporary,) = _FakeFFMpeg.outfiles
    assert temporary.endswith(".mp4"), "ffmpeg picks the container from the extension"
    assert temporary != str(written[0]) and temporary.startswith(str(tmp_path)), "written beside, then renamed"


def test_failed_animation_leaves_neither_file_nor_temporary(t_handle_flip, tmp_path, few_frames, monkeypatch):
    def broken(self, *args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(OSError, match="disk full"):
        plots.save_figures(t_handle_flip, ["flip_animation"], tmp_path, "run")
    assert list(tmp_path.iterdir()) == []


def test_animation_frames_are_evenly_spread_stored_times(t_handle_flip):
    anim = attitude_plots.flip_animation(t_handle_flip, frames=40, fps=10)
    t = t_handle_flip["attitude_time"].values
    assert len(anim.frame_times) == 40 and anim.fps == 10
    assert anim.frame_times[0] == t[0] and anim.frame_times[-1] == t[-1]
    assert np.isin(anim.frame_times, t).all()
    assert np.ptp(np.diff(anim.frame_times)) <= 1.01 * (t[1] - t[0])
    assert isinstance(anim, animation.FuncAnimation) and isinstance(anim.figure, Figure)


# ----------------------------------------------------------------------------------- refusal


@pytest.mark.parametrize("name", ATTITUDE_FIGURES)
def test_dataset_without_attitude_is_refused_with_a_reason(name, tmp_path):
    scan = xr.Dataset({"rate": ("axis", [0.1, 0.5, 0.2]), "kind": ("axis", ["periodic", "exponential", "periodic"])},
                      coords={"axis": [1, 2, 3]})
    ok, reason = plots.can_draw(scan, name)
    assert not ok
    assert reason.startswith(f"{name} needs the attitude of one traced spin")
    assert "'attitude_quaternion'" in reason and "this dataset has none" in reason
    with pytest.raises(ValueError, match="attitude of one traced spin"):
        getattr(plots, name)(scan)
    with pytest.raises(ValueError, match="attitude"):
        plots.save_figures(scan, [name], tmp_path, "run")
    assert list(tmp_path.iterdir()) == []


def test_partial_or_misshapen_attitude_is_refused_naming_what_is_wrong(t_handle_flip):
    ok, reason = plots.can_draw(t_handle_flip.drop_vars("attitude_omega"), "polhode")
    assert not ok and "lacks 'attitude_omega'" in reason
    flat = t_handle_flip.assign(attitude_moments=((), 1.0))
    assert "'attitude_moments' along the dimension(s) 'component'" in plots.can_draw(flat, "polhode")[1]
    nan = t_handle_flip.assign(attitude_quaternion=t_handle_flip["attitude_quaternion"] * np.nan)
    assert "at least 2 finite times" in plots.can_draw(nan, "herpolhode")[1]


def test_drawable_trace_passes_can_draw(t_handle_flip):
    for name in ATTITUDE_FIGURES:
        assert plots.can_draw(t_handle_flip, name) == (True, "")


# ---------------------------------------------------------------------------------- geometry


def test_herpolhode_lies_in_the_invariable_plane_perpendicular_to_L(t_handle_flip):
    q = t_handle_flip["attitude_quaternion"].values
    q = q / np.linalg.norm(q, axis=1, keepdims=True)  # unit to round-off, as the schema says
    w = t_handle_flip["attitude_omega"].values
    moments = t_handle_flip["attitude_moments"].values
    momentum = _rotate(q, moments * w)  # L in space, from the data with the quaternion product
    assert np.ptp(momentum, axis=0).max() <= 1e-9 * np.linalg.norm(momentum[0]), "the reference conserves L"
    normal = momentum.mean(axis=0) / np.linalg.norm(momentum.mean(axis=0))

    omega_space, plane, height = attitude_plots.herpolhode_points(t_handle_flip)
    scale = np.linalg.norm(w, axis=1).max()
    np.testing.assert_allclose(omega_space, _rotate(q, w), rtol=0, atol=1e-12 * scale)
    along_l = omega_space @ normal
    assert np.ptp(along_l) <= 1e-9 * scale, "every point in one plane perpendicular to L"
    np.testing.assert_allclose(height, along_l, rtol=0, atol=1e-12 * scale)
    energy = 0.5 * np.sum(moments * w[0] ** 2)
    np.testing.assert_allclose(height, 2 * energy / np.linalg.norm(momentum[0]), rtol=1e-9)  # Poinsot: 2T/|L|
    np.testing.assert_allclose(np.sum(plane**2, axis=1) + height**2, np.sum(w**2, axis=1), rtol=1e-12)
    assert np.hypot(*plane.T).max() > 0.3 * scale, "the flips carry ω far from L: a real test of the plane"

    wrong = _rotate(q * np.array([1.0, -1.0, -1.0, -1.0]), w)  # the other convention, v_s = q* v_b q
    assert np.ptp(wrong @ normal) > 1e-2 * scale, "the plane test tells the conventions apart"

    fig = plots.herpolhode(t_handle_flip)
    curve = [line for line in fig.axes[0].get_lines() if len(line.get_xdata()) == len(plane)]
    assert curve and np.allclose(np.column_stack(curve[0].get_data()), plane)


def test_invariable_frame_is_right_handed_with_L_up(t_handle_flip):
    frame = attitude_plots.invariable_frame(t_handle_flip)
    np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(frame) == pytest.approx(1.0)
    moments = t_handle_flip["attitude_moments"].values
    w0 = t_handle_flip["attitude_omega"].values[0]
    np.testing.assert_allclose(frame[2], moments * w0 / np.linalg.norm(moments * w0), atol=1e-9)


def test_polhodes_lie_on_the_energy_ellipsoid(t_handle_flip):
    moments = t_handle_flip["attitude_moments"].values
    w = t_handle_flip["attitude_omega"].values
    two_t = np.sum(moments * w**2, axis=1)
    assert np.ptp(two_t) <= 1e-9 * two_t[0]
    fig = plots.polhode(t_handle_flip)
    (ax,) = fig.axes
    curves = [np.column_stack(line.get_data_3d()) for line in ax.get_lines() if len(line.get_xdata()) > 1]
    assert len(curves) >= 5, "the trace, the family of polhodes and the separatrix"
    for curve in curves:
        np.testing.assert_allclose(np.sum(moments * curve**2, axis=1), np.median(two_t), rtol=1e-9)
        momentum2 = np.sum((moments * curve) ** 2, axis=1)
        assert np.ptp(momentum2) <= 1e-9 * momentum2.max(), "and on one momentum ellipsoid: a polhode"
    assert [ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()] == [f"$\\omega_{k}$ (rad/s)" for k in (1, 2, 3)]


def test_box_has_the_proportions_of_a_cuboid_with_the_same_moments():
    body = shapes.cuboid(2.0, 0.1, 0.3, 0.2)
    np.testing.assert_allclose(attitude_plots.box_proportions(body.moments), [1 / 3, 1.0, 2 / 3], rtol=1e-12)
    np.testing.assert_allclose(attitude_plots.box_proportions(7.5 * body.moments), [1 / 3, 1.0, 2 / 3],
                               rtol=1e-12, err_msg="the mass only scales the box")
    lamina = attitude_plots.box_proportions([1.0, 2.0, 3.0 * (1 + 1e-15)])  # I3 = I1 + I2 up to round-off
    assert np.all(np.isfinite(lamina)) and lamina[2] == 0.0
    with pytest.raises(ValueError, match="3 positive"):
        attitude_plots.box_proportions([1.0, -2.0, 3.0])


def test_flips_are_found_where_the_intermediate_axis_crosses_the_invariable_plane(t_handle_flip):
    t = t_handle_flip["attitude_time"].values
    w2 = t_handle_flip["attitude_omega"].sel(component=2).values
    changes = t[1:][w2[1:] * w2[:-1] < 0]
    flips = attitude_plots.flip_times(t_handle_flip)
    assert len(flips) == len(changes) == 3
    assert np.all(np.abs(flips - changes) <= t[1] - t[0])
    times = attitude_plots.snapshot_times(t_handle_flip, 7)
    assert len(times) == 7 and times[0] < flips[0] < times[-1] < flips[1], "the strip shows the first flip"


def test_strip_draws_the_t_handle_through_the_flip_with_times_and_angles(t_handle_flip):
    fig = plots.flip_strip(t_handle_flip)
    assert fig.get_figwidth() == pytest.approx(plots.DOUBLE) and fig.get_figheight() <= 4.0
    assert len(fig.axes) == 8
    labels = [text.get_text() for text in fig.texts if text.get_text().startswith("$t$")]
    assert len(labels) == 8
    angles = [float(label.split("= ")[-1].rstrip("°")) for label in labels]
    # the drawn half of the intermediate axis (the T-handle's stem, along -e2 here) turns over through L's plane
    assert min(angles[0], angles[-1]) < 30 and max(angles[0], angles[-1]) > 150, angles
    assert "T-handle" in [text.get_text() for text in fig.legends[0].get_texts()]
    assert "first flip at" in " ".join(text.get_text() for text in fig.texts)


def test_a_body_known_only_by_its_moments_is_drawn_as_its_box(t_handle_flip):
    plain = t_handle_flip.copy()
    plain["attitude_quaternion"].attrs.update(body_shape="", body_shape_json="")
    legend = [text.get_text() for text in plots.flip_strip(plain).legends[0].get_texts()]
    assert "box of equal moments" in legend


def test_a_shape_whose_moments_differ_from_the_data_falls_back_to_the_box(t_handle_flip):
    other = t_handle_flip.copy()
    other["attitude_quaternion"].attrs["body_shape_json"] = json.dumps({"mass": 0.05, "bar_length": 0.2})
    with pytest.warns(UserWarning, match="does not have the dataset's moments"):
        fig = plots.flip_strip(other)
    assert "box of equal moments" in [text.get_text() for text in fig.legends[0].get_texts()]


def test_a_scan_of_traces_shows_its_first_finite_scene(t_handle_flip):
    padded = xr.concat([t_handle_flip * np.nan, t_handle_flip], dim="spin").assign_coords(spin=[5.0, 10.0])
    padded["attitude_moments"] = t_handle_flip["attitude_moments"]
    padded["attitude_quaternion"].attrs = t_handle_flip["attitude_quaternion"].attrs
    trace = attitude_plots.read_attitude(padded)
    assert trace.label == "spin = 10"
    np.testing.assert_array_equal(trace.omega, t_handle_flip["attitude_omega"].values)
    assert (trace.spin_axis, trace.body_shape, trace.shape_params) == (2, "t_handle", {"mass": 0.05})


def test_attitude_figures_use_the_paper_style_without_warnings(t_handle_flip):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name in ("flip_strip", "polhode", "herpolhode"):
            fig = getattr(plots, name)(t_handle_flip)
            assert isinstance(fig, Figure)
            assert plots.SINGLE <= fig.get_figwidth() <= plots.DOUBLE and fig.get_figheight() <= 4.0
    ax = plots.herpolhode(t_handle_flip).axes[0]
    assert "(rad/s)" in ax.get_xlabel() and "(rad/s)" in ax.get_ylabel()


def test_attitude_plots_keeps_to_its_layer():
    tree = ast.parse(inspect.getsource(attitude_plots))
    imported = {node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert "matplotlib.pyplot" not in imported
    assert not {"config", "cli", "kernels", "numba", "plots"} & {name.split(".")[-1] for name in imported}


@pytest.mark.slow
def test_full_size_animation_is_small(t_handle_flip, tmp_path, monkeypatch):
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    (path,) = plots.save_figures(t_handle_flip, ["flip_animation"], tmp_path, "run")
    with Image.open(path) as gif:
        assert gif.n_frames == attitude_plots.FRAMES
    assert path.stat().st_size < 1.5e6


def test_the_herpolhode_keeps_its_texts_inside_and_apart_without_a_layout_engine(t_handle_flip):
    fig = plots.herpolhode(t_handle_flip)
    assert fig.get_layout_engine() is None
    assert misplaced(fig) == []
