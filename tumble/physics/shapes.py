"""Principal moments of inertia of common shapes, as :class:`~tumble.physics.bodies.Body` objects.

Every constructor takes dimensions in m and masses in kg, checks them (positive and finite; a
``ValueError`` names the offending argument) and returns a :class:`~tumble.physics.bodies.Body` with ``name`` set.
Moments are about the centre of mass unless an ``about`` argument says otherwise.

Axisymmetric shapes (rod, disc, cylinder, cone) have their symmetry axis along ``z`` and list its moment
last: ``(I_perp, I_perp, I_axis)``, so ``axis=3`` is the symmetry axis everywhere in tumble. Box-like
shapes (cuboid, ellipsoid) list the moments about ``x``, ``y``, ``z``. Shapes built from a full inertia
tensor (:func:`cube_about_edge`, :func:`t_handle`) go through :meth:`Body.from_tensor`, whose moments are
ascending and whose ``axes`` give the principal directions.

Formulas: standard results, and the problem sheet "Part 8: Rigid Body Dynamics" (problems 1, 3, 4 and 5:
rod, cone about its apex, cube about an edge by the parallel-axis theorem, loaded die), kept in the
project as ``shared/seeds/002_27b65ae709d61d56.txt``.

The building blocks :func:`parallel_axis` and :func:`composite` are public so that other composite bodies
can be assembled the same way as the T-handle.
"""

from __future__ import annotations

import math

import numpy as np

from .bodies import Body

__all__ = [
    "composite",
    "cone",
    "cube_about_edge",
    "cuboid",
    "cylinder",
    "disc",
    "ellipsoid",
    "loaded_die",
    "parallel_axis",
    "rod",
    "sphere",
    "t_handle",
]

# Default slenderness of a rod: radius = length * _ROD_SLENDERNESS (see :func:`rod`).
_ROD_SLENDERNESS = 1e-2


def _positive(value, name):
    """``value`` as a float, or a ValueError naming ``name`` if it is not a positive finite number."""
    try:
        x = float(value)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}") from err
    if not math.isfinite(x) or x <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return x


def _choice(value, name, allowed):
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, allowed))}; got {value!r}")
    return value


def parallel_axis(tensor, mass, displacement):
    """Shift an inertia tensor from the centre of mass to another point (parallel-axis theorem).

    ``I_ij = I_cm,ij + M (|d|² δ_ij − d_i d_j)`` (problem sheet, problems 4 and 5).

    Parameters
    ----------
    tensor : array_like, shape (3, 3)
        Inertia tensor about the centre of mass, kg m².
    mass : float
        Mass, kg.
    displacement : array_like, shape (3,)
        Vector ``d`` from the new reference point to the centre of mass, m (the sign does not matter).

    Returns
    -------
    ndarray, shape (3, 3)
        Inertia tensor about the new point, kg m².

    See Also
    --------
    tumble.shapes.composite : Parts joined into one body, each shifted by this theorem.
    tumble.Body.from_tensor : Principal moments and axes of a tensor.

    Examples
    --------
    A rod of 3 kg and 2 m along ``z``, from its centre to one end (``ML²/3 = 4`` kg m² across it):

    >>> import numpy as np
    >>> from tumble import shapes
    >>> rod = shapes.rod(3.0, 2.0, radius=1e-3).tensor()
    >>> np.round(np.diag(shapes.parallel_axis(rod, 3.0, (0.0, 0.0, 1.0))), 4)
    array([4., 4., 0.])
    """
    t = np.asarray(tensor, dtype=float)
    d = np.asarray(displacement, dtype=float)
    if t.shape != (3, 3):
        raise ValueError(f"tensor must have shape (3, 3), got {t.shape}")
    if d.shape != (3,):
        raise ValueError(f"displacement must have shape (3,), got {d.shape}")
    return t + float(mass) * (np.dot(d, d) * np.eye(3) - np.outer(d, d))


