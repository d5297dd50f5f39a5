"""Real physics engines through ``tumble check``: does each one tumble right?

    python benchmarks/engines.py            # pip install ".[engines]" first (mujoco, pybullet)
    python benchmarks/engines.py --quick    # two steps per integrator, fewer flips: a smoke run

A free T-handle (tumble.shapes.t_handle's moments) in zero gravity, spun at 10 rad/s 0.002 rad from its
intermediate axis, recorded every 10 ms through ten flips by

* MuJoCo (``mujoco`` from PyPI), each of its integrators (Euler, implicitfast, implicit, RK4), steps of 1 to 10 ms.
  The body's inertia is given as a full tensor in a body frame turned away from the principal axes (MJCF
  ``fullinertia``), so the check finds the principal axes itself (``--inertia``); MuJoCo's free joint reports its
  angular velocity in the body frame and its attitude as a scalar-first body-to-world quaternion.
* PyBullet (``pybullet``): its Featherstone multibody (``btMultiBody``, whose gyroscopic term is switched on) and its
  maximal-coordinate rigid body (``useMaximalCoordinates=True``: ``btRigidBody`` with its default implicit
  gyroscopic step, ``BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY``); PyBullet's Python API has no switch for the
  gyroscopic flag itself, so "without" is the rigid body with the gyroscopic torque cancelled (an external torque
  equal to ``w x (I w)`` applied each step, which is what an engine without the term integrates). World-frame angular
  velocity, scalar-last quaternion; angular damping set to 0 (PyBullet's default is 0.04).
* tumble's own integrators as the control.

Each trajectory is written as a CSV file (``data/runs/engines/``) and checked by ``tumble check`` itself (the command
line, in this process); the table (engine, integrator, step, flip period error, |L| and energy drift after ten
flips, verdict, diagnosis) goes to ``benchmarks/results/engines.md`` with the date and the versions.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io as text_io
import platform
from pathlib import Path

import numpy as np

import tumble
from tumble import cli
from tumble.physics import exact, rotations

ROOT = Path(__file__).resolve().parent.parent
RUNS = ROOT / "data" / "runs" / "engines"
REPORT = ROOT / "benchmarks" / "results" / "engines.md"

SPIN = 10.0        # rad/s
TILT = 0.002       # rad from the intermediate axis
RECORD = 0.01      # s between records
FLIPS = 10
STEPS = (0.001, 0.002, 0.005, 0.01)
MUJOCO_INTEGRATORS = ("Euler", "implicitfast", "implicit", "RK4")
TUMBLE_METHODS = ("rk4", "splitting2", "implicit_midpoint", "symplectic_euler")
MASS = 0.1         # kg (the rotation does not depend on it)
# The recording's body frame: the principal axes turned by this rotation (principal -> body coordinates).
BODY_TURN = rotations.about_axis(0.4, [1.0, 2.0, -1.0])


def t_handle():
    """(principal moments (3,), inertia tensor in the turned body frame (3, 3), w0 in that frame (3,), t_end)."""
    moments = tumble.shapes.t_handle().moments
    w_principal = SPIN * np.array([np.sin(TILT) / np.sqrt(2), np.cos(TILT), np.sin(TILT) / np.sqrt(2)])
    turn = np.column_stack([rotations.rotate(BODY_TURN, e) for e in np.eye(3)])
    tensor = turn @ np.diag(moments) @ turn.T
    first = float(exact.first_flip_time(moments, w_principal))
    spacing = float(exact.flip_spacing(moments, w_principal))
    return moments, tensor, turn @ w_principal, first + (FLIPS - 0.5) * spacing


def record_count(t_end, dt):
    every = max(1, int(round(RECORD / dt)))
    return every, int(t_end / dt) // every


def mujoco_run(integrator, dt, tensor, w0, t_end):
    """MuJoCo's free body: times, body-frame angular velocity, body-to-world quaternion (scalar first)."""
    import mujoco

    full = " ".join(repr(float(v)) for v in inertia_elements(tensor))
    xml = f"""<mujoco model="t_handle">
      <option gravity="0 0 0" timestep="{dt!r}" integrator="{integrator}"/>
      <worldbody><body name="handle"><freejoint/>
        <inertial pos="0 0 0" mass="{MASS}" fullinertia="{full}"/>
      </body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[3:6] = w0
    every, records = record_count(t_end, dt)
    t, w, q = [0.0], [data.qvel[3:6].copy()], [data.qpos[3:7].copy()]
    for _ in range(records):
        for _ in range(every):
            mujoco.mj_step(model, data)
        t.append(data.time)
        w.append(data.qvel[3:6].copy())
        q.append(data.qpos[3:7].copy())
    return {"t": np.array(t), "omega": np.array(w), "quaternion": np.array(q)}


def pybullet_run(mode, dt, tensor, w0, t_end):
    """PyBullet: times, world-frame angular velocity, body-to-world quaternion (returned scalar first)."""
    import pybullet as p

    moments, axes = np.linalg.eigh(tensor)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    inertial = _quaternion(axes)  # principal -> body coordinates: the inertial frame's orientation in the body
    client = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, 0, physicsClientId=client)
        p.setTimeStep(dt, physicsClientId=client)
        shape = p.createCollisionShape(p.GEOM_SPHERE, radius=0.01, physicsClientId=client)
        body = p.createMultiBody(baseMass=MASS, baseCollisionShapeIndex=shape,
                                 baseInertialFrameOrientation=list(inertial[[1, 2, 3, 0]]),
                                 useMaximalCoordinates=(mode != "multibody"), physicsClientId=client)
        p.changeDynamics(body, -1, localInertiaDiagonal=list(moments), linearDamping=0.0, angularDamping=0.0,
                         physicsClientId=client)
        p.resetBaseVelocity(body, [0, 0, 0], list(w0), physicsClientId=client)  # body = world at t = 0
        every, records = record_count(t_end, dt)
        t, w, q = [0.0], [], []

        def sample():
            w.append(p.getBaseVelocity(body, physicsClientId=client)[1])
            q.append(p.getBasePositionAndOrientation(body, physicsClientId=client)[1])

        sample()
        for k in range(records):
            for _ in range(every):
                if mode == "rigid body, gyroscopic torque cancelled":
                    world_w = np.array(p.getBaseVelocity(body, physicsClientId=client)[1])
                    orientation = np.array(p.getBasePositionAndOrientation(body, physicsClientId=client)[1])
                    qp = orientation[[3, 0, 1, 2]]  # PyBullet's orientation is the principal (inertial) frame's
                    wp = rotations.rotate(rotations.conjugate(qp), world_w)
                    gyro = np.cross(wp, moments * wp)  # principal frame: I w' = -w x I w; cancel it
                    p.applyExternalTorque(body, -1, list(rotations.rotate(qp, gyro)), p.WORLD_FRAME,
                                          physicsClientId=client)
                p.stepSimulation(physicsClientId=client)
            t.append((k + 1) * every * dt)
            sample()
    finally:
        p.disconnect(client)
    # PyBullet reports the orientation of the inertial (principal) frame; the body frame's is that times inertial*
    q = rotations.product(np.array(q)[:, [3, 0, 1, 2]], rotations.conjugate(inertial))
    return {"t": np.array(t), "omega": np.array(w), "quaternion": q}


def _quaternion(matrix):
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(matrix).as_quat(scalar_first=True)


def tumble_run(method, dt, tensor, w0, t_end):
    """tumble's integrator on the principal axes, reported in the turned body frame as an engine would."""
    moments, axes = np.linalg.eigh(tensor)
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    every, records = record_count(t_end, dt)
    run = tumble.integrate(tuple(moments), (axes.T @ w0)[None], records * every * dt, dt, method=method,
                           save_every=every, attitude=True)
    w = run.omega.values[0] @ axes.T
    q = rotations.product(run.quaternion.values[0], rotations.conjugate(_quaternion(axes)))
    return {"t": run.time.values, "omega": w, "quaternion": q}


