"""The GPU path against its FP64 bound, tumble's CPU engine, JAX and diffrax (issue 28).

    python benchmarks/gpu.py [--samples N] [--steps S] [--repeats R] [--out DIR] [--fp64-peak FLOPS]
    NUMBA_ENABLE_CUDASIM=1 python benchmarks/gpu.py --quick   # smoke run on numba-cuda's simulator (no GPU)

One problem for every engine: the torque-free Euler equations in float64, I = (1, 2, 3), N spins near the
intermediate axis, ``w0 = (0, 1, 0) + 1e-3 * normal(3)`` (seed 0; the first flips come near t = 12, inside the default horizon),
``dt = 0.01`` and S steps (``t_end = S dt``); rk8 takes S/8 steps of 8 dt and splitting4 S/4 of 4 dt over the same
horizon (rk8's error at 4 dt, 4e-14, is round-off: no step of diffrax's Dopri8 could be matched to it). Parts, each timed as the median of ``--repeats`` runs after a first call (compile time,
reported apart), throughput in sample-steps per second:

1. ``gpu``: ``tumble.propagate(..., device="cuda")`` per method, with its host transfers (what a user gets), and
   the kernel alone (:func:`tumble.kernels.cuda.rigid_body.kernel` launched on device arrays, synchronised; checked to give
   propagate's bits);
2. ``agreement``: the GPU's final states against ``device="cpu"`` on the same spins, max |difference| / max |w|
   (target 1e-10);
3. ``scene``: a growth scene, ``tumble.measure(I, 2, method="rk4", flips=3, device=...)`` (probe norms, the
   growth fit, flips and the early stop in the kernel; the flip statistics and the reduction on the host), sample-steps per second on the GPU and on the CPU, and its
   rates against the CPU's on the same samples;
4. ``cpu``: ``tumble.propagate(..., device="cpu")`` on this machine's cores (N/10 samples, S/5 steps);
5. ``jax``: rk4 in ``jax.lax.fori_loop`` over the stacked (3, N) state, jit, float64, same GPU;
6. ``diffrax``: Tsit5 and Dopri8 with ``ConstantStepSize``, ``jax.vmap`` over the samples, same GPU, at the step
   count where their error against the exact solution equals tumble's rk4 / rk8 error;
7. ``models``: each model of ``tumble.models`` (:func:`_models`: gyrostat, heavy top with rk4 and splitting2,
   gravity gradient, damper) on the device, ``run_model_ensemble(..., device="cuda")`` with its host transfers (S
   steps of dt), against the CPU's model kernels on this machine's cores and their agreement;
8. ``closed_form``: ``tumble.exact.omega_on_device`` at one time (also the kernel alone on device arrays, the
   target 3e9 evaluations/s) and on a grid of :data:`CLOSED_FORM_TIMES` times, against ``tumble.exact.omega`` on
   the cores, and their agreement (about 1e-13);
9. ``maps``: the scans of issue 28's targets (:func:`part_maps`);
10. ``adaptive``: the error-controlled path, ``method="dop853"`` at rtol 1e-10, atol 1e-12 (:func:`part_adaptive`):
    ``tumble.integrate(..., device="cuda")`` of the models part's heavy top (N samples to ``--adaptive-t-end``, 100
    s; the CPU on N/10) and ``tumble.section(..., device="cuda")`` of benchmarks/sections.py's scene (2000 releases
    of its heavy top to T = 1000 s, g1 = 0 upward; both devices on the same releases), against ``device="cpu"``:
    compile time apart, medians, the ratio, and the agreement (final states; crossing counts and times);
11. the FP64 bound of each method (:data:`FP64_COUNTS`), against the chip's vector FP64 peak (:data:`FP64_PEAK`).

Every engine's error is measured against ``tumble.exact.omega`` on the first 4096 samples. A part whose package is
missing is reported as skipped, a part that raises as failed, and the run goes on; ``results/gpu.{json,md}`` are
written after every part, so a run cut short still leaves what it measured. Without a usable device the script
prints tumble's ``device 'cuda': ...`` line and exits 1, writing nothing.

numba-cuda 0.30.4 calls ``numpy.row_stack``, which numpy 2.5 removed; on a GPU (not on the simulator) with such a
numpy this script sets ``numpy.row_stack = numpy.vstack`` before numba.cuda is imported, and says so.
"""

import argparse
import importlib
import importlib.metadata
import json
import math
import os
import platform
import sys
import tempfile
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path

os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")  # JAX must not take the memory numba-cuda uses

import numpy as np
from numba.core import config as numba_config

RESULTS = Path(__file__).with_name("results")
MOMENTS = (1.0, 2.0, 3.0)
DT = 0.01
EPS = 1e-3
N_CHECK = 4096  # samples on which errors and agreement are measured
METHOD_NAMES = ("rk4", "rk8", "symplectic_euler", "splitting2", "splitting4")
LONG_STEP = {"rk8": 8, "splitting4": 4}  # steps of 8 dt / 4 dt over the same horizon (rk8 at 4 dt: 4e-14, round-off)

#: Vector (non-tensor-core) FP64 peak, FLOP/s (an FMA counts 2), by GPU name; the first entry whose key is in the
#: name wins, so the specific keys come first. Sources: NVIDIA H100 Tensor Core GPU datasheet (H100 SXM 34 TFLOPS
#: FP64, 67 FP64 tensor core; H100 PCIe 26 / 51; H100 NVL 30 / 60) and NVIDIA H200 Tensor Core GPU datasheet
#: (H200 SXM 34 / 67; H200 NVL 30 / 60); A100 datasheet (9.7 / 19.5). ``--fp64-peak`` overrides it.
FP64_PEAK = (("H100 PCIe", 26e12), ("H100 NVL", 30e12), ("H200 NVL", 30e12), ("H100", 34e12), ("H200", 34e12),
             ("A100", 9.7e12))

#: FP64 lanes per SM by compute capability (a cross-check of the table: SMs x lanes x 2 x clock).
FP64_LANES = {(9, 0): 64, (8, 0): 32, (7, 0): 32, (6, 0): 32}

# FP64 arithmetic per sample-step of the splittings, counted from the code the device runs (tumble/kernels/
# steppers.py and trig.py), every multiply followed by an add contracted into an FMA as NVVM does by default:
#   one sub-flow, rotate_about: theta = w_a tau (1 MUL; tau = fraction h is loop-invariant, not counted);
#     sincos(theta) (trig.py): quadrant q = floor(x 2/pi + 1/2) 1 FMA; Cody-Waite r1 = fma(-q, P1, x), q P2,
#     fma(q, P2, -p2), two TwoSums (6 ADD each), (t - p2_err) - q P3: 3 FMA, 1 MUL, 13 ADD; sin polynomial
#     z, v, 4 FMA (ps), 0.5 y1, 3 FMA, 1 ADD; cos polynomial w, 5 FMA, w w, w w (...), 0.5 z, y0 y1, 1 FMA,
#     5 ADD; quadrant m = q - 4 floor(q / 4): 1 MUL, 1 FMA  ->  18 FMA, 10 MUL, 19 ADD;
#     rotate: (s r_cb) wc, (s r_bc) wb, 2 FMA  ->  2 FMA, 4 MUL;
#   per sub-flow: 20 FMA, 15 MUL, 19 ADD (54 instructions, 94 FLOPs);
#   the projection onto |L|^2 (project_l_squared): l_squared 3 MUL + 1 MUL + 2 FMA, target - now, target now,
#     sqrt, now + sqrt, a division, w + w d x 3  ->  5 FMA, 5 MUL, 2 ADD, 1 DIV, 1 SQRT.
# Not counted: 2 floors, ~6 compares and the selects of sincos, 1 compare of the projection (which also take FP64
# issue slots on the GPU), and the division and square root are counted as one instruction each (on the GPU each
# is a reciprocal estimate and a few FMAs): the true instruction count is higher, so the bound below is higher
# than what can be reached and the fraction reported is a lower estimate. The totals (multiplies incl. FMAs 28 +
# 6 + 1 per sub-flow, additions incl. FMAs 37 + 2) were checked against the CPU's LLVM IR of the same functions
# (fmul + llvm.fma, fadd + fsub + llvm.fma); gpu.py --check-counts repeats that check.
SUBFLOW = dict(fma=20, mul=15, add=19, div=0, sqrt=0)
PROJECTION = dict(fma=5, mul=5, add=2, div=1, sqrt=1)