def composite(parts):
    """Mass, centre of mass and inertia tensor of a body made of rigidly joined parts.

    Each part's tensor (about its own centre of mass) is shifted to the common centre of mass with
    :func:`parallel_axis` and the shifted tensors are summed.

    Parameters
    ----------
    parts : iterable of (mass, centre, tensor)
        ``mass`` in kg; ``centre``, shape (3,), the part's centre of mass in a common frame, m;
        ``tensor``, shape (3, 3), the part's inertia tensor about its own centre of mass in that frame,
        kg m² (for a Body use ``body.tensor()``).

    Returns
    -------
    mass : float
        Total mass, kg.
    centre : ndarray, shape (3,)
        Centre of mass of the whole, m.
    tensor : ndarray, shape (3, 3)
        Inertia tensor of the whole about ``centre``, kg m²; pass it to :meth:`Body.from_tensor`.

    See Also
    --------
    tumble.shapes.parallel_axis : The shift of one part's tensor.
    tumble.Body.from_tensor : The body of the whole, from its tensor.

    Examples
    --------
    Two balls of 1 kg and radius 0.1 m, 1 m apart along ``x`` (a dumbbell):

    >>> import numpy as np
    >>> from tumble import shapes
    >>> ball = shapes.sphere(1.0, 0.1).tensor()
    >>> mass, centre, tensor = shapes.composite([(1.0, (-0.5, 0.0, 0.0), ball), (1.0, (0.5, 0.0, 0.0), ball)])
    >>> mass, centre.tolist()
    (2.0, [0.0, 0.0, 0.0])
    >>> np.round(np.diag(tensor), 4)
    array([0.008, 0.508, 0.508])
    """
    parts = [(_positive(m, "part mass"), np.asarray(c, dtype=float), np.asarray(t, dtype=float))
             for m, c, t in parts]
    if not parts:
        raise ValueError("composite needs at least one part")
    for _, c, t in parts:
        if c.shape != (3,) or t.shape != (3, 3):
            raise ValueError(f"each part needs a centre of shape (3,) and a tensor of shape (3, 3), "
                             f"got {c.shape} and {t.shape}")
    mass = sum(m for m, _, _ in parts)
    centre = sum(m * c for m, c, _ in parts) / mass
    tensor = sum(parallel_axis(t, m, c - centre) for m, c, t in parts)
    return mass, centre, tensor


def rod(mass, length, *, about="centre", radius=None):
    """A slender rod modelled as a thin solid cylinder along ``z``.

    An ideal thin rod has no moment about its own axis, which no :class:`Body` accepts (a body needs
    three positive moments). The rod is therefore a solid cylinder of small ``radius``: axial moment
    ``M r²/2``, perpendicular moments ``M (3r² + L²)/12`` about the centre, plus ``M L²/4`` about an end.
    As ``radius/length → 0`` these tend to the thin-rod results ``ML²/12`` and ``ML²/3`` (problem sheet,
    problem 1); with the default radius ``length/100`` they are within 3e-4 (centre) and 8e-5 (end).

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    length : float
        Length ``L``, m.
    about : {"centre", "end"}
        Reference point: the centre of mass, or one end on the rod's axis (a rod pivoted at its end).
    radius : float, optional
        Radius ``r``, m; default ``length / 100``.

    Returns
    -------
    Body
        Moments ``(I_perp, I_perp, I_axis)``, kg m², symmetry axis along ``z`` (axis 3).

    See Also
    --------
    tumble.shapes.cylinder : A solid cylinder of any proportions.
    tumble.shapes.t_handle : A bar and a stem joined: the Dzhanibekov nut.

    Examples
    --------
    A rod of 3 kg and 2 m: ``ML²/12 = 1`` kg m² about its centre, ``ML²/3 = 4`` about an end:

    >>> from tumble import shapes
    >>> I_perp, _, I_axis = shapes.rod(3.0, 2.0).moments
    >>> round(float(I_perp), 4), round(float(I_axis), 4)
    (1.0003, 0.0006)
    >>> round(float(shapes.rod(3.0, 2.0, about="end").moments[0]), 4)
    4.0003
    """
    m = _positive(mass, "mass")
    length = _positive(length, "length")
    r = length * _ROD_SLENDERNESS if radius is None else _positive(radius, "radius")
    _choice(about, "about", ("centre", "end"))
    perp = m * (3 * r**2 + length**2) / 12
    if about == "end":
        perp = parallel_axis(np.diag([perp, perp, 0.5 * m * r**2]), m, (0.0, 0.0, length / 2))[0, 0]
    return Body(perp, perp, 0.5 * m * r**2, name=f"rod about {about}" if about == "end" else "rod")


