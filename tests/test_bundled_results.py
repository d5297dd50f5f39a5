"""Every bundled study, run small, gives the numbers stored in ``tests/data/bundled`` (bit for bit on a machine
of the same vector width; to 1e-12 elsewhere, where the compiler may fuse and vectorise differently).

The stored files are rewritten by ``python tests/data/bundled/make.py``, only for a change meant to change
results. Timings (the work-precision study's wall times), the peers' rows of the work-precision study (SciPy's and
heyoka's numbers follow their versions; heyoka is optional) and provenance (versions, dates) are not compared.
"""

import platform
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
import xarray as xr

import tumble
from tumble.measure import precision
from tumble.pipeline import config

DATA = Path(__file__).parent / "data" / "bundled"

# Overrides that keep each study's scenes (kinds, methods, torques, observers) with few samples.
SMALL = {
    "amplitude_sweep": {"perturbation.samples": 32},
    "disc_wobble": {"perturbation.samples": 32},
    "dzhanibekov_flip": {"perturbation.samples": 16},
    "gyrostat_map": {"perturbation.samples": 16},
    "debra_delp_map": {"perturbation.samples": 16},
    "gravity_gradient_pitch": {"perturbation.samples": 16},
    "explorer1": {"perturbation.samples": 16},
    "intermediate_axis": {"perturbation.samples": 64},
    "shapes": {"perturbation.samples": 32},
    "sleeping_top": {"perturbation.samples": 16},
    "space_station": {"perturbation.samples": 16},
    "stability_map": {"perturbation.samples": 32, "scan.triangle": 4},
    "stress": {"perturbation.samples": 16},
    "work_precision": {"perturbation.samples": 64},
}
STUDIES = sorted(SMALL)
# Several seconds each even small (splitting4's many steps; SciPy's tolerance ladder): under -m slow.
_SLOW = ("stress", "work_precision")

# Variables that are measurements of the machine, not results.
_TIMINGS = ("wall", "compile")


def machine_signature():
    """What decides the bits beyond the code: the CPU architecture and its vector width."""
    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features()
    width = "avx512" if features.get("avx512f") else "avx2" if features.get("avx2") else "other"
    return f"{platform.machine()} {width}"


def run_small(name):
    # heyoka, when installed, would become the work-precision study's reference and move every error
    with mock.patch.object(precision, "_import_heyoka", lambda: None):
        ds = tumble.run_study(name, overrides=SMALL[name], progress=False)
    if "solver_kind" in ds:
        ds = ds.isel(solver=np.isin(ds["solver_kind"].values, ("tumble", "exact")))
    drop = [v for v in ds.variables if any(word in v for word in _TIMINGS)]
    ds = ds.drop_vars(drop)
    ds.attrs = {}
    for v in ds.variables.values():
        v.attrs = {k: a for k, a in v.attrs.items() if k not in ("history", "source")}
    return ds


def test_every_bundled_study_is_stored():
    assert set(STUDIES) == set(config.bundled_studies())


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in _SLOW else n for n in STUDIES])
def test_a_bundled_study_gives_the_stored_numbers(name):
    stored = xr.load_dataset(DATA / f"{name}.nc")
    same_machine = stored.attrs.pop("stored_on") == machine_signature()
    got = run_small(name)
    assert sorted(got.variables) == sorted(stored.variables)
    for var in got.variables:
        a, b = got[var].values, stored[var].values
        if a.dtype.kind in "fc" and not same_machine:
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=0, equal_nan=True, err_msg=var)
        else:
            np.testing.assert_array_equal(a, b, err_msg=var)
