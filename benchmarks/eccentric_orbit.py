"""Where adaptivity pays (issue 56, item 4): an eccentric spin-orbit ensemble, dop853 against tumble's fixed steps.

    python benchmarks/eccentric_orbit.py             # about 2 minutes on 2 cores; writes results/eccentric_orbit.*
    python benchmarks/eccentric_orbit.py --quick     # about 20 s: 200 samples, few points; results/quick/
    python benchmarks/eccentric_orbit.py --reanalyse benchmarks/results/eccentric_orbit.json   # report again, no runs

The scene: the planar spin-orbit problem (Wisdom, Peale & Mignard 1984) of a satellite like Hyperion
(w0 = 0.89) on an orbit of eccentricity e = 0.9, mean motion n = 1, written as a user ``tumble.System`` (rate in the
scalar form of docs/howto/own-system.md, so it runs on the CPU's vectorised blocks). State (theta, theta_dot, f):
theta the angle of the long axis from the line of apsides, f the true anomaly,

    theta'     = theta_dot
    theta_dot' = -(w0^2 / 2) (a/r)^3 sin(2 (theta - f))
    f'         = n (1 + e cos f)^2 / (1 - e^2)^(3/2),      a/r = (1 + e cos f) / (1 - e^2).

The forcing (a/r)^3 runs from 0.15 at apocentre to 1000 at pericentre, and f' from 0.0025 to 44: a fixed step is set
by the pericentre passages, which take a few per cent of the orbit. 2 000 samples (seed 0): theta uniform in
[0, pi), theta_dot / n uniform in [0, 3], f = 0 (pericentre); integrated over two orbits, t_end = 4 pi.

* ``tumble.integrate(system, y0, t_end, method="dop853", rtol=tol, atol=1e-2 tol)`` over tol = 1e-4 ... 1e-13 (half
  decades; atol / rtol as tumble's defaults, 1e-12 / 1e-10; the max error reaches 1e-8 only past rtol 1e-12);
* ``tumble.integrate(system, y0, t_end, t_end / N, method="rk4" | "rk8")`` over ladders of step counts N (a ladder
  stops before a run that would take more than ``max_point_s``);
* the reference: dop853 at rtol = atol = 1e-14 (the tightest tumble takes), checked against SciPy's DOP853 at
  rtol 1e-13 and 2.3e-14 on a handful of samples (the most sensitive ones among them), and against dop853 at
  rtol 1e-13, atol 1e-15;
* SciPy's ``solve_ivp(method="DOP853")`` (a Python right-hand side, one sample at a time) over the same tolerances
  (atol = 1e-2 rtol) on an evenly spread subset of the samples: its steps against fixed rk8's at equal error on that
  subset, and its time scaled to the whole ensemble against tumble's dop853.

Error: max over samples of |theta(t_end) - theta_ref(t_end)| (rad); the median over samples is compared too, and
the whole state's max is recorded. The motion is chaotic and two orbits end at a pericentre: an error of 1e-16 in
the initial state reaches ~1e-11 in theta (and 10 times that in theta_dot) for the most sensitive samples, so the
reference's own accuracy bounds the errors that can be compared: its floor, for the max, is its distance to SciPy
at rtol 2.3e-14 on the samples checked (the most sensitive among them), for the median its distance to dop853 at
rtol 1e-13 (an upper bound); an error below 3 times the floor is marked not measurable. Time at equal error:
log-log interpolation along each solver's best-time front (``tumble.measure.precision.time_to_error``, as
work_precision.py). Wall times: medians of ``repeats`` runs taken in interleaved passes over all the points (so
that load from other processes falls on every method alike) after a first, untimed pass, each run right after a
tiny call of the same method (thread pool awake); the first call of each method (compile or cache load) is timed
apart. Target: dop853 >= 3x faster than tumble's faster fixed-step method at equal error. Also recorded: each
method's sample-steps per second.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import warnings
from datetime import date
from pathlib import Path

import numba
import numpy as np
import scipy
from scipy.integrate import solve_ivp

import tumble
from tumble.measure.precision import time_to_error

sys.path.insert(0, str(Path(__file__).resolve().parent))
import provenance  # noqa: E402

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
ECCENTRICITY, W0 = 0.9, 0.89
T_END = 4.0 * math.pi  # two orbits, n = 1
REFERENCE_TOL = (1e-14, 1e-14)  # rtol, atol: the tightest rtol tumble takes
BRIEF_TOL = (1e-13, 1e-15)  # the looser reference first proposed, kept as a check
SCIPY_CHECK_TOLS = ((1e-13, 1e-15), (2.3e-14, 1e-16))
_TIGHTEST = "2.3e-14/1e-16"  # the key of SciPy's tightest check in the results
ERRORS = (1e-6, 1e-8, 1e-10)
TARGET = 3.0
MEASURABLE = 3.0  # an error is compared only if >= MEASURABLE x the reference's floor
ATOL_FACTOR = 1e-2  # atol = rtol x this, tumble's default ratio (1e-10, 1e-12), for dop853 and SciPy alike
SCIPY_EVALS_PER_STEP, SCIPY_EVALS_START = 12, 2  # solve_ivp DOP853: nfev = 2 + 12 (accepted + rejected)

FULL = dict(samples=2000, seed=0, repeats=3, max_point_s=6.0,
            rtols=[10.0 ** (-k / 2) for k in range(8, 27)],
            ladders={"rk4": [2 ** k for k in range(11, 19)], "rk8": [2 ** k for k in range(9, 16)]},
            scipy_subset=40, scipy_rtols=[10.0 ** -k for k in range(4, 13)], checked=6)
QUICK = dict(FULL, samples=200, repeats=1, max_point_s=1.0,
             rtols=[1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-13],
             ladders={"rk4": [2 ** k for k in (12, 14, 16)], "rk8": [2 ** k for k in (10, 11, 12, 13)]},
             scipy_subset=3, scipy_rtols=[1e-6, 1e-8, 1e-10], checked=2)


def spin_orbit(t, y, p, dydt):
    """The spin-orbit equations, mean motion 1; p = (e, w0). Constant indices only: the block path's scalar form."""
    e = p[0]
    w0 = p[1]
    q = 1.0 - e * e
    c = 1.0 + e * math.cos(y[2])
    a_r = c / q
    dydt[0] = y[1]
    dydt[1] = -0.5 * w0 * w0 * a_r * a_r * a_r * math.sin(2.0 * (y[0] - y[2]))
    dydt[2] = c * c / (q * math.sqrt(q))


