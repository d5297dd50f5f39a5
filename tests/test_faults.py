"""Faults a user meets, made to happen for real (issue 33): two runs into one folder, a damaged or unwritable numba
cache, a full disk, a dask scheduler killed mid-run. Each test checks the one line the user reads and what is left on
disk: earlier results intact, no half file, finished chunks kept for a rerun."""

import errno
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import warnings

import pytest

from tumble import cli
from tumble.output import io
from tumble.pipeline import checkpoint

# 12 closed-form scenes (2 x 2 inertia triangle x 3 axes) of 64 samples: a second or two in a fresh process.
SMALL = {"title": "small", "perturbation": {"samples": 64}, "scan": {"triangle": 2, "axis": [1, 2, 3]},
         "integration": {"flips": 0}, "outputs": {"figures": [], "arrays": []}}


def write_study(folder, study=SMALL, name="small"):
    """``study`` as a TOML file ``<folder>/<name>.toml`` (JSON's syntax for these tables is TOML's too)."""
    lines = [f"title = {json.dumps(study['title'])}"]
    for table, fields in study.items():
        if table != "title":
            lines.append(f"[{table}]")
            lines += [f"{key} = {json.dumps(value)}" for key, value in fields.items()]
    path = folder / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def tumble_command(*args, env=None, **kwargs):
    """Start ``python -m tumble ARGS`` (a new process, as a user's shell would)."""
    return subprocess.Popen([sys.executable, "-m", "tumble", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, **(env or {})}, **kwargs)


def finish(process, timeout=240):
    out, err = process.communicate(timeout=timeout)
    return process.returncode, out, err


