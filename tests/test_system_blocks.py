"""A user's System on the built-ins' vectorised block path (tumble/kernels/steps/system_steps.py): its rate rewritten into
the built-ins' scalar form, the same numbers as the built-in model it copies and as the per-sample loop, what has no
scalar form said in one warning, and its kernels loaded from numba's disk cache by a new process."""

import math
import textwrap
import warnings

import numpy as np
import pytest

import tumble
from process_checks import run_twice
from tumble.kernels.steps import system_steps
from tumble.kernels.steps.system_steps import NotScalar

import hand_written_systems
from hand_written_systems import HEAVY_TOP, heavy_top

pytestmark = pytest.mark.xdist_group(hand_written_systems.GROUP)


def _evaluate(source, name, *arguments):
    """The rewritten function run as plain Python (``_tumble_max``, the generated code's ``max``, as Python's)."""
    scope = {"math": math, "_tumble_max": max}
    exec(source, scope)
    return scope[name](*arguments)


def test_a_rate_is_rewritten_into_the_scalar_form_with_its_numbers_and_divisions_by_a_parameter_made_products():
    source = system_steps.scalar_rate(heavy_top, 6, 7)
    assert "_d5 = " in source and "y[" not in source and "dydt" not in source
    assert "/ p[0]" not in source and "* p[7]" in source  # 1 / I1 rides after the seven parameters
    rng = np.random.default_rng(5)
    p = np.array([2.0, 2.5, 3.0, 0.5, 0.3, -0.2, 0.9])
    for y in rng.normal(size=(5, 6)):
        expected = np.empty(6)
        heavy_top(0.0, y, p, expected)
        got = _evaluate(source, "_tumble_rate", 0.0, *y, tuple(system_steps.block_constants(p)))
        np.testing.assert_allclose(got, expected, rtol=1e-15, atol=1e-15)


def test_a_jacobian_becomes_the_tangent_flow_and_without_one_the_difference_is_the_per_sample_loops():
    k, c, a, w = hand_written_systems.ROTOR.values()
    p = (k, c, a, w)
    y, v = np.array([1e4 + 0.3, -0.7]), np.array([0.6, -0.8])
    exact = np.array([v[1], -k * math.cos(y[0]) * v[0] - c * v[1]])
    source = system_steps.scalar_tangent(2, 4, hand_written_systems.rotor_jacobian)
    np.testing.assert_allclose(_evaluate(source, "_tumble_tangent", 0.5, *y, *v, p + tuple(1 / np.array(p))), exact,
                               rtol=1e-15)
    rate = system_steps.scalar_rate(hand_written_systems.rotor, 2, 4)
    difference = system_steps.scalar_tangent(2, 4, None, np.ones(2))
    got = _evaluate(rate + "\n" + difference, "_tumble_tangent", 0.5, *y, *v, p + tuple(1 / np.array(p)))
    np.testing.assert_allclose(got, exact, rtol=1e-10)  # an angle of 1e4 rad: the step follows the scale, not |y|


def _loops(t, y, p, dydt):
    for j in range(2):
        dydt[j] = -p[0] * y[j]


def _length(t, y, p, dydt):
    dydt[0] = -len(y) * y[0]


def _passes_on(t, y, p, dydt):
    dydt[0] = np.sum(y)


def _returns(t, y, p, dydt):
    dydt[0] = y[0]
    return 1.0


def _out_of_range(t, y, p, dydt):
    dydt[0] = y[3]


@pytest.mark.parametrize("rate, why", [
    (_loops, "indexes dydt with j, not a constant index"),
    (_length, "uses the array y other than by a constant index"),
    (_passes_on, "uses the array y other than by a constant index"),
    (_returns, "returns a value"),
    (_out_of_range, "indexes y with 3, not a constant index in range"),
    (lambda t, y, p, dydt: None, "is not a def"),
])
def test_what_has_no_scalar_form_says_why(rate, why):
    with pytest.raises(NotScalar, match=why):
        system_steps.system_code(rate, 1 if rate in (_length, _passes_on, _returns) else 2, 1)


