"""The closed form's attitude as tumble computed it until 2026-11-27: numpy over every sample and time, with
Carlson's ``R_F`` and ``R_J`` from ``scipy.special`` (``tumble.physics.exact.attitude`` then). Kept as an independent
reference for the per-sample kernels that replaced it (:mod:`tumble.kernels.closed_form.elliptic_attitude`), which the CUDA device
runs too; ``tests/test_exact_attitude.py`` compares them."""

import numpy as np
from scipy.special import elliprf, elliprj

from tumble.kernels.closed_form import elliptic as _ell
from tumble.physics import exact, rotations
from tumble.physics.bodies import one_body, spin_vectors


def _cyclic_frame(p):
    """Quaternion of the proper rotation taking body coordinates to ``(a, b, p)``, ``a, b = p+1, p+2``
    (mod 3), for each reference axis ``p`` (0-based)."""
    table = np.array([[0.5, -0.5, -0.5, -0.5],  # p = 0: (x0, x1, x2) -> (x1, x2, x0), -120° about (1, 1, 1)
                      [0.5, 0.5, 0.5, 0.5],  # p = 1: -> (x2, x0, x1), +120° about (1, 1, 1)
                      [1.0, 0.0, 0.0, 0.0]])  # p = 2: identity
    return table[p]


def _wrap(z):
    return z - 2.0 * np.pi * np.round(z / (2.0 * np.pi))


def _sncndn(u, kc):
    out = np.empty(u.shape + (3,))
    _ell.jacobi_sncndn(np.ascontiguousarray(u.ravel()), np.ascontiguousarray(np.broadcast_to(kc, u.shape).ravel()),
                       out.reshape(-1, 3))
    return out[..., 0], out[..., 1], out[..., 2]


def _pi_integral(u, K, kc, n_char, separatrix):
    """``∫_0^u du' / (1 - n sn²(u'))`` for ``n <= 0`` and the elliptic argument ``u`` (continuous in ``u``),
    and the amplitude ``am(u)``; on the separatrix (``m = 1``, ``sn = tanh``) in elementary functions.

    Elliptic: ``u = 2K j + r``, ``|r| <= K``; the integral is ``2 j Π(n|m) + Π(n; am r | m)`` with Carlson's
    ``Π(n; φ|m) = s R_F(c², d², 1) + (n/3) s³ R_J(c², d², 1, 1 - n s²)``, ``s, c, d = sn, cn, dn (r)``
    (DLMF 19.25.14), and ``am(u) = j π + atan2(s, c)``.
    """
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        j = np.where(separatrix, 0.0, np.floor(u / (2.0 * K) + 0.5))
        r = np.where(separatrix, u, u - 2.0 * K * j)
    s, c, d = _sncndn(r, np.where(separatrix, 0.0, kc))
    amplitude = j * np.pi + np.arctan2(s, c)
    a = np.sqrt(-n_char)

    def tangent(v):  # ∫_0^v du / (1 + a² tanh² u): the separatrix's integral (sn = tanh)
        return (v + a * np.arctan(a * np.tanh(v))) / (1.0 + a * a)

    # k' below 1e-100 (a spin within about that of the intermediate axis): sn = tanh + O(k'²) on [-K, K], so the
    # integrals take the separatrix form (Carlson's arguments cn², dn² would underflow there)
    tiny = ~separatrix & (kc < 1e-100)
    c2, d2 = c * c, d * d
    with np.errstate(invalid="ignore", divide="ignore"):  # infinite on the separatrix and for tiny k' (unused)
        incomplete = s * elliprf(c2, d2, 1.0) + (n_char / 3.0) * s**3 * elliprj(c2, d2, 1.0, 1.0 - n_char * s * s)
        complete = elliprf(0.0, kc * kc, 1.0) + (n_char / 3.0) * elliprj(0.0, kc * kc, 1.0, 1.0 - n_char)
        incomplete = np.where(tiny, tangent(r), incomplete)
        complete = np.where(tiny, tangent(K), complete)
        integral = np.where(separatrix, tangent(u), 2.0 * j * complete + incomplete)
    return integral, amplitude


