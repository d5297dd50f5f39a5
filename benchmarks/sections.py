"""Poincaré sections, error-controlled: tumble.section against SciPy's solve_ivp with events, in one run.

    python benchmarks/sections.py [--quick]     # writes benchmarks/results/sections.md and .json

The scene: an asymmetric heavy top (I = (1, 1.6, 2.2) kg m², mgl = 1 N m, centre of mass towards (0.6, 0.3, 1)),
whose energy surface holds regular tori and a chaotic layer; 2 000 releases (w3 from 0.5 to 3 rad/s, a tilt of the
up vector), integrated to T = 1 000 s at rtol = 1e-10, atol = 1e-12, with the section g1 = 0 crossed upward.

* ``tumble.section`` on every release (the built-in model, DOP853 on the CPU's vectorised blocks), median of runs,
  compile apart;
* SciPy's ``solve_ivp(DOP853, events=g1)`` on a subset of releases (a Python right-hand side, one release at a
  time, the way a user writes it), its time scaled to the 2 000;
* accuracy: each one's crossing times over the first 100 s against SciPy at rtol = 2.3e-14 on the subset (the
  horizon a chaotic orbit's crossings can be compared over).

Targets (the tolerance issue): the 2 000 releases within 5 s, and >= 100x SciPy at equal accuracy.
"""

import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import tumble

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

HERE = Path(__file__).resolve().parent
MOMENTS, MGL, CENTRE = (1.0, 1.6, 2.2), 1.0, (0.6, 0.3, 1.0)
RTOL, ATOL = 1e-10, 1e-12
COMPARED = 100.0  # s: the horizon over which crossing times are compared


def releases(n):
    """``n`` states: w3 from 0.5 to 3 rad/s, w1 = w2 = 0.1, the up vector tilted 0.4 rad about a turning axis."""
    spin = np.linspace(0.5, 3.0, n)
    angle = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    up = np.stack([0.4 * np.cos(angle), 0.4 * np.sin(angle), np.ones(n)], axis=1)
    up /= np.linalg.norm(up, axis=1)[:, None]
    return np.column_stack([np.full(n, 0.1), np.full(n, 0.1), spin, up])


def scipy_rate(top):
    """The heavy top's equations as a user writes them for SciPy."""
    inertia = np.array(MOMENTS)
    c = np.array(CENTRE) / np.linalg.norm(CENTRE)

    def rate(t, y):
        w, g = y[:3], y[3:]
        dw = (np.cross(inertia * w, w) + MGL * np.cross(g, c)) / inertia
        return np.concatenate([dw, np.cross(g, w)])

    return rate


def scipy_section(rate, y0, t_end, rtol, atol):
    def g1(t, y):
        return y[3]

    g1.direction = 1
    started = time.perf_counter()
    sol = solve_ivp(rate, (0.0, t_end), y0, method="DOP853", rtol=rtol, atol=atol, events=g1)
    return time.perf_counter() - started, sol.t_events[0]


def main(quick=False):
    n, t_end, subset, repeats = (200, 200.0, 2, 2) if quick else (2000, 1000.0, 4, 3)
    top = tumble.models.HeavyTop(MOMENTS, MGL, centre=CENTRE)
    y0 = releases(n)
    started = time.perf_counter()
    tumble.section(top, y0[:2], 1.0, surface=("g1", 0.0), rtol=RTOL, atol=ATOL)  # compile (or load)
    compile_s = time.perf_counter() - started
    ds = None

    def run():
        nonlocal ds
        ds = tumble.section(top, y0, t_end, surface=("g1", 0.0), rtol=RTOL, atol=ATOL)

    run()
    ours = timing.median_seconds(run, repeats)
    crossings = int(ds["count"].sum())

    rate = scipy_rate(top)
    picked = np.linspace(0, n - 1, subset).astype(int)
    theirs = [scipy_section(rate, y0[i], t_end, RTOL, ATOL)[0] for i in picked]
    scipy_s = float(np.mean(theirs)) * n

    # accuracy over the first COMPARED s: tumble and SciPy at RTOL against SciPy at its tightest tolerance
    short = tumble.section(top, y0[picked], COMPARED, surface=("g1", 0.0), rtol=RTOL, atol=ATOL)
    ours_error = theirs_error = 0.0
    for row, i in enumerate(picked):
        reference = scipy_section(rate, y0[i], COMPARED, 2.3e-14, 1e-16)[1]
        ours_t = short.time.values[row, :int(short["count"][row])]
        theirs_t = scipy_section(rate, y0[i], COMPARED, RTOL, ATOL)[1]
        k = min(len(reference), len(ours_t), len(theirs_t))
        ours_error = max(ours_error, float(np.abs(ours_t[:k] - reference[:k]).max(initial=0.0)))
        theirs_error = max(theirs_error, float(np.abs(theirs_t[:k] - reference[:k]).max(initial=0.0)))

    result = {
        **provenance.stamp(), "releases": n, "t_end_s": t_end, "rtol": RTOL, "atol": ATOL,
        "crossings": crossings, "tumble_s": ours, "tumble_compile_s": compile_s,
        "scipy_subset": int(subset), "scipy_s_scaled": scipy_s, "speedup": scipy_s / ours,
        "crossing_time_error_tumble_s": ours_error, "crossing_time_error_scipy_s": theirs_error,
        "target_seconds": 5.0, "target_speedup": 100.0,
    }
    out = HERE / "results" / ("quick" if quick else "")
    out.mkdir(parents=True, exist_ok=True)
    (out / "sections.json").write_text(json.dumps(result, indent=2) + "\n")
    verdict = ("met" if ours <= 5.0 else "missed", "met" if scipy_s / ours >= 100.0 else "missed")
    (out / "sections.md").write_text(f"""# Poincaré sections — {result['date']}

Machine: {result['machine']}; commit {result['commit']}. {n} releases of the heavy top I = {MOMENTS} kg m², mgl =
{MGL} N m, centre towards {CENTRE}, to T = {t_end:g} s at rtol = {RTOL:g}, atol = {ATOL:g}; the section g1 = 0, upward.

| | time | crossings | crossing-time error (first {COMPARED:g} s) |
|---|---|---|---|
| `tumble.section` (DOP853, vectorised blocks, {result['vector_width']}) | {ours:.3g} s (target <= 5 s: {verdict[0]}) | {crossings} | {ours_error:.2g} s |
| SciPy `solve_ivp(DOP853, events)`, {subset} releases scaled to {n} | {scipy_s:.3g} s | | {theirs_error:.2g} s |
| speed-up | {scipy_s / ours:.3g}x (target >= 100x: {verdict[1]}) | | |

tumble's first call (compile or cache load): {compile_s:.2g} s, apart. Errors against SciPy at rtol = 2.3e-14.
""")
    print((out / "sections.md").read_text())


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
