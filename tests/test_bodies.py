"""Body: validation of principal moments and the inertia-tensor round trip."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tumble.physics.bodies import Body, as_moments, validate_moments


def random_rotation(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def test_body_keeps_moments_in_the_order_given():
    np.testing.assert_array_equal(Body(3.0, 1.0, 2.0).moments, [3.0, 1.0, 2.0])


def test_moments_and_axes_are_read_only_copies():
    body = Body(1.0, 2.0, 3.0)
    body.moments[0] = 99.0
    body.axes[0, 0] = 99.0
    np.testing.assert_array_equal(body.moments, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(body.axes, np.eye(3))


@pytest.mark.parametrize("bad", [0.0, -1.0])
def test_non_positive_moment_is_rejected(bad):
    with pytest.raises(ValueError, match="> 0"):
        Body(1.0, bad, 1.5)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_moment_is_rejected(bad):
    with pytest.raises(ValueError, match="finite"):
        Body(1.0, 1.0, bad)


def test_triangle_inequality_violation_is_rejected_with_a_message_that_says_so():
    with pytest.raises(ValueError, match="triangle inequality"):
        Body(1.0, 1.0, 2.5)


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (0.25, 0.25, 0.5), (0.1, 0.2, 0.30000000000000004)])
def test_flat_lamina_equality_is_accepted(moments):
    Body(*moments)
    validate_moments(moments)


def test_lamina_equality_accepted_when_computed_in_floating_point():
    i1, i2 = 0.1, 0.7
    Body(i1, i2, i1 + i2)
    Body(i1 + i2, i1, i2)


@pytest.mark.parametrize("shape", [(), (2,), (4,), (3, 2)])
def test_validate_moments_rejects_wrong_shapes(shape):
    with pytest.raises(ValueError, match="shape"):
        validate_moments(np.ones(shape))


def test_validate_moments_rejects_non_numbers():
    with pytest.raises(ValueError, match="numbers"):
        validate_moments(["a", "b", "c"])


def test_validate_moments_accepts_stacks_and_names_the_argument():
    arr = validate_moments(np.ones((4, 5, 3)))
    assert arr.shape == (4, 5, 3) and arr.dtype == np.float64
    bad = np.ones((4, 3))
    bad[2] = (1.0, 1.0, 3.0)
    with pytest.raises(ValueError, match="my_moments .*triangle"):
        validate_moments(bad, name="my_moments")


def test_as_moments_accepts_body_or_array():
    np.testing.assert_array_equal(as_moments(Body(1.0, 2.0, 2.5)), [1.0, 2.0, 2.5])
    assert as_moments([[1.0, 1.0, 1.0], [1.0, 2.0, 2.5]]).shape == (2, 3)


@pytest.mark.parametrize("axes", [np.ones((3, 3)), np.eye(2), np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan)])
def test_axes_must_be_a_proper_rotation(axes):
    with pytest.raises(ValueError, match="axes"):
        Body(1.0, 2.0, 2.5, axes=axes)


def test_from_tensor_rejects_bad_tensors():
    with pytest.raises(ValueError, match="shape"):
        Body.from_tensor(np.eye(2))
    with pytest.raises(ValueError, match="finite"):
        Body.from_tensor(np.diag([1.0, np.nan, 1.0]))
    with pytest.raises(ValueError, match="symmetric"):
        Body.from_tensor([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(ValueError, match="positive definite"):
        Body.from_tensor(np.diag([1.0, 1.0, -0.5]))
    with pytest.raises(ValueError, match="triangle"):
        Body.from_tensor(np.diag([1.0, 1.0, 3.0]))


def test_from_tensor_of_a_diagonal_tensor_sorts_the_moments_and_permutes_the_axes():
    body = Body.from_tensor(np.diag([3.0, 1.0, 2.5]))
    np.testing.assert_allclose(body.moments, [1.0, 2.5, 3.0])
    np.testing.assert_allclose(np.abs(body.axes), [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-15)
    assert np.linalg.det(body.axes) == pytest.approx(1.0)


# Principal moments that form a rigid body: I = (a + b, a + c, b + c) with a, b, c >= 0 satisfies the
# triangle inequality (these are the second moments of a mass distribution along three axes).
second_moments = st.tuples(*[st.floats(0.05, 10.0)] * 3)


@settings(max_examples=60, deadline=None)
@given(abc=second_moments, seed=st.integers(0, 2**32 - 1))
def test_from_tensor_round_trip_recovers_moments_right_handed_axes_and_tensor(abc, seed):
    a, b, c = abc
    moments = np.array([b + c, a + c, a + b])
    rot = random_rotation(np.random.default_rng(seed))
    tensor = rot @ np.diag(moments) @ rot.T
    body = Body.from_tensor(tensor)
    np.testing.assert_allclose(body.moments, np.sort(moments), rtol=1e-12, atol=1e-13 * moments.max())
    axes = body.axes
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(body.tensor(), tensor, rtol=0, atol=1e-12 * moments.max())
    # Each column is an eigenvector for its moment.
    np.testing.assert_allclose(tensor @ axes, axes * body.moments, atol=1e-11 * moments.max())


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, 3, elements=st.floats(-1e3, 1e3, allow_nan=False)))
def test_invalid_moments_always_raise_value_error_never_anything_else(moments):
    sorted_m = np.sort(moments)
    gap = sorted_m[0] + sorted_m[1] - sorted_m[2]
    assume(abs(gap) > 1e-12 * abs(sorted_m[2]) or gap == 0)  # away from the rounding slack at equality
    valid = sorted_m[0] > 0 and gap >= 0
    if valid:
        Body(*moments)
    else:
        with pytest.raises(ValueError):
            Body(*moments)


def test_bodies_compare_and_hash_by_moments_and_axes():
    assert Body(1.0, 2.0, 2.5) == Body(1.0, 2.0, 2.5, name="other label")
    assert hash(Body(1.0, 2.0, 2.5)) == hash(Body(1.0, 2.0, 2.5))
    assert Body(1.0, 2.0, 2.5) != Body(2.0, 1.0, 2.5)
    assert "name='x'" in repr(Body(1.0, 2.0, 2.5, name="x"))
