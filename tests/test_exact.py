"""The exact torque-free solution (Landau & Lifshitz §37) against references, invariants and symmetries.

Error metric near the separatrix (``component_error``): for every component ``i`` and time,
``|w_i - w_i,ref| / max(|w_i,ref|, 0.1 |dw_i/du|)``, ``u`` the elliptic argument. That is the error
relative to the component itself -- including the tiny transverse components of a spin near the
intermediate axis, which growth-rate fits use -- except within 0.1 in ``u`` of a zero crossing, where the
rounding of the argument (``~ eps |u|``, unavoidable in double precision once ``u`` is tens to hundreds)
sets an absolute floor. ``vector_error`` is ``|w - w_ref| / |w_ref|``.
"""

import numpy as np
import pytest
import scipy.special as sc
from scipy.integrate import solve_ivp

import tumble
from tumble.physics import exact

mpmath = pytest.importorskip("mpmath")

EPS = np.finfo(float).eps


def euler_rhs(w, moments):
    """Torque-free Euler equations, ``I1 w1' = (I2 - I3) w2 w3`` and cyclic; w (..., 3)."""
    I1, I2, I3 = moments
    w1, w2, w3 = np.moveaxis(np.asarray(w), -1, 0)
    return np.stack([(I2 - I3) * w2 * w3 / I1, (I3 - I1) * w3 * w1 / I2, (I1 - I2) * w1 * w2 / I3], axis=-1)


def dop853(moments, w0, t):
    sol = solve_ivp(
        lambda _, w: euler_rhs(w, moments), (t[0], t[-1]), w0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=t
    )
    assert sol.success
    return sol.y.T


def mp_reference(moments, w0, t, dps=50):
    """Landau & Lifshitz §37 evaluated in mpmath from the exact binary values of the inputs.

    Written independently of tumble.exact: m = k² from the invariants, u0 = F(phi|m) with phi from the
    sn and cn components, the sense of motion from Euler's equations at t = 0 (no parity argument).
    Returns omega (T, 3) and nu (float).
    """
    with mpmath.workdps(dps):
        order = sorted(range(3), key=lambda i: (float(moments[i]), i))
        I = [mpmath.mpf(float(moments[i])) for i in order]
        w = [mpmath.mpf(float(w0[i])) for i in order]
        e2 = sum(I[i] * w[i] ** 2 for i in range(3))
        L2 = sum((I[i] * w[i]) ** 2 for i in range(3))
        p, q = (2, 0) if L2 > e2 * I[1] else (0, 2)  # dn axis, cn axis
        Aq = mpmath.sqrt((e2 * I[p] - L2) / (I[q] * (I[p] - I[q])))
        Am = mpmath.sqrt((e2 * I[p] - L2) / (I[1] * (I[p] - I[1])))
        Ap = mpmath.sqrt((L2 - e2 * I[q]) / (I[p] * (I[p] - I[q])))
        m = (I[1] - I[q]) * (e2 * I[p] - L2) / ((I[p] - I[1]) * (L2 - e2 * I[q]))
        nu = mpmath.sqrt((I[p] - I[1]) * (L2 - e2 * I[q]) / (I[0] * I[1] * I[2]))
        sp = mpmath.sign(w[p])
        u0 = mpmath.ellipf(mpmath.atan2(w[1] / Am, w[q] / Aq), m)
        # d w_mid/dt from Euler's equations in the caller's frame vs d(Am sn u)/dt = Am cn dn nu
        rhs = euler_rhs([float(x) for x in w0], [float(x) for x in moments])[order[1]]
        if Am * mpmath.ellipfun("cn", u0, m=m) * mpmath.ellipfun("dn", u0, m=m) * nu * rhs < 0:
            nu = -nu
        out = np.empty((len(t), 3))
        for j, tj in enumerate(t):
            u = u0 + nu * mpmath.mpf(float(tj))
            vals = {q: Aq * mpmath.ellipfun("cn", u, m=m), 1: Am * mpmath.ellipfun("sn", u, m=m)}
            vals[p] = sp * Ap * mpmath.ellipfun("dn", u, m=m)
            for k in range(3):
                out[j, order[k]] = float(vals[k])
        return out, float(nu)


def component_error(moments, got, ref, nu):
    slope = np.abs(euler_rhs(ref, moments)) / abs(nu)  # |dw/du|
    return np.abs(got - ref) / np.maximum(np.abs(ref), 0.1 * slope)


def vector_error(got, ref):
    return np.linalg.norm(got - ref, axis=-1) / np.linalg.norm(ref, axis=-1)


def near_intermediate_spin(moments, eps, regime, rng, spin=1.3):
    """A spin along the intermediate axis perturbed by ``eps`` (relative), in the requested regime."""
    order = np.argsort(moments, kind="stable")
    I1, I2, I3 = np.asarray(moments)[order]
    a, b = np.abs(rng.normal(size=2)) + 0.1
    w = np.empty(3)
    w[order[1]] = spin
    w[order[0]] = eps * spin * a * rng.choice([-1, 1])
    w[order[2]] = eps * spin * b * rng.choice([-1, 1])
    # regime from the sign of L² - 2E I2 = I3 (I3 - I2) w3² - I1 (I2 - I1) w1²
    big = I3 * (I3 - I2) * w[order[2]] ** 2 > I1 * (I2 - I1) * w[order[0]] ** 2
    if big != (regime > 0):
        w[order[0]], w[order[2]] = w[order[2]] * np.sqrt(I3 * (I3 - I2) / (I1 * (I2 - I1))), w[order[0]] * np.sqrt(
            I1 * (I2 - I1) / (I3 * (I3 - I2))
        )
    return w


