"""Ensemble-engine benchmarks: throughput per method against the naive per-sample loop, the Runge–Kutta steps
against the machine's multiply/FMA peak, peak memory of a million-sample growth measurement, and a warm
4096-sample scene end to end.

    python benchmarks/engine.py                    # all parts; writes benchmarks/results/engine.md
    python benchmarks/engine.py memory warm_scene  # re-measure some parts, keep the others' last results

Compile time is excluded from every timing (each kernel is run once first) and reported separately; each
timing is the median of several runs; the naive loop is measured in the same run as the fast one.
"""

import json
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np
from numba import prange

import tumble
from tumble import measure
from tumble.kernels.steps import fused, steppers
from tumble.kernels.steps.codegen import multiplies_per_sample_step
from tumble.kernels.jit import FASTMATH
from tumble.kernels.loops.methods import METHODS, run

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

RESULTS = Path(__file__).with_name("results")
MOMENTS = np.array([1.0, 2.0, 3.0])
SAMPLES = 20_000
REPEATS = 5


def _naive(sample):
    """The loop a user would write: one sample at a time, its time loop inside (scalar code)."""

    @numba.njit(parallel=True, fastmath=set(FASTMATH), error_model="numpy")
    def naive(w, body, h, n_steps):
        for i in prange(w.shape[0]):
            w1, w2, w3 = w[i, 0], w[i, 1], w[i, 2]
            target = steppers.l_squared(w1, w2, w3, body)
            for k in range(n_steps):
                w1, w2, w3 = sample(w1, w2, w3, k * h, h, body, target)
            w[i, 0], w[i, 1], w[i, 2] = w1, w2, w3

    return naive


def _naive_sample(method):
    """The per-sample step of ``method`` with a uniform signature for :func:`_naive`: a Runge–Kutta method's
    generated step, or a splitting's sub-flows one sample at a time (as a user would loop over them)."""
    if METHODS[method].splitting is None:
        step = getattr(fused, f"{method}_sample")

        @numba.njit(inline="always")
        def sample(w1, w2, w3, t, h, body, target):
            return step(w1, w2, w3, t, h, body, 0, None, None)

        return sample
    flows = getattr(fused, f"_{method.upper()}_FREE_FLOWS")
    fractions = getattr(fused, f"_{method.upper()}_FREE_FRACTIONS")

    @numba.njit(inline="always")
    def sample(w1, w2, w3, t, h, body, target):
        for s in range(flows.shape[0]):
            tau = fractions[s] * h
            if flows[s] == 0:
                w2, w3 = steppers.rotate(w1 * tau, w2, w3, body[9], body[11])
            elif flows[s] == 1:
                w3, w1 = steppers.rotate(w2 * tau, w3, w1, body[10], body[7])
            else:
                w1, w2 = steppers.rotate(w3 * tau, w1, w2, body[6], body[8])
        return steppers.project_l_squared(w1, w2, w3, target, body)

    return sample


def median_seconds(fn, repeats=REPEATS):
    return timing.median_seconds(fn, repeats)


def throughput():
    rng = np.random.default_rng(0)
    w0 = rng.normal(size=(SAMPLES, 3)) * 0.5
    rows = []
    for name, method in METHODS.items():
        n_steps = 2000 if method.order <= 4 and name != "splitting4" else 500
        started = time.perf_counter()
        run(method, np.ascontiguousarray(w0[:8].T), MOMENTS, 0.0, 1e-3, 1)
        compile_fast = time.perf_counter() - started
        fast = median_seconds(lambda: run(method, np.ascontiguousarray(w0.T), MOMENTS, 0.0, 1e-3, n_steps))
        row = dict(method=name, steps=n_steps, fast=SAMPLES * n_steps / fast, compile_fast=compile_fast)
        if name != "implicit_midpoint":  # its block step has no per-sample form
            naive = _naive(_naive_sample(name))
            body = steppers.body_constants(MOMENTS)
            started = time.perf_counter()
            naive(w0[:8].copy(), body, 1e-3, 1)
            row["compile_naive"] = time.perf_counter() - started
            slow = median_seconds(lambda: naive(w0.copy(), body, 1e-3, n_steps))
            row["naive"] = SAMPLES * n_steps / slow
            row["speedup"] = row["fast"] / row["naive"]
        rows.append(row)
        print(row, flush=True)
    return rows


