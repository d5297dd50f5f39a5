"""Jacobi elliptic kernels: relative accuracy up to m = 1 against mpmath, agreement with SciPy."""

import numpy as np
import pytest
import scipy.special as sc

from tumble.kernels.closed_form.elliptic import KC_HYPERBOLIC, agm, jacobi_sncndn

mpmath = pytest.importorskip("mpmath")

KCS = [1.0, 0.9, 0.5, KC_HYPERBOLIC * (1 - 1e-12), 0.2, 0.05, 1e-3, 1e-6, 1e-9, 1e-12, 1e-15]


def sncndn(u, kc):
    u = np.ascontiguousarray(u, dtype=float)
    out = np.empty((u.size, 3))
    jacobi_sncndn(u, np.full(u.size, float(kc)), out)
    return out


def mp_sncndn(u, kc, dps=60):
    with mpmath.workdps(dps):
        m = 1 - mpmath.mpf(kc) ** 2
        K = mpmath.ellipk(m)
        vals = [[mpmath.ellipfun(f, mpmath.mpf(x), m=m) for f in ("sn", "cn", "dn")] for x in u]
        return np.array(vals, dtype=object), K


@pytest.mark.parametrize("kc", KCS)
def test_sncndn_relative_accuracy_against_mpmath_up_to_m_1(kc):
    with mpmath.workdps(60):
        K = float(mpmath.ellipk(1 - mpmath.mpf(kc) ** 2))
    rng = np.random.default_rng(int(-np.log10(kc) * 7) + 1)
    # points everywhere in two periods, near 0 and on both sides of K/2
    u = np.concatenate([rng.uniform(-4 * K, 4 * K, 24), [1e-9, 0.3, 0.49 * K, 0.51 * K, -0.7 * K]])
    got = sncndn(u, kc)
    ref, _ = mp_sncndn(u, kc)
    refd = ref.astype(float)
    err = np.abs(got - refd)
    # relative error growing with |u| (the argument's own rounding, reduced by multiples of K), plus that
    # rounding times the slope, which is what is left near a zero of sn or cn
    s, c, d = refd.T
    slope = np.abs(np.stack([c * d, s * d, (1 - kc * kc) * s * c], axis=-1))
    eps = np.finfo(float).eps
    bound = 4 * eps * ((1 + np.abs(u))[:, None] * np.abs(refd) + np.abs(u)[:, None] * slope)
    assert np.all(err <= bound)


@pytest.mark.parametrize("kc", [1e-3, 1e-8, 1e-12])
def test_cn_dn_near_quarter_period_keep_relative_accuracy(kc):
    # cn, dn ~ k' near u = K: the values a spin near the intermediate axis is made of
    with mpmath.workdps(60):
        K = mpmath.ellipk(1 - mpmath.mpf(kc) ** 2)
        u = [K - mpmath.mpf("0.25"), K + mpmath.mpf(1), K - 3]
        ref = np.array([[float(mpmath.ellipfun(f, x, m=1 - mpmath.mpf(kc) ** 2)) for f in ("cn", "dn")] for x in u])
    got = sncndn([float(x) for x in u], kc)[:, 1:]
    # the argument itself is rounded to a double: relative error ~ eps * K * |d log f / du| ~ eps * K
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-14 * float(K)


@pytest.mark.parametrize("m", [0.0, 0.1, 0.5, 0.9, 0.99])
def test_sncndn_agrees_with_scipy_ellipj_away_from_m_1(m):
    u = np.linspace(-20, 20, 401)
    got = sncndn(u, np.sqrt(1 - m))
    ref = np.stack(sc.ellipj(u, m)[:3], axis=-1)
    assert np.max(np.abs(got - ref)) < 1e-13


@pytest.mark.parametrize("kc", KCS)
def test_sncndn_satisfy_the_pythagorean_identities(kc):
    u = np.linspace(-30, 30, 301)
    s, c, d = sncndn(u, kc).T
    eps = np.finfo(float).eps
    assert np.max(np.abs(s * s + c * c - 1)) < 8 * eps
    assert np.max(np.abs(d * d + (1 - kc * kc) * s * s - 1)) < 8 * eps


def test_agm_gives_complete_integral():
    for kc in [1.0, 0.3, 1e-5, 1e-200]:
        K = 0.5 * np.pi / agm(1.0, kc)
        ref = sc.elliprf(0.0, kc * kc, 1.0) if kc > 1e-150 else np.log(4 / kc)
        assert K == pytest.approx(ref, rel=2e-16 * 8)


def test_carlson_rf_matches_scipy_including_tiny_arguments():
    from tumble.kernels.closed_form.elliptic import carlson_rf

    rng = np.random.default_rng(3)
    args = [(0.0, 1e-24, 1.0), (1e-30, 1e-24, 1.0), (0.5, 0.25, 1.0), (1.0, 1.0, 1.0), (0.0, 1.0, 1.0)]
    args += [tuple(rng.uniform(0, 2, 3)) for _ in range(20)]
    for x, y, z in args:
        assert carlson_rf(x, y, z) == pytest.approx(sc.elliprf(x, y, z), rel=4 * np.finfo(float).eps)


def test_carlson_rf_inverts_sncndn():
    # u = sn R_F(cn², dn², 1) (DLMF 19.25.5), the initial argument of the exact solution
    from tumble.kernels.closed_form.elliptic import carlson_rf

    for kc in [1.0, 0.3, 1e-4, 1e-12]:
        with mpmath.workdps(40):
            m = 1 - mpmath.mpf(kc) ** 2
            K = mpmath.ellipk(m)
            for f in ("0.001", "0.3", "0.9", "-0.7"):
                u = K * mpmath.mpf(f)
                sn, cn, dn = (float(mpmath.ellipfun(g, u, m=m)) for g in ("sn", "cn", "dn"))
                assert sn * carlson_rf(cn * cn, dn * dn, 1.0) == pytest.approx(float(u), rel=1e-15)


def test_sncndn_at_m_1_are_tanh_sech_sech():
    u = np.linspace(-40, 40, 81)
    s, c, d = sncndn(u, 0.0).T
    assert np.allclose(s, np.tanh(u), rtol=1e-15, atol=0)
    assert np.allclose(c, 1 / np.cosh(u), rtol=1e-15, atol=0)
    assert np.array_equal(c, d)
