"""What a command or ``import tumble`` loads: only what it needs (issue 29).

Start-up time is dominated by imports (numba, xarray with pandas, matplotlib, netCDF4, dask: 0.1-0.6 s each on
2 cores), so the tests check the modules a fresh interpreter holds afterwards, not a time (timings are in
``benchmarks/latency.py``).
"""

import json
import os
import subprocess
import sys

import pytest

HEAVY = ("numba", "xarray", "pandas", "matplotlib", "netCDF4", "dask", "distributed", "scipy", "tqdm")


def loaded_after(code):
    """The heavy modules a fresh interpreter has imported after running ``code``."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def test_import_tumble_loads_no_heavy_dependency():
    assert loaded_after("import tumble") == []


@pytest.mark.parametrize("argv", [["--help"], ["studies"], ["run", "--help"], ["plot", "--help"]])
def test_the_command_line_answers_without_loading_the_numerics(argv):
    code = f"import sys\nfrom tumble.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass"
    assert loaded_after(code) == []


def test_each_public_name_loads_only_its_own_layers():
    # the physics of the contract is numpy (and the closed form numba and scipy.special), never the output stack
    assert set(loaded_after("import tumble\ntumble.Body(1, 2, 3)\ntumble.shapes.t_handle()")) == set()
    assert not {"xarray", "matplotlib", "netCDF4", "dask"} & set(loaded_after("import tumble.exact"))
    assert not {"matplotlib", "netCDF4"} & set(loaded_after("import tumble\ntumble.integrate"))


def test_integrate_megno_measure_and_their_datasets_leave_dask_unloaded():
    # xarray's duck-array checks import dask.array (0.8 s in a new process: more than a warm first call's kernels
    # take) unless the Dataset is built from numpy arrays directly (engine.integration.indexed_dataset). The user's
    # first selection on the result still imports it: xarray's own checks, which tumble cannot skip
    code = ("import numpy as np, tumble\n"
            "tumble.integrate(tumble.Body(1, 2, 3), np.array([0.01, 1.0, 0.01]), 0.01, 0.001, attitude=True)\n"
            "tumble.megno(tumble.Body(1, 2, 3), np.array([0.01, 1.0, 0.01]), 0.1, 0.01)\n"  # the indicators' too
            "tumble.measure(tumble.Body(1, 2, 3), axis=2, spin=1.0, samples=16)")  # and a scene's
    assert "dask" not in loaded_after(code)


def test_the_short_import_paths_give_the_layers_modules():
    code = ("import sys, tumble, tumble.exact, tumble.io\nfrom tumble.theory import linear\n"
            "from tumble.models import Gyrostat\nimport tumble.measure.scans\n"
            "assert tumble.exact is sys.modules['tumble.physics.exact']\n"
            "assert tumble.exact.__spec__.name == 'tumble.physics.exact'\n"
            "assert tumble.io is sys.modules['tumble.output.io']\n"
            "assert linear is sys.modules['tumble.physics.theory'].linear\n"
            "assert callable(tumble.measure) and tumble.measure.__name__ == 'measure'\n"
            "assert set(tumble.__all__) <= set(dir(tumble))\n"
            "assert not {'sys', 'importlib'} & set(vars(tumble)), 'the face shows only its names'\n"
            "assert not any(type(f).__module__.startswith('tumble') for f in sys.meta_path), 'no import hook'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_an_unknown_name_is_an_attribute_error():
    import tumble

    with pytest.raises(AttributeError, match="no attribute 'integrat'"):
        tumble.integrat  # noqa: B018


def test_integrate_builds_the_dataset_xarrays_public_constructor_would():
    import numpy as np
    import xarray as xr

    import tumble

    w0 = np.array([0.01, 10.0, 0.01]) + np.random.default_rng(0).normal(0.0, 1e-3, (40, 3))
    for kwargs in ({}, {"save_every": 50, "attitude": True}):
        ds = tumble.integrate(tumble.shapes.t_handle(), w0, 0.2, 0.001, **kwargs)
        public = xr.Dataset({k: v.variable for k, v in ds.data_vars.items()},
                            coords={k: v.variable for k, v in ds.coords.items()}, attrs=ds.attrs)
        assert ds.identical(public)
        assert list(ds.indexes) == [d for d in ("sample", "time", "axis", "component") if d in ds.dims]
        again = tumble.integrate(tumble.shapes.t_handle(), w0, 0.2, 0.001, **kwargs)  # an index reused...
        again["omega"].attrs["units"] = "changed"
        again.sample.attrs["long_name"] = "changed"
        assert ds.omega.attrs["units"] == "rad/s" and ds.sample.attrs["long_name"] == "ensemble member"  # ...not shared
        assert float(ds.sel(time=0.2, method="nearest").omega[0, 1]) == float(ds.omega[0, -1, 1])


def test_exact_omega_at_one_time_in_an_array_is_the_one_time_kernels_answer():
    import numpy as np

    import tumble

    body = tumble.shapes.t_handle()
    w0 = np.array([0.01, 10.0, 0.01]) + np.random.default_rng(1).normal(0.0, 1e-3, (2, 5, 3))
    one = tumble.exact.omega(body, w0, np.array([3.0]))
    assert one.shape == (2, 5, 1, 3)
    np.testing.assert_array_equal(one[..., 0, :], tumble.exact.omega(body, w0, 3.0))
    grid = tumble.exact.omega(body, w0, np.array([3.0, 3.0]))  # the grid kernel: a few ulps of |w| apart
    np.testing.assert_allclose(one[..., 0, :], grid[..., 0, :], rtol=0, atol=1e-14 * 10.0)


def test_the_sample_steps_of_blocks_vectorised_equal_the_block_by_block_sum():
    import numpy as np

    from tumble.engine import ensemble

    rng = np.random.default_rng(2)
    for block in (ensemble.BLOCK, ensemble.WARP):  # a CPU block, a device warp
        for n in (0, 1, block - 1, block, 3 * block + 5):
            steps = rng.integers(0, 1000, n)
            expected = sum(len(part) * int(part.max()) for part in np.split(steps, range(block, n, block)) if len(part))
            assert ensemble._block_steps(steps, block) == expected


def test_the_side_by_side_signatures_are_those_the_closed_form_scenes_call(warm_kernels):
    import tumble
    from tumble.kernels import side_by_side

    tumble.measure((1.0, 2.0, 3.0), 2, samples=16)  # exponential
    tumble.measure((1.0, 2.0, 3.0), 1, samples=16)  # periodic
    # the "grid" jobs are tumble check's (test_check calls them); the rows, those each kind's scenes meet
    for kind, regime in (("exponential", "hyperbolic"), ("periodic", "landen")):
        for name, signature, _ in side_by_side.CLOSED_FORM[kind] + (side_by_side.ROWS[regime],):
            assert tuple(signature) in compiled_or_cached(side_by_side._dispatcher(name)), name


def compiled_or_cached(dispatcher):
    """The signatures of ``dispatcher`` compiled in this process or held by numba's disk cache (a kernel loaded from
    the cache holds the kernels it calls, which are then never loaded themselves: the rows of the closed form)."""
    return {*dispatcher.signatures, *(key[0] for key in dispatcher._cache._cache_file._load_index())}


def test_cold_kernels_compile_in_a_worker_process_and_load_from_the_cache(tmp_path):
    # Two small kernels, one per process: the worker's is in numba's cache afterwards, never compiled here.
    code = """
