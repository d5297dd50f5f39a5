"""What the benchmarks record about the code they measured."""

import hashlib
import os
import platform
import subprocess
import sys
from datetime import datetime, timezone
from pathlib import Path

import tumble

PACKAGE = Path(tumble.__file__).parent


def source_digest(files=None):
    """sha256 of the sources of the tumble modules this run imported (or of ``files``, paths), to tie the figures to
    that code. A run that checks its code did not change compares the digest of the same files, ``source_files()``
    taken at its start: a module imported later would change the digest of everything imported."""
    h = hashlib.sha256()
    for path in sorted(source_files() if files is None else files):
        h.update(str(path.relative_to(PACKAGE)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def source_files():
    """The source files of the tumble modules imported so far."""
    return {Path(m.__file__) for name, m in list(sys.modules.items())
            if (name == "tumble" or name.startswith("tumble.")) and getattr(m, "__file__", None)}


def commit():
    """The checkout's short commit hash ("unknown" outside a git checkout)."""
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parent, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _cpu_flags():
    """The CPU's feature flags: /proc/cpuinfo's ``flags`` line, else LLVM's view of the host (what numba compiles
    for)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    try:
        import llvmlite.binding as llvm

        return {name for name, on in llvm.get_host_cpu_features().items() if on}
    except Exception:  # noqa: BLE001 - no flags to be had: the width is unknown
        return set()


def vector_width():
    """``"AVX-512"`` (8 doubles a register), ``"AVX2"`` (4) or ``"unknown"``: the widest x86 SIMD the CPU offers."""
    flags = _cpu_flags()
    return "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "unknown"


def machine():
    """``"<processor>, <cores> cores, <vector width>, numba <version>"``: the processor's model name where
    /proc/cpuinfo gives it."""
    import numba

    try:
        model = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                      if line.startswith("model name")), "")
    except OSError:
        model = ""
    return (f"{model or platform.processor() or platform.machine()}, {os.cpu_count()} cores, {vector_width()}, "
            f"numba {numba.__version__}")


def _edited():
    """Whether the checkout's tracked files under tumble/ differ from its commit."""
    try:
        return bool(subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", str(PACKAGE)],
                                   cwd=Path(__file__).parent, capture_output=True, text=True,
                                   check=True).stdout.strip())
    except (OSError, subprocess.CalledProcessError):
        return False


def stamp():
    """What every results file of the benchmarks holds about its run: ``{"machine", "vector_width", "date",
    "commit"}`` (date in UTC, ``YYYY-MM-DD``; the commit marked when tumble/ had uncommitted edits).
    ``benchmarks/tables.py`` states them under every table it renders from the file."""
    measured = commit()
    return {"machine": machine(), "vector_width": vector_width(),
            "date": datetime.now(timezone.utc).date().isoformat(),
            "commit": measured + (" (tumble/ edited, uncommitted)" if measured != "unknown" and _edited() else "")}
