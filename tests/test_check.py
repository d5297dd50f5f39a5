"""tumble check / tumble.check: a recorded trajectory held against the exact torque-free solution (issue 30)."""

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import tumble
from tumble import cli
from tumble.measure import check as checking
from tumble.physics import exact, rotations

from layout_checks import misplaced

DATA = Path(__file__).resolve().parent.parent / "data"
EXAMPLE = DATA / "check_t_handle_rk4.csv"
EULER_EXAMPLE = DATA / "check_t_handle_euler.csv"
MOMENTS = np.array([1.0, 2.0, 3.0])
T_HANDLE = ["9.6875e-06", "1.8194444444444445e-05", "2.7256944444444445e-05"]


def exact_trajectory(w0, moments=MOMENTS, t_end=40.0, n=800):
    """The exact solution recorded as an engine would: times, body-frame omega, body-to-world quaternion."""
    t = np.linspace(0.0, t_end, n)
    return t, exact.omega(moments, w0, t), exact.attitude(moments, w0, t)


def forward_euler(w0, moments=MOMENTS, dt=1e-3, t_end=40.0, every=50):
    i1, i2, i3 = moments
    w = np.array(w0, dtype=float)
    out = [w]
    for k in range(1, int(round(t_end / dt)) + 1):
        w = w + dt * np.array([(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2,
                               (i1 - i2) * w[0] * w[1] / i3])
        if k % every == 0:
            out.append(w)
    return np.arange(len(out)) * dt * every, np.array(out)


NEAR_INTERMEDIATE = np.array([0.01, 1.0, 0.01])


@pytest.mark.parametrize("w0", [[0.01, 1.0, 0.01], [0.3, 1.0, 0.8], [0.8, 1.0, 0.3], [0.1, 0.2, 1.5],
                                [1.5, 0.2, 0.1], [0.0, 0.0, 2.0], [0.0, 1.0, 0.0], [2.0, 0.0, 0.0]],
                         ids=["near-intermediate", "largest-regime", "smallest-regime", "near-largest",
                              "near-smallest", "steady-largest", "steady-intermediate", "steady-smallest"])
def test_the_exact_motion_passes_every_criterion_by_four_orders_of_magnitude(w0):
    t, w, q = exact_trajectory(np.array(w0, dtype=float))
    ds = tumble.check(t, w, q, moments=MOMENTS)
    assert ds.attrs["verdict"] == "pass" and ds.attrs["diagnosis"] == ""
    for name, value, tolerance in zip(ds.criterion.values, ds.value.values, ds.tolerance.values):
        if name != "flip_count":
            assert value <= 1e-4 * tolerance, name
    assert ds.value.sel(criterion="flip_count") == 0


def test_the_world_frame_and_scalar_last_quaternions_are_turned_as_named():
    t, w, q = exact_trajectory(np.array([0.3, 1.0, 0.8]))
    world = rotations.rotate(q, w)
    ds = tumble.check(t, world, q[:, [1, 2, 3, 0]], moments=MOMENTS, omega_frame="world", quaternion_order="xyzw")
    assert ds.attrs["verdict"] == "pass"
    assert float(ds.value.sel(criterion="omega_error")) < 1e-12
    wrong = tumble.check(t, world, q, moments=MOMENTS)  # world-frame data read as body-frame data
    assert wrong.attrs["verdict"] == "fail"


def test_an_inertia_tensor_in_a_rotated_body_frame_is_diagonalised_and_the_data_turned():
    t, w, q = exact_trajectory(NEAR_INTERMEDIATE)
    turn = rotations.about_axis(0.7, [1.0, -2.0, 0.5])  # principal -> recording body coordinates
    matrix = np.column_stack([rotations.rotate(turn, e) for e in np.eye(3)])
    tensor = matrix @ np.diag(MOMENTS) @ matrix.T
    w_file = rotations.rotate(turn, w)
    q_file = rotations.product(q, rotations.conjugate(turn))
    ds = tumble.check(t, w_file, q_file, inertia=tensor)
    assert ds.attrs["verdict"] == "pass"
    assert float(ds.value.sel(criterion="attitude_error")) < 1e-8


def test_the_angular_velocity_is_derived_from_the_attitude_alone():
    t, w, q = exact_trajectory(NEAR_INTERMEDIATE, n=4000)
    ds = tumble.check(t, quaternion=q, moments=MOMENTS)
    assert ds.attrs["verdict"] == "pass"
    assert ds.attrs["omega_source"] == "derived from the attitude quaternion"


def test_a_body_without_the_gyroscopic_term_never_flips_and_is_named():
    t = np.linspace(0.0, 60.0, 600)
    ds = tumble.check(t, np.tile(NEAR_INTERMEDIATE, (t.size, 1)), moments=MOMENTS)
    assert ds.attrs["verdict"] == "fail"
    assert "no_flip" in ds.attrs["diagnosis"].split(",")
    assert ds.sizes["flip"] == 0 and ds.sizes["flip_exact"] > 2


def test_a_damped_trajectory_fails_as_energy_decay():
    t, w, q = exact_trajectory(NEAR_INTERMEDIATE)
    ds = tumble.check(t, w * np.exp(-1e-3 * t)[:, None], q, moments=MOMENTS)
    assert ds.attrs["verdict"] == "fail"
    assert {"energy_decay", "momentum_drift"} <= set(ds.attrs["diagnosis"].split(","))
    assert ds.energy_drift.values[-1] < -0.05


def test_forward_euler_fails_as_energy_growth():
    t, w = forward_euler(NEAR_INTERMEDIATE)
    ds = tumble.check(t, w, moments=MOMENTS)
    assert ds.attrs["verdict"] == "fail"
    assert "energy_growth" in ds.attrs["diagnosis"].split(",")
    assert ds.attrs["not_checked"] == "attitude_error,momentum_direction"


def test_a_motion_three_percent_slow_fails_as_period_error_with_its_percentage():
    t = np.linspace(0.0, 60.0, 3000)
    w = exact.omega(MOMENTS, NEAR_INTERMEDIATE, t / 1.03)  # the same orbit, 3 % slower: invariants kept
    ds = tumble.check(t, w, moments=MOMENTS)
    assert ds.attrs["diagnosis"] == "period_error"
    assert float(ds.attrs["flip_spacing"] / ds.attrs["flip_spacing_exact"]) == pytest.approx(1.03, abs=1e-3)
    assert "off by +3.00%" in checking.summary(ds)
    assert tumble.check(t, w, moments=MOMENTS, tolerances={"period_error": 0.05, "omega_error": 2.0,
                                                           "flip_count": 2}).attrs["verdict"] == "pass"


@pytest.mark.parametrize("kwargs, words", [
    ({"t": [0.0, 1.0, 1.0]}, "t, row 3: times not increasing"),
    ({"omega": "nan"}, "omega column 2, row 2"),
    ({"quaternion": "long"}, "quaternion, row 2: |q| = "),
    ({"moments": [1.0, 1.0, 3.0]}, "violate the triangle inequality"),
    ({"omega": None, "quaternion": None}, "give the angular velocity (omega) or the attitude (quaternion)"),
    ({"omega": None}, "the first angular velocity is zero"),  # derived from a quaternion that never turns
    ({"quaternion": None, "omega_frame": "world"}, "omega_frame 'world' needs the attitude quaternion"),
    ({"tolerances": {"omega": 1.0}}, "tolerance 'omega': unknown criterion"),
    ({"tolerances": {"energy_drift": -1.0}}, "tolerance 'energy_drift': must be a finite number >= 0"),
    ({"omega_frame": "space"}, "omega_frame must be one of body, world"),
])
def test_invalid_input_raises_one_line_naming_what_is_wrong(kwargs, words):
    args = {"t": [0.0, 1.0, 2.0], "omega": np.array([[0.1, 1.0, 0.1]] * 3),
            "quaternion": np.array([[1.0, 0.0, 0.0, 0.0]] * 3), "moments": MOMENTS}
    if kwargs.get("omega") == "nan":
        kwargs["omega"] = args["omega"].copy()
        kwargs["omega"][1, 1] = np.nan
    if kwargs.get("quaternion") == "long":
        kwargs["quaternion"] = args["quaternion"] * np.array([[1.0], [1.001], [1.0]])
    args.update(kwargs)
    with pytest.raises(ValueError) as err:
        tumble.check(args.pop("t"), args.pop("omega"), args.pop("quaternion"), **args)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_the_exact_solution_on_the_bundled_example_is_1e4_below_the_smallest_threshold():
    mp_reference = pytest.importorskip("test_exact").mp_reference  # mpmath, written apart from tumble.exact
    t = np.loadtxt(EXAMPLE, delimiter=",", skiprows=1)
    moments = np.array([float(x) for x in T_HANDLE])
    ds = tumble.check(t[:, 0], t[:, 1:4], t[:, 4:8], moments=moments)
    picks = np.linspace(0, t.shape[0] - 1, 25).astype(int)
    reference, _ = mp_reference(moments, t[0, 1:4], ds.time.values[picks], dps=30)
    error = np.max(np.linalg.norm(ds.omega_exact.values[picks] - reference, axis=1) / np.linalg.norm(reference, axis=1))
    smallest = min(tolerance for name, tolerance in checking.DEFAULT_TOLERANCES.items() if name != "flip_count")
    assert error <= 1e-4 * smallest
    assert error < 1e-12  # what it is (1.4e-14 measured): the closed form's own accuracy


# ------------------------------------------------------------------------------------------- the command line

def run_check(capsys, *args):
    status = cli.main(["check", *map(str, args)])
    out, err = capsys.readouterr()
    return status, out, err


def test_the_bundled_examples_pass_and_fail_with_exit_0_and_3_and_write_both_files(tmp_path, capsys):
    status, out, _ = run_check(capsys, EXAMPLE, "--moments", *T_HANDLE, "--out", tmp_path)
    assert status == 0 and "verdict: PASS" in out
    ds = tumble.io.read_dataset(tmp_path / "check_t_handle_rk4_check.nc", require_tumble=True)
    assert ds.attrs["verdict"] == "pass" and ds.attrs["history"].endswith("tumble check check_t_handle_rk4.csv")
    assert all("units" in ds[name].attrs and "long_name" in ds[name].attrs for name in ds.data_vars if
               name != "criterion_units")
    assert (tmp_path / "check_t_handle_rk4_check.png").stat().st_size > 10_000
    status, out, _ = run_check(capsys, EULER_EXAMPLE, "--moments", *T_HANDLE, "--out", tmp_path)
    assert status == cli.EXIT_CHECK_FAILED == 3
    assert "diagnosis: energy_growth" in out
    assert (tmp_path / "check_t_handle_euler_check.nc").is_file()


def test_tolerances_from_options_and_a_toml_table_decide_the_verdict(tmp_path, capsys):
    table = tmp_path / "loose.toml"
    table.write_text("[tolerances]\nenergy_drift = 0.1\nmomentum_drift = 0.01\n")
    args = (EULER_EXAMPLE, "--moments", *T_HANDLE, "--out", tmp_path, "--tolerances", table)
    assert run_check(capsys, *args)[0] == 3  # momentum_drift 2.8e-2 > 0.01
    assert run_check(capsys, *args, "--tolerance", "momentum_drift=0.1")[0] == 0


def test_npz_and_netcdf_recordings_are_read_by_column_name(tmp_path, capsys):
    table = np.loadtxt(EXAMPLE, delimiter=",", skiprows=1)
    names = ["t", "wx", "wy", "wz", "qw", "qx", "qy", "qz"]
    np.savez(tmp_path / "run.npz", **{name: table[:, i] for i, name in enumerate(names)}, other=np.zeros(3))
    xr.Dataset({name: ("sample", table[:, i]) for i, name in enumerate(names)}).to_netcdf(tmp_path / "run.nc")
    for name in ("run.npz", "run.nc"):
        assert run_check(capsys, tmp_path / name, "--moments", *T_HANDLE, "--out", tmp_path / "out")[0] == 0


def write_csv(path, rows, header="t,wx,wy,wz,qw,qx,qy,qz"):
    path.write_text(header + "\n" + "\n".join(",".join(map(str, row)) for row in rows) + "\n")
    return path


GOOD_ROWS = [[0.0, 0.01, 1.0, 0.01, 1, 0, 0, 0], [0.1, 0.01, 1.0, 0.01, 1, 0, 0, 0],
             [0.2, 0.01, 1.0, 0.01, 1, 0, 0, 0]]


def _edited(row, column, value):
    rows = [list(r) for r in GOOD_ROWS]
    rows[row][column] = value
    return rows


@pytest.mark.parametrize("rows, header, words", [
    (GOOD_ROWS, "t,wx,wy,qw,qx,qy,qz", "missing column 'wz'"),
    (GOOD_ROWS, "time,wx,wy,wz,qw,qx,qy,qz", "missing column 't'"),
    ([r[:1] + r[4:] for r in GOOD_ROWS], "t,a,b,c", "no angular velocity (wx wy wz) or attitude"),
    (_edited(2, 0, 0.1), None, "column 't', row 3: times not increasing"),
    (_edited(1, 2, "nan"), None, "column 'wy', row 2: 'nan' is not a finite number"),
    (_edited(1, 3, "abc"), None, "column 'wz', row 2: 'abc' is not a finite number"),
    (_edited(0, 1, ""), None, "column 'wx', row 1: empty"),
    (_edited(2, 4, 1.01), None, "columns qw qx qy qz, row 3: |q| = 1.01 is not a unit quaternion (tolerance 1e-06)"),
])
def test_a_bad_file_exits_2_with_one_line_naming_file_column_and_row_and_writes_nothing(tmp_path, capsys, rows,
                                                                                         header, words):
    path = write_csv(tmp_path / "bad.csv", rows, header or "t,wx,wy,wz,qw,qx,qy,qz")
    status, out, err = run_check(capsys, path, "--moments", "1", "2", "3", "--out", tmp_path / "out")
    assert status == 2
    assert err.startswith(f"tumble: error: {path}") and words in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, words", [
    (["--moments", "1", "1", "3"], "--moments: moments (1.0, 1.0, 3.0) violate the triangle inequality"),
    (["--inertia", "1", "2", "3", "0", "0", "5"], "--inertia: inertia tensor must be positive definite"),
    (["--moments", "1", "2", "3", "--tolerance", "omega_error=x"], "--tolerance 'omega_error=x': expected NAME=VALUE"),
    (["--moments", "1", "2", "3", "--tolerance", "speed=1"], "tolerance 'speed': unknown criterion"),
])
def test_bad_options_exit_2_and_write_nothing(tmp_path, capsys, args, words):
    path = write_csv(tmp_path / "good.csv", GOOD_ROWS)
    status, _, err = run_check(capsys, path, *args, "--out", tmp_path / "out")
    assert status == 2 and words in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