from tumble.kernels import side_by_side as s
jobs = [(name, signature, 5.0) for name, signature, _ in s.CLOSED_FORM["exponential"][-2:]]  # one each
assert not any(s.is_cached(*job[:2]) for job in jobs)
done = s.compile_side_by_side(jobs, workers=2)
assert sorted(done) == sorted(name for name, _, _ in jobs), done
(mine,), (theirs,) = s.deal(jobs, 2)
mine, theirs = s._dispatcher(mine), s._dispatcher(theirs)
assert mine.signatures and not theirs.signatures  # compiled here / by the worker
assert all(s.is_cached(*job[:2]) for job in jobs)
assert s.compile_side_by_side(jobs, workers=2) == []  # warm: nothing started
assert s.compile_side_by_side(s.CLOSED_FORM["exponential"], workers=1) == []  # one core: nothing started
"""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=300)


@pytest.mark.parametrize("argv, status", [(["studies"], 0), (["run", "no_such_study"], 2)])
def test_the_command_ends_at_once_with_mains_status_its_output_flushed_and_exit_handlers_run(argv, status):
    code = ("import atexit, sys\natexit.register(lambda: print('exit handler ran', flush=True))\n"
            f"sys.argv = ['tumble', *{argv!r}]\nfrom tumble.cli import command\ncommand()\nprint('not reached')")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == status, done.stderr
    assert done.stdout.rstrip().endswith("exit handler ran") and "not reached" not in done.stdout
    if status == 0:
        assert "intermediate_axis" in done.stdout and "studies in" in done.stdout
    else:
        assert done.stderr.startswith("tumble: error: no_such_study")


@pytest.fixture(scope="module")
def small_result(warm_kernels):
    import tumble

    return tumble.measure((1.0, 2.0, 3.0), 2, samples=64)


STUDY = {"title": "figure process", "outputs": {"figures": ["summary"], "format": ["png"]}}


def test_the_figure_process_draws_the_files_this_process_would(small_result, tmp_path):
    import xarray as xr

    from tumble.output import io
    from tumble.pipeline import figure_process, runner

    here, paths_here = runner.write_outputs(small_result, STUDY, tmp_path / "here", "s")
    with figure_process.FigureProcess() as drawer:
        apart, paths_apart = runner.write_outputs(small_result, STUDY, tmp_path / "apart", "s", figure_process=drawer)
    assert [p.name for p in paths_apart] == [p.name for p in paths_here] == ["s.nc", "s_summary.png"]
    for mine, theirs in zip(paths_here[1:], paths_apart[1:]):
        assert mine.read_bytes() == theirs.read_bytes(), mine.name
    xr.testing.assert_identical(io.read_dataset(paths_apart[0]), apart)  # written past to_netcdf's dask query
    assert sorted(p.name for p in (tmp_path / "apart").iterdir()) == sorted(p.name for p in paths_apart)


def test_an_error_in_the_figure_process_is_raised_here(small_result, tmp_path):
    from tumble.pipeline import figure_process

    blocker = tmp_path / "a file"
    blocker.write_text("")
    with figure_process.FigureProcess() as drawer:
        drawer.submit(small_result, ["summary"], blocker / "figures", "s", ("png",))
        with pytest.raises(OSError):
            drawer.result()
    with figure_process.FigureProcess() as drawer:
        drawer.submit(small_result, ["no_such_figure"], tmp_path, "s", ("png",))
        with pytest.raises(ValueError, match="no_such_figure"):
            drawer.result()


def test_when_the_figure_process_dies_the_figures_are_drawn_here(small_result, tmp_path):
    from tumble.pipeline import figure_process, runner

    with figure_process.FigureProcess() as drawer:
        drawer._process.kill()
        drawer._process.wait()
        _, paths = runner.write_outputs(small_result, STUDY, tmp_path, "s", figure_process=drawer)
    assert [p.name for p in paths] == ["s.nc", "s_summary.png"]
    assert all(p.stat().st_size > 0 for p in paths)


def test_a_dataset_too_large_to_send_is_drawn_here(small_result, tmp_path, monkeypatch):
    from tumble.pipeline import figure_process, runner

    monkeypatch.setattr(figure_process, "MAX_BYTES", small_result.nbytes - 1)
    with figure_process.FigureProcess() as drawer:
        _, paths = runner.write_outputs(small_result, STUDY, tmp_path, "s", figure_process=drawer)
        assert drawer._process is None  # ended unused
    assert [p.name for p in paths] == ["s.nc", "s_summary.png"] and paths[1].stat().st_size > 0


def test_tumble_run_imports_neither_xarray_dask_scipy_special_nor_asyncio_nor_leaves_its_figure_process_behind(
        tmp_path):
    code = f"""import os, sys
