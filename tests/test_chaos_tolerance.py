"""The chaos indicators at a tolerance (``method="dop853"``): against the fixed steps' at a small step, the free
body's closed-form exponent and zero sum, a System's Jacobian and differences, the spectrum's independence of
``renormalise``, and the refusals."""

import math

import numpy as np
import pytest

import tumble
from tumble import registry

import hand_written_systems
from process_checks import run_twice

# One worker runs the error-controlled tests (--dist loadgroup): the loop over the augmented state of a System whose
# functions cannot be keyed is compiled once per process.
pytestmark = pytest.mark.xdist_group("dop853")

BODY = tumble.Body(1.0, 2.0, 3.0)
# a steady spin about the intermediate axis (exponent sqrt((I2 - I1)(I3 - I2) / (I1 I3)) w = 1/sqrt(3)) and a tumble
SPINS = [[0.0, 1.0, 0.0], [1.0, 0.1, 0.0]]


def test_the_spectrum_at_a_tolerance_is_the_fixed_steps_and_sums_to_zero():
    times = [10.0, 12.5, 15.0]
    ds = tumble.lyapunov(BODY, SPINS, 15.0, method="dop853", rtol=1e-11, transient=5.0, times=times)
    fixed = tumble.lyapunov(BODY, SPINS, 15.0, 0.001, method="rk8", transient=5.0, save_every=2500)
    np.testing.assert_allclose(ds["exponent"].values, fixed["exponent"].values, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ds["finite_time"].values, fixed["finite_time"].sel(time=times).values, rtol=0,
                               atol=1e-9)
    assert np.abs(ds["exponent"].values.sum(axis=1)).max() < 1e-11  # Euler's equations keep volume
    assert ds["exponent"].values[0, 0] == pytest.approx(1.0 / math.sqrt(3.0), rel=2e-4)  # the linear rate, at t = 15 s
    assert ds.attrs["method"] == "dop853" and ds.attrs["rtol"] == 1e-11 and ds.attrs["renormalise"] == 1.0
    assert (ds["status"].values == registry.STATUS_OK).all() and (ds["steps"].values > 0).all()


def test_megno_and_gali_at_a_tolerance_are_the_fixed_steps():
    megno = tumble.megno(BODY, SPINS, 200.0, method="dop853")
    fixed = tumble.megno(BODY, SPINS, 200.0, 0.005, method="rk8")
    np.testing.assert_allclose(megno["megno"].values, fixed["megno"].values, rtol=1e-8)
    np.testing.assert_allclose(megno["lyapunov"].values, fixed["lyapunov"].values, rtol=1e-4)  # a continuous fit
    assert megno["megno"].values[1] == pytest.approx(0.85, abs=0.01)  # regular, near a stable periodic orbit
    gali = tumble.gali(BODY, SPINS, 20.0, method="dop853", times=[5.0, 10.0, 20.0])
    fixed = tumble.gali(BODY, SPINS, 20.0, 0.001, method="rk8", save_every=5000)
    np.testing.assert_allclose(gali["gali"].values, fixed["gali"].sel(time=[5.0, 10.0, 20.0]).values, rtol=1e-6)


def test_the_spectrum_does_not_depend_on_renormalise():
    one = tumble.lyapunov(BODY, SPINS, 12.0, method="dop853", renormalise=1.0)
    four = tumble.lyapunov(BODY, SPINS, 12.0, method="dop853", renormalise=4.0)
    np.testing.assert_allclose(one["exponent"].values, four["exponent"].values, rtol=0, atol=1e-9)


