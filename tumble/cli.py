"""Command line of tumble, Monte Carlo stability studies of rigid-body rotation: ``tumble run [STUDY]`` runs a study
(a TOML file or a bundled study's name), ``tumble studies`` lists the bundled studies, ``tumble plot FILE.nc`` draws
a result file's figures again, ``tumble bench`` runs the benchmarks, ``tumble demo`` the physics-core demo, and
``tumble check TRAJECTORY`` holds another simulator's trajectory against the exact torque-free solution.

Exit status: 0 success, 2 invalid input (one clear message naming the file, the field and what is wrong; no
traceback, no output file), 1 any other failure (``TUMBLE_DEBUG=1`` shows its traceback); ``tumble check``: 3 when
the trajectory fails the check (its files are written).
"""

import argparse
import atexit
import contextlib
import json
import os
import re
import subprocess
import sys
import time
import traceback
import warnings
from pathlib import Path

from . import _interrupt, _startup, registry, warm
from ._version import __version__

# Imports below are made inside the commands that need them: `tumble --help` and `tumble studies` load neither numpy
# nor numba, xarray or matplotlib (tests/test_latency.py).

#: Exit status after Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = _interrupt.EXIT_INTERRUPTED

_METHODS = tuple(m.name for m in registry.METHODS)


def _spins_near_intermediate_axis(body, spin, amplitude, samples, seed):
    """Spins of size ``spin`` tilted by ``amplitude`` rad from the intermediate axis, uniform in azimuth."""
    import numpy as np

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
    import numpy as np

    from .engine.integration import integrate
    from .physics import exact, shapes, theory

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


#: Exit status of ``tumble check`` when the trajectory fails the check (distinct from invalid input, 2).
EXIT_CHECK_FAILED = 3

_BENCHMARKS = ("engine", "accuracy", "work_precision", "stress", "scale_out")
_QUICK = ("work_precision", "stress")  # the benchmarks that take --quick


class InputError(ValueError):
    """Invalid command-line input (exit 2)."""


def _lean_kernel_process():
    """For ``tumble run`` and ``tumble check``: two settings of the command's own process (never of a Python caller's: ``tumble.run_study`` leaves the
    process as it found it) that cut the fixed costs of a run; each leaves alone what the user set.

    - ``OMP_WAIT_POLICY=PASSIVE``: between the many short parallel regions of a scan, numba's OpenMP workers sleep
      instead of spinning, leaving the core to this process's serial work and to the figure process (measured on
      2 cores: ``run_study('stability_map')`` 0.90 -> 0.85 s, 1.7 -> 1.4 s of CPU time; ``tumble run
      stability_map`` -0.13 s). libgomp reads it when numba first starts its thread pool, later than here.
    - numba's first kernel load imports ``numba.np.arraymath``, which imports ``scipy.linalg`` (0.12-0.18 s) only
      to learn whether ``np.cov`` and ``np.corrcoef`` may call BLAS; no tumble kernel calls them (or any BLAS).
      numba also imports ``scipy`` to check its version (5 ms) and PyYAML to read a ``.numba_config.yaml`` in the
      current folder (10 ms). The import is made here with those modules unfindable (PyYAML only where there is
      no such file), then findable again: numba compiles ``np.dot`` and ``np.linalg`` as before (they import
      scipy's BLAS when first compiled).

    Both commands call it, and import what they need, with the garbage collector paused
    (:func:`tumble._startup.collector_paused`).
    """
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    if "numba.np.arraymath" in sys.modules:
        return
    unneeded = ["scipy", "scipy.linalg.cython_blas"] + ([] if os.path.isfile(".numba_config.yaml") else ["yaml"])
    hidden = [name for name in unneeded if name not in sys.modules]
    sys.modules.update(dict.fromkeys(hidden))  # None: `import name` raises ImportError at once
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        for name in hidden:
            del sys.modules[name]


def _run(args):
    from .pipeline import figure_process  # the standard library only

    # Started before this process imports anything heavy: the figure process imports matplotlib and xarray on the
    # other core meanwhile, and draws once the scenes are done (a dry run starts none; invalid input or a study
    # without figures ends it unused).
    with contextlib.nullcontext() if args.dry_run else figure_process.FigureProcess() as drawer:
        _run_study(args, drawer)


