"""The one place where numba options are chosen.

Every kernel in :mod:`tumble.kernels` is compiled through :func:`jit` so that caching, fast-math and the
error model are decided here and nowhere else.

* A disk cache: compiled machine code is kept on disk (numba's ``__pycache__`` beside the sources, else its
  user-wide folder, or ``NUMBA_CACHE_DIR``) so only the first run pays. It is numba's cache with two changes
  (:class:`CheckedCache`), because the cache is an optimisation and must never stop a run: every file carries the
  SHA-256 of its bytes and is checked before use, so a damaged file (cut short, zeroed, one bit flipped: numba
  itself would raise ``UnpicklingError``, an LLVM bitcode error, or run the damaged machine code and die of
  SIGILL) is removed and its kernel compiled again, with one :class:`CacheWarning` naming the folder; and a cache
  that cannot be written (a full disk, a folder made read-only) warns once and the run goes on. Where no folder
  can hold a cache at all (a read-only install and a read-only home), kernels run uncached, with one warning.
  The files are ``*.tbi`` / ``*.tbc`` (numba's own are ``*.nbi`` / ``*.nbc``).
* ``fastmath``: only ``contract`` (fused multiply-add), ``arcp`` (multiply by a reciprocal) and ``nsz``
  (ignore the sign of zero). ``nnan``/``ninf`` are deliberately left out: they let LLVM delete
  ``x != x`` and ``isfinite`` tests, and blow-up detection must keep working (numba issues #9383, #6217).
  ``reassoc`` is left out too: it would let the compiler reorder the compensated and cancellation-free
  formulas the exact solution relies on.
* ``error_model="numpy"``: a division by zero gives inf/NaN (and is caught by the status checks) instead of
  raising, which also lets loops vectorise.

The device kernels (:mod:`tumble.kernels.cuda.rigid_body`) are compiled through :func:`cuda_jit`. The ``@jit`` functions they
call are compiled for the device by numba-cuda with the options above (it copies a CPU function's options).
"""

import hashlib
import io
import os
import pickle
import re
import types
import warnings

import numba
import numba.extending
from numba.core import caching

from .. import _disk

FASTMATH = frozenset({"contract", "arcp", "nsz"})

_NUMBA_IR_INLINE = True

# No ``cache=True``: :func:`jit` gives every kernel a :class:`CheckedCache` itself.
_OPTIONS = dict(fastmath=set(FASTMATH), error_model="numpy", nogil=True)


class CacheWarning(UserWarning):
    """numba's disk cache of compiled kernels is damaged, full or unwritable; the run goes on (see :class:`CheckedCache`)."""


class _Damaged(Exception):
    """A cache file whose checksum does not match its bytes."""


_DIGEST_SIZE = hashlib.sha256().digest_size


class _CheckedCacheFile(caching.IndexDataCacheFile):
    """numba's index and data files of one function, each written as the SHA-256 of its bytes followed by the
    bytes, and checked when read (:class:`_Damaged`)."""

    def __init__(self, cache_path, filename_base, source_stamp):
        super().__init__(cache_path, filename_base, source_stamp)
        self._index_name = f"{filename_base}.tbi"
        self._index_path = os.path.join(cache_path, self._index_name)
        self._data_name_pattern = f"{filename_base}.{{number:d}}.tbc"

    def _read(self, path):
        with open(path, "rb") as f:
            raw = f.read()
        payload = raw[_DIGEST_SIZE:]
        if len(raw) < _DIGEST_SIZE or hashlib.sha256(payload).digest() != raw[:_DIGEST_SIZE]:
            raise _Damaged(f"{path}: its checksum does not match its bytes")
        return payload

    def _write(self, path, payload):
        with self._open_for_write(path) as f:
            f.write(hashlib.sha256(payload).digest())
            f.write(payload)

    def _load_index(self):
        try:
            stream = io.BytesIO(self._read(self._index_path))
        except FileNotFoundError:
            return {}
        if pickle.load(stream) != self._version:  # another numba: its entries are not ours to read
            return {}
        stamp, overloads = pickle.loads(stream.read())
        return overloads if stamp == self._source_stamp else {}

    def _save_index(self, overloads):
        version = pickle.dumps(self._version, protocol=-1)
        self._write(self._index_path, version + self._dump((self._source_stamp, overloads)))

    def _load_data(self, name):
        return pickle.loads(self._read(self._data_path(name)))

    def _save_data(self, name, data):
        self._write(self._data_path(name), self._dump(data))

    def discard(self):
        """Remove this function's index and data files (the kernel is then compiled and saved afresh)."""
        prefix = self._index_name[: -len(".tbi")] + "."
        with os.scandir(self._cache_path) as entries:
            for entry in entries:
                if entry.name.startswith(prefix) and entry.name.endswith((".tbi", ".tbc")):
                    try:
                        os.unlink(entry.path)
                    except FileNotFoundError:
                        pass