def attitude(body, w0, t):
    """The closed-form attitude as tumble computed it before the per-sample kernels (numpy and scipy.special)."""
    tt = exact._check_t(t)
    moments = one_body(body)
    sol = exact._solve(body, w0)
    times = np.ascontiguousarray(np.atleast_1d(tt))
    w = np.ascontiguousarray(spin_vectors(w0).reshape(-1, 3))
    n = w.shape[0]
    w_t = exact.omega_rows(sol, times[None, :], np.zeros(n, dtype=np.int64))
    out = np.empty((n, times.shape[0], 4))

    steady = sol.kind == _ell.KIND_STATIONARY
    spin = np.linalg.norm(w[steady], axis=1)
    axis = np.where(spin[:, None] > 0, w[steady], [1.0, 0.0, 0.0])
    out[steady] = rotations.about_axis(spin[:, None] * times, axis[:, None, :])

    moving = ~steady
    if moving.any():  # t = 0 is prepended: the attitude is taken relative to the start
        start = exact.omega_rows(sol, np.zeros((1, 1)), np.zeros(n, dtype=np.int64))
        out[moving] = _moving_attitude(moments, sol, moving, w[moving],
                                       np.concatenate([start[moving], w_t[moving]], axis=1),
                                       np.concatenate([[0.0], times]))[:, 1:]
    if not np.all(np.isfinite(out)):
        raise FloatingPointError("exact.attitude produced non-finite values; please report this spin")
    out = out.reshape(sol.shape + (times.shape[0], 4))
    return out[..., 0, :] if tt.ndim == 0 else out


def _moving_attitude(moments, sol, rows, w, w_t, times):
    """Attitude of the non-steady spins ``rows`` at ``times`` (``times[0] = 0``), from ``w_t = omega(times)``."""
    cq, cm, cp = (sol.cols[rows, j] for j in range(3))
    Iq, Im, Ip = moments[cq], moments[cm], moments[cp]
    kc, K, nu, phase0 = sol.kc[rows], sol.K[rows], sol.nu[rows], sol.phase0[rows]
    separatrix = sol.kind[rows] == _ell.KIND_SEPARATRIX
    size = np.sqrt(((moments * w) ** 2).sum(axis=1))  # |L|
    ca, cb = (cp + 1) % 3, (cp + 2) % 3
    L = moments * w_t
    la, lb, lp = (np.take_along_axis(L, c[:, None, None], axis=2)[..., 0] for c in (ca, cb, cp))
    theta = np.arctan2(np.hypot(la, lb), lp)

    # the elliptic argument u = u0 + nu t (separatrix: the argument of tanh, sech)
    with np.errstate(invalid="ignore"):
        u = np.where(separatrix, 0.0, K)[:, None] + phase0[:, None] + nu[:, None] * times
        u0 = np.where(separatrix, 0.0, K) + phase0
    n_char = -Ip * (Im - Iq) / (Iq * (Ip - Im))
    sep = separatrix[:, None]
    integral, am = _pi_integral(u, K[:, None], kc[:, None], n_char[:, None], sep)
    integral0, _ = _pi_integral(u0, K, kc, n_char, separatrix)
    phi = size[:, None] * times / Ip[:, None] + (size * (Ip - Iq) / (Iq * Ip * nu))[:, None] * (
        integral - integral0[:, None])

    # psi = atan2(L_a, L_b), carried continuously through the amplitude am(u): L_q ∝ X cn, L_mid ∝ Y sn
    X = (Iq * sol.amp[rows, 0])[:, None]
    Y = (Im * sol.amp[rows, 1])[:, None]
    reference = np.where(X > 0, np.sign(Y) * am, np.pi - np.sign(Y) * am)  # near atan2(Y sn, X cn)
    reference = np.where((ca == cm)[:, None], reference, 0.5 * np.pi - reference)
    psi = reference + _wrap(np.arctan2(la, lb) - reference)

    frame = _cyclic_frame(cp)[:, None, :]
    local = rotations.product(rotations.product(rotations.about_axis(phi, 2), rotations.about_axis(theta, 0)),
                              rotations.about_axis(psi, 2))
    start = rotations.product(local[:, :1], frame)
    return rotations.product(rotations.conjugate(start), rotations.product(local, frame))