def _run_study(args, drawer):
    """``tumble run``: check, plan and run the study, its figures drawn by ``drawer`` (a ``FigureProcess``, or None)."""
    with _startup.collector_paused():  # numba, then the pipeline with the kernels' dispatchers
        _lean_kernel_process()
        from .engine import cost
        from .pipeline import checkpoint, results, runner

    overrides = {key: value for key, value in (("perturbation.samples", args.samples),
                                               ("perturbation.seed", args.seed),
                                               ("integration.device", args.device)) if value is not None}
    _check_chunks_and_workers(args, runner)
    started = time.perf_counter()
    prepared = runner.prepare_study(args.study, overrides=overrides, out=args.out, formats=args.format,
                                    default_directory=True)
    job, directory, stem = prepared.job, prepared.directory, prepared.stem
    if runner.needs_traces(prepared.resolved):  # this process builds the result (else the figure process does)
        from .output import io

        io.assume_no_dask_arrays()  # it makes no dask array: xarray need not import dask.array to look for them
    _check_output_folder(args, prepared)
    scheduler = _scheduler(args)
    chunk = args.chunk_scenes or runner.default_chunk_scenes(job.layout["scenes"])
    if args.dry_run:
        tasks = runner.plan_tasks(job, checkpoint.Finished({}, {}), chunk_scenes=chunk,
                                  chunk_samples=args.chunk_samples)
        split = sum(1 for task in tasks if task.start is not None)
        ranges = (f" ({split} of them sample ranges of up to {runner.chunk_samples_size(args.chunk_samples)} samples)"
                  if split else "")
        print(f"{args.study}: valid; {job.layout['scenes']} scene(s) of {job.samples} samples in {len(tasks)} "
              f"chunk(s) of up to {chunk}{ranges}; would write {directory / (stem + '.nc')}")
        print(f"estimate: {cost.describe(runner.study_cost(prepared.resolved))}")
        return
    print(f"tumble {__version__}: study {args.study!r} ({prepared.resolved['title']})", flush=True)
    command = " ".join(["tumble run", args.study] + [f"--{k.split('.')[1]} {v}" for k, v in overrides.items()])
    options = {"chunk_scenes": chunk, "chunk_samples": args.chunk_samples, "action": command, "fresh": args.fresh,
               "log": lambda line: print(line, flush=True)}
    try:
        with contextlib.ExitStack() as stack:
            if drawer is not None:
                options["figure_process"] = drawer
            if scheduler is None:
                outputs = runner.execute_study(prepared, **options)
            else:
                from .pipeline import distributed

                client = stack.enter_context(distributed.connect(scheduler, workers=args.workers))
                print(f"dask scheduler {client.scheduler.address}: {len(client.scheduler_info()['workers'])} "
                      f"worker(s)", flush=True)
                outputs = runner.execute_study(prepared, client=client, **options)
    except checkpoint.FolderBusy as err:
        raise InputError(f"{_output_option(args, prepared)}: {err.strerror}; wait for it to finish, or choose another "
                         f"--out") from None
    print(outputs.summary if outputs.summary is not None else results.summary_table(outputs.dataset))
    print(f"\n{time.perf_counter() - started:.1f} s; wrote:")
    for path in outputs.paths:
        print(f"  {path}")


def _check_chunks_and_workers(args, runner):
    """``--chunk-scenes``, ``--chunk-samples`` and ``--workers`` of ``tumble run`` (:class:`InputError`)."""
    for flag, value in (("--chunk-scenes", args.chunk_scenes), ("--workers", args.workers)):
        if value is not None and value < 1:
            raise InputError(f"{flag} must be >= 1, got {value}")
    _check_workers(args.workers, args.scheduler)
    try:
        runner.chunk_samples_size(args.chunk_samples)
    except ValueError as err:
        raise InputError(f"--chunk-samples: {err}") from None


