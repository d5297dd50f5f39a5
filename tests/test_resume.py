"""Checkpoint and resume: finished chunks are reused only for the same study, the result is assembled
atomically, and the numbers are the same bits however the scan is cut, resumed or threaded."""

import json
import subprocess
import sys

import numba
import pytest
import xarray as xr

import tumble
from tumble import cli
from tumble.measure import planning, reduction, running
from tumble.output import io
from tumble.pipeline import checkpoint, config, runner

# 27 closed-form scenes (3 x 3 inertia triangle x 3 axes) of 64 samples: about a second.
SCAN = {"title": "resume", "perturbation": {"samples": 64}, "scan": {"triangle": 3, "axis": [1, 2, 3]},
        "integration": {"flips": 0}, "outputs": {"figures": [], "arrays": ["sample_rate", "sample_status"]}}

# Stepping scenes (rk4, samples over two blocks of 256 so that numba's prange splits them), both kinds.
STEPPED = {"title": "stepped", "body": {"moments": [1.0, 2.0, 3.0]}, "perturbation": {"samples": 600},
           "scan": {"axis": [1, 2], "method": ["auto", "rk4"]}, "integration": {"flips": 1},
           "outputs": {"figures": [], "arrays": ["sample_rate", "sample_first_flip"]}}

# One scene of 3 sampler blocks and a bit (closed form, exponential, flips timed): cut into 4 sample ranges with
# chunk_samples=4096, whole by default.
BIG = {"title": "big", "body": {"moments": [1.0, 2.0, 3.0]}, "spin": {"axis": 2},
       "perturbation": {"samples": 3 * 4096 + 100}, "integration": {"flips": 1},
       "outputs": {"figures": [], "arrays": ["sample_rate", "sample_status", "sample_first_flip"]}}
BIG_RANGES = [(0, 4096), (4096, 8192), (8192, 12288), (12288, 12388)]


def without_history(ds):
    """A result file's dataset without the line that records when it was written."""
    ds = ds.copy()
    ds.attrs.pop("history", None)
    return ds


def assert_same_result(path_a, path_b):
    xr.testing.assert_identical(without_history(io.read_dataset(path_a)), without_history(io.read_dataset(path_b)))


