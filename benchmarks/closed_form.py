"""Closed-form (exact torque-free) kernel benchmark: evaluations per second of the vectorised
``torque_free_omega`` against the scalar kernel it replaced, near the largest and near the intermediate axis.

    python benchmarks/closed_form.py            # writes benchmarks/results/closed_form.{json,md}

A second table measures one time per sample straight from the spins (the final state of ``tumble.propagate``):
the fused kernel with samples in SIMD lanes (``exact.omega_at``) against the time-grid path at that one time (the
per-sample set-up with Carlson's R_F and the evaluation, one kernel call: what it replaced), in samples per second.

One evaluation is one sample at one time (three components). Both kernels get the same per-sample inputs
(from ``tumble.physics.exact``) and run in the same process; compile time (or the load from numba's cache)
is excluded and reported separately; each rate is the median of several runs, with 1 numba thread and with
all of them. Other processes on the machine slow the multi-thread runs most (a parallel call waits for its
slowest thread): the load average at the start is recorded with the results.
"""

import json
import os
import time
from pathlib import Path

import numba
import numpy as np

from tumble.kernels.closed_form import elliptic as ell
from tumble.kernels.threads import in_parallel
from tumble.physics import exact

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

RESULTS = Path(__file__).with_name("results")
MOMENTS = (1.0, 2.0, 3.0)
SAMPLES = 4096
TIMES = 257
REPEATS = 7


def median_seconds(fn, repeats=REPEATS):
    return timing.median_seconds(fn, repeats)


def regimes(rng):
    """Spins near the largest axis (k' ~ 0.9 .. 1, the Landen core) and near the intermediate axis at
    distances 1e-3 .. 1e-8 (k' ~ 1e-3 .. 1e-8, the hyperbolic series), both senses."""
    eps = 10.0 ** rng.uniform(-8, -3, (SAMPLES, 1))
    near_mid = np.column_stack([rng.uniform(-1, 1, SAMPLES), rng.choice([-1.0, 1.0], SAMPLES),
                                rng.uniform(-1, 1, SAMPLES)])
    near_mid[:, [0, 2]] *= eps
    near_largest = np.column_stack([rng.uniform(-0.2, 0.2, (SAMPLES, 2)), rng.choice([-1.0, 1.0], SAMPLES)])
    return {"largest axis": near_largest, "intermediate axis": near_mid}


def measure(w0, t):
    sol = exact._solve(MOMENTS, w0)
    args = (sol.kind, sol.amp, sol.cols, sol.kc, sol.phase0, sol.nu)  # the scalar reference kernel's inputs
    args_new = (sol.kind, sol.amp, sol.cols, sol.kc, sol.K, sol.nome, sol.phase0, sol.nu)
    out = np.empty((SAMPLES, TIMES, 3))
    times, row = np.ascontiguousarray(t[None, :]), np.zeros(SAMPLES, dtype=np.int64)

    def new():
        ell.torque_free_omega(*args_new, times, row, out)

    def old():
        in_parallel(ell._torque_free_omega_reference, SAMPLES, *args, t, out)

    row_ = {"kc_min": float(sol.kc.min()), "kc_max": float(sol.kc.max())}
    for name, fn in (("new", new), ("old", old)):
        started = time.perf_counter()
        fn()
        row_[f"compile_{name}"] = time.perf_counter() - started
    check_new, check_old = np.empty_like(out), np.empty_like(out)
    ell.torque_free_omega(*args_new, times, row, check_new)
    in_parallel(ell._torque_free_omega_reference, SAMPLES, *args, t, check_old)
    row_["max_rel_diff_vs_old"] = float(np.max(np.abs(check_new - check_old) / np.max(np.abs(check_old), axis=1,
                                                                                        keepdims=True)))
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        for name, fn in (("new", new), ("old", old)):
            row_[f"{name}_{threads}"] = SAMPLES * TIMES / median_seconds(fn, REPEATS if name == "new" else 3)
        row_[f"speedup_{threads}"] = row_[f"new_{threads}"] / row_[f"old_{threads}"]
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return row_