def _check_workers(workers, scheduler):
    """``--workers``: only with ``--scheduler local``, and no more than this machine can hold
    (:func:`tumble.engine.cost.most_workers`: an absurd count started processes until the machine hung)."""
    from .engine import cost

    if workers is not None and scheduler != "local":
        raise InputError("--workers sets the worker processes of --scheduler local; it needs --scheduler local")
    if workers is not None and workers > cost.most_workers():
        raise InputError(f"--workers {workers}: more than the {cost.most_workers()} worker processes this machine "
                         f"can hold ({cost.WORKERS_PER_CORE} per core, each ~{cost.WORKER_FOOTPRINT / 1e6:.0f} MB "
                         f"within half its memory)")


def _check_output_folder(args, prepared):
    """An output folder that cannot be made or written (a file in the way, no permission) is the user's choice: one
    line naming where it came from, exit 2, before anything runs or is written."""
    from .pipeline import checkpoint

    try:
        checkpoint.check_writable(prepared.directory)
    except checkpoint.OutputError as err:
        raise InputError(f"{_output_option(args, prepared)}: {err.strerror}") from None


def _output_option(args, prepared):
    """Where the output folder came from, for a message: ``--out``, ``outputs.directory`` or the default."""
    return ("--out" if args.out is not None else "outputs.directory" if prepared.resolved["outputs"]["directory"]
            else "the default output folder (choose another with --out)")


def _scheduler(args):
    """The dask scheduler asked for (``--scheduler`` or ``$DASK_SCHEDULER_ADDRESS``), or None: in-process."""
    from .pipeline import distributed

    try:
        return distributed.scheduler_address(args.scheduler)
    except distributed.SchedulerError as err:
        raise InputError(str(err)) from None


def _studies(args):
    from .pipeline import config

    names = config.bundled_studies()
    width = max(map(len, names), default=0)
    for name, title in names.items():
        print(f"{name:{width}s}  {title}")
    print(f"\n{len(names)} studies in {config.STUDIES_DIR}; run one with `tumble run NAME`, or write your own "
          f"(see {config.DEFAULTS_PATH.name})")


def _plot(args):
    from .output import figures as plots
    from .output import io

    io.assume_no_dask_arrays()
    path = Path(args.file)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        ds = io.read_dataset(path, require_tumble=True)
    except (ValueError, OSError) as err:
        raise InputError(f"{path}: not a tumble result file ({err})") from None
    # The figures the file's own study drew (outputs.figures) must all be drawable: a file lacking a variable one of
    # them needs (cut down, or damaged) is refused naming it, not drawn in part with exit 0.
    listed = [name for name in _study_figures(ds) if name in plots.FIGURES]
    for name in [] if args.figures else listed:
        ok, reason = plots.can_draw(ds, name)
        if not ok:
            raise InputError(f"{path}: figure {name!r} (outputs.figures of the file's study): {reason}; draw the "
                             f"others with --figures")
    names = args.figures or [name for name in plots.FIGURES if name in listed or plots.can_draw(ds, name)[0]]
    if not names:  # a file with tumble's attributes but none of the variables a figure reads (forged, or cut down)
        raise InputError(f"{path}: nothing to draw: {plots.can_draw(ds, 'summary')[1]}, and the file holds none of "
                         f"what the other figures read (figures: {', '.join(plots.FIGURES)})")
    for name in names:
        ok, reason = plots.can_draw(ds, name) if name in plots.FIGURES else (False, "unknown figure")
        if not ok:
            raise InputError(f"{path}: figure {name!r}: {reason} (figures: {', '.join(plots.FIGURES)})")
    directory = Path(args.out) if args.out else path.parent
    written = plots.save_figures(ds, names, directory, path.stem, formats=tuple(args.format or ("png",)))
    for written_path in written:
        print(written_path)


def _study_figures(ds):
    """The figures the study stored in a result file asked for (``outputs.figures``; none when it stores no study)."""
    try:
        figures = json.loads(ds.attrs.get("study", "{}")).get("outputs", {}).get("figures", [])
    except (ValueError, AttributeError):
        return []
    return [name for name in figures if isinstance(name, str)] if isinstance(figures, list) else []


