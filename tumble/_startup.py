"""How the command line's own processes import what they need: with Python's cyclic garbage collector paused.

Importing numba, or matplotlib and xarray, makes hundreds of thousands of long-lived objects and next to no garbage,
yet the collector walks them all each time its generations fill: measured in ``tumble run stability_map`` (2 cores),
0.03 s of the command's imports and 0.1 s of the figure process's went to collections that freed nothing.
:func:`collector_paused` turns automatic collection off for the imports, then moves everything they made into the
permanent generation (:func:`gc.freeze`), which later collections skip, and turns it back on: the run's own garbage
is collected as before. Only ``tumble run``, ``tumble check`` and the figure process use it; a Python caller's process
is left as it is.
"""

import contextlib
import gc

__all__ = ["collector_paused"]


@contextlib.contextmanager
def collector_paused():
    """Automatic garbage collection off for the ``with`` block, its survivors frozen after it, then back on (as it
    was: left off where the caller had turned it off)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if enabled:
            gc.enable()