def write_csv(path, run):
    path.parent.mkdir(parents=True, exist_ok=True)
    table = np.column_stack([run["t"], run["omega"], run["quaternion"]])
    np.savetxt(path, table, delimiter=",", header="t,wx,wy,wz,qw,qx,qy,qz", comments="", fmt="%.17g")


def inertia_elements(tensor):
    """The six elements XX YY ZZ XY XZ YZ (MuJoCo's fullinertia order, ``tumble check --inertia``)."""
    return [tensor[0, 0], tensor[1, 1], tensor[2, 2], tensor[0, 1], tensor[0, 2], tensor[1, 2]]


def check_file(path, tensor, omega_frame):
    """``tumble check`` on ``path`` (the command line, in this process): (exit status, the result dataset)."""
    inertia = inertia_elements(tensor)
    with contextlib.redirect_stdout(text_io.StringIO()):
        status = cli.main(["check", str(path), "--inertia", *map(repr, map(float, inertia)), "--omega-frame",
                           omega_frame, "--out", str(path.parent)])
    return status, tumble.io.read_dataset(path.parent / f"{path.stem}_check.nc")


def runs(quick):
    steps = STEPS[1::2] if quick else STEPS
    for integrator in MUJOCO_INTEGRATORS:
        for dt in steps:
            yield "MuJoCo", integrator, dt, "body", mujoco_run
    for mode in ("multibody", "rigid body", "rigid body, gyroscopic torque cancelled"):
        for dt in steps:
            yield "PyBullet", mode, dt, "world", pybullet_run
    for method in TUMBLE_METHODS:
        for dt in steps:
            yield "tumble", method, dt, "body", tumble_run