def fp64_counts(method):
    """FP64 arithmetic of one torque-free sample-step of ``method``: FMAs, lone multiplies, lone additions,
    divisions and square roots, the instructions (each of those one issue slot of an FP64 lane) and the FLOPs
    (an FMA 2, the others 1), with how they were counted."""
    from tumble.kernels import tableaux
    from tumble.kernels.steps.codegen import multiplies_per_sample_step
    from tumble.kernels.loops.methods import METHODS

    coefficients = METHODS[method].coefficients
    if isinstance(coefficients, tableaux.ButcherTableau):
        # codegen.combination: base + ((c0 h) k0 + (c1 h) k1 + ...) per component and stage/final sum: the first
        # term a MUL (an FMA when it is the only one), each further term an FMA, the outer add an ADD; the rate
        # a1 w2 w3 is 2 MUL per component and stage (multiplies_per_sample_step counts all the multiplies).
        terms = [int(np.count_nonzero(row)) for row in coefficients.A] + [int(np.count_nonzero(coefficients.b))]
        multiplies = int(multiplies_per_sample_step(coefficients))
        additions = 3 * sum(terms)
        fma = 3 * sum(n if n <= 1 else n - 1 for n in terms)
        counts = dict(fma=fma, mul=multiplies - fma, add=additions - fma, div=0, sqrt=0,
                      how=f"tableau: {multiplies} multiplies (multiplies_per_sample_step) and {additions} additions, "
                          f"{fma} of them fused")
    else:
        subflows = len(coefficients.without_torque().flows)
        counts = {k: subflows * SUBFLOW[k] + PROJECTION[k] for k in SUBFLOW}
        counts["how"] = f"{subflows} exact sub-flows x (sincos + rotation) + the |L|^2 projection, from the code"
    counts["instructions"] = sum(counts[k] for k in ("fma", "mul", "add", "div", "sqrt"))
    counts["flops"] = 2 * counts["fma"] + sum(counts[k] for k in ("mul", "add", "div", "sqrt"))
    return counts


def check_counts():
    """The splitting counts above against the CPU's LLVM IR of the same functions (multiplies incl. FMAs,
    additions incl. FMAs): returns a list of mismatches (empty when they agree)."""
    import re

    import numba

    from tumble.kernels.steps.steppers import project_l_squared, rotate

    body = np.ones(12)

    @numba.njit
    def subflow(tau, w1, w2, w3, b):  # rotate_about's branch for flow 1 (each branch is the same arithmetic)
        w2, w3 = rotate(w1 * tau, w2, w3, b[9], b[11])
        return w1, w2, w3

    @numba.njit
    def projection(w1, w2, w3, target, b):
        return project_l_squared(w1, w2, w3, target, b)

    subflow(0.1, 1.0, 2.0, 3.0, body)
    projection(1.0, 2.0, 3.0, 4.0, body)
    problems = []
    for label, fn, counted in (("sub-flow", subflow, SUBFLOW), ("projection", projection, PROJECTION)):
        ir = "\n".join(fn.inspect_llvm().values())
        defined = [d for d in ir.split("\ndefine ")[1:] if "cpython" not in d.split("(")[0]]
        text = defined[0]
        fmas = len(re.findall(r"call [^\n]*@llvm\.fma\.f64\(", text))
        muls = len(re.findall(r"= fmul ", text)) + fmas
        adds = len(re.findall(r"= f(?:add|sub) ", text)) + fmas
        want = (counted["fma"] + counted["mul"], counted["fma"] + counted["add"])
        print(f"  {label}: LLVM IR {muls} multiplies, {adds} additions (FMAs in both); counted {want[0]}, "
              f"{want[1]}", flush=True)
        if (muls, adds) != want:
            problems.append(f"{label}: IR {muls} multiplies / {adds} additions, counted {want[0]} / {want[1]}")
    return problems


# --------------------------------------------------------------------------------------------------------------
# set-up


def versions():
    out = {"python": platform.python_version()}
    for name in ("numpy", "numba", "numba-cuda", "jax", "jaxlib", "diffrax", "scipy"):
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def patch_numpy():
    """numpy.row_stack for numba-cuda 0.30.4 on numpy >= 2.5, on a GPU only (before numba.cuda is imported)."""
    if numba_config.ENABLE_CUDASIM or hasattr(np, "row_stack"):
        return False
    np.row_stack = np.vstack
    print(f"numpy {np.__version__} has no row_stack, which numba-cuda calls: set numpy.row_stack = numpy.vstack "
          "for this run", flush=True)
    return True


def gpu_info(override):
    from numba import cuda

    if numba_config.ENABLE_CUDASIM:
        return dict(name="numba-cuda simulator (no GPU)", simulator=True, fp64_peak=override or 34e12,
                    peak_source="--fp64-peak" if override else "placeholder (H100 SXM figure; simulator)")
    device = cuda.get_current_device()
    name = device.name.decode() if isinstance(device.name, bytes) else str(device.name)
    info = dict(name=name, simulator=False, compute_capability=list(device.compute_capability))
    try:
        sms, clock_khz = device.MULTIPROCESSOR_COUNT, device.CLOCK_RATE
        lanes = FP64_LANES.get(tuple(device.compute_capability))
        info.update(sms=sms, clock_ghz=clock_khz / 1e6)
        if lanes:
            info["fp64_peak_from_attributes"] = sms * lanes * 2 * clock_khz * 1e3
    except Exception as error:  # noqa: BLE001 (a cross-check only)
        info["attributes_error"] = repr(error)
    peak = next((value for key, value in FP64_PEAK if key.lower() in name.lower()), None)
    if override:
        info.update(fp64_peak=override, peak_source="--fp64-peak")
    elif peak:
        info.update(fp64_peak=peak, peak_source="datasheet table (FP64_PEAK)")
    elif "fp64_peak_from_attributes" in info:
        info.update(fp64_peak=info["fp64_peak_from_attributes"], peak_source="SMs x FP64 lanes x 2 x clock")
    else:
        info.update(fp64_peak=None, peak_source="unknown GPU: pass --fp64-peak")
    return info