#: Cache folders already reported (one warning per folder and kind of trouble, not one per kernel).
_REPORTED = set()


def _warn_once(kind, folder, message):
    if (kind, folder) not in _REPORTED:
        _REPORTED.add((kind, folder))
        warnings.warn(message, CacheWarning, stacklevel=4)


_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # tumble/

# ``from .x import a, b`` / ``from ..registry import (a,\n b)``: the relative imports of a module's text.
_RELATIVE_IMPORT = re.compile(r"^\s*from\s+(\.+)([\w.]*)\s+import\s+(\([^)]*\)|[^\n]+)", re.MULTILINE)


def _imported_files(path):
    """The files of tumble that the module at ``path`` imports (relative imports, at the top or in a function): a
    module, a package's ``__init__.py``, and each name that is a submodule (``from . import fused``)."""
    with open(path, encoding="utf-8") as f:
        text = re.sub(r"#[^\n]*", "", f.read())  # comments out: a ")" in one would end a parenthesised import early
    found = []
    for dots, module, names in _RELATIVE_IMPORT.findall(text):
        base = os.path.dirname(path)
        for _ in range(len(dots) - 1):
            base = os.path.dirname(base)
        target = os.path.join(base, *module.split(".")) if module else base
        # ``from .. import _disk`` imports a module, not its package's code
        candidates = [target + ".py", os.path.join(target, "__init__.py")] if module else []
        for name in re.findall(r"\w+", names):
            candidates.append(os.path.join(target, name + ".py"))
        found += [c for c in candidates if os.path.isfile(c) and c.startswith(_PACKAGE)]
    return found


def _source_stamp(path):
    """The modification times and sizes of the module at ``path`` and of every module of tumble it imports,
    directly or not: part of the cache stamp of each kernel defined there. numba stamps an entry with its own
    function's file only, but a driver's machine code holds the functions it calls inlined (a system's rate in
    :mod:`tumble.kernels.systems`, the generated steps) and the registry's constants: an edit there would otherwise
    leave a stale driver in the cache, running the old equations. Only what a kernel's module imports counts, so an
    edit to one kernel recompiles the kernels that depend on it, not all of them. Read once per module and process
    (a regular expression over a few files' text and their ``stat``)."""
    path = os.path.abspath(path)
    if path not in _STAMPS:
        seen, todo = set(), [path]
        while todo:
            current = todo.pop()
            if current not in seen:
                seen.add(current)
                todo += _imported_files(current)
        found = []
        for name in sorted(seen):
            info = os.stat(name)
            found.append((os.path.relpath(name, _PACKAGE), info.st_mtime_ns, info.st_size))
        _STAMPS[path] = hashlib.sha256(repr(found).encode()).hexdigest()
    return _STAMPS[path]


_STAMPS = {}


