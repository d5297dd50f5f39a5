"""``tumble warm`` (issue 43): the calls it warms compile nothing more at their first call in a new process; bad names
get one line."""

import os
import shutil
import subprocess
import sys

import pytest

from tumble import cli, warm

# Counts the compiles of tumble's kernels during the call (numba's compile events), and prints the count.
_COUNT_COMPILES = """
import numpy as np, tumble
from numba.core import event
{setup}
compiled = []
class Listener(event.Listener):
    def on_start(self, ev):
        name = getattr(getattr(ev.data.get("dispatcher"), "py_func", None), "__module__", "") or ""
        if name.startswith("tumble."):
            compiled.append(name)
    def on_end(self, ev):
        pass
event.register("numba:compile", Listener())
{call}
print(len(compiled))
"""


def _split(source):
    """A call's source: its set-up lines, and its last line (the call)."""
    lines = source.strip().splitlines()
    return "\n".join(lines[:-1]), lines[-1]


def test_unknown_calls_are_refused_in_one_line(capsys):
    with pytest.raises(ValueError, match="nothing to warm called 'integrat'; the calls are integrate, measure"):
        warm.warm(["integrat"])
    assert cli.main(["warm", "integrat"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"tumble: error: unknown call 'integrat' for tumble warm; the calls are {', '.join(warm.CALLS)} "
                   "(or all)"]


def test_every_default_call_is_a_call():
    assert set(warm.DEFAULT) <= set(warm.CALLS)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["exact", "integrate"])
def test_a_warmed_call_compiles_nothing_at_its_first_call(name, tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    setup, call = _split(warm.CALLS[name][1])
    probe = [sys.executable, "-c", _COUNT_COMPILES.format(setup=setup, call=call)]
    environment = {**os.environ, "NUMBA_NUM_THREADS": "1"}
    cold = subprocess.run(probe, env=environment, capture_output=True, text=True, check=True)
    assert int(cold.stdout.split()[-1]) > 0, "an empty cache compiles (the probe sees compiles)"
    shutil.rmtree(tmp_path)  # empty the cache again
    tmp_path.mkdir()
    (warmed,) = warm.warm([name], workers=1)
    assert warmed.error == ""
    after = subprocess.run(probe, env=environment, capture_output=True, text=True, check=True)
    assert int(after.stdout.split()[-1]) == 0
