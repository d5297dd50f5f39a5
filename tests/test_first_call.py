"""Which kernels the first call of each documented entry point compiles (issue 43, "Done means"): a change that makes
a call compile another kernel, or another signature of one, fails here; so does one that drops a kernel, until the
table says so.

How: each case runs the probe of ``benchmarks/first_call.py`` (the benchmark's call, inputs and recorder) in a fresh
interpreter with ``NUMBA_CACHE_DIR`` at a new empty folder under ``tmp_path`` (the user's cache is never touched) and
``NUMBA_NUM_THREADS=1`` (one core, as each of the suite's workers; and ``tumble.check`` then starts no side-by-side
compile workers, so every kernel compiles in the probe's process, where numba's events see it). The probe records
numba's ``numba:compile`` events during the call; the test compares tumble's kernels among them (``module.qualname``
without the leading ``tumble.`` -> signatures compiled) with :data:`EXPECTED`. numba's own implementations compiled on
the way (``numba.np.arrayobj.ol_np_empty.<locals>.impl`` and the like) are left out: which of them a kernel needs
depends on numba's version. Also held: the cache was empty (no file before the call, nothing loaded from it), the call
wrote cache files, and further calls in the same process compile nothing.

An empty cache, not a warm one: from a warm cache numba loads only the kernels called from Python, whose machine code
holds every kernel they call; the kernels compiled inside them (the step kernel of integrate rk4's driver) would go
unseen, and they are what a first call after an install pays for; and a warm cache in ``tmp_path`` would have to be
compiled first, at the same cost. The cost: about 25 s for ``integrate rk4`` and 15 to 25 s each for ``exact.omega``
and ``measure`` on 2 cores (AVX2, numba 0.68.1), twice that when other work shares the cores (issue 43's targets: 5,
3 and 5 s). So only ``exact.omega`` runs in the default suite (every run pays its compile, the suite's cache warm or
not); the others are marked slow (``-m slow``).

Updating :data:`EXPECTED` after a change that rightly alters what a call compiles (issue 43's item 2 removes kernels):

    python tests/test_first_call.py ["integrate rk4" ...]   # every entry point without a name

prints the tables this tree gives, each as the dict literal below; paste the ones that changed, having checked that
each kernel listed is one the call runs.
"""

import json
import sys
from collections import Counter
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import first_call  # noqa: E402 - benchmarks/first_call.py, on the path above

#: What the free body's fixed-step driver compiles for a plain integration with any method (integrate, propagate:
#: no observer asked for, so the loop's observers are compiled out, each a stand-in that skips): the CPU's driver, with
#: the one time loop inlined into it, and the loop's parts (subroutines of it: tumble.kernels.jit.subroutine); each
#: method adds its own step (:func:`free_body_driver`), and only its own (those that call Euler's
#: rate, its torque-free stand-in: the torque is chosen by type, tumble.kernels.steps.steppers._plus_torque).
FREE_BODY_LOOP = {
    "kernels.loops.block_loop._if_observing.<locals>.stand_in_of.<locals>.skip": 6,
    "kernels.loops.block_loop._invariants_of.<locals>.free_body": 1,
    "kernels.loops.block_loop._step_of.<locals>.fused_step": 1,
    "kernels.loops.block_parts.check_finite": 1,
    "kernels.loops.block_parts.freeze": 1,
    "kernels.loops.block_parts.restore_frozen": 1,
    "kernels.loops.block_parts.store_initial": 1,
    "kernels.loops.block_parts.store_rest": 1,
    "kernels.loops.drivers.make_propagate.<locals>.propagate": 1,
    "kernels.loops.methods._magnitudes": 1,
}


def free_body_driver(*step_kernels):
    """:data:`FREE_BODY_LOOP` with one method's step kernels (:func:`tumble.kernels.loops.free_body_parts.method_step`)."""
    return {**FREE_BODY_LOOP, **{kernel: 1 for kernel in step_kernels}}


#: What the models' and a System's block driver compiles for a run that asks for no observer (run_ensemble,
#: integrate): the models' CPU driver with the one time loop inlined, its observers compiled out, and the loop's parts;
#: each system adds its own step and invariants.
MODEL_LOOP = {
    "kernels.loops.block_loop._if_observing.<locals>.stand_in_of.<locals>.skip": 6,
    **{kernel: 1 for kernel in (
        "kernels.loops.block_parts.check_finite",
        "kernels.loops.block_parts.freeze",
        "kernels.loops.block_parts.restore_frozen",
        "kernels.loops.block_parts.store_initial",
        "kernels.loops.block_parts.store_rest",
        "kernels.loops.model_loop.make_propagate_model.<locals>.propagate",
    )},
}


def model_driver(*system_kernels):
    """:data:`MODEL_LOOP` with one system's kernels."""
    return {**MODEL_LOOP, **{kernel: 1 for kernel in system_kernels}}


