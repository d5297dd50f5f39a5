"""The chaos indicators at a tolerance: the variational equations as one ODE, stepped by the error-controlled loop.

With a fixed step the tangent vectors are the derivative of the method's own map (:mod:`tumble.kernels.loops.tangent_loop`).
At a tolerance the state ``y`` (n,), ``k`` tangent vectors ``V`` (k, n) and what the indicators integrate along are one
ODE, the *augmented state*, which the DOP853 loop of :mod:`tumble.kernels.loops.adaptive_loop` steps to the tolerance
like any other:

* ``unit`` (MEGNO, GALI): each vector kept at its length, ``u_r' = J u_r − ρ_r u_r`` with ``ρ_r = u_r·J u_r / |u_r|²``
  (``|u_r|`` is an invariant of this flow, so it never overflows), and ``(ln |δ_r|)' = ρ_r``, the growth of the vector
  ``δ_r`` it is the direction of;
* otherwise (the Lyapunov spectrum) the plain variational equations ``δ_r' = J δ_r``: the caller stops every
  ``renormalise`` seconds and orthonormalises them (Benettin et al. 1980). A continuous orthonormalisation (Dieci,
  Russell & Van Vleck's continuous QR) was tried and dropped: orthonormality is only an invariant of that flow, and
  its error grows like ``exp((λ1 − λk) t)`` (1e-5 after 15 s at rtol 1e-11 about the free body's intermediate axis);
* ``megno``: four scalars more, ``Ys' = 2 t ρ_0`` and ``Yss' = Ys / t`` (Cincotta & Simó 2000: ``Y = Ys / t``,
  ``<Y> = Yss / t``), and ``∫ t <Y> dt``, ``∫ <Y> dt`` (``Yss`` and ``Yss / t``), from which the least-squares slope of
  ``<Y>`` against ``t`` over the run is read at the end.

The tangent products are the system's own ``tangents(t, y, V, p, out, work)`` (a built-in model's generated tangent, a
System's Jacobian or its differences: :mod:`tumble.kernels.loops.tangent_loop`).
"""

import numpy as np

from ..jit import jit, rebound
from .tangent_loop import WORK_EXTRA

__all__ = ["LAYOUT", "MEGNO_SCALARS", "augmented_size", "layout", "make_variational_rate", "variational"]

# What the template variational reads, until a copy reads its own (rebound).
rate = tangents = None

#: The MEGNO scalars after the log-growths: ``Ys``, ``Yss``, ``∫ Yss dt`` (= ``∫ t <Y> dt``) and ``∫ <Y> dt``.
MEGNO_SCALARS = 4

#: Numbers after the system's parameters that say the augmented state's layout: ``n, k, unit, megno``. They are read
#: at run time, so one compiled loop serves every indicator and every number of vectors of a system (and every
#: built-in model, whose rate and tangent dispatch on the kind).
LAYOUT = 4

def augmented_size(n, k, megno):
    """Components of the augmented state: ``n`` of the state, ``k n`` of the vectors, ``k`` log-growths and, for
    MEGNO, :data:`MEGNO_SCALARS`."""
    return n + k * n + k + (MEGNO_SCALARS if megno else 0)


def layout(n, k, unit, megno):
    """The :data:`LAYOUT` numbers to append to the system's parameters."""
    return np.array([n, k, 1.0 if unit else 0.0, 1.0 if megno else 0.0])


def make_variational_rate(rate, tangents, key=None):
    """``variational(t, Y, p, dYdt)``: the rate of the augmented state (the module docstring) of a system given by
    ``rate(t, y, p, dydt)`` and ``tangents(t, y, V, p, out, work)``; ``p`` is the system's parameters followed by
    :func:`layout`'s numbers. A copy of :func:`variational` that reads them as its globals
    (:func:`tumble.kernels.jit.rebound`): cached on disk under ``key``, compiled in each process without it."""
    return rebound(("variational",), globals(), key, rate=rate, tangents=tangents)["variational"]


@jit(cache=False, contract=False)  # a template over the globals rate, tangents: its copies run
def variational(t, Y, p, dY):
    last = p.shape[0] - LAYOUT
    n, k, unit, megno = int(p[last]), int(p[last + 1]), p[last + 2] != 0.0, p[last + 3] != 0.0
    q = p[:last]
    vectors = n + k * n
    rate(t, Y[:n], q, dY[:n])
    V = Y[n:vectors].reshape((k, n))
    JV = dY[n:vectors].reshape((k, n))
    tangents(t, Y[:n], V, q, JV, np.empty((n + WORK_EXTRA, n)))
    for r in range(k):
        growth = 0.0
        if unit:
            size = 0.0
            for j in range(n):
                growth += V[r, j] * JV[r, j]
                size += V[r, j] * V[r, j]
            growth /= size
            for j in range(n):
                JV[r, j] -= growth * V[r, j]
        dY[vectors + r] = growth
    if megno:
        m = vectors + k
        dY[m] = 2.0 * t * dY[vectors]
        dY[m + 1] = Y[m] / t if t != 0.0 else 0.0
        dY[m + 2] = Y[m + 1]
        dY[m + 3] = Y[m + 1] / t if t != 0.0 else 0.0

