"""The closed form's attitude by the per-sample kernels (tumble/kernels/closed_form/elliptic_attitude.py), which the CUDA device
runs too, against the numpy and scipy.special formulation it replaced (tests/attitude_reference.py), and Carlson's
R_J against scipy's."""

import numpy as np
import pytest
from attitude_reference import attitude as reference_attitude
from scipy.special import elliprj

from tumble.kernels.closed_form.elliptic_attitude import carlson_rj
from tumble.physics import exact


def test_carlson_rj_agrees_with_scipy_to_a_few_ulps():
    rng = np.random.default_rng(2827)
    x, y = rng.uniform(0.0, 1.0, (2, 4000)) ** rng.integers(1, 8, (2, 4000))
    x[::10] = 0.0  # the complete integral's R_J(0, k'^2, 1, 1 - n)
    p = 1.0 + rng.exponential(3.0, 4000) * rng.uniform(0.0, 1.0, 4000)
    ours = np.array([carlson_rj(a, b, 1.0, c) for a, b, c in zip(x, y, p)])
    np.testing.assert_allclose(ours, elliprj(x, y, 1.0, p), rtol=8 * np.finfo(float).eps, atol=0)


BODIES = [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (2.0, 2.0, 3.0), (1.0, 2.0, 2.0), (3.0, 4.0, 6.0), (1.0, 1.0, 1.0)]
# both regimes, either sign of every component, steady spins, zero, near the intermediate axis, the separatrix of
# (3, 4, 6), within 1e-151 of an axis (the lifted set-up)
SPINS = np.vstack([np.random.default_rng(2828).normal(size=(24, 3)),
                   [[0.1, 1.0, 0.05], [1.0, 0.2, 0.1], [0.05, 0.3, -1.0], [-0.3, 0.2, 0.9], [1e-3, 1.0, 1e-3],
                    [2.0, 0.7, 1.0], [0.0, 2.0, 0.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.0], [1e-170, 1.0, 0.0],
                    [1e-200, 0.0, 1.0]]])


@pytest.mark.parametrize("body", BODIES, ids=lambda b: "-".join(f"{m:g}" for m in b))
def test_the_attitude_kernels_give_the_numpy_closed_form(body):
    """Within 1e-13 over 40 s (a few ulps of the angles there; R_J and R_F are ours, not scipy's, and the angles are
    summed in another order), times 0.01/|ν| where the elliptic argument moves slowly: a symmetric top spun close to
    its equal-moment plane (ν = 5e-4 here) takes φ from |L| (I_p - I_q) / (I_q I_p ν) times a difference of
    integrals, which amplifies their rounding by 1/ν in either formulation (at ν ~ 1e-9 both are only good to about
    1e-7 rad against an independent integration)."""
    times = np.concatenate([np.linspace(0.0, 40.0, 41), [-3.0, 0.25]])
    ours = exact.attitude(body, SPINS, times)
    assert ours.shape == (len(SPINS), len(times), 4)
    nu = np.abs(exact.parameters(body, SPINS).nu)
    tolerance = 1e-13 * np.maximum(1.0, np.divide(0.01, nu, out=np.ones_like(nu), where=nu > 0))
    error = np.abs(ours - reference_attitude(body, SPINS, times)).max(axis=(1, 2))
    assert np.all(error <= tolerance), (error / tolerance).max()
    np.testing.assert_allclose(ours[:, 0], np.tile([1.0, 0.0, 0.0, 0.0], (len(SPINS), 1)), rtol=0, atol=1e-15)


def test_one_trajectory_is_evaluated_in_parallel_over_its_times_as_a_whole():
    """exact.attitude of one spin at many times (tumble check's reference) runs over (sample, time) pairs: the values
    do not depend on the batch."""
    times = np.linspace(0.0, 30.0, 3001)
    whole = exact.attitude((1.0, 2.0, 3.0), SPINS[25], times)
    np.testing.assert_array_equal(whole[1234], exact.attitude((1.0, 2.0, 3.0), SPINS[25], times[1234]))