from tumble.cli import main
assert main(['run', '--samples', '32', '--out', {str(tmp_path)!r}]) == 0
assert 'dask.base' not in sys.modules, 'dask was imported'  # dask.array, distributed: 0.3-0.35 s each, dask 0.1 s
assert 'scipy.special' not in sys.modules, 'scipy.special was imported'
assert 'xarray' not in sys.modules, 'xarray was imported'  # the figure process builds and writes the result
assert 'asyncio' not in sys.modules, 'asyncio was imported'  # tqdm.auto's: 13-18 ms (tumble.engine.progress)
assert 'yaml' not in sys.modules, 'yaml was imported'  # numba reads no .numba_config.yaml here
try:
    os.waitpid(-1, os.WNOHANG)
except ChildProcessError:
    pass  # no child process left, ended or not
else:
    raise AssertionError('a child process is left')
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "intermediate_axis.nc", "intermediate_axis_flip_components.png", "intermediate_axis_norm_growth.png",
        "intermediate_axis_summary.png"]


@pytest.fixture(scope="module")
def curves_result(warm_kernels):
    import tumble

    return tumble.measure((1.0, 2.0, 3.0), 2, samples=64, curves=("norm", "trace"))


FIGURES = ["norm_growth", "flip_components", "summary"]


@pytest.mark.slow  # a forked figure process drawing three figures, then the same here (2.1 s)
def test_several_figures_are_shared_with_a_forked_child_and_are_the_files_this_process_would_write(curves_result,
                                                                                                     tmp_path):
    from tumble.output import figures
    from tumble.pipeline import figure_process

    here = figures.save_figures(curves_result, FIGURES, tmp_path / "here", "s", formats=("png", "pdf"))
    with figure_process.FigureProcess() as drawer:
        drawer.submit(curves_result, FIGURES, tmp_path / "apart", "s", ("png", "pdf"))
        apart = drawer.result()
    assert [p.name for p in apart] == [p.name for p in here]
    for mine, theirs in zip(here, apart):
        assert mine.read_bytes() == theirs.read_bytes(), mine.name