def flips_times(moments, w0, flips=10, n=150):
    T = flips * float(exact.flip_spacing(moments, w0))
    return np.concatenate([[0.0], np.linspace(0.0, T, n)[1:]])


# --------------------------------------------------------------------------------------------------
# high-precision reference near the separatrix

SHUFFLED = [(2.4, 1.0, 1.7), (1.7, 2.4, 1.0), (1.0, 2.4, 1.7)]


def separatrix_case(eps, regime, n=150):
    """``(moments, w0, t, reference, nu)``: a spin ``eps`` from the intermediate axis in ``regime``, ``n`` times over
    ten flips, and mpmath's solution there."""
    rng = np.random.default_rng(int(1e3 * -np.log10(eps)) + regime + 5)
    moments = SHUFFLED[int(-np.log10(eps)) % 3]
    w0 = near_intermediate_spin(moments, eps, regime, rng)
    assert exact.parameters(moments, w0).regime == regime
    t = flips_times(moments, w0, n=n)
    return (moments, w0, t, *mp_reference(moments, w0, t))


@pytest.mark.parametrize("eps", [1.0, 1e-3, 1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("regime", [1, -1])
def test_matches_mpmath_to_1e12_near_separatrix_over_ten_flips(eps, regime):
    moments, w0, t, ref, nu = separatrix_case(eps, regime)
    got = exact.omega(moments, w0, t)
    assert vector_error(got, ref).max() < 1e-12
    assert component_error(moments, got, ref, nu).max() < 5e-12


@pytest.mark.slow
@pytest.mark.parametrize("eps", [1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12])
def test_matches_mpmath_many_spins_and_bodies(eps):
    rng = np.random.default_rng(int(-np.log10(eps)) + 100)
    for trial in range(6):
        moments = rng.permutation(rng.uniform(1.0, 2.0, 3))
        w0 = near_intermediate_spin(moments, eps, (-1) ** trial, rng, spin=rng.uniform(0.1, 10))
        t = flips_times(moments, w0, n=300)
        ref, nu = mp_reference(moments, w0, t)
        got = exact.omega(moments, w0, t)
        assert vector_error(got, ref).max() < 1e-12
        assert component_error(moments, got, ref, nu).max() < 5e-12


@pytest.mark.parametrize("eps", [1e-3, 1e-8, 1e-12])
def test_tiny_transverse_components_are_reproduced_to_round_off_at_t0(eps):
    rng = np.random.default_rng(3)
    for moments in SHUFFLED:
        for regime in (1, -1):
            w0 = near_intermediate_spin(moments, eps, regime, rng)
            got = exact.omega(moments, w0, 0.0)
            assert np.all(np.abs(got - w0) <= 8 * EPS * np.abs(w0))


# --- spins within 1e-151 of an axis (issue 17, cause 15): the squares of their small components underflow ---


TINY_SPINS = [[1e-170, 1.0, 0.0], [1e-170, 1.0, 1e-170], [0.0, -1.0, 1e-165], [3e-152, 2.0, -1e-152],
              [-1e-300, -1.0, 2e-300]]


@pytest.mark.parametrize("w0", TINY_SPINS)
def test_a_spin_within_1e_151_of_the_intermediate_axis_flips_as_its_linear_growth_says(w0):
    # The same spin with its small components 1e70 times larger (squares far from underflow) is the same motion
    # shifted in time: in the linear regime w(t; c ε) = c w(t; ε), so every flip comes ln(1e70)/λ later for the
    # tiny one (to relative O(ε²)), and near the flip the two states agree.
    moments = np.array([1.0, 2.0, 3.0])
    tiny = np.array(w0)
    big = tiny.copy()
    big[[0, 2]] *= 1e70
    rate = abs(tiny[1]) * np.sqrt(1.0 / 3.0)  # w2 sqrt(-q)
    delay = np.log(1e70) / rate
    assert exact.omega(moments, tiny, 0.0) == pytest.approx(tiny, rel=1e-14, abs=0)
    assert exact.first_flip_time(moments, tiny) == pytest.approx(exact.first_flip_time(moments, big) + delay,
                                                                 rel=1e-12)
    assert exact.flip_spacing(moments, tiny) == pytest.approx(exact.flip_spacing(moments, big) + 2 * delay,
                                                              rel=1e-12)
    near = exact.first_flip_time(moments, big) + np.linspace(-20.0, 20.0, 9)
    np.testing.assert_allclose(exact.omega(moments, tiny, near + delay), exact.omega(moments, big, near),
                               rtol=0, atol=1e-9 * abs(tiny[1]))
    assert np.isfinite(tumble.integrate(moments, tiny, 4000.0, 4000.0, method="exact")["omega"]).all()


def test_a_spin_within_1e_151_of_the_intermediate_axis_spins_steadily_until_it_flips():
    moments = np.array([1.0, 2.0, 3.0])
    t = np.array([0.0, 1.0, 100.0, 300.0])  # the perturbation is still below 1e-95 at 300 s
    q = exact.attitude(moments, [1e-170, 1.0, 0.0], t)
    steady = np.stack([np.cos(t / 2), 0 * t, np.sin(t / 2), 0 * t], axis=1)  # turning about e2 at 1 rad/s
    np.testing.assert_allclose(q, steady, rtol=0, atol=1e-11)
    dense = exact.attitude(moments, [1e-170, 1.0, 0.0], np.linspace(600.0, 800.0, 4001))  # through the flip
    assert np.abs(np.linalg.norm(dense, axis=1) - 1).max() < 1e-12
    assert np.abs(np.diff(dense, axis=0)).max() < 0.05  # continuous


@pytest.mark.parametrize("w0, axis", [([1e-200, 0.0, 1.0], 2), ([1.0, 0.0, 1e-160], 0), ([0.0, 1e-300, -3.0], 2)])
def test_a_spin_within_1e_151_of_a_stable_axis_follows_the_linearised_motion(w0, axis):
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.array(w0)
    a, b, c = axis, (axis + 1) % 3, (axis + 2) % 3
    alpha = (moments[c] - moments[a]) * w0[a] / moments[b]  # w_b' = alpha w_c, w_c' = beta w_b
    beta = (moments[a] - moments[b]) * w0[a] / moments[c]
    omega = np.sqrt(-alpha * beta)
    t = np.linspace(0.0, 50.0, 11)
    expected = np.empty((len(t), 3))
    expected[:, a] = w0[a]
    expected[:, b] = w0[b] * np.cos(omega * t) + alpha / omega * w0[c] * np.sin(omega * t)
    expected[:, c] = w0[c] * np.cos(omega * t) + beta / omega * w0[b] * np.sin(omega * t)
    got = exact.omega(moments, w0, t)
    scale = np.abs(w0[[b, c]]).max()
    np.testing.assert_allclose(got[:, [b, c]], expected[:, [b, c]], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(got[:, a], w0[a], rtol=4 * EPS, atol=0)
    assert np.isfinite(exact.attitude(moments, w0, t)).all()


def test_transverse_components_grow_at_the_linear_rate_near_the_intermediate_axis():
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.array([1e-12, 1.0, 1e-12])
    rate = np.sqrt((3 - 2) * (2 - 1) / (1 * 3))  # linear theory: w2 sqrt(-q), q = (I2-I1)(I2-I3)/(I1 I3)
    w = exact.omega(moments, w0, np.array([10.0, 20.0]))
    # between 10 s and 20 s the decaying mode is down by exp(-2 rate 10) ~ 1e-5 and the amplitude is
    # still ~1e-7, so the log-slope is the linear rate to ~1e-6
    slope = np.log(np.abs(w[1, [0, 2]]) / np.abs(w[0, [0, 2]])) / 10.0
    assert slope == pytest.approx(np.full(2, rate), rel=1e-5)


# --------------------------------------------------------------------------------------------------
# independent implementations


def scipy_ellipj_reference(moments, w0, t):
    """Landau & Lifshitz §37 with scipy.special.ellipj/ellipkinc (fine away from m = 1)."""
    order = np.argsort(moments, kind="stable")
    I = np.asarray(moments, float)[order]
    w = np.asarray(w0, float)[order]
    e2 = np.sum(I * w * w)
    L2 = np.sum((I * w) ** 2)
    p, q = (2, 0) if L2 > e2 * I[1] else (0, 2)
    Aq = np.sqrt((e2 * I[p] - L2) / (I[q] * (I[p] - I[q])))
    Am = np.sqrt((e2 * I[p] - L2) / (I[1] * (I[p] - I[1])))
    Ap = np.sqrt((L2 - e2 * I[q]) / (I[p] * (I[p] - I[q])))
    m = (I[1] - I[q]) * (e2 * I[p] - L2) / ((I[p] - I[1]) * (L2 - e2 * I[q]))
    nu = np.sqrt((I[p] - I[1]) * (L2 - e2 * I[q]) / np.prod(I))
    phi = np.arctan2(w[1] / Am, w[q] / Aq)
    K = sc.ellipk(m)
    n = np.round(phi / np.pi)
    u0 = sc.ellipkinc(phi - n * np.pi, m) + 2 * n * K
    sn, cn, dn, _ = sc.ellipj(u0, m)
    rhs = euler_rhs(w0, moments)[order[1]]
    if Am * cn * dn * nu * rhs < 0:
        nu = -nu
    sn, cn, dn, _ = sc.ellipj(u0 + nu * np.asarray(t), m)
    out = np.empty((len(t), 3))
    out[:, order[q]] = Aq * cn
    out[:, order[1]] = Am * sn
    out[:, order[p]] = np.sign(w[p]) * Ap * dn
    return out


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (2.0, 3.0, 1.5), (0.5, 1.0, 1.2)])
def test_agrees_with_scipy_ellipj_away_from_separatrix(moments):
    rng = np.random.default_rng(7)
    t = np.linspace(-5.0, 30.0, 120)
    for _ in range(6):
        w0 = rng.normal(size=3)
        got = exact.omega(moments, w0, t)
        ref = scipy_ellipj_reference(moments, w0, t)
        assert np.max(np.abs(got - ref)) < 1e-11 * np.linalg.norm(w0)


@pytest.mark.parametrize(
    "moments", [(1.0, 2.0, 3.0), (3.0, 2.0, 1.0), (2.0, 1.0, 3.0), (1.0, 1.0, 2.0), (2.0, 2.0, 1.0), (1.0, 1.5, 2.5)]
)
def test_agrees_with_dop853_reference_integration(moments):
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 25.0, 60)
    for _ in range(3):
        w0 = rng.normal(size=3)
        got = exact.omega(moments, w0, t)
        ref = dop853(moments, w0, t)
        assert np.max(np.abs(got - ref)) < 1e-10 * np.linalg.norm(w0)