class Problem:
    """The spins, the step plan of each method and the exact final states of the first N_CHECK samples."""

    def __init__(self, samples, steps):
        import tumble

        rng = np.random.default_rng(0)
        self.samples, self.steps = samples, steps
        self.w0 = np.array([0.0, 1.0, 0.0]) + EPS * rng.normal(size=(samples, 3))
        self.t_end = steps * DT
        self.check = min(samples, N_CHECK)
        self.exact = tumble.exact.omega(MOMENTS, self.w0[:self.check], self.t_end)

    def plan(self, method, steps=None):
        """(steps, dt) of ``method`` over S = ``steps`` base steps (default the problem's)."""
        steps = self.steps if steps is None else steps
        factor = LONG_STEP.get(method, 1)
        n = max(1, steps // factor)
        return n, steps * DT / n

    def error(self, w):
        """max |w - exact| / max |exact| over the first N_CHECK samples."""
        w = np.asarray(w)[:self.check]
        return float(np.max(np.abs(w - self.exact)) / np.max(np.abs(self.exact)))


def timed(fn, repeats):
    """(seconds of the first call, median seconds of ``repeats`` further calls, the first call's result)."""
    import timing  # benchmarks/timing.py (the script's folder is on sys.path)

    started = time.perf_counter()
    result = fn()
    first = time.perf_counter() - started
    return first, timing.median_seconds(fn, repeats), result


# --------------------------------------------------------------------------------------------------------------
# parts


def part_gpu(ctx):
    """tumble on the device: propagate with host transfers, and the kernel alone on device arrays."""
    import tumble
    from numba import cuda

    from tumble.kernels import device_kernels
    from tumble.kernels.loops.methods import METHODS, from_kernel_frame, kernel_frame

    device = device_kernels()
    p = ctx["problem"]
    moments = np.array(MOMENTS)
    rows = []
    ctx["gpu_states"] = {}
    for name in METHOD_NAMES:
        n_steps, dt = p.plan(name)
        t_end = n_steps * dt

        def call(name=name, dt=dt, t_end=t_end):
            return tumble.propagate(MOMENTS, p.w0, t_end, dt, method=name, device="cuda")

        first, seconds, out = timed(call, ctx["repeats"])
        row = dict(method=name, samples=p.samples, steps=n_steps, dt=dt, first_call_s=first,
                   seconds_with_transfers=seconds, rate_with_transfers=p.samples * n_steps / seconds,
                   error=p.error(out))
        ctx["gpu_states"][name] = out[:p.check].copy()
        # the kernel alone, as tumble.kernels.cuda.rigid_body.run launches it, on arrays already on the device
        method = METHODS[name]
        kernel_w, constants, _, relabel = kernel_frame(method, np.ascontiguousarray(p.w0.T), moments, None, None)
        start = cuda.to_device(np.ascontiguousarray(kernel_w))
        w = cuda.device_array_like(start)
        saved = cuda.device_array((0, 3, 1))
        # one scene (its table's rows); no probes, flips, drift (after steps_taken: no early stop, drift limit or
        # torque) nor growth fit
        def table_row(*values):
            return cuda.to_device(np.array([values], dtype=float))

        def one(value, dtype=float):
            return cuda.to_device(np.array([value], dtype=dtype))

        scene_table = (cuda.to_device(np.zeros(0, dtype=np.int64)), table_row(*constants), 0.0, one(float(dt)),
                       one(int(n_steps), np.int64), one(0, np.int64))
        # axes, the transverse norm (column_rows, weight_rows, y_eq), probe steps, probes, flips, flip_count, drift
        # (as tumble.kernels.cuda.rigid_body.run_scenes passes them when none is asked for)
        observers = (one(0, np.int64), cuda.to_device(np.array([[1, 2]], dtype=np.int64)), table_row(1.0, 1.0),
                     cuda.to_device(np.zeros(3)), cuda.to_device(np.zeros((1, 0), dtype=np.int64)),
                     cuda.device_array((0, 1)), cuda.device_array((1, 0)), cuda.device_array(p.samples, dtype=np.int64),
                     cuda.device_array((0, 1)))
        no_fit = (one(0.0), 0, one(0.0), cuda.device_array((0, 1)), cuda.device_array(0, dtype=np.int64))
        status = cuda.device_array(p.samples, dtype=np.int8)
        steps_taken = cuda.device_array(p.samples, dtype=np.int64)
        threads = device.THREADS if p.samples >= device.THREADS else 32 * -(-p.samples // 32)
        launch = device.kernel(method, True)[-(-p.samples // threads), threads]
        times = []
        for _ in range(ctx["repeats"] + 1):
            w.copy_to_device(start)
            cuda.synchronize()
            started = time.perf_counter()
            launch(w, *scene_table, saved, *observers, status, steps_taken, one(0.0), 0, 0.0, 0,
                   table_row(0.0, 0.0, 0.0, 0.0), *no_fit)
            cuda.synchronize()
            times.append(time.perf_counter() - started)
        kernel_seconds = float(np.median(times[1:]))
        final = from_kernel_frame(relabel, w.copy_to_host()).T
        row.update(seconds_kernel=kernel_seconds, rate_kernel=p.samples * n_steps / kernel_seconds,
                   kernel_equals_propagate=bool(np.array_equal(final, out)),
                   threads_per_block=threads)
        rows.append(row)
        print(f"  gpu {name}: {row['rate_kernel']:.3e} sample-steps/s kernel alone, {row['rate_with_transfers']:.3e}"
              f" with transfers (first call {first:.1f} s), error {row['error']:.1e}", flush=True)
    return dict(rows=rows)


def part_agreement(ctx):
    """The GPU's final states against device='cpu' on the same spins and steps."""
    import tumble

    if not ctx.get("gpu_states"):
        return dict(skipped="the gpu part did not run")
    p = ctx["problem"]
    rows = []
    for name, gpu in ctx["gpu_states"].items():
        n_steps, dt = p.plan(name)
        cpu = tumble.propagate(MOMENTS, p.w0[:p.check], n_steps * dt, dt, method=name, device="cpu")
        diff = float(np.max(np.abs(gpu - cpu)) / np.max(np.abs(cpu)))
        rows.append(dict(method=name, samples=p.check, steps=n_steps, max_rel_difference=diff, met=diff <= 1e-10,
                         bitwise=bool(np.array_equal(gpu, cpu))))
        print(f"  agreement {name}: max |gpu - cpu| / max |w| = {diff:.1e}", flush=True)
    return dict(rows=rows, target=1e-10)


def part_cpu(ctx):
    """tumble's CPU engine, same problem, fewer samples and steps (throughput is per sample-step)."""
    import numba

    import tumble

    p = ctx["problem"]
    samples, steps = ctx["cpu_samples"], ctx["cpu_steps"]
    w0 = p.w0[:samples]
    rows = []
    for name in METHOD_NAMES:
        n_steps, dt = p.plan(name, steps)

        def call(name=name, dt=dt, n_steps=n_steps):
            return tumble.propagate(MOMENTS, w0, n_steps * dt, dt, method=name, device="cpu")

        first, seconds, _ = timed(call, ctx["repeats"])
        rows.append(dict(method=name, samples=samples, steps=n_steps, dt=dt, first_call_s=first, seconds=seconds,
                         rate=samples * n_steps / seconds))
        print(f"  cpu {name}: {rows[-1]['rate']:.3e} sample-steps/s ({samples} x {n_steps}, first call "
              f"{first:.1f} s)", flush=True)
    return dict(rows=rows, threads=numba.get_num_threads())


def _jax():
    """jax with float64 on, and its first device if that is a GPU; else the reason to skip."""
    try:
        import jax
    except ImportError as error:
        return None, f"jax is not importable ({error})"
    jax.config.update("jax_enable_x64", True)
    device = jax.devices()[0]
    if device.platform != "gpu":
        return None, f"JAX has no GPU backend here (its first device is {device.platform})"
    return jax, None


def _rates(jnp):
    i1, i2, i3 = MOMENTS
    a1, a2, a3 = (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3

    def rate(w):  # w of shape (3, ...)
        return jnp.stack([a1 * w[1] * w[2], a2 * w[2] * w[0], a3 * w[0] * w[1]])

    return rate


def part_jax(ctx):
    """rk4 in jax.lax.fori_loop over the stacked (3, N) state, jit, float64."""
    jax, reason = _jax()
    if jax is None:
        return dict(skipped=reason)
    import jax.numpy as jnp

    p = ctx["problem"]
    rate = _rates(jnp)
    n_steps, dt = p.plan("rk4")

    def step(_, w):
        k1 = rate(w)
        k2 = rate(w + (0.5 * dt) * k1)
        k3 = rate(w + (0.5 * dt) * k2)
        k4 = rate(w + dt * k3)
        return w + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    solve = jax.jit(lambda w: jax.lax.fori_loop(0, n_steps, step, w))
    w0 = jax.device_put(jnp.asarray(np.ascontiguousarray(p.w0.T)))
    first, seconds, out = timed(lambda: solve(w0).block_until_ready(), ctx["repeats"])
    row = dict(method="rk4", samples=p.samples, steps=n_steps, dt=dt, first_call_s=first, seconds=seconds,
               rate=p.samples * n_steps / seconds, error=p.error(np.asarray(out).T),
               device=str(jax.devices()[0].device_kind), dtype=str(out.dtype))
    print(f"  jax rk4: {row['rate']:.3e} sample-steps/s, error {row['error']:.1e}", flush=True)
    return dict(rows=[row])


def part_diffrax(ctx):
    """Tsit5 and Dopri8 with a constant step, vmapped over the samples, at tumble rk4's / rk8's error."""
    jax, reason = _jax()
    if jax is None:
        return dict(skipped=reason)
    try:
        import diffrax
    except ImportError as error:
        return dict(skipped=f"diffrax is not importable ({error})")
    import jax.numpy as jnp

    p = ctx["problem"]
    gpu = {r["method"]: r for r in ctx["report"]["parts"].get("gpu", {}).get("rows", [])}
    if not gpu:
        return dict(skipped="the gpu part did not run (diffrax is matched to its errors)")
    rate = _rates(jnp)
    term = diffrax.ODETerm(lambda t, y, args: rate(y))
    w0 = jax.device_put(jnp.asarray(p.w0))
    rows = []
    for solver_name, peer in (("Tsit5", "rk4"), ("Dopri8", "rk8")):
        solver = getattr(diffrax, solver_name)()
        target = gpu[peer]["error"]
        ladder = sorted({max(2, int(round(p.steps * 2.0 ** k))) for k in range(-5, 3)})
        max_steps = int(ladder[-1] * 1.01) + 16

        def one(y0, dt, solver=solver, max_steps=max_steps):
            sol = diffrax.diffeqsolve(term, solver, t0=0.0, t1=p.t_end, dt0=dt, y0=y0,
                                      stepsize_controller=diffrax.ConstantStepSize(),
                                      saveat=diffrax.SaveAt(t1=True), max_steps=max_steps)
            return sol.ys[-1]

        solve = jax.jit(jax.vmap(one, in_axes=(0, None)))
        started = time.perf_counter()
        errors = {}
        for n in ladder:
            errors[n] = p.error(np.asarray(solve(w0[:p.check], p.t_end / n)))
        search_s = time.perf_counter() - started
        n_star, note = _equal_error_steps(errors, target)
        dt = p.t_end / n_star
        first, seconds, out = timed(lambda dt=dt: solve(w0, dt).block_until_ready(), ctx["repeats"])
        row = dict(method=solver_name, peer=peer, peer_error=target, samples=p.samples, steps=n_star, dt=dt,
                   ladder={str(k): v for k, v in errors.items()}, search_s=search_s, note=note, first_call_s=first,
                   seconds=seconds, rate=p.samples * n_star / seconds, error=p.error(np.asarray(out)),
                   dtype=str(out.dtype))
        rows.append(row)
        print(f"  diffrax {solver_name}: {n_star} steps for tumble {peer}'s error {target:.1e} ({note}): "
              f"{row['rate']:.3e} sample-steps/s, error {row['error']:.1e}", flush=True)
    return dict(rows=rows)


def _equal_error_steps(errors, target):
    """The fewest steps whose error reaches ``target``, interpolated in log-log between the ladder's points."""
    ns = sorted(errors)
    below = [n for n in ns if errors[n] <= target]
    if not below:
        return ns[-1], f"does not reach it; its smallest error {errors[ns[-1]]:.1e} at {ns[-1]} steps"
    n_hi = below[0]
    above = [n for n in ns if n < n_hi]
    if not above:
        return n_hi, "reached at the ladder's fewest steps"
    n_lo = above[-1]
    e_lo, e_hi = errors[n_lo], errors[n_hi]
    if not (e_lo > e_hi > 0):
        return n_hi, "ladder not monotone there; its first step count at or below the error"
    slope = math.log(e_hi / e_lo) / math.log(n_hi / n_lo)
    n = n_lo * (target / e_lo) ** (1.0 / slope)
    return int(min(n_hi, max(n_lo + 1, math.ceil(n)))), f"interpolated between {n_lo} and {n_hi} steps"


def part_scene(ctx):
    """A growth scene on the device and on the CPU: ``tumble.measure`` about the intermediate axis with rk4 (probe
    norms, the growth fit in registers, 3 flips and the early stop in the kernel; the flip statistics and the scene's
    reduction on the host), its sample-steps per second, and its rate against the CPU's on the same samples (kinds
    and statuses equal, rates within 1e-10)."""
    import tumble

    repeats = ctx["repeats"]
    rows = []
    for device, samples in (("cuda", ctx["scene_samples"]), ("cpu", ctx["cpu_scene_samples"])):
        def call(device=device, samples=samples):
            return tumble.measure(MOMENTS, 2, samples=samples, method="rk4", flips=3, device=device)

        first, seconds, ds = timed(call, repeats)
        steps = int(ds.sample_steps_computed)
        rows.append(dict(device=device, samples=samples, first_call_s=first, seconds=seconds, sample_steps=steps,
                         rate=steps / seconds, measured=float(ds.rate), theory=float(ds.rate_theory)))
        print(f"  scene {device}: {samples} samples in {seconds:.3f} s, {steps / seconds:.3e} sample-steps/s, rate "
              f"{float(ds.rate):.6f} (theory {float(ds.rate_theory):.6f})", flush=True)
    n = ctx["cpu_scene_samples"]
    cpu = tumble.measure(MOMENTS, 2, samples=n, method="rk4", flips=3, device="cpu")
    gpu = tumble.measure(MOMENTS, 2, samples=n, method="rk4", flips=3, device="cuda")
    rel = float(np.nanmax(np.abs(gpu.sample_rate.values / cpu.sample_rate.values - 1.0)))
    same = bool(np.array_equal(gpu.sample_status.values, cpu.sample_status.values)) and gpu.kind.item() == cpu.kind.item()
    print(f"  scene agreement on {n} samples: max per-sample rate difference {rel:.1e}, kinds and statuses equal: "
          f"{same}", flush=True)
    return dict(rows=rows, agreement=dict(samples=n, max_rel_rate_difference=rel, statuses_equal=same,
                                          met=same and rel <= 1e-10))


def _models():
    """(label, model, spin axis, method) of the models part: each model of tumble.models once, I = (1, 2, 3)."""
    from tumble.physics import models

    return (("gyrostat", models.Gyrostat(MOMENTS, (0.0, 0.2, 0.0)), 2, "rk4"),
            ("heavy top", models.HeavyTop((2.0, 2.5, 3.0), 0.5), 3, "rk4"),
            ("heavy top", models.HeavyTop((2.0, 2.5, 3.0), 0.5), 3, "splitting2"),
            ("gravity gradient", models.GravityGradient(MOMENTS, 0.1), 2, "rk4"),
            ("damper", models.Damper(MOMENTS, 0.2, 0.05), 3, "rk4"))


def part_models(ctx):
    """The models on the device (run_model_ensemble, final state, with its host transfers) against the CPU's model
    kernels on this machine's cores, and their agreement on the first N_CHECK samples."""
    from tumble.engine.model_ensemble import run_model_ensemble
    from tumble.engine.sampling import perturbed_states

    p = ctx["problem"]
    rows = []
    for label, model, axis, method in _models():
        y0 = perturbed_states(model, axis, 1.0, EPS, p.samples, seed=0)
        cpu_y0 = y0[:ctx["cpu_samples"]]
        n_steps, cpu_steps = p.steps, ctx["cpu_steps"]

        def gpu(y0=y0, model=model, axis=axis, method=method):
            return run_model_ensemble(model, y0, n_steps * DT, DT, method=method, axis=axis, spin=1.0,
                                      drift_limit=0.0, device="cuda", chunk=len(y0)).final

        def cpu(model=model, axis=axis, method=method):
            return run_model_ensemble(model, cpu_y0, cpu_steps * DT, DT, method=method, axis=axis, spin=1.0,
                                      drift_limit=0.0).final

        first, seconds, out = timed(gpu, ctx["repeats"])
        cpu_first, cpu_seconds, _ = timed(cpu, ctx["repeats"])
        check = run_model_ensemble(model, y0[:p.check], n_steps * DT, DT, method=method, axis=axis, spin=1.0,
                                   drift_limit=0.0).final
        diff = float(np.max(np.abs(out[:p.check] - check)) / np.max(np.abs(check)))
        row = dict(model=label, method=method, samples=p.samples, steps=n_steps, first_call_s=first,
                   seconds_with_transfers=seconds, rate_with_transfers=p.samples * n_steps / seconds,
                   cpu_samples=len(cpu_y0), cpu_steps=cpu_steps, cpu_rate=len(cpu_y0) * cpu_steps / cpu_seconds,
                   max_rel_difference=diff)
        row["speedup"] = row["rate_with_transfers"] / row["cpu_rate"]
        rows.append(row)
        print(f"  model {label} {method}: {row['rate_with_transfers']:.3e} sample-steps/s with transfers (first call "
              f"{first:.1f} s), cpu {row['cpu_rate']:.3e}, |gpu - cpu| / max |y| = {diff:.1e}", flush=True)
    return dict(rows=rows)


CLOSED_FORM_TIMES = 64  # times of the closed form's grid evaluation


def part_closed_form(ctx):
    """The closed form on the device, one thread per sample: at one time (the kernel alone on device arrays, and
    with transfers) and on a grid of CLOSED_FORM_TIMES times (with transfers), against the CPU's fused kernels
    (tumble.exact.omega) on this machine's cores, and their agreement."""
    import tumble
    from numba import cuda

    from tumble.kernels import device_closed_form
    from tumble.physics import exact

    kernels = device_closed_form()
    p = ctx["problem"]
    moments = np.array(MOMENTS)
    grid = np.linspace(0.0, p.t_end, CLOSED_FORM_TIMES)
    one = np.array([p.t_end])
    cpu_w = p.w0[:ctx["cpu_samples"]]
    rows = []
    for label, times in (("one time", one), (f"grid of {CLOSED_FORM_TIMES} times", grid)):
        first, seconds, out = timed(lambda times=times: exact.omega_on_device(moments, p.w0, times), ctx["repeats"])
        cpu_first, cpu_seconds, _ = timed(lambda times=times: tumble.exact.omega(MOMENTS, cpu_w, times),
                                          ctx["repeats"])
        check = tumble.exact.omega(MOMENTS, p.w0[:p.check], times)
        diff = float(np.max(np.abs(out[:p.check] - check)) / np.max(np.abs(check)))
        evaluations = p.samples * len(times)
        row = dict(evaluation=label, samples=p.samples, times=len(times), first_call_s=first,
                   seconds_with_transfers=seconds, rate_with_transfers=evaluations / seconds,
                   cpu_samples=len(cpu_w), cpu_rate=len(cpu_w) * len(times) / cpu_seconds, max_rel_difference=diff)
        if len(times) == 1:  # the kernel alone, as cuda_exact.omega_at launches it, on arrays already on the device
            w = cuda.to_device(np.ascontiguousarray(p.w0))
            result = cuda.device_array((p.samples, 3))
            flags = cuda.device_array(p.samples, dtype=np.int8)
            threads = kernels.THREADS
            launch = kernels._omega_at_kernel[-(-p.samples // threads), threads]
            spans = []
            for _ in range(ctx["repeats"] + 1):
                cuda.synchronize()
                started = time.perf_counter()
                launch(*MOMENTS, w, float(p.t_end), result, flags)
                cuda.synchronize()
                spans.append(time.perf_counter() - started)
            row["rate_kernel"] = p.samples / float(np.median(spans[1:]))
            row["kernel_equals_call"] = bool(np.array_equal(result.copy_to_host(), out[:, 0]))
        row["speedup"] = row["rate_with_transfers"] / row["cpu_rate"]
        rows.append(row)
        print(f"  closed form, {label}: {row['rate_with_transfers']:.3e} evaluations/s with transfers"
              + (f", {row['rate_kernel']:.3e} kernel alone" if "rate_kernel" in row else "")
              + f" (first call {first:.1f} s), cpu {row['cpu_rate']:.3e}, |gpu - cpu| / max |w| = {diff:.1e}",
              flush=True)
    return dict(rows=rows)


def part_maps(ctx):
    """The scans of issue 28's targets, in one process, warm, device against this machine's CPU cores: the bundled
    ``stability_map`` study (``run_study``, closed form), the 100 x 100 x 3 map (``tumble.scan`` of
    ``inertia_triangle(100)``, 256 samples, closed form) and a fixed-step map (rk4, many scenes a launch) of
    ``inertia_triangle(20)``; the two smaller maps on the CPU too (the large one takes 22 s on 16 cores: left out to
    stay in the time budget)."""
    import tumble
    from tumble.measure.scans import inertia_triangle

    quick = ctx["report"]["quick"]
    repeats = 1 if quick else 3
    rows = []

    def add(label, call, devices=("cuda", "cpu")):
        for device in devices:
            first, seconds, ds = timed(lambda: call(device), repeats)
            rows.append(dict(map=label, device=device, first_call_s=first, seconds=seconds, scenes=int(ds.rate.size)))
            print(f"  map {label} on {device}: {seconds:.3f} s ({int(ds.rate.size)} scenes; first call {first:.1f} s)",
                  flush=True)

    add("bundled stability_map", lambda device: tumble.run_study(
        "stability_map", device=device, overrides={"perturbation.samples": 8, "scan.triangle": 2} if quick else None))
    large = inertia_triangle(3 if quick else 100)[0]
    add("100 x 100 x 3 closed form" if not quick else "3 x 3 x 3 closed form",
        lambda device: tumble.scan(large, samples=8 if quick else 256, flips=0, device=device), devices=("cuda",))
    small = inertia_triangle(2 if quick else 20)[0]
    add("20 x 20 x 3 rk4" if not quick else "2 x 2 x 3 rk4", lambda device: tumble.scan(
        small, samples=4 if quick else 256, flips=0, method="rk4", device=device, dt=0.05 if quick else None))
    return dict(rows=rows)


#: The error-controlled part's tolerance (the library's defaults, the sections benchmark's).
ADAPTIVE_RTOL, ADAPTIVE_ATOL = 1e-10, 1e-12
#: Seconds of timed runs per figure of the error-controlled part, after its first call: fewer than --repeats runs when
#: one is slow (the part stays within about 90 s on a GPU).
ADAPTIVE_TIMED_S = 12.0
#: Two sections' crossings "agree" where their times are within this (s): sections.py measures tumble's crossing
#: times within 1e-8 s of SciPy's at rtol 2.3e-14 over 100 s.
AGREE_DT = 1e-6


def timed_capped(fn, repeats, cap):
    """As :func:`timed`, but the timed runs stop when the next would take their total past ``cap`` seconds, judged by
    those before it (the first call for the first): (first call s, median s, the first call's result, timed runs).
    A first call longer than ``cap`` is the figure itself (0 timed runs: the compile was a call before it)."""
    started = time.perf_counter()
    result = fn()
    first = time.perf_counter() - started
    times = []
    while len(times) < repeats and sum(times) + (float(np.median(times)) if times else first) <= cap:
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return first, float(np.median(times)) if times else first, result, len(times)


def _crossing_agreement(a, b, horizon):
    """Two sections of the same releases (``a`` the CPU's): the crossing counts; the releases whose crossings agree
    all through (the same count, every time within :data:`AGREE_DT`); and over the first ``horizon`` s (as
    benchmarks/sections.py compares them; later a chaotic orbit's crossings part for any change of rounding), the
    releases with the same count there and, on those, the largest time and state differences, crossing by crossing."""
    ca, cb = a["count"].values, b["count"].values
    k = min(a.time.shape[1], b.time.shape[1])
    ta, tb = a.time.values[:, :k], b.time.values[:, :k]
    dt = np.abs(ta - tb)  # NaN past either count
    ds = np.max(np.abs(a.state.values[:, :k] - b.state.values[:, :k]), axis=2)
    scale = max(float(np.nanmax(np.abs(a.state.values), initial=0.0)), 1e-300)
    same = ca == cb
    through = same & np.all(np.isnan(dt) | (dt <= AGREE_DT), axis=1)
    early_a, early_b = ta < horizon, tb < horizon  # False past a count
    aligned = early_a.sum(axis=1) == early_b.sum(axis=1)
    early = early_a & early_b & aligned[:, None]
    per_release = np.max(np.where(early, dt, 0.0), axis=1)[aligned]
    return dict(samples=int(len(ca)), counts_equal=int(same.sum()),
                max_count_difference=int(np.abs(ca - cb).max(initial=0)), agree_dt=AGREE_DT,
                agree_throughout=int(through.sum()),
                statuses_equal=bool(np.array_equal(a["status"].values, b["status"].values)), compared_s=float(horizon),
                early_counts_equal=int(aligned.sum()), max_dt_early=float(np.max(dt[early], initial=0.0)),
                median_release_max_dt_early=float(np.median(per_release)) if len(per_release) else 0.0,
                max_rel_state_difference_early=float(np.max(ds[early], initial=0.0)) / scale)


def part_adaptive(ctx):
    """The error-controlled path on the device (``method="dop853"``, rtol 1e-10, atol 1e-12; one thread per sample
    running the CPU's per-sample loop, with its host transfers) against the CPU (the built-in models' vectorised
    blocks on this machine's cores): ``tumble.integrate`` of the models part's heavy top (N samples near its steady
    spin, to ``--adaptive-t-end``; the CPU on N/10 of them), and ``tumble.section`` of the sections benchmark's
    asymmetric heavy top (``benchmarks/sections.py``: 2000 releases to T = 1000 s, the surface g1 = 0 upward), both
    devices on the same releases. Compile time (a first call on 2 samples, per device) apart; agreement: the final
    states (integrate), the crossing counts and times (section; over the first 100 s, as sections.py compares them,
    with the spread between the CPU at rtol 1e-10 and 1e-11 beside it: the releases include chaotic orbits)."""
    import tumble
    from tumble.engine.sampling import perturbed_states
    from tumble.physics import models

    import sections as scene  # benchmarks/sections.py: its heavy top and releases

    p = ctx["problem"]
    repeats, cap = ctx["repeats"], ADAPTIVE_TIMED_S
    tol = dict(method="dop853", rtol=ADAPTIVE_RTOL, atol=ADAPTIVE_ATOL)
    top = models.HeavyTop((2.0, 2.5, 3.0), 0.5)  # the models part's heavy top
    section_top = models.HeavyTop(scene.MOMENTS, scene.MGL, centre=scene.CENTRE)
    compile_s = {}
    for device in ("cuda", "cpu"):  # both runs below share one kernel per device (rate and component surface)
        started = time.perf_counter()
        tumble.integrate(top, perturbed_states(top, 3, 1.0, EPS, 2, seed=0), 1.0, device=device, **tol)
        compile_s[device] = time.perf_counter() - started
        print(f"  adaptive: compile (first call on 2 samples) on {device}: {compile_s[device]:.1f} s", flush=True)
    rows = []

    # integrate: the final states of N samples
    t_end = ctx["adaptive_t_end"]
    y0 = perturbed_states(top, 3, 1.0, EPS, p.samples, seed=0)
    cpu_y0 = y0[:ctx["cpu_samples"]]
    first, seconds, gpu, runs = timed_capped(lambda: tumble.integrate(top, y0, t_end, device="cuda", **tol), repeats,
                                             cap)
    cpu_first, cpu_seconds, cpu, cpu_runs = timed_capped(
        lambda: tumble.integrate(top, cpu_y0, t_end, device="cpu", **tol), repeats, cap)
    steps, cpu_steps = int(gpu["steps"].sum()), int(cpu["steps"].sum())
    a, b = cpu["state"].values[:, -1], gpu["state"].values[:len(cpu_y0), -1]
    row = dict(run="integrate", model="heavy top (2, 2.5, 3), mgl 0.5, near its steady spin", samples=len(y0),
               t_end=t_end, rtol=ADAPTIVE_RTOL, atol=ADAPTIVE_ATOL, sample_steps=steps,
               rejected_steps=int(gpu["rejected_steps"].sum()), first_call_s=first, seconds_with_transfers=seconds,
               runs=runs, rate_with_transfers=steps / seconds, samples_per_s=len(y0) / seconds,
               not_ok=int(np.count_nonzero(gpu["status"].values)), cpu_samples=len(cpu_y0), cpu_sample_steps=cpu_steps,
               cpu_first_call_s=cpu_first, cpu_seconds=cpu_seconds, cpu_runs=cpu_runs, cpu_rate=cpu_steps / cpu_seconds,
               cpu_samples_per_s=len(cpu_y0) / cpu_seconds, cpu_not_ok=int(np.count_nonzero(cpu["status"].values)),
               agreement=dict(samples=len(cpu_y0), max_rel_difference=float(np.max(np.abs(a - b)) / np.max(np.abs(a))),
                              statuses_equal=bool(np.array_equal(cpu["status"].values,
                                                                 gpu["status"].values[:len(cpu_y0)])),
                              steps_equal=int(np.sum(cpu["steps"].values == gpu["steps"].values[:len(cpu_y0)]))))
    row["speedup"] = row["samples_per_s"] / row["cpu_samples_per_s"]  # time per sample, CPU over GPU
    rows.append(row)
    print(f"  adaptive integrate: {len(y0):,} samples to {t_end:g} s on the GPU in {seconds:.3g} s ({steps / seconds:.3e} "
          f"accepted sample-steps/s, first call {first:.2f} s), CPU {len(cpu_y0):,} in {cpu_seconds:.3g} s "
          f"({cpu_steps / cpu_seconds:.3e}): {row['speedup']:.3g}x per sample; final |gpu - cpu| / max |y| = "
          f"{row['agreement']['max_rel_difference']:.1e}", flush=True)

    # section: the sections benchmark's scene, the same releases on both
    elapsed = time.perf_counter() - ctx["began"]
    if elapsed > ctx["budget"]:
        rows.append(dict(run="section", skipped=f"time budget: {elapsed:.0f} s used of --budget {ctx['budget']:g}"))
        return dict(rows=rows, compile_s=compile_s)
    n, t_end = ctx["section_samples"], ctx["section_t_end"]
    releases = scene.releases(n)
    surface = ("g1", 0.0)

    def section(device, rtol=ADAPTIVE_RTOL):
        return tumble.section(section_top, releases, t_end, surface=surface, rtol=rtol, atol=ADAPTIVE_ATOL,
                              device=device)

    first, seconds, gpu, runs = timed_capped(lambda: section("cuda"), repeats, cap)
    cpu_first, cpu_seconds, cpu, cpu_runs = timed_capped(lambda: section("cpu"), repeats, cap)
    compared = min(scene.COMPARED, t_end)
    # the scale of "agree": the CPU against itself at a tenth of the tolerance
    spread = _crossing_agreement(cpu, section("cpu", rtol=ADAPTIVE_RTOL / 10), compared)
    steps, cpu_steps = int(gpu["steps"].sum()), int(cpu["steps"].sum())
    row = dict(run="section", model=f"heavy top {scene.MOMENTS}, mgl {scene.MGL}, centre {scene.CENTRE} "
                                    "(benchmarks/sections.py)", surface="g1 = 0, upward", samples=n, t_end=t_end,
               rtol=ADAPTIVE_RTOL, atol=ADAPTIVE_ATOL, crossings=int(gpu["count"].sum()), sample_steps=steps,
               rejected_steps=int(gpu["rejected_steps"].sum()), first_call_s=first, seconds_with_transfers=seconds,
               runs=runs, rate_with_transfers=steps / seconds, samples_per_s=n / seconds,
               not_ok=int(np.count_nonzero(gpu["status"].values)), cpu_samples=n, cpu_crossings=int(cpu["count"].sum()),
               cpu_sample_steps=cpu_steps, cpu_first_call_s=cpu_first, cpu_seconds=cpu_seconds, cpu_runs=cpu_runs,
               cpu_rate=cpu_steps / cpu_seconds, cpu_samples_per_s=n / cpu_seconds,
               cpu_not_ok=int(np.count_nonzero(cpu["status"].values)), speedup=cpu_seconds / seconds,
               agreement=_crossing_agreement(cpu, gpu, compared), cpu_tolerance_spread=spread)
    rows.append(row)
    agree = row["agreement"]
    print(f"  adaptive section: {n:,} releases to {t_end:g} s on the GPU in {seconds:.3g} s (first call {first:.2f} s), "
          f"CPU {cpu_seconds:.3g} s: {row['speedup']:.3g}x; crossings {row['crossings']:,} / {row['cpu_crossings']:,}, "
          f"counts equal on {agree['counts_equal']} of {n}, all crossings within {AGREE_DT:g} s on "
          f"{agree['agree_throughout']} (CPU rtol 1e-10 against 1e-11: {spread['agree_throughout']}); first {compared:g}"
          f" s: max |dt| {agree['max_dt_early']:.1e} s (CPU against itself: {spread['max_dt_early']:.1e} s)",
          flush=True)
    return dict(rows=rows, compile_s=compile_s)


PARTS = {"gpu": part_gpu, "agreement": part_agreement, "scene": part_scene, "cpu": part_cpu, "models": part_models,
         "closed_form": part_closed_form, "maps": part_maps, "adaptive": part_adaptive, "jax": part_jax,
         "diffrax": part_diffrax}


# --------------------------------------------------------------------------------------------------------------
# the report


def bound_rows(report):
    peak = report["gpu_info"].get("fp64_peak")
    gpu = {r["method"]: r for r in report["parts"].get("gpu", {}).get("rows", [])}
    rows = []
    for name in METHOD_NAMES:
        counts = fp64_counts(name)
        row = dict(method=name, **counts)
        if peak:
            row["bound"] = peak / 2 / counts["instructions"]  # an FP64 lane issues one FMA/MUL/ADD per cycle
        if peak and name in gpu:
            rate = gpu[name]["rate_kernel"]
            row.update(rate=rate, fraction=rate / row["bound"], flops_per_s=rate * counts["flops"],
                       fraction_of_peak_flops=rate * counts["flops"] / peak)
        rows.append(row)
    return rows


def targets(report):
    """Issue 28's targets: (text, status, measured)."""
    parts = report["parts"]
    gpu = {r["method"]: r for r in parts.get("gpu", {}).get("rows", [])}
    cpu = {r["method"]: r for r in parts.get("cpu", {}).get("rows", [])}
    bounds = {r["method"]: r for r in report.get("bound", [])}
    jax_rows = {r["method"]: r for r in parts.get("jax", {}).get("rows", [])}
    diffrax_rows = {r["method"]: r for r in parts.get("diffrax", {}).get("rows", [])}
    out = []
    smoke = report["quick"] or report["simulator"]

    def add(text, value, ok, measured):
        status = "not measured" if value is None else "smoke run: not judged" if smoke else "met" if ok else "missed"
        out.append(dict(target=text, status=status,
                        measured=measured if value is not None else "—"))

    rk4 = gpu.get("rk4")
    add("rk4 on the GPU >= 3e11 sample-steps/s (kernel alone)", rk4, rk4 and rk4["rate_kernel"] >= 3e11,
        rk4 and f"{rk4['rate_kernel']:.2e} (with transfers {rk4['rate_with_transfers']:.2e})")
    for name in METHOD_NAMES:
        b = bounds.get(name, {})
        add(f"{name} >= 80 % of its FP64 bound", b.get("fraction"), (b.get("fraction") or 0) >= 0.8,
            b.get("fraction") is not None and f"{b['fraction']:.0%} of {b['bound']:.2e}")
    speedups = [(n, gpu[n]["rate_kernel"] / cpu[n]["rate"], gpu[n]["rate_with_transfers"] / cpu[n]["rate"])
                for n in METHOD_NAMES if n in gpu and n in cpu]
    worst = min(speedups, key=lambda s: s[1]) if speedups else None
    add(">= 50x tumble's CPU engine on the same machine (every method, kernel alone)", worst,
        worst and worst[1] >= 50,
        worst and ", ".join(f"{n} {k:.3g}x ({t:.3g}x with transfers)" for n, k, t in speedups))
    scene = {r["device"]: r for r in parts.get("scene", {}).get("rows", [])}
    g, c = scene.get("cuda"), scene.get("cpu")
    add("a growth scene (tumble.measure, rk4, its fit in the kernel, flips, early stop) >= 2.5e11 sample-steps/s on "
        "the GPU", g,
        g and g["rate"] >= 2.5e11, g and f"{g['rate']:.2e}" + (f" ({c['rate']:.2e} on the CPU)" if c else ""))
    agree = parts.get("scene", {}).get("agreement")
    add("the growth scene: kinds and statuses equal the CPU's, rates within 1e-10", agree, agree and agree["met"],
        agree and f"{agree['max_rel_rate_difference']:.1e} on {agree['samples']} samples, statuses equal: "
                  f"{agree['statuses_equal']}")
    j = jax_rows.get("rk4")
    ratio = j and rk4 and rk4["rate_kernel"] / j["rate"]
    add(">= 30x JAX rk4 (same steps, same GPU)", ratio, ratio and ratio >= 30, ratio and f"{ratio:.1f}x")
    for solver, peer in (("Tsit5", "rk4"), ("Dopri8", "rk8")):
        d, g = diffrax_rows.get(solver), gpu.get(peer)
        ratio = d and g and horizon_seconds(d) / horizon_seconds(g)
        add(f">= 30x diffrax {solver} at tumble {peer}'s error (time per sample over the horizon)", ratio,
            ratio and ratio >= 30, ratio and f"{ratio:.1f}x ({d['steps']} steps against {g['steps']})")
    maps = {(r["map"], r["device"]): r for r in parts.get("maps", {}).get("rows", [])}
    for label, limit in (("bundled stability_map", 0.3), ("100 x 100 x 3 closed form", 2.0)):
        m = maps.get((label, "cuda"))
        add(f"the {label} map in <= {limit:g} s on the GPU (one process, warm)", m, m and m["seconds"] <= limit,
            m and f"{m['seconds']:.3f} s" + (f" ({maps[(label, 'cpu')]['seconds']:.3f} s on the CPU)"
                                              if (label, "cpu") in maps else ""))
    closed = {r["times"]: r for r in parts.get("closed_form", {}).get("rows", [])}.get(1)
    add("the closed form at one time >= 3e9 evaluations/s (kernel alone)", closed,
        closed and closed["rate_kernel"] >= 3e9,
        closed and f"{closed['rate_kernel']:.2e} (with transfers {closed['rate_with_transfers']:.2e})")
    return out


def _adaptive_markdown(part):
    """The error-controlled part's table and agreement lines (none when it did not run)."""
    rows = [r for r in part.get("rows", []) if "skipped" not in r]
    if not rows:
        return [f"- adaptive {r['run']} row: skipped: {r['skipped']}" for r in part.get("rows", [])]
    compile_s = part.get("compile_s", {})
    lines = ["", f"Error-controlled runs (`method=\"dop853\"`, rtol {rows[0]['rtol']:g}, atol {rows[0]['atol']:g}) on "
             "the device (one thread per sample running the CPU's per-sample loop, with host transfers) against the "
             "CPU (the models' vectorised blocks on this machine's cores). Compile (a first call on 2 samples, apart): "
             f"GPU {compile_s.get('cuda', float('nan')):.1f} s, CPU {compile_s.get('cpu', float('nan')):.1f} s. "
             "Medians of timed runs after a first call, at most about 12 s of them (their number, `runs`, in the json; 0: "
             "the first call's time); × CPU: the CPU's time per sample over the GPU's.", "",
             "| run | samples × horizon | GPU s (first call) | accepted sample-steps/s, GPU | CPU samples | "
             "CPU s (first call) | accepted sample-steps/s, CPU | × CPU |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        what = ("`tumble.integrate`, final state" if r["run"] == "integrate" else
                f"`tumble.section`, {r['surface']}") + f": {r['model']}"
        lines.append(f"| {what} | {r['samples']:,} × {r['t_end']:g} s | {r['seconds_with_transfers']:.3g} "
                     f"({r['first_call_s']:.3g}) | {r['rate_with_transfers']:.2e} | {r['cpu_samples']:,} | "
                     f"{r['cpu_seconds']:.3g} ({r['cpu_first_call_s']:.3g}) | {r['cpu_rate']:.2e} | "
                     f"{r['speedup']:.3g}× |")
    lines.append("")
    for r in rows:
        a = r["agreement"]
        stops = f"samples not ok: GPU {r['not_ok']}, CPU {r['cpu_not_ok']}"
        if r["run"] == "integrate":
            lines.append(f"- integrate, GPU against CPU on the first {a['samples']:,} samples: final states "
                         f"max |gpu − cpu| / max |y| = {a['max_rel_difference']:.1e}; statuses equal: "
                         f"{a['statuses_equal']}; the same accepted steps on {a['steps_equal']:,}; {stops}.")
        else:
            s = r["cpu_tolerance_spread"]
            lines.append(f"- section, GPU against CPU on the {a['samples']:,} releases: {r['crossings']:,} crossings "
                         f"against {r['cpu_crossings']:,}, the same count on {a['counts_equal']:,} releases (largest "
                         f"difference {a['max_count_difference']}), every crossing time within {a['agree_dt']:g} s on "
                         f"{a['agree_throughout']:,}; statuses equal: {a['statuses_equal']}; {stops}. Over the first "
                         f"{a['compared_s']:g} s: the same count on {a['early_counts_equal']:,}, on those crossing times "
                         f"max |Δt| = {a['max_dt_early']:.1e} s (median over releases "
                         f"{a['median_release_max_dt_early']:.1e} s), states {a['max_rel_state_difference_early']:.1e} "
                         f"of max |y|. For scale, the CPU at rtol {r['rtol']:g} against {r['rtol'] / 10:g}: the same "
                         f"count on {s['counts_equal']:,}, every time within {s['agree_dt']:g} s on "
                         f"{s['agree_throughout']:,}; over the first {s['compared_s']:g} s the same count on "
                         f"{s['early_counts_equal']:,}, max |Δt| = {s['max_dt_early']:.1e} s (median "
                         f"{s['median_release_max_dt_early']:.1e} s). The releases include chaotic orbits, whose "
                         "crossings part for any change of rounding.")
    lines += [f"- adaptive {r['run']} row: skipped: {r['skipped']}" for r in part.get("rows", []) if "skipped" in r]
    return lines


def _rate_or_dash(rate):
    return "—" if rate is None else f"{rate:.2e}"


def horizon_seconds(row):
    """Seconds per sample over the whole horizon at the row's own step count."""
    return row["steps"] / row.get("rate_kernel", row.get("rate"))


def write(report, out):
    report["bound"] = bound_rows(report)
    report["targets"] = targets(report)
    (out / "gpu.json").write_text(json.dumps(report, indent=1, default=str))
    (out / "gpu.md").write_text(markdown(report))


def markdown(report):
    info, parts = report["gpu_info"], report["parts"]
    p = report["problem"]
    lines = [f"# GPU benchmark (issue 28) — {report['date']}", ""]
    if info.get("simulator") or report["quick"]:
        lines += ["**SMOKE RUN" + (" on numba-cuda's simulator" if info.get("simulator") else "") +
                  " (--quick): the numbers are meaningless; it only shows that the script runs.**", ""]
    peak = info.get("fp64_peak")
    lines += [f"GPU: {info['name']}" + (f", compute capability {info['compute_capability']}, {info.get('sms')} SMs "
                                        f"at {info.get('clock_ghz', 0):.2f} GHz" if "compute_capability" in info else "")
              + (f"; FP64 vector peak {peak / 1e12:.1f} TFLOP/s ({info['peak_source']})" if peak else
                 f"; FP64 peak unknown ({info['peak_source']})")
              + (f"; from its attributes {info['fp64_peak_from_attributes'] / 1e12:.1f}"
                 if "fp64_peak_from_attributes" in info else "") + ".",
              f"CPU: {report['machine']}; load average {report['load_average']:.2f} at the start.",
              "Versions: " + ", ".join(f"{k} {v}" for k, v in report["versions"].items()) + "."
              + (" numpy.row_stack was set to numpy.vstack for numba-cuda." if report["row_stack_patched"] else ""),
              "",
              f"Problem: torque-free Euler equations, float64, I = (1, 2, 3), {p['samples']:,} spins "
              f"w0 = (0, 1, 0) + {EPS:g} normal(3) (near the intermediate axis; the first flips come near t = 12), "
              f"dt = {DT:g}, "
              f"{p['steps']} steps to t = {p['t_end']:g} (rk8: {max(1, p['steps'] // 8)} steps of {p['t_end'] / max(1, p['steps'] // 8):g}, "
              f"splitting4: {max(1, p['steps'] // 4)} of {p['t_end'] / max(1, p['steps'] // 4):g}). "
              f"Medians of {report['repeats']} runs after a first call (compile time, in the json). Errors: max |w - "
              f"exact| / max |w| at t_end over the first {min(p['samples'], N_CHECK)} samples "
              "(`tumble.exact.omega`).", ""]
    cpu = {r["method"]: r for r in parts.get("cpu", {}).get("rows", [])}
    rows = []
    for r in parts.get("gpu", {}).get("rows", []):
        c = cpu.get(r["method"])
        rows.append(("tumble GPU, kernel alone", r["method"], r["samples"], r["steps"], r["rate_kernel"],
                     c and r["rate_kernel"] / c["rate"], r["error"]))
        rows.append(("tumble GPU, propagate with transfers", r["method"], r["samples"], r["steps"],
                     r["rate_with_transfers"], c and r["rate_with_transfers"] / c["rate"], r["error"]))
    for r in parts.get("cpu", {}).get("rows", []):
        rows.append((f"tumble CPU ({parts['cpu'].get('threads')} threads)", r["method"], r["samples"], r["steps"],
                     r["rate"], None, None))
    for key, label in (("jax", "JAX fori_loop"), ("diffrax", "diffrax, vmap")):
        for r in parts.get(key, {}).get("rows", []):
            rows.append((label, r["method"] + (f" (at {r['peer']}'s error)" if "peer" in r else ""), r["samples"],
                         r["steps"], r["rate"], None, r["error"]))
    bounds = {b["method"]: b for b in report.get("bound", [])}
    lines += ["| engine | method | samples × steps | sample-steps/s | × tumble CPU | fraction of FP64 bound | "
              "error vs exact |", "|---|---|---|---|---|---|---|"]
    for engine, method, n, s, rate, vs_cpu, error in rows:
        fraction = bounds.get(method, {}).get("fraction") if "kernel alone" in engine else None
        lines.append(f"| {engine} | {method} | {n:,} × {s} | {rate:.2e} | "
                     f"{'—' if vs_cpu is None else f'{vs_cpu:.3g}×'} | "
                     f"{'—' if fraction is None else f'{fraction:.0%}'} | "
                     f"{'—' if error is None else f'{error:.1e}'} |")
    lines += ["", "The JAX and diffrax rows run on the same GPU; diffrax's step count is the one at which its error "
              "equals tumble's rk4 (Tsit5) or rk8 (Dopri8) error, so compare them by the time per sample over the "
              "horizon (the targets below), not by sample-steps/s.", ""]
    for r in parts.get("scene", {}).get("rows", []):
        lines.append(f"- growth scene (`tumble.measure(I, 2, method='rk4', flips=3)`, its fit in the kernel) on "
                     f"{'the GPU' if r['device'] == 'cuda' else 'the CPU'}: {r['samples']:,} samples in "
                     f"{r['seconds']:.3g} s, {r['rate']:.2e} sample-steps/s, rate {r['measured']:.6f} (theory "
                     f"{r['theory']:.6f})")
    lines.append("")
    for key in PARTS:
        part = parts.get(key)
        if part is None:
            lines.append(f"- part `{key}`: not run (cut short or budget)")
        elif "skipped" in part:
            lines.append(f"- part `{key}`: skipped: {part['skipped']}")
        elif "failed" in part:
            lines.append(f"- part `{key}`: FAILED: {part['failed']}")
    lines += ["", "FP64 bound per method: the FP64 arithmetic of one torque-free sample-step, counted from the code the "
              "kernel runs (Runge–Kutta: from the tableau, `multiplies_per_sample_step` plus the additions, each "
              "`+ (c h) k` term one FMA; splittings: per exact sub-flow the sincos of `trig.py` and the rotation, "
              "54 instructions, and the |L|² projection, 14; the derivation is in `gpu.py` at `SUBFLOW`). An FP64 "
              "lane issues one FMA, multiply or add per cycle and the peak counts an FMA as 2 FLOPs, so the bound is "
              "peak / 2 / instructions. Floors, compares and selects are not counted and a division or square root "
              "counts as one: the bound is above what can be reached, the fraction a lower estimate.", "",
              "| method | FMA | MUL | ADD | DIV + SQRT | FP64 instructions | FLOPs | bound, sample-steps/s | "
              "kernel, sample-steps/s | fraction of bound | FLOP/s (fraction of peak) |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for b in report.get("bound", []):
        bound = f"{b['bound']:.2e}" if "bound" in b else "— (no FP64 peak)"
        measured = (f"{b['rate']:.2e} | {b['fraction']:.0%} | {b['flops_per_s']:.2e} ({b['fraction_of_peak_flops']:.0%})"
                    if "rate" in b else "— | — | —")
        lines.append(f"| {b['method']} | {b['fma']} | {b['mul']} | {b['add']} | {b['div'] + b['sqrt']} | "
                     f"{b['instructions']} | {b['flops']} | {bound} | {measured} |")
    agreement = parts.get("agreement", {})
    if agreement.get("rows"):
        lines += ["", "Agreement, tumble GPU against tumble CPU on the same spins and steps (first "
                  f"{agreement['rows'][0]['samples']} samples), max |difference| / max |w|, target 1e-10:", ""]
        same = {r["method"]: r["kernel_equals_propagate"] for r in parts.get("gpu", {}).get("rows", [])}
        lines += [f"- {r['method']}: {r['max_rel_difference']:.1e} ({'met' if r['met'] else 'MISSED'}"
                  f"{', the same bits' if r['bitwise'] else ''}; the kernel alone gave propagate's bits: "
                  f"{same.get(r['method'], '—')})" for r in agreement["rows"]]
    model_rows = parts.get("models", {}).get("rows", [])
    if model_rows:
        lines += ["", "The models (`run_model_ensemble(..., device=\"cuda\")`, final state, with host transfers) "
                  "against the CPU's model kernels on this machine's cores; |gpu − cpu| / max |y| on the first "
                  f"{min(p['samples'], N_CHECK)} samples:", "",
                  "| model | method | samples × steps | GPU sample-steps/s | CPU sample-steps/s | × CPU | "
                  "|gpu − cpu| |", "|---|---|---|---|---|---|---|"]
        lines += [f"| {r['model']} | {r['method']} | {r['samples']:,} × {r['steps']} | "
                  f"{r['rate_with_transfers']:.2e} | {r['cpu_rate']:.2e} | {r['speedup']:.3g}× | "
                  f"{r['max_rel_difference']:.1e} |" for r in model_rows]
    closed_rows = parts.get("closed_form", {}).get("rows", [])
    if closed_rows:
        lines += ["", "The closed form on the device (one thread per sample: the set-up and the evaluation) against "
                  "`tumble.exact.omega` on this machine's cores, evaluations (sample × time) per second:", "",
                  "| evaluation | samples | GPU, with transfers | GPU, kernel alone | CPU | × CPU | "
                  "|gpu − cpu| / max |w| |",
                  "|---|---|---|---|---|---|---|"]
        lines += [f"| {r['evaluation']} | {r['samples']:,} | {r['rate_with_transfers']:.2e} | "
                  f"{_rate_or_dash(r.get('rate_kernel'))} | {r['cpu_rate']:.2e} | {r['speedup']:.3g}× | "
                  f"{r['max_rel_difference']:.1e} |" for r in closed_rows]
    lines += _adaptive_markdown(parts.get("adaptive", {}))
    lines += ["", "Issue 28's targets:", "", "| target | measured | status |", "|---|---|---|"]
    lines += [f"| {t['target']} | {t['measured']} | {t['status']} |" for t in report["targets"]]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------------------------


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, help="GPU samples (default 1048576; --quick 200)")
    parser.add_argument("--steps", type=int, help="rk4 steps of 0.01 (default 2000; --quick 20)")
    parser.add_argument("--cpu-samples", type=int, help="CPU part's samples (default samples/10)")
    parser.add_argument("--cpu-steps", type=int, help="CPU part's rk4 steps (default steps/5)")
    parser.add_argument("--scene-samples", type=int, help="samples of the growth scene on the GPU (default 1048576; "
                                                          "--quick 64); on the CPU at most 16384 (--quick 32)")
    parser.add_argument("--repeats", type=int, help="timed runs per figure, median (default 5; --quick 2)")
    parser.add_argument("--adaptive-t-end", type=float,
                        help="horizon of the adaptive part's integrate row, s (default 100; --quick 2)")
    parser.add_argument("--section-samples", type=int,
                        help="releases of the adaptive part's section row (default 2000; --quick 4)")
    parser.add_argument("--section-t-end", type=float,
                        help="horizon of the adaptive part's section row, s (default 1000; --quick 20)")
    parser.add_argument("--quick", action="store_true", help="tiny sizes: a smoke run (also on the simulator)")
    parser.add_argument("--out", type=Path, help="report folder (default benchmarks/results; --quick or the "
                                                 "simulator: a new temporary folder)")
    parser.add_argument("--fp64-peak", type=float, help="the GPU's vector FP64 peak, FLOP/s (overrides the table)")
    parser.add_argument("--budget", type=float, default=420.0,
                        help="seconds after which the remaining parts are skipped (default 420)")
    parser.add_argument("--parts", nargs="+", choices=list(PARTS), default=list(PARTS))
    parser.add_argument("--check-counts", action="store_true",
                        help="check the splittings' FP64 counts against the CPU's LLVM IR and exit")
    args = parser.parse_args(argv)
    began = time.perf_counter()
    if args.check_counts:
        problems = check_counts()
        print("\n".join(problems) or "FP64 counts agree with the CPU's LLVM IR")
        return 1 if problems else 0
    quick = args.quick
    samples = args.samples or (200 if quick else 1 << 20)
    steps = args.steps or (20 if quick else 2000)
    repeats = args.repeats or (2 if quick else 5)
    simulator = bool(numba_config.ENABLE_CUDASIM)
    out = args.out
    if out is None or ((quick or simulator) and out.resolve() == RESULTS.resolve()):
        if out is not None:
            print(f"a smoke run does not write over {RESULTS}", flush=True)
        out = Path(tempfile.mkdtemp(prefix="tumble-gpu-smoke-")) if quick or simulator else RESULTS
    if simulator and not quick and samples * steps > 1e6:
        print("numba-cuda's simulator runs the kernels in Python: use --quick (or small --samples/--steps)")
        return 2

    patched = patch_numpy()
    import tumble
    from tumble.engine.device import resolve_device

    try:
        resolve_device("cuda")
    except ValueError as error:
        print(error, flush=True)
        return 1

    sys.path.insert(0, str(Path(__file__).parent))
    import provenance
    import timing

    out.mkdir(parents=True, exist_ok=True)
    print(f"writing {out / 'gpu.md'} and gpu.json" + (" (SMOKE RUN: numbers meaningless)" if simulator or quick
                                                      else ""), flush=True)
    info = gpu_info(args.fp64_peak)
    print(f"GPU: {info['name']}; FP64 peak {info.get('fp64_peak') or 0:.3g} FLOP/s ({info['peak_source']})",
          flush=True)
    problem = Problem(samples, steps)
    report = dict(provenance.stamp(), date=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), quick=quick,
                  simulator=simulator,
                  gpu_info=info, machine=timing.machine(), load_average=os.getloadavg()[0], versions=versions(),
                  row_stack_patched=patched, repeats=repeats, tumble=tumble.__version__,
                  problem=dict(samples=samples, steps=steps, t_end=problem.t_end, dt=DT, eps=EPS),
                  parts={})
    ctx = dict(problem=problem, repeats=repeats, report=report,
               cpu_samples=min(samples, args.cpu_samples or max(64, samples // 10)),
               cpu_steps=args.cpu_steps or max(8, steps // 5),
               scene_samples=args.scene_samples or (64 if quick else 1 << 20),
               cpu_scene_samples=min(args.scene_samples or (1 << 20), 32 if quick else 1 << 14),
               adaptive_t_end=args.adaptive_t_end or (2.0 if quick else 100.0),
               section_samples=args.section_samples or (4 if quick else 2000),
               section_t_end=args.section_t_end or (20.0 if quick else 1000.0), began=began, budget=args.budget)
    write(report, out)
    for name in args.parts:
        elapsed = time.perf_counter() - began
        if elapsed > args.budget:
            report["parts"][name] = dict(skipped=f"time budget: {elapsed:.0f} s used of --budget {args.budget:g}")
        else:
            print(f"part {name} ...", flush=True)
            started = time.perf_counter()
            try:
                report["parts"][name] = PARTS[name](ctx)
            except Exception as error:  # noqa: BLE001 (fail soft: report it, go on with the other parts)
                traceback.print_exc()
                report["parts"][name] = dict(failed=f"{type(error).__name__}: {error}".splitlines()[0][:300])
            report["parts"][name]["seconds"] = time.perf_counter() - started
        status = report["parts"][name]
        print(f"part {name}: " + (f"skipped: {status['skipped']}" if "skipped" in status else
                                  f"FAILED: {status['failed']}" if "failed" in status else
                                  f"done in {status['seconds']:.1f} s"), flush=True)
        write(report, out)
    print(markdown(report), flush=True)
    print(f"wrote {out / 'gpu.md'} and {out / 'gpu.json'} in {time.perf_counter() - began:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
