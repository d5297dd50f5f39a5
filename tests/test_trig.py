"""Branch-free sincos and atan2: accuracy in ulps against libm and mpmath, special values, symmetry, vectorisation."""

import math
import re

import numba
import numpy as np
import pytest

from tumble.kernels.jit import FASTMATH
from tumble.kernels.trig import XMAX, atan2, sincos

mpmath = pytest.importorskip("mpmath")


def _njit(py_func):
    """tumble's numba options but uncached: numba's cache does not see edits to an inlined callee, so a
    cached loop could keep testing an old ``sincos``. (Cached code also cannot be inspected as asm.)"""
    return numba.njit(cache=False, fastmath=set(FASTMATH), error_model="numpy")(py_func)


@_njit
def _sincos_array(x, s, c):
    for i in range(x.shape[0]):
        s[i], c[i] = sincos(x[i])


@_njit
def _libm_array(x, s, c):
    for i in range(x.shape[0]):
        s[i] = math.sin(x[i])
        c[i] = math.cos(x[i])


def ours(x):
    x = np.ascontiguousarray(x, dtype=float)
    s, c = np.empty_like(x), np.empty_like(x)
    _sincos_array(x, s, c)
    return s, c


def libm(x):
    x = np.ascontiguousarray(x, dtype=float)
    s, c = np.empty_like(x), np.empty_like(x)
    _libm_array(x, s, c)
    return s, c


def ulps(got, ref):
    """|got - ref| in units of the last place of ``ref`` (float64 reference)."""
    return np.abs(got - ref) / np.spacing(np.abs(ref))


def mp_ulps(x, got_s, got_c):
    """Errors of ``got_s, got_c`` in ulps of the exact sin x, cos x (mpmath, 200 bits)."""
    es, ec = [], []
    with mpmath.workprec(200):
        for xi, si, ci in zip(x, got_s, got_c):
            s, c = mpmath.sin(mpmath.mpf(float(xi))), mpmath.cos(mpmath.mpf(float(xi)))
            es.append(float(abs(mpmath.mpf(float(si)) - s)) / math.ulp(float(s)))
            ec.append(float(abs(mpmath.mpf(float(ci)) - c)) / math.ulp(float(c)))
    return np.array(es), np.array(ec)


def signed_uniform(rng, lo, hi, n):
    return rng.uniform(lo, hi, n) * rng.choice([-1.0, 1.0], n)


RANGES = [(0.0, math.pi / 4), (0.0, 10.0), (10.0, 1e3), (1e3, 1e5), (1e5, 1e9), (1e9, XMAX)]


# --- accuracy ----------------------------------------------------------------------------------------


def test_agrees_with_libm_to_one_ulp_on_a_dense_grid():
    x = np.linspace(-20.0, 20.0, 2_000_001)
    s, c = ours(x)
    rs, rc = libm(x)
    assert ulps(s, rs).max() <= 1.0
    assert ulps(c, rc).max() <= 1.0


@pytest.mark.parametrize("lo, hi", RANGES)
def test_agrees_with_libm_to_one_ulp_on_random_angles(lo, hi, rng):
    x = signed_uniform(rng, lo, hi, 200_000)
    s, c = ours(x)
    rs, rc = libm(x)
    assert ulps(s, rs).max() <= 1.0
    assert ulps(c, rc).max() <= 1.0


@pytest.mark.parametrize("lo, hi", RANGES)
def test_error_below_one_ulp_against_mpmath(lo, hi, rng):
    # measured max 0.75 ulp over 20 000 samples per range
    x = signed_uniform(rng, lo, hi, 400)
    es, ec = mp_ulps(x, *ours(x))
    assert es.max() < 1.0
    assert ec.max() < 1.0


# k such that the double nearest k pi/2 is among the closest to it (found by an exact big-integer scan of
# k < 2^22 and of 2e6 values of k from 5e8, 2e10 and 6e11): there |r| is ~1e-7 ulp(x), and only a
# reduction carried well beyond 106 bits keeps sin or cos of them accurate.
HARD_K = [1, 2, 3, 4, 5, 100, 29327, 57916, 58285, 1081409, 2162818, 2717817, 500256697, 500959614,
          20000261117, 20001087723, 600000267378, 600000967306]


def test_full_relative_accuracy_next_to_multiples_of_half_pi():
    x0 = np.array([float(k * mpmath.pi / 2) for k in HARD_K])
    x = np.concatenate([x0, np.nextafter(x0, np.inf), np.nextafter(x0, -np.inf), -x0])
    s, c = ours(x)
    es, ec = mp_ulps(x, s, c)
    # the small one of the pair is ~1e-16 .. 1e-7 here and must still be accurate relative to itself
    assert np.minimum(np.abs(s), np.abs(c)).min() < 1e-15
    assert es.max() < 1.0  # measured 0.48: as good as far from the multiples
    assert ec.max() < 1.0


