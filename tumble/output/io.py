"""Result files: provenance attributes, atomic netCDF4 writes, checked reads.

Every dataset tumble writes carries the CF global attributes ``Conventions``, ``title``, ``source``
(``"tumble <version>"``) and ``history``, plus the resolved ``study`` (a JSON string with sorted keys) and
the ``seed_entropy`` (decimal digits), enough to run it again (:func:`provenance`).

:func:`write_dataset` returns the dataset exactly as it is stored, so that
``xarray.testing.assert_identical(read_dataset(path), write_dataset(ds, path))`` holds. To make that true
it normalises what netCDF cannot hold as given (verified with xarray 2026.9, netCDF4 1.7.5, NETCDF4
format); callers need not do anything themselves:

- **Attributes** (global and per variable) go through :func:`netcdf_safe_attrs`: booleans become
  ``numpy.int8`` 0/1 (netCDF has no boolean attribute type); ``None`` is dropped; Python ints become
  ``numpy.int64`` and Python floats ``numpy.float64`` (the types read back); ints beyond int64 become
  decimal strings; sequences of numbers become 1-D arrays, **except that a one-element array becomes a
  numpy scalar**, because netCDF reads a length-1 attribute back as a scalar; mappings, sequences of
  strings and arrays of two or more dimensions become JSON strings (netCDF attributes are 1-D, and a
  list of strings would read back as a bare string if it had one element).
- **String variables** of ``object`` dtype (e.g. ``kind`` built as ``np.array("periodic", dtype=object)``)
  are stored as netCDF variable-length strings and read back as fixed-width unicode (``<U``); they are
  converted to ``<U`` before writing so the returned dataset has the dtypes a reader gets. ``<U``
  variables, 0-d included, round-trip unchanged.
- **Encodings** on the input (e.g. from a dataset that was itself read from a file: stale ``chunksizes``,
  ``source``, ``unlimited_dims``) are dropped; numeric variables with at least one element and at least
  one dimension are written with ``zlib`` + ``shuffle`` (HDF5 cannot chunk, hence compress, a scalar).
  Float data variables get xarray's default ``_FillValue`` of NaN, which reads back as NaN; float
  coordinates get none (CF coordinates have no missing values).

:func:`read_dataset` opens with ``decode_times=False`` and ``decode_timedelta=False``: a ``time``
coordinate in seconds (``units="s"``) stays float64 seconds, never ``timedelta64``.

Safety: only netCDF and JSON are ever read; nothing is unpickled or evaluated.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import json
import numbers
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .. import _disk
from .._version import __version__

__all__ = ["assume_no_dask_arrays", "check_tumble_result", "netcdf_safe_attrs", "provenance", "read_dataset",
           "stored_form", "write_dataset"]

#: Value of the global ``Conventions`` attribute.
CONVENTIONS = "CF-1.10"

#: Title given to a dataset that has none.
DEFAULT_TITLE = "tumble result"

_INT64 = np.iinfo(np.int64)

# File signatures: netCDF classic / 64-bit offset / CDF-5 start with b"CDF"; HDF5 (netCDF-4) has its
# superblock signature at offset 0, 512, 1024, 2048, ... (after an optional user block).
_CDF_MAGIC = b"CDF"
_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"

# The permission bits a plainly created file gets; mkstemp makes its file 0600. Read once, at import,
# because reading the umask means setting it, which is not thread safe.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


# ----------------------------------------------------------------------------------------- attributes


def _json_default(value):
    """JSON form of the numpy and path values that ``json`` does not know."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _to_json(value, key):
    """``value`` as a JSON string with sorted keys, or a TypeError that names the attribute ``key``."""
    try:
        return json.dumps(value, sort_keys=True, default=_json_default)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"attribute {key!r} cannot be stored in a netCDF file: {exc}") from exc


def _safe_array(array, key):
    """A numpy array attribute in the form netCDF reads back."""
    if array.dtype == np.bool_:
        array = array.astype(np.int8)
    if array.dtype.kind not in "iuf":  # strings, objects, complex, datetimes
        return _to_json(array.tolist(), key)
    if array.ndim > 1:
        return _to_json(array.tolist(), key)
    array = array.reshape(-1)
    if array.size == 1:
        return array[0]
    return array.copy()


