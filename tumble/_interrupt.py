"""Ctrl-C or SIGTERM while the ``tumble`` command starts: one line and exit status 130 or 143, no traceback (issue 17,
cause 12; issue 33, cause 5); SIGTERM once it runs: :class:`Terminated`, unwound as Ctrl-C is.

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
#: Exit status after SIGTERM (``kill``, a batch system's time limit, a container stop): 128 + SIGTERM.
EXIT_TERMINATED = 143

_MESSAGE = b"tumble: interrupted while starting; nothing was run or written\n"
_TERMINATED_MESSAGE = b"tumble: terminated (SIGTERM) while starting; nothing was run or written\n"


class Terminated(KeyboardInterrupt):
    """SIGTERM reached the ``tumble`` command once it runs: raised where Python handles the signal, and unwound as
    Ctrl-C is (finished chunks are kept, no partial file is left), then reported with exit status 143."""

    def __init__(self):
        super().__init__("terminated (SIGTERM)")


def launched_as_command():
    """Whether this process is the ``tumble`` command: the console script, or ``python -m tumble``."""
    name = os.path.basename(sys.argv[0]) if sys.argv else ""
    if name.removesuffix(".exe").removesuffix("-script.py") == "tumble":
        return True
    argv = list(getattr(sys, "orig_argv", ()))
    return any(arg == "-m" and argv[i + 1:i + 2] == ["tumble"] or arg == "-mtumble" for i, arg in enumerate(argv))


def started_for_the_command():
    """Whether this process is one the ``tumble`` command started through :mod:`multiprocessing`'s spawn (the worker
    processes of ``--scheduler local``): such a child gets the command's ``sys.argv``, and imports tumble while it
    prepares, as the command's ``__main__``."""
    if "--multiprocessing-fork" not in getattr(sys, "orig_argv", ()) or not sys.argv:
        return False
    first = sys.argv[0]
    own_main = os.path.join(os.path.dirname(os.path.abspath(__file__)), "__main__.py")
    return (os.path.basename(first).removesuffix(".exe").removesuffix("-script.py") == "tumble"
            or os.path.abspath(first) == own_main)


def _startup_handler(signum, frame):
    terminated = signum == signal.SIGTERM
    os.write(2, _TERMINATED_MESSAGE if terminated else _MESSAGE)  # a raw write: safe whatever the interpreter did
    os._exit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED)  # nothing was written yet: no cleanup to run


#: The functions through which LLVM calls back into Python while numba compiles a kernel (llvmlite's object cache): an
#: exception raised in one is printed by ctypes ("Exception ignored on calling ctypes callback function", with a
#: traceback) and dropped.
_LLVM_CALLBACKS = frozenset({"_raw_object_cache_notify", "_raw_object_cache_getbuffer"})

#: Seconds after which a signal that arrived inside such a callback is sent again.
_RESEND_AFTER = 0.05


def _in_an_llvm_callback(frame):
    while frame is not None:
        if frame.f_code.co_name in _LLVM_CALLBACKS and "llvmlite" in frame.f_code.co_filename:
            return True
        frame = frame.f_back
    return False


def _interrupt(signum, frame):
    """Once the command runs: SIGINT raises ``KeyboardInterrupt``, SIGTERM :class:`Terminated` — except inside a
    callback from LLVM (numba compiling a kernel, tens of seconds cold, during which those callbacks are nearly the
    only Python that runs), where the exception was dropped with a traceback and the command went on: a SIGTERM from
    ``timeout 20 tumble run`` left it running for ten minutes. There the same signal is sent again a moment later,
    when the callback has returned."""
    if _in_an_llvm_callback(frame):
        threading.Timer(_RESEND_AFTER, os.kill, (os.getpid(), signum)).start()
        return
    raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt


def install():
    """Replace Python's SIGINT handler, and SIGTERM's default (die without a word), with :func:`_startup_handler`
    when this process is the command. A process the command started (:func:`started_for_the_command`) is not the
    command, though it has its ``sys.argv``: it ignores SIGINT (Ctrl-C reaches every process of the terminal's
    foreground group; the command alone reports it, once, and stops its cluster) and keeps SIGTERM's default (its
    nanny stops it so); each worker printed the command's line (issue 44). The command's LocalCluster also starts
    them with SIGINT blocked (:func:`tumble.pipeline.distributed.connect`), which covers their start-up too."""
    if threading.current_thread() is not threading.main_thread():
        return
    if started_for_the_command():
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        return
    if not launched_as_command():
        return
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _startup_handler)
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _startup_handler)


def release():
    """Once the command can report an interrupt itself: SIGINT raising ``KeyboardInterrupt`` and SIGTERM raising
    :class:`Terminated` (:func:`_interrupt`), where :func:`install` replaced their handlers."""
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is _startup_handler:
        signal.signal(signal.SIGINT, _interrupt)
    if signal.getsignal(signal.SIGTERM) is _startup_handler:
        signal.signal(signal.SIGTERM, _interrupt)


install()