def test_agrees_with_dop853_near_separatrix():
    moments = (1.0, 2.0, 3.0)
    w0 = np.array([1e-6, 1.0, -2e-6])
    t = np.linspace(0.0, 40.0, 81)
    # the separatrix amplifies perturbations by ~exp(rate t); compare where DOP853 is still exact enough
    ref = dop853(moments, w0, t)
    got = exact.omega(moments, w0, t)
    assert np.max(np.abs(got - ref)) < 1e-8


# --------------------------------------------------------------------------------------------------
# invariants and special motions


@pytest.mark.parametrize("eps", [1.0, 1e-4, 1e-12])
def test_energy_and_angular_momentum_are_conserved_to_round_off(eps):
    rng = np.random.default_rng(13)
    moments = np.array([1.7, 1.0, 2.4])
    w0 = np.stack([near_intermediate_spin(moments, eps, r, rng) for r in (1, -1, 1, -1)])
    t = np.linspace(0.0, 200.0, 2001)
    w = exact.omega(moments, w0, t)
    energy = 0.5 * np.sum(moments * w * w, axis=-1)
    L2 = np.sum((moments * w) ** 2, axis=-1)
    e0 = 0.5 * np.sum(moments * w0 * w0, axis=-1)[:, None]
    l0 = np.sum((moments * w0) ** 2, axis=-1)[:, None]
    assert np.max(np.abs(energy / e0 - 1)) < 10 * EPS
    assert np.max(np.abs(L2 / l0 - 1)) < 10 * EPS


