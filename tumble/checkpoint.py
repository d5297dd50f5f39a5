"""Checkpoints of a running study: finished scenes on disk, so that a rerun resumes where a run stopped.

A study's scenes run in *chunks* (groups of scenes). Each finished chunk is written atomically (a hidden
``.part`` file, flushed, renamed) into the hidden folder ``<out>/.<stem>.chunks/`` as
``scenes-<first>-<last>.chunk``: a NumPy ``.npz`` archive (plain arrays, read with ``allow_pickle=False``)
holding every variable and attribute of each scene with its exact dtype, and a JSON manifest with the study's
hash (:func:`study_hash`) and the layout of each scene. (netCDF, one group per scene, cost 35 ms a scene to
write — as much as computing a 256-sample closed-form scene; the archive costs about 1 ms.) A rerun of the
same study into the same folder reads the chunks whose hash matches and runs only the scenes they lack; a
chunk with another hash (another study, another tumble version) is never used, and is removed. The result file is assembled from the scenes and
written atomically by :func:`tumble.io.write_dataset`; the checkpoint folder is removed after that.

Nothing in the folder can be mistaken for a result: it is hidden, its files are not named ``*.nc`` and are not netCDF
(``tumble plot`` refuses them).

Safety: chunk files are read with ``numpy.load(allow_pickle=False)`` and ``json``; nothing is unpickled or
evaluated.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from . import __version__, io

__all__ = ["Checkpoint", "OutputError", "chunk_folder", "local_file_locks", "normalise_scene", "study_hash"]

#: Suffix of a finished chunk file (a NumPy archive; deliberately not ``.nc``).
CHUNK_SUFFIX = ".chunk"

#: Manifest key holding the study hash of a chunk file.
HASH_ATTR = "tumble_checkpoint"

_CHUNK_NAME = re.compile(r"^scenes-(\d+)-(\d+)\.chunk$")

#: Fields of a resolved study that do not change any number in the result (where and in which figure format
#: it is written): left out of the hash, so that ``--format pdf`` or another ``--out`` still resumes.
_NOT_HASHED = {"outputs": ("format", "directory")}


class OutputError(OSError):
    """A result or checkpoint file could not be written (unwritable folder, disk full)."""


def study_hash(resolved):
    """SHA-256 (hex) of the resolved study (as sorted JSON) and the tumble version.

    Parameters
    ----------
    resolved : Mapping
        A resolved study (:func:`tumble.config.load_study`).
    """
    study = json.loads(json.dumps(resolved, sort_keys=True, default=io._json_default))
    for table, keys in _NOT_HASHED.items():
        for key in keys:
            study.get(table, {}).pop(key, None)
    text = json.dumps({"study": study, "tumble": __version__}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def chunk_folder(directory, stem):
    """``<directory>/.<stem>.chunks``: where the chunks of the study writing ``<stem>.nc`` live."""
    return Path(directory) / f".{stem}.chunks"


def normalise_scene(ds):
    """A scene dataset as a netCDF file gives it back: ``<U`` strings, netCDF-safe attributes, no encoding.

    Every scene goes through this before a scan is assembled, whether it was just computed or read from a
    chunk, so that a resumed run assembles exactly the same dataset as an uninterrupted one.
    """
    ds = io._strings_as_unicode(ds).drop_encoding()
    ds = ds.copy(deep=False)
    for var in ds.variables.values():
        var.attrs = io.netcdf_safe_attrs(var.attrs)
    ds.attrs = io.netcdf_safe_attrs(ds.attrs)
    return ds


def local_file_locks():
    """A context in which xarray locks netCDF files with plain thread locks.

    While a dask ``Client`` is the default scheduler, xarray takes a ``distributed.Lock`` — a round trip to
    the scheduler — for every access to a netCDF file it writes, which made writing a chunk 20× slower. The
    files tumble writes are its own, written by one thread of the client process: a thread lock is enough.
    """
    if sys.modules.get("dask") is None:
        return contextlib.nullcontext()
    import dask

    return dask.config.set(scheduler="synchronous")


def _write_error(path, err):
    what = err.strerror or str(err)
    return OutputError(err.errno, f"cannot write {path}: {what}")


def _pack_attrs(attrs, prefix, arrays):
    """Attribute names, their values stored as arrays ``<prefix>@<name>`` (exact dtypes, no JSON typing)."""
    for name, value in attrs.items():
        arrays[f"{prefix}@{name}"] = np.asarray(value)
    return list(attrs)


def _unpack_attrs(arrays, prefix, names):
    out = {}
    for name in names:
        value = arrays[f"{prefix}@{name}"]
        if value.ndim == 0:
            value = str(value[()]) if value.dtype.kind == "U" else value[()]
        out[name] = value
    return out


def _pack_scene(ds, index, arrays):
    """Store a normalised scene's variables and attributes in ``arrays``; return its layout (JSON-able)."""
    variables = []
    for name, var in ds.variables.items():
        key = f"{index}/{name}"
        arrays[key] = var.values
        variables.append({"name": name, "dims": list(var.dims), "coord": name in ds.coords,
                          "attrs": _pack_attrs(var.attrs, key, arrays)})
    return {"variables": variables, "attrs": _pack_attrs(ds.attrs, f"{index}/", arrays)}