SYSTEM = tumble.System(spin_orbit, state=("theta", "theta_dot", "f"),
                       parameters={"e": ECCENTRICITY, "w0": W0}, name="spin_orbit")


def scipy_rate(t, y):
    """The same equations as a user writes them for SciPy."""
    e, w0 = ECCENTRICITY, W0
    q = 1.0 - e * e
    c = 1.0 + e * math.cos(y[2])
    a_r = c / q
    return np.array([y[1], -0.5 * w0 * w0 * a_r ** 3 * math.sin(2.0 * (y[0] - y[2])), c * c / q ** 1.5])


def initial_states(n, seed):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(0.0, math.pi, n), rng.uniform(0.0, 3.0, n), np.zeros(n)])


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _say(*args):
    print("eccentric_orbit:", *args, file=sys.stderr, flush=True)


def _quiet(fn):
    def run():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # coarse fixed steps may blow up: error inf
            return fn()
    return run


def _final(ds):
    return ds["state"].values[:, -1, :]


def _errors(y, ref):
    """Per-sample |theta error| and max |state error| (inf where not finite)."""
    d = np.abs(y - ref)
    d[~np.isfinite(d)] = np.inf
    return d[:, 0], d.max(axis=1)


def _point(setting, wall, walls, y, ref, subset, **extra):
    theta, state = _errors(y, ref)
    return dict(setting=setting, wall_s=wall, walls_s=walls, error_max=float(theta.max()),
                error_median=float(np.median(theta)), error_state_max=float(state.max()),
                error_subset_max=float(theta[subset].max()), **extra), theta


def _at(values, errors, target):
    """``values`` (times or steps) at ``error <= target`` by log-log interpolation along the best front."""
    v, e = np.asarray(values, float), np.asarray(errors, float)
    e = np.where(np.isfinite(e), e, np.nan)
    return time_to_error(v, e, target)


def _fmt_s(t):
    return "—" if not math.isfinite(t) else (f"{t * 1e3:.3g} ms" if t < 1 else f"{t:.3g} s")


