"""Poincaré sections (tumble.section): crossings against SciPy's events, the stroboscopic section against its t_eval,
directions, the stop at max_crossings, bad input."""

import math
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import tumble
from process_checks import run_twice
from tumble import exact, registry

# One worker runs the error-controlled tests (--dist loadgroup): the built-in models' kernel (the free body's too) is
# compiled once per process, a closure over the models' rate that numba's disk cache cannot keep.
pytestmark = pytest.mark.xdist_group("dop853")

BODY = (1.0, 2.0, 3.0)
SPINS = np.array([[1.0, 0.1, 0.0], [0.2, 1.0, 0.3], [0.05, 0.2, 1.0]])


def _euler(t, w):
    i1, i2, i3 = BODY
    return [(i2 - i3) / i1 * w[1] * w[2], (i3 - i1) / i2 * w[2] * w[0], (i1 - i2) / i3 * w[0] * w[1]]


def _events(w0, g, direction, t_end=40.0):
    g.direction = direction
    sol = solve_ivp(_euler, (0.0, t_end), w0, method="DOP853", rtol=2.3e-14, atol=1e-16, events=g)
    return sol.t_events[0][sol.t_events[0] > 0.0], sol.y_events[0][sol.t_events[0] > 0.0]


def _pitch(t, y, p):
    return y[0] * y[1] - 0.05  # a surface that is no component: w1 w2 = 0.05


@pytest.mark.parametrize("direction", [1, -1, 0])
def test_component_crossings_are_scipys_events(direction):
    ds = tumble.section(BODY, SPINS, 40.0, surface=("w2", 0.0), direction=direction, rtol=1e-13, atol=1e-15)
    for i, w0 in enumerate(SPINS):
        times, states = _events(w0, lambda t, w: w[1], direction)
        count = int(ds["count"][i])
        assert count == len(times) > 0
        np.testing.assert_allclose(ds.time.values[i, :count], times, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ds.state.values[i, :count], states, rtol=0, atol=1e-9)
        assert np.abs(ds.state.values[i, :count, 1]).max() < 1e-12  # on the surface, to the root finder's width
        assert np.isnan(ds.time.values[i, count:]).all() and np.isnan(ds.state.values[i, count:]).all()
    assert ds.attrs["surface"] == "w2 = 0" and ds.attrs["direction"] == direction


@pytest.mark.slow  # a kernel of its own for the user's surface (10 s to compile)
def test_a_users_surface_function_is_compiled_and_located_as_scipys_event():
    ds = tumble.section(BODY, SPINS, 40.0, surface=_pitch, direction=0, rtol=1e-13, atol=1e-15)
    for i, w0 in enumerate(SPINS):
        times, _ = _events(w0, lambda t, w: w[0] * w[1] - 0.05, 0)
        count = int(ds["count"][i])
        assert count == len(times)
        np.testing.assert_allclose(ds.time.values[i, :count], times, rtol=0, atol=1e-9)
        w = ds.state.values[i, :count]
        assert np.abs(w[:, 0] * w[:, 1] - 0.05).max(initial=0.0) < 1e-12
    assert ds["count"].values[:2].min() > 2  # the third spin, near axis 3, never reaches it (nor SciPy's)


#: The level a surface reads from this module (a user's global): changed by the test below.
LEVEL = 0.0


def _level(t, y, p):
    return y[0] - LEVEL