def hidden(folder):
    """Names of the hidden entries (checkpoint, staging, lock, part files) left in ``folder``."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# --- cause 1: two runs into one folder ---------------------------------------------------------------------------

@pytest.mark.slow  # two runs in new processes at once (1.7 s)
def test_two_runs_started_together_into_one_folder_leave_one_complete_result(tmp_path):
    study, out = write_study(tmp_path), tmp_path / "out"
    runs = [tumble_command("run", study, "--out", out) for _ in range(2)]
    results = [finish(run) for run in runs]
    statuses = sorted(status for status, _, _ in results)
    assert statuses in ([0, 0], [0, 2]), results
    for status, _, err in results:
        if status == 2:  # refused at once, one line naming the folder and the other run
            assert err.count("\n") == 1 and "another tumble run (process" in err and str(out) in err, err
            assert "Traceback" not in err
    ds = io.read_dataset(out / "small.nc", require_tumble=True)
    assert ds.rate.size == 12 and ds.sizes["axis"] == 3
    assert hidden(out) == [], "no chunks, staging folder or lock left behind"


def hold_lock(out, stem="small"):
    """A process holding the lock of ``<out>/<stem>.nc``, as a running ``tumble run`` does (returns once it holds
    it)."""
    code = ("import sys, time; from tumble.pipeline import checkpoint\n"
            f"with checkpoint.Checkpoint({str(out)!r}, {stem!r}, '', 1).locked():\n"
            "    print('locked', flush=True); time.sleep(600)")
    holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "locked"
    return holder


@pytest.mark.slow  # a holder process, a refused run, a killed holder and a run after it (2.4 s)
def test_a_second_run_into_a_busy_folder_is_refused_at_once_and_a_killed_holder_blocks_nothing(tmp_path):
    study, out = write_study(tmp_path), tmp_path / "out"
    holder = hold_lock(out)
    try:
        status, _, err = finish(tumble_command("run", study, "--out", out, "--samples", 32))
        assert status == 2, err
        assert err == (f"tumble: error: --out: another tumble run (process {holder.pid}) is writing small.nc in {out}; "
                       "wait for it to finish, or choose another --out\n")
        assert hidden(out) == [".small.lock"] and not (out / "small.nc").exists(), "the refused run wrote nothing"
    finally:
        holder.send_signal(signal.SIGKILL)  # a run killed with kill -9: the OS releases its lock
        holder.wait()
    assert hidden(out) == [".small.lock"], "kill -9 leaves the lock file ..."
    status, _, err = finish(tumble_command("run", study, "--out", out, "--samples", 32))
    assert status == 0, err  # ... which blocks nothing
    assert io.read_dataset(out / "small.nc").attrs["source"].startswith("tumble")
    assert hidden(out) == []


# --- cause 2: a damaged or unwritable numba cache ------------------------------------------------------------------

# One small kernel in a fresh process, with numba's cache in NUMBA_CACHE_DIR: it prints whether it was loaded from
# the cache, then its value, which must be right whatever the cache held.
KERNEL = ("import math, warnings; warnings.simplefilter('always'); from tumble.kernels import trig\n"
          "s, c = trig.sincos(0.5)\n"
          "print(sum(trig.sincos.stats.cache_hits.values()), s == math.sin(0.5) and c == math.cos(0.5))")


def run_kernel(cache):
    done = subprocess.run([sys.executable, "-c", KERNEL], capture_output=True, text=True, timeout=240,
                          env={**os.environ, "NUMBA_CACHE_DIR": str(cache)})
    assert done.returncode == 0, done.stderr
    return done.stdout.split(), done.stderr


def cache_files(cache):
    return sorted(p for p in cache.rglob("trig.sincos-*") if p.suffix in (".tbi", ".tbc"))


def truncate_index(files):
    index = files[0] if files[0].suffix == ".tbi" else files[-1]
    index.write_bytes(index.read_bytes()[: index.stat().st_size // 2])


def zero_a_block(files):
    data = next(p for p in files if p.suffix == ".tbc")
    raw = bytearray(data.read_bytes())
    raw[len(raw) // 2: len(raw) // 2 + 256] = bytes(256)
    data.write_bytes(bytes(raw))


def flip_a_bit(files):
    data = next(p for p in files if p.suffix == ".tbc")
    raw = bytearray(data.read_bytes())
    raw[-len(raw) // 3] ^= 0x10  # in the pickled library (its object code: numba would run it as it is)
    data.write_bytes(bytes(raw))


@pytest.fixture(scope="module")
def warm_cache(tmp_path_factory):
    """A NUMBA_CACHE_DIR holding the kernel, compiled and saved by one process and loaded by the next."""
    cache = tmp_path_factory.mktemp("numba-cache")
    assert run_kernel(cache) == (["0", "True"], "")
    assert run_kernel(cache) == (["1", "True"], "")
    return cache


@pytest.mark.slow
@pytest.mark.parametrize("damage", [truncate_index, zero_a_block, flip_a_bit])
def test_a_damaged_numba_cache_is_named_removed_and_compiled_again(tmp_path, warm_cache, damage):
    cache = tmp_path / "numba-cache"
    shutil.copytree(warm_cache, cache)
    files = cache_files(cache)
    damage(files)
    (hits, right), err = run_kernel(cache)
    assert (hits, right) == ("0", "True")
    assert err.count("CacheWarning") == 1 and "held a damaged file" in err and str(files[0].parent) in err, err
    assert "Traceback" not in err
    assert run_kernel(cache) == (["1", "True"], ""), "the damaged files were replaced by good ones"


def test_where_no_folder_can_hold_a_cache_kernels_run_uncached_with_one_warning(tmp_path):
    # numba's own "no locator available" (a read-only install with a read-only home): here by allowing numba only
    # the locator of IPython cells, which no file of tumble is (as root, a read-only folder is still writable)
    done = subprocess.run([sys.executable, "-c", KERNEL], capture_output=True, text=True, timeout=240,
                          env={**os.environ, "NUMBA_CACHE_LOCATOR_CLASSES": "IPythonCacheLocator"})
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", "True"]
    assert done.stderr.count("CacheWarning") == 1 and "running without a cache" in done.stderr, done.stderr
    assert "set NUMBA_CACHE_DIR to a writable folder" in done.stderr



def test_the_command_line_shows_a_cache_warning_as_one_line(capsys):
    from tumble.kernels import jit

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = cli._show_warning
        warnings.warn("numba's cache of compiled kernels in X held a damaged file (...)", jit.CacheWarning)
        warnings.warn("not tumble's", RuntimeWarning)
        warnings.warn_explicit("no sample of the scene (axis 2, amplitude 0.001) gave a rate; statuses: non-finite 8",
                               RuntimeWarning, os.path.join(os.path.dirname(cli.__file__), "pipeline", "runner.py"), 1)
    err = capsys.readouterr().err
    assert err.startswith("tumble: warning: numba's cache of compiled kernels in X held a damaged file (...)\n")
    assert "RuntimeWarning: not tumble's" in err, "other warnings as Python shows them"
    assert err.endswith("\ntumble: warning: no sample of the scene (axis 2, amplitude 0.001) gave a rate; statuses: "
                        "non-finite 8\n"), "a warning raised in tumble's code: one line"

# --- cause 3: a full disk ------------------------------------------------------------------------------------------

@pytest.fixture
def small_disk(tmp_path):
    """A 4 MB file system of its own (tmpfs), to fill up for real."""
    disk = tmp_path / "disk"
    disk.mkdir()
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(disk)], capture_output=True,
                              text=True, timeout=30)
    except FileNotFoundError:
        pytest.skip("no mount command: a full disk needs a small file system of its own (tmpfs)")
    if done.returncode:
        pytest.skip(f"cannot mount a 4 MB tmpfs for a full disk (needs root): {done.stderr.strip()}")
    yield disk
    subprocess.run(["umount", "-l", str(disk)], check=False, timeout=30)


def fill(disk, leave=0):
    """Fill ``disk`` with a file until it is full, then give back ``leave`` bytes."""
    filler = disk / "filler"
    with open(filler, "ab") as f:
        try:
            while True:
                f.write(bytes(1 << 16))
                f.flush()
        except OSError as err:
            assert err.errno == errno.ENOSPC
    if leave:
        os.truncate(filler, max(0, filler.stat().st_size - leave))
    return filler


@pytest.fixture
def earlier_result(small_disk, capsys):
    out = small_disk / "out"
    study = write_study(small_disk)
    assert cli.main(["run", str(study), "--out", str(out)]) == 0
    capsys.readouterr()
    return study, out, (out / "small.nc").read_bytes()


def test_a_disk_full_at_the_first_chunk_is_named_and_loses_nothing(earlier_result, capsys):
    study, out, before = earlier_result
    fill(out.parent)
    assert cli.main(["run", str(study), "--out", str(out), "--seed", "5"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"tumble: failed: cannot write {out}/.small.chunks/") and err.count("\n") == 1, err
    assert f"the disk holding {out}/.small.chunks is full (" in err
    assert (out / "small.nc").read_bytes() == before
    assert not [p for p in out.rglob("*") if p.name.endswith(".part")]


@pytest.mark.default_cases("full-while-writing")
@pytest.mark.parametrize("leave", [0, 40_000], ids=["full-at-create", "full-while-writing"])
def test_a_disk_full_at_the_result_is_named_keeps_the_chunks_and_a_rerun_resumes(earlier_result, capsys,
                                                                                 monkeypatch, leave):
    # netCDF4 says "Permission denied" when it cannot create the file, "NetCDF: HDF error" when a write fails
    study, out, before = earlier_result
    write = checkpoint.Checkpoint.write

    def write_then_fill(self, name, data):  # the disk fills up after the last chunk, as another program writes
        path = write(self, name, data)
        fill(out.parent, leave)
        return path

    monkeypatch.setattr(checkpoint.Checkpoint, "write", write_then_fill)
    args = ["run", str(study), "--out", str(out), "--seed", "5", "--chunk-scenes", "12"]
    assert cli.main(args) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"tumble: failed: cannot write the results to {out}: the disk holding {out} is full ("), err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert (out / "small.nc").read_bytes() == before, "the earlier result, bit for bit"
    assert hidden(out) == [".small.chunks"] and len(list((out / ".small.chunks").iterdir())) == 1
    monkeypatch.undo()
    (out.parent / "filler").unlink()
    assert cli.main(args) == 0
    assert "resuming: 12 of 12 scenes" in capsys.readouterr().out
    assert hidden(out) == [] and io.read_dataset(out / "small.nc").attrs["study"] != json.dumps(SMALL)


def test_a_full_disk_under_the_numba_cache_warns_once_and_the_run_goes_on(small_disk):
    fill(small_disk)
    (hits, right), err = run_kernel(small_disk / "numba-cache")
    assert (hits, right) == ("0", "True")
    assert err.count("CacheWarning") == 1, err
    assert f"cannot save compiled kernels in numba's cache {small_disk}/numba-cache" in err
    assert f"the disk holding {small_disk}/numba-cache" in err and "is full (" in err


# --- cause 4: a dask scheduler that dies mid-run -------------------------------------------------------------------

# 27 stepped scenes, one chunk each: long enough that the scheduler is killed with most of them still to run.
STEPPED = {"title": "stepped", "perturbation": {"samples": 2048}, "scan": {"triangle": 3, "axis": [1, 2, 3]},
           "integration": {"method": "rk4", "flips": 0}, "outputs": {"figures": [], "arrays": []}}


@pytest.mark.slow
def test_a_killed_scheduler_ends_the_run_with_one_line_and_keeps_the_finished_chunks(tmp_path):
    pytest.importorskip("distributed")
    dask = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")
    if dask is None:
        pytest.skip("no dask command (pip install 'tumble[distributed]')")
    study, out, file = write_study(tmp_path, STEPPED, "stepped"), tmp_path / "out", tmp_path / "scheduler.json"
    log = open(tmp_path / "dask.log", "w")
    env = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    scheduler = subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                  "--scheduler-file", str(file)], stdout=log, stderr=subprocess.STDOUT, env=env)
    worker = None
    try:
        deadline = time.monotonic() + 60
        while not file.exists() or not file.read_text().strip():
            assert time.monotonic() < deadline and scheduler.poll() is None, "the scheduler did not start"
            time.sleep(0.1)
        address = json.loads(file.read_text())["address"]
        worker = subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--nworkers", "1", "--no-dashboard",
                                   "--host", "127.0.0.1"], stdout=log, stderr=subprocess.STDOUT, env=env)
        run = tumble_command("run", study, "--out", out, "--scheduler", address, "--chunk-scenes", 1)
        chunks = out / ".stepped.chunks"
        while not (chunks.is_dir() and any(p.suffix == ".chunk" for p in chunks.iterdir())):
            assert run.poll() is None, run.communicate()
            assert time.monotonic() < deadline + 120, "no chunk finished"
            time.sleep(0.05)
        os.kill(scheduler.pid, signal.SIGKILL)
        status, _, err = finish(run, timeout=120)
    finally:
        for process in (worker, scheduler):
            if process is not None and process.poll() is None:
                process.kill()
                process.wait()
        log.close()
    kept = sorted(p.name for p in chunks.iterdir())
    assert status == 1, err
    reason = err.split("was lost")[1].split(";")[0]  # dask's reason for cancelling, one word: " (scheduler-...)"
    assert re.fullmatch(r"( \([\w.-]+\))?", reason), err
    assert err == (f"tumble: failed: the dask scheduler at {address} was lost{reason}; {len(kept)} finished chunk(s) "
                   f"are kept in {chunks}: start a scheduler again (or run without one) and rerun to resume from "
                   f"them\n"), err
    assert 1 <= len(kept) < 27 and all(name.endswith(".chunk") for name in kept), kept
    assert not (out / "stepped.nc").exists() and hidden(out) == [".stepped.chunks"]


# --- issue 44: the last faults -----------------------------------------------------------------------------------

def _from_a_shell():
    """A child with the signal dispositions a shell gives (whatever this test process has set or ignores)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