def _straight(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * y[0] - p[1] * y[1]


def _looped(t, y, p, dydt):
    dydt[0] = y[1]
    for j in range(1, 2):
        dydt[j] = -p[0] * y[j - 1] - p[1] * y[j]


def test_a_rate_without_a_scalar_form_warns_once_and_the_per_sample_loop_gives_the_blocks_numbers():
    parameters = {"k": 2.0, "c": 0.1}
    straight = tumble.System(_straight, state=("x", "v"), parameters=parameters, name="straight")
    looped = tumble.System(_looped, state=("x", "v"), parameters=parameters, name="looped")
    y0 = np.random.default_rng(2).normal(size=(40, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        blocks = tumble.propagate(straight, y0, 3.0, 0.01, method="rk4")
    with pytest.warns(UserWarning, match=r"system 'looped' runs one sample at a time, .*indexes dydt with j"):
        per_sample = tumble.propagate(looped, y0, 3.0, 0.01, method="rk4")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per System
        tumble.propagate(looped, y0, 0.1, 0.01, method="rk4")
    np.testing.assert_allclose(blocks, per_sample, rtol=1e-13, atol=1e-15)


def _unit_tops(n, seed=4):
    rng = np.random.default_rng(seed)
    y = np.tile([0.1, 0.2, 3.0, 0.0, 0.1, 0.99], (n, 1)) + 1e-3 * rng.standard_normal((n, 6))
    y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    return y


def test_the_heavy_top_by_hand_on_the_blocks_gives_the_built_ins_states_and_megno():
    builtin = tumble.models.HeavyTop(moments=(2.0, 2.5, 3.0), mgl=0.5)
    y0 = _unit_tops(300)
    mine = tumble.propagate(HEAVY_TOP, y0, 10.0, 0.01, method="rk4")
    theirs = tumble.propagate(builtin, y0, 10.0, 0.01, method="rk4")
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-12)
    mine, theirs = (tumble.megno(system, y0[:40], 20.0, 0.01)["megno"].values for system in (HEAVY_TOP, builtin))
    np.testing.assert_allclose(mine, theirs, rtol=0, atol=1e-6)  # differences against the exact tangent


CACHED = textwrap.dedent('''
    import math, tumble
    from numba.core.errors import NumbaWarning

    def decay(t, y, p, dydt):
        dydt[0] = -p[0] * y[0] + math.sin(t)

    system = tumble.System(decay, state=("x",), parameters={"k": 0.5}, name="decay")
    print(float(tumble.propagate(system, [[1.0]], 1.0, 0.01, method="rk4")[0, 0]))
    from tumble.kernels import system_steps
    from tumble.kernels.loops import model_loop
    code = system_steps.system_code(decay, 1, 1)
    print(sum(model_loop._DRIVERS[code, 0, False].stats.cache_hits.values()))  # propagate observes nothing
''')


def test_a_new_process_loads_a_systems_kernels_from_the_disk_cache(tmp_path):
    (first, _), (second, hits) = run_twice(tmp_path, CACHED, "decay.py")
    assert first == second
    assert int(hits) == 1  # the second process compiled nothing of the driver


def test_a_rate_whose_file_was_edited_since_it_was_imported_is_not_rewritten_from_the_edited_text(tmp_path,
                                                                                                 monkeypatch):
    module = tmp_path / "edited_rate.py"
    module.write_text("def rate(t, y, p, dydt):\n    dydt[0] = -y[0]\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import edited_rate

    assert "_d0 = -_y0" in system_steps.scalar_rate(edited_rate.rate, 1, 0)
    module.write_text("def rate(t, y, p, dydt):\n    dydt[0] = +y[0]\n")
    import linecache
    linecache.checkcache(str(module))
    with pytest.raises(NotScalar, match="no longer the function that runs"):
        system_steps.scalar_rate(edited_rate.rate, 1, 0)