#: What the chaos indicators' first call compiles for a heavy top stepped by rk4 (megno and lyapunov alike): the
#: driver of that system and method, with its one tangent step.
HEAVY_TOP_TANGENTS = {
    "kernels.steps.model_steps.heavy_top_rk4_tangent_step": 1,
    "kernels.loops.tangent_blocks._copy": 1,
    "kernels.loops.tangent_blocks._finish": 1,
    "kernels.loops.tangent_blocks._gali": 1,
    "kernels.loops.tangent_blocks._orthonormalise": 1,
    "kernels.loops.tangent_blocks._screen": 1,
    "kernels.loops.tangent_blocks._share_state": 1,
    "kernels.loops.tangent_blocks._tangent_step_of.<locals>.generated_step": 1,
    "kernels.loops.tangent_blocks.make_propagate_tangents.<locals>.propagate_tangents": 1,
}

#: The closed form's per-sample set-up, which every closed-form entry point compiles.
CLOSED_FORM_SET_UP = {
    "kernels.closed_form.elliptic.agm": 1,
    "kernels.closed_form.elliptic.carlson_rf": 1,
    "kernels.closed_form.elliptic.complete_integrals": 1,
    "kernels.closed_form.elliptic.hyperbolic_nome": 1,
    "kernels.closed_form.elliptic.torque_free_solve_share": 1,
}

#: The evaluation's rows of the regimes the entry points' spins meet: near the separatrix (the hyperbolic core), far
#: from it (Landen's); a call compiles those of the regimes its samples meet, no other.
HYPERBOLIC_ROWS = {
    "kernels.closed_form.elliptic._omega_row_hyperbolic": 1,
    "kernels.closed_form.elliptic._series_constants": 1,
    "kernels.closed_form.elliptic.omega_hyperbolic_share": 1,
}
LANDEN_ROWS = {
    "kernels.closed_form.elliptic._landen_constants": 1,
    "kernels.closed_form.elliptic._omega_row_landen": 1,
    "kernels.closed_form.elliptic.omega_landen_share": 1,
}

#: The closed form's attitude beside its angular velocity (exact.attitude, tumble check of a recorded attitude).
CLOSED_FORM_ATTITUDE = {
    "kernels.closed_form.elliptic._landen_table": 1,
    "kernels.closed_form.elliptic._sech": 1,
    "kernels.closed_form.elliptic._setup": 1,
    "kernels.closed_form.elliptic._sncndn_core": 1,
    "kernels.closed_form.elliptic._sncndn_shifted": 1,
    "kernels.closed_form.elliptic_attitude._local": 1,
    "kernels.closed_form.elliptic_attitude._pi_integral": 1,
    "kernels.closed_form.elliptic_attitude._rc_one": 1,
    "kernels.closed_form.elliptic_attitude._round_half_even": 1,
    "kernels.closed_form.elliptic_attitude._sncndn": 1,
    "kernels.closed_form.elliptic_attitude._tangent": 1,
    "kernels.closed_form.elliptic_attitude.attitude_at": 1,
    "kernels.closed_form.elliptic_attitude.attitude_constants": 1,
    "kernels.closed_form.elliptic_attitude.attitude_rows_share": 1,
    "kernels.closed_form.elliptic_attitude.attitude_setup": 1,
    "kernels.closed_form.elliptic_attitude.carlson_rj": 1,
}