@pytest.mark.parametrize("moments, axis", [((1.0, 1.0, 1.8), 2), ((1.8, 1.0, 1.8), 1), ((1.3, 0.7, 0.7), 0)])
def test_symmetric_top_transverse_components_rotate_at_Omega(moments, axis):
    I = np.asarray(moments)
    a, b = [i for i in range(3) if i != axis]
    w0 = np.zeros(3)
    w0[[a, b, axis]] = [0.3, -0.2, 1.1]
    t = np.linspace(0.0, 50.0, 201)
    w = exact.omega(moments, w0, t)
    Omega = w0[axis] * (I[axis] - I[a]) / I[a]
    # w_a + i w_b = (w_a0 + i w_b0) exp(i s Omega t), s = +1 when (a, b, axis) is cyclic
    s = 1.0 if (a, b, axis) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] else -1.0
    z = (w0[a] + 1j * w0[b]) * np.exp(1j * s * Omega * t)
    assert np.max(np.abs(w[:, a] - z.real)) < 1e-13
    assert np.max(np.abs(w[:, b] - z.imag)) < 1e-13
    assert np.all(w[:, axis] == w0[axis])
    assert exact.period(moments, w0) == pytest.approx(2 * np.pi / abs(Omega), rel=1e-15)


def test_nearly_symmetric_top_is_continuous_with_the_symmetric_top():
    w0 = np.array([0.3, -0.2, 1.1])
    t = np.linspace(0.0, 20.0, 101)
    exact_sym = exact.omega((1.0, 1.0, 1.8), w0, t)
    for delta in (1e-6, 1e-9, 1e-13):
        near = exact.omega((1.0, 1.0 + delta, 1.8), w0, t)
        ref = dop853((1.0, 1.0 + delta, 1.8), w0, t) if delta == 1e-6 else exact_sym
        assert np.max(np.abs(near - ref)) < max(50 * delta, 1e-11)


@pytest.mark.parametrize("moments", [(1.0, 1 + 1e-12, 1 + 2e-12), (1.0, 1 + 1e-12, 1.5), (1.0, 1.5 - 1e-12, 1.5)])
def test_near_equal_moments_agree_with_dop853(moments):
    w0 = np.array([0.3, 1.0, -0.2])
    t = np.linspace(0.0, 100.0, 11)
    assert np.max(np.abs(exact.omega(moments, w0, t) - dop853(moments, w0, t))) < 1e-12


def test_sphere_and_zero_spin_and_steady_spins_stay_constant():
    t = np.linspace(-3.0, 7.0, 11)
    cases = [
        ((2.0, 2.0, 2.0), [0.3, -1.0, 2.0]),  # sphere
        ((1.0, 2.0, 3.0), [0.0, 0.0, 0.0]),  # no spin
        ((1.0, 2.0, 3.0), [1.5, 0.0, 0.0]),  # about each principal axis
        ((1.0, 2.0, 3.0), [0.0, -1.5, 0.0]),
        ((1.0, 2.0, 3.0), [0.0, 0.0, 1.5]),
        ((1.0, 1.0, 1.5), [0.4, -0.3, 0.0]),  # any axis in the equal-moment plane
    ]
    for moments, w0 in cases:
        w = exact.omega(moments, w0, t)
        assert np.all(w == np.asarray(w0)), (moments, w0)
        assert exact.period(moments, w0) == np.inf
        assert exact.flip_spacing(moments, w0) == np.inf
        assert exact.first_flip_time(moments, w0) == np.inf
        assert exact.parameters(moments, w0).stationary