def test_tiny_angles_give_sin_x_equal_x_and_cos_equal_one(rng):
    x = np.concatenate([[0.0, 5e-324, 1e-310, 2.0**-1022, 1e-300], 10.0 ** rng.uniform(-300, -9, 1000)])
    x = np.concatenate([x, -x])
    s, c = ours(x)
    np.testing.assert_array_equal(s, x)
    np.testing.assert_array_equal(c, 1.0)


def test_pythagorean_identity_within_two_ulps(rng):
    x = np.concatenate([signed_uniform(rng, lo, hi, 20_000) for lo, hi in RANGES])
    s, c = ours(x)
    assert np.abs(s * s + c * c - 1.0).max() <= 2 * np.finfo(float).eps


# --- special values and symmetry ---------------------------------------------------------------------


def test_nan_inf_and_beyond_xmax_give_nan():
    x = np.array([np.nan, np.inf, -np.inf, np.nextafter(XMAX, np.inf), -2 * XMAX, 1e300, -1e300])
    s, c = ours(x)
    assert np.isnan(s).all()
    assert np.isnan(c).all()


def test_xmax_itself_is_finite_and_accurate():
    x = np.array([XMAX, -XMAX, np.nextafter(XMAX, 0.0)])
    s, c = ours(x)
    es, ec = mp_ulps(x, s, c)
    assert es.max() < 1.0 and ec.max() < 1.0


def test_sin_is_odd_and_cos_even_bit_for_bit(rng):
    x = np.concatenate([signed_uniform(rng, lo, hi, 20_000) for lo, hi in RANGES[:4]])
    s, c = ours(x)
    sm, cm = ours(-x)
    np.testing.assert_array_equal(sm, -s)
    np.testing.assert_array_equal(cm, c)


def test_sin_is_odd_and_cos_even_to_one_ulp_at_large_angles(rng):
    # far out, x 2/pi + 1/2 can round to an integer and the two signs pick neighbouring quadrants
    x = np.concatenate([signed_uniform(rng, lo, hi, 20_000) for lo, hi in RANGES[4:]])
    s, c = ours(x)
    sm, cm = ours(-x)
    assert ulps(-sm, s).max() <= 1.0
    assert ulps(cm, c).max() <= 1.0


def test_quadrant_signs_at_the_axes():
    q = np.arange(-8, 9)
    s, c = ours(q * (math.pi / 2))
    np.testing.assert_allclose(s, np.sin(q * np.pi / 2), atol=1e-15)
    np.testing.assert_allclose(c, np.cos(q * np.pi / 2), atol=1e-15)


# --- vectorisation -----------------------------------------------------------------------------------


def _rotate(x, y, theta):
    for i in range(x.shape[0]):
        s, c = sincos(theta[i])
        x[i], y[i] = c * x[i] + s * y[i], c * y[i] - s * x[i]


def _rotate_libm(x, y, theta):
    for i in range(x.shape[0]):
        s, c = math.sin(theta[i]), math.cos(theta[i])
        x[i], y[i] = c * x[i] + s * y[i], c * y[i] - s * x[i]


def _asm(py_func):
    """Assembly of ``py_func`` compiled like tumble's kernels (uncached)."""
    f = _njit(py_func)
    a = np.zeros(8)
    f(a, a.copy(), a.copy())
    return next(iter(f.inspect_asm().values()))


PACKED_FMA = re.compile(r"\bvf(n)?m(add|sub)\d{3}pd\s+[^\n]*%[yz]mm")
TRIG_CALL = re.compile(r"(call\w*|jmp\w*|movabsq)\s+\$?_*(sin|cos|sincos)(@\w+)?\b")


def _has_avx2_and_fma():
    try:
        import llvmlite.binding as llvm

        features = llvm.get_host_cpu_features()
    except Exception:  # pragma: no cover - depends on llvmlite build
        return False
    return bool(features.get("avx2") and features.get("fma"))


needs_avx2 = pytest.mark.skipif(
    not _has_avx2_and_fma(), reason="host CPU lacks AVX2+FMA: LLVM cannot emit packed FMA on ymm/zmm"
)


@needs_avx2
def test_rotation_loop_compiles_to_packed_fma_without_trig_calls():
    asm = _asm(_rotate)
    assert PACKED_FMA.search(asm), "no packed vfmadd/vfmsub on ymm/zmm: the loop did not vectorise"
    assert not TRIG_CALL.search(asm), "a sin/cos call is left in the loop"


