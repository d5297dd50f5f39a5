"""How accurate a System's tangents are without a Jacobian: central differences against the exact Jacobian.

    python benchmarks/difference_tangents.py

A System without ``jacobian`` gets its tangent products ``J(t, y) v`` from extrapolated central differences of its
rate (:func:`tumble.kernels.loops.tangent_loop.difference_tangents`), stepping 2^-10 of each component's scale (1 unless
the System declares ``scale``). Two systems, each with an exact Jacobian to compare with:

1. angle-like: a driven, damped pendulum that turns over and over (``rotor``), its angle placed at 0 ... 1e8 rad;
   the products' largest relative error over 64 random unit vectors per state, and the Lyapunov exponents of a
   run from there (the run's exponents against those of the same run with the exact Jacobian);
2. unit scale: tumble's heavy top written by hand (``tests/hand_written_systems.py``), random states of sizes 1e-3,
   1 and 30 (the physics layer's exact Jacobian), and the exponents of a chaotic release.

Writes ``benchmarks/results/difference_tangents.md`` and ``.json``. Accuracy only: nothing is timed.
"""

import json
import math
import sys
import warnings
from pathlib import Path

import numpy as np
from provenance import source_digest, stamp  # benchmarks/provenance.py

import tumble
from tumble.kernels.loops import sample_loop
from tumble.kernels.loops.tangent_loop import WORK_EXTRA, difference_tangents

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
import hand_written_systems  # noqa: E402
from hand_written_systems import ROTOR, rotor, rotor_jacobian  # noqa: E402

RESULTS = HERE / "results"
ANGLES = [0.0, 1e2, 1e4, 1e6, 1e8]
def product_error(rate, p, states, jacobian, rng):
    """The largest ``|difference - J v| / |J v|`` (max norms) over the states and 64 random unit vectors each."""
    tangents = difference_tangents(sample_loop.compile_function(rate, sample_loop.RATE_SIGNATURE, "bench", "rate"))
    n = states.shape[1]
    scaled = np.concatenate([p, np.ones(n)])  # the kernels' parameters, then the components' scales
    worst = 0.0
    for y in states:
        V = rng.standard_normal((64, n))
        V /= np.linalg.norm(V, axis=1)[:, None]
        out, work = np.empty((64, n)), np.empty((n + WORK_EXTRA, n))
        tangents(0.0, y, V, scaled, out, work)
        exact = V @ jacobian(y).T
        worst = max(worst, float(np.max(np.abs(out - exact).max(axis=1) / np.abs(exact).max(axis=1))))
    return worst


def exponent_error(with_jacobian, without, y0, t_end, dt, parameters=None):
    """``(exponents with the exact Jacobian, largest difference of the differences' ones, warnings)``; ``parameters``
    for ``without`` only."""
    exact = tumble.lyapunov(with_jacobian, y0, t_end, dt)["exponent"].values[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        by_differences = tumble.lyapunov(without, y0, t_end, dt, parameters=parameters)["exponent"].values[0]
    return exact.tolist(), float(np.max(np.abs(by_differences - exact))), [str(w.message) for w in caught]


def main():
    rng = np.random.default_rng(7)
    exact_rotor = tumble.System(rotor, state=("theta", "omega"), parameters=ROTOR, jacobian=rotor_jacobian,
                                name="rotor")
    difference_rotor = tumble.System(rotor, state=("theta", "omega"), parameters=ROTOR, name="rotor")
    p = np.array(list(ROTOR.values()))

    def rotor_matrix(y):
        J = np.empty((2, 2))
        rotor_jacobian(0.0, y, p, J)
        return J

    angle_rows = []
    for theta in ANGLES:
        states = np.column_stack([theta + rng.uniform(-math.pi, math.pi, 8), rng.uniform(-3.0, 3.0, 8)])
        exponents, error, said = exponent_error(exact_rotor, difference_rotor, [theta, 2.0], 50.0, 0.01)
        angle_rows.append({"theta": theta, "product_error": product_error(rotor, p, states, rotor_matrix, rng),
                           "exponents": exponents, "exponent_error": error, "warnings": said})

    top = tumble.models.HeavyTop((1.0, 1.6, 2.2), 1.0, centre=(0.6, 0.3, 1.0))
    top_p = np.array([1.0, 1.6, 2.2, 1.0, *top.centre])
    unit_rows = []
    for size in (1e-3, 1.0, 30.0):
        states = rng.standard_normal((8, 6)) * size
        unit_rows.append({"size": size, "product_error": product_error(hand_written_systems.heavy_top, top_p, states,
                                                                       top.jacobian, rng)})
    chaotic = np.array([0.04071382, 0.0164995, -0.85749567, 0.35671917, -0.78540276, 0.5058596])
    chaotic[3:] /= np.linalg.norm(chaotic[3:])
    parameters = dict(zip(("I1", "I2", "I3", "mgl", "c1", "c2", "c3"), top_p.tolist()))
    exponents, error, said = exponent_error(top, hand_written_systems.HEAVY_TOP, chaotic, 30.0, 0.01, parameters)
    results = {
        **stamp(), "source": source_digest(), "numpy": np.__version__, "angle_like": angle_rows,
        "unit_scale": unit_rows,
        "heavy_top_chaotic": {"exponents": exponents, "exponent_error": error, "warnings": said},
    }
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "difference_tangents.json").write_text(json.dumps(results, indent=1) + "\n")
    lines = [f"# Difference tangents against the exact Jacobian ({results['date']}, source {results['source']})", "",
             "Angle-like: a driven pendulum turning over (`rotor`), scale 1; a product's largest relative error over "
             "8 states x 64 unit vectors, and the largest difference of the Lyapunov exponents (1/s) of a 50 s run "
             "(dt 0.01) from (theta, 2).", "",
             "| theta (rad) | product error | exponents (exact Jacobian) | exponent difference | warned |",
             "|---|---|---|---|---|"]
    for row in angle_rows:
        lines.append(f"| {row['theta']:g} | {row['product_error']:.1e} | "
                     f"{', '.join(f'{e:.6f}' for e in row['exponents'])} | {row['exponent_error']:.1e} | "
                     f"{'yes' if row['warnings'] else 'no'} |")
    lines += ["", "Unit scale: the heavy top written by hand, random states of each size.", "",
              "| state size | product error |", "|---|---|"]
    lines += [f"| {row['size']:g} | {row['product_error']:.1e} |" for row in unit_rows]
    lines += ["", f"A chaotic heavy top over 30 s: exponents {', '.join(f'{e:.6f}' for e in exponents)} 1/s; the "
                  f"differences' exponents differ by {error:.1e} at most.", ""]
    (RESULTS / "difference_tangents.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