def _fmt_reach(row, name):
    """The time to reach the row's error, or "> slowest point" where the method's ladder did not reach it."""
    more = row.get(f"{name}_more_than_s", math.nan)
    return _fmt_s(row[f"{name}_s"]) if math.isfinite(row[f"{name}_s"]) or not math.isfinite(more) else \
        f"> {_fmt_s(more)}"


def _fmt(x, spec=".3g", suffix=""):
    return "—" if x is None or not math.isfinite(x) else f"{x:{spec}}{suffix}"


def block_path_used(system):
    """Whether tumble runs ``system`` on the vectorised blocks (the rate has a scalar form); None if unknown."""
    try:
        from tumble.engine import system_runs

        return system_runs.block_code(system, "rk8") is not None
    except (ImportError, AttributeError, TypeError):
        return None


def compare(curves, key, errors, floor):
    """Per target error: dop853's and each fixed method's time and steps at that error (``key``: the error measure
    of each point), the faster fixed method and its time over dop853's."""
    rows = []
    for target in errors:
        row = dict(error=target, measurable=bool(target >= MEASURABLE * floor))
        for name, points in curves.items():
            errs = [p[key] for p in points]
            row[f"{name}_s"] = _at([p["wall_s"] for p in points], errs, target)
            row[f"{name}_steps"] = _at([p["steps_per_sample"] for p in points], errs, target)
            # not reached: at least the slowest point's time (the ladder stopped there)
            row[f"{name}_more_than_s"] = (max(p["wall_s"] for p in points)
                                          if points and not math.isfinite(row[f"{name}_s"]) else math.nan)
        fixed = {m: row[f"{m}_s"] for m in ("rk4", "rk8") if math.isfinite(row[f"{m}_s"])}
        row["best_fixed"] = min(fixed, key=fixed.get) if fixed else ""
        row["best_fixed_s"] = fixed.get(row["best_fixed"], math.nan)
        row["ratio"] = (row["best_fixed_s"] / row["dop853_s"]
                        if math.isfinite(row["best_fixed_s"]) and math.isfinite(row["dop853_s"]) else math.nan)
        row["steps_ratio"] = (row[f"{row['best_fixed']}_steps"] / row["dop853_steps"]
                              if row["best_fixed"] and math.isfinite(row["dop853_steps"]) else math.nan)
        if not row["measurable"]:
            row["verdict"] = "not measurable (below the reference's floor)"
        elif not math.isfinite(row["dop853_s"]):
            row["verdict"] = "dop853 does not reach it"
        elif not fixed:
            # the ladders stopped before this error: each fixed method needs more than its slowest point's time
            bound = min(row[f"{m}_more_than_s"] for m in ("rk4", "rk8")) / row["dop853_s"]
            row["ratio_more_than"] = bound
            row["verdict"] = (f"met (> {bound:.3g}x: no fixed-step point reaches it)" if bound >= TARGET else
                              "undecided (the fixed-step ladders stop before it)")
        else:
            row["verdict"] = "met" if row["ratio"] >= TARGET else "missed"
        rows.append(row)
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(prog="eccentric_orbit", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="200 samples, few points, 1 repeat: about 20 s")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default benchmarks/results, or benchmarks/results/quick with --quick)")
    parser.add_argument("--reanalyse", type=Path, default=None, metavar="JSON",
                        help="make the comparisons and the report again from a saved results JSON; run nothing")
    args = parser.parse_args(argv)
    cfg = dict(QUICK if args.quick else FULL)
    out = args.out or (RESULTS / "quick" if args.quick else RESULTS)
    if args.reanalyse is not None:
        return reanalyse(args.reanalyse, args.out or args.reanalyse.parent)
    n, repeats, max_s = cfg["samples"], cfg["repeats"], cfg["max_point_s"]

    load_before = os.getloadavg()
    if load_before[0] > 0.5 * (os.cpu_count() or 1):
        _say(f"note: load average {load_before[0]:.2f} on {os.cpu_count()} cores; timings may be inflated")
    started_all = time.perf_counter()
    y0 = initial_states(n, cfg["seed"])
    subset = np.unique(np.linspace(0, n - 1, cfg["scipy_subset"]).round().astype(int))

    # first calls: compile or cache load, apart
    compile_s = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for name, call in (("dop853", lambda: tumble.integrate(SYSTEM, y0[:2], 1.0, method="dop853",
                                                               rtol=1e-8, atol=1e-8)),
                           ("rk4", lambda: tumble.integrate(SYSTEM, y0[:2], 1.0, 0.25, method="rk4")),
                           ("rk8", lambda: tumble.integrate(SYSTEM, y0[:2], 1.0, 0.25, method="rk8"))):
            started = time.perf_counter()
            call()
            compile_s[name] = time.perf_counter() - started
    per_sample_warnings = [str(w.message) for w in caught if "one sample at a time" in str(w.message)]
    block = block_path_used(SYSTEM)
    _say(f"first calls (compile or cache load): {compile_s}; block path: {block}")

    # the reference, and what bounds its accuracy
    started = time.perf_counter()
    ref_ds = tumble.integrate(SYSTEM, y0, T_END, method="dop853", rtol=REFERENCE_TOL[0], atol=REFERENCE_TOL[1])
    reference_s = time.perf_counter() - started
    ref = _final(ref_ds)
    brief = _final(tumble.integrate(SYSTEM, y0, T_END, method="dop853", rtol=BRIEF_TOL[0], atol=BRIEF_TOL[1]))
    brief_theta, brief_state = _errors(brief, ref)
    # SciPy on the most sensitive samples (where the looser run strays most) and a few others
    worst = list(np.argsort(brief_theta)[::-1][:cfg["checked"]])
    checked = sorted(set(int(i) for i in worst) | set(int(i) for i in np.linspace(0, n - 1, cfg["checked"])))
    scipy_check = {}
    for rtol, atol in SCIPY_CHECK_TOLS:
        d = np.array([solve_ivp(scipy_rate, (0.0, T_END), y0[i], method="DOP853", rtol=rtol, atol=atol).y[:, -1]
                      for i in checked]) - ref[checked]
        scipy_check[f"{rtol:g}/{atol:g}"] = dict(theta_max=float(np.abs(d[:, 0]).max()),
                                                 state_max=float(np.abs(d).max()),
                                                 theta=[float(x) for x in d[:, 0]])
    floor = scipy_check[_TIGHTEST]["theta_max"]
    floor_median = float(np.median(brief_theta))
    f_exact = float(np.abs(ref[:, 2] - T_END).max())  # f after two orbits is 4 pi
    _say(f"reference {reference_s:.2f} s; floor (max |theta|) {floor:.2g}, median {floor_median:.2g}; "
         f"|f - 4 pi| {f_exact:.2g}")

    # tumble: dop853 over the tolerances, rk4 and rk8 over their ladders. A first, untimed pass gives each point's
    # result (and where a ladder stops); then `repeats` timed passes over all the points, so that load from other
    # processes falls on every method alike; each point's time is its median.
    runs = {"dop853": [], "rk4": [], "rk8": []}  # (setting, call, first pass's Dataset)
    for tol in cfg["rtols"]:
        call = (lambda tol=tol: tumble.integrate(SYSTEM, y0, T_END, method="dop853", rtol=tol,
                                                 atol=tol * ATOL_FACTOR))
        runs["dop853"].append((tol, call, call()))
    for method, ladder in cfg["ladders"].items():
        last = None  # (count, seconds, error) of the ladder's last point
        for count in ladder:
            if last and last[1] * count / last[0] > max_s:
                _say(f"{method}: stop before N = {count} (would take more than {max_s:g} s)")
                break
            if last and last[2] < 0.1 * floor:
                break
            call = _quiet(lambda m=method, c=count: tumble.integrate(SYSTEM, y0, T_END, T_END / c, method=m))
            started = time.perf_counter()
            ds = call()
            last = (count, time.perf_counter() - started, float(_errors(_final(ds), ref)[0].max()))
            runs[method].append((count, call, ds))
    wake = {"dop853": lambda: tumble.integrate(SYSTEM, y0[:2], 0.1, method="dop853", rtol=1e-6, atol=1e-8),
            "rk4": lambda: tumble.integrate(SYSTEM, y0[:2], 0.1, 0.05, method="rk4"),
            "rk8": lambda: tumble.integrate(SYSTEM, y0[:2], 0.1, 0.05, method="rk8")}
    walls = {(name, k): [] for name, points in runs.items() for k in range(len(points))}
    for rep in range(repeats):
        for name, points in runs.items():
            for k, (setting, call, _) in enumerate(points):
                wake[name]()  # the thread pool awake, the method's code warm
                started = time.perf_counter()
                call()
                walls[(name, k)].append(time.perf_counter() - started)
        _say(f"timed pass {rep + 1} of {repeats} done")

    curves = {"dop853": [], "rk4": [], "rk8": []}
    for k, (tol, _, ds) in enumerate(runs["dop853"]):
        wall = float(np.median(walls[("dop853", k)]))
        steps, rejected = ds["steps"].values, ds["rejected_steps"].values
        point, _ = _point(tol, wall, walls[("dop853", k)], _final(ds), ref, subset,
                          steps_per_sample=float((steps + rejected).mean()),
                          accepted_per_sample=float(steps.mean()), rejected_per_sample=float(rejected.mean()),
                          most_steps=int((steps + rejected).max()),
                          subset_steps_per_sample=float((steps + rejected)[subset].mean()),
                          failed=int((ds["status"].values != 0).sum()),
                          sample_steps_per_s=float((steps + rejected).sum() / wall))
        curves["dop853"].append(point)
        _say(f"dop853 rtol {tol:.2g}: {_fmt_s(wall)}, error {point['error_max']:.2g}, "
             f"steps {point['accepted_per_sample']:.1f} + {point['rejected_per_sample']:.1f} rejected")
    for method in cfg["ladders"]:
        for k, (count, _, ds) in enumerate(runs[method]):
            wall = float(np.median(walls[(method, k)]))
            point, _ = _point(count, wall, walls[(method, k)], _final(ds), ref, subset, steps_per_sample=float(count),
                              dt=T_END / count, n_steps=int(ds.attrs.get("n_steps", count)),
                              failed=int((ds["status"].values != 0).sum()),
                              sample_steps_per_s=float(count * n / wall))
            curves[method].append(point)
            _say(f"{method} N = {count}: {_fmt_s(wall)}, error {point['error_max']:.2g}")
    del runs  # the Datasets

    # SciPy, one sample at a time, on the subset
    scipy_curve = []
    for tol in cfg["scipy_rtols"]:
        ends, accepted, nfev, spent = [], [], [], 0.0
        for i in subset:
            started = time.perf_counter()
            sol = solve_ivp(scipy_rate, (0.0, T_END), y0[i], method="DOP853", rtol=tol, atol=tol * ATOL_FACTOR)
            spent += time.perf_counter() - started
            ends.append(sol.y[:, -1])
            accepted.append(len(sol.t) - 1)
            nfev.append(sol.nfev)
        theta, state = _errors(np.array(ends), ref[subset])
        attempts = (np.array(nfev) - SCIPY_EVALS_START) / SCIPY_EVALS_PER_STEP
        ours = next((p for p in curves["dop853"] if math.isclose(p["setting"], tol)), None)
        scipy_curve.append(dict(setting=tol, wall_s=spent * n / len(subset), wall_subset_s=spent,
                                error_subset_max=float(theta.max()), error_subset_median=float(np.median(theta)),
                                error_state_max=float(state.max()), steps_per_sample=float(attempts.mean()),
                                accepted_per_sample=float(np.mean(accepted)), nfev_per_sample=float(np.mean(nfev)),
                                tumble_dop853_subset_steps=ours["subset_steps_per_sample"] if ours else None))
        _say(f"scipy DOP853 rtol {tol:.0e}: {spent:.2f} s on {len(subset)} samples, error {theta.max():.2g}, "
             f"steps {attempts.mean():.1f}")

    elapsed = time.perf_counter() - started_all
    load_after = os.getloadavg()

    result = {
        **provenance.stamp(), "tumble_source_digest": provenance.source_digest(), "cores": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "versions": {"tumble": tumble.__version__, "numpy": np.__version__, "numba": numba.__version__,
                     "scipy": scipy.__version__, "python": sys.version.split()[0]},
        "load_average_before": list(load_before), "load_average_after": list(load_after), "elapsed_s": elapsed,
        "quick": bool(args.quick), "settings": cfg,
        "scene": {"eccentricity": ECCENTRICITY, "w0": W0, "t_end": T_END, "orbits": 2, "samples": n,
                  "theta0": "uniform [0, pi)", "theta_dot0": "uniform [0, 3]", "f0": 0.0, "seed": cfg["seed"]},
        "block_path": block, "per_sample_warnings": per_sample_warnings, "compile_s": compile_s,
        "stages": {"dop853": 12, "rk4": 4, "rk8": 12},
        "reference": {"rtol": REFERENCE_TOL[0], "atol": REFERENCE_TOL[1], "wall_s": reference_s,
                      "steps_per_sample": float((ref_ds["steps"] + ref_ds["rejected_steps"]).values.mean()),
                      "f_minus_4pi_max": f_exact,
                      "vs_dop853_1e-13_1e-15": {"theta_max": float(brief_theta.max()),
                                                "theta_median": floor_median, "state_max": float(brief_state.max())},
                      "scipy_checked_samples": checked, "vs_scipy": scipy_check},
        "error": "max over samples of |theta(t_end) - theta_ref(t_end)| (rad); also its median",
        "curves": curves, "scipy": {"subset": [int(i) for i in subset], "curve": scipy_curve},
        "target": {"ratio": TARGET, "errors": ERRORS,
                   "measurable": f"error >= {MEASURABLE:g} x the reference's floor"},
    }
    _write(analyse(result), out)
    return 0