def test_figures_the_child_cannot_draw_are_drawn_by_the_figure_process(curves_result, tmp_path, monkeypatch):
    from tumble.pipeline import figure_process

    monkeypatch.setattr(figure_process, "_cores", lambda: 2)
    monkeypatch.setattr(figure_process, "_linux_die_with_parent", lambda: lambda: False)  # the child gives up
    paths = figure_process._figures(curves_result, FIGURES, tmp_path, "s", ("png",))
    assert paths == [str(tmp_path / f"s_{name}.png") for name in FIGURES]
    assert all(os.path.getsize(p) > 0 for p in paths)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the child is tied to its parent on Linux only")
def test_the_forked_child_ends_when_the_figure_process_is_killed(curves_result, tmp_path):
    import time

    from tumble.pipeline import figure_process

    many = FIGURES * 20  # seconds of drawing: the child is still at it when its parent is killed
    with figure_process.FigureProcess() as drawer:
        drawer.submit(curves_result, many, tmp_path, "s", ("png", "pdf"))
        pid = drawer._process.pid
        children, deadline = [], time.monotonic() + 60
        while not children and time.monotonic() < deadline and drawer._process.poll() is None:
            try:
                children = open(f"/proc/{pid}/task/{pid}/children").read().split()
            except OSError:
                break
            time.sleep(0.005)
    killed = time.monotonic()  # close() killed the figure process
    if not children:
        pytest.skip("the figure process's child was not seen")
    child = int(children[0])
    while time.monotonic() < killed + 2.0:
        try:
            state = open(f"/proc/{child}/stat").read().rsplit(")", 1)[1].split()[0]
        except OSError:
            return  # gone
        if state in ("Z", "X"):
            return  # dead, not yet reaped
        time.sleep(0.01)
    raise AssertionError(f"the figure process's child {child} outlived it")


