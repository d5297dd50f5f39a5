"""Shared fixtures. Kernels are cached on disk by numba; the session fixture below compiles each kernel
variant the suite uses once, up front, so individual tests measure physics, not the JIT."""

import numpy as np
import pytest

import tumble


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