def analyse(result):
    """The comparisons at equal error, from a run's measurements (``result``, as written to the JSON): the reference's
    floors, dop853 against the fixed steps at the max and at the median error, and SciPy against rk8 and dop853."""
    ref, curves, scipy_curve = result["reference"], result["curves"], result["scipy"]["curve"]
    # the floor of the max error: the reference against SciPy at its tightest tolerance, on the samples checked
    # (the most sensitive among them); of the median: against dop853 at rtol 1e-13 (ten times looser: an upper bound)
    floor = ref["vs_scipy"][_TIGHTEST]["theta_max"]
    floor_median = ref["vs_dop853_1e-13_1e-15"]["theta_median"]
    ref.update(floor_theta_max=floor, floor_theta_median=floor_median,
               floors="max: the reference against SciPy DOP853 at rtol 2.3e-14 on the samples checked; median: "
                      "against dop853 at rtol 1e-13 (an upper bound)")
    result["comparison_max"] = compare(curves, "error_max", ERRORS, floor)
    result["comparison_median"] = compare(curves, "error_median", ERRORS, floor_median)
    rows = []
    for target in ERRORS:
        s_errs = [p["error_subset_max"] for p in scipy_curve]
        row = dict(error=target, measurable=bool(target >= MEASURABLE * floor),
                   scipy_steps=_at([p["steps_per_sample"] for p in scipy_curve], s_errs, target),
                   scipy_accepted=_at([p["accepted_per_sample"] for p in scipy_curve], s_errs, target),
                   scipy_s=_at([p["wall_s"] for p in scipy_curve], s_errs, target))
        for name in ("dop853", "rk8"):
            errs = [p["error_subset_max"] for p in curves[name]]
            row[f"{name}_steps"] = _at([p["steps_per_sample"] for p in curves[name]], errs, target)
            row[f"{name}_s"] = _at([p["wall_s"] for p in curves[name]], errs, target)
        row["rk8_over_scipy_steps"] = row["rk8_steps"] / row["scipy_steps"]
        row["rk8_over_scipy_accepted"] = row["rk8_steps"] / row["scipy_accepted"]
        row["scipy_over_dop853_time"] = row["scipy_s"] / row["dop853_s"]
        rows.append(row)
    result["scipy_comparison"] = rows
    return result