def test_max_steps_bounds_the_whole_spectrum_run_not_each_segment():
    free = tumble.lyapunov(BODY, SPINS, 12.0, method="dop853")  # 12 segments of 1 s
    taken = free["steps"].values + free["rejected_steps"].values
    limit = int(taken.min()) // 2  # more than any one segment takes, half of the whole run
    assert limit > 3 * taken.max() / 12
    with pytest.warns(RuntimeWarning, match=r"2 of 2 samples .* stopped before t_end \(2 step limit"):
        bound = tumble.lyapunov(BODY, SPINS, 12.0, method="dop853", max_steps=limit)
    assert (bound["status"].values == registry.STATUS_LIMIT).all()
    assert (bound["steps"].values + bound["rejected_steps"].values == limit).all()
    assert (bound["steps"].values <= free["steps"].values).all()


@pytest.mark.slow  # a loop of its own for each System (about 10 s to compile each, then kept in the disk cache)
def test_a_systems_jacobian_and_its_differences_give_the_same_exponents_at_a_tolerance():
    rotor, parameters = hand_written_systems.rotor, hand_written_systems.ROTOR
    exact = tumble.System(rotor, state=("theta", "omega"), parameters=parameters,
                          jacobian=hand_written_systems.rotor_jacobian, name="rotor")
    by_differences = tumble.System(rotor, state=("theta", "omega"), parameters=parameters, name="rotor")
    a = tumble.lyapunov(exact, [0.0, 2.0], 50.0, method="dop853")
    b = tumble.lyapunov(by_differences, [0.0, 2.0], 50.0, method="dop853")
    fixed = tumble.lyapunov(exact, [0.0, 2.0], 50.0, 0.002, method="rk8")
    np.testing.assert_allclose(b["exponent"].values, a["exponent"].values, rtol=0, atol=1e-8)
    np.testing.assert_allclose(a["exponent"].values, fixed["exponent"].values, rtol=0, atol=1e-8)
    assert a.attrs["tangent"] == "jacobian" and b.attrs["tangent"] == "differences"


_CACHED = """
import tumble
from tumble.engine import chaos_tolerance
ds = tumble.megno(tumble.Body(1.0, 2.0, 3.0), [[1.0, 0.1, 0.0]], 50.0, method="dop853")
drive = next(iter(chaos_tolerance._DRIVERS.values()))
print(repr(float(ds["megno"][0])), sum(drive.run_share.stats.cache_hits.values()))
"""


@pytest.mark.slow  # two new processes, the first may compile the loop (10 s)
def test_a_new_process_loads_the_models_loop_at_a_tolerance_from_the_disk_cache(tmp_path):
    """The built-in models' loop over the augmented state is kept in numba's disk cache (written over module-level
    names and copied with the models' rate and tangent: no closure), and gives the same bits loaded as compiled."""
    (first, _), (second, hits) = run_twice(tmp_path, _CACHED, "megno.py")
    assert first == second
    assert int(hits) == 1


@pytest.mark.parametrize("call, message", [
    (lambda: tumble.lyapunov(BODY, SPINS, 10.0), r"dt \(s\) is required for the fixed-step method 'rk4'"),
    (lambda: tumble.megno(BODY, SPINS, 10.0, 0.1, rtol=1e-6), r"rtol: for an error-controlled run"),
    (lambda: tumble.gali(BODY, SPINS, 10.0, method="dop853", save_every=3), r"save_every counts fixed steps"),
    (lambda: tumble.megno(BODY, SPINS, 10.0, method="dop853", stop_above=5.0), r"stop_above stops a fixed-step run"),
    (lambda: tumble.lyapunov(BODY, SPINS, 10.0, method="dop853", transient=5.0, times=[4.0, 10.0]),
     r"times must lie after the transient \(5 s\)"),
    (lambda: tumble.lyapunov(BODY, SPINS, 10.0, method="dop853", rtol=1e-16), r"rtol must be >= 1e-14"),
    (lambda: tumble.lyapunov(BODY, SPINS, 10.0, method="dop853", renormalise=0.0), r"renormalise must be > 0 s"),
    (lambda: tumble.megno(BODY, SPINS, 0.0, method="dop853"), r"t_end must be > 0 s"),
])
def test_bad_arguments_at_a_tolerance_are_one_line_each(call, message):
    with pytest.raises(ValueError, match=message):
        call()
