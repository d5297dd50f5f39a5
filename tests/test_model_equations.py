"""Each built-in model's numpy ``rhs``, ``jacobian`` and ``invariants`` (derived from its module's per-sample
equations, tumble/physics/models/base.py) against an independent transcription in matrix form, written here: Euler's
equations and the models' couplings with cross products (Landau & Lifshitz §36, Wittenburg §3.6, Arnold §30, Hughes
§8.1, Kane & Levinson §4.4), their Jacobians in blocks (the forms the models' docstrings state)."""

import numpy as np
import pytest

from tumble.physics.models import Damper, FreeBody, GravityGradient, Gyrostat, HeavyTop

RNG = np.random.default_rng(11)


def _cross_matrix(v):
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def _euler(moments, w, h):
    """``I⁻¹ ((I w + h) × w)`` and its Jacobian ``I⁻¹ ([I w + h]× − [w]× I)``."""
    rate = np.cross(moments * w + h, w) / moments
    jac = (_cross_matrix(moments * w + h) - _cross_matrix(w) * moments) / moments[:, None]
    return rate, jac


def _gyrostat(model, y, rotor):
    rate, jac = _euler(model.moments, y, rotor)
    lw = model.moments * y
    return rate, jac, {"energy": 0.5 * np.sum(lw * y, -1), "momentum_squared": np.sum((lw + rotor) ** 2, -1)}


def _heavy_top(model, y):
    w, g = y[..., :3], y[..., 3:]
    euler, euler_jac = _euler(model.moments, w, 0.0)
    rate = np.concatenate([euler + model.mgl * np.cross(g, model.centre) / model.moments, np.cross(g, w)], -1)
    jac = np.zeros(y.shape + (6,))
    jac[..., :3, :3] = euler_jac
    jac[..., :3, 3:] = -model.mgl * _cross_matrix(model.centre) / model.moments[:, None]
    jac[..., 3:, :3] = _cross_matrix(g)
    jac[..., 3:, 3:] = -_cross_matrix(w)
    lw = model.moments * w
    return rate, jac, {"energy": 0.5 * np.sum(lw * w, -1) + model.mgl * (g @ model.centre),
                       "vertical_momentum": np.sum(lw * g, -1), "up_squared": np.sum(g * g, -1)}


def _quaternion_rows(q):
    """``c2``, ``c3`` (rows 2 and 3 of the rotation matrix of ``q``) and their derivatives along ``q`` (3, 4)."""
    q0, q1, q2, q3 = q
    c2 = np.array([2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)])
    c3 = np.array([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3])
    d2 = 2 * np.array([[q3, q2, q1, q0], [0.0, -2 * q1, 0.0, -2 * q3], [-q1, -q0, q3, q2]])
    d3 = 2 * np.array([[-q2, q3, -q0, q1], [q1, q0, q3, q2], [0.0, -2 * q1, -2 * q2, 0.0]])
    return c2, c3, d2, d3


def _gravity_gradient(model, y):
    """One state (7,) on the unit sphere (there the rows' ``1 − 2(…)`` form and the ``q0² − …`` form agree)."""
    w, q = y[:3], y[3:]
    n = model.orbit_rate
    c2, c3, d2, d3 = _quaternion_rows(q)
    w_r = w + n * c2
    xi = np.array([[-q[1], -q[2], -q[3]], [q[0], -q[3], q[2]], [q[3], q[0], -q[1]], [-q[2], q[1], q[0]]])
    euler, euler_jac = _euler(model.moments, w, 0.0)
    rate = np.concatenate([euler + 3 * n * n * np.cross(c3, model.moments * c3) / model.moments, 0.5 * xi @ w_r])
    torque_jac = 3 * n * n * (_cross_matrix(c3) * model.moments - _cross_matrix(model.moments * c3)) \
        / model.moments[:, None]
    v1, v2, v3 = w_r
    omega = np.array([[0, -v1, -v2, -v3], [v1, 0, v3, -v2], [v2, -v3, 0, v1], [v3, v2, -v1, 0]])
    jac = np.zeros((7, 7))
    jac[:3, :3], jac[:3, 3:] = euler_jac, torque_jac @ d3
    jac[3:, :3], jac[3:, 3:] = 0.5 * xi, 0.5 * omega + 0.5 * n * (xi @ d2)
    moments = model.moments
    jacobi = 0.5 * moments @ (w_r * w_r) + 1.5 * n * n * moments @ (c3 * c3) - 0.5 * n * n * moments @ (c2 * c2)
    return rate, jac, {"jacobi_integral": jacobi, "quaternion_squared": q @ q}


def _damper(model, y):
    w, s = y[..., :3], y[..., 3:]
    euler, euler_jac = _euler(model.moments, w, 0.0)
    slip = model.damping * (s - w)
    rate = np.concatenate([euler + slip / model.moments, np.cross(s, w) - slip / model.damper_inertia], -1)
    k, c = model.damping / model.damper_inertia, np.diag(model.damping / model.moments)
    jac = np.zeros(y.shape + (6,))
    jac[..., :3, :3], jac[..., :3, 3:] = euler_jac - c, c
    jac[..., 3:, :3], jac[..., 3:, 3:] = _cross_matrix(s) + k * np.eye(3), -_cross_matrix(w) - k * np.eye(3)
    total = model.moments * w + model.damper_inertia * s
    return rate, jac, {"momentum_squared": np.sum(total * total, -1)}


CASES = [
    (FreeBody((1.0, 2.0, 3.0)), lambda m, y: _gyrostat(m, y, 0.0)),
    (Gyrostat((1.0, 2.0, 3.0), (0.1, -0.2, 0.3)), lambda m, y: _gyrostat(m, y, m.rotor)),
    (HeavyTop((2.0, 2.5, 3.0), 0.7), _heavy_top),
    (HeavyTop((2.0, 2.5, 3.0), 0.7, centre=(0.3, -0.2, 1.0)), _heavy_top),
    (GravityGradient((1.0, 2.0, 3.0), 0.1), _gravity_gradient),
    (Damper((1.0, 2.0, 3.0), 0.2, 0.05), _damper),
]


@pytest.mark.parametrize("model, reference", CASES, ids=lambda x: getattr(x, "kind", ""))
def test_rhs_jacobian_and_invariants_match_an_independent_transcription(model, reference):
    y = RNG.normal(size=(5, model.state_size))
    if model.unit_blocks:
        y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    for state in y:  # one state at a time (the gravity gradient's transcription takes one)
        rate, jac, invariants = reference(model, state)
        assert model.rhs(state) == pytest.approx(rate, rel=1e-13, abs=1e-14)
        assert model.jacobian(state) == pytest.approx(jac, rel=1e-13, abs=1e-14)
        found = model.invariants(state)
        assert list(found) == list(invariants)
        for name in found:
            assert float(found[name]) == pytest.approx(float(invariants[name]), rel=1e-13, abs=1e-14)
    # vectorised over leading axes: the same values, state by state
    assert model.rhs(y.reshape(5, 1, -1))[:, 0] == pytest.approx(np.array([model.rhs(s) for s in y]), rel=0, abs=0)
    assert model.jacobian(y).shape == (5, model.state_size, model.state_size)
    assert all(v.shape == (5,) for v in model.invariants(y).values())