def test_separatrix_spin_follows_sech_and_tanh():
    # I = (3, 4, 6): L² - 2E I2 = 6*2*w3² - 3*1*w1² = 0 exactly when w1 = 2 w3
    moments = (3.0, 4.0, 6.0)
    w0 = np.array([0.2, 0.5, 0.1])
    par = exact.parameters(moments, w0)
    assert par.delta == 0 and par.regime == 0 and par.m == 1 and par.kc == 0
    assert exact.period(moments, w0) == np.inf and exact.flip_spacing(moments, w0) == np.inf
    t = np.linspace(-30.0, 30.0, 121)
    w = exact.omega(moments, w0, t)
    # closed form: w1 = A1 sech u, w2 = A2 tanh u, w3 = A3 sech u, u = u0 + nu t
    assert np.allclose(w[:, 0], 2 * w[:, 2], rtol=1e-14, atol=0)
    assert np.allclose(w[:, 0] / par.amplitude[0], 1 / np.cosh(par.u0 + par.nu * t), rtol=1e-13, atol=1e-300)
    assert np.allclose(w[:, 1] / par.amplitude[1], np.tanh(par.u0 + par.nu * t), rtol=1e-13, atol=1e-16)
    # asymptotically the spin approaches the intermediate axis, from opposite sides
    far = exact.omega(moments, w0, np.array([-100.0, 100.0]) / abs(par.nu))
    assert np.allclose(np.abs(far[:, 1]), par.amplitude[1], rtol=1e-15) and far[0, 1] * far[1, 1] < 0
    assert np.all(np.abs(far[:, [0, 2]]) < 1e-40)
    ref = dop853(moments, w0, np.linspace(0.0, 10.0, 11))
    assert np.max(np.abs(exact.omega(moments, w0, np.linspace(0.0, 10.0, 11)) - ref)) < 1e-11
    # the sign of w2 changes once, at t = -u0/nu
    tf = exact.first_flip_time(moments, w0)
    assert np.isfinite(tf) == (-par.u0 / par.nu > 0)


# --------------------------------------------------------------------------------------------------
# period and flips


@pytest.mark.parametrize("eps", [0.5, 1e-4, 1e-10])
def test_omega_returns_to_itself_after_one_period(eps):
    rng = np.random.default_rng(17)
    moments = (2.4, 1.0, 1.7)
    for regime in (1, -1):
        w0 = near_intermediate_spin(moments, eps, regime, rng)
        P = float(exact.period(moments, w0))
        t = np.linspace(0.0, P, 37)
        w = exact.omega(moments, w0, t)
        w_later = exact.omega(moments, w0, t + P)
        assert np.max(np.abs(w_later - w)) < 1e-12 * np.linalg.norm(w0)
        assert np.max(np.abs(w[-1] - w0)) < 1e-12 * np.linalg.norm(w0)


@pytest.mark.parametrize("eps", [0.5, 1e-4, 1e-10])
@pytest.mark.parametrize("moments", [(1.7, 2.4, 1.0), (2.4, 1.7, 1.0)])  # even and odd sorting permutation
def test_mid_component_flips_first_at_first_flip_time_then_every_flip_spacing(eps, moments):
    rng = np.random.default_rng(19)
    mid = int(np.argsort(moments)[1])
    for regime in (1, -1):
        w0 = near_intermediate_spin(moments, eps, regime, rng)
        par = exact.parameters(moments, w0)
        assert par.mid_axis == mid
        spacing = float(exact.flip_spacing(moments, w0))
        assert spacing == pytest.approx(2 * par.K / abs(par.nu), rel=1e-15)
        t1 = float(exact.first_flip_time(moments, w0))
        assert 0 < t1 <= spacing
        flips = t1 + spacing * np.arange(4)
        d = 1e-6 * spacing
        before = exact.omega(moments, w0, flips - d)[:, mid]
        after = exact.omega(moments, w0, flips + d)[:, mid]
        assert np.all(np.sign(before) == -np.sign(after))
        assert np.all(np.sign(before[1:]) == -np.sign(before[:-1]))
        # no sign change before the first flip
        early = exact.omega(moments, w0, np.linspace(0.0, t1 - d, 400))[:, mid]
        assert np.all(np.sign(early) == np.sign(w0[mid]))


def test_parameters_reproduce_the_initial_spin_through_sn_cn_dn():
    # w_mid = A_mid sn(u0), w_cn = A_cn cn(u0), |w_dn| = A_dn dn(u0), with scipy's ellipj (m away from 1)
    rng = np.random.default_rng(41)
    for moments in SHUFFLED:
        w0 = rng.normal(size=(8, 3))
        par = exact.parameters(moments, w0)
        sn, cn, dn, _ = sc.ellipj(par.u0, par.m)
        rows = np.arange(8)
        mid, dn_axis = par.mid_axis, par.dn_axis
        cn_axis = 3 - mid - dn_axis
        A = par.amplitude
        assert np.all(np.abs(par.u0) <= 2 * par.K)
        assert np.allclose(w0[:, mid], A[:, mid] * sn, rtol=0, atol=1e-14)
        assert np.allclose(w0[rows, cn_axis], A[rows, cn_axis] * cn, rtol=0, atol=1e-14)
        assert np.allclose(np.abs(w0[rows, dn_axis]), A[rows, dn_axis] * dn, rtol=0, atol=1e-14)