class CheckedCache(caching.FunctionCache):
    """numba's cache of one function, made safe to lose.

    * Loading: a file whose checksum does not match, or that numba cannot read (``UnpicklingError``, an LLVM
      bitcode error, any other error), is removed and the kernel compiled again; one :class:`CacheWarning` per
      folder names it.
    * Saving: a folder that cannot be written (full disk, read-only) is reported once per folder, with its disk's
      free space; the compiled kernel is used all the same.
    """

    def __init__(self, py_func):
        super().__init__(py_func)
        self._cache_file = _CheckedCacheFile(self._cache_path, self._impl.filename_base,
                                             (self._impl.locator.get_source_stamp(),
                                              _source_stamp(py_func.__code__.co_filename)))

    def load_overload(self, sig, target_context):
        try:
            return super().load_overload(sig, target_context)
        except Exception as err:  # noqa: BLE001 - a cache entry that cannot be loaded is recompiled, never trusted
            try:
                self._cache_file.discard()
            except OSError:
                pass
            reason = str(err) if isinstance(err, _Damaged) else f"{type(err).__name__}: {err}"
            _warn_once("damaged", self._cache_path,
                       f"numba's cache of compiled kernels in {self._cache_path} held a damaged file ({reason}); "
                       f"removed it, compiling that kernel again")
            return None

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except OSError as err:
            what = _disk.disk_problem(err, self._cache_path) or err.strerror or str(err)
            _warn_once("unwritable", self._cache_path,
                       f"cannot save compiled kernels in numba's cache {self._cache_path}: {what}; this run goes on, "
                       f"the next one compiles them again")


def _enable_cache(dispatcher):
    """Give ``dispatcher`` a :class:`CheckedCache` (what ``numba.njit(cache=True)`` does with numba's own), or run it
    uncached, with one warning, where numba finds no folder it can write a cache in."""
    try:
        dispatcher._cache = CheckedCache(dispatcher.py_func)  # noqa: SLF001 - numba's enable_caching sets the same
    except RuntimeError as err:  # "cannot cache function ...: no locator available for file ..."
        if "no locator available" not in str(err):
            raise
        folder = os.path.join(os.path.dirname(os.path.abspath(dispatcher.py_func.__code__.co_filename)), "__pycache__")
        _warn_once("nowhere", "", f"no folder can hold numba's cache of compiled kernels ({folder} and numba's "
                                  f"user-wide cache folder are read-only): running without a cache, every run compiles "
                                  f"its kernels again; set NUMBA_CACHE_DIR to a writable folder to keep them")
    return dispatcher


def jit(fn=None, *, inline=False, contract=True, cache=True, boundscheck=False, refcounts=True):
    """Compile ``fn`` with tumble's numba options.

    Parameters
    ----------
    inline : bool
        Inline at the numba IR level (for tiny helpers called in inner loops).
    contract : bool
        Allow fused multiply-adds. ``False`` for kernels whose bits must not depend on how the compiler
        happened to fuse (numba optimised its ``parallel=True`` kernels differently when it compiled them than
        when it loaded them from the cache, numba issue #10617, and with contraction allowed the two fused
        different products; tumble's parallelism is now :mod:`tumble.kernels.threads`, and these kernels keep
        their bits).
    cache : bool
        Keep the compiled code in the disk cache (:class:`CheckedCache`). ``False`` for a user's function and
        the closures over it (:mod:`tumble.kernels.loops.sample_loop`): numba's cache cannot key a closure over another
        function (issue #6264: a new entry every process, never a hit) nor a function typed in a notebook.
    boundscheck : bool
        Raise ``IndexError`` on an index out of bounds (slow: only for a first call that checks a user's function).
    refcounts : bool
        ``False`` for a loop that allocates nothing and hands its arrays to helpers many times (numba's runtime off,
        ``_nrt=False``): numba counts references to every array a function is handed, two atomic operations each, and
        in the error-controlled block loop, whose helpers take twenty arrays for each sample started, that was 40% of
        the run (measured by ``perf``). Such a function cannot make an array; its callers do.
    """
    options = dict(_OPTIONS)
    if not refcounts:
        options["_nrt"] = False
    if not contract:
        options["fastmath"] = set(FASTMATH - {"contract"})
    if inline and _NUMBA_IR_INLINE:
        options["inline"] = "always"
    if boundscheck:
        options["boundscheck"] = True

    def wrap(f):
        dispatcher = numba.njit(**options)(f)
        return _enable_cache(dispatcher) if cache else dispatcher

    return wrap if fn is None else wrap(fn)


