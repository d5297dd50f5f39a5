"""The least a first call can cost in a new process, for ``benchmarks/first_call.py``'s floor rows: one cached
one-line numba kernel (numba's target set-up and one cache load, what any call of a compiled kernel pays first), and
that kernel with an xarray Dataset of its result built after it (xarray's import too, what a call returning a Dataset
pays first). Nothing of tumble: what these cost, no tumble call can cost less with numba and xarray."""

import numba
import numpy as np


@numba.njit(cache=True)
def total(x):
    """The sum of ``x``: the smallest kernel worth caching."""
    s = 0.0
    for v in x:
        s += v
    return s


def total_as_dataset(x):
    """:func:`total` of ``x``, returned in an xarray Dataset with ``x`` as a coordinate."""
    import xarray as xr

    return xr.Dataset({"total": ((), total(x))}, coords={"x": np.asarray(x)})