def disc(mass, radius):
    """A thin uniform disc (lamina) in the ``xy`` plane.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    radius : float
        Radius ``R``, m.

    Returns
    -------
    Body
        ``(MR²/4, MR²/4, MR²/2)``, kg m²; a flat lamina, so ``I3 = I1 + I2`` exactly.

    See Also
    --------
    tumble.shapes.cylinder : A disc of finite thickness.

    Examples
    --------
    >>> from tumble import shapes
    >>> shapes.disc(4.0, 1.0).moments
    array([1., 1., 2.])
    """
    m = _positive(mass, "mass")
    r = _positive(radius, "radius")
    return Body(m * r**2 / 4, m * r**2 / 4, m * r**2 / 2, name="disc")


def cylinder(mass, radius, height):
    """A uniform solid cylinder with its axis along ``z``, about its centre of mass.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    radius : float
        Radius ``R``, m.
    height : float
        Height (length) ``h``, m.

    Returns
    -------
    Body
        ``(M(3R² + h²)/12, M(3R² + h²)/12, MR²/2)``, kg m².

    See Also
    --------
    tumble.shapes.disc : The thin limit, ``h → 0``.
    tumble.shapes.rod : The slender limit, ``R → 0``.

    Examples
    --------
    >>> from tumble import shapes
    >>> shapes.cylinder(12.0, 1.0, 2.0).moments
    array([7., 7., 6.])
    """
    m = _positive(mass, "mass")
    r = _positive(radius, "radius")
    h = _positive(height, "height")
    perp = m * (3 * r**2 + h**2) / 12
    return Body(perp, perp, m * r**2 / 2, name="cylinder")


def cone(mass, radius, height, *, about="apex"):
    """A uniform solid right circular cone with its axis along ``z``.

    About the apex (a top spinning on its point; problem sheet, problem 3):
    ``I_axis = 3MR²/10``, ``I_perp = 3M(R² + 4h²)/20``. The centre of mass lies on the axis ``3h/4``
    from the apex (``h/4`` above the base); about it, by the parallel-axis theorem,
    ``I_perp = 3M(R²/20 + h²/80)`` and ``I_axis`` is unchanged.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    radius : float
        Radius of the base ``R``, m.
    height : float
        Height ``h``, m.
    about : {"apex", "centre_of_mass"}
        Reference point.

    Returns
    -------
    Body
        ``(I_perp, I_perp, I_axis)``, kg m².

    See Also
    --------
    tumble.models.HeavyTop : A top spinning on its point under gravity.
    tumble.shapes.cylinder : A solid cylinder.

    Examples
    --------
    >>> from tumble import shapes
    >>> shapes.cone(1.0, 0.5, 2.0).moments.round(4)
    array([2.4375, 2.4375, 0.075 ])
    >>> shapes.cone(1.0, 0.5, 2.0, about="centre_of_mass").moments.round(4)
    array([0.1875, 0.1875, 0.075 ])
    """
    m = _positive(mass, "mass")
    r = _positive(radius, "radius")
    h = _positive(height, "height")
    _choice(about, "about", ("apex", "centre_of_mass"))
    axial = 3 * m * r**2 / 10
    perp = 3 * m * (r**2 + 4 * h**2) / 20
    if about == "centre_of_mass":
        # Inverse parallel-axis shift from the apex to the centre of mass, 3h/4 along the axis.
        perp -= m * (3 * h / 4) ** 2
    return Body(perp, perp, axial, name=f"cone about {about.replace('_', ' ')}")


