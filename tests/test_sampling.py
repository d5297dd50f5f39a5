"""Perturbed initial spins: chunked, index-stable random streams; the three tilt distributions; the
energy and momentum constraints; input validation."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from tumble.engine import sampling
from tumble.engine.sampling import (
    CHUNK,
    DISTRIBUTIONS,
    chunk_count,
    chunk_ranges,
    perturbed_spins,
    seed_entropy,
    transverse_axes,
)
from tumble.physics.bodies import Body

BODY = (1.0, 2.0, 3.0)
# Long enough for three chunk boundaries and a partial last chunk.
TOTAL = 3 * CHUNK + 17


def tilt_and_azimuth(w, axis, spin):
    """Angle θ of each spin from ``sign(spin) e_axis`` and azimuth φ in [0, 2π) in the (e_b, e_c) plane."""
    b, c = transverse_axes(axis)
    v = np.sign(spin) * w
    theta = np.arctan2(np.hypot(v[:, b - 1], v[:, c - 1]), v[:, axis - 1])
    phi = np.mod(np.arctan2(v[:, c - 1], v[:, b - 1]), 2 * np.pi)
    return theta, phi


@pytest.fixture(scope="module", params=DISTRIBUTIONS)
def full_draw(request):
    """The whole reference ensemble, drawn once per distribution."""
    kwargs = dict(seed=2024, distribution=request.param)
    return kwargs, perturbed_spins(BODY, 2, 1.5, 0.05, TOTAL, **kwargs)


# --- Streams and chunks ---------------------------------------------------------------------------------


def test_chunk_stream_is_the_spawned_child_of_the_seed():
    children = np.random.SeedSequence(77).spawn(4)
    for j, child in enumerate(children):
        direct = sampling._chunk_rng(77, j).random(5)
        np.testing.assert_array_equal(direct, np.random.default_rng(child).random(5))


def test_samples_follow_the_documented_formula_from_the_chunk_uniforms():
    axis, spin, alpha = 3, -0.7, 0.2
    w = perturbed_spins(BODY, axis, spin, alpha, CHUNK + 10, seed=5)
    b, c = transverse_axes(axis)
    for j in range(2):
        u = np.random.default_rng(np.random.SeedSequence(5).spawn(j + 1)[j]).random((CHUNK, 2))
        phi = 2 * np.pi * u[:, 0]
        expected = np.zeros((CHUNK, 3))
        expected[:, axis - 1] = np.cos(alpha)
        expected[:, b - 1] = np.sin(alpha) * np.cos(phi)
        expected[:, c - 1] = np.sin(alpha) * np.sin(phi)
        rows = w[j * CHUNK:(j + 1) * CHUNK]
        np.testing.assert_allclose(rows, spin * expected[: len(rows)], rtol=0, atol=1e-15)


def test_seed_zero_ensemble_is_pinned():
    # A canary: if numpy's SeedSequence/PCG64 streams or our chunk layout ever change, stored seeds stop
    # reproducing old ensembles. (Tolerance allows last-bit differences of sin/cos between CPUs.)
    w = perturbed_spins(BODY, 1, 1.0, 1e-2, 4, seed=0)
    expected = [
        [0.9999500004166653, 0.00936396669834173, -0.0035089591595597],
        [0.9999500004166653, -0.00172900451462242, -0.00984922383233959],
        [0.9999500004166653, -0.00885147465306924, 0.0046527479167889],
        [0.9999500004166653, 0.00937243204963615, 0.00348628515558665],
    ]
    np.testing.assert_allclose(w, expected, rtol=1e-14, atol=0)


@pytest.mark.parametrize(
    "start, stop",
    [(0, 1), (0, CHUNK - 1), (0, CHUNK), (0, CHUNK + 1), (CHUNK - 1, CHUNK + 1), (CHUNK, 2 * CHUNK),
     (CHUNK + 1, 3 * CHUNK - 1), (3 * CHUNK - 1, TOTAL), (TOTAL - 1, TOTAL), (123, 123)],
)
def test_slice_is_bit_identical_to_the_rows_of_the_full_draw(full_draw, start, stop):
    kwargs, full = full_draw
    part = perturbed_spins(BODY, 2, 1.5, 0.05, TOTAL, start=start, stop=stop, **kwargs)
    assert part.shape == (stop - start, 3)
    np.testing.assert_array_equal(part, full[start:stop])


@pytest.mark.parametrize("samples", [1, 2, CHUNK - 1, CHUNK, CHUNK + 1, 2 * CHUNK + 3])
def test_sample_does_not_depend_on_ensemble_size(full_draw, samples):
    kwargs, full = full_draw
    np.testing.assert_array_equal(perturbed_spins(BODY, 2, 1.5, 0.05, samples, **kwargs), full[:samples])


def test_concatenated_slices_equal_the_whole(full_draw):
    kwargs, full = full_draw
    cuts = [0, 1, 1000, CHUNK - 1, CHUNK, CHUNK + 1, 2 * CHUNK + 500, TOTAL]
    parts = [perturbed_spins(BODY, 2, 1.5, 0.05, TOTAL, start=a, stop=b, **kwargs)
             for a, b in zip(cuts[:-1], cuts[1:])]
    np.testing.assert_array_equal(np.concatenate(parts), full)
    per_chunk = [perturbed_spins(BODY, 2, 1.5, 0.05, TOTAL, start=a, stop=b, **kwargs)
                 for a, b in chunk_ranges(TOTAL)]
    np.testing.assert_array_equal(np.concatenate(per_chunk), full)


def test_threads_drawing_one_chunk_each_reproduce_the_whole(full_draw):
    kwargs, full = full_draw
    with ThreadPoolExecutor(max_workers=2) as pool:
        parts = list(pool.map(lambda r: perturbed_spins(BODY, 2, 1.5, 0.05, TOTAL, start=r[0], stop=r[1],
                                                        **kwargs), chunk_ranges(TOTAL)[::-1]))
    np.testing.assert_array_equal(np.concatenate(parts[::-1]), full)


# One reference ensemble for the property test below (drawn once, at import).
_REFERENCE = perturbed_spins(BODY, 1, 0.3, 0.01, TOTAL, seed=9, distribution="filled_cone",
                             constraint="energy")


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_any_slice_of_any_ensemble_matches_the_reference_rows(data):
    samples = data.draw(st.integers(1, TOTAL), label="samples")
    start = data.draw(st.integers(0, samples), label="start")
    stop = data.draw(st.integers(start, samples), label="stop")
    part = perturbed_spins(BODY, 1, 0.3, 0.01, samples, seed=9, distribution="filled_cone",
                           constraint="energy", start=start, stop=stop)
    np.testing.assert_array_equal(part, _REFERENCE[start:stop])


def test_slice_draws_only_the_chunks_it_covers(monkeypatch):
    drawn = []
    real = sampling._chunk_rng

    def spy(entropy, j):
        drawn.append(j)
        return real(entropy, j)

    monkeypatch.setattr(sampling, "_chunk_rng", spy)
    perturbed_spins(BODY, 1, samples=10 * CHUNK, start=3 * CHUNK - 1, stop=4 * CHUNK + 1)
    assert drawn == [2, 3, 4]
    drawn.clear()
    perturbed_spins(BODY, 1, samples=10 * CHUNK, start=5, stop=5)
    assert drawn == []


def test_chunk_count_and_ranges_tile_the_ensemble():
    assert [chunk_count(n) for n in (1, CHUNK - 1, CHUNK, CHUNK + 1, 3 * CHUNK)] == [1, 1, 1, 2, 3]
    ranges = chunk_ranges(TOTAL)
    assert len(ranges) == chunk_count(TOTAL)
    assert ranges[0][0] == 0 and ranges[-1][1] == TOTAL
    assert all(a[1] == b[0] for a, b in zip(ranges[:-1], ranges[1:]))
    assert all(hi - lo == CHUNK for lo, hi in ranges[:-1])


# --- Seeds ----------------------------------------------------------------------------------------------


def test_same_seed_gives_the_same_spins_and_different_seeds_differ():
    a = perturbed_spins(BODY, 2, samples=100, seed=1)
    np.testing.assert_array_equal(a, perturbed_spins(BODY, 2, samples=100, seed=1))
    np.testing.assert_array_equal(a, perturbed_spins(BODY, 2, samples=100, seed=np.int64(1)))
    b = perturbed_spins(BODY, 2, samples=100, seed=2)
    assert not np.any(np.all(a == b, axis=1))


def test_fresh_seed_is_returned_and_reproduces_the_draw():
    w1, e1 = perturbed_spins(BODY, 3, samples=50, seed=None, return_entropy=True)
    w2, e2 = perturbed_spins(BODY, 3, samples=50, seed=None, return_entropy=True)
    assert e1 != e2 and not np.array_equal(w1, w2)
    np.testing.assert_array_equal(perturbed_spins(BODY, 3, samples=50, seed=e1), w1)
    assert perturbed_spins(BODY, 3, samples=5, seed=42, return_entropy=True)[1] == 42


def test_seed_entropy_is_the_seed_or_fresh_entropy():
    assert seed_entropy(12) == 12
    assert seed_entropy(np.uint32(7)) == 7 and type(seed_entropy(np.uint32(7))) is int
    fresh = seed_entropy(None)
    assert isinstance(fresh, int) and fresh >= 0 and fresh != seed_entropy(None)


# --- Distributions --------------------------------------------------------------------------------------


@pytest.mark.parametrize("axis", [1, 2, 3])
@pytest.mark.parametrize("alpha", [0.0, 1e-9, 1e-3, 0.4, 1.5])
def test_cone_spins_lie_exactly_amplitude_from_the_axis(axis, alpha):
    w = perturbed_spins(BODY, axis, 2.5, alpha, 2000, seed=3)
    theta, _ = tilt_and_azimuth(w, axis, 2.5)
    np.testing.assert_allclose(theta, alpha, rtol=1e-13, atol=1e-300)


def test_zero_amplitude_gives_the_unperturbed_spin_exactly():
    w = perturbed_spins(BODY, 2, -3.0, 0.0, 10, distribution="gaussian")
    np.testing.assert_array_equal(w, np.tile([0.0, -3.0, 0.0], (10, 1)))


@pytest.mark.parametrize("distribution", DISTRIBUTIONS)
def test_azimuths_are_uniform(distribution):
    w = perturbed_spins(BODY, 1, 1.0, 0.1, 20000, seed=11, distribution=distribution)
    _, phi = tilt_and_azimuth(w, 1, 1.0)
    assert stats.kstest(phi / (2 * np.pi), "uniform").pvalue > 1e-3


def test_distributions_share_azimuths_sample_by_sample():
    phis = [tilt_and_azimuth(perturbed_spins(BODY, 3, 1.0, 0.2, 500, seed=4, distribution=d), 3, 1.0)[1]
            for d in DISTRIBUTIONS]
    for phi in phis[1:]:
        np.testing.assert_allclose(phi, phis[0], atol=1e-9)


@pytest.mark.parametrize("alpha", [1e-4, 0.3, 1.2])
def test_filled_cone_is_uniform_in_solid_angle(alpha):
    n = 20000
    w = perturbed_spins(BODY, 2, 1.0, alpha, n, seed=6, distribution="filled_cone")
    theta, _ = tilt_and_azimuth(w, 2, 1.0)
    assert theta.max() <= alpha * (1 + 1e-12)
    # cos θ uniform on [cos α, 1]: mean (1 + cos α)/2, sd (1 − cos α)/sqrt(12).
    one_minus_cos = 2 * np.sin(theta / 2) ** 2
    cap = 2 * np.sin(alpha / 2) ** 2
    mean_err = abs(one_minus_cos.mean() - cap / 2) / (cap / np.sqrt(12 * n))
    assert mean_err < 4
    assert stats.kstest(one_minus_cos / cap, "uniform").pvalue > 1e-3


@pytest.mark.parametrize("alpha", [1e-3, 0.2])
def test_gaussian_tilt_components_are_independent_normals_of_sd_amplitude(alpha):
    n = 20000
    w = perturbed_spins(BODY, 3, -1.0, alpha, n, seed=8, distribution="gaussian")
    theta, phi = tilt_and_azimuth(w, 3, -1.0)
    x, y = theta * np.cos(phi), theta * np.sin(phi)
    for comp in (x, y):
        assert abs(comp.std() / alpha - 1) < 0.03
        assert stats.kstest(comp / alpha, "norm").pvalue > 1e-3
    assert abs(np.corrcoef(x, y)[0, 1]) < 4 / np.sqrt(n)


# --- Magnitudes and constraints -------------------------------------------------------------------------


@pytest.mark.parametrize("distribution", DISTRIBUTIONS)
@pytest.mark.parametrize("spin", [1.0, -4.5, 1e-6, 3e5])
def test_unconstrained_spins_keep_the_magnitude(distribution, spin):
    w = perturbed_spins(BODY, 2, spin, 0.3, 1000, distribution=distribution)
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), abs(spin), rtol=1e-15)


@pytest.mark.parametrize("distribution", DISTRIBUTIONS)
@pytest.mark.parametrize("constraint", [None, "energy", "momentum"])
def test_negative_spin_is_the_mirror_image(distribution, constraint):
    kw = dict(samples=300, seed=13, distribution=distribution, constraint=constraint)
    np.testing.assert_array_equal(perturbed_spins(BODY, 1, -2.0, 0.1, **kw),
                                  -perturbed_spins(BODY, 1, 2.0, 0.1, **kw))


def valid_moments():
    """Three positive moments obeying the triangle inequality."""
    return st.tuples(st.floats(0.05, 20.0), st.floats(0.05, 20.0), st.floats(0.01, 1.0)).map(
        lambda t: (t[0], t[1], abs(t[0] - t[1]) + t[2] * (t[0] + t[1] - abs(t[0] - t[1])))
    )


@settings(max_examples=40, deadline=None)
@given(moments=valid_moments(), axis=st.sampled_from([1, 2, 3]),
       spin=st.floats(1e-3, 1e3) | st.floats(-1e3, -1e-3), distribution=st.sampled_from(DISTRIBUTIONS))
def test_energy_constraint_gives_the_unperturbed_kinetic_energy(moments, axis, spin, distribution):
    body = Body(*moments)
    w = perturbed_spins(body, axis, spin, 0.3, 200, seed=1, distribution=distribution, constraint="energy")
    energy = 0.5 * (w**2 @ body.moments)
    np.testing.assert_allclose(energy, 0.5 * body.moments[axis - 1] * spin**2, rtol=1e-14)


@settings(max_examples=40, deadline=None)
@given(moments=valid_moments(), axis=st.sampled_from([1, 2, 3]),
       spin=st.floats(1e-3, 1e3) | st.floats(-1e3, -1e-3), distribution=st.sampled_from(DISTRIBUTIONS))
def test_momentum_constraint_gives_the_unperturbed_angular_momentum(moments, axis, spin, distribution):
    body = Body(*moments)
    w = perturbed_spins(body, axis, spin, 0.3, 200, seed=1, distribution=distribution, constraint="momentum")
    np.testing.assert_allclose(np.linalg.norm(w * body.moments, axis=1),
                               body.moments[axis - 1] * abs(spin), rtol=1e-14)


@pytest.mark.parametrize("constraint", ["energy", "momentum"])
def test_constraints_rescale_without_turning_the_spins(constraint):
    free = perturbed_spins(BODY, 2, 1.0, 0.2, 500, seed=3, distribution="filled_cone")
    held = perturbed_spins(BODY, 2, 1.0, 0.2, 500, seed=3, distribution="filled_cone", constraint=constraint)
    unit = lambda w: w / np.linalg.norm(w, axis=1, keepdims=True)  # noqa: E731
    np.testing.assert_allclose(unit(held), unit(free), atol=1e-15)
    assert not np.allclose(np.linalg.norm(held, axis=1), 1.0)


# --- Interface ------------------------------------------------------------------------------------------


def test_transverse_axes_are_cyclic():
    assert [transverse_axes(a) for a in (1, 2, 3)] == [(2, 3), (3, 1), (1, 2)]


def test_result_is_a_fresh_contiguous_float64_array():
    w = perturbed_spins(Body(1.0, 2.0, 3.0), 1, samples=CHUNK + 3, start=2, stop=CHUNK + 1)
    assert w.dtype == np.float64 and w.flags.c_contiguous and w.shape == (CHUNK - 1, 3)
    assert perturbed_spins(BODY, 1, samples=10, start=4, stop=4).shape == (0, 3)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(axis=0), "axis must be 1, 2 or 3"),
        (dict(axis=4), "axis must be 1, 2 or 3"),
        (dict(axis=1.0), "axis must be 1, 2 or 3"),
        (dict(axis=True), "axis must be 1, 2 or 3"),
        (dict(spin=0.0), "spin must be non-zero"),
        (dict(spin=np.nan), "spin must be finite"),
        (dict(spin=np.inf), "spin must be finite"),
        (dict(spin=[1.0, 2.0]), "spin must be a single number"),
        (dict(amplitude=-1e-3), "amplitude must be >= 0"),
        (dict(amplitude=np.nan), "amplitude must be finite"),
        (dict(amplitude=np.pi / 2), "amplitude must be < π/2"),
        (dict(amplitude=2.0, distribution="filled_cone"), "amplitude must be < π/2"),
        (dict(samples=0), "samples must be >= 1"),
        (dict(samples=10.0), "samples must be an integer"),
        (dict(samples="10"), "samples must be an integer"),
        (dict(distribution="uniform"), "distribution must be one of 'cone', 'filled_cone', 'gaussian'"),
        (dict(distribution=None), "distribution must be one of"),
        (dict(constraint="volume"), "constraint must be one of None, 'energy', 'momentum'"),
        (dict(start=-1), r"start must be in \[0, samples\]"),
        (dict(start=11), r"start must be in \[0, samples\]"),
        (dict(start=5, stop=4), r"stop must be in \[start, samples\]"),
        (dict(stop=11), r"stop must be in \[start, samples\]"),
        (dict(start=1.5), "start must be an integer"),
        (dict(seed=-1), "seed must be a non-negative integer"),
        (dict(seed=1.5), "seed must be an integer"),
        (dict(body=(1.0, 1.0, 3.0)), "triangle inequality"),
        (dict(body=[(1.0, 2.0, 3.0)] * 2), "body must be one body"),
    ],
)
def test_bad_input_is_rejected_with_a_message_naming_the_argument(kwargs, match):
    args = dict(body=BODY, axis=2, spin=1.0, amplitude=1e-3, samples=10) | kwargs
    with pytest.raises(ValueError, match=match):
        perturbed_spins(**args)


def test_gaussian_accepts_amplitudes_beyond_a_right_angle():
    w = perturbed_spins(BODY, 1, 1.0, 2.0, 100, distribution="gaussian")
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, rtol=1e-15)


@pytest.mark.parametrize("bad", [0, -5, 2.0])
def test_chunk_helpers_reject_bad_sample_counts(bad):
    with pytest.raises(ValueError, match="samples"):
        chunk_count(bad)
    with pytest.raises(ValueError, match="samples"):
        chunk_ranges(bad)
