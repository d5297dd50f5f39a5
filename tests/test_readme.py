"""The README's Python blocks run as written (issue 59): in order, in one fresh Python process, each block on the names
the earlier ones define, as a reader pastes them into a notebook; what each prints is its ``#>`` lines (compared as
doctest compares, with ``...`` matching anything and runs of white space alike)."""

import doctest
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"

#: What the process prints between two blocks.
_SEPARATOR = "--- tumble README block ---"

_RUNNER = """
import json, sys, traceback
namespace = {"__name__": "__main__"}
for i, block in enumerate(json.loads(sys.stdin.read())):
    print(%r, flush=True)
    try:
        exec(compile(block, f"README block {i + 1}", "exec"), namespace)
    except BaseException:
        traceback.print_exc()
        sys.exit(1)
""" % _SEPARATOR


def python_blocks(markdown):
    """The bodies of the ```python blocks of ``markdown``, in order."""
    return re.findall(r"^```python\n(.*?)^```", markdown, flags=re.S | re.M)


def run_blocks(blocks, cwd):
    """``(exit status, [what each block printed], stderr)``: the blocks run in order in one new process."""
    done = subprocess.run([sys.executable, "-c", _RUNNER], input=json.dumps(blocks), capture_output=True, text=True,
                          cwd=cwd, timeout=600)
    printed = done.stdout.split(_SEPARATOR + "\n")[1:]
    return done.returncode, printed, done.stderr


def mismatches(blocks, printed):
    """One line per block whose output is not its ``#>`` lines."""
    checker, flags = doctest.OutputChecker(), doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    found = []
    for i, (block, got) in enumerate(zip(blocks, printed)):
        want = "".join(line[3:] + "\n" for line in block.splitlines() if line.startswith("#> "))
        if not checker.check_output(want, got, flags):
            found.append(f"README block {i + 1} printed\n{got}but its #> lines say\n{want}")
    return found


def test_every_python_block_prints_something_to_compare():
    blocks = python_blocks(README.read_text("utf-8"))
    assert len(blocks) >= 3
    for i, block in enumerate(blocks):
        assert "print(" in block and "\n#> " in block, f"README block {i + 1} shows no result"


def test_the_readmes_python_blocks_run_in_order_in_a_fresh_process_and_print_what_they_say(tmp_path):
    blocks = python_blocks(README.read_text("utf-8"))
    status, printed, stderr = run_blocks(blocks, tmp_path)
    assert status == 0, stderr
    assert len(printed) == len(blocks)
    assert not mismatches(blocks, printed), "\n".join(mismatches(blocks, printed))


@pytest.mark.parametrize("blocks, problem", [
    (["x = 1\nprint(x)\n#> 1\n", "print(y0)\n#> 0\n"], "NameError: name 'y0' is not defined"),
    (["print(2.5)\n#> 2.4...\n"], "README block 1 printed"),
])
def test_a_broken_block_is_caught(tmp_path, blocks, problem):
    """The runner itself: a block that uses a name no block defines fails, and so does one that prints another
    result than its #> lines."""
    status, printed, stderr = run_blocks(blocks, tmp_path)
    assert problem in stderr + "\n".join(mismatches(blocks, printed))
