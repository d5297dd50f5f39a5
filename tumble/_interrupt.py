"""Ctrl-C while the ``tumble`` command starts: one line and exit status 130, no traceback (issue 17, cause 12).

Importing tumble (numpy, numba, xarray, matplotlib) takes a second or more, and ``tumble.cli.main`` can catch
nothing before it is called. When the process is the ``tumble`` command (the console script or ``python -m
tumble``), :func:`install` — run when this module is imported, first thing in ``tumble/__init__.py``; it imports
nothing heavy — replaces
Python's SIGINT handler until :func:`release` (called by ``main`` once it can report an interrupt itself) puts
the default back. A library import of tumble changes nothing.
"""

import os
import signal
import sys
import threading

#: Exit status after Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = 130

_MESSAGE = b"tumble: interrupted while starting; nothing was run or written\n"


def launched_as_command():
    """Whether this process is the ``tumble`` command: the console script, or ``python -m tumble``."""
    name = os.path.basename(sys.argv[0]) if sys.argv else ""
    if name.removesuffix(".exe").removesuffix("-script.py") == "tumble":
        return True
    argv = list(getattr(sys, "orig_argv", ()))
    return any(arg == "-m" and argv[i + 1:i + 2] == ["tumble"] or arg == "-mtumble" for i, arg in enumerate(argv))


def _startup_handler(signum, frame):
    os.write(2, _MESSAGE)  # a raw write: safe whatever the interpreter was doing when the signal came
    os._exit(EXIT_INTERRUPTED)  # nothing was written yet: no cleanup to run


def install():
    """Replace Python's SIGINT handler with :func:`_startup_handler` when this process is the command."""
    if (threading.current_thread() is threading.main_thread() and launched_as_command()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
        signal.signal(signal.SIGINT, _startup_handler)


def release():
    """Put Python's default SIGINT handler (KeyboardInterrupt) back if :func:`install` replaced it."""
    if (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is _startup_handler):
        signal.signal(signal.SIGINT, signal.default_int_handler)


install()