def test_spin_with_zero_mid_component_flips_one_spacing_later():
    moments = (1.0, 2.0, 3.0)
    w0 = np.array([0.3, 0.0, 1.0])
    assert exact.first_flip_time(moments, w0) == pytest.approx(float(exact.flip_spacing(moments, w0)), rel=1e-14)


# --------------------------------------------------------------------------------------------------
# symmetries and vectorisation


def test_permuting_the_axes_permutes_the_solution():
    # a cyclic relabelling is a rotation and leaves Euler's equations as they are; a transposition is a
    # reflection, which reverses w x (I w): the relabelled motion is the original one run backwards
    rng = np.random.default_rng(23)
    moments = np.array([1.0, 1.6, 2.3])
    w0 = rng.normal(size=(5, 3))
    w0[0] = [1e-9, 1.0, -2e-9]
    t = np.linspace(0.0, 30.0, 50)
    forward = exact.omega(moments, w0, t)
    backward = exact.omega(moments, w0, -t)
    for perm, base in (([1, 2, 0], forward), ([2, 0, 1], forward), ([0, 2, 1], backward), ([2, 1, 0], backward)):
        got = exact.omega(moments[perm], w0[:, perm], t)
        assert np.max(np.abs(got - base[..., perm])) < 1e-13 * np.abs(w0).max()


def test_scaling_all_moments_leaves_omega_unchanged():
    rng = np.random.default_rng(29)
    moments = np.array([1.0, 1.6, 2.3])
    w0 = rng.normal(size=(4, 3))
    w0[0] = [1e-11, 1.0, 3e-11]
    t = np.linspace(0.0, 60.0, 40)
    base = exact.omega(moments, w0, t)
    for c in (1e-6, 3.0, 1e5):
        got = exact.omega(c * moments, w0, t)
        assert np.max(np.abs(got - base) / np.maximum(np.abs(base), 1e-3)) < 1e-12
        assert np.allclose(exact.period(c * moments, w0), exact.period(moments, w0), rtol=1e-14)


@pytest.mark.parametrize("scale", [1e-280, 1e-160, 1e150, 1e300])
def test_extreme_spin_magnitudes_scale_exactly(scale):
    # w(t) a solution => c w(c t) is one; internally spins are scaled by powers of two, so nothing
    # under- or overflows and a power-of-two c gives bit-identical results (away from subnormals)
    rng = np.random.default_rng(43)
    moments = (1.0, 1.6, 2.3)
    w0 = rng.normal(size=(3, 3))
    w0[0] = [1e-9, 1.0, -2e-9]
    t = np.linspace(0.0, 20.0, 21)
    base = exact.omega(moments, w0, t)
    c = np.ldexp(1.0, int(np.log2(scale)))
    assert np.array_equal(exact.omega(moments, c * w0, t / c), c * base)
    got = exact.omega(moments, scale * w0, t / scale)
    assert np.allclose(got / scale, base, rtol=1e-12, atol=0)


def test_time_reversal_symmetry():
    # w(t) a solution => -w(-t) is one
    rng = np.random.default_rng(31)
    moments = (1.0, 1.6, 2.3)
    w0 = rng.normal(size=(3, 3))
    t = np.linspace(0.0, 20.0, 21)
    assert np.allclose(exact.omega(moments, w0, -t), -exact.omega(moments, -w0, t), rtol=1e-12, atol=1e-14)


def test_vectorised_over_leading_dimensions_and_body_kinds():
    rng = np.random.default_rng(37)
    w0 = rng.normal(size=(2, 3, 3))
    t = np.linspace(0.0, 5.0, 7)
    body = tumble.Body(1.0, 2.0, 3.0)
    got = exact.omega(body, w0, t)
    assert got.shape == (2, 3, 7, 3)
    for i in range(2):
        for j in range(3):
            assert np.array_equal(got[i, j], exact.omega([1.0, 2.0, 3.0], w0[i, j], t))
    assert exact.omega(body, w0, 1.0).shape == (2, 3, 3)
    for fn in (exact.period, exact.flip_spacing, exact.first_flip_time):
        assert fn(body, w0).shape == (2, 3)
    par = exact.parameters(body, w0)
    for name in ("m", "kc", "K", "nu", "u0", "regime", "stationary", "energy", "L2", "delta", "dn_axis"):
        assert getattr(par, name).shape == (2, 3), name
    assert par.amplitude.shape == (2, 3, 3)


