"""Scale-out on dask.distributed: one LocalCluster of two single-threaded worker processes on 127.0.0.1 for the
whole module; the same bits as in-process, resumed or not, from Python and from `tumble run --scheduler`."""

import pytest

pytest.importorskip("distributed")

import numba  # noqa: E402
import xarray as xr  # noqa: E402
from test_resume import BIG, BIG_RANGES, SCAN, STEPPED, _toml, assert_same_result, finished_chunks, write_chunk  # noqa: E402

import tumble  # noqa: E402
from tumble import cli
from tumble.output import io  # noqa: E402
from tumble.pipeline import config, distributed, runner


@pytest.fixture(scope="module")
def client():
    """The module's one LocalCluster (two worker processes, one thread each, 127.0.0.1), as tumble starts it."""
    with distributed.connect("local", workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def in_process(tmp_path_factory, warm_kernels):
    """The two studies run in this process: their result files."""
    out = tmp_path_factory.mktemp("in_process")
    tumble.run_study(SCAN, out=out)
    tumble.run_study(STEPPED, out=out)
    tumble.run_study(BIG, out=out)
    return {"scan": out / "resume.nc", "stepped": out / "stepped.nc", "big": out / "big.nc"}


def test_the_local_cluster_has_two_single_threaded_workers_on_localhost(client):
    workers = client.scheduler_info()["workers"]
    assert len(workers) == 2
    assert client.scheduler.address.startswith("tcp://127.0.0.1:")
    assert all(address.startswith("tcp://127.0.0.1:") and info["nthreads"] == 1 for address, info in workers.items())


def test_dask_workers_run_numba_with_one_thread(client):
    # numba's thread count is per thread: ask inside a task, where the scenes run, after compute_task set it.
    def threads_in_task():
        runner.compute_task({}, runner.Task(()), threads=1)
        return numba.get_num_threads(), numba.config.NUMBA_NUM_THREADS

    results = client.gather([client.submit(threads_in_task, pure=False, workers=[w])
                             for w in client.scheduler_info()["workers"]])
    assert results == [(1, 1), (1, 1)]
    plugins = client.run(lambda dask_worker: sorted(dask_worker.plugins))
    assert all("tumble-numba" in names for names in plugins.values())


@pytest.mark.default_cases("stepped")
@pytest.mark.parametrize("name, study", [("scan", SCAN), ("stepped", STEPPED)], ids=["scan", "stepped"])
def test_the_cluster_gives_the_bits_of_an_in_process_run(client, in_process, tmp_path, name, study):
    tumble.run_study(study, out=tmp_path, scheduler=client, chunk_scenes=2)
    assert_same_result(in_process[name], next(tmp_path.glob("*.nc")))
    assert [p.name for p in tmp_path.iterdir()] == [in_process[name].name]


def test_the_cluster_runs_the_sample_ranges_of_a_large_scene_with_the_bits_of_the_whole_scene(
        client, in_process, tmp_path, monkeypatch):
    resolved = config.load_study(BIG)
    job = runner.scene_job(resolved)
    store = runner.open_checkpoint(resolved, job, tmp_path, "big")
    task = runner.Task((0,), *BIG_RANGES[1])  # one range finished in process: the cluster runs the other three
    store.write(task.name, runner.compute_task(job, task, store.digest))
    submitted = []
    run_chunks = distributed.run_chunks
    monkeypatch.setattr(distributed, "run_chunks", lambda client, fn, job, tasks, digest: submitted.extend(tasks)
                        or run_chunks(client, fn, job, tasks, digest))
    tumble.run_study(BIG, out=tmp_path, scheduler=client, chunk_samples=4096)
    assert [(t.start, t.stop) for t in submitted] == [BIG_RANGES[0], *BIG_RANGES[2:]]
    assert_same_result(in_process["big"], tmp_path / "big.nc")
    assert [p.name for p in tmp_path.iterdir()] == ["big.nc"]


def test_the_cluster_resumes_a_checkpoint_written_in_process(client, in_process, tmp_path, monkeypatch):
    resolved = config.load_study(SCAN)
    job = runner.scene_job(resolved)
    write_chunk(runner.open_checkpoint(resolved, job, tmp_path, "resume"), job, range(0, 20))
    submitted = []
    run_chunks = distributed.run_chunks
    monkeypatch.setattr(distributed, "run_chunks", lambda client, fn, job, tasks, digest: submitted.extend(tasks)
                        or run_chunks(client, fn, job, tasks, digest))
    tumble.run_study(SCAN, out=tmp_path, scheduler=client, chunk_scenes=3)
    assert [task.scenes for task in submitted] == [(20, 21, 22), (23, 24, 25), (26,)]
    assert_same_result(in_process["scan"], tmp_path / "resume.nc")


def test_tumble_run_uses_the_scheduler_named_in_the_environment(client, in_process, tmp_path, monkeypatch, capsys):
    study = tmp_path / "resume.toml"
    study.write_text(_toml(SCAN))
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", client.scheduler.address)
    assert cli.main(["run", str(study), "--out", str(tmp_path / "env"), "--chunk-scenes", "5"]) == 0
    assert f"dask scheduler {client.scheduler.address}: 2 worker(s)" in capsys.readouterr().out
    assert_same_result(in_process["scan"], tmp_path / "env" / "resume.nc")
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
    assert cli.main(["run", str(study), "--out", str(tmp_path / "flag"), "--scheduler", client.scheduler.address]) == 0
    assert_same_result(in_process["scan"], tmp_path / "flag" / "resume.nc")


def test_an_error_in_a_worker_is_the_input_error_it_would_be_in_process(client, tmp_path, capsys):
    # Valid field by field, but the scene refuses it: a horizon needing more stored states than allowed.
    study = tmp_path / "long.toml"
    study.write_text(_toml({"body": {"moments": [1.0, 2.0, 3.0]}, "spin": {"axis": 1},
                            "perturbation": {"samples": 8}, "integration": {"horizon": 1e6},
                            "outputs": {"figures": [], "arrays": []}}))
    status = cli.main(["run", str(study), "--out", str(tmp_path / "out"), "--scheduler", client.scheduler.address])
    err = capsys.readouterr().err
    assert status == 2 and "horizon" in err and "Traceback" not in err
    assert not list((tmp_path / "out").glob("*.nc")) if (tmp_path / "out").exists() else True


def test_an_unreachable_scheduler_exits_1(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(distributed, "CONNECT_TIMEOUT", 1)
    status = cli.main(["run", "intermediate_axis", "--out", str(tmp_path / "out"), "--scheduler",
                       "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert status == 1 and "cannot reach the dask scheduler at tcp://127.0.0.1:9" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_results_on_the_cluster_are_datasets_xarray_can_compare(client, in_process):
    # The in-memory result (no file) is the same too.
    ds = tumble.run_study(SCAN, scheduler=client)
    stored = io.read_dataset(in_process["scan"])
    xr.testing.assert_equal(ds[["rate", "rel_error", "sample_rate"]], stored[["rate", "rel_error", "sample_rate"]])
    assert finished_chunks(in_process["scan"].parent) == []


def _silent_tcp_server():
    """A server that accepts TCP connections and never says a word."""
    import socket

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    return server.getsockname()[1], server.close


def _http_server():
    import http.server
    import threading

    class Quiet(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.HTTPServer(("127.0.0.1", 0), Quiet)
    threading.Thread(target=server.serve_forever, daemon=True).start()

    def close():
        server.shutdown()
        server.server_close()

    return server.server_address[1], close


@pytest.mark.default_cases("silent-tcp")
@pytest.mark.parametrize("make", [_silent_tcp_server, _http_server], ids=["silent-tcp", "http"])
def test_a_peer_that_is_not_a_dask_scheduler_ends_within_15_s_with_one_line(tmp_path, capsys, monkeypatch, make):
    """The probe gives up after its timeout: checked here with a 1 s timeout (the default's 5 s, twice, was a
    tenth of the warm suite), and the default is checked to stay well inside 15 s."""
    import time

    assert distributed.PROBE_TIMEOUT + 1 <= 7, "probe: TCP and handshake each within the timeout, plus 1 s slack"
    monkeypatch.setattr(distributed, "PROBE_TIMEOUT", 1)
    port, close = make()
    try:
        started = time.perf_counter()
        status = cli.main(["run", "intermediate_axis", "--out", str(tmp_path / "out"), "--scheduler",
                           f"tcp://127.0.0.1:{port}"])
        elapsed = time.perf_counter() - started
    finally:
        close()
    err = capsys.readouterr().err
    assert status == 1 and f"cannot reach the dask scheduler at tcp://127.0.0.1:{port}" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and elapsed < 5, (elapsed, err)
    assert not (tmp_path / "out").exists()


def test_a_closed_port_is_refused_at_once(tmp_path, capsys):
    import time

    started = time.perf_counter()
    status = cli.main(["run", "intermediate_axis", "--out", str(tmp_path / "out"), "--scheduler",
                       "tcp://127.0.0.1:9"])
    assert status == 1 and time.perf_counter() - started < 5 and "Connection refused" in capsys.readouterr().err


# --- the GPU of each worker (device = "cuda") ---------------------------------------------------------------------

@pytest.mark.parametrize("name, count, visible, gpu", [
    (0, 4, None, 0), (1, 4, None, 1), (5, 4, None, 1), ("3", 2, None, 1), (7, 1, None, 0),  # LocalCluster: k mod G
    (2, 4, "2,3,0,1", 0), (1, 2, "1", 0),  # dask-cuda lists the worker's own GPU first
    (3, 4, "", 3), (3, 4, " ", 3),  # set but empty: as unset
], ids=["first", "second", "wraps", "named_by_digits", "one_gpu", "dask_cuda", "one_visible", "empty", "blank"])
def test_a_worker_runs_on_gpu_index_mod_count_unless_cuda_visible_devices_lists_its_own_first(name, count, visible,
                                                                                              gpu):
    assert distributed.gpu_for_worker(name, count, visible) == gpu


def test_a_worker_named_otherwise_is_spread_over_the_gpus_the_same_way_every_run():
    import zlib

    names = [f"tcp://10.0.0.{k}:40000" for k in range(16)] + ["gpu-node-a", "-1"]
    picked = [distributed.gpu_for_worker(name, 4) for name in names]
    assert picked == [zlib.crc32(name.encode()) % 4 for name in names] and len(set(picked)) == 4
    with pytest.raises(ValueError, match="gpu_count must be an integer >= 1"):
        distributed.gpu_for_worker(0, 0)


def test_a_device_study_on_the_cluster_runs_each_task_on_its_workers_gpu(client, tmp_path):
    """With device = "cuda" every task selects its worker's GPU before its first launch (use_worker_gpu; numba-cuda's
    simulator in the workers here, one device), and the result is the in-process run's, bit for bit."""
    study = {"title": "device", "body": {"moments": [1.0, 2.0, 3.0]}, "perturbation": {"samples": 16},
             "scan": {"axis": [1, 2, 3]}, "integration": {"flips": 1, "device": "cuda"},
             "outputs": {"figures": [], "arrays": ["sample_rate", "sample_first_flip"]}}
    tumble.run_study(study, out=tmp_path / "here")
    tumble.run_study(study, out=tmp_path / "cluster", scheduler=client, chunk_scenes=1)
    assert_same_result(tmp_path / "here" / "device.nc", tmp_path / "cluster" / "device.nc")
    selected = client.run(lambda: distributed.SELECTED_GPU)
    assert set(selected.values()) <= {0, None} and 0 in selected.values()
    workers = list(client.scheduler_info()["workers"])
    picked = client.gather([client.submit(distributed.use_worker_gpu, workers=[w], pure=False) for w in workers])
    assert picked == [0, 0]
    assert distributed.use_worker_gpu() is None  # outside a worker: numba's default device
