"""Run a study's scenes on a dask.distributed cluster (optional: ``pip install "tumble[distributed]"``).

``tumble run STUDY --scheduler local`` starts a LocalCluster on 127.0.0.1 (one worker process per core, one
thread each); ``--scheduler tcp://HOST:PORT`` (or the environment variable ``DASK_SCHEDULER_ADDRESS``) uses a
running scheduler. Each task is one chunk of scenes (:func:`tumble.runner.compute_chunk`); its result comes
back to the client, which writes the chunk's checkpoint file, so workers need no shared file system, only
tumble installed.

Numba inside workers: every task sets numba's thread count to 1 for the thread it runs in (the cores are
shared out between dask's worker threads instead), and LocalCluster workers start with
``NUMBA_NUM_THREADS=1``. The kernels are compiled, or loaded from numba's on-disk cache, once per worker
process — on its first task, or at start-up through :class:`NumbaWorkerPlugin` — and stay loaded for every
later task.

Nothing here binds beyond 127.0.0.1: a remote cluster is one the user started and names.
"""

from __future__ import annotations

import contextlib
import os

__all__ = ["SchedulerError", "available", "connect", "run_chunks", "scheduler_address"]

#: Environment variable naming a running scheduler (dask's own convention).
ENV_ADDRESS = "DASK_SCHEDULER_ADDRESS"

#: Address prefixes accepted for a running scheduler.
PROTOCOLS = ("tcp://", "tls://", "ucx://", "ws://", "wss://", "inproc://")

#: Seconds to wait for a running scheduler to answer.
CONNECT_TIMEOUT = 30


class SchedulerError(ValueError):
    """An unusable ``--scheduler``: dask.distributed missing, or an address that is not one."""


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
    if not available():
        raise SchedulerError(f"{where} {address}: dask.distributed is not installed; install it with "
                             f"pip install \"tumble[distributed]\" (or \"dask[distributed]\"), or run without "
                             f"--scheduler")
    return address


def _numba_one_thread():
    """Set numba to one thread in the calling thread (run on each worker at start-up)."""
    import numba

    numba.set_num_threads(1)
    import tumble  # noqa: F401  (import once per worker process, not per task)

    return numba.get_num_threads()


def _plugin():
    from distributed.diagnostics.plugin import WorkerPlugin

    class NumbaWorkerPlugin(WorkerPlugin):
        """Import tumble and set numba to one thread when a worker starts (tasks set it again: numba's
        thread count is per thread, and tasks run in the worker's executor threads)."""

        name = "tumble-numba"

        def setup(self, worker):
            _numba_one_thread()

    return NumbaWorkerPlugin()


@contextlib.contextmanager
def connect(address, *, workers=None):
    """A ``distributed.Client`` for ``"local"`` (a LocalCluster this context starts and stops) or an address.

    Parameters
    ----------
    address : str
        ``"local"`` or ``"tcp://HOST:PORT"`` (see :func:`scheduler_address`).
    workers : int, optional
        Worker processes of a LocalCluster (default: the number of cores), one thread each, bound to
        127.0.0.1, no dashboard.
    """
    address = scheduler_address(address)
    from distributed import Client, LocalCluster

    if address == "local":
        n = workers or os.cpu_count() or 1
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None, env={"NUMBA_NUM_THREADS": "1"}) as cluster, \
                Client(cluster) as client:
            client.register_plugin(_plugin())
            yield client
        return
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except OSError as err:
        raise OSError(f"cannot reach the dask scheduler at {address}: {err}") from err
    with client:
        client.register_plugin(_plugin())
        yield client


def run_chunks(client, compute_chunk, job, chunks):
    """Submit every chunk to the cluster; yield each chunk's ``{index: scene}`` as it finishes.

    On an error (or when the caller stops early) the chunks still queued are cancelled; the error of a task
    is raised again here as it was raised on the worker.
    """
    from distributed import as_completed

    if not chunks:
        return
    job_future = client.scatter(job, broadcast=True)
    futures = [client.submit(compute_chunk, job_future, chunk, threads=1, pure=False) for chunk in chunks]
    try:
        for _, result in as_completed(futures, with_results=True, loop=client.loop):
            yield result
    finally:
        client.cancel(futures)