def test_parameters_carry_kc_without_cancellation():
    moments = (1.0, 2.0, 3.0)
    for eps in (1e-4, 1e-9, 1e-14):
        w0 = np.array([eps, 1.0, 0.3 * eps])
        par = exact.parameters(moments, w0)
        with mpmath.workdps(50):
            I1, I2, I3 = (mpmath.mpf(x) for x in moments)
            w1, w2, w3 = (mpmath.mpf(float(x)) for x in w0)
            e2 = I1 * w1**2 + I2 * w2**2 + I3 * w3**2
            L2 = (I1 * w1) ** 2 + (I2 * w2) ** 2 + (I3 * w3) ** 2
            D = L2 - e2 * I2
            p, q = (I3, I1) if D > 0 else (I1, I3)
            kc2 = abs((p - q) * D / ((p - I2) * (L2 - e2 * q)))
            K = mpmath.ellipk(1 - kc2)
            assert float(par.delta) == pytest.approx(float(D), rel=2 * EPS)
            assert float(par.energy) == pytest.approx(float(e2 / 2), rel=2 * EPS)
            assert float(par.L2) == pytest.approx(float(L2), rel=2 * EPS)
            assert float(par.kc) == pytest.approx(float(mpmath.sqrt(kc2)), rel=4 * EPS)
            assert float(par.K) == pytest.approx(float(K), rel=4 * EPS)
            assert float(1 - par.m) == pytest.approx(float(kc2), rel=1e-15 / float(kc2) + 1e-3)


def test_regime_is_decided_by_exactly_rounded_sign_of_L2_minus_2E_Imid():
    # I3 (I3 - I2) w3² and I1 (I2 - I1) w1² agree to ~1e-16 relative: a naive L² - 2E I2 gets the sign wrong
    moments = (1.0, 2.0, 3.0)
    w1 = 1.0
    w3 = np.nextafter(1 / np.sqrt(3.0), 1.0)
    for w2 in (1.0, 1e3):
        w0 = np.array([w1, w2, w3])
        with mpmath.workdps(60):
            D = 3 * mpmath.mpf(float(w3)) ** 2 - mpmath.mpf(float(w1)) ** 2
        par = exact.parameters(moments, w0)
        assert np.sign(par.delta) == np.sign(float(D))
        assert float(par.delta) == pytest.approx(float(D), rel=4 * EPS)


# --------------------------------------------------------------------------------------------------
# bad input


@pytest.mark.parametrize(
    "body, w0, t, message",
    [
        ((1.0, 2.0, 3.0), [1.0, 2.0], [0.0], "shape"),
        ((1.0, 2.0, 3.0), 1.0, [0.0], "shape"),
        ((1.0, 2.0, 3.0), [1.0, np.nan, 0.0], [0.0], "finite"),
        ((1.0, 2.0, 3.0), [1.0, np.inf, 0.0], [0.0], "finite"),
        ((1.0, 2.0, 3.0), [1.0, 0.0, 0.0], [0.0, np.nan], "t must be finite"),
        ((1.0, 2.0, 3.0), [1.0, 0.0, 0.0], [[0.0, 1.0]], "t must be"),
        ((1.0, 2.0, 3.0), [1.0, 0.0, 0.0], ["a"], "t must be a number or an array of numbers"),
        ((1.0, 2.0, 3.0), ["x", 0.0, 0.0], [0.0], "w0 must be a number"),
        ([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]], [1.0, 0.0, 0.0], [0.0], "one body"),
        ((1.0, -2.0, 3.0), [1.0, 0.0, 0.0], [0.0], "> 0"),
        ((1.0, 1.0, 3.0), [1.0, 0.0, 0.0], [0.0], "triangle"),
        ((1.0, 2.0), [1.0, 0.0, 0.0], [0.0], "three principal moments"),
    ],
)
def test_bad_input_raises_value_error_saying_what_is_wrong(body, w0, t, message):
    with pytest.raises(ValueError, match=message):
        exact.omega(body, w0, t)


def test_bad_input_is_rejected_by_every_entry_point():
    for fn in (exact.period, exact.parameters, exact.first_flip_time, exact.flip_spacing):
        with pytest.raises(ValueError, match="finite"):
            fn((1.0, 2.0, 3.0), [np.nan, 1.0, 0.0])
        with pytest.raises(ValueError, match="shape"):
            fn((1.0, 2.0, 3.0), [1.0, 0.0])


# --------------------------------------------------------------------------------------------------
# one time, fused (exact.omega_at: the addition theorem, no initial argument)


@pytest.mark.parametrize("eps", [1.0, 1e-3, 1e-6, 1e-9, 1e-12])
@pytest.mark.parametrize("regime", [1, -1])
def test_one_time_path_matches_mpmath_near_separatrix_over_ten_flips(eps, regime):
    moments, w0, t, ref, nu = separatrix_case(eps, regime, n=40)
    got = np.stack([exact.omega_at(np.asarray(moments), w0[None, :], float(tj))[0] for tj in t])
    assert vector_error(got, ref).max() < 1e-12
    assert component_error(moments, got, ref, nu).max() < 5e-12


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (1.0, 1.0, 1.8), (1.8, 1.0, 1.8), (2.0, 2.0, 2.0),
                                     (1.0, 1 + 1e-12, 1.5)])
