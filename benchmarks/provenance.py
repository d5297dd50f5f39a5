"""What the benchmarks record about the code they measured."""

import hashlib
import subprocess
import sys
from pathlib import Path

import tumble

PACKAGE = Path(tumble.__file__).parent


def source_digest():
    """sha256 of the sources of the tumble modules this run imported, to tie the figures to that code."""
    h = hashlib.sha256()
    files = {Path(m.__file__) for name, m in list(sys.modules.items())
             if (name == "tumble" or name.startswith("tumble.")) and getattr(m, "__file__", None)}
    for path in sorted(files):
        h.update(str(path.relative_to(PACKAGE)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def commit():
    """The checkout's short commit hash ("unknown" outside a git checkout)."""
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parent, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
