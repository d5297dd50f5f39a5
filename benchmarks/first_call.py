"""The first call of each documented entry point (issue 43): what it costs after an install (an empty numba cache),
in a new process once the cache is warm, and from then on, and where that time goes.

    python benchmarks/first_call.py [--repeats N] [--warm N] [--only NAME ...] [--out DIR]
    # writes DIR/first_call.{md,json}, DIR default benchmarks/results/; about 15 minutes on 2 cores

Every entry point (:data:`ENTRY_POINTS`: ``integrate`` per method, ``propagate``, ``exact.omega``,
``exact.attitude``, ``measure``, ``scan``, ``check``, ``run_ensemble`` with a built-in model, ``megno`` and
``lyapunov`` on one), and two floors under them (a cached one-line numba kernel, and it with an xarray Dataset
built: ``numba_floor.py``, no tumble in it), is run in fresh interpreters, each started as
``python benchmarks/first_call.py --probe NAME`` (:func:`probe`), which times

* ``import tumble``;
* the layer's imports: numpy, numba, the first look-up of the public names the call uses (``tumble.integrate``
  imports the engine, xarray), and building the call's inputs;
* the first call: with ``NUMBA_CACHE_DIR`` pointing at a new empty folder (``--repeats`` processes, default 2, each
  with its own folder: the probe counts the cache files there first and refuses a folder that is not empty), then in
  ``--warm`` new processes (default 3) with the cache the first of those wrote. The issue's targets (:data:`TARGETS`)
  are held against this column: the call alone, imports apart;
* the steady state: the median of further calls in the warm-cache processes.

Where the first call's time goes comes from numba's event API (``numba.core.event``: the ``numba:compile`` and
``numba:run_pass`` events, and ``numba:llvm_lock``) and from timing the loads and saves of numba's cache
(``numba.core.caching.Cache.load_overload`` / ``save_overload``, which tumble's checked cache calls): the
dispatchers and signatures compiled, and those loaded from the cache; the time in type inference, in lowering (the
``native_lowering`` passes: LLVM's optimisation and machine code included), in the other compiler passes, in cache
look-ups and loads, in cache saves, and in the target's set-up (``BaseContext.refresh``: numba imports and registers
its typing and lowering registries at a process's first compile or cache look-up), each exclusive of the compiles
nested in it (a kernel's callees compile during its type inference); the time outside all of them (imports made by
the call, Python, the computation); and the cache files (``*.tbi``/``*.tbc``, numba's own ``*.nbi``/``*.nbc`` too)
the call wrote. ``tumble.measure``, ``tumble.scan`` and ``tumble.check`` compile their closed-form kernels side by
side in worker processes where numba may use two threads or more (:mod:`tumble.kernels.side_by_side`): what the
workers compile shows here as loaded from the cache (the table says how many), and their time in none of the
columns but the first call's.

The warm-cache runs also count what they compile all the same: kernels kept out of the cache (a closure over a
user's function), or a cache made stale by an edit of the sources during the run. The columns are medians over the
processes; the JSON keeps every run. The machine line names the processor, the cores, AVX2 or AVX-512, the commit
(marked when tumble/ has uncommitted edits) and the load average at the start: other processes on the cores slow
every row.
``tests/test_first_call.py`` runs the same probe to hold which kernels each call compiles.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).with_name("results")

#: Suffixes of numba's cache files: tumble's checked cache, and numba's own.
CACHE_SUFFIXES = (".tbi", ".tbc", ".nbi", ".nbc")

#: The issue's targets, seconds of the first call: (empty cache, warm cache in a new process). A warm call is held to
#: :data:`WARM_ABOVE_FLOOR` above the floor's row measured in the same run, the floor's figure when none was run.
TARGETS = {"integrate rk4": (5.0, 0.53), "exact.omega": (3.0, 0.53), "measure": (5.0, 0.53),
           "integrate System": (5.0, 0.53)}

#: Issue 58: a warm first call within this many seconds of the floor (a cached one-line numba kernel, new process).
WARM_ABOVE_FLOOR = 0.25
FLOOR = "floor: one numba kernel"

#: The third-party packages whose import the report names when a warm first call pays for it (0.1-0.8 s each).
HEAVY_PACKAGES = ("numba", "scipy", "pandas", "xarray", "dask", "distributed", "netCDF4", "cftime", "matplotlib",
                  "tqdm")

#: Further calls timed for the steady state (at most; fewer once they add up to STEADY_SECONDS).
STEADY_CALLS = 20
STEADY_SECONDS = 2.0

#: Compiler passes (by pass and function) kept per run in the JSON, the longest first.
TOP_PASSES = 25

_BODY = "body = tumble.shapes.t_handle()\nW = np.array([[0.01, 10.0, 0.01]])\n"
_TOP = ("top = tumble.models.HeavyTop((1.0, 1.6, 2.2), mgl=1.0, centre=(0.6, 0.3, 1.0))\n"
        "y0 = np.array([[0.5, 0.3, 2.0, 0.1, 0.2, np.sqrt(0.95)]])\n")  # w1 w2 w3, then the unit vector up
_SYSTEM = (f"import sys\nsys.path.insert(0, {str(ROOT / 'tests')!r})\nfrom hand_written_systems import HEAVY_TOP\n"
           "integrate = tumble.integrate\ny0 = np.array([[0.5, 0.3, 2.0, 0.1, 0.2, np.sqrt(0.95)]])\n")
_CHECK = (f"rec = np.loadtxt({str(ROOT / 'data' / 'check_t_handle_rk4.csv')!r}, delimiter=',', skiprows=1)\n"
          "t, omega, quaternion = rec[:, 0], rec[:, 1:4], rec[:, 4:8]\n"
          "moments = (9.6875e-06, 1.8194444444444445e-05, 2.7256944444444445e-05)\n")


def _integrate(method):
    return (_BODY + "integrate = tumble.integrate", f"integrate(body, W, 5.0, 1e-3, method={method!r})")


#: Name -> (set-up, call): Python source run in the probe's namespace (``np`` and ``tumble`` imported). The set-up
#: looks up the public names (their layers' imports) and builds the inputs; the call is what is timed.
ENTRY_POINTS = {
    **{f"integrate {m}": _integrate(m) for m in
       ("rk4", "rk8", "symplectic_euler", "splitting2", "splitting4", "implicit_midpoint", "exact")},
    "propagate": (_BODY + "propagate = tumble.propagate", "propagate(body, W, 5.0, 1e-3)"),
    "exact.omega": (_BODY + "exact = tumble.exact", "exact.omega(body, W, np.linspace(0.0, 5.0, 11))"),
    "exact.attitude": (_BODY + "exact = tumble.exact", "exact.attitude(body, W, np.linspace(0.0, 5.0, 11))"),
    "measure": (_BODY + "measure = tumble.measure", "measure(body, axis=2, spin=10.0, samples=256)"),
    "scan": ("scan = tumble.scan", "scan([(1.0, 2.0, 3.0), (1.0, 1.5, 1.7)], axis=[1, 2, 3], spin=10.0, samples=64)"),
    "check": (_CHECK + "check = tumble.check", "check(t, omega, quaternion, moments=moments)"),
    # a user's System (the heavy top written by hand, tests/hand_written_systems.py): its kernels are cached, keyed by
    # what its rate computes
    "integrate System": (_SYSTEM, "integrate(HEAVY_TOP, y0, 10.0, 0.005)"),
    "run_ensemble HeavyTop": (_TOP + "run_ensemble = tumble.run_ensemble", "run_ensemble(top, y0, 10.0, 0.005)"),
    "megno HeavyTop": (_TOP + "megno = tumble.megno", "megno(top, y0, t_end=20.0, dt=0.01)"),
    "lyapunov HeavyTop": (_TOP + "lyapunov = tumble.lyapunov", "lyapunov(top, y0, t_end=20.0, dt=0.01)"),
    # the floor under every row (no tumble in it: benchmarks/numba_floor.py)
    "floor: one numba kernel": ("import numba_floor\nx = np.ones(8)", "numba_floor.total(x)"),
    "floor: one numba kernel, a Dataset": ("import numba_floor\nx = np.ones(8)", "numba_floor.total_as_dataset(x)"),
}


def cache_files(folder):
    """The numba cache files under ``folder``."""
    return [p for p in Path(folder).rglob("*") if p.suffix in CACHE_SUFFIXES]


def _kernel_name(dispatcher):
    function = dispatcher.py_func
    return f"{function.__module__}.{function.__qualname__}"


class Recorder:
    """What numba does while it is installed: the signatures compiled and loaded from the cache (``(kernel,
    signature)`` pairs, the kernel as ``module.qualname``), and the time by activity, each exclusive of the
    activities nested in it (a compile inside another's type inference; a cache look-up inside a compile).

    Installs a listener on numba's events and wraps :meth:`numba.core.caching.Cache.load_overload` and
    ``save_overload``, and ``numba.core.base.BaseContext.refresh`` (the target's set-up, which the first cache look-up
    or compile of a process runs: numba imports its typing and lowering registries there); a probe's process only: it
    never restores them."""

    def __init__(self):
        from numba.core import base, caching, event

        self.compiled, self.loaded, self.seconds, self.passes = [], [], Counter(), Counter()
        self.missed = 0
        self._stack = []  # [activity, start, nested seconds, compiler pass or None]
        self._locks = 0  # depth of numba:llvm_lock (the lock's time overlaps the passes': kept apart)
        self._lock_start = 0.0
        recorder = self

        class Listener(event.Listener):
            def on_start(self, ev):
                recorder._event(ev, start=True)

            def on_end(self, ev):
                recorder._event(ev, start=False)

        listener = Listener()
        for kind in ("numba:compile", "numba:run_pass", "numba:llvm_lock"):
            event.register(kind, listener)
        load, save = caching.Cache.load_overload, caching.Cache.save_overload

        def timed_load(cache, sig, target_context):
            self._begin("cache load")
            try:
                result = load(cache, sig, target_context)
            finally:
                self._end()
            if result is None:
                self.missed += 1
            else:
                self.loaded.append((f"{cache._py_func.__module__}.{cache._py_func.__qualname__}", str(sig)))
            return result

        def timed_save(cache, sig, data):
            self._begin("cache save")
            try:
                return save(cache, sig, data)
            finally:
                self._end()

        caching.Cache.load_overload, caching.Cache.save_overload = timed_load, timed_save
        refresh = base.BaseContext.refresh

        def timed_refresh(context):
            self._begin("target set-up")
            try:
                return refresh(context)
            finally:
                self._end()

        base.BaseContext.refresh = timed_refresh

    def _begin(self, activity, compiler_pass=None):
        self._stack.append([activity, time.perf_counter(), 0.0, compiler_pass])

    def _end(self):
        activity, start, nested, compiler_pass = self._stack.pop()
        took = time.perf_counter() - start
        self.seconds[activity] += took - nested
        if compiler_pass:
            self.passes[compiler_pass] += took - nested
        if self._stack:
            self._stack[-1][2] += took
        else:
            self.seconds["numba, all"] += took

    def _event(self, ev, start):
        if ev.kind == "numba:llvm_lock":
            self._locks += 1 if start else -1
            if start and self._locks == 1:
                self._lock_start = time.perf_counter()
            elif not start and self._locks == 0:
                self.seconds["llvm lock"] += time.perf_counter() - self._lock_start
        elif not start:
            self._end()
        elif ev.kind == "numba:compile":
            args = ", ".join(str(a) for a in ev.data["args"])
            self.compiled.append((_kernel_name(ev.data["dispatcher"]), f"({args})"))
            self._begin("compile, outside passes")
        else:
            name = ev.data["name"]  # "nopython_type_inference [function]"
            kind = name.split(" [")[0]
            self._begin("type inference" if "type_inference" in kind else
                        "lowering" if "lowering" in kind else "other passes", name)

    def take(self):
        """What was recorded since the last ``take`` (a dict for JSON), and start afresh."""
        taken = {"compiled": self.compiled, "loaded": self.loaded, "missed": self.missed,
                 "seconds": dict(self.seconds), "passes": dict(self.passes.most_common(TOP_PASSES))}
        self.compiled, self.loaded, self.seconds, self.passes, self.missed = [], [], Counter(), Counter(), 0
        return taken


def probe(name, steady=True):
    """Run entry point ``name`` in this (fresh) process: the figures of one run, printed as one JSON line."""
    cache = os.environ["NUMBA_CACHE_DIR"]
    started = time.perf_counter()
    import tumble

    imported = time.perf_counter() - started
    started = time.perf_counter()
    import numpy as np

    recorder = Recorder()  # imports numba, as the layer would
    set_up, call = ENTRY_POINTS[name]
    namespace = {"np": np, "tumble": tumble}
    exec(set_up, namespace)  # noqa: S102 - the benchmark's own source text (ENTRY_POINTS)
    layer = time.perf_counter() - started
    set_up_numba = recorder.take()
    before = len(cache_files(cache))
    code = compile(call, f"<{name}>", "eval")
    packages = {module.partition(".")[0] for module in sys.modules}
    started = time.perf_counter()
    eval(code, namespace)
    first = time.perf_counter() - started
    imported_packages = sorted({module.partition(".")[0] for module in sys.modules} - packages)
    record = {"name": name, "import_s": imported, "layer_import_s": layer, "first_s": first,
              "imported_packages": imported_packages,
              "cache_files_before": before, "cache_files_written": len(cache_files(cache)) - before,
              "set_up_compiled": set_up_numba["compiled"], **recorder.take()}
    if steady:
        times = []
        while len(times) < STEADY_CALLS and sum(times) < STEADY_SECONDS:
            started = time.perf_counter()
            eval(code, namespace)
            times.append(time.perf_counter() - started)
        again = recorder.take()
        record.update(steady_s=sorted(times)[len(times) // 2], later_compiled=again["compiled"],
                      later_loaded=again["loaded"])
    print(json.dumps(record))


def run_probe(name, cache, steady=True, threads=None):
    """One fresh process running :func:`probe` with ``NUMBA_CACHE_DIR=cache`` (and ``NUMBA_NUM_THREADS=threads``
    when given): its record."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    argv = [sys.executable, str(Path(__file__).resolve()), "--probe", name] + ([] if steady else ["--no-steady"])
    done = subprocess.run(argv, env=env, capture_output=True, text=True, cwd=ROOT, check=False)
    if done.returncode:
        raise RuntimeError(f"{name}: the probe failed (exit {done.returncode}):\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.splitlines()[-1])


def _median(values):
    ordered = sorted(values)
    n = len(ordered)
    return ordered[n // 2] if n % 2 else 0.5 * (ordered[n // 2 - 1] + ordered[n // 2])


def measure_entry(name, repeats, warm):
    """``repeats`` empty-cache processes (each its own new folder) and ``warm`` warm-cache ones for ``name``."""
    empty, warmed = [], []
    with tempfile.TemporaryDirectory() as keep:
        for k in range(repeats):
            with tempfile.TemporaryDirectory() as scratch:
                cache = keep if k == 0 else scratch  # the first one's cache is the warm-cache runs' cache
                record = run_probe(name, cache, steady=False)
            if record["cache_files_before"]:
                raise RuntimeError(f"{name}: the cache was not empty ({record['cache_files_before']} files)")
            empty.append(record)
        for _ in range(warm):
            warmed.append(run_probe(name, keep))
    return {"empty": empty, "warm": warmed}


def summary(name, runs):
    """The table's figures for one entry point: medians over its processes."""
    empty, warm = runs["empty"], runs["warm"]
    first = empty[0]

    def med(records, key):
        return _median([r[key] for r in records])

    def part(records, key):
        return _median([r["seconds"].get(key, 0.0) for r in records])

    return {"name": name, "import_s": med(empty + warm, "import_s"), "layer_import_s": med(warm, "layer_import_s"),
            "empty_s": med(empty, "first_s"), "warm_s": med(warm, "first_s"), "steady_s": med(warm, "steady_s"),
            "compiled_dispatchers": len({k for k, _ in first["compiled"]}),
            "compiled_signatures": len(first["compiled"]), "empty_loaded_signatures": len(first["loaded"]),
            "written_files": first["cache_files_written"],
            "warm_loaded_dispatchers": len({k for k, _ in warm[0]["loaded"]}),
            "warm_loaded_signatures": len(warm[0]["loaded"]), "warm_compiled_signatures": len(warm[0]["compiled"]),
            "empty_seconds": {key: part(empty, key) for key in
                              ("type inference", "lowering", "other passes", "compile, outside passes", "cache load",
                               "cache save", "target set-up", "llvm lock", "numba, all")},
            "warm_seconds": {key: part(warm, key) for key in ("cache load", "target set-up", "numba, all")},
            "later_compiled": sorted({k for r in warm for k, _ in r["later_compiled"]}),
            "warm_imported_packages": [p for p in HEAVY_PACKAGES if p in warm[0].get("imported_packages", [])]}


def machine():
    """Processor, cores, vector width, numba, and the git commit of the tree measured."""
    model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                  if line.startswith("model name")), "unknown processor")
    avx512 = "avx512f" in Path("/proc/cpuinfo").read_text()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT,
                            check=False)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "tumble"], capture_output=True,
                           text=True, cwd=ROOT, check=False).stdout.strip()
    import numba

    return {"processor": model, "cores": os.cpu_count(), "vector_width": "AVX-512" if avx512 else "AVX2",
            "numba": numba.__version__, "python": sys.version.split()[0],
            "commit": commit.stdout.strip() + (" (tumble/ edited, uncommitted)" if dirty else "")}


