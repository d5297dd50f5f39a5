"""The file layer: provenance attributes, netCDF-safe attributes, atomic writes, checked reads."""

import json
import os
import re
import stat

import netCDF4
import numpy as np
import pytest
import xarray as xr
from xarray.testing import assert_identical

from tumble._version import __version__
from tumble.output import io
from tumble.output.io import check_tumble_result, netcdf_safe_attrs, provenance, read_dataset, write_dataset

STUDY = {
    "body": {"moments": [1.0, 2.0, 3.0], "shape": "cuboid"},
    "scan": {"I1": [1.0, 1.5]},
    "samples": 4,
    "method": "rk4",
}
ENTROPY = 2**127 + 12345  # 128-bit, beyond any netCDF integer type

HISTORY_LINE = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ tumble " + re.escape(__version__) + r": (.+)$")


def result_dataset():
    """A tiny dataset with every kind of variable and attribute a study result carries."""
    status = np.array([[0, 1, 0], [2, 0, 0]], dtype=np.int8)
    ds = xr.Dataset(
        {
            "kind": ((), "periodic", {"long_name": "kind of motion"}),
            "kind_object": ((), np.array("exponential", dtype=object), {"long_name": "kind, object dtype"}),
            "rate": (("body", "axis"), np.array([[0.1, np.nan, 0.3], [0.4, 0.5, 0.6]]),
                     {"units": "1/s", "long_name": "measured rate"}),
            "rel_error": ((), 1.5e-4, {"units": "1", "long_name": "relative error"}),
            "sample_rate": (("sample",), np.linspace(0.0, 1.0, 4), {"units": "1/s", "long_name": "rate per sample"}),
            "n_finished": (("body",), np.array([4, 3], dtype=np.int64), {"units": "1", "long_name": "finished"}),
            "status": (("body", "axis"), status, {
                "long_name": "sample status",
                "flag_values": np.array([0, 1, 2], dtype=np.int8),
                "flag_meanings": "ok blown_up stopped_early",
            }),
            "omega": (("time", "component"), np.arange(6.0).reshape(2, 3), {"units": "rad/s", "long_name": "w"}),
        },
        coords={
            "I1": ("body", [1.0, 1.5], {"units": "kg m2", "long_name": "first principal moment"}),
            "axis": ("axis", np.array([1, 2, 3]), {"long_name": "spin axis"}),
            "time": ("time", [0.0, 0.5], {"units": "s", "long_name": "time"}),
            "body_name": ("body", ["brick", "plate"], {"long_name": "body"}),
            "component": ("component", np.array(["w1", "w2", "w3"], dtype=object), {"long_name": "axis"}),
        },
        attrs={
            "moments": np.array([1.0, 2.0, 3.0]),
            "method": "rk4",
            "path": "studies/intermediate.toml",
            "dt": 0.01,
            "n_steps": 100,
            "early_stop": True,
            "attitude": np.False_,
            "skipped": {"attitude": True, "trajectories": "not requested"},
            "torque": (0, 0, 0),
            "not_stored": None,
        },
    )
    return ds


# ----------------------------------------------------------------------------------- netcdf_safe_attrs


def test_safe_attrs_booleans_become_int8():
    out = netcdf_safe_attrs({"a": True, "b": np.False_, "c": [True, False]})
    assert out["a"] == 1 and out["a"].dtype == np.int8
    assert out["b"] == 0 and out["b"].dtype == np.int8
    assert out["c"].dtype == np.int8 and out["c"].tolist() == [1, 0]


def test_safe_attrs_drop_none_and_keep_strings_and_numpy_scalars():
    out = netcdf_safe_attrs({"gone": None, "s": "rk4", "f": np.float32(0.5), "i": np.int8(3)})
    assert "gone" not in out
    assert out["s"] == "rk4"
    assert out["f"].dtype == np.float32 and out["i"].dtype == np.int8


def test_safe_attrs_mappings_and_string_lists_become_sorted_json():
    out = netcdf_safe_attrs({"d": {"z": 1, "a": [1, 2], "n": np.float64(0.5)}, "names": ["a", "b"]})
    assert out["d"] == '{"a": [1, 2], "n": 0.5, "z": 1}'
    assert json.loads(out["names"]) == ["a", "b"]


