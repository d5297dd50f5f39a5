"""Unit quaternions of rotations, scalar first, vectorised over leading axes (numpy only).

``q = (q0, q1, q2, q3) = (cos(a/2), sin(a/2) n)`` turns vectors by the angle ``a`` about the unit vector
``n``: ``v' = q v q*``. An attitude ``q`` of tumble is the body-to-space rotation: ``v_space = q v_body q*``.
``q`` and ``-q`` are the same rotation.
"""

import numpy as np

__all__ = ["about_axis", "angle_between", "conjugate", "product", "rotate"]


def product(a, b):
    """Hamilton product ``a ⊗ b`` (the rotation ``b`` first, then ``a``), shapes broadcast, last axis 4.

    See Also
    --------
    tumble.rotations.conjugate : The inverse rotation.
    tumble.rotations.about_axis : A rotation by an angle about an axis.

    Examples
    --------
    Two quarter turns about ``x`` make a half turn:

    >>> import numpy as np
    >>> from tumble import rotations
    >>> quarter = rotations.about_axis(np.pi / 2, 0)
    >>> half = rotations.product(quarter, quarter)
    >>> round(float(rotations.angle_between(half, rotations.about_axis(np.pi, 0))), 12)
    0.0
    """
    a0, a1, a2, a3 = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    b0, b1, b2, b3 = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack([a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
                     a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
                     a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
                     a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0], axis=-1)


def conjugate(q):
    """``q*``: the inverse rotation of a unit quaternion.

    See Also
    --------
    tumble.rotations.product : ``q ⊗ q*`` is the identity.

    Examples
    --------
    >>> from tumble import rotations
    >>> q = rotations.about_axis(0.7, (0.0, 1.0, 1.0))
    >>> rotations.product(q, rotations.conjugate(q)).round(12)
    array([1., 0., 0., 0.])
    """
    q = np.array(q, dtype=float)
    q[..., 1:] *= -1.0
    return q


def rotate(q, v):
    """``q v q*`` for vectors ``v`` (last axis 3), shapes broadcast.

    See Also
    --------
    tumble.rotations.about_axis : The quaternion of a rotation.
    tumble.integrate : ``attitude=True``: the body-to-space quaternion over time.

    Examples
    --------
    A quarter turn about ``x`` takes ``y`` to ``z`` and ``z`` to ``−y``:

    >>> import numpy as np
    >>> from tumble import rotations
    >>> q = rotations.about_axis(np.pi / 2, 0)
    >>> rotations.rotate(q, [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).round(12)
    array([[ 0.,  0.,  1.],
           [ 0., -1.,  0.]])
    """
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    s, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + s * t + np.cross(u, t)


def about_axis(angle, axis):
    """Quaternion of the rotation by ``angle`` (rad) about ``axis`` (a vector, normalised here, or 0, 1, 2).

    See Also
    --------
    tumble.rotations.rotate : Turn vectors by it.
    tumble.rotations.product : Compose rotations.

    Examples
    --------
    A quarter turn about ``z`` (index 2) takes ``x`` to ``y``:

    >>> import numpy as np
    >>> from tumble import rotations
    >>> q = rotations.about_axis(np.pi / 2, 2)
    >>> q.round(4)
    array([0.7071, 0.    , 0.    , 0.7071])
    >>> rotations.rotate(q, (1.0, 0.0, 0.0)).round(12)
    array([0., 1., 0.])
    """
    angle = np.asarray(angle, dtype=float)
    if isinstance(axis, (int, np.integer)):
        n = np.zeros(3)
        n[axis] = 1.0
    else:
        n = np.asarray(axis, dtype=float)
        norm = np.linalg.norm(n, axis=-1, keepdims=True)
        if not (np.isfinite(norm) & (norm > 0)).all():
            raise ValueError(f"axis must be a non-zero, finite vector, got {n.tolist()}")
        n = n / norm
    half = 0.5 * angle[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * n], axis=-1)


def angle_between(a, b):
    """Angle (rad, in [0, pi]) of the rotation that takes attitude ``b`` to attitude ``a``; 0 when they
    are the same rotation (``a = ±b``).

    See Also
    --------
    tumble.check : Compares a recorded attitude with the exact one by this angle.
    tumble.exact.attitude : The exact attitude.

    Examples
    --------
    >>> from tumble import rotations
    >>> a, b = rotations.about_axis(0.3, (1.0, 1.0, 0.0)), rotations.about_axis(0.1, (1.0, 1.0, 0.0))
    >>> round(float(rotations.angle_between(a, b)), 12), round(float(rotations.angle_between(a, -a)), 12)
    (0.2, 0.0)
    """
    d = product(a, conjugate(b))
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))
