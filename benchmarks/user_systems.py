"""A user's System against the built-in it copies: the heavy top written by hand (``tests/hand_written_systems.py``)
and ``tumble.models.HeavyTop``, through the documented calls.

    python benchmarks/user_systems.py [--quick]     # writes benchmarks/results/user_systems.md and .json

* ``tumble.propagate``, rk4, 20 000 samples: the built-in, the System on the vectorised block path (its rate
  rewritten into the built-ins' scalar form: ``tumble/kernels/steps/system_steps.py``), and the same System through the
  per-sample loop (the path of a rate without a scalar form, and of every System before the block path);
* ``tumble.megno``, rk4, 4 000 samples: the built-in (its exact tangent), the System with its Jacobian, the System
  without one (fourth-order differences: four rate calls per tangent and stage), and the per-sample loop;
* the first call of the System's ``propagate`` in a new process: with an empty numba cache, then with the cache the
  first process filled (its kernels loaded, not compiled).

Compile time is excluded from the throughput (each call runs once first); each timing is the median of several runs;
the ratios are against the built-in measured in the same run. ``--quick`` times fewer steps and repeats.
"""

import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np

import tumble
from tumble.engine import system_runs

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
import hand_written_systems  # noqa: E402
from hand_written_systems import HEAVY_TOP, HEAVY_TOP_WITH_JACOBIAN  # noqa: E402

RESULTS = HERE / "results"
BUILT_IN = tumble.models.HeavyTop(moments=(2.0, 2.5, 3.0), mgl=0.5)
DT = 0.01


def tops(n, seed=0):
    """``n`` heavy tops near a sleeping spin (|g| = 1)."""
    rng = np.random.default_rng(seed)
    y = np.tile([0.1, 0.2, 3.0, 0.0, 0.1, 0.99], (n, 1)) + 1e-3 * rng.standard_normal((n, 6))
    y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    return y


class _PerSample:
    """The per-sample loop for ``system`` while in this context: its block code taken away (as for a rate without a
    scalar form)."""

    def __init__(self, system):
        self.system = system

    def __enter__(self):
        self.kept = system_runs._BLOCK_CODES.pop(self.system, None)
        system_runs._BLOCK_CODES[self.system] = {False: None, True: None}

    def __exit__(self, *exc):
        system_runs._BLOCK_CODES[self.system] = self.kept or {}


def timed(call, repeats, per_sample=None):
    """Median seconds of ``call()`` (run once first), through the per-sample loop of ``per_sample`` if given."""
    context = _PerSample(per_sample) if per_sample is not None else None
    if context:
        context.__enter__()
    try:
        call()
        return timing.median_seconds(call, repeats)
    finally:
        if context:
            context.__exit__()


_FIRST = """
import sys, time
sys.path.insert(0, {tests!r})
started = time.perf_counter()
import numpy as np, tumble
from hand_written_systems import HEAVY_TOP
tumble.propagate(HEAVY_TOP, np.array([[0.1, 0.2, 3.0, 0.0, 0.0, 1.0]]), 0.1, 0.01, method="rk4")
print(time.perf_counter() - started)
"""


def first_calls():
    """Seconds of the System's first ``propagate`` in a new process (import included): an empty numba cache, then
    the cache the first process filled."""
    script = textwrap.dedent(_FIRST).format(tests=str(HERE.parent / "tests"))
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        return [float(subprocess.run([sys.executable, "-c", script], env=env, check=True, capture_output=True,
                                     text=True).stdout.split()[-1]) for _ in range(2)]


def main(quick=False):
    repeats = 3 if quick else 7
    steps = 200 if quick else 1000
    rows = []
    y = tops(20_000)
    t_end = steps * DT
    propagate = {
        "built-in HeavyTop": timed(lambda: tumble.propagate(BUILT_IN, y, t_end, DT, method="rk4"), repeats),
        "System, vectorised blocks": timed(lambda: tumble.propagate(HEAVY_TOP, y, t_end, DT, method="rk4"), repeats),
        "System, per-sample loop": timed(lambda: tumble.propagate(HEAVY_TOP, y, t_end, DT, method="rk4"), repeats,
                                         per_sample=HEAVY_TOP),
    }
    for label, seconds in propagate.items():
        rows.append({"call": "propagate", "samples": len(y), "steps": steps, "path": label, "seconds": seconds,
                     "sample_steps_per_s": len(y) * steps / seconds,
                     "vs_built_in": seconds / propagate["built-in HeavyTop"]})
    y = tops(4_000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no Jacobian: the difference warnings are not the point here
        megno = {
            "built-in HeavyTop": timed(lambda: tumble.megno(BUILT_IN, y, t_end, DT), repeats),
            "System with its Jacobian, vectorised blocks":
                timed(lambda: tumble.megno(HEAVY_TOP_WITH_JACOBIAN, y, t_end, DT), repeats),
            "System without a Jacobian (differences), vectorised blocks":
                timed(lambda: tumble.megno(HEAVY_TOP, y, t_end, DT), repeats),
            "System with its Jacobian, per-sample loop":
                timed(lambda: tumble.megno(HEAVY_TOP_WITH_JACOBIAN, y, t_end, DT), repeats,
                      per_sample=HEAVY_TOP_WITH_JACOBIAN),
        }
    for label, seconds in megno.items():
        rows.append({"call": "megno", "samples": len(y), "steps": steps, "path": label, "seconds": seconds,
                     "sample_steps_per_s": len(y) * steps / seconds,
                     "vs_built_in": seconds / megno["built-in HeavyTop"]})
    empty, warm = first_calls()
    result = {**provenance.stamp(),
              "quick": quick, "repeats": repeats, "rows": rows,
              "first_call": {"empty_cache_s": empty, "warm_cache_s": warm}}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "user_systems.json").write_text(json.dumps(result, indent=2) + "\n")
    (RESULTS / "user_systems.md").write_text(report(result))
    print(report(result))


def report(result):
    lines = [f"# A user's System against the built-in (heavy top), {result['date']}", "",
             f"{result['machine']}; medians of {result['repeats']} runs, compile time excluded"
             f"{' (--quick)' if result['quick'] else ''}. Ratio: the System's time over the built-in's in the same run.",
             "", "| call | samples x steps | path | s | sample-steps/s | time vs built-in |", "|---|---|---|---|---|---|"]
    for row in result["rows"]:
        lines.append(f"| `{row['call']}` | {row['samples']:,} x {row['steps']:,} | {row['path']} | {row['seconds']:.3f} "
                     f"| {row['sample_steps_per_s']:.3g} | {row['vs_built_in']:.2f}x |")
    first = result["first_call"]
    lines += ["", f"The System's first `propagate` in a new process (import included): {first['empty_cache_s']:.1f} s "
                  f"with an empty numba cache, {first['warm_cache_s']:.1f} s with the cache the first process filled.",
              ""]
    return "\n".join(lines)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
