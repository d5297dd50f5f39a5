"""A study's figures drawn by a process of their own, started before the scenes run (``tumble run``).

From the shell, a small study's figures cost more than its scenes: importing matplotlib takes 0.3 s and drawing
a figure at 200 dpi 0.15-0.3 s, on one core, after the scenes. :class:`FigureProcess` starts
``python -m tumble.pipeline.figure_process`` as soon as the study is planned: it imports matplotlib and xarray on
the second core while this process imports numba and runs the scenes, then draws the figures
(:func:`tumble.output.figures.save_figures`, the same call on the same stored dataset, pickled to it) while this
process writes the netCDF file. The files are those the in-process call writes.

The process is a helper, never a second place where things can go wrong silently:

- it ignores Ctrl-C (the terminal sends SIGINT to both; this process reports it) and ends when its input closes,
  which happens when this process ends, however it ends;
- an error while drawing (an unwritable folder, a full disk) comes back as the exception it was and is raised here;
- if the process cannot start or dies, :meth:`FigureProcess.result` returns None and the caller draws the
  figures itself: slower, never different;
- :meth:`FigureProcess.close` ends it before the caller removes a staging folder it may still be writing into.

Only the command line uses it: a Python caller's process is its own, and tumble does not start processes in it.
"""

import contextlib
import os
import pickle
import signal
import subprocess
import sys
from pathlib import Path

__all__ = ["FigureProcess", "MAX_BYTES"]

#: A stored dataset larger than this is drawn by the command itself: sending it would pickle it through a pipe, the
#: process holding a second copy, for figures that read a small part of it (a scan's per-sample arrays).
MAX_BYTES = 100e6


class FigureProcess:
    """A process that imports matplotlib now and draws one set of figures later (:meth:`submit`, :meth:`result`)."""

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
        if self._process is None:
            return
        if ds.nbytes > MAX_BYTES:
            self.close()
            return
        try:
            pickle.dump((ds, list(names), str(directory), stem, tuple(formats)), self._process.stdin,
                        protocol=pickle.HIGHEST_PROTOCOL)
            self._process.stdin.close()
            self._submitted = True
        except (OSError, ValueError):  # the process is gone (BrokenPipeError) or its pipe closed
            self.close()

    def result(self):
        """The paths written, once the process is done; None if it could not draw them (the caller draws them).

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


def _serve():
    """The process's side: import what drawing needs, wait for one request, draw, answer."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to report
    from ..output import figures, io

    io.assume_no_dask_arrays()
    try:
        ds, names, directory, stem, formats = pickle.load(sys.stdin.buffer)
    except EOFError:  # the parent ended (or needs no figures) before sending any
        return
    try:
        reply = (True, [str(path) for path in figures.save_figures(ds, names, directory, stem, formats=formats)])
    except Exception as err:  # noqa: BLE001 - every failure goes back to the parent, which reports it
        reply = (False, err)
    try:
        data = pickle.dumps(reply)
    except Exception:  # noqa: BLE001 - an exception that does not pickle goes back as its text
        data = pickle.dumps((False, RuntimeError(f"{type(reply[1]).__name__}: {reply[1]}")))
    sys.stdout.buffer.write(data)
    sys.stdout.buffer.flush()


if __name__ == "__main__":
    _serve()
    sys.stdout.flush()
    os._exit(0)  # the parent waits for the exit: skip the interpreter's teardown (0.3 s of freeing matplotlib)
