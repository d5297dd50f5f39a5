"""Scale-out benchmark: scan throughput in-process and on a dask LocalCluster, and the cost of a resume.

    python benchmarks/scale_out.py           # writes benchmarks/results/scale_out.md (and .json)
    python benchmarks/scale_out.py --quick   # small sizes, a smoke run (writes results/quick/)

One scan study (an inertia triangle x 3 axes, rk4 steps), run end to end by ``tumble.run_study`` into a fresh
folder — chunks checkpointed, result assembled and written — in four ways, interleaved, median of REPEATS:

- in-process, numba 1 thread; in-process, numba 2 threads;
- LocalCluster (127.0.0.1) with 1 worker process and with 2 (one thread each, numba 1 thread each),
  one cluster at a time, each interleaved with in-process runs.

The peer of the 2-worker cluster is the 1-worker cluster (target >= 1.7x). Cluster start-up and compile time
are excluded: each cluster runs the study once before it is timed (every worker loads the kernels then).
Resume: the same study rerun into a folder whose chunks are all finished (nothing to compute): the time to
read the checkpoint alone, and the whole rerun (read, assemble, write the result).
"""

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numba

import tumble
from tumble.pipeline import config, distributed, runner

import provenance  # benchmarks/provenance.py (the script's folder is on sys.path)
import timing  # benchmarks/timing.py

RESULTS = Path(__file__).with_name("results")
REPEATS = 3


def study(triangle, samples):
    return {"title": "scale_out", "perturbation": {"samples": samples},
            "scan": {"triangle": triangle, "axis": [1, 2, 3]}, "integration": {"method": "rk4", "flips": 0},
            "outputs": {"figures": [], "arrays": []}}


def timed_run(spec, cpu=None, **kwargs):
    """Wall seconds of one run into a fresh folder; the CPU seconds of this process are appended to ``cpu``."""
    with tempfile.TemporaryDirectory() as out:
        started, started_cpu = time.perf_counter(), time.process_time()
        tumble.run_study(spec, out=out, **kwargs)
        if cpu is not None:
            cpu.append(time.process_time() - started_cpu)
        return time.perf_counter() - started


def resume_cost(spec, chunk_scenes):
    """(seconds to read a finished checkpoint, seconds of the whole rerun) with every chunk finished."""
    resolved = config.load_study(spec)
    job = runner.scene_job(resolved)
    with tempfile.TemporaryDirectory() as out:
        store = runner.open_checkpoint(resolved, job, out, "scale_out")
        runner.run_scenes(job, store=store, chunk_scenes=chunk_scenes)
        started = time.perf_counter()
        done = runner.open_checkpoint(resolved, job, out, "scale_out").load()
        read = time.perf_counter() - started
        assert len(done.scenes) == job.layout["scenes"]
        started = time.perf_counter()
        tumble.run_study(spec, out=out, chunk_scenes=chunk_scenes)
        return read, time.perf_counter() - started


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, for a smoke run")
    args = parser.parse_args()
    triangle, samples = (3, 256) if args.quick else (6, 2048)
    spec = study(triangle, samples)
    scenes = runner.scene_job(config.load_study(spec)).layout["scenes"]
    chunk = runner.default_chunk_scenes(scenes)
    threads_before = numba.get_num_threads()
    load_before = os.getloadavg()[0]  # other work on the machine skews every ratio: reported with them

    def in_process(threads):
        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        try:
            return timed_run(spec, chunk_scenes=chunk)
        finally:
            numba.set_num_threads(threads_before)

    timings = {"in-process, numba 1 thread": [], "in-process, numba 2 threads": [],
               "LocalCluster, 1 worker": [], "LocalCluster, 2 workers": []}
    client_cpu = {"LocalCluster, 1 worker": [], "LocalCluster, 2 workers": []}  # the process running tumble
    in_process(2)  # compile / load the kernels
    # One cluster at a time (a process holding two dask clients confuses their event loops); the in-process
    # runs are interleaved with each cluster's, so that all four see the same machine load.
    for workers in (1, 2):
        name = f"LocalCluster, {workers} worker{'s' if workers > 1 else ''}"
        with distributed.connect("local", workers=workers) as client:
            timed_run(spec, scheduler=client, chunk_scenes=1)  # every worker loads the kernels
            for _ in range(REPEATS):
                timings["in-process, numba 1 thread"].append(in_process(1))
                timings["in-process, numba 2 threads"].append(in_process(2))
                timings[name].append(timed_run(spec, client_cpu[name], scheduler=client, chunk_scenes=chunk))
    medians = {name: statistics.median(values) for name, values in timings.items()}
    read, rerun = resume_cost(spec, chunk)

    peer = medians["LocalCluster, 1 worker"]
    speedup = peer / medians["LocalCluster, 2 workers"]
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%MZ")
    machine = (f"{platform.machine()}, {os.cpu_count()} cores, {timing.vector_width()}, numba {numba.__version__} "
               f"(NUMBA_NUM_THREADS={numba.config.NUMBA_NUM_THREADS}), Python {platform.python_version()}; "
               f"load average before / after {load_before:.2f} / {os.getloadavg()[0]:.2f}")
    lines = [
        "# Scale-out: scan throughput in-process and on a dask LocalCluster",
        "",
        f"Measured {stamp} by `python benchmarks/scale_out.py`{' --quick' if args.quick else ''}. Machine: {machine}.",
        "",
        f"Study: {triangle} x {triangle} inertia triangle x 3 axes = {scenes} scenes of {samples} samples, rk4 steps, "
        f"{chunk} scene(s) per chunk; each run writes its chunks and the result file into a fresh folder. Median of "
        f"{REPEATS} interleaved runs (in-process: 2 x {REPEATS}); cluster start-up and compile time excluded.",
        "",
        "| how | wall, s | scenes/s | vs 1 worker | CPU of the client process, s |",
        "|---|---|---|---|---|",
    ]
    for name, seconds in medians.items():
        cpu = f"{statistics.median(client_cpu[name]):.2f}" if name in client_cpu else "(all of it)"
        lines.append(f"| {name} | {seconds:.2f} | {scenes / seconds:.2f} | {peer / seconds:.2f}x | {cpu} |")
    verdict = "met" if speedup >= 1.7 else "missed"
    lines += [
        "",
        f"2 workers against 1 worker: **{speedup:.2f}x** (target >= 1.7x: {verdict}).",
        "",
        f"Resume with every chunk finished: reading the checkpoint ({scenes} scenes in "
        f"{-(-scenes // chunk)} chunk files) {read:.3f} s; the whole rerun (read, assemble, write the result) "
        f"{rerun:.2f} s, against {medians['in-process, numba 2 threads']:.2f} s for computing the scan in-process.",
    ]
    folder = RESULTS / "quick" if args.quick else RESULTS
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "scale_out.md").write_text("\n".join(lines) + "\n")
    (folder / "scale_out.json").write_text(json.dumps(
        {**provenance.stamp(), "date": stamp, "machine": machine, "scenes": scenes, "samples": samples,
         "chunk_scenes": chunk,
         "timings_s": timings, "medians_s": medians, "client_cpu_s": client_cpu, "speedup_2_over_1_worker": speedup,
         "resume_read_s": read, "resume_rerun_s": rerun}, indent=2) + "\n")
    print("\n".join(lines))
    print(f"\nwrote {folder / 'scale_out.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
