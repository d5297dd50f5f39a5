"""Kernel throughput of two source trees of tumble, alternating in one session: an A/B of a change.

    python benchmarks/compare_trees.py OLD_TREE NEW_TREE [rounds]

After one warm-up round (not printed), each round runs every tree in a fresh process (its own kernels, compiled
or loaded from its own cache; compile time excluded) and prints sample-steps/s on 20 000 samples, medians of 5 runs: rk4, splitting2 and rk8 bare;
rk4 with a scene's observers (probes every 10 steps, flips, drift records and limit); rk4 with a drift limit alone
(``run_ensemble``'s default); rk4 with a constant torque; the
models' driver (heavy top rk4 with probes and drift). Machines here differ from day to day; compare trees only within
one invocation.
"""

import subprocess
import sys

_ONE_TREE = r"""
import sys, time, numpy as np
sys.path.insert(0, sys.argv[1])
from tumble.kernels.loops.methods import METHODS, run
rng = np.random.default_rng(0)
w0 = np.ascontiguousarray((rng.normal(size=(20000, 3)) * 0.5).T)
moments = np.array([1.0, 2.0, 3.0])
from tumble.kernels import run_model
rates = []
observers = dict(axis=1, probe_steps=np.arange(0, 1001, 10), max_flips=4, drift=True, drift_limit=1e-3)
y0 = np.ascontiguousarray(np.vstack([w0, np.tile([[0.0], [0.0], [1.0]], 20000)]))
cases = (("rk4", 2000, {}), ("splitting2", 1000, {}), ("rk8", 500, {}), ("rk4+observers", 1000, observers),
         ("rk4+drift_limit", 1000, dict(drift_limit=1e-3)),
         ("rk4+torque", 1000, dict(torque_params=np.array([0.0, 0.0, 0.1, 0.0]))), ("heavy_top rk4", 500, None))
for label, steps, options in cases:
    if options is None:  # the models' driver
        def go(n_steps, y=None):
            y = y0.copy() if y is None else y
            run_model("heavy_top", "rk4", y, moments, 1e-3, n_steps, columns=np.array([0, 1]), weights=np.ones(2),
                      probe_steps=np.arange(0, n_steps + 1, 10), drift=True, mgl=0.5)
        go(1, y0[:, :8].copy())
    else:
        method = METHODS[label.split("+")[0]]
        def go(n_steps, w=None):
            run(method, w0.copy() if w is None else w, moments, 0.0, 1e-3, n_steps,
                **{k: (v[v <= n_steps] if k == "probe_steps" else v) for k, v in options.items()})
        go(1, w0[:, :8].copy())
    times = []
    for _ in range(5):
        started = time.perf_counter()
        go(steps)
        times.append(time.perf_counter() - started)
    rates.append(f"{label} {20000 * steps / np.median(times):.3g}")
print(sys.argv[1], "  ".join(rates))
"""


def main(trees, rounds=2):
    # A warm-up round first, not printed: a tree's first process compiles or loads its kernels and reads its files
    # from a cold page cache, and its rates came out up to half the later rounds' (2026-11-29, ca28622's rk4 3.7e8
    # against 6.5-7.6e8 in the rounds after).
    for tree in trees:
        subprocess.run([sys.executable, "-c", _ONE_TREE, tree], check=True, stdout=subprocess.DEVNULL)
    for _ in range(rounds):
        for tree in trees:
            subprocess.run([sys.executable, "-c", _ONE_TREE, tree], check=True)


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1:3], int(sys.argv[3]) if len(sys.argv) > 3 else 2)
