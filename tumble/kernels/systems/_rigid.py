"""What every system's constants begin with: the rigid body's moments and Euler coefficients."""

import numpy as np

__all__ = ["RIGID_BODY", "rigid_body"]

#: The first fields of every system's ``Constants``: the moments ``i1 i2 i3`` (kg m²) and ``a_i = (I_j − I_k)/I_i``.
RIGID_BODY = ("i1", "i2", "i3", "a1", "a2", "a3")


def rigid_body(moments):
    """The :data:`RIGID_BODY` values of moments ``(I1, I2, I3)`` (kg m²), as plain floats."""
    i1, i2, i3 = (float(x) for x in np.asarray(moments, dtype=float))
    return i1, i2, i3, (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3