def _check_tolerances(args):
    """The thresholds of ``--tolerances FILE.toml`` (its ``[tolerances]`` table), then each ``--tolerance NAME=VALUE``."""
    import tomllib

    from .measure import check as checking

    tolerances = {}
    if args.tolerances is not None:
        try:
            with open(args.tolerances, "rb") as f:
                table = tomllib.load(f).get("tolerances")
        except (OSError, tomllib.TOMLDecodeError) as err:
            raise InputError(f"--tolerances {args.tolerances}: {err}") from None
        if not isinstance(table, dict):
            raise InputError(f"--tolerances {args.tolerances}: no [tolerances] table (NAME = VALUE lines under it)")
        tolerances.update(table)
    for item in args.tolerance or ():
        name, _, value = item.partition("=")
        try:
            tolerances[name.strip()] = float(value)
        except ValueError:
            raise InputError(f"--tolerance {item!r}: expected NAME=VALUE with a number as VALUE") from None
    try:
        return checking.resolve_tolerances(tolerances)
    except ValueError as err:
        raise InputError(f"--tolerance{'s ' + args.tolerances if args.tolerances else ''}: {err}") from None


def _check(args):
    """``tumble check``: read, check, write the netCDF file and the figure, print the summary; the exit status."""
    with _startup.collector_paused():  # numba, then xarray and matplotlib
        _lean_kernel_process()
        import numpy as np

        from .measure import check as checking
        from .output import check_figure, io, trajectory
        from .physics.bodies import Body

    tolerances = _check_tolerances(args)
    inertia = None
    try:
        if args.moments is not None:
            Body(*args.moments)
        else:
            xx, yy, zz, xy, xz, yz = args.inertia
            inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
            Body.from_tensor(inertia)
    except ValueError as err:
        raise InputError(f"{'--moments' if inertia is None else '--inertia'}: {err}") from None
    path = Path(args.trajectory)
    try:
        columns = trajectory.read_trajectory(path)
        labels = {"t": "column 't'", "omega": "columns wx wy wz", "quaternion": "columns qw qx qy qz"}
        checking.validate_trajectory(columns["t"], columns.get("omega"), columns.get("quaternion"), labels=labels)
        result = checking.check(columns["t"], columns.get("omega"), columns.get("quaternion"), moments=args.moments,
                                inertia=inertia, omega_frame=args.omega_frame, tolerances=tolerances)
    except FileNotFoundError as err:
        raise InputError(str(err)) from None
    except ValueError as err:
        message = str(err)
        raise InputError(message if message.startswith(str(path)) else f"{path}: {message}") from None
    directory = Path(args.out)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"--out {directory}: {err.strerror}") from None
    stem = f"{path.stem}_check"
    written = [directory / f"{stem}.nc", directory / f"{stem}.{args.format}"]
    io.write_dataset(result, written[0], action=f"tumble check {path.name}")
    check_figure.save_check_figure(result, written[1])
    print(f"tumble check {path}")
    print(checking.summary(result))
    print("wrote:")
    for written_path in written:
        print(f"  {written_path}")
    return 0 if result.attrs["verdict"] == "pass" else EXIT_CHECK_FAILED


def _bench(args):
    folder = Path(__file__).resolve().parent.parent / "benchmarks"
    if not folder.is_dir():
        folder = Path.cwd() / "benchmarks"
    if not folder.is_dir():
        raise InputError("tumble bench runs the scripts in benchmarks/ of a tumble source checkout; run it from "
                         "the repository's root folder")
    names = args.names or list(_BENCHMARKS)
    for name in names:
        script = folder / f"{name}.py"
        if not script.is_file():
            raise InputError(f"benchmark {name!r}: no {script} (benchmarks: {', '.join(_BENCHMARKS)})")
    for name in names:
        extra = ["--quick"] if args.quick and name in _QUICK else []
        print(f"== benchmarks/{name}.py {' '.join(extra)}", flush=True)
        done = subprocess.run([sys.executable, str(folder / f"{name}.py"), *extra], check=False)
        if done.returncode:
            raise RuntimeError(f"benchmark {name} failed (exit status {done.returncode})")