#: Entry point (a name of ``first_call.ENTRY_POINTS``) -> the kernels its first call compiles on an empty cache:
#: ``module.qualname`` (below ``tumble.``) -> number of signatures.
EXPECTED = {
    "integrate rk4": free_body_driver("kernels.steps.fused.rk4_block", "kernels.steps.steppers._plus_torque_of.<locals>.torque_free"),
    "exact.omega": {**CLOSED_FORM_SET_UP, **HYPERBOLIC_ROWS},
    "measure": {
        **CLOSED_FORM_SET_UP,
        **HYPERBOLIC_ROWS,
        "kernels.fits.growth_fit_share": 1,
        "kernels.fits.transverse_norms_share": 1,
    },
    "integrate rk8": free_body_driver("kernels.steps.fused.rk8_block", "kernels.steps.steppers._plus_torque_of.<locals>.torque_free"),
    # the splittings' torque-free steps turn the state about an axis through rotate_block
    "integrate symplectic_euler": free_body_driver("kernels.steps.fused.symplectic_euler_block", "kernels.steps.steppers.rotate_block"),
    "integrate splitting2": free_body_driver("kernels.steps.fused.splitting2_block", "kernels.steps.steppers.rotate_block"),
    "integrate splitting4": free_body_driver("kernels.steps.fused.splitting4_block", "kernels.steps.steppers.rotate_block"),
    "integrate implicit_midpoint": free_body_driver("kernels.steps.steppers.implicit_midpoint_block", "kernels.steps.steppers._plus_torque_of.<locals>.torque_free"),
    "integrate exact": {**CLOSED_FORM_SET_UP, **HYPERBOLIC_ROWS},
    "propagate": free_body_driver("kernels.steps.fused.rk4_block", "kernels.steps.steppers._plus_torque_of.<locals>.torque_free"),
    "exact.attitude": {**CLOSED_FORM_SET_UP, **HYPERBOLIC_ROWS, **CLOSED_FORM_ATTITUDE},
    "scan": {
        **CLOSED_FORM_SET_UP,
        **HYPERBOLIC_ROWS,
        **LANDEN_ROWS,
        "kernels.fits._median_in_place": 1,
        "kernels.fits._select_in_place": 1,
        "kernels.fits.fit_sample": 1,
        "kernels.fits.growth_fit_share": 1,
        "kernels.fits.phase_fit_sample": 1,
        "kernels.fits.phase_fit_share": 1,
        "kernels.fits.transverse_norms_share": 1,
    },
    "check": {**CLOSED_FORM_SET_UP, **HYPERBOLIC_ROWS, **CLOSED_FORM_ATTITUDE},
    # A user's System (the heavy top written by hand) on the vectorised block path: the loop with the System's own
    # step (generated from its rate, in a module of its own, not listed) and no invariants
    "integrate System": model_driver("kernels.loops.block_loop._invariants_of.<locals>.none_known",
                                     "kernels.loops.block_loop._step_of.<locals>.users_step"),
    # The heavy top's driver for rk4, no observer asked for: that system's and that method's step only, its invariants
    "run_ensemble HeavyTop": model_driver("kernels.loops.block_loop._invariants_of.<locals>.system_invariants",
                                          "kernels.loops.block_loop._step_of.<locals>.system_step",
                                          "kernels.steps.model_steps.heavy_top_rk4_block"),
    "megno HeavyTop": HEAVY_TOP_TANGENTS,
    "lyapunov HeavyTop": HEAVY_TOP_TANGENTS,
    # the floors: no tumble kernel (benchmarks/numba_floor.py)
    "floor: one numba kernel": {},
    "floor: one numba kernel, a Dataset": {},
}

#: The entry points of the regular run: the cheapest of issue 43's targets, and the floor (each case compiles from an
#: empty cache however warm the suite's is: 20 s here, 25 s for integrate rk4). The others are slow.
REGULAR = ("floor: one numba kernel",)


def first_call_kernels(name, cache):
    """The probe's record of entry point ``name``'s first call, in a fresh process on the cache folder ``cache``, and
    tumble's kernels it compiled as in :data:`EXPECTED`."""
    record = first_call.run_probe(name, cache, threads=1)
    kernels = Counter(kernel.removeprefix("tumble.") for kernel, _ in record["compiled"]
                      if kernel.startswith("tumble."))
    return record, dict(sorted(kernels.items()))


def _difference(found, expected):
    lines = [f"  {kernel}: {expected.get(kernel, 0)} signature(s) expected, {found.get(kernel, 0)} compiled"
             for kernel in sorted(set(found) | set(expected)) if found.get(kernel, 0) != expected.get(kernel, 0)]
    return ("the kernels compiled differ from EXPECTED (this module's docstring says how to update it):\n"
            + "\n".join(lines))


def test_every_entry_point_of_the_benchmark_has_a_table():
    assert set(EXPECTED) == set(first_call.ENTRY_POINTS)


@pytest.mark.parametrize("name", [n if n in REGULAR else pytest.param(n, marks=pytest.mark.slow) for n in EXPECTED])
def test_a_first_call_compiles_the_kernels_of_its_table(name, tmp_path):
    record, kernels = first_call_kernels(name, tmp_path)
    assert record["cache_files_before"] == 0 and record["loaded"] == [], "the numba cache was not empty"
    assert record["cache_files_written"] > 0
    assert kernels == EXPECTED[name], _difference(kernels, EXPECTED[name])
    assert record["later_compiled"] == [], "a second call compiled again"


def _literal(name, kernels):
    """``kernels`` as an entry of :data:`EXPECTED`'s source."""
    return "\n".join([f"    {json.dumps(name)}: {{", *(f"        {json.dumps(k)}: {n}," for k, n in kernels.items()),
                      "    },"])


if __name__ == "__main__":
    import tempfile

    for entry in sys.argv[1:] or first_call.ENTRY_POINTS:
        with tempfile.TemporaryDirectory() as folder:
            print(_literal(entry, first_call_kernels(entry, folder)[1]))