def test_one_time_path_agrees_with_the_time_grid_path(moments):
    rng = np.random.default_rng(11)
    moments = np.asarray(moments)
    spins = [rng.normal(size=(300, 3))]
    for axis in range(3):  # near each axis, on both sides of the separatrix, and zeros in every component
        for eps in (0.3, 1e-4, 1e-9, 1e-13):
            w = eps * rng.normal(size=(50, 3))
            w[:, axis] = rng.choice([-1.0, 1.0], size=50) * (1.0 + rng.random(50))
            spins.append(w)
        w = rng.normal(size=(20, 3))
        w[:, axis] = 0.0
        spins.append(w)
    w0 = np.ascontiguousarray(np.concatenate(spins))
    for t in (0.0, 0.37, -5.0, 20.0):
        got = exact.omega_at(moments, w0, t)
        ref = exact.omega(moments, w0, np.array([t]))[:, 0]
        scale = np.linalg.norm(w0, axis=1)
        # both carry the argument nu t to eps |nu t|: the tolerance grows with it
        assert np.all(np.abs(got - ref).max(axis=1) <= 16 * np.finfo(float).eps * scale * (1.0 + abs(t)))


def test_one_time_path_on_the_separatrix_and_for_steady_spins():
    moments = np.array([3.0, 4.0, 6.0])
    w0 = np.array([[0.2, 0.5, 0.1], [0.0, 1.0, 0.0], [0.0, 0.0, -2.0], [0.0, 0.0, 0.0]])  # separatrix, steady, rest
    t = 7.5
    got = exact.omega_at(moments, w0, t)
    np.testing.assert_allclose(got, exact.omega(moments, w0, np.array([t]))[:, 0], rtol=0, atol=4 * np.finfo(float).eps)
    np.testing.assert_array_equal(exact.omega(moments, w0, t), got)  # a scalar time takes this path
    np.testing.assert_array_equal(got[1:], w0[1:])


def test_one_time_path_hands_spins_within_tiny_of_an_axis_to_the_general_path():
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.array([[1e-200, 1.0, 3e-201], [0.1, 1.0, 0.2]])  # the first below TINY_TRANSVERSE: lifted
    for t in (0.0, 30.0):
        np.testing.assert_array_equal(exact.omega_at(moments, w0, t), exact.omega(moments, w0, np.array([t]))[:, 0])


def test_one_time_path_gives_a_sample_the_same_bits_alone_or_in_any_batch():
    # the chunk's stages run every lane as long as the slowest needs (the AGMs): a lane's bits must not follow
    rng = np.random.default_rng(5)
    w0 = np.concatenate([rng.normal(size=(300, 3)),
                         np.column_stack([1e-9 * rng.normal(size=200), np.ones(200), 1e-9 * rng.normal(size=200)])])
    w0 = np.ascontiguousarray(rng.permutation(w0))
    moments = np.array([1.0, 2.0, 3.0])
    batch = exact.omega_at(moments, w0, 7.0)
    for i in (0, 17, 255, 256, 499):
        np.testing.assert_array_equal(exact.omega_at(moments, w0[i:i + 1], 7.0)[0], batch[i])
    np.testing.assert_array_equal(exact.omega_at(moments, w0[100:400], 7.0), batch[100:400])


# --------------------------------------------------------------------------------------------------
# a time grid (exact.omega: the set-up and the evaluation the scenes call)


@pytest.mark.parametrize("moments", [(1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (1.0, 1.0, 1.8), (2.0, 2.0, 2.0),
                                     (1e-170, 2e-170, 2.5e-170), (1.0, 1 + 1e-12, 1.5)])
def test_the_grid_path_gives_the_scenes_bits_for_each_sample_alone_or_in_any_batch(moments):
    """exact.omega on a time grid: every sample (near each axis, on both sides of the separatrix, zeros, tiny and huge
    scales) gets the bits of solve_rows + omega_rows, which the scenes use, alone or in any batch."""
    rng = np.random.default_rng(12)
    moments = np.asarray(moments)
    spins = [rng.normal(size=(150, 3)), 1e-150 * rng.normal(size=(20, 3)), 1e150 * rng.normal(size=(20, 3))]
    for axis in range(3):
        for eps in (1e-4, 1e-9, 1e-13):
            w = eps * rng.normal(size=(30, 3))
            w[:, axis] = rng.choice([-1.0, 1.0], size=30)
            spins.append(w)
        w = rng.normal(size=(10, 3))
        w[:, axis] = 0.0
        spins.append(w)
    w0 = np.ascontiguousarray(np.concatenate(spins))
    t = np.array([0.0, 0.37, -5.0, 20.0, 1e3])
    sol = exact.solve_rows(np.broadcast_to(moments, w0.shape), w0)
    apart = exact.omega_rows(sol, t[None, :], np.zeros(len(w0), dtype=np.int64))
    out = exact.omega(moments, w0, t)
    np.testing.assert_array_equal(out, apart)
    for i in (0, 63, 64, 200, len(w0) - 1):
        np.testing.assert_array_equal(exact.omega(moments, w0[i], t), out[i])
    np.testing.assert_array_equal(exact.omega(moments, w0[100:300], t), out[100:300])


def test_the_grid_path_lifts_spins_within_tiny_of_an_axis():
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.array([[1e-200, 1.0, 3e-201], [0.1, 1.0, 0.2]])  # the first below TINY_TRANSVERSE: lifted
    t = np.array([0.0, 30.0])
    sol = exact._solve(moments, w0)
    apart = exact.omega_rows(sol, t[None, :], np.zeros(2, dtype=np.int64))
    np.testing.assert_array_equal(exact.omega(moments, w0, t), apart)
    np.testing.assert_array_equal(exact.omega(moments, w0[0], t), apart[0])
