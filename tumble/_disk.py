"""What a failed write says about the disk: a full disk named as one, with the folder and its free space.

Libraries report a full disk in their own words: netCDF4 as "Permission denied" when it creates a file and as
``RuntimeError: NetCDF: HDF error`` while it writes one, Python as ``OSError: [Errno 28]`` without a path. Imports
nothing of tumble (like :mod:`tumble._version`), so that every layer may use it.
"""

import errno
import os
import shutil

__all__ = ["disk_problem", "free_space"]

#: A write that fails with less than this much room left (beyond what it was writing) failed for want of room.
MARGIN = 1 << 20

def _existing(folder):
    """``folder``, or its nearest existing ancestor."""
    folder = os.path.abspath(folder)
    while not os.path.exists(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    return folder


def free_space(folder):
    """``"<N> MB free of <M> MB"`` on the file system holding ``folder``, or ``"free space unknown"``."""
    try:
        usage = shutil.disk_usage(_existing(folder))
    except OSError:
        return "free space unknown"
    return f"{usage.free / 1e6:.1f} MB free of {usage.total / 1e6:.1f} MB"


def disk_problem(err, folder, needed=0):
    """``"the disk holding <folder> is full (<free space>)"`` when ``err`` (an exception raised while writing in
    ``folder``) came from a full disk, else None.

    A full disk is one the error says is full (``ENOSPC``; ``EDQUOT``, a used-up quota, is named as such), or, for a library that words it otherwise,
    one with less than ``needed`` bytes (what was being written) plus :data:`MARGIN` free for this user when the
    error happened: call this before the half-written file is removed.
    """
    if getattr(err, "errno", None) == errno.EDQUOT:
        return f"the disk quota for {folder} is used up ({free_space(folder)} on its disk)"
    full = getattr(err, "errno", None) == errno.ENOSPC
    if not full:
        try:
            stats = os.statvfs(_existing(folder))
            full = stats.f_bavail * stats.f_frsize < needed + MARGIN
        except OSError:
            return None
    return f"the disk holding {folder} is full ({free_space(folder)})" if full else None