# A result file written while Ctrl-C comes at five points of the write (cause 2): a KeyboardInterrupt raised inside
# xarray's locked netCDF calls left a lock held, and closing the file waited for it for ever (the command hung after
# its own line, or printed "Exception ignored in: CachingFileManager.__del__" and a traceback).
_WRITE_INTERRUPTED = """
import os, signal, sys, threading, time
import numpy as np, xarray as xr
from tumble.output import io
folder = sys.argv[1]
ds = xr.Dataset({f"v{i}": (("sample",), np.random.default_rng(i).random(100_000)) for i in range(8)})
started = time.perf_counter()
io.write_dataset(ds, os.path.join(folder, "warm.nc"))
took = time.perf_counter() - started
for fraction in (0.05, 0.2, 0.4, 0.6, 0.8):
    timer = threading.Timer(fraction * took, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        io.write_dataset(ds, os.path.join(folder, "result.nc"))
        time.sleep(2 * took)  # a signal that came after the write is raised here
    except KeyboardInterrupt:
        pass
    timer.join()
    print(sorted(name for name in os.listdir(folder) if name != "warm.nc"), flush=True)
    for name in os.listdir(folder):
        if name != "warm.nc":
            os.remove(os.path.join(folder, name))
"""


@pytest.mark.slow  # a run in a new process interrupted while it writes (1.7 s)
def test_ctrl_c_while_a_result_file_is_written_never_hangs_or_speaks_and_leaves_no_half_file(tmp_path):
    done = subprocess.run([sys.executable, "-c", _WRITE_INTERRUPTED, str(tmp_path)], capture_output=True, text=True,
                          timeout=120, preexec_fn=_from_a_shell)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    listings = done.stdout.splitlines()
    assert len(listings) == 5, done.stdout
    assert all(listing in ("[]", "['result.nc']") for listing in listings), listings  # no .part file, ever