def _parser():
    # The module docstring's two paragraphs, as plain text (no ``literals``): what `tumble --help` prints and the
    # command-line reference on the site (docs/reference/cli.md) opens with.
    intro, statuses = (" ".join(part.replace("``", "").split()) for part in __doc__.split("\n\n")[:2])
    parser = argparse.ArgumentParser(prog="tumble", description=intro, epilog=statuses)
    parser.add_argument("--version", action="version", version=f"tumble {__version__}")
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="run a study: netCDF file, figures and a summary")
    run.add_argument("study", nargs="?", default="intermediate_axis",
                     help="a study file (TOML) or a bundled study's name (default: intermediate_axis)")
    run.add_argument("--out", help="output folder (default: the study's outputs.directory, else data/runs/<study>/)")
    run.add_argument("--samples", type=int, help="override perturbation.samples")
    run.add_argument("--seed", type=int, help="override perturbation.seed")
    run.add_argument("--format", nargs="+", choices=("png", "pdf"), help="figure formats (override outputs.format)")
    run.add_argument("--device", choices=registry.DEVICES,
                     help="where the scenes run (override integration.device): cpu, or cuda for an NVIDIA GPU "
                          "(the gpu extra: pip install \".[gpu]\" from a checkout)")
    run.add_argument("--scheduler", metavar="ADDRESS",
                     help="run the scenes on dask.distributed: 'local' (a LocalCluster on 127.0.0.1) or "
                          "tcp://HOST:PORT of a running scheduler (default: $DASK_SCHEDULER_ADDRESS, else in-process; "
                          "needs the distributed extra: pip install \".[distributed]\")")
    run.add_argument("--workers", type=int, help="worker processes of --scheduler local (default: one per core)")
    run.add_argument("--chunk-scenes", type=int, metavar="N",
                     help="scenes per chunk: the unit of checkpointing and of dask tasks (default: about 32 chunks)")
    run.add_argument("--chunk-samples", type=int, metavar="N",
                     help="cut a scene of more than N samples into ranges of N samples, each its own chunk, so that "
                          "one large scene is checkpointed in pieces and spread over dask workers (a multiple of "
                          "4096; default 131072); the results do not depend on it")
    run.add_argument("--fresh", action="store_true",
                     help="discard finished chunks of an earlier interrupted run instead of resuming from them")
    run.add_argument("--dry-run", action="store_true",
                     help="check the study and show its scenes and chunks; run and write nothing")
    commands.add_parser("studies", help="list the bundled studies")
    plot = commands.add_parser("plot", help="draw the figures of a result file")
    plot.add_argument("file", help="a netCDF file written by tumble run")
    plot.add_argument("--figures", nargs="+", help="which figures (default: every one the file can give)")
    plot.add_argument("--format", nargs="+", choices=("png", "pdf"), help="figure formats (default png)")
    plot.add_argument("--out", help="output folder (default: the file's folder)")
    bench = commands.add_parser("bench", help="run the benchmarks (from a source checkout)")
    bench.add_argument("names", nargs="*", help=f"which ({', '.join(_BENCHMARKS)}; default all)")
    bench.add_argument("--quick", action="store_true", help="small sizes, for a smoke run")
    run_demo = commands.add_parser("demo", help="run the physics-core demo on the Dzhanibekov T-handle")
    run_demo.add_argument("--samples", type=int, default=2000, help="ensemble size (default 2000)")
    run_demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    run_demo.add_argument("--dt", type=float, default=0.002, help="step in s (default 0.002)")
    warming = commands.add_parser(
        "warm", help="compile the kernels of the common first calls now, side by side (once after an install)",
        description="Run each named call once with tiny inputs in new processes, one per core, so that numba "
                    "compiles its kernels into its disk cache now; later first calls load them. Calls: "
                    + "; ".join(f"{name}: {what}" for name, (what, _) in warm.CALLS.items())
                    + f". Default: {' '.join(warm.DEFAULT)}.")
    warming.add_argument("calls", nargs="*", metavar="CALL", help="which calls (default: the Python API's first "
                                                               "examples); 'all' for every one")
    _add_check_parser(commands)
    return parser