def test_the_run_command_settles_its_process_without_scipy_and_keeps_blas_usable(tmp_path):
    # tumble.cli._lean_kernel_process: numba's first kernel load without scipy.linalg; the user's OMP_WAIT_POLICY
    # kept; np.dot still compiles (numba imports scipy's BLAS when it needs it)
    code = ("import os, sys\nfrom tumble import cli\ncli._lean_kernel_process()\n"
            "assert 'numba.np.arraymath' in sys.modules and 'scipy' not in sys.modules\n"
            "assert not [name for name in ('scipy', 'scipy.linalg.cython_blas', 'yaml') if sys.modules.get(name, 0) is None]\n"
            "print(os.environ['OMP_WAIT_POLICY'], 'yaml' in sys.modules)\n"
            "import numba, numpy as np\n"
            "print(numba.njit(lambda a: np.dot(a, a))(np.arange(3.0)), numba.config.NUMBA_NUM_THREADS)")
    env = dict(os.environ)
    env.pop("OMP_WAIT_POLICY", None)
    env.pop("NUMBA_NUM_THREADS", None)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                          cwd=tmp_path)
    assert done.stdout.split()[:3] == ["PASSIVE", "False", "5.0"]
    env["OMP_WAIT_POLICY"] = "ACTIVE"
    (tmp_path / ".numba_config.yaml").write_text("num_threads: 1\n")  # numba reads it with PyYAML: found as usual
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env,
                          cwd=tmp_path)
    assert done.stdout.split() == ["ACTIVE", "True", "5.0", "1"]


@pytest.mark.parametrize("study", ["stability_map", "gyrostat_map", "intermediate_axis"])
def test_scene_records_cross_to_another_process_exactly(warm_kernels, study):
    import pickle

    import numpy as np

    from tumble.measure.records import stack_records, unstack_records
    from tumble.pipeline import runner

    overrides = {"perturbation.samples": 16}
    if study != "intermediate_axis":
        overrides["outputs.arrays"] = ["sample_rate", "sample_status"]
    job = runner.prepare_study(study, overrides=overrides).job
    records = runner.run_scenes(job, chunk_scenes=1000)
    back = unstack_records(pickle.loads(pickle.dumps(stack_records(records))))
    assert len(back) == len(records)
    for mine, theirs in zip(records, back):
        assert list(mine) == list(theirs)
        for name, value in mine.items():
            assert (type(value), value.dtype, value.shape) == (type(theirs[name]), theirs[name].dtype,
                                                               theirs[name].shape), name
            assert np.array_equal(value, theirs[name], equal_nan=value.dtype.kind == "f"), name


def test_records_of_different_dtypes_shapes_or_names_are_stacked_apart_and_come_back_exactly():
    import numpy as np

    from tumble.measure.records import stack_records, unstack_records

    records = [{"x": np.array(1.5), "kind": np.array("periodic")},
               {"x": np.array(2, dtype=np.int64), "kind": np.array("exponential")},  # int: not promoted to float
               {"x": np.array([1.0, 2.0]), "kind": np.array("neutral")},  # another shape
               {"kind": np.array("periodic"), "x": np.array(0.5)},  # another order of names
               {"x": np.array(3.5), "kind": np.array("periodic")}]
    count, groups = stack_records(records)
    assert count == 5 and sorted(positions for positions, *_ in groups) == [[0, 4], [1], [2], [3]]
    for mine, theirs in zip(records, unstack_records((count, groups))):
        assert list(mine) == list(theirs)
        for name, value in mine.items():
            assert (value.dtype, value.shape, value.tolist()) == (theirs[name].dtype, theirs[name].shape,
                                                                  theirs[name].tolist())


def test_the_figure_process_writes_from_the_records_what_this_process_would(warm_kernels, tmp_path, monkeypatch):
    import numpy as np
    import xarray as xr

    from tumble.output import io
    from tumble.pipeline import figure_process, results, runner

    prepared = runner.prepare_study("stability_map", overrides={"perturbation.samples": 16}, out=tmp_path)
    records = runner.run_scenes(prepared.job)
    ds = results.result_dataset(records, **runner._result_shape(prepared.job), resolved=prepared.resolved)
    stored, paths_here = runner.write_outputs(ds, prepared.resolved, tmp_path / "here", "s")
    monkeypatch.setattr(results, "result_dataset", None)  # built in the figure process, not here
    with figure_process.FigureProcess() as process:
        summary, paths_apart = runner.write_records(records, prepared.job, prepared.resolved, tmp_path / "apart", "s",
                                                    figure_process=process)
    assert [p.name for p in paths_apart] == [p.name for p in paths_here] == [
        "s.nc", "s_stability_map.png", "s_summary.png"]
    for mine, theirs in zip(paths_here[1:], paths_apart[1:]):
        assert mine.read_bytes() == theirs.read_bytes(), mine.name
    apart = io.read_dataset(paths_apart[0])
    xr.testing.assert_identical(apart.drop_attrs(deep=False), stored.drop_attrs(deep=False))
    assert apart.attrs.keys() == stored.attrs.keys()
    assert all(np.array_equal(apart.attrs[k], stored.attrs[k]) for k in stored.attrs if k != "history")  # a time
    assert summary == results.summary_table(stored)


