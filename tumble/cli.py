"""Command line: ``tumble demo`` (the study runner and its commands arrive with the studies layer).

Exit status: 0 success, 2 invalid input (one clear message, no traceback), 1 any other failure.
"""

import argparse
import sys
import time

import numpy as np

from . import __version__, exact, shapes, theory
from .integration import integrate

_METHODS = ("rk4", "rk8", "symplectic_euler", "splitting2", "splitting4", "implicit_midpoint", "exact")


def _spins_near_intermediate_axis(body, spin, amplitude, samples, seed):
    """Spins of size ``spin`` tilted by ``amplitude`` rad from the intermediate axis, uniform in azimuth."""
    middle = int(np.argsort(body.moments)[1])
    others = [a for a in range(3) if a != middle]
    azimuth = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, samples)
    w0 = np.zeros((samples, 3))
    w0[:, middle] = spin * np.cos(amplitude)
    w0[:, others[0]] = spin * np.sin(amplitude) * np.cos(azimuth)
    w0[:, others[1]] = spin * np.sin(amplitude) * np.sin(azimuth)
    return w0, middle


def demo(samples=2000, seed=0, dt=0.002, out=sys.stdout):
    """Show the physics core end to end on the Dzhanibekov T-handle.

    Linear theory for each axis; an ensemble of spins about the intermediate axis integrated by every method
    through its first flips and compared with the exact solution; invariants; flip timing.
    """
    body = shapes.t_handle()
    moments = body.moments
    scale = moments.max()
    print(f"tumble {__version__} — physics core demo", file=out)
    print(f"T-handle, moments {np.array2string(moments / scale, precision=4)} x {scale:.3e} kg m²", file=out)
    for axis in (1, 2, 3):
        kind, value = theory.linear(body, axis, 1.0)
        unit = "rad/s" if kind == "periodic" else "1/s"
        print(f"  spin 1 rad/s about axis {axis}: {kind:11s} {value:.6f} {unit}", file=out)

    spin, amplitude = 1.0, 1e-3
    w0, middle = _spins_near_intermediate_axis(body, spin, amplitude, samples, seed)
    first_flip = float(np.median(theory.first_flip_time(body, w0)))
    spacing = float(np.median(theory.flip_spacing(body, w0)))
    t_end = first_flip + 1.5 * spacing
    print(f"\n{samples} spins of {spin} rad/s tilted {amplitude} rad from axis {middle + 1}; "
          f"first flip at {first_flip:.4f} s (asymptote "
          f"{float(np.median(theory.flip_time_asymptote(body, w0))):.4f} s), then every {spacing:.4f} s; "
          f"integrating to {t_end:.3f} s with dt = {dt} s", file=out)

    reference = exact.omega(body, w0, np.array([t_end]))[:, -1, :]
    l2_0 = np.sum((moments * w0) ** 2, axis=1)
    e_0 = 0.5 * np.sum(moments * w0**2, axis=1)
    print("\n  |w - exact| at the end, rad/s: median over the ensemble, and the worst sample (spins that start "
          "nearest the separatrix\n  amplify any error most); invariant drifts are the worst sample's.", file=out)
    print(f"\n  {'method':18s} {'median error':>13s} {'worst error':>12s} {'|L|² drift':>11s} {'energy drift':>13s} "
          f"{'wall s':>8s} {'compile s':>10s}", file=out)
    for method in _METHODS:
        started = time.perf_counter()
        integrate(body, w0[:2], dt, dt, method=method)  # compile (or load from the cache)
        compiled = time.perf_counter() - started
        started = time.perf_counter()
        w = integrate(body, w0, t_end, dt, method=method).omega.values[:, -1, :]
        wall = time.perf_counter() - started
        error = np.linalg.norm(w - reference, axis=1)
        l2 = np.abs(np.sum((moments * w) ** 2, axis=1) / l2_0 - 1).max()
        energy = np.abs(0.5 * np.sum(moments * w**2, axis=1) / e_0 - 1).max()
        label = "exact (reference)" if method == "exact" else method
        print(f"  {label:18s} {np.median(error):13.2e} {error.max():12.2e} {l2:11.1e} {energy:13.1e} {wall:8.3f} "
              f"{compiled:10.2f}", file=out)
    print("\nEvery spin has flipped about the intermediate axis and come part of the way back "
          f"(omega_{middle + 1} changed sign at t ≈ {first_flip:.2f} s).", file=out)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="tumble", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"tumble {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)
    run_demo = commands.add_parser("demo", help="run the physics-core demo on the Dzhanibekov T-handle")
    run_demo.add_argument("--samples", type=int, default=2000, help="ensemble size (default 2000)")
    run_demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    run_demo.add_argument("--dt", type=float, default=0.002, help="step in s (default 0.002)")
    args = parser.parse_args(argv)
    try:
        if args.command == "demo":
            if args.samples < 1:
                raise ValueError(f"--samples must be >= 1, got {args.samples}")
            demo(samples=args.samples, seed=args.seed, dt=args.dt)
    except ValueError as err:
        print(f"tumble: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into a reader that stopped early (e.g. `| head`)
        sys.stderr.close()
        return 1
    except KeyboardInterrupt as err:
        print(f"tumble: interrupted{': ' + str(err) if str(err) else ''}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
