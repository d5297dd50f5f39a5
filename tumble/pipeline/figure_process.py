"""A study's result written and its figures drawn by a process of their own, started before the scenes run
(``tumble run``).

From the shell, a small study's figures and result file cost more than its scenes: importing matplotlib takes
0.3 s, xarray with pandas 0.3 s, and drawing a figure at 200 dpi 0.15-0.3 s, on one core, after the scenes.
:class:`FigureProcess` starts ``python -m tumble.pipeline.figure_process`` before the study is planned: it imports
matplotlib, xarray and netCDF4 on the second core while this process imports numba and runs the scenes. Then,
for most studies, it takes the scenes' records (plain NumPy arrays, pickled to it), builds the result dataset
(:func:`tumble.pipeline.results.result_dataset`, the call :func:`tumble.run_study` makes), writes the netCDF file
and draws the figures (:func:`~tumble.pipeline.results.stage_result`) and sends back the summary: the command's
process never imports xarray (:meth:`FigureProcess.submit_result`). A study whose figures need a trace besides
the scenes' (attitude, invariant drift, flat spin, work-precision) builds its dataset itself and sends it here
to be drawn while it writes the file (:meth:`FigureProcess.submit`). With two figures or more and two cores the
process forks once it has the dataset, and the two draw the figures at once, each taking the next from a common
queue (a study's two figures: 0.3 s instead of 0.6). The files are those the in-process call writes, byte for
byte.

The process is a helper, never a second place where things can go wrong silently:

- it ignores Ctrl-C (the terminal sends SIGINT to both; this process reports it) and ends when its input closes,
  which happens when this process ends, however it ends;
- an error while writing or drawing (an unwritable folder, a full disk) comes back as the exception it was and is
  raised here;
- if the process cannot start or dies, :meth:`FigureProcess.result` returns None and the caller builds, writes and
  draws itself: slower, never different;
- :meth:`FigureProcess.close` ends it before the caller removes a staging folder it may still be writing into; its
  forked child ends with it (Linux's ``PR_SET_PDEATHSIG``; elsewhere it draws alone, without a child).

Only the command line uses it: a Python caller's process is its own, and tumble does not start processes in it.
"""

import contextlib
import os
import pickle
import select
import signal
import subprocess
import sys
from pathlib import Path

from .. import _startup

__all__ = ["FigureProcess", "MAX_BYTES"]

#: A stored dataset larger than this is drawn by the command itself: sending it would pickle it through a pipe, the
#: process holding a second copy, for figures that read a small part of it (a scan's per-sample arrays).
MAX_BYTES = 100e6


class FigureProcess:
    """A process that imports matplotlib and xarray now, and later writes one result and draws its figures
    (:meth:`submit_result`) or draws one set of figures (:meth:`submit`); :meth:`result` waits for it."""

    def __init__(self):
        package_root = str(Path(__file__).resolve().parents[2])  # the folder holding the tumble package
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (package_root, os.environ.get("PYTHONPATH")))))
        try:
            self._process = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
        except OSError:  # no process can be started (limits): the caller draws the figures itself
            self._process = None
        self._submitted = False

    def submit(self, ds, names, directory, stem, formats):
        """Send the figures to draw: :func:`tumble.output.figures.save_figures`'s arguments (``ds`` is pickled; over
        :data:`MAX_BYTES` nothing is sent, the process ends and :meth:`result` says None)."""
        self._send(("figures", ds, list(names), str(directory), stem, tuple(formats)), ds.nbytes)

    def _send(self, request, nbytes):
        if self._process is None:
            return
        if nbytes > MAX_BYTES:
            self.close()
            return
        try:
            pickle.dump(request, self._process.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self._process.stdin.close()
            self._submitted = True
        except (OSError, ValueError):  # the process is gone (BrokenPipeError) or its pipe closed
            self.close()

    def submit_result(self, records, shape, resolved, directory, stem, action):
        # size: tumble.pipeline.results.result_dataset's and stage_result's arguments
        """Send a study's scene records to build its result from (:func:`tumble.pipeline.results.result_dataset` with
        the keywords ``shape``), write it and its figures into ``directory`` (:func:`~tumble.pipeline.results.
        stage_result`) and summarise it: :meth:`result` then says ``(summary text, figure paths)``. Over
        :data:`MAX_BYTES` of records nothing is sent, as :meth:`submit`."""
        from ..measure.records import stack_records  # NumPy only: this module is imported before numpy is

        if self._process is None:
            return
        stacked = stack_records(records)  # sent in a few large arrays, not thousands of small ones
        nbytes = sum(column.nbytes for _, numeric, _, _ in stacked[1] for column in numeric.values())
        self._send(("result", stacked, shape, resolved, str(directory), stem, action), nbytes)

    def result(self):
        """The paths written, once the process is done (after :meth:`submit_result`: the summary and the paths);
        None if it could not do it (the caller does it itself).

        Raises
        ------
        Exception
            What ``save_figures`` raised in the process (``ValueError``, ``OSError``, ...).
        """
        if self._process is None or not self._submitted:
            return None
        try:
            reply = self._process.stdout.read()
            self._process.wait()
            ok, value = pickle.loads(reply)
        except Exception:  # noqa: BLE001 - a process that died or answered garbage: draw in this process instead
            self.close()
            return None
        if not ok:
            raise value
        if isinstance(value, tuple):  # a result's (summary, paths)
            return value[0], [Path(path) for path in value[1]]
        return [Path(path) for path in value]

    def close(self):
        """End the process (if it still runs) and wait for it."""
        process, self._process = self._process, None
        if process is None:
            return
        with contextlib.suppress(OSError):
            process.kill()
        for stream in (process.stdin, process.stdout):
            with contextlib.suppress(OSError):
                stream.close()
        process.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _reply(call):
    """``(True, call())`` or ``(False, the exception it raised)``, pickled (an exception that does not pickle goes
    as its text)."""
    try:
        reply = (True, call())
    except Exception as err:  # noqa: BLE001 - every failure goes back to the parent, which reports it
        reply = (False, err)
    try:
        return pickle.dumps(reply)
    except Exception:  # noqa: BLE001
        return pickle.dumps((False, RuntimeError(f"{type(reply[1]).__name__}: {reply[1]}")))


def _linux_die_with_parent():
    """A function that makes the calling process end (SIGKILL) when its parent does (Linux ``prctl``), or None."""
    if not sys.platform.startswith("linux") or not hasattr(os, "fork"):
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    pr_set_pdeathsig = 1
    return lambda: prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0) == 0


