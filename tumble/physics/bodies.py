"""Rigid bodies: principal moments of inertia, principal axes, and their validation.

The lowest layer of tumble. A :class:`Body` is three principal moments ``(I1, I2, I3)`` in kg m² (any
order) and, when it was built from a full inertia tensor, the principal axes in the frame of that tensor.
Everything above this module works in the principal-axis (body) frame.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Body", "as_moments", "finite_array", "moment_unit", "one_body", "spin_vectors", "validate_moments"]

# A flat lamina has I3 = I1 + I2 exactly; moments computed in floating point may miss the equality by a
# few ulps, so the triangle inequality is checked with this relative slack.
_TRIANGLE_SLACK = 16 * np.finfo(float).eps


def validate_moments(moments, *, name="moments"):
    """Check principal moments and return them as a float64 array.

    Parameters
    ----------
    moments : array_like, shape (..., 3)
        Principal moments of inertia, kg m², in any order.
    name : str
        How the caller calls this argument in error messages.

    Returns
    -------
    ndarray, shape (..., 3), float64

    Raises
    ------
    ValueError
        If the last axis is not of length 3, a moment is not finite or not positive, or the moments violate
        the triangle inequality ``Ia + Ib >= Ic`` (equality, a flat lamina, is allowed).
    """
    try:
        arr = np.asarray(moments, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name} must be numbers, got {moments!r}") from err
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3) (three principal moments), got shape {arr.shape}")
    if arr.ndim == 1 and _one_valid_body(*arr.tolist()):
        return arr  # the common case, one valid body, checked on Python floats (a tenth of the array checks' cost)
    if arr.size == 0:
        raise ValueError(f"{name} hold no body (shape {arr.shape})")
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = np.argwhere(bad)[0]
        raise ValueError(f"{name} must be finite, got I{idx[-1] + 1} = {arr[tuple(idx)]}")
    bad = arr <= 0
    if bad.any():
        idx = np.argwhere(bad)[0]
        raise ValueError(f"{name} must be > 0 kg m², got I{idx[-1] + 1} = {arr[tuple(idx)]}")
    rows = arr.reshape(-1, 3)
    largest = rows.max(axis=1)
    bad = rows.sum(axis=1) - largest < largest * (1.0 - _TRIANGLE_SLACK)
    if bad.any():
        row = rows[np.argmax(bad)]
        raise ValueError(
            f"{name} {tuple(float(x) for x in row)} violate the triangle inequality: the two smaller moments "
            f"sum to {float(row.sum() - row.max())} < largest {float(row.max())}; no rigid body has them"
        )
    return arr


def _one_valid_body(a, b, c):
    """Whether three moments are finite, positive and obey the triangle inequality (as the array checks)."""
    if not (0.0 < a < math.inf and 0.0 < b < math.inf and 0.0 < c < math.inf):
        return False
    largest = max(a, b, c)
    return not (a + b + c) - largest < largest * (1.0 - _TRIANGLE_SLACK)


class Body:
    """A rigid body given by its principal moments of inertia.

    Parameters
    ----------
    I1, I2, I3 : float
        Principal moments of inertia, kg m², in any order; all > 0 and obeying the triangle inequality.
    axes : array_like, shape (3, 3), optional
        Principal axes as the columns of a proper rotation matrix, expressed in the frame the body was
        described in (identity by default). ``axes[:, i]`` belongs to moment ``I(i+1)``.
    name : str, optional
        A label used in reprs and datasets.

    See Also
    --------
    tumble.shapes.cuboid : A body from a shape (also ``rod``, ``disc``, ``cone``, ...).
    tumble.models : The models beyond the free body.
    tumble.integrate : Integrate Euler's equations for an ensemble of spins.

    Examples
    --------
    >>> Body(1.0, 2.0, 3.0).moments
    array([1., 2., 3.])

    From an inertia tensor: the principal moments, ascending, and their axes:

    >>> import numpy as np
    >>> Body.from_tensor(np.diag([3.0, 1.0, 2.0])).moments
    array([1., 2., 3.])
    """

    __slots__ = ("_moments", "_axes", "name")

    def __init__(self, I1, I2, I3, *, axes=None, name=None):
        moments = validate_moments([I1, I2, I3])
        moments.setflags(write=False)
        self._moments = moments
        if axes is None:
            axes = np.eye(3)
        axes = np.array(axes, dtype=float)
        if axes.shape != (3, 3) or not np.all(np.isfinite(axes)):
            raise ValueError(f"axes must be a finite (3, 3) array, got shape {axes.shape}")
        if not np.allclose(axes.T @ axes, np.eye(3), atol=1e-10) or np.linalg.det(axes) < 0:
            raise ValueError("axes must be a proper rotation matrix (orthonormal, right-handed columns)")
        axes.setflags(write=False)
        self._axes = axes
        self.name = name

    @classmethod
    def from_tensor(cls, tensor, *, name=None):
        """Diagonalise a symmetric positive-definite inertia tensor.

        Parameters
        ----------
        tensor : array_like, shape (3, 3)
            Inertia tensor about the centre of mass (or about any fixed point), kg m².

        Returns
        -------
        Body
            Moments in ascending order; ``axes`` holds the matching eigenvectors as a right-handed frame,
            each axis signed so that its largest component is positive (the third one is flipped instead
            when that is needed for handedness).
        """
        t = np.asarray(tensor, dtype=float)
        if t.shape != (3, 3):
            raise ValueError(f"inertia tensor must have shape (3, 3), got {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ValueError("inertia tensor must be finite (found NaN or inf)")
        scale = np.abs(t).max()
        if scale == 0 or not np.allclose(t, t.T, rtol=0, atol=1e-12 * scale):
            raise ValueError("inertia tensor must be symmetric and non-zero")
        moments, axes = np.linalg.eigh(0.5 * (t + t.T))
        if moments[0] <= 0:
            raise ValueError(f"inertia tensor must be positive definite, smallest eigenvalue is {moments[0]}")
        for i in range(3):
            if axes[np.argmax(np.abs(axes[:, i])), i] < 0:
                axes[:, i] = -axes[:, i]
        if np.linalg.det(axes) < 0:
            axes[:, 2] = -axes[:, 2]
        return cls(*moments, axes=axes, name=name)

    @property
    def moments(self):
        """ndarray, shape (3,): principal moments ``(I1, I2, I3)``, kg m²."""
        return self._moments.copy()

    @property
    def axes(self):
        """ndarray, shape (3, 3): principal axes as columns, in the frame the body was described in."""
        return self._axes.copy()

    def tensor(self):
        """The inertia tensor in the describing frame, ``axes @ diag(moments) @ axes.T``, kg m²."""
        return self._axes @ np.diag(self._moments) @ self._axes.T

    def __repr__(self):
        label = f", name={self.name!r}" if self.name else ""
        i1, i2, i3 = (float(x) for x in self._moments)
        return f"Body({i1!r}, {i2!r}, {i3!r}{label})"

    def __eq__(self, other):
        if not isinstance(other, Body):
            return NotImplemented
        return np.array_equal(self._moments, other._moments) and np.array_equal(self._axes, other._axes)

    def __hash__(self):
        return hash((self._moments.tobytes(), self._axes.tobytes()))


def as_moments(body):
    """Principal moments from a :class:`Body` or an array of moments.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (3,) for a Body, else (..., 3); validated, float64.
    """
    if isinstance(body, Body):
        return body.moments
    return validate_moments(body, name="body moments")


def one_body(body):
    """The moments, shape (3,), of one body given as a :class:`Body` or three numbers; ValueError otherwise."""
    moments = as_moments(body)
    if moments.shape != (3,):
        raise ValueError(f"body must be one body (a tumble.Body or three moments), got moments of shape "
                         f"{moments.shape}")
    return moments


def moment_unit(moments):
    """The power of two just above the largest moment of each body: shape (...) for moments (..., 3).

    Linear theory and the closed form are scale invariant; dividing by this is exact, so the same bits as
    unscaled wherever those stay in range, and keeps products of moments of 1e-170 or 1e200 kg m² from under-
    or overflowing.
    """
    return np.ldexp(1.0, np.frexp(np.max(moments, axis=-1))[1])


def finite_array(value, name):
    """``value`` as a writable float64 array, or a ValueError naming ``name`` if it is not numbers or not finite.

    A read-only array (an xarray coordinate's ``.values``, a memory map) is copied: numba types a read-only array
    apart from a writable one, and a kernel handed one would compile a second variant of itself (measured: the
    integrator-check tutorial's ``exact.omega(body, w0, ds.time.values)`` compiled the closed form's kernels
    again, 16 s on 2 cores, after ``tumble warm``)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name} must be a number or an array of numbers, got {value!r}") from err
    if not arr.flags.writeable:
        arr = arr.copy()
    # a few numbers (one spin, a scalar) are checked as Python floats: a quarter of the array check's cost
    finite = all(map(math.isfinite, arr.ravel().tolist())) if arr.size <= 16 else np.isfinite(arr).all()
    if not finite:
        raise ValueError(f"{name} must be finite (found NaN or inf)")
    return arr


def spin_vectors(w0, name="w0"):
    """Body-frame angular velocities as a finite float64 array of shape (..., 3), rad/s."""
    w = finite_array(w0, name)
    if w.ndim == 0 or w.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3) (body-frame angular velocity, rad/s), "
                         f"got shape {w.shape}")
    if w.size == 0:
        raise ValueError(f"{name} holds no spins (shape {w.shape})")
    return w