def test_safe_attrs_big_int_becomes_decimal_string():
    out = netcdf_safe_attrs({"big": 2**100, "small": 7, "neg": -(2**70), "list": [1, 2**64]})
    assert out["big"] == str(2**100)
    assert out["small"] == 7 and out["small"].dtype == np.int64
    assert out["neg"] == str(-(2**70))
    assert json.loads(out["list"]) == [1, 2**64]


def test_safe_attrs_number_sequences_become_arrays_and_length_one_a_scalar():
    out = netcdf_safe_attrs({"ints": (1, 2), "mixed": [1, 2.5], "one": [3.0], "one_array": np.array([4])})
    assert out["ints"].dtype == np.int64 and out["ints"].tolist() == [1, 2]
    assert out["mixed"].dtype == np.float64
    assert np.ndim(out["one"]) == 0 and out["one"] == 3.0
    assert np.ndim(out["one_array"]) == 0 and out["one_array"] == 4


def test_safe_attrs_matrix_becomes_json_and_unknown_types_are_named():
    assert json.loads(netcdf_safe_attrs({"m": np.eye(2)})["m"]) == [[1.0, 0.0], [0.0, 1.0]]
    with pytest.raises(TypeError, match="'when'"):
        netcdf_safe_attrs({"when": 1j})


# ------------------------------------------------------------------------------------------ provenance


def test_provenance_adds_global_attributes_without_touching_input():
    ds = result_dataset()
    out = provenance(ds, study=STUDY, seed_entropy=ENTROPY, action="run intermediate")
    assert out.attrs["Conventions"] == "CF-1.10"
    assert out.attrs["title"] == "tumble result"
    assert out.attrs["source"] == f"tumble {__version__}"
    assert HISTORY_LINE.match(out.attrs["history"]).group(1) == "run intermediate"
    assert json.loads(out.attrs["study"]) == STUDY
    assert out.attrs["seed_entropy"] == str(ENTROPY)
    assert out.attrs["early_stop"].dtype == np.int8
    assert "not_stored" not in out.attrs
    assert ds.attrs["early_stop"] is True and "source" not in ds.attrs  # the input is not modified


def test_provenance_title_keeps_existing_and_rejects_bad_entropy():
    ds = result_dataset().assign_attrs(title="spin scan")
    assert provenance(ds).attrs["title"] == "spin scan"
    assert provenance(ds, title="other").attrs["title"] == "other"
    with pytest.raises(ValueError, match="seed_entropy"):
        provenance(ds, seed_entropy=-1)


# --------------------------------------------------------------------------------------------- writing


def assert_same_dtypes(a, b):
    for name in a.variables:
        assert a[name].dtype == b[name].dtype, name


def test_result_roundtrips_identically(tmp_path):
    path = tmp_path / "result.nc"
    stored = write_dataset(result_dataset(), path, study=STUDY, seed_entropy=ENTROPY, title="scan")
    back = read_dataset(path, require_tumble=True)
    assert_identical(back, stored)
    assert_same_dtypes(back, stored)
    for name, attrs in result_dataset().variables.items():
        for key in ("units", "long_name"):
            if key in attrs.attrs:
                assert back[name].attrs[key] == attrs.attrs[key]
    assert back["time"].dtype == np.float64  # seconds stay seconds, not timedelta64
    assert back["kind"].item() == "periodic" and back["kind_object"].item() == "exponential"
    assert back["status"].dtype == np.int8 and back["n_finished"].dtype == np.int64
    assert back.attrs["title"] == "scan" and back.attrs["source"] == f"tumble {__version__}"
    assert json.loads(back.attrs["study"]) == STUDY
    assert int(back.attrs["seed_entropy"]) == ENTROPY
    assert json.loads(back.attrs["skipped"]) == {"attitude": True, "trajectories": "not requested"}
    assert back.attrs["early_stop"] == 1 and back.attrs["attitude"] == 0
    for key, value in stored.attrs.items():  # same types too, which assert_identical does not check
        assert type(back.attrs[key]) is type(value), key
        assert np.asarray(back.attrs[key]).dtype == np.asarray(value).dtype, key


