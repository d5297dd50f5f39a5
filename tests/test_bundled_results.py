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
    "chaos_map": {"scan.tilt": [0.5, 2.0], "scan.rate": [0.5, 1.0, 3.0], "integration.horizon": 10.0},
    "hyperion": {"scan.angle": [0.0, 1.0], "scan.rate": [0.5, 1.0, 2.5], "integration.horizon": 10.0},
    "hyperion_section": {"scan.angle": [0.0, 1.571], "scan.rate": [0.55, 1.2, 2.7], "integration.horizon": 20.0,
                         "section.crossings": 3},
    "heavy_top_section": {"scan.tilt": [2.6, 2.9, 3.5], "integration.horizon": 20.0, "section.crossings": 3},
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
    """What decides the bits beyond the code: the CPU architecture and the vector width numba compiles for (the
    host's, or the one ``NUMBA_CPU_FEATURES`` names: ``widths.py`` beside the stored files compiles for AVX2 on an
    AVX-512 machine that way)."""
    import numba.core.codegen
    import numba.core.config

    features = numba.core.config.CPU_FEATURES or numba.core.codegen.get_host_cpu_features()
    width = "avx512" if "+avx512f" in features else "avx2" if "+avx2" in features else "other"
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


def across_vector_widths(var, stored):
    """Tolerances of ``var`` between machines of another vector width (AVX2, AVX-512), which fuse other products into
    multiply-adds and sum in another order: 1e-12 of the quantity's scale, with an absolute floor where a value is
    not the scale of its own round-off.

    Every value is allowed 1e-12 relative to itself or 1e-12 of the largest value of its variable, whichever is
    larger: a value near zero reached through many operations (a finite-time Lyapunov exponent of 1e-5 among
    exponents of 0.4, summed logarithms divided by the time) carries the round-off of its variable's scale, not of
    its own size (8.8e-16 absolute seen in ``chaos_map``'s ``finite_time``, 1.5e-11 of the value). A spread (half the
    interquartile range of the samples' rates) is a difference of rates: the scale of the rates. Errors against a
    reference and drifts of invariants (``wp_error*``, ``*_drift``) are differences of states of order 1: 1e-13
    absolute at least (errors of 3e-14 seen moving by half); a relative error 1e-12. A quaternion's components are of
    order 1 together, and one that is zero in exact arithmetic is round-off: 1e-13 absolute. A trajectory over a
    long damped horizon (``trace_*``) amplifies round-off: 1e-9 (1.7e-10 relative seen for ``explorer1``'s nutation).

    ``python tests/data/bundled/widths.py`` runs the studies compiled for each vector width this machine can run and
    prints how much of these tolerances the differences use.
    """
    rtol = 1e-9 if var.startswith("trace_") else 1e-12
    values = stored["rate"] if var == "rate_spread" else stored[var]
    scale = float(np.nanmax(np.abs(values.values), initial=0.0)) if values.dtype.kind in "fc" else 0.0
    floor = 0.0
    if "quaternion" in var or ("error" in var and "rel_error" not in var) or "drift" in var:
        floor = 1e-13
    elif "rel_error" in var:
        floor = 1e-12
    return {"rtol": rtol, "atol": max(floor, rtol * scale)}


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
        # an error against the closed form's reference: its prange kernels' bits depend on the process that compiled
        # them (numba #10617: a CI run from an empty cache moved work_precision's errors by 2e-16), so across processes
        # an error is held to the tolerance between vector widths, not the bit
        if a.dtype.kind in "fc" and (not same_machine or var.startswith("wp_error")):
            np.testing.assert_allclose(a, b, equal_nan=True, err_msg=var, **across_vector_widths(var, stored))
        else:
            np.testing.assert_array_equal(a, b, err_msg=var)
