"""Faults a user meets, made to happen for real (issue 33): two runs into one folder, a damaged or unwritable numba
cache, a full disk, a dask scheduler killed mid-run. Each test checks the one line the user reads and what is left on
disk: earlier results intact, no half file, finished chunks kept for a rerun."""

import errno
import json
import os
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
    assert err == (f"tumble: failed: the dask scheduler at {address} was lost: its tasks were cancelled "
                   f"({err.split('cancelled (')[1].split(')')[0]}); {len(kept)} finished chunk(s) are kept in "
                   f"{chunks}: rerun to resume\n"), err
    assert 1 <= len(kept) < 27 and all(name.endswith(".chunk") for name in kept), kept
    assert not (out / "stepped.nc").exists() and hidden(out) == [".stepped.chunks"]
