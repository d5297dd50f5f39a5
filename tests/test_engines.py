"""MuJoCo and PyBullet through tumble check, on a short case, through the real packages (benchmarks/engines.py).

The packages come with the ``engines`` extra, which the ``test`` extra includes; where one is not importable its
tests skip and say so."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

import tumble

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import engines  # noqa: E402

needs_mujoco = pytest.mark.skipif(importlib.util.find_spec("mujoco") is None,
                                  reason="mujoco is not installed (pip install \".[engines]\")")
needs_pybullet = pytest.mark.skipif(importlib.util.find_spec("pybullet") is None,
                                    reason="pybullet is not installed (pip install \".[engines]\")")

STEP = 0.005


@pytest.fixture(scope="module")
def t_handle():
    moments, tensor, w0, t_end = engines.t_handle()
    first = float(tumble.exact.first_flip_time(moments, np.linalg.eigh(tensor)[1].T @ w0))
    return tensor, w0, min(t_end, 1.5 * first + 0.5)  # two flips or so


def checked(recorded, tensor, frame):
    """tumble.check on the recorded arrays (the command line is exercised once, in the first test)."""
    ds = tumble.check(recorded["t"], recorded["omega"], recorded["quaternion"], inertia=tensor, omega_frame=frame)
    return (0 if ds.attrs["verdict"] == "pass" else 3), ds


@needs_mujoco
def test_mujoco_rk4_passes_and_its_euler_is_named_as_an_explicit_step(tmp_path, t_handle):
    tensor, w0, t_end = t_handle
    path = tmp_path / "rk4.csv"
    engines.write_csv(path, engines.mujoco_run("RK4", STEP, tensor, w0, t_end))
    status, ds = engines.check_file(path, tensor, "body")  # tumble check, the command line
    assert status == 0 and ds.attrs["verdict"] == "pass"
    assert ds.sizes["flip"] == ds.sizes["flip_exact"] >= 1
    status, ds = checked(engines.mujoco_run("Euler", STEP, tensor, w0, t_end), tensor, "body")
    assert status == 3 and "energy_growth" in ds.attrs["diagnosis"]


@needs_mujoco
def test_mujoco_implicit_damps_the_motion(t_handle):
    tensor, w0, t_end = t_handle
    status, ds = checked(engines.mujoco_run("implicit", STEP, tensor, w0, t_end), tensor, "body")
    assert status == 3 and "energy_decay" in ds.attrs["diagnosis"]


@needs_pybullet
@pytest.mark.parametrize("mode, pattern", [("multibody", "energy_growth"), ("rigid body", "energy_decay")])
def test_pybullet_flips_and_its_step_is_named(t_handle, mode, pattern):
    tensor, w0, t_end = t_handle
    status, ds = checked(engines.pybullet_run(mode, STEP, tensor, w0, t_end), tensor, "world")
    assert ds.sizes["flip"] == ds.sizes["flip_exact"] >= 1  # the gyroscopic term is there: it flips on time
    assert status == 3 and pattern in ds.attrs["diagnosis"]


def test_tumble_rk4_as_the_control_passes(t_handle):
    tensor, w0, t_end = t_handle
    status, ds = checked(engines.tumble_run("rk4", STEP, tensor, w0, t_end), tensor, "body")
    assert status == 0 and float(ds.value.sel(criterion="omega_error")) < 1e-5


@needs_pybullet
def test_pybullet_without_the_gyroscopic_term_never_flips_and_is_named(t_handle):
    tensor, w0, t_end = t_handle
    recorded = engines.pybullet_run("rigid body, gyroscopic torque cancelled", STEP, tensor, w0, t_end)
    status, ds = checked(recorded, tensor, "world")
    assert status == 3 and ds.sizes["flip"] == 0 < ds.sizes["flip_exact"]
    assert ds.attrs["diagnosis"].split(",")[0] == "no_flip"
