"""Work-precision benchmark: wall time against error for tumble's integrators, the closed form, SciPy and heyoka.

    python benchmarks/work_precision.py                  # full size; writes benchmarks/results/work_precision.*
    python benchmarks/work_precision.py --quick          # small smoke run; writes benchmarks/results/quick/
    python benchmarks/work_precision.py --out DIR        # somewhere else
    python benchmarks/work_precision.py --threads 1      # numba threads (default: numba's default)

The scene: 2000 spins of 1 rad/s tilted ε = 0.05 rad from the intermediate axis of I = (1, 2, 3) kg m²
(a cone of tilts, :func:`tumble.sampling.perturbed_spins`, seed 0), integrated to t = 20 s — several flips.
Every fixed-step tumble method runs over a ladder of steps (:func:`tumble.measure.precision.default_steps`), the
closed form once, SciPy's ``solve_ivp`` (RK45, DOP853) on the stacked ensemble over rtol = 1e-3 … 1e-13
and, when heyoka is installed (``pip install 'tumble[bench]'``), heyoka's batch-mode Taylor integrator over
tol = 1e-3 … 1e-15 on as many threads as numba's, all in the same process, one after the other. Error: max
over samples of ``|w - w_ref| / |w0|`` at t_end, the reference being heyoka's long-double run (the closed
form without heyoka). Each wall time is the median of 3 runs taken in 3 interleaved passes over all solvers
(so that load from other processes falls on all alike); each solver's first call or build (compile or cache
load) is timed apart and reported, never counted.

Writes ``work_precision.nc`` (the dataset, :func:`tumble.io.write_dataset`), ``work_precision.md`` (the
speed-up tables at errors 1e-4, 1e-7, 1e-10, 1e-13 against DOP853 and heyoka, with the targets of issue 15
marked met or missed; tumble's dop853 against both and its fastest fixed step at each error 1e-4 ... 1e-12, with the
targets of issue 56; compile times, machine, load, date), ``work_precision.json`` (every number) and, when
:mod:`tumble.output.figures` can draw it, ``work_precision_work_precision.png`` (the diagram).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
from tumble.measure.precision import WARM_UP_SECONDS, speedups, time_to_error, work_precision
from tumble.output.io import write_dataset

RESULTS = Path(__file__).with_name("results")

#: Nine interleaved passes: a shared virtual machine's speed drifts by 10-50 % for seconds at a time (measured on the
#: 2-core machines), and five passes let such a phase decide a point's median.
FULL = dict(body=(1.0, 2.0, 3.0), axis=2, spin=1.0, amplitude=0.05, samples=2000, t_end=20.0, seed=0,
            repeats=9, scipy_methods=("RK45", "DOP853"))
QUICK = dict(FULL, samples=200, t_end=5.0, repeats=1, rtols=[1e-3, 1e-5, 1e-7, 1e-9, 1e-11])
ERRORS = (1e-4, 1e-7, 1e-10, 1e-13)
BASELINE = "scipy_DOP853"
HEYOKA = "heyoka"
#: Targets of issue 15: (speed-up, the errors where it applies).
#: Best tumble integrator over DOP853.
TARGET_BEST_TUMBLE = (30.0, (1e-4, 1e-7, 1e-10))
#: Closed form over DOP853.
TARGET_EXACT = (200.0, (1e-10,))
#: Best tumble integrator over heyoka.
TARGET_HEYOKA_BEST = (3.0, (1e-4, 1e-7, 1e-10))
#: tumble's fastest (integrator or closed form) over heyoka.
TARGET_HEYOKA_ANY = (10.0, (1e-4, 1e-7, 1e-10, 1e-13))
#: Targets of issue 56, tumble's error-controlled dop853 at each error 1e-4 ... 1e-12: over SciPy's DOP853, over heyoka.
DOP853_ERRORS = tuple(10.0 ** -k for k in range(4, 13))
TARGET_DOP853_X_SCIPY = 10.0
TARGET_DOP853_X_HEYOKA = 2.0


def _num(x):
    """JSON number (NaN and inf as None)."""
    x = float(x)
    return x if math.isfinite(x) else None


def _fmt_time(t):
    return "—" if not math.isfinite(t) else f"{t * 1e3:.3g} ms"


def _fmt_ratio(r):
    return "—" if not math.isfinite(r) else f"{r:.3g}×"


def _verdict(ours, theirs, target, error, peer):
    """Met or missed: ``theirs / ours >= target`` at ``error`` (times in s, NaN: never reaches the error)."""
    ratio, errors = target
    if not any(math.isclose(error, e) for e in errors):
        return "no target"
    if not math.isfinite(ours):
        return "missed (not reached)"
    if not math.isfinite(theirs):
        return f"met ({peer} never reaches it)"
    return "met" if theirs / ours >= ratio else "missed"


def _speedup(ours, theirs):
    return theirs / ours if math.isfinite(ours) and math.isfinite(theirs) else math.nan


def _comparisons(ds, errors):
    """Per error: the times of the peers, tumble's best integrator, the closed form and the fastest of both,
    their ratios and verdicts against the targets (dicts, for the table and the JSON)."""
    solvers = [str(s) for s in ds.solver.values]
    walls = ds.wp_wall.transpose("solver", "wp_point").values
    errs = ds.wp_error.transpose("solver", "wp_point").values
    kinds = [str(k) for k in ds.solver_kind.values]

    def reach(solver, e):
        if solver not in solvers:
            return math.nan
        i = solvers.index(solver)
        return time_to_error(walls[i], errs[i], e)

    rows = []
    for e in errors:
        times = {s: reach(s, e) for s, k in zip(solvers, kinds) if k == "tumble"}
        reached = {s: t for s, t in times.items() if math.isfinite(t)}
        best = min(reached, key=reached.get) if reached else ""
        row = dict(error=e, dop853=reach(BASELINE, e), heyoka=reach(HEYOKA, e), best=best,
                   best_time=reached.get(best, math.nan), exact=reach("exact", e))
        row["fastest"] = min((row["best_time"], row["exact"]), key=lambda t: t if math.isfinite(t) else math.inf)
        row["fastest_name"] = ("exact" if math.isfinite(row["exact"]) and not row["best_time"] < row["exact"]
                               else best)
        for peer, key in ((BASELINE, "dop853"), (HEYOKA, "heyoka")):
            for ours in ("best_time", "exact", "fastest"):
                row[f"{ours}_x_{key}"] = _speedup(row[ours], row[key])
        row["verdicts"] = {
            "best_tumble_x_dop853": _verdict(row["best_time"], row["dop853"], TARGET_BEST_TUMBLE, e, "DOP853"),
            "exact_x_dop853": _verdict(row["exact"], row["dop853"], TARGET_EXACT, e, "DOP853"),
        }
        if HEYOKA in solvers:
            row["verdicts"].update(
                best_tumble_x_heyoka=_verdict(row["best_time"], row["heyoka"], TARGET_HEYOKA_BEST, e, "heyoka"),
                fastest_tumble_x_heyoka=_verdict(row["fastest"], row["heyoka"], TARGET_HEYOKA_ANY, e, "heyoka"))
        rows.append(row)
    return rows


def _dop853_rows(ds):
    """Per error of :data:`DOP853_ERRORS`: tumble's dop853 against SciPy's DOP853, heyoka and tumble's fastest
    fixed-step method (times to reach it, ratios, verdicts of issue 56's targets)."""
    solvers = [str(s) for s in ds.solver.values]
    kinds = [str(k) for k in ds.solver_kind.values]

    def reach(solver, e):
        if solver not in solvers:
            return math.nan
        return time_to_error(ds.wp_wall.sel(solver=solver).values, ds.wp_error.sel(solver=solver).values, e)

    fixed = [s for s, k in zip(solvers, kinds) if k == "tumble" and s not in ("dop853", "exact")]
    rows = []
    for e in DOP853_ERRORS:
        ours, scipy, heyoka = reach("dop853", e), reach(BASELINE, e), reach(HEYOKA, e)
        times = {s: reach(s, e) for s in fixed}
        best = min((s for s in times if math.isfinite(times[s])), key=times.get, default="")
        rows.append(dict(error=e, dop853=ours, scipy=scipy, heyoka=heyoka, best_fixed=best,
                         best_fixed_time=times.get(best, math.nan), x_scipy=_speedup(ours, scipy),
                         x_heyoka=_speedup(ours, heyoka), dop853_over_fixed=_speedup(times.get(best, math.nan), ours),
                         verdict_scipy=_verdict(ours, scipy, (TARGET_DOP853_X_SCIPY, DOP853_ERRORS), e, "DOP853"),
                         verdict_heyoka=(_verdict(ours, heyoka, (TARGET_DOP853_X_HEYOKA, DOP853_ERRORS), e, "heyoka")
                                         if HEYOKA in solvers else "no heyoka")))
    return rows


def _dop853_report(rows):
    lines = ["", "## tumble's error-controlled dop853 (issue 56)", "",
             f"Targets: dop853 ≥ {TARGET_DOP853_X_SCIPY:g}× SciPy's DOP853 and ≥ {TARGET_DOP853_X_HEYOKA:g}× heyoka at "
             "each error 1e-4 … 1e-12 (times to reach it as above); beside them, tumble's fastest fixed-step method "
             "and dop853's time over its (above 1: the fixed step is faster on this smooth problem).", "",
             "| error | dop853 | SciPy DOP853 | speed-up | target | heyoka | speed-up | target | fastest fixed step "
             "| its time | dop853 / it |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['error']:.0e} | {_fmt_time(r['dop853'])} | {_fmt_time(r['scipy'])} | "
                     f"{_fmt_ratio(r['x_scipy'])} | {r['verdict_scipy']} | {_fmt_time(r['heyoka'])} | "
                     f"{_fmt_ratio(r['x_heyoka'])} | {r['verdict_heyoka']} | {r['best_fixed'] or '—'} | "
                     f"{_fmt_time(r['best_fixed_time'])} | {_fmt_ratio(r['dop853_over_fixed'])} |")
    return lines


def _report(ds, table, rows, load_before, load_after, elapsed, settings):
    solvers = [str(s) for s in ds.solver.values]
    errors = [float(e) for e in table.error.values]
    heyoka = HEYOKA in solvers
    a = ds.attrs
    lines = [f"# Work-precision benchmark — {a['date']}", "",
             f"{a['samples']} spins of {a['spin']:g} rad/s tilted {a['amplitude']:g} rad "
             f"(cone) from axis {a['axis']} of I = ({a['I1']:g}, {a['I2']:g}, {a['I3']:g}) kg m², t_end = "
             f"{a['t_end']:g} s, seed {a['seed']}. Error: max over samples of |ω(t_end) − ω_ref(t_end)| / |ω0|. "
             f"Wall time: median of {a['repeats']} runs taken in interleaved passes over all solvers, each right "
             f"after untimed runs of the same solver lasting {WARM_UP_SECONDS * 1e3:g} ms or more (thread pools awake, "
             "cores up to speed), "
             "compile time excluded (below). SciPy `solve_ivp` on the stacked ensemble (one state of length 3·N, numpy "
             f"right-hand side), atol = rtol × {a['scipy_atol_factor']:g} rad/s.", "",
             f"Machine: {a['machine']}; numba threads: {a['numba_threads']} (SciPy: 1 thread; "
             f"heyoka: {a.get('heyoka_threads', '—')}). {a['versions']}; {a['heyoka']}.", "",
             f"Load average (1 min) {load_before:.2f} before, {load_after:.2f} after; whole run "
             f"{elapsed:.0f} s.", ""]
    if heyoka:
        lines += [f"Reference: {a['reference']} ({a['reference_wall_s']:.2f} s, not timed). Its distance to "
                  f"tumble's closed form: max {a['reference_vs_exact_max']:.2g}, median "
                  f"{a['reference_vs_exact_median']:.2g} (× |ω0|) — the closed form's error below.", ""]
    else:
        lines += ["Reference: tumble's closed form — heyoka is not installed (`pip install 'tumble[bench]'`), so "
                  "there are no heyoka rows and the closed form's error is an estimate (over two halves of "
                  "t_end against one evaluation).", ""]
    t = TARGET_BEST_TUMBLE
    lines += [f"## Speed-up against {BASELINE} (same run)", "",
              "Time to reach each error by log-log interpolation along each solver's best-time front; "
              "— : never reached within the measured points. Targets (issue 15): best tumble integrator "
              f"≥ {t[0]:g}× at {', '.join(f'{e:.0e}' for e in t[1])}; closed form ≥ {TARGET_EXACT[0]:g}× at "
              f"{', '.join(f'{e:.0e}' for e in TARGET_EXACT[1])}.", "",
              f"| error | DOP853 | best tumble integrator | time | speed-up | target ≥ {t[0]:g}× | closed form | "
              f"speed-up | target ≥ {TARGET_EXACT[0]:g}× |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['error']:.0e} | {_fmt_time(r['dop853'])} | {r['best'] or '—'} | "
                     f"{_fmt_time(r['best_time'])} | {_fmt_ratio(r['best_time_x_dop853'])} | "
                     f"{r['verdicts']['best_tumble_x_dop853']} | {_fmt_time(r['exact'])} | "
                     f"{_fmt_ratio(r['exact_x_dop853'])} | {r['verdicts']['exact_x_dop853']} |")
    if heyoka:
        hb, ha = TARGET_HEYOKA_BEST, TARGET_HEYOKA_ANY
        lines += ["", "## Speed-up against heyoka (same run)", "",
                  f"heyoka: {a['heyoka']}; its compile time (building the integrators of the whole tolerance "
                  "ladder) is in the table below, not in the times. Targets (issue 15): best tumble integrator "
                  f"≥ {hb[0]:g}× at {', '.join(f'{e:.0e}' for e in hb[1])}; tumble's fastest, closed form "
                  f"counted, ≥ {ha[0]:g}× at {', '.join(f'{e:.0e}' for e in ha[1])}.", "",
                  f"| error | heyoka | best tumble integrator | time | speed-up | target ≥ {hb[0]:g}× | "
                  f"closed form | speed-up | tumble's fastest | speed-up | target ≥ {ha[0]:g}× |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            lines.append(f"| {r['error']:.0e} | {_fmt_time(r['heyoka'])} | {r['best'] or '—'} | "
                         f"{_fmt_time(r['best_time'])} | {_fmt_ratio(r['best_time_x_heyoka'])} | "
                         f"{r['verdicts']['best_tumble_x_heyoka']} | {_fmt_time(r['exact'])} | "
                         f"{_fmt_ratio(r['exact_x_heyoka'])} | {r['fastest_name'] or '—'} | "
                         f"{_fmt_ratio(r['fastest_x_heyoka'])} | {r['verdicts']['fastest_tumble_x_heyoka']} |")
    lines += _dop853_report(_dop853_rows(ds))
    lines += ["", "## Every solver: time to reach the error (speed-up against DOP853)", "",
              "| solver | " + " | ".join(f"{e:.0e}" for e in errors) + " | compile / cache load |",
              "|---|" + "---|" * (len(errors) + 1)]
    for s in solvers:
        cells = [f"{_fmt_time(float(table.time_to_error.sel(solver=s).values[j]))} "
                 f"({_fmt_ratio(float(table.speedup.sel(solver=s).values[j]))})" for j in range(len(errors))]
        compile_s = float(ds.compile_time.sel(solver=s))
        lines.append(f"| {s} | " + " | ".join(cells) + f" | {compile_s:.2f} s |")
    lines += ["", "## Points (error, wall time)", ""]
    for s, kind in zip(solvers, (str(k) for k in ds.solver_kind.values)):
        err = ds.wp_error.sel(solver=s).values
        wall = ds.wp_wall.sel(solver=s).values
        setting = ds.wp_setting.sel(solver=s).values
        ok = np.isfinite(wall)
        what = {"tumble": "dt", "scipy": "rtol", "heyoka": "tol"}.get(kind, "")
        pts = ", ".join(f"{err[k]:.1e} @ {wall[k] * 1e3:.3g} ms"
                        + ("" if not math.isfinite(setting[k]) else f" ({what} {setting[k]:.3g})")
                        for k in np.nonzero(ok)[0])
        lines.append(f"- **{s}**: {pts}")
    lines += ["", f"Closed form: `tumble.exact.omega(body, w0, t_end)` alone takes {a['exact_omega_wall_s'] * 1e3:.3g} ms of "
              f"the point's time; `tumble.integrate` with one rk4 step (its fixed cost: validation, engine, "
              f"Dataset) {a['integrate_one_step_rk4_wall_s'] * 1e3:.3g} ms.", "",
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
    rows = _comparisons(ds, ERRORS)

    out.mkdir(parents=True, exist_ok=True)
    write_dataset(ds, out / "work_precision.nc", title="tumble work-precision benchmark")
    report = _report(ds, table, rows, load_before, load_after, elapsed, settings)
    solvers = [str(s) for s in ds.solver.values]
    numbers = {
        **provenance.stamp(), "attrs": {k: (v if isinstance(v, (str, int, float)) else str(v))
                                             for k, v in ds.attrs.items()},
        "settings": {k: v for k, v in settings.items()}, "elapsed_s": elapsed,
        "targets": {"best_tumble_x_dop853": TARGET_BEST_TUMBLE, "exact_x_dop853": TARGET_EXACT,
                    "best_tumble_x_heyoka": TARGET_HEYOKA_BEST, "fastest_tumble_x_heyoka": TARGET_HEYOKA_ANY,
                    "baseline": BASELINE},
        "compile_time_s": {s: _num(ds.compile_time.sel(solver=s)) for s in solvers},
        "curves": {s: [{"error": _num(e), "error_median": _num(em), "wall_s": _num(w), "setting": _num(st),
                        "steps": _num(n), "nfev": _num(f)}
                       for e, em, w, st, n, f in zip(*(ds[v].sel(solver=s).values for v in (
                           "wp_error", "wp_error_median", "wp_wall", "wp_setting", "wp_steps", "wp_nfev")))
                       if math.isfinite(w)] for s in solvers},
        "speedups": {f"{e:.0e}": {
            "time_to_error_s": {s: _num(table.time_to_error.sel(solver=s).values[j]) for s in solvers},
            "speedup": {s: _num(table.speedup.sel(solver=s).values[j]) for s in solvers},
            "comparison": {k: (_num(v) if isinstance(v, float) else v) for k, v in rows[j].items()},
        } for j, e in enumerate(table.error.values)},
        "dop853": [{k: (_num(v) if isinstance(v, float) else v) for k, v in r.items()} for r in _dop853_rows(ds)],
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