def _write(result, out):
    out.mkdir(parents=True, exist_ok=True)
    (out / "eccentric_orbit.json").write_text(json.dumps(_clean(result), indent=1) + "\n")
    report = _report(result)
    (out / "eccentric_orbit.md").write_text(report)
    print(report)
    print(f"wrote {out / 'eccentric_orbit.md'}, {out / 'eccentric_orbit.json'}")


def reanalyse(path, out):
    """The comparisons and the report made again from a saved JSON's measurements (nothing is run)."""
    result = json.loads(Path(path).read_text())
    result["reanalysed"] = date.today().isoformat()
    _write(analyse(result), out)
    return 0


def _clean(x):
    """JSON-ready: numpy scalars as Python numbers, NaN and inf as None, tuples as lists."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_clean(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return _num(x)
    return x


def _report(r):
    ref, s = r["reference"], r["scene"]
    lines = [f"# Where adaptivity pays: an eccentric spin-orbit ensemble — {r['date']}", "",
             f"{s['samples']} samples of the planar spin-orbit problem (w0 = {s['w0']}, e = {s['eccentricity']}, "
             f"n = 1; theta0 {s['theta0']}, theta_dot0 {s['theta_dot0']}, f0 = 0, seed {s['seed']}) over two orbits "
             f"(t_end = 4 pi), a user `tumble.System` (vectorised block path: {r['block_path']}). Error: max over "
             "samples of |theta(t_end) − theta_ref(t_end)| (rad). Wall time: median of "
             f"{r['settings']['repeats']} runs in interleaved passes over all the points, after an untimed pass; "
             "first calls apart.", "",
             f"Machine: {r['machine']}; numba threads {r['numba_threads']}; commit {r['commit']}, tumble sources "
             f"{r['tumble_source_digest']}; load average {r['load_average_before'][0]:.2f} before, "
             f"{r['load_average_after'][0]:.2f} after; whole run {r['elapsed_s']:.0f} s."
             + (" **Quick run: few points, not the benchmark's figures.**" if r["quick"] else "")
             + (f" **Note: other processes loaded the machine (load average {r['load_average_before'][0]:.2f} on "
                f"{r['cores']} cores): the times are inflated, the ratios (same run) less so.**"
                if r["load_average_before"][0] > 0.5 * (r["cores"] or 1) else ""), "",
             f"Reference: dop853 at rtol = {ref['rtol']:g}, atol = {ref['atol']:g} ({ref['wall_s']:.2f} s, "
             f"{ref['steps_per_sample']:.0f} steps per sample; |f − 4π| ≤ {ref['f_minus_4pi_max']:.2g}). Against "
             "SciPy DOP853 on samples " + ", ".join(map(str, ref["scipy_checked_samples"])) + ": "
             + "; ".join(f"rtol/atol {k}: max |Δtheta| {v['theta_max']:.2g}, state {v['state_max']:.2g}"
                         for k, v in ref["vs_scipy"].items())
             + f". Against dop853 at rtol 1e-13, atol 1e-15 (all samples): max |Δtheta| "
               f"{ref['vs_dop853_1e-13_1e-15']['theta_max']:.2g}, median "
               f"{ref['vs_dop853_1e-13_1e-15']['theta_median']:.2g}, state "
               f"{ref['vs_dop853_1e-13_1e-15']['state_max']:.2g}. The reference's floor: max "
               f"{ref['floor_theta_max']:.2g} (its distance to SciPy at rtol 2.3e-14 on the samples checked, the "
               "most sensitive among them), "
               f"median {ref['floor_theta_median']:.2g} (its distance to dop853 at rtol 1e-13, an upper bound); "
               f"errors below {MEASURABLE:g}× the floor are not compared."
             + (f" Comparisons made again on {r['reanalysed']} from the saved measurements." if r.get("reanalysed")
                else ""), "",
             f"## dop853 against the faster fixed step (target ≥ {TARGET:g}×)", "",
             "| error (max) | dop853 | steps/sample | rk4 | rk8 | rk8 steps | faster fixed / dop853 | steps ratio | "
             "target |", "|---|---|---|---|---|---|---|---|---|"]
    for row in r["comparison_max"]:
        lines.append(f"| {row['error']:.0e} | {_fmt_reach(row, 'dop853')} | {_fmt(row['dop853_steps'], '.0f')} | "
                     f"{_fmt_reach(row, 'rk4')} | {_fmt_reach(row, 'rk8')} | {_fmt(row['rk8_steps'], '.0f')} | "
                     f"{_fmt(row['ratio'], '.3g', '×')} {row['best_fixed']} | {_fmt(row['steps_ratio'], '.3g', '×')} "
                     f"| {row['verdict']} |")
    lines += ["", "The same at the median error over samples:", "",
              "| error (median) | dop853 | steps/sample | rk4 | rk8 | rk8 steps | faster fixed / dop853 | "
              "steps ratio | target |", "|---|---|---|---|---|---|---|---|---|"]
    for row in r["comparison_median"]:
        lines.append(f"| {row['error']:.0e} | {_fmt_reach(row, 'dop853')} | {_fmt(row['dop853_steps'], '.0f')} | "
                     f"{_fmt_reach(row, 'rk4')} | {_fmt_reach(row, 'rk8')} | {_fmt(row['rk8_steps'], '.0f')} | "
                     f"{_fmt(row['ratio'], '.3g', '×')} {row['best_fixed']} | {_fmt(row['steps_ratio'], '.3g', '×')} "
                     f"| {row['verdict']} |")
    sub = r["scipy"]["subset"]
    lines += ["", f"dop853 steps per sample: accepted + rejected (12 stages a step; rk8 has 12, rk4 4). Time and steps "
              "read off at equal error by log-log interpolation (— : not reached).", "",
              f"## SciPy `solve_ivp(DOP853)` on {len(sub)} samples (one at a time, Python right-hand side)", "",
              "Errors are the max over the same subset for every solver; SciPy's time is scaled to "
              f"{s['samples']} samples.", "",
              "| error (subset max) | SciPy steps (accepted) | rk8 steps | rk8 / SciPy steps (accepted) | "
              "tumble dop853 steps | SciPy time, scaled | tumble dop853 | SciPy / dop853 |",
              "|---|---|---|---|---|---|---|---|"]
    for row in r["scipy_comparison"]:
        mark = "" if row["measurable"] else " (below floor)"
        lines.append(f"| {row['error']:.0e}{mark} | {_fmt(row['scipy_steps'], '.0f')} "
                     f"({_fmt(row['scipy_accepted'], '.0f')}) | {_fmt(row['rk8_steps'], '.0f')} | "
                     f"{_fmt(row['rk8_over_scipy_steps'], '.3g', '×')} "
                     f"({_fmt(row['rk8_over_scipy_accepted'], '.3g', '×')}) | {_fmt(row['dop853_steps'], '.0f')} | "
                     f"{_fmt_s(row['scipy_s'])} | {_fmt_s(row['dop853_s'])} | "
                     f"{_fmt(row['scipy_over_dop853_time'], '.3g', '×')} |")
    lines += ["", "Same tolerance, same subset — steps per sample (accepted + rejected), SciPy against tumble's "
              "dop853: " + ", ".join(f"rtol {p['setting']:.0e}: {p['steps_per_sample']:.1f} / "
                          f"{_fmt(p['tumble_dop853_subset_steps'], '.1f')}" for p in r["scipy"]["curve"]) + ".", "",
              "## Cost of a step", "",
              "Sample-steps per second (dop853: accepted + rejected; each block's lanes take the next sample as "
              "soon as theirs is done): "
              + ", ".join(f"dop853 rtol {p['setting']:.2g}: {p['sample_steps_per_s']:.3g}"
                          for p in r["curves"]["dop853"][::4])
              + "; " + ", ".join(f"{m} N {p['setting']}: {p['sample_steps_per_s']:.3g}"
                                 for m in ("rk4", "rk8") for p in r["curves"][m][-1:]) + ".", "",
              "## First calls (compile or cache load), not in the times", "",
              ", ".join(f"{k}: {v:.2f} s" for k, v in r["compile_s"].items()) + ".", "",
              "## Points", ""]
    for name, points in r["curves"].items():
        what = "rtol" if name == "dop853" else "N"
        lines.append(f"- **{name}**: " + ", ".join(
            f"{what} {p['setting']:.2g}: {p['error_max']:.2g} (median {p['error_median']:.2g}) @ {_fmt_s(p['wall_s'])},"
            f" {p['steps_per_sample']:.0f} steps" if name == "dop853" else
            f"{what} {p['setting']}: {p['error_max']:.2g} (median {p['error_median']:.2g}) @ {_fmt_s(p['wall_s'])}"
            for p in points))
    lines.append("- **SciPy DOP853** (subset): " + ", ".join(
        f"rtol {p['setting']:.0e}: {p['error_subset_max']:.2g} @ {_fmt_s(p['wall_s'])} scaled, "
        f"{p['steps_per_sample']:.1f} steps" for p in r["scipy"]["curve"]))
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
