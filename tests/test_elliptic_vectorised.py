"""The vectorised closed-form kernel: batched time grids, agreement with the scalar kernel it replaced,
its branch-free exponentials, and the assembly of its time loops."""

import math
import re

import numba
import numpy as np
import pytest

from tumble.kernels.closed_form import elliptic as ell
from tumble.kernels.jit import FASTMATH
from tumble.kernels.threads import in_parallel
from tumble.physics import exact

mpmath = pytest.importorskip("mpmath")

EPS = np.finfo(float).eps
MOMENTS = (1.0, 2.0, 3.0)
# k' of the kernel tests: both cores, both sides of the switch between them, the short hyperbolic series
KCS = [1.0, 0.9, 0.7, ell.KC_HYPERBOLIC * (1 + 2 * EPS), ell.KC_HYPERBOLIC, ell.KC_HYPERBOLIC * (1 - EPS), 0.3,
       0.1, 0.02, 1.2e-3, 1e-3, 1e-8, 1e-12, 1e-15, 1e-30, 1e-300]


def _njit(py_func):
    """tumble's numba options, uncached (cached code cannot be inspected, and numba's cache does not see
    edits to inlined callees)."""
    return numba.njit(cache=False, fastmath=set(FASTMATH), error_model="numpy")(py_func)