def test_jobs_are_dealt_to_the_process_that_finishes_them_soonest():
    from tumble.kernels import side_by_side as s

    jobs = [("a", (), 2.0), ("b", (), 1.0), ("c", (), 1.5), ("d", (), 0.1)]
    assert s.deal(jobs, 2) == [["a", "b"], ["c", "d"]]  # a worker starts WORKER_START = 0.7 s late
    assert s.deal(jobs[3:], 2) == [["d"], []]  # not worth a worker
    assert sorted(sum(s.deal(s.CLOSED_FORM["grid"] + s.ATTITUDE, 3), [])) == sorted(
        name for name, _, _ in s.CLOSED_FORM["grid"] + s.ATTITUDE)


def test_the_rows_compiled_ahead_are_those_of_the_regimes_the_set_up_meets():
    # the estimate before the set-up (exact.regimes_met) holds every regime the set-up then finds, spin by spin
    import numpy as np

    from tumble.kernels import elliptic
    from tumble.physics import exact

    rng = np.random.default_rng(5)
    near = rng.normal(size=(60, 3)) * 10.0 ** rng.uniform(-13, 0, (60, 1))
    near[:, 1] = rng.choice([-1.0, 1.0], 60)  # about the intermediate axis, at every distance
    w = np.concatenate([rng.normal(size=(60, 3)), near, np.eye(3), [[0.0, 0.0, 0.0], [0.2, 0.5, 0.1],
                                                                    [1.0, np.sqrt(2.0), 0.0]]])
    for body in ((1.0, 2.0, 3.0), (3.0, 1.0, 2.0), (2.0, 2.0, 3.0), (1.0, 3.0, 3.0), (2.0, 2.0, 2.0)):
        sol = exact._solve(body, w)
        for i in range(w.shape[0]):
            found = [name for name, samples in zip(elliptic.REGIMES, elliptic.regimes(sol.kind[i:i + 1],
                                                                                      sol.kc[i:i + 1])) if samples.size]
            assert set(found) <= set(exact.regimes_met(body, w[i:i + 1])), (body, w[i], found)
    # a scene's spins about the intermediate axis, and about the largest one
    off = near[:, 0] ** 2 + near[:, 2] ** 2  # a spin within 1e-9 of the separatrix may be on it: that row too
    assert exact.regimes_met((1.0, 2.0, 3.0), near[(off > 1e-7) & (off < 1e-4)]) == ("hyperbolic",)
    assert exact.regimes_met((1.0, 2.0, 3.0), [[0.01, 0.02, 1.0], [-0.03, 0.01, 2.0]]) == ("landen",)


def test_a_call_estimates_the_regimes_to_compile_only_while_the_set_up_has_not_run(monkeypatch):
    # the estimate costs about 50 us a call: once the set-up has run in the process, no call pays it again
    import numpy as np

    from tumble.physics import exact

    exact.omega((1.0, 2.0, 3.0), [0.01, 1.0, 0.01], np.linspace(0.0, 1.0, 3))  # the set-up has run
    monkeypatch.setattr(exact, "regimes_met", lambda *args: pytest.fail("estimated again"))
    assert exact.regimes_to_compile((1.0, 2.0, 3.0), np.array([[0.01, 0.02, 1.0]])) == ()
    exact.omega((1.0, 2.0, 3.0), [0.01, 0.02, 1.0], np.linspace(0.0, 1.0, 3))