def targets(rows):
    """:data:`TARGETS`, the warm ones :data:`WARM_ABOVE_FLOOR` above the floor's warm call among ``rows``."""
    floor = [r["warm_s"] for r in rows if r["name"] == FLOOR]
    return {name: (empty, floor[0] + WARM_ABOVE_FLOOR if floor else warm) for name, (empty, warm) in TARGETS.items()}


def _verdict(goals, name, column, value):
    if name not in goals:
        return ""
    target = goals[name][column]
    return f" (<= {target:.2f} s: met)" if value <= target else f" (<= {target:.2f} s: missed by {value - target:.2f} s)"


def _side_by_side(loaded):
    return f" (+{loaded} loaded: compiled side by side)" if loaded else ""


def _seconds(value):
    return f"{value * 1e3:.1f} ms" if value < 0.1 else f"{value:.2f} s"


def report(rows, runs, repeats, warm, load, out, quiet=False):
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%MZ")
    box = machine()
    goals = targets(rows)
    import provenance  # benchmarks/provenance.py (imports tumble: here, not in the probes)

    (out / "first_call.json").write_text(json.dumps(
        {**provenance.stamp(), "date": stamp, "machine": box, "load_average": load, "repeats_empty": repeats,
         "repeats_warm": warm,
         "targets_seconds": goals, "warm_above_floor": WARM_ABOVE_FLOOR, "rows": rows, "runs": runs}, indent=1) + "\n")
    lines = [f"# First call of each entry point — {stamp}", "",
             f"Machine: {box['processor']}, {box['cores']} cores, {box['vector_width']}, numba {box['numba']}, "
             f"Python {box['python']}; commit {box['commit']}; load average at start {load:.2f}. Each call in fresh "
             f"processes: empty numba cache (median of {repeats}), then warm cache (median of {warm}); `import tumble` "
             "and the layer's imports (the first look-up of the names the call uses) are apart from the first call, "
             "which the targets hold.", "",
             "| entry point | import tumble | layer imports | first call, empty cache | first call, warm cache | "
             "then | compiled (dispatchers / signatures) | cache files written | warm: loaded (dispatchers / "
             "signatures) | warm: compiled signatures |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| `{r['name']}` | {_seconds(r['import_s'])} | {_seconds(r['layer_import_s'])} | "
                     f"{_seconds(r['empty_s'])}{_verdict(goals, r['name'], 0, r['empty_s'])} | "
                     f"{_seconds(r['warm_s'])}{_verdict(goals, r['name'], 1, r['warm_s'])} | {_seconds(r['steady_s'])} | "
                     f"{r['compiled_dispatchers']} / {r['compiled_signatures']}"
                     f"{_side_by_side(r['empty_loaded_signatures'])} | {r['written_files']} | "
                     f"{r['warm_loaded_dispatchers']} / {r['warm_loaded_signatures']} | "
                     f"{r['warm_compiled_signatures']} |")
    lines += ["", "Where the empty-cache first call's time goes (seconds, medians; each exclusive of the compiles "
                  "nested in it; the LLVM lock's time overlaps lowering), and the warm-cache call's cache loads:", "",
              "| entry point | first call | numba in all | type inference | lowering (LLVM) | other passes | "
              "compile outside passes | cache look-ups | cache saves | target set-up | LLVM lock | outside numba | "
              "warm: first call | warm: numba in all | warm: cache loads | warm: target set-up |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        s, w = r["empty_seconds"], r["warm_seconds"]
        lines.append(f"| `{r['name']}` | {r['empty_s']:.2f} | {s['numba, all']:.2f} | {s['type inference']:.2f} | "
                     f"{s['lowering']:.2f} | {s['other passes']:.2f} | {s['compile, outside passes']:.2f} | "
                     f"{s['cache load']:.2f} | {s['cache save']:.2f} | {s['target set-up']:.2f} | "
                     f"{s['llvm lock']:.2f} | {r['empty_s'] - s['numba, all']:.2f} | {r['warm_s']:.2f} | "
                     f"{w['numba, all']:.2f} | {w['cache load']:.2f} | {w['target set-up']:.2f} |")
    lines += ["", "Heavy packages the warm-cache first call imported (the layer's imports apart): "
              + "; ".join(f"`{r['name']}`: {', '.join(r['warm_imported_packages']) or 'none'}" for r in rows) + "."]
    set_up = sorted({k for name in runs for r in runs[name]["empty"] for k, _ in r["set_up_compiled"]})
    if set_up:
        lines += ["", "Compiled while building the inputs, outside the figures above: " + ", ".join(set_up) + "."]
    later = [f"`{r['name']}`: {', '.join(r['later_compiled'])}" for r in rows if r["later_compiled"]]
    if later:
        lines += ["", "Compiled again after the first call (a second call should compile nothing): "
                  + "; ".join(later) + "."]
    lines += ["", "Kernels compiled by each first call on an empty cache (signatures per kernel) are in "
                  "`first_call.json` (`runs`, `compiled`); `tests/test_first_call.py` holds them.", ""]
    (out / "first_call.md").write_text("\n".join(lines))
    if not quiet:
        print("\n".join(lines))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2, help="empty-cache processes per entry point (default 2)")
    parser.add_argument("--warm", type=int, default=3, help="warm-cache processes per entry point (default 3)")
    parser.add_argument("--only", action="append", choices=list(ENTRY_POINTS), metavar="NAME",
                        help=f"only this entry point (repeatable): {', '.join(ENTRY_POINTS)}")
    parser.add_argument("--out", type=Path, default=RESULTS, help="folder of first_call.{md,json}")
    parser.add_argument("--probe", choices=list(ENTRY_POINTS), help=argparse.SUPPRESS)  # one fresh process's run
    parser.add_argument("--no-steady", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.probe:
        probe(args.probe, steady=not args.no_steady)
        return
    load = os.getloadavg()[0]
    rows, runs = [], {}
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.only or ENTRY_POINTS:
        runs[name] = measure_entry(name, args.repeats, args.warm)
        rows.append(summary(name, runs[name]))
        report(rows, runs, args.repeats, args.warm, load, args.out, quiet=True)  # written as it goes
    report(rows, runs, args.repeats, args.warm, load, args.out)


if __name__ == "__main__":
    main()