def _is_number(value):
    """True for Python and numpy bools, integers and reals."""
    if isinstance(value, np.generic):
        return value.dtype.kind in "biuf"
    return isinstance(value, numbers.Real)


def _safe_value(value, key):
    """One attribute value in the form netCDF reads back (``None`` is handled by the caller)."""
    if isinstance(value, str):
        return str(value)  # np.str_ -> str
    if isinstance(value, (bool, np.bool_)):
        return np.int8(bool(value))
    if isinstance(value, np.generic) and value.dtype.kind in "iuf":
        return value
    if isinstance(value, numbers.Integral):
        value = int(value)
        return np.int64(value) if _INT64.min <= value <= _INT64.max else str(value)
    if isinstance(value, numbers.Real):
        return np.float64(value)
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, np.ndarray):
        return _safe_array(value, key)
    if isinstance(value, (list, tuple)):
        if value and all(_is_number(v) for v in value):
            if all(isinstance(v, (bool, np.bool_)) for v in value):
                return _safe_array(np.array(value, dtype=bool), key)
            if all(isinstance(v, (numbers.Integral, np.bool_)) for v in value):
                ints = [int(v) for v in value]
                if all(_INT64.min <= v <= _INT64.max for v in ints):
                    return _safe_array(np.array(ints, dtype=np.int64), key)
                return _to_json(ints, key)
            return _safe_array(np.array([float(v) for v in value], dtype=np.float64), key)
        return _to_json(list(value), key)
    if isinstance(value, (Mapping, set, frozenset)):
        return _to_json(value, key)
    raise TypeError(
        f"attribute {key!r} cannot be stored in a netCDF file: {type(value).__name__} value {value!r}"
    )


def netcdf_safe_attrs(attrs):
    """Attributes in the form a netCDF4 file stores and reads back identically.

    Parameters
    ----------
    attrs : mapping of str to value

    Returns
    -------
    dict
        A new dict (``attrs`` is not modified), with each value converted:

        - ``str`` (and ``numpy.str_``): kept; ``bytes``: decoded as UTF-8; path-like: ``os.fspath``.
        - ``bool`` / ``numpy.bool_``: ``numpy.int8`` 0 or 1 (netCDF has no boolean attribute).
        - ``None``: dropped.
        - numpy integer and float scalars: kept, with their dtype.
        - Python ``int``: ``numpy.int64``, or a decimal ``str`` if it does not fit in int64.
        - Python ``float``: ``numpy.float64``.
        - list / tuple / 1-D array of numbers: a 1-D numpy array (bools -> int8, ints -> int64, else
          float64); a single element becomes a numpy scalar, since netCDF reads length-1 attributes back
          as scalars. Ints beyond int64 make the whole sequence a JSON string.
        - mappings, sets, sequences of anything else and arrays of two or more dimensions: a JSON string
          with sorted keys (numpy values converted with ``.item()`` / ``.tolist()``).

    Raises
    ------
    TypeError
        For a value of any other type (complex, datetime, arbitrary objects), naming the attribute.
    """
    out = {}
    for key, value in attrs.items():
        if value is None:
            continue
        out[str(key)] = _safe_value(value, key)
    return out


# ----------------------------------------------------------------------------------------- provenance


def _entropy_string(seed_entropy):
    """The seed entropy as a string of decimal digits, or a ValueError."""
    if isinstance(seed_entropy, str) and seed_entropy.isdecimal() and seed_entropy.isascii():
        return seed_entropy
    if isinstance(seed_entropy, (numbers.Integral, np.integer)) and not isinstance(
        seed_entropy, (bool, np.bool_)
    ):
        if int(seed_entropy) >= 0:
            return str(int(seed_entropy))
    raise ValueError(
        f"seed_entropy must be a non-negative integer or a string of decimal digits, got {seed_entropy!r}"
    )


def _history_line(action):
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    return f"{stamp} tumble {__version__}: {action or 'created'}"


