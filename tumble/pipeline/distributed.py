"""Run a study's scenes on a dask.distributed cluster (optional: ``pip install "tumble[distributed]"``).

``tumble run STUDY --scheduler local`` starts a LocalCluster on 127.0.0.1 (one worker process per core, one
thread each); ``--scheduler tcp://HOST:PORT`` (or the environment variable ``DASK_SCHEDULER_ADDRESS``) uses a
running scheduler. Each task is one chunk — whole scenes, or one range of the samples of a large scene
(:func:`tumble.pipeline.runner.compute_task`); its result is the chunk file's bytes (a compact NumPy archive, made in the
worker), which the client writes as the checkpoint and reads back, so workers need no shared file system, only
tumble installed.

Numba inside workers: every task sets numba's thread count to 1 for the thread it runs in (the cores are
shared out between dask's worker threads instead), and LocalCluster workers start with
``NUMBA_NUM_THREADS=1``. The kernels are compiled, or loaded from numba's on-disk cache, once per worker
process — on its first task, or at start-up through :class:`NumbaWorkerPlugin` — and stay loaded for every
later task.

GPUs: with ``device = "cuda"`` each worker runs its chunks on its own GPU, chosen by :func:`gpu_for_worker` and
selected (``numba.cuda.select_device``) in the thread that runs the task, before its first launch
(:func:`use_worker_gpu`): the first GPU of ``CUDA_VISIBLE_DEVICES`` where the worker's environment sets it (dask-cuda's
``LocalCUDACluster`` lists each worker's own GPU first), else GPU ``worker index mod GPU count`` (a LocalCluster names
its workers 0, 1, 2, ...).

Nothing here binds beyond 127.0.0.1: a remote cluster is one the user started and names.
"""

from __future__ import annotations

import contextlib
import os
import threading
import zlib

__all__ = ["SchedulerError", "SchedulerLost", "available", "connect", "gpu_for_worker", "run_chunks",
           "scheduler_address", "use_worker_gpu"]

#: Environment variable naming a running scheduler (dask's own convention).
ENV_ADDRESS = "DASK_SCHEDULER_ADDRESS"

#: Address prefixes accepted for a running scheduler.
PROTOCOLS = ("tcp://", "tls://", "ucx://", "ws://", "wss://", "inproc://")

#: Seconds to wait for a running scheduler to answer.
CONNECT_TIMEOUT = 10

#: Seconds the first contact may take: a TCP connection, then dask's handshake. A peer that accepts TCP but
#: never answers (or answers in another protocol) is given up on after this, with one clear line.
PROBE_TIMEOUT = 5

#: dask settings of a LocalCluster tumble starts. Its diagnostics sampled dask's own event loops 50 to 100 times a
#: second (the worker's statistical profiler every 10 ms, the event-loop tick every 20 ms, the nannies' memory
#: monitor every 100 ms, the system monitor every 500 ms): 17 % of a core with the cluster idle, on a machine
#: whose cores the workers need. Sampled rarely (and without the profiler, which nobody reads without a
#: dashboard), the idle cluster takes 2 %. And dask starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which
#: also switches off glibc's adaptive mmap threshold: every NumPy temporary above 128 KiB (the phase fits,
#: the sorts of the summaries) was then mapped and unmapped afresh, and a scene ran 10-15 % slower in a worker
#: than in-process; the workers here keep glibc's default. Workers get these settings from their nannies.
QUIET_LOCAL_CLUSTER = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.nanny.pre-spawn-environ": {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1},
}


class SchedulerError(ValueError):
    """An unusable ``--scheduler``: dask.distributed missing, or an address that is not one."""


class SchedulerLost(RuntimeError):
    """The dask scheduler went away mid-run (killed, its machine down, the network cut): the client cancelled every
    task still out. The chunks that finished before are in the checkpoint; a rerun resumes from them."""