def spins(rng, n):
    """Spins of every kind: near the largest and smallest axes, near the intermediate axis at distances
    1e-1 .. 1e-13 on both sides, on the separatrix, and steady rotations."""
    w = rng.normal(size=(n, 3))
    near_mid = rng.normal(size=(n // 2, 3)) * 10.0 ** rng.uniform(-13, -1, (n // 2, 1))
    near_mid[:, 1] = rng.choice([-1.0, 1.0], n // 2)
    w[: n // 2] = near_mid
    w[-1] = [0.2, 0.5, 0.1]  # the separatrix of (3, 4, 6) below is not that of MOMENTS: elliptic here
    w[-2] = [0.0, 1.0, 0.0]
    return w


def kernel_inputs(body, w0):
    sol = exact._solve(body, w0)
    return sol.kind, sol.amp, sol.cols, sol.kc, sol.phase0, sol.nu


def with_constants(args):
    """The vectorised kernel's inputs from the reference kernel's: ``K`` and the hyperbolic ``(h, q)`` added, by
    the set-up's own formulas."""
    kind, amp, cols, kc, phase0, nu = args
    elliptic = kind == ell.KIND_ELLIPTIC
    K = np.array([0.5 * np.pi / ell.agm(1.0, k) if e else np.inf for k, e in zip(kc, elliptic)])
    nome = np.zeros((2, kc.shape[0]))
    for i in np.flatnonzero(elliptic & (kc < ell.KC_HYPERBOLIC)):
        nome[:, i] = ell.hyperbolic_nome(kc[i], K[i])
    return kind, amp, cols, kc, K, nome, phase0, nu


def omega_rows(args, times, row):
    out = np.empty((row.shape[0], times.shape[1], 3))
    ell.torque_free_omega(*with_constants(args), np.ascontiguousarray(times), row.astype(np.int64), out)
    return out


def synthetic(kcs, phases, rates):
    """Kernel inputs for elliptic samples of given k' with unit amplitudes, columns (cn, sn, dn)."""
    n = len(kcs)
    return (np.full(n, ell.KIND_ELLIPTIC, dtype=np.int64), np.ones((n, 3)), np.tile([0, 1, 2], (n, 1)),
            np.asarray(kcs, dtype=float), np.asarray(phases, dtype=float), np.asarray(rates, dtype=float))


def reference(args, t):
    out = np.empty((args[0].shape[0], t.shape[0], 3))
    in_parallel(ell._torque_free_omega_reference, len(out), *args, np.ascontiguousarray(t), out)
    return out


# --- batched time grids ------------------------------------------------------------------------------


@pytest.mark.parametrize("body", [MOMENTS, (3.0, 4.0, 6.0), (1.0, 1.0, 1.8)])
def test_batched_rows_give_the_same_bits_as_one_call_per_sample(body, rng):
    w0 = spins(rng, 40)
    if body == (3.0, 4.0, 6.0):
        w0[::3] = [0.2, 0.5, 0.1]  # on the separatrix
    args = kernel_inputs(body, w0)
    n = w0.shape[0]
    times = np.stack([np.linspace(0.0, 50.0, 37), np.linspace(-3.0, 1e4, 37), rng.uniform(-1e3, 1e3, 37)])
    row = rng.integers(0, 3, n)
    batched = omega_rows(args, times, row)
    for i in range(n):
        one = omega_rows(tuple(a[i:i + 1] for a in args), times[row[i]][None, :], np.zeros(1))
        assert np.array_equal(batched[i], one[0]), i


def test_a_value_does_not_depend_on_its_position_in_the_time_grid(rng):
    # the vectorised loop body and its scalar remainder give the same bits
    args = kernel_inputs(MOMENTS, spins(rng, 64))
    t = rng.uniform(-100.0, 100.0, 23)
    n = args[0].shape[0]
    a = omega_rows(args, t[None, :], np.zeros(n))
    shift = np.roll(t, 7)
    b = omega_rows(args, shift[None, :], np.zeros(n))
    assert np.array_equal(np.roll(a, 7, axis=1), b)
    single = np.stack([omega_rows(args, t[j:j + 1][None, :], np.zeros(n))[:, 0] for j in range(t.size)], axis=1)
    assert np.array_equal(a, single)


def test_exact_omega_is_unchanged_by_batching_its_samples(rng):
    w0 = spins(rng, 16)
    t = np.linspace(0.0, 30.0, 41)
    together = exact.omega(MOMENTS, w0, t)
    for i in range(w0.shape[0]):
        assert np.array_equal(exact.omega(MOMENTS, w0[i], t), together[i])


# --- agreement with the scalar kernel it replaced ----------------------------------------------------


def _bound(ref, s):
    """A few ulps relative, plus the rounding of the argument times the slope near zeros of sn and cn
    (both kernels reduce ``s`` by a rounded ``2K``, though not identically: ``s/(2K)`` against
    ``s * (1/(2K))``)."""
    sn, cn, dn = ref[..., 1], ref[..., 0], ref[..., 2]
    slope = np.stack([np.abs(sn * dn), np.abs(cn * dn), np.abs(sn * cn)], axis=-1)
    return 8 * EPS * np.abs(ref) + 4 * EPS * (1 + np.abs(s))[..., None] * slope


@pytest.mark.parametrize("kc", KCS)
def test_agrees_with_the_scalar_kernel_to_a_few_ulps(kc, rng):
    K = 0.5 * np.pi / ell.agm(1.0, kc)
    n = 16
    args = synthetic(np.full(n, kc), rng.uniform(-3 * K, 3 * K, n), rng.uniform(-2.0, 2.0, n))
    t = np.concatenate([[0.0], rng.uniform(-10 * K, 10 * K, 200)])
    new = omega_rows(args, t[None, :], np.zeros(n))
    old = reference(args, t)
    s = args[4][:, None] + args[5][:, None] * t[None, :]
    assert np.all(np.abs(new - old) <= _bound(old, s))


def test_separatrix_agrees_with_libm_tanh_and_sech(rng):
    n = 8
    args = (np.full(n, ell.KIND_SEPARATRIX, dtype=np.int64), np.ones((n, 3)), np.tile([0, 1, 2], (n, 1)),
            np.zeros(n), rng.uniform(-5, 5, n), rng.uniform(-3, 3, n))
    t = np.concatenate([np.linspace(-300.0, 300.0, 301), rng.uniform(-1e-8, 1e-8, 20)])
    new = omega_rows(args, t[None, :], np.zeros(n))
    old = reference(args, t)
    assert np.all(np.abs(new - old) <= 4 * EPS * np.abs(old))
    assert np.array_equal(new[..., 0], new[..., 2])


def test_symmetric_top_has_dn_exactly_one(rng):
    n = 8
    args = synthetic(np.ones(n), rng.uniform(-3, 3, n), rng.uniform(-2, 2, n))
    out = omega_rows(args, rng.uniform(-1e3, 1e3, 101)[None, :], np.zeros(n))
    assert np.all(out[..., 2] == 1.0)
    assert np.max(np.abs(out[..., 0] ** 2 + out[..., 1] ** 2 - 1)) < 4 * EPS


@pytest.mark.parametrize("kc", [0.9, ell.KC_HYPERBOLIC, 0.1, 1e-3, 1e-9, 1e-14])
def test_core_matches_mpmath_on_a_quarter_period(kc, rng):
    # phase0 = 0, nu = 1: the kernel evaluates at s = u - K exactly; on 0 <= s <= K the reduction is exact
    # (x = s, or x = K - s by Sterbenz), so this measures the cores and the quotients alone
    K = 0.5 * np.pi / ell.agm(1.0, kc)
    s = np.concatenate([rng.uniform(0.0, K, 60), [1e-9, 0.5 * K, np.nextafter(0.5 * K, K)]])
    out = omega_rows(synthetic([kc], [0.0], [1.0]), s[None, :], np.zeros(1))[0]
    near = s <= 0.5 * K
    x = np.where(near, s, K - s)
    with mpmath.workdps(40):
        m = 1 - mpmath.mpf(kc) ** 2
        k_c = mpmath.mpf(kc)
        ref = []
        for xi, ne in zip(x, near):
            sn, cn, dn = (mpmath.ellipfun(f, mpmath.mpf(float(xi)), m=m) for f in ("sn", "cn", "dn"))
            ref.append([-k_c * sn / dn, cn / dn, k_c / dn] if ne else [-cn, sn, dn])  # (cn, sn, dn) of u
        ref = np.array(ref, dtype=float)
    # measured up to 3.7 eps (the scalar kernel: 3.8)
    assert np.max(np.abs(out - ref) / np.abs(ref)) < 6 * EPS


# --- branch-free exponentials ------------------------------------------------------------------------


@_njit
def _exp_arrays(x, e, em1, ep):
    for i in range(x.shape[0]):
        e[i], em1[i] = ell._exp_expm1(x[i])
        _, _, ep[i] = ell._exp_both(max(x[i], -700.0))


def test_exponentials_are_accurate_to_about_one_ulp(rng):
    x = -np.concatenate([10.0 ** rng.uniform(-300, -1, 300), rng.uniform(0, 1, 300), rng.uniform(1, 740, 300),
                         [0.0, 1e-310, 0.34657359027997264, 0.6931471805599453, 36.7368005696771]])
    e, em1, ep = np.empty_like(x), np.empty_like(x), np.empty_like(x)
    _exp_arrays(x, e, em1, ep)
    with mpmath.workdps(40):
        ref_e = np.array([float(mpmath.exp(mpmath.mpf(v))) for v in x])
        ref_m1 = np.array([float(mpmath.expm1(mpmath.mpf(v))) for v in x])
        ref_p = np.array([float(mpmath.exp(-mpmath.mpf(max(v, -700.0)))) for v in x])
    assert np.all(np.abs(e - ref_e) <= 1.5 * np.spacing(ref_e))
    assert np.all(np.abs(em1 - ref_m1) <= 1.5 * np.spacing(np.abs(ref_m1)))
    assert np.all(np.abs(ep - ref_p) <= 1.5 * np.spacing(ref_p))


def test_exponentials_underflow_to_zero_and_pass_nan():
    x = np.array([-800.0, -1e4, -np.inf, np.nan])
    e, em1, ep = np.empty_like(x), np.empty_like(x), np.empty_like(x)
    _exp_arrays(x, e, em1, ep)
    assert np.array_equal(e[:3], [0.0, 0.0, 0.0]) and np.array_equal(em1[:3], [-1.0, -1.0, -1.0])
    assert math.isnan(e[3]) and math.isnan(em1[3])


# --- assembly ----------------------------------------------------------------------------------------


def _has_avx2_and_fma():
    try:
        import llvmlite.binding as llvm

        features = llvm.get_host_cpu_features()
    except (ImportError, AttributeError, RuntimeError):  # pragma: no cover - depends on llvmlite build
        return False
    return bool(features.get("avx2") and features.get("fma"))


PACKED_FMA = re.compile(r"\bvf(n)?m(add|sub)\d{3}pd\s+[^\n]*%[yz]mm")
LIBM_CALL = re.compile(r"(call\w*|jmp\w*|movabsq)\s+\$?_*(sin|cos|sincos|asin|exp|expm1|tanh)(@\w+)?\b")


def _row_asm(name):
    """Assembly of the row function ``name`` (a subroutine of the evaluation: its Python function) compiled alone and
    uncached, after one call (``_omega_row_hyperbolic``'s long and short series each in a loop of its own, both in the
    assembly)."""
    f = _njit(getattr(ell, name))
    t = np.linspace(0.0, 1.0, 16)
    out = np.empty(48)
    W = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    if name == "_omega_row_landen":
        kap, quarter_m, P = ell._landen_constants(0.7)
        f(0.1, 1.0, t, 2.0, 0.7, kap, quarter_m, P, out, W)
    elif name == "_omega_row_separatrix":
        f(0.1, 1.0, t, out, W)
    else:
        dcoef, ccoef, scoef = ell._series_constants(1e-3)
        f(0.1, 1.0, t, 2.0, 0.01, 1.0, 1.0, 1e-3, dcoef, ccoef, scoef, out, W, False)
    return next(iter(f.inspect_asm().values()))


@pytest.mark.skipif(not _has_avx2_and_fma(), reason="host CPU lacks AVX2+FMA")
@pytest.mark.parametrize("name, loops", [("_omega_row_landen", 1), ("_omega_row_hyperbolic", 2),
                                         ("_omega_row_separatrix", 1)])
def test_time_loops_compile_to_packed_fma_without_libm_calls(name, loops):
    asm = _row_asm(name)
    assert PACKED_FMA.search(asm), "no packed vfmadd/vfmsub on ymm/zmm: the time loop did not vectorise"
    assert len(re.findall(r"vmovupd\s+%[yz]mm", asm)) >= loops, "a time loop's stores are not packed"
    assert not LIBM_CALL.search(asm), "a libm call is left in the time loop"


@pytest.mark.parametrize("kc", [0.9, 0.1, 1e-6])
def test_a_non_finite_argument_gives_nan_not_a_number_that_looks_fine(kc):
    args = synthetic([kc, kc], [0.0, 0.0], [1.0, 1.0])
    t = np.array([[np.nan, np.inf, -np.inf, 1.0]])
    out = omega_rows(args, t, np.zeros(2))
    assert np.all(np.isnan(out[:, :3])) and np.all(np.isfinite(out[:, 3]))
    sep = (np.full(1, ell.KIND_SEPARATRIX, dtype=np.int64), np.ones((1, 3)), np.array([[0, 1, 2]]), np.zeros(1),
           np.zeros(1), np.ones(1))
    assert np.all(np.isnan(omega_rows(sep, np.array([[np.nan]]), np.zeros(1))))


PACKED_SQRT = re.compile(r"\bvsqrtpd\s+[^\n]*%[yz]mm")


@pytest.mark.slow  # compiles the chunk uncached: 15 s
@pytest.mark.skipif(not _has_avx2_and_fma(), reason="host CPU lacks AVX2+FMA")
def test_the_one_time_kernel_puts_samples_in_simd_lanes():
    # the set-up, the AGMs and the addition take packed square roots: the stages' loops over samples vectorised
    f = _njit(ell._omega_at_chunk.py_func)
    w = np.random.default_rng(2).normal(size=(40, 3))
    out = np.empty((40, 3))
    assert f(np.array(MOMENTS), w, 1.5, out, 0, 40) == (0, 0)
    asm = next(iter(f.inspect_asm().values()))
    assert len(PACKED_SQRT.findall(asm)) >= 8, "the loops over samples did not vectorise"
    np.testing.assert_allclose(out, exact.omega(MOMENTS, w, np.array([1.5]))[:, 0], rtol=0, atol=1e-14)