def sphere(mass, radius):
    """A uniform solid sphere: ``2MR²/5`` about every axis.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    radius : float
        Radius ``R``, m.

    Returns
    -------
    Body

    See Also
    --------
    tumble.shapes.ellipsoid : A solid ellipsoid, of which the sphere is the round case.

    Examples
    --------
    Every spin of a sphere is steady (its three moments are equal):

    >>> from tumble import shapes
    >>> shapes.sphere(5.0, 1.0).moments
    array([2., 2., 2.])
    """
    m = _positive(mass, "mass")
    r = _positive(radius, "radius")
    i = 2 * m * r**2 / 5
    return Body(i, i, i, name="sphere")


def ellipsoid(mass, a, b, c):
    """A uniform solid ellipsoid with semi-axes ``a``, ``b``, ``c`` along ``x``, ``y``, ``z``.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    a, b, c : float
        Semi-axes, m.

    Returns
    -------
    Body
        ``(M(b² + c²)/5, M(a² + c²)/5, M(a² + b²)/5)``, kg m².

    See Also
    --------
    tumble.shapes.sphere : The round case.
    tumble.shapes.cuboid : A box of the same edges' proportions.

    Examples
    --------
    >>> from tumble import shapes
    >>> shapes.ellipsoid(5.0, 1.0, 2.0, 3.0).moments
    array([13., 10.,  5.])
    """
    m = _positive(mass, "mass")
    a, b, c = (_positive(v, n) for v, n in ((a, "a"), (b, "b"), (c, "c")))
    return Body(m * (b**2 + c**2) / 5, m * (a**2 + c**2) / 5, m * (a**2 + b**2) / 5, name="ellipsoid")


def cuboid(mass, a, b, c):
    """A uniform solid rectangular box with edges ``a``, ``b``, ``c`` along ``x``, ``y``, ``z``.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    a, b, c : float
        Edge lengths (full edges, not half-edges), m.

    Returns
    -------
    Body
        ``(M(b² + c²)/12, M(a² + c²)/12, M(a² + b²)/12)``, kg m², about the centre of mass.

    See Also
    --------
    tumble.shapes.cube_about_edge : A cube about one of its edges.
    tumble.shapes.ellipsoid : A solid ellipsoid.

    Examples
    --------
    A box of 12 kg with edges 1, 2 and 3 m; its intermediate axis is ``y`` (axis 2):

    >>> from tumble import shapes
    >>> shapes.cuboid(12.0, 1.0, 2.0, 3.0).moments
    array([13., 10.,  5.])
    """
    m = _positive(mass, "mass")
    a, b, c = (_positive(v, n) for v, n in ((a, "a"), (b, "b"), (c, "c")))
    return Body(m * (b**2 + c**2) / 12, m * (a**2 + c**2) / 12, m * (a**2 + b**2) / 12, name="cuboid")