def available():
    """True when dask.distributed can be imported."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def scheduler_address(option=None):
    """The scheduler to use: ``option`` (``--scheduler``), else ``$DASK_SCHEDULER_ADDRESS``, else None.

    Raises
    ------
    SchedulerError
        Neither ``"local"`` nor an address with a protocol (``tcp://HOST:PORT``), or dask.distributed is not
        installed.
    """
    address = option if option is not None else os.environ.get(ENV_ADDRESS) or None
    if address is None:
        return None
    where = "--scheduler" if option is not None else ENV_ADDRESS
    if not isinstance(address, str) or not (address == "local" or address.startswith(PROTOCOLS)):
        raise SchedulerError(f"{where}: expected 'local' or a scheduler address like tcp://HOST:PORT, "
                             f"got {address!r}")
    if address != "local":
        _check_host_and_port(address, where)
    if not available():
        raise SchedulerError(f"{where} {address}: dask.distributed is not installed; install it with "
                             f"pip install \"tumble[distributed]\" (or \"dask[distributed]\"), or run without "
                             f"--scheduler")
    return address


def _check_host_and_port(address, where):
    """Refuse an address whose host is empty or whose port is not a number in 1..65535."""
    from urllib.parse import urlsplit

    try:
        parts = urlsplit(address)
        port = parts.port
    except ValueError as err:  # a port that is not a number, or out of range
        raise SchedulerError(f"{where}: {address!r}: the port must be a number from 1 to 65535 ({err})") from None
    if not parts.hostname:
        raise SchedulerError(f"{where}: {address!r} names no host; expected tcp://HOST:PORT")
    if port is not None and not 1 <= port <= 65535:
        raise SchedulerError(f"{where}: {address!r}: the port must be a number from 1 to 65535")


def probe(address, timeout=None):
    """Check that a dask scheduler answers at ``address`` before a Client is made (which would retry for its
    whole timeout, and hang on a peer that accepts TCP but never answers).

    A TCP connection first (a closed port fails at once), then dask's handshake, both within ``timeout``
    seconds (default :data:`PROBE_TIMEOUT`). Skipped inside a running event loop (a notebook's), where the
    Client's own timeout applies.

    Raises
    ------
    OSError
        Nothing listens there, or the peer does not answer as a dask scheduler in time.
    """
    import asyncio
    import socket
    from urllib.parse import urlsplit

    timeout = PROBE_TIMEOUT if timeout is None else timeout
    where = f"cannot reach the dask scheduler at {address}"
    parts = urlsplit(address)
    if parts.scheme in ("tcp", "tls") and parts.hostname:
        try:
            socket.create_connection((parts.hostname, parts.port or 8786), timeout=timeout).close()
        except OSError as err:
            raise OSError(f"{where}: {err.strerror or err}") from None
    try:
        asyncio.get_running_loop()
        return  # inside an event loop: leave it to the Client
    except RuntimeError:
        pass
    from distributed.comm import connect as comm_connect

    async def handshake():
        comm = await comm_connect(address, timeout=timeout)
        await comm.close()

    try:
        asyncio.run(asyncio.wait_for(handshake(), timeout + 1))
    except (TimeoutError, asyncio.TimeoutError):
        raise OSError(f"{where}: no answer in dask's protocol within {timeout} s (something listens there, but "
                      f"it is not a dask scheduler, or it is stuck)") from None
    except MemoryError:  # a peer of another protocol whose bytes read as an absurd frame length
        raise OSError(f"{where}: the peer does not speak dask's protocol (not a dask scheduler)") from None
    except OSError as err:
        raise OSError(f"{where}: {err}") from None


def _numba_one_thread():
    """Set numba to one thread in the calling thread (run on each worker at start-up)."""
    import numba

    numba.set_num_threads(1)
    from . import runner  # noqa: F401  (import once per worker process, not per task)

    return numba.get_num_threads()


def _quiet_worker_logs():
    """Silence dask's loggers in this process, a worker of the command's own LocalCluster, whose lines go to the user's
    terminal: when the command stopped the cluster (Ctrl-C) they logged its cancelled tasks ("Async instruction ...
    ended with CancelledError") and their lost scheduler ("Failed to communicate with scheduler during heartbeat", with
    a traceback) below the command's one line (issue 44). What matters comes back to the command, which says it: a
    task's error (raised again there), a worker that dies (its nanny, in the command's process, logs it)."""
    import logging

    logging.getLogger("distributed").setLevel(logging.CRITICAL)


def _plugin(local=False):
    from distributed.diagnostics.plugin import WorkerPlugin

    class NumbaWorkerPlugin(WorkerPlugin):
        """Import tumble and set numba to one thread when a worker starts (tasks set it again: numba's
        thread count is per thread, and tasks run in the worker's executor threads); in a worker of the command's
        own LocalCluster (``local``), dask's warnings are not shown (:func:`_quiet_worker_logs`)."""

        name = "tumble-numba"

        def __init__(self, local):
            self.local = local

        def setup(self, worker):
            if self.local:
                _quiet_worker_logs()
            _numba_one_thread()

    return NumbaWorkerPlugin(local)


@contextlib.contextmanager
def connect(address, *, workers=None):
    """A ``distributed.Client`` for ``"local"`` (a LocalCluster this context starts and stops) or an address.

    Parameters
    ----------
    address : str
        ``"local"`` or ``"tcp://HOST:PORT"`` (see :func:`scheduler_address`).
    workers : int, optional
        Worker processes of a LocalCluster (default: the number of cores), one thread each, bound to
        127.0.0.1, no dashboard, its diagnostics sampled rarely (:data:`QUIET_LOCAL_CLUSTER`).
    """
    address = scheduler_address(address)
    from distributed import Client, LocalCluster

    if address == "local":
        import dask

        n = workers or os.cpu_count() or 1
        with dask.config.set(QUIET_LOCAL_CLUSTER), contextlib.ExitStack() as stack:
            with _ctrl_c_held():
                # dashboard_address=None still binds the scheduler's HTTP server (health, metrics) to port 8787,
                # and a second cluster on the machine then warns on stderr: any free port instead
                cluster = stack.enter_context(LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                           host="127.0.0.1", dashboard_address=None,
                                                           scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                                           env={"NUMBA_NUM_THREADS": "1"}))
            client = stack.enter_context(Client(cluster))
            client.register_plugin(_plugin(local=True))
            try:
                yield client
            except KeyboardInterrupt:  # Ctrl-C or SIGTERM (tumble._interrupt.Terminated)
                _stop_at_once(cluster)
                raise
        return
    probe(address)
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except OSError as err:
        raise OSError(f"cannot reach the dask scheduler at {address}: {err}") from err
    with client:
        client.register_plugin(_plugin())
        yield client


@contextlib.contextmanager
def _ctrl_c_held():
    """SIGINT blocked in this (main) thread while a LocalCluster starts: the event-loop thread it starts, and the
    worker processes that thread starts, inherit the block (Python's own way to shield the processes it starts,
    bpo-33613), so the terminal's Ctrl-C, sent to every process of its foreground group, never reaches a worker, not
    even half-way through its start-up (issue 44: each printed the command's line, a "Fatal Python error", or dask's
    warnings about its cancelled task). A Ctrl-C meanwhile waits here until the cluster is up, then stops it and the
    command. multiprocessing's resource tracker is started first: starting it unblocks SIGINT in the thread that
    starts it. Only in the main thread, where the system has signal masks."""
    import signal

    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def _stop_at_once(cluster):
    """Stop the worker processes of the command's own LocalCluster after Ctrl-C, without dask's words: a worker still in
    a kernel is killed after 0.4 s (its nanny waited 4 s, then logged that it killed it), and the lines dask logs as the
    cluster goes (lost tasks and scattered data, restarts) are not shown: the command says it was interrupted, once."""
    import asyncio
    import logging

    for name in ["distributed", *logging.root.manager.loggerDict]:
        if name == "distributed" or name.startswith("distributed."):
            logging.getLogger(name).setLevel(logging.CRITICAL)

    async def close(nannies):
        await asyncio.gather(*(nanny.close(timeout=0.5, reason="tumble-interrupted") for nanny in nannies),
                             return_exceptions=True)

    with contextlib.suppress(Exception):
        cluster.sync(close, list(cluster.workers.values()))


def gpu_for_worker(name, gpu_count, visible_devices=None):
    """The GPU on which a dask worker runs its chunks with ``device="cuda"``: an index into the devices numba-cuda
    sees in that worker (``numba.cuda.gpus``, which lists the GPUs of ``CUDA_VISIBLE_DEVICES`` in its order, else all).

    The rule:

    * ``CUDA_VISIBLE_DEVICES`` set and not empty in the worker's environment (``visible_devices``): 0, the first GPU
      it lists. dask-cuda's ``LocalCUDACluster`` and ``dask cuda worker`` start worker ``k`` with its own GPU listed
      first (``k, k+1, ..., 0, ..., k-1``), so each worker keeps to its GPU. A list set alike for every worker of a
      plain LocalCluster puts them all on its first GPU: give each worker its own list, or use dask-cuda.
    * otherwise the worker's index modulo ``gpu_count``: a LocalCluster (``tumble run --scheduler local``) names its
      workers 0, 1, 2, ..., so on a machine of ``G`` GPUs worker ``k`` runs on GPU ``k mod G`` (workers share a GPU
      only when there are more workers than GPUs). A worker named otherwise (``dask worker --name NAME``; by default
      its address) takes the CRC-32 of its name as its index: spread over the GPUs, the same in every run, but two
      workers may share one; start such workers with ``CUDA_VISIBLE_DEVICES`` naming their GPU.

    Parameters
    ----------
    name : int or str
        The worker's name (``distributed.get_worker().name``).
    gpu_count : int
        GPUs numba-cuda sees in the worker (>= 1).
    visible_devices : str, optional
        The worker's ``CUDA_VISIBLE_DEVICES``.

    Returns
    -------
    int
        In ``[0, gpu_count)``.
    """
    if isinstance(gpu_count, bool) or not isinstance(gpu_count, int) or gpu_count < 1:
        raise ValueError(f"gpu_count must be an integer >= 1, got {gpu_count!r}")
    if visible_devices is not None and visible_devices.strip():
        return 0
    if isinstance(name, int) and not isinstance(name, bool) and name >= 0:
        index = name
    elif isinstance(name, str) and name.isascii() and name.isdigit():
        index = int(name)
    else:
        index = zlib.crc32(str(name).encode())
    return index % gpu_count


#: The GPU this worker process selected (:func:`use_worker_gpu`), None before; and the threads that selected it.
SELECTED_GPU = None
_SELECTED_IN = threading.local()


def use_worker_gpu():
    """Select this dask worker's GPU (:func:`gpu_for_worker`) in the calling thread, before its first launch: numba-cuda
    keeps the current device per thread, so the task's thread selects it (once; later tasks in the thread find it
    selected). Outside a dask worker nothing is selected (numba's default, device 0). Returns the GPU's index, or None
    outside a worker.

    Raises
    ------
    ValueError
        ``device 'cuda': ...`` where the worker has no usable device (:func:`tumble.engine.device.resolve_device`).
    """
    global SELECTED_GPU
    selected = getattr(_SELECTED_IN, "gpu", None)
    if selected is not None:
        return selected
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):  # not in a worker
        return None
    from ..engine.device import resolve_device

    resolve_device("cuda")  # no numba-cuda or no GPU in this worker: its one line, before numba.cuda is asked
    from numba import cuda

    index = gpu_for_worker(worker.name, len(cuda.gpus), os.environ.get("CUDA_VISIBLE_DEVICES"))
    cuda.select_device(index)
    _SELECTED_IN.gpu = SELECTED_GPU = index
    return index


