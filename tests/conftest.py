"""Shared fixtures. Kernels are cached on disk by numba; the session fixture below compiles each kernel
variant the suite uses once, up front, so individual tests measure physics, not the JIT.

Bytecode is cached even where ``PYTHONDONTWRITEBYTECODE`` is set (as on our CI machines): otherwise every run
compiles tumble's modules and rewrites the assertions of every test module again, about 11 s per test worker
(measured, 2 cores); ``__pycache__`` is git-ignored."""

import sys

sys.dont_write_bytecode = False  # before tumble and the test modules are imported

import os  # noqa: E402

# The device kernels (tests/test_cuda.py) run on numba-cuda's simulator unless the environment says otherwise
# (NUMBA_ENABLE_CUDASIM=0 on a GPU machine runs the same tests on the GPU). numba reads the switch once, when it is
# first imported, so it is set here, before anything imports numba; no other test touches numba.cuda.
os.environ.setdefault("NUMBA_ENABLE_CUDASIM", "1")
# Every finished chunk is checkpointed as it finishes, as a long run does: the tests' studies are short, and a run
# of under two seconds would otherwise write none (tumble.pipeline.runner.CHECKPOINT_AFTER; tests/test_resume.py
# tests that rule itself). Subprocesses of the tests inherit it.
os.environ["TUMBLE_CHECKPOINT_AFTER"] = "0"

import numba  # noqa: E402
import numpy as np  # noqa: E402
import pytest

import tumble  # noqa: E402

if os.environ.get("PYTEST_XDIST_WORKER"):
    # The suite runs on two worker processes (pyproject's addopts), one per core: each runs numba's parallel kernels
    # on one thread unless a test asks for more, so that the two do not oversubscribe the cores (numba's OpenMP
    # threads spin while they wait). Tests of thread counts set theirs explicitly.
    numba.set_num_threads(1)


@pytest.hookimpl(tryfirst=True)  # before -m 'not slow' deselects
def pytest_collection_modifyitems(config, items):
    """``@pytest.mark.default_cases(id, ...)`` on a parametrized test: the listed cases run by default, the others of
    its combinations are marked ``slow`` (one case proves the path; CI's slow run keeps the breadth). An id that names
    no case of the test is an error, so that a renamed case cannot drop out of both runs unseen."""
    seen, listed = {}, {}
    for item in items:
        marker = item.get_closest_marker("default_cases")
        if marker is None or not hasattr(item, "callspec"):
            continue
        seen.setdefault(item.originalname, set()).add(item.callspec.id)
        listed[item.originalname] = set(marker.args)
        if item.callspec.id not in marker.args:
            item.add_marker(pytest.mark.slow)
    whole = not config.option.keyword and not any("::" in arg for arg in config.args)  # every case collected
    for name, ids in listed.items():
        missing = ids - seen[name]
        if missing and whole:
            raise pytest.UsageError(f"default_cases of {name} names no case {sorted(missing)}; its cases: "
                                    f"{sorted(seen[name])}")


@pytest.fixture(scope="session")
def warm_kernels():
    """Compile (or load from the cache) the torque-free and constant-torque kernels once per session."""
    w0 = np.array([[0.1, 1.0, 0.1]])
    tumble.integrate((1.0, 2.0, 3.0), w0, 0.01, 0.01, method="rk4")
    tumble.integrate((1.0, 2.0, 3.0), w0, 0.01, 0.01, method="rk4", torque=(0.0, 0.0, 1.0))
    return True


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


@pytest.fixture(scope="module")
def cuda_device():
    """The device is usable (the simulator, or a GPU), else the test is skipped with the reason."""
    from tumble.engine.device import resolve_device

    try:
        return resolve_device("cuda")
    except ValueError as err:
        pytest.skip(str(err))
