"""Regressions over a scan: measured rate against theory (:func:`regress_scan`), the flip-time law
(:func:`flip_time_law`)."""

from __future__ import annotations

import numpy as np

from . import estimators as analysis
from .records import KIND_UNITS

__all__ = ["flip_time_law", "regress_scan"]


def regress_scan(ds):
    """Measured rate against theory over a scan, per kind: slope, intercept, R², worst point.

    Parameters
    ----------
    ds : xarray.Dataset
        From :func:`scan` (or one :func:`measure`).

    Returns
    -------
    xarray.Dataset
        Dimension ``kind`` (the kinds present, neutral excluded: its theory is 0); variables ``slope``,
        ``intercept``, ``r2``, ``median_rel_error``, ``worst_rel_error``, ``points``, and the worst point's
        ``rate``, ``rate_theory`` and scan coordinates.

    See Also
    --------
    tumble.scan : The scan it fits.
    tumble.flip_time_law : The flip-time law over an amplitude scan.

    Examples
    --------
    Measured against theory over four bodies of the inertia triangle, all three axes: slope 1 for both kinds:

    >>> import tumble
    >>> moments, coords = tumble.inertia_triangle(2)
    >>> ds = tumble.scan(moments, axis=[1, 2, 3], samples=16, body_coords=coords)
    >>> fit = tumble.regress_scan(ds)
    >>> fit["kind"].values.tolist(), bool((abs(fit["slope"] - 1) < 0.01).all())
    (['periodic', 'exponential'], True)
    """
    import xarray as xr

    rows = []
    for kind in ("periodic", "exponential"):
        mask = ds["kind"] == kind
        if not bool(mask.any()):
            continue
        theory_values = ds["rate_theory"].where(mask).values.ravel()
        measured = ds["rate"].where(mask).values.ravel()
        fit = analysis.regression(theory_values, measured)
        worst = {}
        if fit.worst >= 0:
            point = ds[["rate", "rate_theory"]][dict(zip(ds["rate"].dims, np.unravel_index(fit.worst,
                                                                                          ds["rate"].shape)))]
            for name, variable in [*point.data_vars.items(), *point.coords.items()]:
                if variable.ndim == 0:
                    worst[f"worst_{name}"] = ((), variable.values.item(),
                                              {"units": KIND_UNITS[kind] if name.startswith("rate")
                                               else variable.attrs.get("units", "1"),
                                               "long_name": f"{name} of the scene with the largest error"})
        rel = ds["rel_error"].where(mask).values
        rows.append(xr.Dataset({
            "slope": ((), fit.slope, {"units": "1", "long_name": "slope of measured rate against theory"}),
            "intercept": ((), fit.intercept, {"units": KIND_UNITS[kind], "long_name": "intercept"}),
            "r2": ((), fit.r2, {"units": "1", "long_name": "coefficient of determination"}),
            "median_rel_error": ((), float(np.nanmedian(rel)), {"units": "1",
                                                                "long_name": "median relative error over scenes"}),
            "worst_rel_error": ((), fit.worst_error, {"units": "1", "long_name": "largest relative error"}),
            "points": ((), np.int64(fit.points), {"units": "1", "long_name": "scenes in the fit"}),
            **worst,
        }).expand_dims(kind=[kind]))
    if not rows:
        raise ValueError("the dataset holds no periodic or exponential scene to regress")
    return xr.concat(rows, dim="kind", combine_attrs="override") if len(rows) > 1 else rows[0]


def flip_time_law(ds):
    r"""The flip-time law over an amplitude scan: first-flip time against ``ln(1/ε)``, slope against ``1/λ``.

    Near the separatrix the first flip comes at ``(1/λ) ln(4/k')`` and ``k' ∝ ε``, so the median first-flip
    time is linear in ``ln(1/ε)`` with slope ``1/λ``.

    Parameters
    ----------
    ds : xarray.Dataset
        A :func:`scan` with an ``amplitude`` dimension (at least two amplitudes) of exponential scenes timed
        with ``flips > 0``.

    Returns
    -------
    xarray.Dataset
        ``slope`` (s), ``slope_theory = 1/rate_theory`` (s), ``rel_error``, ``intercept`` (s), ``r2``, over the
        scan's other dimensions.

    See Also
    --------
    tumble.theory.flip_time_asymptote : The law for one spin.
    tumble.regress_scan : Measured rates against theory over a scan.

    Notes
    -----
    Near the separatrix the first flip of a spin tilted by :math:`\varepsilon` comes at [1]_ [2]_

    .. math::

        t_1 \approx \frac{1}{\lambda} \ln\frac{4}{k'}, \qquad k' \propto \varepsilon
        \quad\Longrightarrow\quad t_1 \approx \frac{1}{\lambda} \ln\frac{1}{\varepsilon} + \text{const},

    so the median first-flip time is a line in :math:`\ln(1/\varepsilon)` of slope :math:`1/\lambda`.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.
    .. [2] M. Abramowitz and I. A. Stegun, *Handbook of Mathematical Functions* (Dover, 1964), 17.3.26.

    Examples
    --------
    >>> import tumble
    >>> ds = tumble.scan((1.0, 2.0, 3.0), axis=2, amplitude=[1e-6, 1e-4, 1e-2], samples=16)
    >>> law = tumble.flip_time_law(ds)
    >>> round(float(law["slope_theory"][0]), 4), bool(abs(law["rel_error"][0]) < 1e-3)
    (1.7321, True)
    """
    import xarray as xr

    if "amplitude" not in ds.dims or ds.sizes["amplitude"] < 2:
        raise ValueError("the flip-time law needs a scan over at least two amplitudes (an 'amplitude' dimension)")
    if "flip_first" not in ds:
        raise ValueError("the dataset has no flip times: scan exponential scenes with flips > 0")
    x = np.log(1.0 / ds["amplitude"])

    def fit(times, xs):
        r = analysis.regression(xs, times)
        return np.array([r.slope, r.intercept, r.r2])

    out = xr.apply_ufunc(fit, ds["flip_first"], x, input_core_dims=[["amplitude"], ["amplitude"]],
                         output_core_dims=[["fit"]], vectorize=True)
    theory_slope = 1.0 / ds["rate_theory"].isel(amplitude=0, drop=True)
    result = xr.Dataset({
        "slope": out.isel(fit=0, drop=True).assign_attrs(units="s", long_name="d(first flip time)/d ln(1/amplitude)"),
        "intercept": out.isel(fit=1, drop=True).assign_attrs(units="s", long_name="intercept"),
        "r2": out.isel(fit=2, drop=True).assign_attrs(units="1", long_name="coefficient of determination"),
        "slope_theory": theory_slope.assign_attrs(units="s", long_name="1 / linear growth rate"),
    })
    result["rel_error"] = (abs(result["slope"] - result["slope_theory"]) / result["slope_theory"]).assign_attrs(
        units="1", long_name="|slope - 1/lambda| / (1/lambda)")
    return result.drop_vars([c for c in result.coords if c not in result.dims and c != "method"], errors="ignore")