@needs_avx2
def test_vectorisation_check_flags_a_libm_loop():
    # the detector itself: the same loop with math.sin/math.cos keeps its libm calls
    assert TRIG_CALL.search(_asm(_rotate_libm))


# --- atan2 -------------------------------------------------------------------------------------------


@_njit
def _atan2_array(y, x, out):
    for i in range(x.shape[0]):
        out[i] = atan2(y[i], x[i])


def ours_atan2(y, x):
    y, x = np.broadcast_arrays(np.asarray(y, dtype=float), np.asarray(x, dtype=float))
    out = np.empty(x.shape)
    _atan2_array(np.ascontiguousarray(y).ravel(), np.ascontiguousarray(x).ravel(), out.ravel())
    return out


def _scattered_points(rng, n):
    """Points in every octant, over 20 decades of ratio and of scale, plus the diagonals and the axes."""
    x = rng.standard_normal(n) * 10.0 ** rng.uniform(-150, 150, n)
    y = x * rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-10, 10, n)
    diagonal = rng.standard_normal(200)
    x = np.concatenate([x, diagonal, diagonal, diagonal * (1 + 1e-9), np.ones(4), -np.ones(4)])
    y = np.concatenate([y, diagonal, -diagonal, diagonal, 1e-300 * np.ones(4), [1e-20, -1e-20, 1e-300, -1e-300]])
    return y, x


def test_atan2_within_two_ulps_of_libm(rng):
    y, x = _scattered_points(rng, 200_000)
    assert ulps(ours_atan2(y, x), np.arctan2(y, x)).max() <= 2.0


def test_atan2_within_two_ulps_of_mpmath(rng):
    y, x = _scattered_points(rng, 400)
    got = ours_atan2(y, x)
    with mpmath.workprec(200):
        exact = [mpmath.atan2(mpmath.mpf(float(b)), mpmath.mpf(float(a))) for b, a in zip(y, x)]
    errors = [float(abs(mpmath.mpf(float(g)) - e)) / math.ulp(float(e)) for g, e in zip(got, exact)]
    assert max(errors) <= 2.0


def test_atan2_axes_quadrants_and_special_values():
    cases = {(0.0, 1.0): 0.0, (1.0, 0.0): math.pi / 2, (0.0, -1.0): math.pi, (-1.0, 0.0): -math.pi / 2,
             (1.0, 1.0): math.pi / 4, (1.0, -1.0): 3 * math.pi / 4, (-1.0, -1.0): -3 * math.pi / 4,
             (math.inf, 1.0): math.pi / 2, (1.0, math.inf): 0.0, (0.0, 0.0): 0.0, (1e-320, -1.0): math.pi}
    y, x = np.array(list(cases)).T
    assert ours_atan2(y, x).tolist() == list(cases.values())
    assert np.isnan(ours_atan2([np.nan, 1.0, np.nan, math.inf], [1.0, np.nan, np.nan, math.inf])).all()


def test_atan2_is_odd_in_y_bit_for_bit(rng):
    y, x = _scattered_points(rng, 10_000)
    assert np.array_equal(ours_atan2(-y, x), -ours_atan2(y, x))


def _phases(y, x, out):
    for i in range(x.shape[0]):
        out[i] = atan2(y[i], x[i])


def _phases_libm(y, x, out):
    for i in range(x.shape[0]):
        out[i] = math.atan2(y[i], x[i])


PACKED_DIV = re.compile(r"\bvdivpd\s+[^\n]*%[yz]mm")
ATAN_CALL = re.compile(r"(call\w*|jmp\w*|movabsq)\s+\$?_*atan2?(@\w+)?\b")


@needs_avx2
def test_atan2_loop_compiles_to_packed_code_without_libm_calls():
    # as the phase fit compiles it: without contraction (tumble.kernels.fits)
    f = numba.njit(cache=False, fastmath=set(FASTMATH - {"contract"}), error_model="numpy")(_phases)
    a = np.ones(8)
    f(a, a.copy(), a.copy())
    asm = next(iter(f.inspect_asm().values()))
    assert PACKED_DIV.search(asm), "no packed vdivpd on ymm/zmm: the loop did not vectorise"
    assert not ATAN_CALL.search(asm), "an atan/atan2 call is left in the loop"
    # the detector itself: the libm loop keeps its calls
    g = _njit(_phases_libm)
    g(a, a.copy(), a.copy())
    assert ATAN_CALL.search(next(iter(g.inspect_asm().values())))
