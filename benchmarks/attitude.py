"""Attitude costs nothing unless asked: the ensemble run without it, with it, and what ran.

    python benchmarks/attitude.py            # writes benchmarks/results/attitude.md and attitude.json

For each method (and the closed form) an ensemble of spins is integrated with ``tumble.integrate`` three ways,
interleaved and repeated (median of REPEATS):

1. ``attitude=False`` — the SIMD ensemble kernel alone;
2. the same call while the attitude kernel and the closed-form attitude are replaced by functions that count
   their calls — it must make none (this is what "cost zero" means: the attitude code is never compiled or
   run), and it must take the time of (1);
3. ``attitude=True`` — angular velocity and orientation together (the per-sample attitude kernel, or
   :func:`tumble.exact.attitude`).

Compile (or cache-load) time of each path is measured in a first call and reported apart.
"""

import json
import platform
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import numba
import numpy as np

import tumble
from tumble.kernels.loops import methods as kernel_methods
from tumble.kernels.loops.methods import METHODS
from tumble.physics import exact

sys.path.insert(0, str(Path(__file__).parent))
from provenance import source_digest, stamp as provenance_stamp  # noqa: E402
import timing  # noqa: E402  (benchmarks/timing.py)

RESULTS = Path(__file__).with_name("results")
MOMENTS = np.array([1.0, 2.0, 3.0])
SAMPLES = 4096
T_END, DT, SAVE_EVERY = 10.0, 1e-2, 100
REPEATS = 5


class _Counter:
    def __init__(self, wrapped):
        self.wrapped, self.calls = wrapped, 0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        return self.wrapped(*args, **kwargs)


def _spins():
    rng = np.random.default_rng(7)
    return np.array([0.3, 1.0, 0.2]) + 0.05 * rng.standard_normal((SAMPLES, 3))


def _timed(method, w0, attitude):
    started = time.perf_counter()
    tumble.integrate(MOMENTS, w0, T_END, DT, method=method, save_every=SAVE_EVERY, attitude=attitude)
    return time.perf_counter() - started


def measure(method, w0):
    compile_plain = _timed(method, w0[:8], False)
    compile_attitude = _timed(method, w0[:8], True)
    plain, counted, with_attitude = [], [], []
    kernel, closed = _Counter(kernel_methods.propagate_attitude), _Counter(exact.attitude)
    for _ in range(REPEATS):
        plain.append(_timed(method, w0, False))
        kernel_methods.propagate_attitude, exact.attitude = kernel, closed
        try:
            counted.append(_timed(method, w0, False))
        finally:
            kernel_methods.propagate_attitude, exact.attitude = kernel.wrapped, closed.wrapped
        with_attitude.append(_timed(method, w0, True))
    steps = 0 if method == "exact" else round(T_END / DT)
    return {"method": method, "first_call_plain_s": compile_plain, "first_call_attitude_s": compile_attitude,
            "plain_s": float(np.median(plain)), "counted_s": float(np.median(counted)),
            "attitude_s": float(np.median(with_attitude)), "attitude_calls_when_not_asked": kernel.calls + closed.calls,
            "sample_steps": SAMPLES * steps}


def main():
    w0 = _spins()
    rows = [measure(method, w0) for method in (*METHODS, "exact")]
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%MZ")
    meta = {"date": stamp,
            "machine": f"{platform.machine()}, {timing.vector_width()}, {numba.config.NUMBA_NUM_THREADS} threads",
            "numba": numba.__version__, "python": platform.python_version(), "tumble_sources": source_digest(),
            "samples": SAMPLES, "t_end": T_END, "dt": DT, "save_every": SAVE_EVERY, "repeats": REPEATS}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "attitude.json").write_text(json.dumps({**provenance_stamp(), "meta": meta, "rows": rows}, indent=1))
    lines = [
        "# Attitude: cost when not asked, and when asked",
        "",
        f"Measured {stamp} by `python benchmarks/attitude.py`. Machine: {meta['machine']}, numba {meta['numba']}, "
        f"Python {meta['python']}; tumble sources {meta['tumble_sources']}.",
        "",
        f"`tumble.integrate` on {SAMPLES} spins of I = (1, 2, 3), t_end = {T_END:g} s, dt = {DT:g} s, every "
        f"{SAVE_EVERY}th step stored; median of {REPEATS} interleaved runs, compile / cache-load time excluded "
        "(first calls reported apart). \"Counted\" is the `attitude=False` run with the attitude kernel and "
        "`exact.attitude` replaced by call counters.",
        "",
        "| method | attitude=False, s | counted, s | attitude calls when not asked | attitude=True, s | "
        "with / without | first call without / with, s |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['method']} | {r['plain_s']:.4f} | {r['counted_s']:.4f} | "
                     f"{r['attitude_calls_when_not_asked']} | {r['attitude_s']:.4f} | "
                     f"{r['attitude_s'] / r['plain_s']:.2f}x | {r['first_call_plain_s']:.2f} / "
                     f"{r['first_call_attitude_s']:.2f} |")
    calls = sum(r["attitude_calls_when_not_asked"] for r in rows)
    lines += ["", f"Attitude code called by runs that did not ask for it: **{calls}** (zero cost: the kernels a run "
              "without attitude uses are the ensemble kernels, with no attitude branch compiled in)."]
    (RESULTS / "attitude.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
