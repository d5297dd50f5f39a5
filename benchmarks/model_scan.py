"""Model scan benchmark: a 20 x 20 x 3 gyrostat stability map (issue 18's target: under 10 s warm on 2 cores).

    python benchmarks/model_scan.py     # writes benchmarks/results/model_scan.md and model_scan.json

The map: the free body's ``stability_map`` bodies (``scan.triangle = 20``: I3 = 1 the largest, I1 <= I2), spun at
1 rad/s about each of the 3 axes, with a rotor of h = 0.1 N m s along the spin axis (``scan.rotor = [0.1]``), 256
samples a scene, amplitude 1e-4, rk4; no figures, no files. Timed: ``tumble.run_study`` of it in this process, warm
(the first run, reported apart, loads the model kernels from numba's cache or compiles them), the median of
:data:`REPEATS` runs; then its parts: planning the 1200 scenes and measuring them in the chunks ``tumble run``
uses, checked to give the same bits as scene by scene. The accuracy of the map (largest ``rel_error``) and the
load average before and after go beside the times: the machine is shared.
"""

import json
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

import tumble
from tumble.measure import model_scenes
from tumble.pipeline import config, runner

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

RESULTS = Path(__file__).with_name("results")
REPEATS = 3
STUDY = {"title": "gyrostat map benchmark", "model": {"kind": "gyrostat"},
         "perturbation": {"samples": 256, "amplitude": 1e-4},
         "scan": {"triangle": 20, "axis": [1, 2, 3], "rotor": [0.1]}, "outputs": {"figures": [], "arrays": []}}


def main():
    RESULTS.mkdir(exist_ok=True)
    machine = timing.machine()
    load_before = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    started = time.perf_counter()
    ds = tumble.run_study(STUDY, progress=False)
    first = time.perf_counter() - started
    whole = timing.median_seconds(lambda: tumble.run_study(STUDY, progress=False), REPEATS)

    job = runner.scene_job(config.load_study(STUDY))
    n = job.layout["scenes"]
    plans = [runner._scene_plan(job, i) for i in range(n)]
    planning = timing.median_seconds(lambda: [runner._scene_plan(job, i) for i in range(n)], REPEATS)
    step = runner.default_chunk_scenes(n)

    def batched():
        return [r for lo in range(0, n, step) for r in model_scenes.scene_batch(plans[lo:lo + step])]

    t_batched = timing.median_seconds(batched, REPEATS)
    same = all(all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a)
               for a, b in zip(batched(), [model_scenes.scene_batch([p])[0] for p in plans]))
    kinds, counts = np.unique(ds.kind.values, return_counts=True)
    sample_steps = sum(p.plan.n_steps for p in plans) * job.samples
    load_after = " ".join(Path("/proc/loadavg").read_text().split()[:3])
    report = {**provenance.stamp(), "machine": machine, "threads": numba.get_num_threads(), "scenes": n,
              "samples": job.samples, "first": first, "study": whole, "planning": planning, "measuring": t_batched,
              "chunk": step, "same_bits": same, "sample_steps": sample_steps,
              "kinds": dict(zip(kinds.astype(str).tolist(), counts.tolist())),
              "max_rel_error": float(np.nanmax(ds.rel_error.values)), "load_before": load_before,
              "load_after": load_after, "cpus": os.cpu_count()}
    (RESULTS / "model_scan.json").write_text(json.dumps(report, indent=1))
    lines = [f"# Model scan benchmark — {report['date']}", "",
             f"Machine: {machine} (4 doubles per AVX2 register); numba threads: {report['threads']}. A gyrostat "
             f"stability map: the 20 × 20 inertia triangle × 3 spin axes = {n} scenes of {job.samples} samples, rotor "
             f"h = 0.1 N m s along the spin axis, rk4; medians of {REPEATS} runs, warm. Load average (1, 5, 15 min) "
             f"before / after: {load_before} / {load_after} (a shared 2-core machine).", "",
             "| part | seconds |", "|---|---|",
             f"| `tumble.run_study(map)`, no files written | **{whole:.2f}** |",
             f"| first run in the process (model kernels loaded from numba's cache, or compiled) | {first:.2f} |",
             f"| planning the {n} scenes | {planning:.2f} |",
             f"| measuring the scenes ({step} a chunk, as `tumble run`) | {t_batched:.2f} |", "",
             f"Scenes: {report['kinds']}; {sample_steps / 1e6:.0f} M sample-steps in all. Largest `rel_error` of the "
             f"map: {report['max_rel_error']:.1e}. Chunked records the same bits as scene by scene: {same}. "
             f"Target: under 10 s warm on 2 cores."]
    (RESULTS / "model_scan.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(*sys.argv[1:])
