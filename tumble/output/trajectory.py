"""Reading another simulator's recorded trajectory: CSV (a header row), ``.npz`` or netCDF, by column name.

Columns (every other column is ignored, so a recording may carry positions, contacts, anything else):

* ``t``: time, s;
* ``wx wy wz``: angular velocity, rad/s (body or world frame, as ``tumble check --omega-frame`` says);
* ``qw qx qy qz``: attitude quaternion, body-to-world (``v_world = q v_body q*``), any sign.

A CSV file has one header row naming the columns; ``.npz`` holds one 1-D array per column name (``numpy.savez``);
a netCDF file one variable per column name along one dimension. Nothing is unpickled (``allow_pickle=False``).
Errors are :class:`ValueError` with one line naming the file, the column and the 1-based row (row 1 is the first
sample, the line after a CSV header).
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from . import io

__all__ = ["ATTITUDE_COLUMNS", "OMEGA_COLUMNS", "TIME_COLUMN", "FORMATS", "read_trajectory"]

TIME_COLUMN = "t"
OMEGA_COLUMNS = ("wx", "wy", "wz")
ATTITUDE_COLUMNS = ("qw", "qx", "qy", "qz")

#: File name suffix -> format.
FORMATS = {".csv": "csv", ".npz": "npz", ".nc": "netcdf"}


def _csv_columns(path):
    import pandas as pd

    try:
        frame = pd.read_csv(path, skipinitialspace=True, dtype=str, keep_default_na=False)
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: the file is empty (a CSV trajectory needs a header row naming its columns)") \
            from None
    except (pd.errors.ParserError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not a readable CSV file ({str(err).strip().splitlines()[0]})") from None
    frame.columns = [str(name).strip() for name in frame.columns]
    return {name: frame[name].to_numpy() for name in frame.columns}


def _npz_columns(path):
    try:
        with np.load(path, allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except (zipfile.BadZipFile, OSError, ValueError) as err:
        raise ValueError(f"{path}: not a readable .npz file ({err})") from None


def _netcdf_columns(path):
    ds = io.read_dataset(path)
    return {name: var.values for name, var in ds.variables.items()}


def _numbers(path, name, raw):
    """One column as float64, shape (N,); an error names the column and the first bad row."""
    raw = np.asarray(raw)
    if raw.ndim != 1:
        raise ValueError(f"{path}: column {name!r} must be one-dimensional, got shape {raw.shape}")
    if raw.dtype.kind in "biuf":
        values = raw.astype(float)
        bad = ~np.isfinite(values)
    else:
        import pandas as pd

        values = pd.to_numeric(pd.Series(raw), errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
    if bad.any():
        row = int(np.argmax(bad))
        cell = str(raw[row]).strip()
        what = "empty" if cell == "" else f"{cell!r} is not a finite number"
        raise ValueError(f"{path}: column {name!r}, row {row + 1}: {what}")
    return values


def read_trajectory(path):
    """The recorded columns of a trajectory file.

    Parameters
    ----------
    path : str or path-like
        A ``.csv``, ``.npz`` or ``.nc`` file.

    Returns
    -------
    dict
        ``"t"`` (N,), and ``"omega"`` (N, 3) and/or ``"quaternion"`` (N, 4, scalar first): only the groups whose
        columns the file has.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        One line naming the file and what is wrong: an unknown suffix, an unreadable file, a missing column
        (``t``, or one of a group that is partly there), a cell that is not a finite number (its column and row),
        neither an angular velocity nor an attitude.
    """
    path = Path(os.fspath(path))
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ValueError(f"{path}: unknown trajectory format {path.suffix!r} (formats: {', '.join(FORMATS)})")
    columns = {"csv": _csv_columns, "npz": _npz_columns, "netcdf": _netcdf_columns}[kind](path)
    if TIME_COLUMN not in columns:
        raise ValueError(f"{path}: missing column {TIME_COLUMN!r} (time, s); columns found: "
                         f"{', '.join(map(repr, columns)) or 'none'}")
    out = {"t": _numbers(path, TIME_COLUMN, columns[TIME_COLUMN])}
    for key, group in (("omega", OMEGA_COLUMNS), ("quaternion", ATTITUDE_COLUMNS)):
        present = [name for name in group if name in columns]
        if present and len(present) < len(group):
            missing = next(name for name in group if name not in columns)
            raise ValueError(f"{path}: missing column {missing!r} ({' '.join(group)} go together)")
        if present:
            values = [_numbers(path, name, columns[name]) for name in group]
            for name, value in zip(group, values):
                if value.shape != out["t"].shape:
                    raise ValueError(f"{path}: column {name!r} has {value.size} rows, column 't' has {out['t'].size}")
            out[key] = np.column_stack(values)
    if len(out) == 1:
        raise ValueError(f"{path}: no angular velocity ({' '.join(OMEGA_COLUMNS)}) or attitude "
                         f"({' '.join(ATTITUDE_COLUMNS)}) columns; columns found: {', '.join(map(repr, columns))}")
    return out