def measure_one_time(w0, t):
    """Samples per second at one time ``t``, from the spins: the fused lanes kernel against the time-grid path."""
    moments = np.array(MOMENTS)
    w0 = np.ascontiguousarray(w0)
    tt = np.asarray(t)

    def new():
        exact.omega_at(moments, w0, t)

    def old():
        exact._omega_grid(moments, w0, tt)

    row_ = {}
    for name, fn in (("new", new), ("old", old)):
        started = time.perf_counter()
        fn()
        row_[f"compile_{name}"] = time.perf_counter() - started
    got, ref = exact.omega_at(moments, w0, t), exact._omega_grid(moments, w0, tt)
    row_["max_rel_diff_vs_old"] = float(np.max(np.abs(got - ref) / np.linalg.norm(ref, axis=1, keepdims=True)))
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        for name, fn in (("new", new), ("old", old)):
            row_[f"{name}_{threads}"] = SAMPLES / median_seconds(fn, 3 * REPEATS)
        row_[f"speedup_{threads}"] = row_[f"new_{threads}"] / row_[f"old_{threads}"]
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return row_


def main():
    RESULTS.mkdir(exist_ok=True)
    machine = timing.machine()
    load = os.getloadavg()[0]
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 40.0, TIMES)
    report = {**provenance.stamp(), "machine": machine, "threads": numba.config.NUMBA_NUM_THREADS,
              "load_average": load, "samples": SAMPLES, "times": TIMES, "regimes": {}}
    report["one_time"] = {}
    for label, w0 in regimes(rng).items():
        report["regimes"][label] = measure(w0, t)
        report["one_time"][label] = measure_one_time(w0, float(t[-1]))
        print(label, report["regimes"][label], report["one_time"][label], flush=True)
    (RESULTS / "closed_form.json").write_text(json.dumps(report, indent=1))
    nt = report["threads"]
    lines = [f"# Closed-form kernel benchmark — {report['date']}", "",
             (f"Machine: {machine}; load average at start {load:.2f}. {SAMPLES} samples × {TIMES} times, "
              f"I = (1, 2, 3); evaluations (one sample at one time) per second, medians of {REPEATS} runs "
              "(old: 3), compile time excluded. *new*: the vectorised `torque_free_omega`; *old*: the scalar "
              "kernel it replaced (`_torque_free_omega_reference`), same inputs, same process. A load "
              "average above about 1 means other processes shared the cores: the multi-thread columns are "
              "then lower bounds (a parallel call waits for its slowest thread)."), "",
             (f"| spins | k' | new, 1 thread | old, 1 thread | speed-up | new, {nt} threads | old, {nt} threads "
              "| speed-up | compile new / old, s |"), "|---|---|---|---|---|---|---|---|---|"]
    for label, r in report["regimes"].items():
        lines.append(f"| near the {label} | {r['kc_min']:.1e} … {r['kc_max']:.2g} | {r['new_1']:.2e} | "
                     f"{r['old_1']:.2e} | {r['speedup_1']:.1f}× | {r[f'new_{nt}']:.2e} | {r[f'old_{nt}']:.2e} | "
                     f"{r[f'speedup_{nt}']:.1f}× | {r['compile_new']:.1f} / {r['compile_old']:.1f} |")
    lines += ["", ("Largest difference new − old over each run, relative to the largest |ω| component of the "
                   "sample: ") + ", ".join(f"{label} {r['max_rel_diff_vs_old']:.1e}"
                                     for label, r in report["regimes"].items()) + "."]
    lines += ["", f"## One time per sample, from the spins (t = {t[-1]:g} s)", "",
              (f"Samples per second, {SAMPLES} spins, medians of {3 * REPEATS} runs. *new*: `exact.omega_at` (the "
               "fused kernel, samples in SIMD lanes, Jacobi's addition theorem instead of the initial argument); "
               "*old*: the time-grid path at that one time (`exact._omega_grid`: the per-sample set-up with "
               "Carlson's R_F, then the evaluation: `torque_free_solve`, `torque_free_omega`)."), "",
              (f"| spins | new, 1 thread | old, 1 thread | speed-up | new, {nt} threads | old, {nt} threads | "
               "speed-up | largest difference, × |ω| |"), "|---|---|---|---|---|---|---|---|"]
    for label, r in report["one_time"].items():
        lines.append(f"| near the {label} | {r['new_1']:.2e} | {r['old_1']:.2e} | {r['speedup_1']:.1f}× | "
                     f"{r[f'new_{nt}']:.2e} | {r[f'old_{nt}']:.2e} | {r[f'speedup_{nt}']:.1f}× | "
                     f"{r['max_rel_diff_vs_old']:.1e} |")
    (RESULTS / "closed_form.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
