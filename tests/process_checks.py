"""Running a script in new processes, for the tests that a kernel is kept in numba's disk cache across them."""

import subprocess
import sys


def run_twice(tmp_path, source, name="script.py"):
    """Write ``source`` to ``tmp_path / name``, run it in two new processes one after the other (the second finds the
    cache the first filled) and return each one's standard output split into words; a run that fails fails the test
    with its standard error."""
    script = tmp_path / name
    script.write_text(source)
    runs = [subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
            for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
    return [run.stdout.split() for run in runs]
