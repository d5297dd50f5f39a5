"""Shapes: problem-sheet inertia values, parallel-axis composition, validation of dimensions.

Problem sheet "Part 8: Rigid Body Dynamics" (shared/seeds/002_27b65ae709d61d56.txt): problem 1 (rod),
3 (cone about its apex), 4 (cube about an edge), 5 (loaded die).
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tumble.physics import shapes
from tumble.physics.bodies import Body

M, L = 2.5, 1.7  # arbitrary mass (kg) and length (m) so that factors of M and L are checked too


def test_thin_rod_about_its_centre_is_ml2_over_12():
    body = shapes.rod(M, L, radius=1e-6 * L)
    np.testing.assert_allclose(body.moments[:2], M * L**2 / 12, rtol=1e-11)


def test_thin_rod_about_an_end_is_ml2_over_3():
    body = shapes.rod(M, L, about="end", radius=1e-6 * L)
    np.testing.assert_allclose(body.moments[:2], M * L**2 / 3, rtol=1e-11)


def test_default_rod_is_slender_cylinder_close_to_the_thin_limit():
    centre, end = shapes.rod(M, L), shapes.rod(M, L, about="end")
    r = L / 100
    np.testing.assert_allclose(centre.moments, [M * (3 * r**2 + L**2) / 12] * 2 + [M * r**2 / 2])
    np.testing.assert_allclose(centre.moments[:2], M * L**2 / 12, rtol=3e-4)
    np.testing.assert_allclose(end.moments[:2], M * L**2 / 3, rtol=1e-4)
    assert centre.moments[2] == end.moments[2] == pytest.approx(M * r**2 / 2)


def test_cone_about_apex_matches_problem_sheet():
    R, h = 0.4, 1.3
    body = shapes.cone(M, R, h, about="apex")
    np.testing.assert_allclose(body.moments, [3 * M * (R**2 + 4 * h**2) / 20] * 2 + [3 * M * R**2 / 10])
    assert body.name == "cone about apex"


def test_cone_about_centre_of_mass_is_the_apex_tensor_shifted_by_three_quarters_of_the_height():
    R, h = 0.4, 1.3
    body = shapes.cone(M, R, h, about="centre_of_mass")
    np.testing.assert_allclose(body.moments, [3 * M * (R**2 / 20 + h**2 / 80)] * 2 + [3 * M * R**2 / 10])


def test_cube_about_edge_tensor_matches_problem_sheet():
    a = 0.3
    body = shapes.cube_about_edge(M, a)
    expected = M * a**2 * np.array([[5 / 12, -1 / 4, 0], [-1 / 4, 5 / 12, 0], [0, 0, 2 / 3]])
    np.testing.assert_allclose(body.tensor(), expected, atol=1e-14)
    np.testing.assert_allclose(body.moments, M * a**2 * np.array([1 / 6, 2 / 3, 2 / 3]), rtol=1e-13)
    # The smallest moment is about the face diagonal (1, 1, 0)/sqrt(2).
    np.testing.assert_allclose(np.abs(body.axes[:, 0]), [2**-0.5, 2**-0.5, 0], atol=1e-14)


def test_loaded_die_matches_problem_sheet_23_36_about_centre_of_mass():
    b = 0.006
    body = shapes.loaded_die(M, b)
    np.testing.assert_allclose(body.moments, M * b**2 * np.array([23 / 36, 23 / 36, 2 / 3]), rtol=1e-13)
    np.testing.assert_array_equal(body.axes, np.eye(3))


@pytest.mark.parametrize("load", [0.0, 0.25, 0.5, 1.0])
def test_loaded_die_agrees_with_brute_force_integration(load):
    """Midpoint-rule integration of the density on a fine grid, then the parallel-axis theorem."""
    b, n = 1.0, 60
    x = (np.arange(n) + 0.5) / n * 2 * b - b
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    rho = 1 + load * Z / b
    mass = rho.sum()
    z_cm = (rho * Z).sum() / mass
    assert z_cm == pytest.approx(load * b / 3, rel=1e-3, abs=1e-12)
    ixx = (rho * (Y**2 + (Z - z_cm) ** 2)).sum() / mass
    izz = (rho * (X**2 + Y**2)).sum() / mass
    body = shapes.loaded_die(1.0, b, load=load)
    np.testing.assert_allclose(body.moments, [ixx, ixx, izz], rtol=1e-3)
    np.testing.assert_allclose(body.moments, [2 / 3 - load**2 / 9] * 2 + [2 / 3], rtol=1e-13)


def test_loaded_die_rejects_load_outside_zero_to_one():
    with pytest.raises(ValueError, match="load"):
        shapes.loaded_die(1.0, 1.0, load=1.5)


def test_disc_is_a_flat_lamina():
    R = 0.2
    body = shapes.disc(M, R)
    np.testing.assert_allclose(body.moments, M * R**2 * np.array([1 / 4, 1 / 4, 1 / 2]))
    assert body.moments[2] == body.moments[0] + body.moments[1]


def test_cylinder_sphere_ellipsoid_cuboid_standard_moments():
    R, h = 0.2, 0.9
    np.testing.assert_allclose(shapes.cylinder(M, R, h).moments,
                               [M * (3 * R**2 + h**2) / 12] * 2 + [M * R**2 / 2])
    np.testing.assert_allclose(shapes.sphere(M, R).moments, [2 * M * R**2 / 5] * 3)
    a, b, c = 0.3, 0.5, 0.7
    np.testing.assert_allclose(shapes.ellipsoid(M, a, b, c).moments,
                               M / 5 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2]))
    np.testing.assert_allclose(shapes.cuboid(M, a, b, c).moments,
                               M / 12 * np.array([b**2 + c**2, a**2 + c**2, a**2 + b**2]))


def test_ellipsoid_with_equal_semi_axes_is_a_sphere():
    np.testing.assert_allclose(shapes.ellipsoid(M, 0.3, 0.3, 0.3).moments, shapes.sphere(M, 0.3).moments)


def test_every_shape_sets_a_name():
    bodies = [shapes.rod(1, 1), shapes.disc(1, 1), shapes.cylinder(1, 1, 1), shapes.cone(1, 1, 1),
              shapes.sphere(1, 1), shapes.ellipsoid(1, 1, 2, 3), shapes.cuboid(1, 1, 2, 3),
              shapes.cube_about_edge(1, 1), shapes.loaded_die(1, 1), shapes.t_handle()]
    for body in bodies:
        assert isinstance(body, Body) and body.name


@pytest.mark.parametrize("bad", [0, -1.0, np.nan, np.inf, "x", [1.0, 2.0]])
@pytest.mark.parametrize(
    "call, argument",
    [
        (lambda v: shapes.rod(v, 1.0), "mass"),
        (lambda v: shapes.rod(1.0, v), "length"),
        (lambda v: shapes.rod(1.0, 1.0, radius=v), "radius"),
        (lambda v: shapes.disc(1.0, v), "radius"),
        (lambda v: shapes.cylinder(1.0, 1.0, v), "height"),
        (lambda v: shapes.cone(1.0, v, 1.0), "radius"),
        (lambda v: shapes.sphere(v, 1.0), "mass"),
        (lambda v: shapes.ellipsoid(1.0, 1.0, v, 1.0), "b"),
        (lambda v: shapes.cuboid(1.0, 1.0, 1.0, v), "c"),
        (lambda v: shapes.cube_about_edge(1.0, v), "a"),
        (lambda v: shapes.loaded_die(1.0, v), "half_side"),
        (lambda v: shapes.t_handle(stem_length=v), "stem_length"),
    ],
)
def test_invalid_dimensions_raise_value_error_naming_the_argument(call, argument, bad):
    with pytest.raises(ValueError, match=rf"^{argument} must be"):
        call(bad)


@pytest.mark.parametrize("call", [lambda: shapes.rod(1, 1, about="middle"),
                                  lambda: shapes.cone(1, 1, 1, about="centre")])
def test_unknown_reference_point_is_rejected(call):
    with pytest.raises(ValueError, match="about must be one of"):
        call()


def test_parallel_axis_about_the_centre_of_mass_changes_nothing_and_is_symmetric_in_direction():
    t = np.diag([1.0, 2.0, 2.5])
    np.testing.assert_array_equal(shapes.parallel_axis(t, 3.0, np.zeros(3)), t)
    d = np.array([0.1, -0.4, 0.3])
    np.testing.assert_allclose(shapes.parallel_axis(t, 3.0, d), shapes.parallel_axis(t, 3.0, -d))


def test_composite_of_two_point_like_halves_is_a_dumbbell():
    """Two tiny spheres of mass m at ±d along x: I = 2 m d² about y and z, ~0 about x."""
    m, d, r = 0.5, 1.0, 1e-4
    ball = shapes.sphere(m, r).tensor()
    mass, centre, tensor = shapes.composite([(m, (d, 0, 0), ball), (m, (-d, 0, 0), ball)])
    assert mass == 2 * m
    np.testing.assert_allclose(centre, 0, atol=1e-15)
    i_ball = 2 * ball[0, 0]
    np.testing.assert_allclose(np.diag(tensor), [i_ball, 2 * m * d**2 + i_ball, 2 * m * d**2 + i_ball])
    np.testing.assert_allclose(tensor - np.diag(np.diag(tensor)), 0, atol=1e-15)


def test_composite_of_cylinders_stacked_end_to_end_is_one_longer_cylinder():
    R, h = 0.1, 0.4
    half = np.diag(shapes.cylinder(M / 2, R, h / 2).moments)
    mass, centre, tensor = shapes.composite([(M / 2, (0, 0, 1 + h / 4), half), (M / 2, (0, 0, 1 - h / 4), half)])
    np.testing.assert_allclose(centre, [0, 0, 1])
    np.testing.assert_allclose(tensor, np.diag(shapes.cylinder(M, R, h).moments), rtol=1e-14, atol=1e-16)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.1, 5.0), st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3),
                          st.tuples(*[st.floats(0.1, 3.0)] * 3)), min_size=1, max_size=4))
def test_composite_tensor_does_not_depend_on_the_origin_of_the_frame(parts):
    parts = [(m, np.array(c), shapes.cuboid(m, *edges).tensor()) for m, c, edges in parts]
    shift = np.array([0.7, -1.1, 2.3])
    m1, c1, t1 = shapes.composite(parts)
    m2, c2, t2 = shapes.composite([(m, c + shift, t) for m, c, t in parts])
    assert m1 == pytest.approx(m2)
    np.testing.assert_allclose(c2, c1 + shift, atol=1e-12)
    np.testing.assert_allclose(t2, t1, rtol=1e-10, atol=1e-10 * np.abs(t1).max())
    Body.from_tensor(t1)  # a physical composite always has valid moments


def test_t_handle_has_three_distinct_moments_with_the_stem_axis_intermediate_by_default():
    body = shapes.t_handle()
    i1, i2, i3 = body.moments
    assert i1 < i2 < i3
    assert min(i2 - i1, i3 - i2) > 0.2 * i2  # well separated: a clear intermediate axis
    np.testing.assert_allclose(np.abs(body.axes[:, 0]), [1, 0, 0], atol=1e-12)  # bar axis: smallest
    np.testing.assert_allclose(np.abs(body.axes[:, 1]), [0, 0, 1], atol=1e-12)  # stem axis: intermediate


def test_t_handle_is_the_sum_of_its_two_cylinders_shifted_to_the_common_centre_of_mass():
    mass, lb, rb, ls, rs = 0.2, 0.1, 0.004, 0.05, 0.006
    body = shapes.t_handle(mass, bar_length=lb, bar_radius=rb, stem_length=ls, stem_radius=rs)
    vb, vs = rb**2 * lb, rs**2 * ls
    mb, ms = mass * vb / (vb + vs), mass * vs / (vb + vs)
    zs = -(rb + ls / 2)
    zc = ms * zs / mass
    db, ds = -zc, zs - zc  # offsets of the parts from the centre of mass along z
    ixx = mb * rb**2 / 2 + ms * (3 * rs**2 + ls**2) / 12 + mb * db**2 + ms * ds**2
    iyy = mb * (3 * rb**2 + lb**2) / 12 + ms * (3 * rs**2 + ls**2) / 12 + mb * db**2 + ms * ds**2
    izz = mb * (3 * rb**2 + lb**2) / 12 + ms * rs**2 / 2
    np.testing.assert_allclose(body.moments, np.sort([ixx, iyy, izz]), rtol=1e-12)