def provenance(ds, *, title=None, study=None, seed_entropy=None, action=None):
    """A copy of ``ds`` with provenance global attributes and netCDF-safe attributes throughout.

    Parameters
    ----------
    ds : xarray.Dataset
        Not modified; the copy shares its data arrays.
    title : str, optional
        ``title`` attribute; default: the existing one, else ``"tumble result"``.
    study : mapping, optional
        The resolved study; stored as ``study``, a JSON string with sorted keys.
    seed_entropy : int >= 0 or str of decimal digits, optional
        Stored as ``seed_entropy``, a string of decimal digits (it may exceed 64 bits, e.g.
        :func:`tumble.engine.sampling.seed_entropy` of ``None`` is 128-bit; netCDF integers are at most 64-bit).
    action : str, optional
        What produced this version (default ``"created"``), recorded in the history line.

    Returns
    -------
    xarray.Dataset
        With ``Conventions = "CF-1.10"``, ``title``, ``source = "tumble <version>"``, ``history`` with the
        line ``"<UTC time>Z tumble <version>: <action>"`` appended (newline separated) to any existing
        history, and ``study`` / ``seed_entropy`` when given. All global and variable attributes are then
        passed through :func:`netcdf_safe_attrs`.

    Raises
    ------
    TypeError
        If ``ds`` is not a Dataset, ``study`` not a mapping, or an attribute cannot be stored.
    ValueError
        If ``seed_entropy`` is not a non-negative integer.
    """
    import xarray as xr  # here, not at the top: the command's process runs scenes with this module and no xarray

    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"ds must be an xarray.Dataset, got {type(ds).__name__}")
    attrs = dict(ds.attrs)
    attrs["Conventions"] = CONVENTIONS
    if title is not None:
        attrs["title"] = str(title)
    elif not attrs.get("title"):
        attrs["title"] = DEFAULT_TITLE
    attrs["source"] = f"tumble {__version__}"
    history = attrs.get("history")
    line = _history_line(action)
    if isinstance(history, str) and history.strip():
        line = history.rstrip("\n") + "\n" + line
    attrs["history"] = line
    if study is not None:
        if not isinstance(study, Mapping):
            raise TypeError(f"study must be a mapping (the resolved study), got {type(study).__name__}")
        attrs["study"] = _to_json(dict(study), "study")
    if seed_entropy is not None:
        attrs["seed_entropy"] = _entropy_string(seed_entropy)

    out = ds.copy(deep=False)
    for var in out.variables.values():
        var.attrs = netcdf_safe_attrs(var.attrs)
    out.attrs = netcdf_safe_attrs(attrs)
    return out


# ------------------------------------------------------------------------------------------- writing


def _strings_as_unicode(ds):
    """``ds`` with object-dtype variables that hold only strings converted to ``<U`` (what netCDF reads)."""
    replace = {}
    for name, var in ds.variables.items():
        if var.dtype == object:
            values = var.values
            if all(isinstance(v, str) for v in values.flat):
                replace[name] = var.copy(data=values.astype(str))
    return ds.assign(replace) if replace else ds


def _encoding(ds, compression):
    """Per-variable encoding: zlib + shuffle for numeric variables HDF5 can chunk; no ``_FillValue`` on
    float coordinates (CF: coordinates have no missing values; xarray would add NaN)."""
    encoding = {}
    for name, var in ds.variables.items():
        if compression and var.dtype.kind in "biuf" and var.ndim > 0 and var.size > 0:
            encoding[name] = {"zlib": True, "complevel": compression, "shuffle": True}
        if name in ds.coords and var.dtype.kind == "f":
            encoding.setdefault(name, {})["_FillValue"] = None
    return encoding


def _fsync_path(path):
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def stored_form(ds, **provenance_kwargs):
    """``ds`` as :func:`write_dataset` stores it: with its provenance, object-dtype strings as ``<U``, no encodings.

    Parameters
    ----------
    ds : xarray.Dataset
    **provenance_kwargs
        ``title``, ``study``, ``seed_entropy``, ``action``: passed to :func:`provenance`.
    """
    return _strings_as_unicode(provenance(ds, **provenance_kwargs)).drop_encoding()


