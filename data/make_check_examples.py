"""Write the bundled example trajectories that ``tumble check`` can be tried on without a physics engine.

    python data/make_check_examples.py

A T-handle (tumble.shapes.t_handle: moments about 9.7e-6, 1.8e-5, 2.7e-5 kg m² along x, y, z) spun at 5 rad/s
0.002 rad from its intermediate axis y, recorded every 50 ms for 55 s (ten flips) as an engine would write it:

* ``check_t_handle_rk4.csv``: tumble's RK4 with the attitude, 1 ms steps: t, wx wy wz (body frame), qw qx qy qz
  (body-to-world). It passes the check.
* ``check_t_handle_euler.csv``: forward (explicit) Euler on Euler's equations, 1 ms steps, angular velocity only:
  t, wx wy wz. It fails the check, and the diagnosis names the explicit step (energy growth).

Check them with ``tumble check data/check_t_handle_rk4.csv --moments 9.6875e-06 1.8194444444444445e-05
2.7256944444444445e-05`` (the moments the files' header comments do not carry: CSV has no place for them).
"""

from pathlib import Path

import numpy as np

import tumble

HERE = Path(__file__).resolve().parent
SPIN = 5.0
TILT = 0.002
T_END = 55.0
STEP = 1e-3
EVERY = 50  # steps between records


def initial_spin():
    return SPIN * np.array([np.sin(TILT) / np.sqrt(2), np.cos(TILT), np.sin(TILT) / np.sqrt(2)])


def forward_euler(moments, w0, steps, dt, every):
    i1, i2, i3 = moments
    w = w0.copy()
    out = [w.copy()]
    for k in range(1, steps + 1):
        w = w + dt * np.array([(i2 - i3) * w[1] * w[2] / i1, (i3 - i1) * w[2] * w[0] / i2,
                               (i1 - i2) * w[0] * w[1] / i3])
        if k % every == 0:
            out.append(w.copy())
    return np.array(out)


def write_csv(path, columns):
    names = list(columns)
    table = np.column_stack([columns[name] for name in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    print(f"{path.relative_to(HERE.parent)}: {table.shape[0]} rows, {path.stat().st_size / 1024:.0f} KiB")


def main():
    body = tumble.shapes.t_handle()
    w0 = initial_spin()
    run = tumble.integrate(body, w0[None], T_END, STEP, method="rk4", save_every=EVERY, attitude=True)
    t = run.time.values
    w = run.omega.values[0]
    q = run.quaternion.values[0]
    write_csv(HERE / "check_t_handle_rk4.csv", {"t": t, "wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2], "qw": q[:, 0],
                                                "qx": q[:, 1], "qy": q[:, 2], "qz": q[:, 3]})
    w = forward_euler(body.moments, w0, int(round(T_END / STEP)), STEP, EVERY)
    t = np.arange(w.shape[0]) * (STEP * EVERY)
    write_csv(HERE / "check_t_handle_euler.csv", {"t": t, "wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]})


if __name__ == "__main__":
    main()
