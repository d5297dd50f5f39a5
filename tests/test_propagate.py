"""tumble.propagate, the lean array path: the same bits as tumble.integrate, plain arrays, the same refusals."""

import numpy as np
import pytest

import tumble

MOMENTS = (1.0, 2.0, 3.0)
SPINS = np.random.default_rng(7).normal(size=(40, 3))


@pytest.mark.parametrize("method", ["rk4", "splitting2", "exact"])
@pytest.mark.parametrize("save_every", [None, 7])
def test_propagate_gives_integrates_bits_as_an_array(method, save_every):
    got = tumble.propagate(MOMENTS, SPINS, 1.0, 0.03, method=method, save_every=save_every)
    ds = tumble.integrate(MOMENTS, SPINS, 1.0, 0.03, method=method, save_every=save_every)
    expected = ds.omega.values if save_every else ds.omega.values[:, -1, :]
    assert isinstance(got, np.ndarray) and got.shape == expected.shape
    if method == "exact":  # one time: the fused kernel (addition theorem); a grid: the same kernel as integrate's,
        # but a prange kernel compiled in another process (an xdist worker, the disk cache) may fuse its multiply-adds
        # otherwise (numba issue #10617): a few ulps apart
        np.testing.assert_allclose(got, expected, rtol=0, atol=8 * np.finfo(float).eps * np.abs(SPINS).max())
    else:
        np.testing.assert_array_equal(got, expected)


def test_propagate_with_a_torque_and_auto():
    torque = (0.0, 0.0, 0.5)
    got = tumble.propagate(MOMENTS, SPINS, 1.0, 0.03, method="auto", torque=torque)
    expected = tumble.integrate(MOMENTS, SPINS, 1.0, 0.03, method="rk4", torque=torque).omega.values[:, -1, :]
    np.testing.assert_array_equal(got, expected)
    free = tumble.propagate(MOMENTS, SPINS, 1.0, 0.03, method="auto")
    np.testing.assert_allclose(free, tumble.exact.omega(MOMENTS, SPINS, np.array([1.0]))[:, 0], rtol=0,
                               atol=8 * np.finfo(float).eps * np.abs(SPINS).max())


def test_one_spin_in_one_spin_out_and_the_callers_array_untouched():
    w0 = np.array([0.1, 1.0, 0.1])
    kept = w0.copy()
    assert tumble.propagate(MOMENTS, w0, 0.5, 0.01).shape == (3,)
    assert tumble.propagate(MOMENTS, w0, 0.5, 0.01, save_every=10).shape == (6, 3)
    np.testing.assert_array_equal(w0, kept)


@pytest.mark.parametrize("kwargs, message", [
    (dict(w0=[[np.nan, 1.0, 0.0]]), "w0 must be finite"),
    (dict(w0=np.zeros((0, 3))), "no spins"),
    (dict(w0=[[1.0, 2.0]]), "shape"),
    (dict(t_end=-1.0), "t_end must be >= 0"),
    (dict(dt=0.0), "dt must be > 0"),
    (dict(method="rk5"), "method must be one of"),
    (dict(method="exact", torque=(0.0, 0.0, 1.0)), "cannot take a torque"),
    (dict(save_every=0), "save_every"),
    (dict(body=(1.0, 2.0, -3.0)), "moments"),
])
def test_propagate_refuses_bad_input_naming_the_argument(kwargs, message):
    args = dict(body=MOMENTS, w0=SPINS, t_end=1.0, dt=0.1) | kwargs
    body, w0, t_end, dt = (args.pop(k) for k in ("body", "w0", "t_end", "dt"))
    with pytest.raises(ValueError, match=message):
        tumble.propagate(body, w0, t_end, dt, **args)
