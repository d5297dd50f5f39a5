"""DeBra-Delp map benchmark: the gravity-gradient stability map over (k1, k3), 40 x 40 bodies, 256 samples a scene
(issue 19's target: under 20 s warm on 2 cores).

    python benchmarks/debra_delp.py     # writes benchmarks/results/debra_delp.md

The map: ``studies/debra_delp_map.toml`` with the 40 x 40 grid of cell centres of (-1, 1)² (``scan.k1``,
``scan.k3``), 256 samples, no figures, no files. Timed: ``tumble.run_study`` in this process; the first run
(loading the model kernels from numba's cache, or compiling them) apart, then the median of :data:`REPEATS` warm
runs. The map's accuracy (largest and median ``rel_error`` by kind; kinds against the closed form off the
diagonal) and the load average before and after go beside the times: the machine is shared.
"""

import subprocess
import time
from datetime import date
from pathlib import Path

import numpy as np

import tumble
from tumble.physics import theory

import timing  # benchmarks/timing.py (the script's folder is on sys.path)

RESULTS = Path(__file__).with_name("results")
REPEATS = 3
N = 40
GRID = [float(x) for x in -1.0 + (2.0 * np.arange(N) + 1.0) / N]
STUDY = {"title": "DeBra-Delp map benchmark", "model": {"kind": "gravity_gradient", "orbit_rate": 1.0},
         "perturbation": {"samples": 256, "amplitude": 1e-4}, "scan": {"k1": GRID, "k3": GRID},
         "outputs": {"figures": [], "arrays": []}}


def main():
    RESULTS.mkdir(exist_ok=True)
    machine = timing.machine()
    load_before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    started = time.perf_counter()
    ds = tumble.run_study(STUDY, progress=False)
    first = time.perf_counter() - started
    warm = timing.median_seconds(lambda: tumble.run_study(STUDY, progress=False), REPEATS)
    load_after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    kinds = ds.kind.values.astype(str)
    error = ds.rel_error.values
    k1, k3 = ds.k1.values, ds.k3.values
    off = k1 != k3
    agree = np.array_equal(theory.gravity_gradient_stable(k1, k3)[off], kinds[off] == "periodic")
    rows = [f"| {kind} | {int((kinds == kind).sum())} | {np.nanmedian(error[kinds == kind]):.2e} | "
            f"{np.nanmax(error[kinds == kind]):.2e} |" for kind in np.unique(kinds)]
    text = "\n".join([
        f"# DeBra-Delp map benchmark ({date.today().isoformat()})", "",
        f"Machine: {machine}", "",
        f"Load before: `{load_before}`", "",
        f"Load after: `{load_after}`", "",
        "40 x 40 bodies (k1, k3 cell centres of (-1, 1)², I2 = 1), n = 1 rad/s, 256 samples, amplitude 1e-4, rk4.", "",
        "| run | seconds |", "|---|---|",
        f"| first (kernels loaded from numba's cache or compiled) | {first:.2f} |",
        f"| warm, median of {REPEATS} | {warm:.2f} |", "",
        "| kind | scenes | median rel_error | worst rel_error |", "|---|---|---|---|", *rows, "",
        f"Kinds agree with the closed form (gravity_gradient_stable) off the diagonal k1 = k3: {agree}.", ""])
    (RESULTS / "debra_delp.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
