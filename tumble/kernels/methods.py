"""The fixed-step methods by name, and the call that runs one of them on an ensemble."""

from typing import NamedTuple

import numpy as np

from . import tableaux
from .drivers import propagate, work_buffers
from .steppers import FAMILY_EXPLICIT_RK, FAMILY_IMPLICIT_MIDPOINT, FAMILY_SPLITTING

__all__ = ["Method", "METHODS", "run"]

_NO_TABLE = np.zeros((0, 0))
_NO_VECTOR = np.zeros(0)
_NO_FLOWS = np.zeros(0, dtype=np.int64)


class Method(NamedTuple):
    """A fixed-step integrator: its family, nominal order and coefficients."""

    name: str
    family: int
    order: int
    tableau: tableaux.ButcherTableau | None = None
    splitting: tableaux.Splitting | None = None
    geometric: bool = False  # keeps |L|^2 to round-off (and, for the midpoint rule, the energy too)


def _rk(t):
    return Method(t.name, FAMILY_EXPLICIT_RK, t.order, tableau=t)


def _split(s):
    return Method(s.name, FAMILY_SPLITTING, s.order, splitting=s, geometric=True)


METHODS = {
    m.name: m
    for m in (
        _rk(tableaux.RK4),
        _rk(tableaux.RK8),
        _split(tableaux.SYMPLECTIC_EULER),
        _split(tableaux.SPLITTING2),
        _split(tableaux.SPLITTING4),
        Method("implicit_midpoint", FAMILY_IMPLICIT_MIDPOINT, 2, geometric=True),
    )
}


def run(method, w, moments, t0, h, n_steps, *, save_every=0, torque_kind=0, torque_params=None, torque_fn=None,
        block=128):
    """Integrate an ensemble with a named fixed-step method.

    Parameters
    ----------
    method : Method
    w : ndarray, shape (3, N), float64, C-contiguous
        Initial body-frame angular velocities, rad/s (structure of arrays); overwritten with the final state.
    moments : ndarray, shape (3,)
        Principal moments, kg m².
    t0, h : float
        Start time and step, s.
    n_steps : int
    save_every : int
        0 stores nothing; k > 0 stores the initial state, every k-th step and the final state.
    torque_kind, torque_params, torque_fn
        ``torque_params=None`` and ``torque_fn=None``: torque-free (compiled out).
    block : int
        Samples per SIMD block.

    Returns
    -------
    saved : ndarray, shape (n_saved, 3, N)
        Stored states (``n_saved = 0`` when ``save_every == 0``).
    """
    n = w.shape[1]
    n_saved = 0
    if save_every > 0:
        n_saved = 1 + n_steps // save_every + (1 if n_steps % save_every else 0)
    saved = np.empty((n_saved, 3, n))
    A, b, c = _NO_TABLE, _NO_VECTOR, _NO_VECTOR
    flows, fractions = _NO_FLOWS, _NO_VECTOR
    stages = 0
    if method.tableau is not None:
        A, b, c = method.tableau.A, method.tableau.b, method.tableau.c
        stages = len(b)
    if method.splitting is not None:
        split = method.splitting
        if torque_params is None and torque_fn is None:
            split = split.without_torque()
        flows, fractions = split.flows, split.fractions
    if torque_fn is not None and torque_params is None:
        torque_params = _NO_VECTOR
    moments = np.ascontiguousarray(moments, dtype=float)
    # Splittings turn about the axes in order of ascending moment (smallest errors measured; see tableaux).
    axis_order = np.argsort(moments, kind="stable").astype(np.int64)
    propagate(method.family, A, b, c, flows, fractions, axis_order, work_buffers(method.family, stages), w,
              moments, float(t0), float(h), int(n_steps), int(save_every),
              saved, int(torque_kind), torque_params, torque_fn, int(block))
    return saved