def test_a_missing_file_exits_2(tmp_path, capsys):
    status, _, err = run_check(capsys, tmp_path / "none.csv", "--moments", "1", "2", "3")
    assert status == 2 and f"{tmp_path / 'none.csv'}: no such file" in err


def test_check_help_lists_every_criterion_and_its_default(capsys):
    with pytest.raises(SystemExit):
        cli.main(["check", "--help"])
    out = capsys.readouterr().out
    for name, value in checking.DEFAULT_TOLERANCES.items():
        assert f"{name}={value:g}" in out.replace("\n", " ").replace("  ", " ") or name in out


def test_inertia_elements_in_exponent_notation_may_be_negative(tmp_path, capsys):
    # argparse's own negative-number pattern has no exponent: "-1e-30" was taken for an option
    status, out, err = run_check(capsys, EXAMPLE, "--inertia", *T_HANDLE, "-1e-30", "0", "-2.5e-31", "--out",
                                 tmp_path)
    assert status == 0, err
    assert "verdict: PASS" in out


@pytest.mark.parametrize("example", [EXAMPLE, EULER_EXAMPLE], ids=["rk4", "euler"])
def test_the_check_figure_keeps_its_texts_inside_and_apart(example):
    from tumble.output import check_figure, trajectory

    recording = trajectory.read_trajectory(example)
    ds = tumble.check(recording["t"], recording["omega"], recording.get("quaternion"),
                      moments=np.array(T_HANDLE, dtype=float))
    fig = check_figure.draw_check(ds)
    assert fig.get_layout_engine() is None
    assert misplaced(fig, dpi=150, style=check_figure._STYLE) == []