def _warm(args):
    """``tumble warm``: one line per call as it ends; exit 1 if a call failed (its kernels compile at first use)."""
    names = list(warm.CALLS) if args.calls == ["all"] else args.calls or list(warm.DEFAULT)
    unknown = [name for name in names if name not in warm.CALLS]
    if unknown:
        raise InputError(f"unknown call {', '.join(map(repr, unknown))} for tumble warm; the calls are "
                         f"{', '.join(warm.CALLS)} (or all)")
    start = time.perf_counter()

    def report(warmed):
        outcome = f"failed: {warmed.error}" if warmed.error else "compiled (or already in the cache)"
        print(f"warm {warmed.name}: {warmed.seconds:.1f} s, {outcome}", flush=True)

    failed = [w for w in warm.warm(names, report=report) if w.error]
    print(f"warmed {len(names) - len(failed)} of {len(names)} calls in {time.perf_counter() - start:.1f} s")
    return 1 if failed else 0


def _add_check_parser(commands):
    """The ``tumble check`` subcommand's options (docs/check.md)."""
    check = commands.add_parser(
        "check", help="hold a simulator's free rigid-body trajectory against the exact torque-free solution",
        description="Compare a free rigid body's recorded trajectory (any simulator) with the exact torque-free "
                    "solution from its first state: angular velocity and attitude errors, energy and angular "
                    "momentum drift, flips about the intermediate axis and their period; a verdict per criterion; "
                    "a netCDF file and a figure. Exit status: 0 pass, 3 the trajectory fails the check, 2 invalid "
                    "input (nothing written), 1 any other failure. See docs/check.md.",
        epilog="Criteria and default tolerances: " + ", ".join(
            f"{name}={value:g}" for name, value in registry.CHECK_TOLERANCES.items()))
    check.add_argument("trajectory", metavar="TRAJECTORY",
                       help="a .csv (header row), .npz or .nc file with columns t; wx wy wz (angular velocity, rad/s) "
                            "and/or qw qx qy qz (attitude quaternion, body-to-world); other columns are ignored")
    # argparse takes "-1.5e-06" for an option (its negative-number pattern has no exponent): an inertia tensor's
    # off-diagonal elements are often negative and printed so. The same pattern with an exponent (argparse's own
    # attribute; Python 3.11-3.13 read it the same way).
    check._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")  # noqa: SLF001
    body = check.add_mutually_exclusive_group(required=True)
    body.add_argument("--moments", nargs=3, type=float, metavar=("I1", "I2", "I3"),
                      help="principal moments, kg m^2, along the file's body axes x, y, z")
    body.add_argument("--inertia", nargs=6, type=float, metavar=("XX", "YY", "ZZ", "XY", "XZ", "YZ"),
                      help="instead of --moments: the inertia tensor in the file's body frame, kg m^2, in MuJoCo's "
                           "fullinertia order (XY is the tensor element, -integral of x y dm); the principal axes are "
                           "found and the data rotated onto them")
    check.add_argument("--omega-frame", choices=("body", "world"), default="body",
                       help="frame of wx wy wz (default body; world needs the quaternion columns)")
    check.add_argument("--tolerance", action="append", metavar="NAME=VALUE",
                       help="override one criterion's threshold (repeatable); see the list below")
    check.add_argument("--tolerances", metavar="FILE.toml",
                       help="thresholds from the [tolerances] table of a TOML file (--tolerance overrides them)")
    check.add_argument("--out", default=".",
                       help="output folder for <name>_check.nc and the figure (default: the current folder)")
    check.add_argument("--format", choices=("png", "pdf"), default="png", help="figure format (default png)")


def _raised_by(module, name):
    """``(module.name,)`` (an exception class) if that module has been imported, else an empty tuple.

    The handlers in :func:`main` name the errors of the pipeline without importing it (which would load xarray
    for `tumble --help`): an ``except`` clause's classes are looked up only when an exception arrives, and an
    exception of a class whose module was never imported cannot have been raised.
    """
    loaded = sys.modules.get(f"tumble.{module}")
    return (getattr(loaded, name),) if loaded is not None else ()


