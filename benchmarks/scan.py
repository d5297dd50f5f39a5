"""Scan benchmark: the bundled ``stability_map`` study end to end, and its scenes batched against scene by scene.

    python benchmarks/scan.py          # writes benchmarks/results/scan.md and scan.json
    python benchmarks/scan.py big      # also the 100 x 100 x 3 map (30 000 scenes; minutes) with its peak memory

* ``study``: ``tumble.run_study("stability_map")`` in this process (20 x 20 bodies x 3 axes, 256 samples a
  scene, closed form), warm: planning, the batched closed form, the estimators, the summaries and the dataset;
  figures and the netCDF file are not written (no ``out``).
* ``batched`` against ``one by one``: the same 1200 scene plans measured by :func:`tumble.measure.scans.scene_batch`
  in chunks of 38 scenes (what ``tumble run`` does) and one scene per call (the scene-by-scene path), in the
  same run, on the same plans; the records are checked to be the same bits.

* ``big``: the same study on a 100 x 100 triangle (30 000 scenes of 256 samples) in a fresh process: its wall
  time (cached kernels loaded, not compiled) and the process's peak resident memory.

Compile time is excluded (everything runs once first, and the first run's time is reported apart); each timing
is the median of several runs.
"""

import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np

import tumble
from tumble.measure import scans
from tumble.measure.records import assemble_scan
from tumble.pipeline import config, runner

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

RESULTS = Path(__file__).with_name("results")
REPEATS = 3


def median_seconds(fn, repeats=REPEATS):
    return timing.median_seconds(fn, repeats)


_BIG = """
import time, tumble
started = time.perf_counter()
ds = tumble.run_study("stability_map", overrides={"scan.triangle": 100}, progress=False)
print(time.perf_counter() - started, int(ds.sizes["body"]) * int(ds.sizes["axis"]))
"""


def big_map():
    """Seconds, scenes and peak resident memory (MiB) of the 100 x 100 x 3 map in a fresh process."""
    done = subprocess.run([sys.executable, "-c", _BIG], capture_output=True, text=True, check=True)
    seconds, scenes = done.stdout.split()
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # KiB on Linux
    return {"seconds": float(seconds), "scenes": int(scenes), "peak_mib": peak}


def main(parts=()):
    RESULTS.mkdir(exist_ok=True)
    machine = timing.machine()

    started = time.perf_counter()
    tumble.run_study("stability_map", progress=False)
    first = time.perf_counter() - started
    whole = median_seconds(lambda: tumble.run_study("stability_map", progress=False))

    job = runner.scene_job(config.load_study("stability_map"))
    n = job.layout["scenes"]
    plans = [runner._scene_plan(job, i) for i in range(n)]
    planning = median_seconds(lambda: [runner._scene_plan(job, i) for i in range(n)])
    step = runner.default_chunk_scenes(n)

    def batched():
        return [r for lo in range(0, n, step) for r in scans.scene_batch(plans[lo:lo + step])]

    def one_by_one():
        return [scans.scene_batch([plan])[0] for plan in plans]

    same = all(all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a)
               for a, b in zip(batched(), one_by_one()))
    t_batched, t_single = median_seconds(batched), median_seconds(one_by_one)
    records = batched()
    assemble = median_seconds(lambda: assemble_scan(job.layout, records, job.body_coords))

    big = big_map() if "big" in parts else None
    report = {**provenance.stamp(), "machine": machine, "threads": numba.get_num_threads(), "scenes": n,
              "samples": job.samples, "study_first": first, "study": whole, "planning": planning,
              "batched": t_batched, "one_by_one": t_single, "assemble": assemble, "same_bits": same, "big": big}
    (RESULTS / "scan.json").write_text(json.dumps(report, indent=1))
    lines = [f"# Scan benchmark — {report['date']}", "",
             f"Machine: {machine}; numba threads: {report['threads']}. Bundled `stability_map`: {n} scenes of "
             f"{report['samples']} samples (closed form); medians of {REPEATS} runs, warm.", "",
             "| part | seconds |", "|---|---|",
             f"| `tumble.run_study(\"stability_map\")`, no files written (first run in the process: "
             f"{first:.2f} s) | {whole:.2f} |",
             f"| planning the {n} scenes | {planning:.2f} |",
             f"| measuring the scenes batched ({step} a call, as `tumble run`) | {t_batched:.2f} |",
             f"| measuring the scenes one by one (one scene a call) | {t_single:.2f} |",
             f"| assembling the scan dataset from the records | {assemble:.3f} |", "",
             f"Batched against one by one: **{t_single / t_batched:.1f}x**; records the same bits: {same}."]
    if big:
        lines += ["", f"100 × 100 × 3 map ({big['scenes']} scenes of 256 samples), `run_study` in a fresh process "
                  f"(cached kernels loaded, no files written): **{big['seconds']:.1f} s**, peak resident memory "
                  f"**{big['peak_mib']:.0f} MiB** (targets: 60 s, 2 GB)."]
    (RESULTS / "scan.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