def _cores():
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _start_drawing(ds, names, directory, stem, formats):
    """Start :func:`tumble.output.figures.save_figures`, shared with a forked child when there are two figures or
    more and two cores; return a function that finishes it and returns the paths in ``save_figures``' order.

    The request is checked first, as ``save_figures`` does, so an unsuitable one writes no file. The child starts
    at once; this process joins it when the returned function is called (after writing the netCDF file, for a
    result): both then take the figures one at a time from a common queue (a pipe holding their indices) until it
    is empty, so a long figure does not hold up the rest. The child ends with this process (Linux's
    ``PR_SET_PDEATHSIG``; :meth:`FigureProcess.close` kills this one); where that cannot be arranged there is no
    child, and a figure the child took but did not draw (it died) is drawn here."""
    from ..output import figures

    names, formats = figures.check_request(ds, names, formats)
    die_with_parent = _linux_die_with_parent() if len(names) > 1 and _cores() > 1 else None
    if die_with_parent is None:
        return lambda: [str(path) for path in figures.save_figures(ds, names, directory, stem, formats=formats)]

    def draw(name):
        return [str(path) for path in figures.save_figures(ds, [name], directory, stem, formats=formats)]

    queue, queue_in = os.pipe()
    os.write(queue_in, bytes(range(len(names))))  # fewer than 256 figures: FIGURES has 16; a pipe holds 4 kB at once
    os.close(queue_in)

    def drain():
        drawn = {}
        while index := os.read(queue, 1):  # one byte: one figure, taken by one process only
            name = names[index[0]]
            drawn[name] = draw(name)
        return drawn

    parent = os.getpid()
    answer, answer_in = os.pipe()
    child = os.fork()
    if child == 0:  # pragma: no cover - the child's side (coverage does not follow a fork)
        try:
            os.close(answer)
            if die_with_parent() and os.getppid() == parent:
                data = _reply(drain)
                with os.fdopen(answer_in, "wb") as pipe:
                    pipe.write(data)
        finally:
            os._exit(0)
    os.close(answer_in)

    def finish():
        try:
            paths = drain()
        finally:
            with os.fdopen(answer, "rb") as pipe:
                data = pipe.read()
            os.waitpid(child, 0)
            os.close(queue)
        try:
            ok, value = pickle.loads(data)
        except Exception:  # noqa: BLE001 - the child died: what it took and did not answer for is drawn below
            ok, value = True, {}
        if not ok:
            raise value
        paths.update(value)
        for name in names:
            if name not in paths:
                paths[name] = draw(name)
        return [path for name in names for path in paths[name]]

    return finish


def _figures(ds, names, directory, stem, formats):
    """A ``figures`` request: draw them."""
    return _start_drawing(ds, names, directory, stem, formats)()


def _result(records, shape, resolved, directory, stem, action):
    """A ``result`` request: build the dataset, write it and its figures (drawn by two processes while the file is
    written), return ``(summary text, figure paths)``."""
    from ..measure.records import unstack_records
    from . import results

    ds = results.result_dataset(unstack_records(records), **shape, resolved=resolved)
    stored, figures = results.stage_result(ds, resolved, Path(directory), stem, action=action,
                                           start_drawing=_start_drawing)
    return results.summary_table(stored), [str(path) for path in figures]


def _warm_up():
    """Pay two of the first figure's one-time costs while the scenes run: building mathtext's parser (its grammar)
    and loading the fonts it draws with, 0.05-0.1 s. A child forked later inherits them: each of the two drawing
    processes would pay them again. Measured (medians of paired runs, 2 cores, four sets): stability_map -0.02 to
    -0.10 s, the default study -0.01 to -0.05 s; never slower. Skipped when the request is already there, or
    where there is one core (it would take that core from the scenes)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.mathtext import MathTextParser

    MathTextParser("agg").parse(r"$\mathdefault{10^{-1}}\ \omega_1$", dpi=200, prop=FontProperties(size=8))


def _serve():
    """The process's side: import what drawing needs, wait for one request, draw, answer."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to report
    with _startup.collector_paused():
        from ..output import figures, io  # noqa: F401 - imported while the parent runs the scenes
        from . import results  # noqa: F401 - xarray, netCDF4; no numba

        io.assume_no_dask_arrays()
        if _cores() > 1 and os.name == "posix" and not select.select([sys.stdin], [], [], 0)[0]:
            _warm_up()  # nothing sent yet: the scenes still run
    try:
        kind, *request = pickle.load(sys.stdin.buffer)
    except EOFError:  # the parent ended (or needs no figures) before sending any
        return
    serve = {"figures": _figures, "result": _result}[kind]
    sys.stdout.buffer.write(_reply(lambda: serve(*request)))
    sys.stdout.buffer.flush()


if __name__ == "__main__":
    _serve()
    sys.stdout.flush()
    os._exit(0)  # the parent waits for the exit: skip the interpreter's teardown (0.3 s of freeing matplotlib)
