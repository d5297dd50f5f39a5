"""How long ``tumble check`` takes on a long recording (issue 30: a 100 000-sample trajectory in under 1 s warm).

    python benchmarks/check_speed.py [--samples N] [--repeats N]   # writes benchmarks/results/check_speed.md

The recording: a T-handle spun at 10 rad/s 2 mrad from its intermediate axis, 100 000 samples 1 ms apart (about 35
flips), from tumble's RK4 with the attitude: times, body-frame angular velocity and quaternion. Timed, each the
median of ``--repeats`` runs after one warm-up call (imports done, kernels compiled or loaded from numba's cache):

* ``tumble.check`` on the arrays (the target);
* reading the same recording from a CSV file (``tumble.output.trajectory.read_trajectory``);
* the whole command, ``tumble check FILE`` in this process, with the netCDF file and the figure written.
"""

import argparse
import contextlib
import io as text_io
import os
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

import tumble
from tumble import cli
from tumble.output import trajectory

import timing  # benchmarks/timing.py (the script's folder is on sys.path)

RESULTS = Path(__file__).with_name("results")
TARGET_S = 1.0


def timed(call, repeats):
    call()  # warm-up: imports, kernels
    return timing.median_seconds(call, repeats)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    body = tumble.shapes.t_handle()
    moments = body.moments
    w0 = 10.0 * np.array([0.002 / np.sqrt(2), 1.0, 0.002 / np.sqrt(2)])
    dt = 1e-3
    run = tumble.integrate(body, w0[None], (args.samples - 1) * dt, dt, method="rk4", save_every=1, attitude=True)
    t, w, q = run.time.values, run.omega.values[0], run.quaternion.values[0]
    check_s = timed(lambda: tumble.check(t, w, q, moments=moments), args.repeats)
    result = tumble.check(t, w, q, moments=moments)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "recording.csv"
        np.savetxt(path, np.column_stack([t, w, q]), delimiter=",", header="t,wx,wy,wz,qw,qx,qy,qz", comments="",
                   fmt="%.17g")
        read_s = timed(lambda: trajectory.read_trajectory(path), args.repeats)
        command = ["check", str(path), "--moments", *map(repr, moments.tolist()), "--out", folder]

        def whole():
            with contextlib.redirect_stdout(text_io.StringIO()):
                assert cli.main(command) == 0

        command_s = timed(whole, args.repeats)
    load = os.getloadavg()[0]
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%MZ")
    lines = [f"# tumble check speed — {stamp}", "",
             f"Machine: {timing.machine()}; load average at start {load:.2f}. tumble "
             f"{tumble.__version__}. Medians of {args.repeats} runs after a warm-up call.", "",
             f"A {t.size}-sample recording (T-handle, 10 rad/s near the intermediate axis, {t[-1]:.0f} s, "
             f"{result.sizes['flip']} flips; angular velocity and attitude; verdict {result.attrs['verdict']}).", "",
             "| what | time | target |", "|---|---|---|",
             f"| `tumble.check` on the arrays | {check_s:.3f} s | < {TARGET_S:g} s: "
             f"{'met' if check_s < TARGET_S else 'missed'} |",
             f"| reading the same recording from a CSV file (pandas) | {read_s:.3f} s | |",
             f"| `tumble check FILE` in-process (read, check, write netCDF and PNG) | {command_s:.3f} s | |"]
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "check_speed.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