def versions():
    found = {"tumble": tumble.__version__, "python": platform.python_version(), "numpy": np.__version__}
    for name in ("mujoco", "pybullet"):
        try:
            from importlib.metadata import version

            found[name] = version(name)
        except Exception:  # noqa: BLE001 - a package that is not installed is reported as such
            found[name] = "not installed"
    return found


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two steps per integrator, for a smoke run")
    parser.add_argument("--report", default=str(REPORT), help=f"table file (default {REPORT.relative_to(ROOT)})")
    args = parser.parse_args(argv)
    moments, tensor, w0, t_end = t_handle()
    rows = []
    for engine, integrator, dt, frame, run in runs(args.quick):
        kwargs = {"integrator": integrator} if run is mujoco_run else {"mode": integrator} if run is pybullet_run \
            else {"method": integrator}
        try:
            recorded = run(dt=dt, tensor=tensor, w0=w0, t_end=t_end, **kwargs)
        except ImportError as err:
            print(f"{engine} {integrator}: skipped ({err})")
            continue
        path = RUNS / f"{engine}_{integrator}_{dt * 1000:g}ms".replace(" ", "_").replace(",", "")
        path = path.with_suffix(".csv")
        write_csv(path, recorded)
        status, ds = check_file(path, tensor, frame)
        values = dict(zip(ds.criterion.values.tolist(), ds.value.values.tolist()))
        period = ds.attrs["flip_spacing"] / ds.attrs["flip_spacing_exact"] - 1.0
        row = (engine, integrator, f"{dt * 1000:g}", f"{100 * period:+.3f}%" if np.isfinite(period) else "no flips",
               f"{ds.momentum_drift.values[-1]:+.1e}", f"{ds.energy_drift.values[-1]:+.1e}",
               f"{values['omega_error']:.1e}", f"{ds.sizes['flip']}/{ds.sizes['flip_exact']}",
               ds.attrs["verdict"] + f" ({status})",
               ", ".join(str(c) for c, ok in zip(ds.criterion.values, ds.passed.values) if not ok) or "-",
               ds.attrs["diagnosis"].replace(",", ", ") or "-")
        rows.append(row)
        print(" | ".join(row), flush=True)
    header = ("engine", "integrator", "step (ms)", "flip period error", "abs L drift", "energy drift",
              "max omega error", "flips", "verdict (exit)", "failed criteria", "diagnosis")
    found = versions()
    lines = [f"# Physics engines through `tumble check` ({datetime.date.today().isoformat()})", "",
             f"`python benchmarks/engines.py`{' --quick' if args.quick else ''}; "
             + ", ".join(f"{k} {v}" for k, v in found.items()) + f"; {platform.machine()}.", "",
             f"A free T-handle (moments {', '.join(f'{m:.4e}' for m in moments)} kg m²) in zero gravity, {SPIN:g} rad/s "
             f"{TILT:g} rad from its intermediate axis, recorded every {RECORD * 1000:g} ms for {t_end:.2f} s "
             f"({FLIPS} flips of the exact motion); drifts are at the last sample (after ten flips), relative to the "
             "first. Default tolerances; exit 0 pass, 3 fail.", "",
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    Path(args.report).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.report}")


if __name__ == "__main__":
    main()