def test_numeric_variables_are_compressed(tmp_path):
    path = tmp_path / "result.nc"
    write_dataset(result_dataset(), path, compression=6)
    with netCDF4.Dataset(path) as nc:
        for name in ("rate", "sample_rate", "status", "n_finished", "I1", "time"):
            filters = nc[name].filters()
            assert filters["zlib"] and filters["shuffle"] and filters["complevel"] == 6, name
        assert "_FillValue" not in nc["time"].ncattrs() and "_FillValue" not in nc["I1"].ncattrs()


def test_compression_zero_writes_plain_variables(tmp_path):
    path = tmp_path / "result.nc"
    stored = write_dataset(result_dataset(), path, compression=0)
    with netCDF4.Dataset(path) as nc:
        assert not nc["rate"].filters()["zlib"]
    assert_identical(read_dataset(path), stored)


@pytest.mark.parametrize("bad", [-1, 10, 2.0, True, "4"])
def test_compression_must_be_a_level(tmp_path, bad):
    with pytest.raises(ValueError, match="compression"):
        write_dataset(result_dataset(), tmp_path / "x.nc", compression=bad)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "result.nc"
    write_dataset(result_dataset(), path)
    before = path.read_bytes()

    def half_write(ds, target, encoding):
        with open(target, "wb") as f:
            f.write(before[: len(before) // 2])
        raise RuntimeError("disk full")

    monkeypatch.setattr(io, "_to_netcdf4", half_write)
    with pytest.raises(OSError, match="disk full") as raised:  # netCDF4's RuntimeError, with the file's name
        write_dataset(result_dataset(), path)
    assert str(path) in str(raised.value) and isinstance(raised.value.__cause__, RuntimeError)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["result.nc"]


def test_unstorable_attribute_fails_before_any_file_is_made(tmp_path):
    ds = result_dataset().assign_attrs(callback=object())
    with pytest.raises(TypeError, match="callback"):
        write_dataset(ds, tmp_path / "result.nc")
    assert list(tmp_path.iterdir()) == []


def test_rewrite_appends_history_and_creates_folders(tmp_path):
    first = tmp_path / "a" / "b" / "first.nc"
    write_dataset(result_dataset(), first)
    again = write_dataset(read_dataset(first), first, action="re-written")  # same path, file was closed
    lines = read_dataset(first).attrs["history"].split("\n")
    assert len(lines) == 2
    assert HISTORY_LINE.match(lines[0]).group(1) == "created"
    assert HISTORY_LINE.match(lines[1]).group(1) == "re-written"
    assert_identical(read_dataset(first), again)


def test_written_file_has_the_permissions_of_a_plainly_created_file(tmp_path):
    path = tmp_path / "result.nc"
    write_dataset(result_dataset(), path)
    mask = os.umask(0o022)
    os.umask(mask)
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o666 & ~mask  # not mkstemp's 0600


# --------------------------------------------------------------------------------------------- reading


def test_missing_file_is_file_not_found(tmp_path):
    path = tmp_path / "nowhere.nc"
    with pytest.raises(FileNotFoundError, match=re.escape(str(path))):
        read_dataset(path)


@pytest.mark.parametrize("content", [b"", b"time,rate\n0,1\n", b"\x89HDF\r\n\x1a\n" + b"\0" * 40])
def test_non_netcdf_file_is_a_value_error(tmp_path, content):
    path = tmp_path / "data.nc"
    path.write_bytes(content)
    with pytest.raises(ValueError, match=re.escape(f"{path} is not a netCDF file: ")):
        read_dataset(path)


def test_directory_is_not_a_netcdf_file(tmp_path):
    with pytest.raises(ValueError, match="is not a netCDF file: it is a directory"):
        read_dataset(tmp_path)


def test_foreign_netcdf_is_not_a_tumble_result(tmp_path):
    path = tmp_path / "foreign.nc"
    xr.Dataset({"x": ("n", [1.0, 2.0])}, attrs={"source": "model 7"}).to_netcdf(path, engine="netcdf4")
    ds = read_dataset(path)  # readable without the check
    with pytest.raises(ValueError, match=re.escape(f"{path} is not a tumble result: ") + ".*model 7"):
        read_dataset(path, require_tumble=True)
    with pytest.raises(ValueError, match="no 'source' attribute"):
        check_tumble_result(ds.drop_attrs(), path)