@pytest.mark.slow  # the surface compiled twice, a kernel each (10 s each)
def test_a_global_the_surface_reads_changed_since_it_was_compiled_is_compiled_again_and_said(monkeypatch):
    def crossings(level):
        return _events(SPINS[0], lambda t, w: w[0] - level, 0)[0][:3]

    first = tumble.section(BODY, SPINS[:1], 40.0, surface=_level, direction=0, max_crossings=3, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(first.time.values[0], crossings(0.0), rtol=0, atol=1e-9)
    monkeypatch.setattr(sys.modules[__name__], "LEVEL", 0.1)
    with pytest.warns(RuntimeWarning, match=r"LEVEL, read by surface g, changed since it was compiled"):
        moved = tumble.section(BODY, SPINS[:1], 40.0, surface=_level, direction=0, max_crossings=3, rtol=1e-13,
                               atol=1e-15)
    np.testing.assert_allclose(moved.time.values[0], crossings(0.1), rtol=0, atol=1e-9)


def test_the_stroboscopic_section_is_the_state_at_each_period():
    ds = tumble.section(BODY, SPINS, 40.0, period=3.0, phase=0.5, rtol=1e-12, atol=1e-14)
    marks = 0.5 + 3.0 * np.arange(1, 14)
    np.testing.assert_array_equal(ds.time.values, np.broadcast_to(marks, (3, 13)))
    assert ds["count"].values.tolist() == [13, 13, 13]
    np.testing.assert_allclose(ds.state.values, exact.omega(BODY, SPINS, marks), rtol=0, atol=2e-10)
    sol = solve_ivp(_euler, (0.0, 40.0), SPINS[1], method="DOP853", rtol=2.3e-14, atol=1e-16, t_eval=marks)
    np.testing.assert_allclose(ds.state.values[1], sol.y.T, rtol=0, atol=2e-10)


def test_a_sample_stops_once_it_has_max_crossings():
    full = tumble.section(BODY, SPINS[:1], 40.0, surface=("w2", 0.0), direction=0)
    three = tumble.section(BODY, SPINS[:1], 40.0, surface=("w2", 0.0), direction=0, max_crossings=3)
    assert int(three["count"][0]) == 3 and three.sizes["crossing"] == 3
    np.testing.assert_array_equal(three.time.values[0], full.time.values[0, :3])
    assert int(three.steps[0]) < int(full.steps[0]) / 2  # it stopped stepping there
    assert three.status.values.tolist() == [registry.STATUS_OK]
    # the stroboscopic section too: to its last mark, however far t_end (it ran to t_end, or to the step limit)
    strobe = tumble.section(BODY, SPINS[:1], 1e5, period=1.0, max_crossings=3)
    assert strobe["count"].values.tolist() == [3] and strobe.status.values.tolist() == [registry.STATUS_OK]
    assert int(strobe.steps[0]) < 20 and strobe.attrs["t_end"] == 1e5


def test_a_sample_out_of_steps_keeps_its_crossings_and_says_so():
    full = tumble.section(BODY, SPINS[:1], 40.0, surface=("w2", 0.0), direction=0)
    with pytest.warns(RuntimeWarning, match=r"1 of 1 samples of 'free' stopped before t_end \(1 step limit; status "
                                            r"says which, their crossings are the ones found before\)"):
        short = tumble.section(BODY, SPINS[:1], 40.0, surface=("w2", 0.0), direction=0, max_steps=60)
    assert short.status.values.tolist() == [registry.STATUS_LIMIT]
    assert int(short.steps[0] + short.rejected_steps[0]) == 60
    kept = int(short["count"][0])
    assert 0 < kept < int(full["count"][0])
    np.testing.assert_array_equal(short.time.values[0, :kept], full.time.values[0, :kept])


@pytest.mark.slow  # the heavy top's own kernel's compile (10 s)
def test_a_built_in_models_section():
    top = tumble.models.HeavyTop((1.0, 1.2, 0.5), 1.0)
    g = np.array([0.3, 0.0, 1.0]) / math.hypot(0.3, 1.0)
    ds = tumble.section(top, [[0.2, 0.1, 3.0, *g]], 30.0, surface=("g1", 0.0), direction=1)
    count = int(ds["count"][0])
    assert count > 3 and list(ds.component.values) == ["w1", "w2", "w3", "g1", "g2", "g3"]
    assert np.abs(ds.state.values[0, :count, 3]).max() < 1e-12
    assert (np.diff(ds.time.values[0, :count]) > 0).all()


@pytest.mark.parametrize("keywords, message", [
    (dict(surface=("w2", 0.0), period=1.0), "or a period .the stroboscopic section., one of them, not both"),
    (dict(), "give a surface"),
    (dict(surface=("w2", 0.0), direction=2), "direction must be 1 .g rising through 0., -1 .falling. or 0"),
    (dict(surface=("w2", 0.0), max_crossings=0), "max_crossings must be an integer >= 1"),
    (dict(surface=("w4", 0.0)), "surface: component 'w4' is not one of w1, w2, w3"),
    (dict(surface=("w2", math.nan)), "surface: the value must be finite"),
    (dict(surface="w2"), r"surface must be \(component, value\)"),
    (dict(surface=("w2", 0.0), method="rk4"), "method must be 'dop853'"),
    (dict(period=-1.0), "period must be finite and > 0"),
    (dict(surface=("w2", 0.0), phase=0.5), "phase is the stroboscopic section's .with a period., not a surface's"),
    (dict(period=1.0, direction=0), "direction counts a surface's crossings, not a period's states, got 0"),
    (dict(surface=("w2", 0.0), rtol=0.0), "rtol must be finite and > 0"),
    (dict(surface=lambda t, y, p: (y[0], y[1])), "surface g.t, y, p. must return a number"),
    (dict(surface=lambda t, y, p: y.undefined), "numba cannot compile surface g"),
    (dict(surface=lambda t, y: y[0]), r"surface g\(t, y, p\) must be a function of 3 arguments; it takes 2"),
    (dict(surface=lambda t, y, p: np.linalg.undefined(y)),
     "numba cannot compile surface g.* AttributeError: module 'numpy.linalg' has no attribute 'undefined'"),
])
def test_bad_input_is_one_line_naming_the_argument(keywords, message):
    with pytest.raises(ValueError, match=message) as refused:
        tumble.section(BODY, SPINS, 10.0, **keywords)
    assert "\n" not in str(refused.value)


_CACHED = """
import numpy as np
import tumble
from tumble.engine import adaptive_runs
top = tumble.models.HeavyTop((1.0, 1.5, 2.0), 1.0, centre=(1.0, 0.5, 1.0))
ds = tumble.section(top, [[0.0, 0.0, 2.0, 0.0, 0.3, 0.95]], 20.0, surface=("g1", 0.0), max_crossings=3)
drive = adaptive_runs._MODEL_KERNELS["heavy_top", "rate", None]
print(repr(float(ds["time"][0, 0])), sum(drive.run_share.stats.cache_hits.values()))
"""


@pytest.mark.slow  # two new processes, the first may compile the block loop (15 s)
def test_a_new_process_loads_the_models_block_loop_from_the_disk_cache(tmp_path):
    """The built-in models' error-controlled block loop is kept in numba's disk cache (a function handed in as an
    argument, or a closure, would be compiled again in every process), and gives the same bits loaded as compiled."""
    (first, _), (second, hits) = run_twice(tmp_path, _CACHED, "section.py")
    assert first == second
    assert int(hits) == 1