def _signature_counts():
    """Compiled signatures of every dispatcher tumble holds: module-level kernels and the drivers made so far."""
    from numba.core.dispatcher import Dispatcher

    from tumble.kernels.loops import drivers

    found = {f"{name}.{key}": len(value.overloads) for name, module in list(sys.modules.items())
             if name.startswith("tumble.") for key, value in list(vars(module).items())
             if isinstance(value, Dispatcher)}
    found.update({f"driver {key}": len(made.overloads) for key, made in drivers._DRIVERS.items()})
    return found


def test_one_compiled_variant_serves_every_layout_of_an_input():
    """Issue 43's item 2: Fortran-ordered, read-only (an xarray coordinate's values), strided, float32 and list
    inputs, and one spin as a vector, reach the same compiled kernels as a C-ordered float64 array: no second
    signature of any kernel."""
    import numpy as np

    import tumble

    body = tumble.shapes.t_handle()
    w = np.array([[0.01, 10.0, 0.01], [0.02, 9.0, 0.0]])
    times = np.linspace(0.0, 1.0, 5)
    tumble.integrate(body, w, 0.01, 1e-3)
    tumble.exact.omega(body, w, times)
    before = _signature_counts()
    read_only, read_only_times = w.copy(), times.copy()
    read_only.flags.writeable = read_only_times.flags.writeable = False
    for spins in (np.asfortranarray(w), read_only, w.tolist(), w.astype(np.float32), np.repeat(w, 2, axis=0)[::2],
                  w[0]):
        tumble.integrate(body, spins, 0.01, 1e-3)
        for t in (read_only_times, times[::2], list(times)):
            tumble.exact.omega(body, spins, t)
    after = _signature_counts()
    assert {k: (before.get(k, 0), n) for k, n in after.items() if before.get(k, 0) != n} == {}


_CHOSEN = """
import json
import numba
import numpy as np
from numba.core import event

compiled = []


class Listener(event.Listener):
    def on_start(self, ev):
        compiled.append(getattr(ev.data["dispatcher"], "py_func", ev.data["dispatcher"]).__qualname__)

    def on_end(self, ev):
        pass


event.register("numba:compile", Listener())
from tumble.kernels.loops import block_loop, model_loop
from tumble.kernels.systems import N_CONSTANTS

model, method = model_loop.MODEL_CODES["heavy_top"], model_loop.MODEL_METHODS["rk4"]
source = f'''
def models(ys, t, h, a, x0, active, scale, screen):
    block_loop._step({model}, {method}, True, ys, active, t, h, a, x0, (0, None, None))
    block_loop._drift_suspects({model}, ys, active, a, x0, scale, screen)
    return block_loop._invariants({model}, ys, 0, a)
'''
namespace = {"block_loop": block_loop}
exec(source, namespace)
ys, a = np.zeros((6, 4)), np.zeros(N_CONSTANTS)
numba.njit(namespace["models"])(ys, 0.0, 0.01, a, np.zeros((6, 4)), np.ones(4, dtype=np.bool_), np.ones((3, 4)), 1.0)
print(json.dumps(compiled))
"""


def test_the_overloads_take_the_branch_of_literal_codes():
    """numba tries an overload with plain types first unless it prefers literals: the models' step, invariants and
    drift screen given literal codes must compile that system's branch, not the chain of every system's. Found
    missing by the first-call benchmark (a heavy top's ensemble 36 -> 85 s)."""
    import subprocess

    done = subprocess.run([sys.executable, "-c", _CHOSEN], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    chosen = {name for name in json.loads(done.stdout.splitlines()[-1]) if "_of.<locals>." in name}
    assert chosen == {"_step_of.<locals>.system_step", "_invariants_of.<locals>.system_invariants",
                      "_drift_suspects_of.<locals>.system_drift_suspects"}


def test_codes_known_at_run_time_are_a_typing_error_that_says_so():
    """A loop's method (and system) code must reach it as a literal, a constant of its caller: given as a run-time int
    (or through a star-call's tuple, which numba-cuda types as plain ints) it is a typing error naming the cause, where
    it was a silent chain that compiled every method's step into the loop."""
    import numba
    import numpy as np
    from numba.core.errors import TypingError

    from tumble.kernels.loops import block_loop

    @numba.njit
    def model_step(model, method, ys, a, x0):
        block_loop._step(model, method, True, ys, ys[0] > 0, 0.0, 0.1, a, x0, (0, None, None))

    with pytest.raises(TypingError, match="codes as literals"):
        model_step(2, 0, np.zeros((6, 1)), np.zeros(20), np.zeros((3, 1)))

    @numba.njit
    def free_step(kernel, ys, body):
        block_loop._step(block_loop.FREE_BODY, kernel, True, ys, ys[0] > 0, 0.0, 0.1, body, ys, (0, None, None))

    with pytest.raises(TypingError, match="codes as literals"):
        free_step(0, np.zeros((3, 1)), (1.0,) * 12)
