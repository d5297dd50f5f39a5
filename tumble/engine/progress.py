"""Progress bars of long runs: tqdm's notebook widget under Jupyter, its text bar on a terminal.

``tqdm.auto`` makes that choice and mixes in tqdm's asyncio support, which imports :mod:`asyncio` (13-18 ms of
every ``tumble run``, measured on 2 cores); tumble never iterates asynchronously. ``tqdm.autonotebook`` makes the
same choice without it, and says so with a warning that ``tqdm.auto`` silences the same way.
"""

import warnings

from tqdm.std import TqdmExperimentalWarning

with warnings.catch_warnings():
    warnings.simplefilter("ignore", TqdmExperimentalWarning)
    from tqdm.autonotebook import tqdm

__all__ = ["tqdm"]
