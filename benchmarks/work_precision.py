"""Work-precision benchmark: wall time against error for tumble's integrators, the closed form and SciPy.

    python benchmarks/work_precision.py                  # full size; writes benchmarks/results/work_precision.*
    python benchmarks/work_precision.py --quick          # small smoke run; writes benchmarks/results/quick/
    python benchmarks/work_precision.py --out DIR        # somewhere else
    python benchmarks/work_precision.py --threads 1      # numba threads (default: numba's default)

The scene: 2000 spins of 1 rad/s tilted ε = 0.05 rad from the intermediate axis of I = (1, 2, 3) kg m²
(a cone of tilts, :func:`tumble.sampling.perturbed_spins`, seed 0), integrated to t = 20 s — several flips.
Every fixed-step tumble method runs over a ladder of steps (:func:`tumble.precision.default_steps`), the
closed form once, SciPy's ``solve_ivp`` (RK45, DOP853) on the stacked ensemble over rtol = 1e-3 … 1e-13,
all in the same process, one after the other. Error: max over samples of ``|w - w_exact| / |w0|`` at
t_end. Each wall time is the median of 3 runs taken in 3 interleaved passes over all solvers (so that load
from other processes falls on all alike); each tumble method's first call (compile or cache load) is timed
apart and reported, never counted.

Writes ``work_precision.nc`` (the dataset, :func:`tumble.io.write_dataset`), ``work_precision.md`` (the
speed-up table at errors 1e-4, 1e-7, 1e-10 against DOP853, with the targets — best tumble integrator
>= 30x, closed form >= 300x — marked met or missed, compile times, machine, load, date),
``work_precision.json`` (every number) and, when :mod:`tumble.plots` can draw it,
``work_precision_work_precision.png`` (the diagram).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from datetime import date
from pathlib import Path

import numba
import numpy as np

from tumble.measure.precision import speedups, work_precision
from tumble.output.io import write_dataset

RESULTS = Path(__file__).with_name("results")

FULL = dict(body=(1.0, 2.0, 3.0), axis=2, spin=1.0, amplitude=0.05, samples=2000, t_end=20.0, seed=0,
            repeats=3, scipy_methods=("RK45", "DOP853"))
QUICK = dict(FULL, samples=200, t_end=5.0, repeats=1, rtols=[1e-3, 1e-5, 1e-7, 1e-9, 1e-11])
ERRORS = (1e-4, 1e-7, 1e-10)
BASELINE = "scipy_DOP853"
#: Targets: speed-up over DOP853 at every error of ERRORS.
TARGET_BEST_TUMBLE = 30.0
TARGET_EXACT = 300.0


def _num(x):
    """JSON number (NaN and inf as None)."""
    x = float(x)
    return x if math.isfinite(x) else None


def _fmt_time(t):
    return "—" if not math.isfinite(t) else f"{t * 1e3:.3g} ms"


def _fmt_ratio(r):
    return "—" if not math.isfinite(r) else f"{r:.3g}×"


def _verdict(ratio, target):
    if not math.isfinite(ratio):
        return "missed (not reached)"
    return "met" if ratio >= target else "missed"


def _report(ds, table, load_before, load_after, elapsed, settings):
    solvers = [str(s) for s in ds.solver.values]
    errors = [float(e) for e in table.error.values]
    lines = [f"# Work-precision benchmark — {ds.attrs['date']}", "",
             f"{ds.attrs['samples']} spins of {ds.attrs['spin']:g} rad/s tilted {ds.attrs['amplitude']:g} rad "
             f"(cone) from axis {ds.attrs['axis']} of I = ({ds.attrs['I1']:g}, {ds.attrs['I2']:g}, "
             f"{ds.attrs['I3']:g}) kg m², t_end = {ds.attrs['t_end']:g} s, seed {ds.attrs['seed']}. Error: max "
             f"over samples of |ω(t_end) − ω_exact(t_end)| / |ω0|. Wall time: median of {ds.attrs['repeats']} "
             "runs taken in interleaved passes over all solvers, compile time excluded (below). SciPy `solve_ivp` on the stacked ensemble (one state of "
             f"length 3·N, numpy right-hand side), atol = rtol × {ds.attrs['scipy_atol_factor']:g} rad/s.", "",
             f"Machine: {ds.attrs['machine']}; numba threads: {ds.attrs['numba_threads']} (SciPy: 1 thread). "
             f"{ds.attrs['versions']}.", "",
             f"Load average (1 min) {load_before:.2f} before, {load_after:.2f} after; whole run "
             f"{elapsed:.0f} s.", "",
             f"## Speed-up against {BASELINE} (same run)", "",
             "Time to reach each error by log-log interpolation along each solver's best-time front; "
             "— : never reached within the measured points.", "",
             "| error | DOP853 | best tumble integrator | time | speed-up | target ≥ "
             f"{TARGET_BEST_TUMBLE:g}× | exact | speed-up | target ≥ {TARGET_EXACT:g}× |",
             "|---|---|---|---|---|---|---|---|---|"]
    base = table.time_to_error.sel(solver=BASELINE).values
    exact_time = table.time_to_error.sel(solver="exact").values if "exact" in solvers else [math.nan] * len(errors)
    for j, e in enumerate(errors):
        best = str(table.best_tumble.values[j])
        best_time = float(table.time_to_error.sel(solver=best).values[j]) if best else math.nan
        best_ratio = float(table.best_tumble_speedup.values[j])
        exact_ratio = float(table.exact_speedup.values[j])
        lines.append(f"| {e:.0e} | {_fmt_time(float(base[j]))} | {best or '—'} | {_fmt_time(best_time)} | "
                     f"{_fmt_ratio(best_ratio)} | {_verdict(best_ratio, TARGET_BEST_TUMBLE)} | "
                     f"{_fmt_time(float(exact_time[j]))} | {_fmt_ratio(exact_ratio)} | "
                     f"{_verdict(exact_ratio, TARGET_EXACT)} |")
    lines += ["", "## Every solver: time to reach the error (speed-up against DOP853)", "",
              "| solver | " + " | ".join(f"{e:.0e}" for e in errors) + " | compile / cache load |",
              "|---|" + "---|" * (len(errors) + 1)]
    for s in solvers:
        cells = [f"{_fmt_time(float(table.time_to_error.sel(solver=s).values[j]))} "
                 f"({_fmt_ratio(float(table.speedup.sel(solver=s).values[j]))})" for j in range(len(errors))]
        compile_s = float(ds.compile_time.sel(solver=s))
        lines.append(f"| {s} | " + " | ".join(cells) + f" | {compile_s:.2f} s |")
    lines += ["", "## Points (error, wall time)", ""]
    for s in solvers:
        err = ds.wp_error.sel(solver=s).values
        wall = ds.wp_wall.sel(solver=s).values
        setting = ds.wp_setting.sel(solver=s).values
        ok = np.isfinite(wall)
        what = "dt" if s not in ("exact",) and not s.startswith("scipy") else "rtol"
        pts = ", ".join(f"{err[k]:.1e} @ {wall[k] * 1e3:.3g} ms"
                        + ("" if not math.isfinite(setting[k]) else f" ({what} {setting[k]:.3g})")
                        for k in np.nonzero(ok)[0])
        lines.append(f"- **{s}**: {pts}")
    lines += ["", f"Closed form: `tumble.exact.omega` alone takes {ds.attrs['exact_omega_wall_s'] * 1e3:.3g} ms of "
              f"the point's time; `tumble.integrate` with one rk4 step (its fixed cost: validation, engine, "
              f"Dataset) {ds.attrs['integrate_one_step_rk4_wall_s'] * 1e3:.3g} ms.", "",
              "Exact: its error is an estimate (closed form over two halves of t_end against one evaluation "
              "over t_end; the closed form is the reference of every other error).",
              f"Settings: {json.dumps(settings, default=str)}"]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="work_precision", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small smoke run (200 spins, t_end 5 s, 1 repeat)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default benchmarks/results, or benchmarks/results/quick with --quick)")
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: numba's default)")
    args = parser.parse_args(argv)
    if args.threads is not None:
        numba.set_num_threads(args.threads)
    out = args.out or (RESULTS / "quick" if args.quick else RESULTS)
    settings = dict(QUICK if args.quick else FULL)

    load_before = os.getloadavg()[0]
    if load_before > 0.5 * (os.cpu_count() or 1):
        print(f"work_precision: note: load average {load_before:.2f} on {os.cpu_count()} cores; timings may be "
              "inflated by other processes", file=sys.stderr)
    started = time.perf_counter()
    ds = work_precision(**settings, progress=True)
    elapsed = time.perf_counter() - started
    load_after = os.getloadavg()[0]
    ds.attrs.update(load_average_before=load_before, load_average_after=load_after, quick=int(args.quick))
    table = speedups(ds, errors=ERRORS, baseline=BASELINE)

    out.mkdir(parents=True, exist_ok=True)
    write_dataset(ds, out / "work_precision.nc", title="tumble work-precision benchmark")
    report = _report(ds, table, load_before, load_after, elapsed, settings)
    solvers = [str(s) for s in ds.solver.values]
    numbers = {
        "date": str(date.today()), "attrs": {k: (v if isinstance(v, (str, int, float)) else str(v))
                                             for k, v in ds.attrs.items()},
        "settings": {k: v for k, v in settings.items()}, "elapsed_s": elapsed,
        "targets": {"best_tumble": TARGET_BEST_TUMBLE, "exact": TARGET_EXACT, "baseline": BASELINE},
        "compile_time_s": {s: _num(ds.compile_time.sel(solver=s)) for s in solvers},
        "curves": {s: [{"error": _num(e), "error_median": _num(em), "wall_s": _num(w), "setting": _num(st),
                        "steps": _num(n), "nfev": _num(f)}
                       for e, em, w, st, n, f in zip(*(ds[v].sel(solver=s).values for v in (
                           "wp_error", "wp_error_median", "wp_wall", "wp_setting", "wp_steps", "wp_nfev")))
                       if math.isfinite(w)] for s in solvers},
        "speedups": {f"{e:.0e}": {
            "time_to_error_s": {s: _num(table.time_to_error.sel(solver=s).values[j]) for s in solvers},
            "speedup": {s: _num(table.speedup.sel(solver=s).values[j]) for s in solvers},
            "best_tumble": str(table.best_tumble.values[j]),
            "best_tumble_speedup": _num(table.best_tumble_speedup.values[j]),
            "best_tumble_target_met": bool(table.best_tumble_speedup.values[j] >= TARGET_BEST_TUMBLE),
            "exact_speedup": _num(table.exact_speedup.values[j]),
            "exact_target_met": bool(table.exact_speedup.values[j] >= TARGET_EXACT),
        } for j, e in enumerate(table.error.values)},
    }
    (out / "work_precision.json").write_text(json.dumps(numbers, indent=1, default=str))
    figure = ""
    try:
        from tumble.output import figures as plots

        written = plots.save_figures(ds, ["work_precision"], out, stem="work_precision")
        figure = ", ".join(str(p) for p in written)
    except (ImportError, AttributeError, ValueError) as err:  # plots not there yet, or cannot draw this
        print(f"work_precision: no figure ({type(err).__name__}: {err})", file=sys.stderr)
    if figure:
        report += f"\nFigure: {figure}\n"
    (out / "work_precision.md").write_text(report)
    print(report)
    print(f"wrote {out / 'work_precision.nc'}, {out / 'work_precision.md'}, {out / 'work_precision.json'}"
          + (f", {figure}" if figure else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
