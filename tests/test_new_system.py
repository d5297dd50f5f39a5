"""A new built-in system is one file and one registry row (issue 55, item 4).

In a copy of the package, the test writes a system it has never seen, ``scaled_body`` (a free body whose clock runs
``clock`` times faster: ``w' = clock (I w) × w / I``; its linear rates are ``clock`` times the free body's), as
``physics/models/scaled_body.py`` (its equations and its model class) plus one row in ``registry.MODELS``; runs the
generator; and then, in a new interpreter on that copy, the public calls: ``integrate``, ``measure`` (about an axis and
about a state), ``lyapunov`` and a study with ``[model] kind = "scaled_body"``. Nothing else of the package is edited.

Slow: the copy compiles every kernel it runs from an empty cache (a few minutes on 2 cores).
"""

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import tumble

pytestmark = pytest.mark.slow

SYSTEM_FILE = '''
"""A free body whose clock runs ``clock`` times faster: ``I w' = clock (I w) x w`` (written by a test)."""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ... import registry
from . import base

__all__ = ["Constants", "ScaledBody", "constants", "invariants", "rate", "tangent"]

Constants = namedtuple("Constants", (*registry.RIGID_BODY, "clock"))


def constants(moments, clock=1.0):
    """:class:`Constants` of moments (kg m2) and the clock's rate (1)."""
    return Constants(*registry.rigid_body(moments), float(clock))


def rate(t, w1, w2, w3, c):
    """``w'`` (rad/s2)."""
    return (c.clock * c.a1 * w2 * w3, c.clock * c.a2 * w3 * w1, c.clock * c.a3 * w1 * w2)


def tangent(t, w1, w2, w3, v1, v2, v3, c):
    """``J(w) v``."""
    return (c.clock * c.a1 * (v2 * w3 + w2 * v3), c.clock * c.a2 * (v3 * w1 + w3 * v1),
            c.clock * c.a3 * (v1 * w2 + w1 * v2))


def invariants(w1, w2, w3, c):
    """The energy and |L|2, their scales."""
    l1, l2, l3 = c.i1 * w1, c.i2 * w2, c.i3 * w3
    e = 0.5 * (l1 * w1 + l2 * w2 + l3 * w3)
    m = l1 * l1 + l2 * l2 + l3 * l3
    return e, m, 0.0, e, m, 1.0


@dataclass(frozen=True, eq=False)
class ScaledBody(base.Model):
    """The free body on a faster clock."""

    clock: float
    kind: ClassVar[str] = "scaled_body"

    def equilibrium(self, axis, spin=1.0):
        return base.spin_state(3, base.one_axis(axis), spin)

    def transverse(self, axis, spin=1.0):
        k = base.one_axis(axis)
        pair = np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp)
        return base.Transverse(pair, base.circular_weights(self.moments, k, 1.0, 0.0), pair.copy())
'''

REGISTRY_ROW = '''    Model("scaled_body", (ModelParameter("clock", 1, "1", True, "scaled_body: how many times faster its clock runs"),),
          ("w1", "w2", "w3"), ("energy", "momentum_squared"), True, True, "a free body on a faster clock"),
'''

CALLS = '''
import json, sys
import numpy as np
import tumble
from tumble import models, registry

body = models.ScaledBody((1.0, 2.0, 3.0), clock=2.0)
out = {"kinds": list(registry.MODEL_KINDS)}
w0 = np.array([[0.01, 1.0, 0.01]])
ds = tumble.integrate(body, w0, 1.0, 1e-3)
free = tumble.integrate(tumble.Body(1.0, 2.0, 3.0), w0, 2.0, 2e-3)  # the same steps on the free body's clock
out["integrate"] = float(np.abs(ds.state.values[0, -1] - free.omega.values[0, -1]).max())
by_axis = tumble.measure(body, 2, 1.0, samples=64)
by_state = tumble.measure(body, state=body.equilibrium(2, 1.0), samples=64)
out["measure"] = [[float(d.rate_theory), float(d.rel_error), str(d.kind.values)] for d in (by_axis, by_state)]
out["free_rate"] = tumble.theory.linear(tumble.Body(1.0, 2.0, 3.0), 2, 1.0)[1]
lyap = tumble.lyapunov(body, np.array([[1.0, 0.2, 0.3]]), t_end=200.0, dt=0.01)
out["lyapunov"] = float(np.max(np.abs(lyap.exponent.values)))
study = tumble.run_study({"model": {"kind": "scaled_body", "clock": 2.0}, "body": {"moments": [1.0, 2.0, 3.0]},
                          "perturbation": {"samples": 32}, "scan": {"axis": [1, 2, 3]},
                          "outputs": {"figures": [], "arrays": []}}, progress=False)
out["study"] = [str(k) for k in study.kind.values.ravel()] + [float(e) for e in study.rel_error.values.ravel()]
print(json.dumps(out))
'''


def test_a_system_added_as_one_file_and_one_registry_row_runs_every_public_call(tmp_path):
    package = Path(tumble.__file__).parent
    copy = tmp_path / "tumble"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "physics" / "models" / "scaled_body.py").write_text(SYSTEM_FILE.lstrip())
    registry_text = (copy / "registry.py").read_text()
    end = "\n)\n_MODEL_BY_NAME"
    assert registry_text.count(end) == 1
    (copy / "registry.py").write_text(registry_text.replace(end, "\n" + REGISTRY_ROW.rstrip("\n") + end))
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    subprocess.run([sys.executable, "-m", "tumble.kernels.steps.model_codegen"], cwd=tmp_path, env=env, check=True,
                   capture_output=True)
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(CALLS)], cwd=tmp_path, env=env, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["kinds"][-1] == "scaled_body"
    assert out["integrate"] < 1e-9  # 1 s on a clock twice as fast is the free body's 2 s
    for rate_theory, rel_error, kind in out["measure"]:
        assert kind == "exponential" and rate_theory == pytest.approx(2.0 * out["free_rate"], rel=1e-9)
        assert rel_error < 1e-3
    assert out["lyapunov"] < 0.05  # the free body is integrable: no exponent beyond the finite-time 1/t
    kinds, errors = out["study"][:3], out["study"][3:]
    assert kinds == ["periodic", "exponential", "periodic"] and max(errors) < 5e-3