_PACKAGE = os.path.dirname(os.path.abspath(__file__))


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """tumble's own warnings — of its classes (e.g. :class:`tumble.kernels.jit.CacheWarning`) or raised in its code
    (a scene with no rate, samples that became non-finite: each says why) — as one line, ``tumble: warning: ...``;
    the others as Python shows them."""
    ours = category.__module__.startswith("tumble.") or os.path.abspath(str(filename)).startswith(_PACKAGE + os.sep)
    text = (f"tumble: warning: {message}\n" if ours
            else warnings.formatwarning(message, category, filename, lineno, line))
    (sys.stderr if file is None else file).write(text)


def main(argv=None):
    """Entry point of ``tumble`` and ``python -m tumble``; returns the exit status."""
    args = _parser().parse_args(argv)
    warnings.showwarning = _show_warning
    try:
        _interrupt.release()  # from here on Ctrl-C is a KeyboardInterrupt, reported below
        if args.command == "run":
            _run(args)
        elif args.command == "check":
            return _check(args)
        elif args.command == "studies":
            _studies(args)
        elif args.command == "plot":
            _plot(args)
        elif args.command == "bench":
            _bench(args)
        elif args.command == "warm":
            return _warm(args)
        elif args.command == "demo":
            if args.samples < 1:
                raise InputError(f"--samples must be >= 1, got {args.samples}")
            demo(samples=args.samples, seed=args.seed, dt=args.dt)
    except (InputError, *_raised_by("pipeline.config", "StudyError"),
            *_raised_by("engine.device", "DeviceError")) as err:  # its message starts "device 'cuda':", as in Python
        print(f"tumble: error: {err}", file=sys.stderr)
        return 2
    except _raised_by("pipeline.checkpoint", "OutputError") as err:
        print(f"tumble: failed: {err.strerror or err}; earlier results there are unchanged, and finished chunks are "
              "kept for a rerun to resume from", file=sys.stderr)
        return 1
    except _raised_by("pipeline.distributed", "SchedulerLost") as err:
        print(f"tumble: failed: {err}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # output piped into a reader that stopped early (e.g. `| head`)
        sys.stderr.close()
        return 1
    except _interrupt.Terminated:
        print("tumble: terminated (SIGTERM); no result was written (finished chunks are kept: rerun to resume)",
              file=sys.stderr)
        return _interrupt.EXIT_TERMINATED
    except KeyboardInterrupt as err:
        print(f"tumble: interrupted{': ' + str(err) if str(err) else ''}; no result was written (finished chunks "
              "are kept: rerun to resume)", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as err:  # noqa: BLE001 - the command line reports every failure as one line (exit 1)
        if os.environ.get("TUMBLE_DEBUG"):
            traceback.print_exc()
        print(f"tumble: failed: {type(err).__name__}: {err}", file=sys.stderr)
        return 1
    return 0


def command():
    """The ``tumble`` command (console script and ``python -m tumble``): :func:`main`, then the process ends at once.

    When ``main`` returns, every file is written (atomically) and closed and a dask cluster is shut down; what the
    interpreter's normal exit would add is freeing every module's objects — numba's compiled code, matplotlib,
    xarray — 0.4-0.5 s on 2 cores, more than a study's figures take to draw. So the command flushes its output, runs
    the exit handlers that libraries registered (``atexit``: logging and the like) and leaves with ``os._exit`` —
    unless a profiler, debugger or coverage is watching (``python -m cProfile -m tumble ...``), which write their
    results at the normal exit. Tests and scripts call :func:`main`, which returns.
    """
    status = main()
    if sys.getprofile() is not None or sys.gettrace() is not None:
        sys.exit(status)  # a profiler, debugger or coverage run writes its results at the normal exit
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # a closed pipe (`| head`) has nothing left to flush
            stream.flush()
    atexit._run_exitfuncs()  # noqa: SLF001 - what a normal exit runs first; CPython's, there since 2.x
    os._exit(status)


if __name__ == "__main__":
    command()