def cube_about_edge(mass, a):
    """A uniform cube rotating about one of its edges (problem sheet, problem 4).

    The cube occupies ``[0, a]³`` around the edge along ``z`` through the origin. Its tensor about the
    centre, ``Ma²/6 · 1``, is shifted by the parallel-axis theorem with ``d = (a/2, a/2, 0)``:

    ``I = Ma² [[5/12, −1/4, 0], [−1/4, 5/12, 0], [0, 0, 2/3]]``,

    and diagonalised: principal moments ``Ma² (1/6, 2/3, 2/3)``, the smallest about the face diagonal
    direction ``(1, 1, 0)/√2``. ``body.tensor()`` gives the tensor above back.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    a : float
        Edge length, m.

    Returns
    -------
    Body
        Ascending moments with principal ``axes`` in the cube's frame.

    See Also
    --------
    tumble.shapes.cuboid : A box about its centre of mass.
    tumble.shapes.parallel_axis : The shift from the centre of mass to the edge.

    Examples
    --------
    >>> from tumble import shapes
    >>> shapes.cube_about_edge(6.0, 1.0).moments.round(4)
    array([1., 4., 4.])
    """
    m = _positive(mass, "mass")
    a = _positive(a, "a")
    centre = cuboid(m, a, a, a).tensor()
    return Body.from_tensor(parallel_axis(centre, m, (a / 2, a / 2, 0.0)), name="cube about edge")


def _box_density_moments(density, half_side, order=8):
    """Integrals of ``ρ``, ``ρ r`` and ``ρ r rᵀ`` over the cube ``[−b, b]³`` by Gauss–Legendre quadrature.

    The product rule with ``order`` points per direction is exact for polynomial integrands of degree
    ``2·order − 1`` in each coordinate, so for polynomial densities these are the exact integrals.
    """
    nodes, weights = np.polynomial.legendre.leggauss(order)
    x = half_side * nodes
    w = half_side * weights
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    W = w[:, None, None] * w[None, :, None] * w[None, None, :]
    rho = W * np.asarray(density(X, Y, Z), dtype=float) * np.ones_like(X)
    r = np.stack([X, Y, Z])
    mass = rho.sum()
    first = np.einsum("ijk,aijk->a", rho, r)
    second = np.einsum("ijk,aijk,bijk->ab", rho, r, r)
    return mass, first, second


def loaded_die(mass, half_side, *, load=0.5):
    """A loaded die: a cube of side ``2b`` whose density grows linearly towards one face.

    Density ``ρ(z) = ρ0 (1 + load · z/b)`` on ``[−b, b]³`` (problem sheet, problem 5), heavier towards
    ``+z``. The integrals ``M = ∫ρ dV``, ``M R = ∫ρ r dV`` and ``I_c = ∫ρ (r² 1 − r rᵀ) dV`` about the
    cube's centre are computed by exact (Gauss–Legendre) quadrature, then shifted to the centre of mass
    with the parallel-axis theorem. In closed form the centre of mass is ``load · b/3`` above the centre,
    and ``I = M b² (2/3 − load²/9, 2/3 − load²/9, 2/3)``.

    The default ``load = 1/2``, i.e. ``ρ = ρ0 (1 + z/(2b))``, reproduces the problem sheet's stated
    results: centre of mass ``b/6`` above the centre and ``I = M b² (23/36, 23/36, 2/3)``. The sheet prints
    the density as ``ρ0 (1 + z/b)`` (``load = 1``), but integrating that exactly gives a centre of mass at
    ``b/3`` and ``M b² (5/9, 5/9, 2/3)``; its ``b/6`` corresponds to ``load = 1/2``.

    Parameters
    ----------
    mass : float
        Mass ``M``, kg.
    half_side : float
        Half the edge length, ``b``, m.
    load : float
        Relative density excess at the heavy face, ``ρ(b)/ρ0 − 1``; ``0 <= load <= 1`` (0 is a fair die;
        1 makes the density vanish at the light face).

    Returns
    -------
    Body
        Moments about the centre of mass, kg m²; a symmetric top about ``z`` (axis 3).

    See Also
    --------
    tumble.shapes.cuboid : The fair die (uniform density), ``load = 0``.
    tumble.theory.symmetric_top_precession : How a symmetric top's spin precesses.

    Examples
    --------
    The default load gives the problem sheet's ``M b² (23/36, 23/36, 2/3)``:

    >>> from tumble import shapes
    >>> shapes.loaded_die(36.0, 1.0).moments.round(6)
    array([23., 23., 24.])
    """
    m = _positive(mass, "mass")
    b = _positive(half_side, "half_side")
    try:
        load = float(load)
    except (TypeError, ValueError) as err:
        raise ValueError(f"load must be a number in [0, 1], got {load!r}") from err
    if not 0.0 <= load <= 1.0:
        raise ValueError(f"load must be a number in [0, 1] (density non-negative), got {load!r}")

    def density(x, y, z):  # ρ/ρ0
        return 1.0 + load * z / b

    unit_mass, first, second = _box_density_moments(density, b, order=4)
    scale = m / unit_mass  # ρ0
    centre = first / unit_mass
    second = scale * second
    about_centre = np.trace(second) * np.eye(3) - second
    # Parallel-axis theorem backwards: I_centre = I_com + M(d²δ − d dᵀ), so subtract the shift term.
    about_com = about_centre - parallel_axis(np.zeros((3, 3)), m, centre)
    moments = np.diag(about_com)
    return Body(*moments, name="loaded die")