def _unpack_scene(arrays, index, layout):
    """The scene dataset :func:`_pack_scene` stored, variable order, dtypes and attributes included."""
    data, coords = {}, {}
    for entry in layout["variables"]:
        key = f"{index}/{entry['name']}"
        var = xr.Variable(tuple(entry["dims"]), arrays[key], _unpack_attrs(arrays, key, entry["attrs"]))
        (coords if entry["coord"] else data)[entry["name"]] = var
    return xr.Dataset(data, coords=coords, attrs=_unpack_attrs(arrays, f"{index}/", layout["attrs"]))


class Checkpoint:
    """The finished chunks of one study in one output folder.

    Parameters
    ----------
    directory : path-like
        The output folder of the study (the checkpoint folder is created inside it on the first write).
    stem : str
        Stem of the result file (``<stem>.nc``).
    digest : str
        :func:`study_hash` of the resolved study.
    scenes : int
        Number of scenes of the study (scene indices run from 0 to ``scenes - 1``).
    """

    def __init__(self, directory, stem, digest, scenes):
        self.directory = Path(directory)
        self.folder = chunk_folder(directory, stem)
        self.stem = stem
        self.digest = digest
        self.scenes = int(scenes)
        self.stale = 0  # chunk files of another study hash removed by load()

    def load(self):
        """The finished scenes: ``{index: normalised scene dataset}`` from every chunk with this study's hash.

        Chunk files of another hash and unreadable ones are removed (never used), as are leftover ``.part``
        files of an interrupted write.
        """
        done = {}
        if not self.folder.is_dir():
            return done
        for path in sorted(self.folder.iterdir()):
            if path.name.startswith(".") and path.name.endswith(".part"):
                path.unlink(missing_ok=True)
                continue
            match = _CHUNK_NAME.match(path.name)
            if not match:
                continue
            scenes = self._read(path)
            if scenes is None:
                self.stale += 1
                path.unlink(missing_ok=True)
                continue
            done.update(scenes)
        return done

    def _read(self, path):
        """``{index: scene}`` of one chunk file, or None when it belongs to another study or is unreadable."""
        try:
            with np.load(path, allow_pickle=False) as arrays:
                manifest = json.loads(str(arrays["manifest"][()]))
                if manifest.get(HASH_ATTR) != self.digest:
                    return None
                scenes = {}
                for key, layout in manifest["scenes"].items():
                    index = int(key)
                    if not 0 <= index < self.scenes:
                        return None
                    scenes[index] = _unpack_scene(arrays, index, layout)
                return scenes
        except Exception:  # noqa: BLE001 - any chunk that cannot be read is recomputed, never trusted
            return None

    def write(self, scenes):
        """Write one finished chunk atomically.

        Parameters
        ----------
        scenes : Mapping[int, xarray.Dataset]
            Normalised scene datasets by scene index (at least one).

        Raises
        ------
        OutputError
            The folder cannot be created or the file written (the message names the path); nothing is left
            behind.
        """
        indices = sorted(scenes)
        path = self.folder / f"scenes-{indices[0]:06d}-{indices[-1]:06d}{CHUNK_SUFFIX}"
        arrays, layouts = {}, {}
        for i in indices:
            layouts[str(i)] = _pack_scene(scenes[i], i, arrays)
        manifest = {HASH_ATTR: self.digest, "tumble_version": __version__, "scenes": layouts,
                    "comment": "checkpoint of a running tumble study (not a result); removed when it finishes"}
        arrays["manifest"] = np.array(json.dumps(manifest, sort_keys=True))
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.folder, prefix="." + path.name + ".", suffix=".part")
        except OSError as err:
            raise _write_error(self.folder, err) from err
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, **arrays)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)
        except BaseException as err:
            Path(tmp).unlink(missing_ok=True)
            if isinstance(err, OSError):
                raise _write_error(path, err) from err
            raise
        return path

    def remove(self):
        """Remove the checkpoint folder (after the result file is written)."""
        shutil.rmtree(self.folder, ignore_errors=True)

    def clean_partial_results(self):
        """Remove leftover hidden ``.<stem>.nc.*.part`` files of an interrupted result write."""
        if self.directory.is_dir():
            for path in self.directory.glob(f".{self.stem}.nc.*.part"):
                path.unlink(missing_ok=True)