def test_tumble_checks_kernels_compile_side_by_side_in_the_variants_it_calls(monkeypatch):
    # the jobs' signatures are those check() calls: after a check here, each is among the compiled ones (a drifted
    # signature would have the worker compile a variant the run never loads)
    import numpy as np

    import tumble
    from tumble.kernels import side_by_side
    from tumble.physics import exact

    t = np.linspace(0.0, 5.0, 101)
    w0 = np.array([0.01, 1.0, 0.01])
    omega, quaternion = exact.omega((1.0, 2.0, 3.0), w0, t), exact.attitude((1.0, 2.0, 3.0), w0, t)
    asked = []
    monkeypatch.setattr(exact._side_by_side, "compile_side_by_side", lambda jobs: asked.append(jobs) or [])
    monkeypatch.setattr(exact, "regimes_to_compile", exact.regimes_met)  # as in a process whose set-up never ran
    exact.compile_kernels_side_by_side.cache_clear()
    tumble.check(t, omega, quaternion, moments=(1, 2, 3))
    exact.compile_kernels_side_by_side.cache_clear()
    # the spin is near the separatrix: the evaluation's hyperbolic rows only
    grid_jobs = side_by_side.CLOSED_FORM["grid"] + (side_by_side.ROWS["hyperbolic"],)
    check_jobs = grid_jobs + side_by_side.ATTITUDE
    assert asked[0] == check_jobs  # first, its own; then exact.omega's on a grid, a subset of it, cached by then
    assert all(jobs == grid_jobs for jobs in asked[1:])
    for name, signature, _ in check_jobs:
        assert tuple(signature) in compiled_or_cached(side_by_side._dispatcher(name)), name


@pytest.mark.parametrize("study, overrides, asked", [
    ("dzhanibekov_flip", {}, [("exponential", True)]),
    ("dzhanibekov_flip", {"integration.method": "rk4"}, []),  # the attitude steps: no closed-form kernel
    ("stability_map", {}, []),  # no attitude figure
])
def test_a_study_drawing_the_closed_form_attitude_compiles_it_with_its_scenes(monkeypatch, study, overrides, asked):
    from tumble.pipeline import runner

    calls = []
    monkeypatch.setattr(runner.exact, "compile_kernels_side_by_side", lambda kind, attitude=False: calls.append(
        (kind, attitude)))
    prepared = runner.prepare_study(study, overrides=overrides)
    runner._compile_the_attitude_with_the_scenes(prepared.resolved, prepared.job)
    assert calls == asked


@pytest.mark.parametrize("trouble", ["dead", "too large"])
def test_records_the_figure_process_cannot_take_are_written_here(warm_kernels, tmp_path, monkeypatch, trouble):
    from tumble.pipeline import figure_process, results, runner

    prepared = runner.prepare_study("stability_map", overrides={"perturbation.samples": 16}, out=tmp_path)
    records = runner.run_scenes(prepared.job)
    if trouble == "too large":
        monkeypatch.setattr(figure_process, "MAX_BYTES", 1)
    with figure_process.FigureProcess() as process:
        if trouble == "dead":
            process._process.kill()
            process._process.wait()
        summary, paths = runner.write_records(records, prepared.job, prepared.resolved, tmp_path, "s",
                                              figure_process=process)
        assert process._process is None  # ended
    assert [p.name for p in paths] == ["s.nc", "s_stability_map.png", "s_summary.png"]
    assert all(p.stat().st_size > 0 for p in paths)
    ds = results.result_dataset(records, layout=prepared.job.layout, scanned=True,
                                body_coords=prepared.job.body_coords, resolved=prepared.resolved)
    assert summary == results.summary_table(ds)


def test_the_commands_import_with_the_collector_paused_then_frozen_and_leave_it_as_it_was():
    import gc

    from tumble import _startup

    frozen = gc.get_freeze_count()
    try:
        with _startup.collector_paused():
            assert not gc.isenabled()
            made = [[i] for i in range(1000)]  # what an import leaves: long-lived objects
        assert gc.isenabled() and gc.get_freeze_count() >= frozen + len(made)
        gc.disable()  # a caller that turned it off keeps it off
        with _startup.collector_paused():
            pass
        assert not gc.isenabled()
    finally:
        gc.unfreeze()  # the test process's objects back in sight, as before the test
        gc.enable()