@pytest.fixture(scope="module")
def big_whole(tmp_path_factory):
    """BIG run in one go, in this process, its one scene whole (its file)."""
    out = tmp_path_factory.mktemp("big_whole")
    tumble.run_study(BIG, out=out)
    return out / "big.nc"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The scan run in one go, in this process, one chunk per scene (its file)."""
    out = tmp_path_factory.mktemp("reference")
    tumble.run_study(SCAN, out=out, chunk_scenes=1)
    return out / "resume.nc"


def write_chunk(store, job, indices):
    """Run the scenes ``indices`` as one chunk and write it into ``store``, as a run does."""
    task = runner.Task(tuple(indices))
    return store.write(task.name, runner.compute_task(job, task, store.digest))


def finished_chunks(out, stem="resume"):
    folder = checkpoint.chunk_folder(out, stem)
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []


@pytest.mark.parametrize("chunk_scenes", [4, 27])
def test_the_chunk_size_changes_no_bit_of_the_result(reference, tmp_path, chunk_scenes):
    tumble.run_study(SCAN, out=tmp_path, chunk_scenes=chunk_scenes)
    assert_same_result(reference, tmp_path / "resume.nc")


def test_a_chunked_run_gives_the_bits_of_the_plain_scan(reference):
    resolved = config.load_study(SCAN)
    p = runner.plan(resolved)
    values = p.values
    plain = tumble.scan(p.moments, values["axis"], values["spin"], values["amplitude"], values["method"],
                        samples=p.samples, seed=p.seed, body_coords=p.body_coords, **p.options)
    stored = io.read_dataset(reference)
    for name in ("rate", "rate_theory", "rel_error", "sample_rate", "rate_ci_low", "rate_ci_high"):
        assert plain[name].values.tobytes() == stored[name].values.tobytes(), name


def test_a_finished_run_leaves_only_its_result(reference):
    assert sorted(p.name for p in reference.parent.iterdir()) == ["resume.nc"]


def _run_with_clock(tmp_path, monkeypatch, after, ticks, fail_at=None):
    """run_scenes of SCAN (one chunk per 3 scenes: 9 chunks) with TUMBLE_CHECKPOINT_AFTER=``after`` on a clock that
    advances ``ticks`` seconds per reading; the chunk files written, by the time of each write (in chunks done)."""
    monkeypatch.setenv("TUMBLE_CHECKPOINT_AFTER", after)
    clock = iter(range(0, 10_000, 1))
    monkeypatch.setattr(runner.time, "monotonic", lambda: next(clock) * ticks)
    resolved = config.load_study(SCAN)
    job = runner.scene_job(resolved)
    store = runner.open_checkpoint(resolved, job, tmp_path, "resume")
    written, done = [], []
    write = store.write
    monkeypatch.setattr(store, "write", lambda name, data: written.append((len(done), name)) or write(name, data))
    compute = runner._compute

    def counted(job, task, **kw):
        if len(done) == fail_at:
            raise KeyboardInterrupt
        done.append(task)
        return compute(job, task, **kw)

    monkeypatch.setattr(runner, "_compute", counted)
    return runner.run_scenes(job, store=store, chunk_scenes=3), written


def test_a_run_shorter_than_the_checkpoint_delay_writes_no_chunk(tmp_path, monkeypatch):
    scenes, written = _run_with_clock(tmp_path, monkeypatch, "2", ticks=0.01)  # 9 chunks in well under 2 s
    assert len(scenes) == 27 and written == [] and finished_chunks(tmp_path) == []


def test_a_longer_run_writes_the_chunks_held_once_the_delay_has_passed_then_each_as_it_finishes(tmp_path,
                                                                                                  monkeypatch):
    _, written = _run_with_clock(tmp_path, monkeypatch, "2.5", ticks=1.0)  # the clock is read once per chunk
    assert [done for done, _ in written] == [3, 3, 3, 4, 5, 6, 7, 8, 9]  # the first three at 3 s, together
    assert len(finished_chunks(tmp_path)) == 9


def test_an_interrupted_run_writes_what_it_holds_before_it_stops(tmp_path, monkeypatch):
    with pytest.raises(KeyboardInterrupt):
        _run_with_clock(tmp_path, monkeypatch, "2", ticks=0.01, fail_at=4)
    assert finished_chunks(tmp_path) == ["scenes-000000-000002.chunk", "scenes-000003-000005.chunk",
                                         "scenes-000006-000008.chunk", "scenes-000009-000011.chunk"]


@pytest.mark.parametrize("text", ["soon", "-1", "nan"])
def test_a_checkpoint_delay_that_is_no_number_of_seconds_is_said_and_the_default_used(monkeypatch, text):
    monkeypatch.setenv("TUMBLE_CHECKPOINT_AFTER", text)
    with pytest.warns(RuntimeWarning, match=f"TUMBLE_CHECKPOINT_AFTER='{text}' is not a number of seconds >= 0"):
        assert runner.checkpoint_after() == runner.CHECKPOINT_AFTER
    monkeypatch.delenv("TUMBLE_CHECKPOINT_AFTER")
    assert runner.checkpoint_after() == runner.CHECKPOINT_AFTER == 2.0


def test_a_rerun_skips_the_finished_chunks_and_gives_the_same_bits(reference, tmp_path, monkeypatch):
    resolved = config.load_study(SCAN)
    job = runner.scene_job(resolved)
    store = runner.open_checkpoint(resolved, job, tmp_path, "resume")
    write_chunk(store, job, range(0, 10))
    write_chunk(store, job, [17, 20])
    assert finished_chunks(tmp_path) == ["scenes-000000-000009.chunk", "scenes-000017-000020.chunk"]
    assert not list(tmp_path.glob("*.nc"))  # finished chunks are never named like a result

    computed = []
    compute = runner.compute_scenes
    monkeypatch.setattr(runner, "compute_scenes",
                        lambda job, indices, **kw: computed.extend(indices) or compute(job, indices, **kw))
    logged = []
    scenes = runner.run_scenes(job, store=runner.open_checkpoint(resolved, job, tmp_path, "resume"), chunk_scenes=5,
                               log=logged.append)
    assert sorted(computed) == [i for i in range(27) if i >= 10 and i not in (17, 20)]
    assert "resuming: 12 of 27 scenes" in logged[0]
    assert len(scenes) == 27

    monkeypatch.setattr(runner, "compute_scenes", compute)
    tumble.run_study(SCAN, out=tmp_path)
    assert_same_result(reference, tmp_path / "resume.nc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["resume.nc"]  # checkpoint removed after the result


def test_a_chunk_of_another_study_is_never_reused(reference, tmp_path, monkeypatch):
    other = json.loads(json.dumps(SCAN))
    other["perturbation"]["seed"] = 7  # other numbers, same scenes and chunk names
    resolved = config.load_study(other)
    job = runner.scene_job(resolved)
    write_chunk(runner.open_checkpoint(resolved, job, tmp_path, "resume"), job, range(27))

    computed = []
    compute = runner.compute_scenes
    monkeypatch.setattr(runner, "compute_scenes",
                        lambda job, indices, **kw: computed.extend(indices) or compute(job, indices, **kw))
    tumble.run_study(SCAN, out=tmp_path)
    assert sorted(computed) == list(range(27))
    assert_same_result(reference, tmp_path / "resume.nc")


def test_a_chunk_of_another_tumble_version_is_never_reused(tmp_path, monkeypatch):
    resolved = config.load_study(SCAN)
    job = runner.scene_job(resolved)
    write_chunk(runner.open_checkpoint(resolved, job, tmp_path, "resume"), job, [0])
    monkeypatch.setattr(checkpoint, "__version__", "99.0")
    store = runner.open_checkpoint(resolved, job, tmp_path, "resume")
    assert store.load() == ({}, {}) and store.stale == 1 and finished_chunks(tmp_path) == []


def test_a_chunk_in_the_earlier_layout_is_never_reused(tmp_path):
    # before the records were stacked, a chunk held each array of each scene under "<scene>/<name>"
    resolved = config.load_study(SCAN)
    job = runner.scene_job(resolved)
    store = runner.open_checkpoint(resolved, job, tmp_path, "resume")
    record = runner.compute_scenes(job, [0])[0]
    store.write(checkpoint.scenes_name([0]), checkpoint._pack(
        {checkpoint.HASH_ATTR: store.digest, "kind": "scenes", "scenes": {"0": list(record)}},
        {f"0/{name}": value for name, value in record.items()}))
    with pytest.raises(ValueError, match="earlier layout"):
        checkpoint.unpack(store.folder / checkpoint.scenes_name([0]), store.digest, job.layout["scenes"])
    assert store.load() == ({}, {}) and store.stale == 1 and finished_chunks(tmp_path) == []


def test_the_study_hash_follows_every_number_but_not_where_or_how_figures_are_written():
    base = config.load_study(SCAN)
    digest = checkpoint.study_hash(base)
    for field, value in (("perturbation.samples", 65), ("perturbation.seed", 1), ("perturbation.amplitude", 2e-3),
                         ("integration.method", "rk4"), ("outputs.arrays", ["sample_rate"])):
        assert checkpoint.study_hash(config.load_study(SCAN, overrides={field: value})) != digest, field
    for field, value in (("outputs.format", ["pdf"]), ("outputs.directory", "elsewhere")):
        assert checkpoint.study_hash(config.load_study(SCAN, overrides={field: value})) == digest, field


def test_an_unreadable_chunk_is_recomputed_not_trusted(reference, tmp_path):
    folder = checkpoint.chunk_folder(tmp_path, "resume")
    folder.mkdir()
    (folder / "scenes-000000-000026.chunk").write_bytes(b"\x89HDF\r\n\x1a\n truncated")
    (folder / ".scenes-000000-000003.chunk.abc.part").write_bytes(b"half a chunk")
    tumble.run_study(SCAN, out=tmp_path)
    assert_same_result(reference, tmp_path / "resume.nc")
    assert not folder.exists()


def test_an_interrupted_run_leaves_no_file_named_like_a_result(tmp_path, monkeypatch, capsys):
    compute = runner.compute_scenes

    def fail_at_scene_12(job, indices, **kw):
        if 12 in indices:
            raise KeyboardInterrupt
        return compute(job, indices, **kw)

    monkeypatch.setattr(runner, "compute_scenes", fail_at_scene_12)
    study = tmp_path / "resume.toml"
    study.write_text(_toml(SCAN))
    status = cli.main(["run", str(study), "--out", str(tmp_path / "out"), "--chunk-scenes", "4"])
    assert status == cli.EXIT_INTERRUPTED == 130 and "interrupted" in capsys.readouterr().err
    out = tmp_path / "out"
    assert [p.name for p in out.iterdir()] == [".resume.chunks"]
    assert finished_chunks(out) == ["scenes-000000-000003.chunk", "scenes-000004-000007.chunk",
                                    "scenes-000008-000011.chunk"]
    chunk = checkpoint.chunk_folder(out, "resume") / "scenes-000000-000003.chunk"
    assert cli.main(["plot", str(chunk)]) == 2  # a chunk is not a tumble result
    assert "not a tumble result" in capsys.readouterr().err


def test_numba_thread_count_changes_no_bit(tmp_path, warm_kernels):
    before = numba.get_num_threads()
    try:
        paths = []
        for threads in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(threads)
            tumble.run_study(STEPPED, out=tmp_path / f"threads{threads}", chunk_scenes=3)
            paths.append(tmp_path / f"threads{threads}" / "stepped.nc")
    finally:
        numba.set_num_threads(before)
    assert_same_result(*paths)


def test_fresh_discards_an_earlier_checkpoint(reference, tmp_path, capsys):
    resolved = config.load_study(SCAN)
    job = runner.scene_job(resolved)
    write_chunk(runner.open_checkpoint(resolved, job, tmp_path / "out", "resume"), job, [3])
    study = tmp_path / "resume.toml"
    study.write_text(_toml(SCAN))
    assert cli.main(["run", str(study), "--out", str(tmp_path / "out"), "--fresh"]) == 0
    assert "resuming" not in capsys.readouterr().out
    assert_same_result(reference, tmp_path / "out" / "resume.nc")


def test_dry_run_checks_and_counts_but_writes_nothing(tmp_path, capsys):
    study = tmp_path / "resume.toml"
    study.write_text(_toml(SCAN))
    assert cli.main(["run", str(study), "--out", str(tmp_path / "out"), "--dry-run", "--chunk-scenes", "10"]) == 0
    assert "27 scene(s) of 64 samples in 3 chunk(s)" in capsys.readouterr().out
    big = tmp_path / "big.toml"
    big.write_text(_toml(BIG))
    assert cli.main(["run", str(big), "--out", str(tmp_path / "out"), "--dry-run", "--chunk-samples", "4096"]) == 0
    assert "1 scene(s) of 12388 samples in 4 chunk(s) of up to 1 (4 of them sample ranges of up to 4096 samples)" \
        in capsys.readouterr().out
    assert not (tmp_path / "out").exists()


def test_sample_ranges_are_cut_at_multiples_of_the_sampler_block():
    assert runner.sample_ranges(12388, 4096) == BIG_RANGES
    assert runner.sample_ranges(12388, 8192) == [(0, 8192), (8192, 12388)]
    # the range holding sample 0 reaches `first` (the norm curve's samples); finished ranges stay as they are
    assert runner.sample_ranges(40000, 4096, first=32768) == [(0, 32768), (32768, 36864), (36864, 40000)]
    assert runner.sample_ranges(12388, 8192, done=[(0, 4096), (8192, 12288)]) == [(4096, 8192), (12288, 12388)]
    with pytest.raises(ValueError, match="chunk_samples must be a multiple of 4096"):
        runner.chunk_samples_size(5000)


def test_a_scene_cut_into_sample_ranges_gives_the_bits_of_the_whole_scene(big_whole, tmp_path, monkeypatch):
    ranges = []
    compute = runner.compute_samples
    monkeypatch.setattr(runner, "compute_samples",
                        lambda job, i, lo, hi, **kw: ranges.append((lo, hi)) or compute(job, i, lo, hi, **kw))
    tumble.run_study(BIG, out=tmp_path, chunk_samples=4096)
    assert ranges == BIG_RANGES
    assert_same_result(big_whole, tmp_path / "big.nc")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.nc"]


def test_the_norm_curve_keeps_its_samples_when_a_scene_is_cut(monkeypatch):
    # growth_norm is a quantile over the first SLICE samples: the range holding sample 0 must hold them all.
    job = runner.scene_job(config.load_study(BIG, overrides={"outputs.figures": ["norm_growth"]}))
    tasks = runner.plan_tasks(job, checkpoint.Finished({}, {}), chunk_samples=4096)
    assert [(t.start, t.stop) for t in tasks] == [(0, 12388)]  # SLICE > 12388 samples: one range
    monkeypatch.setattr(planning, "SLICE", 8192)  # a smaller slice, to cut a small scene
    tasks = runner.plan_tasks(job, checkpoint.Finished({}, {}), chunk_samples=4096)
    assert [(t.start, t.stop) for t in tasks] == [(0, 8192), (8192, 12288), (12288, 12388)]
    scene = planning.scene_plan((1.0, 2.0, 3.0), 2, samples=12388, flips=0, curves=("norm",))
    with pytest.raises(ValueError, match="norm curve"):
        running.scene_samples(scene, 0, 4096)
    whole = reduction.scene_result(scene, [running.scene_samples(scene, 0, 12388)])
    cut = reduction.scene_result(scene, [running.scene_samples(scene, t.start, t.stop) for t in tasks])
    xr.testing.assert_identical(whole, cut)
    assert whole.growth_norm.values.tobytes() == cut.growth_norm.values.tobytes()


def test_a_rerun_resumes_from_finished_sample_ranges(big_whole, tmp_path, monkeypatch):
    resolved = config.load_study(BIG)
    job = runner.scene_job(resolved)
    store = runner.open_checkpoint(resolved, job, tmp_path, "big")
    for lo, hi in (BIG_RANGES[0], BIG_RANGES[2]):
        task = runner.Task((0,), lo, hi)
        store.write(task.name, runner.compute_task(job, task, store.digest))
    assert finished_chunks(tmp_path, "big") == ["samples-000000-0000000000-0000004096.chunk",
                                                "samples-000000-0000008192-0000012288.chunk"]
    ranges = []
    compute = runner.compute_samples
    monkeypatch.setattr(runner, "compute_samples",
                        lambda job, i, lo, hi, **kw: ranges.append((lo, hi)) or compute(job, i, lo, hi, **kw))
    logged = []
    runner.run_scenes(job, store=runner.open_checkpoint(resolved, job, tmp_path, "big"), chunk_samples=8192,
                      log=logged.append)  # another range size: the finished ranges are used all the same
    assert ranges == [BIG_RANGES[1], BIG_RANGES[3]]
    assert "resuming: 0 of 1 scenes and 2 sample range(s) of 1 more" in logged[0]
    ranges.clear()
    tumble.run_study(BIG, out=tmp_path)  # every range finished: nothing to compute, only the reduction
    assert ranges == []
    assert_same_result(big_whole, tmp_path / "big.nc")


@pytest.mark.parametrize("args, words", [
    (("--scheduler", "localhost:8786"), "tcp://HOST:PORT"),
    (("--chunk-samples", "5000"), "--chunk-samples: chunk_samples must be a multiple of 4096"),
    (("--chunk-scenes", "0"), "--chunk-scenes"),
    (("--workers", "0"), "--workers"),
])
def test_bad_scale_out_options_exit_2(tmp_path, capsys, args, words):
    status = cli.main(["run", "intermediate_axis", "--out", str(tmp_path / "out"), *args])
    err = capsys.readouterr().err
    assert status == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_without_dask_tumble_runs_and_scheduler_exits_2_with_how_to_install(tmp_path):
    hide_dask = "import sys; sys.modules['distributed'] = None; sys.modules['dask'] = None; import tumble.cli as c; "
    done = subprocess.run([sys.executable, "-c", hide_dask + "sys.exit(c.main(sys.argv[1:]))", "run",
                           "intermediate_axis", "--out", str(tmp_path / "out"), "--scheduler", "local"],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 2, done.stderr
    assert "dask.distributed is not installed" in done.stderr and "pip install" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "out").exists()


def _toml(study):
    """A study mapping as TOML text (tables of scalars and lists only, as the studies here)."""
    lines = []
    for key, value in study.items():
        if not isinstance(value, dict):
            lines.append(f"{key} = {json.dumps(value)}")
    for key, value in study.items():
        if isinstance(value, dict):
            lines.append(f"[{key}]")
            lines += [f"{k} = {json.dumps(v)}" for k, v in value.items()]
    return "\n".join(lines) + "\n"
