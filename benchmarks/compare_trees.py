"""Kernel throughput of two source trees of tumble, alternating in one session: an A/B of a change.

    python benchmarks/compare_trees.py OLD_TREE NEW_TREE [rounds]

Each round runs every tree in a fresh process (its own kernels, compiled or loaded from its own cache;
compile time excluded) and prints sample-steps/s of rk4, splitting2 and rk8 on 20 000 samples, medians of 5
runs. Machines here differ from day to day; compare trees only within one invocation.
"""

import subprocess
import sys

_ONE_TREE = r"""
import sys, time, numpy as np
sys.path.insert(0, sys.argv[1])
from tumble.kernels.methods import METHODS, run
rng = np.random.default_rng(0)
w0 = np.ascontiguousarray((rng.normal(size=(20000, 3)) * 0.5).T)
moments = np.array([1.0, 2.0, 3.0])
rates = []
for name, steps in (("rk4", 2000), ("splitting2", 1000), ("rk8", 500)):
    method = METHODS[name]
    run(method, w0[:, :8].copy(), moments, 0.0, 1e-3, 1)
    times = []
    for _ in range(5):
        w = w0.copy()
        started = time.perf_counter()
        run(method, w, moments, 0.0, 1e-3, steps)
        times.append(time.perf_counter() - started)
    rates.append(f"{name} {20000 * steps / np.median(times):.3g}")
print(sys.argv[1], "  ".join(rates))
"""


def main(trees, rounds=2):
    for _ in range(rounds):
        for tree in trees:
            subprocess.run([sys.executable, "-c", _ONE_TREE, tree], check=True)


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1:3], int(sys.argv[3]) if len(sys.argv) > 3 else 2)