def _on_worker_gpu(compute_task, job, task, digest, threads):
    """``compute_task`` of a device job in a dask worker, on the worker's GPU (:func:`use_worker_gpu`)."""
    use_worker_gpu()
    return compute_task(job, task, digest, threads=threads)


def run_chunks(client, compute_task, job, tasks, digest=""):
    """Submit every task to the cluster; yield ``(task, chunk bytes)`` for each as it finishes.

    The job is scattered to every worker once (tasks carry only a reference to it); each task returns its
    chunk file's bytes (:func:`tumble.pipeline.runner.compute_task`), which the caller writes and reads; a job on the
    CUDA device (``job.options["device"]``) runs each task on its worker's GPU (:func:`use_worker_gpu`). On an error (or
    when the caller stops early) the tasks still queued are cancelled; the error of a task is raised again here
    as it was raised on the worker.
    """
    from distributed import as_completed

    if not tasks:
        return
    job_future = client.scatter(job, broadcast=True)
    if job.options["device"] == "cuda":
        futures = {client.submit(_on_worker_gpu, compute_task, job_future, task, digest, 1, pure=False): task
                   for task in tasks}
    else:
        futures = {client.submit(compute_task, job_future, task, digest, threads=1, pure=False): task
                   for task in tasks}
    try:
        for future, data in as_completed(futures, with_results=True, loop=client.loop):
            if future.status == "cancelled" or not isinstance(data, bytes):  # dask's CancelledError, not a chunk
                raise SchedulerLost(f"the dask scheduler at {client.scheduler.address} was lost"
                                    f"{_lost_because(data)}")
            yield futures[future], data
    except SchedulerLost:
        _quiet_client(client)
        raise
    finally:
        if client.status == "running":
            client.cancel(list(futures))


def _lost_because(cancelled):
    """`` (REASON)``: the reason dask gave for cancelling a task (``scheduler-connection-lost``), or nothing. dask's own
    words run over several lines ("compute_task-... cancelled for reason: scheduler-connection-lost.", then "Client
    lost the connection to the scheduler. ..."), and a failure is one line
    (issue 44): the rest of them is what :class:`SchedulerLost`'s message says anyway."""
    import re

    found = re.search(r"reason:\s*([\w.-]+?)\.?(?:\s|$)", str(cancelled))
    return f" ({found.group(1)})" if found else ""


def _quiet_client(client):
    """Stop a client whose scheduler is gone from retrying and from logging its ERROR lines about it: close it now
    (the caller reports the loss in one line)."""
    import logging

    for name in ("distributed.client", "distributed.batched", "distributed.core", "distributed.comm"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    with contextlib.suppress(Exception):
        client.close(timeout=1)