def write_dataset(ds, path, *, compression=4, stored=False, **provenance_kwargs):
    """Write ``ds`` to a netCDF4 file atomically; return the dataset exactly as stored.

    The file is written to a temporary ``.<name>.*.part`` file in the folder of ``path``, flushed to disk
    and renamed onto ``path`` (``os.replace``), so a reader sees either the old file or the complete new
    one. On any error the temporary file is removed, an existing file at ``path`` is left untouched, and
    the error is raised again.

    Parameters
    ----------
    ds : xarray.Dataset
    path : str or path-like
        Destination; missing parent folders are created.
    compression : int, 0..9
        zlib level for numeric variables (with the shuffle filter); 0 writes uncompressed.
    stored : bool
        ``ds`` is already :func:`stored_form`'s result (``provenance_kwargs`` are then not used).
    **provenance_kwargs
        ``title``, ``study``, ``seed_entropy``, ``action``: passed to :func:`provenance`.

    Returns
    -------
    xarray.Dataset
        :func:`stored_form` of ``ds``; ``read_dataset(path)`` is identical to it.

    Raises
    ------
    ValueError
        If ``compression`` is not an integer from 0 to 9.
    TypeError
        If an attribute cannot be stored (see :func:`netcdf_safe_attrs`).
    OSError
        If the file cannot be written; for a full disk (which netCDF4 reports as "Permission denied" or
        ``RuntimeError: NetCDF: HDF error``) the message says so: ``the disk holding <folder> is full (...)``.

    See Also
    --------
    tumble.io.read_dataset : Reads the file back.
    tumble.run_study : Writes its result with this (``out=``).

    Examples
    --------
    What is returned is what a reader gets back:

    >>> import os, tempfile, tumble
    >>> ds = tumble.measure((1.0, 2.0, 3.0), axis=2, samples=16)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     stored = tumble.io.write_dataset(ds, os.path.join(folder, "scene.nc"), title="one scene")
    ...     back = tumble.io.read_dataset(os.path.join(folder, "scene.nc"), require_tumble=True)
    >>> back.identical(stored), back.attrs["title"], back.attrs["source"].split()[0]
    (True, 'one scene', 'tumble')
    """
    if (
        isinstance(compression, (bool, np.bool_))
        or not isinstance(compression, (numbers.Integral, np.integer))
        or not 0 <= compression <= 9
    ):
        raise ValueError(f"compression must be an integer from 0 to 9, got {compression!r}")
    compression = int(compression)
    if not stored:
        ds = stored_form(ds, **provenance_kwargs)
    encoding = _encoding(ds, compression)

    path = Path(os.fspath(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(path, durable=True) as tmp:
        try:
            with signals_held():  # Ctrl-C inside xarray's locked netCDF calls hung the command (issue 44)
                _to_netcdf4(ds, tmp, encoding)
        except (OSError, RuntimeError) as err:  # netCDF4: a full disk is "Permission denied" or "NetCDF: HDF error"
            # asked while the half-written file still takes its room
            problem = _disk.disk_problem(err, path.parent, needed=ds.nbytes)
            if problem:
                raise OSError(errno.ENOSPC, f"{problem} (writing {path.name})") from err
            if isinstance(err, RuntimeError):  # netCDF4's bare "NetCDF: HDF error" names no file
                raise OSError(errno.EIO, f"{err} (writing {path})") from err
            raise
    return ds


@contextlib.contextmanager
def signals_held():
    """Ctrl-C and SIGTERM held while the block runs, then delivered as they would have been (``KeyboardInterrupt``,
    :class:`tumble._interrupt.Terminated`), after the block or its error.

    For the calls into netCDF4 and HDF5 through xarray's file manager and locks: a ``KeyboardInterrupt`` raised at
    the wrong bytecode inside them (between the two locks of ``NETCDF4_PYTHON_LOCK``, between opening the file and
    registering it) left a lock held, and closing the file then waited for it for ever (Ctrl-C while a study's file
    was written hung ``tumble run``: issue 44), or left a file manager whose collection printed "Exception ignored in:
    CachingFileManager.__del__" and a traceback after the command's own line. A file takes well under a second to
    write or read here; Ctrl-C then acts at its end, and ``replaced_atomically`` removes the half-written file. Only
    in the main thread, and only for Python-level handlers (an ignored signal stays ignored).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held, previous = [], {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(signum)
        if callable(handler):
            previous[signum] = handler
            signal.signal(signum, lambda number, frame: held.append((number, frame)))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if held:
            number, frame = held[0]
            previous[number](number, frame)


def _to_netcdf4(ds, path, encoding):
    """``ds.to_netcdf(path, format="NETCDF4", engine="netcdf4", encoding=encoding)``, without asking dask anything.

    ``to_netcdf`` asks dask which scheduler runs — importing ``dask.distributed``, 0.25 s on 2 cores, in every
    ``tumble run`` where dask is installed — to pick a file lock and whether to close the file after each write:
    choices for dask arrays, which tumble never writes. The same store is opened here with the lock xarray itself
    takes for a netCDF4 file named by a path object (the netCDF-C and HDF5 library lock) and written by xarray's
    :meth:`xarray.Dataset.dump_to_store`, the step ``to_netcdf`` takes (``tests/test_io.py`` reads back what
    ``write_dataset`` returns). Where those names are gone (another xarray), ``to_netcdf`` writes it.
    """
    try:
        from xarray.backends.netCDF4_ import NETCDF4_PYTHON_LOCK, NetCDF4DataStore
    except ImportError:
        ds.to_netcdf(path, mode="w", format="NETCDF4", engine="netcdf4", encoding=encoding)
        return
    store = NetCDF4DataStore.open(path, mode="w", format="NETCDF4", lock=NETCDF4_PYTHON_LOCK)
    try:
        ds.dump_to_store(store, encoding=encoding)
    finally:
        store.close()


def assume_no_dask_arrays():
    """Tell xarray that this process holds no dask array, so that it does not import ``dask.array`` to look for one.

    Where dask is installed (the ``distributed`` extra), xarray imports ``dask.array`` (0.35 s on 2 cores) the
    first time it builds a variable, to recognise dask arrays among its inputs. tumble never makes one (its dask
    use is futures of whole chunks), so the processes that are tumble's own — the command line and its
    :mod:`figure process <tumble.pipeline.figure_process>` — call this first. It fills xarray's cache of array
    modules with what it finds where dask is not installed; were a dask array met after all, xarray would treat
    it as array-like and compute it, which is slower, not different. A library caller's process is never told
    this. It also replaces xarray's ``is_dask_collection``, which imports ``dask.base`` to answer, by one that answers
    the same without the import (:func:`_is_dask_collection`). It uses private names of xarray's: where they are gone,
    nothing is done (and the import is paid).
    """
    try:
        from xarray.namedarray import pycompat, utils
    except ImportError:
        return
    if callable(getattr(utils, "is_dask_collection", None)):
        utils.is_dask_collection = _is_dask_collection
    cache = getattr(pycompat, "_cached_duck_array_modules", None)
    module_class = getattr(pycompat, "DuckArrayModule", None)
    if not isinstance(cache, dict) or module_class is None or "dask" in cache:
        return
    absent = object.__new__(module_class)  # the fields DuckArrayModule.__init__ sets when the import fails
    absent.module, absent.version, absent.type, absent.available = None, pycompat.Version("0.0.0"), (), False
    cache["dask"] = absent


def _is_dask_collection(x):
    """xarray's ``is_dask_collection`` without importing dask: nothing is a dask collection while ``dask.base`` is not
    imported (xarray's own imports it, 0.1-0.15 s, and looks for the package on disk, for every variable it builds)."""
    base = sys.modules.get("dask.base")
    return base is not None and base.is_dask_collection(x)


@contextlib.contextmanager
def replaced_atomically(path, *, suffix=".part", durable=False):
    """A temporary file beside ``path`` that takes its place when the ``with`` block ends without error.

    Yields the temporary file's name (``.<name>.<random><suffix>`` in the same folder, so that the rename
    stays on one file system); the block writes it. Then it gets the permissions of a plainly created file,
    is flushed to disk when ``durable``, and is renamed onto ``path`` (``os.replace``): a reader sees the old
    file or the complete new one, never part of one. On any error, Ctrl-C included, it is removed.
    """
    path = Path(os.fspath(path))
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_UMASK)
        if durable:
            _fsync_path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    if durable:
        with contextlib.suppress(OSError):  # make the rename durable; not possible on every file system
            _fsync_path(path.parent)


# ------------------------------------------------------------------------------------------- reading


def _signature_problem(path):
    """Why ``path`` cannot be a netCDF file judging by its first bytes, or None if it may be one."""
    with open(path, "rb") as f:
        head = f.read(8)
        if not head:
            return "the file is empty"
        if head.startswith(_CDF_MAGIC) or head == _HDF5_MAGIC:
            return None
        size = os.fstat(f.fileno()).st_size
        offset = 512
        while offset + 8 <= size:
            f.seek(offset)
            if f.read(8) == _HDF5_MAGIC:
                return None
            offset *= 2
    return f"no netCDF or HDF5 signature (starts with {head!r})"


def read_dataset(path, *, require_tumble=False):
    """Read a netCDF file fully into memory and close it.

    Parameters
    ----------
    path : str or path-like
    require_tumble : bool
        Also check that the file is a tumble result (:func:`check_tumble_result`).

    Returns
    -------
    xarray.Dataset
        Loaded, with no open file behind it (the path can be rewritten or removed at once). Times are
        not decoded: a ``time`` coordinate in seconds stays float64.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        ``"<path> is not a netCDF file: ..."`` for a directory, an empty, foreign or damaged file;
        ``"<path> is not a tumble result: ..."`` with ``require_tumble``.

    See Also
    --------
    tumble.io.write_dataset : Writes the files it reads (an example there reads one back).
    tumble.io.check_tumble_result : The check of ``require_tumble``.

    Examples
    --------
    >>> import os, tempfile, tumble
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "body.nc")
    ...     _ = tumble.io.write_dataset(tumble.integrate((1.0, 2.0, 3.0), [0.0, 0.0, 1.0], 1.0, 0.1), path)
    ...     ds = tumble.io.read_dataset(path, require_tumble=True)
    >>> ds["omega"].dtype, ds["time"].dtype
    (dtype('float64'), dtype('float64'))
    """
    import xarray as xr

    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    if os.path.isdir(path):
        raise ValueError(f"{path} is not a netCDF file: it is a directory")
    problem = _signature_problem(path)
    if problem is not None:
        raise ValueError(f"{path} is not a netCDF file: {problem}")
    try:
        with signals_held(), xr.open_dataset(
            path, engine="netcdf4", decode_times=False, decode_timedelta=False, cache=False
        ) as opened:
            ds = opened.load()
    except (FileNotFoundError, PermissionError):
        raise
    except OSError as exc:  # netCDF / HDF5 library errors: truncated or damaged file
        raise ValueError(f"{path} is not a netCDF file: {exc}") from exc
    except RuntimeError as exc:  # netCDF4 reading damaged compressed data: "NetCDF: HDF error", naming nothing
        raise ValueError(f"{path} is damaged: its data cannot be read ({exc})") from exc
    if require_tumble:
        check_tumble_result(ds, path)
    return ds


def check_tumble_result(ds, path):
    """Raise unless ``ds`` (read from ``path``) was written by tumble.

    Parameters
    ----------
    ds : xarray.Dataset
    path : str or path-like
        Only used in the message.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself, for chaining.

    Raises
    ------
    ValueError
        ``"<path> is not a tumble result: ..."`` when the global ``source`` attribute is missing or does
        not start with ``"tumble"``.

    See Also
    --------
    tumble.io.read_dataset : ``require_tumble=True`` reads and checks.

    Examples
    --------
    >>> import xarray as xr, tumble
    >>> tumble.io.check_tumble_result(xr.Dataset(attrs={"source": "elsewhere"}), "other.nc")
    Traceback (most recent call last):
        ...
    ValueError: other.nc is not a tumble result: ...
    """
    source = ds.attrs.get("source")
    if not isinstance(source, str) or not source.startswith("tumble"):
        found = "it has no 'source' attribute" if source is None else f"its 'source' attribute is {source!r}"
        raise ValueError(f"{os.fspath(path)} is not a tumble result: {found}, expected 'tumble <version>'")
    return ds