def subroutine(fn):
    """Compile ``fn`` only where a kernel calls it, for that kernel (an overload: numba's ``register_jitable``), with
    tumble's options: no Python entry point and no cache entry of its own, which a :func:`jit` function that only
    kernels call would have built, optimised and saved besides the copy linked into each caller (the block loop's
    parts as subroutines: integrate rk4's first call 4.69 -> 4.15 s, 2 cores). A subroutine called both from a
    subroutine and from a kernel compiles twice (numba keys an overload by its caller's options). From Python it is
    the plain function."""
    # tumble's options, all of them: numba keys an overload's compiled code by its caller's options too
    return numba.extending.register_jitable(**_OPTIONS)(fn)


def rebound(names, namespace, key=None, **replaced):
    """Copies of the functions ``names`` of ``namespace`` (a module's globals: :func:`jit` functions written over
    module-level names, callees before their callers) that read ``replaced`` in place of those names: a loop written
    once over the functions it calls (a rate, a surface), compiled for others without a closure. Each copy is compiled
    with ``contract=False`` (the bits must not depend on the compile; numba issue #10617).

    A closure over a function, or a function handed in as an argument, is never a hit of numba's disk cache (its key
    pickles the closure's cells; an argument is a "dynamic global"). A copy reads ``replaced`` as globals instead, so
    with ``key`` (a string that names what ``replaced`` compute, the same in every process) the copies are cached,
    under their names with ``key`` appended: numba names a function's cache files by its qualified name and does not
    key them by its globals. Without ``key`` they are not cached. Returns the copies' namespace (``namespace`` with
    ``replaced`` and the copies)."""
    scope = dict(namespace, **replaced)
    for name in names:
        options = namespace[name].targetoptions
        scope[name] = jit(keyed_copy(namespace[name].py_func, scope, key), cache=key is not None, contract=False,
                          inline=options.get("inline") == "always", refcounts=options.get("_nrt", True))
    return scope


def keyed_copy(fn, scope, key=None):
    """A copy of the Python function ``fn`` that reads ``scope`` as its globals, named ``<qualname>_<key>`` where a
    ``key`` is given: numba names a function's cache files by its qualified name and does not key them by the globals
    it reads, so copies with different keys keep apart in the cache (:func:`rebound`, a user's compiled function)."""
    copy = types.FunctionType(fn.__code__, scope, fn.__name__, fn.__defaults__, fn.__closure__)
    if key is not None:
        copy.__qualname__ = f"{fn.__qualname__}_{key}"
    return copy


# CUDA kernels: fastmath off, which on the device means IEEE division and square root and no flush of subnormals to
# zero (numba-cuda's fastmath=True turns on all three, and approximate division breaks the 1e-10 agreement with the
# CPU); NVVM fuses multiply-adds by default, as the CPU's ``contract``. No disk cache: a device kernel is a closure
# over the method's step (a dispatcher), and numba's cache key pickles the closure's cells, which for a dispatcher
# differs from one process to the next (measured on the CPU: a new cache entry every run, never a hit), so a cache
# would only fill __pycache__. The simulator ignores the option anyway.
_CUDA_OPTIONS = dict(cache=False, fastmath=False)


def cuda_jit(fn):
    """Compile ``fn`` as a CUDA kernel with tumble's options. Imports ``numba.cuda``: only the device path calls
    this (importing tumble does not import numba.cuda)."""
    from numba import cuda

    return cuda.jit(**_CUDA_OPTIONS)(fn)