@numba.njit(fastmath={"contract"}, error_model="numpy")
def _eight_fma_chains(x):
    """64 multiply-adds per sample in eight independent chains: the loop over the samples vectorises and the
    chains keep both FMA pipes busy, so its rate is the machine's multiply/FMA peak."""
    for i in range(x.shape[0]):
        a0 = x[i]
        a1, a2, a3, a4, a5, a6, a7 = a0 + 1.0, a0 + 2.0, a0 + 3.0, a0 + 4.0, a0 + 5.0, a0 + 6.0, a0 + 7.0
        for _ in range(8):
            a0, a1, a2, a3 = a0 * 0.5 + 0.25, a1 * 0.5 + 0.25, a2 * 0.5 + 0.25, a3 * 0.5 + 0.25
            a4, a5, a6, a7 = a4 * 0.5 + 0.25, a5 * 0.5 + 0.25, a6 * 0.5 + 0.25, a7 * 0.5 + 0.25
        x[i] = a0 + a1 + a2 + a3 + a4 + a5 + a6 + a7


@numba.njit(parallel=True)
def _fma_peak_run(x, repeat):
    for b in prange(x.shape[0] // 256):
        block = x[b * 256:(b + 1) * 256]
        for _ in range(repeat):
            _eight_fma_chains(block)


def roofline():
    """rk4 and rk8 against the bound the FMA pipes set: the measured multiply/FMA peak divided by each step's
    multiplies, and the throughputs, timed in interleaved passes (the machine's speed drifts; a ratio is of
    timings taken side by side)."""
    x = np.random.default_rng(0).random(256 * max(8, 4 * numba.get_num_threads()))  # blocks of 256 for every thread
    repeat = 4000
    w0 = np.ascontiguousarray((np.random.default_rng(0).normal(size=(SAMPLES, 3)) * 0.5).T)
    steps = {"rk4": 2000, "rk8": 500}
    calls = {"peak": lambda: _fma_peak_run(x, repeat)}
    calls.update({name: (lambda name=name: run(METHODS[name], w0.copy(), MOMENTS, 0.0, 1e-3, steps[name]))
                  for name in steps})
    _fma_peak_run(x, 1)
    for name in steps:
        run(METHODS[name], w0[:, :8].copy(), MOMENTS, 0.0, 1e-3, 1)
    walls = {name: [] for name in calls}
    for _ in range(REPEATS):
        for name, call in calls.items():
            walls[name].append(median_seconds(call, 1))
    peak = x.size * repeat * 64 / float(np.median(walls["peak"]))
    rows = []
    for name, n_steps in steps.items():
        rate = SAMPLES * n_steps / float(np.median(walls[name]))
        ops = multiplies_per_sample_step(METHODS[name].coefficients)
        rows.append(dict(method=name, multiplies=ops, rate=rate, peak=peak, bound=peak / ops,
                         fraction=rate * ops / peak))
        print(rows[-1], flush=True)
    return rows


_MEMORY_SCRIPT = """
import resource, sys
import tumble
n = int(sys.argv[1])
ds = tumble.measure((1.0, 2.0, 3.0), 2, samples=n, method="rk4", progress=False)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, int(ds.sample_steps_computed),
      float(ds.rel_error), int(ds.n_steps), ds.sizes["sample"])
"""


def peak_memory(samples=1_000_000):
    """Peak resident memory (MiB) of ``tumble.measure`` on the intermediate axis with rk4 (norm probes, three
    flips, early stop, no trajectory), in a fresh process whose kernels come from the disk cache (compiling
    takes memory of its own, reported nowhere here)."""
    for _ in range(2):  # the second run finds every kernel it needs in the cache
        done = subprocess.run([sys.executable, "-c", _MEMORY_SCRIPT, str(samples)], capture_output=True,
                              text=True, check=True)
    peak, steps, error, n_steps, _ = done.stdout.split()
    return dict(samples=samples, peak_mib=float(peak), sample_steps=int(steps), rel_error=float(error),
                n_steps=int(n_steps))


def warm_scene(samples=4096):
    """``tumble.measure`` of a 4096-sample growth scene end to end (sampling, run, observers, fits, bootstrap,
    dataset), warm kernels, both paths."""
    rows = []
    for method in ("auto", "rk4"):
        def scene():
            return measure(MOMENTS, 2, samples=samples, seed=5, method=method, progress=False)

        scene()
        rows.append(dict(method=method, path=str(scene()["path"].values), seconds=median_seconds(scene)))
    return rows


def _per_call(fn, calls=200):
    """Median seconds per call of ``fn`` (medians of REPEATS batches of ``calls`` calls)."""
    fn()
    return median_seconds(lambda: [fn() for _ in range(calls)]) / calls


def overhead():
    """Fixed cost per call, one sample and one step (warm kernels): what a user's own loop pays."""
    w1 = np.array([[0.1, 1.0, 0.1]])
    t1 = np.array([0.5])
    rows = [
        dict(call="tumble.propagate(body, w0, dt, dt, 'rk4')", seconds=_per_call(
            lambda: tumble.propagate(MOMENTS, w1, 1e-3, 1e-3, method="rk4"))),
        dict(call="tumble.propagate(body, w0, t, t, 'exact')", seconds=_per_call(
            lambda: tumble.propagate(MOMENTS, w1, 0.5, 0.5, method="exact"))),
        dict(call="tumble.integrate(body, w0, dt, dt, 'rk4')", seconds=_per_call(
            lambda: tumble.integrate(MOMENTS, w1, 1e-3, 1e-3, method="rk4"), calls=50)),
        dict(call="tumble.exact.omega(body, w0, t), t of shape (1,)", seconds=_per_call(
            lambda: tumble.exact.omega(MOMENTS, w1, t1))),
        dict(call="tumble.exact.omega(body, w0, 0.5), one time (the fused kernel)", seconds=_per_call(
            lambda: tumble.exact.omega(MOMENTS, w1, 0.5))),
        dict(call="kernels.run(rk4, w, moments, 0, dt, 1) (the kernel call alone)", seconds=_per_call(
            lambda: run(METHODS["rk4"], np.array([[0.1], [1.0], [0.1]]), MOMENTS, 0.0, 1e-3, 1))),
    ]
    for row in rows:
        print(row, flush=True)
    return rows


@numba.njit
def _spin_up(t, w1, w2, w3):
    """A torque function equal to the constant profile (0, 0, 0.1) N m."""
    return 0.0, 0.0, 0.1


def torque_paths():
    """Throughput with a built-in constant torque profile against the same torque as a function (called
    through numba's first-class function type, one compiled driver for every function)."""
    rng = np.random.default_rng(0)
    w0 = np.ascontiguousarray((rng.normal(size=(SAMPLES, 3)) * 0.5).T)
    rows = []
    for name in ("rk4", "splitting4"):
        method = METHODS[name]
        n_steps = 500
        for label, params, fn in (("profile", np.array([0.0, 0.0, 0.1, 0.0]), None), ("function", None, _spin_up)):
            def go(w=w0, params=params, fn=fn, steps=n_steps):
                return run(method, w.copy(), MOMENTS, 0.0, 1e-3, steps, torque_kind=-1 if fn else 0,
                           torque_params=params, torque_fn=fn)

            started = time.perf_counter()
            go(w0[:, :8], steps=1)
            compile_s = time.perf_counter() - started
            rows.append(dict(method=name, torque=label, rate=SAMPLES * n_steps / median_seconds(go),
                             compile=compile_s))
            print(rows[-1], flush=True)
    return rows


PARTS = {"throughput": throughput, "roofline": roofline, "memory": peak_memory, "warm_scene": warm_scene, "overhead": overhead,
         "torque_paths": torque_paths}


def main(parts=None):
    RESULTS.mkdir(exist_ok=True)
    machine = timing.machine()
    store = RESULTS / "engine.json"
    report = json.loads(store.read_text()) if parts and store.exists() else {}
    report.update(provenance.stamp(), machine=machine, threads=numba.get_num_threads())
    for name in parts or PARTS:
        report[name] = PARTS[name]()
    store.write_text(json.dumps(report, indent=1))
    lines = [f"# Ensemble engine benchmark — {report['date']}", "",
             f"Machine: {machine}; numba threads: {report['threads']}. {SAMPLES} samples, I = (1, 2, 3); "
             f"medians of {REPEATS} runs, compile time excluded (reported separately).", "",
             "| method | fast, sample-steps/s | naive loop, sample-steps/s | speed-up | compile fast / naive, s |",
             "|---|---|---|---|---|"]
    for r in report["throughput"]:
        naive = f"{r['naive']:.2e}" if "naive" in r else "—"
        speedup = f"{r['speedup']:.1f}×" if "speedup" in r else "—"
        compile_naive = f"{r['compile_naive']:.1f}" if "compile_naive" in r else "—"
        lines.append(f"| {r['method']} | {r['fast']:.2e} | {naive} | {speedup} | {r['compile_fast']:.1f} / "
                     f"{compile_naive} |")
    if "roofline" in report:
        rows = report["roofline"]
        lines += ["", f"The Runge–Kutta steps against the FMA pipes: the machine's multiply/FMA peak, measured on "
                  f"{report['threads']} threads (eight independent FMA chains per sample, vectorised), is "
                  f"**{rows[0]['peak']:.2e} multiply-adds/s**; a step can go no faster than the peak divided by its "
                  f"multiplies and multiply-adds (counted from the tableau as the generated step computes them; "
                  f"the additions run on other pipes). The last column is what twice the measured rate (issue 15 asks "
                  f"rk8 for it) would need: above 100 % no code can reach it. Same run:", "",
                  "| method | multiplies + FMAs per sample-step | sample-steps/s | bound, sample-steps/s | "
                  "fraction of the bound | twice the rate, as a fraction of the bound |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['method']} | {r['multiplies']} | {r['rate']:.2e} | {r['bound']:.2e} | "
                  f"{r['fraction']:.0%} | {2 * r['fraction']:.0%} |" for r in rows]
    m = report["memory"]
    lines += ["", f"Peak memory of a {m['samples']:,}-sample growth measurement, `tumble.measure(..., axis=2, "
              f"method=\"rk4\")` ({m['n_steps']} steps, 257 norm probes, 3 flips, early stop, no trajectory; "
              f"rel. error {m['rel_error']:.1e}): **{m['peak_mib']:.0f} MiB** (target ≤ 1 GB).", "",
              "Warm 4096-sample growth scene, `tumble.measure` end to end (sampling, run, observers, fits, "
              "bootstrap, dataset):", ""]
    for r in report["warm_scene"]:
        lines.append(f"- method `{r['method']}` ({r['path']}): {r['seconds']:.3f} s (target < 1 s)")
    if "overhead" in report:
        lines += ["", "Fixed cost per call, one sample, one step, warm kernels (medians):", "",
                  "| call | µs per call |", "|---|---|"]
        lines += [f"| `{r['call']}` | {r['seconds'] * 1e6:.1f} |" for r in report["overhead"]]
    if "torque_paths" in report:
        lines += ["", f"A torque as a built-in profile against the same torque as a function ({SAMPLES} samples, "
                  "500 steps; the function is an indirect call, so the step does not vectorise):", "",
                  "| method | torque | sample-steps/s | compile (or cache load), s |", "|---|---|---|---|"]
        lines += [f"| {r['method']} | {r['torque']} | {r['rate']:.2e} | {r['compile']:.1f} |"
                  for r in report["torque_paths"]]
    (RESULTS / "engine.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