# 27 stepped scenes of 8192 samples, one chunk each: the cluster is busy for tens of seconds.
BUSY = {**STEPPED, "title": "busy", "perturbation": {"samples": 8192}}


def _ctrl_c_with_a_local_cluster(tmp_path, wait_for):
    """``tumble run --scheduler local`` in a session of its own, as from a terminal: Ctrl-C (SIGINT to the whole
    foreground group, the workers included) once a stdout line starts with ``wait_for``; returns (status, stderr)."""
    pytest.importorskip("distributed")
    study, out = write_study(tmp_path, BUSY, "busy"), tmp_path / "out"
    run = tumble_command("run", study, "--out", out, "--scheduler", "local", "--workers", 2, "--chunk-scenes", 1,
                         start_new_session=True, preexec_fn=_from_a_shell)
    try:
        for line in run.stdout:
            if line.startswith(wait_for):
                break
        time.sleep(0.5)
        os.killpg(run.pid, signal.SIGINT)
        status, _, err = finish(run, timeout=120)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    return status, err


@pytest.mark.parametrize("command", ["tumble", "-m tumble"])
def test_a_process_the_command_starts_through_multiprocessing_ignores_ctrl_c(command):
    """A LocalCluster's worker is spawned with the command's sys.argv and imports tumble as the command's __main__: it
    took itself for the command and printed "tumble: interrupted while starting" at every Ctrl-C (cause 3)."""
    import tumble

    main = "/usr/local/bin/tumble" if command == "tumble" else os.path.join(os.path.dirname(tumble.__file__),
                                                                           "__main__.py")
    code = (f"import signal, sys; sys.argv = [{main!r}, 'run']; sys.orig_argv += ['--multiprocessing-fork']; "
            "import tumble; print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN, "
            "signal.getsignal(signal.SIGTERM) is signal.SIG_DFL)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                          preexec_fn=_from_a_shell)
    assert done.stdout.split() == ["True", "True"], done.stderr


@pytest.mark.slow
def test_ctrl_c_with_a_local_cluster_is_said_once_by_the_command_and_the_workers_are_silent(tmp_path):
    status, err = _ctrl_c_with_a_local_cluster(tmp_path, "dask scheduler ")  # the cluster is up and running tasks
    assert status == 130, err
    assert err.startswith("tumble: interrupted") and err.count("\n") == 1, err


@pytest.mark.slow
def test_ctrl_c_while_the_local_cluster_starts_is_said_once_by_the_command(tmp_path):
    status, err = _ctrl_c_with_a_local_cluster(tmp_path, "tumble ")  # the first line: the cluster is not up yet
    assert status == 130, err
    assert err.startswith("tumble: interrupted") and err.count("\n") == 1, err


class _CancelledByTheLostScheduler(Exception):
    """What dask gives for a task the client cancelled when its scheduler went away (its reason in two lines)."""


_DASK_REASON = ("compute_task-0a1b2c cancelled for reason: scheduler-connection-lost.\nClient lost the connection to "
                "the scheduler. Please check your connection and re-run your work.")


class _ClientOfALostScheduler:
    """A dask client whose scheduler answers the first task (run here, for real) and is then lost: every other task
    comes back cancelled, with dask's own two-line reason."""

    status = "running"

    def __init__(self, address):
        self.scheduler = type("Scheduler", (), {"address": address})()
        self.loop = None

    def scheduler_info(self):
        return {"workers": {"tcp://127.0.0.1:1": {}}}

    def register_plugin(self, plugin):
        pass

    def scatter(self, job, broadcast=False):
        return job

    def submit(self, function, *args, pure=True, **kwargs):
        future = type("Future", (), {})()
        future.call = lambda: function(*args, **kwargs)
        return future

    def cancel(self, futures):
        pass

    def close(self, timeout=None):
        self.status = "closed"


def _as_completed_then_lost(futures, with_results=True, loop=None):
    for i, future in enumerate(futures):
        future.status = "finished" if i == 0 else "cancelled"
        yield future, future.call() if i == 0 else _CancelledByTheLostScheduler(_DASK_REASON)


def test_a_lost_scheduler_is_one_line_naming_its_address_what_is_kept_and_how_to_resume(tmp_path, monkeypatch, capsys):
    """dask's reason ran over two lines inside tumble's (cause 4); the test of a scheduler killed for real is slow."""
    import contextlib

    pytest.importorskip("distributed")
    import distributed as dask_distributed

    from tumble.pipeline import distributed

    address = "tcp://127.0.0.1:8786"
    @contextlib.contextmanager
    def connect(address, workers=None):
        yield _ClientOfALostScheduler(address)

    monkeypatch.setattr(distributed, "connect", connect)
    monkeypatch.setattr(dask_distributed, "as_completed", _as_completed_then_lost)
    study, out = write_study(tmp_path), tmp_path / "out"
    assert cli.main(["run", str(study), "--out", str(out), "--scheduler", address, "--chunk-scenes", "1"]) == 1
    err = capsys.readouterr().err
    chunks = out / ".small.chunks"
    kept = sorted(p.name for p in chunks.iterdir())
    assert err == (f"tumble: failed: the dask scheduler at {address} was lost (scheduler-connection-lost); "
                   f"{len(kept)} finished chunk(s) are kept in {chunks}: start a scheduler again (or run without one) "
                   f"and rerun to resume from them\n"), err
    assert len(kept) == 1 and not (out / "small.nc").exists()


def test_the_device_refusal_has_the_prefix_of_every_refusal(tmp_path, monkeypatch, capsys):
    """The command printed the device's line bare; the line itself still starts "device 'cuda':" (the contract)."""
    monkeypatch.setitem(sys.modules, "numba_cuda", None)  # as where numba-cuda is not installed
    assert cli.main(["run", "--device", "cuda", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tumble: error: device 'cuda': numba-cuda is not installed") and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


def test_ctrl_c_inside_an_llvm_callback_is_sent_again_not_dropped(monkeypatch):
    """While numba compiles (tens of seconds cold) the Python that runs is mostly llvmlite's object-cache callbacks
    from LLVM; a KeyboardInterrupt or Terminated raised in one was printed by ctypes as "Exception ignored on calling
    ctypes callback function" and dropped: `timeout 20 tumble run` went on for ten minutes. Found while trying issue 44's
    cases; the command's handler now sends the signal again once the callback has returned."""
    import threading

    from tumble import _interrupt

    resent = []
    monkeypatch.setattr(threading, "Timer", lambda delay, function, args: type(
        "Timer", (), {"start": lambda self: resent.append((delay, function, args))})())
    callback = {}
    exec(compile("def _raw_object_cache_notify(handler, signum):\n    import sys\n    handler(signum, sys._getframe())\n",
                 os.path.join("site-packages", "llvmlite", "binding", "executionengine.py"), "exec"), callback)
    for signum in (signal.SIGINT, signal.SIGTERM):
        callback["_raw_object_cache_notify"](_interrupt._interrupt, signum)  # inside the callback: nothing raised...
        assert resent[-1] == (_interrupt._RESEND_AFTER, os.kill, (os.getpid(), signum))  # ...the signal comes again
    with pytest.raises(KeyboardInterrupt):
        _interrupt._interrupt(signal.SIGINT, sys._getframe())
    with pytest.raises(_interrupt.Terminated):
        _interrupt._interrupt(signal.SIGTERM, sys._getframe())
    code = ("import signal, sys; sys.argv = ['tumble']; from tumble import _interrupt; _interrupt.release(); "
            "print(signal.getsignal(signal.SIGINT) is signal.getsignal(signal.SIGTERM) is _interrupt._interrupt)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                          preexec_fn=_from_a_shell)
    assert done.stdout.strip() == "True", done.stderr