def t_handle(mass=0.05, *, bar_length=0.08, bar_radius=0.005, stem_length=0.04, stem_radius=0.005):
    """A T-handle (the Dzhanibekov "wing nut"): a bar with a stem fixed perpendicular at its middle.

    Both parts are uniform solid cylinders of the same density; ``mass`` is shared in proportion to their
    volumes. The bar lies along ``x`` centred at the origin; the stem lies along ``z``, from the bar's
    surface ``z = −bar_radius`` to ``z = −(bar_radius + stem_length)`` (the small gap between the curved
    surface and the stem's flat end is neglected). Each cylinder's tensor is shifted to the common centre of
    mass with :func:`parallel_axis` (:func:`composite`) and the sum diagonalised.

    With the default dimensions (bar 80 mm × Ø10 mm, stem 40 mm × Ø10 mm, 50 g) the principal moments are
    about 9.7e-6, 1.8e-5 and 2.7e-5 kg m²: the smallest about the bar's axis (``x``), the intermediate
    about the stem's axis (``z``) — the unstable spin of the famous demonstration — and the largest about
    ``y``, normal to the plane of the T. Other dimensions may order them differently: the moments are
    computed, not assumed; read ``body.axes`` to see which direction is which.

    Parameters
    ----------
    mass : float
        Total mass, kg.
    bar_length, bar_radius : float
        The handle bar (the "wings"), m.
    stem_length, stem_radius : float
        The stem (the "nut"), m.

    Returns
    -------
    Body
        Ascending moments about the centre of mass, kg m², with principal ``axes`` in the frame above.

    See Also
    --------
    tumble.shapes.composite : How the bar and the stem are joined.
    tumble.attitude_trace : The flipping handle's orientation in space.

    Examples
    --------
    A spin about the handle's intermediate axis flips:

    >>> from tumble import shapes, theory
    >>> handle = shapes.t_handle()
    >>> handle.name, theory.linear(handle, 2)[0]
    ('T-handle', 'exponential')
    """
    m = _positive(mass, "mass")
    lb = _positive(bar_length, "bar_length")
    rb = _positive(bar_radius, "bar_radius")
    ls = _positive(stem_length, "stem_length")
    rs = _positive(stem_radius, "stem_radius")
    vol_bar, vol_stem = rb**2 * lb, rs**2 * ls
    m_bar = m * vol_bar / (vol_bar + vol_stem)
    m_stem = m - m_bar
    bar = cylinder(m_bar, rb, lb).moments  # axis along z in its own frame: reorder to lie along x
    bar_tensor = np.diag([bar[2], bar[0], bar[1]])
    stem_tensor = np.diag(cylinder(m_stem, rs, ls).moments)
    parts = [
        (m_bar, (0.0, 0.0, 0.0), bar_tensor),
        (m_stem, (0.0, 0.0, -(rb + ls / 2)), stem_tensor),
    ]
    _, _, tensor = composite(parts)
    return Body.from_tensor(tensor, name="T-handle")
